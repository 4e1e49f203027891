"""The compiled-reward protocol: registration, the numpy-facing loop, and the cache keys of its kernels."""

import types
from collections import namedtuple

import numpy as np
import pytest

from minimaxplan.kernels import (
    BoxReward,
    CompiledBoxReward,
    StateIndexedReward,
    UncheckedBoxReward,
    box_minima,
    box_minima_kernel,
    box_primitives,
    has_compiled_minimum,
    minimum_sources,
    register_reward_params,
    reward_protocol,
    sources_digest,
)
from minimaxplan.scenarios import compiled_rewards
from minimaxplan.scenarios.geometry import CircularObstacles, MovingObstacles
from minimaxplan.scenarios.rewards import GoalReward, SpeedLaneReward


def test_sources_digest_follows_file_contents(tmp_path):
    source = tmp_path / "reward_module.py"
    source.write_text("x = 1\n")
    before = sources_digest(str(source))
    assert sources_digest(str(source)) == before and 0 <= before < 2**63
    source.write_text("x = 2\n")
    assert sources_digest(str(source)) != before


def test_minimum_sources_name_the_kernels_files_and_the_family_module():
    for params_type in (compiled_rewards.GoalParams, compiled_rewards.SpeedLaneParams):
        assert minimum_sources(params_type) == [
            reward_protocol.__file__,
            box_primitives.__file__,
            compiled_rewards.__file__,
        ]


def test_registered_extra_sources_join_the_key_and_unknown_types_are_rejected(tmp_path):
    helper = tmp_path / "helper.py"
    helper.write_text("# a file the kernel calls into\n")
    module = types.ModuleType("user_rewards")
    module.__file__ = str(tmp_path / "user_rewards.py")
    params_type = namedtuple("UserParams", ["limit"], module="user_rewards")
    with pytest.raises(TypeError, match="UserParams is not registered"):
        minimum_sources(params_type)
    register_reward_params(params_type, sources=(helper,))
    assert has_compiled_minimum(params_type(1.0)) and not has_compiled_minimum((1.0,))
    with pytest.MonkeyPatch.context() as patch:
        patch.setitem(__import__("sys").modules, "user_rewards", module)
        assert minimum_sources(params_type)[2:] == [module.__file__, str(helper)]
    interactive = register_reward_params(namedtuple("InteractiveParams", ["limit"], module="__no_such_module__"))
    with pytest.raises(
        TypeError, match="InteractiveParams is defined in module '__no_such_module__', which has no source file"
    ):
        minimum_sources(interactive)


def test_the_numpy_facing_loop_is_keyed_by_the_sources_it_calls():
    """numba's disk cache tracks only a function's own file: the loop closes over a digest of its callees'.

    And each params type gets a cache index of its own (numba unpickles every signature
    of an index to load one, so a user's type must not share the families' index).
    """
    names = set()
    for params_type in (compiled_rewards.GoalParams, compiled_rewards.SpeedLaneParams):
        kernel = box_minima_kernel(params_type)
        cells = [cell.cell_contents for cell in kernel.py_func.__closure__ or ()]
        assert sources_digest(*minimum_sources(params_type)) in cells
        names.add(kernel.py_func.__qualname__)
    assert len(names) == 2 and all(name.startswith("box_minima_kernel.<locals>.box_minima_loop_") for name in names)


def test_box_minima_broadcasts_boxes_and_times():
    moving = MovingObstacles([[0.0, 0.0]], [[1.0, 0.0]], [0.3], velocity_uncertainty=0.2, dt=0.5)
    reward = GoalReward(
        [4.0, 4.0], obstacles=CircularObstacles([[2.0, 2.0]], [0.5]), moving_obstacles=moving, robot_radius=0.3
    )
    rng = np.random.default_rng(1)
    lower = rng.uniform(-1, 3, (3, 4, 2))
    upper = lower.max(axis=0, keepdims=True) + rng.uniform(0, 1, (1, 4, 2))  # (1, 4, 2) broadcasts against lower
    t = np.arange(4)
    minimum, collided = box_minima(reward.kernel_params, lower, upper, t)
    assert minimum.shape == collided.shape == (3, 4) and collided.dtype == bool
    for i, j in np.ndindex(3, 4):
        one = box_minima(reward.kernel_params, lower[i, j], upper[0, j], t[j])
        assert one[0].shape == () and (one[0], one[1]) == (minimum[i, j], collided[i, j])
    empty = box_minima(reward.kernel_params, np.zeros((0, 2)), np.zeros((0, 2)))
    assert empty[0].shape == empty[1].shape == (0,)
    with pytest.raises(TypeError, match="params has type tuple, for which no compiled box minimum is registered"):
        box_minima((1.0,), lower, upper)


def test_the_families_implement_the_compiled_protocol():
    class NumpyOnly:
        def box_minimum(self, lower, upper, t=0):
            return np.ones(np.shape(lower)[:-1]), np.zeros(np.shape(lower)[:-1], dtype=bool)

    for reward in (GoalReward([0.0, 0.0]), SpeedLaneReward(1.0, 2.0)):
        assert isinstance(reward, CompiledBoxReward) and has_compiled_minimum(reward.kernel_params)
        assert isinstance(reward, UncheckedBoxReward) and isinstance(reward, StateIndexedReward)
    for protocol in (CompiledBoxReward, UncheckedBoxReward, StateIndexedReward):
        assert isinstance(NumpyOnly(), BoxReward) and not isinstance(NumpyOnly(), protocol)


def test_the_planner_models_read_a_reward_only_through_its_declared_protocols():
    """A reward declaring only `BoxReward` is evaluated through box_minimum on the Python engine; one declaring
    `StateIndexedReward` is checked against the system's states; an `UncheckedBoxReward`'s raw minimum is the
    one the model calls."""
    from minimaxplan.models.errors import DimensionError, InputError
    from minimaxplan.planners.interval_model import _check_reward, _kernel_params

    class NumpyOnly:
        def box_minimum(self, lower, upper, t=0):
            return np.ones(np.shape(lower)[:-1]), np.zeros(np.shape(lower)[:-1], dtype=bool)

    class ReadsFive(NumpyOnly):
        min_state_dim = 5

    class WithRaw(NumpyOnly):
        def box_minimum_raw(self, lower, upper, t=0):
            return self.box_minimum(lower, upper, t)

    plain = NumpyOnly()
    assert _check_reward(plain, 4) == plain.box_minimum and _kernel_params(plain) is None
    raw = WithRaw()
    assert _check_reward(raw, 4) == raw.box_minimum_raw
    with pytest.raises(DimensionError, match="up to index 4, but the system has 4 states"):
        _check_reward(ReadsFive(), 4)
    assert _check_reward(ReadsFive(), 5) is not None
    goal = GoalReward([0.0, 0.0])
    assert _check_reward(goal, 4) == goal.box_minimum_raw and _kernel_params(goal) is goal.kernel_params
    with pytest.raises(InputError, match="callable box_minimum"):
        _check_reward(object(), 4)
