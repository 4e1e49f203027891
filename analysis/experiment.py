"""Monte-Carlo experiments: many seeded episodes per method and world, run in parallel.

Scenarios and methods are the registered ones (`minimaxplan.analysis.registry`).
Episodes are independent, so they run on a local process pool by default or on a Dask
cluster (``dask_address``) for a user who outgrows one machine; both give identical
records because every episode is a pure function of ``(scenario, method, seed, config)``
and each job carries the factories of its scenario and method (`EpisodeJob`).
"""

from __future__ import annotations

import concurrent.futures
import csv
import json
import math
import os
import pathlib
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy import stats

from minimaxplan.models.errors import InputError, MinimaxplanError
from minimaxplan.models.validation import as_count

from . import registry
from .driving_table import write_driving_table
from .episode import DEFAULT_CONFIG, EpisodeJob, EpisodeRecord, LoopConfig, make_job, run_job
from .numerical_environment import numerical_environment
from .registry import UnsupportedScenario, resolve, scenario_factory

__all__ = [
    "ClusterUnavailable",
    "DASK_CONNECT_TIMEOUT_S",
    "ExperimentResult",
    "episode_seeds",
    "run_experiment",
    "summarise",
    "supported_methods",
    "write_outputs",
]


#: Seconds to wait for a Dask scheduler to answer before giving up (a reachable one
#: answers in milliseconds; distributed's own default is 30 s).
DASK_CONNECT_TIMEOUT_S = 5.0


class ClusterUnavailable(MinimaxplanError, ConnectionError):
    """The Dask scheduler given as ``dask_address`` cannot be reached (or the address is malformed).

    Raised by `run_experiment` before any episode runs, within
    `DASK_CONNECT_TIMEOUT_S` seconds.
    """


@dataclass(frozen=True)
class ExperimentResult:
    """Every `EpisodeRecord` in job order, the `summarise` records, and the run's wall time.

    Attributes
    ----------
    records : tuple of EpisodeRecord
        One per episode, in job order (scenario, then method, then seed).
    summary : tuple of dict
        The `summarise` records, one per (scenario, method).
    wall_time_s : float
        Wall time of the episodes, in seconds.
    """

    records: tuple[EpisodeRecord, ...]
    summary: tuple[dict, ...]
    wall_time_s: float


def episode_seeds(seed: int, episodes: int) -> list[int]:
    """The world seeds of a run: episode i of every method uses ``seed + i`` (paired comparison).

    Parameters
    ----------
    seed : int
        World seed of the first episode.
    episodes : int
        Number of episodes.

    Returns
    -------
    list of int
        ``[seed, seed + 1, ..., seed + episodes - 1]``.
    """
    return [seed + i for i in range(episodes)]


def _failure_interval(failures: int, episodes: int) -> tuple[float, float]:
    """Exact (Clopper-Pearson) 95% interval of the failure probability."""
    ci = stats.binomtest(failures, episodes).proportion_ci(confidence_level=0.95, method="exact")
    return (float(ci.low), float(ci.high))


def summarise(records: Iterable[EpisodeRecord]) -> list[dict]:
    """One summary record per (scenario, method), in the order first seen.

    Parameters
    ----------
    records : iterable of EpisodeRecord
        The episodes to summarise.

    Returns
    -------
    list of dict
        Per (scenario, method): ``episodes``, ``failures``, ``failure_ci95`` (exact
        Clopper-Pearson 95% interval), ``outcomes`` (counts), ``mean_time_s``,
        ``median_time_s`` and ``max_time_s`` (seconds, over the episodes that reached
        the goal, as in the paper's Table 3; NaN if none did), ``mean_return``
        (over all episodes), and ``boxes_checked`` and ``boxes_missed``: the run-time
        check's counts summed over the episodes (`minimaxplan.analysis.episode.BoxCheck`;
        0 for a method that predicts nothing).
    """
    groups: dict[tuple[str, str], list[EpisodeRecord]] = {}
    for record in records:
        groups.setdefault((record.scenario, record.method), []).append(record)
    summary = []
    for (scenario, method), group in groups.items():
        times = np.array([r.time_s for r in group if r.success])
        failures = sum(not r.success for r in group)
        low, high = _failure_interval(failures, len(group))
        outcomes: dict[str, int] = {}
        for r in group:
            outcomes[r.outcome] = outcomes.get(r.outcome, 0) + 1
        summary.append(
            {
                "scenario": scenario,
                "method": method,
                "episodes": len(group),
                "failures": failures,
                "failure_ci95": [low, high],
                "outcomes": dict(sorted(outcomes.items())),
                "mean_time_s": float(times.mean()) if times.size else math.nan,
                "median_time_s": float(np.median(times)) if times.size else math.nan,
                "max_time_s": float(times.max()) if times.size else math.nan,
                "mean_return": float(np.mean([r.discounted_return for r in group])),
                "boxes_checked": int(sum(r.boxes_checked for r in group)),
                "boxes_missed": int(sum(r.boxes_missed for r in group)),
            }
        )
    return summary


