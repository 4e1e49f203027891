"""The result of one planning call: the chosen action and the root value bounds."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .tree import SearchTree

__all__ = ["Decision"]


def _plain(value: Any) -> Any:
    """A JSON-friendly copy of an action (numpy arrays and scalars become lists/floats)."""
    if isinstance(value, (np.ndarray, np.generic)):
        return value.tolist()
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value


@dataclass(frozen=True)
class Decision:
    """What a tree-search planner decided, with bounds on the value of the problem.

    Attributes
    ----------
    action
        The chosen first action: the root child with the largest lower bound
        (ties go to the smallest action index).
    action_index
        Its index in the planner's ``actions``.
    lower
        Root lower bound ``L`` (eq. (18)): the largest, over the tree's leaves, of the
        worst model's discounted return collected so far. Some action sequence
        attains at least ``lower`` under every model.
    upper
        Root upper bound ``U`` (eq. (17) with the discounted b-value of eq. (16)):
        no action sequence gets more than ``upper`` under its worst model.
        ``upper`` bounds the objective *as the models define it*: for
        `IntervalModel` models, whose rewards are pessimistic minima over predicted boxes,
        it bounds the surrogate objective of eq. (11), which is itself a lower bound
        of the true robust value (10); it is not an upper bound of that true value.
    expansions
        Number of leaves expanded (at most the budget; fewer only when the search
        stopped because ``lower == upper``, see `solved`).
    depth
        Maximal depth of the search tree (the root has depth 0).
    sequence
        The best action sequence by lower bound: from the root, repeatedly the child
        with the largest lower bound (smallest index on ties), down to a leaf. Its
        first item is ``action``.
    sequence_indices
        The same sequence as indices into ``actions``.
    action_lower, action_upper
        The bounds ``L`` and ``U`` of each root child, in the order of ``actions``.
    nodes
        Number of nodes in the tree (``1 + expansions * len(actions)``).
    solved
        True when the search stopped before spending its budget because
        ``lower == upper``: the robust value is known exactly and no expansion could
        change the bounds (e.g. the best leaf has every model terminated).

    Notes
    -----
    Guarantee (Theorem 3, eq. (19)): ``lower <= sup_a min_m sum_n gamma^n r_n^m <=
    upper``, and the robust regret of ``action`` is at most ``upper - lower``.
    """

    action: Any
    action_index: int
    lower: float
    upper: float
    expansions: int
    depth: int
    sequence: tuple
    sequence_indices: tuple[int, ...]
    action_lower: tuple[float, ...]
    action_upper: tuple[float, ...]
    nodes: int
    solved: bool

    @classmethod
    def from_tree(cls, tree: SearchTree, actions: Sequence, *, solved: bool) -> Decision:
        """The decision a search tree supports (the one builder both engines use).

        Parameters
        ----------
        tree
            The tree of the search (`SearchTree`), at least its root expanded.
        actions
            The planner's actions, in index order.
        solved
            Whether the search stopped early because ``lower == upper`` at the root.

        Notes
        -----
        The action is the root child of largest lower bound (eq. (18)), the first on
        ties, and the sequence continues down the children of largest lower bound
        to a leaf (`SearchTree.best_path`).
        """
        first = int(tree.first_child[0])
        n_actions = len(actions)
        path = tree.best_path()
        return cls(
            action=actions[path[0]],
            action_index=path[0],
            lower=float(tree.lower[0]),
            upper=float(tree.upper[0]),
            expansions=len(tree.expanded),
            depth=int(tree.max_depth),
            sequence=tuple(actions[a] for a in path),
            sequence_indices=path,
            action_lower=tuple(tree.lower[first : first + n_actions].tolist()),
            action_upper=tuple(tree.upper[first : first + n_actions].tolist()),
            nodes=int(tree.size),
            solved=bool(solved),
        )

    @property
    def gap(self) -> float:
        """``upper - lower``: a bound on the robust regret of ``action``."""
        return self.upper - self.lower

    def to_dict(self) -> dict:
        """A plain-Python (JSON-serialisable when the actions are) copy."""
        return {
            "action": _plain(self.action),
            "action_index": self.action_index,
            "lower": self.lower,
            "upper": self.upper,
            "gap": self.gap,
            "expansions": self.expansions,
            "depth": self.depth,
            "sequence": [_plain(a) for a in self.sequence],
            "sequence_indices": list(self.sequence_indices),
            "action_lower": list(self.action_lower),
            "action_upper": list(self.action_upper),
            "nodes": self.nodes,
            "solved": self.solved,
        }
