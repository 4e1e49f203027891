"""Model elimination: discard the structural hypotheses that observed transitions contradict.

A hypothesis is an `UncertainLinearSystem` ``x+ = A0 x + E(x) theta + B u + D w``
with ``theta`` in its prior box and ``w`` in its disturbance box. It is *consistent*
with transitions ``(x_n, u_n, x_{n+1})`` iff one ``theta`` and disturbances ``w_n``
explain all of them: a linear-programming feasibility problem (the paper's LP test
of Section III, ref. [48]), solved here with HiGHS through `scipy.optimize.linprog`.

How the decision is made (see `eliminate_models`, Notes):

* the *inconsistency margin* ``s >= 0`` is the smallest inflation of the disturbance
  set that explains the data (an LP: minimise s); ``s = 0`` means consistent;
* a hypothesis is eliminated only if a Lagrangian (weak-duality) lower bound on
  ``s``, recomputed with numpy from HiGHS's dual multipliers and independent of the
  solver's tolerances, exceeds `ELIMINATION_MARGIN`. That bound, its multipliers and
  the transitions they involve form an `EliminationCertificate` anyone can re-check;
* the LPs are solved by constraint generation: few of the ``2 p N`` rows are active,
  so a small LP is solved, every row is checked vectorised in numpy, the most violated
  rows are added, and so on; the last round (after ``max_rounds``) takes every row,
  so the margin is the one of the full LP either way.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog

from minimaxplan.models import Box, UncertainLinearSystem
from minimaxplan.models.validation import as_finite_array, as_positive_scalar, check_shape, frozen_copy
from minimaxplan.models.errors import DimensionError, InputError, NoConsistentModel, SolverFailure

__all__ = [
    "ELIMINATION_MARGIN",
    "ROUNDING_ALLOWANCE",
    "GENERATION_TOLERANCE",
    "MAX_GENERATION_ROUNDS",
    "PARAMETER_BOX_ALLOWANCE",
    "EliminationCertificate",
    "SelectionResult",
    "ModelSelector",
    "eliminate_models",
    "feasible_parameter_box",
    "measurement_noise_bound",
]

#: A hypothesis is eliminated only if the certified lower bound on its inconsistency
#: margin exceeds this (the margin is in units of the disturbance set's radius).
ELIMINATION_MARGIN = 1e-7
#: Relative size of the per-transition allowance for floating-point rounding in the
#: data and in the residuals (errs towards keeping hypotheses).
ROUNDING_ALLOWANCE = 1e-9
#: A row counts as violated in constraint generation if it needs a margin larger than
#: the current one by more than this.
GENERATION_TOLERANCE = 1e-9
#: Constraint-generation rounds before the last round, which takes every row.
MAX_GENERATION_ROUNDS = 30
#: `feasible_parameter_box` bounds the parameters consistent with every row relaxed by
#: this much relative to the row's magnitude (a superset, so sound): a consistent set
#: that is nearly a point (w at its extremes) is otherwise thinner than HiGHS's
#: tolerances, and its presolve may declare it empty.
PARAMETER_BOX_ALLOWANCE = 1e-7

_HIGHS_OPTIONS = {"primal_feasibility_tolerance": 1e-9, "dual_feasibility_tolerance": 1e-9}
_LINPROG_STATUS = {
    1: "iteration limit reached",
    2: "infeasible",
    3: "unbounded",
    4: "numerical difficulties",
}
_EPS = np.finfo(float).eps
# Radii below this count as 0 (their reciprocal would overflow), and beta spans at most
# six orders of magnitude, so that HiGHS (which drops coefficients below 1e-9) keeps
# every coefficient of the margin column.
_NEGLIGIBLE_RADIUS = 1e-150
_BETA_SPREAD = 1e-6


# ----------------------------------------------------------------------------- inputs
def _check_hypotheses(hypotheses) -> list[UncertainLinearSystem]:
    if isinstance(hypotheses, UncertainLinearSystem):
        raise InputError("hypotheses must be a sequence of UncertainLinearSystem, got a single system")
    try:
        hyps = list(hypotheses)
    except TypeError:
        raise InputError(f"hypotheses must be a sequence of UncertainLinearSystem, got {type(hypotheses).__name__}") from None
    if not hyps:
        raise InputError("hypotheses must contain at least one UncertainLinearSystem, got an empty sequence")
    for m, h in enumerate(hyps):
        if not isinstance(h, UncertainLinearSystem):
            raise InputError(f"hypotheses[{m}] must be an UncertainLinearSystem, got {type(h).__name__}")
    p, q = hyps[0].nstates, hyps[0].ninputs
    for m, h in enumerate(hyps[1:], start=1):
        if (h.nstates, h.ninputs) != (p, q):
            raise DimensionError(
                f"hypotheses[{m}] has (nstates, ninputs) = ({h.nstates}, {h.ninputs}), "
                f"but hypotheses[0] has ({p}, {q}): all hypotheses must share state and input dimensions"
            )
    return hyps


def _check_trajectory(states, controls, p: int, q: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


def _noise_vector(measurement_noise, p: int) -> np.ndarray:
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
    v = _noise_vector(measurement_noise, hypothesis.nstates)
    if not np.any(v):
        return v
    lo, hi = hypothesis.theta.low, hypothesis.theta.high
    phi = hypothesis.phi
    a_low = hypothesis.A0 + np.tensordot(lo, np.maximum(phi, 0), 1) + np.tensordot(hi, np.minimum(phi, 0), 1)
    a_high = hypothesis.A0 + np.tensordot(hi, np.maximum(phi, 0), 1) + np.tensordot(lo, np.minimum(phi, 0), 1)
    # Entrywise rounding of those sums is at most (d + 2) eps times the sum of moduli.
    theta_max = np.maximum(np.abs(lo), np.abs(hi))
    rounding = (phi.shape[0] + 3) * _EPS * (np.abs(hypothesis.A0) + np.tensordot(theta_max, np.abs(phi), 1))
    a_abs = np.maximum(np.abs(a_low), np.abs(a_high)) + rounding
    return (v + a_abs @ v) * (1 + 4 * (v.size + 2) * _EPS)


def _disturbance_set_is_box(D: np.ndarray, radius: np.ndarray) -> bool:
    """True iff ``D W`` is itself a box: every column with a nonzero radius has <= 1 nonzero."""
    return bool(np.all(np.count_nonzero(D[:, radius > 0], axis=0) <= 1))


# --------------------------------------------------------------- one hypothesis, data
class _Structure:
    """Everything about one hypothesis that does not depend on the data (computed once).

    The inflation unit ``beta`` (per state coordinate) is the radius of the interval
    hull of ``D W + [-ebar, ebar]``, or 1 where that radius is 0, raised to at least
    `_BETA_SPREAD` times its largest entry.
    """

    def __init__(self, hyp: UncertainLinearSystem, noise_bound: np.ndarray, allowance: float) -> None:
        self.hyp = hyp
        self.noise_bound = noise_bound
        self.allowance = allowance
        self.theta_low, self.theta_high = hyp.theta.low, hyp.theta.high
        self.D = hyp.D
        self.w_center, self.w_radius = hyp.w.center, hyp.w.radius
        self.A0_T, self.B_T, self.phi = hyp.A0.T, hyp.B.T, hyp.phi
        theta_max = np.maximum(np.abs(self.theta_low), np.abs(self.theta_high))
        w_max = np.maximum(np.abs(hyp.w.low), np.abs(hyp.w.high))
        self.abs_A0_T = np.abs(hyp.A0).T
        self.abs_B_T = np.abs(hyp.B).T
        self.abs_regression_T = np.tensordot(theta_max, np.abs(hyp.phi), 1).T
        self.constant_magnitude = np.abs(hyp.D) @ w_max + noise_bound
        self.hull_center = self.D @ self.w_center
        self.hull_radius = np.abs(self.D) @ self.w_radius
        unit = self.hull_radius + noise_bound
        beta = np.where(unit > _NEGLIGIBLE_RADIUS, unit, 1.0)
        self.beta = np.maximum(beta, _BETA_SPREAD * np.max(beta))
        self.is_box = _disturbance_set_is_box(self.D, self.w_radius)
        self.d_pinv = None if self.is_box else np.linalg.pinv(self.D)


class _HypothesisData:
    """The regression ``z_n = E_n theta + D w_n + e_n`` of one hypothesis on transitions.

    ``z_n = x_{n+1} - A0 x_n - B u_n``, ``E_n = regressor(x_n)``, ``|e_n| <= ebar + a_n``
    (measurement noise, rounding allowance), ``w_n`` in the box ``W = c_w +- r_w``.
    """

    def __init__(self, structure: _Structure, X, U, Xn) -> None:
        st = structure
        self.hyp = st.hyp
        self.theta_low, self.theta_high = st.theta_low, st.theta_high
        self.D, self.w_center, self.w_radius = st.D, st.w_center, st.w_radius
        self.hull_center, self.hull_radius, self.beta = st.hull_center, st.hull_radius, st.beta
        self.is_box, self.d_pinv = st.is_box, st.d_pinv
        self.z = Xn - X @ st.A0_T - U @ st.B_T
        self.E = np.einsum("ipq,nq->npi", st.phi, X)
        abs_x = np.abs(X)
        magnitude = (
            np.abs(Xn) + abs_x @ st.abs_A0_T + np.abs(U) @ st.abs_B_T + abs_x @ st.abs_regression_T
            + st.constant_magnitude
        )
        self.e = st.noise_bound + st.allowance * magnitude

    @property
    def ntransitions(self) -> int:
        return self.z.shape[0]

    @property
    def nparams(self) -> int:
        return self.E.shape[2]

    @property
    def nstates(self) -> int:
        return self.z.shape[1]

    def needed_margin(self, theta: np.ndarray, idx=slice(None)) -> np.ndarray:
        """Per transition, a margin s that suffices to explain it with this theta.

        Exact (the least such s) when ``D W`` is a box; otherwise an upper bound, from
        the disturbance ``clip(pinv(D) residual, W)``.
        """
        n, p, d = self.E.shape
        fitted = (self.E.reshape(n * p, d) @ theta).reshape(n, p)
        residual = self.z[idx] - fitted[idx]
        if self.is_box:
            excess = np.abs(residual - self.hull_center) - self.hull_radius - self.e[idx]
        else:
            w = np.clip(residual @ self.d_pinv.T, self.w_center - self.w_radius, self.w_center + self.w_radius)
            excess = np.abs(residual - w @ self.D.T) - self.e[idx]
        return np.max(excess / self.beta, axis=1)

    def needed_margin_with(self, theta: np.ndarray, w: np.ndarray, idx) -> np.ndarray:
        """Per transition, the least s that explains it with this theta and disturbances w (k, r)."""
        w = np.clip(w, self.w_center - self.w_radius, self.w_center + self.w_radius)
        excess = np.abs(self.z[idx] - self.E[idx] @ theta - w @ self.D.T) - self.e[idx]
        return np.max(excess / self.beta, axis=1)


# ----------------------------------------------------------------------- LP pieces
@dataclass
class _LPSolution:
    theta: np.ndarray
    s: float
    w: np.ndarray | None  # (k, r) disturbances of the rows' transitions (general form only)
    y_upper: np.ndarray  # (k, p) multipliers of the rows  z - E theta - D w >= -(e + s beta)
    y_lower: np.ndarray  # (k, p) multipliers of the rows  z - E theta - D w <=  (e + s beta)


def _solve_lp(data: _HypothesisData, idx: np.ndarray, objective: np.ndarray, s_fixed: float | None) -> _LPSolution:
    """Solve the LP over the rows of transitions ``idx`` with HiGHS.

    Variables: theta (d), then s (unless ``s_fixed``), then w_n (r each) unless ``D W``
    is a box, in which case w is eliminated exactly: ``D w_n`` ranges over
    ``hull_center +- hull_radius``. Objective: ``objective . theta`` (+ s when s is free).
    """
    k, p, d = len(idx), data.nstates, data.nparams
    E = data.E[idx].reshape(k * p, d)
    z, e = data.z[idx].reshape(-1), data.e[idx].reshape(-1)
    beta = np.tile(data.beta, k)
    free_s = s_fixed is None
    slack = e if free_s else e + s_fixed * beta
    columns_up = [sp.csr_matrix(E)]
    columns_lo = [sp.csr_matrix(-E)]
    cost = [objective]
    bounds = [np.column_stack([data.theta_low, data.theta_high])]
    # the margin variable is s * sigma, so that its column's largest entry is 1
    sigma = float(np.max(data.beta))
    if free_s:
        columns_up.append(sp.csr_matrix(-beta[:, None] / sigma))
        columns_lo.append(sp.csr_matrix(-beta[:, None] / sigma))
        cost.append([1.0])
        bounds.append(np.array([[0.0, np.inf]]))
    if data.is_box:
        center = np.tile(data.hull_center, k)
        radius = np.tile(data.hull_radius, k)
        b_up = z - center + radius + slack
        b_lo = center + radius + slack - z
    else:
        r = data.D.shape[1]
        block = sp.kron(sp.identity(k, format="csr"), sp.csr_matrix(data.D), format="csr")
        columns_up.append(block)
        columns_lo.append(-block)
        cost.append(np.zeros(k * r))
        w_low, w_high = data.w_center - data.w_radius, data.w_center + data.w_radius
        bounds.append(np.column_stack([np.tile(w_low, k), np.tile(w_high, k)]))
        b_up = z + slack
        b_lo = slack - z
    A_ub = sp.vstack([sp.hstack(columns_up), sp.hstack(columns_lo)], format="csr")
    b_ub = np.concatenate([b_up, b_lo])
    res = linprog(np.concatenate(cost), A_ub=A_ub, b_ub=b_ub, bounds=np.vstack(bounds), method="highs", options=_HIGHS_OPTIONS)
    if res.status != 0:
        what = "margin LP" if free_s else "parameter-bound LP"
        reason = _LINPROG_STATUS.get(res.status, f"unknown status {res.status}")
        raise SolverFailure(
            f"HiGHS failed on the {what} over {k} transitions: status {res.status} ({reason}): {res.message}"
            + (" -- this LP is always feasible in exact arithmetic, so this is a numerical failure"
               if res.status == 2 else "")
        )
    x = np.asarray(res.x, dtype=float)
    y = np.maximum(-np.asarray(res.ineqlin.marginals, dtype=float), 0.0)
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise SolverFailure(f"HiGHS returned non-finite values on the LP over {k} transitions")
    theta = x[:d]
    if free_s:
        y = y / sigma  # multipliers of min s (= min (s sigma) / sigma)
    s = float(x[d]) / sigma if free_s else float(s_fixed)
    offset = d + (1 if free_s else 0)
    w = None if data.is_box else x[offset:].reshape(k, -1)
    return _LPSolution(theta, s, w, y[: k * p].reshape(k, p), y[k * p :].reshape(k, p))


def _lagrangian_bound(
    data: _HypothesisData,
    idx: np.ndarray,
    y_upper: np.ndarray,
    y_lower: np.ndarray,
    objective: np.ndarray,
    s_fixed: float | None,
) -> float:
    """A lower bound on the LP's optimum over *all* transitions, from multipliers on ``idx``.

    Weak duality: for any multipliers y >= 0 of the rows
    ``-(e_n + s beta) <= z_n - E_n theta - D w_n <= e_n + s beta``,
    ``min_{theta in prior, w_n in W, s >= 0} [objective.theta + s + sum y (row violation)]``
    is <= the optimum. Rows of other transitions carry multiplier 0, so the bound holds
    for the full LP. The minimisation is over boxes, hence in closed form. When s is
    free, y is scaled so that ``sum (y+ + y-) . beta <= 1`` (then the s term is >= 0 and
    its minimum over s >= 0 is 0). The result is lowered by a bound on its own rounding.
    """
    mu = y_upper - y_lower
    nu = y_upper + y_lower
    if s_fixed is None:
        total = float(np.sum(nu @ data.beta))
        if total > 1.0 - 1e-12:  # keep the s coefficient 1 - total > 0 despite rounding in total
            scale = (1.0 - 1e-12) / total
            mu, nu = mu * scale, nu * scale
        slack = data.e[idx]
    else:
        slack = data.e[idx] + s_fixed * data.beta
    dmu = mu @ data.D  # (k, r): D^T mu_n
    g = objective + np.einsum("npi,np->i", data.E[idx], mu)
    theta_term = np.minimum(g * data.theta_low, g * data.theta_high)
    terms = (
        -np.sum(mu * data.z[idx]),
        -np.sum(nu * slack),
        np.sum(dmu @ data.w_center),
        -np.sum(np.abs(dmu) @ data.w_radius),
        np.sum(theta_term),
    )
    magnitude = (
        np.sum(np.abs(mu * data.z[idx]))
        + np.sum(nu * slack)
        + np.sum(np.abs(dmu) @ (np.abs(data.w_center) + data.w_radius))
        + np.sum(np.abs(theta_term))
        + np.sum(np.abs(np.einsum("npi,np->i", np.abs(data.E[idx]), np.abs(mu))) * np.maximum(np.abs(data.theta_low), np.abs(data.theta_high)))
    )
    return float(sum(terms)) - 4 * (mu.size + data.nparams + 10) * _EPS * float(magnitude)


@dataclass
class _Generated:
    solution: _LPSolution
    active: np.ndarray
    rounds: int
    upper: float  # a certified upper bound on the LP optimum (margin problems) / 0
    lower: float  # the Lagrangian lower bound


def _generate(
    data: _HypothesisData,
    objective: np.ndarray,
    s_fixed: float | None,
    initial: np.ndarray,
    *,
    max_rounds: int,
) -> _Generated:
    """Constraint generation: solve on a subset, add the most violated transitions, repeat.

    The number added per round doubles, so that even when many transitions are
    undecided (general D, see `_HypothesisData.needed_margin`) the rounds stay few.
    """
    n, d = data.ntransitions, data.nparams
    batch = max(8, 4 * (d + 1))
    active = np.unique(np.asarray(initial, dtype=int))
    rounds = 0
    while True:
        last = rounds >= max_rounds or active.size == n
        if last:
            active = np.arange(n)
        sol = _solve_lp(data, active, objective, s_fixed)
        rounds += 1
        needed_all = data.needed_margin(sol.theta)
        needed = needed_all.copy()
        needed[active] = -np.inf
        violated = needed > sol.s + GENERATION_TOLERANCE
        if last or not np.any(violated):
            break
        candidates = np.flatnonzero(violated)
        worst = candidates[np.argsort(-needed[candidates], kind="stable")[:batch]]
        active = np.union1d(active, worst)
        batch *= 2
    if data.is_box:
        upper = float(np.max(needed_all, initial=0.0))
    else:
        on_active = data.needed_margin_with(sol.theta, sol.w, active)
        upper = float(max(np.max(on_active, initial=0.0), np.max(needed, initial=0.0)))
    lower = _lagrangian_bound(data, active, sol.y_upper, sol.y_lower, objective, s_fixed)
    return _Generated(sol, active, rounds, upper, lower)


def _initial_rows(data: _HypothesisData) -> np.ndarray:
    """Start from the transitions the prior box's centre explains worst."""
    count = max(8, 4 * (data.nparams + 1))
    needed = data.needed_margin((data.theta_low + data.theta_high) / 2)
    if needed.size <= count:
        return np.arange(needed.size)
    return np.argpartition(-needed, count - 1)[:count]


