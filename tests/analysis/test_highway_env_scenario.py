"""highway-env's scenarios and methods (the ``vehicle`` extra: these tests fail, not skip, when CI=true)."""

import warnings

import numpy as np
import pytest
from extras import require_extra
from hypothesis import given, settings
from hypothesis import strategies as st

highway_env = require_extra("highway_env")

from minimaxplan.analysis.episode import LoopConfig, make_job, run_job  # noqa: E402
from minimaxplan.analysis.highway_env_scenario import (  # noqa: E402
    EXTENDED_TARGET_SPEEDS,
    HIGHWAY_ENV_SCENARIOS,
    HighwayEnvNominalMethod,
    HighwayEnvRobustMethod,
    HighwayEnvScenario,
    HighwayEnvWorld,
    normalised_reward,
    simulate_ego,
)
from minimaxplan.analysis.registry import (  # noqa: E402
    GroundTruthWorld,
    UnsupportedScenario,
    method_factory,
    resolve,
    scenario_factory,
    scenario_names,
)
from minimaxplan.analysis.road_scenario import RoadScenario  # noqa: E402
from minimaxplan.models import DimensionError, InputError  # noqa: E402


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # gymnasium: "intersection-v0 is out of date"
        yield


def test_scenarios_are_registered_with_robust_nominal_oracle_and_idm():
    assert set(HIGHWAY_ENV_SCENARIOS) <= set(scenario_names())
    scenario = HighwayEnvScenario("highway-fast-v0")
    from minimaxplan.analysis.highway_env_scenario import HighwayEnvIDMMethod, HighwayEnvOracleMethod

    expected = {
        "robust": HighwayEnvRobustMethod,
        "nominal": HighwayEnvNominalMethod,
        "oracle": HighwayEnvOracleMethod,
        "idm": HighwayEnvIDMMethod,
    }
    for method, cls in expected.items():
        assert resolve(method_factory(method, scenario, LoopConfig())) is cls
    for baseline in ("dwa", "teb"):  # the road worlds' baselines drive RoadWorlds only
        with pytest.raises(UnsupportedScenario):
            method_factory(baseline, scenario, LoopConfig())
    with pytest.raises(UnsupportedScenario):
        HighwayEnvRobustMethod(RoadScenario("highway"), LoopConfig())
    with pytest.raises(UnsupportedScenario):
        HighwayEnvIDMMethod(RoadScenario("highway"), LoopConfig())
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
def test_normalised_reward_is_highway_envs_own_reward_of_the_egos_state(env_id):
    # the search's reward of a predicted state is highway-env's reward of that state, while the
    # ego is on the road, has not crashed or arrived, and keeps its lane (no target lane ahead)
    world = HighwayEnvWorld(env_id, 1)
    names = [a[0] for a in world.actions]
    config = world.adapter.env.unwrapped.config
    width = float(world.adapter.road.widths[0])
    compared = 0
    for k in range(3 * world.substeps):
        action = (
            names.index("FASTER" if k < world.substeps else "SLOWER")
            if k % world.substeps == 0
            else names.index("IDLE")
        )
        if world.apply(np.array([action])) != "running":
            break
        ours = normalised_reward(config, world.state[None, :], highway="highway" in env_id, lane_width=width)
        assert ours.shape == (1,)
        assert ours[0] == world.reward(), (k, ours, world.reward())
        compared += 1
    assert compared >= 2 * world.substeps


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


def test_lane_keeping_sequences_and_the_substeps_they_keep():
    from minimaxplan.analysis.highway_env_scenario import kept_substeps, lane_keeping_sequences

    names = ["SLOWER", "LANE_LEFT", "IDLE", "LANE_RIGHT", "FASTER"]
    sequences = np.array([[0, 2], [4, 0], [0, 1], [1, 0], [3, 3], [2, 3]])
    np.testing.assert_array_equal(lane_keeping_sequences(sequences, names), [True, True, False, False, False, False])
    # all-keeping: the whole horizon (the IDLE tail keeps the lane); else the leading keeping decisions
    np.testing.assert_array_equal(kept_substeps(sequences, names, 5, 25), [25, 25, 5, 0, 0, 5])


