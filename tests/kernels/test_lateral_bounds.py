"""The compiled bounds of the bicycle's nonlinear terms: semantics, exactness and soundness.

`minimaxplan.kernels.lateral_bounds` claims numpy's NaN and signed-zero semantics for its
minima and maxima (the forecast's boxes stay the same bits as the numpy expressions they
replaced, which `benchmarks/compare_forecast_commits.py` checks), exact cosine ranges, and
a vertex box that contains the sector factors of every state of a box. The remainder and
footprint bounds are tested against the bicycle and against sampled rectangles in
`tests/scenarios/test_traffic_models.py`, the radius in `tests/scenarios/test_lateral_contraction.py`.
"""

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.kernels import lateral_bounds as lb
from minimaxplan.models.errors import DimensionError
from minimaxplan.scenarios.traffic_models import footprint_box, lateral_remainder
from minimaxplan.scenarios.vehicles import DEFAULT_VEHICLE

SPECIAL = (0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan)


def _bits(x) -> int:
    return int(np.float64(x).view(np.int64))


@pytest.mark.parametrize(
    "kernel, ufunc",
    [(lb._min, np.minimum), (lb._max, np.maximum), (lb._fmin, np.fmin), (lb._fmax, np.fmax)],
    ids=["minimum", "maximum", "fmin", "fmax"],
)
def test_minima_and_maxima_are_numpys_to_the_bit(kernel, ufunc):
    """Every pair of special values (signed zeros, infinities, NaN) as numpy's vector loop gives it."""
    pairs = list(itertools.product(SPECIAL, SPECIAL))
    first = np.array([a for a, _ in pairs] * 4)  # long enough for numpy's vector loop
    second = np.array([b for _, b in pairs] * 4)
    expected = ufunc(first, second)
    for (a, b), want in zip(pairs, expected):
        got = kernel(a, b)
        if np.isnan(want):
            assert np.isnan(got), (a, b, got)
        else:
            assert _bits(got) == _bits(want), (a, b, got, want)


@given(lo=st.floats(-40, 40), width=st.floats(0, 9))
def test_cos_range_is_exact(lo, width):
    """Every sampled cosine inside; the range reached by the samples to their spacing."""
    low, high = lb._cos_range(lo, lo + width)
    values = np.cos(np.linspace(lo, lo + width, 8001))
    assert low <= values.min() and high >= values.max()
    assert low >= values.min() - 1e-6 and high <= values.max() + 1e-6


def test_cos_range_propagates_nan():
    assert all(np.isnan(lb._cos_range(np.nan, 1.0)))


@given(
    e=st.tuples(st.floats(-4, 4), st.floats(0, 2)),
    chi=st.tuples(st.floats(-1.2, 1.2), st.floats(0, 0.8)),
    v=st.tuples(st.floats(0.2, 30), st.floats(0, 10)),
    b1=st.tuples(st.floats(0, 3), st.floats(0, 2)),
    q=st.tuples(st.floats(-0.5, 1.0), st.floats(0, 1.0)),
    seed=st.integers(0, 2**31),
)
def test_contraction_vertex_box_contains_every_states_factors(e, chi, v, b1, q, seed):
    """s1 = sinc(chi + beta), s2 = sinc(beta), g = beta / delta_r, v, b1 and q of sampled states lie in the box."""
    rng = np.random.default_rng(seed)
    length, dmax = DEFAULT_VEHICLE.length, DEFAULT_VEHICLE.max_steering
    bounds = [np.array([x]) for pair in (e, chi, v, b1, q) for x in (pair[0], pair[0] + pair[1])]
    lower, upper = lb.contraction_vertex_box(length, dmax, *bounds)
    k = 400
    es, cs, vs, bs, qs = (rng.uniform(lo[0], hi[0], k) for lo, hi in zip(bounds[::2], bounds[1::2]))
    # the corner of largest |e| and |chi| (where the steering is largest)
    es[0] = bounds[0][0] if abs(bounds[0][0]) > abs(bounds[1][0]) else bounds[1][0]
    cs[0] = bounds[2][0] if abs(bounds[2][0]) > abs(bounds[3][0]) else bounds[3][0]
    delta_r = -(length / vs) * (bs * cs + qs * es)
    beta = np.arctan(0.5 * np.tan(np.clip(delta_r, -dmax, dmax)))
    with np.errstate(invalid="ignore", divide="ignore"):
        s1 = np.where(cs + beta != 0, np.sin(cs + beta) / (cs + beta), 1.0)
        s2 = np.where(beta != 0, np.sin(beta) / beta, 1.0)
        g = np.where(delta_r != 0, beta / delta_r, 0.5)
    sampled = np.stack([s1, s2, g, vs, bs, qs], axis=1)
    tol = 1e-12
    assert np.all(sampled >= lower - tol) and np.all(sampled <= upper + tol)


