"""Tests of parameter_vertices: every returned polytope contains its parameter set."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from minimaxplan.models import Box, DimensionError, Ellipsoid, EmptySetError, InputError, NonFiniteError
from minimaxplan.models.polytope import parameter_vertices

TOL = 1e-9


def in_hull(vertices: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Membership of points (n, d) in co{vertices}, with a relative tolerance; full-dimensional hulls."""
    points = np.atleast_2d(points)
    if vertices.shape[1] == 1:
        return (points[:, 0] >= vertices.min() - TOL * (1 + abs(vertices.min()))) & (
            points[:, 0] <= vertices.max() + TOL * (1 + abs(vertices.max()))
        )
    equations = ConvexHull(vertices).equations
    slack = points @ equations[:, :-1].T + equations[:, -1]
    return np.all(slack <= TOL * (1 + np.abs(points).max(axis=1, keepdims=True)), axis=1)


def random_ellipsoid(rng, d: int, scale: float = 1.0) -> Ellipsoid:
    factor = rng.normal(size=(d, d))
    gramian = factor @ factor.T + 0.05 * np.eye(d)
    return Ellipsoid(rng.normal(size=d) * scale, gramian, float(rng.uniform(0.2, 2.0)))


def ellipsoid_points(rng, ellipsoid: Ellipsoid, n: int) -> np.ndarray:
    """n points: half on the boundary (the extremes), half inside."""
    d = ellipsoid.dim
    directions = rng.normal(size=(n, d))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    directions[n // 2 :] *= rng.uniform(0, 1, size=(n - n // 2, 1)) ** (1 / d)
    cholesky = np.linalg.cholesky(ellipsoid.gramian)
    offsets = np.linalg.solve(cholesky.T, directions.T).T * ellipsoid.radius
    return ellipsoid.center + offsets


def test_box_gives_its_corners():
    box = Box(np.array([-1.0, 0.0, 2.0]), np.array([1.0, 0.5, 3.0]))
    vertices = parameter_vertices(box)
    assert vertices.shape == (8, 3)
    np.testing.assert_array_equal(vertices, box.vertices())


def test_box_with_prior_is_the_exact_intersection():
    box = Box(np.array([-1.0, -1.0]), np.array([1.0, 1.0]))
    prior = Box(np.array([0.0, -3.0]), np.array([3.0, 0.5]))
    vertices = parameter_vertices(box, prior)
    np.testing.assert_array_equal(vertices, Box(np.array([0.0, -1.0]), np.array([1.0, 0.5])).vertices())


def test_array_is_taken_as_is():
    vertices = np.array([[0.0, 0.0], [1.0, 0.0], [0.3, 2.0]])
    np.testing.assert_array_equal(parameter_vertices(vertices), vertices)


@given(seed=st.integers(0, 2**32 - 1), d=st.integers(1, 4))
def test_ellipsoid_vertices_contain_the_ellipsoid(seed, d):
    rng = np.random.default_rng(seed)
    ellipsoid = random_ellipsoid(rng, d)
    vertices = parameter_vertices(ellipsoid)
    assert vertices.shape == (2**d, d)
    assert np.all(in_hull(vertices, ellipsoid_points(rng, ellipsoid, 200)))


@given(seed=st.integers(0, 2**32 - 1), d=st.integers(1, 4))
def test_ellipsoid_with_prior_contains_the_intersection(seed, d):
    rng = np.random.default_rng(seed)
    ellipsoid = random_ellipsoid(rng, d)
    # A prior that cuts the ellipsoid (its centre lies inside the prior, so it is not empty).
    box = ellipsoid.bounding_box()
    low = ellipsoid.center - rng.uniform(0.05, 1.2, size=d) * box.radius
    high = ellipsoid.center + rng.uniform(0.05, 1.2, size=d) * box.radius
    prior = Box(low, high)
    vertices = parameter_vertices(ellipsoid, prior)
    points = ellipsoid_points(rng, ellipsoid, 2000)
    points = points[np.all((points >= low) & (points <= high), axis=1)]
    # Also the ellipsoid's extreme points along the prior's faces: project boundary points onto them.
    assert np.all(in_hull(vertices, points))
    # Not larger than needed: inside the prior and inside the parallelotope.
    scale = TOL * (1 + np.abs(vertices))
    assert np.all(vertices >= low - scale) and np.all(vertices <= high + scale)
    assert np.all(in_hull(ellipsoid.vertices(), vertices))


@given(seed=st.integers(0, 2**32 - 1), d=st.integers(2, 4), log_condition=st.floats(0, 8))
def test_ill_conditioned_ellipsoids_are_contained(seed, d, log_condition):
    rng = np.random.default_rng(seed)
    rotation, _ = np.linalg.qr(rng.normal(size=(d, d)))
    spectrum = np.logspace(0, log_condition, d)
    ellipsoid = Ellipsoid(rng.normal(size=d) * 10, rotation @ np.diag(spectrum) @ rotation.T, 1.0)
    points = ellipsoid_points(rng, ellipsoid, 500)
    assert np.all(in_hull(parameter_vertices(ellipsoid), points))
    prior = Box(ellipsoid.center - 0.5 / np.sqrt(spectrum[0]), ellipsoid.center + 0.5 / np.sqrt(spectrum[0]))
    inside = points[np.all((points >= prior.low) & (points <= prior.high), axis=1)]
    assert np.all(in_hull(parameter_vertices(ellipsoid, prior), inside))


def test_clipping_vertices_would_be_unsound_but_the_intersection_is_not():
    # A thin ellipsoid along the diagonal; the prior cuts off its two tips in x.
    rotation = np.array([[1.0, -1.0], [1.0, 1.0]]) / np.sqrt(2)
    gramian = rotation @ np.diag([1.0, 100.0]) @ rotation.T
    ellipsoid = Ellipsoid(np.zeros(2), gramian, 1.0)
    prior = Box(np.array([-0.5, -2.0]), np.array([0.5, 2.0]))
    clipped = np.clip(ellipsoid.vertices(), prior.low, prior.high)
    # A point of the ellipsoid inside the prior that the clipped hull misses.
    point = np.array([[0.5, 0.5]])
    assert ellipsoid.contains(point) and prior.contains(point)
    assert not in_hull(clipped, point)[0]
    assert in_hull(parameter_vertices(ellipsoid, prior), point)[0]


@given(seed=st.integers(0, 2**32 - 1), d=st.integers(2, 4))
def test_array_with_prior_contains_the_intersection(seed, d):
    rng = np.random.default_rng(seed)
    vertices = rng.normal(size=(d + 3, d))
    prior = Box(
        vertices.mean(axis=0) - rng.uniform(0.1, 2, size=d), vertices.mean(axis=0) + rng.uniform(0.1, 2, size=d)
    )
    result = parameter_vertices(vertices, prior)
    weights = rng.dirichlet(np.ones(len(vertices)) * 0.3, size=3000)
    points = weights @ vertices
    points = points[np.all((points >= prior.low) & (points <= prior.high), axis=1)]
    assert np.all(in_hull(result, points))


def test_flat_prior_gives_a_sound_box():
    rng = np.random.default_rng(3)
    ellipsoid = random_ellipsoid(rng, 3)
    fixed = float(ellipsoid.center[1])
    prior = Box(np.array([-10.0, fixed, -10.0]), np.array([10.0, fixed, 10.0]))
    vertices = parameter_vertices(ellipsoid, prior)
    points = ellipsoid_points(rng, ellipsoid, 2000)
    points[:, 1] = fixed
    points = points[[ellipsoid.contains(x) for x in points]]
    assert len(points) > 100
    assert Box(vertices.min(axis=0), vertices.max(axis=0)).contains(points, tol=1e-12)


def test_empty_intersection_raises():
    ellipsoid = Ellipsoid(np.zeros(2), np.eye(2), 1.0)
    with pytest.raises(EmptySetError, match="does not meet the prior"):
        parameter_vertices(ellipsoid, Box(np.array([5.0, 5.0]), np.array([6.0, 6.0])))
    # The bounding boxes meet but the parallelotope (a rotated square) does not.
    rotation = np.array([[1.0, -1.0], [1.0, 1.0]]) / np.sqrt(2)
    tilted = Ellipsoid(np.zeros(2), rotation @ np.diag([1.0, 100.0]) @ rotation.T, 1.0)
    with pytest.raises(EmptySetError, match="empty"):
        parameter_vertices(tilted, Box(np.array([0.6, -0.7]), np.array([0.7, -0.6])))
    with pytest.raises(EmptySetError, match="does not meet the prior"):
        parameter_vertices(Box(np.zeros(1), np.ones(1)), Box(np.array([2.0]), np.array([3.0])))


def test_bad_input_is_rejected():
    with pytest.raises(DimensionError, match=r"parameters must be 2-dimensional, got shape \(3,\)"):
        parameter_vertices(np.zeros(3))
    with pytest.raises(NonFiniteError, match="parameters contains NaN"):
        parameter_vertices(np.array([[0.0, np.nan]]))
    with pytest.raises(DimensionError, match=r"prior must have dimension 2 .*shape \(1, 2\).*got 3"):
        parameter_vertices(np.zeros((1, 2)), Box(np.zeros(3), np.ones(3)))
    with pytest.raises(DimensionError, match="prior must have dimension 2 .*got 1"):
        parameter_vertices(Ellipsoid(np.zeros(2), np.eye(2), 1.0), Box(np.zeros(1), np.ones(1)))
    with pytest.raises(InputError, match="prior must be a Box or None, got ndarray"):
        parameter_vertices(np.zeros((1, 2)), np.zeros(2))
    with pytest.raises(DimensionError, match=r"shape \(k, d\) with k, d >= 1, got shape \(0, 2\)"):
        parameter_vertices(np.zeros((0, 2)))


# ----------------------------------------------------------- the ParameterSet protocol
def test_every_parameter_set_implements_the_protocol():
    from minimaxplan.models import ParameterSet, VertexPolytope

    sets = [
        Box(np.zeros(2), np.ones(2)),
        Ellipsoid(np.zeros(2), np.eye(2), 1.0),
        VertexPolytope(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])),
    ]
    for parameter_set in sets:
        assert isinstance(parameter_set, ParameterSet)
        assert parameter_set.dim == 2
        box = parameter_set.bounding_box()
        assert isinstance(box, Box) and box.contains(parameter_set.enclosing_vertices(), tol=1e-9)
        assert parameter_set.contains(np.array([0.25, 0.25])) is True
        assert isinstance(parameter_set.to_dict(), dict)
        # parameter_vertices is the set's own method
        np.testing.assert_array_equal(parameter_vertices(parameter_set), parameter_set.enclosing_vertices())
        prior = Box(np.array([0.0, 0.0]), np.array([0.5, 2.0]))
        np.testing.assert_array_equal(parameter_vertices(parameter_set, prior), parameter_set.enclosing_vertices(prior))
    assert not isinstance(np.zeros((3, 2)), ParameterSet)


