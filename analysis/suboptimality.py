"""The Figure 6 analogue: suboptimality of the robust planner against the number of samples N.

For each N, the robust planner learns only from N transitions of excitation data
recorded before the episode (model elimination and LP parameter boxes, then frozen),
and drives the robot for a fixed number of decisions from the start of a static world.
The oracle planner (OPD on the true friction, same K) drives the same world, whose
disturbance and measurement-noise sequences are identical for both (they are seeded by
the world, not by the actions). Suboptimality is the oracle's discounted return minus
the robust planner's over those decisions, ``r_i`` being the smallest true goal reward
over the sub-steps of decision i.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
from collections.abc import Iterable, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from .arguments import Subcommand, count, count_list, output_directory, report_error

if TYPE_CHECKING:
    from .episode import LoopConfig

__all__ = [
    "suboptimality_study",
    "fit_trend",
    "degenerate_fit",
    "plot_study",
    "draw_suboptimality",
    "markdown",
    "COMMAND",
    "DEFAULT_SAMPLES",
    "DEFAULT_EPISODES",
    "DEFAULT_HORIZON",
    "ROAD_SCENARIOS",
    "TREND_PARAMETERS",
]

#: The values of N of the default study.
DEFAULT_SAMPLES = (2, 5, 10, 20, 50, 100, 200, 400)
#: Episodes per N of the default study.
DEFAULT_EPISODES = 20
#: Decisions per episode of the default study.
DEFAULT_HORIZON = 24
#: The number of parameters (a, b) of the trend ``a + b log(N) / N``.
TREND_PARAMETERS = 2


def fit_trend(ns: Sequence[float], values: Sequence[float]) -> dict:
    """Least-squares fit of ``a + b log(N) / N`` to suboptimality values, or why there is none.

    Parameters
    ----------
    ns : sequence of float
        The numbers of samples N (> 0).
    values : sequence of float
        The suboptimality observed at each N.

    Returns
    -------
    dict
        ``{"a": a, "b": b, "warning": None}``; for a degenerate fit ``{"a": None, "b":
        None, "warning": REASON}``, where REASON says why (`degenerate_fit`).

    Notes
    -----
    ``log(N) / N`` is the shape of the estimation term of eq. (14) (Theorem 2).
    """
    import numpy as np

    warning = degenerate_fit(ns, values)
    if warning is not None:
        return {"a": None, "b": None, "warning": warning}
    n = np.asarray(ns, dtype=float)
    design = np.stack([np.ones_like(n), np.log(n) / n], axis=1)
    coef, *_ = np.linalg.lstsq(design, np.asarray(values, dtype=float), rcond=None)
    return {"a": float(coef[0]), "b": float(coef[1]), "warning": None}


def degenerate_fit(ns: Sequence[float], values: Sequence[float]) -> str | None:
    """Why the trend ``a + b log(N) / N`` cannot be fitted to these points, or None if it can.

    Parameters
    ----------
    ns : sequence of float
        The numbers of samples N.
    values : sequence of float
        The suboptimality observed at each N.

    Returns
    -------
    str or None
        A sentence when the fit is degenerate: fewer distinct values of N than the
        fit's `TREND_PARAMETERS` parameters (the least-squares problem has no unique
        solution), or every value zero (the robust planner matched the oracle at every
        N: nothing to fit, and "0 + 0 log(N)/N" would read as a measured trend).
    """
    import numpy as np

    n = np.asarray(ns, dtype=float)
    v = np.asarray(values, dtype=float)
    distinct = np.unique(n).size
    if distinct < TREND_PARAMETERS:
        return (
            f"no trend fitted: {distinct} distinct value(s) of N, fewer than the {TREND_PARAMETERS} "
            "parameters of a + b log(N)/N"
        )
    if not np.any(v):
        return (
            f"no trend fitted: the suboptimality is exactly 0 at all {v.size} values of N "
            "(the robust planner matched the oracle's return every time)"
        )
    return None


def suboptimality_study(
    samples: Iterable[int] = DEFAULT_SAMPLES,
    *,
    episodes: int = DEFAULT_EPISODES,
    seed: int = 0,
    horizon: int = DEFAULT_HORIZON,
    scenario: str = "static",
    workers: int | None = None,
    progress: bool = True,
    config: LoopConfig | None = None,
) -> dict:
    """Run the study: the robust planner's suboptimality against the oracle for each N.

    Parameters
    ----------
    samples : iterable of int
        The numbers N of excitation transitions the robust planner learns from (each >= 1).
    episodes : int
        Episodes per N (>= 1), world seeds ``seed .. seed + episodes - 1``.
    seed : int
        World seed of the first episode (>= 0).
    horizon : int
        Decisions per episode (>= 1).
    scenario : str
        A registered scenario.
    workers : int, optional
        Local processes (>= 1; default: all cores).
    progress : bool
        Show progress bars.
    config : LoopConfig, optional
        Loop settings (default: `episode.DEFAULT_CONFIG`); ``max_decisions`` and
        ``prior_samples`` are overridden.

    Returns
    -------
    dict
        ``scenario``, ``episodes``, ``horizon_decisions``, ``seed``, ``rows`` (per N:
        ``mean``, ``max``, ``min``, ``per_episode`` suboptimality and ``failures``) and
        ``fit`` (`fit_trend` of the means; its ``warning`` says why when no trend
        can be fitted).

    Raises
    ------
    InputError
        Before any episode runs, if a value of ``samples``, ``episodes``, ``seed``,
        ``horizon`` or ``workers`` is out of range.

    Notes
    -----
    The Figure 6 analogue; the trend is the ``log(N) / N`` term of eq. (14).
    """
    import numpy as np

    from minimaxplan.models.errors import InputError
    from minimaxplan.models.validation import as_count

    from .episode import DEFAULT_CONFIG
    from .experiment import run_experiment

    if isinstance(samples, (str, bytes)) or not isinstance(samples, Iterable):
        raise InputError(f"samples must be a non-empty sequence of positive integers, got {samples!r}")
    samples = [as_count(f"samples[{i}]", n) for i, n in enumerate(samples)]
    if not samples:
        raise InputError("samples must be a non-empty sequence of positive integers, got none")
    as_count("episodes", episodes)
    as_count("seed", seed, minimum=0)
    horizon = as_count("horizon", horizon)
    if workers is not None:
        as_count("workers", workers)
    base = replace(DEFAULT_CONFIG if config is None else config, max_decisions=horizon)
    oracle = run_experiment(
        [scenario], ["oracle"], episodes=episodes, seed=seed, config=base, workers=workers, progress=progress
    )
    oracle_return = {r.seed: r.discounted_return for r in oracle.records}
    rows: list[dict[str, Any]] = []
    for n in samples:
        robust = run_experiment(
            [scenario],
            ["robust"],
            episodes=episodes,
            seed=seed,
            config=replace(base, prior_samples=n),
            workers=workers,
            progress=progress,
        )
        gaps = [oracle_return[r.seed] - r.discounted_return for r in robust.records]
        outcomes = [r.outcome for r in robust.records]
        rows.append(
            {
                "n": n,
                "mean": float(np.mean(gaps)),
                "max": float(np.max(gaps)),
                "min": float(np.min(gaps)),
                "per_episode": gaps,
                "failures": sum(o not in ("goal", "horizon") for o in outcomes),
            }
        )
    return {
        "scenario": scenario,
        "episodes": episodes,
        "horizon_decisions": horizon,
        "seed": seed,
        "rows": rows,
        "fit": fit_trend([r["n"] for r in rows], [r["mean"] for r in rows]),
    }


def plot_study(study: dict, path: str | pathlib.Path) -> pathlib.Path:
    """Plot a study's mean and max suboptimality against N, with the fitted trend.

    Parameters
    ----------
    study : dict
        A `suboptimality_study` result.
    path : str or pathlib.Path
        The image file to write (PNG).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from .figures import draw_png

    def draw(ax: Any) -> None:
        draw_suboptimality(ax, study)
        ax.set_title(f"Suboptimality over {study['horizon_decisions']} decisions, {study['episodes']} episodes")

    return draw_png(draw, path, figsize=(6, 4))


