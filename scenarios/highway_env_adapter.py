"""highway-env behind the library's traffic models (the ``vehicle`` extra; issue 12).

highway-env (Leurent, the simulator of the paper's reference code) is imported only
when a function of this module needs it: ``import minimaxplan.scenarios`` does not
import this module, and planners never do. What the adapter reads:

* the road network ``env.unwrapped.road.network`` into the library's `Road`
  (`road_from_highway_env`): highway-env's ``StraightLane`` and ``CircularLane`` are
  the library's `StraightLane` and `ArcLane` with the same formulas (same left normal,
  ``phi(s) = start_phase + d s / radius``, ``d = +1`` when ``clockwise``), the lanes
  of one edge ``(from, to)`` a side group, a connection wherever an edge ends where
  the next begins, the lanes' priorities;
* of every other vehicle only its position, speed and heading
  (`HighwayEnvAdapter.observe`, an `Observation` with stable agent ids); its lane is the
  geometric fact `prior_belief` derives from the position. Never its behaviour
  parameters, target lane, route, timers or target speed;
* the behaviour *family* (`highway_env_scenario`): the class constants that every
  ``LinearVehicle`` shares (the parameter ranges its ``randomize_behavior`` draws from,
  ``DISTANCE_WANTED``, ``TIME_WANTED``, ``ACC_MAX``, ``TAU_PURSUIT``, the bicycle's size),
  the structure a user of the field knows, mapped onto `BehaviourParameters`.

Time: the forecast runs at highway-env's own simulation step, ``dt = 1 /
simulation_frequency`` (0.2 s on highway-fast-v0, 1/15 s on intersection-v0), so that its
forward-Euler step is highway-env's step (``Vehicle.step``: the same bicycle, the same
order of updates), and a horizon of ``T`` seconds is ``round(T / dt)`` sub-steps.

highway-env writes behaviour constants onto its vehicle classes (``intersection-v0``
sets ``DISTANCE_WANTED``, ``COMFORT_ACC_MAX``, ``COMFORT_ACC_MIN`` on the other
vehicles' class), so an episode depends on what ran before in the process.
`VehicleClassConstants` snapshots every upper-case class attribute of highway-env's
vehicle classes and restores it; `HighwayEnvAdapter.reset` restores before every reset,
so the same seed gives the same episode whatever ran before (tested).
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from minimaxplan.models.errors import InputError

from .road import STRAIGHT, ArcLane, Road, StraightLane
from .road_world import HighwayScenario, Observation, TJunctionScenario
from .traffic_models import TrafficForecast, VehicleBelief, forecast_traffic, prior_belief
from .vehicles import BehaviourParameters, TrafficRules, VehicleParameters

__all__ = [
    "HIGHWAY_ENV_IDS",
    "MISSING_VEHICLE_EXTRA",
    "LINEAR_VEHICLE",
    "INTERSECTION_TARGET_SPEED",
    "require_highway_env",
    "VehicleClassConstants",
    "restore_vehicle_classes",
    "road_from_highway_env",
    "highway_env_scenario",
    "limits_of",
    "meta_action",
    "uncovered_reason",
    "HighwayEnvAdapter",
]

#: The highway-env environments the adapter runs.
HIGHWAY_ENV_IDS = ("highway-fast-v0", "intersection-v0")
#: What is missing, and how to install it, where highway-env cannot be imported.
MISSING_VEHICLE_EXTRA = "it needs highway-env, the vehicle extra: pip install 'minimaxplan[vehicle]'"
#: highway-env's class of the other vehicles (the paper's LinearVehicle law).
LINEAR_VEHICLE = "highway_env.vehicle.behavior.LinearVehicle"
#: Bounds of the other vehicles' hidden target speed at the intersection, m/s: they spawn
#: at 8 + N(0, 1) m/s (their target speed), highway-env's ``RegulatedRoad`` sets it to
#: 0 while one yields and to the lane's limit (10) afterwards; 12 is 4 standard
#: deviations above the spawn mean (a Gaussian is not bounded: P(> 12) = 3e-5).
INTERSECTION_TARGET_SPEED = (0.0, 12.0)
#: Lane-change settle bound of MOBIL, m: highway-env's vehicles may start a change whenever
#: their nearest lane is their target lane, i.e. within half a lane of its centre.
_MOBIL_SETTLED = 2.0
#: Curve lateral acceleration making the library's curve speed cap inactive, m/s^2
#: (highway-env's vehicles do not slow down for curves).
_NO_CURVE_CAP = 1e9
#: Modules whose classes' constants highway-env's environments may overwrite.
_VEHICLE_MODULES = (
    "highway_env.vehicle.objects",
    "highway_env.vehicle.kinematics",
    "highway_env.vehicle.controller",
    "highway_env.vehicle.behavior",
    "highway_env.vehicle.uncertainty.prediction",
)


def require_highway_env() -> Any:
    """Import highway-env (and register its environments with Gymnasium).

    Returns
    -------
    module
        ``highway_env``.

    Raises
    ------
    ImportError
        If the ``vehicle`` extra is not installed (``pip install 'minimaxplan[vehicle]'``).
    """
    try:
        return importlib.import_module("highway_env")
    except ImportError as exc:
        raise ImportError(f"minimaxplan.scenarios.highway_env_adapter: {MISSING_VEHICLE_EXTRA}") from exc


def _vehicle_classes() -> list[type]:
    require_highway_env()
    classes: list[type] = []
    for name in _VEHICLE_MODULES:
        module = importlib.import_module(name)
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__.startswith("highway_env.vehicle") and cls not in classes:
                classes.append(cls)
    return classes


def _constants(cls: type) -> dict[str, Any]:
    return {k: v for k, v in vars(cls).items() if k.isupper() and not callable(v)}


class VehicleClassConstants:
    """Snapshot of the upper-case class attributes of highway-env's vehicle classes.

    Notes
    -----
    Built at construction (so build it before any environment ran in the process: the
    module keeps one, `HighwayEnvAdapter` uses it). `restore` sets every recorded
    attribute back (by value: arrays and lists are copied) and deletes the upper-case
    attributes written onto a class since (``intersection-v0`` writes
    ``DISTANCE_WANTED`` onto ``LinearVehicle``, which inherits it from ``IDMVehicle``).
    """

    def __init__(self) -> None:
        self._saved = {cls: {k: _copy(v) for k, v in _constants(cls).items()} for cls in _vehicle_classes()}

    def changed(self) -> list[str]:
        """``"Class.NAME"`` of every constant that differs from the snapshot (added ones included)."""
        out = []
        for cls, saved in self._saved.items():
            now = _constants(cls)
            for k in sorted(set(now) | set(saved)):
                if k not in saved or k not in now or not _equal(now[k], saved[k]):
                    out.append(f"{cls.__name__}.{k}")
        return out

    def restore(self) -> None:
        """Put every class constant back to its snapshot."""
        for cls, saved in self._saved.items():
            for k in list(_constants(cls)):
                if k not in saved:
                    delattr(cls, k)
            for k, v in saved.items():
                setattr(cls, k, _copy(v))


def _copy(value):
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, list):
        return list(value)
    if isinstance(value, dict):
        return dict(value)
    return value


def _equal(a, b) -> bool:
    try:
        return bool(np.array_equal(np.asarray(a, dtype=object), np.asarray(b, dtype=object)))
    except Exception:  # pragma: no cover - exotic constants
        return a is b


_SNAPSHOT: VehicleClassConstants | None = None


def _snapshot() -> VehicleClassConstants:
    global _SNAPSHOT
    if _SNAPSHOT is None:
        _SNAPSHOT = VehicleClassConstants()
    return _SNAPSHOT


def restore_vehicle_classes() -> VehicleClassConstants:
    """Restore highway-env's vehicle class constants to the process's snapshot.

    The snapshot is taken at the first call of this function or the first
    `HighwayEnvAdapter` of the process, whichever comes first.

    Returns
    -------
    VehicleClassConstants
        The snapshot.
    """
    snapshot = _snapshot()
    snapshot.restore()
    return snapshot


# ------------------------------------------------------------------ the road
def road_from_highway_env(network) -> tuple[Road, dict[tuple, int]]:
    """The library's `Road` of a highway-env ``RoadNetwork``.

    Parameters
    ----------
    network : highway_env.road.road.RoadNetwork
        ``env.unwrapped.road.network``.

    Returns
    -------
    road : Road
        Lanes named ``"from>to:id"``; each edge's lanes a side group ordered right to left
        (by their start's offset along the first lane's left normal), connections where
        an edge's lane ends at the start of a lane of an edge leaving its end node, the
        lanes' priorities. No extra areas (highway-env's ``on_road`` is its lanes).
    index : dict
        highway-env's lane index ``(from, to, id)`` -> the library's lane index.

    Raises
    ------
    InputError
        For a lane that is neither straight nor circular (``SineLane``, ``PolyLane``: the
        library's `Road` has no such lanes).
    """
    hw = require_highway_env()
    lane_mod = hw.road.lane
    lanes: list = []
    names: list[str] = []
    keys: list[tuple] = []
    priorities: list[int] = []
    for _from, tos in network.graph.items():
        for _to, edge in tos.items():
            for i, lane in enumerate(edge):
                if type(lane) is lane_mod.StraightLane:
                    lanes.append(
                        StraightLane(np.array(lane.start, float), np.array(lane.end, float), float(lane.width))
                    )
                elif type(lane) is lane_mod.CircularLane:
                    sweep = float(lane.end_phase - lane.start_phase)
                    if np.sign(sweep) != lane.direction:
                        raise InputError(f"circular lane {(_from, _to, i)}: its phases do not follow its direction")
                    lanes.append(
                        ArcLane(
                            np.array(lane.center, float),
                            float(lane.radius),
                            float(lane.start_phase),
                            sweep,
                            float(lane.width),
                        )
                    )
                else:
                    raise InputError(
                        f"lane {(_from, _to, i)} is a {type(lane).__name__}: the library's Road has straight and arc lanes only"
                    )
                names.append(f"{_from}>{_to}:{i}")
                keys.append((_from, _to, i))
                priorities.append(int(getattr(lane, "priority", 0)))
    index = {key: k for k, key in enumerate(keys)}
    connections = []
    for a, (_, ta, _) in enumerate(keys):
        end = lanes[a].position(lanes[a].length)
        for b, (fb, _, _) in enumerate(keys):
            if fb == ta and b != a and np.linalg.norm(lanes[b].position(0.0) - end) <= 1e-6:
                connections.append((a, b))
    groups = []
    for _from, tos in network.graph.items():
        for _to, edge in tos.items():
            if len(edge) > 1:
                members = [index[(_from, _to, i)] for i in range(len(edge))]
                first = lanes[members[0]]
                normal = (
                    np.array([-first.direction[1], first.direction[0]]) if isinstance(first, StraightLane) else None
                )
                if normal is None:
                    continue
                order = sorted(members, key=lambda k: float(np.dot(lanes[k].position(0.0) - first.start, normal)))
                groups.append(tuple(order))
    road = Road(
        lanes=tuple(lanes),
        names=tuple(names),
        connections=tuple(connections),
        side_groups=tuple(groups),
        priorities=tuple(priorities),
    )
    return road, index


# ------------------------------------------------------------------ the model family
def highway_env_scenario(env) -> HighwayScenario | TJunctionScenario:
    """The forecast's constants for a highway-env environment (after its reset).

    Parameters
    ----------
    env : gymnasium.Env
        ``highway-fast-v0`` or ``intersection-v0`` (or a variant) with ``LinearVehicle``
        other vehicles, after ``reset`` (``intersection-v0`` writes its constants then).

    Returns
    -------
    HighwayScenario or TJunctionScenario
        ``dt = 1 / simulation_frequency``; ``vehicle`` the classes' length, width,
        ``MAX_SPEED`` and ``MAX_STEERING_ANGLE``; ``behaviour`` the ``LinearVehicle``
        family (its nominal gains and ranges, ``d0 = DISTANCE_WANTED - LENGTH`` since
        highway-env measures centre to centre, ``T = TIME_WANTED``, ``TAU_PURSUIT``,
        ``ACC_MAX``, the route switch ``AbstractLane.VEHICLE_LENGTH / 2`` before a lane's
        end, ``follow_road``'s) with no disturbance (highway-env has none); no measurement noise (the
        adapter reads exact states); the target-speed range (``vehicle_speed`` on the
        highway: ``[0.7, 0.8]`` of the lanes' speed limit, ``create_random``'s draw;
        ``main_speed`` = `INTERSECTION_TARGET_SPEED` at the intersection); MOBIL's timer
        period ``LANE_CHANGE_DELAY`` as the lane-change interval, ``lane_change_settled``
        half a lane (MOBIL starts a change from anywhere in its nearest lane), no gap
        margin, no curve speed cap.
    """
    hw = require_highway_env()
    base = env.unwrapped
    cls = hw.utils.class_from_path(base.config["other_vehicles_type"])
    if not issubclass(cls, hw.vehicle.behavior.LinearVehicle):
        raise InputError(f"the adapter models LinearVehicle other vehicles, got {cls.__name__}")
    nominal_a = np.mean(cls.ACCELERATION_RANGE, axis=0)
    nominal_b = np.mean(cls.STEERING_RANGE, axis=0)
    behaviour = BehaviourParameters(
        theta_a_nominal=tuple(float(v) for v in nominal_a),
        theta_a_scale=(
            float(np.min(cls.ACCELERATION_RANGE[0] / nominal_a)),
            float(np.max(cls.ACCELERATION_RANGE[1] / nominal_a)),
        ),
        theta_b_nominal=tuple(float(v) for v in nominal_b),
        theta_b_spread=tuple(float(v) for v in (cls.STEERING_RANGE[1] - cls.STEERING_RANGE[0]) / 2),
        standstill_distance=float(cls.DISTANCE_WANTED - cls.LENGTH),
        time_headway=float(cls.TIME_WANTED),
        pursuit_time=float(cls.TAU_PURSUIT),
        route_switch_distance=float(hw.road.lane.AbstractLane.VEHICLE_LENGTH) / 2,
        acceleration_bound=float(cls.ACC_MAX),
        disturbance_bound=0.0,
    )
    vehicle = VehicleParameters(
        length=float(cls.LENGTH),
        width=float(cls.WIDTH),
        max_speed=float(cls.MAX_SPEED),
        max_steering=float(cls.MAX_STEERING_ANGLE),
    )
    delay = float(cls.LANE_CHANGE_DELAY)
    rules = TrafficRules(
        lane_change_interval=(delay, delay),
        lane_change_settled=_MOBIL_SETTLED,
        lane_change_margin=0.0,
        curve_lateral_acceleration=_NO_CURVE_CAP,
        curve_approach=0.0,
    )
    common: dict[str, Any] = {
        "vehicle": vehicle,
        "behaviour": behaviour,
        "rules": rules,
        "dt": 1.0 / float(base.config["simulation_frequency"]),
        "measurement_noise": (0.0, 0.0, 0.0, 0.0),
    }
    if "intersection" in type(base).__name__.lower():
        # the scenario needs a positive range; the adapter's beliefs carry the true one (from 0)
        return TJunctionScenario(main_speed=(min(limits_of(base)), INTERSECTION_TARGET_SPEED[1]), **common)
    limits = limits_of(base)
    speeds = (0.7 * min(limits), 0.8 * max(limits)) if limits else tuple(float(v) for v in cls.DEFAULT_INITIAL_SPEEDS)
    return HighwayScenario(vehicle_speed=speeds, **common)


def limits_of(base) -> list[float]:
    """The speed limits of the lanes of a highway-env environment that have one, m/s.

    Parameters
    ----------
    base : highway_env.envs.common.abstract.AbstractEnv
        ``env.unwrapped``, after its reset.
    """
    graph = base.road.network.graph
    return [
        float(lane.speed_limit) for tos in graph.values() for edge in tos.values() for lane in edge if lane.speed_limit
    ]


def meta_action(env, name: str, lane_change: int = 0) -> int:
    """The index of a planner action among highway-env's discrete meta-actions.

    Parameters
    ----------
    env : gymnasium.Env
        A highway-env environment with a ``DiscreteMetaAction`` action type.
    name : str
        The planner's action name (`minimaxplan.planners.bicycle_model.HIGHWAY_ACTIONS`,
        `TJUNCTION_ACTIONS`): ``IDLE``, ``FASTER``, ``SLOWER``, ``LANE_LEFT``, ``LANE_RIGHT``.
    lane_change : int
        Ignored for speed actions.

    Returns
    -------
    int
        ``env.unwrapped.action_type.actions_indexes[...]``.

    Notes
    -----
    The library's ``LANE_LEFT`` moves to the side lane on the left of the direction of
    travel (higher lane index in its side groups, +y on highway-fast-v0); highway-env's
    ``LANE_LEFT`` decrements the lane id, which is the lane on the right in the same
    coordinates (highway-env draws y downwards). So the library's ``LANE_LEFT`` is
    highway-env's ``LANE_RIGHT`` and the reverse; the speed actions keep their names.
    """
    indexes: Mapping[str, int] = env.unwrapped.action_type.actions_indexes
    swap = {"LANE_LEFT": "LANE_RIGHT", "LANE_RIGHT": "LANE_LEFT"}
    target = swap.get(name, name)
    if target not in indexes:
        raise InputError(f"action {name!r} is not among highway-env's {sorted(indexes)}")
    return int(indexes[target])


def uncovered_reason(first: dict, now: dict) -> str | None:
    """Why the library's traffic model does not cover a vehicle at a step, or None where it does.

    For evaluation (the containment tests and benchmarks): the forecast from an observation
    holds a vehicle's true state while it keeps its lane, neither crashes nor reverses
    (highway-env's ``MIN_SPEED`` is below 0, the model's speed floor 0). A switch to the next
    route lane is covered (`BehaviourParameters.route_switch_distance`). Once a reason
    applies, the vehicle stays uncovered for the rest of that forecast: callers keep the
    first reason.

    Parameters
    ----------
    first, now : dict
        `HighwayEnvAdapter.ground_truth` entries of the vehicle at the forecast's start and
        at the step.

    Returns
    -------
    str or None
        ``"lane_change"``, ``"crashed"``, ``"reversing"`` or None.
    """
    if first["lane_change"] or now["lane_change"]:
        return "lane_change"
    if now["crashed"]:
        return "crashed"
    if now["state"][2] < 0.0:
        return "reversing"
    return None


# ------------------------------------------------------------------ the adapter
@dataclass
class _Ids:
    by_object: dict

    def of(self, vehicle) -> int:
        key = id(vehicle)
        if key not in self.by_object:
            self.by_object[key] = (len(self.by_object) + 1, vehicle)
        return int(self.by_object[key][0])


class HighwayEnvAdapter:
    """One highway-env environment read into the library's road, scenario and observations.

    Parameters
    ----------
    env_id : str
        One of `HIGHWAY_ENV_IDS` (or another highway-env id with straight and circular lanes).
    config : mapping, optional
        Extra highway-env configuration (e.g. ``{"simulation_frequency": 15}``);
        ``other_vehicles_type`` is always `LINEAR_VEHICLE`.

    Attributes
    ----------
    env : gymnasium.Env
        The environment.
    road : Road
        Its road (after `reset`).
    lane_index : dict
        highway-env lane index -> the library's lane index.
    scenario : HighwayScenario or TJunctionScenario
        `highway_env_scenario` (after `reset`).
    constants : VehicleClassConstants
        The process's snapshot of highway-env's class constants (taken at the first
        adapter), restored before every reset.
    """

    def __init__(self, env_id: str, *, config: Mapping[str, Any] | None = None) -> None:
        require_highway_env()
        import gymnasium

        self.constants = restore_vehicle_classes()
        self.env_id = str(env_id)
        self.env: Any = gymnasium.make(
            self.env_id, config={**dict(config or {}), "other_vehicles_type": LINEAR_VEHICLE}
        )
        self.road: Road | None = None
        self.lane_index: dict[tuple, int] = {}
        self.scenario: HighwayScenario | TJunctionScenario | None = None
        self._ids = _Ids({})

    def reset(self, seed: int) -> Observation:
        """A fresh episode: restore highway-env's class constants, reset with ``seed``, read the road.

        Parameters
        ----------
        seed : int
            highway-env's seed.

        Returns
        -------
        Observation
            `observe` of the first state.
        """
        self.constants.restore()
        self.env.reset(seed=int(seed))
        self._ids = _Ids({})
        self.road, self.lane_index = road_from_highway_env(self.env.unwrapped.road.network)
        self.scenario = highway_env_scenario(self.env)
        return self.observe()

    @property
    def dt(self) -> float:
        """highway-env's simulation step, s (the forecast's sub-step)."""
        return 1.0 / float(self.env.unwrapped.config["simulation_frequency"])

    def steps(self, horizon: float) -> int:
        """Sub-steps in ``horizon`` seconds, ``round(horizon / dt)``.

        Parameters
        ----------
        horizon : float
            Seconds.
        """
        return int(round(float(horizon) / self.dt))

    def agent_id(self, vehicle) -> int:
        """The stable agent index of a highway-env vehicle in this episode (1, 2, ...; the ego is 0).

        Parameters
        ----------
        vehicle : highway_env.vehicle.kinematics.Vehicle
            A vehicle of ``env.unwrapped.road.vehicles``.
        """
        if vehicle is self.env.unwrapped.vehicle:
            return 0
        return self._ids.of(vehicle)

    def ground_truth(self) -> dict[int, dict]:
        """Every other vehicle's true state and lane facts, by agent id: for evaluation only.

        It reads what the forecast never does (the target lane, the crash flag), to tell
        which vehicle-steps the model covers (`uncovered_reason`).

        Returns
        -------
        dict
            ``id -> {"state": (x, y, v, psi), "lane_change": bool (its target lane is a
            neighbour of its lane), "target": highway-env's target lane index, "crashed":
            bool}``.
        """
        base = self.env.unwrapped
        out = {}
        for v in base.road.vehicles:
            if v is base.vehicle:
                continue
            lane, target = v.lane_index, v.target_lane_index
            out[self.agent_id(v)] = {
                "state": np.array([v.position[0], v.position[1], v.speed, v.heading]),
                "lane_change": lane[:2] == target[:2] and lane[2] != target[2],
                "target": target,
                "crashed": bool(v.crashed),
            }
        return out

    def observe(self) -> Observation:
        """The ego and every other vehicle's ``(x, y, v, psi)``, read from highway-env (exact).

        Returns
        -------
        Observation
            ``time`` highway-env's simulated time, ``ego`` the controlled vehicle,
            ``vehicles`` and ``ids`` the others (in the road's order).
        """
        base = self.env.unwrapped
        ego = base.vehicle
        others = [v for v in base.road.vehicles if v is not ego]
        rows = np.array([[v.position[0], v.position[1], v.speed, v.heading] for v in others], dtype=float).reshape(
            -1, 4
        )
        return Observation(
            time=float(base.steps) * self.dt,
            ego=np.array([ego.position[0], ego.position[1], ego.speed, ego.heading], dtype=float),
            vehicles=rows,
            ids=np.array([self.agent_id(v) for v in others], dtype=int),
        )

    def forecast(
        self,
        observation: Observation,
        horizon: float,
        *,
        ego_reach,
        ego_speed=None,
        ego_heading=None,
        beliefs: Mapping[int, VehicleBelief] | None = None,
        road_edges: bool | None = None,
    ) -> TrafficForecast:
        """`forecast_traffic` of an observation over ``horizon`` seconds at highway-env's step.

        Parameters
        ----------
        observation : Observation
            From `observe`.
        horizon : float
            Seconds; ``steps(horizon)`` sub-steps of `dt`.
        ego_reach, ego_speed, ego_heading
            As `forecast_traffic` (shape ``(steps + 1, 4)`` and ``(steps + 1, 2)``).
        beliefs : mapping, optional
            Per agent; default: `prior_belief` of every vehicle (the reference priors).
        road_edges : bool, optional
            Cut coarse boxes to the road (`forecast_traffic`: sound while highway-env's
            vehicles keep their rectangles on the lanes). Default: True on a road of
            straight lanes only (highway-fast-v0, where the containment tests measure
            it), False otherwise (highway-env's turning vehicles are not known to keep
            every corner in a lane strip).

        Returns
        -------
        TrafficForecast
        """
        if self.road is None or self.scenario is None:
            raise InputError("call reset first")
        given = dict(beliefs or {})
        for agent, state in zip(observation.ids, observation.vehicles):
            if int(agent) not in given:
                given[int(agent)] = self.prior(int(agent), state)
        return forecast_traffic(
            observation,
            self.road,
            self.scenario,
            given,
            steps=self.steps(horizon),
            ego_reach=ego_reach,
            ego_speed=ego_speed,
            ego_heading=ego_heading,
            road_edges=bool(np.all(self.road.kinds == STRAIGHT)) if road_edges is None else bool(road_edges),
        )

    @property
    def target_speed(self) -> tuple[float, float]:
        """Bounds of the other vehicles' hidden target speed, m/s (``vehicle_speed`` or `INTERSECTION_TARGET_SPEED`)."""
        if isinstance(self.scenario, HighwayScenario):
            return self.scenario.target_speeds
        return INTERSECTION_TARGET_SPEED

    def prior(self, agent: int, measured) -> VehicleBelief:
        """`prior_belief` of a measured vehicle with the target-speed bounds `target_speed`.

        Parameters
        ----------
        agent : int
            Its agent index.
        measured : array_like, shape (4,)
            Its ``(x, y, v, psi)``.
        """
        if self.road is None or self.scenario is None:
            raise InputError("call reset first")
        belief = prior_belief(agent, measured, self.road, self.scenario)
        return dataclasses.replace(belief, target_speed=self.target_speed)

    def step(self, name: str) -> tuple[Observation, bool, bool]:
        """Apply a planner action (by name, `meta_action`) for one policy step.

        Parameters
        ----------
        name : str
            ``IDLE``, ``FASTER``, ``SLOWER``, ``LANE_LEFT`` or ``LANE_RIGHT``.

        Returns
        -------
        observation : Observation
        terminated, truncated : bool
            highway-env's flags.
        """
        _, _, terminated, truncated, _ = self.env.step(meta_action(self.env, name))
        return self.observe(), bool(terminated), bool(truncated)

    def close(self) -> None:
        """Close the environment."""
        self.env.close()
