"""Reward families: the exact box minimum is attained in the box and never beaten by a sample."""

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.models.errors import DimensionError, InputError, NonFiniteError
from minimaxplan.scenarios.geometry import CircularObstacles, MovingObstacles
from minimaxplan.scenarios.rewards import GoalReward, RewardFamily, SpeedLaneReward

seeds = st.integers(0, 2**31 - 1)


def grid_of_box(lo, hi, n):
    """All points of an n-per-axis grid of the box [lo, hi] (corners included)."""
    axes = [np.linspace(a, b, n) for a, b in zip(lo, hi)]
    return np.array(list(itertools.product(*axes)))


def random_obstacles(rng):
    n = rng.integers(0, 6)
    obstacles = CircularObstacles(rng.uniform(-4, 4, (n, 2)), rng.uniform(0.2, 1.0, n))
    m = rng.integers(0, 3)
    moving = MovingObstacles(
        rng.uniform(-4, 4, (m, 2)),
        rng.uniform(-1, 1, (m, 2)),
        rng.uniform(0.2, 0.4, m),
        velocity_uncertainty=rng.uniform(0, 0.3),
        dt=0.1,
        time0=int(rng.integers(0, 3)),
    )
    return obstacles, moving


def random_box(rng, p, scale=2.0):
    lo = rng.uniform(-5, 5, p)
    width = rng.uniform(0, scale, p)
    width[rng.random(p) < 0.2] = 0.0  # degenerate sides
    return lo, lo + width


def check_exact_minimum(reward, lo, hi, t, n_grid):
    minimum, collided = reward.box_minimum(lo, hi, t)
    argmin = reward.box_argmin(lo, hi, t)
    # the minimiser lies in the box and attains the minimum
    assert np.all(lo <= argmin) and np.all(argmin <= hi)
    value_at_argmin, collided_at_argmin = reward.evaluate(argmin, t)
    assert value_at_argmin == pytest.approx(float(minimum), abs=1e-12)
    assert bool(collided_at_argmin) == bool(collided)
    # no sampled point of the box does better
    grid = grid_of_box(lo, hi, n_grid)
    values = reward.value(grid, t)
    assert np.all(values >= minimum - 1e-12)
    assert 0.0 <= minimum <= 1.0
    return minimum, collided, values


@given(seeds, st.integers(0, 40), st.floats(0, 0.6))
def test_goal_reward_box_minimum_is_exact(seed, t, robot_radius):
    rng = np.random.default_rng(seed)
    obstacles, moving = random_obstacles(rng)
    reward = GoalReward(rng.uniform(-5, 5, 2), obstacles=obstacles, moving_obstacles=moving, robot_radius=robot_radius)
    lo, hi = random_box(rng, 2)
    minimum, collided, values = check_exact_minimum(reward, lo, hi, t, 15)
    if not collided:
        # the grid contains the corners, so it finds the collision-free minimum exactly
        assert values.min() == pytest.approx(float(minimum), abs=1e-12)


@given(seeds, st.integers(0, 40))
def test_goal_reward_reads_positions_out_of_longer_states(seed, t):
    rng = np.random.default_rng(seed)
    obstacles, moving = random_obstacles(rng)
    reward = GoalReward(
        rng.uniform(-5, 5, 2), obstacles=obstacles, moving_obstacles=moving, robot_radius=0.3, position_indices=(3, 1)
    )
    lo, hi = random_box(rng, 4)
    check_exact_minimum(reward, lo, hi, t, 5)
    # only coordinates 3 and 1 matter
    moved_lo, moved_hi = lo.copy(), hi.copy()
    moved_lo[[0, 2]] -= 10.0
    assert reward.box_minimum(moved_lo, moved_hi, t)[0] == reward.box_minimum(lo, hi, t)[0]


@given(seeds, st.integers(1, 2), st.booleans(), st.integers(0, 30))
def test_speed_lane_reward_box_minimum_is_exact(seed, n_speed, with_lane, t):
    rng = np.random.default_rng(seed)
    obstacles, moving = random_obstacles(rng)
    lane_weight = float(rng.uniform(0, 1)) if with_lane else 0.0
    reward = SpeedLaneReward(
        target_speed=float(rng.uniform(-3, 5)),
        speed_range=float(rng.uniform(0.5, 6)),
        speed_indices=(2, 3)[:n_speed],
        lateral_index=1 if with_lane else None,
        lane_width=float(rng.uniform(0.5, 3)),
        n_lanes=int(rng.integers(2, 5)),
        speed_weight=1.0 - lane_weight,
        lane_weight=lane_weight,
        obstacles=obstacles,
        moving_obstacles=moving,
        robot_radius=0.25,
    )
    lo, hi = random_box(rng, 4, scale=3.0)
    # lanes are a staircase: the grid is fine enough to contain y = lo_y, the minimiser
    check_exact_minimum(reward, lo, hi, t, 9)


