"""The regression of one hypothesis on observed transitions (internal to `minimaxplan.verify`).

Input checks shared by the selection API and the certificates, the bound on bounded
measurement noise, and the per-hypothesis data ``z_n = E_n theta + D w_n + e_n`` that
the LPs of `minimaxplan.verify.selection` are built from.
"""

from __future__ import annotations

from itertools import combinations
from math import comb

import numpy as np

from minimaxplan.models import UncertainLinearSystem
from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.models.validation import as_finite_array, check_instance, check_shape

__all__ = [
    "check_hypotheses",
    "check_trajectory",
    "noise_vector",
    "measurement_noise_bound",
    "disturbance_set_is_box",
    "Structure",
    "HypothesisData",
    "EPS",
]

#: The unit roundoff of float64.
EPS = float(np.finfo(float).eps)
#: Radii below this count as 0 (their reciprocal would overflow).
NEGLIGIBLE_RADIUS = 1e-150
#: When ``D W`` is not a box, the per-transition margin is computed exactly from the
#: facet normals of the zonotope ``D W + box`` if there are at most this many
#: candidate normals (``C(g, p - 1)`` for g generators); otherwise it is bounded above
#: with the disturbance ``clip(pinv(D) r, W)``.
MAX_FACET_NORMALS = 4096


def check_hypotheses(hypotheses) -> list[UncertainLinearSystem]:
    """A non-empty list of `UncertainLinearSystem` with equal state and input sizes."""
    if isinstance(hypotheses, UncertainLinearSystem):
        raise InputError("hypotheses must be a sequence of UncertainLinearSystem, got a single system")
    try:
        hyps = list(hypotheses)
    except TypeError:
        raise InputError(
            f"hypotheses must be a sequence of UncertainLinearSystem, got {type(hypotheses).__name__}"
        ) from None
    if not hyps:
        raise InputError("hypotheses must contain at least one UncertainLinearSystem, got an empty sequence")
    for m, h in enumerate(hyps):
        check_instance(f"hypotheses[{m}]", h, UncertainLinearSystem)
    p, q = hyps[0].nstates, hyps[0].ninputs
    for m, h in enumerate(hyps[1:], start=1):
        if (h.nstates, h.ninputs) != (p, q):
            raise DimensionError(
                f"hypotheses[{m}] has (nstates, ninputs) = ({h.nstates}, {h.ninputs}), "
                f"but hypotheses[0] has ({p}, {q}): all hypotheses must share state and input dimensions"
            )
    return hyps


