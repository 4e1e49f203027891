"""Readable Markdown reports and their JSON twins for the ``lmi`` and ``select`` commands.

A report is a frozen value built from library results (`LMIResult`, `SelectionResult`,
`Box`) plus the figures worth showing next to them, which are recomputed here with
numpy so that a reader can check them independently of the solver: eigenvalues of the
state matrices and of P, and the largest eigenvalue of each LMI at the returned
certificate. ``to_dict()`` is the JSON twin, ``to_markdown()`` the readable form.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from minimaxplan.models import Box
from minimaxplan.verify import LMIResult, LMIStatus, RegionMap, SelectionResult, lmi_matrix

if TYPE_CHECKING:
    from .elimination_history import EliminationHistory, InconsistencyExplanation

__all__ = [
    "LMIReport",
    "SelectionReport",
    "proof_status",
    "render_lmi_reports",
    "render_region_map",
    "lmi_reports_to_dict",
    "to_json",
    "REPORT_FORMAT_VERSION",
]

REPORT_FORMAT_VERSION = 1


# ------------------------------------------------------------------- helpers
def to_json(document: dict) -> str:
    """``document`` as indented JSON; numpy scalars and arrays become numbers and lists.

    Parameters
    ----------
    document : dict
        The document; values with a ``to_dict`` method are written as its result, NaN as
        null and infinities as the strings ``"inf"`` and ``"-inf"``.
    """
    return json.dumps(_plain(document), indent=2, allow_nan=False) + "\n"


@runtime_checkable
class _PlainData(Protocol):
    """A result object that serialises itself (the library's results and reports)."""

    def to_dict(self) -> dict:
        """The object as a dict."""


def _plain(value: Any) -> Any:
    if type(value) in (str, int, bool) or value is None:  # the leaves, first: the protocol check costs microseconds
        return value
    if type(value) is float and math.isfinite(value):
        return value
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return _plain(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, _PlainData):
        return _plain(value.to_dict())
    return value


def _num(x: float | None, digits: int = 4) -> str:
    if x is None:
        return "-"
    x = float(x)
    if not math.isfinite(x):
        return str(x)
    return f"{x:.{digits}g}"


def _significant(x: float | None, reference: float, digits: int = 7) -> str:
    """``x`` with at least ``digits`` significant digits, and more if needed to tell it from ``reference``.

    A spectral radius of 0.99999975 prints as ``0.9999998``, never as ``1``; a value
    equal to ``reference`` prints as it is.
    """
    if x is None:
        return "-"
    x = float(x)
    if not math.isfinite(x):
        return str(x)
    text = f"{x:.{digits}g}"
    while x != reference and float(text) == reference and digits < 17:
        digits += 1
        text = f"{x:.{digits}g}"
    return text


def _vector(values, digits: int = 4) -> str:
    return "[" + ", ".join(_num(v, digits) for v in np.ravel(values)) + "]"


def _complex_list(values: np.ndarray, digits: int = 4) -> str:
    parts = []
    for z in values:
        if abs(z.imag) <= 1e-12 * max(1.0, abs(z.real)):
            parts.append(_num(z.real, digits))
        else:
            parts.append(f"{_num(z.real, digits)}{'+' if z.imag >= 0 else '-'}{_num(abs(z.imag), digits)}j")
    return ", ".join(parts)


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(cell).replace("|", "\\|") for cell in row) + " |" for row in rows]
    return lines


def _sorted_eigenvalues(matrix: np.ndarray) -> np.ndarray:
    values = np.linalg.eigvals(matrix)
    return values[np.lexsort((values.imag, values.real))]