def test_latest_clear_sequence_keeps_the_best_clear_plan_else_delays_the_first_possible_collision():
    from minimaxplan.analysis.highway_env_scenario import latest_clear_sequence
    from minimaxplan.models import DimensionError

    def alive(*clear, steps=6):
        return np.arange(steps)[None, :] < np.array(clear)[:, None]

    values = np.array([0.9, 0.5, 0.7, 0.2])
    # some sequences clear over the whole horizon: the best-valued of them (not the best overall)
    assert latest_clear_sequence(alive(3, 6, 6, 2), values) == 2
    # none clear: the longest clear wins over a higher value that may collide sooner
    assert latest_clear_sequence(alive(3, 4, 2, 4), values) == 1
    # ties in the first possible collision: the value decides, then the first index
    assert latest_clear_sequence(alive(4, 4, 4, 1), values) == 0
    assert latest_clear_sequence(alive(2, 2), np.array([0.3, 0.3])) == 0
    # with speeds and nothing clear: the slowest at the latest first possible collision, then the value
    speeds = np.tile(np.array([[20.0], [25.0], [17.0], [19.0]]), (1, 6))  # sequence 2 is slowest but collides sooner
    assert latest_clear_sequence(alive(4, 4, 2, 4), values, speeds=speeds) == 3
    speeds[1, 4] = 18.0  # read at sub-step 4, the candidates' first possible collision
    assert latest_clear_sequence(alive(4, 4, 2, 4), values, speeds=speeds) == 1
    # with a clear sequence the speeds change nothing
    assert latest_clear_sequence(alive(3, 6, 6, 2), values, speeds=speeds) == 2
    with pytest.raises(DimensionError, match="speeds"):
        latest_clear_sequence(alive(3, 4, 2, 4), values, speeds=speeds[:, :3])
    with pytest.raises(DimensionError, match="values"):
        latest_clear_sequence(alive(3, 4), values)
    with pytest.raises(DimensionError, match="alive"):
        latest_clear_sequence(np.ones(4, dtype=bool), values)


def test_sequence_reach_is_the_union_of_the_rectangles_rounded_outward():
    from minimaxplan.analysis.highway_env_scenario import sequence_reach
    from minimaxplan.models import DimensionError
    from minimaxplan.scenarios.vehicles import DEFAULT_VEHICLE, vehicle_corners

    trajectories = np.array(
        [[[0.0, 0.0, 20.0, 0.0], [4.0, 0.0, 20.0, 0.0]], [[0.0, 0.0, 20.0, 0.0], [5.0, 1.0, 25.0, 0.1]]]
    )
    boxes, reach, speed, heading = sequence_reach(trajectories, DEFAULT_VEHICLE)
    corners = vehicle_corners(trajectories, DEFAULT_VEHICLE)
    np.testing.assert_array_equal(boxes[..., :2], corners.min(axis=-2))
    assert np.all(reach[:, :2] < boxes[..., :2].min(axis=0)) and np.all(reach[:, 2:] > boxes[..., 2:].max(axis=0))
    np.testing.assert_array_equal(reach[1, :2], np.nextafter(boxes[:, 1, :2].min(axis=0), -np.inf))
    assert speed[1, 0] < 20.0 < 25.0 < speed[1, 1] and heading[1, 0] < 0.0 < 0.1 < heading[1, 1]
    with pytest.raises(DimensionError, match="trajectories"):
        sequence_reach(trajectories[0], DEFAULT_VEHICLE)


def _fixed_forecast(forecast, box):
    """``forecast`` with every vehicle's box at every sub-step after 0 replaced by ``box``."""
    import dataclasses

    boxes = np.array(forecast.boxes)
    boxes[1:] = box
    return dataclasses.replace(forecast, boxes=boxes)


