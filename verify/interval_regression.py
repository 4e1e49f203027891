"""Consistency of interval regressions: parameters explaining data whose regressors are boxes.

The model of a measured quantity is linear in the parameters, ``y = g . theta``, but
both the target ``y`` and the regressor ``g`` are only known to lie in intervals
(measurement noise on the states *and* on the inputs, such as a leader's measured
speed, plus bounded disturbances and remainders). A row ``k`` is *explained* by
``theta`` iff some ``g`` in ``[g_lo_k, g_hi_k]`` and ``y`` in ``[y_lo_k, y_hi_k]`` have
``g . theta = y``. Where ``theta >= 0`` on every coordinate whose regressor is a
genuine interval, ``g . theta`` ranges exactly over ``[g_lo . theta, g_hi . theta]``
(each coordinate at its own end), so row k holds iff

    ``g_lo_k . theta <= y_hi_k``   and   ``g_hi_k . theta >= y_lo_k``,

two linear inequalities (exact: no relaxation). Coordinates with a point regressor
(``g_lo = g_hi``) may have any sign (e.g. an auxiliary variable or a linear relation
between parameters). A hypothesis is consistent with rows iff one ``theta`` in its prior
box explains all of them: an LP feasibility problem, solved with HiGHS (a single row in
closed form, exactly: the dual of its margin LP has one free weight).

Verdicts are proven both ways, as `minimaxplan.verify.eliminate_models` does:
``"consistent"`` only with a witness ``theta`` re-checked with numpy on every row,
``"inconsistent"`` only with a weak-duality lower bound on the inconsistency margin,
recomputed with numpy from HiGHS's multipliers (an `IntervalCertificate`, re-checkable
from the rows alone), and ``"inconclusive"`` otherwise (kept: errs towards keeping).
`interval_parameter_box` bounds the consistent parameters by up to 2d LPs whose every
side is a weak-duality bound, hence on the safe side whatever HiGHS's accuracy (a side
the witness attains, moved along one coordinate, is the prior's and needs no LP).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.optimize import linprog

from minimaxplan.models import Box
from minimaxplan.models.errors import DimensionError, InputError, NoConsistentModel, SolverFailure
from minimaxplan.models.validation import as_positive_scalar, check_instance, frozen_copy

from ._highs import HIGHS_OPTIONS, LinprogStatus
from ._regression import EPS

__all__ = [
    "INTERVAL_ELIMINATION_MARGIN",
    "INTERVAL_ROUNDING_ALLOWANCE",
    "INTERVAL_BOX_ALLOWANCE",
    "WITNESS_DEPTH",
    "witness_margin",
    "IntervalRows",
    "IntervalCertificate",
    "IntervalVerdict",
    "interval_consistency",
    "interval_parameter_box",
]

#: A hypothesis is declared inconsistent only if the certified lower bound on its
#: margin (in units of each row's natural magnitude) exceeds this.
INTERVAL_ELIMINATION_MARGIN = 1e-7
#: Every row is relaxed by this much relative to its magnitude (floating-point rounding
#: in the data; errs towards keeping).
INTERVAL_ROUNDING_ALLOWANCE = 1e-9
#: The margin LP lets s go down to minus this (dimensionless): its witness is the point of
#: the prior whose smallest slack over the rows is largest, up to this depth.
WITNESS_DEPTH = 1.0
#: `interval_parameter_box` relaxes the rows by this much relative to their magnitude
#: (a superset, so sound), so that a nearly degenerate consistent set stays thicker than
#: HiGHS's tolerances.
INTERVAL_BOX_ALLOWANCE = 1e-7


def _as_bounds(name: str, value, shape) -> np.ndarray:
    """A float array of ``shape``: no NaN (infinite entries are allowed)."""
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a real numeric array: {exc}") from None
    if array.shape != tuple(shape):
        raise DimensionError(f"{name} must have shape {tuple(shape)}, got shape {array.shape}")
    if np.any(np.isnan(array)):
        raise InputError(f"{name} contains NaN entries")
    return array


@dataclass(frozen=True, eq=False)
class IntervalRows:
    """Rows ``y_lo_k <= g^T theta <= y_hi_k`` for some ``g`` in ``[g_lo_k, g_hi_k]``.

    Parameters
    ----------
    regressor_low, regressor_high : array_like
        Shape (k, d): the regressor intervals, finite, ``low <= high``.
    target_low, target_high : array_like
        Shape (k,): the target intervals, ``low <= high``; ``-inf`` / ``+inf`` mark a
        one-sided row (e.g. a transition through a saturation).

    Raises
    ------
    DimensionError
        Shapes that do not match.
    InputError, NonFiniteError
        NaN, infinite regressors, or crossed intervals.

    Notes
    -----
    Rows whose two targets are infinite constrain nothing and are dropped. Each row's
    *magnitude* ``beta_k = sum_i max(|g_lo_ki|, |g_hi_ki|) t_i + max |finite y_k|``
    (``t`` the prior's largest modulus per coordinate, given later) scales like the row,
    so the margins and the verdicts do not depend on the units of the rows nor of the
    parameters.
    """

    regressor_low: np.ndarray
    regressor_high: np.ndarray
    target_low: np.ndarray
    target_high: np.ndarray

    def __post_init__(self) -> None:
        glo = np.array(self.regressor_low, dtype=float)
        if glo.ndim != 2:
            raise DimensionError(f"regressor_low must have shape (k, d), got shape {glo.shape}")
        k, d = glo.shape
        glo = _as_bounds("regressor_low", glo, (k, d))
        ghi = _as_bounds("regressor_high", self.regressor_high, (k, d))
        ylo = _as_bounds("target_low", self.target_low, (k,))
        yhi = _as_bounds("target_high", self.target_high, (k,))
        if not (np.all(np.isfinite(glo)) and np.all(np.isfinite(ghi))):
            raise InputError("regressor_low and regressor_high must be finite (drop uninformative rows instead)")
        if np.any(glo > ghi):
            raise InputError(
                f"regressor_low > regressor_high in rows {np.flatnonzero(np.any(glo > ghi, axis=1)).tolist()}"
            )
        if np.any(ylo > yhi):
            raise InputError(f"target_low > target_high in rows {np.flatnonzero(ylo > yhi).tolist()}")
        if np.any(ylo == np.inf) or np.any(yhi == -np.inf):
            raise InputError("target_low must be < +inf and target_high > -inf")
        keep = np.isfinite(ylo) | np.isfinite(yhi)
        for name, value in (
            ("regressor_low", glo[keep]),
            ("regressor_high", ghi[keep]),
            ("target_low", ylo[keep]),
            ("target_high", yhi[keep]),
        ):
            object.__setattr__(self, name, frozen_copy(value))

    @property
    def nrows(self) -> int:
        """The number k of (informative) rows."""
        return self.target_low.shape[0]

    @property
    def nparams(self) -> int:
        """The number d of parameters."""
        return self.regressor_low.shape[1]

    @staticmethod
    def stack(parts: list[IntervalRows], nparams: int) -> IntervalRows:
        """The rows of several `IntervalRows`, in order.

        Parameters
        ----------
        parts : list of IntervalRows
            Rows with ``nparams`` parameters each.
        nparams : int
            The number of parameters (the size of an empty result).

        Returns
        -------
        IntervalRows
            Every row of ``parts`` (no rows for an empty list).
        """
        if not parts:
            return IntervalRows(np.zeros((0, nparams)), np.zeros((0, nparams)), np.zeros(0), np.zeros(0))
        return IntervalRows(
            np.vstack([p.regressor_low for p in parts]),
            np.vstack([p.regressor_high for p in parts]),
            np.concatenate([p.target_low for p in parts]),
            np.concatenate([p.target_high for p in parts]),
        )

    def scaled(self, rows: ArrayLike, columns: ArrayLike) -> IntervalRows:
        """The same rows in other units: row k times ``rows[k] > 0``, parameter i divided by ``columns[i] > 0``.

        Parameters
        ----------
        rows : array_like
            Shape (k,), positive row factors.
        columns : array_like
            Shape (d,), positive parameter factors (``theta_i -> columns[i] theta_i``).

        Returns
        -------
        IntervalRows
            Explained by ``columns * theta`` iff the original rows are explained by theta.
        """
        r = np.asarray(rows, dtype=float).reshape(-1, 1)
        c = np.asarray(columns, dtype=float).reshape(1, -1)
        if np.any(r <= 0) or np.any(c <= 0):
            raise InputError("row and column factors must be > 0")
        return IntervalRows(
            self.regressor_low * r / c,
            self.regressor_high * r / c,
            self.target_low * r[:, 0],
            self.target_high * r[:, 0],
        )


def _check_prior(rows: IntervalRows, prior: Box) -> np.ndarray:
    """The prior's largest modulus per coordinate, after checking its size and its sign on interval regressors."""
    check_instance("prior", prior, Box)
    if prior.dim != rows.nparams:
        raise DimensionError(f"prior has dimension {prior.dim}, but the rows have {rows.nparams} parameters")
    interval = np.any(rows.regressor_low != rows.regressor_high, axis=0) if rows.nrows else np.zeros(prior.dim, bool)
    if np.any(interval & (prior.low < 0)):
        bad = np.flatnonzero(interval & (prior.low < 0)).tolist()
        raise InputError(
            f"parameters {bad} have interval regressors but a prior reaching below 0: the interval rows "
            "g_lo . theta <= y_hi, g_hi . theta >= y_lo are exact only for theta >= 0 there"
        )
    return np.maximum(np.abs(prior.low), np.abs(prior.high))


class _Scaled:
    """The 2k inequalities ``a . t <= b`` in the scaled variables ``t = theta / theta_scale``."""

    def __init__(self, rows: IntervalRows, prior: Box, allowance: float) -> None:
        theta_max = _check_prior(rows, prior)
        self.theta_scale = np.where(theta_max > 0, theta_max, 1.0)
        glo, ghi, ylo, yhi = rows.regressor_low, rows.regressor_high, rows.target_low, rows.target_high
        y_abs = np.maximum(np.where(np.isfinite(ylo), np.abs(ylo), 0.0), np.where(np.isfinite(yhi), np.abs(yhi), 0.0))
        # a coordinate fixed at 0 adds nothing to a row's magnitude, whatever its regressor's units
        beta = np.maximum(np.abs(glo), np.abs(ghi)) @ theta_max + y_abs
        self.beta = np.where(beta > 0, beta, 1.0)
        upper, lower = np.isfinite(yhi), np.isfinite(ylo)
        # upper rows: g_lo . theta <= y_hi;  lower rows: -g_hi . theta <= -y_lo
        a = np.vstack(
            [
                glo[upper] * self.theta_scale / self.beta[upper, None],
                -ghi[lower] * self.theta_scale / self.beta[lower, None],
            ]
        )
        b = np.concatenate([yhi[upper] / self.beta[upper], -ylo[lower] / self.beta[lower]]) + allowance
        self.a, self.b = a, b
        self.row_of = np.concatenate([np.flatnonzero(upper), np.flatnonzero(lower)])
        self.side = np.concatenate([np.ones(int(upper.sum()), int), -np.ones(int(lower.sum()), int)])
        self.low, self.high = prior.low / self.theta_scale, prior.high / self.theta_scale

    def needed(self, theta: np.ndarray) -> np.ndarray:
        """Per inequality, the margin ``a . t - b`` (dimensionless) that ``theta`` needs."""
        return self.a @ (theta / self.theta_scale) - self.b

    def lower_bound(self, mu: np.ndarray, objective: np.ndarray, slack: float, free_margin: bool) -> float:
        """Weak duality: ``min_t objective . t + sum mu (a t - b - slack)`` over the box, rounded down."""
        mu = np.maximum(mu, 0.0)
        if free_margin:
            # with sum mu = 1 the margin's coefficient vanishes: the bound holds for every s
            total = float(np.sum(mu))
            if total <= 0.0:
                return -np.inf
            mu = mu / total
        c = objective + mu @ self.a
        theta_term = np.minimum(c * self.low, c * self.high)
        constant = mu * (self.b + slack)
        value = float(np.sum(theta_term) - np.sum(constant))
        magnitude = float(
            np.sum(np.abs(theta_term))
            + np.sum(np.abs(constant))
            + np.sum((np.abs(objective) + mu @ np.abs(self.a)) * np.maximum(np.abs(self.low), np.abs(self.high)))
        )
        return value - 4 * (mu.size + self.a.shape[1] + 10) * EPS * magnitude


def _solve(scaled: _Scaled, objective: np.ndarray, margin: float | None) -> tuple[np.ndarray, float, np.ndarray]:
    """HiGHS on the scaled LP: ``margin`` None minimises s with ``a t - s <= b``; else ``a t <= b + margin``."""
    m, d = scaled.a.shape
    free = margin is None
    A = np.hstack([scaled.a, -np.ones((m, 1))]) if free else scaled.a
    c = np.concatenate([objective, [1.0]]) if free else objective
    bounds = np.column_stack([scaled.low, scaled.high])
    if free:
        # s may go down to -1: the witness is then the deepest point (max-min slack), so
        # that it keeps explaining new rows for longer (see `interval_consistency`)
        bounds = np.vstack([bounds, [-WITNESS_DEPTH, np.inf]])
    b = scaled.b if margin is None else scaled.b + margin
    if m == 0:
        return _box_minimiser(scaled, c[:d]), 0.0, np.zeros(0)
    res = linprog(c, A_ub=sp.csr_matrix(A), b_ub=b, bounds=bounds, method="highs", options=HIGHS_OPTIONS)
    if res.status != LinprogStatus.OPTIMAL:
        try:
            reason = LinprogStatus(res.status).reason
        except ValueError:
            reason = f"unknown status {res.status}"
        raise SolverFailure(
            f"HiGHS failed on the interval-regression {'margin' if free else 'parameter-bound'} LP over {m} "
            f"inequalities: status {res.status} ({reason}): {res.message}"
        )
    x = np.asarray(res.x, dtype=float)
    mu = np.maximum(-np.asarray(res.ineqlin.marginals, dtype=float), 0.0)
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(mu))):
        raise SolverFailure(f"HiGHS returned non-finite values on the interval-regression LP over {m} inequalities")
    return x[:d], (float(x[d]) if margin is None else float(margin)), mu[:m]


