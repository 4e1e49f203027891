"""Figure 6 for driving: the robust planner's suboptimality against N, with its models frozen.

For each N and each world seed, the road world (``highway`` or ``tjunction``) first runs
a *warm-up* of N sub-steps in which the ego holds one fixed controller, its IDLE
action's controllers (`EgoSetup`: the speed level nearest to its initial speed, its
initial lane; `warm_up`). The warm-up's N + 1 measurements, i.e. N transitions of every
vehicle in view throughout, are fed to the robust method's `TrafficLearner`, whose
beliefs are then *frozen* (`FrozenRobustMethod`: no new parameter box and no route
elimination; what stays valid without data is kept: the theta boxes, and the surviving
routes at the T-junction; a vehicle first seen later gets the prior theta boxes). On the
highway the lane a vehicle steers to is a switching intention, a state rather than a
model: it is tracked from the measurements as the live learner tracks it (see
`FrozenLearner`). The robust
method then drives H decisions; the oracle (`RoadOracleMethod`: the true parameters and
intentions) drives the same world from the same warm-up state. Both episodes are run by
`minimaxplan.analysis.episode.run_job`, so that the world's dynamics and noise streams,
seeded by the world, are the same for both, and the robust method's predicted boxes are
checked at every sub-step (``boxes_checked``, ``boxes_missed``).

Suboptimality is the oracle's discounted return minus the robust one's over the H
decisions (``r_i`` the smallest true reward over the sub-steps of decision i, as in
`minimaxplan.analysis.suboptimality`); the achieved velocity of a method is its ego's
mean true speed over the sub-steps of the episode, averaged over the episodes. An
episode whose world ended during the warm-up (the ego never acted) is counted under
``warmup_ended`` and left out of both.
"""

from __future__ import annotations

import functools
import pathlib
import time
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from minimaxplan.kernels.bicycle import ego_control
from minimaxplan.models.errors import InputError
from minimaxplan.models.validation import as_count, check_instance
from minimaxplan.scenarios.road_world import ROAD_WORLD_KINDS, Observation, RoadWorld
from minimaxplan.scenarios.traffic_models import VehicleBelief, prior_belief

from . import experiment
from .episode import DEFAULT_CONFIG, EpisodeJob, EpisodeRecord, LoopConfig
from .figures import pyplot, save_png
from .road_planning import EgoSetup, RoadOracleMethod, RoadRobustMethod
from .road_scenario import DrivingWorld, RoadScenario
from .suboptimality import draw_suboptimality, fit_trend
from .traffic_learning import TrafficLearner

__all__ = [
    "ROAD_DEFAULT_SAMPLES",
    "ROAD_DEFAULT_EPISODES",
    "ROAD_DEFAULT_HORIZON",
    "WARMUP_ACTION",
    "ROAD_FAILURES",
    "warm_up",
    "WarmedDrivingWorld",
    "WarmedRoadScenario",
    "FrozenLearner",
    "FrozenRobustMethod",
    "road_suboptimality_study",
    "plot_road_study",
    "road_markdown",
]

#: The values of N of the default road study.
ROAD_DEFAULT_SAMPLES = (1, 2, 5, 10, 20, 50)
#: Episodes per N of the default road study.
ROAD_DEFAULT_EPISODES = 10
#: Decisions per episode of the default road study (5 s at 0.5 s per decision).
ROAD_DEFAULT_HORIZON = 10
#: The ego's action held during the warm-up (at its initial speed level and lane).
WARMUP_ACTION = "IDLE"
#: The outcomes that are failures on the road (the issue's: any collision of the ego,
#: or leaving the road).
ROAD_FAILURES = ("collision", "off_road")


