"""Confidence ellipsoids: reference values, coverage, online == batch, bad input."""

import numpy as np
import pytest
from hypothesis import assume, event, given
from hypothesis import strategies as st
from scipy.stats import binomtest, chi2

from minimaxplan.models import (
    ConfidenceEllipsoidEstimator,
    DimensionError,
    Ellipsoid,
    InputError,
    NonFiniteError,
    confidence_ellipsoid,
)

OPTIONS = dict(sigma=0.5, lam=1.0, delta=0.1, bound=1.0)


# ------------------------------------------------------------------ reference values
def test_reference_values_one_parameter():
    E = np.array([[[1.0]], [[2.0]]])
    y = np.array([[1.0], [2.0]])
    ell = confidence_ellipsoid(E, y, sigma=1.0, lam=1.0, delta=0.1, bound=2.0)
    # G = 1 + 4 + 1, b = 1 + 4, beta = sqrt(2 log(sqrt(6) / 0.1)) + sqrt(1) * 2
    assert ell.gramian == pytest.approx(np.array([[6.0]]), rel=1e-15)
    assert ell.center == pytest.approx([5.0 / 6.0], rel=1e-15)
    assert ell.radius == pytest.approx(np.sqrt(2 * np.log(np.sqrt(6.0) / 0.1)) + 2.0, rel=1e-14)


def test_no_data_gives_the_prior_ball():
    ell = confidence_ellipsoid(np.zeros((0, 2, 3)), np.zeros((0, 2)), sigma=1.0, lam=4.0, delta=0.05, bound=1.5)
    assert np.array_equal(ell.center, np.zeros(3))
    assert np.allclose(ell.gramian, 4.0 * np.eye(3), rtol=0, atol=0)
    assert ell.radius == pytest.approx(np.sqrt(2 * np.log(1 / 0.05)) + 2.0 * 1.5, rel=1e-14)


@given(seed=st.integers(0, 2**32 - 1), d=st.integers(1, 4), p=st.integers(1, 3), n=st.integers(1, 30))
def test_batch_fit_matches_the_textbook_formula(seed, d, p, n):
    rng = np.random.default_rng(seed)
    E = rng.normal(size=(n, p, d))
    y = rng.normal(size=(n, p))
    sigma, lam, delta, bound = 0.7, 0.3, 0.2, 2.0
    ell = confidence_ellipsoid(E, y, sigma=sigma, lam=lam, delta=delta, bound=bound)
    G = sum(E[k].T @ E[k] for k in range(n)) / sigma**2 + lam * np.eye(d)
    b = sum(E[k].T @ y[k] for k in range(n)) / sigma**2
    beta = np.sqrt(2 * np.log(np.sqrt(np.linalg.det(G)) / (delta * np.sqrt(lam**d)))) + np.sqrt(lam) * bound
    assert np.allclose(ell.gramian, G, rtol=1e-12, atol=0)
    assert np.allclose(ell.center, np.linalg.solve(G, b), rtol=1e-9, atol=1e-12)
    assert ell.radius == pytest.approx(beta, rel=1e-10)


# ------------------------------------------------------------------------- coverage
def _coverage_trials(rng, ntrials, *, noise, radius_of):
    """Fit `ntrials` random problems; return the number whose set misses theta*."""
    d, p, sigma, lam, bound = 3, 2, 0.5, 1.0, 1.0
    lengths = rng.integers(1, 41, size=ntrials)
    misses = 0
    for n in lengths:
        direction = rng.normal(size=d)
        # ||theta*|| <= bound, half of them on the sphere (the worst case of the bias term)
        theta = direction / np.linalg.norm(direction) * bound * (1.0 if rng.random() < 0.5 else rng.random())
        E = rng.normal(size=(n, p, d)) * rng.uniform(0.2, 3.0)
        if noise == "gaussian":
            w = sigma * rng.normal(size=(n, p))
        else:  # Rademacher +-sigma: sigma-sub-Gaussian with the largest possible variance
            w = sigma * rng.choice([-1.0, 1.0], size=(n, p))
        ell = confidence_ellipsoid(E, E @ theta + w, sigma=sigma, lam=lam, delta=0.1, bound=bound)
        q = (theta - ell.center) @ ell.gramian @ (theta - ell.center)
        misses += bool(q > radius_of(ell, d) ** 2)
    return misses


@pytest.mark.parametrize("noise", ["gaussian", "rademacher"])
def test_confidence_ellipsoid_holds_theta_with_probability_one_minus_delta(noise):
    """Over 400 random problems the miss rate must not be significantly above delta.

    One-sided binomial test: it rejects (the test fails) when the observed number of
    misses would have probability < 1% if the true miss rate were delta.
    """
    rng = np.random.default_rng(20111212 + len(noise))
    ntrials, delta = 400, 0.1
    misses = _coverage_trials(rng, ntrials, noise=noise, radius_of=lambda ell, d: ell.radius)
    assert binomtest(misses, ntrials, delta, alternative="greater").pvalue >= 0.01, (misses, ntrials)


