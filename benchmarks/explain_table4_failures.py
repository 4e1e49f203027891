"""Every Table 4 episode of nominal, oracle, DWA and TEB that does not reach the goal, re-run and explained (issue 11).

Reads the committed records (``benchmarks/results/experiments/table4/episodes.csv``),
re-runs each such episode in the registered world with the registered method (the
experiment's loop, seed and settings) in a world that also keeps the true state of every
agent after every sub-step, checks that the re-run is the record (outcome, time,
discounted return and decisions, exactly), and reads the ground truth the methods never
see (`RoadWorld.traffic`, `RoadWorld.records`: intentions, lane-change starts, routes,
courtesy, yielding) to say what happened (`explain`):

* a collision: the vehicle the ego touched, where (the ego's lane, the junction box),
  the relative position in the ego's frame (ahead, beside, behind), both speeds, the
  other vehicle's route and intention, and when it last started a lane change; a kind:
  ``cut-in`` (the other vehicle started a change into the ego's lane within
  `RECENT` s), ``ego's lane change`` (the ego left its lane within `RECENT` s),
  ``rear-end`` (the other vehicle ahead in the ego's lane), ``hit from behind``,
  ``in the junction`` (T-junction: the ego in the junction box or on the arc when a
  main-road vehicle, which has priority over the stem, reached it), ``other``;
* a timeout (the time limit): where the ego stands (lane, metres before the stop line
  or along the exit lane), how long it has been below `STOPPED` m/s, and how many
  main-road vehicles drove through the junction box while it waited.

The re-runs of TEB depend on the BLAS kernel (README, "Numerical environment of the
records"), so the script refuses to run unless its process has the records'
environment (``environment.json``'s ``matches_records``). Writes
``benchmarks/results/table4_failures.md`` and ``.json``.

Usage::

    env OPENBLAS_CORETYPE=Haswell NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" \\
        OPENBLAS_NUM_THREADS=1 python benchmarks/explain_table4_failures.py [--methods nominal,teb]
"""

from __future__ import annotations

import argparse
import csv
import datetime
import functools
import json
import os
import pathlib
import sys
import time
from collections.abc import Mapping, Sequence

import numpy as np

from minimaxplan.analysis import road_planning
from minimaxplan.analysis.episode import EpisodeJob, LoopConfig, run_job
from minimaxplan.analysis.numerical_environment import numerical_environment
from minimaxplan.analysis.registry import method_factory
from minimaxplan.analysis.road_scenario import DrivingWorld, RoadScenario
from minimaxplan.models.errors import InputError
from minimaxplan.planners import RobustTreePlanner
from minimaxplan.scenarios.road_world import RoadWorld
from minimaxplan.scenarios.vehicles import vehicle_corners

HERE = pathlib.Path(__file__).parent
RECORDS = HERE / "results" / "experiments" / "table4" / "episodes.csv"
RESULTS = HERE / "results"
#: The methods whose failures are explained here (robust's timeouts: README, "Why robust waits").
METHODS = ("nominal", "oracle", "dwa", "teb")
#: A lane change or a lane left this recently before a collision is its cause, s.
RECENT = 5.0
#: Below this speed the ego counts as stopped, m/s.
STOPPED = 0.5
#: The T-junction's main-road lanes (priority over the stem) and its arcs.
MAIN_LANES = ("west_in", "west_east", "east_out", "east_in", "east_west", "west_out")
TURNS = ("south_west", "south_east", "west_south", "east_south")


class RecordingWorld(RoadWorld):
    """A `RoadWorld` that keeps the true state of every agent after every sub-step (read at diagnosis only)."""

    def reset(self):
        """Restart as `RoadWorld.reset` and start the history with the initial states."""
        observation = super().reset()
        self.history = [(self.traffic.states.copy(), self.traffic.active.copy())]
        return observation

    def apply(self, control=None) -> str:
        """One sub-step as `RoadWorld.apply` (the same draws), then keep the states."""
        outcome = super().apply(control)
        self.history.append((self.traffic.states.copy(), self.traffic.active.copy()))
        return outcome


#: The recording worlds made in this process, by (kind, seed).
_WORLDS: dict[tuple[str, int], RecordingWorld] = {}


