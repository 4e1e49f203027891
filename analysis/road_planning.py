"""The tree-search methods of the road worlds: robust, nominal, oracle (Table 4, Figure 6).

Importing this module registers ``robust``, ``nominal`` and ``oracle`` for the road
scenarios (`minimaxplan.analysis.road_scenario`); the robot's factories of the same
names raise `UnsupportedScenario` for them, and these for the robot's.

All three plan with `RobustTreePlanner` (K = 100, gamma = 0.9 by default) over the
same ego model, `BicycleModel`: the ego knows its own state exactly and has no
disturbance, so its predicted trajectory is a point, computed by the compiled bicycle
and controllers that the world steps the ego with (bit for bit). The actions are the
paper's (`HIGHWAY_ACTIONS`, `TJUNCTION_ACTIONS`), each a saturated low-level controller
held for one decision (5 sub-steps of 0.1 s). The reward is `DrivingReward` (the
paper's vehicle cost flipped into [0, 1]) with, as obstacles, a table of boxes of the
other vehicles over the next `FORECAST_STEPS` sub-steps; beyond them the reward is 0,
so no plan relies on what is not forecast. The methods differ only in that table:

robust
    `forecast_traffic` of every measured vehicle under its `VehicleBelief` from the
    `TrafficLearner` (LP elimination of its intentions, LP boxes of its parameters):
    boxes that contain the vehicle for every parameter, intention, switch time,
    disturbance and measurement noise the data allow. The ego is a possible leader of
    the vehicles behind it, and a vehicle beside it may not change into its lane while
    the world's gap rule fails against it: its reach (`ego_reach`) enters the forecast.
    On the highway there are two forecasts: one from the reach over every action
    sequence, the obstacles of every path, and one from the reach of the lane-keeping
    actions (`lane_keeping_actions`), the obstacles of the paths that have not changed
    lane (`BicycleModel`'s ``lane_keeping_reward``). Sound because a forecast's boxes
    up to a sub-step read the reach only up to it (tested): a path that keeps its lane
    up to sub-step n is, up to n, a lane-keeping trajectory. Without the second one
    the ego, whose reach may leave its lane within a second, could never rule out a
    cut-in beside it, and every plan would end in a possible collision. Each forecast
    is intersected with the previous decision's forecast for any ego at the sub-steps
    they share (`intersect_forecasts`: both contain the true traffic, and they are not
    nested). Where the ego can stop (the T-junction), when the tree's best plan may collide within the
    forecast, the executed first action is the one whose examined plans stay clear of
    every box longest (`latest_collision_action`): the tree's, unless speeding first
    would meet a box sooner than another first action.
nominal
    Certainty equivalence: the other vehicles simulated from their measured states
    under the LinearVehicle law with the least-squares parameters and the
    minimum-error route (`TrafficLearner.nominal`), no disturbance and no future lane
    change, the ego holding its current speed level and lane; their rectangles' boxes.
oracle
    The same simulation from the true states with the true parameters, target speeds
    and intentions (the reference of the suboptimality study).

The robust method's policy is a `PredictingPolicy`: after every sub-step of an
executed decision, the episode loop checks that the true ego equals its predicted
point and that every forecast vehicle lies in its state box (``boxes_checked``,
``boxes_missed``): the boxes of the lane-keeping forecast when the executed action
keeps the lane, else those of the forecast for any ego.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from minimaxplan.kernels.bicycle import apply_action, ego_control
from minimaxplan.models import DimensionError, InputError
from minimaxplan.models.validation import as_count, as_positive_scalar, check_instance
from minimaxplan.planners import RobustTreePlanner
from minimaxplan.planners.bicycle_model import (
    HIGHWAY_ACTIONS,
    HIGHWAY_TARGET_SPEEDS,
    LANE_KEEPING_PREFIX,
    TJUNCTION_ACTIONS,
    TJUNCTION_TARGET_SPEEDS,
    BicycleModel,
    BicycleState,
    ego_controller,
)
from minimaxplan.planners.latest_collision import latest_collision_action
from minimaxplan.scenarios.driving_reward import world_reward
from minimaxplan.scenarios.forecast_intersection import intersect_forecasts
from minimaxplan.scenarios.road import lane_geometry
from minimaxplan.scenarios.road_world import HighwayScenario, Observation, RoadWorld
from minimaxplan.scenarios.traffic_models import TrafficForecast, VehicleBelief, forecast_traffic
from minimaxplan.scenarios.vehicles import BehaviourParameters, TrafficRules, traffic_step, vehicle_corners

from .episode import LoopConfig
from .registry import Method, Policy, Transition, UnsupportedScenario, register_method
from .road_scenario import DrivingWorld, RoadScenario
from .traffic_learning import TrafficLearner

__all__ = [
    "FORECAST_STEPS",
    "RoadPlanningMethod",
    "RoadRobustMethod",
    "RoadNominalMethod",
    "RoadOracleMethod",
    "EgoSetup",
    "ObstacleTables",
    "conservative_first",
    "ego_reach",
    "lane_keeping_actions",
    "lane_keeping_reach",
    "point_forecast",
]

#: Sub-steps of the other vehicles' forecast (5 s at dt = 0.1 s): the planner's
#: reward is 0 beyond them.
FORECAST_STEPS = 50


def conservative_first(actions: tuple) -> tuple:
    """The actions with SLOWER first, then IDLE, then the others in their order.

    `RobustTreePlanner` breaks ties between root actions by their index. When every
    action may collide within the forecast (all lower bounds 0), that tie is broken
    towards braking instead of towards the paper's first action (LANE_LEFT).

    Parameters
    ----------
    actions : tuple of (str, int, int)
        ``(name, speed change, lane change)`` per action (`HIGHWAY_ACTIONS`,
        `TJUNCTION_ACTIONS`).
    """
    rank = {"SLOWER": 0, "IDLE": 1}
    return tuple(sorted(actions, key=lambda a: rank.get(a[0], 2)))


class EgoSetup:
    """The ego of one road episode: its controllers, actions, reward and initial speed level and lane.

    Parameters
    ----------
    world : RoadWorld
        The episode (with an ego).

    Attributes
    ----------
    controller : EgoController
        The compiled controllers (`ego_controller`) on the road's lanes (with the ego's
        route at the T-junction).
    actions : tuple
        `HIGHWAY_ACTIONS` or `TJUNCTION_ACTIONS`.
    speeds : tuple of float
        The speed levels' target speeds, m/s.
    reward : DrivingReward
        The reward with an empty obstacle table (`DrivingReward.with_obstacles` gives
        each decision's).
    level, lane : int
        The speed level nearest to the ego's initial speed, and its lane.
    """

    def __init__(self, world: RoadWorld) -> None:
        road, scenario = world.road, world.scenario
        vehicle = scenario.vehicle
        state = world.ego_state
        if world.kind == "highway":
            self.actions: tuple = conservative_first(HIGHWAY_ACTIONS)
            self.speeds: tuple = HIGHWAY_TARGET_SPEEDS
            lanes = lane_geometry(road)
            route: tuple[int, ...] = ()
        else:
            self.actions = conservative_first(TJUNCTION_ACTIONS)
            self.speeds = TJUNCTION_TARGET_SPEEDS
            route = tuple(int(lane) for lane in world.traffic.routes[0] if lane >= 0)
            lanes = lane_geometry(road, route)
        self.route = route
        self.controller = ego_controller(
            lanes,
            self.speeds,
            acceleration_bound=scenario.ego_acceleration_bound,
            length=vehicle.length,
            max_speed=vehicle.max_speed,
            max_steering=vehicle.max_steering,
            dt=scenario.dt,
        )
        self.reward = world_reward(world)
        self.level = int(np.argmin(np.abs(np.asarray(self.speeds) - state[2])))
        self.lane = int(world.traffic.lane[0])


#: Decisions over which the ego's reach is enumerated exactly (every action sequence);
#: after them it grows by the largest speed (see `ego_reach`).
REACH_DECISIONS = 2


def lane_keeping_actions(actions: tuple) -> tuple[int, ...]:
    """The indices of the actions that do not change the target lane (speed changes only).

    Parameters
    ----------
    actions : tuple of (str, int, int)
        ``(name, speed change, lane change)`` per action (`EgoSetup.actions`).

    Returns
    -------
    tuple of int
    """
    return tuple(i for i, (_, _, lane_change) in enumerate(actions) if lane_change == 0)


def ego_reach(model: BicycleModel, root, speed_bounds: tuple[float, float], steps: int, dt: float, vehicle):
    """Boxes that contain the ego's whole rectangle, speed and heading at each sub-step under any action sequence.

    Parameters
    ----------
    model : BicycleModel
        The ego (deterministic).
    root : BicycleState
        Its state now.
    speed_bounds : tuple of 2 float
        ``(low, high)`` that contain the ego's speed at every future sub-step whatever
        its actions: the controllers track a target speed without overshoot (the gain
        times dt is below 1 and the acceleration is clipped), so the speed stays
        between ``min(v, lowest target)`` and ``max(v, highest target)``.
    steps : int
        H.
    dt : float
        Sub-step, s.
    vehicle : VehicleParameters
        The ego's rectangle.

    Returns
    -------
    reach : numpy.ndarray, shape (steps + 1, 4)
        ``[x_lo, y_lo, x_hi, y_hi]``.
    speed, heading : numpy.ndarray, shape (steps + 1, 2)
        ``(low, high)`` of the speed (m/s) and heading (rad).

    Notes
    -----
    For the first `REACH_DECISIONS` decisions every action sequence is rolled out with
    the model (the ego is a point: this is its exact reach, the boxes of the rectangles'
    corners, rounded outward); from the last enumerated sub-step on, the centre moves
    at most ``high * dt`` per sub-step in any direction, the heading is unbounded.
    """
    check_instance("model", model, BicycleModel)
    steps = as_count("steps", steps)
    dt = as_positive_scalar("dt", dt)
    low, high = (as_positive_scalar(f"speed_bounds[{i}]", b, allow_zero=True) for i, b in enumerate(speed_bounds))
    if low > high:
        raise InputError(f"speed_bounds must satisfy low <= high, got {tuple(speed_bounds)}")
    S = model.substeps
    enumerated = min(steps, REACH_DECISIONS * S)
    frontier = [root]
    states = [np.asarray(root.x, dtype=float)[None]]
    for _ in range(REACH_DECISIONS):
        nxt, rows = [], []
        for state in frontier:
            for a in model.actions:
                sub, _, after = model.predict(state, a)
                nxt.append(after)
                rows.append(sub)
        frontier = nxt
        states.append(np.stack(rows, axis=1))  # (S, sequences, 4)
    per_step = [states[0]]
    for d in range(1, REACH_DECISIONS + 1):
        # sequences of decision d extend those of d - 1: every sub-step row holds all of them
        per_step.extend(states[d][k] for k in range(S))
    per_step = per_step[: enumerated + 1]
    reach = np.empty((steps + 1, 4))
    speed = np.empty((steps + 1, 2))
    heading = np.empty((steps + 1, 2))
    _hull_rows(per_step, vehicle, reach, speed, heading)
    last = per_step[-1]
    centre_lo, centre_hi = last[:, :2].min(axis=0), last[:, :2].max(axis=0)
    half_diagonal = 0.5 * float(np.hypot(vehicle.length, vehicle.width))
    for n in range(enumerated + 1, steps + 1):
        radius = high * dt * (n - enumerated) + half_diagonal
        reach[n, :2] = np.nextafter(centre_lo - radius, -np.inf)
        reach[n, 2:] = np.nextafter(centre_hi + radius, np.inf)
        speed[n] = low, high
        heading[n] = -np.pi, np.pi
    return reach, speed, heading


def _hull_rows(per_step: list, vehicle, reach: np.ndarray, speed: np.ndarray, heading: np.ndarray) -> None:
    """Rows ``n < len(per_step)`` of the reach: the boxes of the rectangles, speeds and headings at n, rounded outward."""
    for n, at_n in enumerate(per_step):
        corners = vehicle_corners(at_n, vehicle).reshape(-1, 2)
        reach[n, :2] = np.nextafter(corners.min(axis=0), -np.inf)
        reach[n, 2:] = np.nextafter(corners.max(axis=0), np.inf)
        speed[n] = np.nextafter(at_n[:, 2].min(), -np.inf), np.nextafter(at_n[:, 2].max(), np.inf)
        heading[n] = np.nextafter(at_n[:, 3].min(), -np.inf), np.nextafter(at_n[:, 3].max(), np.inf)


def lane_keeping_reach(model: BicycleModel, root, actions: tuple[int, ...], steps: int, vehicle):
    """The ego's exact reach along the lane-keeping family: `LANE_KEEPING_PREFIX` decisions of ``actions``, then one held.

    Parameters
    ----------
    model : BicycleModel
        The ego (deterministic).
    root : BicycleState
        Its state now.
    actions : tuple of int
        The actions that do not change the target lane (`lane_keeping_actions`).
    steps : int
        H.
    vehicle : VehicleParameters
        The ego's rectangle.

    Returns
    -------
    reach : numpy.ndarray, shape (steps + 1, 4)
        ``[x_lo, y_lo, x_hi, y_hi]``: the boxes of the rectangles of every path of the
        family at each sub-step, rounded outward.
    speed, heading : numpy.ndarray, shape (steps + 1, 2)
        ``(low, high)`` of the speed (m/s) and heading (rad).

    Notes
    -----
    Every path of the family is rolled out with the model to the horizon (``3^D``
    prefixes for three actions and D = `LANE_KEEPING_PREFIX`, each continued by every
    held action): the boxes are exact (the ego is a point), with no growth bound, so
    that the ego's lateral position stays known over the whole forecast. This is the
    reach of `BicycleModel`'s ``lane_keeping_reward``: the paths with ``kept`` states.
    """
    check_instance("model", model, BicycleModel)
    steps = as_count("steps", steps)
    if not actions or any(a not in model.actions for a in actions):
        raise InputError(f"actions must be a non-empty tuple of the model's actions {model.actions}, got {actions!r}")
    S = model.substeps
    decisions = -(-steps // S)
    prefix = min(LANE_KEEPING_PREFIX, decisions)
    frontier = [root]
    per_step = [np.asarray(root.x, dtype=float)[None]]
    for _ in range(prefix):
        nxt, rows = [], []
        for state in frontier:
            for a in actions:
                sub, _, after = model.predict(state, a)
                nxt.append(after)
                rows.append(sub)
        frontier = nxt
        block = np.stack(rows, axis=1)  # (S, sequences, 4)
        per_step.extend(block[k] for k in range(S))
    held = [(state, a) for state in frontier for a in actions]
    for _ in range(decisions - prefix):
        rows, moved = [], []
        for state, a in held:
            sub, _, after = model.predict(state, a)
            moved.append((after, a))
            rows.append(sub)
        held = moved
        block = np.stack(rows, axis=1)
        per_step.extend(block[k] for k in range(S))
    reach = np.empty((steps + 1, 4))
    speed = np.empty((steps + 1, 2))
    heading = np.empty((steps + 1, 2))
    _hull_rows(per_step[: steps + 1], vehicle, reach, speed, heading)
    return reach, speed, heading


def _rectangle_boxes(states: np.ndarray, active: np.ndarray, vehicle) -> np.ndarray:
    """Axis-aligned boxes ``[x_lo, y_lo, x_hi, y_hi]`` of the rectangles of ``states`` (m, 4); empty where inactive."""
    corners = vehicle_corners(states, vehicle)  # (m, 4, 2)
    boxes = np.concatenate([corners.min(axis=1), corners.max(axis=1)], axis=1)
    boxes[~active] = (np.inf, np.inf, -np.inf, -np.inf)
    return boxes


def point_forecast(world: RoadWorld, traffic, ego: EgoSetup, level: int, lane: int, steps: int) -> np.ndarray:
    """Boxes of the other vehicles' rectangles along one simulated future (nominal and oracle).

    The world's own law (`traffic_step`) from ``traffic`` with no disturbance and no
    lane-change decision, the ego driven by its controllers at speed level ``level``
    towards ``lane``.

    Parameters
    ----------
    world : RoadWorld
        The episode (road, constants, the current sub-step).
    traffic : TrafficState
        The state to simulate from (the truth for the oracle, the estimates for nominal).
    ego : EgoSetup
        The ego's controllers.
    level, lane : int
        The ego's speed level and target lane, held.
    steps : int
        H.

    Returns
    -------
    numpy.ndarray, shape (steps + 1, m, 4)
        Rows for the agents ``1 .. n-1`` (every other vehicle, in agent order).
    """
    scenario = world.scenario
    behaviour = BehaviourParameters(**{**scenario.behaviour.to_dict(), "disturbance_bound": 0.0})
    rules = TrafficRules(**{**scenario.rules.to_dict(), "lane_change_probability": 0.0})
    rng = np.random.default_rng(0)  # drawn from but unused: no disturbance, no lane change
    vehicle = scenario.vehicle
    out = np.empty((steps + 1, len(traffic) - 1, 4))
    out[0] = _rectangle_boxes(traffic.states[1:], traffic.active[1:], vehicle)
    controls = np.zeros((len(traffic), 2))
    for n in range(steps):
        controls[0], lane = ego_control(ego.controller, traffic.states[0], level, lane)
        traffic, _ = traffic_step(
            traffic,
            world.road,
            controls,
            dt=scenario.dt,
            step_index=world.step_index + n,
            rng=rng,
            behaviour=behaviour,
            rules=rules,
            vehicle=vehicle,
        )
        out[n + 1] = _rectangle_boxes(traffic.states[1:], traffic.active[1:], vehicle)
    return out


@dataclass(frozen=True, eq=False)
class ObstacleTables:
    """One decision's obstacle tables for the planner's reward, and the boxes the runtime check reads.

    Attributes
    ----------
    table : numpy.ndarray, shape (H+1, m, 4)
        Boxes ``[x_lo, y_lo, x_hi, y_hi]`` of the other vehicles' rectangles per sub-step,
        for any ego trajectory of the planner (the reward of `BicycleModel`).
    checked : dict
        Sub-step (1-based) to ``{name: (lower, upper)}`` state boxes that the episode loop
        checks the true states against after each sub-step of the executed decision.
    lane_keeping_table : numpy.ndarray or None
        The same for an ego that keeps its target lane (the ``lane_keeping_reward`` of
        `BicycleModel`); None when every action keeps the lane or the method does not
        make the distinction.
    lane_keeping_checked : dict or None
        The boxes to check when the executed decision keeps the lane.
    """

    table: np.ndarray
    checked: dict
    lane_keeping_table: np.ndarray | None = None
    lane_keeping_checked: dict | None = None

    def __post_init__(self) -> None:
        if (self.lane_keeping_table is None) != (self.lane_keeping_checked is None):
            raise InputError(
                "lane_keeping_table and lane_keeping_checked go together (the boxes the plan of a "
                "lane-keeping path was valued on are the ones to check): got only one of them"
            )
        table = np.asarray(self.table)
        if self.lane_keeping_table is not None and np.shape(self.lane_keeping_table) != table.shape:
            raise DimensionError(
                f"lane_keeping_table must have the shape of table {table.shape}, "
                f"got shape {np.shape(self.lane_keeping_table)}"
            )


class _EgoPolicy:
    """The ego's controllers at one speed level and target lane for one decision (a `PredictingPolicy`)."""

    def __init__(self, controller, level: int, lane: int, predicted: Mapping[int, Mapping[str, tuple]]) -> None:
        self.controller = controller
        self.level = level
        self.lane = lane
        self._predicted = predicted

    def control(self, measurement: Observation) -> np.ndarray:
        """``(acceleration, steering)`` of the ego's controllers at its (exactly measured) state."""
        control, self.lane = ego_control(self.controller, measurement.ego, self.level, self.lane)
        return control

    def predicted_boxes(self, substep: int) -> Mapping[str, tuple]:
        """The ego's predicted point and the forecast vehicles' state boxes after ``substep`` (1-based)."""
        return self._predicted.get(substep, {})


class RoadPlanningMethod(Method[DrivingWorld]):
    """What robust, nominal and oracle share: the ego model, the planner, the policy.

    Parameters
    ----------
    scenario
        A `RoadScenario`; anything else raises `UnsupportedScenario`.
    config
        The loop settings (``budget``, ``gamma``).
    """

    def __init__(self, scenario: Any, config: LoopConfig) -> None:
        if not isinstance(scenario, RoadScenario):
            raise UnsupportedScenario(
                f"{type(self).__name__} drives only RoadScenario worlds, got {type(scenario).__name__}"
            )
        self.scenario = scenario
        self.config = config

    def start(self, world: DrivingWorld) -> None:
        """Build the ego model of the episode.

        Parameters
        ----------
        world : DrivingWorld
            The episode.
        """
        self.world = world
        self.ego = EgoSetup(world.world)
        self.model = BicycleModel(self.ego.controller, self.ego.reward, self.ego.actions, substeps=world.substeps)
        self.level, self.lane = self.ego.level, self.ego.lane
        self.decisions: list[dict] = []

    def obstacles(self, observation: Observation) -> ObstacleTables:
        """The obstacle tables of this decision and the state boxes to check (abstract).

        Parameters
        ----------
        observation : Observation
            This decision's measurement: the ego's state exact, the other vehicles' noisy.
        """
        raise NotImplementedError

    def decide(self, measurement: Observation) -> Policy:
        """Plan on this decision's obstacle table; the policy holds the chosen action's controllers.

        Parameters
        ----------
        measurement : Observation
            The current measurement (the ego exact, the others noisy).
        """
        world = self.world.world
        t = world.step_index
        tables = self.obstacles(measurement)
        keeping = tables.lane_keeping_table
        model = self.model.with_reward(
            self.ego.reward.with_obstacles(tables.table, t),
            lane_keeping_reward=None if keeping is None else self.ego.reward.with_obstacles(keeping, t),
        )
        planner = RobustTreePlanner([model], model.actions, gamma=self.config.gamma, budget=self.config.budget)
        root = model.initial_state(measurement.ego, level=self.level, lane=self.lane, time=t)
        decision = planner.plan(root)
        action, latest = self._choose(model, root, decision)
        states, _, after = model.predict(root, action)
        checked = tables.checked
        if keeping is not None and after.kept:
            assert tables.lane_keeping_checked is not None  # ObstacleTables keeps the two together
            checked = tables.lane_keeping_checked
        predicted: dict[int, dict[str, tuple]] = {}
        for k in range(1, states.shape[0] + 1):
            boxes = {"ego": (states[k - 1], states[k - 1])}
            boxes.update(checked.get(k, {}))
            predicted[k] = boxes
        _, speed_change, lane_change = self.ego.actions[action]
        level, lane = apply_action(self.ego.controller, self.level, self.lane, speed_change, lane_change)
        policy = _EgoPolicy(self.ego.controller, int(level), int(lane), predicted)
        self.level, self.lane = after.level, after.lane
        self.decisions.append(
            {
                "step": int(t),
                "action": self.ego.actions[action][0],
                "tree_action": self.ego.actions[decision.action][0],
                "lower": float(decision.lower),
                "upper": float(decision.upper),
                "executed_lower": float(decision.action_lower[action]),
                "depth": int(decision.depth),
                "latest_collision": latest,
            }
        )
        return policy

    def _choose(self, model: BicycleModel, root: BicycleState, decision) -> tuple[int, list[int] | None]:
        """The action to execute: the tree's (the base rule), and no survival figures."""
        return int(decision.action), None

    def observe(self, transition: Transition) -> None:
        """Nothing to learn (the robust method learns).

        Parameters
        ----------
        transition : Transition
            The sub-step (ignored).
        """

    def report(self) -> dict:
        """The decisions' actions."""
        return {"decisions": self.decisions}


class _LearningMethod(RoadPlanningMethod):
    """A tree-search method that feeds a `TrafficLearner` every sub-step's measurement (robust, nominal)."""

    def start(self, world: DrivingWorld) -> None:
        """Build the ego model and the traffic learner.

        Parameters
        ----------
        world : DrivingWorld
            The episode.
        """
        super().start(world)
        self.learner = TrafficLearner(world.world.road, world.world.scenario)
        self._learned_time: float | None = None

    def _learn(self, observation: Observation) -> None:
        # a decision's measurement is the last sub-step's one, already learned from
        if observation.time != self._learned_time:
            self.learner.observe(observation)
            self._learned_time = observation.time

    def observe(self, transition: Transition) -> None:
        """Feed the learner the sub-step's measurement.

        Parameters
        ----------
        transition : Transition
            The sub-step; its ``next_measured`` `Observation` goes to the learner.
        """
        self._learn(transition.next_measured)


class RoadRobustMethod(_LearningMethod):
    """The proposed planner on the road: elimination, sound forecasts, robust tree search (see the module docstring)."""

    def start(self, world: DrivingWorld) -> None:
        """Build the ego model and the traffic learner, and feed it the first measurement.

        Parameters
        ----------
        world : DrivingWorld
            The episode.
        """
        super().start(world)
        self.guaranteed_lost = 0
        # the latest-collision rule needs a place to wait: a speed level that stops the ego
        self.can_wait = min(self.ego.speeds) == 0.0
        # the previous decision's forecast for any ego (intersected in turn): (its sub-step, forecast)
        self._earlier: tuple[int, TrafficForecast] | None = None
        self.inconsistent_boxes = 0

    def obstacles(self, observation: Observation) -> ObstacleTables:
        """`forecast_traffic` under the learner's beliefs, for any ego and for an ego that keeps its lane.

        The forecast depends on the ego's reach: a vehicle beside the ego may not change
        into the ego's lane while the gap rule fails against the ego, which a reach that
        may leave the lane cannot show. On the highway a second forecast from the reach
        of the lane-keeping actions gives the table of paths that keep their lane.

        Parameters
        ----------
        observation : Observation
            This decision's measurement: the ego's state exact, the other vehicles' noisy.
        """
        self._learn(observation)
        road_world = self.world.world
        root = self.model.initial_state(observation.ego, level=self.level, lane=self.lane, time=road_world.step_index)
        beliefs: dict[int, VehicleBelief] = self.learner.beliefs()
        scenario = road_world.scenario
        speeds = np.asarray(self.ego.speeds)
        v = float(observation.ego[2])
        bounds = (min(v, float(speeds.min())), max(v, float(speeds.max())))
        reach = ego_reach(self.model, root, bounds, FORECAST_STEPS, scenario.dt, scenario.vehicle)
        step = int(road_world.step_index)
        forecast = self._intersected(self._forecast(observation, beliefs, reach), step)
        table, checked = self._tables(forecast, count=True)
        keeping = lane_keeping_actions(self.ego.actions)
        if len(keeping) == self.model.n_actions:
            self._earlier = (step, forecast)
            return ObstacleTables(table, checked)
        keep_reach = lane_keeping_reach(self.model, root, keeping, FORECAST_STEPS, scenario.vehicle)
        keep_forecast = self._intersected(self._forecast(observation, beliefs, keep_reach), step)
        self._earlier = (step, forecast)
        keep_table, keep_checked = self._tables(keep_forecast, count=False)
        return ObstacleTables(table, checked, keep_table, keep_checked)

    def _intersected(self, forecast: TrafficForecast, step: int) -> TrafficForecast:
        """``forecast`` intersected with the previous decision's forecast for any ego (`intersect_forecasts`).

        Both contain the true traffic: the previous one was made from the ego's reach
        over every action sequence, which every plan of this decision continues. Disjoint
        boxes (a forecast that is not sound) are counted in `inconsistent_boxes`.
        """
        if self._earlier is None:
            return forecast
        earlier_step, earlier = self._earlier
        met = intersect_forecasts(forecast, step, earlier, earlier_step)
        self.inconsistent_boxes += met.inconsistent
        return met.forecast

    def _choose(self, model: BicycleModel, root: BicycleState, decision) -> tuple[int, list[int] | None]:
        """`latest_collision_action` over the forecast where the ego can stop (a target speed of 0), else the tree's.

        Braking to keep clear longer pays where the ego can wait for the boxes to shrink
        (the T-junction's stem: SLOWER's target is 0). On the highway the slowest target
        is 20 m/s: braking there does not wait for anything, and the rule measured on
        Table 4's seeds cost 1.4 s per episode for no failure avoided (README), so the
        highway executes the tree's action.
        """
        if not self.can_wait:
            return int(decision.action), None
        return latest_collision_action([model], root, decision, horizon=FORECAST_STEPS)

    def _forecast(self, observation: Observation, beliefs, ego: tuple) -> TrafficForecast:
        """One forecast from the ego's ``(reach, speed, heading)``."""
        road_world = self.world.world
        reach, speed, heading = ego
        # the ego's route lanes from the one it is on (its own route position: a route index never
        # decreases, so the lanes it may occupy by the route rule over the horizon are among these)
        route = self.ego.route[int(road_world.traffic.route_index[0]) :] if self.ego.route else ()
        return forecast_traffic(
            observation,
            road_world.road,
            road_world.scenario,
            beliefs,
            steps=FORECAST_STEPS,
            ego_reach=reach,
            ego_speed=speed,
            ego_heading=heading,
            ego_route=route or None,
        )

    def _tables(self, forecast: TrafficForecast, *, count: bool):
        """A forecast's boxes and the state boxes to check over the decision's sub-steps."""
        road_world = self.world.world
        scenario = road_world.scenario
        if count:
            self.guaranteed_lost += int(
                (~np.asarray(forecast.guaranteed[: self.world.substeps + 1], dtype=bool)).any(axis=0).sum()
            )
        checked: dict[int, dict[str, tuple]] = {}
        substeps = self.world.substeps
        last = forecast.boxes[substeps]
        corners = np.stack(
            [last[:, [0, 1]], last[:, [0, 3]], last[:, [2, 1]], last[:, [2, 3]]], axis=1
        )  # (m, 4, 2): a vehicle whose box stays on the road cannot have left it (exited) during the decision
        finite = np.all(np.isfinite(last), axis=1)
        stays = np.zeros(len(last), dtype=bool)
        if finite.any():
            stays[finite] = road_world.road.on_road(corners[finite], scenario.off_road_margin).all(axis=1)
        for k in range(1, substeps + 1):
            checked[k] = {
                f"vehicle {int(agent)}": (forecast.state_lower[k, j], forecast.state_upper[k, j])
                for j, agent in enumerate(forecast.ids)
                if stays[j]
            }
        return forecast.boxes, checked

    def report(self) -> dict:
        """The decisions, the learner's eliminations and LP counts, the coarse-box count and the disjoint consecutive boxes."""
        learner = self.learner
        return {
            "decisions": self.decisions,
            "eliminations": [
                list(map(lambda v: list(v) if isinstance(v, tuple) else v, e)) for e in learner.eliminations
            ],
            "lp_solves": learner.lp_solves,
            "solver_failures": learner.solver_failures,
            "coarse_vehicle_decisions": self.guaranteed_lost,
            "inconsistent_forecast_boxes": self.inconsistent_boxes,
        }


class RoadOracleMethod(RoadPlanningMethod):
    """Tree search on the true traffic (true states, parameters, target speeds, intentions; no disturbance)."""

    def obstacles(self, observation: Observation) -> ObstacleTables:
        """`point_forecast` from the world's true traffic.

        Parameters
        ----------
        observation : Observation
            This decision's measurement (unused: the oracle reads the true traffic).
        """
        world = self.world.world
        return ObstacleTables(point_forecast(world, world.traffic, self.ego, self.level, self.lane, FORECAST_STEPS), {})


class RoadNominalMethod(_LearningMethod):
    """Certainty equivalence: the least-squares parameters and minimum-error routes of the learner."""

    def obstacles(self, observation: Observation) -> ObstacleTables:
        """`point_forecast` from the measured states with the learner's estimates.

        Parameters
        ----------
        observation : Observation
            This decision's measurement: the ego's state exact, the other vehicles' noisy.
        """
        self._learn(observation)
        world = self.world.world
        truth = world.traffic
        estimates = self.learner.nominal()
        n = len(truth)
        states = np.array(truth.states)
        states[0] = observation.ego
        active = np.zeros(n, dtype=bool)
        active[0] = True
        theta_a, theta_b = np.array(truth.theta_a), np.array(truth.theta_b)
        routes = np.full_like(np.asarray(truth.routes), -1)
        routes[0] = truth.routes[0]
        route_index = np.zeros(n, dtype=int)
        route_index[0] = truth.route_index[0]
        # RoadWorld checks that its scenario is a HighwayScenario exactly when kind is "highway"
        scenario = world.scenario
        low, high = scenario.vehicle_speed if isinstance(scenario, HighwayScenario) else scenario.main_speed
        target = np.full(n, 0.5 * (low + high))
        target[0] = truth.target_speed[0]
        for j, agent in enumerate(observation.ids):
            agent = int(agent)
            states[agent] = observation.vehicles[j]
            estimate = estimates.get(agent)
            if estimate is None:
                continue
            active[agent] = True
            theta_a[agent], theta_b[agent] = estimate.theta_a, estimate.theta_b
            route = list(estimate.route)
            routes[agent, : len(route)] = route[: routes.shape[1]]
            route_index[agent] = route.index(estimate.lane) if estimate.lane in route else 0
        traffic = truth.evolve(
            states=states,
            spawned=active,
            exited=np.zeros(n, dtype=bool),
            spawn_step=np.where(active, 0, np.iinfo(np.int64).max),
            routes=routes,
            route_index=route_index,
            theta_a=theta_a,
            theta_b=theta_b,
            target_speed=target,
            timer=np.full(n, np.inf),
            courteous=np.zeros(n, dtype=bool),
            committed=np.zeros(n, dtype=bool),
            yield_time=np.zeros(n),
        )
        return ObstacleTables(point_forecast(world, traffic, self.ego, self.level, self.lane, FORECAST_STEPS), {})


register_method("robust", RoadRobustMethod)
register_method("nominal", RoadNominalMethod)
register_method("oracle", RoadOracleMethod)
