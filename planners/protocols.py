"""The protocols through which the tree-search planners see their models.

`RobustTreePlanner` and `OptimisticPlanner` never import a simulator nor sniff private
attributes: a model is anything following `TransitionModel` (optionally
`VectorisedModel`), and models computed together (e.g. `IntervalModel.linked`) declare
their shared computation through `LinkedModel` and `BatchedTransitions`, and a linked
group whose search can run compiled through `CompiledTransitions`. The planner checks
these with ``isinstance`` (the protocols are ``runtime_checkable``), then validates
what the calls return.

States are opaque to the planner and never copied: one state object may be shared by
several tree nodes (below a terminal transition) and, when `plan` gets one initial
state, by every model. Models must return new states, never modify a given state in
place.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from .box_kernels import IntervalKernel

__all__ = [
    "TransitionModel",
    "VectorisedModel",
    "BatchedTransitions",
    "FallbackModel",
    "LinkedModel",
    "CompiledTransitions",
    "CompiledProblem",
    "CollisionHorizonModel",
]


@runtime_checkable
class TransitionModel(Protocol):
    """A planner model: one deterministic transition per (state, action).

    Notes
    -----
    ``step(state, action)`` returns ``(next_state, reward)`` or ``(next_state,
    reward, terminal)``, with ``reward`` in [0, 1] (maximised; the paper's "cost" J)
    and ``terminal`` a bool. After a terminal transition the model is never stepped
    again on that branch: its later rewards are 0 and its state stays the terminal
    state (eqs. (15)-(18) with the discounted b-value of eq. (16)).
    """

    def step(self, state: Any, action: Any) -> tuple:
        """``(next_state, reward)`` or ``(next_state, reward, terminal)``.

        Parameters
        ----------
        state : Any
            The current state (opaque to the planner; not modified).
        action : Any
            One of the planner's actions.
        """


@runtime_checkable
class VectorisedModel(TransitionModel, Protocol):
    """A `TransitionModel` that also steps every action from one state in one call.

    Notes
    -----
    ``expand(state, actions)`` returns ``(next_states, rewards, terminals)``:
    ``next_states`` a sequence of ``len(actions)`` states, ``rewards`` a float array of
    shape ``(len(actions),)`` and ``terminals`` a bool array of the same shape, equal
    to ``step`` applied to each action. The planner uses it instead of ``step``; the
    tree does not depend on which is used.
    """

    def expand(self, state: Any, actions: Sequence) -> tuple[Sequence, np.ndarray, np.ndarray]:
        """``(next_states, rewards, terminals)`` for every action of ``actions``.

        Parameters
        ----------
        state : Any
            The current state (not modified).
        actions : sequence
            The planner's actions, in order.
        """


@runtime_checkable
class FallbackModel(TransitionModel, Protocol):
    """A `TransitionModel` that bounds the return of a fixed continuation from any state.

    Notes
    -----
    ``fallback_values(states, gamma)`` returns, for each state, a float F in
    ``[0, 1 / (1 - gamma)]`` with ``F <= sum_n gamma^n r_n`` along some sequence of
    actions from that state fixed in advance (e.g. braking until the end of the
    reward's horizon): a pessimistic value of a plan that the planner could also
    follow. `RobustTreePlanner` then takes ``min_m (R_m + gamma^l F_m)`` as a leaf's
    lower bound instead of the paper's ``min_m R_m`` (eq. (18)); it stays a lower bound
    of the robust value (eq. (13)) because the leaf's path followed by the continuation
    is one plan, evaluated in every model. The upper bounds are unchanged. It is used
    only when every model of the planner gives it.
    """

    def fallback_values(self, states: Sequence, gamma: float) -> np.ndarray:
        """F for each state of ``states``, shape ``(len(states),)``.

        Parameters
        ----------
        states : sequence
            States of this model (not modified).
        gamma : float
            The planner's discount factor in (0, 1).
        """


@runtime_checkable
class BatchedTransitions(Protocol):
    """All M models of a group and all actions from one shared state, in one call.

    Attributes
    ----------
    size
        The number of models M of the group.

    Notes
    -----
    ``expand_all(state, actions)`` returns ``(next_states, rewards, terminals)``:
    ``next_states`` a sequence of ``len(actions)`` joint states (each one the state
    of every member, as the members' own ``expand`` returns them), ``rewards`` a
    float64 array ``(M, len(actions))`` and ``terminals`` a bool array of the same
    shape; row m is exactly what member m's ``expand(state, actions)`` returns.
    """

    @property
    def size(self) -> int:
        """The number of models M."""

    def expand_all(self, state: Any, actions: Sequence) -> tuple[Sequence, np.ndarray, np.ndarray]:
        """``(next_states, rewards (M, n), terminals (M, n))`` from ``state`` under every action.

        Parameters
        ----------
        state : Any
            The state shared by every member (not modified).
        actions : sequence
            The planner's n actions, in order.
        """


@runtime_checkable
class LinkedModel(TransitionModel, Protocol):
    """A model computed together with others: member ``member`` of the `BatchedTransitions` ``group``.

    When a planner's models are exactly the members of one group, in member order,
    and a tree node's models share one state, the planner takes all M models'
    transitions from one ``group.expand_all`` call.
    """

    @property
    def group(self) -> BatchedTransitions:
        """The group this model is computed with."""

    @property
    def member(self) -> int:
        """This model's index in its group."""


@runtime_checkable
class CollisionHorizonModel(Protocol):
    """A model that tells when a plan may first collide (`minimaxplan.planners.latest_collision_action`).

    Notes
    -----
    ``first_possible_collision(state, plan, horizon)`` takes the plan's actions in
    turn from ``state``, then holds its last one, and returns the first sub-step in
    ``[1, horizon]`` (relative to the state's time) at which the model's prediction
    may collide, or ``horizon + 1`` if none does: the sub-steps that make a
    transition terminal. `BicycleModel` and `IntervalModel` follow it.
    """

    @property
    def n_actions(self) -> int:
        """The number of actions; plans hold action indices in ``[0, n_actions)``."""

    def first_possible_collision(self, state: Any, plan: Sequence[int], horizon: int) -> int:
        """The first sub-step of a possible collision along ``plan``, or ``horizon + 1``.

        Parameters
        ----------
        state : Any
            The start state (not modified).
        plan : sequence of int
            Action indices, at least one; the last is held.
        horizon : int
            Sub-steps examined, ``>= 1``.
        """


class CompiledProblem(NamedTuple):
    """What the compiled search needs from a linked group for one root state.

    Attributes
    ----------
    root : ndarray (M, 2p)
        The root boxes ``[-lower | upper]``, one per member (writable, contiguous).
    time : int
        The root's sub-step index.
    actions : ndarray (n,) of int64
        The planner's actions as controller indices.
    kernel : IntervalKernel
        The precomputed box arithmetic (`minimaxplan.planners.box_kernels.substep`).
    params : Any
        The reward family's ``kernel_params`` (a registered namedtuple).
    substeps : int
        Sub-steps per decision.
    """

    root: np.ndarray
    time: int
    actions: np.ndarray
    kernel: IntervalKernel
    params: Any
    substeps: int


@runtime_checkable
class CompiledTransitions(BatchedTransitions, Protocol):
    """A `BatchedTransitions` group whose transitions the compiled search can compute itself.

    Notes
    -----
    ``compiled`` says whether it can (e.g. whether the reward has a compiled box
    minimum); ``compiled_problem(state, actions)`` gives the kernel's inputs for a
    root state; ``node_states(z, depth, time)`` turns the boxes the compiled search
    left in ``z`` (nodes, M, 2p) back into the joint state objects that
    ``expand_all`` would have returned for nodes ``1 ..`` (item 0 is unused), with
    ``time`` the root's sub-step index and ``depth`` the node depths.
    """

    @property
    def compiled(self) -> bool:
        """Whether the compiled search can run on this group."""

    def compiled_problem(self, state: Any, actions: Sequence) -> CompiledProblem:
        """The compiled search's inputs for root ``state`` and the planner's ``actions``.

        Parameters
        ----------
        state : Any
            The root state shared by every member.
        actions : sequence
            The planner's actions, in order.
        """

    def node_states(self, z: np.ndarray, depth: Sequence[int], time: int) -> list:
        """The joint state of each node ``i >= 1`` of a compiled search.

        Parameters
        ----------
        z : ndarray (nodes, M, 2p)
            The boxes ``[-lower | upper]`` the compiled search left, one row per node (owned by the group).
        depth : sequence of int
            Each node's depth in the tree.
        time : int
            The root's sub-step index.
        """
