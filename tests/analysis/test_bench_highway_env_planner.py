"""benchmarks/bench_highway_env_planner.py measures what its tables say (the ``vehicle`` extra:
these tests fail, not skip, when CI=true)."""

import pytest
from extras import require_extra

highway_env = require_extra("highway_env")


@pytest.fixture(scope="module")
def bench(benchmark_script):
    return benchmark_script("bench_highway_env_planner")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--seeds", "0"], "--seeds must be >= 1, got 0"),
        (["--budgets", "35,0"], "--budgets must be integers >= 1 separated by commas, got '35,0'"),
        (["--budgets", "35,x"], "--budgets must be integers >= 1 separated by commas, got '35,x'"),
        (["--budgets", ""], "--budgets must be integers >= 1 separated by commas, got ''"),
    ],
)
def test_bad_arguments_exit_2_naming_the_argument(bench, capsys, argv, message):
    with pytest.raises(SystemExit) as exit_:
        bench.parse_arguments(argv)
    assert exit_.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1].endswith(f"error: {message}")


def test_good_arguments_parse_to_counts(bench):
    arguments = bench.parse_arguments(["--seeds", "3", "--budgets", "5,7"])
    assert arguments.seeds == 3 and arguments.budgets == (5, 7) and not arguments.render
    assert bench.parse_arguments([]).budgets == bench.BUDGETS


@pytest.mark.filterwarnings("ignore:.*intersection-v0 is out of date:DeprecationWarning")  # gymnasium
@pytest.mark.parametrize(("env_id", "start"), [("highway-fast-v0", 5), ("intersection-v0", 3)])
def test_a_scene_times_the_parts_it_reports_and_the_full_search_makes_all_k_expansions(bench, env_id, start):
    """The per-expansion column divides the empty-table search's time by its expansions: it
    must make exactly K even where the forecast's search stops early (these scenes of the
    committed run, seed 0), and the whole decision is the sum of the parts the table names."""
    scene = bench.Scene(env_id, 0, start)
    try:
        assert not scene.ended and scene.vehicles > 0
        # a learner on the highway only (its time, over the last decision, is part of the whole)
        assert (scene.method.learner is not None) == ("highway" in env_id)
        budget = 35
        ours = scene.library(budget)
        assert ours["solved"] and 1 <= ours["expansions"] < budget
        assert ours["free_expansions"] == budget
        assert ours["whole_s"] == scene.learn_time + ours["forecast_s"] + ours["search_s"]
        assert ours["lower"] <= ours["upper"]
        assert ours["action"] in [a[0] for a in scene.world.actions]
        theirs = scene.reference(3)  # highway-env's tree: a few expansions keep the test short
        assert 1 <= theirs["expansions"] <= 3 and theirs["time_s"] > 0
        assert theirs["action"] in [a[0] for a in scene.world.actions]
    finally:
        scene.close()
