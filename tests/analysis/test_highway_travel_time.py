"""Where robust's extra travel time on Table 4's highway goes (`benchmarks/explain_highway_travel_time.py`).

The split's arithmetic on synthetic passages (its parts add up to the difference of the
times at the goal, each metre goes to robust's situation there), the situations' rules,
and one real episode re-run as the records were made (in a fresh process under
`RECORDS_ENVIRONMENT`), whose figures the README quotes.
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import types

import numpy as np
import pytest

from minimaxplan.analysis.numerical_environment import RECORDS_ENVIRONMENT

SCRIPT = pathlib.Path(__file__).parents[2] / "benchmarks" / "explain_highway_travel_time.py"


def _trace(speeds, *, dt=0.1, gap=np.inf, leader_speed=np.nan, lateral=0.0):
    """A passage at the given speed per sub-step (s from 0), with a constant leader and lateral speed."""
    speeds = np.asarray(speeds, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(speeds[:-1] * dt)])
    n = len(speeds)
    return {
        "t": dt * np.arange(n),
        "s": s,
        "speed": speeds,
        "lateral": np.broadcast_to(np.asarray(lateral, dtype=float), (n,)).copy(),
        "lane": np.zeros(n, dtype=int),
        "gap": np.broadcast_to(np.asarray(gap, dtype=float), (n,)).copy(),
        "leader_speed": np.broadcast_to(np.asarray(leader_speed, dtype=float), (n,)).copy(),
    }


def test_the_split_adds_up_to_the_difference_at_the_goal_and_goes_to_robusts_situation(benchmark_script):
    module = benchmark_script("explain_highway_travel_time")
    # robust at 20 m/s for the first 100 m, behind a 20 m/s leader 20 m ahead, then free at 30 m/s; DWA at 25 m/s
    speeds = [20.0] * 50 + [30.0] * 60
    robust = _trace(speeds)
    robust["gap"][:50], robust["leader_speed"][:50] = 20.0, 20.0
    dwa = _trace([25.0] * 120)
    split = module.split_gap(robust, dwa, 0.0, 250.0, module.REACH_S)
    parts = sum(split[name] for name in module.SITUATIONS)
    assert parts == pytest.approx(split["total"], abs=1e-12)
    assert split["total"] == pytest.approx(100 / 20 + 150 / 30 - 250 / 25, abs=1e-9)
    # the first 100 m behind the leader (20 m < (30 - 20) x 5 s), the last 150 m free
    assert split["metres"] == {"free": 150, "behind a leader": 100, "sideways": 0}
    assert split["behind a leader"] == pytest.approx(100 / 20 - 100 / 25, abs=1e-9)
    assert split["free"] == pytest.approx(150 / 30 - 150 / 25, abs=1e-9)
    assert split["seconds"]["robust"]["behind a leader"] == pytest.approx(5.0, abs=1e-9)
    # the same leader counts only within the reach time: not at 1 s (20 m > 10 m/s x 1 s)
    assert module.split_gap(robust, dwa, 0.0, 250.0, 1.0)["metres"]["behind a leader"] == 0
    with pytest.raises(RuntimeError, match="before the goal"):
        module.split_gap(robust, dwa, 0.0, 400.0, module.REACH_S)
    backwards = _trace([25.0] * 120)
    backwards["s"][60] = backwards["s"][59]
    with pytest.raises(RuntimeError, match="does not move forward"):
        module.split_gap(robust, backwards, 0.0, 250.0, module.REACH_S)


def test_the_target_speed_follows_the_executed_actions_clipped_to_the_levels(benchmark_script):
    module = benchmark_script("explain_highway_travel_time")
    decisions = [{"step": 0, "action": "FASTER"}, {"step": 5, "action": "FASTER"}, {"step": 10, "action": "SLOWER"}]
    decisions += [
        {"step": 15, "action": "LANE_LEFT"},
        {"step": 20, "action": "SLOWER"},
        {"step": 25, "action": "SLOWER"},
    ]
    record = types.SimpleNamespace(extra={"decisions": decisions})
    target = module.target_speeds(record, 24.2, 5)  # starts at the level nearest 24.2 m/s: 25
    expected = [30.0] * 10 + [25.0] * 10 + [20.0] * 10 + [20.0]
    assert target.tolist() == expected
    # split by target: the parts add up to the total too
    robust = _trace([20.0] * 31)
    robust["target"] = target
    split = module.split_gap(robust, _trace([25.0] * 40), 0.0, 50.0, module.REACH_S)
    assert sum(split["by_target"].values()) == pytest.approx(split["total"], abs=1e-12)
    # robust at 2 m per sub-step: target 20 m/s from sub-step 20, s = 40 m, so over the last 10 m to the goal
    assert split["by_target"]["20"] == pytest.approx(10 * (1 / 20 - 1 / 25), abs=1e-9)
    assert split["by_target"]["30"] == pytest.approx(20 * (1 / 20 - 1 / 25), abs=1e-9)


class _Held:
    """A stand-in for `BicycleModel.predict`: the ego at 30 m/s along x, 5 sub-steps of 0.1 s per decision."""

    def predict(self, state, action):
        x = state.x[0] + 3.0 * np.arange(1, 6)
        states = np.stack([x, np.zeros(5), np.full(5, 30.0), np.zeros(5)], axis=1)
        return states, None, types.SimpleNamespace(x=states[-1], time=state.time + 5)


def test_truly_met_reads_the_recorded_future_of_the_vehicle_the_box_belongs_to(benchmark_script):
    module = benchmark_script("explain_highway_travel_time")
    from minimaxplan.scenarios.vehicles import VehicleParameters

    root = types.SimpleNamespace(x=np.array([0.0, 0.0, 30.0, 0.0]), time=0)

    def world(leader_x0, leader_speed, steps):
        history = []
        for k in range(steps + 1):
            states = np.array([[3.0 * k, 0.0, 30.0, 0.0], [leader_x0 + leader_speed * 0.1 * k, 0.0, leader_speed, 0.0]])
            history.append((states, np.ones(2, dtype=bool)))
        return types.SimpleNamespace(scenario=types.SimpleNamespace(vehicle=VehicleParameters()), history=history)

    # a leader standing 20 m ahead: met within 10 sub-steps (front at 2.5 + 3k reaches its rear at 17.5 m)
    assert module._truly_met(world(20.0, 0.0, 10), _Held(), root, [3], 10, 1) == "truly"
    # one 20 m ahead at the ego's speed is never met; with a shorter recorded future the answer is unknown
    assert module._truly_met(world(20.0, 30.0, 10), _Held(), root, [3], 10, 1) == "box only"
    assert module._truly_met(world(20.0, 30.0, 6), _Held(), root, [3], 10, 1) == "unknown"
    # one standing 40 m ahead is met only after 10 sub-steps: not within the horizon
    assert module._truly_met(world(40.0, 0.0, 20), _Held(), root, [3], 10, 1) == "box only"


def test_the_situations_and_lane_changes(benchmark_script):
    module = benchmark_script("explain_highway_travel_time")
    trace = _trace([25.0] * 6, gap=[10.0, 10.0, 49.0, 51.0, np.inf, 10.0], leader_speed=[20, 31, 20, 20, np.nan, 20])
    trace["lateral"][5] = -1.0  # moving sideways wins over a leader
    assert module.situation(trace, 5.0).tolist() == [1, 0, 1, 0, 0, 2]  # a faster leader never constrains
    trace["lane"][:] = [0, 0, -1, 1, 1, 0]
    assert module.lane_changes(trace) == 2  # off every lane is skipped


def test_the_script_refuses_bad_options_and_another_numerical_environment(tmp_path):
    for argv, message in (
        (["--seeds", "0-120"], "--seeds must lie in 0-99"),
        (["--seeds", "a"], "--seeds must be integers or ranges"),
        (["--workers", "0"], "--workers must be >= 1"),
    ):
        done = subprocess.run([sys.executable, str(SCRIPT), *argv], capture_output=True, text=True)
        assert done.returncode == 2 and message in done.stderr, done.stderr
    environment = {k: v for k, v in os.environ.items() if k not in RECORDS_ENVIRONMENT}
    environment["OPENBLAS_CORETYPE"] = "Sandybridge"
    command = [sys.executable, str(SCRIPT), "--seeds", "5", "--out", str(tmp_path)]
    done = subprocess.run(command, capture_output=True, text=True, env=environment)
    assert done.returncode == 2 and "numerical environment" in done.stderr and "Traceback" not in done.stderr
    assert not list(tmp_path.iterdir())


@pytest.mark.slow
def test_seed_5_re_run_as_recorded_loses_its_time_behind_a_leader(tmp_path):
    """Robust and DWA keep their lane behind the same leader, the oracle overtakes twice, nominal collides (README)."""
    command = [sys.executable, str(SCRIPT), "--seeds", "5", "--workers", "1", "--out", str(tmp_path)]
    done = subprocess.run(command, capture_output=True, text=True, env={**os.environ, **RECORDS_ENVIRONMENT})
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads((tmp_path / "highway_travel_time.json").read_text())
    (episode,) = result["episodes"]
    assert result["meta"]["environment"]["matches_records"]
    recorded = {method: episode[method]["recorded_time_s"] for method in ("robust", "dwa", "oracle", "nominal")}
    assert recorded == pytest.approx({"robust": 10.2, "dwa": 9.8, "oracle": 8.5, "nominal": 1.4})
    # nominal collided at 1.4 s (Table 4's records): no time at the goal, no split against it
    assert episode["nominal"] == {"outcome": "collision", "recorded_time_s": pytest.approx(1.4)}
    assert sorted(episode["split"]) == ["dwa", "oracle"]
    for reference in ("dwa", "oracle"):
        split = episode["split"][reference]["5.0"]
        assert sum(split[name] for name in ("free", "behind a leader", "sideways")) == pytest.approx(split["total"])
        assert sum(split["by_target"].values()) == pytest.approx(split["total"])
        # the times at the goal differ from the recorded ones by less than one sub-step each
        assert abs(split["total"] - (recorded["robust"] - recorded[reference])) < 0.2
        assert split["behind a leader"] > 0.9 * split["total"] > 0
    lanes = {method: episode[method]["lane_changes"] for method in ("robust", "dwa", "oracle")}
    assert lanes == {"robust": 0, "dwa": 0, "oracle": 2}
    assert episode["oracle"]["time_at_top_target_s"] == pytest.approx(8.5)
    assert episode["robust"]["time_at_top_target_s"] == pytest.approx(3.0)
    # 15 of robust's 21 decisions leave its target below 30 m/s, each because FASTER held may meet the leader's
    # box; in the first 11 the true leader would have been met too, the other 4 look past the episode's end
    assert episode["robust"]["decisions"] == 21
    assert episode["robust"]["below_top"] == ["leader: truly"] * 11 + ["leader: unknown"] * 4
    # and at each, changing into the left lane (the ego drives in the right one) may meet first the box of a
    # vehicle two lanes over that may change into it (in truth it did not, where the record tells), later the
    # leader's
    overtake = ["third lane: box only"] * 5 + ["third lane: unknown"] * 4 + ["leader: unknown"] * 6
    assert episode["robust"]["overtake"] == overtake
    assert (tmp_path / "highway_travel_time.md").read_text().startswith("# Table 4's highway")
