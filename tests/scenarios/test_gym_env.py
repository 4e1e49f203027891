"""The Gymnasium interface (the ``gym`` extra: these tests fail, not skip, when CI=true)."""

import os
import warnings

import numpy as np
import pytest

if os.environ.get("CI") == "true":
    import gymnasium
else:
    gymnasium = pytest.importorskip("gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

from minimaxplan.models import InputError  # noqa: E402
from minimaxplan.scenarios.gym_env import ENV_ID, OBSERVED_OBSTACLES, RobotNavigationEnv  # noqa: E402
from minimaxplan.scenarios.worlds import make_world  # noqa: E402


@pytest.mark.parametrize(
    "kind, measurement", [("static", "uniform"), ("pedestrian", "uniform"), ("pedestrian", "gaussian")]
)
def test_env_passes_the_gymnasium_checker(kind, measurement):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the checker's warnings count as failures too
        check_env(RobotNavigationEnv(kind, measurement=measurement), skip_render_check=True)


def test_env_is_registered():
    env = gymnasium.make(ENV_ID, kind="pedestrian")
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert info["outcome"] == "running"


def test_reset_with_a_seed_builds_that_world_and_steps_it_for_one_period():
    env = RobotNavigationEnv("static")
    obs, info = env.reset(seed=42)
    world = make_world("static", 42)
    assert np.array_equal(env.world.goal, world.goal)
    assert np.array_equal(info["true_theta"], world.true_theta)
    # observation: measured state within the noise bound, goal relative to it
    np.testing.assert_allclose(obs[:4], world.state, atol=0.01 + 1e-6)
    np.testing.assert_allclose(obs[4:6], world.goal - world.state[:2], atol=0.01 + 1e-5)
    obstacles = obs[6 : 6 + 4 * OBSERVED_OBSTACLES].reshape(OBSERVED_OBSTACLES, 4)
    assert np.all(obstacles[:, 3] == 1.0)  # a static world has >= 10 obstacles
    clearance = np.linalg.norm(obstacles[:, :2], axis=1) - obstacles[:, 2]
    assert np.all(np.diff(clearance) >= -0.03)  # nearest first (up to measurement noise)

    _, reward, terminated, truncated, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
    for _ in range(5):
        world.apply([1.0, 0.0])
    assert env.world.step_index == 5
    np.testing.assert_array_equal(env.world.state, world.state)
    assert 0.0 < reward <= 1.0 and not terminated and not truncated


def test_same_seed_same_episode():
    def rollout(seed):
        env = RobotNavigationEnv("pedestrian")
        obs, _ = env.reset(seed=seed)
        trace = [obs]
        for k in range(20):
            obs, reward, terminated, truncated, _ = env.step(np.array([np.cos(k), np.sin(k)], dtype=np.float32))
            trace.append(np.append(obs, reward))
            if terminated or truncated:
                break
        return trace

    a, b = rollout(7), rollout(7)
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))


def test_episode_terminates_on_collision_with_zero_reward():
    env = RobotNavigationEnv("static")
    env.reset(seed=1)
    world = env.world
    c, r = world.obstacles.centers[0], world.obstacles.radii[0]
    world.state = np.concatenate([c - [r + 0.35, 0.0], [2.0, 0.0]])
    _, reward, terminated, truncated, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
    assert terminated and not truncated and info["outcome"] == "collision"
    assert reward < 1.0 / (1.0 + np.linalg.norm(world.goal - world.state[:2]))


def test_step_rejects_bad_actions_and_step_before_reset():
    env = RobotNavigationEnv("static")
    with pytest.raises(InputError, match="call reset"):
        env.step(np.zeros(2, dtype=np.float32))
    env.reset(seed=0)
    with pytest.raises(InputError, match=r"action must have shape \(2,\), got shape \(3,\)"):
        env.step(np.zeros(3))
    with pytest.raises(InputError, match=r"action must lie in \[-1.0, 1.0\]\^2"):
        env.step(np.array([2.0, 0.0]))
    with pytest.raises(InputError, match="kind must be one of"):
        RobotNavigationEnv("maze")


def test_scenarios_import_gymnasium_only_when_the_env_is_asked_for():
    import subprocess
    import sys

    code = (
        "import sys, minimaxplan.scenarios as s; assert 'gymnasium' not in sys.modules; "
        "env = s.RobotNavigationEnv; assert 'gymnasium' in sys.modules; print(env.__name__)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "RobotNavigationEnv"
