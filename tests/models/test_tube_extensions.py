"""predict_tube with one parameter set per step, box-valued inputs and per-step disturbance boxes.

The guarantee (eq. (7)): for every theta_n in P_n (switching at every step), every u_n in
U_n, every w_n in W_n and every x0 in the box, lower[n] <= x_n <= upper[n] for the EXACT
x_n. Checked on floating-point simulations (with `Tube.contains`' rounding slack, as
test_prediction.py does) at the extremes and inside the sets, and, without any slack, on
trajectories computed in exact rational arithmetic.
"""

import itertools
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import (
    Box,
    DimensionError,
    EmptySetError,
    InputError,
    IntervalPredictor,
    NonFiniteError,
    UncertainLinearSystem,
    VertexPolytope,
    predict_tube,
    prediction,
)

from .test_prediction import random_basis, random_ellipsoid, random_system, sample_initial_states

HORIZON = 10


# ----------------------------------------------------------------------------- helpers
def random_parameter_set(rng, kind, d):
    """A random Box, Ellipsoid or vertex array (1 to 5 vertices) of dimension d."""
    if kind == "box":
        return Box.from_center(rng.normal(size=d) * 0.2, rng.uniform(0.0, 0.4, size=d))
    if kind == "ellipsoid":
        return random_ellipsoid(rng, d)
    return rng.normal(size=(int(rng.integers(1, 6)), d)) * 0.3


def points_in(rng, parameter_set, n):
    """n points of the set: half of them extreme (a vertex, or on the ellipsoid's boundary), half inside."""
    extreme = rng.integers(2, size=n).astype(bool)
    if isinstance(parameter_set, Box):
        corners = parameter_set.vertices()[rng.integers(2**parameter_set.dim, size=n)]
        inside = rng.uniform(parameter_set.low, parameter_set.high, size=corners.shape)
        return np.where(extreme[:, None], corners, inside)
    if isinstance(parameter_set, np.ndarray):
        vertices = parameter_set
        inside = rng.dirichlet(np.ones(len(vertices)), size=n) @ vertices
        return np.where(extreme[:, None], vertices[rng.integers(len(vertices), size=n)], inside)
    ellipsoid = parameter_set
    directions = rng.normal(size=(n, ellipsoid.dim))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    directions *= np.where(extreme, 1.0, rng.uniform(0, 1, size=n))[:, None]
    offsets = np.linalg.solve(np.linalg.cholesky(ellipsoid.gramian).T, directions.T).T * ellipsoid.radius
    return ellipsoid.center + offsets


def random_step_boxes(rng, steps, dim, scale):
    """(lower, upper) arrays (steps, dim), some sides degenerate."""
    centre = rng.normal(size=(steps, dim)) * scale
    radius = rng.uniform(0.0, scale, size=(steps, dim)) * (rng.uniform(size=(steps, dim)) > 0.2)
    return centre - radius, centre + radius


def points_in_boxes(rng, lower, upper, n):
    """(n, steps, dim): half of the trajectories take a random corner at every step, half interior points."""
    corners = np.where(rng.integers(2, size=(n,) + lower.shape).astype(bool), upper, lower)
    inside = rng.uniform(lower, upper, size=(n,) + lower.shape)
    return np.where(rng.integers(2, size=(n, 1, 1)).astype(bool), corners, inside)


def as_argument(form, lower, upper):
    """Per-step boxes in the requested form: a (lower, upper) pair or a list of Boxes."""
    if form == "pair":
        return lower, upper
    return [Box(lo, hi) for lo, hi in zip(lower, upper)]


def simulate_switching(system, x0s, thetas, inputs, disturbances):
    """Trajectories (n, H+1, p) of x+ = A(theta_n) x + B u_n + D w_n, a new theta, u, w per step and trajectory."""
    x, states = x0s, [x0s]
    for step in range(inputs.shape[1]):
        x = (
            np.einsum("nij,nj->ni", system.A(thetas[:, step]), x)
            + inputs[:, step] @ system.B.T
            + disturbances[:, step] @ system.D.T
        )
        states.append(x)
    return np.stack(states, axis=1)


def exact_entry(A0, phi, theta, i, j):
    """``A(theta)[i, j] = A0[i, j] + sum_m theta[m] phi[m, i, j]``, exactly."""
    return Fraction(A0[i][j]) + sum((Fraction(t) * Fraction(phi[m][i][j]) for m, t in enumerate(theta)), Fraction(0))


