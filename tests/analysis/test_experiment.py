"""Experiment runner: summaries, determinism, Dask == local pool, the robot methods' outcomes."""

from __future__ import annotations

import csv
import json
import math
import pathlib

import numpy as np
import pytest
from extras import require_extra
from hypothesis import example, given, settings
from hypothesis import strategies as st

from minimaxplan.analysis.cli import main
from minimaxplan.analysis.episode import EpisodeRecord, LoopConfig, run_episode
from minimaxplan.analysis.experiment import run_experiment, summarise
from minimaxplan.analysis.registry import UnknownMethod, UnknownScenario
from minimaxplan.analysis.robot_methods import planning_system
from minimaxplan.models import Box, InputError
from minimaxplan.scenarios import robot_hypotheses

# A cheaper planner budget keeps these tests fast; the loop is otherwise the real one.
FAST = LoopConfig(budget=12)
COMMITTED = pathlib.Path(__file__).parents[2] / "benchmarks" / "results" / "experiments" / "table3" / "episodes.csv"


def _record(method, seed, outcome, time_s, ret=0.5):
    return EpisodeRecord("static", method, seed, outcome, time_s, ret, 10, 0.1)


def test_summary_counts_failures_and_averages_time_over_successes():
    records = [
        _record("robust", 0, "goal", 10.0),
        _record("robust", 1, "goal", 14.0),
        _record("robust", 2, "collision", 3.0),
        _record("robust", 3, "timeout", 60.0),
    ]
    (summary,) = summarise(records)
    assert summary["episodes"] == 4 and summary["failures"] == 2
    assert summary["mean_time_s"] == pytest.approx(12.0)
    assert summary["median_time_s"] == pytest.approx(12.0)
    assert summary["max_time_s"] == pytest.approx(14.0)
    low, high = summary["failure_ci95"]
    # Clopper-Pearson for 2/4: [0.0676, 0.9324]
    assert low == pytest.approx(0.06758, abs=1e-4) and high == pytest.approx(0.93242, abs=1e-4)
    assert summary["outcomes"] == {"collision": 1, "goal": 2, "timeout": 1}


def test_summary_with_no_success_has_no_time():
    (summary,) = summarise([_record("dwa", 0, "collision", 3.0)])
    assert math.isnan(summary["mean_time_s"]) and summary["failures"] == 1


def test_bad_method_and_scenario_are_rejected():
    with pytest.raises(UnknownMethod, match="method must be one of"):
        run_experiment(["static"], ["magic"], episodes=1)
    with pytest.raises(UnknownScenario, match="scenario must be one of"):
        run_experiment(["mars"], ["dwa"], episodes=1)
    with pytest.raises(InputError, match="episodes must be a positive integer, got 0"):
        run_experiment(["static"], ["dwa"], episodes=0)
    with pytest.raises(InputError, match="config must be a LoopConfig"):
        run_experiment(["static"], ["dwa"], episodes=1, config={"budget": 12})


def _committed_rows(scenario: str, method: str, seeds) -> list[dict]:
    """The committed Table 3 rows (sequential runs, `LoopConfig()`), as CSV cells."""
    with COMMITTED.open(newline="") as handle:
        rows = {(r["scenario"], r["method"], int(r["seed"])): r for r in csv.DictReader(handle)}
    return [{k: v for k, v in rows[(scenario, method, seed)].items() if k != "wall_time_s"} for seed in seeds]


def _as_cells(result) -> list[dict]:
    return [{k: "" if v is None else str(v) for k, v in r.row().items() if k != "wall_time_s"} for r in result.records]


def test_a_real_episode_on_the_pool_reproduces_the_committed_record():
    # The pool machinery itself (ordering, determinism, factories reaching the workers) is
    # tested on stub episodes in test_registry.py; this is one real robust episode in a worker.
    result = run_experiment(["static"], ["robust"], episodes=1, seed=3, workers=2, progress=False)
    assert _as_cells(result) == _committed_rows("static", "robust", [3])


