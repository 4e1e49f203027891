"""The episode loop, written once for every scenario and method (the paper's Figure 1).

measure -> the method decides on the measurement -> its policy runs for one decision
period, sub-step by sub-step, the world stepping and the method observing each
transition -> measure ... until the world is done, the method gives up
(`EpisodeFailure`) or ``LoopConfig.max_decisions`` is reached.

The guarantee is checked here, at run time: after every sub-step of every executed
decision of a `PredictingPolicy`, each true state of the `GroundTruthWorld` must lie in
the box predicted for it (exact float comparison). The record counts ``boxes_checked``
and ``boxes_missed`` and keeps, in ``extra["runtime_check"]``, the counts per kind and
where each miss happened.

The scenario and the method come from the registries (`minimaxplan.analysis.registry`);
a job sent to a worker process carries both factories (`EpisodeJob`), so that every
episode is a pure function of ``(scenario, method, seed, config)`` wherever it runs.
"""

from __future__ import annotations

import time as wallclock
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from minimaxplan.models import DimensionError, InputError
from minimaxplan.models.validation import as_choice, as_count, as_discount, as_positive_scalar, check_instance

from .registry import (
    CrowdedWorld,
    EpisodeFailure,
    Factory,
    GroundTruthWorld,
    PredictingPolicy,
    TracedWorld,
    Transition,
    box_kind,
    method_factory,
    resolve,
    scenario_factory,
)

__all__ = [
    "LoopConfig",
    "DEFAULT_CONFIG",
    "EpisodeRecord",
    "EpisodeJob",
    "BoxCheck",
    "MAX_RECORDED_MISSES",
    "make_job",
    "run_job",
    "run_episode",
]

#: Misses recorded in detail per episode (all of them are counted).
MAX_RECORDED_MISSES = 100


#: The values of `LoopConfig.measurement` (the measurement models of the robot worlds,
#: `minimaxplan.scenarios.worlds.MEASUREMENT_MODELS`).
MEASUREMENT_MODELS = ("uniform", "gaussian")


@dataclass(frozen=True)
class LoopConfig:
    """Settings of the closed loop (the paper's K = 100 and gamma = 0.9 by default).

    The loop itself reads ``gamma`` (the discounted return) and ``max_decisions``; the
    scenario reads ``measurement``; the other settings are the methods'.

    Attributes
    ----------
    budget, gamma
        Planner expansions per decision and discount.
    speed
        Speed of the diagonal velocity references, m/s.
    gain
        Velocity feedback gain k of the low-level controllers, 1/s.
    prior_samples
        None: learn online from the episode's own transitions. N: learn only from N
        transitions of excitation data recorded beforehand (same robot, random
        controls from rest), then keep the parameter sets fixed: the Figure 6 study.
    max_decisions
        Stop after this many decisions (outcome "horizon" if still running).
    measurement
        "uniform" (bounded, inside the guarantees) or "gaussian" (outside).
    lsq_regularisation
        Ridge parameter of the nominal method's least-squares estimate.
    lookahead, path_clearance
        The waypoint chased is ``lookahead`` m along the global path, which keeps
        ``robot_radius + path_clearance`` m from the static discs.
    directions
        One velocity direction per discrete action.
    """

    budget: int = 100
    gamma: float = 0.9
    speed: float = 1.5
    gain: float = 3.0
    prior_samples: int | None = None
    max_decisions: int | None = None
    measurement: str = "uniform"
    lsq_regularisation: float = 1e-3
    lookahead: float = 3.0
    path_clearance: float = 0.3
    directions: tuple = field(default=((1, 1), (1, -1), (-1, 1), (-1, -1), (0, 0)))

    def __post_init__(self) -> None:
        as_count("budget", self.budget)
        as_discount("gamma", self.gamma)
        for name in ("speed", "gain", "lsq_regularisation", "lookahead"):
            as_positive_scalar(name, getattr(self, name))
        as_positive_scalar("path_clearance", self.path_clearance, allow_zero=True)
        for name in ("prior_samples", "max_decisions"):
            value = getattr(self, name)
            if value is not None:
                as_count(name, value)
        as_choice("measurement", self.measurement, MEASUREMENT_MODELS)
        if not self.directions or any(np.shape(d) != (2,) for d in self.directions):
            raise InputError(f"directions must be a non-empty sequence of 2-vectors, got {self.directions!r}")


DEFAULT_CONFIG = LoopConfig()

#: The fields of an `EpisodeRecord` that its CSV row leaves out.
_NOT_IN_ROW = ("trajectory", "extra", "trace")