def exact_trajectory(system, x0, thetas, inputs, disturbances):
    """The same recursion in rational arithmetic: every float input taken exactly."""
    A0, phi = system.A0.tolist(), system.phi.tolist()
    B, D = system.B.tolist(), system.D.tolist()
    p = system.nstates
    x = [Fraction(v) for v in x0]
    out = [x]
    for theta, u, w in zip(thetas, inputs, disturbances):
        A = [[exact_entry(A0, phi, theta, i, j) for j in range(p)] for i in range(p)]
        x = [
            sum((A[i][j] * x[j] for j in range(p)), Fraction(0))
            + sum((Fraction(B[i][j]) * Fraction(u[j]) for j in range(len(u))), Fraction(0))
            + sum((Fraction(D[i][j]) * Fraction(w[j]) for j in range(len(w))), Fraction(0))
            for i in range(p)
        ]
        out.append(x)
    return out


def assert_contains_exactly(tube, trajectory):
    for n, x in enumerate(trajectory):
        for i, value in enumerate(x):
            assert Fraction(tube.lower[n, i]) <= value <= Fraction(tube.upper[n, i]), (n, i, float(value))


# ----------------------------------------------------------------------------- inclusion
@given(
    seed=st.integers(0, 2**32 - 1),
    p=st.integers(1, 5),
    d=st.integers(1, 3),
    q=st.integers(1, 2),
    dt=st.floats(0.01, 1.0),
    metzler=st.booleans(),
    kinds=st.sampled_from(["box", "ellipsoid", "vertices", "mixed"]),
    basis=st.sampled_from([None, "auto", "random"]),
    controls_form=st.sampled_from(["points", "pair", "boxes"]),
    disturbances_form=st.sampled_from([None, "pair", "boxes", "one box"]),
)
def test_switching_trajectories_stay_in_the_tube(
    seed, p, d, q, dt, metzler, kinds, basis, controls_form, disturbances_form
):
    rng = np.random.default_rng(seed)
    r = int(rng.integers(1, p + 1))
    system = random_system(rng, p, d, q, r, dt, metzler)
    sets = []
    for _ in range(HORIZON):  # a new set at most steps, sometimes the previous one again
        kind = str(rng.choice(["box", "ellipsoid", "vertices"])) if kinds == "mixed" else kinds
        sets.append(sets[-1] if sets and rng.uniform() < 0.3 else random_parameter_set(rng, kind, d))
    n = 40
    thetas = np.stack([points_in(rng, s, n) for s in sets], axis=1)  # (n, H, d): switching at every step
    if controls_form == "points":
        controls = rng.normal(size=(HORIZON, q))
        inputs = np.broadcast_to(controls, (n, HORIZON, q))
    else:
        u_lower, u_upper = random_step_boxes(rng, HORIZON, q, 0.5)
        controls = as_argument(controls_form, u_lower, u_upper)
        inputs = points_in_boxes(rng, u_lower, u_upper, n)
    if disturbances_form is None:
        disturbances = None
        w_lower, w_upper = np.tile(system.w.low, (HORIZON, 1)), np.tile(system.w.high, (HORIZON, 1))
    elif disturbances_form == "one box":
        disturbances = Box.from_center(rng.normal(size=r) * 0.1, rng.uniform(0.0, 0.3, size=r))
        w_lower, w_upper = np.tile(disturbances.low, (HORIZON, 1)), np.tile(disturbances.high, (HORIZON, 1))
    else:
        w_lower, w_upper = random_step_boxes(rng, HORIZON, r, 0.3)
        disturbances = as_argument(disturbances_form, w_lower, w_upper)
    x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.5, size=p))
    chosen = random_basis(rng, p) if basis == "random" else basis
    tube = predict_tube(system, x0, controls, sets, basis=chosen, disturbances=disturbances)
    assert tube.lower.shape == tube.upper.shape == (HORIZON + 1, p)
    assert tube.guaranteed and np.all(tube.lower <= tube.upper)
    states = simulate_switching(
        system, sample_initial_states(rng, x0, n), thetas, inputs, points_in_boxes(rng, w_lower, w_upper, n)
    )
    assert tube.contains(states)