def test_the_coverage_check_has_power():
    """The same binomial check rejects a set that covers only ~75% of the time.

    Without ridge, ``(c - theta)^T G (c - theta)`` is chi-square with d degrees of
    freedom for Gaussian noise; the small ridge here barely changes that, so the radius
    ``sqrt(chi2.ppf(0.75, d))`` misses about 25% of the time (97 of 400 with this
    seed): the check must detect that.
    """
    rng = np.random.default_rng(7)
    ntrials, delta = 400, 0.1
    misses = _coverage_trials(rng, ntrials, noise="gaussian", radius_of=lambda ell, d: np.sqrt(chi2.ppf(0.75, d)))
    assert binomtest(misses, ntrials, delta, alternative="greater").pvalue < 0.01, (misses, ntrials)


# -------------------------------------------------------------------- online == batch
@given(
    seed=st.integers(0, 2**32 - 1),
    d=st.integers(2, 5),  # d = 1 and N = 0 are trivially conditioned: see the tests above and below
    p=st.integers(1, 3),
    n=st.integers(2, 60),
    log_sigma=st.floats(-2, 0.5),
    log_lam=st.floats(-6, 1),
    log_spread=st.floats(0, 9),
)
def test_online_estimator_equals_batch_fit(seed, d, p, n, log_sigma, log_lam, log_spread):
    """Equal to 1e-9 relative while cond(G) <= 1e8; ``log_spread`` sets the conditioning.

    The regressors' singular values span ``10^-log_spread/2 .. 1`` in a random basis, so
    that cond(G) ranges over 1 .. 1e9 (those above 1e8 are discarded).
    """
    rng = np.random.default_rng(seed)
    sigma, lam = 10.0**log_sigma, 10.0**log_lam
    basis, _ = np.linalg.qr(rng.normal(size=(d, d)))
    singular_values = 10.0 ** (-(log_spread / 2) * np.linspace(0, 1, d)) * 10.0 ** rng.uniform(-1, 2)
    E = (rng.normal(size=(n, p, d)) * singular_values) @ basis.T
    y = E @ rng.normal(size=d) + sigma * rng.normal(size=(n, p))
    opts = dict(sigma=sigma, lam=lam, delta=0.05, bound=2.0)
    gramian = np.einsum("npi,npj->ij", E, E) / sigma**2 + lam * np.eye(d)
    condition = np.linalg.cond(gramian)
    assume(condition <= 1e8)
    event(f"cond(G) ~ 1e{int(np.log10(condition))}")
    batch = confidence_ellipsoid(E, y, **opts)
    online = ConfidenceEllipsoidEstimator(d, **opts)
    for k in range(n):
        online.update(E[k], y[k])
    fit = online.ellipsoid()
    assert online.nsamples == n
    assert np.linalg.norm(fit.gramian - batch.gramian) <= 1e-9 * np.linalg.norm(batch.gramian)
    assert np.linalg.norm(fit.center - batch.center) <= 1e-9 * np.linalg.norm(batch.center) + 1e-300
    assert abs(fit.radius - batch.radius) <= 1e-9 * batch.radius


def test_online_radius_survives_a_tiny_ridge_followed_by_informative_data():
    """A well-conditioned end (cond(G) ~ 1e3) after a wildly ill-conditioned start.

    Sherman-Morrison on ``G^-1`` with the determinant lemma misses the batch radius by
    1.3e-7 relative on exactly this data (measured while choosing the update); the
    Cholesky update must stay within 1e-9.
    """
    rng = np.random.default_rng(0)
    E = rng.normal(size=(30, 2, 2)) * np.array([1.0, 30.0])
    y = rng.normal(size=(30, 2))
    opts = dict(sigma=0.01, lam=1e-6, delta=0.1, bound=1.0)
    online = ConfidenceEllipsoidEstimator(2, **opts)
    for k in range(30):
        online.update(E[k], y[k])
    batch = confidence_ellipsoid(E, y, **opts)
    G = np.einsum("npi,npj->ij", E, E) / 0.01**2 + 1e-6 * np.eye(2)
    beta = np.sqrt(np.linalg.slogdet(G)[1] - 2 * np.log(1e-6) + 2 * np.log(10.0)) + 1e-3
    assert np.linalg.cond(G) < 1e4
    assert abs(online.radius() - batch.radius) <= 1e-9 * batch.radius
    assert abs(online.radius() - beta) <= 1e-9 * beta
    assert np.linalg.norm(online.center() - batch.center) <= 1e-9 * np.linalg.norm(batch.center)


