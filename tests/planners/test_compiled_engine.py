"""The compiled engine's transitions are the models' transitions, bit for bit.

Both engines run the same tree operations (`minimaxplan.planners.tree_ops`); they
differ in where a leaf's transitions come from: the compiled box kernel inside the
search kernel, or the models' ``expand`` (and, with numpy rewards, the families'
``box_minimum``). Random systems (Metzler or not, random dt), open-loop and saturating
feedback controllers, 1 to 3 linked hypotheses, 1 to 3 sub-steps, both reward families
with static and moving obstacles placed where the boxes collide. Also: the compiled
box minima equal the families' numpy ``box_minimum_raw`` bit for bit, a reward outside
[0, 1] raises the same error on both engines, and the engine choice is validated.
"""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.kernels import box_primitives, minimum_sources, sources_digest
from minimaxplan.models import Box, UncertainLinearSystem
from minimaxplan.models.errors import InputError, RewardRangeError
from minimaxplan.planners import OpenLoop, PointModel, RobustTreePlanner
from minimaxplan.planners.box_kernels import stack_rewards_kernel
from minimaxplan.planners.interval_model import IntervalModel
from minimaxplan.scenarios.geometry import CircularObstacles, MovingObstacles
from minimaxplan.scenarios.rewards import GoalReward, SpeedLaneReward

from ._systems import random_controllers, random_system
from .test_hot_paths import tree_arrays

seeds = st.integers(0, 2**31 - 1)
REWARD_KINDS = ("goal", "goal_moving", "speed_1", "speed_2")


def random_reward(rng, kind, near):
    """A reward whose obstacles sit around ``near`` (the root's position), so that some boxes collide."""
    n = int(rng.integers(1, 6))
    obstacles = CircularObstacles(near + rng.uniform(-2, 2, (n, 2)), rng.uniform(0.1, 0.8, n))
    moving = None
    if kind in ("goal_moving", "speed_2"):
        moving = MovingObstacles(
            near + rng.uniform(-2, 2, (2, 2)),
            rng.uniform(-1, 1, (2, 2)),
            [0.2, 0.3],
            velocity_uncertainty=0.1,
            position_uncertainty=0.05,
            dt=0.1,
            time0=int(rng.integers(0, 3)),
        )
    radius = float(rng.uniform(0, 0.3))
    if kind.startswith("goal"):
        return GoalReward(
            near + rng.uniform(-4, 4, 2), obstacles=obstacles, moving_obstacles=moving, robot_radius=radius
        )
    speed = (2,) if kind == "speed_1" else (2, 3)
    return SpeedLaneReward(
        float(rng.uniform(-1, 2)),
        float(rng.uniform(0.2, 2)),
        speed_indices=speed,
        lateral_index=1,
        lane_width=float(rng.uniform(0.5, 2)),
        n_lanes=int(rng.integers(2, 4)),
        speed_weight=0.7,
        lane_weight=0.3,
        obstacles=obstacles,
        moving_obstacles=moving,
        robot_radius=radius,
    )


def both_engines(models, root, gamma, budget):
    compiled = RobustTreePlanner(models, models[0].actions, gamma=gamma, budget=budget)
    python = RobustTreePlanner(models, models[0].actions, gamma=gamma, budget=budget, engine="python")
    decisions = compiled.plan(root), python.plan(root)
    assert (compiled.engine_used, python.engine_used) == ("compiled", "python")
    return decisions, (tree_arrays(compiled), tree_arrays(python)), (compiled.tree, python.tree)


@given(
    seeds, st.integers(1, 3), st.integers(1, 3), st.sampled_from(REWARD_KINDS), st.integers(1, 40), st.floats(0.5, 0.95)
)
def test_compiled_engine_builds_the_python_engines_tree(seed, n_models, substeps, kind, budget, gamma):
    rng = np.random.default_rng(seed)
    system = random_system(rng, p=4)
    hypotheses = [(system, None)] + [(random_system(rng, p=4, q=system.ninputs), None) for _ in range(n_models - 1)]
    centre = rng.uniform(-3, 3, 4)
    reward = random_reward(rng, kind, centre[:2])
    models = IntervalModel.linked(hypotheses, reward, random_controllers(rng, system), substeps=substeps)
    root = models[0].initial_state(centre - 0.05, centre + 0.05, time=int(rng.integers(0, 5)))
    (fast, general), (fast_tree, general_tree), _ = both_engines(models, root, gamma, budget)
    assert fast == general
    assert fast_tree == general_tree


