"""Scenario and method registries: what `run_experiment` and the CLI can run.

A *scenario* makes seeded worlds; a *method* drives one world through an episode. Both
are registered under a name by a factory, so that adding a world or a planner touches
no file of the package::

    from minimaxplan.analysis import register_method, register_scenario

    register_scenario("corridor", CorridorScenario)        # factory() -> Scenario
    register_method("bang-bang", BangBang)                 # factory(scenario, config) -> Method

The episode loop (`minimaxplan.analysis.episode.run_episode`) is written once for every
scenario and uses only the interfaces below: `Scenario`, the `World` it makes, `Method`
and the `Policy` a method returns at each decision. ``docs/extending.md`` pins them.

The guarantee is checked at run time through two more protocols: a `PredictingPolicy`
says which box it predicted for every named thing after each sub-step of its decision
(``{"robot": (lower, upper), "pedestrian 2": (lower, upper)}``), a `GroundTruthWorld`
gives the true states under the same names, and the loop counts the boxes checked and
missed (`box_kind` groups the names).

Factories travel with each job to the worker processes (a local pool or Dask): a factory
is a picklable callable (a module-level function or class, a `functools.partial` of one)
or a string ``"package.module:qualname"`` resolved where it is called.

One method name may serve several scenarios: `register_method` called again with the same
name and a new factory adds it, and a run picks the newest factory of that name that does
not raise `UnsupportedScenario` for the scenario at hand.
"""

from __future__ import annotations

import abc
import importlib
import pickle
import re
import sys
from collections.abc import Callable, Mapping
from typing import Any, Generic, NamedTuple, Protocol, TypeVar, runtime_checkable

import numpy as np

from minimaxplan.models.errors import InputError, MinimaxplanError

__all__ = [
    "Scenario",
    "World",
    "Method",
    "Policy",
    "PredictingPolicy",
    "GroundTruthWorld",
    "TracedWorld",
    "CrowdedWorld",
    "box_kind",
    "Transition",
    "UnknownScenario",
    "UnknownMethod",
    "UnsupportedScenario",
    "EpisodeFailure",
    "register_scenario",
    "register_method",
    "register_unavailable",
    "scenario_names",
    "default_scenario_names",
    "method_names",
    "scenario_factory",
    "method_factory",
    "resolve",
]

#: A factory: a picklable callable or an importable ``"module:qualname"``.
Factory = Callable[..., Any] | str

#: Modules that register the built-in scenarios and methods when imported (loaded on the
#: first use of a registry, so that ``import minimaxplan.analysis`` stays light).
BUILTIN_MODULES = (
    "minimaxplan.analysis.robot_scenario",
    "minimaxplan.analysis.robot_methods",
    "minimaxplan.analysis.road_scenario",
    "minimaxplan.analysis.road_methods",
    "minimaxplan.analysis.road_planning",
    "minimaxplan.analysis.highway_env_scenario",
)

_QUALIFIED_NAME = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_][\w.]*$")


# ------------------------------------------------------------------------ errors
class UnknownScenario(InputError):
    """No scenario is registered under the name asked for (the message lists the known names)."""


class UnknownMethod(InputError):
    """No method is registered under the name asked for (the message lists the known names)."""


class UnsupportedScenario(InputError):
    """A method factory does not support the scenario it was given.

    Method factories raise it for a scenario they cannot drive; the registry then tries
    the next factory registered under the same name.
    """


class EpisodeFailure(MinimaxplanError, RuntimeError):
    """Raised by `Method.decide` when the method cannot go on: the episode ends with ``outcome``.

    A failure of the episode (counted in the results), not an error of the run; e.g. the
    robust method raises it with outcome ``"no_consistent_model"`` once the data has
    eliminated every hypothesis.
    """

    def __init__(self, outcome: str, message: str = ""):
        super().__init__(message or outcome)
        self.outcome = outcome


# -------------------------------------------------------------------- interfaces
class Transition(NamedTuple):
    """One sub-step as the method saw it: measurement, applied control, next measurement.

    The measurements are what `World.measure` returns: an array in the robot worlds, an
    Observation in the road worlds.
    """

    measured: Any
    control: np.ndarray
    next_measured: Any


