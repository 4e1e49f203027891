"""Robust optimistic tree search over a finite set of models, and its M = 1 case (OPD).

The planners see models only through a small transition protocol:

- ``model.step(state, action) -> (next_state, reward)`` or
  ``(next_state, reward, terminal)``, with ``reward`` in [0, 1] (maximised);
- optionally ``model.expand(state, actions) -> (next_states, rewards, terminals)``:
  all actions (the planner's tuple) from one state in one batched call,
  ``next_states`` a sequence of ``len(actions)`` states, ``rewards`` a float array
  of shape ``(len(actions),)``, ``terminals`` a bool array of the same shape. When present it is used instead of
  ``step`` (the two must agree; the tree does not depend on which is used).

Linked models (`IntervalModel.linked`) also share one batched transition of all M
hypotheses; when the planner's models are exactly one such group, in member order,
and a node's models share one state, the planner takes all M results from that one
call (the same numbers `expand` returns per model).

After a terminal transition a model is never stepped again on that branch: its
later rewards are 0 and its state stays the terminal state.

Two engines run this search: the Python one below, for every model of the protocol,
and a compiled one (`minimaxplan.planners.compiled_search`) for linked `IntervalModel`s
whose reward has a compiled box minimum. They build the same tree bit for bit; the
``engine`` argument of `RobustTreePlanner` chooses, ``engine_used`` reports.

States are opaque to the planner and never copied: one state object may be shared
by several tree nodes (below a terminal transition) and, when `plan` gets one
initial state, by every model. Models must return new states, never modify a
given state in place.
"""

from __future__ import annotations

import numbers
from typing import Any, Sequence

import numpy as np

from ..models.errors import DimensionError, InputError, NonFiniteError, RewardRangeError
from .compiled_search import SearchArrays, search_kernel
from .decision import Decision
from .tree import SearchTree

__all__ = ["RobustTreePlanner", "OptimisticPlanner"]


class _Transitions:
    """Steps one model from one state by every action; checks the protocol's types."""

    __slots__ = ("index", "model", "actions", "n_actions", "_expand", "_step")

    def __init__(self, index: int, model: Any, actions: tuple) -> None:
        step = getattr(model, "step", None)
        if not callable(step):
            raise InputError(
                f"models[{index}] has no callable step(state, action); got {type(model).__name__}"
            )
        expand = getattr(model, "expand", None)
        self.index = index
        self.model = model
        self.actions = actions
        self.n_actions = len(actions)
        self._step = step
        self._expand = expand if callable(expand) else None

    def __call__(self, state) -> tuple[list, np.ndarray, np.ndarray]:
        if self._expand is not None:
            return self._batched(state)
        return self._one_by_one(state)

    def _batched(self, state) -> tuple[list, np.ndarray, np.ndarray]:
        out = self._expand(state, self.actions)
        if not isinstance(out, tuple) or len(out) != 3:
            raise InputError(
                f"models[{self.index}].expand(state, actions) must return a tuple "
                f"(next_states, rewards, terminals), got {_describe(out)}"
            )
        next_states, rewards, terminals = out
        n = self.n_actions
        if not hasattr(next_states, "__len__"):
            raise InputError(
                f"models[{self.index}].expand next_states must be a sequence of {n} states, "
                f"got {type(next_states).__name__}"
            )
        if len(next_states) != n:
            raise DimensionError(
                f"models[{self.index}].expand returned {len(next_states)} next states "
                f"for {n} actions"
            )
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
            raise InputError(
                f"models[{self.index}].expand terminals must be a bool array, got dtype {terminals.dtype}"
            )
        return next_states, rewards, terminals

    def _as_float_array(self, rewards) -> np.ndarray:
        try:
            return np.asarray(rewards, dtype=float)
        except (TypeError, ValueError):
            raise RewardRangeError(
                f"models[{self.index}].expand returned non-numeric rewards {rewards!r}"
            ) from None

    def _one_by_one(self, state) -> tuple[list, np.ndarray, np.ndarray]:
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
            try:
                rewards[a] = float(out[1])
            except (TypeError, ValueError):
                raise RewardRangeError(
                    f"models[{self.index}] returned a non-numeric reward {out[1]!r} for action "
                    f"{action!r} (index {a})"
                ) from None
            if len(out) == 3:
                terminals[a] = _as_flag(out[2], self.index, action, a)
        return next_states, rewards, terminals


