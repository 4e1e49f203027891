"""The model protocols the planners dispatch on, the frozen `IntervalModel`, and the read-only tree view."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from minimaxplan.models.errors import InputError
from minimaxplan.planners import OpenLoop, PointModel, RobustTreePlanner
from minimaxplan.planners.interval_model import IntervalGroup, IntervalModel
from minimaxplan.planners.protocols import (
    BatchedTransitions,
    CompiledTransitions,
    LinkedModel,
    TransitionModel,
    VectorisedModel,
)
from minimaxplan.scenarios.rewards import GoalReward

from ._systems import random_controllers, random_system
from .test_hot_paths import TREE_FIELDS


class Table:
    """Rewards indexed by the action path (the state), often tied."""

    def __init__(self, seed: int) -> None:
        self.seed = seed

    def reward(self, path: tuple) -> float:
        return float(np.random.default_rng([self.seed, len(path), *path]).integers(0, 3)) / 2

    def step(self, state, action):
        return state + (action,), self.reward(state + (action,))


class TableGroup:
    """M `Table`s sharing the state: a `BatchedTransitions` that counts its calls."""

    def __init__(self, seeds) -> None:
        self.tables = [Table(seed) for seed in seeds]
        self.calls = 0

    @property
    def size(self) -> int:
        return len(self.tables)

    def expand_all(self, state, actions):
        self.calls += 1
        paths = [state + (a,) for a in actions]
        rewards = np.array([[table.reward(path) for path in paths] for table in self.tables])
        return paths, rewards, np.zeros(rewards.shape, dtype=bool)


class Member:
    """Member m of a `TableGroup` (a `LinkedModel`); stepping it alone is an error here."""

    def __init__(self, group: TableGroup, member: int) -> None:
        self.group, self.member = group, member

    def step(self, state, action):
        raise AssertionError("the planner must take the group's batched transitions")


def test_the_library_models_declare_their_protocols():
    rng = np.random.default_rng(1)
    system = random_system(rng, p=4)
    controllers = [OpenLoop(np.zeros(system.ninputs))] * 2
    models = IntervalModel.linked([(system, None)] * 3, GoalReward([0.0, 0.0]), controllers)
    for m, model in enumerate(models):
        assert isinstance(model, TransitionModel) and isinstance(model, VectorisedModel)
        assert isinstance(model, LinkedModel) and model.group is models[0].group and model.member == m
    assert isinstance(models[0].group, CompiledTransitions) and isinstance(models[0].group, BatchedTransitions)
    point = PointModel(system, system.theta.center, GoalReward([0.0, 0.0]), controllers)
    assert isinstance(point, VectorisedModel) and not isinstance(point, LinkedModel)
    assert not isinstance(Table(0), VectorisedModel) and isinstance(Table(0), TransitionModel)


def test_a_batched_group_of_the_protocol_is_used_and_builds_the_per_model_tree():
    seeds = [3, 4, 5]
    group = TableGroup(seeds)
    linked = RobustTreePlanner([Member(group, m) for m in range(3)], range(3), gamma=0.8, budget=30)
    separate = RobustTreePlanner([Table(seed) for seed in seeds], range(3), gamma=0.8, budget=30)
    assert linked.plan(()) == separate.plan(())
    assert group.calls == 30  # one batched call per expansion, never a member's step
    for name in TREE_FIELDS:
        assert np.array_equal(getattr(linked.tree, name), getattr(separate.tree, name)), name
    assert linked.tree.states == separate.tree.states


def test_members_out_of_order_are_stepped_one_by_one():
    group = TableGroup([3, 4])
    members = [Member(group, 1), Member(group, 0)]
    planner = RobustTreePlanner(members, range(2), gamma=0.8, budget=3)
    with pytest.raises(AssertionError, match="the planner must take the group's batched transitions"):
        planner.plan(())
    assert group.calls == 0


def test_interval_model_is_a_frozen_value_sharing_its_group():
    rng = np.random.default_rng(2)
    system = random_system(rng, p=4)
    reward = GoalReward([0.0, 0.0])
    controllers = random_controllers(rng, system)
    alone = IntervalModel(system, None, reward, controllers, substeps=2)
    assert isinstance(alone.group, IntervalGroup) and alone.group.size == 1 and alone.member == 0
    assert alone.parameters is system.theta and alone.controllers == tuple(controllers) and alone.substeps == 2
    with pytest.raises(dataclasses.FrozenInstanceError):
        alone.substeps = 3
    models = IntervalModel.linked([(system, None), (system, system.theta)], reward, controllers)
    assert models[0].group is models[1].group and [m.member for m in models] == [0, 1]
    group = models[0].group
    with pytest.raises(InputError, match="member must be an integer in \\[0, 2\\), got 2"):
        IntervalModel(system, None, reward, controllers, group=group, member=2)
    with pytest.raises(InputError, match="system, reward and substeps must be those of the group's member 0"):
        IntervalModel(system, None, GoalReward([1.0, 0.0]), controllers, group=group)
    with pytest.raises(InputError, match="controllers must be the group's controllers"):
        IntervalModel(system, None, reward, controllers[:1], group=group)
    with pytest.raises(InputError, match="group must be an IntervalGroup"):
        IntervalModel(system, None, reward, controllers, group=object())


@pytest.mark.parametrize("engine", ["compiled", "python"])
def test_a_tree_handed_out_is_read_only_and_survives_the_next_plan(engine):
    rng = np.random.default_rng(4)
    system = random_system(rng, p=4)
    models = IntervalModel.linked([(system, None)] * 2, GoalReward([0.0, 0.0]), random_controllers(rng, system))
    planner = RobustTreePlanner(models, models[0].actions, gamma=0.9, budget=20, engine=engine)
    first_root = models[0].initial_state(np.full(4, -0.1), np.full(4, 0.1))
    decision = planner.plan(first_root)
    tree = planner.tree
    with pytest.raises(ValueError, match="read-only"):
        tree.lower[0] = 0.0
    kept = [getattr(tree, name).copy() for name in TREE_FIELDS]
    planner.plan(models[0].initial_state(np.full(4, 1.0), np.full(4, 1.2)))
    assert planner.tree is not tree
    assert all(np.array_equal(getattr(tree, name), value) for name, value in zip(TREE_FIELDS, kept))
    assert planner.plan(first_root) == decision


def test_the_python_engines_tree_grows_past_its_first_arrays():
    """Budgets whose tree exceeds the first allocation (1024 rows) grow it; the smaller tree is a prefix."""
    model = Table(7)
    big = RobustTreePlanner([model], range(2), gamma=0.95, budget=1500)
    small = RobustTreePlanner([model], range(2), gamma=0.95, budget=400)
    big_decision, small_decision = big.plan(()), small.plan(())
    assert big.tree.size == 3001 and big_decision.expansions == 1500
    n = small.tree.size
    for name in TREE_FIELDS:
        if name not in ("lower", "upper", "first_child", "expanded"):
            assert np.array_equal(getattr(big.tree, name)[:n], getattr(small.tree, name)), name
    assert np.array_equal(big.tree.expanded[:400], small.tree.expanded)
    assert small_decision.lower <= big_decision.lower <= big_decision.upper <= small_decision.upper
