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
    OPD on the true friction (w = 0): the reference of the suboptimality study.
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
"""

from __future__ import annotations

import time as wallclock
from dataclasses import dataclass, field

import numpy as np

from minimaxplan.models import Box, ConfidenceEllipsoidEstimator, NoConsistentModel, UncertainLinearSystem
from minimaxplan.planners.comparison import multi_model_robust_planner, nominal_planner, root_state
from minimaxplan.planners.controllers import LinearFeedback
from minimaxplan.planners.dwa import DynamicWindowPlanner, NavigationScene
from minimaxplan.planners.teb import TimedElasticBand
from minimaxplan.scenarios import MovingObstacles, make_world, robot_hypotheses
from minimaxplan.verify.lmi import check_assumption4
from minimaxplan.verify.selection import ModelSelector, feasible_parameter_box

from .experiment import EpisodeRecord

__all__ = ["LoopConfig", "velocity_controllers", "planning_system", "assumption4_report", "run_episode"]


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
    record_suboptimality
        Also run the oracle planner at every decision of the robust method (Figure 6).
    measurement
        "uniform" (bounded, inside the guarantees) or "gaussian" (outside).
    """

    budget: int = 100
    gamma: float = 0.9
    speed: float = 1.5
    gain: float = 3.0
    record_suboptimality: bool = True
    measurement: str = "uniform"
    lsq_regularisation: float = 1e-3
    directions: tuple = field(default=((1, 1), (1, -1), (-1, 1), (-1, -1), (0, 0)))


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
    """Friction estimate of the true structure from measured transitions (for nominal and baselines)."""

    def __init__(self, system: UncertainLinearSystem, regularisation: float):
        self.system = system
        self.estimator = ConfidenceEllipsoidEstimator(
            system.nparams, sigma=1.0, lam=regularisation, delta=0.1, bound=float(np.linalg.norm(system.theta.high))
        )

    def add(self, x, u, x_next) -> None:
        target = x_next - self.system.A0 @ x - self.system.B @ u
        self.estimator.update(self.system.regressor(x), target)

    def estimate(self) -> np.ndarray:
        prior = self.system.theta
        if self.estimator.nsamples == 0:
            return prior.center
        return np.clip(self.estimator.ellipsoid().center, prior.low, prior.high)


def _truncated_return(rewards: list[float], start: int, horizon: int, gamma: float, outcome: str) -> float:
    """``sum_{n < horizon} gamma^n r_{start + n}``; past the end of the episode the robot
    stays where it ended and keeps its last reward (0 after a collision)."""
    last = 0.0 if outcome == "collision" or not rewards else rewards[-1]
    padded = [rewards[start + n] if start + n < len(rewards) else last for n in range(horizon)]
    return float(sum(gamma**n * r for n, r in enumerate(padded)))


