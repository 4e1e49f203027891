"""The driving reward's box minimum, one compiled kernel (the `minimaxplan.kernels` reward protocol).

`DrivingParams` is the ``kernel_params`` of `minimaxplan.scenarios.DrivingReward`; this
module registers its implementation of `minimaxplan.kernels.box_reward_minimum` on one
box ``z = [-lower | upper]`` of ego states ``(x, y, v, psi, ...)`` (the first four
coordinates are read) at the absolute sub-step t. The planner's ego model inlines it;
the family's numpy-facing ``box_minimum`` runs it through `minimaxplan.kernels.box_minima`.

The reward (the paper's cost flipped into [0, 1], Section IV)::

    J(x, t) = 0                                          if the ego's rectangle may meet an
                                                         obstacle box of row t - time0, or a
                                                         corner may leave the road, or
                                                         t - time0 is outside [0, H]
    J(x, t) = (1 + c1 goal(x) + c2 speed(v) + c3 lane(y)) / (1 + c1 + c2 + c3)   otherwise

with ``speed(v) = clip(v / v_max, 0, 1)``, ``lane(y) = lane_values[clip(floor((y - y0) / w
+ 1/2), 0, n - 1)]`` and ``goal(x) = 1 - min(dist(pos, goal) / goal_scale, 1)`` (the
distance to the goal region, 0 inside it); the zero
cases are terminal (beyond the obstacle table's horizon the traffic is unknown, so the
pessimistic reward is 0 there, and stays 0).

Exactness of the minimum over a box (Theorem 1):

* at a fixed heading (``psi_lo == psi_hi``), for a box P of positions: the rectangle
  centred at c in P meets the obstacle box O iff the rectangle centred at the origin
  meets the box ``O - P = [o_lo - p_hi, o_hi - p_lo]`` (the obstacle grown by the
  position box), tested exactly by separating axes (the two box axes and the two
  rectangle axes). A corner's positions form the box P + (its offset), and it is on the
  road when that box lies in one road piece (a straight strip, an arc's annular sector,
  an area): exact for points and for boxes within one piece, a sound (pessimistic)
  bound for a box that straddles pieces;
* over a heading interval: each corner's offset ranges over an exact box (the range of
  ``r cos(psi + phi)`` over an interval), and the collision test uses the box hull of
  the rectangle's four corner boxes grown by P: a sound lower bound, not exact;
* the free terms are monotone in separate coordinates (speed nondecreasing in v, the
  lane term's minimum over the lanes the y-interval touches, the goal term at the
  corner farthest from the goal region: the distance to a box is ``hypot(dx, dy)`` with
  dx convex in x alone and dy in y alone, so its maximum over a box of positions is at
  the ends of each interval), so their minima add up; the goal and lane terms both read y, so at
  most one of them may have a nonzero weight (checked by the family).

Collision and road tests are rounded outward by `ROUNDING_MARGIN` (m): a rectangle
within that distance of an obstacle box counts as touching it, a corner within that
distance of a road edge as off the road.
"""

from __future__ import annotations

import math
from collections import namedtuple

from numba import njit, types
from numba.extending import overload

from .box_primitives import maximum, minimum
from .reward_protocol import box_reward_minimum, register_reward_params

__all__ = ["DrivingParams", "ROUNDING_MARGIN", "footprint_collides", "interval_cos_range"]

#: Outward rounding of the collision and road tests, m.
ROUNDING_MARGIN = 1e-9

