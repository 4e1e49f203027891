"""Every subcommand rejects a bad option on one line, exit 2, before any work (issue 10 item 6)."""

from __future__ import annotations

import pathlib
import socket
import subprocess
import sys
import time

import pytest
from extras import require_extra

from minimaxplan.analysis import demo as demo_module
from minimaxplan.analysis import experiment as experiment_module

ROOT = pathlib.Path(__file__).resolve().parents[2]
HYPOTHESES = ROOT / "examples" / "robot_hypotheses.toml"
ROBOT_DATA = ROOT / "examples" / "robot_data.csv"

SCALAR = """
name = "scalar"
A0 = [[0.5]]
phi = [[[1.0]]]
B = [[1.0]]
w = { low = [-0.1], high = [0.1] }
theta = { low = [-0.2], high = [0.2] }
"""
HUGE = str(10**400)


@pytest.fixture
def no_work(monkeypatch):
    """Make every episode runner and the demo's part 1 fail the test if they are reached."""

    def forbidden(*args, **kwargs):
        raise AssertionError("work started before the options were checked")

    monkeypatch.setattr(experiment_module, "_run_jobs", forbidden)
    monkeypatch.setattr(experiment_module, "run_job", forbidden)
    monkeypatch.setattr(demo_module, "run", forbidden)


def assert_one_line_error(code: int, out: str, err: str, command: str, option: str) -> None:
    assert code == 2, (code, err)
    assert out == ""
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert "Traceback" not in err
    assert err.startswith(f"minimaxplan {command}: error: "), err
    assert option in err, err


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["experiment", "--episodes", "-3"], "--episodes"),
        (["experiment", "--episodes", "0"], "--episodes"),
        (["experiment", "--episodes", "many"], "--episodes"),
        (["experiment", "--workers", "-2"], "--workers"),
        (["experiment", "--workers", "0"], "--workers"),
        (["experiment", "--seed", "-1"], "--seed"),
        (["experiment", "--scenario", ","], "--scenario"),
        (["suboptimality", "--episodes", "-3"], "--episodes"),
        (["suboptimality", "--workers", "0"], "--workers"),
        (["suboptimality", "--seed", "-1"], "--seed"),
        (["suboptimality", "--horizon", "0"], "--horizon"),
        (["suboptimality", "--samples", "0,5"], "--samples"),
        (["suboptimality", "--samples", "5,x"], "--samples"),
        (["demo", "--seed", "-5"], "--seed"),
        (["demo", "--episodes", "-1"], "--episodes"),
        (["demo", "--workers", "0"], "--workers"),
    ],
)
def test_a_bad_value_exits_2_on_one_line_before_any_work(run_cli, no_work, tmp_path, argv, option):
    command = argv[0]
    code, out, err = run_cli(*argv, "--out", tmp_path / "out")
    assert_one_line_error(code, out, err, command, f"argument {option}: ")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["experiment", "suboptimality", "demo"])
def test_an_unwritable_out_is_rejected_before_any_episode(run_cli, no_work, tmp_path, command):
    a_file = tmp_path / "results.txt"
    a_file.write_text("not a directory")
    code, out, err = run_cli(command, "--out", a_file)
    assert_one_line_error(code, out, err, command, "argument --out: ")
    assert "exists and is not a directory" in err
    code, out, err = run_cli(command, "--out", a_file / "below")
    assert_one_line_error(code, out, err, command, "argument --out: ")
    assert "is not a directory" in err


def test_an_unknown_name_is_one_line_before_any_episode(run_cli, no_work, tmp_path):
    code, out, err = run_cli("experiment", "--methods", "magic", "--out", tmp_path, "--no-progress")
    assert_one_line_error(code, out, err, "experiment", "'magic'")


def _closed_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def test_an_unreachable_dask_scheduler_fails_fast_on_one_line(run_cli, no_work, tmp_path):
    require_extra("distributed")  # the cluster extra (Dask)
    assert experiment_module.DASK_CONNECT_TIMEOUT_S <= 5
    started = time.perf_counter()
    code, out, err = run_cli(
        "experiment",
        "--scenario",
        "static",
        "--methods",
        "dwa",
        "--episodes",
        "1",
        "--dask",
        f"tcp://127.0.0.1:{_closed_port()}",
        "--out",
        tmp_path / "out",
        "--no-progress",
    )
    elapsed = time.perf_counter() - started
    assert_one_line_error(code, out, err, "experiment", "cannot reach the Dask scheduler at 'tcp://127.0.0.1:")
    assert elapsed < experiment_module.DASK_CONNECT_TIMEOUT_S + 15  # distributed's default waits 30 s
    assert not (tmp_path / "out").exists()