def _box_minimiser(scaled: _Scaled, c: np.ndarray) -> np.ndarray:
    """A minimiser of ``c . t`` over the scaled prior box (the midpoint where ``c_i = 0``)."""
    return np.where(c > 0, scaled.low, np.where(c < 0, scaled.high, (scaled.low + scaled.high) / 2))


def _meets_every_inequality(scaled: _Scaled, t: np.ndarray, slack: float) -> bool:
    """Whether ``a . t <= b + slack`` holds for every inequality in exact arithmetic, proven despite rounding.

    Each computed ``a_j . t - b_j - slack`` must lie below 0 by more than the rounding error bound of
    its evaluation (as `_Scaled.lower_bound` rounds its value down).
    """
    value = scaled.a @ t - scaled.b - slack
    magnitude = np.abs(scaled.a) @ np.abs(t) + np.abs(scaled.b) + abs(slack)
    return bool(np.all(value + 4 * (t.size + 10) * EPS * magnitude <= 0.0))


def _dual_value(scaled: _Scaled, weight: float) -> float:
    """``min_t sum_j mu_j (a_j . t - b_j)`` over the box for two inequalities, ``mu = (weight, 1 - weight)``."""
    c = weight * scaled.a[0] + (1.0 - weight) * scaled.a[1]
    return float(
        np.sum(np.minimum(c * scaled.low, c * scaled.high)) - (weight * scaled.b[0] + (1.0 - weight) * scaled.b[1])
    )


