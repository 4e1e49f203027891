"""Dynamic Window Approach (Fox, Burgard & Thrun 1997) for a point mass with friction and a car.

A baseline, not a robust planner: it plans with the *nominal* model (a point estimate of
theta, no disturbance) and the pedestrians' announced velocities, and has no guarantee.

The original DWA searches the velocities a differential-drive robot can reach within
one control period (the dynamic window), scores each by a weighted sum of heading to
the goal, clearance along the arc it would follow and speed, and keeps only
*admissible* velocities, those from which the robot can still stop before the nearest
obstacle. For the holonomic double integrator ``d(vel)/dt = -xi vel + u`` the
reachable set after one period is the image of the control box, so the window is
sampled as a grid of accelerations ``u in [-1, 1]^2``; each is held for the prediction
horizon (the analogue of DWA's constant-velocity arcs) to score it, and admissibility
is checked by holding it for one decision period and then braking at full power.

For a car-like ego on a road (`VehicleDynamicWindow`), the window is a grid of
``(acceleration, steering)`` controls, each held through a given vectorised dynamics
(the worlds' kinematic bicycle, passed in by the analysis layer: planners never import
`scenarios`); the road comes as a `RoadScene` (a lane frame and a road test as
callables, the other vehicles' measured states, predicted at constant velocity).
Both planners choose by the same rule (`_choose`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.models.system import UncertainLinearSystem
from minimaxplan.models.validation import as_count, as_finite_array, as_positive_scalar, check_instance, check_shape

from .navigation import NavigationCache, NavigationFunction

__all__ = [
    "NavigationScene",
    "BicycleBaseline",
    "DWAParameters",
    "DWAEvaluation",
    "DynamicWindowPlanner",
    "planar_robot_model",
    "RoadScene",
    "VehicleDWAParameters",
    "VehicleDynamicWindow",
    "rectangle_discs",
    "steering_window",
]


# ------------------------------------------------------------------ the scene
@dataclass(frozen=True, eq=False)
class NavigationScene:
    """What a baseline planner knows of the world at one decision, as plain arrays.

    Parameters
    ----------
    goal
        Goal position, shape (2,).
    obstacle_centers, obstacle_radii
        Static discs, shapes (n, 2) and (n,); n = 0 allowed.
    pedestrian_positions, pedestrian_velocities, pedestrian_radii
        Moving discs now and their (announced) velocities, shapes (m, 2), (m, 2), (m,).
    """

    goal: np.ndarray
    # Each disc argument also accepts None for "none"; all are arrays after construction.
    obstacle_centers: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    obstacle_radii: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pedestrian_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    pedestrian_velocities: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    pedestrian_radii: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        object.__setattr__(self, "goal", as_finite_array("goal", self.goal, (2,)))
        centers, radii = _discs("obstacle_centers", self.obstacle_centers, "obstacle_radii", self.obstacle_radii)
        positions, ped_radii = _discs(
            "pedestrian_positions", self.pedestrian_positions, "pedestrian_radii", self.pedestrian_radii
        )
        velocities = _points("pedestrian_velocities", self.pedestrian_velocities)
        check_shape("pedestrian_velocities", velocities, (positions.shape[0], 2))
        for name, value in (
            ("obstacle_centers", centers),
            ("obstacle_radii", radii),
            ("pedestrian_positions", positions),
            ("pedestrian_velocities", velocities),
            ("pedestrian_radii", ped_radii),
        ):
            object.__setattr__(self, name, value)

    @property
    def centers(self) -> np.ndarray:
        """All disc centres at time 0, obstacles then pedestrians, (n + m, 2)."""
        return np.concatenate([self.obstacle_centers, self.pedestrian_positions])

    @property
    def radii(self) -> np.ndarray:
        """All disc radii, obstacles then pedestrians, (n + m,)."""
        return np.concatenate([self.obstacle_radii, self.pedestrian_radii])

    @property
    def velocities(self) -> np.ndarray:
        """Disc velocities (zero for static obstacles), (n + m, 2)."""
        return np.concatenate([np.zeros_like(self.obstacle_centers), self.pedestrian_velocities])

    def to_dict(self) -> dict:
        """The scene as plain lists (JSON-ready)."""
        return {k: v.tolist() for k, v in self.__dict__.items()}


def planar_robot_model(system: UncertainLinearSystem, theta, substeps) -> tuple[np.ndarray, float]:
    """Check a baseline's robot model and return ``(A(theta), dt)``.

    The baselines plan for a planar point mass: 4 states (position, velocity), 2 inputs,
    positions integrating velocities with weight dt; ``theta`` defaults to the centre of
    the prior box; ``substeps`` (a control is held that long) must be a positive integer.

    Parameters
    ----------
    system : UncertainLinearSystem
        The robot's discrete model (4 states: position, velocity; 2 inputs).
    theta : array_like, shape (nparams,), or None
        The parameter value to plan with; None for the centre of ``system.theta``.
    substeps : int
        Sub-steps of ``system`` per decision period.
    """
    check_instance("system", system, UncertainLinearSystem)
    if system.nstates != 4 or system.ninputs != 2:
        raise DimensionError(
            f"system must have 4 states and 2 inputs (a planar point mass, B of shape (4, 2)), "
            f"got {system.nstates} states and {system.ninputs} inputs (B of shape {system.B.shape})"
        )
    as_count("substeps", substeps)
    theta = system.theta.center if theta is None else as_finite_array("theta", theta, (system.nparams,))
    A = system.A(theta)
    dt = float(A[0, 2])
    if not dt > 0:
        raise InputError("system must integrate velocity into position (A[0, 2] = dt > 0)")
    return A, dt


def _points(name, value) -> np.ndarray:
    if value is None:
        return np.zeros((0, 2))
    array = as_finite_array(name, value)
    if array.size == 0:
        array = array.reshape(0, 2)
    check_shape(name, array, (None, 2))
    return array


def _discs(center_name, centers, radius_name, radii) -> tuple[np.ndarray, np.ndarray]:
    c = _points(center_name, centers)
    if radii is None or (c.shape[0] and np.size(radii) == 0):
        if c.shape[0]:
            raise InputError(f"{radius_name} is required with {center_name} of shape {c.shape}")
        return c, np.zeros(0)
    r = as_finite_array(radius_name, radii)
    if r.size == 0:
        r = r.reshape(0)
    check_shape(radius_name, r, (c.shape[0],))
    if np.any(r <= 0):
        raise InputError(f"{radius_name} must be > 0, got min {r.min():.6g}")
    return c, r


def _control_grid(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Every pair ``(first[i], second[j])``, shape (len(first) * len(second), 2), ``first`` the slow axis."""
    return np.stack(np.meshgrid(first, second, indexing="ij"), axis=-1).reshape(-1, 2)