def test_a_malformed_dask_address_is_one_line(run_cli, no_work, tmp_path):
    require_extra("distributed")  # the cluster extra (Dask)
    code, out, err = run_cli(
        "experiment",
        "--scenario",
        "static",
        "--methods",
        "dwa",
        "--episodes",
        "1",
        "--dask",
        "nosuchscheme://x",
        "--out",
        tmp_path,
        "--no-progress",
    )
    assert_one_line_error(code, out, err, "experiment", "unknown address scheme 'nosuchscheme'")


# ------------------------------------------------------------- lmi and select
@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("A0 = [[0.5]]", f"A0 = [[{HUGE}]]", r"A0 holds an integer too large for a float"),
        ("high = [0.2]", f"high = [{HUGE}]", r"theta\.high holds an integer too large for a float"),
        (
            'name = "scalar"',
            f'name = "scalar"\ndt = {HUGE}',
            r"dt must be a finite number > 0, got an integer too large",
        ),
        (
            'name = "scalar"',
            f'measurement_noise = {HUGE}\nname = "scalar"',
            r"measurement_noise holds an integer too large",
        ),
    ],
)
@pytest.mark.parametrize("command", ["lmi", "select"])
def test_an_integer_too_large_for_a_float_is_one_line(tmp_path, run_cli, command, old, new, message):
    import re

    assert old in SCALAR
    model = tmp_path / "huge.toml"
    model.write_text(SCALAR.replace(old, new))
    argv = ("lmi", model) if command == "lmi" else ("select", model, ROBOT_DATA)
    code, out, err = run_cli(*argv)
    assert_one_line_error(code, out, err, command, "huge.toml")
    assert re.search(message, err), err


def test_a_directory_named_like_a_file_is_reported_as_a_directory(tmp_path, run_cli):
    (tmp_path / "data.csv").mkdir()
    (tmp_path / "models.toml").mkdir()
    code, out, err = run_cli("select", HYPOTHESES, tmp_path / "data.csv")
    assert_one_line_error(code, out, err, "select", "data.csv' is a directory, not a file")
    code, out, err = run_cli("lmi", tmp_path / "models.toml")
    assert_one_line_error(code, out, err, "lmi", "models.toml' is a directory, not a file")
    code, out, err = run_cli("select", tmp_path / "models.toml", ROBOT_DATA)
    assert_one_line_error(code, out, err, "select", "models.toml' is a directory, not a file")


@pytest.mark.parametrize(
    "argv",
    [
        ["lmi", HYPOTHESES, "--bogus"],
        ["select", HYPOTHESES, ROBOT_DATA, "--bogus"],
        ["experiment", "--bogus"],
        ["demo", "--bogus"],
    ],
)
def test_an_unknown_option_is_reported_by_its_subcommand(run_cli, no_work, argv):
    code, out, err = run_cli(*argv)
    assert_one_line_error(code, out, err, argv[0], "unrecognized arguments: --bogus")
    assert f"see 'minimaxplan {argv[0]} --help'" in err


# ----------------------------------------------------------------------- help
@pytest.mark.parametrize(
    ("command", "shown"),
    [
        (
            "experiment",
            [
                "(default: 100)",
                "EPISODES x scenarios x methods",
                "2,000 episodes",
                "(default: 0)",
                "(default: out/experiment)",
                "default: all cores",
            ],
        ),
        (
            "suboptimality",
            ["(default: 20)", "(default: 24)", "(default: 2,5,10,20,50,100,200,400)", "(default: out/suboptimality)"],
        ),
        ("demo", ["(default: 5)", "(default: 0)", "(default: out/demo)"]),
        ("lmi", ["(default: CLARABEL)", "(default: stdout)"]),
    ],
)
def test_help_shows_the_defaults(run_cli, command, shown):
    code, out, _ = run_cli(command, "--help")
    assert code == 0
    flat = " ".join(out.split())
    for text in shown:
        assert text in flat, (text, flat)


