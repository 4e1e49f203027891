"""Theorem 3 (eq. (19)) and Lemma 1's depth bound, checked against exact brute force.

The models are random finite games: deterministic reward tables indexed by the action
path, M in 1..4 models, |A| in 2..3 actions, random terminal transitions, and every
model terminal at depth H. Rewards past a model's terminal transition are 0, so the
infinite-horizon robust value ``sup_a min_m sum_n gamma^n r_n^m`` is exactly the max
over the |A|^H full paths, which brute force enumerates. The brute force sums in the
same order as the planner (``R += gamma**n * r``), so every comparison is exact.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.planners import RobustTreePlanner


class TableModel:
    """A model whose state is the action path; rewards and terminals come from tables.

    Raises AssertionError if it is stepped from a state after its terminal transition
    (the planner promises never to do that).
    """

    def __init__(self, rewards: dict, terminals: dict) -> None:
        self.rewards = rewards
        self.terminals = terminals

    def step(self, state, action):
        assert not (state and self.terminals[state]), f"stepped after a terminal transition at {state}"
        path = state + (action,)
        return path, self.rewards[path], self.terminals[path]


class Game:
    """M reward tables over all paths of length 1..H, and their exact robust values."""

    def __init__(self, n_models: int, n_actions: int, horizon: int, gamma: float, seed: int, p_terminal: float):
        rng = np.random.default_rng(seed)
        self.n_models, self.n_actions, self.horizon, self.gamma = n_models, n_actions, horizon, gamma
        self.models = []
        for _ in range(n_models):
            rewards, terminals = {}, {}
            for length in range(1, horizon + 1):
                for path in itertools.product(range(n_actions), repeat=length):
                    kind = rng.integers(3)  # rewards at their extremes 0 and 1 are frequent
                    rewards[path] = 0.0 if kind == 0 else 1.0 if kind == 1 else float(rng.random())
                    terminals[path] = bool(length == horizon or rng.random() < p_terminal)
            self.models.append(TableModel(rewards, terminals))
        self.values = self._brute_force()

    def returns(self, path) -> list[float]:
        """Each model's discounted return of a full path (0 rewards after terminal)."""
        out = []
        for model in self.models:
            total, done = 0.0, False
            for n in range(len(path)):
                r = 0.0 if done else model.rewards[path[: n + 1]]
                total = total + (self.gamma**n) * r
                done = done or model.terminals[path[: n + 1]]
            out.append(total)
        return out

    def _brute_force(self) -> dict:
        """``values[p] = max over full paths extending p of min_m return`` for every prefix p."""
        values: dict = {}
        for path in itertools.product(range(self.n_actions), repeat=self.horizon):
            value = min(self.returns(path))
            for length in range(self.horizon + 1):
                prefix = path[:length]
                if prefix not in values or value > values[prefix]:
                    values[prefix] = value
        return values

    def internal_nodes(self) -> int:
        """Number of nodes of depth < H (an upper bound on useful expansions)."""
        return sum(self.n_actions**depth for depth in range(self.horizon))


@st.composite
def games(draw, max_cells: int = 800):
    n_actions = draw(st.integers(2, 3))
    max_horizon = 6 if n_actions == 2 else 5
    horizon = draw(st.integers(3, max_horizon))
    n_models = draw(st.integers(1, 4))
    gamma = draw(st.floats(0.5, 0.95))
    seed = draw(st.integers(0, 2**32 - 1))
    p_terminal = draw(st.sampled_from([0.0, 0.05, 0.15, 0.4]))
    return Game(n_models, n_actions, horizon, gamma, seed, p_terminal)


def budgets():
    """A budget as a fraction of the finite tree's internal nodes, so that some
    searches stop early (solved) and most do not."""
    return st.floats(0.02, 1.0)


def budget_for(game: Game, fraction: float) -> int:
    return max(1, math.ceil(fraction * game.internal_nodes()))


def plan(game: Game, budget: int):
    planner = RobustTreePlanner(game.models, range(game.n_actions), gamma=game.gamma, budget=budget)
    decision = planner.plan(())
    return planner.tree, decision


@given(game=games(), fraction=budgets())
def test_bounds_bracket_the_exact_robust_value_at_every_node(game, fraction):
    budget = budget_for(game, fraction)
    # eq. (19): L_a <= J_a <= T_a, for the root and for every node of the tree.
    tree, decision = plan(game, budget)
    assert decision.lower == tree.lower[0] and decision.upper == tree.upper[0]
    for node in range(tree.size):
        exact = game.values[tree.path(node)]
        assert tree.lower[node] <= exact <= tree.upper[node], (node, tree.path(node))
    assert decision.lower <= game.values[()] <= decision.upper


