"""TrafficLearner against the ground truth of the driving worlds: elimination never removes the
intention in force, the true parameters stay in the boxes, clear wrong intentions are eliminated."""

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.analysis.traffic_learning import (
    TrafficLearner,
    elimination_statistics,
    hold_lane_control,
    remainder_bound,
)
from minimaxplan.models import InputError
from minimaxplan.scenarios.road_world import make_road_world
from minimaxplan.scenarios.traffic_models import VehicleBelief


class _Extremes:
    """A stand-in random stream: every uniform draw at an end of its interval (noise and
    disturbances at their extremes; lane-change draws at 0 or 1, so firing timers always try)."""

    def __init__(self, seed: int) -> None:
        self._rng = np.random.default_rng(seed)

    def uniform(self, low=0.0, high=1.0, size=None):
        return np.where(self._rng.random(size) < 0.5, low, high)


def _run(kind: str, seed: int, steps: int, *, extreme: bool):
    world = make_road_world(kind, seed)
    if extreme:
        world._noise_rng = _Extremes(seed)
        world._dynamics_rng = _Extremes(seed + 1)
    learner = TrafficLearner(world.road, world.scenario)
    learner.observe(world.measure())
    checked = changes = 0
    while not world.done and world.step_index < steps:
        world.apply(hold_lane_control(world))
        learner.observe(world.measure())
        changes += int(world.records[-1].lane_change.sum())
        for agent, belief in learner.beliefs().items():
            checked += 1
            true_lane = int(world.traffic.lane[agent])
            assert true_lane in belief.lanes, (kind, seed, world.step_index, agent, true_lane, belief.lanes)
            if kind == "tjunction":
                route = tuple(int(r) for r in world.traffic.routes[agent] if r >= 0)
                assert any(route[-len(r) :] == r for r in belief.routes), (seed, agent, route, belief.routes)
            assert belief.theta_a.contains(world.traffic.theta_a[agent]), (seed, agent, belief.theta_a)
            assert belief.theta_b.contains(world.traffic.theta_b[agent]), (seed, agent, belief.theta_b)
    return world, learner, checked, changes


@settings(max_examples=4, deadline=None)
@given(seed=st.integers(0, 10_000), extreme=st.booleans())
def test_highway_true_intention_and_parameters_never_lost(seed, extreme):
    _, _, checked, _ = _run("highway", seed, 60, extreme=extreme)
    assert checked > 0


@settings(max_examples=3, deadline=None)
@given(seed=st.integers(0, 10_000), extreme=st.booleans())
def test_tjunction_true_route_and_parameters_never_lost(seed, extreme):
    _, _, checked, _ = _run("tjunction", seed, 100, extreme=extreme)
    assert checked > 0


def test_lane_changes_with_extreme_noise_keep_the_true_intention():
    """Seed 1 has a lane change at sub-step 18 (agent 14); with every draw extreme, more happen."""
    world, learner, checked, changes = _run("highway", 1, 40, extreme=True)
    assert changes >= 1 and checked > 400
    assert learner.eliminations  # wrong lanes do get eliminated


def test_the_lane_being_left_is_eliminated_in_mid_lane_change():
    world = make_road_world("highway", 1)
    learner = TrafficLearner(world.road, world.scenario)
    learner.observe(world.measure())
    agent, origin = 14, None
    while world.step_index < 17:
        world.apply(hold_lane_control(world))
        learner.observe(world.measure())
    origin = int(world.traffic.lane[agent])
    assert (origin,) in learner.survivors(agent)
    world.apply(hold_lane_control(world))
    learner.observe(world.measure())
    assert world.records[-1].lane_change[agent]
    target = int(world.traffic.lane[agent])
    for _ in range(5):
        world.apply(hold_lane_control(world))
        learner.observe(world.measure())
    assert (origin,) not in learner.survivors(agent)
    assert learner.survivors(agent) == [(target,)]
    estimate = learner.nominal([agent])[agent]
    assert estimate.lane == target and estimate.route == (target,)
    b = learner.prior_b
    assert np.all(estimate.theta_b >= b.low) and np.all(estimate.theta_b <= b.high)


def test_the_learner_gives_the_forecast_its_vehicle_belief():
    fields = [f.name for f in dataclasses.fields(VehicleBelief)]
    assert fields[:5] == ["agent", "theta_a", "theta_b", "lanes", "routes"]
    world = make_road_world("highway", 0)
    learner = TrafficLearner(world.road, world.scenario)
    learner.observe(world.measure())
    beliefs = learner.beliefs()
    assert beliefs and all(type(b) is VehicleBelief for b in beliefs.values())


def test_remainder_bound_is_the_largest_remainder():
    D = np.linspace(0, np.pi / 3, 50)
    delta = np.linspace(-np.pi / 3, np.pi / 3, 20001)
    r = np.abs(np.sin(np.arctan(np.tan(delta) / 2)) - delta / 2)
    for d in D:
        assert r[np.abs(delta) <= d].max() <= remainder_bound(d)


def test_elimination_statistics():
    stats = elimination_statistics([("a", 3), ("a", 5), ("a", None), ("b", None), ("a", 10)])
    assert stats["a"] == {"count": 4, "eliminated": 3, "median": 5.0, "min": 3, "max": 10}
    assert stats["b"]["eliminated"] == 0 and stats["b"]["median"] is None


def test_the_learner_refuses_a_sub_step_it_has_already_learned_from():
    """A second measurement of a learned sub-step (or an earlier one) is a typed error, not a silent overwrite."""
    world = make_road_world("highway", 0)
    learner = TrafficLearner(world.road, world.scenario)
    learner.observe(world.measure())
    world.apply(hold_lane_control(world))
    first = world.measure()
    learner.observe(first)
    rows = {a: [h.lat_rows.n for h in t.hyps] for a, t in learner.tracks.items()}
    for again in (world.measure(), first):
        with pytest.raises(InputError, match="sub-step 1, not after the last observed sub-step 1"):
            learner.observe(again)
    assert learner.step == 1
    assert {a: [h.lat_rows.n for h in t.hyps] for a, t in learner.tracks.items()} == rows


def test_the_learner_skips_steering_rows_where_the_route_may_switch_early():
    """With ``route_switch_distance`` > 0 the world may steer by the arc's lane before the
    straight lane ends: no steering row is taken within that distance of a turn (the route
    frame's features would not be the world's), and the same state farther back still gives one."""
    from minimaxplan.analysis.traffic_learning import _Hypothesis
    from minimaxplan.scenarios.road import ARC

    world = make_road_world("tjunction", 0)
    road = world.road
    route = road.route("south_in", "south_west", "west_out")  # a left turn
    before = next(k for k in range(len(route) - 1) if road.kinds[route[k + 1]] == ARC)
    lane, length = route[before], float(road.lengths[route[before]])
    behaviour = dataclasses.replace(world.scenario.behaviour, route_switch_distance=2.5)
    for switch, learner in (
        (0.0, TrafficLearner(road, world.scenario)),
        (2.5, TrafficLearner(road, dataclasses.replace(world.scenario, behaviour=behaviour))),
    ):
        for back, usable in ((10.0, True), (1.0, switch == 0.0)):
            x, y = road.position_at(lane, length - back)
            state = np.array([x, y, 8.0, float(road.heading_at(lane, length - back))])
            step = learner._lateral_step(_Hypothesis(route=tuple(route), tstar=0), state)
            assert (step is not None) == usable, (switch, back)
