"""Robust optimistic tree search over a finite set of models, and its M = 1 case (OPD).

The planners see models only through the protocols of
`minimaxplan.planners.protocols`: each model is a `TransitionModel`
(``step(state, action)``), optionally a `VectorisedModel` (``expand(state, actions)``,
used instead of ``step``); models computed together (`IntervalModel.linked`) are
`LinkedModel`s of one `BatchedTransitions` group, and when the planner's models are
exactly that group, in member order, and a node's models share one state, all M
transitions come from one ``expand_all`` call (the same numbers each member's
``expand`` returns).

After a terminal transition a model is never stepped again on that branch: its
later rewards are 0 and its state stays the terminal state.

Two engines run this search, on one tree layout with one implementation of every
tree operation (`minimaxplan.planners.tree_ops`): the Python engine below, a Python
loop that asks the models for each leaf's transitions, and the compiled engine
(`minimaxplan.planners.compiled_search`), one numba kernel per search that computes
the transitions of a `CompiledTransitions` group with the compiled box kernel. The
``engine`` argument of `RobustTreePlanner` chooses, ``engine_used`` reports.
"""

from __future__ import annotations

import functools
import numbers
from collections.abc import Callable, Sequence, Sized
from typing import Any

import numpy as np

from ..models.errors import DimensionError, InputError, RewardRangeError
from ..models.validation import as_choice, as_count, as_discount
from . import tree_ops
from .compiled_search import FULL, SOLVED, BoxArrays, allocate_boxes, grow_boxes, search_kernel
from .decision import Decision
from .protocols import (
    BatchedTransitions,
    CompiledTransitions,
    FallbackModel,
    LinkedModel,
    TransitionModel,
    VectorisedModel,
)
from .tree import SearchTree
from .tree_ops import REWARD_ERROR, TreeArrays

__all__ = ["RobustTreePlanner", "OptimisticPlanner"]

#: Rows a search's tree arrays start with; they double when full, up to the budget's tree.
INITIAL_TREE_ROWS = 4096
#: The largest tree a planner may be asked to build, ``1 + budget * len(actions)`` nodes (int32 indices).
MAX_TREE_NODES = 2**31 - 1


