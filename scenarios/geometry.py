"""Planar obstacle geometry: static discs, moving discs with growing predicted boxes.

Two implementations answer the same questions:

* vectorised (``*_meet_*`` and ``*_distance`` functions, the methods of
  `CircularObstacles` and `MovingObstacles`): many boxes against many obstacles in
  one call, each pair by the project's one box-disc gap
  `minimaxplan.kernels.box_gap_sq` (the gap the reward kernels' collision test uses);
* python-fcl (the ``fcl_*`` functions): the authoritative cross-check used by the
  tests, and the collision test of the simulated worlds (robot disc against obstacles).

Everything is planar. fcl works in 3-D, so a planar box becomes an ``fcl.Box`` of unit
height centred on the plane z = 0 and a disc becomes an ``fcl.Sphere`` centred on that
plane: the closest points of two such shapes can always be taken in the plane, so the
3-D distance equals the planar one. Only fcl queries that are exact are used:
box-sphere and sphere-sphere distances and collisions, and box-box collisions. Not
used: ``fcl.Cylinder`` (its box distance comes from GJK and is off by up to ~0.2 on
random cases) and box-box DISTANCES, which GJK gets wrong when faces are aligned
(``[0, 1]^2`` against ``[0, 1] x [2, 4]`` gives sqrt(2) instead of 1, with either GJK
solver of python-fcl 0.7). "Does box B meet box A grown by a disc of radius rho" is
instead answered exactly by the rounded-rectangle decomposition: A grown by rho in x,
A grown by rho in y, and the four discs of radius rho at A's corners.

Closed sets throughout: touching counts as meeting.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from minimaxplan.kernels import box_gaps_sq
from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.models.validation import as_count, as_finite_array, as_positive_scalar, check_shape, frozen_copy

__all__ = [
    "CircularObstacles",
    "MovingObstacles",
    "box_point_sq_distance",
    "box_box_sq_distance",
    "boxes_meet_circles",
    "boxes_meet_boxes",
    "fcl_box_circle_distance",
    "fcl_boxes_meet_circles",
    "fcl_box_meets_grown_box",
    "fcl_boxes_meet_boxes",
    "fcl_disc_collisions",
]

#: Height of the slab that lifts planar shapes into fcl's 3-D world (any value > 0 works).
FCL_SLAB_HEIGHT = 1.0


# --------------------------------------------------------------------- vectorised
def _pairwise_gaps_sq(lower, upper, other_lower, other_upper) -> np.ndarray:
    """`box_gap_sq` of every broadcast pair of boxes (arrays (..., 2)), shape (...)."""
    shape = np.broadcast_shapes(lower.shape, upper.shape, other_lower.shape, other_upper.shape)
    n = math.prod(shape[:-1])
    rows = [
        np.ascontiguousarray(np.broadcast_to(a, shape), dtype=float).reshape(n, 2)
        for a in (lower, upper, other_lower, other_upper)
    ]
    out = np.empty(n)
    box_gaps_sq(*rows, out)  # type: ignore[call-arg]  # numba's Dispatcher stub does not declare the compiled signature
    return out.reshape(shape[:-1])


def box_point_sq_distance(lower: np.ndarray, upper: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Squared distance from each box to each point.

    Parameters
    ----------
    lower, upper
        Box corners, shape (..., 2).
    points
        Shape (n, 2).

    Returns
    -------
    ndarray, shape (..., n)
        ``||c - clip(c, lower, upper)||^2`` for every box and point c (`box_gap_sq`
        against the degenerate box ``[c, c]``).
    """
    points = np.asarray(points)
    return _pairwise_gaps_sq(lower[..., None, :], upper[..., None, :], points, points)


def box_box_sq_distance(
    lower: np.ndarray, upper: np.ndarray, other_lower: np.ndarray, other_upper: np.ndarray
) -> np.ndarray:
    """Squared distance between boxes, broadcasting ``(..., 1, 2)`` against ``(n, 2)``-like shapes.

    Parameters
    ----------
    lower, upper
        Boxes, shape (..., 2).
    other_lower, other_upper
        Boxes, shape (..., n, 2) broadcastable against ``lower[..., None, :]``.

    Returns
    -------
    ndarray, shape (..., n)
        The squared Euclidean distance between each pair (0 when they intersect), by
        `box_gap_sq`.
    """
    return _pairwise_gaps_sq(lower[..., None, :], upper[..., None, :], np.asarray(other_lower), np.asarray(other_upper))


