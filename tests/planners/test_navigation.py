"""The grid navigation function under the DWA and TEB baselines."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import InputError
from minimaxplan.planners.navigation import NavigationCache, NavigationFunction

finite = dict(allow_nan=False, allow_infinity=False)
points = st.tuples(st.floats(0, 20, **finite), st.floats(0, 20, **finite))


@given(goal=points, start=points)
@settings(max_examples=30)
def test_cost_to_go_without_discs_is_the_octile_grid_distance(goal, start):
    goal, start = np.array(goal), np.array(start)
    nav = NavigationFunction(goal, np.zeros((0, 2)), np.zeros(0), clearance=0.4, region=start[None])
    d = np.linalg.norm(start - goal)
    cost = float(nav.cost_to_go(start))
    # 8-connected grid paths are at most 1.0824 times longer than straight ones; snapping
    # the goal to its cell and interpolating cost up to one cell diagonal.
    slack = 2 * nav.resolution * np.sqrt(2)
    assert d - slack <= cost <= 1.0824 * d + slack
    if d > 1.0:
        assert nav.descent(start) @ (goal - start) / d > 0.9


@given(seed=st.integers(0, 2**31 - 1))
@settings(max_examples=20)
def test_path_keeps_the_clearance_and_descends_to_the_goal(seed):
    rng = np.random.default_rng(seed)
    centers = rng.uniform(3, 17, size=(8, 2))
    radii = rng.uniform(0.4, 1.2, size=8)
    start, goal = np.array([1.0, 1.0]), np.array([19.0, 19.0])
    nav = NavigationFunction(goal, centers, radii, clearance=0.45, region=start[None])
    try:
        path = nav.path(start)
    except InputError:
        return  # a random layout may close the way; the test below checks that case
    edge = (np.linalg.norm(path[:, None] - centers, axis=-1) - radii).min(axis=1)
    assert edge.min() >= 0.45 - 1e-9
    assert np.linalg.norm(path[-1] - goal) <= nav.resolution
    assert np.linalg.norm(path[0] - start) <= nav.resolution
    values = nav.cost_to_go(path)
    assert np.all(np.diff(values) < 1e-9)


def test_detour_around_a_wall_costs_more_than_the_straight_line():
    ys = np.arange(2.0, 18.5, 0.5)
    wall = np.stack([np.full_like(ys, 10.0), ys], axis=1)
    start, goal = np.array([5.0, 10.0]), np.array([15.0, 10.0])
    nav = NavigationFunction(goal, wall, np.full(ys.size, 0.4), clearance=0.4, region=start[None])
    assert float(nav.cost_to_go(start)) > 1.5 * 10.0  # must go around an end of the wall
    path = nav.path(start)
    assert np.abs(path[:, 1] - 10.0).max() > 8.0


def test_unreachable_goal_raises():
    ring = 5.0 + 2.0 * np.stack([np.cos(np.linspace(0, 2 * np.pi, 60)), np.sin(np.linspace(0, 2 * np.pi, 60))], axis=1)
    nav = NavigationFunction([5.0, 5.0], ring, np.full(60, 0.4), clearance=0.3, region=[[15.0, 15.0]])
    with pytest.raises(InputError, match="goal cannot be reached"):
        nav.path([15.0, 15.0])


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"goal": [0.0]}, "DimensionError", r"goal must have shape \(2,\), got shape \(1,\)"),
        ({"radii": [0.5, 0.5]}, "DimensionError", r"radii must have shape \(1,\), got shape \(2,\)"),
        ({"clearance": -0.1}, "InputError", "clearance must be >= 0"),
        ({"resolution": 0.0}, "InputError", "resolution must be > 0"),
        ({"region": [[np.nan, 0.0]]}, "NonFiniteError", "region contains NaN"),
    ],
)
def test_rejects_bad_input(kwargs, error, message):
    import minimaxplan.models as models

    arguments = {"goal": [5.0, 5.0], "centers": [[2.0, 2.0]], "radii": [0.5], "clearance": 0.4, "region": [[0.0, 0.0]]}
    arguments.update(kwargs)
    goal, centers, radii = arguments.pop("goal"), arguments.pop("centers"), arguments.pop("radii")
    with pytest.raises(getattr(models, error), match=message):
        NavigationFunction(goal, centers, radii, **arguments)


def test_waypoint_is_lookahead_along_the_path_or_the_goal():
    # a wall of discs across x = 10 below y = 15.5: the path detours above it
    ys = np.arange(-6.0, 15.5, 1.0)
    centers, radii = np.stack([np.full_like(ys, 10.0), ys], axis=1), np.full(ys.shape, 0.6)
    nav = NavigationFunction([15.0, 5.0], centers, radii, clearance=0.5, region=[[5.0, 5.0]], padding=3.0)
    start = np.array([5.0, 5.0])
    near, far = nav.waypoint(start, 1.0), nav.waypoint(start, 6.0)
    assert np.linalg.norm(near - start) <= 1.0 + 0.3
    assert nav.cost_to_go(far) < nav.cost_to_go(near) < nav.cost_to_go(start)
    assert far[1] > start[1] + 3.0  # heading for the gap, not straight at the goal
    np.testing.assert_allclose(nav.waypoint([14.8, 5.1], 3.0), [15.0, 5.0])
    with pytest.raises(InputError, match="lookahead"):
        nav.waypoint(start, -1.0)


def test_cache_keeps_the_function_until_the_goal_the_discs_or_the_grid_change():
    cache = NavigationCache(clearance=0.4, resolution=0.2)
    goal, centers, radii = np.array([5.0, 5.0]), np.array([[2.0, 2.0]]), np.array([0.5])
    here = np.array([[0.0, 0.0]])
    first = cache.get(goal, centers, radii, here)
    assert first.clearance == 0.4 and first.resolution == 0.2
    assert cache.get(goal.copy(), centers.copy(), radii.copy(), here) is first
    assert cache.get(np.array([5.0, 6.0]), centers, radii, here) is not first
    moved = cache.get(goal, centers, np.array([0.6]), here)
    assert moved is not first
    far = np.array([[first.extent_high[0] + 1.0, 0.0]])
    rebuilt = cache.get(goal, centers, np.array([0.6]), far)
    assert rebuilt is not moved and rebuilt.covers(far)
