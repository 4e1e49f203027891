"""``minimaxplan sweep``: the crowd and density worlds, the summary's intervals, the outputs, and every bad option."""

from __future__ import annotations

import csv
import json
import pathlib
import re

import numpy as np
import pytest
from scipy import stats

from minimaxplan.analysis.episode import DEFAULT_CONFIG, EpisodeRecord
from minimaxplan.analysis.sweep import (
    HEADING_MARGIN,
    SWEEP_WORLDS,
    CrowdScenarioFactory,
    RoadDensityFactory,
    cell_name,
    make_crowd_world,
    road_density_scenario,
    run_sweep,
    summarise_sweep,
    sweep_markdown,
)
from minimaxplan.models import DimensionError, InputError
from minimaxplan.scenarios import RobotWorld, make_world
from minimaxplan.scenarios.road_world import HighwayScenario, TJunctionScenario
from minimaxplan.scenarios.worlds import PedestrianCrowd, crossing_crowd

COMMITTED = pathlib.Path(__file__).resolve().parents[2] / "benchmarks" / "results" / "experiments" / "sweep"


def small_sweep(run_cli, out, *argv) -> tuple[int, str, str]:
    """``minimaxplan sweep ARGV`` in this process, without a progress bar, writing to ``out``."""
    return run_cli("sweep", *argv, "--workers", "1", "--no-progress", "--out", out)


# ------------------------------------------------------------------ the worlds
@pytest.mark.parametrize(("count", "bound"), [(0, 0.3), (1, 0.1), (5, 0.3), (8, 0.6)])
def test_a_crowd_world_is_the_pedestrian_world_with_the_cells_crowd(count, bound):
    world = make_crowd_world(7, pedestrians=count, velocity_uncertainty=bound)
    paper = make_world("pedestrian", 7)
    np.testing.assert_array_equal(world.start, paper.start)
    np.testing.assert_array_equal(world.goal, paper.goal)
    np.testing.assert_array_equal(world.true_theta, paper.true_theta)
    np.testing.assert_array_equal(world.obstacles.centers, paper.obstacles.centers)
    assert len(world.crowd) == count == len(world.pedestrians.radii)
    assert np.all(np.asarray(world.pedestrians.velocity_uncertainty) == bound)
    assert len(world.to_dict()["pedestrians"]["positions"]) == count
    # the true velocities stay inside the announced bound, however long the walk
    worst = 0.0
    for _ in range(2000):
        world.crowd.advance(world.params.dt)
        if count:
            worst = max(worst, float(np.max(np.abs(world.crowd.velocities - world.crowd.announced))))
    assert worst <= HEADING_MARGIN * bound + 1e-12
    if count:
        assert worst > 0.5 * HEADING_MARGIN * bound  # and the deviation is used, not left at 0


def test_at_the_paper_uncertainty_the_heading_walk_is_the_paper_worlds():
    world = make_crowd_world(3, pedestrians=2, velocity_uncertainty=0.3)
    assert world.crowd.max_deviation == pytest.approx(0.18) and world.crowd.deviation_step == pytest.approx(0.03)


def test_crowd_worlds_reject_bad_values():
    with pytest.raises(InputError, match="pedestrians"):
        make_crowd_world(0, pedestrians=-1, velocity_uncertainty=0.3)
    with pytest.raises(InputError, match="velocity_uncertainty"):
        make_crowd_world(0, pedestrians=1, velocity_uncertainty=-0.1)


def test_cells_have_registry_names_and_equal_factories():
    assert cell_name("pedestrian", 5, 0.3) == "pedestrian[5 ped +-0.3 m/s]"
    assert CrowdScenarioFactory(5, 0.3) == CrowdScenarioFactory(5, 0.3)
    scenario = CrowdScenarioFactory(5, 0.3)()
    assert scenario.kind == "pedestrian" and "pedestrians=5" in repr(scenario)


# ------------------------------------------------------------------ the summary
def record(method: str, outcome: str, time_s: float, seed: int) -> EpisodeRecord:
    return EpisodeRecord("cell", method, seed, outcome, time_s, 0.5, 10, 0.1)


