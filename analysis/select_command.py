"""``minimaxplan select``: eliminate the model hypotheses that observed data contradicts.

    minimaxplan select MODELS.toml DATA.(csv|npz) [--lmi [--lmi-form F] [--lmi-states I,J]] [--json] [--out FILE]

The report explains each elimination: the first transition at which the data became
inconsistent (bisection on prefixes, `elimination_history.first_inconsistency`), the
state component the dual witness rests on, and the margin in that state's unit (a state
that no disturbance reaches is "contradicted exactly"); with ``--out``, a PNG of every
hypothesis's margin against the number N of transitions is written beside the report.
With ``--lmi``, Assumption 4 is checked on each survivor's feasible parameter box (the
chain that ``minimaxplan demo`` runs), and the verdicts and their proofs' status go into
the report.

Exit codes: 0 if at least one hypothesis survives; 1 if the data eliminates every
hypothesis; 2 on an error (bad arguments, an unreadable or malformed file, data whose
size does not match the models, a solver failure), with a message on stderr.
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib
import sys
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from .arguments import Subcommand, count_list, output_file, report_error

if TYPE_CHECKING:
    from .data_file import TransitionData
    from .model_file import ModelFile
    from .reports import SelectionReport

__all__ = [
    "COMMAND",
    "run",
    "select_models",
    "draw_margins",
    "save_margin_plot",
    "EXIT_SURVIVORS",
    "EXIT_NONE_SURVIVES",
    "EXIT_ERROR",
    "LMI_FORMS",
]

EXIT_SURVIVORS = 0
EXIT_NONE_SURVIVES = 1
EXIT_ERROR = 2
#: The forms of ``--lmi-form`` (spelled out so that parsing imports no numpy).
LMI_FORMS = ("discrete", "continuous")


def _add_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("models", type=pathlib.Path, help="TOML model file with one or more [[hypothesis]] tables")
    parser.add_argument("data", type=pathlib.Path, help="observed trajectory: .csv or .npz")
    parser.add_argument(
        "--lmi",
        action="store_true",
        help="check Assumption 4 over the vertices of each survivor's feasible parameter box",
    )
    parser.add_argument(
        "--lmi-form",
        choices=LMI_FORMS,
        default=None,
        help="the LMI's form with --lmi (default: the model's own time domain)",
    )
    parser.add_argument(
        "--lmi-states",
        type=count_list(0),
        default=None,
        metavar="I,J",
        help="with --lmi, check only this invariant subsystem (state indices, e.g. 2,3 for a robot's "
        "velocities; default: all states)",
    )
    parser.add_argument("--json", action="store_true", help="write the JSON report instead of Markdown")
    parser.add_argument(
        "--out",
        type=output_file,
        metavar="FILE",
        help="write the report to this file, and FILE-margins.png beside it (default: stdout, no PNG)",
    )


def select_models(
    model_file: ModelFile,
    data: TransitionData,
    *,
    explain: bool = True,
    lmi: bool = False,
    lmi_form: str | None = None,
    lmi_states: Sequence[int] | None = None,
    solver: str = "CLARABEL",
) -> SelectionReport:
    """Run `eliminate_models` and `feasible_parameter_box`, explain them, and wrap them in a `SelectionReport`.

    Parameters
    ----------
    model_file : ModelFile
        The hypotheses (and the measurement-noise bound) of a model file; its state
        names and units, when it gives them (``state_names``, ``state_units``), label
        the report.
    data : TransitionData
        One observed trajectory.
    explain : bool
        Explain each elimination (`first_inconsistency`) and record every hypothesis's
        margin against N (`elimination_history` on `margin_sample_sizes`).
    lmi : bool
        Check Assumption 4 over each survivor's feasible parameter box
        (`lmi_command.check_parameter_box`).
    lmi_form : {"discrete", "continuous"}, optional
        The LMI's form (default: each model's own time domain).
    lmi_states : sequence of int, optional
        Check only this invariant subsystem (default: all states).
    solver : {"CLARABEL", "SCS"}
        The conic solver of the LMI.

    Returns
    -------
    SelectionReport
        The survivors, each eliminated hypothesis's certificate and explanation, the
        margins against N, the survivors' feasible parameter boxes (and their
        Assumption 4 verdicts) and the timings.

    Raises
    ------
    DataFileError
        If the data's numbers of states or inputs differ from the models'.
    InputError
        If ``lmi_states`` is not an invariant subsystem.

    Notes
    -----
    The hypotheses are the model set M of eq. (15) (Section III); a hypothesis is
    eliminated when an LP finds no parameter in its box consistent with every
    transition, with a certificate (an inconsistency margin > 0).
    """
    from minimaxplan.verify import eliminate_models, feasible_parameter_box

    from .data_file import DataFileError
    from .elimination_history import elimination_history, first_inconsistency, margin_sample_sizes
    from .lmi_command import check_parameter_box
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
    noise = model_file.measurement_noise
    started = time.perf_counter()
    explanations, history = {}, None
    if explain:
        for i in sorted(result.eliminated):
            explanation = first_inconsistency(
                model_file.systems[i],
                data.states,
                data.controls,
                index=i,
                name=model_file.names[i],
                measurement_noise=noise,
            )
            if explanation is not None:  # eliminate_models eliminated it on the same data
                explanations[i] = explanation
        sizes = margin_sample_sizes(data.ntransitions, [e.first_transition for e in explanations.values()])
        if sizes.size:
            history = elimination_history(
                model_file.systems, data.states, data.controls, sizes, names=model_file.names, measurement_noise=noise
            )
    explain_time = time.perf_counter() - started
    started = time.perf_counter()
    lmi_reports = {}
    if lmi:
        for i in result.survivors:
            lmi_reports[i] = check_parameter_box(
                model_file.hypotheses[i], boxes[i], form=lmi_form, states=lmi_states, solver=solver
            )
    lmi_time = time.perf_counter() - started
    # State names and units are optional keys of a model file; older ModelFile values have neither.
    names = model_file.state_names
    units = model_file.state_units
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
        explanations=explanations,
        history=history,
        state_names=None if names is None else tuple(names),
        state_units=None if units is None else tuple(units),
        lmi=lmi_reports,
        lmi_states=None if not lmi or lmi_states is None else tuple(int(j) for j in lmi_states),
        explain_time=explain_time,
        lmi_time=lmi_time,
    )


def draw_margins(report: SelectionReport, ax: Any) -> Any:
    """Draw every hypothesis's inconsistency margin against N on a matplotlib axis.

    Parameters
    ----------
    report : SelectionReport
        A report with a margin history (``select_models(..., explain=True)``).
    ax : matplotlib.axes.Axes
        The axis to draw on.

    Returns
    -------
    matplotlib.axes.Axes
        ``ax``: one line per hypothesis (margin in units of its disturbance radius,
        symmetric-log scale), a dotted vertical line at each first inconsistent prefix,
        and a cross where a hypothesis is contradicted exactly.

    Raises
    ------
    InputError
        If the report has no margin history.
    """
    import numpy as np

    from minimaxplan.models import InputError

    history = report.history
    if history is None:
        raise InputError("report has no margin history: build it with select_models(..., explain=True)")
    from matplotlib.lines import Line2D

    styles = ("o-", "s--", "^-.", "v:", "D-", "P--")
    for m, name in enumerate(history.names):
        (line,) = ax.plot(
            history.sample_sizes, history.margins[m], styles[m % len(styles)], ms=4, label=name, alpha=0.9
        )
        explanation = report.explanations.get(m)
        if explanation is not None:
            first = explanation.first_transition + 1
            ax.axvline(first, color=line.get_color(), ls=":", lw=1)
            if explanation.exact:
                k = int(np.argmin(np.abs(history.sample_sizes - first)))
                ax.plot([first], [history.margins[m, k]], "x", color=line.get_color(), ms=10, mew=2)
    handles, _ = ax.get_legend_handles_labels()
    handles.append(Line2D([], [], color="0.4", ls=":", label="first inconsistent prefix (n + 1)"))
    if any(e.exact for e in report.explanations.values()):
        handles.append(Line2D([], [], color="0.4", ls="", marker="x", mew=2, label="contradicted exactly"))
    ax.set_xscale("log")
    ax.set_yscale("symlog", linthresh=1e-3)
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel("N, transitions observed (0..N-1)")
    ax.set_ylabel("inconsistency margin (disturbance radii)")
    ax.set_title("Model elimination: inconsistency margin against N")
    ax.legend(handles=handles, fontsize="small")
    ax.grid(True, which="both", alpha=0.3)
    return ax


def save_margin_plot(report: SelectionReport, path: pathlib.Path) -> pathlib.Path:
    """Write `draw_margins` as a PNG.

    Parameters
    ----------
    report : SelectionReport
        A report with a margin history.
    path : pathlib.Path
        Where to write the PNG.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from .figures import draw_png

    return draw_png(lambda ax: draw_margins(report, ax), path, figsize=(7, 4.2), dpi=120)


