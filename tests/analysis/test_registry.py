"""A toy scenario and a toy method, registered from this file without touching the package,
run through `run_experiment` (sequentially, on a 2-process pool) and the CLI; the
registries' error paths."""

from __future__ import annotations

import functools
import json
import re

import numpy as np
import pytest

from minimaxplan.analysis import (
    EpisodeFailure,
    Method,
    Policy,
    Scenario,
    Transition,
    UnknownMethod,
    UnknownScenario,
    UnsupportedScenario,
    World,
    default_scenario_names,
    method_names,
    register_method,
    register_scenario,
    scenario_names,
)
from minimaxplan.analysis.cli import main
from minimaxplan.analysis.episode import LoopConfig, make_job, run_episode
from minimaxplan.analysis.experiment import run_experiment
from minimaxplan.analysis.registry import register_unavailable
from minimaxplan.models import InputError


class LineWorld:
    """A point on a line, ``x+ = x + dt u``, chasing ``goal``; noisy measurements."""

    substeps = 2
    dt = 0.1

    def __init__(self, seed: int, goal: float):
        self.seed = seed
        self.goal = goal
        self.rng = np.random.default_rng(seed)
        self.state = np.array([self.rng.uniform(-1.0, 0.0)])
        self.steps = 0
        self.outcome = "running"

    @property
    def done(self) -> bool:
        return self.outcome != "running"

    @property
    def time(self) -> float:
        return self.steps * self.dt

    @property
    def position(self) -> np.ndarray:
        return self.state.copy()

    def measure(self) -> np.ndarray:
        return self.state + self.rng.uniform(-0.01, 0.01, 1)

    def apply(self, u) -> str:
        assert np.all(np.abs(u) <= 1.0)
        self.state = self.state + self.dt * np.asarray(u, dtype=float)
        self.steps += 1
        if abs(self.state[0] - self.goal) <= 0.05:
            self.outcome = "goal"
        elif self.steps >= 60:
            self.outcome = "timeout"
        return self.outcome

    def reward(self) -> float:
        return 1.0 / (1.0 + abs(self.state[0] - self.goal))

    def to_dict(self) -> dict:
        return {"seed": self.seed, "goal": self.goal}


class LineScenario(Scenario):
    def __init__(self, goal: float = 1.0):
        self.goal = goal

    def make_world(self, seed: int, config: LoopConfig) -> LineWorld:
        return LineWorld(seed, self.goal)


class Proportional:
    def __init__(self, gain: float, goal: float):
        self.gain, self.goal = gain, goal

    def control(self, measurement):
        return np.clip(self.gain * (self.goal - measurement), -1.0, 1.0)


class ProportionalMethod(Method):
    """Drives `LineScenario` worlds only; gives up after ``give_up`` decisions if set."""

    def __init__(self, scenario, config, give_up: int | None = None):
        if not isinstance(scenario, LineScenario):
            raise UnsupportedScenario(f"ProportionalMethod drives only LineScenario, got {type(scenario).__name__}")
        self.goal = scenario.goal
        self.gain = 0.5 * config.speed
        self.give_up = give_up

    def start(self, world) -> None:
        self.transitions: list[Transition] = []
        self.decisions = 0

    def decide(self, measurement) -> Policy:
        self.decisions += 1
        if self.give_up is not None and self.decisions > self.give_up:
            raise EpisodeFailure("gave_up")
        return Proportional(self.gain, self.goal)

    def observe(self, transition: Transition) -> None:
        self.transitions.append(transition)

    def report(self) -> dict:
        return {"transitions": len(self.transitions)}


@pytest.fixture(autouse=True, scope="module")
def toy_registrations(registries_restored):
    """Register the toy world and methods for this module's tests, and leave the registries
    as they were afterwards (later tests in the same process see only the built-ins)."""
    with registries_restored():
        register_scenario("toy-line", LineScenario)
        register_scenario("toy-line-far", functools.partial(LineScenario, 3.0))
        register_method("toy-proportional", ProportionalMethod)
        register_method("toy-quitter", functools.partial(ProportionalMethod, give_up=2))
        # The same name serving a second world: the robot's "robust" still serves the robot worlds.
        register_method("robust", ProportionalMethod)
        yield


