"""The stability LMI of Assumption 4: verdicts proven both ways.

`check_assumption4` decides whether one matrix, or every vertex of a matrix polytope
with one common ``P`` (eq. (8)), satisfies the Lyapunov-type LMI of Assumption 4, and
returns an `LMIResult`: "feasible" with a certificate ``(P, rho, Q0)`` proven in exact
rational arithmetic, "infeasible" with a `DualCertificate` proven the same way (no
certificate with a normalised margin above a stated bound exists), or "inconclusive"
with the reason; and the error-bound constants that a certificate buys (Theorem 2,
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
from fractions import Fraction
from typing import Any

import cvxpy as cp
import numpy as np
import scipy.linalg as sla
from numpy.typing import ArrayLike
from scipy.optimize import minimize_scalar

from minimaxplan.models.errors import DimensionError, InputError, SolverFailure
from minimaxplan.models.validation import as_choice, as_finite_array, as_positive_scalar, check_shape, frozen_copy

__all__ = ["check_assumption4", "LMIResult", "LMIStatus", "DualCertificate", "lmi_matrix", "FORMS", "SOLVERS"]

#: The two LMI forms: continuous time ``e' = A e + D w``, discrete time ``e+ = A e + D w``.
FORMS = ("continuous", "discrete")
#: Solvers that handle the semidefinite program (Clarabel is the default).
SOLVERS = ("CLARABEL", "SCS")

#: The returned rho is this factor times the smallest rho that the returned (P, Q0) allow.
RHO_FACTOR = 1.01
#: Primal SDP feasibility/gap tolerance (at most margin / 10). The verdicts never rest on
#: it: every certificate is re-checked exactly.
SOLVER_TOLERANCE = 1e-7
#: Dual SDP tolerance (at most margin / 1000): well below the dual slack, which is about
#: ``DUAL_FRACTION * margin / p``, so that the exact re-check of the dual passes.
DUAL_TOLERANCE = 1e-9
#: The dual SDP asks for ``tr Y <= DUAL_FRACTION * margin`` (with ``sum_k tr Z_k = 1``),
#: so that its proven margin ``tr Y / sum_k tr Z_k`` stays below ``margin``.
DUAL_FRACTION = 0.5
#: Cache size of built cvxpy primal problems (one per form, p and vertex count).
PROBLEM_CACHE_SIZE = 32
#: Smallest shift (relative to 1 + ||A||) of the preconditioner's Lyapunov equation.
_SHIFT_FLOOR = 1e-3
#: A preconditioner whose Lyapunov matrix ``Phat`` has a condition number above this is not
#: used (identity instead): its smallest eigenvalues would have no correct digit.
_MAX_PRECONDITIONER_CONDITION = 1e15

_INACCURATE = {cp.OPTIMAL_INACCURATE, cp.INFEASIBLE_INACCURATE}


class LMIStatus(str, Enum):
    """The three outcomes of `check_assumption4` (the contract's strings).

    A ``str`` enum: ``LMIStatus.FEASIBLE == "feasible"`` holds, ``str()`` and
    ``format()`` give the plain string, and `LMIResult.to_dict` emits it.

    Attributes
    ----------
    FEASIBLE
        A certificate was found and proven in exact arithmetic.
    INFEASIBLE
        A dual certificate proves, in exact arithmetic, that no certificate with a
        normalised margin above `LMIResult.margin` (< the requested margin) exists.
    INCONCLUSIVE
        Neither proof came out; `LMIResult.reason` says what was tried.
    """

    FEASIBLE = "feasible"
    INFEASIBLE = "infeasible"
    INCONCLUSIVE = "inconclusive"

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, format_spec: str) -> str:
        return format(str(self.value), format_spec)


@dataclass(frozen=True, eq=False)
class LMIResult:
    """Outcome of `check_assumption4`: a decision, a certificate and its re-check.

    Attributes
    ----------
    status
        ``"feasible"`` (a certificate proven in exact arithmetic), ``"infeasible"`` (a
        dual certificate proves that no certificate with normalised margin above
        `margin` exists) or ``"inconclusive"`` (neither; `reason` says why).
    form
        ``"continuous"`` or ``"discrete"``.
    P, Q0, rho
        The certificate in the caller's coordinates (``None`` unless the solver returned
        a point). ``Q0`` is the caller's matrix when one was given.
    certified
        True iff ``(P, Q0, rho)`` is proven exactly: ``P`` positive definite and every
        vertex's LMI matrix (the original, non-linear form for ``"discrete"``) negative
        definite, in rational arithmetic on the returned floats.
    inaccurate
        True iff the solver reported an inaccurate status for the solve whose answer
        came back (an exactly proven certificate is valid regardless); for an
        inconclusive result, iff any solve did.
    solver, solver_status
        The solver used and the raw cvxpy status of the solve whose answer came back
        (``"not solved (Lyapunov equation)"`` for a certificate from the Lyapunov
        equation; the last solve's for an inconclusive result).
    solve_time
        Wall-clock seconds of the cvxpy solve calls (parameter update and
        canonicalisation included; every solve of the call).
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
        Where the returned certificate (or dual certificate) was found:
        ``"preconditioned"`` (the normalised coordinates) or ``"caller"`` (see
        `check_assumption4`, *Normalised coordinates*).
    slack
        The primal SDP's optimal normalised slack ``t*`` for the returned certificate
        (None for one from the Lyapunov equation), or of the first primal solve when
        no certificate came back (None without an optimum). Informative only.
    margin
        For "infeasible": the proven bound ``m_proven < margin``: no certificate has a
        normalised margin above it (`DualCertificate.margin`); None otherwise.
    dual
        For "infeasible": the exactly re-checked `DualCertificate`; None otherwise.
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
    margin: float | None = None
    dual: DualCertificate | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "status", LMIStatus(self.status))

    @property
    def holds(self) -> bool:
        """True iff Assumption 4 holds: the status is feasible and the certificate is proven."""
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
        eig_p, Q0, rho = self._require_certificate()
        lmin_q0 = float(np.linalg.eigvalsh(Q0)[0])
        c0 = float(np.sqrt(eig_p[-1] / eig_p[0]))
        cw = float(np.sqrt(rho * eig_p[-1] / (eig_p[0] * lmin_q0)))
        return c0, cw

    def decay_factor(self) -> float:
        """``1 - mu`` with ``mu = lmin(Q0) / lmax(P)``: the per-step contraction of
        ``V = e^T P e`` (discrete form), or ``exp(-mu)`` per unit time (continuous).

        Returns
        -------
        float
            The factor, in (0, 1).

        Raises
        ------
        InputError
            If the result is not a certified feasible one.
        """
        eig_p, Q0, _ = self._require_certificate()
        mu = float(np.linalg.eigvalsh(Q0)[0] / eig_p[-1])
        return float(1.0 - mu) if self.form == "discrete" else float(np.exp(-mu))

    def width_bound(self, e0_norm: float, w_width_norm: float, steps: ArrayLike | None = None) -> float | np.ndarray:
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

    def _require_certificate(self) -> tuple[np.ndarray, np.ndarray, float]:
        """``(eigenvalues_P, Q0, rho)`` of a certified feasible result, else `InputError`."""
        if not self.holds or self.eigenvalues_P is None or self.Q0 is None or self.rho is None:
            raise InputError(f"bound constants need a certified feasible LMIResult, got status {self.status.value!r}")
        return self.eigenvalues_P, self.Q0, self.rho

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
            "margin": self.margin,
            "dual": None if self.dual is None else self.dual.to_dict(),
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


