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

This module is the public API; the pieces live in `minimaxplan.verify.certificates`
(the result values) and the internal modules ``_regression`` (input checks, the
measurement-noise bound, the per-hypothesis regression data), ``_highs`` (the only
`linprog` call and its status map) and ``_generation`` (constraint generation and the
weak-duality bound).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from minimaxplan.models import Box, UncertainLinearSystem
from minimaxplan.models.errors import NoConsistentModel, SolverFailure
from minimaxplan.models.validation import as_count, as_finite_array, as_positive_scalar, check_instance

from ._generation import GENERATION_TOLERANCE, generate, initial_rows, lagrangian_bound
from ._regression import (
    HypothesisData,
    Structure,
    check_hypotheses,
    check_trajectory,
    measurement_noise_bound,
    noise_vector,
)
from .certificates import ELIMINATION_MARGIN, EliminationCertificate, SelectionResult

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

#: Relative size of the per-transition allowance for floating-point rounding in the
#: data and in the residuals (errs towards keeping hypotheses).
ROUNDING_ALLOWANCE = 1e-9
#: Constraint-generation rounds before the last round, which takes every row.
MAX_GENERATION_ROUNDS = 30
#: `feasible_parameter_box` bounds the parameters consistent with every row relaxed by
#: this much relative to the row's magnitude (a superset, so sound): a consistent set
#: that is nearly a point (w at its extremes) is otherwise thinner than HiGHS's
#: tolerances, and its presolve may declare it empty.
PARAMETER_BOX_ALLOWANCE = 1e-7


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
    data: HypothesisData,
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
    start = initial_rows(data) if initial is None else initial
    gen = generate(data, np.zeros(d), None, start, max_rounds=max_rounds)
    sol = gen.solution
    margin = min(max(sol.s, gen.lower, 0.0), gen.upper)
    certificate = None
    if gen.lower > tolerance:
        # Keep only the transitions with a multiplier: still a valid bound (fewer terms),
        # recomputed on exactly what the certificate stores.
        keep = np.flatnonzero(np.any((sol.y_upper > 0) | (sol.y_lower > 0), axis=1))
        transitions = gen.active[keep]
        lower = lagrangian_bound(data, transitions, sol.y_upper[keep], sol.y_lower[keep], np.zeros(d), None)
        if lower > tolerance:
            certificate = EliminationCertificate(
                hypothesis=index,
                margin=margin,
                lower_bound=lower,
                transitions=transitions,
                multipliers_upper=sol.y_upper[keep],
                multipliers_lower=sol.y_lower[keep],
                tolerance=tolerance,
                rounding_allowance=allowance,
                measurement_noise=noise,
            )
    return _Verdict(margin, gen.upper, gen.lower, sol.theta, gen.active, gen.rounds, certificate)


def _check_options(tolerance: float, rounding_allowance: float, max_rounds: int) -> tuple[float, float, int]:
    tol = as_positive_scalar("tolerance", tolerance)
    allowance = as_positive_scalar("rounding_allowance", rounding_allowance, allow_zero=True)
    return tol, allowance, as_count("max_rounds", max_rounds, minimum=0)