# ---------------------------------------------------------------- LMI reports
@dataclass(frozen=True, eq=False)
class LMIReport:
    """The outcome of checking Assumption 4 on one model, with independent numpy figures.

    Parameters
    ----------
    model
        The model's name.
    form
        "continuous" or "discrete".
    matrices
        The state matrices checked with one common P, shape (k, p, p).
    parameters
        The parameter value behind each matrix, shape (k, d).
    D
        The disturbance matrix, shape (p, r).
    result
        The `LMIResult` of `check_assumption4`.
    wall_time
        Seconds spent in `check_assumption4` (model building, solve and re-check).
    vertices
        True if ``matrices`` are the vertices of the parameter box, False for the nominal matrix.
    regions
        The `RegionMap` of `certified_region` over the parameter box (where Assumption 4
        holds, piece by piece), or None when it was not asked for.
    region_image
        File name (relative to the report) of a PNG of the region map, or None.
    """

    model: str
    form: str
    matrices: np.ndarray
    parameters: np.ndarray
    D: np.ndarray
    result: LMIResult
    wall_time: float
    vertices: bool = False
    regions: RegionMap | None = None
    region_image: str | None = None

    @property
    def has_certificate(self) -> bool:
        """True if the solver returned a certificate (P, Q0, rho), checked or not."""
        return self._certificate() is not None

    def _certificate(self) -> tuple[np.ndarray, np.ndarray, float] | None:
        P, Q0, rho = self.result.P, self.result.Q0, self.result.rho
        if P is None or Q0 is None or rho is None:
            return None
        return P, Q0, rho

    @property
    def holds(self) -> bool:
        """True iff the LMI is feasible on a certificate re-checked exactly (`LMIResult.holds`)."""
        return self.result.holds

    @property
    def verdict(self) -> str:
        """The verdict in one sentence: Assumption 4 holds, fails (proven), or is inconclusive (and why)."""
        status = self.result.status
        if self.result.holds:
            return "Assumption 4 holds: feasible, certificate re-checked exactly"
        if status is LMIStatus.INFEASIBLE:
            margin = self.result.margin
            bound = f" above {margin:.3g}" if margin is not None else ""
            return (
                f"Assumption 4 fails: no certificate with normalised margin{bound} exists "
                "(dual certificate re-checked exactly)"
            )
        reason = self.result.reason
        return f"inconclusive: {reason}" if reason else f"inconclusive (status {status.value!r})"

    def state_eigenvalues(self) -> list[np.ndarray]:
        """Per matrix, the eigenvalues of A, shape (p,) complex, sorted by real then imaginary part."""
        return [_sorted_eigenvalues(a) for a in self.matrices]

    def stability_margins(self) -> np.ndarray:
        """Per matrix: max real part of the eigenvalues (continuous) or the spectral radius (discrete)."""
        if self.form == "continuous":
            return np.array([np.max(np.linalg.eigvals(a).real) for a in self.matrices])
        return np.array([np.max(np.abs(np.linalg.eigvals(a))) for a in self.matrices])

    def lmi_max_eigenvalues(self) -> np.ndarray | None:
        """Per matrix, the largest eigenvalue of the LMI at the returned certificate (< 0 required)."""
        certificate = self._certificate()
        if certificate is None:
            return None
        P, Q0, rho = certificate
        return np.array([np.linalg.eigvalsh(lmi_matrix(a, P, Q0, rho, self.D, self.form))[-1] for a in self.matrices])

    def to_dict(self) -> dict:
        """The report as a dict of plain Python values, for JSON (per matrix its eigenvalues and margins)."""
        margins = self.lmi_max_eigenvalues()
        P, Q0 = self.result.P, self.result.Q0
        return {
            "model": self.model,
            "form": self.form,
            "vertices": self.vertices,
            "verdict": self.verdict,
            "holds": self.holds,
            "matrices": [
                {
                    "parameters": theta.tolist(),
                    "A": a.tolist(),
                    "eigenvalues": {"real": ev.real.tolist(), "imag": ev.imag.tolist()},
                    "stability_margin": float(s),
                    "lmi_max_eigenvalue": None if margins is None else float(m),
                }
                for theta, a, ev, s, m in zip(
                    self.parameters,
                    self.matrices,
                    self.state_eigenvalues(),
                    self.stability_margins(),
                    margins if margins is not None else [None] * len(self.matrices),
                )
            ],
            "P_eigenvalues": None if P is None else np.linalg.eigvalsh(P).tolist(),
            "Q0_eigenvalues": None if Q0 is None else np.linalg.eigvalsh(Q0).tolist(),
            "wall_time": self.wall_time,
            "result": self.result.to_dict(),
            "regions": None if self.regions is None else self.regions.to_dict(),
            "region_image": self.region_image,
        }

    def to_markdown(self) -> str:
        """The model's Markdown section: verdict and solver, the margins per matrix, the certificate, the region map.

        The certificate's table gives the eigenvalues of P and Q0, and Theorem 2's bound
        constants when Assumption 4 holds; the region map appears when it was computed.
        """
        result = self.result
        what = (
            f"{len(self.matrices)} vertices of A(theta) over the parameter box, one common P"
            if self.vertices
            else "the nominal matrix A(theta) at the centre of the parameter box"
        )
        lmi = (
            "[[A^T P + P A + Q0, P D], [D^T P, -rho I]] < 0, P > 0"
            if self.form == "continuous"
            else "[[A^T P A - P + Q0, A^T P D], [D^T P A, D^T P D - rho I]] < 0, P > 0"
        )
        solve_time = result.solve_time
        rows: list[tuple[str, ...]] = [
            ("verdict", f"**{self.verdict}**"),
            (
                "status",
                f"{result.status} (certified: {bool(result.certified)}, inaccurate: {bool(result.inaccurate)})",
            ),
            ("form", f"{self.form}: `{lmi}`"),
            ("checked", what),
            ("solver", f"{result.solver}, status `{result.solver_status}`"),
            ("time", f"solver {_num(solve_time)} s, wall {_num(self.wall_time)} s"),
        ]
        if result.rho is not None:
            rows.append(("rho", _num(result.rho, 6)))
        slack = "- (no primal SDP optimum behind this result)" if result.slack is None else _num(result.slack, 6)
        rows.append(("normalised slack t* of the primal SDP", slack))
        if result.margin is not None:
            rows.append(("proven bound on the normalised margin", _num(result.margin, 6)))
        if result.eigenvalues_P is not None and result.eigenvalues_P[0] > 0:
            rows.append(("cond(P)", _num(result.eigenvalues_P[-1] / result.eigenvalues_P[0], 6)))
        if result.reason:
            rows.append(("reason", result.reason))
        lines = [f"## {self.model}", ""] + _table(("", ""), rows) + [""]

        margins = self.lmi_max_eigenvalues()
        stability = self.stability_margins()
        label = "max Re eig(A)" if self.form == "continuous" else "spectral radius of A"
        boundary = 0.0 if self.form == "continuous" else 1.0
        lines += ["### Margins", ""]
        rows = []
        for k, (theta, ev) in enumerate(zip(self.parameters, self.state_eigenvalues())):
            rows.append(
                (
                    str(k),
                    _vector(theta),
                    _significant(stability[k], boundary),
                    "-" if margins is None else _significant(margins[k], 0.0),
                    _complex_list(ev, 7),
                )
            )
        lines += _table(("matrix", "theta", label, "max eig of the LMI at P", "eigenvalues of A"), rows)
        lines.append("")
        if margins is not None:
            lines.append(
                f"Largest LMI eigenvalue over all matrices: {_significant(np.max(margins), 0.0)} "
                "(negative means every LMI holds strictly at the returned certificate)."
            )
            lines.append("")
        certificate = self._certificate()
        if certificate is not None:
            p_eig = np.linalg.eigvalsh(certificate[0])
            q_eig = np.linalg.eigvalsh(certificate[1])
            lines += ["### Certificate", ""]
            rows = [
                ("eigenvalues of P", _vector(p_eig)),
                ("condition number of P", _num(p_eig[-1] / p_eig[0], 6)),
                ("eigenvalues of Q0", _vector(q_eig)),
            ]
            if self.holds:
                c0, cw = result.bound_constants()
                step = "per step" if self.form == "discrete" else "per unit time"
                rows += [
                    ("bound constant c0 = sqrt(lmax(P) / lmin(P))", _num(c0, 6)),
                    ("bound constant cw = sqrt(rho lmax(P) / (lmin(P) lmin(Q0)))", _num(cw, 6)),
                    (f"decay factor of e^T P e {step}", _num(result.decay_factor(), 6)),
                ]
            lines += _table(("quantity", "value"), rows) + [""]
            if self.holds:
                dynamics, error = (
                    ("e+ = A e + D w", "||e_n||") if self.form == "discrete" else ("de/dt = A e + D w", "||e(t)||")
                )
                lines += [
                    f"With this certificate, `{dynamics}` obeys `{error} <= c0 ||e_0|| + cw sup ||w||` "
                    "for every A of the checked set (Theorem 2, bound constants of `LMIResult.bound_constants`).",
                    "",
                ]
        if self.regions is not None:
            lines += _regions_markdown(self.regions)
            if self.region_image is not None:
                lines += [f"![where Assumption 4 holds]({self.region_image})", ""]
        return "\n".join(lines)


