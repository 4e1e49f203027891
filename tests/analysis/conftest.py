"""Fixtures shared by the tests of `minimaxplan.analysis`."""

from __future__ import annotations

import contextlib
import csv
import json
import os
import subprocess
import sys
from collections.abc import Callable, Iterator

import pytest

from minimaxplan.analysis import cli, registry
from minimaxplan.analysis.numerical_environment import RECORDS_ENVIRONMENT


@pytest.fixture
def run_cli(capsys) -> Callable[..., tuple[int, str, str]]:
    """``run_cli(*argv)`` runs ``minimaxplan ARGV`` in this process: ``(exit code, stdout, stderr)``.

    The arguments are passed as strings; argparse's exit (``--help``, a usage error) is
    returned as its code.
    """

    def run(*argv) -> tuple[int, str, str]:
        try:
            code = cli.main([str(a) for a in argv])
        except SystemExit as exc:  # argparse: --help and usage errors
            code = exc.code
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    return run


@pytest.fixture
def replay_records(tmp_path) -> Callable[..., tuple[list[dict[str, str]], dict]]:
    """``replay_records(scenarios, methods, seed)`` re-runs one episode per scenario and method as the records were made.

    ``minimaxplan experiment`` runs in a fresh process under `RECORDS_ENVIRONMENT` (the
    BLAS kernel and numpy's SIMD targets are chosen when the libraries load, so the pin
    cannot be applied to this process). Returns the ``episodes.csv`` rows, every cell a
    string as the records hold it, and the run's ``environment.json``.
    """

    def replay(scenarios, methods, seed: int) -> tuple[list[dict[str, str]], dict]:
        out = tmp_path / f"replay-{seed}-{'-'.join(scenarios)}"
        command = [sys.executable, "-m", "minimaxplan.analysis.cli", "experiment"]
        command += ["--scenario", ",".join(scenarios), "--methods", ",".join(methods), "--episodes", "1"]
        command += ["--seed", str(seed), "--workers", "1", "--no-progress", "--out", str(out)]
        done = subprocess.run(command, env={**os.environ, **RECORDS_ENVIRONMENT}, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr[-2000:]
        with open(out / "episodes.csv", newline="") as handle:
            rows = list(csv.DictReader(handle))
        return rows, json.loads((out / "environment.json").read_text())

    return replay


@contextlib.contextmanager
def _registries_as_they_were() -> Iterator[None]:
    registry.scenario_names()  # the built-ins first, so that the snapshot holds them
    registry.method_names()
    scenarios, optional = dict(registry._SCENARIOS), set(registry._OPTIONAL_SCENARIOS)
    methods = {name: list(factories) for name, factories in registry._METHODS.items()}
    unavailable = dict(registry._UNAVAILABLE)
    try:
        yield
    finally:
        registry._SCENARIOS.clear()
        registry._SCENARIOS.update(scenarios)
        registry._OPTIONAL_SCENARIOS.clear()
        registry._OPTIONAL_SCENARIOS.update(optional)
        registry._METHODS.clear()
        registry._METHODS.update(methods)
        registry._UNAVAILABLE.clear()
        registry._UNAVAILABLE.update(unavailable)


@pytest.fixture(scope="session")
def registries_restored() -> Callable[[], contextlib.AbstractContextManager[None]]:
    """``with registries_restored(): ...`` registers scenarios and methods for a while.

    On leaving the block, the registries are as they were on entering it (the built-ins
    loaded first): the scenarios, which of them default runs leave out, the methods, and
    the reasons given for names that are not available. Later tests in the same process
    see only the built-ins. Session-scoped so that module-scoped fixtures may use it too.
    """
    return _registries_as_they_were
