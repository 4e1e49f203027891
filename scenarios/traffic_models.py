"""Forecasting traffic: sound boxes for every other vehicle of a road world.

One concept: from a noisy `Observation` and a belief per vehicle (`VehicleBelief`: boxes
of its behaviour parameters, the lanes it may be steering to, its possible routes),
`forecast_traffic` returns a `TrafficForecast`: for every other vehicle and every
sub-step ``n = 0 .. H`` after the observation, an axis-aligned box that contains its
whole 5 m x 2 m rectangle, for every parameter of the belief, every surviving
intention (a union), every lane-change switch time, every disturbance and every
measurement noise; and a box of its centre state ``(x, y, v, psi)``.

The models (``docs/traffic-models.md`` has the derivations):

* **longitudinal** ``(s, v)`` along the route, in theta_a: ``v+ = clip(v + dt (clip(theta_a
  . f, -a_max, a_max) + w), 0, v_max)`` with ``f = [v_t - v, min(v_f - v, 0), min(gap - d0 -
  T v, 0)]``. The features are monotone in ``(v, v_f, gap)`` and the map is monotone in
  ``v`` (`longitudinal_bounds`): its exact bounds over the box come from the box's
  corners, and the front object's ``(v_f, gap)`` from every possible leader (any vehicle
  whose box may be ahead in the corridor, the ego through ``ego_reach``, a stop line
  where the vehicle may yield);
* **lateral** ``(e, chi)`` (offset from the lane steered to, heading error): the
  `lateral_system`, affine in ``(v, theta_b1, theta_b2 / v)``, with one parameter box
  per step from the longitudinal tube, propagated by the vertex bound of
  `minimaxplan.models.prediction.IntervalPredictor` in one fixed basis per vehicle; the
  nonlinear remainders (sin, the slip angle, the steering clip) are per-step
  disturbance boxes computed exactly from the box by monotone functions
  (`lateral_remainder`), valid on straight lanes while ``|chi| <= CHI_MAX`` and
  ``v >= V_MIN``; below ``V_MIN`` a direct interval step of the bicycle is hulled in;
  on straight lanes the boxes are also intersected with the hull of a contraction
  ellipse (`lateral_contraction`) and, at every speed down to standstill, of a proven
  invariant parallelogram that holds the unit's states (`lateral_invariant`);
* **coarse** (``guaranteed = False``): from the first step at which a vehicle's tube
  may leave the straight lanes of its route (arcs, heading errors beyond ``CHI_MAX``),
  the reachable box of the bicycle under its speed, steering and acceleration limits,
  cut to the road (``road_edges``);
* **switching intentions**: per vehicle, one row per lane it may steer to, each with
  its own box and *cohorts* of recent switches (a vehicle settled in lane l may start a
  change to a neighbour at any step, when the gap rule may accept it): see
  `forecast_traffic`'s Notes.

The per-step loop is in one place (`forecast_traffic`; the lateral step is its
``lateral_step`` with the batched vertex bound `_vertex_step`), so that it can move to
`predict_tube`'s per-step parameter sets and box-valued inputs when those exist.

Layer: numpy, `minimaxplan.models` for the linear system and boxes, and the compiled interval
products of `minimaxplan.kernels.vertex_bounds` (the lateral step's arithmetic); no planner
import.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from minimaxplan.kernels.lateral_bounds import footprint_bounds, lateral_remainder_bounds
from minimaxplan.kernels.vertex_bounds import interval_matvec, vertex_bound
from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.models.prediction import cos_interval, interval_product, sin_interval
from minimaxplan.models.sets import Box
from minimaxplan.models.system import UncertainLinearSystem
from minimaxplan.models.validation import as_finite_array, check_instance, frozen_copy

from .lateral_contraction import (
    CONTRACTION_MARGIN,
    contraction_metrics,
    ellipse_hull,
    unchecked_contraction_factor,
    unchecked_metric_radius,
)
from .lateral_invariant import invariant_sets
from .road import ARC, STRAIGHT, Road, wrap_to_pi
from .vehicles import DEFAULT_VEHICLE, BehaviourParameters, VehicleParameters, slip_angle

__all__ = [
    "CHI_MAX",
    "V_MIN",
    "ROUND_MARGIN",
    "VehicleBelief",
    "TrafficForecast",
    "prior_belief",
    "forecast_traffic",
    "lateral_system",
    "lateral_remainder",
    "longitudinal_bounds",
    "acceleration_feature_bounds",
    "footprint_box",
]

#: Largest heading error (rad) of the fine lateral model's region of validity.
CHI_MAX = 1.0
#: Speeds (m/s) from which the fine lateral model is used; below it a direct interval
#: step of the bicycle bounds the motion (both hulled when the speed box straddles it).
V_MIN = 1.0
#: Outward rounding of every bound, relative: ``[lo - m (1 + |lo|), hi + m (1 + |hi|)]``
#: per step, orders of magnitude above the floating-point error of the few operations
#: of a step (a few units of 2^-53 relative).
ROUND_MARGIN = 1e-9
#: The fine lateral step splits the speed box into this many geometric bins ...
SPEED_BINS = 3
#: ... when some row's ``v_hi / v_lo`` exceeds this.
SPEED_BIN_RATIO = 1.25
#: Lane-change cohorts: switches are grouped in blocks of this many sub-steps ...
COHORT_BLOCK = 2
#: ... and a cohort is merged into its row's own box after this many sub-steps (capped by the
#: rules' shortest lane-change period: the row's box is the source of further switches).
COHORT_AGE = 30
#: Tolerance of the collinearity test of consecutive straight lanes, m and rad.
COLLINEAR_TOL = 1e-6
#: The default LinearVehicle constants, a module-level value for argument defaults.
DEFAULT_BEHAVIOUR = BehaviourParameters()


def _out(lo, hi):
    """``[lo, hi]`` rounded outward by `ROUND_MARGIN` (infinite bounds stay as they are)."""
    with np.errstate(invalid="ignore"):  # inf - inf = nan on empty boxes: fmin / fmax keep the infinite bound
        return np.fmin(lo, lo - ROUND_MARGIN * (1.0 + np.abs(lo))), np.fmax(hi, hi + ROUND_MARGIN * (1.0 + np.abs(hi)))


def footprint_box(center_lower, center_upper, psi_lower, psi_upper, vehicle: VehicleParameters = DEFAULT_VEHICLE):
    """The exact axis-aligned box of every L x W rectangle with centre in a box and heading in an interval.

    Parameters
    ----------
    center_lower, center_upper : array_like, shape (..., 2)
        Box of the centre ``(x, y)``, m.
    psi_lower, psi_upper : array_like, shape (...)
        Heading interval, rad.
    vehicle : VehicleParameters
        L and W.

    Returns
    -------
    ndarray, shape (..., 4)
        ``[x_lo, y_lo, x_hi, y_hi]``, rounded outward.

    Notes
    -----
    A corner is ``centre + r (cos(psi + a_c), sin(psi + a_c))`` with ``r`` the half
    diagonal and ``a_c`` in ``{+-atan2(W, L), pi +- atan2(W, L)}``; the union over the
    box and the interval is the centre box plus the range of each corner offset, whose
    extremes are exact (the ranges of `cos_interval` and `sin_interval`, compiled in
    `minimaxplan.kernels.lateral_bounds.footprint_bounds`). Rectangles whose heading
    interval is at least 2 pi wide get the disc of radius r.
    """
    clo = np.asarray(center_lower, dtype=float)
    chi = np.asarray(center_upper, dtype=float)
    plo, phi = np.asarray(psi_lower, dtype=float), np.asarray(psi_upper, dtype=float)
    if clo.shape[-1:] != (2,) or chi.shape[-1:] != (2,):
        raise DimensionError(
            f"center_lower and center_upper must have shape (..., 2), got shapes {clo.shape} and {chi.shape}"
        )
    try:
        shape = np.broadcast_shapes(clo.shape[:-1], chi.shape[:-1], plo.shape, phi.shape)
    except ValueError:
        raise DimensionError(
            "center_lower, center_upper (..., 2), psi_lower and psi_upper must broadcast together, got shapes "
            f"{clo.shape}, {chi.shape}, {plo.shape} and {phi.shape}"
        ) from None
    r = 0.5 * np.hypot(vehicle.length, vehicle.width)
    a = np.arctan2(vehicle.width, vehicle.length)
    offsets = np.array([a, -a, np.pi + a, np.pi - a])
    boxes = footprint_bounds(
        np.ascontiguousarray(np.broadcast_to(clo, shape + (2,)).reshape(-1, 2)),
        np.ascontiguousarray(np.broadcast_to(chi, shape + (2,)).reshape(-1, 2)),
        np.ascontiguousarray(np.broadcast_to(plo, shape).reshape(-1)),
        np.ascontiguousarray(np.broadcast_to(phi, shape).reshape(-1)),
        offsets,
        float(r),
        ROUND_MARGIN,
    )
    return boxes.reshape(shape + (4,))


# ----------------------------------------------------------------- beliefs
@dataclass(frozen=True)
class VehicleBelief:
    """What the planner believes about one other vehicle.

    Parameters
    ----------
    agent : int
        Agent index (as `Observation.ids`).
    theta_a : Box
        Box of the acceleration gains, dimension 3.
    theta_b : Box
        Box of the steering gains, dimension 2.
    lanes : tuple of int
        The lanes the vehicle may be steering to now (its lane, or a side lane it may be
        changing to).
    routes : tuple of tuple of int
        Its possible routes (lane sequences; at the T-junction the candidate routes
        through the junction). A route's lanes before the vehicle's current one are
        ignored; on side lanes (the highway) the route of a lane ``l`` is ``(l,)``.
    target_speed : tuple of 2 float, optional
        Bounds of its (hidden) target speed ``v_target``, m/s; None: the scenario's draw
        range (``vehicle_speed`` or ``main_speed``).
    """

    agent: int
    theta_a: Box
    theta_b: Box
    lanes: tuple
    routes: tuple
    target_speed: tuple | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.theta_a, Box) or self.theta_a.dim != 3:
            raise DimensionError(f"theta_a must be a Box of dimension 3, got {self.theta_a!r}")
        if not isinstance(self.theta_b, Box) or self.theta_b.dim != 2:
            raise DimensionError(f"theta_b must be a Box of dimension 2, got {self.theta_b!r}")
        if np.any(self.theta_a.low < 0) or np.any(self.theta_b.low <= 0):
            raise InputError("the forecast needs theta_a >= 0 and theta_b > 0 (the monotone feature bounds)")
        lanes = tuple(int(lane) for lane in self.lanes)
        routes = tuple(tuple(int(lane) for lane in route) for route in self.routes)
        if not lanes or not routes or not all(routes):
            raise InputError("a belief needs at least one lane and one non-empty route")
        object.__setattr__(self, "agent", int(self.agent))
        object.__setattr__(self, "lanes", lanes)
        object.__setattr__(self, "routes", routes)
        if self.target_speed is not None:
            lo, hi = (float(v) for v in self.target_speed)
            if not 0 <= lo <= hi:
                raise InputError(f"target_speed must satisfy 0 <= low <= high, got {self.target_speed}")
            object.__setattr__(self, "target_speed", (lo, hi))

    def to_dict(self) -> dict:
        """The belief as plain data."""
        return {
            "agent": self.agent,
            "theta_a": [self.theta_a.low.tolist(), self.theta_a.high.tolist()],
            "theta_b": [self.theta_b.low.tolist(), self.theta_b.high.tolist()],
            "lanes": list(self.lanes),
            "routes": [list(r) for r in self.routes],
            "target_speed": None if self.target_speed is None else list(self.target_speed),
        }


def _routes_from(road: Road, lane: int) -> list[tuple[int, ...]]:
    """Every lane sequence from ``lane`` to a lane without successor."""
    out: list[tuple[int, ...]] = []
    stack: list[tuple[int, ...]] = [(lane,)]
    while stack:
        route = stack.pop()
        nxt = road.successors(route[-1])
        if not nxt:
            out.append(route)
        for b in nxt:
            if b not in route:
                stack.append(route + (b,))
    return sorted(out)


def prior_belief(agent: int, measured, road: Road, scenario) -> VehicleBelief:
    """The prior belief of a measured vehicle: prior boxes, every geometrically possible intention and route.

    Parameters
    ----------
    agent : int
        Agent index.
    measured : array_like, shape (4,)
        Its measured ``(x, y, v, psi)``.
    road : Road
        The lanes.
    scenario : HighwayScenario or TJunctionScenario
        ``behaviour`` (the priors ``theta_a_prior``, ``theta_b_prior``) and
        ``measurement_noise``.

    Returns
    -------
    VehicleBelief
        ``lanes``: the lanes whose strip (grown by the position noise) holds the measured
        centre and, in a side group, their neighbours (a vehicle may be changing lane
        towards either); ``routes``: every route from those lanes to the end of the road.
    """
    x = as_finite_array("measured", measured, (4,))
    behaviour: BehaviourParameters = scenario.behaviour
    noise = float(max(scenario.measurement_noise[0], scenario.measurement_noise[1])) * np.sqrt(2.0)
    member = road.lane_membership(x[:2], margin=noise)
    lanes = set(int(i) for i in np.flatnonzero(member))
    if not lanes:
        s, off = road.frenet(np.arange(len(road)), x[0], x[1])
        lanes = {int(np.argmin(np.abs(off) + np.maximum(-s, 0) + np.maximum(s - road.lengths, 0)))}
    for lane in list(lanes):
        group = road.side_lanes(lane)
        k = group.index(lane)
        lanes.update(group[max(k - 1, 0) : k + 2])
    routes: list = []
    for lane in sorted(lanes):
        routes.extend(r for r in _routes_from(road, lane) if r not in routes)
    lo_a, hi_a = behaviour.theta_a_prior
    lo_b, hi_b = behaviour.theta_b_prior
    return VehicleBelief(agent, Box(lo_a, hi_a), Box(lo_b, hi_b), tuple(sorted(lanes)), tuple(routes))


# ------------------------------------------------------------ the forecast
@dataclass(frozen=True, eq=False)
class TrafficForecast:
    """Boxes of every other vehicle over the sub-steps of a horizon (read-only arrays).

    Attributes
    ----------
    boxes : ndarray, shape (H+1, m, 4)
        ``[x_lo, y_lo, x_hi, y_hi]`` (m) containing vehicle j's whole rectangle at
        sub-step n after the observation; rows of vehicles not on the road are empty
        boxes (``lo = +inf``, ``hi = -inf``).
    state_lower, state_upper : ndarray, shape (H+1, m, 4)
        Box of the centre state ``(x, y, v, psi)`` (psi unwrapped near the measured heading).
    guaranteed : ndarray of bool, shape (H+1, m)
        False from the step at which the fine model's region of validity was left and
        the coarse reachable box is used instead (still sound).
    ids : ndarray of int, shape (m,)
        Agent indices, as `Observation.ids`.
    dt : float
        Sub-step, s.
    """

    boxes: np.ndarray
    state_lower: np.ndarray
    state_upper: np.ndarray
    guaranteed: np.ndarray
    ids: np.ndarray
    dt: float

    def __post_init__(self) -> None:
        for name in ("boxes", "state_lower", "state_upper"):
            object.__setattr__(self, name, frozen_copy(np.asarray(getattr(self, name))))
        for name, dtype in (("guaranteed", bool), ("ids", int)):  # as documented (frozen_copy makes floats)
            raw = np.asarray(getattr(self, name))
            value = np.array(raw, dtype=dtype, copy=True)
            if raw.size and not np.array_equal(value, raw):
                kind = "booleans (or 0 and 1)" if dtype is bool else "integers"
                raise InputError(f"{name} must hold {kind}, got {raw.ravel()[:5].tolist()}...")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        h1, m = self.guaranteed.shape
        for name in ("boxes", "state_lower", "state_upper"):
            if getattr(self, name).shape != (h1, m, 4):
                raise DimensionError(f"{name} must have shape {(h1, m, 4)}, got {getattr(self, name).shape}")
        if self.ids.shape != (m,):
            raise DimensionError(f"ids must have shape ({m},), got {self.ids.shape}")

    @property
    def steps(self) -> int:
        """H, the number of sub-steps."""
        return self.boxes.shape[0] - 1

    def widths(self) -> np.ndarray:
        """Widths of the centre boxes ``(x, y, v, psi)``, shape (H+1, m, 4)."""
        return self.state_upper - self.state_lower

    def to_dict(self) -> dict:
        """The forecast as plain data (the infinite bounds of empty rows as None)."""

        def plain(a):
            return np.where(np.isfinite(a), a, None).tolist()

        return {
            "boxes": plain(self.boxes),
            "state_lower": plain(self.state_lower),
            "state_upper": plain(self.state_upper),
            "guaranteed": self.guaranteed.tolist(),
            "ids": self.ids.tolist(),
            "dt": self.dt,
        }


# ------------------------------------------------------------------ models
def lateral_system(dt: float, theta_b: Box, speed: tuple, vehicle: VehicleParameters = DEFAULT_VEHICLE):
    """The lateral model as an `UncertainLinearSystem` in ``(v, theta_b1, q = theta_b2 / v)``.

    Parameters
    ----------
    dt : float
        Sub-step, s.
    theta_b : Box
        Steering gains.
    speed : tuple of 2 float
        ``(v_lo, v_hi)``, m/s, ``0 < v_lo <= v_hi``.
    vehicle : VehicleParameters
        L.

    Returns
    -------
    UncertainLinearSystem
        State ``(e, chi)``, ``A = I + v Phi_v + theta_b1 Phi_b1 + q Phi_q`` with
        ``Phi_v = [[0, dt], [0, 0]]``, ``Phi_b1 = [[0, -L dt / 2], [0, -dt]]``,
        ``Phi_q = [[-L dt / 2, 0], [-dt, 0]]``; parameter box ``[v_lo, v_hi] x
        theta_b1 x [theta_b2_lo / v_hi, theta_b2_hi / v_lo]``; the remainders enter as
        the disturbance (``D = I``, `lateral_remainder`).

    Notes
    -----
    Linearising ``sin`` and the slip angle ``beta = arctan(tan(delta) / 2) ~ delta / 2``
    in the bicycle (`minimaxplan.scenarios.vehicles.bicycle_step`) with the steering
    law ``delta = -(L / v)(theta_b1 chi + theta_b2 e / v)`` on a straight lane:
    ``e+ = e + v dt chi + v dt delta / 2`` and ``chi+ = chi + dt v delta / L``. The
    matrix depends on v and on theta_b2 / v, each entry affinely in ``(v, theta_b1,
    q)``: that is the reparametrisation (Assumption 1's ``A0 + sum theta_i phi_i``).
    """
    lo, hi = float(speed[0]), float(speed[1])
    if not 0 < lo <= hi:
        raise InputError(f"speed must satisfy 0 < low <= high, got {speed}")
    half = vehicle.length * dt / 2
    phi = np.array([[[0.0, dt], [0.0, 0.0]], [[0.0, -half], [0.0, -dt]], [[-half, 0.0], [-dt, 0.0]]])
    theta = Box(
        np.array([lo, theta_b.low[0], theta_b.low[1] / hi]), np.array([hi, theta_b.high[0], theta_b.high[1] / lo])
    )
    return UncertainLinearSystem(np.eye(2), phi, np.zeros((2, 1)), w=Box(-np.ones(2), np.ones(2)), theta=theta)


def lateral_remainder(e, chi, v, b1, q, dt: float, vehicle: VehicleParameters = DEFAULT_VEHICLE, *, ff=None):
    """Per-step disturbance boxes: the true bicycle step minus `lateral_system`'s, over a box.

    Parameters
    ----------
    e, chi, v, b1, q : tuple of 2 ndarray
        ``(lo, hi)`` of the offset, heading error, speed (``v_lo > 0``), theta_b1 and
        ``q`` (the steering uses ``b2 / v = q``; the caller gives its range).
    dt : float
        Sub-step, s.
    vehicle : VehicleParameters
        L and the steering bound.
    ff : tuple of 2 ndarray, optional
        ``(lo, hi)`` of a feed-forward steering term added to ``delta_r`` before the
        clip (on a curved route: ``L theta_b1 (h(s + tau v) - h(s)) / v``); the linear
        step is then the one of ``delta_r`` with it. Default none.

    Returns
    -------
    r_e, r_chi : tuple of 2 ndarray
        Bounds on ``e+ - e+_lin`` and ``chi+ - chi+_lin`` for every point of the box.
    delta : tuple of 2 ndarray
        Bounds of the applied steering angle.
    a : tuple of 2 ndarray
        Bounds of the velocity's angle to the lane, ``chi + beta``.

    Notes
    -----
    With ``delta_r = -(L / v)(b1 chi + q e)``, ``delta = clip(delta_r)``, ``beta =
    delta / 2 + g(delta)``, ``g(d) = arctan(tan(d) / 2) - d / 2`` (nondecreasing on
    ``(-pi/2, pi/2)``: ``g' = (1/2)((1 + t^2) / (1 + t^2 / 4) - 1) >= 0``) and
    ``rho(x) = x - sin x`` (nondecreasing): ``e+ - e+_lin = v dt [(delta - delta_r) / 2 +
    g(delta) - rho(chi + beta)]`` and ``chi+ - chi+_lin = (2 v dt / L) [(delta - delta_r)
    / 2 + g(delta) - rho(beta)]``. ``clip(x) - x`` is nonincreasing; every term is
    bounded exactly from its argument's interval, the products by interval products.
    Valid on straight lanes for every ``|chi| < pi`` (the wrap of the heading error) and
    ``v >= speed_epsilon``; the forecast uses it on ``|chi| <= CHI_MAX``,
    ``v >= V_MIN``.
    """
    bounds = [e[0], e[1], chi[0], chi[1], v[0], v[1], b1[0], b1[1], q[0], q[1]]
    if ff is not None:
        bounds += [ff[0], ff[1]]
    given = [np.asarray(bound, dtype=float) for bound in bounds]
    try:
        arrays = np.broadcast_arrays(*given)
    except ValueError:
        names = ("e", "chi", "v", "b1", "q", "ff")
        shapes = ", ".join(f"{names[k // 2]} {given[k].shape} {given[k + 1].shape}" for k in range(0, len(given), 2))
        raise DimensionError(f"the bounds must broadcast together, got shapes {shapes}") from None
    shape = arrays[0].shape
    e_lo, e_hi, c_lo, c_hi, v_lo, v_hi, b_lo, b_hi, q_lo, q_hi, *feed = [
        np.ascontiguousarray(a.reshape(-1)) for a in arrays
    ]
    ff_lo, ff_hi = feed if feed else (np.empty(0), np.empty(0))
    out = lateral_remainder_bounds(
        e_lo,
        e_hi,
        c_lo,
        c_hi,
        v_lo,
        v_hi,
        b_lo,
        b_hi,
        q_lo,
        q_hi,
        ff_lo,
        ff_hi,
        float(dt),
        float(vehicle.length),
        float(vehicle.max_steering),
        ROUND_MARGIN,
    ).reshape((8,) + shape)
    return (out[0], out[1]), (out[2], out[3]), (out[4], out[5]), (out[6], out[7])


def acceleration_feature_bounds(v, target, front_speed, gap, params: BehaviourParameters = DEFAULT_BEHAVIOUR):
    """Exact bounds of the features ``[v_t - v, min(v_f - v, 0), min(gap - d0 - T v, 0)]`` over a box.

    Parameters
    ----------
    v, target, front_speed, gap : tuple of 2 array_like
        ``(lo, hi)`` of the speed, target speed, front speed and gap (``gap_hi = inf``
        and ``front_speed_hi = inf`` when there may be no front object).
    params : BehaviourParameters
        d0 and T.

    Returns
    -------
    lower, upper : ndarray, shape (..., 3)
        Every feature is monotone in each argument (``v_t - v`` and the ``min`` terms
        nonincreasing in v, nondecreasing in the others), so its range over the box is
        attained at opposite corners: exact.
    """
    v_lo, v_hi = (np.asarray(a, dtype=float) for a in v)
    t_lo, t_hi = (np.asarray(a, dtype=float) for a in target)
    f_lo, f_hi = (np.asarray(a, dtype=float) for a in front_speed)
    g_lo, g_hi = (np.asarray(a, dtype=float) for a in gap)
    d0, headway = params.standstill_distance, params.time_headway
    lower = np.stack([t_lo - v_hi, np.minimum(f_lo - v_hi, 0.0), np.minimum(g_lo - d0 - headway * v_hi, 0.0)], axis=-1)
    upper = np.stack([t_hi - v_lo, np.minimum(f_hi - v_lo, 0.0), np.minimum(g_hi - d0 - headway * v_lo, 0.0)], axis=-1)
    return lower, upper


def longitudinal_bounds(v, target, front_speed, gap, theta_a: tuple, dt: float, behaviour: BehaviourParameters, vmax):
    """Bounds of the next speed ``clip(v + dt (clip(theta_a . f) + w), 0, v_max)`` over a box.

    Parameters
    ----------
    v, target, front_speed, gap : tuple of 2 array_like
        As `acceleration_feature_bounds`.
    theta_a : tuple of 2 array_like, shape (..., 3)
        ``(lo, hi)`` of the gains, ``lo >= 0``.
    dt : float
        Sub-step, s.
    behaviour : BehaviourParameters
        d0, T, a_max, w_bar.
    vmax : float
        The speed clip, m/s.

    Returns
    -------
    lo, hi : ndarray
        Rounded outward.

    Notes
    -----
    ``phi(v) = v + dt clip(theta_a . f(v))`` has slope ``>= 1 - dt (theta_1 + theta_2 +
    T theta_3) `` in v: when that is ``>= 0`` (``joint``) the maximum is at ``v_hi``
    with the features evaluated there (and the minimum at ``v_lo``); otherwise the
    features' ranges over the whole box are used with ``v + dt theta_1 (v_t - v)``
    monotone (``dt theta_1 <= 1``). theta_2, theta_3 >= 0 multiply features <= 0: the
    extremes are at theta's corners; clip and the speed clip are nondecreasing.
    """
    v_lo, v_hi = (np.asarray(a, dtype=float) for a in v)
    t_lo, t_hi = (np.asarray(a, dtype=float) for a in target)
    th_lo, th_hi = (np.asarray(a, dtype=float) for a in theta_a)
    headway, amax, wbar = behaviour.time_headway, behaviour.acceleration_bound, behaviour.disturbance_bound
    joint = dt * (th_hi[..., 0] + th_hi[..., 1] + headway * th_hi[..., 2]) <= 1.0
    if np.any(dt * th_hi[..., 0] > 1.0):
        raise InputError("dt theta_a1 > 1: the speed law is not monotone in v at this sub-step")
    vu = np.where(joint, v_hi, v_lo)  # where the features are evaluated for the upper bound
    vl = np.where(joint, v_lo, v_hi)
    f_lo = acceleration_feature_bounds((vl, vl), target, front_speed, gap, behaviour)[0]
    f_hi = acceleration_feature_bounds((vu, vu), target, front_speed, gap, behaviour)[1]
    up1 = np.maximum(th_lo[..., 0] * (t_hi - v_hi), th_hi[..., 0] * (t_hi - v_hi))
    lo1 = np.minimum(th_lo[..., 0] * (t_lo - v_lo), th_hi[..., 0] * (t_lo - v_lo))
    x_hi = up1 + th_lo[..., 1] * f_hi[..., 1] + th_lo[..., 2] * f_hi[..., 2]
    x_lo = lo1 + th_hi[..., 1] * f_lo[..., 1] + th_hi[..., 2] * f_lo[..., 2]
    hi = np.clip(v_hi + dt * (np.clip(x_hi, -amax, amax) + wbar), 0.0, vmax)
    lo = np.clip(v_lo + dt * (np.clip(x_lo, -amax, amax) - wbar), 0.0, vmax)
    lo, hi = _out(lo, hi)
    return np.maximum(lo, 0.0), np.minimum(hi, vmax)


# ------------------------------------------------------------- geometry helpers
def _strip_boxes(road: Road) -> np.ndarray:
    """Axis-aligned boxes (n_lanes, 4) containing each lane's strip (closed), rounded outward."""
    out = np.zeros((len(road), 4))
    for i, lane in enumerate(road.lanes):
        half = lane.width / 2
        if road.kinds[i] == STRAIGHT:
            pts = lane.position(np.array([0.0, 0.0, lane.length, lane.length]), np.array([-half, half, -half, half]))
        else:
            d, r = road.signs[i], road.radii[i]
            a0 = road.start_angles[i]
            a1 = a0 + d * lane.length / r
            lo_a, hi_a = min(a0, a1), max(a0, a1)
            angles = [lo_a, hi_a] + [k * np.pi / 2 for k in range(-8, 9) if lo_a <= k * np.pi / 2 <= hi_a]
            radii = (r - half, r + half)
            pts = np.array([road.centers[i] + rad * np.array([np.cos(a), np.sin(a)]) for a in angles for rad in radii])
        lo, hi = _out(pts.min(axis=0), pts.max(axis=0))
        out[i] = [lo[0], lo[1], hi[0], hi[1]]
    return out


def _lin(c0, cx, cy, x_lo, x_hi, y_lo, y_hi):
    """Exact range of ``c0 + cx x + cy y`` over a box (elementwise)."""
    lo = c0 + np.minimum(cx * x_lo, cx * x_hi) + np.minimum(cy * y_lo, cy * y_hi)
    hi = c0 + np.maximum(cx * x_lo, cx * x_hi) + np.maximum(cy * y_lo, cy * y_hi)
    return _out(lo, hi)


def _centre_arc_length_lower(road: Road, lanes, centre_lo, centre_hi, present) -> np.ndarray:
    """Lower bounds of `Road.frenet`'s arc length ``s`` on some lanes over boxes of points.

    `_centre_arc_length_bounds`' lower bounds (same parameters).
    """
    return _centre_arc_length_bounds(road, lanes, centre_lo, centre_hi, present)[0]


def _centre_arc_length_bounds(road: Road, lanes, centre_lo, centre_hi, present) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of `Road.frenet`'s arc length ``s`` on some lanes over boxes of points.

    Parameters
    ----------
    road : Road
        The lanes.
    lanes : array_like of int
        The lanes to bound (every other column is ``-inf``).
    centre_lo, centre_hi : ndarray, shape (k, 2)
        Boxes of points (an agent's centre).
    present : ndarray of bool, shape (k,)
        Rows to bound (every other row is ``-inf``).

    Returns
    -------
    low, high : ndarray, shape (k, n_lanes)
        ``min s`` and ``max s`` over each box: exact on a straight lane (s is linear); on
        an arc, from the angles of the box's corners seen from the arc's centre (the
        extreme rays of a box that does not hold that centre touch corners), ``-inf`` and
        ``+inf`` where the box holds the centre or its angles reach `Road.frenet`'s wrap
        (``mid_angle + pi``); unbounded on the other lanes. Rounded outward by
        `ROUND_MARGIN`.
    """
    out = np.full((len(centre_lo), len(road)), -np.inf)
    out_hi = np.full((len(centre_lo), len(road)), np.inf)
    lanes = np.asarray(lanes, dtype=int)
    rows = np.flatnonzero(np.asarray(present, dtype=bool) & np.all(centre_lo <= centre_hi, axis=1))
    if lanes.size == 0 or rows.size == 0:
        return out, out_hi
    lo, hi = centre_lo[rows], centre_hi[rows]
    for lane in lanes:
        if road.kinds[lane] != ARC:
            start, d = road.starts[lane], road.directions[lane]
            s_lo, s_hi = _lin(-float(start @ d), d[0], d[1], lo[:, 0], hi[:, 0], lo[:, 1], hi[:, 1])
        else:
            cx, cy = road.centers[lane]
            holds = (lo[:, 0] <= cx) & (cx <= hi[:, 0]) & (lo[:, 1] <= cy) & (cy <= hi[:, 1])
            corners_x = np.stack([lo[:, 0], lo[:, 0], hi[:, 0], hi[:, 0]], 1) - cx
            corners_y = np.stack([lo[:, 1], hi[:, 1], lo[:, 1], hi[:, 1]], 1) - cy
            towards = np.arctan2((lo[:, 1] + hi[:, 1]) / 2 - cy, (lo[:, 0] + hi[:, 0]) / 2 - cx)
            rel = wrap_to_pi(np.arctan2(corners_y, corners_x) - towards[:, None])  # each |rel| < pi
            base = wrap_to_pi(towards - road.mid_angles[lane])
            d_lo, d_hi = base + rel.min(axis=1), base + rel.max(axis=1)
            usable = ~holds & (d_lo > -np.pi) & (d_hi < np.pi)
            radius, half = float(road.radii[lane]), float(road.lengths[lane]) / 2
            s_lo = np.where(road.signs[lane] > 0, half + radius * d_lo, half - radius * d_hi)
            s_hi = np.where(road.signs[lane] > 0, half + radius * d_hi, half - radius * d_lo)
            s_lo = np.where(usable, s_lo, -np.inf)
            s_hi = np.where(usable, s_hi, np.inf)
        out[rows, lane] = s_lo - ROUND_MARGIN * (1 + np.abs(s_lo))
        out_hi[rows, lane] = s_hi + ROUND_MARGIN * (1 + np.abs(s_hi))
    return out, out_hi


def _arc_offset_bounds(center, radius, sign, x_lo, x_hi, y_lo, y_hi):
    """Exact bounds of an arc lane's Frenet offset ``sign (radius - |p - center|)`` over boxes of points."""
    gx = np.maximum(np.maximum(x_lo - center[..., 0], center[..., 0] - x_hi), 0.0)
    gy = np.maximum(np.maximum(y_lo - center[..., 1], center[..., 1] - y_hi), 0.0)
    near = np.hypot(gx, gy)
    far = np.hypot(
        np.maximum(np.abs(x_lo - center[..., 0]), np.abs(x_hi - center[..., 0])),
        np.maximum(np.abs(y_lo - center[..., 1]), np.abs(y_hi - center[..., 1])),
    )
    return _out(np.where(sign > 0, radius - far, near - radius), np.where(sign > 0, radius - near, far - radius))


#: A steering term (rad) that no law's clip can exceed: the bound given where a switch window's
#: geometry is outside its validity (a box reaching the arc's centre).
SWITCH_STEERING_UNBOUNDED = 1e9


def _route_switch_steering(s, e, pursuit, speed, b1, q, *, start, end, radius, sign, switch: float, length: float):
    """Bounds of the steering added when the world may steer by the next route lane early.

    For rows whose route passes one arc (`_route_pieces`): from ``switch`` m before the
    arc's start the world may steer by the arc's lane, and from ``switch`` m before its end
    by the straight lane after it (highway-env's ``follow_road``: ``switch`` = L/2). Its
    steering features are then those of that next lane's Frenet frame, extended before
    the lane's start, instead of the route frame's: ``delta_r`` gains
    ``Delta = (L / v)(theta_b1 Delta_h - q Delta_e)``, ``Delta_h`` the change of the pursuit
    heading and ``Delta_e`` of the offset. With ``x = B - s`` the distance to the lane's
    end ``B`` (``0 <= x <= switch``), ``sigma`` the arc's sign and ``A = R - sigma e``:

    * before the arc (the arc's lane): ``sigma Delta_e = A - sqrt(x^2 + A^2)`` and
      ``Delta_h = (sigma / R)(min(tau v, x) - R atan(x / A))`` (the arc's heading is linear
      in its arc length, ``-R atan(x / A)`` at the centre's projection);
    * on the arc, before its end (the straight lane): ``sigma Delta_e = A (1 - cos(x / R))``
      and ``Delta_h = (sigma / R) max(0, x - tau v)``.

    Each is monotone in ``x`` and ``A`` (and ``tau v``), so its range over the box is that
    of its corners. 0 is always included (the switch may not have happened: the forecast
    allows any switch point in the window, the library's world at the end). Valid while
    the arc is at least ``switch`` and ``tau v`` long, ``x / R <= pi`` and ``A > 0``;
    elsewhere (never on the roads here) ``+-SWITCH_STEERING_UNBOUNDED``.

    Parameters
    ----------
    s, e : tuple of 2 ndarray
        ``(lo, hi)`` of the route distance and the offset (the frame of the lane the
        centre is in).
    pursuit : tuple of 2 ndarray
        ``(lo, hi)`` of the pursuit distance ``tau v`` (the true speed).
    speed : tuple of 2 ndarray
        ``(lo, hi)`` of the features' speed ``max(v, speed_epsilon)`` (> 0).
    b1, q : tuple of 2 ndarray
        ``(lo, hi)`` of theta_b1 and ``q = theta_b2 / v``.
    start, end, radius, sign : ndarray
        The arc's route-distance range (``-inf`` / ``inf`` where the route starts or ends
        on it), radius and turning sign.
    switch : float
        The window's length, m (> 0).
    length : float
        L, m.

    Returns
    -------
    tuple of 2 ndarray
        ``(lo, hi)`` of ``Delta``, rounded outward.
    """
    lo = np.zeros(np.shape(s[0]))
    hi = np.zeros(np.shape(s[0]))
    se_lo = np.where(sign > 0, e[0], -e[1])
    se_hi = np.where(sign > 0, e[1], -e[0])
    a_lo, a_hi = radius - se_hi, radius - se_lo
    inv_v = (length / speed[1], length / speed[0])
    arc_ok = (end - start >= np.maximum(switch, pursuit[1])) & (switch <= np.pi * radius)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        for bound, entering in ((start, True), (end, False)):
            met = (s[1] >= bound - switch) & (s[0] <= bound)
            if not met.any():
                continue
            x_lo, x_hi = np.maximum(bound - s[1], 0.0), np.minimum(bound - s[0], switch)
            if entering:
                de = (a_lo - np.hypot(x_hi, a_lo), a_hi - np.hypot(x_lo, a_hi))
                f = (
                    np.minimum(pursuit[0], x_lo) - radius * np.arctan(x_hi / a_lo),
                    np.minimum(pursuit[1], x_hi) - radius * np.arctan(x_lo / a_hi),
                )
            else:
                de = (a_lo * (1.0 - np.cos(x_lo / radius)), a_hi * (1.0 - np.cos(x_hi / radius)))
                f = (np.maximum(0.0, x_lo - pursuit[1]), np.maximum(0.0, x_hi - pursuit[0]))
            dh = (np.where(sign > 0, f[0], -f[1]) / radius, np.where(sign > 0, f[1], -f[0]) / radius)
            de = (np.where(sign > 0, de[0], -de[1]), np.where(sign > 0, de[1], -de[0]))
            t_h = interval_product(b1[0], b1[1], dh[0], dh[1])
            t_e = interval_product(q[0], q[1], de[0], de[1])
            d_lo, d_hi = interval_product(inv_v[0], inv_v[1], t_h[0] - t_e[1], t_h[1] - t_e[0])
            valid = arc_ok & (a_lo > 0.0) & np.isfinite(d_lo) & np.isfinite(d_hi)
            d_lo = np.where(valid, d_lo, -SWITCH_STEERING_UNBOUNDED)
            d_hi = np.where(valid, d_hi, SWITCH_STEERING_UNBOUNDED)
            lo, hi = np.where(met, np.minimum(lo, d_lo), lo), np.where(met, np.maximum(hi, d_hi), hi)
    return _out(lo, hi)


def _matvec(m, lo, hi):
    """Interval product of one matrix (n, 2, 2) per box (n, 2), rounded outward (`interval_matvec`)."""
    new_lo, new_hi = interval_matvec(_as_rows(m), _as_rows(lo), _as_rows(hi))
    return _out(new_lo, new_hi)


def _as_rows(a):
    """``a`` as a C-contiguous float array (one compiled specialisation of the kernels)."""
    return np.ascontiguousarray(a, dtype=float)


def _bases(a_nominal: np.ndarray) -> np.ndarray:
    """An orthogonal basis per matrix (R, 2, 2): the real Schur vectors of each nominal matrix.

    In it the nominal matrix is upper triangular when its eigenvalues are real, so the
    interval iteration contracts at the rate of the largest eigenvalue modulus; an
    orthogonal basis costs at most a factor sqrt(2) per axis on entering and leaving.
    """
    values, vectors = np.linalg.eig(a_nominal)
    real = np.abs(values[:, 0].imag) <= 1e-12
    first = np.argmax(np.abs(values), axis=1)  # the slow mode first
    v = vectors.real[np.arange(len(a_nominal)), :, first]
    v = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)
    basis = np.stack([v, np.stack([-v[:, 1], v[:, 0]], axis=1)], axis=-1)
    basis[~real] = np.eye(2)
    return basis


def _clip_to_road(box: np.ndarray, road_boxes: np.ndarray) -> np.ndarray:
    """The hull of ``box`` met with each road box (rows (R, 4)); a box meeting none is kept."""
    lo = np.maximum(box[:, None, :2], road_boxes[None, :, :2])
    hi = np.minimum(box[:, None, 2:], road_boxes[None, :, 2:])
    ok = np.all(lo <= hi, axis=-1)
    new_lo = np.where(ok[..., None], lo, np.inf).min(axis=1)
    new_hi = np.where(ok[..., None], hi, -np.inf).max(axis=1)
    keep = ~ok.any(axis=1)
    return np.where(keep[:, None], box, np.concatenate([new_lo, new_hi], axis=1))


# -------------------------------------------------------------- row layout
@dataclass
class _Row:
    veh: int
    lane: int
    c: float
    origin: np.ndarray
    u: np.ndarray
    fine: bool
    alive: bool
    prefix_end: float
    exit_s: float
    stop_s: float
    cap_from: float
    cap_speed: float
    prefix: dict  # lane -> (s_start, s_end)
    beyond: tuple
    beyond_start: dict = field(default_factory=dict)  # beyond lane -> its route distance from s = 0
    # the route's centre line from s = 0, piece by piece: (a, b, kind, start point, direction or centre,
    # radius, sign, polar angle at a, route heading at a); empty: the fine model ends with the prefix
    pieces: tuple = ()
    cap_to: float = np.inf


def _route_rows(road: Road, veh: int, belief: VehicleBelief, state: np.ndarray, vehicle, rules) -> list:
    """Hypothesis rows of one vehicle: side lanes (switching) or candidate routes."""
    junction = np.asarray(road.conflicts.any(axis=1))
    lanes = [lane for lane in belief.lanes if 0 <= lane < len(road)]
    rows = []
    grouped = [lane for lane in lanes if road.side_of[lane] >= 0]
    if grouped:
        group = road.side_lanes(grouped[0])
        base = group[0]
        o, u = road.starts[base], road.directions[base]
        nrm = np.array([-u[1], u[0]])
        straight = all(road.kinds[g] == STRAIGHT for g in group)
        for lane in group:
            c = float((road.starts[lane] - o) @ nrm)
            s0 = float((road.starts[lane] - o) @ u)
            end = s0 + float(road.lengths[lane])
            rows.append(
                _Row(
                    veh,
                    lane,
                    c,
                    o,
                    u,
                    straight,
                    lane in lanes,
                    np.inf,
                    end,
                    np.nan,
                    np.inf,
                    np.inf,
                    {lane: (s0, end)},
                    (),
                )
            )
        return rows
    for route in belief.routes:
        idx = next((i for i, lane in enumerate(route) if lane in lanes), None)
        if idx is None:
            continue
        rest = route[idx:]
        cur = rest[0]
        o, u = road.starts[cur], road.directions[cur]
        nrm = np.array([-u[1], u[0]])
        prefix = {}
        k = 0
        while k < len(rest):
            lane = rest[k]
            if road.kinds[lane] != STRAIGHT:
                break
            d = road.directions[lane]
            if abs(float(d @ u) - 1.0) > COLLINEAR_TOL or abs(float((road.starts[lane] - o) @ nrm)) > COLLINEAR_TOL:
                break
            s0 = float((road.starts[lane] - o) @ u)
            prefix[lane] = (s0, s0 + float(road.lengths[lane]))
            k += 1
        beyond = tuple(rest[k:])
        last_end = max((e for _, e in prefix.values()), default=0.0)
        # the world measures a leader's distance along the route (`find_leaders`: the sum of the
        # route lanes' lengths before its lane, plus its centre's arc length on that lane); the row's
        # s is that distance from cur's start where the prefix lanes abut, as they do on every road here
        beyond_start = {}
        sums = np.cumsum([0.0] + [float(road.lengths[lane]) for lane in rest])
        if k == 0 or all(abs(prefix[lane][0] - sums[i]) <= COLLINEAR_TOL for i, lane in enumerate(rest[:k])):
            beyond_start = {lane: float(sums[k + i]) for i, lane in enumerate(beyond)}
        pieces = _route_pieces(road, cur, prefix, last_end, beyond, beyond_start)
        fine = bool(pieces) or (bool(prefix) and road.kinds[cur] == STRAIGHT)
        prefix_end = np.inf if not beyond or pieces else last_end
        if road.kinds[cur] == ARC:  # the frame's line: the arc's tangent at its start
            o = road.position_at(cur, 0.0)
            hd = float(road.heading_at(cur, 0.0))
            u = np.array([np.cos(hd), np.sin(hd)])
        stop_s = np.nan
        for i in range(min(k, len(rest) - 1)):
            if junction[rest[i + 1]] and not junction[rest[i]]:
                stop_s = prefix[rest[i]][1]
                break
        cap_from, cap_speed, cap_to = np.inf, np.inf, np.inf
        if beyond and road.kinds[beyond[0]] == ARC:
            cap_from = last_end - vehicle.length / 2 - rules.curve_approach
            cap_speed = float(np.sqrt(rules.curve_lateral_acceleration * road.radii[beyond[0]]))
            if pieces:  # the curve cap holds up to the arc's end (beyond it the lane is straight)
                cap_to = beyond_start[beyond[0]] + float(road.lengths[beyond[0]])
        if road.kinds[cur] == ARC and pieces:
            cap_from, cap_to = -np.inf, float(road.lengths[cur])
            cap_speed = float(np.sqrt(rules.curve_lateral_acceleration * road.radii[cur]))
        rows.append(
            _Row(
                veh,
                cur,
                0.0,
                o,
                u,
                fine,
                True,
                prefix_end,
                last_end,
                stop_s,
                cap_from,
                cap_speed,
                prefix,
                beyond,
                beyond_start,
                pieces,
                cap_to,
            )
        )
    if not rows:
        raise InputError(f"belief of agent {belief.agent}: no route holds one of its lanes {belief.lanes}")
    return rows


class _Piece(NamedTuple):
    """One piece of a route's centre line (`_route_pieces`)."""

    a: float  # route distance where it starts
    b: float  # ... and ends
    kind: int  # STRAIGHT or ARC
    point: np.ndarray  # its start point
    vector: np.ndarray  # a straight piece's direction, an arc's centre
    radius: float  # an arc's radius (1 on a straight piece)
    sign: float  # an arc's turning sign (0 on a straight piece)
    phi0: float  # an arc's polar angle at a
    h0: float  # the route heading at a, relative to the row's start heading


def _route_pieces(road: Road, cur: int, prefix: dict, last_end: float, beyond: tuple, beyond_start: dict) -> tuple:
    """The route's centre line from the row's origin as pieces, or () when it is not one G1 curve.

    Each piece is a `_Piece`: route distances ``[a, b]``; a straight piece's start point
    and direction, an arc's centre (radius, sign, polar angle ``phi0`` at ``a``); ``h0``
    the route heading at ``a`` relative to the row's start heading (continuous,
    unwrapped). The world steers by the frame of the
    route lane its centre is in (`_progress` moves on when the arc length passes the
    lane's end, and consecutive lanes meet on a common normal), so ``s`` (the route
    distance) and ``e`` (the lane offset) are that lane's Frenet coordinates.
    """
    if beyond and len(beyond_start) != len(beyond):
        return ()
    lanes = beyond  # with no prefix, cur is the first lane beyond it
    if sum(road.kinds[lane] == ARC for lane in lanes) > 1:  # the lateral terms assume one arc
        return ()
    pieces = []
    heading0 = float(road.heading_at(cur, 0.0))
    h, end = 0.0, 0.0
    if prefix:
        pieces.append(_Piece(0.0, last_end, STRAIGHT, road.starts[cur], road.directions[cur], 1.0, 0.0, 0.0, 0.0))
        end = last_end
        point = road.starts[cur] + last_end * road.directions[cur]
    else:
        point = road.position_at(cur, 0.0)
    for lane in lanes:
        a = beyond_start[lane]
        start_point = road.position_at(lane, 0.0)
        start_heading = float(road.heading_at(lane, 0.0))
        # the pieces must join with a common point and tangent (G1): the steering frames then agree there
        if abs(a - end) > COLLINEAR_TOL or np.linalg.norm(start_point - point) > COLLINEAR_TOL:
            return ()
        if abs(wrap_to_pi(start_heading - (heading0 + h))) > COLLINEAR_TOL:
            return ()
        b = a + float(road.lengths[lane])
        if road.kinds[lane] == ARC:
            sign, radius = float(road.signs[lane]), float(road.radii[lane])
            pieces.append(
                _Piece(a, b, ARC, start_point, road.centers[lane], radius, sign, float(road.start_angles[lane]), h)
            )
            h += sign * float(road.lengths[lane]) / radius
        else:
            pieces.append(_Piece(a, b, STRAIGHT, start_point, road.directions[lane], 1.0, 0.0, 0.0, h))
        end = b
        point = road.position_at(lane, float(road.lengths[lane]))
    return tuple(pieces)


def _structure(dt: float, length: float) -> np.ndarray:
    """``(Phi_v, Phi_b1, Phi_q)`` of `lateral_system`, shape (3, 2, 2)."""
    half = length * dt / 2
    return np.array([[[0.0, dt], [0.0, 0.0]], [[0.0, -half], [0.0, -dt]], [[-half, 0.0], [-dt, 0.0]]])


def _vertex_step(base, z_lo, z_hi, p_lo, p_hi):
    """The `IntervalPredictor` vertex bound, batched over rows, with one parameter box per row.

    ``base``: (R, 3, 2, 2) structure matrices in each row's basis, or (1, 3, 2, 2) shared by
    every row; the matrix is ``I + sum_i p_i base_i`` for ``p`` in the box ``[p_lo, p_hi]``
    (R, 3). Returns the tightest box of ``M z`` over the 8 vertices and the box of z (before
    the disturbance), not rounded (`minimaxplan.kernels.vertex_bounds.vertex_bound`).
    """
    return vertex_bound(_as_rows(base), _as_rows(z_lo), _as_rows(z_hi), _as_rows(p_lo), _as_rows(p_hi))


def forecast_traffic(
    observation,
    road: Road,
    scenario,
    beliefs: Mapping[int, VehicleBelief],
    *,
    steps: int,
    ego_reach,
    ego_route=None,
    road_edges: bool = True,
    ego_speed=None,
    ego_heading=None,
    lateral_contraction: bool = True,
    lateral_invariant: bool = True,
) -> TrafficForecast:
    """Sound boxes of every other vehicle of an observation over ``steps`` sub-steps.

    Parameters
    ----------
    observation : Observation
        The noisy measurement (``vehicles`` (m, 4), ``ids`` (m,)).
    road : Road
        The lanes.
    scenario : HighwayScenario or TJunctionScenario
        ``dt``, ``vehicle``, ``behaviour``, ``rules``, ``measurement_noise`` and the
        target-speed range ``target_speeds`` (``vehicle_speed`` or ``main_speed``).
    beliefs : mapping of int to VehicleBelief
        Per agent index; a vehicle without a belief gets `prior_belief`.
    steps : int
        H, the number of sub-steps.
    ego_reach : array_like, shape (steps + 1, 4)
        World boxes ``[x_lo, y_lo, x_hi, y_hi]`` that contain the ego's whole rectangle
        (hence its centre) at each sub-step under any of its action sequences; an empty
        row (``lo > hi``) means no ego.
    ego_speed, ego_heading : array_like, shape (steps + 1, 2), optional
        ``(low, high)`` of the ego's speed (m/s) and heading (rad) at each sub-step under
        any of its action sequences (the ego is a possible leader: its speed along the
        lane is a feature of its followers); default ``[0, max_speed]`` and any heading.
    road_edges : bool
        Whether the coarse boxes are cut to the road (the hull of the road's lane-strip
        and area boxes met by the box): sound under the world's property that other
        vehicles keep their rectangle's corners and centre on the road (`RoadWorld`
        records any violation in ``traffic_off_road``; tested never to happen). False:
        the bicycle's limits only.
    ego_route : tuple of int or ndarray of bool, shape (steps + 1, n_lanes), optional
        Lanes the ego may have as its route lane (it occupies them whatever its
        position), for the whole horizon or per sub-step; default: every lane of the
        T-junction's ``south_in, south_west, west_out`` at every step (sound, and
        conservative: the planner knows the ego's route position and can pass the
        lanes it may reach); on the highway the ego's route lane is the side lane
        nearest to its centre, which its rectangle always touches, so nothing is needed.
    lateral_contraction : bool
        Whether the fine units on straight lanes carry the contraction radius of
        `lateral_contraction` (their boxes intersected with its ellipse's hull). Both
        settings are sound; False gives the interval boxes alone (for comparison: the
        benchmark's and the tests' reference).
    lateral_invariant : bool
        Whether a fine unit on a straight lane whose states are known to lie in one of the
        proven invariant parallelograms of `lateral_invariant` (its box inside it, and its
        speed box and steering gains inside the set's proof) keeps its box inside that
        set's hull, whatever its speed down to standstill. Both settings are sound; False
        is the reference of the benchmark and the tests.

    Returns
    -------
    TrafficForecast

    Notes
    -----
    Induction over the sub-steps, per hypothesis row (a vehicle's side lane or route):
    the row's box at step n contains the state of every trajectory whose intention in
    force for the transition ``n -> n+1`` is the row's lane, for every admissible
    parameter, disturbance, noise and switch history. Step: the features' exact range
    over the leaders' boxes (`longitudinal_bounds`), the lateral vertex bound plus the
    remainder box (`lateral_remainder`), or the coarse bicycle bound.

    Switching (lane changes at any step): a vehicle changes from lane l' to a
    neighbour l at step n only if settled, ``|e_l'| < lane_change_settled``, and the gap
    rule accepts it. So the set of states at n with intention l is contained in
    ``Pre_l(n) u shift(Pre_l'(n) n {|e_l'| <= settled})`` over the neighbours l', with
    ``Pre_l(n)`` the successor of the row's sets at n - 1. The shifted part enters a
    *cohort* (one per block of `COHORT_BLOCK` steps and source lane; hulling it into the
    row's own box would wrap), propagated with the row's per-step parameters and merged
    into the row's own box after ``min(COHORT_AGE, shortest timer period)`` steps: a
    vehicle switches again only when its timer fires again, so only the row's own box
    (which holds every trajectory that switched at least that long ago) is a source. By
    induction every switch time and sequence of switches is covered; the union over a
    row's units at step n is the union of ``Pre`` (the same physical states), which is
    what is output. A switch is dropped when an agent certainly in the target lane
    certainly fails the gap rule; a vehicle that reaches a lane only by a switch is a
    candidate leader of a row in that lane only once the pair's gap could have been
    accepted at some step so far (the later of two switches into a lane was checked
    against the earlier).

    Routes through an arc (the T-junction's turns) keep the fine model on the arc and the
    lane after it (`_route_pieces`): ``s`` is the route distance and ``e``, ``chi`` the
    Frenet offset and heading error of the lane the centre is in (the lane the world
    steers by). On or near the arc the step adds, as bounded terms: the pursuit law's
    feed-forward ``L theta_b1 tau kappa`` inside ``delta_r`` (the pursuit point's heading
    ahead), the route's turn over the step ``-(h(s+) - h(s))`` in ``chi``, the outward
    drift of a straight move in the arc's frame (``<= D^2 / (2 A)``, ``A`` the distance
    from the arc's centre) and the change of frame at the arc's end in ``e``, and the arc's
    route-distance step ``R atan(D cos(chi + beta) / A)``. World boxes are the hull over
    the pieces the ``s`` box meets (straight: linear; arc: polar, exact ranges of cos and
    sin). Leaders beyond the prefix count only where they may be ahead along the route.

    A vehicle's output is the hull over its rows (the union of its surviving
    hypotheses); ``guaranteed`` is False from the first step after one of its rows left
    the fine region (then its box is the coarse reachable box).
    """
    dt = float(scenario.dt)
    vehicle: VehicleParameters = scenario.vehicle
    beh: BehaviourParameters = scenario.behaviour
    rules = scenario.rules
    steps = int(steps)
    if steps < 0:
        raise InputError(f"steps must be >= 0, got {steps}")
    check_instance("road_edges", road_edges, (bool, np.bool_), "a bool")
    check_instance("lateral_contraction", lateral_contraction, (bool, np.bool_), "a bool")
    check_instance("lateral_invariant", lateral_invariant, (bool, np.bool_), "a bool")
    ids = np.asarray(observation.ids, dtype=int)
    meas = np.asarray(observation.vehicles, dtype=float).reshape(-1, 4)
    m = len(ids)
    if meas.shape != (m, 4):
        raise DimensionError(f"observation.vehicles must have shape ({m}, 4), got shape {meas.shape}")
    reach = np.asarray(ego_reach, dtype=float)
    if reach.shape != (steps + 1, 4):
        raise DimensionError(f"ego_reach must have shape ({steps + 1}, 4), got shape {reach.shape}")
    if np.any(np.isnan(reach)):
        raise InputError("ego_reach contains NaN")
    empty = np.array([np.inf, np.inf, -np.inf, -np.inf])
    e_speed = np.tile([0.0, scenario.vehicle.max_speed], (steps + 1, 1)) if ego_speed is None else ego_speed
    e_speed = as_finite_array("ego_speed", e_speed, (steps + 1, 2))
    e_head = np.tile([-np.pi, np.pi], (steps + 1, 1)) if ego_heading is None else ego_heading
    e_head = as_finite_array("ego_heading", e_head, (steps + 1, 2))
    if m == 0:
        z = np.zeros((steps + 1, 0, 4))
        return TrafficForecast(z, z, z, np.zeros((steps + 1, 0), dtype=bool), ids, dt)
    if ego_route is None:
        ego_route = road.route("south_in", "south_west", "west_out") if "south_west" in road.names else ()
    n_lanes = len(road)
    length = vehicle.length
    noise = np.array(scenario.measurement_noise, dtype=float)
    t_range = scenario.target_speeds
    strips = _strip_boxes(road)
    road_boxes = np.vstack([strips] + [np.array([[a[0][0], a[0][1], a[1][0], a[1][1]]]) for a in road.areas])

    # ---------------------------------------------------------------- rows
    per_vehicle = []
    for j in range(m):
        belief = beliefs.get(int(ids[j])) if beliefs is not None else None
        if belief is None:
            belief = prior_belief(int(ids[j]), meas[j], road, scenario)
        per_vehicle.append((belief, _route_rows(road, j, belief, meas[j], vehicle, rules)))
    P = max(len(r) for _, r in per_vehicle)
    R = m * P
    veh_of = np.repeat(np.arange(m), P)
    alive = np.zeros(R, dtype=bool)
    fine = np.zeros(R, dtype=bool)
    origin = np.zeros((R, 2))
    u = np.tile([1.0, 0.0], (R, 1))
    c = np.zeros(R)
    row_lane = np.zeros(R, dtype=int)
    prefix_end = np.full(R, np.inf)
    exit_s = np.full(R, np.inf)
    stop_s = np.full(R, np.nan)
    cap_from = np.full(R, np.inf)
    cap_speed = np.full(R, np.inf)
    cap_to = np.full(R, np.inf)
    K = max([1] + [len(row.pieces) for _, rows in per_vehicle for row in rows])
    # route pieces (`_route_pieces`); the first extends backwards and the last forwards without end
    pc_a, pc_b = np.full((R, K), np.inf), np.full((R, K), np.inf)
    pc_kind = np.full((R, K), -1)
    pc_pt, pc_vec = np.zeros((R, K, 2)), np.zeros((R, K, 2))
    pc_rad, pc_sgn, pc_phi0, pc_h0 = np.ones((R, K)), np.zeros((R, K)), np.zeros((R, K)), np.zeros((R, K))
    routed = np.zeros(R, dtype=bool)  # rows whose fine model follows the route's pieces
    pre_lo = np.full((R, n_lanes), np.nan)
    pre_hi = np.full((R, n_lanes), np.nan)
    beyond = np.zeros((R, n_lanes), dtype=bool)
    beyond_start = np.full((R, n_lanes), np.nan)  # NaN: no bound (the gap to its occupants is only >= 0)
    route_mask = np.zeros((R, n_lanes), dtype=bool)
    side = np.zeros((R, n_lanes), dtype=bool)
    nbr = np.full((R, 2), -1, dtype=int)
    ta_lo, ta_hi = np.zeros((R, 3)), np.zeros((R, 3))
    tb_lo, tb_hi = np.ones((R, 2)), np.ones((R, 2))
    t_lo, t_hi = np.full(R, t_range[0]), np.full(R, t_range[1])
    for j, (belief, rows) in enumerate(per_vehicle):
        lane_rows = {}
        for p, row in enumerate(rows):
            r = j * P + p
            alive[r], fine[r] = row.alive, row.fine
            origin[r], u[r], c[r], row_lane[r] = row.origin, row.u, row.c, row.lane
            prefix_end[r], exit_s[r], stop_s[r] = row.prefix_end, row.exit_s, row.stop_s
            cap_from[r], cap_speed[r], cap_to[r] = row.cap_from, row.cap_speed, row.cap_to
            if row.pieces and (len(row.pieces) > 1 or row.pieces[0].kind == ARC):
                routed[r] = True
                for q, piece in enumerate(row.pieces):
                    pc_a[r, q], pc_b[r, q], pc_kind[r, q] = piece.a, piece.b, piece.kind
                    pc_pt[r, q], pc_vec[r, q] = piece.point, piece.vector
                    pc_rad[r, q], pc_sgn[r, q] = piece.radius, piece.sign
                    pc_phi0[r, q], pc_h0[r, q] = piece.phi0, piece.h0
                pc_a[r, 0] = -np.inf
                pc_b[r, len(row.pieces) - 1] = np.inf
            for lane, (s0, s1) in row.prefix.items():
                pre_lo[r, lane], pre_hi[r, lane] = s0, s1
            beyond[r, list(row.beyond)] = True
            for lane, start in row.beyond_start.items():
                beyond_start[r, lane] = start
            route_mask[r] = ~np.isnan(pre_lo[r]) | beyond[r]
            if road.side_of[row.lane] >= 0:
                side[r, list(road.side_lanes(row.lane))] = True
            lane_rows[row.lane] = r
        for lane, r in lane_rows.items():
            if road.side_of[lane] >= 0:
                group = road.side_lanes(lane)
                at = group.index(lane)
                if at > 0 and group[at - 1] in lane_rows:
                    nbr[r, 0] = lane_rows[group[at - 1]]
                if at + 1 < len(group) and group[at + 1] in lane_rows:
                    nbr[r, 1] = lane_rows[group[at + 1]]
        sl = slice(j * P, (j + 1) * P)
        ta_lo[sl], ta_hi[sl] = belief.theta_a.low, belief.theta_a.high
        tb_lo[sl], tb_hi[sl] = belief.theta_b.low, belief.theta_b.high
        if belief.target_speed is not None:
            t_lo[sl], t_hi[sl] = belief.target_speed
        for p in range(len(rows), P):  # padding: copies of the first row, never alive
            r = j * P + p
            origin[r], u[r], c[r], row_lane[r] = origin[j * P], u[j * P], c[j * P], row_lane[j * P]
    if np.any(dt * ta_hi[:, 0] > 1.0):
        raise InputError("dt theta_a1 > 1: the speed law is not monotone in v at this sub-step")
    nrm = np.stack([-u[:, 1], u[:, 0]], axis=1)
    heading = np.arctan2(u[:, 1], u[:, 0])
    widths = road.widths[row_lane]
    pc_used = pc_kind >= 0
    pc_arc = pc_kind == ARC
    pc_kappa = np.where(pc_arc, pc_sgn / pc_rad, 0.0)
    pc_lo = np.where(pc_used, pc_a, np.inf)  # the route distance where each piece starts (first: 0)
    pc_lo[:, 0] = np.where(pc_used[:, 0], 0.0, np.inf)
    has_arc = routed & pc_arc.any(axis=1)

    def route_heading(s_at):
        """The route's heading at s (R,) relative to the row's start heading (continuous)."""
        with np.errstate(invalid="ignore"):  # unused pieces span [inf, inf]
            inside = np.where(pc_arc, np.clip(s_at[:, None], pc_a, pc_b) - pc_lo, 0.0)
        return (pc_kappa * inside).sum(axis=1)  # 0 on straight pieces, also where s is unbounded

    def pieces_met(lo, hi):
        """(R, K): the pieces whose route-distance range meets [lo, hi]."""
        return pc_used & (pc_a <= hi[:, None]) & (pc_b >= lo[:, None])

    def heading_range(s_lo_, s_hi_):
        """Bounds of the route heading over [s_lo, s_hi] (piecewise linear: ends and piece starts)."""
        h_a, h_b = route_heading(s_lo_), route_heading(s_hi_)
        lo, hi = np.minimum(h_a, h_b), np.maximum(h_a, h_b)
        inner = pieces_met(s_lo_, s_hi_) & (pc_a >= s_lo_[:, None])
        lo = np.minimum(lo, np.where(inner, pc_h0, np.inf).min(axis=1))
        hi = np.maximum(hi, np.where(inner, pc_h0, -np.inf).max(axis=1))
        return lo, hi

    def curvature_range(lo, hi):
        """Bounds of the route's curvature over [lo, hi], (R,) each (0 off the routed rows)."""
        met = pieces_met(lo, hi)
        k_lo = np.where(met, pc_kappa, np.inf).min(axis=1)
        k_hi = np.where(met, pc_kappa, -np.inf).max(axis=1)
        return np.where(routed, k_lo, 0.0), np.where(routed, k_hi, 0.0)

    def route_xy(rows, s_lo_, s_hi_, e_lo_, e_hi_):
        """World boxes of the centres of the rows ``rows`` from their (s, e) boxes: the hull over the pieces met."""
        met = pieces_met(s_lo_, s_hi_)[rows]
        out = [
            np.full(len(rows), np.inf),
            np.full(len(rows), -np.inf),
            np.full(len(rows), np.inf),
            np.full(len(rows), -np.inf),
        ]
        sl, sh, el, eh = s_lo_[rows], s_hi_[rows], e_lo_[rows], e_hi_[rows]
        for q in range(K):
            on = met[:, q]
            if not on.any():
                continue
            arc = pc_arc[rows, q]
            for part in (np.flatnonzero(on & ~arc), np.flatnonzero(on & arc)):
                if part.size == 0:
                    continue
                r = rows[part]
                a, b = pc_a[r, q], pc_b[r, q]
                t_lo, t_hi = np.maximum(sl[part], a) - pc_lo[r, q], np.minimum(sh[part], b) - pc_lo[r, q]
                pt, vec = pc_pt[r, q], pc_vec[r, q]
                e_l, e_h = el[part], eh[part]
                if not arc[part[0]]:  # a straight piece: affine in (t, e)
                    x = _lin(pt[:, 0], vec[:, 0], -vec[:, 1], t_lo, t_hi, e_l, e_h)
                    y = _lin(pt[:, 1], vec[:, 1], vec[:, 0], t_lo, t_hi, e_l, e_h)
                else:  # an arc: a sector of an annulus about its centre (an arc's vec)
                    rad, sgn = pc_rad[r, q], pc_sgn[r, q]
                    ph_a, ph_b = pc_phi0[r, q] + sgn * t_lo / rad, pc_phi0[r, q] + sgn * t_hi / rad
                    ph_lo, ph_hi = np.minimum(ph_a, ph_b), np.maximum(ph_a, ph_b)
                    r_lo = rad - np.maximum(sgn * e_l, sgn * e_h)
                    r_hi = rad - np.minimum(sgn * e_l, sgn * e_h)
                    with np.errstate(invalid="ignore"):
                        xa = interval_product(r_lo, r_hi, *cos_interval(ph_lo, ph_hi))
                        ya = interval_product(r_lo, r_hi, *sin_interval(ph_lo, ph_hi))
                    x = _out(vec[:, 0] + xa[0], vec[:, 0] + xa[1])
                    y = _out(vec[:, 1] + ya[0], vec[:, 1] + ya[1])
                for i, val in enumerate((x[0], x[1], y[0], y[1])):
                    out[i][part] = (np.minimum if i % 2 == 0 else np.maximum)(out[i][part], val)
        return out

    # ------------------------------------------------------- initial boxes
    mv = meas[veh_of]
    x_lo, x_hi = _out(mv[:, 0] - noise[0], mv[:, 0] + noise[0])
    y_lo, y_hi = _out(mv[:, 1] - noise[1], mv[:, 1] + noise[1])
    v_lo, v_hi = _out(np.maximum(mv[:, 2] - noise[2], 0.0), mv[:, 2] + noise[2])
    v_lo = np.maximum(v_lo, 0.0)
    chi0 = wrap_to_pi(mv[:, 3] - heading)
    h_unw = mv[:, 3] - chi0
    p_lo, p_hi = _out(mv[:, 3] - noise[3], mv[:, 3] + noise[3])  # psi (coarse rows)
    s_lo, s_hi = _lin(-np.sum(origin * u, axis=1), u[:, 0], u[:, 1], x_lo, x_hi, y_lo, y_hi)
    l_lo, l_hi = _lin(-np.sum(origin * nrm, axis=1) - c, nrm[:, 0], nrm[:, 1], x_lo, x_hi, y_lo, y_hi)
    ch_lo, ch_hi = _out(chi0 - noise[3], chi0 + noise[3])
    on_arc = np.flatnonzero(routed & pc_arc[:, 0])
    if on_arc.size:  # the row's frame is its arc's: Frenet bounds of the measured box, heading error from them
        lane_a = row_lane[on_arc]
        arc_lo, arc_hi = _centre_arc_length_bounds(
            road,
            np.unique(lane_a),
            np.stack([x_lo[on_arc], y_lo[on_arc]], 1),
            np.stack([x_hi[on_arc], y_hi[on_arc]], 1),
            np.ones(on_arc.size, dtype=bool),
        )
        s_lo[on_arc], s_hi[on_arc] = arc_lo[np.arange(on_arc.size), lane_a], arc_hi[np.arange(on_arc.size), lane_a]
        l_lo[on_arc], l_hi[on_arc] = _arc_offset_bounds(
            pc_vec[on_arc, 0],
            pc_rad[on_arc, 0],
            pc_sgn[on_arc, 0],
            x_lo[on_arc],
            x_hi[on_arc],
            y_lo[on_arc],
            y_hi[on_arc],
        )
        s_mid, _ = road.frenet(lane_a, mv[on_arc, 0], mv[on_arc, 1])
        chi_a = wrap_to_pi(mv[on_arc, 3] - road.heading_at(lane_a, s_mid))
        h_unw[on_arc] = mv[on_arc, 3] - chi_a - pc_kappa[on_arc, 0] * s_mid  # the route heading at s_mid
        hh_lo, hh_hi = heading_range(s_lo, s_hi)
        ch_lo[on_arc], ch_hi[on_arc] = _out(
            p_lo[on_arc] - h_unw[on_arc] - hh_hi[on_arc], p_hi[on_arc] - h_unw[on_arc] - hh_lo[on_arc]
        )
        bounded = np.isfinite(s_lo[on_arc]) & np.isfinite(s_hi[on_arc])
        fine[on_arc] &= bounded
        # a box holding the arc's centre has no arc-frame bounds: the row is coarse from the start, and its
        # (unused) frame boxes are kept finite so that no inf * 0 reaches the bases
        loose = on_arc[~bounded]
        s_lo[loose] = s_hi[loose] = ch_lo[loose] = ch_hi[loose] = 0.0
    ahead0 = beh.pursuit_time * v_hi
    if beh.route_switch_distance > 0.0:  # the world may steer by the lane beyond the prefix from that far before it
        ahead0 = np.maximum(ahead0, beh.route_switch_distance)
    fine &= (np.maximum(-ch_lo, ch_hi) <= CHI_MAX) & (s_hi + ahead0 <= prefix_end)
    # one basis per vehicle (rows share it): the nominal matrix at the measured speed
    phi = _structure(dt, length)
    v0 = np.maximum(mv[:, 2], V_MIN)
    b1m, b2m = (tb_lo[:, 0] + tb_hi[:, 0]) / 2, (tb_lo[:, 1] + tb_hi[:, 1]) / 2
    nominal = np.eye(2) + v0[:, None, None] * phi[0] + b1m[:, None, None] * phi[1] + (b2m / v0)[:, None, None] * phi[2]
    T = _bases(nominal)
    Tinv = np.linalg.inv(T)
    base = np.einsum("rij,kjl,rlm->rkim", Tinv, phi, T)  # (R, 3, 2, 2)
    # lateral units: each row's own box (unit r) and, on side lanes, its switch cohorts
    # (unit R + (2 r + d) C + c: switches from the neighbour d during block c of `block` steps)
    gap_steps = int(np.floor(rules.lane_change_interval[0] / dt + 1e-9)) - 1
    block = COHORT_BLOCK
    C = max(1, min(COHORT_AGE, max(gap_steps, 1)) // block)
    has_side = bool(np.any(nbr >= 0))
    U = R + (2 * R * C if has_side else 0)
    unit_row = np.concatenate([np.arange(R), np.repeat(np.arange(R), 2 * C)]) if has_side else np.arange(R)
    ui_lo = np.full((U, 2), np.inf)
    ui_hi = np.full((U, 2), -np.inf)
    ui_lo[:R], ui_hi[:R] = np.stack([l_lo, ch_lo], 1), np.stack([l_hi, ch_hi], 1)
    uz_lo, uz_hi = ui_lo.copy(), ui_hi.copy()
    uz_lo[:R], uz_hi[:R] = _matvec(Tinv, ui_lo[:R], ui_hi[:R])
    ualive = np.zeros(U, dtype=bool)
    ualive[:R] = alive
    for arr, val in ((ui_lo, np.inf), (ui_hi, -np.inf), (uz_lo, np.inf), (uz_hi, -np.inf)):
        arr[:R][~alive] = val
    # each unit's contraction radius (`lateral_contraction`): its states satisfy ||x||_P <= rho in the
    # metric P of index umet (inf: no radius yet)
    # (without the radius: never read, so never kept up to date)
    c_speeds, c_metrics, c_conv = contraction_metrics(float(dt), vehicle, beh)
    log_nodes = np.log(c_speeds)
    urho = np.full(U, np.inf)
    umet = np.zeros(U, dtype=int)
    # each unit's invariant set (`lateral_invariant`): its states lie in the table's set uinv (-1: none known);
    # the proofs hold for the prior's steering gains, so only for rows whose belief lies in them
    inv_sets = invariant_sets(dt, vehicle, beh) if lateral_invariant else None
    uinv = np.full(U, -1)
    if inv_sets is not None:
        inv_gains = np.all((tb_lo >= inv_sets.theta_b_low) & (tb_hi <= inv_sets.theta_b_high), axis=1)
        uinv[:R] = np.where(inv_gains, inv_sets.smallest_containing(ui_lo[:R], ui_hi[:R]), -1)

    H1 = steps + 1
    boxes = np.empty((H1, m, 4))
    lower = np.empty((H1, m, 4))
    upper = np.empty((H1, m, 4))
    guaranteed = np.empty((H1, m), dtype=bool)
    half_w = widths / 2
    tau, settle = beh.pursuit_time, rules.lane_change_settled
    switch = float(beh.route_switch_distance)
    vmax = vehicle.max_speed
    beta_max = float(slip_angle(vehicle.max_steering))
    eps = beh.speed_epsilon
    if isinstance(ego_route, np.ndarray) and ego_route.ndim == 2:
        if ego_route.shape != (steps + 1, n_lanes):
            raise DimensionError(f"ego_route must have shape ({steps + 1}, {n_lanes}), got shape {ego_route.shape}")
        ego_lanes = ego_route.astype(bool)
    else:
        ego_lanes = np.zeros((steps + 1, n_lanes), dtype=bool)
        ego_lanes[:, list(ego_route)] = True
    same = veh_of[:, None] == np.arange(m + 1)[None, :]
    beyond_used = np.flatnonzero(beyond.any(axis=0))  # the lanes whose occupants' arc length is bounded
    pair_ok = np.zeros((R, m + 1), dtype=bool)
    lane_offset = np.full(n_lanes, np.nan)
    lane_offset[row_lane[fine | alive]] = c[fine | alive]
    belief_lane = alive.copy()  # the rows of the lanes in the beliefs
    side_row = road.side_of[row_lane] >= 0
    same_group = (road.side_of[row_lane][:, None] == road.side_of[None, :]) & side_row[:, None]

    def unit_boxes():
        """(e, chi) box of every unit: the intersection of its two sound boxes."""
        lo, hi = np.full((U, 2), np.inf), np.full((U, 2), -np.inf)
        a = np.flatnonzero(ualive)
        b_lo, b_hi = _matvec(T[unit_row[a]], uz_lo[a], uz_hi[a])
        lo[a], hi[a] = np.maximum(b_lo, ui_lo[a]), np.minimum(b_hi, ui_hi[a])
        return lo, hi

    def row_hull(lo, hi):
        """Hull over each row's units, (R, 2) each (empty rows: inf, -inf)."""
        if not has_side:
            return lo, hi
        c_lo = lo[R:].reshape(R, 2 * C, 2).min(axis=1)
        c_hi = hi[R:].reshape(R, 2 * C, 2).max(axis=1)
        return np.minimum(lo[:R], c_lo), np.maximum(hi[:R], c_hi)

    arc_q = np.argmax(pc_arc, axis=1)
    arc_rad = pc_rad[np.arange(R), arc_q]
    arc_sgn = np.where(has_arc, pc_sgn[np.arange(R), arc_q], 0.0)
    arc_end = np.where(has_arc, pc_b[np.arange(R), arc_q], np.nan)
    arc_start = np.where(has_arc, pc_a[np.arange(R), arc_q], np.nan)

    def curved_rows(v_hi_):
        """Per row: whether a step may meet the arc, the curvature ranges of the pursuit window and of the
        motion, and whether the motion may leave the arc at its end."""
        if not has_arc.any():  # the highway: no row has an arc
            zero = np.zeros(R)
            return np.zeros(R, dtype=bool), (zero, zero), (zero, zero), np.zeros(R, dtype=bool)
        # a step moves the centre's route distance by at most D R / A (D = v dt, A >= R - |e| - D the
        # distance from the arc's centre; `curved_terms`), at least 1.5 D taken
        d_hi = v_hi_ * dt
        a_lo = arc_rad - np.maximum(np.abs(e_lo[:, 0]), np.abs(e_hi[:, 0])) - d_hi
        with np.errstate(divide="ignore", invalid="ignore"):
            factor = np.where(has_arc & (a_lo > 0.0), np.maximum(1.5, arc_rad / a_lo), np.where(has_arc, np.inf, 1.5))
        reach_d = factor * d_hi
        m_lo, m_hi = s_lo - reach_d, s_hi + reach_d
        w_lo, w_hi = s_lo, s_hi + tau * v_hi_
        kw = curvature_range(np.minimum(w_lo, m_lo), np.maximum(w_hi, m_hi))
        km = curvature_range(m_lo, m_hi)
        with np.errstate(invalid="ignore"):
            # the pursuit point may reach the arc before the motion does (tau > 1.5 dt, e.g. dt = 0.05)
            arc_in = has_arc & (arc_start <= np.maximum(m_hi, w_hi)) & (arc_end >= m_lo)
            if switch > 0.0:  # the world may already steer by the arc's lane (`_route_switch_steering`)
                arc_in |= has_arc & (arc_start - switch <= s_hi) & (arc_end >= m_lo)
            end_in = has_arc & (arc_end >= m_lo) & (arc_end <= m_hi)
        kw = (np.where(arc_in, kw[0], 0.0), np.where(arc_in, kw[1], 0.0))
        km = (np.where(arc_in, km[0], 0.0), np.where(arc_in, km[1], 0.0))
        return arc_in, kw, km, end_in

    def curved_terms(rr_, d, e, a, ff, km, end_in):
        """The extra terms of a step on or near the arc, for rows rr_ (one per unit).

        ``d``: (lo, hi) of the displacement ``v dt``; ``e``: the offset box; ``a``: the
        velocity's angle to the lane ``chi + beta``; ``ff``: the feed-forward steering. With
        ``A = r - sign D sin(a)`` (the distance from the arc's centre, ``r = R - sign e``): in
        the arc the offset moves by ``-sign D^2 cos^2 a / (A + r+)`` beyond the straight step
        (``|.| <= D^2 / (2 A)``), and by at most as much, of the other sign, when the centre
        passes the arc's end (the next lane's frame); the route distance by ``R atan(D cos a / A)``;
        the heading error by ``-(h(s+) - h(s))``, the route's turn over the step. Returns the
        e and chi terms beyond the linear step (with ``delta_r`` holding ``ff``) and the
        route-distance step.
        """
        rad, sg = arc_rad[rr_], arc_sgn[rr_]
        c = cos_interval(*a)
        sn = sin_interval(*a)
        dsin = interval_product(d[0], d[1], *sn)
        de = (np.where(sg > 0, e[0], -e[1]), np.where(sg > 0, e[1], -e[0]))
        tot = (e[0] + dsin[0], e[1] + dsin[1])
        dsum = (np.where(sg > 0, tot[0], -tot[1]), np.where(sg > 0, tot[1], -tot[0]))
        a_lo = rad - np.maximum(dsum[1], de[1])
        a_hi = rad - np.minimum(dsum[0], de[0])
        bad = ~(a_lo > 0.0)
        a_lo = np.where(bad, 1.0, a_lo)
        a_hi = np.where(bad, 1.0, a_hi)
        dc = interval_product(d[0], d[1], *c)
        x_lo = np.minimum(dc[0] / a_lo, dc[0] / a_hi)
        x_hi = np.maximum(dc[1] / a_lo, dc[1] / a_hi)
        ds = (np.minimum(dc[0], rad * np.arctan(x_lo)), np.maximum(dc[1], rad * np.arctan(x_hi)))
        xm = np.maximum(np.abs(x_lo), np.abs(x_hi))
        sigma = np.where(xm > 0.0, np.arctan(xm) / np.where(xm > 0.0, xm, 1.0), 1.0)
        rho_a = interval_product(*interval_product(rad / a_hi, rad / a_lo, *c), sigma, np.ones_like(sigma))
        rho = (np.minimum(rho_a[0], c[0]), np.maximum(rho_a[1], c[1]))  # ds / D, hulled with the straight step's
        km_rho = interval_product(km[0][rr_], km[1][rr_], *rho)
        bracket = (ff[0] / length - km_rho[1], ff[1] / length - km_rho[0])
        chi_x = interval_product(d[0], d[1], *bracket)
        m_e = d[1] ** 2 / (2.0 * a_lo)
        arc_part, end_part = m_e, np.where(end_in[rr_], m_e, 0.0)
        eps_e = (np.where(sg > 0, -arc_part, -end_part), np.where(sg > 0, end_part, arc_part))
        ff_e = interval_product(d[0], d[1], ff[0] / 2, ff[1] / 2)
        e_x = (ff_e[0] + eps_e[0], ff_e[1] + eps_e[1])
        # a box reaching the arc's centre is outside the terms' validity: widen it past CHI_MAX (finite, so no
        # inf - inf reaches the vertex bound) and the row turns coarse at the next step
        big = np.where(bad, 4.0 * np.pi, 0.0)
        e_x, chi_x = _out(e_x[0] - big, e_x[1] + big), _out(chi_x[0] - big, chi_x[1] + big)
        return e_x, chi_x, _out(ds[0] - big, ds[1] + big), interval_product(km[0][rr_], km[1][rr_], *ds)

    def switch_steering(rr_, e, pursuit, speed, q):
        """`_route_switch_steering` for the units of rows rr_ (their row's s box, arc and gains)."""
        return _route_switch_steering(
            (s_lo[rr_], s_hi[rr_]),
            e,
            pursuit,
            speed,
            (tb_lo[rr_, 0], tb_hi[rr_, 0]),
            q,
            start=arc_start[rr_],
            end=arc_end[rr_],
            radius=arc_rad[rr_],
            sign=arc_sgn[rr_],
            switch=switch,
            length=length,
        )

    def lateral_step(idx, v_lo, v_hi):
        """One step of the units idx: vertex bound plus remainders (v >= V_MIN), hulled with the
        direct interval step of the bicycle (v < V_MIN); the basis and identity boxes intersected."""
        rr = unit_row[idx]
        e_lo, e_hi = eu_lo[idx], eu_hi[idx]
        vlo, vhi = v_lo[rr], v_hi[rr]
        arc_in, kw, km, end_in = curved_rows(v_hi)
        curved_u = arc_in[rr]
        ff_row = interval_product(tb_lo[:, 0], tb_hi[:, 0], length * tau * kw[0], length * tau * kw[1])
        f_ok = vhi >= V_MIN
        l_ok = vlo < V_MIN
        vf_lo_, vf_hi_ = np.maximum(vlo, V_MIN), np.maximum(vhi, V_MIN)
        b1 = (tb_lo[rr, 0], tb_hi[rr, 0])
        e_box, c_box = (e_lo[:, 0], e_hi[:, 0]), (e_lo[:, 1], e_hi[:, 1])
        # the speed box in geometric bins: q = theta_b2 / v then ranges with each bin's v, not the whole box's
        # (only for the units whose speed box is wide)
        ratio = vf_hi_ / vf_lo_
        zf_lo = np.full((len(idx), 2), np.inf)
        zf_hi = np.full((len(idx), 2), -np.inf)
        if_lo, if_hi = zf_lo.copy(), zf_hi.copy()
        sf = (np.full(len(idx), np.inf), np.full(len(idx), -np.inf))
        wide = ratio > SPEED_BIN_RATIO
        for sel, bins in ((np.flatnonzero(~wide), 1), (np.flatnonzero(wide), SPEED_BINS)):
            if sel.size == 0:
                continue
            rs, us = rr[sel], idx[sel]
            eb, cb, b1s = (e_box[0][sel], e_box[1][sel]), (c_box[0][sel], c_box[1][sel]), (b1[0][sel], b1[1][sel])
            for k in range(bins):
                bv_lo = vf_lo_[sel] * ratio[sel] ** (k / bins)
                bv_hi = vf_hi_[sel] if k == bins - 1 else vf_lo_[sel] * ratio[sel] ** ((k + 1) / bins)
                q_lo, q_hi = tb_lo[rs, 1] / bv_hi, tb_hi[rs, 1] / bv_lo
                # each unit's remainder once: the straight law off the arcs, the feed-forward law on them
                curved = curved_u[sel]
                flat, sub = np.flatnonzero(~curved), np.flatnonzero(curved)
                r_e, r_c, a_f = [(np.empty(sel.size), np.empty(sel.size)) for _ in range(3)]
                if flat.size:
                    f_e, f_c, _, f_a = lateral_remainder(
                        (eb[0][flat], eb[1][flat]),
                        (cb[0][flat], cb[1][flat]),
                        (bv_lo[flat], bv_hi[flat]),
                        (b1s[0][flat], b1s[1][flat]),
                        (q_lo[flat], q_hi[flat]),
                        dt,
                        vehicle,
                    )
                    for tgt, src in ((r_e, f_e), (r_c, f_c), (a_f, f_a)):
                        tgt[0][flat], tgt[1][flat] = src
                if sub.size:  # on or near the arc: the feed-forward in the law, the frame's turn and drift
                    rsub = rs[sub]
                    ffs = (ff_row[0][rsub], ff_row[1][rsub])
                    e_s, c_s = (eb[0][sub], eb[1][sub]), (cb[0][sub], cb[1][sub])
                    vb = (bv_lo[sub], bv_hi[sub])
                    if switch > 0.0:
                        sw = switch_steering(rsub, e_s, (tau * vb[0], tau * vb[1]), vb, (q_lo[sub], q_hi[sub]))
                        ffs = _out(ffs[0] + sw[0], ffs[1] + sw[1])
                    r_e2, r_c2, _, a_f2 = lateral_remainder(
                        e_s, c_s, vb, (b1s[0][sub], b1s[1][sub]), (q_lo[sub], q_hi[sub]), dt, vehicle, ff=ffs
                    )
                    e_x, c_x, ds_c, _ = curved_terms(rsub, (vb[0] * dt, vb[1] * dt), e_s, a_f2, ffs, km, end_in)
                    for tgt, src, extra in ((r_e, r_e2, e_x), (r_c, r_c2, c_x)):
                        lo_x, hi_x = _out(src[0] + extra[0], src[1] + extra[1])
                        tgt[0][sub], tgt[1][sub] = lo_x, hi_x
                    a_f[0][sub], a_f[1][sub] = a_f2
                p_lo_ = np.stack([bv_lo, b1s[0], q_lo], 1)
                p_hi_ = np.stack([bv_hi, b1s[1], q_hi], 1)
                rw_lo, rw_hi = np.stack([r_e[0], r_c[0]], 1), np.stack([r_e[1], r_c[1]], 1)
                z1_lo, z1_hi = _vertex_step(base[rs], uz_lo[us], uz_hi[us], p_lo_, p_hi_)
                w_lo, w_hi = _matvec(Tinv[rs], rw_lo, rw_hi)
                z1_lo, z1_hi = _out(z1_lo + w_lo, z1_hi + w_hi)
                i1_lo, i1_hi = _vertex_step(phi[None], e_lo[sel], e_hi[sel], p_lo_, p_hi_)
                i1_lo, i1_hi = _out(i1_lo + rw_lo, i1_hi + rw_hi)
                s1 = interval_product(bv_lo * dt, bv_hi * dt, *cos_interval(*a_f))
                if sub.size:
                    s1 = (s1[0].copy(), s1[1].copy())
                    s1[0][sub], s1[1][sub] = ds_c
                zf_lo[sel], zf_hi[sel] = np.minimum(zf_lo[sel], z1_lo), np.maximum(zf_hi[sel], z1_hi)
                if_lo[sel], if_hi[sel] = np.minimum(if_lo[sel], i1_lo), np.maximum(if_hi[sel], i1_hi)
                sf[0][sel], sf[1][sel] = np.minimum(sf[0][sel], s1[0]), np.maximum(sf[1][sel], s1[1])

        def direct_step(vl_lo, vl_hi):
            """The bicycle's step bounded directly by intervals (no linearisation), speeds in [vl_lo, vl_hi]."""
            vh_lo, vh_hi = np.maximum(vl_lo, eps), np.maximum(vl_hi, eps)
            low_e, low_c, ds_l = [(np.empty(vl_lo.shape[0]), np.empty(vl_lo.shape[0])) for _ in range(3)]
            flat, sub = np.flatnonzero(~curved_u), np.flatnonzero(curved_u)
            if flat.size:  # straight lanes: the law without feed-forward
                rf = rr[flat]
                e_f, c_f = (e_box[0][flat], e_box[1][flat]), (c_box[0][flat], c_box[1][flat])
                vf = (vh_lo[flat], vh_hi[flat])
                q_f = (tb_lo[rf, 1] / vf[1], tb_hi[rf, 1] / vf[0])
                _, _, d_l, a_l = lateral_remainder(e_f, c_f, vf, (b1[0][flat], b1[1][flat]), q_f, dt, vehicle)
                dd = (vl_lo[flat] * dt, vl_hi[flat] * dt)
                de = interval_product(*dd, *sin_interval(*a_l))
                dc = interval_product(
                    2 * vl_lo[flat] * dt / length,
                    2 * vl_hi[flat] * dt / length,
                    np.sin(slip_angle(d_l[0])),
                    np.sin(slip_angle(d_l[1])),
                )
                low_e[0][flat], low_e[1][flat] = _out(e_f[0] + de[0], e_f[1] + de[1])
                low_c[0][flat], low_c[1][flat] = _out(c_f[0] + dc[0], c_f[1] + dc[1])
                ds_l[0][flat], ds_l[1][flat] = interval_product(*dd, *cos_interval(*a_l))
            if sub.size:  # on or near the arc: the feed-forward in the law (any share of it below speed_epsilon)
                rsub = rr[sub]
                ffd = (np.minimum(ff_row[0][rsub], 0.0), np.maximum(ff_row[1][rsub], 0.0))
                e_s, c_s = (e_box[0][sub], e_box[1][sub]), (c_box[0][sub], c_box[1][sub])
                vs = (vh_lo[sub], vh_hi[sub])
                q_s = (tb_lo[rsub, 1] / vs[1], tb_hi[rsub, 1] / vs[0])
                if switch > 0.0:
                    sw = switch_steering(rsub, e_s, (tau * vl_lo[sub], tau * vl_hi[sub]), vs, q_s)
                    ffd = _out(ffd[0] + sw[0], ffd[1] + sw[1])
                _, _, d_s, a_s = lateral_remainder(e_s, c_s, vs, (b1[0][sub], b1[1][sub]), q_s, dt, vehicle, ff=ffd)
                dd = (vl_lo[sub] * dt, vl_hi[sub] * dt)
                de_s = interval_product(*dd, *sin_interval(*a_s))
                dc_s = interval_product(
                    2 * dd[0] / length, 2 * dd[1] / length, np.sin(slip_angle(d_s[0])), np.sin(slip_angle(d_s[1]))
                )
                zero = np.zeros(sub.size)
                e_x, _, ds_c, turn_c = curved_terms(rsub, dd, e_s, a_s, (zero, zero), km, end_in)
                low_e[0][sub], low_e[1][sub] = _out(e_s[0] + de_s[0] + e_x[0], e_s[1] + de_s[1] + e_x[1])
                low_c[0][sub], low_c[1][sub] = _out(c_s[0] + dc_s[0] - turn_c[1], c_s[1] + dc_s[1] - turn_c[0])
                ds_l[0][sub], ds_l[1][sub] = ds_c
            step_lo, step_hi = np.stack([low_e[0], low_c[0]], 1), np.stack([low_e[1], low_c[1]], 1)
            return step_lo, step_hi, ds_l

        def contract(nz_lo, nz_hi, ni_lo, ni_hi):
            """The boxes intersected with the hull of the units' contraction ellipse (straight lanes, v >= V_MIN)."""
            if not lateral_contraction:
                return nz_lo, nz_hi, ni_lo, ni_hi
            ok = ~curved_u & (vlo >= V_MIN) & np.all(np.isfinite(e_lo) & np.isfinite(e_hi), axis=1)
            rho = np.full(len(idx), np.inf)
            k_new = np.argmin(np.abs(log_nodes[None, :] - 0.5 * np.log(vf_lo_ * vf_hi_)[:, None]), axis=1)
            sel = np.flatnonzero(ok)
            if sel.size:
                us, rs, ks = idx[sel], rr[sel], k_new[sel]
                met = c_metrics[ks]
                rho_cur = np.minimum(
                    urho[us] * c_conv[umet[us], ks], unchecked_metric_radius(met, e_lo[sel], e_hi[sel])
                )
                # the speed box in SPEED_BINS geometric bins (narrow boxes too: cheap and tighter), lambda the
                # largest over the bins
                nb_ = SPEED_BINS
                rep = np.tile(sel, nb_)
                j = np.repeat(np.arange(nb_), sel.size)
                vs_lo, vs_hi = vlo[rep], vhi[rep]
                ratio_s = vs_hi / vs_lo
                bv_lo = vs_lo * ratio_s ** (j / nb_)
                bv_hi = np.where(j == nb_ - 1, vs_hi, vs_lo * ratio_s ** ((j + 1) / nb_))
                q = (tb_lo[rr[rep], 1] / bv_hi, tb_hi[rr[rep], 1] / bv_lo)
                lam = unchecked_contraction_factor(
                    np.tile(met, (nb_, 1, 1)),
                    (e_lo[rep, 0], e_hi[rep, 0]),
                    (e_lo[rep, 1], e_hi[rep, 1]),
                    (bv_lo, bv_hi),
                    (b1[0][rep], b1[1][rep]),
                    q,
                    dt,
                    vehicle,
                )
                lam = lam.reshape(nb_, sel.size).max(axis=0)
                # lam is inf outside the bound's validity (no radius then, even for a point box)
                rho[sel] = np.where(np.isfinite(lam), np.sqrt(lam) * rho_cur * (1.0 + CONTRACTION_MARGIN), np.inf)
                h_i = ellipse_hull(met, rho[sel])
                h_z = ellipse_hull(met, rho[sel], to_basis=Tinv[rs])
                ni_lo, ni_hi, nz_lo, nz_hi = ni_lo.copy(), ni_hi.copy(), nz_lo.copy(), nz_hi.copy()
                ni_lo[sel], ni_hi[sel] = np.maximum(ni_lo[sel], -h_i), np.minimum(ni_hi[sel], h_i)
                nz_lo[sel], nz_hi[sel] = np.maximum(nz_lo[sel], -h_z), np.minimum(nz_hi[sel], h_z)
            urho[idx], umet[idx] = rho, k_new
            return nz_lo, nz_hi, ni_lo, ni_hi

        def invariant(nz_lo, nz_hi, ni_lo, ni_hi):
            """The boxes of the units known to lie in an invariant set, whose step its proof covers (a straight
            lane, the speed box below its bound), intersected with its hull; then every unit's set updated."""
            if inv_sets is None or not len(inv_sets):
                return nz_lo, nz_hi, ni_lo, ni_hi
            cur = uinv[idx]
            bound = inv_sets.speed_bounds[np.maximum(cur, 0)]
            ok = (cur >= 0) & ~curved_u & inv_gains[rr] & (vhi <= bound)
            sel = np.flatnonzero(ok)
            if sel.size:
                t_lo, t_hi = inv_sets.tighten(cur[sel], ni_lo[sel], ni_hi[sel])
                z_lo, z_hi = _matvec(Tinv[rr[sel]], t_lo, t_hi)
                ni_lo, ni_hi, nz_lo, nz_hi = ni_lo.copy(), ni_hi.copy(), nz_lo.copy(), nz_hi.copy()
                ni_lo[sel], ni_hi[sel] = t_lo, t_hi
                nz_lo[sel], nz_hi[sel] = np.maximum(nz_lo[sel], z_lo), np.minimum(nz_hi[sel], z_hi)
            # a box inside a (smaller) set puts its states there too; the sets are nested
            found = np.where(inv_gains[rr], inv_sets.smallest_containing(ni_lo, ni_hi), -1)
            kept = np.where(ok, cur, -1)
            uinv[idx] = np.where((kept >= 0) & (found >= 0), np.minimum(kept, found), np.maximum(kept, found))
            return nz_lo, nz_hi, ni_lo, ni_hi

        # The direct step over the whole speed box contains the fine step's set too: intersect them (both
        # sound). Where the speed box is wide and reaches low speeds, the linearised law's stiff gains
        # (q = theta_b2 / v) make the vertex bound grow faster than the bicycle can turn.
        wd_lo, wd_hi, wd_s = direct_step(vlo, vhi)
        if_lo, if_hi = np.maximum(if_lo, wd_lo), np.minimum(if_hi, wd_hi)
        wz_lo, wz_hi = _matvec(Tinv[rr], wd_lo, wd_hi)
        zf_lo, zf_hi = np.maximum(zf_lo, wz_lo), np.minimum(zf_hi, wz_hi)
        sf = (np.maximum(sf[0], wd_s[0]), np.minimum(sf[1], wd_s[1]))
        if not l_ok.any():
            back_lo, back_hi = _matvec(T[rr], zf_lo, zf_hi)
            into_lo, into_hi = _matvec(Tinv[rr], if_lo, if_hi)
            boxes_ = contract(
                np.maximum(zf_lo, into_lo),
                np.minimum(zf_hi, into_hi),
                np.maximum(if_lo, back_lo),
                np.minimum(if_hi, back_hi),
            )
            return (*invariant(*boxes_), sf[0], sf[1])
        # low speeds: the direct step alone
        il_lo, il_hi, sl = direct_step(vlo, np.minimum(vhi, V_MIN))
        zl_lo, zl_hi = _matvec(Tinv[rr], il_lo, il_hi)
        fo, lo_ = f_ok[:, None], l_ok[:, None]
        nz_lo = np.minimum(np.where(fo, zf_lo, np.inf), np.where(lo_, zl_lo, np.inf))
        nz_hi = np.maximum(np.where(fo, zf_hi, -np.inf), np.where(lo_, zl_hi, -np.inf))
        ni_lo = np.minimum(np.where(fo, if_lo, np.inf), np.where(lo_, il_lo, np.inf))
        ni_hi = np.maximum(np.where(fo, if_hi, -np.inf), np.where(lo_, il_hi, -np.inf))
        back_lo, back_hi = _matvec(T[rr], nz_lo, nz_hi)
        into_lo, into_hi = _matvec(Tinv[rr], ni_lo, ni_hi)
        nz_lo, nz_hi = np.maximum(nz_lo, into_lo), np.minimum(nz_hi, into_hi)
        ni_lo, ni_hi = np.maximum(ni_lo, back_lo), np.minimum(ni_hi, back_hi)
        ds_lo = np.minimum(np.where(f_ok, sf[0], np.inf), np.where(l_ok, sl[0], np.inf))
        ds_hi = np.maximum(np.where(f_ok, sf[1], -np.inf), np.where(l_ok, sl[1], -np.inf))
        return (*invariant(*contract(nz_lo, nz_hi, ni_lo, ni_hi)), ds_lo, ds_hi)

    # dead units hold empty boxes (inf, -inf): their arithmetic is masked, never output
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        for n in range(H1):
            # ------------------------------------------------ world boxes per row
            eu_lo, eu_hi = unit_boxes()
            alive = ualive[:R].copy()
            if has_side:
                alive |= ualive[R:].reshape(R, 2 * C).any(axis=1)
            e_lo, e_hi = row_hull(eu_lo, eu_hi)
            lat_lo, lat_hi = e_lo[:, 0] + c, e_hi[:, 0] + c
            ch_lo, ch_hi = e_lo[:, 1], e_hi[:, 1]
            with np.errstate(invalid="ignore"):
                fx = _lin(origin[:, 0], u[:, 0], -u[:, 1], s_lo, s_hi, lat_lo, lat_hi)
                fy = _lin(origin[:, 1], u[:, 1], u[:, 0], s_lo, s_hi, lat_lo, lat_hi)
            ps_lo = np.where(fine, h_unw + ch_lo, p_lo)
            ps_hi = np.where(fine, h_unw + ch_hi, p_hi)
            rt = np.flatnonzero(routed & fine & alive)
            if rt.size:  # rows on their route's pieces: the hull over the pieces met, the route's heading added
                fx, fy = [a.copy() for a in fx], [a.copy() for a in fy]
                fx[0][rt], fx[1][rt], fy[0][rt], fy[1][rt] = route_xy(rt, s_lo, s_hi, lat_lo, lat_hi)
                hr_lo, hr_hi = heading_range(s_lo, s_hi)
                ps_lo[rt], ps_hi[rt] = _out(h_unw[rt] + hr_lo[rt] + ch_lo[rt], h_unw[rt] + hr_hi[rt] + ch_hi[rt])
            cx_lo, cx_hi = np.where(fine, fx[0], x_lo), np.where(fine, fx[1], x_hi)
            cy_lo, cy_hi = np.where(fine, fy[0], y_lo), np.where(fine, fy[1], y_hi)
            dead = ~alive
            cx_lo[dead] = cy_lo[dead] = ps_lo[dead] = 0.0
            cx_hi[dead] = cy_hi[dead] = ps_hi[dead] = 0.0
            foot = footprint_box(np.stack([cx_lo, cy_lo], 1), np.stack([cx_hi, cy_hi], 1), ps_lo, ps_hi, vehicle)
            if road_edges:
                foot = np.where(fine[:, None], foot, _clip_to_road(foot, road_boxes))
            st_lo = np.stack([cx_lo, cy_lo, v_lo, ps_lo], 1)
            st_hi = np.stack([cx_hi, cy_hi, v_hi, ps_hi], 1)
            st_lo[dead], st_hi[dead], foot[dead] = np.inf, -np.inf, empty
            lower[n] = st_lo.reshape(m, P, 4).min(axis=1)
            upper[n] = st_hi.reshape(m, P, 4).max(axis=1)
            fb = foot.reshape(m, P, 4)
            boxes[n] = np.concatenate([fb[..., :2].min(axis=1), fb[..., 2:].max(axis=1)], axis=1)
            guaranteed[n] = (fine | dead).reshape(m, P).all(axis=1)
            if n == steps:
                break

            # ------------------------------------- leave the fine region -> coarse
            ahead = tau * v_hi if switch == 0.0 else np.maximum(tau * v_hi, switch)
            leave = fine & alive & ((np.maximum(-ch_lo, ch_hi) > CHI_MAX) | (s_hi + ahead > prefix_end))

            # --------------------------------------- the other agents' boxes at step n
            vb_lo = np.where(alive[:, None], np.stack([cx_lo, cy_lo], 1), np.inf)
            vb_hi = np.where(alive[:, None], np.stack([cx_hi, cy_hi], 1), -np.inf)
            k_lo = np.vstack([vb_lo.reshape(m, P, 2).min(axis=1), reach[n, :2]])
            k_hi = np.vstack([vb_hi.reshape(m, P, 2).max(axis=1), reach[n, 2:]])
            kfoot = np.vstack([boxes[n], reach[n]])
            present = np.all(kfoot[:, :2] <= kfoot[:, 2:], axis=1)
            k_lo[~present], k_hi[~present] = 0.0, 0.0
            kv_lo = np.append(lower[n, :, 2], max(e_speed[n, 0], 0.0))
            kv_hi = np.append(upper[n, :, 2], e_speed[n, 1])
            pk_lo, pk_hi = _lin(
                -np.sum(origin * u, axis=1)[:, None],
                u[:, None, 0],
                u[:, None, 1],
                k_lo[None, :, 0],
                k_hi[None, :, 0],
                k_lo[None, :, 1],
                k_hi[None, :, 1],
            )
            lk_lo, lk_hi = _lin(
                (-np.sum(origin * nrm, axis=1) - c)[:, None],
                nrm[:, None, 0],
                nrm[:, None, 1],
                k_lo[None, :, 0],
                k_hi[None, :, 0],
                k_lo[None, :, 1],
                k_hi[None, :, 1],
            )
            # agents that certainly occupy the row's lane and stay on the road: every hypothesis of
            # theirs steers to it or has its centre in its strip (the ego: its centre box in the strip)
            abs_lo, abs_hi = lat_lo, lat_hi
            lw = road.widths[None, :] / 2
            with np.errstate(invalid="ignore"):
                strip_in = (abs_lo[:, None] >= lane_offset[None, :] - lw) & (
                    abs_hi[:, None] <= lane_offset[None, :] + lw
                )
            certain_row = ~alive[:, None] | (row_lane[:, None] == np.arange(n_lanes)[None, :]) | (strip_in & same_group)
            certain_row = (certain_row & fine[:, None]) | ~alive[:, None] | ~side_row[:, None]
            certain_veh = certain_row.reshape(m, P, n_lanes).all(axis=1)[:, row_lane].T  # (R, m)
            phys = (lk_lo >= -half_w[:, None]) & (lk_hi <= half_w[:, None])  # centre certainly in the strip
            certain_k = np.where(side_row[:, None], np.concatenate([certain_veh, phys[:, m:]], axis=1), phys)
            in_strip = present[None, :] & ~same & certain_k & (pk_hi + length / 2 < exit_s[:, None])
            # pairs that may both steer to the row's lane after a switch: the later switch accepted the gap
            # the pair's states at a switch may lie in any row of the vehicle: use its hull over the rows
            sv_lo = np.where(alive, s_lo, np.inf).reshape(m, P).min(axis=1)[veh_of]
            sv_hi = np.where(alive, s_hi, -np.inf).reshape(m, P).max(axis=1)[veh_of]
            vv_lo = np.where(alive, v_lo, np.inf).reshape(m, P).min(axis=1)[veh_of]
            gap_need = (
                beh.standstill_distance
                + rules.lane_change_margin
                + beh.time_headway * np.minimum(vv_lo[:, None], kv_lo[None, :])
            )
            pair_ok |= np.maximum(np.abs(pk_lo - sv_hi[:, None]), np.abs(pk_hi - sv_lo[:, None])) - length >= gap_need

            # ------------------------------------------- switching (side lanes)
            if has_side:
                slot = (n // block) % C
                cohort = R + (2 * np.arange(R)[:, None] + np.arange(2)[None, :]) * C + slot  # (R, 2)
                if (
                    n % block == 0 and n > 0
                ):  # the slot's cohorts are >= C block steps old: merge into the row's own box
                    for d in range(2):
                        k = cohort[:, d]
                        old = ualive[k]
                        if lateral_contraction:
                            # the merged states satisfy either ellipse: the larger radius in the row's metric
                            from_k = np.minimum(
                                urho[k] * c_conv[umet[k], umet[:R]],
                                unchecked_metric_radius(c_metrics[umet[:R]], eu_lo[k], eu_hi[k]),
                            )
                            urho[:R] = np.where(
                                old, np.where(ualive[:R], np.maximum(urho[:R], from_k), from_k), urho[:R]
                            )
                            urho[k] = np.inf
                        # the merged states lie in the larger of two known sets (nested), else in none known
                        both_known = (uinv[:R] >= 0) & (uinv[k] >= 0)
                        merged = np.where(ualive[:R], np.where(both_known, np.maximum(uinv[:R], uinv[k]), -1), uinv[k])
                        uinv[:R] = np.where(old, merged, uinv[:R])
                        uinv[k] = -1
                        for lo_a, hi_a in ((ui_lo, ui_hi), (uz_lo, uz_hi)):
                            lo_a[:R] = np.where(old[:, None], np.minimum(lo_a[:R], lo_a[k]), lo_a[:R])
                            hi_a[:R] = np.where(old[:, None], np.maximum(hi_a[:R], hi_a[k]), hi_a[:R])
                            lo_a[k], hi_a[k] = np.inf, -np.inf
                        ualive[:R] |= old
                        ualive[k] = False
                nat_lo, nat_hi = eu_lo[:R], eu_hi[:R]  # the sources: each row's own box (settled part)
                new_s = [
                    np.where(alive, a, np.inf if q % 2 == 0 else -np.inf)
                    for q, a in enumerate((s_lo, s_hi, v_lo, v_hi))
                ]
                to_coarse = np.zeros(R, dtype=bool)
                xy = [cx_lo.copy(), cx_hi.copy(), cy_lo.copy(), cy_hi.copy(), ps_lo.copy(), ps_hi.copy()]
                xy = [np.where(alive, a, np.inf if i % 2 == 0 else -np.inf) for i, a in enumerate(xy)]
                for d in range(2):
                    nb = nbr[:, d]
                    ok = nb >= 0
                    nb = np.maximum(nb, 0)
                    src_alive = ualive[nb] & ok
                    fine_pair = fine[nb] & fine & ~leave & ~leave[nb]
                    je_lo = np.maximum(nat_lo[nb, 0], -settle)
                    je_hi = np.minimum(nat_hi[nb, 0], settle)
                    # gap acceptance: blocked by an agent certainly in the target lane whatever the states
                    d_lo, d_hi = pk_lo - s_hi[nb][:, None], pk_hi - s_lo[nb][:, None]
                    far = np.maximum(np.abs(d_lo), np.abs(d_hi)) - length
                    # the rule's headway reads the follower's speed: the agent's when it is certainly
                    # behind (d_hi < 0), the switching vehicle's when the agent is certainly ahead
                    follower_lo = np.where(
                        d_hi < 0.0,
                        kv_lo[None, :],
                        np.where(d_lo > 0.0, v_lo[nb][:, None], np.minimum(v_lo[nb][:, None], kv_lo[None, :])),
                    )
                    need = beh.standstill_distance + rules.lane_change_margin + beh.time_headway * follower_lo
                    blocked = (in_strip & (far < need)).any(axis=1)
                    both = src_alive & fine_pair & (je_lo <= je_hi) & ~blocked
                    coarse_in = ok & alive[nb] & ~fine_pair
                    shift = c[nb] - c
                    ii_lo, ii_hi = _out(
                        np.stack([je_lo + shift, nat_lo[nb, 1]], 1), np.stack([je_hi + shift, nat_hi[nb, 1]], 1)
                    )
                    zi_lo, zi_hi = _matvec(Tinv, ii_lo, ii_hi)
                    k = cohort[:, d]
                    for lo_a, hi_a, a_lo, a_hi in ((ui_lo, ui_hi, ii_lo, ii_hi), (uz_lo, uz_hi, zi_lo, zi_hi)):
                        lo_a[k] = np.where(both[:, None], np.minimum(lo_a[k], a_lo), lo_a[k])
                        hi_a[k] = np.where(both[:, None], np.maximum(hi_a[k], a_hi), hi_a[k])
                    if lateral_contraction:
                        # the cohort's new states: the radius of their box joins the cohort's
                        entry = unchecked_metric_radius(c_metrics[umet[k]], ii_lo, ii_hi)
                        urho[k] = np.where(both, np.where(ualive[k], np.maximum(urho[k], entry), entry), urho[k])
                    ualive[k] |= both
                    uinv[k] = np.where(both, -1, uinv[k])  # new states, in no set known yet
                    grow = both | coarse_in
                    for q, (arr, op) in enumerate(
                        ((s_lo, np.minimum), (s_hi, np.maximum), (v_lo, np.minimum), (v_hi, np.maximum))
                    ):
                        new_s[q] = np.where(grow, op(new_s[q], arr[nb]), new_s[q])
                    src_xy = (cx_lo, cx_hi, cy_lo, cy_hi, ps_lo, ps_hi)
                    for q in range(6):
                        op = np.minimum if q % 2 == 0 else np.maximum
                        xy[q] = np.where(coarse_in, op(xy[q], src_xy[q][nb]), xy[q])
                    to_coarse |= coarse_in
                grown = np.isfinite(new_s[0])
                s_lo, s_hi, v_lo, v_hi = (np.where(grown, a, b) for a, b in zip(new_s, (s_lo, s_hi, v_lo, v_hi)))
                leave = leave | (to_coarse & fine)
                cx_lo, cx_hi, cy_lo, cy_hi, ps_lo, ps_hi = (
                    np.where(to_coarse, xy[q], a) for q, a in enumerate((cx_lo, cx_hi, cy_lo, cy_hi, ps_lo, ps_hi))
                )
                alive = alive | to_coarse | ualive[R:].reshape(R, 2 * C).any(axis=1)
                eu_lo, eu_hi = unit_boxes()
                e_lo, e_hi = row_hull(eu_lo, eu_hi)
                ch_lo, ch_hi = e_lo[:, 1], e_hi[:, 1]
                # the rows' physical boxes after the switches (a new row holds its source's states)
                fx = _lin(origin[:, 0], u[:, 0], -u[:, 1], s_lo, s_hi, e_lo[:, 0] + c, e_hi[:, 0] + c)
                fy = _lin(origin[:, 1], u[:, 1], u[:, 0], s_lo, s_hi, e_lo[:, 0] + c, e_hi[:, 0] + c)
                upd = fine & ~to_coarse & alive
                cx_lo, cx_hi = np.where(upd, fx[0], cx_lo), np.where(upd, fx[1], cx_hi)
                cy_lo, cy_hi = np.where(upd, fy[0], cy_lo), np.where(upd, fy[1], cy_hi)
                ps_lo, ps_hi = np.where(upd, h_unw + ch_lo, ps_lo), np.where(upd, h_unw + ch_hi, ps_hi)
            if leave.any():
                x_lo, x_hi = np.where(leave, cx_lo, x_lo), np.where(leave, cx_hi, x_hi)
                y_lo, y_hi = np.where(leave, cy_lo, y_lo), np.where(leave, cy_hi, y_hi)
                p_lo, p_hi = np.where(leave, ps_lo, p_lo), np.where(leave, ps_hi, p_hi)
                fine = fine & ~leave
                gone = ~fine[unit_row]
                ualive[:R] |= alive & ~fine
                ualive[R:] &= ~gone[R:]

            # ------------------------------------------------- possible leaders
            in_prefix = ~np.isnan(pre_lo) & (np.nan_to_num(pre_hi, nan=-np.inf) >= s_lo[:, None])
            row_int = np.where(
                fine[:, None], in_prefix & (np.nan_to_num(pre_lo, nan=np.inf) <= s_hi[:, None]), route_mask
            )
            if routed.any():  # beyond the prefix too (the lanes of a routed row are its route lanes met by s)
                met_bey = (np.nan_to_num(beyond_start, nan=np.inf) <= s_hi[:, None]) & (
                    np.nan_to_num(beyond_start + road.lengths[None, :], nan=-np.inf) >= s_lo[:, None]
                )
                row_int |= (routed & fine)[:, None] & met_bey
            row_int &= alive[:, None]
            switched = (
                row_int & ~belief_lane[:, None]
            )  # side lanes steered to only after a switch since the observation
            foot_now = footprint_box(
                np.stack([np.where(alive, cx_lo, 0.0), np.where(alive, cy_lo, 0.0)], 1),
                np.stack([np.where(alive, cx_hi, 0.0), np.where(alive, cy_hi, 0.0)], 1),
                np.where(alive, ps_lo, 0.0),
                np.where(alive, ps_hi, 0.0),
                vehicle,
            )
            row_touch = (
                np.all(
                    (foot_now[:, None, :2] <= strips[None, :, 2:]) & (foot_now[:, None, 2:] >= strips[None, :, :2]), -1
                )
                & alive[:, None]
            )
            # a switched row's rectangle in the lane it switched into: gated by the gap rule like its intention
            into_own = (alive & ~belief_lane & side_row)[:, None] & (np.arange(n_lanes)[None, :] == row_lane[:, None])
            occ = np.zeros((m + 1, n_lanes), dtype=bool)
            occ[:m] = ((row_int & ~switched) | (row_touch & ~into_own)).reshape(m, P, n_lanes).any(axis=1)
            occ[m] = ego_lanes[n] | np.all(
                (reach[n, None, :2] <= strips[:, 2:]) & (reach[n, None, 2:] >= strips[:, :2]), axis=-1
            )
            occ &= present[:, None]
            occ_sw = np.zeros((m + 1, n_lanes), dtype=bool)
            occ_sw[:m] = (switched | (row_touch & into_own)).reshape(m, P, n_lanes).any(axis=1)
            occ_sw &= present[:, None]
            interest_pre = in_prefix | (side & (row_touch | (np.arange(n_lanes)[None, :] == row_lane[:, None])))
            pre = (interest_pre[:, None, :] & occ[None, :, :]).any(axis=-1)
            pre |= (interest_pre[:, None, :] & occ_sw[None, :, :]).any(axis=-1) & pair_ok
            pre &= ~same
            bey_lanes = beyond[:, None, :] & occ[None, :, :]  # (R, m + 1, n_lanes)
            bey = bey_lanes.any(axis=-1) & ~same
            dist_lo, dist_hi = pk_lo - s_hi[:, None], pk_hi - s_lo[:, None]
            poss_pre = pre & (dist_hi > 0)
            gap_cand = np.where(poss_pre, np.maximum(dist_lo, 0.0) - length, np.inf)
            if bey.any():  # never on the highway (its rows have no lane beyond a prefix)
                # an occupant of a lane beyond the prefix is at least the route distance to that lane's
                # start plus its centre's arc length on it away (a candidate leader is ahead: >= 0)
                cols = beyond_used
                arc_lo, arc_hi = _centre_arc_length_bounds(road, cols, k_lo, k_hi, present)
                arc_lo, arc_hi = arc_lo[:, cols], arc_hi[:, cols]  # (m + 1, lanes)
                # a leader is ahead along the route: an occupant that is certainly behind the row is not one
                ahead = beyond_start[:, None, cols] + arc_hi[None] > s_lo[:, None, None]
                bey_lanes[..., cols] &= ahead | np.isnan(beyond_start[:, None, cols])
                bey = bey_lanes.any(axis=-1) & ~same
                bey_dist = np.where(
                    bey_lanes[..., cols], beyond_start[:, None, cols] + arc_lo[None] - s_hi[:, None, None], np.inf
                ).min(axis=-1)
                bey_dist = np.where(np.isnan(bey_dist), 0.0, bey_dist)
                gap_cand = np.where(bey, np.minimum(gap_cand, np.maximum(bey_dist, 0.0) - length), gap_cand)
            kp_lo = np.append(lower[n, :, 3], e_head[n, 0])[None, :] - heading[:, None]
            kp_hi = np.append(upper[n, :, 3], e_head[n, 1])[None, :] - heading[:, None]
            with np.errstate(invalid="ignore"):
                cs_lo, cs_hi = cos_interval(np.nan_to_num(kp_lo), np.nan_to_num(kp_hi))
            vf_lo = np.minimum(kv_lo[None, :] * cs_lo, kv_hi[None, :] * cs_lo)
            vf_hi = np.maximum(kv_hi[None, :] * cs_hi, kv_lo[None, :] * cs_hi)
            vf_lo = np.where(bey, -np.abs(kv_hi)[None, :], vf_lo)  # a lane beyond the prefix: any direction
            vf_hi = np.where(bey, np.abs(kv_hi)[None, :], vf_hi)
            certain = poss_pre & in_strip & (dist_lo > 0)
            gap_hi = np.where(certain, dist_hi - length, np.inf).min(axis=1)
            # the leader is the nearest candidate: one farther than a certain candidate can be is not it
            nearest = np.where(certain, dist_hi, np.inf).min(axis=1)
            any_poss = (poss_pre & (dist_lo <= nearest[:, None])) | bey
            front_lo = np.where(any_poss, vf_lo, np.inf).min(axis=1)
            front_hi = np.where(any_poss, vf_hi, -np.inf).max(axis=1)
            gap_lo = np.where(any_poss, gap_cand, np.inf).min(axis=1)
            may_stop = ~np.isnan(stop_s) & (s_lo <= np.nan_to_num(stop_s, nan=-np.inf))
            stop_gap = np.maximum(np.nan_to_num(stop_s, nan=np.inf) - s_hi - length / 2, 0.0)
            gap_lo = np.where(may_stop, np.minimum(gap_lo, stop_gap), gap_lo)
            front_lo = np.where(may_stop, np.minimum(front_lo, 0.0), front_lo)
            front_hi = np.where(may_stop, np.maximum(front_hi, 0.0), front_hi)
            front_hi = np.where(np.isfinite(gap_hi), front_hi, np.inf)
            vt_lo = np.where((s_hi >= cap_from) & (s_lo <= cap_to), np.minimum(t_lo, cap_speed), t_lo)
            vt_hi = np.where((s_lo >= cap_from) & (s_hi <= cap_to), np.minimum(t_hi, cap_speed), t_hi)
            coarse = ~fine  # no information on the front object or the curve cap
            gap_lo = np.where(coarse, -length, gap_lo)
            front_lo = np.where(coarse, -vmax, front_lo)
            gap_hi = np.where(coarse, np.inf, gap_hi)
            front_hi = np.where(coarse, np.inf, front_hi)
            vt_lo = np.where(coarse, 0.0, vt_lo)
            vt_hi = np.where(coarse, t_hi, vt_hi)
            # ----------------------------------------------------- longitudinal
            nv_lo, nv_hi = longitudinal_bounds(
                (v_lo, v_hi), (vt_lo, vt_hi), (front_lo, front_hi), (gap_lo, gap_hi), (ta_lo, ta_hi), dt, beh, vmax
            )

            # ---------------------------------------------------------- lateral
            idx = np.flatnonzero(ualive & fine[unit_row])
            if idx.size:
                nz_lo, nz_hi, ni_lo, ni_hi, ds_lo, ds_hi = lateral_step(idx, v_lo, v_hi)
                uz_lo[idx], uz_hi[idx], ui_lo[idx], ui_hi[idx] = nz_lo, nz_hi, ni_lo, ni_hi
                d_lo = np.full(R, np.inf)
                d_hi = np.full(R, -np.inf)
                np.minimum.at(d_lo, unit_row[idx], ds_lo)
                np.maximum.at(d_hi, unit_row[idx], ds_hi)
                moved = fine & np.isfinite(d_lo) & np.isfinite(d_hi)
                ns_lo, ns_hi = _out(s_lo + np.where(moved, d_lo, 0.0), s_hi + np.where(moved, d_hi, 0.0))
                s_lo, s_hi = np.where(moved, ns_lo, s_lo), np.where(moved, ns_hi, s_hi)

            # ----------------------------------------------------------- coarse
            a_lo, a_hi = p_lo - beta_max, p_hi + beta_max
            dx = interval_product(v_lo * dt, v_hi * dt, *cos_interval(a_lo, a_hi))
            dy = interval_product(v_lo * dt, v_hi * dt, *sin_interval(a_lo, a_hi))
            turn = 2 * dt / length * np.sin(beta_max)
            x_lo, x_hi = _out(x_lo + dx[0], x_hi + dx[1])
            y_lo, y_hi = _out(y_lo + dy[0], y_hi + dy[1])
            if road_edges:
                x_lo, y_lo, x_hi, y_hi = _clip_to_road(np.stack([x_lo, y_lo, x_hi, y_hi], 1), road_boxes).T
            p_lo, p_hi = _out(p_lo - turn * v_hi, p_hi + turn * v_hi)
            v_lo, v_hi = nv_lo, nv_hi

    if np.isnan(boxes).any() or np.isnan(lower).any() or np.isnan(upper).any():
        raise FloatingPointError("the forecast produced NaN bounds (a bug: please report it)")
    return TrafficForecast(boxes, lower, upper, guaranteed, ids, dt)
