"""The compiled-reward protocol: how a reward's exact box minimum reaches compiled code.

A reward family in [0, 1] gives the planners its exact minimum over a box of states
(Theorem 1: each term of the surrogate objective (11) is such a minimum). It writes
that minimum ONCE, as a compiled kernel on one box, and gets every other form from it:

1. ``kernel_params``: a `collections.namedtuple` of C-contiguous arrays and floats
   holding everything the minimum reads (obstacles, goal, weights, state indices);
2. an implementation of `box_reward_minimum` for that namedtuple type, registered with
   ``numba.extending.overload(box_reward_minimum)``: ``(params, z, p, t) -> (reward,
   collided)`` on one box ``z = [-lower | upper]`` (2p,) at the absolute sub-step t;
3. `register_reward_params` on the namedtuple type (with the source files the kernel
   calls into, beyond its own module and `minimaxplan.kernels.box_primitives`);
4. its numpy-facing ``box_minimum(lower, upper, t)`` is `box_minima` (``kernel_params``,
   ...): a compiled loop over the boxes calling the same kernel, so the planner's
   compiled engine, the Python engine and `PointModel` evaluate the same operations.

The planners never import the family: `minimaxplan.planners.IntervalModel` reads
``reward.kernel_params``, checks it with `has_compiled_minimum`, and passes it
through to its kernels, where numba picks the implementation from its type. A reward
without ``kernel_params`` (None) is evaluated through its ``box_minimum`` alone, on
the Python engine. See `BoxReward`, `UncheckedBoxReward`, `StateIndexedReward` and
`CompiledBoxReward` for the attributes read, and ``docs/rewards.md`` for a worked
example.

Cache keys: numba's on-disk cache checks only the source file of the compiled
function itself, not the files of the functions it inlines. Kernels that call
`box_reward_minimum` are therefore built by factories closing over
``sources_digest(*minimum_sources(params_type))`` (numba hashes a cached closure's
cell contents into its cache key), so a change to any of those files recompiles them,
and are compiled by `compile_per_params_type`, so that each params type has an on-disk
index of its own.
"""

from __future__ import annotations

import functools
import hashlib
import logging
import math
import pathlib
import sys
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numba import njit

from . import box_primitives

__all__ = [
    "BoxReward",
    "CompiledBoxReward",
    "StateIndexedReward",
    "UncheckedBoxReward",
    "box_minima",
    "box_minima_kernel",
    "box_reward_minimum",
    "compile_per_params_type",
    "has_compiled_minimum",
    "minimum_sources",
    "register_reward_params",
    "sources_digest",
]


@runtime_checkable
class BoxReward(Protocol):
    """What a planner model (`IntervalModel`, `PointModel`) calls on a reward.

    ``box_minimum(lower, upper, t) -> (reward, collided)``: for boxes of states
    ``lower``, ``upper`` of shape (..., p) and sub-step indices ``t`` (a scalar or an
    array broadcasting against the leading shape), the exact
    ``min_{lower <= x <= upper} J(x, t)`` in [0, 1] and whether some state of the box
    collides (a collision is terminal; the minimum is then 0). A point is the
    degenerate box ``[x, x]``.

    Optional capabilities, each declared by a protocol of its own and checked with
    ``isinstance``: `UncheckedBoxReward` (``box_minimum_raw``, the same without
    argument checks, for hot loops), `StateIndexedReward` (``min_state_dim``, the
    number of state coordinates the reward reads) and `CompiledBoxReward`
    (``kernel_params``).
    """

    def box_minimum(self, lower: np.ndarray, upper: np.ndarray, t: Any = 0) -> tuple[np.ndarray, np.ndarray]:
        """The exact minimum of the reward over each box at sub-step ``t``, and the collision flags.

        Parameters
        ----------
        lower, upper : numpy.ndarray
            Boxes of states, float arrays of shape (..., p) broadcasting against each
            other, ``lower <= upper``, in the state's units.
        t : int or array_like
            Absolute sub-step indices: a scalar or an integer array broadcasting
            against the leading shape (time-varying rewards, e.g. moving obstacles).

        Returns
        -------
        reward : numpy.ndarray
            Float array of the leading shape: ``min_{lower <= x <= upper} J(x, t)`` in
            [0, 1], 0 where the box collides.
        collided : numpy.ndarray
            Bool array of the leading shape: whether some state of the box collides.

        Notes
        -----
        Each term of the pessimistic surrogate objective (11) is such a minimum; that it
        is the exact minimum (not an estimate at the box centre) is what Theorem 1 needs.
        """


