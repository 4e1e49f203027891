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
