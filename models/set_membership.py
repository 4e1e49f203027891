"""Recursive set-membership estimation of the uncertain parameters under bounded noise."""

from __future__ import annotations

import numpy as np

from .errors import DimensionError, EmptySetError, InputError
from .sets import Box, Ellipsoid
from .validation import as_count, as_finite_array, check_dimension, check_instance, check_shape, frozen_copy

__all__ = ["SetMembershipEstimator"]

#: Relative outward rounding of every reported bound (radius, box), covering the
#: rounding errors of the update so that the reported sets stay sound in floating point.
OUTWARD_ROUNDING = 1e-9

#: An update whose new shape factor ``s`` falls below this is skipped (skipping is
#: always sound): the ellipsoid would be thinner than rounding can resolve.
MIN_SHRINK = 1e-12

#: The noise bound of each row is widened by this much relative to the magnitudes in
#: the measurement, ``|y| + |phi| |c|``: targets formed in floating point carry rounding
#: errors of that order, which would otherwise put theta* just outside an extreme strip.
MEASUREMENT_ROUNDING = 1e-12

#: ``s`` below ``-INCONSISTENCY_TOLERANCE`` proves the data empty the feasible set.
INCONSISTENCY_TOLERANCE = 1e-9


class SetMembershipEstimator:
    """Recursive least-squares set-membership estimator with a dead zone (eqs. (3)-(6)).

    It keeps an ellipsoid ``E_k = {t : (t - c_k)^T P_k^-1 (t - c_k) <= 1}`` that holds
    every parameter consistent with the prior box and with all measurements
    ``|target_i - regressor_i @ theta| <= noise_bound_i`` seen so far.

    Parameters
    ----------
    nparams
        d, the number of parameters.
    noise_bound
        The bound on the lumped disturbance of each measured row: for every sample,
        ``|target_i - regressor_i @ theta*| <= noise_bound_i`` for each row i (an
        infinity-norm bound when a scalar, else one bound per row, shape (p,)). For an
        `UncertainLinearSystem` with ``target = x_{n+1} - A0 x_n - B u_n`` the lumped
        disturbance is ``D w_n``, bounded per row by ``max |D w|`` over the box ``w``.
        Must be > 0.
    prior
        The prior parameter box (the set D of Assumption 1), which must contain theta*.

    Attributes
    ----------
    estimate
        The current point estimate, shape (d,): of the ellipsoid centre ``c_k``
        projected on `parameter_set`, the centre of `parameter_set` and the previous
        estimate, the one with the smallest certified error bound (see the notes).
    radius
        A bound on ``||theta* - estimate||_2``; it never grows.
    ellipsoid_center, shape_matrix
        ``c_k`` and ``P_k`` of the ellipsoid ``E_k``.
    nsamples
        The number of samples absorbed.

    Notes
    -----
    The paper prints eqs. (3)-(6) garbled. This is the set-membership recursion of
    Dasgupta & Huang (1987) without forgetting factor (the form the paper's dead-zone
    gain (4c) comes from, as in Tan, Wen & Soh 1997), in normalised form. For a scalar
    measurement ``y = phi^T theta + v`` with ``|v| <= gamma``, prediction error
    ``e = y - phi^T c`` and ``g = phi^T P phi``:

    * dead zone: if ``|e| <= gamma`` (or ``g = 0``), nothing changes (eq. (4c), kappa = 0).
      Here gamma is the row's noise bound widened by ``MEASUREMENT_ROUNDING`` times
      ``|y| + |phi|^T |c| + gamma``, so that rounding in the targets cannot exclude theta*;
    * otherwise, with the gain ``kappa = (|e| - gamma) / (gamma g)`` of eq. (4c) (it
      minimises the new scale, eq. (6)) every t in ``E_k`` that satisfies the
      measurement satisfies ``(t - c)^T (P^-1 + kappa phi phi^T) (t - c) <= s`` after
      completing the square, where

      ``c+ = c + (e - gamma sign(e)) P phi / g``                 (eq. (3))
      ``P+ = s (P - (1 - gamma/|e|) P phi phi^T P / g)``        (eq. (4b))
      ``s  = 1 - (|e| - gamma)^2 / g``                           (eq. (6))

      so ``E_{k+1}`` contains ``E_k`` intersected with the measurement's strip.

    Why the radius cannot grow: ``0 < s <= 1`` and ``P+ <= s P <= P`` in the Loewner
    order, so the largest semi-axis ``sqrt(lmax(P_k))`` of ``E_k`` never grows, and it
    bounds ``||theta* - c_k||``. (A Fogel-Huang minimum-volume ellipsoid, or
    Dasgupta-Huang with a forgetting factor, can grow ``lmax`` and so does not qualify.)
    The reported pair (`estimate`, `radius`) is then chosen after each sample as the
    better certified of two candidates:

    * ``c_k`` projected on `parameter_set` (projection on a convex set that holds
      theta* moves no point away from theta*), with bound
      ``min(sqrt(lmax(P_k)), farthest corner of the box from it)``;
    * the centre of `parameter_set`, with bound its half-diagonal;
    * the previous estimate, with bound ``min(previous radius, its farthest corner)``.

    Each bound is valid for its own point, and the last candidate's is at most the
    previous radius, so the radius never grows, by construction and not only up to
    rounding. Bounds are rounded outward by ``OUTWARD_ROUNDING``.

    ``P`` is carried as a square-root factor ``P = L L^T``, updated as
    ``L+ = sqrt(s) (L - (1 - sqrt(gamma/|e|)) (L v) v^T / g)`` with ``v = L^T phi``; this
    stays positive semidefinite in floating point and allows degenerate prior sides.
    The prior box enters as its minimum-volume enclosing ellipsoid, ``P_0 = d diag(r^2)``.

    The dead zone makes ``c_k`` converge (its prediction errors end up within the noise
    bound), but the ellipsoid shrinks only while they leave it, so ``sqrt(lmax(P_k))``
    stalls above the feasible set; the box, which uses every row, keeps shrinking. In
    a 2-parameter test with uniform noise (bound 0.05, 400 samples of 2 rows) the largest
    semi-axis fell from 1.41 to 0.28 but the box to half-widths below 1e-3 and the
    reported radius to 1e-3. The box is not the tightest one consistent with the data;
    that is the LP of ``minimaxplan.verify.feasible_parameter_box``.

    `parameter_set` is eq. (5) with boxes: the intersection of the prior with the
    bounding boxes of every ``E_k`` so far (each holds theta*), further tightened by
    every measured row, dead zone or not, through interval propagation of its strip
    ``|y - phi^T t| <= gamma`` (for each j, bound ``phi_j t_j`` by the strip minus the
    other terms' ranges over the box). All of these are sound, so the box only shrinks
    and always holds theta*. A measurement whose strip misses ``E_k`` (``s < 0``) or the
    box proves that the prior, the noise bound and the data are inconsistent: `update`
    then raises `EmptySetError` and keeps its state.
    """

    def __init__(self, nparams: int, *, noise_bound, prior: Box) -> None:
        d = as_count("nparams", nparams)
        check_instance("prior", prior, Box)
        check_dimension("prior", prior.dim, d, "nparams")
        bound = as_finite_array("noise_bound", noise_bound)
        if bound.ndim > 1:
            raise DimensionError(f"noise_bound must be a scalar or have shape (p,), got shape {bound.shape}")
        if bound.size == 0 or np.any(bound <= 0):
            raise InputError(f"noise_bound must be > 0 in every row, got {bound.tolist()}")
        self._d = d
        self._noise_bound = frozen_copy(bound)
        self._center = prior.center.copy()
        self._factor = np.diag(np.sqrt(d) * prior.radius)
        self._estimate = prior.center.copy()
        self._radius = _farthest_corner_distance(self._estimate, prior)
        self._box = prior
        self._nsamples = 0

    # ------------------------------------------------------------------ state
    @property
    def nparams(self) -> int:
        """d, the number of parameters."""
        return self._d

    @property
    def nsamples(self) -> int:
        """The number of samples absorbed so far."""
        return self._nsamples

    @property
    def estimate(self) -> np.ndarray:
        """The current estimate, shape (d,); a copy (see the notes for how it is chosen)."""
        return self._estimate.copy()

    @property
    def ellipsoid_center(self) -> np.ndarray:
        """``c_k``, the centre of the current ellipsoid (eq. (3)); a copy."""
        return self._center.copy()

    @property
    def radius(self) -> float:
        """A bound on ``||theta* - estimate||_2`` that never grows."""
        return self._radius

    @property
    def shape_matrix(self) -> np.ndarray:
        """``P_k``: the ellipsoid is ``{t : (t - c)^T P^-1 (t - c) <= 1}``; a copy."""
        return self._factor @ self._factor.T

    def parameter_set(self) -> Box:
        """The box of eq. (5): the prior, cut by every ellipsoid's bounding box and every row's strip.

        It holds theta* (given the prior and the noise bound) and never grows.
        """
        return self._box

    def ellipsoid(self) -> Ellipsoid:
        """The current ellipsoid ``E_k`` as an `Ellipsoid` (radius 1, gramian ``P^-1``).

        Raises `InputError` when ``P`` is singular (a degenerate prior side); use
        `parameter_set` then.
        """
        singular_values = np.linalg.svd(self._factor, compute_uv=False)
        if not singular_values[-1] > singular_values[0] * 1e-7:
            raise InputError("the set-membership ellipsoid is degenerate (a flat prior side?): use parameter_set()")
        inverse_factor = np.linalg.inv(self._factor)
        return Ellipsoid(self._center, inverse_factor.T @ inverse_factor, 1.0)

    # ----------------------------------------------------------------- update
    def update(self, regressor, target) -> None:
        """Absorb one sample ``target = regressor @ theta* + v`` with ``|v_i| <= noise_bound_i``.

        Parameters
        ----------
        regressor
            Shape (p, d), or (d,) for one row with a scalar target.
        target
            Shape (p,); for a system, ``x_{n+1} - A0 x_n - B u_n``.

        Raises
        ------
        EmptySetError
            If the sample contradicts the prior and the noise bound (the state is kept).
        """
        E = as_finite_array("regressor", regressor)
        if E.ndim == 1:
            E = E.reshape(1, -1)
        if E.ndim != 2 or E.shape[1] != self._d:
            raise DimensionError(f"regressor must have shape (p, {self._d}), got shape {np.shape(regressor)}")
        y = as_finite_array("target", target)
        if y.ndim == 0:
            y = y.reshape(1)
        check_shape("target", y, (E.shape[0],))
        if self._noise_bound.ndim == 0:
            gammas = np.full(E.shape[0], float(self._noise_bound))
        elif self._noise_bound.shape != y.shape:
            raise DimensionError(
                f"noise_bound has shape {self._noise_bound.shape} but the sample has {E.shape[0]} rows (regressor shape {E.shape})"
            )
        else:
            gammas = self._noise_bound
        center, factor = self._center, self._factor
        for phi, target_i, gamma in zip(E, y, gammas):
            center, factor = _absorb_row(center, factor, phi, float(target_i), float(gamma))
        half_widths = np.linalg.norm(factor, axis=1)
        slack = OUTWARD_ROUNDING * (half_widths + np.abs(center)) + np.finfo(float).tiny
        low = np.maximum(self._box.low, center - half_widths - slack)
        high = np.minimum(self._box.high, center + half_widths + slack)
        for phi, target_i, gamma in zip(E, y, gammas):
            if np.any(low > high):
                break
            low, high = _tighten_box(low, high, phi, float(target_i), float(gamma))
        if np.any(low > high):
            raise EmptySetError(
                "the data are inconsistent with the prior box and noise_bound: the feasible parameter set is empty"
            )
        self._box = Box(low, high)
        self._center, self._factor = center, factor
        self._estimate, self._radius = self._best_certified_point()
        self._nsamples += 1

    def _best_certified_point(self) -> tuple[np.ndarray, float]:
        """The candidate point with the smallest certified bound on its distance to theta*.

        Candidates, each with a bound valid for it: the ellipsoid centre projected on
        the box (the ellipsoid's largest semi-axis, as projecting on a convex set that
        holds theta* never moves a point away from theta*; or the box's farthest
        corner), the box centre (its half-diagonal) and the previous estimate (the
        previous radius, or the current box's farthest corner). Ties go to the first.
        """
        box = self._box
        projected = np.clip(self._center, box.low, box.high)
        largest_axis = float(np.linalg.norm(self._factor, 2)) * (1 + OUTWARD_ROUNDING)
        candidates = [
            (min(largest_axis, _farthest_corner_distance(projected, box)), projected),
            (_farthest_corner_distance(box.center, box), box.center),
            (min(self._radius, _farthest_corner_distance(self._estimate, box)), self._estimate),
        ]
        bound, point = min(candidates, key=lambda candidate: candidate[0])
        return point, bound

    def to_dict(self) -> dict:
        """The current state as plain data (for reports)."""
        return {
            "nsamples": self._nsamples,
            "estimate": self._estimate.tolist(),
            "radius": self._radius,
            "parameter_set": self._box.to_dict(),
            "ellipsoid_center": self._center.tolist(),
            "shape_matrix": self.shape_matrix.tolist(),
        }

    def __repr__(self) -> str:
        return f"SetMembershipEstimator(nparams={self._d}, nsamples={self._nsamples}, radius={self._radius:.6g})"