def test_robust_method_values_lane_keeping_paths_against_the_lane_keeping_forecast():
    """On the highway two forecasts: the general one from the reach of every sequence, the lane-keeping
    one from the reach of the SLOWER/IDLE/FASTER sequences. A path reads the second while it keeps its
    lane, the first after; the run-time check holds the boxes of the forecast that valued the
    executed decision."""
    from minimaxplan.analysis.highway_env_scenario import lane_keeping_sequences, sequence_reach

    scenario = HighwayEnvScenario("highway-fast-v0")
    config = LoopConfig()
    world = scenario.make_world(3, config)
    method = HighwayEnvRobustMethod(scenario, config)
    method.start(world)
    observation = world.measure()
    calls = []
    inner = method.forecast

    def forecast(obs, reach, speed, heading):
        real = inner(obs, reach, speed, heading)
        calls.append((reach, real))
        # the general forecast: a vehicle's box over the whole road (every path hits it at sub-step 1);
        # the lane-keeping one: its real boxes far away (no path keeping its lane hits it)
        if len(calls) == 1:
            return _fixed_forecast(real, [-1e6, -1e6, 1e6, 1e6])
        return _fixed_forecast(real, [1e6, 1e6, 1e6 + 1.0, 1e6 + 1.0])

    method.forecast = forecast
    policy = method.decide(observation)
    assert len(calls) == 2
    names = [a[0] for a in world.actions]
    S = world.substeps
    keeping = lane_keeping_sequences(method.sequences, names)
    assert 0 < keeping.sum() < len(keeping)
    # the second forecast read the exact reach of the lane-keeping sequences only
    base = world.adapter.env.unwrapped
    swap = {"LANE_LEFT": "LANE_RIGHT", "LANE_RIGHT": "LANE_LEFT"}
    steps = world.adapter.steps(5.0)
    keep_trajectories = np.stack(
        [
            simulate_ego(
                base.vehicle, base.road.network, [swap.get(names[k], names[k]) for k in seq] + ["IDLE"] * 3, S, 0.2
            )[: steps + 1]
            for seq in method.sequences[keeping]
        ]
    )
    np.testing.assert_array_equal(calls[1][0], sequence_reach(keep_trajectories, world.adapter.scenario.vehicle)[1])
    assert not np.array_equal(calls[0][0], calls[1][0])
    decision = method.decisions[-1]
    assert decision["lane_keeping"] is True and decision["safe_sequences"] == keeping.sum()
    assert decision["action"] in ("SLOWER", "IDLE", "FASTER")
    # the run-time check reads the lane-keeping forecast's state boxes (the real ones, from the second call)
    real_keep = calls[1][1]
    for j, agent in enumerate(real_keep.ids):
        lo, hi = policy.predicted_boxes(1)[f"vehicle {int(agent)}"]
        np.testing.assert_array_equal(lo, real_keep.state_lower[1, j])
        np.testing.assert_array_equal(hi, real_keep.state_upper[1, j])


def test_robust_method_values_lane_changes_against_the_general_forecast():
    """A sequence that changes lane reads the general forecast from its lane change on: with the
    lane-keeping forecast hitting every path and the general one none, only sequences that change
    lane at the first decision escape, and the check holds the general forecast's boxes."""
    scenario = HighwayEnvScenario("highway-fast-v0")
    config = LoopConfig()
    world = scenario.make_world(3, config)
    method = HighwayEnvRobustMethod(scenario, config)
    method.start(world)
    calls = []
    inner = method.forecast

    def forecast(obs, reach, speed, heading):
        real = inner(obs, reach, speed, heading)
        calls.append(real)
        if len(calls) == 1:
            return _fixed_forecast(real, [1e6, 1e6, 1e6 + 1.0, 1e6 + 1.0])
        return _fixed_forecast(real, [-1e6, -1e6, 1e6, 1e6])

    method.forecast = forecast
    policy = method.decide(world.measure())
    names = [a[0] for a in world.actions]
    decision = method.decisions[-1]
    first = method.sequences[:, 0]
    changes_first = np.array([names[k] in ("LANE_LEFT", "LANE_RIGHT") for k in first])
    assert decision["safe_sequences"] == changes_first.sum() > 0
    assert decision["action"] in ("LANE_LEFT", "LANE_RIGHT") and decision["lane_keeping"] is False
    general = calls[0]
    for j, agent in enumerate(general.ids):
        lo, _ = policy.predicted_boxes(world.substeps)[f"vehicle {int(agent)}"]
        np.testing.assert_array_equal(lo, general.state_lower[world.substeps, j])


def test_robust_method_forecasts_once_at_the_intersection():
    """Every intersection action keeps the lane: one forecast, as before."""
    scenario = HighwayEnvScenario("intersection-v0")
    world = scenario.make_world(0, LoopConfig())
    method = HighwayEnvRobustMethod(scenario, LoopConfig())
    method.start(world)
    calls = []
    inner = method.forecast
    method.forecast = lambda *args: calls.append(1) or inner(*args)
    method.decide(world.measure())
    assert len(calls) == 1 and method.decisions[-1]["lane_keeping"] is False