# --------------------------------------------------------------------------- exact arithmetic


class _Exact:
    """An exact rational matrix ``n / 2**e``: ``n`` an object array of Python ints.

    Every float is a dyadic rational, so float matrices convert exactly, and sums and
    products of dyadic matrices stay dyadic; nothing here rounds.
    """

    __slots__ = ("n", "e")

    def __init__(self, n: np.ndarray, e: int) -> None:
        self.n = n
        self.e = e

    @classmethod
    def of(cls, X: Any) -> _Exact:
        """The exact value of a float array."""
        X = np.asarray(X, dtype=float)
        ratios = [float(x).as_integer_ratio() for x in X.ravel().tolist()]
        e = max((den.bit_length() - 1 for _, den in ratios), default=0)
        ints = [num * (1 << (e - den.bit_length() + 1)) for num, den in ratios]
        return cls(np.array(ints, dtype=object).reshape(X.shape), e)

    def lifted(self, e: int) -> np.ndarray:
        """The integer array at the finer scale ``2**-e`` (``e >= self.e``)."""
        return self.n * (1 << (e - self.e))

    def __matmul__(self, other: _Exact) -> _Exact:
        return _Exact(self.n @ other.n, self.e + other.e)

    def __add__(self, other: _Exact) -> _Exact:
        e = max(self.e, other.e)
        return _Exact(self.lifted(e) + other.lifted(e), e)

    def __sub__(self, other: _Exact) -> _Exact:
        e = max(self.e, other.e)
        return _Exact(self.lifted(e) - other.lifted(e), e)

    def __neg__(self) -> _Exact:
        return _Exact(-self.n, self.e)

    @property
    def T(self) -> _Exact:
        return _Exact(self.n.T, self.e)

    def symmetric_part(self) -> _Exact:
        """``(M + M^T) / 2``, exactly."""
        return _Exact(self.n + self.n.T, self.e + 1)

    def trace(self) -> Fraction:
        return Fraction(int(sum(self.n.diagonal().tolist())), 1 << self.e)


def _exact_block(rows: list[list[_Exact]]) -> _Exact:
    e = max(block.e for row in rows for block in row)
    return _Exact(np.block([[block.lifted(e) for block in row] for row in rows]), e)


def _exact_identity(p: int) -> _Exact:
    return _Exact(np.array([[int(i == j) for j in range(p)] for i in range(p)], dtype=object).reshape(p, p), 0)


def _exact_positive_definite(M: _Exact) -> bool:
    """Whether the symmetric part of ``M`` is positive definite, decided exactly.

    Sylvester's criterion: every leading principal minor is > 0. Bareiss' fraction-free
    elimination makes its k-th pivot the k-th leading principal minor, in integers.
    """
    a = M.symmetric_part().n.tolist()
    n = len(a)
    previous = 1
    for k in range(n):
        pivot = a[k][k]
        if pivot <= 0:
            return False
        row_k = a[k]
        for i in range(k + 1, n):
            row_i, factor = a[i], a[i][k]
            for j in range(k + 1, n):
                row_i[j] = (row_i[j] * pivot - factor * row_k[j]) // previous
        previous = pivot
    return True


