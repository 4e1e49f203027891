"""Compiled box minima of the reward families, for the planner's compiled engine.

`GoalReward` and `SpeedLaneReward` expose ``kernel_params`` (the namedtuples below);
this module registers, for each type, an implementation of
`minimaxplan.planners.box_kernels.box_reward_minimum`. Each implementation performs
the same floating-point operations as the family's numpy ``box_minimum_raw`` (see
`minimaxplan.scenarios.rewards` for the exactness arguments), on one box
``z = [-lower | upper]``: tests check that the two agree bit for bit.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit, types
from numba.extending import overload

from minimaxplan.planners.box_kernels import _maximum, _minimum, box_reward_minimum, register_reward_params

__all__ = ["CollisionParams", "GoalParams", "SpeedLaneParams", "collision_params"]

CollisionParams = namedtuple(
    "CollisionParams",
    ["position", "centers", "reach_sq", "moving_positions", "moving_velocities", "moving_position_spread",
     "moving_velocity_spread", "moving_reach_sq", "dt", "time0"],
)
GoalParams = namedtuple("GoalParams", ["collision", "goal"])
SpeedLaneParams = namedtuple(
    "SpeedLaneParams",
    ["collision", "speed", "lateral", "target_speed", "speed_range", "speed_weight", "lane_weight", "lane_width",
     "n_lanes"],
)


def collision_params(collision) -> CollisionParams:
    """The arrays of a reward's collision term (`rewards._CollisionTerm`) for compiled code."""
    moving = collision.moving
    return CollisionParams(
        np.array(collision.position_indices, dtype=np.int64),
        np.ascontiguousarray(collision.obstacles.centers, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(collision._reach_sq, dtype=float),
        np.ascontiguousarray(moving.positions, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(moving.velocities, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(moving.position_uncertainty, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(moving.velocity_uncertainty, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(collision._moving_reach_sq, dtype=float),
        float(moving.dt),
        float(moving.time0),
    )


def _is(params, cls) -> bool:
    return isinstance(params, types.BaseNamedTuple) and params.instance_class is cls


@njit(inline="always")
def _collides(c, z, p, t):
    """beta = 0 somewhere in the box: static discs, then the moving discs' predicted boxes at t."""
    ix, iy = c.position[0], c.position[1]
    low_x, low_y = -z[ix], -z[iy]
    high_x, high_y = z[p + ix], z[p + iy]
    for j in range(c.centers.shape[0]):
        cx, cy = c.centers[j, 0], c.centers[j, 1]
        gap_x = _maximum(_maximum(low_x - cx, cx - high_x), 0.0)
        gap_y = _maximum(_maximum(low_y - cy, cy - high_y), 0.0)
        if gap_x * gap_x + gap_y * gap_y <= c.reach_sq[j]:
            return True
    if c.moving_positions.shape[0] > 0:
        elapsed = _maximum(t - c.time0, 0.0) * c.dt
        for j in range(c.moving_positions.shape[0]):
            centre_x = c.moving_positions[j, 0] + c.moving_velocities[j, 0] * elapsed
            centre_y = c.moving_positions[j, 1] + c.moving_velocities[j, 1] * elapsed
            half_x = c.moving_position_spread[j, 0] + c.moving_velocity_spread[j, 0] * elapsed
            half_y = c.moving_position_spread[j, 1] + c.moving_velocity_spread[j, 1] * elapsed
            gap_x = _maximum(_maximum((centre_x - half_x) - high_x, low_x - (centre_x + half_x)), 0.0)
            gap_y = _maximum(_maximum((centre_y - half_y) - high_y, low_y - (centre_y + half_y)), 0.0)
            if gap_x * gap_x + gap_y * gap_y <= c.moving_reach_sq[j]:
                return True
    return False


@overload(box_reward_minimum)
def _goal_box_minimum(params, z, p, t):
    if not _is(params, GoalParams):
        return None

    def implementation(params, z, p, t):
        # GoalReward: 0 if the box may collide, else 1 / (1 + distance of the farthest corner)
        if _collides(params.collision, z, p, t):
            return 0.0, True
        c = params.collision
        ix, iy = c.position[0], c.position[1]
        goal = params.goal
        far_x = _maximum(goal[0] + z[ix], z[p + ix] - goal[0])
        far_y = _maximum(goal[1] + z[iy], z[p + iy] - goal[1])
        return 1.0 / (1.0 + math.hypot(far_x, far_y)), False

    return implementation


@overload(box_reward_minimum)
def _speed_lane_box_minimum(params, z, p, t):
    if not _is(params, SpeedLaneParams):
        return None

    def implementation(params, z, p, t):
        # SpeedLaneReward: worst speed deviation over the speed interval, lane term at the lowest y
        if _collides(params.collision, z, p, t):
            return 0.0, True
        speed = params.speed
        if speed.shape[0] == 1:
            s_lo, s_hi = -z[speed[0]], z[p + speed[0]]
        else:
            lo_x, lo_y = -z[speed[0]], -z[speed[1]]
            hi_x, hi_y = z[p + speed[0]], z[p + speed[1]]
            near_x, near_y = _minimum(_maximum(0.0, lo_x), hi_x), _minimum(_maximum(0.0, lo_y), hi_y)
            far_x, far_y = _maximum(abs(lo_x), abs(hi_x)), _maximum(abs(lo_y), abs(hi_y))
            s_lo = math.sqrt(near_x * near_x + near_y * near_y)
            s_hi = math.sqrt(far_x * far_x + far_y * far_y)
        worst = _maximum(abs(s_lo - params.target_speed), abs(s_hi - params.target_speed))
        reward = params.speed_weight * (1.0 - _minimum(worst / params.speed_range, 1.0))
        if params.lane_weight != 0.0:
            y = -z[params.lateral]
            lane = _minimum(_maximum(math.floor(y / params.lane_width + 0.5), 0.0), params.n_lanes - 1.0)
            reward = reward + params.lane_weight * (lane / (params.n_lanes - 1.0))
        return reward, False

    return implementation


register_reward_params(GoalParams)
register_reward_params(SpeedLaneParams)