@runtime_checkable
class World(Protocol):
    """One seeded episode of a scenario, as the episode loop drives it.

    Attributes
    ----------
    substeps
        Sub-steps per decision: the policy of a decision is applied this many times.
    done
        True once the episode has ended.
    outcome
        "running" while not done; then e.g. "goal", "collision" or "timeout" (only
        "goal" counts as a success).
    time
        Simulated time, s.
    position
        Where the agent is, a 1-D array (recorded, rounded, as the trajectory).
    """

    @property
    def substeps(self) -> int:
        """Sub-steps per decision."""

    @property
    def done(self) -> bool:
        """True once the episode has ended."""

    @property
    def outcome(self) -> str:
        """The outcome: "running" while not done, then e.g. "goal" or "collision"."""

    @property
    def time(self) -> float:
        """Simulated time, s."""

    @property
    def position(self) -> np.ndarray:
        """Where the agent is, a 1-D array."""

    def measure(self) -> Any:
        """A (noisy) measurement of the state; the only thing the method sees of it.

        An array in the robot worlds, an Observation in the road worlds.
        """

    def apply(self, u: np.ndarray) -> str:
        """Apply the control ``u`` for one sub-step; returns the outcome.

        Parameters
        ----------
        u : numpy.ndarray
            The control, shape (q,).

        Returns
        -------
        str
            The world's outcome after the sub-step ("running" while not done).
        """

    def reward(self) -> float:
        """The true reward in [0, 1] of the current state."""

    def to_dict(self) -> dict:
        """The episode's setup (stored in ``EpisodeRecord.extra["world"]``)."""


@runtime_checkable
class Policy(Protocol):
    """What a method decided: a feedback law held for one decision period."""

    def control(self, measurement: Any) -> np.ndarray:
        """The control to apply now, admissible for the world (e.g. saturated).

        Parameters
        ----------
        measurement : Any
            The current measurement (`World.measure`): an array in the robot worlds,
            shape (p,), an Observation in the road worlds.

        Returns
        -------
        numpy.ndarray
            The control, shape (q,).
        """


@runtime_checkable
class PredictingPolicy(Policy, Protocol):
    """A `Policy` that also says where it predicted everything to be during its decision.

    The episode loop checks, after every sub-step of the decision, that each true state
    (`GroundTruthWorld.true_states`) lies in the box predicted for it under the same
    name, by exact float comparison (no tolerance: a sound predictor rounds its boxes
    outward), and counts the boxes checked and missed in the episode's record.

    Notes
    -----
    This is the run-time form of the inclusion property (7) and of Theorem 1's premise:
    the true trajectory stays in the interval prediction. A miss is a bug, never a
    number to tune.
    """

    def predicted_boxes(self, substep: int) -> Mapping[str, tuple[np.ndarray, np.ndarray]]:
        """The boxes predicted for the states after sub-step ``substep`` of this decision.

        Parameters
        ----------
        substep : int
            1 for the state after the first sub-step of the decision, up to the world's
            ``substeps``.

        Returns
        -------
        Mapping of str to (numpy.ndarray, numpy.ndarray)
            ``name -> (lower, upper)``, each corner of the shape of the true state of
            ``name``. A name is a kind, optionally followed by a space and an
            identifier (`box_kind`): ``"robot"``, ``"pedestrian 2"``, ``"vehicle 7"``.
            Only what the method claims to contain the truth is listed (an empty
            mapping checks nothing).
        """


@runtime_checkable
class GroundTruthWorld(World, Protocol):
    """A `World` that tells the episode loop the true states of what it simulates.

    Read by the loop only, to check the boxes of a `PredictingPolicy`; never shown to a
    method. Reading it must draw no random number and change nothing.
    """

    def true_states(self) -> Mapping[str, np.ndarray]:
        """The true state of everything a method may predict, now, by name.

        Returns
        -------
        Mapping of str to numpy.ndarray
            ``name -> state`` (1-D arrays), under the names a `PredictingPolicy` uses
            (e.g. ``"robot"``: the robot's state, ``"pedestrian 0"``: a pedestrian's
            position).
        """


