"""The DWA baseline: admissibility of its choice, closed-loop behaviour, validation."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import DimensionError, InputError, NonFiniteError
from minimaxplan.planners.dwa import DWAParameters, DynamicWindowPlanner, NavigationScene
from minimaxplan.scenarios.robot import robot_system

from ._systems import on_three_lanes, random_system, three_lanes
from ._systems import run_baseline_episode as run_episode

finite = dict(allow_nan=False, allow_infinity=False)


thetas = st.tuples(st.floats(0.2, 0.8, **finite), st.floats(0.2, 0.8, **finite))


@given(
    theta=thetas,
    heading=st.floats(-np.pi, np.pi, **finite),
    distance=st.floats(14, 18, **finite),
    seed=st.integers(0, 10_000),
)
@settings(max_examples=10)
def test_reaches_the_goal_in_an_empty_arena(theta, heading, distance, seed):
    start = np.array([10.0, 10.0]) - distance / 2 * np.array([np.cos(heading), np.sin(heading)])
    goal = start + distance * np.array([np.cos(heading), np.sin(heading)])
    planner = DynamicWindowPlanner(robot_system())
    world, _ = run_episode(planner, start, goal, np.zeros((0, 2)), np.zeros(0), theta, seed)
    assert world.outcome == "goal"
    assert world.time < 30.0


@pytest.mark.parametrize("radius", [0.4, 0.8, 1.2])
@pytest.mark.parametrize("offset", [0.0, 0.3])
def test_avoids_a_single_obstacle_on_the_straight_line(radius, offset):
    start, goal = np.array([2.0, 10.0]), np.array([18.0, 10.0])
    centre = np.array([10.0, 10.0 + offset])
    planner = DynamicWindowPlanner(robot_system())
    for theta, seed in (((0.5, 0.5), 1), ((0.2, 0.8), 2), ((0.8, 0.2), 3)):
        world, path = run_episode(planner, start, goal, [centre], [radius], theta, seed)
        assert world.outcome == "goal"
        clearance = np.linalg.norm(path - centre, axis=1) - radius - 0.3
        assert clearance.min() > 0
        # it really had to go around: the straight line would have collided
        assert np.max(np.abs(path[:, 1] - 10.0)) > radius + 0.3 - offset - 1e-9


def _independent_stopping_path(system, x, u, substeps, brake_steps):
    """Nominal model: hold u for one period, then brake at full power (as documented)."""
    theta = system.theta.center
    dt = system.A0[0, 2]
    states = []
    for _ in range(substeps):
        x = system.step(x, u, theta)
        states.append(x)
    for _ in range(brake_steps):
        x = system.step(x, np.clip(-x[2:] / dt, -1, 1), theta)
        states.append(x)
    return np.array(states)


@given(
    vx=st.floats(-2, 2, **finite),
    vy=st.floats(-2, 2, **finite),
    obstacles=st.lists(
        st.tuples(st.floats(-4, 4, **finite), st.floats(-4, 4, **finite), st.floats(0.4, 1.2, **finite)),
        min_size=1,
        max_size=6,
    ),
    pedestrian=st.tuples(
        st.floats(-5, 5, **finite),
        st.floats(-5, 5, **finite),
        st.floats(-1.5, 1.5, **finite),
        st.floats(-1.5, 1.5, **finite),
    ),
    goal=st.tuples(st.floats(-10, 10, **finite), st.floats(-10, 10, **finite)),
)
@settings(max_examples=60)
def test_chosen_control_is_admissible(vx, vy, obstacles, pedestrian, goal):
    """Unless flagged as a fallback, the chosen sample can stop without entering any margin."""
    system = robot_system()
    params = DWAParameters()
    planner = DynamicWindowPlanner(system, params=params)
    state = np.array([0.0, 0.0, vx, vy])
    centers = np.array([o[:2] for o in obstacles])
    radii = np.array([o[2] for o in obstacles])
    scene = NavigationScene(np.array(goal), centers, radii, [pedestrian[:2]], [pedestrian[2:]], [0.3])
    evaluation = planner.evaluate(state, scene)
    u = evaluation.control
    assert np.all(np.abs(u) <= 1.0)
    assert evaluation.fallback == (not evaluation.admissible.any())
    if evaluation.fallback:
        return
    assert evaluation.admissible[np.argmax(evaluation.scores)]
    steps = _independent_stopping_path(system, state, u, 5, int(round(params.brake_time / 0.1)))
    times = 0.1 * np.arange(1, steps.shape[0] + 1)
    static_gap = np.linalg.norm(steps[:, None, :2] - centers, axis=-1) - radii
    assert static_gap.min() >= 0.3 + params.safety_margin - 1e-9
    walker = np.array(pedestrian[:2]) + times[:, None] * np.array(pedestrian[2:])
    ped_gap = np.linalg.norm(steps[:, :2] - walker, axis=-1) - 0.3
    assert ped_gap.min() >= 0.3 + params.safety_margin + params.pedestrian_margin - 1e-9


def test_rejects_the_colliding_samples_and_keeps_the_others():
    # An obstacle right ahead: accelerating into it is not admissible, turning away is.
    planner = DynamicWindowPlanner(robot_system())
    scene = NavigationScene([10.0, 0.0], [[1.6, 0.0]], [0.5])
    evaluation = planner.evaluate([0.0, 0.0, 1.0, 0.0], scene)
    forward = np.flatnonzero(np.all(evaluation.controls == [1.0, 0.0], axis=1))[0]
    assert not evaluation.admissible[forward]
    assert evaluation.admissible.any() and not evaluation.fallback
    assert evaluation.to_dict()["fallback"] is False


def test_fallback_escapes_when_nothing_is_admissible():
    # Inside the safety margin of an obstacle on the left: every stopping path violates
    # it; the fallback is the sample that violates it least, i.e. moving away (to +x).
    planner = DynamicWindowPlanner(robot_system())
    scene = NavigationScene([-10.0, 0.0], [[-0.85, 0.0]], [0.5])
    evaluation = planner.evaluate([0.0, 0.0, 0.0, 0.0], scene)
    assert evaluation.fallback and not evaluation.admissible.any()
    assert evaluation.control[0] == 1.0


@pytest.mark.parametrize(
    "make, error, message",
    [
        (lambda: NavigationScene([0.0]), DimensionError, r"goal must have shape \(2,\), got shape \(1,\)"),
        (
            lambda: NavigationScene([0, 0], [[1, 1]], [1, 2]),
            DimensionError,
            r"obstacle_radii must have shape \(1,\), got shape \(2,\)",
        ),
        (lambda: NavigationScene([0, 0], [[1, 1]], [-1.0]), InputError, "obstacle_radii must be > 0"),
        (lambda: NavigationScene([0, 0], [[1, 1]]), InputError, "obstacle_radii is required"),
        (
            lambda: NavigationScene([0, 0], [[1, 1, 1]], [1.0]),
            DimensionError,
            r"obstacle_centers must have shape \(\*, 2\)",
        ),
        (
            lambda: NavigationScene([0, 0], None, None, [[1, 1]], [[0, 0], [0, 0]], [0.3]),
            DimensionError,
            r"pedestrian_velocities must have shape \(1, 2\), got shape \(2, 2\)",
        ),
        (lambda: NavigationScene([np.nan, 0]), NonFiniteError, "goal contains NaN"),
        (lambda: DWAParameters(samples_per_axis=1), InputError, "samples_per_axis must be an integer >= 2"),
        (
            lambda: DWAParameters(samples_per_axis=3.0),
            InputError,
            r"samples_per_axis must be an integer >= 2, got 3\.0",
        ),
        (
            lambda: DynamicWindowPlanner(robot_system(), substeps=2.5),
            InputError,
            r"substeps must be a positive integer, got 2\.5",
        ),
        (
            lambda: DynamicWindowPlanner(random_system(np.random.default_rng(0), p=3, q=2, d=1)),
            DimensionError,
            r"system must have 4 states and 2 inputs .*got 3 states and 2 inputs \(B of shape \(3, 2\)\)",
        ),
        (lambda: DWAParameters(horizon=0.0), InputError, "horizon must be > 0"),
        (lambda: DynamicWindowPlanner("system"), InputError, "system must be an UncertainLinearSystem"),
        (
            lambda: DynamicWindowPlanner(robot_system(isotropic=True), theta=[0.5, 0.5]),
            DimensionError,
            r"theta must have shape \(1,\)",
        ),
        (lambda: DynamicWindowPlanner(robot_system(), substeps=0), InputError, "substeps must be a positive integer"),
        (lambda: DynamicWindowPlanner(robot_system(), params={}), InputError, "params must be a DWAParameters"),
    ],
)
def test_rejects_bad_input(make, error, message):
    with pytest.raises(error, match=message):
        make()


def test_plan_rejects_bad_state_and_scene():
    planner = DynamicWindowPlanner(robot_system())
    scene = NavigationScene([1.0, 1.0])
    with pytest.raises(DimensionError, match=r"state must have shape \(4,\), got shape \(2,\)"):
        planner.plan([0.0, 0.0], scene)
    with pytest.raises(InputError, match="scene must be a NavigationScene"):
        planner.plan(np.zeros(4), {"goal": [1.0, 1.0]})


def test_purely_local_variant_reaches_the_goal_in_an_empty_arena():
    """``navigation_function=False`` is Fox et al.'s straight-line DWA."""
    planner = DynamicWindowPlanner(robot_system(), params=DWAParameters(navigation_function=False))
    world, _ = run_episode(planner, [3.0, 3.0], [15.0, 13.0], np.zeros((0, 2)), np.zeros(0), (0.4, 0.6), 4)
    assert world.outcome == "goal"