def test_lane_keeping_forecast_contains_highway_envs_vehicles_along_a_lane_keeping_path():
    """Containment of the lane-keeping forecast on a highway-env scene, the ego keeping its lane (IDLE)
    over the whole horizon, in the cases the model covers (no lane change in progress, no crash, no
    change of target lane: highway-env's ground truth read here, in the test only)."""
    total = {"inside": 0, "outside": 0, "excluded": 0}
    for seed in (0, 5):
        scenario = HighwayEnvScenario("highway-fast-v0")
        world = scenario.make_world(seed, LoopConfig())
        method = HighwayEnvRobustMethod(scenario, LoopConfig())
        method.start(world)
        captured = []
        inner = method.forecast
        method.forecast = lambda *args, out=captured, f=inner: out.append(f(*args)) or out[-1]
        method.decide(world.measure())
        assert len(captured) == 2
        keep = captured[1]
        base = world.adapter.env.unwrapped
        vehicles = {world.adapter.agent_id(v): v for v in base.road.vehicles if v is not base.vehicle}
        first = {a: (v.lane_index, v.target_lane_index) for a, v in vehicles.items()}
        idle = [a[0] for a in world.actions].index("IDLE")
        excluded: set[int] = set()
        for n in range(1, keep.steps + 1):
            world.apply(np.array([idle]))
            if world.done:
                break
            for j, agent in enumerate(keep.ids):
                v = vehicles[int(agent)]
                if v not in base.road.vehicles:
                    excluded.add(int(agent))
                lane, target = first[int(agent)]
                if v.crashed or v.target_lane_index != target or v.lane_index != lane or lane != target:
                    excluded.add(int(agent))
                if int(agent) in excluded:
                    total["excluded"] += 1
                    continue
                state = np.array([v.position[0], v.position[1], v.speed, v.heading])
                inside = np.all(keep.state_lower[n, j] <= state) and np.all(state <= keep.state_upper[n, j])
                total["inside" if inside else "outside"] += 1
    assert total["outside"] == 0 and total["inside"] > 500, total


def _fact(
    lane=("0", "1", 1),
    target=None,
    speed=20.0,
    crashed=False,
    curved=False,
    centre=(0.0, 4.0),
    position=(0.0, 4.0),
    front_heading=None,
    front_connected=None,
):
    return {
        "crashed": crashed,
        "lane": list(lane),
        "target": list(target or lane),
        "target_centre": list(centre),
        "position": list(position),
        "heading": 0.0,
        "speed": speed,
        "curved": curved,
        "front_heading": front_heading,
        "front_connected": front_connected,
    }