class RecordingScenario(RoadScenario):
    """The registered road scenario of ``kind`` whose worlds are `RecordingWorld`s (the same episodes)."""

    def make_world(self, seed: int, config: LoopConfig) -> DrivingWorld:
        """`RoadScenario.make_world` with a `RecordingWorld`, kept for the diagnosis."""
        if config.measurement != "uniform":
            raise InputError(f"the road worlds measure with bounded uniform noise only, got {config.measurement!r}")
        world = RecordingWorld(self.kind, seed)
        _WORLDS[(self.kind, int(seed))] = world
        return DrivingWorld(world)


def _lane_names(world: RoadWorld, point) -> list[str]:
    """The names of the lanes whose strips hold ``point``."""
    inside = world.road.lane_membership(np.asarray(point, dtype=float)[None, :])[0]
    return [world.road.names[k] for k in np.flatnonzero(inside)]


def _nearest_lane(world: RoadWorld, point) -> int:
    """The lane whose centre line is nearest to ``point`` among the lanes whose strips hold it (-1: none)."""
    inside = np.flatnonzero(world.road.lane_membership(np.asarray(point, dtype=float)[None, :])[0])
    if inside.size == 0:
        return -1
    _, offset = world.road.frenet(inside, float(point[0]), float(point[1]))
    return int(inside[np.argmin(np.abs(offset))])


def _in_junction(world: RoadWorld, point) -> bool:
    """Whether ``point`` lies in one of the road's areas (the junction box) or on a turn."""
    in_area = bool(world.road.in_areas(np.asarray(point, dtype=float)[None, :])[0]) if world.road.areas else False
    return in_area or any(name in TURNS for name in _lane_names(world, point))


def _route(world: RoadWorld, agent: int) -> list[str]:
    return [world.road.names[k] for k in world.traffic.routes[agent] if k >= 0]


#: T-junction routes by their lanes' names.
MOVEMENTS = {
    ("west_in", "west_east", "east_out"): "eastbound, straight",
    ("west_in", "west_south", "south_out"): "eastbound, turning right into the stem",
    ("east_in", "east_west", "west_out"): "westbound, straight",
    ("east_in", "east_south", "south_out"): "westbound, turning left into the stem",
}


def _movement(world: RoadWorld, agent: int) -> str:
    """What ``agent``'s route does: a `MOVEMENTS` entry at the T-junction, its lane on the highway."""
    route = tuple(_route(world, agent))
    return MOVEMENTS.get(route, " > ".join(route))


def _last_lane_change(world: RoadWorld, agent: int) -> int | None:
    """The last sub-step (index into `records`) at which ``agent`` started a lane change, or None."""
    starts = [k for k, r in enumerate(world.records) if r.lane_change[agent]]
    return starts[-1] if starts else None


def _forecast_error(world: RecordingWorld, made_at: int, table: np.ndarray, j: int) -> dict:
    """How a one-future forecast (nominal, oracle) made at sub-step ``made_at`` saw vehicle ``j`` at the collision.

    ``error_ahead_m``, ``error_left_m``: the centre of j's predicted rectangle box minus its
    true centre, in the ego's frame at contact (positive: predicted further ahead, further
    left); ``box_clear``: whether that box was clear of the ego's true rectangle box there.
    """
    end = world.step_index
    if not 0 <= end - made_at < len(table):
        return {}
    box = table[end - made_at, j - 1]
    facts: dict = {"s_before": round((end - made_at) * world.scenario.dt, 2)}
    if not np.all(np.isfinite(box)):
        return {**facts, "error_ahead_m": None, "error_left_m": None, "box_clear": True}
    ego = world.traffic.states[0]
    c, s = np.cos(ego[3]), np.sin(ego[3])
    dx, dy = 0.5 * (box[:2] + box[2:]) - world.traffic.states[j, :2]
    ego_box = _rectangle_box(world, 0)
    return {
        **facts,
        "error_ahead_m": round(float(c * dx + s * dy), 2),
        "error_left_m": round(float(-s * dx + c * dy), 2),
        "box_clear": bool(np.any(box[2:] < ego_box[:2]) or np.any(ego_box[2:] < box[:2])),
    }