def warm_up(world: DrivingWorld, substeps: int) -> tuple[Observation, ...]:
    """Drive the ego with its IDLE controllers for ``substeps`` sub-steps; the measurements.

    Parameters
    ----------
    world : DrivingWorld
        A fresh episode (it is advanced in place).
    substeps : int
        N (>= 1).

    Returns
    -------
    tuple of Observation
        The measurement before the first sub-step and after each one: N + 1 of them,
        fewer if the world ends first (its outcome is then the world's).

    Notes
    -----
    The ego's controllers are `EgoSetup`'s at the speed level nearest to its initial
    speed and its initial lane, held (`WARMUP_ACTION`), and read the ego's measured
    state (exact, as the planners' policies do).
    """
    check_instance("world", world, DrivingWorld)
    substeps = as_count("substeps", substeps)
    ego = EgoSetup(world.world)
    level, lane = ego.level, ego.lane
    observations = [world.measure()]
    for _ in range(substeps):
        if world.done:
            break
        control, lane = ego_control(ego.controller, observations[-1].ego, level, lane)
        world.apply(control)
        observations.append(world.measure())
    return tuple(observations)


class WarmedDrivingWorld(DrivingWorld):
    """A `DrivingWorld` after its warm-up (`warm_up`), which it keeps for the learner.

    Parameters
    ----------
    world : RoadWorld
        A fresh world with an ego.
    warmup : int
        N, the warm-up's sub-steps (>= 1).

    Attributes
    ----------
    warmup_observations : tuple of Observation
        The warm-up's measurements (N + 1, fewer if the world ended during it).
    warmup_substeps : int
        The sub-steps the warm-up ran.
    warmup_outcome : str
        The world's outcome after it ("running" unless it ended the episode).
    """

    def __init__(self, world: RoadWorld, warmup: int) -> None:
        super().__init__(world)
        self.warmup_observations = warm_up(self, warmup)
        self.warmup_substeps = len(self.warmup_observations) - 1
        self.warmup_outcome = str(world.outcome)
        self._warmup_ego = np.array(world.ego_state, dtype=float)
        self._warmup_step = int(world.step_index)

    def to_dict(self) -> dict:
        """`DrivingWorld.to_dict` with ``warmup``: its sub-steps, outcome and the ego's state after it."""
        return {
            **super().to_dict(),
            "warmup": {
                "substeps": self.warmup_substeps,
                "outcome": self.warmup_outcome,
                "ego_state": self._warmup_ego.tolist(),
                "step_index": self._warmup_step,
            },
        }


class WarmedRoadScenario(RoadScenario):
    """A road scenario whose worlds start after an N-sub-step warm-up (`WarmedDrivingWorld`).

    Parameters
    ----------
    kind : str
        One of `ROAD_WORLD_KINDS`.
    warmup : int
        N (>= 1).
    """

    def __init__(self, kind: str, warmup: int) -> None:
        super().__init__(kind)
        self.warmup = as_count("warmup", warmup)

    def __repr__(self) -> str:
        return f"WarmedRoadScenario({self.kind!r}, warmup={self.warmup})"

    def make_world(self, seed: int, config: LoopConfig) -> WarmedDrivingWorld:
        """The seeded world of `RoadScenario.make_world`, warmed up for N sub-steps.

        Parameters
        ----------
        seed : int
            The episode's seed.
        config : LoopConfig
            The loop settings (``measurement`` must be "uniform").
        """
        return WarmedDrivingWorld(super().make_world(seed, config).world, self.warmup)