def test_miss_classifier_on_a_small_case(benchmark_script):
    """benchmarks/highway_env_misses.py: each miss gets the first kind that applies from the step before
    the decision's start to the missed sub-step."""
    misses = benchmark_script("highway_env_misses")
    classify = misses.classify_miss
    box = {"lower": [-1.0, 3.0, 0.0, -0.1], "upper": [1.0, 5.0, 30.0, 0.1]}  # reaches (0, 4), not (0, 8)

    def miss(substep, name="vehicle 1"):
        return {"name": name, "substep": substep, **box}

    plain = [{"vehicle 1": _fact()} for _ in range(8)]
    assert classify(miss(2), plain, 3) == "unexplained"
    assert classify(miss(2, "vehicle 9"), plain, 3) == "unexplained"  # no facts at all
    crashed = [dict(f) for f in plain]
    crashed[5] = {"vehicle 1": _fact(crashed=True, speed=-1.0)}
    assert classify(miss(2), crashed, 3) == "crash"  # crash first
    assert classify(miss(1), crashed, 3) == "unexplained"  # the crash is after the miss
    reversing = [dict(f) for f in plain]
    reversing[4] = {"vehicle 1": _fact(speed=-0.1)}
    assert classify(miss(2), reversing, 3) == "reversing"
    changing = [dict(f) for f in plain]
    changing[2] = {"vehicle 1": _fact(target=("0", "1", 2), centre=(0.0, 8.0))}  # the step before the start
    changing[3] = changing[4] = changing[5] = changing[2]
    assert classify(miss(2), changing, 3) == "lane change ruled out"
    aborted = [dict(f) for f in plain]  # MOBIL sets the target back while changing
    aborted[4] = {"vehicle 1": _fact(target=("0", "1", 0), centre=(0.0, 0.0))}
    assert classify(miss(2), aborted, 3) == "lane change aborted"
    towards = [dict(f) for f in plain]
    towards[5] = {"vehicle 1": _fact(target=("0", "1", 0), centre=(0.0, 4.0))}
    assert classify(miss(2), towards, 3) == "lane change allowed"
    cut_in = [dict(f) for f in plain]  # vehicle 2, 30 m ahead, changes into vehicle 1's lane
    cut_in[4] = {"vehicle 1": _fact(), "vehicle 2": _fact(lane=("0", "1", 2), target=("0", "1", 1), position=(30, 6))}
    assert classify(miss(2), cut_in, 3) == "a leader's lane change"
    behind = [dict(f) for f in plain]  # behind it, or the ego: not a leader the forecast missed
    behind[4] = {
        "vehicle 1": _fact(),
        "vehicle 2": _fact(lane=("0", "1", 2), target=("0", "1", 1), position=(-30, 6)),
        "ego": _fact(lane=("0", "1", 2), target=("0", "1", 1), position=(30, 6)),
    }
    assert classify(miss(2), behind, 3) == "unexplained"
    switching = [dict(f) for f in plain]
    switching[4] = switching[5] = {"vehicle 1": _fact(target=("1", "2", 1))}
    assert classify(miss(2), switching, 3) == "route lane switch"
    ahead_of_lane = [{"vehicle 1": _fact(lane=("0", "1", 0), target=("1", "2", 0))} for _ in range(8)]
    assert classify(miss(2), ahead_of_lane, 3) == "route lane switch"  # switched before the window
    unseen = [dict(f) for f in plain]  # no front vehicle on its lane, one on a connected lane
    unseen[4] = {"vehicle 1": _fact(front_connected=True, front_heading=None)}
    assert classify(miss(2), unseen, 3) == "next-lane leader unseen"
    seen_too = [dict(f) for f in plain]  # a front vehicle found on its own lane too: not unseen
    seen_too[4] = {"vehicle 1": _fact(front_connected=True, front_heading=0.0)}
    assert classify(miss(2), seen_too, 3) == "unexplained"
    crossing = [dict(f) for f in plain]  # its highway-env leader crosses at right angles
    crossing[4] = {"vehicle 1": _fact(front_heading=np.pi / 2, curved=True)}
    assert classify(miss(2), crossing, 3) == "crossing leader"
    following = [dict(f) for f in plain]  # a leader in the same direction is no crossing one
    following[4] = {"vehicle 1": _fact(front_heading=0.1)}
    assert classify(miss(2), following, 3) == "unexplained"
    wrapped = [dict(f) for f in plain]  # headings compared modulo 2 pi
    wrapped[4] = {"vehicle 1": _fact(front_heading=2 * np.pi + 0.05)}
    assert classify(miss(2), wrapped, 3) == "unexplained"
    curved = [dict(f) for f in plain]
    curved[5] = {"vehicle 1": _fact(curved=True)}
    assert classify(miss(2), curved, 3) == "curved lane"
    summary = misses.summarise(
        [
            {
                "scenario": "s",
                "seed": 0,
                "boxes_checked": 10,
                "boxes_missed": 3,
                "recorded": 3,
                "misses": [{"kind": "crash"}, {"kind": "crash"}, {"kind": "unexplained", "name": "vehicle 1"}],
            }
        ]
    )["s"]
    assert summary["kinds"] == {"crash": {"misses": 2, "episodes": 1}, "unexplained": {"misses": 1, "episodes": 1}}
    assert summary["unexplained"] == [{"seed": 0, "kind": "unexplained", "name": "vehicle 1"}]


def test_highway_env_worlds_declare_the_trace_protocol():
    from minimaxplan.analysis.registry import CrowdedWorld, TracedWorld

    world = HighwayEnvScenario("highway-fast-v0").make_world(0, LoopConfig())
    assert isinstance(world, TracedWorld) and not isinstance(world, CrowdedWorld)
    assert world.state.shape == (4,) and world.params.dt == world.adapter.dt


def test_idm_method_hands_the_ego_to_highway_envs_idm_vehicle():
    """The reference ego: highway-env's IDMVehicle replaces the controlled vehicle at reset and drives itself
    (IDMVehicle.act ignores the action); the episode is reproducible; the hand-over is refused mid-episode."""
    from minimaxplan.analysis.highway_env_scenario import HighwayEnvIDMMethod

    scenario = HighwayEnvScenario("highway-fast-v0")
    world = scenario.make_world(3, LoopConfig())
    before = world.state
    method = HighwayEnvIDMMethod(scenario, LoopConfig())
    method.start(world)
    base = world.adapter.env.unwrapped
    assert type(base.vehicle) is highway_env.vehicle.behavior.IDMVehicle
    assert base.vehicle in base.road.vehicles and base.vehicle is base.action_type.controlled_vehicle
    np.testing.assert_array_equal(world.state, before)
    assert world.adapter.agent_id(base.vehicle) == 0 and 0 not in world.measure().ids
    world.apply(np.array([0.0]))
    with pytest.raises(InputError, match="only at the start"):
        world.drive_ego_by_idm()
    record = run_job(make_job("highway-env:highway-fast-v0", "idm", 3, LoopConfig(max_decisions=3)))
    again = run_job(make_job("highway-env:highway-fast-v0", "idm", 3, LoopConfig(max_decisions=3)))
    assert record.decisions == 3 and record.boxes_checked == 0 and record.trajectory == again.trajectory
    assert record.extra["ego"].startswith("highway-env IDMVehicle")