def boxes_meet_circles(
    lower: np.ndarray, upper: np.ndarray, centers: np.ndarray, radii: np.ndarray, margin: float = 0.0
) -> np.ndarray:
    """Whether each box, grown by a disc of radius ``margin``, meets any of the discs.

    Exact: a box grown by a disc meets the disc (c, R) iff the distance from c to the
    box is at most ``R + margin``. Raw arrays, no validation (planner hot path).

    Parameters
    ----------
    lower, upper
        Shape (..., 2).
    centers, radii
        Shapes (n, 2) and (n,).
    margin
        The robot's footprint radius, >= 0.

    Returns
    -------
    ndarray of bool, shape (...)
    """
    if centers.shape[0] == 0:
        return np.zeros(np.broadcast_shapes(lower.shape, upper.shape)[:-1], dtype=bool)
    reach = radii + margin
    return np.any(box_point_sq_distance(lower, upper, centers) <= reach * reach, axis=-1)


def boxes_meet_boxes(
    lower: np.ndarray,
    upper: np.ndarray,
    other_lower: np.ndarray,
    other_upper: np.ndarray,
    radii: np.ndarray,
    margin: float = 0.0,
) -> np.ndarray:
    """Whether each box meets any of the other boxes grown by ``radii + margin``.

    This answers "can a disc of radius ``margin`` centred in the box meet a disc of
    radius ``radii[j]`` centred in the other box j": exactly when the distance between
    the two boxes is at most ``radii[j] + margin``.

    Parameters
    ----------
    lower, upper
        Shape (..., 2).
    other_lower, other_upper
        Shape (..., n, 2) (broadcastable against ``lower[..., None, :]``).
    radii
        Shape (n,).
    margin
        The robot's footprint radius, >= 0.

    Returns
    -------
    ndarray of bool, shape (...)
    """
    if radii.shape[0] == 0:
        return np.zeros(np.broadcast_shapes(lower.shape, upper.shape)[:-1], dtype=bool)
    reach = radii + margin
    return np.any(box_box_sq_distance(lower, upper, other_lower, other_upper) <= reach * reach, axis=-1)