def _forecast_facts(world: RecordingWorld, forecasts: Sequence[tuple[int, np.ndarray]], j: int) -> dict:
    """The last one-future forecast's view of vehicle ``j`` at the collision (`_forecast_error`), as ``forecast_*``."""
    if not forecasts:
        return {}
    made_at, table = forecasts[-1]
    return {f"forecast_{k}": v for k, v in _forecast_error(world, made_at, table, j).items()}


def _rectangle_box(world: RoadWorld, agent: int) -> np.ndarray:
    """``[x_lo, y_lo, x_hi, y_hi]`` of ``agent``'s true rectangle now."""
    corners = vehicle_corners(world.traffic.states[agent : agent + 1], world.scenario.vehicle)[0]
    return np.concatenate([corners.min(axis=0), corners.max(axis=0)])


class RecordingPlanner(RobustTreePlanner):
    """`RobustTreePlanner` that keeps, per plan, the model, the root and the decision (nominal, oracle)."""

    plans: list = []

    def plan(self, state, *args, **kwargs):
        """`RobustTreePlanner.plan`, kept with its model and root."""
        decision = super().plan(state, *args, **kwargs)
        RecordingPlanner.plans.append((self.models[0], state, decision))
        return decision


def _plan_facts(world: RecordingWorld, plans: Sequence, forecasts: Sequence[tuple[int, np.ndarray]], j: int) -> dict:
    """When the tree's best plan last was clear of the forecast, and when every later one collided.

    For each decision of a tree-search method, the first possible collision of the tree's
    best sequence (its last action then held) over `road_planning.FORECAST_STEPS`
    sub-steps of that decision's forecast (`BicycleModel.first_possible_collision`).
    ``plan_clear_last_s_before``: the last decision whose best plan was clear over the
    whole forecast, s before the collision; ``plans_colliding_from_s_before``: from which
    decision on every best plan may collide (None if the last one is clear);
    ``clear_forecast_*``: how the forecast of that last clear decision saw vehicle ``j``
    at the collision (`_forecast_error`).
    """
    if not plans:
        return {}
    end, dt = world.step_index, world.scenario.dt
    horizon = road_planning.FORECAST_STEPS
    first = []
    for model, root, decision in plans:
        first.append(model.first_possible_collision(root, list(decision.sequence), horizon))
    clear = [f > horizon for f in first]
    times = [int(root.time) for _, root, _ in plans]
    last_clear = max((i for i, c in enumerate(clear) if c), default=None)
    colliding_from = None if clear[-1] else (0 if last_clear is None else last_clear + 1)
    made = dict(forecasts)
    seen = {} if last_clear is None else _forecast_error(world, times[last_clear], made[times[last_clear]], j)
    replan = {} if last_clear is None else _replan_facts(world, plans, forecasts, last_clear)
    return {
        **replan,
        **{f"clear_forecast_{k}": v for k, v in seen.items()},
        "plan_clear_last_s_before": None if last_clear is None else round((end - times[last_clear]) * dt, 2),
        "plans_colliding_from_s_before": None
        if colliding_from is None
        else round((end - times[colliding_from]) * dt, 2),
        "plan_first_collision_s": [round(f * dt, 2) if f <= horizon else None for f in first[-4:]],
    }


def _first_obstacle(world: RoadWorld, model, root, plan: Sequence[int], horizon: int, table, made_at: int):
    """The planner's first possible collision of ``plan`` from ``root`` on ``model``'s table, and the vehicle met.

    Returns ``(step, agent)``, ``step`` relative to ``root.time``
    (`BicycleModel.first_possible_collision`, the planner's own test), ``agent`` the
    vehicle of ``table`` (the same forecast) whose box is nearest to the ego's rectangle
    box there (-1 when the zero case is no vehicle's: the road's edge); None if clear.
    """
    step = model.first_possible_collision(root, plan, horizon)
    if step > horizon:
        return None
    state, elapsed, decision = root, 0, 0
    while True:
        states, _, state = model.predict(state, plan[min(decision, len(plan) - 1)])
        if elapsed + len(states) >= step:
            x = states[step - elapsed - 1]
            break
        elapsed += len(states)
        decision += 1
    corners = vehicle_corners(x[None, :], world.scenario.vehicle)[0]
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    boxes = table[min(step + int(root.time) - made_at, len(table) - 1)]
    gap = np.maximum(np.maximum(boxes[:, :2] - hi, lo - boxes[:, 2:]), 0.0)
    distance = np.where(np.isfinite(boxes).all(axis=1), np.hypot(gap[:, 0], gap[:, 1]), np.inf)
    near = int(np.argmin(distance))
    return step, (near + 1 if distance[near] < 1.0 else -1)


