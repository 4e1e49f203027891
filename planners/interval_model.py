"""The interval-model adapter: an uncertain system as a planner model whose state is a box.

`IntervalModel` turns a system, a parameter set, a reward family with an exact box
minimum and one low-level controller per action into a model for
`RobustTreePlanner`. Its state is a `BoxState` (a box of plant states and the
absolute sub-step index); a transition holds the action's controller for
``substeps`` sub-steps, propagating the box with the interval predictor, and returns
the pessimistic reward of Theorem 1: the exact minimum of the reward over every
sub-step box between the two decisions (terminal as soon as one of those boxes may
collide).

The planner never imports `minimaxplan.scenarios`: the reward is any object with
``box_minimum(lower, upper, t) -> (reward, collided)`` (and, optionally, the
unchecked ``box_minimum_raw`` with the same meaning, used on the hot path).
"""

from __future__ import annotations

import numpy as np

from ..models._validation import as_finite_array
from ..models.errors import DimensionError, EmptySetError, InputError
from ..models.prediction import IntervalPredictor, interval_matvec
from ..models.sets import Box
from ..models.system import UncertainLinearSystem
from .controllers import ControllerBank

__all__ = ["BoxState", "IntervalModel"]


class BoxState:
    """A planner state of `IntervalModel`: the box ``[lower, upper]`` at sub-step ``time``.

    Immutable by convention (its arrays are read-only views). ``lower`` and ``upper``
    have shape (p,), or (M, p) for the states of linked models (one box per
    hypothesis). ``z`` is the same box as ``[-lower | upper]``, the form the
    arithmetic works on (computed on demand when not given).
    """

    __slots__ = ("_lower", "_upper", "time", "_z", "_source")

    def __init__(self, lower, upper, time: int, z=None) -> None:
        self._lower = lower
        self._upper = upper
        self.time = time
        self._z = z
        self._source = None

    @classmethod
    def _from_batch(cls, lower, upper, z, key, time: int) -> "BoxState":
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
        if self._lower is None and self._source is not None:
            self._lower = self._source[0][self._source[3]]
        return self._lower

    @property
    def upper(self) -> np.ndarray:
        if self._upper is None and self._source is not None:
            self._upper = self._source[1][self._source[3]]
        return self._upper

    @property
    def z(self) -> np.ndarray:
        if self._z is None and self._source is not None:
            self._z = self._source[2][self._source[3]]
        if self._z is None:
            z = np.concatenate([-np.asarray(self.lower, dtype=float), np.asarray(self.upper, dtype=float)], axis=-1)
            z.setflags(write=False)
            self._z = z
        return self._z

    def __iter__(self):
        return iter((self.lower, self.upper, self.time))

    def __repr__(self) -> str:
        return f"BoxState(lower={np.asarray(self.lower).tolist()}, upper={np.asarray(self.upper).tolist()}, time={self.time})"


def _check_substeps(substeps) -> int:
    if isinstance(substeps, bool) or int(substeps) != substeps or substeps < 1:
        raise InputError(f"substeps must be an integer >= 1, got {substeps!r}")
    return int(substeps)


def _check_reward(reward, nstates: int):
    minimum = getattr(reward, "box_minimum", None)
    if not callable(minimum):
        raise InputError(
            f"reward must have a callable box_minimum(lower, upper, t) -> (reward, collided), got {type(reward).__name__}"
        )
    needed = getattr(reward, "min_state_dim", None)
    if needed is not None and needed > nstates:
        raise DimensionError(f"reward reads state coordinates up to index {needed - 1}, but the system has {nstates} states")
    raw = getattr(reward, "box_minimum_raw", None)
    return raw if callable(raw) else minimum


def _check_time(time) -> int:
    if isinstance(time, bool) or int(time) != time or time < 0:
        raise InputError(f"time must be a nonnegative integer sub-step index, got {time!r}")
    return int(time)


class _ActionIndex:
    """Maps the planner's actions (controller indices) to an index array, cached per actions object."""

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
        value = None if index == list(range(self.n)) else np.array(index)
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


_max_reduce = np.maximum.reduce  # ndarray.max without its Python wrapper (hot path)
_min_reduce = np.minimum.reduce


