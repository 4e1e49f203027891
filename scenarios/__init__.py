"""minimaxplan.scenarios."""

from .geometry import CircularObstacles, MovingObstacles, fcl_disc_collisions
from .rewards import GoalReward, SpeedLaneReward
