"""Timed Elastic Band (Rösmann et al. 2015) for a point mass with friction.

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
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import minimize

from minimaxplan.models.errors import InputError, SolverFailure
from minimaxplan.models.system import UncertainLinearSystem
from minimaxplan.models.validation import as_count, as_finite_array, as_positive_scalar, check_instance

from .dwa import NavigationScene, planar_robot_model
from .navigation import NavigationFunction

__all__ = ["TEBParameters", "TEBPlan", "TimedElasticBand", "band_cost", "LBFGSB_STATUS"]

#: scipy's L-BFGS-B statuses and what they mean for a band; any other status raises.
LBFGSB_STATUS = {0: "converged", 1: "iteration_limit", 2: "line_search_stopped"}


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
        if self.min_poses > self.max_poses:
            raise InputError(f"min_poses must be <= max_poses, got {self.min_poses} > {self.max_poses}")
        if not self.dt_min < self.dt_ref < self.dt_max:
            raise InputError(f"need dt_min < dt_ref < dt_max, got {self.dt_min}, {self.dt_ref}, {self.dt_max}")

    def to_dict(self) -> dict:
        """The parameters as a plain dict (JSON-ready)."""
        return asdict(self)


@dataclass(frozen=True, eq=False)
class TEBPlan:
    """One TEB call: the optimised band ``positions`` (n + 1, 2), ``intervals`` (n,),
    its ``cost``, the worst clearance shortfall ``violation`` (m, 0 if none), the
    optimiser's ``iterations`` and ``status`` (a value of `LBFGSB_STATUS`) and the
    ``control`` (2,) for the next period."""

    positions: np.ndarray
    intervals: np.ndarray
    cost: float
    violation: float
    iterations: int
    status: str
    control: np.ndarray

    def to_dict(self) -> dict:
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
) -> tuple[float, np.ndarray]:
    """The band's cost and its gradient with respect to ``z = (X_1..X_{n-1} flattened, dT_0..dT_{n-1})``.

    ``discs = (centers (k, 2), velocities (k, 2), radii (k,), required clearance (k,))``.
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

    # chain the velocities to positions and intervals
    g_seg = g_v / dT[:, None]
    g_dT += -np.sum(g_v * seg, axis=1) / dT**2
    g_X[1:] += g_seg
    g_X[:-1] -= g_seg
    grad = np.concatenate([g_X[1:-1].ravel(), g_dT])
    return cost, grad


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
        key = (scene.goal.tobytes(), scene.obstacle_centers.tobytes(), scene.obstacle_radii.tobytes())
        nav = self._nav
        if nav is None or self._nav_key != key or not nav.covers(start):
            nav = NavigationFunction(
                scene.goal,
                scene.obstacle_centers,
                scene.obstacle_radii,
                clearance=self.robot_radius + self.params.obstacle_margin,
                region=start[None],
                resolution=self.params.grid_resolution,
            )
            self._nav, self._nav_key = nav, key
        try:
            return nav.path(start)
        except InputError:
            return None  # boxed in on the grid: fall back to the straight line

    def _warm_band(self, band: tuple[np.ndarray, np.ndarray], start) -> tuple[np.ndarray, np.ndarray]:
        X, dT = band
        # Drop the poses already passed: keep from the pose nearest to the robot (among the first few).
        look = min(len(dT), 4)
        nearest = int(np.argmin(np.linalg.norm(X[: look + 1] - start, axis=1)))
        nearest = min(nearest, len(dT) - 1)
        X = X[nearest:].copy()
        dT = dT[nearest:].copy()
        X[0] = start
        return self._resize(X, dT)

    def _resize(self, X, dT) -> tuple[np.ndarray, np.ndarray]:
        """One pass of TEB's automatic resizing: split intervals longer than
        ``dt_ref + hysteresis``, merge those shorter than ``dt_ref - hysteresis`` with
        their successor (each interval is touched at most once per call, so it terminates)."""
        p = self.params
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
        p = self.params
        n = len(dT)
        start, goal = X[0], X[-1]
        z0 = np.concatenate([X[1:-1].ravel(), dT])
        bounds = [(None, None)] * (2 * (n - 1)) + [(p.dt_min, p.dt_max)] * n
        result = minimize(
            band_cost,
            z0,
            args=(start, velocity, goal, n, self.friction, discs, p, self.control_bound),
            jac=True,
            method="L-BFGS-B",
            bounds=bounds,
            options={"maxiter": p.max_iterations},
        )
        status = LBFGSB_STATUS.get(int(result.status))
        if status is None or not np.all(np.isfinite(result.x)) or not np.isfinite(result.fun):
            raise SolverFailure(f"L-BFGS-B failed on the band (status {result.status}: {result.message})")
        # Every named status gives a usable band: the penalties are soft and the band is
        # re-optimised at the next call, and L-BFGS-B returns its best iterate.
        X = np.concatenate([start[None], result.x[: 2 * (n - 1)].reshape(n - 1, 2), goal[None]])
        dT = result.x[2 * (n - 1) :]
        return X, dT, float(result.fun), int(result.nit), status

    def _violation(self, X, dT, discs) -> float:
        centers, velocities, radii, required = discs
        if centers.shape[0] == 0:
            return 0.0
        T = np.concatenate([[0.0], np.cumsum(dT)])
        points = np.concatenate([X, (X[:-1] + X[1:]) / 2])
        times = np.concatenate([T, T[:-1] + dT / 2])
        where = centers + times[:, None, None] * velocities
        gap = np.linalg.norm(points[:, None, :] - where, axis=-1) - radii
        return float(np.max(np.maximum(required - gap, 0.0)))

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
        if best is None or self._violation(best[0], best[1], discs) > self.params.reinit_violation:
            guide = self._guide(start, scene)
            amplitude = self.params.detour_amplitude
            for bump in (0.0, amplitude, -amplitude):
                trial = self._optimise(*self._fresh_band(start, scene.goal, bump, guide), velocity, discs)
                if best is None or self._score(trial, discs) < self._score(best, discs):
                    best = trial
                if (
                    bump == 0.0
                    and guide is not None
                    and self._violation(trial[0], trial[1], discs) <= self.params.reinit_violation
                ):
                    break  # the band along the global path is clear: no need for side bumps
        assert best is not None  # the fresh bands above run whenever no warm band did
        X, dT, cost, iterations, status = best
        self._band = (X, dT)
        return TEBPlan(X, dT, cost, self._violation(X, dT, discs), iterations, status, self._control(X, dT, velocity))

    def _score(self, band, discs) -> tuple[bool, float]:
        """Bands without clearance violation (beyond the tolerance) first, then by cost."""
        return (self._violation(band[0], band[1], discs) > self.params.reinit_violation, band[2])

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