@runtime_checkable
class UncheckedBoxReward(BoxReward, Protocol):
    """A `BoxReward` that also offers its minimum without argument checks.

    The planner models call ``box_minimum_raw`` in their hot loops instead of
    ``box_minimum``; it must return exactly what ``box_minimum`` returns for valid
    arguments.
    """

    def box_minimum_raw(self, lower: np.ndarray, upper: np.ndarray, t: Any = 0) -> tuple[np.ndarray, np.ndarray]:
        """`BoxReward.box_minimum` without its argument checks.

        Parameters
        ----------
        lower, upper : numpy.ndarray
            Boxes of states, float arrays of shape (..., p), ``lower <= upper``
            (not checked).
        t : int or array_like
            Absolute sub-step indices, broadcasting against the leading shape.
        """


@runtime_checkable
class StateIndexedReward(BoxReward, Protocol):
    """A `BoxReward` that declares how many state coordinates it reads.

    A planner model checks ``min_state_dim`` against its system's number of states at
    construction and raises a `DimensionError` when the reward reads a coordinate the
    state does not have.
    """

    @property
    def min_state_dim(self) -> int:
        """One more than the largest state index the reward reads."""


@runtime_checkable
class CompiledBoxReward(BoxReward, Protocol):
    """A `BoxReward` whose minimum is also a compiled kernel.

    ``kernel_params`` is an instance of a namedtuple type registered with
    `register_reward_params`, for which an implementation of `box_reward_minimum` is
    registered with ``numba.extending.overload``. The planners' compiled engine runs
    only for such rewards.
    """

    kernel_params: Any


#: The logger that says, before a kernel of `compile_per_params_type` is first compiled, what is compiling
#: and where it is cached (INFO; DEBUG when numba's disk cache already holds an index for it).
COMPILE_LOGGER = logging.getLogger("minimaxplan.kernels")

# params type -> the extra source files its kernel calls into (beyond its own module)
_REWARD_PARAMS_TYPES: dict[type, tuple[str, ...]] = {}


def register_reward_params(params_type: type, *, sources: tuple[str, ...] = ()) -> type:
    """Declare that ``params_type`` has an implementation of `box_reward_minimum`.

    Parameters
    ----------
    params_type
        The namedtuple type of a family's ``kernel_params``.
    sources
        Source files the implementation calls into besides its own module and
        `minimaxplan.kernels.box_primitives` (they join the cache key, see
        `minimum_sources`).

    Returns
    -------
    type
        ``params_type`` (so that the call can decorate the type's definition).
    """
    _REWARD_PARAMS_TYPES[params_type] = tuple(str(file) for file in sources)
    return params_type


def has_compiled_minimum(params: Any) -> bool:
    """Whether ``params``'s type was registered with `register_reward_params`.

    Parameters
    ----------
    params
        A reward's ``kernel_params``.

    Returns
    -------
    bool
    """
    return type(params) in _REWARD_PARAMS_TYPES


def box_reward_minimum(params, z, p, t):
    """The exact minimum of a reward over the box ``z = [-lower | upper]`` (2p,) at sub-step t.

    Compiled code only: a reward family registers an implementation for the type of
    its ``kernel_params`` with ``numba.extending.overload(box_reward_minimum)`` (see
    the module docstring). Called from Python, it raises.

    Parameters
    ----------
    params
        The reward's ``kernel_params``.
    z
        One box as ``[-lower | upper]``, float64 (2p,).
    p
        The state dimension.
    t
        The absolute sub-step index, as a float.

    Returns
    -------
    reward, collided
        The minimum (0.0 when the box may collide) and whether it may.
    """
    raise NotImplementedError(
        f"no compiled box minimum is registered for reward parameters of type {type(params).__name__}"
    )


