"""The episode loop's run-time check of the guarantee cannot silently pass.

`BoxCheck` compares every true state with its predicted box exactly; a box one ulp off
the truth is a miss. Through the loop: a toy world whose true state lands exactly on an
edge of the interval prediction (its disturbance is always at an extreme) is contained
by the prediction rounded outward (or computed with the world's own rounding) and missed
by the prediction rounded inward; and the robot's robust method predicts boxes that the
check reads.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.analysis.episode import DEFAULT_CONFIG, BoxCheck, EpisodeJob, LoopConfig, run_episode, run_job
from minimaxplan.analysis.registry import GroundTruthWorld, Method, PredictingPolicy, Scenario, box_kind
from minimaxplan.models import DimensionError, InputError

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
states = st.lists(finite, min_size=1, max_size=5).map(np.array)


# -------------------------------------------------------------------- BoxCheck
@given(states)
def test_the_degenerate_box_of_the_truth_is_contained(x):
    check = BoxCheck()
    check.check({"robot": (x.copy(), x.copy())}, {"robot": x}, decision=0, substep=1, time=0.1)
    assert (check.checked, check.missed, check.misses) == (1, 0, [])
    assert check.by_kind == {"robot": {"checked": 1, "missed": 0}}


@given(states, st.data())
def test_a_box_one_ulp_beside_the_truth_is_a_miss(x, data):
    i = data.draw(st.integers(0, x.size - 1), label="coordinate")
    above = data.draw(st.booleans(), label="box above the truth")
    lower, upper = x.copy(), x.copy()
    if above:  # the whole box shifted up by one ulp in coordinate i: the truth is below it
        lower[i] = upper[i] = np.nextafter(x[i], math.inf)
    else:
        lower[i] = upper[i] = np.nextafter(x[i], -math.inf)
    check = BoxCheck()
    check.check({"pedestrian 3": (lower, upper)}, {"pedestrian 3": x}, decision=4, substep=2, time=1.3)
    assert (check.checked, check.missed) == (1, 1)
    assert check.by_kind == {"pedestrian": {"checked": 1, "missed": 1}}
    (miss,) = check.misses
    assert miss["decision"] == 4 and miss["substep"] == 2 and miss["time"] == 1.3
    assert miss["name"] == "pedestrian 3" and miss["coordinates"] == [i]
    assert miss["excess"] == abs(lower[i] - x[i]) > 0  # one ulp
    assert miss["state"] == x.tolist() and miss["lower"] == lower.tolist() and miss["upper"] == upper.tolist()


def test_nan_is_a_miss_and_errors_name_the_box():
    check = BoxCheck()
    box = (np.zeros(2), np.ones(2))
    check.check({"vehicle 7": box}, {"vehicle 7": np.array([0.5, np.nan])}, decision=0, substep=1, time=0.0)
    assert check.missed == 1 and math.isnan(check.misses[0]["excess"]) and check.misses[0]["coordinates"] == [1]
    with pytest.raises(
        InputError, match=r"predicted a box for 'robot', but .* has no such name \(it has \['vehicle 7'\]\)"
    ):
        check.check({"robot": box}, {"vehicle 7": np.zeros(2)}, decision=0, substep=1, time=0.0)
    with pytest.raises(
        DimensionError, match=r"'robot' has corners of shapes \(2,\) and \(2,\), but its true state has shape \(4,\)"
    ):
        check.check({"robot": box}, {"robot": np.zeros(4)}, decision=0, substep=1, time=0.0)
    with pytest.raises(InputError, match="predicted a box for 'ghost'"):
        check.check({"vehicle 7": box, "ghost": box}, {"vehicle 7": np.zeros(2)}, decision=0, substep=1, time=0.0)
    assert check.checked == 1  # the failed calls counted nothing, not even their valid boxes
    assert box_kind("robot") == "robot" and box_kind("pedestrian 12") == "pedestrian"


def test_only_the_first_misses_are_recorded_but_all_are_counted():
    from minimaxplan.analysis.episode import MAX_RECORDED_MISSES

    check = BoxCheck()
    for n in range(MAX_RECORDED_MISSES + 5):
        check.check({"robot": (np.ones(1), np.ones(1))}, {"robot": np.zeros(1)}, decision=n, substep=1, time=0.0)
    assert check.missed == MAX_RECORDED_MISSES + 5 and len(check.misses) == MAX_RECORDED_MISSES
    assert check.to_dict()["boxes_missed"] == MAX_RECORDED_MISSES + 5


# ------------------------------------------------------------- through the loop
class EdgeWorld:
    """``x+ = (x + c u) + w`` with ``w = +-w_bar`` (an extreme, drawn per sub-step), measured exactly."""

    substeps = 3
    dt = 0.1
    max_steps = 12

    def __init__(self, seed: int, c: float, w_bar: float, x0: float):
        self.rng = np.random.default_rng(seed)
        self.c, self.w_bar = c, w_bar
        self.state = np.array([x0])
        self.steps = 0
        self.outcome = "running"

    done = property(lambda self: self.outcome != "running")
    time = property(lambda self: self.steps * self.dt)
    position = property(lambda self: self.state.copy())

    def measure(self) -> np.ndarray:
        return self.state.copy()

    def apply(self, u) -> str:
        w = self.w_bar if self.rng.uniform() < 0.5 else -self.w_bar
        self.state = (self.state + self.c * np.asarray(u, dtype=float)) + w
        self.steps += 1
        if self.steps >= self.max_steps:
            self.outcome = "timeout"
        return self.outcome

    def reward(self) -> float:
        return 1.0

    def to_dict(self) -> dict:
        return {"c": self.c, "w_bar": self.w_bar}

    def true_states(self) -> dict:
        return {"point": self.state.copy()}


class BlindEdgeWorld(EdgeWorld):
    """The same world without `true_states` (not a `GroundTruthWorld`)."""

    true_states = None


class EdgeScenario(Scenario):
    def __init__(self, c: float, w_bar: float, x0: float, world=EdgeWorld):
        self.c, self.w_bar, self.x0, self.world = c, w_bar, x0, world

    def make_world(self, seed: int, config: LoopConfig) -> EdgeWorld:
        return self.world(seed, self.c, self.w_bar, self.x0)


class HeldPrediction:
    """A constant control and the boxes predicted for each sub-step of its decision."""

    def __init__(self, u: float, boxes: list):
        self.u, self.boxes = np.array([u]), boxes

    def control(self, measurement):
        return self.u

    def predicted_boxes(self, substep: int) -> dict:
        return {"point": self.boxes[substep - 1]}


class IntervalMethod(Method):
    """Interval prediction of `EdgeWorld` from the (exact) measurement, rounded as asked:
    "outward" (one ulp), "none" (the world's own rounding: sound by monotonicity) or
    "inward" (one ulp: unsound, since the truth lies on an edge)."""

    def __init__(self, scenario: EdgeScenario, config, u: float, rounding: str):
        self.c, self.w_bar, self.u, self.rounding = scenario.c, scenario.w_bar, u, rounding

    def start(self, world) -> None:
        pass

    def decide(self, measurement) -> HeldPrediction:
        lo, hi = measurement.copy(), measurement.copy()
        step = {"outward": (-math.inf, math.inf), "inward": (math.inf, -math.inf)}.get(self.rounding)
        boxes = []
        for _ in range(EdgeWorld.substeps):
            lo, hi = (lo + self.c * self.u) - self.w_bar, (hi + self.c * self.u) + self.w_bar
            if step is not None:
                lo, hi = np.nextafter(lo, step[0]), np.nextafter(hi, step[1])
            boxes.append((lo, hi))
        return HeldPrediction(self.u, boxes)


def _edge_job(seed, c, w_bar, x0, u, rounding, world=EdgeWorld) -> EpisodeJob:
    return EpisodeJob(
        "edge",
        f"interval-{rounding}",
        seed,
        DEFAULT_CONFIG,
        functools.partial(EdgeScenario, c, w_bar, x0, world),
        functools.partial(IntervalMethod, u=u, rounding=rounding),
    )


edge_cases = dict(
    seed=st.integers(0, 2**31 - 1),
    c=st.floats(0.01, 10.0),
    w_bar=st.floats(1e-9, 1.0),
    x0=st.floats(-1e3, 1e3),
    u=st.floats(-1.0, 1.0),
)


@given(**edge_cases, rounding=st.sampled_from(["outward", "none"]))
def test_sound_boxes_are_never_missed(seed, c, w_bar, x0, u, rounding):
    record = run_job(_edge_job(seed, c, w_bar, x0, u, rounding))
    assert record.outcome == "timeout" and record.decisions == 4
    assert (record.boxes_checked, record.boxes_missed) == (12, 0)
    assert record.extra["runtime_check"]["by_kind"] == {"point": {"checked": 12, "missed": 0}}


@given(**edge_cases)
def test_inward_rounded_boxes_of_the_toy_world_are_missed(seed, c, w_bar, x0, u):
    record = run_job(_edge_job(seed, c, w_bar, x0, u, "inward"))
    # after the first sub-step of every decision the truth is exactly an edge of the
    # world-rounded box, so the box moved one ulp inward misses it
    assert record.boxes_checked == 12 and record.boxes_missed >= 4
    misses = record.extra["runtime_check"]["misses"]
    assert {m["decision"] for m in misses if m["substep"] == 1} == {0, 1, 2, 3}
    assert all(m["name"] == "point" and m["excess"] > 0 for m in misses)
    assert record.row()["boxes_missed"] == record.boxes_missed


def test_a_predicting_policy_needs_a_world_with_true_states():
    assert isinstance(EdgeWorld(0, 1.0, 0.1, 0.0), GroundTruthWorld)
    assert not isinstance(BlindEdgeWorld(0, 1.0, 0.1, 0.0), GroundTruthWorld)
    assert isinstance(HeldPrediction(0.0, []), PredictingPolicy)
    with pytest.raises(InputError, match=r"predicts boxes, but the world of scenario 'edge' \(BlindEdgeWorld\)"):
        run_job(_edge_job(0, 1.0, 0.1, 0.0, 0.5, "outward", world=BlindEdgeWorld))


def test_the_robust_robot_method_predicts_the_robot_and_the_pedestrians():
    record = run_episode("pedestrian", "robust", 3, LoopConfig(budget=12, max_decisions=4))
    check = record.extra["runtime_check"]
    pedestrians = len(record.extra["world"]["pedestrians"]["positions"])
    steps = 4 * 5  # every sub-step of the four decisions
    assert record.boxes_checked == steps * (1 + pedestrians) and record.boxes_missed == 0
    assert check["by_kind"] == {
        "pedestrian": {"checked": steps * pedestrians, "missed": 0},
        "robot": {"checked": steps, "missed": 0},
    }
    other = run_episode("pedestrian", "dwa", 3, LoopConfig(max_decisions=4))
    assert (other.boxes_checked, other.boxes_missed) == (0, 0) and "runtime_check" not in other.extra
