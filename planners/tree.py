"""A read-only view of the look-ahead tree that a search left in its `TreeArrays`.

Both engines of `RobustTreePlanner` build the tree in the same arrays with the same
compiled operations (`minimaxplan.planners.tree_ops`); `SearchTree` shows it to
callers and tests: read-only views of the first ``size`` rows, the models' states,
and a few derived queries.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from . import tree_ops
from .tree_ops import MAX_DEPTH, N_EXPANDED, SIZE, TreeArrays

__all__ = ["SearchTree"]


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.setflags(write=False)
    return view


class SearchTree:
    """The tree of one search: read-only views of its arrays and the models' states.

    Parameters
    ----------
    arrays
        The `TreeArrays` of the search (not copied: the planner hands out a view only
        of arrays it does not reuse).
    states
        ``states[m][i]`` is model m's state at node i; or a callable returning that
        list, called on first access (the compiled engine materialises its states
        only when asked).

    Attributes
    ----------
    size
        Number of nodes.
    n_models, n_actions
        M and ``|A|``.
    gamma
        The discount factor.
    parent, action, depth, first_child
        Int arrays ``(size,)``; ``parent[0] = -1``; ``first_child[i] = -1`` for a leaf.
    returns
        Array ``(size, M)``: ``R_m(i) = sum_{n < depth(i)} gamma^n r_n^m``.
    terminal
        Bool array ``(size, M)``: model m made a terminal transition on the path.
    leaf_lower, leaf_upper
        The leaf bounds of each node as created: ``min_m R_m`` and the robust b-value
        ``min_m (R_m + gamma^l / (1 - gamma) [m not terminated])`` (eqs. (16), (18)).
    lower, upper
        Backed-up bounds (eqs. (17), (18)).
    any_terminated
        Bool array ``(size,)``: ``terminal.any(axis=1)``.
    expanded
        Node ids in the order they were expanded.
    max_depth
        Largest node depth.
    states
        ``states[m][i]``: model m's state at node i (opaque objects, never copied).

    See `minimaxplan.planners.tree_ops.TreeArrays` for the layout.
    """

    __slots__ = ("_arrays", "_states", "_views", "size", "max_depth", "n_models", "n_actions", "gamma")

    def __init__(self, arrays: TreeArrays, states: list | Callable[[], list]) -> None:
        self._arrays = arrays
        self._states = states
        self._views: dict[str, np.ndarray] = {}
        self.size = int(arrays.counts[SIZE])
        self.max_depth = int(arrays.counts[MAX_DEPTH])
        self.n_models, self.n_actions = arrays.rewards.shape
        self.gamma = arrays.gamma

    def _view(self, name: str, rows: int) -> np.ndarray:
        view = self._views.get(name)
        if view is None:
            view = self._views[name] = _read_only(getattr(self._arrays, name)[:rows])
        return view

    @property
    def parent(self) -> np.ndarray:
        """Each node's parent (-1 at the root)."""
        return self._view("parent", self.size)

    @property
    def action(self) -> np.ndarray:
        """The action index leading to each node (-1 at the root)."""
        return self._view("action", self.size)

    @property
    def depth(self) -> np.ndarray:
        """Each node's depth (0 at the root)."""
        return self._view("depth", self.size)

    @property
    def first_child(self) -> np.ndarray:
        """Each node's first child (-1 for a leaf); the children are contiguous."""
        return self._view("first_child", self.size)

    @property
    def returns(self) -> np.ndarray:
        """``R_m(i)``, shape (size, M): the discounted returns along the path."""
        return self._view("returns", self.size)

    @property
    def terminal(self) -> np.ndarray:
        """Shape (size, M): whether model m made a terminal transition on the path."""
        return self._view("terminal", self.size)

    @property
    def leaf_lower(self) -> np.ndarray:
        """``min_m R_m`` of each node as created (eq. (18))."""
        return self._view("leaf_lower", self.size)

    @property
    def leaf_upper(self) -> np.ndarray:
        """The robust b-value of each node as created (eq. (16))."""
        return self._view("leaf_upper", self.size)

    @property
    def lower(self) -> np.ndarray:
        """Backed-up lower bounds (eqs. (17), (18))."""
        return self._view("lower", self.size)

    @property
    def upper(self) -> np.ndarray:
        """Backed-up upper bounds (eqs. (17), (18))."""
        return self._view("upper", self.size)

    @property
    def any_terminated(self) -> np.ndarray:
        """Whether some model terminated on the path to each node."""
        return self._view("any_terminated", self.size)

    @property
    def expanded(self) -> np.ndarray:
        """The expanded nodes, in expansion order."""
        return self._view("expanded", int(self._arrays.counts[N_EXPANDED]))

    @property
    def states(self) -> list:
        """``states[m][i]``: model m's state at node i."""
        if callable(self._states):
            self._states = self._states()
        return self._states

    # ---------------------------------------------------------------- queries
    def path(self, node: int) -> tuple[int, ...]:
        """The action indices from the root to ``node``.

        Parameters
        ----------
        node : int
            A node id in ``[0, size)``.
        """
        action, parent = self._arrays.action, self._arrays.parent
        actions = []
        while node > 0:
            actions.append(int(action[node]))
            node = parent[node]
        return tuple(reversed(actions))

    def is_leaf(self, node: int) -> bool:
        """Whether ``node`` has not been expanded.

        Parameters
        ----------
        node : int
            A node id in ``[0, size)``.
        """
        return bool(self._arrays.first_child[node] < 0)

    def children(self, node: int) -> range:
        """The ids of the children of ``node`` (empty for a leaf).

        Parameters
        ----------
        node : int
            A node id in ``[0, size)``.
        """
        first = int(self._arrays.first_child[node])
        return range(0) if first < 0 else range(first, first + self.n_actions)

    def all_terminated(self, node: int) -> bool:
        """Whether every model has terminated on the path to ``node``.

        Parameters
        ----------
        node : int
            A node id in ``[0, size)``.
        """
        return bool(self._arrays.terminal[node].all())

    def best_path(self) -> tuple[int, ...]:
        """From the root, the child with the largest ``lower`` (first on ties), down to a leaf."""
        return tuple(tree_ops.best_path(self._arrays).tolist())