@dataclass(frozen=True)
class EpisodeRecord:
    """The outcome of one episode.

    ``outcome`` is the world's final outcome ("goal", "collision", "timeout", ...), the
    `EpisodeFailure` outcome of the method (e.g. "no_consistent_model"), or "horizon"
    (stopped after ``LoopConfig.max_decisions``); only "goal" is a success.
    ``time_s`` is the simulated time at the end of the episode.

    ``trajectory`` holds the robot's true position after every sub-step (row 0 the
    start). ``extra`` holds the method's `Method.report` (the robust method's
    ``plans`` and per-decision ``decisions``) and the world's setup (``world``).
    ``boxes_checked`` and ``boxes_missed`` count the predicted boxes checked against the
    true states after the sub-steps of the executed decisions, and the misses (`BoxCheck`;
    0 and 0 for a method that predicts nothing); ``extra["runtime_check"]`` holds the
    same per kind and the misses' details (`BoxCheck.to_dict`; absent when no policy of
    the episode predicted boxes).
    ``trace`` is what the plots and the animation read (`minimaxplan.analysis.plots`):
    ``dt`` (s), the true ``states`` and the pedestrians' true positions (m, robot
    worlds) after every sub-step, and the sub-step index of every decision
    (``decision_steps``). Neither ``trajectory``, ``trace`` nor ``extra`` (but its
    Assumption 4 report) enters `row`.

    Attributes
    ----------
    scenario, method : str
        The registered names of the scenario and of the method.
    seed : int
        The episode's seed.
    outcome : str
        How the episode ended (see above).
    time_s : float
        Simulated time at the end of the episode, s.
    discounted_return : float
        ``sum_i gamma^i r_i`` over the decisions, ``r_i`` the smallest true reward over
        the sub-steps of decision i.
    decisions : int
        Decisions taken.
    wall_time_s : float
        Wall-clock time of the whole job (building the scenario and method included), s.
    boxes_checked, boxes_missed : int
        Predicted boxes checked against the true states, and the misses among them.
    trajectory : tuple of tuple of float
        The agent's true position (`World.position`) at the start and after every
        sub-step, rounded to 4 decimals.
    extra : dict
        The method's report, the world's setup and the run-time check (see above).
    trace : dict
        ``dt``, ``states``, ``pedestrians`` and ``decision_steps`` (see above).
    """

    scenario: str
    method: str
    seed: int
    outcome: str
    time_s: float
    discounted_return: float
    decisions: int
    wall_time_s: float
    boxes_checked: int = 0
    boxes_missed: int = 0
    trajectory: tuple = field(default=(), repr=False)
    extra: dict = field(default_factory=dict, repr=False)
    trace: dict = field(default_factory=dict, repr=False)

    @property
    def success(self) -> bool:
        """True iff the outcome is "goal"."""
        return self.outcome == "goal"

    def row(self) -> dict:
        """The flat CSV row (no trajectory)."""
        data = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in _NOT_IN_ROW}
        data["success"] = self.success
        # The Assumption 4 report of the robust method (once per episode), empty otherwise.
        lmi = self.extra.get("lmi") or {}
        data["assumption4_full_model"] = lmi.get("full_model", "")
        data["assumption4_velocity_subsystem"] = lmi.get("velocity_subsystem", "")
        return data


@dataclass(frozen=True)
class EpisodeJob:
    """One episode to run, with the factories that build its scenario and method.

    Picklable: it is what a worker process of the pool or of Dask receives.

    Attributes
    ----------
    scenario, method : str
        The registered names of the scenario and of the method.
    seed : int
        The episode's seed (>= 0).
    config : LoopConfig
        The loop settings.
    scenario_factory : Factory
        ``factory() -> Scenario``, as registered (`scenario_factory`).
    method_factory : Factory
        ``factory(scenario, config) -> Method``: the one registered under ``method`` that
        supports the scenario (`method_factory`).
    """

    scenario: str
    method: str
    seed: int
    config: LoopConfig
    scenario_factory: Factory
    method_factory: Factory

    @property
    def key(self) -> tuple[str, str, int]:
        """``(scenario, method, seed)``: what identifies the job's record."""
        return (self.scenario, self.method, self.seed)


