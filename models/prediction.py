"""Discrete-time interval prediction: tubes that contain every possible trajectory.

The predictor bounds ``x+ = A(theta) x + B u + D w`` for every ``theta`` in a parameter
polytope and every disturbance ``w`` in the system's box, for ANY time step and any
state matrix (Metzler or not): unlike the paper's continuous-time predictor (eq. (9),
see `continuous_predictor`), it needs no condition on ``dt``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike

from .errors import DimensionError, EmptySetError, InputError, NonFiniteError
from .polytope import VertexPolytope, parameter_vertices
from .sets import Box, Ellipsoid, ParameterSet
from .system import UncertainLinearSystem
from .validation import as_finite_array, check_dimension, check_instance, check_same_shape, check_shape, frozen_copy

__all__ = [
    "Tube",
    "IntervalPredictor",
    "predict_tube",
    "ROUNDING_TOL",
    "UNIT_ROUNDOFF",
    "interval_matvec",
    "interval_product",
    "cos_interval",
    "sin_interval",
    "summation_error_bound",
]

#: Default relative tolerance of `Tube.contains`: a state x counts as inside when
#: ``lower - tol (1 + |x|) <= x <= upper + tol (1 + |x|)``. The tube's own bounds are
#: rounded outward (they contain the exact trajectories); this slack is for the
#: rounding in the caller's floating-point simulation of the states it checks.
ROUNDING_TOL = 1e-9

#: Largest condition number of a change of basis that ``basis="auto"`` accepts (the
#: outward-rounding margins, and the wrapping of entering and leaving, grow with it).
AUTO_BASIS_MAX_CONDITION = 1e4

#: Largest condition number accepted for a user-given basis (the mismatch between the
#: computed T and T^-1 is bounded and accounted for, but grows with it).
BASIS_MAX_CONDITION = 1e6

#: ``basis="auto"`` adopts a candidate only if it narrows the trial tube by this factor.
AUTO_BASIS_MIN_GAIN = 1e-6

#: Number of steps of the trial tube by which ``basis="auto"`` compares candidate bases.
AUTO_BASIS_HORIZON = 20


#: The unit roundoff of float64, 2^-53.
UNIT_ROUNDOFF = np.finfo(float).eps / 2


def summation_error_bound(n: int) -> float:
    """A bound on the relative rounding error of an n-term floating-point sum or dot product.

    Parameters
    ----------
    n
        The number of terms (products count as terms), n u < 1.

    Returns
    -------
    float
        ``gamma_n = 2 n u / (1 - n u)`` with u = 2^-53 (`UNIT_ROUNDOFF`): twice the
        classical bound ``n u / (1 - n u)`` (Higham, *Accuracy and Stability of
        Numerical Algorithms*, Lemma 3.1), the factor 2 leaving room for the rounding of
        the error bound itself.

    Notes
    -----
    ``|fl(sum_i a_i b_i) - sum_i a_i b_i| <= gamma_n sum_i |a_i b_i|``; the interval
    predictor rounds every bound outward by such margins, so that its tubes contain the
    exact trajectories (eq. (7)).
    """
    return 2.0 * n * UNIT_ROUNDOFF / (1.0 - n * UNIT_ROUNDOFF)


def interval_product(a_lower, a_upper, b_lower, b_upper) -> tuple[np.ndarray, np.ndarray]:
    """The elementwise interval product ``[a_lower, a_upper] * [b_lower, b_upper]``.

    Parameters
    ----------
    a_lower, a_upper, b_lower, b_upper : array_like
        Bounds, broadcast together; ``lower <= upper``.

    Returns
    -------
    lower, upper : numpy.ndarray
        The smallest and largest of the four corner products (exact in real arithmetic;
        each product is one rounding, which callers that need rigour round outward).
    """
    corners = (a_lower * b_lower, a_lower * b_upper, a_upper * b_lower, a_upper * b_upper)
    lower, upper = np.minimum(corners[0], corners[1]), np.maximum(corners[0], corners[1])
    for corner in corners[2:]:  # in order, as a reduction over the stacked corners would (NaN propagates)
        lower, upper = np.minimum(lower, corner), np.maximum(upper, corner)
    return lower, upper


def cos_interval(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """Exact range of ``cos`` over ``[lo, hi]`` (elementwise, before rounding).

    Parameters
    ----------
    lo, hi : array_like
        Angles, rad, ``lo <= hi``.

    Returns
    -------
    low, high : ndarray
        ``min`` and ``max`` of cos on the interval: the endpoint values, or -1 / +1 when
        the interval holds an odd / even multiple of pi.
    """
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    a, b = np.cos(lo), np.cos(hi)
    has_max = np.floor(hi / (2 * np.pi)) * (2 * np.pi) >= lo
    has_min = np.floor((hi - np.pi) / (2 * np.pi)) * (2 * np.pi) + np.pi >= lo
    return np.where(has_min, -1.0, np.minimum(a, b)), np.where(has_max, 1.0, np.maximum(a, b))


def sin_interval(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """Exact range of ``sin`` over ``[lo, hi]`` (``sin x = cos(x - pi/2)``).

    Parameters
    ----------
    lo, hi : array_like
        Angles, rad, ``lo <= hi``.
    """
    return cos_interval(np.asarray(lo, dtype=float) - np.pi / 2, np.asarray(hi, dtype=float) - np.pi / 2)


def interval_matvec(matrix: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The tightest box containing ``{M x : lower <= x <= upper}`` for a fixed matrix M.

    Parameters
    ----------
    matrix : numpy.ndarray
        M, shape (m, n).
    lower, upper : numpy.ndarray
        Bounds of shape (..., n), ``lower <= upper``; leading dimensions are batched.

    Returns
    -------
    lower, upper : numpy.ndarray
        Shape (..., m): ``(M+ lower - M- upper, M+ upper - M- lower)`` with
        ``M+ = max(M, 0)``, ``M- = max(-M, 0)``.

    Notes
    -----
    Exact in real arithmetic; evaluated with rounding to nearest, NOT outward
    (`IntervalPredictor` adds its own rigorous margins).
    """
    positive, negative = np.maximum(matrix, 0.0), np.maximum(-matrix, 0.0)
    return lower @ positive.T - upper @ negative.T, upper @ positive.T - lower @ negative.T


