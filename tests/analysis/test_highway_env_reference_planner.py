"""The reference planner of benchmarks/highway_env_reference_planner.py (the ``vehicle`` extra: these
tests fail, not skip, when CI=true)."""

import copy
import warnings

import numpy as np
import pytest
from extras import require_extra

highway_env = require_extra("highway_env")

from highway_env.vehicle.uncertainty.prediction import IntervalVehicle  # noqa: E402

from minimaxplan.scenarios.driving_reward import DrivingReward  # noqa: E402
from minimaxplan.scenarios.highway_env_adapter import HighwayEnvAdapter, meta_action  # noqa: E402


@pytest.fixture(scope="module")
def reference(benchmark_script):
    """``benchmarks/highway_env_reference_planner.py``, loaded once."""
    return benchmark_script("highway_env_reference_planner")


ACTIONS = ("SLOWER", "IDLE", "LANE_LEFT", "LANE_RIGHT", "FASTER")


@pytest.fixture
def scene():
    warnings.simplefilter("ignore")
    adapter = HighwayEnvAdapter("highway-fast-v0")
    adapter.reset(0)
    reward = DrivingReward.highway(np.zeros((1, 0, 4)), 0, adapter.road)
    yield adapter, reward
    adapter.close()


def _snapshot(env):
    return [
        (type(v).__name__, v.position.copy(), float(v.speed), float(v.heading), bool(v.crashed))
        + ((v.interval.position.copy(),) if isinstance(v, IntervalVehicle) else ())
        for v in env.road.vehicles
    ]


def _same(a, b):
    return len(a) == len(b) and all(
        x[0] == y[0] and all(np.array_equal(np.asarray(p), np.asarray(q)) for p, q in zip(x[1:], y[1:]))
        for x, y in zip(a, b)
    )


def test_interval_root_replaces_the_other_vehicles_and_puts_the_ego_last(scene, reference):
    adapter, _ = scene
    base = adapter.env.unwrapped
    before = _snapshot(base)
    root = reference.interval_root(adapter.env)
    assert root.road.vehicles[-1] is root.vehicle
    assert not isinstance(root.vehicle, IntervalVehicle)
    others = root.road.vehicles[:-1]
    assert others and all(isinstance(v, IntervalVehicle) for v in others)
    assert root.config["policy_frequency"] == 1
    # the environment it copies is untouched: still LinearVehicles, the ego first, same states
    assert _same(_snapshot(base), before)
    assert not any(isinstance(v, IntervalVehicle) for v in base.road.vehicles)


def test_reference_planner_at_budget_3_expands_3_nodes_and_returns_a_valid_action(scene, reference):
    adapter, reward = scene
    root = reference.interval_root(adapter.env)
    metas = [meta_action(adapter.env, name) for name in ACTIONS]
    planner = reference.HighwayEnvReferencePlanner(
        metas, reference.driving_reward_of(reward), gamma=0.9, budget=3, horizon_decisions=5
    )
    decision = planner.plan(root)
    assert 0 <= decision.action < len(ACTIONS)
    assert not decision.solved
    assert decision.expansions == 3
    assert planner.expanded_nodes() == 3
    assert decision.env_steps == 3 * len(ACTIONS)
    # the root action is the one of largest lower bound, and the root's bounds are its children's
    lowers = [child.lower for child in planner.root.children]
    assert decision.action == int(np.argmax(lowers))
    assert decision.lower == max(lowers)
    assert decision.lower <= decision.upper <= 1 / (1 - 0.9)


def test_reference_copies_are_independent(scene, reference):
    adapter, reward = scene
    root = reference.interval_root(adapter.env)
    metas = [meta_action(adapter.env, name) for name in ACTIONS]
    planner = reference.HighwayEnvReferencePlanner(
        metas, reference.driving_reward_of(reward), gamma=0.9, budget=3, horizon_decisions=5
    )
    before = _snapshot(root)
    planner.plan(root)
    # planning stepped copies only: the root environment is unchanged
    assert _same(_snapshot(root), before)
    assert root.steps == adapter.env.unwrapped.steps
    child = next(c for c in planner.root.children if c.children)
    grandchild = child.children[0]
    assert child.env is not root and grandchild.env is not child.env
    assert child.env.steps == root.steps + 5 and grandchild.env.steps == child.env.steps + 5
    assert not np.array_equal(child.env.vehicle.position, root.vehicle.position)
    # stepping a child does not change its parent
    parent_before = _snapshot(child.env)
    copy.deepcopy(grandchild.env)  # copying is not stepping either
    grandchild.env.step(metas[1])
    assert _same(_snapshot(child.env), parent_before)