# ------------------------------------------------------------ DWA on the bicycle
from functools import partial  # noqa: E402

from minimaxplan.planners.dwa import (  # noqa: E402
    RoadScene,
    VehicleDWAParameters,
    VehicleDynamicWindow,
    rectangle_discs,
    steering_window,
)
from minimaxplan.scenarios.road_world import rectangles_collide  # noqa: E402
from minimaxplan.scenarios.vehicles import VehicleParameters, bicycle_step  # noqa: E402

CAR = VehicleParameters()
BICYCLE = partial(bicycle_step, vehicle=CAR)


def road_scene(vehicles=None, **kwargs):
    return RoadScene(reference=three_lanes, on_road=on_three_lanes, vehicles=vehicles, **kwargs)


def vehicle_dwa(**params):
    return VehicleDynamicWindow(
        BICYCLE, dt=0.1, acceleration_bound=6.0, max_steering=CAR.max_steering, params=VehicleDWAParameters(**params)
    )


@given(
    x=st.tuples(st.floats(-5, 5, **finite), st.floats(-6, 6, **finite), st.floats(0, 35, **finite)),
    heading=st.floats(-0.5, 0.5, **finite),
)
@settings(max_examples=20)
def test_vehicle_window_and_rollouts_are_admissible_bicycle_motion(x, heading):
    planner = vehicle_dwa()
    state = np.array([x[0], x[1], x[2], heading])
    controls = planner.window(state[2])
    assert np.all(np.abs(controls[:, 0]) <= 6.0) and np.all(np.abs(controls[:, 1]) <= CAR.max_steering)
    assert np.any(np.all(controls == 0.0, axis=1))  # odd grids hold "keep going"
    held = planner.rollout(state, controls, 7)
    expected = np.broadcast_to(state, controls.shape[:1] + (4,))
    for n in range(7):  # the planner's rollout is the given dynamics, step by step, bit for bit
        expected = bicycle_step(expected, controls[:, 0], controls[:, 1], 0.1, CAR)
        np.testing.assert_array_equal(held[:, n], expected)
    evaluation = planner.evaluate(state, road_scene())
    assert np.all(np.abs(evaluation.control) <= [6.0, CAR.max_steering])