def _balance(scaled: _Scaled, t: np.ndarray, free: np.ndarray, goal: str) -> np.ndarray:
    """Move the free coordinates of ``t`` inside the box so that ``d(t) = (a_0 - a_1) . t - (b_0 - b_1)`` is
    largest (``goal="max"``), smallest (``"min"``) or 0 (``"zero"``, or the end nearest 0 if 0 is not reached).

    Every such ``t`` minimises the dual combination at the chosen weight (the free coordinates are those
    whose coefficient vanishes there); the goal picks among them the one with the smallest larger side.
    """
    diff = scaled.a[0] - scaled.a[1]
    t = t.copy()
    up = np.where(diff > 0, scaled.high, scaled.low)  # the end raising d
    down = np.where(diff > 0, scaled.low, scaled.high)
    if goal == "max":
        t[free] = up[free]
        return t
    t[free] = down[free]
    if goal == "min":
        return t
    offset = scaled.b[0] - scaled.b[1]
    value = float(diff @ t - offset)
    for i in np.flatnonzero(free):
        if value >= 0.0:
            break
        gain = diff[i] * (up[i] - down[i])
        if value + gain >= 0.0 and gain > 0.0:
            t[i] = min(max(down[i] - value / diff[i], min(down[i], up[i])), max(down[i], up[i]))
            break
        t[i] = up[i]
        value += gain
    return t


