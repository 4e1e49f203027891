"""Building the `IntervalKernel` that `box_kernels.substep` reads, from systems, parameter sets and controllers.

`IntervalModel` (through its `IntervalGroup`) precomputes, per hypothesis m and
action a, the z-form columns of the closed- and open-loop vertex matrices, the drift
and disturbance boxes, and the rigorous rounding-error bounds that move every bound
of the compiled arithmetic outward (see `IntervalModel`, Notes). Numpy only: the
compiled code is in `minimaxplan.planners.box_kernels`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..models.prediction import IntervalPredictor, interval_matvec, summation_error_bound
from ..models.system import UncertainLinearSystem
from .box_kernels import IntervalKernel
from .controllers import ControllerBank, LinearFeedback

__all__ = ["build_interval_kernel"]


def _z_matrix(matrices: np.ndarray) -> np.ndarray:
    """For matrices (..., m, n): ``[[M+^T, M-^T], [M-^T, M+^T]]`` of shape (..., 2n, 2m).

    With a box written ``z = [-lower | upper]`` (..., 2n), ``z @ result`` is the exact
    box of ``M x`` in the same form.
    """
    pos_t = np.swapaxes(np.maximum(matrices, 0.0), -1, -2)
    neg_t = np.swapaxes(np.maximum(-matrices, 0.0), -1, -2)
    top = np.concatenate([pos_t, neg_t], axis=-1)
    bottom = np.concatenate([neg_t, pos_t], axis=-1)
    return np.ascontiguousarray(np.concatenate([top, bottom], axis=-2))


def _columns(matrices: np.ndarray) -> np.ndarray:
    """`_z_matrix` as the compiled kernels read it: (..., 2n, 2m) for matrices (..., m, n), writable, contiguous."""
    return np.array(_z_matrix(matrices), dtype=float)


def _rounding_errors(
    systems, predictors, vertices, B, bank: ControllerBank, closed_abs, drift_z, w_z
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """The rigorous rounding-error bounds `box_kernels.substep` adds (see `IntervalModel`, Notes).

    Returns ``(closed_error, drift_error, opened_error, w_error, gain_error,
    offset_error, input_error, tiny)``. Every n-term sum of the kernel loses at most
    ``gamma_n`` times the sum of its terms' magnitudes (``gamma_n = 2 n u / (1 - n
    u)``, `minimaxplan.models.prediction`); with ``n`` the longest sum of a sub-step
    (its 2p products, the drift, the input terms, the error terms and the final
    additions), each bound below holds for every sum it covers.
    """
    p, q = B.shape[1], B.shape[2]
    safety = 1.0 + 1e-10  # covers the rounding in evaluating the bounds themselves
    g = summation_error_bound(2 * p + 2 * q + 8)
    tiny = (2 * p + 2 * q + 8) * 2.0 * np.finfo(float).smallest_subnormal  # underflow of every product
    abs_B = np.abs(B)  # (M, p, q)
    abs_K = np.abs(bank.gains)  # (A, q, p)
    formation = np.stack([predictor.vertex_matrix_error for predictor in predictors])  # (M, p, p)
    open_abs = np.max(np.abs(vertices), axis=1)  # (M, p, p), over the vertices
    opened_error = safety * (formation + g * open_abs)
    if closed_abs is None:
        closed_error = opened_error[:, None]
    else:  # A(v) - B K: the product B K (q terms) and the subtraction round too
        product_abs = np.einsum("mpq,aqr->mapr", abs_B, abs_K)
        closed_error = safety * (
            formation[:, None] + summation_error_bound(q + 1) * (open_abs[:, None] + product_abs) + g * closed_abs
        )
    # c_a = K x_ref + u_ff is computed in floating point for feedback controllers
    offset_error = np.zeros_like(bank.offsets)
    for a, controller in enumerate(bank.controllers):
        if isinstance(controller, LinearFeedback):
            offset_error[a] = summation_error_bound(p + 2) * (
                np.abs(controller.K) @ np.abs(controller.x_ref) + np.abs(controller.u_ff)
            )
    offset_error = safety * offset_error + tiny
    w_max = [np.maximum(np.abs(system.w.low), np.abs(system.w.high)) for system in systems]
    w_rounding = np.stack(
        [
            summation_error_bound(2 * system.ndisturbances + 1) * np.abs(system.D) @ wm
            for system, wm in zip(systems, w_max)
        ]
    )
    w_error = safety * (w_rounding + g * np.maximum(np.abs(w_z[:, :p]), np.abs(w_z[:, p:]))) + tiny
    drift_abs = np.maximum(np.abs(drift_z[..., :p]), np.abs(drift_z[..., p:]))  # (M, A, p)
    c_abs = np.abs(bank.offsets) + offset_error  # (A, q)
    drift_error = (
        safety
        * (
            summation_error_bound(q + 1) * np.einsum("mpq,aq->map", abs_B, c_abs)
            + np.einsum("mpq,aq->map", abs_B, offset_error)
            + w_rounding[:, None]
            + g * drift_abs
        )
        + tiny
    )
    gain_error = safety * g * abs_K
    input_error = safety * g * abs_B

    def columns(rows):  # the kernels apply row-indexed bounds by columns
        return np.ascontiguousarray(np.swapaxes(rows, -1, -2), dtype=float)

    def constant(values):
        return np.ascontiguousarray(values, dtype=float)

    return (
        columns(closed_error),
        constant(drift_error),
        columns(opened_error),
        constant(w_error),
        columns(gain_error),
        constant(offset_error),
        columns(input_error),
        float(tiny),
    )


def build_interval_kernel(
    systems: Sequence[UncertainLinearSystem], predictors: Sequence[IntervalPredictor], bank: ControllerBank
) -> IntervalKernel:
    """The `IntervalKernel` of M hypotheses (``systems[m]`` with ``predictors[m]``) under every controller of ``bank``.

    Parameters
    ----------
    systems
        The M systems, with equal numbers of states and inputs.
    predictors
        Their `IntervalPredictor` over each hypothesis's parameter set (the vertex
        matrices ``A(v_k)``; the identity basis).
    bank
        The controllers, one per action.

    Returns
    -------
    IntervalKernel
        The arrays documented in `minimaxplan.planners.box_kernels.substep`.

    Notes
    -----
    Each hypothesis is padded to the largest vertex count k by repeating one vertex
    matrix (harmless under the max over vertices). With feedback, the closed-loop
    vertex matrices are ``A(v_k) - B_m K_a`` per action; otherwise one action slot
    holds the open-loop ones. The rounding-error bounds are those of `IntervalModel`
    (Notes): every n-term sum loses at most ``gamma_n`` times its terms' magnitudes.
    """
    k = max(pred.nvertices for pred in predictors)
    # pad each hypothesis to k vertex matrices by repeating one (harmless under max)
    vertices = np.stack(
        [
            np.concatenate([pred.vertex_matrices, np.repeat(pred.vertex_matrices[:1], k - pred.nvertices, axis=0)])
            for pred in predictors
        ]
    )  # (M, k, p, p), identity basis
    B = np.stack([system.B for system in systems])  # (M, p, q)
    per_action = bank.has_feedback
    opened = _columns(vertices)  # (M, k, 2p, 2p)
    if per_action:
        feedback = np.einsum("mpq,aqr->mapr", B, bank.gains)  # B_m K_a
        closed_matrices = vertices[:, None] - feedback[:, :, None]  # (M, A, k, p, p)
        closed = _columns(closed_matrices)  # (M, A, k, 2p, 2p)
        closed_abs = np.max(np.abs(closed_matrices), axis=2)
    else:
        closed = np.ascontiguousarray(opened[:, None])  # (M, 1, k, 2p, 2p)
        closed_abs = None
    w = [interval_matvec(system.D, system.w.low, system.w.high) for system in systems]
    w_lo = np.stack([lo for lo, _ in w])
    w_hi = np.stack([hi for _, hi in w])
    w_z = np.concatenate([-w_lo, w_hi], axis=-1)  # (M, 2p)
    drift = np.einsum("mpq,aq->map", B, bank.offsets)  # (M, A, p): B_m c_a
    drift_z = np.concatenate([-drift, drift], axis=-1) + w_z[:, None]  # (M, A, 2p)
    offsets, low, high = (np.array(a, dtype=float) for a in (bank.offsets, bank.low, bank.high))
    errors = _rounding_errors(systems, predictors, vertices, B, bank, closed_abs, drift_z, w_z)
    return IntervalKernel(
        closed,
        opened,
        drift_z,
        w_z,
        _columns(bank.gains),
        _columns(B),
        offsets,
        low,
        high,
        bool(per_action),
        bool(bank.saturating),
        *errors,
    )
