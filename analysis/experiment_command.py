"""``minimaxplan experiment``: the paper's Table 3 experiment.

``--scenario`` and ``--methods`` accept every registered name
(`minimaxplan.analysis.register_scenario`, `register_method`); an unknown name, or a
method that does not support a scenario, exits 2 with one line naming the known names.
Every other option is checked while parsing (`minimaxplan.analysis.arguments`), and a
Dask scheduler that cannot be reached within `DASK_CONNECT_TIMEOUT_S` exits 2 with one
line, all before the first episode runs.
"""

from __future__ import annotations

import argparse
import pathlib
from collections.abc import Sequence

from .arguments import Subcommand, count, name_list, output_directory, report_error

__all__ = ["COMMAND", "run_and_report"]


def run_and_report(
    scenarios: Sequence[str],
    methods: Sequence[str],
    *,
    episodes: int,
    seed: int,
    workers: int | None,
    dask_address: str | None,
    out: pathlib.Path,
    progress: bool = True,
    plot_seeds: int = 3,
) -> tuple[str, pathlib.Path]:
    """Run the experiment, write every output into ``out`` and return the Markdown table.

    Parameters
    ----------
    scenarios, methods : sequence of str
        Registered scenario and method names.
    episodes : int
        Episodes per method and scenario (>= 1).
    seed : int
        World seed of the first episode (>= 0); episode i uses ``seed + i``.
    workers : int or None
        Local processes (default: all cores); ignored with ``dask_address``.
    dask_address : str or None
        Address of a Dask scheduler to run the episodes on.
    out : pathlib.Path
        Output directory (created if needed).
    progress : bool
        Show a progress bar on stderr.
    plot_seeds : int
        How many episodes per scenario the trajectory plots show.

    Returns
    -------
    table : str
        The Table 3 layout (Markdown) and the run's wall time.
    out : pathlib.Path
        The directory the outputs were written to.

    Raises
    ------
    UnknownScenario, UnknownMethod, UnsupportedScenario
        Before any episode runs, for a name that is not registered.
    ClusterUnavailable
        Before any episode runs, if the Dask scheduler cannot be reached.
    """
    from .experiment import markdown_table, run_experiment, write_outputs
    from .plots import plot_experiment

    result = run_experiment(
        scenarios, methods, episodes=episodes, seed=seed, workers=workers, dask_address=dask_address, progress=progress
    )
    out = write_outputs(result, out)
    plot_experiment(result.records, out, scenarios=scenarios, plot_seeds=plot_seeds)
    table = markdown_table(result.summary) + f"\nWall time of the run: {result.wall_time_s:.1f} s\n"
    return table, out


def _run(args: argparse.Namespace) -> int:
    from minimaxplan.models import MinimaxplanError

    from .experiment import supported_methods
    from .registry import UnknownMethod, UnknownScenario, UnsupportedScenario, default_scenario_names

    try:
        scenarios = args.scenario or default_scenario_names()
        table, out = run_and_report(
            scenarios,
            args.methods or supported_methods(scenarios),
            episodes=args.episodes,
            seed=args.seed,
            workers=args.workers,
            dask_address=args.dask,
            out=args.out,
            progress=not args.no_progress,
        )
    except UnknownScenario as exc:  # raised before any episode runs, like the two below
        return report_error("experiment", exc, option="--scenario")
    except (UnknownMethod, UnsupportedScenario) as exc:
        return report_error("experiment", exc, option="--methods")
    except MinimaxplanError as exc:
        return report_error("experiment", exc)
    print(table)
    print(f"outputs written to {out}/")
    return 0


def _add_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--scenario",
        type=name_list,
        default=None,
        help="comma-separated registered scenarios (default: those of the default runs, static,pedestrian,highway,"
        "tjunction; the optional highway-env: ones only by name)",
    )
    parser.add_argument(
        "--methods",
        type=name_list,
        default=None,
        help="comma-separated registered methods (default: every registered method that supports every scenario "
        "of the run, e.g. robust,nominal,oracle,dwa,teb)",
    )
    parser.add_argument("--episodes", type=count(1), default=100, help="episodes per method and scenario (>= 1)")
    parser.add_argument(
        "--seed", type=count(0), default=0, help="world seed of the first episode (>= 0); episode i uses SEED + i"
    )
    parser.add_argument("--workers", type=count(1), default=None, help="local processes (>= 1; default: all cores)")
    parser.add_argument(
        "--dask",
        metavar="ADDRESS",
        default=None,
        help="run on the Dask scheduler at this address instead (the 'cluster' extra)",
    )
    parser.add_argument("--out", type=output_directory, default=pathlib.Path("out/experiment"), help="output directory")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


COMMAND = Subcommand(
    "experiment",
    help="Monte-Carlo episodes per method and world (Table 3)",
    description="Run seeded episodes of every method in every scenario and write the Table 3 "
    "summary, the per-episode records and trajectory plots. A run has EPISODES x scenarios x "
    "methods episodes, by default of the default runs' scenarios and every method that supports them "
    "all (e.g. 100 x 4 worlds x 5 methods = 2,000 episodes); the progress bar shows the total.",
    epilog="Exit codes: 0 done; 2 a bad option, an unknown name or an unreachable Dask scheduler "
    "(one line on stderr, before any episode runs).",
    add_options=_add_options,
    run=_run,
)
