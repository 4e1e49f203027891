"""Collision geometry: the vectorised numpy answers against python-fcl, the authoritative one."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models.errors import DimensionError, InputError, NonFiniteError
from minimaxplan.scenarios.geometry import (
    CircularObstacles,
    MovingObstacles,
    box_box_sq_distance,
    box_point_sq_distance,
    boxes_meet_boxes,
    boxes_meet_circles,
    fcl_box_circle_distance,
    fcl_box_meets_grown_box,
    fcl_boxes_meet_boxes,
    fcl_boxes_meet_circles,
    fcl_disc_collisions,
)

coord = st.floats(-5, 5, allow_nan=False)
side = st.floats(0, 3, allow_nan=False)


@st.composite
def boxes(draw, n=None, degenerate=True):
    k = draw(st.integers(1, 4)) if n is None else n
    lo = np.array(draw(st.lists(st.tuples(coord, coord), min_size=k, max_size=k)))
    sides = side if degenerate else st.floats(0.01, 3, allow_nan=False)
    size = np.array(draw(st.lists(st.tuples(sides, sides), min_size=k, max_size=k)))
    if degenerate:  # some boxes degenerate to segments or points
        size[np.array(draw(st.lists(st.booleans(), min_size=k, max_size=k)))] *= 0.0
    return lo, lo + size


@st.composite
def discs(draw):
    n = draw(st.integers(0, 5))
    centers = np.array(draw(st.lists(st.tuples(coord, coord), min_size=n, max_size=n))).reshape(n, 2)
    radii = np.array(draw(st.lists(st.floats(0.05, 1.5), min_size=n, max_size=n)))
    return centers, radii


def exact_box_point_distance(lo, hi, c):
    return float(np.linalg.norm(c - np.clip(c, lo, hi)))


# ------------------------------------------------------------------ distances
@given(boxes(n=1), st.tuples(coord, coord), st.floats(0.05, 2))
def test_box_circle_distance_matches_fcl(box, center, radius):
    lo, hi = box[0][0], box[1][0]
    c = np.array(center)
    numpy_distance = max(np.sqrt(box_point_sq_distance(lo, hi, c[None])[0]) - radius, 0.0)
    assert numpy_distance == pytest.approx(fcl_box_circle_distance(lo, hi, c, radius), abs=1e-9)


@given(boxes(n=1), boxes(n=1), st.floats(0, 2))
def test_box_box_meets_match_fcl(box, other, reach):
    """Box-box distance <= reach exactly when fcl says the other box meets the grown box."""
    lo, hi = box[0][0], box[1][0]
    olo, ohi = other[0], other[1]
    distance = np.sqrt(box_box_sq_distance(lo, hi, olo, ohi)[0])
    if abs(distance - reach) > 1e-9:
        assert (distance <= reach) == fcl_box_meets_grown_box(lo, hi, olo[0], ohi[0], reach)
    assert fcl_box_meets_grown_box(lo, hi, olo[0], ohi[0], distance + 1e-9)
    if distance > 1e-6:
        assert not fcl_box_meets_grown_box(lo, hi, olo[0], ohi[0], distance - 1e-6)


# ------------------------------------------------------- meet tests, many at once
def _separated_from_tangency(lo, hi, centers, radii, margin, tol=1e-7):
    """True when no pair is within tol of tangency (where rounding may legitimately differ)."""
    for i in range(lo.shape[0]):
        for c, r in zip(centers, radii):
            if abs(exact_box_point_distance(lo[i], hi[i], c) - (r + margin)) < tol:
                return False
    return True


@given(boxes(), discs(), st.floats(0, 1))
def test_boxes_meet_circles_matches_fcl(box, obstacles, margin):
    lo, hi = box
    centers, radii = obstacles
    fast = boxes_meet_circles(lo, hi, centers, radii, margin)
    assert fast.shape == (lo.shape[0],)
    if _separated_from_tangency(lo, hi, centers, radii, margin):
        np.testing.assert_array_equal(fast, fcl_boxes_meet_circles(lo, hi, centers, radii, margin))
    # the same answer through the obstacle value, with extra leading dimensions
    obstacle_set = CircularObstacles(centers, radii)
    np.testing.assert_array_equal(obstacle_set.boxes_meet(lo[None], hi[None], margin)[0], fast)


@given(boxes(), boxes(), st.floats(0, 1))
def test_boxes_meet_boxes_matches_fcl(box, others, margin):
    lo, hi = box
    olo, ohi = others
    radii = np.linspace(0.1, 0.5, olo.shape[0])
    fast = boxes_meet_boxes(lo, hi, olo, ohi, radii, margin)
    for i in range(lo.shape[0]):
        gaps = np.sqrt(box_box_sq_distance(lo[i], hi[i], olo, ohi)) - radii - margin
        if np.all(np.abs(gaps) > 1e-7):
            assert fast[i] == fcl_boxes_meet_boxes(lo[i], hi[i], olo, ohi, radii, margin)[0]


def test_fcl_box_box_distance_is_not_used_because_it_fails_on_aligned_boxes():
    """Why box-box cross-checks go through fcl collisions: fcl's GJK distance, not the closed form, is wrong here."""
    from minimaxplan.scenarios.geometry import _fcl_box, _fcl_distance

    assert _fcl_distance(_fcl_box([0.0, 0.0], [1.0, 1.0]), _fcl_box([0.0, 2.0], [1.0, 4.0])) == pytest.approx(
        np.sqrt(2.0)
    )
    assert (
        np.sqrt(
            box_box_sq_distance(
                np.array([0.0, 0.0]), np.array([1.0, 1.0]), np.array([[0.0, 2.0]]), np.array([[1.0, 4.0]])
            )
        )[0]
        == 1.0
    )
    assert fcl_box_meets_grown_box([0.0, 0.0], [1.0, 1.0], [0.0, 2.0], [1.0, 4.0], 1.0)
    assert not fcl_box_meets_grown_box([0.0, 0.0], [1.0, 1.0], [0.0, 2.0], [1.0, 4.0], 1.0 - 1e-9)


