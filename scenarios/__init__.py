"""minimaxplan.scenarios."""

from .geometry import CircularObstacles, MovingObstacles, fcl_disc_collisions
from .rewards import GoalReward, SpeedLaneReward
from .robot import DEFAULT_ROBOT, Hypothesis, RobotParameters, robot_hypotheses, robot_system
from .worlds import EpisodeOver, RobotWorld, make_world


def __getattr__(name):
    # The Gymnasium env needs the optional `gym` extra: import it only when asked for.
    if name == "RobotNavigationEnv":
        from .gym_env import RobotNavigationEnv

        return RobotNavigationEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
