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
from .estimation import ConfidenceEllipsoidEstimator, confidence_ellipsoid
from .polytope import VertexPolytope, parameter_vertices
from .prediction import IntervalPredictor, Tube, predict_tube
from .set_membership import SetMembershipEstimator
from .sets import Box, Ellipsoid, Membership, ParameterSet
from .system import UncertainLinearSystem

__all__ = [
    "Box",
    "Ellipsoid",
    "VertexPolytope",
    "ParameterSet",
    "Membership",
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
