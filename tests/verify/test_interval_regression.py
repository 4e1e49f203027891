"""The interval-regression LP: sound verdicts proven both ways, sound parameter boxes, units invariance."""

from types import SimpleNamespace
from unittest.mock import patch

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import Box
from minimaxplan.models.errors import DimensionError, InputError, NoConsistentModel
from minimaxplan.verify import (
    IntervalRows,
    interval_consistency,
    interval_parameter_box,
    interval_regression,
)
from minimaxplan.verify.interval_regression import INTERVAL_ELIMINATION_MARGIN, WITNESS_DEPTH, witness_margin

PRIOR = Box([0.15, 0.15, 1.0], [0.45, 0.45, 3.0])


def _rows(rng, theta, k, *, extreme: bool, width: float = 0.5, noise: float = 0.2):
    """Rows explained by theta: true g inside [g_lo, g_hi], true y inside [y_lo, y_hi] (at an end if extreme)."""
    g = rng.normal(size=(k, theta.size)) * 5
    below, above = rng.uniform(0, width, size=(2, k, theta.size))
    if extreme:  # the true regressor at a corner of its interval
        corner = rng.integers(0, 2, size=(k, theta.size)).astype(bool)
        below, above = np.where(corner, 0.0, below), np.where(corner, above, 0.0)
    y = g @ theta
    lo, hi = rng.uniform(0, noise, size=(2, k))
    if extreme:
        side = rng.integers(0, 2, size=k).astype(bool)
        lo, hi = np.where(side, 0.0, lo), np.where(side, hi, 0.0)
    return IntervalRows(g - below, g + above, y - lo, y + hi)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(1, 60), extreme=st.booleans())
def test_true_parameter_never_eliminated_and_inside_the_box(seed, k, extreme):
    rng = np.random.default_rng(seed)
    theta = rng.uniform(PRIOR.low, PRIOR.high)
    rows = _rows(rng, theta, k, extreme=extreme)
    verdict = interval_consistency(rows, PRIOR)
    assert verdict.status != "inconsistent"
    assert PRIOR.contains(verdict.witness)
    box = interval_parameter_box(rows, PRIOR, verdict=verdict)
    assert box.contains(theta)
    assert np.all(box.low >= PRIOR.low) and np.all(box.high <= PRIOR.high)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_one_sided_rows_and_true_parameter(seed):
    """Rows through a saturation keep one side only (the other infinite): still sound."""
    rng = np.random.default_rng(seed)
    theta = rng.uniform(PRIOR.low, PRIOR.high)
    rows = _rows(rng, theta, 30, extreme=True)
    ylo, yhi = rows.target_low.copy(), rows.target_high.copy()
    ylo[::3] = -np.inf
    yhi[1::3] = np.inf
    one_sided = IntervalRows(rows.regressor_low, rows.regressor_high, ylo, yhi)
    assert one_sided.nrows == 30
    assert interval_parameter_box(one_sided, PRIOR).contains(theta)


def test_a_clear_inconsistency_is_certified_and_rechecked():
    rng = np.random.default_rng(1)
    theta = np.array([0.3, 0.3, 2.0])
    rows = _rows(rng, theta, 40, extreme=False)
    shifted = IntervalRows(rows.regressor_low, rows.regressor_high, rows.target_low + 50, rows.target_high + 50)
    verdict = interval_consistency(shifted, PRIOR)
    assert verdict.status == "inconsistent" and verdict.eliminated
    assert verdict.lower > INTERVAL_ELIMINATION_MARGIN
    assert verdict.certificate.recheck(shifted, PRIOR) == pytest.approx(verdict.lower, rel=1e-9)
    # the same multipliers prove nothing about consistent rows
    assert verdict.certificate.recheck(rows, PRIOR) <= INTERVAL_ELIMINATION_MARGIN
    with pytest.raises(NoConsistentModel):
        interval_parameter_box(shifted, PRIOR)
    assert verdict.to_dict()["status"] == "inconsistent"


