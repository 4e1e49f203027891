"""Road geometry of the driving worlds: lanes as straight segments and circular arcs.

One concept: a *lane* is a centre line (a straight segment or a circular arc) with a
width, and an exact Frenet map between the plane and lane coordinates ``(s, offset)``:

* ``s`` (m) is the arc length along the centre line from its start, in the direction
  of travel;
* ``offset`` (m) is the signed distance from the centre line, **positive to the left**
  of the direction of travel (the plane is the usual right-handed frame, x east, y
  north, headings in rad counter-clockwise from +x).

A `Road` is a set of lanes with their connections (routes are lane sequences), groups
of parallel *side lanes* (lanes whose ``s`` coordinates are aligned, between which
vehicles change lane), a priority per lane (higher has the right of way), extra
drivable areas (the junction box), and the lane-membership and on-road tests. Every
map is vectorised: lane indices, ``s`` and points broadcast against each other.

Two factories build the scenarios' roads: `highway_road` (straight parallel lanes)
and `tjunction_road` (the geometry of highway-env's ``intersection-v0`` without its
north arm: a two-lane main road, west-east, and a two-lane stem from the south).

Closed sets: a point on a lane edge is on the lane.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from minimaxplan.kernels.bicycle import LaneGeometry
from minimaxplan.models.errors import DimensionError, InputError, NonFiniteError
from minimaxplan.models.validation import as_finite_array, as_positive_scalar

__all__ = [
    "STRAIGHT",
    "ARC",
    "wrap_to_pi",
    "StraightLane",
    "ArcLane",
    "Road",
    "HighwayGeometry",
    "TJunctionGeometry",
    "highway_road",
    "tjunction_road",
    "lane_geometry",
]

#: Lane kinds in `Road.kinds`.
STRAIGHT = 0
ARC = 1
#: Number of centre-line samples per lane used to find conflicting lanes.
CONFLICT_SAMPLES = 200


def wrap_to_pi(angle):
    """Wrap angles to ``[-pi, pi)`` (rad), elementwise.

    Parameters
    ----------
    angle : array_like
        Angles, rad.

    Returns
    -------
    ndarray or float
        ``(angle + pi) mod 2 pi - pi``.
    """
    return np.mod(np.asarray(angle, dtype=float) + np.pi, 2.0 * np.pi) - np.pi


def readonly_copy(value) -> np.ndarray:
    """A read-only copy of ``value`` that keeps its dtype (integer route tables stay integer)."""
    out = np.array(value, copy=True)
    out.setflags(write=False)
    return out


# ------------------------------------------------------------------------- lanes
@dataclass(frozen=True, eq=False)
class StraightLane:
    """A straight lane from ``start`` to ``end``.

    Parameters
    ----------
    start, end : array_like, shape (2,)
        End points of the centre line, m; the direction of travel is start -> end.
    width : float
        Lane width, m (> 0).

    Notes
    -----
    With ``u`` the unit direction and ``n = (-u_y, u_x)`` its left normal,
    ``position(s, offset) = start + s u + offset n`` and ``local_coordinates(p) =
    ((p - start) . u, (p - start) . n)``: exact inverses of each other on the whole
    plane. ``s`` outside ``[0, length]`` continues the centre line as a straight line
    (the nearest point of the infinite line).
    """

    start: np.ndarray
    end: np.ndarray
    width: float = 4.0

    def __post_init__(self) -> None:
        start = as_finite_array("start", self.start, (2,))
        end = as_finite_array("end", self.end, (2,))
        if np.linalg.norm(end - start) <= 0:
            raise InputError("a straight lane needs start != end")
        object.__setattr__(self, "start", readonly_copy(start))
        object.__setattr__(self, "end", readonly_copy(end))
        object.__setattr__(self, "width", as_positive_scalar("width", self.width))

    @property
    def length(self) -> float:
        """Length of the centre line, m."""
        return float(np.linalg.norm(self.end - self.start))

    @property
    def direction(self) -> np.ndarray:
        """Unit direction of travel, shape (2,)."""
        return (self.end - self.start) / self.length

    def position(self, s, offset=0.0) -> np.ndarray:
        """The point at arc length ``s`` (m) and lateral ``offset`` (m, left positive).

        Parameters
        ----------
        s, offset : array_like
            Broadcast against each other, m.

        Returns
        -------
        ndarray, shape broadcast(s, offset) + (2,)
        """
        s, offset = np.broadcast_arrays(np.asarray(s, dtype=float), np.asarray(offset, dtype=float))
        u = self.direction
        n = np.array([-u[1], u[0]])
        return self.start + s[..., None] * u + offset[..., None] * n

    def heading(self, s) -> np.ndarray:
        """Heading of the centre line at ``s`` (rad), constant on a straight lane.

        Parameters
        ----------
        s : array_like
            Arc lengths, m.
        """
        u = self.direction
        return np.full(np.shape(s), float(np.arctan2(u[1], u[0])))

    def curvature(self, s) -> np.ndarray:
        """Signed curvature at ``s`` (1/m, positive turning left): 0.

        Parameters
        ----------
        s : array_like
            Arc lengths, m.
        """
        return np.zeros(np.shape(s))

    def local_coordinates(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """``(s, offset)`` of the points ``(x, y)`` (m): the nearest point of the centre line's line.

        Parameters
        ----------
        x, y : array_like
            Coordinates, m, broadcast against each other.
        """
        u = self.direction
        dx = np.asarray(x, dtype=float) - self.start[0]
        dy = np.asarray(y, dtype=float) - self.start[1]
        return dx * u[0] + dy * u[1], -dx * u[1] + dy * u[0]

    def to_dict(self) -> dict:
        """The lane as plain data."""
        return {"kind": "straight", "start": self.start.tolist(), "end": self.end.tolist(), "width": self.width}


@dataclass(frozen=True, eq=False)
class ArcLane:
    """A lane whose centre line is a circular arc.

    Parameters
    ----------
    center : array_like, shape (2,)
        Centre of the circle, m.
    radius : float
        Radius of the centre line, m (> 0).
    start_angle : float
        Polar angle (rad, about ``center``) of the lane's start.
    sweep : float
        Signed swept angle, rad, ``0 < |sweep| < 2 pi``: positive turns left
        (counter-clockwise), negative right.
    width : float
        Lane width, m (> 0, < 2 radius).

    Notes
    -----
    With ``d = sign(sweep)`` and ``phi(s) = start_angle + d s / radius``:
    ``position(s, offset) = center + (radius - d offset) (cos phi, sin phi)``,
    ``heading(s) = phi(s) + d pi / 2``, curvature ``d / radius``. The inverse measures
    the polar angle of a point relative to the arc's midpoint, in ``[-pi, pi)``, so
    ``local_coordinates(position(s, offset)) = (s, offset)`` exactly (to rounding)
    whenever ``|s - length / 2| < pi radius`` and ``radius - d offset > 0`` (the point
    is not at or beyond the centre), and ``position(local_coordinates(p)) = p`` for
    every point but the centre. For points within the arc's angular span, the
    coordinates are those of the nearest centre-line point.
    """

    center: np.ndarray
    radius: float
    start_angle: float
    sweep: float
    width: float = 4.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", readonly_copy(as_finite_array("center", self.center, (2,))))
        radius = as_positive_scalar("radius", self.radius)
        sweep = float(as_finite_array("sweep", self.sweep))
        if not 0.0 < abs(sweep) < 2.0 * np.pi:
            raise InputError(f"sweep must satisfy 0 < |sweep| < 2 pi, got {sweep}")
        width = as_positive_scalar("width", self.width)
        if width >= 2.0 * radius:
            raise InputError(f"width must be < 2 radius, got width={width}, radius={radius}")
        object.__setattr__(self, "radius", radius)
        object.__setattr__(self, "start_angle", float(as_finite_array("start_angle", self.start_angle)))
        object.__setattr__(self, "sweep", sweep)
        object.__setattr__(self, "width", width)

    @property
    def direction_sign(self) -> float:
        """``+1`` for a left (counter-clockwise) arc, ``-1`` for a right one."""
        return 1.0 if self.sweep > 0 else -1.0

    @property
    def length(self) -> float:
        """Length of the centre line, ``radius |sweep|``, m."""
        return self.radius * abs(self.sweep)

    def _angle(self, s) -> np.ndarray:
        return self.start_angle + self.direction_sign * np.asarray(s, dtype=float) / self.radius

    def position(self, s, offset=0.0) -> np.ndarray:
        """The point at arc length ``s`` (m) and lateral ``offset`` (m, left positive).

        Parameters
        ----------
        s, offset : array_like
            Broadcast against each other, m.

        Returns
        -------
        ndarray, shape broadcast(s, offset) + (2,)
        """
        s, offset = np.broadcast_arrays(np.asarray(s, dtype=float), np.asarray(offset, dtype=float))
        phi = self._angle(s)
        r = self.radius - self.direction_sign * offset
        return self.center + np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1)

    def heading(self, s) -> np.ndarray:
        """Heading of the centre line at ``s`` (rad), ``phi(s) + d pi / 2`` (not wrapped).

        Parameters
        ----------
        s : array_like
            Arc lengths, m.
        """
        return self._angle(s) + self.direction_sign * np.pi / 2

    def curvature(self, s) -> np.ndarray:
        """Signed curvature at ``s``: ``sign(sweep) / radius`` (1/m, positive turning left).

        Parameters
        ----------
        s : array_like
            Arc lengths, m.
        """
        return np.full(np.shape(s), self.direction_sign / self.radius)

    def local_coordinates(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """``(s, offset)`` of the points ``(x, y)`` (m), by the polar angle about the centre.

        Parameters
        ----------
        x, y : array_like
            Coordinates, m, broadcast against each other.
        """
        d = self.direction_sign
        dx = np.asarray(x, dtype=float) - self.center[0]
        dy = np.asarray(y, dtype=float) - self.center[1]
        mid = self.start_angle + self.sweep / 2
        delta = wrap_to_pi(np.arctan2(dy, dx) - mid)
        s = self.length / 2 + d * self.radius * delta
        offset = d * (self.radius - np.hypot(dx, dy))
        return s, offset

    def to_dict(self) -> dict:
        """The lane as plain data."""
        return {
            "kind": "arc",
            "center": self.center.tolist(),
            "radius": self.radius,
            "start_angle": self.start_angle,
            "sweep": self.sweep,
            "width": self.width,
        }


# -------------------------------------------------------------------------- road
@dataclass(frozen=True, eq=False)
class Road:
    """Lanes with connections, side lanes, priorities and extra drivable areas.

    Parameters
    ----------
    lanes : tuple of StraightLane or ArcLane
        The lanes; a lane is referred to by its index in this tuple.
    names : tuple of str
        One unique name per lane.
    connections : tuple of (int, int)
        ``(a, b)``: a vehicle at the end of lane a may continue on lane b (the end of a
        is the start of b, to 1e-6 m).
    side_groups : tuple of tuple of int
        Groups of parallel lanes with aligned ``s`` (same start abscissa along a common
        direction), ordered by lateral position (from right to left); a vehicle may
        change between neighbours of a group. A lane in no group has no side lane.
    priorities : tuple of int
        One per lane: at a junction, a vehicle entering lane a yields to traffic
        approaching or on a conflicting lane b of higher priority.
    areas : tuple of ((float, float), (float, float))
        Axis-aligned rectangles ``((x_lo, y_lo), (x_hi, y_hi))`` (m) that are road
        without being part of a lane (the junction box).
    conflict_distance : float
        Two lanes that are not connected, not siblings (sharing a predecessor) and not
        the same *conflict* when their centre lines come closer than this, m (crossings
        and merges). Default 2.5 m.

    Notes
    -----
    The lane data is also held as arrays (``kinds``, ``starts``, ``directions``,
    ``centers``, ``radii``, ``start_angles``, ``signs``, ``lengths``, ``widths``) so that
    `frenet`, `position_at` and `heading_at` evaluate any mix of straight and arc lanes
    in one vectorised call, with exactly the formulas of the lane classes.
    """

    lanes: tuple
    names: tuple
    connections: tuple = ()
    side_groups: tuple = ()
    priorities: tuple = ()
    areas: tuple = ()
    conflict_distance: float = 2.5
    kinds: np.ndarray = field(init=False, repr=False)
    starts: np.ndarray = field(init=False, repr=False)
    directions: np.ndarray = field(init=False, repr=False)
    centers: np.ndarray = field(init=False, repr=False)
    radii: np.ndarray = field(init=False, repr=False)
    start_angles: np.ndarray = field(init=False, repr=False)
    mid_angles: np.ndarray = field(init=False, repr=False)
    signs: np.ndarray = field(init=False, repr=False)
    lengths: np.ndarray = field(init=False, repr=False)
    widths: np.ndarray = field(init=False, repr=False)
    conflicts: np.ndarray = field(init=False, repr=False)
    side_of: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        lanes = tuple(self.lanes)
        if not lanes or not all(isinstance(lane, (StraightLane, ArcLane)) for lane in lanes):
            raise InputError("lanes must be a non-empty sequence of StraightLane or ArcLane")
        n = len(lanes)
        names = tuple(str(name) for name in self.names)
        if len(names) != n or len(set(names)) != n:
            raise InputError(f"names must hold {n} unique names, got {names!r}")
        priorities = tuple(int(p) for p in self.priorities) if self.priorities else (0,) * n
        if len(priorities) != n:
            raise DimensionError(f"priorities must have length {n}, got length {len(priorities)}")
        connections = tuple((int(a), int(b)) for a, b in self.connections)
        for a, b in connections:
            if not (0 <= a < n and 0 <= b < n) or a == b:
                raise InputError(f"connection {(a, b)} does not join two different lanes of {n}")
            gap = np.linalg.norm(lanes[a].position(lanes[a].length) - lanes[b].position(0.0))
            if gap > 1e-6:
                raise InputError(f"connection {names[a]} -> {names[b]}: the lanes are {gap:.3g} m apart")
        side_groups = tuple(tuple(int(i) for i in group) for group in self.side_groups)
        side_of = np.full(n, -1, dtype=int)
        for g, group in enumerate(side_groups):
            for i in group:
                if not 0 <= i < n or side_of[i] >= 0:
                    raise InputError(f"side group {group} holds an invalid or repeated lane {i}")
                side_of[i] = g
        areas = tuple(((float(a[0][0]), float(a[0][1])), (float(a[1][0]), float(a[1][1]))) for a in self.areas)
        for (x0, y0), (x1, y1) in areas:
            if not (x0 < x1 and y0 < y1):
                raise InputError(f"area {((x0, y0), (x1, y1))} is empty")
        object.__setattr__(self, "lanes", lanes)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "priorities", priorities)
        object.__setattr__(self, "connections", connections)
        object.__setattr__(self, "side_groups", side_groups)
        object.__setattr__(self, "areas", areas)
        object.__setattr__(self, "conflict_distance", as_positive_scalar("conflict_distance", self.conflict_distance))
        kinds = np.array([STRAIGHT if isinstance(lane, StraightLane) else ARC for lane in lanes], dtype=int)
        starts = np.zeros((n, 2))
        directions = np.tile([1.0, 0.0], (n, 1))
        centers = np.zeros((n, 2))
        radii = np.ones(n)
        start_angles = np.zeros(n)
        mid_angles = np.zeros(n)
        signs = np.ones(n)
        for i, lane in enumerate(lanes):
            if isinstance(lane, StraightLane):
                starts[i] = lane.start
                directions[i] = lane.direction
            else:
                centers[i] = lane.center
                radii[i] = lane.radius
                start_angles[i] = lane.start_angle
                mid_angles[i] = lane.start_angle + lane.sweep / 2
                signs[i] = lane.direction_sign
        arrays = {
            "kinds": kinds,
            "starts": starts,
            "directions": directions,
            "centers": centers,
            "radii": radii,
            "start_angles": start_angles,
            "mid_angles": mid_angles,
            "signs": signs,
            "lengths": np.array([lane.length for lane in lanes]),
            "widths": np.array([lane.width for lane in lanes]),
            "side_of": side_of,
        }
        for name, value in arrays.items():
            object.__setattr__(self, name, readonly_copy(value))
        object.__setattr__(self, "conflicts", readonly_copy(self._find_conflicts()))

    # ------------------------------------------------------------ structure
    def __len__(self) -> int:
        return len(self.lanes)

    def index(self, name: str) -> int:
        """The index of the lane called ``name``.

        Parameters
        ----------
        name : str
            A lane name.
        """
        try:
            return self.names.index(name)
        except ValueError:
            raise InputError(f"no lane called {name!r}; lanes are {self.names}") from None

    def route(self, *names: str) -> tuple[int, ...]:
        """Lane indices of a route given by lane names, checked to be connected.

        Parameters
        ----------
        names : str
            Lane names, in driving order.
        """
        ids = tuple(self.index(name) for name in names)
        for a, b in zip(ids[:-1], ids[1:]):
            if (a, b) not in self.connections:
                raise InputError(f"{self.names[a]} does not connect to {self.names[b]}")
        return ids

    def successors(self, lane: int) -> tuple[int, ...]:
        """The lanes a vehicle may take at the end of ``lane``.

        Parameters
        ----------
        lane : int
            A lane index.
        """
        return tuple(b for a, b in self.connections if a == lane)

    def side_lanes(self, lane: int) -> tuple[int, ...]:
        """The lanes of ``lane``'s side group, ordered right to left (``(lane,)`` if none).

        Parameters
        ----------
        lane : int
            A lane index.
        """
        g = int(self.side_of[lane])
        return (lane,) if g < 0 else self.side_groups[g]

    def _find_conflicts(self) -> np.ndarray:
        n = len(self.lanes)
        samples = [lane.position(np.linspace(0.0, lane.length, CONFLICT_SAMPLES)) for lane in self.lanes]
        predecessors = [{a for a, b in self.connections if b == i} for i in range(n)]
        connected = set(self.connections)
        out = np.zeros((n, n), dtype=bool)
        for a in range(n):
            for b in range(a + 1, n):
                if (a, b) in connected or (b, a) in connected or predecessors[a] & predecessors[b]:
                    continue
                if self.side_of[a] >= 0 and self.side_of[a] == self.side_of[b]:
                    continue
                gaps = np.linalg.norm(samples[a][:, None, :] - samples[b][None, :, :], axis=-1)
                out[a, b] = out[b, a] = gaps.min() < self.conflict_distance
        return out

    # --------------------------------------------------------- vectorised maps
    def frenet(self, lane, x, y) -> tuple[np.ndarray, np.ndarray]:
        """``(s, offset)`` (m) of the points ``(x, y)`` in the lanes ``lane``, all broadcast.

        Parameters
        ----------
        lane : array_like of int
            Lane indices.
        x, y : array_like
            Coordinates, m.

        Returns
        -------
        s, offset : ndarray
            As each lane's ``local_coordinates`` (bit for bit the same formulas).
        """
        lane = np.asarray(lane, dtype=int)
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        # straight
        dx = x - self.starts[lane, 0]
        dy = y - self.starts[lane, 1]
        ux, uy = self.directions[lane, 0], self.directions[lane, 1]
        s_straight = dx * ux + dy * uy
        off_straight = -dx * uy + dy * ux
        # arc
        cx = x - self.centers[lane, 0]
        cy = y - self.centers[lane, 1]
        d = self.signs[lane]
        radius = self.radii[lane]
        delta = wrap_to_pi(np.arctan2(cy, cx) - self.mid_angles[lane])
        s_arc = self.lengths[lane] / 2 + d * radius * delta
        off_arc = d * (radius - np.hypot(cx, cy))
        is_arc = self.kinds[lane] == ARC
        return np.where(is_arc, s_arc, s_straight), np.where(is_arc, off_arc, off_straight)

    def position_at(self, lane, s, offset=0.0) -> np.ndarray:
        """Points at ``(s, offset)`` (m) of the lanes ``lane``, broadcast; shape (..., 2).

        Parameters
        ----------
        lane : array_like of int
            Lane indices.
        s, offset : array_like
            Lane coordinates, m.
        """
        lane, s, offset = np.broadcast_arrays(
            np.asarray(lane, dtype=int), np.asarray(s, dtype=float), np.asarray(offset, dtype=float)
        )
        u = self.directions[lane]
        normal = np.stack([-u[..., 1], u[..., 0]], axis=-1)
        straight = self.starts[lane] + s[..., None] * u + offset[..., None] * normal
        d = self.signs[lane]
        phi = self.start_angles[lane] + d * s / self.radii[lane]
        r = self.radii[lane] - d * offset
        arc = self.centers[lane] + np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1)
        return np.where((self.kinds[lane] == ARC)[..., None], arc, straight)

    def heading_at(self, lane, s) -> np.ndarray:
        """Heading (rad, not wrapped) of the centre lines of ``lane`` at ``s`` (m), broadcast.

        Parameters
        ----------
        lane : array_like of int
            Lane indices.
        s : array_like
            Arc lengths, m.
        """
        lane = np.asarray(lane, dtype=int)
        s = np.asarray(s, dtype=float)
        straight = np.arctan2(self.directions[lane, 1], self.directions[lane, 0])
        d = self.signs[lane]
        arc = self.start_angles[lane] + d * s / self.radii[lane] + d * np.pi / 2
        return np.where(self.kinds[lane] == ARC, arc, straight + 0.0 * s)

    def curvature_at(self, lane, s) -> np.ndarray:
        """Signed curvature (1/m, positive left) of the lanes ``lane`` at ``s``, broadcast.

        Parameters
        ----------
        lane : array_like of int
            Lane indices.
        s : array_like
            Arc lengths, m.
        """
        lane = np.asarray(lane, dtype=int)
        s = np.asarray(s, dtype=float)
        return np.where(self.kinds[lane] == ARC, self.signs[lane] / self.radii[lane], 0.0) + 0.0 * s

    # ---------------------------------------------------------- membership
    def lane_membership(self, points, margin: float = 0.0) -> np.ndarray:
        """Which lanes' strips hold each point: ``-margin <= s <= length + margin`` and ``|offset| <= width / 2 + margin``.

        Parameters
        ----------
        points : array_like, shape (..., 2)
            Points, m.
        margin : float
            Grows every strip by this much, m (>= 0; 0 is the lane itself).

        Returns
        -------
        ndarray of bool, shape (..., n_lanes)
        """
        pts = np.asarray(points, dtype=float)
        if pts.shape[-1:] != (2,):
            raise DimensionError(f"points must have shape (..., 2), got shape {pts.shape}")
        margin = as_positive_scalar("margin", margin, allow_zero=True)
        lanes = np.arange(len(self.lanes))
        s, offset = self.frenet(lanes, pts[..., 0:1], pts[..., 1:2])
        return (s >= -margin) & (s <= self.lengths + margin) & (np.abs(offset) <= self.widths / 2 + margin)

    def in_areas(self, points, margin: float = 0.0) -> np.ndarray:
        """Whether each point lies in one of the extra drivable `areas` (each grown by ``margin`` m).

        Parameters
        ----------
        points : array_like, shape (..., 2)
            Points, m.
        margin : float
            Grows every area by this much on each side, m (>= 0).

        Returns
        -------
        ndarray of bool, shape (...)
        """
        pts = np.asarray(points, dtype=float)
        inside = np.zeros(pts.shape[:-1], dtype=bool)
        for (x0, y0), (x1, y1) in self.areas:
            inside |= (
                (pts[..., 0] >= x0 - margin)
                & (pts[..., 0] <= x1 + margin)
                & (pts[..., 1] >= y0 - margin)
                & (pts[..., 1] <= y1 + margin)
            )
        return inside

    def on_road(self, points, margin: float = 0.0) -> np.ndarray:
        """Whether each point is on the road: in a lane's strip or in an extra area (grown by ``margin``).

        Parameters
        ----------
        points : array_like, shape (..., 2)
            Points, m.
        margin : float
            Tolerance, m (>= 0; 0: the road itself, closed).

        Returns
        -------
        ndarray of bool, shape (...)
        """
        pts = np.asarray(points, dtype=float)
        if not np.all(np.isfinite(pts)):
            raise NonFiniteError("points contains NaN or infinite entries")
        return self.lane_membership(pts, margin).any(axis=-1) | self.in_areas(pts, margin)

    def lane_edges(self, lane: int, samples: int = 50) -> tuple[np.ndarray, np.ndarray]:
        """The right and left edges of a lane as polylines, each shape (samples, 2), m.

        Parameters
        ----------
        lane : int
            A lane index.
        samples : int
            Points per edge (>= 2).
        """
        if samples < 2:
            raise InputError(f"samples must be >= 2, got {samples}")
        item = self.lanes[lane]
        s = np.linspace(0.0, item.length, samples)
        return item.position(s, -item.width / 2), item.position(s, item.width / 2)

    def to_dict(self) -> dict:
        """The road as plain data."""
        return {
            "lanes": [lane.to_dict() for lane in self.lanes],
            "names": list(self.names),
            "connections": [list(c) for c in self.connections],
            "side_groups": [list(g) for g in self.side_groups],
            "priorities": list(self.priorities),
            "areas": [list(map(list, a)) for a in self.areas],
            "conflict_distance": self.conflict_distance,
        }


# ------------------------------------------------------------------- factories
@dataclass(frozen=True)
class HighwayGeometry:
    """The highway: parallel straight lanes along +x.

    Attributes
    ----------
    lane_count : int
        Number of lanes (3).
    lane_width : float
        Lane width, m (4).
    length : float
        Length of every lane, m (2000: the goal is 250 m ahead of an ego starting at
        200 m, and traffic at 25 m/s covers 1000 m in the 40 s time limit).

    Notes
    -----
    Lane k (``k = 0 .. lane_count - 1``) runs from ``(0, k lane_width)`` to ``(length,
    k lane_width)``: the lane index is the one `SpeedLaneReward` reads from y, and all
    lanes form one side group (lane 0 first).
    """

    lane_count: int = 3
    lane_width: float = 4.0
    length: float = 2000.0

    def __post_init__(self) -> None:
        if int(self.lane_count) != self.lane_count or self.lane_count < 1:
            raise InputError(f"lane_count must be a positive integer, got {self.lane_count!r}")
        as_positive_scalar("lane_width", self.lane_width)
        as_positive_scalar("length", self.length)


def highway_road(geometry: HighwayGeometry = HighwayGeometry()) -> Road:
    """The highway `Road`: ``lane_count`` straight lanes of ``length`` m, one side group.

    Parameters
    ----------
    geometry : HighwayGeometry
        Lane count, width and length.
    """
    w = geometry.lane_width
    lanes = tuple(
        StraightLane(np.array([0.0, k * w]), np.array([geometry.length, k * w]), w) for k in range(geometry.lane_count)
    )
    return Road(
        lanes=lanes,
        names=tuple(f"lane{k}" for k in range(geometry.lane_count)),
        side_groups=(tuple(range(geometry.lane_count)),),
        priorities=(0,) * geometry.lane_count,
    )


@dataclass(frozen=True)
class TJunctionGeometry:
    """The T-junction: highway-env ``intersection-v0``'s geometry without the north arm.

    Attributes
    ----------
    lane_width : float
        Lane width, m (4, highway-env's default).
    right_turn_radius : float
        Radius of the right-turn arcs' centre lines, m (9 = lane width + 5 in
        intersection-v0); the left turns have radius ``right_turn_radius + lane_width``.
    access_length : float
        Length of each arm's incoming and outgoing lanes, from the junction box outwards,
        m (100, as intersection-v0).

    Notes
    -----
    The junction is centred at the origin. ``o = right_turn_radius + lane_width / 2``
    is the half-size of the junction box. The main road runs west-east: eastbound at
    ``y = -lane_width / 2`` (``west_in``, ``west_east`` through the junction,
    ``east_out``), westbound at ``y = +lane_width / 2`` (``east_in``, ``east_west``,
    ``west_out``). The stem comes from the south: northbound ``south_in`` at ``x =
    +lane_width / 2`` ending at ``y = -o``, southbound ``south_out`` at ``x = -lane_width
    / 2``. Turns (quarter circles): ``south_west`` (left from the stem, the ego's
    manoeuvre, centre ``(-o, -o)``), ``south_east`` (right from the stem, centre ``(o,
    -o)``), ``west_south`` (eastbound turning right into the stem, centre ``(-o, -o)``)
    and ``east_south`` (westbound turning left into the stem, centre ``(o, -o)``).
    Priorities: the main road's straight lanes and right turns 3, its left turn 2,
    the stem's right turn 1 and left turn 0 (intersection-v0's levels; the main road has
    priority). The area ``[-lane_width, lane_width] x [-o, -lane_width]`` (the stem's
    continuation into the junction box) is road.
    """

    lane_width: float = 4.0
    right_turn_radius: float = 9.0
    access_length: float = 100.0

    def __post_init__(self) -> None:
        as_positive_scalar("lane_width", self.lane_width)
        as_positive_scalar("access_length", self.access_length)
        if as_positive_scalar("right_turn_radius", self.right_turn_radius) <= self.lane_width / 2:
            raise InputError("right_turn_radius must exceed lane_width / 2")

    @property
    def left_turn_radius(self) -> float:
        """Radius of the left turns' centre lines, m."""
        return self.right_turn_radius + self.lane_width

    @property
    def outer_distance(self) -> float:
        """Half-size of the junction box, ``right_turn_radius + lane_width / 2``, m."""
        return self.right_turn_radius + self.lane_width / 2