def check_trajectory(states, controls, p: int, q: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N+1, p) states and (N, q) controls -> the N transitions (x_n, u_n, x_{n+1})."""
    x = as_finite_array("states", states, ndim=2)
    if x.shape[0] < 1:
        raise DimensionError(f"states must have shape (N+1, {p}) with N+1 >= 1, got shape {x.shape}")
    check_shape("states", x, (None, p))
    n = x.shape[0] - 1
    u = as_finite_array("controls", controls)
    if u.size == 0 and n == 0:
        u = u.reshape(0, q)
    if u.ndim != 2 or u.shape != (n, q):
        raise DimensionError(
            f"controls must have shape (N, q) = ({n}, {q}) for states of shape {x.shape}, got shape {u.shape}"
        )
    return x[:-1], u, x[1:]


def noise_vector(measurement_noise, p: int) -> np.ndarray:
    """The measurement-noise bound as shape (p,), >= 0 (None means 0)."""
    if measurement_noise is None:
        return np.zeros(p)
    v = as_finite_array("measurement_noise", measurement_noise)
    if v.ndim == 0:
        v = np.full(p, float(v))
    check_shape("measurement_noise", v, (p,))
    if np.any(v < 0):
        raise InputError(f"measurement_noise must be >= 0 in every coordinate, got {v.tolist()}")
    return v


def measurement_noise_bound(hypothesis: UncertainLinearSystem, measurement_noise) -> np.ndarray:
    """The bound ``v_bar + max_theta |A(theta)| v_bar`` on ``v_{n+1} - A(theta) v_n``.

    Parameters
    ----------
    hypothesis
        The system whose prior box ``theta`` is maximised over.
    measurement_noise
        ``v_bar``: a scalar or shape (p,), >= 0; ``None`` means 0.

    Returns
    -------
    numpy.ndarray
        Shape (p,), rounded upwards.

    Notes
    -----
    With measured states ``x~_n = x_n + v_n``, ``|v_n| <= v_bar``, the plant gives
    ``x~_{n+1} = A0 x~_n + E(x~_n) theta + B u_n + D w_n + (v_{n+1} - A(theta) v_n)``:
    the same regression with one more bounded term (DESIGN errata). Each entry of
    ``A(theta)`` is affine in theta, so its largest modulus over the prior box is
    attained at an end of its range; this interval bound is exact entrywise.
    """
    v = noise_vector(measurement_noise, hypothesis.nstates)
    if not np.any(v):
        return v
    lo, hi = hypothesis.theta.low, hypothesis.theta.high
    phi = hypothesis.phi
    a_low = hypothesis.A0 + np.tensordot(lo, np.maximum(phi, 0), 1) + np.tensordot(hi, np.minimum(phi, 0), 1)
    a_high = hypothesis.A0 + np.tensordot(hi, np.maximum(phi, 0), 1) + np.tensordot(lo, np.minimum(phi, 0), 1)
    # Entrywise rounding of those sums is at most (d + 2) eps times the sum of moduli.
    theta_max = np.maximum(np.abs(lo), np.abs(hi))
    rounding = (phi.shape[0] + 3) * EPS * (np.abs(hypothesis.A0) + np.tensordot(theta_max, np.abs(phi), 1))
    a_abs = np.maximum(np.abs(a_low), np.abs(a_high)) + rounding
    return (v + a_abs @ v) * (1 + 4 * (v.size + 2) * EPS)


def zonotope_normals(D: np.ndarray, radius: np.ndarray) -> np.ndarray | None:
    """Unit normals of every facet the zonotope ``D W + box`` can have, or None if too many.

    Parameters
    ----------
    D : numpy.ndarray
        Shape (p, r), the disturbance matrix.
    radius : numpy.ndarray
        Shape (r,), the radii of W (columns with radius 0 are no generators).

    Returns
    -------
    numpy.ndarray or None
        Shape (m, p): one normal per (p - 1)-subset of the generators (the columns of D
        with a positive radius and the p coordinate axes) that spans a hyperplane; None
        if there are more than `MAX_FACET_NORMALS` subsets.

    Notes
    -----
    A zonotope ``c + sum_j [-1, 1] g_j`` whose generators span R^p is the set of the
    points y with ``|nu . (y - c)| <= sum_j |nu . g_j|`` for the normals nu of the
    hyperplanes spanned by p - 1 generators, whatever the (positive) lengths of the
    generators; with the p axes among the generators the zonotope is full-dimensional.
    """
    p = D.shape[0]
    columns = D[:, radius > NEGLIGIBLE_RADIUS]
    columns = columns[:, np.any(columns != 0, axis=0)]
    generators = np.hstack([columns / np.linalg.norm(columns, axis=0), np.eye(p)])
    if p == 1:
        return np.ones((1, 1))
    if comb(generators.shape[1], p - 1) > MAX_FACET_NORMALS:
        return None
    normals = []
    for subset in combinations(range(generators.shape[1]), p - 1):
        u, sv, _ = np.linalg.svd(generators[:, subset], full_matrices=True)
        if sv[-1] > 1e-9 * sv[0]:
            normals.append(u[:, -1])
    nu = np.array(normals)
    first = np.argmax(np.abs(nu) > 1e-12, axis=1)
    nu *= np.where(nu[np.arange(len(nu)), first] < 0, -1.0, 1.0)[:, None]  # one sign per hyperplane
    _, keep = np.unique(np.round(nu, 12), axis=0, return_index=True)
    return nu[np.sort(keep)]


def disturbance_set_is_box(D: np.ndarray, radius: np.ndarray) -> bool:
    """True iff ``D W`` is itself a box: every column with a nonzero radius has <= 1 nonzero."""
    return bool(np.all(np.count_nonzero(D[:, radius > 0], axis=0) <= 1))


# --------------------------------------------------------------- one hypothesis, data
class Structure:
    """Everything about one hypothesis that does not depend on the data (computed once).

    Parameters
    ----------
    hyp : UncertainLinearSystem
        The hypothesis.
    noise_bound : numpy.ndarray
        Shape (p,): the bound on the measurement-noise term of each row (see
        `measurement_noise_bound`), in state units.
    allowance : float
        Relative rounding allowance per row (dimensionless).

    Notes
    -----
    The inflation unit of state coordinate i is the radius ``unit_i`` of the interval
    hull of ``D W + [-ebar, ebar]`` (state units). Where that radius is 0 (no
    disturbance nor noise reaches the coordinate) the unit is taken per row, as the
    row's natural magnitude (see `HypothesisData`): both scale like the coordinate, so
    the margin does not depend on the units of the states and inputs.
    """

    def __init__(self, hyp: UncertainLinearSystem, noise_bound: np.ndarray, allowance: float) -> None:
        self.hyp = hyp
        self.noise_bound = noise_bound
        self.allowance = allowance
        self.theta_low, self.theta_high = hyp.theta.low, hyp.theta.high
        # (the constructor of UncertainLinearSystem replaces D = None by the identity)
        self.D: np.ndarray = hyp.D if hyp.D is not None else np.eye(hyp.nstates)
        self.w_center, self.w_radius = hyp.w.center, hyp.w.radius
        self.A0_T, self.B_T, self.phi = hyp.A0.T, hyp.B.T, hyp.phi
        theta_max = np.maximum(np.abs(self.theta_low), np.abs(self.theta_high))
        w_max = np.maximum(np.abs(hyp.w.low), np.abs(hyp.w.high))
        self.theta_scale = np.where(theta_max > 0, theta_max, 1.0)
        self.w_scale = np.where(w_max > 0, w_max, 1.0)
        self.abs_A0_T = np.abs(hyp.A0).T
        self.abs_B_T = np.abs(hyp.B).T
        self.abs_regression_T = np.tensordot(theta_max, np.abs(hyp.phi), 1).T
        self.constant_magnitude = np.abs(self.D) @ w_max + noise_bound
        self.hull_center = self.D @ self.w_center
        self.hull_radius = np.abs(self.D) @ self.w_radius
        self.unit = self.hull_radius + noise_bound
        self.has_unit = self.unit > NEGLIGIBLE_RADIUS
        self.is_box = disturbance_set_is_box(self.D, self.w_radius)
        self.d_pinv = None if self.is_box else np.linalg.pinv(self.D)
        # The zonotope test runs in coordinates divided by ``unit`` (1 where that is 0),
        # which scale like the states: no cancellation between coordinates of very
        # different units. The normals are then applied to ``(r - D c_w) / unit``.
        self.coordinate_scale = np.where(self.has_unit, self.unit, 1.0)
        scaled_D = self.D / self.coordinate_scale[:, None]
        self.normals = None if self.is_box else zonotope_normals(scaled_D, self.w_radius)
        if self.normals is not None:
            self.normals_T = (self.normals / self.coordinate_scale).T  # acts on unscaled vectors
            self.abs_normals_T = np.abs(self.normals_T)
            self.normal_support = np.abs(self.normals @ scaled_D) @ self.w_radius


class HypothesisData:
    """The regression ``z_n = E_n theta + D w_n + e_n`` of one hypothesis on transitions.

    Parameters
    ----------
    structure : Structure
        The hypothesis' data-independent part.
    X, U, Xn : numpy.ndarray
        States (N, p), controls (N, q) and next states (N, p) of N transitions.

    Notes
    -----
    ``z_n = x_{n+1} - A0 x_n - B u_n``, ``E_n = regressor(x_n)``, ``|e_n| <= ebar + a_n``
    (measurement noise, rounding allowance), ``w_n`` in the box ``W = c_w +- r_w``.
    ``magnitude`` (N, p) is the natural magnitude of each row, the sum of the moduli of
    its terms ``|x_{n+1}| + |A0| |x_n| + |B| |u_n| + |E_n| theta_max + |D| w_max + ebar``:
    the rounding allowance is relative to it, the LPs divide each row by it (``scale``),
    and ``beta`` (N, p), the inflation unit of each row, is the structure's ``unit``
    where it is positive and the magnitude elsewhere (1 for an identically zero row).
    All three scale like the state coordinate of the row, so the margins, the
    verdicts and the LPs solved do not depend on the units of x and u.
    """

    def __init__(self, structure: Structure, X, U, Xn) -> None:
        st = structure
        self.hyp = st.hyp
        self.theta_low, self.theta_high = st.theta_low, st.theta_high
        self.D, self.w_center, self.w_radius = st.D, st.w_center, st.w_radius
        self.hull_center, self.hull_radius = st.hull_center, st.hull_radius
        self.theta_scale, self.w_scale = st.theta_scale, st.w_scale
        self.is_box, self.d_pinv = st.is_box, st.d_pinv
        self._structure = st
        self._facets: tuple[np.ndarray, np.ndarray] | None = None
        self.z = Xn - X @ st.A0_T - U @ st.B_T
        self.E = np.einsum("ipq,nq->npi", st.phi, X)
        abs_x = np.abs(X)
        magnitude = (
            np.abs(Xn)
            + abs_x @ st.abs_A0_T
            + np.abs(U) @ st.abs_B_T
            + abs_x @ st.abs_regression_T
            + st.constant_magnitude
        )
        self.e = st.noise_bound + st.allowance * magnitude
        self.magnitude = magnitude
        self.beta = np.where(st.has_unit, st.unit, np.where(magnitude > 0, magnitude, 1.0))
        self.scale = np.where(magnitude > 0, np.maximum(magnitude, self.beta), self.beta)

    @property
    def ntransitions(self) -> int:
        """The number N of transitions."""
        return self.z.shape[0]

    @property
    def nparams(self) -> int:
        """The number d of parameters."""
        return self.E.shape[2]

    @property
    def exact_margins(self) -> bool:
        """True iff `needed_margin` is exact (``D W`` a box, or few zonotope facets)."""
        return self.d_pinv is None or self._structure.normals is not None

    @property
    def nstates(self) -> int:
        """The state dimension p."""
        return self.z.shape[1]

    def needed_margin(self, theta: np.ndarray, idx: slice | np.ndarray = slice(None)) -> np.ndarray:
        """Per transition, a margin s that suffices to explain it with this theta.

        Parameters
        ----------
        theta : numpy.ndarray
            Shape (d,), a parameter.
        idx : slice or numpy.ndarray
            The transitions to evaluate (all by default).

        Returns
        -------
        numpy.ndarray
            Shape (k,), dimensionless (excess over ``e`` in units of ``beta``; <= 0
            means explained without inflation). Exact (the least such s) when ``D W``
            is a box, or when the zonotope ``D W + box(e + s beta)`` has at most
            `MAX_FACET_NORMALS` candidate facets (see `zonotope_normals`: the least s is
            the largest over the facet normals nu of ``(|nu . (r - D c_w)| - |nu D| r_w
            - |nu| . e) / (|nu| . beta)``); otherwise an upper bound, from the
            disturbance ``clip(pinv(D) residual, W)``.
        """
        n, p, d = self.E.shape
        fitted = (self.E.reshape(n * p, d) @ theta).reshape(n, p)
        residual = self.z[idx] - fitted[idx]
        st = self._structure
        if self.d_pinv is None:
            excess = np.abs(residual - self.hull_center) - self.hull_radius - self.e[idx]
        elif st.normals is not None:
            if self._facets is None:  # per row and facet: |nu| . e and |nu| . beta, once
                slack = np.einsum("np,pm->nm", self.e, st.abs_normals_T) + st.normal_support
                self._facets = (slack, np.einsum("np,pm->nm", self.beta, st.abs_normals_T))
            facet_slack, facet_unit = self._facets
            along = np.abs(np.einsum("np,pm->nm", residual - self.hull_center, st.normals_T))
            return np.max((along - facet_slack[idx]) / facet_unit[idx], axis=1)
        else:
            w = np.clip(residual @ self.d_pinv.T, self.w_center - self.w_radius, self.w_center + self.w_radius)
            excess = np.abs(residual - w @ self.D.T) - self.e[idx]
        return np.max(excess / self.beta[idx], axis=1)

    def needed_margin_with(self, theta: np.ndarray, w: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """Per transition, the least s that explains it with this theta and disturbances.

        Parameters
        ----------
        theta : numpy.ndarray
            Shape (d,), a parameter.
        w : numpy.ndarray
            Shape (k, r), disturbances of the transitions ``idx`` (clipped to W).
        idx : numpy.ndarray
            Shape (k,), transition indices.

        Returns
        -------
        numpy.ndarray
            Shape (k,), dimensionless margins.
        """
        w = np.clip(w, self.w_center - self.w_radius, self.w_center + self.w_radius)
        excess = np.abs(self.z[idx] - self.E[idx] @ theta - w @ self.D.T) - self.e[idx]
        return np.max(excess / self.beta[idx], axis=1)
