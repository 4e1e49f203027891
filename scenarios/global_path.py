"""A global path on the static map, and the waypoint ("carrot") that local planners chase.

In a navigation stack the local planner (DWA, TEB, or the robust tree search here)
does not see the whole map: a global planner gives it a path around the static
obstacles, and it chases a waypoint some metres ahead on that path. Without it, the
goal reward ``1 / (1 + ||pos - goal||)`` of the paper is myopic and any local planner
with a short look-ahead stalls in front of concave obstacle clusters. Every method
of the experiments gets the same waypoints; the pedestrians are left to the local
planners.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import dijkstra

from minimaxplan.models._validation import as_finite_array, as_positive_scalar
from minimaxplan.models.errors import InputError

from .geometry import CircularObstacles

__all__ = ["GlobalPath"]


@dataclass(frozen=True, eq=False)
class GlobalPath:
    """Shortest 8-connected grid paths to ``goal`` around inflated static discs.

    Parameters
    ----------
    obstacles
        The static discs.
    goal
        Shape (2,).
    clearance
        Discs are grown by this much (the robot's radius plus a safety margin), m.
    bounds
        ``(low, high)`` of the square grid, m; it extends past the arena so paths may
        skirt its edge.
    resolution
        Grid cell size, m.

    Notes
    -----
    One Dijkstra from the goal over the free cells gives, for every cell, the next
    cell on a shortest path to the goal; `waypoint` follows it from the robot's cell
    for ``lookahead`` metres.
    """

    obstacles: CircularObstacles
    goal: np.ndarray
    clearance: float = 0.6
    bounds: tuple = (-3.0, 23.0)
    resolution: float = 0.2

    def __post_init__(self) -> None:
        goal = as_finite_array("goal", self.goal, (2,))
        as_positive_scalar("clearance", self.clearance, allow_zero=True)
        as_positive_scalar("resolution", self.resolution)
        low, high = map(float, self.bounds)
        if not high > low:
            raise InputError(f"bounds must be (low, high) with high > low, got {self.bounds}")
        n = int(np.ceil((high - low) / self.resolution)) + 1
        axis = low + self.resolution * np.arange(n)
        gx, gy = np.meshgrid(axis, axis, indexing="ij")
        cells = np.stack([gx.ravel(), gy.ravel()], axis=1)
        free = np.ones(cells.shape[0], dtype=bool)
        for c, r in zip(self.obstacles.centers, self.obstacles.radii):
            free &= np.linalg.norm(cells - c, axis=1) > r + self.clearance
        goal_cell = self._cell_of(goal, low, n)
        free[goal_cell] = True
        graph = self._grid_graph(n, free)
        distance, predecessors = dijkstra(graph, directed=False, indices=goal_cell, return_predecessors=True)
        for name, value in (("goal", goal), ("_cells", cells), ("_free", free), ("_distance", distance),
                            ("_next", predecessors), ("_n", n), ("_low", low)):
            object.__setattr__(self, name, value)

    def _cell_of(self, point, low, n) -> int:
        i, j = np.clip(np.rint((np.asarray(point) - low) / self.resolution).astype(int), 0, n - 1)
        return int(i * n + j)

    def _grid_graph(self, n: int, free: np.ndarray) -> sparse.csr_matrix:
        index = np.arange(n * n).reshape(n, n)
        rows, cols, weights = [], [], []
        for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
            a = index[max(0, -di): n - max(0, di), max(0, -dj): n - max(0, dj)]
            b = index[max(0, di): n - max(0, -di) or None, max(0, dj): n - max(0, -dj) or None]
            a, b = a.ravel(), b.ravel()
            keep = free[a] & free[b]
            rows.append(a[keep])
            cols.append(b[keep])
            weights.append(np.full(keep.sum(), self.resolution * np.hypot(di, dj)))
        return sparse.csr_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                                 shape=(n * n, n * n))

    def _nearest_reachable(self, position) -> int:
        cell = self._cell_of(position, self._low, self._n)
        if np.isfinite(self._distance[cell]):
            return cell
        reachable = np.flatnonzero(np.isfinite(self._distance))
        return int(reachable[np.argmin(np.linalg.norm(self._cells[reachable] - position, axis=1))])

    def distance(self, position) -> float:
        """Path length from the grid cell nearest ``position`` to the goal (inf if cut off)."""
        position = as_finite_array("position", position, (2,))
        return float(self._distance[self._cell_of(position, self._low, self._n)])

    def path(self, position) -> np.ndarray:
        """The grid path from ``position`` to the goal, shape (k, 2), ending at the goal."""
        position = as_finite_array("position", position, (2,))
        cell = self._nearest_reachable(position)
        points = [self._cells[cell]]
        while self._next[cell] >= 0:
            cell = int(self._next[cell])
            points.append(self._cells[cell])
        points.append(self.goal)
        return np.array(points)

    def waypoint(self, position, lookahead: float = 3.0) -> np.ndarray:
        """The point ``lookahead`` metres along the path from ``position`` (the goal if nearer)."""
        lookahead = as_positive_scalar("lookahead", lookahead)
        points = self.path(position)
        steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
        travelled = np.concatenate([[0.0], np.cumsum(steps)])
        k = int(np.searchsorted(travelled, lookahead))
        return self.goal.copy() if k >= len(points) else points[k].copy()
