"""The highway-env adapter (the ``vehicle`` extra: these tests fail, not skip, when CI=true).

Ground truth (target lanes, crashes) is read here, in the tests only, to select the
vehicle-steps the library's model covers; the adapter itself reads positions, speeds
and headings only.
"""

import warnings

import numpy as np
import pytest
from extras import require_extra
from hypothesis import given
from hypothesis import strategies as st

highway_env = require_extra("highway_env")

from minimaxplan.models import InputError  # noqa: E402
from minimaxplan.scenarios.highway_env_adapter import (  # noqa: E402
    HighwayEnvAdapter,
    VehicleClassConstants,
    meta_action,
    restore_vehicle_classes,
    road_from_highway_env,
    uncovered_reason,
)
from minimaxplan.scenarios.road_world import HighwayScenario, TJunctionScenario  # noqa: E402
from minimaxplan.scenarios.traffic_models import _route_switch_steering  # noqa: E402
from minimaxplan.scenarios.vehicles import vehicle_corners  # noqa: E402

#: The planner's horizon, s.
HORIZON = 5.0


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # gymnasium: "intersection-v0 is out of date"
        yield


def _adapter(env_id, hz):
    # one policy step per simulation step: every simulated state is observed
    return HighwayEnvAdapter(env_id, config={"simulation_frequency": hz, "policy_frequency": hz})


def _record(adapter, seed, steps, action):
    observations = [adapter.reset(seed)]
    truth = [adapter.ground_truth()]
    for _ in range(steps):
        observation, terminated, truncated = adapter.step(action)
        observations.append(observation)
        truth.append(adapter.ground_truth())
        if terminated or truncated:
            break
    return observations, truth


def _containment(adapter, observations, truth, t0, steps):
    """Counts of covered vehicle-steps inside / outside the forecast, and of excluded ones."""
    ego = np.array([o.ego for o in observations[t0 : t0 + steps + 1]])
    corners = vehicle_corners(ego, adapter.scenario.vehicle)
    reach = np.concatenate([corners.min(axis=1) - 1e-9, corners.max(axis=1) + 1e-9], axis=1)
    speed = np.stack([ego[:, 2] - 1e-9, ego[:, 2] + 1e-9], axis=1)
    heading = np.stack([ego[:, 3] - 1e-9, ego[:, 3] + 1e-9], axis=1)
    forecast = adapter.forecast(
        observations[t0], steps * adapter.dt, ego_reach=reach, ego_speed=speed, ego_heading=heading
    )
    assert forecast.steps == steps
    counts = {"inside": 0, "outside": 0, "lane_change": 0, "crashed": 0, "reversing": 0, "next_lane": 0}
    misses = []
    for j, agent in enumerate(forecast.ids):
        first = truth[t0][int(agent)]
        excluded = None
        for n in range(1, steps + 1):
            now = truth[t0 + n].get(int(agent))
            if now is None:
                break  # left the road
            if excluded is None:
                excluded = uncovered_reason(first, now)
            if excluded is not None:
                counts[excluded] += 1
                continue
            # covered, also once highway-env steers by the next route lane (counted)
            counts["next_lane"] += now["target"] != first["target"]
            state = now["state"]
            lo, hi = forecast.state_lower[n, j], forecast.state_upper[n, j]
            box = forecast.boxes[n, j]
            rect = vehicle_corners(state, adapter.scenario.vehicle).reshape(-1, 2)
            inside = (
                np.all(state[:3] >= lo[:3])
                and np.all(state[:3] <= hi[:3])
                and np.all(rect >= box[:2])
                and np.all(rect <= box[2:])
            )
            counts["inside" if inside else "outside"] += 1
            if not inside:
                misses.append(state)
    return counts, misses


def _total(adapter, seeds, action, starts):
    steps = adapter.steps(HORIZON)
    total = {"inside": 0, "outside": 0, "lane_change": 0, "crashed": 0, "reversing": 0, "next_lane": 0}
    misses = []
    for seed in seeds:
        observations, truth = _record(adapter, seed, steps + max(starts), action)
        for t0 in starts:
            if t0 + steps < len(observations):
                counts, miss = _containment(adapter, observations, truth, t0, steps)
                misses += miss
                for key, value in counts.items():
                    total[key] += value
    return total, misses


