"""Transitions until a wrong intention is eliminated, per kind of intention, in both road worlds (issue 11).

Runs `minimaxplan.analysis.traffic_learning.elimination_study` (the ego on
`hold_lane_control`, a `TrafficLearner` fed every sub-step's measurement, every belief
checked against the world's ground truth) on the seeds given, one process per world, and
writes ``benchmarks/results/elimination_times.md`` and ``.json``: per kind, the median
[min, max] of the transitions from the moment the intention was wrong to its elimination,
and how many of the wrong intentions were eliminated while their vehicle was observed;
with the vehicle-steps checked and the misses (the true intention in force not among the
survivors, the true parameters outside the belief's boxes), which must be 0.

Usage: ``python benchmarks/elimination_times.py [--seeds 0-19]``.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import datetime
import json
import os
import pathlib
import time
from collections.abc import Mapping, Sequence

from minimaxplan.analysis.traffic_learning import elimination_study

RESULTS = pathlib.Path(__file__).parent / "results"
WORLDS = ("highway", "tjunction")


def _seeds(text: str) -> list[int]:
    """``"a-b"`` (inclusive) or ``"a,b,c"`` as a non-empty list of non-negative seeds."""
    try:
        if "-" in text:
            low, high = (int(v) for v in text.split("-", 1))
            seeds = list(range(low, high + 1))
        else:
            seeds = [int(v) for v in text.split(",") if v]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seeds must be a-b or a,b,c of integers, got {text!r}") from None
    if not seeds or min(seeds) < 0:
        raise argparse.ArgumentTypeError(f"--seeds must name at least one seed, each >= 0, got {text!r}")
    return seeds


def _run(kind: str, seeds: Sequence[int]) -> dict:
    began = time.perf_counter()
    study = elimination_study(kind, seeds)
    study["wall_s"] = time.perf_counter() - began
    return study


def markdown(studies: Mapping[str, dict], meta: Mapping) -> str:
    """The statistics per world and kind, and the checks against the truth."""
    lines = [
        "# Transitions until a wrong intention is eliminated",
        "",
        f"`python benchmarks/elimination_times.py --seeds {meta['seeds']}`, {meta['date']}, load {meta['load']}; "
        "the ego holds its lane (`hold_lane_control`), a `TrafficLearner` sees every sub-step (0.1 s). "
        "Transitions from the moment the intention was wrong (for the lane being left, the start of the "
        "lane change) to its elimination; eliminated / wrong: of the wrong intentions, those eliminated "
        "while their vehicle was observed.",
        "",
        "| world | kind of wrong intention | median | [min, max] | eliminated / wrong |",
        "|---|---|---:|---|---:|",
    ]
    for kind, study in studies.items():
        for name, s in study["statistics"].items():
            span = "-" if s["median"] is None else f"[{s['min']}, {s['max']}]"
            median = "-" if s["median"] is None else f"{s['median']:g}"
            lines.append(f"| {kind} | {name} | {median} | {span} | {s['eliminated']}/{s['count']} |")
    lines += [
        "",
        "| world | vehicle-steps checked | true intention not a survivor | theta_a outside | theta_b outside "
        "| LP solves | solver failures | learner ms per sub-step | wall (s) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for kind, s in studies.items():
        per_step = 1000.0 * s["learn_seconds"] / max(s["substeps"], 1)
        lines.append(
            f"| {kind} | {s['vehicle_steps']} | {s['intention_misses']} | {s['theta_a_misses']} | "
            f"{s['theta_b_misses']} | {s['lp_solves']} | {s['solver_failures']} | {per_step:.1f} | {s['wall_s']:.0f} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> dict:
    """Run the study in both worlds and write the results."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=_seeds, default=list(range(20)), help="a-b or a,b,c (default 0-19)")
    parser.add_argument("--out", type=pathlib.Path, default=RESULTS)
    args = parser.parse_args(argv)
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    with concurrent.futures.ProcessPoolExecutor(max_workers=len(WORLDS)) as pool:
        futures = {kind: pool.submit(_run, kind, args.seeds) for kind in WORLDS}
        studies = {kind: future.result() for kind, future in futures.items()}
    seeds = args.seeds
    contiguous = seeds == list(range(seeds[0], seeds[-1] + 1))
    meta = {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "seeds": f"{seeds[0]}-{seeds[-1]}" if contiguous and len(seeds) > 1 else ",".join(map(str, seeds)),
        "load": load,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "elimination_times.json").write_text(json.dumps({"meta": meta, "studies": studies}, indent=2) + "\n")
    (args.out / "elimination_times.md").write_text(markdown(studies, meta))
    return studies


if __name__ == "__main__":
    main()
