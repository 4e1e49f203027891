"""Two sound forecasts of one world intersected at their shared sub-steps: still sound, at least as tight."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import InputError
from minimaxplan.scenarios.forecast_intersection import intersect_forecasts
from minimaxplan.scenarios.traffic_models import TrafficForecast

from .test_traffic_models import SCENES, _check, _episode, _misses


@settings(max_examples=20)
@given(**SCENES, lag=st.integers(1, 12))
def test_the_intersection_of_two_forecasts_contains_the_world_and_is_inside_both(kind, seed, dt, lag, corners):
    """Forecasts made ``lag`` sub-steps apart from prior beliefs (disturbances at their extremes, parameters in
    the prior or at its vertices): their intersection contains every vehicle at every shared sub-step, is inside
    the later forecast everywhere and inside the earlier one where it covers, and finds nothing inconsistent."""
    steps = 30
    world, run, observations, _ = _episode(kind, seed, dt, lag + steps + 1, corners=corners)
    states = run[0]
    if len(states) < lag + steps + 1:
        return  # the episode ended early (the ego reached the goal)
    earlier_misses, _, earlier = _check(world, run, observations, 0, steps)
    later_misses, _, later = _check(world, run, observations, lag, steps)
    assert earlier_misses == later_misses == 0
    met = intersect_forecasts(later, lag, earlier, 0)
    assert met.inconsistent == 0
    assert met.shared_steps == steps + 1 - lag and met.shared_vehicles > 0
    out = met.forecast
    assert _misses(out, states, lag, steps + 1) == 0
    finite = np.isfinite(out.boxes).all(-1)
    assert np.all(out.boxes[finite][:, :2] >= later.boxes[finite][:, :2])
    assert np.all(out.boxes[finite][:, 2:] <= later.boxes[finite][:, 2:])
    columns = {int(a): j for j, a in enumerate(earlier.ids)}
    for j, agent in enumerate(out.ids):
        if int(agent) not in columns:
            continue
        k = columns[int(agent)]
        for n in range(met.shared_steps):
            old = earlier.boxes[lag + n, k]
            if np.isfinite(old).all() and np.isfinite(out.boxes[n, j]).all():
                assert np.all(out.boxes[n, j, :2] >= old[:2]) and np.all(out.boxes[n, j, 2:] <= old[2:])
    np.testing.assert_array_equal(out.state_lower[..., 3], later.state_lower[..., 3])  # headings kept


def _forecast(boxes, lower, upper, ids):
    boxes = np.asarray(boxes, dtype=float)
    return TrafficForecast(
        boxes=boxes,
        state_lower=np.asarray(lower, dtype=float),
        state_upper=np.asarray(upper, dtype=float),
        guaranteed=np.ones(boxes.shape[:2], dtype=bool),
        ids=np.asarray(ids),
        dt=0.1,
    )


def test_rows_empty_in_either_forecast_keep_the_later_one_and_disjoint_rows_are_counted():
    empty = [np.inf, np.inf, -np.inf, -np.inf]
    state = np.zeros(4)
    # later: 2 steps, vehicles 7 and 9; earlier: 3 steps from one sub-step before, vehicles 9 and 7
    later = _forecast(
        [[[0, 0, 2, 2], [10, 0, 12, 2]], [[0, 0, 2, 2], empty]],
        [[state, state + 10], [state - 1, state]],
        [[state + 2, state + 12], [state + 1, state]],
        [7, 9],
    )
    earlier = _forecast(
        [[[9, 9, 9, 9], [9, 9, 9, 9]], [[11, 1, 13, 3], [1, 1, 3, 3]], [empty, [5, 5, 6, 6]]],
        np.zeros((3, 2, 4)) - 100,
        np.zeros((3, 2, 4)) + 100,
        [9, 7],
    )
    met = intersect_forecasts(later, 5, earlier, 4)
    assert met.shared_steps == 2 and met.shared_vehicles == 2
    out = met.forecast
    np.testing.assert_array_equal(out.boxes[0, 0], [1, 1, 2, 2])  # vehicle 7 met with [1, 1, 3, 3]
    np.testing.assert_array_equal(out.boxes[0, 1], [11, 1, 12, 2])  # vehicle 9 met with [11, 1, 13, 3]
    np.testing.assert_array_equal(out.boxes[1, 0], [0, 0, 2, 2])  # disjoint from [5, 5, 6, 6]: kept, counted
    assert np.all(np.isinf(out.boxes[1, 1]))  # empty in the later forecast: kept empty
    assert met.inconsistent == 1
    assert met.to_dict() == {"shared_steps": 2, "shared_vehicles": 2, "inconsistent": 1}
    # with no shared sub-step nothing changes
    far = intersect_forecasts(later, 40, earlier, 4)
    assert far.shared_steps == 0 and far.inconsistent == 0
    np.testing.assert_array_equal(far.forecast.boxes, later.boxes)


@pytest.mark.parametrize(
    "later_step, earlier_step, match",
    [
        (-1, 0, "later_step must be a non-negative integer"),
        (3, 4, "earlier_step must be <= later_step"),
        (2.0, 1, "later_step must be a non-negative integer"),
        (True, 0, "later_step"),
    ],
)
def test_bad_steps_are_refused_with_a_typed_error(later_step, earlier_step, match):
    one = _forecast([[[0, 0, 1, 1]]], [[np.zeros(4)]], [[np.ones(4)]], [1])
    with pytest.raises(InputError, match=match):
        intersect_forecasts(one, later_step, one, earlier_step)
    with pytest.raises(InputError, match="TrafficForecasts"):
        intersect_forecasts(one, 1, "not a forecast", 0)


def test_a_forecast_refuses_ids_that_are_not_integers_and_flags_that_are_not_booleans():
    with pytest.raises(InputError, match="ids must hold integers"):
        _forecast([[[0, 0, 1, 1]]], [[np.zeros(4)]], [[np.ones(4)]], [1.5])
    with pytest.raises(InputError, match="guaranteed must hold booleans"):
        TrafficForecast(
            np.zeros((1, 1, 4)), np.zeros((1, 1, 4)), np.zeros((1, 1, 4)), np.full((1, 1), 0.5), np.array([1]), 0.1
        )
    ok = _forecast([[[0, 0, 1, 1]]], [[np.zeros(4)]], [[np.ones(4)]], [3.0])
    assert ok.ids.dtype.kind == "i" and ok.guaranteed.dtype == bool