@given(boxes(), boxes(n=1))
def test_flat_and_point_boxes_against_the_closed_form(box, other):
    """Box-box distance against a brute-force minimum over points of both boxes (corners and edges)."""
    lo, hi = box
    olo, ohi = other[0][0], other[1][0]
    fast = np.sqrt(box_box_sq_distance(lo, hi, olo[None], ohi[None])[:, 0])
    t = np.linspace(0.0, 1.0, 41)
    for i in range(lo.shape[0]):
        # the distance between boxes is the smaller of point-box distances from the
        # boundary points of either box; sample both boundaries finely
        ring = np.concatenate(
            [np.stack([lo[i][0] + t * (hi[i][0] - lo[i][0]), np.full_like(t, y)], axis=1) for y in (lo[i][1], hi[i][1])]
            + [
                np.stack([np.full_like(t, x), lo[i][1] + t * (hi[i][1] - lo[i][1])], axis=1)
                for x in (lo[i][0], hi[i][0])
            ]
        )
        to_other = np.sqrt(box_point_sq_distance(olo, ohi, ring)).min()
        other_ring = olo + np.stack(np.meshgrid(t, t), axis=-1).reshape(-1, 2) * (ohi - olo)
        to_box = np.sqrt(box_point_sq_distance(lo[i], hi[i], other_ring)).min()
        brute = min(to_other, to_box)
        assert fast[i] <= brute + 1e-12
        assert fast[i] >= brute - 0.05 * np.max(np.concatenate([hi[i] - lo[i], ohi - olo])) - 1e-12


