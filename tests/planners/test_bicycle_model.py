"""The planner's ego model: the world's ego bit for bit, the pessimistic reward over sub-steps, planning with it."""

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from minimaxplan.kernels.bicycle import apply_action, ego_control
from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.planners import RobustTreePlanner
from minimaxplan.planners.bicycle_model import (
    HIGHWAY_ACTIONS,
    HIGHWAY_TARGET_SPEEDS,
    LANE_KEEPING_PREFIX,
    TJUNCTION_ACTIONS,
    TJUNCTION_TARGET_SPEEDS,
    BicycleModel,
    BicycleState,
    ego_controller,
)
from minimaxplan.planners.protocols import VectorisedModel
from minimaxplan.scenarios.driving_reward import DrivingReward
from minimaxplan.scenarios.road import lane_geometry
from minimaxplan.scenarios.road_world import HighwayScenario, TJunctionScenario, make_road_world

EMPTY = np.array([np.inf, np.inf, -np.inf, -np.inf])


def _ego_setup(kind):
    if kind == "highway":
        world = make_road_world("highway", 3, scenario=HighwayScenario(vehicle_count=0))
        road = world.road
        controller = ego_controller(lane_geometry(road), HIGHWAY_TARGET_SPEEDS)
        reward = DrivingReward.highway(np.tile(EMPTY, (400, 1, 1)), 0, road)
        model = BicycleModel(controller, reward, HIGHWAY_ACTIONS)
        lane = int(world.traffic.lane[0])
        return world, controller, model, model.initial_state(world.ego_state, level=1, lane=lane)
    world = make_road_world("tjunction", 3, scenario=TJUNCTION_NO_TRAFFIC)
    road = world.road
    route = road.route("south_in", "south_west", "west_out")
    controller = ego_controller(lane_geometry(road, route), TJUNCTION_TARGET_SPEEDS)
    goal = road.position_at(road.index("west_out"), 25.0)
    reward = DrivingReward.tjunction(np.tile(EMPTY, (400, 1, 1)), 0, road, goal, 80.0)
    model = BicycleModel(controller, reward, TJUNCTION_ACTIONS)
    return world, controller, model, model.initial_state(world.ego_state, level=1, lane=route[0])


#: No main-road traffic (the first arrival is after the time limit).
TJUNCTION_NO_TRAFFIC = TJunctionScenario(headway_min=1e6)


@pytest.mark.parametrize(
    "kind, actions",
    [
        ("highway", [0, 0, 3, 1, 2, 2, 4, 1, 0, 3, 1, 1]),
        ("tjunction", [2, 2, 1, 1, 1, 2, 1, 1, 1, 1, 0, 1, 2, 1, 1, 1, 1, 1]),
    ],
)
def test_the_predicted_ego_is_the_worlds_bit_for_bit(kind, actions):
    """The world stepped with the kernel's controls puts the ego exactly where the model predicts it."""
    world, controller, model, state = _ego_setup(kind)
    for a in actions:
        predicted, controls, after = model.predict(state, a)
        (expanded,), _, (terminal,) = model.expand(state, (a,))
        assert np.array_equal(expanded.x, after.x) and (expanded.level, expanded.lane) == (after.level, after.lane)
        assert not terminal
        level, lane = apply_action(controller, state.level, state.lane, model._speed_changes[a], model._lane_changes[a])
        for k in range(model.substeps):
            control, lane = ego_control(controller, world.ego_state, level, lane)
            assert np.array_equal(control, controls[k])
            assert world.apply(control) == "running"
            assert np.array_equal(world.ego_state, predicted[k])
            assert np.array_equal(world.measure().ego, world.ego_state)  # the ego is measured exactly
        assert lane == after.lane
        state = after
    if kind == "tjunction":  # the left turn is done
        assert state.lane == world.road.index("west_out")