def supported_methods(scenarios: Sequence[str], config: LoopConfig = DEFAULT_CONFIG) -> list[str]:
    """The registered methods that support every scenario named, in registration order.

    What a run that names no method runs (``minimaxplan experiment`` without
    ``--methods``, ``minimaxplan demo``): a method registered for other worlds only (the
    ``idm`` ego of the highway-env scenarios) is left out instead of failing the run.

    Parameters
    ----------
    scenarios : sequence of str
        Registered scenario names.
    config : LoopConfig
        The loop settings the methods' factories are asked with.

    Returns
    -------
    list of str

    Raises
    ------
    UnknownScenario
        If a name is not registered.
    InputError
        If no scenario is named, or no registered method supports them all.
    """
    if not scenarios:
        raise InputError("scenarios must name at least one scenario, got none")
    built = [resolve(scenario_factory(name))() for name in scenarios]
    names = []
    for name in registry.method_names():
        try:
            for instance in built:
                registry.method_factory(name, instance, config)
        except UnsupportedScenario:
            continue
        names.append(name)
    if not names:
        raise InputError(f"no registered method supports every one of the scenarios {list(scenarios)}")
    return names


def _jobs(
    scenarios: Sequence[str], methods: Sequence[str], episodes: int, seed: int, config: LoopConfig
) -> list[EpisodeJob]:
    """Every job in order (scenario, then method, then seed), names checked before any runs."""
    as_count("episodes", episodes)
    as_count("seed", seed, minimum=0)
    if not scenarios or not methods:
        raise InputError(f"at least one scenario and one method are needed, got {list(scenarios)} and {list(methods)}")
    jobs = []
    for s in scenarios:
        built = resolve(scenario_factory(s))()
        for m in methods:
            template = make_job(s, m, seed, config, built=built)
            jobs += [replace(template, seed=k) for k in episode_seeds(seed, episodes)]
    return jobs


def run_experiment(
    scenarios: Sequence[str],
    methods: Sequence[str],
    *,
    episodes: int,
    seed: int = 0,
    config: LoopConfig = DEFAULT_CONFIG,
    workers: int | None = None,
    dask_address: str | None = None,
    progress: bool = True,
) -> ExperimentResult:
    """Run ``episodes`` seeded episodes of every method in every scenario.

    Parameters
    ----------
    scenarios, methods : sequence of str
        Registered names (`register_scenario`, `register_method`); every method must
        support every scenario.
    episodes : int
        Episodes per method and scenario (>= 1).
    seed : int
        World seed of the first episode (>= 0); episode i of every method uses world
        seed ``seed + i`` (paired comparison).
    config : LoopConfig
        The loop settings of every episode.
    workers : int, optional
        Local processes (>= 1; default: all cores). Ignored with ``dask_address``.
    dask_address : str, optional
        Address of a Dask scheduler (the ``cluster`` extra); episodes are mapped there.
    progress : bool
        Show a progress bar (tqdm, on stderr).

    Returns
    -------
    ExperimentResult
        The records in job order, their summary and the wall time.

    Raises
    ------
    InputError
        Before any episode runs, if ``episodes``, ``seed`` or ``workers`` is not an
        integer in range, or no scenario or method is given.
    UnknownScenario, UnknownMethod, UnsupportedScenario
        Before any episode runs, if a name is not registered or a method does not
        support a scenario (the message names the registered names).
    ClusterUnavailable
        Before any episode runs, if the scheduler at ``dask_address`` does not answer
        within `DASK_CONNECT_TIMEOUT_S` seconds.
    """
    workers = (os.cpu_count() or 1) if workers is None else as_count("workers", workers)
    jobs = _jobs(scenarios, methods, episodes, seed, config)
    client = None if dask_address is None else _connect(dask_address)
    started = time.perf_counter()
    try:
        completed = _run_jobs(jobs, workers, client, progress)
    finally:
        if client is not None:
            client.close()
    # Order is by job, not by completion, so that the same seed gives the same output.
    order = {job.key: n for n, job in enumerate(jobs)}
    records = tuple(sorted(completed, key=lambda r: order[(r.scenario, r.method, r.seed)]))
    return ExperimentResult(records, tuple(summarise(records)), time.perf_counter() - started)