DrivingParams = namedtuple(
    "DrivingParams",
    [
        "boxes",
        "time0",
        "half_length",
        "half_width",
        "strips",
        "arcs",
        "areas",
        "check_road",
        "speed_weight",
        "max_speed",
        "lane_weight",
        "lane_values",
        "lane_width",
        "lane_origin",
        "goal_weight",
        "goal",
        "goal_scale",
    ],
)
DrivingParams.__doc__ = """``kernel_params`` of `minimaxplan.scenarios.DrivingReward` (C-contiguous arrays, floats).

Attributes
----------
boxes : ndarray (H+1, m, 4)
    Obstacle boxes ``[x_lo, y_lo, x_hi, y_hi]`` per sub-step row and vehicle (empty rows:
    lo = +inf, hi = -inf).
time0 : float
    The absolute sub-step of row 0.
half_length, half_width : float
    Half the ego's length and width, m.
strips : ndarray (k, 6)
    Straight road pieces ``[start_x, start_y, dir_x, dir_y, length, half_width]``: the
    points with ``0 <= s <= length`` and ``|offset| <= half_width``.
arcs : ndarray (k, 7)
    Arc pieces ``[center_x, center_y, radius, mid_angle, half_sweep, half_width, 0]``:
    the points at distance ``radius +- half_width`` from the centre whose polar angle is
    within ``half_sweep`` (< pi / 2 for the box test) of ``mid_angle``.
areas : ndarray (k, 4)
    Axis-aligned pieces ``[x_lo, y_lo, x_hi, y_hi]``.
check_road : bool
    Whether leaving the pieces is a collision.
speed_weight, max_speed : float
    c2 and v_max.
lane_weight : float
    c3.
lane_values : ndarray (n,)
    The lane term of each lane (lane k centred at ``y = lane_origin + k lane_width``).
lane_width, lane_origin : float
    Lane geometry for the lane term, m.
goal_weight : float
    c1.
goal : ndarray (4,)
    The goal region ``[x_lo, y_lo, x_hi, y_hi]``, m (a point: zero size).
goal_scale : float
    The distance at which the goal term reaches 0, m.
"""


@njit(cache=True, inline="always")
def _cos_range(low, high):
    """``[min, max]`` of cos over ``[low, high]`` (exact, before rounding)."""
    two_pi = 2.0 * math.pi
    if high - low >= two_pi:
        return -1.0, 1.0
    c_low, c_high = math.cos(low), math.cos(high)
    top = maximum(c_low, c_high)
    bottom = minimum(c_low, c_high)
    if math.ceil(low / two_pi) * two_pi <= high:
        top = 1.0
    if math.ceil((low - math.pi) / two_pi) * two_pi + math.pi <= high:
        bottom = -1.0
    return bottom, top


@njit(cache=True)
def interval_cos_range(low, high):
    """``[min, max]`` of ``cos(psi)`` over ``low <= psi <= high`` (rad), exact before rounding.

    Parameters
    ----------
    low, high : float
        The interval, ``low <= high``.

    Returns
    -------
    tuple of 2 float
    """
    return _cos_range(low, high)


@njit(cache=True, inline="always")
def _corner_offset_box(psi_lo, psi_hi, along, across):
    """The box of the offset ``R(psi) (along, across)`` of a rectangle corner over a heading interval."""
    r = math.hypot(along, across)
    phi = math.atan2(across, along)
    # x = r cos(psi + phi), y = r sin(psi + phi) = r cos(psi + phi - pi / 2)
    cx_lo, cx_hi = _cos_range(psi_lo + phi, psi_hi + phi)
    cy_lo, cy_hi = _cos_range(psi_lo + phi - math.pi / 2, psi_hi + phi - math.pi / 2)
    m = ROUNDING_MARGIN
    return r * cx_lo - m, r * cy_lo - m, r * cx_hi + m, r * cy_hi + m


@njit(cache=True, inline="always")
def _rectangle_meets_box(c, s, a, b, lo_x, lo_y, hi_x, hi_y):
    """Whether the rectangle centred at the origin (half-sizes a along (c, s), b across) meets a box.

    Separating axes: the box axes x, y and the rectangle axes u = (c, s), n = (-s, c).
    Closed sets: touching counts. An empty box (lo > hi) never meets it.
    """
    if lo_x > hi_x or lo_y > hi_y:
        return False
    ac, as_ = abs(c), abs(s)
    ex = a * ac + b * as_
    ey = a * as_ + b * ac
    if lo_x > ex or hi_x < -ex or lo_y > ey or hi_y < -ey:
        return False
    mx, my = 0.5 * (lo_x + hi_x), 0.5 * (lo_y + hi_y)
    hx, hy = 0.5 * (hi_x - lo_x), 0.5 * (hi_y - lo_y)
    centre_u = mx * c + my * s
    radius_u = hx * ac + hy * as_
    if centre_u - radius_u > a or centre_u + radius_u < -a:
        return False
    centre_n = -mx * s + my * c
    radius_n = hx * as_ + hy * ac
    if centre_n - radius_n > b or centre_n + radius_n < -b:
        return False
    return True


