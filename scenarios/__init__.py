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
* `RobotNavigationEnv`, the Gymnasium API (the `gym` extra), imported on demand.
"""

from .geometry import CircularObstacles, MovingObstacles, fcl_disc_collisions
from .rewards import GoalReward, RewardFamily, SpeedLaneReward
from .road import ArcLane, HighwayGeometry, Road, StraightLane, TJunctionGeometry, highway_road, tjunction_road
from .road_world import HighwayScenario, RoadWorld, TJunctionScenario, make_road_world, rectangles_collide
from .robot import DEFAULT_ROBOT, Hypothesis, RobotParameters, robot_hypotheses, robot_system
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
]


def __getattr__(name):
    # The Gymnasium env needs the optional `gym` extra: import it only when asked for.
    if name == "RobotNavigationEnv":
        from .gym_env import RobotNavigationEnv

        return RobotNavigationEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