class FrozenLearner:
    """A `TrafficLearner` after the warm-up: its parameter boxes and routes fixed, the highway's lanes in force tracked.

    Parameters
    ----------
    learner : TrafficLearner
        The learner fed the warm-up's measurements.

    Attributes
    ----------
    learner : TrafficLearner
        The wrapped learner (fed again on the highway only, for the lanes in force).
    frozen : dict of int to VehicleBelief
        Its beliefs at the last warm-up sub-step (`TrafficLearner.beliefs`).
    frozen_step : int
        The learner's sub-step when frozen.

    Notes
    -----
    What stays valid without more data: the boxes ``theta_a`` and ``theta_b`` (theta is
    constant and each box contains it), and at the T-junction the surviving routes
    (routes never switch, and elimination never removes the true one). What does not:
    the lanes a vehicle may be steering to *now*. They move along its route, and on the
    highway a lane change may start at any sub-step after the freeze.

    * At the T-junction `beliefs` places each frozen belief on the current measurement
      with `prior_belief`'s geometry: its routes are the frozen survivors through one of
      the prior's lanes (those whose strip holds the measured centre), its lanes those of
      the prior on them (the prior's, if none is: never the case for a sound belief).
    * On the highway the wrapped learner keeps being fed every measurement (`see`) and
      `beliefs` takes each vehicle's lanes and routes from it (`TrafficLearner.beliefs`)
      with the frozen theta boxes (the prior's for a vehicle first seen after the
      freeze). This learns nothing about the model: the learner's lane verdicts test
      the data since each lane's last possible switch against the *prior* theta_b box
      (an intention in force is refuted by its own transitions, whatever the learned
      boxes), so they are what a tracker of the switching intention would say. Without
      it, every neighbour beside the ego could always be already changing into its lane
      (an intention in force, which no gap rule constrains): Figure 6's seed 9 collided
      at N = 1 and N = 5 on those boxes, every plan possibly colliding within three
      decisions. Freezing the highway's survivors as they were made the run-time check
      miss lane-changing vehicles (65 of 1600 boxes, seeds 0-1, N = 10), as it should.

    A vehicle first seen after the freeze at the T-junction gets the prior belief
    (`forecast_traffic`'s default for a vehicle without one).
    """

    def __init__(self, learner: TrafficLearner) -> None:
        check_instance("learner", learner, TrafficLearner)
        self.learner = learner
        self.frozen: dict[int, VehicleBelief] = dict(learner.beliefs())
        self.frozen_step = int(learner.step)
        self.current: Observation | None = None
        self.tracks_lanes = learner.kind == "highway"

    def see(self, observation: Observation) -> None:
        """Record the current measurement, on which `beliefs` places the frozen beliefs (no model is learned).

        On the highway the wrapped learner is fed it too, for the lanes in force only
        (see the Notes), if it is of a sub-step after the last one learned from (the
        episode's first measurement re-measures the warm-up's last sub-step, and a
        decision's measurement is its last sub-step's).

        Parameters
        ----------
        observation : Observation
            The measurement of a sub-step after the freeze.
        """
        check_instance("observation", observation, Observation)
        if self.tracks_lanes and int(round(observation.time / self.learner.dt)) > self.learner.step:
            self.learner.observe(observation)
        self.current = observation

    def beliefs(self) -> dict[int, VehicleBelief]:
        """The frozen beliefs of the vehicles in the current measurement, placed on it (see the Notes).

        Before any `see`, the frozen beliefs as they were made.
        """
        if self.current is None:
            return dict(self.frozen)
        road, scenario = self.learner.road, self.learner.scenario
        if self.tracks_lanes:
            live = self.learner.beliefs()
            prior_a, prior_b = self.learner.prior_a, self.learner.prior_b
            tracked = {}
            for agent, live_belief in live.items():
                made = self.frozen.get(agent)
                theta_a, theta_b = (made.theta_a, made.theta_b) if made is not None else (prior_a, prior_b)
                tracked[agent] = replace(live_belief, theta_a=theta_a, theta_b=theta_b)
            return tracked
        out = {}
        for row, agent in enumerate(np.asarray(self.current.ids, dtype=int)):
            belief = self.frozen.get(int(agent))
            if belief is None:
                continue
            prior = prior_belief(int(agent), self.current.vehicles[row], road, scenario)
            lanes, routes = prior.lanes, prior.routes
            if self.learner.kind == "tjunction":
                kept = tuple(r for r in belief.routes if set(r) & set(prior.lanes))
                on_them = tuple(lane for lane in prior.lanes if any(lane in r for r in kept))
                if kept and on_them:
                    lanes, routes = on_them, kept
            out[int(agent)] = replace(belief, lanes=lanes, routes=routes)
        return out

    def observe(self, observation: Observation) -> None:
        """Refuse: a frozen learner takes no more data to learn from (`see` is for the lanes in force).

        Parameters
        ----------
        observation : Observation
            A measurement (refused).

        Raises
        ------
        InputError
            Always.
        """
        raise InputError("the learner is frozen after the warm-up: it takes no more observations")

    @property
    def eliminations(self) -> list:
        """The wrapped learner's eliminations (after the warm-up, only the highway's lane verdicts)."""
        return self.learner.eliminations

    @property
    def lp_solves(self) -> int:
        """The wrapped learner's LP solves (after the warm-up, only on the highway)."""
        return self.learner.lp_solves

    @property
    def solver_failures(self) -> int:
        """The wrapped learner's HiGHS failures (after the warm-up, only on the highway)."""
        return self.learner.solver_failures