def test_arrays_are_wrapped_in_a_vertex_polytope_with_the_same_vertices():
    from minimaxplan.models import VertexPolytope
    from minimaxplan.models.polytope import as_parameter_set

    vertices = np.array([[0.0, 1.0], [2.0, -1.0], [0.5, 0.5]])
    wrapped = as_parameter_set(vertices)
    assert isinstance(wrapped, VertexPolytope)
    np.testing.assert_array_equal(wrapped.vertices, vertices)
    assert not wrapped.vertices.flags.writeable and wrapped.vertices is not vertices
    assert wrapped.nvertices == 3
    assert wrapped.bounding_box() == Box(np.array([0.0, -1.0]), np.array([2.0, 1.0]))
    assert wrapped.to_dict() == {"vertices": vertices.tolist()}
    assert as_parameter_set(wrapped) is wrapped
    with pytest.raises(DimensionError, match=r"vertices must have shape \(k, d\) with k, d >= 1, got shape \(0, 2\)"):
        VertexPolytope(np.zeros((0, 2)))
    with pytest.raises(NonFiniteError, match="vertices contains NaN"):
        VertexPolytope(np.array([[np.inf, 0.0]]))


def test_vertex_polytope_membership_is_the_convex_hull():
    from minimaxplan.models import VertexPolytope

    triangle = VertexPolytope(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
    assert triangle.contains(np.array([[0.2, 0.2], [0.5, 0.5], [0.0, 0.0], [1.0, 0.0]]))  # inside, on a facet, vertices
    assert not triangle.contains(np.array([0.6, 0.6]))
    assert triangle.contains(np.array([0.6, 0.6]), tol=0.11)
    membership = triangle.contains(np.array([[0.1, 0.1], [0.6, 0.6], [2.0, 2.0]]), witness=True)
    assert not membership and membership.point == 1
    assert membership.excess == pytest.approx(0.1, abs=1e-8)  # infinity-norm distance to the facet x + y = 1
    with pytest.raises(DimensionError, match=r"x must have shape \(2,\) or \(k, 2\), got shape \(3,\)"):
        triangle.contains(np.zeros(3))


def test_witness_names_the_first_violation():
    box = Box(np.array([0.0, 0.0]), np.array([1.0, 1.0]))
    assert box.contains(np.array([0.5, 0.5]), witness=True) == box.contains(np.array([0.5, 0.5]), witness=True)
    inside = box.contains(np.array([[0.5, 0.5], [1.0, 0.0]]), witness=True)
    assert inside and inside.inside and inside.point is None and inside.excess == 0.0
    outside = box.contains(np.array([[0.5, 0.5], [0.5, 1.25], [-3.0, 0.5]]), witness=True)
    assert not outside and outside.point == 1 and outside.constraint == "x[1] <= high[1] + tol"
    assert outside.excess == pytest.approx(0.25)
    below = box.contains(np.array([-0.5, 2.0]), tol=0.25, witness=True)
    assert (below.point, below.constraint, below.excess) == (0, "x[0] >= low[0] - tol", pytest.approx(0.25))
    # without witness: plain bools, as before
    assert box.contains(np.array([0.5, 1.25])) is False and box.contains(np.array([0.5, 1.25]), 0.25) is True

    ellipsoid = Ellipsoid(np.zeros(2), np.eye(2), 1.0)
    result = ellipsoid.contains(np.array([[0.0, 0.5], [0.0, 2.0]]), witness=True)
    assert not result and result.point == 1 and result.excess == pytest.approx(3.0)
    assert ellipsoid.contains(np.array([0.0, 0.5]), witness=True).inside


@given(st.integers(0, 2**32 - 1))
def test_witness_agrees_with_the_plain_answer(seed):
    from minimaxplan.models import VertexPolytope

    rng = np.random.default_rng(seed)
    d = int(rng.integers(1, 4))
    points = rng.normal(size=(int(rng.integers(1, 5)), d))
    sets = [
        Box(-rng.uniform(0.5, 2, d), rng.uniform(0.5, 2, d)),
        random_ellipsoid(rng, d),
        VertexPolytope(rng.normal(size=(d + 2, d)) * 2),
    ]
    for parameter_set in sets:
        plain = parameter_set.contains(points)
        membership = parameter_set.contains(points, witness=True)
        assert plain == membership.inside
        if not plain:
            assert membership.excess > 0
            assert not parameter_set.contains(points[membership.point])
            assert parameter_set.contains(points[: membership.point]) if membership.point else True
