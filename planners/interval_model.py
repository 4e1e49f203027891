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

from typing import NamedTuple

import numpy as np

from ..models._validation import as_finite_array
from ..models.errors import DimensionError, EmptySetError, InputError
from ..models.prediction import IntervalPredictor, interval_matvec
from ..models.sets import Box
from ..models.system import UncertainLinearSystem
from .controllers import ControllerBank

__all__ = ["BoxState", "IntervalModel"]


class BoxState(NamedTuple):
    """A planner state of `IntervalModel`: the box ``[lower, upper]`` at sub-step ``time``."""

    lower: np.ndarray
    upper: np.ndarray
    time: int


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
    """``times[t]``: the sub-step indices t+1 .. t+S as an array (S, 1, 1), cached per t."""

    def __init__(self, substeps: int) -> None:
        self._offsets = np.arange(1, substeps + 1).reshape(substeps, 1, 1)
        self._cache: dict[int, np.ndarray] = {}

    def __getitem__(self, time: int) -> np.ndarray:
        value = self._cache.get(time)
        if value is None:
            value = self._offsets + time
            value.setflags(write=False)
            if len(self._cache) < 4096:
                self._cache[time] = value
        return value


class _IntervalCore:
    """The batched arithmetic of one or several hypotheses under every controller.

    Boxes are arrays (M, A', p): M hypotheses (``members``) times A' actions. Every
    array below is precomputed; `propagate` runs on raw arrays only.
    """

    def __init__(self, members, reward_minimum, bank: ControllerBank, substeps: int) -> None:
        self.reward_minimum = reward_minimum
        self.bank = bank
        self.substeps = substeps
        self.times = _SubstepTimes(substeps)
        systems = [system for system, _ in members]
        self.M = M = len(members)
        self.p = p = systems[0].nstates
        predictors = [IntervalPredictor(system, parameters) for system, parameters in members]
        self.predictors = predictors
        k = max(pred.nvertices for pred in predictors)
        # pad each hypothesis to k vertex matrices by repeating one (harmless under min / max)
        vertices = np.stack(
            [np.concatenate([pred.vertex_matrices, np.repeat(pred.vertex_matrices[:1], k - pred.nvertices, axis=0)])
             for pred in predictors]
        )  # (M, k, p, p), identity basis
        B = np.stack([system.B for system in systems])  # (M, p, q)
        self.k = k
        self.per_action = bank.has_feedback
        # columns: [-(lower candidates) | upper candidates], so that one max over k gives both bounds
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
        drift = np.einsum("mpq,aq->map", B, bank.offsets)  # (M, A, p): B_m c_a
        self.drift_lo = drift + self.w_lo
        self.drift_hi = drift + self.w_hi
        self.B_pos = np.maximum(B, 0.0)
        self.B_neg = np.maximum(-B, 0.0)
        self.K_pos = np.maximum(bank.gains, 0.0)
        self.K_neg = np.maximum(-bank.gains, 0.0)

    def _product(self, matrices):
        """``[z_lo | z_hi] @ product = [-(M+ z_lo - M- z_hi) | M+ z_hi - M- z_lo]`` for each of k matrices."""
        p, k = self.p, matrices.shape[-3]
        stacked = matrices.reshape(*matrices.shape[:-3], k * p, p)
        pos_t = np.swapaxes(np.maximum(stacked, 0.0), -1, -2)  # (..., p, kp)
        neg_t = np.swapaxes(np.maximum(-stacked, 0.0), -1, -2)
        top = np.concatenate([-pos_t, -neg_t], axis=-1)  # rows for z_lo
        bottom = np.concatenate([neg_t, pos_t], axis=-1)  # rows for z_hi
        return np.ascontiguousarray(np.concatenate([top, bottom], axis=-2))

    def substep(self, lower, upper, index):
        """One sub-step of boxes (M, A', p) under the actions ``index`` (None = all, in order)."""
        M, k, p = self.M, self.k, self.p
        z = np.concatenate([lower, upper], axis=-1)
        if self.per_action:
            product = self.product if index is None else self.product[:, index]
            candidates = np.matmul(z[..., None, :], product)[..., 0, :]
        else:
            candidates = np.matmul(z, self.open_product)
        n = z.shape[1]
        bounds = candidates.reshape(M, n, 2, k, p).max(axis=3) if k > 1 else candidates.reshape(M, n, 2, p)
        if index is None:
            new_lower = self.drift_lo - bounds[:, :, 0]
            new_upper = bounds[:, :, 1] + self.drift_hi
        else:
            new_lower = self.drift_lo[:, index] - bounds[:, :, 0]
            new_upper = bounds[:, :, 1] + self.drift_hi[:, index]
        if self.bank.saturating:
            new_lower, new_upper = self._saturation(lower, upper, new_lower, new_upper, z, index)
        return new_lower, new_upper

    def _saturation(self, lower, upper, cl_lower, cl_upper, z, index):
        """Closed loop plus the bounded correction s(v), intersected with the open-loop bound."""
        sel = slice(None) if index is None else index
        bank = self.bank
        k_pos, k_neg = self.K_pos[sel], self.K_neg[sel]
        # v = c - K x over the box: [c - (K+ hi - K- lo), c - (K+ lo - K- hi)]
        kx_lo = np.einsum("aqp,map->maq", k_pos, lower) - np.einsum("aqp,map->maq", k_neg, upper)
        kx_hi = np.einsum("aqp,map->maq", k_pos, upper) - np.einsum("aqp,map->maq", k_neg, lower)
        offsets, low, high = bank.offsets[sel], bank.low[sel], bank.high[sel]
        v_lo, v_hi = offsets - kx_hi, offsets - kx_lo
        u_lo, u_hi = np.clip(v_lo, low, high), np.clip(v_hi, low, high)
        # s(v) = sat(v) - v is nonincreasing: s in [s(v_hi), s(v_lo)], entered through B
        s_lo, s_hi = u_hi - v_hi, u_lo - v_lo
        cl_lower = cl_lower + self._input_lower(s_lo, s_hi)
        cl_upper = cl_upper + self._input_upper(s_lo, s_hi)
        # open loop with the interval input [sat(v_lo), sat(v_hi)]
        M, k, p = self.M, self.k, self.p
        n = z.shape[1]
        candidates = np.matmul(z, self.open_product)
        bounds = candidates.reshape(M, n, 2, k, p).max(axis=3)
        ol_lower = self.w_lo - bounds[:, :, 0] + self._input_lower(u_lo, u_hi)
        ol_upper = bounds[:, :, 1] + self.w_hi + self._input_upper(u_lo, u_hi)
        return np.maximum(cl_lower, ol_lower), np.minimum(cl_upper, ol_upper)

    def _input_lower(self, u_lo, u_hi):
        return np.einsum("mpq,maq->map", self.B_pos, u_lo) - np.einsum("mpq,maq->map", self.B_neg, u_hi)

    def _input_upper(self, u_lo, u_hi):
        return np.einsum("mpq,maq->map", self.B_pos, u_hi) - np.einsum("mpq,maq->map", self.B_neg, u_lo)

    def propagate(self, lower, upper, time, index, n_actions):
        """All sub-steps of one decision; boxes broadcast to (M, n_actions, p).

        Returns the final boxes, the pessimistic rewards (M, n_actions) (minimum over
        the sub-steps) and the collision flags (any over the sub-steps). The reward is
        evaluated once for the boxes of all sub-steps, stacked as (S, M, n_actions, p)
        with the sub-step indices ``t`` of shape (S, 1, 1).
        """
        shape = (self.M, n_actions, self.p)
        lower = np.broadcast_to(lower, shape)
        upper = np.broadcast_to(upper, shape)
        S = self.substeps
        if S == 1:
            lower, upper = self.substep(lower, upper, index)
            reward, collided = self.reward_minimum(lower, upper, time + 1)
            return lower, upper, reward, collided
        lowers = np.empty((S,) + shape)
        uppers = np.empty((S,) + shape)
        for s in range(S):
            lower, upper = self.substep(lower, upper, index)
            lowers[s] = lower
            uppers[s] = upper
        reward, collided = self.reward_minimum(lowers, uppers, self.times[time])
        return lower, upper, reward.min(axis=0), collided.any(axis=0)