def _replan_facts(
    world: RecordingWorld, plans: Sequence, forecasts: Sequence[tuple[int, np.ndarray]], last: int
) -> dict:
    """Why the plan of the last clear decision ``last`` did not carry the ego through.

    The rest of that plan (its actions after the first, the last held) from the next
    decision's true state, against the old forecast and against the next decision's: the
    first vehicle box it meets on each (`_first_obstacle`), and, for the one met on the
    new forecast, how far the two forecasts put that vehicle there and where it truly was.
    ``replan``: ``"forecast changed"`` (clear on the old forecast, not on the new one),
    ``"old plan not clear"`` (its rest meets a box on the old forecast too: the first
    action's sub-steps were the plan's last clear ones), or ``"clear on both"``.
    """
    if last + 1 >= len(plans):
        return {}
    made = dict(forecasts)
    model_old, root_old, decision_old = plans[last]
    model_new, root_new, _ = plans[last + 1]
    rest = list(decision_old.sequence[1:]) or list(decision_old.sequence[-1:])
    horizon = road_planning.FORECAST_STEPS - (int(root_new.time) - int(root_old.time))
    old_table, new_table = made[int(root_old.time)], made[int(root_new.time)]
    on_old = _first_obstacle(world, model_old, root_new, rest, horizon, old_table, int(root_old.time))
    on_new = _first_obstacle(world, model_new, root_new, rest, horizon, new_table, int(root_new.time))
    facts: dict = {"replan_on_old": on_old, "replan_on_new": on_new}
    if on_new is not None and on_old is None:
        facts["replan"] = "forecast changed"
        step, agent = on_new
        at = int(root_new.time) + step
        old_box = old_table[at - int(root_old.time), agent - 1]
        new_box = new_table[at - int(root_new.time), agent - 1]
        truth = world.history[at][0][agent, :2] if at < len(world.history) else None
        facts["replan_vehicle"] = agent
        facts["replan_old_centre"] = np.round(0.5 * (old_box[:2] + old_box[2:]), 2).tolist()
        facts["replan_new_centre"] = np.round(0.5 * (new_box[:2] + new_box[2:]), 2).tolist()
        facts["replan_true_centre"] = None if truth is None else np.round(truth, 2).tolist()
    elif on_old is not None:
        facts["replan"] = "old plan not clear"
    else:
        facts["replan"] = "clear on both"
    return facts


def explain_collision(world: RecordingWorld, forecasts: Sequence[tuple[int, np.ndarray]] = ()) -> dict:
    """What the ego touched at the end of a collision episode, and a kind (module docstring)."""
    dt = world.scenario.dt
    end = world.step_index
    ego = world.traffic.states[0]
    partners = world.ego_collisions()
    j = int(partners[0])
    other = world.traffic.states[j]
    c, s = np.cos(ego[3]), np.sin(ego[3])
    dx, dy = other[:2] - ego[:2]
    ahead, left = float(c * dx + s * dy), float(-s * dx + c * dy)
    ego_lane = _nearest_lane(world, ego[:2])
    recent = max(0, end - int(round(RECENT / dt)))
    earlier = world.history[recent][0][0]
    ego_lane_before = _nearest_lane(world, earlier[:2])
    change = _last_lane_change(world, j)
    two_s = max(0, end - int(round(2.0 / dt)))
    intention = int(world.records[-1].intention[j])
    facts = {
        "time_s": round(end * dt, 2),
        "other": j,
        "other_route": _route(world, j),
        "other_movement": _movement(world, j),
        "other_intention": world.road.names[intention] if intention >= 0 else None,
        "other_courteous": bool(world.traffic.courteous[j]),
        "other_yielding_last_s": bool(any(r.yielding[j] for r in world.records[-int(round(1.0 / dt)) :])),
        "other_followed_ego_last_2s": bool(any(r.leader[j] == 0 for r in world.records[-int(round(2.0 / dt)) :])),
        "ego_lanes": _lane_names(world, ego[:2]),
        "other_lanes": _lane_names(world, other[:2]),
        "ego_in_junction": _in_junction(world, ego[:2]),
        "ahead_m": round(ahead, 2),
        "left_m": round(left, 2),
        "ego_speed": round(float(ego[2]), 2),
        "other_speed": round(float(other[2]), 2),
        "ego_speed_2s_before": round(float(world.history[two_s][0][0, 2]), 2),
        "other_speed_2s_before": round(float(world.history[two_s][0][j, 2]), 2),
        "other_lane_change_s_before": None if change is None else round((end - 1 - change) * dt, 2),
        "ego_lane_before": world.road.names[ego_lane_before] if ego_lane_before >= 0 else None,
    }
    if world.kind == "highway":
        if change is not None and change >= recent and intention == ego_lane:
            kind = "cut-in"
        elif ego_lane_before != ego_lane:
            kind = "ego's lane change"
        elif ahead > 0:
            kind = "rear-end"
        else:
            kind = "hit from behind"
    else:
        main = any(name in MAIN_LANES for name in _route(world, j))
        if main and facts["ego_in_junction"]:
            kind = "in the junction"
        elif ahead > 0 and abs(left) < 2.0:
            kind = "rear-end"
        elif ahead <= 0 and abs(left) < 2.0:
            kind = "hit from behind"
        else:
            kind = "other"
    facts["kind"] = kind
    facts.update(_forecast_facts(world, forecasts, j))
    return facts


