"""IntervalModel, PointModel, controllers and the comparison factories."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import Box
from minimaxplan.models.errors import DimensionError, EmptySetError, InputError
from minimaxplan.models.prediction import IntervalPredictor
from minimaxplan.planners import OptimisticPlanner, RobustTreePlanner
from minimaxplan.planners.comparison import (
    interval_robust_planner,
    multi_model_robust_planner,
    nominal_planner,
    oracle_planner,
    root_state,
)
from minimaxplan.planners.controllers import ControllerBank, LinearFeedback, OpenLoop
from minimaxplan.planners.interval_model import BoxState, IntervalModel
from minimaxplan.planners.point_model import PointModel, PointState
from minimaxplan.scenarios.geometry import CircularObstacles
from minimaxplan.scenarios.rewards import GoalReward

from . import _systems as systems
from ._systems import ROBOT_ACTIONS, robot_system

seeds = st.integers(0, 2**31 - 1)


class UnboundedReward:
    """A reward without obstacles that reads the first two coordinates (box minimum of a goal reward)."""

    def __init__(self):
        self.inner = GoalReward([1.0, -1.0])

    def box_minimum(self, lower, upper, t):
        return self.inner.box_minimum(lower, upper, t)


# ------------------------------------------------------------------ inclusion
@given(seeds, st.integers(1, 4))
def test_boxes_contain_every_true_trajectory(seed, substeps):
    """Every true sub-step state lies in its box: random plants (non-Metzler), random dt,
    parameters at every vertex and inside, disturbances at their extremes, feedback with
    active saturation."""
    rng = np.random.default_rng(seed)
    system = systems.random_system(rng)
    controllers = systems.random_controllers(rng, system)
    model = IntervalModel(system, system.theta, UnboundedReward(), controllers, substeps=substeps)
    lo0 = rng.uniform(-1, 1, system.nstates)
    hi0 = lo0 + rng.uniform(0, 0.5, system.nstates)
    sequence = list(rng.integers(0, len(controllers), size=4))
    lower, upper, _, _ = model.rollout(model.initial_state(lo0, hi0), sequence)
    thetas = systems.parameter_samples(rng, system.theta)
    x0 = systems.initial_samples(rng, lo0, hi0, len(thetas))
    for _ in range(3):
        states = systems.simulate(rng, system, thetas, x0, [controllers[a] for a in sequence], substeps)
        assert systems.inside(states, lower, upper)


def test_saturation_is_active_and_still_contained():
    """A feedback law that saturates inside the box: the closed-loop formula alone would be wrong."""
    system = robot_system()
    feedback = LinearFeedback(np.array([[2.0, 0, 1.5, 0], [0, 2.0, 0, 1.5]]), [1.0, 1.0, 0, 0], u_low=-0.5, u_high=0.5)
    model = IntervalModel(system, system.theta, UnboundedReward(), [feedback], substeps=1)
    lo0, hi0 = np.array([0.9, 0.9, -0.1, -0.1]), np.array([4.0, 4.0, 0.1, 0.1])
    # saturation is active for part of the box (far from x_ref), not all of it (at x_ref)
    corners = systems.initial_samples(np.random.default_rng(0), lo0, hi0, 16)
    raw = (feedback.x_ref - corners) @ feedback.K.T + feedback.u_ff
    assert np.any(np.abs(raw) > 0.5)
    assert np.all(np.abs(feedback.control(np.array([1.0, 1.0, 0.1, -0.1]))) < 0.5)
    lower, upper, _, _ = model.rollout(model.initial_state(lo0, hi0), [0] * 30)
    rng = np.random.default_rng(1)
    thetas = systems.parameter_samples(rng, system.theta, n_random=60)
    x0 = systems.initial_samples(rng, lo0, hi0, len(thetas))
    states = systems.simulate(rng, system, thetas, x0, [feedback] * 30, 1)
    assert systems.inside(states, lower, upper)
    # from a point far from x_ref the unsaturated closed-loop predictor excludes the true
    # (saturated) trajectories, and the model does not
    start = np.array([4.0, 4.0, 0.0, 0.0])
    lower, upper, _, _ = model.rollout(model.initial_state(start, start), [0] * 30)
    states = systems.simulate(rng, system, thetas, np.tile(start, (len(thetas), 1)), [feedback] * 30, 1)
    assert systems.inside(states, lower, upper)
    closed = IntervalPredictor(feedback.closed_loop(system), system.theta)
    zl, zh = start, start
    escaped = False
    for n in range(1, 31):
        zl, zh = closed.step(zl, zh, feedback.feedforward)
        escaped |= not systems.inside(states[:, n], zl, zh)
    assert escaped


def test_stacked_step_equals_the_interval_predictor_per_controller():
    rng = np.random.default_rng(7)
    for _ in range(20):
        system = systems.random_system(rng)
        controllers = systems.random_controllers(rng, system, n=4, saturate=False)
        model = IntervalModel(system, system.theta, UnboundedReward(), controllers)
        lo0 = rng.uniform(-1, 1, system.nstates)
        hi0 = lo0 + rng.uniform(0, 1, system.nstates)
        next_states, _, _ = model.expand(model.initial_state(lo0, hi0), model.actions)
        for controller, state in zip(controllers, next_states):
            if isinstance(controller, OpenLoop):
                predictor, u = IntervalPredictor(system, system.theta), controller.u
            else:
                predictor, u = IntervalPredictor(controller.closed_loop(system), system.theta), controller.feedforward
            lo, hi = predictor.step(lo0, hi0, u)
            np.testing.assert_allclose(state.lower, lo, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(state.upper, hi, rtol=1e-12, atol=1e-12)


@settings(max_examples=20)
@given(seeds, st.integers(1, 3))
def test_expand_equals_repeated_step_and_rollout(seed, substeps):
    rng = np.random.default_rng(seed)
    system = systems.random_system(rng, p=4, q=2)
    controllers = systems.random_controllers(rng, system, n=3)
    obstacles = CircularObstacles(rng.uniform(-3, 3, (4, 2)), rng.uniform(0.1, 0.5, 4))
    reward = GoalReward(rng.uniform(-3, 3, 2), obstacles=obstacles, robot_radius=0.2)
    model = IntervalModel(system, system.theta, reward, controllers, substeps=substeps)
    state = model.initial_state(rng.uniform(-1, 0, 4), rng.uniform(0, 1, 4), time=3)
    next_states, rewards, terminals = model.expand(state, model.actions)
    # BLAS may round a batched product differently from a single one: equal to rounding
    same = dict(rtol=1e-13, atol=1e-13)
    for a in model.actions:
        one, reward_a, terminal_a = model.step(state, a)
        np.testing.assert_allclose(one.lower, next_states[a].lower, **same)
        np.testing.assert_allclose(one.upper, next_states[a].upper, **same)
        assert one.time == next_states[a].time == 3 + substeps
        assert reward_a == pytest.approx(rewards[a], abs=1e-13) and terminal_a == terminals[a]
    # a subset of actions, in another order
    sub_states, sub_rewards, _ = model.expand(state, [2, 0])
    np.testing.assert_allclose(sub_states[0].upper, next_states[2].upper, **same)
    assert sub_rewards[1] == pytest.approx(rewards[0], abs=1e-13)
    # rollout over a sequence == chained steps; its per-decision rewards are minima over sub-steps
    sequence = [1, 2, 0]
    lower, upper, roll_rewards, roll_terminals = model.rollout(state, sequence)
    current = state
    for n, a in enumerate(sequence):
        current, r, term = model.step(current, a)
        np.testing.assert_allclose(current.lower, lower[(n + 1) * substeps], **same)
        assert r == pytest.approx(roll_rewards[n], abs=1e-13) and term == roll_terminals[n]
        sub_minima = [
            reward.box_minimum(lower[n * substeps + s], upper[n * substeps + s], 3 + n * substeps + s)[0]
            for s in range(1, substeps + 1)
        ]
        assert r == pytest.approx(min(sub_minima), abs=0)


def test_pessimistic_reward_is_the_worst_sub_step_and_collision_is_terminal():
    system = robot_system()
    reward = GoalReward([5.0, 0.0], obstacles=CircularObstacles([[1.2, 0.0]], [0.2]), robot_radius=0.3)
    model = IntervalModel(system, system.theta, reward, ROBOT_ACTIONS, substeps=5)
    state = model.initial_state([0.0, -0.05, 1.0, 0.0], [0.05, 0.05, 1.2, 0.1])
    next_states, rewards, terminals = model.expand(state, model.actions)
    # right-hand actions drive into the obstacle within the 5 sub-steps
    assert terminals[3] and rewards[3] == 0.0
    assert not terminals[0] and 0.0 < rewards[0] < 1.0
    lower, upper, per_decision, _ = model.rollout(state, [0])
    minima = [reward.box_minimum(lower[s], upper[s], s)[0] for s in range(1, 6)]
    assert per_decision[0] == min(minima)


# --------------------------------------------------------------- point model
@pytest.mark.parametrize("with_feedback", [True, False])
def test_point_model_matches_system_step(with_feedback):
    system = robot_system()
    theta = np.array([0.3, 0.6])
    feedback = LinearFeedback(np.array([[1.0, 0, 1, 0], [0, 1.0, 0, 1]]), [2.0, 1.0, 0, 0], u_low=-1.0, u_high=1.0)
    controllers = ROBOT_ACTIONS + [feedback] if with_feedback else ROBOT_ACTIONS
    reward = GoalReward([3.0, 3.0], obstacles=CircularObstacles([[1.0, 1.0]], [0.3]), robot_radius=0.3)
    model = PointModel(system, theta, reward, controllers, substeps=3)
    x0 = np.array([0.0, 0.0, 0.2, -0.1])
    state = model.initial_state(x0, time=2)
    assert isinstance(state, PointState) and state.time == 2
    next_states, rewards, terminals = model.expand(state, model.actions)
    for a, controller in enumerate(controllers):
        x = x0
        values = []
        for s in range(1, 4):
            x = system.step(x, controller.control(x), theta)
            values.append(reward.value(x, 2 + s))
        np.testing.assert_allclose(next_states[a].x, x, rtol=1e-13, atol=1e-13)
        assert rewards[a] == pytest.approx(min(values), abs=1e-12)
        one = model.step(state, a)
        np.testing.assert_array_equal(one[0].x, next_states[a].x)
        assert one[1] == rewards[a] and one[2] == terminals[a]
        assert next_states[a].time == 5


# ------------------------------------------------------------------ factories
def test_comparison_factories_plan():
    system = robot_system()
    reward = GoalReward([3.0, 3.0], obstacles=CircularObstacles([[1.5, 1.5]], [0.4]), robot_radius=0.3)
    robust = interval_robust_planner(system, Box([0.3, 0.3], [0.6, 0.6]), reward, ROBOT_ACTIONS, budget=20, substeps=5)
    assert isinstance(robust, RobustTreePlanner) and robust.n_models == 1
    decision = robust.plan(root_state(robust, [0, 0, 0, 0], [0.02, 0.02, 0, 0]))
    assert 0.0 <= decision.lower <= decision.upper and decision.action in range(4)
    hypotheses = [(system, Box([0.3, 0.3], [0.6, 0.6])), (robot_system(0.1), Box([0.2, 0.2], [0.4, 0.4]))]
    multi = multi_model_robust_planner(hypotheses, reward, ROBOT_ACTIONS, budget=20, substeps=5)
    assert multi.n_models == 2
    multi_decision = multi.plan(root_state(multi, Box([0, 0, 0, 0], [0.02, 0.02, 0, 0])))
    assert 0.0 <= multi_decision.lower <= multi_decision.upper <= 1 / (1 - 0.9)
    nominal = nominal_planner(system, [0.45, 0.45], reward, ROBOT_ACTIONS, budget=20, substeps=5)
    oracle = oracle_planner(system, [0.5, 0.7], reward, ROBOT_ACTIONS, budget=20, substeps=5)
    for planner in (nominal, oracle):
        assert isinstance(planner, OptimisticPlanner)
        point_decision = planner.plan(root_state(planner, [0.0, 0.0, 0.0, 0.0]))
        # the certainty-equivalent value is at least the robust surrogate (w = 0, one theta in the box)
        assert point_decision.upper >= decision.lower - 1e-12
    with pytest.raises(InputError, match="point-model planner starts from one state"):
        root_state(nominal, [0.0] * 4, [0.0] * 4)


def test_multi_model_lower_bound_is_the_worst_model():
    system = robot_system()
    reward = GoalReward([3.0, 3.0])
    boxes = [Box([0.3, 0.3], [0.4, 0.4]), Box([0.6, 0.6], [0.8, 0.8])]
    single = [interval_robust_planner(system, b, reward, ROBOT_ACTIONS, budget=15, substeps=2) for b in boxes]
    multi = multi_model_robust_planner([(system, b) for b in boxes], reward, ROBOT_ACTIONS, budget=15, substeps=2)
    root = multi.models[0].initial_state([0, 0, 0, 0], [0.1, 0.1, 0, 0])
    decision = multi.plan(root)
    # a sequence good under both models is good under each: below each model's own upper bound
    assert decision.lower <= min(p.plan(root).upper for p in single) + 1e-12
    # and its sequence really achieves decision.lower under the worse model
    returns = []
    for model in multi.models:
        _, _, rewards, terminals = model.rollout(root, decision.sequence)
        alive = np.concatenate([[True], ~np.cumsum(terminals)[:-1].astype(bool)])
        returns.append(float(np.sum(0.9 ** np.arange(len(rewards)) * rewards * alive)))
    assert min(returns) == pytest.approx(decision.lower, abs=1e-12)


# ----------------------------------------------------------------- validation
def test_interval_model_validation():
    system = robot_system()
    reward = GoalReward([1.0, 1.0])
    with pytest.raises(InputError, match="system must be an UncertainLinearSystem, got str"):
        IntervalModel("plant", None, reward, ROBOT_ACTIONS)
    with pytest.raises(InputError, match="reward must have a callable box_minimum"):
        IntervalModel(system, None, object(), ROBOT_ACTIONS)
    with pytest.raises(
        DimensionError, match="reward reads state coordinates up to index 5, but the system has 4 states"
    ):
        IntervalModel(system, None, GoalReward([1.0, 1.0], position_indices=(5, 0)), ROBOT_ACTIONS)
    with pytest.raises(InputError, match="substeps must be a positive integer, got 0"):
        IntervalModel(system, None, reward, ROBOT_ACTIONS, substeps=0)
    with pytest.raises(InputError, match="controllers must be a non-empty sequence"):
        IntervalModel(system, None, reward, [])
    with pytest.raises(DimensionError, match=r"controllers\[1\]\.u must have shape \(2,\), got shape \(3,\)"):
        IntervalModel(system, None, reward, [OpenLoop([0.0, 0.0]), OpenLoop([0.0, 0.0, 0.0])])
    with pytest.raises(DimensionError, match=r"controllers\[0\]\.K must have shape \(2, 4\), got shape \(2, 3\)"):
        IntervalModel(system, None, reward, [LinearFeedback(np.zeros((2, 3)), np.zeros(3))])
    with pytest.raises(InputError, match=r"controllers\[0\] must be OpenLoop or LinearFeedback, got function"):
        IntervalModel(system, None, reward, [lambda x: x])
    with pytest.raises(DimensionError, match="parameters must have dimension 2"):
        IntervalModel(system, Box([0.0], [1.0]), reward, ROBOT_ACTIONS)
    model = IntervalModel(system, None, reward, ROBOT_ACTIONS)
    with pytest.raises(DimensionError, match=r"lower and upper must have shape \(4,\), got shapes \(3,\) and \(3,\)"):
        model.initial_state([0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    with pytest.raises(EmptySetError, match=r"lower > upper at indices \[1\]"):
        model.initial_state([0.0, 2.0, 0.0, 0.0], [1.0, 1.0, 1.0, 1.0])
    with pytest.raises(InputError, match="time must be an integer >= 0, got -1"):
        model.initial_state([0.0] * 4, time=-1)
    with pytest.raises(InputError, match="time must be an integer >= 0, got 2.0"):
        model.initial_state([0.0] * 4, time=2.0)
    with pytest.raises(InputError, match="substeps must be a positive integer, got 2.0"):
        IntervalModel(system, None, reward, ROBOT_ACTIONS, substeps=2.0)
    state = model.initial_state(Box([0.0] * 4, [1.0] * 4))
    with pytest.raises(InputError, match="state must be a BoxState"):
        model.expand((state.lower, state.upper), model.actions)
    with pytest.raises(InputError, match=r"actions must be controller indices in \[0, 4\), got \[0, 4\]"):
        model.expand(state, (0, 4))
    with pytest.raises(InputError, match=r"actions must be controller indices"):
        model.step(state, "left")


def test_controller_validation():
    with pytest.raises(DimensionError, match=r"x_ref must have shape \(3,\), got shape \(2,\)"):
        LinearFeedback(np.zeros((1, 3)), [0.0, 0.0])
    with pytest.raises(InputError, match="u_low must be <= u_high"):
        LinearFeedback(np.zeros((1, 3)), np.zeros(3), u_low=1.0, u_high=0.0)
    with pytest.raises(DimensionError, match=r"u_high must have shape \(1,\), got shape \(2,\)"):
        LinearFeedback(np.zeros((1, 3)), np.zeros(3), u_high=[1.0, 2.0])
    with pytest.raises(DimensionError, match=r"K must have shape \(2, 4\) for this system, got shape \(1, 4\)"):
        LinearFeedback(np.zeros((1, 4)), np.zeros(4)).closed_loop(robot_system())
    with pytest.raises(InputError, match="controllers must be a non-empty sequence"):
        ControllerBank([], 4, 2)
    feedback = LinearFeedback(np.eye(2), [1.0, -1.0], u_low=-0.5, u_high=0.5)
    np.testing.assert_allclose(feedback.control([[0.0, 0.0], [1.2, -0.9]]), [[0.5, -0.5], [-0.2, -0.1]])
    assert feedback.saturates and not LinearFeedback(np.eye(2), [0.0, 0.0]).saturates
    np.testing.assert_array_equal(OpenLoop([1.0, 2.0]).control(np.zeros((3, 4))), np.tile([1.0, 2.0], (3, 1)))


def test_point_model_validation():
    system = robot_system()
    with pytest.raises(DimensionError, match=r"theta must have shape \(2,\), got shape \(3,\)"):
        PointModel(system, [0.1, 0.2, 0.3], GoalReward([0.0, 0.0]), ROBOT_ACTIONS)
    model = PointModel(system, [0.1, 0.2], GoalReward([0.0, 0.0]), ROBOT_ACTIONS)
    with pytest.raises(DimensionError, match=r"x must have shape \(4,\), got shape \(2,\)"):
        model.initial_state([0.0, 0.0])
    with pytest.raises(InputError, match="state must be a PointState"):
        model.expand(np.zeros(4), model.actions)
    with pytest.raises(InputError, match="systems_with_parameters must hold at least one"):
        multi_model_robust_planner([], GoalReward([0.0, 0.0]), ROBOT_ACTIONS)
    small = systems.random_system(np.random.default_rng(0), p=3, q=2, d=2)
    with pytest.raises(
        DimensionError,
        match=r"systems_with_parameters\[1\] has 3 states and 2 inputs \(B of shape \(3, 2\)\), "
        r"but systems_with_parameters\[0\] has 4 and 2 \(B of shape \(4, 2\)\)",
    ):
        multi_model_robust_planner([(system, None), (small, None)], GoalReward([0.0, 0.0]), ROBOT_ACTIONS)
    with pytest.raises(DimensionError, match=r"systems_with_parameters\[1\] has 3 states"):
        IntervalModel.linked([(system, None), (small, None)], GoalReward([0.0, 0.0]), ROBOT_ACTIONS)
    with pytest.raises(InputError, match="time must be an integer >= 0, got 1.5"):
        model.initial_state(np.zeros(4), time=1.5)


# --------------------------------------------------------------- linked models
def _hypotheses(rng, n):
    p, q = 4, 2
    return [systems.random_system(rng, p=p, q=q, d=int(rng.integers(1, 3))) for _ in range(n)]


def _linked_case(rng, most, substeps):
    """2 to ``most - 1`` random hypotheses, controllers and a reward with discs, and their linked models."""
    hypotheses = _hypotheses(rng, int(rng.integers(2, most)))
    controllers = systems.random_controllers(rng, hypotheses[0], n=3)
    reward = GoalReward(
        [2.0, 2.0], obstacles=CircularObstacles(rng.uniform(-3, 3, (5, 2)), np.full(5, 0.4)), robot_radius=0.2
    )
    linked = IntervalModel.linked([(h, h.theta) for h in hypotheses], reward, controllers, substeps=substeps)
    return hypotheses, controllers, reward, linked


@settings(max_examples=15)
@given(seeds, st.integers(1, 3))
def test_linked_models_equal_separate_models(seed, substeps):
    rng = np.random.default_rng(seed)
    hypotheses, controllers, reward, linked = _linked_case(rng, 4, substeps)
    separate = [IntervalModel(h, h.theta, reward, controllers, substeps=substeps) for h in hypotheses]
    assert [m.n_linked for m in linked] == [len(hypotheses)] * len(hypotheses) and separate[0].n_linked == 1
    root = linked[0].initial_state(rng.uniform(-1, 0, 4), rng.uniform(0, 1, 4))
    same = dict(rtol=1e-13, atol=1e-13)
    # members asked in reverse order (the cache must not mix rows up), twice
    for order in (reversed(range(len(linked))), range(len(linked))):
        for m in order:
            states, rewards, terminals = linked[m].expand(root, linked[m].actions)
            ref_states, ref_rewards, ref_terminals = separate[m].expand(root, separate[m].actions)
            np.testing.assert_allclose(rewards, ref_rewards, **same)
            np.testing.assert_array_equal(terminals, ref_terminals)
            for state, ref in zip(states, ref_states):
                lo, hi = linked[m].box(state)
                np.testing.assert_allclose(lo, ref.lower, **same)
                np.testing.assert_allclose(hi, ref.upper, **same)
    # one step further from the joint states: each member continues from its own box
    child = linked[0].expand(root, linked[0].actions)[0][1]
    ref_child = [s.expand(root, s.actions)[0][1] for s in separate]
    for m, model in enumerate(linked):
        _, rewards, _ = model.expand(child, model.actions)
        _, ref_rewards, _ = separate[m].expand(ref_child[m], separate[m].actions)
        np.testing.assert_allclose(rewards, ref_rewards, **same)
    # rollout of a member == rollout of the separate model
    for m, model in enumerate(linked):
        a, b = model.rollout(root, [0, 2, 1]), separate[m].rollout(root, [0, 2, 1])
        for x, y in zip(a, b):
            np.testing.assert_allclose(x, y, **same)


@settings(max_examples=15, deadline=None)
@given(seeds, st.integers(1, 3), st.integers(1, 4))
def test_linked_rollouts_share_one_computation_and_follow_the_tree_transitions(seed, substeps, decisions):
    """The members' rollouts of one plan from one state are one pass of the group (one propagation per
    decision, not one per member and decision), each row is its member's chain of tree transitions
    (`expand`) bit for bit, and what a member gets back is its own writable copy."""
    rng = np.random.default_rng(seed)
    _, _, _, linked = _linked_case(rng, 5, substeps)
    group = linked[0].group
    calls = []
    propagate = group.propagate
    group.propagate = lambda z, time, index: calls.append(len(index)) or propagate(z, time, index)
    root = linked[0].initial_state(rng.uniform(-1, 0, 4), rng.uniform(0, 1, 4), time=3)
    plan = [int(a) for a in rng.integers(0, 3, size=decisions)]
    rollouts = [model.rollout(root, plan) for model in linked]
    assert calls == [1] * decisions
    for m, (lower, upper, rewards, terminals) in enumerate(rollouts):
        assert lower.shape == upper.shape == (decisions * substeps + 1, 4) and lower.flags.writeable
        state = root
        for k, action in enumerate(plan):
            states, step_rewards, step_terminals = linked[m].expand(state, (action,))
            state = states[0]
            lo, hi = linked[m].box(state)
            np.testing.assert_array_equal(lower[(k + 1) * substeps], lo)
            np.testing.assert_array_equal(upper[(k + 1) * substeps], hi)
            assert rewards[k] == step_rewards[0] and terminals[k] == step_terminals[0]
    # a member's copy is its own: writing into it changes nothing another member reads
    rollouts[0][0][:] = np.nan
    np.testing.assert_array_equal(linked[0].rollout(root, plan)[1], rollouts[0][1])
    assert not np.isnan(linked[0].rollout(root, plan)[0]).any()
    # from a joint state (one box per member), a child of the tree: each row continues from its own box
    child = linked[0].expand(root, (plan[0],))[0][0]
    calls.clear()
    for model in linked:
        lower, upper, _, _ = model.rollout(child, plan)
        np.testing.assert_array_equal(lower[0], model.box(child)[0])
        np.testing.assert_array_equal(upper[0], model.box(child)[1])
    assert calls == [1] * decisions
    # another plan, or an equal state that is another object, is computed again
    calls.clear()
    linked[1].rollout(child, plan + [0])
    linked[1].rollout(BoxState(child.lower, child.upper, child.time), plan + [0])
    assert calls == [1] * (2 * decisions + 2)


def test_linked_rollout_checks_its_input_after_a_cached_pass():
    system = robot_system()
    models = IntervalModel.linked([(system, None), (system, None)], GoalReward([0.0, 0.0]), ROBOT_ACTIONS)
    root = models[0].initial_state(np.zeros(4))
    models[0].rollout(root, [1, 2])
    with pytest.raises(InputError, match=r"actions must be controller indices in \[0, 4\), got \[1, 7\]"):
        models[1].rollout(root, [1, 7])
    with pytest.raises(InputError, match="state must be"):
        models[1].rollout(root.z, [1, 2])
    with pytest.raises(DimensionError, match=r"state holds 3 boxes, expected 2"):
        models[1].rollout(BoxState(np.zeros((3, 4)), np.ones((3, 4)), 0), [1, 2])


def test_linked_planner_decides_like_separate_models():
    rng = np.random.default_rng(4)
    system = robot_system()
    boxes = [Box([0.2, 0.2], [0.4, 0.5]), Box([0.5, 0.3], [0.8, 0.6]), Box([0.3, 0.6], [0.5, 0.8])]
    obstacles = CircularObstacles(rng.uniform(0.5, 4.0, (6, 2)), rng.uniform(0.2, 0.5, 6))
    reward = GoalReward([4.0, 4.0], obstacles=obstacles, robot_radius=0.3)
    linked = multi_model_robust_planner([(system, b) for b in boxes], reward, ROBOT_ACTIONS, budget=60, substeps=3)
    separate = RobustTreePlanner(
        [IntervalModel(system, b, reward, ROBOT_ACTIONS, substeps=3) for b in boxes], range(4), gamma=0.9, budget=60
    )
    root = linked.models[0].initial_state([0, 0, 0, 0], [0.1, 0.1, 0, 0])
    a, b = linked.plan(root), separate.plan(root)
    assert a.sequence == b.sequence and a.expansions == b.expansions == 60
    assert a.lower == pytest.approx(b.lower, abs=1e-12) and a.upper == pytest.approx(b.upper, abs=1e-12)
    # one initial box per model
    roots = [linked.models[0].initial_state([0, 0, 0, 0], [0.1 * (m + 1), 0.1, 0, 0]) for m in range(3)]
    a, b = linked.plan(roots, per_model=True), separate.plan(roots, per_model=True)
    assert a.sequence == b.sequence and a.lower == pytest.approx(b.lower, abs=1e-12)


def test_linked_validation():
    system = robot_system()
    with pytest.raises(InputError, match="systems_with_parameters must hold at least one"):
        IntervalModel.linked([], GoalReward([0.0, 0.0]), ROBOT_ACTIONS)
    with pytest.raises(InputError, match=r"each item of systems_with_parameters must be a \(system, parameters\) pair"):
        IntervalModel.linked([(system,)], GoalReward([0.0, 0.0]), ROBOT_ACTIONS)
    models = IntervalModel.linked([(system, None), (system, None)], GoalReward([0.0, 0.0]), ROBOT_ACTIONS)
    bad = BoxState(np.zeros((3, 4)), np.ones((3, 4)), 0)
    with pytest.raises(DimensionError, match=r"state holds 3 boxes, expected 2"):
        models[0].expand(bad, models[0].actions)


def test_controllers_to_dict_and_box_state():
    import json

    feedback = LinearFeedback(np.eye(2), [1.0, -1.0], u_low=-0.5)
    data = json.loads(json.dumps(feedback.to_dict(), allow_nan=False))
    assert data["u_low"] == [-0.5, -0.5] and data["u_high"] == [None, None] and data["kind"] == "linear_feedback"
    assert json.loads(json.dumps(OpenLoop([1.0, 0.0]).to_dict(), allow_nan=False)) == {
        "kind": "open_loop",
        "u": [1.0, 0.0],
    }
    state = BoxState(np.zeros(2), np.ones(2), 3)
    lower, upper, time = state
    np.testing.assert_array_equal(state.z, [0.0, 0.0, 1.0, 1.0])
    assert time == 3 and "time=3" in repr(state)


def test_ellipsoid_parameter_set_contains_true_trajectories():
    from minimaxplan.models import Ellipsoid

    system = robot_system()
    ellipsoid = Ellipsoid([0.5, 0.4], np.array([[40.0, 10.0], [10.0, 30.0]]), 1.0)
    model = IntervalModel(system, ellipsoid, UnboundedReward(), ROBOT_ACTIONS, substeps=5)
    lo0, hi0 = np.array([0.0, 0.0, 0.1, -0.1]), np.array([0.05, 0.05, 0.2, 0.0])
    sequence = [3, 0, 2, 1]
    lower, upper, _, _ = model.rollout(model.initial_state(lo0, hi0), sequence)
    rng = np.random.default_rng(2)
    # parameters on the ellipsoid's boundary and inside it
    directions = rng.normal(size=(40, 2))
    directions /= np.sqrt(np.einsum("ni,ij,nj->n", directions, ellipsoid.gramian, directions))[:, None]
    scale = np.where(np.arange(40) < 20, 1.0, rng.uniform(0.0, 1.0, 40))[:, None]
    thetas = ellipsoid.center + directions * ellipsoid.radius * scale
    assert ellipsoid.contains(thetas, tol=1e-9)
    x0 = systems.initial_samples(rng, lo0, hi0, len(thetas))
    states = systems.simulate(rng, system, thetas, x0, [ROBOT_ACTIONS[a] for a in sequence], 5)
    assert systems.inside(states, lower, upper)