@pytest.mark.parametrize("kind", ["highway", "tjunction"])
def test_expand_is_step_and_its_reward_the_minimum_over_the_substeps(kind):
    _, _, model, state = _ego_setup(kind)
    assert isinstance(model, VectorisedModel) and model.actions == tuple(range(len(model.action_names)))
    for _ in range(3):
        next_states, rewards, terminals = model.expand(state, model.actions)
        for a in model.actions:
            one, reward, terminal = model.step(state, a)
            assert np.array_equal(one.x, next_states[a].x) and reward == rewards[a] and terminal == terminals[a]
            predicted, _, _ = model.predict(state, a)
            times = state.time + 1 + np.arange(model.substeps)
            values, collided = model.reward.box_minimum(predicted, predicted, times)
            assert rewards[a] == values.min() and terminals[a] == collided.any()
            assert 0.0 <= rewards[a] <= 1.0 and next_states[a].time == state.time + model.substeps
        state = next_states[1]


def test_beyond_the_obstacle_table_the_transition_is_terminal():
    world, controller, _, _ = _ego_setup("highway")
    reward = DrivingReward.highway(np.tile(EMPTY, (8, 1, 1)), 0, world.road)
    model = BicycleModel(controller, reward, HIGHWAY_ACTIONS)
    state = model.initial_state(world.ego_state, level=1, lane=int(world.traffic.lane[0]))
    _, rewards, terminals = model.expand(state, model.actions)
    assert not terminals.any() and rewards.min() > 0
    _, rewards, terminals = model.expand(BicycleState(state.x, 1, state.lane, 5), model.actions)
    assert terminals.all() and np.all(rewards == 0.0)


def _stopped_vehicle_ahead(lane_y, x_front, horizon=50):
    table = np.tile(EMPTY, (horizon + 1, 2, 1))
    table[:, 0] = [x_front - 2.6, lane_y - 1.1, x_front + 2.6, lane_y + 1.1]
    return table


def test_the_robust_planner_drives_around_a_stopped_vehicle_without_collision():
    world, controller, _, _ = _ego_setup("highway")
    road = world.road
    ego = np.array([200.0, 4.0, 25.0, 0.0])
    reward = DrivingReward.highway(_stopped_vehicle_ahead(4.0, 240.0, 80), 0, road)
    model = BicycleModel(controller, reward, HIGHWAY_ACTIONS)
    state = model.initial_state(ego, level=1, lane=1)
    planner = RobustTreePlanner([model], model.actions, gamma=0.9, budget=100)
    for _ in range(12):
        decision = planner.plan(state)
        assert 0.0 < decision.lower <= decision.upper
        state, reward_value, terminal = model.step(state, decision.action)
        assert not terminal and reward_value > 0
    assert state.x[0] > 240.0 + 5.0 and state.lane != 1  # passed it in another lane


def test_malformed_arguments_are_rejected():
    world, controller, model, state = _ego_setup("highway")
    with pytest.raises(InputError, match="kernel_params"):
        BicycleModel(controller, object(), HIGHWAY_ACTIONS)
    with pytest.raises(InputError, match="actions"):
        BicycleModel(controller, model.reward, [("JUMP", 2, 0)])
    with pytest.raises(InputError, match="controller"):
        BicycleModel(object(), model.reward, HIGHWAY_ACTIONS)
    with pytest.raises(InputError, match="action indices"):
        model.expand(state, (7,))
    with pytest.raises(InputError, match="BicycleState"):
        model.expand((state.x, 1, 1, 0), (0,))
    with pytest.raises(InputError, match="level"):
        model.initial_state(state.x, level=3, lane=0)
    with pytest.raises(InputError, match="lane"):
        model.initial_state(state.x, level=0, lane=9)
    with pytest.raises(InputError, match="target_speeds"):
        ego_controller(lane_geometry(world.road), [25.0, 20.0])


def _held_return(model, state, action, gamma):
    """The discounted return of holding ``action`` until the first terminal transition (`step`, in Python)."""
    total, discount = 0.0, 1.0
    for _ in range(10_000):
        state, reward, terminal = model.step(state, action)
        total += discount * reward
        discount *= gamma
        if terminal:
            return total
    raise AssertionError("no terminal transition")


