"""Boxes and ellipsoids: construction, immutability, membership, enclosures, bad input."""

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import linprog

from minimaxplan.models import Box, DimensionError, Ellipsoid, EmptySetError, InputError, NonFiniteError
from minimaxplan.models.sets import SUPPORT_MARGIN, SUPPORT_ROUNDING, hypercube_signs

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
    # the exact box [0, 2] x [-3, 1], rounded outward by the documented relative margin
    # (SUPPORT_MARGIN + SUPPORT_ROUNDING d eps cond(G) of the half-widths 1 and 2, plus an ulp)
    assert np.all(box.low <= [0.0, -3.0]) and np.all(box.high >= [2.0, 1.0])
    margin = (SUPPORT_MARGIN + SUPPORT_ROUNDING * 2 * np.finfo(float).eps * 4.0) * np.array([1.0, 2.0])
    np.testing.assert_allclose(box.low, [0.0, -3.0], rtol=0, atol=float(np.max(margin)) + 1e-15)
    np.testing.assert_allclose(box.high, [2.0, 1.0], rtol=0, atol=float(np.max(margin)) + 1e-15)
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
        # both routes (inverse here, solve there) lose ~cond(G) eps of the largest semi-axis, and
        # the box is rounded outward by at most the documented margin of its half-width
        margin = (
            SUPPORT_MARGIN + SUPPORT_ROUNDING * d * np.finfo(float).eps * np.linalg.cond(ell.gramian)
        ) * box.radius[i]
        assert extreme[i] == pytest.approx(box.high[i], rel=1e-9, abs=1e-9 * largest_axis + 1e-12 * scale[i] + margin)


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


def _exactly_inside(ellipsoid, point):
    """``(t - c)^T G (t - c) <= radius^2`` in exact rational arithmetic (no rounding at all)."""
    delta = [Fraction(float(t)) - Fraction(float(c)) for t, c in zip(point, ellipsoid.center)]
    gramian = [[Fraction(float(g)) for g in row] for row in ellipsoid.gramian]
    form = sum(delta[i] * gramian[i][j] * delta[j] for i in range(len(delta)) for j in range(len(delta)))
    return form <= Fraction(ellipsoid.radius) ** 2


def _outermost_inside(ellipsoid, start, i, sign):
    """The float point farthest along ``sign * e_i`` from ``start`` (moving coordinate i only) that is exactly inside.

    ``start`` (a float approximation of a boundary point) is first pulled towards the
    centre until it is exactly inside; coordinate i then moves outward, galloping and
    then one ulp at a time, until the next float outward is exactly outside.
    """
    start = np.array(start, dtype=float)
    point, k = start, 0
    while not _exactly_inside(ellipsoid, point):
        point = ellipsoid.center + (1 - 2.0**k * 1e-16) * (start - ellipsoid.center)
        k += 1
        assert k < 60, "could not find a point exactly inside"

    def moved(value):
        trial = point.copy()
        trial[i] = value
        return trial

    step = float(np.spacing(abs(point[i])))
    while _exactly_inside(ellipsoid, moved(point[i] + sign * step)):
        point, step = moved(point[i] + sign * step), 2 * step
    while step > np.spacing(abs(point[i])):
        step /= 2
        if _exactly_inside(ellipsoid, moved(point[i] + sign * step)):
            point = moved(point[i] + sign * step)
    direction = np.inf if sign > 0 else -np.inf
    while _exactly_inside(ellipsoid, moved(np.nextafter(point[i], direction))):
        point = moved(np.nextafter(point[i], direction))
    return point


def _random_1d_ellipsoid(rng):
    center = rng.normal() * 10.0 ** rng.uniform(-3, 3)
    return Ellipsoid([center], [[10.0 ** rng.uniform(-6, 6)]], 10.0 ** rng.uniform(-3, 3))


