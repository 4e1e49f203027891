"""The robust optimistic tree search for linked `IntervalModel`s, compiled with numba.

`RobustTreePlanner` runs this engine when its models are one linked `IntervalModel`
group (in member order) whose reward has a compiled box minimum (``kernel_params``)
and every model starts from the same state; it runs the Python engine otherwise. Both
engines follow the same algorithm step for step (`SearchTree.add_children` and
`SearchTree.backup`, the frontier order, the stopping rule) on the same box
arithmetic (`minimaxplan.planners.box_kernels`), so they build the same tree, bit for
bit (tested); the planner's ``engine_used`` attribute says which one ran.

The frontier is a binary heap of leaves ordered by b-value (largest first), ties by
action path (lexicographically smallest first). No leaf's path is a prefix of
another's, so this order is total and the heap pops the same leaves, in the same
order, as the Python engine's heap keyed by ``(-b-value, rank)``. Ties are resolved by
walking both paths up to the root (they are rare, and paths are short).
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

from .box_kernels import pessimistic_rewards, propagate, reward_sources, sources_digest

__all__ = ["search_kernel", "SearchArrays"]


class SearchArrays:
    """The preallocated arrays of one compiled search (``max_nodes`` rows), reused across calls."""

    def __init__(self, max_nodes: int, n_models: int, n_actions: int, n_box: int, substeps: int, budget: int) -> None:
        self.z = np.empty((max_nodes, n_models, n_box))
        self.returns = np.empty((max_nodes, n_models))
        self.terminal = np.zeros((max_nodes, n_models), dtype=bool)
        self.parent = np.empty(max_nodes, dtype=np.int64)
        self.action = np.empty(max_nodes, dtype=np.int64)
        self.depth = np.empty(max_nodes, dtype=np.int64)
        self.first_child = np.empty(max_nodes, dtype=np.int64)
        self.leaf_lower = np.empty(max_nodes)
        self.leaf_upper = np.empty(max_nodes)
        self.lower = np.empty(max_nodes)
        self.upper = np.empty(max_nodes)
        self.any_terminated = np.zeros(max_nodes, dtype=bool)
        self.expanded = np.empty(budget, dtype=np.int64)
        self.heap = np.empty(max_nodes, dtype=np.int64)
        self.stack = np.empty((substeps, n_models, n_actions, n_box))
        self.rewards = np.empty((n_models, n_actions))
        self.collided = np.empty((n_models, n_actions), dtype=bool)
        self.error = np.zeros(1)


@njit(cache=True)
def _path_before(first, second, parent, action, depth):
    """Whether leaf ``first``'s action path is lexicographically before leaf ``second``'s."""
    d1, d2 = depth[first], depth[second]
    a, b = first, second
    while d1 > d2:  # lift the deeper one to the common depth
        a = parent[a]
        d1 -= 1
    while d2 > d1:
        b = parent[b]
        d2 -= 1
    if a == b:
        # one path is a prefix of the other: impossible between two leaves
        return depth[first] < depth[second]
    while parent[a] != parent[b]:  # up to the children of the deepest common ancestor
        a = parent[a]
        b = parent[b]
    return action[a] < action[b]


@njit(cache=True, inline="always")
def _before(i, j, upper_key, parent, action, depth):
    """Heap order: larger b-value first, then the smaller action path."""
    if upper_key[i] != upper_key[j]:
        return upper_key[i] > upper_key[j]
    return _path_before(i, j, parent, action, depth)


@njit(cache=True)
def _heap_push(heap, size, node, leaf_upper, parent, action, depth):
    position = size
    heap[position] = node
    while position > 0:
        up = (position - 1) // 2
        if not _before(heap[position], heap[up], leaf_upper, parent, action, depth):
            break
        heap[position], heap[up] = heap[up], heap[position]
        position = up
    return size + 1


@njit(cache=True)
def _heap_pop(heap, size, leaf_upper, parent, action, depth):
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
        if right < size and _before(heap[right], heap[left], leaf_upper, parent, action, depth):
            best = right
        if not _before(heap[best], heap[position], leaf_upper, parent, action, depth):
            break
        heap[position], heap[best] = heap[best], heap[position]
        position = best
    return top, size


@functools.lru_cache(maxsize=None)
def search_kernel(params_type: type):
    """The compiled search for rewards whose ``kernel_params`` have type ``params_type``.

    Cached on disk by numba, keyed (through ``version``) by the sources it calls into:
    `box_kernels` and the reward family's module.
    """
    version = sources_digest(__file__, *reward_sources(params_type))

    def run_search(budget, gamma, discounts, root_z, time0, actions, substeps, core, params,
                   z, returns, terminal, parent, action, depth, first_child,
                   leaf_lower, leaf_upper, lower, upper, any_terminated, expanded, heap,
                   stack, rewards, collided, error):
        """Run up to ``budget`` expansions from the root boxes ``root_z`` (M, 2p).

        Mirrors `RobustTreePlanner._search` with `SearchTree.add_children` and `backup`:
        the same floating-point operations in the same order. ``discounts[d]`` is
        ``gamma ** d`` as Python computes it. Returns ``(size, n_expanded, solved,
        max_depth, bad_action, bad_model)``: ``bad_action >= 0`` reports a reward outside
        [0, 1] (value in ``error[0]``) at the first such (action, model) pair, row-major,
        and the search stopped there.
        """
        _ = version  # ties numba's cache entry to the sources it calls into
        n_models = root_z.shape[0]
        n_actions = actions.shape[0]
        for m in range(n_models):
            z[0, m] = root_z[m]
            returns[0, m] = 0.0
            terminal[0, m] = False
        root_upper = 1.0 / (1.0 - gamma)
        parent[0] = -1
        action[0] = -1
        depth[0] = 0
        first_child[0] = -1
        leaf_lower[0] = 0.0
        leaf_upper[0] = root_upper
        lower[0] = 0.0
        upper[0] = root_upper
        any_terminated[0] = False
        heap[0] = 0
        heap_size = 1
        size = 1
        max_depth = 0
        n_expanded = 0
        for _ in range(budget):
            if upper[0] <= lower[0]:
                return size, n_expanded, True, max_depth, -1, -1
            leaf, heap_size = _heap_pop(heap, heap_size, leaf_upper, parent, action, depth)
            # ---- transitions of every (model, action) pair
            all_terminated = True
            for m in range(n_models):
                if not terminal[leaf, m]:
                    all_terminated = False
            first = size
            if not all_terminated:
                propagate(z[leaf], actions, core, stack)
                pessimistic_rewards(stack, time0 + depth[leaf] * substeps, params, rewards, collided)
                for a in range(n_actions):
                    for m in range(n_models):
                        z[first + a, m] = stack[substeps - 1, m, a]
            else:
                for a in range(n_actions):
                    z[first + a] = z[leaf]
            # a terminated model is not stepped again: reward 0, still terminal
            for m in range(n_models):
                if terminal[leaf, m]:
                    for a in range(n_actions):
                        rewards[m, a] = 0.0
                        collided[m, a] = True
            for a in range(n_actions):
                for m in range(n_models):
                    r = rewards[m, a]
                    if not (r >= 0.0 and r <= 1.0):
                        error[0] = r
                        return size, n_expanded, False, max_depth, a, m
            # ---- SearchTree.add_children
            d = depth[leaf]
            tail = discounts[d + 1] / (1.0 - gamma)
            parent_upper = leaf_upper[leaf]
            new_terminal = False
            for a in range(n_actions):
                for m in range(n_models):
                    if collided[m, a]:
                        new_terminal = True
            check_terminal = any_terminated[leaf] or new_terminal
            for a in range(n_actions):
                child = first + a
                child_lower = np.inf
                child_optimistic = np.inf
                child_any = False
                for m in range(n_models):
                    value = returns[leaf, m] + discounts[d] * rewards[m, a]
                    returns[child, m] = value
                    if value < child_lower:
                        child_lower = value
                    if check_terminal:
                        done = terminal[leaf, m] or collided[m, a]
                        terminal[child, m] = done
                        child_any = child_any or done
                        optimistic = value + (0.0 if done else tail)
                        if optimistic < child_optimistic:
                            child_optimistic = optimistic
                    else:
                        terminal[child, m] = False
                if check_terminal:
                    child_upper = min(child_optimistic, parent_upper)
                else:
                    # no model terminated: min_m fl(R_m + tail) == fl(min_m R_m + tail)
                    child_upper = min(child_lower + tail, parent_upper)
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
            for a in range(n_actions):
                heap_size = _heap_push(heap, heap_size, first + a, leaf_upper, parent, action, depth)
            size = first + n_actions
            expanded[n_expanded] = leaf
            n_expanded += 1
            if d + 1 > max_depth:
                max_depth = d + 1
            # ---- SearchTree.backup
            node = leaf
            while node >= 0:
                start = first_child[node]
                new_lower = lower[start]
                new_upper = upper[start]
                for a in range(1, n_actions):
                    if lower[start + a] > new_lower:
                        new_lower = lower[start + a]
                    if upper[start + a] > new_upper:
                        new_upper = upper[start + a]
                if new_lower == lower[node] and new_upper == upper[node]:
                    break
                lower[node] = new_lower
                upper[node] = new_upper
                node = parent[node]
        return size, n_expanded, False, max_depth, -1, -1

    return njit(cache=True)(run_search)