@given(game=games(), fraction=budgets())
def test_robust_regret_of_the_chosen_action_is_at_most_the_gap(game, fraction):
    budget = budget_for(game, fraction)
    _, decision = plan(game, budget)
    first_action_values = [game.values[(a,)] for a in range(game.n_actions)]
    regret = max(first_action_values) - first_action_values[decision.action_index]
    assert regret >= 0.0
    assert regret <= decision.upper - decision.lower
    # The chosen action is the root child of largest lower bound, first on ties.
    assert decision.action_index == int(np.argmax(decision.action_lower))
    assert decision.lower == max(decision.action_lower)


@settings(max_examples=25)
@given(game=games(), max_budget=st.integers(2, 30))
def test_tree_grows_by_prefix_and_bounds_are_monotone_in_the_budget(game, max_budget):
    previous_tree, previous = plan(game, 1)
    for budget in range(2, max_budget + 1):
        tree, decision = plan(game, budget)
        n = previous_tree.size
        assert tree.size >= n
        assert [tree.path(i) for i in range(n)] == [previous_tree.path(i) for i in range(n)]
        assert np.array_equal(tree.expanded[: len(previous_tree.expanded)], previous_tree.expanded)
        for name in ("parent", "action", "depth", "returns", "terminal", "leaf_lower", "leaf_upper"):
            assert np.array_equal(getattr(tree, name)[:n], getattr(previous_tree, name)[:n]), name
        assert decision.lower >= previous.lower
        assert decision.upper <= previous.upper
        # eq. (19) for every node of the smaller tree: L_a(k) <= L_a(K), T_a(K) <= T_a(k).
        assert np.all(np.asarray(tree.lower[:n]) >= np.asarray(previous_tree.lower[:n]))
        assert np.all(np.asarray(tree.upper[:n]) <= np.asarray(previous_tree.upper[:n]))
        previous_tree, previous = tree, decision


@given(game=games())
def test_a_budget_beyond_the_finite_tree_recovers_the_exact_value(game):
    # Remark 4: with enough budget the robust value is recovered exactly.
    budget = game.internal_nodes() + 1
    _, decision = plan(game, budget)
    assert decision.solved
    assert decision.expansions < budget
    assert decision.lower == decision.upper == game.values[()]
    assert game.values[tuple(decision.sequence_indices)] == game.values[()]


@given(game=games(), fraction=budgets())
def test_gap_is_at_most_the_tail_below_the_deepest_expanded_node(game, fraction):
    budget = budget_for(game, fraction)
    # Appendix C: U_root - L_root <= gamma^d / (1 - gamma), d the depth of the
    # deepest expanded node (tree depth - 1). The two sides are computed with
    # different roundings; allow a few ulps of the largest value 1 / (1 - gamma).
    tree, decision = plan(game, budget)
    deepest_expanded = max(int(tree.depth[i]) for i in tree.expanded)
    assert deepest_expanded == decision.depth - 1
    rounding = 4 * np.finfo(float).eps / (1.0 - game.gamma)
    assert decision.upper - decision.lower <= game.gamma**deepest_expanded / (1.0 - game.gamma) + rounding


@given(game=games(), fraction=budgets())
def test_best_sequence_attains_the_root_lower_bound(game, fraction):
    budget = budget_for(game, fraction)
    # Following the returned sequence collects at least `lower` under every model.
    _, decision = plan(game, budget)
    path = tuple(decision.sequence_indices)
    assert path[0] == decision.action_index
    collected = []
    for model in game.models:
        total, done = 0.0, False
        for n in range(len(path)):
            r = 0.0 if done else model.rewards[path[: n + 1]]
            total = total + (game.gamma**n) * r
            done = done or model.terminals[path[: n + 1]]
        collected.append(total)
    assert min(collected) == decision.lower
    assert game.values[path] >= decision.lower


def test_single_branch_of_ones_reference_values():
    # One action always pays 1, the other 0: OPD follows the paying branch and after
    # K expansions knows lower = sum_{n<K} gamma^n, upper = 1 / (1 - gamma) exactly.
    gamma, budget = 0.8, 12

    class Chain:
        def step(self, state, action):
            return state + 1, float(action == 1)

    planner = RobustTreePlanner([Chain()], [0, 1], gamma=gamma, budget=budget)
    decision = planner.plan(0)
    expected_lower = 0.0
    for n in range(budget):
        expected_lower = expected_lower + gamma**n * 1.0
    assert decision.action == 1
    assert decision.depth == budget
    assert decision.sequence == (1,) * budget
    assert decision.lower == expected_lower
    assert math.isclose(decision.upper, 1.0 / (1.0 - gamma), rel_tol=0, abs_tol=1e-12)
    assert decision.upper <= 1.0 / (1.0 - gamma)
