"""The proven invariant parallelograms of the lateral closed loop (`lateral_invariant`)."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.scenarios.lateral_invariant import (
    FAMILY_WIDTH,
    HEADING_RATIO,
    InvariantSets,
    check_invariance,
    invariant_sets,
)
from minimaxplan.scenarios.vehicles import (
    BehaviourParameters,
    VehicleParameters,
    bicycle_step,
    linear_steering,
    steering_features,
)

VEHICLE = VehicleParameters()
BEHAVIOUR = BehaviourParameters()
K = 2.0 / VEHICLE.length
DTS = (0.05, 0.1, 0.2)


def _world_step(e, chi, v, theta_b, dt, heading=0.0):
    """The world's own step (law, bicycle) of vehicles on a straight lane through the origin with this heading.

    Returns the offset and heading error after the step, read in the lane's frame as the world reads them.
    """
    n = e.shape[0]
    u = np.array([np.cos(heading), np.sin(heading)])
    nrm = np.array([-u[1], u[0]])
    xy = 50.0 * u[None, :] + e[:, None] * nrm[None, :]
    g = steering_features(np.full(n, heading), heading + chi, e, v, VEHICLE.length, BEHAVIOUR.speed_epsilon)
    steer = linear_steering(theta_b, g, VEHICLE.max_steering)
    nxt = bicycle_step(np.stack([xy[:, 0], xy[:, 1], v, heading + chi], 1), np.zeros(n), steer, dt, VEHICLE)
    return nxt[:, :2] @ nrm, nxt[:, 3] - heading


def _inside(e, chi, offset, margin, widen=FAMILY_WIDTH):
    """Membership in ``S(E (1 + widen))``."""
    top = 1.0 + widen
    return (np.abs(e) <= offset * top) & (np.abs(chi - K * e) <= margin * top)


@pytest.mark.parametrize("dt", DTS)
def test_the_table_is_proven_nested_and_covers_the_junction_speeds(dt):
    """Every row is a proven certificate; the sets grow; at dt = 0.1 s they cover the junction's speeds (<= 9 m/s)."""
    sets = invariant_sets(dt, VEHICLE, BEHAVIOUR)
    assert len(sets) > 0
    assert all(c.proven and c.boxes > 0 for c in sets.certificates)
    assert np.all(np.diff(sets.offsets) > 0)
    np.testing.assert_allclose(sets.heading_margins, HEADING_RATIO * K * sets.offsets)
    assert not sets.offsets.flags.writeable and not sets.speed_bounds.flags.writeable
    if dt == 0.1:
        assert sets.offsets[0] <= 0.15 and sets.speed_bounds[0] >= 10.0
    assert sets.to_dict()["certificates"][0]["status"] == "proven"


@given(
    dt=st.sampled_from(DTS),
    row=st.integers(0, 10),
    heading=st.floats(-np.pi, np.pi),
    steps=st.integers(1, 60),
    seed=st.integers(0, 2**31),
)
def test_every_proven_set_holds_the_world_under_switching_speeds(dt, row, heading, steps, seed):
    """States of a proven set stay in it through the world's own step, for any lane heading, with the speed
    switching at every step anywhere in ``[0, v_bar]`` (its ends and standstill included) and the gains at
    their box's corners or inside; the set's vertices and faces are among the starting points."""
    sets = invariant_sets(dt, VEHICLE, BEHAVIOUR)
    i = row % len(sets)
    offset, margin, vbar = sets.offsets[i], sets.heading_margins[i], sets.speed_bounds[i]
    rng = np.random.default_rng(seed)
    n = 300
    t, s = rng.uniform(-1.0, 1.0, n), rng.uniform(-1.0, 1.0, n)
    t[:40] = rng.choice([-1.0, 1.0], 40)  # the offset faces
    s[20:60] = rng.choice([-1.0, 1.0], 40)  # the heading faces (the vertices where both)
    e = t * offset
    chi = s * margin + K * e
    lo, hi = sets.theta_b_low, sets.theta_b_high
    gains = rng.uniform(lo, hi, (n, 2))
    corner = rng.random(n) < 0.5
    gains[corner] = np.where(rng.random((int(corner.sum()), 2)) < 0.5, lo, hi)
    for _ in range(steps):
        v = rng.uniform(0.0, vbar, n)
        pick = rng.random(n)
        v = np.where(pick < 0.15, vbar, np.where(pick < 0.25, 0.0, np.where(pick < 0.35, 1e-3, v)))
        e, chi = _world_step(e, chi, v, gains, dt, heading)
        assert np.all(_inside(e, chi, offset, margin)), (dt, i, np.abs(e).max(), np.abs(chi - K * e).max())


def test_a_refuted_set_has_a_counterexample_that_the_world_confirms():
    """The verifier can say no: a set too small for the speeds (one step crosses it) is refuted, and the world's
    own step takes the returned point out of the set."""
    cert = check_invariance(0.1, 12.0, 0.1, vehicle=VEHICLE, behaviour=BEHAVIOUR)
    assert cert.status == "refuted" and not cert.proven
    e, chi, v, b1, b2 = cert.counterexample
    assert abs(e) <= 0.1 and abs(chi - K * e) <= cert.heading_margin and 0.0 <= v <= 12.0
    e1, chi1 = _world_step(np.array([e]), np.array([chi]), np.array([v]), np.array([[b1, b2]]), 0.1)
    assert not _inside(e1, chi1, 0.1, cert.heading_margin, widen=0.0)[0]
    assert cert.to_dict()["face"] == cert.face and cert.face in ("offset", "heading")