@pytest.mark.parametrize("seed", [0, 2, 4])
def test_the_committed_idm_records_re_run_exactly(seed):
    """The idm rows of benchmarks/results/experiments/highway-env (a collision, a goal, a timeout at the
    intersection) come back the same from a fresh run: outcome, time and return."""
    import csv
    import pathlib

    path = pathlib.Path(__file__).parents[2] / "benchmarks/results/experiments/highway-env/episodes.csv"
    with path.open(newline="") as handle:
        (row,) = [
            r
            for r in csv.DictReader(handle)
            if (r["scenario"], r["method"], r["seed"]) == ("highway-env:intersection-v0", "idm", str(seed))
        ]
    record = run_job(make_job("highway-env:intersection-v0", "idm", seed, LoopConfig()))
    assert record.outcome == row["outcome"] and record.decisions == int(row["decisions"])
    assert record.time_s == float(row["time_s"]) and record.discounted_return == float(row["discounted_return"])


@settings(max_examples=200, deadline=None)
@given(
    clear=st.lists(st.integers(1, 8), min_size=1, max_size=12),
    data=st.data(),
)
def test_latest_clear_sequence_against_brute_force(clear, data):
    """The rule, by enumeration: with a sequence clear over the horizon, the best-valued clear one; otherwise
    among the clear longest (and, with speeds, the slowest at that sub-step) the best-valued, first on ties."""
    from minimaxplan.analysis.highway_env_scenario import latest_clear_sequence

    steps = 8
    n = len(clear)
    alive = np.arange(steps)[None, :] < np.array(clear)[:, None]
    values = np.array(data.draw(st.lists(st.sampled_from([0.1, 0.5, 0.9]), min_size=n, max_size=n)))
    speeds = np.array(
        data.draw(
            st.lists(
                st.lists(st.sampled_from([18.0, 20.0, 25.0]), min_size=steps, max_size=steps), min_size=n, max_size=n
            )
        )
    )
    longest = max(clear)
    pool = [i for i in range(n) if clear[i] == longest]
    plain = max(pool, key=lambda i: (values[i], -i))
    assert latest_clear_sequence(alive, values) == plain
    if longest < steps:
        slowest = min(speeds[i, longest] for i in pool)
        pool = [i for i in pool if speeds[i, longest] == slowest]
    assert latest_clear_sequence(alive, values, speeds=speeds) == max(pool, key=lambda i: (values[i], -i))


def test_latest_clear_sequence_rejects_rows_that_clear_again_and_non_finite_inputs():
    from minimaxplan.analysis.highway_env_scenario import latest_clear_sequence

    alive = np.array([[True, False, True], [True, True, False]])
    with pytest.raises(InputError, match="nonincreasing"):
        latest_clear_sequence(alive, np.array([0.5, 0.5]))
    alive = np.array([[True, False, False], [True, True, False]])
    with pytest.raises(InputError, match="values must be finite"):
        latest_clear_sequence(alive, np.array([np.nan, 0.5]))
    with pytest.raises(InputError, match="speeds must be finite"):
        latest_clear_sequence(alive, np.array([0.5, 0.5]), speeds=np.full((2, 3), np.nan))


def test_stall_trace_tells_a_follower_from_other_traffic(benchmark_script):
    """benchmarks/trace_highway_env_stalls.py: a follower is behind the ego, in its lane, heading its way."""
    follower = benchmark_script("trace_highway_env_stalls")._follower
    ego = np.array([2.0, 30.0, 5.0, -np.pi / 2])  # heading south (-y)
    assert follower(ego, np.array([2.0, 45.0, 8.0, -np.pi / 2]))  # behind, same lane
    assert follower(ego, np.array([3.5, 45.0, 8.0, -np.pi / 2 + 0.2]))
    assert not follower(ego, np.array([2.0, 20.0, 8.0, -np.pi / 2]))  # ahead
    assert not follower(ego, np.array([-2.0, 45.0, 8.0, -np.pi / 2]))  # the lane beside
    assert not follower(ego, np.array([-2.0, 45.0, 8.0, np.pi / 2]))  # oncoming
    assert not follower(ego, np.array([2.0, 45.0, 8.0, 0.0]))  # crossing