# ----------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class EliminationCertificate:
    """Why a hypothesis was eliminated: a re-checkable lower bound on its margin.

    Attributes
    ----------
    hypothesis
        Index of the hypothesis in the list given.
    margin
        The optimum of the margin LP (HiGHS's value): the smallest inflation s of the
        disturbance set that explains the data (see `eliminate_models`).
    lower_bound
        The certified lower bound on the margin, computed with numpy from
        ``multipliers_upper`` and ``multipliers_lower`` on ``transitions`` only
        (weak duality); it exceeds ``tolerance``.
    transitions
        Indices (k,) of the transitions whose rows carry a multiplier: the transitions
        that force the inconsistency.
    multipliers_upper, multipliers_lower
        (k, p) multipliers of the rows ``z_n - E_n theta - D w_n >= -(e_n + s beta)`` and
        ``<= e_n + s beta``.
    tolerance, rounding_allowance, measurement_noise
        The settings the bound was computed with (measurement_noise as (p,)).
    """

    hypothesis: int
    margin: float
    lower_bound: float
    transitions: np.ndarray
    multipliers_upper: np.ndarray
    multipliers_lower: np.ndarray
    tolerance: float
    rounding_allowance: float
    measurement_noise: np.ndarray

    def __post_init__(self) -> None:
        for name in ("multipliers_upper", "multipliers_lower", "measurement_noise"):
            object.__setattr__(self, name, frozen_copy(getattr(self, name)))
        t = np.array(self.transitions, dtype=int, copy=True)
        t.setflags(write=False)
        object.__setattr__(self, "transitions", t)

    def recheck_transitions(self, hypothesis: UncertainLinearSystem, states, controls, next_states) -> float:
        """Recompute the lower bound from transition triples (N, p), (N, q), (N, p).

        Only the rows of ``self.transitions`` are read. Returns the bound; the
        certificate holds iff it exceeds ``self.tolerance``.
        """
        if not isinstance(hypothesis, UncertainLinearSystem):
            raise InputError(f"hypothesis must be an UncertainLinearSystem, got {type(hypothesis).__name__}")
        p, q = hypothesis.nstates, hypothesis.ninputs
        X = as_finite_array("states", states, (None, p))
        U = as_finite_array("controls", controls, (X.shape[0], q))
        Xn = as_finite_array("next_states", next_states, X.shape)
        if self.transitions.size and self.transitions.max() >= X.shape[0]:
            raise DimensionError(
                f"the certificate refers to transition {int(self.transitions.max())}, "
                f"but states has shape {X.shape} ({X.shape[0]} transitions)"
            )
        check_shape("multipliers_upper", self.multipliers_upper, (self.transitions.size, p))
        t = self.transitions
        noise = measurement_noise_bound(hypothesis, self.measurement_noise)
        data = _HypothesisData(_Structure(hypothesis, noise, self.rounding_allowance), X[t], U[t], Xn[t])
        local = np.arange(t.size)
        return _lagrangian_bound(data, local, self.multipliers_upper, self.multipliers_lower, np.zeros(data.nparams), None)

    def recheck(self, hypothesis: UncertainLinearSystem, states, controls) -> float:
        """Recompute the lower bound from a trajectory: states (N+1, p), controls (N, q)."""
        X, U, Xn = _check_trajectory(states, controls, hypothesis.nstates, hypothesis.ninputs)
        return self.recheck_transitions(hypothesis, X, U, Xn)

    def verify(self, hypothesis: UncertainLinearSystem, states, controls) -> bool:
        """True iff the re-checked bound exceeds the tolerance (the elimination stands)."""
        return self.recheck(hypothesis, states, controls) > self.tolerance

    def to_dict(self) -> dict:
        return {
            "hypothesis": self.hypothesis,
            "margin": self.margin,
            "lower_bound": self.lower_bound,
            "transitions": self.transitions.tolist(),
            "multipliers_upper": self.multipliers_upper.tolist(),
            "multipliers_lower": self.multipliers_lower.tolist(),
            "tolerance": self.tolerance,
            "rounding_allowance": self.rounding_allowance,
            "measurement_noise": self.measurement_noise.tolist(),
        }