def render_region_map(regions: RegionMap) -> str:
    """The Markdown section "Where Assumption 4 holds" of a region map.

    Parameters
    ----------
    regions : RegionMap
        The result of `minimaxplan.verify.certified_region`.

    Returns
    -------
    str
        The certified, infeasible and inconclusive fractions of the box, the conflicting
        vertices of the whole box (when it is proven infeasible) and a table of the
        pieces with their verdicts, normalised slacks and cond(P).

    Notes
    -----
    Assumption 4 over a polytope (eq. (8)), piece by piece: each certified piece has
    its own P.
    """
    return "\n".join(_regions_markdown(regions))


def _regions_markdown(regions: RegionMap) -> list[str]:
    """The lines of `render_region_map`."""
    lines = ["### Where Assumption 4 holds", ""]
    lines.append(
        f"The parameter box was split recursively (depth <= {regions.max_depth}, "
        f"pieces of at least {_num(regions.min_volume, 4)} of its volume) and each piece checked over its "
        "corner matrices with its own P (exactly re-checked)."
    )
    lines.append("")
    lines += _table(
        ("certified fraction", "infeasible fraction", "inconclusive fraction", "pieces"),
        [
            (
                _significant(regions.certified_fraction, 1.0, 4),
                _significant(regions.infeasible_fraction, 0.0, 4),
                _significant(regions.inconclusive_fraction, 0.0, 4),
                str(len(regions.pieces)),
            )
        ],
    ) + [""]
    conflict = regions.conflict
    if conflict is not None:
        proven = "proven irreducible" if conflict.irreducible else "irreducibility not proven for every member"
        lines += [
            f"Conflicting vertices of the whole box: {', '.join(str(i) for i in conflict.indices)} "
            f"(no common P with normalised margin above {_num(conflict.infeasible.margin, 3)}; "
            f"dropping any one restores one: {proven}).",
            "",
        ]
    rows = []
    for n, piece in enumerate(regions.pieces):
        rows.append(
            (
                str(n),
                _vector(piece.box.low, 7),
                _vector(piece.box.high, 7),
                str(piece.depth),
                _num(piece.fraction, 4),
                "**certified**" if piece.certified else piece.status.value,
                _num(piece.result.slack, 4),
                _num(piece.condition_P, 4),
            )
        )
    lines += _table(("piece", "low", "high", "depth", "fraction", "verdict", "normalised slack", "cond(P)"), rows)
    return lines + [""]