def test_online_estimator_accepts_single_rows_and_scalar_targets():
    rng = np.random.default_rng(3)
    E = rng.normal(size=(10, 1, 2))
    y = rng.normal(size=(10, 1))
    online = ConfidenceEllipsoidEstimator(2, **OPTIONS)
    for k in range(10):
        online.update(E[k, 0], float(y[k, 0]))
    batch = confidence_ellipsoid(E, y, **OPTIONS)
    assert np.allclose(online.ellipsoid().center, batch.center, rtol=1e-12, atol=0)
    assert online.nsamples == 10 and online.nparams == 2


def test_to_dict_reports_the_state():
    online = ConfidenceEllipsoidEstimator(2, **OPTIONS)
    online.update(np.eye(2), [0.1, 0.2])
    assert online.to_dict() == {"nsamples": 1, "ellipsoid": online.ellipsoid().to_dict()}
    assert repr(online) == "ConfidenceEllipsoidEstimator(nparams=2, nsamples=1)"


def test_online_update_does_not_alias_or_modify_callers_arrays():
    E = np.array([[1.0, 2.0], [0.5, -1.0]])
    y = np.array([0.3, 0.1])
    E0, y0 = E.copy(), y.copy()
    online = ConfidenceEllipsoidEstimator(2, **OPTIONS)
    online.update(E, y)
    first = online.ellipsoid()
    E[:] = 100.0
    y[:] = 100.0
    assert np.array_equal(online.ellipsoid().center, first.center)
    assert isinstance(first, Ellipsoid)
    np.testing.assert_array_equal(E0, np.array([[1.0, 2.0], [0.5, -1.0]]))
    np.testing.assert_array_equal(y0, np.array([0.3, 0.1]))


# -------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "name, value, error, message",
    [
        ("sigma", 0.0, InputError, r"sigma must be > 0, got 0.0"),
        ("sigma", np.nan, NonFiniteError, r"sigma must be finite"),
        ("lam", -1.0, InputError, r"lam must be > 0"),
        ("delta", 1.0, InputError, r"delta must lie in \(0, 1\), got 1.0"),
        ("delta", 0.0, InputError, r"delta must be > 0"),
        ("bound", "big", InputError, r"bound must be a real scalar"),
    ],
)
def test_bad_options_are_rejected(name, value, error, message):
    opts = dict(OPTIONS, **{name: value})
    with pytest.raises(error, match=message):
        confidence_ellipsoid(np.ones((1, 1, 1)), np.ones((1, 1)), **opts)
    with pytest.raises(error, match=message):
        ConfidenceEllipsoidEstimator(1, **opts)


def test_bad_shapes_and_values_are_rejected():
    with pytest.raises(DimensionError, match=r"regressors must be 3-dimensional, got shape \(2, 3\)"):
        confidence_ellipsoid(np.ones((2, 3)), np.ones((2, 1)), **OPTIONS)
    with pytest.raises(
        DimensionError,
        match=r"targets must have shape \(4, 2\) to match regressors of shape \(4, 2, 3\), got shape \(4, 3\)",
    ):
        confidence_ellipsoid(np.ones((4, 2, 3)), np.ones((4, 3)), **OPTIONS)
    with pytest.raises(
        DimensionError, match=r"regressors must have shape \(N, p, d\) with p, d >= 1, got shape \(4, 2, 0\)"
    ):
        confidence_ellipsoid(np.ones((4, 2, 0)), np.ones((4, 2)), **OPTIONS)
    with pytest.raises(NonFiniteError, match=r"targets contains NaN or infinite entries"):
        confidence_ellipsoid(np.ones((1, 1, 1)), [[np.inf]], **OPTIONS)
    online = ConfidenceEllipsoidEstimator(3, **OPTIONS)
    with pytest.raises(DimensionError, match=r"regressor must have shape \(p, 3\), got shape \(2, 2\)"):
        online.update(np.ones((2, 2)), np.ones(2))
    with pytest.raises(DimensionError, match=r"target must have shape \(2,\), got shape \(3,\)"):
        online.update(np.ones((2, 3)), np.ones(3))
    with pytest.raises(NonFiniteError, match=r"regressor contains NaN"):
        online.update([[np.nan, 0.0, 0.0]], [1.0])
    assert online.nsamples == 0
    for bad in (0, -2, 2.0, True):
        with pytest.raises(InputError, match=r"nparams must be a positive integer"):
            ConfidenceEllipsoidEstimator(bad, **OPTIONS)


def test_numerically_singular_gramian_is_refused_with_a_clear_error():
    E = np.array([[[1e8, 1e8]], [[1e8, 1e8]]])
    with pytest.raises(InputError, match=r"Gramian is numerically singular .* increase lam"):
        confidence_ellipsoid(E, np.ones((2, 1)), sigma=1.0, lam=1e-9, delta=0.1, bound=1.0)
    online = ConfidenceEllipsoidEstimator(2, sigma=1.0, lam=1e-9, delta=0.1, bound=1.0)
    online.update(E[0], [1.0])
    with pytest.raises(InputError, match=r"Gramian is numerically singular"):
        online.ellipsoid()