@dataclass(frozen=True, eq=False)
class SelectionResult:
    """The verdict on every hypothesis.

    Attributes
    ----------
    survivors
        Indices of the hypotheses the data does not contradict, increasing.
    eliminated
        Index -> `EliminationCertificate` of each eliminated hypothesis.
    margins
        Per hypothesis (in input order), the optimum of its margin LP: 0 if the data
        is consistent with it, else the inflation of its disturbance set needed.
    rounds
        Per hypothesis, the number of LPs constraint generation solved.
    tolerance
        The elimination threshold on the certified margin bound.
    """

    survivors: list[int]
    eliminated: dict[int, EliminationCertificate]
    margins: list[float]
    rounds: list[int] = field(default_factory=list)
    tolerance: float = ELIMINATION_MARGIN

    def to_dict(self) -> dict:
        return {
            "survivors": list(self.survivors),
            "eliminated": {str(k): c.to_dict() for k, c in self.eliminated.items()},
            "margins": list(self.margins),
            "rounds": list(self.rounds),
            "tolerance": self.tolerance,
        }


@dataclass
class _Verdict:
    margin: float
    upper: float
    lower: float
    theta: np.ndarray
    active: np.ndarray
    rounds: int
    certificate: EliminationCertificate | None


def _decide(
    index: int,
    data: _HypothesisData,
    *,
    initial: np.ndarray | None,
    tolerance: float,
    max_rounds: int,
    allowance: float,
    noise: np.ndarray,
) -> _Verdict:
    """Solve the margin LP of one hypothesis and decide, with a certificate if eliminated."""
    d = data.nparams
    if data.ntransitions == 0:
        centre = (data.theta_low + data.theta_high) / 2
        return _Verdict(0.0, 0.0, 0.0, centre, np.zeros(0, dtype=int), 0, None)
    start = _initial_rows(data) if initial is None else initial
    gen = _generate(data, np.zeros(d), None, start, max_rounds=max_rounds)
    sol = gen.solution
    certificate = None
    if gen.lower > tolerance:
        # Keep only the transitions with a multiplier: still a valid bound (fewer terms),
        # recomputed on exactly what the certificate stores.
        keep = np.flatnonzero(np.any((sol.y_upper > 0) | (sol.y_lower > 0), axis=1))
        transitions = gen.active[keep]
        lower = _lagrangian_bound(data, transitions, sol.y_upper[keep], sol.y_lower[keep], np.zeros(d), None)
        if lower > tolerance:
            certificate = EliminationCertificate(
                hypothesis=index,
                margin=sol.s,
                lower_bound=lower,
                transitions=transitions,
                multipliers_upper=sol.y_upper[keep],
                multipliers_lower=sol.y_lower[keep],
                tolerance=tolerance,
                rounding_allowance=allowance,
                measurement_noise=noise,
            )
    return _Verdict(sol.s, gen.upper, gen.lower, sol.theta, gen.active, gen.rounds, certificate)


