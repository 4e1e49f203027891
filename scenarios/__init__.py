"""minimaxplan.scenarios."""

from .geometry import CircularObstacles, MovingObstacles, fcl_disc_collisions
from .rewards import GoalReward, SpeedLaneReward
from .robot import DEFAULT_ROBOT, Hypothesis, RobotParameters, robot_hypotheses, robot_system
from .worlds import EpisodeOver, RobotWorld, make_world