class FrozenRobustMethod(RoadRobustMethod):
    """The road robust method whose learner sees only the warm-up, then is frozen.

    Parameters
    ----------
    scenario
        A `RoadScenario` (its worlds must be `WarmedDrivingWorld`).
    config
        The loop settings (``budget``, ``gamma``).

    Notes
    -----
    `start` feeds the learner the world's warm-up measurements and replaces it by a
    `FrozenLearner`; the measurements of the episode then teach it no model, so every
    decision forecasts the traffic under the warm-up's theta boxes (and T-junction
    routes), placed on the current measured states, with the highway's lanes in force
    tracked from the measurements (`FrozenLearner.beliefs`).
    """

    def start(self, world: DrivingWorld) -> None:
        """Build the ego model, feed the learner the warm-up and freeze it.

        Parameters
        ----------
        world : WarmedDrivingWorld
            The episode after its warm-up.

        Raises
        ------
        InputError
            If ``world`` is not a `WarmedDrivingWorld`.
        """
        check_instance("world", world, WarmedDrivingWorld)
        assert isinstance(world, WarmedDrivingWorld)  # for mypy: checked above
        self._frozen = False
        super().start(world)
        for observation in world.warmup_observations:
            self._learn(observation)
        self.frozen_learner = FrozenLearner(self.learner)
        self.learner = self.frozen_learner  # type: ignore[assignment]  # beliefs() as the robust method reads them
        self._frozen = True

    def _learn(self, observation: Observation) -> None:
        if self._frozen:
            self.frozen_learner.see(observation)  # where the vehicles are now; nothing learned
        else:
            super()._learn(observation)

    def report(self) -> dict:
        """`RoadRobustMethod.report` with the frozen beliefs and the learner's sub-steps at freeze and now."""
        frozen = self.frozen_learner
        return {
            **super().report(),
            "frozen_step": frozen.frozen_step,
            "learner_step": int(frozen.learner.step),
            "frozen_beliefs": [frozen.frozen[a].to_dict() for a in sorted(frozen.frozen)],
        }


# ------------------------------------------------------------------- the study
def _mean_speed(record: EpisodeRecord) -> float | None:
    """The ego's mean true speed over the sub-steps of an episode (None if it has none), m/s."""
    states = record.trace.get("states", [])[1:]
    return float(np.mean([s[2] for s in states])) if states else None


def _mean(values: Sequence[float | None]) -> float | None:
    kept = [v for v in values if v is not None]
    return float(np.mean(kept)) if kept else None


def _jobs(kind: str, n: int, method: str, seeds: Sequence[int], config: LoopConfig) -> list[EpisodeJob]:
    factory = RoadOracleMethod if method == "oracle" else FrozenRobustMethod
    world = functools.partial(WarmedRoadScenario, kind, n)
    return [EpisodeJob(kind, method, int(s), config, world, factory) for s in seeds]