def _comparable(result):
    return [{k: v for k, v in r.row().items() if k != "wall_time_s"} for r in result.records], list(result.summary)


def test_toy_scenario_and_method_run_sequentially_and_on_a_pool_of_two():
    kwargs = dict(episodes=3, seed=5, progress=False)
    methods = ["toy-proportional", "toy-quitter"]
    first = run_experiment(["toy-line", "toy-line-far"], methods, workers=1, **kwargs)
    second = run_experiment(["toy-line", "toy-line-far"], methods, workers=2, **kwargs)
    assert _comparable(first) == _comparable(second)
    assert [(r.scenario, r.method, r.seed) for r in first.records][:4] == [
        ("toy-line", "toy-proportional", 5),
        ("toy-line", "toy-proportional", 6),
        ("toy-line", "toy-proportional", 7),
        ("toy-line", "toy-quitter", 5),
    ]
    by_key = {(r.scenario, r.method, r.seed): r for r in first.records}
    near = by_key[("toy-line", "toy-proportional", 5)]
    assert near.outcome == "goal" and near.success
    assert near.extra["world"] == {"seed": 5, "goal": 1.0}
    assert near.extra["transitions"] == len(near.trajectory) - 1  # one per sub-step
    quitter = by_key[("toy-line-far", "toy-quitter", 6)]
    assert quitter.outcome == "gave_up" and quitter.decisions == 2 and not quitter.success
    assert quitter.extra["transitions"] == 4  # two decisions of two sub-steps each


def test_the_loop_follows_the_documented_protocol():
    record = run_episode("toy-line", "toy-proportional", 11, LoopConfig(gamma=0.5))
    world = LineWorld(11, 1.0)
    method = ProportionalMethod(LineScenario(), LoopConfig())
    method.start(world)
    x, rewards, positions = world.measure(), [], [world.position]
    while not world.done:
        policy = method.decide(x)
        worst = 1.0
        for _ in range(world.substeps):
            u = policy.control(x)
            world.apply(u)
            positions.append(world.position)
            worst = min(worst, world.reward())
            x_next = world.measure()
            method.observe(Transition(x, u, x_next))
            x = x_next
            if world.done:
                break
        rewards.append(worst)
    assert record.outcome == world.outcome == "goal"
    assert record.decisions == len(rewards)
    assert record.discounted_return == pytest.approx(sum(0.5**i * r for i, r in enumerate(rewards)), rel=0, abs=0)
    assert record.time_s == world.time
    assert record.trajectory == tuple(map(tuple, np.round(positions, 4).tolist()))
    assert record.extra == {"transitions": len(method.transitions), "world": world.to_dict()}
    assert isinstance(world, World) and isinstance(policy, Policy)


def test_max_decisions_stops_with_horizon():
    record = run_episode("toy-line-far", "toy-proportional", 0, LoopConfig(max_decisions=3))
    assert record.outcome == "horizon" and record.decisions == 3


def test_one_method_name_serves_several_scenarios():
    from minimaxplan.analysis.robot_methods import RobustMethod

    assert method_names().count("robust") == 1
    assert make_job("toy-line", "robust", 0).method_factory is ProportionalMethod
    assert make_job("static", "robust", 0).method_factory is RobustMethod
    record = run_episode("toy-line", "robust", 2)
    assert record.method == "robust" and record.outcome == "goal"


def test_registered_names_and_unknown_names():
    assert {"static", "pedestrian", "toy-line", "toy-line-far"} <= set(scenario_names())
    assert scenario_names()[:2] == ["static", "pedestrian"]
    assert method_names()[:5] == ["robust", "nominal", "oracle", "dwa", "teb"]
    with pytest.raises(UnknownScenario, match=r"scenario must be one of the registered scenarios \['static', "):
        run_experiment(["mars"], ["dwa"], episodes=1)
    with pytest.raises(UnknownMethod, match=r"method must be one of the registered methods \['robust', "):
        run_experiment(["static"], ["magic"], episodes=1)
    assert issubclass(UnknownScenario, InputError) and issubclass(UnknownMethod, InputError)