def test_compiled_engine_covers_collisions_and_terminated_models():
    """The property test's worlds do exercise terminal transitions, with models terminating apart."""
    terminal_trees = partial = 0
    for seed in range(40):
        rng = np.random.default_rng(seed)
        system = random_system(rng, p=4)
        hypotheses = [(system, None), (random_system(rng, p=4, q=system.ninputs), None)]
        centre = rng.uniform(-3, 3, 4)
        models = IntervalModel.linked(
            hypotheses, random_reward(rng, "goal_moving", centre[:2]), random_controllers(rng, system)
        )
        root = models[0].initial_state(centre - 0.05, centre + 0.05)
        (fast, general), (fast_tree, general_tree), (tree, _) = both_engines(models, root, 0.9, 30)
        assert fast == general and fast_tree == general_tree
        terminal = tree.terminal[: tree.size]
        terminal_trees += bool(terminal.any())
        partial += bool((terminal.any(axis=1) & ~terminal.all(axis=1)).any())
    assert terminal_trees >= 10 and partial >= 3, (terminal_trees, partial)


class _NumpyReward:
    """A reward family seen only through its numpy ``box_minimum`` (no compiled form)."""

    def __init__(self, reward):
        self.box_minimum = reward.box_minimum


@given(seeds, st.sampled_from(REWARD_KINDS), st.integers(1, 2))
def test_numpy_rewards_on_the_python_engine_give_the_compiled_tree(seed, kind, substeps):
    rng = np.random.default_rng(seed)
    system = random_system(rng, p=4)
    centre = rng.uniform(-3, 3, 4)
    reward = random_reward(rng, kind, centre[:2])
    controllers = random_controllers(rng, system)
    compiled_models = IntervalModel.linked([(system, None)] * 2, reward, controllers, substeps=substeps)
    numpy_models = IntervalModel.linked([(system, None)] * 2, _NumpyReward(reward), controllers, substeps=substeps)
    planners = [
        RobustTreePlanner(models, models[0].actions, gamma=0.85, budget=20)
        for models in (compiled_models, numpy_models)
    ]
    decisions = [
        planner.plan(models[0].initial_state(centre - 0.05, centre + 0.05))
        for planner, models in zip(planners, (compiled_models, numpy_models))
    ]
    assert [planner.engine_used for planner in planners] == ["compiled", "python"]
    assert decisions[0] == decisions[1]
    assert tree_arrays(planners[0]) == tree_arrays(planners[1])


