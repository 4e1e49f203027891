"""The driving reward: the paper's vehicle cost flipped into [0, 1], with a compiled exact box minimum.

`DrivingReward` is a `RewardFamily` over ego states ``(x, y, v, psi, ...)`` (m, m, m/s,
rad; further coordinates are not read) for both driving worlds. Its obstacles are a
table of axis-aligned boxes per sub-step, the traffic forecast's ``boxes`` (H+1, m, 4)
``[x_lo, y_lo, x_hi, y_hi]``, whose row 0 is the absolute sub-step ``time_offset``:

* 0 (terminal) when the ego's rectangle (L x W along psi) may meet a box of the row of
  sub-step t, when a corner of the rectangle may leave the road (a collision, as in
  the world), and at every sub-step outside the table (beyond its horizon the traffic
  is unknown: pessimistic, sound);
* otherwise ``(1 + c1 goal + c2 speed + c3 lane) / (1 + c1 + c2 + c3)``: the highway's
  ``(1 + 0.4 v / v_max + 0.1 lane) / 1.5`` (`DrivingReward.highway`, v_max = 30 m/s, the
  lane term 1 in the rightmost lane and 0 in the leftmost, the paper's l_c / (l_s - 1)
  with highway-env's lane order, in which the last lane is the right one), and the
  T-junction's progress to the goal ``(1 + 0.4 (1 - min(d / d_ref, 1))) / 1.4``
  (`DrivingReward.tjunction`, d the distance of the ego's centre to the goal point).

The box minimum is the compiled kernel of `minimaxplan.kernels.driving_reward` (exact
at a fixed heading for boxes of positions, a sound lower bound over a heading
interval and for position boxes that straddle two road pieces; see there), reached by
`box_minimum` through `minimaxplan.kernels.box_minima` and inlined by the planner's
ego model (`minimaxplan.planners.BicycleModel`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from minimaxplan.kernels.driving_reward import ROUNDING_MARGIN, DrivingParams
from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.models.validation import as_count, as_finite_array, as_positive_scalar

from .rewards import RewardFamily
from .road import ARC, Road

__all__ = ["DrivingReward", "road_pieces", "world_reward", "true_reward"]

#: The paper's weights (Section IV): highway c2 = 0.4 (speed), c3 = 0.1 (lane); T-junction c1 = 0.4 (goal).
HIGHWAY_SPEED_WEIGHT = 0.4
HIGHWAY_LANE_WEIGHT = 0.1
HIGHWAY_MAX_SPEED = 30.0
TJUNCTION_GOAL_WEIGHT = 0.4
#: Two straight lanes of a side group are merged into one strip when they are parallel and aligned to this, m.
MERGE_TOL = 1e-9


def _strip(start, direction, length, half_width) -> list[float]:
    return [float(start[0]), float(start[1]), float(direction[0]), float(direction[1]), float(length), half_width]


def road_pieces(road: Road, margin: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The road as the kernel's pieces: straight strips, arcs' annular sectors and areas, grown by ``margin``.

    Parameters
    ----------
    road : Road
        The lanes and areas; the union of the pieces is `Road.on_road`'s road.
    margin : float
        The world's ``off_road_margin`` (m, >= 0): every piece grown by it.

    Returns
    -------
    strips : ndarray (k, 6)
        ``[start_x, start_y, dir_x, dir_y, length, half_width]``; a side group of
        parallel, aligned straight lanes of equal length that touch edge to edge (the
        highway) is one strip, its exact union, so that a box across two lanes is inside.
    arcs : ndarray (k, 7)
        ``[center_x, center_y, radius, mid_angle, half_sweep, half_width, 0]``.
    areas : ndarray (k, 4)
        ``[x_lo, y_lo, x_hi, y_hi]``.
    """
    margin = as_positive_scalar("margin", margin, allow_zero=True)
    strips, arcs = [], []
    merged: set[int] = set()
    for group in road.side_groups:
        lanes = [road.lanes[i] for i in group]
        if len(group) < 2 or any(road.kinds[i] == ARC for i in group):
            continue
        first = lanes[0]
        u = first.direction
        normal = np.array([-u[1], u[0]])
        offsets = [float((lane.start - first.start) @ normal) for lane in lanes]
        aligned = all(
            np.allclose(lane.direction, u, rtol=0, atol=MERGE_TOL)
            and abs(float((lane.start - first.start) @ u)) <= MERGE_TOL
            and abs(lane.length - first.length) <= MERGE_TOL
            for lane in lanes
        )
        touching = all(
            abs((offsets[k + 1] - offsets[k]) - (lanes[k].width + lanes[k + 1].width) / 2) <= MERGE_TOL
            for k in range(len(lanes) - 1)
        )
        if not (aligned and touching and all(b > a for a, b in zip(offsets[:-1], offsets[1:]))):
            continue
        right_edge = offsets[0] - lanes[0].width / 2
        left_edge = offsets[-1] + lanes[-1].width / 2
        centre = first.start + normal * (right_edge + left_edge) / 2 - u * margin
        strips.append(_strip(centre, u, first.length + 2 * margin, (left_edge - right_edge) / 2 + margin))
        merged.update(group)
    for i, lane in enumerate(road.lanes):
        if i in merged:
            continue
        if road.kinds[i] == ARC:
            half_sweep = abs(lane.sweep) / 2 + margin / lane.radius
            arcs.append(
                [
                    *map(float, lane.center),
                    lane.radius,
                    lane.start_angle + lane.sweep / 2,
                    half_sweep,
                    lane.width / 2 + margin,
                    0.0,
                ]
            )
        else:
            strips.append(
                _strip(
                    lane.start - lane.direction * margin,
                    lane.direction,
                    lane.length + 2 * margin,
                    lane.width / 2 + margin,
                )
            )
    areas = [[x0 - margin, y0 - margin, x1 + margin, y1 + margin] for (x0, y0), (x1, y1) in road.areas]

    def table(rows, width):
        return np.ascontiguousarray(np.array(rows, dtype=float).reshape(-1, width))

    return table(strips, 6), table(arcs, 7), table(areas, 4)