@settings(max_examples=25)
@given(
    seed=st.integers(0, 2**32 - 1),
    p=st.integers(1, 3),
    d=st.integers(1, 2),
    dt=st.floats(0.01, 1.0),
    thin=st.booleans(),
    basis=st.sampled_from([None, "auto", "random"]),
)
def test_exact_extreme_trajectories_stay_in_the_tube(seed, p, d, dt, thin, basis):
    # No tolerance: the exact (rational) trajectories through vertices of every step's
    # parameter polytope, corners of the input and disturbance boxes and of x0. With thin
    # sets (one vertex, boxes one ulp wide, a point x0) the tube is as narrow as its own
    # outward rounding, so too small a margin would show.
    rng = np.random.default_rng(seed)
    steps, q, r = 8, 2, p
    system = random_system(rng, p, d, q, r, dt, metzler=False)
    if thin:
        vertex_sets = [rng.normal(size=(1, d)) * 0.3 for _ in range(steps)]
        u_lower = rng.normal(size=(steps, q))
        u_upper = np.nextafter(u_lower, np.inf)
        w_lower = rng.normal(size=(steps, r)) * 0.1
        w_upper = np.nextafter(w_lower, np.inf)
        x0 = Box.from_center(rng.normal(size=p), 0.0)
    else:
        vertex_sets = [rng.normal(size=(int(rng.integers(1, 4)), d)) * 0.3 for _ in range(steps)]
        u_lower, u_upper = random_step_boxes(rng, steps, q, 0.5)
        w_lower, w_upper = random_step_boxes(rng, steps, r, 0.2)
        x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.3, size=p))
    chosen = random_basis(rng, p) if basis == "random" else basis
    tube = predict_tube(system, x0, (u_lower, u_upper), vertex_sets, basis=chosen, disturbances=(w_lower, w_upper))
    for _ in range(4):
        thetas = [v[rng.integers(len(v))] for v in vertex_sets]
        inputs = np.where(rng.integers(2, size=u_lower.shape).astype(bool), u_upper, u_lower)
        disturbances = np.where(rng.integers(2, size=w_lower.shape).astype(bool), w_upper, w_lower)
        start = x0.vertices()[rng.integers(2**p)]
        assert_contains_exactly(tube, exact_trajectory(system, start, thetas, inputs, disturbances))


@given(
    seed=st.integers(0, 2**32 - 1),
    p=st.integers(1, 3),
    source=st.sampled_from(["inputs", "disturbances"]),
    basis=st.sampled_from([None, "random"]),
)
def test_rounding_of_the_input_and_disturbance_terms_is_covered(seed, p, source, basis):
    # From x0 = 0 the first step's box is the input (or disturbance) term alone, whose
    # rounding only its own margin covers: without it, a bound rounded inward would cut
    # the exact successor of a corner (checked in rational arithmetic, no tolerance).
    rng = np.random.default_rng(seed)
    q = r = 3
    system = UncertainLinearSystem(
        rng.normal(size=(p, p)),
        rng.normal(size=(1, p, p)) * 0.1,
        rng.normal(size=(p, q)),
        D=rng.normal(size=(p, r)),
        w=Box(np.zeros(r), np.zeros(r)),
        theta=Box(np.zeros(1), np.zeros(1)),
    )
    steps = 3
    zeros_u, zeros_w = np.zeros((steps, q)), np.zeros((steps, r))
    u_lower = rng.normal(size=(steps, q)) * 10 if source == "inputs" else zeros_u
    w_lower = rng.normal(size=(steps, r)) * 10 if source == "disturbances" else zeros_w
    u_upper, w_upper = np.nextafter(u_lower, np.inf), np.nextafter(w_lower, np.inf)
    parameters = [rng.normal(size=(1, 1)) for _ in range(steps)]
    chosen = random_basis(rng, p) if basis == "random" else None
    x0 = Box(np.zeros(p), np.zeros(p))
    tube = predict_tube(system, x0, (u_lower, u_upper), parameters, basis=chosen, disturbances=(w_lower, w_upper))
    for corner in range(4):
        pick = np.random.default_rng(corner).integers(2, size=(2, steps, 3)).astype(bool)
        inputs, disturbances = np.where(pick[0], u_upper, u_lower), np.where(pick[1], w_upper, w_lower)
        thetas = [v[0] for v in parameters]
        assert_contains_exactly(tube, exact_trajectory(system, np.zeros(p), thetas, inputs, disturbances))


