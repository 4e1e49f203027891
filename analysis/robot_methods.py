"""The methods that drive the robot scenarios (`RobotScenario`): robust, nominal, oracle, dwa, teb.

Each is a `Method` of `minimaxplan.analysis.registry`, run by the one episode loop of
`minimaxplan.analysis.episode`; importing this module registers them, in this order.

Methods
-------
robust
    The proposed planner: `ModelSelector` over `robot_hypotheses` (with the errata's
    inflation for the bounded measurement noise), the LP `feasible_parameter_box` of
    every survivor as its parameter polytope, and `RobustTreePlanner` over one
    `IntervalModel` per survivor (K = 100, gamma = 0.9). The Assumption 4 report is
    made once per episode (see `assumption4_report`). When the tree's best plan may
    collide within `LATEST_COLLISION_DECISIONS` decisions, it executes the first action
    whose plans stay clear longest under every survivor (`latest_collision_action`, the
    road worlds' rule). Its policies are
    `PredictingPolicy`s: after every sub-step of the executed action, the episode loop
    checks the true robot state and the pedestrians' true positions against the boxes
    the planner predicted for them (`RobustMethod.executed_boxes`).
nominal
    Certainty equivalence: OPD on the least-squares friction estimate (w = 0), the
    pedestrians at their announced velocities.
oracle
    OPD on the true friction (w = 0): the reference of the suboptimality study
    (`minimaxplan.analysis.suboptimality`).
dwa, teb
    The baselines of `minimaxplan.planners`, given the same noisy measurements and the
    pedestrians' current positions and announced velocities. Like the ROS local
    planners of the paper they do not learn the friction: their rollouts use the
    nominal model at the centre of the prior box.

The low-level controllers (one per discrete action) track a velocity reference,
``u = sat(k (v_ref - v))``: the four diagonal directions of the paper, each axis at
``LoopConfig.speed`` (the control set is the box [-1, 1]^2, so each axis runs at its
own speed; alternating two diagonals moves along an axis at full speed), plus "stop". They act on *measured* states, so the applied
control differs from the model's by at most ``k * v_bar`` per axis; that difference
enters the robust planner's model as an extra bounded disturbance through ``B``,
which keeps the interval prediction sound.

Every method chases the same waypoint, ``LoopConfig.lookahead`` metres along a grid
path to the goal around the static discs (`NavigationFunction`, the global planner of
a navigation stack): the paper's goal reward ``1 / (1 + ||pos - goal||)`` is myopic,
and with K = 100 every local planner, robust or not, stalled or crashed in front of
concave obstacle clusters without it (tuning seeds 10000-10009: 6/10 robust
timeouts, 4/10 nominal collisions). Pedestrians are left to the local planners.
"""

from __future__ import annotations

import numpy as np

from minimaxplan.models import Box, ConfidenceEllipsoidEstimator, NoConsistentModel, UncertainLinearSystem
from minimaxplan.planners.comparison import multi_model_robust_planner, nominal_planner, root_state
from minimaxplan.planners.controllers import LinearFeedback
from minimaxplan.planners.dwa import DynamicWindowPlanner
from minimaxplan.planners.interval_model import BoxState
from minimaxplan.planners.latest_collision import latest_collision_action
from minimaxplan.planners.search import RobustTreePlanner
from minimaxplan.planners.teb import TimedElasticBand
from minimaxplan.scenarios import MovingObstacles, RobotWorld
from minimaxplan.verify.selection import ModelSelector, feasible_parameter_box

from .episode import LoopConfig
from .registry import EpisodeFailure, Method, Policy, PredictingPolicy, Transition, UnsupportedScenario, register_method
from .robot_scenario import RobotScenario, assumption4_report, excitation_data

__all__ = [
    "LATEST_COLLISION_DECISIONS",
    "RobotMethod",
    "RobustMethod",
    "NominalMethod",
    "OracleMethod",
    "DWAMethod",
    "TEBMethod",
    "velocity_controllers",
    "planning_system",
    "measurement_box",
]


#: Decisions over which the robust method's latest-possible-collision rule looks for a
#: possible collision (2 s at the paper's 0.5 s decisions: the depth its tree reaches at
#: K = 100 in the pedestrian world).
LATEST_COLLISION_DECISIONS = 4


