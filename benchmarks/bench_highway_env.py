"""Containment and cost on highway-env's own scenes: the library's traffic models against
highway-env's ``IntervalVehicle`` (the reference of the paper's eq. (9)), side by side.

For every scene (an environment, a simulation frequency, a seed, a forecast time t0):
highway-env runs with ``LinearVehicle`` other vehicles (the ego IDLE on the highway,
SLOWER at the intersection, one simulation step per ``env.step``), and the true states
are recorded. From the state at t0, over 5 s:

* the library: `HighwayEnvAdapter.forecast` (prior beliefs from the reference priors,
  the true ego's rectangle as its reach, highway-env's step as the forecast's dt);
* highway-env: a deep copy of the environment at t0 whose other vehicles are
  ``IntervalVehicle.create_from(v)`` (the reference agents' construction: the copy
  inherits each vehicle's true target lane, target speed, route and timer, and the
  prior parameter boxes), stepped with ``IntervalVehicle.step(dt, mode)`` in its
  default ``partial`` mode and in its ``predictor`` mode; its box is
  ``vehicle.interval.position``.

Reported per predictor, environment, frequency and horizon h in {1, 3, 5} s: the
fraction of vehicle-steps at t0 + h whose true centre is outside the predicted
centre box, over all vehicles present at both times ("all") and over those the library's
model covers ("covered": no lane change, crash or reversing, speed below 0, since t0, from
highway-env's ground truth; the switch to the next route lane is covered, the forecast's
``route_switch_distance``), the mean x and y widths of the box (m), and the
predictor's wall time per vehicle-step (the library: one forecast call; highway-env:
stepping the copy, which also simulates its nominal vehicles, as the reference agents
do).

Writes benchmarks/results/highway_env.md and .json. Needs the ``vehicle`` extra.
Usage: ``python benchmarks/bench_highway_env.py [--seeds N]`` (default 4).
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import datetime
import functools
import io
import json
import os
import pathlib
import platform
import time
import warnings

import numpy as np

from minimaxplan.scenarios.highway_env_adapter import HighwayEnvAdapter, uncovered_reason
from minimaxplan.scenarios.lateral_contraction import contraction_metrics
from minimaxplan.scenarios.lateral_invariant import invariant_sets
from minimaxplan.scenarios.vehicles import vehicle_corners

RESULTS = pathlib.Path(__file__).parent / "results"
HORIZONS = (1.0, 3.0, 5.0)
ENVS = {"highway-fast-v0": "IDLE", "intersection-v0": "SLOWER"}
FREQUENCIES = (5, 15)
#: Forecast times, s after the reset.
STARTS = (0.0, 2.0)
PREDICTORS = ("library", "IntervalVehicle partial", "IntervalVehicle predictor")


def _reference(adapter, mode: str, steps: int, action: str):
    """Interval boxes of highway-env's IntervalVehicle from the current state: id -> (steps + 1, 2, 2)."""
    from highway_env.vehicle.uncertainty.prediction import IntervalVehicle

    base = adapter.env.unwrapped
    ids = {id(v): adapter.agent_id(v) for v in base.road.vehicles if v is not base.vehicle}
    twin = copy.deepcopy(base)
    quiet = contextlib.redirect_stdout(io.StringIO())  # highway-env's LPV prints "Non Metzler A0 ..."
    # deepcopy keeps the vehicles' order: pair them with the original ids
    originals = [v for v in base.road.vehicles]
    replaced = []
    for original, v in zip(originals, twin.road.vehicles):
        if original is base.vehicle:
            replaced.append(v)
            continue
        iv = IntervalVehicle.create_from(v)
        iv.step = functools.partial(IntervalVehicle.step, iv, mode=mode)
        iv._agent = ids[id(original)]
        replaced.append(iv)
    twin.road.vehicles = replaced
    ego = next(v for v in replaced if not isinstance(v, IntervalVehicle))
    dt = adapter.dt
    boxes = {iv._agent: [iv.interval.position.copy()] for iv in replaced if isinstance(iv, IntervalVehicle)}
    started = time.perf_counter()
    for k in range(steps):
        if k == 0:
            ego.act(action)
        with quiet:
            twin.road.act()
            twin.road.step(dt)
        for iv in replaced:
            if isinstance(iv, IntervalVehicle) and iv in twin.road.vehicles:
                boxes[iv._agent].append(iv.interval.position.copy())
    elapsed = time.perf_counter() - started
    return boxes, elapsed