def test_speed_interval_of_a_box_containing_the_origin():
    reward = SpeedLaneReward(
        target_speed=2.0,
        speed_range=4.0,
        speed_indices=(0, 1),
        lateral_index=None,
        speed_weight=1.0,
        lane_weight=0.0,
        position_indices=(2, 3),
    )
    lo, hi = np.array([-1.0, -0.5, 0, 0]), np.array([1.0, 3.0, 0, 0])
    # speeds over the box span [0, sqrt(1 + 9)]: worst deviation max(2, sqrt(10) - 2) = 2
    assert reward.box_minimum(lo, hi)[0] == pytest.approx(0.5)
    np.testing.assert_allclose(reward.box_argmin(lo, hi)[:2], [0.0, 0.0])


def test_goal_minimum_is_farthest_corner_not_centre():
    reward = GoalReward([0.0, 0.0])
    lo, hi = np.array([1.0, -2.0]), np.array([3.0, 1.0])
    assert reward.box_minimum(lo, hi)[0] == pytest.approx(1 / (1 + np.hypot(3.0, 2.0)))
    np.testing.assert_allclose(reward.box_argmin(lo, hi), [3.0, -2.0])
    assert reward.value([2.0, -0.5]) > reward.box_minimum(lo, hi)[0]  # the centre is optimistic


def test_collision_in_the_middle_of_an_edge_is_found():
    # the obstacle pokes into the box's grown edge between corners: a 4-corner test misses it
    obstacle = CircularObstacles([[0.5, 1.5]], [0.3])
    reward = GoalReward([0.0, 0.0], obstacles=obstacle, robot_radius=0.25)
    lo, hi = np.array([0.0, 0.0]), np.array([1.0, 1.0])
    corners = grid_of_box(lo, hi, 2)
    assert not reward.evaluate(corners)[1].any()
    minimum, collided = reward.box_minimum(lo, hi)
    assert collided and minimum == 0.0
    np.testing.assert_allclose(reward.box_argmin(lo, hi), [0.5, 1.0])


def test_vectorised_over_leading_dimensions_and_times():
    rng = np.random.default_rng(5)
    obstacles, _ = random_obstacles(rng)
    moving = MovingObstacles([[0.0, 0.0]], [[1.0, 0.0]], [0.3], velocity_uncertainty=0.2, dt=0.5)
    reward = GoalReward([4.0, 4.0], obstacles=obstacles, moving_obstacles=moving, robot_radius=0.3)
    lo = rng.uniform(-5, 5, (3, 4, 2))
    hi = lo + rng.uniform(0, 1, (3, 4, 2))
    t = np.arange(4)
    minimum, collided = reward.box_minimum(lo, hi, t)
    assert minimum.shape == collided.shape == (3, 4)
    for i in range(3):
        for j in range(4):
            m, c = reward.box_minimum(lo[i, j], hi[i, j], t[j])
            assert m == minimum[i, j] and c == collided[i, j]
    raw = reward.box_minimum_raw(lo, hi, t)
    np.testing.assert_array_equal(raw[0], minimum)


@given(seeds, st.integers(0, 20))
def test_true_pedestrian_positions_inside_their_boxes_never_collide_unseen(seed, t):
    rng = np.random.default_rng(seed)
    moving = MovingObstacles(
        rng.uniform(-2, 2, (3, 2)), rng.uniform(-1, 1, (3, 2)), np.full(3, 0.3), velocity_uncertainty=0.3, dt=0.1
    )
    reward = GoalReward([5.0, 5.0], moving_obstacles=moving, robot_radius=0.3)
    olo, ohi = moving.boxes(t)
    true_positions = rng.uniform(olo, ohi)
    robots = rng.uniform(-3, 3, (50, 2))
    true_reward, true_collided = reward.evaluate(robots, t, moving_positions=true_positions)
    predicted_reward, predicted_collided = reward.evaluate(robots, t)
    assert np.all(predicted_collided[true_collided])
    assert np.all(predicted_reward <= true_reward)