# ------------------------------------------------------------------ obstacle values
@dataclass(frozen=True, eq=False)
class CircularObstacles:
    """Static discs ``{p : ||p - centers[j]|| <= radii[j]}`` in the plane.

    Parameters
    ----------
    centers
        Shape (n, 2); n = 0 (no obstacle) is allowed.
    radii
        Shape (n,), each > 0.
    """

    centers: np.ndarray
    radii: np.ndarray

    def __post_init__(self) -> None:
        centers = as_finite_array("centers", self.centers)
        if centers.size == 0:
            centers = centers.reshape(0, 2)
        check_shape("centers", centers, (None, 2))
        radii = as_finite_array("radii", self.radii)
        if radii.size == 0:
            radii = radii.reshape(0)
        check_shape("radii", radii, (centers.shape[0],))
        if np.any(radii <= 0):
            raise InputError(f"radii must be > 0, got min {radii.min():.6g}")
        object.__setattr__(self, "centers", frozen_copy(centers))
        object.__setattr__(self, "radii", frozen_copy(radii))

    @classmethod
    def empty(cls) -> CircularObstacles:
        """No obstacle at all."""
        return cls(np.zeros((0, 2)), np.zeros(0))

    def __len__(self) -> int:
        return self.centers.shape[0]

    def boxes_meet(self, lower: np.ndarray, upper: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Whether each box, grown by a disc of radius ``margin``, meets any of these discs.

        `boxes_meet_circles` against these discs; raw arrays, no validation (planner
        hot path).

        Parameters
        ----------
        lower, upper : numpy.ndarray
            Corners of the boxes, shape (..., 2), in metres.
        margin : float
            Radius of the disc the boxes are grown by (e.g. the robot's), in metres.

        Returns
        -------
        numpy.ndarray
            Bool array of shape (...).
        """
        return boxes_meet_circles(lower, upper, self.centers, self.radii, margin)

    def clearance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance from each point to the nearest disc.

        Parameters
        ----------
        points : array_like
            Shape (..., 2), in metres.

        Returns
        -------
        numpy.ndarray
            Shape (...): distance to the nearest disc's boundary, in metres, negative
            inside a disc; +inf if there is no disc.

        Raises
        ------
        DimensionError
            If ``points`` does not have a last axis of length 2.
        NonFiniteError
            If ``points`` has NaN or infinite entries.
        """
        pts = as_finite_array("points", points)
        if pts.shape[-1:] != (2,):
            raise DimensionError(f"points must have shape (..., 2), got shape {pts.shape}")
        if len(self) == 0:
            return np.full(pts.shape[:-1], np.inf)
        d = np.linalg.norm(pts[..., None, :] - self.centers, axis=-1) - self.radii
        return d.min(axis=-1)

    def to_dict(self) -> dict:
        """The discs as plain lists (JSON-ready).

        Returns
        -------
        dict
            ``{"centers": [[x, y], ...], "radii": [r, ...]}``.
        """
        return {"centers": self.centers.tolist(), "radii": self.radii.tolist()}


@dataclass(frozen=True, eq=False)
class MovingObstacles:
    """Discs (e.g. pedestrians) moving at uncertain constant velocity, as growing boxes.

    At absolute sub-step index ``t >= time0`` the centre of obstacle j lies in the box
    ``positions[j] + velocities[j] * (t - time0) * dt
    +- (position_uncertainty[j] + velocity_uncertainty[j] * (t - time0) * dt)``
    whenever its true velocity stays within ``velocities[j] +- velocity_uncertainty[j]``
    (per axis) and its position at ``time0`` within ``positions[j] +-
    position_uncertainty[j]``. Before ``time0`` the box of ``time0`` is used.

    Parameters
    ----------
    positions, velocities
        Shape (m, 2): announced positions at ``time0`` and announced velocities.
    radii
        Shape (m,), > 0.
    velocity_uncertainty, position_uncertainty
        Half-widths, scalar or shape (m, 2), >= 0.
    dt
        Duration of one sub-step, > 0.
    time0
        The sub-step index at which ``positions`` were observed.
    """

    positions: np.ndarray
    velocities: np.ndarray
    radii: np.ndarray
    velocity_uncertainty: np.ndarray | float = 0.0
    position_uncertainty: np.ndarray | float = 0.0
    dt: float = 1.0
    time0: int = 0

    def __post_init__(self) -> None:
        positions = as_finite_array("positions", self.positions)
        if positions.size == 0:
            positions = positions.reshape(0, 2)
        check_shape("positions", positions, (None, 2))
        m = positions.shape[0]
        velocities = as_finite_array("velocities", self.velocities)
        if velocities.size == 0:
            velocities = velocities.reshape(0, 2)
        check_shape("velocities", velocities, (m, 2))
        radii = as_finite_array("radii", self.radii)
        if radii.size == 0:
            radii = radii.reshape(0)
        check_shape("radii", radii, (m,))
        if np.any(radii <= 0):
            raise InputError(f"radii must be > 0, got min {radii.min():.6g}")
        spreads = {}
        for name in ("velocity_uncertainty", "position_uncertainty"):
            value = as_finite_array(name, getattr(self, name))
            if value.ndim == 0:
                value = np.full((m, 2), float(value))
            check_shape(name, value, (m, 2))
            if np.any(value < 0):
                raise InputError(f"{name} must be >= 0")
            spreads[name] = value
        dt = as_positive_scalar("dt", self.dt)
        as_count("time0", self.time0, minimum=0)
        for name, value in (("positions", positions), ("velocities", velocities), ("radii", radii), *spreads.items()):
            object.__setattr__(self, name, frozen_copy(value))
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "time0", int(self.time0))

    @classmethod
    def empty(cls) -> MovingObstacles:
        """No moving obstacle at all.

        Returns
        -------
        MovingObstacles
            m = 0 obstacles, ``dt = 1``, ``time0 = 0``.
        """
        return cls(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0))

    def __len__(self) -> int:
        return self.positions.shape[0]

    def boxes(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted boxes of the obstacles' centres at sub-step index ``t``.

        Parameters
        ----------
        t : float or numpy.ndarray
            Absolute sub-step index (scalar or array); before ``time0`` the box of
            ``time0`` is returned.

        Returns
        -------
        lower, upper : numpy.ndarray
            Shape ``shape(t) + (m, 2)``, in metres.
        """
        elapsed = (np.maximum(np.asarray(t, dtype=float) - self.time0, 0.0) * self.dt)[..., None, None]
        centre = self.positions + self.velocities * elapsed
        half = self.position_uncertainty + self.velocity_uncertainty * elapsed
        return centre - half, centre + half

    def boxes_meet(self, lower: np.ndarray, upper: np.ndarray, t, margin: float = 0.0) -> np.ndarray:
        """Whether each box grown by ``margin`` can meet an obstacle at sub-step ``t``.

        Parameters
        ----------
        lower, upper : numpy.ndarray
            Corners of the boxes, shape (..., 2), in metres (raw arrays, no validation).
        t : float or numpy.ndarray
            Absolute sub-step index; a scalar, or an array that broadcasts against the
            leading shape of ``lower``.
        margin : float
            Radius of the disc the boxes are grown by (e.g. the robot's), in metres.

        Returns
        -------
        numpy.ndarray
            Bool array of shape (...): True if some obstacle's predicted box, grown by
            its radius, is within ``margin`` of the box.
        """
        other_lower, other_upper = self.boxes(t)
        return boxes_meet_boxes(lower, upper, other_lower, other_upper, self.radii, margin)

    def to_dict(self) -> dict:
        """The obstacles as plain lists and numbers (JSON-ready).

        Returns
        -------
        dict
            Every field of the dataclass; arrays as nested lists.
        """
        return {
            "positions": self.positions.tolist(),
            "velocities": self.velocities.tolist(),
            "radii": self.radii.tolist(),
            "velocity_uncertainty": np.asarray(self.velocity_uncertainty).tolist(),
            "position_uncertainty": np.asarray(self.position_uncertainty).tolist(),
            "dt": self.dt,
            "time0": self.time0,
        }


# --------------------------------------------------------------------- python-fcl
def _fcl():
    import fcl  # python-fcl lives in scenarios only

    return fcl


def _fcl_box(lower, upper):
    fcl = _fcl()
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    centre = (lower + upper) / 2
    size = upper - lower
    shape = fcl.Box(float(size[0]), float(size[1]), FCL_SLAB_HEIGHT)
    return fcl.CollisionObject(shape, fcl.Transform(np.array([centre[0], centre[1], 0.0])))


def _fcl_disc(center, radius):
    fcl = _fcl()
    shape = fcl.Sphere(float(radius))
    return fcl.CollisionObject(shape, fcl.Transform(np.array([float(center[0]), float(center[1]), 0.0])))


def _fcl_distance(a, b) -> float:
    """fcl's distance, with its collision marker (-1) mapped to 0."""
    fcl = _fcl()
    d = fcl.distance(a, b, fcl.DistanceRequest(), fcl.DistanceResult())
    return max(float(d), 0.0)


def fcl_box_circle_distance(lower, upper, center, radius) -> float:
    """Distance between the planar box [lower, upper] and the disc (center, radius), by fcl (0 if they meet).

    Parameters
    ----------
    lower, upper : array_like, shape (2,)
        The box's corners, m.
    center : array_like, shape (2,)
        The disc's centre, m.
    radius : float
        The disc's radius (> 0), m.
    """
    return _fcl_distance(_fcl_box(lower, upper), _fcl_disc(center, radius))


def fcl_boxes_meet_circles(lower, upper, centers, radii, margin: float = 0.0, *, tol: float = 0.0) -> np.ndarray:
    """`boxes_meet_circles` computed with fcl, one box-sphere distance query per pair (slow, authoritative).

    ``tol`` widens the test to ``distance <= margin + tol`` (for tangent cases, where
    fcl's rounding may differ from numpy's).

    Parameters
    ----------
    lower, upper : array_like, shape (..., 2)
        Box corners, m.
    centers, radii : array_like, shapes (n, 2) and (n,)
        The discs, m.
    margin : float, optional
        The robot's footprint radius, >= 0 (default 0).
    tol : float, optional
        Slack added to ``margin`` (default 0).

    Returns
    -------
    ndarray of bool, shape (...)
    """
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    flat_lo = lower.reshape(-1, 2)
    flat_hi = upper.reshape(-1, 2)
    out = np.zeros(flat_lo.shape[0], dtype=bool)
    for i in range(flat_lo.shape[0]):
        box = _fcl_box(flat_lo[i], flat_hi[i])
        out[i] = any(_fcl_distance(box, _fcl_disc(c, r)) <= margin + tol for c, r in zip(centers, radii))
    return out.reshape(lower.shape[:-1])


def _fcl_collide(a, b) -> bool:
    fcl = _fcl()
    return fcl.collide(a, b, fcl.CollisionRequest(), fcl.CollisionResult()) > 0


def fcl_box_meets_grown_box(lower, upper, other_lower, other_upper, reach: float) -> bool:
    """Whether the box [other_lower, other_upper] meets [lower, upper] grown by a disc of radius ``reach``, by fcl.

    Exact decomposition of the grown box (a rounded rectangle) into the box grown by
    ``reach`` along x, along y, and the four discs at its corners; each part is tested
    with fcl's exact box-box or box-sphere collision (touching counts).

    Parameters
    ----------
    lower, upper : array_like, shape (2,)
        The box that is grown, m.
    other_lower, other_upper : array_like, shape (2,)
        The other box, m.
    reach : float
        The radius of the growing disc, >= 0, m.
    """
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    other = _fcl_box(other_lower, other_upper)
    along_x = _fcl_box(lower - [reach, 0.0], upper + [reach, 0.0])
    along_y = _fcl_box(lower - [0.0, reach], upper + [0.0, reach])
    if _fcl_collide(other, along_x) or _fcl_collide(other, along_y):
        return True
    corners = [(lower[0], lower[1]), (lower[0], upper[1]), (upper[0], lower[1]), (upper[0], upper[1])]
    return any(_fcl_collide(other, _fcl_disc(c, reach)) for c in corners)


def fcl_boxes_meet_boxes(
    lower, upper, other_lower, other_upper, radii, margin: float = 0.0, *, tol: float = 0.0
) -> np.ndarray:
    """`boxes_meet_boxes` computed with fcl for boxes (k, 2) against other boxes (n, 2) (slow, authoritative).

    Uses `fcl_box_meets_grown_box` with ``reach = radii[j] + margin + tol``.

    Parameters
    ----------
    lower, upper : array_like, shape (k, 2)
        Box corners, m (any leading shape is flattened to k rows).
    other_lower, other_upper : array_like, shape (n, 2)
        The other boxes, m.
    radii : array_like, shape (n,)
        The other boxes' disc radii, m.
    margin : float, optional
        The robot's footprint radius, >= 0 (default 0).
    tol : float, optional
        Slack added to every reach (default 0).

    Returns
    -------
    ndarray of bool, shape (k,)
    """
    lower = np.asarray(lower, dtype=float).reshape(-1, 2)
    upper = np.asarray(upper, dtype=float).reshape(-1, 2)
    out = np.zeros(lower.shape[0], dtype=bool)
    for i in range(lower.shape[0]):
        out[i] = any(
            fcl_box_meets_grown_box(lower[i], upper[i], ol, oh, r + margin + tol)
            for ol, oh, r in zip(other_lower, other_upper, radii)
        )
    return out


def fcl_disc_collisions(position: np.ndarray, radius: float, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Which discs the disc (``position``, ``radius``) touches or overlaps.

    The simulated worlds' true collision test (robot disc against obstacles or
    pedestrians), by ``fcl.collide`` on spheres centred in the plane.

    Parameters
    ----------
    position : array_like
        Centre of the disc, shape (2,), in metres.
    radius : float
        Its radius (> 0), in metres.
    centers : array_like
        Centres of the other discs, shape (n, 2), in metres.
    radii : array_like
        Their radii, shape (n,), in metres.

    Returns
    -------
    numpy.ndarray
        Bool array of shape (n,).

    Raises
    ------
    DimensionError
        If a shape does not match.
    InputError
        If ``radius`` is not > 0 or an entry is not finite.
    """
    fcl = _fcl()
    position = as_finite_array("position", position, (2,))
    radius = as_positive_scalar("radius", radius)
    centers = as_finite_array("centers", centers)
    if centers.size == 0:
        return np.zeros(0, dtype=bool)
    check_shape("centers", centers, (None, 2))
    radii = as_finite_array("radii", radii, (centers.shape[0],))
    robot = _fcl_disc(position, radius)
    hits = np.zeros(centers.shape[0], dtype=bool)
    for j, (c, r) in enumerate(zip(centers, radii)):
        hits[j] = fcl.collide(robot, _fcl_disc(c, r), fcl.CollisionRequest(), fcl.CollisionResult()) > 0
    return hits
