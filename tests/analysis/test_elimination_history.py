"""Histories of model elimination and parameter sets over growing data prefixes."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from minimaxplan.analysis.data_file import load_data_file
from minimaxplan.analysis.elimination_history import elimination_history, parameter_set_history
from minimaxplan.analysis.model_file import load_model_file
from minimaxplan.models import Box, InputError, UncertainLinearSystem, confidence_ellipsoid
from minimaxplan.verify import eliminate_models, feasible_parameter_box

ROOT = pathlib.Path(__file__).resolve().parents[2]
MODELS = load_model_file(ROOT / "examples" / "robot_hypotheses.toml")
DATA = load_data_file(ROOT / "examples" / "robot_data.csv")


def test_history_equals_direct_calls_on_each_prefix():
    sizes = [0, 3, 10, 40]
    history = elimination_history(MODELS.systems, DATA.states, DATA.controls, sizes, names=MODELS.names)
    assert history.margins.shape == history.survives.shape == (4, 4)
    for k, n in enumerate(sizes):
        direct = eliminate_models(MODELS.systems, DATA.states[: n + 1], DATA.controls[:n])
        np.testing.assert_array_equal(history.margins[:, k], direct.margins)
        assert [m for m in range(4) if history.survives[m, k]] == direct.survivors
    first = history.first_elimination()
    assert first["anisotropic friction"] is None and first["coupled friction"] is None
    assert first["isotropic friction"] in (3, 10, 40) and first["wrong input gain"] in (3, 10, 40)
    assert history.to_dict()["names"] == MODELS.names


def test_parameter_set_history_equals_direct_calls():
    system = MODELS.select("anisotropic friction").systems[0]
    sizes = [0, 1, 5, 30]
    history = parameter_set_history(
        system, DATA.states, DATA.controls, sizes, sigma=0.01, lam=0.5, delta=0.05, bound=2.0
    )
    regressors = system.regressor(DATA.states[:-1])
    targets = DATA.states[1:] - DATA.states[:-1] @ system.A0.T - DATA.controls @ system.B.T
    for k, n in enumerate(sizes):
        box = feasible_parameter_box(system, DATA.states[: n + 1], DATA.controls[:n])
        np.testing.assert_array_equal(history.feasible_low[k], box.low)
        np.testing.assert_array_equal(history.feasible_high[k], box.high)
        batch = confidence_ellipsoid(
            regressors[:n], targets[:n], sigma=0.01, lam=0.5, delta=0.05, bound=2.0
        ).bounding_box()
        scale = 1 + float(np.max(np.abs(batch.high - batch.low)))
        np.testing.assert_allclose(history.confidence_low[k], batch.low, rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(history.confidence_high[k], batch.high, rtol=0, atol=1e-9 * scale)
    assert history.prior == system.theta
    assert set(history.to_dict()) >= {"feasible_low", "confidence_high", "prior"}


def test_default_bound_is_the_largest_norm_over_the_prior():
    system = MODELS.select("anisotropic friction").systems[0]
    default = parameter_set_history(system, DATA.states, DATA.controls, [0, 4], sigma=0.01)
    explicit = parameter_set_history(system, DATA.states, DATA.controls, [0, 4], sigma=0.01, bound=np.hypot(1.5, 1.5))
    np.testing.assert_array_equal(default.confidence_low, explicit.confidence_low)


@st.composite
def plants(draw):
    """A random (non-Metzler) plant, its true parameter and a trajectory with disturbances at their extremes."""
    p = draw(st.integers(1, 3))
    d = draw(st.integers(1, 2))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    A0 = rng.normal(scale=0.4, size=(p, p))
    phi = rng.normal(scale=0.3, size=(d, p, p))
    B = rng.normal(size=(p, 1))
    w = Box(-rng.uniform(0.01, 0.2, p), rng.uniform(0.01, 0.2, p))
    theta_box = Box(-rng.uniform(0.1, 1, d), rng.uniform(0.1, 1, d))
    system = UncertainLinearSystem(A0, phi, B, w=w, theta=theta_box)
    theta = rng.uniform(theta_box.low, theta_box.high)
    steps = 25
    x = np.zeros((steps + 1, p))
    u = rng.uniform(-1, 1, (steps, 1))
    for n in range(steps):
        extreme = np.where(rng.random(p) < 0.5, w.low, w.high)
        x[n + 1] = system.step(x[n], u[n], theta, extreme)
    return system, theta, x, u


@settings(max_examples=20)
@given(plants())
def test_true_hypothesis_always_survives_and_its_boxes_hold_the_truth(plant):
    system, theta, states, controls = plant
    assume(np.abs(states).max() < 1e4)  # an unstable draw: its numbers say nothing about the guarantee
    sizes = [0, 5, 12, 25]
    history = elimination_history([system], states, controls, sizes)
    assert history.survives.all()
    sets = parameter_set_history(system, states, controls, sizes, sigma=0.2)
    tol = 1e-9 * (1 + np.abs(theta))
    assert np.all(sets.feasible_low <= theta + tol) and np.all(theta <= sets.feasible_high + tol)
    assert np.all(sets.feasible_low >= system.theta.low) and np.all(sets.feasible_high <= system.theta.high)


@pytest.mark.parametrize(
    ("sizes", "message"),
    [
        ([], r"sample_sizes must be a non-empty 1-dimensional array of integers"),
        ([1.0, 2.0], r"sample_sizes must be a non-empty 1-dimensional array of integers"),
        ([3, 2], r"sample_sizes must increase strictly within \[0, 120\].*got \[3, 2\]"),
        ([0, 121], r"sample_sizes must increase strictly within \[0, 120\]"),
        ([-1, 2], r"sample_sizes must increase strictly"),
    ],
)
def test_bad_sample_sizes_are_rejected(sizes, message):
    with pytest.raises(InputError, match=message):
        elimination_history(MODELS.systems, DATA.states, DATA.controls, sizes)
    with pytest.raises(InputError, match=message):
        parameter_set_history(MODELS.systems[1], DATA.states, DATA.controls, sizes, sigma=0.01)


def test_bad_arguments_are_rejected():
    with pytest.raises(InputError, match=r"names must have one entry per hypothesis \(4\), got 1"):
        elimination_history(MODELS.systems, DATA.states, DATA.controls, [1], names=["a"])
    with pytest.raises(InputError, match=r"hypotheses must hold at least one"):
        elimination_history([], DATA.states, DATA.controls, [1])
    with pytest.raises(InputError, match=r"controls must have shape \(120, 2\), got shape \(119, 2\)"):
        elimination_history(MODELS.systems, DATA.states, DATA.controls[:-1], [1])
    with pytest.raises(InputError, match=r"states must have shape \(\*, 4\), got shape \(121, 3\)"):
        parameter_set_history(MODELS.systems[1], DATA.states[:, :3], DATA.controls, [1], sigma=0.01)
    with pytest.raises(InputError, match=r"hypothesis must be an UncertainLinearSystem"):
        parameter_set_history("model", DATA.states, DATA.controls, [1], sigma=0.01)
