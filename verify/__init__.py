"""minimaxplan.verify: certificates.

* `check_assumption4`: the stability LMI of Assumption 4 (continuous or discrete form,
  one matrix or a polytope with a common P), solved with cvxpy + Clarabel; its verdicts
  are proven both ways in exact rational arithmetic: "feasible" with a certificate
  (`LMIResult`), "infeasible" with a `DualCertificate` of the normalised problem. The
  only module of the library that imports cvxpy.
* `eliminate_models`, `ModelSelector`, `feasible_parameter_box`: LP feasibility of
  structural hypotheses against observed transitions (HiGHS through scipy), with
  certificates of inconsistency.

Modules: `lmi` (the SDPs and their exact re-checks); `selection` (the public model-elimination
API); `certificates` (`EliminationCertificate`, `SelectionResult`); and, internal,
`_regression` (input checks and the per-hypothesis regression data), `_highs` (the
only `linprog` call and its status map) and `_generation` (constraint generation and
the weak-duality bound).
"""

from .certificates import EliminationCertificate, SelectionResult
from .lmi import DualCertificate, LMIResult, LMIStatus, check_assumption4, lmi_matrix
from .selection import ModelSelector, eliminate_models, feasible_parameter_box

__all__ = [
    "check_assumption4",
    "LMIResult",
    "LMIStatus",
    "DualCertificate",
    "lmi_matrix",
    "eliminate_models",
    "ModelSelector",
    "feasible_parameter_box",
    "SelectionResult",
    "EliminationCertificate",
]