def sources_digest(*files: str) -> int:
    """A 63-bit digest of source files, for the cache key of compiled code that calls into them.

    numba's on-disk cache checks only the source file of the compiled function
    itself. A kernel compiled through a factory that closes over this digest is
    re-compiled whenever one of ``files`` changes (numba hashes a cached closure's
    cell contents into the cache key).

    Parameters
    ----------
    *files
        Paths of source files, in a fixed order.

    Returns
    -------
    int
        In ``[0, 2**63)``.
    """
    digest = hashlib.sha256()
    for file in files:
        digest.update(pathlib.Path(file).read_bytes())
    return int.from_bytes(digest.digest()[:8], "little") >> 1


def minimum_sources(params_type: type) -> list[str]:
    """The source files a compiled call of `box_reward_minimum` on ``params_type`` depends on.

    Parameters
    ----------
    params_type
        A type registered with `register_reward_params`.

    Returns
    -------
    list of str
        This module, `minimaxplan.kernels.box_primitives`, the module defining
        ``params_type`` (where its implementation lives), then the ``sources`` it was
        registered with. A caller adds its own file in front (see
        `minimaxplan.planners.box_kernels.reward_sources`).

    Raises
    ------
    TypeError
        If ``params_type`` is not registered, or its module has no source file (a
        class defined interactively): its kernel could not be keyed on disk, so define
        it in a module file.
    """
    if params_type not in _REWARD_PARAMS_TYPES:
        raise TypeError(f"{params_type.__name__} is not registered (see minimaxplan.kernels.register_reward_params)")
    module = sys.modules.get(params_type.__module__)
    source = getattr(module, "__file__", None)
    if source is None:
        raise TypeError(
            f"{params_type.__name__} is defined in module {params_type.__module__!r}, which has no source file: "
            "define compiled reward kernels in a module file (their disk cache is keyed by its contents)"
        )
    return [__file__, box_primitives.__file__, source, *_REWARD_PARAMS_TYPES[params_type]]


@functools.cache
def box_minima_kernel(params_type: type):
    """The compiled loop of `box_minima` for rewards whose ``kernel_params`` have type ``params_type``.

    Parameters
    ----------
    params_type
        A type registered with `register_reward_params`.

    Returns
    -------
    numba dispatcher
        ``kernel(params, z, t, reward, collided)``: for each row k of ``z`` (K, 2p)
        (C-contiguous float64) and ``t`` (K,) float64, writes
        ``box_reward_minimum(params, z[k], p, t[k])`` to ``reward[k]`` (float64) and
        ``collided[k]`` (bool). Cached on disk, keyed by `minimum_sources`.
    """
    version = sources_digest(*minimum_sources(params_type))

    def box_minima_loop(params, z, t, reward, collided):
        _ = version  # ties numba's cache entry to the sources it calls into
        p = z.shape[1] // 2
        for k in range(z.shape[0]):
            value, hit = box_reward_minimum(params, z[k], p, t[k])
            reward[k] = value
            collided[k] = hit

    return compile_per_params_type(box_minima_loop, params_type, what="the reward's box-minimum loop")


_CACHED: dict[str, Any] = {"cache": True, "no_cfunc_wrapper": True}


