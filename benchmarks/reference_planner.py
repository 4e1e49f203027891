"""An in-repo reference planner built the way the public reference planners are.

rl-agents' deterministic and robust planners (with highway-env's ``IntervalVehicle``
as the interval model) store a simulator object in every tree node and, to expand a
leaf, deep-copy the leaf's simulator once per action (and per model) and call its
``step``; the simulator advances its one interval with per-step Python interval code
(highway-env's ``LPV.step`` rebuilds the positive and negative parts of the model
matrices at every step) and evaluates the reward on it. This module reproduces that
architecture around OUR model and reward mathematics (the same vertex-wise interval
bound and the same exact box minimum of the goal reward), so that it reaches the same
decisions as `minimaxplan.planners.RobustTreePlanner` on linked `IntervalModel`s and
the benchmark measures the architecture alone: simulator objects and deep copies
against batched arrays. It searches the same tree: expand the leaf of largest robust
b-value ``min_m (R_m + gamma^l / (1 - gamma) [m alive])``, ties to the
lexicographically smallest action path; lower bounds ``min_m R_m``; back-ups by max
over children; the action of largest lower bound at the root.

Benchmark code only: nothing in the library imports it. No code is copied from the
public repositories.
"""

from __future__ import annotations

import copy
import math

import numpy as np


class ReferenceIntervalEnv:
    """A simulator holding one box of robot states, stepped by per-step Python interval code.

    Parameters
    ----------
    vertex_matrices
        The state matrices at the vertices of the parameter polytope (list of (p, p)).
    B, D, w_low, w_high
        Input matrix, disturbance matrix and disturbance box.
    controls
        The constant control of each action.
    substeps
        Sub-steps per ``step``.
    goal, obstacles, robot_radius
        The goal reward ``beta(x) / (1 + ||pos - goal||)`` with discs ``(cx, cy, R)``.
    lower, upper, time
        The current box and sub-step index.
    """

    def __init__(
        self,
        vertex_matrices,
        B,
        D,
        w_low,
        w_high,
        controls,
        substeps,
        goal,
        obstacles,
        robot_radius,
        lower,
        upper,
        time=0,
    ):
        self.vertex_matrices = [np.array(m, dtype=float) for m in vertex_matrices]
        self.B = np.array(B, dtype=float)
        self.D = np.array(D, dtype=float)
        self.w_low = np.array(w_low, dtype=float)
        self.w_high = np.array(w_high, dtype=float)
        self.controls = [np.array(u, dtype=float) for u in controls]
        self.substeps = int(substeps)
        self.goal = (float(goal[0]), float(goal[1]))
        self.obstacles = [(float(cx), float(cy), float(r)) for cx, cy, r in obstacles]
        self.robot_radius = float(robot_radius)
        self.lower = np.array(lower, dtype=float)
        self.upper = np.array(upper, dtype=float)
        self.time = int(time)
        self.crashed = False

    def step(self, action: int):
        """Hold the action's control for ``substeps`` sub-steps; return (observation, reward, terminal)."""
        u = self.controls[action]
        worst, crashed = 1.0, False
        for _ in range(self.substeps):
            self._predict(u)
            self.time += 1
            reward, hit = self._reward()
            worst = min(worst, reward)
            crashed = crashed or hit
        self.crashed = crashed
        return (self.lower.copy(), self.upper.copy()), worst, crashed

    def _predict(self, u):
        lower, upper = self.lower, self.upper
        new_lower = new_upper = None
        for matrix in self.vertex_matrices:  # as LPV.step: the matrix parts are rebuilt at every step
            positive, negative = np.maximum(matrix, 0.0), np.maximum(-matrix, 0.0)
            candidate_lower = positive @ lower - negative @ upper
            candidate_upper = positive @ upper - negative @ lower
            if new_lower is None:
                new_lower, new_upper = candidate_lower, candidate_upper
            else:
                new_lower = np.minimum(new_lower, candidate_lower)
                new_upper = np.maximum(new_upper, candidate_upper)
        d_pos, d_neg = np.maximum(self.D, 0.0), np.maximum(-self.D, 0.0)
        drift = self.B @ u
        self.lower = new_lower + drift + (d_pos @ self.w_low - d_neg @ self.w_high)
        self.upper = new_upper + drift + (d_pos @ self.w_high - d_neg @ self.w_low)

    def _reward(self):
        x_lo, y_lo = float(self.lower[0]), float(self.lower[1])
        x_hi, y_hi = float(self.upper[0]), float(self.upper[1])
        for cx, cy, radius in self.obstacles:
            dx = max(x_lo - cx, cx - x_hi, 0.0)
            dy = max(y_lo - cy, cy - y_hi, 0.0)
            reach = radius + self.robot_radius
            if dx * dx + dy * dy <= reach * reach:
                return 0.0, True
        gx, gy = self.goal
        far_x = max(gx - x_lo, x_hi - gx)
        far_y = max(gy - y_lo, y_hi - gy)
        return 1.0 / (1.0 + math.hypot(far_x, far_y)), False


