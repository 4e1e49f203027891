"""Reward families in [0, 1] with their exact minimum over a box of states.

The interval planner needs, for every predicted box of states, the pessimistic reward
``min_{x in [lower, upper]} J(x, t)`` (Theorem 1: the surrogate objective (11) is a
lower bound of the robust objective (10) exactly because each of its terms is a
minimum of J over a box that contains the true state). Each family (a `RewardFamily`)
gives

* ``value(states, t)`` / ``evaluate(states, t)``: J at points (and the collision flag);
* ``box_minimum(lower, upper, t) -> (reward, collided)``: the EXACT minimum over the
  box, vectorised over leading dimensions, and ``box_argmin`` a point of the box that
  attains it (for tests and diagnostics);
* ``box_minimum_raw``: the same without argument checks;
* ``kernel_params``: the family's parameters for its compiled kernel.

The box minimum has ONE implementation per family, the compiled kernel in
`minimaxplan.scenarios.compiled_rewards` (the compiled-reward protocol of
`minimaxplan.kernels`): ``box_minimum_raw`` runs it over the boxes through
`minimaxplan.kernels.box_minima`, and the planners' compiled engine inlines it.

``t`` is the absolute sub-step index (moving obstacles' predicted boxes depend on
it); a scalar or an array broadcasting against the leading dimensions.

Rewards read full states: each family holds the indices of the coordinates it uses
(``position_indices`` for the robot's planar position, which the collision term always
reads). A state array whose last axis is just the position works with the default
``position_indices=(0, 1)``.

Collision (the paper's beta(x), Section IV): a state collides at sub-step t when the
robot's disc (radius ``robot_radius``) around its position meets a static obstacle
disc or, for a moving obstacle, a disc of its radius centred anywhere in its predicted
box at t (at points, given the true positions of the moving obstacles through
``moving_positions``, the disc at that position). A box collides when one of its
points does; then its minimum reward is 0 (the DESIGN errata: the reference code tests
only four corners).
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from minimaxplan.kernels import box_minima
from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.models.validation import as_count, as_finite_array, as_positive_scalar, as_real_scalar, frozen_copy

from .compiled_rewards import GoalParams, SpeedLaneParams, collision_params
from .geometry import CircularObstacles, MovingObstacles, box_box_sq_distance, box_point_sq_distance

__all__ = ["GoalReward", "RewardFamily", "SpeedLaneReward"]

#: Two weights "sum to one" when they do to this absolute tolerance.
WEIGHT_SUM_TOL = 1e-12


def _as_index_tuple(name: str, value, *, length: int | None = None) -> tuple[int, ...]:
    if isinstance(value, (str, bytes)):
        raise InputError(f"{name} must be a sequence of integers, got {value!r}")
    try:
        items = tuple(value)
    except TypeError:
        raise InputError(f"{name} must be a sequence of integers, got {value!r}") from None
    # Each index is an integer >= 0 (not a float, a bool or numeric text).
    try:
        indices = tuple(as_count(name, i, minimum=0) for i in items)
    except InputError:
        raise InputError(f"{name} must hold nonnegative integers, got {value!r}") from None
    if length is not None and len(indices) != length:
        raise DimensionError(f"{name} must have length {length}, got length {len(indices)}")
    if len(set(indices)) != len(indices):
        raise InputError(f"{name} must not repeat an index, got {indices}")
    return indices


def _selector(indices: tuple[int, ...]) -> slice | list[int]:
    """A basic slice when the indices are contiguous (a view, no copy), else the index list."""
    if indices == tuple(range(indices[0], indices[0] + len(indices))):
        return slice(indices[0], indices[0] + len(indices))
    return list(indices)


class _CollisionTerm:
    """beta(x) of the paper: robot disc against static discs and moving discs' predicted boxes.

    Over boxes it is evaluated by the families' compiled kernels
    (`minimaxplan.scenarios.compiled_rewards`); here: at points given the moving
    obstacles' true positions, and the witness points of `RewardFamily.box_argmin`.
    """

    def __init__(self, obstacles, moving_obstacles, robot_radius, position_indices):
        if obstacles is None:
            obstacles = CircularObstacles.empty()
        if moving_obstacles is None:
            moving_obstacles = MovingObstacles.empty()
        if not isinstance(obstacles, CircularObstacles):
            raise InputError(f"obstacles must be CircularObstacles or None, got {type(obstacles).__name__}")
        if not isinstance(moving_obstacles, MovingObstacles):
            raise InputError(f"moving_obstacles must be MovingObstacles or None, got {type(moving_obstacles).__name__}")
        self.obstacles = obstacles
        self.moving = moving_obstacles
        self.robot_radius = as_positive_scalar("robot_radius", robot_radius, allow_zero=True)
        self.position_indices = _as_index_tuple("position_indices", position_indices, length=2)
        self.pos = _selector(self.position_indices)
        self.reach_sq = (obstacles.radii + self.robot_radius) ** 2
        self.moving_reach_sq = (moving_obstacles.radii + self.robot_radius) ** 2
        self.has_static = len(obstacles) > 0
        self.has_moving = len(moving_obstacles) > 0

    def points(self, positions, moving_positions):
        """Whether each position (..., 2) collides, the moving obstacles at ``moving_positions`` (m, 2)."""
        hit = np.zeros(positions.shape[:-1], dtype=bool)
        if self.has_static:
            hit |= np.any(box_point_sq_distance(positions, positions, self.obstacles.centers) <= self.reach_sq, axis=-1)
        mp = as_finite_array("moving_positions", moving_positions, (len(self.moving), 2))
        if self.has_moving:
            hit |= np.any(box_point_sq_distance(positions, positions, mp) <= self.moving_reach_sq, axis=-1)
        return hit

    def witness(self, lower, upper, t):
        """For each box that collides, a colliding point of the box (positions (..., 2)); else ``lower``.

        The point of the box closest to the first obstacle it meets: ``clip(c, lower,
        upper)`` for a disc centred at c, ``clip(other_lower, lower, upper)`` for a
        moving obstacle's box (closest to that box on every axis).
        """
        shape = np.broadcast_shapes(lower.shape, upper.shape)
        out = np.broadcast_to(lower, shape).copy()
        found = np.zeros(shape[:-1], dtype=bool)
        candidates = []
        if self.has_static:
            centers = self.obstacles.centers
            d2 = box_point_sq_distance(lower, upper, centers)
            candidates.append((d2 <= self.reach_sq, np.clip(centers, lower[..., None, :], upper[..., None, :])))
        if self.has_moving:
            olo, ohi = self.moving.boxes(t)
            meets = box_box_sq_distance(lower, upper, olo, ohi) <= self.moving_reach_sq
            candidates.append((meets, np.clip(olo, lower[..., None, :], upper[..., None, :])))
        for meets, points in candidates:
            meets = np.broadcast_to(meets, shape[:-1] + meets.shape[-1:])
            points = np.broadcast_to(points, shape[:-1] + points.shape[-2:])
            first = np.argmax(meets, axis=-1)
            take = meets.any(axis=-1) & ~found
            chosen = np.take_along_axis(points, first[..., None, None], axis=-2)[..., 0, :]
            out[take] = chosen[take]
            found |= take
        return out

    def to_dict(self):
        return {
            "obstacles": self.obstacles.to_dict(),
            "moving_obstacles": self.moving.to_dict(),
            "robot_radius": self.robot_radius,
            "position_indices": list(self.position_indices),
        }


class RewardFamily(abc.ABC):
    """The base of the reward families ``J(x, t) = beta(x, t) * f(x)``, in [0, 1].

    beta is the collision term shared by every family (0 when the robot's disc meets an
    obstacle, see the module docstring), f the family's own term. A family implements
    the hooks below; the base derives from them the checked API (`value`, `evaluate`,
    `box_minimum`, `box_argmin`) and `box_minimum_raw`, which runs the family's ONE
    box-minimum implementation, its compiled kernel, through
    `minimaxplan.kernels.box_minima`.

    This is the `minimaxplan.kernels.CompiledBoxReward` protocol that `IntervalModel`
    and `PointModel` read (``box_minimum``, ``box_minimum_raw``, ``min_state_dim``,
    ``kernel_params``); a user's reward may implement that protocol directly instead
    (``docs/rewards.md``).

    Notes
    -----
    Exactness (Theorem 1 needs the true minimum over each box): when the box, grown by
    the robot's disc, meets an obstacle, some state of the box has beta = 0 and the
    minimum is 0; otherwise beta = 1 on the whole box and the minimum is that of f,
    which each family derives in closed form (see its Notes).
    """

    _collision: _CollisionTerm

    @property
    @abc.abstractmethod
    def kernel_params(self) -> Any:
        """The parameters of the family's compiled box minimum (a registered namedtuple)."""

    @property
    @abc.abstractmethod
    def used_indices(self) -> tuple[int, ...]:
        """The state coordinates the reward reads (positions included)."""

    @abc.abstractmethod
    def free_value(self, states: np.ndarray) -> np.ndarray:
        """f at each state: the reward where nothing collides.

        Parameters
        ----------
        states : numpy.ndarray
            States, shape (..., p), checked by the caller (`value`).

        Returns
        -------
        numpy.ndarray
            f at each state, shape (...), in [0, 1].
        """

    @abc.abstractmethod
    def free_argmin(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        """A state of each box where f attains its minimum over the box.

        Parameters
        ----------
        lower, upper : numpy.ndarray
            Corners of the boxes, shape (..., p), ``lower <= upper``, checked by the
            caller (`box_argmin`).

        Returns
        -------
        numpy.ndarray
            One state per box, shape (..., p), inside the box.
        """

    @abc.abstractmethod
    def to_dict(self) -> dict:
        """A JSON-serialisable description, with the key ``"family"``."""

    @property
    def min_state_dim(self) -> int:
        """The smallest state dimension this reward can read."""
        return max(self.used_indices) + 1

    def _check_states(self, name, states):
        x = as_finite_array(name, states)
        if x.ndim < 1 or x.shape[-1] < self.min_state_dim:
            raise DimensionError(
                f"{name} must have shape (..., p) with p >= {self.min_state_dim} (indices {sorted(self.used_indices)}), "
                f"got shape {x.shape}"
            )
        return x

    def _check_box(self, lower, upper):
        lo = self._check_states("lower", lower)
        hi = self._check_states("upper", upper)
        if lo.shape != hi.shape:
            raise DimensionError(f"lower and upper must have the same shape, got {lo.shape} and {hi.shape}")
        if np.any(lo > hi):
            raise InputError("lower must be <= upper in every coordinate")
        return lo, hi

    def value(self, states: np.ndarray, t: int = 0, *, moving_positions: np.ndarray | None = None) -> np.ndarray:
        """J at each state; see `evaluate`.

        Parameters
        ----------
        states : array_like
            States, shape (..., p).
        t : int
            Absolute sub-step index (where the moving obstacles' boxes are predicted).
        moving_positions : array_like, optional
            The moving obstacles' true positions, shape (m, 2), in metres.

        Returns
        -------
        numpy.ndarray
            J at each state, shape (...), in [0, 1].
        """
        return self.evaluate(states, t, moving_positions=moving_positions)[0]

    def evaluate(
        self, states: np.ndarray, t: int = 0, *, moving_positions: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """J and the collision flag at each state at sub-step ``t``.

        Parameters
        ----------
        states : array_like
            States, shape (..., p).
        t : int
            Absolute sub-step index.
        moving_positions : array_like, optional
            The moving obstacles' true positions, shape (m, 2) (a simulated world's
            view). Without them a state collides when it can meet a moving obstacle
            anywhere in its predicted box at ``t`` (the box minimum's verdict on the
            degenerate box ``[x, x]``).

        Returns
        -------
        reward : numpy.ndarray
            J at each state, shape (...), in [0, 1] (0 where it collides).
        collided : numpy.ndarray
            Bool, shape (...).

        Raises
        ------
        DimensionError
            If ``states`` has fewer than `min_state_dim` coordinates, or
            ``moving_positions`` is not (m, 2).
        NonFiniteError
            If an entry is NaN or infinite.
        """
        x = self._check_states("states", states)
        if moving_positions is None:
            collided = self.box_minimum_raw(x, x, t)[1]
        else:
            collided = self._collision.points(x[..., self._collision.pos], moving_positions)
        reward = np.where(collided, 0.0, self.free_value(x))
        return reward, collided

    def box_minimum(self, lower, upper, t=0) -> tuple[np.ndarray, np.ndarray]:
        """The exact ``min_{x in [lower, upper]} J(x, t)`` and whether the box may collide.

        Parameters
        ----------
        lower, upper
            Boxes of states, shape (..., p).
        t
            Absolute sub-step index, scalar or broadcasting against the leading shape.

        Returns
        -------
        reward, collided
            Arrays of shape (...): the minimum (0 where ``collided``) and whether some
            state of the box collides.
        """
        lo, hi = self._check_box(lower, upper)
        return self.box_minimum_raw(lo, hi, t)

    def box_minimum_raw(self, lower: np.ndarray, upper: np.ndarray, t=0) -> tuple[np.ndarray, np.ndarray]:
        """`box_minimum` without argument checks.

        Runs the family's compiled kernel over the boxes (`minimaxplan.kernels.box_minima`):
        bit for bit the minima of the planners' compiled engine.

        Parameters
        ----------
        lower, upper : numpy.ndarray
            Float arrays of shape (..., p) with ``lower <= upper`` (not checked).
        t : int
            Absolute sub-step index.

        Returns
        -------
        minimum : numpy.ndarray
            The exact minimum of J over each box, shape (...).
        collided : numpy.ndarray
            Bool, shape (...): the box can meet an obstacle (its minimum is 0).

        Notes
        -----
        The minimum over the predicted interval is the pessimistic reward J_n of
        eq. (11) that the robust planners sum.
        """
        return box_minima(self.kernel_params, lower, upper, t)

    def box_argmin(self, lower: np.ndarray, upper: np.ndarray, t: int = 0) -> np.ndarray:
        """A state of each box where J attains `box_minimum`.

        Parameters
        ----------
        lower, upper : array_like
            Corners of the boxes, shape (..., p), ``lower <= upper``.
        t : int
            Absolute sub-step index.

        Returns
        -------
        numpy.ndarray
            One state per box, shape (..., p): a colliding point of the box if the box
            can collide, else a minimiser of f.

        Raises
        ------
        DimensionError, InputError
            If the boxes are malformed (shapes, ``lower > upper``, non-finite entries).
        """
        lo, hi = self._check_box(lower, upper)
        pos = self._collision.pos
        point = self.free_argmin(lo, hi)
        collided = self.box_minimum_raw(lo, hi, t)[1]
        if np.any(collided):
            witness = self._collision.witness(lo[..., pos], hi[..., pos], t)
            sub = point[..., pos]
            sub[collided] = witness[collided]
            point[..., pos] = sub
        return point


@dataclass(frozen=True, eq=False)
class GoalReward(RewardFamily):
    """Goal reaching, ``J(x) = beta(x) / (1 + ||pos(x) - goal||_2)`` (paper, Section IV).

    Parameters
    ----------
    goal
        The goal position, shape (2,).
    obstacles
        Static discs, or None.
    moving_obstacles
        Moving discs with predicted boxes, or None.
    robot_radius
        The robot's footprint radius, >= 0.
    position_indices
        Where the planar position sits in the state.

    Notes
    -----
    Exact box minimum: if the box grown by the footprint meets an obstacle, some state
    of the box has beta = 0 and the minimum is 0. Otherwise beta = 1 on the whole box
    and ``1 / (1 + d)`` is decreasing in the distance d to the goal, so the minimum is
    at the point of the box farthest from the goal. The distance to the goal is a
    separable sum of squares, each term maximised at the end of its interval farther
    from the goal: the farthest point is the corner ``where(|lo - g| >= |hi - g|, lo, hi)``,
    at distance ``||max(|lo - g|, |hi - g|)||`` (the reference code uses the box centre,
    which is not a lower bound).
    """

    goal: np.ndarray
    obstacles: CircularObstacles | None = None
    moving_obstacles: MovingObstacles | None = None
    robot_radius: float = 0.0
    position_indices: tuple = (0, 1)
    # Derived in __post_init__ (not constructor arguments).
    _kernel_params: GoalParams = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "goal", frozen_copy(as_finite_array("goal", self.goal, (2,))))
        collision = _CollisionTerm(self.obstacles, self.moving_obstacles, self.robot_radius, self.position_indices)
        object.__setattr__(self, "_collision", collision)
        object.__setattr__(self, "obstacles", collision.obstacles)
        object.__setattr__(self, "moving_obstacles", collision.moving)
        object.__setattr__(self, "robot_radius", collision.robot_radius)
        object.__setattr__(self, "position_indices", collision.position_indices)
        object.__setattr__(self, "_kernel_params", GoalParams(collision_params(collision), self.goal))

    @property
    def kernel_params(self) -> GoalParams:
        """`GoalParams` of the compiled box minimum."""
        return self._kernel_params

    @property
    def used_indices(self) -> tuple[int, ...]:
        """``position_indices``."""
        return self.position_indices

    def free_value(self, states: np.ndarray) -> np.ndarray:
        """``1 / (1 + ||pos(x) - goal||)`` at each state.

        Parameters
        ----------
        states : numpy.ndarray
            States, shape (..., p), checked by the caller (`value`).

        Returns
        -------
        numpy.ndarray
            f at each state, shape (...), in [0, 1].
        """
        return 1.0 / (1.0 + np.linalg.norm(states[..., self._collision.pos] - self.goal, axis=-1))

    def free_argmin(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        """The corner of each box farthest from the goal (other coordinates at ``lower``).

        Parameters
        ----------
        lower, upper : numpy.ndarray
            Corners of the boxes, shape (..., p), ``lower <= upper``, checked by the
            caller (`box_argmin`).

        Returns
        -------
        numpy.ndarray
            One state per box, shape (..., p), inside the box.
        """
        pos = self._collision.pos
        point = lower.copy()
        lo, hi = lower[..., pos], upper[..., pos]
        point[..., pos] = np.where(np.abs(lo - self.goal) >= np.abs(hi - self.goal), lo, hi)
        return point

    def with_obstacles(
        self, obstacles: CircularObstacles | None = None, moving_obstacles: MovingObstacles | None = None
    ) -> GoalReward:
        """The same reward with other obstacles (e.g. the pedestrians observed now).

        Parameters
        ----------
        obstacles : CircularObstacles, optional
            New static discs (default: keep this reward's).
        moving_obstacles : MovingObstacles, optional
            New moving discs (default: keep this reward's).

        Returns
        -------
        GoalReward
            Same goal, robot radius and position indices.
        """
        return GoalReward(
            self.goal,
            obstacles=self.obstacles if obstacles is None else obstacles,
            moving_obstacles=self.moving_obstacles if moving_obstacles is None else moving_obstacles,
            robot_radius=self.robot_radius,
            position_indices=self.position_indices,
        )

    def to_dict(self) -> dict:
        return {"family": "goal", "goal": self.goal.tolist(), **self._collision.to_dict()}


@dataclass(frozen=True, eq=False)
class SpeedLaneReward(RewardFamily):
    """Speed tracking with a lane term, the vehicle reward of the paper's Section IV.

    ``J(x) = beta(x) * (speed_weight * (1 - min(|s(x) - target_speed| / speed_range, 1))
    + lane_weight * lane(y) / (n_lanes - 1))`` with ``speed_weight + lane_weight = 1``,
    so J lies in [0, 1] (the paper writes the vehicle "cost" with c2 v / v_max,
    c3 l_c / (l_s - 1) and a collision penalty; this is its [0, 1] reward form, with
    speed tracking instead of raw speed).

    Parameters
    ----------
    target_speed, speed_range
        The tracked speed and the deviation at which the speed term reaches 0 (> 0).
    speed_indices
        One index (the speed s is that signed coordinate, e.g. the longitudinal
        velocity) or two (s is the Euclidean norm of those velocity coordinates).
    lateral_index
        The lateral position y; ``lane(y) = clip(floor(y / lane_width + 1/2), 0,
        n_lanes - 1)`` (lane k is centred at ``y = k * lane_width``; a higher lane index
        is the preferred, "right", lane as in the paper's l_c / (l_s - 1)). May be None
        when ``lane_weight`` is 0.
    lane_width, n_lanes
        Lane geometry (> 0, >= 2).
    speed_weight, lane_weight
        Nonnegative, summing to 1.
    obstacles, moving_obstacles, robot_radius, position_indices
        The collision term, as in `GoalReward`.

    Notes
    -----
    Exact box minimum (no collision): the speed coordinates and y are different state
    coordinates, so the minimum of the weighted sum is the weighted sum of the minima.
    Over a box the speed s takes exactly the values of an interval [s_lo, s_hi] (the box
    is connected and s continuous): ``[lo, hi]`` of the coordinate for one index; for
    two, ``s_lo = ||clip(0, lo, hi)||`` (the box point nearest the origin) and ``s_hi =
    ||max(|lo|, |hi|)||`` (the farthest corner). The deviation ``|s - target|`` is convex
    in s, so its maximum over the interval is at an end, and the speed term's minimum
    is ``1 - min(max(|s_lo - target|, |s_hi - target|) / speed_range, 1)``. lane(y) is
    nondecreasing, so the lane term's minimum is at ``y = lo_y``. With a collision
    possible anywhere in the box, the minimum is 0.
    """

    target_speed: float
    speed_range: float
    speed_indices: tuple = (2,)
    lateral_index: int | None = 1
    lane_width: float = 4.0
    n_lanes: int = 2
    speed_weight: float = 0.8
    lane_weight: float = 0.2
    obstacles: CircularObstacles | None = None
    moving_obstacles: MovingObstacles | None = None
    robot_radius: float = 0.0
    position_indices: tuple = (0, 1)
    # Derived in __post_init__ (not constructor arguments).
    _speed_sel: slice | list[int] = field(init=False, repr=False, compare=False)
    _kernel_params: SpeedLaneParams = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "target_speed", as_real_scalar("target_speed", self.target_speed))
        object.__setattr__(self, "speed_range", as_positive_scalar("speed_range", self.speed_range))
        speed = _as_index_tuple("speed_indices", self.speed_indices)
        if len(speed) not in (1, 2):
            raise DimensionError(f"speed_indices must have length 1 or 2, got length {len(speed)}")
        object.__setattr__(self, "speed_indices", speed)
        c1 = as_positive_scalar("speed_weight", self.speed_weight, allow_zero=True)
        c2 = as_positive_scalar("lane_weight", self.lane_weight, allow_zero=True)
        if abs(c1 + c2 - 1.0) > WEIGHT_SUM_TOL:
            raise InputError(f"speed_weight + lane_weight must be 1, got {c1} + {c2} = {c1 + c2}")
        object.__setattr__(self, "speed_weight", c1)
        object.__setattr__(self, "lane_weight", c2)
        if self.lateral_index is None:
            if c2 != 0:
                raise InputError("lateral_index is None, so lane_weight must be 0")
        else:
            (lateral,) = _as_index_tuple("lateral_index", (self.lateral_index,))
            if lateral in speed:
                raise InputError(f"lateral_index {lateral} must differ from speed_indices {speed}")
            object.__setattr__(self, "lateral_index", lateral)
        object.__setattr__(self, "lane_width", as_positive_scalar("lane_width", self.lane_width))
        object.__setattr__(self, "n_lanes", as_count("n_lanes", self.n_lanes, minimum=2))
        try:
            road_width = float(self.n_lanes) * self.lane_width
        except OverflowError:
            road_width = float("inf")
        if not np.isfinite(road_width):
            raise InputError(f"n_lanes * lane_width (the road's width) must be finite, got n_lanes = {self.n_lanes}")
        collision = _CollisionTerm(self.obstacles, self.moving_obstacles, self.robot_radius, self.position_indices)
        if set(speed) & set(collision.position_indices):
            raise InputError(f"speed_indices {speed} must differ from position_indices {collision.position_indices}")
        object.__setattr__(self, "_collision", collision)
        object.__setattr__(self, "obstacles", collision.obstacles)
        object.__setattr__(self, "moving_obstacles", collision.moving)
        object.__setattr__(self, "robot_radius", collision.robot_radius)
        object.__setattr__(self, "position_indices", collision.position_indices)
        object.__setattr__(self, "_speed_sel", _selector(speed))
        params = SpeedLaneParams(
            collision_params(collision),
            np.array(speed, dtype=np.int64),
            -1 if self.lateral_index is None else self.lateral_index,
            self.target_speed,
            self.speed_range,
            c1,
            c2,
            self.lane_width,
            float(self.n_lanes),
        )
        object.__setattr__(self, "_kernel_params", params)

    @property
    def kernel_params(self) -> SpeedLaneParams:
        """`SpeedLaneParams` of the compiled box minimum."""
        return self._kernel_params

    @property
    def used_indices(self) -> tuple[int, ...]:
        """Positions, speed coordinates and the lateral coordinate (when there is a lane term)."""
        extra = () if self.lateral_index is None else (self.lateral_index,)
        return self.position_indices + self.speed_indices + extra

    def _lane_term(self, y):
        lane = np.clip(np.floor(y / self.lane_width + 0.5), 0, self.n_lanes - 1)
        return lane / (self.n_lanes - 1)

    def _speed_term(self, deviation):
        return 1.0 - np.minimum(deviation / self.speed_range, 1.0)

    def _speed(self, x):
        v = x[..., self._speed_sel]
        return v[..., 0] if len(self.speed_indices) == 1 else np.sqrt(np.einsum("...i,...i->...", v, v))

    def _speed_interval(self, lower, upper):
        lo, hi = lower[..., self._speed_sel], upper[..., self._speed_sel]
        if len(self.speed_indices) == 1:
            return lo[..., 0], hi[..., 0]
        near = np.clip(0.0, lo, hi)
        far = np.maximum(np.abs(lo), np.abs(hi))
        return np.sqrt(np.einsum("...i,...i->...", near, near)), np.sqrt(np.einsum("...i,...i->...", far, far))

    def free_value(self, states: np.ndarray) -> np.ndarray:
        """The speed and lane terms at each state.

        Parameters
        ----------
        states : numpy.ndarray
            States, shape (..., p), checked by the caller (`value`).

        Returns
        -------
        numpy.ndarray
            f at each state, shape (...), in [0, 1].
        """
        reward = self.speed_weight * self._speed_term(np.abs(self._speed(states) - self.target_speed))
        if self.lane_weight:
            reward = reward + self.lane_weight * self._lane_term(states[..., self.lateral_index])
        return reward

    def free_argmin(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        """A state of each box at the worst end of the speed interval (the lane term's minimiser is ``lower``).

        Parameters
        ----------
        lower, upper : numpy.ndarray
            Corners of the boxes, shape (..., p), ``lower <= upper``, checked by the
            caller (`box_argmin`).

        Returns
        -------
        numpy.ndarray
            One state per box, shape (..., p), inside the box.
        """
        point = lower.copy()
        lo, hi = lower[..., self._speed_sel], upper[..., self._speed_sel]
        s_lo, s_hi = self._speed_interval(lower, upper)
        low_is_worse = (np.abs(s_lo - self.target_speed) >= np.abs(s_hi - self.target_speed))[..., None]
        if len(self.speed_indices) == 1:
            point[..., self._speed_sel] = np.where(low_is_worse, lo, hi)
        else:
            nearest = np.clip(0.0, lo, hi)
            farthest = np.where(np.abs(lo) >= np.abs(hi), lo, hi)
            point[..., self._speed_sel] = np.where(low_is_worse, nearest, farthest)
        return point

    def to_dict(self) -> dict:
        return {
            "family": "speed_lane",
            "target_speed": self.target_speed,
            "speed_range": self.speed_range,
            "speed_indices": list(self.speed_indices),
            "lateral_index": self.lateral_index,
            "lane_width": self.lane_width,
            "n_lanes": self.n_lanes,
            "speed_weight": self.speed_weight,
            "lane_weight": self.lane_weight,
            **self._collision.to_dict(),
        }
