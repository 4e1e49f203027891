"""The demo's library walk-through (part 1) reports true facts."""

from minimaxplan.analysis.cli import main
from minimaxplan.analysis.demo import run


def test_demo_walkthrough_is_consistent():
    result = run(seed=1, steps=120, horizon=10)
    assert result["survivors"] == ["anisotropic friction"]
    assert set(result["eliminated"]) == {"isotropic friction", "wrong input gain"}
    assert result["box"].contains(result["theta_true"])
    assert result["contained"]
    assert result["lmi"].status == "feasible" and result["lmi"].certified


def test_demo_command_part_one_only(capsys):
    assert main(["demo", "--episodes", "0", "--seed", "2"]) == 0
    text = capsys.readouterr().out
    assert "surviving hypotheses           : anisotropic friction" in text
    assert "every sampled trajectory inside: True" in text


def test_demo_writes_the_plots_and_an_animation(tmp_path, monkeypatch, capsys):
    from PIL import Image

    from minimaxplan.analysis import experiment, registry

    # the demo's own choice, before it is narrowed: the default worlds and the methods that support them all
    assert experiment.supported_methods(registry.default_scenario_names()) == [
        "robust",
        "nominal",
        "oracle",
        "dwa",
        "teb",
    ]
    # one world and one method keep the test short; the demo itself runs those
    monkeypatch.setattr(registry, "default_scenario_names", lambda: ["pedestrian"])
    monkeypatch.setattr(experiment, "supported_methods", lambda scenarios: ["robust"])
    out = tmp_path / "demo"
    assert main(["demo", "--episodes", "1", "--seed", "3", "--workers", "1", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    gif = out / "episode_pedestrian_robust_3.gif"
    assert f"animation of robust in the pedestrian world, seed 3: {gif}" in text
    with Image.open(gif) as image:
        assert image.n_frames > 1
    for name in ("trajectories_pedestrian.png", "motion_pedestrian.png", "episodes.csv", "table.md"):
        assert (out / name).stat().st_size > 0, name


def test_demo_animates_the_robust_method_among_pedestrians():
    from minimaxplan.analysis.demo import _animated_record
    from minimaxplan.analysis.episode import EpisodeRecord

    def record(scenario, method, seed):
        return EpisodeRecord(scenario, method, seed, "goal", 1.0, 1.0, 1, 0.0)

    records = [record("static", "robust", 0), record("pedestrian", "dwa", 0), record("pedestrian", "robust", 0)]
    assert _animated_record(records, 0) is records[2]
    assert _animated_record(records[:2], 0) is records[0]
    assert _animated_record(records[1:2], 0) is None
