"""``minimaxplan lmi``: check Assumption 4 for the models of a TOML model file.

    minimaxplan lmi MODEL.toml [--form discrete|continuous] [--vertices] [--model NAME]
                               [--regions [--depth N]] [--solver CLARABEL|SCS] [--json] [--out FILE]

With ``--regions`` the report also says where Assumption 4 holds: the parameter box is
split recursively (`minimaxplan.verify.certified_region`) and each piece certified with
its own P; the conflicting vertices of the whole box are named; with ``--out`` and a
parameter dimension d <= 2 a PNG of the map is written beside the report.

Exit codes: 0 if Assumption 4 holds with a re-checked certificate for every model
checked; 1 if it does not for some model (infeasible on a re-checked dual certificate,
or inconclusive); 2 on an error (bad arguments, an unreadable or malformed file), with a
message on stderr.
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib
import re
import sys
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from .arguments import Subcommand, output_file, report_error

if TYPE_CHECKING:
    from minimaxplan.models import Box
    from minimaxplan.verify import RegionMap

    from .model_file import ModelHypothesis
    from .reports import LMIReport

__all__ = [
    "COMMAND",
    "run",
    "check_model",
    "check_parameter_box",
    "check_subsystem",
    "draw_region_map",
    "save_region_map",
    "EXIT_HOLDS",
    "EXIT_FAILS",
    "EXIT_ERROR",
    "FORMS",
    "DEFAULT_DEPTH",
]

EXIT_HOLDS = 0
EXIT_FAILS = 1
EXIT_ERROR = 2

#: The LMI forms, `model_file.DISCRETE` and `model_file.CONTINUOUS` (spelled out here so
#: that parsing the command line imports neither numpy nor cvxpy).
FORMS = ("discrete", "continuous")
#: Default ``--depth`` of ``--regions``: bisections along a branch (2^4 pieces at most for d = 1).
DEFAULT_DEPTH = 4


def _add_options(parser: argparse.ArgumentParser) -> None:
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
        "--regions",
        action="store_true",
        help="also map where Assumption 4 holds: split the parameter box and certify each piece with its own P",
    )
    parser.add_argument(
        "--depth",
        type=_depth,
        default=None,
        metavar="N",
        help=f"largest number of bisections along a branch of --regions (default: {DEFAULT_DEPTH})",
    )
    parser.add_argument(
        "--solver", choices=("CLARABEL", "SCS"), default="CLARABEL", help="conic solver (default: CLARABEL)"
    )
    parser.add_argument("--model", dest="model_name", metavar="NAME", help="check only the model with this name")
    parser.add_argument("--json", action="store_true", help="write the JSON report instead of Markdown")
    parser.add_argument(
        "--out", type=output_file, metavar="FILE", help="write the report to this file (default: stdout)"
    )


def _depth(text: str) -> int:
    """``--depth``: an integer >= 0 (argparse reports a bad value in one line)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {value}")
    return value