def velocity_controllers(config: LoopConfig, control_bound: float = 1.0) -> list[LinearFeedback]:
    """One saturated velocity-tracking controller per direction: ``v_ref = speed * direction``.

    Parameters
    ----------
    config : LoopConfig
        Its ``directions`` (one controller each), ``speed`` (m/s) and ``gain`` k (1/s).
    control_bound : float
        Each control is saturated to ``[-control_bound, control_bound]`` per axis.

    Returns
    -------
    list of LinearFeedback
        ``u = sat(k (v_ref - v))``, one per direction, in the order of ``directions``.
    """
    K = np.zeros((2, 4))
    K[0, 2] = K[1, 3] = config.gain
    controllers = []
    for direction in config.directions:
        v_ref = config.speed * np.asarray(direction, dtype=float)
        controllers.append(
            LinearFeedback(K, np.concatenate([np.zeros(2), v_ref]), u_low=-control_bound, u_high=control_bound)
        )
    return controllers


def planning_system(system: UncertainLinearSystem, control_error: float) -> UncertainLinearSystem:
    """``system`` with the control error ``|e| <= control_error`` added as a disturbance through B.

    ``x+ = A(theta) x + B (u + e) + D w = A(theta) x + B u + [D B] (w, e)``.

    Parameters
    ----------
    system : UncertainLinearSystem
        The hypothesis.
    control_error : float
        Bound on the error of each control input, in the units of u (the robot: ``k *
        v_bar``, the gain times the measurement-noise bound).
    """
    D = np.hstack([system.D, system.B])
    w = Box(
        np.concatenate([system.w.low, np.full(system.ninputs, -control_error)]),
        np.concatenate([system.w.high, np.full(system.ninputs, control_error)]),
    )
    return UncertainLinearSystem(system.A0, system.phi, system.B, D=D, w=w, theta=system.theta)


def measurement_box(measured: np.ndarray, noise: float) -> tuple[np.ndarray, np.ndarray]:
    """The box ``measured +- noise`` that holds the true state, rounded outward.

    The measurement itself was rounded (``fl(x + v)``, error up to half an ulp of
    ``|measured|``) and so is ``measured -+ noise``: a margin of ``2 eps (|measured| +
    noise)`` covers both, whatever the magnitudes of x and v.

    Parameters
    ----------
    measured : numpy.ndarray
        The measured state, shape (p,).
    noise : float
        The bound on the measurement noise of every coordinate, state units.

    Returns
    -------
    tuple of numpy.ndarray
        ``(lower, upper)``, each of shape (p,).
    """
    margin = 2 * np.finfo(float).eps * (np.abs(measured) + noise)
    return np.nextafter(measured - noise - margin, -np.inf), np.nextafter(measured + noise + margin, np.inf)


class _LeastSquares:
    """Least-squares friction estimate of the true structure from measured transitions (nominal planner)."""

    def __init__(self, system: UncertainLinearSystem, regularisation: float):
        self.system = system
        self.estimator = ConfidenceEllipsoidEstimator(
            system.nparams, sigma=1.0, lam=regularisation, delta=0.1, bound=float(np.linalg.norm(system.theta.high))
        )

    def add(self, x, u, x_next) -> None:
        target = x_next - self.system.A0 @ x - self.system.B @ u
        self.estimator.update(self.system.regressor(x), target)

    def estimate(self) -> np.ndarray:
        """The regularised least-squares centre, projected onto the prior box (a friction
        outside it is physically excluded; the prior centre before any data)."""
        prior = self.system.theta
        if self.estimator.nsamples == 0:
            return prior.center
        return np.clip(self.estimator.ellipsoid().center, prior.low, prior.high)


