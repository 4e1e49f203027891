"""minimaxplan.models: sets, uncertain systems, estimation and interval prediction.

Pure numpy/scipy; the base layer that every other subpackage builds on.
"""

from .errors import (
    DimensionError,
    EmptySetError,
    InputError,
    MinimaxplanError,
    NoConsistentModel,
    NonFiniteError,
    RewardRangeError,
    SolverFailure,
)
from .sets import Box, Ellipsoid
from .system import UncertainLinearSystem
from .estimation import ConfidenceEllipsoidEstimator, confidence_ellipsoid
from .set_membership import SetMembershipEstimator
from .polytope import parameter_vertices
from .prediction import IntervalPredictor, Tube, predict_tube

__all__ = [
    "Box",
    "Ellipsoid",
    "UncertainLinearSystem",
    "confidence_ellipsoid",
    "ConfidenceEllipsoidEstimator",
    "SetMembershipEstimator",
    "parameter_vertices",
    "IntervalPredictor",
    "Tube",
    "predict_tube",
    "MinimaxplanError",
    "InputError",
    "DimensionError",
    "NonFiniteError",
    "EmptySetError",
    "RewardRangeError",
    "SolverFailure",
    "NoConsistentModel",
]
