"""Simulated navigation worlds for the mobile robot: static obstacles or pedestrians.

A world is one seeded episode: a start, a goal 14-18 m away, circular obstacles, maybe
pedestrians, the true friction, and the true state. The closed loop asks it for noisy
measurements (`RobotWorld.measure`) and applies one control per sub-step
(`RobotWorld.apply`); the world steps the robot with ``system.step`` (the exact model,
unknown theta and disturbance) and checks collisions with python-fcl
(`minimaxplan.scenarios.geometry.fcl_disc_collisions`).

Everything random is drawn from separate streams spawned from the seed (layout,
friction, disturbance, measurement noise, pedestrians), so the same seed and the same
controls give the same episode, and e.g. measuring more often does not change the
disturbances.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from minimaxplan.models.errors import InputError, MinimaxplanError
from minimaxplan.models.system import UncertainLinearSystem
from minimaxplan.models.validation import (
    as_choice,
    as_count,
    as_finite_array,
    as_positive_scalar,
    check_instance,
)

from .geometry import CircularObstacles, MovingObstacles, fcl_disc_collisions
from .rewards import GoalReward
from .robot import DEFAULT_ROBOT, RobotParameters, robot_system

__all__ = [
    "WORLD_KINDS",
    "OUTCOMES",
    "EpisodeOver",
    "WorldLayout",
    "PedestrianCrowd",
    "crossing_crowd",
    "RobotWorld",
    "make_world",
    "generate_layout",
    "layout_has_path",
]

WORLD_KINDS = ("static", "pedestrian")
#: The measurement models of a `RobotWorld`: bounded (inside the guarantees) or Gaussian.
MEASUREMENT_MODELS = ("uniform", "gaussian")
OUTCOMES = ("running", "goal", "collision", "timeout")

#: Static obstacles in the static world (inclusive range) and their radii, m.
STATIC_OBSTACLE_COUNT = (10, 15)
#: Static obstacles in the pedestrian world (inclusive range).
PEDESTRIAN_WORLD_OBSTACLE_COUNT = (3, 5)
OBSTACLE_RADIUS = (0.4, 1.2)
#: Fraction of obstacles placed near the start-goal segment (the rest anywhere).
ON_ROUTE_FRACTION = 0.5
#: Lateral spread of on-route obstacles around the start-goal segment, m.
ON_ROUTE_SPREAD = 3.0
#: Free space kept around start and goal beyond the robot's footprint, m.
START_GOAL_CLEARANCE = 1.0
#: Resolution of the feasibility grid, m, and free margin its path keeps beyond the footprint.
GRID_RESOLUTION = 0.2
CORRIDOR_MARGIN = 0.15
#: Pedestrians: count (inclusive), speed range (m/s), radius (m), velocity uncertainty per axis (m/s).
PEDESTRIAN_COUNT = (1, 3)
PEDESTRIAN_SPEED = (0.5, 1.5)
PEDESTRIAN_RADIUS = 0.3
PEDESTRIAN_VELOCITY_UNCERTAINTY = 0.3
#: Bound on the heading deviation from the announced heading (rad) and its random-walk step (rad per sub-step).
#: With speed <= 1.5 m/s the per-axis velocity error is <= 1.5 * 0.18 = 0.27 < 0.3 m/s.
PEDESTRIAN_HEADING_DEVIATION = 0.18
PEDESTRIAN_HEADING_STEP = 0.03
#: Spread of crossing directions around the perpendicular to the route, rad.
PEDESTRIAN_CROSSING_SPREAD = np.pi / 6
#: Robot speed assumed to time the pedestrians' crossings, m/s.
CROSSING_TIMING_SPEED = 1.2

_MAX_LAYOUT_ATTEMPTS = 200
# Robot centres closer than this to an obstacle's candidate-collision radius are sent to fcl.
_BROAD_PHASE_SLACK = 0.05


class EpisodeOver(MinimaxplanError, RuntimeError):
    """A control was applied to a world whose episode has already ended."""


@dataclass(frozen=True, eq=False)
class WorldLayout:
    """The static part of an episode: start, goal and circular obstacles.

    Attributes
    ----------
    start, goal : ndarray, shape (2,)
        The robot's start and goal positions, m.
    obstacles : CircularObstacles
        The static discs.
    """

    start: np.ndarray
    goal: np.ndarray
    obstacles: CircularObstacles

    def to_dict(self) -> dict:
        """The layout as plain lists (JSON-ready): ``start``, ``goal`` and ``obstacles.to_dict()``."""
        return {"start": self.start.tolist(), "goal": self.goal.tolist(), "obstacles": self.obstacles.to_dict()}


def layout_has_path(
    start,
    goal,
    obstacles: CircularObstacles,
    *,
    robot_radius: float,
    arena_size: float,
    resolution: float = GRID_RESOLUTION,
    margin: float = CORRIDOR_MARGIN,
) -> bool:
    """Whether a grid path joins start to goal with clearance ``robot_radius + margin``.

    Connected components (`scipy.ndimage.label`) of the cells of a ``resolution`` grid of the arena
    (8-connected) whose centres keep that clearance from every obstacle. Start and goal
    are snapped to their nearest cells. Every point of a move between two neighbouring
    cells lies within ``resolution / sqrt(2)`` of one of them, so with the default
    ``margin >= resolution / sqrt(2)`` the polyline through the found cells keeps the
    robot's whole footprint off the obstacles.

    Parameters
    ----------
    start, goal : array_like, shape (2,)
        The positions to join, m.
    obstacles : CircularObstacles
        The static discs.
    robot_radius : float
        The robot's footprint radius, m.
    arena_size : float
        The grid covers the square ``[0, arena_size]^2``, m.
    resolution : float, optional
        The grid's cell size, m (default `GRID_RESOLUTION`).
    margin : float, optional
        Free margin kept beyond the footprint, m (default `CORRIDOR_MARGIN`).
    """
    n = int(np.ceil(arena_size / resolution)) + 1
    axis = np.linspace(0.0, arena_size, n)
    gx, gy = np.meshgrid(axis, axis, indexing="ij")
    cells = np.stack([gx, gy], axis=-1)
    free = obstacles.clearance(cells) >= robot_radius + margin
    spacing = axis[1] - axis[0]
    source = tuple(np.clip(np.rint(np.asarray(start) / spacing).astype(int), 0, n - 1))
    target = tuple(np.clip(np.rint(np.asarray(goal) / spacing).astype(int), 0, n - 1))
    if not (free[source] and free[target]):
        return False
    labels, _ = ndimage.label(free, structure=np.ones((3, 3), dtype=int))
    return bool(labels[source] == labels[target])


def _start_and_goal(rng: np.random.Generator, params: RobotParameters) -> tuple[np.ndarray, np.ndarray]:
    border = START_GOAL_CLEARANCE + params.robot_radius
    low, high = border, params.arena_size - border
    while True:
        start = rng.uniform(low, high, size=2)
        heading = rng.uniform(-np.pi, np.pi)
        distance = rng.uniform(params.goal_distance_low, params.goal_distance_high)
        goal = start + distance * np.array([np.cos(heading), np.sin(heading)])
        if np.all(goal >= low) and np.all(goal <= high):
            return start, goal


def _obstacles(rng, count, start, goal, params: RobotParameters) -> CircularObstacles:
    """``count`` obstacles, about half near the route, none within reach of start or goal."""
    route = goal - start
    normal = np.array([-route[1], route[0]]) / np.linalg.norm(route)
    centers: list[np.ndarray] = []
    radii: list[float] = []
    while len(centers) < count:
        radius = rng.uniform(*OBSTACLE_RADIUS)
        if rng.uniform() < ON_ROUTE_FRACTION:
            center = start + rng.uniform(0.15, 0.85) * route + rng.uniform(-ON_ROUTE_SPREAD, ON_ROUTE_SPREAD) * normal
        else:
            center = rng.uniform(0.0, params.arena_size, size=2)
        keep_out = radius + params.robot_radius + START_GOAL_CLEARANCE
        if np.linalg.norm(center - start) < keep_out or np.linalg.norm(center - goal) < keep_out:
            continue
        if np.any(center < 0.0) or np.any(center > params.arena_size):
            continue
        centers.append(center)
        radii.append(radius)
    return CircularObstacles(np.array(centers), np.array(radii))


def generate_layout(kind: str, rng: np.random.Generator, params: RobotParameters = DEFAULT_ROBOT) -> WorldLayout:
    """Draw a start, a goal and obstacles that leave a path (checked by `layout_has_path`).

    ``kind="static"``: 10-15 obstacles; ``"pedestrian"``: 3-5. Radii 0.4-1.2 m. Layouts
    without a path are redrawn from the same stream.

    Parameters
    ----------
    kind : str
        One of `WORLD_KINDS`: ``"static"`` or ``"pedestrian"``.
    rng : numpy.random.Generator
        The stream the layout is drawn from.
    params : RobotParameters, optional
        The arena size, robot radius and start-goal distance range (default `DEFAULT_ROBOT`).
    """
    as_choice("kind", kind, WORLD_KINDS)
    low, high = STATIC_OBSTACLE_COUNT if kind == "static" else PEDESTRIAN_WORLD_OBSTACLE_COUNT
    for _ in range(_MAX_LAYOUT_ATTEMPTS):
        start, goal = _start_and_goal(rng, params)
        obstacles = _obstacles(rng, int(rng.integers(low, high + 1)), start, goal, params)
        if layout_has_path(start, goal, obstacles, robot_radius=params.robot_radius, arena_size=params.arena_size):
            return WorldLayout(start, goal, obstacles)
    raise RuntimeError(f"no feasible {kind} layout in {_MAX_LAYOUT_ATTEMPTS} attempts")  # pragma: no cover


@dataclass(eq=False)
class PedestrianCrowd:
    """Pedestrians walking straight across the robot's route, with bounded heading noise.

    Each pedestrian has an announced constant velocity ``announced[j]`` (what planners
    are told) and a true heading that random-walks within
    ``+-PEDESTRIAN_HEADING_DEVIATION`` of the announced one at constant speed. Since
    ``|s cos(h + e) - s cos h| <= s |e|`` (and likewise for sin), the true velocity
    stays within ``announced +- PEDESTRIAN_VELOCITY_UNCERTAINTY`` per axis at all
    times, so the growing boxes of `MovingObstacles` built from any current position
    are sound. Pedestrians ignore the robot and the obstacles.

    Attributes
    ----------
    positions : ndarray, shape (m, 2)
        The pedestrians' current positions, m.
    announced : ndarray, shape (m, 2)
        The announced constant velocities, m/s.
    speeds : ndarray, shape (m,)
        The true (constant) speeds, m/s.
    headings : ndarray, shape (m,)
        The announced headings, rad.
    deviations : ndarray, shape (m,)
        The true headings' current deviations from ``headings``, rad.
    radii : ndarray, shape (m,)
        The pedestrians' radii, m.
    rng : numpy.random.Generator
        The stream of the heading random walk.
    """

    positions: np.ndarray
    announced: np.ndarray
    speeds: np.ndarray
    headings: np.ndarray
    deviations: np.ndarray
    radii: np.ndarray
    rng: np.random.Generator = field(repr=False)

    @property
    def velocities(self) -> np.ndarray:
        """True current velocities, shape (m, 2)."""
        h = self.headings + self.deviations
        return self.speeds[:, None] * np.stack([np.cos(h), np.sin(h)], axis=-1)

    def advance(self, dt: float) -> None:
        """Move every pedestrian for ``dt`` at its current velocity, then perturb its heading.

        Parameters
        ----------
        dt : float
            The time step, s.
        """
        self.positions = self.positions + self.velocities * dt
        step = self.rng.uniform(-PEDESTRIAN_HEADING_STEP, PEDESTRIAN_HEADING_STEP, size=self.deviations.shape)
        self.deviations = np.clip(self.deviations + step, -PEDESTRIAN_HEADING_DEVIATION, PEDESTRIAN_HEADING_DEVIATION)

    def __len__(self) -> int:
        return self.positions.shape[0]


def crossing_crowd(rng: np.random.Generator, count: int, start, goal) -> PedestrianCrowd:
    """``count`` pedestrians timed to cross the route from ``start`` to ``goal`` near the robot's passage.

    The crowd of the pedestrian world (`make_world`), drawn from ``rng``: each
    pedestrian crosses the segment at a fraction U[0.3, 0.8] of its length, from either
    side, within ``PEDESTRIAN_CROSSING_SPREAD`` of the perpendicular, at a speed
    ``U(PEDESTRIAN_SPEED)``, timed to arrive about when a robot at
    ``CROSSING_TIMING_SPEED`` would, and starting at least 2 m plus its radius from
    ``start``.

    Parameters
    ----------
    rng : numpy.random.Generator
        The stream the crowd is drawn from; it stays the crowd's (its heading walk).
    count : int
        Number of pedestrians (>= 0).
    start, goal : array_like, shape (2,)
        The robot's start and goal, m (distinct).

    Returns
    -------
    PedestrianCrowd
        The pedestrians at rest on their heading walk (deviations 0), radius
        ``PEDESTRIAN_RADIUS``.

    Raises
    ------
    InputError
        If ``rng`` is not a `numpy.random.Generator`, ``count`` is not an integer >= 0,
        or ``start`` and ``goal`` coincide.
    DimensionError
        If ``start`` or ``goal`` is not of shape (2,).
    """
    check_instance("rng", rng, np.random.Generator)
    count = as_count("count", count, minimum=0)
    start = as_finite_array("start", start, (2,))
    goal = as_finite_array("goal", goal, (2,))
    route = goal - start
    if not np.any(route):
        raise InputError(f"start and goal must differ, got {start.tolist()} for both")
    length = np.linalg.norm(route)
    route_heading = np.arctan2(route[1], route[0])
    position_list: list[np.ndarray] = []
    heading_list: list[float] = []
    speed_list: list[float] = []
    while len(position_list) < count:
        fraction = rng.uniform(0.3, 0.8)
        crossing = start + fraction * route
        side = rng.choice([-1.0, 1.0])
        heading = (
            route_heading + side * np.pi / 2 + rng.uniform(-PEDESTRIAN_CROSSING_SPREAD, PEDESTRIAN_CROSSING_SPREAD)
        )
        speed = rng.uniform(*PEDESTRIAN_SPEED)
        arrival = fraction * length / CROSSING_TIMING_SPEED * rng.uniform(0.7, 1.3)
        position = crossing - speed * arrival * np.array([np.cos(heading), np.sin(heading)])
        if np.linalg.norm(position - start) < 2.0 + PEDESTRIAN_RADIUS:
            continue
        position_list.append(position)
        heading_list.append(heading)
        speed_list.append(speed)
    headings = np.array(heading_list, dtype=float)
    speeds = np.array(speed_list, dtype=float)
    positions = np.array(position_list, dtype=float).reshape(count, 2)
    announced = speeds[:, None] * np.stack([np.cos(headings), np.sin(headings)], axis=-1)
    return PedestrianCrowd(
        positions=positions,
        announced=announced,
        speeds=speeds,
        headings=headings,
        deviations=np.zeros(count),
        radii=np.full(count, PEDESTRIAN_RADIUS),
        rng=rng,
    )


def _check_crowd(crowd: PedestrianCrowd, velocity_uncertainty: float) -> None:
    """Raise unless ``crowd``'s arrays describe one set of pedestrians whose velocities respect the bound."""
    m = as_finite_array("crowd.positions", crowd.positions, (None, 2)).shape[0]
    for name, shape in (("announced", (m, 2)), ("speeds", (m,)), ("headings", (m,)), ("deviations", (m,))):
        as_finite_array(f"crowd.{name}", getattr(crowd, name), shape)
    radii = as_finite_array("crowd.radii", crowd.radii, (m,))
    if np.any(radii <= 0):
        raise InputError(f"crowd.radii must be > 0, got {radii.tolist()}")
    check_instance("crowd.rng", crowd.rng, np.random.Generator)
    error = np.abs(np.asarray(crowd.velocities) - np.asarray(crowd.announced))
    if error.size and float(error.max()) > velocity_uncertainty:
        raise InputError(
            f"the crowd's true velocities lie up to {float(error.max()):.6g} m/s per axis from the announced ones, "
            f"beyond velocity_uncertainty={velocity_uncertainty:g} m/s"
        )


