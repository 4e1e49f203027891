"""The driving reward: its box minimum against brute force and python-fcl, the road test, the range [0, 1]."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.kernels import box_minima, has_compiled_minimum
from minimaxplan.kernels.driving_reward import interval_cos_range
from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.scenarios.driving_reward import DrivingReward, road_pieces
from minimaxplan.scenarios.geometry import _fcl
from minimaxplan.scenarios.road import highway_road, tjunction_road
from minimaxplan.scenarios.vehicles import vehicle_corners

HIGHWAY = highway_road()
TJUNCTION = tjunction_road()
EMPTY = np.array([np.inf, np.inf, -np.inf, -np.inf])


def _fcl_rectangle_meets_box(centre, psi, box, grow=0.0):
    """python-fcl: the 5 m x 2 m rectangle at ``centre`` and heading psi against an axis-aligned box (grown)."""
    fcl = _fcl()
    c, s = np.cos(psi), np.sin(psi)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    rect = fcl.CollisionObject(fcl.Box(5.0, 2.0, 1.0), fcl.Transform(rotation, np.array([centre[0], centre[1], 0.0])))
    lo, hi = np.asarray(box[:2]) - grow, np.asarray(box[2:]) + grow
    mid = (lo + hi) / 2
    obstacle = fcl.CollisionObject(
        fcl.Box(float(hi[0] - lo[0]), float(hi[1] - lo[1]), 1.0), fcl.Transform(np.array([mid[0], mid[1], 0.0]))
    )
    return fcl.collide(rect, obstacle, fcl.CollisionRequest(), fcl.CollisionResult()) > 0


def _obstacle_reward(boxes):
    table = np.asarray(boxes, dtype=float).reshape(1, -1, 4)
    return DrivingReward(table, 0, None, speed_weight=0.4)


def _random_box(rng, centre_range=6.0, size=(0.5, 5.0)):
    centre = rng.uniform(-centre_range, centre_range, 2)
    half = rng.uniform(*size, 2) / 2
    return np.concatenate([centre - half, centre + half])


def test_the_family_is_registered_and_reads_x_y_v_psi():
    reward = _obstacle_reward(EMPTY)
    assert has_compiled_minimum(reward.kernel_params) and reward.min_state_dim == 4
    assert reward.horizon == 0 and reward.to_dict()["family"] == "driving"


def test_the_rectangle_box_test_at_points_is_fcls():
    rng = np.random.default_rng(1)
    agree = 0
    for _ in range(1500):
        box = _random_box(rng)
        centre, psi = rng.uniform(-4, 4, 2), rng.uniform(-np.pi, np.pi)
        state = np.array([centre[0], centre[1], 20.0, psi])
        collided = _obstacle_reward(box).box_minimum(state, state)[1]
        inner, outer = (
            _fcl_rectangle_meets_box(centre, psi, box, -1e-7),
            _fcl_rectangle_meets_box(centre, psi, box, 1e-7),
        )
        if inner == outer:  # not within 1e-7 m of touching
            assert collided == inner
            agree += 1
    assert agree > 1400


def _check_fixed_heading(box, psi, lo, hi) -> bool:
    """The box minimum over positions ``[lo, hi]`` at heading ``psi`` against python-fcl; returns whether it collided.

    Clear: no position of a 7 x 7 grid over the box (its corners included) has a rectangle
    that fcl finds meeting the obstacle, and the value is the free one. Colliding: the value
    is exactly 0 and `box_argmin` gives a witness inside the box whose rectangle fcl finds
    meeting it.
    """
    lower, upper = np.array([*lo, 20.0, psi]), np.array([*hi, 25.0, psi])
    reward = _obstacle_reward(box)
    value, collided = reward.box_minimum(lower, upper)
    if collided:
        assert value == 0.0
        witness = reward.box_argmin(lower, upper)
        assert np.all(witness >= lower) and np.all(witness <= upper)
        assert _fcl_rectangle_meets_box(witness[:2], psi, box, 1e-6)
    else:
        xs, ys = np.meshgrid(np.linspace(lo[0], hi[0], 7), np.linspace(lo[1], hi[1], 7))
        assert not any(_fcl_rectangle_meets_box((x, y), psi, box, -1e-7) for x, y in zip(xs.ravel(), ys.ravel()))
        assert value == pytest.approx((1 + 0.4 * 20 / 30) / 1.4)
    return bool(collided)


def _box_of(centre, size):
    half = np.asarray(size, dtype=float) / 2
    return np.concatenate([np.asarray(centre, dtype=float) - half, np.asarray(centre, dtype=float) + half])


_CENTRE = st.tuples(st.floats(-8.0, 8.0), st.floats(-8.0, 8.0))
_SIZE = st.tuples(st.floats(0.5, 5.0), st.floats(0.5, 5.0))
_CORNER = st.tuples(st.floats(-4.0, 4.0), st.floats(-4.0, 4.0))


@settings(max_examples=150, deadline=None)
@given(
    centre=_CENTRE,
    size=_SIZE,
    psi=st.floats(-np.pi, np.pi),
    p_lo=_CORNER,
    width=st.tuples(st.floats(0.0, 3.0), st.floats(0.0, 3.0)),
)
def test_the_box_minimum_at_a_fixed_heading_is_exact_against_fcl(centre, size, psi, p_lo, width):
    lo = np.array(p_lo)
    _check_fixed_heading(_box_of(centre, size), psi, lo, lo + np.array(width))


def test_the_fixed_heading_check_sees_both_cases():
    """The geometry of the test above exercises both verdicts: of 300 seeded draws, both clear and colliding boxes."""
    rng = np.random.default_rng(2)
    hits = 0
    for _ in range(300):
        lo = rng.uniform(-4, 4, 2)
        hits += _check_fixed_heading(
            _random_box(rng, 8.0), rng.uniform(-np.pi, np.pi), lo, lo + rng.uniform(0.0, 3.0, 2)
        )
    assert 50 < hits < 280


@settings(max_examples=100, deadline=None)
@given(
    centre=_CENTRE,
    size=_SIZE,
    psi_lo=st.floats(-np.pi, np.pi),
    psi_width=st.floats(0.0, 1.5),
    p_lo=_CORNER,
    width=st.tuples(st.floats(0.0, 2.0), st.floats(0.0, 2.0)),
    seed=st.integers(0, 2**32 - 1),
)
def test_over_a_heading_interval_the_minimum_is_a_sound_bound(centre, size, psi_lo, psi_width, p_lo, width, seed):
    """No pose of a box reported clear over a heading interval (its corners at both extreme headings, 24 random)
    has a rectangle that fcl finds meeting the obstacle."""
    box = _box_of(centre, size)
    lo = np.array(p_lo)
    hi = lo + np.array(width)
    psi_hi = psi_lo + psi_width
    if not _obstacle_reward(box).box_minimum([*lo, 20.0, psi_lo], [*hi, 20.0, psi_hi])[1]:
        rng = np.random.default_rng(seed)
        corners = [(x, y) for x in (lo[0], hi[0]) for y in (lo[1], hi[1])]
        poses = [(c, psi) for c in corners for psi in (psi_lo, psi_hi)]
        poses += [(rng.uniform(lo, hi), rng.uniform(psi_lo, psi_hi)) for _ in range(24)]
        assert not any(_fcl_rectangle_meets_box(c, psi, box, -1e-7) for c, psi in poses)


@settings(max_examples=200, deadline=None)
@given(st.floats(-20, 20), st.floats(0, 7))
def test_the_cosine_range_over_an_interval_is_exact(low, width):
    bottom, top = interval_cos_range(low, low + width)
    grid = np.cos(np.linspace(low, low + width, 2001))
    assert bottom <= grid.min() + 1e-12 and top >= grid.max() - 1e-12
    assert bottom >= grid.min() - 1e-5 and top <= grid.max() + 1e-5  # the extremes are attained


@pytest.mark.parametrize("road", [HIGHWAY, TJUNCTION], ids=["highway", "tjunction"])
def test_the_road_test_at_points_is_the_worlds(road):
    rng = np.random.default_rng(4)
    table = np.tile(EMPTY, (1, 1, 1))
    reward = DrivingReward(table, 0, road, speed_weight=0.4)
    if road is HIGHWAY:
        x = np.column_stack([rng.uniform(-10, 2010, 4000), rng.uniform(-5, 13, 4000)])
    else:  # near the lanes
        lanes = rng.integers(0, len(TJUNCTION), 4000)
        s = rng.uniform(-5, 105, 4000)
        x = TJUNCTION.position_at(lanes, np.minimum(s, TJUNCTION.lengths[lanes] + 5), rng.uniform(-4, 4, 4000))
    states = np.column_stack([x, np.full(4000, 5.0), rng.uniform(-np.pi, np.pi, 4000)])
    off = ~road.on_road(vehicle_corners(states)).all(axis=1)
    collided = reward.box_minimum(states, states)[1]
    assert 300 < off.sum() < 3700
    assert np.array_equal(collided, off)


def test_the_road_test_over_boxes_is_sound():
    rng = np.random.default_rng(5)
    reward = DrivingReward(np.tile(EMPTY, (1, 1, 1)), 0, TJUNCTION)
    inside = 0
    for _ in range(400):
        p_lo = rng.uniform(-20, 20, 2)
        p_hi = p_lo + rng.uniform(0.0, 1.0, 2)
        psi = rng.uniform(-np.pi, np.pi)
        psi_hi = psi + rng.choice([0.0, rng.uniform(0.0, 0.3)])
        if not reward.box_minimum([*p_lo, 5.0, psi], [*p_hi, 5.0, psi_hi])[1]:
            inside += 1
            c = rng.uniform(p_lo, p_hi, (30, 2))
            states = np.column_stack([c, np.full(30, 5.0), rng.uniform(psi, psi_hi, 30)])
            assert TJUNCTION.on_road(vehicle_corners(states)).all()
    assert inside > 20


def test_the_highway_is_one_strip_and_the_junction_its_lanes_and_area():
    strips, arcs, areas = road_pieces(HIGHWAY)
    assert strips.tolist() == [[0.0, 4.0, 1.0, 0.0, 2000.0, 6.0]] and arcs.shape == (0, 7) and areas.shape == (0, 4)
    strips, arcs, areas = road_pieces(TJUNCTION, 0.5)
    assert strips.shape == (8, 6) and arcs.shape == (4, 7) and areas.tolist() == [[-4.5, -11.5, 4.5, -3.5]]
    # a box across two highway lanes is on the road
    reward = DrivingReward.highway(np.tile(EMPTY, (1, 1, 1)), 0, HIGHWAY)
    assert not reward.box_minimum([100.0, 1.0, 25.0, 0.0], [101.0, 3.0, 25.0, 0.0])[1]


def test_highway_reward_values_and_the_right_lane_preference():
    reward = DrivingReward.highway(np.tile(EMPTY, (1, 1, 1)), 0, HIGHWAY)
    states = np.array([[100.0, 0.0, 30.0, 0.0], [100.0, 4.0, 30.0, 0.0], [100.0, 8.0, 15.0, 0.0]])
    value, collided = reward.box_minimum(states, states)
    assert np.allclose(value, [1.0, (1 + 0.4 + 0.05) / 1.5, (1 + 0.2) / 1.5]) and not collided.any()
    # over a box: the lowest speed and the worst lane the y-interval touches
    value, _ = reward.box_minimum([100.0, -0.5, 20.0, 0.0], [100.5, 5.0, 28.0, 0.0])
    assert value == pytest.approx((1 + 0.4 * 20 / 30 + 0.1 * 0.5) / 1.5)


def test_tjunction_reward_is_progress_to_the_goal():
    goal = TJUNCTION.position_at(TJUNCTION.index("west_out"), 25.0)
    reward = DrivingReward.tjunction(np.tile(EMPTY, (1, 1, 1)), 0, TJUNCTION, goal, 80.0)
    at_goal = np.array([goal[0], goal[1], 0.0, np.pi])
    assert reward.box_minimum(at_goal, at_goal)[0] == pytest.approx(1.0)
    start = np.array([2.0, -51.0, 4.5, np.pi / 2])
    d = np.hypot(*(start[:2] - goal))
    assert reward.box_minimum(start, start)[0] == pytest.approx((1 + 0.4 * (1 - min(d / 80, 1))) / 1.4)


def _free_reward(kind: str) -> DrivingReward:
    if kind == "highway":
        return DrivingReward.highway(np.tile(EMPTY, (1, 1, 1)), 0, HIGHWAY)
    goal = TJUNCTION.position_at(TJUNCTION.index("west_out"), 25.0)
    if kind == "goal region":  # a region that the random boxes straddle, enter and miss
        goal = np.array([53.0, 1.0, 56.0, 4.0])
    return DrivingReward(np.tile(EMPTY, (1, 1, 1)), 0, None, goal_weight=0.4, goal=goal, goal_scale=80.0)


@settings(max_examples=150, deadline=None)
@given(
    kind=st.sampled_from(["highway", "tjunction", "goal region"]),
    lower=st.tuples(st.floats(50.0, 60.0), st.floats(-1.5, 9.0), st.floats(0.0, 35.0)),
    width=st.tuples(st.floats(0.0, 3.0), st.floats(0.0, 6.0), st.floats(0.0, 5.0)),
)
def test_the_free_minimum_over_a_box_is_exact_and_attained(kind, lower, width):
    """The free value's minimum over a box is below every point of a 7^3 grid over it, and attained at
    `box_argmin`, inside the box."""
    reward = _free_reward(kind)
    low = np.array([*lower, 0.0])
    high = low + np.array([*width, 0.0])
    high[1] = min(high[1], 9.5)
    value, collided = reward.box_minimum(low, high)
    if collided:
        return
    grid = np.stack(np.meshgrid(*[np.linspace(a, b, 7) for a, b in zip(low, high)]), -1).reshape(-1, 4)
    assert reward.free_value(grid).min() >= value - 1e-12
    point = reward.box_argmin(low, high)
    assert np.all(point >= low) and np.all(point <= high)
    assert reward.free_value(point) == pytest.approx(value, abs=1e-12)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.floats(-20, 20), min_size=4, max_size=4),
    st.lists(st.floats(0, 5), min_size=4, max_size=4),
    st.integers(-3, 8),
)
def test_the_reward_lies_in_zero_one(low, width, t):
    rng = np.random.default_rng(abs(int(sum(low) * 1000)) % 2**32)
    boxes = np.array([[_random_box(rng, 20.0) for _ in range(3)] for _ in range(6)])
    goal = np.array([0.0, 0.0])
    for reward in (
        DrivingReward.highway(boxes, 0, HIGHWAY),
        DrivingReward.tjunction(boxes, 0, TJUNCTION, goal, 30.0),
    ):
        lower = np.array(low)
        value, collided = reward.box_minimum(lower, lower + np.array(width), t)
        assert 0.0 <= value <= 1.0 and (not collided or value == 0.0)


def test_beyond_the_table_the_reward_is_zero_and_terminal_and_empty_rows_never_collide():
    table = np.tile(EMPTY, (3, 2, 1))
    table[1, 0] = [-1.0, -1.0, 1.0, 1.0]
    reward = DrivingReward(table, 10, None, speed_weight=0.4)
    state = np.array([0.0, 0.0, 30.0, 0.0])
    value, collided = reward.box_minimum(state, state, np.arange(8, 15))
    assert collided.tolist() == [True, True, False, True, False, True, True]
    assert value.tolist()[2] == value.tolist()[4] == pytest.approx(1.0)
    assert np.array_equal(box_minima(reward.kernel_params, state, state, 12), (value[4], collided[4]))
    moved = reward.with_obstacles(np.tile(EMPTY, (1, 1, 1)), 0)
    assert moved.horizon == 0 and moved.speed_weight == 0.4


def test_a_point_goal_is_the_region_of_zero_size():
    point = DrivingReward(np.tile(EMPTY, (1, 1, 1)), 0, goal_weight=0.4, goal=[3.0, -2.0], goal_scale=10.0)
    region = DrivingReward(np.tile(EMPTY, (1, 1, 1)), 0, goal_weight=0.4, goal=[3.0, -2.0, 3.0, -2.0], goal_scale=10.0)
    assert point.goal.tolist() == [3.0, -2.0, 3.0, -2.0] and not point.goal.flags.writeable
    states = np.random.default_rng(2).uniform(-10, 10, (50, 4))
    assert np.array_equal(point.free_value(states), region.free_value(states))
    d = np.hypot(states[:, 0] - 3.0, states[:, 1] + 2.0)
    assert np.allclose(point.free_value(states), (1 + 0.4 * (1 - np.minimum(d / 10, 1))) / 1.4, rtol=0, atol=1e-15)


@pytest.mark.parametrize("seed", [0, 3])
def test_the_tjunction_reward_is_highest_exactly_where_the_world_counts_the_goal(seed):
    from minimaxplan.scenarios.driving_reward import world_reward
    from minimaxplan.scenarios.road_world import make_road_world

    world = make_road_world("tjunction", seed=seed)
    reward = world_reward(world)
    lane = world.goal_lanes[0]
    rng = np.random.default_rng(seed)
    s = rng.uniform(world.goal_s - 20, world.road.lengths[lane], 400)
    offset = rng.uniform(-3.0, 3.0, 400)
    points = np.asarray(world.road.position_at(lane, s, offset)).reshape(400, 2)
    for x, y in points:
        states = np.array(world.traffic.states)
        states[0, :2] = x, y
        world.traffic = world.traffic.evolve(states=states)
        state = np.array([x, y, 5.0, np.pi])
        at_top = reward.free_value(state) == pytest.approx(1.0, abs=0.0)
        assert at_top == world.goal_reached(), (x, y)


def test_malformed_arguments_are_rejected():
    with pytest.raises(DimensionError, match=r"\(H\+1, m, 4\)"):
        DrivingReward(np.zeros((3, 4)), 0)
    with pytest.raises(InputError, match="NaN"):
        DrivingReward(np.full((1, 1, 4), np.nan), 0)
    with pytest.raises(InputError, match="lo <= hi"):
        DrivingReward(np.array([[[1.0, 0.0, 0.0, 1.0]]]), 0)
    with pytest.raises(InputError, match="at most one"):
        DrivingReward(np.tile(EMPTY, (1, 1, 1)), 0, lane_weight=0.1, lane_values=[1.0], goal_weight=0.4, goal=[0, 0])
    with pytest.raises(InputError, match="lane_values"):
        DrivingReward(np.tile(EMPTY, (1, 1, 1)), 0, lane_weight=0.1)
    with pytest.raises(InputError, match="goal"):
        DrivingReward(np.tile(EMPTY, (1, 1, 1)), 0, goal_weight=0.4)
    with pytest.raises(DimensionError, match=r"goal must have shape \(2,\) or \(4,\), got shape \(3,\)"):
        DrivingReward(np.tile(EMPTY, (1, 1, 1)), 0, goal_weight=0.4, goal=[0, 0, 1])
    with pytest.raises(InputError, match="x_lo <= x_hi"):
        DrivingReward(np.tile(EMPTY, (1, 1, 1)), 0, goal_weight=0.4, goal=[1, 0, 0, 1])
    with pytest.raises(InputError, match="road"):
        DrivingReward(np.tile(EMPTY, (1, 1, 1)), 0, road="highway")
    with pytest.raises(InputError, match="moving_positions"):
        DrivingReward(np.tile(EMPTY, (1, 1, 1)), 0).evaluate(np.zeros(4), moving_positions=np.zeros((0, 2)))
