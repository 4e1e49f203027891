"""Dynamic Window Approach (Fox, Burgard & Thrun 1997) for a point mass with friction.

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
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.models.system import UncertainLinearSystem
from minimaxplan.models.validation import as_count, as_finite_array, as_positive_scalar, check_instance, check_shape

from .navigation import NavigationFunction

__all__ = ["NavigationScene", "DWAParameters", "DWAEvaluation", "DynamicWindowPlanner", "planar_robot_model"]


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


def _validated_state(state, nstates: int) -> np.ndarray:
    return as_finite_array("state", state, (nstates,))


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
    its points)."""

    controls: np.ndarray
    scores: np.ndarray
    admissible: np.ndarray
    min_clearance: np.ndarray
    control: np.ndarray
    fallback: bool

    def to_dict(self) -> dict:
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

    # The navigation function of the last scene, and the key it was built for.
    _nav: NavigationFunction | None = None
    _nav_key: tuple[bytes, bytes, bytes] | None = None

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
        self.controls = np.stack(np.meshgrid(grid, grid, indexing="ij"), axis=-1).reshape(-1, 2)
        self._horizon_steps = max(self.substeps, int(round(params.horizon / self._dt)))
        self._brake_steps = int(round(params.brake_time / self._dt))

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
        scores = np.where(admissible, score, -np.inf)
        if np.any(admissible):
            control = self.controls[int(np.argmax(scores))].copy()
            fallback = False
        else:
            # Nothing admissible (e.g. already inside the margin): the sample whose stopping
            # path violates the clearance least in total (summed over its points), the best escape.
            control = self.controls[int(np.argmin(violation))].copy()
            fallback = True
        return DWAEvaluation(self.controls.copy(), scores, admissible, clearance, control, fallback)

    def _navigation(self, scene: NavigationScene, points: np.ndarray) -> NavigationFunction:
        """The navigation function of this scene's goal and static discs (cached; rebuilt
        when they change or the points leave its grid)."""
        key = (scene.goal.tobytes(), scene.obstacle_centers.tobytes(), scene.obstacle_radii.tobytes())
        nav = self._nav
        if nav is None or self._nav_key != key or not nav.covers(points):
            nav = NavigationFunction(
                scene.goal,
                scene.obstacle_centers,
                scene.obstacle_radii,
                clearance=self.robot_radius + self.params.safety_margin,
                region=points,
                resolution=self.params.grid_resolution,
            )
            self._nav, self._nav_key = nav, key
        return nav

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