def test_summary_intervals_are_clopper_pearson_and_student_t():
    times = [10.0, 12.0, 11.0, 15.0]
    records = [record("dwa", "goal", t, k) for k, t in enumerate(times)]
    records += [record("dwa", "collision", 3.0, 4), record("dwa", "timeout", 60.0, 5)]
    (row,) = summarise_sweep(records, {"cell": {"pedestrians": 3, "velocity_uncertainty": 0.6}})
    assert (row["pedestrians"], row["velocity_uncertainty"], row["method"]) == (3, 0.6, "dwa")
    assert (row["failures"], row["collisions"], row["timeouts"], row["successes"]) == (2, 1, 1, 4)
    exact = stats.binomtest(2, 6).proportion_ci(confidence_level=0.95, method="exact")
    np.testing.assert_allclose(row["failure_ci95"], [exact.low, exact.high])
    half = stats.t.ppf(0.975, 3) * np.std(times, ddof=1) / 2
    np.testing.assert_allclose(row["time_ci95"], [np.mean(times) - half, np.mean(times) + half])
    assert row["mean_time_s"] == pytest.approx(12.0)
    one = summarise_sweep([record("teb", "goal", 9.0, 0)], {"cell": {"pedestrians": 1, "velocity_uncertainty": 0.1}})[0]
    assert np.isnan(one["time_ci95"][0]) and one["mean_time_s"] == 9.0
    text = sweep_markdown(
        {"grid": {"scenario": "pedestrian", "episodes": 1, "seed": 0}, "rows": [one], "wall_time_s": 1}
    )
    assert "| 1 | 0.1 | teb | 0/1 | [0.000, 0.975] | 0 | 0 | 9.0 | - |" in text