@pytest.mark.parametrize("kind", ["highway", "tjunction"])
def test_the_fallback_values_are_the_best_held_actions_return(kind):
    world, controller, model, state = _ego_setup(kind)
    if kind == "highway":
        x = state.x
        table = _stopped_vehicle_ahead(float(x[1]), float(x[0]) + 45.0)[:31]
        table[:, 1] = [x[0] + 10.0, x[1] + 2.0, x[0] + 16.0, x[1] + 6.0]  # a box in the lane to the left
        model = model.with_reward(DrivingReward.highway(table, 0, world.road))
    else:
        model = model.with_reward(model.reward.with_obstacles(np.tile(EMPTY, (37, 1, 1)), 0))
    children, _, _ = model.expand(state, model.actions)
    values = model.fallback_values([state, *children], 0.9)
    for value, start in zip(values, [state, *children]):
        expected = max(_held_return(model, start, a, 0.9) for a in model.actions)
        assert value == pytest.approx(expected, rel=1e-12, abs=1e-12)
        assert 0.0 <= value <= 10.0
    with pytest.raises(InputError, match="states\\[0\\]"):
        model.fallback_values([(state.x, 1, 1, 0)], 0.9)
    with pytest.raises(InputError, match="gamma"):
        model.fallback_values([state], 1.0)
    with pytest.raises(DimensionError, match="states\\[1\\].x must have shape \\(4,\\), got shape \\(3,\\)"):
        model.fallback_values([state, state._replace(x=state.x[:3])], 0.9)


def _robust_value(models, state, depth, gamma):
    """``max_plan min_m sum_n gamma^n r_n^m`` over every action sequence of ``depth`` decisions (brute force)."""

    def value(states, alive, d):
        if d == depth or not alive.any():
            return np.zeros(len(models))
        best = None
        for a in models[0].actions:
            steps = [m.step(s, a) if live else (s, 0.0, True) for m, s, live in zip(models, states, alive)]
            rewards = np.array([r for _, r, _ in steps])
            later = value([n for n, _, _ in steps], alive & ~np.array([t for _, _, t in steps]), d + 1)
            returns = rewards + gamma * later
            if best is None or returns.min() > best.min():
                best = returns
        return best

    return float(value([state] * len(models), np.ones(len(models), dtype=bool), 0).min())


def test_fallback_bounds_keep_theorem_3s_bracket_and_only_raise_the_lower_bound():
    """Three scene hypotheses (a blocked lane, a taken side lane) over a 4-decision table: brute force is exact."""
    world, controller, model, state = _ego_setup("highway")
    x = state.x
    free = np.tile(EMPTY, (21, 2, 1))
    blocked = _stopped_vehicle_ahead(float(x[1]), float(x[0]) + 40.0)[:21]
    side = blocked.copy()
    side[:, 1] = [x[0] - 30.0, x[1] + 2.5, x[0] + 60.0, x[1] + 6.0]
    models = [model.with_reward(DrivingReward.highway(table, 0, world.road)) for table in (free, blocked, side)]
    exact = _robust_value(models, state, 5, 0.9)  # the table ends within the 5th decision: reward 0 after
    for budget in (1, 3, 10, 40, 200):
        with_fallback = RobustTreePlanner(models, models[0].actions, gamma=0.9, budget=budget).plan(state)
        paper = RobustTreePlanner([_NoFallback(m) for m in models], models[0].actions, gamma=0.9, budget=budget)
        without = paper.plan(state)
        assert with_fallback.lower <= exact + 1e-12 <= with_fallback.upper + 2e-12
        assert with_fallback.lower >= without.lower and with_fallback.upper == without.upper
    assert with_fallback.lower == pytest.approx(exact, abs=1e-12)  # the budget closes the tree


class _NoFallback:
    """A model without `fallback_values`: the paper's lower bound (a reference for the test above)."""

    def __init__(self, model):
        self._model = model

    def expand(self, state, actions):
        return self._model.expand(state, actions)

    def step(self, state, action):
        return self._model.step(state, action)


