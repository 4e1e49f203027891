"""Figure 6 for driving (`minimaxplan.analysis.road_suboptimality`): warm-up, frozen learner, CLI."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from minimaxplan.analysis import experiment as experiment_module
from minimaxplan.analysis import road_suboptimality as study_module
from minimaxplan.analysis.episode import DEFAULT_CONFIG, LoopConfig, run_job
from minimaxplan.analysis.registry import Transition
from minimaxplan.analysis.road_suboptimality import (
    FrozenLearner,
    FrozenRobustMethod,
    WarmedRoadScenario,
    road_suboptimality_study,
)
from minimaxplan.models.errors import InputError


def test_a_tiny_road_study_runs_end_to_end(tmp_path, run_cli):
    code, out, err = run_cli(
        *("suboptimality", "--scenario", "highway", "--samples", "1,3", "--episodes", "2", "--horizon", "2"),
        *("--workers", "1", "--no-progress", "--out", tmp_path),
    )
    assert code == 0, err
    study = json.loads((tmp_path / "suboptimality.json").read_text())
    assert study["scenario"] == "highway" and study["episodes"] == 2 and study["horizon_decisions"] == 2
    assert [r["n"] for r in study["rows"]] == [1, 3]
    for row in study["rows"]:
        assert row["warmup_ended"] == 0 and row["seeds"] == [0, 1]
        assert len(row["per_episode"]) == 2
        assert row["mean"] == pytest.approx(np.mean(row["per_episode"]))
        assert row["max"] == max(row["per_episode"]) and row["min"] == min(row["per_episode"])
        assert sum(row["outcomes"].values()) == 2 and sum(row["oracle_outcomes"].values()) == 2
        assert row["failures"] == sum(row["outcomes"].get(o, 0) for o in ("collision", "off_road"))
        assert 0 < row["robust_speed"] < 40 and 0 < row["oracle_speed"] < 40
        # the frozen beliefs' boxes are still checked at every sub-step, and the guarantee holds
        assert row["boxes_checked"] > 0 and row["boxes_missed"] == 0
        assert row["frozen_vehicles"] > 0
    fit = study["fit"]
    assert (fit["warning"] is None) == (fit["a"] is not None)
    table = (tmp_path / "suboptimality.md").read_text()
    assert table in out and "| 1 |" in table and "| 3 |" in table and "oracle speed" in table
    assert ("Trend fit" in table) == (fit["warning"] is None)
    assert (tmp_path / "suboptimality.png").read_bytes()[:4] == b"\x89PNG"


def _step_episode(world, method, decisions: int) -> None:
    """What `run_job` does, for a few decisions (so that the method can be inspected after)."""
    x = world.measure()
    for _ in range(decisions):
        policy = method.decide(x)
        for _ in range(world.substeps):
            u = policy.control(x)
            world.apply(u)
            x_next = world.measure()
            method.observe(Transition(x, u, x_next))
            x = x_next


def _boxes(belief) -> tuple:
    return (
        belief.theta_a.low.tolist(),
        belief.theta_a.high.tolist(),
        belief.theta_b.low.tolist(),
        belief.theta_b.high.tolist(),
    )


@pytest.mark.parametrize("kind", ["highway", "tjunction"])
def test_the_learner_is_frozen_after_the_warm_up(kind):
    n = 3
    scenario = WarmedRoadScenario(kind, n)
    world = scenario.make_world(0, DEFAULT_CONFIG)
    assert world.warmup_substeps == n and len(world.warmup_observations) == n + 1
    assert world.world.step_index == n
    method = FrozenRobustMethod(scenario, DEFAULT_CONFIG)
    method.start(world)
    learner = method.frozen_learner.learner
    assert learner.step == n
    # every vehicle in view throughout the warm-up was seen at its N + 1 sub-steps: N transitions
    assert max(len(track.states) for track in learner.tracks.values()) == n + 1
    frozen = {a: b.to_dict() for a, b in method.frozen_learner.frozen.items()}
    assert frozen and frozen == {a: b.to_dict() for a, b in learner.beliefs().items()}
    _step_episode(world, method, 2)
    now = n + 2 * world.substeps
    assert world.world.step_index == now
    if kind == "tjunction":
        assert learner.step == n  # not fed: the episode's measurements taught it nothing
        assert {a: b.to_dict() for a, b in learner.beliefs(agents=list(frozen)).items()} == frozen
    else:
        assert learner.step == now  # fed for the lanes in force only
    # the beliefs the last decision forecast under: the frozen theta boxes, placed on the measurement
    used = method.learner.beliefs()
    assert used
    if kind == "tjunction":
        assert set(used) <= set(frozen)
    for agent, belief in used.items():
        made = method.frozen_learner.frozen.get(agent)
        if made is None:  # first seen after the freeze (the highway): the prior boxes
            assert _boxes(belief) == _boxes(replace(belief, theta_a=learner.prior_a, theta_b=learner.prior_b))
            continue
        assert _boxes(belief) == _boxes(made)
        if kind == "tjunction":
            assert set(belief.routes) <= set(made.routes)
    report = method.report()
    assert report["frozen_step"] == n
    assert report["learner_step"] == (n if kind == "tjunction" else now)
    assert len(report["decisions"]) == 2
    assert report["frozen_beliefs"] == [frozen[a] for a in sorted(frozen)]
    with pytest.raises(InputError, match="frozen"):
        method.learner.observe(world.measure())


def test_frozen_tjunction_beliefs_follow_the_vehicles_lanes_with_the_prior_geometry():
    """At the T-junction the lanes are the prior's at the current measurement, on the frozen routes."""
    from minimaxplan.scenarios.traffic_models import prior_belief

    scenario = WarmedRoadScenario("tjunction", 10)
    world = scenario.make_world(0, DEFAULT_CONFIG)
    method = FrozenRobustMethod(scenario, DEFAULT_CONFIG)
    method.start(world)
    for _ in range(20):
        world.apply(np.zeros(2))
        method.frozen_learner.see(world.measure())
    observation = world.measure()
    used = method.learner.beliefs()
    assert used
    frozen = method.frozen_learner.frozen
    for row, agent in enumerate(observation.ids):
        if int(agent) not in used:
            continue
        prior = prior_belief(int(agent), observation.vehicles[row], world.world.road, world.world.scenario)
        belief = used[int(agent)]
        assert set(belief.routes) <= set(frozen[int(agent)].routes)
        assert set(belief.lanes) <= set(prior.lanes)
        assert all(any(lane in route for route in belief.routes) for lane in belief.lanes)


