"""The figures and the animation of an episode (issue 13 item 1): the matplotlib objects, not pixels."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402
from PIL import Image  # noqa: E402

from minimaxplan.analysis import animate as animate_module  # noqa: E402
from minimaxplan.analysis.animate import animate_episode  # noqa: E402
from minimaxplan.analysis.cli import main  # noqa: E402
from minimaxplan.analysis.episode import EpisodeRecord, LoopConfig, run_episode  # noqa: E402
from minimaxplan.analysis.plots import (  # noqa: E402
    METHOD_STYLES,
    motion_figure,
    plot_experiment,
    speed_and_heading,
    trajectory_figure,
)
from minimaxplan.models import InputError  # noqa: E402

DT = 0.1


def _record(method: str, outcome: str, *, seed: int = 4, steps: int = 30, offset: float = 0.0) -> EpisodeRecord:
    """A synthetic robot episode: the robot drives along x, one pedestrian walks down y."""
    time = np.arange(steps + 1) * DT
    states = np.stack([1.0 + time, 5.0 + offset + 0 * time, np.ones_like(time), np.zeros_like(time)], axis=1)
    pedestrians = np.stack([2.5 + 0 * time, 8.0 - time], axis=1)[:, None, :]
    extra: dict = {
        "lmi": None,
        "plans": [],
        "world": {
            "start": [1.0, 5.0],
            "goal": [9.0, 5.0],
            "obstacles": {"centers": [[5.0, 2.0]], "radii": [0.8]},
            "pedestrians": {"positions": [[2.5, 8.0]], "announced": [[0.0, -1.0]]},
            "params": {"goal_tolerance": 0.5, "robot_radius": 0.3},
        },
    }
    trace = {
        "dt": DT,
        "states": states.tolist(),
        "pedestrians": pedestrians.tolist(),
        "decision_steps": list(range(0, steps, 5)),
    }
    if method == "robust":
        lower = states[:6, :2] - 0.2
        upper = states[:6, :2] + 0.2
        extra["plans"] = [(0, lower.tolist(), upper.tolist())]
        extra["decisions"] = [
            {
                "step": 0,
                "action": 0,
                "lower": lower.tolist(),
                "upper": upper.tolist(),
                "pedestrian_lower": (pedestrians[:6] - 0.4).tolist(),
                "pedestrian_upper": (pedestrians[:6] + 0.4).tolist(),
                "survivors": ["anisotropic friction"],
            }
        ]
    return EpisodeRecord(
        scenario="pedestrian",
        method=method,
        seed=seed,
        outcome=outcome,
        time_s=steps * DT,
        discounted_return=1.0,
        decisions=len(trace["decision_steps"]),
        wall_time_s=0.0,
        trajectory=tuple(map(tuple, states[:, :2].tolist())),
        extra=extra,
        trace=trace,
    )


@pytest.fixture
def records() -> list[EpisodeRecord]:
    return [
        _record("robust", "goal"),
        _record("oracle", "goal"),
        _record("nominal", "collision", steps=20),  # the same path as oracle's, cut short
        _record("dwa", "goal", offset=0.3),
    ]


def _legend_labels(fig) -> list[str]:
    return [text.get_text() for legend in fig.legends for text in legend.get_texts()]


def _lines(ax, gid: str) -> list:
    return [line for line in ax.get_lines() if line.get_gid() == gid]


def test_trajectory_figure_labels_every_mark(records):
    fig = trajectory_figure(records)
    try:
        (ax,) = fig.axes
        assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
        labels = _legend_labels(fig)
        for label in (
            "static obstacle",
            "start",
            "goal region",
            "pedestrian path (true)",
            "pedestrian start",
            "collision",
            "pedestrians at the collision",
            "robust: predicted robot boxes",
            "robust: predicted pedestrian boxes",
            "robust",
            "oracle",
            "nominal",
            "dwa",
        ):
            assert label in labels, (label, labels)
        for method in ("robust", "oracle", "nominal", "dwa"):
            assert len(_lines(ax, f"method {method}")) == 1
        # nominal's line runs over oracle's: drawn above it and dashed, oracle wide underneath
        (nominal,) = _lines(ax, "method nominal")
        (oracle,) = _lines(ax, "method oracle")
        assert nominal.get_zorder() > oracle.get_zorder()
        assert nominal.get_linestyle() != "-" and oracle.get_linewidth() > nominal.get_linewidth()
        (same,) = [t for t in ax.texts if t.get_gid() == "identical paths"]
        assert same.get_text() == "same path: robust = oracle"
        # the pedestrian's whole walk, not only its start
        (walk,) = _lines(ax, "pedestrian path")
        assert len(walk.get_xdata()) == 31
        # one collision cross, at nominal's last position
        (cross,) = _lines(ax, "collision")
        np.testing.assert_allclose(np.ravel(cross.get_xydata()), records[2].trajectory[-1])
        assert sum(isinstance(p, Rectangle) for p in ax.patches) == 5 + 2  # robot boxes + 2 pedestrian boxes
    finally:
        plt.close(fig)


def test_method_styles_are_distinct():
    styles = {(s["color"], str(s["ls"])) for s in METHOD_STYLES.values()}
    assert len(styles) == len(METHOD_STYLES)


def test_motion_figure_speed_heading_and_decisions(records):
    fig = motion_figure(records)
    try:
        path_ax, speed_ax, heading_ax = fig.axes
        assert (path_ax.get_xlabel(), path_ax.get_ylabel()) == ("x (m)", "y (m)")
        assert (speed_ax.get_xlabel(), speed_ax.get_ylabel()) == ("time (s)", "speed (m/s)")
        assert heading_ax.get_xlabel() == "time (s)" and "(deg)" in heading_ax.get_ylabel()
        for ax in (path_ax, speed_ax, heading_ax):
            for method in ("robust", "oracle", "nominal", "dwa"):
                assert len(_lines(ax, f"method {method}")) == 1
        (speed,) = _lines(speed_ax, "method robust")
        np.testing.assert_allclose(speed.get_ydata(), 1.0)
        np.testing.assert_allclose(speed.get_xdata()[-1], 3.0)
        decisions = _lines(speed_ax, "decisions")
        assert len(decisions) == 4 and len(decisions[0].get_xdata()) == 6
        assert len(_lines(speed_ax, "collision")) == 1 and len(_lines(heading_ax, "collision")) == 1
        assert "decision" in _legend_labels(fig) and "collision" in _legend_labels(fig)
    finally:
        plt.close(fig)


def test_speed_and_heading_of_the_velocity():
    states = np.array([[0, 0, 0, 0], [0, 0, 0, 2.0], [0, 0, -1.0, 1e-9], [0, 0, -1.0, -1e-9], [0, 0, 1.0, 1.0]])
    speed, heading = speed_and_heading(states)
    np.testing.assert_allclose(speed, [0, 2, 1, 1, np.sqrt(2)])
    assert np.isnan(heading[0])  # standing still has no heading
    assert heading[1] == 90.0 and heading[4] == 45.0
    np.testing.assert_allclose(heading[2:4], 180.0)  # unwrapped: no jump from +180 to -180


def test_plot_experiment_writes_both_figures(tmp_path, records):
    written = plot_experiment(records, tmp_path, scenarios=["pedestrian"])
    assert [p.name for p in written] == ["trajectories_pedestrian.png", "motion_pedestrian.png"]
    assert all(p.stat().st_size > 1000 for p in written)


def test_animate_episode_frames(tmp_path, records):
    gif = animate_episode(records[0], tmp_path / "a.gif", max_frames=12)
    with Image.open(gif) as image:
        assert image.n_frames == 12
    with pytest.raises(InputError):
        animate_episode(EpisodeRecord("s", "m", 0, "goal", 0.0, 0.0, 0, 0.0), tmp_path / "b.gif")


def test_episode_records_the_trace_the_plots_need():
    record = run_episode("pedestrian", "robust", 3, LoopConfig(budget=8, max_decisions=3))
    trace = record.trace
    states = np.array(trace["states"])
    assert states.shape == (len(record.trajectory), 4)
    np.testing.assert_allclose(states[:, :2], np.array(record.trajectory), atol=1e-4)
    substeps = record.extra["world"]["params"]["substeps"]
    assert trace["decision_steps"] == [k * substeps for k in range(record.decisions)]
    pedestrians = np.array(trace["pedestrians"])
    assert pedestrians.shape[0] == len(states) and pedestrians.shape[2] == 2
    np.testing.assert_allclose(pedestrians[0], record.extra["world"]["pedestrians"]["positions"], atol=1e-4)
    decisions = record.extra["decisions"]
    assert [d["step"] for d in decisions] == trace["decision_steps"]
    first = decisions[0]
    assert first["survivors"] and all(isinstance(name, str) for name in first["survivors"])
    lower, upper = np.array(first["lower"]), np.array(first["upper"])
    assert np.all(lower <= upper) and np.all(lower[0] <= states[0, :2]) and np.all(states[0, :2] <= upper[0])
    ped_lower, ped_upper = np.array(first["pedestrian_lower"]), np.array(first["pedestrian_upper"])
    assert ped_lower.shape == (len(lower), pedestrians.shape[1], 2)
    # the true pedestrians stay inside the predicted boxes (grown by their radii) over the plan
    horizon = min(len(lower), len(pedestrians))
    assert np.all(ped_lower[:horizon] <= pedestrians[:horizon]) and np.all(pedestrians[:horizon] <= ped_upper[:horizon])


def test_animate_command_writes_a_gif(tmp_path, capsys):
    out = tmp_path / "anim"
    code = main(
        ["animate", "--scenario", "pedestrian", "--method", "robust", "--seed", "3", "--max-decisions", "3"]
        + ["--out", str(out)]
    )
    assert code == 0
    gif = out / "episode_pedestrian_robust_3.gif"
    assert str(gif) in capsys.readouterr().out
    with Image.open(gif) as image:
        assert image.n_frames > 1


@pytest.fixture
def no_episode(monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("an episode ran before the options were checked")

    monkeypatch.setattr("minimaxplan.analysis.episode.run_job", forbidden)
    monkeypatch.setattr(animate_module, "animate_episode", forbidden)


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["--scenario", "pedestrian", "--method", "magic"], "magic"),
        (["--scenario", "moon", "--method", "robust"], "moon"),
        (["--scenario", "pedestrian", "--method", "robust", "--seed", "-1"], "--seed"),
        (["--scenario", "pedestrian", "--method", "robust", "--max-decisions", "0"], "--max-decisions"),
        (["--method", "robust"], "--scenario"),
    ],
)
def test_animate_command_rejects_bad_options(capsys, no_episode, argv, option):
    try:
        code = main(["animate", *argv])
    except SystemExit as exc:
        code = exc.code
    captured = capsys.readouterr()
    assert code == 2 and captured.out == ""
    assert captured.err.count("\n") == 1 and captured.err.startswith("minimaxplan animate: error: ")
    assert option in captured.err, captured.err


def test_draw_png_writes_the_drawing_and_closes_the_figure_even_when_drawing_fails(tmp_path):
    from minimaxplan.analysis.figures import draw_png

    before = set(plt.get_fignums())
    out = draw_png(lambda ax: ax.plot([0, 1], [0, 1]), tmp_path / "line.png", figsize=(2, 1), dpi=50)
    assert out == tmp_path / "line.png"
    with Image.open(out) as image:
        assert image.size == (100, 50)

    def broken(ax):
        raise RuntimeError("no data")

    with pytest.raises(RuntimeError, match="no data"):
        draw_png(broken, tmp_path / "broken.png", figsize=(2, 1))
    assert not (tmp_path / "broken.png").exists()
    assert set(plt.get_fignums()) == before


def test_the_trace_reads_only_what_a_world_declares():
    """Robot and road worlds declare `TracedWorld` (robot worlds `CrowdedWorld` too); a world that declares
    neither gets a trace without states or pedestrians, its decisions counted, dt 1."""
    from minimaxplan.analysis.episode import _Trace
    from minimaxplan.analysis.registry import CrowdedWorld, TracedWorld, World, scenario_factory

    config = LoopConfig()
    robot = scenario_factory("pedestrian")().make_world(3, config)
    road = scenario_factory("highway")().make_world(3, config)
    assert isinstance(robot, TracedWorld) and isinstance(robot, CrowdedWorld)
    assert isinstance(road, TracedWorld) and not isinstance(road, CrowdedWorld)

    class Bare:  # a World with nothing more
        substeps, done, outcome, time, position = 1, False, "running", 0.0, np.zeros(2)

        def measure(self):
            return np.zeros(2)

        def apply(self, u):
            return "running"

        def reward(self):
            return 1.0

        def to_dict(self):
            return {}

    bare = Bare()
    assert isinstance(bare, World) and not isinstance(bare, TracedWorld) and not isinstance(bare, CrowdedWorld)
    trace = _Trace(bare)
    trace.decided(bare)
    trace.decided(bare)
    trace.stepped(bare)
    assert trace.to_dict(bare) == {"dt": 1.0, "states": [], "pedestrians": [], "decision_steps": [0, 1]}
    traced = _Trace(road)
    traced.decided(road)
    assert traced.to_dict(road)["dt"] == road.params.dt and len(traced.states) == 1 and not traced.pedestrians