def test_stall_trace_counts_every_decision_and_restores_the_method(benchmark_script):
    """The trace of one episode attributes each decision once (free or blocked, with at least one kind),
    and the patched functions are restored afterwards."""
    module = benchmark_script("trace_highway_env_stalls")
    from minimaxplan.analysis import highway_env_scenario as hes

    def patched():
        return (
            hes.sequence_reach,
            hes.HighwayEnvRobustMethod.forecast,
            hes._SearchMethod.decide,
            hes.HighwayEnvRobustMethod.observe,
            hes.HighwayEnvRobustMethod._beliefs,
        )

    before = patched()
    outcome, counts, lines = module.trace(2)
    assert patched() == before
    assert outcome in ("goal", "timeout", "collision")
    assert counts["free"] + counts["blocked"] == len(lines) > 0
    kinds = sum(v for k, v in counts.items() if k.startswith("blocked: "))
    assert counts["blocked"] <= kinds  # every blocked decision names at least one kind of box
    assert all(("blocked at" in line) == (" free " not in line) for line in lines)


def test_stall_trace_true_routes_cut_each_prior_to_the_vehicles_own_route(benchmark_script):
    """`--true-routes` (a privileged diagnosis) keeps, of each vehicle's prior, the routes that end where
    its highway-env route ends and the lanes on that route; nothing it keeps is outside the prior."""
    import types

    module = benchmark_script("trace_highway_env_stalls")
    world = HighwayEnvWorld("intersection-v0", 2)
    idle = np.array([[a[0] for a in world.actions].index("IDLE")])
    for _ in range(2 * world.substeps):  # let vehicles enter the junction
        world.apply(idle)
    adapter = world.adapter
    observation = world.measure()
    cut = module._true_route_beliefs(types.SimpleNamespace(world=world), observation)
    base = adapter.env.unwrapped
    vehicles = {adapter.agent_id(v): v for v in base.road.vehicles if v is not base.vehicle}
    narrowed = 0
    for agent, state in zip(np.asarray(observation.ids).tolist(), observation.vehicles):
        prior, belief = adapter.prior(agent, state), cut[agent]
        assert set(belief.routes) <= set(prior.routes) and set(belief.lanes) <= set(prior.lanes)
        route = [adapter.lane_index[(a, b, 0 if i is None else i)] for a, b, i in (vehicles[agent].route or [])]
        if belief.routes != prior.routes:
            assert route and all(r[-1] == route[-1] for r in belief.routes)
            narrowed += 1
    assert narrowed > 0  # at the intersection a prior holds several routes; the cut keeps the true one's


def test_stall_trace_lane_history_keeps_neighbours_and_measures_heading_errors(benchmark_script):
    """`--lane-history` keeps a lane, its successors and its predecessors, nothing else; the heading
    error of a state against a lane is 0 along it and pi against it."""
    from minimaxplan.scenarios.road import Road, StraightLane

    module = benchmark_script("trace_highway_env_stalls")
    # 0 -> 1 -> 2 in a row, and 3 apart, all straight, 10 m long, heading +x
    lanes = tuple(StraightLane((x, y), (x + 10.0, y)) for x, y in ((0.0, 0.0), (10.0, 0.0), (20.0, 0.0), (0.0, 20.0)))
    road = Road(lanes, ("a", "b", "c", "d"), connections=((0, 1), (1, 2)))
    assert module._neighbour_lanes(road, {1}) == {0, 1, 2}
    assert module._neighbour_lanes(road, {0}) == {0, 1}
    assert module._neighbour_lanes(road, {3}) == {3}
    assert module._largest_heading_error(road, [0], np.array([5.0, 0.0, 5.0, 0.0])) == pytest.approx(0.0)
    assert module._largest_heading_error(road, [0, 3], np.array([5.0, 0.0, 5.0, np.pi])) == pytest.approx(np.pi)