class RobotWorld:
    """One seeded episode of robot navigation; see `make_world`.

    Attributes
    ----------
    kind, seed, params
        What was asked for.
    system
        The truth's structure (anisotropic friction), an `UncertainLinearSystem`
        whose prior box holds ``true_theta``.
    true_theta
        The friction ``(xi_x, xi_y)`` of this episode.
    start, goal
        Shape (2,).
    obstacles
        `CircularObstacles` (``.centers`` (n, 2), ``.radii`` (n,)).
    goal_reward
        The episode's `GoalReward` over the static obstacles (planners add the
        pedestrians with ``goal_reward.with_obstacles(moving_obstacles=world.pedestrians)``).
    state
        The true state (px, py, vx, vy); starts at rest at ``start``.
    step_index
        Sub-steps applied so far; ``time = step_index * dt``.
    velocity_uncertainty
        Per-axis bound on the pedestrians' ``true - announced`` velocity that planners
        are told, m/s (`PEDESTRIAN_VELOCITY_UNCERTAINTY`, or that of `with_crowd`).
    outcome
        "running", "goal", "collision" or "timeout"; ``done`` once it is not "running".
    measurement
        "uniform" (bounded noise, inside the guarantees) or "gaussian".
    """

    def __init__(self, kind: str, seed: int, *, measurement: str = "uniform", params: RobotParameters = DEFAULT_ROBOT):
        as_choice("kind", kind, WORLD_KINDS)
        as_choice("measurement", measurement, MEASUREMENT_MODELS)
        check_instance("params", params, RobotParameters)
        self.kind = kind
        self.seed = as_count("seed", seed, minimum=0)
        self.measurement = measurement
        self.params = params
        layout_seq, theta_seq, disturbance_seq, noise_seq, pedestrian_seq = np.random.SeedSequence(self.seed).spawn(5)
        layout = generate_layout(kind, np.random.default_rng(layout_seq), params)
        self.start = layout.start
        self.goal = layout.goal
        self.obstacles = layout.obstacles
        self.system: UncertainLinearSystem = robot_system(params)
        self.true_theta = np.random.default_rng(theta_seq).uniform(self.system.theta.low, self.system.theta.high)
        self._disturbance_rng = np.random.default_rng(disturbance_seq)
        self._noise_rng = np.random.default_rng(noise_seq)
        pedestrian_rng = np.random.default_rng(pedestrian_seq)
        if kind == "pedestrian":
            count = int(pedestrian_rng.integers(PEDESTRIAN_COUNT[0], PEDESTRIAN_COUNT[1] + 1))
            crowd = crossing_crowd(pedestrian_rng, count, self.start, self.goal)
        else:
            crowd = crossing_crowd(pedestrian_rng, 0, self.start, self.goal)
        self.goal_reward = GoalReward(self.goal, obstacles=self.obstacles, robot_radius=params.robot_radius)
        self.state = np.concatenate([self.start, np.zeros(2)])
        self.step_index = 0
        self.velocity_uncertainty = PEDESTRIAN_VELOCITY_UNCERTAINTY
        self._install_crowd(crowd)
        self.outcome = "running"
        self.last_disturbance = np.zeros(2)

    def _install_crowd(self, crowd: PedestrianCrowd) -> None:
        self.crowd = crowd
        self._initial_pedestrians = (crowd.positions.copy(), crowd.announced.copy())
        # Only the pedestrians' radii matter here: their true positions are passed at evaluation.
        self._true_reward = (
            self.goal_reward.with_obstacles(moving_obstacles=self.pedestrians) if len(crowd) else self.goal_reward
        )

    @classmethod
    def with_crowd(
        cls,
        kind: str,
        seed: int,
        crowd: PedestrianCrowd | Callable[[np.ndarray, np.ndarray], PedestrianCrowd],
        *,
        velocity_uncertainty: float = PEDESTRIAN_VELOCITY_UNCERTAINTY,
        measurement: str = "uniform",
        params: RobotParameters = DEFAULT_ROBOT,
    ) -> RobotWorld:
        """The world of ``kind`` and ``seed`` with the pedestrians of ``crowd`` instead of its own.

        Layout, friction, disturbances and measurement noise are those of
        ``make_world(kind, seed, measurement=measurement, params=params)``; only the
        crowd and the velocity uncertainty that planners are told
        (`pedestrians`) differ.

        Parameters
        ----------
        kind : {"static", "pedestrian"}
            The world whose layout is kept.
        seed : int
            World seed (>= 0).
        crowd : PedestrianCrowd or callable
            The pedestrians, or a function ``(start, goal) -> PedestrianCrowd`` called
            with (copies of) the world's start and goal, e.g. a `crossing_crowd` with a
            stream of the caller's. The world owns it from here on (it advances it).
        velocity_uncertainty : float
            Per-axis bound u on ``true - announced`` velocity that the world announces,
            m/s (finite, >= 0). The crowd's heading walk must keep its true velocities
            within it at all times, or the predicted boxes are not sound; a crowd whose
            current velocities already leave it is refused.
        measurement : {"uniform", "gaussian"}
            As in `make_world`.
        params : RobotParameters
            As in `make_world`.

        Returns
        -------
        RobotWorld
            A new episode whose ``crowd`` is the given one and whose
            ``velocity_uncertainty`` is ``velocity_uncertainty``.

        Raises
        ------
        InputError
            For an argument of `make_world` out of range, a ``crowd`` that is neither a
            `PedestrianCrowd` nor a callable returning one, a velocity uncertainty that
            is negative or not finite, non-finite crowd arrays, radii <= 0, or current
            velocities farther than ``velocity_uncertainty`` from the announced ones.
        DimensionError
            If the crowd's arrays do not describe the same number of pedestrians
            (positions and announced (m, 2), speeds, headings, deviations and radii (m,)).
        """
        bound = as_positive_scalar("velocity_uncertainty", velocity_uncertainty, allow_zero=True)
        if not isinstance(crowd, PedestrianCrowd) and not callable(crowd):
            raise InputError(f"crowd must be a PedestrianCrowd or a callable, got {type(crowd).__name__}")
        world = cls(kind, seed, measurement=measurement, params=params)
        if not isinstance(crowd, PedestrianCrowd):
            crowd = crowd(world.start.copy(), world.goal.copy())
            check_instance("crowd", crowd, PedestrianCrowd, "a PedestrianCrowd (returned by the crowd callable)")
        _check_crowd(crowd, bound)
        world.velocity_uncertainty = bound
        world._install_crowd(crowd)
        return world

    # ------------------------------------------------------------ observation
    @property
    def time(self) -> float:
        """Simulated time, s."""
        return self.step_index * self.params.dt

    @property
    def done(self) -> bool:
        """Whether the episode has ended (``outcome`` is not "running")."""
        return self.outcome != "running"

    @property
    def substeps(self) -> int:
        """Sub-steps per decision (``params.substeps``): a control is held this many times."""
        return self.params.substeps

    @property
    def position(self) -> np.ndarray:
        """The robot's true position (px, py), shape (2,), in metres (a copy)."""
        return self.state[:2].copy()

    @property
    def pedestrians(self) -> MovingObstacles:
        """What planners may know of the pedestrians now: current positions (observed
        exactly), announced velocities, per-axis velocity uncertainty
        (`velocity_uncertainty`), radii, as
        `MovingObstacles` whose ``time0`` is the current sub-step index (the boxes are
        sound from here on)."""
        return MovingObstacles(
            self.crowd.positions.copy(),
            self.crowd.announced.copy(),
            self.crowd.radii.copy(),
            velocity_uncertainty=self.velocity_uncertainty,
            dt=self.params.dt,
            time0=self.step_index,
        )

    def true_states(self) -> dict[str, np.ndarray]:
        """The true states for the episode loop's run-time check (`GroundTruthWorld`).

        Never shown to a method; reading them draws no random number.

        Returns
        -------
        dict of str to numpy.ndarray
            ``"robot"``: the state (px, py, vx, vy), shape (4,); ``"pedestrian j"``:
            pedestrian j's position, shape (2,), for j = 0..m-1 (copies).
        """
        truth = {"robot": self.state.copy()}
        for j, position in enumerate(self.crowd.positions):
            truth[f"pedestrian {j}"] = position.copy()
        return truth

    def measure(self) -> np.ndarray:
        """The state with measurement noise: uniform ``|v_i| <= measurement_noise``
        (inside the guarantees) or Gaussian with ``gaussian_measurement_std`` (outside)."""
        if self.measurement == "uniform":
            bound = self.params.measurement_noise
            noise = self._noise_rng.uniform(-bound, bound, size=4)
        else:
            noise = self._noise_rng.normal(0.0, self.params.gaussian_measurement_std, size=4)
        return self.state + noise

    def reward(self) -> float:
        """The true goal reward ``J = beta(x) / (1 + ||pos - goal||)`` of the current state.

        Evaluated by `goal_reward` with the pedestrians' true positions; beta is the
        world's own (fcl) collision verdict once the episode has ended in a collision.
        """
        if self.outcome == "collision":
            return 0.0
        return float(self._true_reward.value(self.state, self.step_index, moving_positions=self.crowd.positions))

    def collisions(self) -> np.ndarray:
        """Which obstacles then pedestrians the robot's disc touches now, bool (n + m,), by fcl."""
        centers = np.concatenate([self.obstacles.centers, self.crowd.positions])
        radii = np.concatenate([self.obstacles.radii, self.crowd.radii])
        hits = np.zeros(centers.shape[0], dtype=bool)
        if centers.shape[0] == 0:
            return hits
        # Broad phase in numpy; fcl decides every pair that may touch.
        gap = np.linalg.norm(centers - self.state[:2], axis=-1) - radii - self.params.robot_radius
        near = np.flatnonzero(gap <= _BROAD_PHASE_SLACK)
        if near.size:
            hits[near] = fcl_disc_collisions(self.state[:2], self.params.robot_radius, centers[near], radii[near])
        return hits

    # ---------------------------------------------------------------- dynamics
    def apply(self, u: np.ndarray) -> str:
        """Hold the control ``u`` for one sub-step and return the outcome.

        The robot steps by ``system.step(state, u, true_theta, w)`` with a fresh
        ``w ~ U[-0.1, 0.1]^2``; the pedestrians move; then collision (fcl), goal and
        time limit are checked in that order.

        Parameters
        ----------
        u : array_like
            The control, shape (2,), in ``[-control_bound, control_bound]^2``.

        Returns
        -------
        str
            "running", "goal", "collision" or "timeout".

        Raises
        ------
        EpisodeOver
            If the episode has already ended.
        InputError
            If ``u`` is out of bounds, not finite or not of shape (2,).
        """
        if self.done:
            raise EpisodeOver(f"the episode has ended (outcome={self.outcome!r}); make a new world")
        u = as_finite_array("u", u, (2,))
        bound = self.params.control_bound
        if np.any(np.abs(u) > bound):
            raise InputError(f"u must lie in [-{bound}, {bound}]^2, got {u.tolist()}")
        bound_w = self.params.disturbance_bound
        w = self._disturbance_rng.uniform(-bound_w, bound_w, size=2)
        self.state = self.system.step(self.state, u, self.true_theta, w)
        self.last_disturbance = w
        self.crowd.advance(self.params.dt)
        self.step_index += 1
        if np.any(self.collisions()):
            self.outcome = "collision"
        elif np.linalg.norm(self.state[:2] - self.goal) <= self.params.goal_tolerance:
            self.outcome = "goal"
        elif self.step_index >= self.params.max_steps:
            self.outcome = "timeout"
        return self.outcome

    def apply_held(self, u: np.ndarray) -> str:
        """Hold ``u`` for one decision period (``substeps`` sub-steps, fewer if the episode ends).

        Parameters
        ----------
        u : array_like
            The control, shape (2,); see `apply`.

        Returns
        -------
        str
            The outcome after the last sub-step applied.
        """
        for _ in range(self.params.substeps):
            if self.apply(u) != "running":
                break
        return self.outcome

    def to_dict(self) -> dict:
        """The episode's setup (not its state)."""
        return {
            "kind": self.kind,
            "seed": self.seed,
            "measurement": self.measurement,
            "true_theta": self.true_theta.tolist(),
            "start": self.start.tolist(),
            "goal": self.goal.tolist(),
            "obstacles": self.obstacles.to_dict(),
            "pedestrians": {
                "positions": self._initial_pedestrians[0].tolist(),
                "announced": self._initial_pedestrians[1].tolist(),
            },
            "params": self.params.to_dict(),
        }


def make_world(
    kind: str, seed: int, *, measurement: str = "uniform", params: RobotParameters = DEFAULT_ROBOT
) -> RobotWorld:
    """A new seeded episode of robot navigation; see `RobotWorld`.

    Parameters
    ----------
    kind : {"static", "pedestrian"}
        "static": 10-15 obstacles; "pedestrian": 3-5 obstacles and 1-3 crossing
        pedestrians.
    seed : int
        World seed (>= 0): the same seed gives the same episode.
    measurement : {"uniform", "gaussian"}
        Measurement noise: bounded (inside the guarantees) or Gaussian (outside).
    params : RobotParameters
        The robot and the arena.

    Returns
    -------
    RobotWorld
        The world at its start, the robot at rest.

    Raises
    ------
    InputError
        If ``kind`` or ``measurement`` is unknown, ``seed`` is not an integer >= 0,
        or ``params`` is not a `RobotParameters`.
    """
    return RobotWorld(kind, seed, measurement=measurement, params=params)