def _validated_state(state, nstates: int) -> np.ndarray:
    return as_finite_array("state", state, (nstates,))


def _choose(controls: np.ndarray, score, admissible, violation, clearance) -> DWAEvaluation:
    """DWA's choice: the best admissible sample, or (nothing admissible, e.g. already
    inside the margin) the sample whose path violates the clearance least in total,
    the best escape (flagged as a fallback)."""
    scores = np.where(admissible, score, -np.inf)
    if np.any(admissible):
        control = controls[int(np.argmax(scores))].copy()
        fallback = False
    else:
        control = controls[int(np.argmin(violation))].copy()
        fallback = True
    return DWAEvaluation(controls.copy(), scores, admissible, clearance, control, fallback)


# ------------------------------------------------------------------ DWA
@dataclass(frozen=True)
class DWAParameters:
    """Tuned weights and limits of `DynamicWindowPlanner` (see docs/baselines.md).

    Attributes
    ----------
    samples_per_axis
        The window ``[-1, 1]^2`` is sampled on a ``samples_per_axis^2`` grid (odd: holds 0).
    horizon
        Prediction horizon over which a sample is held to score it, s.
    brake_time
        Time allowed to stop after the first decision period (admissibility), s.
    max_speed
        Samples whose speed would exceed this after one period are not admissible, m/s.
    safety_margin
        Extra clearance beyond the footprint demanded of admissible samples, m.
    pedestrian_margin
        Extra clearance demanded from pedestrians (their velocity is uncertain), m.
    clearance_cap
        Clearances above this count as "free" in the clearance score, m.
    progress_weight, heading_weight, clearance_weight, velocity_weight
        Weights of the normalised terms of the objective.
    navigation_function
        Measure progress and heading with a grid `NavigationFunction` around the static
        discs (the global DWA of Brock & Khatib 1999, as a global planner does in ROS)
        instead of the straight-line distance to the goal (Fox et al.'s purely local
        DWA, which stalls in front of obstacles between robot and goal).
    grid_resolution
        Cell size of that navigation function, m.
    """

    samples_per_axis: int = 9
    horizon: float = 1.0
    brake_time: float = 2.0
    max_speed: float = 1.5
    safety_margin: float = 0.1
    pedestrian_margin: float = 0.3
    clearance_cap: float = 1.5
    progress_weight: float = 1.0
    heading_weight: float = 0.3
    clearance_weight: float = 0.4
    velocity_weight: float = 0.1
    navigation_function: bool = True
    grid_resolution: float = 0.2

    def __post_init__(self) -> None:
        as_count("samples_per_axis", self.samples_per_axis, minimum=2)
        for name in ("horizon", "brake_time", "max_speed", "clearance_cap", "grid_resolution"):
            as_positive_scalar(name, getattr(self, name))
        for name in (
            "safety_margin",
            "pedestrian_margin",
            "progress_weight",
            "heading_weight",
            "clearance_weight",
            "velocity_weight",
        ):
            as_positive_scalar(name, getattr(self, name), allow_zero=True)

    def to_dict(self) -> dict:
        """The parameters as a plain dict (JSON-ready)."""
        return asdict(self)


