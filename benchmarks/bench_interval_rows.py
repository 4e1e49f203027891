"""The learner's interval LPs: its two shortcuts against HiGHS on every LP, on the learner's own rows.

The traffic learner (`minimaxplan.analysis.traffic_learning`) asks two kinds of questions of
interval rows, and each has a shortcut that gives HiGHS's answer without calling it:

* one-row verdicts: for every vehicle and lane-change intention whose last possible switch
  is now, whether the one transition just observed rules it out
  (`TrafficLearner._in_force_before_now`), and a new hypothesis's first row. Both are
  `interval_consistency` on one row, which solves that row's margin LP in closed form
  (`_solve_single_row`);
* parameter boxes: `interval_parameter_box` skips the LP of every side the prior attains (the
  verdict's witness moved onto it meets every row, `_meets_every_inequality`).

This benchmark records every one-row verdict and every parameter box of a few robust episodes in
both road worlds (real rows, real priors), then times, in the same run and process, on the same
calls:

* ours: the functions as shipped;
* the reference: the same functions with every LP handed to HiGHS (`linprog`), everything else
  identical.

Asserted on every row: the same status, margins equal to 1e-9 (they are dimensionless), and the
certificate of every elimination re-checks above the tolerance; on every box call, the same box to
the bit. Also timed: the learner's share of those episodes' CPU time with either side, the
episodes' outcomes, times and returns asserted equal, and every parameter box the learner fits in
them the same bits. Writes benchmarks/results/interval_rows.md and .json.
"""

from __future__ import annotations

import datetime
import json
import os
import pathlib
import platform
import time

import numpy as np

import minimaxplan.verify.interval_regression as interval_regression
from minimaxplan.analysis.episode import run_episode
from minimaxplan.analysis.traffic_learning import TrafficLearner
from minimaxplan.models.errors import NoConsistentModel, SolverFailure

RESULTS = pathlib.Path(__file__).parent / "results"
EPISODES = {"highway": (0, 1), "tjunction": (0, 1)}
REPEATS = 5


def _highs_single_row(scaled):
    """The reference: the same margin LP solved by HiGHS."""
    return interval_regression._solve(scaled, np.zeros(scaled.a.shape[1]), None)


def _every_side(*_args) -> bool:
    """The reference: no side is taken as attained, every side is an LP."""
    return False


class _UseHighs:
    """Within this context every LP goes to HiGHS (the reference): one-row verdicts and every box side."""

    def __enter__(self):
        self.closed_form = interval_regression._solve_single_row
        self.attained = interval_regression._meets_every_inequality
        interval_regression._solve_single_row = _highs_single_row
        interval_regression._meets_every_inequality = _every_side

    def __exit__(self, *exc):
        interval_regression._solve_single_row = self.closed_form
        interval_regression._meets_every_inequality = self.attained


def _record_rows() -> tuple[dict, dict, dict]:
    """Every one-row verdict and every box call of the episodes, per world, and the learner's CPU seconds
    with each side."""
    original = interval_regression.interval_consistency
    import minimaxplan.analysis.traffic_learning as traffic_learning

    calls: dict = {world: [] for world in EPISODES}
    box_calls: dict = {world: [] for world in EPISODES}
    learner: dict = {world: {"ours": 0.0, "reference": 0.0, "decisions": 0, "boxes": 0} for world in EPISODES}
    current = {"world": None, "side": "ours"}
    boxes: dict = {"ours": [], "reference": []}
    fit = TrafficLearner._box

    def keep_box(self, rows, prior, old, coordinates=None):
        if current["side"] == "ours":
            box_calls[current["world"]].append((rows, prior, coordinates))
        box = fit(self, rows, prior, old, coordinates)
        boxes[current["side"]].append(b"" if box is None else box.low.tobytes() + box.high.tobytes())
        return box

    def recording(rows, prior, **kwargs):
        if rows.nrows == 1 and current["side"] == "ours":
            calls[current["world"]].append((rows, prior))
        return original(rows, prior, **kwargs)

    methods = (TrafficLearner.observe, TrafficLearner.beliefs)

    def timed(function):
        def wrapper(*args, **kwargs):
            start = time.process_time()
            try:
                return function(*args, **kwargs)
            finally:
                learner[current["world"]][current["side"]] += time.process_time() - start

        return wrapper

    traffic_learning.interval_consistency = recording
    TrafficLearner.observe, TrafficLearner.beliefs = (timed(m) for m in methods)
    TrafficLearner._box = keep_box
    try:
        current["world"] = "highway"
        run_episode("highway", "robust", 10000)  # compile the numba kernels outside the clock
        calls["highway"].clear()
        box_calls["highway"].clear()
        learner["highway"]["ours"] = 0.0
        for world, seeds in EPISODES.items():
            current["world"] = world
            for seed in seeds:
                current["side"] = "ours"
                boxes["ours"].clear()
                boxes["reference"].clear()
                record = run_episode(world, "robust", seed)
                learner[world]["decisions"] += record.decisions
                current["side"] = "reference"
                with _UseHighs():
                    again = run_episode(world, "robust", seed)
                if (again.outcome, again.time_s, again.discounted_return) != (
                    record.outcome,
                    record.time_s,
                    record.discounted_return,
                ):
                    raise AssertionError(f"{world} seed {seed}: the episode differs with HiGHS on every LP")
                if boxes["ours"] != boxes["reference"]:
                    raise AssertionError(f"{world} seed {seed}: a parameter box differs with HiGHS on every LP")
                learner[world]["boxes"] += len(boxes["ours"])
    finally:
        traffic_learning.interval_consistency = original
        TrafficLearner.observe, TrafficLearner.beliefs = methods
        TrafficLearner._box = fit
    return calls, box_calls, learner