def test_consistent_verdict_has_a_rechecked_witness():
    rng = np.random.default_rng(2)
    rows = _rows(rng, np.array([0.2, 0.4, 1.5]), 50, extreme=True)
    verdict = interval_consistency(rows, PRIOR)
    assert verdict.status == "consistent" and verdict.certificate is None
    assert witness_margin(rows, PRIOR, verdict.witness) <= INTERVAL_ELIMINATION_MARGIN


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), shift=st.sampled_from([0.0, 3.0, 50.0]))
def test_verdicts_and_boxes_do_not_depend_on_units(seed, shift):
    """Rows scaled by 1e-3..1e3 each and parameters by 1e-2..1e2: same verdict, box scaled alike."""
    rng = np.random.default_rng(seed)
    theta = rng.uniform(PRIOR.low, PRIOR.high)
    rows = _rows(rng, theta, 25, extreme=True)
    rows = IntervalRows(rows.regressor_low, rows.regressor_high, rows.target_low + shift, rows.target_high + shift)
    r = 10.0 ** rng.uniform(-3, 3, size=rows.nrows)
    c = 10.0 ** rng.uniform(-2, 2, size=3)
    scaled_prior = Box(PRIOR.low * c, PRIOR.high * c)
    a = interval_consistency(rows, PRIOR)
    b = interval_consistency(rows.scaled(r, c), scaled_prior)
    assert a.status == b.status
    if not a.eliminated:
        box_a = interval_parameter_box(rows, PRIOR, verdict=a)
        box_b = interval_parameter_box(rows.scaled(r, c), scaled_prior, verdict=b)
        np.testing.assert_allclose(box_b.low / c, box_a.low, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(box_b.high / c, box_a.high, rtol=1e-6, atol=1e-9)


def test_point_regressors_allow_any_sign_and_linear_relations():
    """c = theta_1 v with v in [20, 25]: two exact rows on a point regressor with a negative entry."""
    prior = Box([0.15, 0.0], [0.45, 20.0])
    relation = IntervalRows([[-20.0, 1.0], [-25.0, 1.0]], [[-20.0, 1.0], [-25.0, 1.0]], [0.0, -np.inf], [np.inf, 0.0])
    box = interval_parameter_box(relation, prior)
    assert box.low[1] == pytest.approx(0.15 * 20, rel=1e-6) and box.high[1] == pytest.approx(0.45 * 25, rel=1e-6)
    bad = IntervalRows(
        [[-20.0, 1.0], [-25.0, 1.0], [1.0, 0.0]],
        [[-20.0, 1.0], [-25.0, 1.0], [1.0, 0.0]],
        [0.0, -np.inf, 0.5],
        [np.inf, 0.0, 0.6],
    )
    assert interval_consistency(bad, prior).eliminated  # theta_1 > 0.45


def test_bad_inputs_are_rejected():
    with pytest.raises(DimensionError, match="regressor_high"):
        IntervalRows(np.zeros((2, 3)), np.zeros((2, 2)), np.zeros(2), np.zeros(2))
    with pytest.raises(InputError, match="NaN"):
        IntervalRows(np.zeros((1, 2)), np.zeros((1, 2)), [np.nan], [1.0])
    with pytest.raises(InputError, match="regressor_low > regressor_high"):
        IntervalRows(np.ones((1, 2)), np.zeros((1, 2)), [0.0], [1.0])
    with pytest.raises(InputError, match="finite"):
        IntervalRows([[np.inf, 0.0]], [[np.inf, 0.0]], [0.0], [1.0])
    rows = IntervalRows([[0.0, 1.0]], [[1.0, 1.0]], [0.0], [1.0])
    with pytest.raises(InputError, match="below 0"):
        interval_consistency(rows, Box([-1.0, 0.0], [1.0, 1.0]))
    with pytest.raises(DimensionError, match="dimension"):
        interval_consistency(rows, PRIOR)
    # rows infinite on both sides say nothing and are dropped
    assert IntervalRows([[0.0, 1.0]], [[1.0, 1.0]], [-np.inf], [np.inf]).nrows == 0


@st.composite
def _single_rows(draw):
    """One row in random units: interval and point regressors, targets one- or two-sided, thin or wide."""
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    d = int(rng.integers(1, 7))
    low = rng.uniform(0, 1, d) * (rng.random(d) < 0.8)
    high = low + rng.uniform(0, 2, d) * (rng.random(d) < 0.9)
    g = rng.normal(size=(1, d)) * 10 ** rng.uniform(-3, 3)
    g[0, rng.random(d) < 0.15] = 0.0
    half = rng.uniform(0, 1, (1, d)) * (rng.random((1, d)) < 0.7) * np.abs(g).max(initial=1.0)
    y = float(rng.normal() * 10 ** rng.uniform(-3, 3))
    width = float(abs(rng.normal()) * 10 ** rng.uniform(-6, 2))
    sides = draw(st.sampled_from(["both", "both", "both", "upper", "lower"]))  # two sides: the dual has a weight
    y_lo = -np.inf if sides == "upper" else y - width
    y_hi = np.inf if sides == "lower" else y + width
    return IntervalRows(g - half, g + half, [y_lo], [y_hi]), Box(low, high)


@settings(max_examples=300, deadline=None)
@given(case=_single_rows())
def test_single_row_closed_form_is_the_lp_optimum(case):
    """One row is solved in closed form: its margin is HiGHS's optimum of the same LP, and both
    proofs hold (the witness needs what the margin says; the multipliers bound it from below)."""
    from minimaxplan.verify.interval_regression import _Scaled, _solve, _solve_single_row

    rows, prior = case
    scaled = _Scaled(rows, prior, 1e-9)
    t, s, mu = _solve_single_row(scaled)
    _, s_highs, _ = _solve(scaled, np.zeros(rows.nparams), None)
    assert s == pytest.approx(s_highs, abs=1e-9)
    assert np.all(t >= scaled.low) and np.all(t <= scaled.high)
    assert float(np.max(scaled.needed(t * scaled.theta_scale))) <= max(s, 0.0) + 1e-12
    bound = scaled.lower_bound(mu, np.zeros(rows.nparams), 0.0, True)
    if s > -WITNESS_DEPTH:
        assert bound == pytest.approx(s_highs, abs=1e-9)
    else:  # both LPs stop at the floor; the dual bound is the true optimum below it
        assert s_highs == pytest.approx(-WITNESS_DEPTH) and bound <= -WITNESS_DEPTH + 1e-9
    verdict = interval_consistency(rows, prior)
    if verdict.eliminated:
        assert verdict.certificate.recheck(rows, prior) > INTERVAL_ELIMINATION_MARGIN
    else:
        assert verdict.status == "consistent"
        assert witness_margin(rows, prior, verdict.witness) <= INTERVAL_ELIMINATION_MARGIN


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), extreme=st.booleans())
def test_single_row_never_eliminates_its_true_parameter(seed, extreme):
    """A row made by a parameter of the prior (at the ends of every interval if extreme) is explained."""
    rng = np.random.default_rng(seed)
    theta = rng.uniform(PRIOR.low, PRIOR.high)
    if extreme:
        theta = np.where(rng.random(3) < 0.5, PRIOR.low, PRIOR.high)
    rows = _rows(rng, theta, 1, extreme=extreme, width=rng.choice([0.0, 0.5]), noise=rng.choice([0.0, 0.2]))
    verdict = interval_consistency(rows, PRIOR)
    assert verdict.status == "consistent"
    assert witness_margin(rows, PRIOR, verdict.witness) <= INTERVAL_ELIMINATION_MARGIN