class _Transitions:
    """Steps one `TransitionModel` from one state by every action (``expand`` if it has one); checks the types."""

    __slots__ = ("index", "model", "actions", "n_actions", "_expand", "_step")

    def __init__(self, index: int, model: Any, actions: tuple) -> None:
        if not (isinstance(model, TransitionModel) and callable(model.step)):
            raise InputError(f"models[{index}] has no callable step(state, action); got {type(model).__name__}")
        self.index = index
        self.model = model
        self.actions = actions
        self.n_actions = len(actions)
        self._step = model.step
        self._expand: Callable[[Any, tuple], Any] | None = (
            model.expand if isinstance(model, VectorisedModel) and callable(model.expand) else None
        )

    def __call__(self, state) -> tuple[Sequence, np.ndarray, np.ndarray]:
        expand = self._expand
        if expand is not None:
            return self._batched(expand, state)
        return self._one_by_one(state)

    def _batched(self, expand: Callable[[Any, tuple], Any], state) -> tuple[Sequence, np.ndarray, np.ndarray]:
        out = expand(state, self.actions)
        if not isinstance(out, tuple) or len(out) != 3:
            raise InputError(
                f"models[{self.index}].expand(state, actions) must return a tuple "
                f"(next_states, rewards, terminals), got {_describe(out)}"
            )
        next_states: Sequence  # what the caller reads; checked only to be Sized (a numpy array of states is one)
        next_states, rewards, terminals = out
        n = self.n_actions
        if not isinstance(next_states, Sized):
            raise InputError(
                f"models[{self.index}].expand next_states must be a sequence of {n} states, "
                f"got {type(next_states).__name__}"
            )
        if len(next_states) != n:
            raise DimensionError(f"models[{self.index}].expand returned {len(next_states)} next states for {n} actions")
        if type(rewards) is not np.ndarray or rewards.dtype != np.float64:
            rewards = self._as_float_array(rewards)
        if rewards.shape != (n,):
            raise DimensionError(
                f"models[{self.index}].expand rewards must have shape ({n},), got shape {rewards.shape}"
            )
        if type(terminals) is not np.ndarray:
            terminals = np.asarray(terminals)
        if terminals.shape != (n,):
            raise DimensionError(
                f"models[{self.index}].expand terminals must have shape ({n},), got shape {terminals.shape}"
            )
        if terminals.dtype != bool:
            raise InputError(f"models[{self.index}].expand terminals must be a bool array, got dtype {terminals.dtype}")
        return next_states, rewards, terminals

    def _as_float_array(self, rewards) -> np.ndarray:
        try:
            raw = np.asarray(rewards)
            if raw.dtype.kind in "USbc" or (
                raw.dtype.kind == "O" and any(isinstance(r, _NOT_A_REWARD) for r in raw.flat)
            ):
                raise TypeError
            return raw.astype(float, copy=False)
        except (TypeError, ValueError, OverflowError):
            raise RewardRangeError(f"models[{self.index}].expand returned non-numeric rewards {rewards!r}") from None

    def _one_by_one(self, state) -> tuple[Sequence, np.ndarray, np.ndarray]:
        n = self.n_actions
        next_states = [None] * n
        rewards = np.empty(n)
        terminals = np.zeros(n, dtype=bool)
        for a, action in enumerate(self.actions):
            out = self._step(state, action)
            if not isinstance(out, tuple) or len(out) not in (2, 3):
                raise InputError(
                    f"models[{self.index}].step(state, action) must return (next_state, reward) "
                    f"or (next_state, reward, terminal), got {_describe(out)} for action "
                    f"{action!r} (index {a})"
                )
            next_states[a] = out[0]
            reward = out[1]
            try:
                if isinstance(reward, _NOT_A_REWARD):  # float() would parse "0.5" and take True as 1
                    raise TypeError
                rewards[a] = float(reward)
            except (TypeError, ValueError, OverflowError):
                raise RewardRangeError(
                    f"models[{self.index}] returned a non-numeric reward {out[1]!r} for action {action!r} (index {a})"
                ) from None
            if len(out) == 3:
                terminals[a] = _as_flag(out[2], self.index, action, a)
        return next_states, rewards, terminals


#: Types that float() converts but that are not a reward: numeric text and truth values.
_NOT_A_REWARD = (str, bytes, bool, np.bool_)


def _linked_group(models: Sequence) -> BatchedTransitions | None:
    """The `BatchedTransitions` group whose members are exactly ``models``, in member order, or None."""
    first = models[0]
    if not isinstance(first, LinkedModel):
        return None
    group = first.group
    if not isinstance(group, BatchedTransitions) or group.size != len(models):
        return None
    for m, model in enumerate(models):
        if not isinstance(model, LinkedModel) or model.group is not group or model.member != m:
            return None
    return group


ENGINES = ("auto", "compiled", "python")


def _describe(out) -> str:
    if isinstance(out, tuple):
        return f"a tuple of length {len(out)}"
    return f"an object of type {type(out).__name__}"


def _as_flag(value, index: int, action, a: int) -> bool:
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, numbers.Integral) and value in (0, 1):
        return bool(value)
    raise InputError(
        f"models[{index}].step returned terminal={value!r} for action {action!r} (index {a}); expected a bool"
    )


