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

from typing import TYPE_CHECKING, Any

from .._lazy import lazy_attributes

if TYPE_CHECKING:
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

# Each name is imported from its module when first asked for: the robot's worlds and rewards do not import
# the road worlds, the traffic and the driving reward (0.2 s of a fresh process, see
# benchmarks/bench_cold_start.py), nor the reverse.
_MODULES = {
    "DrivingReward": "driving_reward",
    "road_pieces": "driving_reward",
    "true_reward": "driving_reward",
    "world_reward": "driving_reward",
    "CircularObstacles": "geometry",
    "MovingObstacles": "geometry",
    "fcl_disc_collisions": "geometry",
    "GoalReward": "rewards",
    "RewardFamily": "rewards",
    "SpeedLaneReward": "rewards",
    "ArcLane": "road",
    "HighwayGeometry": "road",
    "Road": "road",
    "StraightLane": "road",
    "TJunctionGeometry": "road",
    "highway_road": "road",
    "lane_geometry": "road",
    "tjunction_road": "road",
    "HighwayScenario": "road_world",
    "RoadWorld": "road_world",
    "TJunctionScenario": "road_world",
    "make_road_world": "road_world",
    "rectangles_collide": "road_world",
    "DEFAULT_ROBOT": "robot",
    "Hypothesis": "robot",
    "RobotParameters": "robot",
    "robot_hypotheses": "robot",
    "robot_system": "robot",
    "TrafficForecast": "traffic_models",
    "VehicleBelief": "traffic_models",
    "forecast_traffic": "traffic_models",
    "prior_belief": "traffic_models",
    "BehaviourParameters": "vehicles",
    "TrafficRules": "vehicles",
    "TrafficState": "vehicles",
    "VehicleParameters": "vehicles",
    "traffic_step": "vehicles",
    "EpisodeOver": "worlds",
    "RobotWorld": "worlds",
    "make_world": "worlds",
}

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


_lazy_getattr = lazy_attributes(__name__, globals(), _MODULES)


def __getattr__(name: str) -> Any:
    # The Gymnasium env needs the optional `gym` extra: import it only when asked for (not cached).
    if name in ("RobotNavigationEnv", "RoadDrivingEnv"):
        from . import gym_env

        return getattr(gym_env, name)
    return _lazy_getattr(name)


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
