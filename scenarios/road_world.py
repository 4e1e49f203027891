"""The driving worlds: a highway and a T-junction, one seeded episode each.

A `RoadWorld` holds the road, the ego (the kinematic bicycle of
`minimaxplan.scenarios.vehicles`, parameters known, no disturbance, driven by a control
``(acceleration, steering)``) and the other vehicles (the LinearVehicle law with theta
drawn per vehicle, disturbances, lane changes on a timer, routes drawn at spawn,
yielding at the junction). The closed loop asks for observations (`measure`:
bounded uniform noise on every other vehicle; the ego is measured exactly by default,
``ego_measurement_noise``) and applies one control per decision period
(`step`: held for ``substeps`` sub-steps of ``dt``), like `RobotWorld`.

Outcomes, checked after every sub-step in this order: ``"collision"`` (the ego's
rectangle touches another vehicle's, checked with python-fcl, whoever caused it),
``"off_road"`` (a corner of the ego's rectangle is off the road), ``"goal"`` and
``"timeout"``. Collisions among the other vehicles and other vehicles leaving the road
are not outcomes (the ego did not fail) but are recorded (`traffic_collisions`,
`traffic_off_road`): they should never happen.

Randomness comes from separate streams spawned from the seed (layout and parameters,
dynamics, measurement noise), so the same seed and the same controls give the same
episode bit for bit, and measuring more often changes nothing else.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from minimaxplan.models.errors import DimensionError, InputError, NonFiniteError

from .geometry import FCL_SLAB_HEIGHT, _fcl
from .road import HighwayGeometry, Road, TJunctionGeometry, highway_road, tjunction_road
from .vehicles import (
    DEFAULT_VEHICLE,
    BehaviourParameters,
    StepRecord,
    TrafficRules,
    TrafficState,
    VehicleParameters,
    draw_parameters,
    traffic_step,
    vehicle_corners,
)
from .worlds import EpisodeOver

__all__ = [
    "ROAD_WORLD_KINDS",
    "ROAD_OUTCOMES",
    "EpisodeOver",
    "HighwayScenario",
    "TJunctionScenario",
    "Observation",
    "RoadWorld",
    "make_road_world",
    "rectangles_collide",
]

ROAD_WORLD_KINDS = ("highway", "tjunction")
ROAD_OUTCOMES = ("running", "goal", "collision", "off_road", "timeout")


#: Slab height lifting the planar rectangles into fcl's 3-D world (any value > 0 works).
def _noise_tuple(value, name: str = "measurement_noise") -> tuple:
    noise = tuple(float(v) for v in value)
    if len(noise) != 4 or min(noise) < 0 or not all(np.isfinite(noise)):
        raise InputError(f"{name} must be 4 finite half-widths >= 0, got {value!r}")
    return noise


def _check_common(scenario) -> None:
    if scenario.dt <= 0 or not np.isfinite(scenario.dt):
        raise InputError(f"dt must be finite and > 0, got {scenario.dt!r}")
    if int(scenario.substeps) != scenario.substeps or scenario.substeps < 1:
        raise InputError(f"substeps must be a positive integer, got {scenario.substeps!r}")
    if scenario.time_limit <= 0:
        raise InputError(f"time_limit must be > 0, got {scenario.time_limit!r}")
    if not 0 < scenario.ego_acceleration_bound:
        raise InputError(f"ego_acceleration_bound must be > 0, got {scenario.ego_acceleration_bound!r}")
    object.__setattr__(scenario, "measurement_noise", _noise_tuple(scenario.measurement_noise))
    object.__setattr__(
        scenario, "ego_measurement_noise", _noise_tuple(scenario.ego_measurement_noise, "ego_measurement_noise")
    )
    if not np.isfinite(scenario.off_road_margin) or scenario.off_road_margin < 0:
        raise InputError(f"off_road_margin must be finite and >= 0, got {scenario.off_road_margin!r}")


@dataclass(frozen=True)
class HighwayScenario:
    """Every constant of the highway episodes (DRIVING.md item 9).

    Attributes
    ----------
    geometry : HighwayGeometry
        3 lanes x 4 m, 2000 m long.
    vehicle, behaviour, rules : VehicleParameters, BehaviourParameters, TrafficRules
        The bicycle, the LinearVehicle law and the traffic rules.
    dt : float
        Sub-step, s (0.1).
    substeps : int
        Sub-steps per decision (5: a control is held for 0.5 s).
    time_limit : float
        Episode length limit, s (40).
    ego_start : float
        The ego starts at ``x = ego_start`` (m, 200), centred in a lane drawn uniformly,
        heading along the road.
    ego_speed : float
        Its initial speed, m/s (25).
    goal_distance : float
        The goal: the ego's centre ``goal_distance`` m ahead of its start (250), on the road.
    vehicle_count : int
        Other vehicles (15).
    vehicle_speed : tuple of 2 float
        Their initial and target speeds, ``U[low, high]`` m/s, one draw per vehicle (20, 25).
    spawn_behind : float
        Vehicles are placed lane by lane from ``ego_start - spawn_behind`` forwards, m (100).
    spacing : tuple of 2 float
        The bumper-to-bumper gap between consecutive vehicles of a lane is
        ``(d0 + T v) U[low, high]`` with v the follower's speed (1.2, 2.5).
    ego_clearance : float
        No other vehicle starts within this longitudinal distance (centre to centre) of
        the ego in the lanes beside it, m (12); in the ego's lane the safety gaps apply
        (``d0 + T v + L`` both ways, times the spacing's low factor).
    ego_acceleration_bound : float
        The ego's acceleration control must lie in ``[-bound, bound]``, m/s^2 (6);
        its steering in ``[-max_steering, max_steering]``.
    measurement_noise : tuple of 4 float
        Half-widths of the uniform measurement noise on the other vehicles' ``(x, y, v,
        psi)`` (m, m, m/s, rad): (0.1, 0.1, 0.1, 0.01).
    ego_measurement_noise : tuple of 4 float
        The same for the ego: (0, 0, 0, 0), the ego knows its own state exactly
        (odometry; a documented choice, so the planner's ego is a point model).
    off_road_margin : float
        The ego is off the road when a corner of its rectangle is farther than this
        outside the road (`Road.on_road`), m (0: strictly on the road).
    """

    geometry: HighwayGeometry = HighwayGeometry()
    vehicle: VehicleParameters = VehicleParameters()
    behaviour: BehaviourParameters = BehaviourParameters()
    rules: TrafficRules = TrafficRules()
    dt: float = 0.1
    substeps: int = 5
    time_limit: float = 40.0
    ego_start: float = 200.0
    ego_speed: float = 25.0
    goal_distance: float = 250.0
    vehicle_count: int = 15
    vehicle_speed: tuple = (20.0, 25.0)
    spawn_behind: float = 100.0
    spacing: tuple = (1.2, 2.5)
    ego_clearance: float = 12.0
    ego_acceleration_bound: float = 6.0
    measurement_noise: tuple = (0.1, 0.1, 0.1, 0.01)
    ego_measurement_noise: tuple = (0.0, 0.0, 0.0, 0.0)
    off_road_margin: float = 0.0

    def __post_init__(self) -> None:
        _check_common(self)
        if int(self.vehicle_count) != self.vehicle_count or self.vehicle_count < 0:
            raise InputError(f"vehicle_count must be a nonnegative integer, got {self.vehicle_count!r}")
        if not 0 < self.vehicle_speed[0] <= self.vehicle_speed[1]:
            raise InputError(f"vehicle_speed must satisfy 0 < low <= high, got {self.vehicle_speed}")
        if not 0 < self.spacing[0] <= self.spacing[1]:
            raise InputError(f"spacing must satisfy 0 < low <= high, got {self.spacing}")
        if self.ego_start + self.goal_distance >= self.geometry.length:
            raise InputError("the goal lies beyond the end of the highway")
        if self.ego_start - self.spawn_behind < 0:
            raise InputError("spawn_behind reaches before the start of the highway")

    @property
    def max_steps(self) -> int:
        """Sub-steps in the time limit."""
        return int(round(self.time_limit / self.dt))

    @property
    def target_speeds(self) -> tuple[float, float]:
        """Bounds of the other vehicles' target speeds, m/s (``vehicle_speed``)."""
        return (float(self.vehicle_speed[0]), float(self.vehicle_speed[1]))

    def to_dict(self) -> dict:
        """The scenario as plain data."""
        return asdict(self)


@dataclass(frozen=True)
class TJunctionScenario:
    """Every constant of the T-junction episodes (DRIVING.md item 9).

    Attributes
    ----------
    geometry : TJunctionGeometry
        intersection-v0 without its north arm (lane names in `TJunctionGeometry`).
    vehicle, behaviour, rules : VehicleParameters, BehaviourParameters, TrafficRules
        The bicycle, the LinearVehicle law and the traffic rules.
    dt : float
        Sub-step, s (0.1).
    substeps : int
        Sub-steps per decision (5: 0.5 s).
    time_limit : float
        Episode length limit, s (30).
    ego_start : tuple of 2 float
        The ego starts centred on ``south_in`` at arc length ``U[low, high]`` m (55, 65:
        35-45 m before the stop line, as intersection-v0's 60 +- 5), heading north.
    ego_speed : float
        Its initial speed, m/s (4.5, the middle of the target speeds {0, 4.5, 9}).
    goal_distance : float
        The goal: the ego's centre on ``west_out`` at least this far past the junction
        box (m, 25, intersection-v0's exit distance); the ego turns left from the stem.
    main_speed : tuple of 2 float
        Main-road vehicles' initial and target speed ``U[low, high]`` m/s (7, 9: 8 +- 1).
    headway_min, headway_mean_extra : float
        Per direction of the main road, vehicles arrive at the arm's entry with
        headways ``headway_min + Exponential(headway_mean_extra)`` s (3 and 3: mean 6 s).
        Arrivals are drawn from ``-access_length / main_speed[0]`` s (those already on
        the arm at the start are placed where they would be at constant speed, if at
        least ``entry_margin`` m before the junction) up to the time limit; later ones
        spawn at the entry when it is clear (`TrafficRules.spawn_clearance`).
    entry_margin : float
        See above, m (20).
    turn_probability : float
        A main-road vehicle's route turns into the stem with this probability (eastbound
        right, westbound left), else goes straight (0.3).
    courteous_probability : float
        A main-road vehicle is courteous (also yields to the stem) with this probability (0.2).
    stem_vehicles : int
        Other vehicles queued behind the ego on the stem, routes left or right with equal
        probability (0).
    stem_spacing : float
        Their spacing, centre to centre, m (25).
    ego_acceleration_bound : float
        The ego's acceleration control must lie in ``[-bound, bound]``, m/s^2 (6).
    measurement_noise : tuple of 4 float
        Half-widths of the uniform measurement noise on the other vehicles' ``(x, y, v,
        psi)``: (0.1, 0.1, 0.1, 0.01).
    ego_measurement_noise : tuple of 4 float
        The same for the ego: (0, 0, 0, 0), the ego's state is known exactly.
    off_road_margin : float
        The ego is off the road when a corner of its rectangle is farther than this
        outside the road (`Road.on_road`), m (0: strictly on the road).
    """

    geometry: TJunctionGeometry = TJunctionGeometry()
    vehicle: VehicleParameters = VehicleParameters()
    behaviour: BehaviourParameters = BehaviourParameters()
    rules: TrafficRules = TrafficRules()
    dt: float = 0.1
    substeps: int = 5
    time_limit: float = 30.0
    ego_start: tuple = (55.0, 65.0)
    ego_speed: float = 4.5
    goal_distance: float = 25.0
    main_speed: tuple = (7.0, 9.0)
    headway_min: float = 3.0
    headway_mean_extra: float = 3.0
    entry_margin: float = 20.0
    turn_probability: float = 0.3
    courteous_probability: float = 0.2
    stem_vehicles: int = 0
    stem_spacing: float = 25.0
    ego_acceleration_bound: float = 6.0
    measurement_noise: tuple = (0.1, 0.1, 0.1, 0.01)
    ego_measurement_noise: tuple = (0.0, 0.0, 0.0, 0.0)
    off_road_margin: float = 0.0

    def __post_init__(self) -> None:
        _check_common(self)
        if not 0 < self.main_speed[0] <= self.main_speed[1]:
            raise InputError(f"main_speed must satisfy 0 < low <= high, got {self.main_speed}")
        if not 0 <= self.ego_start[0] <= self.ego_start[1] <= self.geometry.access_length:
            raise InputError(f"ego_start must lie on south_in, got {self.ego_start}")
        if self.headway_min <= 0 or self.headway_mean_extra < 0:
            raise InputError("headway_min must be > 0 and headway_mean_extra >= 0")
        for name in ("turn_probability", "courteous_probability"):
            if not 0 <= getattr(self, name) <= 1:
                raise InputError(f"{name} must lie in [0, 1], got {getattr(self, name)!r}")
        if int(self.stem_vehicles) != self.stem_vehicles or self.stem_vehicles < 0:
            raise InputError(f"stem_vehicles must be a nonnegative integer, got {self.stem_vehicles!r}")
        if not 0 < self.goal_distance < self.geometry.access_length:
            raise InputError(f"goal_distance must lie in (0, access_length), got {self.goal_distance!r}")

    @property
    def max_steps(self) -> int:
        """Sub-steps in the time limit."""
        return int(round(self.time_limit / self.dt))

    @property
    def target_speeds(self) -> tuple[float, float]:
        """Bounds of the main-road vehicles' target speeds, m/s (``main_speed``)."""
        return (float(self.main_speed[0]), float(self.main_speed[1]))

    def to_dict(self) -> dict:
        """The scenario as plain data."""
        return asdict(self)


@dataclass(frozen=True, eq=False)
class Observation:
    """Noisy observation of every vehicle on the road at one sub-step.

    Parameters
    ----------
    time : float
        Simulated time, s.
    ego : ndarray, shape (4,)
        The ego's ``(x, y, v, psi)`` with its noise ``ego_measurement_noise`` (exact by
        default; all zeros without an ego).
    vehicles : ndarray, shape (m, 4)
        The other vehicles on the road, with noise.
    ids : ndarray of int, shape (m,)
        Their agent indices (stable over the episode).
    """

    time: float
    ego: np.ndarray
    vehicles: np.ndarray
    ids: np.ndarray


# ------------------------------------------------------------------ collisions
def _fcl_rectangle(state, vehicle: VehicleParameters):
    fcl = _fcl()
    c, s = np.cos(state[3]), np.sin(state[3])
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    shape = fcl.Box(float(vehicle.length), float(vehicle.width), FCL_SLAB_HEIGHT)
    return fcl.CollisionObject(shape, fcl.Transform(rotation, np.array([state[0], state[1], 0.0])))


def rectangles_collide(state_a, state_b, vehicle: VehicleParameters = DEFAULT_VEHICLE) -> bool:
    """Whether two vehicles' rectangles (L x W, centred, along psi) touch or overlap, by python-fcl.

    Parameters
    ----------
    state_a, state_b : array_like, shape (4,)
        ``(x, y, v, psi)``.
    vehicle : VehicleParameters
        L and W.
    """
    fcl = _fcl()
    a = np.asarray(state_a, dtype=float)
    b = np.asarray(state_b, dtype=float)
    if a.shape != (4,) or b.shape != (4,):
        raise DimensionError(f"states must have shape (4,), got shapes {a.shape} and {b.shape}")
    return (
        fcl.collide(
            _fcl_rectangle(a, vehicle), _fcl_rectangle(b, vehicle), fcl.CollisionRequest(), fcl.CollisionResult()
        )
        > 0
    )


def _colliding_pairs(states: np.ndarray, active: np.ndarray, vehicle: VehicleParameters) -> list[tuple[int, int]]:
    """Pairs (i < j) of active agents whose rectangles meet: numpy broad phase, fcl narrow phase."""
    idx = np.flatnonzero(active)
    if idx.size < 2:
        return []
    reach = np.hypot(vehicle.length, vehicle.width)  # centres farther apart cannot meet
    pos = states[idx, :2]
    d = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
    a, b = np.nonzero(np.triu(d <= reach, k=1))
    return [
        (int(idx[i]), int(idx[j])) for i, j in zip(a, b) if rectangles_collide(states[idx[i]], states[idx[j]], vehicle)
    ]


# -------------------------------------------------------------------- layouts
def _base_traffic(count: int) -> dict:
    return {
        "states": np.zeros((count, 4)),
        "controlled": np.zeros(count, dtype=bool),
        "spawned": np.ones(count, dtype=bool),
        "exited": np.zeros(count, dtype=bool),
        "spawn_step": np.zeros(count, dtype=int),
        "routes": np.full((count, 3), -1, dtype=int),
        "route_index": np.zeros(count, dtype=int),
        "theta_a": np.zeros((count, 3)),
        "theta_b": np.zeros((count, 2)),
        "target_speed": np.zeros(count),
        "timer": np.zeros(count),
        "interval": np.ones(count),
        "courteous": np.zeros(count, dtype=bool),
        "committed": np.zeros(count, dtype=bool),
        "yield_time": np.zeros(count),
    }


def _highway_layout(rng: np.random.Generator, scenario: HighwayScenario, road: Road, include_ego: bool):
    """The ego (row 0 when included) and the other vehicles, placed lane by lane."""
    n_lanes = scenario.geometry.lane_count
    width = scenario.geometry.lane_width
    behaviour, vehicle = scenario.behaviour, scenario.vehicle
    ego_lane = int(rng.integers(n_lanes))
    count = int(scenario.vehicle_count)
    lanes = rng.integers(n_lanes, size=count)
    speeds = rng.uniform(scenario.vehicle_speed[0], scenario.vehicle_speed[1], size=count)
    factors = rng.uniform(scenario.spacing[0], scenario.spacing[1], size=count)
    jitter = rng.uniform(0.0, 20.0, size=n_lanes)
    theta_a, theta_b = draw_parameters(rng, count, behaviour)
    intervals = rng.uniform(scenario.rules.lane_change_interval[0], scenario.rules.lane_change_interval[1], size=count)
    phases = rng.uniform(0.0, 1.0, size=count)
    x0 = scenario.ego_start
    low = scenario.spacing[0]
    safe_behind = (
        vehicle.length + (behaviour.standstill_distance + behaviour.time_headway * scenario.vehicle_speed[1]) * low
    )
    safe_ahead = vehicle.length + (behaviour.standstill_distance + behaviour.time_headway * scenario.ego_speed) * low
    front = x0 - scenario.spawn_behind + jitter
    positions = np.zeros(count)
    for i in range(count):
        k = int(lanes[i])
        x = front[k]
        if k == ego_lane and x0 - safe_behind < x < x0 + safe_ahead:
            x = x0 + safe_ahead
        elif k != ego_lane and abs(x - x0) < scenario.ego_clearance:
            x = x0 + scenario.ego_clearance
        positions[i] = x
        front[k] = (
            x + vehicle.length + (behaviour.standstill_distance + behaviour.time_headway * speeds[i]) * factors[i]
        )
    rows = (1 if include_ego else 0) + count
    t = _base_traffic(rows)
    o = 1 if include_ego else 0
    if include_ego:
        t["states"][0] = (x0, ego_lane * width, scenario.ego_speed, 0.0)
        t["controlled"][0] = True
        t["routes"][0, 0] = ego_lane
        t["target_speed"][0] = scenario.ego_speed
        t["timer"][0] = np.inf
    t["states"][o:] = np.stack([positions, lanes * width, speeds, np.zeros(count)], axis=1)
    t["routes"][o:, 0] = lanes
    t["theta_a"][o:], t["theta_b"][o:] = theta_a, theta_b
    t["target_speed"][o:] = speeds
    t["interval"][o:] = intervals
    t["timer"][o:] = phases * intervals
    t["routes"] = t["routes"][:, :1]
    return TrafficState(**t), ego_lane


def _tjunction_layout(rng: np.random.Generator, scenario: TJunctionScenario, road: Road, include_ego: bool):
    """The ego (row 0 when included), main-road arrivals in both directions, stem vehicles."""
    behaviour, vehicle = scenario.behaviour, scenario.vehicle
    geometry = scenario.geometry
    access = geometry.access_length
    ego_s = float(rng.uniform(*scenario.ego_start))
    earliest = -access / scenario.main_speed[0]
    arms = []  # (route, arrival time, speed, courteous)
    for entry, straight, turn in (
        ("west_in", ("west_east", "east_out"), ("west_south", "south_out")),
        ("east_in", ("east_west", "west_out"), ("east_south", "south_out")),
    ):
        t = earliest + float(rng.uniform(0.0, scenario.headway_min))
        while t < scenario.time_limit:
            speed = float(rng.uniform(*scenario.main_speed))
            turning = rng.uniform() < scenario.turn_probability
            courteous = bool(rng.uniform() < scenario.courteous_probability)
            route = road.route(entry, *(turn if turning else straight))
            arms.append((route, t, speed, courteous))
            t += (
                scenario.headway_min + float(rng.exponential(scenario.headway_mean_extra))
                if scenario.headway_mean_extra > 0
                else scenario.headway_min
            )
    stem = []
    for q in range(int(scenario.stem_vehicles)):
        left = rng.uniform() < 0.5
        route = (
            road.route("south_in", "south_west", "west_out")
            if left
            else road.route("south_in", "south_east", "east_out")
        )
        stem.append((route, ego_s - (q + 1) * scenario.stem_spacing, scenario.ego_speed))
    count = len(arms) + len(stem)
    theta_a, theta_b = draw_parameters(rng, count, behaviour)
    o = 1 if include_ego else 0
    t = _base_traffic(o + count)
    if include_ego:
        lane = road.index("south_in")
        x, y = road.position_at(lane, ego_s)
        t["states"][0] = (x, y, scenario.ego_speed, float(road.heading_at(lane, ego_s)))
        t["controlled"][0] = True
        t["routes"][0] = road.route("south_in", "south_west", "west_out")
        t["target_speed"][0] = scenario.ego_speed
        t["timer"][0] = np.inf
    keep = np.ones(o + count, dtype=bool)
    for q, (route, arrival, speed, courteous) in enumerate(arms):
        i = o + q
        lane = route[0]
        if arrival < 0:
            s = vehicle.length / 2 - arrival * speed
            if s > access - scenario.entry_margin:
                keep[i] = False
                continue
            spawn_step = 0
        else:
            s = vehicle.length / 2
            spawn_step = int(np.ceil(arrival / scenario.dt))
        x, y = road.position_at(lane, s)
        t["states"][i] = (x, y, speed, float(road.heading_at(lane, s)))
        t["routes"][i] = route
        t["target_speed"][i] = speed
        t["courteous"][i] = courteous
        t["spawn_step"][i] = spawn_step
        t["spawned"][i] = spawn_step == 0
    for q, (route, s, speed) in enumerate(stem):
        i = o + len(arms) + q
        if s < 0:
            keep[i] = False
            continue
        lane = route[0]
        x, y = road.position_at(lane, s)
        t["states"][i] = (x, y, speed, float(road.heading_at(lane, s)))
        t["routes"][i] = route
        t["target_speed"][i] = float(np.mean(scenario.main_speed))
    t["theta_a"][o:], t["theta_b"][o:] = theta_a, theta_b
    t["timer"][:] = np.inf  # no side lanes: lane changes never fire
    t = {name: value[keep] for name, value in t.items()}
    return TrafficState(**t)


# ---------------------------------------------------------------------- world
class RoadWorld:
    """One seeded driving episode; see `make_road_world`.

    Parameters
    ----------
    kind : str
        "highway" or "tjunction".
    seed : int
        Nonnegative episode seed.
    scenario : HighwayScenario or TJunctionScenario, optional
        The episode constants (default: the kind's defaults).
    include_ego : bool
        False builds the same traffic without the ego (for tests of the traffic alone);
        then `step` takes no control and the only outcome is "timeout".

    Attributes
    ----------
    road : Road
        The lanes.
    traffic : TrafficState
        The true state of every agent (row 0 is the ego when included), with the true
        parameters theta_a, theta_b, target speeds, routes and intentions.
    records : list of StepRecord
        What the behaviour law did at each sub-step (intentions, leaders, yields,
        disturbances): the ground truth for the runtime checks.
    outcome : str
        One of `ROAD_OUTCOMES`.
    traffic_collisions, traffic_off_road : list of tuple
        ``(step_index, i, j)`` collisions between other vehicles and ``(step_index,
        i)`` other vehicles with a corner off the road (both should stay empty).
    """

    def __init__(
        self,
        kind: str,
        seed: int,
        *,
        scenario: HighwayScenario | TJunctionScenario | None = None,
        include_ego: bool = True,
    ):
        if kind not in ROAD_WORLD_KINDS:
            raise InputError(f"kind must be one of {ROAD_WORLD_KINDS}, got {kind!r}")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise InputError(f"seed must be a non-negative integer, got {seed!r}")
        expected = HighwayScenario if kind == "highway" else TJunctionScenario
        scenario = expected() if scenario is None else scenario
        if not isinstance(scenario, expected):
            raise InputError(f"scenario must be a {expected.__name__} for kind {kind!r}, got {type(scenario).__name__}")
        self.kind = kind
        self.seed = int(seed)
        self.scenario = scenario
        self.include_ego = bool(include_ego)
        if isinstance(scenario, HighwayScenario):
            self.road = highway_road(scenario.geometry)
        else:
            self.road = tjunction_road(scenario.geometry)
        self.reset()

    # ------------------------------------------------------------- episode
    def reset(self) -> Observation:
        """Restart the episode from its seed (the same episode, bit for bit) and measure it.

        Returns
        -------
        Observation
            The first measurement.
        """
        layout_seq, dynamics_seq, noise_seq = np.random.SeedSequence(self.seed).spawn(3)
        layout_rng = np.random.default_rng(layout_seq)
        if self.kind == "highway":
            assert isinstance(self.scenario, HighwayScenario)
            self.traffic, _ = _highway_layout(layout_rng, self.scenario, self.road, self.include_ego)
            self._goal_lanes = tuple(range(self.scenario.geometry.lane_count))
            self.goal_s = self.scenario.ego_start + self.scenario.goal_distance
        else:
            assert isinstance(self.scenario, TJunctionScenario)
            self.traffic = _tjunction_layout(layout_rng, self.scenario, self.road, self.include_ego)
            self._goal_lanes = (self.road.index("west_out"),)
            self.goal_s = self.scenario.goal_distance
        self._initial = self.traffic
        self._dynamics_rng = np.random.default_rng(dynamics_seq)
        self._noise_rng = np.random.default_rng(noise_seq)
        self.step_index = 0
        self.outcome = "running"
        self.records: list[StepRecord] = []
        self.traffic_collisions: list[tuple[int, int, int]] = []
        self.traffic_off_road: list[tuple[int, int]] = []
        return self.measure()

    @property
    def time(self) -> float:
        """Simulated time, s."""
        return self.step_index * self.scenario.dt

    @property
    def done(self) -> bool:
        """Whether the episode has ended."""
        return self.outcome != "running"

    @property
    def ego_state(self) -> np.ndarray:
        """The ego's true ``(x, y, v, psi)`` (a copy)."""
        if not self.include_ego:
            raise InputError("this world has no ego")
        return self.traffic.states[0].copy()

    @property
    def initial_ego(self) -> np.ndarray:
        """The ego's true ``(x, y, v, psi)`` at the start of the episode (a copy)."""
        if not self.include_ego:
            raise InputError("this world has no ego")
        return self._initial.states[0].copy()

    @property
    def goal_lanes(self) -> tuple[int, ...]:
        """Lanes on which the goal is reached (at arc length >= `goal_s`, centre in the lane strip)."""
        return self._goal_lanes

    @property
    def others(self) -> np.ndarray:
        """Agent indices of the other vehicles (active or not)."""
        return np.arange(1 if self.include_ego else 0, len(self.traffic))

    def measure(self) -> Observation:
        """Noisy observations of the ego and of every other vehicle on the road.

        Uniform noise, ``|noise_k| <= measurement_noise[k]`` on ``(x, y, v, psi)`` of the
        other vehicles and ``|noise_k| <= ego_measurement_noise[k]`` on the ego's (by
        default 0: the ego is measured exactly), from the measurement stream (one draw
        for every agent, on the road or not, so the other vehicles' noise does not
        depend on the ego's bound).

        Returns
        -------
        Observation
        """
        bound = np.tile(np.array(self.scenario.measurement_noise), (len(self.traffic), 1))
        if self.include_ego:
            bound[0] = self.scenario.ego_measurement_noise
        noise = self._noise_rng.uniform(-1.0, 1.0, size=self.traffic.states.shape) * bound
        measured = self.traffic.states + noise
        others = self.others
        present = others[self.traffic.active[others]]
        ego = measured[0].copy() if self.include_ego else np.zeros(4)
        return Observation(time=self.time, ego=ego, vehicles=measured[present], ids=present)

    def ego_collisions(self) -> list[int]:
        """Agents whose rectangle the ego's touches now (python-fcl), as agent indices.

        Returns
        -------
        list of int
        """
        if not self.include_ego:
            return []
        pairs = _colliding_pairs(self.traffic.states, self.traffic.active, self.scenario.vehicle)
        return [j if i == 0 else i for i, j in pairs if 0 in (i, j)]

    def goal_reached(self) -> bool:
        """Whether the ego's centre is on a goal lane at arc length >= ``goal_s``."""
        if not self.include_ego:
            return False
        x, y = self.traffic.states[0, :2]
        lanes = np.array(self.goal_lanes)
        s, offset = self.road.frenet(lanes, x, y)
        inside = (np.abs(offset) <= self.road.widths[lanes] / 2) & (s <= self.road.lengths[lanes])
        return bool(np.any(inside & (s >= self.goal_s)))

    def _check_control(self, control) -> np.ndarray:
        u = np.asarray(control, dtype=float)
        if u.shape != (2,):
            raise DimensionError(f"control must have shape (2,), got shape {u.shape}")
        if not np.all(np.isfinite(u)):
            raise NonFiniteError("control contains NaN or infinite entries")
        bound_a, bound_d = self.scenario.ego_acceleration_bound, self.scenario.vehicle.max_steering
        if abs(u[0]) > bound_a or abs(u[1]) > bound_d:
            raise InputError(
                f"control must lie in [-{bound_a}, {bound_a}] x [-{bound_d:.6g}, {bound_d:.6g}], got {u.tolist()}"
            )
        return u

    def apply(self, control=None) -> str:
        """Hold ``control = (acceleration m/s^2, steering rad)`` for one sub-step; return the outcome.

        Parameters
        ----------
        control : array_like, shape (2,), optional
            The ego's control; must be None without an ego.
        """
        if self.done:
            raise EpisodeOver(f"the episode has ended (outcome={self.outcome!r}); reset or make a new world")
        n = len(self.traffic)
        controls = np.zeros((n, 2))
        if self.include_ego:
            if control is None:
                raise InputError("control is required: this world has an ego")
            controls[0] = self._check_control(control)
        elif control is not None:
            raise InputError("this world has no ego: control must be None")
        scenario = self.scenario
        self.traffic, record = traffic_step(
            self.traffic,
            self.road,
            controls,
            dt=scenario.dt,
            step_index=self.step_index,
            rng=self._dynamics_rng,
            behaviour=scenario.behaviour,
            rules=scenario.rules,
            vehicle=scenario.vehicle,
        )
        self.records.append(record)
        self.step_index += 1
        ego_hit = False
        for i, j in _colliding_pairs(self.traffic.states, self.traffic.active, scenario.vehicle):
            if self.include_ego and 0 in (i, j):
                ego_hit = True
            else:
                self.traffic_collisions.append((self.step_index, i, j))
        corners = vehicle_corners(self.traffic.states, scenario.vehicle)
        off = ~self.road.on_road(corners, scenario.off_road_margin).all(axis=1) & self.traffic.active
        for agent in np.flatnonzero(off):
            if not (self.include_ego and agent == 0):
                self.traffic_off_road.append((self.step_index, int(agent)))
        if ego_hit:
            self.outcome = "collision"
        elif self.include_ego and off[0]:
            self.outcome = "off_road"
        elif self.goal_reached():
            self.outcome = "goal"
        elif self.step_index >= scenario.max_steps:
            self.outcome = "timeout"
        return self.outcome

    def step(self, control=None) -> str:
        """Hold ``control`` for one decision period (``substeps`` sub-steps, fewer if the episode ends).

        Parameters
        ----------
        control : array_like, shape (2,), optional
            ``(acceleration, steering)`` of the ego (None without an ego).
        """
        for _ in range(int(self.scenario.substeps)):
            if self.apply(control) != "running":
                break
        return self.outcome

    def intentions(self) -> np.ndarray:
        """The lane each agent steered to at each sub-step so far, int (steps, n) (-1: not on the road)."""
        if not self.records:
            return np.zeros((0, len(self.traffic)), dtype=int)
        return np.stack([r.intention for r in self.records])

    def to_dict(self) -> dict:
        """The episode's setup (not its state): kind, seed, scenario, initial traffic and parameters."""
        t = self._initial
        return {
            "kind": self.kind,
            "seed": self.seed,
            "include_ego": self.include_ego,
            "scenario": self.scenario.to_dict(),
            "initial_states": t.states.tolist(),
            "routes": t.routes.tolist(),
            "spawn_step": t.spawn_step.tolist(),
            "theta_a": t.theta_a.tolist(),
            "theta_b": t.theta_b.tolist(),
            "target_speed": t.target_speed.tolist(),
            "courteous": t.courteous.tolist(),
        }


def make_road_world(
    kind: str, seed: int, *, scenario: HighwayScenario | TJunctionScenario | None = None, include_ego: bool = True
) -> RoadWorld:
    """A new seeded driving episode; the same seed gives the same episode, bit for bit.

    Parameters
    ----------
    kind : str
        "highway" (3 lanes, ego from 25 m/s among 15 vehicles at 20-25 m/s, goal 250 m
        ahead, 40 s) or "tjunction" (left turn from the stem across main-road traffic at
        8 +- 1 m/s, goal 25 m past the junction, 30 s).
    seed : int
        Nonnegative episode seed.
    scenario : HighwayScenario or TJunctionScenario, optional
        Override the kind's default constants.
    include_ego : bool
        False: the same traffic without the ego.
    """
    return RoadWorld(kind, seed, scenario=scenario, include_ego=include_ego)