@dataclass(frozen=True, eq=False)
class DWAEvaluation:
    """Every sample of one DWA call: ``controls`` (k, 2), ``scores`` (k,) (``-inf`` where
    not admissible), ``admissible`` (k,), ``min_clearance`` (k,) over the scored rollout,
    and the chosen ``control`` (when no sample is admissible, ``fallback`` is set and the
    control is the sample whose stopping path violates the clearance least, summed over
    its points).

    Attributes
    ----------
    controls : ndarray (k, 2)
        The sampled controls of the window (accelerations, or ``(acceleration, steering)`` on a road).
    scores : ndarray (k,)
        Each sample's objective, ``-inf`` where not admissible.
    admissible : ndarray (k,) of bool
        Whether each sample is admissible.
    min_clearance : ndarray (k,)
        The smallest clearance along each sample's held rollout, m (inf with nothing to avoid).
    control : ndarray (2,)
        The chosen control.
    fallback : bool
        Whether no sample was admissible (``control`` is then the least violating one).
    """

    controls: np.ndarray
    scores: np.ndarray
    admissible: np.ndarray
    min_clearance: np.ndarray
    control: np.ndarray
    fallback: bool

    def to_dict(self) -> dict:
        """The evaluation as a dict of plain Python values (lists for arrays), for JSON."""
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in self.__dict__.items()}


