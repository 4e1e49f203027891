"""Decision latency of the driving planner: the ego model (`BicycleModel`) with 8 vehicles in view.

The highway ego (the paper's five actions, target speeds {20, 25, 30} m/s, 5 sub-steps of
0.1 s per decision) plans with `RobustTreePlanner` at the paper's K = 100 and gamma = 0.9
against a synthetic traffic forecast: 8 other vehicles within 60 m, each an obstacle box
per sub-step for H = 50 sub-steps (5 s) that grows linearly with time (0.5 m + 0.6 m/s
longitudinally, 0.2 m + 0.2 m/s laterally: the shape of a forecast's boxes, not its
numbers). The reward is `DrivingReward.highway` (exact box minimum, road test).

Engines, on the same roots, checked to return the same `Decision`:

- python: `RobustTreePlanner` (its Python engine; the ego model is a `VectorisedModel`
  whose ``expand`` steps all five actions over the five sub-steps in one compiled call);
- compiled: `compiled_plan`, the same tree operations and transitions in one compiled call.

Median and 90th percentile over 40 roots (seeded layouts, each planned 3 times, the
median kept), after one warm-up plan (compilation, reported separately). Goal: at most
20 ms median. Writes benchmarks/results/driving.md and .json.
"""

from __future__ import annotations

import datetime
import json
import pathlib
import platform
import time

import numpy as np

from minimaxplan.planners import RobustTreePlanner
from minimaxplan.planners.bicycle_model import (
    HIGHWAY_ACTIONS,
    HIGHWAY_TARGET_SPEEDS,
    BicycleModel,
    compiled_plan,
    ego_controller,
)
from minimaxplan.scenarios.driving_reward import DrivingReward
from minimaxplan.scenarios.road import highway_road, lane_geometry

RESULTS = pathlib.Path(__file__).parent / "results"
BENCH_SEED0 = 20_000
ROOTS = 40
REPEATS = 3
VEHICLES = 8
HORIZON = 50
BUDGET = 100
GAMMA = 0.9
DT = 0.1
GOAL_MS = 20.0


def synthetic_forecast(rng: np.random.Generator, ego: np.ndarray) -> np.ndarray:
    """Boxes (H+1, 8, 4) of 8 vehicles around the ego, none meeting it at the start."""
    n = np.arange(HORIZON + 1)[:, None] * DT
    while True:
        lanes = rng.integers(0, 3, VEHICLES)
        x0 = ego[0] + rng.uniform(-60.0, 60.0, VEHICLES)
        speed = rng.uniform(20.0, 25.0, VEHICLES)
        if np.all((np.abs(x0 - ego[0]) > 12.0) | (lanes * 4.0 != ego[1])):
            break
    cx = x0[None, :] + speed[None, :] * n
    cy = np.broadcast_to(lanes * 4.0, cx.shape)
    grow_x, grow_y = 0.5 + 0.6 * n, 0.2 + 0.2 * n
    return np.stack([cx - 2.5 - grow_x, cy - 1.0 - grow_y, cx + 2.5 + grow_x, cy + 1.0 + grow_y], axis=-1)


def _timed(function, *args, repeats: int = REPEATS, **kwargs) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        out = function(*args, **kwargs)
        times.append(time.perf_counter() - start)
    return float(np.median(times)), out


def main() -> dict:
    road = highway_road()
    controller = ego_controller(lane_geometry(road), HIGHWAY_TARGET_SPEEDS)
    rng = np.random.default_rng(BENCH_SEED0)
    roots = []
    for _ in range(ROOTS):
        lane = int(rng.integers(0, 3))
        ego = np.array([200.0, 4.0 * lane, float(rng.uniform(20.0, 30.0)), 0.0])
        reward = DrivingReward.highway(synthetic_forecast(rng, ego), 0, road)
        model = BicycleModel(controller, reward, HIGHWAY_ACTIONS)
        roots.append((model, model.initial_state(ego, level=1, lane=lane)))

    model, state = roots[0]
    start = time.perf_counter()
    RobustTreePlanner([model], model.actions, gamma=GAMMA, budget=BUDGET).plan(state)
    warm_python = time.perf_counter() - start
    start = time.perf_counter()
    compiled_plan(model, state, gamma=GAMMA, budget=BUDGET)
    warm_compiled = time.perf_counter() - start

    python_ms, compiled_ms, depths, lowers = [], [], [], []
    for model, state in roots:
        planner = RobustTreePlanner([model], model.actions, gamma=GAMMA, budget=BUDGET)
        seconds, expected = _timed(planner.plan, state)
        python_ms.append(1e3 * seconds)
        seconds, (decision, _) = _timed(compiled_plan, model, state, gamma=GAMMA, budget=BUDGET)
        compiled_ms.append(1e3 * seconds)
        assert decision == expected, "the engines disagree"
        depths.append(decision.depth)
        lowers.append(decision.lower)

    def summary(values):
        return {"median_ms": float(np.median(values)), "p90_ms": float(np.percentile(values, 90))}

    result = {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": f"{platform.machine()}, {platform.python_implementation()} {platform.python_version()}",
        "setup": {
            "budget": BUDGET,
            "gamma": GAMMA,
            "vehicles": VEHICLES,
            "horizon_substeps": HORIZON,
            "substeps": 5,
            "actions": len(HIGHWAY_ACTIONS),
            "roots": ROOTS,
        },
        "python": summary(python_ms),
        "compiled": summary(compiled_ms),
        "first_plan_s": {"python": warm_python, "compiled": warm_compiled},
        "median_depth": float(np.median(depths)),
        "median_lower": float(np.median(lowers)),
    }
    verdict = {name: "met" if result[name]["median_ms"] <= GOAL_MS else "NOT met" for name in ("python", "compiled")}
    lines = [
        "# Driving planner: decision latency",
        "",
        f"{result['date']}, {result['machine']} (benchmarks/bench_driving.py). Highway ego, "
        f"{len(HIGHWAY_ACTIONS)} actions x 5 sub-steps, K = {BUDGET}, gamma = {GAMMA}, {VEHICLES} vehicles in view "
        f"as obstacle boxes over H = {HORIZON} sub-steps (synthetic forecast), {ROOTS} roots, the same Decision "
        "from both engines at every root.",
        "",
        "| engine | median ms | p90 ms | first plan s (compiles) | goal <= 20 ms |",
        "|---|---:|---:|---:|---|",
    ]
    for name, label in (
        ("python", "RobustTreePlanner (Python engine, compiled expand)"),
        ("compiled", "compiled_plan"),
    ):
        lines.append(
            f"| {label} | {result[name]['median_ms']:.2f} | {result[name]['p90_ms']:.2f} | "
            f"{result['first_plan_s'][name]:.1f} | {verdict[name]} |"
        )
    lines += [
        "",
        f"Median tree depth {result['median_depth']:.0f}, median root lower bound {result['median_lower']:.3f}.",
        "",
    ]
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "driving.md").write_text("\n".join(lines))
    (RESULTS / "driving.json").write_text(json.dumps(result, indent=2) + "\n")
    print("\n".join(lines))
    return result


if __name__ == "__main__":
    main()
