"""Decision latency of the driving planner, and what building its models costs per decision.

Planner latency: the highway ego (the paper's five actions, target speeds {20, 25, 30}
m/s, 5 sub-steps of 0.1 s per decision) plans with `RobustTreePlanner` at the paper's
K = 100 and gamma = 0.9 against a synthetic traffic forecast: 8 other vehicles within
60 m, each an obstacle box per sub-step for H = 50 sub-steps (5 s) that grows linearly
with time (0.5 m + 0.6 m/s longitudinally, 0.2 m + 0.2 m/s laterally: the shape of a
forecast's boxes, not its numbers). The reward is `DrivingReward.highway` (exact box
minimum, road test). Measured in the same run, on the same roots:

- planner: `RobustTreePlanner` over `BicycleModel` as the road methods use it (the
  Python engine; ``expand`` steps all five actions over the five sub-steps in one
  compiled call; the continuation bounds of `BicycleModel.fallback_values` raise the
  leaves' lower bounds);
- paper's bound: the same planner without the continuation bounds (the paper's
  ``min_m R_m``), the reference for what they cost;
- re-predicting reference: the way the public reference agents plan (an environment
  copy with interval-predicting vehicles in every tree node): at every expansion, every
  vehicle is forecast again (`forecast_traffic`) from a real highway scene's
  measurement, conditioned on the ego's own path to the node, and the children are
  scored on that forecast; same budget, on `REFERENCE_ROOTS` roots (it is slow).

Model building: the robust road method's per-decision cost of the traffic learner (LP
elimination, `TrafficLearner`), the forecast (`forecast_traffic`) and its intersection with
the previous decision's (`intersect_forecasts`) next to the planning itself and the
latest-collision rule (`latest_collision_action`), timed inside real episodes of both
worlds (`MODEL_SEEDS`).

Median and 90th percentile over the roots (each planned 3 times, the median kept),
after one warm-up plan (compilation, reported separately). Every figure is CPU time of
this process (`time.process_time`): the machine is shared, and the wall time would count
the other processes' turns. Goal: at most 20 ms median
for the planner. Writes benchmarks/results/driving.md and .json.
"""

from __future__ import annotations

import datetime
import json
import os
import pathlib
import platform
import time

import numpy as np