def explain_timeout(world: RecordingWorld) -> dict:
    """Where the ego waits at the time limit, for how long, and what drove past meanwhile."""
    dt = world.scenario.dt
    ego = world.traffic.states[0]
    lane = _nearest_lane(world, ego[:2])
    name = world.road.names[lane] if lane >= 0 else None
    s, _ = world.road.frenet(np.array([lane]), float(ego[0]), float(ego[1]))
    s0 = float(s[0])
    where = {"lane": name, "s_m": round(s0, 2)}
    if name == "south_in":
        where["before_stop_line_m"] = round(float(world.road.lengths[lane]) - s0, 2)
    speeds = np.array([states[0, 2] for states, _ in world.history])
    moving = np.flatnonzero(speeds >= STOPPED)
    stopped_since = (moving[-1] + 1) * dt if moving.size else 0.0
    junction_agents: set[int] = set()
    first_stop = int(round(stopped_since / dt))
    for states, active in world.history[first_stop:]:
        for j in np.flatnonzero(active):
            if j != 0 and _in_junction(world, states[j, :2]):
                junction_agents.add(int(j))
    others = [int(j) for j in np.flatnonzero(world.traffic.active) if j != 0]
    nearest = min(others, key=lambda j: float(np.hypot(*(world.traffic.states[j, :2] - ego[:2]))), default=None)
    near: dict = {}
    if nearest is not None:
        state = world.traffic.states[nearest]
        near = {
            "nearest": nearest,
            "nearest_m": round(float(np.hypot(*(state[:2] - ego[:2]))), 2),
            "nearest_movement": _movement(world, nearest),
            "nearest_speed": round(float(state[2]), 2),
            "nearest_courteous": bool(world.traffic.courteous[nearest]),
            "nearest_yielding": bool(world.records[-1].yielding[nearest]),
            "nearest_follows_ego": bool(world.records[-1].leader[nearest] == 0),
        }
    return {
        **where,
        **near,
        "ego_speed": round(float(ego[2]), 2),
        "stopped_since_s": round(float(stopped_since), 2),
        "stopped_share": round(float(np.mean(speeds < STOPPED)), 3),
        "vehicles_through_junction_while_stopped": len(junction_agents),
        "kind": f"waits on {name}" if name else "waits off the lanes",
    }