class _Node:
    __slots__ = (
        "parent",
        "path",
        "depth",
        "children",
        "envs",
        "returns",
        "terminal",
        "leaf_lower",
        "leaf_upper",
        "lower",
        "upper",
    )

    def __init__(self, parent, path, envs, returns, terminal, leaf_lower, leaf_upper):
        self.parent = parent
        self.path = path
        self.depth = len(path)
        self.children = []
        self.envs = envs
        self.returns = returns
        self.terminal = terminal
        self.leaf_lower = self.lower = leaf_lower
        self.leaf_upper = self.upper = leaf_upper


class ReferenceRobustPlanner:
    """Robust optimistic planning with a simulator per node, deep-copied at every expansion."""

    def __init__(self, n_actions: int, *, gamma: float, budget: int) -> None:
        self.n_actions = n_actions
        self.gamma = gamma
        self.budget = budget

    def plan(self, envs):
        """Search from the simulators ``envs`` (one per model); returns a small dict of the decision."""
        gamma, n_models = self.gamma, len(envs)
        root_upper = 1.0 / (1.0 - gamma)
        root = _Node(None, (), list(envs), [0.0] * n_models, [False] * n_models, 0.0, root_upper)
        leaves = [root]
        expansions = 0
        solved = False
        for _ in range(self.budget):
            leaf = min(leaves, key=lambda node: (-node.leaf_upper, node.path))
            if all(leaf.terminal):
                solved = True
                break
            leaves.remove(leaf)
            leaves.extend(self._expand(leaf))
            expansions += 1
            self._backup(leaf)
        children = root.children
        best = max(range(len(children)), key=lambda a: (children[a].lower, -a)) if children else None
        sequence, node = [], root
        while node.children:
            a = max(range(len(node.children)), key=lambda i: (node.children[i].lower, -i))
            sequence.append(a)
            node = node.children[a]
        return {
            "action": best,
            "lower": root.lower,
            "upper": root.upper,
            "expansions": expansions,
            "sequence": tuple(sequence),
            "solved": solved,
        }

    def _expand(self, leaf: _Node):
        gamma, depth = self.gamma, leaf.depth
        discount = gamma**depth
        tail = gamma ** (depth + 1) / (1.0 - gamma)
        for action in range(self.n_actions):
            envs, returns, terminal = [], [], []
            for m, env in enumerate(leaf.envs):
                if leaf.terminal[m]:
                    envs.append(env)
                    returns.append(leaf.returns[m])
                    terminal.append(True)
                    continue
                child_env = copy.deepcopy(env)  # the public reference's safe_deepcopy_env
                _, reward, done = child_env.step(action)
                envs.append(child_env)
                returns.append(leaf.returns[m] + discount * reward)
                terminal.append(bool(done))
            lower = min(returns)
            upper = min(r + (0.0 if t else tail) for r, t in zip(returns, terminal))
            upper = min(upper, leaf.leaf_upper)
            leaf.children.append(_Node(leaf, leaf.path + (action,), envs, returns, terminal, lower, upper))
        return leaf.children

    @staticmethod
    def _backup(node: _Node) -> None:
        while node is not None:
            node.lower = max(child.lower for child in node.children)
            node.upper = max(child.upper for child in node.children)
            node = node.parent