class DynamicWindowPlanner:
    """DWA on a sampled acceleration window with the nominal model.

    Parameters
    ----------
    system
        The robot's discrete model (4 states: position, velocity; 2 inputs).
    theta
        The parameter value to plan with (default: the centre of ``system.theta``).
    substeps
        Sub-steps of ``system`` per decision period (a control is held that long).
    robot_radius
        Footprint radius, m.
    params
        `DWAParameters`.
    control_bound
        Controls lie in ``[-control_bound, control_bound]^2``.

    Notes
    -----
    Score of an admissible sample (all terms in [0, 1] except progress, about [-1, 1]):
    ``progress_weight * (d0 - d_end) / (max_speed * horizon)
    + heading_weight * (1 + cos(angle(v_end, way))) / 2
    + clearance_weight * min(clearance, cap) / cap
    + velocity_weight * |v_end| / max_speed``, with ``clearance`` the smallest distance
    from the footprint to a disc along the held rollout (0 if it would collide), ``d``
    the cost-to-go of the navigation function (or the distance to the goal without it)
    at the robot and at the rollout's end, and ``way`` the direction of steepest descent
    of that cost-to-go at the end (or the direction to the goal).
    """

    def __init__(
        self,
        system: UncertainLinearSystem,
        *,
        theta=None,
        substeps: int = 5,
        robot_radius: float = 0.3,
        params: DWAParameters = DWAParameters(),
        control_bound: float = 1.0,
    ):
        check_instance("params", params, DWAParameters)
        self._A, self._dt = planar_robot_model(system, theta, substeps)
        self._B = system.B
        self.system = system
        self.params = params
        self.substeps = int(substeps)
        self.robot_radius = as_positive_scalar("robot_radius", robot_radius, allow_zero=True)
        self.control_bound = as_positive_scalar("control_bound", control_bound)
        grid = np.linspace(-1.0, 1.0, params.samples_per_axis) * self.control_bound
        self.controls = _control_grid(grid, grid)
        self._horizon_steps = max(self.substeps, int(round(params.horizon / self._dt)))
        self._brake_steps = int(round(params.brake_time / self._dt))
        self._navigation_cache = NavigationCache(
            clearance=self.robot_radius + params.safety_margin, resolution=params.grid_resolution
        )

    # ------------------------------------------------------------- rollouts
    def _roll(self, x0: np.ndarray, controls: np.ndarray, steps: int) -> np.ndarray:
        """States (k, steps, 4) after holding each control from x0 (k, 4)."""
        out = np.empty((controls.shape[0], steps, 4))
        x = x0
        drive = controls @ self._B.T
        for n in range(steps):
            x = x @ self._A.T + drive
            out[:, n] = x
        return out

    def _brake(self, x0: np.ndarray) -> np.ndarray:
        """States (k, brake_steps, 4) braking at full power from x0 (k, 4)."""
        out = np.empty((x0.shape[0], self._brake_steps, 4))
        x = x0
        gain = 1.0 / self._dt  # cancels the velocity in one sub-step when the bound allows
        for n in range(self._brake_steps):
            u = np.clip(-gain * x[:, 2:], -self.control_bound, self.control_bound)
            x = x @ self._A.T + u @ self._B.T
            out[:, n] = x
        return out

    def evaluate(self, state, scene: NavigationScene) -> DWAEvaluation:
        """Score every sample of the window from the measured ``state``.

        Parameters
        ----------
        state : array_like, shape (4,)
            The measured robot state (position, velocity).
        scene : NavigationScene
            The goal and the discs to avoid, as seen now.

        Returns
        -------
        DWAEvaluation
            Every sample's score, admissibility and clearance, and the chosen control.
        """
        check_instance("scene", scene, NavigationScene)
        x = _validated_state(state, 4)
        p = self.params
        k = self.controls.shape[0]
        held = self._roll(np.broadcast_to(x, (k, 4)), self.controls, self._horizon_steps)
        braked = self._brake(held[:, self.substeps - 1])
        dt = self._dt
        held_times = dt * np.arange(1, self._horizon_steps + 1)
        brake_times = dt * (self.substeps + np.arange(1, self._brake_steps + 1))
        footprint = self.robot_radius
        margin_static = footprint + p.safety_margin
        margin_ped = margin_static + p.pedestrian_margin
        n_static = scene.obstacle_centers.shape[0]
        # Admissible: the first period then braking stays clear (pedestrians with a wider margin).
        admissible_path = np.concatenate([held[:, : self.substeps, :2], braked[..., :2]], axis=1)
        admissible_times = np.concatenate([held_times[: self.substeps], brake_times])
        gaps = self._gaps(admissible_path, admissible_times, scene)
        required = np.concatenate([np.full(n_static, margin_static), np.full(gaps.shape[-1] - n_static, margin_ped)])
        # Shortfall below the required clearance along the stopping path (all <= 0: admissible).
        if gaps.shape[-1]:
            shortfall = required - gaps
            admissible = np.all(shortfall <= 0, axis=(-1, -2))
            violation = np.maximum(shortfall, 0.0).sum(axis=(-1, -2))
        else:
            admissible = np.ones(k, dtype=bool)
            violation = np.zeros(k)
        speed_after = np.linalg.norm(held[:, self.substeps - 1, 2:], axis=-1)
        speed_now = np.linalg.norm(x[2:])
        # Too fast is not admissible, unless the sample slows the robot down.
        admissible &= (speed_after <= p.max_speed) | (speed_after < speed_now)
        # Score along the held rollout.
        held_gaps = self._gaps(held[..., :2], held_times, scene)
        if held_gaps.shape[-1]:
            clearance = (
                held_gaps
                - np.concatenate(
                    [
                        np.full(n_static, footprint),
                        np.full(held_gaps.shape[-1] - n_static, footprint + p.pedestrian_margin),
                    ]
                )
            ).min(axis=(-1, -2))
        else:
            clearance = np.full(k, np.inf)
        end = held[:, -1]
        speed_end = np.linalg.norm(end[:, 2:], axis=-1)
        if p.navigation_function:
            nav = self._navigation(scene, np.concatenate([x[None, :2], end[:, :2]]))
            d0 = float(nav.cost_to_go(x[:2]))
            d_end = nav.cost_to_go(end[:, :2])
            way = nav.descent(end[:, :2])
            cosine = np.einsum("ki,ki->k", end[:, 2:], way) / np.maximum(speed_end, 1e-9)
        else:
            d0 = float(np.linalg.norm(scene.goal - x[:2]))
            to_goal = scene.goal - end[:, :2]
            d_end = np.linalg.norm(to_goal, axis=-1)
            cosine = np.einsum("ki,ki->k", end[:, 2:], to_goal) / np.maximum(speed_end * d_end, 1e-9)
        progress = (d0 - d_end) / (p.max_speed * p.horizon)
        score = (
            p.progress_weight * progress
            + p.heading_weight * (1.0 + cosine) / 2.0
            + p.clearance_weight * np.clip(clearance, 0.0, p.clearance_cap) / p.clearance_cap
            + p.velocity_weight * np.minimum(speed_end / p.max_speed, 1.0)
        )
        return _choose(self.controls, score, admissible, violation, clearance)

    def _navigation(self, scene: NavigationScene, points: np.ndarray) -> NavigationFunction:
        """The navigation function of this scene's goal and static discs (cached; rebuilt
        when they change or the points leave its grid)."""
        return self._navigation_cache.get(scene.goal, scene.obstacle_centers, scene.obstacle_radii, points)

    @staticmethod
    def _gaps(positions: np.ndarray, times: np.ndarray, scene: NavigationScene) -> np.ndarray:
        """Distance from each point (k, T, 2) to each disc edge at that time, (k, T, n + m)."""
        centers = scene.centers
        if centers.shape[0] == 0:
            return np.zeros(positions.shape[:-1] + (0,))
        moving = centers + times[:, None, None] * scene.velocities
        return np.linalg.norm(positions[..., None, :] - moving, axis=-1) - scene.radii

    def plan(self, state, scene: NavigationScene) -> np.ndarray:
        """The control ``u`` (2,) to hold for the next decision period.

        Parameters
        ----------
        state : array_like, shape (4,)
            The measured robot state (position, velocity).
        scene : NavigationScene
            The goal and the discs to avoid, as seen now.
        """
        return self.evaluate(state, scene).control


