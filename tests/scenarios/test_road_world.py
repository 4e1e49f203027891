"""The driving worlds: determinism, spawning per DRIVING.md, fcl collisions against an exact test, outcomes, traffic sanity."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import DimensionError, InputError
from minimaxplan.scenarios.road_world import (
    EpisodeOver,
    HighwayScenario,
    TJunctionScenario,
    make_road_world,
    rectangles_collide,
)
from minimaxplan.scenarios.vehicles import (
    acceleration_features,
    find_leaders,
    linear_acceleration,
    linear_steering,
    steering_features,
    vehicle_corners,
)

KINDS = ["highway", "tjunction"]


def _sat_overlap(a, b) -> bool:
    """Exact separating-axis test for two rectangles (closed sets: touching counts)."""
    ca, cb = vehicle_corners(a), vehicle_corners(b)
    for corners in (ca, cb):
        for k in range(2):
            edge = corners[k + 1] - corners[k]
            axis = np.array([-edge[1], edge[0]])
            pa, pb = ca @ axis, cb @ axis
            if pa.max() < pb.min() or pb.max() < pa.min():
                return False
    return True


def _margin(a, b) -> float:
    """The largest separation (or smallest overlap) along the four candidate axes, scaled to metres."""
    ca, cb = vehicle_corners(a), vehicle_corners(b)
    best = -np.inf
    for corners in (ca, cb):
        for k in range(2):
            edge = corners[k + 1] - corners[k]
            axis = np.array([-edge[1], edge[0]]) / np.linalg.norm(edge)
            pa, pb = ca @ axis, cb @ axis
            best = max(best, pb.min() - pa.max(), pa.min() - pb.max())
    return best


@given(x=st.floats(-7, 7), y=st.floats(-4, 4), psi_a=st.floats(-np.pi, np.pi), psi_b=st.floats(-np.pi, np.pi))
@settings(max_examples=300)
def test_fcl_rectangle_collision_agrees_with_an_exact_separating_axis_test(x, y, psi_a, psi_b):
    a = np.array([0.0, 0.0, 10.0, psi_a])
    b = np.array([x, y, 3.0, psi_b])
    if abs(_margin(a, b)) < 1e-6:  # tangent: either answer is within rounding
        return
    assert rectangles_collide(a, b) == _sat_overlap(a, b)


def test_rectangle_collision_reference_cases():
    a = np.array([0.0, 0.0, 0.0, 0.0])
    assert rectangles_collide(a, [4.9, 0.0, 0.0, 0.0]) and not rectangles_collide(a, [5.1, 0.0, 0.0, 0.0])
    assert rectangles_collide(a, [0.0, 1.9, 0.0, 0.0]) and not rectangles_collide(a, [0.0, 2.1, 0.0, 0.0])
    # rotated by 90 degrees: the long side across
    assert not rectangles_collide(a, [3.6, 0.0, 0.0, np.pi / 2]) and rectangles_collide(a, [3.4, 0.0, 0.0, np.pi / 2])
    with pytest.raises(DimensionError, match=r"shape \(4,\)"):
        rectangles_collide(np.zeros(3), a)


def _nominal_ego_control(world):
    """The ego driven like a nominal LinearVehicle along its lane (it follows its leader; no junction rule)."""
    traffic, road = world.traffic, world.road
    leader, gap, front = find_leaders(traffic, road)
    x = traffic.states[0]
    lane = int(traffic.lane[0])
    s, off = road.frenet(lane, x[0], x[1])
    f = acceleration_features(x[2:3], traffic.target_speed[:1], front[:1], gap[:1])
    a = linear_acceleration(np.array([[0.3, 0.3, 2.0]]), f)[0]
    k = int(traffic.route_index[0])
    s_ahead = s + 0.1 * x[2]
    if s_ahead > road.lengths[lane] and k + 1 < traffic.route_lengths[0]:
        s_ahead, lane_ahead = s_ahead - road.lengths[lane], int(traffic.routes[0, k + 1])
    else:
        lane_ahead = lane
    g = steering_features(road.heading_at(lane_ahead, s_ahead)[None], x[3:4], np.array([off]), x[2:3], 5.0)
    return np.array([a, linear_steering(np.array([[5.0, 8.33]]), g, np.pi / 3)[0]])


def _trace(kind, seed, steps=30):
    world = make_road_world(kind, seed)
    states, measured = [world.traffic.states.copy()], []
    while not world.done and world.step_index < steps * world.scenario.substeps:
        obs = world.measure()
        measured.append(np.concatenate([obs.ego, obs.vehicles.ravel(), obs.ids]))
        world.step(_nominal_ego_control(world))
        states.append(world.traffic.states.copy())
    return world, states, measured


@pytest.mark.parametrize("kind", KINDS)
def test_same_seed_gives_the_same_episode_bit_for_bit(kind):
    a, states_a, meas_a = _trace(kind, 11)
    b, states_b, meas_b = _trace(kind, 11)
    assert len(states_a) == len(states_b) and all(np.array_equal(x, y) for x, y in zip(states_a, states_b))
    assert all(np.array_equal(x, y) for x, y in zip(meas_a, meas_b))
    assert a.outcome == b.outcome and a.step_index == b.step_index
    assert a.to_dict() == b.to_dict()
    assert np.array_equal(a.intentions(), b.intentions())
    for ra, rb in zip(a.records, b.records):
        assert np.array_equal(ra.acceleration, rb.acceleration) and np.array_equal(ra.disturbance, rb.disturbance)
    # reset replays the same episode
    a.reset()
    assert np.array_equal(a.traffic.states, states_a[0]) and a.step_index == 0 and a.outcome == "running"
    c, states_c, _ = _trace(kind, 12)
    assert c.to_dict() != a.to_dict()


def test_measuring_does_not_change_the_episode():
    a, b = make_road_world("tjunction", 4), make_road_world("tjunction", 4)
    for k in range(20):
        a.measure()
        if k % 3 == 0:
            b.measure()
            b.measure()
        a.step([0.0, 0.0])
        b.step([0.0, 0.0])
    assert np.array_equal(a.traffic.states, b.traffic.states)


@pytest.mark.parametrize("kind", KINDS)
def test_measurement_noise_is_bounded_and_covers_every_vehicle_on_the_road(kind):
    world = make_road_world(kind, 3)
    bound = np.array(world.scenario.measurement_noise)
    largest = np.zeros(4)
    for _ in range(30):
        world.step([0.0, 0.0]) if not world.done else None
        obs = world.measure()
        truth = world.traffic.states
        assert np.array_equal(obs.ids, world.others[world.traffic.active[world.others]])
        err = np.abs(np.vstack([obs.ego, obs.vehicles]) - np.vstack([truth[0], truth[obs.ids]]))
        assert np.all(err <= bound)
        largest = np.maximum(largest, err.max(axis=0))
    assert np.all(largest > 0.8 * bound)  # the noise uses its whole range


def test_highway_spawning_follows_driving_md():
    for seed in range(5):
        world = make_road_world("highway", seed)
        t = world.traffic
        assert len(t) == 16 and t.controlled.tolist() == [True] + [False] * 15
        assert np.isclose(t.states[0, 2], 25.0) and np.isclose(t.states[0, 0], 200.0)
        assert np.all((t.states[1:, 2] >= 20) & (t.states[1:, 2] <= 25))
        assert set(np.round(t.states[:, 1] / 4.0).astype(int)) <= {0, 1, 2}
        assert world.goal_s == 450.0 and world.scenario.max_steps == 400
        # in each lane, consecutive vehicles start at least d0 + T v (the follower's) apart, bumper to bumper
        lanes = np.round(t.states[:, 1] / 4.0).astype(int)
        for k in range(3):
            row = t.states[lanes == k]
            row = row[np.argsort(row[:, 0])]
            gaps = np.diff(row[:, 0]) - 5.0
            assert np.all(gaps >= 5.0 + 1.5 * row[:-1, 2]), (seed, k, gaps)
        # beside the ego, nobody within the ego clearance
        beside = (lanes != lanes[0]) & (np.abs(t.states[:, 0] - 200.0) < world.scenario.ego_clearance)
        assert not beside.any()
        lowa, higha = world.scenario.behaviour.theta_a_prior
        assert np.all((t.theta_a[1:] >= lowa) & (t.theta_a[1:] <= higha))


def test_tjunction_spawning_follows_driving_md():
    world = make_road_world("tjunction", 2)
    t, road = world.traffic, world.road
    assert road.names[t.lane[0]] == "south_in" and 35 <= 100 - road.frenet(t.lane[0], *t.states[0, :2])[0] <= 45
    main = t.states[1:, 2]
    assert np.all((main >= 7) & (main <= 9))
    first = {road.names[r] for r in t.routes[1:, 0]}
    assert first == {"west_in", "east_in"}
    assert np.any(t.spawn_step[1:] > 0) and np.any(t.spawned[1:])  # some on the road, more arriving later
    assert world.scenario.max_steps == 300 and world.goal_s == 25.0


@pytest.mark.parametrize("kind", KINDS)
@given(seed=st.integers(0, 2**31 - 1), stem=st.integers(0, 2))
@settings(max_examples=6, deadline=None)
def test_traffic_without_the_ego_keeps_to_the_road_without_collisions(kind, seed, stem):
    scenario = TJunctionScenario(stem_vehicles=stem) if kind == "tjunction" else None
    world = make_road_world(kind, seed, scenario=scenario, include_ego=False)
    while not world.done:
        world.step()
    assert world.outcome == "timeout" and world.step_index == world.scenario.max_steps
    assert world.traffic_collisions == [] and world.traffic_off_road == []
    moved = sum(float(np.sum(np.abs(r.acceleration))) for r in world.records)
    assert moved > 0
    if kind == "highway":
        assert sum(int(r.lane_change.sum()) for r in world.records) > 0
    else:
        assert world.traffic.exited.any()  # traffic flows through the junction


def test_intentions_are_recorded_at_every_step():
    world = make_road_world("highway", 5, include_ego=False)
    for _ in range(40):
        world.step()
    intentions = world.intentions()
    assert intentions.shape == (world.step_index, len(world.traffic))
    changes = np.stack([r.lane_change for r in world.records])
    assert changes.any()
    for k in range(1, len(intentions)):
        switched = intentions[k] != intentions[k - 1]
        assert np.array_equal(switched, changes[k])  # the intention switches exactly when a change starts
    assert np.all(np.abs(np.diff(intentions, axis=0)) <= 1)  # to a neighbouring lane


def test_highway_ego_following_its_lane_reaches_the_goal():
    world, _, _ = _trace("highway", 1, steps=80)
    assert world.outcome == "goal" and 8.0 < world.time < 40.0
    assert world.traffic_collisions == [] and world.traffic_off_road == []


def test_collision_outcome_whoever_caused_it():
    world = make_road_world("highway", 0)
    states = world.traffic.states.copy()
    states[1] = states[0] + [5.5, 0.0, -25.0, 0.0]  # a stopped vehicle just ahead of the ego
    world.traffic = world.traffic.evolve(states=states)
    assert world.step([0.0, 0.0]) == "collision" and world.time < 0.3
    assert 1 in world.ego_collisions()
    with pytest.raises(EpisodeOver, match="collision"):
        world.step([0.0, 0.0])
    # a vehicle hitting the ego from behind also ends the episode as a collision
    world = make_road_world("highway", 0)
    states = world.traffic.states.copy()
    states[1] = states[0] + [-5.5, 0.0, 15.0, 0.0]
    world.traffic = world.traffic.evolve(states=states)
    assert world.step([-6.0, 0.0]) == "collision"


def test_off_road_and_goal_outcomes():
    world = make_road_world("highway", 0)
    lane = int(world.traffic.lane[0])
    steer = world.scenario.vehicle.max_steering * (1 if lane < 2 else -1)  # towards the nearer edge's far side
    outcome = "running"
    while outcome == "running":
        outcome = world.step([0.0, steer])
    assert outcome in ("off_road", "collision")
    world = make_road_world("tjunction", 0)
    road = world.road
    goal_lane = road.index("west_out")
    x, y = road.position_at(goal_lane, 24.0)
    states = world.traffic.states.copy()
    states[0] = (x, y, 5.0, np.pi)
    world.traffic = world.traffic.evolve(states=states)
    assert world.step([0.0, 0.0]) == "goal" and world.step_index <= 5
    assert world.goal_reached() and world.goal_lanes == (goal_lane,)


def test_world_rejects_bad_input():
    with pytest.raises(InputError, match="kind must be one of"):
        make_road_world("roundabout", 0)
    with pytest.raises(InputError, match="seed"):
        make_road_world("highway", -1)
    with pytest.raises(InputError, match="HighwayScenario"):
        make_road_world("highway", 0, scenario=TJunctionScenario())
    world = make_road_world("highway", 0)
    with pytest.raises(InputError, match="control must lie in"):
        world.step([7.0, 0.0])
    with pytest.raises(DimensionError, match=r"control must have shape \(2,\)"):
        world.step([0.0])
    with pytest.raises(InputError, match="control is required"):
        world.step()
    with pytest.raises(InputError, match="no ego"):
        make_road_world("highway", 0, include_ego=False).step([0.0, 0.0])
    with pytest.raises(InputError, match="measurement_noise"):
        HighwayScenario(measurement_noise=(0.1, 0.1))
    with pytest.raises(InputError, match="goal lies beyond"):
        HighwayScenario(goal_distance=5000.0)


def test_target_speeds_are_the_scenarios_draw_range_as_floats():
    """The forecast and the learner read the other vehicles' target-speed range from `target_speeds` alone."""
    assert HighwayScenario(vehicle_speed=(21, 24)).target_speeds == (21.0, 24.0)
    assert TJunctionScenario(main_speed=(6, 8.5)).target_speeds == (6.0, 8.5)
    assert all(type(v) is float for v in HighwayScenario(vehicle_speed=(21, 24)).target_speeds)
