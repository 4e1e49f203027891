"""Set-membership estimation under bounded noise: soundness, monotone radius, bad input."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.models import Box, DimensionError, EmptySetError, InputError, NonFiniteError, SetMembershipEstimator
from minimaxplan.models.set_membership import OUTWARD_ROUNDING


def _noise(rng, mode, bounds):
    if mode == "uniform":
        return rng.uniform(-bounds, bounds)
    if mode == "extreme":  # every row at +-bound: the strips touch theta*
        return bounds * rng.choice([-1.0, 1.0], size=bounds.shape)
    if mode == "mixed":
        return np.where(rng.random(bounds.shape) < 0.5, rng.uniform(-bounds, bounds), bounds * np.sign(rng.normal(size=bounds.shape)))
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
            offset = np.linalg.solve(np.linalg.cholesky(estimator.shape_matrix), theta - estimator.estimate)
            assert offset @ offset <= 1 + 1e-6
        previous_radius, previous_box = estimator.radius, box
    assert estimator.nsamples == n


def test_the_estimator_learns_under_uniform_noise():
    """Reference run (fixed seed, measured: radius 1.414 -> 0.284, error 4e-4 after 400 samples).

    The estimate converges well inside the noise level, while the bound stalls once the
    centre's prediction errors stay in the dead zone (see the class notes).
    """
    rng = np.random.default_rng(1)
    theta = np.array([0.3, -0.7])
    estimator = SetMembershipEstimator(2, noise_bound=0.05, prior=Box([-1.0, -1.0], [1.0, 1.0]))
    initial = estimator.radius
    for _ in range(400):
        E = rng.normal(size=(2, 2))
        estimator.update(E, E @ theta + rng.uniform(-0.05, 0.05, size=2))
    assert estimator.radius < initial / 4
    assert np.linalg.norm(estimator.estimate - theta) < 0.01
    assert np.linalg.norm(estimator.estimate - theta) <= estimator.radius
    assert np.all(estimator.parameter_set().radius < 0.3)


def test_reference_step_in_one_dimension():
    # prior [-1, 1]: P0 = 1; y = 0.5 with gamma = 0.1 leaves the dead zone by 0.4.
    estimator = SetMembershipEstimator(1, noise_bound=0.1, prior=Box([-1.0], [1.0]))
    estimator.update([[1.0]], [0.5])
    # s = 1 - 0.4^2 = 0.84, c = 0.4, P = 0.84 (1 - (1 - 0.1/0.5)) = 0.168
    # (up to the 1e-12 relative widening of gamma against rounding in the targets)
    assert estimator.estimate == pytest.approx([0.4], rel=1e-11)
    assert estimator.shape_matrix == pytest.approx(np.array([[0.168]]), rel=1e-11)
    assert estimator.radius == pytest.approx(np.sqrt(0.168), rel=2e-9)
    box = estimator.parameter_set()
    # the bounding interval, rounded outward by at most 1e-9 (|c| + half width)
    exact_low, exact_high = 0.4 - np.sqrt(0.168), 0.4 + np.sqrt(0.168)
    assert exact_low - 1e-9 <= box.low[0] <= exact_low
    assert exact_high <= box.high[0] <= exact_high + 2e-9
    assert estimator.ellipsoid().contains([0.5])


def test_dead_zone_leaves_the_state_unchanged():
    estimator = SetMembershipEstimator(2, noise_bound=[0.5, 0.5], prior=Box([-1.0, -1.0], [1.0, 1.0]))
    before = (estimator.estimate, estimator.shape_matrix, estimator.radius, estimator.parameter_set())
    estimator.update(np.eye(2), [0.5, -0.2])  # prediction errors within the bound
    assert np.array_equal(estimator.estimate, before[0])
    assert np.array_equal(estimator.shape_matrix, before[1])
    assert estimator.radius == before[2]
    assert estimator.parameter_set() == before[3]
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