def _exact_gram(S: np.ndarray) -> _Exact:
    """An exactly positive semidefinite rational matrix near the float matrix ``S``.

    ``V diag(max(lambda, 0)) V^T`` from the eigen-decomposition of ``S``, evaluated
    exactly: a sum of ``lambda_i v_i v_i^T`` with ``lambda_i >= 0``, so PSD by construction.
    """
    lam, V = np.linalg.eigh((S + S.T) / 2)
    exact_v = _Exact.of(V)
    return exact_v @ _Exact.of(np.diag(np.maximum(lam, 0.0))) @ exact_v.T


def _exact_lyapunov(form: str, A: _Exact, P: _Exact) -> _Exact:
    """``L(P) = A^T P + P A`` (continuous) or ``A^T P A - P`` (discrete), exactly."""
    return A.T @ P + P @ A if form == "continuous" else A.T @ P @ A - P


def _exact_adjoint(form: str, A: _Exact, Z: _Exact) -> _Exact:
    """The adjoint ``L*(Z) = A Z + Z A^T`` or ``A Z A^T - Z`` (``<Z, L(P)> = <L*(Z), P>``)."""
    return A @ Z + Z @ A.T if form == "continuous" else A @ Z @ A.T - Z


def _exact_lmi(form: str, A: np.ndarray, P: np.ndarray, Q0: np.ndarray, rho: float, D: np.ndarray) -> _Exact:
    """The LMI matrix of `lmi_matrix`, in exact arithmetic on the float inputs."""
    exact_a, exact_p, exact_q, exact_d = (_Exact.of(m) for m in (A, P, Q0, D))
    rho_identity = _Exact.of(rho * np.eye(D.shape[1]))
    if form == "continuous":
        top = exact_a.T @ exact_p + exact_p @ exact_a + exact_q
        coupling, corner = exact_p @ exact_d, -rho_identity
    else:
        top = exact_a.T @ exact_p @ exact_a - exact_p + exact_q
        coupling = exact_a.T @ exact_p @ exact_d
        corner = exact_d.T @ exact_p @ exact_d - rho_identity
    return _exact_block([[top, coupling], [coupling.T, corner]])


def _upper_float(x: Fraction) -> float:
    """The smallest float >= x."""
    f = float(x)
    return float(np.nextafter(f, np.inf)) if Fraction(f) < x else f


# --------------------------------------------------------------------------- the primal SDP


@dataclass(frozen=True)
class _Program:
    problem: cp.Problem
    A: tuple
    P: cp.Variable
    Q: cp.Variable
    slack: cp.Variable


def _lyapunov_block(form: str, A, P, Q):
    """The LMI without its disturbance row and column (see check_assumption4, Notes)."""
    if form == "continuous":
        M = A.T @ P + P @ A + Q
    else:
        M = cp.bmat([[Q - P, A.T @ P], [P @ A, -P]])
    return (M + M.T) / 2


def _build_program(form: str, p: int, k: int) -> _Program:
    """maximise t  s.t.  t I <= P <= I,  Q0 >= t I,  Lyapunov block_k <= -t I."""
    A = tuple(cp.Parameter((p, p), name=f"A{i}") for i in range(k))
    P = cp.Variable((p, p), symmetric=True, name="P")
    Q = cp.Variable((p, p), symmetric=True, name="Q0")
    slack = cp.Variable(name="t")
    eye = np.eye(p)
    constraints = [P << eye, P >> slack * eye, Q >> slack * eye]
    size = 2 * p if form == "discrete" else p
    for Ai in A:
        constraints.append(_lyapunov_block(form, Ai, P, Q) << -slack * np.eye(size))
    problem = cp.Problem(cp.Maximize(slack), constraints)
    return _Program(problem, A, P, Q, slack)


_PROGRAMS: OrderedDict[tuple, _Program] = OrderedDict()
# The cached problems' parameters are set per call: one call at a time per process.
_LOCK = threading.Lock()


def _program(form: str, p: int, k: int) -> _Program:
    """The cached DPP problem for this structure (least recently used evicted)."""
    key = (form, p, k)
    if key in _PROGRAMS:
        _PROGRAMS.move_to_end(key)
        return _PROGRAMS[key]
    program = _build_program(form, p, k)
    _PROGRAMS[key] = program
    while len(_PROGRAMS) > PROBLEM_CACHE_SIZE:
        _PROGRAMS.popitem(last=False)
    return program


def _solver_options(solver: str, tolerance: float) -> dict:
    if solver == "CLARABEL":
        return {"tol_feas": tolerance, "tol_gap_abs": tolerance, "tol_gap_rel": tolerance}
    return {"eps_abs": tolerance, "eps_rel": tolerance}


def _run_solver(problem: cp.Problem, solver: str, tolerance: float) -> str:
    try:
        with warnings.catch_warnings():
            # cvxpy warns on inaccurate statuses; the exact re-checks decide instead.
            warnings.filterwarnings("ignore", message="Solution may be inaccurate", category=UserWarning)
            problem.solve(solver=solver, **_solver_options(solver, tolerance))
    except cp.error.SolverError as exc:
        raise SolverFailure(f"{solver} failed: {exc}") from exc
    return str(problem.status)


@dataclass(frozen=True)
class _Candidate:
    """A Lyapunov matrix to be re-checked, with where it came from."""

    P: np.ndarray
    Q: np.ndarray | None
    coordinates: str
    source: str
    solver_status: str
    inaccurate: bool
    slack: float | None


