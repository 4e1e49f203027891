"""The compiled engine: the whole robust search for linked `IntervalModel` models in one numba kernel.

`RobustTreePlanner` runs this engine when its models are one linked group following
`minimaxplan.planners.protocols.CompiledTransitions` (an `IntervalModel.linked`
group, in member order, whose reward has a compiled box minimum) and every model
starts from the same state; it runs the Python engine otherwise. The tree operations
are those of `minimaxplan.planners.tree_ops`, the same compiled functions the Python
engine calls; only the transitions differ in origin: here the compiled box kernel
(`minimaxplan.planners.box_kernels.propagate` and `pessimistic_rewards`), there the
models' ``expand``/``step``. The planner's ``engine_used`` says which one ran.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from ..kernels.reward_protocol import compile_per_params_type, sources_digest
from . import tree_ops
from .box_kernels import SCRATCH_ROWS, pessimistic_rewards, propagate_into, reward_sources, scratch_width

# Module globals, not closure cells: numba keys a cached closure by its cells' pickles, and a
# dispatcher's pickle differs from process to process (a closure over `tree_ops.reset` & co.
# was recompiled by every new process, the cache never hit).
from .tree_ops import N_EXPANDED, SIZE, expand, reset, select

__all__ = ["BoxArrays", "allocate_boxes", "grow_boxes", "search_kernel", "DONE", "SOLVED", "FULL"]

#: The search kernel's status: budget spent, stopped because the root's bounds met, or the arrays are full.
DONE, SOLVED, FULL = 0, 1, 2


class BoxArrays(NamedTuple):
    """The transition inputs and work arrays of one compiled search.

    Attributes
    ----------
    z : ndarray (capacity, M, 2p)
        Each node's boxes ``[-lower | upper]``, one per model.
    stack : ndarray (S, M, n_actions, 2p)
        The boxes after every sub-step of the leaf being expanded.
    root : ndarray (M, 2p)
        The root boxes.
    actions : ndarray (n_actions,) of int64
        The planner's actions as controller indices.
    time : int
        The root's sub-step index.
    """

    z: np.ndarray
    stack: np.ndarray
    root: np.ndarray
    actions: np.ndarray
    time: int


def allocate_boxes(capacity: int, n_models: int, n_actions: int, n_box: int, substeps: int) -> BoxArrays:
    """`BoxArrays` for ``capacity`` nodes (root, actions and time filled in per search with ``_replace``).

    Parameters
    ----------
    capacity : int
        The number of node rows of ``z``.
    n_models : int
        The number of linked models M.
    n_actions : int
        The number of planner actions.
    n_box : int
        The width 2p of one box ``[-lower | upper]``.
    substeps : int
        The number of sub-steps S per action (the rows of ``stack``).
    """
    return BoxArrays(
        z=np.empty((capacity, n_models, n_box)),
        stack=np.empty((substeps, n_models, n_actions, n_box)),
        root=np.empty((n_models, n_box)),
        actions=np.zeros(n_actions, dtype=np.int64),
        time=0,
    )


def grow_boxes(boxes: BoxArrays, capacity: int, size: int) -> BoxArrays:
    """``boxes`` with ``capacity`` node rows (the first ``size`` copied).

    Parameters
    ----------
    boxes : BoxArrays
        The arrays to grow (not modified).
    capacity : int
        The number of node rows of the new ``z``.
    size : int
        The number of nodes in use, whose rows are copied.
    """
    z = np.empty((capacity,) + boxes.z.shape[1:])
    z[:size] = boxes.z[:size]
    return boxes._replace(z=z)


@functools.cache
def search_kernel(params_type: type):
    """The compiled search for rewards whose ``kernel_params`` have type ``params_type``.

    Cached on disk by numba, keyed (through ``version``) by the sources it calls into:
    `tree_ops`, `box_kernels` and the reward family's module.
    """
    version = sources_digest(__file__, tree_ops.__file__, *reward_sources(params_type))

    def run_search(budget, tree, boxes, kernel, params, resume):
        """Expand ``tree`` (`tree_ops.TreeArrays`) from ``boxes.root`` until it holds ``budget`` expansions.

        Starts from the root alone, or with ``resume`` continues the search the arrays
        hold (after the caller grew them). Returns ``(status, bad)``: the status is
        `DONE` (budget spent), `SOLVED` (stopped because the root's bounds met) or
        `FULL` (the next expansion does not fit in the arrays: grow them and resume);
        ``bad >= 0`` reports a reward outside [0, 1] at the flat pair ``bad = a * M +
        m`` (value in ``tree.rewards[m, a]``), where the search stopped.
        """
        _ = version  # ties numba's cache entry to the sources it calls into
        # the arrays are read once into locals: every read of a field of a tuple costs a reference count
        z, stack, actions, time = boxes.z, boxes.stack, boxes.actions, boxes.time
        rewards, new_terminal, terminal, depth, counts = (
            tree.rewards,
            tree.new_terminal,
            tree.terminal,
            tree.depth,
            tree.counts,
        )
        n_models, n_actions = rewards.shape
        substeps, n_box = stack.shape[0], stack.shape[3]
        capacity = tree.parent.shape[0]
        scratch = np.empty((SCRATCH_ROWS, scratch_width(kernel, n_box)))
        if not resume:
            reset(tree)
            root = boxes.root  # copied element by element: an array assignment compiles numba's shape-error formatting
            for m in range(root.shape[0]):
                for j in range(root.shape[1]):
                    z[0, m, j] = root[m, j]
        while counts[N_EXPANDED] < budget:
            if counts[SIZE] + n_actions > capacity:
                return FULL, -1
            leaf = select(tree)
            if leaf < 0:
                return SOLVED, -1
            first = counts[SIZE]
            alive = False
            for m in range(n_models):
                if not terminal[leaf, m]:
                    alive = True
            if alive:
                propagate_into(z[leaf], actions, kernel, stack, scratch)
                pessimistic_rewards(stack, time + depth[leaf] * substeps, params, rewards, new_terminal)
                for a in range(n_actions):
                    for m in range(n_models):
                        for j in range(n_box):
                            z[first + a, m, j] = stack[substeps - 1, m, a, j]
            else:  # every model terminated: nothing is stepped (`expand` zeroes the rewards)
                for a in range(n_actions):
                    for m in range(n_models):
                        for j in range(n_box):
                            z[first + a, m, j] = z[leaf, m, j]
            bad = expand(tree, leaf)
            if bad >= 0:
                return DONE, bad
        return DONE, -1

    return compile_per_params_type(
        run_search, params_type, what="the planner's search kernel (tree search, box transitions, reward minima)"
    )