# ------------------------------------------------------------ DWA on the bicycle
#: ``dynamics(states (k, 4), acceleration (k,), steering (k,), dt) -> states (k, 4)``:
#: one vectorised sub-step of a car-like model (the analysis layer passes the worlds'
#: kinematic bicycle, `minimaxplan.scenarios.vehicles.bicycle_step`).
VehicleDynamics = Callable[[np.ndarray, np.ndarray, np.ndarray, float], np.ndarray]

#: ``reference(points (..., 2)) -> (progress, offset, heading)``, each shape (...): the
#: arc length along the ego's route (m), the signed lateral offset from the nearest
#: lane centre the ego may drive on (m, positive to the left) and that lane's heading (rad).
RoadReference = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]

#: ``on_road(points (..., 2)) -> bool (...)``: whether each point lies on the road.
RoadTest = Callable[[np.ndarray], np.ndarray]

#: Discs per rectangle in the footprint cover of `rectangle_discs`.
FOOTPRINT_DISCS = 3


def rectangle_discs(states: np.ndarray, length: float, width: float) -> tuple[np.ndarray, float]:
    """Centres (..., 3, 2) and radius of three discs covering each L x W rectangle along psi.

    Parameters
    ----------
    states : numpy.ndarray, shape (..., 4)
        ``(x, y, v, psi)``; the rectangle is centred on ``(x, y)``, its long side along psi.
    length, width : float
        L and W, m.

    Returns
    -------
    centres : numpy.ndarray, shape (..., 3, 2)
        Disc centres at ``-L/3, 0, L/3`` along the heading.
    radius : float
        ``sqrt((L/6)^2 + (W/2)^2)``: each disc holds one third of the rectangle, so the
        union of the discs contains it (distances between covers are lower bounds of the
        distances between the rectangles).
    """
    offsets = np.array([-1.0, 0.0, 1.0]) * (length / FOOTPRINT_DISCS)
    heading = np.stack([np.cos(states[..., 3]), np.sin(states[..., 3])], axis=-1)
    centres = states[..., None, :2] + offsets[:, None] * heading[..., None, :]
    return centres, float(np.hypot(length / (2 * FOOTPRINT_DISCS), width / 2))


@dataclass(frozen=True, eq=False)
class RoadScene:
    """What a baseline planner knows of the road at one decision, as arrays and callables.

    Parameters
    ----------
    reference
        A `RoadReference`: progress along the route, offset from the nearest lane centre
        the ego may use, and its heading, at any points.
    on_road
        A `RoadTest`: whether points lie on the road.
    vehicles
        The other vehicles' measured states ``(x, y, v, psi)``, shape (m, 4); m = 0 allowed.
    goal_progress
        The progress (m, as `reference` measures it) at which the goal is reached.
    speed_limit
        The speed the ego should not exceed, m/s (the reward's v_max).
    lane_width
        Lane width, m (normalises the lane-keeping terms).
    local_goals
        Candidate local goals for an elastic band, shape (g, 2), e.g. one per lane
        ahead; g = 0 allowed (a planner that needs one raises).
    vehicle_length, vehicle_width
        The other vehicles' rectangle, m.
    """

    reference: RoadReference
    on_road: RoadTest
    vehicles: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    goal_progress: float = np.inf
    speed_limit: float = 30.0
    lane_width: float = 4.0
    local_goals: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    vehicle_length: float = 5.0
    vehicle_width: float = 2.0

    def __post_init__(self) -> None:
        for name in ("reference", "on_road"):
            if not callable(getattr(self, name)):
                raise InputError(f"{name} must be callable, got {type(getattr(self, name)).__name__}")
        vehicles = np.zeros((0, 4)) if self.vehicles is None else as_finite_array("vehicles", self.vehicles)
        if vehicles.size == 0:
            vehicles = vehicles.reshape(0, 4)
        check_shape("vehicles", vehicles, (None, 4))
        object.__setattr__(self, "vehicles", vehicles)
        object.__setattr__(self, "local_goals", _points("local_goals", self.local_goals))
        goal = float(self.goal_progress)
        if np.isnan(goal):
            raise InputError("goal_progress must not be NaN")
        object.__setattr__(self, "goal_progress", goal)
        for name in ("speed_limit", "lane_width", "vehicle_length", "vehicle_width"):
            object.__setattr__(self, name, as_positive_scalar(name, getattr(self, name)))

    def predicted(self, times: np.ndarray) -> np.ndarray:
        """The vehicles at constant velocity (speed and heading held), shape (T, m, 4).

        Parameters
        ----------
        times : numpy.ndarray, shape (T,)
            Seconds after the measurement.
        """
        v = self.vehicles
        t = np.asarray(times, dtype=float)[:, None]
        out = np.broadcast_to(v, (t.shape[0],) + v.shape).copy()
        out[..., 0] = v[:, 0] + v[:, 2] * np.cos(v[:, 3]) * t
        out[..., 1] = v[:, 1] + v[:, 2] * np.sin(v[:, 3]) * t
        return out


