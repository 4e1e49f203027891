"""Decision time on highway-env's scenes: the library's robust planner against a reference
planner built from highway-env's own classes (issue 12, point 3), measured in one run.

Scenes: highway-fast-v0 and intersection-v0 (``LinearVehicle`` traffic), a few seeds, a
decision at t0 seconds after the reset; the ego is driven there by IDLE, and the library's
`TrafficLearner` (highway only, as `HighwayEnvRobustMethod`) is fed every simulation step.
At t0, with CPU time (`time.process_time`):

* library, per budget K: ``forecast`` = the ego's reach over every action sequence
  (`ego_reach`) and the forecast of every vehicle over 5 s (`HighwayEnvRobustMethod.forecast`:
  the learner's beliefs or the priors, `HighwayEnvAdapter.forecast`); ``search`` = the
  `DrivingReward` of that table, `BicycleModel` with it (the library's compiled ego, one
  decision = 1 s = 5 or 15 sub-steps) and `RobustTreePlanner(budget=K, gamma=0.9)`'s plan;
  ``learn`` = the learner's updates over the last decision's simulation steps (highway);
  ``whole`` = learn + forecast + search;
* ``decide``: `HighwayEnvRobustMethod.decide` as the registered ``robust`` method runs it
  on highway-env (an exhaustive search of every pair of meta-actions, then IDLE: it has no
  budget, reported once per scene for reference);
* reference, per K: `highway_env_reference_planner.interval_root` (highway-env's
  ``simplify`` and ``change_vehicles(IntervalVehicle)``) and
  `HighwayEnvReferencePlanner(budget=K, gamma=0.9)` with the same actions in the same
  order, the same `DrivingReward` (its free value, 0 on highway-env's interval collision
  check), the same depth rule (5 decisions).

Ratios: reference / library (whole decision and search alone), per scene, then median
and min/max over scenes. The numba kernels are compiled (or loaded from the cache) by a
warm-up decision on a scene of each environment before any timing.

Writes benchmarks/results/highway_env_planner.md and .json. Needs the ``vehicle`` extra.
Usage: ``python benchmarks/bench_highway_env_planner.py [--seeds N] [--budgets 35,100,200]``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import pathlib
import platform
import sys
import time
import warnings

import numpy as np

from minimaxplan.analysis.episode import LoopConfig
from minimaxplan.analysis.highway_env_scenario import (
    HORIZON,
    HighwayEnvRobustMethod,
    HighwayEnvScenario,
    HighwayEnvWorld,
)
from minimaxplan.analysis.road_planning import ego_reach
from minimaxplan.planners import RobustTreePlanner
from minimaxplan.planners.bicycle_model import (
    HIGHWAY_TARGET_SPEEDS,
    TJUNCTION_TARGET_SPEEDS,
    BicycleModel,
    ego_controller,
)
from minimaxplan.scenarios.driving_reward import DrivingReward
from minimaxplan.scenarios.highway_env_adapter import meta_action
from minimaxplan.scenarios.road import lane_geometry

HERE = pathlib.Path(__file__).parent
RESULTS = HERE / "results"
sys.path.insert(0, str(HERE))
import highway_env_reference_planner as reference  # noqa: E402  (a script beside this one, loaded once)

BUDGETS = (35, 100, 200)
GAMMA = 0.9
#: env id -> decision times t0 (s after the reset; whole decisions, so that the copy's
#: ``env.step`` starts on a decision boundary).
STARTS = {"highway-fast-v0": (2, 5), "intersection-v0": (1, 3)}


class Scene:
    """One decision of one highway-env episode, with the library's ego model and reward built for it.

    Parameters
    ----------
    env_id : str
        highway-fast-v0 or intersection-v0.
    seed : int
        highway-env's seed.
    start : int
        The decision's time, s after the reset.
    """

    def __init__(self, env_id: str, seed: int, start: int) -> None:
        self.env_id, self.seed, self.start = env_id, seed, start
        self.world = world = HighwayEnvWorld(env_id, seed)
        self.method = method = HighwayEnvRobustMethod(HighwayEnvScenario(env_id), LoopConfig(gamma=GAMMA))
        method.start(world)
        idle = np.array([float([a[0] for a in world.actions].index("IDLE"))])
        S = world.substeps
        self.learn_time = 0.0
        self.ended = False
        for k in range(start * S):
            world.apply(idle)
            if world.done:
                self.ended = True
                return
            began = time.process_time()
            method._learn(world.measure())
            if k >= (start - 1) * S:
                self.learn_time += time.process_time() - began
        self.observation = world.measure()
        adapter = world.adapter
        base = adapter.env.unwrapped
        road, scenario = adapter.road, adapter.scenario
        assert road is not None and scenario is not None
        ego = base.vehicle
        vehicle = scenario.vehicle
        if "highway" in env_id:
            speeds, route = HIGHWAY_TARGET_SPEEDS, ()
            self.reward = DrivingReward.highway(
                np.zeros((1, 0, 4)), 0, road, length=vehicle.length, width=vehicle.width
            )
        else:
            speeds = TJUNCTION_TARGET_SPEEDS
            route = tuple(adapter.lane_index[(a, b, 0 if i is None else i)] for a, b, i in ego.route)
            # highway-env's intersection reward is its speed term: the library's family with c2 only
            self.reward = DrivingReward(
                np.zeros((1, 0, 4)),
                0,
                road,
                length=vehicle.length,
                width=vehicle.width,
                speed_weight=0.4,
                max_speed=float(max(speeds)),
            )
        controller = ego_controller(
            lane_geometry(road, route),
            speeds,
            acceleration_bound=scenario.ego_acceleration_bound,
            length=vehicle.length,
            max_speed=vehicle.max_speed,
            max_steering=vehicle.max_steering,
            dt=adapter.dt,
        )
        self.speeds = speeds
        self.model = BicycleModel(controller, self.reward, world.actions, substeps=S)
        lane = adapter.lane_index[tuple(ego.target_lane_index)]
        level = int(np.argmin(np.abs(np.asarray(speeds) - ego.speed)))
        self.root = self.model.initial_state(self.observation.ego, level=level, lane=lane, time=world.step_index)
        self.steps = adapter.steps(HORIZON)
        self.horizon_decisions = self.steps // S
        self.meta_actions = [meta_action(adapter.env, a[0]) for a in world.actions]
        self.vehicles = len(self.observation.ids)

    def library(self, budget: int) -> dict:
        """The library's decision at ``budget``: CPU times of forecast and search, the decision."""
        world, scenario = self.world, self.world.adapter.scenario
        assert scenario is not None
        began = time.process_time()
        v = float(self.observation.ego[2])
        bounds = (min(v, min(self.speeds)), max(v, max(self.speeds)))
        reach, speed, heading = ego_reach(self.model, self.root, bounds, self.steps, world.adapter.dt, scenario.vehicle)
        forecast = self.method.forecast(self.observation, reach, speed, heading)
        forecast_time = time.process_time() - began
        began = time.process_time()
        model = self.model.with_reward(self.reward.with_obstacles(forecast.boxes, world.step_index))
        planner = RobustTreePlanner([model], model.actions, gamma=GAMMA, budget=budget)
        decision = planner.plan(self.root)
        search_time = time.process_time() - began
        # the same search on a table of the same shape with every box empty: nothing may collide,
        # so it makes all K expansions (the forecast's table usually solves the tree early)
        empty = np.full_like(forecast.boxes, np.inf)
        empty[..., 2:] = -np.inf
        began = time.process_time()
        free_model = self.model.with_reward(self.reward.with_obstacles(empty, world.step_index))
        free = RobustTreePlanner([free_model], free_model.actions, gamma=GAMMA, budget=budget).plan(self.root)
        free_time = time.process_time() - began
        return {
            "forecast_s": forecast_time,
            "search_s": search_time,
            "whole_s": self.learn_time + forecast_time + search_time,
            "action": world.actions[decision.action][0],
            "lower": float(decision.lower),
            "upper": float(decision.upper),
            "depth": int(decision.depth),
            "expansions": int(decision.expansions),
            "solved": bool(decision.solved),
            "search_free_s": free_time,
            "free_expansions": int(free.expansions),
        }

    def decide(self) -> float:
        """CPU time of `HighwayEnvRobustMethod.decide` (the registered robust method) at this scene."""
        began = time.process_time()
        self.method.decide(self.observation)
        return time.process_time() - began

    def reference(self, budget: int) -> dict:
        """The reference planner's decision at ``budget``: CPU time (root copy + search), the decision."""
        began = time.process_time()
        root = reference.interval_root(self.world.adapter.env)
        planner = reference.HighwayEnvReferencePlanner(
            self.meta_actions,
            reference.driving_reward_of(self.reward),
            gamma=GAMMA,
            budget=budget,
            horizon_decisions=self.horizon_decisions,
        )
        decision = planner.plan(root)
        elapsed = time.process_time() - began
        return {"time_s": elapsed, **decision.to_dict(), "action": self.world.actions[decision.action][0]}

    def close(self) -> None:
        """Close the environment."""
        self.world.adapter.close()


