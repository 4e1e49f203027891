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
        returning the EXACT minimum over each box (e.g. `minimaxplan.scenarios.GoalReward`),
        rewards in [0, 1]. It reads full states (each family holds its own coordinate
        indices).
    controllers
        One `OpenLoop` or `LinearFeedback` per action; the planner's actions are the
        indices ``0 .. len(controllers) - 1``.
    substeps
        Sub-steps of ``system`` per decision (>= 1); the action's controller acts at
        every sub-step.

    Notes
    -----
    Per sub-step, for every action a at once (one batched product), the box is
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
    """

    def __init__(self, system: UncertainLinearSystem, parameters, reward, controllers, *, substeps: int = 1) -> None:
        if not isinstance(system, UncertainLinearSystem):
            raise InputError(f"system must be an UncertainLinearSystem, got {type(system).__name__}")
        p, q = system.nstates, system.ninputs
        self.system = system
        self.parameters = system.theta if parameters is None else parameters
        self.reward = reward
        self._reward_min = _check_reward(reward, p)
        self.substeps = _check_substeps(substeps)
        self.bank = ControllerBank(controllers, p, q)
        self.controllers = self.bank.controllers
        self.predictor = IntervalPredictor(system, self.parameters)
        self._actions = _ActionIndex(len(self.bank))
        self._precompute()

    @property
    def n_actions(self) -> int:
        return len(self.bank)

    @property
    def actions(self) -> tuple[int, ...]:
        """The planner's actions: the controller indices."""
        return tuple(range(self.n_actions))

    # ----------------------------------------------------------------- set-up
    def _precompute(self) -> None:
        system, bank = self.system, self.bank
        p = system.nstates
        vertices = np.asarray(self.predictor.vertex_matrices)  # (k, p, p), identity basis
        k = vertices.shape[0]
        closed = vertices[None] - np.einsum("ij,ajl->ail", system.B, bank.gains)[:, None]  # (a, k, p, p)
        stacked = closed.reshape(len(bank), k * p, p)
        positive, negative = np.maximum(stacked, 0.0), np.maximum(-stacked, 0.0)
        pt, nt = positive.transpose(0, 2, 1), negative.transpose(0, 2, 1)
        # [lower | upper] @ product -> [all k lower candidates | all k upper candidates]
        product = np.concatenate([np.concatenate([pt, -nt], axis=2), np.concatenate([-nt, pt], axis=2)], axis=1)
        self._k, self._p = k, p
        self._shared = not bank.has_feedback
        self._product = np.ascontiguousarray(product[0] if self._shared else product)  # (2p, 2kp) or (a, 2p, 2kp)
        self._open_product = None
        if bank.saturating:
            open_stacked = vertices.reshape(k * p, p)
            op, on = np.maximum(open_stacked, 0.0).T, np.maximum(-open_stacked, 0.0).T
            self._open_product = np.ascontiguousarray(np.block([[op, -on], [-on, op]]))
        w_lo, w_hi = interval_matvec(system.D, system.w.low, system.w.high)
        self._w_lo, self._w_hi = w_lo, w_hi
        self._drift = bank.offsets @ system.B.T  # (a, p): B c_a
        self._B = np.asarray(system.B)
        self._B_pos_T = np.maximum(self._B, 0.0).T.copy()
        self._B_neg_T = np.maximum(-self._B, 0.0).T.copy()
        self._K_pos = np.maximum(bank.gains, 0.0)
        self._K_neg = np.maximum(-bank.gains, 0.0)

    # -------------------------------------------------------------- hot path
    def _substep(self, lower, upper, index):
        """One sub-step for the actions ``index`` (None = all), boxes (a, p)."""
        k, p = self._k, self._p
        z = np.concatenate([lower, upper], axis=-1)
        if self._shared:
            candidates = z @ self._product
        else:
            product = self._product if index is None else self._product[index]
            candidates = np.matmul(z[:, None, :], product)[:, 0, :]
        new_lower, new_upper = candidates[:, : k * p], candidates[:, k * p :]
        if k > 1:
            new_lower = new_lower.reshape(-1, k, p).min(axis=1)
            new_upper = new_upper.reshape(-1, k, p).max(axis=1)
        drift = self._drift if index is None else self._drift[index]
        new_lower = new_lower + (drift + self._w_lo)
        new_upper = new_upper + (drift + self._w_hi)
        if self.bank.saturating:
            new_lower, new_upper = self._saturation(lower, upper, new_lower, new_upper, z, index)
        return new_lower, new_upper

    def _saturation(self, lower, upper, cl_lower, cl_upper, z, index):
        """Account for saturation: closed loop + bounded correction, intersected with the open-loop bound."""
        sel = slice(None) if index is None else index
        bank = self.bank
        # v = c - K x over the box: [c - (K+ hi - K- lo), c - (K+ lo - K- hi)]
        kx_lo = np.einsum("aqp,ap->aq", self._K_pos[sel], lower) - np.einsum("aqp,ap->aq", self._K_neg[sel], upper)
        kx_hi = np.einsum("aqp,ap->aq", self._K_pos[sel], upper) - np.einsum("aqp,ap->aq", self._K_neg[sel], lower)
        offsets, low, high = bank.offsets[sel], bank.low[sel], bank.high[sel]
        v_lo, v_hi = offsets - kx_hi, offsets - kx_lo
        u_lo, u_hi = np.clip(v_lo, low, high), np.clip(v_hi, low, high)
        # correction s(v) = sat(v) - v is nonincreasing: s in [s(v_hi), s(v_lo)]
        s_lo, s_hi = u_hi - v_hi, u_lo - v_lo
        cl_lower = cl_lower + (s_lo @ self._B_pos_T - s_hi @ self._B_neg_T)
        cl_upper = cl_upper + (s_hi @ self._B_pos_T - s_lo @ self._B_neg_T)
        # open loop with the interval input [sat(v_lo), sat(v_hi)]
        k, p = self._k, self._p
        candidates = z @ self._open_product
        ol_lower, ol_upper = candidates[:, : k * p], candidates[:, k * p :]
        if k > 1:
            ol_lower = ol_lower.reshape(-1, k, p).min(axis=1)
            ol_upper = ol_upper.reshape(-1, k, p).max(axis=1)
        ol_lower = ol_lower + (u_lo @ self._B_pos_T - u_hi @ self._B_neg_T) + self._w_lo
        ol_upper = ol_upper + (u_hi @ self._B_pos_T - u_lo @ self._B_neg_T) + self._w_hi
        return np.maximum(cl_lower, ol_lower), np.minimum(cl_upper, ol_upper)

    def _propagate(self, lower, upper, time, index, n_actions):
        """All sub-steps of one decision for n_actions actions; returns boxes, rewards, collisions."""
        lower = np.broadcast_to(lower, (n_actions, self._p))
        upper = np.broadcast_to(upper, (n_actions, self._p))
        worst = None
        collided = None
        for s in range(1, self.substeps + 1):
            lower, upper = self._substep(lower, upper, index)
            reward, hit = self._reward_min(lower, upper, time + s)
            if worst is None:
                worst, collided = reward, hit
            else:
                worst = np.minimum(worst, reward)
                collided = collided | hit
        return lower, upper, np.asarray(worst, dtype=float), np.asarray(collided, dtype=bool)

    # --------------------------------------------------------------- protocol
    def expand(self, state: BoxState, actions) -> tuple[list, np.ndarray, np.ndarray]:
        """Step every action from ``state`` in one batched call (the planner's vectorised protocol).

        Returns ``(next_states, rewards, terminals)``: a list of `BoxState`, the
        pessimistic rewards (len(actions),) and the collision flags (len(actions),).
        """
        if type(state) is not BoxState:
            raise InputError(f"state must be a BoxState (see IntervalModel.initial_state), got {type(state).__name__}")
        index = self._actions(actions)
        n = self.n_actions if index is None else len(index)
        lower, upper, rewards, terminals = self._propagate(state.lower, state.upper, state.time, index, n)
        time = state.time + self.substeps
        return [BoxState(lower[i], upper[i], time) for i in range(n)], rewards, terminals

    def step(self, state: BoxState, action) -> tuple[BoxState, float, bool]:
        """One transition: ``(next_state, pessimistic reward, terminal)``."""
        next_states, rewards, terminals = self.expand(state, (action,))
        return next_states[0], float(rewards[0]), bool(terminals[0])

    def initial_state(self, lower, upper=None, *, time: int = 0) -> BoxState:
        """The planner's root state: a `Box` (or arrays ``lower``, ``upper`` of shape (p,)) at sub-step ``time``."""
        p = self._p
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

    def rollout(self, state: BoxState, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Boxes at every sub-step along an action sequence.

        Returns ``lower, upper`` of shape (len(actions) * substeps + 1, p) (row 0 is
        the initial box) and the per-decision pessimistic rewards and terminal flags,
        each of shape (len(actions),). Rewards after a terminal transition are
        reported as computed (the planner ignores them).
        """
        if type(state) is not BoxState:
            raise InputError(f"state must be a BoxState, got {type(state).__name__}")
        seq = list(actions)
        self._actions(seq)
        S = self.substeps
        lowers = [np.asarray(state.lower)]
        uppers = [np.asarray(state.upper)]
        rewards = np.empty(len(seq))
        terminals = np.zeros(len(seq), dtype=bool)
        lower, upper, time = state.lower[None], state.upper[None], state.time
        for n, action in enumerate(seq):
            index = np.array([int(action)])
            worst, hit = 1.0, False
            for s in range(1, S + 1):
                lower, upper = self._substep(lower, upper, index)
                r, c = self._reward_min(lower, upper, time + s)
                worst, hit = min(worst, float(r[0])), hit or bool(c[0])
                lowers.append(lower[0])
                uppers.append(upper[0])
            rewards[n], terminals[n] = worst, hit
            time += S
        return np.array(lowers), np.array(uppers), rewards, terminals
