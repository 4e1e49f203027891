"""How much the learner narrows the other vehicles' parameter boxes inside robust episodes (issue 11).

Runs robust episodes of a driving world (the registered world and method, the
experiment's loop and seeds) and, at every decision, reads the belief the forecast gets
for each vehicle (`TrafficLearner.beliefs`): the width of each parameter's box over the
prior's width (theta_a1..3, theta_b1..2; 1.00 means nothing learned), binned by the
vehicle's track age (sub-steps since it was first measured).

It also measures what the longitudinal rows know that a box cannot hold. The free-driving
term of the acceleration is ``theta_a1 (v_t - v) = (c - theta_a1 v_ref) - theta_a1 (v -
v_ref)`` with ``c = theta_a1 v_t`` (the learner's fourth parameter) and ``v_ref`` the
vehicle's last measured speed. For every vehicle with at least `MIN_ROWS` longitudinal
rows it bounds ``d = c - theta_a1 v_ref`` over the rows of each surviving hypothesis
(`interval_parameter_box` after the linear change of coordinates ``c' = c - v_ref
theta_a1``, so each side is the library's certified weak-duality bound) and compares the
hull's width with the width of the same quantity over the boxes the forecast uses
(``theta_a1`` in its belief box, ``v_t`` in the scenario's range): the ratio is the share
of the free-driving acceleration's uncertainty at ``v = v_ref`` that the rows leave.

Usage::

    python benchmarks/trace_parameter_boxes.py --world tjunction --seeds 1,3,5 [--out FILE]
"""

from __future__ import annotations

import argparse
import pathlib
import time

import numpy as np

from minimaxplan.analysis import traffic_learning
from minimaxplan.analysis.arguments import count_list
from minimaxplan.analysis.episode import run_episode
from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.models.sets import Box
from minimaxplan.verify.interval_regression import IntervalRows, interval_parameter_box

#: Track-age bins, sub-steps (dt = 0.1 s).
AGE_BINS = ((0, 20), (20, 50), (50, 100), (100, 200), (200, 400), (400, 10**6))
#: Longitudinal rows a hypothesis needs before its ``d`` bound is computed.
MIN_ROWS = 40
#: A box side counts as narrowed when its width is below this share of the prior's.
NARROWED = 0.99
PARAMETERS = ("theta_a1", "theta_a2", "theta_a3", "theta_b1", "theta_b2")


def speed_offset_bound(rows: IntervalRows, prior: Box, v_ref: float) -> tuple[float, float]:
    """Certified ``(lo, hi)`` of ``d = c - theta_a1 v_ref`` over the parameters (theta_a, c) that explain ``rows``.

    Parameters
    ----------
    rows : IntervalRows
        Longitudinal rows in ``(theta_a1, theta_a2, theta_a3, c)``, the target-speed rows included.
    prior : Box
        Their prior box (dimension 4).
    v_ref : float
        The reference speed, m/s.

    Raises
    ------
    DimensionError, InputError
        Rows or prior not of dimension 4; a non-finite ``v_ref``.
    NoConsistentModel, SolverFailure
        As `interval_parameter_box`.

    Notes
    -----
    In the coordinates ``(theta_a1, theta_a2, theta_a3, d)`` a row ``g . theta`` becomes
    ``(g1 + v_ref g4) theta_a1 + g2 theta_a2 + g3 theta_a3 + g4 d``: the fourth column is
    exact (not an interval) in the learner's rows, so ``d`` may range below 0; its prior
    side is the hull of ``c - theta_a1 v_ref`` over the prior box.
    """
    if rows.nparams != 4 or prior.dim != 4:
        raise DimensionError(
            f"rows and prior must be in (theta_a1, theta_a2, theta_a3, c): got {rows.nparams} parameters "
            f"and a prior of dimension {prior.dim}"
        )
    if not np.isfinite(v_ref):
        raise InputError(f"v_ref must be finite, got {v_ref!r}")
    m = np.eye(4)
    m[3, 0] = v_ref  # column 1 of the new regressors: g1 + v_ref g4
    shifted = IntervalRows(rows.regressor_low @ m, rows.regressor_high @ m, rows.target_low, rows.target_high)
    lo, hi = prior.low.copy(), prior.high.copy()
    lo[3], hi[3] = prior.low[3] - v_ref * prior.high[0], prior.high[3] - v_ref * prior.low[0]
    box = interval_parameter_box(shifted, Box(lo, hi), coordinates=(3,))
    return float(box.low[3]), float(box.high[3])