def _row(n: int, robust: Sequence[EpisodeRecord], oracle: Sequence[EpisodeRecord]) -> dict[str, Any]:
    by_seed = {r.seed: r for r in oracle}
    acted = [
        (r, by_seed[r.seed])
        for r in robust
        if r.extra["world"]["warmup"]["outcome"] == "running"
        and by_seed[r.seed].extra["world"]["warmup"]["outcome"] == "running"
    ]
    gaps = [o.discounted_return - r.discounted_return for r, o in acted]
    return {
        "n": n,
        "mean": float(np.mean(gaps)) if gaps else None,
        "max": float(np.max(gaps)) if gaps else None,
        "min": float(np.min(gaps)) if gaps else None,
        "per_episode": gaps,
        "seeds": [r.seed for r, _ in acted],
        "warmup_ended": len(robust) - len(acted),
        "failures": sum(r.outcome in ROAD_FAILURES for r, _ in acted),
        "oracle_failures": sum(o.outcome in ROAD_FAILURES for _, o in acted),
        "outcomes": dict(Counter(r.outcome for r, _ in acted)),
        "oracle_outcomes": dict(Counter(o.outcome for _, o in acted)),
        "robust_speed": _mean([_mean_speed(r) for r, _ in acted]),
        "oracle_speed": _mean([_mean_speed(o) for _, o in acted]),
        "boxes_checked": sum(r.boxes_checked for r, _ in acted),
        "boxes_missed": sum(r.boxes_missed for r, _ in acted),
        "frozen_vehicles": _mean([len(r.extra["frozen_beliefs"]) for r, _ in acted]),
        "wall_time_s": float(sum(r.wall_time_s for r in robust) + sum(o.wall_time_s for o in oracle)),
    }


def road_suboptimality_study(
    kind: str,
    samples: Iterable[int] = ROAD_DEFAULT_SAMPLES,
    *,
    episodes: int = ROAD_DEFAULT_EPISODES,
    seed: int = 0,
    horizon: int = ROAD_DEFAULT_HORIZON,
    workers: int | None = None,
    progress: bool = True,
    config: LoopConfig | None = None,
) -> dict:
    """Run Figure 6 for a road world: the frozen robust planner against the oracle, for each N.

    Parameters
    ----------
    kind : str
        "highway" or "tjunction" (`ROAD_WORLD_KINDS`).
    samples : iterable of int
        The warm-up lengths N, sub-steps (each >= 1).
    episodes : int
        Episodes per N (>= 1), world seeds ``seed .. seed + episodes - 1``.
    seed : int
        World seed of the first episode (>= 0).
    horizon : int
        Decisions per episode after the warm-up (>= 1).
    workers : int, optional
        Local processes (>= 1; default: all cores).
    progress : bool
        Show progress bars.
    config : LoopConfig, optional
        Loop settings (default: `episode.DEFAULT_CONFIG`, K = 100, gamma = 0.9);
        ``max_decisions`` is overridden.

    Returns
    -------
    dict
        ``scenario``, ``episodes``, ``horizon_decisions``, ``seed``, ``warmup`` (the
        controller held), ``rows`` (per N: ``mean``, ``max``, ``min`` and
        ``per_episode`` suboptimality, ``failures`` and ``oracle_failures`` (collisions
        and off-road), ``outcomes``, ``robust_speed`` and ``oracle_speed`` (m/s),
        ``boxes_checked`` and ``boxes_missed`` of the robust episodes, ``warmup_ended``,
        ``frozen_vehicles`` (mean number of vehicles with a learned belief),
        ``wall_time_s``), ``fit`` (`fit_trend` of the means) and ``wall_time_s``.

    Raises
    ------
    InputError
        Before any episode runs, if ``kind`` is not a road world or a value of
        ``samples``, ``episodes``, ``seed``, ``horizon`` or ``workers`` is out of range.

    Notes
    -----
    The trend fitted is the ``log(N) / N`` term of eq. (14) (Theorem 2), as for the robot.
    """
    import os

    if kind not in ROAD_WORLD_KINDS:
        raise InputError(f"kind must be one of {ROAD_WORLD_KINDS}, got {kind!r}")
    if isinstance(samples, (str, bytes)) or not isinstance(samples, Iterable):
        raise InputError(f"samples must be a non-empty sequence of positive integers, got {samples!r}")
    ns = [as_count(f"samples[{i}]", n) for i, n in enumerate(samples)]
    if not ns:
        raise InputError("samples must be a non-empty sequence of positive integers, got none")
    as_count("episodes", episodes)
    as_count("seed", seed, minimum=0)
    horizon = as_count("horizon", horizon)
    workers = (os.cpu_count() or 1) if workers is None else as_count("workers", workers)
    base = replace(DEFAULT_CONFIG if config is None else config, max_decisions=horizon)
    seeds = experiment.episode_seeds(seed, episodes)
    started = time.perf_counter()
    rows = []
    for n in ns:
        jobs = _jobs(kind, n, "robust", seeds, base) + _jobs(kind, n, "oracle", seeds, base)
        records = experiment._run_jobs(jobs, workers, None, progress)  # one pool per N
        rows.append(
            _row(
                n,
                sorted((r for r in records if r.method == "robust"), key=lambda r: r.seed),
                [r for r in records if r.method == "oracle"],
            )
        )
    fitted = [r for r in rows if r["mean"] is not None]
    return {
        "scenario": kind,
        "episodes": episodes,
        "horizon_decisions": horizon,
        "seed": seed,
        "warmup": f"the ego holds {WARMUP_ACTION} (its speed level nearest its initial speed, its initial lane)",
        "rows": rows,
        "fit": fit_trend([r["n"] for r in fitted], [r["mean"] for r in fitted]),
        "wall_time_s": time.perf_counter() - started,
    }