def check_model(
    model: ModelHypothesis,
    *,
    form: str | None = None,
    vertices: bool = False,
    solver: str = "CLARABEL",
    regions: bool = False,
    depth: int = DEFAULT_DEPTH,
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
    regions : bool
        Also split the parameter box recursively and certify each piece
        (`minimaxplan.verify.certified_region`); the map goes to `LMIReport.regions`.
    depth : int
        Largest number of bisections along a branch of the map (>= 0).

    Returns
    -------
    LMIReport
        The matrices checked, their parameters, the re-checked result and, with
        ``regions``, the region map.

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
    from minimaxplan.verify import certified_region, check_assumption4

    from .reports import LMIReport

    form = form or model.time
    matrices, D = model.state_matrices(form, vertices=vertices)
    system = model.system_for(form)
    parameters = system.theta.vertices() if vertices else system.theta.center[None, :]
    started = time.perf_counter()
    result = check_assumption4(list(matrices) if vertices else matrices[0], form=form, D=D, solver=solver)
    wall_time = time.perf_counter() - started
    region_map = certified_region(system, form=form, D=D, max_depth=depth, solver=solver) if regions else None
    return LMIReport(model.name, form, matrices, parameters, D, result, wall_time, vertices, region_map)


def check_subsystem(model: ModelHypothesis, states: Sequence[int], *, form: str | None = None) -> list[int]:
    """Check that ``states`` index an invariant subsystem of a model; return them as a list.

    Parameters
    ----------
    model : ModelHypothesis
        One model of a model file.
    states : sequence of int
        State indices.
    form : {"discrete", "continuous"}, optional
        The time domain whose matrices are checked (default: the model's own).

    Returns
    -------
    list of int
        ``states``, in the order given.

    Raises
    ------
    InputError
        If an index repeats or lies outside ``0..p-1``, or a state outside ``states``
        enters the rows of ``states`` in ``A(theta)`` at some vertex of the prior box
        (then it does somewhere in every open part of the box: the entries are affine in
        theta).
    """
    import numpy as np

    from minimaxplan.models import InputError

    system = model.system_for(form or model.time)
    p = system.nstates
    chosen = [int(i) for i in states]
    if not chosen or len(set(chosen)) != len(chosen) or min(chosen) < 0 or max(chosen) >= p:
        raise InputError(f"states must be distinct state indices in 0..{p - 1}, got {chosen}")
    rest = [i for i in range(p) if i not in chosen]
    coupling = system.A(system.theta.vertices())[:, chosen][:, :, rest]
    if np.any(coupling != 0):
        entering = sorted({rest[j] for j in np.nonzero(coupling)[2].tolist()})
        raise InputError(
            f"states {chosen} are not an invariant subsystem of model {model.name!r}: "
            f"states {entering} enter their rows of A(theta)"
        )
    return chosen


def check_parameter_box(
    model: ModelHypothesis,
    box: Box,
    *,
    form: str | None = None,
    states: Sequence[int] | None = None,
    solver: str = "CLARABEL",
) -> LMIReport:
    """Check Assumption 4 over a parameter box of one model (e.g. its data-consistent box).

    Parameters
    ----------
    model : ModelHypothesis
        One model of a model file.
    box : Box
        The parameter box, dimension d = the model's number of parameters (e.g.
        `minimaxplan.verify.feasible_parameter_box` of the model on observed data).
    form : {"discrete", "continuous"}, optional
        Which LMI to check; defaults to the model's time domain.
    states : sequence of int, optional
        Check only the subsystem of these state indices (e.g. the velocities of a
        robot whose positions integrate them). It must be invariant: no state outside
        it enters the rows of the states in it, at any vertex.
    solver : {"CLARABEL", "SCS"}
        The conic solver.

    Returns
    -------
    LMIReport
        The 2^d vertex matrices of ``box`` (restricted to ``states``), checked with one
        common P, and the re-checked `LMIResult`.

    Raises
    ------
    DimensionError
        If ``box`` does not have the model's parameter dimension.
    InputError
        If ``states`` is not an invariant subsystem (`check_subsystem`).
    ModelFileError
        If the continuous form is asked of a discrete-time model.

    Notes
    -----
    ``A(theta)`` is affine in theta (eq. (2)), so the vertex matrices span every
    ``A(theta)`` of the box, and one common P for them is Assumption 4 over the box.
    """
    import numpy as np

    from minimaxplan.models import DimensionError
    from minimaxplan.verify import check_assumption4

    from .reports import LMIReport

    form = form or model.time
    system = model.system_for(form)
    if box.dim != system.nparams:
        raise DimensionError(
            f"box must have the model's {system.nparams} parameters (theta of shape ({system.nparams},)), "
            f"got a box of dimension {box.dim}"
        )
    parameters = box.vertices()
    matrices = system.A(parameters)
    D = np.array(system.D)
    if states is not None:
        chosen = check_subsystem(model, states, form=form)
        matrices = matrices[:, chosen][:, :, chosen]
        D = D[chosen]
    started = time.perf_counter()
    result = check_assumption4(list(matrices), form=form, D=D, solver=solver)
    wall_time = time.perf_counter() - started
    return LMIReport(model.name, form, matrices, parameters, D, result, wall_time, vertices=True)


def draw_region_map(regions: RegionMap, ax: Any, *, names: tuple[str, ...] | None = None) -> Any:
    """Draw a region map (d <= 2) on a matplotlib axis: certified pieces green, others red or grey.

    Parameters
    ----------
    regions : RegionMap
        The result of `minimaxplan.verify.certified_region`, parameter dimension 1 or 2.
    ax : matplotlib.axes.Axes
        The axis to draw on.
    names : tuple of str, optional
        Axis labels of the parameters (default ``theta[i]``).

    Returns
    -------
    matplotlib.axes.Axes
        ``ax``.

    Raises
    ------
    InputError
        If the parameter dimension is above 2.
    """
    from matplotlib.patches import Patch, Rectangle

    from minimaxplan.models import InputError

    d = regions.box.dim
    if d > 2:
        raise InputError(f"a region map is drawn for d <= 2 parameters, got d = {d}")
    labels = names or tuple(f"theta[{i}]" for i in range(d))
    colours = {"certified": "tab:green", "infeasible": "tab:red", "inconclusive": "0.6"}
    for piece in regions.pieces:
        kind = "certified" if piece.certified else piece.status.value
        low, high = piece.box.low, piece.box.high
        y0, height = (low[1], high[1] - low[1]) if d == 2 else (0.0, 1.0)
        ax.add_patch(Rectangle((low[0], y0), high[0] - low[0], height, facecolor=colours[kind], edgecolor="k", lw=0.5))
    box = regions.box
    ax.set_xlim(box.low[0], box.high[0] if box.high[0] > box.low[0] else box.low[0] + 1)
    if d == 2:
        ax.set_ylim(box.low[1], box.high[1] if box.high[1] > box.low[1] else box.low[1] + 1)
        ax.set_ylabel(labels[1])
    else:
        ax.set_ylim(0.0, 1.0)
        ax.set_yticks([])
    ax.set_xlabel(labels[0])
    ax.set_title(f"Assumption 4 ({regions.form}): certified fraction {regions.certified_fraction:.4g}")
    ax.legend(handles=[Patch(color=c, label=k) for k, c in colours.items()], loc="upper right", fontsize="small")
    return ax


def save_region_map(regions: RegionMap, path: pathlib.Path) -> pathlib.Path:
    """Write the region map (d <= 2) as a PNG.

    Parameters
    ----------
    regions : RegionMap
        The map to draw (`draw_region_map`).
    path : pathlib.Path
        Where to write the PNG.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from .figures import draw_png

    return draw_png(
        lambda ax: draw_region_map(regions, ax), path, figsize=(6, 2.2 if regions.box.dim == 1 else 5), dpi=120
    )


def run(args: argparse.Namespace) -> int:
    """Run ``minimaxplan lmi`` on parsed arguments.

    Parameters
    ----------
    args : argparse.Namespace
        The options of `COMMAND`'s parser: ``model``, ``form``, ``vertices``,
        ``regions``, ``depth``, ``solver``, ``model_name``, ``json``, ``out``.

    Returns
    -------
    int
        `EXIT_HOLDS`, `EXIT_FAILS` or `EXIT_ERROR` (after one line on stderr).
    """
    from minimaxplan.models import MinimaxplanError

    from .model_file import load_model_file
    from .reports import lmi_reports_to_dict, render_lmi_reports, to_json

    if args.depth is not None and not args.regions:
        print("minimaxplan lmi: error: --depth needs --regions", file=sys.stderr)
        return EXIT_ERROR
    depth = DEFAULT_DEPTH if args.depth is None else args.depth
    try:
        model_file = load_model_file(args.model)
        if args.model_name is not None:
            try:
                model_file = model_file.select(args.model_name)
            except MinimaxplanError as exc:
                return report_error("lmi", exc, option="--model")
        reports = [
            check_model(
                m, form=args.form, vertices=args.vertices, solver=args.solver, regions=args.regions, depth=depth
            )
            for m in model_file.hypotheses
        ]
        if args.out is not None:
            reports = [_with_map_image(report, args.out) for report in reports]
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


def _with_map_image(report: LMIReport, out: pathlib.Path) -> LMIReport:
    """Write the report's region map (d <= 2) as a PNG beside ``out``; name it in the report."""
    if report.regions is None or report.regions.box.dim > 2:
        return report
    slug = re.sub(r"[^A-Za-z0-9]+", "-", report.model).strip("-").lower() or "model"
    path = out.with_name(f"{out.stem}-{slug}-regions.png")
    save_region_map(report.regions, path)
    return dataclasses.replace(report, region_image=path.name)


def _emit(text: str, out: pathlib.Path | None) -> None:
    if out is None:
        sys.stdout.write(text)
    else:
        out.write_text(text, encoding="utf-8")


COMMAND = Subcommand(
    "lmi",
    help="check Assumption 4 (an LMI) for a model file and write a report",
    description="Check Assumption 4 (the LMI of the paper, continuous or discrete form) for every "
    "model of a TOML model file, on the nominal matrix or on every vertex of the parameter box, "
    "and write a Markdown (or JSON) report with the certificate and its exact re-check.",
    epilog="Exit codes: 0 Assumption 4 holds (certified) for every model; 1 it does not for some "
    "model (infeasible, inconclusive or not certified); 2 error. Format: docs/model-format.md.",
    add_options=_add_options,
    run=run,
)
