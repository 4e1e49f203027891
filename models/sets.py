"""Immutable set values: axis-aligned boxes and ellipsoids."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from .validation import as_finite_array, as_positive_scalar, check_shape, frozen_copy
from .errors import DimensionError, EmptySetError, InputError

__all__ = ["Box", "Ellipsoid", "hypercube_signs"]


def hypercube_signs(dim: int) -> np.ndarray:
    """The 2^dim sign vectors of {-1, 1}^dim, one per row, in lexicographic order."""
    return np.array(list(itertools.product((-1.0, 1.0), repeat=dim))).reshape(2**dim, dim)


@dataclass(frozen=True, eq=False)
class Box:
    """The axis-aligned box ``{x : low <= x <= high}`` (an interval vector).

    Parameters
    ----------
    low, high
        Arrays of shape (n,). Every ``low[i] <= high[i]``; degenerate sides
        (``low[i] == high[i]``) are allowed.
    """

    low: np.ndarray
    high: np.ndarray

    def __post_init__(self) -> None:
        low = as_finite_array("low", self.low, ndim=1)
        high = as_finite_array("high", self.high, ndim=1)
        if low.shape != high.shape:
            raise DimensionError(f"low and high must have the same shape, got {low.shape} and {high.shape}")
        if low.size == 0:
            raise DimensionError("a Box needs at least one dimension, got shape (0,)")
        if np.any(low > high):
            bad = np.flatnonzero(low > high)
            raise EmptySetError(f"Box is empty: low > high at indices {bad.tolist()}")
        object.__setattr__(self, "low", frozen_copy(low))
        object.__setattr__(self, "high", frozen_copy(high))

    @classmethod
    def from_center(cls, center, radius) -> "Box":
        """The box ``center +- radius``; ``radius`` is a scalar or an array, >= 0."""
        c = as_finite_array("center", center, ndim=1)
        r = as_finite_array("radius", radius)
        if r.ndim == 0:
            r = np.full_like(c, float(r))
        check_shape("radius", r, c.shape)
        if np.any(r < 0):
            raise EmptySetError("radius must be >= 0 in every coordinate")
        return cls(c - r, c + r)

    @property
    def dim(self) -> int:
        """The dimension n."""
        return self.low.shape[0]

    @property
    def center(self) -> np.ndarray:
        """``(low + high) / 2``."""
        return (self.low + self.high) / 2

    @property
    def radius(self) -> np.ndarray:
        """``(high - low) / 2``, per coordinate."""
        return (self.high - self.low) / 2

    def contains(self, x, tol: float = 0.0) -> bool:
        """True iff every point of ``x`` ((n,) or (k, n)) lies in the box grown by ``tol``."""
        pts = as_finite_array("x", x)
        if pts.shape[-1:] != (self.dim,) or pts.ndim > 2:
            raise DimensionError(f"x must have shape ({self.dim},) or (k, {self.dim}), got shape {pts.shape}")
        return bool(np.all(pts >= self.low - tol) and np.all(pts <= self.high + tol))

    def vertices(self) -> np.ndarray:
        """The 2^n corners, shape (2^n, n), ordered like `hypercube_signs`.

        Taken from ``low`` and ``high`` exactly (``center +- radius`` can round outside the box).
        """
        return np.where(hypercube_signs(self.dim) > 0, self.high, self.low)

    def intersect(self, other: "Box") -> "Box":
        """The intersection with another box; raises `EmptySetError` if empty."""
        if other.dim != self.dim:
            raise DimensionError(f"other must have dimension {self.dim}, got {other.dim}")
        return Box(np.maximum(self.low, other.low), np.minimum(self.high, other.high))

    def to_dict(self) -> dict:
        return {"low": self.low.tolist(), "high": self.high.tolist()}

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Box) and np.array_equal(self.low, other.low) and np.array_equal(self.high, other.high)

    def __hash__(self) -> int:
        return hash((self.low.tobytes(), self.high.tobytes()))

    def __repr__(self) -> str:
        return f"Box(low={self.low.tolist()}, high={self.high.tolist()})"


@dataclass(frozen=True, eq=False)
class Ellipsoid:
    """The ellipsoid ``{t : (t - c)^T G (t - c) <= radius^2}``.

    Parameters
    ----------
    center
        The centre c, shape (d,).
    gramian
        The symmetric positive definite shape matrix G, shape (d, d).
    radius
        The radius, > 0.
    """

    center: np.ndarray
    gramian: np.ndarray
    radius: float
    _eig: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        c = as_finite_array("center", self.center, ndim=1)
        d = c.shape[0]
        if d == 0:
            raise DimensionError("center needs at least one dimension, got shape (0,)")
        g = as_finite_array("gramian", self.gramian, (d, d))
        scale = max(1.0, float(np.max(np.abs(g))))
        if not np.max(np.abs(g - g.T)) <= 1e-10 * scale:
            raise InputError("gramian must be symmetric")
        g = (g + g.T) / 2
        eigenvalues, eigenvectors = np.linalg.eigh(g)
        if eigenvalues[0] <= 0:
            raise InputError(f"gramian must be positive definite, smallest eigenvalue is {eigenvalues[0]:.3g}")
        r = as_positive_scalar("radius", self.radius)
        object.__setattr__(self, "center", frozen_copy(c))
        object.__setattr__(self, "gramian", frozen_copy(g))
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "_eig", (frozen_copy(eigenvalues), frozen_copy(eigenvectors)))

    @property
    def dim(self) -> int:
        return self.center.shape[0]

    def contains(self, t, tol: float = 0.0) -> bool:
        """True iff every point of ``t`` ((d,) or (k, d)) satisfies the defining inequality.

        ``tol`` relaxes it to ``(t-c)^T G (t-c) <= radius^2 (1 + tol)``.
        """
        pts = as_finite_array("t", t)
        if pts.shape[-1:] != (self.dim,) or pts.ndim > 2:
            raise DimensionError(f"t must have shape ({self.dim},) or (k, {self.dim}), got shape {pts.shape}")
        delta = np.atleast_2d(pts) - self.center
        q = np.einsum("ki,ij,kj->k", delta, self.gramian, delta)
        return bool(np.all(q <= self.radius**2 * (1 + tol)))

    def semi_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Lengths ``radius / sqrt(l_i)`` and directions (columns of P), with G = P diag(l) P^T."""
        eigenvalues, eigenvectors = self._eig
        return self.radius / np.sqrt(eigenvalues), eigenvectors

    def bounding_box(self) -> Box:
        """The tightest enclosing box: ``c_i +- radius * sqrt((G^-1)_ii)``."""
        eigenvalues, eigenvectors = self._eig
        half_width = self.radius * np.sqrt(np.einsum("ij,j,ij->i", eigenvectors, 1 / eigenvalues, eigenvectors))
        return Box(self.center - half_width, self.center + half_width)

    def vertices(self) -> np.ndarray:
        """The 2^d vertices of the enclosing parallelotope aligned with the principal axes.

        Notes
        -----
        With ``G = P diag(l) P^T`` the vertices are ``c + radius * P diag(l)^(-1/2) h``
        for h in {-1, 1}^d (DESIGN errata: the reference code uses ``P^-1`` and one copy
        scales by ``sqrt(radius)``). Their convex hull contains the whole ellipsoid.
        """
        lengths, axes = self.semi_axes()
        return self.center + (hypercube_signs(self.dim) * lengths) @ axes.T

    def to_dict(self) -> dict:
        return {"center": self.center.tolist(), "gramian": self.gramian.tolist(), "radius": self.radius}

    def __repr__(self) -> str:
        return f"Ellipsoid(center={self.center.tolist()}, radius={self.radius:.6g}, dim={self.dim})"