class _LinkedGroup:
    """The hypotheses of a multi-model planner, stepped together.

    The planner steps its M models one after the other from the same node. Linked
    models share one `_IntervalCore`: the first model asked computes the transitions of
    all M hypotheses in one batched call and the others read their row from a
    one-entry cache, keyed by the identity of the (immutable) state and actions objects.
    """

    def __init__(self, core: _IntervalCore) -> None:
        self.core = core
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
        lower, upper = state.lower, state.upper
        if lower.ndim == 2:  # one box per hypothesis
            if lower.shape[0] != core.M:
                raise DimensionError(f"state holds {lower.shape[0]} boxes, expected {core.M} (one per linked hypothesis)")
            lower, upper = lower[:, None, :], upper[:, None, :]
        lower, upper, rewards, collided = core.propagate(lower, upper, state.time, index, n)
        time = state.time + core.substeps
        if core.M == 1:
            next_states = [BoxState(lower[0, i], upper[0, i], time) for i in range(n)]
        else:
            next_states = [BoxState(lower[:, i], upper[:, i], time) for i in range(n)]
        rewards.flags.writeable = False
        collided.flags.writeable = False
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
        lower, upper = (state.lower[:, None, :], state.upper[:, None, :]) if state.lower.ndim == 2 else (state.lower, state.upper)
        lower = np.broadcast_to(lower, (core.M, 1, core.p))
        upper = np.broadcast_to(upper, (core.M, 1, core.p))
        lowers, uppers = [lower[m, 0]], [upper[m, 0]]
        rewards = np.empty(len(seq))
        terminals = np.zeros(len(seq), dtype=bool)
        time = state.time
        for n, action in enumerate(seq):
            index = np.array([int(action)])
            worst, hit = 1.0, False
            for s in range(1, self.substeps + 1):
                lower, upper = core.substep(lower, upper, index)
                r, c = core.reward_minimum(lower, upper, time + s)
                worst, hit = min(worst, float(r[m, 0])), hit or bool(c[m, 0])
                lowers.append(lower[m, 0])
                uppers.append(upper[m, 0])
            rewards[n], terminals[n] = worst, hit
            time += self.substeps
        return np.array(lowers), np.array(uppers), rewards, terminals
