"""The kinematic bicycle and the ego's low-level controllers, compiled once (numpy and numba only).

One implementation of the vehicles' motion, used by the world
(`minimaxplan.scenarios.vehicles.bicycle_step` calls `bicycle_step_into`) and by the
planner's ego model (`minimaxplan.planners.bicycle_model`), so that the planner's
predicted ego trajectory equals the world's ego bit for bit under the same controls.

Bicycle (highway-env's kinematic bicycle, forward Euler with step dt, rear axle and
centre of mass L / 2 apart), state ``(x, y, v, psi)``::

    beta = arctan(tan(delta) / 2)
    x+   = x + v cos(psi + beta) dt,      y+ = y + v sin(psi + beta) dt,
    psi+ = psi + v sin(beta) / (L / 2) dt,
    v+   = clip(v + a dt, 0, max_speed).

Ego controllers (`EgoController`): an action sets a target speed level and a target
lane; at every sub-step the control is

* acceleration ``clip(k_v (v_target - v), -a_bound, a_bound)``;
* steering, the LinearVehicle steering law with fixed gains ``theta_b`` on the target
  lane: ``clip(theta_b . [wrap(h(s + tau v) - psi) L / v, -offset L / v^2],
  -max_steering, max_steering)`` (v replaced by ``speed_epsilon`` when smaller; h the
  lane heading ``tau v`` ahead, on the lane's route successor when beyond its end).

The lane geometry comes as arrays (`LaneGeometry`, made from a road by
`minimaxplan.scenarios.road.lane_geometry`), with the exact Frenet formulas of
`minimaxplan.scenarios.road.Road.frenet`. On a route (the T-junction's left turn) the
target lane moves to its successor (``next_lane``) when the ego's arc length passes its
end, as the world's route progress does.
"""

from __future__ import annotations

import math
from collections import namedtuple
from typing import Any

import numpy as np
from numba import njit

__all__ = [
    "LaneGeometry",
    "EgoController",
    "STRAIGHT_LANE",
    "ARC_LANE",
    "bicycle_step_one",
    "bicycle_step_into",
    "lane_frenet",
    "lane_heading",
    "apply_action",
    "ego_control_one",
    "ego_control",
    "ego_rollout",
]

#: Lane kinds in `LaneGeometry.kinds` (the values of `minimaxplan.scenarios.road.STRAIGHT` / ``ARC``).
STRAIGHT_LANE = 0
ARC_LANE = 1

LaneGeometry = namedtuple(
    "LaneGeometry",
    [
        "kinds",
        "starts",
        "directions",
        "centers",
        "radii",
        "start_angles",
        "mid_angles",
        "signs",
        "lengths",
        "widths",
        "next_lane",
        "left_lane",
        "right_lane",
    ],
)
LaneGeometry.__doc__ = """The lanes of a road as C-contiguous arrays, row i for lane i (compiled code reads them).

Attributes
----------
kinds : ndarray (n,) of int64
    `STRAIGHT_LANE` or `ARC_LANE`.
starts, directions : ndarray (n, 2)
    A straight lane's start point (m) and unit direction (zeros-safe for arcs).
centers : ndarray (n, 2)
    An arc's centre (m).
radii, start_angles, mid_angles, signs : ndarray (n,)
    An arc's radius (m), polar angle of its start and of its midpoint (rad), and
    direction sign (+1 left, -1 right); for straight lanes radius 1 and the rest 0.
lengths, widths : ndarray (n,)
    Centre-line length and lane width, m.
next_lane : ndarray (n,) of int64
    The lane a controlled vehicle continues on after the end of lane i (-1: none).
left_lane, right_lane : ndarray (n,) of int64
    The side lane to the left / right of lane i (-1: none).
"""

EgoController = namedtuple(
    "EgoController",
    [
        "lanes",
        "target_speeds",
        "speed_gain",
        "acceleration_bound",
        "theta_b",
        "pursuit_time",
        "speed_epsilon",
        "length",
        "max_speed",
        "max_steering",
        "dt",
    ],
)
EgoController.__doc__ = """The ego's low-level controllers and bicycle, for compiled code.

Attributes
----------
lanes : LaneGeometry
    The road's lanes as arrays.
target_speeds : ndarray (k,)
    The target speed of each speed level, m/s (highway {20, 25, 30}, T-junction {0, 4.5, 9}).
speed_gain : float
    k_v, 1/s: the acceleration is ``clip(k_v (v_target - v), -a_bound, a_bound)``.
acceleration_bound : float
    a_bound, m/s^2 (at most the world's ``ego_acceleration_bound``, so the controls are admissible).
theta_b : ndarray (2,)
    The fixed steering gains of the LinearVehicle law (1/s, 1/s^2).
pursuit_time : float
    tau, s: the steering aims at the lane heading ``tau v`` ahead.
speed_epsilon : float
    Speeds below this are replaced by it in the steering features, m/s.
length : float
    L, m (the bicycle's length; axle to centre L / 2).
max_speed, max_steering : float
    The bicycle's speed clip (m/s) and the steering clip (rad).
dt : float
    The sub-step, s.
"""


