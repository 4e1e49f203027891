"""How model elimination and parameter sets evolve as data arrives (for notebooks and reports).

`elimination_history` reruns `eliminate_models` on growing prefixes of one trajectory
and records, for every hypothesis, whether it survives and its inconsistency margin.
`parameter_set_history` records, for one hypothesis, the feasible parameter box
(`feasible_parameter_box`) next to the bounding box of the confidence ellipsoid
(`ConfidenceEllipsoidEstimator`), on the same prefixes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from minimaxplan.models import Box, ConfidenceEllipsoidEstimator, InputError, UncertainLinearSystem
from minimaxplan.models.validation import as_finite_array, as_positive_scalar, check_instance, check_shape
from minimaxplan.verify import eliminate_models, feasible_parameter_box

__all__ = ["EliminationHistory", "ParameterSetHistory", "elimination_history", "parameter_set_history"]


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