def _z_matrix(matrices: np.ndarray) -> np.ndarray:
    """For matrices (..., m, n): ``[[M+^T, M-^T], [M-^T, M+^T]]`` of shape (..., 2n, 2m).

    With a box written ``z = [-lower | upper]`` (..., 2n), ``z @ result`` is the exact
    box of ``M x`` in the same form.
    """
    pos_t = np.swapaxes(np.maximum(matrices, 0.0), -1, -2)
    neg_t = np.swapaxes(np.maximum(-matrices, 0.0), -1, -2)
    top = np.concatenate([pos_t, neg_t], axis=-1)
    bottom = np.concatenate([neg_t, pos_t], axis=-1)
    return np.ascontiguousarray(np.concatenate([top, bottom], axis=-2))


class _IntervalCore:
    """The batched arithmetic of one or several hypotheses under every controller.

    A box is stored as ``z = [-lower | upper]`` (shape (..., 2p)). For a fixed matrix
    M the exact box of ``{M x : lower <= x <= upper}`` is then ``z @ [[M+^T, M-^T],
    [M-^T, M+^T]]`` (``M+ = max(M, 0)``, ``M- = max(-M, 0)``): one product, and the
    bound over the k vertex matrices is one max over k. Boxes are arrays (M, A', 2p):
    M hypotheses (``members``) times A' actions. Everything is precomputed;
    `propagate` runs on raw arrays only.
    """

    def __init__(self, members, reward_minimum, bank: ControllerBank, substeps: int) -> None:
        self.reward_minimum = reward_minimum
        self.bank = bank
        self.substeps = substeps
        self.times = _SubstepTimes(substeps)
        systems = [system for system, _ in members]
        self.M = len(members)
        self.p = systems[0].nstates
        predictors = [IntervalPredictor(system, parameters) for system, parameters in members]
        self.predictors = predictors
        k = max(pred.nvertices for pred in predictors)
        # pad each hypothesis to k vertex matrices by repeating one (harmless under max)
        vertices = np.stack(
            [np.concatenate([pred.vertex_matrices, np.repeat(pred.vertex_matrices[:1], k - pred.nvertices, axis=0)])
             for pred in predictors]
        )  # (M, k, p, p), identity basis
        B = np.stack([system.B for system in systems])  # (M, p, q)
        self.k = k
        self.per_action = bank.has_feedback
        # open loop without saturation: every sub-step is one product, one max, one sum
        self.plain = not bank.has_feedback and not bank.saturating
        self.open_product = self._product(vertices)  # (M, 2p, 2kp)
        if self.per_action:
            feedback = np.einsum("mpq,aqr->mapr", B, bank.gains)  # B_m K_a
            closed = vertices[:, None] - feedback[:, :, None]  # (M, A, k, p, p)
            self.product = self._product(closed)  # (M, A, 2p, 2kp)
        else:
            self.product = self.open_product
        w = [interval_matvec(system.D, system.w.low, system.w.high) for system in systems]
        self.w_lo = np.stack([lo for lo, _ in w])[:, None, :]  # (M, 1, p)
        self.w_hi = np.stack([hi for _, hi in w])[:, None, :]
        self.w_z = np.concatenate([-self.w_lo, self.w_hi], axis=-1)  # (M, 1, 2p)
        drift = np.einsum("mpq,aq->map", B, bank.offsets)  # (M, A, p): B_m c_a
        self.drift_z = np.concatenate([-drift, drift], axis=-1) + self.w_z  # (M, A, 2p)
        self.q = B.shape[2]
        self.B_z = _z_matrix(B)  # (M, 2q, 2p)
        self.K_z = _z_matrix(bank.gains)  # (A, 2p, 2q)

    def _product(self, matrices):
        """`_z_matrix` of each of the k matrices, side by side: (..., 2p, 2kp).

        The columns are ordered (vertex, bound, coordinate), so that the product's
        result reshapes to (..., k, 2p), each row a z-box, and one max over the
        vertex axis gives the bound over all k (numpy reduces that axis fastest).
        """
        p, k = self.p, matrices.shape[-3]
        per_vertex = _z_matrix(matrices)  # (..., k, 2p, 2p)
        return np.ascontiguousarray(np.moveaxis(per_vertex, -3, -2).reshape(matrices.shape[:-3] + (2 * p, 2 * k * p)))

    def substep(self, z, index, out=None):
        """One sub-step of boxes z = [-lower | upper] under the actions ``index`` (None = all).

        ``z`` has shape (M or 1, A' or 1, 2p): a box shared by all actions (or all
        hypotheses) is propagated once and broadcast against the per-action terms.
        ``out``, if given, is an array of the result's shape (M, A', 2p) to write to.
        """
        if self.per_action:
            product = self.product if index is None else self.product[:, index]
            candidates = np.matmul(z[..., None, :], product)[..., 0, :]
        else:
            candidates = np.matmul(z, self.open_product)
        k = self.k
        if k > 1:
            bounds = _max_reduce(candidates.reshape(candidates.shape[:-1] + (k, 2 * self.p)), axis=-2)
        else:
            bounds = candidates
        drift = self.drift_z if index is None else self.drift_z[:, index]
        if self.bank.saturating:
            new_z = self._saturation(z, bounds + drift, index)
            if out is None:
                return new_z
            out[...] = new_z
            return out
        return np.add(bounds, drift, out=out)

    def _saturation(self, z, closed_z, index):
        """Closed loop plus the bounded correction s(v), intersected with the open-loop bound.

        All in z-form: ``[-(K x)_lo | (K x)_hi]`` over the box is one product with
        ``K_z``; the input boxes of the correction and of the open loop go through
        ``B_z`` in one product; the intersection of two z-boxes is their elementwise min.
        """
        sel = slice(None) if index is None else index
        q, k, p = self.q, self.k, self.p
        bank = self.bank
        kx = np.matmul(z[..., None, :], self.K_z[sel])[..., 0, :]  # (M, A', 2q)
        offsets = bank.offsets[sel]
        # v = c - K x over the box: [c - (K x)_hi, c - (K x)_lo]
        v_lo = offsets - kx[..., q:]
        v_hi = offsets + kx[..., :q]
        low, high = bank.low[sel], bank.high[sel]
        u_lo = np.minimum(np.maximum(v_lo, low), high)
        u_hi = np.minimum(np.maximum(v_hi, low), high)
        # s(v) = sat(v) - v is nonincreasing: s in [u_hi - v_hi, u_lo - v_lo]; u in [u_lo, u_hi]
        inputs = np.concatenate([v_hi - u_hi, u_lo - v_lo, -u_lo, u_hi], axis=-1)
        through_B = np.matmul(inputs.reshape(inputs.shape[:-1] + (2, 2 * q)), self.B_z[:, None])  # (M, A', 2, 2p)
        candidates = np.matmul(z, self.open_product)
        open_z = (candidates.reshape(candidates.shape[:-1] + (k, 2 * p)).max(axis=-2) if k > 1 else candidates) + self.w_z
        return np.minimum(closed_z + through_B[..., 0, :], open_z + through_B[..., 1, :])

    def _plain_substeps(self, z, index, stack):
        """`substep` repeated, inlined for open-loop controllers without saturation (hot path).

        With ``stack`` None, one sub-step, returned; else ``len(stack)`` sub-steps written
        to ``stack[s]``, the last one returned. Same operations as `substep`.
        """
        product, k = self.open_product, self.k
        drift = self.drift_z if index is None else self.drift_z[:, index]
        vertex_shape = (k, 2 * self.p)
        matmul, add = np.matmul, np.add
        for out in (None,) if stack is None else stack:
            candidates = matmul(z, product)
            if k > 1:
                candidates = _max_reduce(candidates.reshape(candidates.shape[:-1] + vertex_shape), axis=-2)
            z = add(candidates, drift, out=out)
        return z

    def state_z(self, state: BoxState) -> np.ndarray:
        """The boxes of a state as z of shape (M or 1, 1, 2p)."""
        z = state.z
        if z.ndim == 1:
            return z[None, None, :]
        if z.shape[0] != self.M:
            raise DimensionError(f"state holds {z.shape[0]} boxes, expected {self.M} (one per linked hypothesis)")
        return z[:, None, :]

    def propagate(self, z, time, index):
        """All sub-steps of one decision from boxes z (M or 1, 1 or A', 2p).

        Returns the final boxes z and their lower corners (``-z[..., :p]``), the
        pessimistic rewards (M, A') (minimum over the sub-steps) and the collision
        flags (any over the sub-steps). The reward is
        evaluated once for the boxes of all sub-steps, stacked as (S, M, A', p), with
        the sub-step indices ``t`` of shape (S, 1, 1).
        """
        p, S = self.p, self.substeps
        if S == 1:
            z = self._plain_substeps(z, index, None) if self.plain else self.substep(z, index)
            lower = -z[..., :p]
            reward, collided = self.reward_minimum(lower, z[..., p:], time + 1)
            return z, lower, reward, collided
        # each sub-step's result has the per-action drift's shape (M, A', 2p)
        stack = np.empty((S, self.M, self.drift_z.shape[1] if index is None else len(index), 2 * p))
        if self.plain:
            z = self._plain_substeps(z, index, stack)
        else:
            for s in range(S):
                z = self.substep(z, index, out=stack[s])
        lowers = -stack[..., :p]
        reward, collided = self.reward_minimum(lowers, stack[..., p:], self.times[time])
        return z, lowers[-1], _min_reduce(reward, axis=0), np.logical_or.reduce(collided, axis=0)


