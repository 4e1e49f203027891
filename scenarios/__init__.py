"""minimaxplan.scenarios: the simulated worlds, their geometry and reward families.

* the planar robot (`robot_system`, `robot_hypotheses`, `RobotParameters`) and its
  seeded worlds (`make_world`: "static" or "pedestrian");
* obstacle geometry (`CircularObstacles`, `MovingObstacles`; python-fcl for true
  collisions, an exact vectorised twin for planners);
* reward families with exact box minima (`GoalReward`, `SpeedLaneReward`, on the base
  `RewardFamily`), each minimum one compiled kernel (`minimaxplan.kernels` protocol);
* the road worlds of the driving experiments (`make_road_world`: "highway" or
  "tjunction"; lanes with exact Frenet maps in `Road`, other vehicles on the kinematic
  bicycle with the LinearVehicle law in `traffic_step`; `docs/driving-world.md`);
* the driving ego's reward (`DrivingReward`) and the planner's models of traffic
  (`forecast_traffic`, `VehicleBelief`; `docs/traffic-models.md`);
* `RobotNavigationEnv` and `RoadDrivingEnv`, the Gymnasium API (the `gym` extra),
  imported on demand.
"""

from .driving_reward import DrivingReward, road_pieces, true_reward, world_reward
from .geometry import CircularObstacles, MovingObstacles, fcl_disc_collisions
from .rewards import GoalReward, RewardFamily, SpeedLaneReward
from .road import (
    ArcLane,
    HighwayGeometry,
    Road,
    StraightLane,
    TJunctionGeometry,
    highway_road,
    lane_geometry,
    tjunction_road,
)
from .road_world import HighwayScenario, RoadWorld, TJunctionScenario, make_road_world, rectangles_collide
from .robot import DEFAULT_ROBOT, Hypothesis, RobotParameters, robot_hypotheses, robot_system
from .traffic_models import TrafficForecast, VehicleBelief, forecast_traffic, prior_belief
from .vehicles import BehaviourParameters, TrafficRules, TrafficState, VehicleParameters, traffic_step
from .worlds import EpisodeOver, RobotWorld, make_world

__all__ = [
    "ArcLane",
    "BehaviourParameters",
    "HighwayGeometry",
    "HighwayScenario",
    "Road",
    "RoadWorld",
    "StraightLane",
    "TJunctionGeometry",
    "TJunctionScenario",
    "TrafficRules",
    "TrafficState",
    "VehicleParameters",
    "highway_road",
    "make_road_world",
    "rectangles_collide",
    "tjunction_road",
    "traffic_step",
    "lane_geometry",
    "DrivingReward",
    "road_pieces",
    "world_reward",
    "true_reward",
    "VehicleBelief",
    "TrafficForecast",
    "forecast_traffic",
    "prior_belief",
    "CircularObstacles",
    "MovingObstacles",
    "fcl_disc_collisions",
    "GoalReward",
    "RewardFamily",
    "SpeedLaneReward",
    "DEFAULT_ROBOT",
    "Hypothesis",
    "RobotParameters",
    "robot_hypotheses",
    "robot_system",
    "EpisodeOver",
    "RobotWorld",
    "make_world",
    "RobotNavigationEnv",
    "RoadDrivingEnv",
]


def __getattr__(name):
    # The Gymnasium env needs the optional `gym` extra: import it only when asked for.
    if name in ("RobotNavigationEnv", "RoadDrivingEnv"):
        from . import gym_env

        return getattr(gym_env, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
