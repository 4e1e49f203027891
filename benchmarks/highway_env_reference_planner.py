"""A reference robust planner made of highway-env's own classes (issue 12, the decision-time benchmark).

What it mirrors: the public reference agents' construction (rl-agents' interval robust
planner over its deterministic optimistic planner, with highway-env's ``IntervalVehicle``
as the interval model). The root is a copy of ``env.unwrapped`` made with highway-env's
own ``simplify()`` (vehicles beyond ``PERCEPTION_DISTANCE`` dropped) and
``change_vehicles(IntervalVehicle)`` (every other vehicle replaced by
``IntervalVehicle.create_from(v)``: its true lane, target speed, route and timer, the
class's prior parameter boxes, the class-nominal parameters), stepped at one decision per
``env.step`` (``policy_frequency`` 1: 5 simulation steps on highway-fast-v0, 15 on
intersection-v0). Every tree node holds such an environment; expanding a leaf deep-copies
its environment once per action and calls ``env.step(meta_action)`` on the copy (its
other vehicles advance their intervals with highway-env's per-step Python interval code,
``IntervalVehicle.step`` in its default ``partial`` mode, and store their trajectories).

The reward of a transition is the library's driving reward's pessimistic value, as in
`minimaxplan.analysis.road_planning`'s planner: 0 and terminal when the ego may have
collided, else `DrivingReward.free_value` of the ego's state after the decision (the
same `DrivingReward` as the library's planner's, so the same weights). "May have
collided" is highway-env's own worst-case interval check,
``IntervalVehicle.handle_collisions(ego)`` (the ego's rectangle against the vehicle's
rectangle projected into its position interval), which highway-env's ``Road.step`` calls
only for a vehicle *before* the ego in ``road.vehicles``: the root copy therefore puts
the ego last (``change_vehicles`` keeps the ego first on highway-fast-v0, where the
interval check would never run), or highway-env's own ``on_road`` is False.

The search is `minimaxplan.planners.RobustTreePlanner`'s rule with one model: K
expansions, each of the leaf of largest b-value ``R + gamma^l / (1 - gamma)`` (``R``
alone when terminal), ties to the lexicographically smallest action path; lower bound
``R``; internal nodes the max over children of both; it stops early once the root's
lower bound reaches its upper bound; the root action of largest lower bound (ties: the
smallest index). The same depth rule: the library's reward is 0 (terminal) beyond its
obstacle table of ``horizon_decisions`` decisions, so a transition into depth
``horizon_decisions + 1`` is 0 and terminal here too (without stepping a copy).

What it does not mirror: the library's planner's ego is its own compiled bicycle and
controllers (`BicycleModel`), not highway-env's ``MDPVehicle``, so the two trees hold
different ego trajectories and may reach different decisions (the benchmark compares
cost, not decisions); its transition reward is the minimum over the decision's sub-step
states, here the state after the decision only (``env.step`` returns only that); it adds
continuation lower bounds (`BicycleModel.fallback_values`, rolled out per child) that
the reference does not compute, which only makes the library's side slower; the
reference's interval boxes are highway-env's (not sound on these scenes:
benchmarks/results/highway_env.md), the library's are `forecast_traffic`'s.

Benchmark code only: nothing in the library imports it. No code is copied from the
public repositories.
"""

from __future__ import annotations

import contextlib
import copy
import io
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "INTERVAL_VEHICLE",
    "interval_root",
    "ReferenceDecision",
    "HighwayEnvReferencePlanner",
    "state_reward_of",
    "driving_reward_of",
]

#: highway-env's interval-predicting vehicle class (the reference of the paper's eq. (9)).
INTERVAL_VEHICLE = "highway_env.vehicle.uncertainty.prediction.IntervalVehicle"


def interval_root(env: Any, *, simplify: bool = True) -> Any:
    """The reference's root environment: a copy of ``env.unwrapped`` with interval vehicles, the ego last.

    Parameters
    ----------
    env : gymnasium.Env
        A highway-env environment (not modified).
    simplify : bool
        Drop the vehicles beyond highway-env's ``PERCEPTION_DISTANCE`` first (its
        ``simplify()``, as the reference agents' preprocessing does).

    Returns
    -------
    highway_env.envs.common.abstract.AbstractEnv
        Its own copy: every other vehicle an ``IntervalVehicle``, the ego the last of
        ``road.vehicles`` (so that highway-env's ``Road.step`` runs the interval
        collision check against it), ``policy_frequency`` 1 (one decision per
        ``env.step``).
    """
    base = env.unwrapped
    twin = base.simplify() if simplify else copy.deepcopy(base)
    twin = twin.change_vehicles(INTERVAL_VEHICLE)
    ego = twin.vehicle
    twin.road.vehicles = [v for v in twin.road.vehicles if v is not ego] + [ego]
    twin.config["policy_frequency"] = 1
    return twin


def state_reward_of(free_value: Callable[[np.ndarray], np.ndarray]) -> Callable[[Any], tuple[float, bool]]:
    """The reference's transition reward from a reward of ego states without collision.

    Parameters
    ----------
    free_value : callable
        ``states (n, 4) -> values (n,)`` in [0, 1], the ego's ``(x, y, v, psi)``.

    Returns
    -------
    callable
        ``env -> (value, terminal)``: ``(0, True)`` when the copy's ego crashed
        (highway-env's interval check) or left the road (its ``on_road``), else
        ``free_value`` of the ego's state and False.
    """

    def value(env: Any) -> tuple[float, bool]:
        ego = env.vehicle
        if ego.crashed or not ego.on_road:
            return 0.0, True
        state = np.array([[ego.position[0], ego.position[1], ego.speed, ego.heading]], dtype=float)
        return float(free_value(state)[0]), False

    return value


