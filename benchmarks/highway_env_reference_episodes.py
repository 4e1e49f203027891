"""The reference planner built from highway-env's classes as the ego's controller: its failures (issue 12).

The decision-time benchmark (`bench_highway_env_planner.py`) times one decision of
`highway_env_reference_planner.HighwayEnvReferencePlanner` against the library's; it does
not say how the reference *drives*. This script runs it as a method of the registered
highway-env scenarios, over the same seeds and with the same episode loop, outcomes and
failure accounting as ``minimaxplan experiment``'s robust, nominal and idm rows:

``reference``
    At every decision (highway-env's 1 s), `interval_root` of the episode's environment
    (highway-env's ``simplify`` and ``change_vehicles(IntervalVehicle)``: every other
    vehicle with its true lane, target speed, route and timer, the class's prior parameter
    boxes) and `HighwayEnvReferencePlanner` with ``budget`` K expansions, gamma 0.9, the
    planner's actions in its order (SLOWER first) and the 5 s depth rule; a transition is
    worth the robust method's own reward (highway-env's, normalised:
    `minimaxplan.analysis.highway_env_scenario.normalised_reward`) of the copy's ego after
    the decision, 0 and terminal on highway-env's interval collision check or off the
    road. The root action is held for the decision's first simulation step, IDLE after
    (as every method here).

What it reads that the library's robust method does not: each vehicle's true lane,
target speed, route and timer (``IntervalVehicle.create_from``), as the public reference
agents do. Its boxes are highway-env's, which are not sound on these scenes
(`benchmarks/results/highway_env.md`), so nothing here is checked at run time.

Writes ``--out`` (default ``benchmarks/results/experiments/highway-env-reference/``):
``minimaxplan experiment``'s files (summary.json, episodes.csv, table.md,
environment.json) and ``decisions.json`` (per episode: every decision's action, bounds,
expansions and CPU time). Needs the ``vehicle`` extra.

Usage::

    python benchmarks/highway_env_reference_episodes.py [--episodes 50] [--workers 2] [--budget 35]
        [--scenarios highway-env:highway-fast-v0,highway-env:intersection-v0]
"""

from __future__ import annotations

import argparse
import functools
import importlib.util
import json
import pathlib
import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from minimaxplan.analysis.episode import LoopConfig
from minimaxplan.analysis.experiment import run_experiment, write_outputs
from minimaxplan.analysis.highway_env_scenario import (
    HORIZON,
    HighwayEnvScenario,
    HighwayEnvWorld,
    normalised_reward,
)
from minimaxplan.analysis.registry import Method, UnsupportedScenario, register_method
from minimaxplan.models.errors import InputError
from minimaxplan.scenarios.highway_env_adapter import meta_action

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import highway_env_reference_planner as reference  # noqa: E402

RESULTS = pathlib.Path(__file__).resolve().parent / "results" / "experiments" / "highway-env-reference"
SCENARIOS = ("highway-env:highway-fast-v0", "highway-env:intersection-v0")
#: The reference's expansions per decision: the smallest budget of the decision-time benchmark
#: (its trees usually stop after a few expansions, long before K).
BUDGET = 35
#: The reference's discount per decision (the benchmark's).
GAMMA = 0.9


class _HoldFirst:
    """The chosen meta-action at the decision's first simulation step, IDLE after."""

    def __init__(self, action: int, idle: int) -> None:
        self.action, self.idle, self._calls = action, idle, 0

    def control(self, measurement: Any) -> np.ndarray:
        """The action index (shape (1,))."""
        self._calls += 1
        return np.array([self.action if self._calls == 1 else self.idle], dtype=float)


class HighwayEnvReferenceMethod(Method[HighwayEnvWorld]):
    """`HighwayEnvReferencePlanner` as the ego's controller (see the module docstring).

    Parameters
    ----------
    scenario : HighwayEnvScenario
        The highway-env scenario (any other raises `UnsupportedScenario`).
    config : LoopConfig
        The loop settings (unused: the reference discounts by `GAMMA` per decision).
    budget : int
        Expansions per decision.
    """

    def __init__(self, scenario: Any, config: LoopConfig, *, budget: int = BUDGET) -> None:
        if not isinstance(scenario, HighwayEnvScenario):
            raise UnsupportedScenario(f"{type(self).__name__} drives highway-env scenarios only")
        self.scenario, self.config, self.budget = scenario, config, int(budget)

    def start(self, world: HighwayEnvWorld) -> None:
        """Remember the world; map the planner's actions to highway-env's.

        Parameters
        ----------
        world : HighwayEnvWorld
            The episode, at reset.
        """
        self.world = world
        names = [a[0] for a in world.actions]
        self.meta_actions = [meta_action(world.adapter.env, name) for name in names]
        self.idle = names.index("IDLE")
        adapter = world.adapter
        width = float(adapter.road.widths[0]) if adapter.road is not None else 4.0
        config = adapter.env.unwrapped.config
        highway = "highway" in adapter.env_id
        self.value = reference.state_reward_of(
            lambda states: normalised_reward(config, states, highway=highway, lane_width=width)
        )
        self.horizon_decisions = int(round(HORIZON))
        self.decisions: list[dict] = []

    def decide(self, measurement: Any) -> _HoldFirst:
        """Plan from a fresh interval copy of the episode's environment.

        Parameters
        ----------
        measurement : Observation
            Unused: the reference reads the environment itself.
        """
        began = time.process_time()
        root = reference.interval_root(self.world.adapter.env)
        planner = reference.HighwayEnvReferencePlanner(
            self.meta_actions, self.value, gamma=GAMMA, budget=self.budget, horizon_decisions=self.horizon_decisions
        )
        decision = planner.plan(root)
        self.decisions.append(
            {
                "step": int(self.world.step_index),
                "action": self.world.actions[decision.action][0],
                **{k: v for k, v in decision.to_dict().items() if k != "action"},
                "cpu_s": time.process_time() - began,
            }
        )
        return _HoldFirst(decision.action, self.idle)

    def report(self) -> dict:
        """The decisions: action, the root's bounds, expansions, env steps and CPU time."""
        return {"budget": self.budget, "decisions": self.decisions}


def main(argv: Sequence[str] | None = None) -> dict:
    """Run the reference over the scenarios; write the experiment's files and ``decisions.json``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--budget", type=int, default=BUDGET)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scenarios", default=",".join(SCENARIOS))
    parser.add_argument("--out", type=pathlib.Path, default=RESULTS)
    args = parser.parse_args(argv)
    if importlib.util.find_spec("highway_env") is None:
        parser.error("needs the vehicle extra (highway-env)")
    if args.budget < 1:
        parser.error(f"--budget must be >= 1, got {args.budget}")
    register_method("reference", functools.partial(HighwayEnvReferenceMethod, budget=args.budget))
    scenarios = [s for s in args.scenarios.split(",") if s]
    try:
        result = run_experiment(scenarios, ["reference"], episodes=args.episodes, seed=args.seed, workers=args.workers)
    except InputError as error:  # an unknown scenario, a count out of range: one line, exit 2
        parser.error(str(error))
    out = write_outputs(result, args.out)
    decisions = [
        {"scenario": r.scenario, "seed": r.seed, "outcome": r.outcome, "decisions": r.extra.get("decisions", [])}
        for r in result.records
    ]
    (out / "decisions.json").write_text(json.dumps(decisions, indent=1) + "\n")
    print((out / "table.md").read_text())
    return {"summary": list(result.summary), "wall_time_s": result.wall_time_s}


if __name__ == "__main__":
    main()