@settings(max_examples=100, deadline=None)
@given(case=_single_rows(), seed=st.integers(0, 2**31 - 1))
def test_single_row_verdict_does_not_depend_on_units(case, seed):
    """One row scaled by 1e-3..1e3 and its parameters by 1e-2..1e2: the same verdict and margin."""
    rows, prior = case
    rng = np.random.default_rng(seed)
    r = 10.0 ** rng.uniform(-3, 3, size=1)
    c = 10.0 ** rng.uniform(-2, 2, size=rows.nparams)
    a = interval_consistency(rows, prior)
    b = interval_consistency(rows.scaled(r, c), Box(prior.low * c, prior.high * c))
    assert a.status == b.status
    assert a.margin == pytest.approx(b.margin, abs=1e-9)


def test_a_parameter_fixed_at_zero_leaves_the_margin_unit_free():
    """A coordinate whose prior is [0, 0] adds nothing to a row's magnitude, in any units of its regressor."""
    rng = np.random.default_rng(3)
    prior = Box([0.15, 0.0, 1.0], [0.45, 0.0, 3.0])
    rows = _rows(rng, np.array([0.3, 0.0, 2.0]), 12, extreme=False)
    rows = IntervalRows(rows.regressor_low, rows.regressor_high, rows.target_low + 3.0, rows.target_high + 3.0)
    c = np.array([1.0, 1e-3, 1.0])
    a = interval_consistency(rows, prior)
    b = interval_consistency(rows.scaled(np.ones(rows.nrows), c), Box(prior.low * c, prior.high * c))
    assert a.margin > 1e-3  # shifted rows: a margin worth comparing
    assert a.status == b.status and a.margin == pytest.approx(b.margin, rel=1e-9)
    consistent = IntervalRows(rows.regressor_low, rows.regressor_high, rows.target_low - 3.0, rows.target_high - 3.0)
    box_a = interval_parameter_box(consistent, prior)
    box_b = interval_parameter_box(consistent.scaled(np.ones(rows.nrows), c), Box(prior.low * c, prior.high * c))
    np.testing.assert_allclose(box_b.low / c, box_a.low, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(box_b.high / c, box_a.high, rtol=1e-6, atol=1e-9)


def _box_with_and_without_the_shortcut(rows, prior, verdict):
    """The box, and the box with an LP for every side; and how many LPs the first solved."""
    solved = []
    solve = interval_regression._solve

    def counting(*args):
        solved.append(args)
        return solve(*args)

    with patch.object(interval_regression, "_solve", counting):
        box = interval_parameter_box(rows, prior, verdict=verdict)
    with patch.object(interval_regression, "_meets_every_inequality", return_value=False):
        every_side = interval_parameter_box(rows, prior, verdict=verdict)
    return box, every_side, len(solved)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    k=st.integers(1, 40),
    extreme=st.booleans(),
    width=st.sampled_from([0.05, 0.5, 3.0]),
    noise=st.sampled_from([0.01, 0.2, 5.0]),
    shift=st.sampled_from([0.0, 1e-3, 0.3]),
    units=st.floats(-2.0, 2.0),
)
def test_a_side_the_witness_attains_is_the_lps_side_bit_for_bit(seed, k, extreme, width, noise, shift, units):
    """Skipping the LP of a side the shifted witness attains gives the box the 2d LPs give, to the bit.

    Rows from a parameter of the prior (regressors and targets at their interval's ends when
    ``extreme``), narrow to wide, shifted off it up to an inconsistency within the tolerance or
    beyond (then nothing to compare), in units 1e-2..1e2.
    """
    rng = np.random.default_rng(seed)
    c = np.full(PRIOR.dim, 10.0**units)
    prior = Box(PRIOR.low * c, PRIOR.high * c)
    theta = rng.uniform(prior.low, prior.high)
    rows = _rows(rng, theta, k, extreme=extreme, width=width * 10.0**-units, noise=noise)
    rows = IntervalRows(rows.regressor_low, rows.regressor_high, rows.target_low + shift, rows.target_high + shift)
    verdict = interval_consistency(rows, prior)
    if verdict.eliminated:
        return
    box, every_side, solved = _box_with_and_without_the_shortcut(rows, prior, verdict)
    assert box.low.tobytes() == every_side.low.tobytes() and box.high.tobytes() == every_side.high.tobytes()
    # a side that is not the prior's was solved for
    constrained = int(np.sum(box.low > prior.low) + np.sum(box.high < prior.high))
    assert constrained <= solved <= 2 * prior.dim