#: Obstacles moving along the highway's lanes: (metres ahead of the ego, lane, speed m/s, length m).
MOVING_BOXES = st.lists(
    st.tuples(st.floats(5.0, 60.0), st.integers(0, 2), st.floats(-8.0, 8.0), st.floats(1.0, 10.0)),
    min_size=1,
    max_size=3,
)
#: Which of them a lane-keeping table keeps (None: no lane-keeping table).
KEPT_MASKS = st.one_of(st.none(), st.lists(st.booleans(), min_size=3, max_size=3))


def _moving_box_table(x, boxes, rows):
    """The obstacle table, shape (rows, len(boxes), 4), of `MOVING_BOXES` ahead of an ego at ``x`` (dt = 0.1 s)."""
    n = np.arange(rows) * 0.1
    return np.stack(
        [
            np.stack(
                [
                    x[0] + a + s * n - length / 2,
                    np.full(rows, 4.0 * lane - 1.0),
                    x[0] + a + s * n + length / 2,
                    np.full(rows, 4.0 * lane + 1.0),
                ],
                axis=1,
            )
            for a, lane, s, length in boxes
        ],
        axis=1,
    )


def _with_tables(model, road, table, kept):
    """``model`` on ``table``, and with ``kept`` a lane-keeping table of the obstacles it marks."""
    keeping = None
    if kept is not None:
        keep_table = table.copy()
        keep_table[:, ~np.array(kept[: table.shape[1]])] = EMPTY
        keeping = DrivingReward.highway(keep_table, 0, road)
    return model.with_reward(DrivingReward.highway(table, 0, road), lane_keeping_reward=keeping)