class _LinkedGroup:
    """The hypotheses of a multi-model planner, stepped together.

    The planner steps its M models one after the other from the same node. Linked
    models share one `_IntervalCore`: the first model asked computes the transitions of
    all M hypotheses in one batched call and the others read their row from a
    one-entry cache, keyed by the identity of the (immutable) state and actions objects.
    """

    def __init__(self, core: _IntervalCore) -> None:
        self.core = core
        self.size = core.M
        self.actions = _ActionIndex(len(core.bank))
        self._key_state = None
        self._key_actions = None
        self._result = None

    def expand(self, state: BoxState, actions):
        if state is self._key_state and actions is self._key_actions:
            return self._result
        if type(state) is not BoxState:
            raise InputError(f"state must be a BoxState (see IntervalModel.initial_state), got {type(state).__name__}")
        core = self.core
        index = self.actions(actions)
        n = len(core.bank) if index is None else len(index)
        z, lower, rewards, collided = core.propagate(core.state_z(state), state.time, index)
        # z, rewards and collided have full shape (M, n, .): the per-action drift broadcasts them
        z.flags.writeable = False
        upper = z[..., core.p:]
        lower.flags.writeable = False
        time = state.time + core.substeps
        batch = BoxState._from_batch
        if core.M == 1:
            next_states = [batch(lower, upper, z, (0, i), time) for i in range(n)]
        else:
            next_states = [batch(lower, upper, z, (slice(None), i), time) for i in range(n)]
        self._key_state, self._key_actions = state, actions
        self._result = (next_states, rewards, collided)
        return self._result


