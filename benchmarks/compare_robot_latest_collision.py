"""The robot's robust method with and without the latest-possible-collision rule, on the same episodes.

`RobustMethod` executes, when the tree's best plan may collide within
`LATEST_COLLISION_DECISIONS` decisions, the first action whose plans stay clear of every
box longest under every surviving hypothesis (`minimaxplan.planners.latest_collision_action`).
This script runs the registered robust method on the same seeds twice, the rule on and
off (``RobustMethod.latest_collision``), in the stress sweep's crowd worlds
(``--cells``, pedestrians:velocity uncertainty) and in Table 3's worlds (``--worlds``),
and writes per world and mode the outcomes, the mean travel time of the goals, how many
decisions the rule examined and overrode, and every seed whose outcome differs.

Usage::

    python benchmarks/compare_robot_latest_collision.py --cells 8:0.6 --first-seed 20 --episodes 400 \\
        --worlds static,pedestrian --world-episodes 100 [--workers 2] [--out benchmarks/results/robot_latest_collision]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import pathlib
import sys
import time

import numpy as np

from minimaxplan.analysis.arguments import count, one_line
from minimaxplan.analysis.episode import run_episode
from minimaxplan.analysis.registry import register_scenario
from minimaxplan.analysis.robot_methods import LATEST_COLLISION_DECISIONS, RobustMethod
from minimaxplan.analysis.sweep import CrowdScenarioFactory, cell_name

MODES = ("rule", "tree")


def parse_cells(text: str) -> list[tuple[int, float]]:
    """``"8:0.6,5:0.3"`` -> ``[(8, 0.6), (5, 0.3)]``; raises ValueError naming the bad item."""
    cells = []
    for item in filter(None, (part.strip() for part in text.split(","))):
        try:
            pedestrians, bound = item.split(":")
            cell = (int(pedestrians), float(bound))
        except ValueError:
            raise ValueError(f"--cells items are PEDESTRIANS:UNCERTAINTY, got {item!r}") from None
        if cell[0] < 0 or not np.isfinite(cell[1]) or cell[1] < 0:
            raise ValueError(f"--cells needs pedestrians >= 0 and an uncertainty >= 0, got {item!r}")
        cells.append(cell)
    return cells


def run_one(job: tuple[str, str, int]) -> dict:
    """One robust episode of ``(mode, scenario, seed)``: its outcome and the rule's counts."""
    mode, scenario, seed = job
    RobustMethod.latest_collision = mode == "rule"
    record = run_episode(scenario, "robust", seed)
    decisions = record.extra["decisions"]
    return {
        "mode": mode,
        "scenario": scenario,
        "seed": seed,
        "outcome": record.outcome,
        "time_s": record.time_s,
        "decisions": record.decisions,
        "examined": sum(d["latest_collision"] is not None for d in decisions),
        "overridden": sum(d["action"] != d["tree_action"] for d in decisions),
        "boxes_missed": record.boxes_missed,
    }


def summarise(rows: list[dict]) -> list[dict]:
    """Per (scenario, mode): episodes, outcome counts, mean goal time, decisions examined and overridden."""
    groups: dict[tuple[str, str], list[dict]] = {}
    for row in rows:
        groups.setdefault((row["scenario"], row["mode"]), []).append(row)
    table = []
    for (scenario, mode), group in groups.items():
        goals = [r["time_s"] for r in group if r["outcome"] == "goal"]
        outcomes: dict[str, int] = {}
        for r in group:
            outcomes[r["outcome"]] = outcomes.get(r["outcome"], 0) + 1
        table.append(
            {
                "scenario": scenario,
                "mode": mode,
                "episodes": len(group),
                "outcomes": dict(sorted(outcomes.items())),
                "mean_goal_time_s": float(np.mean(goals)) if goals else None,
                "decisions": sum(r["decisions"] for r in group),
                "examined": sum(r["examined"] for r in group),
                "overridden": sum(r["overridden"] for r in group),
                "boxes_missed": sum(r["boxes_missed"] for r in group),
            }
        )
    return table


def differences(rows: list[dict]) -> list[dict]:
    """The seeds whose outcome differs between the modes."""
    by_key = {(r["scenario"], r["seed"], r["mode"]): r for r in rows}
    out = []
    for scenario, seed in sorted({(r["scenario"], r["seed"]) for r in rows}):
        rule, tree = by_key.get((scenario, seed, "rule")), by_key.get((scenario, seed, "tree"))
        if rule and tree and rule["outcome"] != tree["outcome"]:
            out.append({"scenario": scenario, "seed": seed, "rule": rule["outcome"], "tree": tree["outcome"]})
    return out