# ------------------------------------------------------------------ the road
@pytest.mark.parametrize("env_id", ["highway-fast-v0", "intersection-v0"])
def test_road_is_highway_envs_road(env_id):
    adapter = HighwayEnvAdapter(env_id)
    adapter.reset(0)
    network = adapter.env.unwrapped.road.network
    road = adapter.road
    rng = np.random.default_rng(0)
    lanes = [(key, network.get_lane(key)) for key in adapter.lane_index]
    assert len(lanes) == len(road) and len(road) == sum(len(e) for t in network.graph.values() for e in t.values())
    for key, lane in lanes:
        k = adapter.lane_index[key]
        s = rng.uniform(0.0, lane.length, 20)
        lat = rng.uniform(-2.0, 2.0, 20)
        theirs = np.array([lane.position(a, b) for a, b in zip(s, lat)])
        np.testing.assert_allclose(road.position_at(np.full(20, k), s, lat), theirs, atol=1e-9)
        np.testing.assert_allclose(road.heading_at(np.full(20, k), s), [lane.heading_at(a) for a in s], atol=1e-12)
        assert road.widths[k] == lane.width
        assert road.priorities[k] == lane.priority
        ours = np.stack(road.frenet(np.full(20, k), theirs[:, 0], theirs[:, 1]), axis=1)
        np.testing.assert_allclose(ours, np.stack([s, lat], axis=1), atol=1e-9)
    for a, b in road.connections:  # lane a's end node is lane b's start node, and a's end is b's start
        assert road.names[a].split(">")[1].split(":")[0] == road.names[b].split(">")[0]
        np.testing.assert_allclose(road.lanes[a].position(road.lanes[a].length), road.lanes[b].position(0.0), atol=1e-6)
    if env_id == "highway-fast-v0":
        assert road.side_groups == ((0, 1, 2),)  # right to left: lane id 0 at y = 0 is the rightmost
        assert isinstance(adapter.scenario, HighwayScenario)
        assert adapter.scenario.dt == 0.2
    else:
        assert not road.side_groups and len(road.connections) == 24  # 4 arms x 3 turns x 2
        assert isinstance(adapter.scenario, TJunctionScenario)
        assert adapter.scenario.dt == pytest.approx(1 / 15)
        assert adapter.scenario.behaviour.standstill_distance == 2.0  # intersection-v0's DISTANCE_WANTED = 7


def test_road_rejects_lanes_the_library_cannot_express():
    from highway_env.road.lane import SineLane
    from highway_env.road.road import RoadNetwork

    net = RoadNetwork()
    net.add_lane("a", "b", SineLane([0, 0], [100, 0], 2.0, 0.1, 0.0))
    with pytest.raises(InputError, match="SineLane"):
        road_from_highway_env(net)


def test_scenario_is_the_linear_vehicle_family():
    adapter = HighwayEnvAdapter("highway-fast-v0")
    adapter.reset(0)
    from highway_env.vehicle.behavior import LinearVehicle

    behaviour = adapter.scenario.behaviour
    lo, hi = behaviour.theta_a_prior
    np.testing.assert_allclose(lo, LinearVehicle.ACCELERATION_RANGE[0], rtol=1e-12)
    np.testing.assert_allclose(hi, LinearVehicle.ACCELERATION_RANGE[1], rtol=1e-12)
    b_lo, b_hi = behaviour.theta_b_prior
    np.testing.assert_allclose(b_lo, LinearVehicle.STEERING_RANGE[0], rtol=1e-12)
    np.testing.assert_allclose(b_hi, LinearVehicle.STEERING_RANGE[1], rtol=1e-12)
    assert behaviour.time_headway == LinearVehicle.TIME_WANTED == 2.5
    assert behaviour.standstill_distance == 5.0 and behaviour.disturbance_bound == 0.0
    assert adapter.scenario.vehicle_speed == pytest.approx((21.0, 24.0))
    for v in adapter.env.unwrapped.road.vehicles[1:]:  # every other vehicle is a LinearVehicle in the priors
        assert type(v) is LinearVehicle
        assert np.all(lo <= v.ACCELERATION_PARAMETERS) and np.all(v.ACCELERATION_PARAMETERS <= hi)
        assert np.all(b_lo - 1e-12 <= v.STEERING_PARAMETERS) and np.all(v.STEERING_PARAMETERS <= b_hi + 1e-12)
        assert 21.0 <= v.target_speed <= 24.0