@njit(cache=True, inline="always")
def _hits_obstacles(boxes, half_length, half_width, row, lo_x, lo_y, hi_x, hi_y, psi_lo, psi_hi):
    """Whether the ego's rectangle, centred in the position box at a heading in the interval, may meet a box of ``row``."""
    a = half_length + ROUNDING_MARGIN
    b = half_width + ROUNDING_MARGIN
    if psi_lo == psi_hi:
        c, s = math.cos(psi_lo), math.sin(psi_lo)
        for j in range(boxes.shape[1]):
            # the obstacle grown by the position box, relative to the rectangle's centre
            if _rectangle_meets_box(
                c,
                s,
                a,
                b,
                boxes[row, j, 0] - hi_x,
                boxes[row, j, 1] - hi_y,
                boxes[row, j, 2] - lo_x,
                boxes[row, j, 3] - lo_y,
            ):
                return True
        return False
    # a heading interval: the box hull of the four corners' offset boxes (a superset of the rectangles)
    ex_lo, ey_lo, ex_hi, ey_hi = math.inf, math.inf, -math.inf, -math.inf
    for k in range(4):
        along = half_length if k < 2 else -half_length
        across = half_width if k % 2 == 0 else -half_width
        x0, y0, x1, y1 = _corner_offset_box(psi_lo, psi_hi, along, across)
        ex_lo, ey_lo = minimum(ex_lo, x0), minimum(ey_lo, y0)
        ex_hi, ey_hi = maximum(ex_hi, x1), maximum(ey_hi, y1)
    for j in range(boxes.shape[1]):
        if (
            boxes[row, j, 0] <= hi_x + ex_hi
            and boxes[row, j, 2] >= lo_x + ex_lo
            and boxes[row, j, 1] <= hi_y + ey_hi
            and boxes[row, j, 3] >= lo_y + ey_lo
        ):
            return True
    return False


@njit(cache=True, inline="always")
def _box_in_pieces(strips, arcs, areas, lo_x, lo_y, hi_x, hi_y):
    """Whether the box of points lies inside one road piece (shrunk by `ROUNDING_MARGIN`)."""
    m = ROUNDING_MARGIN
    for k in range(areas.shape[0]):
        if lo_x >= areas[k, 0] + m and lo_y >= areas[k, 1] + m and hi_x <= areas[k, 2] - m and hi_y <= areas[k, 3] - m:
            return True
    for k in range(strips.shape[0]):
        sx, sy, ux, uy = strips[k, 0], strips[k, 1], strips[k, 2], strips[k, 3]
        length, half = strips[k, 4], strips[k, 5]
        inside = True
        for corner in range(4):  # a strip is convex: the box is inside iff its corners are
            px = lo_x if corner < 2 else hi_x
            py = lo_y if corner % 2 == 0 else hi_y
            dx, dy = px - sx, py - sy
            s = dx * ux + dy * uy
            off = -dx * uy + dy * ux
            if not (s >= m and s <= length - m and abs(off) <= half - m):
                inside = False
                break
        if inside:
            return True
    for k in range(arcs.shape[0]):
        cx, cy, radius, mid, half_sweep, half = arcs[k, 0], arcs[k, 1], arcs[k, 2], arcs[k, 3], arcs[k, 4], arcs[k, 5]
        # radial range of the box about the centre: nearest point, farthest corner
        near_x = minimum(maximum(cx, lo_x), hi_x) - cx
        near_y = minimum(maximum(cy, lo_y), hi_y) - cy
        far_x = maximum(abs(lo_x - cx), abs(hi_x - cx))
        far_y = maximum(abs(lo_y - cy), abs(hi_y - cy))
        if math.hypot(near_x, near_y) < radius - half + m or math.hypot(far_x, far_y) > radius + half - m:
            continue
        # the angular wedge |angle - mid| <= half_sweep (< pi / 2: convex): the corners decide
        inside = half_sweep < math.pi / 2
        cm, sm = math.cos(mid), math.sin(mid)
        ch = math.cos(half_sweep)
        for corner in range(4):
            if not inside:
                break
            px = (lo_x if corner < 2 else hi_x) - cx
            py = (lo_y if corner % 2 == 0 else hi_y) - cy
            dist = math.hypot(px, py)
            # cos(angle - mid) >= cos(half_sweep), with the radial margin already checked (dist > 0)
            if px * cm + py * sm < ch * dist + m:
                inside = False
        if inside:
            return True
    return False


