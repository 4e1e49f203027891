"""Where Assumption 4 holds: conflicting vertices and certified regions of a parameter box.

`conflicting_vertices` names an irreducible set of matrices with no common Lyapunov
matrix ``P`` (dropping any one of them restores one), by a deletion filter on
`check_assumption4`: every "infeasible" of the filter is proven by an exactly re-checked
`DualCertificate`, every "drop one -> feasible" by an exactly re-checked primal
certificate. `certified_region` splits a parameter box recursively and certifies each
piece with its own ``P`` over the polytope of the piece's corner matrices, up to a depth
or a volume tolerance, and reports the certified fraction of the box (`RegionMap`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from minimaxplan.models import Box, UncertainLinearSystem
from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.models.validation import as_choice, as_count, as_finite_array, as_positive_scalar, check_instance

from .lmi import FORMS, LMIResult, LMIStatus, _as_vertices, check_assumption4

__all__ = ["conflicting_vertices", "certified_region", "ConflictSet", "RegionPiece", "RegionMap", "DEFAULT_MAX_DEPTH"]

#: Default number of bisections along a branch of `certified_region`.
DEFAULT_MAX_DEPTH = 4

MatrixFunction = Callable[[np.ndarray], np.ndarray]


def _condition_number(result: LMIResult) -> float | None:
    eig = result.eigenvalues_P
    if eig is None or not eig[0] > 0:
        return None
    return float(eig[-1] / eig[0])


@dataclass(frozen=True, eq=False)
class ConflictSet:
    """An irreducible set of matrices with no common certificate of Assumption 4.

    Attributes
    ----------
    indices
        Positions, in the caller's sequence, of the conflicting matrices (ascending).
    matrices
        Those matrices, shape (m, p, p), read-only.
    infeasible
        The `LMIResult` of the set: "infeasible", with its exactly re-checked
        `DualCertificate` (no common ``P`` with normalised margin above
        ``infeasible.margin``).
    drop_one
        For each index (same order), an `LMIResult` certified feasible over a superset
        of the set without that matrix (a common ``P`` of a superset serves every
        subset), or an inconclusive one when no proof came out.
    irreducible
        True iff every entry of `drop_one` holds (`LMIResult.holds`): the set is then
        proven irreducible. A single matrix is irreducible when it is infeasible alone.
    """

    indices: tuple[int, ...]
    matrices: np.ndarray
    infeasible: LMIResult
    drop_one: tuple[LMIResult, ...]

    @property
    def irreducible(self) -> bool:
        """True iff dropping any one matrix is proven to restore a common certificate."""
        return all(result.holds for result in self.drop_one)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dictionary (matrices as nested lists; verdicts summarised).

        Returns
        -------
        dict
            ``indices``, ``matrices``, ``irreducible``, ``margin`` (the dual
            certificate's bound) and, per index, the drop-one verdict.
        """
        return {
            "indices": list(self.indices),
            "matrices": self.matrices.tolist(),
            "irreducible": self.irreducible,
            "margin": self.infeasible.margin,
            "drop_one": [
                {"dropped": i, "status": r.status.value, "certified": r.holds, "condition_P": _condition_number(r)}
                for i, r in zip(self.indices, self.drop_one)
            ],
        }