def test_tangent_cases_count_as_meeting():
    lo, hi = np.array([0.0, 0.0]), np.array([1.0, 1.0])
    # disc of radius 0.75 centred 1 to the right of the box: touches when grown by 0.25
    centers, radii = np.array([[2.0, 0.5]]), np.array([0.75])
    assert boxes_meet_circles(lo, hi, centers, radii, 0.25)
    assert not boxes_meet_circles(lo, hi, centers, radii, 0.25 - 1e-9)
    assert fcl_box_circle_distance(lo, hi, centers[0], 0.75) == pytest.approx(0.25, abs=1e-12)
    # corner tangency: distance sqrt(2) * 0.5 from the corner (1, 1)
    corner = np.array([[1.5, 1.5]])
    reach = np.hypot(0.5, 0.5)
    assert boxes_meet_circles(lo, hi, corner, np.array([reach]), 0.0)
    assert not boxes_meet_circles(lo, hi, corner, np.array([reach - 1e-9]), 0.0)
    assert fcl_box_circle_distance(lo, hi, corner[0], reach - 1e-6) == pytest.approx(1e-6, abs=1e-12)
    # two boxes sharing an edge meet; one a hair apart with zero radii do not
    assert boxes_meet_boxes(lo, hi, np.array([[1.0, 0.2]]), np.array([[2.0, 0.4]]), np.array([1e-300]))
    assert fcl_box_meets_grown_box(lo, hi, [1.0, 0.2], [2.0, 0.4], 0.0)
    assert not boxes_meet_boxes(lo, hi, np.array([[1.5, 0.2]]), np.array([[2.0, 0.4]]), np.array([0.4999]))
    assert boxes_meet_boxes(lo, hi, np.array([[1.5, 0.2]]), np.array([[2.0, 0.4]]), np.array([0.5]))


def test_box_containing_the_obstacle_and_obstacle_containing_the_box():
    big_lo, big_hi = np.array([-10.0, -10.0]), np.array([10.0, 10.0])
    centers, radii = np.array([[3.0, -4.0]]), np.array([0.5])
    assert boxes_meet_circles(big_lo, big_hi, centers, radii)
    assert fcl_boxes_meet_circles(big_lo, big_hi, centers, radii)
    small_lo, small_hi = np.array([2.9, -4.1]), np.array([3.1, -3.9])
    assert boxes_meet_circles(small_lo, small_hi, centers, radii)
    assert fcl_boxes_meet_circles(small_lo, small_hi, centers, radii)


def test_point_boxes_reduce_to_disc_tests():
    rng = np.random.default_rng(3)
    points = rng.uniform(-4, 4, size=(200, 2))
    centers = rng.uniform(-4, 4, size=(6, 2))
    radii = rng.uniform(0.2, 1.0, size=6)
    robot_radius = 0.3
    fast = boxes_meet_circles(points, points, centers, radii, robot_radius)
    direct = np.any(np.linalg.norm(points[:, None] - centers, axis=-1) <= radii + robot_radius, axis=1)
    np.testing.assert_array_equal(fast, direct)
    assert fast.any() and not fast.all()  # the sample exercises both outcomes
    for p, hit in zip(points[:40], fast[:40]):
        assert fcl_disc_collisions(p, robot_radius, centers, radii).any() == hit


def test_fcl_disc_collisions_per_obstacle_and_tangent():
    hits = fcl_disc_collisions([0.0, 0.0], 0.5, [[1.0, 0.0], [1.0 + 1e-6, 0.0], [0.0, 0.2]], [0.5, 0.5, 0.1])
    np.testing.assert_array_equal(hits, [True, False, True])
    assert fcl_disc_collisions([0.0, 0.0], 0.5, np.zeros((0, 2)), np.zeros(0)).shape == (0,)


def test_vectorised_broadcasts_many_boxes_by_many_obstacles():
    rng = np.random.default_rng(0)
    lo = rng.uniform(-5, 5, size=(3, 7, 2))
    hi = lo + rng.uniform(0, 1, size=(3, 7, 2))
    centers = rng.uniform(-5, 5, size=(10, 2))
    radii = rng.uniform(0.1, 1.0, size=10)
    fast = boxes_meet_circles(lo, hi, centers, radii, 0.3)
    assert fast.shape == (3, 7)
    np.testing.assert_array_equal(fast, fcl_boxes_meet_circles(lo, hi, centers, radii, 0.3))
    assert boxes_meet_circles(lo, hi, np.zeros((0, 2)), np.zeros(0)).shape == (3, 7)


