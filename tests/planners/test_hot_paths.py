"""The planner's fast paths give the same numbers as the general ones, bit for bit.

- linked `IntervalModel`s: one `BatchedTransitions.expand_all` per expansion vs each
  model's own ``expand`` (both on the Python engine);
- the rewards' bounding-box pre-check of static obstacles: a batch of boxes vs each box alone.

The compiled transitions against the models': tests/planners/test_compiled_engine.py.
"""

from unittest import mock

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.planners import RobustTreePlanner
from minimaxplan.planners.interval_model import IntervalModel
from minimaxplan.scenarios.geometry import CircularObstacles, MovingObstacles
from minimaxplan.scenarios.rewards import GoalReward

from ._systems import random_controllers, random_system

seeds = st.integers(0, 2**31 - 1)


def random_goal_reward(rng, with_moving):
    n = int(rng.integers(1, 8))
    obstacles = CircularObstacles(rng.uniform(-3, 3, (n, 2)), rng.uniform(0.1, 1.0, n))
    moving = None
    if with_moving:
        moving = MovingObstacles(
            rng.uniform(-3, 3, (2, 2)), rng.uniform(-1, 1, (2, 2)), [0.2, 0.3], velocity_uncertainty=0.1, dt=0.1
        )
    return GoalReward(
        rng.uniform(-4, 4, 2), obstacles=obstacles, moving_obstacles=moving, robot_radius=float(rng.uniform(0, 0.4))
    )


TREE_FIELDS = (
    "returns",
    "terminal",
    "parent",
    "action",
    "depth",
    "first_child",
    "lower",
    "upper",
    "leaf_lower",
    "leaf_upper",
    "expanded",
    "any_terminated",
)


def tree_arrays(planner):
    """Every array of the planner's last tree and every model's state at every node, as bytes."""
    tree = planner.tree
    return (
        [getattr(tree, name).tobytes() for name in TREE_FIELDS],
        [[np.asarray(state.z).tobytes() for state in states] for states in tree.states],
    )


class OneModel:
    """One model of a linked group seen through the per-model protocol only (``step``, ``expand``)."""

    def __init__(self, model):
        self.model = model

    def step(self, state, action):
        return self.model.step(state, action)

    def expand(self, state, actions):
        return self.model.expand(state, actions)


@given(seeds, st.booleans(), st.integers(1, 3))
def test_linked_models_joint_path_equals_per_model_protocol(seed, with_moving, substeps):
    rng = np.random.default_rng(seed)
    system = random_system(rng, p=4)
    controllers = random_controllers(rng, system)
    hypotheses = [(system, None), (random_system(rng, p=4, q=system.ninputs), None)]
    reward = random_goal_reward(rng, with_moving)
    models = IntervalModel.linked(hypotheses, reward, controllers, substeps=substeps)
    planner = RobustTreePlanner(models, models[0].actions, gamma=0.85, budget=25, engine="python")
    per_model = RobustTreePlanner([OneModel(m) for m in models], models[0].actions, gamma=0.85, budget=25)
    centre = rng.uniform(-3, 3, 4)
    root = models[0].initial_state(centre - 0.1, centre + 0.1, time=int(rng.integers(0, 5)))
    expand_all = models[0].group.expand_all
    with mock.patch.object(models[0].group, "expand_all", side_effect=expand_all) as joint:
        fast = planner.plan(root)
    assert joint.call_count > 0  # the batched path is taken
    general = per_model.plan(root)
    assert planner.engine_used == per_model.engine_used == "python"
    assert fast == general
    assert tree_arrays(planner) == tree_arrays(per_model)


@given(seeds, st.booleans(), st.floats(0.001, 2.0), st.integers(0, 20))
def test_batched_box_minimum_equals_each_box_alone(seed, with_moving, spread, t):
    """A batch whose bounding box meets an obstacle that only some (or none) of its boxes meet."""
    rng = np.random.default_rng(seed)
    reward = random_goal_reward(rng, with_moving)
    # boxes clustered around a point near an obstacle's reach
    centre = reward.obstacles.centers[0] + rng.normal(size=2) * (reward.obstacles.radii[0] + reward.robot_radius + 0.2)
    shape = (int(rng.integers(1, 4)), int(rng.integers(1, 5)))
    lower = np.concatenate(
        [centre + rng.uniform(-spread, spread, shape + (2,)), rng.uniform(-1, 1, shape + (2,))], axis=-1
    )
    upper = lower + rng.uniform(0, spread / 4, shape + (4,))
    minimum, collided = reward.box_minimum_raw(lower, upper, t)
    assert minimum.shape == collided.shape == shape and collided.dtype == bool
    for index in np.ndindex(shape):
        alone_minimum, alone_collided = reward.box_minimum_raw(lower[index][None], upper[index][None], t)
        assert minimum[index] == alone_minimum[0] and collided[index] == alone_collided[0]
        # and the single box against the discs directly (no pre-check involved)
        lo, hi = lower[index][:2], upper[index][:2]
        gap = np.maximum(np.maximum(lo - reward.obstacles.centers, reward.obstacles.centers - hi), 0.0)
        hits_static = bool(np.any((gap * gap).sum(axis=-1) <= (reward.obstacles.radii + reward.robot_radius) ** 2))
        if not with_moving:
            assert collided[index] == hits_static
        elif hits_static:
            assert collided[index]