def _joint_expand(models: list):
    """The shared ``expand`` of linked models, if ``models`` are exactly one group in member order."""
    joints = [getattr(model, "_joint", None) for model in models]
    if any(joint is None for joint in joints):
        return None
    group = joints[0][0]
    if getattr(group, "size", None) != len(models):
        return None
    if any(joint[0] is not group or joint[1] != m for m, joint in enumerate(joints)):
        return None
    return group.expand


def _compiled_group(models: list, joint):
    """The linked group whose search can run compiled (see `compiled_search`), or None."""
    if joint is None:
        return None
    group = models[0]._joint[0]
    if getattr(group, "compiled", False) and callable(getattr(group, "search_inputs", None)):
        return group
    return None


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
        f"models[{index}].step returned terminal={value!r} for action {action!r} (index {a}); "
        "expected a bool"
    )


def _check_gamma(gamma) -> float:
    try:
        value = float(gamma)
    except (TypeError, ValueError):
        raise InputError(f"gamma must be a real number in (0, 1), got {gamma!r}") from None
    if not np.isfinite(value):
        raise NonFiniteError(f"gamma must be finite and in (0, 1), got {value}")
    if not 0.0 < value < 1.0:
        raise InputError(f"gamma must be in the open interval (0, 1), got {value}")
    return value


def _check_count(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value}")
    return int(value)


