"""Compiled (numba) interval arithmetic of `IntervalModel` and the pessimistic rewards of its boxes.

The one implementation of the box transition: `IntervalModel.expand` and `rollout`
call `propagate`, and the compiled search (`minimaxplan.planners.compiled_search`)
calls the same functions, so both engines compute the same boxes bit for bit.

A box is stored as ``z = [-lower | upper]`` (2p,). For a fixed matrix ``M`` the exact
box of ``{M x : lower <= x <= upper}`` is ``z @ Z(M)`` with ``Z(M) = [[M+^T, M-^T],
[M-^T, M+^T]]`` (``M+ = max(M, 0)``, ``M- = max(-M, 0)``), and the box over k vertex
matrices is the elementwise max of the k products. Each sum is accumulated in index
order without fast-math reassociation (numba's default), so results do not depend on
the machine's BLAS. Every bound is then moved outward by a rigorous bound on its
rounding error (precomputed columns applied to the box's magnitudes, see
`IntervalModel`), so the boxes contain the exact reachable sets, not just up to a
tolerance.

Compiled rewards
----------------
A reward's exact box minimum reaches these kernels through the compiled-reward
protocol of `minimaxplan.kernels.reward_protocol` (``kernel_params`` and an overload
of `box_reward_minimum`): the planner never imports the family, it passes the params
object through, and numba picks the implementation from its type.
"""

from __future__ import annotations

import functools
import math
from collections import namedtuple
from typing import Any

import numpy as np
from numba import njit

from ..kernels import box_primitives
from ..kernels.box_primitives import maximum as _maximum
from ..kernels.box_primitives import minimum as _minimum
from ..kernels.reward_protocol import (
    box_reward_minimum,
    compile_per_params_type,
    minimum_sources,
    sources_digest,
)

__all__ = ["IntervalKernel", "SCRATCH_ROWS", "propagate", "propagate_into", "scratch_width", "stack_rewards_kernel"]

# numba's disk cache checks only a function's own source file: the kernels below call into
# `box_primitives` (compiled into their cached code), so they close over its digest and recompile when it changes.
_PRIMITIVES_VERSION = sources_digest(box_primitives.__file__)

# The box code is compiled once, as one internal function (`_step`), with its helpers as internal
# functions too: no Python wrapper, no reference counting (they allocate nothing), no numba inlining
# (LLVM inlines them). numba's inliner (``inline="always"``) copies the callee's IR block by block with
# its whole variable scope: compiling `substep` and `propagate` with the box code inlined into each took
# 18.6 s of the first plan's 28.4 s of CPU, and gave a slower kernel (see benchmarks/bench_cold_start.py).
_INTERNAL: dict[str, Any] = {"no_cpython_wrapper": True, "no_cfunc_wrapper": True, "_nrt": False}
# No kernel builds numba's C wrapper (for first-class function values, unused here): one function less to emit.
_CACHED: dict[str, Any] = {"cache": True, "no_cfunc_wrapper": True}


IntervalKernel = namedtuple(
    "IntervalKernel",
    [
        "closed",
        "opened",
        "drift",
        "w",
        "gains",
        "inputs",
        "offsets",
        "low",
        "high",
        "per_action",
        "saturating",
        "closed_error",
        "drift_error",
        "opened_error",
        "w_error",
        "gain_error",
        "offset_error",
        "input_error",
        "tiny",
    ],
)
IntervalKernel.__doc__ = (
    """The precomputed arrays of `substep` (built by `IntervalModel`; see `substep` for each field)."""
)


@njit(**_INTERNAL)
def _vertex_bound(z, columns, out, total):
    """``out[j] = max_v sum_i columns[v, i, j] z[i]``: the box over k vertex matrices (columns (k, 2p, 2p)).

    Each sum runs over i in order; the loop over j is innermost, so the 2p sums
    advance together (vectorisable without reordering any sum). ``total`` is a (2p,)
    work array.
    """
    n = z.shape[0]
    for j in range(n):
        out[j] = -np.inf
    for v in range(columns.shape[0]):
        for j in range(n):
            total[j] = 0.0
        for i in range(n):
            zi = z[i]
            for j in range(n):
                total[j] += columns[v, i, j] * zi
        for j in range(n):
            out[j] = _maximum(out[j], total[j])