def lmi_reports_to_dict(reports: Sequence[LMIReport], *, source: str, exit_code: int) -> dict:
    """The JSON document of ``minimaxplan lmi``.

    Parameters
    ----------
    reports : sequence of LMIReport
        One per model checked, in file order.
    source : str
        The model file's path.
    exit_code : int
        The command's exit status (`EXIT_HOLDS` or `EXIT_FAILS`), recorded in the document.
    """
    return {
        "command": "lmi",
        "format_version": REPORT_FORMAT_VERSION,
        "model_file": source,
        "exit_code": exit_code,
        "all_hold": all(r.holds for r in reports),
        "models": [r.to_dict() for r in reports],
    }


def render_lmi_reports(reports: Sequence[LMIReport], *, source: str) -> str:
    """The Markdown document of ``minimaxplan lmi``: a summary table, then one section per model.

    Parameters
    ----------
    reports : sequence of LMIReport
        One per model checked, in file order.
    source : str
        The model file's path, named in the title.
    """
    lines = [f"# Assumption 4 (LMI) report: `{source}`", ""]
    rows = [
        (
            r.model,
            r.form,
            "vertices" if r.vertices else "nominal",
            r.result.status,
            str(bool(r.result.certified)),
            r.verdict,
        )
        for r in reports
    ]
    lines += _table(("model", "form", "matrices", "status", "certified", "verdict"), rows) + [""]
    lines += [r.to_markdown() for r in reports]
    return "\n".join(lines).rstrip("\n") + "\n"


