"""A quadratic contraction bound of the lateral closed loop on a straight lane.

One concept: the LinearVehicle's lateral state ``x = (e, chi)`` (offset from the lane it
steers to, heading error) under its own steering law shrinks, step by step, in a fixed
quadratic norm ``||x||_P = sqrt(x' P x)``, by a factor that `contraction_factor` bounds
over a box of states, speeds and gains. `forecast_traffic` carries one radius per lateral
box and intersects the box with the ellipse's hull: where the interval iteration wraps
(its box grows with its own remainder), the ellipse does not.

The step (`minimaxplan.scenarios.vehicles.bicycle_step` with the law
``delta = clip(-(L / v)(b1 chi + q e))``, ``q = theta_b2 / v``, on a straight lane) is,
exactly, with ``beta = arctan(tan(delta) / 2)``::

    e+   = e   + v dt sin(chi + beta)
    chi+ = chi + (2 v dt / L) sin(beta)

Write ``beta = g delta_r`` (``g = beta(clip(delta_r)) / delta_r``), ``sin(chi + beta) =
s1 (chi + beta)``, ``sin(beta) = s2 beta``: then ``x+ = A x`` with::

    A = [[1 - dt s1 g L q,   dt s1 (v - g L b1)],
         [  - 2 dt s2 g q,   1 - 2 dt s2 g b1  ]]

multi-affine in ``(s1, s2, g, v, b1, q)``, each in an interval computed from the box (the
sector factors from the largest ``|delta_r|``, ``|beta|`` and ``|chi + beta|`` over it).
A multi-affine map of a box lies in the convex hull of its 64 vertex values, and
``A -> ||A x||_P`` is convex, so ``||x+||_P <= sqrt(lambda) ||x||_P`` with ``lambda`` the
largest ``||C A_k C^-1||_2^2`` over the vertices (``P = C' C``). The bound needs no
disturbance term: the lateral law has none (its only uncertainty is in the gains, the
speed and the initial state), and it is valid for every state of the box, whichever
speed in the box and whichever gains in theirs the step has.

The metric ``P`` is one of a table per speed (`contraction_metrics`), each tuned once by
a grid search over the prior's gains, so that ``lambda < 1`` over a moderate box; the
bound is sound for any ``P``, the tuning only makes it tight.

Layer: numpy, and the compiled arithmetic of `minimaxplan.kernels.vertex_bounds` (the vertex
maximum) and `minimaxplan.kernels.lateral_bounds` (the vertex box, the corner norms).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from minimaxplan.kernels.lateral_bounds import contraction_vertex_box, metric_radius_bounds
from minimaxplan.kernels.vertex_bounds import contraction_vertex_factor
from minimaxplan.models.errors import DimensionError, InputError

from .vehicles import DEFAULT_VEHICLE, BehaviourParameters, VehicleParameters, slip_angle

__all__ = [
    "CONTRACTION_MARGIN",
    "contraction_factor",
    "contraction_metrics",
    "ellipse_hull",
    "metric_radius",
    "unchecked_contraction_factor",
    "unchecked_metric_radius",
]

#: Relative outward rounding of a contraction factor (orders of magnitude above the
#: floating-point error of the few operations of one vertex).
CONTRACTION_MARGIN = 1e-9
_DEFAULT_BEHAVIOUR = BehaviourParameters()
#: Speed ratio between neighbouring metrics of the table.
_TABLE_RATIO = 1.25
#: The box a metric is tuned on: speeds within this ratio of its node, |e| and |chi| up to these.
_TUNE_SPEED_RATIO, _TUNE_OFFSET, _TUNE_HEADING = 1.12, 0.5, 0.1


def _vertex_box(length, max_steering, e, chi, v, b1, q):
    """The box of ``(s1, s2, g, v, b1, q)`` over the state box, as (lower, upper), each shape (n, 6).

    The sector factors' ranges (`minimaxplan.kernels.lateral_bounds.contraction_vertex_box`):
    ``s1 = sinc(chi + beta)`` and ``s2 = sinc(beta)`` from the largest ``|chi| + |beta|``
    and ``|beta|``, ``g = beta(clip(delta_r)) / delta_r`` from the largest ``|delta_r| <=
    (L / v_lo)(|b1|_max |chi|_max + |q|_max |e|_max)``.
    """
    rows = [np.ascontiguousarray(bound, dtype=float) for pair in (e, chi, v, b1, q) for bound in pair]
    return contraction_vertex_box(float(length), float(max_steering), *rows)


def _metrics(metric) -> np.ndarray:
    """``metric`` as a float array of shape (n, 2, 2), each symmetric positive definite, or a typed error."""
    p = np.asarray(metric, dtype=float)
    if p.ndim != 3 or p.shape[1:] != (2, 2):
        raise DimensionError(f"metric must have shape (n, 2, 2), got shape {p.shape}")
    det = p[:, 0, 0] * p[:, 1, 1] - p[:, 0, 1] * p[:, 1, 0]
    if not (np.all(np.isfinite(p)) and np.all(p[:, 0, 1] == p[:, 1, 0]) and np.all(p[:, 0, 0] > 0) and np.all(det > 0)):
        raise InputError("metric must hold finite symmetric positive definite matrices")
    return p


def _boxes(name: str, lo, hi, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(lo, hi)`` as float arrays of shape (n, 2), or a typed error."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    if lo.shape != (n, 2) or hi.shape != (n, 2):
        raise DimensionError(f"{name} must have shape ({n}, 2) each, got shapes {lo.shape} and {hi.shape}")
    return lo, hi


def _inverse(m):
    """Closed-form inverse of each 2 x 2 matrix, shape (..., 2, 2)."""
    det = m[..., 0, 0] * m[..., 1, 1] - m[..., 0, 1] * m[..., 1, 0]
    out = np.empty(m.shape)
    out[..., 0, 0], out[..., 1, 1] = m[..., 1, 1] / det, m[..., 0, 0] / det
    out[..., 0, 1], out[..., 1, 0] = -m[..., 0, 1] / det, -m[..., 1, 0] / det
    return out


def _upper_factor(metric):
    """``C`` upper triangular with ``P = C' C``, shape (..., 2, 2)."""
    p11, p12, p22 = metric[..., 0, 0], metric[..., 0, 1], metric[..., 1, 1]
    c = np.zeros(metric.shape)
    c[..., 0, 0] = np.sqrt(p11)
    c[..., 0, 1] = p12 / np.sqrt(p11)
    c[..., 1, 1] = np.sqrt(p22 - p12**2 / p11)
    return c