@given(seed=st.integers(0, 2**32 - 1), p=st.integers(1, 3), d=st.integers(1, 2), dt=st.floats(0.01, 1.0))
def test_one_step_with_box_inputs_is_the_tightest_box(seed, p, d, dt):
    # The one-step bound equals the extremes over parameter vertices x initial corners x
    # input corners x disturbance corners, where the exact reachable set's extremes lie.
    rng = np.random.default_rng(seed)
    q = 2
    system = random_system(rng, p, d, q, p, dt, metzler=False)
    theta = Box.from_center(rng.normal(size=d) * 0.2, rng.uniform(0.0, 0.4, size=d))
    x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.5, size=p))
    u = Box.from_center(rng.normal(size=q), rng.uniform(0, 0.5, size=q))
    w = Box.from_center(rng.normal(size=p) * 0.1, rng.uniform(0, 0.3, size=p))
    tube = predict_tube(system, x0, [u], [theta], disturbances=[w])
    combos = itertools.product(theta.vertices(), x0.vertices(), u.vertices(), w.vertices())
    successors = np.array([system.step(x, uc, t, wc) for t, x, uc, wc in combos])
    scale = 1e-12 * (1 + np.abs(successors).max())
    np.testing.assert_allclose(tube.lower[1], successors.min(axis=0), rtol=0, atol=scale)
    np.testing.assert_allclose(tube.upper[1], successors.max(axis=0), rtol=0, atol=scale)


@given(seed=st.integers(0, 2**32 - 1), p=st.integers(1, 4), d=st.integers(1, 3), dt=st.floats(0.01, 1.0))
def test_smaller_step_sets_give_a_nested_tube(seed, p, d, dt):
    rng = np.random.default_rng(seed)
    system = random_system(rng, p, d, 1, p, dt, metzler=False)
    x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.5, size=p))
    u_lower, u_upper = random_step_boxes(rng, HORIZON, 1, 0.5)
    w_lower, w_upper = random_step_boxes(rng, HORIZON, p, 0.2)
    big = system.theta
    small = [Box(rng.uniform(big.low, big.center), rng.uniform(big.center, big.high)) for _ in range(HORIZON)]
    u_mid = rng.uniform(u_lower, u_upper)
    w_lo, w_hi = np.sort(rng.uniform(w_lower, w_upper, size=(2,) + w_lower.shape), axis=0)
    wide = predict_tube(system, x0, (u_lower, u_upper), disturbances=(w_lower, w_upper))
    narrow = predict_tube(system, x0, (u_mid, u_mid), small, disturbances=(w_lo, w_hi))
    slack = 1e-9 * (1 + np.abs(wide.lower) + np.abs(wide.upper))
    assert np.all(narrow.lower >= wide.lower - slack) and np.all(narrow.upper <= wide.upper + slack)