# ------------------------------------------------------------- moving obstacles
@settings(max_examples=30)
@given(
    st.floats(0.01, 0.5),
    st.integers(0, 20),
    st.floats(0, 0.5),
    st.integers(0, 2**31 - 1),
)
def test_moving_boxes_contain_every_admissible_trajectory(dt, steps, speed_spread, seed):
    rng = np.random.default_rng(seed)
    m = 3
    positions = rng.uniform(-3, 3, (m, 2))
    velocities = rng.uniform(-1.5, 1.5, (m, 2))
    moving = MovingObstacles(positions, velocities, np.full(m, 0.3), velocity_uncertainty=speed_spread, dt=dt, time0=5)
    # a true velocity that changes at every step, at the extremes of the admissible box
    true = positions.copy()
    for t in range(5, 5 + steps + 1):
        lo, hi = moving.boxes(t)
        tol = 1e-9 * (1 + np.abs(true))
        assert np.all(lo - tol <= true) and np.all(true <= hi + tol)
        signs = rng.choice([-1.0, 1.0], size=(m, 2))
        true = true + (velocities + signs * speed_spread) * dt
    lo_all, hi_all = moving.boxes(np.arange(5, 8))
    assert lo_all.shape == (3, m, 2)
    # before time0 the box stays that of time0
    np.testing.assert_array_equal(moving.boxes(0)[0], positions)


def test_moving_boxes_meet_against_fcl():
    rng = np.random.default_rng(1)
    moving = MovingObstacles(
        rng.uniform(-3, 3, (4, 2)),
        rng.uniform(-1, 1, (4, 2)),
        rng.uniform(0.2, 0.5, 4),
        velocity_uncertainty=0.3,
        dt=0.1,
    )
    lo = rng.uniform(-4, 4, (50, 2))
    hi = lo + rng.uniform(0, 1, (50, 2))
    for t in (0, 7, 30):
        fast = moving.boxes_meet(lo, hi, t, 0.3)
        olo, ohi = moving.boxes(t)
        np.testing.assert_array_equal(fast, fcl_boxes_meet_boxes(lo, hi, olo, ohi, moving.radii, 0.3))
    # per-box time indices broadcast against the leading shape
    ts = np.arange(50)
    per_box = moving.boxes_meet(lo, hi, ts, 0.3)
    np.testing.assert_array_equal(per_box, [moving.boxes_meet(lo[i], hi[i], ts[i], 0.3) for i in range(50)])


# ------------------------------------------------------------------- validation
def test_obstacle_validation():
    with pytest.raises(DimensionError, match=r"centers must have shape \(\*, 2\), got shape \(3, 3\)"):
        CircularObstacles(np.zeros((3, 3)), np.ones(3))
    with pytest.raises(DimensionError, match=r"radii must have shape \(2,\), got shape \(3,\)"):
        CircularObstacles(np.zeros((2, 2)), np.ones(3))
    with pytest.raises(InputError, match="radii must be > 0"):
        CircularObstacles(np.zeros((2, 2)), np.array([1.0, 0.0]))
    with pytest.raises(NonFiniteError, match="centers"):
        CircularObstacles(np.array([[np.nan, 0.0]]), np.ones(1))
    with pytest.raises(DimensionError, match=r"velocities must have shape \(2, 2\), got shape \(1, 2\)"):
        MovingObstacles(np.zeros((2, 2)), np.zeros((1, 2)), np.ones(2))
    with pytest.raises(InputError, match="velocity_uncertainty must be >= 0"):
        MovingObstacles(np.zeros((1, 2)), np.zeros((1, 2)), np.ones(1), velocity_uncertainty=-0.1)
    with pytest.raises(InputError, match="dt must be > 0"):
        MovingObstacles(np.zeros((1, 2)), np.zeros((1, 2)), np.ones(1), dt=0.0)
    with pytest.raises(DimensionError, match=r"position must have shape \(2,\)"):
        fcl_disc_collisions([0.0, 0.0, 0.0], 0.3, np.zeros((1, 2)), np.ones(1))
    assert len(CircularObstacles.empty()) == 0 and len(MovingObstacles.empty()) == 0


def test_clearance_is_signed_distance():
    obstacles = CircularObstacles(np.array([[0.0, 0.0], [5.0, 0.0]]), np.array([1.0, 2.0]))
    np.testing.assert_allclose(obstacles.clearance([[2.0, 0.0], [0.0, 0.5], [5.0, 3.0]]), [1.0, -0.5, 1.0])
    assert CircularObstacles.empty().clearance([1.0, 1.0]) == np.inf
