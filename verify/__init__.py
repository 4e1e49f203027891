"""minimaxplan.verify: certificates.

* `check_assumption4`: the stability LMI of Assumption 4 (continuous or discrete form,
  one matrix or a polytope with a common P), solved with cvxpy + Clarabel and re-checked
  with numpy eigenvalues; the only module of the library that imports cvxpy.
* `eliminate_models`, `ModelSelector`, `feasible_parameter_box`: LP feasibility of
  structural hypotheses against observed transitions (HiGHS through scipy), with
  certificates of inconsistency.
"""

from .lmi import LMIResult, LMIStatus, check_assumption4, lmi_matrix
from .selection import (
    EliminationCertificate,
    ModelSelector,
    SelectionResult,
    eliminate_models,
    feasible_parameter_box,
)

__all__ = [
    "check_assumption4",
    "LMIResult",
    "LMIStatus",
    "lmi_matrix",
    "eliminate_models",
    "ModelSelector",
    "feasible_parameter_box",
    "SelectionResult",
    "EliminationCertificate",
]
