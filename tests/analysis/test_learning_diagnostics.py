"""The learner diagnostics of benchmarks/: trace_parameter_boxes.py and ablate_tjunction_knowledge.py (issue 11)."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.analysis import road_planning, traffic_learning
from minimaxplan.analysis.traffic_learning import TrafficLearner, hold_lane_control
from minimaxplan.models import Box, DimensionError, InputError
from minimaxplan.scenarios import make_road_world
from minimaxplan.verify.interval_regression import IntervalRows, interval_parameter_box


def _free_driving_rows(theta1, v_target, v0, steps, disturbance, noise, *, dt=0.1, window=16, v_bar=0.1, w_bar=0.1):
    """The learner's windowed free-driving rows in (theta_a1..3, c) for a simulated speed trace, and the prior."""
    v = [v0]
    for n in range(steps):
        v.append(v[-1] + dt * (theta1 * (v_target - v[-1]) + disturbance(n)))
    v = np.array(v)
    measured = v + np.array([noise(n) for n in range(steps + 1)])
    glo, ghi, ylo, yhi = [], [], [], []
    for start in range(0, steps - window + 1, window // 4):
        m = measured[start : start + window]
        glo.append([-np.sum(m + v_bar), 0.0, 0.0, window])
        ghi.append([-np.sum(m - v_bar), 0.0, 0.0, window])
        dv = measured[start + window] - measured[start]
        ylo.append((dv - 2 * v_bar) / dt - window * w_bar)
        yhi.append((dv + 2 * v_bar) / dt + window * w_bar)
    v_lo, v_hi = 7.0, 9.0
    target_rows = IntervalRows(
        np.array([[-v_lo, 0, 0, 1.0], [-v_hi, 0, 0, 1.0]]),
        np.array([[-v_lo, 0, 0, 1.0], [-v_hi, 0, 0, 1.0]]),
        np.array([0.0, -np.inf]),
        np.array([np.inf, 0.0]),
    )
    rows = IntervalRows.stack(
        [target_rows, IntervalRows(np.array(glo), np.array(ghi), np.array(ylo), np.array(yhi))], 4
    )
    lo, hi = np.array([0.15, 0.15, 1.0]), np.array([0.45, 0.45, 3.0])
    prior = Box(np.append(lo, lo[0] * v_lo), np.append(hi, hi[0] * v_hi))
    return rows, prior, measured


@given(
    theta1=st.floats(0.15, 0.45),
    v_target=st.floats(7.0, 9.0),
    v0=st.floats(5.0, 11.0),
    signs=st.lists(st.sampled_from([-1.0, 1.0]), min_size=4, max_size=4),
    switch=st.integers(1, 60),
)
def test_speed_offset_bound_holds_the_true_offset(benchmark_script, theta1, v_target, v0, signs, switch):
    """The certified bound of d = c - theta_a1 v_ref holds the true one: disturbances and noise at their
    extremes, switching sign at a random step (the change of coordinates is what this would catch)."""
    module = benchmark_script("trace_parameter_boxes")
    rows, prior, measured = _free_driving_rows(
        theta1,
        v_target,
        v0,
        80,
        lambda n: 0.1 * (signs[0] if n < switch else signs[1]),
        lambda n: 0.1 * (signs[2] if n < switch else signs[3]),
    )
    v_ref = float(measured[-1])
    lo, hi = module.speed_offset_bound(rows, prior, v_ref)
    d = theta1 * v_target - theta1 * v_ref
    assert lo <= d <= hi


def test_speed_offset_bound_is_narrower_than_the_boxes_at_steady_speed(benchmark_script):
    """At a steady speed the rows pin d = theta_a1 (v_t - v_ref) far better than theta_a1's and v_t's boxes do
    (what the trace reports), while theta_a1 alone stays unidentified (the learner's longest window, 64)."""
    module = benchmark_script("trace_parameter_boxes")
    rows, prior, _ = _free_driving_rows(0.3, 8.0, 8.0, 200, lambda n: 0.0, lambda n: 0.0, window=64)
    lo, hi = module.speed_offset_bound(rows, prior, 8.0)
    boxes = 0.45 * (9.0 - 8.0) - 0.45 * (7.0 - 8.0)  # theta_a1 (v_t - 8) over [0.15, 0.45] x [7, 9]
    assert lo <= 0.0 <= hi
    assert hi - lo < 0.5 * boxes
    theta1 = interval_parameter_box(rows, prior, coordinates=(0,))
    assert theta1.high[0] - theta1.low[0] > 0.9 * (0.45 - 0.15)


@pytest.mark.parametrize("kind, seed", [("tjunction", 3), ("highway", 1)])
def test_speed_offset_bound_holds_the_truth_on_the_learners_rows(benchmark_script, kind, seed):
    """On the learner's own rows in a world (noise, disturbances, leaders, yielding), every surviving
    hypothesis' d bound holds the vehicle's true theta_a1 (v_t - v_ref): the rows and the change of
    coordinates together, which the synthetic rows above do not exercise."""
    module = benchmark_script("trace_parameter_boxes")
    world = make_road_world(kind, seed)
    learner = TrafficLearner(world.road, world.scenario)
    for _ in range(120):
        learner.observe(world.measure())
        if world.done:
            break
        world.apply(hold_lane_control(world))
    traffic, checked = world.traffic, 0
    for agent, track in learner.tracks.items():
        v_ref = float(track.states[max(track.states)][2])
        truth = traffic.theta_a[agent][0] * (traffic.target_speed[agent] - v_ref)
        for lon in {id(h.lon): h.lon for h in track.hyps if learner._alive(h)}.values():
            if lon.rows.n < module.MIN_ROWS:
                continue
            lo, hi = module.speed_offset_bound(learner._lon_rows_of(lon), learner.prior_lon, v_ref)
            assert lo <= truth <= hi, (agent, lo, truth, hi)
            checked += 1
    assert checked >= 3


def test_speed_offset_bound_rejects_bad_input(benchmark_script):
    """Rows or a prior of the wrong dimension, or a non-finite v_ref: typed errors naming them."""
    module = benchmark_script("trace_parameter_boxes")
    rows, prior, _ = _free_driving_rows(0.3, 8.0, 8.0, 40, lambda n: 0.0, lambda n: 0.0)
    with pytest.raises(DimensionError, match="prior of dimension 3"):
        module.speed_offset_bound(rows, Box(prior.low[:3], prior.high[:3]), 8.0)
    with pytest.raises(InputError, match="v_ref"):
        module.speed_offset_bound(rows, prior, float("nan"))


def test_parameter_box_trace_reads_every_belief_and_restores_the_learner(benchmark_script):
    """trace() on Table 4's T-junction seed 0 (a goal): one width row per belief, ratios in (0, 1], and the
    learner's method restored."""
    module = benchmark_script("trace_parameter_boxes")
    before = traffic_learning.TrafficLearner.beliefs
    outcome, widths, offsets = module.trace("tjunction", 0)
    assert traffic_learning.TrafficLearner.beliefs is before
    assert outcome == "goal"
    w = np.array(widths)
    assert len(w) > 0 and np.all(w[:, 1:] > 0) and np.all(w[:, 1:] <= 1.0)
    assert all(age >= 0 and ratio >= 0 for age, ratio in offsets)
    assert module.summary(w, np.array(offsets))[2].startswith("| 0-20 |")


def test_told_beliefs_hold_the_truth_at_each_level(benchmark_script):
    """ablate_tjunction_knowledge.told_beliefs: the true parameters in narrow boxes, only routes on the true
    route (when told), the exact target speed only at the top level."""
    module = benchmark_script("ablate_tjunction_knowledge")
    world = make_road_world("tjunction", 3)
    learner = TrafficLearner(world.road, world.scenario)
    for _ in range(5):
        learner.observe(world.measure())
        world.apply(np.zeros(2))
    traffic = world.traffic
    beliefs = learner.beliefs()
    assert beliefs
    for level in module.LEVELS:
        told = module.told_beliefs(beliefs, traffic, level)
        assert told.keys() == beliefs.keys()
        for agent, belief in told.items():
            ta, tb = traffic.theta_a[agent], traffic.theta_b[agent]
            assert np.all(belief.theta_a.low <= ta) and np.all(ta <= belief.theta_a.high)
            assert np.all(belief.theta_b.low <= tb) and np.all(tb <= belief.theta_b.high)
            assert np.all(belief.theta_a.high - belief.theta_a.low <= 2.01 * module.PAD * np.abs(ta))
            true_route = [int(lane) for lane in traffic.routes[agent] if lane >= 0]
            if level == "parameters":
                assert belief.routes == beliefs[agent].routes
            else:
                assert set(belief.routes) <= set(beliefs[agent].routes)
                assert all(module._on_route(r, true_route) for r in belief.routes)
            if level == "parameters+route+target":
                assert belief.target_speed == (traffic.target_speed[agent],) * 2
            else:
                assert belief.target_speed is None


def test_knowledge_ablation_restores_the_method(benchmark_script):
    """run() patches the learner and the method for one episode only (Table 4's T-junction seed 0)."""
    module = benchmark_script("ablate_tjunction_knowledge")
    before = (traffic_learning.TrafficLearner.beliefs, road_planning._LearningMethod._learn)
    seed, outcome, _, missed, checked = module.run(0, "parameters")
    assert (traffic_learning.TrafficLearner.beliefs, road_planning._LearningMethod._learn) == before
    assert (seed, outcome, missed) == (0, "goal", 0) and checked > 0
