"""The stability LMI of Assumption 4, solved with cvxpy and re-checked with numpy.

`check_assumption4` decides whether one matrix, or every vertex of a matrix polytope
with one common ``P`` (eq. (8)), satisfies the Lyapunov-type LMI of Assumption 4, and
returns an `LMIResult` that carries the certificate ``(P, rho, Q0)``, its independent
numpy re-check, and the error-bound constants that the certificate buys (Theorem 2,
corrected: see `LMIResult.width_bound`).
"""

from __future__ import annotations

import dataclasses
import threading
import time
import warnings
from collections import OrderedDict
from dataclasses import dataclass
from enum import Enum
from typing import Any

import cvxpy as cp
import numpy as np
import scipy.linalg as sla
from scipy.optimize import minimize_scalar

from minimaxplan.models.errors import DimensionError, InputError, SolverFailure
from minimaxplan.models.validation import as_choice, as_finite_array, as_positive_scalar, check_shape, frozen_copy

__all__ = ["check_assumption4", "LMIResult", "LMIStatus", "lmi_matrix", "FORMS", "SOLVERS"]

#: The two LMI forms: continuous time ``e' = A e + D w``, discrete time ``e+ = A e + D w``.
FORMS = ("continuous", "discrete")
#: Solvers that handle the semidefinite program (Clarabel is the default).
SOLVERS = ("CLARABEL", "SCS")

#: A computed eigenvalue of a symmetric matrix M is trusted to within
#: ``EIGENVALUE_ROUNDING * n * eps * ||M||_F`` (backward stability of eigvalsh, plus the
#: rounding made when M itself is assembled); certification demands a margin beyond it.
EIGENVALUE_ROUNDING = 64.0
#: The returned rho is this factor times the smallest rho that the returned (P, Q0) allow.
RHO_FACTOR = 1.01
#: Solver feasibility/gap tolerance (at most margin / 10, so that ``t* > margin`` decides).
SOLVER_TOLERANCE = 1e-7
#: Cache size of built cvxpy problems (one per form, p, vertex count, Q0 given or not).
PROBLEM_CACHE_SIZE = 32
#: Smallest shift (relative to 1 + ||A||) of the preconditioner's Lyapunov equation.
_SHIFT_FLOOR = 1e-3
#: A preconditioner whose condition number exceeds this is not used (identity instead).
_MAX_PRECONDITIONER_CONDITION = 1e12

_INACCURATE = {cp.OPTIMAL_INACCURATE, cp.INFEASIBLE_INACCURATE}


class LMIStatus(str, Enum):
    """The three outcomes of `check_assumption4` (the contract's strings).

    A ``str`` enum: ``LMIStatus.FEASIBLE == "feasible"`` holds, ``str()`` and
    ``format()`` give the plain string, and `LMIResult.to_dict` emits it.

    Attributes
    ----------
    FEASIBLE
        A certificate was found and passed the numpy re-check.
    INFEASIBLE
        No certificate exists with the stated margin (the normalised slack ``t* <= margin``).
    INCONCLUSIVE
        An inaccurate solver answer, or a certificate that failed the re-check.
    """

    FEASIBLE = "feasible"
    INFEASIBLE = "infeasible"
    INCONCLUSIVE = "inconclusive"

    __str__ = str.__str__
    __format__ = str.__format__