@pytest.mark.slow
def test_dask_local_cluster_gives_the_same_summary():
    LocalCluster = require_extra("distributed").LocalCluster  # the cluster extra (Dask)
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        on_dask = run_experiment(
            ["pedestrian"],
            ["robust", "dwa"],
            episodes=1,
            seed=3,
            dask_address=cluster.scheduler_address,
            progress=False,
        )
    assert _as_cells(on_dask) == _committed_rows("pedestrian", "robust", [3]) + _committed_rows(
        "pedestrian", "dwa", [3]
    )


def test_every_hypothesis_eliminated_is_a_failure(monkeypatch):
    import minimaxplan.analysis.robot_scenario as robot_scenario

    wrong_only = [h for h in robot_hypotheses() if h.name == "wrong input gain"]
    monkeypatch.setattr(robot_scenario, "robot_hypotheses", lambda dt, params: wrong_only)
    record = run_episode("static", "robust", 0, FAST)
    assert record.outcome == "no_consistent_model"
    assert not record.success and record.decisions >= 1


def test_planning_system_adds_the_control_error_through_B():
    system = robot_hypotheses()[0].system
    augmented = planning_system(system, 0.03)
    assert augmented.ndisturbances == system.ndisturbances + system.ninputs
    np.testing.assert_array_equal(augmented.D[:, system.ndisturbances :], system.B)
    assert augmented.w == Box(np.r_[system.w.low, -0.03, -0.03], np.r_[system.w.high, 0.03, 0.03])


def test_robust_episode_record_is_consistent():
    record = run_episode("static", "robust", 11, LoopConfig(budget=12))
    assert record.outcome in {"goal", "collision", "timeout", "no_consistent_model"}
    assert 0.0 <= record.discounted_return <= 1 / (1 - 0.9)
    assert record.extra["lmi"]["full_model"] == "infeasible"
    assert record.extra["lmi"]["velocity_subsystem"] == "feasible"
    from minimaxplan.analysis.experiment import assumption4_note

    assert "certified in 1/1 episodes; full model infeasible in 1/1" in assumption4_note([record])
    assert len(record.trajectory) >= record.decisions