def draw_suboptimality(ax: Any, study: dict) -> None:
    """Draw a study's mean and max suboptimality against N, and its trend or warning, on ``ax``.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        The axes (log N on x); no title is set.
    study : dict
        A study with ``rows`` (``n``, ``mean``, ``max``) and ``fit`` (`fit_trend`), as
        `suboptimality_study` and `road_suboptimality.road_suboptimality_study` return.
    """
    import numpy as np

    n = np.array([r["n"] for r in study["rows"]], dtype=float)
    ax.plot(n, [r["mean"] for r in study["rows"]], "o-", label="mean over episodes")
    ax.plot(n, [r["max"] for r in study["rows"]], "s--", label="max over episodes")
    fit = study["fit"]
    if fit.get("warning") is None:
        grid = np.geomspace(n.min(), n.max(), 200)
        ax.plot(grid, fit["a"] + fit["b"] * np.log(grid) / grid, "k:", label="fit a + b log(N)/N")
    else:
        ax.text(0.02, 0.02, fit["warning"], transform=ax.transAxes, fontsize="small", color="tab:red", wrap=True)
    ax.set_xscale("log")
    ax.set_xlabel("N, transitions observed before planning")
    ax.set_ylabel("oracle return - robust return")
    ax.legend()


def markdown(study: dict) -> str:
    """A study as a Markdown table, one row per N, and the fitted trend.

    Parameters
    ----------
    study : dict
        A `suboptimality_study` result.

    Returns
    -------
    str
        The table and the trend line.
    """
    lines = ["| N | mean suboptimality | max | min | failures |", "|---:|---:|---:|---:|---:|"]
    for r in study["rows"]:
        lines.append(
            f"| {r['n']} | {r['mean']:.4f} | {r['max']:.4f} | {r['min']:.4f} | {r['failures']}/{study['episodes']} |"
        )
    fit = study["fit"]
    if fit.get("warning") is None:
        lines.append(f"\nTrend fit: suboptimality ~ {fit['a']:.4f} + {fit['b']:.4f} log(N)/N")
    else:
        lines.append(f"\n**Warning: {fit['warning']}.**")
    return "\n".join(lines) + "\n"