def test_the_shortcut_skips_the_sides_the_rows_do_not_bound():
    """Two rows bound few sides: most are the prior's and need no LP; the box is the same."""
    rng = np.random.default_rng(5)
    rows = _rows(rng, np.array([0.3, 0.3, 2.0]), 2, extreme=False, width=2.0, noise=3.0)
    verdict = interval_consistency(rows, PRIOR)
    box, every_side, solved = _box_with_and_without_the_shortcut(rows, PRIOR, verdict)
    assert solved < 2 * PRIOR.dim
    assert box.low.tobytes() == every_side.low.tobytes() and box.high.tobytes() == every_side.high.tobytes()


def test_a_point_is_not_taken_to_meet_a_row_that_only_rounding_satisfies():
    """1 + 1e-17 <= 1 holds in floating point, not in exact arithmetic: not proven."""
    meets = interval_regression._meets_every_inequality
    row = SimpleNamespace(a=np.array([[1.0, 1e-17]]), b=np.array([1.0]))
    assert float(row.a[0] @ np.ones(2) - row.b[0]) <= 0.0  # what an unguarded check would accept
    assert not meets(row, np.ones(2), 0.0)
    assert meets(row, np.array([1.0 - 1e-9, 1.0]), 0.0)
    assert not meets(row, np.array([1.0 - 1e-9, 1.0]), -1e-8)  # a negative slack tightens the row


def test_bad_coordinates_and_a_verdict_of_other_rows_are_refused():
    """A negative coordinate would wrap round to the last one; a verdict of other rows has another size."""
    rng = np.random.default_rng(6)
    rows = _rows(rng, np.array([0.3, 0.3, 2.0]), 5, extreme=False)
    for bad in ((-1,), (3,), (0.5,), ((0, 1),)):
        with pytest.raises(InputError, match="coordinates"):
            interval_parameter_box(rows, PRIOR, coordinates=bad)
    other = _rows(rng, np.array([0.3, 2.0]), 5, extreme=False)
    verdict = interval_consistency(other, Box([0.15, 1.0], [0.45, 3.0]))
    with pytest.raises(DimensionError, match="verdict.witness"):
        interval_parameter_box(rows, PRIOR, verdict=verdict)
    full = interval_parameter_box(rows, PRIOR)
    some = interval_parameter_box(rows, PRIOR, coordinates=iter([np.int64(2), 0]))
    assert some.low[[0, 2]].tobytes() == full.low[[0, 2]].tobytes() and some.low[1] == PRIOR.low[1]