# ---------------------------------------------------------- selection reports
def proof_status(result: LMIResult) -> str:
    """How an Assumption 4 verdict is proven, in one phrase.

    Parameters
    ----------
    result : LMIResult
        A result of `check_assumption4`.

    Returns
    -------
    str
        "primal certificate re-checked exactly" (feasible), "dual certificate re-checked
        exactly" (infeasible), or "no proof either way: REASON" (inconclusive).
    """
    if result.holds:
        return "primal certificate re-checked exactly"
    if result.status is LMIStatus.INFEASIBLE and result.dual is not None:
        return "dual certificate re-checked exactly"
    reason = result.reason
    return f"no proof either way: {reason}" if reason else "no proof either way"


@dataclass(frozen=True, eq=False)
class SelectionReport:
    """The outcome of model elimination on one data set, with an explanation of each verdict.

    Parameters
    ----------
    names
        The hypotheses' names, in file order.
    result
        The `SelectionResult` of `eliminate_models`.
    feasible_boxes
        For each survivor (by index), the box bounding its data-consistent parameters.
    ntransitions, nstates, ninputs
        The data's size.
    data_source, model_source
        Where the data and the hypotheses came from.
    measurement_noise
        The measurement-noise bound used, or None.
    elimination_time, box_time
        Wall-clock seconds spent in `eliminate_models` and in `feasible_parameter_box`.
    explanations
        For each eliminated hypothesis (by index), its `InconsistencyExplanation`: the
        first inconsistent transition, the violated state and the margin per state.
    history
        The margins of every hypothesis against the number N of transitions
        (`EliminationHistory`), or None.
    state_names, state_units
        One name and one unit per state (default ``x0, x1, ...`` and "state units").
    margin_image
        File name (relative to the report) of the PNG of the margins against N, or None.
    lmi
        For each survivor (by index), the `LMIReport` of Assumption 4 over its feasible
        parameter box (``select --lmi``); empty when not asked for.
    lmi_states
        The state indices of the subsystem the LMI was checked on, or None (all states).
    explain_time, lmi_time
        Wall-clock seconds spent in the explanations (bisection and history) and in the
        LMI checks.
    """

    names: tuple[str, ...]
    result: SelectionResult
    feasible_boxes: dict[int, Box]
    ntransitions: int
    nstates: int
    ninputs: int
    data_source: str
    model_source: str
    measurement_noise: np.ndarray | None
    elimination_time: float
    box_time: float
    explanations: Mapping[int, InconsistencyExplanation] = field(default_factory=dict)
    history: EliminationHistory | None = None
    state_names: tuple[str, ...] | None = None
    state_units: tuple[str, ...] | None = None
    margin_image: str | None = None
    lmi: Mapping[int, LMIReport] = field(default_factory=dict)
    lmi_states: tuple[int, ...] | None = None
    explain_time: float = 0.0
    lmi_time: float = 0.0

    @property
    def survivors(self) -> list[int]:
        """The indices of the surviving hypotheses (`SelectionResult.survivors`)."""
        return list(self.result.survivors)

    def state_label(self, j: int) -> str:
        """The name of state ``j`` (``x<j>`` when the model file names none).

        Parameters
        ----------
        j : int
            A state index, 0 <= j < p.
        """
        return self.state_names[j] if self.state_names is not None else f"x{j}"

    def state_unit(self, j: int) -> str:
        """The unit of state ``j`` ("state units" when the model file gives none).

        Parameters
        ----------
        j : int
            A state index, 0 <= j < p.
        """
        return self.state_units[j] if self.state_units is not None else "state units"

    def to_dict(self) -> dict:
        """The report as a dict of plain Python values, for JSON (``select --json`` less its ``exit_code``)."""
        return {
            "command": "select",
            "format_version": REPORT_FORMAT_VERSION,
            "model_file": self.model_source,
            "data_file": self.data_source,
            "data": {"transitions": self.ntransitions, "states": self.nstates, "inputs": self.ninputs},
            "measurement_noise": None
            if self.measurement_noise is None
            else np.asarray(self.measurement_noise).tolist(),
            "states": [{"name": self.state_label(j), "unit": self.state_unit(j)} for j in range(self.nstates)],
            "hypotheses": [
                {
                    "index": i,
                    "name": name,
                    "survives": i in self.survivors,
                    "margin": float(self.result.margins[i]),
                    "certificate": None if i in self.survivors else _plain(self.result.eliminated[i]),
                    "explanation": self.explanations[i].to_dict() if i in self.explanations else None,
                    "feasible_box": self.feasible_boxes[i].to_dict() if i in self.feasible_boxes else None,
                    "assumption4": self._lmi_entry(i),
                }
                for i, name in enumerate(self.names)
            ],
            "survivors": [self.names[i] for i in self.survivors],
            "eliminated": [self.names[i] for i in sorted(self.result.eliminated)],
            "margin_history": None if self.history is None else self.history.to_dict(),
            "margin_image": self.margin_image,
            "lmi_states": None if self.lmi_states is None else list(self.lmi_states),
            "timing": {
                "elimination": self.elimination_time,
                "feasible_boxes": self.box_time,
                "explanations": self.explain_time,
                "lmi": self.lmi_time,
            },
            "result": _plain(self.result),
        }

    def _lmi_entry(self, i: int) -> dict | None:
        if i not in self.lmi:
            return None
        report = self.lmi[i]
        return {
            "status": report.result.status.value,
            "holds": report.holds,
            "certified": bool(report.result.certified),
            "proof": proof_status(report.result),
            "verdict": report.verdict,
            "report": report.to_dict(),
        }

    def _margin_cells(self, i: int) -> tuple[str, str, str, str, str]:
        """Margin, certified bound, first transition, violated state, margin in state units."""
        certificate = self.result.eliminated[i]
        explanation = self.explanations.get(i)
        if explanation is None:
            return (_num(self.result.margins[i], 6), _num(certificate.lower_bound, 6), "-", "-", "-")
        j = explanation.violated
        state = f"{self.state_label(j)} (state {j})"
        if explanation.exact:
            exact = "contradicted exactly"
            return (exact, exact, str(explanation.first_transition), state, "no disturbance reaches it")
        excess = explanation.margin_in_state_units()[j]
        return (
            _num(self.result.margins[i], 6),
            _num(certificate.lower_bound, 6),
            str(explanation.first_transition),
            state,
            f"{_num(excess, 4)} {self.state_unit(j)}",
        )

    def to_markdown(self) -> str:
        """The Markdown document of ``minimaxplan select``: verdicts and margins, explanations, feasible boxes.

        A table of every hypothesis's verdict and margin, why each eliminated one fails,
        the survivors' feasible parameter boxes, Assumption 4 on them (``--lmi``) and the
        timings.
        """
        lines = [
            f"# Model selection report: `{self.model_source}`",
            "",
            f"Data: `{self.data_source}`, {self.ntransitions} transitions, "
            f"{self.nstates} states, {self.ninputs} inputs."
            + (
                ""
                if self.measurement_noise is None
                else f" Measurement noise bound: {_vector(self.measurement_noise)}."
            ),
            "",
            "A hypothesis survives iff some parameter in its prior box explains every transition "
            "with a disturbance inside its bounds (an LP). Its inconsistency margin is the least "
            "inflation of the disturbance set (in units of its radius) that explains the data: 0 "
            "when consistent. A hypothesis is eliminated only with a certificate: a lower bound on "
            "the margin recomputed with numpy (weak duality). The first inconsistent transition n "
            "is the smallest n such that transitions 0..n already contradict the hypothesis (each "
            "prefix's verdict proven the same way); the margin per state is the margin times that "
            "state's disturbance radius, in the state's unit.",
            "",
        ]
        rows: list[tuple[str, ...]] = []
        for i, name in enumerate(self.names):
            margin = _num(self.result.margins[i], 6)
            if i in self.survivors:
                rows.append((str(i), name, "survives", margin, "-", "-", "-", "-"))
            else:
                rows.append((str(i), name, "**eliminated**", *self._margin_cells(i)))
        header = (
            "#",
            "hypothesis",
            "verdict",
            "margin",
            "certified margin >=",
            "first inconsistent transition",
            "violated state",
            "margin on that state (its unit)",
        )
        lines += _table(header, rows) + [""]
        if self.explanations:
            lines += ["## Why each eliminated hypothesis fails", ""]
            for i in sorted(self.explanations):
                lines += [self._explanation_text(self.explanations[i]), ""]
        if self.margin_image is not None:
            lines += [f"![inconsistency margins against N]({self.margin_image})", ""]
        if self.survivors:
            lines += ["## Feasible parameter boxes of the survivors", ""]
            rows = []
            for i in self.survivors:
                box = self.feasible_boxes[i]
                for k in range(box.dim):
                    rows.append(
                        (
                            self.names[i],
                            f"theta[{k}]",
                            _num(box.low[k], 6),
                            _num(box.high[k], 6),
                            _num(box.high[k] - box.low[k], 4),
                        )
                    )
            lines += _table(("hypothesis", "parameter", "low", "high", "width"), rows) + [""]
        else:
            lines += ["**No hypothesis is consistent with the data.**", ""]
        if self.lmi:
            lines += self._lmi_markdown()
        timing = f"Time: elimination {_num(self.elimination_time)} s, feasible boxes {_num(self.box_time)} s"
        if self.explanations or self.history is not None:
            timing += f", explanations {_num(self.explain_time)} s"
        if self.lmi:
            timing += f", Assumption 4 {_num(self.lmi_time)} s"
        lines += [timing + ".", ""]
        return "\n".join(lines)

    def _explanation_text(self, e: InconsistencyExplanation) -> str:
        j = e.violated
        label = f"`{self.state_label(j)}` (state {j})"
        n = e.first_transition
        # Where the contradiction is exact the bound is only relative to the row's rounding
        # scale: the report says that it holds, not a number that reads as "barely".
        bound = (
            f"re-checked: bound above the tolerance {_num(e.certificate.tolerance, 3)}"
            if e.exact
            else f"re-checked bound {_num(e.recheck_bound, 6)} > {_num(e.certificate.tolerance, 3)}"
        )
        before = f"transitions 0..{n - 1} do not" if n > 0 else "no shorter prefix does"
        text = (
            f"**{self.names[e.hypothesis]}**: transitions 0..{n} already contradict it ({before}; "
            f"bisection over prefixes, {e.prefixes_checked} LPs, each verdict proven by a re-checked "
            f"certificate). The dual witness of that prefix (transitions "
            f"{_transitions_text(e.certificate.transitions)}, {bound}) rests on {label}"
        )
        others = [
            f"`{self.state_label(k)}` {100 * e.weights[k]:.0f}%"
            for k in np.argsort(-e.weights, kind="stable")
            if k != j and e.weights[k] >= 0.005
        ]
        text += f" ({100 * e.weights[j]:.0f}% of its weight" + (f"; {', '.join(others)})" if others else ")")
        if e.exact:
            return (
                text + f". Neither the disturbance nor the measurement noise reaches {label}: the hypothesis "
                "gives an exact equation for it, and the data **contradicts it exactly** (no disturbance "
                "bound, however large, explains it)."
            )
        unit = self.state_unit(j)
        prefix, full = e.margin_in_state_units("prefix")[j], e.margin_in_state_units("full")[j]
        return text + (
            f". Margin: {_num(e.prefix_margin, 4)} disturbance radii on transitions 0..{n}, "
            f"{_num(e.margin, 4)} on all {self.ntransitions}; on {label}, whose disturbance radius is "
            f"{_num(e.unit_radius[j], 4)} {unit}, the disturbance would have to exceed its bound by "
            f"{_num(prefix, 4)} {unit} (transitions 0..{n}) and {_num(full, 4)} {unit} (all)."
        )

    def _lmi_markdown(self) -> list[str]:
        where = (
            "all states"
            if self.lmi_states is None
            else "the subsystem of states " + ", ".join(f"`{self.state_label(j)}`" for j in self.lmi_states)
        )
        lines = [
            "## Assumption 4 on each survivor's feasible parameter box",
            "",
            f"Checked over the 2^d vertices of each survivor's feasible parameter box with one common P, on {where}.",
            "",
        ]
        rows = []
        for i in sorted(self.lmi):
            report = self.lmi[i]
            rows.append(
                (
                    self.names[i],
                    report.form,
                    str(len(report.matrices)),
                    report.result.status.value,
                    str(bool(report.result.certified)),
                    proof_status(report.result),
                    report.verdict,
                )
            )
        lines += _table(("survivor", "form", "vertices", "status", "certified", "proof", "verdict"), rows)
        return lines + [""]


def _transitions_text(transitions, limit: int = 12) -> str:
    indices = [str(int(n)) for n in np.ravel(transitions)]
    if len(indices) > limit:
        return ", ".join(indices[:limit]) + f", ... ({len(indices)} in all)"
    return ", ".join(indices)