@dataclass
class _Log:
    """What the attempts of one call saw: reasons, solver statuses, time spent."""

    reasons: list[str] = dataclasses.field(default_factory=list)
    statuses: list[str] = dataclasses.field(default_factory=list)
    solve_time: float = 0.0
    slack: float | None = None

    @property
    def inaccurate(self) -> bool:
        return any(status in _INACCURATE for status in self.statuses)


def _primal_sdp(form, vertices, T, T_inv, coordinates, margin, solver, log: _Log) -> _Candidate | None:
    """Solve the primal SDP in the coordinates ``x = T z``; its P (in the caller's coordinates)."""
    k, p = vertices.shape[0], vertices.shape[1]
    program = _program(form, p, k)
    for param, vertex in zip(program.A, vertices):
        param.value = T_inv @ vertex @ T
    start = time.perf_counter()
    try:
        status = _run_solver(program.problem, solver, min(SOLVER_TOLERANCE, margin / 10))
    except SolverFailure as exc:
        log.reasons.append(f"primal SDP ({coordinates} coordinates): {exc}")
        return None
    finally:
        log.solve_time += time.perf_counter() - start
    log.statuses.append(status)
    slack_value = program.slack.value
    if status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or program.P.value is None or slack_value is None:
        log.reasons.append(f"primal SDP ({coordinates} coordinates): solver status {status!r}")
        return None
    slack = float(slack_value)
    if log.slack is None:
        log.slack = slack
    if not slack > 0:
        log.reasons.append(f"primal SDP ({coordinates} coordinates): normalised slack {slack:.3g} <= 0")
        return None
    P = T_inv.T @ program.P.value @ T_inv
    Q = T_inv.T @ np.asarray(program.Q.value) @ T_inv
    return _Candidate((P + P.T) / 2, (Q + Q.T) / 2, coordinates, "primal SDP", status, status in _INACCURATE, slack)


def _lyapunov_candidate(form, vertices, T, T_inv, coordinates) -> _Candidate | None:
    """The solution of the Lyapunov (Stein) equation ``L(P) = -I`` of the mean vertex, in
    the coordinates ``x = T z``: a certificate for one matrix, often for a small polytope."""
    p = vertices.shape[1]
    mean = T_inv @ vertices.mean(axis=0) @ T
    eigenvalues = np.linalg.eigvals(mean)
    stable = eigenvalues.real.max() < 0 if form == "continuous" else np.abs(eigenvalues).max() < 1
    if not stable:
        return None
    try:
        with warnings.catch_warnings():
            # an ill-conditioned solve is fine: the exact re-check judges the result
            warnings.simplefilter("ignore", sla.LinAlgWarning)
            warnings.simplefilter("ignore", RuntimeWarning)
            if form == "continuous":
                P_z = sla.solve_continuous_lyapunov(mean.T, -np.eye(p))
            else:
                P_z = sla.solve_discrete_lyapunov(mean.T, np.eye(p))
    except (np.linalg.LinAlgError, ValueError):
        return None
    P = T_inv.T @ P_z @ T_inv
    if not np.all(np.isfinite(P)):
        return None
    return _Candidate(
        (P + P.T) / 2, None, coordinates, "Lyapunov equation", "not solved (Lyapunov equation)", False, None
    )


# --------------------------------------------------------------------------- the dual SDP


