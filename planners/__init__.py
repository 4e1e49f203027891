"""minimaxplan.planners: tree search and the models and baselines it is compared with.

* `RobustTreePlanner` (eqs. (15)-(18)) and `OptimisticPlanner` (OPD, eq. (12) with its
  discount), returning a `Decision` with root lower/upper value bounds (Theorem 3);
* `IntervalModel` (a box-valued planner model whose reward is the pessimistic surrogate
  of Theorem 1) and `PointModel` (nominal/oracle), driven by low-level controllers
  (`OpenLoop`, `LinearFeedback`); `BicycleModel`, the driving ego as a point model
  (compiled bicycle and controllers, `ego_controller`, over a compiled reward);
* factories for the paper's comparison (`interval_robust_planner`,
  `multi_model_robust_planner`, `nominal_planner`, `oracle_planner`);
* `latest_collision_action`: when the tree's best plan may collide, the first action
  whose plans stay clear longest under every model;
* the baselines `DynamicWindowPlanner` (DWA) and `TimedElasticBand` (TEB), and the grid
  `NavigationFunction` that serves as their global planner.

Planners see models only through ``step(state, action)`` (optionally ``expand``) and
get obstacles as data; they never import `minimaxplan.scenarios`.
"""

from .bicycle_model import (
    HIGHWAY_ACTIONS,
    HIGHWAY_TARGET_SPEEDS,
    TJUNCTION_ACTIONS,
    TJUNCTION_TARGET_SPEEDS,
    BicycleModel,
    BicycleState,
    ego_controller,
)
from .comparison import (
    interval_robust_planner,
    multi_model_robust_planner,
    nominal_planner,
    oracle_planner,
    root_state,
)
from .controllers import LinearFeedback, OpenLoop
from .decision import Decision
from .dwa import (
    DWAParameters,
    DynamicWindowPlanner,
    NavigationScene,
    RoadScene,
    VehicleDWAParameters,
    VehicleDynamicWindow,
)
from .interval_model import BoxState, IntervalModel
from .latest_collision import latest_collision_action
from .navigation import NavigationFunction
from .point_model import PointModel, PointState
from .search import OptimisticPlanner, RobustTreePlanner
from .teb import TEBParameters, TimedElasticBand, VehicleElasticBand, VehicleTEBParameters

__all__ = [
    "RobustTreePlanner",
    "OptimisticPlanner",
    "Decision",
    "IntervalModel",
    "BoxState",
    "PointModel",
    "PointState",
    "BicycleModel",
    "BicycleState",
    "ego_controller",
    "HIGHWAY_ACTIONS",
    "TJUNCTION_ACTIONS",
    "HIGHWAY_TARGET_SPEEDS",
    "TJUNCTION_TARGET_SPEEDS",
    "OpenLoop",
    "LinearFeedback",
    "interval_robust_planner",
    "multi_model_robust_planner",
    "nominal_planner",
    "oracle_planner",
    "root_state",
    "latest_collision_action",
    "DynamicWindowPlanner",
    "DWAParameters",
    "NavigationScene",
    "TimedElasticBand",
    "TEBParameters",
    "RoadScene",
    "VehicleDynamicWindow",
    "VehicleDWAParameters",
    "VehicleElasticBand",
    "VehicleTEBParameters",
    "NavigationFunction",
]
