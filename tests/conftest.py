"""Shared test configuration: one fixed hypothesis profile for CI and local runs."""

import importlib.util
import os
import pathlib
import sys

import pytest
from hypothesis import HealthCheck, settings

BENCHMARKS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"
# test modules import their shared helpers (`extras`) from this folder
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

# CI: a fixed, derandomised profile so that a run is reproducible and bounded in time.
settings.register_profile(
    "ci",
    max_examples=60,
    deadline=None,  # numerical work on a shared 2-core machine; time is checked by benchmarks
    derandomize=True,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile("dev", max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("thorough", max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture(scope="session")
def benchmark_script():
    """``name -> module``: a script of ``benchmarks/`` (not a package) loaded once per session."""
    loaded: dict = {}

    def load(name: str):
        if name not in loaded:
            spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
            module = importlib.util.module_from_spec(spec)
            sys.modules.setdefault(name, module)
            spec.loader.exec_module(module)
            loaded[name] = module
        return loaded[name]

    return load
