"""Constraint generation and the weak-duality bound (internal to `minimaxplan.verify`).

Few of the ``2 p N`` rows of a margin LP are active, so `generate` solves the LP on a
subset of transitions, checks every row vectorised in numpy, adds the most violated and
repeats; the last round takes every row. `lagrangian_bound` turns the multipliers of a
subset into a lower bound on the full LP's optimum, recomputed with numpy and
independent of HiGHS's tolerances.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._highs import LPSolution, solve_lp
from ._regression import EPS, HypothesisData

__all__ = ["GENERATION_TOLERANCE", "lagrangian_bound", "Generated", "generate", "initial_rows"]

#: A row counts as violated in constraint generation if it needs a margin larger than
#: the current one by more than this.
GENERATION_TOLERANCE = 1e-9


def lagrangian_bound(
    data: HypothesisData,
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
    beta = data.beta[idx]
    if s_fixed is None:
        total = float(np.sum(nu * beta))
        if total > 1.0 - 1e-12:  # keep the s coefficient 1 - total > 0 despite rounding in total
            scale = (1.0 - 1e-12) / total
            mu, nu = mu * scale, nu * scale
        slack = data.e[idx]
    else:
        slack = data.e[idx] + s_fixed * beta
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
        + np.sum(
            np.abs(np.einsum("npi,np->i", np.abs(data.E[idx]), np.abs(mu)))
            * np.maximum(np.abs(data.theta_low), np.abs(data.theta_high))
        )
    )
    return float(sum(terms)) - 4 * (mu.size + data.nparams + 10) * EPS * float(magnitude)


@dataclass
class Generated:
    """The outcome of `generate`: the last LP's solution, its rows, and bounds on the optimum."""

    solution: LPSolution
    active: np.ndarray
    rounds: int
    upper: float  # a certified upper bound on the LP optimum (margin problems) / 0
    lower: float  # the Lagrangian lower bound


def generate(
    data: HypothesisData,
    objective: np.ndarray,
    s_fixed: float | None,
    initial: np.ndarray,
    *,
    max_rounds: int,
) -> Generated:
    """Constraint generation: solve on a subset, add the most violated transitions, repeat.

    The number added per round doubles, so that even when many transitions are
    undecided (general D, see `HypothesisData.needed_margin`) the rounds stay few.
    """
    n, d = data.ntransitions, data.nparams
    batch = max(8, 4 * (d + 1))
    active = np.unique(np.asarray(initial, dtype=int))
    rounds = 0
    while True:
        last = rounds >= max_rounds or active.size == n
        if last:
            active = np.arange(n)
        sol = solve_lp(data, active, objective, s_fixed)
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
    if data.exact_margins or sol.w is None:
        upper = float(np.max(needed_all, initial=0.0))
    else:
        on_active = data.needed_margin_with(sol.theta, sol.w, active)
        upper = float(max(np.max(on_active, initial=0.0), np.max(needed, initial=0.0)))
    lower = lagrangian_bound(data, active, sol.y_upper, sol.y_lower, objective, s_fixed)
    return Generated(sol, active, rounds, upper, lower)


def initial_rows(data: HypothesisData) -> np.ndarray:
    """Start from the transitions the prior box's centre explains worst."""
    count = max(8, 4 * (data.nparams + 1))
    needed = data.needed_margin((data.theta_low + data.theta_high) / 2)
    if needed.size <= count:
        return np.arange(needed.size)
    return np.argpartition(-needed, count - 1)[:count]
