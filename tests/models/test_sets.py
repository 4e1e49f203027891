"""Boxes and ellipsoids: construction, immutability, membership, enclosures, bad input."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import linprog

from minimaxplan.models import Box, DimensionError, Ellipsoid, EmptySetError, InputError, NonFiniteError
from minimaxplan.models.sets import hypercube_signs

SEEDS = st.integers(0, 2**32 - 1)


def _random_gramian(rng, d):
    """A random symmetric positive definite matrix with condition number up to ~1e6."""
    Q, _ = np.linalg.qr(rng.normal(size=(d, d)))
    eigenvalues = 10.0 ** rng.uniform(-3, 3, size=d)
    G = (Q * eigenvalues) @ Q.T
    return (G + G.T) / 2


def _boundary_points(rng, ellipsoid, k):
    """k points with (t - c)^T G (t - c) = radius^2, from a Cholesky factor (not the eigenbasis)."""
    u = rng.normal(size=(k, ellipsoid.dim))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    C = np.linalg.cholesky(ellipsoid.gramian)  # G = C C^T, so t = c + r C^-T u is on the boundary
    return ellipsoid.center + ellipsoid.radius * np.linalg.solve(C.T, u.T).T


def _in_convex_hull(vertices, point):
    """LP (HiGHS): is ``point`` a convex combination of the rows of ``vertices``?"""
    k = vertices.shape[0]
    result = linprog(
        np.zeros(k),
        A_eq=np.vstack([vertices.T, np.ones((1, k))]),
        b_eq=np.append(point, 1.0),
        bounds=[(0, None)] * k,
        method="highs",
    )
    if result.status == 0:
        return True
    if result.status == 2:
        return False
    raise AssertionError(f"linprog failed: status {result.status}, {result.message}")


# ------------------------------------------------------------------------------ Box
def test_box_basics():
    box = Box([-1.0, 0.0, 2.0], [1.0, 0.0, 5.0])
    assert box.dim == 3
    np.testing.assert_array_equal(box.center, [0.0, 0.0, 3.5])
    np.testing.assert_array_equal(box.radius, [1.0, 0.0, 1.5])
    assert box.contains([0.5, 0.0, 5.0])
    assert not box.contains([0.5, 1e-12, 5.0])
    assert box.contains([0.5, 1e-12, 5.0], tol=1e-9)
    assert box.contains(np.array([[1.0, 0.0, 2.0], [-1.0, 0.0, 5.0]]))
    assert not box.contains(np.array([[1.0, 0.0, 2.0], [-1.1, 0.0, 5.0]]))
    assert box == Box(np.array([-1, 0, 2]), np.array([1, 0, 5]))
    assert hash(box) == hash(Box([-1, 0, 2], [1, 0, 5]))
    assert box.to_dict() == {"low": [-1.0, 0.0, 2.0], "high": [1.0, 0.0, 5.0]}


def test_box_from_center_scalar_and_vector_radius():
    assert Box.from_center([1.0, 2.0], 0.5) == Box([0.5, 1.5], [1.5, 2.5])
    assert Box.from_center([1.0, 2.0], [0.0, 1.0]) == Box([1.0, 1.0], [1.0, 3.0])


def test_box_is_immutable_and_does_not_alias():
    low, high = np.array([0.0, 1.0]), np.array([2.0, 3.0])
    box = Box(low, high)
    low[0] = -100.0
    high[1] = 100.0
    np.testing.assert_array_equal(box.low, [0.0, 1.0])
    np.testing.assert_array_equal(box.high, [2.0, 3.0])
    with pytest.raises(ValueError, match="read-only"):
        box.low[0] = 5.0
    with pytest.raises(AttributeError):
        box.low = np.zeros(2)


@given(seed=SEEDS, n=st.integers(1, 6))
def test_box_vertices_are_the_corners_and_inside(seed, n):
    rng = np.random.default_rng(seed)
    center = rng.normal(size=n) * 10.0 ** rng.uniform(-3, 3)
    box = Box.from_center(center, np.abs(rng.normal(size=n)) * 10.0 ** rng.uniform(-8, 2))
    vertices = box.vertices()
    assert vertices.shape == (2**n, n)
    assert box.contains(vertices)  # exactly, no tolerance
    assert np.all((vertices == box.low) | (vertices == box.high))
    assert len({tuple(v) for v in vertices}) == 2 ** np.count_nonzero(box.high > box.low)
    np.testing.assert_array_equal(vertices.min(axis=0), box.low)
    np.testing.assert_array_equal(vertices.max(axis=0), box.high)


@given(seed=SEEDS, n=st.integers(1, 5))
def test_box_intersection_is_the_set_intersection(seed, n):
    rng = np.random.default_rng(seed)
    a = Box.from_center(rng.normal(size=n), rng.uniform(0.5, 2, size=n))
    b = Box.from_center(rng.uniform(a.low, a.high), rng.uniform(0.5, 2, size=n))  # overlaps a
    both = a.intersect(b)
    points = rng.uniform(np.minimum(a.low, b.low) - 1, np.maximum(a.high, b.high) + 1, size=(50, n))
    for x in points:
        assert both.contains(x) == (a.contains(x) and b.contains(x))


def test_hypercube_signs():
    signs = hypercube_signs(3)
    assert signs.shape == (8, 3)
    np.testing.assert_array_equal(signs[0], [-1, -1, -1])
    np.testing.assert_array_equal(signs[1], [-1, -1, 1])
    np.testing.assert_array_equal(signs[-1], [1, 1, 1])
    assert len({tuple(s) for s in signs}) == 8


def test_box_errors():
    with pytest.raises(EmptySetError, match=r"Box is empty: low > high at indices \[1\]"):
        Box([0.0, 2.0], [1.0, 1.0])
    with pytest.raises(DimensionError, match=r"low and high must have the same shape, got \(2,\) and \(3,\)"):
        Box([0.0, 0.0], [1.0, 1.0, 1.0])
    with pytest.raises(DimensionError, match=r"low must be 1-dimensional, got shape \(1, 2\)"):
        Box([[0.0, 0.0]], [1.0, 1.0])
    with pytest.raises(DimensionError, match=r"a Box needs at least one dimension"):
        Box([], [])
    with pytest.raises(NonFiniteError, match=r"low contains NaN or infinite entries"):
        Box([np.nan], [1.0])
    with pytest.raises(NonFiniteError, match=r"high contains NaN or infinite entries"):
        Box([0.0], [np.inf])
    with pytest.raises(InputError, match=r"low must be a real numeric array"):
        Box(["a"], [1.0])
    with pytest.raises(InputError, match=r"high must be a real numeric array, got complex values"):
        Box([0.0], np.array([1.0 + 2.0j]))
    with pytest.raises(InputError, match=r"radius must be a real scalar, got np.complex128"):
        Ellipsoid([0.0], [[1.0]], np.complex128(1.0 + 1.0j))
    with pytest.raises(InputError, match=r"radius must be a real scalar, got True"):
        Ellipsoid([0.0], [[1.0]], True)
    with pytest.raises(EmptySetError, match=r"radius must be >= 0"):
        Box.from_center([0.0, 0.0], [1.0, -1.0])
    with pytest.raises(DimensionError, match=r"radius must have shape \(2,\), got shape \(3,\)"):
        Box.from_center([0.0, 0.0], [1.0, 1.0, 1.0])
    box = Box([0.0, 0.0], [1.0, 1.0])
    with pytest.raises(DimensionError, match=r"x must have shape \(2,\) or \(k, 2\), got shape \(3,\)"):
        box.contains([0.0, 0.0, 0.0])
    with pytest.raises(DimensionError, match=r"other must have dimension 2, got 1"):
        box.intersect(Box([0.0], [1.0]))
    with pytest.raises(EmptySetError, match=r"Box is empty"):
        box.intersect(Box([2.0, 2.0], [3.0, 3.0]))


# ------------------------------------------------------------------------ Ellipsoid
def test_ellipsoid_basics():
    ell = Ellipsoid([1.0, -1.0], [[4.0, 0.0], [0.0, 1.0]], 2.0)  # semi-axes 1 and 2
    assert ell.dim == 2
    assert ell.contains([1.0, -1.0])
    assert ell.contains([2.0, -1.0]) and ell.contains([1.0, 1.0])
    assert not ell.contains([2.01, -1.0])
    assert ell.contains([2.01, -1.0], tol=0.03)
    assert ell.contains(np.array([[1.0, 0.0], [1.5, -1.0]]))
    box = ell.bounding_box()
    np.testing.assert_allclose(box.low, [0.0, -3.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(box.high, [2.0, 1.0], rtol=0, atol=1e-15)
    assert ell.to_dict() == {"center": [1.0, -1.0], "gramian": [[4.0, 0.0], [0.0, 1.0]], "radius": 2.0}


def test_ellipsoid_is_immutable_and_does_not_alias():
    center, gramian = np.array([0.0, 0.0]), np.eye(2)
    ell = Ellipsoid(center, gramian, 1.0)
    center[0], gramian[0, 0] = 5.0, 9.0
    np.testing.assert_array_equal(ell.center, [0.0, 0.0])
    np.testing.assert_array_equal(ell.gramian, np.eye(2))
    for array in (ell.center, ell.gramian):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 1.0
    with pytest.raises(AttributeError):
        ell.radius = 3.0


@given(seed=SEEDS, d=st.integers(1, 5))
def test_bounding_box_encloses_the_boundary_and_is_tight(seed, d):
    rng = np.random.default_rng(seed)
    ell = Ellipsoid(rng.normal(size=d), _random_gramian(rng, d), 10.0 ** rng.uniform(-2, 2))
    box = ell.bounding_box()
    points = _boundary_points(rng, ell, 200)
    scale = box.radius + np.abs(ell.center)
    assert np.all(points >= box.low - 1e-12 * scale) and np.all(points <= box.high + 1e-12 * scale)
    # tight: the maximiser of t_i over the ellipsoid, c + r G^-1 e_i / sqrt((G^-1)_ii), reaches high_i
    inverse = np.linalg.inv(ell.gramian)
    largest_axis = ell.radius / np.sqrt(np.linalg.eigvalsh(ell.gramian)[0])
    for i in range(d):
        extreme = ell.center + ell.radius * inverse[:, i] / np.sqrt(inverse[i, i])
        assert ell.contains(extreme, tol=1e-9)
        # both routes (inverse here, eigenbasis there) lose ~cond(G) eps of the largest semi-axis
        assert extreme[i] == pytest.approx(box.high[i], rel=1e-9, abs=1e-9 * largest_axis + 1e-12 * scale[i])


@given(seed=SEEDS, d=st.integers(1, 4))
def test_ellipsoid_vertices_enclose_the_ellipsoid(seed, d):
    """Boundary points are convex combinations of the 2^d vertices (LP hull test)."""
    rng = np.random.default_rng(seed)
    ell = Ellipsoid(rng.normal(size=d), _random_gramian(rng, d), 10.0 ** rng.uniform(-1, 1))
    vertices = ell.vertices()
    assert vertices.shape == (2**d, d)
    # LP equality tolerances are ~1e-9: keep the points a hair inside, relative to the size
    lengths, _ = ell.semi_axes()
    for point in _boundary_points(rng, ell, 12):
        inner = ell.center + (1 - 1e-7) * (point - ell.center)
        assert _in_convex_hull(vertices, inner), point
    # the enclosure is not trivial: the vertices themselves lie outside the ellipsoid
    # (for d >= 2), and a point beyond a vertex is not in their hull
    if d >= 2:
        assert not any(ell.contains(v) for v in vertices)
    beyond = ell.center + 1.01 * (vertices[0] - ell.center)
    assert not _in_convex_hull(vertices, beyond)
    assert np.all(lengths > 0)


def test_vertices_follow_the_errata_formula():
    # G = diag(4, 1/9), radius 2: semi-axes 1 and 6 along the coordinate axes
    ell = Ellipsoid([0.0, 0.0], np.diag([4.0, 1.0 / 9.0]), 2.0)
    vertices = {tuple(np.round(np.abs(v), 12)) for v in ell.vertices()}
    assert vertices == {(1.0, 6.0)}


def test_ellipsoid_errors():
    with pytest.raises(InputError, match=r"gramian must be positive definite, smallest eigenvalue is -1"):
        Ellipsoid([0.0, 0.0], [[1.0, 0.0], [0.0, -1.0]], 1.0)
    with pytest.raises(InputError, match=r"gramian must be positive definite, smallest eigenvalue is 0"):
        Ellipsoid([0.0, 0.0], [[1.0, 1.0], [1.0, 1.0]], 1.0)
    with pytest.raises(InputError, match=r"gramian must be symmetric"):
        Ellipsoid([0.0, 0.0], [[1.0, 0.5], [0.0, 1.0]], 1.0)
    with pytest.raises(DimensionError, match=r"gramian must have shape \(2, 2\), got shape \(3, 3\)"):
        Ellipsoid([0.0, 0.0], np.eye(3), 1.0)
    with pytest.raises(DimensionError, match=r"center must be 1-dimensional, got shape \(\)"):
        Ellipsoid(0.0, np.eye(1), 1.0)
    with pytest.raises(NonFiniteError, match=r"center contains NaN"):
        Ellipsoid([np.nan, 0.0], np.eye(2), 1.0)
    with pytest.raises(NonFiniteError, match=r"gramian contains NaN"):
        Ellipsoid([0.0, 0.0], [[1.0, np.inf], [np.inf, 1.0]], 1.0)
    with pytest.raises(InputError, match=r"radius must be > 0, got 0.0"):
        Ellipsoid([0.0], [[1.0]], 0.0)
    with pytest.raises(NonFiniteError, match=r"radius must be finite"):
        Ellipsoid([0.0], [[1.0]], np.inf)
    with pytest.raises(DimensionError, match=r"t must have shape \(2,\) or \(k, 2\), got shape \(1, 3\)"):
        Ellipsoid([0.0, 0.0], np.eye(2), 1.0).contains([[0.0, 0.0, 0.0]])
