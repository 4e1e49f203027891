"""minimaxplan.scenarios: the simulated worlds, their geometry and reward families.

* the planar robot (`robot_system`, `robot_hypotheses`, `RobotParameters`) and its
  seeded worlds (`make_world`: "static" or "pedestrian");
* obstacle geometry (`CircularObstacles`, `MovingObstacles`; python-fcl for true
  collisions, an exact vectorised twin for planners);
* reward families with exact box minima (`GoalReward`, `SpeedLaneReward`, on the base
  `RewardFamily`), each minimum one compiled kernel (`minimaxplan.kernels` protocol);
* `RobotNavigationEnv`, the Gymnasium API (the `gym` extra), imported on demand.
"""

from .geometry import CircularObstacles, MovingObstacles, fcl_disc_collisions
from .rewards import GoalReward, RewardFamily, SpeedLaneReward
from .robot import DEFAULT_ROBOT, Hypothesis, RobotParameters, robot_hypotheses, robot_system
from .worlds import EpisodeOver, RobotWorld, make_world

__all__ = [
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