def test_metric_radius_bounds_is_the_largest_corner_norm():
    rng = np.random.default_rng(5)
    n = 200
    a = rng.normal(size=(n, 2, 2))
    metrics = a @ np.swapaxes(a, 1, 2) + 0.1 * np.eye(2)
    lo = rng.normal(size=(n, 2))
    hi = lo + rng.random((n, 2)) * 3
    rho = lb.metric_radius_bounds(metrics, lo, hi, 1e-9)
    corners = np.stack([lo, np.stack([lo[:, 0], hi[:, 1]], 1), np.stack([hi[:, 0], lo[:, 1]], 1), hi], 1)
    norms = np.sqrt(np.einsum("nki,nij,nkj->nk", corners, metrics, corners)).max(axis=1)
    # the largest corner norm, rounded up by the margin, to a few roundings
    assert np.all(rho >= norms) and np.allclose(rho, norms * (1 + 1e-9), rtol=1e-12)
    empty = lb.metric_radius_bounds(metrics[:1], hi[:1], lo[:1] - 1.0, 1e-9)
    assert np.isinf(empty[0])


def test_kernels_refuse_rows_of_different_lengths():
    with pytest.raises(ValueError, match="metric_radius_bounds"):
        lb.metric_radius_bounds(np.tile(np.eye(2), (3, 1, 1)), np.zeros((2, 2)), np.ones((2, 2)), 1e-9)
    with pytest.raises(ValueError, match="footprint_bounds"):
        lb.footprint_bounds(np.zeros((2, 2)), np.zeros((2, 2)), np.zeros(3), np.zeros(3), np.zeros(4), 1.0, 1e-9)
    z = np.zeros(2)
    with pytest.raises(ValueError, match="lateral_remainder_bounds"):
        lb.lateral_remainder_bounds(z, z, z, z, z + 1, z + 1, z, z, z, z, np.zeros(1), np.zeros(1), 0.1, 5.0, 0.8, 1e-9)
    short = np.zeros(1)
    with pytest.raises(ValueError, match="lateral_remainder_bounds"):
        lb.lateral_remainder_bounds(
            z, z, z, z, z + 1, z + 1, z, z, z, short, np.empty(0), np.empty(0), 0.1, 5.0, 0.8, 1e-9
        )
    with pytest.raises(ValueError, match="contraction_vertex_box"):
        lb.contraction_vertex_box(5.0, 0.8, z, z, z, z, z + 1, z + 1, z, z, z, short)
    with pytest.raises(ValueError, match="metric_radius_bounds"):
        lb.metric_radius_bounds(np.zeros((2, 3, 3)), np.zeros((2, 2)), np.ones((2, 2)), 1e-9)


def test_the_wrappers_broadcast_as_before():
    """Scalars and (..., 2) centres broadcast against headings, as the numpy versions did."""
    one = footprint_box(np.array([1.0, 2.0]), np.array([1.5, 2.0]), 0.0, 0.3)
    many = footprint_box(np.array([1.0, 2.0]), np.array([1.5, 2.0]), np.zeros(3), np.full(3, 0.3))
    assert one.shape == (4,) and many.shape == (3, 4) and np.array_equal(many[1], one)
    grid = footprint_box(np.zeros((2, 3, 2)), np.ones((2, 3, 2)), np.zeros((2, 3)), np.ones((2, 3)))
    assert grid.shape == (2, 3, 4)
    with pytest.raises(DimensionError, match="center_lower"):
        footprint_box(np.zeros(3), np.zeros(3), 0.0, 0.0)
    r_e, r_c, delta, angle = lateral_remainder((0.1, 0.2), (0.0, 0.05), (10.0, 12.0), (1.0, 1.2), (0.01, 0.02), 0.1)
    assert all(np.shape(x) == () for pair in (r_e, r_c, delta, angle) for x in pair)
    with pytest.raises(DimensionError, match="psi_lower"):
        footprint_box(np.zeros((3, 2)), np.ones((3, 2)), np.zeros(4), np.ones(4))
    with pytest.raises(DimensionError, match=r"q \(3,\)"):
        lateral_remainder((0.1, 0.2), (0.0, 0.05), (10.0, 12.0), (1.0, 1.2), (np.zeros(3), np.ones(2)), 0.1)
    assert r_e[0] <= r_e[1] and r_c[0] <= r_c[1] and delta[0] <= delta[1]