@given(seed=SEEDS)
def test_1d_enclosures_contain_the_exact_boundary_points(seed):
    """Issue 10 item 4: in d = 1 the box and the vertices must hold the floats exactly inside.

    The outermost floats t with ``(t - c)^2 g <= r^2`` exactly (near ``c +- r / sqrt(g)``)
    must lie in `bounding_box` and between the two `vertices`; without outward rounding
    about 5% of such ellipsoids cut one of them off by an ulp.
    """
    rng = np.random.default_rng(seed)
    for _ in range(20):
        ell = _random_1d_ellipsoid(rng)
        box, vertices = ell.bounding_box(), ell.vertices()
        half_width = ell.radius / np.sqrt(ell.gramian[0, 0])
        for sign in (-1.0, 1.0):
            point = _outermost_inside(ell, ell.center + sign * half_width, 0, sign)
            assert box.contains(point), (ell, point, box)
            assert vertices.min() <= point[0] <= vertices.max(), (ell, point, vertices)


def _in_quadrilateral_exactly(corners, point):
    """Is ``point`` in the convex quadrilateral ``corners`` (in cyclic order)? Exact rational arithmetic."""
    px, py = Fraction(float(point[0])), Fraction(float(point[1]))
    signs = set()
    for k in range(4):
        (ax, ay), (bx, by) = corners[k], corners[(k + 1) % 4]
        ax, ay, bx, by = (Fraction(float(v)) for v in (ax, ay, bx, by))
        cross = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
        if cross != 0:
            signs.add(cross > 0)
    return len(signs) <= 1


@given(seed=SEEDS, d=st.integers(1, 4))
def test_bounding_box_contains_the_exact_extreme_points(seed, d):
    """The maximiser of ``t_i`` over the ellipsoid, moved to the last float exactly inside, is in the box."""
    rng = np.random.default_rng(seed)
    ell = Ellipsoid(
        rng.normal(size=d) * 10.0 ** rng.uniform(-3, 3), _random_gramian(rng, d), 10.0 ** rng.uniform(-2, 2)
    )
    box = ell.bounding_box()
    inverse = np.linalg.inv(ell.gramian)
    for i in range(d):
        for sign in (-1.0, 1.0):
            extreme = ell.center + sign * ell.radius * inverse[:, i] / np.sqrt(inverse[i, i])
            point = _outermost_inside(ell, extreme, i, sign)
            assert box.contains(point), (i, sign, point, box)


@given(seed=SEEDS)
def test_2d_vertices_contain_the_exact_boundary_points(seed):
    """Points exactly inside, pushed to the last float along each semi-axis, lie in the hull of `vertices`.

    The hull test is exact (rational cross products), so an enclosure that misses such a
    point by one ulp fails.
    """
    rng = np.random.default_rng(seed)
    ell = Ellipsoid(
        rng.normal(size=2) * 10.0 ** rng.uniform(-3, 3), _random_gramian(rng, 2), 10.0 ** rng.uniform(-2, 2)
    )
    vertices = ell.vertices()
    corners = vertices[[0, 1, 3, 2]]  # sign vectors (--, -+, ++, +-) of the axes: cyclic order
    lengths, axes = ell.semi_axes()
    for j in range(2):
        for sign in (-1.0, 1.0):
            tip = ell.center + sign * lengths[j] * axes[:, j]
            i = int(np.argmax(np.abs(axes[:, j])))  # walk along the coordinate closest to that axis
            point = _outermost_inside(ell, tip, i, sign * np.sign(axes[i, j]))
            assert _in_quadrilateral_exactly(corners, point), (j, sign, point, vertices)


def test_vertices_follow_the_errata_formula():
    # G = diag(4, 1/9), radius 2: semi-axes 1 and 6 along the coordinate axes
    ell = Ellipsoid([0.0, 0.0], np.diag([4.0, 1.0 / 9.0]), 2.0)
    vertices = ell.vertices()
    assert {tuple(np.sign(v)) for v in vertices} == {(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)}
    # |v| = (1, 6), rounded outward by the documented margins (relative ~1e-12)
    assert np.all(np.abs(vertices) >= [1.0, 6.0])
    np.testing.assert_allclose(np.abs(vertices), np.tile([1.0, 6.0], (4, 1)), rtol=2e-12, atol=0)


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