def _absorb_row(center: np.ndarray, factor: np.ndarray, phi: np.ndarray, y: float, gamma: float):
    """One scalar measurement: the dead-zone step of eqs. (3)-(6) in square-root form."""
    v = factor.T @ phi
    g = float(v @ v)
    error = y - float(phi @ center)
    gamma = gamma + MEASUREMENT_ROUNDING * (abs(y) + float(np.abs(phi) @ np.abs(center)) + gamma)
    if abs(error) <= gamma or g == 0.0:
        if abs(error) > gamma * (1 + INCONSISTENCY_TOLERANCE) + INCONSISTENCY_TOLERANCE * abs(y):
            # g == 0: the measurement does not depend on the free directions and misses the strip.
            raise EmptySetError(
                "the data are inconsistent with the prior box and noise_bound: the feasible parameter set is empty"
            )
        return center, factor
    excess = abs(error) - gamma
    shrink = 1.0 - excess**2 / g
    if shrink < -INCONSISTENCY_TOLERANCE:
        raise EmptySetError(
            "the data are inconsistent with the prior box and noise_bound: the feasible parameter set is empty "
            f"(prediction error {error:.6g} exceeds the noise bound {gamma:.6g} by more than the ellipsoid allows)"
        )
    if shrink < MIN_SHRINK:
        return center, factor
    Lv = factor @ v
    new_center = center + (np.sign(error) * excess / g) * Lv
    new_factor = np.sqrt(shrink) * (factor - ((1.0 - np.sqrt(gamma / abs(error))) / g) * np.outer(Lv, v))
    return new_center, new_factor