def test_depth_rule_and_crash_reward(scene, reference):
    adapter, reward = scene
    root = reference.interval_root(adapter.env)
    metas = [meta_action(adapter.env, name) for name in ACTIONS]
    value = reference.driving_reward_of(reward)
    planner = reference.HighwayEnvReferencePlanner(metas, value, gamma=0.9, budget=3, horizon_decisions=1)
    decision = planner.plan(root)
    # beyond one decision every transition is 0 and terminal, without stepping a copy
    assert decision.env_steps == len(ACTIONS)
    deeper = [c for child in planner.root.children for c in child.children]
    assert deeper and all(c.terminal and c.env is None and c.ret == c.parent.ret for c in deeper)
    crashed = copy.deepcopy(root)
    free, terminal = value(crashed)
    assert not terminal and 0 < free <= 1
    crashed.vehicle.crashed = True
    assert value(crashed) == (0.0, True)


def test_the_reference_method_plans_from_the_episodes_environment_and_holds_its_action(benchmark_script):
    # the reference as a controller (benchmarks/highway_env_reference_episodes.py): one decision
    # from the episode's environment, the root action at the first simulation step, IDLE after
    from minimaxplan.analysis.episode import LoopConfig
    from minimaxplan.analysis.highway_env_scenario import HighwayEnvScenario, normalised_reward
    from minimaxplan.analysis.registry import UnsupportedScenario
    from minimaxplan.analysis.road_scenario import RoadScenario

    episodes = benchmark_script("highway_env_reference_episodes")
    warnings.simplefilter("ignore")
    scenario = HighwayEnvScenario("highway-fast-v0")
    with pytest.raises(UnsupportedScenario):
        episodes.HighwayEnvReferenceMethod(RoadScenario("highway"), LoopConfig())
    method = episodes.HighwayEnvReferenceMethod(scenario, LoopConfig(), budget=2)
    world = scenario.make_world(0, LoopConfig())
    try:
        method.start(world)
        before = _snapshot(world.adapter.env.unwrapped)
        policy = method.decide(world.measure())
        assert _same(_snapshot(world.adapter.env.unwrapped), before)  # planning stepped copies only
        (decision,) = method.report()["decisions"]
        assert decision["expansions"] <= 2 and decision["env_steps"] <= 2 * len(world.actions)
        chosen = [a[0] for a in world.actions].index(decision["action"])
        controls = [int(policy.control(None)[0]) for _ in range(world.substeps)]
        assert controls == [chosen] + [[a[0] for a in world.actions].index("IDLE")] * (world.substeps - 1)
        # its transition value is the search's reward of the copy's ego state, 0 and terminal on a crash
        twin = episodes.reference.interval_root(world.adapter.env)
        ego = twin.vehicle
        state = np.array([[ego.position[0], ego.position[1], ego.speed, ego.heading]])
        config = world.adapter.env.unwrapped.config
        width = float(world.adapter.road.widths[0])
        assert method.value(twin) == (float(normalised_reward(config, state, highway=True, lane_width=width)[0]), False)
        twin.vehicle.crashed = True
        assert method.value(twin) == (0.0, True)
    finally:
        world.adapter.close()


def test_a_committed_reference_record_re_runs_exactly(benchmark_script, registries_restored):
    """Seed 46 of the highway's second reference run (benchmarks/results/experiments/
    highway-env-reference-seeds-20-49: a collision at 2.2 s after 3 decisions) comes back the same
    from a fresh run: outcome, time, return, and every decision's action and bounds."""
    import csv
    import functools
    import json
    import pathlib

    from minimaxplan.analysis import registry
    from minimaxplan.analysis.episode import LoopConfig, make_job, run_job

    records = pathlib.Path(__file__).parents[2] / "benchmarks/results/experiments/highway-env-reference-seeds-20-49"
    with (records / "episodes.csv").open(newline="") as handle:
        (row,) = [r for r in csv.DictReader(handle) if r["seed"] == "46"]
    (trees,) = [d for d in json.loads((records / "decisions.json").read_text()) if d["seed"] == 46]
    episodes = benchmark_script("highway_env_reference_episodes")
    warnings.simplefilter("ignore")
    with registries_restored():
        registry.register_method("reference", functools.partial(episodes.HighwayEnvReferenceMethod, budget=35))
        record = run_job(make_job("highway-env:highway-fast-v0", "reference", 46, LoopConfig()))
    assert row["outcome"] == "collision"
    assert record.outcome == row["outcome"] and record.decisions == int(row["decisions"])
    assert record.time_s == float(row["time_s"]) and record.discounted_return == float(row["discounted_return"])
    replayed = [{k: v for k, v in d.items() if k != "cpu_s"} for d in record.extra["decisions"]]
    assert replayed == [{k: v for k, v in d.items() if k != "cpu_s"} for d in trees["decisions"]]
