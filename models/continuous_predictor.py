"""The paper's continuous-time interval predictor (eq. (9), corrected), kept for fidelity.

It is integrated by forward Euler and keeps inclusion only under a condition on the
time step (see `predict_tube_continuous`); the library's planners use the
discrete-time `predict_tube`, which is sound for every time step.
"""

from __future__ import annotations

import numpy as np

from .errors import DimensionError
from .polytope import parameter_vertices
from .prediction import Tube, _check_no_overflow, interval_matvec
from .sets import Box
from .validation import as_finite_array, as_positive_scalar, check_dimension, check_instance, check_shape

__all__ = ["predict_tube_continuous", "euler_keeps_inclusion"]


def euler_keeps_inclusion(nominal, dt: float) -> bool:
    """The sufficient condition ``I + dt A_N >= 0`` (elementwise) of the Euler predictor.

    Parameters
    ----------
    nominal : array_like
        The continuous-time nominal matrix ``A_N``, shape (p, p), in 1/s.
    dt : float
        The Euler time step in seconds, > 0.

    Returns
    -------
    bool
        Whether every entry of ``I + dt A_N`` is >= 0.

    Notes
    -----
    The condition implies that ``A_N`` is Metzler (its off-diagonal entries are
    ``dt A_N[i, j] >= 0``) and bounds the step: ``dt <= 1 / max_i(-A_N[i, i])``. It is
    sufficient (not necessary) for the forward-Euler version of eq. (9), as corrected
    in DESIGN's errata, to keep inclusion.
    """
    nominal = as_finite_array("nominal", nominal, ndim=2)
    check_shape("nominal", nominal, (nominal.shape[0], nominal.shape[0]))
    dt = as_positive_scalar("dt", dt)
    return bool(np.all(np.eye(nominal.shape[0]) + dt * nominal >= 0))


def predict_tube_continuous(A, phi, B, *, D=None, w: Box, x0: Box, controls, dt: float, parameters) -> Tube:
    """Euler integration of the corrected continuous-time predictor of eq. (9).

    Parameters
    ----------
    A, phi, B, D
        The continuous-time model ``dx/dt = (A + sum_i theta_i phi_i) x + B u + D w``
        (eq. (1)); shapes (p, p), (d, p, p), (p, q), (p, r); D defaults to the identity.
    w
        `Box` of disturbances, dimension r.
    x0
        `Box` of initial states, dimension p.
    controls
        Array (H, q), held constant over each step.
    dt
        The Euler step, > 0.
    parameters
        `Box`, `Ellipsoid` or vertex array (k, d), see `parameter_vertices`.

    Returns
    -------
    Tube
        Shape (H+1, p); ``guaranteed`` is `euler_keeps_inclusion` of ``A_N`` and dt.
        When it is False the tube may miss trajectories or even cross (lower > upper).

    Notes
    -----
    With ``A_N = A(mean of the vertices)``, ``X_k = A(v_k) - A_N``, ``X+ = max_k X_k+`` and
    ``X- = max_k X_k-`` (elementwise; DESIGN errata, tighter than summing eq. (8)'s
    2^d terms), the corrected eq. (9) is

    ``dx_lo = A_N x_lo - X+ x_lo^- - X- x_hi^+ + B u + D+ w_lo - D- w_hi``,
    ``dx_hi = A_N x_hi + X+ x_hi^+ + X- x_lo^- + B u + D+ w_hi - D- w_lo``

    (as printed, eq. (9) loses the positive perturbations and ignores D). One Euler step
    is ``x_lo+ = (I + dt A_N) x_lo + dt (...)``. It bounds the Euler-discretised plant
    ``x+ = x + dt (A(theta) x + B u + D w)`` (the model of `from_continuous`) whenever
    ``I + dt A_N >= 0``: then ``(I + dt A_N) x >= (I + dt A_N) x_lo`` for ``x >= x_lo``,
    and ``(A(theta) - A_N) x >= -X+ x_lo^- - X- x_hi^+``. The condition is sufficient,
    not necessary; for larger dt the predictor can lose trajectories (on the reference
    code, 90 of 197 random runs at dt = 0.4). Kept for fidelity to the paper, it is
    computed in plain round-to-nearest (no outward rounding, unlike `predict_tube`).
    """
    dt = as_positive_scalar("dt", dt)
    A = as_finite_array("A", A, ndim=2)
    p = A.shape[0]
    check_shape("A", A, (p, p))
    phi = as_finite_array("phi", phi, ndim=3)
    check_shape("phi", phi, (None, p, p))
    B = as_finite_array("B", B, ndim=2)
    check_shape("B", B, (p, None))
    D = np.eye(p) if D is None else as_finite_array("D", D, ndim=2)
    check_shape("D", D, (p, None))
    check_instance("w", w, Box)
    check_instance("x0", x0, Box)
    check_dimension("w", w.dim, D.shape[1], f"columns of D, shape {D.shape}")
    check_dimension("x0", x0.dim, p, f"A has shape {A.shape}")
    u = as_finite_array("controls", controls, ndim=2)
    check_shape("controls", u, (None, B.shape[1]))
    vertices = parameter_vertices(parameters)
    if vertices.shape[1] != phi.shape[0]:
        raise DimensionError(
            f"parameters must have dimension {phi.shape[0]} (phi has shape {phi.shape}), got vertices of shape {vertices.shape}"
        )
    nominal = A + np.tensordot(vertices.mean(axis=0), phi, axes=1)
    deviations = A + np.tensordot(vertices, phi, axes=1) - nominal
    X_pos = np.max(np.maximum(deviations, 0.0), axis=0)
    X_neg = np.max(np.maximum(-deviations, 0.0), axis=0)
    w_lo, w_hi = interval_matvec(D, w.low, w.high)

    lower = np.empty((u.shape[0] + 1, p))
    upper = np.empty_like(lower)
    lower[0], upper[0] = x0.low, x0.high
    with np.errstate(over="ignore", invalid="ignore"):
        for n in range(u.shape[0]):
            x_lo, x_hi = lower[n], upper[n]
            lo_neg, hi_pos = np.maximum(-x_lo, 0.0), np.maximum(x_hi, 0.0)
            drift = B @ u[n]
            dx_lo = nominal @ x_lo - X_pos @ lo_neg - X_neg @ hi_pos + drift + w_lo
            dx_hi = nominal @ x_hi + X_pos @ hi_pos + X_neg @ lo_neg + drift + w_hi
            lower[n + 1], upper[n + 1] = x_lo + dt * dx_lo, x_hi + dt * dx_hi
    _check_no_overflow(lower, upper)
    guaranteed = euler_keeps_inclusion(nominal, dt)
    condition = "holds" if guaranteed else "fails: inclusion not guaranteed"
    return Tube(
        lower,
        upper,
        guaranteed=guaranteed,
        note=f"continuous-time predictor (eq. (9) corrected), Euler dt={dt:g}; I + dt A_N >= 0 {condition}",
    )