def rerun(kind: str, method: str, seed: int, config: LoopConfig, expected: Mapping[str, str]):
    """Re-run one recorded episode in a `RecordingWorld`; check it is the record; return ``(record, world, plans)``.

    ``plans`` are the tree searches' ``(model, root, decision)``, one per plan
    (`RecordingPlanner`; empty for a method without tree search). Raises RuntimeError if
    the outcome, time, discounted return or number of decisions differs from ``expected``
    (a row of the records' ``episodes.csv``).
    """
    factory = functools.partial(RecordingScenario, kind)
    scenario = factory()
    job = EpisodeJob(kind, method, seed, config, factory, method_factory(method, scenario, config))
    road_planning.RobustTreePlanner = RecordingPlanner
    RecordingPlanner.plans = []
    try:
        record = run_job(job)
    finally:
        road_planning.RobustTreePlanner = RobustTreePlanner
        plans, RecordingPlanner.plans = RecordingPlanner.plans, []
    got = {
        "outcome": record.outcome,
        "time_s": float(record.time_s),
        "discounted_return": float(record.discounted_return),
        "decisions": int(record.decisions),
    }
    want = {
        "outcome": expected["outcome"],
        "time_s": float(expected["time_s"]),
        "discounted_return": float(expected["discounted_return"]),
        "decisions": int(expected["decisions"]),
    }
    world = _WORLDS.pop((kind, int(seed)))
    if got != want:
        raise RuntimeError(f"{kind} {method} seed {seed}: the re-run {got} is not the record {want}")
    return record, world, plans


def explain(kind: str, method: str, seed: int, config: LoopConfig, expected: Mapping[str, str]) -> dict:
    """Re-run one recorded episode, check it is the record, and explain its outcome."""
    forecasts: list[tuple[int, np.ndarray]] = []
    point_forecast = road_planning.point_forecast

    def keep(world, *args, **kwargs):
        table = point_forecast(world, *args, **kwargs)
        forecasts.append((world.step_index, table))
        return table

    began = time.perf_counter()
    road_planning.point_forecast = keep
    try:
        record, world, plans = rerun(kind, method, seed, config, expected)
    finally:
        road_planning.point_forecast = point_forecast
    wall = time.perf_counter() - began
    facts = explain_collision(world, forecasts) if record.outcome == "collision" else explain_timeout(world)
    if record.outcome == "collision":
        facts.update(_plan_facts(world, plans, forecasts, facts["other"]))
    return {"scenario": kind, "method": method, "seed": seed, "outcome": record.outcome, "wall_s": wall, **facts}


def records_environment(script: str) -> dict:
    """This process's `numerical_environment`; exit 2 with one line on stderr unless it is the records'."""
    environment = numerical_environment()
    if not environment["matches_records"]:
        print(
            f"{script}: the process does not have the records' numerical environment "
            "(run it with the env prefix in this script's docstring)",
            file=sys.stderr,
        )
        raise SystemExit(2)
    return environment