def test_experiment_command_writes_every_output(tmp_path):
    out = tmp_path / "run"
    code = main(
        [
            "experiment",
            "--scenario",
            "static",
            "--methods",
            "dwa,nominal",
            "--episodes",
            "1",
            "--workers",
            "1",
            "--seed",
            "2",
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert {s["method"] for s in summary} == {"dwa", "nominal"}
    for key in (
        "scenario",
        "method",
        "episodes",
        "failures",
        "failure_ci95",
        "mean_time_s",
        "median_time_s",
        "max_time_s",
        "mean_return",
    ):
        assert key in summary[0]
    csv_text = (out / "episodes.csv").read_text()
    assert csv_text.count("\n") == 3 and "assumption4_velocity_subsystem" in csv_text.splitlines()[0]
    assert "| scenario | method |" in (out / "table.md").read_text()
    assert "Assumption 4" not in (out / "table.md").read_text()  # no robust episode, no report
    assert (out / "trajectories_static.png").stat().st_size > 1000
    assert (out / "motion_static.png").stat().st_size > 1000  # speed and heading over time (Figures 3-4)


def test_experiment_command_rejects_unknown_method(capsys):
    assert main(["experiment", "--methods", "robust,magic"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(
        "minimaxplan experiment: error: argument --methods: method must be one of the registered methods ['robust', "
    )
    assert "got 'magic'" in err and err.count("\n") == 1


def test_frozen_prior_data_and_decision_horizon():
    from minimaxplan.analysis.robot_scenario import excitation_data
    from minimaxplan.scenarios import make_world

    world = make_world("static", 5)
    X, U = excitation_data(world, 30)
    X2, U2 = excitation_data(make_world("static", 5), 30)
    np.testing.assert_array_equal(X, X2)
    assert X.shape == (31, 4) and U.shape == (30, 2) and np.all(np.abs(U) <= 1)
    record = run_episode("static", "robust", 5, LoopConfig(budget=12, prior_samples=30, max_decisions=3))
    assert record.outcome == "horizon" and record.decisions == 3


def test_suboptimality_study_shape_and_trend_fit():
    from minimaxplan.analysis.suboptimality import fit_trend, markdown, suboptimality_study

    study = suboptimality_study(
        (3, 60), episodes=1, seed=4, horizon=3, workers=1, progress=False, config=LoopConfig(budget=8)
    )
    assert [row["n"] for row in study["rows"]] == [3, 60]
    for row in study["rows"]:
        assert row["min"] <= row["mean"] <= row["max"] and len(row["per_episode"]) == 1
    assert "| 60 |" in markdown(study)
    fit = fit_trend([1, 2, 4, 8], [2 + 3 * np.log(n) / n for n in (1, 2, 4, 8)])
    assert fit["a"] == pytest.approx(2.0) and fit["b"] == pytest.approx(3.0)


@settings(max_examples=40)
@given(
    seed=st.integers(0, 2**31 - 1),
    actions=st.lists(st.integers(0, 4), min_size=1, max_size=4),
)
def test_boxes_of_the_robust_model_contain_the_loop_driven_by_noisy_measurements(seed, actions):
    """The control acts on measured states; with the control error as a disturbance
    through B (planning_system), the interval model still contains the true states,
    with w and the measurement noise at their extremes."""
    from minimaxplan.analysis.robot_methods import measurement_box, velocity_controllers
    from minimaxplan.planners import IntervalModel
    from minimaxplan.scenarios import GoalReward

    rng = np.random.default_rng(seed)
    system = robot_hypotheses()[0].system
    theta = rng.uniform(system.theta.low, system.theta.high)
    params_box = Box(np.maximum(theta - 0.05, system.theta.low), np.minimum(theta + 0.05, system.theta.high))
    config = LoopConfig()
    noise = 0.01
    controllers = velocity_controllers(config)
    model = IntervalModel(
        planning_system(system, config.gain * noise), params_box, GoalReward([50.0, 50.0]), controllers, substeps=5
    )
    # Start near the first action's reference velocity so that the feedback does not
    # saturate, and keep the noise and the disturbance at extremes of constant sign: the
    # control error then accumulates (the worst case for the boxes).
    x = np.concatenate([rng.uniform(0, 20, 2), controllers[actions[0]].x_ref[2:] + rng.uniform(-0.2, 0.2, 2)])
    noise_sign, w_sign = rng.choice([-1.0, 1.0], size=4), rng.choice([-1.0, 1.0], size=2)
    measured = x + noise * noise_sign
    lower, upper, _, _ = model.rollout(model.initial_state(*measurement_box(measured, noise)), actions)
    k = 0
    assert np.all(lower[0] <= x) and np.all(x <= upper[0])
    for action in actions:
        for _ in range(5):
            u = np.clip(controllers[action].control(measured), -1, 1)
            x = system.step(x, u, theta, 0.1 * w_sign)
            measured = x + noise * noise_sign
            k += 1
            tol = 1e-9 * (1 + np.abs(x))
            assert np.all(lower[k] - tol <= x) and np.all(x <= upper[k] + tol)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"budget": 0}, "budget must be a positive integer"),
        ({"gamma": 1.0}, r"gamma must be in the open interval \(0, 1\), got 1.0"),
        ({"speed": -1.0}, "speed must be > 0"),
        ({"prior_samples": 0}, "prior_samples must be a positive integer, got 0"),
        ({"measurement": "laser"}, r"measurement must be one of \('uniform', 'gaussian'\), got 'laser'"),
        ({"directions": ((1, 1, 1),)}, "directions must be a non-empty sequence of 2-vectors"),
    ],
)
def test_loop_config_rejects_bad_settings(kwargs, message):
    with pytest.raises(InputError, match=message):
        LoopConfig(**kwargs)