# ----------------------------------------------------------------------------- the old call, unchanged
@given(
    seed=st.integers(0, 2**32 - 1),
    p=st.integers(1, 5),
    d=st.integers(1, 3),
    dt=st.floats(0.01, 1.0),
    kind=st.sampled_from(["box", "ellipsoid", "vertices", "default"]),
    basis=st.sampled_from([None, "auto", "random"]),
)
def test_old_call_is_bit_identical_to_h_copies(seed, p, d, dt, kind, basis):
    rng = np.random.default_rng(seed)
    q = int(rng.integers(1, 3))
    system = random_system(rng, p, d, q, int(rng.integers(1, p + 1)), dt, metzler=bool(rng.integers(2)))
    parameters = None if kind == "default" else random_parameter_set(rng, kind, d)
    x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.5, size=p))
    controls = rng.normal(size=(HORIZON, q))
    chosen = random_basis(rng, p) if basis == "random" else basis
    old = predict_tube(system, x0, controls, parameters, basis=chosen)
    one = system.theta if parameters is None else parameters
    # The same set object H times, and H equal but distinct values.
    if isinstance(one, np.ndarray):
        copies = [one.copy() for _ in range(HORIZON)]
    elif isinstance(one, Box):
        copies = [Box(one.low, one.high) for _ in range(HORIZON)]
    else:
        copies = [one] * HORIZON
    w = system.w
    variants = [
        dict(controls=controls, parameters=[one] * HORIZON, disturbances=None),
        dict(controls=controls, parameters=copies, disturbances=w),
        dict(controls=(controls, controls.copy()), parameters=copies, disturbances=[w] * HORIZON),
        dict(
            controls=[Box(u, u) for u in controls],
            parameters=np.array(copies) if isinstance(one, np.ndarray) else copies,
            disturbances=(np.tile(w.low, (HORIZON, 1)), np.tile(w.high, (HORIZON, 1))),
        ),
    ]
    for variant in variants:
        new = predict_tube(
            system, x0, variant["controls"], variant["parameters"], basis=chosen, disturbances=variant["disturbances"]
        )
        assert new.lower.tobytes() == old.lower.tobytes() and new.upper.tobytes() == old.upper.tobytes()
        assert new.note == old.note
    # The predictor, for the same sets through with_sets and the disturbances keyword.
    predictor = IntervalPredictor(system, parameters, basis=chosen)
    for other in (
        predictor.with_sets(one, disturbances=Box(w.low, w.high)),
        IntervalPredictor(system, parameters, basis=chosen, disturbances=w),
    ):
        z = rng.normal(size=(5, p))
        u = rng.normal(size=(5, q))
        for a, b in zip(predictor.step(z - 0.1, z + 0.1, u), other.step(z - 0.1, z + 0.1, u)):
            assert a.tobytes() == b.tobytes()
        np.testing.assert_array_equal(other.basis, predictor.basis)


@given(seed=st.integers(0, 2**32 - 1), k=st.integers(1, 9), n=st.integers(1, 9))
def test_unique_rows_is_numpy_unique(seed, k, n):
    # The vertex matrices' order and selection must stay numpy.unique's (the old call's bits).
    rng = np.random.default_rng(seed)
    rows = rng.choice([-1.0, -0.0, 0.0, 0.5, 2.0], size=(k, n)) if rng.integers(2) else rng.normal(size=(k, n))
    rows[rng.uniform(size=k) < 0.3] = rows[0]
    assert prediction._unique_rows(rows).tobytes() == np.unique(rows, axis=0).tobytes()


def test_auto_basis_is_chosen_once_from_the_union_of_the_steps():
    # Far from nonnegative, real eigenvalues: "auto" adopts a basis, the same for every step,
    # chosen from the union of the steps' vertices (and the hull of the disturbance boxes).
    rng = np.random.default_rng(3)
    p, d = 3, 2
    S = random_basis(rng, p)
    nominal = S @ np.diag([0.9, 0.5, -0.2]) @ np.linalg.inv(S)
    system = UncertainLinearSystem(
        nominal,
        rng.normal(size=(d, p, p)) * 0.02,
        rng.normal(size=(p, 1)),
        w=Box.from_center(np.zeros(p), 0.01),
        theta=Box.from_center(np.zeros(d), 1.0),
    )
    sets = [rng.normal(size=(3, d)) * 0.5 for _ in range(HORIZON)]
    w_lower, w_upper = random_step_boxes(rng, HORIZON, p, 0.02)
    tube = predict_tube(
        system,
        Box.from_center(np.ones(p), 0.1),
        np.zeros((HORIZON, 1)),
        sets,
        basis="auto",
        disturbances=(w_lower, w_upper),
    )
    union = IntervalPredictor(
        system, np.vstack(sets), basis="auto", disturbances=Box(w_lower.min(axis=0), w_upper.max(axis=0))
    )
    assert tube.note.startswith("basis auto: ")
    assert "kept the identity" not in tube.note
    assert tube.note.split(",")[0] == union.basis_note.split(",")[0]


def test_box_inputs_between_the_point_tubes():
    # A box of inputs contains both constant controls at its ends: its tube contains theirs.
    rng = np.random.default_rng(5)
    system = random_system(rng, 3, 2, 1, 3, 0.3, metzler=False)
    x0 = Box.from_center(rng.normal(size=3), 0.1)
    low, high = np.full((HORIZON, 1), -1.0), np.full((HORIZON, 1), 2.0)
    tube = predict_tube(system, x0, (low, high))
    for controls in (low, high):
        inner = predict_tube(system, x0, controls)
        assert np.all(tube.lower <= inner.lower) and np.all(tube.upper >= inner.upper)
    assert np.all(tube.widths[1:] > predict_tube(system, x0, low).widths[1:])