def _goal_region(goal) -> np.ndarray:
    """The goal as a read-only region ``[x_lo, y_lo, x_hi, y_hi]`` (a point: the region of zero size)."""
    region = np.array(as_finite_array("goal", goal), dtype=float, copy=True)
    if region.shape == (2,):
        region = np.concatenate([region, region])
    if region.shape != (4,):
        raise DimensionError(f"goal must have shape (2,) or (4,), got shape {region.shape}")
    if region[0] > region[2] or region[1] > region[3]:
        raise InputError(f"goal must satisfy x_lo <= x_hi and y_lo <= y_hi, got {region.tolist()}")
    region.setflags(write=False)
    return region


def _obstacle_table(boxes) -> np.ndarray:
    table = np.array(boxes, dtype=float, copy=True)
    if table.ndim != 3 or table.shape[2] != 4 or table.shape[0] < 1:
        raise DimensionError(f"obstacles must have shape (H+1, m, 4) with H >= 0, got shape {table.shape}")
    if np.isnan(table).any():
        raise InputError("obstacles contains NaN entries (an absent vehicle is the empty box lo = +inf, hi = -inf)")
    lo, hi = table[..., :2], table[..., 2:]
    empty = (lo == np.inf) & (hi == -np.inf)
    if not np.all(np.isfinite(table[..., :2]) | empty) or not np.all(np.isfinite(table[..., 2:]) | empty):
        raise InputError("obstacles must be finite boxes, or the empty box lo = +inf, hi = -inf")
    if np.any((lo > hi) & ~empty):
        raise InputError("obstacles must have lo <= hi (or be the empty box lo = +inf, hi = -inf)")
    table.setflags(write=False)
    return table


