"""minimaxplan.planners."""

from .decision import Decision
from .search import OptimisticPlanner, RobustTreePlanner
from .controllers import LinearFeedback, OpenLoop
from .interval_model import BoxState, IntervalModel
from .point_model import PointModel, PointState
from .comparison import (
    interval_robust_planner,
    multi_model_robust_planner,
    nominal_planner,
    oracle_planner,
    root_state,
)
from .dwa import DWAParameters, DynamicWindowPlanner, NavigationScene
from .teb import TEBParameters, TimedElasticBand
