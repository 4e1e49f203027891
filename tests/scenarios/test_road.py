"""Road geometry: exact Frenet maps of straight and arc lanes, the vectorised road maps, the two roads."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import DimensionError, InputError
from minimaxplan.scenarios.road import (
    ArcLane,
    HighwayGeometry,
    Road,
    StraightLane,
    TJunctionGeometry,
    highway_road,
    tjunction_road,
    wrap_to_pi,
)

coords = st.floats(-500, 500)
small = st.floats(-50, 50)


def _close(a, b):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return np.allclose(a, b, rtol=0.0, atol=1e-9 * (1.0 + np.max(np.abs(b))))


@given(
    x0=coords,
    y0=coords,
    angle=st.floats(-np.pi, np.pi),
    length=st.floats(1.0, 500.0),
    s=st.floats(-600, 600),
    offset=small,
)
def test_straight_lane_frenet_maps_invert_each_other(x0, y0, angle, length, s, offset):
    start = np.array([x0, y0])
    lane = StraightLane(start, start + length * np.array([np.cos(angle), np.sin(angle)]))
    p = lane.position(s, offset)
    s_back, off_back = lane.local_coordinates(p[0], p[1])
    assert _close([s_back, off_back], [s, offset])
    q = lane.position(*lane.local_coordinates(x0 + offset, y0 + s))
    assert _close(q, [x0 + offset, y0 + s])


@given(
    cx=coords,
    cy=coords,
    radius=st.floats(3.0, 60.0),
    start=st.floats(-np.pi, np.pi),
    sweep=st.floats(0.1, 2 * np.pi - 0.1),
    left=st.booleans(),
    u=st.floats(-0.99, 0.99),
    v=st.floats(-0.95, 0.95),
)
def test_arc_lane_frenet_maps_invert_each_other(cx, cy, radius, start, sweep, left, u, v):
    lane = ArcLane(np.array([cx, cy]), radius, start, sweep if left else -sweep, width=min(4.0, radius))
    d = lane.direction_sign
    s = lane.length / 2 + u * np.pi * radius  # |s - length / 2| < pi radius
    offset = d * v * radius  # radius - d offset = radius (1 - v) > 0
    p = lane.position(s, offset)
    s_back, off_back = lane.local_coordinates(p[0], p[1])
    assert _close([s_back, off_back], [s, offset])
    q = lane.position(*lane.local_coordinates(cx + radius * (1 + u), cy + radius * v))
    assert _close(q, [cx + radius * (1 + u), cy + radius * v])


@given(
    radius=st.floats(3.0, 60.0),
    start=st.floats(-np.pi, np.pi),
    sweep=st.floats(0.2, 3.0),
    left=st.booleans(),
    fraction=st.floats(0.05, 0.95),
)
def test_arc_heading_and_curvature_are_the_derivatives_of_the_centre_line(radius, start, sweep, left, fraction):
    lane = ArcLane(np.zeros(2), radius, start, sweep if left else -sweep)
    s, h = fraction * lane.length, 1e-6 * radius
    tangent = (lane.position(s + h) - lane.position(s - h)) / (2 * h)
    heading = float(lane.heading(s))
    assert np.allclose(tangent, [np.cos(heading), np.sin(heading)], atol=1e-5)
    dheading = (lane.heading(s + h) - lane.heading(s - h)) / (2 * h)
    assert np.isclose(dheading, lane.curvature(s), rtol=1e-6)
    assert np.isclose(float(lane.curvature(s)), (1 if left else -1) / radius)
    # left offsets are on the left of the direction of travel
    left_normal = np.array([-np.sin(heading), np.cos(heading)])
    assert np.allclose(lane.position(s, 1.0) - lane.position(s), left_normal, atol=1e-9 * radius)


def test_road_maps_are_the_lanes_maps_bit_for_bit():
    rng = np.random.default_rng(0)
    for road in (highway_road(), tjunction_road()):
        pts = rng.uniform(-120, 120, size=(50, 2))
        for i, lane in enumerate(road.lanes):
            s, off = road.frenet(i, pts[:, 0], pts[:, 1])
            s_ref, off_ref = lane.local_coordinates(pts[:, 0], pts[:, 1])
            assert np.array_equal(s, s_ref) and np.array_equal(off, off_ref)
            grid = np.linspace(0, lane.length, 7)
            assert np.allclose(road.position_at(i, grid, 0.7), lane.position(grid, 0.7), atol=1e-12)
            assert np.allclose(road.heading_at(i, grid), lane.heading(grid), atol=1e-12)
            assert np.allclose(road.curvature_at(i, grid), lane.curvature(grid))
    # broadcasting: lanes against points
    road = tjunction_road()
    s, _ = road.frenet(np.arange(len(road)), pts[:, None, 0], pts[:, None, 1])
    assert s.shape == (50, len(road))


def test_highway_geometry():
    road = highway_road()
    assert len(road) == 3 and road.side_lanes(1) == (0, 1, 2)
    assert np.allclose(road.widths, 4.0) and np.allclose(road.lengths, 2000.0)
    for k in range(3):
        assert np.allclose(road.lanes[k].start, [0.0, 4.0 * k])
        assert float(road.heading_at(k, 10.0)) == 0.0
    assert not road.conflicts.any()
    ys = np.array([-2.0, 0.0, 5.0, 10.0, -2.01, 10.01])
    on = road.on_road(np.stack([np.full(6, 500.0), ys], axis=1))
    assert on.tolist() == [True, True, True, True, False, False]  # closed edges
    assert road.on_road([[500.0, 10.2]], margin=0.25)[0]
    assert HighwayGeometry().length >= 200 + 250


def test_tjunction_geometry_is_intersection_v0_without_the_north_arm():
    g = TJunctionGeometry()
    road = tjunction_road(g)
    assert g.outer_distance == 11.0 and g.left_turn_radius == 13.0
    ego = road.route("south_in", "south_west", "west_out")
    assert np.allclose(road.position_at(ego[0], 0.0), [2.0, -111.0])
    assert np.allclose(road.position_at(ego[1], 0.0), [2.0, -11.0])
    assert np.allclose(road.position_at(ego[1], road.lengths[ego[1]]), [-11.0, 2.0])
    assert np.isclose(float(road.heading_at(ego[1], road.lengths[ego[1]])) % (2 * np.pi), np.pi)
    assert np.isclose(road.lengths[ego[1]], 13.0 * np.pi / 2)
    # every route is continuous: positions and headings match at each connection
    for a, b in road.connections:
        end = road.lanes[a].length
        assert np.allclose(road.position_at(a, end), road.position_at(b, 0.0), atol=1e-9)
        assert np.isclose(wrap_to_pi(road.heading_at(a, end) - road.heading_at(b, 0.0)), 0.0, atol=1e-9)
    names = road.names
    conflicts = {names[b] for b in np.flatnonzero(road.conflicts[road.index("south_west")])}
    assert conflicts == {"west_east", "east_west", "east_south"}  # crossing, merge, crossing
    prio = dict(zip(names, road.priorities))
    assert prio["south_west"] < prio["south_east"] < prio["east_south"] < prio["west_east"] == prio["east_west"]
    # the junction is road; the curbs' corners are not
    assert road.on_road([[0.0, -8.0], [0.0, 0.0], [-3.0, -10.0], [2.0, -50.0]]).all()
    assert not road.on_road([[8.0, -8.0], [-8.0, -8.0], [0.0, 4.5], [20.0, -20.0]]).any()


def test_lane_membership_and_edges():
    road = tjunction_road()
    arc = road.index("south_west")
    right, left = road.lane_edges(arc, 9)
    assert np.allclose(np.linalg.norm(right - [-11.0, -11.0], axis=1), 15.0)  # right of a left turn: outside
    assert np.allclose(np.linalg.norm(left - [-11.0, -11.0], axis=1), 11.0)
    member = road.lane_membership(np.concatenate([right, left]))
    assert member[:, arc].all()
    mid = road.position_at(arc, road.lengths[arc] / 2, 2.0 + 1e-6)
    assert not road.lane_membership(mid)[arc]


def test_road_rejects_bad_input():
    with pytest.raises(InputError, match="width"):
        StraightLane(np.zeros(2), np.ones(2), width=0.0)
    with pytest.raises(InputError, match="start != end"):
        StraightLane(np.zeros(2), np.zeros(2))
    with pytest.raises(DimensionError, match=r"start must have shape \(2,\)"):
        StraightLane(np.zeros(3), np.ones(2))
    with pytest.raises(InputError, match="sweep"):
        ArcLane(np.zeros(2), 5.0, 0.0, 0.0)
    with pytest.raises(InputError, match="width must be < 2 radius"):
        ArcLane(np.zeros(2), 1.0, 0.0, 1.0, width=4.0)
    road = tjunction_road()
    with pytest.raises(InputError, match="no lane called 'north_in'"):
        road.index("north_in")
    with pytest.raises(InputError, match="does not connect"):
        road.route("south_in", "east_out")
    with pytest.raises(DimensionError, match=r"points must have shape \(\.\.\., 2\)"):
        road.on_road(np.zeros((3, 3)))
    with pytest.raises(InputError, match="apart"):
        Road(
            lanes=(
                StraightLane(np.zeros(2), np.array([1.0, 0.0])),
                StraightLane(np.array([2.0, 0.0]), np.array([3.0, 0.0])),
            ),
            names=("a", "b"),
            connections=((0, 1),),
        )
    with pytest.raises(InputError, match="unique names"):
        Road(lanes=(StraightLane(np.zeros(2), np.ones(2)),), names=("a", "b"))


@given(angle=st.floats(-100, 100))
@settings(max_examples=50)
def test_wrap_to_pi(angle):
    wrapped = float(wrap_to_pi(angle))
    assert -np.pi <= wrapped < np.pi
    assert np.isclose(np.cos(wrapped), np.cos(angle), atol=1e-9) and np.isclose(
        np.sin(wrapped), np.sin(angle), atol=1e-9
    )
