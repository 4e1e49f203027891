"""Compiled interval bounds of the bicycle's nonlinear terms: the rest of the traffic forecast's per-unit arithmetic.

`minimaxplan.scenarios.traffic_models.forecast_traffic` bounds, at every sub-step and for
every unit of every vehicle, a few nonlinear functions of boxes. Four of them are here,
each over a batch of rows (one element per row, no reduction across rows):

* `lateral_remainder_bounds`: the bicycle's lateral step minus its linear model, the
  steering applied and the velocity's angle to the lane (the arithmetic of
  `minimaxplan.scenarios.traffic_models.lateral_remainder`);
* `footprint_bounds`: the axis-aligned box of every rectangle with its centre in a box
  and its heading in an interval (`minimaxplan.scenarios.traffic_models.footprint_box`);
* `contraction_vertex_box`: the box of the contraction bound's six vertex parameters
  over a state box (`minimaxplan.scenarios.lateral_contraction`);
* `metric_radius_bounds`: the largest norm of a box's corners in a metric
  (`minimaxplan.scenarios.lateral_contraction.metric_radius`).

They were numpy expressions over small arrays, a few dozen calls each, about a third of a
highway forecast's time when profiled (2026-12-06). Each performs the same floating-point
operations in the same order as those expressions did, with numpy's semantics for NaN and
for ties between signed zeros (`np.minimum` and `np.maximum` return the second argument
on a tie; `np.fmin` and `np.fmax`, as numpy's vector loops do, too), so the forecast's
boxes are unchanged to the last bit (`benchmarks/results/commits/273f767dd9c0-de7304f18ee8.md`).
``cos``, ``sin``, ``tan`` and ``arctan`` are the C library's; numpy's agreed with them bit
for bit on the AVX2 machine where this was measured, and the records' numerical
environment (`minimaxplan.analysis.numerical_environment`) keeps numpy off its AVX-512
kernels, which may not. The callers keep the argument checks and the meaning: this
module is their arithmetic only.

Layer: numpy and numba only.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["contraction_vertex_box", "footprint_bounds", "lateral_remainder_bounds", "metric_radius_bounds"]

_PI = float(np.pi)
_TWO_PI = 2 * float(np.pi)
_HALF_PI = float(np.pi) / 2


@njit(cache=True)
def _min(a, b):
    """``np.minimum``: NaN if either is; the second argument on a tie."""
    return a if (a < b or a != a) else b


@njit(cache=True)
def _max(a, b):
    """``np.maximum``: NaN if either is; the second argument on a tie."""
    return a if (a > b or a != a) else b


@njit(cache=True)
def _fmin(a, b):
    """``np.fmin`` as its vector loop: the other argument where one is NaN; the second on a tie."""
    return a if (a < b or b != b) else b


@njit(cache=True)
def _fmax(a, b):
    """``np.fmax`` as its vector loop: the other argument where one is NaN; the second on a tie."""
    return a if (a > b or b != b) else b


@njit(cache=True)
def _same_rows(n, a, b, c, d, e, f, g, h, i):
    """Whether the nine arrays have ``n`` rows each (any layouts: no tuple to iterate)."""
    return (a.shape[0] == n and b.shape[0] == n and c.shape[0] == n and d.shape[0] == n and e.shape[0] == n) and (
        f.shape[0] == n and g.shape[0] == n and h.shape[0] == n and i.shape[0] == n
    )


@njit(cache=True)
def _round_out(lo, hi, margin):
    """``[lo, hi]`` widened by ``margin (1 + |.|)`` (infinite bounds stay; `traffic_models._out`)."""
    return _fmin(lo, lo - margin * (1.0 + abs(lo))), _fmax(hi, hi + margin * (1.0 + abs(hi)))


@njit(cache=True)
def _product(a_lo, a_hi, b_lo, b_hi):
    """The interval product, the four corners reduced in order (`minimaxplan.models.prediction.interval_product`)."""
    c0, c1, c2, c3 = a_lo * b_lo, a_lo * b_hi, a_hi * b_lo, a_hi * b_hi
    lo, hi = _min(c0, c1), _max(c0, c1)
    lo, hi = _min(lo, c2), _max(hi, c2)
    return _min(lo, c3), _max(hi, c3)


@njit(cache=True)
def _cos_range(lo, hi):
    """The exact range of cos over ``[lo, hi]`` (`minimaxplan.models.prediction.cos_interval`)."""
    a, b = np.cos(lo), np.cos(hi)
    has_max = np.floor(hi / _TWO_PI) * _TWO_PI >= lo
    has_min = np.floor((hi - _PI) / _TWO_PI) * _TWO_PI + _PI >= lo
    return (-1.0 if has_min else _min(a, b)), (1.0 if has_max else _max(a, b))


@njit(cache=True)
def _slip(delta):
    """The slip angle ``arctan(tan(delta) / 2)`` (`minimaxplan.scenarios.vehicles.slip_angle`)."""
    return np.arctan(0.5 * np.tan(delta))


@njit(cache=True)
def _clip(x, lo, hi):
    """``np.clip`` of a float (NaN stays NaN)."""
    return _min(_max(x, lo), hi)


@njit(cache=True)
def lateral_remainder_bounds(
    e_lo, e_hi, c_lo, c_hi, v_lo, v_hi, b_lo, b_hi, q_lo, q_hi, ff_lo, ff_hi, dt, length, max_steering, margin
):
    """The remainder boxes, steering and velocity angle of the lateral step, per row.

    Parameters
    ----------
    e_lo, e_hi, c_lo, c_hi, v_lo, v_hi, b_lo, b_hi, q_lo, q_hi : ndarray, shape (n,)
        Bounds of the offset, heading error, speed, theta_b1 and ``q = theta_b2 / v``.
    ff_lo, ff_hi : ndarray, shape (n,) or (0,)
        The feed-forward steering's bounds, or empty arrays for none.
    dt, length, max_steering : float
        Sub-step (s), wheelbase L (m), steering bound (rad).
    margin : float
        The relative outward rounding (`minimaxplan.scenarios.traffic_models.ROUND_MARGIN`).

    Returns
    -------
    ndarray, shape (8, n)
        Rows ``r_e`` (lo, hi), ``r_chi`` (lo, hi), ``delta`` (lo, hi) and ``chi + beta``
        (lo, hi), as `minimaxplan.scenarios.traffic_models.lateral_remainder` documents.
    """
    n = e_lo.shape[0]
    if not _same_rows(n, e_hi, c_lo, c_hi, v_lo, v_hi, b_lo, b_hi, q_lo, q_hi):
        raise ValueError("lateral_remainder_bounds: every bound must have the rows' length")
    with_ff = ff_lo.shape[0] > 0 or ff_hi.shape[0] > 0
    if with_ff and (ff_lo.shape[0] != n or ff_hi.shape[0] != n):
        raise ValueError("lateral_remainder_bounds: ff_lo and ff_hi must have the rows' length or be empty")
    out = np.empty((8, n))
    for i in range(n):
        x_lo, x_hi = _product(b_lo[i], b_hi[i], c_lo[i], c_hi[i])
        y_lo, y_hi = _product(q_lo[i], q_hi[i], e_lo[i], e_hi[i])
        s_lo, s_hi = x_lo + y_lo, x_hi + y_hi
        k_lo, k_hi = length / v_hi[i], length / v_lo[i]
        d_lo, d_hi = _product(-k_hi, -k_lo, s_lo, s_hi)
        d_lo, d_hi = _round_out(d_lo, d_hi, margin)
        if with_ff:
            d_lo, d_hi = _round_out(d_lo + ff_lo[i], d_hi + ff_hi[i], margin)
        dc_lo, dc_hi = _clip(d_lo, -max_steering, max_steering), _clip(d_hi, -max_steering, max_steering)
        cl_lo, cl_hi = dc_hi - d_hi, dc_lo - d_lo  # clip(x) - x, nonincreasing
        beta_lo, beta_hi = _slip(dc_lo), _slip(dc_hi)
        g_lo, g_hi = beta_lo - dc_lo / 2, beta_hi - dc_hi / 2
        a_lo, a_hi = c_lo[i] + beta_lo, c_hi[i] + beta_hi
        ra_lo, ra_hi = a_lo - np.sin(a_lo), a_hi - np.sin(a_hi)
        rb_lo, rb_hi = beta_lo - np.sin(beta_lo), beta_hi - np.sin(beta_hi)
        common_lo, common_hi = cl_lo / 2 + g_lo, cl_hi / 2 + g_hi
        re_lo, re_hi = _product(v_lo[i] * dt, v_hi[i] * dt, common_lo - ra_hi, common_hi - ra_lo)
        rc_lo, rc_hi = _product(
            2 * v_lo[i] * dt / length, 2 * v_hi[i] * dt / length, common_lo - rb_hi, common_hi - rb_lo
        )
        out[0, i], out[1, i] = _round_out(re_lo, re_hi, margin)
        out[2, i], out[3, i] = _round_out(rc_lo, rc_hi, margin)
        out[4, i], out[5, i], out[6, i], out[7, i] = dc_lo, dc_hi, a_lo, a_hi
    return out


@njit(cache=True)
def footprint_bounds(center_lo, center_hi, psi_lo, psi_hi, offsets, radius, margin):
    """The box ``[x_lo, y_lo, x_hi, y_hi]`` of every rectangle of a row, rounded outward.

    Parameters
    ----------
    center_lo, center_hi : ndarray, shape (n, 2)
        Box of the centre.
    psi_lo, psi_hi : ndarray, shape (n,)
        Heading interval, rad.
    offsets : ndarray, shape (4,)
        The corners' angles to the heading, ``(a, -a, pi + a, pi - a)`` with
        ``a = atan2(W, L)``, in that order.
    radius : float
        The half diagonal, m.
    margin : float
        The relative outward rounding.

    Returns
    -------
    ndarray, shape (n, 4)
    """
    n = psi_lo.shape[0]
    if center_lo.shape[0] != n or center_hi.shape[0] != n or psi_hi.shape[0] != n:
        raise ValueError("footprint_bounds: the centre boxes and headings must have the same rows")
    if center_lo.shape[1] != 2 or center_hi.shape[1] != 2 or offsets.shape[0] != 4:
        raise ValueError("footprint_bounds: centres must have 2 columns and offsets 4 entries")
    out = np.empty((n, 4))
    for i in range(n):
        dx_lo, dy_lo, dx_hi, dy_hi = np.inf, np.inf, -np.inf, -np.inf
        for k in range(4):
            lo, hi = psi_lo[i] + offsets[k], psi_hi[i] + offsets[k]
            c_lo, c_hi = _cos_range(lo, hi)
            s_lo, s_hi = _cos_range(lo - _HALF_PI, hi - _HALF_PI)
            dx_lo, dx_hi = _min(dx_lo, radius * c_lo), _max(dx_hi, radius * c_hi)
            dy_lo, dy_hi = _min(dy_lo, radius * s_lo), _max(dy_hi, radius * s_hi)
        out[i, 0], out[i, 2] = _round_out(center_lo[i, 0] + dx_lo, center_hi[i, 0] + dx_hi, margin)
        out[i, 1], out[i, 3] = _round_out(center_lo[i, 1] + dy_lo, center_hi[i, 1] + dy_hi, margin)
    return out


@njit(cache=True)
def _sinc_lower(a):
    """``min sin(x) / x`` over ``|x| <= a``, for ``a`` capped at pi (`lateral_contraction._sinc_lower`)."""
    a = _min(a, _PI)
    return np.sin(a) / a if a > 0.0 else 1.0


@njit(cache=True)
def contraction_vertex_box(length, max_steering, e_lo, e_hi, c_lo, c_hi, v_lo, v_hi, b_lo, b_hi, q_lo, q_hi):
    """The box of ``(s1, s2, g, v, b1, q)`` over each row's state box (`lateral_contraction._vertex_box`).

    Parameters
    ----------
    length, max_steering : float
        L (m) and the steering bound (rad).
    e_lo, e_hi, c_lo, c_hi, v_lo, v_hi, b_lo, b_hi, q_lo, q_hi : ndarray, shape (n,)
        Bounds of the offset, heading error, speed (``v_lo > 0``), theta_b1 and q.

    Returns
    -------
    lower, upper : ndarray, shape (n, 6)
    """
    n = e_lo.shape[0]
    if not _same_rows(n, e_hi, c_lo, c_hi, v_lo, v_hi, b_lo, b_hi, q_lo, q_hi):
        raise ValueError("contraction_vertex_box: every bound must have the rows' length")
    lower, upper = np.empty((n, 6)), np.empty((n, 6))
    beta_max = _slip(max_steering)
    for i in range(n):
        e_m = _max(abs(e_lo[i]), abs(e_hi[i]))
        c_m = _max(abs(c_lo[i]), abs(c_hi[i]))
        # |delta_r| <= (L / v_lo)(b1_hi |chi| + q_hi |e|)
        dr = length / v_lo[i] * (_max(abs(b_lo[i]), abs(b_hi[i])) * c_m + _max(abs(q_lo[i]), abs(q_hi[i])) * e_m)
        dm = _min(dr, max_steering)
        beta_m = _slip(dm)
        # g(x) = beta(clip(x)) / x: 1/2 at 0, increasing in |x| up to max_steering, then beta_max / |x|
        g_hi = beta_m / dm if dm > 0.0 else 0.5
        g_lo = _min(0.5, beta_max / dr) if dr > 0.0 else 0.5
        lower[i, 0], lower[i, 1], lower[i, 2] = _sinc_lower(c_m + beta_m), _sinc_lower(beta_m), g_lo
        lower[i, 3], lower[i, 4], lower[i, 5] = v_lo[i], b_lo[i], q_lo[i]
        upper[i, 0], upper[i, 1], upper[i, 2] = 1.0, 1.0, g_hi
        upper[i, 3], upper[i, 4], upper[i, 5] = v_hi[i], b_hi[i], q_hi[i]
    return lower, upper


@njit(cache=True)
def metric_radius_bounds(metrics, lo, hi, margin):
    """The largest ``sqrt(x' P x)`` over each row's box corners, rounded up; inf for an empty box.

    Parameters
    ----------
    metrics : ndarray, shape (n, 2, 2)
        Symmetric positive definite.
    lo, hi : ndarray, shape (n, 2)
    margin : float
        The relative rounding up (`minimaxplan.scenarios.lateral_contraction.CONTRACTION_MARGIN`).

    Returns
    -------
    ndarray, shape (n,)
    """
    n = lo.shape[0]
    if metrics.shape != (n, 2, 2) or hi.shape[0] != n or lo.shape[1] != 2 or hi.shape[1] != 2:
        raise ValueError("metric_radius_bounds: metrics (n, 2, 2), lo and hi (n, 2) must share n")
    out = np.empty(n)
    for i in range(n):
        p00, p01, p11 = metrics[i, 0, 0], metrics[i, 0, 1], metrics[i, 1, 1]
        best = 0.0
        for x0 in (lo[i, 0], hi[i, 0]):
            for x1 in (lo[i, 1], hi[i, 1]):
                best = _max(best, p00 * (x0 * x0) + 2 * p01 * x0 * x1 + p11 * (x1 * x1))
        empty = not (lo[i, 0] <= hi[i, 0] and lo[i, 1] <= hi[i, 1])
        out[i] = np.inf if empty else np.sqrt(best) * (1.0 + margin)
    return out
