"""``minimaxplan experiment``: the paper's Table 3 experiment.

``--scenario`` and ``--methods`` accept every registered name
(`minimaxplan.analysis.register_scenario`, `register_method`); an unknown name, or a
method that does not support a scenario, exits 2 with one line naming the known names.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

from .experiment import markdown_table, run_experiment, write_outputs
from .plots import plot_trajectories
from .registry import UnknownMethod, UnknownScenario, UnsupportedScenario, method_names, scenario_names

__all__ = ["register", "run_and_report"]


def _csv_list(text: str) -> list[str]:
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items:
        raise argparse.ArgumentTypeError(f"expected comma-separated names, got {text!r}")
    return items


def run_and_report(scenarios, methods, *, episodes, seed, workers, dask_address, out, progress=True,
                   plot_seeds: int = 3) -> tuple[str, pathlib.Path]:
    """Run the experiment, write every output into ``out`` and return the Markdown table."""
    result = run_experiment(scenarios, methods, episodes=episodes, seed=seed, workers=workers,
                            dask_address=dask_address, progress=progress)
    out = write_outputs(result, out)
    for scenario in scenarios:
        shown = sorted({r.seed for r in result.records if r.scenario == scenario})[:plot_seeds]
        records = [r for r in result.records if r.scenario == scenario and r.seed in shown]
        plot_trajectories(records, out / f"trajectories_{scenario}.png")
    table = markdown_table(result.summary) + f"\nWall time of the run: {result.wall_time_s:.1f} s\n"
    return table, out


def _run(args: argparse.Namespace) -> int:
    try:
        table, out = run_and_report(args.scenario or scenario_names(), args.methods or method_names(),
                                    episodes=args.episodes, seed=args.seed, workers=args.workers,
                                    dask_address=args.dask, out=args.out, progress=not args.no_progress)
    except (UnknownScenario, UnknownMethod, UnsupportedScenario) as exc:
        print(f"minimaxplan experiment: error: {exc}", file=sys.stderr)
        return 2
    print(table)
    print(f"outputs written to {out}/")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("experiment", help="Monte-Carlo episodes per method and world (Table 3)")
    parser.add_argument("--scenario", type=_csv_list, default=None,
                        help="comma-separated registered scenarios (default: all, e.g. static,pedestrian)")
    parser.add_argument("--methods", type=_csv_list, default=None,
                        help="comma-separated registered methods (default: all, e.g. robust,nominal,oracle,dwa,teb)")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per method and world")
    parser.add_argument("--seed", type=int, default=0, help="world seed of the first episode")
    parser.add_argument("--workers", type=int, default=None, help="local processes (default: all cores)")
    parser.add_argument("--dask", metavar="ADDRESS", default=None, help="run on this Dask scheduler instead")
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("out/experiment"))
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(func=_run)