# ------------------------------------------------------------------ observations and actions
def test_observation_holds_kinematics_with_stable_ids():
    adapter = HighwayEnvAdapter("highway-fast-v0")
    first = adapter.reset(1)
    base = adapter.env.unwrapped
    others = [v for v in base.road.vehicles if v is not base.vehicle]
    np.testing.assert_array_equal(first.vehicles, [[*v.position, v.speed, v.heading] for v in others])
    np.testing.assert_array_equal(first.ego, [*base.vehicle.position, base.vehicle.speed, base.vehicle.heading])
    assert sorted(first.ids.tolist()) == list(range(1, len(others) + 1))
    second, _, _ = adapter.step("IDLE")
    assert second.ids.tolist() == first.ids.tolist()  # the same vehicles, the same ids
    assert second.time == pytest.approx(1.0)  # one policy step of highway-fast-v0 (1 Hz)
    assert not np.array_equal(second.vehicles, first.vehicles)


def test_meta_actions_map_the_planners_lanes_onto_highway_envs():
    adapter = HighwayEnvAdapter("highway-fast-v0", config={"initial_lane_id": 1})
    adapter.reset(2)
    indexes = adapter.env.unwrapped.action_type.actions_indexes
    assert meta_action(adapter.env, "LANE_LEFT") == indexes["LANE_RIGHT"]
    assert meta_action(adapter.env, "LANE_RIGHT") == indexes["LANE_LEFT"]
    for name in ("IDLE", "FASTER", "SLOWER"):
        assert meta_action(adapter.env, name) == indexes[name]
    y0 = adapter.env.unwrapped.vehicle.position[1]
    observation, _, _ = adapter.step("LANE_LEFT")  # the library's left: +y, the next lane of its side group
    assert adapter.env.unwrapped.vehicle.target_lane_index[2] == 2
    assert observation.ego[1] > y0 + 1.0
    intersection = HighwayEnvAdapter("intersection-v0")
    intersection.reset(0)
    assert meta_action(intersection.env, "SLOWER") == intersection.env.unwrapped.action_type.actions_indexes["SLOWER"]
    with pytest.raises(InputError, match="LANE_LEFT"):
        meta_action(intersection.env, "LANE_LEFT")