class RobustTreePlanner:
    """Optimistic tree search for ``sup_a min_m sum_n gamma^n r_n^m`` (eqs. (15)-(18)).

    Parameters
    ----------
    models
        Non-empty sequence of M models following the transition protocol of this
        module (``step``, optionally ``expand``). Rewards must lie in [0, 1].
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
        models are one `IntervalModel.linked` group (or a single `IntervalModel`)
        whose reward has a compiled box minimum (``kernel_params``, as the
        `minimaxplan.scenarios` families do), and every model starts from the same
        state; ``"auto"`` uses it then and the Python engine otherwise, ``"compiled"``
        raises `InputError` when it cannot run. Both engines build the same tree bit
        for bit; `engine_used` says which one ran last.

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
    Internal nodes take the max over children of both (17)-(18). Each iteration
    expands the leaf with the largest b-value; ties go to the lexicographically
    smallest action path. The returned action maximises the lower bound at the root.

    Guarantees (Theorem 3, eq. (19)): ``L_root <= sup_a min_m sum_n gamma^n r_n^m <=
    U_root``; ``L_root`` never decreases and ``U_root`` never increases with K (the
    tree after K expansions is a prefix of the tree after K + 1); and the robust
    regret of the chosen first action is at most ``U_root - L_root``.
    """

    def __init__(self, models: Sequence, actions: Sequence, *, gamma: float, budget: int, seed: int = 0,
                 engine: str = "auto") -> None:
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
        self.gamma = _check_gamma(gamma)
        self.budget = _check_count("budget", budget, 1)
        self.seed = _check_count("seed", seed, 0)
        self.models = tuple(models)
        self.actions = actions
        self._transitions = [_Transitions(m, model, actions) for m, model in enumerate(models)]
        self._joint = _joint_expand(models)
        self._rewards = np.zeros((len(actions), len(models)))
        self._new_terminal = np.zeros((len(actions), len(models)), dtype=bool)
        if engine not in ENGINES:
            raise InputError(f"engine must be one of {ENGINES}, got {engine!r}")
        self.engine = engine
        self._compiled = None if engine == "python" else _compiled_group(self.models, self._joint)
        if engine == "compiled" and self._compiled is None:
            raise InputError(
                "engine='compiled' needs the models of one IntervalModel.linked group, in member order, "
                "whose reward has a compiled box minimum (kernel_params)"
            )
        self.engine_used: str | None = None
        self._arrays: SearchArrays | None = None
        self._tree: SearchTree | None = None
        self._compiled_result = None

    @property
    def tree(self) -> SearchTree | None:
        """The search tree of the last `plan` call (None before the first).

        After a compiled search the tree is copied out of the engine's arrays on first
        access.
        """
        if self._tree is None and self._compiled_result is not None:
            self._tree = self._materialise(*self._compiled_result)
        return self._tree

    @property
    def n_models(self) -> int:
        """Number of models M."""
        return len(self.models)

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
                raise InputError(
                    "with per_model=True, state must be a sequence of one state per model"
                ) from None
            if len(states) != n_models:
                raise DimensionError(
                    f"with per_model=True, state must hold {n_models} states (one per model), "
                    f"got {len(states)}"
                )
        else:
            states = [state] * n_models
        self._tree = self._compiled_result = None
        if self._compiled is not None and all(s is states[0] for s in states):
            return self._plan_compiled(states[0])
        if self.engine == "compiled":
            raise InputError("engine='compiled' needs one initial state shared by every model")
        self.engine_used = "python"
        tree = SearchTree(n_models, len(self.actions), self.gamma, max_nodes=1 + self.budget * len(self.actions))
        tree.add_root(states)
        self._tree = tree
        solved = self._search(tree)
        return self._decision(tree, solved)

    # ------------------------------------------------------------------ internals
    def _search(self, tree: SearchTree) -> bool:
        """Run the expansions; True if stopped early because ``lower == upper`` at the root.

        Each round expands the leaf of largest b-value, ties to the smallest action
        path (`SearchTree.pop_best_leaf`), then backs the bounds up to the root.
        """
        lower, upper = tree.lower, tree.upper
        for _ in range(self.budget):
            if upper[0] <= lower[0]:
                # The value is known exactly and the bounds are monotone: no expansion
                # can change them. This is also what happens when the best leaf has
                # every model terminated (its b-value equals its lower bound).
                return True
            leaf = tree.pop_best_leaf()
            self._expand(tree, leaf)
            tree.backup(leaf)
        return False

    def _expand(self, tree: SearchTree, leaf: int) -> int:
        if self._joint is not None and not tree.any_terminated[leaf]:
            first = self._expand_jointly(tree, leaf)
            if first is not None:
                return first
        n_actions = len(self.actions)
        # Scratch buffers, reused: add_children copies what it keeps.
        rewards, new_terminal = self._rewards, self._new_terminal
        terminal = tree.terminal[leaf]
        for m, transitions in enumerate(self._transitions):
            state = tree.states[m][leaf]
            if terminal[m]:
                tree.states[m].extend([state] * n_actions)
                rewards[:, m] = 0.0
                new_terminal[:, m] = True
                continue
            next_states, model_rewards, model_terminals = transitions(state)
            rewards[:, m] = model_rewards
            new_terminal[:, m] = model_terminals
            tree.states[m].extend(next_states)
        if not (rewards.min() >= 0.0 and rewards.max() <= 1.0):
            self._reward_error(rewards)
        return tree.add_children(leaf, rewards, new_terminal)

    def _expand_jointly(self, tree: SearchTree, leaf: int) -> int | None:
        """`_expand` for one linked group sharing the leaf's state; None to take the general path.

        The general path would ask each model in turn and get row m of this same
        cached batched result, so the children are the same; shapes and dtypes are
        checked here once (on a mismatch the general path reports the error).
        """
        state_lists = tree.states
        state = state_lists[0][leaf]
        for states in state_lists:
            if states[leaf] is not state:
                return None
        next_states, rewards, terminals = self._joint(state, self.actions)
        shape = (len(state_lists), len(self.actions))
        if (
            type(rewards) is not np.ndarray or rewards.dtype != np.float64 or rewards.shape != shape
            or type(terminals) is not np.ndarray or terminals.dtype != bool or terminals.shape != shape
            or len(next_states) != shape[1]
        ):
            return None
        for states in state_lists:
            states.extend(next_states)
        rewards = rewards.T
        if not (np.minimum.reduce(rewards, axis=None) >= 0.0 and np.maximum.reduce(rewards, axis=None) <= 1.0):
            self._reward_error(rewards)
        return tree.add_children(leaf, rewards, terminals.T)

    def _reward_error(self, rewards: np.ndarray) -> None:
        bad = ~((rewards >= 0.0) & (rewards <= 1.0))
        a, m = (int(i) for i in np.argwhere(bad)[0])
        self._raise_reward_error(a, m, float(rewards[a, m]))

    def _raise_reward_error(self, a: int, m: int, value: float) -> None:
        raise RewardRangeError(
            f"models[{m}] returned reward {value!r} for action {self.actions[a]!r} "
            f"(index {a}); rewards must be finite and in [0, 1]"
        )

    # ---------------------------------------------------------- compiled engine
    def _plan_compiled(self, state) -> Decision:
        """`plan` on the compiled engine: same tree, same `Decision` (see `compiled_search`)."""
        group = self._compiled
        root, time, index, kernel, params, substeps = group.search_inputs(state, self.actions)
        n_actions, n_models = len(self.actions), self.n_models
        max_nodes = 1 + self.budget * n_actions
        if self._arrays is None:
            self._arrays = SearchArrays(max_nodes, n_models, n_actions, root.shape[1], substeps, self.budget)
            self._discounts = np.array([self.gamma ** d for d in range(self.budget + 2)])
        arrays = self._arrays
        self.engine_used = "compiled"
        size, n_expanded, solved, max_depth, bad_action, bad_model = search_kernel(type(params))(
            self.budget, self.gamma, self._discounts, root, time, index, substeps, kernel, params,
            arrays.z, arrays.returns, arrays.terminal, arrays.parent, arrays.action, arrays.depth,
            arrays.first_child, arrays.leaf_lower, arrays.leaf_upper, arrays.lower, arrays.upper,
            arrays.any_terminated, arrays.expanded, arrays.heap, arrays.stack, arrays.rewards, arrays.collided,
            arrays.error,
        )
        if bad_action >= 0:
            self._raise_reward_error(int(bad_action), int(bad_model), float(arrays.error[0]))
        self._compiled_result = (state, time, size, n_expanded, max_depth)
        first_child, lower = arrays.first_child, arrays.lower
        first = int(first_child[0])
        path, node = [], 0
        while first_child[node] >= 0:
            start = int(first_child[node])
            a = int(np.argmax(lower[start:start + n_actions]))
            path.append(a)
            node = start + a
        return Decision(
            action=self.actions[path[0]],
            action_index=path[0],
            lower=float(lower[0]),
            upper=float(arrays.upper[0]),
            expansions=int(n_expanded),
            depth=int(max_depth),
            sequence=tuple(self.actions[a] for a in path),
            sequence_indices=tuple(path),
            action_lower=tuple(lower[first:first + n_actions].tolist()),
            action_upper=tuple(arrays.upper[first:first + n_actions].tolist()),
            nodes=int(size),
            solved=bool(solved),
        )

    def _materialise(self, root_state, time: int, size: int, n_expanded: int, max_depth: int) -> SearchTree:
        """The `SearchTree` of the last compiled search, with the states the Python engine would hold."""
        arrays = self._arrays
        depth = arrays.depth[:size].tolist()
        joint = self._compiled.node_states(arrays.z[:size].copy(), depth, time)
        parent, terminal = arrays.parent[:size].tolist(), arrays.terminal
        states = []
        for m in range(self.n_models):
            # a terminated model keeps its terminal state on the rest of the branch
            column = [root_state] + [None] * (size - 1)
            for i in range(1, size):
                column[i] = column[parent[i]] if terminal[parent[i], m] else joint[i]
            states.append(column)
        return SearchTree.from_arrays(arrays, size, n_expanded, max_depth, self.gamma, 1 + self.budget * len(self.actions), states)

    def _decision(self, tree: SearchTree, solved: bool) -> Decision:
        n_actions = len(self.actions)
        first = int(tree.first_child[0])
        action_lower = tuple(float(v) for v in tree.lower[first:first + n_actions])
        action_upper = tuple(float(v) for v in tree.upper[first:first + n_actions])
        path = tree.best_path()
        return Decision(
            action=self.actions[path[0]],
            action_index=path[0],
            lower=float(tree.lower[0]),
            upper=float(tree.upper[0]),
            expansions=len(tree.expanded),
            depth=int(tree.max_depth),
            sequence=tuple(self.actions[a] for a in path),
            sequence_indices=path,
            action_lower=action_lower,
            action_upper=action_upper,
            nodes=int(tree.size),
            solved=solved,
        )


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