def conflicting_vertices(
    matrices: ArrayLike,
    *,
    form: str,
    D: ArrayLike | None = None,
    margin: float = 1e-6,
    solver: str = "CLARABEL",
) -> ConflictSet:
    """An irreducible subset of ``matrices`` that has no common certificate (deletion filter).

    Parameters
    ----------
    matrices : array_like
        The vertex matrices, shape (k, p, p) or a sequence of (p, p) matrices.
    form : {"continuous", "discrete"}
        The LMI's form (`check_assumption4`).
    D : array_like or None
        Disturbance input matrix (p, r); default the identity.
    margin : float
        Normalised margin of the "infeasible" verdicts (`check_assumption4`).
    solver : {"CLARABEL", "SCS"}
        The SDP solver.

    Returns
    -------
    ConflictSet
        The set, its dual certificate and the drop-one certificates.

    Raises
    ------
    InputError
        If the whole set is not proven infeasible (it has a common certificate, or no
        proof either way came out): there is no proven conflict to reduce.
    DimensionError
        ``matrices`` or ``D`` of the wrong shape.

    Notes
    -----
    Assumption 4 over a polytope (eq. (8)). The deletion filter keeps a working set
    ``S`` (all matrices, proven infeasible) and, for each ``i`` in order, checks
    ``S - {i}``: if it is proven infeasible, ``i`` is dropped; otherwise ``i`` stays,
    with the verdict of ``S - {i}``. The final ``S`` is infeasible (its dual certificate
    is the last infeasible verdict), and each ``S - {i}`` is a subset of the set checked
    when ``i`` was kept, so a certificate found then serves it.
    """
    form = as_choice("form", form, FORMS)
    vertices = _as_vertices(matrices)

    def check(indices: list[int]) -> LMIResult:
        return check_assumption4(vertices[indices], form=form, D=D, margin=margin, solver=solver)

    working = list(range(vertices.shape[0]))
    proof = check(working)
    if proof.status is not LMIStatus.INFEASIBLE:
        raise InputError(
            f"the {len(working)} matrices are not proven to lack a common certificate "
            f"(status {proof.status.value!r}): there is no conflict to reduce"
        )
    kept: dict[int, LMIResult] = {}
    for i in list(working):
        rest = [j for j in working if j != i]
        if not rest:
            break
        verdict = check(rest)
        if verdict.status is LMIStatus.INFEASIBLE:
            working, proof = rest, verdict
        else:
            kept[i] = verdict
    if len(working) == 1:
        # the empty set trivially has a certificate: a single infeasible matrix is irreducible
        only = working[0]
        kept[only] = _trivial_feasible(form, vertices.shape[1])
    return ConflictSet(
        indices=tuple(working),
        matrices=_read_only(vertices[working]),
        infeasible=proof,
        drop_one=tuple(kept[i] for i in working),
    )


def _trivial_feasible(form: str, p: int) -> LMIResult:
    """The empty set's verdict: every ``P > 0`` serves it (P = Q0 = I, rho = 1)."""
    eye = _read_only(np.eye(p))
    return LMIResult(
        status=LMIStatus.FEASIBLE,
        form=form,
        P=eye,
        rho=1.0,
        Q0=eye,
        certified=True,
        inaccurate=False,
        solver="none",
        solver_status="not solved (empty set)",
        solve_time=0.0,
        max_eigenvalue=None,
        eigenvalues_P=_read_only(np.ones(p)),
        nvertices=0,
    )