def contraction_factor(metric, e, chi, v, b1, q, dt: float, vehicle: VehicleParameters = DEFAULT_VEHICLE) -> np.ndarray:
    """``lambda`` with ``||x+||_P^2 <= lambda ||x||_P^2`` for every state of the box (module docstring).

    Parameters
    ----------
    metric : array_like, shape (n, 2, 2)
        Symmetric positive definite ``P`` per box.
    e, chi, v, b1, q : tuple of 2 array_like, shape (n,)
        ``(lo, hi)`` of the offset (m), heading error (rad), speed (m/s, ``v_lo > 0``),
        theta_b1 and ``q = theta_b2 / v`` over the step.
    dt : float
        Step, s.
    vehicle : VehicleParameters
        L and the steering bound.

    Returns
    -------
    ndarray, shape (n,)
        The factor, rounded up by `CONTRACTION_MARGIN`; inf where the box is outside the
        bound's validity (``|chi| + |beta| > pi``).
    """
    p = _metrics(metric)
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"dt must be finite and > 0, got {dt!r}")
    ranges = []
    for name, pair in zip(("e", "chi", "v", "b1", "q"), (e, chi, v, b1, q)):
        lo, hi = (np.asarray(r, dtype=float) for r in pair)
        if lo.shape not in ((), (p.shape[0],)) or hi.shape not in ((), (p.shape[0],)):
            raise DimensionError(
                f"{name} must be (lo, hi) of shape ({p.shape[0]},) or scalars, got shapes {lo.shape} and {hi.shape}"
            )
        lo, hi = np.broadcast_to(lo, (p.shape[0],)), np.broadcast_to(hi, (p.shape[0],))
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo <= hi)):
            raise InputError(f"{name} must hold finite intervals with lo <= hi")
        ranges.append((lo, hi))
    if np.any(ranges[2][0] <= 0.0):
        raise InputError("v must have a positive lower bound")
    e_r, chi_r, v_r, b1_r, q_r = ranges
    return unchecked_contraction_factor(p, e_r, chi_r, v_r, b1_r, q_r, float(dt), vehicle)


