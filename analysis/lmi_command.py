"""``minimaxplan lmi``: check Assumption 4 for the models of a TOML model file.

    minimaxplan lmi MODEL.toml [--form discrete|continuous] [--vertices] [--model NAME]
                               [--solver CLARABEL|SCS] [--json] [--out FILE]

Exit codes: 0 if Assumption 4 holds with a re-checked certificate for every model
checked; 1 if it does not for some model (infeasible, inconclusive, or a feasible
solve whose certificate fails the numpy re-check); 2 on an error (bad arguments, an
unreadable or malformed file, a solver failure), with a message on stderr.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time
from typing import TYPE_CHECKING

from .arguments import output_file

if TYPE_CHECKING:
    from .model_file import ModelHypothesis
    from .reports import LMIReport

__all__ = ["register", "run", "check_model", "EXIT_HOLDS", "EXIT_FAILS", "EXIT_ERROR", "FORMS"]

EXIT_HOLDS = 0
EXIT_FAILS = 1
EXIT_ERROR = 2

#: The LMI forms, `model_file.DISCRETE` and `model_file.CONTINUOUS` (spelled out here so
#: that parsing the command line imports neither numpy nor cvxpy).
FORMS = ("discrete", "continuous")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``lmi`` subcommand to ``subparsers``.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The subcommands of the ``minimaxplan`` parser (`minimaxplan.analysis.cli`).
    """
    parser = subparsers.add_parser(
        "lmi",
        help="check Assumption 4 (an LMI) for a model file and write a report",
        description="Check Assumption 4 (the LMI of the paper, continuous or discrete form) for every "
        "model of a TOML model file, on the nominal matrix or on every vertex of the parameter box, "
        "and write a Markdown (or JSON) report with the certificate and its numpy re-check.",
        epilog="Exit codes: 0 Assumption 4 holds (certified) for every model; 1 it does not for some "
        "model (infeasible, inconclusive or not certified); 2 error. Format: docs/model-format.md.",
    )
    parser.add_argument("model", type=pathlib.Path, help="TOML model file")
    parser.add_argument(
        "--form",
        choices=FORMS,
        default=None,
        help="which LMI to check (default: the model's own time domain)",
    )
    parser.add_argument(
        "--vertices",
        action="store_true",
        help="check every vertex A(theta) of the parameter box with one common P (default: the nominal A)",
    )
    parser.add_argument(
        "--solver", choices=("CLARABEL", "SCS"), default="CLARABEL", help="conic solver (default: CLARABEL)"
    )
    parser.add_argument("--model", dest="model_name", metavar="NAME", help="check only the model with this name")
    parser.add_argument("--json", action="store_true", help="write the JSON report instead of Markdown")
    parser.add_argument(
        "--out", type=output_file, metavar="FILE", help="write the report to this file (default: stdout)"
    )
    parser.set_defaults(func=run)


def check_model(
    model: ModelHypothesis, *, form: str | None = None, vertices: bool = False, solver: str = "CLARABEL"
) -> LMIReport:
    """Check Assumption 4 for one model and wrap the result in an `LMIReport`.

    Parameters
    ----------
    model : ModelHypothesis
        One model of a model file.
    form : {"discrete", "continuous"}, optional
        Which LMI to check; defaults to the model's time domain. The continuous form
        checks the continuous-time matrices of the file, the discrete form the
        discretised ones.
    vertices : bool
        Check every vertex A(theta) of the parameter box with one common P (default:
        the nominal A, at the box's centre).
    solver : {"CLARABEL", "SCS"}
        The conic solver.

    Returns
    -------
    LMIReport
        The matrices checked, their parameters, and the re-checked result.

    Raises
    ------
    ModelFileError
        If the continuous form is asked of a discrete-time model.
    SolverFailure
        If the solver fails.

    Notes
    -----
    Assumption 4 of the paper (Section III) is the continuous-time LMI; the discrete
    form is its analogue for x_{n+1} = A x_n + D w_n (DESIGN.md).
    """
    from minimaxplan.verify import check_assumption4

    from .reports import LMIReport

    form = form or model.time
    matrices, D = model.state_matrices(form, vertices=vertices)
    system = model.system_for(form)
    parameters = system.theta.vertices() if vertices else system.theta.center[None, :]
    started = time.perf_counter()
    result = check_assumption4(list(matrices) if vertices else matrices[0], form=form, D=D, solver=solver)
    wall_time = time.perf_counter() - started
    return LMIReport(model.name, form, matrices, parameters, D, result, wall_time, vertices)


def run(args: argparse.Namespace) -> int:
    """Run ``minimaxplan lmi`` on parsed arguments.

    Parameters
    ----------
    args : argparse.Namespace
        The options of `register`'s parser: ``model``, ``form``, ``vertices``,
        ``solver``, ``model_name``, ``json``, ``out``.

    Returns
    -------
    int
        `EXIT_HOLDS`, `EXIT_FAILS` or `EXIT_ERROR` (after one line on stderr).
    """
    from minimaxplan.models import MinimaxplanError

    from .model_file import load_model_file
    from .reports import lmi_reports_to_dict, render_lmi_reports, to_json

    try:
        model_file = load_model_file(args.model)
        if args.model_name is not None:
            model_file = model_file.select(args.model_name)
        reports = [
            check_model(m, form=args.form, vertices=args.vertices, solver=args.solver) for m in model_file.hypotheses
        ]
        code = EXIT_HOLDS if all(r.holds for r in reports) else EXIT_FAILS
        if args.json:
            text = to_json(lmi_reports_to_dict(reports, source=str(args.model), exit_code=code))
        else:
            text = render_lmi_reports(reports, source=str(args.model))
        _emit(text, args.out)
    except (MinimaxplanError, OSError) as exc:
        print(f"minimaxplan lmi: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    return code


def _emit(text: str, out: pathlib.Path | None) -> None:
    if out is None:
        sys.stdout.write(text)
    else:
        out.write_text(text, encoding="utf-8")