def test_steering_window_bounds_the_lateral_acceleration():
    for v in (2.0, 9.0, 25.0):
        delta = steering_window(v, 4.0, CAR.max_steering, CAR.length)
        beta = np.arctan(np.tan(delta) / 2)
        assert v * v * np.sin(beta) / (CAR.length / 2) <= 4.0 + 1e-9
    assert steering_window(0.0, 4.0, CAR.max_steering, CAR.length) == pytest.approx(CAR.max_steering)


@given(
    state=st.tuples(st.floats(-20, 20, **finite), st.floats(-20, 20, **finite), st.floats(-np.pi, np.pi, **finite)),
)
@settings(max_examples=30)
def test_the_disc_cover_contains_the_rectangle(state):
    x = np.array([state[0], state[1], 0.0, state[2]])
    centres, radius = rectangle_discs(x, CAR.length, CAR.width)
    c, s = np.cos(x[3]), np.sin(x[3])
    u = np.linspace(-0.5, 0.5, 21)
    grid = np.stack(np.meshgrid(u * CAR.length, u * CAR.width, indexing="ij"), axis=-1).reshape(-1, 2)
    points = x[:2] + grid @ np.array([[c, s], [-s, c]])
    distance = np.linalg.norm(points[:, None] - centres[None], axis=-1).min(axis=1)
    assert np.all(distance <= radius + 1e-9)