@dataclass(frozen=True, eq=False)
class DualCertificate:
    """A proof that no Assumption 4 certificate with normalised margin above `margin` exists.

    Attributes
    ----------
    T
        The normalisation, shape (p, p): the margin is measured in the coordinates
        ``z = T^-1 x`` (see `check_assumption4`, *Infeasible*).
    Y
        Positive semidefinite (p, p) multiplier of the normalisation ``T^T P T <= I``.
    Z
        Positive semidefinite multipliers, shape (k, p, p), one per vertex, of
        ``T^T L_k(P) T <= -m I`` (``L_k(P) = A_k^T P + P A_k`` or ``A_k^T P A_k - P``).
    margin
        ``tr(Y) / sum_k tr(Z_k)`` rounded up: for every ``P >= 0`` with
        ``T^T P T <= I`` some ``T^T L_k(P) T`` has an eigenvalue above ``-margin``.

    Notes
    -----
    With ``W = T Y T^T + sum_k L_k*(T Z_k T^T)`` (``L*(Z) = A Z + Z A^T`` or
    ``A Z A^T - Z``, the adjoint), ``W >= 0`` and ``tr Y < m sum_k tr Z_k`` forbid a
    ``P >= 0`` with ``T^T P T <= I`` and ``T^T L_k(P) T <= -m I``: otherwise
    ``0 <= <W, P> = <Y, T^T P T> + sum_k <Z_k, T^T L_k(P) T> <= tr Y - m sum_k tr Z_k < 0``.
    `check_assumption4` verifies ``W > 0`` and the trace inequality in exact rational
    arithmetic on the exact values of the float matrices ``T`` and ``A_k`` and of
    exactly positive semidefinite Gram forms of ``Y`` and ``Z_k`` (the stored arrays are
    those Gram forms rounded to floats).
    """

    T: np.ndarray
    Y: np.ndarray
    Z: np.ndarray
    margin: float

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dictionary (arrays as nested lists)."""
        return {"T": self.T.tolist(), "Y": self.Y.tolist(), "Z": self.Z.tolist(), "margin": self.margin}


def _adjoint(form: str, B: np.ndarray, Z):
    return B @ Z + Z @ B.T if form == "continuous" else B @ Z @ B.T - Z


def _dual_certificate(form, vertices, T, T_inv, coordinates, margin, solver, log: _Log) -> DualCertificate | None:
    """Solve the dual SDP of the normalised problem in ``x = T z``; re-check it exactly.

    ``max s  s.t.  Y, Z_k >= 0,  sum_k tr Z_k = 1,  tr Y <= DUAL_FRACTION margin,
    Y + sum_k L_{B_k}*(Z_k) >= s I`` with ``B_k = T^-1 A_k T``; ``s > 0`` leaves room for
    the rounding of the exact re-check (see `DualCertificate`).
    """
    k, p = vertices.shape[0], vertices.shape[1]
    B = [T_inv @ vertex @ T for vertex in vertices]
    Y = cp.Variable((p, p), PSD=True)
    Z = [cp.Variable((p, p), PSD=True) for _ in range(k)]
    s = cp.Variable()
    W = Y + sum(_adjoint(form, Bk, Zk) for Bk, Zk in zip(B, Z))
    constraints = [
        sum(cp.trace(Zk) for Zk in Z) == 1,
        cp.trace(Y) <= DUAL_FRACTION * margin,
        (W + W.T) / 2 >> s * np.eye(p),
    ]
    problem = cp.Problem(cp.Maximize(s), constraints)
    start = time.perf_counter()
    try:
        status = _run_solver(problem, solver, min(DUAL_TOLERANCE, margin / 1000))
    except SolverFailure as exc:
        log.reasons.append(f"dual SDP ({coordinates} coordinates): {exc}")
        return None
    finally:
        log.solve_time += time.perf_counter() - start
    log.statuses.append(status)
    s_value = s.value
    if status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or Y.value is None or s_value is None:
        log.reasons.append(f"dual SDP ({coordinates} coordinates): solver status {status!r}")
        return None
    if not float(s_value) > 0:
        log.reasons.append(
            f"dual SDP ({coordinates} coordinates): no strict dual certificate (slack {float(s_value):.3g})"
        )
        return None
    exact_t = _Exact.of(T)
    exact_y = _exact_gram(np.asarray(Y.value))
    exact_z = [_exact_gram(np.asarray(Zk.value)) for Zk in Z]
    exact_w = exact_t @ exact_y @ exact_t.T
    for vertex, Zk in zip(vertices, exact_z):
        exact_w = exact_w + _exact_adjoint(form, _Exact.of(vertex), exact_t @ Zk @ exact_t.T)
    trace_z = sum((Zk.trace() for Zk in exact_z), Fraction(0))
    proven = exact_y.trace() / trace_z if trace_z > 0 else None
    if proven is None or not proven < Fraction(margin) or not _exact_positive_definite(exact_w):
        log.reasons.append(f"dual SDP ({coordinates} coordinates): the dual certificate failed the exact re-check")
        return None

    def floats(m: _Exact) -> np.ndarray:
        return np.array([[float(Fraction(int(v), 1 << m.e)) for v in row] for row in m.n.tolist()])

    return DualCertificate(
        T=frozen_copy(T),
        Y=frozen_copy(floats(exact_y)),
        Z=frozen_copy(np.array([floats(Zk) for Zk in exact_z])),
        margin=_upper_float(proven),
    )


# --------------------------------------------------------------------------- scaling


def _preconditioner(vertices: np.ndarray, form: str) -> tuple[np.ndarray, np.ndarray]:
    """A similarity ``T`` (and ``T^-1``) that makes the solver's problem well scaled.

    ``T = S Phat^(-1/2)``: ``S`` the diagonal balancing similarity of the mean vertex
    (powers of 2, so exact), ``Phat`` a Lyapunov (Stein) solution for the balanced mean
    vertex with its spectrum shifted halfway towards (or past) the stability boundary, so
    that in the new coordinates a multiple of the identity nearly certifies the mean
    vertex. Changing coordinates never changes feasibility (a congruence of the LMI); it
    moves the solvers' problems away from the scale at which their tolerances matter and
    fixes the normalisation of the dual certificate. ``T = S`` when ``Phat`` is not
    usable (see `_MAX_PRECONDITIONER_CONDITION`).
    """
    p = vertices.shape[1]
    # Balance first: a diagonal similarity by powers of 2 (exact in floating point).
    _, (balance, _) = sla.matrix_balance(vertices.mean(axis=0), permute=False, separate=True)
    mean = vertices.mean(axis=0) * (1.0 / balance)[:, None] * balance[None, :]
    eigenvalues = np.linalg.eigvals(mean)
    scale = 1.0 + float(np.abs(eigenvalues).max())
    try:
        with warnings.catch_warnings():
            # an ill-conditioned solve is caught below (the condition-number test)
            warnings.simplefilter("ignore", sla.LinAlgWarning)
            warnings.simplefilter("ignore", RuntimeWarning)
            if form == "continuous":
                abscissa = eigenvalues.real.max()
                shift = abscissa + max(abs(abscissa) / 2, _SHIFT_FLOOR * scale)
                phat = sla.solve_continuous_lyapunov((mean - shift * np.eye(p)).T, -np.eye(p))
            else:
                radius = np.abs(eigenvalues).max()
                target = radius + max(abs(1.0 - radius) / 2, _SHIFT_FLOOR)
                # The Schur-based (bilinear) solve, not scipy's default for p < 10 (a
                # Kronecker system): for a non-normal matrix that balancing cannot fix (a
                # Jordan block in a rotated basis) the Kronecker solve returns an indefinite
                # Phat (rcond 7e-18), the preconditioner falls back to T = S and the
                # normalised margin depends on the basis.
                phat = sla.solve_discrete_lyapunov(mean.T / target, np.eye(p), method="bilinear")
            phat = (phat + phat.T) / 2
            lam, U = np.linalg.eigh(phat)
    except (np.linalg.LinAlgError, ValueError):
        return np.eye(p), np.eye(p)
    if not np.all(np.isfinite(lam)) or lam[0] <= 0 or lam[-1] / lam[0] > _MAX_PRECONDITIONER_CONDITION:
        return np.diag(balance), np.diag(1.0 / balance)
    lam = lam / lam[-1]
    T = balance[:, None] * ((U / np.sqrt(lam)) @ U.T)
    T_inv = ((U * np.sqrt(lam)) @ U.T) * (1.0 / balance)[None, :]
    return T, T_inv


# --------------------------------------------------------------------------- numpy helpers


def lmi_matrix(A: ArrayLike, P: ArrayLike, Q0: ArrayLike, rho: float, D: ArrayLike | None, form: str) -> np.ndarray:
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
    (the original, non-linear form, which `check_assumption4` re-checks in exact arithmetic).
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


def _q0_options(
    form: str, vertices: np.ndarray, D: np.ndarray, P: np.ndarray, Q_solver: np.ndarray | None
) -> list[np.ndarray]:
    """Free Q0 to try for a Lyapunov matrix P, best first: the tuned ``q I``, then safer ones.

    ``cw^2 = rho lmax(P) / (lmin(P) lmin(Q0))``; for fixed P, a larger ``Q0`` raises the
    smallest admissible rho, so ``rho(q I) / q`` is minimised over ``0 < q < q_max``,
    ``q_max = min_k -lmax(L_k(P))``, by a bounded scalar search; the solver's own Q0 is
    preferred if it does better. ``q_max / 2`` and ``q_max / 8`` follow, in case the
    exact re-check refuses a Q0 too close to ``q_max``.
    """
    p = P.shape[0]
    blocks = [_lyapunov(form, A, P) for A in vertices]
    q_max = min(-float(np.linalg.eigvalsh(N)[-1]) for N in blocks)
    if not q_max > 0:
        return []
    search = minimize_scalar(
        lambda s: _disturbance_gain(form, vertices, D, P, s * q_max * np.eye(p)),
        bounds=(1e-6, 1 - 1e-6),
        method="bounded",
        options={"xatol": 1e-4},
    )
    options = [float(search.x) * q_max * np.eye(p)]
    if Q_solver is not None and _disturbance_gain(form, vertices, D, P, Q_solver) < _disturbance_gain(
        form, vertices, D, P, options[0]
    ):
        options.insert(0, Q_solver)
    return options + [q_max / 2 * np.eye(p), q_max / 8 * np.eye(p)]


def _lyapunov(form: str, A: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``L(P) = A^T P + P A`` or ``A^T P A - P``, symmetrised (floats)."""
    N = A.T @ P + P @ A if form == "continuous" else A.T @ P @ A - P
    return (N + N.T) / 2


