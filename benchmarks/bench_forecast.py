"""The traffic forecast with and without its lateral bounds: cost and what they buy.

`forecast_traffic` carries, for every fine unit on a straight lane, a quadratic-norm
bound of the lateral state (`scenarios.lateral_contraction`) and intersects the unit's
boxes with its ellipse's hull, and it keeps a unit that lies in one of the proven
invariant parallelograms of `scenarios.lateral_invariant` inside that set at every speed.
Measured in the same run, on the same scenes, in three settings: the interval boxes
alone (``lateral_contraction=False, lateral_invariant=False``, the reference), the radius
alone (``lateral_invariant=False``), and both (what the road methods run):

- CPU time per forecast (`time.process_time`, each forecast repeated `REPEATS` times, the
  median kept; a ratio is a setting's time over the reference's per scene, then the
  median over the scenes);
- guaranteed vehicle-steps (on the fine model, ``forecast.guaranteed``) out of all;
- misses: vehicle-steps whose true state or rectangle is outside the forecast's box
  (both settings are sound: 0 is the only correct figure).

Scenes: `SEEDS` episodes per world (the default scenarios, dt 0.1 s; seeds from
`BENCH_SEED0`, disjoint from the tests' and the evaluation's), the ego driven by a simple
lane-keeping (highway) or creeping (T-junction) controller, the worlds' own disturbance
and noise draws, every other vehicle with its prior belief, forecast `STEPS` sub-steps
ahead from sub-steps `STARTS` with the ego's exact footprint as its reach. Writes benchmarks/results/forecast.md and .json.
"""

from __future__ import annotations

import datetime
import json
import os
import pathlib
import platform
import time

import numpy as np

from minimaxplan.scenarios.road_world import make_road_world
from minimaxplan.scenarios.traffic_models import footprint_box, forecast_traffic, prior_belief
from minimaxplan.scenarios.vehicles import vehicle_corners

RESULTS = pathlib.Path(__file__).parent / "results"
BENCH_SEED0 = 20_000
SEEDS = 8
STARTS = (20, 40)
STEPS = 30
REPEATS = 3
#: Containment tolerance of the check, m or rad (as the tests').
TOL = 1e-9


def _ego_control(kind: str, state: np.ndarray) -> np.ndarray:
    """Lane keeping at 25 m/s (highway) or creeping to a stop (T-junction): an admissible ego, not a planner."""
    if kind == "highway":
        lane = np.clip(np.round(state[1] / 4.0), 0, 2)
        e, chi = state[1] - 4.0 * lane, state[3]
        return np.array([np.clip(2.0 * (25.0 - state[2]), -6, 6), np.clip(-0.5 * chi - 0.05 * e, -1.0, 1.0)])
    return np.array([np.clip(-1.0 * state[2], -6, 6), 0.0])


def _scenes(kind: str) -> list:
    """(world, true states per sub-step, the ego's route lane per sub-step, observation at t0, t0) per scene."""
    scenes = []
    for seed in range(BENCH_SEED0, BENCH_SEED0 + SEEDS):
        world = make_road_world(kind, seed)
        states, observations, lanes = [], [], []
        for _ in range(max(STARTS) + STEPS + 1):
            observations.append(world.measure())
            states.append(world.traffic.states.copy())
            lanes.append(int(world.traffic.lane[0]))
            if world.done:
                break
            world.apply(_ego_control(kind, world.traffic.states[0]))
        for t0 in STARTS:
            if t0 + STEPS < len(states):
                scenes.append((world, states[t0 : t0 + STEPS + 1], lanes[t0 : t0 + STEPS + 1], observations[t0]))
    return scenes


#: (name, lateral_contraction, lateral_invariant), the reference first.
SETTINGS = (("interval", False, False), ("radius", True, False), ("radius+sets", True, True))


def _forecast(scene, contraction: bool, invariant: bool):
    world, states, lanes, obs = scene
    vehicle = world.scenario.vehicle
    ego = [s[0] for s in states]
    reach = np.array([footprint_box(s[:2], s[:2], s[3], s[3], vehicle) for s in ego])
    beliefs = {int(i): prior_belief(int(i), obs.vehicles[k], world.road, world.scenario) for k, i in enumerate(obs.ids)}
    route = np.zeros((STEPS + 1, len(world.road)), dtype=bool)
    route[np.arange(STEPS + 1), lanes] = True
    return forecast_traffic(
        obs,
        world.road,
        world.scenario,
        beliefs,
        steps=STEPS,
        ego_reach=reach,
        ego_speed=np.array([[s[2], s[2]] for s in ego]),
        ego_heading=np.array([[s[3], s[3]] for s in ego]),
        ego_route=route,
        lateral_contraction=contraction,
        lateral_invariant=invariant,
    )


