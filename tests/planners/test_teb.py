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