@runtime_checkable
class TracedWorld(World, Protocol):
    """A `World` whose true state the episode's trace records, for plots and animations.

    Read by the loop only (`EpisodeRecord.trace`); reading it must draw no random number
    and change nothing. A world that is not one leaves the trace's states empty.
    """

    @property
    def step_index(self) -> int:
        """Sub-steps applied so far."""

    @property
    def state(self) -> np.ndarray:
        """The agent's true state, a 1-D array."""

    @property
    def params(self) -> Any:
        """The episode's constants; ``params.dt`` is the sub-step, s."""


@runtime_checkable
class CrowdedWorld(World, Protocol):
    """A `World` with pedestrians, whose true positions the episode's trace records."""

    @property
    def crowd(self) -> Any:
        """The pedestrians; ``crowd.positions`` is their true positions (n, 2), m."""


def box_kind(name: str) -> str:
    """The kind of a predicted box's name: the name up to its first space.

    Parameters
    ----------
    name : str
        E.g. ``"robot"`` or ``"pedestrian 2"``.

    Returns
    -------
    str
        E.g. ``"robot"`` or ``"pedestrian"``: the key under which the loop also counts
        the boxes checked and missed per kind.
    """
    return name.split(" ", 1)[0]


#: The world type of a scenario and of the methods that drive it (bound: `World`).
WorldT = TypeVar("WorldT", bound=World)


class Scenario(abc.ABC, Generic[WorldT]):
    """A family of seeded worlds, registered with ``register_scenario(name, factory)``.

    ``factory()`` returns the scenario; it should be cheap (it is also called in the
    main process to check that every method asked for supports it).
    """

    @abc.abstractmethod
    def make_world(self, seed: int, config: Any) -> WorldT:
        """A new world for episode ``seed`` under the loop settings ``config``.

        The same seed must give the same world: records depend only on
        ``(scenario, method, seed, config)``.

        Parameters
        ----------
        seed : int
            The episode's world seed (>= 0).
        config : LoopConfig
            The loop settings of the episode.

        Returns
        -------
        World
            A fresh world, before its first sub-step.
        """


class Method(abc.ABC, Generic[WorldT]):
    """A planner driving a world, registered with ``register_method(name, factory)``.

    ``factory(scenario, config)`` returns a fresh method for one episode, or raises
    `UnsupportedScenario` for a scenario it cannot drive; it should be cheap (heavy
    set-up belongs in `start`). The episode loop then calls, in this order::

        method.start(world)
        x = world.measure()
        while not world.done:
            policy = method.decide(x)                       # may raise EpisodeFailure
            for each of world.substeps sub-steps k = 1, 2, ...:
                u = policy.control(x); world.apply(u)
                if policy is a PredictingPolicy: check policy.predicted_boxes(k)
                    against world.true_states()
                x_next = world.measure()
                method.observe(Transition(x, u, x_next)); x = x_next
        record.extra = {**method.report(), "world": world.to_dict(), "runtime_check": ...}
    """

    @abc.abstractmethod
    def start(self, world: WorldT) -> None:
        """Begin an episode in ``world`` (before its first measurement).

        Parameters
        ----------
        world : World
            The episode's world, made by the scenario the method was built for.
        """

    @abc.abstractmethod
    def decide(self, measurement: Any) -> Policy:
        """Plan on the current measurement; the returned policy runs for one decision period.

        Parameters
        ----------
        measurement : Any
            The current measurement (`World.measure`): an array in the robot worlds,
            shape (p,), an Observation in the road worlds.

        Returns
        -------
        Policy
            The feedback law applied for every sub-step of the decision period.

        Raises
        ------
        EpisodeFailure
            If the method cannot go on (the episode ends with ``outcome``).
        """

    def observe(self, transition: Transition) -> None:  # noqa: B027 (optional hook)
        """Learn from one sub-step (default: ignore it).

        Parameters
        ----------
        transition : Transition
            The measured state before the sub-step, the control applied and the
            measured state after it.
        """

    def report(self) -> dict:
        """Per-episode data for ``EpisodeRecord.extra`` (default: none)."""
        return {}


