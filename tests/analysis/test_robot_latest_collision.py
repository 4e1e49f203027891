"""The robot's robust method and its latest-possible-collision rule (`RobustMethod.latest_collision`)."""

from __future__ import annotations

import pytest

from minimaxplan.analysis.episode import run_episode
from minimaxplan.analysis.registry import register_scenario
from minimaxplan.analysis.robot_methods import RobustMethod
from minimaxplan.analysis.sweep import CrowdScenarioFactory, cell_name

# The stress sweep's one robust failure: 8 pedestrians told +-0.6 m/s, seed 7 (README).
CROWD = (8, 0.6)
SEED = 7


@pytest.fixture(scope="module")
def crowd_episodes(registries_restored):
    """Seed 7 of the crowd cell, the rule on (as registered) and off."""
    records = {}
    with registries_restored():
        name = cell_name("pedestrian", *CROWD)
        register_scenario(name, CrowdScenarioFactory(*CROWD))
        try:
            for rule in (True, False):
                RobustMethod.latest_collision = rule
                records[rule] = run_episode(name, "robust", SEED)
        finally:
            RobustMethod.latest_collision = True
    return records


@pytest.mark.slow
def test_without_the_rule_the_ties_of_a_possible_collision_go_to_action_0_and_it_collides(crowd_episodes):
    """The tree alone: from 6.5 s every first action may collide within two decisions, then within one; the
    best lower bounds tie and the tie goes to action 0 each time; a pedestrian walks into the robot at 8.1 s.
    No box missed: the predictions held; the plan did not."""
    record = crowd_episodes[False]
    assert record.outcome == "collision" and record.time_s == pytest.approx(8.1)
    assert record.boxes_checked > 0 and record.boxes_missed == 0
    decisions = record.extra["decisions"]
    assert all(d["latest_collision"] is None and d["action"] == d["tree_action"] for d in decisions)
    assert [d["action"] for d in decisions[13:]] == [0, 0, 0, 0]


@pytest.mark.slow
def test_with_the_rule_it_reaches_the_goal_and_every_override_is_clear_longest(crowd_episodes):
    record = crowd_episodes[True]
    assert record.outcome == "goal" and record.boxes_missed == 0
    decisions = record.extra["decisions"]
    examined = [d for d in decisions if d["latest_collision"] is not None]
    overrides = [d for d in decisions if d["action"] != d["tree_action"]]
    assert overrides and set(map(id, overrides)) <= set(map(id, examined))
    for d in examined:
        assert d["latest_collision"][d["action"]] == max(d["latest_collision"])
    # up to the first decision the rule examined, the two runs are the same episode
    first = decisions.index(examined[0])
    assert [d["action"] for d in decisions[:first]] == [
        d["action"] for d in crowd_episodes[False].extra["decisions"][:first]
    ]


def test_the_comparison_script_summarises_and_rejects_bad_cells(benchmark_script):
    script = benchmark_script("compare_robot_latest_collision")
    assert script.parse_cells("8:0.6, 5:0") == [(8, 0.6), (5, 0.0)]
    for bad in ("8", "8:x", "-1:0.3", "8:-0.1", "8:nan"):
        with pytest.raises(ValueError, match="--cells"):
            script.parse_cells(bad)
    rows = [
        {"mode": m, "scenario": "w", "seed": s, "outcome": o, "time_s": t, "decisions": 3, "examined": e,
         "overridden": v, "boxes_missed": 0}
        for m, s, o, t, e, v in [
            ("rule", 1, "goal", 10.0, 2, 1), ("tree", 1, "collision", 5.0, 0, 0),
            ("rule", 2, "goal", 12.0, 0, 0), ("tree", 2, "goal", 12.0, 0, 0),
        ]
    ]  # fmt: skip
    summary = {r["mode"]: r for r in script.summarise(rows)}
    assert summary["rule"]["outcomes"] == {"goal": 2} and summary["rule"]["mean_goal_time_s"] == 11.0
    assert summary["tree"]["outcomes"] == {"collision": 1, "goal": 1} and summary["tree"]["mean_goal_time_s"] == 12.0
    assert (summary["rule"]["examined"], summary["rule"]["overridden"]) == (2, 1)
    assert script.differences(rows) == [{"scenario": "w", "seed": 1, "rule": "goal", "tree": "collision"}]


def test_the_comparison_script_exits_2_on_bad_options(benchmark_script):
    script = benchmark_script("compare_robot_latest_collision")
    for argv in (["--cells", "8:x"], ["--worlds", "highway"], ["--episodes", "0"]):
        with pytest.raises(SystemExit) as exit_info:
            script.parse_arguments(argv)
        assert exit_info.value.code == 2