@dataclass(frozen=True, eq=False)
class Tube:
    """A sequence of boxes ``[lower[n], upper[n]]``, n = 0..H, bounding a trajectory.

    Attributes
    ----------
    lower, upper
        Arrays of shape (H+1, p).
    guaranteed
        True when the predictor that made the tube guarantees inclusion (always for
        `predict_tube`; for the Euler predictor of `continuous_predictor`, only when
        its sufficient condition holds).
    note
        How the tube was made (e.g. the basis that ``basis="auto"`` chose).
    """

    lower: np.ndarray
    upper: np.ndarray
    guaranteed: bool = True
    note: str = ""

    def __post_init__(self) -> None:
        lower = as_finite_array("lower", self.lower, ndim=2)
        upper = as_finite_array("upper", self.upper, ndim=2)
        check_same_shape("lower", lower, "upper", upper)
        object.__setattr__(self, "lower", frozen_copy(lower))
        object.__setattr__(self, "upper", frozen_copy(upper))
        object.__setattr__(self, "guaranteed", bool(self.guaranteed))

    @property
    def horizon(self) -> int:
        """H, the number of steps."""
        return self.lower.shape[0] - 1

    @property
    def widths(self) -> np.ndarray:
        """``upper - lower``, shape (H+1, p)."""
        return self.upper - self.lower

    def contains(self, states, tol: float | None = None) -> bool:
        """True iff every state lies in its box.

        Parameters
        ----------
        states
            A trajectory of shape (H+1, p), or a batch of shape (..., H+1, p).
        tol
            Relative slack: x is inside when ``lower - tol (1 + |x|) <= x <= upper + tol (1 + |x|)``.
            None means `ROUNDING_TOL`, for states from a floating-point simulation; 0 is exact.
        """
        x = as_finite_array("states", states)
        if x.ndim < 2 or x.shape[-2:] != self.lower.shape:
            raise DimensionError(
                f"states must have shape {self.lower.shape} or (..., *{self.lower.shape}), got shape {x.shape}"
            )
        slack = (ROUNDING_TOL if tol is None else float(tol)) * (1.0 + np.abs(x))
        return bool(np.all(x >= self.lower - slack) and np.all(x <= self.upper + slack))

    def to_dict(self) -> dict:
        """The tube as plain data.

        Returns
        -------
        dict
            ``{"lower": [[...]], "upper": [[...]], "guaranteed": bool, "note": str}``.
        """
        return {
            "lower": self.lower.tolist(),
            "upper": self.upper.tolist(),
            "guaranteed": self.guaranteed,
            "note": self.note,
        }

    def __repr__(self) -> str:
        return f"Tube(horizon={self.horizon}, nstates={self.lower.shape[1]}, guaranteed={self.guaranteed})"


def _trial_width(vertex_matrices: np.ndarray, D: np.ndarray, w: Box, basis: np.ndarray | None) -> float:
    """Mean width, in original coordinates, of a trial tube from the unit box at the origin.

    Runs `AUTO_BASIS_HORIZON` steps without control; inf when the widths overflow.
    """
    p = vertex_matrices.shape[-1]
    if basis is not None:
        inverse = np.linalg.inv(basis)
        vertex_matrices, D = inverse @ vertex_matrices @ basis, inverse @ D
    k = vertex_matrices.shape[0]
    stacked = vertex_matrices.reshape(k * p, p)
    w_lo, w_hi = interval_matvec(D, w.low, w.high)
    lower, upper = -np.ones(p), np.ones(p)
    if basis is not None:
        lower, upper = interval_matvec(inverse, lower, upper)
    total = 0.0
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(AUTO_BASIS_HORIZON):
            new_lower, new_upper = interval_matvec(stacked, lower, upper)
            lower = new_lower.reshape(k, p).min(axis=0) + w_lo
            upper = new_upper.reshape(k, p).max(axis=0) + w_hi
            out_lower, out_upper = (lower, upper) if basis is None else interval_matvec(basis, lower, upper)
            total += float(np.sum(out_upper - out_lower))
    return total / (AUTO_BASIS_HORIZON * p) if np.isfinite(total) else np.inf


def _real_eigenbasis(matrix: np.ndarray) -> np.ndarray | None:
    """Columns: real eigenvectors and (Re v, Im v) for complex pairs, unit norm; None if not real-diagonalisable."""
    eigenvalues, eigenvectors = np.linalg.eig(matrix)
    scale = max(1.0, float(np.max(np.abs(eigenvalues))))
    columns = []
    for value, vector in zip(eigenvalues, eigenvectors.T):
        if abs(value.imag) <= 1e-12 * scale:
            columns.append(vector.real)
        elif value.imag > 0:
            columns.extend([vector.real, vector.imag])
    if len(columns) != matrix.shape[0]:
        return None
    basis = np.array(columns).T
    return basis / np.linalg.norm(basis, axis=0)


def _choose_basis(vertex_matrices: np.ndarray, D: np.ndarray, w: Box) -> tuple[np.ndarray | None, str]:
    """The basis of ``basis="auto"``: the candidate whose trial tube is narrowest.

    Candidates: the identity, the real eigenvector basis of the nominal matrix
    ``A_N`` (the mean vertex matrix; block diagonal, so ``T^-1 A_N T >= 0`` when its
    eigenvalues are real and >= 0), and its real Schur basis (orthogonal). Only bases
    with condition number <= `AUTO_BASIS_MAX_CONDITION` compete. The score is the mean
    width, in original coordinates, of a tube over `AUTO_BASIS_HORIZON` steps from the
    unit box at the origin (so it counts the cost of entering and leaving the basis
    and of the transformed disturbance and uncertainty); a candidate replaces the
    identity only if it lowers that score by the factor `AUTO_BASIS_MIN_GAIN`.
    """
    nominal = vertex_matrices.mean(axis=0)
    identity_score = _trial_width(vertex_matrices, D, w, None)
    best, best_score, best_name = None, identity_score, "identity"
    candidates = [
        ("eigenvector", _real_eigenbasis(nominal)),
        ("real Schur", scipy.linalg.schur(nominal, output="real")[1]),
    ]
    for name, basis in candidates:
        if basis is None or not np.linalg.cond(basis) <= AUTO_BASIS_MAX_CONDITION:
            continue
        score = _trial_width(vertex_matrices, D, w, basis)
        if score < best_score and score < identity_score * (1.0 - AUTO_BASIS_MIN_GAIN):
            best, best_score, best_name = basis, score, name
    if best is None:
        return (
            None,
            f"basis auto: kept the identity (no candidate narrowed the trial tube, mean width {identity_score:.6g})",
        )
    return best, f"basis auto: {best_name} basis, trial tube mean width {identity_score:.6g} -> {best_score:.6g}"