# ----------------------------------------------------------------------------- errors
X0 = Box.from_center(np.zeros(2), 0.1)
U3 = np.zeros((3, 1))
THETA = Box.from_center(np.zeros(1), 0.1)
W = Box.from_center(np.zeros(2), 0.1)
NAN = float("nan")

BAD_CALLS = [
    # parameters, one per step
    (
        "per-step count",
        dict(parameters=[THETA, THETA]),
        DimensionError,
        r"parameters must have one set per step, 3 \(the controls' length\), got 2",
    ),
    (
        "per-step array count",
        dict(parameters=np.zeros((4, 2, 1))),
        DimensionError,
        r"parameters must have one set per step, 3 \(the controls' length\), got 4",
    ),
    (
        "set of wrong dimension",
        dict(parameters=[THETA, Box(np.zeros(2), np.ones(2)), THETA]),
        DimensionError,
        r"parameters\[1\] must have dimension 1 \(phi has shape \(1, 2, 2\)\), got 2",
    ),
    (
        "vertices of wrong dimension",
        dict(parameters=[THETA, THETA, np.zeros((2, 2))]),
        DimensionError,
        r"parameters\[2\] must have shape \(\*, 1\), got shape \(2, 2\)",
    ),
    (
        "no vertex",
        dict(parameters=[np.empty((0, 1)), THETA, THETA]),
        DimensionError,
        r"parameters\[0\] must have shape \(k, 1\) with k >= 1, got shape \(0, 1\)",
    ),
    ("nan vertex", dict(parameters=[THETA, np.array([[NAN]]), THETA]), NonFiniteError, r"parameters\[1\] contains NaN"),
    ("text set", dict(parameters=[THETA, THETA, "box"]), InputError, r"parameters\[2\] must be a real numeric array"),
    (
        "1-d vertices",
        dict(parameters=[THETA, np.zeros(1), THETA]),
        DimensionError,
        r"parameters\[1\] must be 2-dimensional, got shape \(1,\)",
    ),
    # box-valued controls
    (
        "controls pair of wrong q",
        dict(controls=(np.zeros((3, 2)), np.zeros((3, 2)))),
        DimensionError,
        r"controls lower must have shape \(\*, 1\), got shape \(3, 2\)",
    ),
    (
        "controls pair of unequal length",
        dict(controls=(np.zeros((3, 1)), np.zeros((2, 1)))),
        DimensionError,
        r"controls lower and controls upper must have the same shape, got \(3, 1\) and \(2, 1\)",
    ),
    (
        "controls lower > upper",
        dict(controls=(np.zeros((3, 1)), np.array([[1.0], [-1.0], [1.0]]))),
        EmptySetError,
        r"controls is empty at step 1: lower\[1, 0\] = 0.0 > upper\[1, 0\] = -1.0",
    ),
    (
        "controls nan",
        dict(controls=(np.zeros((3, 1)), np.full((3, 1), NAN))),
        NonFiniteError,
        r"controls upper contains NaN",
    ),
    (
        "controls text",
        dict(controls=(np.zeros((3, 1)), np.full((3, 1), "1"))),
        InputError,
        r"controls upper must be a real numeric array, got text",
    ),
    (
        "control box of wrong q",
        dict(controls=[Box([0.0], [1.0]), Box(np.zeros(2), np.ones(2))]),
        DimensionError,
        r"controls\[1\] must have dimension 1 \(B has shape \(2, 1\)\), got 2",
    ),
    (
        "not a control box",
        dict(controls=[Box([0.0], [1.0]), Box([0.0], [1.0]), np.zeros(1)]),
        InputError,
        r"controls\[2\] must be a Box, got ndarray",
    ),
    # disturbances
    (
        "disturbances of wrong length",
        dict(disturbances=(np.zeros((2, 2)), np.zeros((2, 2)))),
        DimensionError,
        r"disturbances lower must have shape \(3, 2\), got shape \(2, 2\)",
    ),
    (
        "disturbances of wrong r",
        dict(disturbances=(np.zeros((3, 3)), np.zeros((3, 3)))),
        DimensionError,
        r"disturbances lower must have shape \(3, 2\), got shape \(3, 3\)",
    ),
    (
        "disturbance boxes count",
        dict(disturbances=[W, W]),
        DimensionError,
        r"disturbances must have one box per step, 3 \(the controls' length\), got 2",
    ),
    (
        "disturbance box of wrong r",
        dict(disturbances=[W, Box(np.zeros(3), np.ones(3)), W]),
        DimensionError,
        r"disturbances\[1\] must have dimension 2 \(columns of D, shape \(2, 2\)\), got 3",
    ),
    (
        "one disturbance box of wrong r",
        dict(disturbances=Box(np.zeros(3), np.ones(3))),
        DimensionError,
        r"disturbances must have dimension 2 \(columns of D, shape \(2, 2\)\), got 3",
    ),
    (
        "disturbances lower > upper",
        dict(disturbances=(np.ones((3, 2)), np.zeros((3, 2)))),
        EmptySetError,
        r"disturbances is empty at step 0: lower\[0, 0\] = 1.0 > upper\[0, 0\] = 0.0",
    ),
    (
        "disturbances nan",
        dict(disturbances=(np.full((3, 2), NAN), np.zeros((3, 2)))),
        NonFiniteError,
        r"disturbances lower contains NaN",
    ),
    (
        "disturbances inf",
        dict(disturbances=(np.zeros((3, 2)), np.full((3, 2), np.inf))),
        NonFiniteError,
        r"disturbances upper contains NaN or infinite",
    ),
    (
        "disturbances array",
        dict(disturbances=np.zeros((3, 2))),
        InputError,
        r"disturbances must be None, a Box, a \(lower, upper\) pair of \(H, r\) arrays or a sequence of H Boxes, "
        r"got ndarray",
    ),
    ("disturbances text", dict(disturbances="w"), InputError, r"disturbances must be None, a Box, .*got str"),
    (
        "not a disturbance box",
        dict(disturbances=[W, W, (0.0, 1.0)]),
        InputError,
        r"disturbances\[2\] must be a Box, got tuple",
    ),
]