def _xy(x: float, y: float) -> np.ndarray:
    return np.array([x, y], dtype=float)


def tjunction_road(geometry: TJunctionGeometry = TJunctionGeometry()) -> Road:
    """The T-junction `Road` (see `TJunctionGeometry` for the lane names and layout).

    Parameters
    ----------
    geometry : TJunctionGeometry
        Lane width, turn radius and arm length.
    """
    w = geometry.lane_width
    h = w / 2
    o = geometry.outer_distance
    far = o + geometry.access_length
    rr, rl = geometry.right_turn_radius, geometry.left_turn_radius
    quarter = np.pi / 2
    spec = [
        ("west_in", StraightLane(_xy(-far, -h), _xy(-o, -h), w), 3),
        ("west_east", StraightLane(_xy(-o, -h), _xy(o, -h), w), 3),
        ("east_out", StraightLane(_xy(o, -h), _xy(far, -h), w), 3),
        ("east_in", StraightLane(_xy(far, h), _xy(o, h), w), 3),
        ("east_west", StraightLane(_xy(o, h), _xy(-o, h), w), 3),
        ("west_out", StraightLane(_xy(-o, h), _xy(-far, h), w), 3),
        ("south_in", StraightLane(_xy(h, -far), _xy(h, -o), w), 1),
        ("south_out", StraightLane(_xy(-h, -o), _xy(-h, -far), w), 1),
        ("south_west", ArcLane(_xy(-o, -o), rl, 0.0, quarter, w), 0),
        ("south_east", ArcLane(_xy(o, -o), rr, np.pi, -quarter, w), 1),
        ("west_south", ArcLane(_xy(-o, -o), rr, quarter, -quarter, w), 3),
        ("east_south", ArcLane(_xy(o, -o), rl, quarter, quarter, w), 2),
    ]
    names = tuple(name for name, _, _ in spec)
    idx = {name: i for i, name in enumerate(names)}
    pairs = [
        ("west_in", "west_east"),
        ("west_east", "east_out"),
        ("west_in", "west_south"),
        ("west_south", "south_out"),
        ("east_in", "east_west"),
        ("east_west", "west_out"),
        ("east_in", "east_south"),
        ("east_south", "south_out"),
        ("south_in", "south_west"),
        ("south_west", "west_out"),
        ("south_in", "south_east"),
        ("south_east", "east_out"),
    ]
    return Road(
        lanes=tuple(lane for _, lane, _ in spec),
        names=names,
        connections=tuple((idx[a], idx[b]) for a, b in pairs),
        priorities=tuple(p for _, _, p in spec),
        areas=(((-w, -o), (w, -w)),),
    )


