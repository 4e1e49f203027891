"""Compiled bounds of 2 x 2 matrix families over boxes: the arithmetic of the traffic forecast's lateral step.

`minimaxplan.scenarios.traffic_models.forecast_traffic` propagates each vehicle's lateral
state ``(e, chi)`` (and its image in a per-vehicle basis) as a box, through matrices that
are affine or multi-affine in a box of parameters. Three operations, each over a batch of
rows, are the whole of that arithmetic:

* `interval_matvec`: the exact box of ``M z`` for one point matrix per row and ``z`` in a
  box (the interval product, the building block of the others);
* `vertex_bound`: the tightest box of ``M(p) z`` over the 8 vertices of a parameter box,
  ``M(p) = I + sum_i p_i B_i`` (the `IntervalPredictor` vertex bound, Section III of the
  paper: the map is affine in p, so the box over p is spanned by its vertices for each z,
  and the interval product covers z);
* `contraction_vertex_factor`: the largest ``||C A_k C^-1||_2^2`` over the 64 vertices of
  the contraction bound's multi-affine matrix (`minimaxplan.scenarios.lateral_contraction`,
  ``P = C' C``).

They were numpy expressions over small arrays, whose call overhead made up about a third
of a forecast's time (`benchmarks/results/commits/cea30b31cf01-39ffdf072809.md`). Each performs the same
floating-point operations in the same order as those numpy expressions did (left to
right, ``np.maximum``/``np.minimum`` semantics for NaN; on a tie between signed zeros
`minimaxplan.kernels.box_primitives` keeps the first argument where numpy keeps the
second, so a bound that is exactly zero may differ from numpy's in its sign only), so the
forecast's boxes are unchanged to the last bit on every scene compared
(`benchmarks/compare_forecast_commits.py`); the rounding outward that makes them sound
stays with the callers (`ROUND_MARGIN`, `CONTRACTION_MARGIN`).

Dead rows hold empty boxes (``inf``, ``-inf``): their products may be NaN, which
propagates as numpy's would; callers mask them.

Layer: numpy and numba only.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .box_primitives import maximum, minimum

__all__ = ["contraction_vertex_factor", "interval_matvec", "vertex_bound"]


@njit(cache=True)
def _product_row(m00, m01, m10, m11, l0, l1, h0, h1):
    """The exact box of ``M z``, ``z`` in ``[l, h]``: positive parts times the near end, negative times the far."""
    a00, a01, a10, a11 = maximum(m00, 0.0), maximum(m01, 0.0), maximum(m10, 0.0), maximum(m11, 0.0)
    n00, n01, n10, n11 = maximum(-m00, 0.0), maximum(-m01, 0.0), maximum(-m10, 0.0), maximum(-m11, 0.0)
    lo0 = a00 * l0 + a01 * l1 - n00 * h0 - n01 * h1
    lo1 = a10 * l0 + a11 * l1 - n10 * h0 - n11 * h1
    hi0 = a00 * h0 + a01 * h1 - n00 * l0 - n01 * l1
    hi1 = a10 * h0 + a11 * h1 - n10 * l0 - n11 * l1
    return lo0, lo1, hi0, hi1


@njit(cache=True)
def interval_matvec(matrices, lower, upper):
    """The exact interval product of one 2 x 2 matrix per row with one box per row, not rounded.

    Parameters
    ----------
    matrices : ndarray, shape (n, 2, 2)
    lower, upper : ndarray, shape (n, 2)
        The boxes ``[lower, upper]``.

    Returns
    -------
    tuple of ndarray, shape (n, 2)
        ``(lo, hi)``: the smallest box containing ``M z`` for every ``z`` of the row's box.
    """
    n = lower.shape[0]
    if matrices.shape != (n, 2, 2) or upper.shape[0] != n or lower.shape[1] != 2 or upper.shape[1] != 2:
        raise ValueError("interval_matvec: matrices (n, 2, 2), lower and upper (n, 2) must share n")
    out_lo, out_hi = np.empty((n, 2)), np.empty((n, 2))
    for r in range(n):
        m = matrices[r]
        lo0, lo1, hi0, hi1 = _product_row(
            m[0, 0], m[0, 1], m[1, 0], m[1, 1], lower[r, 0], lower[r, 1], upper[r, 0], upper[r, 1]
        )
        out_lo[r, 0], out_lo[r, 1], out_hi[r, 0], out_hi[r, 1] = lo0, lo1, hi0, hi1
    return out_lo, out_hi


@njit(cache=True)
def vertex_bound(structure, lower, upper, p_lower, p_upper):
    """The tightest box of ``(I + sum_i p_i B_i) z`` over the vertices of the parameter box, not rounded.

    Parameters
    ----------
    structure : ndarray, shape (n, 3, 2, 2) or (1, 3, 2, 2)
        ``B_1, B_2, B_3`` per row (one set shared by every row when the first axis is 1).
    lower, upper : ndarray, shape (n, 2)
        The boxes of ``z``.
    p_lower, p_upper : ndarray, shape (n, 3)
        The parameter box per row.

    Returns
    -------
    tuple of ndarray, shape (n, 2)
        ``(lo, hi)``: the hull over the 8 vertices (vertex k takes ``p_i`` at its upper end
        where bit i of k is set) of the exact interval products.
    """
    n = lower.shape[0]
    if structure.shape[0] not in (1, n) or structure.shape[1:] != (3, 2, 2):
        raise ValueError("vertex_bound: structure must have shape (n or 1, 3, 2, 2)")
    if upper.shape[0] != n or p_lower.shape[0] != n or p_upper.shape[0] != n:
        raise ValueError(
            "vertex_bound: structure (n or 1, 3, 2, 2), boxes (n, 2) and parameter boxes (n, 3) must share n"
        )
    if lower.shape[1] != 2 or upper.shape[1] != 2 or p_lower.shape[1] != 3 or p_upper.shape[1] != 3:
        raise ValueError("vertex_bound: boxes must have 2 columns and parameter boxes 3")
    shared = structure.shape[0] == 1
    out_lo, out_hi = np.empty((n, 2)), np.empty((n, 2))
    for r in range(n):
        b = structure[0] if shared else structure[r]
        l0, l1, h0, h1 = lower[r, 0], lower[r, 1], upper[r, 0], upper[r, 1]
        best_lo0 = best_lo1 = best_hi0 = best_hi1 = 0.0
        for k in range(8):
            p0 = p_upper[r, 0] if k & 1 else p_lower[r, 0]
            p1 = p_upper[r, 1] if k & 2 else p_lower[r, 1]
            p2 = p_upper[r, 2] if k & 4 else p_lower[r, 2]
            lo0, lo1, hi0, hi1 = _product_row(
                p0 * b[0, 0, 0] + p1 * b[1, 0, 0] + p2 * b[2, 0, 0] + 1.0,
                p0 * b[0, 0, 1] + p1 * b[1, 0, 1] + p2 * b[2, 0, 1],
                p0 * b[0, 1, 0] + p1 * b[1, 1, 0] + p2 * b[2, 1, 0],
                p0 * b[0, 1, 1] + p1 * b[1, 1, 1] + p2 * b[2, 1, 1] + 1.0,
                l0,
                l1,
                h0,
                h1,
            )
            if k == 0:
                best_lo0, best_lo1, best_hi0, best_hi1 = lo0, lo1, hi0, hi1
            else:
                best_lo0, best_lo1 = minimum(best_lo0, lo0), minimum(best_lo1, lo1)
                best_hi0, best_hi1 = maximum(best_hi0, hi0), maximum(best_hi1, hi1)
        out_lo[r, 0], out_lo[r, 1], out_hi[r, 0], out_hi[r, 1] = best_lo0, best_lo1, best_hi0, best_hi1
    return out_lo, out_hi


@njit(cache=True)
def contraction_vertex_factor(metric, lower, upper, dt, length):
    """``max_k ||C A_k C^-1||_2^2`` per row over the 64 vertices of the contraction bound's matrix, not rounded.

    Parameters
    ----------
    metric : ndarray, shape (n, 2, 2)
        Symmetric positive definite ``P = C' C`` per row (C upper triangular).
    lower, upper : ndarray, shape (n, 6)
        The box of ``(s1, s2, g, v, b1, q)`` per row (`minimaxplan.scenarios.lateral_contraction`).
    dt, length : float
        The step (s) and the wheelbase L (m).

    Returns
    -------
    ndarray, shape (n,)
        The largest squared spectral norm over the vertices of ``C A C^-1`` with::

            A = [[1 - dt s1 g L q,   dt s1 (v - g L b1)],
                 [  - 2 dt s2 g q,   1 - 2 dt s2 g b1  ]]

        (the closed form ``(f + sqrt(f^2 - 4 det^2)) / 2``, f the squared Frobenius norm).

    Notes
    -----
    The vertices are visited in nested loops, each product computed in the loop of the
    last coordinate it depends on (``(s2, g, q)`` outermost, ``v`` innermost), so that a
    vertex costs the operations of ``v`` alone. Every value is the same floating-point
    expression, evaluated left to right, as the formula above written per vertex (tested
    to the bit), and the maximum does not depend on the order of the vertices.
    """
    n = metric.shape[0]
    if (
        metric.shape[1:] != (2, 2)
        or lower.shape[0] != n
        or upper.shape[0] != n
        or lower.shape[1] != 6
        or upper.shape[1] != 6
    ):
        raise ValueError("contraction_vertex_factor: metric (n, 2, 2), lower and upper (n, 6)")
    out = np.empty(n)
    for r in range(n):
        p11, p12, p22 = metric[r, 0, 0], metric[r, 0, 1], metric[r, 1, 1]
        c11, c12, c22 = np.sqrt(p11), p12 / np.sqrt(p11), np.sqrt(p22 - p12 * p12 / p11)
        best = 0.0
        first = True
        for i_s2 in range(2):
            s2 = upper[r, 1] if i_s2 else lower[r, 1]
            minus_2dt_s2 = -2.0 * dt * s2
            plus_2dt_s2 = 2.0 * dt * s2
            for i_g in range(2):
                g = upper[r, 2] if i_g else lower[r, 2]
                minus_2dt_s2_g, plus_2dt_s2_g, g_length = minus_2dt_s2 * g, plus_2dt_s2 * g, g * length
                for i_q in range(2):
                    q = upper[r, 5] if i_q else lower[r, 5]
                    a21 = minus_2dt_s2_g * q
                    # C A = [[c11 a11 + c12 a21, c11 a12 + c12 a22], [c22 a21, c22 a22]];
                    # C^-1 = [[1/c11, -c12/(c11 c22)], [0, 1/c22]]
                    u21 = c22 * a21
                    m10 = u21 / c11
                    u21_c = u21 * c12 / c11
                    for i_s1 in range(2):
                        s1 = upper[r, 0] if i_s1 else lower[r, 0]
                        dt_s1 = dt * s1
                        a11 = 1.0 - dt_s1 * g * length * q
                        u11 = c11 * a11 + c12 * a21
                        m00 = u11 / c11
                        u11_c = u11 * c12 / c11
                        for i_b1 in range(2):
                            b1 = upper[r, 4] if i_b1 else lower[r, 4]
                            a22 = 1.0 - plus_2dt_s2_g * b1
                            m11 = (c22 * a22 - u21_c) / c22
                            g_length_b1 = g_length * b1
                            c12_a22 = c12 * a22
                            for i_v in range(2):
                                v = upper[r, 3] if i_v else lower[r, 3]
                                a12 = dt_s1 * (v - g_length_b1)
                                m01 = (c11 * a12 + c12_a22 - u11_c) / c22
                                f = m00 * m00 + m01 * m01 + m10 * m10 + m11 * m11
                                det = m00 * m11 - m01 * m10
                                value = 0.5 * (f + np.sqrt(maximum(f * f - 4.0 * (det * det), 0.0)))
                                best = value if first else maximum(best, value)
                                first = False
        out[r] = best
    return out
