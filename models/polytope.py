"""Parameter sets as polytopes: the vertices that the interval predictor works with.

The interval predictor needs the uncertain parameters as the convex hull of finitely
many vertices (eq. (8)). This module turns every parameter set that the library
produces (a prior `Box`, a confidence `Ellipsoid`, an explicit vertex array) into such
a vertex array, always for a polytope that CONTAINS the set, never one that merely
approximates it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection, QhullError

from .errors import DimensionError, EmptySetError, SolverFailure
from .sets import Box, Ellipsoid, Membership, ParameterSet, _centered_support, _parallelotope
from .validation import as_finite_array, as_points, check_dimension, check_instance, frozen_copy

__all__ = [
    "VertexPolytope",
    "as_parameter_set",
    "parameter_vertices",
    "box_halfspaces",
    "parallelotope_halfspaces",
    "polytope_vertices",
    "intersect_boxes",
    "ellipsoid_in_box_vertices",
    "HULL_MEMBERSHIP_TOLERANCE",
]

#: Absolute error budget of qhull's vertices, relative to the coordinates' magnitude.
#: The returned vertices are dilated about an interior point so that their hull
#: exceeds the exact polytope by at least this margin in every direction.
VERTEX_ERROR = 1e-11

#: A Chebyshev radius below this (relative to the set's size) means the polytope is
#: flat (lower-dimensional), where qhull cannot enumerate vertices.
FLAT_RADIUS = 1e-9

#: `VertexPolytope.contains` counts a point as inside when its distance (infinity norm)
#: to the hull, computed by an LP, is at most ``tol`` plus this times the coordinates'
#: magnitude (the LP solver's own feasibility tolerance; points on a facet may otherwise
#: come out a few ulps outside).
HULL_MEMBERSHIP_TOLERANCE = 1e-9


def box_halfspaces(box: Box) -> tuple[np.ndarray, np.ndarray]:
    """The box as ``{t : a t <= b}``.

    Parameters
    ----------
    box : Box
        A box of dimension d.

    Returns
    -------
    a : numpy.ndarray
        Shape (2d, d): the rows of I, then of -I.
    b : numpy.ndarray
        Shape (2d,): ``high``, then ``-low`` (exact).
    """
    eye = np.eye(box.dim)
    return np.vstack([eye, -eye]), np.concatenate([box.high, -box.low])


def _bounding_box(ellipsoid: Ellipsoid) -> Box:
    """The ellipsoid's bounding box from its support along the axes, without the final ulp.

    `ellipsoid_in_box_vertices` dilates its result by `VERTEX_ERROR`, which absorbs the
    rounding of ``c +- half_width``; `Ellipsoid.bounding_box` rounds that outward instead.
    """
    half_width = _centered_support(ellipsoid, np.eye(ellipsoid.dim))
    return Box(ellipsoid.center - half_width, ellipsoid.center + half_width)


def parallelotope_halfspaces(ellipsoid: Ellipsoid) -> tuple[np.ndarray, np.ndarray]:
    """The enclosing parallelotope of the ellipsoid as ``{t : a t <= b}``.

    Parameters
    ----------
    ellipsoid : Ellipsoid
        The ellipsoid, dimension d.

    Returns
    -------
    a : numpy.ndarray
        Shape (2d, d): the unit axes ``P^T``, then ``-P^T``.
    b : numpy.ndarray
        Shape (2d,): the support along each row, grown by the rounding margin of
        `~minimaxplan.models.Ellipsoid.vertices`.

    Notes
    -----
    With ``G = P diag(l) P^T`` the parallelotope is ``|P^T (t - c)|_i <= radius / sqrt(l_i)``
    (DESIGN errata: the box of the ellipsoid's principal axes), see `_parallelotope`.
    Rows of ``a`` are unit vectors.
    """
    axes, support = _parallelotope(ellipsoid)
    offset = axes.T @ ellipsoid.center
    return np.vstack([axes.T, -axes.T]), np.concatenate([offset + support, -offset + support])


def _chebyshev_center(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and radius of the largest ball in ``{t : a t <= b}`` (an LP, HiGHS).

    Raises `EmptySetError` when the LP is infeasible (the polytope is empty) and
    `SolverFailure` for any other status that is not a success.
    """
    norms = np.linalg.norm(a, axis=1)
    d = a.shape[1]
    cost = np.zeros(d + 1)
    cost[-1] = -1.0  # maximise the radius
    result = linprog(
        cost,
        A_ub=np.hstack([a, norms[:, None]]),
        b_ub=b,
        bounds=[(None, None)] * d + [(0, None)],
        method="highs",
    )
    if result.status == 2:
        raise EmptySetError("the intersection of the parameter set with the prior box is empty")
    if result.status != 0:
        raise SolverFailure(f"Chebyshev-centre LP failed with status {result.status}: {result.message}")
    return result.x[:d], float(result.x[-1])


def polytope_vertices(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """Vertices of the bounded polytope ``{t : a t <= b}``, slightly dilated outward.

    Parameters
    ----------
    a : numpy.ndarray
        Constraint normals, shape (m, d); the polytope must be bounded.
    b : numpy.ndarray
        Offsets, shape (m,).

    Returns
    -------
    numpy.ndarray or None
        The vertices, shape (k, d), whose hull contains the polytope; None when the
        polytope is flat (its Chebyshev radius is below `FLAT_RADIUS` times its size),
        where exact enumeration by qhull is impossible.

    Raises
    ------
    EmptySetError
        If the polytope is empty.
    SolverFailure
        If the Chebyshev-centre LP or qhull fails.

    Notes
    -----
    The vertices are computed by `scipy.spatial.HalfspaceIntersection` from the
    Chebyshev centre ``c`` (radius ``r``) and then moved to ``c + (1 + s) (v - c)``.
    Since the polytope contains the ball of radius r about c, the dilated hull
    contains the exact polytope grown by ``s r``; with ``s r >= VERTEX_ERROR * scale``
    (scale = the largest coordinate magnitude) the rounding of qhull is absorbed.
    """
    d = a.shape[1]
    if d == 1:
        upper = np.min(b[a[:, 0] > 0] / a[a[:, 0] > 0, 0])
        lower = np.max(b[a[:, 0] < 0] / a[a[:, 0] < 0, 0])
        if lower > upper:
            raise EmptySetError("the intersection of the parameter set with the prior box is empty")
        return np.array([[lower], [upper]])
    center, radius = _chebyshev_center(a, b)
    size = max(1.0, float(np.max(np.abs(b))))
    if radius <= FLAT_RADIUS * size:
        return None
    try:
        vertices = HalfspaceIntersection(np.hstack([a, -b[:, None]]), center).intersections
    except QhullError as exc:  # not expected with a strictly interior point; never hidden
        raise SolverFailure(f"qhull failed to enumerate the polytope's vertices: {exc}") from None
    scale = max(1.0, float(np.max(np.abs(vertices))))
    vertices = _drop_near_duplicates(vertices, 1e-14 * scale)
    dilation = max(VERTEX_ERROR, VERTEX_ERROR * scale / radius)
    return center + (1.0 + dilation) * (vertices - center)


def _drop_near_duplicates(points: np.ndarray, tol: float) -> np.ndarray:
    """Keep one of each cluster of points closer than ``tol`` (qhull repeats degenerate vertices).

    Dropping a point within ``tol`` of a kept one shrinks the hull by at most ``tol``;
    callers pass a ``tol`` far below the dilation margin ``VERTEX_ERROR * scale``.
    """
    kept: list[np.ndarray] = []
    for point in points:
        if not any(np.max(np.abs(point - other)) <= tol for other in kept):
            kept.append(point)
    return np.array(kept)


def intersect_boxes(box: Box, prior: Box, what: str) -> Box:
    """``box ∩ prior``, with an error message that says which set missed the prior.

    Parameters
    ----------
    box : Box
        The enclosure of a parameter set.
    prior : Box
        The prior parameter box, same dimension.
    what : str
        What ``box`` is, in words (e.g. ``"the ellipsoid's bounding box"``).

    Returns
    -------
    Box

    Raises
    ------
    EmptySetError
        If the boxes do not meet, naming ``what`` and both boxes.
    """
    try:
        return box.intersect(prior)
    except EmptySetError:
        raise EmptySetError(f"{what} {box!r} does not meet the prior {prior!r}: the parameter set is empty") from None


def ellipsoid_in_box_vertices(ellipsoid: Ellipsoid, prior: Box) -> np.ndarray:
    """Vertices of (parallelotope ∩ bounding box ∩ prior), a sound enclosure of ellipsoid ∩ prior.

    Parameters
    ----------
    ellipsoid : Ellipsoid
        The parameter set, dimension d.
    prior : Box
        The prior parameter box (Assumption 1), dimension d.

    Returns
    -------
    numpy.ndarray
        Shape (k, d): qhull's vertices, dilated outward (see `polytope_vertices`), or
        the corners of bounding box ∩ prior when that intersection is flat.

    Raises
    ------
    EmptySetError
        If the ellipsoid's bounding box or the polytope does not meet ``prior``.
    """
    box = intersect_boxes(_bounding_box(ellipsoid), prior, "the ellipsoid's bounding box")
    a_par, b_par = parallelotope_halfspaces(ellipsoid)
    a_box, b_box = box_halfspaces(box)
    vertices = polytope_vertices(np.vstack([a_par, a_box]), np.concatenate([b_par, b_box]))
    if vertices is None:
        # Flat intersection (e.g. a prior side of zero width): the box, which contains it, is enumerable.
        return box.vertices()
    return vertices


def _array_in_box_vertices(vertices: np.ndarray, prior: Box) -> np.ndarray:
    """Vertices of a sound enclosure of co{vertices} ∩ prior."""
    if np.all(vertices >= prior.low) and np.all(vertices <= prior.high):
        return vertices  # the hull already lies in the prior box
    hull_box = intersect_boxes(Box(vertices.min(axis=0), vertices.max(axis=0)), prior, "the vertices' bounding box")
    d = vertices.shape[1]
    if vertices.shape[0] <= d or np.linalg.matrix_rank(vertices[1:] - vertices[0]) < d:
        return hull_box.vertices()  # a flat hull: its bounding box (∩ prior) contains co{V} ∩ prior
    equations = ConvexHull(vertices).equations
    a_box, b_box = box_halfspaces(hull_box)
    clipped = polytope_vertices(np.vstack([equations[:, :-1], a_box]), np.concatenate([-equations[:, -1], b_box]))
    return hull_box.vertices() if clipped is None else clipped


@dataclass(frozen=True, eq=False)
class VertexPolytope:
    """The polytope ``co{v_1, ..., v_k}``, given by its vertices (any k >= 1): a `ParameterSet`.

    Parameters
    ----------
    vertices : array_like
        Array of shape (k, d), k, d >= 1, finite; stored as a read-only copy and taken
        as is (rows need not be extreme points).

    Raises
    ------
    DimensionError
        If ``vertices`` is not of shape (k, d) with k, d >= 1.
    NonFiniteError
        If a coordinate is NaN or inf.

    Notes
    -----
    The form of the parameter polytope of eq. (8). Arrays of vertices given to
    `parameter_vertices`, `~minimaxplan.models.predict_tube` or the planners are wrapped
    in this value at the boundary.
    """

    vertices: np.ndarray

    def __post_init__(self) -> None:
        v = as_finite_array("vertices", self.vertices, ndim=2)
        if v.shape[0] == 0 or v.shape[1] == 0:
            raise DimensionError(f"vertices must have shape (k, d) with k, d >= 1, got shape {v.shape}")
        object.__setattr__(self, "vertices", frozen_copy(v))

    @property
    def dim(self) -> int:
        """The dimension d."""
        return self.vertices.shape[1]

    @property
    def nvertices(self) -> int:
        """The number k of vertices given."""
        return self.vertices.shape[0]

    def bounding_box(self) -> Box:
        """The tightest enclosing box: the vertices' coordinate-wise minima and maxima (exact).

        Returns
        -------
        Box
        """
        return Box(self.vertices.min(axis=0), self.vertices.max(axis=0))

    def enclosing_vertices(self, prior: Box | None = None) -> np.ndarray:
        """The vertices themselves, or those of a sound enclosure of ``co{V} ∩ prior``.

        Parameters
        ----------
        prior : Box or None
            The prior parameter box (the set D of Assumption 1), dimension d.

        Returns
        -------
        numpy.ndarray
            Shape (k', d). Without a prior, or when every vertex lies in the prior: the
            vertices as given. Otherwise the vertices of co{V} ∩ bounding box ∩ prior
            (qhull's, dilated outward by `VERTEX_ERROR`; the box when co{V} is flat).

        Raises
        ------
        DimensionError
            If ``prior`` has another dimension.
        EmptySetError
            If the hull does not meet ``prior``.
        """
        if prior is None:
            return self.vertices
        check_dimension("prior", prior.dim, self.dim, f"the polytope's vertices have shape {self.vertices.shape}")
        return _array_in_box_vertices(self.vertices, prior)

    def contains(self, x: ArrayLike, tol: float = 0.0, *, witness: bool = False) -> bool | Membership:
        """True iff every point of ``x`` lies in the convex hull, within ``tol``.

        Parameters
        ----------
        x : array_like
            One point, shape (d,), or k points, shape (k, d).
        tol : float
            Absolute slack, in the coordinates' units: a point counts as inside when its
            infinity-norm distance to the hull (an LP, HiGHS) is at most
            ``tol + HULL_MEMBERSHIP_TOLERANCE * (1 + max |coordinate|)``.
        witness : bool
            Return a `Membership` naming the first point outside and its distance beyond
            that allowance.

        Returns
        -------
        bool or Membership

        Raises
        ------
        DimensionError
            If ``x`` is not of shape (d,) or (k, d).
        SolverFailure
            If the distance LP does not solve.
        """
        pts = as_points("x", x, self.dim)
        for index, point in enumerate(np.atleast_2d(pts)):
            distance = self._distance(point)
            allowance = tol + HULL_MEMBERSHIP_TOLERANCE * (
                1.0 + max(float(np.max(np.abs(point))), float(np.max(np.abs(self.vertices))))
            )
            if distance > allowance:
                if not witness:
                    return False
                return Membership(False, index, "distance to co{vertices} <= tol", float(distance - allowance))
        return Membership(True) if witness else True

    def _distance(self, point: np.ndarray) -> float:
        """``min ||V^T lam - point||_inf`` over the simplex, by an LP."""
        k, d = self.vertices.shape
        # variables: lam (k) >= 0, s >= 0;  -s <= V^T lam - x <= s,  sum lam = 1;  minimise s
        cost = np.zeros(k + 1)
        cost[-1] = 1.0
        V_T = self.vertices.T
        A_ub = np.block([[V_T, -np.ones((d, 1))], [-V_T, -np.ones((d, 1))]])
        b_ub = np.concatenate([point, -point])
        A_eq = np.concatenate([np.ones(k), [0.0]])[None]
        result = linprog(
            cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=[1.0], bounds=[(0, None)] * (k + 1), method="highs"
        )
        if result.status != 0:
            raise SolverFailure(f"hull-membership LP failed with status {result.status}: {result.message}")
        return float(result.x[-1])

    def to_dict(self) -> dict:
        """The polytope as plain data.

        Returns
        -------
        dict
            ``{"vertices": [[...], ...]}``.
        """
        return {"vertices": self.vertices.tolist()}

    def __repr__(self) -> str:
        return f"VertexPolytope(nvertices={self.nvertices}, dim={self.dim})"


def as_parameter_set(parameters: ParameterSet | ArrayLike) -> ParameterSet:
    """``parameters`` as a `ParameterSet`: a set is returned as is, an array (k, d) of vertices is wrapped.

    Parameters
    ----------
    parameters : ParameterSet or array_like
        A `Box`, `Ellipsoid`, `VertexPolytope` (any `ParameterSet`), or the vertices
        of a polytope, shape (k, d).

    Returns
    -------
    ParameterSet
        The set itself, or a `VertexPolytope` of the vertices.

    Raises
    ------
    DimensionError, NonFiniteError, InputError
        For an array that is not a finite (k, d) array with k, d >= 1 (named ``parameters``).
    """
    if isinstance(parameters, ParameterSet):
        return parameters
    vertices = as_finite_array("parameters", parameters, ndim=2)
    if vertices.shape[0] == 0 or vertices.shape[1] == 0:
        raise DimensionError(f"parameters must have shape (k, d) with k, d >= 1, got shape {vertices.shape}")
    return VertexPolytope(vertices)


def parameter_vertices(parameters: ParameterSet | ArrayLike, prior: Box | None = None) -> np.ndarray:
    """Vertices of a polytope that contains a parameter set (eq. (8)).

    Parameters
    ----------
    parameters : ParameterSet or array_like
        A `ParameterSet` (`Box`, `Ellipsoid`, `VertexPolytope`), or an array of shape
        (k, d) whose rows are the vertices of a polytope (any k >= 1; taken as is,
        wrapped in a `VertexPolytope`).
    prior : Box or None
        Optional prior `Box` (the set D of Assumption 1); the result then contains
        ``parameters ∩ prior``.

    Returns
    -------
    numpy.ndarray
        Shape (k', d): the convex hull of the rows contains the (intersected) set.

    Raises
    ------
    EmptySetError
        If the enclosing polytope does not meet ``prior``.
    DimensionError, NonFiniteError, InputError
        For a malformed argument.

    Notes
    -----
    - Box: its 2^d corners, exactly (intersected with ``prior`` first; box ∩ box is exact).
    - Ellipsoid, no prior: the 2^d vertices of the enclosing parallelotope of the
      errata, ``c + radius P diag(l)^(-1/2) h``, grown by rounding-level margins so
      that their hull contains the ellipsoid in floating point too.
    - Ellipsoid with prior: clipping the parallelotope's vertices to the prior is NOT
      sound (the clipped hull can miss parts of the ellipsoid). The result here is the
      exact vertex set of parallelotope ∩ bounding box ∩ prior, three sound
      enclosures of the ellipsoid intersected, so it is contained in each of the
      obvious candidates (the clipped box, the parallelotope) and never larger. The
      vertices come from `scipy.spatial.HalfspaceIntersection`, dilated outward (see
      `polytope_vertices`) to absorb rounding. When that intersection is flat
      (some prior side has zero width) qhull cannot enumerate it, and the enclosing
      box (bounding box ∩ prior) is returned instead: equally sound, possibly larger.
    - Array with prior: unchanged if every vertex lies in the prior; otherwise the
      exact vertices of co{V} ∩ bounding box ∩ prior (the box when co{V} is flat).

    Emptiness is decided on the enclosing polytope, so an ellipsoid that misses the
    prior only between the parallelotope's corners is not reported as empty.

    Each case is the set's own `ParameterSet.enclosing_vertices` method.
    """
    check_instance("prior", prior, (Box, type(None)), "a Box or None")
    return as_parameter_set(parameters).enclosing_vertices(prior)
