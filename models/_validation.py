"""Argument checks shared by every public entry point (private module)."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .errors import DimensionError, InputError, NonFiniteError

__all__ = ["as_finite_array", "check_shape", "frozen_copy", "as_positive_scalar"]


def _shape_text(shape: Sequence[int | None]) -> str:
    return "(" + ", ".join("*" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"


def check_shape(name: str, array: np.ndarray, shape: Sequence[int | None]) -> None:
    """Raise `DimensionError` unless ``array.shape`` matches ``shape`` (None = any)."""
    if array.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, array.shape)):
        raise DimensionError(
            f"{name} must have shape {_shape_text(shape)}, got shape {array.shape}"
        )


def as_finite_array(
    name: str, value, shape: Sequence[int | None] | None = None, *, ndim: int | None = None
) -> np.ndarray:
    """Convert ``value`` to a float64 array, checking its shape and finiteness.

    Parameters
    ----------
    name
        The argument's name, used in error messages.
    value
        Anything `numpy.asarray` accepts.
    shape
        Expected shape; ``None`` entries match any length.
    ndim
        Expected number of dimensions, when the lengths are free.
    """
    try:
        raw = np.asarray(value)
        if np.iscomplexobj(raw):  # a float cast would silently drop the imaginary part
            raise InputError(f"{name} must be a real numeric array, got complex values")
        array = raw.astype(float, copy=False)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{name} must be a real numeric array: {exc}") from None
    if shape is not None:
        check_shape(name, array, shape)
    elif ndim is not None and array.ndim != ndim:
        raise DimensionError(f"{name} must be {ndim}-dimensional, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise NonFiniteError(f"{name} contains NaN or infinite entries")
    return array


def frozen_copy(array: np.ndarray) -> np.ndarray:
    """A read-only copy, so that immutable values never alias a caller's array."""
    out = np.array(array, dtype=float, copy=True)
    out.setflags(write=False)
    return out


def as_positive_scalar(name: str, value, *, allow_zero: bool = False) -> float:
    """Check that ``value`` is a finite real scalar > 0 (or >= 0)."""
    if np.iscomplexobj(value) or isinstance(value, (bool, np.bool_)):
        raise InputError(f"{name} must be a real scalar, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a real scalar, got {value!r}") from None
    if not np.isfinite(x):
        raise NonFiniteError(f"{name} must be finite, got {x}")
    if x < 0 or (x == 0 and not allow_zero):
        raise InputError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {x}")
    return x
