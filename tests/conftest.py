"""Shared test configuration: one fixed hypothesis profile for CI and local runs."""

import os

from hypothesis import HealthCheck, settings

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
