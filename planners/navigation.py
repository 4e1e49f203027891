"""A grid navigation function: the cost-to-go to the goal around static discs.

The global layer that local planners such as DWA and TEB run under (as in the ROS
navigation stack the paper's baselines come from, and Brock & Khatib's global dynamic
window): Dijkstra's shortest path lengths from every cell of a grid to the goal, over
the 8-connected free cells, where a cell is free when its centre keeps
``clearance`` from every static disc. Steps into cells within ``soft_clearance`` of a
disc cost more (``1 + near_cost`` times their length at the disc's edge, decreasing
linearly to 1 at ``soft_clearance``), so that paths keep some distance when they can.
Pedestrians are not part of it: local planners handle them.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from minimaxplan.models.errors import InputError
from minimaxplan.models.validation import as_finite_array, as_positive_scalar, check_shape

__all__ = ["NavigationFunction", "NavigationCache"]

_MOVES = np.array([(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)])


class NavigationFunction:
    """Cost-to-go to ``goal`` on a grid covering the goal and ``region``, plus ``padding``.

    Parameters
    ----------
    goal
        Shape (2,).
    centers, radii
        Static discs, shapes (n, 2) and (n,).
    clearance
        Cells whose centre is closer than this to a disc's edge are blocked, m.
    region
        Points (k, 2) the grid must cover besides the goal; the first one (the robot)
        must reach the goal on it, else the grid grows (see below).
    resolution, padding
        Cell size and (initial) margin around the covered points, m.
    soft_clearance, near_cost
        Cost shaping near discs (see the module docstring).
    """

    def __init__(
        self,
        goal,
        centers,
        radii,
        *,
        clearance: float,
        region=None,
        resolution: float = 0.2,
        padding: float = 4.0,
        soft_clearance: float = 1.0,
        near_cost: float = 2.0,
    ):
        self.goal = as_finite_array("goal", goal, (2,))
        self.centers = as_finite_array("centers", centers).reshape(-1, 2) if np.size(centers) else np.zeros((0, 2))
        self.radii = as_finite_array("radii", radii).reshape(-1) if np.size(radii) else np.zeros(0)
        check_shape("radii", self.radii, (self.centers.shape[0],))
        self.clearance = as_positive_scalar("clearance", clearance, allow_zero=True)
        self.resolution = as_positive_scalar("resolution", resolution)
        padding = as_positive_scalar("padding", padding, allow_zero=True)
        soft = as_positive_scalar("soft_clearance", soft_clearance, allow_zero=True)
        near = as_positive_scalar("near_cost", near_cost, allow_zero=True)
        # The grid covers the goal and the region (not every disc), so that a goal a few
        # metres ahead (a waypoint of a global path) gives a small, fast grid. If the
        # region's first point (the robot) cannot reach the goal on it, the padding
        # doubles until it can or until the grid covers every disc with room around.
        cover = [self.goal[None]]
        if region is not None:
            cover.append(as_finite_array("region", region).reshape(-1, 2))
        points = np.concatenate(cover)
        anchor = points[1] if points.shape[0] > 1 else None
        all_discs = self.centers, self.radii
        if all_discs[0].shape[0]:
            reach = np.max(
                np.abs(all_discs[0][:, None, :] - points[None]).max(axis=1) + all_discs[1][:, None], initial=0.0
            )
        else:
            reach = 0.0
        full_padding = max(padding, float(reach) + self.clearance + 2 * self.resolution + 1.0)
        while True:
            self._build(points, padding, all_discs, soft, near)
            if anchor is None or padding >= full_padding or self._reachable_near(anchor):
                break
            padding = min(2 * padding + self.resolution, full_padding)
        self.padding = padding

    def _build(self, points, padding, discs, soft, near) -> None:
        self.origin = points.min(axis=0) - padding
        top = points.max(axis=0) + padding
        self.shape = tuple(int(s) for s in np.ceil((top - self.origin) / self.resolution).astype(int) + 1)
        self.extent_high = self.origin + (np.array(self.shape) - 1) * self.resolution
        # Discs too far from the grid to block or shape any cell play no part.
        centers, radii = discs
        gap = np.linalg.norm(
            np.maximum(self.origin - centers, 0.0) + np.maximum(centers - self.extent_high, 0.0), axis=1
        )
        relevant = gap - radii <= self.clearance + soft
        self.centers, self.radii = centers[relevant], radii[relevant]
        gx = self.origin[0] + self.resolution * np.arange(self.shape[0])
        gy = self.origin[1] + self.resolution * np.arange(self.shape[1])
        cells = np.stack(np.meshgrid(gx, gy, indexing="ij"), axis=-1)
        if self.centers.shape[0]:
            edge = (np.linalg.norm(cells[..., None, :] - self.centers, axis=-1) - self.radii).min(axis=-1)
        else:
            edge = np.full(self.shape, np.inf)
        free = edge >= self.clearance
        goal_cell = self._cell(self.goal)
        free[goal_cell] = True  # the goal is always a target, even when it sits in a margin
        shaping = (
            1.0 + near * np.clip((soft + self.clearance - edge) / max(soft, 1e-12), 0.0, 1.0)
            if soft > 0
            else np.ones(self.shape)
        )
        self.free = free
        self.values = self._dijkstra(free, shaping, goal_cell)
        finite = np.isfinite(self.values)
        # Blocked or unreachable cells: worse than every reachable one, so descent leaves them.
        self._filled = np.where(finite, self.values, (self.values[finite].max() if finite.any() else 0.0) + 10.0)
        self._grad_x, self._grad_y = np.gradient(self._filled, self.resolution)

    def _reachable_near(self, point, window: int = 5) -> bool:
        """Whether some cell within ``window`` cells of ``point`` reaches the goal."""
        i, j = self._cell(point)
        block = self.values[max(i - window, 0) : i + window + 1, max(j - window, 0) : j + window + 1]
        return bool(np.isfinite(block).any())

    def _cell(self, point) -> tuple[int, int]:
        index = np.rint((np.asarray(point) - self.origin) / self.resolution).astype(int)
        return tuple(np.clip(index, 0, np.array(self.shape) - 1))

    def _dijkstra(self, free, shaping, goal_cell) -> np.ndarray:
        nx, ny = self.shape
        index = np.arange(nx * ny).reshape(nx, ny)
        rows, cols, weights = [], [], []
        for dx, dy in _MOVES:
            src = (slice(max(0, -dx), nx - max(0, dx)), slice(max(0, -dy), ny - max(0, dy)))
            dst = (slice(max(0, dx), nx - max(0, -dx)), slice(max(0, dy), ny - max(0, -dy)))
            ok = free[src] & free[dst]
            length = self.resolution * np.hypot(dx, dy)
            rows.append(index[src][ok])
            cols.append(index[dst][ok])
            weights.append(length * 0.5 * (shaping[src][ok] + shaping[dst][ok]))
        graph = coo_matrix(
            (np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))), shape=(nx * ny,) * 2
        )
        # The graph is symmetric, so distances from the goal are distances to it.
        distances = dijkstra(graph.tocsr(), directed=True, indices=index[goal_cell])
        return distances.reshape(nx, ny)

    def covers(self, points) -> bool:
        """Whether every point lies on the grid.

        Parameters
        ----------
        points : array_like, shape (..., 2)
            Planar positions.
        """
        p = np.asarray(points, dtype=float)
        return bool(np.all(p >= self.origin) and np.all(p <= self.extent_high))

    def _bilinear(self, field: np.ndarray, points: np.ndarray) -> np.ndarray:
        g = np.clip((points - self.origin) / self.resolution, 0.0, np.array(self.shape) - 1.000001)
        i0 = np.floor(g).astype(int)
        f = g - i0
        i, j = i0[..., 0], i0[..., 1]
        fx, fy = f[..., 0], f[..., 1]
        return (
            (1 - fx) * (1 - fy) * field[i, j]
            + fx * (1 - fy) * field[i + 1, j]
            + (1 - fx) * fy * field[i, j + 1]
            + fx * fy * field[i + 1, j + 1]
        )

    def cost_to_go(self, points) -> np.ndarray:
        """Interpolated cost-to-go at points (blocked cells count as worse than any reachable one).

        Parameters
        ----------
        points : array_like, shape (..., 2)
            Planar positions.
        """
        return self._bilinear(self._filled, np.asarray(points, dtype=float))

    def descent(self, points) -> np.ndarray:
        """Unit direction of steepest descent of the cost-to-go at points (0 where flat).

        Parameters
        ----------
        points : array_like, shape (..., 2)
            Planar positions.
        """
        p = np.asarray(points, dtype=float)
        g = np.stack([self._bilinear(self._grad_x, p), self._bilinear(self._grad_y, p)], axis=-1)
        norm = np.linalg.norm(g, axis=-1, keepdims=True)
        return np.where(norm > 0, -g / np.maximum(norm, 1e-12), 0.0)

    def path(self, start) -> np.ndarray:
        """Cell centres (k, 2) from ``start`` to the goal, each the neighbour of lowest cost-to-go.

        Parameters
        ----------
        start : array_like, shape (2,)
            The position the path starts from.

        Raises
        ------
        InputError
            When the goal cannot be reached from the start's cell.
        """
        cell = self._cell(as_finite_array("start", start, (2,)))
        values = self._filled
        if not np.isfinite(self.values[cell]):
            # Start inside a margin: step to the best reachable neighbourhood first.
            window = 5
            i0, j0 = max(cell[0] - window, 0), max(cell[1] - window, 0)
            block = self.values[i0 : cell[0] + window + 1, j0 : cell[1] + window + 1]
            if not np.isfinite(block).any():
                raise InputError("the goal cannot be reached from start on the navigation grid")
            k = np.unravel_index(np.argmin(block), block.shape)
            cell = (int(i0 + k[0]), int(j0 + k[1]))
        goal_cell = self._cell(self.goal)
        cells = [cell]
        limit = self.shape[0] * self.shape[1]
        while cell != goal_cell and len(cells) < limit:
            candidates = [
                (cell[0] + dx, cell[1] + dy)
                for dx, dy in _MOVES
                if 0 <= cell[0] + dx < self.shape[0] and 0 <= cell[1] + dy < self.shape[1]
            ]
            nxt = min(candidates, key=lambda c: values[c])
            if values[nxt] >= values[cell]:
                break
            cell = nxt
            cells.append(cell)
        return self.origin + self.resolution * np.array(cells, dtype=float)

    def waypoint(self, start, lookahead: float) -> np.ndarray:
        """The point ``lookahead`` metres along `path` from ``start`` (the goal when nearer).

        This is the "carrot" a local planner chases, as under a global planner.

        Parameters
        ----------
        start : array_like, shape (2,)
            The position the path starts from.
        lookahead : float
            Distance along the path, metres (> 0).
        """
        lookahead = as_positive_scalar("lookahead", lookahead)
        points = np.concatenate([self.path(start), self.goal[None]])
        travelled = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        k = int(np.searchsorted(travelled, lookahead))
        return self.goal.copy() if k >= len(points) else points[k].copy()


class NavigationCache:
    """The navigation function of the last goal and static discs a local planner saw.

    `get` rebuilds it when the goal or the discs change, or when the points the planner
    asks about leave its grid; otherwise it returns the one it holds.

    Parameters
    ----------
    clearance : float
        The `NavigationFunction` clearance, m (the planner's footprint and margin).
    resolution : float
        Its cell size, m.
    """

    def __init__(self, *, clearance: float, resolution: float):
        self.clearance = clearance
        self.resolution = resolution
        self._nav: NavigationFunction | None = None
        self._key: tuple[bytes, bytes, bytes] | None = None

    def get(self, goal: np.ndarray, centers: np.ndarray, radii: np.ndarray, points: np.ndarray) -> NavigationFunction:
        """The navigation function to ``goal`` around the discs, on a grid covering ``points``.

        Parameters
        ----------
        goal : numpy.ndarray, shape (2,)
            The goal.
        centers, radii : numpy.ndarray, shapes (n, 2) and (n,)
            The static discs.
        points : numpy.ndarray, shape (k, 2)
            Points the grid must cover (the first one, the robot, must reach the goal);
            a new grid is built over them when one leaves the current grid.

        Returns
        -------
        NavigationFunction
            The cached function, or a new one (then cached).
        """
        key = (goal.tobytes(), centers.tobytes(), radii.tobytes())
        nav = self._nav
        if nav is None or self._key != key or not nav.covers(points):
            nav = NavigationFunction(
                goal, centers, radii, clearance=self.clearance, region=points, resolution=self.resolution
            )
            self._nav, self._key = nav, key
        return nav