def driving_reward_of(reward: Any) -> Callable[[Any], tuple[float, bool]]:
    """`state_reward_of` the library's `DrivingReward` (its ``free_value``; the obstacle table is not read).

    Parameters
    ----------
    reward : minimaxplan.scenarios.DrivingReward
        The library's planner's reward.
    """
    return state_reward_of(reward.free_value)


class _Node:
    __slots__ = ("parent", "path", "depth", "children", "env", "ret", "terminal", "lower", "upper")

    def __init__(self, parent, path, env, ret, terminal, upper) -> None:
        self.parent = parent
        self.path = path
        self.depth = len(path)
        self.children: list[_Node] = []
        self.env = env
        self.ret = ret
        self.terminal = terminal
        self.lower = ret
        self.upper = upper


@dataclass(frozen=True)
class ReferenceDecision:
    """What `HighwayEnvReferencePlanner.plan` decided.

    Attributes
    ----------
    action : int
        Index into the planner's ``actions`` of the root action of largest lower bound.
    lower, upper : float
        The root's bounds.
    expansions : int
        Leaves expanded (at most the budget).
    depth : int
        The deepest node.
    solved : bool
        Stopped early (lower == upper at the root).
    env_steps : int
        ``env.step`` calls on copies.
    """

    action: int
    lower: float
    upper: float
    expansions: int
    depth: int
    solved: bool
    env_steps: int

    def to_dict(self) -> dict:
        """The fields as a dict."""
        return {
            "action": self.action,
            "lower": self.lower,
            "upper": self.upper,
            "expansions": self.expansions,
            "depth": self.depth,
            "solved": self.solved,
            "env_steps": self.env_steps,
        }


class HighwayEnvReferencePlanner:
    """Robust optimistic planning over deep copies of a highway-env environment (see the module docstring).

    Parameters
    ----------
    actions : sequence of int
        highway-env's meta-action indices, in the library's planner's order (its ties).
    reward : callable
        ``env -> (value, terminal)`` after a decision, value in [0, 1] (`driving_reward_of`).
    gamma : float
        Discount factor in (0, 1).
    budget : int
        K >= 1 expansions.
    horizon_decisions : int
        Decisions with a reward (the library's obstacle table); deeper transitions are 0, terminal.
    """

    def __init__(
        self,
        actions: Sequence[int],
        reward: Callable[[Any], tuple[float, bool]],
        *,
        gamma: float,
        budget: int,
        horizon_decisions: int,
    ) -> None:
        self.actions = tuple(int(a) for a in actions)
        if not self.actions:
            raise ValueError("actions must be non-empty")
        if not 0.0 < gamma < 1.0:
            raise ValueError(f"gamma must lie in (0, 1), got {gamma}")
        if int(budget) < 1 or int(horizon_decisions) < 1:
            raise ValueError(f"budget and horizon_decisions must be >= 1, got {budget}, {horizon_decisions}")
        self.reward = reward
        self.gamma = float(gamma)
        self.budget = int(budget)
        self.horizon_decisions = int(horizon_decisions)
        self.root: _Node | None = None

    def plan(self, env: Any) -> ReferenceDecision:
        """Search from ``env`` (`interval_root`; never stepped itself) with the full budget.

        Parameters
        ----------
        env : AbstractEnv
            The root environment.

        Returns
        -------
        ReferenceDecision
        """
        gamma = self.gamma
        root = self.root = _Node(None, (), env, 0.0, False, 1.0 / (1.0 - gamma))
        leaves = [root]
        expansions, steps, solved = 0, 0, False
        quiet = contextlib.redirect_stdout(io.StringIO())  # highway-env's LPV prints "Non Metzler A0 ..."
        with quiet:
            for _ in range(self.budget):
                if root.lower >= root.upper:
                    solved = True
                    break
                leaf = min(leaves, key=lambda node: (-node.upper, node.path))
                leaves.remove(leaf)
                steps += self._expand(leaf)
                leaves.extend(leaf.children)
                expansions += 1
                node: _Node | None = leaf
                while node is not None:
                    node.lower = max(child.lower for child in node.children)
                    node.upper = max(child.upper for child in node.children)
                    node = node.parent
        children = root.children
        action = max(range(len(children)), key=lambda a: (children[a].lower, -a))
        depth = max(node.depth for node in leaves)
        return ReferenceDecision(action, root.lower, root.upper, expansions, depth, solved, steps)

    def _expand(self, leaf: _Node) -> int:
        gamma, depth = self.gamma, leaf.depth
        discount = gamma**depth
        tail = gamma ** (depth + 1) / (1.0 - gamma)
        steps = 0
        for a, meta in enumerate(self.actions):
            if depth + 1 > self.horizon_decisions:  # beyond the library's obstacle table: 0, terminal
                child_env, reward, terminal = None, 0.0, True
            else:
                child_env = copy.deepcopy(leaf.env)  # the reference agents' per-node copy
                child_env.step(meta)
                steps += 1
                reward, terminal = self.reward(child_env)
            ret = leaf.ret + discount * reward
            leaf.children.append(
                _Node(leaf, leaf.path + (a,), child_env, ret, terminal, ret if terminal else ret + tail)
            )
        return steps

    def expanded_nodes(self) -> int:
        """Nodes of the last tree that have children (the expansions made)."""
        if self.root is None:
            return 0
        count, stack = 0, [self.root]
        while stack:
            node = stack.pop()
            if node.children:
                count += 1
                stack.extend(node.children)
        return count
