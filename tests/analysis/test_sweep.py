"""``minimaxplan sweep``: the crowd worlds, the summary's intervals, the outputs, and every bad option."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from scipy import stats

from minimaxplan.analysis import cli
from minimaxplan.analysis.episode import EpisodeRecord
from minimaxplan.analysis.sweep import (
    HEADING_MARGIN,
    CrowdScenarioFactory,
    cell_name,
    make_crowd_world,
    run_sweep,
    summarise_sweep,
    sweep_markdown,
)
from minimaxplan.models import InputError
from minimaxplan.scenarios import make_world


def run(capsys, *argv) -> tuple[int, str, str]:
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as exc:  # argparse usage errors
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


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
    (row,) = summarise_sweep(records, {"cell": (3, 0.6)})
    assert (row["pedestrians"], row["velocity_uncertainty"], row["method"]) == (3, 0.6, "dwa")
    assert (row["failures"], row["collisions"], row["timeouts"], row["successes"]) == (2, 1, 1, 4)
    exact = stats.binomtest(2, 6).proportion_ci(confidence_level=0.95, method="exact")
    np.testing.assert_allclose(row["failure_ci95"], [exact.low, exact.high])
    half = stats.t.ppf(0.975, 3) * np.std(times, ddof=1) / 2
    np.testing.assert_allclose(row["time_ci95"], [np.mean(times) - half, np.mean(times) + half])
    assert row["mean_time_s"] == pytest.approx(12.0)
    one = summarise_sweep([record("teb", "goal", 9.0, 0)], {"cell": (1, 0.1)})[0]
    assert np.isnan(one["time_ci95"][0]) and one["mean_time_s"] == 9.0
    text = sweep_markdown(
        {"grid": {"scenario": "pedestrian", "episodes": 1, "seed": 0}, "rows": [one], "wall_time_s": 1}
    )
    assert "| 1 | 0.1 | teb | 0/1 | [0.000, 0.975] | 0 | 0 | 9.0 | - |" in text


# ------------------------------------------------------------------ a real run
def test_a_small_sweep_writes_its_table_plot_json_and_csv(tmp_path, capsys):
    out = tmp_path / "sweep"
    code, stdout, err = run(
        capsys,
        "sweep",
        "--pedestrians", "0,4",
        "--velocity-uncertainty", "0.3",
        "--methods", "dwa",
        "--episodes", "2",
        "--workers", "1",
        "--no-progress",
        "--out", out,
    )  # fmt: skip
    assert code == 0, err
    assert "| pedestrians | velocity uncertainty (m/s) | method |" in stdout
    assert re.search(r"\| 4 \| 0\.3 \| dwa \| \d/2 \|", stdout) and "Wall time of the run:" in stdout
    assert (out / "sweep.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    document = json.loads((out / "sweep.json").read_text())
    assert document["grid"]["pedestrians"] == [0, 4] and len(document["rows"]) == 2
    lines = (out / "sweep.csv").read_text().splitlines()
    assert lines[0].startswith("pedestrians,velocity_uncertainty,scenario,method,seed,outcome") and len(lines) == 5
    assert (out / "sweep.md").read_text() in stdout


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
        (["--scenario", "static"], r"argument --scenario: the sweep varies the scenarios \['pedestrian'\]"),
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
    ],
)
def test_bad_options_exit_2_with_one_line_before_any_episode(tmp_path, capsys, argv, message):
    code, out, err = run(capsys, "sweep", *argv, "--no-progress", "--out", tmp_path / "never")
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith("minimaxplan sweep: error: "), err
    assert re.search(message, err), err
    assert not (tmp_path / "never").exists()