class _Learner:
    """What the robust planner knows: surviving hypotheses and their parameter boxes.

    Online (``frozen`` False) it is fed every measured transition; frozen, it is fitted
    once on prior data and never changes.

    The LP boxes are refitted on all the data only when it has grown by a factor
    ``refit_growth`` since the last fit (or the survivors changed), so the total LP
    work over an episode is O(N log N) instead of O(N^2). In between, the last box is
    used: still sound, because the set of parameters consistent with more data is a
    subset of the set consistent with less.
    """

    refit_growth = 1.25

    def __init__(self, hypotheses, noise: float, prior: tuple | None):
        self.hypotheses = hypotheses
        self.noise = noise
        self.selector = ModelSelector([h.system for h in hypotheses], measurement_noise=noise)
        self.states: list = []
        self.controls: list = []
        self.frozen = prior is not None
        if prior is not None:
            X, U = prior
            self.states, self.controls = list(X), list(U)
            for n in range(U.shape[0]):
                self.selector.add(X[n], U[n], X[n + 1])
        self._boxes: list[tuple[int, Box]] | None = None
        self._fitted_on = 0  # transitions behind the current boxes

    def add(self, x, u, x_next) -> None:
        if self.frozen:
            return
        if not self.states:
            self.states.append(x)
        self.controls.append(u)
        self.states.append(x_next)
        self.selector.add(x, u, x_next)

    def survivors_with_boxes(self) -> list[tuple[int, Box]]:
        """``(index, feasible parameter box)`` of every surviving hypothesis.

        Raises `NoConsistentModel` when the data contradicts every hypothesis.
        """
        if not self.selector.survivors:
            names = ", ".join(h.name for h in self.hypotheses)
            raise NoConsistentModel(
                f"every hypothesis ({names}) is contradicted by the {len(self.controls)} transitions observed"
            )
        n = len(self.controls)
        boxes = self._boxes
        stale = boxes is None or [i for i, _ in boxes] != self.selector.survivors
        if boxes is None or stale or n >= self.refit_growth * self._fitted_on + 1:
            X, U = np.array(self.states).reshape(-1, 4), np.array(self.controls).reshape(-1, 2)
            self._fitted_on = n
            boxes = [
                (
                    i,
                    feasible_parameter_box(self.hypotheses[i].system, X, U, measurement_noise=self.noise)
                    if U.shape[0]
                    else self.hypotheses[i].system.theta,
                )
                for i in self.selector.survivors
            ]
            self._boxes = boxes
        return boxes


def _outward(corners: np.ndarray, direction: int) -> list:
    """Box corners rounded outward to 0.1 mm (``direction`` -1: lower, +1: upper), as lists."""
    scaled = np.asarray(corners, dtype=float) * 1e4
    return ((np.ceil(scaled) if direction > 0 else np.floor(scaled)) / 1e4).tolist()


class _HeldControl:
    """A baseline's control, held for one decision period."""

    def __init__(self, u):
        self.u = np.asarray(u, dtype=float)

    def control(self, x):
        return self.u


class _Saturated:
    """A policy's control clipped to the robot's control box ``[-bound, bound]^2``."""

    def __init__(self, policy, bound: float):
        self.policy = policy
        self.bound = bound

    def control(self, measurement: np.ndarray) -> np.ndarray:
        return np.clip(self.policy.control(measurement), -self.bound, self.bound)