@pytest.mark.parametrize(("label", "changes", "error", "message"), BAD_CALLS, ids=[c[0] for c in BAD_CALLS])
def test_bad_arguments_are_rejected_before_any_work(small_system, monkeypatch, label, changes, error, message):
    def no_work(*args, **kwargs):
        raise AssertionError("the tube's computation started before the arguments were checked")

    monkeypatch.setattr(prediction, "_Frame", no_work)
    arguments = dict(controls=U3, parameters=None, disturbances=None, basis="auto") | changes
    with pytest.raises(error, match=message):
        predict_tube(
            small_system,
            X0,
            arguments["controls"],
            arguments["parameters"],
            basis=arguments["basis"],
            disturbances=arguments["disturbances"],
        )


def test_predictor_rejects_bad_disturbances(small_system):
    with pytest.raises(InputError, match="disturbances must be a Box, got tuple"):
        IntervalPredictor(small_system, disturbances=(np.zeros(2), np.ones(2)))
    message = r"disturbances must have dimension 2 \(columns of D, shape \(2, 2\)\), got 1"
    with pytest.raises(DimensionError, match=message):
        IntervalPredictor(small_system).with_sets(disturbances=Box([0.0], [1.0]))
    with pytest.raises(DimensionError, match=r"parameters must have dimension 1 .*got vertices of shape \(4, 2\)"):
        IntervalPredictor(small_system).with_sets(Box(np.zeros(2), np.ones(2)))


def test_old_forms_keep_their_meaning(small_system):
    # A pair of 1-d rows is still a (2, 1) control array (or a (2, 1) vertex array), not a box.
    pair = (np.array([0.5]), np.array([0.7]))
    tube = predict_tube(small_system, X0, pair, pair)
    np.testing.assert_array_equal(tube.lower, predict_tube(small_system, X0, np.array(pair), np.array(pair)).lower)
    assert tube.horizon == 2
    empty = (np.zeros((0, 2)), np.zeros((0, 2)))
    assert predict_tube(small_system, X0, np.zeros((0, 1)), disturbances=empty).horizon == 0
    assert predict_tube(small_system, X0, [Box([0.0], [1.0])], [VertexPolytope([[0.0]])]).horizon == 1
