"""docs/guide.md runs as printed, and says what the code does.

The guide's blocks are executed in a fresh, empty folder, as a reader would: each toml
block that opens with a comment ``# NAME.toml:`` and each python block whose docstring
opens with ``NAME.py:`` is written to the file it names; the other python blocks run in
order, in one fresh process (with its own numba cache directory, so the reward kernel it
compiles stays out of the project's caches), and each one's output must equal the text
block that follows it; every ``$ command`` of a console block then runs in a shell
there, and its output must be the lines printed under it. The claims the guide makes in
prose about those commands' reports are checked on their JSON form.
"""

from __future__ import annotations

import json
import os
import pathlib
import re
import subprocess
import sys

import numpy as np
import pytest

GUIDE = pathlib.Path(__file__).resolve().parents[1] / "docs" / "guide.md"
BLOCK = re.compile(r"^```(\w+)\n(.*?)^```$", flags=re.S | re.M)
FILE_HEADER = re.compile(r'^(?:# |""")([\w.]+\.(?:toml|py)):')
MARKER = "---- guide block {} ----"

pytestmark = pytest.mark.slow


def guide_blocks() -> list[tuple[str, str]]:
    """The guide's fenced blocks, in order, as (language, text)."""
    return [(language, text) for language, text in BLOCK.findall(GUIDE.read_text(encoding="utf-8"))]


def _files_and_session(blocks):
    files, session = {}, []  # session: (code, expected output lines)
    for i, (language, text) in enumerate(blocks):
        header = FILE_HEADER.match(text)
        if language in ("toml", "python") and header:
            assert header.group(1) not in files, f"the guide writes {header.group(1)} twice"
            files[header.group(1)] = text
        elif language == "python":
            following = blocks[i + 1] if i + 1 < len(blocks) else ("", "")
            assert following[0] == "text", f"python block {len(session)} is not followed by its output"
            session.append((text, following[1].splitlines()))
    return files, session


def _commands(blocks):
    commands = []  # (command, expected output lines)
    for language, text in blocks:
        if language != "console":
            continue
        for line in text.splitlines():
            if line.startswith("$ "):
                commands.append((line[2:], []))
            else:
                assert commands, f"console output before any command: {line!r}"
                commands[-1][1].append(line)
    return commands


def _run_guide(folder: pathlib.Path) -> dict:
    """Write the guide's files in ``folder``, run its Python session, then its commands."""
    blocks = guide_blocks()
    files, session = _files_and_session(blocks)
    for name, text in files.items():
        (folder / name).write_text(text, encoding="utf-8")
    script = "\n".join(f"print({MARKER.format(n)!r})\n{code}" for n, (code, _) in enumerate(session))
    (folder / "session.py").write_text(script, encoding="utf-8")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(folder / "numba_cache"), "PYTHONPATH": str(folder)}
    env["PATH"] = str(pathlib.Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")  # the venv's minimaxplan
    run = subprocess.run(
        [sys.executable, "session.py"], cwd=folder, env=env, capture_output=True, text=True, timeout=900
    )
    assert run.returncode == 0, run.stderr[-3000:]
    outputs = re.split(r"^---- guide block \d+ ----\n", run.stdout, flags=re.M)[1:]
    results = []
    for command, expected in _commands(blocks):
        done = subprocess.run(["bash", "-c", command], cwd=folder, env=env, capture_output=True, text=True, timeout=300)
        results.append((command, expected, done))
    return {"folder": folder, "files": files, "session": session, "outputs": outputs, "commands": results}


def test_the_guide_has_what_the_task_names():
    blocks = guide_blocks()
    files, session = _files_and_session(blocks)
    commands = [command for command, _ in _commands(blocks)]
    assert {"motor.toml", "motor_pd.toml", "motor_reward.py"} <= set(files)
    assert any(c.startswith("minimaxplan select ") for c in commands)
    assert any(c.startswith("minimaxplan lmi ") for c in commands)
    code = "\n".join(text for text, _ in session)
    for name in ("predict_tube", "RobustTreePlanner", "eliminate_models", "feasible_parameter_box"):
        assert name in code, name
    assert "register_reward_params" in files["motor_reward.py"]


def test_the_guide_runs_as_printed(tmp_path):
    # One test, one run: the session compiles the reward kernel (about 10 s of CPU), and pytest-xdist
    # would run a module fixture once per worker.
    guide_run = _run_guide(tmp_path)
    outputs, session = guide_run["outputs"], guide_run["session"]
    assert len(outputs) == len(session) >= 5
    for n, ((code, expected), printed) in enumerate(zip(session, outputs)):
        assert printed.splitlines() == expected, f"guide block {n}:\n{code}"
    assert len(guide_run["commands"]) == 3
    for command, expected, done in guide_run["commands"]:
        assert done.stdout.splitlines() == expected, (command, done.stdout, done.stderr)
    folder = guide_run["folder"]
    for report in ("selection.md", "open_loop.md", "closed_loop.md"):
        assert (folder / report).read_text(encoding="utf-8").startswith("# ")
    _check_what_the_reports_say(folder)


def _json(folder, *args):
    done = subprocess.run(
        ["minimaxplan", *args, "--json"],
        cwd=folder,
        env={**os.environ, "PATH": str(pathlib.Path(sys.executable).parent) + os.pathsep + os.environ["PATH"]},
        capture_output=True,
        text=True,
        timeout=300,
    )
    return json.loads(done.stdout)


def _check_what_the_reports_say(folder: pathlib.Path) -> None:
    # the prose of sections 3 and 4, on the reports' JSON form
    selection = _json(folder, "select", "motor.toml", "motor_data.npz")
    assert selection["survivors"] == ["viscous friction", "friction and spring"]
    assert selection["eliminated"] == ["weak motor"]
    boxes = {h["name"]: h["feasible_box"] for h in selection["hypotheses"] if h["survives"]}
    low, high = boxes["viscous friction"]["low"][0], boxes["viscous friction"]["high"][0]
    assert round(low, 2) == 1.89 and round(high, 2) == 2.01 and low <= 2.0 <= high  # "about [1.89, 2.01]"
    # "friction and spring" contains the truth: its spring constant's box holds 0
    assert boxes["friction and spring"]["low"][1] <= 0.0 <= boxes["friction and spring"]["high"][1]
    # motor_pd.toml's box [1.8, 2.1] widens the feasible box of the true hypothesis
    assert 1.8 <= low and high <= 2.1
    open_loop = _json(folder, "lmi", "motor.toml", "--model", "viscous friction", "--vertices")
    assert [m["result"]["status"] for m in open_loop["models"]] == ["infeasible"]
    closed_loop = _json(folder, "lmi", "motor_pd.toml", "--vertices")
    assert closed_loop["all_hold"] and closed_loop["models"][0]["result"]["status"] == "feasible"


def test_full_voltage_would_break_the_speed_limit():
    # "Full voltage would reach about 2 rad/s" (the limit is 1.5): the true motor's steady
    # speed is 4 u / theta_b, approached by the forward-Euler model of motor.toml.
    assert "speed_limit=1.5" in GUIDE.read_text(encoding="utf-8")
    x = np.zeros(2)
    for _ in range(100):  # 5 s at full voltage, no disturbance
        x = x + 0.05 * np.array([x[1], -2.0 * x[1] + 4.0])
    assert 1.5 < 1.95 < x[1] < 2.0