def _solve_single_row(scaled: _Scaled) -> tuple[np.ndarray, float, np.ndarray]:
    """The margin LP of `interval_consistency` for one row (one or two inequalities), in closed form.

    With one inequality ``a . t <= b`` the optimum is ``min_t a . t - b``, at a vertex. With two
    (the row's two sides), by LP duality ``s* = max_w phi(w)``, ``phi(w) = min_t (w a_0 + (1 - w) a_1) . t
    - w b_0 - (1 - w) b_1`` over ``w`` in [0, 1]: a concave piecewise-linear function whose kinks are
    where one coordinate's coefficient changes sign, so its maximum is at 0, 1 or a kink, and every
    candidate is evaluated. The multipliers are ``(w*, 1 - w*)``; the primal ``t`` minimises the
    combination at ``w*`` and, among those minimisers, balances the two sides (`_balance`), which makes
    it optimal (0 is a subgradient of phi at an interior ``w*``). Returns ``(t, s, mu)`` as `_solve`,
    ``s`` floored at ``-WITNESS_DEPTH``. Nothing here is trusted: `interval_consistency` re-checks the
    witness on the row and recomputes the bound from the multipliers, as for HiGHS's answer.
    """
    low, high = scaled.low, scaled.high
    if scaled.a.shape[0] == 1:
        c = scaled.a[0]
        t = _box_minimiser(scaled, c)
        return t, max(float(c @ t - scaled.b[0]), -WITNESS_DEPTH), np.ones(1)
    a0, a1 = scaled.a
    diff = a0 - a1
    with np.errstate(divide="ignore", invalid="ignore"):
        kinks = np.where(diff != 0.0, -a1 / diff, np.nan)
    inside = np.isfinite(kinks) & (kinks > 0.0) & (kinks < 1.0)
    candidates = np.concatenate([[0.0, 1.0], kinks[inside]])
    values = [_dual_value(scaled, float(w)) for w in candidates]
    best = int(np.argmax(values))
    weight = float(candidates[best])
    c = weight * a0 + (1.0 - weight) * a1
    free = c == 0.0
    if best >= 2:
        free |= inside & (kinks == weight)
    t = np.where(c > 0, low, high)
    goal = "min" if weight == 0.0 else "max" if weight == 1.0 else "zero"
    t = _balance(scaled, t, free, goal)
    unused = (a0 == 0.0) & (a1 == 0.0)
    t[unused] = (low[unused] + high[unused]) / 2
    s = float(np.max(scaled.a @ t - scaled.b))
    return t, max(s, -WITNESS_DEPTH), np.array([weight, 1.0 - weight])