def markdown(document: dict) -> str:
    """The report of a run."""
    lines = [
        "# The robot's robust method with and without the latest-possible-collision rule",
        "",
        f"Measured {document['date']} on {document['machine']}; load average before {document['load_before']}, "
        f"after {document['load_after']}; {document['wall_s']:.0f} s wall on {document['workers']} workers. "
        f"`benchmarks/compare_robot_latest_collision.py`, the registered robust method (K = 100), "
        f"`LATEST_COLLISION_DECISIONS` = {LATEST_COLLISION_DECISIONS}; rule: the method as registered, tree: "
        "`RobustMethod.latest_collision = False` (the tree's action always).",
        "",
        "| world | mode | episodes | outcomes | mean goal time (s) | decisions | examined by the rule | overridden | "
        "boxes missed |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in document["summary"]:
        outcomes = ", ".join(f"{k} {v}" for k, v in row["outcomes"].items())
        mean = "-" if row["mean_goal_time_s"] is None else f"{row['mean_goal_time_s']:.2f}"
        lines.append(
            f"| {row['scenario']} | {row['mode']} | {row['episodes']} | {outcomes} | {mean} | {row['decisions']} | "
            f"{row['examined']} | {row['overridden']} | {row['boxes_missed']} |"
        )
    lines += ["", "Seeds whose outcome differs:", ""]
    lines += [f"- {d['scenario']} seed {d['seed']}: rule {d['rule']}, tree {d['tree']}" for d in document["differ"]]
    if not document["differ"]:
        lines.append("- none")
    return "\n".join(lines) + "\n"


def parse_arguments(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line; a bad value exits 2 with one line naming the option."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", default="8:0.6", help="crowd cells PEDESTRIANS:UNCERTAINTY,... (default 8:0.6)")
    parser.add_argument("--first-seed", type=count(0), default=20, help="first seed of the cells (default 20)")
    parser.add_argument("--episodes", type=count(), default=400, help="episodes per cell and mode (default 400)")
    parser.add_argument("--worlds", default="static,pedestrian", help="Table 3 worlds (default static,pedestrian)")
    parser.add_argument("--world-episodes", type=count(0), default=100, help="seeds 0.. per world (default 100)")
    parser.add_argument("--workers", type=count(), default=2, help="processes (default 2)")
    parser.add_argument("--out", default="benchmarks/results/robot_latest_collision", help="output path stem")
    args = parser.parse_args(argv)
    try:
        args.cells = parse_cells(args.cells)
    except ValueError as exc:
        parser.exit(2, f"{parser.prog}: error: {one_line(str(exc))}\n")
    args.worlds = [w for w in (part.strip() for part in args.worlds.split(",")) if w]
    unknown = [w for w in args.worlds if w not in ("static", "pedestrian")]
    if unknown:
        parser.exit(2, f"{parser.prog}: error: --worlds takes static and pedestrian, got {unknown}\n")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_arguments(argv)
    jobs = []
    for pedestrians, bound in args.cells:
        name = cell_name("pedestrian", pedestrians, bound)
        register_scenario(name, CrowdScenarioFactory(pedestrians, bound))
        seeds = range(args.first_seed, args.first_seed + args.episodes)
        jobs += [(mode, name, seed) for seed in seeds for mode in MODES]
    jobs += [(mode, world, seed) for world in args.worlds for seed in range(args.world_episodes) for mode in MODES]
    load_before = [round(x, 2) for x in os.getloadavg()]
    started = time.perf_counter()
    rows = []
    with multiprocessing.get_context("fork").Pool(args.workers) as pool:
        for i, row in enumerate(pool.imap_unordered(run_one, jobs, chunksize=4), 1):
            rows.append(row)
            if i % 50 == 0 or i == len(jobs):
                print(f"{i}/{len(jobs)} episodes", file=sys.stderr, flush=True)
    rows.sort(key=lambda r: (r["scenario"], r["mode"], r["seed"]))
    document = {
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "machine": f"{os.uname().machine} {sys.implementation.name} {sys.version.split()[0]}",
        "load_before": load_before,
        "load_after": [round(x, 2) for x in os.getloadavg()],
        "wall_s": time.perf_counter() - started,
        "workers": args.workers,
        "summary": summarise(rows),
        "differ": differences(rows),
        "rows": rows,
    }
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(document, indent=1) + "\n")
    out.with_suffix(".md").write_text(markdown(document))
    print(markdown(document))
    return 0


if __name__ == "__main__":
    sys.exit(main())
