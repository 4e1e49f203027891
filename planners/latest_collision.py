"""The latest-possible-collision rule: when the tree's best plan may collide, the first action clear longest.

`RobustTreePlanner` maximises the worst-case discounted return (eq. (13)). When every
plan may collide within the horizon, that return is the reward collected until the
first possible collision, and the tree's lower bounds no longer say which first action
keeps the agent clear longest: plans that meet a box within the same decision tie (the
smallest action index wins), and a plan that first moves towards the goal may collect
more reward before meeting a box sooner. Time clear of every box is time in which new
measurements shrink the boxes. `latest_collision_action` executes, in that case, a first
action whose examined plans stay clear longest under every model.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..models.errors import InputError
from ..models.validation import as_count, check_instance
from .decision import Decision
from .protocols import CollisionHorizonModel

__all__ = ["latest_collision_action"]


def latest_collision_action(
    models: Sequence[CollisionHorizonModel], root: Any, decision: Decision, *, horizon: int
) -> tuple[int, list[int] | None]:
    """The tree's action, unless another first action keeps clear of every box for longer under every model.

    A plan's figure is its first possible collision over ``models``: the earliest of
    their `CollisionHorizonModel.first_possible_collision` (the worst case over the
    models, as the robust objective takes it). For each first action ``a``, the latest
    figure over the examined plans that start with it: ``a`` then each action held,
    and the tree's best sequence (its last action held) when it starts with ``a``. The
    executed action is the tree's when its figure is the largest (always when the
    tree's best sequence stays clear for the whole horizon), else the action of the
    largest figure with the largest tree lower bound (the smallest index on ties).

    Parameters
    ----------
    models : sequence of CollisionHorizonModel
        The models the tree planned with (e.g. one `IntervalModel` per surviving
        hypothesis, or one `BicycleModel`), at least one, with the same actions.
    root : Any
        The tree's root state (a state of every model).
    decision : Decision
        The tree's decision from ``root``.
    horizon : int
        Sub-steps examined, ``>= 1``.

    Returns
    -------
    action : int
        The index of the action to execute.
    latest : list of int or None
        Per action, the latest figure over its examined plans, in sub-steps after the
        root (``horizon + 1``: some examined plan stays clear over the horizon); None
        when the tree's best sequence stays clear (nothing else examined).

    Raises
    ------
    InputError
        If ``models`` is empty, holds a model without the protocol or models with
        different numbers of actions, ``decision`` is not a `Decision` or has another
        number of root actions, or ``horizon`` is not a positive integer.
    """
    check_instance("decision", decision, Decision)
    horizon = as_count("horizon", horizon)
    if not isinstance(models, Sequence):
        raise InputError(f"models must be a sequence of CollisionHorizonModel, got {type(models).__name__}")
    models = tuple(models)
    if not models:
        raise InputError("models must hold at least one CollisionHorizonModel, got an empty sequence")
    for i, model in enumerate(models):
        if not isinstance(model, CollisionHorizonModel):
            raise InputError(
                f"models[{i}] must follow CollisionHorizonModel (n_actions, first_possible_collision), "
                f"got {type(model).__name__}"
            )
    n_actions = models[0].n_actions
    if any(model.n_actions != n_actions for model in models):
        raise InputError(f"models must share their actions, got n_actions {[m.n_actions for m in models]}")
    if len(decision.action_lower) != n_actions or not 0 <= decision.action_index < n_actions:
        raise InputError(
            f"decision has {len(decision.action_lower)} root actions (action_lower of shape "
            f"({len(decision.action_lower)},), action_index {decision.action_index}), but the models have "
            f"n_actions = {n_actions}: it is not a decision of a planner over these models"
        )

    def first_collision(plan: tuple[int, ...]) -> int:
        return min(model.first_possible_collision(root, plan, horizon) for model in models)

    clear = horizon + 1
    tree = int(decision.action_index)
    sequence = tuple(int(a) for a in decision.sequence_indices)
    along_tree = first_collision(sequence)
    if along_tree == clear:
        return tree, None
    latest = []
    for first in range(n_actions):
        held = max(first_collision((first, then)) for then in range(n_actions))
        latest.append(max(held, along_tree) if sequence[0] == first else held)
    best = max(latest)
    if latest[tree] == best:
        return tree, latest
    lower = np.asarray(decision.action_lower, dtype=float)
    candidates = [a for a in range(n_actions) if latest[a] == best]
    return max(candidates, key=lambda a: (lower[a], -a)), latest