def _misses(scene, forecast) -> int:
    world, states, _, obs = scene
    missed = 0
    for n, state in enumerate(states):
        true = state[obs.ids]
        inside = np.all((true >= forecast.state_lower[n] - TOL) & (true <= forecast.state_upper[n] + TOL), axis=1)
        corners = vehicle_corners(true, world.scenario.vehicle)
        box = forecast.boxes[n]
        covered = np.all((corners >= box[:, None, :2] - TOL) & (corners <= box[:, None, 2:] + TOL), axis=(1, 2))
        missed += int(np.sum(~(inside & covered)))
    return missed


def _timed(scene, contraction: bool, invariant: bool) -> tuple[float, object]:
    times, forecast = [], None
    for _ in range(REPEATS):
        start = time.process_time()
        forecast = _forecast(scene, contraction, invariant)
        times.append(time.process_time() - start)
    return float(np.median(times)), forecast


def main() -> dict:
    for kind in ("highway", "tjunction"):  # warm-up: the metric and invariant-set tables, numpy's first calls
        _forecast(_scenes(kind)[0], True, True)
    worlds = {}
    for kind in ("highway", "tjunction"):
        scenes = _scenes(kind)
        rows = {name: {"ms": [], "guaranteed": 0, "missed": 0} for name, _, _ in SETTINGS}
        total = 0
        for scene in scenes:
            for name, contraction, invariant in SETTINGS:
                seconds, forecast = _timed(scene, contraction, invariant)
                row = rows[name]
                row["ms"].append(1e3 * seconds)
                row["guaranteed"] += int(np.sum(forecast.guaranteed))
                row["missed"] += _misses(scene, forecast)
            total += forecast.guaranteed.size
        reference = np.array(rows[SETTINGS[0][0]]["ms"])
        worlds[kind] = {"scenes": len(scenes), "vehicle_steps": total, "settings": {}}
        for name, _, _ in SETTINGS:
            ratios = np.array(rows[name]["ms"]) / reference
            worlds[kind]["settings"][name] = {
                "median_ms": float(np.median(rows[name]["ms"])),
                "guaranteed": rows[name]["guaranteed"],
                "missed": rows[name]["missed"],
                "time_ratio_median": float(np.median(ratios)),
                "time_ratio_range": [float(ratios.min()), float(ratios.max())],
            }
    result = {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": f"{platform.machine()}, {platform.python_implementation()} {platform.python_version()}",
        "load_average": list(os.getloadavg()),
        "setup": {"seeds": SEEDS, "starts": list(STARTS), "steps": STEPS, "repeats": REPEATS},
        "settings": [{"name": n, "lateral_contraction": c, "lateral_invariant": i} for n, c, i in SETTINGS],
        "worlds": worlds,
    }
    lines = [
        "# Traffic forecast: the interval boxes alone, with the contraction radius, with the radius and the invariant sets",
        "",
        f"{result['date']}, {result['machine']}, load average {result['load_average'][0]:.1f}, CPU times "
        f"(benchmarks/bench_forecast.py). {SEEDS} episodes per world from seed {BENCH_SEED0}, forecasts of "
        f"{STEPS} sub-steps (dt 0.1 s) from sub-steps {', '.join(map(str, STARTS))}, prior beliefs, the ego's "
        "exact footprint as its reach; each forecast timed "
        f"{REPEATS} times, the median kept. Time ratio: the setting's time over the interval boxes' per scene, "
        "median (range) over the scenes.",
        "",
        "| world | setting | scenes | forecast ms, median | time ratio, median (range) | guaranteed vehicle-steps "
        "| of | missed |",
        "|---|---|---:|---:|---|---:|---:|---:|",
    ]
    for kind, w in worlds.items():
        for name, row in w["settings"].items():
            lo, hi = row["time_ratio_range"]
            lines.append(
                f"| {kind} | {name} | {w['scenes']} | {row['median_ms']:.0f} | {row['time_ratio_median']:.2f} "
                f"({lo:.2f}-{hi:.2f}) | {row['guaranteed']:,} | {w['vehicle_steps']:,} | {row['missed']} |"
            )
    lines.append("")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "forecast.md").write_text("\n".join(lines))
    (RESULTS / "forecast.json").write_text(json.dumps(result, indent=2) + "\n")
    print("\n".join(lines))
    return result


if __name__ == "__main__":
    main()
