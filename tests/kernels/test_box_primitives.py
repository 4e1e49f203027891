"""The box primitives: numpy's NaN-propagating min/max, and the one box-disc gap against brute force."""

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numba import njit

from minimaxplan.kernels import box_gap_sq, box_gaps_sq, maximum, minimum

specials = st.sampled_from([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 1e-308, -2.5])
floats = st.one_of(specials, st.floats(allow_nan=True, allow_infinity=True))


@njit
def _compiled(a, b):
    return maximum(a, b), minimum(a, b)


@given(floats, floats)
def test_maximum_and_minimum_are_numpys(a, b):
    for got, want in zip(_compiled(a, b), (np.maximum(a, b), np.minimum(a, b))):
        assert (np.isnan(got) and np.isnan(want)) or got == want
    assert np.isnan(maximum.py_func(np.nan, 1.0)) and np.isnan(minimum.py_func(1.0, np.nan))


def _brute_force_gap_sq(lower, upper, other_lower, other_upper, n=13):
    """The smallest squared distance between two grids of the boxes (exact when the closest points are on them)."""
    grid = [
        np.array(list(itertools.product(*[np.linspace(a, b, n) for a, b in zip(lo, hi)])))
        for lo, hi in ((lower, upper), (other_lower, other_upper))
    ]
    diff = grid[0][:, None, :] - grid[1][None, :, :]
    return np.min(np.einsum("...i,...i->...", diff, diff))


@given(st.integers(0, 2**31 - 1))
def test_box_gap_is_the_distance_between_the_boxes(seed):
    rng = np.random.default_rng(seed)
    # corners on the quarter grid and widths of at most 4 quarters: the 13-point grids
    # of the boxes hold every quarter point, among them the closest points of the boxes
    lower = rng.integers(-8, 8, 2) / 4
    upper = lower + rng.integers(0, 5, 2) / 4
    other_lower = rng.integers(-8, 8, 2) / 4
    other_upper = other_lower + rng.integers(0, 5, 2) / 4 * (rng.random() < 0.7)  # sometimes a point
    gap = box_gap_sq.py_func(*lower, *upper, *other_lower, *other_upper)
    assert gap == pytest.approx(_brute_force_gap_sq(lower, upper, other_lower, other_upper), abs=1e-12)
    # symmetric, zero exactly when the boxes meet
    assert gap == box_gap_sq.py_func(*other_lower, *other_upper, *lower, *upper)
    meets = np.all(lower <= other_upper) and np.all(other_lower <= upper)
    assert (gap == 0.0) == meets


def test_box_gap_of_a_disc_touching_an_edge_and_a_corner():
    # box [0, 1]^2; a centre at (0.5, 1.25) is 0.25 above the top edge, (1.3, 1.4) is 0.5 from the corner
    assert box_gap_sq.py_func(0.0, 0.0, 1.0, 1.0, 0.5, 1.25, 0.5, 1.25) == 0.0625
    assert box_gap_sq.py_func(0.0, 0.0, 1.0, 1.0, 1.3, 1.4, 1.3, 1.4) == pytest.approx(0.25, abs=1e-15)
    assert np.isnan(box_gap_sq.py_func(np.nan, 0.0, 1.0, 1.0, 0.5, 0.5, 0.5, 0.5))


def test_batched_gaps_equal_the_scalar_gap_bit_for_bit():
    rng = np.random.default_rng(4)
    lower = rng.uniform(-3, 3, (200, 2))
    upper = lower + rng.uniform(0, 1, (200, 2))
    other_lower = rng.uniform(-3, 3, (200, 2))
    other_upper = other_lower + rng.uniform(0, 1, (200, 2)) * (rng.random((200, 1)) < 0.5)
    out = np.empty(200)
    box_gaps_sq(lower, upper, other_lower, other_upper, out)
    scalar = [box_gap_sq.py_func(*lower[k], *upper[k], *other_lower[k], *other_upper[k]) for k in range(200)]
    assert out.tobytes() == np.array(scalar).tobytes()