def markdown(rows: Sequence[Mapping], meta: Mapping) -> str:
    """The explanations as tables: one row per episode, then the count of each kind."""
    lines = [
        "# Table 4: every episode of nominal, oracle, DWA and TEB without the goal, explained",
        "",
        f"`python benchmarks/explain_table4_failures.py` under the records' numerical environment, "
        f"{meta['date']}, {meta['wall_time_s']:.0f} s wall, load {meta['load']}: each episode re-run "
        "from `benchmarks/results/experiments/table4/episodes.csv` and found identical to its record "
        "(outcome, time, discounted return, decisions), then read against the world's ground truth.",
        "",
        "Collisions (`ahead`, `left`: the other vehicle's centre in the ego's frame at contact, m; "
        "`changed`: s since the other vehicle last started a lane change):",
        "",
        "| scenario | method | seed | t (s) | kind | ego on | other on | other's route | ahead, left (m) "
        "| speeds ego / other (m/s) | 2 s before | changed (s before) | courteous / yielding |",
        "|---|---|---:|---:|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r["outcome"] != "collision":
            continue
        changed = "-" if r["other_lane_change_s_before"] is None else f"{r['other_lane_change_s_before']:.1f}"
        lines.append(
            f"| {r['scenario']} | {r['method']} | {r['seed']} | {r['time_s']:.1f} | {r['kind']} | "
            f"{', '.join(r['ego_lanes']) or '-'} | {', '.join(r['other_lanes']) or '-'} | "
            f"{r['other_movement']} | {r['ahead_m']:.1f}, {r['left_m']:.1f} | "
            f"{r['ego_speed']:.1f} / {r['other_speed']:.1f} | "
            f"{r['ego_speed_2s_before']:.1f} / {r['other_speed_2s_before']:.1f} | {changed} | "
            f"{'yes' if r['other_courteous'] else 'no'} / {'yes' if r['other_yielding_last_s'] else 'no'} |"
        )
    planned = [r for r in rows if r["outcome"] == "collision" and "replan" in r]
    if planned:
        lines += [
            "",
            "The tree-search methods' collisions, decision by decision (`_plan_facts`, `_replan_facts`): the last "
            "decision whose best plan was clear of every box over the 5 s forecast; the rest of that plan from the "
            "next decision's true state, against the old forecast and the new one; where each put the vehicle met "
            "and where it truly was (x, y in m):",
            "",
            "| scenario | method | seed | last clear plan (s before) | every plan collides from (s before) | "
            "the rest of the plan | vehicle met | old forecast | new forecast | truth |",
            "|---|---|---:|---:|---:|---|---:|---|---|---|",
        ]
        for r in planned:
            lines.append(
                f"| {r['scenario']} | {r['method']} | {r['seed']} | {r['plan_clear_last_s_before']} | "
                f"{r['plans_colliding_from_s_before']} | {r['replan']} | {r.get('replan_vehicle', '-')} | "
                f"{r.get('replan_old_centre', '-')} | {r.get('replan_new_centre', '-')} | "
                f"{r.get('replan_true_centre') or 'after the episode'} |"
            )
    timeouts = [r for r in rows if r["outcome"] == "timeout"]
    if timeouts:
        lines += [
            "",
            f"Timeouts (stopped: below {STOPPED} m/s; through the junction: other vehicles in the junction "
            "box or on a turn while the ego stood):",
            "",
            "| scenario | method | seed | ego on | s (m) | before the stop line (m) | stopped from t (s) "
            "| share of the episode stopped | vehicles through the junction since "
            "| nearest vehicle at the end: distance (m), route, speed (m/s), courteous / yielding / following the ego |",
            "|---|---|---:|---|---:|---:|---:|---:|---:|---|",
        ]
        for r in timeouts:
            before = r.get("before_stop_line_m")
            nearest = (
                f"{r['nearest_m']:.1f}, {r['nearest_movement']}, {r['nearest_speed']:.1f}, "
                f"{'yes' if r['nearest_courteous'] else 'no'} / {'yes' if r['nearest_yielding'] else 'no'} / "
                f"{'yes' if r['nearest_follows_ego'] else 'no'}"
                if "nearest" in r
                else "-"
            )
            lines.append(
                f"| {r['scenario']} | {r['method']} | {r['seed']} | {r['lane']} | {r['s_m']:.1f} | "
                f"{'-' if before is None else f'{before:.1f}'} | {r['stopped_since_s']:.1f} | "
                f"{r['stopped_share']:.2f} | {r['vehicles_through_junction_while_stopped']} | {nearest} |"
            )
    counts: dict[tuple[str, str, str], int] = {}
    for r in rows:
        key = (r["scenario"], r["method"], r["kind"])
        counts[key] = counts.get(key, 0) + 1
    lines += ["", "| scenario | method | kind | episodes |", "|---|---|---|---:|"]
    lines += [f"| {a} | {b} | {c} | {n} |" for (a, b, c), n in sorted(counts.items())]
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> list[dict]:
    """Explain every recorded non-goal episode of the methods asked for; write the results."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", default=",".join(METHODS), help="comma-separated methods (default: %(default)s)")
    parser.add_argument("--out", type=pathlib.Path, default=RESULTS)
    args = parser.parse_args(argv)
    methods = [m for m in args.methods.split(",") if m]
    unknown = sorted(set(methods) - set(METHODS))
    if unknown:
        parser.error(f"--methods must be among {list(METHODS)}, got {unknown}")
    environment = records_environment("explain_table4_failures")
    with RECORDS.open(newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r["method"] in methods and r["outcome"] != "goal"]
    config = LoopConfig()
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    began = time.perf_counter()
    explained = [explain(r["scenario"], r["method"], int(r["seed"]), config, r) for r in rows]
    meta = {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "wall_time_s": time.perf_counter() - began,
        "load": load,
        "environment": environment,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "table4_failures.json").write_text(json.dumps({"meta": meta, "episodes": explained}, indent=2) + "\n")
    (args.out / "table4_failures.md").write_text(markdown(explained, meta))
    return explained


if __name__ == "__main__":
    main()