@dataclass(frozen=True, eq=False)
class IntervalCertificate:
    """Why rows are inconsistent with a prior: multipliers giving a lower bound on the margin.

    Attributes
    ----------
    multipliers_upper, multipliers_lower : numpy.ndarray
        Shape (k,), >= 0: the multipliers of the rows ``g_lo . theta <= y_hi`` and
        ``g_hi . theta >= y_lo`` (each divided by its magnitude), 0 on absent sides.
    lower_bound : float
        The weak-duality bound on the margin they give, recomputed with numpy.
    tolerance, rounding_allowance : float
        The settings it was computed with.
    """

    multipliers_upper: np.ndarray
    multipliers_lower: np.ndarray
    lower_bound: float
    tolerance: float
    rounding_allowance: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "multipliers_upper", frozen_copy(self.multipliers_upper))
        object.__setattr__(self, "multipliers_lower", frozen_copy(self.multipliers_lower))

    def recheck(self, rows: IntervalRows, prior: Box) -> float:
        """The lower bound on the margin recomputed from the rows and the prior alone.

        Parameters
        ----------
        rows : IntervalRows
            The rows the certificate was computed on.
        prior : Box
            The prior box.

        Returns
        -------
        float
            The certificate holds iff this exceeds ``self.tolerance``.
        """
        check_instance("rows", rows, IntervalRows)
        if self.multipliers_upper.shape != (rows.nrows,):
            raise DimensionError(
                f"the certificate has {self.multipliers_upper.shape[0]} rows, the rows given {rows.nrows}"
            )
        scaled = _Scaled(rows, prior, self.rounding_allowance)
        mu = np.where(scaled.side > 0, self.multipliers_upper[scaled.row_of], self.multipliers_lower[scaled.row_of])
        return scaled.lower_bound(mu, np.zeros(rows.nparams), 0.0, True)

    def to_dict(self) -> dict:
        """A JSON-ready dictionary."""
        return {
            "multipliers_upper": self.multipliers_upper.tolist(),
            "multipliers_lower": self.multipliers_lower.tolist(),
            "lower_bound": self.lower_bound,
            "tolerance": self.tolerance,
            "rounding_allowance": self.rounding_allowance,
        }


