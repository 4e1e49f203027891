"""The robot navigation scenarios ("static", "pedestrian") and what its methods share.

`RobotScenario` makes the seeded `RobotWorld`s of `minimaxplan.scenarios`; it also knows
the robot's structural hypotheses, the global path (the static map's cost-to-go), the
planners' objective with the pedestrians (predicted boxes or announced velocities), the
navigation scene of the baselines, the excitation data of the Figure 6 study and the
Assumption 4 report on the velocity subsystem. The methods that drive it are in
`minimaxplan.analysis.robot_methods`.

Importing this module registers one scenario per world kind (`WORLD_KINDS`).
"""

from __future__ import annotations

import functools

import numpy as np

from minimaxplan.models import Box, UncertainLinearSystem
from minimaxplan.planners.dwa import NavigationScene
from minimaxplan.planners.navigation import NavigationFunction
from minimaxplan.scenarios import GoalReward, Hypothesis, MovingObstacles, RobotWorld, make_world, robot_hypotheses
from minimaxplan.scenarios.worlds import WORLD_KINDS

from .episode import LoopConfig
from .registry import Scenario, register_scenario

__all__ = ["RobotScenario", "assumption4_report", "excitation_data"]


class RobotScenario(Scenario[RobotWorld]):
    """The mobile robot among static discs (``kind="static"``) or pedestrians (``"pedestrian"``).

    Parameters
    ----------
    kind
        One of `minimaxplan.scenarios.WORLD_KINDS`.
    """

    def __init__(self, kind: str):
        self.kind = kind

    def __repr__(self) -> str:
        return f"RobotScenario({self.kind!r})"

    def make_world(self, seed: int, config: LoopConfig) -> RobotWorld:
        """`make_world` of ``kind`` and ``seed``, with the measurement model of ``config``.

        Parameters
        ----------
        seed : int
            The episode's world seed (>= 0).
        config : LoopConfig
            The loop settings; only ``measurement`` is read.
        """
        return make_world(self.kind, seed, measurement=config.measurement)

    @staticmethod
    def hypotheses(world: RobotWorld) -> list[Hypothesis]:
        """The competing structural hypotheses of the robot (the truth first).

        Parameters
        ----------
        world : RobotWorld
            The episode's world (its ``params``: the sampling time and the robot's bounds).
        """
        return robot_hypotheses(world.params.dt, world.params)

    @staticmethod
    def global_path(world: RobotWorld, clearance: float) -> NavigationFunction:
        """The static map's cost-to-go to the goal, on a grid covering the whole arena.

        Parameters
        ----------
        world : RobotWorld
            The episode's world.
        clearance : float
            Grid cells whose centre is closer than this to a disc's edge are blocked, m.
        """
        size = world.params.arena_size
        region = np.array([world.start, [0.0, 0.0], [size, size]])
        return NavigationFunction(
            world.goal, world.obstacles.centers, world.obstacles.radii, clearance=clearance, region=region, padding=3.0
        )

    @staticmethod
    def objective(world: RobotWorld, waypoint, *, uncertain: bool) -> GoalReward:
        """The reward a planner maximises at this decision: reach ``waypoint`` without touching
        the static discs or the pedestrians (predicted boxes if ``uncertain``, else points
        moving at their announced velocities).

        Parameters
        ----------
        world : RobotWorld
            The episode's world.
        waypoint : array_like
            Shape (2,), m: the point chased at this decision.
        uncertain : bool
            Whether the pedestrians are the boxes of their velocity uncertainty (robust)
            or points at their announced velocities (nominal, oracle).
        """
        return GoalReward(
            waypoint,
            obstacles=world.obstacles,
            robot_radius=world.params.robot_radius,
            moving_obstacles=_pedestrian_prediction(world, uncertain) if len(world.crowd) else None,
        )

    @staticmethod
    def scene(world: RobotWorld, waypoint) -> NavigationScene:
        """What the baselines are told: the waypoint, the discs, the pedestrians' current
        positions and announced velocities.

        Parameters
        ----------
        world : RobotWorld
            The episode's world.
        waypoint : array_like
            Shape (2,), m: the point chased at this decision.
        """
        peds = world.pedestrians
        return NavigationScene(
            goal=waypoint,
            obstacle_centers=world.obstacles.centers,
            obstacle_radii=world.obstacles.radii,
            pedestrian_positions=peds.positions,
            pedestrian_velocities=peds.velocities,
            pedestrian_radii=peds.radii,
        )


def _pedestrian_prediction(world: RobotWorld, uncertain: bool) -> MovingObstacles:
    peds = world.pedestrians
    if uncertain:
        return peds
    return MovingObstacles(peds.positions, peds.velocities, peds.radii, dt=peds.dt, time0=peds.time0)


def assumption4_report(system: UncertainLinearSystem, parameters: Box) -> dict:
    """Assumption 4 once per episode: the full model and its velocity subsystem.

    The full open-loop model has two integrators (eigenvalue 1 in discrete time), so
    the discrete LMI is infeasible there and Theorem 2's bound does not apply; the
    velocity block ``I - dt diag(theta)`` is Schur for every friction in the box, and
    a common certificate over the box's vertices is sought.

    Parameters
    ----------
    system : UncertainLinearSystem
        The robot's system, states ``(px, py, vx, vy)``.
    parameters : Box
        The friction box whose vertices are checked (a survivor's feasible parameter box).

    Returns
    -------
    dict
        ``full_model`` and ``velocity_subsystem``: the `LMIStatus` of each check, with
        ``full_model_note`` and ``velocity_certified`` (the velocity LMI re-checked exactly).
    """
    from minimaxplan.verify.lmi import check_assumption4  # cvxpy: imported when an episode checks Assumption 4

    vertices = parameters.vertices()
    full = check_assumption4([system.A(v) for v in vertices], form="discrete", D=system.D)
    velocity = check_assumption4([system.A(v)[2:, 2:] for v in vertices], form="discrete", D=system.D[2:])
    return {
        "full_model": full.status,
        "full_model_note": "integrators: infeasible is expected and Theorem 2 does not apply",
        "velocity_subsystem": velocity.status,
        "velocity_certified": bool(velocity.certified),
    }


def excitation_data(world: RobotWorld, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` measured transitions of the episode's robot under random controls from rest,
    recorded before the episode (seeded by the world's seed).

    The measurement noise is the bounded uniform noise of ``world.params.measurement_noise``
    whatever the world's measurement model (a world with ``measurement="gaussian"`` still
    gets bounded prior data: the data the estimator's guarantee covers).

    Returns measured states (n + 1, 4) and controls (n, 2).

    Parameters
    ----------
    world : RobotWorld
        The episode's world: its seed, robot, true friction and bounds.
    n : int
        The number of transitions.
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


for _kind in WORLD_KINDS:
    register_scenario(_kind, functools.partial(RobotScenario, _kind))