# -------------------------------------------------------------------- registries
_SCENARIOS: dict[str, Factory] = {}
#: Registered scenarios left out of runs that name none (`register_scenario(..., in_default_runs=False)`).
_OPTIONAL_SCENARIOS: set[str] = set()
_METHODS: dict[str, list[Factory]] = {}
#: ("scenario" or "method", name) -> why it is not registered here (`register_unavailable`).
_UNAVAILABLE: dict[tuple[str, str], str] = {}
_builtins_loaded = False
_builtins_loading = False


def _load_builtins() -> None:
    """Import the built-in modules in `BUILTIN_MODULES` order, so that names register in that order.

    A built-in module still being imported (the caller, or one further up the import
    chain) stops the loading there: it registers its names next, and the modules after
    it are imported by a later call. So whichever module a program imports first, the
    robot's names come before the road's.
    """
    global _builtins_loaded, _builtins_loading
    if _builtins_loaded or _builtins_loading:
        return
    _builtins_loading = True  # the built-in modules register through this function
    try:
        for module in BUILTIN_MODULES:
            loaded = sys.modules.get(module)
            spec = getattr(loaded, "__spec__", None)
            if loaded is not None and getattr(spec, "_initializing", False):
                return
            importlib.import_module(module)
        _builtins_loaded = True
    finally:
        _builtins_loading = False


def _checked_factory(kind: str, name: str, factory: Factory) -> Factory:
    if not isinstance(name, str) or not name.strip() or "," in name:
        raise InputError(f"{kind} name must be a non-empty string without commas, got {name!r}")
    if isinstance(factory, str):
        if not _QUALIFIED_NAME.match(factory):
            raise InputError(f"{kind} factory {factory!r} must be a callable or a 'package.module:qualname' string")
        return factory
    if not callable(factory):
        raise InputError(f"{kind} factory must be callable or a 'module:qualname' string, got {type(factory).__name__}")
    try:
        pickle.dumps(factory)
    except Exception as exc:  # noqa: BLE001 (pickle raises many types)
        raise InputError(
            f"{kind} factory {factory!r} for {name!r} cannot be sent to worker processes ({exc}); register a "
            "module-level function or class, a functools.partial of one, or a 'module:qualname' string"
        ) from None
    return factory


def register_scenario(name: str, factory: Factory, *, in_default_runs: bool = True) -> None:
    """Make the scenario ``name`` available to `run_experiment` and to ``--scenario``.

    Parameters
    ----------
    name
        The scenario's name in records, tables and on the command line.
    factory
        ``factory() -> Scenario``: a picklable callable or ``"module:qualname"``.
    in_default_runs
        Whether a run that names no scenario (``minimaxplan experiment`` without
        ``--scenario``, ``minimaxplan demo``) includes it (`default_scenario_names`);
        False for scenarios that only some methods drive (the highway-env worlds).

    Raises
    ------
    InputError
        If ``name`` is taken by another factory, or ``factory`` cannot reach a worker.
    """
    _load_builtins()
    factory = _checked_factory("scenario", name, factory)
    known = _SCENARIOS.get(name)
    if known is not None and known is not factory and known != factory:
        raise InputError(f"scenario {name!r} is already registered (factory {known!r})")
    _SCENARIOS[name] = factory
    if in_default_runs:
        _OPTIONAL_SCENARIOS.discard(name)
    else:
        _OPTIONAL_SCENARIOS.add(name)


def register_method(name: str, factory: Factory) -> None:
    """Make the method ``name`` available to `run_experiment` and to ``--methods``.

    Parameters
    ----------
    name
        The method's name in records, tables and on the command line.
    factory
        ``factory(scenario, config) -> Method``, raising `UnsupportedScenario` for a
        scenario it does not support: a picklable callable or ``"module:qualname"``.
        Registering a second factory under a name already known adds it; the newest
        factory that supports a scenario is used for it.

    Raises
    ------
    InputError
        If ``factory`` cannot reach a worker.
    """
    _load_builtins()
    factory = _checked_factory("method", name, factory)
    factories = _METHODS.setdefault(name, [])
    if not any(known is factory or known == factory for known in factories):
        factories.append(factory)