def _road_clearance(ego: np.ndarray, times: np.ndarray, scene: RoadScene, length: float, width: float) -> np.ndarray:
    """Lower bound of the gap between the ego's rectangles ``ego`` (k, T, 4) and every other
    vehicle at constant velocity at ``times`` (T,): the smallest disc-cover gap, (k, T) (inf
    without vehicles)."""
    if scene.vehicles.shape[0] == 0:
        return np.full(ego.shape[:2], np.inf)
    mine, r_ego = rectangle_discs(ego, length, width)  # (k, T, 3, 2)
    theirs, r_other = rectangle_discs(scene.predicted(times), scene.vehicle_length, scene.vehicle_width)  # (T, m, 3, 2)
    rel = mine[:, :, None, :, None, :] - theirs[None, :, :, None, :, :]  # (k, T, m, 3, 3, 2)
    gaps = np.sqrt(np.einsum("...i,...i->...", rel, rel)) - (r_ego + r_other)
    return gaps.min(axis=(2, 3, 4))


def _off_road(ego: np.ndarray, scene: RoadScene, length: float, width: float) -> np.ndarray:
    """How many rectangle corners of the ego states (k, T, 4) are off the road, (k, T)."""
    c, s = np.cos(ego[..., 3]), np.sin(ego[..., 3])
    forward = np.stack([c, s], axis=-1)[..., None, :] * (length / 2)
    left = np.stack([-s, c], axis=-1)[..., None, :] * (width / 2)
    signs_f = np.array([1.0, 1.0, -1.0, -1.0])[:, None]
    signs_l = np.array([1.0, -1.0, -1.0, 1.0])[:, None]
    corners = ego[..., None, :2] + signs_f * forward + signs_l * left  # (k, T, 4, 2)
    return (~np.asarray(scene.on_road(corners), dtype=bool)).sum(axis=-1)


def steering_window(speed: float, lateral_acceleration: float, max_steering: float, length: float) -> float:
    """The steering magnitude at which the bicycle's lateral acceleration reaches a bound.

    ``v^2 sin(beta) / (L / 2) = a_lat`` with ``beta = arctan(tan(delta) / 2)``, capped at
    ``max_steering`` (and below 0.5 m/s the cap itself).

    Parameters
    ----------
    speed : float
        m/s.
    lateral_acceleration : float
        m/s^2 (> 0).
    max_steering : float
        rad.
    length : float
        The bicycle's L, m.
    """
    v = max(float(speed), 0.5)
    sin_beta = min(1.0, lateral_acceleration * (length / 2) / (v * v))
    delta = float(np.arctan(2.0 * np.tan(np.arcsin(sin_beta)))) if sin_beta < 1.0 else np.pi / 2
    return min(delta, float(max_steering))


