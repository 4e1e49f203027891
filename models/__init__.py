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

__all__ = [
    "Box",
    "Ellipsoid",
    "UncertainLinearSystem",
    "MinimaxplanError",
    "InputError",
    "DimensionError",
    "NonFiniteError",
    "EmptySetError",
    "RewardRangeError",
    "SolverFailure",
    "NoConsistentModel",
]