class _Predicted:
    """A policy and the boxes predicted for the sub-steps of its decision (a `PredictingPolicy`).

    ``boxes[k - 1]`` maps each name to the box ``(lower, upper)`` predicted after
    sub-step k; the control is the wrapped policy's, unchanged.
    """

    def __init__(self, policy: Policy, boxes: list[dict[str, tuple[np.ndarray, np.ndarray]]]):
        self.policy = policy
        self.boxes = boxes

    def control(self, measurement: np.ndarray) -> np.ndarray:
        return self.policy.control(measurement)

    def predicted_boxes(self, substep: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        return self.boxes[substep - 1]


class RobotMethod(Method[RobotWorld]):
    """What every robot method shares: the velocity controllers and the global path's waypoint.

    Parameters
    ----------
    scenario
        A `RobotScenario`; anything else raises `UnsupportedScenario`.
    config
        The loop settings (budget, gamma, speed, gain, lookahead, path clearance, ...).

    Notes
    -----
    A subclass implements `plan`, which gets the measurement and the waypoint of this
    decision and returns the (unsaturated) policy; `decide` saturates it.
    """

    def __init__(self, scenario: RobotScenario, config: LoopConfig):
        if not isinstance(scenario, RobotScenario):
            raise UnsupportedScenario(
                f"{type(self).__name__} drives only RobotScenario worlds, got {type(scenario).__name__}"
            )
        self.scenario = scenario
        self.config = config

    def start(self, world: RobotWorld) -> None:
        """Keep the world; build the velocity controllers and the global path of its map.

        Parameters
        ----------
        world : RobotWorld
            The episode's world.
        """
        self.world = world
        self.params = world.params
        self.controllers = velocity_controllers(self.config, self.params.control_bound)
        self.global_path = self.scenario.global_path(world, self.params.robot_radius + self.config.path_clearance)

    def decide(self, measurement: np.ndarray) -> Policy:
        """`plan` towards the waypoint ``lookahead`` m along the global path, saturated.

        Parameters
        ----------
        measurement : numpy.ndarray
            The measured state ``(px, py, vx, vy)``, shape (4,), m and m/s.
        """
        waypoint = self.global_path.waypoint(measurement[:2], self.config.lookahead)
        return _Saturated(self.plan(measurement, waypoint), self.params.control_bound)

    def plan(self, measurement: np.ndarray, waypoint: np.ndarray) -> Policy:  # pragma: no cover - abstract
        """The policy for this decision, towards ``waypoint`` (unsaturated: `decide` saturates it).

        Parameters
        ----------
        measurement : numpy.ndarray
            The measured state ``(px, py, vx, vy)``, shape (4,), m and m/s.
        waypoint : numpy.ndarray
            Shape (2,), m: the point ``lookahead`` m along the global path.
        """
        raise NotImplementedError

    def report(self) -> dict:
        """No Assumption 4 report and no predicted boxes (the robust method has both)."""
        return {"lmi": None, "plans": []}


class RobustMethod(RobotMethod):
    """The proposed planner: model elimination, LP parameter boxes, robust tree search.

    Notes
    -----
    `ModelSelector` over the scenario's hypotheses (with the errata's inflation for the
    bounded measurement noise), the LP `feasible_parameter_box` of every survivor as its
    parameter polytope, and `RobustTreePlanner` over one `IntervalModel` per survivor
    (eqs. (16)-(18)), rooted at the measurement box. The Assumption 4 report is made once
    per episode, on the first survivor's box.

    When the tree's best plan may collide within `LATEST_COLLISION_DECISIONS` decisions
    (its lower bounds then often tie, and a tie goes to the smallest action index), the
    executed action is the first action whose plans stay clear of every box longest
    under every survivor (`latest_collision_action`); ``latest_collision = False`` turns
    the rule off (the tree's action always), for comparisons.
    """

    #: Whether the latest-possible-collision rule overrides the tree (see above).
    latest_collision = True

    def start(self, world: RobotWorld) -> None:
        """`RobotMethod.start`, then the learner (fitted on excitation data if ``prior_samples``) and planning systems.

        Parameters
        ----------
        world : RobotWorld
            The episode's world.
        """
        super().start(world)
        self.noise = self.params.measurement_noise
        hypotheses = self.scenario.hypotheses(world)
        prior = None if self.config.prior_samples is None else excitation_data(world, self.config.prior_samples)
        self.learner = _Learner(hypotheses, self.noise, prior)
        self.planning = [planning_system(h.system, self.config.gain * self.noise) for h in hypotheses]
        self.lmi: dict | None = None
        self.plans: list = []
        self.decisions: list[dict] = []

    def plan(self, measurement: np.ndarray, waypoint: np.ndarray) -> Policy:
        """The robust tree search's action over the survivors' parameter boxes, from the measurement box.

        See `RobotMethod.plan`. Raises `EpisodeFailure` ("no_consistent_model") once the
        data contradicts every hypothesis.

        Parameters
        ----------
        measurement : numpy.ndarray
            The measured state ``(px, py, vx, vy)``, shape (4,), m and m/s.
        waypoint : numpy.ndarray
            Shape (2,), m: the point ``lookahead`` m along the global path.
        """
        world, config = self.world, self.config
        t = world.step_index
        try:
            survivors = self.learner.survivors_with_boxes()
        except NoConsistentModel as exc:
            raise EpisodeFailure("no_consistent_model", str(exc)) from exc
        pairs = [(self.planning[i], box) for i, box in survivors]
        if self.lmi is None:
            self.lmi = assumption4_report(world.system, pairs[0][1])
        objective = self.scenario.objective(world, waypoint, uncertain=True)
        planner = multi_model_robust_planner(
            pairs,
            objective,
            self.controllers,
            gamma=config.gamma,
            budget=config.budget,
            substeps=self.params.substeps,
        )
        root = root_state(planner, *measurement_box(measurement, self.noise), time=t)
        decision = planner.plan(root)
        action, latest = int(decision.action_index), None
        if self.latest_collision:
            horizon = LATEST_COLLISION_DECISIONS * self.params.substeps
            action, latest = latest_collision_action(planner.models, root, decision, horizon=horizon)
        sequence = decision.sequence_indices if action == decision.action_index else (action,)
        lower, upper, _, _ = planner.models[0].rollout(root, sequence)
        self.plans.append((t, lower[:, :2].tolist(), upper[:, :2].tolist()))
        trace = self._decision_trace(t, lower, upper, survivors, action)
        trace.update(tree_action=int(decision.action_index), latest_collision=latest)
        self.decisions.append(trace)
        assert objective.moving_obstacles is not None  # GoalReward makes None MovingObstacles.empty()
        self._predicted = self.executed_boxes(planner, root, action, objective.moving_obstacles)
        return self.controllers[action]

    def decide(self, measurement: np.ndarray) -> PredictingPolicy:
        """`RobotMethod.decide`, with the boxes predicted for the executed action's sub-steps.

        Parameters
        ----------
        measurement : numpy.ndarray
            The measured state ``(px, py, vx, vy)``, shape (4,), m and m/s.
        """
        policy = super().decide(measurement)
        return _Predicted(policy, self._predicted)

    def executed_boxes(
        self, planner: RobustTreePlanner, root: BoxState, action: int, pedestrians: MovingObstacles
    ) -> list[dict[str, tuple[np.ndarray, np.ndarray]]]:
        """What the planner predicted after each sub-step of the executed ``action``.

        Parameters
        ----------
        planner : RobustTreePlanner
            This decision's planner (one linked `IntervalModel` per surviving hypothesis).
        root : BoxState
            Its root: the measurement box at the decision's sub-step index t.
        action : int
            The executed action.
        pedestrians : MovingObstacles
            The pedestrians' prediction the planner's reward used (``time0 = t``).

        Returns
        -------
        list of dict
            Entry k - 1 (k = 1..substeps) maps ``"robot"`` to the hull over the surviving
            hypotheses of their boxes after sub-step k (`IntervalModel.rollout`, rounded
            outward), and ``"pedestrian j"`` to pedestrian j's centre box at sub-step
            t + k (`MovingObstacles.boxes`).

        Notes
        -----
        The true hypothesis is never eliminated (the LP test is sound), so the true state
        lies in its own box, hence in the hull (inclusion property (7) with the LP
        parameter box). The pedestrians' boxes hold their true positions because their
        velocities stay within the announced ones +- the velocity uncertainty.
        """
        S = self.params.substeps
        rollouts = [model.rollout(root, [action]) for model in planner.models]
        lower = np.min([r[0][1:] for r in rollouts], axis=0)
        upper = np.max([r[1][1:] for r in rollouts], axis=0)
        boxes: list[dict[str, tuple[np.ndarray, np.ndarray]]] = [{"robot": (lower[k], upper[k])} for k in range(S)]
        if len(pedestrians):
            ped_lower, ped_upper = pedestrians.boxes(root.time + np.arange(1, S + 1))
            for k in range(S):
                for j in range(len(pedestrians)):
                    boxes[k][f"pedestrian {j}"] = (ped_lower[k, j], ped_upper[k, j])
        return boxes

    def _decision_trace(self, t: int, lower: np.ndarray, upper: np.ndarray, survivors, action: int) -> dict:
        """What the animation shows of a decision: the executed plan's position boxes, the
        pedestrians' predicted boxes over the same sub-steps and the surviving hypotheses."""
        peds = self.world.pedestrians
        steps = t + np.arange(lower.shape[0])
        ped_lower, ped_upper = peds.boxes(steps) if len(peds) else (np.zeros((len(steps), 0, 2)),) * 2
        return {
            "step": int(t),
            "action": int(action),
            "lower": _outward(lower[:, :2], -1),
            "upper": _outward(upper[:, :2], 1),
            "pedestrian_lower": _outward(ped_lower - peds.radii[:, None], -1),
            "pedestrian_upper": _outward(ped_upper + peds.radii[:, None], 1),
            "survivors": [self.learner.hypotheses[i].name for i, _ in survivors],
        }

    def observe(self, transition: Transition) -> None:
        """Feed the learner the measured transition (ignored when it was fitted on prior data).

        Parameters
        ----------
        transition : Transition
            The measured state before the sub-step, the control applied and the
            measured state after it.
        """
        self.learner.add(*transition)

    def report(self) -> dict:
        """The Assumption 4 report, every eighth plan's boxes (``plans``) and every decision's
        trace (``decisions``: plan boxes, pedestrians' predicted boxes, survivors, the tree's action
        ``tree_action`` and the rule's figures ``latest_collision``, see `latest_collision_action`)."""
        plans = self.plans
        return {
            "lmi": self.lmi,
            "plans": plans[:: max(1, len(plans) // 8)] if plans else [],
            "decisions": self.decisions,
        }


class OracleMethod(RobotMethod):
    """OPD on the true friction (w = 0): the reference of the suboptimality study."""

    def theta(self) -> np.ndarray:
        """The friction the planner's model uses."""
        return self.world.true_theta

    def plan(self, measurement: np.ndarray, waypoint: np.ndarray) -> Policy:
        """OPD's action on the nominal model at `theta` (w = 0), from the measured state.

        Parameters
        ----------
        measurement : numpy.ndarray
            The measured state ``(px, py, vx, vy)``, shape (4,), m and m/s.
        waypoint : numpy.ndarray
            Shape (2,), m: the point ``lookahead`` m along the global path.
        """
        world, config = self.world, self.config
        planner = nominal_planner(
            world.system,
            self.theta(),
            self.scenario.objective(world, waypoint, uncertain=False),
            self.controllers,
            gamma=config.gamma,
            budget=config.budget,
            substeps=self.params.substeps,
        )
        return self.controllers[planner.plan(root_state(planner, measurement, time=world.step_index)).action]


class NominalMethod(OracleMethod):
    """Certainty equivalence: OPD on the least-squares friction estimate (w = 0), the
    pedestrians at their announced velocities."""

    def start(self, world: RobotWorld) -> None:
        """`RobotMethod.start`, then the least-squares estimator (fed the excitation data if ``prior_samples``).

        Parameters
        ----------
        world : RobotWorld
            The episode's world.
        """
        super().start(world)
        self.lsq = _LeastSquares(world.system, self.config.lsq_regularisation)
        prior_samples = self.config.prior_samples
        self.learning = prior_samples is None
        if prior_samples is not None:
            X, U = excitation_data(world, prior_samples)
            for n in range(U.shape[0]):
                self.lsq.add(X[n], U[n], X[n + 1])

    def theta(self) -> np.ndarray:
        """The least-squares friction estimate, clipped to the prior box (its centre before any data)."""
        return self.lsq.estimate()

    def observe(self, transition: Transition) -> None:
        """Add the measured transition to the least-squares estimate (not when learning from prior data only).

        Parameters
        ----------
        transition : Transition
            The measured state before the sub-step, the control applied and the
            measured state after it.
        """
        if self.learning:
            self.lsq.add(*transition)


class DWAMethod(RobotMethod):
    """The dynamic window baseline on the nominal model at the centre of the prior box.

    It gets the same noisy measurements and the pedestrians' current positions and
    announced velocities, and does not learn the friction (like the ROS local planners).
    """

    baseline: type[DynamicWindowPlanner] | type[TimedElasticBand] = DynamicWindowPlanner

    def start(self, world: RobotWorld) -> None:
        """`RobotMethod.start`, then the baseline planner on the nominal model at the prior box's centre.

        Parameters
        ----------
        world : RobotWorld
            The episode's world.
        """
        super().start(world)
        self.planner = self.baseline(
            world.system,
            theta=world.system.theta.center,
            substeps=self.params.substeps,
            robot_radius=self.params.robot_radius,
            control_bound=self.params.control_bound,
        )

    def plan(self, measurement: np.ndarray, waypoint: np.ndarray) -> Policy:
        """The baseline's control on the scene towards ``waypoint``, held for the decision.

        Parameters
        ----------
        measurement : numpy.ndarray
            The measured state ``(px, py, vx, vy)``, shape (4,), m and m/s.
        waypoint : numpy.ndarray
            Shape (2,), m: the point ``lookahead`` m along the global path.
        """
        return _HeldControl(self.planner.plan(measurement, self.scenario.scene(self.world, waypoint)))


class TEBMethod(DWAMethod):
    """The timed elastic band baseline; see `DWAMethod`."""

    baseline = TimedElasticBand


register_method("robust", RobustMethod)
register_method("nominal", NominalMethod)
register_method("oracle", OracleMethod)
register_method("dwa", DWAMethod)
register_method("teb", TEBMethod)
