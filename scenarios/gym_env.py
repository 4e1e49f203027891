"""Gymnasium interfaces to the robot navigation and the driving worlds (the ``gym`` extra).

`RobotNavigationEnv` wraps `minimaxplan.scenarios.worlds.RobotWorld`:

* action: ``Box(-1, 1, (2,), float32)``, the control ``u``, held for one decision
  period (``substeps`` = 5 sub-steps of 0.1 s). A continuous action keeps the env
  useful to any agent; the discrete controller sets of the tree planners live in
  ``minimaxplan.planners`` and wrap around this env if needed.
* observation: a flat ``Box`` (float32) of
  ``[measured state (4), goal - measured position (2),
  nearest K obstacles: (dx, dy, radius, present) * K,
  pedestrians: (dx, dy, announced vx, announced vy, present) * 3]``; positions are
  relative to the measured robot position, obstacles sorted by clearance; absent
  entries are zeros with ``present = 0``. Measurement noise is the world's (uniform,
  bounded by default).
* reward: the mean over the held sub-steps of the true goal reward
  ``J = beta(x) / (1 + ||pos - goal||)`` in [0, 1] (0 after a collision).
* ``terminated`` on goal or collision, ``truncated`` at the 60 s time limit;
  ``info`` holds ``outcome``, ``time``, ``true_theta``.

`RoadDrivingEnv` wraps `minimaxplan.scenarios.road_world.RoadWorld` (highway or
T-junction):

* action: ``Box(-1, 1, (2,), float32)``, the ego's control ``(acceleration, steering)``
  normalised as in highway-env's continuous actions: ``(a_1 a_bound, a_2 max_steering)``
  (6 m/s^2 and pi/3 rad by default), held for one decision period (``substeps`` = 5
  sub-steps of 0.1 s);
* observation: a flat ``Box`` (float32) of ``[measured ego (x, y, v, psi) (4),
  nearest OBSERVED_VEHICLES vehicles: (dx, dy, v, psi, present) * 8]``, the world's
  noisy `Observation`: positions of the others relative to the measured ego position,
  nearest first, headings wrapped to [-pi, pi), absent entries zeros with
  ``present = 0``;
* reward: the mean over the held sub-steps of `driving_reward.true_reward` in [0, 1] (0 once the ego
  collided or left the road);
* ``terminated`` on goal, collision or leaving the road, ``truncated`` at the time
  limit; ``info`` holds ``outcome``, ``time`` and the observed vehicles' ``ids``.

``reset(seed=s)`` builds the world of seed ``s``; without a seed, the env draws the
next world seed from its own generator (seeded by the first seeded reset).
Importing this module needs gymnasium; the rest of ``minimaxplan.scenarios`` does not.
"""

from __future__ import annotations

import numpy as np

try:
    import gymnasium as gym
    from gymnasium import spaces
except ImportError as exc:  # pragma: no cover - exercised only without the extra
    raise ImportError("minimaxplan.scenarios.gym_env needs gymnasium: pip install 'minimaxplan[gym]'") from exc

from minimaxplan.models.errors import InputError
from minimaxplan.models.validation import as_choice, check_instance

from .driving_reward import true_reward, world_reward
from .road_world import ROAD_WORLD_KINDS, HighwayScenario, RoadWorld, TJunctionScenario
from .robot import DEFAULT_ROBOT, RobotParameters
from .worlds import MEASUREMENT_MODELS, PEDESTRIAN_COUNT, WORLD_KINDS, RobotWorld

__all__ = ["RobotNavigationEnv", "RoadDrivingEnv", "ENV_ID", "ROAD_ENV_ID"]

ENV_ID = "minimaxplan/RobotNavigation-v0"
ROAD_ENV_ID = "minimaxplan/RoadDriving-v0"
#: Obstacles reported in the observation (the nearest ones).
OBSERVED_OBSTACLES = 8
OBSERVED_PEDESTRIANS = PEDESTRIAN_COUNT[1]
#: Bound of every observation entry. Speeds stay below (1 + 0.1) / 0.2 = 5.5 m/s (input
#: plus disturbance against the smallest friction), so in 60 s positions move less than
#: 330 m from the 20 m arena; pedestrians walk below 2 m/s.
OBSERVATION_BOUND = 1000.0


def _action_array(action: np.ndarray) -> np.ndarray:
    """The action as a float array; raises `InputError` unless it has shape (2,)."""
    u = np.asarray(action, dtype=float)
    if u.shape != (2,):
        raise InputError(f"action must have shape (2,), got shape {u.shape}")
    return u


