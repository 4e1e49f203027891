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

from minimaxplan.models import MinimaxplanError
from minimaxplan.verify import check_assumption4

from .model_file import CONTINUOUS, DISCRETE, ModelHypothesis, load_model_file
from .reports import LMIReport, lmi_reports_to_dict, render_lmi_reports, to_json

__all__ = ["register", "run", "check_model", "EXIT_HOLDS", "EXIT_FAILS", "EXIT_ERROR"]

EXIT_HOLDS = 0
EXIT_FAILS = 1
EXIT_ERROR = 2


def register(subparsers) -> None:
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
        choices=(DISCRETE, CONTINUOUS),
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
    parser.add_argument("--out", type=pathlib.Path, metavar="FILE", help="write the report to this file (default: stdout)")
    parser.set_defaults(func=run)


def check_model(
    model: ModelHypothesis, *, form: str | None = None, vertices: bool = False, solver: str = "CLARABEL"
) -> LMIReport:
    """Check Assumption 4 for one model and wrap the result in an `LMIReport`.

    ``form`` defaults to the model's time domain. The continuous form checks the
    continuous-time matrices of the file, the discrete form the discretised ones.
    """
    form = form or model.time
    matrices, D = model.state_matrices(form, vertices=vertices)
    system = model.continuous_system if form == CONTINUOUS else model.system
    parameters = system.theta.vertices() if vertices else system.theta.center[None, :]
    started = time.perf_counter()
    result = check_assumption4(list(matrices) if vertices else matrices[0], form=form, D=D, solver=solver)
    wall_time = time.perf_counter() - started
    return LMIReport(model.name, form, matrices, parameters, D, result, wall_time, vertices)


def run(args: argparse.Namespace) -> int:
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