# ------------------------------------------------------------------ containment
@pytest.mark.parametrize("hz", [5, 15])
def test_forecast_contains_highway_envs_vehicles_on_the_highway(hz):
    """highway-fast-v0: every covered vehicle-step (no lane change) in its box over 5 s."""
    adapter = _adapter("highway-fast-v0", hz)
    steps = adapter.steps(HORIZON)
    total, misses = _total(adapter, seeds=(1, 4), action="IDLE", starts=(0, steps // 2, steps))
    assert total["outside"] == 0, misses[:3]
    assert total["inside"] >= 2000  # 20 vehicles x 25 or 75 sub-steps x the windows that fit
    assert 0 < total["lane_change"] < total["inside"]  # MOBIL changes lanes: counted, excluded


@pytest.mark.parametrize("hz", [5, 15])
def test_forecast_contains_highway_envs_vehicles_at_the_intersection(hz):
    """intersection-v0: every covered vehicle-step in its box over 5 s, through the turns.

    Covered: every step until a crash or reversing (speed below 0), including those after
    highway-env steers by the next route lane (``follow_road`` switches L/2 before a
    lane's end, the forecast's ``route_switch_distance``; counted in ``next_lane``).
    """
    adapter = _adapter("intersection-v0", hz)
    steps = adapter.steps(HORIZON)
    total, misses = _total(adapter, seeds=(0, 1, 2, 3), action="SLOWER", starts=(0, steps // 2, steps))
    assert total["inside"] >= 1000 * hz // 5, total
    assert total["next_lane"] >= total["inside"] // 10, total  # the turns are in the test
    assert total["outside"] == 0, (total, misses[:3])


def test_uncovered_reason_names_the_first_rule_that_applies():
    fact = {"state": np.array([0.0, 0.0, 5.0, 0.0]), "lane_change": False, "target": ("a", "b", 0), "crashed": False}
    assert uncovered_reason(fact, fact) is None
    assert uncovered_reason(fact, {**fact, "target": ("b", "c", 0)}) is None  # the next route lane is covered
    assert uncovered_reason({**fact, "lane_change": True}, fact) == "lane_change"
    assert uncovered_reason(fact, {**fact, "crashed": True, "state": np.array([0.0, 0.0, -1.0, 0.0])}) == "crashed"
    assert uncovered_reason(fact, {**fact, "state": np.array([0.0, 0.0, -0.1, 0.0])}) == "reversing"


# ------------------------------------------------------------------ the early route switch
def _turn(radius, clockwise):
    """highway-env lanes of a turn: a 40 m straight, a quarter arc tangent to it, a straight after."""
    from highway_env.road.lane import CircularLane, StraightLane
    from highway_env.road.road import Road as HighwayEnvRoad
    from highway_env.road.road import RoadNetwork

    direction = 1 if clockwise else -1  # highway-env's arcs turn to +phi when clockwise
    approach = StraightLane([-40.0, 0.0], [0.0, 0.0])
    center = np.array([0.0, direction * radius])
    start = -direction * np.pi / 2
    arc = CircularLane(center, radius, start, start + direction * np.pi / 2, clockwise=clockwise)
    end = arc.position(arc.length, 0.0)
    exit_lane = StraightLane(
        end, end + 40.0 * np.array([np.cos(arc.heading_at(arc.length)), np.sin(arc.heading_at(arc.length))])
    )
    network = RoadNetwork()
    network.add_lane("a", "b", approach)
    network.add_lane("b", "c", arc)
    network.add_lane("c", "d", exit_lane)
    return HighwayEnvRoad(network=network), (("a", "b", 0), ("b", "c", 0), ("c", "d", 0)), direction


def _route_frame_features(vehicle, road, lanes, piece):
    """The library's law: the lane the centre is in by route distance, the heading tau v ahead along the route."""
    from highway_env import utils

    lane = road.network.get_lane(lanes[piece])
    lon, lat = lane.local_coordinates(vehicle.position)
    ahead = lon + vehicle.speed * vehicle.TAU_PURSUIT
    for nxt in lanes[piece + 1 :]:
        if ahead <= lane.length:
            break
        ahead -= lane.length
        lane = road.network.get_lane(nxt)
    heading = lane.heading_at(ahead)
    v = utils.not_zero(vehicle.speed)
    return np.array([utils.wrap_to_pi(heading - vehicle.heading) * vehicle.LENGTH / v, -lat * vehicle.LENGTH / v**2])


@given(
    radius=st.floats(6.0, 40.0),
    clockwise=st.booleans(),
    entering=st.booleans(),
    x=st.floats(0.0, 2.5),
    width=st.floats(0.0, 1.0),
    e=st.floats(-1.5, 1.5),
    chi=st.floats(-0.6, 0.6),
    v=st.one_of(st.just(0.0), st.just(1e-3), st.floats(0.0, 20.0)),
    gains=st.tuples(st.floats(4.93, 5.07), st.floats(6.83, 9.83)),
    at=st.tuples(*[st.one_of(st.just(0.0), st.just(1.0), st.floats(0.0, 1.0))] * 3),
    widths=st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 3.0)),
)
def test_the_route_switch_steering_holds_highway_envs_own_features(
    radius, clockwise, entering, x, width, e, chi, v, gains, at, widths
):
    """The steering change of an early switch (`_route_switch_steering`) bounds highway-env's own.

    A ``LinearVehicle`` on highway-env's lanes of a turn, ``x`` m before the end of the
    approach (its next lane the arc) or of the arc (the straight after), any offset,
    heading error, speed (standstill and ``not_zero``'s floor among them) and gains:
    ``theta_b . (features on the next lane - features of the route frame)`` lies in the
    bound of a box of route distances, offsets and speeds that holds the vehicle (at
    either end of each side or inside).
    """
    from highway_env.vehicle.behavior import LinearVehicle

    road, lanes, sign = _turn(radius, clockwise)
    approach, arc = road.network.get_lane(lanes[0]), road.network.get_lane(lanes[1])
    piece = 0 if entering else 1
    lane = (approach, arc)[piece]
    lon = lane.length - x
    vehicle = LinearVehicle(road, lane.position(lon, e), heading=lane.heading_at(lon) + chi, speed=v)
    vehicle.STEERING_PARAMETERS = list(gains)
    switched = vehicle.steering_features(lanes[piece + 1])
    library = _route_frame_features(vehicle, road, lanes, piece)
    delta = float(np.dot(gains, switched - library))

    s = approach.length - x if entering else approach.length + arc.length - x

    def around(value, spread, where, floor=-np.inf):
        low = max(value - spread * where, floor)
        return np.array([low]), np.array([max(low + spread, value)])

    v_lo, v_hi = around(v, widths[1], at[2], floor=0.0)
    speed = (np.maximum(v_lo, 1e-2), np.maximum(v_hi, 1e-2))  # not_zero
    lo, hi = _route_switch_steering(
        around(s, width, at[0]),
        around(e, widths[0], at[1]),
        (vehicle.TAU_PURSUIT * v_lo, vehicle.TAU_PURSUIT * v_hi),
        speed,
        (np.array([gains[0]]),) * 2,
        (gains[1] / speed[1], gains[1] / speed[0]),
        start=np.array([approach.length]),
        end=np.array([approach.length + arc.length]),
        radius=np.array([radius]),
        sign=np.array([float(sign)]),
        switch=2.5,
        length=vehicle.LENGTH,
    )
    assert lo[0] <= delta <= hi[0], (lo[0], delta, hi[0])
    assert lo[0] <= 0.0 <= hi[0]  # the library's own law (no early switch) is covered too


def test_the_route_switch_changes_nothing_where_lanes_continue_straight():
    """highway-fast-v0's lanes are collinear segments: its forecasts are the same bits without the switch window."""
    import dataclasses

    adapter = _adapter("highway-fast-v0", 5)
    assert adapter.reset(1) is not None
    scenario = adapter.scenario
    assert scenario.behaviour.route_switch_distance == 2.5  # highway-env's L / 2
    observation = adapter.step("IDLE")[0]
    steps = adapter.steps(HORIZON)
    corners = vehicle_corners(observation.ego, scenario.vehicle).reshape(-1, 2)
    reach = np.tile(np.concatenate([corners.min(axis=0), corners.max(axis=0)]), (steps + 1, 1))
    switched = adapter.forecast(observation, HORIZON, ego_reach=reach)
    adapter.scenario = dataclasses.replace(
        scenario, behaviour=dataclasses.replace(scenario.behaviour, route_switch_distance=0.0)
    )
    at_the_end = adapter.forecast(observation, HORIZON, ego_reach=reach)
    for name in ("boxes", "state_lower", "state_upper", "guaranteed"):
        assert getattr(switched, name).tobytes() == getattr(at_the_end, name).tobytes(), name


# ------------------------------------------------------------------ no leak between episodes
def _trajectory(adapter, seed, steps=8):
    observation = adapter.reset(seed)
    rows = [observation.vehicles.copy()]
    for _ in range(steps):
        observation, terminated, truncated = adapter.step("IDLE" if "highway" in adapter.env_id else "SLOWER")
        rows.append(observation.vehicles.copy())
        if terminated or truncated:
            break
    return rows


def _same(a, b):
    return len(a) == len(b) and all(x.shape == y.shape and np.array_equal(x, y) for x, y in zip(a, b))


def test_the_same_seed_gives_the_same_episode_after_another_environment():
    from highway_env.vehicle.behavior import LinearVehicle

    highway = HighwayEnvAdapter("highway-fast-v0")
    intersection = HighwayEnvAdapter("intersection-v0")
    before = _trajectory(highway, 5)
    junction_before = _trajectory(intersection, 3)
    # intersection-v0 wrote its constants onto the class: a leak without the restore
    assert LinearVehicle.DISTANCE_WANTED == 7
    assert "LinearVehicle.DISTANCE_WANTED" in highway.constants.changed()
    after = _trajectory(highway, 5)
    assert LinearVehicle.DISTANCE_WANTED == 10.0  # restored: IDMVehicle's 5 + LENGTH
    assert _same(before, after)
    assert _same(junction_before, _trajectory(intersection, 3))


def test_class_constants_snapshot_restores_written_and_added_constants():
    from highway_env.vehicle.behavior import IDMVehicle, LinearVehicle

    restore_vehicle_classes()  # an earlier test may have run intersection-v0
    snapshot = VehicleClassConstants()
    assert snapshot.changed() == []
    LinearVehicle.DISTANCE_WANTED = 7  # what intersection-v0 does
    IDMVehicle.COMFORT_ACC_MAX = 6
    assert snapshot.changed() == ["IDMVehicle.COMFORT_ACC_MAX", "LinearVehicle.DISTANCE_WANTED"]
    snapshot.restore()
    assert snapshot.changed() == []
    assert "DISTANCE_WANTED" not in vars(LinearVehicle) and LinearVehicle.DISTANCE_WANTED == 10.0
    assert IDMVehicle.COMFORT_ACC_MAX == 3.0


def test_the_library_imports_neither_the_adapter_nor_highway_env():
    import subprocess
    import sys

    code = (
        "import sys, minimaxplan.scenarios, minimaxplan.planners, minimaxplan.analysis.cli;"
        "print(sorted(m for m in sys.modules if m.startswith('highway_env') or m.endswith('highway_env_adapter')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("cut", [3, 5])
def test_the_adapters_forecast_at_a_step_reads_the_ego_reach_only_up_to_it(cut):
    """Causality on the adapter's call path (its road from highway-env, road edges, target-speed priors),
    on which the robust method's lane-keeping forecast rests: boxes up to sub-step n do not depend on
    the ego's reach, speed or heading after n."""
    adapter = _adapter("highway-fast-v0", 5)
    observation = adapter.reset(4)
    steps = adapter.steps(HORIZON)
    ego = observation.ego
    states = np.array([[ego[0] + ego[2] * adapter.dt * n, ego[1], ego[2], 0.0] for n in range(steps + 1)])
    corners = vehicle_corners(states, adapter.scenario.vehicle)
    reach = np.concatenate([corners.min(axis=1), corners.max(axis=1)], axis=1)
    speed = np.stack([states[:, 2], states[:, 2]], axis=1)
    heading = np.zeros((steps + 1, 2))
    wide_reach, wide_speed, wide_heading = reach.copy(), speed.copy(), heading.copy()
    wide_reach[cut + 1 :, :2] -= 6.0
    wide_reach[cut + 1 :, 2:] += 6.0
    wide_speed[cut + 1 :] = [0.0, adapter.scenario.vehicle.max_speed]
    wide_heading[cut + 1 :] = [-np.pi, np.pi]
    narrow = adapter.forecast(observation, HORIZON, ego_reach=reach, ego_speed=speed, ego_heading=heading)
    wide = adapter.forecast(observation, HORIZON, ego_reach=wide_reach, ego_speed=wide_speed, ego_heading=wide_heading)
    np.testing.assert_array_equal(narrow.boxes[: cut + 1], wide.boxes[: cut + 1])
    np.testing.assert_array_equal(narrow.state_lower[: cut + 1], wide.state_lower[: cut + 1])
    np.testing.assert_array_equal(narrow.state_upper[: cut + 1], wide.state_upper[: cut + 1])
    assert not np.array_equal(narrow.boxes, wide.boxes)  # the wider reach matters after the cut
