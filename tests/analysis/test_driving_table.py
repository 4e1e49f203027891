"""Table 4 from episode rows: failures as the paper counts them, timeouts apart, paired travel-time ratios."""

import math

import pytest

from minimaxplan.analysis.driving_table import driving_markdown, outcome_counts, paired_ratio, write_driving_table
from minimaxplan.models.errors import InputError


def _row(scenario, method, seed, outcome, time_s):
    return {"scenario": scenario, "method": method, "seed": seed, "outcome": outcome, "time_s": time_s}


ROWS = [
    _row("highway", "robust", 0, "goal", 10.0),
    _row("highway", "robust", 1, "goal", 12.0),
    _row("highway", "robust", 2, "timeout", 40.0),
    _row("highway", "robust", 3, "goal", 9.0),
    _row("highway", "dwa", 0, "goal", 8.0),
    _row("highway", "dwa", 1, "collision", 3.0),
    _row("highway", "dwa", 2, "goal", 9.0),
    _row("highway", "dwa", 3, "goal", 9.0),
    _row("highway", "teb", 0, "goal", 11.0),
    _row("highway", "teb", 1, "off_road", 2.0),
    _row("highway", "teb", 2, "goal", 12.0),
    _row("highway", "teb", 3, "goal", 10.0),
]


def test_failures_are_collisions_and_leaving_the_road_and_timeouts_are_counted_apart():
    counts = {c["method"]: c for c in outcome_counts(ROWS)}
    robust, dwa, teb = counts["robust"], counts["dwa"], counts["teb"]
    assert (robust["failures"], robust["timeouts"], robust["goals"]) == (0, 1, 3)
    assert (dwa["failures"], dwa["collisions"], teb["failures"], teb["off_road"]) == (1, 1, 1, 1)
    assert robust["failure_ci95"][0] == 0.0 and 0.5 < robust["failure_ci95"][1] < 0.65  # 0/4: [0, 0.602]
    assert robust["time_mean_s"] == pytest.approx(31 / 3)
    low, high = robust["time_ci95"]
    assert low < 31 / 3 < high


def test_the_paired_ratio_uses_only_seeds_both_complete():
    ratio = paired_ratio(ROWS, "highway", "robust", "dwa")
    assert ratio["pairs"] == 2  # seed 1: dwa collided; seed 2: robust timed out
    assert ratio["mean"] == pytest.approx((10 / 8 + 9 / 9) / 2)
    assert ratio["method_time_s"] == pytest.approx(9.5) and ratio["reference_time_s"] == pytest.approx(8.5)
    single = paired_ratio(ROWS[:1] + ROWS[4:5], "highway", "robust", "dwa")
    assert single["pairs"] == 1 and math.isnan(single["ci95"][0])
    assert paired_ratio(ROWS, "tjunction", "robust", "dwa")["pairs"] == 0


def test_the_markdown_compares_against_the_faster_baseline(tmp_path):
    text = driving_markdown(ROWS)
    assert "| highway | robust | 0/4 |" in text and "| 1 |" in text
    assert "| highway | dwa | 2 | 1.12 |" in text  # dwa (8.7 s mean) is faster than teb (11 s)
    assert write_driving_table(ROWS, tmp_path) == tmp_path / "table4.md"
    assert (tmp_path / "table4.md").read_text() == text
    robot = [_row("static", "robust", 0, "goal", 5.0)]
    assert write_driving_table(robot, tmp_path / "none") is None


def test_malformed_rows_are_rejected():
    with pytest.raises(InputError, match=r"rows\[0\] must have scenario"):
        outcome_counts([{"scenario": "highway"}])
    with pytest.raises(InputError, match="time_s"):
        outcome_counts([_row("highway", "robust", 0, "goal", "fast")])


def test_a_driving_run_writes_table4_beside_table_md(tmp_path):
    from minimaxplan.analysis.experiment import run_experiment, write_outputs

    result = run_experiment(["highway"], ["dwa"], episodes=1, workers=1, progress=False)
    out = write_outputs(result, tmp_path)
    record = result.records[0]
    text = (out / "table4.md").read_text()
    failures = int(record.outcome in ("collision", "off_road"))
    assert f"| highway | dwa | {failures}/1 |" in text
