"""Low-level controllers: what a discrete planner action does between two decisions.

The paper (Section III-B) discretises the control space by letting each high-level
action ``a`` select a low-level controller. Two kinds are provided:

* `OpenLoop(u)`: the constant control u;
* `LinearFeedback(K, x_ref, u_ff, u_low, u_high)`: ``u = sat(K (x_ref - x) + u_ff)``,
  saturated elementwise to ``[u_low, u_high]`` (no saturation by default).

Without saturation, feedback on the plant ``x+ = A(theta) x + B u + D w`` gives the
closed loop ``x+ = (A(theta) - B K) x + B (K x_ref + u_ff) + D w``: an
`UncertainLinearSystem` with ``A0 - B K`` and the same ``phi``, driven by the constant
input ``K x_ref + u_ff`` (`LinearFeedback.closed_loop`). Saturation is handled by the
interval model (see `minimaxplan.planners.interval_model`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..models.errors import DimensionError, InputError
from ..models.system import UncertainLinearSystem
from ..models.validation import as_finite_array, check_instance, check_shape, frozen_copy

__all__ = ["OpenLoop", "LinearFeedback", "ControllerBank"]


@dataclass(frozen=True, eq=False, init=False)
class OpenLoop:
    """The constant control ``u``, whatever the state (an open-loop low-level controller).

    Parameters
    ----------
    u : array_like, shape (q,)
        The control input held between two decisions, in the plant's input units
        (e.g. an acceleration in m/s^2 for the robot scenario). Copied and stored
        read-only.

    Raises
    ------
    DimensionError
        If ``u`` is not one-dimensional.
    NonFiniteError
        If ``u`` has NaN or infinite entries.

    Notes
    -----
    One high-level action of the paper's discretised control space (Section III-B):
    the action selects this controller, which applies ``u`` at every sub-step of
    ``x+ = A(theta) x + B u + D w`` (eq. (1), discretised). As a `ControllerBank` row
    it has ``K_a = 0``, ``c_a = u`` and no saturation.
    """

    u: np.ndarray

    def __init__(self, u: ArrayLike) -> None:
        object.__setattr__(self, "u", frozen_copy(as_finite_array("u", u, ndim=1)))

    @property
    def ninputs(self) -> int:
        """The number of plant inputs q (the length of ``u``)."""
        return self.u.shape[0]

    def control(self, x) -> np.ndarray:
        """The control at one or several states: ``u`` broadcast over the leading dimensions of ``x``.

        Parameters
        ----------
        x : array_like, shape (..., p)
            Plant state(s); only the leading dimensions are used.

        Returns
        -------
        ndarray, shape (..., q)
            A writable copy of ``u`` per state.
        """
        x = np.asarray(x, dtype=float)
        return np.broadcast_to(self.u, x.shape[:-1] + self.u.shape).copy()

    def to_dict(self) -> dict:
        """A JSON-serialisable description: ``{"kind": "open_loop", "u": [...]}``.

        Returns
        -------
        dict
            The controller kind and ``u`` as a list of floats.
        """
        return {"kind": "open_loop", "u": self.u.tolist()}


@dataclass(frozen=True, eq=False, init=False)
class LinearFeedback:
    """State feedback ``u = clip(K (x_ref - x) + u_ff, u_low, u_high)``.

    Parameters
    ----------
    K : array_like, shape (q, p)
        Feedback gain, in input units per state unit.
    x_ref : array_like, shape (p,)
        Reference state the controller regulates to, in the plant's state units.
    u_ff : array_like, shape (q,), optional
        Feedforward control, in input units; default 0.
    u_low, u_high : array_like, shape (q,), or float, optional
        Saturation limits, in input units (scalars broadcast to every input); None
        means no limit on that side. ``u_low <= u_high``.

    Raises
    ------
    DimensionError
        If ``K`` is not two-dimensional or another array's shape does not match it.
    NonFiniteError
        If an array has NaN or infinite entries (use None for "no limit").
    InputError
        If ``u_low > u_high`` for some input.

    Notes
    -----
    A low-level controller of the paper's discretised control space (Section III-B).
    Unsaturated, it turns eq. (1) into the closed loop
    ``x+ = (A(theta) - B K) x + B (K x_ref + u_ff) + D w`` (`closed_loop`), with the
    same parameter structure (2); saturation is bounded by `IntervalModel`.
    """

    K: np.ndarray
    x_ref: np.ndarray
    u_ff: np.ndarray
    u_low: np.ndarray
    u_high: np.ndarray

    def __init__(
        self,
        K: ArrayLike,
        x_ref: ArrayLike,
        u_ff: ArrayLike | None = None,
        u_low: ArrayLike | float | None = None,
        u_high: ArrayLike | float | None = None,
    ) -> None:
        gain = as_finite_array("K", K, ndim=2)
        q, p = gain.shape
        reference = as_finite_array("x_ref", x_ref, (p,))
        feedforward = np.zeros(q) if u_ff is None else as_finite_array("u_ff", u_ff, (q,))
        limits: dict[str, np.ndarray] = {}
        for name, default, value in (("u_low", -np.inf, u_low), ("u_high", np.inf, u_high)):
            if value is None:
                limits[name] = np.full(q, default)
                continue
            arr = as_finite_array(name, value)
            if arr.ndim == 0:
                arr = np.full(q, float(arr))
            check_shape(name, arr, (q,))
            limits[name] = arr
        if np.any(limits["u_low"] > limits["u_high"]):
            raise InputError(f"u_low must be <= u_high, got {limits['u_low'].tolist()} and {limits['u_high'].tolist()}")
        for name, array in (("K", gain), ("x_ref", reference), ("u_ff", feedforward), *limits.items()):
            object.__setattr__(self, name, frozen_copy(array))

    @property
    def ninputs(self) -> int:
        """The number of plant inputs q (rows of ``K``)."""
        return self.K.shape[0]

    @property
    def nstates(self) -> int:
        """The number of plant states p (columns of ``K``)."""
        return self.K.shape[1]

    @property
    def saturates(self) -> bool:
        """Whether any saturation limit is finite."""
        return bool(np.any(np.isfinite(self.u_low)) or np.any(np.isfinite(self.u_high)))

    @property
    def feedforward(self) -> np.ndarray:
        """``K x_ref + u_ff``, the constant input of the closed loop."""
        return self.K @ self.x_ref + self.u_ff

    def control(self, x) -> np.ndarray:
        """The saturated control ``clip(K (x_ref - x) + u_ff, u_low, u_high)`` at one or several states.

        Parameters
        ----------
        x : array_like, shape (..., p)
            Plant state(s), in the plant's state units.

        Returns
        -------
        ndarray, shape (..., q)
            The control input(s), in input units.
        """
        x = np.asarray(x, dtype=float)
        return np.clip((self.x_ref - x) @ self.K.T + self.u_ff, self.u_low, self.u_high)

    def closed_loop(self, system: UncertainLinearSystem) -> UncertainLinearSystem:
        """The unsaturated closed loop ``x+ = (A(theta) - B K) x + B v + D w`` with ``v = feedforward``.

        Exact for every state at which saturation is inactive.

        Parameters
        ----------
        system : UncertainLinearSystem
            The plant, with ``nstates == self.nstates`` and ``ninputs == self.ninputs``.

        Returns
        -------
        UncertainLinearSystem
            The closed loop: ``A0 - B K`` and the plant's ``phi`` (so the parameter
            structure of eq. (2) is unchanged), ``B``, ``D``, ``w`` and ``theta``; drive
            it with the constant input `feedforward`.

        Raises
        ------
        InputError
            If ``system`` is not an `UncertainLinearSystem`.
        DimensionError
            If ``K`` does not have shape (system.ninputs, system.nstates).
        """
        check_instance("system", system, UncertainLinearSystem)
        if self.K.shape != (system.ninputs, system.nstates):
            raise DimensionError(
                f"K must have shape ({system.ninputs}, {system.nstates}) for this system, got shape {self.K.shape}"
            )
        return UncertainLinearSystem(
            system.A0 - system.B @ self.K, system.phi, system.B, D=system.D, w=system.w, theta=system.theta
        )

    def to_dict(self) -> dict:
        """A JSON-serialisable description of the controller.

        Returns
        -------
        dict
            ``kind`` (``"linear_feedback"``), ``K``, ``x_ref``, ``u_ff`` as nested lists
            and ``u_low``, ``u_high`` per input, None where unlimited.
        """
        return {
            "kind": "linear_feedback",
            "K": self.K.tolist(),
            "x_ref": self.x_ref.tolist(),
            "u_ff": self.u_ff.tolist(),
            "u_low": [None if np.isinf(v) else float(v) for v in self.u_low],
            "u_high": [None if np.isinf(v) else float(v) for v in self.u_high],
        }


class ControllerBank:
    """A sequence of controllers as stacked arrays, for batched stepping of all actions.

    Every controller is written as ``u = clip(c_a - K_a x, low_a, high_a)``:
    `OpenLoop` has ``K_a = 0``, ``c_a = u`` and no limits; `LinearFeedback` has
    ``c_a = K x_ref + u_ff``.

    Parameters
    ----------
    controllers : sequence of OpenLoop or LinearFeedback
        One controller per action, non-empty.
    nstates : int
        The number of plant states p.
    ninputs : int
        The number of plant inputs q.

    Attributes
    ----------
    gains : ndarray (a, q, p)
    offsets : ndarray (a, q)
    low, high : ndarray (a, q), with -inf / inf where unlimited
    saturating : bool
        Whether any controller has a finite limit.
    """

    def __init__(self, controllers, nstates: int, ninputs: int) -> None:
        try:
            controllers = tuple(controllers)
        except TypeError:
            raise InputError(f"controllers must be a sequence, got {type(controllers).__name__}") from None
        if not controllers:
            raise InputError("controllers must be a non-empty sequence (one controller per action)")
        n = len(controllers)
        self.controllers = controllers
        self.gains = np.zeros((n, ninputs, nstates))
        self.offsets = np.zeros((n, ninputs))
        self.low = np.full((n, ninputs), -np.inf)
        self.high = np.full((n, ninputs), np.inf)
        for a, controller in enumerate(controllers):
            if isinstance(controller, OpenLoop):
                if controller.u.shape != (ninputs,):
                    raise DimensionError(
                        f"controllers[{a}].u must have shape ({ninputs},), got shape {controller.u.shape}"
                    )
                self.offsets[a] = controller.u
            elif isinstance(controller, LinearFeedback):
                if controller.K.shape != (ninputs, nstates):
                    raise DimensionError(
                        f"controllers[{a}].K must have shape ({ninputs}, {nstates}), got shape {controller.K.shape}"
                    )
                self.gains[a] = controller.K
                self.offsets[a] = controller.feedforward
                self.low[a] = controller.u_low
                self.high[a] = controller.u_high
            else:  # neither kind: raises InputError naming the type given
                check_instance(
                    f"controllers[{a}]", controller, (OpenLoop, LinearFeedback), "OpenLoop or LinearFeedback"
                )
        self.saturating = bool(np.any(np.isfinite(self.low)) or np.any(np.isfinite(self.high)))
        self.has_feedback = bool(np.any(self.gains != 0))
        for arr in (self.gains, self.offsets, self.low, self.high):
            arr.setflags(write=False)

    def __len__(self) -> int:
        return len(self.controllers)

    def controls(self, x: np.ndarray, index=slice(None)) -> np.ndarray:
        """The controls of the selected controllers at states x (a, p) -> (a, q) (raw arrays).

        Parameters
        ----------
        x : ndarray, shape (a, p)
            One plant state per selected controller.
        index : slice or array of int, optional
            The controllers to apply; default all.
        """
        v = self.offsets[index] - np.einsum("aqp,ap->aq", self.gains[index], x)
        return np.clip(v, self.low[index], self.high[index])