def _summary(values: list[float]) -> dict:
    return {"median": float(np.median(values)), "min": float(np.min(values)), "max": float(np.max(values))}


def summarise(rows: list[dict], budgets) -> dict:
    """Per environment and budget: medians and ranges over the scenes of the times and ratios."""
    tables: dict = {}
    for env_id in STARTS:
        mine = [r for r in rows if r["env"] == env_id]
        if not mine:
            continue
        table = {"scenes": len(mine), "decide_s": _summary([r["decide_s"] for r in mine]), "budgets": {}}
        for budget in budgets:
            cells = [r["budgets"][str(budget)] for r in mine]
            table["budgets"][str(budget)] = {
                "library_whole_s": _summary([c["library"]["whole_s"] for c in cells]),
                "library_search_s": _summary([c["library"]["search_s"] for c in cells]),
                "library_forecast_s": _summary([c["library"]["forecast_s"] for c in cells]),
                "reference_s": _summary([c["reference"]["time_s"] for c in cells]),
                "ratio_whole": _summary([c["ratio_whole"] for c in cells]),
                "ratio_search": _summary([c["ratio_search"] for c in cells]),
                "library_search_full_s": _summary([c["library"]["search_free_s"] for c in cells]),
                "ratio_search_full": _summary([c["ratio_search_full"] for c in cells]),
                "library_expansions": _summary([c["library"]["expansions"] for c in cells]),
                "library_full_expansions": _summary([c["library"]["free_expansions"] for c in cells]),
                "reference_expansions": _summary([c["reference"]["expansions"] for c in cells]),
                "reference_env_steps": _summary([c["reference"]["env_steps"] for c in cells]),
                "reference_per_expansion_s": _summary(
                    [c["reference"]["time_s"] / max(c["reference"]["expansions"], 1) for c in cells]
                ),
                "library_full_per_expansion_s": _summary(
                    [c["library"]["search_free_s"] / max(c["library"]["free_expansions"], 1) for c in cells]
                ),
                "ratio_per_expansion": _summary(
                    [
                        (c["reference"]["time_s"] / max(c["reference"]["expansions"], 1))
                        / (c["library"]["search_free_s"] / max(c["library"]["free_expansions"], 1))
                        for c in cells
                    ]
                ),
                "same_action": sum(c["library"]["action"] == c["reference"]["action"] for c in cells),
            }
        tables[env_id] = table
    return tables


