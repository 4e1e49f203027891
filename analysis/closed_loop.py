"""The closed loop of the paper's Figure 1, one seeded episode at a time.

measure -> (online estimation, model elimination, parameter boxes) -> robust tree
search over the surviving hypotheses -> low-level controller for one decision period
-> the world steps -> measure ...

Methods
-------
robust
    The proposed planner: `ModelSelector` over `robot_hypotheses` (with the errata's
    inflation for the bounded measurement noise), the LP `feasible_parameter_box` of
    every survivor as its parameter polytope, and `RobustTreePlanner` over one
    `IntervalModel` per survivor (K = 100, gamma = 0.9). The Assumption 4 report is
    made once per episode (see `assumption4_report`).
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

import time as wallclock
from dataclasses import dataclass, field

import numpy as np

from minimaxplan.models import Box, ConfidenceEllipsoidEstimator, InputError, NoConsistentModel, UncertainLinearSystem
from minimaxplan.models._validation import as_positive_scalar
from minimaxplan.planners.comparison import multi_model_robust_planner, nominal_planner, root_state
from minimaxplan.planners.controllers import LinearFeedback
from minimaxplan.planners.dwa import DynamicWindowPlanner, NavigationScene
from minimaxplan.planners.navigation import NavigationFunction
from minimaxplan.planners.teb import TimedElasticBand
from minimaxplan.scenarios import GoalReward, MovingObstacles, make_world, robot_hypotheses
from minimaxplan.verify.lmi import check_assumption4
from minimaxplan.verify.selection import ModelSelector, feasible_parameter_box

from .experiment import METHODS, EpisodeRecord

__all__ = [
    "LoopConfig",
    "velocity_controllers",
    "planning_system",
    "measurement_box",
    "assumption4_report",
    "excitation_data",
    "run_episode",
]


@dataclass(frozen=True)
class LoopConfig:
    """Settings of the closed loop (the paper's K = 100 and gamma = 0.9 by default).

    Attributes
    ----------
    budget, gamma
        Planner expansions per decision and discount.
    speed
        Speed of the diagonal velocity references, m/s.
    gain
        Velocity feedback gain k of the low-level controllers, 1/s.
    prior_samples
        None: learn online from the episode's own transitions. N: learn only from N
        transitions of excitation data recorded beforehand (same robot, random
        controls from rest), then keep the parameter sets fixed: the Figure 6 study.
    max_decisions
        Stop after this many decisions (outcome "horizon" if still running).
    measurement
        "uniform" (bounded, inside the guarantees) or "gaussian" (outside).
    lookahead, path_clearance
        The waypoint chased is ``lookahead`` m along the global path, which keeps
        ``robot_radius + path_clearance`` m from the static discs.
    """

    budget: int = 100
    gamma: float = 0.9
    speed: float = 1.5
    gain: float = 3.0
    prior_samples: int | None = None
    max_decisions: int | None = None
    measurement: str = "uniform"
    lsq_regularisation: float = 1e-3
    lookahead: float = 3.0
    path_clearance: float = 0.3
    directions: tuple = field(default=((1, 1), (1, -1), (-1, 1), (-1, -1), (0, 0)))

    def __post_init__(self) -> None:
        if isinstance(self.budget, bool) or not isinstance(self.budget, int) or self.budget < 1:
            raise InputError(f"budget must be a positive integer, got {self.budget!r}")
        if not 0.0 < float(self.gamma) < 1.0:
            raise InputError(f"gamma must lie in (0, 1), got {self.gamma!r}")
        for name in ("speed", "gain", "lsq_regularisation", "lookahead"):
            as_positive_scalar(name, getattr(self, name))
        as_positive_scalar("path_clearance", self.path_clearance, allow_zero=True)
        for name in ("prior_samples", "max_decisions"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
                raise InputError(f"{name} must be None or a positive integer, got {value!r}")
        if self.measurement not in ("uniform", "gaussian"):
            raise InputError(f"measurement must be 'uniform' or 'gaussian', got {self.measurement!r}")
        if not self.directions or any(np.shape(d) != (2,) for d in self.directions):
            raise InputError(f"directions must be a non-empty sequence of 2-vectors, got {self.directions!r}")


DEFAULT_CONFIG = LoopConfig()


def velocity_controllers(config: LoopConfig, control_bound: float = 1.0) -> list[LinearFeedback]:
    """One saturated velocity-tracking controller per direction: ``v_ref = speed * direction``."""
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
    """
    D = np.hstack([system.D, system.B])
    w = Box(
        np.concatenate([system.w.low, np.full(system.ninputs, -control_error)]),
        np.concatenate([system.w.high, np.full(system.ninputs, control_error)]),
    )
    return UncertainLinearSystem(system.A0, system.phi, system.B, D=D, w=w, theta=system.theta)


def assumption4_report(system: UncertainLinearSystem, parameters: Box) -> dict:
    """Assumption 4 once per episode: the full model and its velocity subsystem.

    The full open-loop model has two integrators (eigenvalue 1 in discrete time), so
    the discrete LMI is infeasible there and Theorem 2's bound does not apply; the
    velocity block ``I - dt diag(theta)`` is Schur for every friction in the box, and
    a common certificate over the box's vertices is sought.
    """
    vertices = parameters.vertices()
    full = check_assumption4([system.A(v) for v in vertices], form="discrete", D=system.D)
    velocity = check_assumption4([system.A(v)[2:, 2:] for v in vertices], form="discrete", D=system.D[2:])
    return {
        "full_model": full.status,
        "full_model_note": "integrators: infeasible is expected and Theorem 2 does not apply",
        "velocity_subsystem": velocity.status,
        "velocity_certified": bool(velocity.certified),
    }


def _pedestrian_prediction(world, uncertain: bool) -> MovingObstacles:
    peds = world.pedestrians
    if uncertain:
        return peds
    return MovingObstacles(peds.positions, peds.velocities, peds.radii, dt=peds.dt, time0=peds.time0)


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


def _global_path(world, clearance: float) -> NavigationFunction:
    """The static map's cost-to-go to the goal, on a grid covering the whole arena."""
    size = world.params.arena_size
    region = np.array([world.start, [0.0, 0.0], [size, size]])
    return NavigationFunction(world.goal, world.obstacles.centers, world.obstacles.radii, clearance=clearance,
                              region=region, padding=3.0)


def measurement_box(measured: np.ndarray, noise: float) -> tuple[np.ndarray, np.ndarray]:
    """The box ``measured +- noise`` that holds the true state, rounded outward.

    The measurement itself was rounded (``fl(x + v)``, error up to half an ulp of
    ``|measured|``) and so is ``measured -+ noise``: a margin of ``2 eps (|measured| +
    noise)`` covers both, whatever the magnitudes of x and v.
    """
    margin = 2 * np.finfo(float).eps * (np.abs(measured) + noise)
    return np.nextafter(measured - noise - margin, -np.inf), np.nextafter(measured + noise + margin, np.inf)


def _objective(world, waypoint, uncertain: bool) -> GoalReward:
    """The reward a planner maximises at this decision: reach ``waypoint`` without touching
    the static discs or the pedestrians (predicted boxes if ``uncertain``, else points
    moving at their announced velocities)."""
    return GoalReward(waypoint, obstacles=world.obstacles, robot_radius=world.params.robot_radius,
                      moving_obstacles=_pedestrian_prediction(world, uncertain) if len(world.crowd) else None)


def excitation_data(world, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` measured transitions of the episode's robot under random controls from rest,
    recorded before the episode (seeded by the world's seed; same noise model).

    Returns measured states (n + 1, 4) and controls (n, 2).
    """
    rng = np.random.default_rng(np.random.SeedSequence([world.seed, 0x5EED]))
    params = world.params
    x = np.zeros(4)
    states, controls = [x + rng.uniform(-params.measurement_noise, params.measurement_noise, 4)], []
    for _ in range(n):
        u = rng.uniform(-params.control_bound, params.control_bound, 2)
        w = rng.uniform(-params.disturbance_bound, params.disturbance_bound, 2)
        x = world.system.step(x, u, world.true_theta, w)
        controls.append(u)
        states.append(x + rng.uniform(-params.measurement_noise, params.measurement_noise, 4))
    return np.array(states), np.array(controls).reshape(n, 2)


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
        self._boxes = None
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
        stale = self._boxes is None or [i for i, _ in self._boxes] != self.selector.survivors
        if stale or n >= self.refit_growth * self._fitted_on + 1:
            X, U = np.array(self.states).reshape(-1, 4), np.array(self.controls).reshape(-1, 2)
            self._fitted_on = n
            self._boxes = [
                (i, feasible_parameter_box(self.hypotheses[i].system, X, U, measurement_noise=self.noise)
                 if U.shape[0] else self.hypotheses[i].system.theta)
                for i in self.selector.survivors
            ]
        return self._boxes


def run_episode(scenario: str, method: str, seed: int, config: LoopConfig = DEFAULT_CONFIG) -> EpisodeRecord:
    """Run one episode of ``method`` in the world ``make_world(scenario, seed)``.

    A failure is a collision, a timeout, or `NoConsistentModel` (robust method: every
    hypothesis eliminated). Every method chases the same waypoints of a global path on
    the static map. ``discounted_return`` is ``sum_i gamma^i r_i`` over the decisions,
    ``r_i`` the smallest true goal reward over the sub-steps of decision i.
    """
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    if not isinstance(config, LoopConfig):
        raise InputError(f"config must be a LoopConfig, got {type(config).__name__}")
    started = wallclock.perf_counter()
    world = make_world(scenario, seed, measurement=config.measurement)
    params = world.params
    controllers = velocity_controllers(config, params.control_bound)
    hypotheses = robot_hypotheses(params.dt, params)
    noise = params.measurement_noise
    prior = None if config.prior_samples is None else excitation_data(world, config.prior_samples)
    learner = _Learner(hypotheses, noise, prior) if method == "robust" else None
    lsq = _LeastSquares(world.system, config.lsq_regularisation) if method == "nominal" else None
    if lsq is not None and prior is not None:
        for n in range(prior[1].shape[0]):
            lsq.add(prior[0][n], prior[1][n], prior[0][n + 1])
    planning = [planning_system(h.system, config.gain * noise) for h in hypotheses]
    global_path = _global_path(world, params.robot_radius + config.path_clearance)
    baseline = _make_baseline(method, world) if method in ("dwa", "teb") else None
    x = world.measure()
    rewards, positions, plans = [], [world.state[:2].copy()], []
    outcome = None
    lmi = None
    while not world.done:
        if config.max_decisions is not None and len(rewards) >= config.max_decisions:
            outcome = "horizon"
            break
        t = world.step_index
        waypoint = global_path.waypoint(x[:2], config.lookahead)
        if method == "robust":
            try:
                survivors = learner.survivors_with_boxes()
            except NoConsistentModel:
                outcome = "no_consistent_model"  # a failure of the episode, not an error of the run
                break
            pairs = [(planning[i], box) for i, box in survivors]
            if lmi is None:
                lmi = assumption4_report(world.system, pairs[0][1])
            planner = multi_model_robust_planner(pairs, _objective(world, waypoint, uncertain=True), controllers,
                                                 gamma=config.gamma, budget=config.budget, substeps=params.substeps)
            root = root_state(planner, *measurement_box(x, noise), time=t)
            decision = planner.plan(root)
            controller = controllers[decision.action]
            lower, upper, _, _ = planner.models[0].rollout(root, decision.sequence)
            plans.append((t, lower[:, :2].tolist(), upper[:, :2].tolist()))
        elif method in ("nominal", "oracle"):
            theta = world.true_theta if method == "oracle" else lsq.estimate()
            planner = nominal_planner(world.system, theta, _objective(world, waypoint, uncertain=False), controllers,
                                      gamma=config.gamma, budget=config.budget, substeps=params.substeps)
            controller = controllers[planner.plan(root_state(planner, x, time=t)).action]
        else:
            controller = _HeldControl(baseline.plan(x, _scene(world, waypoint)))
        worst = 1.0
        for _ in range(params.substeps):
            u = np.clip(controller.control(x), -params.control_bound, params.control_bound)
            world.apply(u)
            positions.append(world.state[:2].copy())
            worst = min(worst, world.reward())
            x_next = world.measure()
            if learner is not None:
                learner.add(x, u, x_next)
            if lsq is not None and prior is None:
                lsq.add(x, u, x_next)
            x = x_next
            if world.done:
                break
        rewards.append(worst)
    outcome = outcome or world.outcome
    discounted = float(sum(config.gamma**i * r for i, r in enumerate(rewards)))
    return EpisodeRecord(
        scenario=scenario,
        method=method,
        seed=int(seed),
        outcome=outcome,
        time_s=float(world.time),
        discounted_return=discounted,
        decisions=len(rewards),
        wall_time_s=wallclock.perf_counter() - started,
        trajectory=tuple(map(tuple, np.round(positions, 4).tolist())),
        extra={"lmi": lmi, "plans": plans[:: max(1, len(plans) // 8)] if plans else [], "world": world.to_dict()},
    )


class _HeldControl:
    """A baseline's control, held for one decision period."""

    def __init__(self, u):
        self.u = np.asarray(u, dtype=float)

    def control(self, x):
        return self.u


def _make_baseline(method: str, world):
    cls = DynamicWindowPlanner if method == "dwa" else TimedElasticBand
    return cls(world.system, theta=world.system.theta.center, substeps=world.params.substeps,
               robot_radius=world.params.robot_radius, control_bound=world.params.control_bound)


def _scene(world, waypoint) -> NavigationScene:
    peds = world.pedestrians
    return NavigationScene(
        goal=waypoint,
        obstacle_centers=world.obstacles.centers,
        obstacle_radii=world.obstacles.radii,
        pedestrian_positions=peds.positions,
        pedestrian_velocities=peds.velocities,
        pedestrian_radii=peds.radii,
    )
