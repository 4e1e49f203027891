"""minimaxplan.verify."""

from .selection import (  # LP model elimination (HiGHS)
    EliminationCertificate,
    ModelSelector,
    SelectionResult,
    eliminate_models,
    feasible_parameter_box,
)