@dataclass(frozen=True)
class VehicleDWAParameters:
    """Tuned weights and limits of `VehicleDynamicWindow` (see docs/baselines.md, driving).

    Attributes
    ----------
    acceleration_samples, steering_samples
        The window is sampled on an ``acceleration_samples x steering_samples`` grid
        (odd counts hold 0; the paper's Table 1 "(10, 0, 10)" samples).
    horizon
        Prediction horizon over which a sample is held to score it, s.
    lateral_acceleration
        The steering window at speed v is the steering whose lateral acceleration is this, m/s^2.
    safety_margin
        Clearance (lower bound, disc covers) demanded of admissible samples along the
        held rollout, m.
    road_margin
        Admissible rollouts keep the footprint grown by this on every side on the road
        (the measured state is noisy), m.
    clearance_cap
        Clearances above this count as "free" in the clearance score, m.
    progress_weight, lane_weight, heading_weight, clearance_weight, speed_weight
        Weights of the normalised terms of the objective (started from Table 1:
        reaching the local goal 24, closest point 40, avoiding obstacles 0.25; tuning
        lowered the lane weight to 10).
    """

    acceleration_samples: int = 11
    steering_samples: int = 11
    horizon: float = 2.0
    lateral_acceleration: float = 4.0
    safety_margin: float = 0.3
    road_margin: float = 0.3
    clearance_cap: float = 10.0
    progress_weight: float = 24.0
    lane_weight: float = 10.0
    heading_weight: float = 10.0
    clearance_weight: float = 0.25
    speed_weight: float = 0.0

    def __post_init__(self) -> None:
        for name in ("acceleration_samples", "steering_samples"):
            as_count(name, getattr(self, name), minimum=2)
        for name in ("horizon", "lateral_acceleration", "clearance_cap"):
            as_positive_scalar(name, getattr(self, name))
        for name in (
            "safety_margin",
            "road_margin",
            "progress_weight",
            "lane_weight",
            "heading_weight",
            "clearance_weight",
            "speed_weight",
        ):
            as_positive_scalar(name, getattr(self, name), allow_zero=True)

    def to_dict(self) -> dict:
        """The parameters as a plain dict (JSON-ready)."""
        return asdict(self)


class BicycleBaseline:
    """The ego bicycle shared by the road baselines (`VehicleDynamicWindow`, `VehicleElasticBand`).

    Attributes
    ----------
    dynamics : VehicleDynamics
        The vectorised bicycle step (the analysis layer passes the world's).
    dt : float
        Sub-step, s.
    substeps : int
        Sub-steps per decision.
    acceleration_bound, max_steering : float
        The admissible control box, m/s^2 and rad.
    length, width : float
        The rectangle, m.
    """

    dynamics: VehicleDynamics
    dt: float
    substeps: int
    acceleration_bound: float
    max_steering: float
    length: float
    width: float

    def _set_vehicle(self, dynamics, dt, substeps, acceleration_bound, max_steering, length, width) -> None:
        if not callable(dynamics):
            raise InputError(f"dynamics must be callable, got {type(dynamics).__name__}")
        self.dynamics = dynamics
        self.dt = as_positive_scalar("dt", dt)
        self.substeps = as_count("substeps", substeps)
        self.acceleration_bound = as_positive_scalar("acceleration_bound", acceleration_bound)
        self.max_steering = as_positive_scalar("max_steering", max_steering)
        self.length = as_positive_scalar("length", length)
        self.width = as_positive_scalar("width", width)

    def control_window(
        self, speed: float, *, acceleration_samples: int, steering_samples: int, lateral_acceleration: float
    ) -> np.ndarray:
        """A grid of controls ``(a, delta)`` at this speed, shape (k, 2), all admissible for the ego.

        The accelerations span ``[-acceleration_bound, acceleration_bound]``, the
        steerings the `steering_window` of ``lateral_acceleration`` at ``speed``.

        Parameters
        ----------
        speed : float
            The ego's speed, m/s.
        acceleration_samples, steering_samples : int
            Grid points per axis (odd counts hold 0).
        lateral_acceleration : float
            The steering window's lateral acceleration, m/s^2.
        """
        a = np.linspace(-1.0, 1.0, acceleration_samples) * self.acceleration_bound
        d = np.linspace(-1.0, 1.0, steering_samples) * steering_window(
            speed, lateral_acceleration, self.max_steering, self.length
        )
        return _control_grid(a, d)


