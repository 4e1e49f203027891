"""The certainty-equivalent planner model: one parameter value, no disturbance.

`PointModel` steps the plant with a single parameter vector: the estimate theta-hat
(the paper's "nominal" comparison, certainty equivalence) or the true theta (the
"oracle"). Disturbances are taken as w = 0. Its rewards use the same aggregation as
`IntervalModel` (the minimum over the sub-steps between two decisions), so the
returns of both are directly comparable.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..models.system import UncertainLinearSystem
from ..models.validation import as_count, as_finite_array, check_instance
from .controllers import ControllerBank
from .interval_model import _ActionIndex, _check_reward, _SubstepTimes

__all__ = ["PointState", "PointModel"]


class PointState(NamedTuple):
    """A planner state of `PointModel`: the plant state ``x`` at sub-step ``time``."""

    x: np.ndarray
    time: int


class PointModel:
    """A planner model for one known parameter value, w = 0.

    Parameters
    ----------
    system : UncertainLinearSystem
        The plant ``x+ = A(theta) x + B u + D w`` (one sub-step).
    theta : array_like, shape (d,)
        The parameter vector used: an estimate (nominal planner) or the truth
        (oracle planner).
    reward : BoxReward
        A reward family with ``box_minimum(lower, upper, t)`` (evaluated on the
        degenerate box ``[x, x]``, i.e. at the point), rewards in [0, 1].
    controllers : sequence of OpenLoop or LinearFeedback
        One controller per action (saturation applied exactly).
    substeps : int, optional
        Sub-steps per decision (>= 1, default 1).

    Raises
    ------
    InputError
        If ``system`` is not an `UncertainLinearSystem`, ``reward`` has no callable
        ``box_minimum``, ``controllers`` is empty or holds another type, or
        ``substeps`` is not a positive integer.
    DimensionError
        If ``theta`` does not have shape (d,) or a controller does not fit the plant.

    Notes
    -----
    ``x+ = A(theta) x + B u(x)`` at every sub-step; the reward of a transition is
    ``min_s J(x_s, t + s)`` over its sub-steps, terminal on a collision.
    """

    def __init__(self, system: UncertainLinearSystem, theta, reward, controllers, *, substeps: int = 1) -> None:
        check_instance("system", system, UncertainLinearSystem)
        self.system = system
        self.theta = as_finite_array("theta", theta, (system.nparams,))
        self.theta.setflags(write=False)
        self.reward = reward
        self._reward_min = _check_reward(reward, system.nstates)
        self.substeps = as_count("substeps", substeps)
        self.bank = ControllerBank(controllers, system.nstates, system.ninputs)
        self.controllers = self.bank.controllers
        self._A_T = np.ascontiguousarray(system.A(self.theta).T)
        self._B_T = np.ascontiguousarray(system.B.T)
        self._actions = _ActionIndex(len(self.bank))
        self._p = system.nstates
        self._times = _SubstepTimes(self.substeps, trailing=1)
        # open-loop controls without saturation: B u is a constant per action
        constant = not self.bank.has_feedback and not self.bank.saturating
        self._constant_drift = self.bank.offsets @ self._B_T if constant else None

    @property
    def n_actions(self) -> int:
        """The number of actions ``|A|`` (one per controller)."""
        return len(self.bank)

    @property
    def actions(self) -> tuple[int, ...]:
        """The planner's actions: the controller indices ``0 .. n_actions - 1``."""
        return tuple(range(self.n_actions))

    def _propagate(self, x, time, index, n):
        """All sub-steps for n actions from x (p,); the reward is evaluated once for all sub-steps."""
        sel = slice(None) if index is None else index
        S = self.substeps
        states = np.empty((S, n, self._p))
        if self._constant_drift is not None:
            drift = self._constant_drift[sel]
            x = x @ self._A_T + drift  # the first step from one state, broadcast over actions
            states[0] = x
            for s in range(1, S):
                x = x @ self._A_T + drift
                states[s] = x
        else:
            x = np.broadcast_to(x, (n, self._p))
            for s in range(S):
                x = x @ self._A_T + self.bank.controls(x, sel) @ self._B_T
                states[s] = x
        reward, collided = self._reward_min(states, states, self._times[time])
        return states[-1], reward.min(axis=0), collided.any(axis=0)

    def expand(self, state: PointState, actions) -> tuple[list, np.ndarray, np.ndarray]:
        """Step every action from ``state`` in one batched call.

        Parameters
        ----------
        state : PointState
            The current state (from `initial_state` or an earlier transition).
        actions : sequence of int
            Controller indices in ``[0, n_actions)``.

        Returns
        -------
        next_states : list of PointState
            The state after the decision, per action.
        rewards : ndarray, shape (len(actions),)
            The minimum of the reward over the decision's sub-step states, in [0, 1].
        terminals : ndarray of bool, shape (len(actions),)
            Whether one of those states collides.

        Raises
        ------
        InputError
            If ``state`` is not a `PointState` or an action is not a controller index.
        """
        if type(state) is not PointState:  # the hot path tests the exact type; the validator words the error
            check_instance("state", state, PointState, "a PointState (see PointModel.initial_state)")
        index = self._actions(actions)
        n = self.n_actions if index is None else len(index)
        x, rewards, terminals = self._propagate(state.x, state.time, index, n)
        time = state.time + self.substeps
        return [PointState(x[i], time) for i in range(n)], rewards, terminals

    def step(self, state: PointState, action) -> tuple[PointState, float, bool]:
        """One transition: ``(next_state, reward, terminal)``.

        Parameters
        ----------
        state : PointState
            The current state.
        action : int
            A controller index in ``[0, n_actions)``.

        Returns
        -------
        next_state : PointState
            The state after the decision.
        reward : float
            The minimum reward over the decision's sub-steps, in [0, 1].
        terminal : bool
            Whether a sub-step state collides.

        Raises
        ------
        InputError
            As for `expand`.
        """
        next_states, rewards, terminals = self.expand(state, (action,))
        return next_states[0], float(rewards[0]), bool(terminals[0])

    def initial_state(self, x, *, time: int = 0) -> PointState:
        """The planner's root state from a measured state at sub-step ``time``.

        Parameters
        ----------
        x : array_like, shape (p,)
            The plant state, in the plant's state units (copied, read-only).
        time : int, optional
            The absolute sub-step index (>= 0, default 0), the reward's time argument.

        Returns
        -------
        PointState
            The root state.

        Raises
        ------
        DimensionError
            If ``x`` does not have shape (p,).
        NonFiniteError
            If ``x`` has NaN or infinite entries.
        InputError
            If ``time`` is not an integer >= 0.
        """
        x = as_finite_array("x", x, (self._p,))
        x = x.copy()
        x.setflags(write=False)
        return PointState(x, as_count("time", time, minimum=0))