#: Relative growth of every rounding-error bound of a step, for the rounding in evaluating
#: the bound itself.
_SAFETY = 1.0 + 1e-10


def _distinct_vertex_matrices(
    system: UncertainLinearSystem, parameters, name: str = "parameters"
) -> tuple[np.ndarray, np.ndarray]:
    """``A(v)`` for the distinct vertices v of a parameter set, and the bound on forming them.

    Returns the distinct matrices (k, p, p), in `numpy.unique` order, and an elementwise
    bound (p, p), one for all of them, on the rounding in ``A0 + sum_i v_i phi_i``.
    """
    p, d = system.nstates, system.nparams
    if parameters is None:
        parameters = system.theta
    if isinstance(parameters, (Box, Ellipsoid, VertexPolytope)):  # `parameter_vertices` without its checks
        vertices = parameters.enclosing_vertices()
    else:
        vertices = parameter_vertices(parameters)
    if vertices.shape[1] != d:
        raise DimensionError(
            f"{name} must have dimension {d} (phi has shape {system.phi.shape}), got vertices of shape {vertices.shape}"
        )
    k = len(vertices)
    # A(v) = A0 + sum_i v_i phi_i, as `UncertainLinearSystem.A` forms it (its tensordot is this dot).
    raw = system.A0 + np.dot(vertices, system.phi.reshape(d, p * p)).reshape(k, p, p)
    # Rounding in forming A(v) (d + 1 terms), one bound for all vertices.
    formation_error = summation_error_bound(d + 1) * np.max(
        np.abs(system.A0) + np.dot(np.abs(vertices), np.abs(system.phi).reshape(d, p * p)).reshape(k, p, p), axis=0
    )
    matrices = _unique_rows(raw.reshape(k, p * p)).reshape(-1, p, p)
    return matrices, formation_error


def _unique_rows(rows: np.ndarray) -> np.ndarray:
    """``numpy.unique(rows, axis=0)``, the same array, five times faster when no two rows are equal.

    Without equal rows (under ``==``) both sort the rows lexicographically by the same
    strict order, so they agree; with equal or non-finite rows, `numpy.unique` itself
    decides (which of two rows that differ only in the sign of a zero it keeps).
    """
    ordered = rows[np.lexsort(rows.T[::-1])]
    if not np.all(np.isfinite(ordered)) or np.any(np.all(ordered[1:] == ordered[:-1], axis=1)):
        return np.unique(rows, axis=0)
    return ordered


def _checked_basis(basis, p: int):
    """``basis`` validated: None, ``"auto"``, or the (p, p) matrix as a float array."""
    if basis is None:
        return None
    if isinstance(basis, str):
        if basis != "auto":
            raise InputError(f'basis must be None, "auto" or a (p, p) matrix, got {basis!r}')
        return basis
    transform = as_finite_array("basis", basis, (p, p))
    condition = np.linalg.cond(transform)
    if not condition <= BASIS_MAX_CONDITION:
        raise InputError(
            f"basis must be invertible with condition number <= {BASIS_MAX_CONDITION:g}, got {condition:.3g}"
        )
    return transform


