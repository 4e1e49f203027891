"""The compiled engine's kernels run once with numba's bounds checking on.

An out-of-bounds access in a kernel must fail a test, not corrupt memory. numba ignores
``NUMBA_BOUNDSCHECK=1`` for kernels it loads from a populated disk cache, so the checked
run is a fresh process with an empty ``NUMBA_CACHE_DIR``; it first proves that bounds
checking is really on there (a deliberately out-of-bounds kernel raises `IndexError`).
"""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]

OUT_OF_BOUNDS = """
import numpy as np
from numba import njit

@njit
def read_past_the_end(a):
    return a[a.shape[0] + 3]

try:
    read_past_the_end(np.zeros(4))
except IndexError:
    print("bounds checked")
else:
    print("bounds NOT checked")
"""


def _checked_environment(cache_dir: pathlib.Path) -> dict[str, str]:
    env = dict(os.environ)
    env.update(NUMBA_BOUNDSCHECK="1", NUMBA_CACHE_DIR=str(cache_dir))
    return env


def _run(args: list[str], cache_dir: pathlib.Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, *args], cwd=ROOT, env=_checked_environment(cache_dir), capture_output=True, text=True
    )


def test_bounds_checking_is_on_in_a_fresh_process_with_an_empty_cache(tmp_path):
    result = _run(["-c", OUT_OF_BOUNDS], tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "bounds checked"


@pytest.mark.slow
def test_the_compiled_engine_tests_pass_with_bounds_checking(tmp_path):
    """The compiled search on random systems (both reward families, trees growing past
    their first arrays) with every array access checked."""
    probe = _run(["-c", OUT_OF_BOUNDS], tmp_path / "probe")
    assert probe.stdout.strip() == "bounds checked", probe.stderr
    selection = "builds_the_python_engines_tree or budgets_beyond or monotone_and_trees_nest"
    result = _run(
        [
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:xdist",
            "-p",
            "no:cacheprovider",
            "tests/planners/test_compiled_engine.py",
            "-k",
            selection,
        ],
        tmp_path / "cache",
    )
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-4000:]
    assert " passed" in result.stdout and "failed" not in result.stdout