class _WorldEnv(gym.Env):
    """What both environments share: a world per episode, built by ``_start(world_seed)``
    (and observed by ``_observation`` and ``_info``), a control held through sub-steps."""

    metadata = {"render_modes": []}
    #: The outcomes that end an episode as ``terminated`` (a timeout truncates it).
    _terminal_outcomes: tuple[str, ...] = ()
    world: RobotWorld | RoadWorld | None

    def _start(self, world_seed: int) -> None:
        raise NotImplementedError

    def _observation(self) -> np.ndarray:
        raise NotImplementedError

    def _info(self) -> dict:
        raise NotImplementedError

    def _current_world(self):
        if self.world is None:
            raise InputError("call reset() before step()")
        return self.world

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Start a new episode (gymnasium API).

        Parameters
        ----------
        seed : int, optional
            World seed of the new episode (>= 0); without it, the next seed of the
            env's own generator (seeded by the first seeded reset).
        options : dict, optional
            Unused (gymnasium API).

        Returns
        -------
        observation : numpy.ndarray
            float32, shape ``observation_space.shape``.
        info : dict
            ``outcome``, ``time`` (s), and ``true_theta`` (`RobotNavigationEnv`) or the
            observed vehicles' agent ``ids`` (`RoadDrivingEnv`).
        """
        super().reset(seed=seed)
        world_seed = int(seed) if seed is not None else int(self.np_random.integers(0, 2**31 - 1))
        self._start(world_seed)
        return self._observation(), self._info()

    def _hold(self, world, u: np.ndarray, substeps: int, reward) -> tuple[np.ndarray, float, bool, bool, dict]:
        """Apply ``u`` for ``substeps`` sub-steps (fewer if the episode ends); the step's
        result with the mean of ``reward(world)`` after each."""
        rewards = []
        for _ in range(substeps):
            world.apply(u)
            rewards.append(reward(world))
            if world.done:
                break
        outcome = world.outcome
        terminated = outcome in self._terminal_outcomes
        truncated = outcome == "timeout"
        return self._observation(), float(np.mean(rewards)), terminated, truncated, self._info()


class RobotNavigationEnv(_WorldEnv):
    """Robot navigation among static obstacles or pedestrians (see the module docstring).

    Parameters
    ----------
    kind
        "static" or "pedestrian".
    measurement
        "uniform" (bounded noise, inside the guarantees) or "gaussian".
    params
        `RobotParameters`.
    """

    _terminal_outcomes = ("goal", "collision")

    def __init__(self, kind: str = "static", *, measurement: str = "uniform", params: RobotParameters = DEFAULT_ROBOT):
        as_choice("kind", kind, WORLD_KINDS)
        as_choice("measurement", measurement, MEASUREMENT_MODELS)
        check_instance("params", params, RobotParameters)
        self.kind = kind
        self.measurement = measurement
        self.params = params
        bound = params.control_bound
        self.action_space = spaces.Box(-bound, bound, shape=(2,), dtype=np.float32)
        size = 4 + 2 + 4 * OBSERVED_OBSTACLES + 5 * OBSERVED_PEDESTRIANS
        self.observation_space = spaces.Box(-OBSERVATION_BOUND, OBSERVATION_BOUND, shape=(size,), dtype=np.float32)
        self.world: RobotWorld | None = None

    def _observation(self) -> np.ndarray:
        world = self._current_world()
        x = world.measure()
        obs = [x, world.goal - x[:2]]
        obstacles = np.zeros((OBSERVED_OBSTACLES, 4))
        rel = world.obstacles.centers - x[:2]
        order = np.argsort(np.linalg.norm(rel, axis=1) - world.obstacles.radii)[:OBSERVED_OBSTACLES]
        obstacles[: order.size] = np.column_stack([rel[order], world.obstacles.radii[order], np.ones(order.size)])
        pedestrians = np.zeros((OBSERVED_PEDESTRIANS, 5))
        m = len(world.crowd)
        pedestrians[:m] = np.column_stack([world.crowd.positions - x[:2], world.crowd.announced, np.ones(m)])
        obs += [obstacles.ravel(), pedestrians.ravel()]
        return np.concatenate(obs).astype(np.float32)

    def _info(self) -> dict:
        world = self._current_world()
        return {"outcome": world.outcome, "time": world.time, "true_theta": world.true_theta.copy()}

    def _start(self, world_seed: int) -> None:
        self.world = RobotWorld(self.kind, world_seed, measurement=self.measurement, params=self.params)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        """Hold ``action`` for one decision period (gymnasium API).

        Parameters
        ----------
        action : array_like
            The control, shape (2,), in ``action_space``.

        Returns
        -------
        observation : numpy.ndarray
            float32, shape ``observation_space.shape``.
        reward : float
            Mean true reward over the sub-steps, in [0, 1].
        terminated : bool
            The robot reached the goal or collided.
        truncated : bool
            The time limit ran out.
        info : dict
            ``outcome``, ``time`` (s) and ``true_theta``.

        Raises
        ------
        InputError
            If `reset` was not called, or ``action`` is malformed or out of bounds.
        """
        world = self._current_world()
        u = _action_array(action)
        # float32 actions at the bound may exceed it by rounding: clip only that.
        bound = self.params.control_bound
        if np.any(np.abs(u) > bound * (1 + 1e-6)) or not np.all(np.isfinite(u)):
            raise InputError(f"action must lie in [-{bound}, {bound}]^2, got {u.tolist()}")
        u = np.clip(u, -bound, bound)
        return self._hold(world, u, self.params.substeps, lambda w: w.reward())


#: Other vehicles reported in the observation (the nearest ones).
OBSERVED_VEHICLES = 8
#: Bound of every road observation entry: the lanes lie within 2 km of the origin and
#: speeds are clipped to ``max_speed`` (40 m/s); headings are wrapped.
ROAD_OBSERVATION_BOUND = 1.0e4


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


class RoadDrivingEnv(_WorldEnv):
    """The ego among uncertain traffic on the highway or at the T-junction (see the module docstring).

    Parameters
    ----------
    kind
        "highway" or "tjunction".
    scenario
        A `HighwayScenario` or `TJunctionScenario` overriding the kind's constants.
    """

    _terminal_outcomes = ("goal", "collision", "off_road")

    def __init__(self, kind: str = "highway", *, scenario: HighwayScenario | TJunctionScenario | None = None):
        as_choice("kind", kind, ROAD_WORLD_KINDS)
        expected = HighwayScenario if kind == "highway" else TJunctionScenario
        scenario = expected() if scenario is None else scenario
        check_instance("scenario", scenario, expected)
        self.kind = kind
        self.scenario = scenario
        self._bounds = np.array([scenario.ego_acceleration_bound, scenario.vehicle.max_steering])
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        size = 4 + 5 * OBSERVED_VEHICLES
        self.observation_space = spaces.Box(
            -ROAD_OBSERVATION_BOUND, ROAD_OBSERVATION_BOUND, shape=(size,), dtype=np.float32
        )
        self.world: RoadWorld | None = None
        self._ids = np.zeros(0, dtype=int)

    def _observation(self) -> np.ndarray:
        seen = self._current_world().measure()
        ego = np.array(seen.ego, dtype=float)
        ego[3] = _wrap(ego[3])
        rel = seen.vehicles[:, :2] - ego[:2]
        order = np.argsort(np.linalg.norm(rel, axis=1), kind="stable")[:OBSERVED_VEHICLES]
        vehicles = np.zeros((OBSERVED_VEHICLES, 5))
        vehicles[: order.size] = np.column_stack(
            [rel[order], seen.vehicles[order, 2], _wrap(seen.vehicles[order, 3]), np.ones(order.size)]
        )
        self._ids = np.asarray(seen.ids)[order]
        obs = np.concatenate([ego, vehicles.ravel()])
        return np.clip(obs, -ROAD_OBSERVATION_BOUND, ROAD_OBSERVATION_BOUND).astype(np.float32)

    def _info(self) -> dict:
        world = self._current_world()
        return {"outcome": world.outcome, "time": world.time, "ids": self._ids.copy()}

    def _start(self, world_seed: int) -> None:
        self.world = RoadWorld(self.kind, world_seed, scenario=self.scenario)
        self._reward = world_reward(self.world)  # built once per episode, evaluated every sub-step

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        """Hold ``action`` for one decision period (gymnasium API).

        Parameters
        ----------
        action : array_like
            ``(acceleration, steering)`` normalised to [-1, 1], shape (2,): the control is
            ``action * (a_bound, max_steering)``.

        Returns
        -------
        observation : numpy.ndarray
            float32, shape ``observation_space.shape``.
        reward : float
            Mean `true_reward` over the sub-steps, in [0, 1].
        terminated : bool
            The ego reached the goal, collided or left the road.
        truncated : bool
            The time limit ran out.
        info : dict
            ``outcome``, ``time`` (s) and the observed vehicles' agent ``ids``.

        Raises
        ------
        InputError
            If `reset` was not called, or ``action`` is malformed or out of bounds.
        """
        world = self._current_world()
        u = _action_array(action)
        if np.any(np.abs(u) > 1.0) or not np.all(np.isfinite(u)):
            raise InputError(f"action must lie in [-1, 1]^2, got {u.tolist()}")
        # the scaled control may exceed its bound by one rounding: clip only that.
        u = np.clip(u * self._bounds, -self._bounds, self._bounds)
        return self._hold(world, u, int(self.scenario.substeps), lambda w: true_reward(w, self._reward))


def _register() -> None:
    if ENV_ID not in gym.registry:
        gym.register(ENV_ID, entry_point="minimaxplan.scenarios.gym_env:RobotNavigationEnv")
    if ROAD_ENV_ID not in gym.registry:
        gym.register(ROAD_ENV_ID, entry_point="minimaxplan.scenarios.gym_env:RoadDrivingEnv")


_register()