def _check_options(tolerance, rounding_allowance, max_rounds) -> tuple[float, float, int]:
    tol = as_positive_scalar("tolerance", tolerance)
    allowance = as_positive_scalar("rounding_allowance", rounding_allowance, allow_zero=True)
    if not isinstance(max_rounds, (int, np.integer)) or max_rounds < 0:
        raise InputError(f"max_rounds must be an integer >= 0, got {max_rounds!r}")
    return tol, allowance, int(max_rounds)


# --------------------------------------------------------------------------- API
def eliminate_models(
    hypotheses: Sequence[UncertainLinearSystem],
    states,
    controls,
    *,
    measurement_noise=None,
    tolerance: float = ELIMINATION_MARGIN,
    rounding_allowance: float = ROUNDING_ALLOWANCE,
    max_rounds: int = MAX_GENERATION_ROUNDS,
) -> SelectionResult:
    """Discard the hypotheses that the observed trajectory contradicts.

    Parameters
    ----------
    hypotheses
        Non-empty sequence of `UncertainLinearSystem` with equal state and input sizes.
    states
        Observed states, shape (N+1, p).
    controls
        Applied controls, shape (N, q).
    measurement_noise
        Bound ``v_bar`` (scalar or (p,)) on bounded noise in the observed states, or None.
    tolerance
        A hypothesis is eliminated iff the certified lower bound on its margin exceeds this.
    rounding_allowance
        Relative allowance for floating-point rounding in each transition.
    max_rounds
        Constraint-generation rounds before a last round over every transition.

    Returns
    -------
    SelectionResult
        Survivors, certificates of the eliminated, margins. If every hypothesis is
        eliminated, ``survivors`` is empty (no exception: the certificates are the result).

    Raises
    ------
    InputError, DimensionError, NonFiniteError
        Bad hypotheses, shapes, NaN/inf, or options.
    SolverFailure
        HiGHS returned any status but optimal.

    Notes
    -----
    Hypothesis m, ``x+ = A(theta) x + B u + D w`` (eq. (2), Assumptions 1-2), is
    consistent iff there are ``theta`` in its prior box and ``w_n`` in ``W`` with
    ``z_n = E_n theta + D w_n`` for every transition, ``z_n = x_{n+1} - A0 x_n - B u_n``,
    ``E_n = regressor(x_n)`` (the paper's LP test, Section III). Two allowances are
    added to each row, both erring towards keeping: bounded measurement noise
    ``|e_n| <= v_bar + max_theta |A(theta)| v_bar`` (see `measurement_noise_bound`,
    DESIGN errata) and rounding, ``rounding_allowance`` times the magnitude of the
    terms of the row. When ``D W`` is a box the noise term gives exactly the errata's
    inflated bound ``|D| w_bar + v_bar + max_theta |A(theta)| v_bar`` (about the centre
    of ``D W``); otherwise ``D w_n`` is kept exact and only the noise is a box, which is
    tighter and still sound. The *margin* is the least ``s >= 0`` such that

    ``-(e_n + s beta) <= z_n - E_n theta - D w_n <= e_n + s beta``  for all n,

    with ``beta`` the radius of the interval hull of ``D W + [-v, v]`` (``|D| r_w`` plus
    the noise bound), or 1 where that is 0, and at least 1e-6 times its largest entry
    (to keep the LP well scaled). For D = I without noise this is the
    inflation of W to ``[w_lo - s r_w, w_hi + s r_w]``. When ``D W`` is a box (every
    column of D with a nonzero disturbance radius has one nonzero entry, e.g. D = I or
    ``dt I``), w is eliminated exactly and the LP has d + 1 variables and 2 p N rows;
    otherwise the ``w_n`` are LP variables (rows of transitions outside the generated
    subset are checked with the disturbance ``clip(pinv(D) residual, W)``, which only
    over-estimates their violation, so an undecided transition is simply added).

    The decision uses a weak-duality bound recomputed with numpy (see
    `EliminationCertificate`), so neither HiGHS's tolerances nor an early stop of
    constraint generation can eliminate a consistent hypothesis.
    """
    hyps = _check_hypotheses(hypotheses)
    p, q = hyps[0].nstates, hyps[0].ninputs
    X, U, Xn = _check_trajectory(states, controls, p, q)
    tol, allowance, rounds_cap = _check_options(tolerance, rounding_allowance, max_rounds)
    noise = _noise_vector(measurement_noise, p)
    survivors, eliminated, margins, rounds = [], {}, [], []
    for m, hyp in enumerate(hyps):
        data = _HypothesisData(_Structure(hyp, measurement_noise_bound(hyp, noise), allowance), X, U, Xn)
        verdict = _decide(m, data, initial=None, tolerance=tol, max_rounds=rounds_cap, allowance=allowance, noise=noise)
        margins.append(verdict.margin)
        rounds.append(verdict.rounds)
        if verdict.certificate is None:
            survivors.append(m)
        else:
            eliminated[m] = verdict.certificate
    return SelectionResult(survivors, eliminated, margins, rounds, tol)