def _read_only(a: np.ndarray) -> np.ndarray:
    out = np.array(a, dtype=float, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class RegionPiece:
    """One leaf of `certified_region`: a sub-box of the parameter box and its verdict.

    Attributes
    ----------
    box
        The piece, a sub-box of the parameter box.
    depth
        Number of bisections that produced it (0 for the whole box).
    fraction
        Its volume as a fraction of the parameter box's (over the box's non-degenerate
        sides).
    result
        The `LMIResult` of `check_assumption4` on the matrices at the piece's corners.
    """

    box: Box
    depth: int
    fraction: float
    result: LMIResult

    @property
    def certified(self) -> bool:
        """True iff one ``P`` is proven to serve every corner matrix (`LMIResult.holds`)."""
        return self.result.holds

    @property
    def status(self) -> LMIStatus:
        """The piece's verdict (`LMIResult.status`)."""
        return self.result.status

    @property
    def condition_P(self) -> float | None:
        """``lmax(P) / lmin(P)`` of the piece's certificate, or None without one."""
        return _condition_number(self.result)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready summary of the piece (bounds, verdict, certificate figures).

        Returns
        -------
        dict
            ``low``, ``high``, ``depth``, ``fraction``, ``status``, ``certified``,
            ``slack`` (normalised), ``margin`` (of a dual certificate), ``condition_P``.
        """
        return {
            "low": self.box.low.tolist(),
            "high": self.box.high.tolist(),
            "depth": self.depth,
            "fraction": self.fraction,
            "status": self.result.status.value,
            "certified": self.certified,
            "slack": self.result.slack,
            "margin": self.result.margin,
            "condition_P": self.condition_P,
        }


@dataclass(frozen=True, eq=False)
class RegionMap:
    """The outcome of `certified_region`: where Assumption 4 is certified in a box.

    Attributes
    ----------
    box
        The parameter box that was split.
    form
        ``"continuous"`` or ``"discrete"``.
    pieces
        The leaves of the subdivision, in depth-first order (lower halves first); they
        tile the box.
    max_depth, min_volume
        The limits the subdivision stopped at.
    conflict
        For a box that is proven infeasible as a whole: the `ConflictSet` of its corner
        matrices; None otherwise.
    """

    box: Box
    form: str
    pieces: tuple[RegionPiece, ...]
    max_depth: int
    min_volume: float
    conflict: ConflictSet | None = None

    def _fraction(self, status: LMIStatus | None) -> float:
        if status is None:
            return float(sum(piece.fraction for piece in self.pieces if piece.certified))
        return float(sum(piece.fraction for piece in self.pieces if piece.status is status and not piece.certified))

    @property
    def certified_fraction(self) -> float:
        """Fraction of the box's volume covered by certified pieces (each with its own ``P``)."""
        return self._fraction(None)

    @property
    def infeasible_fraction(self) -> float:
        """Fraction covered by pieces proven to have no common ``P`` over their corners."""
        return self._fraction(LMIStatus.INFEASIBLE)

    @property
    def inconclusive_fraction(self) -> float:
        """Fraction covered by pieces with no proof either way."""
        return self._fraction(LMIStatus.INCONCLUSIVE)

    @property
    def certified_pieces(self) -> tuple[RegionPiece, ...]:
        """The certified leaves."""
        return tuple(piece for piece in self.pieces if piece.certified)

    @property
    def uncovered_pieces(self) -> tuple[RegionPiece, ...]:
        """The leaves that are not certified (infeasible or inconclusive at the depth reached)."""
        return tuple(piece for piece in self.pieces if not piece.certified)

    @property
    def holds(self) -> bool:
        """True iff one ``P`` is certified over the whole box (a single certified piece)."""
        return len(self.pieces) == 1 and self.pieces[0].certified

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dictionary: the box, the fractions, the pieces and the conflict.

        Returns
        -------
        dict
        """
        return {
            "box": self.box.to_dict(),
            "form": self.form,
            "max_depth": self.max_depth,
            "min_volume": self.min_volume,
            "certified_fraction": self.certified_fraction,
            "infeasible_fraction": self.infeasible_fraction,
            "inconclusive_fraction": self.inconclusive_fraction,
            "pieces": [piece.to_dict() for piece in self.pieces],
            "conflict": None if self.conflict is None else self.conflict.to_dict(),
        }


def certified_region(
    system: UncertainLinearSystem | MatrixFunction,
    box: Box | None = None,
    *,
    form: str,
    D: ArrayLike | None = None,
    max_depth: int = DEFAULT_MAX_DEPTH,
    min_volume: float = 0.0,
    margin: float = 1e-6,
    solver: str = "CLARABEL",
) -> RegionMap:
    """Split a parameter box recursively and certify Assumption 4 on each piece.

    Parameters
    ----------
    system : UncertainLinearSystem or callable
        The plant (its ``A(theta)`` is affine in ``theta``, eq. (2)), or a function that
        maps parameter points, shape (m, d), to matrices, shape (m, p, p); it must be
        affine in theta for a certified piece to cover its whole box (see Notes).
    box : Box or None
        The parameter box; default ``system.theta`` (required for a callable).
    form : {"continuous", "discrete"}
        The LMI's form (`check_assumption4`).
    D : array_like or None
        Disturbance input matrix (p, r); default ``system.D`` for a system, else the
        identity.
    max_depth : int
        Largest number of bisections along a branch (>= 0; default `DEFAULT_MAX_DEPTH`).
    min_volume : float
        A piece is split only if each half keeps at least this fraction (in [0, 1]) of
        the box's volume. Default 0 (only ``max_depth`` limits).
    margin : float
        Normalised margin of the "infeasible" verdicts (`check_assumption4`).
    solver : {"CLARABEL", "SCS"}
        The SDP solver.

    Returns
    -------
    RegionMap
        The pieces with their verdicts, the certified fraction, and the conflicting
        corner matrices of the whole box when it is proven infeasible.

    Raises
    ------
    InputError
        A callable without a ``box``, an unknown ``form``, ``max_depth`` < 0, a
        ``min_volume`` outside [0, 1].
    DimensionError
        A box whose dimension is not the system's, matrices that are not square.

    Notes
    -----
    Assumption 4 over a polytope (eq. (8)). A piece is certified only on a "feasible"
    verdict of `check_assumption4` (exactly re-checked) over the matrices at its 2^d
    corners; since ``A`` is affine in ``theta`` their convex hull contains ``A(theta)``
    for every ``theta`` in the piece, so one ``P`` serves the whole piece. A piece that
    is not certified is bisected (at its midpoint, along the side that is widest
    relative to the box's; degenerate sides are never split) until ``max_depth`` or
    ``min_volume`` stops it. Different pieces have different ``P``: the map says where
    the LMI holds piecewise, not that one ``P`` serves the union.
    """
    form = as_choice("form", form, FORMS)
    max_depth = as_count("max_depth", max_depth, minimum=0)
    min_volume = as_positive_scalar("min_volume", min_volume, allow_zero=True)
    if min_volume > 1:
        raise InputError(f"min_volume must be a fraction in [0, 1], got {min_volume}")
    D_mat: np.ndarray | None = None if D is None else as_finite_array("D", D, ndim=2)
    if isinstance(system, UncertainLinearSystem):
        matrix_function: MatrixFunction = system.A
        root = system.theta if box is None else box
        check_instance("box", root, Box)
        if root.dim != system.nparams:
            raise DimensionError(f"box must have dimension {system.nparams} (the system's d), got {root.dim}")
        if D_mat is None:
            D_mat = np.asarray(system.D)
    else:
        if not callable(system):
            raise InputError(f"system must be an UncertainLinearSystem or a callable, got {type(system).__name__}")
        if box is None:
            raise InputError("certified_region needs a box for a matrix function")
        matrix_function = system
        root = box
        check_instance("box", root, Box)
    widths = root.high - root.low
    splittable = widths > 0

    def fraction(piece: Box) -> float:
        if not np.any(splittable):
            return 1.0
        return float(np.prod((piece.high - piece.low)[splittable] / widths[splittable]))

    def check(piece: Box) -> LMIResult:
        matrices = np.asarray(matrix_function(piece.vertices()), dtype=float)
        if matrices.ndim != 3:
            raise DimensionError(f"the matrix function must return shape (m, p, p), got shape {matrices.shape}")
        return check_assumption4(matrices, form=form, D=D_mat, margin=margin, solver=solver)

    leaves: list[RegionPiece] = []
    root_result: LMIResult | None = None

    def visit(piece: Box, depth: int) -> None:
        nonlocal root_result
        result = check(piece)
        if depth == 0:
            root_result = result
        share = fraction(piece)
        if result.holds or depth >= max_depth or not np.any(splittable) or share / 2 < min_volume:
            leaves.append(RegionPiece(piece, depth, share, result))
            return
        relative = np.where(splittable, (piece.high - piece.low) / np.where(splittable, widths, 1.0), -1.0)
        axis = int(np.argmax(relative))
        middle = 0.5 * (piece.low[axis] + piece.high[axis])
        lower_high, upper_low = piece.high.copy(), piece.low.copy()
        lower_high[axis] = middle
        upper_low[axis] = middle
        visit(Box(piece.low, lower_high), depth + 1)
        visit(Box(upper_low, piece.high), depth + 1)

    visit(root, 0)
    conflict = None
    if root_result is not None and root_result.status is LMIStatus.INFEASIBLE:
        corners = np.asarray(matrix_function(root.vertices()), dtype=float)
        conflict = conflicting_vertices(corners, form=form, D=D_mat, margin=margin, solver=solver)
    return RegionMap(root, form, tuple(leaves), max_depth, float(min_volume), conflict)