def test_a_scenario_left_out_of_default_runs_is_registered_but_not_run_by_default():
    register_scenario("toy-optional", "minimaxplan.analysis.registry:Scenario", in_default_runs=False)
    assert "toy-optional" in scenario_names() and "toy-optional" not in default_scenario_names()
    assert default_scenario_names()[:4] == ["static", "pedestrian", "highway", "tjunction"]
    assert not any(name.startswith("highway-env:") for name in default_scenario_names())
    register_scenario("toy-optional", "minimaxplan.analysis.registry:Scenario")  # the same factory, now by default
    assert "toy-optional" in default_scenario_names()


def test_registrations_made_inside_registries_restored_are_gone_after_it(registries_restored):
    before = (scenario_names(), default_scenario_names(), method_names())
    quitter = functools.partial(ProportionalMethod, give_up=1)
    with registries_restored():
        register_scenario("toy-passing", LineScenario, in_default_runs=False)
        register_method("toy-passing", ProportionalMethod)
        register_method("robust", quitter)  # a second factory under a known name
        assert "toy-passing" in scenario_names() and "toy-passing" in method_names()
        assert make_job("toy-line", "robust", 0).method_factory is quitter
    assert (scenario_names(), default_scenario_names(), method_names()) == before
    assert make_job("toy-line", "robust", 0).method_factory is ProportionalMethod


def test_an_unavailable_name_is_not_registered_and_its_error_says_why(registries_restored):
    with registries_restored():
        register_unavailable("scenario", "toy-elsewhere", "it needs the toy extra")
        register_unavailable("method", "toy-elsewhere", "it needs the toy extra too")
        assert "toy-elsewhere" not in scenario_names() and "toy-elsewhere" not in method_names()
        with pytest.raises(
            UnknownScenario,
            match=r"^scenario must be one of the registered scenarios \['static', .*\], got 'toy-elsewhere' "
            r"\('toy-elsewhere' is not available: it needs the toy extra\)$",
        ):
            run_experiment(["toy-elsewhere"], ["dwa"], episodes=1, progress=False)
        with pytest.raises(
            UnknownMethod,
            match=r"got 'toy-elsewhere' \('toy-elsewhere' is not available: it needs the toy extra too\)$",
        ):
            run_experiment(["static"], ["toy-elsewhere"], episodes=1, progress=False)
        # a name registered later is found, whatever was said of it before
        register_scenario("toy-elsewhere", LineScenario)
        assert "toy-elsewhere" in scenario_names()
    with pytest.raises(UnknownScenario, match=r"got 'toy-elsewhere'$"):  # the reason went with the block
        run_experiment(["toy-elsewhere"], ["dwa"], episodes=1, progress=False)


@pytest.mark.parametrize(
    ("kind", "name", "reason", "message"),
    [
        ("world", "x", "why", "kind must be 'scenario' or 'method', got 'world'"),
        ("scenario", "", "why", "name must be a non-empty string, got ''"),
        ("method", "x", " ", "reason must be a non-empty string, got ' '"),
        ("method", "x", None, "reason must be a non-empty string, got None"),
    ],
)
def test_register_unavailable_refuses_bad_arguments(kind, name, reason, message):
    with pytest.raises(InputError, match=re.escape(message)):
        register_unavailable(kind, name, reason)


def test_a_method_rejects_a_scenario_it_does_not_support():
    with pytest.raises(
        UnsupportedScenario,
        match=r"method 'dwa' supports no scenario of type LineScenario: .*"
        r"RoadDWAMethod drives only RoadScenario worlds.*DWAMethod drives only RobotScenario worlds",
    ):
        run_experiment(["toy-line"], ["dwa"], episodes=1, progress=False)
    with pytest.raises(UnsupportedScenario, match="ProportionalMethod drives only LineScenario"):
        run_episode("static", "toy-proportional", 0)