def main(seeds: int = 2, budgets: tuple[int, ...] = BUDGETS) -> dict:
    """Warm the kernels, time every scene and budget; write the tables."""
    warnings.simplefilter("ignore")
    load_before = os.getloadavg()
    started = time.perf_counter()
    # warm-up: numba compiles (or loads) the ego model's, the reward's and the forecast's kernels
    warm_compile = {}
    for env_id in STARTS:
        began = time.perf_counter()
        scene = Scene(env_id, 1000, 1)
        if not scene.ended:
            scene.library(5)
            scene.decide()
            scene.reference(1)
        scene.close()
        warm_compile[env_id] = time.perf_counter() - began
    rows = []
    for env_id, starts in STARTS.items():
        for seed in range(seeds):
            for start in starts:
                scene = Scene(env_id, seed, start)
                if scene.ended:
                    print(env_id, seed, start, "episode ended before t0", flush=True)
                    scene.close()
                    continue
                row = {
                    "env": env_id,
                    "seed": seed,
                    "t0_s": start,
                    "vehicles": scene.vehicles,
                    "learn_s": scene.learn_time,
                    "decide_s": scene.decide(),
                    "budgets": {},
                }
                for budget in budgets:
                    ours = scene.library(budget)
                    theirs = scene.reference(budget)
                    row["budgets"][str(budget)] = {
                        "library": ours,
                        "reference": theirs,
                        "ratio_whole": theirs["time_s"] / ours["whole_s"],
                        "ratio_search": theirs["time_s"] / ours["search_s"],
                        "ratio_search_full": theirs["time_s"] / ours["search_free_s"],
                    }
                    print(
                        f"{env_id} seed {seed} t0 {start} K {budget}: library {ours['whole_s'] * 1e3:.1f} ms "
                        f"(search {ours['search_s'] * 1e3:.1f}), reference {theirs['time_s']:.2f} s, "
                        f"x{row['budgets'][str(budget)]['ratio_whole']:.0f}",
                        flush=True,
                    )
                rows.append(row)
                scene.close()
    tables = summarise(rows, budgets)
    results = {
        "machine": f"{platform.machine()} {platform.python_implementation()} {platform.python_version()}, "
        f"{os.cpu_count()} cores shared with other jobs",
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "load_average_before": [round(x, 2) for x in load_before],
        "load_average_after": [round(x, 2) for x in os.getloadavg()],
        "wall_s": time.perf_counter() - started,
        "warm_up_s": warm_compile,
        "seeds": list(range(seeds)),
        "starts_s": {k: list(v) for k, v in STARTS.items()},
        "budgets": list(budgets),
        "gamma": GAMMA,
        "rows": rows,
        "tables": tables,
    }
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "highway_env_planner.json").write_text(json.dumps(results, indent=2) + "\n")
    (RESULTS / "highway_env_planner.md").write_text(markdown(results))
    print(markdown(results))
    return results


