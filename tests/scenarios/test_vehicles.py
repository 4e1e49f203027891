"""The other vehicles: the LinearVehicle law, its clip and disturbance, the bicycle, leaders, lane changes, yielding."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import DimensionError, InputError
from minimaxplan.scenarios.road import highway_road, tjunction_road, wrap_to_pi
from minimaxplan.scenarios.vehicles import (
    BehaviourParameters,
    TrafficRules,
    TrafficState,
    VehicleParameters,
    acceleration_features,
    bicycle_step,
    desired_speed,
    draw_parameters,
    find_leaders,
    linear_acceleration,
    linear_steering,
    steering_features,
    traffic_step,
    vehicle_corners,
)

BEHAVIOUR = BehaviourParameters()
VEHICLE = VehicleParameters()
NOMINAL_A = np.array([0.3, 0.3, 2.0])
NOMINAL_B = np.array([5.0, 8.33])


def _traffic(
    states,
    routes,
    *,
    controlled=None,
    theta_a=None,
    timer=None,
    interval=None,
    courteous=None,
    target_speed=None,
    route_index=None,
):
    states = np.asarray(states, dtype=float)
    n = states.shape[0]
    routes = np.asarray(routes, dtype=int)
    return TrafficState(
        states=states,
        controlled=np.zeros(n, bool) if controlled is None else np.asarray(controlled),
        spawned=np.ones(n, bool),
        exited=np.zeros(n, bool),
        spawn_step=np.zeros(n, int),
        routes=routes,
        route_index=np.zeros(n, int) if route_index is None else np.asarray(route_index, dtype=int),
        theta_a=np.tile(NOMINAL_A, (n, 1)) if theta_a is None else theta_a,
        theta_b=np.tile(NOMINAL_B, (n, 1)),
        target_speed=states[:, 2].copy() if target_speed is None else target_speed,
        timer=np.full(n, np.inf) if timer is None else timer,
        interval=np.ones(n) if interval is None else interval,
        courteous=np.zeros(n, bool) if courteous is None else courteous,
        committed=np.zeros(n, bool),
        yield_time=np.zeros(n),
    )


def test_parameters_are_drawn_from_the_reference_priors():
    theta_a, theta_b = draw_parameters(np.random.default_rng(0), 4000)
    low_a, high_a = BEHAVIOUR.theta_a_prior
    low_b, high_b = BEHAVIOUR.theta_b_prior
    assert np.allclose(low_a, [0.15, 0.15, 1.0]) and np.allclose(high_a, [0.45, 0.45, 3.0])
    assert np.allclose(low_b, [4.93, 6.83]) and np.allclose(high_b, [5.07, 9.83])
    assert np.all((theta_a >= low_a) & (theta_a <= high_a)) and np.all((theta_b >= low_b) & (theta_b <= high_b))
    # uniform over the whole box: both ends are reached
    assert np.allclose(theta_a.min(axis=0), low_a, atol=0.002 * high_a)
    assert np.allclose(theta_a.max(axis=0), high_a, atol=0.002 * high_a)
    assert np.allclose(theta_b.min(axis=0), low_b, atol=0.01) and np.allclose(theta_b.max(axis=0), high_b, atol=0.01)
    again, _ = draw_parameters(np.random.default_rng(0), 4000)
    assert np.array_equal(theta_a, again)


finite = st.floats(-50, 50)


@given(
    v=st.floats(0, 40),
    vt=st.floats(0, 40),
    vf=st.floats(0, 40),
    gap=st.floats(-5, 200),
    a1=st.floats(0.15, 0.45),
    a2=st.floats(0.15, 0.45),
    a3=st.floats(1.0, 3.0),
    w=st.floats(-0.1, 0.1),
)
def test_acceleration_law_matches_its_formula(v, vt, vf, gap, a1, a2, a3, w):
    f = acceleration_features([v], [vt], [vf], [gap])
    d0, headway = BEHAVIOUR.standstill_distance, BEHAVIOUR.time_headway
    expected_f = [vt - v, min(vf - v, 0.0), min(gap - d0 - headway * v, 0.0)]
    assert np.allclose(f[0], expected_f, atol=1e-12)
    a = linear_acceleration(np.array([[a1, a2, a3]]), f, disturbance=np.array([w]))[0]
    raw = a1 * expected_f[0] + a2 * expected_f[1] + a3 * expected_f[2]
    assert np.isclose(a, np.clip(raw, -6.0, 6.0) + w, atol=1e-9)


def test_no_front_object_zeroes_the_interaction_features():
    f = acceleration_features([20.0], [25.0], [0.0], [np.inf])
    assert f.tolist() == [[5.0, 0.0, 0.0]]


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_clip_and_disturbance_bounds_hold_at_their_extremes(sign):
    theta = np.tile(BEHAVIOUR.theta_a_prior[1], (3, 1))  # the largest gains
    huge = sign * np.array([[1e3, 1e3, 1e3]] * 3)
    w = np.array([-0.1, 0.0, 0.1])
    a = linear_acceleration(theta, huge, disturbance=w)
    assert np.array_equal(a, sign * 6.0 + w)
    # exactly at the clip: no rounding beyond the bound
    at = np.array([[sign * 6.0 / 0.3, 0.0, 0.0]])
    assert linear_acceleration(np.array([[0.3, 0.3, 2.0]]), at)[0] == sign * 6.0
    steer = linear_steering(np.tile(NOMINAL_B, (1, 1)), sign * np.array([[1e3, 1e3]]), VEHICLE.max_steering)
    assert steer[0] == sign * VEHICLE.max_steering


@given(
    h=st.floats(-10, 10),
    psi=st.floats(-10, 10),
    off=st.floats(-5, 5),
    v=st.floats(0, 40),
    b1=st.floats(4.93, 5.07),
    b2=st.floats(6.83, 9.83),
)
def test_steering_law_matches_its_formula(h, psi, off, v, b1, b2):
    g = steering_features([h], [psi], [off], [v], 5.0)
    vv = max(v, 0.01)
    error = (h - psi + np.pi) % (2 * np.pi) - np.pi
    assert np.allclose(g[0], [error * 5.0 / vv, -off * 5.0 / vv**2], rtol=1e-9, atol=1e-9)
    delta = linear_steering(np.array([[b1, b2]]), g, np.pi / 3)[0]
    assert np.isclose(delta, np.clip(b1 * g[0, 0] + b2 * g[0, 1], -np.pi / 3, np.pi / 3), rtol=1e-9, atol=1e-12)


def test_bicycle_step():
    x = np.array([[0.0, 0.0, 10.0, 0.0], [0.0, 0.0, 0.1, 0.5], [0.0, 0.0, 39.9, 0.0], [1.0, 2.0, 5.0, 1.0]])
    nxt = bicycle_step(x, np.array([1.0, -6.0, 6.0, 0.0]), np.array([0.0, 0.0, 0.0, 0.2]), 0.1)
    assert np.allclose(nxt[0], [1.0, 0.0, 10.1, 0.0])
    assert nxt[1, 2] == 0.0  # no reversing
    assert nxt[2, 2] == 40.0  # max speed
    beta = np.arctan(0.5 * np.tan(0.2))
    assert np.allclose(
        nxt[3],
        [1.0 + 0.5 * np.cos(1.0 + beta), 2.0 + 0.5 * np.sin(1.0 + beta), 5.0, 1.0 + 5.0 * np.sin(beta) / 2.5 * 0.1],
    )
    with pytest.raises(DimensionError, match=r"states must have shape \(n, 4\)"):
        bicycle_step(np.zeros((2, 3)), np.zeros(2), np.zeros(2), 0.1)


def test_vehicle_corners():
    c = vehicle_corners(np.array([1.0, 2.0, 0.0, np.pi / 2]))
    assert np.allclose(c, [[0.0, 4.5], [2.0, 4.5], [2.0, -0.5], [0.0, -0.5]])


def test_leaders_follow_lanes_and_routes():
    road = highway_road()
    states = [[100, 0, 20, 0], [130, 0, 20, 0], [160, 0.5, 18, 0], [140, 4, 20, 0], [110, 2.0, 20, 0]]
    traffic = _traffic(states, [[0], [0], [0], [1], [1]])
    leader, gap, front = find_leaders(traffic, road)
    # agent 4 straddles lanes 0 and 1 (heading to lane 1): agent 0 sees it, it sees 1 (lane 0) before 3 (lane 1)
    assert leader.tolist() == [4, 2, -1, -1, 1]
    assert np.allclose(gap, [10 - 5, 30 - 5, np.inf, np.inf, 20 - 5])
    assert np.allclose(front[[0, 1, 4]], [20, 18, 20])
    # through a junction: the leader on the next lane of the route
    tj = tjunction_road()
    route = tj.route("west_in", "west_east", "east_out")
    a = tj.position_at(route[0], 95.0)
    b = tj.position_at(route[1], 10.0)
    traffic = _traffic([[*a, 8, 0], [*b, 6, 0]], [route, route])
    traffic = traffic.evolve(route_index=np.array([0, 1]))
    leader, gap, front = find_leaders(traffic, tj)
    assert leader.tolist() == [1, -1] and np.isclose(gap[0], 100 - 95 + 10 - 5) and np.isclose(front[0], 6)


def _run(traffic, road, steps, *, rules=None, seed=0, controls=None):
    rules = TrafficRules() if rules is None else rules
    rng = np.random.default_rng(seed)
    records = []
    u = np.zeros((len(traffic), 2)) if controls is None else controls
    for k in range(steps):
        traffic, record = traffic_step(traffic, road, u, dt=0.1, step_index=k, rng=rng, rules=rules)
        records.append(record)
    return traffic, records


def test_traffic_step_applies_the_law_it_records():
    road = highway_road()
    theta_a, _ = draw_parameters(np.random.default_rng(1), 4)
    states = [[100, 0, 22, 0], [125, 0, 20, 0], [90, 4, 25, 0.01], [200, 8.3, 21, -0.01]]
    traffic = _traffic(states, [[0], [0], [1], [2]], theta_a=theta_a, target_speed=np.array([25.0, 20, 24, 21]))
    before = traffic
    traffic, (record,) = _run(traffic, road, 1)
    f = record.features
    assert np.allclose(record.acceleration, np.clip(np.einsum("ij,ij->i", theta_a, f), -6, 6) + record.disturbance)
    assert np.all(np.abs(record.disturbance) <= 0.1)
    assert np.allclose(
        record.steering, np.clip(np.einsum("ij,ij->i", before.theta_b, record.steering_features), -np.pi / 3, np.pi / 3)
    )
    assert np.allclose(traffic.states, bicycle_step(before.states, record.acceleration, record.steering, 0.1))
    assert record.leader.tolist() == [1, -1, -1, -1] and np.isclose(record.gap[0], 20.0)
    assert record.intention.tolist() == [0, 0, 1, 2]


def test_lane_changes_fire_on_the_timer_and_respect_gaps():
    road = highway_road()
    rules = TrafficRules(lane_change_probability=1.0)
    # agent 0 in the middle lane, its timer fires at the first step; the left lane (2) is free, the right one (0)
    # is blocked by agent 1 right beside it
    states = [[300, 4, 22, 0], [302, 0, 22, 0]]
    timer = np.array([0.05, np.inf])
    traffic = _traffic(states, [[1], [0]], timer=timer, interval=np.array([5.0, 5.0]))
    outcomes = {}
    for seed in range(12):
        after, records = _run(traffic, road, 1, rules=rules, seed=seed)
        assert records[0].lane_change[0] == (after.lane[0] != 1)
        outcomes[int(after.lane[0])] = seed
    assert set(outcomes) == {1, 2}  # lane 0 (agent 1 is beside it) is never accepted, lane 2 is
    # the change is carried out: 4.5 s later the vehicle is centred in lane 2
    after, records = _run(traffic, road, 45, rules=rules, seed=outcomes[2])
    assert after.lane[0] == 2 and abs(after.states[0, 1] - 8.0) < 0.2 and abs(wrap_to_pi(after.states[0, 3])) < 0.02
    assert max(abs(r.steering[0]) for r in records) < np.pi / 3
    # the timer rearmed with the vehicle's interval (5 s): no second decision yet
    assert sum(int(r.lane_change[0]) for r in records) == 1 and np.isclose(after.timer[0], 0.05 + 5.0 - 4.5)


def _junction_traffic(main_x, main_speed, *, courteous=False):
    """A stem vehicle 1 m before its stop line, turning left; a main-road vehicle eastbound at x = main_x."""
    road = tjunction_road()
    stem = road.route("south_in", "south_west", "west_out")
    main = road.route("west_in", "west_east", "east_out")
    p = road.position_at(stem[0], road.lengths[stem[0]] - 3.5)
    s_main = main_x + 111.0
    q = road.position_at(main[0], s_main)
    traffic = _traffic(
        [[*p, 0.0, np.pi / 2], [*q, main_speed, 0.0]],
        [stem, main],
        target_speed=np.array([8.0, main_speed]),
        courteous=np.array([False, courteous]),
    )
    return road, traffic


def test_a_stem_vehicle_yields_to_the_main_road_then_commits():
    # main-road vehicle 30 m before its stop line at 8 m/s: about 3.4 s < critical gap
    road, traffic = _junction_traffic(-41.0, 8.0)
    _, records = _run(traffic, road, 1)
    assert records[0].yielding[0] and not records[0].yielding[1]
    assert np.isclose(records[0].gap[0], 1.0)
    # far away (100 m at 8 m/s: 12 s): the stem vehicle commits and goes
    road, traffic = _junction_traffic(-105.0, 8.0)
    after, records = _run(traffic, road, 1)
    assert not records[0].yielding[0] and after.committed[0]
    # the whole crossing happens without the two vehicles meeting, and the stem vehicle ends on west_out
    road, traffic = _junction_traffic(-60.0, 8.0)
    rng = np.random.default_rng(0)
    closest, held = np.inf, 0
    for k in range(200):
        traffic, record = traffic_step(traffic, road, np.zeros((2, 2)), dt=0.1, step_index=k, rng=rng)
        closest = min(closest, float(np.linalg.norm(traffic.states[0, :2] - traffic.states[1, :2])))
        held += int(record.yielding[0])
    assert road.names[traffic.lane[0]] == "west_out"
    assert held > 50 and closest > np.hypot(5.0, 2.0)  # it waited, and the rectangles never came near


def test_a_courteous_main_road_vehicle_yields_to_a_waiting_one():
    road, rude = _junction_traffic(-30.0, 8.0)
    _, records = _run(rude, road, 1)
    assert not records[0].yielding[1]
    road, polite = _junction_traffic(-30.0, 8.0, courteous=True)
    _, records = _run(polite, road, 1)
    assert records[0].yielding[1]


def test_desired_speed_is_capped_on_and_before_arcs():
    road = tjunction_road()
    route = road.route("west_in", "west_south", "south_out")
    far = road.position_at(route[0], 10.0)
    near = road.position_at(route[0], 90.0)
    traffic = _traffic([[*far, 8, 0], [*near, 8, 0]], [route, route])
    cap = np.sqrt(2.5 * 9.0)
    assert np.allclose(desired_speed(traffic, road), [8.0, cap])


def test_traffic_state_checks_shapes():
    with pytest.raises(DimensionError, match=r"theta_a must have shape \(2, 3\)"):
        _traffic(np.zeros((2, 4)), [[0], [0]], theta_a=np.zeros((2, 2)))
    with pytest.raises(InputError, match="no field"):
        _traffic(np.zeros((1, 4)), [[0]]).evolve(speed=np.zeros(1))
    with pytest.raises(InputError, match="lane_change_probability"):
        TrafficRules(lane_change_probability=2.0)
    with pytest.raises(DimensionError, match="theta_a_nominal must have length 3"):
        BehaviourParameters(theta_a_nominal=(1.0, 2.0))
    traffic = _traffic(np.zeros((2, 4)), [[0], [0]])
    with pytest.raises(DimensionError, match=r"controls must have shape \(2, 2\)"):
        traffic_step(traffic, highway_road(), np.zeros(2), dt=0.1, step_index=0, rng=np.random.default_rng(0))


@given(seed=st.integers(0, 2**31 - 1))
@settings(max_examples=10, deadline=None)
def test_applied_accelerations_stay_within_the_clip_plus_the_disturbance(seed):
    road = highway_road()
    rng = np.random.default_rng(seed)
    n = 6
    x = np.sort(rng.uniform(100, 400, size=n))
    lanes = rng.integers(3, size=n)
    states = np.stack([x, 4.0 * lanes, rng.uniform(15, 30, size=n), np.zeros(n)], axis=1)
    theta_a, _ = draw_parameters(rng, n)
    traffic = _traffic(
        states,
        lanes[:, None],
        theta_a=theta_a,
        target_speed=rng.uniform(0, 40, size=n),
        timer=rng.uniform(0, 3, size=n),
        interval=np.full(n, 3.0),
    )
    _, records = _run(traffic, road, 50, seed=seed)
    for r in records:
        assert np.all(np.abs(r.disturbance) <= 0.1)
        assert np.all(np.abs(r.acceleration - r.disturbance) <= 6.0)
        assert np.all(np.abs(r.steering) <= np.pi / 3)