def compile_per_params_type(function, params_type: type, *, what: str = "a compiled kernel"):
    """``numba.njit(cache=True)`` of a kernel made for one params type, with an on-disk index of its own.

    numba keeps one cache index per function (by module and qualified name) holding
    every compiled signature, and unpickles all of them to load any one: a kernel made
    by a factory for several params types would share one index, and a params type
    whose module cannot be imported later (a user's reward moved or deleted) would make
    loading fail for every type. The function's qualified name is therefore suffixed
    with a digest of the type's module and name before compiling.

    Before returning (so before the first call compiles anything), logs on
    `COMPILE_LOGGER` what is about to be compiled and where numba caches it: at INFO
    when numba's disk cache has no index for the kernel yet (the first run on this
    machine, or after a source change: tens of seconds), at DEBUG otherwise.

    Parameters
    ----------
    function
        A Python function defined in a factory (typically closing over
        ``sources_digest(*minimum_sources(params_type))``).
    params_type
        The type the kernel is made for.
    what
        What the kernel is, for the log message (e.g. "the planner's search kernel").

    Returns
    -------
    numba dispatcher
    """
    tag = hashlib.sha256(f"{params_type.__module__}.{params_type.__qualname__}".encode()).hexdigest()[:12]
    function.__qualname__ = f"{function.__qualname__}_{tag}"
    # no C wrapper: that is for numba's first-class function values (unused), one more function to emit
    dispatcher = njit(**_CACHED)(function)
    index, directory = _cache_index(dispatcher)
    if index is not None and index.exists():
        COMPILE_LOGGER.debug("loading %s for %s from numba's cache in %s", what, params_type.__name__, directory)
    else:
        COMPILE_LOGGER.info(
            "compiling %s for %s (once: the first run takes tens of seconds; cached in %s)",
            what,
            params_type.__name__,
            directory,
        )
    return dispatcher


def _cache_index(dispatcher) -> tuple[pathlib.Path | None, str]:
    """The path of numba's on-disk cache index of ``dispatcher`` (None if numba hides it) and its folder."""
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    index = getattr(cache_file, "_index_path", None)
    if index is None:  # numba's private layout changed: say where the cache lives in general
        from numba.core import config

        return None, getattr(config, "CACHE_DIR", "") or "the __pycache__ folders next to the sources"
    return pathlib.Path(index), str(pathlib.Path(index).parent)


def box_minima(params: Any, lower: np.ndarray, upper: np.ndarray, t: Any = 0) -> tuple[np.ndarray, np.ndarray]:
    """The numpy-facing form of a registered compiled box minimum, over many boxes.

    No argument checks beyond the registration (the families validate first).

    Parameters
    ----------
    params
        A reward's ``kernel_params`` (its type registered with `register_reward_params`).
    lower, upper
        Boxes of states, float arrays of shape (..., p) broadcasting against each other,
        ``lower <= upper``.
    t
        Absolute sub-step indices: a scalar or an array broadcasting against the
        leading shape.

    Returns
    -------
    reward, collided
        Arrays of the broadcast leading shape: the exact minimum over each box (0 where
        it may collide) and the collision flags, bit for bit what the compiled engines
        compute for the same boxes.

    Raises
    ------
    TypeError
        If no compiled minimum is registered for ``type(params)``.
    """
    if not has_compiled_minimum(params):
        raise TypeError(
            f"params has type {type(params).__name__}, for which no compiled box minimum is registered "
            "(see minimaxplan.kernels.register_reward_params)"
        )
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    shape = np.broadcast_shapes(lower.shape, upper.shape)
    times = np.asarray(t, dtype=float)
    lead = np.broadcast_shapes(shape[:-1], times.shape)
    p = shape[-1]
    z = np.empty(lead + (2 * p,))
    np.negative(lower, out=z[..., :p])
    z[..., p:] = upper
    n = math.prod(lead)
    reward = np.empty(n)
    collided = np.empty(n, dtype=bool)
    if n:
        flat_times = np.ascontiguousarray(np.broadcast_to(times, lead)).reshape(n)
        params_type: type = type(params)  # mypy infers type[Any], which it does not treat as Hashable
        box_minima_kernel(params_type)(params, z.reshape(n, 2 * p), flat_times, reward, collided)
    return reward.reshape(lead), collided.reshape(lead)