class RobustTreePlanner:
    """Optimistic tree search for ``sup_a min_m sum_n gamma^n r_n^m`` (eqs. (15)-(18)).

    Parameters
    ----------
    models
        Non-empty sequence of M `TransitionModel`s (``step``, optionally
        ``expand``: `minimaxplan.planners.protocols`). Rewards must lie in [0, 1].
    actions
        Non-empty sequence of actions, passed unchanged to the models. Ties between
        actions are broken by their index in this sequence.
    gamma
        Discount factor, 0 < gamma < 1.
    budget
        Number of expansions K >= 1 (fewer are made only once ``lower == upper`` at
        the root). Each expansion creates ``len(actions)`` children and steps every
        not-yet-terminated model once per action, i.e. at most ``K * |A| * M``
        model transitions per `plan` call.
    seed
        Accepted for interface stability and validated (an integer); it currently
        has no effect: every tie (equal b-values, equal lower bounds) is broken
        deterministically by action path, so the search is a deterministic function
        of the models and the state.
    engine
        ``"auto"`` (default), ``"compiled"`` or ``"python"``. The compiled engine
        (`minimaxplan.planners.compiled_search`, numba) runs the whole search when the
        models are the members of one `CompiledTransitions` group, in member order (an
        `IntervalModel.linked` group, or a single `IntervalModel`, whose reward has a
        compiled box minimum, ``kernel_params``, as the `minimaxplan.scenarios`
        families do), and every model starts from the same state; ``"auto"`` uses it
        then and the Python engine otherwise, ``"compiled"`` raises `InputError` when
        it cannot run. Both engines run the same tree operations
        (`minimaxplan.planners.tree_ops`) and differ only in where the transitions
        come from; `engine_used` says which one ran last.

    Notes
    -----
    Budget accounting differs from the public reference (rl-agents'
    ``OptimisticDeterministicPlanner`` and ``DiscreteRobustPlanner``): there
    ``budget`` counts created tree nodes, i.e. simulator calls of the joint
    environment, and the search runs ``budget // |A|`` expansions, each node stepping
    all M model environments. A reference budget B corresponds to
    ``budget = B // |A|`` here.

    Each leaf ``a`` of depth ``l`` holds the discounted return of each model,
    ``R_m(a) = sum_{n<l} gamma^n r_n^m``. Its robust lower bound (18) is
    ``L_a = min_m R_m(a)`` and its robust b-value (16), with the discount that the
    paper's eq. (12) omits (see DESIGN.md errata), is
    ``U_a = min_m (R_m(a) + gamma^l / (1 - gamma) [m not terminated])``.
    Internal nodes take the max over children of both (17)-(18). When every model is
    a `FallbackModel` (the Python engine), a leaf's lower bound is
    ``min_m (R_m(a) + gamma^l F_m)`` with F_m the model's bound on a fixed
    continuation from the leaf's state: the leaf's path followed by that continuation
    is one plan, so this is still a lower bound, and the search prefers paths that
    end where the continuation is safe. Each iteration
    expands the leaf with the largest b-value; ties go to the lexicographically
    smallest action path. The returned action maximises the lower bound at the root.

    Guarantees (Theorem 3, eq. (19)): ``L_root <= sup_a min_m sum_n gamma^n r_n^m <=
    U_root``; ``L_root`` never decreases and ``U_root`` never increases with K (the
    tree after K expansions is a prefix of the tree after K + 1); and the robust
    regret of the chosen first action is at most ``U_root - L_root``.
    """

    def __init__(
        self, models: Sequence, actions: Sequence, *, gamma: float, budget: int, seed: int = 0, engine: str = "auto"
    ) -> None:
        try:
            models = list(models)
        except TypeError:
            raise InputError(f"models must be a sequence of models, got {type(models).__name__}") from None
        if not models:
            raise InputError("models must be a non-empty sequence of models")
        try:
            actions = tuple(actions)
        except TypeError:
            raise InputError(f"actions must be a sequence, got {type(actions).__name__}") from None
        if not actions:
            raise InputError("actions must be a non-empty sequence")
        self._gamma = as_discount("gamma", gamma)
        self._budget = as_count("budget", budget)
        if 1 + self._budget * len(actions) > MAX_TREE_NODES:
            raise InputError(
                f"budget must be at most {(MAX_TREE_NODES - 1) // len(actions)} with {len(actions)} actions "
                f"(the tree holds 1 + budget * len(actions) nodes, at most {MAX_TREE_NODES}), got {budget}"
            )
        self._seed = as_count("seed", seed, minimum=0)
        self._models = tuple(models)
        self._actions = actions
        self._transitions = [_Transitions(m, model, actions) for m, model in enumerate(models)]
        self._group = _linked_group(self._models)
        self._fallback = all(isinstance(model, FallbackModel) and callable(model.fallback_values) for model in models)
        engine = as_choice("engine", engine, ENGINES)
        self._engine = engine
        group = self._group
        self._compiled = (
            group
            if engine != "python" and isinstance(group, CompiledTransitions) and group.compiled and not self._fallback
            else None
        )
        if engine == "compiled" and self._fallback:
            raise InputError(
                "engine='compiled' does not evaluate the models' continuation bounds (FallbackModel.fallback_values); "
                "use engine='python' or 'auto'"
            )
        if engine == "compiled" and self._compiled is None:
            raise InputError(
                "engine='compiled' needs the models of one IntervalModel.linked group, in member order, "
                "whose reward has a compiled box minimum (kernel_params)"
            )
        self.engine_used: str | None = None
        self._max_nodes = 1 + self._budget * len(actions)
        self._discounts = tree_ops.discount_table(self._gamma, 2)
        # The arrays of the last search, reused by the next one unless `tree` handed them out.
        self._arrays: TreeArrays | None = None
        self._boxes: BoxArrays | None = None
        self._tree: SearchTree | None = None
        self._tree_shared = False

    @property
    def tree(self) -> SearchTree | None:
        """The search tree of the last `plan` call (None before the first), a read-only view.

        After a compiled search the models' states are built from the engine's boxes on
        first access of ``tree.states``.
        """
        self._tree_shared = self._tree is not None
        return self._tree

    @property
    def models(self) -> tuple:
        """The M models, in order (read-only)."""
        return self._models

    @property
    def actions(self) -> tuple:
        """The actions, in index order (read-only)."""
        return self._actions

    @property
    def gamma(self) -> float:
        """The discount factor in (0, 1) (read-only)."""
        return self._gamma

    @property
    def budget(self) -> int:
        """The number of expansions K per `plan` call (read-only)."""
        return self._budget

    @property
    def seed(self) -> int:
        """The validated seed (no effect: ties are broken by action path; read-only)."""
        return self._seed

    @property
    def engine(self) -> str:
        """The requested engine: ``"auto"``, ``"compiled"`` or ``"python"`` (read-only)."""
        return self._engine

    @property
    def n_models(self) -> int:
        """Number of models M."""
        return len(self._models)

    def plan(self, state, *, per_model: bool = False) -> Decision:
        """Search from ``state`` with the full budget and return the `Decision`.

        Parameters
        ----------
        state
            The initial state, shared by every model (the usual case: one measured
            state). With ``per_model=True``, a sequence of M states, one per model
            in the order of ``models``.
        per_model
            Whether ``state`` holds one initial state per model.

        Returns
        -------
        Decision
            The chosen action and the root bounds. The tree itself stays available
            as ``self.tree`` until the next call.
        """
        n_models = self.n_models
        if per_model:
            try:
                states = list(state)
            except TypeError:
                raise InputError("with per_model=True, state must be a sequence of one state per model") from None
            if len(states) != n_models:
                raise DimensionError(
                    f"with per_model=True, state must hold {n_models} states (one per model), got {len(states)}"
                )
        else:
            states = [state] * n_models
        if self._tree_shared:  # a caller holds the last tree: search in new arrays
            self._arrays = self._boxes = None
            self._tree_shared = False
        self._tree = None
        compiled = self._compiled
        if compiled is not None and all(s is states[0] for s in states):
            self.engine_used = "compiled"
            tree, solved, node_states = self._search_compiled(compiled, states[0])
        elif self.engine == "compiled":
            raise InputError("engine='compiled' needs one initial state shared by every model")
        else:
            self.engine_used = "python"
            tree, solved, node_states = self._search_python(states)
        self._tree = SearchTree(tree, node_states)
        return Decision.from_tree(self._tree, self.actions, solved=solved)

    # ------------------------------------------------------------ the tree arrays
    def _tree_arrays(self) -> TreeArrays:
        """The arrays of the last search (unless `tree` handed them out), else new ones of the first size."""
        arrays = self._arrays
        if arrays is None:
            capacity = min(self._max_nodes, INITIAL_TREE_ROWS)
            arrays = self._arrays = tree_ops.allocate(
                capacity, self.n_models, len(self.actions), self.gamma, self._discount_table(capacity)
            )
        return arrays

    def _grown_capacity(self, tree: TreeArrays, needed: int) -> int:
        """Twice the rows of ``tree`` (at least ``needed``), at most the budget's tree."""
        return max(min(2 * tree.parent.shape[0], self._max_nodes), needed)

    def _discount_table(self, capacity: int) -> np.ndarray:
        needed = (capacity - 1) // len(self.actions) + 2
        if self._discounts.shape[0] < needed:
            self._discounts = tree_ops.discount_table(self.gamma, needed)
        return self._discounts

    # ------------------------------------------------------------ Python engine
    def _search_python(self, states: list) -> tuple[TreeArrays, bool, list]:
        """Run the expansions, asking the models; ``solved`` if stopped early because ``lower == upper`` at the root.

        Each round expands the leaf of largest b-value, ties to the smallest action
        path, then backs the bounds up to the root (`tree_ops.expand_and_select`).
        """
        n_actions, budget = len(self.actions), self.budget
        tree = self._tree_arrays()
        state_lists = [[s] for s in states]
        leaf = tree_ops.start(tree)
        for k in range(budget):
            if leaf < 0:
                return tree, True, state_lists
            needed = 1 + (k + 1) * n_actions
            if needed > tree.parent.shape[0]:
                capacity = self._grown_capacity(tree, needed)
                tree = self._arrays = tree_ops.grow(tree, capacity, self._discount_table(capacity))
            self._transitions_of(tree, leaf, state_lists)
            leaf = tree_ops.expand_and_select(tree, leaf, k + 1 < budget)
            if leaf <= REWARD_ERROR:
                self._raise_reward_error(tree, REWARD_ERROR - leaf)
        return tree, False, state_lists

    def _transitions_of(self, tree: TreeArrays, leaf: int, state_lists: list) -> None:
        """Write ``leaf``'s transitions into ``tree.rewards``/``new_terminal``; append the children's states."""
        group = self._group
        if (
            group is not None
            and not tree.any_terminated[leaf]
            and self._transitions_jointly(group, tree, leaf, state_lists)
        ):
            self._fallbacks_of(tree, leaf, state_lists)
            return
        n_actions = len(self.actions)
        rewards, new_terminal = tree.rewards, tree.new_terminal
        terminal = tree.terminal[leaf]
        for m, transitions in enumerate(self._transitions):
            state = state_lists[m][leaf]
            if terminal[m]:
                # not stepped again: `tree_ops.expand` sets its rewards to 0, terminal
                state_lists[m].extend([state] * n_actions)
                continue
            next_states, model_rewards, model_terminals = transitions(state)
            rewards[m] = model_rewards
            new_terminal[m] = model_terminals
            state_lists[m].extend(next_states)
        self._fallbacks_of(tree, leaf, state_lists)

    def _fallbacks_of(self, tree: TreeArrays, leaf: int, state_lists: list) -> None:
        """Write the continuation bounds of ``leaf``'s children into ``tree.fallback`` (`FallbackModel`s only)."""
        if not self._fallback:
            return
        n_actions = len(self.actions)
        bound = 1.0 / (1.0 - self.gamma)
        terminal = tree.terminal[leaf]
        for m, model in enumerate(self._models):
            if terminal[m]:
                continue  # `tree_ops.expand` sets its bounds to 0
            children = state_lists[m][-n_actions:]
            values = np.asarray(model.fallback_values(children, self.gamma), dtype=float)
            if values.shape != (n_actions,):
                raise DimensionError(
                    f"models[{m}].fallback_values must return shape ({n_actions},), got shape {values.shape}"
                )
            if not np.all((values >= 0.0) & (values <= bound)):
                raise RewardRangeError(
                    f"models[{m}].fallback_values returned {values.tolist()!r}; "
                    f"continuation bounds must be finite and in [0, 1 / (1 - gamma)] = [0, {bound!r}]"
                )
            tree.fallback[m] = values

    def _transitions_jointly(self, group: BatchedTransitions, tree: TreeArrays, leaf: int, state_lists: list) -> bool:
        """`_transitions_of` from one ``expand_all`` of the group, if the leaf's models share one state.

        False to take the per-model path: the models' states differ, or the group's
        result has unexpected types (the per-model path would ask each member in turn
        and get row m of this same result, and reports such errors).
        """
        state = state_lists[0][leaf]
        for states in state_lists:
            if states[leaf] is not state:
                return False
        next_states, rewards, terminals = group.expand_all(state, self.actions)
        shape = tree.rewards.shape
        if (
            type(rewards) is not np.ndarray
            or rewards.dtype != np.float64
            or rewards.shape != shape
            or type(terminals) is not np.ndarray
            or terminals.dtype != bool
            or terminals.shape != shape
            or len(next_states) != shape[1]
        ):
            return False
        tree.rewards[:] = rewards
        tree.new_terminal[:] = terminals
        for states in state_lists:
            states.extend(next_states)
        return True

    def _raise_reward_error(self, tree: TreeArrays, pair: int) -> None:
        a, m = divmod(int(pair), self.n_models)
        raise RewardRangeError(
            f"models[{m}] returned reward {float(tree.rewards[m, a])!r} for action {self.actions[a]!r} "
            f"(index {a}); rewards must be finite and in [0, 1]"
        )

    # ---------------------------------------------------------- compiled engine
    def _search_compiled(self, group: CompiledTransitions, state) -> tuple[TreeArrays, bool, Any]:
        """`_search_python` with the transitions computed by ``group`` in the compiled box kernel (`compiled_search`)."""
        problem = group.compiled_problem(state, self.actions)
        tree = self._tree_arrays()
        boxes = self._boxes
        if boxes is None or boxes.z.shape[0] != tree.parent.shape[0] or boxes.stack.shape[0] != problem.substeps:
            boxes = allocate_boxes(
                tree.parent.shape[0], self.n_models, len(self.actions), problem.root.shape[1], problem.substeps
            )
        boxes = self._boxes = boxes._replace(root=problem.root, actions=problem.actions, time=int(problem.time))
        params_type: type = type(problem.params)
        kernel = search_kernel(params_type)
        status, bad = kernel(self.budget, tree, boxes, problem.kernel, problem.params, False)
        while status == FULL:  # only for budgets beyond the first rows: grow, then resume where it stopped
            capacity = self._grown_capacity(tree, tree.parent.shape[0] + len(self.actions))
            tree = self._arrays = tree_ops.grow(tree, capacity, self._discount_table(capacity))
            boxes = self._boxes = grow_boxes(boxes, capacity, int(tree.counts[tree_ops.SIZE]))
            status, bad = kernel(self.budget, tree, boxes, problem.kernel, problem.params, True)
        if bad >= 0:
            self._raise_reward_error(tree, bad)
        solved = status == SOLVED
        return tree, bool(solved), functools.partial(self._node_states, group, tree, boxes, state)

    def _node_states(self, group: CompiledTransitions, tree: TreeArrays, boxes: BoxArrays, root_state) -> list:
        """``states[m][i]`` of a compiled search: the objects the Python engine would hold."""
        size = int(tree.counts[tree_ops.SIZE])
        depth = tree.depth[:size].tolist()
        joint = group.node_states(boxes.z[:size].copy(), depth, boxes.time)
        parent, terminal = tree.parent[:size].tolist(), tree.terminal
        states = []
        for m in range(self.n_models):
            # a terminated model keeps its terminal state on the rest of the branch
            column = [root_state] + [None] * (size - 1)
            for i in range(1, size):
                column[i] = column[parent[i]] if terminal[parent[i], m] else joint[i]
            states.append(column)
        return states


class OptimisticPlanner(RobustTreePlanner):
    """Optimistic planning for deterministic systems (OPD, Hren & Munos 2008).

    The single-model case of `RobustTreePlanner` (same search engine, M = 1).

    Parameters
    ----------
    model
        One model following the transition protocol (``step``, optionally
        ``expand``); rewards in [0, 1].
    actions, gamma, budget, engine
        As for `RobustTreePlanner`.

    Notes
    -----
    Expands the leaf maximising the discounted b-value
    ``sum_{n<l} gamma^n r_n + gamma^l / (1 - gamma)`` (eq. (12) with the discount the
    paper omits), or ``sum_{n<l} gamma^n r_n`` alone below a terminal transition.
    Simple regret of the returned action: at most ``upper - lower``, which is
    ``O(K^(-log(1/gamma) / log kappa))`` (Lemma 1, eq. (13)).
    """

    def __init__(self, model: Any, actions: Sequence, *, gamma: float, budget: int, engine: str = "auto") -> None:
        super().__init__([model], actions, gamma=gamma, budget=budget, engine=engine)

    @property
    def model(self) -> Any:
        """The single model."""
        return self.models[0]
