"""Argument validators shared by every subpackage of minimaxplan.

An internal module: the subpackages (``models``, ``verify``, ``planners``,
``scenarios``, ``analysis``) check their public entry points with these functions so
that every check raises the same typed error (`minimaxplan.models.errors`) with the
same wording, naming the argument and, for shapes, both shapes. It is NOT part of the
public API contract of DESIGN.md: names here may change with the library.

Validators either return the checked, converted value (``as_*``) or return nothing and
raise on a bad value (``check_*``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .errors import DimensionError, InputError, NonFiniteError

__all__ = [
    "as_finite_array",
    "as_positive_scalar",
    "as_real_scalar",
    "as_count",
    "as_choice",
    "as_points",
    "as_discount",
    "as_probability",
    "check_instance",
    "check_shape",
    "check_same_shape",
    "check_dimension",
    "frozen_copy",
]


def _shape_text(shape: Sequence[int | None]) -> str:
    return "(" + ", ".join("*" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"


def check_shape(name: str, array: np.ndarray, shape: Sequence[int | None]) -> None:
    """Raise `DimensionError` unless ``array.shape`` matches ``shape`` (None = any length).

    Parameters
    ----------
    name : str
        The argument's name, used in the message.
    array : numpy.ndarray
        The array to check.
    shape : sequence of int or None
        The expected shape; a None entry matches any length.

    Raises
    ------
    DimensionError
        Naming the argument, the expected shape (``*`` for a free length) and the
        shape given.
    """
    if array.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, array.shape)):
        raise DimensionError(f"{name} must have shape {_shape_text(shape)}, got shape {array.shape}")


def check_same_shape(first: str, a: np.ndarray, second: str, b: np.ndarray) -> None:
    """Raise `DimensionError` unless two arrays have the same shape.

    Parameters
    ----------
    first : str
        The name of ``a``, used in the message.
    a : numpy.ndarray
        The first array.
    second : str
        The name of ``b``.
    b : numpy.ndarray
        The second array.

    Raises
    ------
    DimensionError
        Naming both arguments and both shapes.
    """
    if np.shape(a) != np.shape(b):
        raise DimensionError(f"{first} and {second} must have the same shape, got {np.shape(a)} and {np.shape(b)}")


def check_dimension(name: str, dim: int, expected: int, reason: str = "") -> None:
    """Raise `DimensionError` unless a set or vector argument has dimension ``expected``.

    Parameters
    ----------
    name : str
        The argument's name.
    dim : int
        Its dimension.
    expected : int
        The dimension required.
    reason : str
        Where ``expected`` comes from (e.g. ``"A0 has shape (2, 2)"``), shown in parentheses.

    Raises
    ------
    DimensionError
        Naming the argument, both dimensions and the reason.
    """
    if dim != expected:
        why = f" ({reason})" if reason else ""
        raise DimensionError(f"{name} must have dimension {expected}{why}, got {dim}")


def check_instance(name: str, value: Any, types: type | tuple[type, ...], what: str | None = None) -> None:
    """Raise `InputError` unless ``value`` is an instance of ``types``.

    Parameters
    ----------
    name : str
        The argument's name, used in the message.
    value : object
        The value to check.
    types : type or tuple of type
        The accepted types (as for `isinstance`).
    what : str, optional
        The expected kind in words (default: ``"a <Type>"``, or ``"an <Type>"`` before a
        vowel, after the first of ``types``).

    Raises
    ------
    InputError
        Naming the argument, the expected kind and the type that was given.
    """
    if isinstance(value, types):
        return
    if what is None:
        first = types[0] if isinstance(types, tuple) else types
        article = "an" if first.__name__[:1].upper() in "AEIOU" else "a"
        what = f"{article} {first.__name__}"
    raise InputError(f"{name} must be {what}, got {type(value).__name__}")


def as_finite_array(
    name: str, value, shape: Sequence[int | None] | None = None, *, ndim: int | None = None
) -> np.ndarray:
    """Convert ``value`` to a float64 array, checking its shape and finiteness.

    Parameters
    ----------
    name : str
        The argument's name, used in error messages.
    value : array_like
        Anything `numpy.asarray` accepts.
    shape : sequence of int or None, optional
        Expected shape; ``None`` entries match any length.
    ndim : int, optional
        Expected number of dimensions, when the lengths are free.

    Returns
    -------
    numpy.ndarray
        ``value`` as float64 (not copied when it already is one).

    Raises
    ------
    InputError
        If ``value`` is not real and numeric: complex values are refused (not truncated),
        and so are text (even numeric, ``["0.5"]``) and booleans, which a float cast
        would silently parse or turn into 0 and 1.
    DimensionError
        If the shape or the number of dimensions is wrong.
    NonFiniteError
        If an entry is NaN or infinite, or an integer too large for a float.
    """
    try:
        raw = np.asarray(value)
        if np.iscomplexobj(raw):  # a float cast would silently drop the imaginary part
            raise InputError(f"{name} must be a real numeric array, got complex values")
        # A float cast would parse numeric text (["0.5"]) and turn bools into 0/1: refuse both.
        if raw.dtype.kind in "USb" or (raw.dtype.kind == "O" and any(_is_text_or_bool(x) for x in raw.flat)):
            raise InputError(f"{name} must be a real numeric array, got {_kind_of(raw)}")
        array = raw.astype(float, copy=False)
    except OverflowError:  # an int too large for a float (10**400)
        raise NonFiniteError(f"{name} contains an integer too large for a float") from None
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


def _is_text_or_bool(x: Any) -> bool:
    return isinstance(x, (str, bytes, bool, np.bool_))


def _kind_of(raw: np.ndarray) -> str:
    if raw.dtype.kind == "b" or (raw.dtype.kind == "O" and any(isinstance(x, (bool, np.bool_)) for x in raw.flat)):
        return "booleans"
    return "text"


def as_points(name: str, value, dim: int, *, batch: str = "k") -> np.ndarray:
    """A finite float array of one point, shape (dim,), or a batch of points, shape (k, dim).

    Parameters
    ----------
    name : str
        The argument's name, used in error messages.
    value : array_like
        The point or points.
    dim : int
        The dimension of a point.
    batch : str
        The name of the batch length in the message (e.g. ``"N"``).

    Returns
    -------
    numpy.ndarray
        Float64, shape (dim,) or (k, dim).

    Raises
    ------
    DimensionError
        ``"<name> must have shape (dim,) or (k, dim), got shape ..."``.
    InputError, NonFiniteError
        As `as_finite_array`.
    """
    points = as_finite_array(name, value)
    if points.shape[-1:] != (dim,) or points.ndim > 2:
        raise DimensionError(f"{name} must have shape ({dim},) or ({batch}, {dim}), got shape {points.shape}")
    return points


def frozen_copy(array: np.ndarray) -> np.ndarray:
    """A read-only float64 copy, so that immutable values never alias a caller's array.

    Parameters
    ----------
    array : array_like
        The array to copy.

    Returns
    -------
    numpy.ndarray
        A new float64 array with ``writeable=False``.
    """
    out = np.array(array, dtype=float, copy=True)
    out.setflags(write=False)
    return out


def as_real_scalar(name: str, value) -> float:
    """Check that ``value`` is a finite real scalar (any sign); return it as a float.

    Parameters
    ----------
    name : str
        The argument's name, used in error messages.
    value : float
        The value to check: Python and numpy numbers; strings (even numeric ones such as
        ``"0.5"``), bools, complex numbers and arrays are refused.

    Returns
    -------
    float

    Raises
    ------
    InputError
        If ``value`` is not a real scalar.
    NonFiniteError
        If it is NaN or infinite, or an integer too large for a float.
    """
    return _as_real_scalar(name, value)


def _as_real_scalar(name: str, value) -> float:
    # A string is not a number even when float() would parse it ("0.5"), nor is a bool.
    if isinstance(value, (str, bytes, bool, np.bool_)) or np.iscomplexobj(value):
        raise InputError(f"{name} must be a real scalar, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a real scalar, got {value!r}") from None
    except OverflowError:  # an int too large for a float (10**400)
        raise NonFiniteError(f"{name} must be finite, got an integer too large for a float") from None
    if not np.isfinite(x):
        raise NonFiniteError(f"{name} must be finite, got {x}")
    return x


def as_positive_scalar(name: str, value, *, allow_zero: bool = False) -> float:
    """Check that ``value`` is a finite real scalar > 0 (or >= 0); return it as a float.

    Parameters
    ----------
    name : str
        The argument's name, used in error messages.
    value : float
        The value to check (bools and complex numbers are refused).
    allow_zero : bool
        Accept 0 too.

    Returns
    -------
    float

    Raises
    ------
    InputError
        If ``value`` is not a real scalar, or is negative (or 0 without ``allow_zero``).
    NonFiniteError
        If it is NaN or infinite.
    """
    x = _as_real_scalar(name, value)
    if x < 0 or (x == 0 and not allow_zero):
        raise InputError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {x}")
    return x


def as_probability(name: str, value) -> float:
    """Check that ``value`` is a real scalar in the open interval (0, 1); return it as a float.

    Used for confidence levels (``delta``: the set holds with probability >= 1 - delta).

    Parameters
    ----------
    name : str
        The argument's name, used in error messages.
    value : float
        The value to check.

    Returns
    -------
    float

    Raises
    ------
    InputError
        A value <= 0 as by `as_positive_scalar` (``"must be > 0"``), one >= 1 as
        ``"must lie in (0, 1)"``.
    NonFiniteError
        If it is NaN or infinite.
    """
    x = as_positive_scalar(name, value)
    if not x < 1:
        raise InputError(f"{name} must lie in (0, 1), got {x}")
    return x


def as_discount(name: str, value) -> float:
    """Check that a discount factor satisfies ``0 < gamma < 1``; return it as a float.

    Parameters
    ----------
    name : str
        The argument's name, used in error messages.
    value : float
        The discount factor.

    Returns
    -------
    float

    Notes
    -----
    The paper allows eta = 1 (its discount); the value bounds of eqs. (12) and
    (16)-(18) need ``gamma < 1`` (DESIGN errata).

    Raises
    ------
    InputError
        If ``value`` is not a real number, or not in the open interval (0, 1).
    NonFiniteError
        If it is NaN or infinite.
    """
    if isinstance(value, (str, bytes, bool, np.bool_)) or np.iscomplexobj(value):
        raise InputError(f"{name} must be a real number in (0, 1), got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be a real number in (0, 1), got {value!r}") from None
    if not np.isfinite(x):
        raise NonFiniteError(f"{name} must be finite and in (0, 1), got {x}")
    if not 0.0 < x < 1.0:
        raise InputError(f"{name} must be in the open interval (0, 1), got {x}")
    return x


def as_count(name: str, value, *, minimum: int = 1) -> int:
    """Check that ``value`` is an integer >= ``minimum``; return it as an ``int``.

    Parameters
    ----------
    name : str
        The argument's name, used in error messages.
    value : int
        Python and numpy integers are accepted; bools, floats (even integral ones) and
        strings are not.
    minimum : int
        The smallest value accepted.

    Returns
    -------
    int

    Raises
    ------
    InputError
        If ``value`` is not an integer or is below ``minimum``.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < minimum:
        what = "a positive integer" if minimum == 1 else f"an integer >= {minimum}"
        raise InputError(f"{name} must be {what}, got {value!r}")
    return int(value)


def as_choice(name: str, value, choices: Sequence, *, ignore_case: bool = False):
    """Check that ``value`` is one of ``choices``; return the matching choice.

    Parameters
    ----------
    name : str
        The argument's name, used in error messages.
    value : object
        The value to check.
    choices : sequence
        The accepted values.
    ignore_case : bool
        Compare strings upper-cased (the choices are then given upper-case) and return
        the choice in its canonical spelling.

    Returns
    -------
    object
        The matching choice.

    Raises
    ------
    InputError
        ``"<name> must be one of (...), got ..."``.
    """
    key = value.upper() if ignore_case and isinstance(value, str) else value
    try:
        found = key in choices
    except TypeError:  # an unhashable value, for a set of choices
        found = False
    if not found:
        raise InputError(f"{name} must be one of {tuple(choices)}, got {value!r}")
    return key