def run_episode(scenario: str, method: str, seed: int, config: LoopConfig = DEFAULT_CONFIG) -> EpisodeRecord:
    """Run one episode of ``method`` in the world ``make_world(scenario, seed)``.

    A failure is a collision, a timeout, or `NoConsistentModel` (robust method: every
    hypothesis eliminated). Returns an `EpisodeRecord` whose ``discounted_return`` is
    ``sum_i gamma^i r_i`` over the decisions, ``r_i`` the smallest true reward over the
    sub-steps of decision i (the quantity the surrogate bounds, Theorem 1).
    """
    started = wallclock.perf_counter()
    world = make_world(scenario, seed, measurement=config.measurement)
    params = world.params
    controllers = velocity_controllers(config, params.control_bound)
    hypotheses = robot_hypotheses(params.dt, params)
    noise = params.measurement_noise
    selector = ModelSelector([h.system for h in hypotheses], measurement_noise=noise) if method == "robust" else None
    lsq = _LeastSquares(world.system, config.lsq_regularisation)
    planning = [planning_system(h.system, config.gain * noise) for h in hypotheses]
    oracle_needed = method == "oracle" or (method == "robust" and config.record_suboptimality)
    baseline = _make_baseline(method, world) if method in ("dwa", "teb") else None
    states, controls = [world.measure()], []
    rewards, positions, plans, subopt_points = [], [world.state[:2].copy()], [], []
    outcome = None
    lmi = None
    while not world.done:
        x = states[-1]
        t = world.step_index
        n_obs = len(controls)
        oracle_value = None
        if oracle_needed:
            reward = world.goal_reward.with_obstacles(moving_obstacles=_pedestrian_prediction(world, uncertain=False))
            oracle = nominal_planner(world.system, world.true_theta, reward, controllers,
                                     gamma=config.gamma, budget=config.budget, substeps=params.substeps)
            oracle_decision = oracle.plan(root_state(oracle, x, time=t))
            oracle_value = (oracle_decision.lower, len(oracle_decision.sequence))
        if method == "robust":
            survivors = selector.survivors
            if not survivors:
                outcome = "no_consistent_model"
                break
            X, U = np.array(states), np.array(controls).reshape(-1, 2)
            pairs = []
            for i in survivors:
                box = feasible_parameter_box(hypotheses[i].system, X, U, measurement_noise=noise) if U.shape[0] else hypotheses[i].system.theta
                pairs.append((planning[i], box))
            if lmi is None:
                lmi = assumption4_report(world.system, pairs[0][1])
            reward = world.goal_reward.with_obstacles(moving_obstacles=_pedestrian_prediction(world, uncertain=True))
            planner = multi_model_robust_planner(pairs, reward, controllers, gamma=config.gamma,
                                                 budget=config.budget, substeps=params.substeps)
            decision = planner.plan(root_state(planner, x - noise, x + noise, time=t))
            controller = controllers[decision.action]
            lower, upper, _, _ = planner.models[0].rollout(root_state(planner, x - noise, x + noise, time=t), decision.sequence)
            plans.append((t, lower[:, :2].tolist(), upper[:, :2].tolist()))
        elif method in ("nominal", "oracle"):
            theta = world.true_theta if method == "oracle" else lsq.estimate()
            reward = world.goal_reward.with_obstacles(moving_obstacles=_pedestrian_prediction(world, uncertain=False))
            planner = nominal_planner(world.system, theta, reward, controllers, gamma=config.gamma,
                                      budget=config.budget, substeps=params.substeps)
            decision = planner.plan(root_state(planner, x, time=t))
            controller = controllers[decision.action]
        else:
            controller = _HeldControl(baseline.plan(x, _scene(world)))
        if oracle_value is not None and method == "robust":
            subopt_points.append((n_obs, oracle_value))
        worst = 1.0
        for _ in range(params.substeps):
            u = np.clip(controller.control(x), -params.control_bound, params.control_bound)
            world.apply(u)
            positions.append(world.state[:2].copy())
            worst = min(worst, world.reward())
            x_next = world.measure()
            controls.append(u)
            states.append(x_next)
            if selector is not None:
                selector.add(x, u, x_next)
            lsq.add(x, u, x_next)
            x = x_next
            if world.done:
                break
        rewards.append(worst)
    outcome = outcome or world.outcome
    # Figure 6: the oracle's value over its look-ahead depth d (its lower bound: the
    # discounted sum along its best d-step sequence, w = 0) minus the return the robust
    # planner actually collected over the same d decisions from that state.
    suboptimality = tuple(
        (n, value - _truncated_return(rewards, i, depth, config.gamma, outcome))
        for i, (n, (value, depth)) in enumerate(subopt_points)
        if i < len(rewards)
    )
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
        suboptimality=suboptimality,
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


def _scene(world) -> NavigationScene:
    peds = world.pedestrians
    return NavigationScene(
        goal=world.goal,
        obstacle_centers=world.obstacles.centers,
        obstacle_radii=world.obstacles.radii,
        pedestrian_positions=peds.positions,
        pedestrian_velocities=peds.velocities,
        pedestrian_radii=peds.radii,
    )
