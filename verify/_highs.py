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

__all__ = ["HIGHS_OPTIONS", "LinprogStatus", "LPSolution", "solve_lp"]

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
    """An optimal solution of `solve_lp`: parameter, margin, disturbances and row multipliers."""

    theta: np.ndarray
    s: float
    w: np.ndarray | None  # (k, r) disturbances of the rows' transitions (general form only)
    y_upper: np.ndarray  # (k, p) multipliers of the rows  z - E theta - D w >= -(e + s beta)
    y_lower: np.ndarray  # (k, p) multipliers of the rows  z - E theta - D w <=  (e + s beta)


def solve_lp(data: HypothesisData, idx: np.ndarray, objective: np.ndarray, s_fixed: float | None) -> LPSolution:
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
    res = linprog(np.concatenate(cost), A_ub=A_ub, b_ub=b_ub, bounds=np.vstack(bounds), method="highs", options=HIGHS_OPTIONS)
    if res.status != LinprogStatus.OPTIMAL:
        what = "margin LP" if free_s else "parameter-bound LP"
        raise SolverFailure(
            f"HiGHS failed on the {what} over {k} transitions: status {res.status} ({_reason(res.status)}): {res.message}"
            + (" -- this LP is always feasible in exact arithmetic, so this is a numerical failure"
               if res.status == LinprogStatus.INFEASIBLE else "")
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
    return LPSolution(theta, s, w, y[: k * p].reshape(k, p), y[k * p :].reshape(k, p))
