"""``minimaxplan select``: eliminate the model hypotheses that observed data contradicts.

    minimaxplan select MODELS.toml DATA.(csv|npz) [--json] [--out FILE]

Exit codes: 0 if at least one hypothesis survives; 1 if the data eliminates every
hypothesis; 2 on an error (bad arguments, an unreadable or malformed file, data whose
size does not match the models, a solver failure), with a message on stderr.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time
from typing import TYPE_CHECKING

from .arguments import output_file

if TYPE_CHECKING:
    from .data_file import TransitionData
    from .model_file import ModelFile
    from .reports import SelectionReport

__all__ = ["register", "run", "select_models", "EXIT_SURVIVORS", "EXIT_NONE_SURVIVES", "EXIT_ERROR"]

EXIT_SURVIVORS = 0
EXIT_NONE_SURVIVES = 1
EXIT_ERROR = 2


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``select`` subcommand to ``subparsers``.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The subcommands of the ``minimaxplan`` parser (`minimaxplan.analysis.cli`).
    """
    parser = subparsers.add_parser(
        "select",
        help="eliminate the model hypotheses that observed data contradicts",
        description="Run LP model elimination of the hypotheses of a TOML model file against one "
        "observed trajectory (CSV or NPZ); report the survivors, each eliminated hypothesis's "
        "inconsistency margin and forcing transitions, and the survivors' feasible parameter boxes.",
        epilog="Exit codes: 0 some hypothesis survives; 1 none does; 2 error. Formats: docs/model-format.md.",
    )
    parser.add_argument("models", type=pathlib.Path, help="TOML model file with one or more [[hypothesis]] tables")
    parser.add_argument("data", type=pathlib.Path, help="observed trajectory: .csv or .npz")
    parser.add_argument("--json", action="store_true", help="write the JSON report instead of Markdown")
    parser.add_argument(
        "--out", type=output_file, metavar="FILE", help="write the report to this file (default: stdout)"
    )
    parser.set_defaults(func=run)


def select_models(model_file: ModelFile, data: TransitionData) -> SelectionReport:
    """Run `eliminate_models` and `feasible_parameter_box` and wrap them in a `SelectionReport`.

    Parameters
    ----------
    model_file : ModelFile
        The hypotheses (and the measurement-noise bound) of a model file.
    data : TransitionData
        One observed trajectory.

    Returns
    -------
    SelectionReport
        The survivors, each eliminated hypothesis's certificate, the survivors'
        feasible parameter boxes and the timings.

    Raises
    ------
    DataFileError
        If the data's numbers of states or inputs differ from the models'.

    Notes
    -----
    The hypotheses are the model set M of eq. (15) (Section III); a hypothesis is
    eliminated when an LP finds no parameter in its box consistent with every
    transition, with a certificate (an inconsistency margin > 0).
    """
    from minimaxplan.verify import eliminate_models, feasible_parameter_box

    from .data_file import DataFileError
    from .reports import SelectionReport

    first = model_file.systems[0]
    p, q = first.nstates, first.ninputs
    if data.states.shape[1] != p or data.controls.shape[1] != q:
        raise DataFileError(
            f"{data.source}: the models have {p} states and {q} inputs, so states must have shape (N+1, {p}) "
            f"and controls (N, {q}); got states shape {data.states.shape} and controls shape {data.controls.shape}"
        )
    started = time.perf_counter()
    result = eliminate_models(
        model_file.systems, data.states, data.controls, measurement_noise=model_file.measurement_noise
    )
    elimination_time = time.perf_counter() - started
    started = time.perf_counter()
    boxes = {
        i: feasible_parameter_box(
            model_file.systems[i], data.states, data.controls, measurement_noise=model_file.measurement_noise
        )
        for i in result.survivors
    }
    box_time = time.perf_counter() - started
    return SelectionReport(
        names=tuple(model_file.names),
        result=result,
        feasible_boxes=boxes,
        ntransitions=data.ntransitions,
        nstates=p,
        ninputs=q,
        data_source=data.source,
        model_source=model_file.source,
        measurement_noise=model_file.measurement_noise,
        elimination_time=elimination_time,
        box_time=box_time,
    )


def run(args: argparse.Namespace) -> int:
    """Run ``minimaxplan select`` on parsed arguments.

    Parameters
    ----------
    args : argparse.Namespace
        The options of `register`'s parser: ``models``, ``data``, ``json``, ``out``.

    Returns
    -------
    int
        `EXIT_SURVIVORS`, `EXIT_NONE_SURVIVES` or `EXIT_ERROR` (after one line on stderr).
    """
    from minimaxplan.models import MinimaxplanError

    from .data_file import load_data_file
    from .model_file import load_model_file
    from .reports import to_json

    try:
        report = select_models(load_model_file(args.models), load_data_file(args.data))
        code = EXIT_SURVIVORS if report.survivors else EXIT_NONE_SURVIVES
        text = to_json({**report.to_dict(), "exit_code": code}) if args.json else report.to_markdown()
        if args.out is None:
            sys.stdout.write(text)
        else:
            args.out.write_text(text, encoding="utf-8")
    except (MinimaxplanError, OSError) as exc:
        print(f"minimaxplan select: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    return code