class BoxCheck:
    """The run-time check of one episode: true states against the policies' predicted boxes.

    `run_job` calls `check` after every sub-step of every decision of a
    `PredictingPolicy`. A box ``(lower, upper)`` predicted for ``name`` is *checked*
    when the world's true state of ``name`` is read against it, and *missed* unless
    ``lower <= state <= upper`` in every coordinate, compared exactly in floating point
    (no tolerance: sound boxes are rounded outward; a NaN anywhere is a miss).

    Attributes
    ----------
    active : bool
        Whether `check` was called (some decision's policy predicted boxes).
    checked, missed : int
        Boxes checked and missed so far.
    by_kind : dict
        ``kind -> {"checked": n, "missed": n}`` (`box_kind` of the names).
    misses : list of dict
        The first `MAX_RECORDED_MISSES` misses: ``decision`` (0-based), ``substep``
        (1-based), ``time`` (s, the world's, after the sub-step), ``name``, ``excess``
        (the largest distance by which a coordinate is outside its interval, in the
        state's units; NaN if a value is NaN), ``coordinates`` (those outside) and the
        ``state``, ``lower`` and ``upper`` compared.
    """

    def __init__(self) -> None:
        self.active = False
        self.checked = 0
        self.missed = 0
        self.by_kind: dict[str, dict[str, int]] = {}
        self.misses: list[dict] = []

    def check(
        self,
        boxes: Mapping[str, tuple[Any, Any]],
        truth: Mapping[str, Any],
        *,
        decision: int,
        substep: int,
        time: float,
    ) -> None:
        """Check every box of ``boxes`` against the state of the same name in ``truth``.

        Parameters
        ----------
        boxes : Mapping of str to (array_like, array_like)
            ``name -> (lower, upper)`` as `PredictingPolicy.predicted_boxes` returns it.
        truth : Mapping of str to array_like
            ``name -> state`` as `GroundTruthWorld.true_states` returns it.
        decision, substep : int
            Where in the episode (recorded with a miss).
        time : float
            The world's time after the sub-step, s (recorded with a miss).

        Raises
        ------
        InputError
            If a box is predicted for a name the world does not know.
        DimensionError
            If a box's corners and the true state differ in shape.
        """
        self.active = True
        compared = []  # every box validated before any is counted
        for name, (lower, upper) in boxes.items():
            if name not in truth:
                raise InputError(
                    f"the policy predicted a box for {name!r}, but the world's true_states() has no such name "
                    f"(it has {sorted(truth)})"
                )
            state = np.asarray(truth[name], dtype=float)
            lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
            if lo.shape != state.shape or hi.shape != state.shape:
                raise DimensionError(
                    f"the box predicted for {name!r} has corners of shapes {lo.shape} and {hi.shape}, "
                    f"but its true state has shape {state.shape}"
                )
            compared.append((name, state, lo, hi))
        for name, state, lo, hi in compared:
            counts = self.by_kind.setdefault(box_kind(name), {"checked": 0, "missed": 0})
            self.checked += 1
            counts["checked"] += 1
            if bool(np.all(lo <= state) and np.all(state <= hi)):
                continue
            self.missed += 1
            counts["missed"] += 1
            if len(self.misses) < MAX_RECORDED_MISSES:
                outside = np.maximum(lo - state, state - hi)
                bad = ~((lo <= state) & (state <= hi))
                self.misses.append(
                    {
                        "decision": int(decision),
                        "substep": int(substep),
                        "time": float(time),
                        "name": name,
                        "excess": float(np.max(outside)) if not np.isnan(outside).any() else float("nan"),
                        "coordinates": np.flatnonzero(bad).tolist(),
                        "state": state.tolist(),
                        "lower": lo.tolist(),
                        "upper": hi.tolist(),
                    }
                )

    def to_dict(self) -> dict:
        """``boxes_checked``, ``boxes_missed``, ``by_kind`` and ``misses``, as plain data."""
        return {
            "boxes_checked": self.checked,
            "boxes_missed": self.missed,
            "by_kind": {kind: dict(counts) for kind, counts in sorted(self.by_kind.items())},
            "misses": list(self.misses),
        }


class _Trace:
    """What the plots and the animation read of an episode, recorded by the loop only.

    Reading the world's true state and the pedestrians' positions draws no random
    number and changes nothing, so the records stay those of an untraced loop.
    """

    def __init__(self, world: Any):
        self.states: list[list[float]] = []
        self.pedestrians: list[list[list[float]]] = []
        self.decision_steps: list[int] = []
        self._traced = isinstance(world, TracedWorld)
        self._crowded = isinstance(world, CrowdedWorld)
        self.stepped(world)

    def decided(self, world: Any) -> None:
        self.decision_steps.append(int(world.step_index) if self._traced else len(self.decision_steps))

    def stepped(self, world: Any) -> None:
        if self._traced:
            self.states.append(np.round(np.asarray(world.state, dtype=float), 4).tolist())
        if self._crowded:
            self.pedestrians.append(np.round(np.asarray(world.crowd.positions, dtype=float), 4).tolist())

    def to_dict(self, world: Any) -> dict:
        return {
            "dt": float(world.params.dt) if self._traced else 1.0,
            "states": self.states,
            "pedestrians": self.pedestrians,
            "decision_steps": self.decision_steps,
        }