@dataclass(frozen=True, eq=False)
class LMIResult:
    """Outcome of `check_assumption4`: a decision, a certificate and its re-check.

    Attributes
    ----------
    status
        ``"feasible"`` (a certificate was found and passed the numpy re-check),
        ``"infeasible"`` (the solver's largest normalised slack ``t*`` is at most
        ``margin``: no certificate exists with that margin) or
        ``"inconclusive"`` (an inaccurate solver answer, or a certificate that failed the
        re-check; `reason` says which).
    form
        ``"continuous"`` or ``"discrete"``.
    P, Q0, rho
        The certificate in the caller's coordinates (``None`` unless the solver returned
        a point). ``Q0`` is the caller's matrix when one was given.
    certified
        True iff ``P`` is positive definite and every vertex's LMI matrix (the original,
        non-linear form for ``"discrete"``) is negative definite by numpy eigenvalues,
        beyond their rounding error.
    inaccurate
        True iff the solver reported an inaccurate status.
    solver, solver_status
        The solver used and its raw cvxpy status.
    solve_time
        Wall-clock seconds of the cvxpy solve calls (parameter update and
        canonicalisation included; both solves when a second one was made).
    max_eigenvalue
        Largest eigenvalue over the vertices of the LMI matrix at the certificate
        (< 0 when certified), or None.
    eigenvalues_P
        Eigenvalues of ``P`` in ascending order, or None.
    nvertices
        Number of matrices that share the certificate.
    reason
        A sentence explaining an infeasible or inconclusive outcome ("" when feasible).
    coordinates
        Where the SDP that produced the outcome was solved: ``"preconditioned"`` or
        ``"caller"`` (see `check_assumption4`, *Scaling*).
    slack
        The optimal normalised slack ``t*`` of the solve that decided (compared with
        ``margin``), or None when the solver gave no optimum.
    """

    status: LMIStatus
    form: str
    P: np.ndarray | None
    rho: float | None
    Q0: np.ndarray | None
    certified: bool
    inaccurate: bool
    solver: str
    solver_status: str
    solve_time: float
    max_eigenvalue: float | None
    eigenvalues_P: np.ndarray | None
    nvertices: int
    reason: str = ""
    coordinates: str = "caller"
    slack: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "status", LMIStatus(self.status))

    @property
    def holds(self) -> bool:
        """True iff Assumption 4 holds: the status is feasible and the certificate passed the re-check."""
        return self.status is LMIStatus.FEASIBLE and bool(self.certified)

    def bound_constants(self) -> tuple[float, float]:
        """The constants ``(c0, cw)`` of the error bound that this certificate buys.

        ``c0 = sqrt(lmax(P) / lmin(P))`` and
        ``cw = sqrt(rho lmax(P) / (lmin(P) lmin(Q0)))``.

        Raises
        ------
        InputError
            If the result is not a certified feasible one.

        Notes
        -----
        See `width_bound` for the derivation (Appendix B, eqs. (25)-(30), corrected).
        """
        self._require_certificate()
        eig_p = self.eigenvalues_P
        lmin_q0 = float(np.linalg.eigvalsh(self.Q0)[0])
        c0 = float(np.sqrt(eig_p[-1] / eig_p[0]))
        cw = float(np.sqrt(self.rho * eig_p[-1] / (eig_p[0] * lmin_q0)))
        return c0, cw

    def decay_factor(self) -> float:
        """``1 - mu`` with ``mu = lmin(Q0) / lmax(P)``: the per-step contraction of
        ``V = e^T P e`` (discrete form), or ``exp(-mu)`` per unit time (continuous)."""
        self._require_certificate()
        mu = float(np.linalg.eigvalsh(self.Q0)[0] / self.eigenvalues_P[-1])
        return float(1.0 - mu) if self.form == "discrete" else float(np.exp(-mu))

    def width_bound(self, e0_norm, w_width_norm, steps=None):
        """Bound on ``||e_n||_2`` for ``e+ = A e + D w`` (or ``e' = A e + D w``).

        Parameters
        ----------
        e0_norm
            ``||e_0||_2`` (>= 0).
        w_width_norm
            ``sup_n ||w_n||_2`` (>= 0); for interval widths, ``sup ||w_hi - w_lo||_2``.
        steps
            Optional step count n (discrete form) or time t (continuous form), an int or
            an array; gives the tighter time-dependent bound. Without it, the uniform
            bound ``c0 ||e_0|| + cw sup ||w||`` valid for every n.

        Returns
        -------
        float or numpy.ndarray
            The bound (an array when ``steps`` is an array).

        Notes
        -----
        With ``V = e^T P e`` and the certified LMI (the quadratic form of the discrete
        LMI at ``[e; w]`` is negative):

        ``V+ = (A e + D w)^T P (A e + D w) < V - e^T Q0 e + rho ||w||^2
        <= (1 - mu) V + rho ||w||^2``, ``mu = lmin(Q0) / lmax(P)``, ``0 < mu < 1``
        (the LMI's top-left block gives ``Q0 < P``). By induction
        ``V_n <= (1 - mu)^n V_0 + rho W^2 (1 - (1 - mu)^n) / mu``, and with
        ``lmin(P) ||e||^2 <= V <= lmax(P) ||e||^2`` and ``sqrt(a + b) <= sqrt(a) + sqrt(b)``:

        ``||e_n|| <= c0 (1 - mu)^(n/2) ||e_0|| + cw sqrt(1 - (1 - mu)^n) W
        <= c0 ||e_0|| + cw W``.

        The continuous form is the same with ``dV/dt <= -mu V + rho ||w||^2`` and
        ``exp(-mu t)`` in place of ``(1 - mu)^n``. This is the bound of Theorem 2 (eq.
        (29)) without the factor 2 that the paper's proof loses to ``Q = Q0 / 2``.

        Interval widths (Errata): with no parametric uncertainty the discrete predictor's
        width obeys ``e+ <= |A_N| e + |D| (w_hi - w_lo)`` elementwise, with ``e >= 0``.
        Since ``|A_N|, |D| >= 0``, the comparison system with equality dominates ``e``
        elementwise (induction), hence in 2-norm; so a certificate from
        ``check_assumption4(abs(A_N), form="discrete", D=abs(D))`` bounds the widths.
        """
        self._require_certificate()
        e0 = as_positive_scalar("e0_norm", e0_norm, allow_zero=True)
        ww = as_positive_scalar("w_width_norm", w_width_norm, allow_zero=True)
        c0, cw = self.bound_constants()
        if steps is None:
            return c0 * e0 + cw * ww
        n = as_finite_array("steps", steps)
        if np.any(n < 0):
            raise InputError("steps must be >= 0")
        decay = self.decay_factor() ** n
        out = c0 * np.sqrt(decay) * e0 + cw * np.sqrt(1.0 - decay) * ww
        return float(out) if out.ndim == 0 else out

    def _require_certificate(self) -> None:
        if not self.holds:
            raise InputError(f"bound constants need a certified feasible LMIResult, got status {self.status.value!r}")

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dictionary (arrays as nested lists, absent values as None)."""

        def listed(a):
            return None if a is None else np.asarray(a).tolist()

        out = {
            "status": self.status.value,
            "form": self.form,
            "P": listed(self.P),
            "rho": self.rho,
            "Q0": listed(self.Q0),
            "certified": self.certified,
            "inaccurate": self.inaccurate,
            "solver": self.solver,
            "solver_status": self.solver_status,
            "solve_time": self.solve_time,
            "max_eigenvalue": self.max_eigenvalue,
            "eigenvalues_P": listed(self.eigenvalues_P),
            "nvertices": self.nvertices,
            "reason": self.reason,
            "coordinates": self.coordinates,
            "slack": self.slack,
        }
        if self.holds:
            out["bound_constants"] = list(self.bound_constants())
        return out


# --------------------------------------------------------------------------- input


def _as_vertices(A) -> np.ndarray:
    if isinstance(A, (list, tuple)):
        if len(A) == 0:
            raise DimensionError("A must hold at least one matrix, got an empty sequence")
        shapes = [np.shape(matrix) for matrix in A]
        if len(set(shapes)) > 1:
            raise DimensionError(f"A's matrices must all have one shape (p, p), got shapes {shapes}")
    given = as_finite_array("A", A)
    stack = given[None] if given.ndim == 2 else given
    if stack.ndim != 3 or stack.shape[0] == 0 or stack.shape[1] != stack.shape[2] or stack.shape[1] == 0:
        raise DimensionError(f"A must have shape (p, p) or (k, p, p) with k, p >= 1, got shape {given.shape}")
    return stack


def _as_q0(Q0, p: int) -> np.ndarray | None:
    if Q0 is None:
        return None
    q0 = as_finite_array("Q0", Q0)
    check_shape("Q0", q0, (p, p))
    if not np.allclose(q0, q0.T, rtol=1e-12, atol=1e-12 * np.abs(q0).max()):
        raise InputError("Q0 must be symmetric")
    q0 = (q0 + q0.T) / 2
    if np.linalg.eigvalsh(q0)[0] <= 0:
        raise InputError(f"Q0 must be positive definite, its smallest eigenvalue is {np.linalg.eigvalsh(q0)[0]:.3g}")
    return q0


def _as_solver(solver) -> str:
    name = as_choice("solver", solver, SOLVERS, ignore_case=True)
    if name not in cp.installed_solvers():
        raise InputError(f"solver {name!r} is not installed for cvxpy")
    return name


# --------------------------------------------------------------------------- the SDP


@dataclass(frozen=True)
class _Program:
    problem: cp.Problem
    A: tuple
    Q0: cp.Parameter | None
    P: cp.Variable
    Q: Any
    slack: cp.Variable
    sigma: cp.Variable | None


def _lyapunov_block(form: str, A, P, Q):
    """The LMI without its disturbance row and column (see check_assumption4, Notes)."""
    if form == "continuous":
        M = A.T @ P + P @ A + Q
    else:
        M = cp.bmat([[Q - P, A.T @ P], [P @ A, -P]])
    return (M + M.T) / 2


def _build_program(form: str, p: int, k: int, q0_given: bool) -> _Program:
    """maximise t  s.t.  t I <= P <= I,  Q0 >= t I,  Lyapunov block_k <= -t I."""
    A = tuple(cp.Parameter((p, p), name=f"A{i}") for i in range(k))
    P = cp.Variable((p, p), symmetric=True, name="P")
    slack = cp.Variable(name="t")
    eye = np.eye(p)
    constraints = [P << eye, P >> slack * eye]
    if q0_given:
        q0_param = cp.Parameter((p, p), symmetric=True, name="Q0")
        sigma = cp.Variable(name="sigma")
        Q = sigma * q0_param
        constraints.append(sigma >= slack)
    else:
        q0_param = sigma = None
        Q = cp.Variable((p, p), symmetric=True, name="Q0")
        constraints.append(Q >> slack * eye)
    size = 2 * p if form == "discrete" else p
    for Ai in A:
        constraints.append(_lyapunov_block(form, Ai, P, Q) << -slack * np.eye(size))
    problem = cp.Problem(cp.Maximize(slack), constraints)
    return _Program(problem, A, q0_param, P, Q, slack, sigma)


_PROGRAMS: OrderedDict[tuple, _Program] = OrderedDict()
# The cached problems' parameters are set per call: one call at a time per process.
_LOCK = threading.Lock()


def _program(form: str, p: int, k: int, q0_given: bool) -> _Program:
    """The cached DPP problem for this structure (least recently used evicted)."""
    key = (form, p, k, q0_given)
    if key in _PROGRAMS:
        _PROGRAMS.move_to_end(key)
        return _PROGRAMS[key]
    program = _build_program(form, p, k, q0_given)
    _PROGRAMS[key] = program
    while len(_PROGRAMS) > PROBLEM_CACHE_SIZE:
        _PROGRAMS.popitem(last=False)
    return program


def _solver_options(solver: str, margin: float) -> dict:
    """Tolerances well below the decision margin (the decision compares t* with it)."""
    tolerance = min(SOLVER_TOLERANCE, margin / 10)
    if solver == "CLARABEL":
        return {"tol_feas": tolerance, "tol_gap_abs": tolerance, "tol_gap_rel": tolerance}
    return {"eps_abs": tolerance, "eps_rel": tolerance}


def _run_solver(problem: cp.Problem, solver: str, margin: float) -> str:
    try:
        with warnings.catch_warnings():
            # cvxpy warns on inaccurate statuses; they are mapped to a flagged result instead.
            warnings.filterwarnings("ignore", message="Solution may be inaccurate", category=UserWarning)
            problem.solve(solver=solver, **_solver_options(solver, margin))
    except cp.error.SolverError as exc:
        raise SolverFailure(f"{solver} failed on the Assumption 4 LMI: {exc}") from exc
    return str(problem.status)


# --------------------------------------------------------------------------- scaling


def _preconditioner(vertices: np.ndarray, form: str) -> tuple[np.ndarray, np.ndarray]:
    """A similarity ``T`` (and ``T^-1``) that makes the solver's problem well scaled.

    ``T = Phat^(-1/2)`` where ``Phat`` is a Lyapunov (Stein) solution for the mean vertex
    with its spectrum shifted halfway towards the stability boundary, so that in the new
    coordinates a multiple of the identity nearly certifies the mean vertex. Changing
    coordinates never changes feasibility (a congruence of the LMI); it only moves the
    solver's problem away from the scale at which its tolerance matters.
    """
    p = vertices.shape[1]
    mean = vertices.mean(axis=0)
    eigenvalues = np.linalg.eigvals(mean)
    scale = 1.0 + np.linalg.norm(mean, 2)
    try:
        if form == "continuous":
            abscissa = eigenvalues.real.max()
            shift = abscissa + max(abs(abscissa) / 2, _SHIFT_FLOOR * scale)
            phat = sla.solve_continuous_lyapunov((mean - shift * np.eye(p)).T, -np.eye(p))
        else:
            radius = np.abs(eigenvalues).max()
            target = radius + max(abs(1.0 - radius) / 2, _SHIFT_FLOOR)
            phat = sla.solve_discrete_lyapunov(mean.T / target, np.eye(p))
        phat = (phat + phat.T) / 2
        lam, U = np.linalg.eigh(phat)
    except (np.linalg.LinAlgError, ValueError):
        return np.eye(p), np.eye(p)
    if not np.all(np.isfinite(lam)) or lam[0] <= 0 or lam[-1] / lam[0] > _MAX_PRECONDITIONER_CONDITION:
        return np.eye(p), np.eye(p)
    lam = lam / lam[-1]
    T = (U / np.sqrt(lam)) @ U.T
    T_inv = (U * np.sqrt(lam)) @ U.T
    return T, T_inv


# --------------------------------------------------------------------------- numpy re-check


def _rounding(M: np.ndarray) -> float:
    return EIGENVALUE_ROUNDING * M.shape[0] * np.finfo(float).eps * float(np.linalg.norm(M))


def lmi_matrix(A, P, Q0, rho: float, D, form: str) -> np.ndarray:
    """The matrix that Assumption 4 requires to be negative definite, at a given certificate.

    Parameters
    ----------
    A
        The state matrix, shape (p, p).
    P, Q0
        The certificate's matrices, shape (p, p).
    rho
        The disturbance gain.
    D
        The disturbance matrix, shape (p, r), or None for the identity.
    form
        ``"continuous"`` or ``"discrete"``.

    Returns
    -------
    numpy.ndarray
        The symmetrised matrix, shape (p + r, p + r).

    Raises
    ------
    InputError
        If ``form`` is not one of `FORMS`.

    Notes
    -----
    Continuous form (Assumption 4, with the disturbance matrix D):
    ``[[A^T P + P A + Q0, P D], [D^T P, -rho I]]``. Discrete form, for
    ``e+ = A e + D w``: ``[[A^T P A - P + Q0, A^T P D], [D^T P A, D^T P D - rho I]]``
    (the original, non-linear form, which the numpy re-check of `check_assumption4` uses).
    """
    form = as_choice("form", form, FORMS)
    A, P, Q0 = (np.asarray(m, dtype=float) for m in (A, P, Q0))
    D = np.eye(A.shape[0]) if D is None else np.asarray(D, dtype=float)
    r = D.shape[1]
    if form == "continuous":
        top, coupling, corner = A.T @ P + P @ A + Q0, P @ D, -rho * np.eye(r)
    else:
        top, coupling, corner = A.T @ P @ A - P + Q0, A.T @ P @ D, D.T @ P @ D - rho * np.eye(r)
    M = np.block([[top, coupling], [coupling.T, corner]])
    return (M + M.T) / 2


def _smallest_rho(form: str, vertices: np.ndarray, D: np.ndarray, P: np.ndarray, Q0: np.ndarray):
    """The infimum of rho for which the LMI holds at (P, Q0), by the Schur complement.

    ``M < 0`` iff ``N < 0`` and ``rho I > H + G^T (-N)^-1 G`` with ``N`` the top-left block
    without rho, ``G`` the coupling block and ``H`` = 0 (continuous) or ``D^T P D``
    (discrete). Returns ``(rho_inf, slack)`` with ``slack = min_k -lmax(N_k)``, or None
    when some ``N`` is not negative definite.
    """
    rho, slack = 0.0, np.inf
    for A in vertices:
        if form == "continuous":
            N, G, H = A.T @ P + P @ A + Q0, P @ D, np.zeros((D.shape[1],) * 2)
        else:
            N, G, H = A.T @ P @ A - P + Q0, A.T @ P @ D, D.T @ P @ D
        try:
            L = np.linalg.cholesky(-(N + N.T) / 2)
        except np.linalg.LinAlgError:
            return None
        slack = min(slack, -float(np.linalg.eigvalsh((N + N.T) / 2)[-1]))
        X = sla.solve_triangular(L, G, lower=True)
        S = H + X.T @ X
        rho = max(rho, float(np.linalg.eigvalsh((S + S.T) / 2)[-1]))
    return rho, slack


def _disturbance_gain(form, vertices, D, P, Q0) -> float:
    """``rho / lmin(Q0)`` for the returned rho (the factor of ``cw^2`` that Q0 controls)."""
    smallest = _smallest_rho(form, vertices, D, P, Q0)
    if smallest is None:
        return np.inf
    return RHO_FACTOR * smallest[0] / float(np.linalg.eigvalsh(Q0)[0])


def _tuned_q0(form: str, vertices: np.ndarray, D: np.ndarray, P: np.ndarray, Q_solver: np.ndarray) -> np.ndarray:
    """The free Q0 that makes ``cw`` smallest for the solver's P: ``q I`` or the solver's.

    ``cw^2 = rho lmax(P) / (lmin(P) lmin(Q0))``; for fixed P, a larger ``Q0`` raises the
    smallest admissible rho, so ``rho(q I) / q`` is minimised over ``0 < q < q_max``,
    ``q_max = min_k -lmax(N0_k)`` (``N0`` the Lyapunov block without Q0), by a bounded
    scalar search; the solver's own Q0 is kept if it does better.
    """
    p = P.shape[0]
    if form == "continuous":
        blocks = [A.T @ P + P @ A for A in vertices]
    else:
        blocks = [A.T @ P @ A - P for A in vertices]
    q_max = min(-float(np.linalg.eigvalsh((N + N.T) / 2)[-1]) for N in blocks)
    if not q_max > 0:
        return Q_solver
    search = minimize_scalar(
        lambda s: _disturbance_gain(form, vertices, D, P, s * q_max * np.eye(p)),
        bounds=(1e-6, 1 - 1e-6),
        method="bounded",
        options={"xatol": 1e-4},
    )
    candidate = float(search.x) * q_max * np.eye(p)
    if _disturbance_gain(form, vertices, D, P, candidate) < _disturbance_gain(form, vertices, D, P, Q_solver):
        return candidate
    return Q_solver


# --------------------------------------------------------------------------- entry point


def check_assumption4(A, *, form, Q0=None, D=None, margin=1e-6, solver="CLARABEL") -> LMIResult:
    """Decide the LMI of Assumption 4 for a matrix or a polytope of matrices.

    Parameters
    ----------
    A
        One matrix (p, p), or the vertices of a matrix polytope, shape (k, p, p) or a
        sequence of (p, p) matrices (eq. (8)); one common ``P`` must serve them all, which
        makes the LMI hold uniformly over the polytope (it is affine in ``A`` for the
        continuous form and, in the linear form below, for the discrete form).
    form
        ``"continuous"``: ``[[A^T P + P A + Q0, P D], [D^T P, -rho I]] < 0`` with
        ``P > 0`` (the paper's LMI, ``D = I``).
        ``"discrete"``: ``[[A^T P A - P + Q0, A^T P D], [D^T P A, D^T P D - rho I]] < 0``,
        ``P > 0``, the analogue for ``e+ = A e + D w``.
    Q0
        A symmetric positive definite (p, p) matrix, or None to let the solver choose one
        (``Q0 > 0``).
    D
        Disturbance input matrix (p, r); default the identity. Extends the paper's
        continuous LMI (where ``D = I``) in the obvious way.
    margin
        Strictness margin: the LMI counts as feasible only if it holds with the
        normalised slack ``t > margin`` (see Notes).
    solver
        ``"CLARABEL"`` (default) or ``"SCS"``.

    Returns
    -------
    LMIResult

    Raises
    ------
    DimensionError, NonFiniteError, InputError
        Bad shapes, NaN/inf entries, a ``form`` or ``solver`` not known, a ``Q0`` that is
        not symmetric positive definite, a ``margin`` that is not > 0.
    SolverFailure
        The solver raised an error, or returned a status other than optimal or an
        inaccurate status (infeasible or unbounded cannot happen for this problem).

    Notes
    -----
    Assumption 4 and Theorem 2 (Appendix B, eqs. (25)-(29)).

    *Linear form of the discrete LMI.* With ``P > 0``, the Schur complement of the block
    ``-P`` in

    ``L = [[Q0 - P, 0, A^T P], [0, -rho I, D^T P], [P A, P D, -P]]``

    is ``[[Q0 - P, 0], [0, -rho I]] + [A^T P; D^T P] P^-1 [P A, P D]
    = [[A^T P A - P + Q0, A^T P D], [D^T P A, D^T P D - rho I]]``, so ``L < 0`` iff
    ``P > 0`` and the discrete LMI holds. ``L`` is affine in ``(P, Q0, rho)`` and in ``A``,
    hence the cvxpy problem is DPP: it is built once per (form, p, k, Q0 given?) with
    ``A`` (and ``Q0``) as parameters, cached (LRU, `PROBLEM_CACHE_SIZE`), and re-solved.

    *rho in closed form.* ``rho`` is a free scalar: for fixed ``(P, Q0)`` the LMI holds
    iff its disturbance-free principal block ``N`` (``A^T P + P A + Q0``, or
    ``[[Q0 - P, A^T P], [P A, -P]]`` in the linear form) is negative definite and
    ``rho I > H + G^T (-N)^-1 G`` (Schur complement; ``G`` the coupling block, ``H = 0``
    or ``D^T P D``). So the LMI is feasible iff its block ``N < 0`` is, and the SDP
    solves that block for ``(P, Q0)``; ``rho`` is then ``RHO_FACTOR`` times its infimum
    (which also makes ``cw`` smallest for that ``(P, Q0)``). Keeping ``rho`` in the SDP
    would either leave it unbounded under the objective below or need a penalty on it
    that trades against ``t`` and could turn a feasible LMI into a reported infeasible
    one. The full LMI, with ``D`` and ``rho``, is what the numpy re-check verifies.

    *Normalisation and objective.* The LMI is homogeneous in ``(P, Q0, rho)``. The solver
    maximises the common slack ``t`` of all the strict inequalities, with the scale fixed
    by ``P <= I``:

    ``max t  s.t.  t I <= P <= I,  Q0 >= t I,  N_k <= -t I  (all vertices k)``

    (a given ``Q0`` enters as ``sigma Q0`` with ``sigma lmin(Q0) >= t``, and the
    certificate is rescaled by ``1 / sigma`` at the end). The problem is always feasible
    (``t <= 0``, ``P = 0``) and bounded; its optimum ``t*`` is 0 exactly when no
    certificate exists, and positive otherwise. So the decision is ``t* > margin``:
    feasible; ``t* <= margin``: "infeasible" (no certificate with that normalised
    margin). Normalising from above keeps the infeasible cases well posed (the optimum
    ``t* = 0`` is attained); a normalisation ``P >= I`` with a constraint ``t >= margin``
    makes them infeasible only by about ``margin``, which Clarabel often reports as
    "infeasible_inaccurate". Maximising ``t`` also makes the bound constants
    meaningful: in the solver's units ``cond(P) <= 1 / t`` and the decay rate
    ``mu = lmin(Q0) / lmax(P) >= t``. A free ``Q0`` is then re-chosen for the solver's
    ``P`` to make ``cw`` small (see `_tuned_q0`).

    *Scaling.* A stable matrix near the stability boundary with an ill-conditioned
    eigenbasis needs a ``P`` whose condition number is about ``cond(V)^2 / distance``,
    beyond a solver's relative tolerance. The SDP is therefore solved in coordinates
    ``x = T z`` (``A -> T^-1 A T``, ``P -> T^T P T``, a congruence that preserves
    feasibility) chosen by a shifted Lyapunov equation of the mean vertex; the
    certificate is mapped back and re-checked in the caller's coordinates. That solve
    makes the decision. When it is "feasible", the SDP is solved once more in the
    caller's own coordinates, and the certified result with the smaller ``c0 + cw`` is
    returned (in well-conditioned problems the second one's constants are often several
    times smaller; in ill-conditioned ones it may fail, which is then ignored because
    the decision already has a certificate). `LMIResult.coordinates` says which one
    came back; ``solve_time`` counts both solves.

    *Statuses.* optimal with ``t* > margin`` -> numpy re-check: ``P`` positive definite
    and every vertex's LMI (the original form) negative definite beyond rounding
    (`EIGENVALUE_ROUNDING`) -> "feasible" (``certified=True``), else "inconclusive"
    with the reason; optimal with ``t* <= margin`` -> "infeasible"; optimal_inaccurate
    or infeasible_inaccurate -> "inconclusive", ``inaccurate=True``; anything else
    (including a claim of infeasibility of this always-feasible problem), or a solver
    error -> `SolverFailure`.
    """
    form = as_choice("form", form, FORMS)
    vertices = _as_vertices(A)
    p = vertices.shape[1]
    D_mat = np.eye(p) if D is None else as_finite_array("D", D, ndim=2)
    check_shape("D", D_mat, (p, None))
    if D_mat.shape[1] == 0:
        raise DimensionError(f"D must have shape ({p}, r) with r >= 1, got shape {D_mat.shape}")
    q0 = _as_q0(Q0, p)
    margin = as_positive_scalar("margin", margin)
    solver = _as_solver(solver)

    with _LOCK:
        return _decide(form, vertices, D_mat, q0, margin, solver)


def _decide(form, vertices, D_mat, q0, margin, solver) -> LMIResult:
    """Decide in preconditioned coordinates; if feasible, also try the caller's (see Notes)."""
    p = vertices.shape[1]
    T, T_inv = _preconditioner(vertices, form)
    preconditioned = not np.array_equal(T, np.eye(p))
    first = _attempt(form, vertices, D_mat, q0, margin, solver, T, T_inv, "preconditioned" if preconditioned else "caller")
    if not (preconditioned and first.status is LMIStatus.FEASIBLE):
        return first
    # The decision is made; a certificate found in the caller's own coordinates often has
    # smaller bound constants when the problem is well conditioned there. Keep the better.
    try:
        second = _attempt(form, vertices, D_mat, q0, margin, solver, np.eye(p), np.eye(p), "caller")
    except SolverFailure:
        second = None
    total_time = first.solve_time + (0.0 if second is None else second.solve_time)
    best = first
    if second is not None and second.status is LMIStatus.FEASIBLE and sum(second.bound_constants()) < sum(first.bound_constants()):
        best = second
    return dataclasses.replace(best, solve_time=total_time, slack=first.slack)


def _attempt(form, vertices, D_mat, q0, margin, solver, T, T_inv, coordinates) -> LMIResult:
    """Solve the cached SDP in the coordinates ``x = T z`` and turn its answer into a result."""
    k, p = vertices.shape[0], vertices.shape[1]
    program = _program(form, p, k, q0 is not None)
    for param, vertex in zip(program.A, vertices):
        param.value = T_inv @ vertex @ T
    if q0 is not None:
        scaled_q0 = T.T @ q0 @ T
        scaled_q0 = (scaled_q0 + scaled_q0.T) / 2
        q0_unit = float(np.linalg.eigvalsh(scaled_q0)[0])
        program.Q0.value = scaled_q0 / q0_unit

    start = time.perf_counter()
    status = _run_solver(program.problem, solver, margin)
    elapsed = time.perf_counter() - start

    def outcome(kind, *, reason, inaccurate=False, P=None, Q=None, rho=None, max_eig=None, certified=False, slack=None):
        return LMIResult(
            status=kind,
            form=form,
            P=None if P is None else frozen_copy(P),
            rho=None if rho is None else float(rho),
            Q0=None if Q is None else frozen_copy(Q),
            certified=certified,
            inaccurate=inaccurate,
            solver=solver,
            solver_status=status,
            solve_time=elapsed,
            max_eigenvalue=None if max_eig is None else float(max_eig),
            eigenvalues_P=None if P is None else frozen_copy(np.linalg.eigvalsh(P)),
            nvertices=k,
            reason=reason,
            coordinates=coordinates,
            slack=slack,
        )

    if status in _INACCURATE:
        return outcome(LMIStatus.INCONCLUSIVE, inaccurate=True, reason=f"the solver's answer is inaccurate ({status})")
    if status != cp.OPTIMAL:
        raise SolverFailure(f"{solver} returned status {status!r} on the Assumption 4 LMI, which is always feasible and bounded")
    best_slack = float(program.slack.value)
    if not best_slack > margin:
        return outcome(
            LMIStatus.INFEASIBLE,
            slack=best_slack,
            reason=f"the largest normalised LMI slack is {best_slack:.3g} <= margin {margin:.3g}: no certificate exists",
        )

    # Back to the caller's coordinates: x = T z, so P = T^-T P_z T^-1 (a congruence).
    P_cert = T_inv.T @ program.P.value @ T_inv
    Q_cert = T_inv.T @ np.asarray(program.Q.value) @ T_inv
    if q0 is not None:
        # The solver's Q0 is c q0 with c = sigma / q0_unit; divide the certificate by c.
        c = float(program.sigma.value) / q0_unit
        P_cert, Q_cert = P_cert / c, q0
    P_cert, Q_cert = (P_cert + P_cert.T) / 2, (Q_cert + Q_cert.T) / 2
    if q0 is None:
        Q_cert = _tuned_q0(form, vertices, D_mat, P_cert, Q_cert)
    smallest = _smallest_rho(form, vertices, D_mat, P_cert, Q_cert)
    if smallest is None:
        return outcome(
            LMIStatus.INCONCLUSIVE,
            P=P_cert,
            Q=Q_cert,
            slack=best_slack,
            reason="numpy re-check failed: the Lyapunov block is not negative definite at the solver's P",
        )
    rho_min, block_slack = smallest
    # With D = 0 any rho > 0 serves; the top-left block's slack gives it a sensible scale.
    rho = RHO_FACTOR * rho_min if rho_min > 0 else block_slack
    eig_p = np.linalg.eigvalsh(P_cert)
    max_eig = -np.inf
    lmi_ok = True
    for vertex in vertices:
        M = lmi_matrix(vertex, P_cert, Q_cert, rho, D_mat, form)
        top = float(np.linalg.eigvalsh(M)[-1])
        max_eig = max(max_eig, top)
        lmi_ok &= top < -_rounding(M)
    p_ok = eig_p[0] > _rounding(P_cert)
    if lmi_ok and p_ok:
        return outcome(
            LMIStatus.FEASIBLE, P=P_cert, Q=Q_cert, rho=rho, max_eig=max_eig, certified=True, slack=best_slack, reason=""
        )
    failed = "P is not positive definite" if not p_ok else "an LMI matrix is not negative definite"
    return outcome(
        LMIStatus.INCONCLUSIVE,
        P=P_cert,
        Q=Q_cert,
        rho=rho,
        max_eig=max_eig,
        slack=best_slack,
        reason=f"numpy re-check failed: {failed} beyond rounding error",
    )