def trace(world: str, seed: int) -> tuple[str, list, list]:
    """One robust episode: its outcome, (age, width ratios) per belief, (age, d ratio) per bounded vehicle."""
    widths: list = []
    offsets: list = []
    beliefs = traffic_learning.TrafficLearner.beliefs

    def recorded(self, agents=None):
        out = beliefs(self, agents)
        prior_a, prior_b = self.prior_a, self.prior_b
        v_lo, v_hi = self.speed_range
        for agent, belief in out.items():
            track = self.tracks[agent]
            age = self.step - track.first
            ra = (belief.theta_a.high - belief.theta_a.low) / (prior_a.high - prior_a.low)
            rb = (belief.theta_b.high - belief.theta_b.low) / (prior_b.high - prior_b.low)
            widths.append((age, *ra, *rb))
            lons = {id(h.lon): h.lon for h in track.hyps if self._alive(h)}.values()
            if not lons or any(lon.rows.n < MIN_ROWS for lon in lons):
                continue
            v_ref = float(track.states[max(track.states)][2])
            sides = [speed_offset_bound(self._lon_rows_of(lon), self.prior_lon, v_ref) for lon in lons]
            learned = max(s[1] for s in sides) - min(s[0] for s in sides)
            a1_lo, a1_hi = belief.theta_a.low[0], belief.theta_a.high[0]
            corners = [a * (v - v_ref) for a in (a1_lo, a1_hi) for v in (v_lo, v_hi)]
            offsets.append((age, learned / (max(corners) - min(corners))))
        return out

    traffic_learning.TrafficLearner.beliefs = recorded
    try:
        record = run_episode(world, "robust", seed)
    finally:
        traffic_learning.TrafficLearner.beliefs = beliefs
    return record.outcome, widths, offsets


def summary(widths: np.ndarray, offsets: np.ndarray) -> list[str]:
    """Markdown rows per age bin: beliefs, median width ratio per parameter, share narrowed, d ratio."""
    lines = [
        "| track age (sub-steps) | beliefs | median width / prior: "
        + ", ".join(PARAMETERS)
        + f" | narrowed below {NARROWED:.2f} of the prior (any parameter) | vehicles with d bounded "
        "| d width: rows / boxes, median (min-max) |",
        "|---|---:|---|---:|---:|---|",
    ]
    for lo, hi in AGE_BINS:
        w = widths[(widths[:, 0] >= lo) & (widths[:, 0] < hi)] if widths.size else np.zeros((0, 6))
        if not len(w):
            continue
        d = offsets[(offsets[:, 0] >= lo) & (offsets[:, 0] < hi)] if offsets.size else np.zeros((0, 2))
        med = ", ".join(f"{x:.2f}" for x in np.median(w[:, 1:], axis=0))
        narrowed = float(np.mean(np.any(w[:, 1:] < NARROWED, axis=1)))
        d_cell = f"{np.median(d[:, 1]):.2f} ({d[:, 1].min():.2f}-{d[:, 1].max():.2f})" if len(d) else "-"
        label = f"{lo}-{hi}" if hi < 10**6 else f">= {lo}"
        lines.append(f"| {label} | {len(w)} | {med} | {narrowed:.2f} | {len(d)} | {d_cell} |")
    return lines


def main() -> None:
    """Trace the seeds given and write the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", required=True, choices=("highway", "tjunction"))
    parser.add_argument("--seeds", required=True, type=count_list(0), help="comma-separated episode seeds, each >= 0")
    parser.add_argument("--out", default=None, help="default benchmarks/results/trace_parameter_boxes_WORLD.md")
    args = parser.parse_args()
    out = args.out or f"benchmarks/results/trace_parameter_boxes_{args.world}.md"
    start = time.time()
    widths, offsets, outcomes = [], [], []
    for seed in args.seeds:
        outcome, w, d = trace(args.world, seed)
        outcomes.append(f"{seed} {outcome}")
        widths += w
        offsets += d
    lines = [
        f"# Learned parameter boxes inside robust {args.world} episodes",
        "",
        f"`python benchmarks/trace_parameter_boxes.py --world {args.world} --seeds "
        f"{','.join(map(str, args.seeds))}`; episodes (seed outcome): {', '.join(outcomes)}.",
        "",
        *summary(np.array(widths, dtype=float), np.array(offsets, dtype=float)),
        "",
        f"{len(args.seeds)} episodes, {time.time() - start:.0f} s wall.",
        "",
    ]
    text = "\n".join(lines)
    pathlib.Path(out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