def unchecked_contraction_factor(metric, e, chi, v, b1, q, dt: float, vehicle: VehicleParameters) -> np.ndarray:
    """`contraction_factor` without its argument checks, for callers whose arguments are valid by construction.

    The traffic forecast calls it at every sub-step with metrics from `contraction_metrics`
    and boxes it built; the checks cost about as much as the bound there.

    Parameters
    ----------
    metric : ndarray, shape (n, 2, 2)
        Symmetric positive definite, float.
    e, chi, v, b1, q : tuple of 2 ndarray, shape (n,)
        Finite intervals, ``v_lo > 0``.
    dt : float
        Step, s, > 0.
    vehicle : VehicleParameters
        L and the steering bound.

    Returns
    -------
    ndarray, shape (n,)
        As `contraction_factor`.
    """
    lower, upper = _vertex_box(vehicle.length, vehicle.max_steering, e, chi, v, b1, q)
    lam = contraction_vertex_factor(metric, lower, upper, float(dt), float(vehicle.length))
    lam = lam * (1.0 + CONTRACTION_MARGIN)
    beta_max = slip_angle(vehicle.max_steering)
    c_m = np.maximum(np.abs(chi[0]), np.abs(chi[1]))
    return np.where(c_m + beta_max <= np.pi, lam, np.inf)


def metric_radius(metric, lo, hi) -> np.ndarray:
    """The smallest ``rho`` with the box ``[lo, hi]`` inside ``{x : x' P x <= rho^2}``: its largest corner norm.

    Parameters
    ----------
    metric : array_like, shape (n, 2, 2)
    lo, hi : array_like, shape (n, 2)
        The boxes' corners; an empty box (``lo > hi``) gives inf.
    """
    p = _metrics(metric)
    lo, hi = _boxes("lo, hi", lo, hi, p.shape[0])
    return unchecked_metric_radius(p, lo, hi)


def unchecked_metric_radius(metric, lo, hi) -> np.ndarray:
    """`metric_radius` without its argument checks (metrics of `contraction_metrics`, boxes of shape (n, 2)).

    Parameters
    ----------
    metric : ndarray, shape (n, 2, 2)
    lo, hi : ndarray, shape (n, 2)

    Returns
    -------
    ndarray, shape (n,)
        As `metric_radius` (compiled: `minimaxplan.kernels.lateral_bounds.metric_radius_bounds`).
    """
    return metric_radius_bounds(
        np.ascontiguousarray(metric, dtype=float),
        np.ascontiguousarray(lo, dtype=float),
        np.ascontiguousarray(hi, dtype=float),
        CONTRACTION_MARGIN,
    )


def ellipse_hull(metric, radius, to_basis=None) -> np.ndarray:
    """Half-widths of the box hull of ``{x : x' P x <= rho^2}``, or of its image ``z = to_basis x``.

    Parameters
    ----------
    metric : array_like, shape (n, 2, 2)
    radius : array_like, shape (n,)
        ``rho >= 0`` (inf: no bound).
    to_basis : array_like, shape (n, 2, 2), optional
        ``T^-1`` with ``z = T^-1 x`` (the forecast's basis coordinates); the hull of ``z`` is
        then returned.

    Returns
    -------
    ndarray, shape (n, 2)
        ``rho sqrt(diag(M P^-1 M'))``, ``M`` = ``to_basis`` (identity by default).
    """
    p = _metrics(metric)
    rho = np.asarray(radius, dtype=float)
    if rho.shape != (p.shape[0],):
        raise DimensionError(f"radius must have shape ({p.shape[0]},), got shape {rho.shape}")
    if np.any(np.isnan(rho)) or np.any(rho < 0):
        raise InputError("radius must be >= 0 (or inf)")
    p_inv = _inverse(p)
    if to_basis is not None:
        m = np.asarray(to_basis, dtype=float)
        if m.shape != p.shape:
            raise DimensionError(f"to_basis must have shape {p.shape}, got shape {m.shape}")
        p_inv = m @ p_inv @ np.swapaxes(m, -1, -2)
    diag = np.stack([p_inv[:, 0, 0], p_inv[:, 1, 1]], axis=1)
    return rho[:, None] * np.sqrt(diag) * (1.0 + CONTRACTION_MARGIN)


