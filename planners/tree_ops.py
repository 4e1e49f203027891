"""The tree operations of the robust optimistic search, written once, compiled with numba.

Both engines of `RobustTreePlanner` build their look-ahead tree in one array layout,
`TreeArrays`, with the functions of this module: leaf selection (`select`), the
creation of a leaf's children (`add_children`, with the terminal handling and the
reward-range check of `expand`), the back-up of the bounds (`backup`) and the walk of
the decision (`best_path`). The engines differ only in how a leaf's transitions are
obtained: the compiled engine (`minimaxplan.planners.compiled_search`) computes them
with the compiled box kernel inside one whole-search kernel that calls these
functions; the Python engine (`minimaxplan.planners.search`) asks the models of the
protocol (`minimaxplan.planners.protocols`) in a Python loop that calls
`expand_and_select` once per expansion.

Layout
------
Nodes are numbered in creation order; node 0 is the root. The ``n_actions`` children
of a node are created together, so they are contiguous: ``first_child[i] + a`` is the
child reached by action index ``a``. A transition's inputs are written by the engine
into ``rewards`` and ``new_terminal`` (shape ``(M, n_actions)``) before `expand`.

The frontier is a binary heap of the leaves (``heap[:counts[HEAP_SIZE]]``) ordered by
b-value, largest first, ties by action path, lexicographically smallest first. No
leaf's path is a prefix of another's, so this order is total; ties are resolved by
walking both paths up to their deepest common ancestor (ties are rare, paths short).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

__all__ = [
    "TreeArrays",
    "allocate",
    "grow",
    "discount_table",
    "reset",
    "select",
    "expand",
    "add_children",
    "backup",
    "best_path",
    "start",
    "expand_and_select",
    "SIZE",
    "HEAP_SIZE",
    "N_EXPANDED",
    "MAX_DEPTH",
    "NO_LEAF",
    "REWARD_ERROR",
]

#: Indices into ``TreeArrays.counts``.
SIZE, HEAP_SIZE, N_EXPANDED, MAX_DEPTH = 0, 1, 2, 3
#: `select` and `expand_and_select`: no leaf to expand (the root's bounds met, or no selection asked).
NO_LEAF = -1
#: `expand_and_select` returns ``REWARD_ERROR - k`` for a reward outside [0, 1] at flat pair ``k = a * M + m``.
REWARD_ERROR = -2

# The operations are compiled without numba's reference counting (they allocate nothing): each read of
# an array field of `TreeArrays` would otherwise cost an atomic increment and decrement, which the
# compiled search pays on every expansion (measured: +15% on a whole search with M = |A| = 4, one
# sub-step). The entry points called from Python (`start`, `expand_and_select`) keep it, and only they
# have a Python wrapper: the others are called from compiled code only (a wrapper unboxing the 18 fields
# of `TreeArrays` is compiled for nothing; see benchmarks/bench_cold_start.py). No function has a C
# wrapper (``no_cfunc_wrapper``: that is for numba's first-class function values, which nothing here
# uses; each is one more function for LLVM to optimise and emit).
#
# Each compiled function is a library of its own, which numba optimises and turns into machine code,
# then again inside every compiled caller above it (the caller links it in and optimises the whole). The
# functions with a single call site are therefore inlined by numba into it (``inline="always"``):
# `reset` (into the search kernel and `start`), `add_children` and `backup` (into `expand`), `_heap_pop`
# (into `select`), `_heap_push` (into `add_children`); measured, 0.4-0.5 s less CPU for the compiled
# engine's first plan. numba's inliner copies the callee's IR with its whole scope at each call site, so
# the functions called from several places (`_before`, `select`, `expand`) stay functions of their own.
_NO_REFCOUNTS: dict[str, Any] = {"cache": True, "_nrt": False, "no_cpython_wrapper": True, "no_cfunc_wrapper": True}
_INTERNAL: dict[str, Any] = {"no_cpython_wrapper": True, "no_cfunc_wrapper": True, "_nrt": False}
_ENTRY: dict[str, Any] = {"cache": True, "no_cfunc_wrapper": True}
_INLINED: dict[str, Any] = {**_INTERNAL, "inline": "always"}


class TreeArrays(NamedTuple):
    """The look-ahead tree of one search, as arrays of ``capacity`` rows (valid up to ``counts[SIZE]``).

    Attributes
    ----------
    returns : ndarray (capacity, M)
        ``R_m(i) = sum_{n < depth(i)} gamma^n r_n^m`` along the path to node i.
    terminal : ndarray (capacity, M) of bool
        Whether model m made a terminal transition on the path to node i.
    parent, action, depth, first_child : ndarray (capacity,) of int64
        ``parent[0] = action[0] = -1``; ``first_child[i] = -1`` for a leaf.
    leaf_lower, leaf_upper : ndarray (capacity,)
        The leaf bounds of each node as computed when it was created, which never
        change: ``min_m (R_m + gamma^l F_m [m not terminated])`` (eq. (18), with the
        continuation bound F_m of ``fallback``; 0 unless the models give one) and the
        robust b-value ``min_m (R_m + gamma^l / (1 - gamma) [m not terminated])``
        (eq. (16)).
    lower, upper : ndarray (capacity,)
        Backed-up bounds: the leaf bounds at a leaf; at an internal node the max over
        the children (eqs. (17), (18)), and for ``lower`` at least the node's own leaf
        bound (the continuation bound of a node is not always met by its children's
        after rounding).
    any_terminated : ndarray (capacity,) of bool
        ``terminal[i].any()``.
    expanded : ndarray (capacity,) of int64
        The expanded nodes in expansion order (``counts[N_EXPANDED]`` of them).
    heap : ndarray (capacity,) of int64
        The frontier (see the module docstring).
    discounts : ndarray (D,)
        ``discounts[d] = gamma ** d`` as Python computes it (`discount_table`), for
        every depth the tree can reach plus one.
    rewards : ndarray (M, n_actions)
        The transition's rewards, written by the engine before `expand`.
    new_terminal : ndarray (M, n_actions) of bool
        Whether each transition was terminal, written with ``rewards``.
    fallback : ndarray (M, n_actions)
        F_m: a lower bound, in ``[0, 1 / (1 - gamma)]``, of model m's discounted return
        from each transition's next state under some fixed continuation of actions
        (`minimaxplan.planners.protocols.FallbackModel`), written with ``rewards``; 0
        (the paper's bound) when the models give none.
    counts : ndarray (4,) of int64
        ``[size, heap size, expansions, max depth]`` (indices `SIZE`, `HEAP_SIZE`,
        `N_EXPANDED`, `MAX_DEPTH`).
    gamma : float
        The discount factor in (0, 1).
    """

    returns: np.ndarray
    terminal: np.ndarray
    parent: np.ndarray
    action: np.ndarray
    depth: np.ndarray
    first_child: np.ndarray
    leaf_lower: np.ndarray
    leaf_upper: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    any_terminated: np.ndarray
    expanded: np.ndarray
    heap: np.ndarray
    discounts: np.ndarray
    rewards: np.ndarray
    new_terminal: np.ndarray
    fallback: np.ndarray
    counts: np.ndarray
    gamma: float


def discount_table(gamma: float, n: int) -> np.ndarray:
    """``[gamma ** d for d < n]``, each power computed by Python (the values both engines use).

    Parameters
    ----------
    gamma : float
        The discount factor in (0, 1).
    n : int
        The number of powers.
    """
    return np.array([gamma**d for d in range(n)], dtype=float)


def allocate(capacity: int, n_models: int, n_actions: int, gamma: float, discounts: np.ndarray) -> TreeArrays:
    """Empty `TreeArrays` of ``capacity`` rows (call `reset` before use).

    ``discounts`` must hold at least ``(capacity - 1) // n_actions + 2`` powers (the
    deepest child's depth plus one).

    Parameters
    ----------
    capacity : int
        The number of node rows.
    n_models : int
        The number of models M.
    n_actions : int
        The number of actions.
    gamma : float
        The discount factor in (0, 1).
    discounts : ndarray (D,)
        ``discounts[d] = gamma ** d`` (`discount_table`), stored as given.

    Raises
    ------
    ValueError
        If ``discounts`` holds too few powers for ``capacity`` nodes.
    """
    if discounts.shape[0] < (capacity - 1) // n_actions + 2:
        raise ValueError(f"discounts holds {discounts.shape[0]} powers, too few for {capacity} nodes")
    return TreeArrays(
        returns=np.empty((capacity, n_models)),
        terminal=np.zeros((capacity, n_models), dtype=bool),
        parent=np.empty(capacity, dtype=np.int64),
        action=np.empty(capacity, dtype=np.int64),
        depth=np.empty(capacity, dtype=np.int64),
        first_child=np.empty(capacity, dtype=np.int64),
        leaf_lower=np.empty(capacity),
        leaf_upper=np.empty(capacity),
        lower=np.empty(capacity),
        upper=np.empty(capacity),
        any_terminated=np.zeros(capacity, dtype=bool),
        expanded=np.empty(capacity, dtype=np.int64),
        heap=np.empty(capacity, dtype=np.int64),
        discounts=discounts,
        rewards=np.zeros((n_models, n_actions)),
        new_terminal=np.zeros((n_models, n_actions), dtype=bool),
        fallback=np.zeros((n_models, n_actions)),
        counts=np.zeros(4, dtype=np.int64),
        gamma=float(gamma),
    )


def grow(tree: TreeArrays, capacity: int, discounts: np.ndarray) -> TreeArrays:
    """A copy of ``tree`` with ``capacity`` rows (the same nodes, heap and counts).

    Parameters
    ----------
    tree : TreeArrays
        The tree to copy (not modified).
    capacity : int
        The number of node rows of the copy, at least the tree's size.
    discounts : ndarray (D,)
        The powers of gamma for the copy, enough for ``capacity`` nodes (see `allocate`).
    """
    n_models, n_actions = tree.rewards.shape
    grown = allocate(capacity, n_models, n_actions, tree.gamma, discounts)
    size = int(tree.counts[SIZE])
    for name in (
        "returns",
        "terminal",
        "parent",
        "action",
        "depth",
        "first_child",
        "leaf_lower",
        "leaf_upper",
        "lower",
        "upper",
        "any_terminated",
    ):
        getattr(grown, name)[:size] = getattr(tree, name)[:size]
    grown.expanded[: tree.counts[N_EXPANDED]] = tree.expanded[: tree.counts[N_EXPANDED]]
    grown.heap[: tree.counts[HEAP_SIZE]] = tree.heap[: tree.counts[HEAP_SIZE]]
    grown.counts[:] = tree.counts
    return grown


# ------------------------------------------------------------------ frontier
@njit(**_INTERNAL)
def _before(i, j, key, parent, action, depth):
    """Heap order: larger b-value (``key``) first, then the lexicographically smaller action path.

    The path comparison is written here, not in a function of its own: each compiled
    function is a library of its own, optimised and turned into machine code again by
    each compiled caller above it (benchmarks/bench_cold_start.py).
    """
    if key[i] != key[j]:
        return key[i] > key[j]
    d1, d2 = depth[i], depth[j]
    a, b = i, j
    while d1 > d2:  # lift the deeper one to the common depth
        a = parent[a]
        d1 -= 1
    while d2 > d1:
        b = parent[b]
        d2 -= 1
    if a == b:
        # one path is a prefix of the other: impossible between two leaves
        return depth[i] < depth[j]
    while parent[a] != parent[b]:  # up to the children of the deepest common ancestor
        a = parent[a]
        b = parent[b]
    return action[a] < action[b]


@njit(**_INLINED)
def _heap_push(heap, size, node, key, parent, action, depth):
    """Push ``node`` on ``heap[:size]``; returns the new size."""
    position = size
    heap[position] = node
    while position > 0:
        up = (position - 1) // 2
        if not _before(heap[position], heap[up], key, parent, action, depth):
            break
        heap[position], heap[up] = heap[up], heap[position]
        position = up
    return size + 1


@njit(**_INLINED)
def _heap_pop(heap, size, key, parent, action, depth):
    """Pop the first node of ``heap[:size]``; returns it (the new size is ``size - 1``)."""
    top = heap[0]
    size -= 1
    heap[0] = heap[size]
    position = 0
    while True:
        left = 2 * position + 1
        if left >= size:
            break
        best = left
        right = left + 1
        if right < size and _before(heap[right], heap[left], key, parent, action, depth):
            best = right
        if not _before(heap[best], heap[position], key, parent, action, depth):
            break
        heap[position], heap[best] = heap[best], heap[position]
        position = best
    return top


# ------------------------------------------------------------ the operations
@njit(**_INLINED)
def reset(tree):
    """Make ``tree`` the root alone: depth 0, zero returns, nothing terminated, on the frontier."""
    n_models = tree.returns.shape[1]
    for m in range(n_models):
        tree.returns[0, m] = 0.0
        tree.terminal[0, m] = False
    root_upper = 1.0 / (1.0 - tree.gamma)
    tree.parent[0] = -1
    tree.action[0] = -1
    tree.depth[0] = 0
    tree.first_child[0] = -1
    tree.leaf_lower[0] = 0.0
    tree.leaf_upper[0] = root_upper
    tree.lower[0] = 0.0
    tree.upper[0] = root_upper
    tree.any_terminated[0] = False
    tree.heap[0] = 0
    tree.counts[SIZE] = 1
    tree.counts[HEAP_SIZE] = 1
    tree.counts[N_EXPANDED] = 0
    tree.counts[MAX_DEPTH] = 0


@njit(**_NO_REFCOUNTS)
def select(tree):
    """Remove and return the leaf to expand, or `NO_LEAF` when ``upper <= lower`` at the root.

    Notes
    -----
    The leaf of largest b-value, the lexicographically smallest action path on ties.
    A leaf's b-value never changes and an internal node's ``upper`` is the max of the
    b-values of the leaves below it, so this is the leaf reached by descending from
    the root through the child of largest ``upper`` (smallest action index on ties).
    When ``upper <= lower`` at the root the value is known exactly and, the bounds
    being monotone, no expansion can change them; this is also what happens when the
    best leaf has every model terminated (its b-value equals its lower bound).
    """
    if tree.upper[0] <= tree.lower[0]:
        return NO_LEAF
    counts = tree.counts
    size = counts[HEAP_SIZE]
    counts[HEAP_SIZE] = size - 1
    return _heap_pop(tree.heap, size, tree.leaf_upper, tree.parent, tree.action, tree.depth)


@njit(**_NO_REFCOUNTS)
def expand(tree, leaf):
    """Expand ``leaf`` with the transitions in ``tree.rewards``/``tree.new_terminal``; back the bounds up.

    A model already terminated on the path to ``leaf`` is not stepped again: its
    rewards are set to 0 and its transitions to terminal, whatever the engine wrote.
    Then every reward must lie in [0, 1] (NaN included): on the first pair that does
    not, in (action, model) row-major order, the tree is left unchanged and the flat
    index ``a * M + m`` is returned (the value stays in ``tree.rewards[m, a]``).
    Otherwise the children are created (`add_children`), the bounds backed up
    (`backup`), and -1 is returned.
    """
    rewards, new_terminal, terminal = tree.rewards, tree.new_terminal, tree.terminal
    n_models, n_actions = rewards.shape
    for m in range(n_models):
        if terminal[leaf, m]:
            for a in range(n_actions):
                rewards[m, a] = 0.0
                new_terminal[m, a] = True
                tree.fallback[m, a] = 0.0
    for a in range(n_actions):
        for m in range(n_models):
            r = rewards[m, a]
            if not (r >= 0.0 and r <= 1.0):
                return a * n_models + m
    add_children(tree, leaf)
    backup(tree, leaf)
    return -1


@njit(**_INLINED)
def add_children(tree, leaf):
    """Create the ``n_actions`` children of ``leaf`` from ``tree.rewards``, put them on the frontier.

    Returns the id of the first child.

    Notes
    -----
    A child's b-value (16) is ``min_m (R_m + gamma^(l+1)/(1-gamma) [not
    terminated])``, which is mathematically at most the parent's; it is clipped to
    the parent's so that rounding of the last bit cannot make the root's ``upper``
    increase with the budget. Both are valid upper bounds, so the min is. The lower
    bound needs no clipping: ``R_m + gamma^l r`` with ``r >= 0`` never rounds below
    ``R_m``. While no model has terminated every optimistic term is ``R_m + tail``
    and rounding is monotone, so ``min_m fl(R_m + tail) == fl(min_m R_m + tail)``.

    With a continuation bound F_m (``tree.fallback``), the child's lower bound is
    ``min_m (R_m + gamma^(l+1) F_m [not terminated])``: the action path followed by a
    fixed continuation is one plan, whose worst return over the models is at most the
    robust value of the child (eq. (13)); with F = 0 this is the paper's ``min_m R_m``
    bit for bit (``x + 0.0 == x``).
    """
    rewards, new_terminal, discounts = tree.rewards, tree.new_terminal, tree.discounts
    fallback = tree.fallback
    returns, terminal, counts = tree.returns, tree.terminal, tree.counts
    parent, action, depth, first_child = tree.parent, tree.action, tree.depth, tree.first_child
    leaf_lower, leaf_upper, lower, upper = tree.leaf_lower, tree.leaf_upper, tree.lower, tree.upper
    any_terminated = tree.any_terminated
    n_models, n_actions = rewards.shape
    first = counts[SIZE]
    d = depth[leaf]
    tail = discounts[d + 1] / (1.0 - tree.gamma)
    parent_upper = leaf_upper[leaf]
    any_new = False
    for a in range(n_actions):
        for m in range(n_models):
            if new_terminal[m, a]:
                any_new = True
    check_terminal = any_terminated[leaf] or any_new
    for a in range(n_actions):
        child = first + a
        child_lower = np.inf
        child_return = np.inf
        child_optimistic = np.inf
        child_any = False
        for m in range(n_models):
            value = returns[leaf, m] + discounts[d] * rewards[m, a]
            returns[child, m] = value
            if value < child_return:
                child_return = value
            done = False
            if check_terminal:
                done = terminal[leaf, m] or new_terminal[m, a]
                terminal[child, m] = done
                child_any = child_any or done
                optimistic = value + (0.0 if done else tail)
                if optimistic < child_optimistic:
                    child_optimistic = optimistic
            else:
                terminal[child, m] = False
            pessimistic = value if done else value + discounts[d + 1] * fallback[m, a]
            if pessimistic < child_lower:
                child_lower = pessimistic
        if check_terminal:
            child_upper = min(child_optimistic, parent_upper)
        else:
            child_upper = min(child_return + tail, parent_upper)
        parent[child] = leaf
        action[child] = a
        depth[child] = d + 1
        first_child[child] = -1
        leaf_lower[child] = child_lower
        leaf_upper[child] = child_upper
        lower[child] = child_lower
        upper[child] = child_upper
        any_terminated[child] = child_any
    first_child[leaf] = first
    counts[SIZE] = first + n_actions
    heap, heap_size = tree.heap, counts[HEAP_SIZE]
    for a in range(n_actions):
        heap_size = _heap_push(heap, heap_size, first + a, leaf_upper, parent, action, depth)
    counts[HEAP_SIZE] = heap_size
    tree.expanded[counts[N_EXPANDED]] = leaf
    counts[N_EXPANDED] += 1
    if d + 1 > counts[MAX_DEPTH]:
        counts[MAX_DEPTH] = d + 1
    return first


@njit(**_INLINED)
def backup(tree, node):
    """Recompute ``lower``/``upper`` from ``node`` up to the root (max over the children; ``lower`` at least the leaf bound).

    Only the path to the root can change, and the walk stops at the first ancestor
    whose bounds are unchanged (its ancestors then are too). Without continuation
    bounds the children's max is never below the node's leaf bound (their returns add
    rewards >= 0), so the max with it changes nothing there.
    """
    lower, upper, first_child, parent = tree.lower, tree.upper, tree.first_child, tree.parent
    leaf_lower = tree.leaf_lower
    n_actions = tree.rewards.shape[1]
    while node >= 0:
        start = first_child[node]
        new_lower = max(leaf_lower[node], lower[start])
        new_upper = upper[start]
        for a in range(1, n_actions):
            if lower[start + a] > new_lower:
                new_lower = lower[start + a]
            if upper[start + a] > new_upper:
                new_upper = upper[start + a]
        if new_lower == lower[node] and new_upper == upper[node]:
            return
        lower[node] = new_lower
        upper[node] = new_upper
        node = parent[node]


def best_path(tree: TreeArrays) -> np.ndarray:
    """The decision's action indices: from the root, the child of largest ``lower`` (first on ties), to a leaf.

    Python, not compiled: a walk of at most the tree's depth, whose compile cost more
    than every call of it (0.3 s of a cold start); the comparisons are the same float64
    ``>`` in either form, so the path is the same.

    Parameters
    ----------
    tree : TreeArrays
        A searched tree.

    Returns
    -------
    ndarray of int64
        One action index per level, from the root down to a leaf.
    """
    lower, first_child = tree.lower, tree.first_child
    n_actions = tree.rewards.shape[1]
    path = []
    node = 0
    while first_child[node] >= 0:
        start = int(first_child[node])
        best = 0
        for a in range(1, n_actions):
            if lower[start + a] > lower[start + best]:
                best = a
        path.append(best)
        node = start + best
    return np.array(path, dtype=np.int64)


@njit(**_ENTRY)
def start(tree):
    """`reset` then `select`: the root, the first leaf to expand (called from Python)."""
    reset(tree)
    return select(tree)


@njit(**_ENTRY)
def expand_and_select(tree, leaf, select_next):
    """`expand` then, if ``select_next``, `select`: the Python engine's one compiled call per expansion.

    Returns the next leaf to expand, `NO_LEAF` (the root's bounds met, or
    ``select_next`` false), or ``REWARD_ERROR - k`` for a reward outside [0, 1] at
    the flat pair ``k`` (see `expand`; the tree is then unchanged).
    """
    bad = expand(tree, leaf)
    if bad >= 0:
        return REWARD_ERROR - bad
    if not select_next:
        return NO_LEAF
    return select(tree)
