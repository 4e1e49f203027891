"""The interval-model adapter: an uncertain system as a planner model whose state is a box.

`IntervalModel` turns a system, a parameter set, a reward family with an exact box
minimum and one low-level controller per action into a model for
`RobustTreePlanner`. Its state is a `BoxState` (a box of plant states and the
absolute sub-step index); a transition holds the action's controller for
``substeps`` sub-steps, propagating the box with the interval predictor, and returns
the pessimistic reward of Theorem 1: the exact minimum of the reward over every
sub-step box between the two decisions (terminal as soon as one of those boxes may
collide).

The planner never imports `minimaxplan.scenarios`: the reward is any object of the
`minimaxplan.kernels.BoxReward` protocol, ``box_minimum(lower, upper, t) -> (reward,
collided)`` (and, optionally, the unchecked ``box_minimum_raw`` with the same meaning).
A reward of the `minimaxplan.kernels.CompiledBoxReward` protocol (its ``kernel_params``
registered with `minimaxplan.kernels.register_reward_params`) has its minimum evaluated
in compiled code, and lets `RobustTreePlanner` run its compiled engine
(`docs/rewards.md`).

The box arithmetic is compiled (`minimaxplan.planners.box_kernels`, its matrices
built by `minimaxplan.planners.interval_kernel`); the hypotheses of one planner are
stepped together by an `IntervalGroup`, which this module wraps as `BoxState` objects.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..kernels import BoxReward, CompiledBoxReward, StateIndexedReward, UncheckedBoxReward, has_compiled_minimum
from ..models.errors import DimensionError, EmptySetError, InputError
from ..models.prediction import IntervalPredictor
from ..models.sets import Box
from ..models.system import UncertainLinearSystem
from ..models.validation import as_count, as_finite_array, check_instance
from .box_kernels import propagate, stack_rewards_kernel
from .controllers import ControllerBank
from .interval_kernel import build_interval_kernel
from .protocols import CompiledProblem

__all__ = ["BoxState", "IntervalGroup", "IntervalModel"]


class BoxState:
    """A planner state of `IntervalModel`: the box ``[lower, upper]`` at sub-step ``time``.

    Immutable by convention (its arrays are read-only views). Build root states with
    `IntervalModel.initial_state`; the planner creates the others.

    Parameters
    ----------
    lower, upper : ndarray, shape (p,) or (M, p)
        The box's corners, in the plant's state units: one box, or one per hypothesis
        for the states of linked models (`IntervalModel.linked`). Stored as given
        (pass read-only arrays).
    time : int
        The absolute sub-step index t of the box (the reward's time argument).
    z : ndarray, shape (2p,) or (M, 2p), optional
        The same box as ``[-lower | upper]``, the form the compiled arithmetic works
        on; computed on first use when None.

    Attributes
    ----------
    time : int
        As given.

    Notes
    -----
    The box ``[lower, upper]`` is the interval prediction of eq. (9): it contains
    every state the plant can reach under the model's parameter set and
    disturbances (inclusion property (7)).
    """

    __slots__ = ("_lower", "_upper", "time", "_z", "_source")

    def __init__(self, lower: np.ndarray, upper: np.ndarray, time: int, z: np.ndarray | None = None) -> None:
        self._lower: np.ndarray | None = lower
        self._upper: np.ndarray | None = upper
        self.time = time
        self._z: np.ndarray | None = z
        # (lower, upper, z, key) of a batched transition: the arrays this state's views are taken from
        self._source: tuple[np.ndarray, np.ndarray, np.ndarray, Any] | None = None

    @classmethod
    def _from_batch(cls, lower: np.ndarray, upper: np.ndarray, z: np.ndarray, key: Any, time: int) -> BoxState:
        """The state ``lower[key], upper[key]`` of a batched transition, its views taken on first use.

        Most children of the search tree are never expanded nor inspected, so the
        planner's hot path creates their states without slicing.
        """
        state = cls.__new__(cls)
        state._lower = state._upper = state._z = None
        state.time = time
        state._source = (lower, upper, z, key)
        return state

    @property
    def lower(self) -> np.ndarray:
        """The lower corner(s) of the box, shape (p,) or (M, p) (read-only)."""
        if self._lower is None:
            self._lower = self._batch_view(0)
        return self._lower

    @property
    def upper(self) -> np.ndarray:
        """The upper corner(s) of the box, shape (p,) or (M, p) (read-only)."""
        if self._upper is None:
            self._upper = self._batch_view(1)
        return self._upper

    @property
    def z(self) -> np.ndarray:
        """The box as ``[-lower | upper]``, shape (2p,) or (M, 2p) (read-only), as the arithmetic stores it."""
        if self._z is None and self._source is not None:
            self._z = self._batch_view(2)
        if self._z is None:
            z = np.concatenate([-np.asarray(self.lower, dtype=float), np.asarray(self.upper, dtype=float)], axis=-1)
            z.setflags(write=False)
            self._z = z
        return self._z

    def _batch_view(self, which: int) -> np.ndarray:
        """This state's view of array ``which`` (0: lower, 1: upper, 2: z) of the batch it was created from."""
        source = self._source
        if source is None:  # only `_from_batch` leaves a corner unset
            raise InputError("a BoxState needs lower and upper (see IntervalModel.initial_state)")
        return source[which][source[3]]

    def __iter__(self):
        return iter((self.lower, self.upper, self.time))

    def __repr__(self) -> str:
        return f"BoxState(lower={np.asarray(self.lower).tolist()}, upper={np.asarray(self.upper).tolist()}, time={self.time})"


def _check_reward(reward, nstates: int):
    """The box minimum a model calls on ``reward`` (`BoxReward`), checked against ``nstates``."""
    if not isinstance(reward, BoxReward) or not callable(reward.box_minimum):
        raise InputError(
            f"reward must have a callable box_minimum(lower, upper, t) -> (reward, collided), got {type(reward).__name__}"
        )
    needed = reward.min_state_dim if isinstance(reward, StateIndexedReward) else None
    if needed is not None and needed > nstates:
        raise DimensionError(
            f"reward reads state coordinates up to index {needed - 1}, but the system has {nstates} states"
        )
    if isinstance(reward, UncheckedBoxReward) and callable(reward.box_minimum_raw):
        return reward.box_minimum_raw
    return reward.box_minimum


def _kernel_params(reward):
    """``reward.kernel_params`` of a `CompiledBoxReward`; None for any other reward."""
    return reward.kernel_params if isinstance(reward, CompiledBoxReward) else None


def _as_result_array(name: str, what: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """A user callable's array result, checked to have ``shape`` (an array of that shape passes as it is)."""
    if type(value) is not np.ndarray:
        value = np.asarray(value)
    if value.shape != shape:
        raise DimensionError(
            f"{name}.box_minimum must return {what} of shape {shape} (sub-steps, models, actions), "
            f"got shape {value.shape}"
        )
    return value


class _ActionIndex:
    """Maps the planner's actions (controller indices) to an int64 index array, cached per actions object."""

    def __init__(self, n: int) -> None:
        self.n = n
        self._key = None
        self._value = None

    def __call__(self, actions):
        if actions is self._key:
            return self._value
        try:
            index = [int(a) for a in actions]
        except (TypeError, ValueError):
            raise InputError(f"actions must be controller indices (integers), got {actions!r}") from None
        if any(i != a for i, a in zip(index, actions)) or any(not 0 <= i < self.n for i in index):
            raise InputError(f"actions must be controller indices in [0, {self.n}), got {list(actions)!r}")
        value = np.array(index, dtype=np.int64)  # writable, like every array the kernels get (one compiled signature)
        if isinstance(actions, tuple):
            self._key, self._value = actions, value
        return value


class _SubstepTimes:
    """``times[t]``: the sub-step indices t+1 .. t+S as an array (S, 1, ..., 1), cached per t."""

    def __init__(self, substeps: int, trailing: int = 2) -> None:
        self._offsets = np.arange(1, substeps + 1).reshape((substeps,) + (1,) * trailing)
        self._cache: dict[int, np.ndarray] = {}

    def __getitem__(self, time: int) -> np.ndarray:
        value = self._cache.get(time)
        if value is None:
            value = self._offsets + time
            value.setflags(write=False)
            if len(self._cache) < 4096:
                self._cache[time] = value
        return value


class IntervalGroup:
    """The hypotheses of `IntervalModel.linked`, stepped together: the models' shared computation.

    Implements `minimaxplan.planners.protocols.CompiledTransitions` (so also
    `BatchedTransitions`): ``expand_all`` steps every hypothesis under every action in
    one compiled call, and the planner's compiled engine reads ``compiled_problem``.
    The members' ``expand`` read their row of ``expand_all``, from a one-entry cache
    keyed by the identity of the (immutable) state and actions objects.

    Parameters
    ----------
    systems_with_parameters
        The ``(system, parameters)`` hypotheses (``parameters`` None means
        ``system.theta``); the systems must have equal numbers of states and inputs.
    reward, controllers, substeps
        As for `IntervalModel`, shared by every hypothesis.

    Attributes
    ----------
    systems, parameters
        Per hypothesis, the system and the resolved parameter set.
    reward, bank, substeps
        The shared reward family, controllers (`ControllerBank`) and sub-steps.
    predictors
        Per hypothesis, its `IntervalPredictor` (identity basis).
    kernel
        The `IntervalKernel` of the compiled arithmetic (`build_interval_kernel`).
    kernel_params
        The reward's ``kernel_params`` (its compiled box minimum), or None.
    """

    def __init__(self, systems_with_parameters, reward, controllers, *, substeps: int = 1) -> None:
        try:
            pairs = [tuple(pair) for pair in systems_with_parameters]
        except TypeError:
            raise InputError("systems_with_parameters must be a sequence of (system, parameters) pairs") from None
        if not pairs:
            raise InputError("systems_with_parameters must hold at least one (system, parameters) pair")
        if any(len(pair) != 2 for pair in pairs):
            raise InputError("each item of systems_with_parameters must be a (system, parameters) pair")
        resolved = []
        for i, (system, parameters) in enumerate(pairs):
            check_instance("system", system, UncertainLinearSystem)
            first = pairs[0][0]
            if (system.nstates, system.ninputs) != (first.nstates, first.ninputs):
                raise DimensionError(
                    f"systems_with_parameters[{i}] has {system.nstates} states and {system.ninputs} inputs "
                    f"(B of shape {system.B.shape}), but systems_with_parameters[0] has {first.nstates} and "
                    f"{first.ninputs} (B of shape {first.B.shape}); the hypotheses must share the state and "
                    "input dimensions"
                )
            resolved.append((system, system.theta if parameters is None else parameters))
        p, q = pairs[0][0].nstates, pairs[0][0].ninputs
        self.reward_minimum = _check_reward(reward, p)
        self.substeps = as_count("substeps", substeps)
        self.bank = ControllerBank(controllers, p, q)
        self.kernel_params = _kernel_params(reward)
        if self.kernel_params is not None and not has_compiled_minimum(self.kernel_params):
            raise InputError(
                f"reward.kernel_params has type {type(self.kernel_params).__name__}, for which no compiled box minimum "
                "is registered (see minimaxplan.kernels.register_reward_params); use None for a reward "
                "without a compiled form"
            )
        self.reward = reward
        self.systems = tuple(system for system, _ in resolved)
        self.parameters = tuple(parameters for _, parameters in resolved)
        self.p = p
        try:
            self.times = _SubstepTimes(self.substeps)
        except (ValueError, MemoryError):  # numpy cannot allocate the sub-step offsets
            raise InputError(
                f"substeps = {self.substeps} is too large: its sub-step arrays cannot be allocated"
            ) from None
        self.predictors = tuple(IntervalPredictor(system, parameters) for system, parameters in resolved)
        self.kernel = build_interval_kernel(self.systems, self.predictors, self.bank)
        self.actions = _ActionIndex(len(self.bank))
        # the one-entry cache of `expand_all`, keyed by the identity of its arguments
        self._key_state: BoxState | None = None
        self._key_actions: Any = None
        self._result: tuple[list[BoxState], np.ndarray, np.ndarray] | None = None
        # the one-entry cache of `rollout`, keyed by the identity of the state and the actions' values
        self._rollout_key: tuple[BoxState, tuple[int, ...]] | None = None
        self._rollout: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None

    @property
    def size(self) -> int:
        """The number of hypotheses M."""
        return len(self.systems)

    def state_z(self, state: BoxState) -> np.ndarray:
        """The boxes of a state as z of shape (M or 1, 2p): a writable contiguous copy (one compiled signature).

        Parameters
        ----------
        state : BoxState
            A state of the group's models: one box, or one per hypothesis.
        """
        if type(state) is not BoxState:  # the hot path tests the exact type; the validator words the error
            check_instance("state", state, BoxState, "a BoxState (see IntervalModel.initial_state)")
        z = state.z
        if z.ndim == 1:
            return np.array(z[None, :], dtype=float)
        if z.shape[0] != self.size:
            raise DimensionError(f"state holds {z.shape[0]} boxes, expected {self.size} (one per linked hypothesis)")
        return np.array(z, dtype=float)

    def propagate(self, z, time, index):
        """All sub-steps of one decision from boxes z (M or 1, 2p) under the actions ``index`` (int64 (n,)).

        Returns the boxes after every sub-step, ``stack`` (S, M, n, 2p), the
        pessimistic rewards (M, n) (minimum over the sub-steps) and the collision
        flags (any over the sub-steps).

        Parameters
        ----------
        z : ndarray, shape (M or 1, 2p)
            The boxes ``[-lower | upper]`` at the decision (as `state_z` gives them).
        time : int
            Their absolute sub-step index t (the sub-steps are t + 1 .. t + S).
        index : ndarray (n,) of int64
            The controller indices of the actions.
        """
        p, S = self.p, self.substeps
        stack = np.empty((S, self.size, index.shape[0], 2 * p))
        propagate(z, index, self.kernel, stack)
        if self.kernel_params is not None:
            rewards = np.empty(stack.shape[1:3])
            collided = np.empty(stack.shape[1:3], dtype=bool)
            # looked up per call (a cached dict lookup), so that models stay picklable
            stack_rewards_kernel(type(self.kernel_params))(stack, time, self.kernel_params, rewards, collided)
            return stack, rewards, collided
        out = self.reward_minimum(-stack[..., :p], stack[..., p:], self.times[time])
        try:
            reward, collided = out
        except (TypeError, ValueError):
            raise InputError(
                f"reward.box_minimum must return a pair (rewards, collided), got {type(out).__name__}"
            ) from None
        reward = _as_result_array("reward", "rewards", reward, stack.shape[:3])
        collided = _as_result_array("reward", "collision flags", collided, stack.shape[:3])
        return stack, np.minimum.reduce(reward, axis=0), np.logical_or.reduce(collided, axis=0)

    def rollout(self, state: BoxState, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every hypothesis's boxes at every sub-step along one action sequence, in one pass.

        The members' `IntervalModel.rollout` read their row of it, from a one-entry
        cache keyed by the identity of the (immutable) state and the actions' values:
        the M members of a group rolling the same plan out from the same state (the
        run-time check's hull, the latest-collision rule) share one computation.

        Parameters
        ----------
        state : BoxState
            The initial state: one box, or one per hypothesis.
        actions : sequence of int
            Controller indices, one per decision.

        Returns
        -------
        lower, upper : ndarray, shape (M, len(actions) * substeps + 1, p)
            Per hypothesis, the box corners after every sub-step; row 0 is the initial
            box. Read-only (shared through the cache).
        rewards : ndarray, shape (M, len(actions))
            The per-decision pessimistic rewards (Theorem 1).
        terminals : ndarray of bool, shape (M, len(actions))
            The per-decision collision flags.

        Raises
        ------
        InputError
            If ``state`` is not a `BoxState` or an action is not a controller index.
        DimensionError
            If ``state`` holds a number of boxes other than 1 or the group size.
        """
        index = self.actions(list(actions))
        key = (state, tuple(int(a) for a in index))
        cached = self._rollout_key
        if self._rollout is not None and cached is not None and cached[0] is state and cached[1] == key[1]:
            return self._rollout
        z = self.state_z(state)
        M, p, S, n = self.size, self.p, self.substeps, len(index)
        lower = np.empty((M, n * S + 1, p))
        upper = np.empty((M, n * S + 1, p))
        lower[:, 0], upper[:, 0] = -z[:, :p], z[:, p:]  # a single root box broadcasts to every hypothesis
        rewards = np.empty((M, n))
        terminals = np.zeros((M, n), dtype=bool)
        time = state.time
        for k in range(n):
            stack, reward, collided = self.propagate(z, time, index[k : k + 1].copy())
            lower[:, 1 + k * S : 1 + (k + 1) * S] = -stack[:, :, 0, :p].transpose(1, 0, 2)
            upper[:, 1 + k * S : 1 + (k + 1) * S] = stack[:, :, 0, p:].transpose(1, 0, 2)
            rewards[:, k], terminals[:, k] = reward[:, 0], collided[:, 0]
            z = np.ascontiguousarray(stack[-1, :, 0])
            time += S
        for array in (lower, upper, rewards, terminals):
            array.flags.writeable = False
        self._rollout_key, self._rollout = key, (lower, upper, rewards, terminals)
        return self._rollout

    # ------------------------------------------------- BatchedTransitions
    def expand_all(self, state: BoxState, actions) -> tuple[list[BoxState], np.ndarray, np.ndarray]:
        """Every hypothesis under every action from ``state``, in one compiled call.

        Returns ``(next_states, rewards, terminals)``: a list of `BoxState` holding
        one box per hypothesis (one box when M = 1), the pessimistic rewards and the
        collision flags, each of shape (M, len(actions)).

        Parameters
        ----------
        state : BoxState
            The state shared by every hypothesis.
        actions : sequence of int
            Controller indices in ``[0, len(bank))``.
        """
        if self._result is not None and state is self._key_state and actions is self._key_actions:
            return self._result
        p = self.p
        root = self.state_z(state)
        index = self.actions(actions)
        stack, rewards, collided = self.propagate(root, state.time, index)
        z = stack[-1]  # (M, n, 2p)
        z.flags.writeable = False
        upper = z[..., p:]
        lower = -z[..., :p]
        lower.flags.writeable = False
        time = state.time + self.substeps
        batch = BoxState._from_batch
        if self.size == 1:
            next_states = [batch(lower, upper, z, (0, i), time) for i in range(len(index))]
        else:
            next_states = [batch(lower, upper, z, (slice(None), i), time) for i in range(len(index))]
        self._key_state, self._key_actions = state, actions
        self._result = (next_states, rewards, collided)
        return self._result

    # ------------------------------------------------- CompiledTransitions
    @property
    def compiled(self) -> bool:
        """Whether the reward has a compiled box minimum, so the compiled search can run."""
        return self.kernel_params is not None

    def compiled_problem(self, state: BoxState, actions) -> CompiledProblem:
        """The compiled search's inputs: the root boxes (M, 2p), time, action indices, kernel, params, substeps.

        Parameters
        ----------
        state : BoxState
            The root state (one box is repeated for every hypothesis).
        actions : sequence of int
            Controller indices in ``[0, len(bank))``.
        """
        root = self.state_z(state)
        if root.shape[0] != self.size:
            root = np.repeat(root, self.size, axis=0)
        return CompiledProblem(root, state.time, self.actions(actions), self.kernel, self.kernel_params, self.substeps)

    def node_states(self, z: np.ndarray, depth: Sequence[int], time: int) -> list:
        """The joint state of each node ``i >= 1`` of a compiled search (``z`` (nodes, M, 2p), owned).

        The same objects, up to identity, that `expand_all` creates on the Python
        engine: ``lower``, ``upper`` and ``z`` views of one batch, a (M, 2p) box per
        node (2p, for M = 1), at sub-step ``time + depth * substeps``.

        Parameters
        ----------
        z : ndarray (nodes, M, 2p)
            The boxes the compiled search left, one row per node; made read-only and viewed by the states.
        depth : sequence of int
            Each node's depth in the tree.
        time : int
            The root's sub-step index.
        """
        p = self.p
        z.flags.writeable = False
        lower = -z[..., :p]
        lower.flags.writeable = False
        upper = z[..., p:]
        batch, S = BoxState._from_batch, self.substeps
        if self.size == 1:
            return [None] + [batch(lower, upper, z, (i, 0), time + depth[i] * S) for i in range(1, z.shape[0])]
        return [None] + [batch(lower, upper, z, (i,), time + depth[i] * S) for i in range(1, z.shape[0])]


def _check_member(group: IntervalGroup, m, system, parameters, reward, controllers, substeps) -> None:
    """Check that the arguments of an `IntervalModel` are those of member ``m`` of ``group``."""
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or not 0 <= m < group.size:
        raise InputError(f"member must be an integer in [0, {group.size}), got {m!r}")
    if system is not group.systems[m] or reward is not group.reward or substeps != group.substeps:
        raise InputError(f"system, reward and substeps must be those of the group's member {m}")
    if parameters is not None and parameters is not group.parameters[m]:
        raise InputError(f"parameters must be None or the group's member {m} parameters")
    try:
        given = tuple(controllers)
    except TypeError:
        raise InputError(f"controllers must be a sequence, got {type(controllers).__name__}") from None
    if len(given) != len(group.bank) or any(c is not d for c, d in zip(given, group.bank.controllers)):
        raise InputError("controllers must be the group's controllers")


@dataclass(frozen=True, eq=False, init=False)
class IntervalModel:
    """A planner model whose state is a box containing the true state (Theorem 1).

    Parameters
    ----------
    system : UncertainLinearSystem
        The plant ``x+ = A(theta) x + B u + D w`` (one sub-step).
    parameters : Box, Ellipsoid, array_like of shape (k, d), or None
        The parameter set (a vertex array holds k parameter vectors), as for
        `IntervalPredictor`; None means ``system.theta``.
    reward : BoxReward
        A reward family with ``box_minimum(lower, upper, t) -> (reward, collided)``
        returning the EXACT minimum over each box, vectorised over leading dimensions
        (e.g. `minimaxplan.scenarios.GoalReward`), rewards in [0, 1]. It reads full
        states (each family holds its own coordinate indices).
    controllers : sequence of OpenLoop or LinearFeedback
        One controller per action; the planner's actions are the indices
        ``0 .. len(controllers) - 1``.
    substeps : int, optional
        Sub-steps of ``system`` per decision (>= 1, default 1); the action's
        controller acts at every sub-step.
    group : IntervalGroup, optional
        The group this model is computed with, as `linked` passes it; by default
        (None) a group of this hypothesis alone. The other arguments must then be
        the group's.
    member : int, optional
        The model's index in ``group`` (default 0).

    Raises
    ------
    InputError
        If ``system`` is not an `UncertainLinearSystem`, ``reward`` has no callable
        ``box_minimum`` (or an unregistered ``kernel_params``), ``controllers`` is
        empty or holds another type, ``substeps`` is not a positive integer, or
        ``group``/``member`` do not match the other arguments.
    DimensionError
        If ``parameters``, the reward's state indices or a controller do not fit
        the system.

    Attributes
    ----------
    system, parameters, reward, controllers, substeps
        As given (``parameters`` resolved, ``controllers`` a tuple).
    group, member
        The model's `IntervalGroup` and its index in it (the
        `minimaxplan.planners.protocols.LinkedModel` protocol).

    Notes
    -----
    Per sub-step, for every action and hypothesis (one compiled call), the box is
    propagated by the interval predictor of the closed loop. Writing the controller as
    ``u = sat(v)``, ``v = c_a - K_a x`` (`ControllerBank`), and ``sat(v) = v + s(v)``:

    ``x+ = (A(theta) - B K_a) x + B c_a + B s(v) + D w``.

    The first part is bounded exactly as `IntervalPredictor` does, with the vertex
    matrices ``A(v_k) - B K_a`` (the predictor's vertex matrices, stacked per action).
    ``s(v) = clip(v, low, high) - v`` is nonincreasing in each coordinate, so over the
    box, where ``v`` lies in ``[v_lo, v_hi]`` (interval product), ``s`` lies in
    ``[s(v_hi), s(v_lo)]``; this interval, zero when saturation cannot activate
    anywhere in the box, enters as a bounded input through ``B``. When some controller
    saturates, the open-loop bound ``A(theta) x + B [sat(v_lo), sat(v_hi)] + D w``
    (exact under heavy saturation, when u is constant) is computed as well, and the
    two sound boxes are intersected.

    The reward of a transition is ``min_{s=1..S} min_{x in box_s} J(x, t + s)``, with
    box_s the box after sub-step s. By the inclusion property each true state at
    sub-step s lies in box_s, so the true reward at that sub-step is at least this
    value (Theorem 1, Appendix A); a collision possible in any box makes the
    transition terminal with reward 0. The predictor runs in the identity basis,
    because the closed-loop matrices differ per action and the reward reads the
    boxes in plant coordinates at every sub-step.

    The compiled arithmetic computes, per action and hypothesis, the same one-step box
    as `IntervalPredictor.step` (its vertex-wise exact bound), and rounds it outward
    like the predictor: each bound gets ``E |x| + e``, with ``|x|`` bounded by the box's
    magnitudes ``max(|lower|, |upper|)``, ``E`` covering the formation of the vertex
    matrices (`IntervalPredictor.vertex_matrix_error`), of ``B K`` and of ``A(v) - B K``,
    and ``gamma_n`` times the magnitudes of every n-term sum of the sub-step, and ``e``
    the same for the drift ``B c + D w`` (with the rounding of ``c = K x_ref + u_ff``)
    and for underflow. On the saturation path the input interval's ends are moved one
    ulp outward after each operation, and the products with ``B`` carry their own
    ``gamma_n`` bound. So the boxes contain the exact reachable sets (tested against
    rational arithmetic on a nilpotent loop whose rounding errors grow 14-fold per
    step); the margins are of order 1e-15 relative.

    Several hypotheses for one planner: `IntervalModel.linked` builds one model per
    hypothesis that compute their transitions together (the planner sees M ordinary
    models; states then hold one box per hypothesis).
    """

    system: UncertainLinearSystem
    parameters: Any
    reward: Any
    controllers: tuple
    substeps: int
    group: IntervalGroup = field(repr=False)
    member: int

    def __init__(
        self,
        system: UncertainLinearSystem,
        parameters: Any,
        reward: Any,
        controllers: Sequence,
        *,
        substeps: int = 1,
        group: IntervalGroup | None = None,
        member: int = 0,
    ) -> None:
        if group is None:
            group = IntervalGroup([(system, parameters)], reward, controllers, substeps=substeps)
        else:
            check_instance("group", group, IntervalGroup, "an IntervalGroup (see IntervalModel.linked)")
            _check_member(group, member, system, parameters, reward, controllers, substeps)
        for name, value in (
            ("system", system),
            ("parameters", group.parameters[member]),
            ("reward", reward),
            ("controllers", group.bank.controllers),
            ("substeps", group.substeps),
            ("group", group),
            ("member", member),
        ):
            object.__setattr__(self, name, value)

    @classmethod
    def linked(cls, systems_with_parameters, reward, controllers, *, substeps: int = 1) -> list[IntervalModel]:
        """One `IntervalModel` per ``(system, parameters)`` hypothesis, computing their transitions together.

        Use the list as the ``models`` of a `RobustTreePlanner` (in this order): the
        planner then steps all of them in one `IntervalGroup.expand_all` call per
        expansion, or runs its compiled engine.

        Parameters
        ----------
        systems_with_parameters : sequence of (UncertainLinearSystem, parameter set or None)
            The M >= 1 structural hypotheses; ``parameters`` as for `IntervalModel`
            (None means ``system.theta``). The systems must have the same numbers of
            states and inputs.
        reward : BoxReward
            The reward family, shared by every hypothesis (as for `IntervalModel`).
        controllers : sequence of OpenLoop or LinearFeedback
            One controller per action, shared by every hypothesis.
        substeps : int, optional
            Sub-steps of the systems per decision (>= 1, default 1).

        Returns
        -------
        list of IntervalModel
            M models of one `IntervalGroup`, member ``m`` for hypothesis ``m``.

        Raises
        ------
        InputError
            If ``systems_with_parameters`` is empty or not a sequence of pairs, or an
            argument is invalid as for `IntervalModel`.
        DimensionError
            If a system's numbers of states and inputs differ from the first one's.

        Notes
        -----
        The multi-model objective (15): the planner maximises the minimum over these
        M models of the discounted pessimistic returns, with the robust bounds
        (16)-(18).
        """
        group = IntervalGroup(systems_with_parameters, reward, controllers, substeps=substeps)
        return [
            cls(system, parameters, reward, group.bank.controllers, substeps=group.substeps, group=group, member=m)
            for m, (system, parameters) in enumerate(zip(group.systems, group.parameters))
        ]

    @property
    def bank(self) -> ControllerBank:
        """The controllers as stacked arrays (shared by the group)."""
        return self.group.bank

    @property
    def predictor(self) -> IntervalPredictor:
        """This hypothesis's `IntervalPredictor`."""
        return self.group.predictors[self.member]

    @property
    def n_actions(self) -> int:
        """The number of actions ``|A|`` (one per controller)."""
        return len(self.bank)

    @property
    def actions(self) -> tuple[int, ...]:
        """The planner's actions: the controller indices."""
        return tuple(range(self.n_actions))

    @property
    def n_linked(self) -> int:
        """How many hypotheses this model is computed together with (itself included)."""
        return self.group.size

    # --------------------------------------------------------------- protocol
    def expand(self, state: BoxState, actions) -> tuple[list, np.ndarray, np.ndarray]:
        """Step every action from ``state`` in one batched call (the planner's vectorised protocol).

        Parameters
        ----------
        state : BoxState
            The current box (from `initial_state` or an earlier transition).
        actions : sequence of int
            Controller indices in ``[0, n_actions)``.

        Returns
        -------
        next_states : list of BoxState
            The box after the decision, per action (one box per hypothesis for
            linked models).
        rewards : ndarray, shape (len(actions),)
            The pessimistic rewards: the exact minimum of the reward over every
            sub-step box of the decision, in [0, 1].
        terminals : ndarray of bool, shape (len(actions),)
            Whether a collision is possible in one of those boxes.

        Raises
        ------
        InputError
            If ``state`` is not a `BoxState` or an action is not a controller index.
        DimensionError
            If ``state`` holds a number of boxes other than 1 or the group size.

        Notes
        -----
        The rewards are the pessimistic costs J_n of the surrogate objective (11):
        by the inclusion property (7) they bound the true rewards from below
        (Theorem 1).
        """
        next_states, rewards, terminals = self.group.expand_all(state, actions)
        m = self.member
        return next_states, rewards[m], terminals[m]

    def step(self, state: BoxState, action) -> tuple[BoxState, float, bool]:
        """One transition: ``(next_state, pessimistic reward, terminal)``.

        Parameters
        ----------
        state : BoxState
            The current box.
        action : int
            A controller index in ``[0, n_actions)``.

        Returns
        -------
        next_state : BoxState
            The box after the decision.
        reward : float
            The pessimistic reward (Theorem 1), in [0, 1].
        terminal : bool
            Whether a collision is possible during the decision.

        Raises
        ------
        InputError
            As for `expand`.
        """
        next_states, rewards, terminals = self.expand(state, (action,))
        return next_states[0], float(rewards[0]), bool(terminals[0])

    def initial_state(self, lower, upper=None, *, time: int = 0) -> BoxState:
        """The planner's root state: a box of plant states at sub-step ``time``.

        The same root state serves every linked hypothesis.

        Parameters
        ----------
        lower : Box or array_like, shape (p,)
            A `Box` of plant states, or its lower corner, in the plant's state units.
        upper : array_like, shape (p,), optional
            The upper corner (only with an array ``lower``); None means the
            degenerate box ``[lower, lower]`` (an exactly known state).
        time : int, optional
            The absolute sub-step index of the box (>= 0, default 0), the reward's
            time argument.

        Returns
        -------
        BoxState
            The box, with read-only copies of the corners.

        Raises
        ------
        InputError
            If both a `Box` and ``upper`` are given, or ``time`` is not an integer >= 0.
        DimensionError
            If the corners do not have shape (p,).
        NonFiniteError
            If a corner has NaN or infinite entries.
        EmptySetError
            If ``lower > upper`` in some coordinate.
        """
        p = self.system.nstates
        if isinstance(lower, Box):
            if upper is not None:
                raise InputError("give either a Box or the arrays lower and upper, not both")
            lo, hi = np.array(lower.low), np.array(lower.high)
        else:
            lo = as_finite_array("lower", lower)
            hi = lo if upper is None else as_finite_array("upper", upper)
        if lo.shape != (p,) or hi.shape != (p,):
            raise DimensionError(f"lower and upper must have shape ({p},), got shapes {lo.shape} and {hi.shape}")
        if np.any(lo > hi):
            raise EmptySetError(
                f"the initial box is empty: lower > upper at indices {np.flatnonzero(lo > hi).tolist()}"
            )
        lo, hi = lo.copy(), hi.copy()
        lo.setflags(write=False)
        hi.setflags(write=False)
        return BoxState(lo, hi, as_count("time", time, minimum=0))

    def box(self, state: BoxState) -> tuple[np.ndarray, np.ndarray]:
        """This hypothesis's box in ``state`` (states of linked models hold one box per hypothesis).

        Parameters
        ----------
        state : BoxState
            A state of this model (or of its linked group).

        Returns
        -------
        lower, upper : ndarray, shape (p,)
            The corners of this hypothesis's box (read-only views).
        """
        if state.lower.ndim == 2:
            return state.lower[self.member], state.upper[self.member]
        return state.lower, state.upper

    def rollout(self, state: BoxState, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """This hypothesis's boxes at every sub-step along an action sequence.

        Its row of `IntervalGroup.rollout`: linked models rolling the same actions out
        from the same state share one computation.

        Parameters
        ----------
        state : BoxState
            The initial box (e.g. the planner's root state).
        actions : sequence of int
            Controller indices, one per decision (e.g. ``Decision.sequence``).

        Returns
        -------
        lower, upper : ndarray, shape (len(actions) * substeps + 1, p)
            The box corners after every sub-step; row 0 is the initial box.
        rewards : ndarray, shape (len(actions),)
            The per-decision pessimistic rewards (Theorem 1). Rewards after a
            terminal transition are reported as computed (the planner ignores them).
        terminals : ndarray of bool, shape (len(actions),)
            The per-decision collision flags.

        Raises
        ------
        InputError
            If ``state`` is not a `BoxState` or an action is not a controller index.
        DimensionError
            If ``state`` holds a number of boxes other than 1 or the group size.
        """
        check_instance("state", state, BoxState)
        lower, upper, rewards, terminals = self.group.rollout(state, actions)
        m = self.member
        return lower[m].copy(), upper[m].copy(), rewards[m].copy(), terminals[m].copy()

    def first_possible_collision(self, state: BoxState, plan: Sequence[int], horizon: int) -> int:
        """The first sub-step at which this hypothesis's box along a plan may collide, or ``horizon + 1``.

        The plan's actions are taken in turn from ``state`` and its last one is then
        held (the `minimaxplan.planners.protocols.CollisionHorizonModel` protocol). A
        possible collision is a sub-step box whose reward minimum is a collision
        (``collided`` of the reward's ``box_minimum``), the sub-step boxes that make a
        transition of `expand` terminal.

        Parameters
        ----------
        state : BoxState
            The start box (e.g. the planner's root state).
        plan : sequence of int
            Controller indices, at least one.
        horizon : int
            Sub-steps examined, ``>= 1``.

        Returns
        -------
        int
            In ``[1, horizon + 1]``, relative to ``state.time``.

        Raises
        ------
        InputError
            If ``state`` is not a `BoxState`, ``plan`` is empty or holds an action that
            is not a controller index, or ``horizon`` is not a positive integer.
        """
        horizon = as_count("horizon", horizon)
        actions = [int(a) for a in self.group.actions(tuple(plan))]
        if not actions:
            raise InputError("plan must hold at least one action, got an empty sequence")
        decisions = -(-horizon // self.substeps)
        held = (actions + [actions[-1]] * decisions)[: max(decisions, len(actions))]
        lower, upper, _, _ = self.rollout(state, held)
        lower, upper = lower[1 : horizon + 1], upper[1 : horizon + 1]
        _, collided = self.reward.box_minimum(lower, upper, state.time + 1 + np.arange(horizon))
        collided = np.asarray(collided, dtype=bool)
        return 1 + int(np.argmax(collided)) if collided.any() else horizon + 1
