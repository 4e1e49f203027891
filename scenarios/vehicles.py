"""The other vehicles of the driving worlds: a kinematic bicycle with the LinearVehicle law.

Everything is vectorised over vehicles (numpy arrays whose first axis is the vehicle)
and written as pure functions of frozen parameter dataclasses; the random draws take a
seeded `numpy.random.Generator` argument, never global state.

State of a vehicle: ``(x, y, v, psi)``: position (m), speed (m/s, >= 0), heading (rad,
not wrapped). Dynamics (`bicycle_step`, the kinematic bicycle of highway-env, forward
Euler with step dt, rear axle and centre of mass L / 2 apart):

    beta = arctan(tan(delta) / 2)
    x+   = x + v cos(psi + beta) dt,      y+ = y + v sin(psi + beta) dt,
    psi+ = psi + v sin(beta) / (L / 2) dt,
    v+   = clip(v + a dt, 0, max_speed).

Behaviour (highway-env's ``LinearVehicle``, linear in its parameters theta):

* acceleration ``a = clip(theta_a . f, -a_max, a_max) + w`` with the features
  ``f = [v_target - v, min(v_front - v, 0), min(gap - d0 - T v, 0)]`` (`acceleration_features`;
  ``gap`` is bumper to bumper, m, to the front object: the leader along the route, or a
  stop line when the vehicle yields; ``v_target`` is the target speed capped on and before
  arcs, `desired_speed`) and a bounded disturbance ``w ~ U[-w_bar, w_bar]``;
* steering ``delta = clip(theta_b . g, -delta_max, delta_max)`` with
  ``g = [wrap(h(s + tau v) - psi) L / v, -offset L / v^2]`` (`steering_features`; h the
  route's heading at the arc length reached after the pursuit time tau, offset the
  lateral offset from the route lane, v replaced by ``speed_epsilon`` when smaller).

theta is drawn per vehicle from the reference priors (`draw_parameters`): ``theta_a =
(0.3, 0.3, 2.0) x U[0.5, 1.5]`` and ``theta_b = (5, 8.33) + U[-(0.07, 1.5), (0.07, 1.5)]``
(per component).

Traffic rules (`traffic_step`): routes are lane sequences drawn at spawn; a vehicle
follows the nearest agent ahead that occupies one of its route lanes (or a side lane it
straddles); lane changes are decided on a timer (`TrafficRules`); at a junction a
vehicle yields, by a virtual stopped leader at its stop line, to traffic on or
approaching a conflicting lane of higher priority within the critical gap (the main
road has priority), and a *courteous* main-road vehicle also yields to any vehicle in
or waiting at a conflicting lane (for at most ``courtesy_patience`` s of waiting). The
controlled agent (the ego) takes part in every rule as an obstacle, and its own motion
comes from its control.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from minimaxplan.kernels.bicycle import bicycle_step_into
from minimaxplan.models.errors import DimensionError, InputError

from .road import Road, readonly_copy, wrap_to_pi

__all__ = [
    "VehicleParameters",
    "BehaviourParameters",
    "TrafficRules",
    "TrafficState",
    "StepRecord",
    "draw_parameters",
    "bicycle_step",
    "slip_angle",
    "acceleration_features",
    "linear_acceleration",
    "steering_features",
    "linear_steering",
    "vehicle_corners",
    "find_leaders",
    "desired_speed",
    "traffic_step",
]


@dataclass(frozen=True)
class VehicleParameters:
    """The kinematic bicycle shared by every vehicle (the ego's are known exactly).

    Attributes
    ----------
    length : float
        Vehicle length L, m (5); also the wheelbase of the bicycle (axle to centre L / 2).
    width : float
        Vehicle width, m (2).
    max_speed : float
        Speeds are clipped to ``[0, max_speed]``, m/s (40, highway-env's MAX_SPEED).
    max_steering : float
        Steering angles are clipped to ``[-max_steering, max_steering]``, rad (pi / 3).
    """

    length: float = 5.0
    width: float = 2.0
    max_speed: float = 40.0
    max_steering: float = float(np.pi / 3)

    def __post_init__(self) -> None:
        for name in ("length", "width", "max_speed", "max_steering"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise InputError(f"{name} must be finite and > 0, got {value!r}")
        if self.max_steering >= np.pi / 2:
            raise InputError(f"max_steering must be < pi / 2, got {self.max_steering}")

    def to_dict(self) -> dict:
        """The parameters as plain data."""
        return asdict(self)


@dataclass(frozen=True)
class BehaviourParameters:
    """Constants and parameter priors of the LinearVehicle law.

    Attributes
    ----------
    theta_a_nominal : tuple of 3 float
        Nominal acceleration gains (1/s, 1/s, 1/s^2): (0.3, 0.3, 2.0).
    theta_a_scale : tuple of 2 float
        Each component of theta_a is its nominal value times U[low, high]: (0.5, 1.5).
    theta_b_nominal : tuple of 2 float
        Nominal steering gains (1/s, 1/s^2): (5, 8.33), highway-env's KP_HEADING and
        KP_HEADING * KP_LATERAL.
    theta_b_spread : tuple of 2 float
        Each component of theta_b is its nominal value plus U[-spread, spread]: (0.07, 1.5).
    standstill_distance : float
        d0, the bumper-to-bumper gap kept at standstill, m (5; highway-env's
        DISTANCE_WANTED = 5 + L measured centre to centre).
    time_headway : float
        T, s (1.5): the desired gap grows by T v.
    pursuit_time : float
        tau, s (0.1, highway-env's TAU_PURSUIT): the steering aims at the route heading
        ``tau v`` ahead.
    route_switch_distance : float
        m (0): the steering may follow the next lane of the route from this distance
        before the end of its lane on (0: at the end, as this library's world does;
        highway-env's ``follow_road`` switches ``AbstractLane.VEHICLE_LENGTH / 2`` = 2.5 m
        early). Read by the forecast only (`minimaxplan.scenarios.traffic_models`, which
        then allows any switch point in that window); the library's world steers by the
        lane its centre is in.
    acceleration_bound : float
        a_max, m/s^2 (6): the law's output is clipped to ``[-a_max, a_max]``.
    disturbance_bound : float
        w_bar, m/s^2 (0.1): ``w ~ U[-w_bar, w_bar]`` is added to the clipped acceleration.
    speed_epsilon : float
        Speeds below this (m/s) are replaced by it in the steering features (0.01,
        highway-env's ``not_zero``).
    """

    theta_a_nominal: tuple = (0.3, 0.3, 2.0)
    theta_a_scale: tuple = (0.5, 1.5)
    theta_b_nominal: tuple = (5.0, 8.33)
    theta_b_spread: tuple = (0.07, 1.5)
    standstill_distance: float = 5.0
    time_headway: float = 1.5
    pursuit_time: float = 0.1
    route_switch_distance: float = 0.0
    acceleration_bound: float = 6.0
    disturbance_bound: float = 0.1
    speed_epsilon: float = 0.01

    def __post_init__(self) -> None:
        for name, length in (
            ("theta_a_nominal", 3),
            ("theta_a_scale", 2),
            ("theta_b_nominal", 2),
            ("theta_b_spread", 2),
        ):
            value = tuple(float(v) for v in getattr(self, name))
            if len(value) != length:
                raise DimensionError(f"{name} must have length {length}, got length {len(value)}")
            object.__setattr__(self, name, value)
        if not 0 <= self.theta_a_scale[0] <= self.theta_a_scale[1]:
            raise InputError(f"theta_a_scale must satisfy 0 <= low <= high, got {self.theta_a_scale}")
        if min(self.theta_b_spread) < 0:
            raise InputError(f"theta_b_spread must be >= 0, got {self.theta_b_spread}")
        for name in (
            "standstill_distance",
            "time_headway",
            "pursuit_time",
            "route_switch_distance",
            "acceleration_bound",
            "disturbance_bound",
            "speed_epsilon",
        ):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0 or (value == 0 and name in ("acceleration_bound", "speed_epsilon")):
                raise InputError(f"{name} must be finite and >= 0 (> 0 for bounds), got {value!r}")

    @property
    def theta_a_prior(self) -> tuple[np.ndarray, np.ndarray]:
        """``(low, high)`` of the acceleration gains' prior box."""
        nominal = np.array(self.theta_a_nominal)
        return nominal * self.theta_a_scale[0], nominal * self.theta_a_scale[1]

    @property
    def theta_b_prior(self) -> tuple[np.ndarray, np.ndarray]:
        """``(low, high)`` of the steering gains' prior box."""
        nominal, spread = np.array(self.theta_b_nominal), np.array(self.theta_b_spread)
        return nominal - spread, nominal + spread

    def to_dict(self) -> dict:
        """The parameters as plain data."""
        return asdict(self)


@dataclass(frozen=True)
class TrafficRules:
    """Lane changes and junction rules.

    Attributes
    ----------
    lane_change_interval : tuple of 2 float
        Each vehicle reconsiders its lane every ``U[low, high]`` s (its own period, drawn
        at spawn, with a random phase): (4, 8).
    lane_change_probability : float
        When its timer fires, a vehicle attempts a lane change with this probability
        (to the left or right neighbour with equal probability, if it exists): 0.5.
    lane_change_settled : float
        A vehicle counts as settled in its lane (and may start a new change) when
        ``|offset| <`` this, m (0.5).
    lane_change_margin : float
        A lane change is accepted when, in the target lane, the gap to the vehicle ahead
        is at least ``d0 + T v + margin`` and the gap of the vehicle behind at least
        ``d0 + T v_behind + margin``, m (2).
    critical_gap : float
        At a junction a vehicle enters its junction lane only if no agent on a
        conflicting higher-priority lane is on it or reaches it within this time, s (6).
    commit_distance : float
        A vehicle whose front is within this distance of its stop line and finds the
        junction clear commits: it no longer yields to anyone at this junction, m (6).
    courtesy_patience : float
        A courteous vehicle stops yielding to a *waiting* vehicle after having been
        held (below 1 m/s) for this long, s (3); it always yields to one that is on a
        conflicting lane.
    waiting_distance : float
        An agent within this distance of its stop line counts as waiting there, m (15).
    spawn_clearance : float
        A scheduled vehicle enters its first lane only when no agent on that lane is
        within this distance of its spawn point, m (20).
    curve_lateral_acceleration : float
        On an arc of curvature kappa, and within ``curve_approach`` m before one, a
        vehicle's target speed is capped at ``sqrt(curve_lateral_acceleration / |kappa|)``,
        m/s^2 (2.5: 4.7 m/s on the 9 m right turns, 5.7 m/s on the 13 m left turns).
    curve_approach : float
        See above, m (30).
    """

    lane_change_interval: tuple = (4.0, 8.0)
    lane_change_probability: float = 0.5
    lane_change_settled: float = 0.5
    lane_change_margin: float = 2.0
    critical_gap: float = 6.0
    commit_distance: float = 6.0
    courtesy_patience: float = 3.0
    waiting_distance: float = 15.0
    spawn_clearance: float = 20.0
    curve_lateral_acceleration: float = 2.5
    curve_approach: float = 30.0

    def __post_init__(self) -> None:
        low, high = (float(v) for v in self.lane_change_interval)
        if not 0 < low <= high:
            raise InputError(f"lane_change_interval must satisfy 0 < low <= high, got {self.lane_change_interval}")
        object.__setattr__(self, "lane_change_interval", (low, high))
        if not 0 <= self.lane_change_probability <= 1:
            raise InputError(f"lane_change_probability must lie in [0, 1], got {self.lane_change_probability}")
        for name in (
            "lane_change_settled",
            "lane_change_margin",
            "critical_gap",
            "commit_distance",
            "courtesy_patience",
            "waiting_distance",
            "spawn_clearance",
            "curve_approach",
        ):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0:
                raise InputError(f"{name} must be finite and >= 0, got {value!r}")

        if not np.isfinite(self.curve_lateral_acceleration) or self.curve_lateral_acceleration <= 0:
            raise InputError(
                f"curve_lateral_acceleration must be finite and > 0, got {self.curve_lateral_acceleration!r}"
            )

    def to_dict(self) -> dict:
        """The rules as plain data."""
        return asdict(self)


#: The default bicycle (5 m x 2 m), a module-level value for argument defaults.
DEFAULT_VEHICLE = VehicleParameters()


@dataclass(frozen=True, eq=False)
class TrafficState:
    """Every agent of a world at one sub-step (row i is agent i; read-only arrays).

    Parameters
    ----------
    states : ndarray, shape (n, 4)
        ``(x, y, v, psi)`` in m, m, m/s, rad.
    controlled : ndarray of bool, shape (n,)
        Agents driven by an external control (the ego): no behaviour law, no
        disturbance, never leave.
    spawned, exited : ndarray of bool, shape (n,)
        Whether the agent has entered the road, and whether it has left it (reached the
        end of its route); an agent is *active* when spawned and not exited.
    spawn_step : ndarray of int, shape (n,)
        The sub-step from which a not yet spawned agent may enter (when its spawn point
        is clear).
    routes : ndarray of int, shape (n, R)
        Lane indices of each route, padded with -1.
    route_index : ndarray of int, shape (n,)
        The route position of the lane the agent is on (or heads to, during a lane change).
    theta_a, theta_b : ndarray, shapes (n, 3) and (n, 2)
        Behaviour parameters (unused for controlled agents).
    target_speed : ndarray, shape (n,)
        v_target, m/s.
    timer, interval : ndarray, shape (n,)
        Time until the next lane-change decision, and the decision period, s.
    courteous : ndarray of bool, shape (n,)
        Whether the agent also yields to lower-priority traffic.
    committed : ndarray of bool, shape (n,)
        Whether the agent has committed to cross its junction.
    yield_time : ndarray, shape (n,)
        Time spent held (below 1 m/s) by a yielding decision, s.
    """

    states: np.ndarray
    controlled: np.ndarray
    spawned: np.ndarray
    exited: np.ndarray
    spawn_step: np.ndarray
    routes: np.ndarray
    route_index: np.ndarray
    theta_a: np.ndarray
    theta_b: np.ndarray
    target_speed: np.ndarray
    timer: np.ndarray
    interval: np.ndarray
    courteous: np.ndarray
    committed: np.ndarray
    yield_time: np.ndarray

    def __post_init__(self) -> None:
        n = np.asarray(self.states).shape[0]
        shapes = {
            "states": (n, 4),
            "controlled": (n,),
            "spawned": (n,),
            "exited": (n,),
            "spawn_step": (n,),
            "route_index": (n,),
            "theta_a": (n, 3),
            "theta_b": (n, 2),
            "target_speed": (n,),
            "timer": (n,),
            "interval": (n,),
            "courteous": (n,),
            "committed": (n,),
            "yield_time": (n,),
        }
        for name, shape in shapes.items():
            value = np.asarray(getattr(self, name))
            if value.shape != shape:
                raise DimensionError(f"{name} must have shape {shape}, got shape {value.shape}")
            object.__setattr__(self, name, readonly_copy(value))
        routes = np.asarray(self.routes, dtype=int)
        if routes.ndim != 2 or routes.shape[0] != n or routes.shape[1] < 1:
            raise DimensionError(f"routes must have shape ({n}, R) with R >= 1, got shape {routes.shape}")
        object.__setattr__(self, "routes", readonly_copy(routes))

    def __len__(self) -> int:
        return self.states.shape[0]

    def evolve(self, **changes) -> TrafficState:
        """A copy with some fields replaced (arrays of the same shapes, made read-only; not re-validated).

        Parameters
        ----------
        changes : ndarray
            Field name to new array.
        """
        new = object.__new__(TrafficState)
        new.__dict__.update(self.__dict__)
        for name, value in changes.items():
            if name not in self.__dict__:
                raise InputError(f"TrafficState has no field {name!r}")
            new.__dict__[name] = readonly_copy(value)
        return new

    @property
    def active(self) -> np.ndarray:
        """Agents on the road now, bool (n,)."""
        return self.spawned & ~self.exited

    @property
    def route_lengths(self) -> np.ndarray:
        """Number of lanes in each route, int (n,)."""
        return (self.routes >= 0).sum(axis=1)

    @property
    def lane(self) -> np.ndarray:
        """The lane each agent is on or steers to (its intention), int (n,)."""
        return self.routes[np.arange(len(self)), self.route_index]


@dataclass(frozen=True, eq=False)
class StepRecord:
    """What the behaviour law did during one sub-step (per agent, shape (n,) unless noted).

    Parameters
    ----------
    acceleration : ndarray
        Applied acceleration, m/s^2: ``clip(theta_a . features) + disturbance`` for
        behaviour-driven agents, the control for controlled ones, 0 when inactive.
    steering : ndarray
        Applied steering angle, rad.
    disturbance : ndarray
        w, m/s^2 (0 for controlled or inactive agents).
    features : ndarray, shape (n, 3)
        The acceleration features f.
    steering_features : ndarray, shape (n, 2)
        The steering features g.
    leader : ndarray of int
        Index of the agent followed, -1 if none (a stop line is not an agent).
    gap : ndarray
        Bumper-to-bumper gap to the front object used in f (inf if none), m.
    yielding : ndarray of bool
        Whether a stop line held the agent (its front object was the stop line).
    intention : ndarray of int
        The lane each agent steered to (-1 when inactive).
    lane_change : ndarray of bool
        Whether the agent started a lane change at this sub-step.
    """

    acceleration: np.ndarray
    steering: np.ndarray
    disturbance: np.ndarray
    features: np.ndarray
    steering_features: np.ndarray
    leader: np.ndarray
    gap: np.ndarray
    yielding: np.ndarray
    intention: np.ndarray
    lane_change: np.ndarray


# ------------------------------------------------------------------- the law
def draw_parameters(rng: np.random.Generator, count: int, params: BehaviourParameters = BehaviourParameters()):
    """Draw ``count`` vehicles' ``(theta_a, theta_b)`` from the reference priors.

    Parameters
    ----------
    rng : numpy.random.Generator
        The random stream.
    count : int
        Number of vehicles.
    params : BehaviourParameters
        The priors.

    Returns
    -------
    theta_a : ndarray, shape (count, 3)
        ``theta_a_nominal * U[scale_low, scale_high]`` per component.
    theta_b : ndarray, shape (count, 2)
        ``theta_b_nominal + U[-spread, spread]`` per component.
    """
    if int(count) != count or count < 0:
        raise InputError(f"count must be a nonnegative integer, got {count!r}")
    scale = rng.uniform(params.theta_a_scale[0], params.theta_a_scale[1], size=(int(count), 3))
    spread = np.array(params.theta_b_spread)
    delta = rng.uniform(-1.0, 1.0, size=(int(count), 2)) * spread
    return np.array(params.theta_a_nominal) * scale, np.array(params.theta_b_nominal) + delta


def acceleration_features(speed, target_speed, front_speed, gap, params: BehaviourParameters = BehaviourParameters()):
    """The LinearVehicle acceleration features ``[v_t - v, min(v_f - v, 0), min(gap - d0 - T v, 0)]``.

    Parameters
    ----------
    speed, target_speed : array_like, shape (n,)
        v and v_target, m/s.
    front_speed : array_like, shape (n,)
        Speed of the front object along the route, m/s (ignored where ``gap`` is inf).
    gap : array_like, shape (n,)
        Bumper-to-bumper gap to the front object, m; ``inf`` when there is none (then
        the last two features are 0).
    params : BehaviourParameters
        d0 and T.

    Returns
    -------
    ndarray, shape (n, 3)
    """
    v = np.asarray(speed, dtype=float)
    gap = np.asarray(gap, dtype=float)
    has_front = np.isfinite(gap)
    dv = np.where(has_front, np.minimum(np.asarray(front_speed, dtype=float) - v, 0.0), 0.0)
    safe = params.standstill_distance + params.time_headway * v
    dp = np.where(has_front, np.minimum(np.where(has_front, gap, 0.0) - safe, 0.0), 0.0)
    return np.stack([np.asarray(target_speed, dtype=float) - v, dv, dp], axis=-1)


def linear_acceleration(theta_a, features, params: BehaviourParameters = BehaviourParameters(), disturbance=0.0):
    """``clip(theta_a . features, -a_max, a_max) + disturbance`` (m/s^2), row by row.

    Parameters
    ----------
    theta_a : array_like, shape (n, 3)
        Acceleration gains.
    features : array_like, shape (n, 3)
        From `acceleration_features`.
    params : BehaviourParameters
        a_max.
    disturbance : array_like, shape (n,) or scalar
        w, m/s^2.
    """
    raw = np.einsum("ij,ij->i", np.asarray(theta_a, dtype=float), np.asarray(features, dtype=float))
    bound = params.acceleration_bound
    return np.clip(raw, -bound, bound) + disturbance


def steering_features(heading_ahead, heading, offset, speed, length: float, speed_epsilon: float = 0.01):
    """The LinearVehicle steering features ``[wrap(h - psi) L / v, -offset L / v^2]``.

    Parameters
    ----------
    heading_ahead : array_like, shape (n,)
        Route heading h at ``s + tau v``, rad.
    heading : array_like, shape (n,)
        psi, rad.
    offset : array_like, shape (n,)
        Lateral offset from the route lane, m (left positive).
    speed : array_like, shape (n,)
        v, m/s (replaced by ``speed_epsilon`` where smaller).
    length : float
        L, m.
    speed_epsilon : float
        The smallest speed used, m/s.

    Returns
    -------
    ndarray, shape (n, 2)
    """
    v = np.maximum(np.asarray(speed, dtype=float), speed_epsilon)
    error = wrap_to_pi(np.asarray(heading_ahead, dtype=float) - np.asarray(heading, dtype=float))
    return np.stack([error * length / v, -np.asarray(offset, dtype=float) * length / (v * v)], axis=-1)


def linear_steering(theta_b, features, max_steering: float):
    """``clip(theta_b . features, -max_steering, max_steering)`` (rad), row by row.

    Parameters
    ----------
    theta_b : array_like, shape (n, 2)
        Steering gains.
    features : array_like, shape (n, 2)
        From `steering_features`.
    max_steering : float
        The steering bound, rad.
    """
    raw = np.einsum("ij,ij->i", np.asarray(theta_b, dtype=float), np.asarray(features, dtype=float))
    return np.clip(raw, -max_steering, max_steering)


def slip_angle(steering):
    """The bicycle's slip angle ``beta = arctan(tan(delta) / 2)`` (rad) of a steering angle (rad).

    Parameters
    ----------
    steering : array_like
        delta, rad, in ``(-pi/2, pi/2)``.
    """
    return np.arctan(0.5 * np.tan(steering))


def bicycle_step(states, acceleration, steering, dt: float, vehicle: VehicleParameters = VehicleParameters()):
    """One forward-Euler step of the kinematic bicycle (see the module docstring).

    The one implementation is the compiled `minimaxplan.kernels.bicycle.bicycle_step_into`,
    which the planner's ego model runs too (its predicted ego is the world's, bit for bit).

    Parameters
    ----------
    states : array_like, shape (n, 4)
        ``(x, y, v, psi)``.
    acceleration : array_like, shape (n,)
        a, m/s^2.
    steering : array_like, shape (n,)
        delta, rad (used as given: clip it beforehand).
    dt : float
        Step, s.
    vehicle : VehicleParameters
        L and max_speed.

    Returns
    -------
    ndarray, shape (n, 4)
        The next states; the speed is clipped to ``[0, max_speed]``.
    """
    x = np.ascontiguousarray(states, dtype=float)
    if x.ndim != 2 or x.shape[1] != 4:
        raise DimensionError(f"states must have shape (n, 4), got shape {x.shape}")
    n = x.shape[0]
    accel = np.ascontiguousarray(np.broadcast_to(np.asarray(acceleration, dtype=float), (n,)))
    steer = np.ascontiguousarray(np.broadcast_to(np.asarray(steering, dtype=float), (n,)))
    out = np.empty_like(x)
    bicycle_step_into(x, accel, steer, float(dt), float(vehicle.length), float(vehicle.max_speed), out)
    return out


def vehicle_corners(states, vehicle: VehicleParameters = VehicleParameters()) -> np.ndarray:
    """The four corners of each vehicle's rectangle, shape (..., 4, 2) (front-left, front-right, rear-right, rear-left).

    Parameters
    ----------
    states : array_like, shape (..., 4)
        ``(x, y, v, psi)``; the rectangle is L x W centred on ``(x, y)``, along psi.
    vehicle : VehicleParameters
        L and W.
    """
    x = np.asarray(states, dtype=float)
    c, s = np.cos(x[..., 3]), np.sin(x[..., 3])
    forward = np.stack([c, s], axis=-1) * (vehicle.length / 2)
    left = np.stack([-s, c], axis=-1) * (vehicle.width / 2)
    centre = x[..., :2]
    return np.stack(
        [centre + forward + left, centre + forward - left, centre - forward - left, centre - forward + left], axis=-2
    )


# ------------------------------------------------------------ traffic logic
def _projections(traffic: TrafficState, road: Road, vehicle: VehicleParameters):
    """Frenet coordinates of every agent's centre and corners on every lane: (n, 5, n_lanes) each."""
    points = np.concatenate([traffic.states[:, None, :2], vehicle_corners(traffic.states, vehicle)], axis=1)
    lanes = np.arange(len(road))
    return road.frenet(lanes, points[..., 0:1], points[..., 1:2])


def _occupancy(traffic: TrafficState, road: Road, s: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Lanes each active agent occupies: a point of its rectangle in the strip, or its route lane."""
    inside = (s >= 0.0) & (s <= road.lengths) & (np.abs(offset) <= road.widths / 2)
    occ = inside.any(axis=1)
    n = len(traffic)
    occ[np.arange(n), traffic.lane] = True
    return occ & traffic.active[:, None]


def desired_speed(
    traffic: TrafficState,
    road: Road,
    rules: TrafficRules = TrafficRules(),
    vehicle: VehicleParameters = VehicleParameters(),
    *,
    s: np.ndarray | None = None,
) -> np.ndarray:
    """The v_target of the acceleration law: the target speed, capped on and before arcs.

    Parameters
    ----------
    traffic : TrafficState
        The agents (their ``target_speed``, lanes and routes).
    road : Road
        The lanes.
    rules : TrafficRules
        ``curve_lateral_acceleration`` and ``curve_approach``.
    vehicle : VehicleParameters
        L (the approach distance is measured from the front bumper).
    s : ndarray, shape (n,), optional
        The agents' arc lengths on their lanes, m, if already known.

    Returns
    -------
    ndarray, shape (n,)
        ``min(target_speed, sqrt(a_lat / |kappa|))`` with kappa the curvature of the
        current lane, or of the next route lane when the front bumper is within
        ``curve_approach`` of it, m/s. A known function of the route and the position:
        the law stays linear in theta.
    """
    rows = np.arange(len(traffic))
    lane = traffic.lane
    k = traffic.route_index
    has_next = k + 1 < traffic.route_lengths
    nxt = traffic.routes[rows, np.minimum(k + 1, traffic.routes.shape[1] - 1)]
    if s is None:
        s, _ = road.frenet(lane, traffic.states[:, 0], traffic.states[:, 1])
    near = has_next & (road.lengths[lane] - s - vehicle.length / 2 <= rules.curve_approach)
    kappa = np.abs(road.curvature_at(lane, s))
    kappa_next = np.where(near, np.abs(road.curvature_at(np.where(has_next, nxt, lane), 0.0)), 0.0)
    kappa = np.maximum(kappa, kappa_next)
    cap = np.sqrt(rules.curve_lateral_acceleration / np.maximum(kappa, 1e-12))
    return np.minimum(traffic.target_speed, cap)


def find_leaders(traffic: TrafficState, road: Road, vehicle: VehicleParameters = VehicleParameters()):
    """For each agent, the nearest agent ahead along its route, its gap and its speed along the route.

    Parameters
    ----------
    traffic : TrafficState
        The agents (inactive ones are neither leaders nor followers).
    road : Road
        The lanes.
    vehicle : VehicleParameters
        L (every agent has the same length).

    Returns
    -------
    leader : ndarray of int, shape (n,)
        -1 if none.
    gap : ndarray, shape (n,)
        Bumper-to-bumper distance along the route, ``path distance - L`` (inf if none), m.
    front_speed : ndarray, shape (n,)
        The leader's speed projected on the route lane it occupies, m/s.

    Notes
    -----
    Agent j is a candidate leader of i if it occupies (`_occupancy`) a lane of i's route
    at or after i's route position, or a side lane that i itself occupies (during a lane
    change), and is ahead of i along that path (positive path distance, measured from
    the centres' projections: side lanes have aligned s).
    """
    s_all, off_all = _projections(traffic, road, vehicle)
    return _leaders(traffic, road, vehicle, s_all[:, 0, :], _occupancy(traffic, road, s_all, off_all))


def _leaders(traffic: TrafficState, road: Road, vehicle: VehicleParameters, s_c: np.ndarray, occ: np.ndarray):
    n = len(traffic)
    rows = np.arange(n)
    routes = traffic.routes
    valid_route = routes >= 0
    safe_routes = np.where(valid_route, routes, 0)
    lengths = np.where(valid_route, road.lengths[safe_routes], 0.0)
    cumstart = np.concatenate([np.zeros((n, 1)), np.cumsum(lengths, axis=1)[:, :-1]], axis=1)
    k = traffic.route_index
    lane_i = traffic.lane
    s_i = s_c[rows, lane_i]
    path_i = cumstart[rows, k] + s_i
    r_idx = np.arange(routes.shape[1])
    ahead = valid_route & (r_idx[None, :] >= k[:, None])  # (n, R)
    # distance from i to j along i's route lane r: (n_i, n_j, R)
    s_j_on = s_c.T[safe_routes]  # (n_i, R, n_j)
    dist = cumstart[:, :, None] + s_j_on - path_i[:, None, None]
    cand = ahead[:, :, None] & np.transpose(occ, (1, 0))[safe_routes]  # occ[j, routes[i, r]] -> (n_i, R, n_j)
    not_self = rows[None, :] != rows[:, None]  # (n_i, n_j)
    cand &= not_self[:, None, :] & (dist > 0)
    dist = np.where(cand, dist, np.inf)
    # side lanes occupied by i itself (lane changes): aligned s
    same_group = (road.side_of[None, :] >= 0) & (road.side_of[None, :] == road.side_of[lane_i][:, None])  # (n_i, L)
    side = occ & same_group  # lanes i occupies in its group
    side[rows, lane_i] = False
    side_dist = s_c.T[None, :, :] - s_c[rows][:, :, None]  # (n_i, L, n_j): s_j(m) - s_i(m)
    side_cand = side[:, :, None] & occ.T[None, :, :] & not_self[:, None, :] & (side_dist > 0)
    side_dist = np.where(side_cand, side_dist, np.inf)
    best_route = dist.min(axis=1)  # (n_i, n_j)
    best_side = side_dist.min(axis=1)
    best = np.minimum(best_route, best_side)
    # the lane on which the leader is measured, for its speed projection
    lane_route = safe_routes[rows[:, None], dist.argmin(axis=1)]  # (n_i, n_j)
    lane_side = side_dist.argmin(axis=1)
    lane_of_pair = np.where(best_route <= best_side, lane_route, lane_side)
    leader = best.argmin(axis=1)
    dist_min = best[rows, leader]
    has = np.isfinite(dist_min) & traffic.active
    leader = np.where(has, leader, -1)
    safe_leader = np.where(has, leader, 0)
    lane_l = lane_of_pair[rows, safe_leader]
    lane_heading = road.heading_at(lane_l, s_c[safe_leader, lane_l])
    front_speed = traffic.states[safe_leader, 2] * np.cos(traffic.states[safe_leader, 3] - lane_heading)
    gap = np.where(has, dist_min - vehicle.length, np.inf)
    return leader, gap, np.where(has, front_speed, 0.0)


def _progress(traffic: TrafficState, road: Road, vehicle: VehicleParameters) -> TrafficState:
    """Advance route positions past lane ends (a controlled agent on side lanes takes the nearest one);
    behaviour-driven agents on their route's last lane whose front bumper has passed its end leave the road."""
    n = len(traffic)
    rows = np.arange(n)
    k = traffic.route_index.copy()
    x, y = traffic.states[:, 0], traffic.states[:, 1]
    last = traffic.route_lengths - 1
    lane = traffic.routes[rows, k]
    s, _ = road.frenet(lane, x, y)
    for _ in range(traffic.routes.shape[1]):
        move = traffic.active & (s > road.lengths[lane]) & (k < last)
        if not move.any():
            break
        k = np.where(move, k + 1, k)
        lane = traffic.routes[rows, k]
        s, _ = road.frenet(lane, x, y)
    leaving = traffic.active & ~traffic.controlled & (k == last) & (s + vehicle.length / 2 > road.lengths[lane])
    routes = traffic.routes
    side = traffic.controlled & (road.side_of[lane] >= 0)
    if side.any():
        routes = routes.copy()
        for i in np.flatnonzero(side):
            group = np.array(road.side_lanes(int(lane[i])))
            _, offs = road.frenet(group, x[i], y[i])
            routes[i, k[i]] = group[int(np.argmin(np.abs(offs)))]
    return traffic.evolve(route_index=k, routes=routes, exited=traffic.exited | leaving)


def _yield_gaps(
    traffic: TrafficState, road: Road, rules: TrafficRules, vehicle: VehicleParameters, s_c: np.ndarray, dt: float
):
    """Stop-line gaps (inf when not yielding) and the updated committed / yield_time arrays."""
    n = len(traffic)
    rows = np.arange(n)
    lane = traffic.lane
    k = traffic.route_index
    has_next = k + 1 < traffic.route_lengths
    nxt = np.where(has_next, traffic.routes[rows, np.minimum(k + 1, traffic.routes.shape[1] - 1)], 0)
    nxt = np.where(has_next, nxt, -1)
    junction_lane: np.ndarray = np.asarray(road.conflicts.any(axis=1))
    inside = junction_lane[lane]
    approaching = (nxt >= 0) & junction_lane[np.maximum(nxt, 0)] & ~inside
    committed = traffic.committed | (inside & traffic.active)
    s_i = s_c[rows, lane]
    to_line = road.lengths[lane] - s_i - vehicle.length / 2  # front bumper to the end of the lane
    speed = traffic.states[:, 2]
    # agent j's conflict-relevant lane and time to reach it
    on_lane = lane  # lane j is on
    j_next = np.maximum(nxt, 0)
    time_to = np.where(speed > 1e-3, np.maximum(to_line, 0.0) / np.maximum(speed, 1e-3), np.inf)
    me = np.where(approaching, nxt, 0)
    conflict_on = road.conflicts[me[:, None], on_lane[None, :]]  # (n_i, n_j)
    conflict_next = road.conflicts[me[:, None], j_next[None, :]] & (nxt >= 0)[None, :]
    prio_me = np.asarray(road.priorities)[me]
    prio = np.asarray(road.priorities)
    higher_on = prio[on_lane][None, :] > prio_me[:, None]
    higher_next = prio[j_next][None, :] > prio_me[:, None]
    others = traffic.active[None, :] & (rows[None, :] != rows[:, None])
    blocked_rule = others & (
        (conflict_on & higher_on) | (conflict_next & higher_next & (time_to[None, :] < rules.critical_gap))
    )
    waiting = conflict_next & (to_line[None, :] <= rules.waiting_distance)
    held = speed < 1.0
    patient = traffic.yield_time < rules.courtesy_patience
    blocked_courtesy = others & traffic.courteous[:, None] & (conflict_on | (waiting & patient[:, None]))
    blocked = (blocked_rule | blocked_courtesy).any(axis=1) & approaching & traffic.active & ~traffic.controlled
    must_stop = blocked & ~committed
    committed = committed | (approaching & traffic.active & ~blocked & (to_line <= rules.commit_distance))
    yield_time = traffic.yield_time + np.where(must_stop & held, dt, 0.0)
    return np.where(must_stop, np.maximum(to_line, 0.0), np.inf), committed, yield_time


def _lane_changes(
    traffic: TrafficState,
    road: Road,
    behaviour: BehaviourParameters,
    rules: TrafficRules,
    vehicle: VehicleParameters,
    s_c: np.ndarray,
    off_c: np.ndarray,
    occ: np.ndarray,
    draws: np.ndarray,
    dt: float,
):
    """Timer-driven lane-change decisions with gap acceptance (sequential over the deciding agents)."""
    n = len(traffic)
    rows = np.arange(n)
    lane = traffic.lane
    timer = traffic.timer - dt
    fire = (timer <= 0.0) & traffic.active & ~traffic.controlled & (road.side_of[lane] >= 0)
    timer = np.where(timer <= 0.0, timer + traffic.interval, timer)
    routes = traffic.routes
    started = np.zeros(n, dtype=bool)
    settled = np.abs(off_c[rows, lane]) < rules.lane_change_settled
    candidates = np.flatnonzero(fire & settled & (draws[:, 0] < rules.lane_change_probability))
    if candidates.size:
        routes = routes.copy()
        occ = occ.copy()
        d0, headway, margin = behaviour.standstill_distance, behaviour.time_headway, rules.lane_change_margin
        for i in candidates:
            group = road.side_lanes(int(lane[i]))
            pos = group.index(int(lane[i]))
            step = 1 if draws[i, 1] < 0.5 else -1
            if not 0 <= pos + step < len(group):
                continue
            target = group[pos + step]
            others = np.flatnonzero(occ[:, target] & (rows != i))
            delta = s_c[others, target] - s_c[i, target]
            ahead = delta > 0
            gap = np.abs(delta) - vehicle.length
            need = d0 + margin + headway * np.where(ahead, traffic.states[i, 2], traffic.states[others, 2])
            if np.all(gap >= need):
                routes[i, traffic.route_index[i]] = target
                occ[i, target] = True
                started[i] = True
    return routes, timer, started


def traffic_step(
    traffic: TrafficState,
    road: Road,
    controls,
    *,
    dt: float,
    step_index: int,
    rng: np.random.Generator,
    behaviour: BehaviourParameters = BehaviourParameters(),
    rules: TrafficRules = TrafficRules(),
    vehicle: VehicleParameters = VehicleParameters(),
) -> tuple[TrafficState, StepRecord]:
    """Advance every agent by one sub-step ``dt``: spawns, routes, decisions, the law, the bicycle.

    Parameters
    ----------
    traffic : TrafficState
        The agents now.
    road : Road
        The lanes.
    controls : array_like, shape (n, 2)
        ``(acceleration, steering)`` of each agent; read only for controlled agents.
    dt : float
        Sub-step, s.
    step_index : int
        Index of this sub-step (agents with ``spawn_step <= step_index`` may spawn).
    rng : numpy.random.Generator
        The stream of disturbances and lane-change draws: 3 uniforms per agent and
        sub-step are drawn whatever happens, so the stream's use does not depend on
        the traffic.
    behaviour, rules, vehicle : BehaviourParameters, TrafficRules, VehicleParameters
        The law, the rules and the bicycle.

    Returns
    -------
    TrafficState
        The agents after the sub-step.
    StepRecord
        The law's inputs and outputs during the sub-step (decided on the state before it).
    """
    n = len(traffic)
    controls = np.asarray(controls, dtype=float)
    if controls.shape != (n, 2):
        raise DimensionError(f"controls must have shape ({n}, 2), got shape {controls.shape}")
    draws = rng.uniform(0.0, 1.0, size=(n, 3))
    traffic = _spawn(traffic, road, rules, step_index)
    rows = np.arange(n)
    active = traffic.active
    s_all, off_all = _projections(traffic, road, vehicle)
    occ = _occupancy(traffic, road, s_all, off_all)
    s_c, off_c = s_all[:, 0, :], off_all[:, 0, :]
    routes, timer, started = _lane_changes(traffic, road, behaviour, rules, vehicle, s_c, off_c, occ, draws, dt)
    traffic = traffic.evolve(routes=routes, timer=timer)
    if started.any():
        occ = _occupancy(traffic, road, s_all, off_all)
    leader, gap, front_speed = _leaders(traffic, road, vehicle, s_c, occ)
    if road.conflicts.any():
        stop_gap, committed, yield_time = _yield_gaps(traffic, road, rules, vehicle, s_c, dt)
    else:
        stop_gap, committed, yield_time = np.full(n, np.inf), traffic.committed, traffic.yield_time
    yielding = stop_gap < gap
    gap = np.where(yielding, stop_gap, gap)
    front_speed = np.where(yielding, 0.0, front_speed)
    leader = np.where(yielding, -1, leader)
    speed = traffic.states[:, 2]
    desired = desired_speed(traffic, road, rules, vehicle, s=s_c[rows, traffic.lane])
    features = acceleration_features(speed, desired, front_speed, gap, behaviour)
    bound = behaviour.disturbance_bound
    driven = active & ~traffic.controlled
    disturbance = np.where(driven, (2.0 * draws[:, 2] - 1.0) * bound, 0.0)
    accel = linear_acceleration(traffic.theta_a, features, behaviour, disturbance)
    # steering: route heading tau v ahead, on the next route lane when beyond this one
    lane = traffic.lane
    s_lane = s_c[rows, lane]
    offset = off_c[rows, lane]
    s_ahead = s_lane + behaviour.pursuit_time * speed
    k = traffic.route_index
    has_next = k + 1 < traffic.route_lengths
    beyond = (s_ahead > road.lengths[lane]) & has_next
    next_lane = traffic.routes[rows, np.minimum(k + 1, traffic.routes.shape[1] - 1)]
    lane_ahead = np.where(beyond, next_lane, lane)
    s_ahead = np.where(beyond, s_ahead - road.lengths[lane], s_ahead)
    heading_ahead = road.heading_at(lane_ahead, s_ahead)
    g = steering_features(heading_ahead, traffic.states[:, 3], offset, speed, vehicle.length, behaviour.speed_epsilon)
    steer = linear_steering(traffic.theta_b, g, vehicle.max_steering)
    accel = np.where(traffic.controlled, controls[:, 0], accel)
    steer = np.where(traffic.controlled, controls[:, 1], steer)
    accel = np.where(active, accel, 0.0)
    steer = np.where(active, steer, 0.0)
    moved = bicycle_step(traffic.states, accel, steer, dt, vehicle)
    states = np.where(active[:, None], moved, traffic.states)
    record = StepRecord(
        acceleration=accel,
        steering=steer,
        disturbance=disturbance,
        features=features,
        steering_features=g,
        leader=np.where(active, leader, -1),
        gap=np.where(active, gap, np.inf),
        yielding=yielding & active,
        intention=np.where(active, lane, -1),
        lane_change=started,
    )
    after = traffic.evolve(states=states, committed=committed, yield_time=yield_time)
    return _progress(after, road, vehicle), record


def _spawn(traffic: TrafficState, road: Road, rules: TrafficRules, step_index: int) -> TrafficState:
    """Let due agents enter, in index order, when no active agent is near their spawn point."""
    due = np.flatnonzero(~traffic.spawned & (traffic.spawn_step <= step_index))
    if due.size == 0:
        return traffic
    spawned = traffic.spawned.copy()
    lanes = traffic.lane
    for i in due:
        lane = int(lanes[i])
        s0, _ = road.frenet(lane, traffic.states[i, 0], traffic.states[i, 1])
        active = spawned & ~traffic.exited
        others = np.flatnonzero(active)
        if others.size:
            s, off = road.frenet(lane, traffic.states[others, 0], traffic.states[others, 1])
            near = (np.abs(s - s0) < rules.spawn_clearance) & (np.abs(off) <= road.widths[lane])
            if near.any():
                continue
        spawned[i] = True
    return traffic.evolve(spawned=spawned)