@njit(cache=True, inline="always")
def _leaves_road(strips, arcs, areas, a, b, lo_x, lo_y, hi_x, hi_y, psi_lo, psi_hi):
    """Whether a corner of the ego's rectangle (half-sizes a, b) may leave the road (no single piece holds its box)."""
    exact = psi_lo == psi_hi
    c, s = math.cos(psi_lo), math.sin(psi_lo)
    for k in range(4):
        along = a if k < 2 else -a
        across = b if k % 2 == 0 else -b
        if exact:
            ox = along * c - across * s
            oy = along * s + across * c
            x0, y0, x1, y1 = ox, oy, ox, oy
        else:
            x0, y0, x1, y1 = _corner_offset_box(psi_lo, psi_hi, along, across)
        if not _box_in_pieces(strips, arcs, areas, lo_x + x0, lo_y + y0, hi_x + x1, hi_y + y1):
            return True
    return False


@njit(cache=True, inline="always")
def footprint_collides(params, lo_x, lo_y, hi_x, hi_y, psi_lo, psi_hi, row):
    """The zero cases of the reward: an obstacle of ``row`` may be met, or the road left.

    Parameters
    ----------
    params : DrivingParams
        The reward's parameters.
    lo_x, lo_y, hi_x, hi_y : float
        The box of the ego's centre positions, m.
    psi_lo, psi_hi : float
        Its heading interval, rad (equal: exact test).
    row : int
        The obstacle table's row (``0 <= row <= H``).

    Returns
    -------
    bool
    """
    a, b = params.half_length, params.half_width
    if _hits_obstacles(params.boxes, a, b, row, lo_x, lo_y, hi_x, hi_y, psi_lo, psi_hi):
        return True
    if not params.check_road:
        return False
    return _leaves_road(params.strips, params.arcs, params.areas, a, b, lo_x, lo_y, hi_x, hi_y, psi_lo, psi_hi)


def _is_driving(params) -> bool:
    return isinstance(params, types.BaseNamedTuple) and getattr(params, "instance_class", None) is DrivingParams


@overload(box_reward_minimum)
def _driving_box_minimum(params, z, p, t):
    if not _is_driving(params):
        return None

    def implementation(params, z, p, t):
        n = t - params.time0
        if not (n >= 0.0 and n <= params.boxes.shape[0] - 1):
            return 0.0, True  # beyond the forecast: unknown, pessimistically 0 from here on
        row = int(n)
        lo_x, lo_y, v_lo, psi_lo = -z[0], -z[1], -z[2], -z[3]
        hi_x, hi_y, psi_hi = z[p], z[p + 1], z[p + 3]
        if footprint_collides(params, lo_x, lo_y, hi_x, hi_y, psi_lo, psi_hi, row):
            return 0.0, True
        total = 1.0
        norm = 1.0
        if params.speed_weight != 0.0:
            total += params.speed_weight * minimum(maximum(v_lo / params.max_speed, 0.0), 1.0)
            norm += params.speed_weight
        if params.lane_weight != 0.0:
            count = params.lane_values.shape[0]
            k_lo = minimum(maximum(math.floor((lo_y - params.lane_origin) / params.lane_width + 0.5), 0.0), count - 1.0)
            k_hi = minimum(maximum(math.floor((hi_y - params.lane_origin) / params.lane_width + 0.5), 0.0), count - 1.0)
            worst = params.lane_values[int(k_lo)]
            for k in range(int(k_lo) + 1, int(k_hi) + 1):
                worst = minimum(worst, params.lane_values[k])
            total += params.lane_weight * worst
            norm += params.lane_weight
        if params.goal_weight != 0.0:
            goal = params.goal
            far_x = maximum(maximum(goal[0] - lo_x, hi_x - goal[2]), 0.0)
            far_y = maximum(maximum(goal[1] - lo_y, hi_y - goal[3]), 0.0)
            progress = 1.0 - minimum(math.hypot(far_x, far_y) / params.goal_scale, 1.0)
            total += params.goal_weight * progress
            norm += params.goal_weight
        return minimum(total / norm, 1.0), False

    return implementation


register_reward_params(DrivingParams)
