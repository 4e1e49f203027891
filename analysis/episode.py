"""The episode loop, written once for every scenario and method (the paper's Figure 1).

measure -> the method decides on the measurement -> its policy runs for one decision
period, sub-step by sub-step, the world stepping and the method observing each
transition -> measure ... until the world is done, the method gives up
(`EpisodeFailure`) or ``LoopConfig.max_decisions`` is reached.

The scenario and the method come from the registries (`minimaxplan.analysis.registry`);
a job sent to a worker process carries both factories (`EpisodeJob`), so that every
episode is a pure function of ``(scenario, method, seed, config)`` wherever it runs.
"""

from __future__ import annotations

import time as wallclock
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from minimaxplan.models import InputError
from minimaxplan.models.validation import as_choice, as_count, as_discount, as_positive_scalar, check_instance

from .registry import EpisodeFailure, Factory, Transition, method_factory, resolve, scenario_factory

__all__ = ["LoopConfig", "DEFAULT_CONFIG", "EpisodeRecord", "EpisodeJob", "make_job", "run_job", "run_episode"]


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
    ``trace`` is what the plots and the animation read (`minimaxplan.analysis.plots`):
    ``dt`` (s), the true ``states`` and the pedestrians' true positions (m, robot
    worlds) after every sub-step, and the sub-step index of every decision
    (``decision_steps``). Neither ``trajectory``, ``trace`` nor ``extra`` (but its
    Assumption 4 report) enters `row`.
    """

    scenario: str
    method: str
    seed: int
    outcome: str
    time_s: float
    discounted_return: float
    decisions: int
    wall_time_s: float
    trajectory: tuple = field(default=(), repr=False)
    extra: dict = field(default_factory=dict, repr=False)
    trace: dict = field(default_factory=dict, repr=False)

    @property
    def success(self) -> bool:
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


class _Trace:
    """What the plots and the animation read of an episode, recorded by the loop only.

    Reading the world's true state and the pedestrians' positions draws no random
    number and changes nothing, so the records stay those of an untraced loop.
    """

    def __init__(self, world: Any):
        self.states: list[list[float]] = []
        self.pedestrians: list[list[list[float]]] = []
        self.decision_steps: list[int] = []
        self.stepped(world)

    def decided(self, world: Any) -> None:
        self.decision_steps.append(int(getattr(world, "step_index", len(self.decision_steps))))

    def stepped(self, world: Any) -> None:
        state = getattr(world, "state", None)
        if state is not None:
            self.states.append(np.round(np.asarray(state, dtype=float), 4).tolist())
        crowd = getattr(world, "crowd", None)
        if crowd is not None:
            self.pedestrians.append(np.round(np.asarray(crowd.positions, dtype=float), 4).tolist())

    def to_dict(self, world: Any) -> dict:
        params = getattr(world, "params", None)
        return {
            "dt": float(getattr(params, "dt", 1.0)),
            "states": self.states,
            "pedestrians": self.pedestrians,
            "decision_steps": self.decision_steps,
        }


def run_job(job: EpisodeJob) -> EpisodeRecord:
    """Run ``job`` (in whichever process receives it); see `run_episode`."""
    started = wallclock.perf_counter()
    scenario = resolve(job.scenario_factory)()
    world = scenario.make_world(job.seed, job.config)
    method = resolve(job.method_factory)(scenario, job.config)
    method.start(world)
    x = world.measure()
    rewards: list[float] = []
    positions = [np.array(world.position, dtype=float)]
    trace = _Trace(world)
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
        worst = 1.0
        for _ in range(world.substeps):
            u = policy.control(x)
            world.apply(u)
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
        trajectory=tuple(map(tuple, np.round(positions, 4).tolist())),
        extra={**method.report(), "world": world.to_dict()},
        trace=trace.to_dict(world),
    )


def make_job(
    scenario: str, method: str, seed: int, config: LoopConfig = DEFAULT_CONFIG, *, built: Any = None
) -> EpisodeJob:
    """The job of episode ``seed`` of ``method`` in ``scenario`` (names looked up in the registries).

    ``built`` may pass the scenario instance already made from its factory.

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

    Raises
    ------
    UnknownScenario, UnknownMethod, UnsupportedScenario
        If a name is not registered or the method does not support the scenario.
    """
    return run_job(make_job(scenario, method, seed, config))