def test_registration_errors():
    with pytest.raises(InputError, match="cannot be sent to worker processes"):
        register_method("toy-lambda", lambda scenario, config: None)
    with pytest.raises(InputError, match="'toy-line' is already registered"):
        register_scenario("toy-line", functools.partial(LineScenario, 2.0))
    with pytest.raises(InputError, match="name must be a non-empty string without commas"):
        register_scenario("a,b", LineScenario)
    with pytest.raises(InputError, match="must be a callable or a 'package.module:qualname' string"):
        register_method("toy-bad", "not a name")
    register_scenario("toy-line", LineScenario)  # the same factory again: a no-op
    register_method("toy-by-name", "tests_analysis_missing_module:Method")
    with pytest.raises(InputError, match="factory 'tests_analysis_missing_module:Method' cannot be imported"):
        run_episode("toy-line", "toy-by-name", 0)


def test_factories_named_by_module_and_qualname_reach_pool_workers():
    register_scenario("toy-line-by-name", f"{__name__}:LineScenario")
    register_method("toy-proportional-by-name", f"{__name__}:ProportionalMethod")
    register_method("toy-dwa-by-name", "minimaxplan.analysis.robot_methods:DWAMethod")
    by_name = run_experiment(
        ["toy-line-by-name"], ["toy-proportional-by-name"], episodes=2, seed=1, workers=2, progress=False
    )
    direct = run_experiment(["toy-line"], ["toy-proportional"], episodes=2, seed=1, workers=1, progress=False)
    strip = ("scenario", "method", "wall_time_s")
    assert [{k: v for k, v in r.row().items() if k not in strip} for r in by_name.records] == [
        {k: v for k, v in r.row().items() if k not in strip} for r in direct.records
    ]
    result = run_experiment(["static"], ["toy-dwa-by-name", "dwa"], episodes=1, seed=3, workers=2, progress=False)
    named, builtin = ({k: v for k, v in r.row().items() if k not in strip} for r in result.records)
    assert named == builtin


def test_cli_accepts_registered_names_and_rejects_unknown_ones_in_one_line(tmp_path, capsys):
    out = tmp_path / "toy"
    code = main(
        [
            "experiment",
            "--scenario",
            "toy-line",
            "--methods",
            "toy-proportional,toy-quitter",
            "--episodes",
            "2",
            "--workers",
            "1",
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert [(s["scenario"], s["method"]) for s in summary] == [
        ("toy-line", "toy-proportional"),
        ("toy-line", "toy-quitter"),
    ]
    capsys.readouterr()
    for argv, message in [
        (["--methods", "robust,magic"], "method must be one of the registered methods ['robust', 'nominal', "),
        (["--scenario", "mars"], "scenario must be one of the registered scenarios ['static', 'pedestrian', "),
        (["--scenario", "toy-line", "--methods", "teb"], "method 'teb' supports no scenario of type LineScenario"),
    ]:
        code = main(["experiment", *argv, "--episodes", "1", "--out", str(tmp_path / "x")])
        captured = capsys.readouterr()
        assert code == 2 and captured.out == ""
        assert captured.err.startswith("minimaxplan experiment: error: ") and message in captured.err
        assert captured.err.count("\n") == 1


def test_the_example_of_docs_extending_runs_as_printed(capsys):
    import pathlib
    import re
    import sys
    import types

    text = (pathlib.Path(__file__).resolve().parents[2] / "docs" / "extending.md").read_text()
    (example,) = [b for b in re.findall(r"```python\n(.*?)```", text, flags=re.S) if "run_experiment" in b]
    module = types.ModuleType("extending_example")  # a module, so that its factories pickle by reference
    sys.modules[module.__name__] = module
    try:
        exec(compile(example, "docs/extending.md", "exec"), module.__dict__)
    finally:
        del sys.modules[module.__name__]
    assert capsys.readouterr().out == "['goal', 'goal', 'goal']\n"
    assert "['goal', 'goal', 'goal']" in text


@pytest.mark.parametrize("first", ["robot_methods", "road_methods", "road_planning", "road_scenario"])
def test_the_builtin_names_keep_their_order_whichever_module_is_imported_first(first):
    import subprocess
    import sys

    code = (
        f"import minimaxplan.analysis.{first}\n"
        "from minimaxplan.analysis.registry import method_names, scenario_names\n"
        "print(method_names()[:5], scenario_names()[:4])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert (
        out.strip() == "['robust', 'nominal', 'oracle', 'dwa', 'teb'] ['static', 'pedestrian', 'highway', 'tjunction']"
    )