def run(args: argparse.Namespace) -> int:
    """Run ``minimaxplan select`` on parsed arguments.

    Parameters
    ----------
    args : argparse.Namespace
        The options of `COMMAND`'s parser: ``models``, ``data``, ``lmi``, ``lmi_form``,
        ``lmi_states``, ``json``, ``out``.

    Returns
    -------
    int
        `EXIT_SURVIVORS`, `EXIT_NONE_SURVIVES` or `EXIT_ERROR` (after one line on stderr).
    """
    from minimaxplan.models import InputError, MinimaxplanError

    from .data_file import load_data_file
    from .lmi_command import check_subsystem
    from .model_file import ModelFileError, load_model_file
    from .reports import to_json

    if not args.lmi and (args.lmi_form is not None or args.lmi_states is not None):
        print("minimaxplan select: error: --lmi-form and --lmi-states need --lmi", file=sys.stderr)
        return EXIT_ERROR
    try:
        model_file, data = load_model_file(args.models), load_data_file(args.data)
        if args.lmi_states is not None:
            try:
                for hypothesis in model_file.hypotheses:
                    check_subsystem(hypothesis, args.lmi_states, form=args.lmi_form)
            except ModelFileError:
                raise  # the form does not fit the model: reported below, like any model-file error
            except InputError as exc:
                return report_error("select", exc, option="--lmi-states")
        report = select_models(model_file, data, lmi=args.lmi, lmi_form=args.lmi_form, lmi_states=args.lmi_states)
        if args.out is not None and report.history is not None:
            image = args.out.with_name(f"{args.out.stem}-margins.png")
            save_margin_plot(report, image)
            report = dataclasses.replace(report, margin_image=image.name)
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


COMMAND = Subcommand(
    "select",
    help="eliminate the model hypotheses that observed data contradicts",
    description="Run LP model elimination of the hypotheses of a TOML model file against one "
    "observed trajectory (CSV or NPZ); report the survivors, each eliminated hypothesis's "
    "first inconsistent transition, violated state and margin per state, and the survivors' feasible "
    "parameter boxes; with --out, a PNG of the margins against N beside the report; with --lmi, "
    "Assumption 4 on each survivor's feasible parameter box.",
    epilog="Exit codes: 0 some hypothesis survives; 1 none does; 2 error. Formats: docs/model-format.md.",
    add_options=_add_options,
    run=run,
)