def _best(cases: list, repeats: int) -> float:
    """The least CPU seconds of ``repeats`` passes of `interval_consistency` over ``cases``."""
    best = np.inf
    for _ in range(repeats):
        start = time.process_time()
        for rows, prior in cases:
            interval_regression.interval_consistency(rows, prior)
        best = min(best, time.process_time() - start)
    return best


def _boxes(cases: list) -> list:
    """The box of every recorded call (None where the rows are proven inconsistent or HiGHS fails)."""
    out = []
    for rows, prior, coordinates in cases:
        try:
            out.append(interval_regression.interval_parameter_box(rows, prior, coordinates=coordinates))
        except (NoConsistentModel, SolverFailure):
            out.append(None)
    return out


def _best_boxes(cases: list, repeats: int) -> float:
    """The least CPU seconds of ``repeats`` passes of `interval_parameter_box` over ``cases``."""
    best = np.inf
    for _ in range(repeats):
        start = time.process_time()
        _boxes(cases)
        best = min(best, time.process_time() - start)
    return best


def _box_rows(box_calls: dict) -> list:
    """Per world: the box calls solved both ways, the same bits asserted, LPs counted and timed."""
    solve = interval_regression._solve
    out = []
    for world, cases in box_calls.items():
        solved = [0]

        def counting(*args, _solved=solved):
            _solved[0] += 1
            return solve(*args)

        interval_regression._solve = counting
        try:
            ours = _boxes(cases)
        finally:
            interval_regression._solve = solve
        with _UseHighs():
            reference = _boxes(cases)
        for a, b in zip(ours, reference):
            same = (a is None and b is None) or (
                a is not None
                and b is not None
                and a.low.tobytes() == b.low.tobytes()
                and a.high.tobytes() == b.high.tobytes()
            )
            if not same:
                raise AssertionError(f"{world}: a parameter box differs with an LP for every side: {a} against {b}")
        sides = sum(2 * (p.dim if c is None else len(c)) for _, p, c in cases)
        # each call solves its verdict's margin LP too (one row: in closed form, both sides)
        margin_lps = sum(r.nrows > 1 for r, _, _ in cases)
        ours_s = _best_boxes(cases, REPEATS)
        with _UseHighs():
            reference_s = _best_boxes(cases, REPEATS)
        n = max(len(cases), 1)
        out.append(
            {
                "world": world,
                "calls": len(cases),
                "sides": sides,
                "sides_solved": solved[0] - margin_lps,
                "ours_ms": 1e3 * ours_s / n,
                "reference_ms": 1e3 * reference_s / n,
                "ratio": reference_s / ours_s if ours_s > 0 else float("nan"),
            }
        )
    return out


