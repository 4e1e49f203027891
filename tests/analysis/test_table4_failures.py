"""Table 4's diagnostics: the per-episode explanations of its failures (`benchmarks/explain_table4_failures.py`) hold on the records.

Each explained episode is re-run and must equal its committed record (the script raises
otherwise); these cases are the ones the README and docs/baselines.md quote. Only
methods whose records do not depend on the BLAS kernel are re-run here (nominal, DWA;
TEB's need the records' environment, which this process may not have).
"""

import csv
import pathlib

import pytest

RECORDS = pathlib.Path(__file__).parents[2] / "benchmarks/results/experiments/table4/episodes.csv"


def _record(scenario: str, method: str, seed: int) -> dict:
    with RECORDS.open(newline="") as handle:
        (row,) = [
            r
            for r in csv.DictReader(handle)
            if (r["scenario"], r["method"], r["seed"]) == (scenario, method, str(seed))
        ]
    return row


@pytest.mark.slow
def test_nominal_highway_seed_74_changed_lane_on_a_forecast_that_missed_its_leader_by_decimetres(benchmark_script):
    """Nominal's plan 0.9 s before the contact was clear of every box; its rest met vehicle 7 on the next
    forecast, which put it 0.35 m further back (the truth 0.03 m from the new one)."""
    module = benchmark_script("explain_table4_failures")
    facts = module.explain("highway", "nominal", 74, module.LoopConfig(), _record("highway", "nominal", 74))
    assert facts["outcome"] == "collision" and facts["other"] == 7
    assert facts["kind"] == "ego's lane change" and facts["ego_lane_before"] == "lane1"
    assert facts["plan_clear_last_s_before"] == pytest.approx(0.9) and facts[
        "plans_colliding_from_s_before"
    ] == pytest.approx(0.4)
    assert facts["replan"] == "forecast changed" and facts["replan_vehicle"] == 7
    old, new, truth = facts["replan_old_centre"], facts["replan_new_centre"], facts["replan_true_centre"]
    assert old[0] - truth[0] > 0.3 and abs(new[0] - truth[0]) < 0.05


@pytest.mark.slow
def test_dwa_tjunction_seed_31_waits_on_the_arc_with_a_turning_car_stopped_behind_it(benchmark_script):
    module = benchmark_script("explain_table4_failures")
    facts = module.explain("tjunction", "dwa", 31, module.LoopConfig(), _record("tjunction", "dwa", 31))
    assert facts["outcome"] == "timeout" and facts["lane"] == "south_west" and facts["ego_speed"] < module.STOPPED
    assert facts["nearest_movement"] == "westbound, turning left into the stem"
    assert facts["nearest_follows_ego"] and facts["nearest_speed"] == 0.0


def test_a_re_run_that_is_not_the_record_is_refused(benchmark_script):
    module = benchmark_script("explain_table4_failures")
    wrong = {**_record("highway", "nominal", 5), "time_s": "99.0"}
    with pytest.raises(RuntimeError, match="is not the record"):
        module.explain("highway", "nominal", 5, module.LoopConfig(), wrong)


@pytest.mark.slow
def test_the_elimination_times_script_checks_every_belief_against_the_truth(benchmark_script, tmp_path):
    """`benchmarks/elimination_times.py` on one seed per world: every vehicle-step checked, no true intention or
    parameter lost, the statistics and their table written."""
    module = benchmark_script("elimination_times")
    studies = module.main(["--seeds", "0", "--out", str(tmp_path)])
    for kind in ("highway", "tjunction"):
        study = studies[kind]
        assert study["vehicle_steps"] > 0
        assert study["intention_misses"] == study["theta_a_misses"] == study["theta_b_misses"] == 0
        assert study["solver_failures"] == 0
    assert "lane being left (mid lane change)" in studies["highway"]["statistics"]
    text = (tmp_path / "elimination_times.md").read_text()
    assert "| highway | lane being left (mid lane change) |" in text and "--seeds 0`" in text
    with pytest.raises(SystemExit):
        module.main(["--seeds", "5-2", "--out", str(tmp_path)])
    with pytest.raises(SystemExit):
        module.main(["--seeds", "x", "--out", str(tmp_path)])
