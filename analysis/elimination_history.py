"""How model elimination and parameter sets evolve as data arrives (for notebooks and reports).

`elimination_history` reruns `eliminate_models` on growing prefixes of one trajectory
and records, for every hypothesis, whether it survives and its inconsistency margin.
`parameter_set_history` records, for one hypothesis, the feasible parameter box
(`feasible_parameter_box`) next to the bounding box of the confidence ellipsoid
(`ConfidenceEllipsoidEstimator`), on the same prefixes. `first_inconsistency` explains
one elimination: the first transition at which the data became inconsistent (found by
bisection on prefixes, each verdict proven as `eliminate_models` proves it), the state
component that the re-checked dual witness of that prefix rests on, and the margin in
that state's units.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from minimaxplan.models import Box, ConfidenceEllipsoidEstimator, InputError, UncertainLinearSystem
from minimaxplan.models.errors import SolverFailure
from minimaxplan.models.validation import (
    as_count,
    as_finite_array,
    as_positive_scalar,
    check_instance,
    check_shape,
)
from minimaxplan.verify import EliminationCertificate, eliminate_models, feasible_parameter_box
from minimaxplan.verify.selection import measurement_noise_bound

__all__ = [
    "EliminationHistory",
    "ParameterSetHistory",
    "InconsistencyExplanation",
    "elimination_history",
    "parameter_set_history",
    "first_inconsistency",
    "margin_sample_sizes",
    "UNREACHABLE_RADIUS",
]

#: A state coordinate whose disturbance-and-noise radius ``(|D| r_w + noise)_j`` is at
#: most this (state units) cannot be reached by the disturbance: the hypothesis states an
#: exact equation for it, and data that contradicts it is "contradicted exactly". The
#: same threshold as the LP's (`minimaxplan.verify` treats such radii as 0).
UNREACHABLE_RADIUS = 1e-150


@dataclass(frozen=True, eq=False)
class EliminationHistory:
    """Verdicts of `eliminate_models` on the first N transitions, for each N in ``sample_sizes``.

    Attributes
    ----------
    names
        The hypotheses' names (M of them).
    sample_sizes
        The prefix lengths N, increasing, shape (K,).
    margins
        Shape (M, K): the inconsistency margin of hypothesis m on the first N transitions
        (0 when consistent; see `eliminate_models`).
    survives
        Shape (M, K), bool: hypothesis m survives the first N transitions.
    """

    names: tuple[str, ...]
    sample_sizes: np.ndarray
    margins: np.ndarray
    survives: np.ndarray

    def first_elimination(self) -> dict[str, int | None]:
        """Per hypothesis, the smallest recorded N at which it is eliminated (None if never)."""
        out = {}
        for name, row in zip(self.names, self.survives):
            out[name] = int(self.sample_sizes[np.argmin(row)]) if not row.all() else None
        return out

    def to_dict(self) -> dict:
        """The history as a dict of plain Python values (nested lists for the arrays), for JSON."""
        return {
            "names": list(self.names),
            "sample_sizes": self.sample_sizes.tolist(),
            "margins": self.margins.tolist(),
            "survives": self.survives.tolist(),
        }


@dataclass(frozen=True, eq=False)
class ParameterSetHistory:
    """Parameter sets of one hypothesis on the first N transitions, for each N in ``sample_sizes``.

    Attributes
    ----------
    sample_sizes
        Shape (K,).
    feasible_low, feasible_high
        Shape (K, d): the box bounding the parameters consistent with the data (set
        membership: holds the true parameter whenever the disturbances respect their box).
    confidence_low, confidence_high
        Shape (K, d): the bounding box of the confidence ellipsoid (holds the true
        parameter with probability at least ``1 - delta`` under sub-Gaussian noise).
    prior
        The hypothesis's prior parameter box.
    """

    sample_sizes: np.ndarray
    feasible_low: np.ndarray
    feasible_high: np.ndarray
    confidence_low: np.ndarray
    confidence_high: np.ndarray
    prior: Box

    def to_dict(self) -> dict:
        """The history as a dict of plain Python values (nested lists, the prior as `Box.to_dict`), for JSON."""
        return {
            "sample_sizes": self.sample_sizes.tolist(),
            "feasible_low": self.feasible_low.tolist(),
            "feasible_high": self.feasible_high.tolist(),
            "confidence_low": self.confidence_low.tolist(),
            "confidence_high": self.confidence_high.tolist(),
            "prior": self.prior.to_dict(),
        }


def _check_sample_sizes(sample_sizes, ntransitions: int) -> np.ndarray:
    sizes = np.asarray(sample_sizes)
    if sizes.ndim != 1 or sizes.size == 0 or sizes.dtype.kind not in "iu":
        raise InputError(f"sample_sizes must be a non-empty 1-dimensional array of integers, got {sizes!r}")
    if np.any(np.diff(sizes) <= 0) or sizes[0] < 0 or sizes[-1] > ntransitions:
        raise InputError(
            f"sample_sizes must increase strictly within [0, {ntransitions}] (the number of transitions), "
            f"got {sizes.tolist()}"
        )
    return sizes.astype(int)


def _check_trajectory(states, controls, p: int, q: int) -> tuple[np.ndarray, np.ndarray]:
    X = as_finite_array("states", states, (None, p))
    U = as_finite_array("controls", controls, (X.shape[0] - 1, q))
    return X, U


def elimination_history(
    hypotheses: Sequence[UncertainLinearSystem],
    states,
    controls,
    sample_sizes,
    *,
    names: Sequence[str] | None = None,
    measurement_noise=None,
) -> EliminationHistory:
    """Run `eliminate_models` on ``states[:N+1], controls[:N]`` for each N in ``sample_sizes``.

    Parameters
    ----------
    hypotheses
        The competing `UncertainLinearSystem` s.
    states, controls
        One trajectory, shapes (N+1, p) and (N, q).
    sample_sizes
        Strictly increasing prefix lengths in [0, N].
    names
        The hypotheses' names (default ``"0"``, ``"1"``, ...).
    measurement_noise
        As in `eliminate_models`.
    """
    hypotheses = list(hypotheses)
    if not hypotheses:
        raise InputError("hypotheses must hold at least one UncertainLinearSystem, got none")
    X, U = _check_trajectory(states, controls, hypotheses[0].nstates, hypotheses[0].ninputs)
    sizes = _check_sample_sizes(sample_sizes, U.shape[0])
    names = tuple(str(i) for i in range(len(hypotheses))) if names is None else tuple(names)
    if len(names) != len(hypotheses):
        raise InputError(f"names must have one entry per hypothesis ({len(hypotheses)}), got {len(names)}")
    margins = np.empty((len(hypotheses), sizes.size))
    survives = np.empty((len(hypotheses), sizes.size), dtype=bool)
    for k, n in enumerate(sizes):
        result = eliminate_models(hypotheses, X[: n + 1], U[:n], measurement_noise=measurement_noise)
        margins[:, k] = result.margins
        survives[:, k] = [m in result.survivors for m in range(len(hypotheses))]
    return EliminationHistory(names, sizes, margins, survives)


def parameter_set_history(
    hypothesis: UncertainLinearSystem,
    states,
    controls,
    sample_sizes,
    *,
    sigma: float,
    lam: float = 1.0,
    delta: float = 0.1,
    bound: float | None = None,
    measurement_noise=None,
) -> ParameterSetHistory:
    """Feasible parameter box and confidence-ellipsoid bounding box on growing prefixes.

    Parameters
    ----------
    hypothesis
        A hypothesis consistent with the whole trajectory (else `feasible_parameter_box`
        raises `NoConsistentModel`).
    states, controls, sample_sizes, measurement_noise
        As in `elimination_history`.
    sigma, lam, delta
        As in `ConfidenceEllipsoidEstimator`; ``sigma`` is the sub-Gaussian scale of each
        entry of ``D w`` (a zero-mean noise bounded by c in absolute value is
        c-sub-Gaussian).
    bound
        A bound on ``||theta*||_2``; default the largest norm over the prior box, which
        holds the true parameter by assumption.

    Notes
    -----
    The estimator fits ``y_n = E_n theta + D w_n`` with ``E_n = regressor(x_n)`` and
    ``y_n = x_{n+1} - A0 x_n - B u_n`` (eq. (2)), one rank-one update per transition.
    """
    check_instance("hypothesis", hypothesis, UncertainLinearSystem)
    X, U = _check_trajectory(states, controls, hypothesis.nstates, hypothesis.ninputs)
    sizes = _check_sample_sizes(sample_sizes, U.shape[0])
    prior = hypothesis.theta
    if bound is None:
        bound = float(np.linalg.norm(np.maximum(np.abs(prior.low), np.abs(prior.high))))
    bound = as_positive_scalar("bound", bound)
    estimator = ConfidenceEllipsoidEstimator(hypothesis.nparams, sigma=sigma, lam=lam, delta=delta, bound=bound)
    regressors = hypothesis.regressor(X[:-1])
    targets = X[1:] - X[:-1] @ hypothesis.A0.T - U @ hypothesis.B.T
    check_shape("targets", targets, (U.shape[0], hypothesis.nstates))
    d = hypothesis.nparams
    feasible = np.empty((2, sizes.size, d))
    confidence = np.empty((2, sizes.size, d))
    fed = 0
    for k, n in enumerate(sizes):
        for i in range(fed, n):
            estimator.update(regressors[i], targets[i])
        fed = n
        box = feasible_parameter_box(hypothesis, X[: n + 1], U[:n], measurement_noise=measurement_noise)
        feasible[0, k], feasible[1, k] = box.low, box.high
        ellipsoid_box = estimator.ellipsoid().bounding_box()
        confidence[0, k], confidence[1, k] = ellipsoid_box.low, ellipsoid_box.high
    return ParameterSetHistory(sizes, feasible[0], feasible[1], confidence[0], confidence[1], prior)


# ------------------------------------------------------------ explaining a verdict
@dataclass(frozen=True, eq=False)
class InconsistencyExplanation:
    """Where the data first contradicts one hypothesis, which state it contradicts, and by how much.

    Attributes
    ----------
    hypothesis
        Index of the hypothesis (in the list its caller holds).
    name
        Its name.
    first_transition
        The smallest n such that transitions ``0..n`` already contradict the hypothesis:
        `eliminate_models` eliminates it on them (with a certificate), and keeps it on
        transitions ``0..n-1``.
    certificate
        The `EliminationCertificate` of transitions ``0..n`` (its transition indices are
        those of the whole trajectory).
    recheck_bound
        The certificate's lower bound on the margin, recomputed from the data of that
        prefix with `EliminationCertificate.recheck` (it exceeds the tolerance).
    prefix_margin
        The inconsistency margin of transitions ``0..n`` (dimensionless: the inflation
        of the disturbance set, in units of its radius).
    margin
        The inconsistency margin of the whole trajectory (dimensionless).
    unit_radius
        Shape (p,), state units: the radius ``(|D| r_w)_j + ebar_j`` of the interval hull
        of the disturbance set plus the measurement-noise term, per state. A margin s on
        state j means that its disturbance bound would have to grow by ``s *
        unit_radius[j]`` to explain the data; 0 (at most `UNREACHABLE_RADIUS`) where
        neither the disturbance nor noise reaches the state.
    weights
        Shape (p,), summing to 1: the share of the dual witness's weight carried by each
        state component, each row's multiplier times that row's inflation unit (the
        ``beta`` of the margin LP), which does not depend on the units.
    violated
        The state component with the largest share: the one the witness rests on.
    prefixes_checked
        How many prefixes the bisection solved (each one call of `eliminate_models`).

    Notes
    -----
    The model elimination of Section III (ref. [48] of the paper): the hypothesis is
    eliminated on the prefix only on a weak-duality certificate recomputed with numpy.
    """

    hypothesis: int
    name: str
    first_transition: int
    certificate: EliminationCertificate
    recheck_bound: float
    prefix_margin: float
    margin: float
    unit_radius: np.ndarray
    weights: np.ndarray
    violated: int
    prefixes_checked: int

    def __post_init__(self) -> None:
        for key in ("unit_radius", "weights"):
            value = np.array(getattr(self, key), dtype=float, copy=True)
            value.setflags(write=False)
            object.__setattr__(self, key, value)

    @property
    def reachable(self) -> np.ndarray:
        """Shape (p,), bool: the states that the disturbance or the measurement noise reaches."""
        return self.unit_radius > UNREACHABLE_RADIUS

    @property
    def exact(self) -> bool:
        """True iff the violated state is unreachable: the data contradicts an exact equation of the hypothesis."""
        return not bool(self.reachable[self.violated])

    def margin_in_state_units(self, which: str = "full") -> np.ndarray:
        """The margin as a disturbance excess per state, in state units.

        Parameters
        ----------
        which : {"full", "prefix"}
            The margin of the whole trajectory or of transitions ``0..first_transition``.

        Returns
        -------
        numpy.ndarray
            Shape (p,): ``margin * unit_radius``; NaN at the unreachable states (where
            any contradiction is exact and no disturbance excess explains it).
        """
        if which not in ("full", "prefix"):
            raise InputError(f"which must be 'full' or 'prefix', got {which!r}")
        s = self.margin if which == "full" else self.prefix_margin
        return np.where(self.reachable, s * self.unit_radius, np.nan)

    def to_dict(self) -> dict:
        """A JSON-ready dictionary (NaN written as None)."""

        def plain(values: np.ndarray) -> list:
            return [None if not np.isfinite(v) else float(v) for v in values]

        return {
            "hypothesis": self.hypothesis,
            "name": self.name,
            "first_transition": self.first_transition,
            "violated_state": self.violated,
            "contradicted_exactly": self.exact,
            "state_weights": self.weights.tolist(),
            "reachable_states": self.reachable.tolist(),
            "unit_radius": self.unit_radius.tolist(),
            "prefix_margin": self.prefix_margin,
            "margin": self.margin,
            "prefix_margin_in_state_units": plain(self.margin_in_state_units("prefix")),
            "margin_in_state_units": plain(self.margin_in_state_units("full")),
            "recheck_bound": self.recheck_bound,
            "witness_transitions": self.certificate.transitions.tolist(),
            "prefixes_checked": self.prefixes_checked,
            "certificate": self.certificate.to_dict(),
        }


def _row_units(hypothesis: UncertainLinearSystem, noise_bound: np.ndarray, X, U, Xn) -> np.ndarray:
    """The inflation unit ``beta`` (k, p) of the margin LP's rows for transitions (X, U, Xn).

    The disturbance-and-noise radius of the state where it is positive, else the row's
    natural magnitude ``|x+| + |A0| |x| + |B| |u| + |E(x)| theta_max + |D| w_max + ebar``
    (as documented in `eliminate_models`; both scale like the state).
    """
    theta_max = np.maximum(np.abs(hypothesis.theta.low), np.abs(hypothesis.theta.high))
    w_max = np.maximum(np.abs(hypothesis.w.low), np.abs(hypothesis.w.high))
    unit = np.abs(hypothesis.D) @ hypothesis.w.radius + noise_bound
    abs_x = np.abs(X)
    magnitude = (
        np.abs(Xn)
        + abs_x @ np.abs(hypothesis.A0).T
        + np.abs(U) @ np.abs(hypothesis.B).T
        + abs_x @ np.tensordot(theta_max, np.abs(hypothesis.phi), 1).T
        + (np.abs(hypothesis.D) @ w_max + noise_bound)
    )
    return np.where(unit > UNREACHABLE_RADIUS, unit, np.where(magnitude > 0, magnitude, 1.0))


def first_inconsistency(
    hypothesis: UncertainLinearSystem,
    states,
    controls,
    *,
    index: int = 0,
    name: str | None = None,
    measurement_noise=None,
) -> InconsistencyExplanation | None:
    """The first transition at which a trajectory contradicts a hypothesis, and why.

    Parameters
    ----------
    hypothesis : UncertainLinearSystem
        The hypothesis.
    states : array_like
        Shape (N+1, p), the observed states (state units).
    controls : array_like
        Shape (N, q), the controls applied.
    index : int
        The hypothesis's index, recorded in the result.
    name : str, optional
        Its name (default ``str(index)``).
    measurement_noise : array_like, optional
        As in `eliminate_models`.

    Returns
    -------
    InconsistencyExplanation or None
        None if `eliminate_models` keeps the hypothesis on the whole trajectory.

    Raises
    ------
    DimensionError, NonFiniteError
        Bad shapes or NaN/inf.
    SolverFailure
        If HiGHS fails, or (a bug) the certificate of the first inconsistent prefix does
        not survive its own re-check.

    Notes
    -----
    Bisection on the prefix length L (transitions ``0..L-1``): ``L = N`` eliminates,
    ``L = 0`` never does, and each probe is one call of `eliminate_models` on the
    prefix, so every verdict is proven as that function proves it (a weak-duality
    certificate recomputed with numpy), never read off the dual multipliers of the whole
    trajectory (whose transitions need not be the first). Adding transitions adds rows
    to the margin LP (Section III), so its optimum never decreases with L and the
    bisection finds the smallest L; the result reports a proven elimination at L and a
    kept hypothesis at ``L - 1``. About ``log2(N)`` LPs.
    """
    check_instance("hypothesis", hypothesis, UncertainLinearSystem)
    X, U = _check_trajectory(states, controls, hypothesis.nstates, hypothesis.ninputs)

    def probe(length: int):
        return eliminate_models([hypothesis], X[: length + 1], U[:length], measurement_noise=measurement_noise)

    total = U.shape[0]
    full = probe(total)
    if 0 not in full.eliminated:
        return None
    low, high, at_high, checked = 0, total, full, 1
    while high - low > 1:
        middle = (low + high) // 2
        result = probe(middle)
        checked += 1
        if 0 in result.eliminated:
            high, at_high = middle, result
        else:
            low = middle
    certificate = at_high.eliminated[0]
    bound = certificate.recheck(hypothesis, X[: high + 1], U[:high])
    if not bound > certificate.tolerance:
        raise SolverFailure(
            f"the certificate of transitions 0..{high - 1} re-checks to {bound:.6g}, not above its "
            f"tolerance {certificate.tolerance:g}"
        )
    noise_bound = measurement_noise_bound(hypothesis, measurement_noise)
    unit = np.abs(hypothesis.D) @ hypothesis.w.radius + noise_bound
    unit = np.where(unit > UNREACHABLE_RADIUS, unit, 0.0)
    t = certificate.transitions
    beta = _row_units(hypothesis, noise_bound, X[t], U[t], X[t + 1])
    weight = np.sum((certificate.multipliers_upper + certificate.multipliers_lower) * beta, axis=0)
    total_weight = float(np.sum(weight))
    weights = weight / total_weight if total_weight > 0 else np.full(weight.shape, 1.0 / weight.size)
    return InconsistencyExplanation(
        hypothesis=index,
        name=str(index) if name is None else str(name),
        first_transition=high - 1,
        certificate=certificate,
        recheck_bound=float(bound),
        prefix_margin=float(at_high.margins[0]),
        margin=float(full.margins[0]),
        unit_radius=unit,
        weights=weights,
        violated=int(np.argmax(weights)),
        prefixes_checked=checked,
    )


def margin_sample_sizes(ntransitions: int, firsts=(), *, count: int = 24) -> np.ndarray:
    """Prefix lengths for a margin-against-N plot: a geometric grid plus each elimination's jump.

    Parameters
    ----------
    ntransitions : int
        N, the length of the trajectory (>= 0).
    firsts : iterable of int
        First inconsistent transitions n (`InconsistencyExplanation.first_transition`):
        the prefix lengths n and n + 1 are included, so that the plot shows the jump.
    count : int
        Points of the geometric grid over [1, N].

    Returns
    -------
    numpy.ndarray
        Strictly increasing integers in [1, N] (empty if N = 0).
    """
    n = as_count("ntransitions", ntransitions, minimum=0)
    if n == 0:
        return np.zeros(0, dtype=int)
    grid = np.geomspace(1, n, as_count("count", count)).round().astype(int)
    extra = [k for f in firsts for k in (int(f), int(f) + 1)]
    sizes = np.unique(np.concatenate([grid, np.array(extra + [n], dtype=int)]))
    return sizes[(sizes >= 1) & (sizes <= n)]