# ------------------------------------------------------------------ a real run
def test_a_small_pedestrian_sweep_writes_what_the_committed_sweep_holds(tmp_path, run_cli):
    """The generalised command writes the committed sweep's cells, columns and episodes, robust's
    (with the latest-collision rule and the run-time check) and DWA's."""
    out = tmp_path / "sweep"
    code, stdout, err = small_sweep(
        run_cli,
        out,
        "--pedestrians",
        "1,8",
        "--velocity-uncertainty",
        "0.6",
        "--methods",
        "robust,dwa",
        "--episodes",
        "2",
        "--seed",
        "6",
    )
    assert code == 0, err
    assert re.search(r"\| 8 \| 0\.6 \| dwa \| \d/2 \|", stdout) and "Wall time of the run:" in stdout
    assert (out / "sweep.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "sweep.md").read_text() in stdout
    # the table's header, the JSON's keys and the CSV's columns are the committed sweep's
    committed_md = (COMMITTED / "sweep.md").read_text().splitlines()
    assert (out / "sweep.md").read_text().splitlines()[2:4] == committed_md[2:4]
    document, committed = (
        json.loads((out / "sweep.json").read_text()),
        json.loads((COMMITTED / "sweep.json").read_text()),
    )
    assert list(document) == list(committed) and list(document["grid"]) == list(committed["grid"])
    assert document["grid"]["pedestrians"] == [1, 8] and len(document["rows"]) == 4
    assert [list(r) for r in document["rows"]] == [list(committed["rows"][0])] * 4
    for row in document["rows"]:
        if row["method"] == "dwa":  # DWA predicts no boxes
            assert row["boxes_missed"] is None and row["boxes_checked"] is None
        else:
            assert row["boxes_missed"] == 0 and row["boxes_checked"] > 0
    with open(out / "sweep.csv", newline="") as handle:
        ours = list(csv.DictReader(handle))
    with open(COMMITTED / "sweep.csv", newline="") as handle:
        reference = {(r["scenario"], r["method"], r["seed"]): r for r in csv.DictReader(handle)}
    assert len(ours) == 8 and list(ours[0]) == list(next(iter(reference.values())))
    # and the episodes themselves: every field but the wall time, to the digit (seed 7 of the 8-pedestrian
    # cell is the collision the latest-collision rule turned into a goal, seed 6 of the 1-pedestrian cell
    # one of the goals it changed)
    assert {r["scenario"] for r in ours} == {"pedestrian[1 ped +-0.6 m/s]", "pedestrian[8 ped +-0.6 m/s]"}
    for row in ours:
        expected = reference[(row["scenario"], row["method"], row["seed"])]
        assert {k: v for k, v in row.items() if k != "wall_time_s"} == {
            k: v for k, v in expected.items() if k != "wall_time_s"
        }
    seven = reference[("pedestrian[8 ped +-0.6 m/s]", "robust", "7")]
    assert (seven["outcome"], seven["time_s"]) == ("goal", "18.2")


def test_a_small_highway_sweep_writes_one_row_per_density_and_method(tmp_path, run_cli):
    out = tmp_path / "highway"
    code, stdout, err = small_sweep(
        run_cli, out, "--scenario", "highway", "--vehicles", "2,5", "--methods", "dwa,nominal", "--episodes", "1"
    )
    assert code == 0, err
    header = "| vehicles | method | failures / episodes | failure 95% CI | collisions | off road | timeouts |"
    assert header in stdout
    assert re.search(r"\| 5 \| nominal \| \d/1 \| \[", stdout)
    document = json.loads((out / "sweep.json").read_text())
    assert document["grid"] == {
        "scenario": "highway",
        "vehicles": [2, 5],
        "methods": ["dwa", "nominal"],
        "episodes": 1,
        "seed": 0,
    }
    rows = document["rows"]
    assert [(r["vehicles"], r["method"]) for r in rows] == [(2, "dwa"), (2, "nominal"), (5, "dwa"), (5, "nominal")]
    for r in rows:
        assert r["collisions"] + r["off_road"] + r["timeouts"] == r["failures"] == r["episodes"] - r["successes"]
        assert 0.0 <= r["failure_ci95"][0] <= r["failure_rate"] <= r["failure_ci95"][1] <= 1.0
    with open(out / "sweep.csv", newline="") as handle:
        episodes = list(csv.DictReader(handle))
    assert len(episodes) == 4 and list(episodes[0])[:4] == ["vehicles", "scenario", "method", "seed"]
    assert {(e["vehicles"], e["scenario"]) for e in episodes} == {
        ("2", "highway[2 vehicles]"),
        ("5", "highway[5 vehicles]"),
    }
    assert (out / "sweep.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_tjunction_sweep_is_the_same_for_the_same_seed():
    def summary():
        study = run_sweep(
            scenario="tjunction",
            arrival_rate=[300, 1200],
            methods=["dwa"],
            episodes=1,
            seed=3,
            workers=1,
            progress=False,
        )
        return study["rows"], [{k: v for k, v in r.items() if k != "wall_time_s"} for r in study["records"]]

    first = summary()
    assert [r["arrival_rate"] for r in first[0]] == [300.0, 1200.0]
    assert [r["scenario"] for r in first[1]] == ["tjunction[300 veh/h]", "tjunction[1200 veh/h]"]
    assert {r["seed"] for r in first[1]} == {3}
    assert summary() == first


@pytest.mark.parametrize(("scenario", "axis"), [("highway", {"vehicles": [2]}), ("tjunction", {"arrival_rate": [300]})])
def test_the_robust_method_runs_a_driving_cell_and_its_boxes_are_counted(scenario, axis):
    study = run_sweep(scenario=scenario, **axis, methods=["robust"], episodes=1, workers=1, progress=False)
    (row,) = study["rows"]
    (episode,) = study["records"]
    assert row["boxes_checked"] == episode["boxes_checked"] > 0
    assert row["boxes_missed"] == episode["boxes_missed"] == 0
    assert f"{row['boxes_checked']} predicted boxes checked against the true states, 0 missed" in sweep_markdown(study)


# ------------------------------------------------------------------ the density worlds
def test_densities_set_the_vehicle_count_and_the_arrival_rate():
    assert road_density_scenario("highway", 15) == HighwayScenario()  # the default world is a cell
    assert road_density_scenario("tjunction", 600.0) == TJunctionScenario()
    for rate in (300.0, 900.0, 1200.0):
        constants = road_density_scenario("tjunction", rate)
        assert constants.headway_min == 3.0
        assert 3600.0 / (constants.headway_min + constants.headway_mean_extra) == pytest.approx(rate)
    world = RoadDensityFactory("highway", 25)().make_world(4, DEFAULT_CONFIG).world
    assert world.scenario.vehicle_count == 25 and len(world.traffic) == 26  # the ego and 25 others
    assert RoadDensityFactory("highway", 25) == RoadDensityFactory("highway", 25)
    assert "density=25" in repr(RoadDensityFactory("highway", 25)())
    # denser traffic at the junction: more main-road arrivals in the episode
    sparse = RoadDensityFactory("tjunction", 300.0)().make_world(2, DEFAULT_CONFIG).world
    dense = RoadDensityFactory("tjunction", 1200.0)().make_world(2, DEFAULT_CONFIG).world
    assert len(dense.traffic) > len(sparse.traffic)
    assert (
        cell_name("highway", 10) == "highway[10 vehicles]" and cell_name("tjunction", 450.0) == "tjunction[450 veh/h]"
    )


def test_densities_out_of_range_are_refused():
    with pytest.raises(InputError, match=r"arrival_rate\[0\] must be > 0 and <= 1200 veh/h per direction"):
        road_density_scenario("tjunction", 1500.0)
    with pytest.raises(InputError, match=r"arrival_rate\[0\] must be > 0"):
        road_density_scenario("tjunction", 0.0)
    with pytest.raises(InputError, match=r"vehicles\[0\]"):
        road_density_scenario("highway", 2.5)
    with pytest.raises(InputError, match="kind"):
        road_density_scenario("pedestrian", 3)
    with pytest.raises(InputError, match="vehicles is an axis of the highway sweep, not of the tjunction sweep"):
        run_sweep(scenario="tjunction", vehicles=[5], methods=["dwa"], episodes=1, workers=1, progress=False)
    with pytest.raises(InputError, match="arrival_rate must not repeat"):
        run_sweep(
            scenario="tjunction", arrival_rate=[600, 600.0], methods=["dwa"], episodes=1, workers=1, progress=False
        )
    with pytest.raises(InputError, match="arrival_rate\\[1\\] must be a finite number"):
        run_sweep(scenario="tjunction", arrival_rate=[600, float("nan")], episodes=1, workers=1, progress=False)
    assert SWEEP_WORLDS["highway"].methods == ("robust", "nominal", "oracle", "dwa", "teb")


# ------------------------------------------------------------------ the public crowd constructor
def test_with_crowd_of_the_worlds_own_stream_is_the_pedestrian_world_bit_for_bit():
    seed = 11
    paper = make_world("pedestrian", seed)

    def own_crowd(start, goal):
        rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(5)[4])
        return crossing_crowd(rng, int(rng.integers(1, 4)), start, goal)

    world = RobotWorld.with_crowd("pedestrian", seed, own_crowd)
    assert world.velocity_uncertainty == paper.velocity_uncertainty == 0.3
    assert world.to_dict() == paper.to_dict()
    controls = np.random.default_rng(0).uniform(-1.0, 1.0, size=(60, 2))
    for u in controls:
        if paper.done:
            break
        assert world.apply(u) == paper.apply(u)
        np.testing.assert_array_equal(world.state, paper.state)
        np.testing.assert_array_equal(world.crowd.positions, paper.crowd.positions)
        assert world.reward() == paper.reward()
    np.testing.assert_array_equal(world.measure(), paper.measure())


def test_with_crowd_announces_its_uncertainty_and_takes_a_ready_crowd():
    paper = make_world("static", 2)
    crowd = crossing_crowd(np.random.default_rng(5), 2, paper.start, paper.goal)
    world = RobotWorld.with_crowd("static", 2, crowd, velocity_uncertainty=0.5)
    assert world.crowd is crowd and len(world.to_dict()["pedestrians"]["positions"]) == 2
    assert np.all(np.asarray(world.pedestrians.velocity_uncertainty) == 0.5)
    np.testing.assert_array_equal(world.obstacles.centers, paper.obstacles.centers)


def test_with_crowd_and_crossing_crowd_reject_bad_values():
    paper = make_world("pedestrian", 0)
    good = crossing_crowd(np.random.default_rng(1), 2, paper.start, paper.goal)
    with pytest.raises(InputError, match="crowd must be a PedestrianCrowd or a callable"):
        RobotWorld.with_crowd("pedestrian", 0, "three")
    with pytest.raises(InputError, match="crowd must be a PedestrianCrowd"):
        RobotWorld.with_crowd("pedestrian", 0, lambda start, goal: None)
    with pytest.raises(InputError, match="velocity_uncertainty"):
        RobotWorld.with_crowd("pedestrian", 0, good, velocity_uncertainty=-0.1)
    with pytest.raises(InputError, match="seed"):
        RobotWorld.with_crowd("pedestrian", -1, good)
    fields = dict(vars(good))
    with pytest.raises(DimensionError, match="crowd.speeds"):
        RobotWorld.with_crowd("pedestrian", 0, PedestrianCrowd(**{**fields, "speeds": np.ones(3)}))
    with pytest.raises(InputError, match="crowd.radii must be > 0"):
        RobotWorld.with_crowd("pedestrian", 0, PedestrianCrowd(**{**fields, "radii": np.zeros(2)}))
    turned = PedestrianCrowd(**{**fields, "deviations": np.full(2, 0.5)})  # velocities far from the announced ones
    with pytest.raises(InputError, match="beyond velocity_uncertainty=0.3 m/s"):
        RobotWorld.with_crowd("pedestrian", 0, turned)
    with pytest.raises(InputError, match="count"):
        crossing_crowd(np.random.default_rng(0), -1, paper.start, paper.goal)
    with pytest.raises(InputError, match="start and goal must differ"):
        crossing_crowd(np.random.default_rng(0), 1, paper.start, paper.start)
    with pytest.raises(DimensionError, match="goal"):
        crossing_crowd(np.random.default_rng(0), 1, paper.start, [1.0, 2.0, 3.0])
    with pytest.raises(InputError, match="rng"):
        crossing_crowd(0, 1, paper.start, paper.goal)


def test_cells_share_seeds_and_worlds_but_not_crowds():
    study = run_sweep(
        pedestrians=[1, 3], velocity_uncertainty=[0.3], methods=["dwa"], episodes=1, seed=5, workers=1, progress=False
    )
    assert [r["pedestrians"] for r in study["rows"]] == [1, 3]
    assert {r["seed"] for r in study["records"]} == {5}
    with pytest.raises(InputError, match="must not repeat"):
        run_sweep(pedestrians=[1, 1], methods=["dwa"], episodes=1, workers=1, progress=False)


# ------------------------------------------------------------------ bad options
@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--scenario", "static"],
            r"argument --scenario: the sweep varies the scenarios \['pedestrian', 'highway', 'tjunction'\]",
        ),
        (["--pedestrians", "-1"], r"argument --pedestrians: every value must be an integer >= 0"),
        (["--pedestrians", "1,x"], r"argument --pedestrians: expected comma-separated integers"),
        (["--pedestrians", "3,3"], r"argument --pedestrians: values must not repeat"),
        (["--velocity-uncertainty", "-0.1"], r"argument --velocity-uncertainty: every value must be a finite number"),
        (["--velocity-uncertainty", "nan"], r"argument --velocity-uncertainty: every value must be a finite number"),
        (["--velocity-uncertainty", "fast"], r"argument --velocity-uncertainty: expected comma-separated numbers"),
        (["--velocity-uncertainty", ""], r"argument --velocity-uncertainty: expected comma-separated numbers >= 0"),
        (["--velocity-uncertainty", "0.3,0.3"], r"argument --velocity-uncertainty: values must not repeat"),
        (["--methods", "robust,robust"], r"argument --methods: values must not repeat"),
        (["--methods", "sideways"], r"argument --methods: method must be one of the registered methods"),
        (["--episodes", "0"], r"argument --episodes: must be an integer >= 1"),
        (["--workers", "0"], r"argument --workers: must be an integer >= 1"),
        (["--scenario", "highway", "--vehicles", "-5"], r"argument --vehicles: every value must be an integer >= 0"),
        (["--scenario", "highway", "--vehicles", "5,5"], r"argument --vehicles: values must not repeat"),
        (["--scenario", "highway", "--vehicles", "2.5"], r"argument --vehicles: expected comma-separated integers"),
        (
            ["--scenario", "tjunction", "--arrival-rate", "0"],
            r"argument --arrival-rate: every value must be a finite number > 0 and <= 1200 \(veh/h per direction\)",
        ),
        (["--scenario", "tjunction", "--arrival-rate", "1500"], r"argument --arrival-rate: every value must be"),
        (["--scenario", "tjunction", "--arrival-rate", "inf"], r"argument --arrival-rate: every value must be"),
        (["--scenario", "tjunction", "--arrival-rate", "busy"], r"argument --arrival-rate: expected comma-separated"),
        (["--vehicles", "5"], r"argument --vehicles: varies the highway world, not the pedestrian world"),
        (["--scenario", "highway", "--pedestrians", "3"], r"argument --pedestrians: varies the pedestrian world"),
        (["--scenario", "highway", "--arrival-rate", "600"], r"argument --arrival-rate: varies the tjunction world"),
        (["--scenario", "tjunction", "--methods", "sideways"], r"argument --methods: method must be one of"),
    ],
)
def test_bad_options_exit_2_with_one_line_before_any_episode(tmp_path, run_cli, argv, message):
    code, out, err = run_cli("sweep", *argv, "--no-progress", "--out", tmp_path / "never")
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith("minimaxplan sweep: error: "), err
    assert re.search(message, err), err
    assert not (tmp_path / "never").exists()
