"""The road scenarios behind the registry, their World adapter, plots, and the road baselines."""

import dataclasses

import numpy as np
import pytest

import minimaxplan.analysis.road_methods  # noqa: F401 (registers dwa and teb for the road scenarios)
from minimaxplan.analysis.episode import DEFAULT_CONFIG, LoopConfig, run_episode
from minimaxplan.analysis.experiment import summarise
from minimaxplan.analysis.registry import UnsupportedScenario, World, method_factory, scenario_names
from minimaxplan.analysis.road_methods import RoadDWAMethod, RoadTEBMethod
from minimaxplan.analysis.road_scenario import DrivingWorld, RoadFrame, RoadScenario, road_trajectory_figure
from minimaxplan.analysis.robot_methods import DWAMethod, TEBMethod
from minimaxplan.analysis.robot_scenario import RobotScenario
from minimaxplan.models import InputError
from minimaxplan.scenarios.road import highway_road, tjunction_road
from minimaxplan.scenarios.road_world import ROAD_OUTCOMES, Observation

SHORT = LoopConfig(max_decisions=4)


def test_both_road_scenarios_are_registered_and_make_driving_worlds():
    assert {"highway", "tjunction"} <= set(scenario_names())
    for kind in ("highway", "tjunction"):
        world = RoadScenario(kind).make_world(3, DEFAULT_CONFIG)
        assert isinstance(world, DrivingWorld) and isinstance(world, World)
        assert world.substeps == 5 and world.outcome == "running" and not world.done and world.time == 0.0
        observation = world.measure()
        assert isinstance(observation, Observation) and observation.vehicles.shape[1] == 4
        assert world.position.shape == (2,) and world.state.shape == (4,)
        assert 0.0 <= world.reward() <= 1.0
    with pytest.raises(InputError, match="uniform"):
        RoadScenario("highway").make_world(0, LoopConfig(measurement="gaussian"))
    with pytest.raises(InputError, match="kind"):
        RoadScenario("roundabout")


def test_each_method_name_resolves_to_the_factory_of_its_world():
    config = DEFAULT_CONFIG
    assert method_factory("dwa", RoadScenario("highway"), config) is RoadDWAMethod
    assert method_factory("teb", RoadScenario("tjunction"), config) is RoadTEBMethod
    assert method_factory("dwa", RobotScenario("static"), config) is DWAMethod
    assert method_factory("teb", RobotScenario("pedestrian"), config) is TEBMethod
    with pytest.raises(UnsupportedScenario):
        RoadDWAMethod(RobotScenario("static"), config)
    with pytest.raises(UnsupportedScenario):
        DWAMethod(RoadScenario("highway"), config)


def test_the_lane_frame_measures_progress_offset_and_heading():
    road = highway_road()
    frame = RoadFrame(road, range(3), np.zeros(3))
    progress, offset, heading = frame(np.array([[100.0, 0.5], [250.0, 7.0], [10.0, 5.9]]))
    np.testing.assert_allclose(progress, [100.0, 250.0, 10.0])
    np.testing.assert_allclose(offset, [0.5, -1.0, 1.9])
    np.testing.assert_allclose(heading, 0.0)
    junction = tjunction_road()
    route = [junction.index(name) for name in ("south_in", "south_west", "west_out")]
    offsets = np.concatenate([[0.0], np.cumsum(junction.lengths[route[:-1]])])
    frame = RoadFrame(junction, route, offsets)
    quarter = np.pi / 2 * 13.0
    progress, offset, heading = frame(np.array([[2.0, -50.0], [-20.0, 2.0]]))
    np.testing.assert_allclose(progress, [61.0, 100.0 + quarter + 9.0])
    np.testing.assert_allclose(offset, [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(heading, [np.pi / 2, np.pi])


@pytest.mark.parametrize("kind", ["highway", "tjunction"])
@pytest.mark.parametrize("method", ["dwa", "teb"])
def test_a_short_episode_of_each_baseline_ends_with_a_valid_outcome(kind, method):
    record = run_episode(kind, method, 10_001, SHORT)
    assert record.outcome in set(ROAD_OUTCOMES) | {"horizon"}
    assert 1 <= record.decisions <= 4 and 0.0 <= record.discounted_return <= sum(0.9**i for i in range(4))
    world = record.extra["world"]
    assert world["kind"] == kind and world["traffic_paths"] and world["traffic_collisions"] == []
    assert record.extra["planner"]  # the frozen parameters travel with the record
    assert np.shape(record.trajectory)[1] == 2 and np.shape(record.trace["states"])[1] == 4


def test_the_same_seed_gives_the_same_summary():
    def summary():
        records = [run_episode(kind, "dwa", 10_002, SHORT) for kind in ("highway", "tjunction")]
        return [{k: v for k, v in s.items()} for s in summarise(records)], [r.trajectory for r in records]

    first, second = summary(), summary()
    assert first == second


def test_a_dwa_highway_episode_reaches_the_goal():
    record = run_episode("highway", "dwa", 10_000)
    assert record.outcome == "goal" and record.time_s < 15.0
    assert record.discounted_return > 0


def test_the_road_figure_draws_lanes_paths_and_a_legend():
    records = [run_episode("tjunction", method, 10_003, SHORT) for method in ("dwa", "teb")]
    failed = dataclasses.replace(records[0], outcome="collision")
    fig = road_trajectory_figure([failed, records[1]], title="test")
    ax = fig.axes[0]
    gids = [line.get_gid() for line in ax.lines]
    assert gids.count("lane edge") == 2 * len(tjunction_road()) and "vehicle path" in gids and "failure" in gids
    assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert {"dwa", "teb", "lane edges", "collision / off road"} <= set(labels)
