"""The search mechanics of RobustTreePlanner / OptimisticPlanner: selection rule,
batched vs one-by-one transitions, terminal handling, M = 1 reduction, validation."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models.errors import DimensionError, InputError, NonFiniteError, RewardRangeError
from minimaxplan.planners import Decision, OptimisticPlanner, RobustTreePlanner


class PathModel:
    """Deterministic random rewards indexed by the action path (the state).

    Rewards are often exactly 0, 1/2 or 1 (so that b-values tie); transitions are
    terminal at random and always at depth ``horizon``. Stepping from a state after
    a terminal transition is an error (the planner must never do it).
    """

    def __init__(self, seed: int, horizon: int, p_terminal: float) -> None:
        self.seed, self.horizon, self.p_terminal = seed, horizon, p_terminal
        self.step_calls = 0

    def outcome(self, path: tuple) -> tuple[float, bool]:
        rng = np.random.default_rng([self.seed, len(path), *path])
        kind = rng.integers(4)
        reward = (0.0, 0.5, 1.0)[kind] if kind < 3 else float(rng.random())
        return reward, bool(len(path) >= self.horizon or rng.random() < self.p_terminal)

    def step(self, state, action):
        self.step_calls += 1
        assert not (state and self.outcome(state)[1]), f"stepped after a terminal transition at {state}"
        path = state + (action,)
        reward, terminal = self.outcome(path)
        return path, reward, terminal


class BatchedPathModel(PathModel):
    """The same model with the vectorised ``expand`` protocol."""

    def __init__(self, *args) -> None:
        super().__init__(*args)
        self.expand_calls = 0

    def expand(self, state, actions):
        self.expand_calls += 1
        assert not (state and self.outcome(state)[1]), f"expanded after a terminal transition at {state}"
        paths = [state + (a,) for a in actions]
        outcomes = [self.outcome(p) for p in paths]
        rewards = np.array([r for r, _ in outcomes])
        terminals = np.array([t for _, t in outcomes], dtype=bool)
        return paths, rewards, terminals


@st.composite
def problems(draw):
    n_models = draw(st.integers(1, 4))
    n_actions = draw(st.integers(2, 3))
    horizon = draw(st.integers(2, 8))
    p_terminal = draw(st.sampled_from([0.0, 0.05, 0.2]))
    seeds = draw(st.lists(st.integers(0, 2**31), min_size=n_models, max_size=n_models))
    gamma = draw(st.floats(0.5, 0.95))
    return seeds, n_actions, horizon, p_terminal, gamma


def make_models(problem, cls=PathModel):
    seeds, _, horizon, p_terminal, _ = problem
    return [cls(seed, horizon, p_terminal) for seed in seeds]


def run(problem, budget, cls=PathModel):
    _, n_actions, _, _, gamma = problem
    models = make_models(problem, cls)
    planner = RobustTreePlanner(models, range(n_actions), gamma=gamma, budget=budget)
    decision = planner.plan(())
    return planner.tree, decision, models


def naive_descent(tree) -> int:
    """Follow the child of largest backed-up upper bound (smallest index on ties)."""
    node = 0
    while not tree.is_leaf(node):
        children = list(tree.children(node))
        uppers = [tree.upper[c] for c in children]
        node = children[uppers.index(max(uppers))]
    return node


def best_leaf_by_enumeration(tree) -> int:
    """The leaf of largest b-value, lexicographically smallest path on ties."""
    leaves = [i for i in range(tree.size) if tree.is_leaf(i)]
    return min(leaves, key=lambda i: (-tree.leaf_upper[i], tree.path(i)))


@settings(max_examples=30)
@given(problem=problems(), max_budget=st.integers(2, 25))
def test_heap_selection_equals_naive_descent(problem, max_budget):
    for budget in range(1, max_budget):
        tree, decision, _ = run(problem, budget)
        if decision.solved:
            # Stopped early: the root's bounds met, no further expansion.
            assert decision.lower == decision.upper and decision.expansions < budget
            break
        descended = naive_descent(tree)
        assert descended == best_leaf_by_enumeration(tree)
        # The backed-up upper bound of every internal node is its leaves' max b-value.
        assert tree.upper[0] == tree.leaf_upper[descended]
        next_tree, next_decision, _ = run(problem, budget + 1)
        if next_decision.solved and next_decision.expansions == budget:
            assert decision.lower == decision.upper
            break
        assert next_tree.expanded[budget] == descended


def test_deep_tree_ties_follow_the_lexicographic_path():
    # Both actions always pay 1 and gamma = 1/2, so every b-value is exactly
    # 2 = 1 / (1 - gamma) in binary floating point: all leaves tie, and the smallest
    # path (all zeros) is expanded each time, down to depth 50.
    class Ones:
        def step(self, state, action):
            return state, 1.0

    budget = 50
    planner = OptimisticPlanner(Ones(), ["a", "b"], gamma=0.5, budget=budget)
    decision = planner.plan(None)
    tree = planner.tree
    assert np.all(tree.leaf_upper == 2.0)
    assert decision.depth == budget and decision.sequence == ("a",) * budget
    assert [tree.path(i) for i in tree.expanded] == [(0,) * k for k in range(budget)]
    assert decision.lower == 2.0 - 2.0 ** (1 - budget) and decision.upper == 2.0


@given(problem=problems(), budget=st.integers(1, 40))
def test_expand_protocol_and_step_build_identical_trees(problem, budget):
    tree, decision, _ = run(problem, budget, PathModel)
    batched_tree, batched_decision, batched_models = run(problem, budget, BatchedPathModel)
    assert decision.to_dict() == batched_decision.to_dict()
    assert tree.size == batched_tree.size
    for name in (
        "parent",
        "action",
        "depth",
        "first_child",
        "returns",
        "terminal",
        "leaf_lower",
        "leaf_upper",
        "lower",
        "upper",
    ):
        assert np.array_equal(getattr(tree, name)[: tree.size], getattr(batched_tree, name)[: tree.size]), name
    assert tree.states == batched_tree.states
    # The batched protocol is used whenever it exists: no single steps at all.
    assert all(m.step_calls == 0 for m in batched_models)
    assert sum(m.expand_calls for m in batched_models) > 0


@given(problem=problems(), copies=st.integers(1, 3), budget=st.integers(1, 40))
def test_identical_models_reduce_to_optimistic_planning(problem, copies, budget):
    # min over M copies of one model is that model: the robust search is OPD.
    seeds, n_actions, horizon, p_terminal, gamma = problem
    robust = RobustTreePlanner(
        [PathModel(seeds[0], horizon, p_terminal) for _ in range(copies)], range(n_actions), gamma=gamma, budget=budget
    )
    opd = OptimisticPlanner(PathModel(seeds[0], horizon, p_terminal), range(n_actions), gamma=gamma, budget=budget)
    assert robust.plan(()).to_dict() == opd.plan(()).to_dict()
    assert np.array_equal(robust.tree.parent, opd.tree.parent)
    assert np.array_equal(robust.tree.expanded, opd.tree.expanded)


@given(problem=problems(), budget=st.integers(1, 40))
def test_optimistic_planner_b_values_are_the_corrected_eq12(problem, budget):
    # OPD leaf b-value: sum_{n<l} gamma^n r_n + gamma^l / (1 - gamma), or the return
    # alone below a terminal transition; never above the parent's.
    seeds, n_actions, horizon, p_terminal, gamma = problem
    model = PathModel(seeds[0], horizon, p_terminal)
    planner = OptimisticPlanner(model, range(n_actions), gamma=gamma, budget=budget)
    planner.plan(())
    tree = planner.tree
    for node in range(1, tree.size):
        path = tree.path(node)
        total, done = 0.0, False
        for n in range(len(path)):
            reward, terminal = model.outcome(path[: n + 1])
            total = total + gamma**n * (0.0 if done else reward)
            done = done or terminal
        assert tree.returns[node, 0] == total
        assert tree.leaf_lower[node] == total
        expected = total if done else total + gamma ** len(path) / (1 - gamma)
        parent_bound = tree.leaf_upper[tree.parent[node]]
        assert tree.leaf_upper[node] == min(expected, parent_bound)
        # The clipping to the parent's b-value only ever removes rounding.
        assert expected - tree.leaf_upper[node] <= 4 * np.finfo(float).eps / (1 - gamma)


def test_terminated_model_is_never_stepped_and_adds_no_tail():
    gamma = 0.9

    class Crash:
        """Terminal at the first transition, reward 1."""

        def __init__(self):
            self.calls = []

        def step(self, state, action):
            self.calls.append(state)
            return "crashed", 1.0, True

    class Halves:
        def step(self, state, action):
            return state + 1, 0.5

    crash = Crash()
    planner = RobustTreePlanner([crash, Halves()], ["left", "right"], gamma=gamma, budget=10)
    decision = planner.plan(0)
    tree = planner.tree
    assert crash.calls == [0, 0]  # only the root's two children
    # The crashed model adds no tail: every leaf's b-value is min(1, ...) = 1.
    assert np.all(tree.leaf_upper[1:] == 1.0)
    # Halves collects 0.5 (1 + 0.9 + 0.81) = 1.355 >= 1 after three steps, so the
    # robust value 1 is known after three expansions (down the "left" branch).
    assert decision.lower == decision.upper == 1.0
    assert decision.solved and decision.expansions == 3 and decision.depth == 3
    assert decision.sequence == ("left", "left", "left")
    assert tree.states[0][3:] == ["crashed"] * 4  # carried along, not stepped
    assert tree.states[1][tree.size - 1] == 3


def test_per_model_initial_states():
    seen = {0: [], 1: []}

    class Recorder:
        def __init__(self, index):
            self.index = index

        def step(self, state, action):
            seen[self.index].append(state)
            return state, 0.5

    planner = RobustTreePlanner([Recorder(0), Recorder(1)], [0, 1], gamma=0.5, budget=1)
    planner.plan(["a", "b"], per_model=True)
    assert seen == {0: ["a", "a"], 1: ["b", "b"]}
    seen[0].clear(), seen[1].clear()
    planner.plan(("shared", "tuple"))
    assert seen == {0: [("shared", "tuple")] * 2, 1: [("shared", "tuple")] * 2}
    with pytest.raises(DimensionError, match=r"per_model=True, state must hold 2 states \(one per model\), got 3"):
        planner.plan(["a", "b", "c"], per_model=True)
    with pytest.raises(InputError, match=r"per_model=True, state must be a sequence of one state per model"):
        planner.plan(3, per_model=True)


@given(problem=problems(), budget=st.integers(1, 30), seed=st.integers(0, 1000))
def test_seed_has_no_effect_ties_are_deterministic(problem, budget, seed):
    _, n_actions, _, _, gamma = problem
    a = RobustTreePlanner(make_models(problem), range(n_actions), gamma=gamma, budget=budget, seed=0).plan(())
    b = RobustTreePlanner(make_models(problem), range(n_actions), gamma=gamma, budget=budget, seed=seed).plan(())
    assert a == b


def test_decision_is_a_frozen_value_with_a_json_dict():
    class Goal:
        def step(self, x, u):
            y = x + u
            return y, float(1.0 / (1.0 + abs(y[0] - 2.0)))

    actions = [np.array([-1.0]), np.array([0.0]), np.array([1.0])]
    decision = RobustTreePlanner([Goal()], actions, gamma=0.8, budget=20).plan(np.zeros(1))
    assert isinstance(decision, Decision)
    with pytest.raises(AttributeError):
        decision.lower = 0.0
    data = json.loads(json.dumps(decision.to_dict()))
    assert data["action"] == [1.0] and data["action_index"] == 2
    assert data["expansions"] == 20 and data["nodes"] == 61
    assert data["gap"] == decision.upper - decision.lower
    assert data["sequence"][0] == [1.0]
    assert len(data["action_lower"]) == len(data["action_upper"]) == 3


# ---------------------------------------------------------------------- validation
class Fixed:
    """Returns a fixed outcome for every action (for validation tests)."""

    def __init__(self, outcome):
        self.outcome = outcome

    def step(self, state, action):
        return self.outcome


class FixedBatch:
    def __init__(self, outcome):
        self.outcome = outcome

    def step(self, state, action):  # pragma: no cover - expand takes precedence
        raise AssertionError("step must not be called when expand exists")

    def expand(self, state, actions):
        return self.outcome


good = Fixed((0, 0.5))


@pytest.mark.parametrize("gamma", [0.0, 1.0, -0.2, 1.5])
def test_gamma_outside_open_unit_interval(gamma):
    with pytest.raises(InputError, match=rf"gamma must be in the open interval \(0, 1\), got {gamma}"):
        RobustTreePlanner([good], [0], gamma=gamma, budget=1)


def test_gamma_not_finite_or_not_a_number():
    with pytest.raises(NonFiniteError, match=r"gamma must be finite and in \(0, 1\), got nan"):
        RobustTreePlanner([good], [0], gamma=float("nan"), budget=1)
    with pytest.raises(InputError, match=r"gamma must be a real number in \(0, 1\), got 'x'"):
        OptimisticPlanner(good, [0], gamma="x", budget=1)


@pytest.mark.parametrize("budget", [0, -3, 2.5, True, "10"])
def test_budget_must_be_a_positive_integer(budget):
    with pytest.raises(InputError, match=rf"budget must be a positive integer, got {budget!r}"):
        RobustTreePlanner([good], [0, 1], gamma=0.9, budget=budget)


def test_seed_must_be_a_nonnegative_integer():
    with pytest.raises(InputError, match=r"seed must be an integer >= 0, got -1"):
        RobustTreePlanner([good], [0, 1], gamma=0.9, budget=1, seed=-1)


def test_empty_models_or_actions():
    with pytest.raises(InputError, match=r"models must be a non-empty sequence of models"):
        RobustTreePlanner([], [0, 1], gamma=0.9, budget=1)
    with pytest.raises(InputError, match=r"models must be a sequence of models, got int"):
        RobustTreePlanner(3, [0, 1], gamma=0.9, budget=1)
    with pytest.raises(InputError, match=r"actions must be a non-empty sequence"):
        RobustTreePlanner([good], [], gamma=0.9, budget=1)
    with pytest.raises(InputError, match=r"actions must be a sequence, got int"):
        OptimisticPlanner(good, 4, gamma=0.9, budget=1)


def test_model_without_step():
    with pytest.raises(InputError, match=r"models\[1\] has no callable step\(state, action\); got object"):
        RobustTreePlanner([good, object()], [0, 1], gamma=0.9, budget=1)


@pytest.mark.parametrize(
    "reward, shown", [(1.5, "1.5"), (-0.01, "-0.01"), (float("nan"), "nan"), (float("inf"), "inf")]
)
def test_reward_outside_unit_interval_names_model_and_action(reward, shown):
    planner = RobustTreePlanner([good, Fixed((0, reward))], ["a", "b"], gamma=0.9, budget=1)
    with pytest.raises(
        RewardRangeError,
        match=rf"models\[1\] returned reward {shown} for action 'a' \(index 0\); "
        r"rewards must be finite and in \[0, 1\]",
    ):
        planner.plan(0)


def test_reward_out_of_range_from_expand_names_model_and_action():
    bad = FixedBatch(([0, 0], np.array([0.5, 2.0]), np.array([False, False])))
    with pytest.raises(RewardRangeError, match=r"models\[0\] returned reward 2.0 for action 'b' \(index 1\)"):
        RobustTreePlanner([bad], ["a", "b"], gamma=0.9, budget=1).plan(0)


def test_non_numeric_reward():
    with pytest.raises(
        RewardRangeError, match=r"models\[0\] returned a non-numeric reward 'high' for action 7 \(index 0\)"
    ):
        RobustTreePlanner([Fixed((0, "high"))], [7], gamma=0.9, budget=1).plan(0)
    bad = FixedBatch(([0], ["high"], np.array([False])))
    with pytest.raises(RewardRangeError, match=r"models\[0\].expand returned non-numeric rewards \['high'\]"):
        RobustTreePlanner([bad], [7], gamma=0.9, budget=1).plan(0)


@pytest.mark.parametrize(
    "outcome, text",
    [
        ((0,), "a tuple of length 1"),
        ((0, 0.5, False, None), "a tuple of length 4"),
        ([0, 0.5], "an object of type list"),
        (0.5, "an object of type float"),
    ],
)
def test_step_with_wrong_arity(outcome, text):
    with pytest.raises(
        InputError,
        match=rf"models\[0\].step\(state, action\) must return \(next_state, reward\) or "
        rf"\(next_state, reward, terminal\), got {text} for action 'x' \(index 0\)",
    ):
        RobustTreePlanner([Fixed(outcome)], ["x"], gamma=0.9, budget=1).plan(0)


def test_step_with_non_boolean_terminal():
    with pytest.raises(
        InputError, match=r"models\[0\].step returned terminal='yes' for action 'x' \(index 0\); expected a bool"
    ):
        RobustTreePlanner([Fixed((0, 0.5, "yes"))], ["x"], gamma=0.9, budget=1).plan(0)
    # 0/1 integers and numpy booleans are accepted as flags.
    assert RobustTreePlanner([Fixed((0, 0.5, np.True_))], ["x"], gamma=0.9, budget=1).plan(0).solved is False
    assert RobustTreePlanner([Fixed((0, 0.5, 1))], ["x"], gamma=0.9, budget=3).plan(0).solved is True


@pytest.mark.parametrize(
    "outcome, error, text",
    [
        (
            ([0, 0], np.array([0.5, 0.5])),
            InputError,
            r"models\[0\].expand\(state, actions\) must return a tuple \(next_states, rewards, terminals\), got a tuple of length 2",
        ),
        (
            (iter([0, 0]), np.array([0.5, 0.5]), np.array([False, False])),
            InputError,
            r"models\[0\].expand next_states must be a sequence of 2 states, got list_iterator",
        ),
        (
            ([0], np.array([0.5, 0.5]), np.array([False, False])),
            DimensionError,
            r"models\[0\].expand returned 1 next states for 2 actions",
        ),
        (
            ([0, 0], np.array([0.5]), np.array([False, False])),
            DimensionError,
            r"models\[0\].expand rewards must have shape \(2,\), got shape \(1,\)",
        ),
        (
            ([0, 0], np.array([0.5, 0.5]), np.array([[False, False]])),
            DimensionError,
            r"models\[0\].expand terminals must have shape \(2,\), got shape \(1, 2\)",
        ),
        (
            ([0, 0], np.array([0.5, 0.5]), np.array([0, 1])),
            InputError,
            r"models\[0\].expand terminals must be a bool array, got dtype int",
        ),
    ],
)
def test_expand_protocol_violations(outcome, error, text):
    with pytest.raises(error, match=text):
        RobustTreePlanner([FixedBatch(outcome)], ["a", "b"], gamma=0.9, budget=1).plan(0)


@pytest.mark.parametrize(
    "name, value",
    [("budget", 7), ("gamma", 0.5), ("models", (good,)), ("actions", (0,)), ("seed", 1), ("engine", "python")],
)
def test_planner_settings_are_read_only(name, value):
    planner = RobustTreePlanner([good], [0, 1], gamma=0.9, budget=3)
    before = getattr(planner, name)
    with pytest.raises(AttributeError):
        setattr(planner, name, value)
    assert getattr(planner, name) == before


def test_an_absurd_budget_is_rejected_naming_the_argument():
    with pytest.raises(InputError, match=r"budget must be at most 1073741823 with 2 actions .* got 1000000000000"):
        RobustTreePlanner([good], [0, 1], gamma=0.9, budget=10**12)
    # the largest accepted budget builds its tree lazily: a search that is solved at once allocates little
    ones = OptimisticPlanner(Fixed((0, 1.0, True)), [0, 1], gamma=0.9, budget=(2**31 - 2) // 2)
    decision = ones.plan(0)
    assert decision.solved and decision.expansions == 1 and decision.lower == decision.upper == 1.0
