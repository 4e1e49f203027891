"""The results of model elimination: certificates of inconsistency and the verdicts.

An `EliminationCertificate` carries the dual multipliers that prove a hypothesis
inconsistent with the data, and re-checks them with numpy; a `SelectionResult` holds
the verdict on every hypothesis. Both are returned by `minimaxplan.verify.selection`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from minimaxplan.models import UncertainLinearSystem
from minimaxplan.models.errors import DimensionError
from minimaxplan.models.validation import as_finite_array, check_instance, check_shape, frozen_copy

from ._generation import lagrangian_bound
from ._regression import HypothesisData, Structure, check_trajectory, measurement_noise_bound

__all__ = ["ELIMINATION_MARGIN", "EliminationCertificate", "SelectionResult"]

#: A hypothesis is eliminated only if the certified lower bound on its inconsistency
#: margin exceeds this (the margin is in units of the disturbance set's radius).
ELIMINATION_MARGIN = 1e-7


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

    def recheck_transitions(
        self, hypothesis: UncertainLinearSystem, states: ArrayLike, controls: ArrayLike, next_states: ArrayLike
    ) -> float:
        """Recompute the lower bound from transition triples, in their own units.

        Parameters
        ----------
        hypothesis : UncertainLinearSystem
            The eliminated hypothesis.
        states : array_like
            Shape (N, p), the states x_n of the transitions.
        controls : array_like
            Shape (N, q), the controls u_n.
        next_states : array_like
            Shape (N, p), the next states x_{n+1}.

        Returns
        -------
        float
            The weak-duality lower bound on the margin (dimensionless), recomputed
            with numpy from the stored multipliers; the certificate holds iff it
            exceeds ``self.tolerance``. Only the rows of ``self.transitions`` are read.

        Raises
        ------
        DimensionError
            Shapes that do not match the hypothesis or the certificate.
        NonFiniteError
            NaN or inf in the data.

        Notes
        -----
        The multipliers are those of the original (unscaled) rows: the scaling applied
        to solve the LP is undone before they are stored, so this check uses nothing
        but the data, the hypothesis and the multipliers (Section III's LP test).
        """
        check_instance("hypothesis", hypothesis, UncertainLinearSystem)
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
        data = HypothesisData(Structure(hypothesis, noise, self.rounding_allowance), X[t], U[t], Xn[t])
        local = np.arange(t.size)
        return lagrangian_bound(
            data, local, self.multipliers_upper, self.multipliers_lower, np.zeros(data.nparams), None
        )

    def recheck(self, hypothesis: UncertainLinearSystem, states: ArrayLike, controls: ArrayLike) -> float:
        """Recompute the lower bound from a trajectory.

        Parameters
        ----------
        hypothesis : UncertainLinearSystem
            The eliminated hypothesis.
        states : array_like
            Shape (N+1, p), the observed states.
        controls : array_like
            Shape (N, q), the controls applied.

        Returns
        -------
        float
            As `recheck_transitions`.
        """
        X, U, Xn = check_trajectory(states, controls, hypothesis.nstates, hypothesis.ninputs)
        return self.recheck_transitions(hypothesis, X, U, Xn)

    def verify(self, hypothesis: UncertainLinearSystem, states: ArrayLike, controls: ArrayLike) -> bool:
        """Whether the elimination stands on this trajectory.

        Parameters
        ----------
        hypothesis : UncertainLinearSystem
            The eliminated hypothesis.
        states : array_like
            Shape (N+1, p), the observed states.
        controls : array_like
            Shape (N, q), the controls applied.

        Returns
        -------
        bool
            True iff the re-checked bound (`recheck`) exceeds ``self.tolerance``.
        """
        return self.recheck(hypothesis, states, controls) > self.tolerance

    def to_dict(self) -> dict:
        """A JSON-ready dictionary (arrays as nested lists)."""
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
        """A JSON-ready dictionary (certificates keyed by the hypothesis index as a string)."""
        return {
            "survivors": list(self.survivors),
            "eliminated": {str(k): c.to_dict() for k, c in self.eliminated.items()},
            "margins": list(self.margins),
            "rounds": list(self.rounds),
            "tolerance": self.tolerance,
        }