@lru_cache(maxsize=16)
def contraction_metrics(
    dt: float, vehicle: VehicleParameters = DEFAULT_VEHICLE, behaviour: BehaviourParameters = _DEFAULT_BEHAVIOUR
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The table of metrics: speed nodes, one ``P`` per node, and the conversions between them.

    Each ``P = [[1, c sqrt(r)], [c sqrt(r), r]]`` minimises `contraction_factor` over a grid
    of ``(r, c)``, on the box of the prior's gains, speeds within a ratio of 1.12 of its
    node, ``|e| <= 0.5`` m and ``|chi| <= 0.1`` rad. Deterministic; computed once per
    ``(dt, vehicle, behaviour)``.

    Returns
    -------
    speeds : ndarray, shape (K,)
        Geometric nodes from 1 m/s to the vehicle's top speed.
    metrics : ndarray, shape (K, 2, 2)
        Read-only.
    conversion : ndarray, shape (K, K)
        ``||x||_{P_j} <= conversion[i, j] ||x||_{P_i}`` (rounded up).
    """
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"dt must be finite and > 0, got {dt!r}")
    count = max(2, int(np.ceil(np.log(vehicle.max_speed) / np.log(_TABLE_RATIO))) + 1)
    speeds = np.geomspace(1.0, max(vehicle.max_speed, 1.0 * _TABLE_RATIO), count)
    r = np.geomspace(1e-2, 1e2, 41)
    c = np.linspace(-0.95, 0.95, 39)
    rr, cc = np.meshgrid(r, c, indexing="ij")
    cand = np.empty((rr.size, 2, 2))
    cand[:, 0, 0], cand[:, 1, 1] = 1.0, rr.ravel()
    cand[:, 0, 1] = cand[:, 1, 0] = cc.ravel() * np.sqrt(rr.ravel())
    b_lo, b_hi = behaviour.theta_b_prior
    metrics = np.empty((count, 2, 2))
    for k, node in enumerate(speeds):
        v = (np.array([node / _TUNE_SPEED_RATIO]), np.array([node * _TUNE_SPEED_RATIO]))
        q = (np.array([b_lo[1] / v[1][0]]), np.array([b_hi[1] / v[0][0]]))
        lower, upper = _vertex_box(
            vehicle.length,
            vehicle.max_steering,
            (np.array([-_TUNE_OFFSET]), np.array([_TUNE_OFFSET])),
            (np.array([-_TUNE_HEADING]), np.array([_TUNE_HEADING])),
            v,
            (np.array([b_lo[0]]), np.array([b_hi[0]])),
            q,
        )
        n_cand = cand.shape[0]
        scores = contraction_vertex_factor(
            cand,
            np.repeat(lower, n_cand, axis=0),
            np.repeat(upper, n_cand, axis=0),
            float(dt),
            vehicle.length,
        )
        metrics[k] = cand[int(np.argmin(scores))]
    # ||x||_{P_j}^2 <= mu ||x||_{P_i}^2, mu the largest eigenvalue of C_i^-T P_j C_i^-1
    ci_inv = _inverse(_upper_factor(metrics))
    rel = np.swapaxes(ci_inv, -1, -2)[:, None] @ metrics[None, :] @ ci_inv[:, None]
    conversion = np.sqrt(np.linalg.eigvalsh(0.5 * (rel + np.swapaxes(rel, -1, -2)))[..., -1]) * (
        1.0 + CONTRACTION_MARGIN
    )
    for arr in (speeds, metrics, conversion):
        arr.setflags(write=False)
    return speeds, metrics, conversion
