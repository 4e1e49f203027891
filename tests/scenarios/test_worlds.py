"""The robot navigation worlds: determinism, layouts, pedestrians, exact model, noise, episode logic."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import DimensionError, InputError
from minimaxplan.scenarios.geometry import CircularObstacles
from minimaxplan.scenarios.robot import DEFAULT_ROBOT, RobotParameters
from minimaxplan.scenarios.worlds import (
    CORRIDOR_MARGIN,
    OBSTACLE_RADIUS,
    PEDESTRIAN_VELOCITY_UNCERTAINTY,
    START_GOAL_CLEARANCE,
    EpisodeOver,
    generate_layout,
    layout_has_path,
    make_world,
)

seeds = st.integers(0, 2**31 - 1)
kinds = st.sampled_from(["static", "pedestrian"])


def _go_to_goal(world, period_steps=5):
    """A simple measured-state controller, to drive worlds through varied states."""
    u = np.zeros(2)
    for _ in range(period_steps * 40):
        if world.done:
            break
        x = world.measure()
        if world.step_index % period_steps == 0:
            direction = world.goal - x[:2]
            u = np.clip(direction / max(np.linalg.norm(direction), 1e-9) - 0.7 * x[2:], -1, 1)
        world.apply(u)


def _episode_trace(kind, seed):
    world = make_world(kind, seed)
    states, measurements = [world.state.copy()], []
    while not world.done and world.step_index < 150:
        x = world.measure()
        measurements.append(x)
        direction = world.goal - x[:2]
        world.apply(np.clip(direction - x[2:], -1, 1))
        states.append(world.state.copy())
    return world, np.array(states), np.array(measurements)


@pytest.mark.parametrize("kind", ["static", "pedestrian"])
def test_same_seed_gives_the_identical_episode(kind):
    a, states_a, meas_a = _episode_trace(kind, 17)
    b, states_b, meas_b = _episode_trace(kind, 17)
    assert np.array_equal(states_a, states_b)
    assert np.array_equal(meas_a, meas_b)
    assert a.outcome == b.outcome and a.step_index == b.step_index
    assert np.array_equal(a.true_theta, b.true_theta)
    assert a.to_dict() == b.to_dict()
    c, states_c, _ = _episode_trace(kind, 18)
    assert not np.array_equal(a.obstacles.centers, c.obstacles.centers) or not np.array_equal(states_a, states_c)


def test_measuring_does_not_change_the_dynamics():
    """Separate RNG streams: extra measurements leave the disturbances untouched."""
    a, b = make_world("pedestrian", 5), make_world("pedestrian", 5)
    for k in range(40):
        a.measure()
        if k % 3 == 0:
            b.measure()
            b.measure()
        a.apply([0.3, -0.2])
        b.apply([0.3, -0.2])
    assert np.array_equal(a.state, b.state)
    assert np.array_equal(a.crowd.positions, b.crowd.positions)


@given(kind=kinds, seed=seeds)
@settings(max_examples=40)
def test_layout_constraints(kind, seed):
    world = make_world(kind, seed)
    p = DEFAULT_ROBOT
    n = len(world.obstacles)
    assert (10 <= n <= 15) if kind == "static" else (3 <= n <= 5)
    radii = world.obstacles.radii
    assert np.all(radii >= OBSTACLE_RADIUS[0]) and np.all(radii <= OBSTACLE_RADIUS[1])
    for point in (world.start, world.goal):
        assert np.all(point >= 0) and np.all(point <= p.arena_size)
        assert world.obstacles.clearance(point) >= p.robot_radius + START_GOAL_CLEARANCE
    assert p.goal_distance_low <= np.linalg.norm(world.goal - world.start) <= p.goal_distance_high
    assert np.all(world.obstacles.centers >= 0) and np.all(world.obstacles.centers <= p.arena_size)
    assert layout_has_path(
        world.start, world.goal, world.obstacles, robot_radius=p.robot_radius, arena_size=p.arena_size
    )
    assert world.system.theta.contains(world.true_theta)
    assert np.array_equal(world.state, np.concatenate([world.start, np.zeros(2)]))


def test_layout_has_path_detects_a_blocking_wall():
    # A wall of touching discs across the whole arena at x = 10 separates start from goal.
    ys = np.arange(0.0, 20.5, 0.5)
    wall = CircularObstacles(np.stack([np.full_like(ys, 10.0), ys], axis=1), np.full(ys.shape, 0.4))
    start, goal = np.array([3.0, 10.0]), np.array([17.0, 10.0])
    assert not layout_has_path(start, goal, wall, robot_radius=0.3, arena_size=20.0)
    assert layout_has_path(start, goal, CircularObstacles.empty(), robot_radius=0.3, arena_size=20.0)

    def wall_without(half_gap):
        keep = np.abs(ys - 10.0) > half_gap
        return CircularObstacles(wall.centers[keep], np.full(int(keep.sum()), 0.4))

    # Removing the discs at y = 9.5, 10, 10.5 leaves a 1.2 m gap: wider than the
    # footprint (0.6 m) plus the corridor margin on both sides (0.3 m): open.
    assert layout_has_path(start, goal, wall_without(0.6), robot_radius=0.3, arena_size=20.0)
    # Removing only the disc at y = 10 leaves a 0.2 m gap, narrower than the footprint: closed.
    assert not layout_has_path(start, goal, wall_without(0.1), robot_radius=0.3, arena_size=20.0)


def test_generate_layout_rejects_unknown_kind():
    with pytest.raises(InputError, match="kind must be one of"):
        generate_layout("maze", np.random.default_rng(0))


@given(seed=seeds)
@settings(max_examples=25)
def test_pedestrians_true_velocity_stays_in_the_announced_box_and_boxes_are_sound(seed):
    world = make_world("pedestrian", seed)
    assert 1 <= len(world.crowd) <= 3
    speeds = np.linalg.norm(world.crowd.announced, axis=1)
    assert np.all((speeds >= 0.5) & (speeds <= 1.5))
    announced = world.crowd.announced.copy()
    view = world.pedestrians  # boxes announced now, checked against the next 400 sub-steps
    assert np.allclose(view.velocity_uncertainty, PEDESTRIAN_VELOCITY_UNCERTAINTY)
    largest_error = 0.0
    for t in range(1, 401):
        error = np.abs(world.crowd.velocities - announced)
        assert np.all(error <= PEDESTRIAN_VELOCITY_UNCERTAINTY)
        largest_error = max(largest_error, float(error.max()))
        world.crowd.advance(world.params.dt)
        lower, upper = view.boxes(t)
        assert np.all(world.crowd.positions >= lower - 1e-9) and np.all(world.crowd.positions <= upper + 1e-9)
    # the heading noise is real: the true velocity does move away from the announced one
    assert largest_error > 0.01


def test_pedestrians_cross_the_route():
    """Each pedestrian's straight announced path crosses the start-goal line between the ends."""
    for seed in range(10):
        world = make_world("pedestrian", seed)
        a, b = world.start, world.goal
        for p, v in zip(world.crowd.positions, world.crowd.announced):
            matrix = np.column_stack([b - a, -v])
            s, t = np.linalg.solve(matrix, p - a)
            assert 0.2 < s < 0.9 and t > 0