def _scaled_for_q0(form: str, vertices: np.ndarray, P: np.ndarray, q0: np.ndarray) -> list[np.ndarray]:
    """Multiples ``s P`` that make ``s L_k(P) + Q0 < 0`` for a given Q0 (see Notes, *Q0 given*).

    ``s > s_min = max_k lmax(Q0, -L_k(P))``, the largest generalised eigenvalue; tried at
    ``RHO_FACTOR s_min`` and then larger, in case the exact re-check refuses the first.
    """
    try:
        s_min = max(float(sla.eigh(q0, -_lyapunov(form, A, P), eigvals_only=True)[-1]) for A in vertices)
    except (np.linalg.LinAlgError, ValueError):
        return []
    if not (np.isfinite(s_min) and s_min > 0):
        return []
    return [factor * s_min * P for factor in (RHO_FACTOR, 1.1, 2.0, 8.0)]


def _certify(form, vertices, D, q0, candidate: _Candidate):
    """Turn a Lyapunov matrix into a full certificate ``(P, Q0, rho)`` proven exactly.

    Returns ``(P, Q0, rho)`` or a string saying why none came out.
    """
    P = candidate.P
    exact_p = _Exact.of(P)
    if not _exact_positive_definite(exact_p):
        return "P is not positive definite (exact re-check)"
    if not all(_exact_positive_definite(-_exact_lyapunov(form, _Exact.of(A), exact_p)) for A in vertices):
        return "a Lyapunov block L_k(P) is not negative definite (exact re-check)"
    if q0 is not None:
        pairs = [(scaled, q0) for scaled in _scaled_for_q0(form, vertices, P, q0)]
    else:
        pairs = [(P, Q) for Q in _q0_options(form, vertices, D, P, candidate.Q)]
    for P_try, Q_try in pairs:
        P_try, Q_try = (P_try + P_try.T) / 2, (Q_try + Q_try.T) / 2
        smallest = _smallest_rho(form, vertices, D, P_try, Q_try)
        if smallest is None or (q0 is None and not _exact_positive_definite(_Exact.of(Q_try))):
            continue
        rho_min, block_slack = smallest
        for factor in (RHO_FACTOR, 1.1, 2.0):
            # With D = 0 any rho > 0 serves; the top-left block's slack gives it a scale.
            rho = factor * rho_min if rho_min > 0 else factor * block_slack
            if all(_exact_positive_definite(-_exact_lmi(form, A, P_try, Q_try, rho, D)) for A in vertices):
                return P_try, Q_try, float(rho)
    return "no (Q0, rho) for this P passed the exact re-check of the full LMI"


