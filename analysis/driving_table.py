"""The paper's Table 4 from the per-episode rows of a driving run: failures as the paper counts them, paired travel times.

Table 4 counts a failure as any collision of the ego (whoever caused it) or leaving
the road; an episode that ends at the time limit without either is not a failure but
not a success either, so it is counted apart (``timeouts``) and, like a failure, has
no travel time. Travel times are compared paired, over the seeds that both methods
complete (every method of a run drives the same worlds, `episode_seeds`): the ratio of
a method's time to the reference's on each such seed, its mean and a Student-t 95%
interval of the mean.

`write_driving_table` is what ``minimaxplan experiment`` calls: it writes
``table4.md`` beside ``table.md`` when the run has driving episodes.
"""

from __future__ import annotations

import math
import pathlib
from collections.abc import Iterable, Mapping, Sequence

import numpy as np
from scipy import stats

from minimaxplan.models.errors import InputError

__all__ = [
    "DRIVING_SCENARIOS",
    "FAILURE_OUTCOMES",
    "BASELINES",
    "outcome_counts",
    "paired_ratio",
    "driving_markdown",
    "write_driving_table",
]

#: The registered driving worlds (`minimaxplan.analysis.road_scenario`).
DRIVING_SCENARIOS = ("highway", "tjunction")
#: The outcomes that are failures in Table 4.
FAILURE_OUTCOMES = ("collision", "off_road")
#: The reference methods of the travel-time comparison: the faster of them (Table 4's DWA and TEB).
BASELINES = ("dwa", "teb")