def test_a_spent_budget_is_inconclusive_and_the_speed_bound_matters():
    """A tiny budget decides nothing ("inconclusive"); a proven set is refuted at speeds beyond its bound."""
    assert check_invariance(0.3, 12.5, 0.1, max_boxes=3).status == "inconclusive"
    assert check_invariance(0.3, 12.5, 0.1).status == "proven"
    assert check_invariance(0.3, 30.0, 0.1).status == "refuted"
    # a gain box beyond the prior is a different question, answered on its own
    wide = (np.array([1.0, 1.0]), np.array([5.07, 9.83]))
    assert check_invariance(0.3, 12.5, 0.1, theta_b=wide).status != "proven"


@given(
    lo=st.tuples(st.floats(-0.8, 0.8), st.floats(-0.8, 0.8)),
    width=st.tuples(st.floats(0.0, 0.6), st.floats(0.0, 0.6)),
    seed=st.integers(0, 2**31),
)
def test_containment_and_tightening_are_exact_on_boxes(lo, width, seed):
    """A box is reported inside the smallest set that holds its four corners (a convex set holds the box iff it
    holds them); tightening keeps every point of the box that lies in the set and nothing outside its hull."""
    sets = invariant_sets(0.1, VEHICLE, BEHAVIOUR)
    b_lo = np.array([lo])
    b_hi = b_lo + np.array([width])
    corners = np.array(
        [[b_lo[0, 0], b_lo[0, 1]], [b_lo[0, 0], b_hi[0, 1]], [b_hi[0, 0], b_lo[0, 1]], [b_hi[0, 0], b_hi[0, 1]]]
    )
    holds = [
        bool(np.all(_inside(corners[:, 0], corners[:, 1], sets.offsets[i], sets.heading_margins[i], 0.0)))
        for i in range(len(sets))
    ]
    expect = holds.index(True) if any(holds) else -1
    assert sets.smallest_containing(b_lo, b_hi)[0] == expect
    # nested: a box in a set lies in every larger one (what merging two units' sets relies on)
    assert all(holds[expect:]) if expect >= 0 else not any(holds)
    rng = np.random.default_rng(seed)
    pts = rng.uniform(b_lo[0], b_hi[0], (400, 2))
    for i in range(len(sets)):
        t_lo, t_hi = sets.tighten([i], b_lo, b_hi)
        keep = _inside(pts[:, 0], pts[:, 1], sets.offsets[i], sets.heading_margins[i], 0.0)
        inside_t = np.all((pts >= t_lo[0]) & (pts <= t_hi[0]), axis=1)
        assert np.all(inside_t[keep])
        top = 1.0 + FAMILY_WIDTH
        assert np.all(np.abs(t_lo[0, 0]) <= sets.offsets[i] * top + 1e-12 or t_lo[0, 0] > t_hi[0, 0])


def test_bad_input_is_refused_with_typed_errors():
    sets = invariant_sets(0.1, VEHICLE, BEHAVIOUR)
    with pytest.raises(InputError, match="offset"):
        check_invariance(0.0, 5.0, 0.1)
    with pytest.raises(InputError, match="speed_bound"):
        check_invariance(0.3, -1.0, 0.1)
    with pytest.raises(InputError, match="dt"):
        check_invariance(0.3, 5.0, float("nan"))
    with pytest.raises(InputError, match="max_boxes"):
        check_invariance(0.3, 5.0, 0.1, max_boxes=0)
    with pytest.raises(InputError, match="max_boxes"):
        check_invariance(0.3, 5.0, 0.1, max_boxes="many")
    with pytest.raises(DimensionError, match=r"theta_b.*\(3,\)"):
        check_invariance(0.3, 5.0, 0.1, theta_b=(np.ones(3), np.ones(3)))
    with pytest.raises(InputError, match="theta_b"):
        check_invariance(0.3, 5.0, 0.1, theta_b=(np.array([5.0, 9.0]), np.array([4.0, 9.0])))
    with pytest.raises(DimensionError, match=r"lo and hi.*\(3,\)"):
        sets.smallest_containing(np.zeros(3), np.zeros(3))
    with pytest.raises(InputError, match="index"):
        sets.tighten([len(sets)], np.zeros((1, 2)), np.zeros((1, 2)))
    with pytest.raises(DimensionError, match=r"lo and hi.*\(1, 2\)"):
        sets.tighten([0], np.zeros((2, 2)), np.zeros((2, 2)))
    with pytest.raises(InputError, match="dt"):
        invariant_sets(-0.1, VEHICLE, BEHAVIOUR)
    # a table that is not nested, smallest first, would make smallest_containing pick a wrong set
    fields = dict(
        offsets=sets.offsets,
        heading_margins=sets.heading_margins,
        speed_bounds=sets.speed_bounds,
        theta_b_low=sets.theta_b_low,
        theta_b_high=sets.theta_b_high,
        dt=sets.dt,
        slope=sets.slope,
    )
    with pytest.raises(InputError, match="increasing"):
        InvariantSets(**{**fields, "offsets": sets.offsets[::-1]})
    with pytest.raises(DimensionError, match="speed_bounds"):
        InvariantSets(**{**fields, "speed_bounds": sets.speed_bounds[:-1]})
    with pytest.raises(InputError, match="slope"):
        InvariantSets(**{**fields, "slope": 0.0})
