"""The TEB baseline: exact gradient, closed-loop behaviour, warm starts, resizing, validation."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import approx_fprime

from minimaxplan.models import DimensionError, InputError
from minimaxplan.planners.dwa import NavigationScene
from minimaxplan.planners.teb import TEBParameters, TimedElasticBand, band_cost
from minimaxplan.scenarios.robot import robot_system

from ._systems import on_three_lanes, three_lanes
from ._systems import run_baseline_episode as run_episode

finite = dict(allow_nan=False, allow_infinity=False)


@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 12), k=st.integers(0, 5))
@settings(max_examples=40)
def test_band_cost_gradient_matches_finite_differences(seed, n, k):
    rng = np.random.default_rng(seed)
    start, goal, velocity = rng.uniform(0, 3, 2), rng.uniform(5, 8, 2), rng.uniform(-2, 2, 2)
    X = start + np.linspace(0, 1, n + 1)[:, None] * (goal - start) + rng.normal(0, 0.5, (n + 1, 2))
    dT = rng.uniform(0.1, 0.8, n)
    z = np.concatenate([X[1:-1].ravel(), dT])
    discs = (rng.uniform(0, 8, (k, 2)), rng.uniform(-1.5, 1.5, (k, 2)), rng.uniform(0.4, 1.2, k), np.full(k, 0.6))
    friction = rng.uniform(0.2, 0.8, 2)
    params = TEBParameters()

    def cost(v):
        return band_cost(v, start, velocity, goal, n, friction, discs, params)[0]

    _, grad = band_cost(z, start, velocity, goal, n, friction, discs, params)
    numeric = approx_fprime(z, cost, 1e-6)
    scale = max(1.0, np.max(np.abs(numeric)))
    # Central differences would be tighter; forward differences of a piecewise-quadratic
    # cost of size `scale` are accurate to about 1e-6 * (curvature) relative.
    assert np.max(np.abs(grad - numeric)) <= 1e-4 * scale


@given(
    theta=st.tuples(st.floats(0.2, 0.8, **finite), st.floats(0.2, 0.8, **finite)),
    heading=st.floats(-np.pi, np.pi, **finite),
    seed=st.integers(0, 10_000),
)
@settings(max_examples=4)
def test_reaches_the_goal_in_an_empty_arena(theta, heading, seed):
    direction = np.array([np.cos(heading), np.sin(heading)])
    start, goal = np.array([10.0, 10.0]) - 8 * direction, np.array([10.0, 10.0]) + 8 * direction
    world, _ = run_episode(TimedElasticBand(robot_system()), start, goal, np.zeros((0, 2)), np.zeros(0), theta, seed)
    assert world.outcome == "goal"
    assert world.time < 30.0


@pytest.mark.parametrize("radius, offset", [(0.4, 0.0), (1.2, 0.0), (1.2, 0.3)])
def test_avoids_a_single_obstacle_on_the_straight_line(radius, offset):
    start, goal = np.array([2.0, 10.0]), np.array([18.0, 10.0])
    centre = np.array([10.0, 10.0 + offset])
    planner = TimedElasticBand(robot_system())
    for theta, seed in (((0.5, 0.5), 1), ((0.2, 0.8), 2)):
        world, path = run_episode(planner, start, goal, [centre], [radius], theta, seed)
        assert world.outcome == "goal"
        assert (np.linalg.norm(path - centre, axis=1) - radius - 0.3).min() > 0


def test_band_is_clear_and_warm_started():
    planner = TimedElasticBand(robot_system())
    scene = NavigationScene([18.0, 10.0], [[10.0, 10.0]], [1.0])
    state = np.array([2.0, 10.0, 0.0, 0.0])
    first = planner.optimise(state, scene)
    assert np.array_equal(first.positions[0], state[:2]) and np.array_equal(first.positions[-1], scene.goal)
    assert first.violation <= planner.params.reinit_violation
    assert np.all(np.abs(first.control) <= 1.0)
    gap = np.linalg.norm(first.positions - [10.0, 10.0], axis=1) - 1.0
    assert gap.min() >= 0.3  # the band goes around the disc, with the footprint
    # Warm start: the same call again starts from the previous optimum and does not get worse.
    second = planner.optimise(state, scene)
    assert second.cost <= first.cost + 1e-9
    planner.reset()
    assert planner._band is None


def test_band_resizing_keeps_intervals_near_the_reference():
    planner = TimedElasticBand(robot_system())
    p = planner.params
    X = np.linspace([0.0, 0.0], [10.0, 0.0], 6)
    dT = np.array([2.0, 0.1, 0.1, 0.1, 1.2])
    X2, dT2 = planner._resize(X, dT)
    assert X2.shape[0] == dT2.shape[0] + 1
    assert np.isclose(dT2.sum(), dT.sum())  # resizing redistributes time, never loses it
    assert np.array_equal(X2[0], X[0]) and np.array_equal(X2[-1], X[-1])
    assert dT2.max() < dT.max() and dT2.min() > dT.min()
    assert p.min_poses <= dT2.size <= p.max_poses


def test_pedestrian_moving_into_the_route_bends_the_band():
    planner = TimedElasticBand(robot_system())
    state = np.array([0.0, 0.0, 1.0, 0.0])
    still = planner.optimise(state, NavigationScene([12.0, 0.0]))
    planner.reset()
    # A pedestrian that will stand on the route around t = 4 s (x = 5).
    crossing = planner.optimise(state, NavigationScene([12.0, 0.0], None, None, [[5.0, -4.0]], [[0.0, 1.0]], [0.3]))
    assert np.max(np.abs(still.positions[:, 1])) < 0.2
    T = np.concatenate([[0.0], np.cumsum(crossing.intervals)])
    walker = np.array([5.0, -4.0]) + T[:, None] * [0.0, 1.0]
    assert (np.linalg.norm(crossing.positions - walker, axis=1) - 0.3).min() > 0.3


@pytest.mark.parametrize(
    "make, error, message",
    [
        (lambda: TEBParameters(dt_ref=5.0), InputError, "need dt_min < dt_ref < dt_max"),
        (lambda: TEBParameters(min_poses=10, max_poses=5), InputError, "min_poses must be <= max_poses"),
        (lambda: TEBParameters(max_iterations=0), InputError, "max_iterations must be a positive integer"),
        (lambda: TEBParameters(min_poses=2.5), InputError, r"min_poses must be a positive integer, got 2\.5"),
        (lambda: TEBParameters(obstacle_weight=-1.0), InputError, "obstacle_weight must be > 0"),
        (lambda: TimedElasticBand(None), InputError, "system must be an UncertainLinearSystem"),
        (
            lambda: TimedElasticBand(robot_system(), theta=[0.5]),
            DimensionError,
            r"theta must have shape \(2,\), got shape \(1,\)",
        ),
        (lambda: TimedElasticBand(robot_system(), params=None), InputError, "params must be a TEBParameters"),
        (
            lambda: TimedElasticBand(robot_system()).plan(np.zeros(3), NavigationScene([1.0, 1.0])),
            DimensionError,
            r"state must have shape \(4,\), got shape \(3,\)",
        ),
        (
            lambda: TimedElasticBand(robot_system()).plan(np.zeros(4), [1.0, 1.0]),
            InputError,
            "scene must be a NavigationScene",
        ),
    ],
)
def test_rejects_bad_input(make, error, message):
    with pytest.raises(error, match=message):
        make()


def test_plans_report_a_named_solver_status_and_non_finite_bands_raise(monkeypatch):
    from minimaxplan.models import SolverFailure
    from minimaxplan.planners import teb

    planner = TimedElasticBand(robot_system())
    scene = NavigationScene([8.0, 0.0], [[4.0, 0.2]], [0.5])
    plan = planner.optimise(np.zeros(4), scene)
    assert plan.status in teb.LBFGSB_STATUS.values()
    assert plan.to_dict()["status"] == plan.status

    def broken_cost(z, *args):
        cost, grad = band_cost(z, *args)
        return np.nan, grad

    monkeypatch.setattr(teb, "band_cost", broken_cost)
    planner.reset()
    with pytest.raises(SolverFailure, match="L-BFGS-B failed on the band"):
        planner.optimise(np.zeros(4), scene)


def test_a_goal_that_slides_keeps_the_warm_band_and_a_jump_starts_afresh():
    planner = TimedElasticBand(robot_system())
    state = np.array([0.0, 0.0, 0.5, 0.0])
    first = planner.optimise(state, NavigationScene([3.0, 0.0]))
    slid = planner.optimise(state, NavigationScene([3.5, 0.2]))  # a waypoint moving along a path
    assert np.array_equal(slid.positions[-1], [3.5, 0.2])
    assert slid.positions.shape[0] >= first.positions.shape[0] - 1  # warm band kept (then resized)
    jumped = planner.optimise(state, NavigationScene([3.0, 8.0]))
    assert np.array_equal(jumped.positions[-1], [3.0, 8.0])
    assert np.max(jumped.positions[:, 1]) > 7.0


# ------------------------------------------------------------ TEB on the bicycle
from functools import partial  # noqa: E402

from minimaxplan.planners.dwa import RoadScene  # noqa: E402
from minimaxplan.planners.teb import VehicleElasticBand, VehicleTEBParameters, turning_cost  # noqa: E402
from minimaxplan.scenarios.road_world import rectangles_collide  # noqa: E402
from minimaxplan.scenarios.vehicles import VehicleParameters, bicycle_step  # noqa: E402

CAR = VehicleParameters()


def lane_goals(x: float) -> np.ndarray:
    return np.array([[x, 0.0], [x, 4.0], [x, 8.0]])


@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 10))
@settings(max_examples=40)
def test_turning_cost_gradient_matches_finite_differences(seed, n):
    rng = np.random.default_rng(seed)
    X = np.cumsum(rng.uniform(0.5, 3.0, (n + 1, 2)) * [1.0, 0.6] + rng.normal(0, 1.0, (n + 1, 2)), axis=0)
    heading, curvature = rng.uniform(-1, 1), rng.uniform(0.01, 0.5)

    def cost(flat):
        return turning_cost(flat.reshape(-1, 2), heading, curvature, 1000.0)[0]

    _, grad = turning_cost(X, heading, curvature, 1000.0)
    numeric = approx_fprime(X.ravel(), cost, 1e-7)
    assert np.max(np.abs(grad.ravel() - numeric)) <= 1e-3 * max(1.0, np.max(np.abs(numeric)))


@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 10), k=st.integers(0, 4))
@settings(max_examples=30)
def test_band_cost_with_the_vehicle_terms_has_the_exact_gradient(seed, n, k):
    rng = np.random.default_rng(seed)
    start, goal, velocity = np.array([0.0, 0.0]), np.array([60.0, rng.uniform(-4, 4)]), np.array([20.0, 0.0])
    X = start + np.linspace(0, 1, n + 1)[:, None] * (goal - start) + rng.normal(0, 1.0, (n + 1, 2))
    dT = rng.uniform(0.3, 0.8, n)
    z = np.concatenate([X[1:-1].ravel(), dT])
    discs = (rng.uniform(0, 60, (k, 2)), rng.uniform(-20, 20, (k, 2)), np.full(k, 2.6), np.full(k, 0.1))
    planner = VehicleElasticBand(partial(bicycle_step, vehicle=CAR), dt=0.1)
    scene = RoadScene(reference=three_lanes, on_road=on_three_lanes, local_goals=lane_goals(60.0))
    extra = planner._extra(scene, 0.1)
    band = planner.params.band_parameters(30.0)

    def cost(v):
        return band_cost(v, start, velocity, goal, n, np.zeros(2), discs, band, 6.0, extra)[0]

    _, grad = band_cost(z, start, velocity, goal, n, np.zeros(2), discs, band, 6.0, extra)
    numeric = approx_fprime(z, cost, 1e-6)
    assert np.max(np.abs(grad - numeric)) <= 1e-3 * max(1.0, np.max(np.abs(numeric)))


@pytest.mark.parametrize("lane_weight", [1.0, 10.0])
def test_vehicle_band_behind_a_slow_car_stays_clear_with_admissible_bicycle_controls(lane_weight):
    # A weak lane term lets the band overtake in the next lane; the tuned one (10) follows.
    params = VehicleTEBParameters(lane_weight=lane_weight)
    planner = VehicleElasticBand(
        partial(bicycle_step, vehicle=CAR), dt=0.1, max_steering=CAR.max_steering, params=params
    )
    slow = np.array([40.0, 0.0, 10.0, 0.0])
    state = np.array([0.0, 0.0, 20.0, 0.0])
    for _ in range(16):  # 8 s at 0.5 s decisions
        ahead = slow.copy()
        lookahead = max(state[2], 5.0) * planner.params.lookahead_time
        scene = RoadScene(
            reference=three_lanes,
            on_road=on_three_lanes,
            vehicles=ahead[None],
            speed_limit=30.0,
            local_goals=lane_goals(state[0] + lookahead),
        )
        plan = planner.optimise(state, scene)
        assert plan.status in {"converged", "iteration_limit", "line_search_stopped"}
        u = plan.control
        assert abs(u[0]) <= 6.0 and abs(u[1]) <= CAR.max_steering
        for _ in range(5):
            state = bicycle_step(state[None], [u[0]], [u[1]], 0.1, CAR)[0]
            slow = bicycle_step(slow[None], [0.0], [0.0], 0.1, CAR)[0]
            assert not rectangles_collide(state, slow, CAR)
            assert on_three_lanes(state[None, :2])[0]
    if lane_weight < 10:
        assert state[0] > slow[0]  # it overtook
    else:
        assert state[0] < slow[0] - CAR.length and abs(state[2] - 10.0) < 1.0  # it follows at the car's speed


def test_vehicle_band_needs_a_local_goal():
    planner = VehicleElasticBand(partial(bicycle_step, vehicle=CAR), dt=0.1)
    with pytest.raises(InputError, match="local goal"):
        planner.plan(np.array([0.0, 0.0, 10.0, 0.0]), RoadScene(reference=three_lanes, on_road=on_three_lanes))
    with pytest.raises(InputError, match="dynamics must be callable"):
        VehicleElasticBand(None, dt=0.1)
    with pytest.raises(InputError, match="min_poses"):
        VehicleTEBParameters(min_poses=9, max_poses=3)