class IntervalModel:
    """A planner model whose state is a box containing the true state (Theorem 1).

    Parameters
    ----------
    system
        The `UncertainLinearSystem` ``x+ = A(theta) x + B u + D w`` (one sub-step).
    parameters
        The parameter set: `Box`, `Ellipsoid` or vertex array (k, d), as for
        `IntervalPredictor`; None means ``system.theta``.
    reward
        A reward family with ``box_minimum(lower, upper, t) -> (reward, collided)``
        returning the EXACT minimum over each box, vectorised over leading dimensions
        (e.g. `minimaxplan.scenarios.GoalReward`), rewards in [0, 1]. It reads full
        states (each family holds its own coordinate indices).
    controllers
        One `OpenLoop` or `LinearFeedback` per action; the planner's actions are the
        indices ``0 .. len(controllers) - 1``.
    substeps
        Sub-steps of ``system`` per decision (>= 1); the action's controller acts at
        every sub-step.

    Notes
    -----
    Per sub-step, for every action at once (one batched product), the box is
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

    The batched arithmetic computes, per action and hypothesis, the same one-step box
    as `IntervalPredictor.step` (its vertex-wise exact bound), in round-to-nearest:
    it skips the predictor's outward rounding, so inclusion holds up to
    `minimaxplan.models.prediction.ROUNDING_TOL` relative (the tolerance DESIGN.md
    allows and the tests use), which saves the error-bound product of every sub-step.

    Several hypotheses for one planner: `IntervalModel.linked` builds one model per
    hypothesis that compute their transitions together (the planner sees M ordinary
    models; states then hold one box per hypothesis).
    """

    def __init__(self, system: UncertainLinearSystem, parameters, reward, controllers, *, substeps: int = 1) -> None:
        (model,) = self.linked([(system, parameters)], reward, controllers, substeps=substeps)
        self.__dict__.update(model.__dict__)

    @classmethod
    def linked(cls, systems_with_parameters, reward, controllers, *, substeps: int = 1) -> list["IntervalModel"]:
        """One `IntervalModel` per ``(system, parameters)`` hypothesis, computing their transitions together.

        The systems must have the same numbers of states and inputs. Use the list as
        the ``models`` of a `RobustTreePlanner` (in this order).
        """
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
            if not isinstance(system, UncertainLinearSystem):
                raise InputError(f"system must be an UncertainLinearSystem, got {type(system).__name__}")
            first = pairs[0][0]
            if (system.nstates, system.ninputs) != (first.nstates, first.ninputs):
                raise InputError(
                    f"systems_with_parameters[{i}] has {system.nstates} states and {system.ninputs} inputs, "
                    f"but the first system has {first.nstates} and {first.ninputs}"
                )
            resolved.append((system, system.theta if parameters is None else parameters))
        p, q = pairs[0][0].nstates, pairs[0][0].ninputs
        reward_minimum = _check_reward(reward, p)
        substeps = _check_substeps(substeps)
        bank = ControllerBank(controllers, p, q)
        group = _LinkedGroup(_IntervalCore(resolved, reward_minimum, bank, substeps))
        models = []
        for m, (system, parameters) in enumerate(resolved):
            model = cls.__new__(cls)
            model.system = system
            model.parameters = parameters
            model.reward = reward
            model.substeps = substeps
            model.bank = bank
            model.controllers = bank.controllers
            model.predictor = group.core.predictors[m]
            model.member = m
            model._group = group
            models.append(model)
        return models

    @property
    def n_actions(self) -> int:
        return len(self.bank)

    @property
    def actions(self) -> tuple[int, ...]:
        """The planner's actions: the controller indices."""
        return tuple(range(self.n_actions))

    @property
    def n_linked(self) -> int:
        """How many hypotheses this model is computed together with (itself included)."""
        return self._group.core.M

    @property
    def _joint(self):
        """``(group, member)``: the planner's private fast path for linked models.

        ``group.expand(state, actions)`` returns ``(next_states, rewards, terminals)``
        for every hypothesis of the group at once (rewards and terminals of shape
        (M, len(actions)), row m the result of `expand` of member m; ``group.size`` is M).
        """
        return self._group, self.member

    # --------------------------------------------------------------- protocol
    def expand(self, state: BoxState, actions) -> tuple[list, np.ndarray, np.ndarray]:
        """Step every action from ``state`` in one batched call (the planner's vectorised protocol).

        Returns ``(next_states, rewards, terminals)``: a list of `BoxState`, the
        pessimistic rewards (len(actions),) and the collision flags (len(actions),).
        """
        next_states, rewards, terminals = self._group.expand(state, actions)
        m = self.member
        return next_states, rewards[m], terminals[m]

    def step(self, state: BoxState, action) -> tuple[BoxState, float, bool]:
        """One transition: ``(next_state, pessimistic reward, terminal)``."""
        next_states, rewards, terminals = self.expand(state, (action,))
        return next_states[0], float(rewards[0]), bool(terminals[0])

    def initial_state(self, lower, upper=None, *, time: int = 0) -> BoxState:
        """The planner's root state: a `Box` (or arrays ``lower``, ``upper`` of shape (p,)) at sub-step ``time``.

        The same root state serves every linked hypothesis.
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
            raise EmptySetError(f"the initial box is empty: lower > upper at indices {np.flatnonzero(lo > hi).tolist()}")
        lo, hi = lo.copy(), hi.copy()
        lo.setflags(write=False)
        hi.setflags(write=False)
        return BoxState(lo, hi, _check_time(time))

    def box(self, state: BoxState) -> tuple[np.ndarray, np.ndarray]:
        """This hypothesis's box in ``state`` (states of linked models hold one box per hypothesis)."""
        if state.lower.ndim == 2:
            return state.lower[self.member], state.upper[self.member]
        return state.lower, state.upper

    def rollout(self, state: BoxState, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """This hypothesis's boxes at every sub-step along an action sequence.

        Returns ``lower, upper`` of shape (len(actions) * substeps + 1, p) (row 0 is
        the initial box) and the per-decision pessimistic rewards and terminal flags,
        each of shape (len(actions),). Rewards after a terminal transition are
        reported as computed (the planner ignores them).
        """
        if type(state) is not BoxState:
            raise InputError(f"state must be a BoxState, got {type(state).__name__}")
        seq = list(actions)
        self._group.actions(seq)
        core, m = self._group.core, self.member
        z = np.broadcast_to(core.state_z(state), (core.M, 1, 2 * core.p))
        p = core.p
        lowers, uppers = [-z[m, 0, :p]], [z[m, 0, p:]]
        rewards = np.empty(len(seq))
        terminals = np.zeros(len(seq), dtype=bool)
        time = state.time
        for n, action in enumerate(seq):
            index = np.array([int(action)])
            worst, hit = 1.0, False
            for s in range(1, self.substeps + 1):
                z = core.substep(z, index)
                r, c = core.reward_minimum(-z[..., :p], z[..., p:], time + s)
                worst, hit = min(worst, float(r[m, 0])), hit or bool(c[m, 0])
                lowers.append(-z[m, 0, :p])
                uppers.append(z[m, 0, p:])
            rewards[n], terminals[n] = worst, hit
            time += self.substeps
        return np.array(lowers), np.array(uppers), rewards, terminals
