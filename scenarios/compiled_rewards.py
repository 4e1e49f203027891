"""The one implementation of each reward family's exact box minimum: a compiled kernel per family.

`GoalReward` and `SpeedLaneReward` expose ``kernel_params`` (the namedtuples below);
this module registers, for each type, an implementation of
`minimaxplan.kernels.box_reward_minimum` on one box ``z = [-lower | upper]`` (see
`minimaxplan.scenarios.rewards` for the exactness arguments). Every caller evaluates
these kernels: the planners' compiled engine inlines them, and the families'
numpy-facing ``box_minimum`` runs them over many boxes through
`minimaxplan.kernels.box_minima`. The collision test of a box uses the one box-disc
gap `minimaxplan.kernels.box_gap_sq`.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit, types
from numba.extending import overload

from minimaxplan.kernels import box_gap_sq, box_reward_minimum, maximum, minimum, register_reward_params

__all__ = ["CollisionParams", "GoalParams", "SpeedLaneParams", "collision_params"]

CollisionParams = namedtuple(
    "CollisionParams",
    [
        "position",
        "centers",
        "reach_sq",
        "moving_positions",
        "moving_velocities",
        "moving_position_spread",
        "moving_velocity_spread",
        "moving_reach_sq",
        "dt",
        "time0",
    ],
)
CollisionParams.__doc__ = """The arrays of a reward's collision term (see `collision_params`)."""
GoalParams = namedtuple("GoalParams", ["collision", "goal"])
GoalParams.__doc__ = """``kernel_params`` of `GoalReward`: its collision term and goal (2,)."""
SpeedLaneParams = namedtuple(
    "SpeedLaneParams",
    [
        "collision",
        "speed",
        "lateral",
        "target_speed",
        "speed_range",
        "speed_weight",
        "lane_weight",
        "lane_width",
        "n_lanes",
    ],
)
SpeedLaneParams.__doc__ = """``kernel_params`` of `SpeedLaneReward` (``lateral`` is -1 without a lane term)."""


def collision_params(collision) -> CollisionParams:
    """The arrays of a reward's collision term (`rewards.CollisionTerm`) for compiled code.

    Parameters
    ----------
    collision
        The family's collision term.

    Returns
    -------
    CollisionParams
        C-contiguous float64 arrays (int64 position indices) and floats.
    """
    moving = collision.moving
    return CollisionParams(
        np.array(collision.position_indices, dtype=np.int64),
        np.ascontiguousarray(collision.obstacles.centers, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(collision.reach_sq, dtype=float),
        np.ascontiguousarray(moving.positions, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(moving.velocities, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(moving.position_uncertainty, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(moving.velocity_uncertainty, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(collision.moving_reach_sq, dtype=float),
        float(moving.dt),
        float(moving.time0),
    )


def _is(params, cls) -> bool:
    """Whether numba type ``params`` is the namedtuple type ``cls`` (an overload's dispatch test)."""
    return isinstance(params, types.BaseNamedTuple) and getattr(params, "instance_class", None) is cls


@njit
def _collides(c, z, p, t):
    """beta = 0 somewhere in the box: static discs, then the moving discs' predicted boxes at t."""
    ix, iy = c.position[0], c.position[1]
    low_x, low_y = -z[ix], -z[iy]
    high_x, high_y = z[p + ix], z[p + iy]
    for j in range(c.centers.shape[0]):
        cx, cy = c.centers[j, 0], c.centers[j, 1]
        if box_gap_sq(low_x, low_y, high_x, high_y, cx, cy, cx, cy) <= c.reach_sq[j]:
            return True
    if c.moving_positions.shape[0] > 0:
        elapsed = maximum(t - c.time0, 0.0) * c.dt
        for j in range(c.moving_positions.shape[0]):
            centre_x = c.moving_positions[j, 0] + c.moving_velocities[j, 0] * elapsed
            centre_y = c.moving_positions[j, 1] + c.moving_velocities[j, 1] * elapsed
            half_x = c.moving_position_spread[j, 0] + c.moving_velocity_spread[j, 0] * elapsed
            half_y = c.moving_position_spread[j, 1] + c.moving_velocity_spread[j, 1] * elapsed
            gap_sq = box_gap_sq(
                low_x, low_y, high_x, high_y, centre_x - half_x, centre_y - half_y, centre_x + half_x, centre_y + half_y
            )
            if gap_sq <= c.moving_reach_sq[j]:
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
        far_x = maximum(goal[0] + z[ix], z[p + ix] - goal[0])
        far_y = maximum(goal[1] + z[iy], z[p + iy] - goal[1])
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
            near_x, near_y = minimum(maximum(0.0, lo_x), hi_x), minimum(maximum(0.0, lo_y), hi_y)
            far_x, far_y = maximum(abs(lo_x), abs(hi_x)), maximum(abs(lo_y), abs(hi_y))
            s_lo = math.sqrt(near_x * near_x + near_y * near_y)
            s_hi = math.sqrt(far_x * far_x + far_y * far_y)
        worst = maximum(abs(s_lo - params.target_speed), abs(s_hi - params.target_speed))
        reward = params.speed_weight * (1.0 - minimum(worst / params.speed_range, 1.0))
        if params.lane_weight != 0.0:
            y = -z[params.lateral]
            # float(): numba's math.floor gives an int64, which compiled a second `maximum` (int64, float64);
            # the float of that int64 is the same value, so the reward is the same bit for bit
            lane = minimum(maximum(float(math.floor(y / params.lane_width + 0.5)), 0.0), params.n_lanes - 1.0)
            reward = reward + params.lane_weight * (lane / (params.n_lanes - 1.0))
        return reward, False

    return implementation


register_reward_params(GoalParams)
register_reward_params(SpeedLaneParams)