def main() -> dict:
    started = time.perf_counter()
    calls, box_calls, learner = _record_rows()
    consistency = interval_regression.interval_consistency
    tolerance = interval_regression.INTERVAL_ELIMINATION_MARGIN
    rows_out = []
    for world, cases in calls.items():
        ours = [consistency(r, p) for r, p in cases]
        with _UseHighs():
            reference = [consistency(r, p) for r, p in cases]
        for (rows, prior), a, b in zip(cases, ours, reference):
            assert a.status == b.status, (a.to_dict(), b.to_dict())
            assert abs(a.margin - b.margin) <= 1e-9, (a.margin, b.margin)
            if a.eliminated:
                assert a.certificate.recheck(rows, prior) > tolerance
        ours_s = _best(cases, REPEATS)
        with _UseHighs():
            reference_s = _best(cases, REPEATS)
        n = max(len(cases), 1)
        per_decision = {
            side: 1e3 * learner[world][side] / max(learner[world]["decisions"], 1) for side in ("ours", "reference")
        }
        rows_out.append(
            {
                "world": world,
                "rows": len(cases),
                "eliminated": int(sum(v.eliminated for v in ours)),
                "ours_us": 1e6 * ours_s / n,
                "reference_us": 1e6 * reference_s / n,
                "ratio": reference_s / ours_s if ours_s > 0 else float("nan"),
                "max_margin_difference": float(
                    max((abs(a.margin - b.margin) for a, b in zip(ours, reference)), default=0.0)
                ),
                "learner_ms_per_decision": per_decision,
                "decisions": learner[world]["decisions"],
                "parameter_boxes_identical": learner[world]["boxes"],
                "explained_ms_per_decision": 1e3 * (reference_s - ours_s) / max(learner[world]["decisions"], 1),
            }
        )
    boxes_out = _box_rows(box_calls)
    for b in boxes_out:
        decisions = max(learner[b["world"]]["decisions"], 1)
        b["explained_ms_per_decision"] = (b["reference_ms"] - b["ours_ms"]) * b["calls"] / decisions
    machine = f"{platform.machine()} {platform.processor() or ''} {platform.python_implementation()} {platform.python_version()}".strip()
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    load = os.getloadavg()[0]
    total = time.perf_counter() - started
    lines = [
        "# The learner's interval LPs: its shortcuts against HiGHS on every LP, on the learner's own rows",
        "",
        f"Machine: {machine}; date: {date}; load {load:.1f}; run time {total:.0f} s. Calls: every one-row "
        f"`interval_consistency` and every `interval_parameter_box` of robust episodes {EPISODES}; CPU time, best of "
        f"{REPEATS} passes over all calls, both sides in the same process.",
        "",
        "## One-row verdicts: closed form against HiGHS",
        "",
        "Statuses equal and margins within 1e-9 on every row (asserted); every elimination's certificate re-checked.",
        "",
        "| world | one-row verdicts | eliminated | closed form (us / verdict) | HiGHS (us / verdict) | ratio | max margin difference |",
        "|---|---|---|---|---|---|---|",
        *[
            f"| {r['world']} | {r['rows']} | {r['eliminated']} | {r['ours_us']:.0f} | {r['reference_us']:.0f} | "
            f"{r['ratio']:.1f}x | {r['max_margin_difference']:.1e} |"
            for r in rows_out
        ],
        "",
        "## Parameter boxes: the sides the prior attains skipped, against an LP for every side",
        "",
        "The same box to the bit on every call (asserted). A call also decides its rows' verdict (one LP, "
        "not counted among the sides).",
        "",
        "| world | box calls | sides | sides solved by an LP | shortcut (ms / box) | every side an LP (ms / box) | ratio |",
        "|---|---|---|---|---|---|---|",
        *[
            f"| {b['world']} | {b['calls']} | {b['sides']} | {b['sides_solved']} | {b['ours_ms']:.2f} | "
            f"{b['reference_ms']:.2f} | {b['ratio']:.1f}x |"
            for b in boxes_out
        ],
        "",
        "## The learner inside the episodes",
        "",
        "| world | decisions | learner, as shipped (ms / decision) | learner, every LP to HiGHS (ms / decision) "
        "| of which the one-row verdicts (ms / decision) | of which the boxes (ms / decision) |",
        "|---|---|---|---|---|---|",
        *[
            f"| {r['world']} | {r['decisions']} | {r['learner_ms_per_decision']['ours']:.1f} | "
            f"{r['learner_ms_per_decision']['reference']:.1f} | {r['explained_ms_per_decision']:.1f} | "
            f"{b['explained_ms_per_decision']:.1f} |"
            for r, b in zip(rows_out, boxes_out)
        ],
        "",
        "The learner's columns time `TrafficLearner.observe` and `beliefs` over the same episodes, run once with "
        "each side (the episodes' outcomes, times and returns are asserted equal); each is one run, not a best of, "
        "so their difference carries the machine's noise; the last two columns are the parts of it the one-row "
        "verdicts and the boxes account for (their time differences above, over the decisions). Every parameter box the learner fitted in "
        "those episodes is the same bits with either side (asserted): "
        + ", ".join(f"{r['world']} {r['parameter_boxes_identical']}" for r in rows_out)
        + ".",
    ]
    text = "\n".join(lines) + "\n"
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "interval_rows.md").write_text(text)
    results = {
        "machine": machine,
        "date": date,
        "load": load,
        "run_seconds": total,
        "worlds": rows_out,
        "parameter_boxes": boxes_out,
    }
    (RESULTS / "interval_rows.json").write_text(json.dumps(results, indent=2) + "\n")
    print(text)
    return results


if __name__ == "__main__":
    main()
