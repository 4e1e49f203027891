"""The exception hierarchy of minimaxplan.

Every error subclasses a builtin so that callers can catch either the precise
minimaxplan type or the builtin they already expect (``ValueError`` for bad input,
``RuntimeError`` for a failure at run time).
"""

from __future__ import annotations

__all__ = [
    "MinimaxplanError",
    "InputError",
    "DimensionError",
    "NonFiniteError",
    "EmptySetError",
    "RewardRangeError",
    "SolverFailure",
    "NoConsistentModel",
]


class MinimaxplanError(Exception):
    """Base class of every error raised on purpose by minimaxplan."""


class InputError(MinimaxplanError, ValueError):
    """An argument has an invalid value (the message names the argument)."""


class DimensionError(InputError):
    """An array argument has the wrong shape (the message names both shapes)."""


class NonFiniteError(InputError):
    """An array argument contains NaN or infinity."""


class EmptySetError(InputError):
    """A set argument is empty, e.g. a box with ``low > high`` somewhere."""


class RewardRangeError(InputError):
    """A model returned a reward outside [0, 1] or a non-finite reward."""


class SolverFailure(MinimaxplanError, RuntimeError):
    """A numerical solver failed (not: reported infeasibility, which is a result)."""


class NoConsistentModel(MinimaxplanError, RuntimeError):
    """Every model hypothesis has been eliminated by the data."""
