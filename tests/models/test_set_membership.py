"""Set-membership estimation under bounded noise: soundness, monotone radius, bad input."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import (
    Box,
    DimensionError,
    EmptySetError,
    InputError,
    NonFiniteError,
    SetMembershipEstimator,
    UncertainLinearSystem,
)
from minimaxplan.models.set_membership import OUTWARD_ROUNDING


def _noise(rng, mode, bounds):
    if mode == "uniform":
        return rng.uniform(-bounds, bounds)
    if mode == "extreme":  # every row at +-bound: the strips touch theta*
        return bounds * rng.choice([-1.0, 1.0], size=bounds.shape)
    if mode == "mixed":
        return np.where(
            rng.random(bounds.shape) < 0.5,
            rng.uniform(-bounds, bounds),
            bounds * np.sign(rng.normal(size=bounds.shape)),
        )
    return np.zeros_like(bounds)


@given(
    seed=st.integers(0, 2**32 - 1),
    d=st.integers(1, 4),
    p=st.integers(1, 3),
    n=st.integers(1, 40),
    mode=st.sampled_from(["uniform", "extreme", "mixed", "zero"]),
    per_row=st.booleans(),
    flat_side=st.booleans(),
    on_boundary=st.booleans(),
)
def test_theta_stays_inside_and_radius_never_grows(seed, d, p, n, mode, per_row, flat_side, on_boundary):
    rng = np.random.default_rng(seed)
    half = 10.0 ** rng.uniform(-1, 1, size=d)
    if flat_side:
        half[rng.integers(d)] = 0.0
    prior = Box.from_center(rng.normal(size=d), half)
    theta = rng.uniform(prior.low, prior.high)
    if on_boundary:
        theta = np.where(rng.random(d) < 0.5, prior.low, prior.high)
    gamma = 10.0 ** rng.uniform(-3, 0, size=p) if per_row else np.full(p, 10.0 ** rng.uniform(-3, 0))
    estimator = SetMembershipEstimator(d, noise_bound=gamma if per_row else gamma[0], prior=prior)
    previous_radius, previous_box = estimator.radius, estimator.parameter_set()
    assert np.linalg.norm(theta - estimator.estimate) <= previous_radius
    for _ in range(n):
        E = rng.normal(size=(p, d)) * 10.0 ** rng.uniform(-1, 1)
        estimator.update(E, E @ theta + _noise(rng, mode, gamma))
        box = estimator.parameter_set()
        assert box.contains(theta), (box, theta)
        assert estimator.radius <= previous_radius
        assert np.linalg.norm(theta - estimator.estimate) <= estimator.radius
        # eq. (5): the reported set only shrinks and stays inside the prior
        assert np.all(box.low >= previous_box.low) and np.all(box.high <= previous_box.high)
        assert prior.contains(box.vertices())
        # the ellipsoid itself holds theta* (up to the rounding the reported sets absorb)
        if not flat_side:
            offset = np.linalg.solve(np.linalg.cholesky(estimator.shape_matrix), theta - estimator.ellipsoid_center)
            assert offset @ offset <= 1 + 1e-6
        previous_radius, previous_box = estimator.radius, box
    assert estimator.nsamples == n


@settings(max_examples=12)
@given(seed=st.integers(0, 2**32 - 1), d=st.integers(1, 4), p=st.integers(1, 3), extreme=st.booleans())
def test_long_runs_stay_sound_while_the_set_collapses(seed, d, p, extreme):
    """Hundreds of samples: the box shrinks to the rounding floor under extreme noise."""
    rng = np.random.default_rng(seed)
    prior = Box.from_center(5 * rng.normal(size=d), 10.0 ** rng.uniform(-1, 1, size=d))
    theta = np.where(rng.random(d) < 0.5, prior.low, prior.high) if extreme else rng.uniform(prior.low, prior.high)
    gamma = 10.0 ** rng.uniform(-4, 0)
    estimator = SetMembershipEstimator(d, noise_bound=gamma, prior=prior)
    radius = estimator.radius
    for _ in range(300):
        E = rng.normal(size=(p, d)) * 10.0 ** rng.uniform(-1, 1)
        noise = gamma * rng.choice([-1.0, 1.0], size=p) if extreme else rng.uniform(-gamma, gamma, size=p)
        estimator.update(E, E @ theta + noise)
        assert estimator.parameter_set().contains(theta)
        assert estimator.radius <= radius
        assert np.linalg.norm(theta - estimator.estimate) <= estimator.radius
        radius = estimator.radius


@settings(max_examples=30)
@given(seed=st.integers(0, 2**32 - 1), log_dt=st.floats(-2, -0.3))
def test_documented_use_with_a_simulated_system(seed, log_dt):
    """targets = x+ - A0 x - B u, noise bound per row = max |D w| over the box w (at its corners)."""
    rng = np.random.default_rng(seed)
    p, d = 3, 2
    A = rng.normal(size=(p, p))  # neither Metzler nor stable
    phi = rng.normal(size=(d, p, p))
    D = rng.normal(size=(p, 2))
    w_box = Box.from_center(np.zeros(2), rng.uniform(0.01, 0.2, size=2))
    prior = Box([-1.0, -1.0], [1.0, 1.0])
    system = UncertainLinearSystem.from_continuous(
        A, phi, rng.normal(size=(p, 1)), D=D, w=w_box, theta=prior, dt=10.0**log_dt
    )
    theta = rng.uniform(prior.low, prior.high)
    noise_bound = np.abs(system.D) @ w_box.high  # per row, for a box centred at 0
    estimator = SetMembershipEstimator(d, noise_bound=noise_bound, prior=prior)
    x = rng.normal(size=p)
    for _ in range(40):
        u = rng.uniform(-1, 1, size=1)
        w = w_box.vertices()[rng.integers(4)]  # disturbances at the corners of their box
        x_next = system.step(x, u, theta, w)
        estimator.update(system.regressor(x), x_next - system.A0 @ x - system.B @ u)
        assert estimator.parameter_set().contains(theta)
        assert np.linalg.norm(theta - estimator.estimate) <= estimator.radius
        x = x_next / max(1.0, np.linalg.norm(x_next))  # keep the state bounded; any x is a valid sample


def test_the_estimator_learns_under_uniform_noise():
    """Reference run (fixed seed; measured: radius 1.414 -> 1.04e-3, box half-widths <= 8.3e-4, error 1.6e-4).

    The ellipsoid alone stalls (largest semi-axis 0.28: its centre's prediction errors
    stay in the dead zone); the box, propagated from every row, keeps shrinking.
    """
    rng = np.random.default_rng(1)
    theta = np.array([0.3, -0.7])
    estimator = SetMembershipEstimator(2, noise_bound=0.05, prior=Box([-1.0, -1.0], [1.0, 1.0]))
    initial = estimator.radius
    for _ in range(400):
        E = rng.normal(size=(2, 2))
        estimator.update(E, E @ theta + rng.uniform(-0.05, 0.05, size=2))
    assert initial == pytest.approx(np.sqrt(2), rel=1e-8)
    assert estimator.radius < 2e-3
    assert np.linalg.norm(estimator.estimate - theta) <= estimator.radius
    assert np.all(estimator.parameter_set().radius < 1e-3)
    assert np.sqrt(np.linalg.eigvalsh(estimator.shape_matrix)[-1]) > 0.1  # the ellipsoid alone stalls


def test_reference_step_in_one_dimension():
    # prior [-1, 1]: P0 = 1; y = 0.5 with gamma = 0.1 leaves the dead zone by 0.4.
    estimator = SetMembershipEstimator(1, noise_bound=0.1, prior=Box([-1.0], [1.0]))
    estimator.update([[1.0]], [0.5])
    # s = 1 - 0.4^2 = 0.84, c = 0.4, P = 0.84 (1 - (1 - 0.1/0.5)) = 0.168
    # (up to the 1e-12 relative widening of gamma against rounding in the targets)
    assert estimator.ellipsoid_center == pytest.approx([0.4], rel=1e-11)
    assert estimator.shape_matrix == pytest.approx(np.array([[0.168]]), rel=1e-11)
    assert estimator.ellipsoid().contains([0.5])
    # the box: [-1, 1] with the ellipsoid's interval 0.4 +- sqrt(0.168) = [-0.0099, 0.8099],
    # then the strip [0.4, 0.6] (both rounded outward by ~1e-9 relative at most)
    box = estimator.parameter_set()
    assert 0.4 - 1e-9 <= box.low[0] <= 0.4 and 0.6 <= box.high[0] <= 0.6 + 1e-9
    # estimate: the box centre 0.5 (half-width 0.1) beats the ellipsoid centre 0.4 (farthest corner 0.2)
    assert estimator.estimate == pytest.approx([0.5], rel=1e-9)
    assert 0.1 <= estimator.radius <= 0.1 + 1e-8


def test_dead_zone_leaves_the_ellipsoid_unchanged_but_the_box_uses_the_row():
    estimator = SetMembershipEstimator(2, noise_bound=[0.5, 0.5], prior=Box([-1.0, -1.0], [1.0, 1.0]))
    center, shape = estimator.ellipsoid_center, estimator.shape_matrix
    estimator.update(np.eye(2), [0.5, -0.2])  # prediction errors within the bound
    assert np.array_equal(estimator.ellipsoid_center, center)
    assert np.array_equal(estimator.shape_matrix, shape)
    # the strips |0.5 - t1| <= 0.5, |-0.2 - t2| <= 0.5 still cut the prior box
    box = estimator.parameter_set()
    np.testing.assert_allclose(box.low, [0.0, -0.7], rtol=0, atol=1e-11)
    np.testing.assert_allclose(box.high, [1.0, 0.3], rtol=0, atol=1e-11)
    assert box.contains([0.0, -0.7]) and box.contains([1.0, 0.3])  # rounded outward
    assert estimator.nsamples == 1


def test_inconsistent_data_raise_and_keep_the_state():
    estimator = SetMembershipEstimator(1, noise_bound=0.1, prior=Box([-1.0], [1.0]))
    estimator.update([[1.0]], [0.5])
    state = (estimator.estimate, estimator.radius, estimator.parameter_set())
    with pytest.raises(EmptySetError, match=r"inconsistent with the prior box and noise_bound"):
        estimator.update([[1.0]], [5.0])
    assert np.array_equal(estimator.estimate, state[0])
    assert estimator.radius == state[1] and estimator.parameter_set() == state[2]
    assert estimator.nsamples == 1


def test_to_dict_reports_the_state():
    estimator = SetMembershipEstimator(2, noise_bound=0.1, prior=Box([-1.0, -1.0], [1.0, 1.0]))
    estimator.update(np.eye(2), [0.5, -0.5])
    state = estimator.to_dict()
    assert state["nsamples"] == 1
    assert state["estimate"] == estimator.estimate.tolist() and state["radius"] == estimator.radius
    assert state["parameter_set"] == estimator.parameter_set().to_dict()
    assert np.allclose(state["shape_matrix"], estimator.shape_matrix)


def test_returned_arrays_are_copies():
    gamma = np.array([0.1, 0.2])
    estimator = SetMembershipEstimator(2, noise_bound=gamma, prior=Box([-1.0, -1.0], [1.0, 1.0]))
    gamma[:] = 100.0  # must not widen the dead zone
    estimator.update(np.eye(2), [0.9, 0.9])
    assert estimator.radius < np.sqrt(2) * (1 + OUTWARD_ROUNDING)
    estimate = estimator.estimate
    estimate[:] = 7.0
    assert not np.any(estimator.estimate == 7.0)


def test_bad_input_is_rejected():
    prior = Box([-1.0, -1.0], [1.0, 1.0])
    with pytest.raises(InputError, match=r"nparams must be a positive integer"):
        SetMembershipEstimator(0, noise_bound=0.1, prior=prior)
    with pytest.raises(InputError, match=r"prior must be a Box, got tuple"):
        SetMembershipEstimator(2, noise_bound=0.1, prior=(0, 1))
    with pytest.raises(DimensionError, match=r"prior must have dimension 3 \(nparams\), got 2"):
        SetMembershipEstimator(3, noise_bound=0.1, prior=prior)
    with pytest.raises(InputError, match=r"noise_bound must be > 0 in every row, got \[0.1, 0.0\]"):
        SetMembershipEstimator(2, noise_bound=[0.1, 0.0], prior=prior)
    with pytest.raises(NonFiniteError, match=r"noise_bound contains NaN"):
        SetMembershipEstimator(2, noise_bound=np.nan, prior=prior)
    with pytest.raises(DimensionError, match=r"noise_bound must be a scalar or have shape \(p,\), got shape \(1, 2\)"):
        SetMembershipEstimator(2, noise_bound=[[0.1, 0.1]], prior=prior)
    estimator = SetMembershipEstimator(2, noise_bound=[0.1, 0.2, 0.3], prior=prior)
    with pytest.raises(DimensionError, match=r"noise_bound has shape \(3,\) but the sample has 2 rows"):
        estimator.update(np.eye(2), [0.0, 0.0])
    with pytest.raises(DimensionError, match=r"regressor must have shape \(p, 2\), got shape \(3, 3\)"):
        estimator.update(np.eye(3), np.zeros(3))
    with pytest.raises(DimensionError, match=r"target must have shape \(3,\), got shape \(2,\)"):
        estimator.update(np.ones((3, 2)), np.zeros(2))
    with pytest.raises(NonFiniteError, match=r"target contains NaN"):
        estimator.update(np.ones((3, 2)), [0.0, np.nan, 0.0])
    assert estimator.nsamples == 0


def test_degenerate_prior_side_is_supported_but_has_no_ellipsoid():
    estimator = SetMembershipEstimator(2, noise_bound=0.1, prior=Box([0.5, -1.0], [0.5, 1.0]))
    estimator.update([[1.0, 1.0]], [1.2])
    box = estimator.parameter_set()
    assert box.low[0] == 0.5 and box.high[0] == 0.5
    assert box.contains([0.5, 0.7])
    with pytest.raises(InputError, match=r"ellipsoid is degenerate"):
        estimator.ellipsoid()
