"""Linear systems whose state matrix is affine in uncertain parameters."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from .errors import DimensionError, InputError
from .sets import Box
from .validation import (
    as_choice,
    as_finite_array,
    as_points,
    as_positive_scalar,
    check_dimension,
    check_instance,
    check_shape,
    frozen_copy,
)

__all__ = ["UncertainLinearSystem"]


@dataclass(frozen=True, eq=False, init=False)
class UncertainLinearSystem:
    """The discrete-time plant ``x+ = A(theta) x + B u + D w``.

    Parameters
    ----------
    A0 : array_like
        Nominal state matrix, shape (p, p).
    phi : array_like
        Structure matrices, shape (d, p, p): ``A(theta) = A0 + sum_i theta[i] phi[i]``
        (eq. (2), Assumption 1).
    B : array_like
        Input matrix, shape (p, q); a vector of shape (p,) is one input column.
    D : array_like, optional
        Disturbance input matrix, shape (p, r); defaults to the identity (r = p). Not a
        feedthrough.
    w : Box
        Box of admissible disturbances, dimension r (Assumption 2).
    theta : Box
        Prior parameter box, dimension d: the set D of Assumption 1.

    Raises
    ------
    DimensionError
        If a matrix or box has the wrong shape or dimension (the message names both).
    NonFiniteError
        If a matrix contains NaN or inf.
    InputError
        If ``w`` or ``theta`` is not a `Box`.

    Notes
    -----
    An immutable value: the matrices are stored as read-only float64 copies, and ``D``
    is always an array (the identity when not given).
    """

    A0: np.ndarray
    phi: np.ndarray
    B: np.ndarray
    D: np.ndarray
    w: Box
    theta: Box

    def __init__(
        self, A0: ArrayLike, phi: ArrayLike, B: ArrayLike, *, D: ArrayLike | None = None, w: Box, theta: Box
    ) -> None:
        A0_ = as_finite_array("A0", A0, ndim=2)
        p = A0_.shape[0]
        check_shape("A0", A0_, (p, p))
        if p == 0:
            raise DimensionError("A0 needs at least one state, got shape (0, 0)")
        phi_ = as_finite_array("phi", phi, ndim=3)
        check_shape("phi", phi_, (None, p, p))
        B_ = as_finite_array("B", B)
        if B_.ndim == 1:
            B_ = B_.reshape(p, 1) if B_.shape == (p,) else B_
        check_shape("B", B_, (p, None))
        D_ = np.eye(p) if D is None else as_finite_array("D", D, ndim=2)
        check_shape("D", D_, (p, None))
        check_instance("w", w, Box)
        check_instance("theta", theta, Box)
        check_dimension("w", w.dim, D_.shape[1], f"columns of D, shape {D_.shape}")
        check_dimension("theta", theta.dim, phi_.shape[0], f"phi has shape {phi_.shape}")
        for name, value in (("A0", A0_), ("phi", phi_), ("B", B_), ("D", D_)):
            object.__setattr__(self, name, frozen_copy(value))
        object.__setattr__(self, "w", w)
        object.__setattr__(self, "theta", theta)

    # ----------------------------------------------------------------- sizes
    @property
    def nstates(self) -> int:
        """p, the state dimension."""
        return self.A0.shape[0]

    @property
    def ninputs(self) -> int:
        """q, the control dimension."""
        return self.B.shape[1]

    @property
    def nparams(self) -> int:
        """d, the number of uncertain parameters."""
        return self.phi.shape[0]

    @property
    def ndisturbances(self) -> int:
        """r, the disturbance dimension (columns of D)."""
        return self.D.shape[1]

    # ------------------------------------------------------------- dynamics
    def A(self, theta: ArrayLike) -> np.ndarray:
        """The state matrix ``A(theta) = A0 + sum_i theta[i] phi[i]`` (eq. (2)).

        Parameters
        ----------
        theta : array_like
            One parameter vector, shape (d,), or k of them, shape (k, d).

        Returns
        -------
        numpy.ndarray
            Shape (p, p), or (k, p, p) for k parameter vectors.

        Raises
        ------
        DimensionError
            If ``theta`` is not of shape (d,) or (k, d).
        """
        t = as_points("theta", theta, self.nparams)
        return self.A0 + np.tensordot(t, self.phi, axes=([-1], [0]))

    def step(self, x: ArrayLike, u: ArrayLike, theta: ArrayLike, w: ArrayLike | None = None) -> np.ndarray:
        """One transition ``x+ = A(theta) x + B u + D w``.

        Parameters
        ----------
        x : array_like
            The state, shape (p,).
        u : array_like
            The control, shape (q,).
        theta : array_like
            The parameters, shape (d,) (any vector: not checked against the prior box).
        w : array_like, optional
            The disturbance, shape (r,); defaults to 0 (not checked against ``w``'s box).

        Returns
        -------
        numpy.ndarray
            The next state, shape (p,).

        Raises
        ------
        DimensionError
            If an argument has the wrong shape.
        NonFiniteError
            If an argument contains NaN or inf.
        """
        x = as_finite_array("x", x, (self.nstates,))
        u = as_finite_array("u", u, (self.ninputs,))
        w = np.zeros(self.ndisturbances) if w is None else as_finite_array("w", w, (self.ndisturbances,))
        return self.A(theta) @ x + self.B @ u + self.D @ w

    def regressor(self, x: ArrayLike) -> np.ndarray:
        """The p x d matrix whose column i is ``phi[i] @ x``, so ``A(theta) x = A0 x + regressor(x) theta``.

        Parameters
        ----------
        x : array_like
            One state, shape (p,), or N states, shape (N, p).

        Returns
        -------
        numpy.ndarray
            Shape (p, d), or (N, p, d): the regressors ``E_n`` of the least-squares fit
            (``confidence_ellipsoid``) and of the set-membership estimator (eqs. (3)-(6)).

        Raises
        ------
        DimensionError
            If ``x`` is not of shape (p,) or (N, p).
        """
        x = as_points("x", x, self.nstates, batch="N")
        return np.einsum("ipq,...q->...pi", self.phi, x)

    # --------------------------------------------------------- constructors
    @classmethod
    def from_continuous(
        cls, A: ArrayLike, phi: ArrayLike, B: ArrayLike, *, D: ArrayLike | None = None, w: Box, theta: Box, dt: float
    ) -> UncertainLinearSystem:
        """Discretise eq. (1), ``dx/dt = A(theta) x + B u + D w``, by forward Euler.

        Parameters
        ----------
        A : array_like
            Continuous-time nominal state matrix, shape (p, p), in 1/s.
        phi : array_like
            Continuous-time structure matrices, shape (d, p, p), in 1/s.
        B : array_like
            Continuous-time input matrix, shape (p, q).
        D : array_like, optional
            Continuous-time disturbance input matrix, shape (p, r); defaults to the identity.
        w : Box
            Box of admissible disturbances (rates), dimension r (Assumption 2).
        theta : Box
            Prior parameter box, dimension d (Assumption 1).
        dt : float
            Time step in seconds, > 0.

        Returns
        -------
        UncertainLinearSystem
            ``A0 = I + dt A``, ``phi = dt phi``, ``B = dt B``, ``D = dt D``; ``w`` and
            ``theta`` unchanged.

        Raises
        ------
        InputError
            If ``dt`` is not > 0.
        DimensionError, NonFiniteError
            For a malformed matrix (see the class).

        Notes
        -----
        ``x+ = (I + dt A0 + sum_i theta_i dt phi_i) x + dt B u + dt D w``. Forward Euler
        keeps the model affine in theta (an exact discretisation would not), and the
        simulated worlds step with the same scheme, so the discrete model is exact for them.
        """
        dt = as_positive_scalar("dt", dt)
        A = as_finite_array("A", A, ndim=2)
        p = A.shape[0]
        check_shape("A", A, (p, p))
        phi = as_finite_array("phi", phi, ndim=3)
        B = as_finite_array("B", B)
        Dm = np.eye(p) if D is None else as_finite_array("D", D, ndim=2)
        return cls(np.eye(p) + dt * A, dt * phi, dt * B, D=dt * Dm, w=w, theta=theta)

    @classmethod
    def from_statespace(
        cls,
        sys: Any,
        phi: ArrayLike,
        *,
        D: ArrayLike | None = None,
        w: Box,
        theta: Box,
        dt: float | None = None,
        phi_time: Literal["continuous", "discrete"] | None = None,
    ) -> UncertainLinearSystem:
        """Build from a python-control ``StateSpace``, stating the time base of ``phi``.

        Parameters
        ----------
        sys : control.StateSpace
            Its ``A`` is the nominal matrix and its ``B`` the input matrix; its ``C`` and
            its ``D`` (python-control's feedthrough) are ignored. Continuous-time
            (``sys.dt == 0``) or discrete-time (``sys.dt > 0``, or ``True`` for an
            unspecified sampling time); the unspecified timebase ``sys.dt = None`` is
            refused, since it could be either.
        phi : array_like
            Structure matrices, shape (d, p, p), in the time base named by ``phi_time``.
        D : array_like, optional
            OUR disturbance input matrix, shape (p, r), in the same time base as ``sys``
            (unrelated to python-control's feedthrough ``sys.D``); defaults to the identity.
        w : Box
            Box of admissible disturbances, dimension r (Assumption 2).
        theta : Box
            Prior parameter box, dimension d (Assumption 1).
        dt : float, optional
            Time step in seconds, > 0. Required for a continuous-time ``sys`` (forward
            Euler, see `from_continuous`); for a discrete-time one it may only repeat
            ``sys.dt`` (any value when ``sys.dt`` is True).
        phi_time : {"continuous", "discrete"}, optional
            The time base of ``phi``. Required when ``sys`` is discrete-time, where only
            ``"discrete"`` is accepted: ``A(theta) = sys.A + sum_i theta_i phi_i``. For a
            continuous-time ``sys``, None or ``"continuous"``.

        Returns
        -------
        UncertainLinearSystem
            The discrete-time model.

        Raises
        ------
        InputError
            If ``sys`` is not a StateSpace or has the unspecified timebase, if ``dt`` is
            missing for a continuous ``sys`` or contradicts a discrete one, if
            ``phi_time`` is missing for a discrete ``sys``, not one of the choices, or
            names a time base that ``sys`` does not have.

        Notes
        -----
        A continuous-time ``phi`` is never added to a discrete-time ``sys.A``: that sum
        (the old silent behaviour) mixes a rate with a one-step matrix. Nor is such a
        ``phi`` discretised here, because that is consistent only with the method that
        made ``sys.A`` (e.g. forward Euler gives ``dt phi``; zero-order hold
        ``expm(dt A(theta))`` is not affine in theta at all), which a StateSpace does
        not record. Give the continuous-time StateSpace with ``dt=`` instead (forward
        Euler for ``A``, ``B``, ``D`` and ``phi`` together, as the simulated worlds
        step), or discretise ``phi`` consistently with ``sys`` and pass
        ``phi_time="discrete"``. Likewise a discrete-time ``phi`` with a continuous
        ``sys`` is refused.
        """
        from control import StateSpace  # imported here: only a caller who holds a StateSpace pays for it

        if not isinstance(sys, StateSpace):
            raise InputError(f"sys must be a python-control StateSpace, got {type(sys).__name__}")
        phi_time = as_choice("phi_time", phi_time, ("continuous", "discrete", None))
        sys_dt = sys.dt
        if sys_dt is None:  # python-control's "unspecified timebase": continuous and discrete at once
            raise InputError(
                "sys has an unspecified timebase (dt=None): build it with dt=0 (continuous) or its sampling time"
            )
        is_continuous = sys_dt is not True and float(sys_dt) == 0.0
        if is_continuous:
            if phi_time == "discrete":
                raise InputError(
                    "phi_time='discrete' but sys is continuous-time: give phi in continuous time "
                    "(phi_time='continuous'; forward Euler discretises A, B, D and phi together), "
                    "or a discrete-time sys"
                )
            if dt is None:
                raise InputError("sys is continuous-time: give dt= to discretise it")
            return cls.from_continuous(np.asarray(sys.A), phi, np.asarray(sys.B), D=D, w=w, theta=theta, dt=dt)
        if phi_time is None:
            raise InputError(
                f"phi_time is required when sys is discrete-time (dt={sys_dt}): pass phi_time='discrete' "
                "if phi is in sys's time base (A(theta) = sys.A + sum_i theta_i phi_i)"
            )
        if phi_time == "continuous":
            raise InputError(
                f"phi_time='continuous' with a discrete-time sys (dt={sys_dt}): a continuous-time phi cannot be "
                "added to sys.A, and discretising it consistently needs the method that made sys.A; "
                "give the continuous-time StateSpace with dt= (forward Euler for A, B, D and phi together), "
                "or discretise phi like sys and pass phi_time='discrete'"
            )
        if dt is not None:
            dt = as_positive_scalar("dt", dt)
        if dt is not None and sys_dt is not True and not np.isclose(float(sys_dt), dt):
            raise InputError(f"sys is discrete-time with dt={sys_dt}; dt={dt} contradicts it")
        return cls(np.asarray(sys.A), phi, np.asarray(sys.B), D=D, w=w, theta=theta)

    def to_dict(self) -> dict:
        """The system as plain data (lists, JSON-serialisable).

        Returns
        -------
        dict
            ``A0``, ``phi``, ``B``, ``D`` as nested lists, ``w`` and ``theta`` as
            `Box.to_dict`.
        """
        return {
            "A0": self.A0.tolist(),
            "phi": self.phi.tolist(),
            "B": self.B.tolist(),
            "D": self.D.tolist(),
            "w": self.w.to_dict(),
            "theta": self.theta.to_dict(),
        }

    def __repr__(self) -> str:
        return (
            f"UncertainLinearSystem(nstates={self.nstates}, ninputs={self.ninputs}, "
            f"nparams={self.nparams}, ndisturbances={self.ndisturbances})"
        )