def register_unavailable(kind: str, name: str, reason: str) -> None:
    """Say why the scenario or method ``name`` is not registered in this installation.

    A module whose names need an optional extra calls it when the extra is missing, so
    that asking for such a name raises `UnknownScenario` or `UnknownMethod` with the
    reason (e.g. the extra to install) after the list of the registered names. It
    registers nothing: `scenario_names` and `method_names` do not list ``name``.

    Parameters
    ----------
    kind : {"scenario", "method"}
        Which registry the name belongs to.
    name : str
        The name, as it would be registered.
    reason : str
        One clause, e.g. ``"it needs highway-env: pip install 'minimaxplan[vehicle]'"``.

    Raises
    ------
    InputError
        If ``kind`` is neither, or ``name`` or ``reason`` is not a non-empty string.
    """
    if kind not in ("scenario", "method"):
        raise InputError(f"kind must be 'scenario' or 'method', got {kind!r}")
    for label, value in (("name", name), ("reason", reason)):
        if not isinstance(value, str) or not value.strip():
            raise InputError(f"{label} must be a non-empty string, got {value!r}")
    _UNAVAILABLE[(kind, name)] = reason


def _unknown(kind: str, name: str, known: list[str]) -> str:
    message = f"{kind} must be one of the registered {kind}s {known}, got {name!r}"
    reason = _UNAVAILABLE.get((kind, name))
    return message if reason is None else f"{message} ({name!r} is not available: {reason})"


def scenario_names() -> list[str]:
    """The registered scenario names, in registration order."""
    _load_builtins()
    return list(_SCENARIOS)


def default_scenario_names() -> list[str]:
    """The scenarios of a run that names none: those registered with ``in_default_runs`` (in order)."""
    _load_builtins()
    return [name for name in _SCENARIOS if name not in _OPTIONAL_SCENARIOS]


def method_names() -> list[str]:
    """The registered method names, in registration order."""
    _load_builtins()
    return list(_METHODS)


def resolve(factory: Factory) -> Callable[..., Any]:
    """The callable a factory names (``"module:qualname"`` imported, a callable as is).

    Parameters
    ----------
    factory : Factory
        A callable, or a ``"package.module:qualname"`` string.

    Raises
    ------
    InputError
        If the string's module or name cannot be imported.
    """
    if not isinstance(factory, str):
        return factory
    module_name, qualname = factory.split(":")
    try:
        target: Any = importlib.import_module(module_name)
        for part in qualname.split("."):
            target = getattr(target, part)
    except (ImportError, AttributeError) as exc:
        raise InputError(f"factory {factory!r} cannot be imported: {exc}") from None
    return target


def scenario_factory(name: str) -> Factory:
    """The factory registered for scenario ``name``.

    Parameters
    ----------
    name : str
        A registered scenario name (`scenario_names`).

    Raises
    ------
    UnknownScenario
        If none is (the message names the registered scenarios).
    """
    _load_builtins()
    if name not in _SCENARIOS:
        raise UnknownScenario(_unknown("scenario", name, list(_SCENARIOS)))
    return _SCENARIOS[name]


def method_factory(name: str, scenario: Scenario, config: Any) -> Factory:
    """The newest factory registered for method ``name`` that supports ``scenario``.

    Each candidate is called once, ``factory(scenario, config)``, to find out.

    Parameters
    ----------
    name : str
        A registered method name (`method_names`).
    scenario : Scenario
        The scenario instance the method must drive.
    config : LoopConfig
        The loop settings passed to each candidate factory.

    Raises
    ------
    UnknownMethod
        If no method is registered as ``name`` (the message names the registered ones).
    UnsupportedScenario
        If every factory of that name rejects ``scenario``.
    """
    _load_builtins()
    if name not in _METHODS:
        raise UnknownMethod(_unknown("method", name, list(_METHODS)))
    reasons = []
    for factory in reversed(_METHODS[name]):
        try:
            resolve(factory)(scenario, config)
        except UnsupportedScenario as exc:
            reasons.append(str(exc))
            continue
        return factory
    raise UnsupportedScenario(
        f"method {name!r} supports no scenario of type {type(scenario).__name__}: " + "; ".join(reasons)
    )