@dataclass(frozen=True, eq=False)
class IntervalVerdict:
    """The verdict on one hypothesis' interval rows.

    Attributes
    ----------
    status : str
        ``"consistent"`` (a re-checked witness), ``"inconsistent"`` (a re-checked
        certificate) or ``"inconclusive"`` (neither: treated as consistent).
    witness : numpy.ndarray
        Shape (d,): the LP's parameter, in the prior box.
    margin : float
        The optimum of the margin LP (dimensionless): HiGHS's, or the closed form's for one row.
    upper : float
        The margin the witness needs on every row, recomputed with numpy (>= 0).
    lower : float
        The certified lower bound on the margin.
    certificate : IntervalCertificate or None
        Present iff ``status == "inconsistent"``.
    """

    status: str
    witness: np.ndarray
    margin: float
    upper: float
    lower: float
    certificate: IntervalCertificate | None

    def __post_init__(self) -> None:
        object.__setattr__(self, "witness", frozen_copy(self.witness))

    @property
    def eliminated(self) -> bool:
        """True iff the rows are proven inconsistent with the prior."""
        return self.status == "inconsistent"

    def to_dict(self) -> dict:
        """A JSON-ready dictionary."""
        return {
            "status": self.status,
            "witness": self.witness.tolist(),
            "margin": self.margin,
            "upper": self.upper,
            "lower": self.lower,
            "certificate": None if self.certificate is None else self.certificate.to_dict(),
        }


def witness_margin(
    rows: IntervalRows, prior: Box, theta: ArrayLike, *, rounding_allowance: float = INTERVAL_ROUNDING_ALLOWANCE
) -> float:
    """The margin (dimensionless, >= 0) that ``theta`` needs to explain every row.

    Parameters
    ----------
    rows : IntervalRows
        The rows.
    prior : Box
        The prior (sets the magnitudes).
    theta : array_like
        Shape (d,), a parameter (clipped to the prior).
    rounding_allowance : float
        Relative relaxation of every row.

    Returns
    -------
    float
        0 iff ``theta`` explains every row up to the allowance.
    """
    scaled = _Scaled(rows, prior, rounding_allowance)
    t = np.clip(np.asarray(theta, dtype=float), prior.low, prior.high)
    needed = scaled.needed(t)
    return float(max(np.max(needed, initial=0.0), 0.0))


