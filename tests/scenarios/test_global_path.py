"""Global grid path and its waypoints."""

import numpy as np
import pytest

from minimaxplan.models import DimensionError, InputError
from minimaxplan.scenarios import CircularObstacles
from minimaxplan.scenarios.global_path import GlobalPath


def _wall():
    # A wall of discs across x = 10 from the grid's lower edge, with a gap above y = 16.
    ys = np.arange(-3.0, 15.5, 1.0)
    return CircularObstacles(np.stack([np.full_like(ys, 10.0), ys], axis=1), np.full(ys.shape, 0.6))


def test_empty_map_gives_the_straight_line():
    path = GlobalPath(CircularObstacles.empty(), [15.0, 5.0])
    assert path.distance([5.0, 5.0]) == pytest.approx(10.0, abs=0.3)
    np.testing.assert_allclose(path.waypoint([5.0, 5.0], 3.0), [8.0, 5.0], atol=0.25)


def test_path_goes_around_the_wall_and_keeps_its_clearance():
    obstacles = _wall()
    path = GlobalPath(obstacles, [15.0, 5.0], clearance=0.5)
    points = path.path([5.0, 5.0])
    gaps = np.linalg.norm(points[:, None, :] - obstacles.centers[None], axis=-1) - obstacles.radii
    assert gaps.min() > 0.5 - 1e-9
    assert points[:, 1].max() > 15.0  # through the gap, not through the wall
    assert path.distance([5.0, 5.0]) > 20.0
    np.testing.assert_allclose(points[-1], [15.0, 5.0])


def test_waypoint_is_lookahead_along_the_path_or_the_goal():
    path = GlobalPath(_wall(), [15.0, 5.0])
    start = np.array([5.0, 5.0])
    near = path.waypoint(start, 1.0)
    far = path.waypoint(start, 4.0)
    assert np.linalg.norm(near - start) <= 1.0 + 0.3
    assert path.distance(far) < path.distance(near) < path.distance(start)
    np.testing.assert_allclose(path.waypoint([14.8, 5.1], 3.0), [15.0, 5.0])


def test_bad_arguments_are_named():
    with pytest.raises(DimensionError, match="goal"):
        GlobalPath(CircularObstacles.empty(), [1.0, 2.0, 3.0])
    with pytest.raises(InputError, match="bounds"):
        GlobalPath(CircularObstacles.empty(), [1.0, 2.0], bounds=(5.0, 5.0))
    with pytest.raises(InputError, match="lookahead"):
        GlobalPath(CircularObstacles.empty(), [1.0, 2.0]).waypoint([0.0, 0.0], -1.0)