from minimaxplan.planners import RobustTreePlanner
from minimaxplan.planners.bicycle_model import (
    HIGHWAY_ACTIONS,
    HIGHWAY_TARGET_SPEEDS,
    BicycleModel,
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
REFERENCE_ROOTS = 3
MODEL_SEEDS = (0, 1)


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
        start = time.process_time()
        out = function(*args, **kwargs)
        times.append(time.process_time() - start)
    return float(np.median(times)), out


class _PaperBound:
    """The ego model without `fallback_values`: the paper's leaf lower bound (the reference of their cost)."""

    def __init__(self, model: BicycleModel) -> None:
        self._model = model

    def expand(self, state, actions):
        return self._model.expand(state, actions)

    def step(self, state, action):
        return self._model.step(state, action)


class _RepredictingModel:
    """Every vehicle forecast again at every expansion, conditioned on the ego's path to the node.

    A node's state is ``(BicycleState, path)``, ``path`` the ego's exact points from the
    root (the reference agents' environment copy holds the same: the ego's state and
    every vehicle's interval). `expand` forecasts the scene from the root measurement
    with the ego's reach equal to its exact path up to the node and, beyond it, the
    largest-speed growth of `ego_reach`, then scores the children on that forecast.
    """

    def __init__(self, model: BicycleModel, scene, time: int) -> None:
        self.model = model
        self.scene = scene
        self.time = time

    def expand(self, state, actions):
        from minimaxplan.analysis.road_planning import FORECAST_STEPS
        from minimaxplan.scenarios.traffic_models import forecast_traffic

        ego, path = state
        observation, road, scenario, beliefs, reach = self.scene
        conditioned = reach.copy()
        for n, point in enumerate(path[: len(conditioned) - 1]):
            half = 0.5 * np.hypot(scenario.vehicle.length, scenario.vehicle.width)
            conditioned[n + 1] = [point[0] - half, point[1] - half, point[0] + half, point[1] + half]
        forecast = forecast_traffic(observation, road, scenario, beliefs, steps=FORECAST_STEPS, ego_reach=conditioned)
        reward = self.model.reward.with_obstacles(forecast.boxes, self.time)
        model = self.model.with_reward(reward)
        children, rewards, terminals = model.expand(ego, actions)
        out = []
        for a, child in zip(actions, children):
            states, _, _ = model.predict(ego, a)
            out.append((child, path + [row for row in states]))
        return out, rewards, terminals

    def step(self, state, action):
        children, rewards, terminals = self.expand(state, (action,))
        return children[0], float(rewards[0]), bool(terminals[0])


def _highway_scene():
    """A real highway measurement with prior beliefs, the ego and its reach (the re-predicting reference's input)."""
    from minimaxplan.analysis.road_planning import FORECAST_STEPS, EgoSetup, ego_reach
    from minimaxplan.scenarios.road_world import make_road_world

    world = make_road_world("highway", BENCH_SEED0)
    ego = EgoSetup(world)
    model = BicycleModel(ego.controller, ego.reward, ego.actions)
    observation = world.measure()
    root = model.initial_state(observation.ego, level=ego.level, lane=ego.lane, time=world.step_index)
    speeds = np.asarray(ego.speeds)
    v = float(observation.ego[2])
    bounds = (min(v, float(speeds.min())), max(v, float(speeds.max())))
    reach, _, _ = ego_reach(model, root, bounds, FORECAST_STEPS, world.scenario.dt, world.scenario.vehicle)
    return model, root, (observation, world.road, world.scenario, {}, reach)


def _plan_on_scene(model: BicycleModel, root, scene):
    """What the road methods do per decision on the reference's scene: one forecast, then the search."""
    from minimaxplan.analysis.road_planning import FORECAST_STEPS
    from minimaxplan.scenarios.traffic_models import forecast_traffic

    observation, road, scenario, beliefs, reach = scene
    forecast = forecast_traffic(observation, road, scenario, beliefs, steps=FORECAST_STEPS, ego_reach=reach)
    planned = model.with_reward(model.reward.with_obstacles(forecast.boxes, root.time))
    return RobustTreePlanner([planned], planned.actions, gamma=GAMMA, budget=BUDGET).plan(root)


def _model_building() -> dict:
    """Per-decision seconds of the learner, the forecast and the planning inside robust road episodes."""
    import minimaxplan.analysis.road_planning as road_planning
    from minimaxplan.analysis.episode import run_episode
    from minimaxplan.analysis.traffic_learning import TrafficLearner

    timings: dict = {}
    originals = (
        road_planning.forecast_traffic,
        TrafficLearner.observe,
        TrafficLearner.beliefs,
        RobustTreePlanner.plan,
        road_planning.ego_reach,
        road_planning.lane_keeping_reach,
        road_planning.latest_collision_action,
        road_planning.intersect_forecasts,
    )

    def timed(key, function):
        def wrapper(*args, **kwargs):
            start = time.process_time()
            try:
                return function(*args, **kwargs)
            finally:
                timings[key] = timings.get(key, 0.0) + time.process_time() - start

        return wrapper

    result = {}
    try:
        road_planning.forecast_traffic = timed("forecast", originals[0])
        TrafficLearner.observe = timed("learner", originals[1])
        TrafficLearner.beliefs = timed("learner", originals[2])
        RobustTreePlanner.plan = timed("planning", originals[3])
        road_planning.ego_reach = timed("reach", originals[4])
        road_planning.lane_keeping_reach = timed("reach", originals[5])
        road_planning.latest_collision_action = timed("latest_collision", originals[6])
        road_planning.intersect_forecasts = timed("intersection", originals[7])
        for world in ("highway", "tjunction"):
            per = {key: [] for key in ("forecast", "intersection", "learner", "planning", "reach", "latest_collision")}
            for seed in MODEL_SEEDS:
                timings.clear()
                record = run_episode(world, "robust", seed)
                for key in per:
                    per[key].append(timings.get(key, 0.0) / record.decisions)
            result[world] = {key: 1e3 * float(np.mean(values)) for key, values in per.items()}
    finally:
        road_planning.forecast_traffic = originals[0]
        TrafficLearner.observe, TrafficLearner.beliefs, RobustTreePlanner.plan = originals[1:4]
        road_planning.ego_reach, road_planning.lane_keeping_reach = originals[4:6]
        road_planning.latest_collision_action, road_planning.intersect_forecasts = originals[6:]
    return result


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
    start = time.process_time()
    RobustTreePlanner([model], model.actions, gamma=GAMMA, budget=BUDGET).plan(state)
    warm = time.process_time() - start

    planner_ms, paper_ms, depths, lowers, paper_lowers = [], [], [], [], []
    for model, state in roots:
        planner = RobustTreePlanner([model], model.actions, gamma=GAMMA, budget=BUDGET)
        seconds, decision = _timed(planner.plan, state)
        planner_ms.append(1e3 * seconds)
        paper = RobustTreePlanner([_PaperBound(model)], model.actions, gamma=GAMMA, budget=BUDGET)
        seconds, reference = _timed(paper.plan, state)
        paper_ms.append(1e3 * seconds)
        assert decision.lower >= reference.lower and decision.upper == reference.upper
        depths.append(decision.depth)
        lowers.append(decision.lower)
        paper_lowers.append(reference.lower)

    scene_model, scene_root, scene = _highway_scene()
    repredicting_ms = []
    for _ in range(REFERENCE_ROOTS):
        reference = RobustTreePlanner(
            [_RepredictingModel(scene_model, scene, scene_root.time)], scene_model.actions, gamma=GAMMA, budget=BUDGET
        )
        seconds, _ = _timed(reference.plan, (scene_root, []), repeats=1)
        repredicting_ms.append(1e3 * seconds)
    scene_seconds, _ = _timed(_plan_on_scene, scene_model, scene_root, scene)
    building = _model_building()

    def summary(values):
        return {"median_ms": float(np.median(values)), "p90_ms": float(np.percentile(values, 90))}

    result = {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": f"{platform.machine()}, {platform.python_implementation()} {platform.python_version()}",
        "load_average": list(os.getloadavg()),
        "setup": {
            "budget": BUDGET,
            "gamma": GAMMA,
            "vehicles": VEHICLES,
            "horizon_substeps": HORIZON,
            "substeps": 5,
            "actions": len(HIGHWAY_ACTIONS),
            "roots": ROOTS,
            "reference_roots": REFERENCE_ROOTS,
        },
        "planner": summary(planner_ms),
        "paper_bound": summary(paper_ms),
        "repredicting_reference": summary(repredicting_ms),
        "planner_on_the_reference_scene_ms": 1e3 * scene_seconds,
        "first_plan_s": warm,
        "median_depth": float(np.median(depths)),
        "median_lower": float(np.median(lowers)),
        "median_lower_paper_bound": float(np.median(paper_lowers)),
        "model_building_ms_per_decision": building,
    }
    met = "met" if result["planner"]["median_ms"] <= GOAL_MS else "NOT met"
    speedup = result["repredicting_reference"]["median_ms"] / result["planner_on_the_reference_scene_ms"]
    lines = [
        "# Driving planner: decision latency and model-building cost",
        "",
        f"{result['date']}, {result['machine']}, load average {result['load_average'][0]:.1f}, CPU times "
        f"(benchmarks/bench_driving.py). Highway ego, {len(HIGHWAY_ACTIONS)} actions x 5 sub-steps, "
        f"K = {BUDGET}, gamma = {GAMMA}, {VEHICLES} vehicles in view as obstacle boxes over H = {HORIZON} "
        f"sub-steps (synthetic forecast), {ROOTS} roots.",
        "",
        "| planner | median ms | p90 ms | goal <= 20 ms |",
        "|---|---:|---:|---|",
        f"| RobustTreePlanner with continuation bounds (as the road methods run it) | "
        f"{result['planner']['median_ms']:.2f} | {result['planner']['p90_ms']:.2f} | {met} |",
        f"| the same, paper's lower bound (reference) | {result['paper_bound']['median_ms']:.2f} | "
        f"{result['paper_bound']['p90_ms']:.2f} | |",
        "",
        f"First plan (compiles the kernels): {warm:.1f} s. Median tree depth {result['median_depth']:.0f}; median "
        f"root lower bound {result['median_lower']:.3f} with the continuation bounds, "
        f"{result['median_lower_paper_bound']:.3f} with the paper's (the upper bounds are equal at every root).",
        "",
        f"Re-predicting reference (every vehicle forecast again at every expansion, a real highway scene, "
        f"{REFERENCE_ROOTS} plans): median {result['repredicting_reference']['median_ms']:.0f} ms per decision, "
        f"against {result['planner_on_the_reference_scene_ms']:.1f} ms for one forecast and the search on the "
        f"same scene (what the road methods do per decision): {speedup:.0f}x.",
        "",
        f"Model building per decision inside robust episodes (seeds {', '.join(map(str, MODEL_SEEDS))}), ms:",
        "",
        "| world | learner (LP elimination) | ego reach | forecast (highway: two, any ego and lane keeping) "
        "| forecasts intersected with the previous decision's | planning | latest-collision rule (T-junction only) |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for world, row in building.items():
        lines.append(
            f"| {world} | {row['learner']:.1f} | {row['reach']:.1f} | {row['forecast']:.1f} "
            f"| {row['intersection']:.2f} | {row['planning']:.1f} | {row['latest_collision']:.1f} |"
        )
    lines.append("")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "driving.md").write_text("\n".join(lines))
    (RESULTS / "driving.json").write_text(json.dumps(result, indent=2) + "\n")
    print("\n".join(lines))
    return result


if __name__ == "__main__":
    main()
