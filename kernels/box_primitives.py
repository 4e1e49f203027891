"""Scalar box primitives for compiled code: NaN-propagating min/max and the one box-disc gap.

Every compiled box computation of the project (the planner's interval arithmetic in
`minimaxplan.planners.box_kernels`, the reward families' box minima in
`minimaxplan.scenarios.compiled_rewards`, the obstacle geometry of
`minimaxplan.scenarios.geometry`) takes its maxima, minima and box-to-disc gaps from
here, so that the compiled and the numpy-facing forms perform the same floating-point
operations.

All functions are ``numba.njit``. The scalar ones are ordinary compiled functions, which LLVM inlines
into their compiled callers (not ``inline="always"``: numba's own inliner copies the callee's IR at each
call site, which cost seconds of the first run's compile, see benchmarks/bench_cold_start.py).
"""

from __future__ import annotations

from numba import njit

__all__ = ["box_gap_sq", "box_gaps_sq", "maximum", "minimum"]


@njit(cache=True)
def maximum(a: float, b: float) -> float:
    """``np.maximum`` of two floats: the larger, NaN if either is NaN.

    Parameters
    ----------
    a, b
        Floats.

    Returns
    -------
    float
        ``a`` when ``a >= b`` or ``a`` is NaN, else ``b``. On a tie numpy returns ``b``:
        the two differ only in the sign of a zero (``maximum(-0.0, 0.0)`` is -0.0 here,
        0.0 in numpy); `minimaxplan.kernels.lateral_bounds` has numpy's tie rule where
        its results must be numpy's to the bit.
    """
    return a if (a >= b or a != a) else b


@njit(cache=True)
def minimum(a: float, b: float) -> float:
    """``np.minimum`` of two floats: the smaller, NaN if either is NaN.

    Parameters
    ----------
    a, b
        Floats.

    Returns
    -------
    float
        ``a`` when ``a <= b`` or ``a`` is NaN, else ``b``. On a tie numpy returns ``b``:
        the two differ only in the sign of a zero (``minimum(0.0, -0.0)`` is 0.0 here,
        -0.0 in numpy).
    """
    return a if (a <= b or a != a) else b


@njit(cache=True)
def box_gap_sq(low_x, low_y, high_x, high_y, other_low_x, other_low_y, other_high_x, other_high_y) -> float:
    """The squared distance between two planar boxes (0 when they meet): the one box-disc gap.

    Parameters
    ----------
    low_x, low_y, high_x, high_y
        The box ``[low, high]`` (e.g. a box of robot positions).
    other_low_x, other_low_y, other_high_x, other_high_y
        The other box: a disc's centre as a degenerate box ``[c, c]``, or the predicted
        box of a moving disc's centre.

    Returns
    -------
    float
        ``gap_x^2 + gap_y^2`` with ``gap = max(low - other_high, other_low - high, 0)``
        per axis (at most one of the two differences is positive when both boxes are
        ordered); NaN propagates.

    Notes
    -----
    A disc of radius r centred anywhere in the box meets a disc of radius R centred
    anywhere in the other box iff this is at most ``(r + R)^2`` (closed sets: touching
    counts). This is the collision test beta(x) = 0 of the paper's robot reward
    (Section IV) over a box, exact rather than on four corners (DESIGN.md, Errata).
    """
    gap_x = maximum(maximum(low_x - other_high_x, other_low_x - high_x), 0.0)
    gap_y = maximum(maximum(low_y - other_high_y, other_low_y - high_y), 0.0)
    return gap_x * gap_x + gap_y * gap_y


@njit(cache=True)
def box_gaps_sq(lower, upper, other_lower, other_upper, out) -> None:
    """`box_gap_sq` of row pairs: ``out[k]`` for boxes ``k`` of four (K, 2) float64 arrays.

    Parameters
    ----------
    lower, upper, other_lower, other_upper
        C-contiguous float64 arrays of shape (K, 2).
    out
        Float64 array of shape (K,), written.
    """
    for k in range(out.shape[0]):
        out[k] = box_gap_sq(
            lower[k, 0],
            lower[k, 1],
            upper[k, 0],
            upper[k, 1],
            other_lower[k, 0],
            other_lower[k, 1],
            other_upper[k, 0],
            other_upper[k, 1],
        )
