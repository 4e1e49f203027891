"""Timed Elastic Band (Rösmann et al. 2015) for a point mass with friction and a car.

A baseline, not a robust planner: it plans with the nominal model (a point estimate of
the friction, no disturbance) and the pedestrians' announced velocities.

The band is a sequence of positions ``X_0 .. X_n`` (``X_0`` the measured position,
``X_n`` the goal) and time intervals ``dT_0 .. dT_{n-1}`` between them. Its cost is a
weighted sum of soft penalties, minimised by L-BFGS-B with an analytic gradient:

* time optimality: ``w_time * sum_i dT_i``;
* velocity limit: ``v_i = (X_{i+1} - X_i) / dT_i``, penalty ``w_velocity * max(0, |v_i| - v_max)^2``;
* input limit through the dynamics ``d(vel)/dt = -xi vel + u``: at every inner pose
  ``u_i = (v_i - v_{i-1}) / tau_i + xi * (v_i + v_{i-1}) / 2`` with
  ``tau_i = (dT_{i-1} + dT_i) / 2`` (and at ``X_0`` from the measured velocity over
  ``dT_0 / 2``), penalty ``w_input * max(0, |u_i| - u_max)^2`` per axis;
* clearance: at every pose and segment midpoint, for each disc (static, or a pedestrian
  at its predicted position ``c + v t`` at that point's band time),
  ``w_obstacle * max(0, d_min - (|q - c| - R))^2`` with ``d_min = robot_radius + margin``.

The band is warm-started between calls (poses already passed are dropped, the first
pose moves to the measured position) and resized so that every ``dT`` stays near
``dt_ref`` (within ``resize_hysteresis``). As a stand-in for TEB's exploration of
homotopy classes, fresh bands are tried whenever the band is (re)initialised or the
warm band still violates a clearance by more than ``reinit_violation``: first along
the shortest grid path of a `NavigationFunction` around the static discs (the global
plan TEB follows in ROS), then, if that one still violates a clearance, bent to either
side (a lateral bump); the cheapest band wins. The control for the next decision period makes the
nominal model reach the band's velocity at the end of the period.

For a car-like ego on a road (`VehicleElasticBand`) the same `band_cost` is used with
an extra penalty on the poses (`turning_cost`, the car's kinematics, and lane keeping),
one band per local goal (lane) as the homotopy classes, and the band is tracked by
sampled rollouts of a given vectorised dynamics (the worlds' kinematic bicycle).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import minimize

from minimaxplan.models.errors import InputError, SolverFailure
from minimaxplan.models.system import UncertainLinearSystem
from minimaxplan.models.validation import as_count, as_finite_array, as_positive_scalar, check_instance

from .dwa import (
    BicycleBaseline,
    NavigationScene,
    RoadScene,
    VehicleDynamics,
    _off_road,
    planar_robot_model,
)
from .navigation import NavigationCache

__all__ = [
    "TEBParameters",
    "TEBPlan",
    "TimedElasticBand",
    "band_cost",
    "LBFGSB_STATUS",
    "VehicleTEBParameters",
    "VehicleElasticBand",
    "turning_cost",
]

#: scipy's L-BFGS-B statuses and what they mean for a band; any other status raises.
LBFGSB_STATUS = {0: "converged", 1: "iteration_limit", 2: "line_search_stopped"}


def _check_band_limits(params: TEBParameters | VehicleTEBParameters) -> None:
    """Raise `InputError` unless ``min_poses <= max_poses`` and ``dt_min < dt_ref < dt_max``."""
    if params.min_poses > params.max_poses:
        raise InputError(f"min_poses must be <= max_poses, got {params.min_poses} > {params.max_poses}")
    if not params.dt_min < params.dt_ref < params.dt_max:
        raise InputError(f"need dt_min < dt_ref < dt_max, got {params.dt_min}, {params.dt_ref}, {params.dt_max}")


@dataclass(frozen=True)
class TEBParameters:
    """Tuned weights and limits of `TimedElasticBand` (see docs/baselines.md).

    Attributes
    ----------
    dt_ref, resize_hysteresis
        Target time interval between poses, s, and the tolerance before resizing.
    min_poses, max_poses
        Bounds on the number of intervals n of the band.
    dt_min, dt_max
        Bounds on every interval, s.
    max_speed
        Velocity limit, m/s.
    obstacle_margin
        Clearance wanted beyond the footprint from static discs, m.
    pedestrian_margin
        Extra clearance wanted from pedestrians (their velocity is uncertain), m.
    time_weight, velocity_weight, input_weight, obstacle_weight
        Penalty weights.
    detour_amplitude
        Lateral size of the side bumps tried when (re)initialising, m.
    reinit_violation
        Fresh bands are tried when the warm band's clearance shortfall exceeds this, m
        (the penalties are soft, so tiny shortfalls inside the margin are normal).
    goal_jump
        A goal that moves less than this between calls (m) keeps the warm band, whose
        end pose follows it; a larger jump starts afresh.
    max_iterations
        L-BFGS-B iterations per optimisation.
    navigation_function
        Initialise fresh bands along the shortest grid path of a `NavigationFunction`
        around the static discs (TEB follows a global plan in ROS); otherwise along the
        straight line to the goal.
    grid_resolution
        Cell size of that navigation function, m.
    """

    dt_ref: float = 0.5
    resize_hysteresis: float = 0.1
    min_poses: int = 3
    max_poses: int = 40
    dt_min: float = 0.05
    dt_max: float = 3.0
    max_speed: float = 1.5
    obstacle_margin: float = 0.2
    pedestrian_margin: float = 0.4
    time_weight: float = 1.0
    velocity_weight: float = 50.0
    input_weight: float = 10.0
    obstacle_weight: float = 200.0
    detour_amplitude: float = 2.5
    reinit_violation: float = 0.05
    goal_jump: float = 2.0
    max_iterations: int = 25
    navigation_function: bool = True
    grid_resolution: float = 0.2

    def __post_init__(self) -> None:
        for name in (
            "dt_ref",
            "dt_min",
            "dt_max",
            "max_speed",
            "time_weight",
            "velocity_weight",
            "input_weight",
            "obstacle_weight",
            "grid_resolution",
        ):
            as_positive_scalar(name, getattr(self, name))
        for name in (
            "resize_hysteresis",
            "obstacle_margin",
            "pedestrian_margin",
            "detour_amplitude",
            "reinit_violation",
            "goal_jump",
        ):
            as_positive_scalar(name, getattr(self, name), allow_zero=True)
        for name in ("min_poses", "max_poses", "max_iterations"):
            as_count(name, getattr(self, name))
        _check_band_limits(self)

    def to_dict(self) -> dict:
        """The parameters as a plain dict (JSON-ready)."""
        return asdict(self)


@dataclass(frozen=True, eq=False)
class TEBPlan:
    """One TEB call: the optimised band ``positions`` (n + 1, 2), ``intervals`` (n,),
    its ``cost``, the worst clearance shortfall ``violation`` (m, 0 if none), the
    optimiser's ``iterations`` and ``status`` (a value of `LBFGSB_STATUS`) and the
    ``control`` (2,) for the next period.

    Attributes
    ----------
    positions : ndarray (n + 1, 2)
        The band's poses ``X_0..X_n``, m.
    intervals : ndarray (n,)
        The time intervals ``dT_0..dT_{n-1}`` between consecutive poses, s.
    cost : float
        The optimised `band_cost`.
    violation : float
        The band's worst clearance shortfall over its poses and segment midpoints, m (0 if none).
    iterations : int
        The L-BFGS-B iterations of the optimisation that gave the band.
    status : str
        How L-BFGS-B stopped, a value of `LBFGSB_STATUS`.
    control : ndarray (2,)
        The control to hold for the next period (an acceleration, or ``(a, delta)`` on a road).
    """

    positions: np.ndarray
    intervals: np.ndarray
    cost: float
    violation: float
    iterations: int
    status: str
    control: np.ndarray

    def to_dict(self) -> dict:
        """The plan as a dict of plain Python values (lists for arrays), for JSON."""
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in self.__dict__.items()}


# ------------------------------------------------------------------ the cost
def band_cost(
    z: np.ndarray,
    start: np.ndarray,
    velocity: np.ndarray,
    goal: np.ndarray,
    n: int,
    friction: np.ndarray,
    discs: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    params: TEBParameters,
    control_bound: float = 1.0,
    extra: Callable[[np.ndarray], tuple[float, np.ndarray]] | None = None,
) -> tuple[float, np.ndarray]:
    """The band's cost and its gradient with respect to ``z = (X_1..X_{n-1} flattened, dT_0..dT_{n-1})``.

    Parameters
    ----------
    z : numpy.ndarray, shape (2 (n - 1) + n,)
        The free poses, flattened, then the intervals.
    start, velocity, goal : numpy.ndarray, shape (2,)
        ``X_0``, the measured velocity there and ``X_n``.
    n : int
        Number of intervals.
    friction : numpy.ndarray, shape (2,)
        Per-axis friction of the input-limit term (0 for no friction).
    discs : tuple of numpy.ndarray
        ``(centers (k, 2), velocities (k, 2), radii (k,), required clearance (k,))``.
    params : TEBParameters
        The weights and limits.
    control_bound : float
        The per-axis input limit.
    extra : callable, optional
        ``extra(X) -> (cost, gradient (n + 1, 2))`` adds penalties on the poses ``X``
        (n + 1, 2) (the vehicle band's lane keeping and turning radius); None for none.
    """
    inner = z[: 2 * (n - 1)].reshape(n - 1, 2)
    dT = z[2 * (n - 1) :]
    X = np.concatenate([start[None], inner, goal[None]])
    seg = X[1:] - X[:-1]
    v = seg / dT[:, None]
    g_v = np.zeros_like(v)
    g_dT = np.full(n, params.time_weight)
    cost = params.time_weight * float(dT.sum())

    # velocity limit
    speed = np.linalg.norm(v, axis=1)
    excess = np.maximum(speed - params.max_speed, 0.0)
    cost += params.velocity_weight * float(excess @ excess)
    g_v += (2 * params.velocity_weight * excess / np.maximum(speed, 1e-12))[:, None] * v

    # input limit through the dynamics, at X_0 (from the measured velocity) and inner poses
    prev = np.concatenate([velocity[None], v[:-1]])
    tau = np.concatenate([[dT[0] / 2], (dT[:-1] + dT[1:]) / 2])
    dv = v - prev
    u = dv / tau[:, None] + friction * (v + prev) / 2
    over = np.maximum(np.abs(u) - control_bound, 0.0)
    cost += params.input_weight * float(np.sum(over * over))
    g_u = 2 * params.input_weight * over * np.sign(u)
    g_v += g_u * (1 / tau[:, None] + friction / 2)
    g_v[:-1] += (g_u * (-1 / tau[:, None] + friction / 2))[1:]
    g_tau = -np.sum(g_u * dv, axis=1) / tau**2
    g_dT[0] += g_tau[0] / 2
    g_dT[:-1] += g_tau[1:] / 2
    g_dT[1:] += g_tau[1:] / 2

    # clearance at inner poses (times T_i) and segment midpoints (T_i + dT_i / 2)
    g_X = np.zeros_like(X)
    centers, disc_velocities, radii, required = discs
    if centers.shape[0]:
        T = np.concatenate([[0.0], np.cumsum(dT)])
        points = np.concatenate([X[1:-1], (X[:-1] + X[1:]) / 2])
        times = np.concatenate([T[1:-1], T[:-1] + dT / 2])
        where = centers + times[:, None, None] * disc_velocities  # (P, k, 2)
        rel = points[:, None, :] - where
        dist = np.linalg.norm(rel, axis=-1)
        short = np.maximum(required - (dist - radii), 0.0)
        cost += params.obstacle_weight * float(np.sum(short * short))
        direction = rel / np.maximum(dist, 1e-12)[..., None]
        g_point_disc = (-2 * params.obstacle_weight * short)[..., None] * direction  # d cost / d point, per disc
        g_point = g_point_disc.sum(axis=1)
        g_time = -np.einsum("pki,ki->p", g_point_disc, disc_velocities)
        g_X[1:-1] += g_point[: n - 1]
        g_X[:-1] += g_point[n - 1 :] / 2
        g_X[1:] += g_point[n - 1 :] / 2
        # times: T_i = sum_{k<i} dT_k for inner pose i; midpoint i: T_i + dT_i / 2
        g_T = np.zeros(n + 1)
        g_T[1:-1] += g_time[: n - 1]
        g_T[:-1] += g_time[n - 1 :]
        g_dT += g_time[n - 1 :] / 2
        # d T_i / d dT_k = 1 for k < i
        g_dT += np.cumsum(g_T[::-1])[::-1][1:]

    if extra is not None:
        extra_cost, extra_grad = extra(X)
        cost += float(extra_cost)
        g_X += extra_grad

    # chain the velocities to positions and intervals
    g_seg = g_v / dT[:, None]
    g_dT += -np.sum(g_v * seg, axis=1) / dT**2
    g_X[1:] += g_seg
    g_X[:-1] -= g_seg
    grad = np.concatenate([g_X[1:-1].ravel(), g_dT])
    return cost, grad


def _resize_band(X, dT, p: TEBParameters) -> tuple[np.ndarray, np.ndarray]:
    """One pass of TEB's automatic resizing: split intervals longer than
    ``dt_ref + hysteresis``, merge those shorter than ``dt_ref - hysteresis`` with
    their successor (each interval is touched at most once per call, so it terminates)."""
    X, dT = list(X), list(dT)
    i = 0
    while i < len(dT):
        if dT[i] > p.dt_ref + p.resize_hysteresis and len(dT) < p.max_poses:
            X.insert(i + 1, (X[i] + X[i + 1]) / 2)
            half = dT[i] / 2
            dT[i : i + 1] = [half, half]
            i += 2
        elif dT[i] < p.dt_ref - p.resize_hysteresis and len(dT) > p.min_poses and i + 1 < len(dT):
            del X[i + 1]
            dT[i : i + 2] = [dT[i] + dT[i + 1]]
            i += 1
        else:
            i += 1
    return np.array(X), np.clip(np.array(dT), p.dt_min, p.dt_max)


def _optimised_band(
    X: np.ndarray,
    dT: np.ndarray,
    velocity: np.ndarray,
    discs: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    params: TEBParameters,
    *,
    friction: np.ndarray,
    control_bound: float,
    extra: Callable[[np.ndarray], tuple[float, np.ndarray]] | None = None,
) -> tuple[np.ndarray, np.ndarray, float, int, str]:
    """The band ``(X, dT)`` optimised by L-BFGS-B on `band_cost`, its ends held.

    Returns ``(X, dT, cost, iterations, status)`` (``status`` a value of
    `LBFGSB_STATUS`); raises `SolverFailure` on any other status or a non-finite result.
    """
    n = len(dT)
    start, goal = X[0], X[-1]
    z0 = np.concatenate([X[1:-1].ravel(), dT])
    bounds = [(None, None)] * (2 * (n - 1)) + [(params.dt_min, params.dt_max)] * n
    result = minimize(
        band_cost,
        z0,
        args=(start, velocity, goal, n, friction, discs, params, control_bound, extra),
        jac=True,
        method="L-BFGS-B",
        bounds=bounds,
        options={"maxiter": params.max_iterations},
    )
    status = LBFGSB_STATUS.get(int(result.status))
    if status is None or not np.all(np.isfinite(result.x)) or not np.isfinite(result.fun):
        raise SolverFailure(f"L-BFGS-B failed on the band (status {result.status}: {result.message})")
    # Every named status gives a usable band: the penalties are soft and the band is
    # re-optimised at the next call, and L-BFGS-B returns its best iterate.
    X = np.concatenate([start[None], result.x[: 2 * (n - 1)].reshape(n - 1, 2), goal[None]])
    return X, result.x[2 * (n - 1) :], float(result.fun), int(result.nit), status


def _band_violation(X: np.ndarray, dT: np.ndarray, discs) -> float:
    """The band's worst clearance shortfall over its poses and segment midpoints, m (0 if none)."""
    centers, velocities, radii, required = discs
    if centers.shape[0] == 0:
        return 0.0
    T = np.concatenate([[0.0], np.cumsum(dT)])
    points = np.concatenate([X, (X[:-1] + X[1:]) / 2])
    times = np.concatenate([T, T[:-1] + dT / 2])
    where = centers + times[:, None, None] * velocities
    gap = np.linalg.norm(points[:, None, :] - where, axis=-1) - radii
    return float(np.max(np.maximum(required - gap, 0.0)))


def _trimmed_band(band: tuple[np.ndarray, np.ndarray], start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A copy of the warm band without the poses already passed (it starts at the pose
    nearest to ``start`` among its first few), its first pose moved to ``start``."""
    X, dT = band
    look = min(len(dT), 4)
    nearest = min(int(np.argmin(np.linalg.norm(X[: look + 1] - start, axis=1))), len(dT) - 1)
    X, dT = X[nearest:].copy(), dT[nearest:].copy()
    X[0] = start
    return X, dT


# ------------------------------------------------------------------ the planner
class TimedElasticBand:
    """TEB local planner with warm starts; `plan` returns the control for the next period.

    Parameters
    ----------
    system
        The robot's discrete model (4 states, 2 inputs, friction on the velocities).
    theta
        Friction to plan with (default: the centre of ``system.theta``), shape (d,);
        the per-axis friction is read off ``A(theta)``.
    substeps
        Sub-steps of ``system`` per decision period.
    robot_radius
        Footprint radius, m.
    params
        `TEBParameters`.
    control_bound
        Controls lie in ``[-control_bound, control_bound]^2``.
    """

    def __init__(
        self,
        system: UncertainLinearSystem,
        *,
        theta=None,
        substeps: int = 5,
        robot_radius: float = 0.3,
        params: TEBParameters = TEBParameters(),
        control_bound: float = 1.0,
    ):
        check_instance("params", params, TEBParameters)
        A, self._dt = planar_robot_model(system, theta, substeps)
        self._decay = np.diag(A)[2:].copy()  # per-axis velocity factor a = 1 - dt * xi
        self._gain = np.diag(system.B[2:]).copy()
        self.friction = (1.0 - self._decay) / self._dt
        self.system = system
        self.params = params
        self.substeps = int(substeps)
        self.robot_radius = as_positive_scalar("robot_radius", robot_radius, allow_zero=True)
        self.control_bound = as_positive_scalar("control_bound", control_bound)
        self._navigation_cache = NavigationCache(
            clearance=self.robot_radius + params.obstacle_margin, resolution=params.grid_resolution
        )
        self.reset()

    def reset(self) -> None:
        """Forget the warm-start band (e.g. at the start of an episode)."""
        self._band: tuple[np.ndarray, np.ndarray] | None = None
        self._goal: np.ndarray | None = None

    # ------------------------------------------------------------- bands
    def _fresh_band(self, start, goal, bump: float, guide: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """A band along ``guide`` (a polyline from start to goal) or the straight line,
        bent sideways by ``bump`` (m) in the middle."""
        p = self.params
        route = goal - start
        if guide is None:
            guide = np.stack([start, goal])
        guide = np.concatenate([start[None], guide[1:-1], goal[None]]) if len(guide) > 2 else np.stack([start, goal])
        pieces = np.linalg.norm(np.diff(guide, axis=0), axis=1)
        arc = np.concatenate([[0.0], np.cumsum(pieces)])
        length = float(arc[-1])
        speed = 0.8 * p.max_speed
        n = int(np.clip(np.ceil(length / (speed * p.dt_ref)), p.min_poses, p.max_poses))
        s = np.linspace(0.0, 1.0, n + 1)
        at = s * length
        X = np.stack([np.interp(at, arc, guide[:, 0]), np.interp(at, arc, guide[:, 1])], axis=1)
        normal = np.array([-route[1], route[0]]) / max(float(np.linalg.norm(route)), 1e-12)
        X = X + (bump * np.sin(np.pi * s))[:, None] * normal
        dT = np.full(n, max(length / n / speed, p.dt_min * 2))
        return X, dT

    def _guide(self, start, scene: NavigationScene) -> np.ndarray | None:
        """The navigation function's grid path from ``start`` to the goal (cached per scene), or None."""
        if not self.params.navigation_function:
            return None
        nav = self._navigation_cache.get(scene.goal, scene.obstacle_centers, scene.obstacle_radii, start[None])
        try:
            return nav.path(start)
        except InputError:
            return None  # boxed in on the grid: fall back to the straight line

    def _warm_band(self, band: tuple[np.ndarray, np.ndarray], start) -> tuple[np.ndarray, np.ndarray]:
        return self._resize(*_trimmed_band(band, start))

    def _resize(self, X, dT) -> tuple[np.ndarray, np.ndarray]:
        """One pass of TEB's automatic resizing (`_resize_band`)."""
        return _resize_band(X, dT, self.params)

    def _discs(self, scene: NavigationScene):
        p = self.params
        n_static = scene.obstacle_centers.shape[0]
        required = np.concatenate(
            [
                np.full(n_static, self.robot_radius + p.obstacle_margin),
                np.full(
                    scene.pedestrian_positions.shape[0], self.robot_radius + p.obstacle_margin + p.pedestrian_margin
                ),
            ]
        )
        return scene.centers, scene.velocities, scene.radii, required

    def _optimise(self, X, dT, velocity, discs):
        return _optimised_band(
            X, dT, velocity, discs, self.params, friction=self.friction, control_bound=self.control_bound
        )

    # ------------------------------------------------------------- control
    def _control(self, X, dT, velocity) -> np.ndarray:
        """The held control after which the nominal model moves at the band's velocity at the period's end."""
        period = self.substeps * self._dt
        T = np.cumsum(dT)
        segment = min(int(np.searchsorted(T, period)), len(dT) - 1)
        target = (X[segment + 1] - X[segment]) / dT[segment]
        a = self._decay
        n = self.substeps
        reach = self._gain * (1 - a**n) / np.where(a == 1.0, 1.0, 1 - a)
        reach = np.where(a == 1.0, self._gain * n, reach)
        u = (target - a**n * velocity) / reach
        return np.clip(u, -self.control_bound, self.control_bound)

    def optimise(self, state, scene: NavigationScene) -> TEBPlan:
        """Optimise the band from the measured ``state`` and return it with the control.

        Parameters
        ----------
        state : array_like, shape (4,)
            The measured robot state (position, velocity).
        scene : NavigationScene
            The goal and the discs to avoid, as seen now.

        Returns
        -------
        TEBPlan
            The optimised band, its cost and clearance violation, and the control.
        """
        check_instance("scene", scene, NavigationScene)
        x = as_finite_array("state", state, (4,))
        start, velocity = x[:2], x[2:]
        discs = self._discs(scene)
        if self._band is not None and self._goal is not None and not np.array_equal(self._goal, scene.goal):
            if np.linalg.norm(scene.goal - self._goal) <= self.params.goal_jump:
                # The (local) goal moved a little, e.g. a waypoint sliding along a global
                # path: keep the band and move its end, as TEB does with a moving local goal.
                X, dT = self._band
                X = X.copy()
                X[-1] = scene.goal
                self._band = (X, dT)
            else:
                self._band = None
        self._goal = scene.goal.copy()
        candidates = []
        if self._band is not None and len(self._band[1]) >= 1:
            candidates.append(self._warm_band(self._band, start))
        best = None
        for X, dT in candidates:
            best = self._optimise(X, dT, velocity, discs)
        if best is None or _band_violation(best[0], best[1], discs) > self.params.reinit_violation:
            guide = self._guide(start, scene)
            amplitude = self.params.detour_amplitude
            for bump in (0.0, amplitude, -amplitude):
                trial = self._optimise(*self._fresh_band(start, scene.goal, bump, guide), velocity, discs)
                if best is None or self._score(trial, discs) < self._score(best, discs):
                    best = trial
                if (
                    bump == 0.0
                    and guide is not None
                    and _band_violation(trial[0], trial[1], discs) <= self.params.reinit_violation
                ):
                    break  # the band along the global path is clear: no need for side bumps
        assert best is not None  # the fresh bands above run whenever no warm band did
        X, dT, cost, iterations, status = best
        self._band = (X, dT)
        return TEBPlan(X, dT, cost, _band_violation(X, dT, discs), iterations, status, self._control(X, dT, velocity))

    def _score(self, band, discs) -> tuple[bool, float]:
        """Bands without clearance violation (beyond the tolerance) first, then by cost."""
        return (_band_violation(band[0], band[1], discs) > self.params.reinit_violation, band[2])

    def plan(self, state, scene: NavigationScene) -> np.ndarray:
        """The control ``u`` (2,) to hold for the next decision period.

        Parameters
        ----------
        state : array_like, shape (4,)
            The measured robot state (position, velocity).
        scene : NavigationScene
            The goal and the discs to avoid, as seen now.
        """
        return self.optimise(state, scene).control


# ------------------------------------------------------------ TEB on the bicycle
def turning_cost(X: np.ndarray, heading: float, curvature: float, weight: float) -> tuple[float, np.ndarray]:
    """TEB's car-like kinematics: the band may turn at most ``curvature`` per metre.

    With ``theta_i`` the direction of segment ``X_{i+1} - X_i`` (``theta_{-1} = heading``,
    the vehicle's) and ``l_i`` its length, the cost is
    ``weight * sum_i max(0, |wrap(theta_i - theta_{i-1})| - curvature * l_i)^2``.

    Parameters
    ----------
    X : numpy.ndarray, shape (n + 1, 2)
        The band's positions.
    heading : float
        The vehicle's heading at ``X_0``, rad.
    curvature : float
        The largest curvature, 1/m (``tan(max_steering) / L`` for the bicycle).
    weight : float
        The penalty weight (Table 2's "non-holonomic kinematics").

    Returns
    -------
    cost : float
    gradient : numpy.ndarray, shape (n + 1, 2)
        With respect to ``X``.
    """
    seg = X[1:] - X[:-1]
    length = np.maximum(np.linalg.norm(seg, axis=1), 1e-9)
    theta = np.arctan2(seg[:, 1], seg[:, 0])
    previous = np.concatenate([[heading], theta[:-1]])
    turn = np.angle(np.exp(1j * (theta - previous)))
    excess = np.maximum(np.abs(turn) - curvature * length, 0.0)
    cost = weight * float(excess @ excess)
    g_turn = 2 * weight * excess * np.sign(turn)
    g_theta = g_turn.copy()
    g_theta[:-1] -= g_turn[1:]
    g_length = -2 * weight * excess * curvature
    perpendicular = np.stack([-seg[:, 1], seg[:, 0]], axis=1) / (length**2)[:, None]
    g_seg = g_theta[:, None] * perpendicular + g_length[:, None] * seg / length[:, None]
    grad = np.zeros_like(X)
    grad[1:] += g_seg
    grad[:-1] -= g_seg
    return cost, grad


@dataclass(frozen=True)
class VehicleTEBParameters:
    """Tuned weights and limits of `VehicleElasticBand` (see docs/baselines.md, driving).

    Attributes
    ----------
    dt_ref, resize_hysteresis
        Target time interval between poses, s, and the tolerance before resizing
        (Table 2: hysteresis 0.15).
    min_poses, max_poses
        Bounds on the number of intervals (Table 2: at least 5 samples).
    dt_min, dt_max
        Bounds on every interval, s.
    lookahead_time
        The local goals lie ``max(v, min_speed) * lookahead_time`` m ahead, s.
    min_speed
        See ``lookahead_time``, m/s.
    obstacle_margin
        Clearance wanted from the other vehicles' footprint covers, m (Table 2: 0.1).
    time_weight, velocity_weight, input_weight, obstacle_weight
        Penalty weights (Table 2: avoiding obstacles 0.55; scaled as the robot's 0.05 -> 200).
    kinematics_weight
        Weight of `turning_cost` (Table 2: non-holonomic kinematics 1000).
    lane_weight
        Weight of the squared offset from the nearest lane centre at every inner pose,
        1/m^2 (tuned: 10; 1 let the band cut into the crossing lanes at the junction).
    lateral_acceleration
        The steering tried to track the band lies within `steering_window` of this, m/s^2.
    acceleration_samples, steering_samples
        The grid of controls tried to track the band (odd counts hold 0).
    tracking_time
        Each tried control is held this long; the one ending nearest to the band's
        position at that time (with the footprint on the road) is applied, s.
    road_margin
        The tracking rollouts keep the footprint grown by this on every side on the road, m.
    switching_hysteresis
        A fresh band replaces the warm one (another lane, TEB's homotopy class) only
        when its cost is below this fraction of the warm band's.
    reinit_violation
        A warm band whose clearance shortfall exceeds this is not kept, m.
    max_iterations
        L-BFGS-B iterations per optimisation.
    """

    dt_ref: float = 0.5
    resize_hysteresis: float = 0.15
    min_poses: int = 5
    max_poses: int = 30
    dt_min: float = 0.05
    dt_max: float = 3.0
    lookahead_time: float = 4.0
    min_speed: float = 5.0
    obstacle_margin: float = 0.1
    time_weight: float = 1.0
    velocity_weight: float = 50.0
    input_weight: float = 10.0
    obstacle_weight: float = 2200.0
    kinematics_weight: float = 1000.0
    lane_weight: float = 10.0
    lateral_acceleration: float = 6.0
    acceleration_samples: int = 13
    steering_samples: int = 41
    tracking_time: float = 1.0
    road_margin: float = 0.3
    switching_hysteresis: float = 0.9
    reinit_violation: float = 0.05
    max_iterations: int = 25

    def __post_init__(self) -> None:
        for name in (
            "dt_ref",
            "dt_min",
            "dt_max",
            "lookahead_time",
            "min_speed",
            "time_weight",
            "velocity_weight",
            "input_weight",
            "obstacle_weight",
            "lateral_acceleration",
            "tracking_time",
            "switching_hysteresis",
        ):
            as_positive_scalar(name, getattr(self, name))
        for name in (
            "resize_hysteresis",
            "obstacle_margin",
            "kinematics_weight",
            "lane_weight",
            "reinit_violation",
            "road_margin",
        ):
            as_positive_scalar(name, getattr(self, name), allow_zero=True)
        for name in ("min_poses", "max_poses", "max_iterations", "acceleration_samples", "steering_samples"):
            as_count(name, getattr(self, name))
        _check_band_limits(self)

    def band_parameters(self, max_speed: float) -> TEBParameters:
        """The `TEBParameters` that `band_cost` reads, with the scene's speed limit.

        Parameters
        ----------
        max_speed : float
            The speed limit, m/s.
        """
        return TEBParameters(
            dt_ref=self.dt_ref,
            resize_hysteresis=self.resize_hysteresis,
            min_poses=self.min_poses,
            max_poses=self.max_poses,
            dt_min=self.dt_min,
            dt_max=self.dt_max,
            max_speed=max_speed,
            obstacle_margin=self.obstacle_margin,
            pedestrian_margin=0.0,
            time_weight=self.time_weight,
            velocity_weight=self.velocity_weight,
            input_weight=self.input_weight,
            obstacle_weight=self.obstacle_weight,
            max_iterations=self.max_iterations,
            navigation_function=False,
        )

    def to_dict(self) -> dict:
        """The parameters as a plain dict (JSON-ready)."""
        return asdict(self)


#: Footprint discs of another vehicle relative to the ego's centre: its centre plus
#: ``k L / 3`` along its heading, k = -2..2 (the Minkowski sum of two three-disc covers
#: of aligned rectangles), each of twice the cover radius.
_MINKOWSKI_STEPS = np.arange(-2, 3) / 3.0


class VehicleElasticBand(BicycleBaseline):
    """TEB for a car-like ego on a road: bands to each local goal, tracked through a given dynamics.

    Parameters
    ----------
    dynamics
        A `VehicleDynamics` (one vectorised sub-step), used to choose the steering
        that tracks the band.
    dt
        Its sub-step, s.
    substeps
        Sub-steps per decision period.
    acceleration_bound, max_steering
        The admissible controls ``[-a, a] x [-max_steering, max_steering]`` (m/s^2, rad).
    length, width
        The ego's rectangle, m (L is also the bicycle's length).
    params
        `VehicleTEBParameters`.

    Notes
    -----
    The band is the ego's position ``X_0``, free poses and a local goal ``X_n`` (one of
    the scene's ``local_goals``: one per lane on a highway, the route ahead at a
    junction), with the time intervals between them. Its cost is `band_cost` (time,
    speed limit, acceleration limit ``a`` per axis with no friction, clearance from the
    other vehicles moved at their measured velocity) plus `turning_cost` (curvature at
    most ``tan(max_steering) / L``) and a lane-keeping term ``lane_weight * offset^2``
    at every inner pose (offset from the nearest lane centre, the scene's
    `RoadReference`). Every call optimises a fresh straight band to every local goal and
    the warm band of the previous call (its end moved to the nearest local goal); the
    band without clearance violation, then of least cost, wins (TEB's homotopy classes,
    here the lanes). The control held for the next period: the acceleration that reaches
    the band's speed at the period's end, and the steering (among ``steering_samples``
    within `steering_window`) whose rollout through ``dynamics`` ends nearest to the
    band's position at that time; both within the admissible box.
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
        params: VehicleTEBParameters = VehicleTEBParameters(),
    ):
        check_instance("params", params, VehicleTEBParameters)
        self._set_vehicle(dynamics, dt, substeps, acceleration_bound, max_steering, length, width)
        self.params = params
        self.curvature = float(np.tan(self.max_steering) / self.length)
        self.reset()

    def reset(self) -> None:
        """Forget the warm-start band (e.g. at the start of an episode)."""
        self._band: tuple[np.ndarray, np.ndarray] | None = None

    def _discs(self, scene: RoadScene):
        """The other vehicles as moving discs around the ego's centre (`band_cost`'s ``discs``)."""
        v = scene.vehicles
        if v.shape[0] == 0:
            empty = np.zeros((0, 2))
            return empty, empty, np.zeros(0), np.zeros(0)
        heading = np.stack([np.cos(v[:, 3]), np.sin(v[:, 3])], axis=1)
        centres = (v[:, None, :2] + _MINKOWSKI_STEPS[None, :, None] * scene.vehicle_length * heading[:, None]).reshape(
            -1, 2
        )
        velocities = np.repeat(v[:, 2:3] * heading, len(_MINKOWSKI_STEPS), axis=0)
        cover = np.hypot(self.length / 6, self.width / 2) + np.hypot(scene.vehicle_length / 6, scene.vehicle_width / 2)
        radii = np.full(centres.shape[0], cover)
        return centres, velocities, radii, np.full(centres.shape[0], self.params.obstacle_margin)

    def _extra(self, scene: RoadScene, heading: float):
        p = self.params

        def extra(X: np.ndarray) -> tuple[float, np.ndarray]:
            cost, grad = turning_cost(X, heading, self.curvature, p.kinematics_weight)
            if p.lane_weight > 0 and X.shape[0] > 2:
                _, offset, lane_heading = scene.reference(X[1:-1])
                normal = np.stack([-np.sin(lane_heading), np.cos(lane_heading)], axis=1)
                cost += p.lane_weight * float(offset @ offset)
                grad[1:-1] += (2 * p.lane_weight * offset)[:, None] * normal
            return cost, grad

        return extra

    def _fresh(self, start: np.ndarray, goal: np.ndarray, speed: float, limit: float):
        p = self.params
        distance = float(np.linalg.norm(goal - start))
        cruise = float(np.clip(speed, p.min_speed, limit))
        n = int(np.clip(np.ceil(distance / (cruise * p.dt_ref)), p.min_poses, p.max_poses))
        s = np.linspace(0.0, 1.0, n + 1)[:, None]
        X = start + s * (goal - start)
        dT = np.full(n, max(distance / n / cruise, 2 * p.dt_min))
        return X, dT

    def _control(self, state: np.ndarray, X: np.ndarray, dT: np.ndarray, scene: RoadScene) -> np.ndarray:
        """The admissible ``(a, delta)`` that tracks the band.

        Every control of an ``acceleration_samples x steering_samples`` grid (the whole
        acceleration range, the steering within `steering_window`) is held for
        ``tracking_time`` through ``dynamics``; those whose footprint stays on the road
        are *feasible* (ROS TEB's feasibility check of the band's first poses), and the
        feasible control whose rollout ends nearest to the band's position at that time
        wins (the nearest of all if none is feasible).
        """
        p = self.params
        T = np.concatenate([[0.0], np.cumsum(dT)])
        horizon = min(p.tracking_time, float(T[-1]))
        segment = min(int(np.searchsorted(T, horizon, side="right")) - 1, len(dT) - 1)
        fraction = float(np.clip((horizon - T[segment]) / dT[segment], 0.0, 1.0))
        target = X[segment] + fraction * (X[segment + 1] - X[segment])
        controls = self.control_window(
            state[2],
            acceleration_samples=p.acceleration_samples,
            steering_samples=p.steering_samples,
            lateral_acceleration=p.lateral_acceleration,
        )
        k = controls.shape[0]
        steps = max(self.substeps, int(round(p.tracking_time / self.dt)))
        x = np.broadcast_to(state, (k, 4)).copy()
        off = np.zeros(k, dtype=int)
        for _ in range(steps):
            x = np.asarray(self.dynamics(x, controls[:, 0], controls[:, 1], self.dt), dtype=float)
            off += _off_road(x[:, None], scene, self.length + 2 * p.road_margin, self.width + 2 * p.road_margin)[:, 0]
        miss = np.linalg.norm(x[:, :2] - target, axis=1)
        feasible = off == 0
        best = int(np.argmin(np.where(feasible, miss, np.inf))) if feasible.any() else int(np.argmin(miss))
        return controls[best].copy()

    def optimise(self, state, scene: RoadScene) -> TEBPlan:
        """Optimise the bands from the measured ego ``state`` and return the best with the control.

        Parameters
        ----------
        state : array_like, shape (4,)
            The ego's ``(x, y, v, psi)``.
        scene : RoadScene
            The road, the other vehicles and the local goals (at least one).

        Returns
        -------
        TEBPlan
            The chosen band, its cost and clearance violation, and the control.
        """
        check_instance("scene", scene, RoadScene)
        x = as_finite_array("state", state, (4,))
        goals = scene.local_goals
        if goals.shape[0] == 0:
            raise InputError("scene must hold at least one local goal for the elastic band")
        p = self.params
        band = p.band_parameters(scene.speed_limit)
        start = x[:2]
        velocity = x[2] * np.array([np.cos(x[3]), np.sin(x[3])])
        discs = self._discs(scene)
        extra = self._extra(scene, float(x[3]))
        candidates = [self._fresh(start, goal, float(x[2]), scene.speed_limit) for goal in goals]
        warm = self._band is not None and len(self._band[1]) >= 1
        if warm:
            assert self._band is not None  # warm implies a band
            X, dT = _trimmed_band(self._band, start)
            X[-1] = goals[int(np.argmin(np.linalg.norm(goals - X[-1], axis=1)))]
            candidates.insert(0, _resize_band(X, dT, band))
        best, best_key = None, None
        for index, (X, dT) in enumerate(candidates):
            trial = _optimised_band(
                X, dT, velocity, discs, band, friction=np.zeros(2), control_bound=self.acceleration_bound, extra=extra
            )
            # The warm band (first, if any) keeps its class unless a fresh one is clearly cheaper.
            scale = 1.0 if warm and index == 0 else 1.0 / p.switching_hysteresis
            key = (_band_violation(trial[0], trial[1], discs) > p.reinit_violation, trial[2] * scale)
            if best_key is None or key < best_key:
                best, best_key = trial, key
        assert best is not None  # at least one local goal
        X, dT, cost, iterations, status = best
        self._band = (X, dT)
        return TEBPlan(X, dT, cost, _band_violation(X, dT, discs), iterations, status, self._control(x, X, dT, scene))

    def plan(self, state, scene: RoadScene) -> np.ndarray:
        """The control ``(acceleration, steering)`` to hold for the next decision period.

        Parameters
        ----------
        state : array_like, shape (4,)
            The ego's ``(x, y, v, psi)``.
        scene : RoadScene
            The road, the other vehicles and the local goals.
        """
        return self.optimise(state, scene).control
