"""minimaxplan.planners."""

from .decision import Decision
from .search import OptimisticPlanner, RobustTreePlanner
