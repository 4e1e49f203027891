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

from .errors import DimensionError, InputError, NonFiniteError
from .polytope import parameter_vertices
from .sets import Box
from .system import UncertainLinearSystem
from .validation import as_finite_array, check_dimension, check_instance, check_same_shape, check_shape, frozen_copy

__all__ = [
    "Tube",
    "IntervalPredictor",
    "predict_tube",
    "ROUNDING_TOL",
    "UNIT_ROUNDOFF",
    "interval_matvec",
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

    Attributes
    ----------
    basis : numpy.ndarray
        The T in use (the identity for None, and for ``"auto"`` when no candidate helps).
    basis_note : str
        What ``"auto"`` chose and why (empty unless ``basis="auto"``).
    vertex_matrices : numpy.ndarray
        ``T^-1 A(v_k) T`` for the distinct parameter vertices v_k, shape (k, p, p).

    Notes
    -----
    Let ``M_k = T^-1 A(v_k) T``. For a fixed z, ``theta -> T^-1 A(theta) T z`` is affine,
    so over the polytope co{v_k} its extremes are at vertices; over the box
    ``[z_lo, z_hi]`` the extremes of ``M z`` are ``M+ z_lo - M- z_hi`` and
    ``M+ z_hi - M- z_lo``. Hence

    ``z_lo+ = min_k (M_k+ z_lo - M_k- z_hi) + T^-1 B u + (T^-1 D)+ w_lo - (T^-1 D)- w_hi``

    (and symmetrically ``z_hi+`` with max) is the TIGHTEST box containing every
    successor ``A(theta) x + B u + D w`` of the box, for every dt and every A: the
    minimum over (theta, z) of a row is attained at a parameter vertex and a box
    corner, and the disturbance term separates. Eq. (7) follows by induction (theta
    may even vary in time). Any other sound one-step bound contains this box, in
    particular the errata's form ``A_N x`` plus the elementwise max over k of the
    positive/negative parts of ``X_k = A(v_k) - A_N``, and the exact interval-matrix
    product with ``[A_N + min_k X_k, A_N + max_k X_k]``. Its cost is k matrix
    products of size p, done as one batched product.

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
    order eps relative to ``|x|``.
    """

    def __init__(self, system: UncertainLinearSystem, parameters=None, *, basis=None) -> None:
        check_instance("system", system, UncertainLinearSystem)
        p = system.nstates
        vertices = parameter_vertices(system.theta if parameters is None else parameters)
        if vertices.shape[1] != system.nparams:
            raise DimensionError(
                f"parameters must have dimension {system.nparams} (phi has shape {system.phi.shape}), "
                f"got vertices of shape {vertices.shape}"
            )
        raw = system.A(vertices)
        # Rounding in forming A(v) = A0 + sum_i v_i phi_i (d + 1 terms), one bound for all vertices.
        formation_error = summation_error_bound(system.nparams + 1) * np.max(
            np.abs(system.A0) + np.tensordot(np.abs(vertices), np.abs(system.phi), axes=1), axis=0
        )
        matrices = np.unique(raw.reshape(len(vertices), p * p), axis=0).reshape(-1, p, p)
        self.system = system
        self.basis_note = ""
        if basis is None:
            transform = None
        elif isinstance(basis, str):
            if basis != "auto":
                raise InputError(f'basis must be None, "auto" or a (p, p) matrix, got {basis!r}')
            transform, self.basis_note = _choose_basis(matrices, system.D, system.w)
        else:
            transform = as_finite_array("basis", basis, (p, p))
            condition = np.linalg.cond(transform)
            if not condition <= BASIS_MAX_CONDITION:
                raise InputError(
                    f"basis must be invertible with condition number <= {BASIS_MAX_CONDITION:g}, got {condition:.3g}"
                )
        self._transform = transform
        abs_matrices = np.max(np.abs(matrices), axis=0)
        if transform is None:
            self.basis = frozen_copy(np.eye(p))
            self._inverse = None
            B, D = system.B, system.D
            matrix_error, B_error, D_error = formation_error, np.zeros_like(B), np.zeros_like(D)
        else:
            self.basis = frozen_copy(transform)
            inverse = np.linalg.inv(transform)
            self._inverse = inverse
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
            self._leave_error = summation_error_bound(2 * p + 1) * abs_t + inverse_error
            self._enter_error = summation_error_bound(2 * p + 1) * abs_inv
            matrices = inverse @ matrices @ transform
            # Target: inverse @ A_exact(v) @ S. Error: rounding of the triple product, of
            # forming A(v), and of using T for S.
            matrix_error = (
                summation_error_bound(2 * p + 1) * abs_inv @ abs_matrices @ abs_t
                + abs_inv @ formation_error @ abs_t
                + abs_inv @ (abs_matrices + formation_error) @ inverse_error
            )
            B, D = inverse @ system.B, inverse @ system.D
            B_error, D_error = (
                summation_error_bound(p) * abs_inv @ np.abs(system.B),
                summation_error_bound(p) * abs_inv @ np.abs(system.D),
            )
            abs_matrices = np.max(np.abs(matrices), axis=0)
        self.vertex_matrices = frozen_copy(matrices)
        #: Elementwise bound on ``|vertex_matrices[v] - (the exact matrix they round)|``, one for all v
        #: (forming A(v), and the basis change when there is one).
        self.vertex_matrix_error = frozen_copy(matrix_error)
        k = matrices.shape[0]
        stacked = matrices.reshape(k * p, p)
        positive, negative = np.maximum(stacked, 0.0), np.maximum(-stacked, 0.0)
        # [z_lo, z_hi] @ _product -> [all lower candidates | all upper candidates], shape (..., 2 k p).
        self._product = np.ascontiguousarray(np.block([[positive.T, -negative.T], [-negative.T, positive.T]]))
        self._nvertices, self._p = k, p
        self._B_T = np.ascontiguousarray(B.T)
        w_lo, w_hi = interval_matvec(D, system.w.low, system.w.high)
        w_max = np.maximum(np.abs(system.w.low), np.abs(system.w.high))
        w_error = summation_error_bound(2 * system.ndisturbances + 1) * np.abs(D) @ w_max + D_error @ w_max
        self._w_lo, self._w_hi = w_lo, w_hi
        # Outward rounding: the step's error is at most  m @ G.T + |u| @ H.T + g  with
        # m = max(|z_lo|, |z_hi|); see the class Notes. The n-term sum counts the 2p
        # products, the q control terms, the constant, the margin and the final rounding.
        gamma_step = summation_error_bound(2 * p + system.ninputs + 5)
        safety = 1.0 + 1e-10  # covers the rounding in evaluating the bound itself
        self._error_state_T = np.ascontiguousarray(safety * (matrix_error + gamma_step * abs_matrices).T)
        self._error_input_T = np.ascontiguousarray(safety * (B_error + gamma_step * np.abs(B)).T)
        # Underflow: each of the terms may lose up to the smallest subnormal.
        underflow = (2 * p + system.ninputs + 5) * 2.0 * np.finfo(float).smallest_subnormal
        constant = safety * (w_error + gamma_step * np.maximum(np.abs(w_lo), np.abs(w_hi))) + underflow
        self._lower_shift, self._upper_shift = w_lo - constant, w_hi + constant

    @property
    def nvertices(self) -> int:
        """The number of distinct vertex matrices used per step."""
        return self._nvertices

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
            parameter polytope and w in ``system.w`` (eq. (7), one step).

        Notes
        -----
        No validation: this is a planner's hot loop. See the class Notes for the bound
        and the rounding.
        """
        k, p = self._nvertices, self._p
        candidates = np.concatenate([lower, upper], axis=-1) @ self._product
        if candidates.ndim == 1:
            new_lower = candidates[: k * p].reshape(k, p).min(axis=0)
            new_upper = candidates[k * p :].reshape(k, p).max(axis=0)
        else:  # numpy reduces a short middle axis slowly; fold the k slices pairwise instead
            new_lower, new_upper = candidates[..., :p], candidates[..., k * p : (k + 1) * p]
            for j in range(1, k):
                new_lower = np.minimum(new_lower, candidates[..., j * p : (j + 1) * p])
                new_upper = np.maximum(new_upper, candidates[..., (k + j) * p : (k + j + 1) * p])
        drift = u @ self._B_T
        error = np.maximum(np.abs(lower), np.abs(upper)) @ self._error_state_T + np.abs(u) @ self._error_input_T
        return new_lower + (drift - error) + self._lower_shift, new_upper + (drift + error) + self._upper_shift


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


def predict_tube(system: UncertainLinearSystem, x0: Box, controls, parameters=None, *, basis=None) -> Tube:
    """Predict a tube that contains every trajectory of an uncertain system.

    Parameters
    ----------
    system
        The discrete-time `UncertainLinearSystem` ``x+ = A(theta) x + B u + D w``.
    x0
        `Box` of initial states, dimension p.
    controls
        Array of shape (H, q): the known control sequence.
    parameters
        A `ParameterSet` (`Box`, `Ellipsoid`, `VertexPolytope`) or a vertex array (k, d);
        default ``system.theta``.
    basis
        None, ``"auto"`` or an invertible (p, p) matrix, see `IntervalPredictor`.

    Returns
    -------
    Tube
        ``lower``, ``upper`` of shape (H+1, p).

    Notes
    -----
    Guarantee (the inclusion property, eq. (7)), for every dt and every system, Metzler
    or not: for all theta in ``parameters``, all x0 in the box and all ``w_n`` in
    ``system.w``, ``lower[n] <= x_n <= upper[n]``; the bounds are rounded outward, so
    this holds for the exact x_n (see `IntervalPredictor` for the one-step bound and
    the rounding).
    ``parameters`` is used as given, not intersected with ``system.theta``.

    Raises `NonFiniteError` if the bounds overflow the float range.
    """
    check_instance("system", system, UncertainLinearSystem)
    check_instance("x0", x0, Box)
    check_dimension("x0", x0.dim, system.nstates, f"A0 has shape {system.A0.shape}")
    u = as_finite_array("controls", controls, ndim=2)
    check_shape("controls", u, (None, system.ninputs))
    predictor = IntervalPredictor(system, parameters, basis=basis)
    lower = np.empty((u.shape[0] + 1, system.nstates))
    upper = np.empty_like(lower)
    lower[0], upper[0] = x0.low, x0.high
    z_lo, z_hi = predictor.enter(x0.low, x0.high)
    with np.errstate(over="ignore", invalid="ignore"):
        for n in range(u.shape[0]):
            z_lo, z_hi = predictor.step(z_lo, z_hi, u[n])
            lower[n + 1], upper[n + 1] = predictor.leave(z_lo, z_hi)
    _check_no_overflow(lower, upper)
    return Tube(lower, upper, guaranteed=True, note=predictor.basis_note)