def _fmt(value: float | None, digits: int = 4) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def road_markdown(study: dict) -> str:
    """A road study as a Markdown table, one row per N, and the fitted trend.

    Parameters
    ----------
    study : dict
        A `road_suboptimality_study` result.

    Returns
    -------
    str
        The table (suboptimality, failures of both methods, velocities, the run-time
        check, episodes ended in the warm-up) and the trend line or the warning.
    """
    lines = [
        f"{study['scenario']}: {study['episodes']} episodes per N, {study['horizon_decisions']} decisions after "
        f"a warm-up of N sub-steps in which {study['warmup']}.",
        "",
        "| N | mean suboptimality | max | min | robust failures | oracle failures | robust speed (m/s) "
        "| oracle speed (m/s) | boxes missed / checked | ended in warm-up |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in study["rows"]:
        acted = len(r["per_episode"])
        lines.append(
            f"| {r['n']} | {_fmt(r['mean'])} | {_fmt(r['max'])} | {_fmt(r['min'])} | {r['failures']}/{acted} "
            f"| {r['oracle_failures']}/{acted} | {_fmt(r['robust_speed'], 2)} | {_fmt(r['oracle_speed'], 2)} "
            f"| {r['boxes_missed']}/{r['boxes_checked']} | {r['warmup_ended']} |"
        )
    fit = study["fit"]
    if fit.get("warning") is None:
        lines.append(f"\nTrend fit: suboptimality ~ {fit['a']:.4f} + {fit['b']:.4f} log(N)/N")
    else:
        lines.append(f"\n**Warning: {fit['warning']}.**")
    return "\n".join(lines) + "\n"


def plot_road_study(study: dict, path: str | pathlib.Path) -> pathlib.Path:
    """Plot a road study: suboptimality (mean, max, trend) and the achieved velocities against N.

    Parameters
    ----------
    study : dict
        A `road_suboptimality_study` result.
    path : str or pathlib.Path
        The image file to write (PNG).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    rows = [r for r in study["rows"] if r["mean"] is not None]
    fig, (left, right) = pyplot().subplots(1, 2, figsize=(11, 4))
    draw_suboptimality(left, {**study, "rows": rows})
    left.set_title(f"{study['scenario']}: suboptimality over {study['horizon_decisions']} decisions")
    n = [r["n"] for r in rows]
    right.plot(n, [r["robust_speed"] for r in rows], "o-", label="robust (frozen after N)")
    right.plot(n, [r["oracle_speed"] for r in rows], "s--", label="oracle")
    right.set_xscale("log")
    right.set_xlabel("N, transitions observed before planning")
    right.set_ylabel("mean ego speed, m/s")
    right.set_title(f"Achieved velocity, {study['episodes']} episodes per N")
    right.legend()
    fig.tight_layout()
    return save_png(fig, path)