def _t_interval(values: Sequence[float]) -> tuple[float, float, float]:
    """Mean and Student-t 95% interval of the mean (NaN bounds for fewer than two values)."""
    x = np.asarray(values, dtype=float)
    if x.size == 0:
        return math.nan, math.nan, math.nan
    mean = float(x.mean())
    if x.size < 2:
        return mean, math.nan, math.nan
    half = float(stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    return mean, mean - half, mean + half


def _clopper_pearson(k: int, n: int) -> tuple[float, float]:
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    return float(ci.low), float(ci.high)


def _rows_of(rows: Iterable[Mapping]) -> list[dict]:
    out = []
    for i, row in enumerate(rows):
        try:
            out.append(
                {
                    "scenario": str(row["scenario"]),
                    "method": str(row["method"]),
                    "seed": int(row["seed"]),
                    "outcome": str(row["outcome"]),
                    "time_s": float(row["time_s"]),
                }
            )
        except (KeyError, TypeError, ValueError) as error:
            raise InputError(
                f"rows[{i}] must have scenario, method, seed, outcome and a numeric time_s ({error})"
            ) from None
    return out


def outcome_counts(rows: Iterable[Mapping]) -> list[dict]:
    """Per (scenario, method), in the order first seen: the outcomes and the travel time of the successes.

    Parameters
    ----------
    rows : iterable of mapping
        Episode rows with ``scenario, method, seed, outcome, time_s`` (`EpisodeRecord.row`
        or the run's ``episodes.csv``).

    Returns
    -------
    list of dict
        ``scenario, method, episodes, goals, collisions, off_road, timeouts, other,
        failures`` (collisions + off_road), ``failure_ci95`` (Clopper-Pearson) and
        ``time_mean_s, time_ci95`` over the goals (Student-t).
    """
    groups: dict[tuple[str, str], list[dict]] = {}
    for row in _rows_of(rows):
        groups.setdefault((row["scenario"], row["method"]), []).append(row)
    out = []
    for (scenario, method), members in groups.items():
        outcomes = [r["outcome"] for r in members]
        collisions, off_road = outcomes.count("collision"), outcomes.count("off_road")
        goals, timeouts = outcomes.count("goal"), outcomes.count("timeout")
        failures = collisions + off_road
        mean, low, high = _t_interval([r["time_s"] for r in members if r["outcome"] == "goal"])
        out.append(
            {
                "scenario": scenario,
                "method": method,
                "episodes": len(members),
                "goals": goals,
                "collisions": collisions,
                "off_road": off_road,
                "timeouts": timeouts,
                "other": len(members) - goals - collisions - off_road - timeouts,
                "failures": failures,
                "failure_ci95": _clopper_pearson(failures, len(members)),
                "time_mean_s": mean,
                "time_ci95": (low, high),
            }
        )
    return out


def paired_ratio(rows: Iterable[Mapping], scenario: str, method: str, reference: str) -> dict:
    """``time(method) / time(reference)`` over the seeds of ``scenario`` that both complete.

    Parameters
    ----------
    rows : iterable of mapping
        Episode rows (as `outcome_counts`).
    scenario, method, reference : str
        The world and the two methods.

    Returns
    -------
    dict
        ``pairs`` (the number of seeds both reached the goal on), ``mean`` and ``ci95``
        (Student-t) of the per-seed ratios, and the two methods' mean times over those
        seeds, ``method_time_s`` and ``reference_time_s``.
    """
    times: dict[str, dict[int, float]] = {method: {}, reference: {}}
    for row in _rows_of(rows):
        if row["scenario"] == scenario and row["method"] in times and row["outcome"] == "goal":
            times[row["method"]][row["seed"]] = row["time_s"]
    seeds = sorted(set(times[method]) & set(times[reference]))
    ratios = [times[method][s] / times[reference][s] for s in seeds]
    mean, low, high = _t_interval(ratios)
    return {
        "pairs": len(seeds),
        "mean": mean,
        "ci95": (low, high),
        "method_time_s": float(np.mean([times[method][s] for s in seeds])) if seeds else math.nan,
        "reference_time_s": float(np.mean([times[reference][s] for s in seeds])) if seeds else math.nan,
    }


def _fmt(x: float, digits: int = 1) -> str:
    return "-" if not math.isfinite(x) else f"{x:.{digits}f}"


def driving_markdown(rows: Iterable[Mapping], *, method: str = "robust", baselines: Sequence[str] = BASELINES) -> str:
    """Table 4 as Markdown: the outcome counts, then ``method``'s paired ratio against the faster baseline per world.

    Parameters
    ----------
    rows : iterable of mapping
        Episode rows of the driving worlds (others are ignored).
    method : str
        The method compared (default ``"robust"``).
    baselines : sequence of str
        The reference methods; per world the one with the smallest mean travel time
        over its successes is the reference.
    """
    rows = [r for r in _rows_of(rows) if r["scenario"] in DRIVING_SCENARIOS]
    counts = outcome_counts(rows)
    lines = [
        "| scenario | method | failures / episodes | failure 95% CI | collisions | off road | timeouts "
        "| travel time (s), successes | 95% CI |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for c in counts:
        low, high = c["failure_ci95"]
        t_low, t_high = c["time_ci95"]
        lines.append(
            f"| {c['scenario']} | {c['method']} | {c['failures']}/{c['episodes']} | [{low:.3f}, {high:.3f}] | "
            f"{c['collisions']} | {c['off_road']} | {c['timeouts']} | {_fmt(c['time_mean_s'])} | "
            f"[{_fmt(t_low)}, {_fmt(t_high)}] |"
        )
    lines += [
        "",
        f"Travel time of {method} against the faster of {', '.join(baselines)}, paired over the seeds both "
        "complete (per-seed ratio, mean and Student-t 95% interval):",
        "",
        "| scenario | reference | pairs | ratio | 95% CI | times (s) |",
        "|---|---|---|---|---|---|",
    ]
    for scenario in dict.fromkeys(c["scenario"] for c in counts):
        present = [c for c in counts if c["scenario"] == scenario and c["method"] in baselines]
        if not present or not any(c["scenario"] == scenario and c["method"] == method for c in counts):
            continue
        reference = min(present, key=lambda c: c["time_mean_s"] if math.isfinite(c["time_mean_s"]) else math.inf)
        ratio = paired_ratio(rows, scenario, method, reference["method"])
        low, high = ratio["ci95"]
        lines.append(
            f"| {scenario} | {reference['method']} | {ratio['pairs']} | {_fmt(ratio['mean'], 2)} | "
            f"[{_fmt(low, 2)}, {_fmt(high, 2)}] | {_fmt(ratio['method_time_s'])} vs "
            f"{_fmt(ratio['reference_time_s'])} |"
        )
    return "\n".join(lines) + "\n"


def write_driving_table(rows: Sequence[Mapping], out_dir: str | pathlib.Path) -> pathlib.Path | None:
    """Write ``table4.md`` (`driving_markdown`) into ``out_dir`` if ``rows`` hold driving episodes.

    Parameters
    ----------
    rows : sequence of mapping
        The run's episode rows.
    out_dir : str or path
        The run's output directory (it exists).

    Returns
    -------
    pathlib.Path or None
        The file written, or None for a run without driving episodes.
    """
    if not any(str(r["scenario"]) in DRIVING_SCENARIOS for r in rows):
        return None
    path = pathlib.Path(out_dir) / "table4.md"
    path.write_text(driving_markdown(rows))
    return path
