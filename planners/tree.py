"""The look-ahead tree of the robust optimistic planner, stored in flat arrays.

Nodes are numbered in creation order; node 0 is the root. The ``n_actions`` children
of a node are created together, so they are contiguous: ``first_child[i] + a`` is
the child reached by action index ``a``. Arrays are preallocated and grown by
doubling; the per-model states live in one Python list per model (states are opaque
objects, never copied).
"""

from __future__ import annotations

import numpy as np

__all__ = ["SearchTree"]

_INITIAL_CAPACITY = 4096


class SearchTree:
    """A look-ahead tree with per-model returns and robust value bounds.

    Parameters
    ----------
    n_models, n_actions
        Number of models M and of actions |A|.
    gamma
        Discount factor in (0, 1) (validated by the planner).
    max_nodes
        Number of nodes the search may create (``1 + budget * n_actions``); the
        arrays start at ``min(max_nodes, 4096)`` rows and double when full.

    Attributes
    ----------
    size
        Number of nodes.
    parent, action, depth, first_child
        Integer arrays; ``parent[0] = -1``; ``first_child[i] = -1`` for a leaf.
    returns
        ``(size, M)``: ``R_m(i) = sum_{n < depth(i)} gamma^n r_n^m`` along the path.
    terminal
        ``(size, M)`` bool: model m has made a terminal transition on the path.
    leaf_lower, leaf_upper
        The leaf bounds of each node as computed when it was created, which never
        change: ``min_m R_m`` and the robust b-value
        ``min_m (R_m + gamma^l / (1 - gamma) [m not terminated])`` (eqs. (16), (18)).
    lower, upper
        Backed-up bounds: equal to the leaf bounds at a leaf, and the max over
        the children at an internal node (eqs. (17), (18)).
    paths
        The action-index path from the root of every node (a tuple).
    states
        ``states[m][i]`` is model m's state at node i.
    expanded
        Node ids in the order they were expanded.
    """

    def __init__(self, n_models: int, n_actions: int, gamma: float, max_nodes: int) -> None:
        self.n_models = n_models
        self.n_actions = n_actions
        self.gamma = gamma
        self.max_nodes = max_nodes
        self.size = 0
        self.max_depth = 0
        capacity = min(max_nodes, _INITIAL_CAPACITY)
        self.parent = np.empty(capacity, dtype=np.int64)
        self.action = np.empty(capacity, dtype=np.int64)
        self.depth = np.empty(capacity, dtype=np.int64)
        self.first_child = np.empty(capacity, dtype=np.int64)
        self.returns = np.empty((capacity, n_models))
        self.terminal = np.empty((capacity, n_models), dtype=bool)
        self.leaf_lower = np.empty(capacity)
        self.leaf_upper = np.empty(capacity)
        self.lower = np.empty(capacity)
        self.upper = np.empty(capacity)
        self.paths: list[tuple[int, ...]] = []
        self.states: list[list] = [[] for _ in range(n_models)]
        self.expanded: list[int] = []

    # ------------------------------------------------------------------ building
    def add_root(self, states) -> None:
        """Create the root (depth 0, zero returns, nothing terminated)."""
        self.parent[0] = -1
        self.action[0] = -1
        self.depth[0] = 0
        self.first_child[0] = -1
        self.returns[0] = 0.0
        self.terminal[0] = False
        self.leaf_lower[0] = 0.0
        self.leaf_upper[0] = 1.0 / (1.0 - self.gamma)
        self.lower[0] = self.leaf_lower[0]
        self.upper[0] = self.leaf_upper[0]
        self.paths.append(())
        for m, state in enumerate(states):
            self.states[m].append(state)
        self.size = 1

    def _grow(self, needed: int) -> None:
        capacity = self.parent.shape[0]
        if needed <= capacity:
            return
        new_capacity = min(max(2 * capacity, needed), max(self.max_nodes, needed))
        for name in ("parent", "action", "depth", "first_child", "returns", "terminal",
                     "leaf_lower", "leaf_upper", "lower", "upper"):
            old = getattr(self, name)
            new = np.empty((new_capacity,) + old.shape[1:], dtype=old.dtype)
            new[:capacity] = old
            setattr(self, name, new)

    def add_children(self, node: int, rewards: np.ndarray, new_terminal: np.ndarray) -> int:
        """Create the ``n_actions`` children of leaf ``node``; return the first id.

        ``rewards`` and ``new_terminal`` have shape (n_actions, M): the reward of each
        (action, model) transition (0 for a model already terminated) and whether it
        was terminal. The caller has already appended the children's states.

        Notes
        -----
        A child's b-value (16) is ``min_m (R_m + gamma^(l+1)/(1-gamma) [not
        terminated])``, which is mathematically at most the parent's; it is clipped
        to the parent's so that rounding of the last bit cannot make the root's
        ``upper`` increase with the budget. Both are valid upper bounds, so the min is.
        The lower bound needs no clipping: ``R_m + gamma^l r`` with ``r >= 0`` never
        rounds below ``R_m``.
        """
        n_actions = self.n_actions
        first = self.size
        end = first + n_actions
        self._grow(end)
        depth = int(self.depth[node])
        child_returns = self.returns[node] + (self.gamma ** depth) * rewards
        child_terminal = self.terminal[node] | new_terminal
        tail = self.gamma ** (depth + 1) / (1.0 - self.gamma)
        optimistic = np.where(child_terminal, child_returns, child_returns + tail)
        child_upper = np.minimum(optimistic.min(axis=1), self.leaf_upper[node])
        child_lower = child_returns.min(axis=1)

        self.parent[first:end] = node
        self.action[first:end] = np.arange(n_actions)
        self.depth[first:end] = depth + 1
        self.first_child[first:end] = -1
        self.returns[first:end] = child_returns
        self.terminal[first:end] = child_terminal
        self.leaf_lower[first:end] = child_lower
        self.leaf_upper[first:end] = child_upper
        self.lower[first:end] = child_lower
        self.upper[first:end] = child_upper
        self.first_child[node] = first
        path = self.paths[node]
        self.paths.extend(path + (a,) for a in range(n_actions))
        self.size = end
        self.expanded.append(node)
        if depth + 1 > self.max_depth:
            self.max_depth = depth + 1
        return first

    def backup(self, node: int) -> None:
        """Recompute ``lower``/``upper`` from ``node`` up to the root (max over children).

        Only the path to the root can change, and the walk stops at the first
        ancestor whose bounds are unchanged (its ancestors then are too).
        """
        n_actions = self.n_actions
        lower, upper, first_child, parent = self.lower, self.upper, self.first_child, self.parent
        while node >= 0:
            first = first_child[node]
            new_lower = lower[first:first + n_actions].max()
            new_upper = upper[first:first + n_actions].max()
            if new_lower == lower[node] and new_upper == upper[node]:
                return
            lower[node] = new_lower
            upper[node] = new_upper
            node = parent[node]

    # ---------------------------------------------------------------- inspection
    def is_leaf(self, node: int) -> bool:
        """Whether ``node`` has not been expanded."""
        return bool(self.first_child[node] < 0)

    def children(self, node: int) -> range:
        """The ids of the children of ``node`` (empty for a leaf)."""
        first = int(self.first_child[node])
        return range(0) if first < 0 else range(first, first + self.n_actions)

    def all_terminated(self, node: int) -> bool:
        """Whether every model has terminated on the path to ``node``."""
        return bool(self.terminal[node].all())

    def best_path(self) -> tuple[int, ...]:
        """From the root, the child with the largest ``lower`` (first on ties), to a leaf."""
        node, path = 0, []
        while self.first_child[node] >= 0:
            first = int(self.first_child[node])
            a = int(np.argmax(self.lower[first:first + self.n_actions]))
            path.append(a)
            node = first + a
        return tuple(path)