class _Frame:
    """The change of basis of a predictor, shared by every step of a tube.

    Holds T and the computed ``T^-1`` (None for the identity), the bounds on the rounding
    of entering and leaving the basis and of the mismatch between T and ``T^-1``, the
    transformed ``B`` and ``D`` with their rounding bounds, and the step's error factors
    that do not depend on the parameter set or the disturbance box.
    """

    def __init__(self, system: UncertainLinearSystem, basis, matrices: np.ndarray, w: Box) -> None:
        # ``basis`` as returned by `_checked_basis`; ``matrices`` and ``w`` are what "auto" compares on.
        p = system.nstates
        self.system, self.p, self.note = system, p, ""
        if isinstance(basis, str):
            transform, self.note = _choose_basis(matrices, system.D, w)
        else:
            transform = basis
        self.transform = transform
        if transform is None:
            self.basis = frozen_copy(np.eye(p))
            self.inverse = None
            B, D = system.B, system.D
            B_error, D_error = np.zeros_like(B), np.zeros_like(D)
        else:
            self.basis = frozen_copy(transform)
            inverse = np.linalg.inv(transform)
            self.inverse = inverse
            abs_t, abs_inv = np.abs(transform), np.abs(inverse)
            # The internal state is z = inverse @ x exactly, so x = S z with S the exact
            # inverse of `inverse`; bound |S - T| from the residual R = I - inverse @ T.
            residual = np.abs(np.eye(p) - inverse @ transform) + summation_error_bound(p + 1) * (
                np.eye(p) + abs_inv @ abs_t
            )
            r = float(np.max(residual.sum(axis=1)))
            if not r < 0.5:
                raise InputError(f"basis is too ill-conditioned for rigorous bounds: ||I - T^-1 T|| bound {r:.3g}")
            inverse_error = abs_t @ residual
            inverse_error = inverse_error + (r / (1 - r)) * inverse_error.sum(axis=1, keepdims=True)
            self.abs_t, self.abs_inv, self.inverse_error = abs_t, abs_inv, inverse_error
            self.leave_error = summation_error_bound(2 * p + 1) * abs_t + inverse_error
            self.enter_error = summation_error_bound(2 * p + 1) * abs_inv
            B, D = inverse @ system.B, inverse @ system.D
            B_error, D_error = (
                summation_error_bound(p) * abs_inv @ np.abs(system.B),
                summation_error_bound(p) * abs_inv @ np.abs(system.D),
            )
        self.D, self.D_error = D, D_error
        self.B_T = np.ascontiguousarray(B.T)
        # B+ and B- (disjoint supports) for box-valued inputs, see `IntervalPredictor.step_interval`.
        self.B_pos_T = np.ascontiguousarray(np.maximum(B, 0.0).T)
        self.B_neg_T = np.ascontiguousarray(np.maximum(-B, 0.0).T)
        # Outward rounding: the step's error is at most  m @ G.T + |u| @ H.T + g  with
        # m = max(|z_lo|, |z_hi|); see the IntervalPredictor Notes. The n-term sum counts the
        # 2p products, the q control terms, the constant, the margin and the final rounding.
        self.gamma_step = summation_error_bound(2 * p + system.ninputs + 5)
        self.error_input_T = np.ascontiguousarray(_SAFETY * (B_error + self.gamma_step * np.abs(B)).T)
        # Underflow: each of the terms may lose up to the smallest subnormal.
        self.underflow = (2 * p + system.ninputs + 5) * 2.0 * np.finfo(float).smallest_subnormal

    def vertex_step(self, matrices: np.ndarray, formation_error: np.ndarray) -> _VertexStep:
        """The parameter-dependent part of a step, for vertex matrices in original coordinates."""
        p = self.p
        abs_matrices = np.max(np.abs(matrices), axis=0)
        if self.transform is None:
            matrix_error = formation_error
        else:
            inverse, transform = self.inverse, self.transform
            abs_t, abs_inv = self.abs_t, self.abs_inv
            matrices = inverse @ matrices @ transform
            # Target: inverse @ A_exact(v) @ S. Error: rounding of the triple product, of
            # forming A(v), and of using T for S.
            matrix_error = (
                summation_error_bound(2 * p + 1) * abs_inv @ abs_matrices @ abs_t
                + abs_inv @ formation_error @ abs_t
                + abs_inv @ (abs_matrices + formation_error) @ self.inverse_error
            )
            abs_matrices = np.max(np.abs(matrices), axis=0)
        k = matrices.shape[0]
        stacked = matrices.reshape(k * p, p)
        positive, negative = np.maximum(stacked, 0.0).T, np.maximum(-stacked, 0.0).T
        # [z_lo, z_hi] @ product -> [all lower candidates | all upper candidates], shape (..., 2 k p):
        # the block matrix [[M+^T, -M-^T], [-M-^T, M+^T]].
        product = np.empty((2 * p, 2 * k * p))
        product[:p, : k * p], product[:p, k * p :] = positive, -negative
        product[p:, : k * p], product[p:, k * p :] = -negative, positive
        error_state_T = np.ascontiguousarray(_SAFETY * (matrix_error + self.gamma_step * abs_matrices).T)
        return _VertexStep(frozen_copy(matrices), frozen_copy(matrix_error), product, k, error_state_T)

    def shifts(self, w_low: np.ndarray, w_high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The disturbance part of a step, widened by its rounding bound: (lower, upper) shifts."""
        D = self.D
        w_lo, w_hi = interval_matvec(D, w_low, w_high)
        w_max = np.maximum(np.abs(w_low), np.abs(w_high))
        w_error = summation_error_bound(2 * self.system.ndisturbances + 1) * np.abs(D) @ w_max + self.D_error @ w_max
        constant = _SAFETY * (w_error + self.gamma_step * np.maximum(np.abs(w_lo), np.abs(w_hi))) + self.underflow
        return w_lo - constant, w_hi + constant


class _VertexStep:
    """The parameter-set part of a step: vertex matrices (in the basis), error bounds, product."""

    __slots__ = ("matrices", "matrix_error", "product", "nvertices", "error_state_T")

    def __init__(self, matrices, matrix_error, product, nvertices, error_state_T) -> None:
        self.matrices, self.matrix_error, self.product = matrices, matrix_error, product
        self.nvertices, self.error_state_T = nvertices, error_state_T


def _check_disturbance_box(system: UncertainLinearSystem, disturbances) -> Box:
    """``disturbances`` of `IntervalPredictor`: None means ``system.w``; else a Box of dimension r."""
    if disturbances is None:
        return system.w
    check_instance("disturbances", disturbances, Box)
    check_dimension("disturbances", disturbances.dim, system.ndisturbances, f"columns of D, shape {system.D.shape}")
    return disturbances


class IntervalPredictor:
    """One-step interval predictor of an uncertain linear system, on raw arrays.

    Parameters
    ----------
    system
        The discrete-time `UncertainLinearSystem`.
    parameters
        A `ParameterSet` (`Box`, `Ellipsoid`, `VertexPolytope`) or a vertex array (k, d);
        default ``system.theta``.
        The guarantee covers every theta in this set (it is not intersected with
        ``system.theta``; use `parameter_vertices` with ``prior=`` for that).
    basis
        None (identity), ``"auto"``, or an invertible (p, p) matrix T: the predictor
        then bounds ``z = T^-1 x``, whose dynamics use ``T^-1 A(theta) T``,
        ``T^-1 B`` and ``T^-1 D``.
    disturbances
        A `Box` of dimension r that replaces ``system.w`` as the set of disturbances
        (None: ``system.w``).

    Attributes
    ----------
    basis : numpy.ndarray
        The T in use (the identity for None, and for ``"auto"`` when no candidate helps).
    basis_note : str
        What ``"auto"`` chose and why (empty unless ``basis="auto"``).
    vertex_matrices : numpy.ndarray
        ``T^-1 A(v_k) T`` for the distinct parameter vertices v_k, shape (k, p, p).
    vertex_matrix_error : numpy.ndarray
        Elementwise bound (p, p) on ``|vertex_matrices[k] - (the exact matrix they round)|``,
        one for all k (forming ``A(v)``, and the basis change when there is one).

    Notes
    -----
    Let ``M_k = T^-1 A(v_k) T``. For a fixed z, ``theta -> T^-1 A(theta) T z`` is affine,
    so over the polytope co{v_k} (eq. (8)) its extremes are at vertices; over the box
    ``[z_lo, z_hi]`` the extremes of ``M z`` are ``M+ z_lo - M- z_hi`` and
    ``M+ z_hi - M- z_lo``. Hence

    ``z_lo+ = min_k (M_k+ z_lo - M_k- z_hi) + T^-1 B u + (T^-1 D)+ w_lo - (T^-1 D)- w_hi``

    (and symmetrically ``z_hi+`` with max) is the TIGHTEST box containing every
    successor ``A(theta) x + B u + D w`` of the box, for every dt and every A: the
    minimum over (theta, z) of a row is attained at a parameter vertex and a box
    corner, and the disturbance term separates. The inclusion property eq. (7) follows
    by induction (theta may even vary in time). Any other sound one-step bound contains
    this box, in particular the errata's form of eq. (9), ``A_N x`` plus the elementwise
    max over k of the positive/negative parts of ``X_k = A(v_k) - A_N``, and the exact
    interval-matrix product with ``[A_N + min_k X_k, A_N + max_k X_k]``. Its cost is k
    matrix products of size p, done as one batched product.

    For a box of inputs ``[u_lo, u_hi]`` (`step_interval`), the input term separates
    too and its exact extremes are ``(T^-1 B)+ u_lo - (T^-1 B)- u_hi`` and
    ``(T^-1 B)+ u_hi - (T^-1 B)- u_lo``: the one-step box is still the tightest.

    With ``basis="auto"`` the predictor seeks ``T^-1 A_N T >= 0`` (discrete time:
    nonnegative, not Metzler), for which the nominal part has no wrapping effect; a
    candidate is kept only if it narrows a trial tube (see ``_choose_basis``). Every
    T gives a sound predictor: entering and leaving the basis use exact interval
    products, so keeping the identity is never less sound, only possibly wider.

    Rounding: every bound is rounded outward, so the tube contains the EXACT
    trajectories, not just up to a tolerance (in a non-normal system, rounding errors
    of an interval recursion grow like ``rho(|M|)^n``, faster than the states, so a
    fixed relative tolerance would not do). Each step subtracts a rigorous bound
    ``max(|z_lo|, |z_hi|) @ G^T + |u| @ H^T + g`` on its floating-point error
    (``gamma_n = 2 n u / (1 - n u)`` per n-term sum, u = 2^-53, plus the rounding of
    forming ``A(v_k)``, of the basis change and of the mismatch between the computed
    T and T^-1); n includes the final additions, so the rounded results are still
    outward. The cost is one more small matrix product per step; the margins are of
    order eps relative to ``|x|``. For a box of inputs, ``|u|`` is ``max(|u_lo|, |u_hi|)``
    and the same n holds: ``B+`` and ``B-`` have disjoint supports, so each row of the
    input term has at most q nonzero products (a zero product and the addition of an
    exact zero are exact).
    """

    def __init__(self, system: UncertainLinearSystem, parameters=None, *, basis=None, disturbances=None) -> None:
        check_instance("system", system, UncertainLinearSystem)
        w = _check_disturbance_box(system, disturbances)
        matrices, formation_error = _distinct_vertex_matrices(system, parameters)
        frame = _Frame(system, _checked_basis(basis, system.nstates), matrices, w)
        self._assemble(frame, frame.vertex_step(matrices, formation_error), frame.shifts(w.low, w.high))

    @classmethod
    def _from_parts(cls, frame: _Frame, vertex_step: _VertexStep, shifts) -> IntervalPredictor:
        """A predictor from precomputed parts (no validation, no computation)."""
        predictor = cls.__new__(cls)
        predictor._assemble(frame, vertex_step, shifts)
        return predictor

    def _assemble(self, frame: _Frame, vertex_step: _VertexStep, shifts) -> None:
        self.system = frame.system
        self.basis = frame.basis
        self.basis_note = frame.note
        self.vertex_matrices = vertex_step.matrices
        self.vertex_matrix_error = vertex_step.matrix_error
        self._frame, self._vertex_step = frame, vertex_step
        self._transform, self._inverse = frame.transform, frame.inverse
        if frame.transform is not None:
            self._enter_error, self._leave_error = frame.enter_error, frame.leave_error
        self._nvertices, self._p = vertex_step.nvertices, frame.p
        self._product = vertex_step.product
        self._error_state_T = vertex_step.error_state_T
        self._B_T, self._error_input_T = frame.B_T, frame.error_input_T
        self._lower_shift, self._upper_shift = shifts

    @property
    def nvertices(self) -> int:
        """The number of distinct vertex matrices used per step."""
        return self._nvertices

    def with_sets(self, parameters=None, *, disturbances: Box | None = None) -> IntervalPredictor:
        """A predictor in the SAME basis for another parameter set and disturbance box.

        Parameters
        ----------
        parameters
            A `ParameterSet` or a vertex array (k, d); None keeps this predictor's.
        disturbances
            A `Box` of dimension r; None keeps this predictor's.

        Returns
        -------
        IntervalPredictor
            Its `enter` and `leave` are this predictor's (same T, same ``T^-1``), so
            internal boxes pass from one predictor to the other: chaining the steps of
            predictors for the sets P_0, P_1, ... bounds the trajectories whose
            parameters lie in P_n at step n (eq. (7)). ``basis_note`` is this one's.
        """
        frame = self._frame
        if parameters is None:
            vertex_step = self._vertex_step
        else:
            vertex_step = frame.vertex_step(*_distinct_vertex_matrices(frame.system, parameters))
        if disturbances is None:
            shifts = (self._lower_shift, self._upper_shift)
        else:
            w = _check_disturbance_box(frame.system, disturbances)
            shifts = frame.shifts(w.low, w.high)
        return IntervalPredictor._from_parts(frame, vertex_step, shifts)

    def enter(self, lower: ArrayLike, upper: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """The box ``[lower, upper]`` in original coordinates as an internal box ``z = T^-1 x``.

        Parameters
        ----------
        lower, upper : array_like
            Bounds of shape (..., p) in the original coordinates, ``lower <= upper``.

        Returns
        -------
        z_lower, z_upper : numpy.ndarray
            Shape (..., p): copies when the basis is the identity, otherwise the exact
            interval product with ``T^-1`` rounded outward (it contains ``T^-1 x`` for
            every x of the box).
        """
        lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
        if self._inverse is None:
            return lower.copy(), upper.copy()
        z_lower, z_upper = interval_matvec(self._inverse, lower, upper)
        return _widen(z_lower, z_upper, np.maximum(np.abs(lower), np.abs(upper)) @ self._enter_error.T)

    def leave(self, lower: ArrayLike, upper: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """An internal box back in original coordinates.

        Parameters
        ----------
        lower, upper : array_like
            Internal bounds (on ``z = T^-1 x``) of shape (..., p).

        Returns
        -------
        x_lower, x_upper : numpy.ndarray
            Shape (..., p): copies when the basis is the identity, otherwise the interval
            product with T rounded outward (it contains every ``x = T z`` of the box,
            with the exact inverse of the computed ``T^-1``).
        """
        lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
        if self._transform is None:
            return lower.copy(), upper.copy()
        x_lower, x_upper = interval_matvec(self._transform, lower, upper)
        return _widen(x_lower, x_upper, np.maximum(np.abs(lower), np.abs(upper)) @ self._leave_error.T)

    def _vertex_extremes(self, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``min_k (M_k+ z_lo - M_k- z_hi)`` and ``max_k (M_k+ z_hi - M_k- z_lo)``, rounded to nearest."""
        k, p = self._nvertices, self._p
        candidates = np.concatenate([lower, upper], axis=-1) @ self._product
        if candidates.ndim == 1:
            return candidates[: k * p].reshape(k, p).min(axis=0), candidates[k * p :].reshape(k, p).max(axis=0)
        # numpy reduces a short middle axis slowly; fold the k slices pairwise instead
        new_lower, new_upper = candidates[..., :p], candidates[..., k * p : (k + 1) * p]
        for j in range(1, k):
            new_lower = np.minimum(new_lower, candidates[..., j * p : (j + 1) * p])
            new_upper = np.maximum(new_upper, candidates[..., (k + j) * p : (k + j + 1) * p])
        return new_lower, new_upper

    def step(self, lower: np.ndarray, upper: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One step of the predictor on internal boxes.

        Parameters
        ----------
        lower, upper : numpy.ndarray
            Internal boxes (see `enter`), float arrays of shape (..., p).
        u : numpy.ndarray
            Controls, float array of shape (..., q); leading dimensions broadcast with
            the boxes'.

        Returns
        -------
        lower, upper : numpy.ndarray
            The successor boxes, rounded outward: they contain
            ``T^-1 (A(theta) x + B u + D w)`` for every x of the box, theta in the
            parameter polytope and w in the disturbance box (eq. (7), one step).

        Notes
        -----
        No validation: this is a planner's hot loop. See the class Notes for the bound
        and the rounding.
        """
        new_lower, new_upper = self._vertex_extremes(lower, upper)
        drift = u @ self._B_T
        error = np.maximum(np.abs(lower), np.abs(upper)) @ self._error_state_T + np.abs(u) @ self._error_input_T
        return new_lower + (drift - error) + self._lower_shift, new_upper + (drift + error) + self._upper_shift

    def step_interval(
        self, lower: np.ndarray, upper: np.ndarray, u_lower: np.ndarray, u_upper: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One step of the predictor on internal boxes, for a box of inputs.

        Parameters
        ----------
        lower, upper : numpy.ndarray
            Internal boxes (see `enter`), float arrays of shape (..., p).
        u_lower, u_upper : numpy.ndarray
            Bounds of the inputs, float arrays of shape (..., q), ``u_lower <= u_upper``;
            leading dimensions broadcast with the boxes'.

        Returns
        -------
        lower, upper : numpy.ndarray
            The successor boxes, rounded outward: they contain
            ``T^-1 (A(theta) x + B u + D w)`` for every x of the box, theta in the
            parameter polytope, u in ``[u_lower, u_upper]`` and w in the disturbance
            box (eq. (7), one step).

        Notes
        -----
        No validation. The input term is bounded by exact interval arithmetic,
        ``B+ u_lower - B- u_upper`` and ``B+ u_upper - B- u_lower`` (B in the basis),
        and rounded outward as in `step` (see the class Notes).
        """
        new_lower, new_upper = self._vertex_extremes(lower, upper)
        frame = self._frame
        drift_lower = u_lower @ frame.B_pos_T - u_upper @ frame.B_neg_T
        drift_upper = u_upper @ frame.B_pos_T - u_lower @ frame.B_neg_T
        error = (
            np.maximum(np.abs(lower), np.abs(upper)) @ self._error_state_T
            + np.maximum(np.abs(u_lower), np.abs(u_upper)) @ self._error_input_T
        )
        return (
            new_lower + (drift_lower - error) + self._lower_shift,
            new_upper + (drift_upper + error) + self._upper_shift,
        )


def _widen(lower: np.ndarray, upper: np.ndarray, error: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``[lower - error, upper + error]``, each bound then moved one ulp outward."""
    return np.nextafter(lower - error, -np.inf), np.nextafter(upper + error, np.inf)


def _check_no_overflow(lower: np.ndarray, upper: np.ndarray) -> None:
    """Raise `NonFiniteError` naming the first step whose bounds left the float range."""
    finite = np.all(np.isfinite(lower) & np.isfinite(upper), axis=1)
    if not np.all(finite):
        step = int(np.argmin(finite))
        raise NonFiniteError(
            f"the tube's bounds overflowed at step {step} of {lower.shape[0] - 1}: the predicted widths "
            "grew beyond the float range (an unstable system over a long horizon)"
        )


def _is_parameter_set(value) -> bool:
    """``isinstance(value, ParameterSet)``, the library's own sets first (a Protocol check is slow)."""
    return isinstance(value, (Box, Ellipsoid, VertexPolytope)) or isinstance(value, ParameterSet)


def _depth(value) -> int:
    """How deeply ``value`` nests lists, tuples and arrays (0 for anything else), by first elements."""
    if isinstance(value, np.ndarray):
        return value.ndim
    if isinstance(value, (list, tuple)):
        return 1 + (_depth(value[0]) if len(value) else 0)
    return 0


def _is_bound_pair(value) -> bool:
    """True for a ``(lower, upper)`` pair of 2-D arrays (never a valid (H, q) array: that is 3-D)."""
    return isinstance(value, (list, tuple)) and len(value) == 2 and all(_depth(v) == 2 for v in value)


def _is_box_sequence(value) -> bool:
    """True for a non-empty list or tuple with a `Box` among its entries."""
    return isinstance(value, (list, tuple)) and len(value) > 0 and any(isinstance(v, Box) for v in value)


def _step_boxes(name: str, value, steps: int | None, dim: int, reason: str) -> tuple[np.ndarray, np.ndarray]:
    """Per-step boxes given as a (lower, upper) pair of (H, dim) arrays or a sequence of H `Box` objects.

    ``steps`` None accepts any H (the controls define it). Checks shapes, NaN/inf and
    ``lower <= upper``; returns the bounds as float arrays (H, dim).
    """
    if _is_bound_pair(value):
        lower = as_finite_array(f"{name} lower", value[0], ndim=2)
        upper = as_finite_array(f"{name} upper", value[1], ndim=2)
        check_shape(f"{name} lower", lower, (steps, dim))
        check_same_shape(f"{name} lower", lower, f"{name} upper", upper)
        empty = lower > upper
        if np.any(empty):
            n, i = (int(j) for j in np.argwhere(empty)[0])
            raise EmptySetError(
                f"{name} is empty at step {n}: "
                f"lower[{n}, {i}] = {float(lower[n, i])!r} > upper[{n}, {i}] = {float(upper[n, i])!r}"
            )
        return lower, upper
    for n, box in enumerate(value):
        check_instance(f"{name}[{n}]", box, Box)
        check_dimension(f"{name}[{n}]", box.dim, dim, reason)
    if steps is not None and len(value) != steps:
        raise DimensionError(f"{name} must have one box per step, {steps} (the controls' length), got {len(value)}")
    return np.array([box.low for box in value]), np.array([box.high for box in value])


def _step_parameters(system: UncertainLinearSystem, parameters, steps: int) -> list:
    """The per-step parameter sets, checked: each a `ParameterSet` or a vertex array (k, d)."""
    if len(parameters) != steps:
        raise DimensionError(
            f"parameters must have one set per step, {steps} (the controls' length), got {len(parameters)}"
        )
    checked = []
    for n, entry in enumerate(parameters):
        name = f"parameters[{n}]"
        if _is_parameter_set(entry):
            check_dimension(name, entry.dim, system.nparams, f"phi has shape {system.phi.shape}")
        else:
            vertices = as_finite_array(name, entry, ndim=2)
            if vertices.shape[0] == 0:
                raise DimensionError(
                    f"{name} must have shape (k, {system.nparams}) with k >= 1, got shape {vertices.shape}"
                )
            check_shape(name, vertices, (None, system.nparams))
            entry = VertexPolytope(vertices)
        checked.append(entry)
    return checked


def _distinct_sets(system: UncertainLinearSystem, sets: list) -> tuple[list, list[int]]:
    """The distinct sets' vertex matrices (each computed once) and the index of each step's set.

    Sets are the same when they are the same object or have the same vertex matrices.
    """
    distinct: list[tuple[np.ndarray, np.ndarray]] = []
    by_identity: dict[int, int] = {}
    by_content: dict[tuple, int] = {}
    set_of_step = []
    for entry in sets:
        index = by_identity.get(id(entry))
        if index is None:
            matrices, formation_error = _distinct_vertex_matrices(system, entry)
            key = (matrices.shape, matrices.tobytes(), formation_error.tobytes())
            index = by_content.setdefault(key, len(distinct))
            if index == len(distinct):
                distinct.append((matrices, formation_error))
            by_identity[id(entry)] = index
        set_of_step.append(index)
    return distinct, set_of_step


def _distinct_shifts(
    frame: _Frame, w_lower: np.ndarray, w_upper: np.ndarray
) -> tuple[list[int], list[tuple[np.ndarray, np.ndarray]]]:
    """Each step's index into the shifts of the distinct disturbance boxes (each from fresh 1-D copies)."""
    by_box: dict[bytes, int] = {}
    box_of_step: list[int] = []
    shifts: list[tuple[np.ndarray, np.ndarray]] = []
    for lo, hi in zip(w_lower, w_upper):
        key = lo.tobytes() + hi.tobytes()
        index = by_box.get(key)
        if index is None:
            index = by_box[key] = len(shifts)
            shifts.append(frame.shifts(np.array(lo), np.array(hi)))
        box_of_step.append(index)
    return box_of_step, shifts


def predict_tube(
    system: UncertainLinearSystem,
    x0: Box,
    controls,
    parameters=None,
    *,
    basis=None,
    disturbances=None,
) -> Tube:
    """Predict a tube that contains every trajectory of an uncertain system.

    Parameters
    ----------
    system
        The discrete-time `UncertainLinearSystem` ``x+ = A(theta) x + B u + D w``.
    x0
        `Box` of initial states, dimension p.
    controls
        The inputs, one of:

        - an array of shape (H, q): the known control sequence;
        - a ``(lower, upper)`` pair of (H, q) arrays, or a sequence of H `Box` objects of
          dimension q: at step n the input is any ``u_n`` in the box (e.g. a leader's
          predicted state). A step whose box is a point is the point control.
    parameters
        A `ParameterSet` (`Box`, `Ellipsoid`, `VertexPolytope`) or a vertex array (k, d),
        used at every step; default ``system.theta``. Or one set per step: a sequence of
        H such sets (or an array (H, k, d)), step n using set n.
    basis
        None, ``"auto"`` or an invertible (p, p) matrix, see `IntervalPredictor`. One
        basis for the whole tube: ``"auto"`` chooses it once, from the union of every
        step's parameter vertices (and the hull of the disturbance boxes).
    disturbances
        What replaces ``system.w`` as the disturbance set: None (``system.w`` at every
        step), a `Box` of dimension r (at every step), or one box per step, a
        ``(lower, upper)`` pair of (H, r) arrays or a sequence of H `Box` objects (e.g. the
        bounds of a model's nonlinear remainder along the tube).

    Returns
    -------
    Tube
        ``lower``, ``upper`` of shape (H+1, p).

    Raises
    ------
    InputError
        For an argument of the wrong kind (the message names it).
    DimensionError
        For a wrong shape or dimension, or a per-step sequence whose length is not H
        (the message names the argument and both shapes).
    NonFiniteError
        For NaN or inf in an argument, or if the bounds overflow the float range.
    EmptySetError
        For a box of controls or disturbances with ``lower > upper`` somewhere.

    Notes
    -----
    Guarantee (the inclusion property, eq. (7)), for every dt and every system, Metzler
    or not: for every ``theta_n`` in ``P_n`` (the step's parameter set, switching
    arbitrarily at every step), every ``u_n`` in ``U_n`` (the step's control box, or the
    control itself), every ``w_n`` in ``W_n`` (the step's disturbance box) and every x0
    in the box, the exact trajectory of ``x_{n+1} = A(theta_n) x_n + B u_n + D w_n``
    satisfies ``lower[n] <= x_n <= upper[n]``, n = 0..H. The bounds are rounded
    outward, so this holds for the exact x_n, not only up to a tolerance. Each step is
    the tightest box that contains the successors of the previous box (see
    `IntervalPredictor`); unlike the paper's continuous-time predictor eq. (9), no
    condition on dt or on A is needed.
    ``parameters`` is used as given, not intersected with ``system.theta``.
    Every argument is checked before any work; with one set for every step, no
    disturbance boxes and point controls, the result is the same, bit for bit, as
    passing H copies of the set, of ``system.w`` and of the controls as point boxes.
    """
    check_instance("system", system, UncertainLinearSystem)
    check_instance("x0", x0, Box)
    check_dimension("x0", x0.dim, system.nstates, f"A0 has shape {system.A0.shape}")
    q, r = system.ninputs, system.ndisturbances
    if _is_bound_pair(controls) or _is_box_sequence(controls):
        u_lower, u_upper = _step_boxes("controls", controls, None, q, f"B has shape {system.B.shape}")
        is_point = np.all(u_lower == u_upper, axis=1)
    else:
        u_lower = u_upper = as_finite_array("controls", controls, ndim=2)
        check_shape("controls", u_lower, (None, q))
        is_point = np.ones(u_lower.shape[0], dtype=bool)
    steps = u_lower.shape[0]
    per_step = isinstance(parameters, np.ndarray) and parameters.ndim == 3
    per_step = per_step or (
        isinstance(parameters, (list, tuple))
        and len(parameters) > 0
        and any(_is_parameter_set(entry) or _depth(entry) >= 2 for entry in parameters)
    )
    if per_step:
        sets = _step_parameters(system, parameters, steps)
    else:  # one set: its vertices are how it is checked (as IntervalPredictor does)
        distinct = [_distinct_vertex_matrices(system, parameters)]
        set_of_step = [0] * steps
    if disturbances is None:
        w_lower = w_upper = None
    elif isinstance(disturbances, Box):
        check_dimension("disturbances", disturbances.dim, r, f"columns of D, shape {system.D.shape}")
        w_lower, w_upper = np.tile(disturbances.low, (steps, 1)), np.tile(disturbances.high, (steps, 1))
    elif _is_bound_pair(disturbances) or _is_box_sequence(disturbances):
        w_lower, w_upper = _step_boxes("disturbances", disturbances, steps, r, f"columns of D, shape {system.D.shape}")
    else:
        raise InputError(
            "disturbances must be None, a Box, a (lower, upper) pair of (H, r) arrays or a sequence of H Boxes, "
            f"got {type(disturbances).__name__}"
        )
    basis = _checked_basis(basis, system.nstates)

    if per_step:
        distinct, set_of_step = _distinct_sets(system, sets)
    # The basis, once for the whole tube.
    if len(distinct) == 1:
        union = distinct[0][0]
    else:
        p = system.nstates
        union = _unique_rows(np.concatenate([m for m, _ in distinct]).reshape(-1, p * p)).reshape(-1, p, p)
    if w_lower is None or steps == 0:
        hull = system.w
    else:
        assert w_upper is not None  # set together with w_lower
        hull = Box(w_lower.min(axis=0), w_upper.max(axis=0))
    frame = _Frame(system, basis, union, hull)
    vertex_steps = [frame.vertex_step(matrices, formation_error) for matrices, formation_error in distinct]
    if w_lower is None or steps == 0:
        box_of_step, shifts = [0] * steps, [frame.shifts(system.w.low, system.w.high)]
    else:
        assert w_upper is not None  # set together with w_lower
        box_of_step, shifts = _distinct_shifts(frame, w_lower, w_upper)
    predictors: dict[tuple[int, int], IntervalPredictor] = {}
    first = IntervalPredictor._from_parts(frame, vertex_steps[0], shifts[0])
    predictors[0, 0] = first

    lower = np.empty((steps + 1, system.nstates))
    upper = np.empty_like(lower)
    lower[0], upper[0] = x0.low, x0.high
    z_lo, z_hi = first.enter(x0.low, x0.high)
    with np.errstate(over="ignore", invalid="ignore"):
        for n in range(steps):
            key = (set_of_step[n], box_of_step[n])
            predictor = predictors.get(key)
            if predictor is None:
                predictor = predictors[key] = IntervalPredictor._from_parts(frame, vertex_steps[key[0]], shifts[key[1]])
            if is_point[n]:
                z_lo, z_hi = predictor.step(z_lo, z_hi, u_lower[n])
            else:
                z_lo, z_hi = predictor.step_interval(z_lo, z_hi, u_lower[n], u_upper[n])
            lower[n + 1], upper[n + 1] = first.leave(z_lo, z_hi)
    _check_no_overflow(lower, upper)
    return Tube(lower, upper, guaranteed=True, note=frame.note)
