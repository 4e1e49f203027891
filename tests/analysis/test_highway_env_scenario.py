"""highway-env's scenarios and methods (the ``vehicle`` extra: these tests fail, not skip, when CI=true)."""

import os
import warnings

import numpy as np
import pytest


def _require_highway_env():
    """highway_env, or a skip outside CI (a failure in CI, where the extra is installed)."""
    if os.environ.get("CI") == "true":
        import highway_env

        return highway_env
    return pytest.importorskip("highway_env")


highway_env = _require_highway_env()

from minimaxplan.analysis.episode import LoopConfig, make_job, run_job  # noqa: E402
from minimaxplan.analysis.highway_env_scenario import (  # noqa: E402
    HIGHWAY_ENV_SCENARIOS,
    HighwayEnvNominalMethod,
    HighwayEnvRobustMethod,
    HighwayEnvScenario,
    HighwayEnvWorld,
    simulate_ego,
)
from minimaxplan.analysis.registry import (  # noqa: E402
    GroundTruthWorld,
    UnsupportedScenario,
    method_factory,
    resolve,
    scenario_names,
)
from minimaxplan.analysis.road_scenario import RoadScenario  # noqa: E402
from minimaxplan.models import InputError  # noqa: E402


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # gymnasium: "intersection-v0 is out of date"
        yield


def test_scenarios_are_registered_with_robust_nominal_and_oracle():
    assert set(HIGHWAY_ENV_SCENARIOS) <= set(scenario_names())
    scenario = HighwayEnvScenario("highway-fast-v0")
    from minimaxplan.analysis.highway_env_scenario import HighwayEnvOracleMethod

    expected = {"robust": HighwayEnvRobustMethod, "nominal": HighwayEnvNominalMethod, "oracle": HighwayEnvOracleMethod}
    for method, cls in expected.items():
        assert resolve(method_factory(method, scenario, LoopConfig())) is cls
    for baseline in ("dwa", "teb"):  # the road worlds' baselines drive RoadWorlds only
        with pytest.raises(UnsupportedScenario):
            method_factory(baseline, scenario, LoopConfig())
    with pytest.raises(UnsupportedScenario):
        HighwayEnvRobustMethod(RoadScenario("highway"), LoopConfig())
    with pytest.raises(InputError, match="env_id"):
        HighwayEnvScenario("merge-v0")
    with pytest.raises(InputError, match="measured exactly"):
        scenario.make_world(0, LoopConfig(measurement="gaussian"))


def test_world_steps_highway_env_one_simulation_step_at_a_time():
    world = HighwayEnvWorld("highway-fast-v0", 0)
    assert isinstance(world, GroundTruthWorld)
    assert world.substeps == 5 and world.adapter.dt == 0.2
    truth = world.true_states()
    observation = world.measure()
    assert set(truth) == {"ego"} | {f"vehicle {int(i)}" for i in observation.ids}
    np.testing.assert_array_equal(truth["ego"], observation.ego)
    idle = [a[0] for a in world.actions].index("IDLE")
    assert world.apply(np.array([idle])) == "running"
    assert world.time == pytest.approx(0.2) and world.step_index == 1
    assert 0.0 <= world.reward() <= 1.0
    with pytest.raises(InputError, match="action index"):
        world.apply(np.array([len(world.actions)]))


@pytest.mark.parametrize("env_id", ["highway-fast-v0", "intersection-v0"])
def test_simulated_ego_is_highway_envs_ego_bit_for_bit(env_id):
    world = HighwayEnvWorld(env_id, 2)
    base = world.adapter.env.unwrapped
    names = [a[0] for a in world.actions]
    sequence = ["FASTER", "SLOWER"] if env_id == "intersection-v0" else ["LANE_LEFT", "FASTER"]
    swap = {"LANE_LEFT": "LANE_RIGHT", "LANE_RIGHT": "LANE_LEFT"}
    predicted = simulate_ego(
        base.vehicle, base.road.network, [swap.get(n, n) for n in sequence], world.substeps, world.adapter.dt
    )
    states = [world.state]
    for name in sequence:
        for k in range(world.substeps):
            world.apply(np.array([names.index(name if k == 0 else "IDLE")]))
            states.append(world.state)
            if world.done:
                break
        if world.done:
            break
    assert not base.vehicle.crashed
    np.testing.assert_array_equal(predicted[: len(states)], np.array(states))


def test_robust_method_runs_with_the_runtime_check():
    config = LoopConfig(max_decisions=3)
    record = run_job(make_job("highway-env:highway-fast-v0", "robust", 1, config))
    assert record.decisions == 3 or record.outcome != "horizon"
    check = record.extra["runtime_check"]
    assert check["by_kind"]["ego"]["checked"] == 5 * record.decisions
    assert check["by_kind"]["vehicle"]["checked"] > 0
    if record.outcome != "collision":  # the ego's prediction is exact away from a crash impulse
        assert check["by_kind"]["ego"]["missed"] == 0
    assert record.boxes_checked == sum(k["checked"] for k in check["by_kind"].values())
    assert len(record.extra["decisions"]) == record.decisions


def test_nominal_method_predicts_nothing_to_check():
    record = run_job(make_job("highway-env:intersection-v0", "nominal", 0, LoopConfig(max_decisions=2)))
    assert record.decisions == 2 and record.boxes_checked == 0
    assert [d["action"] for d in record.extra["decisions"]][0] in ("SLOWER", "IDLE", "FASTER")


def test_oracle_method_searches_highway_envs_true_future():
    from minimaxplan.analysis.highway_env_scenario import HighwayEnvOracleMethod

    scenario = HighwayEnvScenario("intersection-v0")
    world = scenario.make_world(0, LoopConfig())
    method = HighwayEnvOracleMethod(scenario, LoopConfig())
    method.start(world)
    before = world.true_states()
    observation = world.measure()
    steps = world.adapter.steps(5.0)
    forecast = method.forecast(observation, None, None, None)
    assert forecast.boxes.shape == (steps + 1, len(observation.ids), 4)
    np.testing.assert_array_equal(forecast.state_lower[0], observation.vehicles)
    for name, state in world.true_states().items():  # the copy leaves the episode untouched
        np.testing.assert_array_equal(state, before[name])
    policy = method.decide(observation)
    assert not hasattr(policy, "predicted_boxes")


def test_nominal_forecast_takes_a_reversing_vehicle():
    """highway-env lets a braking vehicle's speed go below 0 (MIN_SPEED = -40 m/s)."""
    import dataclasses

    scenario = HighwayEnvScenario("intersection-v0")
    world = scenario.make_world(0, LoopConfig())
    method = HighwayEnvNominalMethod(scenario, LoopConfig())
    method.start(world)
    observation = world.measure()
    vehicles = observation.vehicles.copy()
    vehicles[:, 2] = -0.3
    steps = world.adapter.steps(5.0)
    empty = np.tile([np.inf, np.inf, -np.inf, -np.inf], (steps + 1, 1))
    forecast = method.forecast(dataclasses.replace(observation, vehicles=vehicles), empty, None, None)
    assert forecast.boxes.shape == (steps + 1, len(observation.ids), 4)