@given(kind=kinds, seed=seeds)
@settings(max_examples=15)
def test_world_steps_exactly_with_its_discrete_model(kind, seed):
    world = make_world(kind, seed)
    rng = np.random.default_rng(seed)
    A = world.system.A(world.true_theta)
    for _ in range(30):
        if world.done:
            break
        u = rng.uniform(-1, 1, size=2)
        before = world.state.copy()
        world.apply(u)
        w = world.last_disturbance
        assert np.all(np.abs(w) <= 0.1)
        assert np.array_equal(world.state, world.system.step(before, u, world.true_theta, w))
        np.testing.assert_allclose(
            world.state, A @ before + world.system.B @ u + world.system.D @ w, rtol=0, atol=1e-12
        )


def test_uniform_measurement_noise_is_bounded_and_gaussian_is_not():
    world = make_world("static", 3)
    errors = np.array([world.measure() - world.state for _ in range(2000)])
    assert np.all(np.abs(errors) <= DEFAULT_ROBOT.measurement_noise)
    assert np.max(np.abs(errors)) > 0.9 * DEFAULT_ROBOT.measurement_noise
    gaussian = make_world("static", 3, measurement="gaussian")
    errors = np.array([gaussian.measure() - gaussian.state for _ in range(4000)])
    assert abs(errors.std() - DEFAULT_ROBOT.gaussian_measurement_std) < 0.01
    assert np.max(np.abs(errors)) > 3 * DEFAULT_ROBOT.measurement_noise


