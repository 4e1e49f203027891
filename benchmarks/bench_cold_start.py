"""The first run: from ``import minimaxplan`` to the first robot `Decision`, with an empty numba cache.

A fresh checkout compiles the planner's numba kernels on its first plan. Each
measurement runs a fresh Python process (``sys.executable``) with its own
``NUMBA_CACHE_DIR``:

- cold: an empty cache directory (what a new user's first ``make demo`` pays);
- warm: the same directory again, now filled by the cold run (the reference, measured
  in the same run on the same machine: loading the cached kernels).

In each process: the seconds to import the library and build the first robot decision
(the paper's robot in a seeded "pedestrian" world, the robust multi-model planner on
its four hypotheses, the velocity controllers, K = 100, 5 sub-steps: the compiled engine
with the goal reward), then the seconds for each further reward family's first decision
on the same system (`SpeedLaneReward`: only its search kernel is new), then the
seconds of a second goal-reward decision (nothing left to compile). Each is measured
as wall time and as the process's CPU time (``time.process_time``, user + system): the
compile is single-threaded, so on a quiet machine the two agree, and on a shared one
the CPU time is the figure that does not count other processes' turns (the load
average is reported). The goal's verdict reads the CPU time.

Writes benchmarks/results/cold_start.md and .json (BENCH_RESULTS: another output
directory; BENCH_COLD_REPEATS: cold/warm pairs, default 1, the medians are reported).
"""

from __future__ import annotations

import datetime
import json
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).parent
RESULTS = pathlib.Path(os.environ.get("BENCH_RESULTS", HERE / "results"))
REPEATS = int(os.environ.get("BENCH_COLD_REPEATS", 1))
GOAL_SECONDS = 10.0

# Run in the fresh process: prints one JSON line of timings.
CHILD = r"""
import json, sys, time
started, started_cpu = time.perf_counter(), time.process_time()
from numba.core import event

compiles, open_compiles = [], []


class CompileTimes(event.Listener):
    # each dispatcher compile's CPU seconds, with and without the compiles it triggers (its callees)
    def on_start(self, ev):
        open_compiles.append([time.process_time(), 0.0])

    def on_end(self, ev):
        began, nested = open_compiles.pop()
        spent = time.process_time() - began
        if open_compiles:
            open_compiles[-1][1] += spent
        function = ev.data["dispatcher"].py_func
        compiles.append((function.__module__ + ":" + function.__qualname__, spent, spent - nested))


event.register("numba:compile", CompileTimes())
import numpy as np
import minimaxplan
from minimaxplan.analysis.episode import LoopConfig
from minimaxplan.analysis.robot_methods import velocity_controllers
from minimaxplan.analysis.robot_scenario import RobotScenario
from minimaxplan.planners.comparison import multi_model_robust_planner, root_state
from minimaxplan.scenarios import SpeedLaneReward
imported, imported_cpu = time.perf_counter(), time.process_time()
imports_cvxpy = "cvxpy" in sys.modules

scenario, config = RobotScenario("pedestrian"), LoopConfig()
world = scenario.make_world(0, config)
pairs = [(h.system, h.system.theta) for h in scenario.hypotheses(world)]
controllers = velocity_controllers(config)
start = np.asarray(world.state, dtype=float)


def decide(reward):
    planner = multi_model_robust_planner(pairs, reward, controllers, gamma=config.gamma, budget=config.budget,
                                         substeps=world.params.substeps)
    began, began_cpu = time.perf_counter(), time.process_time()
    decision = planner.plan(root_state(planner, start - 0.01, start + 0.01, time=0))
    assert planner.engine_used == "compiled", planner.engine_used
    return (time.perf_counter() - began, time.process_time() - began_cpu), decision


goal = scenario.objective(world, world.goal, uncertain=True)
first, decision = decide(goal)
first_decision, first_decision_cpu = time.perf_counter(), time.process_time()
first_compiles = list(compiles)
speed_lane, _ = decide(SpeedLaneReward(target_speed=1.0, speed_range=2.0, speed_indices=(2, 3), lateral_index=1,
                                        obstacles=world.obstacles, robot_radius=world.params.robot_radius))
again, second = decide(goal)
assert second.action == decision.action
print(json.dumps({
    "import_s": imported - started,
    "to_first_decision_s": first_decision - started,
    "first_plan_s": first[0],
    "speed_lane_first_plan_s": speed_lane[0],
    "compiled_plan_s": again[0],
    "import_cpu_s": imported_cpu - started_cpu,
    "to_first_decision_cpu_s": first_decision_cpu - started_cpu,
    "first_plan_cpu_s": first[1],
    "speed_lane_first_plan_cpu_s": speed_lane[1],
    "compiled_plan_cpu_s": again[1],
    "action": int(decision.action),
    "imports_cvxpy": imports_cvxpy,
    "first_plan_compiles": first_compiles,
}))
"""


