"""Tune the DWA and TEB baselines on tuning seeds (10000+), never on evaluation seeds (0-999).

Each candidate parameter set runs the same seeded episodes of both worlds in the closed
loop (measured state in, control held for one decision period out); candidates are
ranked by failures (collisions + timeouts), then collisions, then mean time to goal.
Prints a Markdown table per planner; docs/baselines.md records the outcome.

    OMP_NUM_THREADS=1 python benchmarks/tune_baselines.py dwa 40 1    # round 1
    OMP_NUM_THREADS=1 python benchmarks/tune_baselines.py dwa 100 2   # round 2
    OMP_NUM_THREADS=1 python benchmarks/tune_baselines.py teb 20 1
    OMP_NUM_THREADS=1 python benchmarks/tune_baselines.py teb 40 2

The driving baselines (the bicycle DWA and TEB of the road worlds, "highway" and
"tjunction", run through the registry's episode loop) are tuned the same way, ranked by
failures (collisions + off-road + timeouts), then collisions, then mean travel time:

    OMP_NUM_THREADS=1 python benchmarks/tune_baselines.py road-dwa 10 1
    OMP_NUM_THREADS=1 python benchmarks/tune_baselines.py road-teb 5 1
"""

from __future__ import annotations

import sys
import time

import numpy as np

from minimaxplan.planners.dwa import DWAParameters, DynamicWindowPlanner, NavigationScene
from minimaxplan.planners.teb import TEBParameters, TimedElasticBand
from minimaxplan.scenarios.worlds import make_world

TUNING_SEED0 = 10_000

# Round 1 screens single changes; round 2 compares the leaders on more seeds.
DWA_ROUND1 = [
    {},
    {"clearance_weight": 0.8},
    {"clearance_weight": 0.8, "heading_weight": 0.6},
    {"clearance_weight": 0.8, "max_speed": 1.2},
    {"clearance_weight": 0.8, "safety_margin": 0.2},
    {"clearance_weight": 0.8, "horizon": 3.0},
    {"clearance_weight": 0.8, "horizon": 1.0},
    {"clearance_weight": 1.5},
    {"clearance_weight": 0.8, "pedestrian_margin": 0.5},
    {"clearance_weight": 0.8, "samples_per_axis": 11},
]

DWA_ROUND2 = [
    {},
    {"horizon": 1.0},
    {"clearance_weight": 0.8, "horizon": 1.0},
    {"clearance_weight": 0.8, "horizon": 1.5},
]

TEB_ROUND1 = [
    {},
    {"obstacle_margin": 0.3},
    {"pedestrian_margin": 0.6},
    {"max_speed": 1.2},
    {"obstacle_weight": 500.0},
    {"max_iterations": 25},
]

TEB_ROUND2 = [
    {},
    {"max_iterations": 25},
    {"max_iterations": 25, "obstacle_margin": 0.3},
    {"max_iterations": 25, "pedestrian_margin": 0.6},
]

# The driving baselines: single changes from the defaults (Tables 1-2's vehicle columns).
ROAD_DWA_ROUND1 = [
    {},
    {"horizon": 3.0},
    {"horizon": 1.5},
    {"lateral_acceleration": 6.0},
    {"lane_weight": 10.0},
    {"heading_weight": 30.0},
]

ROAD_TEB_ROUND1 = [
    {},
    {"lane_weight": 10.0},
    {"lane_weight": 10.0, "obstacle_margin": 0.5},
    {"lane_weight": 10.0, "lookahead_time": 3.0},
]

ROUNDS = {
    ("dwa", 1): DWA_ROUND1,
    ("dwa", 2): DWA_ROUND2,
    ("teb", 1): TEB_ROUND1,
    ("teb", 2): TEB_ROUND2,
    ("road-dwa", 1): ROAD_DWA_ROUND1,
    ("road-teb", 1): ROAD_TEB_ROUND1,
}


def scene_of(world) -> NavigationScene:
    crowd = world.crowd
    return NavigationScene(
        world.goal, world.obstacles.centers, world.obstacles.radii, crowd.positions, crowd.announced, crowd.radii
    )


def run_episode(planner, kind: str, seed: int) -> tuple[str, float, list[float]]:
    world = make_world(kind, seed)
    if hasattr(planner, "reset"):
        planner.reset()
    latencies = []
    while not world.done:
        state = world.measure()
        started = time.perf_counter()
        u = planner.plan(state, scene_of(world))
        latencies.append(time.perf_counter() - started)
        world.apply_held(u)
    return world.outcome, world.time, latencies


def evaluate(make_planner, seeds) -> dict:
    row = {}
    for kind in ("static", "pedestrian"):
        outcomes, times, latencies = {}, [], []
        for seed in seeds:
            world_outcome, t, lat = run_episode(make_planner(), kind, seed)
            outcomes[world_outcome] = outcomes.get(world_outcome, 0) + 1
            latencies += lat
            if world_outcome == "goal":
                times.append(t)
        row[kind] = {
            "collision": outcomes.get("collision", 0),
            "timeout": outcomes.get("timeout", 0),
            "goal": outcomes.get("goal", 0),
            "mean_time": float(np.mean(times)) if times else float("nan"),
            "median_ms": 1e3 * float(np.median(latencies)),
        }
    return row


def rank_key(row: dict) -> tuple:
    failures = sum(row[k]["collision"] + row[k]["timeout"] for k in row)
    collisions = sum(row[k]["collision"] for k in row)
    time_sum = sum(row[k]["mean_time"] for k in row)
    return (failures, collisions, time_sum)


