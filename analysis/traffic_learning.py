"""Learning the other vehicles of the driving worlds: intentions eliminated, parameter boxes.

`TrafficLearner` is fed one `Observation` per sub-step. Per other vehicle it keeps the
measured history in the Frenet frames of the lanes (`Road.frenet`), turns every
measured transition into *interval rows* linear in the behaviour parameters (the
LinearVehicle law of `minimaxplan.scenarios.vehicles`, with the measurement noise on
the states **and** on the regressors: the leader's measured speed and the gap are
inputs of the follower's law), eliminates the wrong intentions with the certified LP
of `minimaxplan.verify.interval_regression`, and gives a `VehicleBelief` per vehicle.

Hypotheses
----------
A hypothesis of a vehicle is the route it follows from the lane it was first seen on:
on the highway one single-lane route per lane of the side group (the lane it steers
to); at the T-junction every lane sequence through the road's connections (its route
through the junction). Whether it yields is not a hypothesis of its own: it may
switch at any sub-step, so the stop line is one more possible front object in the
hull of the longitudinal regressors (below) whenever the vehicle approaches a junction
lane.

Data models (per transition ``n -> n+1`` of sub-step ``dt``; noise half-widths
``(x, y, v, psi)`` = ``measurement_noise``, disturbance ``|w| <= w_bar``)

* Longitudinal, parameters ``(theta_a1, theta_a2, theta_a3, c)`` with
  ``c = theta_a1 v_target`` (the unknown target speed lies in the scenario's range, so
  ``theta_a1 v_lo <= c <= theta_a1 v_hi``: two exact linear rows). When the transition
  is surely linear (speed surely in ``(0, max_speed)`` after it, and the acceleration
  surely inside the clip), ``v_{n+1} - v_n = dt (theta_a . f_n + w_n)``; summed over a
  window of ``k`` such transitions the measurement noise telescopes:
  ``theta . sum f in [(dv~ - 2 v_bar) / dt - k w_bar, (dv~ + 2 v_bar) / dt + k w_bar]``
  with ``f_n`` an interval: ``f1 = -v`` (+ c) or ``cap - v`` on and before arcs (the
  curve cap is known there), ``f2 = min(v_front - v, 0)`` and ``f3 = min(gap - d0 - T v, 0)``
  hulled over every possible front object (a possible leader, the stop line if the
  vehicle may yield, none if no leader is sure), each bounded exactly (monotone) from
  the measured boxes. A transition that may be clipped gives the one-sided single row
  of the clip's monotone inverse (``clip(u) >= lo > -a_max`` implies ``u >= lo``).
* Lateral, parameters ``theta_b``: ``psi_{n+1} - psi_n = (2 dt / L) v_n sin(beta_n)``,
  ``tan beta = tan(delta) / 2``, ``delta = theta_b . g``; with ``v g = [e L, -offset L / v]``
  and ``sin(beta) = delta / 2 + r(delta)``, ``0 <= r(|delta|) <= R(D) = s(D) - D / 2`` for
  ``|delta| <= D <= pi / 3`` (s' >= 1/2 there, proven in `remainder_bound`), summed over
  a window: ``theta_b . sum v g in (L / dt) (dpsi~ +- 2 psi_bar) +- 2 sum v_hi R``. The
  bound D of each transition comes from its own measured heading change; a transition
  whose D reaches the steering clip, or whose speed may be below `LATERAL_MIN_SPEED`,
  ends the windows (it is not used). The heading error and the offset are taken from
  the hypothesis' lane with the Frenet maps of a noise box (exact for straight lanes,
  1-Lipschitz bounds on arcs); near a lane end both possible current lanes are hulled.

theta_a, theta_b >= 0 in the priors, so an interval regressor ``g`` gives
``theta . g_lo <= y_hi`` and ``theta . g_hi >= y_lo`` (exact).

Last possible switch
--------------------
A lane change into lane ``l`` can only start at a sub-step at which the vehicle is
settled in a side neighbour ``l'`` of ``l`` (``|offset from l'| < lane_change_settled``,
`TrafficRules`): ``t*_l`` is the last sub-step at which the *measured* offset from a
neighbour of ``l`` is below ``lane_change_settled`` plus the offset's noise bound (or
the first sub-step seen). If ``l`` is in force now, it was chosen at some sub-step
``t_s`` at which the vehicle was settled in a neighbour of ``l``, so ``t_s <= t*_l``, and
``l`` has been in force for every transition from ``t*_l`` on; the rows of ``l`` use
only those. Hence elimination never removes the intention in force (the rows of the
true hypothesis are satisfied by the true theta, and the LP eliminates only with a
re-checked certificate); a hypothesis eliminated earlier is revived when ``t*`` moves
(a new possible switch). Routes at the T-junction never switch (``t*`` = first seen).

Beliefs
-------
``theta_a`` and ``theta_b`` of a `VehicleBelief` are the hull over the surviving
hypotheses of their LP boxes, intersected with every earlier such hull (each was
sound when made, and theta is constant). LP boxes are refitted only when a
hypothesis' rows grew by ``refit_growth`` (like `analysis.robot_methods._Learner`);
between refits the last box stays valid (more rows, smaller set). A hypothesis'
witness is checked on its new rows in numpy at every sub-step; the LP is re-solved
only when the witness fails.

Measured (`elimination_study`, seeds 0-19, `hold_lane_control`, by
``benchmarks/elimination_times.py``; transitions from the moment the intention was wrong
to its elimination, median [min, max], eliminated / wrong cases): highway, the lane being
left in a lane change 1 [1, 2] (39/39), a lane two away 4 [4, 4] (226/227), a side
neighbour of the lane kept 4 [4, 4] (1/386: by design not while the vehicle is settled;
the one was mid-change, when no change to that lane can start); T-junction, the straight route of a turning vehicle 133 [77, 285] (31/83, the
rest left view first: until the stop line a courteous vehicle may be yielding), the
turn of a vehicle going straight 86 [6, 276] (101/168). No miss in 30000 + 44942
vehicle-steps (true intention among the survivors, true theta in both boxes). Cost:
about 22 ms per sub-step for 15 highway vehicles (110 ms per 0.5 s decision), over the
goal of a few ms per decision.

Assumption (stated, not proven): another vehicle at the T-junction steers to a lane
whose centre line is within ``OCCUPANCY_REACH`` of its centre; it decides who may be a
leader there (measured: at most 0.69 m, docs/driving-world.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from minimaxplan.models import Box
from minimaxplan.models.errors import InputError, NoConsistentModel, SolverFailure
from minimaxplan.models.prediction import cos_interval, interval_product
from minimaxplan.scenarios.road import ARC, Road
from minimaxplan.scenarios.road_world import HighwayScenario, Observation, TJunctionScenario
from minimaxplan.scenarios.traffic_models import VehicleBelief
from minimaxplan.verify.interval_regression import (
    INTERVAL_ROUNDING_ALLOWANCE,
    IntervalRows,
    interval_consistency,
    interval_parameter_box,
)

__all__ = [
    "NominalEstimate",
    "TrafficLearner",
    "LATERAL_MIN_SPEED",
    "OCCUPANCY_REACH",
    "WINDOWS",
    "remainder_bound",
    "elimination_statistics",
    "elimination_events",
    "censored_events",
    "hold_lane_control",
    "elimination_study",
]

#: Transitions whose speed may be below this (m/s) give no lateral row (1 / v unbounded).
LATERAL_MIN_SPEED = 1.0
#: T-junction: lanes whose strip, widened by this (m), holds a vehicle's centre are
#: the lanes it may steer to (see the module's assumption).
OCCUPANCY_REACH = 1.0
#: Window lengths (transitions) of the telescoped rows; a window of length k is made
#: every max(1, k // 4) sub-steps.
WINDOWS = (4, 16, 64)
#: Relative outward rounding applied to every computed row.
ROW_ROUNDING = 1e-10


@dataclass(frozen=True)
class NominalEstimate:
    """The nominal method's point estimates for one vehicle.

    Attributes
    ----------
    agent : int
        Agent index.
    theta_a : numpy.ndarray
        Shape (3,): least-squares acceleration gains (clipped to the prior).
    theta_b : numpy.ndarray
        Shape (2,): least-squares steering gains of the minimum-error route (clipped).
    route : tuple of int
        The minimum-error route (smallest mean squared normalised residual).
    lane : int
        Its current lane.
    """

    agent: int
    theta_a: np.ndarray
    theta_b: np.ndarray
    route: tuple[int, ...]
    lane: int


def remainder_bound(D):
    """``R(D) = s(D) - D / 2`` with ``s(delta) = sin(arctan(tan(delta) / 2))``, rounded up.

    Parameters
    ----------
    D : array_like
        Bounds on ``|delta|`` in ``[0, pi / 3]``, rad.

    Returns
    -------
    numpy.ndarray
        ``max_{|delta| <= D} |s(delta) - delta / 2|``.

    Notes
    -----
    With ``u = tan(delta) / 2``, ``s = u / sqrt(1 + u^2)`` and
    ``s' = (1 + 4 u^2) / (2 (1 + u^2)^(3/2))``; ``s' >= 1/2`` iff
    ``x (5 + 13 x - x^2) >= 0`` (``x = u^2``), true for ``u <= 3.6``, i.e. every
    ``|delta| <= 82 deg``. So ``s(delta) - delta / 2`` is odd and nondecreasing on
    ``[0, pi/3]``: its largest modulus over ``|delta| <= D`` is at D.
    """
    D = np.asarray(D, dtype=float)
    value = np.sin(np.arctan(np.tan(D) / 2)) - D / 2
    return np.maximum(value, 0.0) * (1 + 1e-9) + 1e-15


class _RowStore:
    """Interval rows in arrays grown by doubling; ``ok`` marks the rows the current witness explains."""

    def __init__(self, d: int) -> None:
        self.d, self.n = d, 0
        self.start = np.zeros(16, dtype=int)
        self.glo, self.ghi = np.zeros((16, d)), np.zeros((16, d))
        self.ylo, self.yhi = np.zeros(16), np.zeros(16)
        self.ok = np.zeros(16, dtype=bool)

    def append(self, start: int, glo, ghi, ylo: float, yhi: float) -> None:
        if self.n == self.start.size:
            for name in ("start", "glo", "ghi", "ylo", "yhi", "ok"):
                a = getattr(self, name)
                setattr(self, name, np.concatenate([a, np.zeros_like(a)]))
        i = self.n
        self.start[i], self.glo[i], self.ghi[i], self.ylo[i], self.yhi[i], self.ok[i] = start, glo, ghi, ylo, yhi, False
        self.n += 1

    def drop_before(self, first: int) -> None:
        keep = np.flatnonzero(self.start[: self.n] >= first)
        if keep.size == self.n:
            return
        for name in ("start", "glo", "ghi", "ylo", "yhi", "ok"):
            a = getattr(self, name)
            a[: keep.size] = a[keep]
        self.n = keep.size

    def rows(self, extra: IntervalRows | None = None) -> IntervalRows:
        n = self.n
        own = IntervalRows(self.glo[:n], self.ghi[:n], self.ylo[:n], self.yhi[:n])
        return own if extra is None else IntervalRows.stack([extra, own], self.d)

    def explained(self, theta: np.ndarray, scale: np.ndarray) -> bool:
        """Whether ``theta`` explains the rows not yet marked (marks them if so), as `witness_margin`."""
        idx = np.flatnonzero(~self.ok[: self.n])
        if idx.size == 0:
            return True
        glo, ghi, ylo, yhi = self.glo[idx], self.ghi[idx], self.ylo[idx], self.yhi[idx]
        y_abs = np.maximum(np.where(np.isfinite(ylo), np.abs(ylo), 0.0), np.where(np.isfinite(yhi), np.abs(yhi), 0.0))
        beta = np.maximum(np.abs(glo), np.abs(ghi)) @ scale + y_abs
        beta = np.where(beta > 0, beta, 1.0)
        allowance = INTERVAL_ROUNDING_ALLOWANCE * beta
        with np.errstate(invalid="ignore"):
            fine = (glo @ theta - yhi <= allowance) & (ylo - ghi @ theta <= allowance)
        if np.all(fine):
            self.ok[idx] = True
            return True
        return False


@dataclass
class _Hypothesis:
    route: tuple[int, ...]
    tstar: int
    dead_at: int | None = None  # t* of the data that eliminated it
    lat_steps: dict = field(default_factory=dict)  # step -> (glo(2), ghi(2), vR, psi) or None
    lat_rows: _RowStore = field(default_factory=lambda: _RowStore(2))
    lat_witness: np.ndarray | None = None
    lat_box: Box | None = None
    lat_fit_rows: int = 0
    lat_fit_start: int = -1
    lon: _Longitudinal | None = None


@dataclass
class _Longitudinal:
    steps: dict = field(default_factory=dict)  # step -> (glo(4), ghi(4)) or None (unusable)
    rows: _RowStore = field(default_factory=lambda: _RowStore(4))
    witness: np.ndarray | None = None
    box: Box | None = None
    fit_rows: int = 0
    dead: bool = False


@dataclass
class _Track:
    agent: int
    first: int
    states: dict = field(default_factory=dict)  # step -> measured (4,)
    hyps: list = field(default_factory=list)
    theta_a: Box | None = None
    theta_b: Box | None = None
    shared_lon: _Longitudinal | None = None
    hull_key: tuple = ()


class TrafficLearner:
    """Per-vehicle intention elimination and parameter boxes from noisy observations.

    Parameters
    ----------
    road : Road
        The world's road.
    scenario : HighwayScenario or TJunctionScenario
        The constants (dt, noise, priors, rules, target-speed range).
    refit_growth : float
        LP boxes are refitted when a hypothesis' rows grew by this factor.
    min_rows : tuple of 2 int
        No lateral / longitudinal LP box is fitted on fewer rows (the prior is used).
        Lateral boxes are fitted only while every surviving hypothesis has rows (in
        practice during lane changes, when the neighbours of the lane steered to are
        eliminated): a single row is then worth a fit, since the hull is otherwise the
        prior.

    Notes
    -----
    See the module docstring for the data models, the last possible switch and the
    soundness argument. `observe` must be called at every sub-step (a gap in the
    sub-steps of a vehicle restarts its windows).
    """

    def __init__(
        self,
        road: Road,
        scenario: HighwayScenario | TJunctionScenario,
        *,
        refit_growth: float = 2.0,
        min_rows: tuple = (1, 40),
    ) -> None:
        self.road = road
        self.scenario = scenario
        self.kind = "highway" if isinstance(scenario, HighwayScenario) else "tjunction"
        self.dt = float(scenario.dt)
        self.noise = np.asarray(scenario.measurement_noise, dtype=float)
        self.ego_noise = np.asarray(scenario.ego_measurement_noise, dtype=float)
        b, v, rules = scenario.behaviour, scenario.vehicle, scenario.rules
        self.behaviour, self.vehicle, self.rules = b, v, rules
        lo, hi = b.theta_a_prior
        self.speed_range = scenario.target_speeds
        self.prior_a = Box(lo, hi)
        self.prior_lon = Box(np.append(lo, lo[0] * self.speed_range[0]), np.append(hi, hi[0] * self.speed_range[1]))
        self.prior_b = Box(*b.theta_b_prior)
        self.refit_growth = float(refit_growth)
        self.min_rows_lateral, self.min_rows_longitudinal = (int(m) for m in min_rows)
        self.tracks: dict[int, _Track] = {}
        self.step = -1
        #: (step, agent, route, first sub-step of the data that eliminated it), in order
        self.eliminations: list[tuple[int, int, tuple[int, ...], int]] = []
        self.lp_solves = 0
        #: HiGHS failures (the hypothesis is kept, the last box stays): should stay 0
        self.solver_failures = 0
        self._box_cache: dict = {}
        self._junction = np.asarray(road.conflicts.any(axis=1)) if len(road) else np.zeros(0, bool)
        lanes = np.arange(len(road))
        self._straight = road.kinds[lanes] != ARC
        self._vt_rows = IntervalRows(
            np.array([[-self.speed_range[0], 0, 0, 1.0], [-self.speed_range[1], 0, 0, 1.0]]),
            np.array([[-self.speed_range[0], 0, 0, 1.0], [-self.speed_range[1], 0, 0, 1.0]]),
            np.array([0.0, -np.inf]),
            np.array([np.inf, 0.0]),
        )

    # ------------------------------------------------------------------ geometry
    def _frenet_box(self, lane, x, y, nx, ny):
        """``(s, off, s_err, off_err)`` of points with noise ``|dx| <= nx, |dy| <= ny`` on lanes."""
        road = self.road
        lane = np.asarray(lane, dtype=int)
        s, off = road.frenet(lane, x, y)
        ux, uy = road.directions[lane, 0], road.directions[lane, 1]
        s_err_straight = np.abs(ux) * nx + np.abs(uy) * ny
        off_err_straight = np.abs(uy) * nx + np.abs(ux) * ny
        nn = np.hypot(nx, ny)
        rho = np.hypot(x - road.centers[lane, 0], y - road.centers[lane, 1])
        s_err_arc = np.where(rho > nn, np.pi / 2 * road.radii[lane] * nn / np.maximum(rho, 1e-300), np.inf)
        straight = road.kinds[lane] != ARC
        pad = 1e-9 * (1 + np.abs(s) + np.abs(off))
        return (
            s,
            off,
            np.where(straight, s_err_straight, s_err_arc) + pad,
            np.where(straight, off_err_straight, nn) + pad,
        )

    def _routes_from(self, lane: int) -> list[tuple[int, ...]]:
        out = []

        def walk(path):
            nxt = self.road.successors(path[-1])
            if not nxt:
                out.append(tuple(path))
            for b in nxt:
                walk(path + [b])

        walk([lane])
        return out

    def _current_lane(self, x, y) -> int:
        """The lane the point is on: the smallest |offset| among lanes whose span holds it, then its
        predecessors while they still may hold it (so that a route from it covers every possible lane)."""
        road = self.road
        lanes = np.arange(len(road))
        s, off = road.frenet(lanes, x, y)
        inside = (s >= -1.0) & (s <= road.lengths + 1.0)
        score = np.where(inside, np.abs(off), np.inf)
        lane = int(np.argmin(score))
        for _ in range(len(road)):
            before = [
                a for a, b in road.connections if b == lane and inside[a] and abs(off[a]) <= road.widths[a] / 2 + 1.0
            ]
            if not before:
                break
            lane = int(before[0])
        return lane

    def _new_track(self, agent: int, state: np.ndarray) -> _Track:
        track = _Track(agent, self.step)
        lane = self._current_lane(state[0], state[1])
        if self.kind == "highway":
            group = self.road.side_lanes(lane) or (lane,)
            routes = [(g,) for g in group]
            shared = _Longitudinal()
            track.shared_lon = shared
            track.hyps = [_Hypothesis(r, self.step, lon=shared) for r in routes]
        else:
            track.hyps = [_Hypothesis(r, self.step, lon=_Longitudinal()) for r in self._routes_from(lane)]
        track.theta_a, track.theta_b = self.prior_a, self.prior_b
        return track

    def _all_lanes_box(self, x, y):
        """`_frenet_box` of one measured point on every lane (cached for the current sub-step)."""
        key = (float(x), float(y))
        box = self._box_cache.get(key)
        if box is None:
            lanes = np.arange(len(self.road))
            n = self.noise
            box = self._frenet_box(lanes, np.full(len(lanes), x), np.full(len(lanes), y), n[0], n[1])
            self._box_cache[key] = box
        return box

    def _route_positions(self, route, x, y, n):
        """Candidate route indices (the lane the vehicle is on) and the Frenet boxes on each route lane."""
        lanes = np.array(route)
        s, off, se, oe = (a[lanes] for a in self._all_lanes_box(x, y))
        L = self.road.lengths[lanes]
        cands = []
        for k in range(len(route)):
            advanced = k == 0 or s[k - 1] + se[k - 1] > L[k - 1]
            not_past = k == len(route) - 1 or s[k] - se[k] <= L[k]
            if advanced and not_past:
                cands.append(k)
        return cands, s, off, se, oe

    # ------------------------------------------------------------------ lateral
    def _lateral_step(self, hyp: _Hypothesis, state: np.ndarray):
        """(glo, ghi) of ``v g`` at this sub-step for this route, or None if unusable."""
        n, L, tau = self.noise, self.vehicle.length, self.behaviour.pursuit_time
        x, y, v, psi = state
        v_lo, v_hi = max(v - n[2], 0.0), min(v + n[2], self.vehicle.max_speed)
        if v_lo < LATERAL_MIN_SPEED:
            return None
        cands, s, off, se, oe = self._route_positions(hyp.route, x, y, n)
        if not cands or not np.all(np.isfinite(se[cands])):
            return None
        road = self.road
        switch = self.behaviour.route_switch_distance
        glo, ghi = np.full(2, np.inf), np.full(2, -np.inf)
        for k in cands:
            lane = hyp.route[k]
            a_lo, a_hi = s[k] - se[k] + tau * v_lo, s[k] + se[k] + tau * v_hi
            length = road.lengths[lane]
            has_next = k + 1 < len(hyp.route)
            if (
                switch > 0
                and has_next
                and s[k] + se[k] > length - switch
                and (road.kinds[lane] == ARC or road.kinds[hyp.route[k + 1]] == ARC)
            ):
                return None  # the world may steer by the next lane's frame here (an early route switch)
            pts = []
            if not has_next or a_lo <= length:
                pts += [(lane, a_lo), (lane, min(a_hi, length) if has_next else a_hi)]
            if has_next and a_hi > length:
                nxt = hyp.route[k + 1]
                pts += [(nxt, max(a_lo - length, 0.0)), (nxt, a_hi - length)]
            headings = road.heading_at(np.array([p[0] for p in pts]), np.array([p[1] for p in pts]))
            e_lo, e_hi = headings.min() - (psi + n[3]), headings.max() - (psi - n[3])
            mid = (e_lo + e_hi) / 2
            shift = 2 * np.pi * np.round(mid / (2 * np.pi))
            e_lo, e_hi = e_lo - shift, e_hi - shift
            if e_lo < -np.pi or e_hi >= np.pi:
                return None
            g2lo, g2hi = interval_product(-(off[k] + oe[k]) * L, -(off[k] - oe[k]) * L, 1 / v_hi, 1 / v_lo)
            glo = np.minimum(glo, [e_lo * L, g2lo])
            ghi = np.maximum(ghi, [e_hi * L, g2hi])
        pad = ROW_ROUNDING * (1 + np.abs(glo) + np.abs(ghi))
        return glo - pad, ghi + pad

    def _lateral_transition(self, prev: np.ndarray, cur: np.ndarray):
        """(usable, 2 v_hi R) of the transition prev -> cur (its own heading change bounds |delta|)."""
        n, L, dt = self.noise, self.vehicle.length, self.dt
        v_lo, v_hi = max(prev[2] - n[2], 0.0), min(prev[2] + n[2], self.vehicle.max_speed)
        if v_lo < LATERAL_MIN_SPEED:
            return False, 0.0
        sin_beta = (abs(cur[3] - prev[3]) + 2 * n[3]) * (L / 2) / (v_lo * dt) * (1 + 1e-9)
        if sin_beta >= 1:
            return False, 0.0
        D = np.arctan(2 * np.tan(np.arcsin(sin_beta))) * (1 + 1e-9)
        if D >= self.vehicle.max_steering:
            return False, 0.0
        return True, 2 * v_hi * float(remainder_bound(D))

    # -------------------------------------------------------------- longitudinal
    def _longitudinal_step(self, hyp: _Hypothesis | None, route, state, obs_states, obs_noise):
        """(glo(4), ghi(4)) of the acceleration regressors at this sub-step, or None if unusable."""
        n, b, veh, rules = self.noise, self.behaviour, self.vehicle, self.rules
        road = self.road
        x, y, v, psi = state
        v_lo, v_hi = max(v - n[2], 0.0), min(v + n[2], veh.max_speed)
        L = veh.length
        if self.kind == "highway":
            cands = [0]
            group = np.array(road.side_lanes(route[0]) or route)
            s_i, _, se_i, _ = (float(a[group[0]]) for a in self._all_lanes_box(x, y))
            # every agent ahead in any lane of the group may be the leader (side lanes have aligned s)
            s_o, off_o, se_o, oe_o = self._frenet_box(
                np.full(len(obs_states), group[0]), obs_states[:, 0], obs_states[:, 1], obs_noise[:, 0], obs_noise[:, 1]
            )
            dist_lo, dist_hi = s_o - se_o - (s_i + se_i), s_o + se_o - (s_i - se_i)
            width = road.widths[group[0]]
            lane_off = (
                off_o[:, None] - (np.arange(len(group)) * width)[None, :]
            )  # offsets from each group lane (parallel)
            _, off_i = road.frenet(group, x, y)
            sure_i = np.abs(off_i) + n[1] <= road.widths[group] / 2
            sure_j = np.abs(lane_off) + oe_o[:, None] <= width / 2
            sure = np.any(sure_j & sure_i[None, :], axis=1) & (dist_lo > 0)
            possible = dist_hi > 0
            heading = float(road.heading_at(group[0], 0.0))
            head_err = None
            cap = np.inf
            may_yield = False
            stop_gap = None
        else:
            cands, s, off, se, oe = self._route_positions(route, x, y, n)
            if len(cands) != 1:
                return None  # ambiguous current lane near a lane end: not used
            k = cands[0]
            lanes = np.array(route)
            lane = route[k]
            # curve cap: the current lane's curvature, or the next lane's within curve_approach
            to_end_lo = road.lengths[lane] - (s[k] + se[k]) - L / 2
            to_end_hi = road.lengths[lane] - (s[k] - se[k]) - L / 2
            has_next = k + 1 < len(route)
            kappa_here = abs(float(road.curvature_at(lane, 0.0)))
            kappa_next = abs(float(road.curvature_at(route[k + 1], 0.0))) if has_next else 0.0
            near_lo, near_hi = (
                has_next and to_end_hi <= rules.curve_approach,
                has_next and to_end_lo <= rules.curve_approach,
            )
            if near_lo != near_hi and kappa_next > kappa_here:
                return None  # the cap may or may not apply
            kappa = max(kappa_here, kappa_next if near_hi else 0.0)
            cap = np.sqrt(rules.curve_lateral_acceleration / kappa) if kappa > 0 else np.inf
            # path distances to every other agent along the remaining route lanes it may occupy
            cum = np.concatenate([[0.0], np.cumsum(road.lengths[lanes])])
            path_lo, path_hi = cum[k] + s[k] - se[k], cum[k] + s[k] + se[k]
            m = len(obs_states)
            rl = lanes[k:]
            S, OF, SE, OE = self._frenet_box(
                rl[None, :].repeat(m, 0), obs_states[:, 0:1], obs_states[:, 1:2], obs_noise[:, 0:1], obs_noise[:, 1:2]
            )
            lengths, widths = road.lengths[rl][None, :], road.widths[rl][None, :]
            corners = _corners(obs_states, veh)  # (m, 4, 2)
            cs, co = road.frenet(rl[None, None, :], corners[:, :, 0:1], corners[:, :, 1:2])  # (m, 4, R)
            cpad = 0.2 + np.hypot(obs_noise[:, 0], obs_noise[:, 1])[:, None, None]
            corner_in = np.any(
                (cs >= -cpad) & (cs <= lengths[:, None, :] + cpad) & (np.abs(co) <= widths[:, None, :] / 2 + cpad),
                axis=1,
            )
            reach = OCCUPANCY_REACH + OE
            centre_in = (S + SE >= -reach) & (S - SE <= lengths + reach) & (np.abs(OF) - OE <= widths / 2 + reach)
            possible_occ = corner_in | centre_in
            sure_occ = (S - SE >= 0) & (S + SE <= lengths) & (np.abs(OF) + OE <= widths / 2)
            d_lo = cum[k:-1][None, :] + S - SE - path_hi
            d_hi = cum[k:-1][None, :] + S + SE - path_lo
            dl = np.where(possible_occ & (d_hi > 0), d_lo, np.inf)
            dist_lo = dl.min(axis=1)
            sure_d = np.where(sure_occ & (d_lo > 0), d_hi, np.inf)
            sure = np.isfinite(sure_d.min(axis=1))
            possible = np.isfinite(dist_lo)
            # the lane a leader is measured on: hull of the heading error over its possible lanes
            heads = road.heading_at(rl[None, :], S)
            err = obs_states[:, 3:4] - heads
            err = err - 2 * np.pi * np.round(err / (2 * np.pi))
            err = np.where(possible_occ, np.abs(err), 0.0)
            head_err = (
                err.max(axis=1)
                + obs_noise[:, 3]
                + np.max(
                    np.where(possible_occ & (road.kinds[rl] == ARC)[None, :], SE / road.radii[rl][None, :], 0.0),
                    axis=1,
                    initial=0.0,
                )
            )
            # the true distance is the least over the lanes it occupies: at most the largest possible one
            dist_hi = np.max(np.where(possible_occ & (d_hi > 0), d_hi, -np.inf), axis=1)
            sure_bound = sure_d.min(axis=1)
            nxt_lane = route[k + 1] if has_next else -1
            may_yield = has_next and bool(self._junction[nxt_lane]) and not bool(self._junction[lane])
            stop_gap = (max(to_end_lo, 0.0), max(to_end_hi, 0.0))
            heading = None
            sure = sure_bound
        # sure leader distance bound and the possible leaders
        if self.kind == "highway":
            d_up = np.min(np.where(sure, dist_hi, np.inf), initial=np.inf)
            vf_lo, vf_hi = obs_states[:, 2] - obs_noise[:, 2], obs_states[:, 2] + obs_noise[:, 2]
            clo, chi = cos_interval(
                obs_states[:, 3] - heading - obs_noise[:, 3], obs_states[:, 3] - heading + obs_noise[:, 3]
            )
        else:
            assert head_err is not None  # set off the highway
            d_up = float(np.min(sure, initial=np.inf))
            vf_lo, vf_hi = obs_states[:, 2] - obs_noise[:, 2], obs_states[:, 2] + obs_noise[:, 2]
            clo, chi = cos_interval(-head_err, head_err)
        vf_lo, vf_hi = np.maximum(vf_lo, 0.0), vf_hi
        pf_lo, pf_hi = interval_product(vf_lo, vf_hi, clo, chi)
        cand = possible & (dist_lo <= d_up)
        d0, T = b.standstill_distance, b.time_headway
        f2lo, f2hi, f3lo, f3hi = [], [], [], []
        for j in np.flatnonzero(cand):
            f2lo.append(min(pf_lo[j] - v_hi, 0.0))
            f2hi.append(min(pf_hi[j] - v_lo, 0.0))
            f3lo.append(min(dist_lo[j] - L - d0 - T * v_hi, 0.0))
            f3hi.append(min(dist_hi[j] - L - d0 - T * v_lo, 0.0))
        if not np.isfinite(d_up):
            f2lo.append(0.0)
            f2hi.append(0.0)
            f3lo.append(0.0)
            f3hi.append(0.0)
        if may_yield:
            assert stop_gap is not None  # may_yield is only set off the highway, with stop_gap
            f2lo.append(-v_hi)
            f2hi.append(-v_lo)
            f3lo.append(min(stop_gap[0] - d0 - T * v_hi, 0.0))
            f3hi.append(min(stop_gap[1] - d0 - T * v_lo, 0.0))
        vt_lo, vt_hi = self.speed_range
        if cap <= vt_lo:
            g1lo, g1hi, K = cap - v_hi, cap - v_lo, 0.0
        elif cap >= vt_hi:
            g1lo, g1hi, K = -v_hi, -v_lo, 1.0
        else:
            return None
        glo = np.array([g1lo, min(f2lo), min(f3lo), K])
        ghi = np.array([g1hi, max(f2hi), max(f3hi), K])
        if not (np.all(np.isfinite(glo)) and np.all(np.isfinite(ghi))):
            return None
        pad = ROW_ROUNDING * (1 + np.abs(glo) + np.abs(ghi))
        pad[3] = 0.0
        return glo - pad, ghi + pad

    # ------------------------------------------------------------------ feeding
    def observe(self, observation: Observation) -> None:
        """Record one sub-step's observation and update every vehicle's rows and verdicts.

        Parameters
        ----------
        observation : Observation
            The noisy states of every vehicle on the road (and the ego) at this sub-step.

        Raises
        ------
        InputError
            If the observation's sub-step is not after the last one observed (each
            sub-step is learned from once, in order; a second measurement of a sub-step
            would silently replace the state its rows were built on).
        """
        step = int(round(observation.time / self.dt))
        if step <= self.step:
            raise InputError(
                f"observation.time = {observation.time!r} is sub-step {step}, not after the last observed "
                f"sub-step {self.step}: observe each sub-step once, in order"
            )
        self.step = step
        self._box_cache = {}
        ids = np.asarray(observation.ids, dtype=int)
        vehicles = np.asarray(observation.vehicles, dtype=float).reshape(-1, 4)
        ego = np.asarray(observation.ego, dtype=float)
        all_states = np.vstack([vehicles, ego[None, :]]) if np.any(ego) else vehicles
        all_noise = np.vstack(
            [np.tile(self.noise, (len(vehicles), 1))] + ([self.ego_noise[None, :]] if np.any(ego) else [])
        )
        seen = set()
        for row, agent in enumerate(ids):
            agent = int(agent)
            seen.add(agent)
            state = vehicles[row]
            track = self.tracks.get(agent)
            if track is None or (step - 1) not in track.states:
                if track is not None:  # a gap: restart the windows
                    for h in track.hyps:
                        h.tstar = step
                else:
                    track = self._new_track(agent, state)
                    self.tracks[agent] = track
            others = np.delete(all_states, row, axis=0)
            others_noise = np.delete(all_noise, row, axis=0)
            self._update(track, step, state, others, others_noise)
        for agent in list(self.tracks):
            if agent not in seen and self.tracks[agent].states and max(self.tracks[agent].states) < step - 1:
                pass  # kept for the statistics; no more data

    def _update(self, track: _Track, step: int, state, others, others_noise) -> None:
        prev = track.states.get(step - 1)
        track.states[step] = state.copy()
        # last possible switch (highway): measured settled in a neighbour of the hypothesis' lane
        if self.kind == "highway":
            lanes = np.array([h.route[0] for h in track.hyps])
            _, off, _, oe = (a[lanes] for a in self._all_lanes_box(state[0], state[1]))
            settled = np.abs(off) - oe < self.rules.lane_change_settled
            for h in track.hyps:
                nb = [j for j, g in enumerate(lanes) if self._adjacent(g, h.route[0])]
                if any(settled[j] for j in nb):
                    h.tstar = step
        # per-step regressors at this sub-step (for the transition step -> step + 1)
        lon_done = set()
        for h in track.hyps:
            h.lat_steps[step] = self._lateral_step(h, state)
            if id(h.lon) not in lon_done:
                lon_done.add(id(h.lon))
                h.lon.steps[step] = self._longitudinal_step(h, h.route, state, others, others_noise)
        if prev is None:
            return
        j = step - 1  # the completed transition j -> step
        ok_lat, vR = self._lateral_transition(prev, state)
        lon_lin, lon_single = self._longitudinal_transition(prev, state)
        lon_done = set()
        for h in track.hyps:
            data = h.lat_steps.get(j)
            h.lat_steps[j] = None if (data is None or not ok_lat) else (data[0], data[1], vR, prev[3])
            self._lateral_rows(h, track, step)
            if id(h.lon) not in lon_done:
                lon_done.add(id(h.lon))
                self._lon_rows(h.lon, track, step, lon_lin, lon_single)
        self._verdicts(track, step)
        # forget per-step data older than the longest window
        old = step - max(WINDOWS) - 2
        for h in track.hyps:
            h.lat_steps.pop(old, None)
            h.lon.steps.pop(old, None)
        track.states.pop(old, None)

    def _adjacent(self, a, b) -> bool:
        group = self.road.side_lanes(int(a))
        return int(b) in group and abs(group.index(int(a)) - group.index(int(b))) == 1

    def _longitudinal_transition(self, prev, cur):
        """(surely linear?, single-step one-sided target (lo, hi) of theta . f) for prev -> cur."""
        n, dt, veh, b = self.noise, self.dt, self.vehicle, self.behaviour
        v1lo, v1hi = max(cur[2] - n[2], 0.0), min(cur[2] + n[2], veh.max_speed)
        v0lo, v0hi = max(prev[2] - n[2], 0.0), min(prev[2] + n[2], veh.max_speed)
        a_lo = (v1lo - v0hi) / dt if v1lo > 0 else -np.inf
        a_hi = (v1hi - v0lo) / dt if v1hi < veh.max_speed else np.inf
        amax, wbar = b.acceleration_bound, b.disturbance_bound
        lo = a_lo - wbar if a_lo - wbar > -amax else -np.inf
        hi = a_hi + wbar if a_hi + wbar < amax else np.inf
        linear = np.isfinite(lo) and np.isfinite(hi)
        pad = ROW_ROUNDING * (1 + abs(prev[2]) + abs(cur[2])) / dt
        return linear, (lo - pad, hi + pad)

    def _lateral_rows(self, h: _Hypothesis, track: _Track, step: int) -> None:
        L, dt, n = self.vehicle.length, self.dt, self.noise
        for k in WINDOWS:
            if step % max(1, k // 4):
                continue
            start = step - k
            if start < h.tstar:
                continue
            found = [h.lat_steps.get(t) for t in range(start, step)]
            items = [it for it in found if it is not None]
            if len(items) < len(found):
                continue
            glo = np.sum([it[0] for it in items], axis=0)
            ghi = np.sum([it[1] for it in items], axis=0)
            rem = sum(it[2] for it in items)
            dpsi = track.states[step][3] - track.states[start][3]
            y_lo = (L / dt) * (dpsi - 2 * n[3]) - rem
            y_hi = (L / dt) * (dpsi + 2 * n[3]) + rem
            pad = ROW_ROUNDING * k * (1 + np.abs(glo) + np.abs(ghi))
            ypad = ROW_ROUNDING * k * (1 + abs(y_lo) + abs(y_hi))
            h.lat_rows.append(start, glo - pad, ghi + pad, y_lo - ypad, y_hi + ypad)

    def _lon_rows(self, lon: _Longitudinal, track: _Track, step: int, linear: bool, single) -> None:
        j = step - 1
        data = lon.steps.get(j)
        if data is None:
            lon.steps[j] = None
            return
        lon.steps[j] = (data[0], data[1], linear)
        n, dt, wbar = self.noise, self.dt, self.behaviour.disturbance_bound
        if not linear:
            lon.rows.append(j, data[0], data[1], single[0], single[1])
            return
        for k in WINDOWS:
            if step % max(1, k // 4):
                continue
            start = step - k
            found = [lon.steps.get(t) for t in range(start, step)]
            items = [it for it in found if it is not None and it[2]]
            if len(items) < len(found):
                continue
            glo = np.sum([it[0] for it in items], axis=0)
            ghi = np.sum([it[1] for it in items], axis=0)
            dv = track.states[step][2] - track.states[start][2]
            y_lo = (dv - 2 * n[2]) / dt - k * wbar
            y_hi = (dv + 2 * n[2]) / dt + k * wbar
            pad = ROW_ROUNDING * k * (1 + np.abs(glo) + np.abs(ghi))
            pad[3] = 0.0
            ypad = ROW_ROUNDING * k * (1 + abs(y_lo) + abs(y_hi))
            lon.rows.append(start, glo - pad, ghi + pad, y_lo - ypad, y_hi + ypad)

    # ------------------------------------------------------------------ verdicts
    def _lat_rows_of(self, h: _Hypothesis) -> IntervalRows:
        h.lat_rows.drop_before(h.tstar)
        return h.lat_rows.rows()

    def _lon_rows_of(self, lon: _Longitudinal) -> IntervalRows:
        return lon.rows.rows(self._vt_rows)

    def _alive(self, h: _Hypothesis) -> bool:
        if h.dead_at is not None and h.tstar > h.dead_at:
            h.dead_at = None  # a new possible switch into it: revived on fresh data
            h.lat_witness, h.lat_box, h.lat_fit_rows = None, None, 0
        assert h.lon is not None  # every hypothesis is made with one (_new_track)
        return h.dead_at is None and not h.lon.dead

    def _check(self, store: _RowStore, prior: Box, witness, extra: IntervalRows | None = None):
        """(eliminated?, witness): the witness is checked on the rows it has not explained yet (a
        subset of explained rows stays explained); the LP is re-solved on every row only if it fails."""
        if store.n == 0:
            return False, witness
        if witness is not None and store.explained(witness, np.maximum(np.abs(prior.low), np.abs(prior.high))):
            return False, witness
        self.lp_solves += 1
        try:
            verdict = interval_consistency(store.rows(extra), prior)
        except SolverFailure:
            self.solver_failures += 1
            return False, None  # undecided: kept (sound)
        good = verdict.upper <= 0.0
        store.ok[: store.n] = good
        return verdict.eliminated, (verdict.witness if good else None)

    def _box(self, rows: IntervalRows, prior: Box, old: Box | None, coordinates=None) -> Box | None:
        """The LP box, or ``old`` if HiGHS fails (a solver failure is counted, never hidden)."""
        try:
            return interval_parameter_box(rows, prior, coordinates=coordinates)
        except (SolverFailure, NoConsistentModel):
            # NoConsistentModel here would contradict the witness just checked: counted as a failure
            self.solver_failures += 1
            return old

    def _verdicts(self, track: _Track, step: int) -> None:
        alive_before = [h for h in track.hyps if self._alive(h)]
        for h in alive_before:
            h.lat_rows.drop_before(h.tstar)
            dead, h.lat_witness = self._check(h.lat_rows, self.prior_b, h.lat_witness)
            if dead:
                h.dead_at = h.tstar
                self.eliminations.append((step, track.agent, h.route, h.tstar))
                continue
            if h.lat_fit_start != h.tstar:
                h.lat_box, h.lat_fit_rows, h.lat_fit_start = None, 0, h.tstar
        # the hull over the survivors is informative only if every survivor has rows enough
        alive = [h for h in alive_before if h.dead_at is None]
        if alive and all(h.lat_rows.n >= self.min_rows_lateral for h in alive):
            for h in alive:
                if h.lat_rows.n >= self.refit_growth * h.lat_fit_rows:
                    self.lp_solves += 5
                    h.lat_box = self._box(h.lat_rows.rows(), self.prior_b, h.lat_box)
                    h.lat_fit_rows = h.lat_rows.n
        for lon in {id(h.lon): h.lon for h in alive_before}.values():
            if lon.dead:
                continue
            dead, lon.witness = self._check(lon.rows, self.prior_lon, lon.witness, self._vt_rows)
            if dead:
                lon.dead = True
                for h in track.hyps:
                    if h.lon is lon:
                        self.eliminations.append((step, track.agent, h.route, track.first))
                continue
            if lon.rows.n >= max(self.min_rows_longitudinal, self.refit_growth * lon.fit_rows):
                self.lp_solves += 7
                box = self._box(self._lon_rows_of(lon), self.prior_lon, None, coordinates=(0, 1, 2))
                if box is not None:
                    lon.box = Box(box.low[:3], box.high[:3])
                lon.fit_rows = lon.rows.n
        alive = [h for h in track.hyps if self._alive(h)]
        if not alive:
            return  # only if the world broke a stated assumption: the last beliefs are kept
        boxes_b = [h.lat_box or self.prior_b for h in alive]
        boxes_a = [h.lon.box or self.prior_a for h in alive]
        key = tuple(id(b) for b in boxes_b + boxes_a)
        if key != track.hull_key:  # the hulls change only when a box or the survivors do
            track.hull_key = key
            assert track.theta_a is not None and track.theta_b is not None  # set by _new_track
            track.theta_b = _intersect(track.theta_b, _hull(boxes_b))
            track.theta_a = _intersect(track.theta_a, _hull(boxes_a))

    # ------------------------------------------------------------------ outputs
    def survivors(self, agent: int) -> list[tuple[int, ...]]:
        """The routes of a vehicle not eliminated now (its intentions that may be in force).

        Parameters
        ----------
        agent : int
            Agent index.
        """
        return [h.route for h in self.tracks[agent].hyps if self._alive(h)]

    def _in_force_before_now(self, h: _Hypothesis, track: _Track) -> bool:
        """Whether ``h`` may have been in force on the last transition ``step - 1 -> step``.

        A hypothesis whose last possible switch is the current sub-step has no data of
        its own: it may be chosen *now* (a lane change decided at this sub-step, which
        `forecast_traffic` covers as a switch at its step 0, under the gap rule), or it
        was chosen earlier and was in force on the last transition. The second case is
        refuted by that one transition's row (the rows of a window of length 1, built as
        `_lateral_rows` builds them) when `interval_consistency` proves it inconsistent
        with every theta_b of the prior (one row: its margin LP in closed form, the
        certificate re-checked as for HiGHS's); the hypothesis then stays alive (it may
        start now) but is not an intention in force.
        """
        step = self.step
        if h.tstar < step:
            return True
        prev = step - 1
        item = h.lat_steps.get(prev)
        if item is None or prev not in track.states or step not in track.states:
            return True
        L, dt, n = self.vehicle.length, self.dt, self.noise
        glo, ghi, rem = item[0], item[1], item[2]
        dpsi = track.states[step][3] - track.states[prev][3]
        y_lo = (L / dt) * (dpsi - 2 * n[3]) - rem
        y_hi = (L / dt) * (dpsi + 2 * n[3]) + rem
        pad = ROW_ROUNDING * (1 + np.abs(glo) + np.abs(ghi))
        ypad = ROW_ROUNDING * (1 + abs(y_lo) + abs(y_hi))
        rows = IntervalRows((glo - pad)[None], (ghi + pad)[None], np.array([y_lo - ypad]), np.array([y_hi + ypad]))
        self.lp_solves += 1
        try:
            verdict = interval_consistency(rows, self.prior_b)
        except SolverFailure:
            self.solver_failures += 1
            return True
        return not verdict.eliminated

    def current_lanes(self, agent: int) -> tuple[int, ...]:
        """The lanes a vehicle may be steering to now (current lanes of its surviving routes).

        On the highway a side lane that can only be chosen now (see
        `_in_force_before_now`) is left out: the forecast's switching covers it. The
        vehicle's own lane always stays.

        Parameters
        ----------
        agent : int
            A tracked vehicle's id (as in `Observation.ids`).
        """
        track = self.tracks[agent]
        state = track.states[max(track.states)]
        lanes = set()
        for h in track.hyps:
            if not self._alive(h):
                continue
            if self.kind == "highway" and len(h.route) == 1 and not self._in_force_before_now(h, track):
                if h.route[0] != self._current_lane(state[0], state[1]):
                    continue
            cands, *_ = self._route_positions(h.route, state[0], state[1], self.noise)
            for k in cands or [0]:
                lanes.add(h.route[k])
        return tuple(sorted(lanes))

    def beliefs(self, agents=None) -> dict[int, VehicleBelief]:
        """``agent -> VehicleBelief`` for every tracked vehicle seen at the last sub-step (or ``agents``).

        Parameters
        ----------
        agents : iterable of int, optional
            Which vehicles (default: those observed at the last sub-step).
        """
        if agents is None:
            agents = [a for a, t in self.tracks.items() if self.step in t.states]
        out = {}
        for a in agents:
            t = self.tracks[int(a)]
            assert t.theta_a is not None and t.theta_b is not None  # set by _new_track
            out[int(a)] = VehicleBelief(
                int(a),
                t.theta_a,
                t.theta_b,
                self.current_lanes(int(a)),
                tuple(self.survivors(int(a))) or tuple(h.route for h in t.hyps),
            )
        return out

    def nominal(self, agents=None) -> dict[int, NominalEstimate]:
        """``agent -> NominalEstimate``: least-squares parameters and the minimum-error route.

        Parameters
        ----------
        agents : iterable of int, optional
            Which vehicles (default: those observed at the last sub-step).

        Notes
        -----
        Least squares on the rows' midpoints (each row divided by its target's
        half-width), clipped to the prior; the route with the smallest mean squared
        normalised residual of its lateral rows is the minimum-error one (ties: the
        first; a route without rows counts as residual 0 only if every route has none).
        """
        if agents is None:
            agents = [a for a, t in self.tracks.items() if self.step in t.states]
        out = {}
        for a in agents:
            t = self.tracks[int(a)]
            best, best_err, best_b = t.hyps[0], np.inf, (self.prior_b.low + self.prior_b.high) / 2
            for h in t.hyps:
                rows = self._lat_rows_of(h)
                theta, err = _least_squares(rows, self.prior_b)
                if err < best_err:
                    best, best_err, best_b = h, err, theta
            theta_a, _ = _least_squares(self._lon_rows_of(best.lon), self.prior_lon, skip=2)
            state = t.states[max(t.states)]
            cands, *_ = self._route_positions(best.route, state[0], state[1], self.noise)
            out[int(a)] = NominalEstimate(int(a), theta_a[:3], best_b, best.route, best.route[(cands or [0])[0]])
        return out


def _least_squares(rows: IntervalRows, prior: Box, skip: int = 0):
    if rows.nrows <= skip:
        return (prior.low + prior.high) / 2, np.inf
    g = (rows.regressor_low[skip:] + rows.regressor_high[skip:]) / 2
    ylo, yhi = rows.target_low[skip:], rows.target_high[skip:]
    both = np.isfinite(ylo) & np.isfinite(yhi)
    if not np.any(both):
        return (prior.low + prior.high) / 2, np.inf
    g, y = g[both], (ylo[both] + yhi[both]) / 2
    w = 1.0 / np.maximum((yhi[both] - ylo[both]) / 2, 1e-12)
    theta, *_ = np.linalg.lstsq(g * w[:, None], y * w, rcond=None)
    theta = np.clip(theta, prior.low, prior.high)
    err = float(np.mean(((g @ theta - y) * w) ** 2))
    return theta, err


def _corners(states: np.ndarray, vehicle) -> np.ndarray:
    c, s = np.cos(states[:, 3]), np.sin(states[:, 3])
    f = np.stack([c, s], axis=-1) * (vehicle.length / 2)
    left = np.stack([-s, c], axis=-1) * (vehicle.width / 2)
    p = states[:, None, :2]
    return np.concatenate(
        [p + (f + left)[:, None], p + (f - left)[:, None], p + (-f - left)[:, None], p + (-f + left)[:, None]], axis=1
    )


def _hull(boxes: list[Box]) -> Box:
    return Box(np.min([b.low for b in boxes], axis=0), np.max([b.high for b in boxes], axis=0))


def _intersect(a: Box, b: Box) -> Box:
    low, high = np.maximum(a.low, b.low), np.minimum(a.high, b.high)
    if np.any(low > high):  # cannot happen when both are sound; keep the newer one
        return b
    return Box(low, high)


def elimination_statistics(events) -> dict[str, dict]:
    """Median [min, max] of the transitions until a wrong intention is eliminated, per kind.

    Parameters
    ----------
    events : iterable of (kind, transitions or None)
        One entry per (vehicle, wrong intention) episode: its kind (e.g. "keep lane
        during a change", "wrong route") and the number of transitions observed from
        the moment it was wrong until its elimination (None: never eliminated while
        observed).

    Returns
    -------
    dict
        kind -> {"count", "eliminated", "median", "min", "max"} (None when nothing was
        eliminated).
    """
    out: dict[str, list] = {}
    for kind, n in events:
        out.setdefault(kind, []).append(n)
    result = {}
    for kind, values in sorted(out.items()):
        done = [v for v in values if v is not None]
        result[kind] = {
            "count": len(values),
            "eliminated": len(done),
            "median": float(np.median(done)) if done else None,
            "min": int(min(done)) if done else None,
            "max": int(max(done)) if done else None,
        }
    return result


def hold_lane_control(world) -> np.ndarray:
    """A simple admissible ego control: highway, keep the lane at 25 m/s; T-junction, stop and wait on the stem.

    Parameters
    ----------
    world : RoadWorld
        The episode (its true ego state is read: the ego knows its own state).

    Returns
    -------
    numpy.ndarray
        ``(acceleration, steering)`` inside the world's control bounds.
    """
    x, y, v, psi = world.ego_state
    if world.kind == "highway":
        width = world.scenario.geometry.lane_width
        lane_y = round(y / width) * width
        return np.array([np.clip(2.0 * (25.0 - v), -5.0, 5.0), np.clip(0.1 * (lane_y - y) - psi, -0.5, 0.5)])
    return np.array([np.clip(-3.0 * v, -5.0, 5.0), 0.0])


def _kind_of(world, route, agent: int, first: int) -> tuple[str, int]:
    """The kind of a wrong intention just eliminated, and the sub-step since which it was wrong and observed."""
    road = world.road
    if world.kind == "tjunction":
        true_route = [int(r) for r in world.traffic.routes[agent] if r >= 0]
        if any(road.kinds[lane] == ARC for lane in true_route):
            turn = any(road.kinds[lane] == ARC for lane in route)
            return ("route: other turn (vehicle turns)" if turn else "route: straight (vehicle turns)"), first
        return "route: turn (vehicle goes straight)", first
    records = world.records
    lane = route[0]
    for i in range(len(records) - 1, max(len(records) - 200, 0), -1):
        if records[i].lane_change[agent]:
            if i >= 1 and records[i - 1].intention[agent] == lane:
                return "lane being left (mid lane change)", max(i, first)
            break
    now = int(world.traffic.lane[agent])
    group = road.side_lanes(now)
    if abs(group.index(lane) - group.index(now)) >= 2:
        return "lane two away", first
    return "neighbour lane (vehicle keeps its lane)", first


def elimination_events(world, learner: TrafficLearner, start: int = 0) -> list[tuple[str, int]]:
    """The (kind, transitions until eliminated) of every elimination logged since index ``start``.

    Parameters
    ----------
    world : RoadWorld
        The episode, at the sub-step of the last `TrafficLearner.observe` (ground truth).
    learner : TrafficLearner
        Its learner.
    start : int
        First index of ``learner.eliminations`` to read.

    Returns
    -------
    list of (str, int)
        Kind of the wrong intention and the transitions observed from the moment it was
        wrong (the start of the lane change for the lane being left; otherwise the first
        sub-step of the data that eliminated it) to its elimination.
    """
    out = []
    for step, agent, route, first in learner.eliminations[start:]:
        kind, since = _kind_of(world, route, agent, first)
        out.append((kind, step - since))
    return out


def censored_events(world, learner: TrafficLearner) -> list[tuple[str, None]]:
    """``(kind, None)`` for every wrong intention still alive at each vehicle's last observation.

    Parameters
    ----------
    world : RoadWorld
        The episode at its end (ground truth).
    learner : TrafficLearner
        Its learner.

    Returns
    -------
    list of (str, None)
        Wrong intentions never eliminated while observed (their kind as in
        `elimination_events`); on the highway these include the side neighbours of a
        settled vehicle's lane, which cannot be eliminated by design (a lane change may
        start at any sub-step).
    """
    out = []
    for agent, track in learner.tracks.items():
        true_lane = int(world.traffic.lane[agent])
        true_route = tuple(int(r) for r in world.traffic.routes[agent] if r >= 0)
        for h in track.hyps:
            if not learner._alive(h):
                continue
            wrong = true_lane not in h.route if world.kind == "highway" else true_route[-len(h.route) :] != h.route
            if not wrong:
                continue
            if world.kind == "highway":  # alive now: a side neighbour of the lane it keeps, or two away
                group = world.road.side_lanes(true_lane)
                far = abs(group.index(h.route[0]) - group.index(true_lane)) >= 2
                out.append(("lane two away" if far else "neighbour lane (vehicle keeps its lane)", None))
            else:
                out.append((_kind_of(world, h.route, agent, track.first)[0], None))
    return out


def elimination_study(kind: str, seeds, *, max_steps: int | None = None) -> dict:
    """Run episodes with `hold_lane_control` and a `TrafficLearner`; check it against the truth.

    Parameters
    ----------
    kind : str
        "highway" or "tjunction".
    seeds : iterable of int
        Episode seeds.
    max_steps : int, optional
        Stop each episode after this many sub-steps.

    Returns
    -------
    dict
        ``statistics`` (`elimination_statistics` of every elimination), ``vehicle_steps``
        checked, ``intention_misses`` (the true intention in force not among the
        survivors), ``theta_a_misses`` and ``theta_b_misses`` (the true parameters
        outside the belief's boxes), ``learn_seconds``, ``substeps``, ``lp_solves`` and
        ``solver_failures``; a miss would be a bug.
    """
    import time

    from minimaxplan.scenarios.road_world import make_road_world

    events: list = []
    out: dict = {
        "vehicle_steps": 0,
        "intention_misses": 0,
        "theta_a_misses": 0,
        "theta_b_misses": 0,
        "learn_seconds": 0.0,
        "substeps": 0,
        "lp_solves": 0,
        "solver_failures": 0,
    }
    for seed in seeds:
        world = make_road_world(kind, int(seed))
        learner = TrafficLearner(world.road, world.scenario)
        learner.observe(world.measure())
        while not world.done and (max_steps is None or world.step_index < max_steps):
            world.apply(hold_lane_control(world))
            observation = world.measure()
            start = len(learner.eliminations)
            t0 = time.perf_counter()
            learner.observe(observation)
            out["learn_seconds"] += time.perf_counter() - t0
            out["substeps"] += 1
            events += elimination_events(world, learner, start)
            for agent, belief in learner.beliefs().items():
                out["vehicle_steps"] += 1
                out["intention_misses"] += int(world.traffic.lane[agent]) not in belief.lanes
                out["theta_a_misses"] += not belief.theta_a.contains(world.traffic.theta_a[agent])
                out["theta_b_misses"] += not belief.theta_b.contains(world.traffic.theta_b[agent])
        events += censored_events(world, learner)
        out["lp_solves"] += learner.lp_solves
        out["solver_failures"] += learner.solver_failures
    out["statistics"] = elimination_statistics(events)
    return out
