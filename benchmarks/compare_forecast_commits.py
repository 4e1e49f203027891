"""The traffic forecast and the driving search at two commits: CPU time, and whether their outputs are the same bits.

A change meant to make `forecast_traffic` or the driving planner faster without changing
what they compute is checked here: each revision is checked out into a temporary git
worktree and imported from there in its own process (the two never share a process),
the processes alternate over `ROUNDS` rounds, and each times `REPEATS` times, keeping
the median:

- every forecast of `benchmarks/bench_forecast.py`'s scenes (16 per world, 30 sub-steps,
  prior beliefs, the setting the road methods run: the contraction radius and the
  invariant sets);
- the search at every root of `benchmarks/bench_driving.py` (40 highway roots, K = 100,
  8 vehicles in view, the continuation bounds: as the road methods plan).

It also writes every forecast's boxes, state bounds and ``guaranteed`` flags and every
search's action, bounds and depth, which must be equal bit for bit between the
revisions (the script exits with status 1 otherwise).

Usage::

    python benchmarks/compare_forecast_commits.py BEFORE [AFTER]

``AFTER`` defaults to HEAD. Writes benchmarks/results/commits/BEFORE-AFTER.md and .json
(the first 12 hex digits of each commit).
"""

from __future__ import annotations

import datetime
import json
import os
import pathlib
import platform
import shutil
import subprocess
import sys
import tempfile

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent
RESULTS = HERE / "results"
ROUNDS = 3
REPEATS = 3

#: Row labels of the results table.
_LABELS = {"highway": "highway forecast", "tjunction": "T-junction forecast", "search": "driving search"}

#: The child: import the package from the given checkout, time the bench scenes' forecasts, save the arrays.
_CHILD = """
import json, sys, time
import numpy as np
sys.path.insert(0, sys.argv[1] + "/minimaxplan/benchmarks")
import minimaxplan
assert minimaxplan.__file__.startswith(sys.argv[1]), minimaxplan.__file__
import bench_forecast as b
times, arrays = {}, {}
for kind in ("highway", "tjunction"):
    scenes = b._scenes(kind)
    b._forecast(scenes[0], True, True)  # warm-up: tables, compiled kernels
    per = []
    for i, scene in enumerate(scenes):
        runs = []
        for _ in range(int(sys.argv[3])):
            start = time.process_time()
            forecast = b._forecast(scene, True, True)
            runs.append(time.process_time() - start)
        per.append(1e3 * float(np.median(runs)))
        for name in ("boxes", "state_lower", "state_upper", "guaranteed"):
            arrays[f"{kind}_{i}_{name}"] = getattr(forecast, name)
    times[kind] = per
import bench_driving as d
from minimaxplan.planners import RobustTreePlanner
from minimaxplan.planners.bicycle_model import HIGHWAY_ACTIONS, HIGHWAY_TARGET_SPEEDS, BicycleModel, ego_controller
from minimaxplan.scenarios.driving_reward import DrivingReward
from minimaxplan.scenarios.road import highway_road, lane_geometry
road = highway_road()
controller = ego_controller(lane_geometry(road), HIGHWAY_TARGET_SPEEDS)
rng = np.random.default_rng(d.BENCH_SEED0)
roots = []
for _ in range(d.ROOTS):  # the roots of bench_driving.main, drawn in its order
    lane = int(rng.integers(0, 3))
    ego = np.array([200.0, 4.0 * lane, float(rng.uniform(20.0, 30.0)), 0.0])
    model = BicycleModel(controller, DrivingReward.highway(d.synthetic_forecast(rng, ego), 0, road), HIGHWAY_ACTIONS)
    roots.append((model, model.initial_state(ego, level=1, lane=lane)))
RobustTreePlanner([roots[0][0]], roots[0][0].actions, gamma=d.GAMMA, budget=d.BUDGET).plan(roots[0][1])  # warm-up
per = []
for i, (model, state) in enumerate(roots):
    runs = []
    for _ in range(int(sys.argv[3])):
        planner = RobustTreePlanner([model], model.actions, gamma=d.GAMMA, budget=d.BUDGET)
        start = time.process_time()
        decision = planner.plan(state)
        runs.append(time.process_time() - start)
    per.append(1e3 * float(np.median(runs)))
    arrays[f"search_{i}"] = np.array([decision.action, decision.lower, decision.upper, decision.depth], dtype=float)
times["search"] = per
np.savez(sys.argv[2] + ".npz", **arrays)
print(json.dumps(times))
"""


def _checkout(revision: str, root: pathlib.Path, index: int) -> pathlib.Path:
    """A detached worktree of ``revision`` importable as ``minimaxplan`` (index: the two may be one commit)."""
    tree = root / f"tree_{index}"
    subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "-q", str(tree), revision], check=True)
    site = root / f"site_{index}"
    site.mkdir()
    (site / "minimaxplan").symlink_to(tree)
    return site