@given(seeds, st.sampled_from(REWARD_KINDS), st.floats(0.0, 3.0), st.integers(0, 30))
def test_compiled_box_minimum_equals_numpy_bit_for_bit(seed, kind, spread, t):
    rng = np.random.default_rng(seed)
    reward = random_reward(rng, kind, np.zeros(2))
    n = 64
    lower = rng.uniform(-3, 3, (n, 4))
    lower[: n // 4, 2:] = rng.choice([-1.0, 0.0, 1.0], (n // 4, 2))  # speed boxes touching 0 and the target
    upper = lower + rng.uniform(0, spread, (n, 4)) * (rng.random((n, 4)) < 0.8)
    expected, expected_hit = reward.box_minimum_raw(lower, upper, t)
    stack = np.concatenate([-lower, upper], axis=-1)[None, None]  # (S=1, M=1, n, 2p) at sub-step t = time + 1
    minimum, hit = np.empty((1, n)), np.empty((1, n), dtype=bool)
    stack_rewards_kernel(type(reward.kernel_params))(stack, t - 1, reward.kernel_params, minimum, hit)
    assert np.array_equal(minimum[0], expected) and np.array_equal(hit[0], expected_hit)


def overflowing_models():
    """A system whose boxes overflow to inf and then NaN (0 * inf in the product) at the second step."""
    A0 = np.diag([1e200, 1e200, 1.0, 1.0])
    A0[0, 1] = 0.0
    phi = np.zeros((1, 4, 4))
    phi[0, 2, 2] = 1.0
    system = UncertainLinearSystem(
        A0, phi, np.eye(4)[:, :2], D=np.eye(4)[:, :1], w=Box([0.0], [0.0]), theta=Box([0.0], [0.1])
    )
    reward = GoalReward([0.0, 0.0])
    return IntervalModel.linked([(system, None)], reward, [OpenLoop([0.0, 0.0]), OpenLoop([1.0, 0.0])])


def test_a_reward_outside_the_unit_interval_raises_the_same_error_on_both_engines():
    models = overflowing_models()
    root = models[0].initial_state([1.0, 1.0, 0.0, 0.0], [2.0, 2.0, 0.0, 0.0])
    messages = []
    for engine in ("compiled", "python"):
        planner = RobustTreePlanner(models, models[0].actions, gamma=0.9, budget=10, engine=engine)
        with pytest.raises(
            RewardRangeError, match=r"models\[0\] returned reward nan for action 0 \(index 0\)"
        ) as error:
            planner.plan(root)
        messages.append(str(error.value))
    assert messages[0] == messages[1]


def test_engine_validation():
    rng = np.random.default_rng(3)
    system = random_system(rng, p=4)
    reward = GoalReward([0.0, 0.0])
    models = IntervalModel.linked([(system, None)] * 2, reward, [OpenLoop(np.zeros(system.ninputs))] * 2)
    with pytest.raises(InputError, match="engine must be one of"):
        RobustTreePlanner(models, models[0].actions, gamma=0.9, budget=5, engine="numba")
    with pytest.raises(InputError, match="engine='compiled' needs the models of one IntervalModel.linked group"):
        RobustTreePlanner(models[::-1], models[0].actions, gamma=0.9, budget=5, engine="compiled")
    with pytest.raises(InputError, match="kernel_params"):
        numpy_models = IntervalModel.linked(
            [(system, None)], _NumpyReward(reward), [OpenLoop(np.zeros(system.ninputs))]
        )
        RobustTreePlanner(numpy_models, (0,), gamma=0.9, budget=5, engine="compiled")
    with pytest.raises(InputError, match="engine='compiled' needs the models"):
        RobustTreePlanner(
            [PointModel(system, system.theta.center, reward, [OpenLoop(np.zeros(system.ninputs))])],
            (0,),
            gamma=0.9,
            budget=5,
            engine="compiled",
        )
    planner = RobustTreePlanner(models, models[0].actions, gamma=0.9, budget=5, engine="compiled")
    roots = [models[0].initial_state(np.zeros(4)), models[0].initial_state(np.ones(4))]
    with pytest.raises(InputError, match="one initial state shared by every model"):
        planner.plan(roots, per_model=True)
    auto = RobustTreePlanner(models, models[0].actions, gamma=0.9, budget=5)
    assert auto.tree is None and auto.engine_used is None
    auto.plan(roots, per_model=True)
    assert auto.engine_used == "python"  # per-model root states: the Python engine
    same = auto.plan([roots[0], roots[0]], per_model=True)
    assert auto.engine_used == "compiled" and same == auto.plan(roots[0])


def test_a_pickled_planner_plans_alike_in_another_process_state():
    """Experiments ship planners to worker processes: the compiled engine's pieces must pickle."""
    import pickle

    rng = np.random.default_rng(5)
    system = random_system(rng, p=4)
    centre = rng.uniform(-3, 3, 4)
    models = IntervalModel.linked(
        [(system, None)] * 2, random_reward(rng, "speed_2", centre[:2]), random_controllers(rng, system)
    )
    planner = RobustTreePlanner(models, models[0].actions, gamma=0.9, budget=20)
    root = models[0].initial_state(centre - 0.05, centre + 0.05)
    decision = planner.plan(root)
    clone = pickle.loads(pickle.dumps(planner))
    assert clone.plan(pickle.loads(pickle.dumps(root))) == decision and clone.engine_used == "compiled"


def test_compiled_kernels_are_keyed_by_the_sources_they_call():
    """numba's disk cache tracks only a function's own file: the kernels close over a digest of their callees'."""
    from minimaxplan.planners import box_kernels, compiled_search, tree_ops
    from minimaxplan.scenarios import compiled_rewards

    def closure_values(dispatcher):
        return [cell.cell_contents for cell in dispatcher.py_func.__closure__ or ()]

    for params_type in (compiled_rewards.GoalParams, compiled_rewards.SpeedLaneParams):
        rewards = stack_rewards_kernel(params_type)
        search = compiled_search.search_kernel(params_type)
        assert compiled_rewards.__file__ in minimum_sources(params_type)
        assert box_primitives.__file__ in minimum_sources(params_type)
        assert sources_digest(box_kernels.__file__, *minimum_sources(params_type)) in closure_values(rewards)
        search_sources = (
            compiled_search.__file__,
            tree_ops.__file__,
            box_kernels.__file__,
            *minimum_sources(params_type),
        )
        assert sources_digest(*search_sources) in closure_values(search)
    # the box transition inlines the box primitives: its kernels close over their digest too
    for kernel in (box_kernels.substep, box_kernels.propagate):
        assert sources_digest(box_primitives.__file__) in closure_values(kernel)


@given(seeds, st.integers(1, 3), st.sampled_from(REWARD_KINDS))
def test_compiled_bounds_are_monotone_and_trees_nest_as_the_budget_grows(seed, n_models, kind):
    """Theorem 3 on the compiled engine itself: the tree after K expansions is a prefix of the one after K + 1."""
    rng = np.random.default_rng(seed)
    system = random_system(rng, p=4)
    hypotheses = [(system, None)] + [(random_system(rng, p=4, q=system.ninputs), None) for _ in range(n_models - 1)]
    centre = rng.uniform(-3, 3, 4)
    models = IntervalModel.linked(hypotheses, random_reward(rng, kind, centre[:2]), random_controllers(rng, system))
    root = models[0].initial_state(centre - 0.05, centre + 0.05)
    previous = None
    for budget in range(1, 16):
        planner = RobustTreePlanner(models, models[0].actions, gamma=0.85, budget=budget, engine="compiled")
        decision = planner.plan(root)
        tree = planner.tree
        assert decision.lower <= decision.upper
        if previous is not None:
            old_decision, old_tree = previous
            assert decision.lower >= old_decision.lower and decision.upper <= old_decision.upper
            n = old_tree.size
            assert np.array_equal(tree.parent[:n], old_tree.parent)
            assert np.array_equal(tree.expanded[: len(old_tree.expanded)], old_tree.expanded)
            assert np.array_equal(tree.returns[:n], old_tree.returns[:n])
        previous = decision, tree


def test_kernel_params_without_a_registered_minimum_are_rejected():
    from collections import namedtuple

    rng = np.random.default_rng(2)
    system = random_system(rng, p=4)

    class Unregistered(_NumpyReward):
        kernel_params = namedtuple("SomethingElse", ["goal"])(np.zeros(2))

    with pytest.raises(
        InputError, match="reward.kernel_params has type SomethingElse, for which no compiled box minimum"
    ):
        IntervalModel(system, None, Unregistered(GoalReward([0.0, 0.0])), [OpenLoop(np.zeros(system.ninputs))])


def test_budgets_beyond_the_first_arrays_grow_them_on_both_engines_without_allocating_by_the_budget():
    """The compiled search stops when its arrays are full and resumes in grown ones: the same tree as the Python engine's."""
    import tracemalloc

    rng = np.random.default_rng(8)
    system = random_system(rng, p=4)
    models = IntervalModel.linked([(system, None)], GoalReward([40.0, 40.0]), [OpenLoop(np.zeros(system.ninputs))] * 2)
    root = models[0].initial_state(np.full(4, -0.01), np.full(4, 0.01))
    (fast, general), (fast_tree, general_tree), (tree, _) = both_engines(models, root, 0.99, 2500)
    assert fast == general and fast_tree == general_tree and tree.size == 5001 > 4096
    # a huge budget is not allocated up front: a search solved at once stays small
    stuck = IntervalModel.linked(
        [(system, None)],
        GoalReward([0.0, 0.0], obstacles=CircularObstacles([[0.0, 0.0]], [1.0])),
        [OpenLoop(np.zeros(system.ninputs))] * 4,
    )
    planner = RobustTreePlanner(stuck, stuck[0].actions, gamma=0.9, budget=10**7, engine="compiled")
    tracemalloc.start()
    try:
        decision = planner.plan(stuck[0].initial_state(np.full(4, -0.01), np.full(4, 0.01)))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert decision.solved and decision.expansions == 1 and planner.engine_used == "compiled"
    assert peak < 20 * 2**20, peak
