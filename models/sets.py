"""Immutable set values: axis-aligned boxes and ellipsoids, and the parameter-set protocol.

Every parameter set the library accepts (a prior `Box`, a confidence `Ellipsoid`, a
`~minimaxplan.models.polytope.VertexPolytope`) implements `ParameterSet`: dimension,
membership (with an optional witness of the first violation, as LazySets.jl's
``∈`` with ``witness=true``), a bounding box, the vertices of an enclosing polytope,
and ``to_dict``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

from .errors import DimensionError, EmptySetError, InputError
from .validation import (
    as_finite_array,
    as_points,
    as_positive_scalar,
    check_dimension,
    check_instance,
    check_same_shape,
    check_shape,
    frozen_copy,
)

__all__ = ["Box", "Ellipsoid", "Membership", "ParameterSet", "hypercube_signs"]


@dataclass(frozen=True)
class Membership:
    """The answer of ``contains(x, witness=True)``: inside or not, and the first violation.

    Attributes
    ----------
    inside
        True iff every point satisfies every constraint (within the tolerance).
    point
        Index of the first point (in the order given; 0 for a single point) that violates a
        constraint, or None when inside.
    constraint
        The violated constraint, in words (e.g. ``"x[1] <= high[1] + tol"``), or "" when inside.
    excess
        By how much that point violates it (> 0), in the constraint's own units; 0.0 when inside.

    Notes
    -----
    ``bool(membership)`` is ``membership.inside``.
    """

    inside: bool
    point: int | None = None
    constraint: str = ""
    excess: float = 0.0

    def __bool__(self) -> bool:
        return self.inside


@runtime_checkable
class ParameterSet(Protocol):
    """What the library needs of a set of uncertain parameters ``theta``.

    Implemented by `Box`, `Ellipsoid` and `~minimaxplan.models.polytope.VertexPolytope`;
    `~minimaxplan.models.polytope.parameter_vertices` and the interval predictors call
    `enclosing_vertices` instead of dispatching on the type.

    Notes
    -----
    The interval predictor needs the parameters as the convex hull of finitely many
    vertices (eq. (8)); `enclosing_vertices` returns vertices of a polytope that
    CONTAINS the set (never one that merely approximates it).
    """

    @property
    def dim(self) -> int:
        """The dimension d of the parameter space."""
        ...

    def contains(self, x: ArrayLike, tol: float = 0.0, *, witness: bool = False) -> bool | Membership:
        """Whether every point of ``x`` lies in the set.

        Parameters
        ----------
        x : array_like
            One point, shape (d,), or k points, shape (k, d).
        tol : float
            Slack, >= 0, in the units that the implementation documents (absolute for
            `Box`, relative on the quadratic form for `Ellipsoid`).
        witness : bool
            Return a `Membership` naming the first violation instead of a bool.

        Returns
        -------
        bool or Membership
        """
        ...

    def bounding_box(self) -> Box:
        """A box that contains the set.

        Returns
        -------
        Box
        """
        ...

    def enclosing_vertices(self, prior: Box | None = None) -> np.ndarray:
        """Vertices of a polytope containing the set (intersected with ``prior`` if given).

        Parameters
        ----------
        prior : Box or None
            The prior parameter box (the set D of Assumption 1), dimension d.

        Returns
        -------
        numpy.ndarray
            Shape (k, d): the convex hull of the rows contains the set (∩ ``prior``);
            eq. (8) needs the parameters in this form.

        Raises
        ------
        EmptySetError
            If the enclosure does not meet ``prior``.
        """
        ...

    def to_dict(self) -> dict:
        """The set as plain data (lists and floats, JSON-serialisable).

        Returns
        -------
        dict
        """
        ...


def hypercube_signs(dim: int) -> np.ndarray:
    """The 2^dim sign vectors of {-1, 1}^dim, one per row, in lexicographic order.

    Parameters
    ----------
    dim : int
        The dimension, >= 0.

    Returns
    -------
    numpy.ndarray
        Shape (2^dim, dim), float, -1 before 1 in each column (the last varies fastest).
    """
    return np.array(list(itertools.product((-1.0, 1.0), repeat=dim))).reshape(2**dim, dim)


#: Relative growth of an ellipsoid's computed support (`Ellipsoid.bounding_box`,
#: `Ellipsoid.vertices`), on top of ``SUPPORT_ROUNDING * d eps cond(G)``.
SUPPORT_MARGIN = 1e-12

#: Factor of ``d eps cond(G)`` in the relative growth of an ellipsoid's computed support:
#: solving with G perturbs ``p^T G^-1 p`` by a relative O(d eps cond(G)) (first order).
SUPPORT_ROUNDING = 16


def _centered_support(ellipsoid: Ellipsoid, directions: np.ndarray) -> np.ndarray:
    """``radius sqrt(p^T G^-1 p)`` for each column p, grown by the rounding margin.

    The margin is ``SUPPORT_MARGIN + SUPPORT_ROUNDING * d eps cond(G)`` (relative).
    """
    eps = np.finfo(float).eps
    support = ellipsoid.radius * np.sqrt(
        np.einsum("ji,ji->i", directions, np.linalg.solve(ellipsoid.gramian, directions))
    )
    return support * (1.0 + SUPPORT_MARGIN + SUPPORT_ROUNDING * ellipsoid.dim * eps * np.linalg.cond(ellipsoid.gramian))


def _parallelotope(ellipsoid: Ellipsoid) -> tuple[np.ndarray, np.ndarray]:
    """Axes P (columns) and half-widths h of the enclosing parallelotope ``|P^T (t - c)| <= h``.

    The half-widths are the ellipsoid's support ``radius sqrt(p_i^T G^-1 p_i)`` along the
    computed axes (equal to ``radius / sqrt(l_i)`` for exact eigenvectors, and correct for
    any direction, so rounding in the eigenvectors cannot cut the ellipsoid), grown by the
    margin of `_centered_support`.
    """
    _, axes = ellipsoid.semi_axes()
    return axes, _centered_support(ellipsoid, axes)


@dataclass(frozen=True, eq=False)
class Box:
    """The axis-aligned box ``{x : low <= x <= high}`` (an interval vector).

    Parameters
    ----------
    low, high : array_like
        Arrays of shape (n,), n >= 1, finite. Every ``low[i] <= high[i]``; degenerate
        sides (``low[i] == high[i]``) are allowed. Stored as read-only copies.

    Raises
    ------
    DimensionError
        If the shapes differ or are not (n,) with n >= 1.
    NonFiniteError
        If a bound is NaN or inf.
    EmptySetError
        If some ``low[i] > high[i]``.
    """

    low: np.ndarray
    high: np.ndarray

    def __post_init__(self) -> None:
        low = as_finite_array("low", self.low, ndim=1)
        high = as_finite_array("high", self.high, ndim=1)
        check_same_shape("low", low, "high", high)
        if low.size == 0:
            raise DimensionError("a Box needs at least one dimension, got shape (0,)")
        if np.any(low > high):
            bad = np.flatnonzero(low > high)
            raise EmptySetError(f"Box is empty: low > high at indices {bad.tolist()}")
        object.__setattr__(self, "low", frozen_copy(low))
        object.__setattr__(self, "high", frozen_copy(high))

    @classmethod
    def from_center(cls, center: ArrayLike, radius: ArrayLike) -> Box:
        """The box ``center +- radius``.

        Parameters
        ----------
        center : array_like
            Shape (n,).
        radius : float or array_like
            Half-widths, >= 0: a scalar (every coordinate) or shape (n,).

        Returns
        -------
        Box
            ``Box(center - radius, center + radius)`` (rounded to nearest).

        Raises
        ------
        DimensionError
            If ``center`` is empty or ``radius`` is an array whose shape is not ``center``'s.
        EmptySetError
            If some radius is negative.
        """
        c = as_finite_array("center", center, ndim=1)
        if c.size == 0:
            raise DimensionError("center needs at least one dimension, got shape (0,)")
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

    def contains(self, x: ArrayLike, tol: float = 0.0, *, witness: bool = False) -> bool | Membership:
        """True iff every point of ``x`` lies in the box grown by ``tol``.

        Parameters
        ----------
        x : array_like
            One point, shape (n,), or k points, shape (k, n).
        tol : float
            Absolute slack, finite and >= 0, in the coordinates' units: the test is
            ``low - tol <= x <= high + tol``.
        witness : bool
            Return a `Membership` naming the first violation instead: the first point
            (in order) and, within it, the first coordinate outside, with the distance
            beyond ``low - tol`` or ``high + tol``.

        Returns
        -------
        bool or Membership

        Raises
        ------
        DimensionError
            If ``x`` is not of shape (n,) or (k, n).
        InputError, NonFiniteError
            If ``tol`` is not a finite real number >= 0.
        """
        pts = as_points("x", x, self.dim)
        tol = as_positive_scalar("tol", tol, allow_zero=True)
        if not witness:
            return bool(np.all(pts >= self.low - tol) and np.all(pts <= self.high + tol))
        rows = np.atleast_2d(pts)
        below, above = (self.low - tol) - rows, rows - (self.high + tol)
        bad = np.flatnonzero(((below > 0) | (above > 0)).reshape(-1))
        if bad.size == 0:
            return Membership(True)
        k, i = divmod(int(bad[0]), self.dim)
        if below[k, i] > 0:
            return Membership(False, k, f"x[{i}] >= low[{i}] - tol", float(below[k, i]))
        return Membership(False, k, f"x[{i}] <= high[{i}] + tol", float(above[k, i]))

    def vertices(self) -> np.ndarray:
        """The 2^n corners, ordered like `hypercube_signs`.

        Returns
        -------
        numpy.ndarray
            Shape (2^n, n), taken from ``low`` and ``high`` exactly (``center +- radius``
            can round outside the box).
        """
        return np.where(hypercube_signs(self.dim) > 0, self.high, self.low)

    def intersect(self, other: Box) -> Box:
        """The intersection with another box (exact: the bounds are maxima and minima).

        Parameters
        ----------
        other : Box
            A box of the same dimension.

        Returns
        -------
        Box

        Raises
        ------
        InputError
            If ``other`` is not a `Box`.
        DimensionError
            If the dimensions differ.
        EmptySetError
            If the boxes do not meet.
        """
        check_instance("other", other, Box)
        check_dimension("other", other.dim, self.dim)
        return Box(np.maximum(self.low, other.low), np.minimum(self.high, other.high))

    def bounding_box(self) -> Box:
        """The box itself (a `ParameterSet` method).

        Returns
        -------
        Box
        """
        return self

    def enclosing_vertices(self, prior: Box | None = None) -> np.ndarray:
        """The 2^n corners (exactly ``low`` or ``high``), of ``self ∩ prior`` when a prior is given.

        Parameters
        ----------
        prior : Box or None
            The prior parameter box (the set D of Assumption 1), dimension n.

        Returns
        -------
        numpy.ndarray
            Shape (2^n, n), ordered like `hypercube_signs`. Box ∩ box is exact.

        Raises
        ------
        DimensionError
            If ``prior`` has another dimension.
        EmptySetError
            If the intersection is empty.
        """
        if prior is None:
            return self.vertices()
        check_dimension("prior", prior.dim, self.dim, "the parameter box's")
        from .polytope import intersect_boxes

        return intersect_boxes(self, prior, "the parameter box").vertices()

    def to_dict(self) -> dict:
        """The box as plain data.

        Returns
        -------
        dict
            ``{"low": [...], "high": [...]}``.
        """
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
    center : array_like
        The centre c, shape (d,), d >= 1.
    gramian : array_like
        The symmetric positive definite shape matrix G, shape (d, d) (symmetric to
        1e-10 relative; stored symmetrised).
    radius : float
        The radius, > 0.

    Raises
    ------
    DimensionError
        If the shapes do not match.
    NonFiniteError
        If an entry is NaN or inf.
    InputError
        If G is not symmetric or not positive definite, or the radius is not > 0.

    Notes
    -----
    The confidence sets of `~minimaxplan.models.confidence_ellipsoid` have this form,
    with G the regularised Gram matrix ``G_N`` and radius ``beta_N(delta)``.
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
        """The dimension d."""
        return self.center.shape[0]

    def contains(self, t: ArrayLike, tol: float = 0.0, *, witness: bool = False) -> bool | Membership:
        """True iff every point of ``t`` satisfies the defining inequality (in floating point).

        Parameters
        ----------
        t : array_like
            One point, shape (d,), or k points, shape (k, d).
        tol : float
            Relative slack on the quadratic form, finite and >= 0: the test is
            ``(t-c)^T G (t-c) <= radius^2 (1 + tol)``.
        witness : bool
            Return a `Membership` naming the first point outside and by how much its
            quadratic form exceeds ``radius^2 (1 + tol)``.

        Returns
        -------
        bool or Membership

        Raises
        ------
        DimensionError
            If ``t`` is not of shape (d,) or (k, d).
        InputError, NonFiniteError
            If ``tol`` is not a finite real number >= 0.
        """
        pts = as_points("t", t, self.dim)
        tol = as_positive_scalar("tol", tol, allow_zero=True)
        delta = np.atleast_2d(pts) - self.center
        q = np.einsum("ki,ij,kj->k", delta, self.gramian, delta)
        limit = self.radius**2 * (1 + tol)
        if not witness:
            return bool(np.all(q <= limit))
        bad = np.flatnonzero(~(q <= limit))
        if bad.size == 0:
            return Membership(True)
        k = int(bad[0])
        return Membership(False, k, "(t - c)^T G (t - c) <= radius^2 (1 + tol)", float(q[k] - limit))

    def semi_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """The principal semi-axes: lengths and directions.

        Returns
        -------
        lengths : numpy.ndarray
            Shape (d,): ``radius / sqrt(l_i)``, ascending eigenvalues ``l_i`` of G.
        axes : numpy.ndarray
            Shape (d, d): the unit directions, as columns of P, with ``G = P diag(l) P^T``.
        """
        eigenvalues, eigenvectors = self._eig
        return self.radius / np.sqrt(eigenvalues), eigenvectors

    def bounding_box(self) -> Box:
        """An enclosing box, rounded outward: ``c_i +- radius * sqrt((G^-1)_ii)`` and a margin.

        Returns
        -------
        Box
            Contains every point of the ellipsoid, also in floating point: a point
            that satisfies ``(t - c)^T G (t - c) <= radius^2`` exactly (in real
            arithmetic) lies in the box.

        Notes
        -----
        The exact tightest box has half-widths ``radius sqrt((G^-1)_ii)``. They are
        computed as the ellipsoid's support along the coordinate axes, grown by the
        relative margin ``SUPPORT_MARGIN + SUPPORT_ROUNDING * d eps cond(G)`` (the
        first-order error of solving with G), and ``c -+ half_width`` is then moved one
        ulp outward, since rounding ``c + half_width`` to nearest may land inside by half
        an ulp of ``|c|``. The interval predictor's enclosures use the same margins
        (`~minimaxplan.models.polytope.parameter_vertices`).
        """
        half_width = _centered_support(self, np.eye(self.dim))
        return Box(np.nextafter(self.center - half_width, -np.inf), np.nextafter(self.center + half_width, np.inf))

    def vertices(self) -> np.ndarray:
        """The 2^d vertices of the enclosing parallelotope aligned with the principal axes, rounding-safe.

        Returns
        -------
        numpy.ndarray
            Shape (2^d, d), one vertex per sign vector of `hypercube_signs`. Their
            convex hull contains every point of the ellipsoid, also in floating point:
            a point that satisfies the defining inequality exactly lies in the hull.

        Notes
        -----
        With ``G = P diag(l) P^T`` the vertices are ``c + radius * P diag(l)^(-1/2) h``
        for h in {-1, 1}^d (DESIGN errata: the reference code uses ``P^-1`` and one copy
        scales by ``sqrt(radius)``). The half-widths ``radius / sqrt(l_i)`` are computed
        as the ellipsoid's support along the computed axes (correct for any direction,
        so rounding in the eigenvectors cannot cut the ellipsoid), grown by the relative
        margin ``SUPPORT_MARGIN + SUPPORT_ROUNDING * d eps cond(G)``; the vertices are then
        dilated about c by their own rounding error, ``4 (d + 1) eps (max |c| + sum h)``,
        over the smallest half-width (the parallelotope's inradius, P being orthonormal).
        These are the vertices that the interval predictor uses for an ellipsoid (eq. (8)).
        """
        axes, support = _parallelotope(self)
        vertices = self.center + (hypercube_signs(self.dim) * support) @ axes.T
        vertex_error = 4 * (self.dim + 1) * np.finfo(float).eps * (np.max(np.abs(self.center)) + np.sum(support))
        return self.center + (1.0 + vertex_error / np.min(support)) * (vertices - self.center)

    def enclosing_vertices(self, prior: Box | None = None) -> np.ndarray:
        """Vertices of a polytope that contains the ellipsoid (∩ ``prior`` when given), rounding-safe.

        Parameters
        ----------
        prior : Box or None
            The prior parameter box (the set D of Assumption 1), dimension d.

        Returns
        -------
        numpy.ndarray
            Without a prior: `vertices`, the 2^d vertices of the enclosing
            parallelotope, grown by rounding-level margins so that their hull contains
            the ellipsoid in floating point too. With a prior: the vertices of
            parallelotope ∩ bounding box ∩ prior (clipping the vertices to the prior
            would NOT be sound; DESIGN errata), shape (k, d).

        Raises
        ------
        DimensionError
            If ``prior`` has another dimension.
        EmptySetError
            If the enclosing polytope does not meet ``prior``.

        Notes
        -----
        The parameter polytope of eq. (8); see
        `~minimaxplan.models.polytope.parameter_vertices`, Notes.
        """
        from .polytope import ellipsoid_in_box_vertices

        if prior is None:
            return self.vertices()
        check_dimension("prior", prior.dim, self.dim, "the ellipsoid's")
        return ellipsoid_in_box_vertices(self, prior)

    def to_dict(self) -> dict:
        """The ellipsoid as plain data.

        Returns
        -------
        dict
            ``{"center": [...], "gramian": [[...]], "radius": r}``.
        """
        return {"center": self.center.tolist(), "gramian": self.gramian.tolist(), "radius": self.radius}

    def __repr__(self) -> str:
        return f"Ellipsoid(center={self.center.tolist()}, radius={self.radius:.6g}, dim={self.dim})"
