"""minimaxplan.verify: certificates.

* `check_assumption4`: the stability LMI of Assumption 4 (continuous or discrete form,
  one matrix or a polytope with a common P), solved with cvxpy + Clarabel; its verdicts
  are proven both ways in exact rational arithmetic: "feasible" with a certificate
  (`LMIResult`), "infeasible" with a `DualCertificate` of the normalised problem. The
  only module of the library that imports cvxpy.
* `conflicting_vertices`, `certified_region`: where Assumption 4 holds: an irreducible
  set of vertex matrices with no common P, and a recursive split of a parameter box
  into pieces certified each with its own P (`RegionMap`).
* `eliminate_models`, `ModelSelector`, `feasible_parameter_box`: LP feasibility of
  structural hypotheses against observed transitions (HiGHS through scipy), with
  certificates of inconsistency.
* `interval_consistency`, `interval_parameter_box` (`IntervalRows`): the same LP test
  for models whose regressors are intervals (noisy measured inputs, e.g. a leader's
  speed in a follower's law), verdicts proven both ways, and the LP box of theta.

Modules: `lmi` (the SDPs and their exact re-checks); `regions` (conflicts and region maps); `selection` (the public model-elimination
API); `interval_regression` (interval rows); `certificates` (`EliminationCertificate`, `SelectionResult`); and, internal,
`_regression` (input checks and the per-hypothesis regression data), `_highs` (the
only `linprog` call and its status map) and `_generation` (constraint generation and
the weak-duality bound).
"""

from typing import TYPE_CHECKING

from .._lazy import lazy_attributes

if TYPE_CHECKING:
    from .certificates import EliminationCertificate, SelectionResult
    from .interval_regression import (
        IntervalCertificate,
        IntervalRows,
        IntervalVerdict,
        interval_consistency,
        interval_parameter_box,
    )
    from .lmi import DualCertificate, LMIResult, LMIStatus, check_assumption4, lmi_matrix
    from .regions import ConflictSet, RegionMap, RegionPiece, certified_region, conflicting_vertices
    from .selection import ModelSelector, eliminate_models, feasible_parameter_box

# Each name is imported from its module when first asked for: importing `minimaxplan.verify.selection` (the
# LP model elimination, as the robot's methods do) does not import cvxpy and scipy.stats with `lmi`
# (0.9 s of a fresh process, see benchmarks/bench_cold_start.py).
_MODULES = {
    "EliminationCertificate": "certificates",
    "SelectionResult": "certificates",
    "IntervalCertificate": "interval_regression",
    "IntervalRows": "interval_regression",
    "IntervalVerdict": "interval_regression",
    "interval_consistency": "interval_regression",
    "interval_parameter_box": "interval_regression",
    "DualCertificate": "lmi",
    "LMIResult": "lmi",
    "LMIStatus": "lmi",
    "check_assumption4": "lmi",
    "lmi_matrix": "lmi",
    "ConflictSet": "regions",
    "RegionMap": "regions",
    "RegionPiece": "regions",
    "certified_region": "regions",
    "conflicting_vertices": "regions",
    "ModelSelector": "selection",
    "eliminate_models": "selection",
    "feasible_parameter_box": "selection",
}


__getattr__ = lazy_attributes(__name__, globals(), _MODULES)


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


__all__ = [
    "check_assumption4",
    "LMIResult",
    "LMIStatus",
    "DualCertificate",
    "lmi_matrix",
    "conflicting_vertices",
    "certified_region",
    "ConflictSet",
    "RegionPiece",
    "RegionMap",
    "eliminate_models",
    "ModelSelector",
    "feasible_parameter_box",
    "SelectionResult",
    "EliminationCertificate",
    "IntervalRows",
    "IntervalVerdict",
    "IntervalCertificate",
    "interval_consistency",
    "interval_parameter_box",
]