@settings(max_examples=300)
@given(
    x=st.floats(-0.05, 0.05, allow_nan=False) | st.floats(-30, 30, allow_nan=False),
    v=st.sampled_from([-1.0, 1.0]) | st.floats(-1.0, 1.0, allow_nan=False),
    noise=st.sampled_from([0.01, 0.1, 1e-3]),
)
# |x + v| > |x - noise|: an ulp of the result does not cover the measurement's rounding
@example(x=0.005767577380981881, v=1.0, noise=0.01)
@example(x=0.0062231842228457, v=1.0, noise=0.01)
def test_measurement_box_holds_the_true_state_exactly(x, v, noise):
    from minimaxplan.analysis.robot_methods import measurement_box

    measured = np.array([x + v * noise])  # rounded, as a sensor reading is
    lower, upper = measurement_box(measured, noise)
    assert lower[0] <= x <= upper[0]  # no tolerance: the box is rounded outward


def test_run_episode_rejects_unknown_method_and_world():
    with pytest.raises(UnknownMethod, match=r"method must be one of the registered methods \['robust', .*got 'magic'"):
        run_episode("static", "magic", 0)
    with pytest.raises(UnknownScenario, match=r"scenario must be one of the registered scenarios \['static', "):
        run_episode("mars", "robust", 0)
    with pytest.raises(InputError, match="config must be a LoopConfig"):
        run_episode("static", "robust", 0, config=None)


def test_learner_boxes_stay_sound_and_nested_between_refits():
    from minimaxplan.analysis.robot_methods import _Learner
    from minimaxplan.analysis.robot_scenario import excitation_data
    from minimaxplan.scenarios import make_world

    world = make_world("static", 8)
    X, U = excitation_data(world, 120)
    learner = _Learner(robot_hypotheses(), 0.01, None)
    previous, fits = None, set()
    for n in range(U.shape[0]):
        learner.add(X[n], U[n], X[n + 1])
        (index, box), *_ = learner.survivors_with_boxes()
        assert index == 0 and box.contains(world.true_theta)
        if previous is not None:
            assert np.all(box.low >= previous.low) and np.all(box.high <= previous.high)
        previous = box
        fits.add(learner._fitted_on)
    # refitted as the data grows geometrically (1, 2, 3, 4, 6, 8, ...), not at every transition
    assert 10 <= len(fits) <= 25


def test_a_run_that_names_no_method_runs_those_that_support_its_scenarios(monkeypatch):
    """`supported_methods`: the robot and road worlds get the five planners, not highway-env's own idm ego
    (registered for the highway-env scenarios only, it made the demo and a default `experiment` fail); the
    highway-env scenarios get robust, nominal, oracle and idm."""
    from minimaxplan.analysis import registry
    from minimaxplan.analysis.experiment import supported_methods
    from minimaxplan.analysis.registry import UnknownScenario, default_scenario_names, method_names

    assert "idm" in method_names()
    assert supported_methods(default_scenario_names()) == ["robust", "nominal", "oracle", "dwa", "teb"]
    assert supported_methods(["highway-env:intersection-v0"]) == ["robust", "nominal", "oracle", "idm"]
    assert supported_methods(["static", "highway-env:intersection-v0"]) == ["robust", "nominal", "oracle"]
    with monkeypatch.context() as patch:  # a registry whose only method drives highway-env alone
        patch.setattr(registry, "method_names", lambda: ["idm"])
        with pytest.raises(InputError, match="no registered method supports every one of the scenarios"):
            supported_methods(["static"])
    with pytest.raises(InputError, match="scenarios must name"):
        supported_methods([])
    with pytest.raises(UnknownScenario, match="nowhere"):
        supported_methods(["nowhere"])