def test_help_imports_neither_cvxpy_nor_numba():
    script = (
        "import sys\n"
        "from minimaxplan.analysis import cli\n"
        "for argv in (['--help'], ['experiment', '--help'], ['lmi', '--help']):\n"
        "    try:\n"
        "        cli.main(argv)\n"
        "    except SystemExit:\n"
        "        pass\n"
        "heavy = sorted(m for m in ('cvxpy', 'numba', 'scipy', 'numpy') if m in sys.modules)\n"
        "print('HEAVY', heavy, file=sys.stderr)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=True)
    assert "HEAVY []" in done.stderr, done.stderr


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["--scenario", "highway-env:intersection-v0", "--methods", "robust"], "--scenario"),
        (["--scenario", "highway", "--methods", "idm"], "--methods"),
    ],
)
def test_a_highway_env_name_without_the_vehicle_extra_says_what_to_install(tmp_path, argv, option):
    """Run where highway-env cannot be imported (its entry in sys.modules set to None)."""
    script = (
        "import sys\n"
        "sys.modules['highway_env'] = None\n"
        "from minimaxplan.analysis import cli\n"
        f"sys.exit(cli.main({['experiment', *argv, '--episodes', '1', '--out', str(tmp_path)]!r}))\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert_one_line_error(done.returncode, done.stdout, done.stderr, "experiment", f"argument {option}: ")
    assert (
        "is not available: it needs highway-env, the vehicle extra: pip install 'minimaxplan[vehicle]'" in done.stderr
    )
    assert not any(tmp_path.iterdir())


def test_the_constants_spelled_out_for_a_light_parser_match_the_library():
    from minimaxplan.analysis import episode, lmi_command, model_file
    from minimaxplan.scenarios import worlds

    assert lmi_command.FORMS == (model_file.DISCRETE, model_file.CONTINUOUS)
    assert episode.MEASUREMENT_MODELS == worlds.MEASUREMENT_MODELS


@pytest.mark.parametrize("command", ["lmi", "select"])
def test_an_unwritable_report_file_is_rejected_before_the_solve(tmp_path, run_cli, monkeypatch, command):
    from minimaxplan.analysis import model_file

    def forbidden(*args, **kwargs):
        raise AssertionError("the model file was read before the options were checked")

    monkeypatch.setattr(model_file, "load_model_file", forbidden)
    inputs = [HYPOTHESES] if command == "lmi" else [HYPOTHESES, ROBOT_DATA]
    for out, message in [(tmp_path, "is a directory, not a file"), (tmp_path / "absent" / "r.md", "does not exist")]:
        code, stdout, err = run_cli(command, *inputs, "--out", out)
        assert_one_line_error(code, stdout, err, command, "argument --out: ")
        assert message in err, err


def test_the_library_entry_points_check_their_counts_before_any_episode(no_work):
    import numpy as np

    from minimaxplan.analysis.suboptimality import suboptimality_study
    from minimaxplan.models import InputError

    with pytest.raises(InputError, match=r"samples\[0\] must be a positive integer, got np.int64\(0\)"):
        suboptimality_study(np.array([0, 5]), episodes=1)
    with pytest.raises(InputError, match="samples must be a non-empty sequence"):
        suboptimality_study([], episodes=1)
    for kwargs, message in [
        ({"episodes": 0}, "episodes must be"),
        ({"seed": -1}, "seed must be an integer >= 0"),
        ({"horizon": 0}, "horizon must be"),
        ({"workers": 0}, "workers must be"),
    ]:
        with pytest.raises(InputError, match=message):
            suboptimality_study((5,), **{"episodes": 1, **kwargs})
    with pytest.raises(InputError, match="workers must be a positive integer, got 0"):
        experiment_module.run_experiment(["static"], ["dwa"], episodes=1, workers=0)
    with pytest.raises(InputError, match="seed must be an integer >= 0, got -1"):
        experiment_module.run_experiment(["static"], ["dwa"], episodes=1, seed=-1)


def test_the_demo_walkthrough_checks_its_arguments():
    from minimaxplan.models import InputError

    for kwargs, message in [
        ({"seed": -5}, "seed must be an integer >= 0, got -5"),
        ({"steps": 0}, "steps must be a positive integer"),
        ({"horizon": 0}, "horizon must be a positive integer"),
    ]:
        with pytest.raises(InputError, match=message):
            demo_module.run(**kwargs)
