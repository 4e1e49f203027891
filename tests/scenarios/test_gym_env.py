"""The Gymnasium interface (the ``gym`` extra: these tests fail, not skip, when CI=true)."""

import dataclasses
import warnings

import numpy as np
import pytest
from extras import require_extra

from minimaxplan.scenarios.driving_reward import true_reward, world_reward

gymnasium = require_extra("gymnasium")

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


# ------------------------------------------------------------------ road worlds
from minimaxplan.scenarios.gym_env import (  # noqa: E402
    OBSERVED_VEHICLES,
    ROAD_ENV_ID,
    RoadDrivingEnv,
)
from minimaxplan.scenarios.road_world import make_road_world  # noqa: E402


@pytest.mark.parametrize("kind", ["highway", "tjunction"])
def test_road_env_passes_the_gymnasium_checker(kind):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the checker's warnings count as failures too
        check_env(RoadDrivingEnv(kind), skip_render_check=True)


@pytest.mark.parametrize("kind", ["highway", "tjunction"])
def test_road_env_same_seed_same_episode(kind):
    def rollout(seed):
        env = RoadDrivingEnv(kind)
        obs, info = env.reset(seed=seed)
        trace = [np.append(obs, info["ids"])]
        for k in range(30):
            action = np.array([0.3 * np.sin(k), 0.02 * np.cos(k)], dtype=np.float32)
            obs, reward, terminated, truncated, info = env.step(action)
            trace.append(np.concatenate([obs, [reward, terminated, truncated], info["ids"]]))
            if terminated or truncated:
                break
        return trace, env.world

    (a, world_a), (b, world_b) = rollout(4), rollout(4)
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    np.testing.assert_array_equal(world_a.traffic.states, world_b.traffic.states)
    (c, _) = rollout(5)
    assert not np.array_equal(a[0], c[0])  # another seed, another episode


def test_road_env_observes_the_world_and_steps_it_for_one_period():
    env = RoadDrivingEnv("highway")
    obs, info = env.reset(seed=2)
    world = make_road_world("highway", 2)
    seen = world.measure()  # the same measurement stream as the env's first observation
    assert env.observation_space.contains(obs)
    np.testing.assert_allclose(obs[:4], seen.ego, rtol=1e-6)
    np.testing.assert_allclose(obs[:2], world.ego_state[:2], atol=0.1 + 1e-3)  # within the noise
    vehicles = obs[4:].reshape(OBSERVED_VEHICLES, 5)
    assert np.all(vehicles[:, 4] == 1.0)  # 15 vehicles on the highway: every slot is filled
    distance = np.linalg.norm(vehicles[:, :2], axis=1)
    assert np.all(np.diff(distance) >= 0)  # nearest first
    assert len(info["ids"]) == OBSERVED_VEHICLES and set(info["ids"]) <= set(seen.ids.tolist())
    j = int(np.flatnonzero(seen.ids == info["ids"][0])[0])
    np.testing.assert_allclose(vehicles[0, :2], seen.vehicles[j, :2] - seen.ego[:2], rtol=1e-5, atol=1e-3)

    _, reward, terminated, truncated, info = env.step(np.array([0.25, 0.0], dtype=np.float32))
    rewards = []
    for _ in range(5):
        world.apply([1.5, 0.0])  # the normalised action times the 6 m/s^2 bound
        rewards.append(true_reward(world))
    np.testing.assert_array_equal(env.world.traffic.states, world.traffic.states)
    assert reward == pytest.approx(np.mean(rewards), rel=1e-12)
    assert 0.0 < reward <= 1.0 and not terminated and not truncated and info["outcome"] == "running"
    # the highway reward: (1 + 0.4 v / 30 + 0.1 (2 - lane) / 2) / 1.5 (lane 0, the rightmost, preferred)
    x, y, v, _ = world.ego_state
    lane = np.clip(np.floor(y / 4 + 0.5), 0, 2)
    assert rewards[-1] == pytest.approx((1 + 0.4 * min(v / 30, 1) + 0.1 * (2 - lane) / 2) / 1.5, rel=1e-12)


def test_road_env_ends_off_road_with_zero_reward():
    env = RoadDrivingEnv("highway")
    env.reset(seed=1)
    _, reward, terminated, truncated = 0.0, 1.0, False, False
    for _ in range(40):  # full steering to the left: the ego leaves the road
        _, reward, terminated, truncated, info = env.step(env.action_space.high)
        if terminated or truncated:
            break
    assert terminated and not truncated and info["outcome"] in ("off_road", "collision")
    assert true_reward(env.world) == 0.0


def test_tjunction_reward_grows_with_the_progress_to_the_goal():
    world = make_road_world("tjunction", 0)
    start = world.ego_state[:2]
    assert true_reward(world) == pytest.approx(1 / 1.4, rel=1e-12)  # at the start: no progress yet
    region = world_reward(world).goal  # where the world counts the goal as reached
    nearest = np.clip(start, region[:2], region[2:])  # so every point between start and it is nearest to it too
    states = world.traffic.states.copy()
    states[0, :2] = (start + nearest) / 2
    world.traffic = dataclasses.replace(world.traffic, states=states)
    assert true_reward(world) == pytest.approx((1 + 0.4 * 0.5) / 1.4, rel=1e-12)
    states[0, :2] = world.road.position_at(world.goal_lanes[0], world.goal_s + 1.0)
    world.traffic = dataclasses.replace(world.traffic, states=states)
    assert true_reward(world) == 1.0


def test_road_env_rejects_bad_actions_and_step_before_reset():
    env = RoadDrivingEnv("tjunction")
    with pytest.raises(InputError, match="call reset"):
        env.step(np.zeros(2, dtype=np.float32))
    env.reset(seed=0)
    with pytest.raises(InputError, match=r"action must have shape \(2,\), got shape \(3,\)"):
        env.step(np.zeros(3))
    with pytest.raises(InputError, match=r"action must lie in \[-1, 1\]\^2"):
        env.step(np.array([1.5, 0.0]))
    with pytest.raises(InputError, match="kind must be one of"):
        RoadDrivingEnv("roundabout")
    with pytest.raises(InputError, match="scenario must be"):
        RoadDrivingEnv("highway", scenario=object())


def test_road_env_is_registered():
    env = gymnasium.make(ROAD_ENV_ID, kind="tjunction")
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert info["outcome"] == "running"