def scene(env_id: str, hz: int, seed: int, start: float) -> dict:
    """Every predictor's boxes against the truth on one scene; counts per horizon."""
    action = ENVS[env_id]
    adapter = HighwayEnvAdapter(env_id, config={"simulation_frequency": hz, "policy_frequency": hz})
    steps = adapter.steps(max(HORIZONS))
    t0 = adapter.steps(start)
    observation = adapter.reset(seed)
    for k in range(t0):
        observation, terminated, truncated = adapter.step(action if k == 0 else "IDLE")
        if terminated or truncated:
            return {}
    # the reference's copies of the environment at t0
    first_action = action if t0 == 0 else "IDLE"
    references = {mode: _reference(adapter, mode, steps, first_action) for mode in ("partial", "predictor")}
    truth = [adapter.ground_truth()]
    observations = [observation]
    for k in range(steps):
        observation, terminated, truncated = adapter.step(first_action if k == 0 else "IDLE")
        observations.append(observation)
        truth.append(adapter.ground_truth())
        if terminated or truncated:
            return {}
    t0 = 0  # indices into this scene's records
    ego = np.array([o.ego for o in observations[t0 : t0 + steps + 1]])
    corners = vehicle_corners(ego, adapter.scenario.vehicle)
    reach = np.concatenate([corners.min(axis=1) - 1e-9, corners.max(axis=1) + 1e-9], axis=1)
    speed = np.stack([ego[:, 2] - 1e-9, ego[:, 2] + 1e-9], axis=1)
    heading = np.stack([ego[:, 3] - 1e-9, ego[:, 3] + 1e-9], axis=1)
    # the forecast's tables per sub-step (contraction metrics, invariant sets) are built once per process and
    # cached: built here, before the clock starts, so that no scene's time holds them
    sc = adapter.scenario
    contraction_metrics(float(sc.dt), sc.vehicle, sc.behaviour)
    invariant_sets(float(sc.dt), sc.vehicle, sc.behaviour)
    started = time.perf_counter()
    forecast = adapter.forecast(
        observations[t0], steps * adapter.dt, ego_reach=reach, ego_speed=speed, ego_heading=heading
    )
    library_time = time.perf_counter() - started
    m = len(forecast.ids)
    out: dict = {"vehicle_steps": m * steps, "time": {"library": library_time}}
    for mode in ("partial", "predictor"):
        out["time"][f"IntervalVehicle {mode}"] = references[mode][1]
    rows = {
        p: {h: {"all": [0, 0], "covered": [0, 0], "wx": [], "wy": [], "inv": []} for h in HORIZONS} for p in PREDICTORS
    }
    for j, agent in enumerate(forecast.ids):
        agent = int(agent)
        first = truth[t0][agent]
        covered = True
        for n in range(1, steps + 1):
            now = truth[t0 + n].get(agent)
            if now is None:
                break
            covered = covered and uncovered_reason(first, now) is None
            h = n * adapter.dt
            match = [hh for hh in HORIZONS if abs(hh - h) < 1e-9]
            if not match:
                continue
            p = now["state"][:2]
            boxes = {"library": (forecast.state_lower[n, j, :2], forecast.state_upper[n, j, :2])}
            inverted = {"partial": False, "predictor": False}
            for mode in ("partial", "predictor"):
                trace = references[mode][0].get(agent, [])
                if n < len(trace):
                    # read charitably: an inverted interval (lower > upper) as the hull of its corners
                    lo_r, hi_r = trace[n][0], trace[n][1]
                    inverted[mode] = bool(np.any(lo_r > hi_r))
                    boxes[f"IntervalVehicle {mode}"] = (np.minimum(lo_r, hi_r), np.maximum(lo_r, hi_r))
            if len(boxes) < len(PREDICTORS):
                continue  # the reference's copy removed the vehicle: compare on common vehicle-steps only
            for name, (lo, hi) in boxes.items():
                cell = rows[name][match[0]]
                outside = bool(np.any(p < lo) or np.any(p > hi))
                cell["all"][0] += outside
                cell["all"][1] += 1
                if covered:
                    cell["covered"][0] += outside
                    cell["covered"][1] += 1
                cell["wx"].append(float(hi[0] - lo[0]))
                cell["wy"].append(float(hi[1] - lo[1]))
                cell["inv"].append(inverted.get(name.removeprefix("IntervalVehicle "), False))
    out["rows"] = rows
    adapter.close()
    return out