ROAD_KINDS = ("highway", "tjunction")


def evaluate_road(which: str, change: dict, seeds) -> dict:
    """Closed-loop road episodes of one candidate: outcomes, mean travel time, median call time."""
    import functools

    from minimaxplan.analysis.episode import DEFAULT_CONFIG, EpisodeJob, run_job
    from minimaxplan.analysis.road_methods import (
        ROAD_DWA_PARAMETERS,
        ROAD_TEB_PARAMETERS,
        RoadDWAMethod,
        RoadTEBMethod,
    )
    from minimaxplan.analysis.road_scenario import RoadScenario

    method, frozen = (
        (RoadDWAMethod, ROAD_DWA_PARAMETERS) if which == "road-dwa" else (RoadTEBMethod, ROAD_TEB_PARAMETERS)
    )
    row = {}
    for kind in ROAD_KINDS:
        params = type(frozen[kind])(**{**frozen[kind].to_dict(), **change})
        outcomes, times, walls, calls = {}, [], 0.0, 0
        for seed in seeds:
            job = EpisodeJob(
                kind,
                which,
                seed,
                DEFAULT_CONFIG,
                functools.partial(RoadScenario, kind),
                functools.partial(method, params=params),
            )
            record = run_job(job)
            outcomes[record.outcome] = outcomes.get(record.outcome, 0) + 1
            walls += record.wall_time_s
            calls += record.decisions
            if record.outcome == "goal":
                times.append(record.time_s)
        row[kind] = {
            "collision": outcomes.get("collision", 0),
            "off_road": outcomes.get("off_road", 0),
            "timeout": outcomes.get("timeout", 0),
            "goal": outcomes.get("goal", 0),
            "mean_time": float(np.mean(times)) if times else float("nan"),
            "ms_per_decision": 1e3 * walls / max(calls, 1),
        }
    return row


def main_road(which: str, episodes: int, round_: int) -> None:
    seeds = range(TUNING_SEED0, TUNING_SEED0 + episodes)
    print(
        f"| {which} change from defaults | highway coll/off/timeout/goal | highway time (s) | "
        "T-junction coll/off/timeout/goal | T-junction time (s) | wall per decision (ms) |"
    )
    print("|---|---|---|---|---|---|")
    rows = []
    for change in ROUNDS[which, round_]:
        row = evaluate_road(which, change, seeds)
        rows.append((change, row))
        h, t = row["highway"], row["tjunction"]
        print(
            f"| {change or 'defaults'} | {h['collision']}/{h['off_road']}/{h['timeout']}/{h['goal']} | "
            f"{h['mean_time']:.2f} | {t['collision']}/{t['off_road']}/{t['timeout']}/{t['goal']} | "
            f"{t['mean_time']:.2f} | {max(h['ms_per_decision'], t['ms_per_decision']):.0f} |",
            flush=True,
        )

    def key(row: dict) -> tuple:
        failures = sum(row[k]["collision"] + row[k]["off_road"] + row[k]["timeout"] for k in row)
        return (failures, sum(row[k]["collision"] for k in row), sum(row[k]["mean_time"] for k in row))

    best = min(rows, key=lambda r: key(r[1]))
    print(
        f"\nbest on {episodes} tuning seeds per world ({TUNING_SEED0}..{TUNING_SEED0 + episodes - 1}): "
        f"{best[0] or 'defaults'}"
    )


def main(which: str, episodes: int, round_: int) -> None:
    if which.startswith("road-"):
        main_road(which, episodes, round_)
        return
    seeds = range(TUNING_SEED0, TUNING_SEED0 + episodes)
    system = make_world("static", TUNING_SEED0).system  # the same model structure in every world
    if which == "dwa":
        candidates = [
            (c, lambda c=c: DynamicWindowPlanner(system, params=DWAParameters(**c))) for c in ROUNDS["dwa", round_]
        ]
    else:
        candidates = [
            (c, lambda c=c: TimedElasticBand(system, params=TEBParameters(**c))) for c in ROUNDS["teb", round_]
        ]
    rows = []
    print(
        f"| {which} change from defaults | static coll/timeout/goal | static time (s) | "
        "pedestrian coll/timeout/goal | pedestrian time (s) | median call (ms) |"
    )
    print("|---|---|---|---|---|---|")
    for change, make in candidates:
        row = evaluate(make, seeds)
        rows.append((change, row))
        s, p = row["static"], row["pedestrian"]
        print(
            f"| {change or 'defaults'} | {s['collision']}/{s['timeout']}/{s['goal']} | {s['mean_time']:.1f} | "
            f"{p['collision']}/{p['timeout']}/{p['goal']} | {p['mean_time']:.1f} | "
            f"{max(s['median_ms'], p['median_ms']):.1f} |",
            flush=True,
        )
    best = min(rows, key=lambda r: rank_key(r[1]))
    print(
        f"\nbest on {episodes} tuning seeds per world ({TUNING_SEED0}..{TUNING_SEED0 + episodes - 1}): {best[0] or 'defaults'}"
    )


if __name__ == "__main__":
    main(
        sys.argv[1] if len(sys.argv) > 1 else "dwa",
        int(sys.argv[2]) if len(sys.argv) > 2 else 40,
        int(sys.argv[3]) if len(sys.argv) > 3 else 1,
    )