def test_collision_goal_and_timeout_outcomes():
    world = make_world("static", 2)
    centre, radius = world.obstacles.centers[0], world.obstacles.radii[0]
    # Just outside contact, heading into the obstacle: the next sub-step collides.
    direction = np.array([1.0, 0.0])
    world.state = np.concatenate([centre - direction * (radius + 0.3 + 0.05), 2.0 * direction])
    assert world.apply([1.0, 0.0]) == "collision"
    assert world.done and world.reward() == 0.0
    with pytest.raises(EpisodeOver, match="outcome='collision'"):
        world.apply([0.0, 0.0])

    world = make_world("static", 2)
    world.state = np.concatenate([world.goal + [0.2, 0.0], [0.0, 0.0]])
    assert world.apply([0.0, 0.0]) == "goal"
    assert 1.0 / 1.3 < world.reward() <= 1.0

    short = RobotParameters(time_limit=0.3)
    world = make_world("static", 2, params=short)
    assert [world.apply([0.0, 0.0]) for _ in range(3)] == ["running", "running", "timeout"]
    assert world.time == pytest.approx(0.3)


def test_apply_held_holds_for_one_decision_period():
    world = make_world("static", 4)
    assert world.apply_held([0.5, 0.5]) == "running"
    assert world.step_index == 5 and world.time == pytest.approx(0.5)


def test_reward_is_the_goal_reward_of_the_true_state():
    world = make_world("pedestrian", 6)
    _go_to_goal(world, 5)
    if world.outcome != "collision":
        d = np.linalg.norm(world.state[:2] - world.goal)
        assert world.reward() == pytest.approx(1.0 / (1.0 + d))


def test_collisions_agree_with_the_vectorised_geometry():
    world = make_world("static", 9)
    rng = np.random.default_rng(0)
    for _ in range(300):
        world.state = np.concatenate([rng.uniform(0, 20, size=2), np.zeros(2)])
        clearance = world.obstacles.clearance(world.state[:2]) - world.params.robot_radius
        if abs(clearance) > 1e-9:
            assert bool(np.any(world.collisions())) == (clearance < 0)


@pytest.mark.parametrize(
    "call, error, message",
    [
        (lambda w: w.apply([0.0, 0.0, 0.0]), DimensionError, r"u must have shape \(2,\), got shape \(3,\)"),
        (lambda w: w.apply([1.5, 0.0]), InputError, r"u must lie in \[-1.0, 1.0\]\^2"),
        (lambda w: w.apply([np.nan, 0.0]), InputError, "u contains NaN"),
    ],
)
def test_apply_rejects_bad_controls(call, error, message):
    with pytest.raises(error, match=message):
        call(make_world("static", 0))


@pytest.mark.parametrize(
    "args, kwargs, message",
    [
        (("maze", 0), {}, "kind must be one of"),
        (("static", -1), {}, "seed must be an integer >= 0, got -1"),
        (("static", 1.5), {}, "seed must be an integer >= 0, got 1.5"),
        (
            ("static", 0),
            {"measurement": "laplace"},
            r"measurement must be one of \('uniform', 'gaussian'\), got 'laplace'",
        ),
        (("static", 0), {"params": {"dt": 0.1}}, "params must be a RobotParameters"),
    ],
)
def test_make_world_rejects_bad_arguments(args, kwargs, message):
    with pytest.raises(InputError, match=message):
        make_world(*args, **kwargs)


def test_corridor_margin_covers_the_grid_diagonal():
    from minimaxplan.scenarios.worlds import GRID_RESOLUTION

    assert CORRIDOR_MARGIN >= GRID_RESOLUTION / np.sqrt(2)


def test_to_dict_describes_the_setup_not_the_current_state():
    world = make_world("pedestrian", 8)
    before = world.to_dict()
    for _ in range(10):
        world.apply([0.0, 0.0])
    assert world.to_dict() == before
    assert before["pedestrians"]["positions"] != world.crowd.positions.tolist()