def _cell(s: dict, scale: float = 1.0, fmt: str = ".3g") -> str:
    return f"{s['median'] * scale:{fmt}} ({s['min'] * scale:{fmt}}-{s['max'] * scale:{fmt}})"


def markdown(results: dict) -> str:
    """The tables as Markdown."""
    lines = [
        "# Decision time on highway-env's scenes: the library's robust planner vs a reference built from highway-env",
        "",
        f"Measured {results['date']} on {results['machine']}; load average before "
        f"{results['load_average_before']}, after {results['load_average_after']}; one run of "
        f"`benchmarks/bench_highway_env_planner.py` ({results['wall_s']:.0f} s wall), seeds {results['seeds']}, "
        f"decisions at t0 = {results['starts_s']} s, gamma {results['gamma']}. CPU time (`time.process_time`). "
        "The numba kernels were compiled or loaded from the cache by one warm-up decision per environment "
        f"before any timing ({', '.join(f'{k} {v:.1f} s' for k, v in results['warm_up_s'].items())}).",
        "",
        "Library: whole = the learner's updates over the last decision (highway) + the ego's reach and the "
        "5 s forecast + `RobustTreePlanner(budget=K)` on `BicycleModel` with the `DrivingReward` of that "
        "forecast; search = the last alone (it stops early, `solved`, once every sequence may collide within "
        "the forecast: expansions made); search at full K = the same search on a table of empty boxes "
        "(nothing collides, all K expansions: the library's cost at the reference's amount of work). Reference: `benchmarks/highway_env_reference_planner.py` "
        "(a copy of the environment with `IntervalVehicle`s in every node, `env.step` per action on a deep "
        "copy, the same K, actions, reward, depth rule). Median (min-max) over the scenes; ratio = "
        "reference / library per scene. `decide`: the registered robust method's own decision on highway-env "
        "(exhaustive over two meta-actions, no budget; on the highway two forecasts, the second for the lane-keeping sequences).",
        "",
    ]
    for env_id, table in results["tables"].items():
        lines += [
            f"## {env_id} ({table['scenes']} scenes; `decide` {_cell(table['decide_s'], 1e3)} ms)",
            "",
            "| K | library whole (ms) | library search (ms), expansions | library search at full K (ms) | "
            "reference (s), expansions | ratio whole | ratio search | ratio search at full K | same action |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for budget, c in table["budgets"].items():
            lines.append(
                f"| {budget} | {_cell(c['library_whole_s'], 1e3)} | {_cell(c['library_search_s'], 1e3)}, "
                f"{_cell(c['library_expansions'], fmt='.0f')} | {_cell(c['library_search_full_s'], 1e3)} | "
                f"{_cell(c['reference_s'])}, {_cell(c['reference_expansions'], fmt='.0f')} | "
                f"{_cell(c['ratio_whole'], fmt='.0f')} | {_cell(c['ratio_search'], fmt='.0f')} | "
                f"{_cell(c['ratio_search_full'], fmt='.0f')} | {c['same_action']}/{table['scenes']} |"
            )
        lines += [
            "",
            "Per expansion (the same amount of work): the reference's time over its expansions, the library's "
            "search at full K over its K expansions.",
            "",
            "| K | reference expansions | reference env.steps | reference per expansion (ms) | "
            "library per expansion at full K (ms) | ratio per expansion |",
            "|---|---|---|---|---|---|",
        ]
        for budget, c in table["budgets"].items():
            lines.append(
                f"| {budget} | {_cell(c['reference_expansions'], fmt='.0f')} | "
                f"{_cell(c['reference_env_steps'], fmt='.0f')} | {_cell(c['reference_per_expansion_s'], 1e3)} | "
                f"{_cell(c['library_full_per_expansion_s'], 1e3)} | {_cell(c['ratio_per_expansion'], fmt='.0f')} |"
            )
        lines.append("")
    return "\n".join(lines) + "\n"


def render() -> dict:
    """Re-derive the tables and the Markdown from the rows of the saved run (no new measurement)."""
    results = json.loads((RESULTS / "highway_env_planner.json").read_text())
    results["tables"] = summarise(results["rows"], results["budgets"])
    (RESULTS / "highway_env_planner.json").write_text(json.dumps(results, indent=2) + "\n")
    (RESULTS / "highway_env_planner.md").write_text(markdown(results))
    return results


def parse_arguments(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line: ``--seeds`` >= 1, ``--budgets`` a comma-separated list of integers >= 1
    (``budgets`` is returned as a tuple), ``--render``; anything else exits 2 with argparse's message."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--budgets", default=",".join(map(str, BUDGETS)))
    parser.add_argument("--render", action="store_true", help="re-render the tables of the saved run only")
    arguments = parser.parse_args(argv)
    if arguments.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {arguments.seeds}")
    try:
        budgets = tuple(int(b) for b in arguments.budgets.split(","))
    except ValueError:
        budgets = ()
    if not budgets or min(budgets) < 1:
        parser.error(f"--budgets must be integers >= 1 separated by commas, got {arguments.budgets!r}")
    arguments.budgets = budgets
    return arguments


if __name__ == "__main__":
    arguments = parse_arguments()
    if arguments.render:
        print(markdown(render()))
    else:
        main(arguments.seeds, arguments.budgets)
