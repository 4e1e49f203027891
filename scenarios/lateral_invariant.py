"""Robust invariant sets of the lateral closed loop on a straight lane, at every speed up to a bound.

One concept: the parallelograms ::

    S(E) = {(e, chi) : |e| <= E,  |chi - k e| <= m k E},      k = 2 / L,  m = HEADING_RATIO,

of the LinearVehicle's lateral state (offset from the lane it steers to, heading error)
are mapped into themselves by the exact step of its steering law and the kinematic
bicycle, whatever the speed in ``[0, v_bar]`` at each step and whatever the steering
gains in their box (`check_invariance` proves it, for one ``(E, v_bar)``, by interval
branch and bound). `forecast_traffic` uses them where the quadratic contraction of
`minimaxplan.scenarios.lateral_contraction` has none: a speed box reaching down to
walking pace (a vehicle that may stop at a stop line), where the law's gain ``L theta_b2
/ v^2`` saturates the steering and the true vehicle chatters about its lane's centre;
a box that holds only states of ``S(E)`` then stays inside ``S(E)``'s hull.

The step (`minimaxplan.scenarios.vehicles.bicycle_step` under the law, on a straight
lane, ``D = v dt``, ``v_e = max(v, speed_epsilon)``) is, exactly::

    delta = clip(-(L / v_e)(theta_b1 chi + theta_b2 e / v_e), -delta_max, delta_max)
    beta  = arctan(tan(delta) / 2)
    e+    = e   + D sin(chi + beta)
    chi+  = chi + (2 D / L) sin(beta)

Two faces make the set, and each is checked over the whole set (a step may jump from
inside it past a face):

* the **offset faces** ``|e+| <= E``: the law must turn a vehicle near ``e = E`` back
  before it moves out (this is what fails for small sets at high speed: one step of
  ``D sin(chi + beta)`` crosses them);
* the **heading faces** ``|z+| <= M`` with ``z = chi - k e`` (``-k`` times the rear
  axle's offset, to first order): ``z+ - z = (2 D / L)(sin(beta) - sin(chi + beta)) =
  -(4 D / L) cos(beta + chi / 2) sin(chi / 2)``, of the sign of ``-chi`` whatever the
  steering while ``|beta + chi / 2| < pi / 2``; on the face ``z = M`` the heading error is
  ``chi = M + k e >= (m - 1) k E > 0``, so ``z`` decreases there, and inside the set a
  step adds at most ``(2 D / L)|chi|``, which ``D <= L / 2`` keeps below the slack.

By the odd symmetry of the step (``(e, chi) -> (-e, -chi)`` maps the law and the
bicycle to themselves) the lower faces follow from the upper ones. `check_invariance`
bounds both upper faces over boxes of ``(e / E, z / M, v, theta_b1, theta_b2)``,
splitting the widest coordinate of every box it cannot decide, until every box is
proven (``"proven"``), a box's centre is a point that leaves the set (``"refuted"``, the
point returned), or the box budget is spent (``"inconclusive"``).

Floating point: the world steps in doubles, off the exact map by about one unit in the
last place of its coordinates per step. The proof covers every ``E'`` of ``[E, E (1 +
FAMILY_WIDTH)]`` at once (``S(E')`` with the same ``m``), so a world state that starts
in ``S(E)`` and drifts by at most ``eps`` per step stays in ``S(E + n eps)`` for ``n``
steps, inside ``S(E (1 + FAMILY_WIDTH))`` for any horizon shorter than ``1e7`` steps;
the forecast intersects with that set's hull.

Layer: numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.models.prediction import cos_interval, interval_product, sin_interval
from minimaxplan.models.validation import as_count, frozen_copy

from .vehicles import (
    DEFAULT_VEHICLE,
    BehaviourParameters,
    VehicleParameters,
    bicycle_step,
    linear_steering,
    slip_angle,
    steering_features,
)

__all__ = [
    "HEADING_RATIO",
    "FAMILY_WIDTH",
    "TABLE_OFFSETS",
    "TABLE_SPEEDS",
    "TABLE_BUDGET",
    "InvarianceCertificate",
    "InvariantSets",
    "check_invariance",
    "invariant_sets",
]

#: ``m``: the heading faces sit at ``|chi - k e| = m k E`` (``m > 1`` leaves the slack
#: the heading faces' proof needs).
HEADING_RATIO = 1.25
#: The proof holds for every ``E'`` in ``[E, E (1 + FAMILY_WIDTH)]`` (module docstring).
FAMILY_WIDTH = 1e-6
#: The offsets ``E`` (m) of the table `invariant_sets` proves, smallest first.
TABLE_OFFSETS = (0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7)
#: The speed bounds ``v_bar`` (m/s) tried for each offset, in increasing order (the
#: largest proven one is kept).
TABLE_SPEEDS = (2.5, 5.0, 7.5, 10.0, 12.5, 15.0, 20.0, 25.0, 30.0, 40.0)
#: Box budget of one `check_invariance` call in the table.
TABLE_BUDGET = 1_500_000
#: Outward rounding of every transcendental bound (absolute; far above the error of
#: numpy's sin, cos, tan and arctan, about one unit in the last place).
_ROUND = 1e-12
_DEFAULT_BEHAVIOUR = BehaviourParameters()


def _sin(lo, hi):
    """Bounds of sin over ``[lo, hi]``: `sin_interval`, rounded outward by `_ROUND`."""
    low, high = sin_interval(lo, hi)
    return low - _ROUND, high + _ROUND


def _cos(lo, hi):
    """Bounds of cos over ``[lo, hi]``: `cos_interval`, rounded outward by `_ROUND`."""
    low, high = cos_interval(lo, hi)
    return low - _ROUND, high + _ROUND


@dataclass(frozen=True)
class InvarianceCertificate:
    """The verdict of `check_invariance` on one set and speed bound.

    Attributes
    ----------
    status : str
        ``"proven"`` (every box of the branch and bound decided), ``"refuted"`` (a point of
        the set that one step takes out of it: ``counterexample``) or ``"inconclusive"``
        (the box budget was spent first).
    offset : float
        E, m.
    heading_margin : float
        ``M = m k E``, rad.
    speed_bound : float
        v_bar, m/s: every speed of ``[0, v_bar]``.
    dt : float
        The sub-step, s.
    theta_b_low, theta_b_high : ndarray, shape (2,)
        The steering gains' box (read-only).
    boxes : int
        Boxes bounded.
    counterexample : ndarray, shape (5,) or None
        ``(e, chi, v, theta_b1, theta_b2)`` of a refuting point (read-only).
    face : str
        The face a refuting point crosses (``"offset"`` or ``"heading"``), else ``""``.
    """

    status: str
    offset: float
    heading_margin: float
    speed_bound: float
    dt: float
    theta_b_low: np.ndarray
    theta_b_high: np.ndarray
    boxes: int
    counterexample: np.ndarray | None = None
    face: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "theta_b_low", frozen_copy(self.theta_b_low))
        object.__setattr__(self, "theta_b_high", frozen_copy(self.theta_b_high))
        if self.counterexample is not None:
            object.__setattr__(self, "counterexample", frozen_copy(self.counterexample))

    @property
    def proven(self) -> bool:
        """Whether the set is proven invariant."""
        return self.status == "proven"

    def to_dict(self) -> dict:
        """The certificate as plain data."""
        return {
            "status": self.status,
            "offset": self.offset,
            "heading_margin": self.heading_margin,
            "speed_bound": self.speed_bound,
            "dt": self.dt,
            "theta_b_low": self.theta_b_low.tolist(),
            "theta_b_high": self.theta_b_high.tolist(),
            "boxes": self.boxes,
            "counterexample": None if self.counterexample is None else self.counterexample.tolist(),
            "face": self.face,
        }


def _world_step(e, chi, v, b1, b2, dt, vehicle, speed_epsilon):
    """The world's own step (`steering_features`, `linear_steering`, `bicycle_step`) of vehicles on a lane
    along +x at y = 0, from offset ``e`` and heading error ``chi``: the offsets and heading errors after it."""
    n = e.shape[0]
    g = steering_features(np.zeros(n), chi, e, v, vehicle.length, speed_epsilon)
    steer = linear_steering(np.stack([b1, b2], axis=1), g, vehicle.max_steering)
    nxt = bicycle_step(np.stack([np.zeros(n), e, v, chi], axis=1), np.zeros(n), steer, dt, vehicle)
    return nxt[:, 1], nxt[:, 3]


def _face_bounds(boxes, offset, margin, dt, length, max_steering, speed_epsilon):
    """Per box of ``(t, s, v, b1, b2)``: ``(accepted_offset, accepted_heading)``.

    ``e = t E'``, ``z = s M'`` with ``E'`` in ``[E, E (1 + FAMILY_WIDTH)]`` and ``M' = m k E'``.
    A face is accepted for a box when ``e+ <= E'`` (resp. ``z+ <= M'``) holds for every
    point of it.
    """
    k = 2.0 / length
    n = boxes.shape[0]
    t0, s0, v0, b10, b20 = (boxes[:, i, 0] for i in range(5))
    t1, s1, v1, b11, b21 = (boxes[:, i, 1] for i in range(5))
    top = 1.0 + FAMILY_WIDTH
    e = interval_product(t0, t1, np.full(n, offset), np.full(n, offset * top))
    z = interval_product(s0, s1, np.full(n, margin), np.full(n, margin * top))
    chi = (z[0] + k * e[0], z[1] + k * e[1])
    ve = (np.maximum(v0, speed_epsilon), np.maximum(v1, speed_epsilon))
    inv = (1.0 / ve[1], 1.0 / ve[0])
    sigma1 = interval_product(b10, b11, *chi)
    sigma2 = interval_product(b20, b21, *interval_product(*e, *inv))
    sigma = (sigma1[0] + sigma2[0], sigma1[1] + sigma2[1])
    delta = interval_product(-length * inv[1], -length * inv[0], *sigma)
    spread = 1e-12 * (1.0 + np.abs(delta[0])), 1e-12 * (1.0 + np.abs(delta[1]))
    d_lo = np.clip(delta[0] - spread[0], -max_steering, max_steering)
    d_hi = np.clip(delta[1] + spread[1], -max_steering, max_steering)
    beta = (slip_angle(d_lo) - _ROUND, slip_angle(d_hi) + _ROUND)
    disp = (v0 * dt, v1 * dt)
    # offset face: e+ - E' <= E (t - 1) + D sin(chi + beta)
    move = interval_product(*disp, *_sin(chi[0] + beta[0], chi[1] + beta[1]))
    ok_e = (move[1] <= 0.0) | (offset * (t1 - 1.0) + move[1] <= -1e-12 * (1.0 + offset))
    # heading face: z+ - M' <= M (s - 1) - (4 D / L) cos(beta + chi / 2) sin(chi / 2)
    cos_ = _cos(beta[0] + chi[0] / 2, beta[1] + chi[1] / 2)
    sin_ = _sin(chi[0] / 2, chi[1] / 2)
    turn = interval_product(-4.0 * disp[1] / length, -4.0 * disp[0] / length, *interval_product(*cos_, *sin_))
    ok_z = (turn[1] <= 0.0) | (margin * (s1 - 1.0) + turn[1] <= -1e-12 * (1.0 + margin))
    return ok_e, ok_z


def check_invariance(
    offset: float,
    speed_bound: float,
    dt: float,
    *,
    vehicle: VehicleParameters = DEFAULT_VEHICLE,
    behaviour: BehaviourParameters = _DEFAULT_BEHAVIOUR,
    theta_b=None,
    max_boxes: int = TABLE_BUDGET,
) -> InvarianceCertificate:
    """Prove, refute or leave open that ``S(E)`` is invariant for speeds in ``[0, v_bar]``.

    Parameters
    ----------
    offset : float
        E, m, > 0.
    speed_bound : float
        v_bar, m/s, >= 0.
    dt : float
        The sub-step, s, > 0.
    vehicle : VehicleParameters
        L and the steering bound.
    behaviour : BehaviourParameters
        ``speed_epsilon`` and, by default, the steering gains' prior box.
    theta_b : tuple of 2 array_like, optional
        ``(low, high)`` of the steering gains; default ``behaviour.theta_b_prior``.
    max_boxes : int
        The box budget.

    Returns
    -------
    InvarianceCertificate

    Notes
    -----
    Branch and bound over ``(e / E, z / M, v, theta_b1, theta_b2)`` in ``[-1, 1]^2 x [0,
    v_bar] x theta_b``, for both upper faces (module docstring): a box is bounded by
    interval arithmetic (the clip and ``arctan(tan(.) / 2)`` are monotone, sin and cos
    have exact ranges, `sin_interval` and `cos_interval`), transcendental bounds
    rounded outward; an undecided box is split in its widest coordinate (relative to the
    domain), and its centre is stepped by the world's own functions (`steering_features`,
    `linear_steering`, `bicycle_step`): if that point leaves the set, the verdict is
    ``"refuted"``. Deterministic.
    """
    for name, value, low in (("offset", offset, 0.0), ("dt", dt, 0.0)):
        if not (np.isfinite(value) and value > low):
            raise InputError(f"{name} must be finite and > 0, got {value!r}")
    if not (np.isfinite(speed_bound) and speed_bound >= 0.0):
        raise InputError(f"speed_bound must be finite and >= 0, got {speed_bound!r}")
    max_boxes = as_count("max_boxes", max_boxes)
    b_lo, b_hi = behaviour.theta_b_prior if theta_b is None else theta_b
    b_lo, b_hi = np.asarray(b_lo, dtype=float), np.asarray(b_hi, dtype=float)
    if b_lo.shape != (2,) or b_hi.shape != (2,):
        raise DimensionError(f"theta_b must be two arrays of shape (2,), got shapes {b_lo.shape} and {b_hi.shape}")
    if not (np.all(np.isfinite(b_lo)) and np.all(np.isfinite(b_hi)) and np.all(b_lo <= b_hi) and np.all(b_lo > 0)):
        raise InputError(f"theta_b must be a finite box of positive gains, got {b_lo} .. {b_hi}")
    length, dmax, eps = float(vehicle.length), float(vehicle.max_steering), float(behaviour.speed_epsilon)
    k = 2.0 / length
    offset, speed_bound, dt = float(offset), float(speed_bound), float(dt)
    margin = HEADING_RATIO * k * offset
    domain = np.array([[-1.0, 1.0], [-1.0, 1.0], [0.0, speed_bound], [b_lo[0], b_hi[0]], [b_lo[1], b_hi[1]]])
    scale = np.where(domain[:, 1] > domain[:, 0], domain[:, 1] - domain[:, 0], 1.0)
    boxes = domain[None].copy()
    count = 0

    def verdict(status, point=None, face=""):
        return InvarianceCertificate(status, offset, margin, speed_bound, dt, b_lo, b_hi, count, point, face)

    while boxes.shape[0]:
        count += boxes.shape[0]
        ok_e, ok_z = _face_bounds(boxes, offset, margin, dt, length, dmax, eps)
        undecided = ~(ok_e & ok_z)
        boxes, bad_e = boxes[undecided], ~ok_e[undecided]
        if not boxes.shape[0]:
            break
        centre = boxes.mean(axis=2)
        e_c, chi_c = centre[:, 0] * offset, centre[:, 1] * margin + k * centre[:, 0] * offset
        e1, chi1 = _world_step(e_c, chi_c, centre[:, 2], centre[:, 3], centre[:, 4], dt, vehicle, eps)
        out_e, out_z = np.abs(e1) > offset, np.abs(chi1 - k * e1) > margin
        if np.any(out_e | out_z):
            i = int(np.argmax(out_e | out_z))
            point = np.array([e_c[i], chi_c[i], centre[i, 2], centre[i, 3], centre[i, 4]])
            return verdict("refuted", point, "offset" if out_e[i] else "heading")
        if count + 2 * boxes.shape[0] > max_boxes:
            return verdict("inconclusive", face="offset" if bad_e.any() else "heading")
        width = (boxes[:, :, 1] - boxes[:, :, 0]) / scale
        dim = np.argmax(width, axis=1)
        rows = np.arange(boxes.shape[0])
        mid = centre[rows, dim]
        left, right = boxes.copy(), boxes.copy()
        left[rows, dim, 1] = mid
        right[rows, dim, 0] = mid
        boxes = np.concatenate([left, right])
    return verdict("proven")


@dataclass(frozen=True)
class InvariantSets:
    """A table of proven invariant parallelograms ``S(E_i)``, smallest first (nested).

    Attributes
    ----------
    offsets : ndarray, shape (K,)
        ``E_i``, m, increasing.
    heading_margins : ndarray, shape (K,)
        ``M_i = m k E_i``, rad.
    speed_bounds : ndarray, shape (K,)
        ``v_bar_i``: ``S(E_i)`` is proven invariant for every speed in ``[0, v_bar_i]``.
    theta_b_low, theta_b_high : ndarray, shape (2,)
        The steering gains' box of the proofs.
    dt : float
        The sub-step of the proofs, s.
    slope : float
        ``k = 2 / L``.
    certificates : tuple of InvarianceCertificate
        The proof of each row.
    """

    offsets: np.ndarray
    heading_margins: np.ndarray
    speed_bounds: np.ndarray
    theta_b_low: np.ndarray
    theta_b_high: np.ndarray
    dt: float
    slope: float
    certificates: tuple = ()

    def __post_init__(self) -> None:
        for name in ("offsets", "heading_margins", "speed_bounds", "theta_b_low", "theta_b_high"):
            object.__setattr__(self, name, frozen_copy(getattr(self, name)))
        k = self.offsets.size
        shapes = [getattr(self, n).shape for n in ("offsets", "heading_margins", "speed_bounds")]
        if any(shape != (k,) for shape in shapes):
            raise DimensionError(f"offsets, heading_margins and speed_bounds must have shape ({k},), got {shapes}")
        if self.theta_b_low.shape != (2,) or self.theta_b_high.shape != (2,):
            raise DimensionError(
                f"theta_b_low and theta_b_high must have shape (2,), got {self.theta_b_low.shape} and "
                f"{self.theta_b_high.shape}"
            )
        # smallest_containing takes the first set that holds a box: the table must be nested, smallest first
        if not (
            np.all(self.offsets > 0)
            and np.all(np.diff(self.offsets) > 0)
            and np.all(np.diff(self.heading_margins) >= 0)
            and np.all(self.heading_margins >= 0)
            and np.all(np.isfinite(self.speed_bounds))
        ):
            raise InputError(
                "offsets must be positive and increasing, heading_margins nonnegative and nondecreasing (nested "
                f"sets), speed bounds finite; got {self.offsets}, {self.heading_margins}, {self.speed_bounds}"
            )
        if not (np.isfinite(self.slope) and self.slope > 0 and np.isfinite(self.dt) and self.dt > 0):
            raise InputError(f"slope and dt must be finite and > 0, got {self.slope!r} and {self.dt!r}")

    def __len__(self) -> int:
        return int(self.offsets.size)

    def smallest_containing(self, lo, hi) -> np.ndarray:
        """Index of the smallest set that contains each box ``[lo, hi]`` of ``(e, chi)``, -1 if none.

        Parameters
        ----------
        lo, hi : array_like, shape (n, 2)

        Returns
        -------
        ndarray of int, shape (n,)
        """
        lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        if lo.ndim != 2 or lo.shape[1:] != (2,) or hi.shape != lo.shape:
            raise DimensionError(f"lo and hi must have the same shape (n, 2), got shapes {lo.shape} and {hi.shape}")
        if not len(self):
            return np.full(lo.shape[0], -1)
        k = self.slope
        with np.errstate(invalid="ignore"):
            e_m = np.maximum(np.abs(lo[:, 0]), np.abs(hi[:, 0]))
            # max |chi - k e| over the box: at its corners
            z_m = np.maximum(np.abs(hi[:, 1] - k * lo[:, 0]), np.abs(lo[:, 1] - k * hi[:, 0]))
            inside = (
                (e_m[:, None] <= self.offsets[None, :])
                & (z_m[:, None] <= self.heading_margins[None, :])
                & (lo[:, None, 0] <= hi[:, None, 0])
                & (lo[:, None, 1] <= hi[:, None, 1])
            )
        return np.where(inside.any(axis=1), np.argmax(inside, axis=1), -1)

    def tighten(self, index, lo, hi) -> tuple[np.ndarray, np.ndarray]:
        """Each box ``[lo, hi]`` intersected with the hull of ``S(E_i (1 + FAMILY_WIDTH))``, ``i = index``.

        The offset to ``|e| <= E'``, then the heading error to ``k [e_lo, e_hi] +- M'``.

        Parameters
        ----------
        index : array_like of int, shape (n,)
            Rows of the table (each >= 0).
        lo, hi : array_like, shape (n, 2)

        Returns
        -------
        lo, hi : ndarray, shape (n, 2)
        """
        index = np.asarray(index, dtype=int)
        lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
        if lo.shape != (index.size, 2) or hi.shape != lo.shape:
            raise DimensionError(f"lo and hi must have shape ({index.size}, 2), got shapes {lo.shape} and {hi.shape}")
        if index.size and (index.min() < 0 or index.max() >= len(self)):
            raise InputError(f"index must lie in [0, {len(self)}), got {index.min()} .. {index.max()}")
        top = 1.0 + FAMILY_WIDTH
        e_bar, z_bar = self.offsets[index] * top, self.heading_margins[index] * top
        lo[:, 0], hi[:, 0] = np.maximum(lo[:, 0], -e_bar), np.minimum(hi[:, 0], e_bar)
        k = self.slope
        lo[:, 1] = np.maximum(lo[:, 1], k * lo[:, 0] - z_bar)
        hi[:, 1] = np.minimum(hi[:, 1], k * hi[:, 0] + z_bar)
        return lo, hi

    def to_dict(self) -> dict:
        """The table as plain data."""
        return {
            "offsets": self.offsets.tolist(),
            "heading_margins": self.heading_margins.tolist(),
            "speed_bounds": self.speed_bounds.tolist(),
            "theta_b_low": self.theta_b_low.tolist(),
            "theta_b_high": self.theta_b_high.tolist(),
            "dt": self.dt,
            "slope": self.slope,
            "certificates": [c.to_dict() for c in self.certificates],
        }


@lru_cache(maxsize=16)
def invariant_sets(
    dt: float, vehicle: VehicleParameters = DEFAULT_VEHICLE, behaviour: BehaviourParameters = _DEFAULT_BEHAVIOUR
) -> InvariantSets:
    """The proven sets for a sub-step, vehicle and steering prior (computed once per arguments).

    For each offset of `TABLE_OFFSETS`, the largest speed bound of `TABLE_SPEEDS` (up to
    the vehicle's top speed) such that it and every smaller one are ``"proven"`` by
    `check_invariance` on the prior's steering gains; offsets with none are left out.
    The sets are nested: a larger ``E`` contains a smaller one.

    Parameters
    ----------
    dt : float
        The sub-step, s.
    vehicle : VehicleParameters
    behaviour : BehaviourParameters

    Returns
    -------
    InvariantSets
    """
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"dt must be finite and > 0, got {dt!r}")
    rows = []
    for offset in TABLE_OFFSETS:
        best = None
        for speed in TABLE_SPEEDS:
            if speed > vehicle.max_speed:
                break
            cert = check_invariance(offset, speed, dt, vehicle=vehicle, behaviour=behaviour)
            if not cert.proven:
                break
            best = cert
        if best is not None:
            rows.append(best)
    b_lo, b_hi = behaviour.theta_b_prior
    return InvariantSets(
        offsets=np.array([c.offset for c in rows]),
        heading_margins=np.array([c.heading_margin for c in rows]),
        speed_bounds=np.array([c.speed_bound for c in rows]),
        theta_b_low=b_lo,
        theta_b_high=b_hi,
        dt=float(dt),
        slope=2.0 / vehicle.length,
        certificates=tuple(rows),
    )
