"""The HiGHS boundary of model elimination (internal to `minimaxplan.verify`).

The only place that calls `scipy.optimize.linprog`: it builds the sparse LP over a
subset of transitions, maps every HiGHS status to a named case (optimal is the only
success; anything else raises `SolverFailure`) and returns the solution with its dual
multipliers as plain arrays.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog

from minimaxplan.models.errors import SolverFailure

from ._regression import HypothesisData

__all__ = ["HIGHS_OPTIONS", "MARGIN_COLUMN_FLOOR", "LinprogStatus", "LPSolution", "solve_lp"]

#: Feasibility tolerances passed to HiGHS (the decisions do not rely on them: every
#: verdict is re-derived from the multipliers with numpy, see `lagrangian_bound`).
HIGHS_OPTIONS = {"primal_feasibility_tolerance": 1e-9, "dual_feasibility_tolerance": 1e-9}


class LinprogStatus(IntEnum):
    """The status codes of `scipy.optimize.linprog` (``OptimizeResult.status``)."""

    OPTIMAL = 0
    ITERATION_LIMIT = 1
    INFEASIBLE = 2
    UNBOUNDED = 3
    NUMERICAL_DIFFICULTIES = 4

    @property
    def reason(self) -> str:
        """The status in words, as used in error messages."""
        return _REASONS[self]


_REASONS = {
    LinprogStatus.OPTIMAL: "optimal",
    LinprogStatus.ITERATION_LIMIT: "iteration limit reached",
    LinprogStatus.INFEASIBLE: "infeasible",
    LinprogStatus.UNBOUNDED: "unbounded",
    LinprogStatus.NUMERICAL_DIFFICULTIES: "numerical difficulties",
}


def _reason(status: int) -> str:
    try:
        return LinprogStatus(status).reason
    except ValueError:
        return f"unknown status {status}"


@dataclass
class LPSolution:
    """An optimal solution of `solve_lp`, in the original units.

    Attributes
    ----------
    theta : numpy.ndarray
        Shape (d,), the parameter.
    s : float
        The margin (dimensionless; the fixed one when the LP had s fixed).
    w : numpy.ndarray or None
        Shape (k, r), the disturbances of the rows' transitions (general form only).
    y_upper, y_lower : numpy.ndarray
        Shape (k, p), multipliers >= 0 of the original (unscaled) rows
        ``z - E theta - D w >= -(e + s beta)`` and ``z - E theta - D w <= e + s beta``.
    """

    theta: np.ndarray
    s: float
    w: np.ndarray | None
    y_upper: np.ndarray
    y_lower: np.ndarray


#: In the scaled LP, the coefficients of the margin column are at least this (relative
#: to the largest): smaller ones would be dropped by HiGHS, which could make the margin
#: LP infeasible. Raising them is a relaxation; the decisions do not rely on it (they
#: use `lagrangian_bound` with the true coefficients).
MARGIN_COLUMN_FLOOR = 1e-7


def solve_lp(data: HypothesisData, idx: np.ndarray, objective: np.ndarray, s_fixed: float | None) -> LPSolution:
    """Solve the LP over the rows of transitions ``idx`` with HiGHS, equilibrated.

    Parameters
    ----------
    data : HypothesisData
        The regression of one hypothesis.
    idx : numpy.ndarray
        Shape (k,), the transitions whose rows are in the LP.
    objective : numpy.ndarray
        Shape (d,), the linear objective on theta (dimensionless weights).
    s_fixed : float or None
        None: s is a variable and ``s`` is added to the objective (the margin LP);
        otherwise the margin is fixed at this value (the parameter-bound LPs).

    Returns
    -------
    LPSolution
        The solution and the multipliers of the original rows.

    Raises
    ------
    SolverFailure
        HiGHS returned any status but optimal, or non-finite values.

    Notes
    -----
    Variables: theta (d), then s (unless ``s_fixed``), then w_n (r each) unless ``D W``
    is a box, in which case w is eliminated exactly: ``D w_n`` ranges over
    ``hull_center +- hull_radius``. The LP handed to HiGHS is equilibrated: every row is
    divided by its natural magnitude ``data.scale`` (which scales like its state
    coordinate), theta_j by the largest modulus of its prior, w_j by the largest
    modulus of W, s by the largest coefficient of its column, and the objective by its
    largest entry. In a change of units ``x -> S x``, ``u -> R u`` applied to the data
    and the hypothesis alike, the scaled LP is the same up to rounding, so its solution
    is too. The solution and the multipliers are mapped back to the original rows
    (``y = y_scaled * kappa / rho``).
    """
    k, p, d = len(idx), data.nstates, data.nparams
    rho = data.scale[idx].reshape(-1)
    E = data.E[idx].reshape(k * p, d) * (data.theta_scale / rho[:, None])
    z, e = data.z[idx].reshape(-1) / rho, data.e[idx].reshape(-1) / rho
    beta = data.beta[idx].reshape(-1) / rho
    free_s = s_fixed is None
    slack = e if s_fixed is None else e + s_fixed * beta
    columns_up = [sp.csr_matrix(E)]
    columns_lo = [sp.csr_matrix(-E)]
    cost = [objective * data.theta_scale]
    bounds = [np.column_stack([data.theta_low, data.theta_high]) / data.theta_scale[:, None]]
    # the margin variable is s * sigma, so that its column's largest entry is 1
    sigma = float(np.max(beta)) if beta.size else 1.0
    if free_s:
        column = np.maximum(beta / sigma, MARGIN_COLUMN_FLOOR)
        columns_up.append(sp.csr_matrix(-column[:, None]))
        columns_lo.append(sp.csr_matrix(-column[:, None]))
        cost.append(np.array([1.0 / sigma]))
        bounds.append(np.array([[0.0, np.inf]]))
    if data.d_pinv is None:
        center = np.tile(data.hull_center, k) / rho
        radius = np.tile(data.hull_radius, k) / rho
        b_up = z - center + radius + slack
        b_lo = center + radius + slack - z
    else:
        r = data.D.shape[1]
        block = sp.kron(sp.identity(k, format="csr"), sp.csr_matrix(data.D * data.w_scale), format="csr")
        block = sp.diags(1.0 / rho) @ block
        columns_up.append(block)
        columns_lo.append(-block)
        cost.append(np.zeros(k * r))
        w_low, w_high = data.w_center - data.w_radius, data.w_center + data.w_radius
        bounds.append(np.column_stack([np.tile(w_low / data.w_scale, k), np.tile(w_high / data.w_scale, k)]))
        b_up = z + slack
        b_lo = slack - z
    c = np.concatenate(cost)
    kappa = float(np.max(np.abs(c))) if np.any(c) else 1.0
    A_ub = sp.vstack([sp.hstack(columns_up), sp.hstack(columns_lo)], format="csr")
    b_ub = np.concatenate([b_up, b_lo])
    res = linprog(c / kappa, A_ub=A_ub, b_ub=b_ub, bounds=np.vstack(bounds), method="highs", options=HIGHS_OPTIONS)
    if res.status != LinprogStatus.OPTIMAL:
        what = "margin LP" if free_s else "parameter-bound LP"
        raise SolverFailure(
            f"HiGHS failed on the {what} over {k} transitions: status {res.status} ({_reason(res.status)}): {res.message}"
            + (
                " -- this LP is always feasible in exact arithmetic, so this is a numerical failure"
                if res.status == LinprogStatus.INFEASIBLE
                else ""
            )
        )
    x = np.asarray(res.x, dtype=float)
    y = np.maximum(-np.asarray(res.ineqlin.marginals, dtype=float), 0.0) * (kappa / np.tile(rho, 2))
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise SolverFailure(f"HiGHS returned non-finite values on the LP over {k} transitions")
    theta = x[:d] * data.theta_scale
    s = float(x[d]) / sigma if s_fixed is None else float(s_fixed)
    offset = d + (1 if free_s else 0)
    w = None if data.d_pinv is None else x[offset:].reshape(k, -1) * data.w_scale
    return LPSolution(theta, s, w, y[: k * p].reshape(k, p), y[k * p :].reshape(k, p))