def _progress_bar(total: int, enabled: bool):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc="episodes", unit="ep", disable=not enabled)


def _connect(address: str) -> Any:
    """A `distributed.Client` of the scheduler at ``address``, or `ClusterUnavailable`."""
    from distributed import Client

    try:
        return Client(address, timeout=DASK_CONNECT_TIMEOUT_S)
    except (OSError, ValueError, TypeError) as exc:
        raise ClusterUnavailable(
            f"cannot reach the Dask scheduler at {address!r} within {DASK_CONNECT_TIMEOUT_S:g} s: {exc}"
        ) from None


def _run_jobs(jobs: list[EpisodeJob], workers: int, client: Any, progress: bool) -> list[EpisodeRecord]:
    bar = _progress_bar(len(jobs), progress)
    records: list[EpisodeRecord] = []
    try:
        if client is not None:
            from distributed import as_completed

            futures = [client.submit(run_job, job, pure=False) for job in jobs]
            for future in as_completed(futures):
                records.append(future.result())
                bar.update()
        elif workers == 1:
            for job in jobs:
                records.append(run_job(job))
                bar.update()
        else:
            with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
                futures = [pool.submit(run_job, job) for job in jobs]
                for future in concurrent.futures.as_completed(futures):
                    records.append(future.result())
                    bar.update()
    finally:
        bar.close()
    return records


def _fmt(x: float, digits: int = 1) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def _boxes(summary: dict) -> str:
    checked = summary["boxes_checked"]
    return f"{summary['boxes_missed']}/{checked}" if checked else "-"


def markdown_table(summary: Sequence[dict]) -> str:
    """The summary laid out like the paper's Table 3, with the run-time check's counts.

    The last column is ``boxes_missed / boxes_checked`` ("-" for a method that predicts
    no box).
    """
    lines = [
        "| scenario | method | failures / episodes | failure 95% CI | mean time (s) | median time (s) | max time (s) "
        "| mean return | boxes missed / checked |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for s in summary:
        low, high = s["failure_ci95"]
        lines.append(
            f"| {s['scenario']} | {s['method']} | {s['failures']}/{s['episodes']} | "
            f"[{low:.3f}, {high:.3f}] | {_fmt(s['mean_time_s'])} | {_fmt(s['median_time_s'])} | "
            f"{_fmt(s['max_time_s'])} | {s['mean_return']:.3f} | {_boxes(s)} |"
        )
    return "\n".join(lines) + "\n"


def write_outputs(result: ExperimentResult, out_dir: str | os.PathLike) -> pathlib.Path:
    """Write summary.json, episodes.csv, table.md and environment.json (and table4.md for driving runs) into ``out_dir``.

    ``environment.json`` is `numerical_environment` of the writing process: the CPU,
    numpy's SIMD targets and the BLAS kernels its floating-point results depend on, and
    whether they are the ones the committed records are made with (the episodes of a run
    on Dask workers ran in the workers' environment, which it does not describe).

    Parameters
    ----------
    result : ExperimentResult
        The run to write (at least one record).
    out_dir : str or os.PathLike
        The output directory, created (with its parents) if missing.

    Returns
    -------
    pathlib.Path
        The output directory.
    """
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(list(result.summary), indent=2, allow_nan=True) + "\n")
    rows = [r.row() for r in result.records]
    with open(out / "episodes.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    (out / "table.md").write_text(
        markdown_table(result.summary)
        + assumption4_note(result.records)
        + f"\nWall time of the run: {result.wall_time_s:.1f} s\n"
    )
    write_driving_table(rows, out)
    (out / "environment.json").write_text(json.dumps(numerical_environment(), indent=2) + "\n")
    return out


def assumption4_note(records: Sequence[EpisodeRecord]) -> str:
    """How the once-per-episode Assumption 4 reports of the robust method came out."""
    reports = [r.extra["lmi"] for r in records if r.extra.get("lmi")]
    if not reports:
        return ""
    certified = sum(rep["velocity_subsystem"] == "feasible" and rep["velocity_certified"] for rep in reports)
    infeasible = sum(rep["full_model"] == "infeasible" for rep in reports)
    return (
        f"\nAssumption 4 (robust method, once per episode, discrete LMI over the parameter box's vertices): "
        f"velocity subsystem feasible and certified in {certified}/{len(reports)} "
        f"episodes; full model infeasible in {infeasible}/{len(reports)} "
        f"(its integrators make that expected, and Theorem 2 does not apply to it).\n"
    )
