"""The forecast's compiled interval arithmetic against sampling, vertex enumeration and the SVD.

Each kernel claims a box (or a factor) that contains every value of a set and is attained
by it: sampled points of the sets must land inside, and enumerating the corners and
vertices with numpy's matrix products (or its SVD) must give the same bounds to rounding.
Matrices are random and not Metzler (entries of either sign, zeros), boxes reach 1e3 and
down to points.
"""

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.kernels.vertex_bounds import contraction_vertex_factor, interval_matvec, vertex_bound

#: Relative slack of a comparison with numpy's products in another order (a few roundings).
REL = 1e-12


def _scaled(rng, shape, zero_share=0.2):
    """Normal entries of random magnitude, with some exact zeros (the sign of M's entries decides the product)."""
    out = rng.normal(size=shape) * 10.0 ** rng.uniform(-3, 3, size=shape)
    out[rng.random(shape) < zero_share] = 0.0
    return out


def _boxes(rng, n, d):
    lower = _scaled(rng, (n, d))
    width = rng.random((n, d)) * 10.0 ** rng.uniform(-3, 3, size=(n, d))
    width[rng.random((n, d)) < 0.2] = 0.0  # point boxes
    return lower, lower + width


def _corners(lower, upper):
    """(2^d, d) corners of one box."""
    return np.array(list(itertools.product(*zip(lower, upper))))


def _close(got, want, scale):
    return np.all(np.abs(got - want) <= REL * (1.0 + scale))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 12))
def test_interval_matvec_is_the_hull_of_the_corner_products(seed, n):
    rng = np.random.default_rng(seed)
    m = _scaled(rng, (n, 2, 2))
    lower, upper = _boxes(rng, n, 2)
    lo, hi = interval_matvec(m, lower, upper)
    for r in range(n):
        images = _corners(lower[r], upper[r]) @ m[r].T  # a linear map's extremes over a box are at corners
        scale = np.abs(m[r]).sum() * np.abs(np.concatenate([lower[r], upper[r]])).max()
        assert _close(lo[r], images.min(axis=0), scale) and _close(hi[r], images.max(axis=0), scale)
        inside = lower[r] + rng.random((64, 2)) * (upper[r] - lower[r])
        values = inside @ m[r].T
        assert np.all(values >= lo[r] - REL * (1 + scale)) and np.all(values <= hi[r] + REL * (1 + scale))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 12), shared=st.booleans())
def test_vertex_bound_contains_every_matrix_of_the_parameter_box_and_is_attained(seed, n, shared):
    rng = np.random.default_rng(seed)
    structure = _scaled(rng, (1 if shared else n, 3, 2, 2))
    lower, upper = _boxes(rng, n, 2)
    p_lower, p_upper = _boxes(rng, n, 3)
    lo, hi = vertex_bound(structure, lower, upper, p_lower, p_upper)
    for r in range(n):
        b = structure[0 if shared else r]
        mats = np.eye(2) + np.einsum("ki,ijl->kjl", _corners(p_lower[r], p_upper[r]), b)  # (8, 2, 2)
        images = np.einsum("kjl,cl->kcj", mats, _corners(lower[r], upper[r])).reshape(-1, 2)
        scale = (1.0 + np.abs(mats).max()) * (1.0 + np.abs(np.concatenate([lower[r], upper[r]])).max())
        assert _close(lo[r], images.min(axis=0), scale) and _close(hi[r], images.max(axis=0), scale)
        # any parameter and any state of the boxes (the map is affine in each)
        p = p_lower[r] + rng.random((32, 3)) * (p_upper[r] - p_lower[r])
        z = lower[r] + rng.random((32, 2)) * (upper[r] - lower[r])
        values = np.einsum("kjl,kl->kj", np.eye(2) + np.einsum("ki,ijl->kjl", p, b), z)
        assert np.all(values >= lo[r] - REL * scale) and np.all(values <= hi[r] + REL * scale)


def test_empty_rows_stay_empty_or_nan_and_never_widen_the_others():
    """A dead row (inf, -inf) yields an empty box or NaN in its own row only."""
    m = np.array([[[1.0, -2.0], [0.0, 3.0]], [[0.5, 0.0], [1.0, 1.0]]])
    lower = np.array([[np.inf, np.inf], [0.0, 1.0]])
    upper = np.array([[-np.inf, -np.inf], [1.0, 2.0]])
    lo, hi = interval_matvec(m, lower, upper)
    assert not np.any(lo[0] <= hi[0])  # empty (inf > -inf) or NaN: never a box that holds a point
    np.testing.assert_array_equal(lo[1], [0.0, 1.0])
    np.testing.assert_array_equal(hi[1], [0.5, 3.0])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), dt=st.floats(0.01, 0.5), length=st.floats(2.0, 6.0))