@settings(max_examples=12, deadline=None)
@given(
    boxes=MOVING_BOXES,
    rows=st.integers(6, 21),
    budget=st.integers(1, 60),
    gamma=st.floats(0.5, 0.95),
    kept=KEPT_MASKS,
)
def test_property_fallback_bounds_stay_below_the_robust_value(boxes, rows, budget, gamma, kept):
    """Random obstacles (moving, any lane), table lengths, budgets and discounts: L <= V* <= U, and L only rises.

    With ``kept``, the paths that keep their lane see only the obstacles it marks (a
    lane-keeping table): the brute force steps the same path-dependent rewards."""
    world, controller, model, state = _ego_setup("highway")
    models = [_with_tables(model, world.road, _moving_box_table(state.x, boxes, rows), kept)]
    exact = _robust_value(models, state, (rows - 2) // 5 + 1, gamma)  # the table ends within the last decision
    decision = RobustTreePlanner(models, models[0].actions, gamma=gamma, budget=budget).plan(state)
    paper = RobustTreePlanner([_NoFallback(models[0])], models[0].actions, gamma=gamma, budget=budget).plan(state)
    assert decision.lower <= exact + 1e-9 <= decision.upper + 2e-9
    assert decision.lower >= paper.lower and decision.upper == paper.upper


def _lane_keeping_case():
    """A highway ego with a general table (a box ahead in its lane and one to its left) and a lane-keeping one."""
    world, controller, model, state = _ego_setup("highway")
    x = state.x
    general = _stopped_vehicle_ahead(float(x[1]), float(x[0]) + 16.0)[:31]
    general[:, 1] = [x[0] + 5.0, x[1] + 2.0, x[0] + 12.0, x[1] + 6.0]
    keeping = general.copy()
    keeping[:, 0] = EMPTY  # e.g. the vehicle ahead cannot be there while the ego holds its lane
    general_reward = DrivingReward.highway(general, 0, world.road)
    keep_reward = DrivingReward.highway(keeping, 0, world.road)
    both = model.with_reward(general_reward, lane_keeping_reward=keep_reward)
    return world, state, both, model.with_reward(general_reward), model.with_reward(keep_reward)


def test_paths_that_keep_their_lane_read_the_lane_keeping_table():
    world, root, both, general, keeping = _lane_keeping_case()
    names = both.action_names
    children, rewards, terminals = both.expand(root, both.actions)
    g_children, g_rewards, g_terminals = general.expand(root, general.actions)
    k_children, k_rewards, k_terminals = keeping.expand(root, keeping.actions)
    for a, name in enumerate(names):
        changes = name.startswith("LANE")
        assert children[a].kept is (not changes)
        expected = (g_rewards, g_terminals) if changes else (k_rewards, k_terminals)
        assert rewards[a] == expected[0][a] and terminals[a] == expected[1][a]
        np.testing.assert_array_equal(children[a].x, g_children[a].x)
    assert any(rewards[a] != g_rewards[a] for a in range(len(names)) if not names[a].startswith("LANE"))
    # after a lane change, every path reads the general table
    left = children[names.index("LANE_LEFT")]
    grand, rewards, _ = both.expand(left, both.actions)
    _, g_rewards, _ = general.expand(left, general.actions)
    np.testing.assert_array_equal(rewards, g_rewards)
    assert not any(child.kept for child in grand)
    # predict agrees with expand on the flag
    for a in both.actions:
        assert both.predict(root, a)[2].kept is children[a].kept


def test_a_lane_change_that_has_no_effect_keeps_the_lane():
    world, controller, model, state = _ego_setup("highway")
    lanes = controller.lanes
    edge = next(lane for lane in range(lanes.kinds.shape[0]) if lanes.left_lane[lane] < 0)
    root = model.initial_state(state.x, level=1, lane=edge)
    left = model.action_names.index("LANE_LEFT")
    child = model.expand(root, (left,))[0][0]
    assert apply_action(controller, 1, edge, 0, 1)[1] == edge and child.kept
    right = model.action_names.index("LANE_RIGHT")
    assert not model.expand(root, (right,))[0][0].kept
    # the continuation bounds agree with `step` there: the best held action's return
    world, _, both, _, _ = _lane_keeping_case()
    edge_root = both.initial_state(state.x, level=1, lane=edge)
    for start in (edge_root, both.expand(edge_root, (left,))[0][0]):
        expected = max(_held_return(both, start, a, 0.9) for a in both.actions)
        assert both.fallback_values([start], 0.9)[0] == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_the_fallback_values_hold_speed_actions_on_the_lane_keeping_table():
    world, root, both, general, keeping = _lane_keeping_case()
    children, _, _ = both.expand(root, both.actions)
    values = both.fallback_values([root, *children], 0.9)
    for value, start in zip(values, [root, *children]):
        expected = max(_held_return(both, start, a, 0.9) for a in both.actions)
        assert value == pytest.approx(expected, rel=1e-12, abs=1e-12)
    # a kept state: the speed actions held on the lane-keeping table, lane changes on the general one
    speeds = [a for a, name in enumerate(both.action_names) if not name.startswith("LANE")]
    changes = [a for a, name in enumerate(both.action_names) if name.startswith("LANE")]
    expected = max(
        max(_held_return(keeping, root, a, 0.9) for a in speeds),
        max(_held_return(general, root, a, 0.9) for a in changes),
    )
    assert values[0] == pytest.approx(expected, rel=1e-12, abs=1e-12)
    assert values[0] > general.fallback_values([root], 0.9)[0]
    # after the prefix, a path holding IDLE stays in the family only by holding it
    idle = both.action_names.index("IDLE")
    held = root._replace(keep_depth=LANE_KEEPING_PREFIX + 1, keep_hold=1)
    others = [a for a in both.actions if a != idle]
    expected = max(_held_return(keeping, held, idle, 0.9), max(_held_return(general, held, a, 0.9) for a in others))
    assert both.fallback_values([held], 0.9)[0] == pytest.approx(expected, rel=1e-12, abs=1e-12)
    children, _, _ = both.expand(held, both.actions)
    assert [child.kept for child in children] == [a == idle for a in both.actions]
    assert both.expand(held, (idle,))[0][0].keep_hold == 1


def test_a_lane_keeping_reward_of_another_kind_is_rejected():
    world, state, both, general, keeping = _lane_keeping_case()
    with pytest.raises(InputError, match="lane_keeping_reward must expose kernel_params"):
        general.with_reward(general.reward, lane_keeping_reward="a table")
    with pytest.raises(InputError, match="states\\[0\\].keep_hold must be -1, 0, 1 or 2, got 7"):
        both.fallback_values([state._replace(keep_depth=5, keep_hold=7)], 0.9)


def _first_terminal_decision(model, state, plan, decisions):
    """The 1-based index of the first terminal transition of ``plan`` (last action held), by `expand`; None if none."""
    for d in range(decisions):
        (state,), _, (terminal,) = model.expand(state, (plan[min(d, len(plan) - 1)],))
        if terminal:
            return d + 1
    return None


@settings(max_examples=20, deadline=None)
@given(
    boxes=MOVING_BOXES,
    plan=st.lists(st.integers(0, len(HIGHWAY_ACTIONS) - 1), min_size=1, max_size=4),
    decisions=st.integers(1, 8),
    kept=KEPT_MASKS,
)
def test_property_first_possible_collision_is_the_first_colliding_substep(boxes, plan, decisions, kept):
    """Random moving boxes, plans and horizons, with or without a lane-keeping table.

    It falls in the first terminal transition of the compiled `expand` (an independent
    code path), and it is exactly the first colliding sub-step: with the table's rows
    from it on emptied the plan stays clear, with only its row kept it collides there.
    """
    world, controller, model, state = _ego_setup("highway")
    substeps = model.substeps
    rows = decisions * substeps + 1
    table = _moving_box_table(state.x, boxes, rows)

    def with_table(t):
        return _with_tables(model, world.road, t, kept)

    horizon = decisions * substeps
    found = with_table(table).first_possible_collision(state, plan, horizon)
    terminal = _first_terminal_decision(with_table(table), state, plan, decisions)
    assert 1 <= found <= horizon + 1
    event("clear" if found == horizon + 1 else "collides")
    if found == horizon + 1:
        assert terminal is None
        return
    assert terminal == (found - 1) // substeps + 1
    later = table.copy()
    later[found + 1 :] = EMPTY
    assert with_table(later).first_possible_collision(state, plan, horizon) == found
    earlier = table.copy()
    earlier[found:] = EMPTY
    assert with_table(earlier).first_possible_collision(state, plan, horizon) == horizon + 1
    only = np.tile(EMPTY, (rows, len(boxes), 1))
    only[found] = table[found]
    assert with_table(only).first_possible_collision(state, plan, horizon) == found


def test_first_possible_collision_rejects_an_empty_plan_and_a_bad_horizon():
    world, controller, model, state = _ego_setup("tjunction")
    assert model.first_possible_collision(state, (0,), 20) == 21  # no traffic: clear
    with pytest.raises(InputError, match="plan"):
        model.first_possible_collision(state, (), 10)
    with pytest.raises(InputError, match="horizon"):
        model.first_possible_collision(state, (0,), 0)
    with pytest.raises(InputError, match="action indices"):
        model.first_possible_collision(state, (5,), 10)


def _random_table(rng, x, rows):
    """Obstacle boxes of 3 vehicles near the ego at random speeds; the first one slower, ahead in its lane."""
    table = np.tile(EMPTY, (rows, 3, 1))
    for j in range(3):
        lane_y = x[1] if j == 0 else 4.0 * rng.integers(0, 3)
        start = x[0] + (rng.uniform(15.0, 60.0) if j == 0 else rng.uniform(-20.0, 80.0))
        speed = rng.uniform(0.0, 15.0) if j == 0 else rng.uniform(10.0, 30.0)
        grow = rng.uniform(0.0, 0.5)
        for n in range(rows):
            centre = start + speed * 0.1 * n
            half = 2.5 + grow * 0.1 * n
            table[n, j] = [centre - half, lane_y - 1.0, centre + half, lane_y + 1.0]
    return table


def _continuation_rewards(model, states):
    """The per-decision rewards of every held action's continuation from each state, as ``model`` kept them."""
    out = []
    for state in states:
        _, record, recorded, _, row = model._continuations[id(state)]
        out.append([record[row, a, : recorded[row, a]].tobytes() for a in model.actions])
    return out


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    lane_keeping=st.booleans(),
    gamma=st.floats(0.5, 0.99),
    # mostly lane-keeping actions, so that paths often pass the lane-keeping prefix and then switch actions
    path=st.lists(st.sampled_from([0, 1, 1, 2, 3, 3, 4, 4]), min_size=1, max_size=8),
)
def test_inherited_continuations_give_the_fallback_values_bit_for_bit(seed, lane_keeping, gamma, path):
    """Along a path expanded as the planner does, each call equals a fresh model's, which rolls everything out.

    A model remembers each state's continuations and hands the child reached by action a
    its parent's continuation of a after the first decision (`_fallback_kernel`); a fresh
    model (`with_reward`: no memo) asked for the same states rolls every action out. The
    reuse assumes that both continuations read the same table (lane-keeping or not): the
    random paths change lanes, hold actions past the prefix and try lane changes that
    have no effect at the road's edge (the kernel also checks the tables per action).
    """
    rng = np.random.default_rng(seed)
    world, controller, model, state = _ego_setup("highway")
    x = np.array([200.0, 4.0 * rng.integers(0, 3), rng.uniform(18.0, 30.0), rng.uniform(-0.05, 0.05)])
    rows = int(rng.integers(25, 60))
    table = _random_table(rng, x, rows)
    general = DrivingReward.highway(table, 0, world.road)
    keeping = None
    if lane_keeping:  # as the forecast for a lane-keeping ego: a subset of the boxes (here: some vehicles gone)
        kept_table = table.copy()
        kept_table[:, rng.random(table.shape[1]) < 0.5] = EMPTY
        keeping = DrivingReward.highway(kept_table, 0, world.road)
    searching = model.with_reward(general, lane_keeping_reward=keeping)
    node = searching.initial_state(x, level=int(rng.integers(0, 3)), lane=int(round(x[1] / 4.0)))
    inherited = 0
    for action in path:
        children, _, _ = searching.expand(node, searching.actions)
        inherited += int(np.sum(searching._arrivals(children)[0] >= 0))
        values = searching.fallback_values(children, gamma)
        fresh = searching.with_reward(general, lane_keeping_reward=keeping)
        expected = fresh.fallback_values(children, gamma)
        assert values.tobytes() == expected.tobytes()
        # each action's continuation too, not only the best one (a wrong table may hide under the max)
        assert _continuation_rewards(searching, children) == _continuation_rewards(fresh, children)
        # and what the values mean: the best return of holding one action, stepped in Python
        child = children[action]
        held = max(_held_return(fresh, child, a, gamma) for a in fresh.actions)
        assert values[action] == pytest.approx(held, rel=1e-12, abs=1e-12)
        node = child
    event(f"children that inherited a continuation: {'some' if inherited else 'none'}")