def test_frozen_highway_beliefs_track_the_lanes_in_force_with_the_frozen_boxes():
    """On the highway the lanes come from the learner fed after the freeze; its boxes are not used.

    The lanes are narrower than the prior's (which would let a neighbour beside the ego be
    always already changing into its lane), the theta boxes stay those made at the freeze,
    and the learner's own boxes did move on (the test is not vacuous).
    """
    from minimaxplan.scenarios.traffic_models import prior_belief

    scenario = WarmedRoadScenario("highway", 10)
    world = scenario.make_world(0, DEFAULT_CONFIG)
    method = FrozenRobustMethod(scenario, DEFAULT_CONFIG)
    method.start(world)
    frozen_learner = method.frozen_learner
    frozen_learner.see(world.measure())  # a re-measurement of the warm-up's last sub-step: not learned from
    assert frozen_learner.learner.step == 10
    for _ in range(60):
        world.apply(np.zeros(2))
        observation = world.measure()
        frozen_learner.see(observation)
        frozen_learner.see(observation)  # a measurement seen twice is fed once
    learner = frozen_learner.learner
    assert learner.step == 10 + 60
    used = frozen_learner.beliefs()
    live = learner.beliefs()
    assert set(used) == set(live)
    narrower = 0
    for row, agent in enumerate(observation.ids):
        agent = int(agent)
        belief = used[agent]
        assert (belief.lanes, belief.routes) == (live[agent].lanes, live[agent].routes)
        made = frozen_learner.frozen.get(agent)
        if made is not None:
            assert _boxes(belief) == _boxes(made)
        prior = prior_belief(agent, observation.vehicles[row], world.world.road, world.world.scenario)
        assert set(belief.lanes) <= set(prior.lanes)
        narrower += len(belief.lanes) < len(prior.lanes)
    assert narrower > 0
    assert any(_boxes(live[a]) != _boxes(used[a]) for a in used if a in frozen_learner.frozen)


def test_an_unfrozen_learner_would_have_changed():
    """The freezing test above is not vacuous: fed the episode, the learner moves on."""
    from minimaxplan.analysis.traffic_learning import TrafficLearner

    scenario = WarmedRoadScenario("highway", 3)
    world = scenario.make_world(0, DEFAULT_CONFIG)
    learner = TrafficLearner(world.world.road, world.world.scenario)
    for observation in world.warmup_observations:
        learner.observe(observation)
    frozen = FrozenLearner(learner)
    for _ in range(10):
        world.apply(np.zeros(2))
        learner.observe(world.measure())
    assert learner.step == 13 and frozen.frozen_step == 3
    now = learner.beliefs(agents=list(frozen.frozen))
    assert any(now[a].to_dict() != frozen.frozen[a].to_dict() for a in frozen.frozen)
    assert {a: b.to_dict() for a, b in frozen.beliefs().items()} == {a: b.to_dict() for a, b in frozen.frozen.items()}


