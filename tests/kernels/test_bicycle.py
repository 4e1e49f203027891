"""The compiled bicycle and ego controllers: the world's formulas, admissible controls, lane changes and routes."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.kernels import bicycle as bk
from minimaxplan.planners.bicycle_model import HIGHWAY_TARGET_SPEEDS, TJUNCTION_TARGET_SPEEDS, ego_controller
from minimaxplan.scenarios.road import highway_road, lane_geometry, tjunction_road, wrap_to_pi
from minimaxplan.scenarios.vehicles import bicycle_step, vehicle_corners

HIGHWAY = highway_road()
TJUNCTION = tjunction_road()
LEFT_TURN = TJUNCTION.route("south_in", "south_west", "west_out")


def _numpy_bicycle(x, a, d, dt, length=5.0, max_speed=40.0):
    """The numpy formulas `bicycle_step` had before it called the kernel."""
    v, psi = x[:, 2], x[:, 3]
    beta = np.arctan(0.5 * np.tan(d))
    out = np.empty_like(x)
    out[:, 0] = x[:, 0] + v * np.cos(psi + beta) * dt
    out[:, 1] = x[:, 1] + v * np.sin(psi + beta) * dt
    out[:, 3] = psi + v * np.sin(beta) / (length / 2) * dt
    out[:, 2] = np.clip(v + a * dt, 0.0, max_speed)
    return out


def test_bicycle_step_is_the_kernel_and_matches_the_numpy_formulas_to_rounding():
    rng = np.random.default_rng(0)
    x = rng.uniform(-50, 50, (2000, 4))
    x[:, 2] = rng.uniform(0, 40, 2000)
    a, d = rng.uniform(-8, 8, 2000), rng.uniform(-1.0, 1.0, 2000)
    out = bicycle_step(x, a, d, 0.1)
    expected = _numpy_bicycle(x, a, d, 0.1)
    assert np.allclose(out, expected, rtol=1e-14, atol=1e-12)
    assert np.array_equal(out[:, 2], expected[:, 2])  # the speed involves no transcendental function: exact
    kernel = np.empty_like(x)
    bk.bicycle_step_into(x, a, d, 0.1, 5.0, 40.0, kernel)
    assert np.array_equal(out, kernel)
    assert out[:, 2].min() >= 0.0 and out[:, 2].max() <= 40.0


@settings(max_examples=60, deadline=None)
@given(
    st.sampled_from(["south_in", "south_west", "west_out", "east_south", "south_east", "west_east"]),
    st.floats(-30, 120),
    st.floats(-3, 3),
)
def test_lane_frenet_and_heading_are_the_roads(name, s, offset):
    lanes = lane_geometry(TJUNCTION)
    lane = TJUNCTION.index(name)
    x, y = TJUNCTION.position_at(lane, s, offset)
    s_k, off_k = bk.lane_frenet(lanes, lane, x, y)
    s_r, off_r = TJUNCTION.frenet(lane, x, y)
    assert np.isclose(s_k, s_r, rtol=0, atol=1e-9) and np.isclose(off_k, off_r, rtol=0, atol=1e-9)
    assert np.isclose(bk.lane_heading(lanes, lane, s), TJUNCTION.heading_at(lane, s), rtol=0, atol=1e-12)


@given(st.floats(-1e3, 1e3))
def test_wrap_is_numpys(angle):
    assert bk._wrap_to_pi(angle) == wrap_to_pi(angle)


@settings(max_examples=200, deadline=None)
@given(
    st.floats(-50, 2050),
    st.floats(-4, 12),
    st.floats(0, 40),
    st.floats(-3.5, 3.5),
    st.integers(0, 2),
    st.integers(0, 2),
)
def test_controls_are_admissible_for_the_road_world(x, y, v, psi, level, lane):
    controller = ego_controller(lane_geometry(HIGHWAY), HIGHWAY_TARGET_SPEEDS)
    control, lane_after = bk.ego_control(controller, [x, y, v, psi], level, lane)
    assert abs(control[0]) <= 6.0 and abs(control[1]) <= np.pi / 3
    assert lane_after == lane  # no successors on the highway
    expected = np.clip((1 / 0.6) * (HIGHWAY_TARGET_SPEEDS[level] - v), -6.0, 6.0)
    assert control[0] == expected


def test_actions_move_the_level_and_the_lane_within_bounds():
    controller = ego_controller(lane_geometry(HIGHWAY), HIGHWAY_TARGET_SPEEDS)
    assert bk.apply_action(controller, 2, 1, 1, 0) == (2, 1)  # FASTER at the top level
    assert bk.apply_action(controller, 0, 1, -1, 0) == (0, 1)
    assert bk.apply_action(controller, 1, 1, 0, 1) == (1, 2)  # LANE_LEFT: lane 2 is left of lane 1 (+y)
    assert bk.apply_action(controller, 1, 2, 0, 1) == (1, 2)  # no lane left of the leftmost
    assert bk.apply_action(controller, 1, 0, 0, -1) == (1, 0)
    assert bk.apply_action(controller, 1, 1, 0, -1) == (1, 0)


def _rollout(controller, state, level, lane, steps):
    states, controls = np.empty((steps, 4)), np.empty((steps, 2))
    lane = bk.ego_rollout(controller, np.asarray(state, dtype=float), level, lane, steps, states, controls)
    return states, controls, lane


def test_a_lane_change_settles_in_the_target_lane_and_the_speed_reaches_its_target():
    controller = ego_controller(lane_geometry(HIGHWAY), HIGHWAY_TARGET_SPEEDS)
    states, controls, _ = _rollout(controller, [200.0, 0.0, 25.0, 0.0], 2, 1, 60)  # 6 s
    assert abs(states[-1, 1] - 4.0) < 0.05 and abs(states[-1, 3]) < 0.01 and abs(states[-1, 2] - 30.0) < 0.1
    assert np.all(np.abs(controls[:, 0]) <= 6.0) and np.all(np.abs(controls[:, 1]) <= np.pi / 3)
    assert HIGHWAY.on_road(vehicle_corners(states)).all()
    assert states[:, 1].max() < 4.0 + 0.5  # small overshoot


def test_the_left_turn_route_is_followed_on_the_road():
    controller = ego_controller(lane_geometry(TJUNCTION, LEFT_TURN), TJUNCTION_TARGET_SPEEDS)
    lane = LEFT_TURN[0]
    x, y = TJUNCTION.position_at(lane, 60.0)
    start = [x, y, 4.5, float(TJUNCTION.heading_at(lane, 60.0))]
    states, controls, lane_after = _rollout(controller, start, 2, lane, 120)  # 12 s at up to 9 m/s
    assert lane_after == LEFT_TURN[2]
    assert TJUNCTION.on_road(vehicle_corners(states)).all()  # before the end of west_out
    s, offset = TJUNCTION.frenet(LEFT_TURN[2], states[-1, 0], states[-1, 1])
    assert s > 25.0 and abs(offset) < 0.1 and abs(wrap_to_pi(states[-1, 3] - np.pi)) < 0.01
    assert np.all(np.abs(controls[:, 0]) <= 6.0) and np.all(np.abs(controls[:, 1]) <= np.pi / 3)


def test_the_stop_level_brakes_to_a_standstill_without_leaving_the_lane():
    controller = ego_controller(lane_geometry(TJUNCTION, LEFT_TURN), TJUNCTION_TARGET_SPEEDS)
    lane = LEFT_TURN[0]
    x, y = TJUNCTION.position_at(lane, 60.0)
    states, _, _ = _rollout(controller, [x, y, 9.0, np.pi / 2], 0, lane, 100)
    assert states[-1, 2] < 1e-3 and TJUNCTION.on_road(vehicle_corners(states)).all()
    assert abs(TJUNCTION.frenet(lane, states[-1, 0], states[-1, 1])[1]) < 0.05
