"""The ``minimaxplan`` console script: one subcommand per job.

Each subcommand lives in its own module of `minimaxplan.analysis` exposing
``register(subparsers)``, which adds its parser and sets ``func`` (args -> exit code).
"""

from __future__ import annotations

import argparse
import importlib
import sys

# Modules of minimaxplan.analysis that provide a subcommand, in help order.
SUBCOMMAND_MODULES = ["demo", "lmi_command", "select_command", "experiment_command", "suboptimality"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="minimaxplan",
        description="Robust motion planning under model uncertainty, with checked guarantees.",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(f"minimaxplan.analysis.{name}").register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