@njit(**_INTERNAL)
def _add_products(columns, vector, out):
    """``out[j] += sum_i columns[i, j] vector[i]``, the sum over i in order."""
    for i in range(columns.shape[0]):
        vi = vector[i]
        for j in range(columns.shape[1]):
            out[j] += columns[i, j] * vi


@njit(**_INTERNAL)
def _magnitudes(z, mag):
    """``mag[i] = max(|lower_i|, |upper_i|)``, a bound on |x_i| over the box (NaN propagates)."""
    p = mag.shape[0]
    for i in range(p):
        mag[i] = _maximum(abs(z[i]), abs(z[p + i]))


@njit(**_INTERNAL)
def _step(z, m, slot, a, core, out, error, scratch, linear, finish):
    """`substep`'s arithmetic on box ``z`` (2p,) of hypothesis m under controller a, in two parts.

    With ``linear``: ``out = max_v Z(M_v) z`` for the closed loop's vertex matrices of
    action slot ``slot``, and ``error`` (p,) its rounding bound before the drift. With
    ``finish``: the rest, on ``out`` (``error`` read only): the drift, the bounds, the
    saturation path. `substep` runs both; `propagate`'s open loop without saturation
    runs the first part once per hypothesis and the second per action: one compiled
    function for every caller, so the box code compiles once.
    """
    p = z.shape[0] // 2
    mag = scratch[4, :p]  # the box's magnitudes (the saturation path reads them)
    if linear:
        total = scratch[5, : 2 * p]
        _magnitudes(z, mag)
        _vertex_bound(z, core.closed[m, slot], out, total)
        for j in range(p):
            error[j] = 0.0
        _add_products(core.closed_error[m, slot], mag, error)
    if not finish:
        return
    (
        closed,
        opened,
        drift,
        w,
        gains,
        inputs,
        offsets,
        low,
        high,
        per_action,
        saturating,
        closed_error,
        drift_error,
        opened_error,
        w_error,
        gain_error,
        offset_error,
        input_error,
        tiny,
    ) = core
    n = 2 * p
    for j in range(p):
        bound = error[j] + drift_error[m, a, j]
        out[j] += drift[m, a, j] + bound
        out[p + j] += drift[m, a, p + j] + bound
    if not saturating:
        return
    q = offsets.shape[1]
    kx = scratch[0, : 2 * q]
    for r in range(2 * q):
        kx[r] = 0.0
    _add_products(gains[a], z, kx)  # [-(K x)_lo | (K x)_hi] over the box
    gain_rounding = scratch[7, :q]
    for r in range(q):
        gain_rounding[r] = tiny
    _add_products(gain_error[a], mag, gain_rounding)
    correction = scratch[1, : 2 * q]
    applied = scratch[2, : 2 * q]
    for r in range(q):
        # v = c - K x over the box, each bound moved outward past its rounding and c's
        v_lo = math.nextafter(offsets[a, r] - (kx[q + r] + gain_rounding[r]), -math.inf)
        v_lo = math.nextafter(v_lo - offset_error[a, r], -math.inf)
        v_hi = math.nextafter(offsets[a, r] + (kx[r] + gain_rounding[r]), math.inf)
        v_hi = math.nextafter(v_hi + offset_error[a, r], math.inf)
        u_lo = _minimum(_maximum(v_lo, low[a, r]), high[a, r])
        u_hi = _minimum(_maximum(v_hi, low[a, r]), high[a, r])
        # s(v) = sat(v) - v is nonincreasing: s in [u_hi - v_hi, u_lo - v_lo]; u in [u_lo, u_hi]
        correction[r] = math.nextafter(v_hi - u_hi, math.inf)
        correction[q + r] = math.nextafter(u_lo - v_lo, math.inf)
        applied[r] = -u_lo
        applied[q + r] = u_hi
    through = scratch[3, :n]
    input_mag = scratch[0, :q]  # kx is no longer needed
    _magnitudes(correction, input_mag)
    for j in range(n):
        through[j] = 0.0
    _add_products(inputs[m], correction, through)
    input_rounding = scratch[8, :p]
    for j in range(p):
        input_rounding[j] = tiny
    _add_products(input_error[m], input_mag, input_rounding)
    for j in range(p):
        out[j] += through[j] + input_rounding[j]
        out[p + j] += through[p + j] + input_rounding[j]
    open_box = scratch[1, :n]  # the correction is no longer needed
    _vertex_bound(z, opened[m], open_box, scratch[5, :n])
    _magnitudes(applied, input_mag)
    for j in range(n):
        through[j] = 0.0
    _add_products(inputs[m], applied, through)
    open_rounding = scratch[8, :p]
    for j in range(p):
        open_rounding[j] = w_error[m, j]
    _add_products(opened_error[m], mag, open_rounding)
    _add_products(input_error[m], input_mag, open_rounding)
    for j in range(p):
        out[j] = _minimum(out[j], open_box[j] + w[m, j] + through[j] + open_rounding[j])
        out[p + j] = _minimum(out[p + j], open_box[p + j] + w[m, p + j] + through[p + j] + open_rounding[j])