# ------------------------------------------------------------ compiled arrays
def lane_geometry(road: Road, route: tuple[int, ...] = ()) -> LaneGeometry:
    """The lanes of ``road`` as the arrays of `minimaxplan.kernels.bicycle.LaneGeometry`.

    What the compiled ego controllers and the planner's ego model read (planners never
    import this package: they get the road as these arrays).

    Parameters
    ----------
    road : Road
        The lanes.
    route : tuple of int
        A controlled vehicle's route, in driving order (e.g. the T-junction's
        ``south_in -> south_west -> west_out``): ``next_lane`` maps each of its lanes
        to the next one (the last to -1). Empty (the highway): no successors.

    Returns
    -------
    LaneGeometry
        The arrays of `Road` (``kinds``, ``starts``, ``directions``, ``centers``,
        ``radii``, ``start_angles``, ``mid_angles``, ``signs``, ``lengths``,
        ``widths``), the successors along ``route``, and each lane's side neighbours
        (``left_lane``: the next lane of its side group, which is ordered right to left;
        ``right_lane``: the previous one; -1 when none).

    Raises
    ------
    InputError
        If ``route`` names a lane that does not exist or two consecutive lanes that
        are not connected.
    """
    n = len(road)
    route = tuple(int(i) for i in route)
    for i in route:
        if not 0 <= i < n:
            raise InputError(f"route holds lane {i}, but the road has {n} lanes")
    for a, b in zip(route[:-1], route[1:]):
        if (a, b) not in road.connections:
            raise InputError(f"route: lane {road.names[a]} does not connect to {road.names[b]}")
    next_lane = np.full(n, -1, dtype=np.int64)
    for a, b in zip(route[:-1], route[1:]):
        next_lane[a] = b
    left = np.full(n, -1, dtype=np.int64)
    right = np.full(n, -1, dtype=np.int64)
    for group in road.side_groups:
        for k, lane in enumerate(group):
            if k + 1 < len(group):
                left[lane] = group[k + 1]
            if k > 0:
                right[lane] = group[k - 1]

    def floats(value):
        return np.ascontiguousarray(value, dtype=np.float64)

    return LaneGeometry(
        kinds=np.ascontiguousarray(road.kinds, dtype=np.int64),
        starts=floats(road.starts),
        directions=floats(road.directions),
        centers=floats(road.centers),
        radii=floats(road.radii),
        start_angles=floats(road.start_angles),
        mid_angles=floats(road.mid_angles),
        signs=floats(road.signs),
        lengths=floats(road.lengths),
        widths=floats(road.widths),
        next_lane=next_lane,
        left_lane=left,
        right_lane=right,
    )