def test_children_inherit_their_parents_continuation_and_the_memo_stays_bounded():
    """The search's order (expand, then the children's values) reuses continuations; past the limit the memo forgets."""
    from minimaxplan.planners.bicycle_model import MEMO_STATES

    world, root, both, general, keeping = _lane_keeping_case()
    wide = both.with_reward(
        DrivingReward.highway(np.tile(EMPTY, (51, 1, 1)), 0, world.road),
        lane_keeping_reward=DrivingReward.highway(np.tile(EMPTY, (51, 1, 1)), 0, world.road),
    )
    for model in (both, wide):
        children, _, _ = model.expand(root, model.actions)
        assert np.all(model._arrivals(children)[0] == -1)  # the root's continuations were never asked for
        model.fallback_values(children, 0.9)
        grand, _, _ = model.expand(children[1], model.actions)
        arrived_by = model._arrivals(grand)[0]
        assert arrived_by.tolist() == list(model.actions)
        # a list that is not the last expansion's children inherits nothing
        assert np.all(model._arrivals([*grand[1:], grand[0]])[0] == -1)
    planner = RobustTreePlanner([wide], wide.actions, gamma=0.9, budget=100)
    for _ in range(12):
        planner.plan(root)
        assert len(wide._continuations) <= MEMO_STATES