def interval_consistency(
    rows: IntervalRows,
    prior: Box,
    *,
    tolerance: float = INTERVAL_ELIMINATION_MARGIN,
    rounding_allowance: float = INTERVAL_ROUNDING_ALLOWANCE,
) -> IntervalVerdict:
    """Decide whether one parameter of the prior box explains every interval row.

    Parameters
    ----------
    rows : IntervalRows
        The data model of one hypothesis.
    prior : Box
        The prior parameter box; >= 0 on every coordinate with an interval regressor.
    tolerance : float
        Inconsistent iff the certified margin bound exceeds this; consistent iff the
        witness needs at most this.
    rounding_allowance : float
        Relative relaxation of every row (errs towards keeping).

    Returns
    -------
    IntervalVerdict

    Raises
    ------
    InputError, DimensionError
        A prior of the wrong size, or reaching below 0 where a regressor is an interval.
    SolverFailure
        HiGHS returned any status but optimal (on two rows or more).

    Notes
    -----
    The margin LP: minimise ``s >= -WITNESS_DEPTH`` over ``theta`` in the prior with
    ``(g_lo . theta - y_hi) / beta <= s + a`` and ``(y_lo - g_hi . theta) / beta <= s + a``
    (``beta`` each row's magnitude, ``a`` the allowance). It is equilibrated (rows by
    beta, theta by its prior's largest modulus), so rescaling the rows or the
    parameters (`IntervalRows.scaled`) leaves the LP HiGHS solves the same up to
    rounding. The inconsistency margin is ``max(s*, 0)``; a negative optimum makes the
    witness the deepest point of the consistent set (its smallest slack is largest),
    which keeps explaining new rows for longer in streaming use. The witness is
    re-checked with numpy; the multipliers ``mu >= 0``, normalised to ``sum mu = 1``,
    give ``s >= sum mu (row(theta))`` for every feasible ``(theta, s)``, hence
    ``s* >= min_theta sum mu row(theta)`` (weak duality, minimised over the box in
    closed form and rounded down). A single row (one or two inequalities, the common case of a
    streaming check) is solved without HiGHS, in closed form (`_solve_single_row`: the dual's one
    weight is maximised over its finitely many kinks); its witness and multipliers are re-checked
    exactly as HiGHS's are.
    """
    check_instance("rows", rows, IntervalRows)
    tol = as_positive_scalar("tolerance", tolerance)
    allowance = as_positive_scalar("rounding_allowance", rounding_allowance, allow_zero=True)
    scaled = _Scaled(rows, prior, allowance)
    d = rows.nparams
    t, s, mu = _solve_single_row(scaled) if rows.nrows == 1 else _solve(scaled, np.zeros(d), None)
    witness = np.clip(t * scaled.theta_scale, prior.low, prior.high)
    upper = float(max(np.max(scaled.needed(witness), initial=0.0), 0.0))
    lower = scaled.lower_bound(mu, np.zeros(d), 0.0, True) if mu.size else -np.inf
    certificate = None
    if lower > tol:
        mu_up, mu_lo = np.zeros(rows.nrows), np.zeros(rows.nrows)
        mu_up[scaled.row_of[scaled.side > 0]] = mu[scaled.side > 0]
        mu_lo[scaled.row_of[scaled.side < 0]] = mu[scaled.side < 0]
        certificate = IntervalCertificate(mu_up, mu_lo, lower, tol, allowance)
        status = "inconsistent"
    elif upper <= tol:
        status = "consistent"
    else:
        status = "inconclusive"
    margin = float(min(max(s, lower, 0.0), upper))
    return IntervalVerdict(status, witness, margin, upper, float(max(lower, -WITNESS_DEPTH)), certificate)


def _coordinates(coordinates, d: int) -> list[int]:
    """``coordinates`` as a list of ints in ``[0, d)``, or a typed error (no wrap-around of negatives)."""
    given = list(coordinates)
    values = np.asarray(given)
    if values.ndim != 1 or not (values.size == 0 or np.issubdtype(values.dtype, np.integer)):
        raise InputError(f"coordinates must be integers, got {given!r}")
    if np.any(values < 0) or np.any(values >= d):
        raise InputError(f"coordinates must lie in [0, {d}), got {values.tolist()}")
    return [int(c) for c in values]


