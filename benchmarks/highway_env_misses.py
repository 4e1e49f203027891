"""Attribute every missed box of the robust method on highway-env, one by one (issue 12).

The run-time check (`minimaxplan.analysis.episode.BoxCheck`) records each miss: which
box (``"ego"`` or ``"vehicle j"``), in which decision and sub-step, the true state and
the predicted box. This diagnostic runs the robust method's episodes (the registered
``highway-env:highway-fast-v0`` and ``highway-env:intersection-v0`` worlds, the same
loop and seeds as ``minimaxplan experiment``) in a world that also records, after every
simulation step, highway-env's ground truth of every vehicle: whether it has crashed,
its lane and target lane indices, the centre of its target lane at its position, its
speed, and whether its lane is a ``CircularLane``. That ground truth is read here, at
diagnosis only: the method never sees it (the world's `measure` is unchanged, and
reading highway-env's attributes draws no random number, so the episodes are the
experiment's).

Each miss gets the first kind that applies, over the steps from the one before the
decision's start (where the forecast began: a switch of hidden target during that step
is not in its observation) to the missed sub-step (`classify_miss`):

``crash``
    the vehicle (or the ego) has crashed: highway-env's collision impulse, outside
    every model;
``reversing``
    its speed was negative (highway-env's vehicles brake through 0 to ``MIN_SPEED``);
``lane change aborted``
    a lane change in progress was aborted (highway-env's MOBIL sets the target back to
    the current lane when another vehicle changes into the same lane: the vehicle
    turns back, a manoeuvre the forecast's lane-change rows do not have);
``lane change ruled out``
    a lane change was in progress (``target_lane_index != lane_index`` on the same
    edge) and the box does not reach its target lane's centre: the forecast ruled the
    change out (its gap rule, its settling or its interval rule disagree with MOBIL);
``lane change allowed``
    a lane change was in progress and the box reaches the target lane's centre;
``a leader's lane change``
    another vehicle (not the ego, whose every path is in its reach) up to
    `LEADER_RANGE` m ahead was changing lane into or out of this vehicle's lane: the
    vehicle followed a leader the forecast did not give it (a change the forecast
    ruled out, the first kind, seen from the follower);
``route lane switch``
    its target lane is on another edge than its lane, or moved to another edge
    (highway-env steers to the next lane of its route 2.5 m before the current one
    ends);
``next-lane leader unseen``
    highway-env found no front vehicle on the vehicle's current lane while a search of
    the connected lanes finds one: ``intersection-v0`` keeps its v0 default
    ``neighbour_vehicles_connected_lanes = False``, so its vehicles do not follow a leader
    on their next route lane, while the library's model (and world) follows the nearest
    vehicle along the route, so highway-env's vehicle brakes less than the model allows;
``crossing leader``
    highway-env's front vehicle of this one (`Road.neighbour_vehicles`, any vehicle whose
    centre is on the lane, a crossing one included) drove at a heading more than
    `CROSSING_ANGLE` from its own: highway-env's `LinearVehicle` reads that leader's own
    speed (``min(front.speed - speed, 0)``), the library's model (and world) its speed
    along the follower's lane, which is lower for a crossing leader, so highway-env's
    vehicle brakes less than the model allows;
``curved lane``
    it drove on a ``CircularLane``;
``unexplained``
    none of these (a bug to find).

Writes benchmarks/results/highway_env_misses.md and .json (kind -> misses and
episodes, per environment; every unexplained miss in full). Needs the ``vehicle``
extra. Usage: ``python benchmarks/highway_env_misses.py [--episodes N] [--workers W]
[--scenario NAME]`` (default 50 episodes, seeds 0..N-1, 2 workers, highway-fast-v0 and
intersection-v0; with ``--scenario`` only the registered scenarios it names are run, such
as ``highway-env:highway-fast-v0-speeds-0-30``, the others' results in the files are kept).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import datetime
import functools
import json
import os
import pathlib
import platform
import time
import warnings
from collections.abc import Mapping, Sequence

import numpy as np

from minimaxplan.analysis import episode as episode_module
from minimaxplan.analysis.episode import EpisodeJob, LoopConfig, run_job
from minimaxplan.analysis.highway_env_scenario import (
    HIGHWAY_ENV_SCENARIOS,
    HIGHWAY_ENV_VARIANTS,
    HighwayEnvScenario,
    HighwayEnvWorld,
)
from minimaxplan.analysis.registry import method_factory
from minimaxplan.models.errors import InputError

RESULTS = pathlib.Path(__file__).parent / "results"
#: The kinds, in the order they are tried.
KINDS = (
    "crash",
    "reversing",
    "lane change aborted",
    "lane change ruled out",
    "lane change allowed",
    "a leader's lane change",
    "route lane switch",
    "next-lane leader unseen",
    "crossing leader",
    "curved lane",
    "unexplained",
)
#: The registered scenario name -> (highway-env id, the ego's target speeds or None for highway-env's).
SCENARIOS = {
    **{name: (env_id, None) for name, env_id in HIGHWAY_ENV_SCENARIOS.items()},
    **HIGHWAY_ENV_VARIANTS,
}
#: The scenarios run when ``--scenario`` names none (the README's table).
DEFAULT_SCENARIOS = tuple(HIGHWAY_ENV_SCENARIOS)
#: How far ahead a lane-changing vehicle counts as a leader, m.
LEADER_RANGE = 150.0
#: A front vehicle whose heading differs from the follower's by more than this (rad) is a crossing leader.
CROSSING_ANGLE = 0.2
#: Misses recorded per episode here (the loop's default keeps the first 100).
RECORDED_MISSES = 100_000


def vehicle_facts(vehicle, network, road=None) -> dict:
    """highway-env's ground truth of one vehicle now (diagnosis only).

    Parameters
    ----------
    vehicle : highway_env.vehicle.kinematics.Vehicle
        The vehicle.
    network : highway_env.road.road.RoadNetwork
        Its road network.
    road : highway_env.road.road.Road, optional
        Its road: then ``front_heading`` is the heading of its front vehicle as
        highway-env's behaviour finds it (None when it has none), and
        ``front_connected`` whether a search of the connected lanes finds one.

    Returns
    -------
    dict
        ``crashed``, ``lane`` and ``target`` (lane indices as lists), ``target_centre``
        (the point of the target lane's centre line at the vehicle's longitudinal
        position), ``position``, ``heading``, ``speed``, ``curved`` (its lane is a
        ``CircularLane``), ``front_heading`` and ``front_connected``.
    """
    from highway_env.road.lane import CircularLane

    target = getattr(vehicle, "target_lane_index", None) or vehicle.lane_index
    lane = network.get_lane(target)
    s, _ = lane.local_coordinates(vehicle.position)
    return {
        "crashed": bool(vehicle.crashed),
        "lane": list(vehicle.lane_index),
        "target": list(target),
        "target_centre": [float(v) for v in lane.position(s, 0.0)],
        "position": [float(v) for v in vehicle.position],
        "heading": float(vehicle.heading),
        "speed": float(vehicle.speed),
        "curved": isinstance(vehicle.lane, CircularLane),
        "front_heading": _front_heading(vehicle, road),
        "front_connected": _front_connected(vehicle, road),
    }


def _front_connected(vehicle, road) -> bool | None:
    if road is None:
        return None
    flag = road.neighbour_vehicles_connected_lanes
    road.neighbour_vehicles_connected_lanes = True
    try:
        front, _ = road.neighbour_vehicles(vehicle)
    finally:
        road.neighbour_vehicles_connected_lanes = flag
    return front is not None


def _front_heading(vehicle, road) -> float | None:
    if road is None:
        return None
    front, _ = road.neighbour_vehicles(vehicle)
    return None if front is None else float(front.heading)


class DiagnosedWorld(HighwayEnvWorld):
    """A `HighwayEnvWorld` that records highway-env's ground truth after every step (``to_dict()["facts"]``).

    Parameters
    ----------
    env_id : str
        A highway-env id of `minimaxplan.analysis.highway_env_scenario.HIGHWAY_ENV_SCENARIOS`.
    seed : int
        highway-env's seed.
    target_speeds : sequence of float, optional
        The ego's target speeds (`HighwayEnvWorld`).
    """

    def __init__(self, env_id: str, seed: int, *, target_speeds=None) -> None:
        super().__init__(env_id, seed, target_speeds=target_speeds)
        self.facts: list[dict[str, dict]] = [self._facts()]

    def _facts(self) -> dict[str, dict]:
        base = self.adapter.env.unwrapped
        network = base.road.network
        out = {"ego": vehicle_facts(base.vehicle, network, base.road)}
        for v in base.road.vehicles:
            if v is not base.vehicle:
                out[f"vehicle {self.adapter.agent_id(v)}"] = vehicle_facts(v, network, base.road)
        return out

    def apply(self, u: np.ndarray) -> str:
        """`HighwayEnvWorld.apply`, then record the ground truth.

        Parameters
        ----------
        u : numpy.ndarray, shape (1,)
            The action's index.
        """
        outcome = super().apply(u)
        self.facts.append(self._facts())
        return outcome

    def to_dict(self) -> dict:
        """`HighwayEnvWorld.to_dict` with ``facts``: per step, name -> `vehicle_facts`."""
        return {**super().to_dict(), "facts": self.facts}


class DiagnosedScenario(HighwayEnvScenario):
    """`HighwayEnvScenario` whose worlds are `DiagnosedWorld`s.

    Parameters
    ----------
    env_id : str
        A highway-env id.
    """

    def make_world(self, seed: int, config: LoopConfig) -> DiagnosedWorld:
        """The episode's world (`HighwayEnvScenario.make_world`'s checks, then a `DiagnosedWorld`).

        Parameters
        ----------
        seed : int
            The episode's seed.
        config : LoopConfig
            The loop settings.
        """
        if config.measurement != "uniform":
            raise InputError(f"highway-env worlds are measured exactly, got measurement {config.measurement!r}")
        return DiagnosedWorld(self.env_id, seed, target_speeds=self.target_speeds)


def _changing(fact: Mapping) -> bool:
    lane, target = fact["lane"], fact["target"]
    return lane[:2] == target[:2] and lane[2] != target[2]


def _leader_changing(step: Mapping[str, Mapping], name: str) -> bool:
    """Whether a vehicle other than ``name`` and the ego, ahead within `LEADER_RANGE`, changes lane into or out of its lane."""
    me = step[name]
    direction = np.array([np.cos(me["heading"]), np.sin(me["heading"])])
    for other, fact in step.items():
        if other in (name, "ego") or not _changing(fact):
            continue
        if me["lane"] not in (fact["lane"], fact["target"]):
            continue
        ahead = float(np.dot(np.asarray(fact["position"]) - np.asarray(me["position"]), direction))
        if 0.0 < ahead <= LEADER_RANGE:
            return True
    return False


def _crossing(fact: Mapping) -> bool:
    front = fact.get("front_heading")
    return front is not None and abs(float(np.angle(np.exp(1j * (front - fact["heading"]))))) > CROSSING_ANGLE


def classify_miss(miss: Mapping, facts: Sequence[Mapping[str, Mapping]], start: int) -> str:
    """The kind of one missed box (the first of `KINDS` that applies).

    Parameters
    ----------
    miss : mapping
        A miss of the run-time check (``name``, ``substep``, ``lower``, ``upper``).
    facts : sequence of mapping
        Per world step, name -> `vehicle_facts`.
    start : int
        The world step at which the missed decision began (its forecast's start); the
        facts are read from the step before it to the missed sub-step.

    Returns
    -------
    str
        One of `KINDS`.
    """
    name, end = miss["name"], start + int(miss["substep"])
    # from the step before the decision: a hidden switch during it is not in the observation
    seen = [f[name] for f in facts[max(start - 1, 0) : end + 1] if name in f]
    if not seen:
        return "unexplained"
    if any(f["crashed"] for f in seen):
        return "crash"
    if any(f["speed"] < 0.0 for f in seen):
        return "reversing"
    changes = [f for f in seen if _changing(f)]
    if any(_changing(a) and b["lane"] == a["lane"] and b["target"] != a["target"] for a, b in zip(seen, seen[1:])):
        return "lane change aborted"
    if changes:
        lower, upper = np.asarray(miss["lower"], float), np.asarray(miss["upper"], float)
        centre = np.asarray(seen[-1]["target_centre"], float)
        reaches = bool(np.all(lower[:2] <= centre) and np.all(centre <= upper[:2]))
        return "lane change allowed" if reaches else "lane change ruled out"
    window = facts[max(start - 1, 0) : end + 1]
    if any(_leader_changing(step, name) for step in window if name in step):
        return "a leader's lane change"
    if any(f["target"][:2] != f["lane"][:2] or f["target"][:2] != seen[0]["target"][:2] for f in seen):
        return "route lane switch"
    if any(f.get("front_connected") and f.get("front_heading") is None for f in seen):
        return "next-lane leader unseen"
    if any(_crossing(f) for f in seen):
        return "crossing leader"
    if any(f["curved"] for f in seen):
        return "curved lane"
    return "unexplained"


def attribute(record) -> list[dict]:
    """Every recorded miss of one episode with its kind (and where it happened).

    Parameters
    ----------
    record : EpisodeRecord
        A robust episode of a `DiagnosedWorld`.

    Returns
    -------
    list of dict
        Per miss: ``kind``, ``name``, ``decision``, ``substep``, ``time``, ``excess``,
        ``coordinates``; an unexplained one also its ``state``, ``lower``, ``upper`` and
        the ``facts`` of every vehicle over its window.
    """
    facts = record.extra["world"]["facts"]
    steps = record.trace["decision_steps"]
    out = []
    for miss in record.extra["runtime_check"]["misses"]:
        kind = classify_miss(miss, facts, steps[miss["decision"]])
        row = {k: miss[k] for k in ("name", "decision", "substep", "time", "excess", "coordinates")}
        row["kind"] = kind
        if kind == "unexplained":
            start = steps[miss["decision"]]
            window = facts[max(start - 1, 0) : start + int(miss["substep"]) + 1]
            row.update(state=miss["state"], lower=miss["lower"], upper=miss["upper"], facts=window)
        out.append(row)
    return out


def _init_worker() -> None:
    episode_module.MAX_RECORDED_MISSES = RECORDED_MISSES  # type: ignore[attr-defined]
    warnings.simplefilter("ignore", DeprecationWarning)


def _episode(job: EpisodeJob) -> dict:
    _init_worker()
    record = run_job(job)
    misses = attribute(record)
    return {
        "scenario": job.scenario,
        "seed": job.seed,
        "outcome": record.outcome,
        "boxes_checked": record.boxes_checked,
        "boxes_missed": record.boxes_missed,
        "recorded": len(misses),
        "misses": misses,
        "wall_time_s": record.wall_time_s,
    }


def summarise(episodes: Sequence[Mapping]) -> dict:
    """Per scenario: kind -> misses and episodes, and the totals.

    Parameters
    ----------
    episodes : sequence of mapping
        `_episode`'s results.
    """
    out: dict = {}
    for ep in episodes:
        s = out.setdefault(
            ep["scenario"],
            {"episodes": 0, "boxes_checked": 0, "boxes_missed": 0, "recorded": 0, "kinds": {}, "unexplained": []},
        )
        s["episodes"] += 1
        s["boxes_checked"] += ep["boxes_checked"]
        s["boxes_missed"] += ep["boxes_missed"]
        s["recorded"] += ep["recorded"]
        seen = set()
        for miss in ep["misses"]:
            kind = s["kinds"].setdefault(miss["kind"], {"misses": 0, "episodes": 0})
            kind["misses"] += 1
            if miss["kind"] not in seen:
                kind["episodes"] += 1
                seen.add(miss["kind"])
            if miss["kind"] == "unexplained":
                s["unexplained"].append({"seed": ep["seed"], **miss})
    return out


def markdown(summary: Mapping, runs: Mapping) -> str:
    """The kind -> count table per scenario, with each scenario's run (date, workers, wall time, load)."""
    lines = ["# highway-env: every missed box of the robust method, attributed", ""]
    for scenario, meta in sorted(runs.items()):
        lines.append(
            f"* {scenario}: `python benchmarks/highway_env_misses.py --episodes {meta['episodes']}"
            f"{'' if scenario in DEFAULT_SCENARIOS else ' --scenario ' + scenario}` "
            f"(seeds 0-{meta['episodes'] - 1}), {meta['date']}, {meta['workers']} workers, "
            f"{meta['wall_time_s']:.0f} s wall, load {meta['load']}"
        )
    lines += [
        "",
        "Kinds in `benchmarks/highway_env_misses.py` (the first that applies, from the step before the "
        "decision's start to the miss).",
        "",
        "| scenario | kind | misses | episodes |",
        "|---|---|---|---|",
    ]
    for scenario, s in summary.items():
        for kind in KINDS:
            if kind in s["kinds"]:
                lines.append(f"| {scenario} | {kind} | {s['kinds'][kind]['misses']} | {s['kinds'][kind]['episodes']} |")
        lines.append(
            f"| {scenario} | **all** | {s['boxes_missed']} of {s['boxes_checked']} checked "
            f"({s['recorded']} recorded) | {s['episodes']} run |"
        )
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> dict:
    """Run the episodes, attribute the misses, write the results."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=pathlib.Path, default=RESULTS)
    parser.add_argument(
        "--scenario",
        action="append",
        choices=sorted(SCENARIOS),
        help="run only this registered scenario (repeatable; by default highway-fast-v0 and intersection-v0); "
        "the others' results in --out are kept",
    )
    args = parser.parse_args(argv)
    _init_worker()
    config = LoopConfig()
    jobs = []
    for name in args.scenario or DEFAULT_SCENARIOS:
        env_id, speeds = SCENARIOS[name]
        factory = functools.partial(DiagnosedScenario, env_id, target_speeds=speeds)
        scenario = factory()
        for seed in range(args.episodes):
            jobs.append(EpisodeJob(name, "robust", seed, config, factory, method_factory("robust", scenario, config)))
    started = time.perf_counter()
    if args.workers == 1:
        episodes = [_episode(job) for job in jobs]
    else:
        with concurrent.futures.ProcessPoolExecutor(max_workers=args.workers, initializer=_init_worker) as pool:
            episodes = list(pool.map(_episode, jobs))
    wall = time.perf_counter() - started
    meta = {
        "episodes": args.episodes,
        "workers": args.workers,
        "wall_time_s": wall,
        "load": " ".join(f"{v:.1f}" for v in os.getloadavg()),
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "python": platform.python_version(),
    }
    path = args.out / "highway_env_misses.json"
    runs = {scenario: meta for scenario in {job.scenario for job in jobs}}
    if args.scenario and path.exists():  # keep the other environments' episodes and runs
        previous = json.loads(path.read_text())
        ran = set(runs)
        episodes = [e for e in previous["episodes"] if e["scenario"] not in ran] + episodes
        runs = {**{k: v for k, v in previous["runs"].items() if k not in ran}, **runs}
    episodes.sort(key=lambda e: (e["scenario"], e["seed"]))
    summary = summarise(episodes)
    args.out.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"runs": runs, "summary": summary, "episodes": episodes}, indent=1) + "\n")
    (args.out / "highway_env_misses.md").write_text(markdown(summary, runs))
    print(markdown(summary, runs))
    return summary


if __name__ == "__main__":
    main()
