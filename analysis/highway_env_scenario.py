"""highway-env's highway-fast-v0 and intersection-v0 as registered scenarios (the ``vehicle`` extra).

Importing this module registers the scenarios ``highway-env:highway-fast-v0`` and
``highway-env:intersection-v0`` (and `HIGHWAY_ENV_VARIANTS`: highway-fast-v0 with the ego's
target speeds extended down to standstill) and their methods ``robust``, ``nominal``,
``oracle`` and ``idm`` when highway-env is installed (it checks with `importlib.util.find_spec`, without
importing it; highway-env is imported when a world is made). The road worlds' ``dwa``
and ``teb`` do not support these scenarios, so a run of every registered scenario and
method must leave them out unless it names them.

The world (`HighwayEnvWorld`) is one highway-env environment with ``LinearVehicle``
other vehicles, read through `minimaxplan.scenarios.highway_env_adapter`. A sub-step is
one highway-env simulation step (0.2 s on highway-fast-v0, 1/15 s on intersection-v0);
a decision lasts ``simulation_frequency`` sub-steps (1 s, highway-env's default policy
frequency); the control is a meta-action index (shape (1,)) in the planner's naming
(`HIGHWAY_ACTIONS`, `TJUNCTION_ACTIONS`), applied at a decision's first sub-step and
followed by IDLE, which is what highway-env does with its own policy frequency.
Outcomes: "collision" (highway-env's ``crashed``), "off_road", "goal" (the intersection:
highway-env's ``has_arrived``; the highway: the time limit reached without a crash) and
"timeout" (the intersection's time limit).

Why these methods and not `minimaxplan.analysis.road_planning`'s: those drive a
`RoadWorld` (`EgoSetup` reads its `TrafficState`, and the ego model `BicycleModel` runs
the library's ego controllers, whose trajectory is not highway-env's ``MDPVehicle``'s:
highway-env's steering controller is another law, with arcsin and a heading-rate
stage). Here the ego's future under an action sequence is highway-env's own
(`simulate_ego`: a copy of its ``MDPVehicle`` on the same lanes, the same code, bit for
bit; the run-time check verifies it), and the methods search every sequence of
`SEARCH_DECISIONS` meta-actions, then IDLE, over the forecast horizon:

robust
    `forecast_traffic` (the adapter's, prior beliefs from the reference priors) of every
    vehicle over `HORIZON` s at highway-env's step, the ego's reach over every action
    sequence as the leaders' input; a sequence's value is the discounted sum of the
    reward (highway-env's, normalised) along the ego's predicted states, 0 from the first
    sub-step at which the ego's rectangle box meets a vehicle's box (a possible
    collision). On the highway a second forecast from the exact reach of the
    lane-keeping sequences (SLOWER/IDLE/FASTER, `LANE_KEEPING_NAMES`), which a sequence
    reads up to its last lane-keeping sub-step (`kept_substeps`), the general one after:
    sound because a forecast's boxes up to sub-step n read the ego's reach only up to n
    (as the road worlds' lane-keeping forecast). When the best-valued sequence may
    collide within the horizon, the executed one is, among those whose first possible
    collision is the latest, the slowest there when none is clear, then the best-valued
    (`latest_clear_sequence`, the road worlds' latest-collision rule). A
    `PredictingPolicy`: the ego's
    predicted state and the state boxes of the forecast that valued the executed
    decision are checked after each sub-step (``boxes_checked``, ``boxes_missed``).
nominal
    The same search on a point-like forecast: the nominal parameters (the priors'
    centres), the measured speed as the target speed, no lane change (the road without
    side groups), every route.
oracle
    The same search on the other vehicles' true future: a deep copy of the environment
    stepped over the horizon with the ego holding its targets (as the road worlds'
    oracle).
idm
    A reference point, not a planner: highway-env's own ``IDMVehicle`` (IDM and MOBIL)
    drives the ego from reset, whatever the library's action.

The road worlds' DWA and TEB (`minimaxplan.analysis.road_methods`) drive `RoadWorld`s
only: they raise `UnsupportedScenario` here.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import importlib.util
from collections.abc import Mapping
from typing import Any

import numpy as np

from minimaxplan.models import Box
from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.planners.bicycle_model import HIGHWAY_ACTIONS, TJUNCTION_ACTIONS
from minimaxplan.scenarios.highway_env_adapter import MISSING_VEHICLE_EXTRA
from minimaxplan.scenarios.road import Road
from minimaxplan.scenarios.road_world import Observation
from minimaxplan.scenarios.traffic_models import TrafficForecast, VehicleBelief
from minimaxplan.scenarios.vehicles import vehicle_corners

from .episode import LoopConfig
from .registry import (
    Method,
    Policy,
    Scenario,
    UnsupportedScenario,
    register_method,
    register_scenario,
    register_unavailable,
)
from .road_planning import conservative_first

__all__ = [
    "HIGHWAY_ENV_SCENARIOS",
    "HIGHWAY_ENV_VARIANTS",
    "EXTENDED_TARGET_SPEEDS",
    "HORIZON",
    "SEARCH_DECISIONS",
    "HighwayEnvScenario",
    "HighwayEnvWorld",
    "HighwayEnvRobustMethod",
    "HighwayEnvNominalMethod",
    "HighwayEnvOracleMethod",
    "HighwayEnvIDMMethod",
    "simulate_ego",
    "sequence_reach",
    "lane_keeping_sequences",
    "kept_substeps",
    "box_overlaps",
    "latest_clear_sequence",
    "normalised_reward",
    "learner_scenario",
    "LEARNER_NOISE",
    "LANE_KEEPING_NAMES",
    "checked_target_speeds",
]

#: Registered scenario name -> highway-env id.
HIGHWAY_ENV_SCENARIOS = {
    "highway-env:highway-fast-v0": "highway-fast-v0",
    "highway-env:intersection-v0": "intersection-v0",
}
#: The ego's target speeds of the extended variant, m/s: 0 to 30, 5 apart. highway-fast-v0's
#: own (``MDPVehicle.DEFAULT_TARGET_SPEEDS``) are 20, 25 and 30, so SLOWER cannot brake
#: below 20 m/s; the robust ego's collisions there happen at that floor (README).
EXTENDED_TARGET_SPEEDS = (0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0)
#: Registered scenario name -> (highway-env id, the ego's target speeds): the same
#: environment with its ``DiscreteMetaAction``'s ``target_speeds`` configured.
HIGHWAY_ENV_VARIANTS = {
    "highway-env:highway-fast-v0-speeds-0-30": ("highway-fast-v0", EXTENDED_TARGET_SPEEDS),
}
#: The forecast's horizon, s (the planner's 5 s).
HORIZON = 5.0
#: Decisions whose meta-actions are enumerated (then IDLE until the horizon).
SEARCH_DECISIONS = 2
#: highway-env's meta-action names that move the ego's target lane or speed.
_IDLE = "IDLE"


def checked_target_speeds(target_speeds) -> tuple[float, ...] | None:
    """``target_speeds`` as a tuple of floats, or None; refused unless at least two, finite and increasing.

    Parameters
    ----------
    target_speeds : sequence of float or None
        An ego's target speeds, m/s.

    Raises
    ------
    DimensionError
        If they are not one-dimensional with at least two values.
    InputError
        If one is not finite or negative, or they do not increase strictly.
    """
    if target_speeds is None:
        return None
    speeds = np.asarray(target_speeds, dtype=float)
    if speeds.ndim != 1 or speeds.size < 2:
        raise DimensionError(
            f"target_speeds must be one-dimensional with at least two values, got shape {speeds.shape}"
        )
    if not np.all(np.isfinite(speeds)) or np.any(speeds < 0):
        raise InputError(f"target_speeds must be finite and non-negative, got {speeds.tolist()}")
    if np.any(np.diff(speeds) <= 0):
        raise InputError(f"target_speeds must increase strictly, got {speeds.tolist()}")
    return tuple(float(v) for v in speeds)


class _StubRoad:
    """What an ``MDPVehicle`` reads of its road when it acts and steps alone: the lanes."""

    def __init__(self, network) -> None:
        self.network = network
        self.record_history = False
        self.np_random = np.random.RandomState(0)  # used by next_lane only without a route
        self.vehicles: list = []
        self.objects: list = []


def simulate_ego(ego, network, names: list[str], substeps: int, dt: float) -> np.ndarray:
    """highway-env's ego under a sequence of meta-actions, alone on its lanes.

    Parameters
    ----------
    ego : highway_env.vehicle.controller.MDPVehicle
        The controlled vehicle now (not modified).
    network : highway_env.road.road.RoadNetwork
        The lanes.
    names : list of str
        highway-env meta-action names, one per decision.
    substeps : int
        Simulation steps per decision.
    dt : float
        Simulation step, s.

    Returns
    -------
    numpy.ndarray, shape (len(names) * substeps + 1, 4)
        ``(x, y, v, psi)`` now and after every simulation step.

    Notes
    -----
    Replays what highway-env's ``step`` does to the ego at every simulation step: the
    action type's ``act(name)`` at the first step of a decision (IDLE after), the
    road's ``act()``, then ``step(dt)``. The ego's controllers read only its own state
    and its lanes, so away from a collision this is its trajectory bit for bit.
    """
    twin = copy.copy(ego)
    twin.road = _StubRoad(network)
    twin.position = np.array(ego.position, dtype=float)
    twin.route = list(ego.route) if ego.route else ego.route
    twin.action = dict(ego.action)
    twin.history = type(ego.history)(maxlen=1)
    out = [np.array([twin.position[0], twin.position[1], twin.speed, twin.heading])]
    for name in names:
        for k in range(substeps):
            twin.act(name if k == 0 else _IDLE)
            twin.act()
            twin.step(dt)
            out.append(np.array([twin.position[0], twin.position[1], twin.speed, twin.heading]))
    return np.array(out)


class HighwayEnvWorld:
    """One highway-env episode as the registry's `World` and `GroundTruthWorld`.

    Parameters
    ----------
    env_id : str
        A value of `HIGHWAY_ENV_SCENARIOS`.
    seed : int
        highway-env's seed.
    target_speeds : sequence of float, optional
        The ego's target speeds (m/s, increasing, at least two), configured as the
        environment's ``DiscreteMetaAction`` ``target_speeds``; by default highway-env's.

    Attributes
    ----------
    adapter : HighwayEnvAdapter
        The environment and its reading into the library's road and observations.
    actions : tuple
        The planner's actions (`HIGHWAY_ACTIONS` or `TJUNCTION_ACTIONS`).
    """

    def __init__(self, env_id: str, seed: int, *, target_speeds=None) -> None:
        from minimaxplan.scenarios.highway_env_adapter import HighwayEnvAdapter, meta_action

        speeds = checked_target_speeds(target_speeds)
        self._meta_action = meta_action
        self.adapter = HighwayEnvAdapter(env_id, config={"normalize_reward": True})
        base = self.adapter.env.unwrapped
        hz = int(base.config["simulation_frequency"])
        # one env.step per simulation step; the decision period stays highway-env's 1 s
        base.configure({"policy_frequency": hz})
        if speeds is not None:
            # highway-env's configure replaces a key's value: keep the action type's other settings
            base.configure({"action": {**base.config["action"], "target_speeds": list(speeds)}})
        self.seed = int(seed)
        self.adapter.reset(self.seed)
        self._substeps = hz
        # SLOWER first, then IDLE: the search breaks ties towards braking (`conservative_first`)
        self.actions = conservative_first(HIGHWAY_ACTIONS if "highway" in env_id else TJUNCTION_ACTIONS)
        self._outcome = "running"
        self._reward = 1.0
        self.step_index = 0

    # -------------------------------------------------------------- World protocol
    @property
    def substeps(self) -> int:
        """Simulation steps per decision (highway-env's 1 s)."""
        return self._substeps

    @property
    def done(self) -> bool:
        """True once the episode has ended."""
        return self._outcome != "running"

    @property
    def outcome(self) -> str:
        """ "running", then "goal", "collision", "off_road" or "timeout"."""
        return self._outcome

    @property
    def time(self) -> float:
        """Simulated time, s."""
        return self.step_index * self.adapter.dt

    @property
    def position(self) -> np.ndarray:
        """The ego's ``(x, y)``, m."""
        return np.array(self.adapter.env.unwrapped.vehicle.position, dtype=float)

    @property
    def state(self) -> np.ndarray:
        """The ego's ``(x, y, v, psi)``."""
        ego = self.adapter.env.unwrapped.vehicle
        return np.array([ego.position[0], ego.position[1], ego.speed, ego.heading], dtype=float)

    @property
    def params(self) -> Any:
        """The forecast's constants (``dt`` for the trace)."""
        return self.adapter.scenario

    def measure(self) -> Observation:
        """The ego and the other vehicles' exact kinematics (`HighwayEnvAdapter.observe`)."""
        return self.adapter.observe()

    def apply(self, u: np.ndarray) -> str:
        """One simulation step with the planner's action index ``u[0]`` (into `actions`).

        Parameters
        ----------
        u : numpy.ndarray, shape (1,)
            The action's index in `actions`.
        """
        if self.done:
            raise InputError("the episode is over")
        k = int(np.asarray(u).reshape(-1)[0])
        if not 0 <= k < len(self.actions):
            raise InputError(f"action index must lie in [0, {len(self.actions)}), got {k}")
        env = self.adapter.env
        _, reward, terminated, truncated, _ = env.step(self._meta_action(env, self.actions[k][0]))
        self.step_index += 1
        self._reward = float(np.clip(reward, 0.0, 1.0))
        base = env.unwrapped
        ego = base.vehicle
        if ego.crashed:
            self._outcome = "collision"
        elif not ego.on_road:
            self._outcome = "off_road"
        elif terminated:
            self._outcome = "goal"  # the intersection: arrived
        elif truncated:
            self._outcome = "goal" if "highway" in self.adapter.env_id else "timeout"
        return self._outcome

    def drive_ego_by_idm(self) -> None:
        """Hand the ego to highway-env's own ``IDMVehicle`` (IDM and MOBIL, highway-env's constants).

        The reference point of the highway-env table: ``IDMVehicle.create_from`` the ego
        (its position, heading, speed, target lane and speed, route) replaces it on the
        road and as the controlled vehicle, so that `apply`'s ``env.step`` runs IDM and
        MOBIL on it (``IDMVehicle.act`` ignores the action it is given).

        Raises
        ------
        InputError
            If the episode has already started (it must be the state at reset).
        """
        from minimaxplan.scenarios.highway_env_adapter import require_highway_env

        if self.step_index:
            raise InputError("the ego can be handed to IDM only at the start of the episode")
        base = self.adapter.env.unwrapped
        ego = base.vehicle
        idm = require_highway_env().vehicle.behavior.IDMVehicle.create_from(ego)
        base.road.vehicles[base.road.vehicles.index(ego)] = idm
        base.controlled_vehicles[base.controlled_vehicles.index(ego)] = idm
        base.action_type.controlled_vehicle = idm

    def reward(self) -> float:
        """highway-env's normalised reward of the last step, clipped to [0, 1]."""
        return self._reward

    def true_states(self) -> dict[str, np.ndarray]:
        """``"ego"`` and ``"vehicle j"`` (the adapter's ids): ``(x, y, v, psi)``."""
        base = self.adapter.env.unwrapped
        states = {"ego": self.state}
        for v in base.road.vehicles:
            if v is not base.vehicle:
                states[f"vehicle {self.adapter.agent_id(v)}"] = np.array(
                    [v.position[0], v.position[1], v.speed, v.heading], dtype=float
                )
        return states

    def to_dict(self) -> dict:
        """The environment id, seed and highway-env configuration, the meta-actions' target speeds, and the ego's final state.

        ``target_speeds`` are those of the environment's action type (m/s), which an
        ``MDPVehicle`` ego tracks; an ego driven by IDM (`drive_ego_by_idm`) ignores them.
        """
        base = self.adapter.env.unwrapped
        config = {k: v for k, v in base.config.items() if isinstance(v, (int, float, str, bool))}
        return {
            "env_id": self.adapter.env_id,
            "seed": self.seed,
            "config": config,
            "target_speeds": [float(v) for v in base.action_type.target_speeds],
            "ego": self.state.tolist(),
        }


class HighwayEnvScenario(Scenario[HighwayEnvWorld]):
    """A highway-env environment as a scenario (one seeded `HighwayEnvWorld` per episode).

    Parameters
    ----------
    env_id : str
        A value of `HIGHWAY_ENV_SCENARIOS`.
    target_speeds : sequence of float, optional
        The ego's target speeds (`HighwayEnvWorld`); by default highway-env's.
    """

    def __init__(self, env_id: str, *, target_speeds=None) -> None:
        if env_id not in HIGHWAY_ENV_SCENARIOS.values():
            raise InputError(f"env_id must be one of {sorted(HIGHWAY_ENV_SCENARIOS.values())}, got {env_id!r}")
        self.env_id = env_id
        self.target_speeds = checked_target_speeds(target_speeds)

    def __repr__(self) -> str:
        if self.target_speeds is None:
            return f"HighwayEnvScenario({self.env_id!r})"
        return f"HighwayEnvScenario({self.env_id!r}, target_speeds={self.target_speeds!r})"

    def make_world(self, seed: int, config: LoopConfig) -> HighwayEnvWorld:
        """The episode's environment, reset with ``seed`` (after restoring highway-env's class constants).

        Parameters
        ----------
        seed : int
            The episode's seed.
        config : LoopConfig
            The loop settings (``measurement`` must be "uniform": highway-env's states are read exactly).
        """
        if config.measurement != "uniform":
            raise InputError(f"highway-env worlds are measured exactly, got measurement {config.measurement!r}")
        return HighwayEnvWorld(self.env_id, seed, target_speeds=self.target_speeds)


# ------------------------------------------------------------------ methods
class _SearchPolicy:
    """The chosen action at the decision's first sub-step, IDLE after; the predicted boxes."""

    def __init__(self, action: int, idle: int, predicted: Mapping[int, Mapping[str, tuple]]) -> None:
        self.action = action
        self.idle = idle
        self._predicted = predicted
        self._calls = 0

    def control(self, measurement: Observation) -> np.ndarray:
        """The action index (shape (1,))."""
        self._calls += 1
        return np.array([self.action if self._calls == 1 else self.idle], dtype=float)


class _PredictingSearchPolicy(_SearchPolicy):
    def predicted_boxes(self, substep: int) -> Mapping[str, tuple]:
        """The ego's predicted point and the forecast vehicles' state boxes after ``substep``."""
        return self._predicted.get(substep, {})


def _rect_boxes(states: np.ndarray, vehicle) -> np.ndarray:
    corners = vehicle_corners(states, vehicle)
    return np.concatenate([corners.min(axis=-2), corners.max(axis=-2)], axis=-1)


#: highway-env's meta-actions that keep the ego's target lane (speed changes only).
LANE_KEEPING_NAMES = ("SLOWER", "IDLE", "FASTER")


def sequence_reach(trajectories: np.ndarray, vehicle) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The ego's rectangle boxes along each trajectory and their union over the trajectories.

    Parameters
    ----------
    trajectories : numpy.ndarray, shape (sequences, steps + 1, 4)
        ``(x, y, v, psi)`` of the ego under each action sequence (`simulate_ego`).
    vehicle : VehicleParameters
        The ego's rectangle.

    Returns
    -------
    boxes : numpy.ndarray, shape (sequences, steps + 1, 4)
        ``[x_lo, y_lo, x_hi, y_hi]`` of the rectangle of each trajectory at each sub-step.
    reach : numpy.ndarray, shape (steps + 1, 4)
        The smallest box that holds every trajectory's rectangle at each sub-step,
        rounded outward by one ulp (the ego's exact reach over these sequences).
    speed, heading : numpy.ndarray, shape (steps + 1, 2)
        ``(low, high)`` of the speed and heading over the trajectories, rounded outward.

    Notes
    -----
    The reach at sub-step n reads the trajectories up to n only, so a forecast that is
    causal in its ego reach (`forecast_traffic`) gives, up to n, boxes valid for every
    ego path that agrees with one of these trajectories up to n.
    """
    trajectories = np.asarray(trajectories, dtype=float)
    if trajectories.ndim != 3 or trajectories.shape[-1] != 4 or trajectories.shape[0] == 0:
        raise DimensionError(f"trajectories must have shape (sequences >= 1, steps + 1, 4), got {trajectories.shape}")
    boxes = _rect_boxes(trajectories, vehicle)
    reach = np.concatenate(
        [np.nextafter(boxes[..., :2].min(axis=0), -np.inf), np.nextafter(boxes[..., 2:].max(axis=0), np.inf)], axis=1
    )
    bounds = []
    for column in (2, 3):
        values = trajectories[..., column]
        bounds.append(
            np.stack([np.nextafter(values.min(axis=0), -np.inf), np.nextafter(values.max(axis=0), np.inf)], axis=1)
        )
    return boxes, reach, bounds[0], bounds[1]


def lane_keeping_sequences(sequences: np.ndarray, names: list[str]) -> np.ndarray:
    """Which action sequences keep the ego's target lane (every meta-action in `LANE_KEEPING_NAMES`).

    Parameters
    ----------
    sequences : numpy.ndarray of int, shape (sequences, decisions)
        Action indices into ``names``.
    names : list of str
        The actions' names.

    Returns
    -------
    numpy.ndarray of bool, shape (sequences,)
    """
    keeps = np.array([name in LANE_KEEPING_NAMES for name in names], dtype=bool)
    return np.all(keeps[np.asarray(sequences, dtype=int)], axis=1)


def kept_substeps(sequences: np.ndarray, names: list[str], substeps: int, steps: int) -> np.ndarray:
    """The last sub-step up to which each sequence is a lane-keeping path.

    Parameters
    ----------
    sequences : numpy.ndarray of int, shape (sequences, decisions)
        Action indices into ``names`` (then IDLE to the horizon).
    names : list of str
        The actions' names.
    substeps : int
        Sub-steps per decision.
    steps : int
        The horizon, sub-steps.

    Returns
    -------
    numpy.ndarray of int, shape (sequences,)
        ``steps`` for a sequence of lane-keeping actions only (its IDLE tail keeps the
        lane too); else ``p * substeps`` with ``p`` its leading lane-keeping decisions.

    Notes
    -----
    Up to sub-step ``p * substeps`` the ego's trajectory under such a sequence is the
    trajectory of a sequence of lane-keeping actions (a decision's meta-action acts
    from its first sub-step on), so it lies in their reach up to there: the
    lane-keeping forecast, causal in its ego reach, holds for it up to there.
    """
    keeps = np.array([name in LANE_KEEPING_NAMES for name in names], dtype=bool)[np.asarray(sequences, dtype=int)]
    leading = np.where(keeps.all(axis=1), keeps.shape[1], np.argmin(keeps, axis=1))
    return np.where(leading == keeps.shape[1], int(steps), np.minimum(leading * int(substeps), int(steps)))


def box_overlaps(boxes: np.ndarray, other: np.ndarray) -> np.ndarray:
    """Whether each sequence's ego box meets any vehicle's box at each sub-step (closed boxes).

    Parameters
    ----------
    boxes : numpy.ndarray, shape (sequences, steps + 1, 4)
        The ego's rectangle boxes (`sequence_reach`).
    other : numpy.ndarray, shape (steps + 1, m, 4)
        The forecast's boxes (empty boxes meet nothing).

    Returns
    -------
    numpy.ndarray of bool, shape (sequences, steps + 1)
    """
    overlap = (
        (boxes[:, :, None, 0] <= other[None, :, :, 2])
        & (other[None, :, :, 0] <= boxes[:, :, None, 2])
        & (boxes[:, :, None, 1] <= other[None, :, :, 3])
        & (other[None, :, :, 1] <= boxes[:, :, None, 3])
    )
    return np.any(overlap, axis=2)


def latest_clear_sequence(alive: np.ndarray, values: np.ndarray, *, speeds: np.ndarray | None = None) -> int:
    """The best-valued sequence, unless it may collide sooner than another: then the best of those clear longest.

    The road worlds' rule (`minimaxplan.planners.latest_collision_action`)
    for an exhaustive search: when the best-valued sequence may collide within the
    forecast, its value is the reward collected before that possible collision, and a
    sequence that takes speed first may collect more of it for a collision a few
    sub-steps earlier, giving up the time in which new measurements shrink the boxes.

    With ``speeds``, when no sequence is clear over the whole horizon (nothing is proven
    then), the candidates whose first possible collision is the latest are narrowed to
    those slowest at that sub-step before the value decides: the least speed where a
    collision may first happen (braking also leaves the most time for measurements).

    Parameters
    ----------
    alive : numpy.ndarray of bool, shape (sequences, steps + 1)
        Whether each sequence is still clear of every box up to each sub-step
        (nonincreasing along a row).
    values : numpy.ndarray, shape (sequences,)
        The sequences' discounted values.
    speeds : numpy.ndarray, shape (sequences, steps + 1), optional
        The ego's speed along each sequence, m/s.

    Returns
    -------
    int
        The index of the best-valued sequence among those whose first possible collision
        is the latest (and, with ``speeds`` and no clear sequence, the slowest there; the
        first on ties; every clear sequence qualifies when one is).
    """
    alive = np.asarray(alive, dtype=bool)
    values = np.asarray(values, dtype=float)
    if alive.ndim != 2 or values.shape != (alive.shape[0],) or alive.shape[0] == 0:
        raise DimensionError(
            f"alive must have shape (sequences, steps + 1) and values (sequences,), got {alive.shape} and {values.shape}"
        )
    if np.any(alive[:, 1:] & ~alive[:, :-1]):
        raise InputError("alive must be nonincreasing along each sequence (clear up to its first possible collision)")
    if not np.all(np.isfinite(values)):
        raise InputError("values must be finite")
    clear = alive.sum(axis=1)
    candidates = np.flatnonzero(clear == clear.max())
    if speeds is not None:
        speeds = np.asarray(speeds, dtype=float)
        if speeds.shape != alive.shape:
            raise DimensionError(f"speeds must have the shape of alive {alive.shape}, got {speeds.shape}")
        if not np.all(np.isfinite(speeds)):
            raise InputError("speeds must be finite")
        if not alive[:, -1].any():
            at = speeds[candidates, int(clear.max())]  # the candidates' first possible collision sub-step
            candidates = candidates[at == at.min()]
    return int(candidates[np.argmax(values[candidates])])


def normalised_reward(config: Mapping[str, Any], states, *, highway: bool, lane_width: float) -> np.ndarray:
    """highway-env's reward of ego states without a collision, normalised to [0, 1] as highway-env does.

    Highway: ``high_speed_reward`` times the forward speed ``v cos(psi)`` scaled over
    ``reward_speed_range`` (clipped to [0, 1]) plus ``right_lane_reward`` times the lane
    index (``round(y / lane_width)``) over the last lane's; intersection: the speed term
    alone. Both are then mapped from ``[collision_reward, top]`` to [0, 1], ``top`` the
    largest reward without arrival (highway) or ``arrived_reward`` (intersection).

    Parameters
    ----------
    config : mapping
        The environment's ``config``.
    states : array_like, shape (n, 4)
        Ego states ``(x, y, v, psi)``.
    highway : bool
        highway-fast-v0's reward (else intersection-v0's).
    lane_width : float
        The lanes' width, m (highway only).

    Returns
    -------
    numpy.ndarray, shape (n,)
    """
    states = np.asarray(states, dtype=float)
    lo, hi = config["reward_speed_range"]
    if highway:
        speed = np.clip((states[:, 2] * np.cos(states[:, 3]) - lo) / (hi - lo), 0.0, 1.0)
        lanes = int(config["lanes_count"])
        lane = np.clip(np.round(states[:, 1] / lane_width), 0, lanes - 1) / max(lanes - 1, 1)
        raw = config["high_speed_reward"] * speed + config["right_lane_reward"] * lane
        top = config["high_speed_reward"] + config["right_lane_reward"]
        return (raw - config["collision_reward"]) / (top - config["collision_reward"])
    speed = np.clip((states[:, 2] - lo) / (hi - lo), 0.0, 1.0)
    return (config["high_speed_reward"] * speed - config["collision_reward"]) / (
        config["arrived_reward"] - config["collision_reward"]
    )


class _HighwayEnvMethod(Method[HighwayEnvWorld]):
    """A method of the highway-env scenarios only (any other raises `UnsupportedScenario`)."""

    def __init__(self, scenario: Any, config: LoopConfig) -> None:
        if not isinstance(scenario, HighwayEnvScenario):
            raise UnsupportedScenario(f"{type(self).__name__} drives highway-env scenarios only")
        self.scenario = scenario
        self.config = config


class _SearchMethod(_HighwayEnvMethod):
    """The exhaustive search over `SEARCH_DECISIONS` meta-actions shared by robust and nominal."""

    predicting = False
    #: Value the paths that keep their lane against a second forecast from the lane-keeping reach.
    lane_keeping = False
    #: When every sequence may collide, take the one clear longest (`latest_clear_sequence`).
    latest_collision = False

    def start(self, world: HighwayEnvWorld) -> None:
        """Remember the world; enumerate the action sequences.

        Parameters
        ----------
        world : HighwayEnvWorld
            The episode.
        """
        self.world = world
        n = len(world.actions)
        grids = np.meshgrid(*[np.arange(n)] * SEARCH_DECISIONS, indexing="ij")
        self.sequences = np.stack([g.ravel() for g in grids], axis=1)
        self.decisions: list[dict] = []

    def forecast(self, observation: Observation, reach, speed, heading) -> TrafficForecast:
        """The other vehicles' boxes over the horizon (abstract)."""
        raise NotImplementedError

    def _reward(self, states: np.ndarray) -> np.ndarray:
        """highway-env's normalised reward of predicted ego states without collision."""
        adapter = self.world.adapter
        width = float(adapter.road.widths[0]) if adapter.road is not None else 4.0
        return normalised_reward(
            adapter.env.unwrapped.config, states, highway="highway" in adapter.env_id, lane_width=width
        )

    def decide(self, measurement: Observation) -> Policy:
        """Search every action sequence against the forecast; hold the best first action.

        Parameters
        ----------
        measurement : Observation
            The current (exact) observation.
        """
        world = self.world
        base = world.adapter.env.unwrapped
        S, dt = world.substeps, world.adapter.dt
        steps = world.adapter.steps(HORIZON)
        tail = int(np.ceil(steps / S)) - SEARCH_DECISIONS
        names = [a[0] for a in world.actions]
        swap = {"LANE_LEFT": "LANE_RIGHT", "LANE_RIGHT": "LANE_LEFT"}  # the planner's -> highway-env's
        trajectories = np.stack(
            [
                simulate_ego(
                    base.vehicle,
                    base.road.network,
                    [swap.get(names[k], names[k]) for k in seq] + [_IDLE] * max(tail, 0),
                    S,
                    dt,
                )[: steps + 1]
                for seq in self.sequences
            ]
        )  # (sequences, steps + 1, 4)
        scenario = world.adapter.scenario
        if scenario is None:
            raise InputError("the world's adapter has not been reset")
        boxes, reach, speed, heading = sequence_reach(trajectories, scenario.vehicle)
        forecast = self.forecast(measurement, reach, speed, heading)
        hit = box_overlaps(boxes, forecast.boxes)  # (sequences, steps + 1)
        kept = np.zeros(len(self.sequences), dtype=int)  # sub-steps read from the lane-keeping forecast
        keep_forecast = None
        if self.lane_keeping:
            keeping = lane_keeping_sequences(self.sequences, names)
            if not keeping.all():
                _, keep_reach, keep_speed, keep_heading = sequence_reach(trajectories[keeping], scenario.vehicle)
                keep_forecast = self.forecast(measurement, keep_reach, keep_speed, keep_heading)
                kept = kept_substeps(self.sequences, names, S, steps)
                on_keep = np.arange(steps + 1)[None, :] <= kept[:, None]
                hit = np.where(on_keep, box_overlaps(boxes, keep_forecast.boxes), hit)
        hit[:, 0] = False
        alive = ~np.logical_or.accumulate(hit, axis=1)
        rewards = np.stack([self._reward(t) for t in trajectories]) * alive
        discount = self.config.gamma ** (np.arange(steps + 1) / S)
        values = (rewards[:, 1:] * discount[1:]).sum(axis=1)
        best = int(np.argmax(values))  # ties: the first sequence (SLOWER first at the intersection)
        if self.latest_collision and not alive[best, -1]:
            best = latest_clear_sequence(alive, values, speeds=trajectories[:, :, 2])
        first = int(self.sequences[best, 0])
        predicted: dict[int, dict[str, tuple]] = {}
        if self.predicting:
            ego = trajectories[best]
            # the executed decision was valued against the lane-keeping forecast when its action keeps the lane
            if keep_forecast is not None and kept[best] >= S:
                forecast = keep_forecast
            limit = _removal_free(world, forecast, S)
            for k in range(1, S + 1):
                row = {"ego": (ego[k], ego[k])}
                for j, agent in enumerate(forecast.ids):
                    if limit[j]:
                        row[f"vehicle {int(agent)}"] = (forecast.state_lower[k, j], forecast.state_upper[k, j])
                predicted[k] = row
        self.decisions.append(
            {
                "step": int(world.step_index),
                "action": names[first],
                "value": float(values[best]),
                "safe_sequences": int(alive[:, -1].sum()),
            }
        )
        if self.lane_keeping:
            self.decisions[-1]["lane_keeping"] = bool(keep_forecast is not None and kept[best] >= S)
        idle = names.index(_IDLE)
        cls = _PredictingSearchPolicy if self.predicting else _SearchPolicy
        return cls(first, idle, predicted)

    def report(self) -> dict:
        """The decisions' actions, values and counts of sequences without a possible collision."""
        return {"decisions": self.decisions}


#: Measurement noise half-widths the learner is told (m, m, m/s, rad): highway-env's states
#: are read exactly, but the learner's interval rows need a non-degenerate width (with
#: zero noise an exact row is infeasible by one rounding error and eliminates the truth).
LEARNER_NOISE = (1e-6, 1e-6, 1e-6, 1e-7)


def learner_scenario(scenario):
    """The forecast's constants with `LEARNER_NOISE` as measurement noise (the learner's view).

    Parameters
    ----------
    scenario : HighwayScenario or TJunctionScenario
        The adapter's.
    """
    return dataclasses.replace(scenario, measurement_noise=LEARNER_NOISE)


def _removal_free(world: HighwayEnvWorld, forecast: TrafficForecast, substeps: int) -> np.ndarray:
    """Vehicles that highway-env cannot remove during the decision (intersection-v0 removes
    vehicles 4 L before the end of their exit lane): their boxes stay within 80 m of the
    junction's centre; every vehicle on the highway."""
    m = len(forecast.ids)
    if "intersection" not in world.adapter.env_id:
        return np.ones(m, dtype=bool)
    box = forecast.boxes[: substeps + 1]
    finite = np.all(np.isfinite(box), axis=(0, 2))
    far = np.max(np.abs(box), axis=(0, 2))
    return finite & (far < 80.0)


class HighwayEnvRobustMethod(_SearchMethod):
    """The search against `forecast_traffic`'s sound boxes under prior beliefs (see the module docstring)."""

    predicting = True
    lane_keeping = True
    latest_collision = True

    def start(self, world: HighwayEnvWorld) -> None:
        """Enumerate the sequences; on the highway, a `TrafficLearner` of the episode.

        Parameters
        ----------
        world : HighwayEnvWorld
            The episode.
        """
        super().start(world)
        self.learner: Any = None
        self.prior_fallbacks: set[int] = set()
        self._believed: tuple[float, dict[int, VehicleBelief]] | None = None
        road, scenario = world.adapter.road, world.adapter.scenario
        if "highway" in world.adapter.env_id and road is not None and scenario is not None:
            from .traffic_learning import TrafficLearner

            self.learner = TrafficLearner(road, learner_scenario(scenario))
            self._learned: float | None = None

    def _learn(self, observation: Observation) -> None:
        if self.learner is not None and observation.time != self._learned:
            self.learner.observe(observation)
            self._learned = observation.time

    def observe(self, transition) -> None:
        """Feed the learner the sub-step's observation (the highway).

        Parameters
        ----------
        transition : Transition
            The sub-step; its ``next_measured`` `Observation` goes to the learner (none
            off the highway).
        """
        self._learn(transition.next_measured)

    def forecast(self, observation: Observation, reach, speed, heading) -> TrafficForecast:
        """The adapter's forecast over `HORIZON` with the ego's reach.

        Parameters
        ----------
        observation : Observation
            The current observation.
        reach, speed, heading : numpy.ndarray
            The ego's rectangle boxes, speed and heading bounds over every sequence.
        """
        return self.world.adapter.forecast(
            observation,
            HORIZON,
            ego_reach=reach,
            ego_speed=speed,
            ego_heading=heading,
            beliefs=self._beliefs(observation),
        )

    def _beliefs(self, observation: Observation) -> dict[int, VehicleBelief]:
        """The learner's beliefs at this observation (computed once per observation: both forecasts read them)."""
        if self._believed is not None and self._believed[0] == observation.time:
            return self._believed[1]
        beliefs: dict[int, VehicleBelief] = {}
        if self.learner is not None:
            self._learn(observation)
            for agent in observation.ids:
                try:
                    beliefs.update(self.learner.beliefs([int(agent)]))
                except InputError:  # every hypothesis eliminated: highway-env is not the learner's model
                    self.prior_fallbacks.add(int(agent))
        self._believed = (observation.time, beliefs)
        return beliefs

    def report(self) -> dict:
        """The decisions and the vehicles whose learned belief fell back to the prior."""
        return {"decisions": self.decisions, "prior_fallbacks": sorted(self.prior_fallbacks)}


class HighwayEnvNominalMethod(_SearchMethod):
    """The search against a nominal forecast (priors' centres, measured speed as target, no lane change)."""

    def forecast(self, observation: Observation, reach, speed, heading) -> TrafficForecast:
        """Point parameters, the measured speed as target speed, the road without side groups.

        Parameters
        ----------
        observation : Observation
            The current observation.
        reach, speed, heading : numpy.ndarray
            The ego's rectangle boxes, speed and heading bounds over every sequence.
        """
        from minimaxplan.scenarios.traffic_models import forecast_traffic

        adapter = self.world.adapter
        road = adapter.road
        assert road is not None and adapter.scenario is not None
        flat = _without_side_groups(road)
        behaviour = adapter.scenario.behaviour
        a = np.mean(behaviour.theta_a_prior, axis=0)
        b = np.mean(behaviour.theta_b_prior, axis=0)
        beliefs: dict[int, VehicleBelief] = {}
        for agent, state in zip(observation.ids, observation.vehicles):
            prior = adapter.prior(int(agent), state)
            _, off = flat.frenet(np.array(prior.lanes), state[0], state[1])
            lane = int(np.array(prior.lanes)[np.argmin(np.abs(off))])
            routes = tuple(r for r in prior.routes if r[0] == lane) or ((lane,),)
            beliefs[int(agent)] = dataclasses.replace(
                prior,
                theta_a=Box(a, a),
                theta_b=Box(b, b),
                lanes=(lane,),
                routes=routes,
                target_speed=(max(float(state[2]), 0.0),) * 2,
            )
        return forecast_traffic(
            observation,
            flat,
            adapter.scenario,
            beliefs,
            steps=adapter.steps(HORIZON),
            ego_reach=reach,
            ego_speed=speed,
            ego_heading=heading,
            road_edges=False,
        )


class HighwayEnvOracleMethod(_SearchMethod):
    """The search against the other vehicles' true future (highway-env itself, the ego holding its targets)."""

    def forecast(self, observation: Observation, reach, speed, heading) -> TrafficForecast:
        """The true states of a deep copy of the environment stepped over `HORIZON`, the ego acting IDLE.

        Parameters
        ----------
        observation : Observation
            The current observation (its ids name the vehicles).
        reach, speed, heading : numpy.ndarray
            Unused (the copy's ego is simulated).

        Notes
        -----
        The reference of the suboptimality study, like `RoadOracleMethod`: the true
        parameters, target speeds, lane changes and routes (highway-env's own
        vehicles), the ego holding its current target lane and speed. Every state of
        the copy is a point box; a vehicle removed by highway-env has empty boxes.
        """
        adapter = self.world.adapter
        base = adapter.env.unwrapped
        twin = copy.deepcopy(base)
        order = [adapter.agent_id(v) for v in base.road.vehicles]
        index = {int(agent): j for j, agent in enumerate(observation.ids)}
        steps = adapter.steps(HORIZON)
        states = np.full((steps + 1, len(index), 4), np.nan)
        pairs = [(index[a], v) for a, v in zip(order, twin.road.vehicles) if a in index]
        for j, v in pairs:
            states[0, j] = (v.position[0], v.position[1], v.speed, v.heading)
        for n in range(1, steps + 1):
            twin.road.act()
            twin.road.step(adapter.dt)
            present = {id(v) for v in twin.road.vehicles}
            for j, v in pairs:
                if id(v) in present:
                    states[n, j] = (v.position[0], v.position[1], v.speed, v.heading)
        scenario = adapter.scenario
        assert scenario is not None
        boxes = _rect_boxes(np.nan_to_num(states), scenario.vehicle)
        gone = np.isnan(states).any(axis=2)
        boxes[gone] = (np.inf, np.inf, -np.inf, -np.inf)
        filled = np.where(gone[..., None], 0.0, states)
        return TrafficForecast(
            boxes, filled, filled, np.zeros(gone.shape, dtype=bool), np.asarray(observation.ids, dtype=int), adapter.dt
        )


class HighwayEnvIDMMethod(_HighwayEnvMethod):
    """highway-env's own rule-based ego (``IDMVehicle``: IDM and MOBIL), a reference point, not a planner.

    `start` hands the episode's ego to highway-env's ``IDMVehicle`` (`HighwayEnvWorld.drive_ego_by_idm`);
    it then decides by itself at every simulation step, whatever the library's action. It predicts
    nothing (no boxes to check). The ego keeps its target speed at reset (highway-env's MDPVehicle's).

    Parameters
    ----------
    scenario : HighwayEnvScenario
        The highway-env scenario (any other raises `UnsupportedScenario`).
    config : LoopConfig
        The loop settings (unused).
    """

    def start(self, world: HighwayEnvWorld) -> None:
        """Hand the ego to highway-env's IDM.

        Parameters
        ----------
        world : HighwayEnvWorld
            The episode, at reset.
        """
        world.drive_ego_by_idm()
        self.idle = [name for name, *_ in world.actions].index("IDLE")

    def decide(self, measurement: Observation) -> Policy:
        """IDLE, ignored by the IDM ego.

        Parameters
        ----------
        measurement : Observation
            Unused.
        """
        return _SearchPolicy(self.idle, self.idle, {})

    def report(self) -> dict:
        """Which driver the ego had."""
        return {"ego": "highway-env IDMVehicle (IDM and MOBIL)"}


@functools.lru_cache(maxsize=8)
def _without_side_groups(road: Road) -> Road:
    return Road(
        lanes=road.lanes,
        names=road.names,
        connections=road.connections,
        priorities=road.priorities,
        areas=road.areas,
        conflict_distance=road.conflict_distance,
    )


def highway_env_installed() -> bool:
    """Whether highway-env can be imported (checked without importing it)."""
    return importlib.util.find_spec("highway_env") is not None


if highway_env_installed():
    for _name, _env_id in HIGHWAY_ENV_SCENARIOS.items():
        register_scenario(_name, functools.partial(HighwayEnvScenario, _env_id), in_default_runs=False)
    for _name, (_env_id, _speeds) in HIGHWAY_ENV_VARIANTS.items():
        register_scenario(
            _name, functools.partial(HighwayEnvScenario, _env_id, target_speeds=_speeds), in_default_runs=False
        )
    register_method("robust", HighwayEnvRobustMethod)
    register_method("nominal", HighwayEnvNominalMethod)
    register_method("oracle", HighwayEnvOracleMethod)
    register_method("idm", HighwayEnvIDMMethod)
else:
    for _name in (*HIGHWAY_ENV_SCENARIOS, *HIGHWAY_ENV_VARIANTS):
        register_unavailable("scenario", _name, MISSING_VEHICLE_EXTRA)
    register_unavailable("method", "idm", MISSING_VEHICLE_EXTRA)