def _make_substep(version: int):
    """`substep`, compiled with a cache key that covers `minimaxplan.kernels.box_primitives`."""

    def substep(z, m, a, core, out, scratch):
        """One sub-step of hypothesis m's box ``z`` under controller a, written to ``out`` (2p,), rounded outward.

        ``core`` is the `IntervalKernel` that `IntervalModel` precomputes, in the z-form's
        column layout (``M x`` is ``sum_i column_i x_i``):

        - ``closed`` (M, A or 1, k, 2p, 2p): Z-form columns of the closed-loop vertex
          matrices ``A(v) - B_m K_a`` (one action slot when no controller has feedback);
        - ``opened`` (M, k, 2p, 2p): the open-loop vertex matrices ``A(v)``;
        - ``drift`` (M, A, 2p): ``B_m c_a`` plus the disturbance box ``D w``, z-form;
        - ``w`` (M, 2p): the disturbance box alone; ``gains`` (A, 2p, 2q) and ``inputs``
          (M, 2q, 2p): Z-form columns of ``K_a`` and ``B_m``;
        - ``offsets``, ``low``, ``high`` (A, q): ``u = clip(c_a - K_a x, low_a, high_a)``;
        - the ``*_error`` arrays: rigorous bounds on the rounding of each part, as columns
          applied to the box's magnitudes (``closed_error`` (M, A or 1, p, p),
          ``opened_error`` (M, p, p), ``gain_error`` (A, p, q), ``input_error`` (M, q, p))
          or constants (``drift_error`` (M, A, p), ``w_error`` (M, p), ``offset_error`` (A, q),
          ``tiny`` for underflow); see `IntervalModel` (Notes) for how they are formed.

        Without saturation: ``Z(A(v) - B K) z`` maximised over vertices, plus the drift,
        plus the error bound. With saturation (see `IntervalModel`): that box plus ``B
        s(v)`` with the saturation correction's interval, intersected with the open-loop
        box ``A(theta) x + B sat(v) + D w``; the scalar steps of the correction are moved
        one ulp outward. ``scratch`` is a (11, max(2p, 2q)) work array.
        """
        _ = version  # ties numba's cache entry to the box primitives' source (see _PRIMITIVES_VERSION)
        slot = a if core.per_action else np.int64(0)
        yes = np.bool_(True)  # not a literal: the same typing of `_step` as `propagate`'s
        _step(z, m, slot, a, core, out, scratch[6, : z.shape[0] // 2], scratch, yes, yes)

    return njit(**_CACHED)(substep)


substep = _make_substep(_PRIMITIVES_VERSION)


#: The rows of the work array of `propagate_into` (its width: `scratch_width`).
SCRATCH_ROWS = 11


@njit(inline="always")
def scratch_width(core, n_box):
    """The width of `propagate_into`'s work array for boxes of ``n_box`` = 2p numbers: ``max(2p, 2q)``.

    Parameters
    ----------
    core : IntervalKernel
        The transition's arrays.
    n_box : int
        2p.

    Returns
    -------
    int
    """
    return max(n_box, 2 * core.offsets.shape[1])


@njit(inline="always")
def propagate_into(z0, actions, core, stack, scratch):
    """Every sub-step of every (hypothesis, action) from the boxes ``z0`` into ``stack`` (compiled code only).

    `propagate` with the caller's work array: the compiled search allocates it once
    per search, not once per expansion (numba inlines this loop into both callers).

    Parameters
    ----------
    z0 : ndarray (R, 2p)
        One box per hypothesis (R = M) or one shared box (R = 1).
    actions : ndarray (n,) of int64
        Controller indices.
    core : IntervalKernel
        The transition's arrays.
    stack : ndarray (S, M, n, 2p)
        Receives the box after each sub-step s.
    scratch : ndarray (SCRATCH_ROWS, scratch_width(core, 2p))
        Work array (overwritten).
    """
    n_sub, n_models, n_actions, n = stack.shape
    # Open loop without saturation: the first sub-step's product is the same for every action
    shared = not core.per_action and not core.saturating
    base, base_error = scratch[9, :n], scratch[10, : n // 2]
    error = scratch[6, : n // 2]
    # an int64 and bools, not literals: one typing of `_step` for every call
    no_slot, yes, no = np.int64(0), np.bool_(True), np.bool_(False)
    for m in range(n_models):
        start = z0[m if z0.shape[0] > 1 else 0]
        if shared:
            _step(start, m, no_slot, no_slot, core, base, base_error, scratch, yes, no)
        for i in range(n_actions):
            a = actions[i]
            slot = a if core.per_action else no_slot
            source = start
            first = 0
            if shared:
                out = stack[0, m, i]
                for j in range(n):
                    out[j] = base[j]
                _step(start, m, no_slot, a, core, out, base_error, scratch, no, yes)
                source = out
                first = 1
            for s in range(first, n_sub):
                _step(source, m, slot, a, core, stack[s, m, i], error, scratch, yes, yes)
                source = stack[s, m, i]


def _make_propagate(version: int):
    """`propagate`, compiled with a cache key that covers `minimaxplan.kernels.box_primitives`."""

    def propagate(z0, actions, core, stack):
        """Every sub-step of every (hypothesis, action) from the boxes ``z0`` into ``stack``.

        ``z0`` (R, 2p) holds one box per hypothesis (R = M) or one shared box (R = 1);
        ``actions`` (n,) are controller indices; ``stack`` (S, M, n, 2p) receives the box
        after each sub-step s (`propagate_into` with a work array of its own).
        """
        _ = version  # ties numba's cache entry to the box primitives' source (see _PRIMITIVES_VERSION)
        scratch = np.empty((SCRATCH_ROWS, scratch_width(core, stack.shape[3])))
        propagate_into(z0, actions, core, stack, scratch)

    return njit(**_CACHED)(propagate)


propagate = _make_propagate(_PRIMITIVES_VERSION)


# Inlined by numba into its two callers (the search kernel and `stack_rewards_kernel`'s loop), each
# compiled per reward family anyway: no library of its own to optimise and emit, then again in the caller
# (measured: 0.2-0.5 s less CPU per family). Reference counting kept: a reward family's kernel may allocate.
_COMPILED_ONLY: dict[str, Any] = {"no_cpython_wrapper": True, "no_cfunc_wrapper": True, "inline": "always"}


def reward_sources(params_type: type) -> list[str]:
    """The source files a compiled reward call from here depends on: this module and `minimum_sources`'s."""
    return [__file__, *minimum_sources(params_type)]


@njit(**_COMPILED_ONLY)
def pessimistic_rewards(stack, time, params, rewards, collided):
    """Pessimistic rewards of the boxes of `propagate`: the minimum over the sub-steps.

    ``rewards[m, i] = min_s box_reward_minimum(stack[s, m, i], time + s + 1)`` (0 at a
    sub-step whose box may collide), ``collided[m, i]`` whether any sub-step's box may.
    Not cached itself (it calls the reward family's overload): callers cache it
    through a factory keyed by `sources_digest`, as `stack_rewards_kernel` does.
    Compiled code only: numba inlines it into its callers, the compiled search and
    `stack_rewards_kernel` (reference counting stays on for rewards that allocate).
    """
    n_sub, n_models, n_actions, n = stack.shape
    p = n // 2
    for m in range(n_models):
        for i in range(n_actions):
            worst = 0.0
            hit = False
            for s in range(n_sub):
                value, collides = box_reward_minimum(params, stack[s, m, i], p, float(time + s + 1))
                if collides:
                    value = 0.0
                    hit = True
                worst = value if s == 0 else _minimum(worst, value)
            rewards[m, i] = worst
            collided[m, i] = hit


@functools.cache
def stack_rewards_kernel(params_type: type):
    """`pessimistic_rewards`, compiled and cached for rewards whose ``kernel_params`` have type ``params_type``."""
    version = sources_digest(*reward_sources(params_type))

    def stack_rewards(stack, time, params, rewards, collided):
        _ = version  # ties numba's cache entry to the sources it calls into
        pessimistic_rewards(stack, time, params, rewards, collided)

    return compile_per_params_type(stack_rewards, params_type, what="the interval model's pessimistic-reward kernel")