def _tighten_box(low: np.ndarray, high: np.ndarray, phi: np.ndarray, y: float, gamma: float):
    """Shrink the box to the strip ``|y - phi^T t| <= gamma`` by interval propagation.

    For each j, ``phi_j t_j = (phi^T t) - sum_{i != j} phi_i t_i`` lies in
    ``[y - gamma - sum_{i != j} max_i, y + gamma - sum_{i != j} min_i]``, where min_i and
    max_i bound ``phi_i t_i`` over the box. Every bound is rounded outward; the result
    may be empty (``low > high`` somewhere), which proves the data inconsistent.
    """
    magnitude = np.maximum(np.abs(low), np.abs(high))
    gamma = gamma + MEASUREMENT_ROUNDING * (abs(y) + float(np.abs(phi) @ magnitude) + gamma)
    term_low = np.minimum(phi * low, phi * high)
    term_high = np.maximum(phi * low, phi * high)
    slack = MEASUREMENT_ROUNDING * (abs(y) + gamma + float(np.sum(np.abs(term_low) + np.abs(term_high))))
    others_high = np.sum(term_high) - term_high
    others_low = np.sum(term_low) - term_low
    t_low = y - gamma - others_high - slack
    t_high = y + gamma - others_low + slack
    active = phi != 0
    with np.errstate(divide="ignore", invalid="ignore"):
        bound_a = np.where(active, t_low / np.where(active, phi, 1.0), -np.inf)
        bound_b = np.where(active, t_high / np.where(active, phi, 1.0), np.inf)
    with np.errstate(over="ignore", invalid="ignore"):
        new_low = np.where(phi >= 0, bound_a, bound_b)
        new_high = np.where(phi >= 0, bound_b, bound_a)
        new_low = new_low - MEASUREMENT_ROUNDING * np.abs(new_low)
        new_high = new_high + MEASUREMENT_ROUNDING * np.abs(new_high)
    # an infinite bound (phi_j = 0, or so small that the quotient overflows) carries no information
    new_low = np.where(np.isfinite(new_low), new_low, low)
    new_high = np.where(np.isfinite(new_high), new_high, high)
    return np.maximum(low, new_low), np.minimum(high, new_high)


def _farthest_corner_distance(point: np.ndarray, box: Box) -> float:
    """``max_{t in box} ||t - point||_2`` (attained at a corner), rounded outward."""
    reach = np.maximum(np.abs(point - box.low), np.abs(box.high - point))
    return float(np.linalg.norm(reach)) * (1 + OUTWARD_ROUNDING)
