"""The ``minimaxplan`` console script: one subcommand per job.

Each subcommand lives in its own module of `minimaxplan.analysis` exposing
``register(subparsers)``, which adds its parser and sets ``func`` (args -> exit code).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys

# The jobs here work on tiny matrices (p = 4) in parallel processes: BLAS threads only
# contend (L-BFGS-B in TEB ran ~10x slower with them on a busy machine). Set before
# numpy is first imported; an explicit setting of the user's wins.
for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

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


def _show_library_messages() -> None:
    """Show the library's INFO records on stderr, e.g. "compiling the planner's search kernel ..." on a first run."""
    logger = logging.getLogger("minimaxplan")
    if not logger.handlers:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("minimaxplan: %(message)s"))
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    _show_library_messages()
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