def _run(site: pathlib.Path, out: pathlib.Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(site))
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, str(site), str(out), str(REPEATS)],
        env=env,
        cwd=str(site),
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def _same_bits(a: pathlib.Path, b: pathlib.Path) -> list[str]:
    """Names of the arrays that differ or are in one file only (NaN equal to NaN; -0.0 and 0.0 count as different)."""
    first, second = np.load(a), np.load(b)
    differing = sorted(set(first.files) ^ set(second.files))
    for name in sorted(set(first.files) & set(second.files)):
        x, y = first[name], second[name]
        if x.shape != y.shape or x.tobytes() != y.tobytes():
            differing.append(name)
    return differing


def main(argv: list[str]) -> int:
    if len(argv) not in (1, 2):
        print("usage: compare_forecast_commits.py BEFORE [AFTER]", file=sys.stderr)
        return 2
    revisions = []
    for name in argv + (["HEAD"] if len(argv) == 1 else []):
        done = subprocess.run(
            ["git", "-C", str(REPO), "rev-parse", "--verify", name + "^{commit}"], capture_output=True, text=True
        )
        if done.returncode != 0:
            print(f"error: revision {name!r} is not a commit of {REPO}", file=sys.stderr)
            return 2
        revisions.append(done.stdout.strip())
    root = pathlib.Path(tempfile.mkdtemp(prefix="forecast-commits-"))
    sites = []
    try:
        sites = [_checkout(rev, root, index) for index, rev in enumerate(revisions)]
        times: list[dict[str, list[list[float]]]] = [{}, {}]  # per revision (the two may be one commit)
        for round_ in range(ROUNDS):
            for index in (0, 1) if round_ % 2 == 0 else (1, 0):
                print(f"round {round_ + 1}/{ROUNDS}: {revisions[index][:12]}", file=sys.stderr, flush=True)
                for kind, per in _run(sites[index], root / f"arrays_{index}").items():
                    times[index].setdefault(kind, []).append(per)
        differing = _same_bits(root / "arrays_0.npz", root / "arrays_1.npz")
        total = len(set(np.load(root / "arrays_0.npz").files) | set(np.load(root / "arrays_1.npz").files))
    finally:
        for site in sites:
            subprocess.run(
                ["git", "-C", str(REPO), "worktree", "remove", "--force", str(site / "minimaxplan")], check=False
            )
        shutil.rmtree(root, ignore_errors=True)  # then prune forgets any worktree whose checkout failed midway
        subprocess.run(["git", "-C", str(REPO), "worktree", "prune"], check=False)
    before, after = revisions
    worlds = {}
    for kind in times[0]:
        # per scene: the median over the rounds of each revision's median; the ratio per scene
        b = np.median(np.array(times[0][kind]), axis=0)
        a = np.median(np.array(times[1][kind]), axis=0)
        ratio = b / a
        worlds[kind] = {
            "scenes": len(b),
            "before_median_ms": float(np.median(b)),
            "after_median_ms": float(np.median(a)),
            "speedup_median": float(np.median(ratio)),
            "speedup_range": [float(ratio.min()), float(ratio.max())],
        }
    result = {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": f"{platform.machine()}, {platform.python_implementation()} {platform.python_version()}",
        "load_average": list(os.getloadavg()),
        "before": before,
        "after": after,
        "rounds": ROUNDS,
        "repeats": REPEATS,
        "worlds": worlds,
        "arrays_compared": total,
        "differing_arrays": differing,
    }
    lines = [
        "# The traffic forecast and the driving search at two commits",
        "",
        f"{result['date']}, {result['machine']}, load average {result['load_average'][0]:.1f} at the end, CPU times "
        f"(benchmarks/compare_forecast_commits.py). Before: `{before[:12]}`, after: `{after[:12]}`, each imported from "
        f"its own worktree in its own process, {ROUNDS} alternating rounds, each forecast timed {REPEATS} times (median), "
        "then the median over the rounds; the forecasts of benchmarks/bench_forecast.py's scenes with the contraction "
        "radius and the invariant sets (what the road methods run), and the search at benchmarks/bench_driving.py's roots "
        "(K = 100, continuation bounds).",
        "",
        "| what | scenes or roots | before, ms (median) | after, ms (median) | speed-up per scene, median (range) |",
        "|---|---:|---:|---:|---|",
    ]
    for kind, w in worlds.items():
        lo, hi = w["speedup_range"]
        lines.append(
            f"| {_LABELS.get(kind, kind)} | {w['scenes']} | {w['before_median_ms']:.1f} | {w['after_median_ms']:.1f} "
            f"| {w['speedup_median']:.2f} ({lo:.2f}-{hi:.2f}) |"
        )
    lines += [
        "",
        f"Outputs (per forecast: boxes, state bounds, `guaranteed`; per search: action, bounds, depth): "
        f"{total - len(differing)} of {total} arrays the same bit "
        f"for bit{'' if not differing else '; differing: ' + ', '.join(differing[:10])}.",
        "",
    ]
    out = RESULTS / "commits"
    out.mkdir(parents=True, exist_ok=True)
    name = f"{before[:12]}-{after[:12]}"
    (out / f"{name}.md").write_text("\n".join(lines))
    (out / f"{name}.json").write_text(json.dumps(result, indent=2) + "\n")
    print("\n".join(lines))
    return 1 if differing else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
