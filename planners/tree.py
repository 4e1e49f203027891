"""The look-ahead tree of the robust optimistic planner, stored in flat containers.

Nodes are numbered in creation order; node 0 is the root. The ``n_actions`` children
of a node are created together, so they are contiguous: ``first_child[i] + a`` is
the child reached by action index ``a``.

Storage: the per-model data (returns and terminal flags, ``(nodes, M)``) live in
numpy arrays preallocated and grown by doubling, so that one expansion updates all
(action, model) pairs in a few vectorised operations. The per-node scalars (parent,
action, depth, first child, bounds) live in Python lists, which also grow by
amortised doubling: the backup walks the tree one scalar at a time, and reading a
list item or taking ``max`` of a 4-item list slice is several times faster than the
same on a numpy array (measured: 0.2 us vs 1.2 us per slice max). States are opaque
objects kept in one list per model, never copied.

The tree also keeps its frontier: a heap of the leaves keyed by
``(-b-value, rank)``, where the rank orders leaves by action path (see `SearchTree`).
"""

from __future__ import annotations

import heapq

import numpy as np

__all__ = ["SearchTree"]

_INITIAL_CAPACITY = 1024
_min_reduce = np.minimum.reduce  # ndarray.min without its Python wrapper (hot path)
_INITIAL_RANK_DIGITS = 64


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
        numpy arrays start at ``min(max_nodes, 1024)`` rows and double when full.

    Attributes
    ----------
    size
        Number of nodes.
    parent, action, depth, first_child
        Lists of ints; ``parent[0] = -1``; ``first_child[i] = -1`` for a leaf.
    returns
        Array ``(capacity, M)``, valid up to ``size``:
        ``R_m(i) = sum_{n < depth(i)} gamma^n r_n^m`` along the path to node i.
    terminal
        Bool array ``(capacity, M)``: model m made a terminal transition on the path.
    leaf_lower, leaf_upper
        Lists: the leaf bounds of each node as computed when it was created, which
        never change: ``min_m R_m`` and the robust b-value
        ``min_m (R_m + gamma^l / (1 - gamma) [m not terminated])`` (eqs. (16), (18)).
    lower, upper
        Lists: backed-up bounds, equal to the leaf bounds at a leaf and to the max
        over the children at an internal node (eqs. (17), (18)).
    rank
        List of ints: each node's action path read as a base-|A| number of
        ``rank_digits`` digits, ``sum_i a_i |A|^(rank_digits - i - 1)`` (path padded
        with zeros). Among leaves, no path is a prefix of another, so a smaller rank
        is exactly a lexicographically smaller path: the rank breaks ties without
        storing paths (tuples would cost O(depth) pointers per node, quadratic in K
        on deep trees). ``rank_digits`` doubles when the tree outgrows it, which
        rescales every rank by the same factor and so preserves the order.
    states
        ``states[m][i]`` is model m's state at node i.
    any_terminated
        List of bools: whether some model made a terminal transition on the path
        (``terminal[i].any()``).
    expanded
        Node ids in the order they were expanded.
    max_depth
        Largest node depth.
    """

    def __init__(self, n_models: int, n_actions: int, gamma: float, max_nodes: int) -> None:
        self.n_models = n_models
        self.n_actions = n_actions
        self.gamma = gamma
        self.max_nodes = max_nodes
        self.size = 0
        self.max_depth = 0
        capacity = min(max_nodes, _INITIAL_CAPACITY)
        self.returns = np.empty((capacity, n_models))
        # zero-filled (also when grown): rows without a terminated model need no write
        self.terminal = np.zeros((capacity, n_models), dtype=bool)
        self.parent: list[int] = []
        self.action: list[int] = []
        self.depth: list[int] = []
        self.first_child: list[int] = []
        self.leaf_lower: list[float] = []
        self.leaf_upper: list[float] = []
        self.lower: list[float] = []
        self.upper: list[float] = []
        self.rank: list[int] = []
        self.rank_digits = _INITIAL_RANK_DIGITS
        self._digit_weights = self._weights(self.rank_digits)
        self._frontier: list[tuple[float, int, int]] = []
        self.states: list[list] = [[] for _ in range(n_models)]
        self.expanded: list[int] = []
        self._child_actions = list(range(n_actions))
        # any_terminated[i]: some model terminated on the path to i (skips the per-model
        # optimistic terms while no model has terminated, the usual case)
        self.any_terminated: list[bool] = []
        self._discounts: list[float] = [1.0]

    @classmethod
    def from_arrays(cls, arrays, size: int, n_expanded: int, max_depth: int, gamma: float, max_nodes: int,
                    states: list[list]) -> "SearchTree":
        """The tree a compiled search left in ``arrays`` (`compiled_search.SearchArrays`), as this class stores it.

        Copies the first ``size`` rows; ranks, frontier and discounts are recomputed
        from the structure, so the result equals the tree the Python engine builds.
        """
        n_models, n_actions = arrays.returns.shape[1], arrays.stack.shape[2]
        tree = cls(n_models, n_actions, gamma, max_nodes)
        tree.size, tree.max_depth = size, max_depth
        tree.returns = arrays.returns[:size].copy()
        tree.terminal = arrays.terminal[:size].copy()
        for name in ("parent", "action", "depth", "first_child", "leaf_lower", "leaf_upper", "lower", "upper",
                     "any_terminated"):
            setattr(tree, name, getattr(arrays, name)[:size].tolist())
        tree.expanded = arrays.expanded[:n_expanded].tolist()
        tree.states = states
        while tree.rank_digits < max_depth:
            tree.rank_digits *= 2
        weights = tree._digit_weights = tree._weights(tree.rank_digits)
        rank = [0] * size
        for i in range(1, size):
            rank[i] = rank[tree.parent[i]] + tree.action[i] * weights[tree.depth[i]]
        tree.rank = rank
        tree._frontier = [(-tree.leaf_upper[i], rank[i], i) for i in range(size) if tree.first_child[i] < 0]
        heapq.heapify(tree._frontier)
        tree._discounts = [1.0]
        while len(tree._discounts) <= max_depth:
            tree._discounts.append(gamma ** len(tree._discounts))
        return tree

    # ------------------------------------------------------------------ building
    def add_root(self, states) -> None:
        """Create the root (depth 0, zero returns, nothing terminated)."""
        root_upper = 1.0 / (1.0 - self.gamma)
        self.returns[0] = 0.0
        self.terminal[0] = False
        self.parent.append(-1)
        self.action.append(-1)
        self.depth.append(0)
        self.first_child.append(-1)
        self.leaf_lower.append(0.0)
        self.leaf_upper.append(root_upper)
        self.lower.append(0.0)
        self.upper.append(root_upper)
        self.rank.append(0)
        self.any_terminated.append(False)
        for m, state in enumerate(states):
            self.states[m].append(state)
        self.size = 1
        self._frontier.append((-root_upper, 0, 0))

    def pop_best_leaf(self) -> int:
        """Remove and return the leaf of largest b-value (smallest action path on ties).

        Notes
        -----
        A leaf's b-value never changes, and an internal node's ``upper`` is the max of
        the b-values of the leaves below it, so this is the leaf reached by descending
        from the root through the child of largest ``upper`` (smallest action index on
        ties): a smaller-index subtree holds the lexicographically smaller paths.
        """
        return heapq.heappop(self._frontier)[2]

    def _weights(self, digits: int) -> list[int]:
        """``weights[d]``: the rank weight of the action taken into depth d (1..digits)."""
        return [0] + [self.n_actions ** (digits - d) for d in range(1, digits + 1)]

    def _widen_ranks(self, depth: int) -> None:
        """Double ``rank_digits`` until it covers ``depth``; rescale ranks and frontier keys."""
        digits = self.rank_digits
        while digits < depth:
            digits *= 2
        factor = self.n_actions ** (digits - self.rank_digits)
        self.rank = [r * factor for r in self.rank]
        # Uniform scaling keeps the heap order, so the entries are rescaled in place.
        self._frontier = [(key, rank * factor, node) for key, rank, node in self._frontier]
        self.rank_digits = digits
        self._digit_weights = self._weights(digits)

    def _grow(self, needed: int) -> None:
        capacity = self.returns.shape[0]
        if needed <= capacity:
            return
        new_capacity = max(min(2 * capacity, self.max_nodes), needed)
        for name in ("returns", "terminal"):
            old = getattr(self, name)
            new = np.zeros((new_capacity,) + old.shape[1:], dtype=old.dtype)
            new[:capacity] = old
            setattr(self, name, new)

    def add_children(self, node: int, rewards: np.ndarray, new_terminal: np.ndarray) -> int:
        """Create the ``n_actions`` children of leaf ``node`` and put them on the frontier.

        Returns the id of the first child.

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
        depth = self.depth[node]
        discounts = self._discounts
        while len(discounts) <= depth + 1:
            discounts.append(self.gamma ** len(discounts))
        child_returns = self.returns[node] + discounts[depth] * rewards
        tail = discounts[depth + 1] / (1.0 - self.gamma)
        parent_upper = self.leaf_upper[node]
        child_lower = _min_reduce(child_returns, axis=1).tolist()
        if self.any_terminated[node] or new_terminal.any():
            child_terminal = self.terminal[node] | new_terminal
            optimistic = child_returns + tail * ~child_terminal
            child_upper = np.minimum(optimistic.min(axis=1), parent_upper).tolist()
            self.terminal[first:end] = child_terminal
            self.any_terminated.extend(child_terminal.any(axis=1).tolist())
        else:
            # No model terminated: every optimistic term is R_m + tail, and rounding is
            # monotone, so min_m fl(R_m + tail) == fl(min_m R_m + tail) exactly.
            child_upper = [min(value + tail, parent_upper) for value in child_lower]
            self.any_terminated.extend([False] * n_actions)

        self.returns[first:end] = child_returns
        self.parent.extend([node] * n_actions)
        self.action.extend(self._child_actions)
        self.depth.extend([depth + 1] * n_actions)
        self.first_child.extend([-1] * n_actions)
        self.leaf_lower.extend(child_lower)
        self.leaf_upper.extend(child_upper)
        self.lower.extend(child_lower)
        self.upper.extend(child_upper)
        self.first_child[node] = first
        if depth + 1 > self.rank_digits:
            self._widen_ranks(depth + 1)
        rank, weight = self.rank[node], self._digit_weights[depth + 1]
        child_ranks = [rank + a * weight for a in self._child_actions]
        self.rank.extend(child_ranks)
        frontier = self._frontier
        for a in self._child_actions:
            heapq.heappush(frontier, (-child_upper[a], child_ranks[a], first + a))
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
            new_lower = max(lower[first:first + n_actions])
            new_upper = max(upper[first:first + n_actions])
            if new_lower == lower[node] and new_upper == upper[node]:
                return
            lower[node] = new_lower
            upper[node] = new_upper
            node = parent[node]

    # ---------------------------------------------------------------- inspection
    def path(self, node: int) -> tuple[int, ...]:
        """The action indices from the root to ``node``."""
        actions = []
        while node > 0:
            actions.append(self.action[node])
            node = self.parent[node]
        return tuple(reversed(actions))

    def is_leaf(self, node: int) -> bool:
        """Whether ``node`` has not been expanded."""
        return bool(self.first_child[node] < 0)

    def children(self, node: int) -> range:
        """The ids of the children of ``node`` (empty for a leaf)."""
        first = self.first_child[node]
        return range(0) if first < 0 else range(first, first + self.n_actions)

    def all_terminated(self, node: int) -> bool:
        """Whether every model has terminated on the path to ``node``."""
        return bool(self.terminal[node].all())

    def best_path(self) -> tuple[int, ...]:
        """From the root, the child with the largest ``lower`` (first on ties), to a leaf."""
        node, path = 0, []
        while self.first_child[node] >= 0:
            first = self.first_child[node]
            children_lower = self.lower[first:first + self.n_actions]
            a = children_lower.index(max(children_lower))
            path.append(a)
            node = first + a
        return tuple(path)