def test_reward_validation():
    reward = GoalReward([0.0, 0.0])
    with pytest.raises(DimensionError, match=r"goal must have shape \(2,\), got shape \(3,\)"):
        GoalReward([0.0, 0.0, 1.0])
    with pytest.raises(DimensionError, match=r"lower and upper must have the same shape, got \(2,\) and \(3,\)"):
        reward.box_minimum([0.0, 0.0], [1.0, 1.0, 1.0])
    with pytest.raises(DimensionError, match=r"states must have shape \(\.\.\., p\) with p >= 4 .*got shape \(2,\)"):
        GoalReward([0.0, 0.0], position_indices=(3, 1)).value([0.0, 0.0])
    with pytest.raises(InputError, match="lower must be <= upper"):
        reward.box_minimum([1.0, 0.0], [0.0, 1.0])
    with pytest.raises(NonFiniteError, match="lower"):
        reward.box_minimum([np.nan, 0.0], [1.0, 1.0])
    with pytest.raises(DimensionError, match="position_indices must have length 2, got length 3"):
        GoalReward([0.0, 0.0], position_indices=(0, 1, 2))
    with pytest.raises(InputError, match="robot_radius must be >= 0"):
        GoalReward([0.0, 0.0], robot_radius=-1.0)
    with pytest.raises(InputError, match="obstacles must be CircularObstacles or None, got ndarray"):
        GoalReward([0.0, 0.0], obstacles=np.zeros((1, 2)))
    with pytest.raises(InputError, match=r"speed_weight \+ lane_weight must be 1, got 0.5 \+ 0.4"):
        SpeedLaneReward(1.0, 1.0, speed_weight=0.5, lane_weight=0.4)
    with pytest.raises(InputError, match="lateral_index 2 must differ from speed_indices"):
        SpeedLaneReward(1.0, 1.0, speed_indices=(2,), lateral_index=2)
    with pytest.raises(InputError, match="lateral_index is None, so lane_weight must be 0"):
        SpeedLaneReward(1.0, 1.0, lateral_index=None)
    with pytest.raises(InputError, match="speed_range must be > 0"):
        SpeedLaneReward(1.0, 0.0)
    with pytest.raises(InputError, match="n_lanes must be an integer >= 2"):
        SpeedLaneReward(1.0, 1.0, n_lanes=1)
    with pytest.raises(DimensionError, match=r"moving_positions must have shape \(1, 2\)"):
        GoalReward([0.0, 0.0], moving_obstacles=MovingObstacles([[0, 0]], [[0, 0]], [1.0])).value(
            [1.0, 1.0], moving_positions=np.zeros((2, 2))
        )


def test_with_obstacles_and_to_dict():
    import json

    base = GoalReward([1.0, 2.0], obstacles=CircularObstacles([[0.0, 0.0]], [0.5]), robot_radius=0.3)
    moving = MovingObstacles([[3.0, 3.0]], [[0.0, -1.0]], [0.3], velocity_uncertainty=0.2, dt=0.1, time0=4)
    with_moving = base.with_obstacles(moving_obstacles=moving)
    assert len(with_moving.moving_obstacles) == 1 and with_moving.obstacles is base.obstacles
    assert with_moving.robot_radius == 0.3 and with_moving.position_indices == (0, 1)
    # the pedestrian's box at t = 14 (1 s later) reaches y in [1.8, 2.2]: a robot at (3, 2) may collide
    assert with_moving.evaluate([3.0, 2.0], 14)[1] and not base.evaluate([3.0, 2.0], 14)[1]
    for value in (base, with_moving, SpeedLaneReward(1.0, 2.0)):
        assert json.loads(json.dumps(value.to_dict()))["family"] in ("goal", "speed_lane")


def test_reward_family_declares_its_hooks():
    assert RewardFamily.__abstractmethods__ == {"kernel_params", "used_indices", "free_value", "free_argmin", "to_dict"}

    class Partial(RewardFamily):
        def free_value(self, states):
            return np.ones(np.shape(states)[:-1])

    with pytest.raises(TypeError, match="abstract"):
        Partial()
    for reward in (GoalReward([0.0, 0.0]), SpeedLaneReward(1.0, 2.0)):
        assert isinstance(reward, RewardFamily)
    assert SpeedLaneReward(1.0, 2.0).min_state_dim == 3  # positions (0, 1), speed 2, lateral 1