def main(seeds: int = 4) -> dict:
    """Run every scene; write the tables."""
    results: dict = {
        "machine": f"{platform.machine()} {platform.python_implementation()} {platform.python_version()}",
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "seeds": list(range(seeds)),
        "starts_s": list(STARTS),
        "load_before": [round(x, 2) for x in os.getloadavg()],
        "tables": {},
    }
    began = time.perf_counter()
    for env_id in ENVS:
        for hz in FREQUENCIES:
            total = {
                p: {h: {"all": [0, 0], "covered": [0, 0], "wx": [], "wy": [], "inv": []} for h in HORIZONS}
                for p in PREDICTORS
            }
            time_total = {p: 0.0 for p in PREDICTORS}
            vehicle_steps = 0
            scenes = 0
            for seed in range(seeds):
                for start in STARTS:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        got = scene(env_id, hz, seed, start)
                    if not got:
                        continue
                    scenes += 1
                    vehicle_steps += got["vehicle_steps"]
                    for p in PREDICTORS:
                        time_total[p] += got["time"][p]
                        for h in HORIZONS:
                            for key in ("all", "covered"):
                                total[p][h][key][0] += got["rows"][p][h][key][0]
                                total[p][h][key][1] += got["rows"][p][h][key][1]
                            total[p][h]["wx"] += got["rows"][p][h]["wx"]
                            total[p][h]["wy"] += got["rows"][p][h]["wy"]
                            total[p][h]["inv"] += got["rows"][p][h]["inv"]
            table = {
                "scenes": scenes,
                "vehicle_steps": vehicle_steps,
                "time_per_vehicle_step_ms": {p: 1e3 * time_total[p] / max(vehicle_steps, 1) for p in PREDICTORS},
                "horizons": {},
            }
            for p in PREDICTORS:
                for h in HORIZONS:
                    cell = total[p][h]
                    table["horizons"].setdefault(str(h), {})[p] = {
                        "outside_all": cell["all"][0] / max(cell["all"][1], 1),
                        "n_all": cell["all"][1],
                        "outside_covered": cell["covered"][0] / max(cell["covered"][1], 1),
                        "n_covered": cell["covered"][1],
                        "mean_width_x": float(np.mean(cell["wx"])) if cell["wx"] else float("nan"),
                        "mean_width_y": float(np.mean(cell["wy"])) if cell["wy"] else float("nan"),
                        "median_width_x": float(np.median(cell["wx"])) if cell["wx"] else float("nan"),
                        "median_width_y": float(np.median(cell["wy"])) if cell["wy"] else float("nan"),
                        "inverted": float(np.mean(cell["inv"])) if cell["inv"] else float("nan"),
                    }
            results["tables"][f"{env_id} @ {hz} Hz"] = table
            print(env_id, hz, json.dumps(table["time_per_vehicle_step_ms"]), flush=True)
    results["wall_s"] = round(time.perf_counter() - began, 1)
    results["load_after"] = [round(x, 2) for x in os.getloadavg()]
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "highway_env.json").write_text(json.dumps(results, indent=2) + "\n")
    (RESULTS / "highway_env.md").write_text(markdown(results))
    print(markdown(results))
    return results


def markdown(results: dict) -> str:
    """The tables as Markdown."""
    lines = [
        "# Containment on highway-env's scenes: the library's traffic models vs IntervalVehicle",
        "",
        f"Measured {results['date']} on {results['machine']} (2 cores shared with other jobs; load average "
        f"before {results['load_before']}, after {results['load_after']}; {results['wall_s']} s wall); "
        f"seeds {results['seeds']}, forecasts from t0 = {results['starts_s']} s, LinearVehicle traffic "
        "(`benchmarks/bench_highway_env.py`, see its docstring for the set-up).",
        "",
        "Outside: the fraction of vehicle-steps at t0 + h whose true centre lies outside the predicted "
        "centre box (all vehicles present / those the library's model covers: no lane change, crash or "
        "reversing since t0; the switch to the next route lane is covered). Widths: median (mean) x and y widths of the box, m; a mean far above its "
        "median is a box that diverged. Inverted: the fraction of IntervalVehicle's boxes with lower > upper in "
        "some coordinate (its partial observer produces them); they are read as the hull of their corners.",
        "",
    ]
    for name, table in results["tables"].items():
        lines += [
            f"## {name} ({table['scenes']} scenes, {table['vehicle_steps']} vehicle-steps forecast)",
            "",
            "| predictor | h (s) | outside, all | outside, covered | width x (m) | width y (m) | inverted |",
            "|---|---|---|---|---|---|---|",
        ]
        for h, cells in table["horizons"].items():
            for p, c in cells.items():
                lines.append(
                    f"| {p} | {float(h):g} | {c['outside_all']:.3f} ({c['n_all']}) | "
                    f"{c['outside_covered']:.3f} ({c['n_covered']}) | {c['median_width_x']:.3g} ({c['mean_width_x']:.3g}) | "
                    f"{c['median_width_y']:.3g} ({c['mean_width_y']:.3g}) | {c['inverted']:.3f} |"
                )
        lines += ["", "Predictor time per vehicle-step (ms): "]
        lines[-1] += ", ".join(f"{p} {t:.3f}" for p, t in table["time_per_vehicle_step_ms"].items())
        lines.append("")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=4)
    args = parser.parse_args()
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    main(args.seeds)