def test_the_oracle_and_the_robust_method_start_from_the_same_warm_up_state():
    n = 4
    config = LoopConfig(max_decisions=1)
    jobs = study_module._jobs("tjunction", n, "robust", [2], config) + study_module._jobs(
        "tjunction", n, "oracle", [2], config
    )
    robust, oracle = (run_job(job) for job in jobs)
    assert (robust.method, oracle.method) == ("robust", "oracle")
    warm_r, warm_o = robust.extra["world"]["warmup"], oracle.extra["world"]["warmup"]
    assert warm_r == warm_o and warm_r["substeps"] == n and warm_r["step_index"] == n
    assert robust.trajectory[0] == oracle.trajectory[0]
    assert robust.trace["states"][0] == oracle.trace["states"][0]
    assert np.allclose(robust.trace["states"][0], warm_r["ego_state"], atol=1e-4)
    # the other vehicles' true paths are the same up to the end of the warm-up
    paths_r, paths_o = robust.extra["world"]["traffic_paths"], oracle.extra["world"]["traffic_paths"]
    early = {a: [p for p in rows if p[0] <= n] for a, rows in paths_r.items()}
    assert early == {a: [p for p in rows if p[0] <= n] for a, rows in paths_o.items() if a in early}
    assert any(early.values())
    assert robust.decisions == oracle.decisions == 1
    assert robust.extra["frozen_step"] == robust.extra["learner_step"] == n


@pytest.fixture
def no_work(monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("work started before the options were checked")

    monkeypatch.setattr(experiment_module, "_run_jobs", forbidden)
    monkeypatch.setattr(experiment_module, "run_job", forbidden)


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["--scenario", "nowhere"], "argument --scenario: "),
        (["--scenario", "highway", "--samples", "0,5"], "argument --samples: "),
        (["--scenario", "tjunction", "--episodes", "0"], "argument --episodes: "),
        (["--scenario", "highway", "--horizon", "-1"], "argument --horizon: "),
        (["--scenario", "tjunction", "--workers", "0"], "argument --workers: "),
        (["--scenario", "highway", "--seed", "x"], "argument --seed: "),
    ],
)
def test_a_bad_option_exits_2_on_one_line(run_cli, no_work, tmp_path, argv, option):
    code, out, err = run_cli("suboptimality", *argv, "--out", tmp_path / "out")
    assert code == 2, err
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("minimaxplan suboptimality") and option in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"kind": "static"}, "kind must be one of"),
        ({"samples": []}, "samples must be a non-empty"),
        ({"samples": "5"}, "samples must be a non-empty"),
        ({"samples": [0]}, "samples"),
        ({"episodes": 0}, "episodes"),
        ({"horizon": 0}, "horizon"),
        ({"seed": -1}, "seed"),
        ({"workers": 0}, "workers"),
    ],
)
def test_the_study_rejects_bad_arguments_before_any_episode(no_work, kwargs, message):
    arguments = {"kind": "highway", "samples": [1], **kwargs}
    with pytest.raises(InputError, match=message):
        road_suboptimality_study(arguments.pop("kind"), arguments.pop("samples"), **arguments)


def test_a_warm_up_needs_a_positive_length():
    with pytest.raises(InputError, match="warmup"):
        WarmedRoadScenario("highway", 0)


def test_the_scenario_option_picks_the_study(tmp_path, run_cli, monkeypatch):
    """The default stays the robot's study (no scenario passed); a robot name is passed on; a road name goes to the road study."""
    from minimaxplan.analysis import suboptimality

    calls = []

    def robot(samples, **kwargs):
        calls.append(("robot", list(samples), kwargs))
        rows = [{"n": n, "mean": 1.0, "max": 1.0, "min": 1.0, "per_episode": [1.0], "failures": 0} for n in samples]
        fit = suboptimality.fit_trend([r["n"] for r in rows], [r["mean"] for r in rows])
        return {"scenario": "x", "episodes": 1, "horizon_decisions": 1, "seed": 0, "rows": rows, "fit": fit}

    def road(kind, samples, **kwargs):
        calls.append((kind, list(samples), kwargs))
        study = robot(samples)
        calls.pop()
        for row in study["rows"]:
            row.update(
                oracle_failures=0, robust_speed=1.0, oracle_speed=2.0, boxes_checked=1, boxes_missed=0, warmup_ended=0
            )
        return {**study, "warmup": "the ego holds IDLE"}

    monkeypatch.setattr(suboptimality, "suboptimality_study", robot)
    monkeypatch.setattr(study_module, "road_suboptimality_study", road)
    for argv in ([], ["--scenario", "static"], ["--scenario", "pedestrian"], ["--scenario", "tjunction"]):
        code, _, err = run_cli("suboptimality", *argv, "--samples", "2,5", "--out", tmp_path)
        assert code == 0, err
    assert [c[0] for c in calls] == ["robot", "robot", "robot", "tjunction"]
    assert "scenario" not in calls[0][2] and "scenario" not in calls[1][2]
    assert calls[2][2]["scenario"] == "pedestrian"
    assert (calls[0][2]["episodes"], calls[0][2]["horizon"]) == (20, 24)
    assert (calls[3][2]["episodes"], calls[3][2]["horizon"]) == (10, 10)
    assert "robust speed" in (tmp_path / "suboptimality.md").read_text()