#: The worlds of the road study (`minimaxplan.scenarios.road_world.ROAD_WORLD_KINDS`,
#: named here so that ``--help`` imports neither numpy nor the road modules).
ROAD_SCENARIOS = ("highway", "tjunction")
#: The robot's world of the default study.
ROBOT_SCENARIO = "static"


def _run(args: argparse.Namespace) -> int:
    from minimaxplan.models import MinimaxplanError

    from .registry import UnknownScenario, UnsupportedScenario

    road = args.scenario in ROAD_SCENARIOS
    samples: Sequence[int] = DEFAULT_SAMPLES
    episodes, horizon = DEFAULT_EPISODES, DEFAULT_HORIZON
    out = pathlib.Path("out/suboptimality")
    if road:
        from . import road_suboptimality as study_module

        samples = study_module.ROAD_DEFAULT_SAMPLES
        episodes, horizon = study_module.ROAD_DEFAULT_EPISODES, study_module.ROAD_DEFAULT_HORIZON
        out = pathlib.Path(f"out/suboptimality-{args.scenario}")
    samples = samples if args.samples is None else args.samples
    episodes = episodes if args.episodes is None else args.episodes
    horizon = horizon if args.horizon is None else args.horizon
    out = out if args.out is None else pathlib.Path(args.out)
    try:
        if road:
            study = study_module.road_suboptimality_study(
                args.scenario,
                samples,
                episodes=episodes,
                seed=args.seed,
                horizon=horizon,
                workers=args.workers,
                progress=not args.no_progress,
            )
            text = study_module.road_markdown(study)
        else:
            study = suboptimality_study(
                samples,
                episodes=episodes,
                seed=args.seed,
                horizon=horizon,
                workers=args.workers,
                progress=not args.no_progress,
                **({} if args.scenario == ROBOT_SCENARIO else {"scenario": args.scenario}),
            )
            text = markdown(study)
    except (UnknownScenario, UnsupportedScenario) as exc:
        return report_error("suboptimality", exc, option="--scenario")
    except MinimaxplanError as exc:
        return report_error("suboptimality", exc)
    out.mkdir(parents=True, exist_ok=True)
    (out / "suboptimality.json").write_text(json.dumps(study, indent=2) + "\n")
    (out / "suboptimality.md").write_text(text)
    if road:
        study_module.plot_road_study(study, out / "suboptimality.png")
    else:
        plot_study(study, out / "suboptimality.png")
    if study["fit"].get("warning") is not None:
        print(f"minimaxplan suboptimality: warning: {study['fit']['warning']}", file=sys.stderr)
    print(text)
    print(f"outputs written to {out}/")
    return 0


def _add_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--scenario",
        default=ROBOT_SCENARIO,
        help=f"the world: a robot scenario (default: {ROBOT_SCENARIO}) or a road world ({', '.join(ROAD_SCENARIOS)})",
    )
    parser.add_argument(
        "--samples",
        type=count_list(1),
        default=None,
        help=f"comma-separated values of N, each >= 1 (default: {','.join(map(str, DEFAULT_SAMPLES))}); "
        "the road worlds: 1,2,5,10,20,50",
    )
    parser.add_argument(
        "--episodes",
        type=count(1),
        default=None,
        help=f"episodes per value of N, >= 1 (default: {DEFAULT_EPISODES}); the road worlds: 10",
    )
    parser.add_argument(
        "--horizon",
        type=count(1),
        default=None,
        help=f"decisions per episode, >= 1 (default: {DEFAULT_HORIZON}); the road worlds: 10",
    )
    parser.add_argument("--seed", type=count(0), default=0, help="world seed of the first episode (>= 0)")
    parser.add_argument("--workers", type=count(1), default=None, help="local processes (>= 1; default: all cores)")
    parser.add_argument(
        "--out",
        type=output_directory,
        default=None,
        help="output directory (default: out/suboptimality); the road worlds: out/suboptimality-SCENARIO",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


COMMAND = Subcommand(
    "suboptimality",
    help="Figure 6: suboptimality against the number of samples N",
    description="For each N, run EPISODES robust episodes that learn from N prior transitions, "
    "and EPISODES oracle episodes on the same worlds; report the oracle's return minus the robust "
    "planner's. A run has EPISODES x (1 + number of values of N) episodes (180 with the defaults). "
    "With --scenario highway or tjunction (the road worlds), each world first runs N sub-steps with "
    "the ego holding IDLE; the robust method learns from those N transitions per vehicle, then its "
    "beliefs are frozen, and it and the oracle each drive HORIZON decisions from that same state "
    "(EPISODES x 2 x number of values of N episodes; 120 with the road defaults); the outputs add "
    "the failures of both, their mean speeds and the run-time check of the robust boxes.",
    epilog="Exit codes: 0 done; 2 a bad option (one line on stderr, before any episode runs).",
    add_options=_add_options,
    run=_run,
)