def _targets_under_slower(world, decisions: int) -> list[float]:
    """The ego's target speed now and after each of ``decisions`` decisions that brake (SLOWER, then IDLE)."""
    names = [action[0] for action in world.actions]
    ego = world.adapter.env.unwrapped.vehicle
    targets = [float(ego.target_speeds[ego.speed_index])]
    for _ in range(decisions):
        for k in range(world.substeps):
            world.apply(np.array([names.index("SLOWER" if k == 0 else "IDLE")]))
        ego = world.adapter.env.unwrapped.vehicle
        targets.append(float(ego.target_speeds[ego.speed_index]))
    return targets


def test_extended_target_speeds_let_slower_brake_below_highway_envs_floor():
    """The registered variant configures the ego's target speeds (0-30 m/s) and keeps the action type's
    other settings; SLOWER then steps the target below 20 m/s, which highway-fast-v0's own cannot."""
    scenario = resolve(scenario_factory("highway-env:highway-fast-v0-speeds-0-30"))()
    assert isinstance(scenario, HighwayEnvScenario) and scenario.target_speeds == EXTENDED_TARGET_SPEEDS
    world = scenario.make_world(3, LoopConfig())
    np.testing.assert_array_equal(world.adapter.env.unwrapped.vehicle.target_speeds, EXTENDED_TARGET_SPEEDS)
    assert world.to_dict()["target_speeds"] == list(EXTENDED_TARGET_SPEEDS)
    assert _targets_under_slower(world, 3) == [25.0, 20.0, 15.0, 10.0]
    default = HighwayEnvWorld("highway-fast-v0", 3)
    assert default.to_dict()["target_speeds"] == [20.0, 25.0, 30.0]
    assert _targets_under_slower(default, 3) == [25.0, 20.0, 20.0, 20.0]
    # the intersection's action type is longitudinal only: configuring its speeds keeps that
    crossing = HighwayEnvWorld("intersection-v0", 3, target_speeds=(0.0, 3.0, 6.0, 9.0))
    action = crossing.adapter.env.unwrapped.config["action"]
    assert action["longitudinal"] and not action["lateral"] and action["target_speeds"] == [0.0, 3.0, 6.0, 9.0]
    np.testing.assert_array_equal(crossing.adapter.env.unwrapped.vehicle.target_speeds, [0.0, 3.0, 6.0, 9.0])


@pytest.mark.parametrize(
    "speeds, error, match",
    [
        ([20.0], DimensionError, r"at least two values, got shape \(1,\)"),
        ([[0.0, 5.0]], DimensionError, r"got shape \(1, 2\)"),
        ([0.0, float("nan")], InputError, "finite and non-negative"),
        ([-5.0, 5.0], InputError, "finite and non-negative"),
        ([0.0, 10.0, 10.0], InputError, "increase strictly"),
        ([30.0, 20.0], InputError, "increase strictly"),
    ],
)
def test_target_speeds_are_refused_with_a_typed_error_naming_them(speeds, error, match):
    with pytest.raises(error, match=match):
        HighwayEnvScenario("highway-fast-v0", target_speeds=speeds)
    with pytest.raises(error, match="target_speeds"):
        HighwayEnvWorld("highway-fast-v0", 0, target_speeds=speeds)


@pytest.mark.slow
def test_seed_21_collides_at_the_20_m_s_floor_and_reaches_the_goal_with_lower_targets(replay_records):
    """The committed robust records of highway-fast-v0's seed 21 (a collision at 20 m/s, SLOWER at every
    one of its last decisions) and of the same seed with the extended target speeds (the goal) come back
    the same from a fresh run: the only difference between the two episodes is the action set."""
    import csv
    import pathlib

    results = pathlib.Path(__file__).parents[2] / "benchmarks/results/experiments"
    committed = {}
    for folder in ("highway-env", "highway-env-speeds-0-30"):
        with (results / folder / "episodes.csv").open(newline="") as handle:
            committed.update({(r["scenario"], r["method"], r["seed"]): r for r in csv.DictReader(handle)})
    names = ["highway-env:highway-fast-v0", "highway-env:highway-fast-v0-speeds-0-30"]
    rows, environment = replay_records(names, ["robust"], 21)
    assert environment["matches_records"], environment
    outcomes = {}
    for got in rows:
        want = committed[(got["scenario"], got["method"], got["seed"])]
        mismatches = {k: (got.get(k), want[k]) for k in want if k != "wall_time_s" and got.get(k) != want[k]}
        assert not mismatches, f"{got['scenario']}: {mismatches}"
        outcomes[got["scenario"]] = got["outcome"]
    assert outcomes == dict(zip(names, ["collision", "goal"]))