@njit(cache=True, inline="always")
def bicycle_step_one(x, y, v, psi, acceleration, steering, dt, half_length, max_speed):
    """One forward-Euler step of the kinematic bicycle for one vehicle (see the module docstring).

    Parameters
    ----------
    x, y, v, psi : float
        The state (m, m, m/s, rad).
    acceleration, steering : float
        a (m/s^2) and delta (rad, used as given).
    dt : float
        Step, s.
    half_length : float
        L / 2, m.
    max_speed : float
        The speed clip, m/s.

    Returns
    -------
    tuple of 4 float
        The next ``(x, y, v, psi)``.
    """
    beta = math.atan(0.5 * math.tan(steering))
    x_next = x + v * math.cos(psi + beta) * dt
    y_next = y + v * math.sin(psi + beta) * dt
    psi_next = psi + v * math.sin(beta) / half_length * dt
    speed = v + acceleration * dt
    # np.clip(speed, 0, max_speed): NaN propagates
    if speed < 0.0:
        speed = 0.0
    elif speed > max_speed:
        speed = max_speed
    return x_next, y_next, speed, psi_next


#: The Python-facing kernels are compiled without numba's reference counting (they allocate nothing): every
#: read of an array field of the controller's namedtuples would otherwise cost an atomic increment and
#: decrement (measured: 7x slower rollouts).
_NO_REFCOUNTS: dict[str, Any] = {"cache": True, "_nrt": False}


@njit(**_NO_REFCOUNTS)
def bicycle_step_into(states, acceleration, steering, dt, length, max_speed, out):
    """`bicycle_step_one` for every row: ``out[i]`` from ``states[i]`` (n, 4), ``acceleration[i]``, ``steering[i]``.

    Parameters
    ----------
    states : ndarray (n, 4)
        ``(x, y, v, psi)``, float64.
    acceleration, steering : ndarray (n,)
        Float64.
    dt, length, max_speed : float
        Step (s), L (m) and the speed clip (m/s).
    out : ndarray (n, 4)
        Written.
    """
    half = length / 2
    for i in range(states.shape[0]):
        x, y, v, psi = bicycle_step_one(
            states[i, 0], states[i, 1], states[i, 2], states[i, 3], acceleration[i], steering[i], dt, half, max_speed
        )
        out[i, 0] = x
        out[i, 1] = y
        out[i, 2] = v
        out[i, 3] = psi


@njit(cache=True, inline="always")
def _wrap_to_pi(angle):
    """``np.mod(angle + pi, 2 pi) - pi``: numba's float ``%`` is Python's, the modulo numpy computes."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True, inline="always")
def lane_frenet(lanes, lane, x, y):
    """``(s, offset)`` of the point ``(x, y)`` in lane ``lane`` (the formulas of `Road.frenet`).

    Parameters
    ----------
    lanes : LaneGeometry
        The lanes.
    lane : int
        A lane index.
    x, y : float
        The point, m.

    Returns
    -------
    s, offset : float
        Arc length along the centre line and signed offset (left positive), m.
    """
    if lanes.kinds[lane] == ARC_LANE:
        cx = x - lanes.centers[lane, 0]
        cy = y - lanes.centers[lane, 1]
        d = lanes.signs[lane]
        radius = lanes.radii[lane]
        delta = _wrap_to_pi(math.atan2(cy, cx) - lanes.mid_angles[lane])
        return lanes.lengths[lane] / 2 + d * radius * delta, d * (radius - math.hypot(cx, cy))
    dx = x - lanes.starts[lane, 0]
    dy = y - lanes.starts[lane, 1]
    ux, uy = lanes.directions[lane, 0], lanes.directions[lane, 1]
    return dx * ux + dy * uy, -dx * uy + dy * ux


@njit(cache=True, inline="always")
def lane_heading(lanes, lane, s):
    """Heading (rad, not wrapped) of lane ``lane``'s centre line at arc length ``s`` (m)."""
    if lanes.kinds[lane] == ARC_LANE:
        d = lanes.signs[lane]
        return lanes.start_angles[lane] + d * s / lanes.radii[lane] + d * math.pi / 2
    return math.atan2(lanes.directions[lane, 1], lanes.directions[lane, 0])