def test_contraction_vertex_factor_is_the_largest_vertex_norm_by_svd(seed, n, dt, length):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, 2, 2))
    metric = a @ np.swapaxes(a, 1, 2) + 0.05 * np.eye(2)
    lower = np.column_stack(
        [
            rng.uniform(0.5, 1.0, n),
            rng.uniform(0.5, 1.0, n),
            rng.uniform(0.2, 0.5, n),
            rng.uniform(0.5, 30.0, n),
            rng.uniform(-1.0, 3.0, n),
            rng.uniform(-1.0, 1.0, n),
        ]
    )
    upper = lower + rng.random((n, 6)) * np.array([0.0, 0.0, 0.3, 10.0, 1.0, 1.0])
    upper[:, :2] = 1.0
    corners = np.array(list(itertools.product([False, True], repeat=6)))
    got = contraction_vertex_factor(metric, lower, upper, dt, length)
    for r in range(n):
        c = np.linalg.cholesky(metric[r]).T  # upper triangular, P = C' C
        worst, closed_form = 0.0, 0.0
        for corner in corners:
            s1, s2, g, v, b1, q = (float(x) for x in np.where(corner, upper[r], lower[r]))
            mat = np.array(
                [
                    [1 - dt * s1 * g * length * q, dt * s1 * (v - g * length * b1)],
                    [-2 * dt * s2 * g * q, 1 - 2 * dt * s2 * g * b1],
                ]
            )
            worst = max(worst, np.linalg.norm(c @ mat @ np.linalg.inv(c), 2) ** 2)
            closed_form = max(closed_form, _vertex_value(metric[r], dt, length, s1, s2, g, v, b1, q))
        assert abs(got[r] - worst) <= 1e-9 * (1.0 + worst)
        # and the same bits as the documented closed form, evaluated per vertex left to right
        assert got[r] == closed_form


def _vertex_value(p, dt, length, s1, s2, g, v, b1, q):
    """One vertex of `contraction_vertex_factor`, in plain Python floats, in the order of its docstring."""
    p11, p12, p22 = float(p[0, 0]), float(p[0, 1]), float(p[1, 1])
    c11, c12, c22 = math.sqrt(p11), p12 / math.sqrt(p11), math.sqrt(p22 - p12 * p12 / p11)
    a11 = 1.0 - dt * s1 * g * length * q
    a12 = dt * s1 * (v - g * length * b1)
    a21 = -2.0 * dt * s2 * g * q
    a22 = 1.0 - 2.0 * dt * s2 * g * b1
    u11, u12, u21, u22 = c11 * a11 + c12 * a21, c11 * a12 + c12 * a22, c22 * a21, c22 * a22
    m00, m01 = u11 / c11, (u12 - u11 * c12 / c11) / c22
    m10, m11 = u21 / c11, (u22 - u21 * c12 / c11) / c22
    f = m00 * m00 + m01 * m01 + m10 * m10 + m11 * m11
    det = m00 * m11 - m01 * m10
    return 0.5 * (f + math.sqrt(max(f * f - 4.0 * (det * det), 0.0)))


def test_rows_that_do_not_match_are_refused_not_read_past():
    """Compiled code reads past an array's end silently: every kernel checks that its inputs share n."""
    box = np.zeros((3, 2))
    with pytest.raises(ValueError, match="share n"):
        interval_matvec(np.zeros((2, 2, 2)), box, box)
    with pytest.raises(ValueError, match="share n"):
        interval_matvec(np.zeros((3, 2, 1)), box, box)
    with pytest.raises(ValueError, match="structure"):
        vertex_bound(np.zeros((1, 2, 2, 2)), box, box, np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="structure"):
        vertex_bound(np.zeros((2, 3, 2, 2)), box, box, np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="share n"):
        vertex_bound(np.zeros((1, 3, 2, 2)), box, box, np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="3"):
        vertex_bound(np.zeros((1, 3, 2, 2)), box, box, np.zeros((3, 2)), np.zeros((3, 2)))
    with pytest.raises(ValueError, match="lower and upper"):
        contraction_vertex_factor(np.tile(np.eye(2), (3, 1, 1)), np.ones((2, 6)), np.ones((3, 6)), 0.1, 5.0)
    with pytest.raises(ValueError, match="lower and upper"):
        contraction_vertex_factor(np.ones((3, 2, 1)), np.ones((3, 6)), np.ones((3, 6)), 0.1, 5.0)
    with pytest.raises(ValueError, match="lower and upper"):
        contraction_vertex_factor(np.tile(np.eye(2), (3, 1, 1)), np.ones((3, 5)), np.ones((3, 5)), 0.1, 5.0)