def run_child(cache: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the cold-start process failed:\n{done.stderr}")
    return json.loads(done.stdout.strip().splitlines()[-1])


HELP_REPEATS = 5
HELP_GOAL_SECONDS = 0.5


def time_command(argv: list[str]) -> float:
    """Wall seconds of one fresh process running ``argv`` (it must exit 0)."""
    started = time.perf_counter()
    subprocess.run(argv, check=True, capture_output=True)
    return time.perf_counter() - started


def help_times() -> dict:
    """``minimaxplan --help`` in fresh processes, and a bare interpreter start as the reference."""
    script = pathlib.Path(sys.executable).with_name("minimaxplan")
    command = (
        [str(script)]
        if script.exists()
        else [sys.executable, "-c", "from minimaxplan.analysis.cli import main; main()"]
    )
    help_runs = [time_command([*command, "--help"]) for _ in range(HELP_REPEATS)]
    bare_runs = [time_command([sys.executable, "-c", "pass"]) for _ in range(HELP_REPEATS)]
    return {"help_s": statistics.median(help_runs), "interpreter_s": statistics.median(bare_runs)}


def compile_table(compiles: list, imports_cvxpy: bool) -> list[str]:
    """Markdown lines: what the first plan compiled (numba's compile events), by CPU seconds of its own."""
    total_self = sum(own for _, _, own in compiles)
    lines = [
        f"What the first plan compiles (one cold process; numba's compile events, {len(compiles)} dispatcher "
        f"compiles, {total_self:.2f} s of CPU in all): each function's own seconds (without the compiles it "
        "triggers; a caller's own seconds include optimising and emitting its callees' code again, linked "
        "into its own), then with them.",
        "",
        "| function | own CPU s | with its callees |",
        "|---|---:|---:|",
    ]
    for name, spent, own in sorted(compiles, key=lambda row: -row[2]):
        if own >= 0.05:
            lines.append(f"| `{name}` | {own:.2f} | {spent:.2f} |")
    lines += [
        "",
        f"The import {'imports' if imports_cvxpy else 'does not import'} cvxpy (`minimaxplan.verify.lmi`).",
        "",
    ]
    return lines


def main() -> dict:
    load_before = os.getloadavg()[0]
    cold, warm = [], []
    for _ in range(REPEATS):
        with tempfile.TemporaryDirectory(prefix="minimaxplan-numba-") as cache:
            cold.append(run_child(cache))
            warm.append(run_child(cache))

    def median(runs, key):
        return statistics.median(run[key] for run in runs)

    keys = ["to_first_decision_s", "import_s", "first_plan_s", "speed_lane_first_plan_s", "compiled_plan_s"]
    cpu_keys = [key[: -len("_s")] + "_cpu_s" for key in keys]
    result = {
        "cold": {key: median(cold, key) for key in keys + cpu_keys},
        "warm": {key: median(warm, key) for key in keys + cpu_keys},
        "runs": {"cold": cold, "warm": warm},
        "goal_s": GOAL_SECONDS,
        "help": help_times(),
        "repeats": REPEATS,
        "machine": f"{platform.machine()} {platform.python_implementation()} {platform.python_version()}, "
        f"{os.cpu_count()} cores, load average {load_before:.1f} before, {os.getloadavg()[0]:.1f} after",
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
    }
    labels = {
        "to_first_decision_s": "import to the first robot Decision",
        "import_s": "of which: import",
        "first_plan_s": "of which: the first plan (goal reward)",
        "speed_lane_first_plan_s": "first plan of a further family (SpeedLaneReward)",
        "compiled_plan_s": "a later plan (nothing to compile)",
    }
    cold_total = result["cold"]["to_first_decision_s"]
    cold_cpu = result["cold"]["to_first_decision_cpu_s"]
    lines = [
        "# Cold start: import to the first robot Decision",
        "",
        f"{result['date']}, {result['machine']}; fresh processes, median of {REPEATS} "
        "(benchmarks/bench_cold_start.py).",
        "",
        "| seconds | cold: wall | cold: CPU | warm (same cache, reference): wall | warm: CPU |",
        "|---|---:|---:|---:|---:|",
    ]
    for key, cpu_key in zip(keys, cpu_keys):
        cold_row, warm_row = result["cold"], result["warm"]
        lines.append(
            f"| {labels[key]} | {cold_row[key]:.2f} | {cold_row[cpu_key]:.2f} | {warm_row[key]:.2f} "
            f"| {warm_row[cpu_key]:.2f} |"
        )
    verdict = "met" if cold_cpu < GOAL_SECONDS else "NOT met"
    lines += [
        "",
        f"Goal: under {GOAL_SECONDS:.0f} s cold to the first Decision: {verdict} ({cold_cpu:.1f} s of CPU, "
        f"{cold_total:.1f} s wall). The verdict reads the CPU time (user + system, `time.process_time` in the "
        "fresh process): the compile is single-threaded, so on a quiet machine the wall time is the CPU time, "
        "while on a shared one the wall time also counts the other processes' turns (see the load average).",
        "",
    ]
    lines += compile_table(cold[len(cold) // 2]["first_plan_compiles"], cold[0]["imports_cvxpy"])
    helped = result["help"]
    help_verdict = "met" if helped["help_s"] < HELP_GOAL_SECONDS else "NOT met"
    lines += [
        f"`minimaxplan --help` in a fresh process: {helped['help_s']:.3f} s (median of {HELP_REPEATS}; a bare "
        f"interpreter start, the reference, {helped['interpreter_s']:.3f} s); goal under {HELP_GOAL_SECONDS} s: "
        f"{help_verdict}. It imports neither numpy, cvxpy nor numba (tests/analysis/test_cli_errors.py).",
        "",
    ]
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "cold_start.md").write_text("\n".join(lines))
    (RESULTS / "cold_start.json").write_text(json.dumps(result, indent=2) + "\n")
    print("\n".join(lines))
    return result


if __name__ == "__main__":
    main()