# --------------------------------------------------------------------------- entry point


def check_assumption4(
    A: ArrayLike,
    *,
    form: str,
    Q0: ArrayLike | None = None,
    D: ArrayLike | None = None,
    margin: float = 1e-6,
    solver: str = "CLARABEL",
) -> LMIResult:
    """Decide the LMI of Assumption 4 for a matrix or a polytope of matrices.

    Parameters
    ----------
    A : array_like
        One matrix (p, p), or the vertices of a matrix polytope, shape (k, p, p) or a
        sequence of (p, p) matrices (eq. (8)); one common ``P`` must serve them all, which
        makes the LMI hold uniformly over the polytope (it is affine in ``A`` for the
        continuous form and, in the linear form below, for the discrete form).
    form : {"continuous", "discrete"}
        ``"continuous"``: ``[[A^T P + P A + Q0, P D], [D^T P, -rho I]] < 0`` with
        ``P > 0`` (the paper's LMI, ``D = I``).
        ``"discrete"``: ``[[A^T P A - P + Q0, A^T P D], [D^T P A, D^T P D - rho I]] < 0``,
        ``P > 0``, the analogue for ``e+ = A e + D w``.
    Q0 : array_like or None
        A symmetric positive definite (p, p) matrix, or None to let the solver choose one
        (``Q0 > 0``). It never changes the verdict (see Notes).
    D : array_like or None
        Disturbance input matrix (p, r); default the identity. Extends the paper's
        continuous LMI (where ``D = I``) in the obvious way.
    margin : float
        Normalised margin (> 0) of the "infeasible" verdict: it is given only with a proof
        that no certificate with a normalised margin of ``margin`` or more exists (see
        Notes). Default ``1e-6``.
    solver : {"CLARABEL", "SCS"}
        The SDP solver, case-insensitive (Clarabel by default).

    Returns
    -------
    LMIResult
        ``"feasible"`` with an exactly re-checked certificate, ``"infeasible"`` with an
        exactly re-checked dual certificate (`LMIResult.dual`), or ``"inconclusive"``
        with the reason.

    Raises
    ------
    DimensionError
        ``A``, ``Q0`` or ``D`` of the wrong shape.
    NonFiniteError
        NaN or infinite entries, or a non-finite ``margin``.
    InputError
        A ``form`` or ``solver`` not known (or not installed), a ``Q0`` that is not
        symmetric positive definite, a ``margin`` that is not > 0.

    Notes
    -----
    Assumption 4 and Theorem 2 (Appendix B, eqs. (25)-(29)).

    *What is decided.* With ``L_k(P) = A_k^T P + P A_k`` (continuous) or
    ``A_k^T P A_k - P`` (discrete), the LMI is feasible iff some ``P > 0`` has
    ``L_k(P) < 0`` for every vertex. ``rho`` is a free scalar: for fixed ``(P, Q0)`` the
    LMI holds iff its disturbance-free block ``N_k = L_k(P) + Q0`` is negative definite
    and ``rho I > H + G^T (-N_k)^-1 G`` (Schur complement; ``G`` the coupling block,
    ``H = 0`` or ``D^T P D``), so ``rho`` is ``RHO_FACTOR`` times that infimum. A free
    ``Q0`` is any ``0 < Q0 < -L_k(P)``; it is tuned to make ``cw`` small
    (`LMIResult.bound_constants`). *Q0 given*: ``(P, Q0, rho)`` scale together, so for
    any ``Q0 > 0`` the matrix ``s P`` with ``s > max_k lmax(Q0, -L_k(P))`` (generalised
    eigenvalue) certifies the LMI with that ``Q0``: a given ``Q0`` is feasible exactly
    when a free one is, and the verdict is the same.

    *Feasible.* Candidate Lyapunov matrices come from the Lyapunov equation
    ``L(P) = -I`` of the mean vertex and from the SDP

    ``max t  s.t.  t I <= P <= I,  Q0 >= t I,  N_k <= -t I  (all vertices k)``

    (the discrete ``N_k`` in the linear form ``[[Q0 - P, A^T P], [P A, -P]]``, the Schur
    complement of ``-P``; affine in ``A``, so the cvxpy problem is DPP, built once per
    (form, p, k) with ``A`` as parameters, cached, LRU `PROBLEM_CACHE_SIZE`), solved in
    the normalised coordinates below and in the caller's. A candidate counts only if
    ``P > 0``, ``L_k(P) < 0`` and every vertex's full LMI (original form, with ``D`` and
    ``rho``) at the returned ``(P, Q0, rho)`` are proven in exact rational arithmetic on
    the floats returned (Sylvester's criterion, fraction-free): the certificate is then
    exactly valid at its own scale, whatever its conditioning. Of the valid ones, the
    one with the smallest ``c0 + cw`` is returned (`LMIResult.coordinates` says where it
    was found).

    *Normalised coordinates.* ``x = T z`` with ``T = S Phat^(-1/2)``: ``S`` the exact
    (powers of 2) diagonal balancing of the mean vertex, ``Phat`` the Lyapunov (Stein)
    solution of the balanced mean vertex with its spectrum shifted halfway towards (or
    past) the stability boundary (shift floor relative to ``1 +`` the spectral radius,
    an invariant; the discrete equation solved through a Schur decomposition). The
    normalisation is chosen from the matrix, but it is not exactly independent of the
    caller's basis: the equation's right-hand side ``I`` and the balancing depend on it
    (no choice can be exactly invariant: for ``A = a I`` every metric is as good as
    another). Measured on the Jordan blocks of ``tests/verify/test_lmi_verdicts.py``
    (``T^-1 A T``'s singular values across six bases, scalings, a rotation and their
    product): discrete, near the boundary, within ``2.2e-2`` relative; continuous up to
    ``0.47``. So the normalised margin, and with it the margin at which "infeasible" is
    declared, moves with the basis by such factors; a verdict can change with the basis
    only for a matrix whose best normalised margin is within those factors of
    ``margin``. (When ``Phat`` is not positive definite or its condition number exceeds
    `_MAX_PRECONDITIONER_CONDITION`, ``T = S``.) The limit is floating point: a basis in
    which every certificate needs a condition number near ``1 / eps`` has no float
    certificate that survives the exact re-check, and there the verdict can be
    "infeasible" at the normalised margin (a true statement) or "inconclusive".

    *Infeasible.* The normalised margin of ``P >= 0`` is the largest ``m`` with
    ``T^T L_k(P) T <= -m I`` for all k, once ``P`` is scaled to ``T^T P T <= I``. Every
    certificate has a positive normalised margin. The verdict "infeasible" is given only
    with a `DualCertificate` (found by a dual SDP, see `_dual_certificate`) proving, in
    exact arithmetic, that no ``P >= 0`` with ``T^T P T <= I`` reaches a normalised
    margin above ``m_proven`` (`LMIResult.margin`), with ``m_proven < margin``. It says
    exactly that: no certificate with normalised margin above ``m_proven`` exists (a
    stable matrix whose certificates all have a smaller margin can be reported
    infeasible; a floating-point witness cannot prove more).

    *Inconclusive* when neither proof came out (a case within about ``margin`` of the
    boundary, or solver trouble): `LMIResult.reason` lists what each attempt saw. Solver
    errors and unexpected statuses are recorded there, never raised.
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
    """Primal candidates, exactly re-checked; else a dual certificate; else inconclusive."""
    k, p = vertices.shape[0], vertices.shape[1]
    T, T_inv = _preconditioner(vertices, form)
    eye = np.eye(p)
    frames = [(T, T_inv, "preconditioned")] if not np.array_equal(T, eye) else []
    frames.append((eye, eye, "caller"))
    log = _Log()
    candidates = []
    lyapunov = _lyapunov_candidate(form, vertices, *frames[0])
    if lyapunov is not None:
        candidates.append(lyapunov)
    for frame in frames:
        sdp = _primal_sdp(form, vertices, *frame, margin, solver, log)
        if sdp is not None:
            candidates.append(sdp)

    def result(kind, *, candidate=None, certificate=None, dual=None, reason=""):
        P = Q = rho = max_eig = None
        if certificate is not None:
            P, Q, rho = certificate
            max_eig = max(float(np.linalg.eigvalsh(lmi_matrix(A, P, Q, rho, D_mat, form))[-1]) for A in vertices)
        return LMIResult(
            status=kind,
            form=form,
            P=None if P is None else frozen_copy(P),
            rho=rho,
            Q0=None if Q is None else frozen_copy(Q),
            certified=certificate is not None,
            inaccurate=candidate.inaccurate if candidate is not None else (dual is None and log.inaccurate),
            solver=solver,
            solver_status=candidate.solver_status
            if candidate is not None
            else (log.statuses[-1] if log.statuses else "none"),
            solve_time=log.solve_time,
            max_eigenvalue=max_eig,
            eigenvalues_P=None if P is None else frozen_copy(np.linalg.eigvalsh(P)),
            nvertices=k,
            reason=reason,
            coordinates=candidate.coordinates if candidate is not None else (frames[0][2] if dual is None else dual[1]),
            slack=candidate.slack if candidate is not None else log.slack,
            margin=None if dual is None else dual[0].margin,
            dual=None if dual is None else dual[0],
        )

    best = None
    for candidate in candidates:
        certificate = _certify(form, vertices, D_mat, q0, candidate)
        if isinstance(certificate, str):
            log.reasons.append(f"{candidate.source} ({candidate.coordinates} coordinates): {certificate}")
            continue
        feasible = result(LMIStatus.FEASIBLE, candidate=candidate, certificate=certificate)
        if best is None or sum(feasible.bound_constants()) < sum(best.bound_constants()):
            best = feasible
    if best is not None:
        return best
    for frame in frames:
        dual = _dual_certificate(form, vertices, *frame, margin, solver, log)
        if dual is not None:
            reason = (
                f"no certificate with normalised margin above {dual.margin:.3g} exists "
                f"(dual certificate re-checked in exact arithmetic, {frame[2]} coordinates)"
            )
            return result(LMIStatus.INFEASIBLE, dual=(dual, frame[2]), reason=reason)
    return result(LMIStatus.INCONCLUSIVE, reason="no proof either way: " + "; ".join(log.reasons))