def test_vehicle_dwa_rejects_samples_that_meet_a_stopped_car_and_keeps_clear_in_closed_loop():
    planner = vehicle_dwa()
    stopped = np.array([[60.0, 0.0, 0.0, 0.0]])
    scene = road_scene(stopped, speed_limit=30.0)
    state = np.array([0.0, 0.0, 20.0, 0.0])
    for _ in range(30):  # 15 s of closed loop at 0.5 s decisions
        evaluation = planner.evaluate(state, scene)
        assert not evaluation.fallback
        for _ in range(5):
            state = bicycle_step(state[None], [evaluation.control[0]], [evaluation.control[1]], 0.1, CAR)[0]
            assert not rectangles_collide(state, stopped[0], CAR)
            assert on_three_lanes(state[None, :2])[0]
    assert state[0] > 60.0 or state[2] < 0.5  # past the stopped car in another lane, or stopped behind it


def test_vehicle_dwa_falls_back_when_every_sample_meets_a_vehicle():
    planner = vehicle_dwa()
    head_on = np.array([[8.0, 0.0, 20.0, np.pi], [8.0, 4.0, 20.0, np.pi], [8.0, -3.0, 20.0, np.pi]])
    evaluation = planner.evaluate(np.array([0.0, 0.0, 20.0, 0.0]), road_scene(head_on))
    assert evaluation.fallback and not evaluation.admissible.any()
    assert np.all(np.abs(evaluation.control) <= [6.0, CAR.max_steering])


def test_road_scene_and_vehicle_dwa_reject_bad_input():
    with pytest.raises(InputError, match="reference must be callable"):
        RoadScene(reference=None, on_road=on_three_lanes)
    with pytest.raises(DimensionError):
        road_scene(np.zeros((2, 3)))
    with pytest.raises(InputError, match="dynamics must be callable"):
        VehicleDynamicWindow(None, dt=0.1)
    with pytest.raises(DimensionError):
        vehicle_dwa().plan(np.zeros(3), road_scene())
    with pytest.raises(DimensionError, match="dynamics must return"):
        VehicleDynamicWindow(lambda x, a, d, dt: x[:, :3], dt=0.1).plan(np.array([0, 0, 10.0, 0]), road_scene())
