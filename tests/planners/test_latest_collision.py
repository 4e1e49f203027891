"""The latest-possible-collision rule over interval models: the first possible collision and the executed action."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import Box
from minimaxplan.models.errors import InputError
from minimaxplan.planners import IntervalModel, latest_collision_action
from minimaxplan.planners.comparison import multi_model_robust_planner
from minimaxplan.planners.protocols import CollisionHorizonModel
from minimaxplan.scenarios.geometry import CircularObstacles
from minimaxplan.scenarios.rewards import GoalReward

from . import _systems as systems
from ._systems import ROBOT_ACTIONS, robot_system

seeds = st.integers(0, 2**31 - 1)


def test_the_interval_model_follows_the_protocol():
    """(The road tests pass a `BicycleModel` to the same rule.)"""
    planner, _, _ = _crowded_case(0)
    assert all(isinstance(m, CollisionHorizonModel) for m in planner.models)


@settings(max_examples=30, deadline=None)
@given(seeds, st.integers(1, 4), st.integers(1, 4))
def test_property_first_possible_collision_is_the_first_terminal_sub_step(seed, substeps, decisions):
    """Random plants (non-Metzler), random controllers with saturation, random obstacles: the figure is the
    first sub-step whose box may collide, and it lies in the first decision that `rollout` (the tree's
    transitions) flags terminal; a plan shorter than the horizon holds its last action."""
    rng = np.random.default_rng(seed)
    system = systems.random_system(rng, p=4, q=2)
    controllers = systems.random_controllers(rng, system, n=3)
    obstacles = CircularObstacles(rng.uniform(-2, 2, (5, 2)), rng.uniform(0.1, 0.6, 5))
    reward = GoalReward(rng.uniform(-3, 3, 2), obstacles=obstacles, robot_radius=0.2)
    model = IntervalModel(system, system.theta, reward, controllers, substeps=substeps)
    state = model.initial_state(rng.uniform(-1, 0, 4), rng.uniform(0, 0.5, 4), time=2)
    plan = [int(a) for a in rng.integers(0, 3, size=decisions)]
    horizon = decisions * substeps
    first = model.first_possible_collision(state, plan, horizon)
    lower, upper, _, terminals = model.rollout(state, plan)
    if first == horizon + 1:
        assert not terminals.any()
    else:
        assert 1 <= first <= horizon
        assert int(np.argmax(terminals)) == (first - 1) // substeps and terminals.any()
        _, collided = reward.box_minimum(lower[first], upper[first], 2 + first)
        assert bool(collided)
        for k in range(1, first):
            assert not bool(reward.box_minimum(lower[k], upper[k], 2 + k)[1])
    # the last action held: the same figure as the plan padded by hand, over a longer horizon
    padded = plan + [plan[-1]] * 2
    assert model.first_possible_collision(state, plan, horizon + 2 * substeps) == model.first_possible_collision(
        state, padded, horizon + 2 * substeps
    )
    # a shorter horizon cuts the figure
    assert model.first_possible_collision(state, plan, 1) == min(first, 2)


def _crowded_case(seed):
    rng = np.random.default_rng(seed)
    system = robot_system()
    obstacles = CircularObstacles(rng.uniform(-2.5, 2.5, (12, 2)), rng.uniform(0.2, 0.5, 12))
    reward = GoalReward(rng.uniform(-3, 3, 2), obstacles=obstacles, robot_radius=0.3)
    boxes = [Box([0.2, 0.2], [0.5, 0.5]), Box([0.4, 0.3], [0.8, 0.6])]
    planner = multi_model_robust_planner([(system, b) for b in boxes], reward, ROBOT_ACTIONS, budget=30, substeps=3)
    lo = np.concatenate([rng.uniform(-0.3, 0.3, 2), rng.uniform(-2, 2, 2)])
    root = planner.models[0].initial_state(lo, lo + 0.05)
    return planner, root, planner.plan(root)


@settings(max_examples=25, deadline=None)
@given(seeds, st.integers(1, 15))
def test_property_the_rule_executes_a_first_action_clear_longest_under_every_model(seed, horizon):
    """Two linked hypotheses among random discs: a plan's figure is the earliest over the models; the executed
    action's figure is the largest; the tree's action is kept when its best sequence stays clear or its
    figure is the largest; otherwise the largest tree lower bound among the largest figures."""
    planner, root, decision = _crowded_case(seed)
    models = planner.models
    action, latest = latest_collision_action(models, root, decision, horizon=horizon)

    def figure(plan):
        return min(m.first_possible_collision(root, plan, horizon) for m in models)

    sequence = tuple(decision.sequence_indices)
    if latest is None:
        assert figure(sequence) == horizon + 1 and action == decision.action_index
        return
    assert figure(sequence) <= horizon
    for first in range(len(ROBOT_ACTIONS)):
        examined = [(first, held) for held in range(len(ROBOT_ACTIONS))] + ([sequence] if sequence[0] == first else [])
        assert latest[first] == max(figure(plan) for plan in examined)
    assert latest[action] == max(latest)
    assert (action == decision.action_index) == (latest[decision.action_index] == max(latest))
    if action != decision.action_index:
        best = [a for a in range(len(latest)) if latest[a] == max(latest)]
        assert decision.action_lower[action] == max(decision.action_lower[a] for a in best)


def test_when_every_action_may_collide_at_once_the_tie_goes_to_the_one_clear_longest():
    """Among 12 discs (seed 36) every first action may collide within the first decision: the tree's lower
    bounds all tie at 0 and the tree takes action 0, whose plans may collide at sub-step 2; actions 1-3
    stay clear one sub-step longer, and the rule executes the first of them."""
    planner, root, decision = _crowded_case(36)
    assert list(decision.action_lower) == [0.0] * 4 and decision.action_index == 0
    action, latest = latest_collision_action(planner.models, root, decision, horizon=9)
    assert latest == [2, 3, 3, 3] and action == 1


def test_first_possible_collision_rejects_bad_plans_and_horizons():
    planner, root, _ = _crowded_case(0)
    model = planner.models[0]
    with pytest.raises(InputError, match="at least one action"):
        model.first_possible_collision(root, [], 5)
    with pytest.raises(InputError, match="controller indices"):
        model.first_possible_collision(root, [7], 5)
    with pytest.raises(InputError, match="horizon"):
        model.first_possible_collision(root, [0], 0)
    with pytest.raises(InputError, match="share their actions"):
        other = IntervalModel(
            robot_system(), Box([0.2, 0.2], [0.5, 0.5]), GoalReward([1.0, 1.0]), ROBOT_ACTIONS[:2], substeps=3
        )
        latest_collision_action([model, other], root, planner.plan(root), horizon=5)
    # a decision of a planner over other actions: its root bounds would be read for the wrong actions
    two = multi_model_robust_planner(
        [(robot_system(), Box([0.2, 0.2], [0.5, 0.5]))], GoalReward([1.0, 1.0]), ROBOT_ACTIONS[:2], budget=5, substeps=3
    )
    with pytest.raises(InputError, match=r"decision has 2 root actions .* n_actions = 4"):
        latest_collision_action(
            planner.models, root, two.plan(two.models[0].initial_state(root.lower, root.upper)), horizon=5
        )