@dataclass(frozen=True, eq=False)
class DrivingReward(RewardFamily):
    """The driving reward over ego states ``(x, y, v, psi, ...)`` (see the module docstring).

    Parameters
    ----------
    obstacles : array_like, shape (H+1, m, 4)
        Per sub-step row and other vehicle, an axis-aligned box ``[x_lo, y_lo, x_hi,
        y_hi]`` (m) containing its whole rectangle (the traffic forecast's ``boxes``);
        absent vehicles are the empty box (lo = +inf, hi = -inf).
    time_offset : int
        The absolute sub-step of row 0 (the forecast's time); sub-steps outside
        ``[time_offset, time_offset + H]`` have reward 0 (terminal).
    road : Road, optional
        The road: a corner of the ego's rectangle off it is a collision (None: no road test).
    off_road_margin : float
        The world's ``off_road_margin`` (m): the road's pieces are grown by it.
    length, width : float
        The ego's rectangle, m (5 x 2).
    speed_weight, max_speed : float
        c2 >= 0 and v_max > 0 (the speed term ``clip(v / v_max, 0, 1)``).
    lane_weight : float
        c3 >= 0.
    lane_values : array_like, shape (n,), optional
        The lane term of each lane, in [0, 1] (lane k centred at ``y = lane_origin + k
        lane_width``); required when ``lane_weight > 0``.
    lane_width, lane_origin : float
        Lane geometry of the lane term, m.
    goal_weight : float
        c1 >= 0 (at most one of ``lane_weight`` and ``goal_weight`` nonzero: both read y,
        and their minima would not add up).
    goal : array_like, shape (2,) or (4,), optional
        The goal, m: a point ``(x, y)`` or an axis-aligned region ``[x_lo, y_lo, x_hi,
        y_hi]`` (a point is the region of zero size); required when ``goal_weight > 0``.
        Stored as the region, shape (4,).
    goal_scale : float
        d_ref > 0, m: the goal term is ``1 - min(d / d_ref, 1)``, d the distance of the
        ego's centre to the goal region (0 inside it).

    Notes
    -----
    The paper's cost (Section IV), ``c1 ||x - x_g|| + c2 v / v_max + c3 l_c / (l_s - 1) +
    b_penalty``, is flipped into a reward in [0, 1]: the crash penalty becomes the
    terminal reward 0, and the other terms are normalised by ``1 + c1 + c2 + c3``.
    Exactness of the box minimum (Theorem 1) is argued in
    `minimaxplan.kernels.driving_reward`: exact for boxes of positions at a fixed
    heading (the planner's ego is a point), a sound lower bound over heading intervals.
    """

    obstacles: np.ndarray
    time_offset: int = 0
    road: Road | None = None
    off_road_margin: float = 0.0
    length: float = 5.0
    width: float = 2.0
    speed_weight: float = 0.0
    max_speed: float = HIGHWAY_MAX_SPEED
    lane_weight: float = 0.0
    lane_values: np.ndarray | None = None
    lane_width: float = 4.0
    lane_origin: float = 0.0
    goal_weight: float = 0.0
    goal: np.ndarray | None = None
    goal_scale: float = 1.0
    _pieces: tuple = field(init=False, repr=False, compare=False)
    _kernel_params: DrivingParams = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "obstacles", _obstacle_table(self.obstacles))
        object.__setattr__(self, "time_offset", as_count("time_offset", self.time_offset, minimum=0))
        if self.road is not None and not isinstance(self.road, Road):
            raise InputError(f"road must be a Road or None, got {type(self.road).__name__}")
        for name in ("length", "width", "max_speed", "lane_width", "goal_scale"):
            object.__setattr__(self, name, as_positive_scalar(name, getattr(self, name)))
        for name in ("speed_weight", "lane_weight", "goal_weight", "off_road_margin"):
            object.__setattr__(self, name, as_positive_scalar(name, getattr(self, name), allow_zero=True))
        object.__setattr__(self, "lane_origin", float(as_finite_array("lane_origin", self.lane_origin)))
        if self.lane_weight > 0 and self.goal_weight > 0:
            raise InputError("at most one of lane_weight and goal_weight may be nonzero (both read y)")
        if self.lane_values is None:
            if self.lane_weight > 0:
                raise InputError("lane_weight > 0 needs lane_values")
            lane_values = np.zeros(1)
        else:
            lane_values = as_finite_array("lane_values", self.lane_values).copy()
            if lane_values.ndim != 1 or lane_values.size < 1:
                raise DimensionError(f"lane_values must have shape (n,) with n >= 1, got shape {lane_values.shape}")
            if np.any(lane_values < 0) or np.any(lane_values > 1):
                raise InputError("lane_values must lie in [0, 1]")
        lane_values.setflags(write=False)
        object.__setattr__(self, "lane_values", lane_values if self.lane_values is not None else None)
        if self.goal is None:
            if self.goal_weight > 0:
                raise InputError("goal_weight > 0 needs a goal")
            goal = np.zeros(4)
        else:
            goal = _goal_region(self.goal)
            object.__setattr__(self, "goal", goal)
        if self.road is None:
            pieces = (np.zeros((0, 6)), np.zeros((0, 7)), np.zeros((0, 4)))
        else:
            pieces = road_pieces(self.road, self.off_road_margin)
        object.__setattr__(self, "_pieces", pieces)
        # the kernel reads private writable copies (numba compiles read-only arrays into slower code)
        params = DrivingParams(
            np.array(self.obstacles, order="C"),
            float(self.time_offset),
            self.length / 2,
            self.width / 2,
            pieces[0],
            pieces[1],
            pieces[2],
            self.road is not None,
            self.speed_weight,
            self.max_speed,
            self.lane_weight,
            np.array(lane_values, order="C"),
            self.lane_width,
            self.lane_origin,
            self.goal_weight,
            np.array(goal, order="C"),
            self.goal_scale,
        )
        object.__setattr__(self, "_kernel_params", params)

    # ------------------------------------------------------------ factories
    @classmethod
    def highway(
        cls,
        obstacles,
        time_offset: int,
        road: Road,
        *,
        off_road_margin: float = 0.0,
        length: float = 5.0,
        width: float = 2.0,
    ) -> DrivingReward:
        """The highway's reward ``(1 + 0.4 v / 30 + 0.1 lane) / 1.5`` on a road of parallel lanes along +x.

        Parameters
        ----------
        obstacles : array_like, shape (H+1, m, 4)
            The traffic forecast's boxes.
        time_offset : int
            The absolute sub-step of row 0.
        road : Road
            The highway (`highway_road`): lane k centred at ``y = k lane_width``, lane 0
            the rightmost (the side group is ordered right to left).
        off_road_margin, length, width : float
            As `DrivingReward`.

        Returns
        -------
        DrivingReward
            With the lane term ``(n - 1 - k) / (n - 1)`` of lane k: 1 in the rightmost
            lane (the paper's right-lane preference), 0 in the leftmost.
        """
        n = len(road)
        widths = np.asarray(road.widths)
        lane_values = np.ones(1) if n == 1 else (n - 1 - np.arange(n)) / (n - 1)
        return cls(
            obstacles,
            time_offset,
            road,
            off_road_margin=off_road_margin,
            length=length,
            width=width,
            speed_weight=HIGHWAY_SPEED_WEIGHT,
            max_speed=HIGHWAY_MAX_SPEED,
            lane_weight=HIGHWAY_LANE_WEIGHT if n > 1 else 0.0,
            lane_values=lane_values,
            lane_width=float(widths[0]),
            lane_origin=float(road.starts[0, 1]),
        )

    @classmethod
    def tjunction(
        cls,
        obstacles,
        time_offset: int,
        road: Road,
        goal,
        goal_scale: float,
        *,
        off_road_margin: float = 0.0,
        length: float = 5.0,
        width: float = 2.0,
    ) -> DrivingReward:
        """The T-junction's reward ``(1 + 0.4 (1 - min(d / d_ref, 1))) / 1.4``, d the distance to the ``goal`` region.

        Parameters
        ----------
        obstacles : array_like, shape (H+1, m, 4)
            The traffic forecast's boxes.
        time_offset : int
            The absolute sub-step of row 0.
        road : Road
            The T-junction (`tjunction_road`).
        goal : array_like, shape (2,) or (4,)
            The goal point or region, m (`world_reward`: the part of ``west_out`` where the
            world counts the goal as reached).
        goal_scale : float
            d_ref, m (e.g. the ego's initial distance to the goal).
        off_road_margin, length, width : float
            As `DrivingReward`.
        """
        return cls(
            obstacles,
            time_offset,
            road,
            off_road_margin=off_road_margin,
            length=length,
            width=width,
            goal_weight=TJUNCTION_GOAL_WEIGHT,
            goal=goal,
            goal_scale=goal_scale,
        )

    def with_obstacles(self, obstacles, time_offset: int) -> DrivingReward:
        """The same reward with a new obstacle table (the forecast of the next decision).

        Parameters
        ----------
        obstacles : array_like, shape (H+1, m, 4)
            The new boxes.
        time_offset : int
            Their row 0's absolute sub-step.
        """
        return replace(self, obstacles=obstacles, time_offset=time_offset)

    # ------------------------------------------------------------ family hooks
    @property
    def kernel_params(self) -> DrivingParams:
        """`DrivingParams` of the compiled box minimum."""
        return self._kernel_params

    @property
    def horizon(self) -> int:
        """H: the table holds the sub-steps ``time_offset .. time_offset + H``."""
        return int(self.obstacles.shape[0] - 1)

    @property
    def used_indices(self) -> tuple[int, ...]:
        """``(0, 1, 2, 3)``: x, y, v, psi."""
        return (0, 1, 2, 3)

    def free_value(self, states: np.ndarray) -> np.ndarray:
        """The reward where nothing collides, at each state.

        Parameters
        ----------
        states : numpy.ndarray
            States, shape (..., p) with p >= 4, checked by the caller (`value`).

        Returns
        -------
        numpy.ndarray
            Shape (...), in [0, 1].
        """
        total = np.ones(states.shape[:-1])
        norm = 1.0
        if self.speed_weight:
            total = total + self.speed_weight * np.clip(states[..., 2] / self.max_speed, 0.0, 1.0)
            norm += self.speed_weight
        if self.lane_weight:
            assert self.lane_values is not None
            count = self.lane_values.shape[0]
            k = np.clip(np.floor((states[..., 1] - self.lane_origin) / self.lane_width + 0.5), 0, count - 1)
            total = total + self.lane_weight * self.lane_values[k.astype(int)]
            norm += self.lane_weight
        if self.goal_weight:
            goal = self.goal
            assert goal is not None
            dx = np.maximum(np.maximum(goal[0] - states[..., 0], states[..., 0] - goal[2]), 0.0)
            dy = np.maximum(np.maximum(goal[1] - states[..., 1], states[..., 1] - goal[3]), 0.0)
            d = np.hypot(dx, dy)
            total = total + self.goal_weight * (1.0 - np.minimum(d / self.goal_scale, 1.0))
            norm += self.goal_weight
        return np.minimum(total / norm, 1.0)

    def free_argmin(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        """A state of each box where the free reward attains its minimum over the box.

        The lowest speed, the corner farthest from the goal region (goal term) or the y of the
        worst lane the y-interval touches (lane term).

        Parameters
        ----------
        lower, upper : numpy.ndarray
            Corners of the boxes, shape (..., p), ``lower <= upper``.

        Returns
        -------
        numpy.ndarray
            One state per box, shape (..., p), inside the box.
        """
        point = np.array(lower, dtype=float, copy=True)
        if self.goal_weight:
            goal = self.goal
            assert goal is not None
            for i in (0, 1):
                # the distance to the interval [goal[i], goal[i + 2]] is convex: largest at an end
                far_low = goal[i] - lower[..., i] >= upper[..., i] - goal[i + 2]
                point[..., i] = np.where(far_low, lower[..., i], upper[..., i])
        if self.lane_weight:
            assert self.lane_values is not None
            count = self.lane_values.shape[0]
            lanes = np.arange(count)
            lane_y = self.lane_origin + lanes * self.lane_width
            k_lo = np.clip(np.floor((lower[..., 1] - self.lane_origin) / self.lane_width + 0.5), 0, count - 1)
            k_hi = np.clip(np.floor((upper[..., 1] - self.lane_origin) / self.lane_width + 0.5), 0, count - 1)
            touched = (lanes >= k_lo[..., None]) & (lanes <= k_hi[..., None])
            worst = np.argmin(np.where(touched, self.lane_values, np.inf), axis=-1)
            y = np.clip(lane_y[worst], lower[..., 1], upper[..., 1])
            point[..., 1] = y
        return point

    def evaluate(self, states, t=0, *, moving_positions=None):
        """J and the zero-case flag at each state at sub-step ``t`` (the box minimum on ``[x, x]``).

        Parameters
        ----------
        states : array_like
            States, shape (..., p) with p >= 4.
        t : int or array_like
            Absolute sub-step index.
        moving_positions : None
            Not used by this family (its obstacles are boxes per sub-step): must be None.

        Returns
        -------
        reward, collided : numpy.ndarray
            Shape (...).
        """
        if moving_positions is not None:
            raise InputError("DrivingReward has no moving discs: moving_positions must be None")
        x = self._check_states("states", states)
        return self.box_minimum_raw(x, x, t)

    def box_argmin(self, lower, upper, t=0) -> np.ndarray:
        """A state of each box where J attains `box_minimum`, for boxes where it is exact.

        For a box that does not collide, the free minimiser (`free_argmin`). For a box
        that collides, a colliding state: the box itself when degenerate in position and
        heading; otherwise, at a fixed heading, a position whose rectangle meets an
        obstacle box (an obstacle collision; a witness found by a small LP).

        Parameters
        ----------
        lower, upper : array_like, shape (p,)
            One box (p >= 4), ``lower <= upper``.
        t : int
            Absolute sub-step index.

        Returns
        -------
        numpy.ndarray, shape (p,)

        Raises
        ------
        InputError
            If the box collides only through the road test or over a heading interval,
            where the minimum is a sound bound and no witness need exist.
        """
        lo, hi = self._check_box(lower, upper)
        if lo.ndim != 1:
            raise DimensionError(f"box_argmin takes one box of shape (p,), got shape {lo.shape}")
        _, collided = self.box_minimum_raw(lo, hi, t)
        if not collided:
            return self.free_argmin(lo, hi)
        if np.array_equal(lo[:4], hi[:4]):
            return lo.copy()
        row = int(t) - self.time_offset
        if lo[3] != hi[3] or not 0 <= row <= self.horizon:
            raise InputError("no witness: the box collides only through a bound (heading interval or horizon)")
        witness = _obstacle_witness(self.obstacles[row], lo[:2], hi[:2], lo[3], self.length / 2, self.width / 2)
        if witness is None:
            raise InputError("no witness: the box collides only through the road test, a sound bound for boxes")
        point = lo.copy()
        point[:2] = witness
        return point

    def to_dict(self) -> dict:
        """A JSON-serialisable description, with the key ``"family"``."""
        return {
            "family": "driving",
            "obstacles_shape": list(self.obstacles.shape),
            "time_offset": self.time_offset,
            "road": None if self.road is None else self.road.to_dict(),
            "off_road_margin": self.off_road_margin,
            "length": self.length,
            "width": self.width,
            "speed_weight": self.speed_weight,
            "max_speed": self.max_speed,
            "lane_weight": self.lane_weight,
            "lane_values": None if self.lane_values is None else self.lane_values.tolist(),
            "lane_width": self.lane_width,
            "lane_origin": self.lane_origin,
            "goal_weight": self.goal_weight,
            "goal": None if self.goal is None else self.goal.tolist(),
            "goal_scale": self.goal_scale,
        }


def _obstacle_witness(boxes, p_lo, p_hi, psi, a, b):
    """A centre c in [p_lo, p_hi] whose rectangle (heading psi) meets one of ``boxes``, or None.

    A point q of the origin-centred rectangle inside ``O - P`` (an LP in q), then
    ``c = max(p_lo, o_lo - q)``, which lies in P and puts ``q + c`` in O.
    """
    from scipy.optimize import linprog

    u = np.array([np.cos(psi), np.sin(psi)])
    n = np.array([-np.sin(psi), np.cos(psi)])
    a, b = a + ROUNDING_MARGIN, b + ROUNDING_MARGIN
    for o in boxes:
        if not np.all(np.isfinite(o)):
            continue
        lo_b, hi_b = o[:2] - p_hi, o[2:] - p_lo
        res = linprog(
            np.zeros(2),
            A_ub=np.array([u, -u, n, -n]),
            b_ub=np.array([a, a, b, b]),
            bounds=list(zip(lo_b, hi_b)),
            method="highs",
        )
        if res.status == 0:
            q = res.x
            return np.minimum(np.maximum(p_lo, o[:2] - q), p_hi)
    return None


def world_reward(world) -> DrivingReward:
    """The reward of a driving episode, with an empty obstacle table (`DrivingReward.with_obstacles` adds them).

    Highway: `DrivingReward.highway`. T-junction: `DrivingReward.tjunction` towards the
    goal region, the part of the goal lane where the world counts the goal as reached
    (arc length from ``goal_s`` to the lane's end, centre within the lane's strip; its
    box hull, equal to it on the T-junction's straight, axis-aligned ``west_out``), so
    that the reward is highest exactly where the episode succeeds; ``d_ref`` is the
    ego's distance to the region at the start of the episode.

    Parameters
    ----------
    world : RoadWorld
        The episode (with an ego).
    """
    scenario = world.scenario
    vehicle = scenario.vehicle
    empty = np.zeros((1, 0, 4))
    if world.kind == "highway":
        return DrivingReward.highway(
            empty, 0, world.road, off_road_margin=scenario.off_road_margin, length=vehicle.length, width=vehicle.width
        )
    road = world.road
    lane = world.goal_lanes[0]
    half_width = 0.5 * float(road.widths[lane])
    ends = [world.goal_s, float(road.lengths[lane])]
    corners = np.array([road.position_at(lane, s, offset) for s in ends for offset in (-half_width, half_width)])
    goal = np.concatenate([corners.min(axis=0), corners.max(axis=0)])
    start = np.asarray(world.initial_ego[:2], dtype=float)
    outside = np.maximum(np.maximum(goal[:2] - start, start - goal[2:]), 0.0)
    scale = max(float(np.hypot(*outside)), 1e-9)
    return DrivingReward.tjunction(
        empty,
        0,
        road,
        goal,
        scale,
        off_road_margin=scenario.off_road_margin,
        length=vehicle.length,
        width=vehicle.width,
    )


def true_reward(world, reward: DrivingReward | None = None) -> float:
    """The reward in [0, 1] of the ego's true state now: 0 once it collided or left the road.

    The same terms as the planner's (`world_reward`); the collision term is the world's
    own outcome (python-fcl rectangles), not the boxes.

    Parameters
    ----------
    world : RoadWorld
        The episode (with an ego).
    reward : DrivingReward, optional
        ``world_reward(world)`` if None (pass it to avoid rebuilding it).
    """
    if world.outcome in ("collision", "off_road"):
        return 0.0
    reward = world_reward(world) if reward is None else reward
    return float(reward.free_value(np.asarray(world.ego_state, dtype=float)[None])[0])
