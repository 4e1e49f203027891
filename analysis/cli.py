"""The ``minimaxplan`` console script: one subcommand per job.

Each subcommand lives in its own module of `minimaxplan.analysis` exposing
``COMMAND``, a `minimaxplan.analysis.arguments.Subcommand` (its texts, its options and
its job, args -> exit code).
Those modules import only the standard library at their top, and the library (numpy,
scipy, cvxpy, numba) inside ``func``, so that ``minimaxplan --help`` and a usage error
cost no heavy import. Every option is checked while parsing (`minimaxplan.analysis.arguments`):
a bad value exits 2 with one line on stderr naming the option, before any work.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys

from .arguments import CommandParser

__all__ = ["build_parser", "main", "SUBCOMMAND_MODULES"]

# The jobs here work on tiny matrices (p = 4) in parallel processes: BLAS threads only
# contend (L-BFGS-B in TEB ran ~10x slower with them on a busy machine). Set before
# numpy is first imported; an explicit setting of the user's wins.
for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

#: Modules of minimaxplan.analysis that provide a subcommand, in help order.
SUBCOMMAND_MODULES = (
    "demo",
    "lmi_command",
    "select_command",
    "experiment_command",
    "suboptimality",
    "sweep",
    "animate",
)


def build_parser() -> argparse.ArgumentParser:
    """The parser of the ``minimaxplan`` command and all its subcommands.

    Returns
    -------
    argparse.ArgumentParser
        A `CommandParser`; each subcommand's parser is stored as the ``parser`` default
        of its namespace, so that `main` reports a stray argument in that subcommand's
        words.
    """
    parser = CommandParser(
        prog="minimaxplan",
        description="Robust motion planning under model uncertainty, with checked guarantees.",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(f"minimaxplan.analysis.{name}").COMMAND.add_to(subparsers)
    for subparser in subparsers.choices.values():
        subparser.set_defaults(parser=subparser)
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
    """Run the ``minimaxplan`` command line.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The subcommand's exit status (each subcommand documents its own; 2 is a usage
        error or a failure to start).

    Raises
    ------
    SystemExit
        On ``--help`` (status 0) and on a usage error (status 2, one line on stderr).
    """
    args, extra = build_parser().parse_known_args(argv)
    if extra:
        args.parser.error(f"unrecognized arguments: {' '.join(extra)}")
    _show_library_messages()
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
