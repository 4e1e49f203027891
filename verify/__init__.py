"""minimaxplan.verify."""

from .lmi import LMIResult, check_assumption4  # Assumption 4 LMI (cvxpy + Clarabel)

from .selection import (  # LP model elimination (HiGHS)
    EliminationCertificate,
    ModelSelector,
    SelectionResult,
    eliminate_models,
    feasible_parameter_box,
)