@njit(cache=True, inline="always")
def apply_action(controller, level, lane, speed_change, lane_change):
    """The speed level and target lane after an action.

    Parameters
    ----------
    controller : EgoController
        The target speeds and the lanes' side neighbours.
    level, lane : int
        The current speed level and target lane.
    speed_change : int
        -1 (SLOWER), 0 or +1 (FASTER): the level moves by it, clipped to the levels.
    lane_change : int
        +1 (LANE_LEFT), 0 or -1 (LANE_RIGHT): the target lane becomes the side lane to
        that side of the current target lane, if there is one (else it stays).

    Returns
    -------
    level, lane : int
    """
    new_level = level + speed_change
    if new_level < 0:
        new_level = 0
    elif new_level > controller.target_speeds.shape[0] - 1:
        new_level = controller.target_speeds.shape[0] - 1
    new_lane = lane
    if lane_change > 0 and controller.lanes.left_lane[lane] >= 0:
        new_lane = controller.lanes.left_lane[lane]
    elif lane_change < 0 and controller.lanes.right_lane[lane] >= 0:
        new_lane = controller.lanes.right_lane[lane]
    return new_level, new_lane


@njit(cache=True, inline="always")
def ego_control_one(controller, x, y, v, psi, level, lane):
    """The ego's control at one sub-step, and its target lane after route progress.

    Parameters
    ----------
    controller : EgoController
        Gains, target speeds, lanes.
    x, y, v, psi : float
        The ego's state.
    level : int
        Its speed level (index into ``target_speeds``).
    lane : int
        Its target lane.

    Returns
    -------
    acceleration, steering : float
        ``clip(k_v (v_target - v), -a_bound, a_bound)`` and the clipped LinearVehicle
        steering on the target lane (see the module docstring).
    lane : int
        The target lane, moved along ``next_lane`` while the ego's arc length is past
        the lane's end.
    """
    lanes = controller.lanes
    s, offset = lane_frenet(lanes, lane, x, y)
    for _ in range(lanes.kinds.shape[0]):
        successor = lanes.next_lane[lane]
        if s <= lanes.lengths[lane] or successor < 0:
            break
        lane = successor
        s, offset = lane_frenet(lanes, lane, x, y)
    accel = controller.speed_gain * (controller.target_speeds[level] - v)
    bound = controller.acceleration_bound
    if accel < -bound:
        accel = -bound
    elif accel > bound:
        accel = bound
    s_ahead = s + controller.pursuit_time * v
    lane_ahead = lane
    if s_ahead > lanes.lengths[lane] and lanes.next_lane[lane] >= 0:
        s_ahead = s_ahead - lanes.lengths[lane]
        lane_ahead = lanes.next_lane[lane]
    heading = lane_heading(lanes, lane_ahead, s_ahead)
    speed = v if v > controller.speed_epsilon else controller.speed_epsilon
    length = controller.length
    error = _wrap_to_pi(heading - psi)
    steer = controller.theta_b[0] * (error * length / speed) + controller.theta_b[1] * (
        -offset * length / (speed * speed)
    )
    limit = controller.max_steering
    if steer < -limit:
        steer = -limit
    elif steer > limit:
        steer = limit
    return accel, steer, lane


@njit(**_NO_REFCOUNTS)
def _ego_control(controller, state, level, lane):
    return ego_control_one(controller, state[0], state[1], state[2], state[3], level, lane)


def ego_control(controller, state, level: int, lane: int) -> tuple[np.ndarray, int]:
    """The ego's control ``(acceleration, steering)`` at one sub-step, for a Python caller (a policy).

    Parameters
    ----------
    controller : EgoController
        The controllers.
    state : array_like, shape (4,)
        The ego's ``(x, y, v, psi)``.
    level : int
        Its speed level.
    lane : int
        Its target lane.

    Returns
    -------
    control : ndarray, shape (2,)
        ``(acceleration, steering)``: what `RoadWorld.apply` takes, bit for bit the
        control of the planner's ego model at this sub-step.
    lane : int
        The target lane after route progress (keep it for the next sub-step).
    """
    x = np.ascontiguousarray(state, dtype=float)
    accel, steer, lane_after = _ego_control(controller, x, int(level), int(lane))
    return np.array([accel, steer]), int(lane_after)


@njit(**_NO_REFCOUNTS)
def ego_rollout(controller, state, level, lane, substeps, out_states, out_controls):
    """Run the ego's controller and bicycle for ``substeps`` sub-steps from ``state`` (4,).

    Parameters
    ----------
    controller : EgoController
        The controllers.
    state : ndarray (4,)
        The start state.
    level, lane : int
        Speed level and target lane (held: no action changes them).
    substeps : int
        Number of sub-steps.
    out_states : ndarray (substeps, 4)
        Written: the state after each sub-step.
    out_controls : ndarray (substeps, 2)
        Written: the control applied at each sub-step.

    Returns
    -------
    int
        The target lane after the last sub-step's route progress.
    """
    x, y, v, psi = state[0], state[1], state[2], state[3]
    half = controller.length / 2
    for k in range(substeps):
        accel, steer, lane = ego_control_one(controller, x, y, v, psi, level, lane)
        out_controls[k, 0] = accel
        out_controls[k, 1] = steer
        x, y, v, psi = bicycle_step_one(x, y, v, psi, accel, steer, controller.dt, half, controller.max_speed)
        out_states[k, 0] = x
        out_states[k, 1] = y
        out_states[k, 2] = v
        out_states[k, 3] = psi
    return lane