# --------------------------------------------------------------------------- API
def eliminate_models(
    hypotheses: Sequence[UncertainLinearSystem],
    states: ArrayLike,
    controls: ArrayLike,
    *,
    measurement_noise: ArrayLike | None = None,
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
    the noise bound) where it is positive, and elsewhere the row's natural magnitude
    (the sum of the moduli of its terms, see `HypothesisData`): both scale like their
    state coordinate, so the margin is dimensionless and does not depend on the units
    of x and u. The LPs are equilibrated before HiGHS solves them (rows by their
    magnitude, theta and w by their prior's, see `solve_lp`), so that a change of units
    ``x -> S x``, ``u -> R u`` applied to the data and to the hypothesis alike
    (``A0 -> S A0 S^-1``, ``phi_i -> S phi_i S^-1``, ``B -> S B R^-1``, ``D -> S D`` with
    W unchanged, ``v_bar -> S v_bar``; theta unchanged) leaves the LPs HiGHS solves the
    same up to rounding. The reported margin is HiGHS's optimum clipped to the certified
    interval ``[lower, upper]`` (upper: the margin the LP's theta achieves on every row,
    recomputed with numpy). For D = I without noise this is the
    inflation of W to ``[w_lo - s r_w, w_hi + s r_w]``. When ``D W`` is a box (every
    column of D with a nonzero disturbance radius has one nonzero entry, e.g. D = I or
    ``dt I``), w is eliminated exactly and the LP has d + 1 variables and 2 p N rows;
    otherwise the ``w_n`` are LP variables, and the rows of transitions outside the
    generated subset are checked exactly against the facets of the zonotope
    ``D W + box(e_n + s beta)`` (see ``_regression.zonotope_normals``; when it has more
    than ``MAX_FACET_NORMALS`` candidate facets, with the disturbance
    ``clip(pinv(D) residual, W)``, which only over-estimates their violation, so an
    undecided transition is simply added).

    The decision uses a weak-duality bound recomputed with numpy (see
    `EliminationCertificate`), so neither HiGHS's tolerances nor an early stop of
    constraint generation can eliminate a consistent hypothesis.
    """
    hyps = check_hypotheses(hypotheses)
    p, q = hyps[0].nstates, hyps[0].ninputs
    X, U, Xn = check_trajectory(states, controls, p, q)
    tol, allowance, rounds_cap = _check_options(tolerance, rounding_allowance, max_rounds)
    noise = noise_vector(measurement_noise, p)
    survivors, eliminated, margins, rounds = [], {}, [], []
    for m, hyp in enumerate(hyps):
        data = HypothesisData(Structure(hyp, measurement_noise_bound(hyp, noise), allowance), X, U, Xn)
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
    states: ArrayLike,
    controls: ArrayLike,
    *,
    measurement_noise: ArrayLike | None = None,
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
    a superset, hence still sound. The LPs are equilibrated as in `eliminate_models`,
    so the box does not depend on the units of x and u. Cost: the margin LP and the 2d
    bound LPs, each by constraint generation from the margin LP's active rows.
    """
    check_instance("hypothesis", hypothesis, UncertainLinearSystem)
    X, U, Xn = check_trajectory(states, controls, hypothesis.nstates, hypothesis.ninputs)
    tol, allowance, rounds_cap = _check_options(tolerance, rounding_allowance, max_rounds)
    noise = noise_vector(measurement_noise, hypothesis.nstates)
    data = HypothesisData(Structure(hypothesis, measurement_noise_bound(hypothesis, noise), allowance), X, U, Xn)
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
    data = HypothesisData(Structure(hypothesis, measurement_noise_bound(hypothesis, noise), box_allowance), X, U, Xn)
    d = data.nparams
    low, high = np.empty(d), np.empty(d)
    for i in range(d):
        for sign in (1.0, -1.0):
            objective = np.zeros(d)
            objective[i] = sign
            gen = generate(data, objective, s_box, verdict.active, max_rounds=rounds_cap)
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
        measurement_noise: ArrayLike | None = None,
        tolerance: float = ELIMINATION_MARGIN,
        rounding_allowance: float = ROUNDING_ALLOWANCE,
        max_rounds: int = MAX_GENERATION_ROUNDS,
    ) -> None:
        self._hypotheses = tuple(check_hypotheses(hypotheses))
        h0 = self._hypotheses[0]
        self._p, self._q = h0.nstates, h0.ninputs
        self._tolerance, self._allowance, self._max_rounds = _check_options(tolerance, rounding_allowance, max_rounds)
        self._noise = noise_vector(measurement_noise, self._p)
        self._structures = [
            Structure(h, measurement_noise_bound(h, self._noise), self._allowance) for h in self._hypotheses
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
        """The hypotheses, in the order given (indices of `survivors` refer to it)."""
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
        """The number of transitions added so far."""
        return self._count

    @property
    def solves(self) -> int:
        """How many margin LPs were re-solved (the rest were settled by the O(p d) check)."""
        return self._solves

    def transitions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Copies of the stored (states, controls, next_states), shapes (N, p), (N, q), (N, p)."""
        n = self._count
        return self._X[:n].copy(), self._U[:n].copy(), self._Xn[:n].copy()

    def add(self, state: ArrayLike, control: ArrayLike, next_state: ArrayLike) -> list[int]:
        """Record the transition (state, control) -> next_state; return the survivors.

        Parameters
        ----------
        state : array_like
            Shape (p,), the observed state x_n (state units).
        control : array_like
            Shape (q,), the control u_n applied (input units).
        next_state : array_like
            Shape (p,), the observed next state x_{n+1}.

        Returns
        -------
        list of int
            Indices of the hypotheses not eliminated so far, increasing.

        Raises
        ------
        DimensionError, NonFiniteError
            Wrong shapes or NaN/inf (nothing is recorded then).
        SolverFailure
            HiGHS failed on a re-solve.
        """
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
            one = HypothesisData(self._structures[m], x[None], u[None], xn[None])
            needed = float(one.needed_margin(self._theta[m])[0])
            if max(self._upper[m], needed) <= self._tolerance:
                self._upper[m] = max(self._upper[m], needed, 0.0)
                continue
            self._resolve(m, n)
        return self.survivors

    def _resolve(self, m: int, newest: int) -> None:
        n = self._count
        data = HypothesisData(self._structures[m], self._X[:n], self._U[:n], self._Xn[:n])
        initial = np.union1d(self._active[m], [newest])
        verdict = _decide(
            m,
            data,
            initial=initial,
            tolerance=self._tolerance,
            max_rounds=self._max_rounds,
            allowance=self._allowance,
            noise=self._noise,
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
