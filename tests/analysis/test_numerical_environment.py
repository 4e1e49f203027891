"""The numerical environment of the committed records: the pin takes effect and is reported as it is."""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

import pytest

from minimaxplan.analysis.numerical_environment import (
    RECORDS_BLAS_KERNEL,
    RECORDS_ENVIRONMENT,
    numerical_environment,
)

README = pathlib.Path(__file__).parents[2] / "README.md"
REPORT = "import json; from minimaxplan.analysis.numerical_environment import numerical_environment as n; print(json.dumps(n()))"


def _report_in_fresh_process(env: dict[str, str]) -> dict:
    done = subprocess.run([sys.executable, "-c", REPORT], env=env, capture_output=True, text=True, check=True)
    return json.loads(done.stdout)


def _without_pin() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k not in RECORDS_ENVIRONMENT}


def test_the_records_environment_takes_effect_in_a_fresh_process():
    report = _report_in_fresh_process({**_without_pin(), **RECORDS_ENVIRONMENT})
    # the kernels are read from the loaded libraries, not from the variables
    assert report["blas_kernels"] == {"numpy": RECORDS_BLAS_KERNEL, "scipy": RECORDS_BLAS_KERNEL}
    assert not {"X86_V4", "AVX512_ICL", "AVX512_SPR", "AVX512F", "AVX512_SKX"} & set(report["numpy_simd_targets"])
    assert report["pinned"] == dict(RECORDS_ENVIRONMENT)
    assert report["matches_records"] is True


def test_another_kernel_is_reported_as_not_the_records_one():
    report = _report_in_fresh_process({**_without_pin(), **RECORDS_ENVIRONMENT, "OPENBLAS_CORETYPE": "Sandybridge"})
    assert report["blas_kernels"] == {"numpy": "Sandybridge", "scipy": "Sandybridge"}
    assert report["matches_records"] is False
    unpinned = _report_in_fresh_process(_without_pin())
    assert unpinned["pinned"] == dict.fromkeys(RECORDS_ENVIRONMENT)
    assert unpinned["matches_records"] is False


def test_this_process_report_is_json_ready_and_names_its_versions():
    import numpy
    import scipy

    report = numerical_environment()
    assert json.loads(json.dumps(report)) == report
    assert (report["numpy"], report["scipy"]) == (numpy.__version__, scipy.__version__)


def test_the_readme_states_the_pin_that_the_code_applies():
    pin = " ".join(
        f'{name}="{value}"' if " " in value else f"{name}={value}" for name, value in RECORDS_ENVIRONMENT.items()
    )
    assert pin in README.read_text()


def test_the_sensitivity_benchmark_runs_a_variant_and_checks_that_it_took_effect(benchmark_script, tmp_path):
    sensitivity = benchmark_script("blas_kernel_sensitivity")
    label, overrides, kernel, targets = sensitivity.VARIANTS[1]
    records, environment, _ = sensitivity.run_variant((label, overrides, kernel, targets), [0], tmp_path)
    assert len(records) == len(sensitivity.WORLDS) * len(sensitivity.METHODS)
    assert environment["blas_kernels"] == {"numpy": kernel, "scipy": kernel}
    # a variant whose stated kernel is not what loads is refused, not reported
    with pytest.raises(RuntimeError, match="did not take effect"):
        sensitivity.run_variant(("wrong", overrides, RECORDS_BLAS_KERNEL, targets), [0], tmp_path)


def test_matches_records_needs_the_variables_the_kernels_and_no_avx512_loop_in_use():
    from minimaxplan.analysis.numerical_environment import _matches_records

    pinned, kernels = dict(RECORDS_ENVIRONMENT), {"numpy": RECORDS_BLAS_KERNEL, "scipy": RECORDS_BLAS_KERNEL}
    assert _matches_records(pinned, kernels, ["X86_V3"])
    # an older numpy on an AVX-512 machine: the variable is set, its names cap nothing
    assert not _matches_records(pinned, kernels, ["AVX512F", "AVX512_SKX"])
    assert not _matches_records(pinned, kernels, ["X86_V3", "X86_V4"])
    assert not _matches_records(pinned, {**kernels, "scipy": None}, ["X86_V3"])
    assert not _matches_records({**pinned, "OPENBLAS_NUM_THREADS": None}, kernels, ["X86_V3"])