def interval_parameter_box(
    rows: IntervalRows,
    prior: Box,
    *,
    tolerance: float = INTERVAL_ELIMINATION_MARGIN,
    rounding_allowance: float = INTERVAL_ROUNDING_ALLOWANCE,
    verdict: IntervalVerdict | None = None,
    coordinates=None,
) -> Box:
    """The bounding box of the prior's parameters that explain every interval row.

    Parameters
    ----------
    rows : IntervalRows
        The rows.
    prior : Box
        The prior parameter box.
    tolerance, rounding_allowance : float
        As in `interval_consistency`.
    verdict : IntervalVerdict, optional
        The verdict of `interval_consistency` on the same rows, if known (saves an LP).
    coordinates : iterable of int, optional
        Bound only these coordinates, each in ``[0, d)`` (the others keep the prior's
        sides); default all.

    Returns
    -------
    Box
        Contains every parameter of the prior that explains every row (with the rows
        relaxed by the allowances); a sub-box of the prior.

    Raises
    ------
    NoConsistentModel
        If the rows are proven inconsistent with the prior.
    SolverFailure
        If HiGHS returns any status but optimal.
    InputError, DimensionError
        Coordinates that are not integers in ``[0, d)``, or a verdict whose witness is not of size d.

    Notes
    -----
    Up to 2d LPs, minimising and maximising each theta_i with every row relaxed by
    ``max(rounding_allowance, INTERVAL_BOX_ALLOWANCE)`` plus the margin the witness
    needs (0 when consistent; at most the tolerance otherwise). Each side is the
    weak-duality bound recomputed with numpy from HiGHS's multipliers, rounded outward
    by one ulp and intersected with the prior, so it is sound whatever HiGHS's accuracy.
    A side is not solved for when the prior's own side is attained: the verdict's witness,
    moved onto that side along theta_i, meets every relaxed row in exact arithmetic (checked
    with numpy and a rounding error bound). The LP's optimum is then the prior's side, and
    its rounded-down weak-duality bound lies below it, so the LP would return the prior's
    side too: the box is the same either way, bit for bit. In the traffic learner's rows
    most sides are the prior's (the data bound few parameters): this skips 1,271 of 1,412
    LPs at the T-junction and 318 of 408 on the highway (`benchmarks/bench_interval_rows.py`).
    """
    check_instance("rows", rows, IntervalRows)
    d = rows.nparams
    indices = list(range(d)) if coordinates is None else _coordinates(coordinates, d)
    if verdict is None:
        verdict = interval_consistency(rows, prior, tolerance=tolerance, rounding_allowance=rounding_allowance)
    else:
        check_instance("verdict", verdict, IntervalVerdict)
        if verdict.witness.shape != (d,):
            raise DimensionError(
                f"verdict.witness has shape {verdict.witness.shape}, but the rows have {d} parameters: "
                "a verdict of other rows"
            )
    if verdict.eliminated:
        raise NoConsistentModel("the interval rows are proven inconsistent with the prior box")
    allowance = max(float(rounding_allowance), INTERVAL_BOX_ALLOWANCE)
    scaled = _Scaled(rows, prior, allowance)
    slack = float(max(verdict.upper, 0.0))
    low, high = prior.low.copy(), prior.high.copy()
    if scaled.a.shape[0] == 0:
        return Box(low, high)
    witness = verdict.witness / scaled.theta_scale
    for i in indices:
        for sign in (1.0, -1.0):
            # the side is the prior's if the witness moved onto it along theta_i still meets every row
            attained = witness.copy()
            attained[i] = scaled.low[i] if sign > 0 else scaled.high[i]
            if _meets_every_inequality(scaled, attained, slack):
                continue
            objective = np.zeros(d)
            objective[i] = sign
            _, _, mu = _solve(scaled, objective, slack)
            bound = scaled.lower_bound(mu, objective, slack, False) * scaled.theta_scale[i]
            if sign > 0:
                low[i] = max(low[i], np.nextafter(bound, -np.inf))
            else:
                high[i] = min(high[i], np.nextafter(-bound, np.inf))
    if np.any(low > high):
        raise SolverFailure(
            f"parameter bounds crossed (low {low.tolist()}, high {high.tolist()}) although the rows are consistent"
        )
    return Box(low, high)