class VehicleDynamicWindow(BicycleBaseline):
    """DWA for a car-like ego: a sampled (acceleration, steering) window on a given dynamics.

    Parameters
    ----------
    dynamics
        A `VehicleDynamics` (one vectorised sub-step); the planner has no model of its own.
    dt
        Its sub-step, s.
    substeps
        Sub-steps per decision period (a control is held that long).
    acceleration_bound, max_steering
        The admissible controls ``[-a, a] x [-max_steering, max_steering]`` (m/s^2, rad).
    length, width
        The ego's rectangle, m (L is also the bicycle's length in the steering window).
    params
        `VehicleDWAParameters`.

    Notes
    -----
    Every sample ``(a, delta)`` of the window (``a`` over the whole acceleration range,
    ``delta`` within `steering_window` of the current speed) is held for ``horizon``
    seconds through ``dynamics``. It is *admissible* when its rollout stays on the road
    (every corner of the footprint grown by ``road_margin``) and keeps ``safety_margin`` from every other vehicle moved at its
    measured speed and heading (the disc covers of `rectangle_discs`), and its speed
    after one period does not exceed the scene's speed limit unless it slows down. The
    score of an admissible sample (all terms in [0, 1] but progress, about [-1, 1]):
    ``progress_weight * (p_end - p_0) / (speed_limit * horizon)
    + lane_weight * (1 - min(|offset_end| / (lane_width / 2), 1))
    + heading_weight * (1 + cos(psi_end - heading_end)) / 2
    + clearance_weight * min(clearance, cap) / cap
    + speed_weight * min(v_end / speed_limit, 1)``, with the scene's `RoadReference`
    (progress, offset from the nearest lane centre, its heading) at the rollout's end.
    Without an admissible sample DWA takes the one whose rollout violates the clearance
    and the road least (`DWAEvaluation.fallback`).
    """

    def __init__(
        self,
        dynamics: VehicleDynamics,
        *,
        dt: float,
        substeps: int = 5,
        acceleration_bound: float = 6.0,
        max_steering: float = float(np.pi / 3),
        length: float = 5.0,
        width: float = 2.0,
        params: VehicleDWAParameters = VehicleDWAParameters(),
    ):
        check_instance("params", params, VehicleDWAParameters)
        self._set_vehicle(dynamics, dt, substeps, acceleration_bound, max_steering, length, width)
        self.params = params
        self._steps = max(self.substeps, int(round(params.horizon / self.dt)))

    def window(self, speed: float) -> np.ndarray:
        """The sampled controls ``(a, delta)`` at this speed, shape (k, 2), all admissible for the ego.

        Parameters
        ----------
        speed : float
            The ego's speed, m/s.
        """
        p = self.params
        return self.control_window(
            speed,
            acceleration_samples=p.acceleration_samples,
            steering_samples=p.steering_samples,
            lateral_acceleration=p.lateral_acceleration,
        )

    def rollout(self, state: np.ndarray, controls: np.ndarray, steps: int) -> np.ndarray:
        """States (k, steps, 4) after holding each control (k, 2) from ``state`` (4,) through ``dynamics``.

        Parameters
        ----------
        state : numpy.ndarray, shape (4,)
            ``(x, y, v, psi)``.
        controls : numpy.ndarray, shape (k, 2)
            ``(acceleration, steering)``.
        steps : int
            Sub-steps.
        """
        k = controls.shape[0]
        out = np.empty((k, steps, 4))
        x = np.broadcast_to(state, (k, 4)).copy()
        for n in range(steps):
            x = np.asarray(self.dynamics(x, controls[:, 0], controls[:, 1], self.dt), dtype=float)
            if x.shape != (k, 4):
                raise DimensionError(f"dynamics must return states of shape {(k, 4)}, got shape {x.shape}")
            out[:, n] = x
        return out

    def evaluate(self, state, scene: RoadScene) -> DWAEvaluation:
        """Score every sample of the window from the measured ego ``state``.

        Parameters
        ----------
        state : array_like, shape (4,)
            The ego's ``(x, y, v, psi)``.
        scene : RoadScene
            The road and the other vehicles, as seen now.

        Returns
        -------
        DWAEvaluation
            Every sample's score, admissibility and clearance, and the chosen control.
        """
        check_instance("scene", scene, RoadScene)
        x = _validated_state(state, 4)
        p = self.params
        controls = self.window(float(x[2]))
        held = self.rollout(x, controls, self._steps)
        times = self.dt * np.arange(1, self._steps + 1)
        gaps = _road_clearance(held, times, scene, self.length, self.width)  # (k, T)
        grow = 2 * p.road_margin
        off = _off_road(held, scene, self.length + grow, self.width + grow)  # (k, T)
        clearance = gaps.min(axis=1)
        violation = np.maximum(p.safety_margin - gaps, 0.0).sum(axis=1) + off.sum(axis=1)
        admissible = violation == 0.0
        speed_after = held[:, self.substeps - 1, 2]
        admissible &= (speed_after <= scene.speed_limit) | (speed_after < x[2])
        progress0, _, _ = scene.reference(x[None, :2])
        end = held[:, -1]
        progress, offset, heading = scene.reference(end[:, :2])
        score = (
            p.progress_weight * (progress - float(progress0[0])) / (scene.speed_limit * p.horizon)
            + p.lane_weight * (1.0 - np.minimum(np.abs(offset) / (scene.lane_width / 2), 1.0))
            + p.heading_weight * (1.0 + np.cos(end[:, 3] - heading)) / 2.0
            + p.clearance_weight * np.clip(clearance, 0.0, p.clearance_cap) / p.clearance_cap
            + p.speed_weight * np.minimum(end[:, 2] / scene.speed_limit, 1.0)
        )
        return _choose(controls, score, admissible, violation, clearance)

    def plan(self, state, scene: RoadScene) -> np.ndarray:
        """The control ``(acceleration, steering)`` to hold for the next decision period.

        Parameters
        ----------
        state : array_like, shape (4,)
            The ego's ``(x, y, v, psi)``.
        scene : RoadScene
            The road and the other vehicles, as seen now.
        """
        return self.evaluate(state, scene).control