def run_job(job: EpisodeJob) -> EpisodeRecord:
    """Run ``job`` (in whichever process receives it); see `run_episode`.

    Parameters
    ----------
    job : EpisodeJob
        The episode to run: its factories build the scenario and the method here.

    Returns
    -------
    EpisodeRecord
        The outcome of the episode.
    """
    started = wallclock.perf_counter()
    scenario = resolve(job.scenario_factory)()
    world = scenario.make_world(job.seed, job.config)
    method = resolve(job.method_factory)(scenario, job.config)
    method.start(world)
    x = world.measure()
    rewards: list[float] = []
    positions = [np.array(world.position, dtype=float)]
    trace = _Trace(world)
    boxes = BoxCheck()
    outcome = None
    while not world.done:
        if job.config.max_decisions is not None and len(rewards) >= job.config.max_decisions:
            outcome = "horizon"
            break
        try:
            policy = method.decide(x)
        except EpisodeFailure as failure:
            outcome = failure.outcome  # a failure of the episode, not an error of the run
            break
        trace.decided(world)
        predicting = isinstance(policy, PredictingPolicy)
        if predicting and not isinstance(world, GroundTruthWorld):
            raise InputError(
                f"the policy of method {job.method!r} predicts boxes, but the world of scenario {job.scenario!r} "
                f"({type(world).__name__}) has no true_states() to check them against"
            )
        worst = 1.0
        for substep in range(1, world.substeps + 1):
            u = policy.control(x)
            world.apply(u)
            if predicting:
                boxes.check(
                    policy.predicted_boxes(substep),
                    world.true_states(),
                    decision=len(rewards),
                    substep=substep,
                    time=float(world.time),
                )
            positions.append(np.array(world.position, dtype=float))
            trace.stepped(world)
            worst = min(worst, world.reward())
            x_next = world.measure()
            method.observe(Transition(x, u, x_next))
            x = x_next
            if world.done:
                break
        rewards.append(worst)
    outcome = outcome or world.outcome
    discounted = float(sum(job.config.gamma**i * r for i, r in enumerate(rewards)))
    return EpisodeRecord(
        scenario=job.scenario,
        method=job.method,
        seed=int(job.seed),
        outcome=outcome,
        time_s=float(world.time),
        discounted_return=discounted,
        decisions=len(rewards),
        wall_time_s=wallclock.perf_counter() - started,
        boxes_checked=boxes.checked,
        boxes_missed=boxes.missed,
        trajectory=tuple(map(tuple, np.round(positions, 4).tolist())),
        extra={
            **method.report(),
            "world": world.to_dict(),
            **({"runtime_check": boxes.to_dict()} if boxes.active else {}),
        },
        trace=trace.to_dict(world),
    )


def make_job(
    scenario: str, method: str, seed: int, config: LoopConfig = DEFAULT_CONFIG, *, built: Any = None
) -> EpisodeJob:
    """The job of episode ``seed`` of ``method`` in ``scenario`` (names looked up in the registries).

    ``built`` may pass the scenario instance already made from its factory.

    Parameters
    ----------
    scenario, method : str
        Registered names of the scenario and of the method.
    seed : int
        The episode's seed (>= 0).
    config : LoopConfig
        The loop settings.
    built : Scenario, optional
        The scenario already made from its factory (default: make it here, to find the
        method's factory that supports it).

    Raises
    ------
    UnknownScenario, UnknownMethod, UnsupportedScenario
        If a name is not registered or the method does not support the scenario.
    InputError
        If ``config`` is not a `LoopConfig` or ``seed`` not a non-negative integer.
    """
    check_instance("config", config, LoopConfig)
    as_count("seed", seed, minimum=0)
    world_factory = scenario_factory(scenario)
    instance = built if built is not None else resolve(world_factory)()
    return EpisodeJob(scenario, method, int(seed), config, world_factory, method_factory(method, instance, config))


def run_episode(scenario: str, method: str, seed: int, config: LoopConfig = DEFAULT_CONFIG) -> EpisodeRecord:
    """Run one seeded episode of the registered ``method`` in the registered ``scenario``.

    The discounted return is ``sum_i gamma^i r_i`` over the decisions, ``r_i`` the
    smallest true reward over the sub-steps of decision i.

    Parameters
    ----------
    scenario, method : str
        Registered names of the scenario and of the method.
    seed : int
        The episode's seed (>= 0).
    config : LoopConfig
        The loop settings.

    Returns
    -------
    EpisodeRecord
        The outcome of the episode.

    Raises
    ------
    UnknownScenario, UnknownMethod, UnsupportedScenario
        If a name is not registered or the method does not support the scenario.
    """
    return run_job(make_job(scenario, method, seed, config))