def feasible_parameter_box(
    hypothesis: UncertainLinearSystem,
    states,
    controls,
    *,
    measurement_noise=None,
    tolerance: float = ELIMINATION_MARGIN,
    rounding_allowance: float = ROUNDING_ALLOWANCE,
    max_rounds: int = MAX_GENERATION_ROUNDS,
) -> Box:
    """The bounding box of the parameters consistent with a trajectory.

    Parameters
    ----------
    hypothesis
        An `UncertainLinearSystem`.
    states, controls
        Shapes (N+1, p) and (N, q).
    measurement_noise, tolerance, rounding_allowance, max_rounds
        As in `eliminate_models`.

    Returns
    -------
    Box
        Contains every theta of the prior box that explains the data (with the
        allowances of `eliminate_models`); usable as ``parameters`` of ``predict_tube``.

    Raises
    ------
    NoConsistentModel
        If `eliminate_models` would eliminate the hypothesis.
    SolverFailure
        If HiGHS returns any status but optimal.

    Notes
    -----
    2d LPs, minimising and maximising each theta_i over the consistent set (by
    constraint generation). Each side is the weak-duality bound recomputed with numpy,
    so it is on the safe side of the LP optimum whatever HiGHS's accuracy, then rounded
    outward by one ulp and intersected with the prior. The rows are relaxed by
    `PARAMETER_BOX_ALLOWANCE` (relative) instead of ``rounding_allowance`` if that is
    larger, so that a nearly degenerate consistent set stays thicker than HiGHS's
    tolerances. If the data is consistent only
    up to the margin tolerance (margin ``s`` in (0, tolerance]), the set of
    ``theta`` consistent with the disturbance set inflated by ``s`` is bounded instead:
    a superset, hence still sound.
    """
    if not isinstance(hypothesis, UncertainLinearSystem):
        raise InputError(f"hypothesis must be an UncertainLinearSystem, got {type(hypothesis).__name__}")
    X, U, Xn = _check_trajectory(states, controls, hypothesis.nstates, hypothesis.ninputs)
    tol, allowance, rounds_cap = _check_options(tolerance, rounding_allowance, max_rounds)
    noise = _noise_vector(measurement_noise, hypothesis.nstates)
    data = _HypothesisData(_Structure(hypothesis, measurement_noise_bound(hypothesis, noise), allowance), X, U, Xn)
    if data.ntransitions == 0:
        return hypothesis.theta
    verdict = _decide(0, data, initial=None, tolerance=tol, max_rounds=rounds_cap, allowance=allowance, noise=noise)
    if verdict.certificate is not None:
        raise NoConsistentModel(
            f"the hypothesis is inconsistent with the data: margin {verdict.margin:.6g} "
            f"(certified >= {verdict.certificate.lower_bound:.6g} > tolerance {tol:g})"
        )
    s_box = verdict.upper + GENERATION_TOLERANCE
    # A larger allowance only enlarges the feasible set, so s_box stays feasible.
    box_allowance = max(allowance, PARAMETER_BOX_ALLOWANCE)
    data = _HypothesisData(_Structure(hypothesis, measurement_noise_bound(hypothesis, noise), box_allowance), X, U, Xn)
    d = data.nparams
    low, high = np.empty(d), np.empty(d)
    for i in range(d):
        for sign in (1.0, -1.0):
            objective = np.zeros(d)
            objective[i] = sign
            gen = _generate(data, objective, s_box, verdict.active, max_rounds=rounds_cap)
            if sign > 0:
                low[i] = np.nextafter(gen.lower, -np.inf)
            else:
                high[i] = np.nextafter(-gen.lower, np.inf)
    low = np.maximum(low, hypothesis.theta.low)
    high = np.minimum(high, hypothesis.theta.high)
    if np.any(low > high):
        raise SolverFailure(
            f"parameter bounds crossed (low {low.tolist()}, high {high.tolist()}) although a "
            "consistent parameter was found: the dual multipliers are unusable"
        )
    return Box(low, high)


# --------------------------------------------------------------------- streaming
class ModelSelector:
    """Streaming model elimination: add transitions one at a time.

    Parameters
    ----------
    hypotheses
        As in `eliminate_models`.
    measurement_noise, tolerance, rounding_allowance, max_rounds
        As in `eliminate_models`.

    Notes
    -----
    A new transition can only eliminate. For each survivor the parameter of its last
    LP is kept; if that parameter explains the new transition within the tolerance
    (an O(p (p + q + d)) check), nothing is solved. Otherwise the margin LP is re-solved over all
    transitions so far, starting constraint generation from the previous active rows.
    Eliminated hypotheses are never checked again nor revived; when all are
    eliminated, ``survivors`` is empty (no exception: the certificates are the result).
    Verdicts equal those of `eliminate_models` on the same transitions (both eliminate
    iff the certified bound exceeds the tolerance).

    Memory: the transitions are stored in arrays grown by doubling, O(N (2p + q))
    floats for N transitions, plus the active row indices per survivor (typically
    O(d) each); per-hypothesis regression data is rebuilt only for a re-solve.
    """

    def __init__(
        self,
        hypotheses: Sequence[UncertainLinearSystem],
        *,
        measurement_noise=None,
        tolerance: float = ELIMINATION_MARGIN,
        rounding_allowance: float = ROUNDING_ALLOWANCE,
        max_rounds: int = MAX_GENERATION_ROUNDS,
    ) -> None:
        self._hypotheses = tuple(_check_hypotheses(hypotheses))
        h0 = self._hypotheses[0]
        self._p, self._q = h0.nstates, h0.ninputs
        self._tolerance, self._allowance, self._max_rounds = _check_options(tolerance, rounding_allowance, max_rounds)
        self._noise = _noise_vector(measurement_noise, self._p)
        self._structures = [
            _Structure(h, measurement_noise_bound(h, self._noise), self._allowance) for h in self._hypotheses
        ]
        self._count = 0
        self._X = np.empty((16, self._p))
        self._U = np.empty((16, self._q))
        self._Xn = np.empty((16, self._p))
        self._theta = {m: (h.theta.low + h.theta.high) / 2 for m, h in enumerate(self._hypotheses)}
        self._upper = {m: 0.0 for m in range(len(self._hypotheses))}
        self._margins = [0.0] * len(self._hypotheses)
        self._active = {m: np.zeros(0, dtype=int) for m in range(len(self._hypotheses))}
        self._certificates: dict[int, EliminationCertificate] = {}
        self._solves = 0

    @property
    def hypotheses(self) -> tuple[UncertainLinearSystem, ...]:
        return self._hypotheses

    @property
    def survivors(self) -> list[int]:
        """Indices of the hypotheses not eliminated so far."""
        return [m for m in range(len(self._hypotheses)) if m not in self._certificates]

    @property
    def eliminated(self) -> list[int]:
        """Indices of the eliminated hypotheses, increasing."""
        return sorted(self._certificates)

    @property
    def certificates(self) -> dict[int, EliminationCertificate]:
        """Index -> certificate of each eliminated hypothesis (transition indices count `add` calls)."""
        return dict(sorted(self._certificates.items()))

    @property
    def ntransitions(self) -> int:
        return self._count

    @property
    def solves(self) -> int:
        """How many margin LPs were re-solved (the rest were settled by the O(p d) check)."""
        return self._solves

    def transitions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Copies of the stored (states, controls, next_states), shapes (N, p), (N, q), (N, p)."""
        n = self._count
        return self._X[:n].copy(), self._U[:n].copy(), self._Xn[:n].copy()

    def add(self, state, control, next_state) -> list[int]:
        """Record the transition (state, control) -> next_state; return the survivors."""
        x = as_finite_array("state", state, (self._p,))
        u = as_finite_array("control", control, (self._q,))
        xn = as_finite_array("next_state", next_state, (self._p,))
        if self._count == self._X.shape[0]:
            grow = lambda a: np.concatenate([a, np.empty_like(a)])  # noqa: E731
            self._X, self._U, self._Xn = grow(self._X), grow(self._U), grow(self._Xn)
        n = self._count
        self._X[n], self._U[n], self._Xn[n] = x, u, xn
        self._count += 1
        for m in self.survivors:
            one = _HypothesisData(self._structures[m], x[None], u[None], xn[None])
            needed = float(one.needed_margin(self._theta[m])[0])
            if max(self._upper[m], needed) <= self._tolerance:
                self._upper[m] = max(self._upper[m], needed, 0.0)
                continue
            self._resolve(m, n)
        return self.survivors

    def _resolve(self, m: int, newest: int) -> None:
        n = self._count
        data = _HypothesisData(self._structures[m], self._X[:n], self._U[:n], self._Xn[:n])
        initial = np.union1d(self._active[m], [newest])
        verdict = _decide(
            m, data, initial=initial, tolerance=self._tolerance, max_rounds=self._max_rounds,
            allowance=self._allowance, noise=self._noise,
        )
        self._solves += 1
        self._margins[m] = verdict.margin
        if verdict.certificate is not None:
            self._certificates[m] = verdict.certificate
            return
        self._theta[m], self._upper[m], self._active[m] = verdict.theta, verdict.upper, verdict.active

    def result(self) -> SelectionResult:
        """The current verdicts as a `SelectionResult` (margins: last LP optimum, 0 before any)."""
        return SelectionResult(self.survivors, self.certificates, list(self._margins), [], self._tolerance)
