"""Tests of the discrete-time interval predictor: inclusion for every dt and every system."""

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.models import (
    Box,
    DimensionError,
    Ellipsoid,
    InputError,
    IntervalPredictor,
    NonFiniteError,
    Tube,
    UncertainLinearSystem,
    predict_tube,
)
from minimaxplan.models.polytope import parameter_vertices
from minimaxplan.models.prediction import interval_product

HORIZON = 12


# ----------------------------------------------------------------------------- helpers
def random_system(rng, p, d, q, r, dt, metzler):
    """A random continuous-time system discretised by forward Euler (non-Metzler unless asked)."""
    A = rng.normal(size=(p, p))
    phi = rng.normal(size=(d, p, p)) * rng.uniform(0.05, 0.5)
    if metzler:
        off_diagonal = ~np.eye(p, dtype=bool)
        A[off_diagonal] = np.abs(A[off_diagonal])
        A -= np.eye(p) * rng.uniform(0.5, 2.0)
    B = rng.normal(size=(p, q))
    D = rng.normal(size=(p, r))
    centre = rng.normal(size=r) * 0.1
    w = Box(centre - rng.uniform(0, 0.3, size=r), centre + rng.uniform(0, 0.3, size=r))
    theta = Box.from_center(rng.normal(size=d) * 0.2, rng.uniform(0.05, 0.5, size=d))
    return UncertainLinearSystem.from_continuous(A, phi, B, D=D, w=w, theta=theta, dt=dt)


def random_ellipsoid(rng, d):
    factor = rng.normal(size=(d, d))
    return Ellipsoid(rng.normal(size=d) * 0.2, factor @ factor.T + 0.5 * np.eye(d), float(rng.uniform(0.1, 0.6)))


def sample_parameters(rng, kind, system, n):
    """(parameter set, thetas (n, d)): the set's extreme points and interior points."""
    d = system.nparams
    if kind == "box":
        box = system.theta
        extremes = box.vertices()[rng.integers(2**d, size=n // 2)]
        inside = rng.uniform(box.low, box.high, size=(n - n // 2, d))
        return box, np.vstack([extremes, inside])
    if kind == "ellipsoid":
        ellipsoid = random_ellipsoid(rng, d)
        directions = rng.normal(size=(n, d))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        directions[n // 2 :] *= rng.uniform(0, 1, size=(n - n // 2, 1))
        offsets = np.linalg.solve(np.linalg.cholesky(ellipsoid.gramian).T, directions.T).T * ellipsoid.radius
        return ellipsoid, ellipsoid.center + offsets
    vertices = rng.normal(size=(int(rng.integers(1, 6)), d)) * 0.3
    extremes = vertices[rng.integers(len(vertices), size=n // 2)]
    inside = rng.dirichlet(np.ones(len(vertices)), size=n - n // 2) @ vertices
    return vertices, np.vstack([extremes, inside])


def simulate(system, x0, thetas, controls, disturbances):
    """Trajectories (n, H+1, p) of x+ = A(theta) x + B u + D w, batched over n."""
    matrices = system.A(thetas)
    states = [x0]
    for step in range(controls.shape[0]):
        x = states[-1]
        states.append(
            np.einsum("nij,nj->ni", matrices, x) + controls[step] @ system.B.T + disturbances[:, step] @ system.D.T
        )
    return np.stack(states, axis=1)


def sample_initial_states(rng, box, n):
    corners = box.vertices()[rng.integers(2**box.dim, size=n // 2)]
    return np.vstack([corners, rng.uniform(box.low, box.high, size=(n - n // 2, box.dim))])


def sample_disturbances(rng, w, n, horizon):
    """Half the trajectories take a random vertex of the w box at every step, half interior points."""
    signs = rng.integers(0, 2, size=(n // 2, horizon, w.dim))
    extremes = np.where(signs == 1, w.high, w.low)
    inside = rng.uniform(w.low, w.high, size=(n - n // 2, horizon, w.dim))
    return np.concatenate([extremes, inside])


def random_basis(rng, p):
    """A random invertible basis with a moderate condition number."""
    while True:
        basis = rng.normal(size=(p, p))
        if np.linalg.cond(basis) < 50:
            return basis


# ----------------------------------------------------------------------------- inclusion
@given(
    seed=st.integers(0, 2**32 - 1),
    p=st.integers(1, 6),
    d=st.integers(1, 4),
    q=st.integers(1, 2),
    dt=st.floats(0.01, 1.0),
    metzler=st.booleans(),
    kind=st.sampled_from(["box", "ellipsoid", "vertices"]),
    basis=st.sampled_from([None, "auto", "random"]),
)
def test_every_trajectory_stays_in_the_tube(seed, p, d, q, dt, metzler, kind, basis):
    rng = np.random.default_rng(seed)
    system = random_system(rng, p, d, q, int(rng.integers(1, p + 1)), dt, metzler)
    parameters, thetas = sample_parameters(rng, kind, system, 40)
    x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.5, size=p))
    controls = rng.normal(size=(HORIZON, q))
    chosen = random_basis(rng, p) if basis == "random" else basis
    tube = predict_tube(system, x0, controls, parameters, basis=chosen)
    assert tube.lower.shape == tube.upper.shape == (HORIZON + 1, p)
    assert tube.guaranteed
    states = simulate(
        system, sample_initial_states(rng, x0, 40), thetas, controls, sample_disturbances(rng, system.w, 40, HORIZON)
    )
    assert tube.contains(states)


@given(
    seed=st.integers(0, 2**32 - 1),
    p=st.integers(1, 5),
    d=st.integers(1, 3),
    dt=st.floats(0.01, 1.0),
    auto=st.booleans(),
)
def test_inclusion_holds_even_when_theta_varies_in_time(seed, p, d, dt, auto):
    rng = np.random.default_rng(seed)
    system = random_system(rng, p, d, 1, p, dt, metzler=bool(rng.integers(2)))
    x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.5, size=p))
    controls = rng.normal(size=(HORIZON, 1))
    tube = predict_tube(system, x0, controls, basis="auto" if auto else None)
    n = 40
    x = sample_initial_states(rng, x0, n)
    disturbances = sample_disturbances(rng, system.w, n, HORIZON)
    states = [x]
    for step in range(HORIZON):
        thetas = system.theta.vertices()[rng.integers(2**d, size=n)]  # a new vertex at every step
        x = (
            np.einsum("nij,nj->ni", system.A(thetas), x)
            + controls[step] @ system.B.T
            + disturbances[:, step] @ system.D.T
        )
        states.append(x)
    assert tube.contains(np.stack(states, axis=1))


@given(
    seed=st.integers(0, 2**32 - 1),
    p=st.integers(2, 6),
    d=st.integers(1, 3),
    kind=st.sampled_from(["box", "ellipsoid", "vertices"]),
)
def test_auto_basis_is_sound_where_it_changes_the_basis(seed, p, d, kind):
    # A_N = S diag(eigenvalues) S^-1 with real eigenvalues and a random S: far from
    # nonnegative, so "auto" often adopts a non-identity basis; inclusion must hold either way.
    rng = np.random.default_rng(seed)
    S = random_basis(rng, p)
    nominal = S @ np.diag(rng.uniform(-0.3, 1.0, size=p)) @ np.linalg.inv(S)
    phi = rng.normal(size=(d, p, p)) * 0.02
    w = Box.from_center(rng.normal(size=p) * 0.05, rng.uniform(0, 0.1, size=p))
    system = UncertainLinearSystem(
        nominal, phi, rng.normal(size=(p, 1)), D=rng.normal(size=(p, p)), w=w, theta=Box.from_center(np.zeros(d), 1.0)
    )
    parameters, thetas = sample_parameters(rng, kind, system, 40)
    x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.5, size=p))
    controls = rng.normal(size=(HORIZON, 1))
    tube = predict_tube(system, x0, controls, parameters, basis="auto")
    assert tube.note.startswith("basis auto: ")
    states = simulate(
        system, sample_initial_states(rng, x0, 40), thetas, controls, sample_disturbances(rng, w, 40, HORIZON)
    )
    assert tube.contains(states)


def test_outward_rounding_keeps_a_non_normal_tube_sound():
    # A point tube in a basis where rho(|T^-1 A T|) = 14.7 but rho(A) = 1.5: rounding
    # errors of the interval recursion grow 10x faster than the state. Without outward
    # rounding the bounds cross and miss the trajectory by ~3e-5 relative.
    rng = np.random.default_rng(1)
    p, d, dt = int(rng.integers(1, 7)), int(rng.integers(1, 5)), float(rng.uniform(0.01, 1))
    assert (p, d) == (3, 3)
    system = random_system(rng, p, d, 2, 3, dt, metzler=False)
    theta, w = rng.normal(size=d), rng.normal(size=3)
    point_system = UncertainLinearSystem(
        system.A0, system.phi, system.B, D=system.D, w=Box(w, w), theta=Box(theta, theta)
    )
    x, controls, basis = rng.normal(size=p), rng.normal(size=(HORIZON, 2)), random_basis(rng, p)
    states = [x]
    for u in controls:
        states.append(point_system.step(states[-1], u, theta, w))
    states = np.array(states)
    # The same recursion in round-to-nearest without the margins, started from bounds
    # crossed by one ulp (as rounding can leave them): the crossing grows like 14.7^n.
    inverse = np.linalg.inv(basis)
    matrix = inverse @ point_system.A(theta) @ basis
    pos, neg = np.maximum(matrix, 0), np.maximum(-matrix, 0)
    z_lo = inverse @ x
    z_hi = np.nextafter(z_lo, -np.inf)
    naive_lower = [x]
    for u in controls:
        shift = inverse @ point_system.B @ u + inverse @ point_system.D @ w
        z_lo, z_hi = pos @ z_lo - neg @ z_hi + shift, pos @ z_hi - neg @ z_lo + shift
        naive_lower.append(np.maximum(basis, 0) @ z_lo - np.maximum(-basis, 0) @ z_hi)
    assert np.max((np.array(naive_lower) - states) / (1 + np.abs(states))) > 1e-6
    tube = predict_tube(point_system, Box(x, x), controls, basis=basis)
    assert tube.contains(states, tol=1e-13)
    assert np.all(tube.lower <= tube.upper)
    # The same non-normal matrix as the system itself, identity basis: the step's own margins.
    internal = UncertainLinearSystem(
        matrix,
        np.zeros((1, p, p)),
        inverse @ point_system.B,
        D=inverse @ point_system.D,
        w=Box(w, w),
        theta=Box(np.zeros(1), np.zeros(1)),
    )
    z0 = inverse @ x
    internal_states = [z0]
    for u in controls:
        internal_states.append(internal.step(internal_states[-1], u, np.zeros(1), w))
    internal_tube = predict_tube(internal, Box(z0, z0), controls)
    assert internal_tube.contains(np.array(internal_states), tol=1e-13)
    assert np.all(internal_tube.lower <= internal_tube.upper)


def test_box_corners_are_exact():
    box = Box(np.array([0.1, -0.7]), np.array([0.3, 0.2]))
    corners = parameter_vertices(box)
    assert set(corners[:, 0]) == {0.1, 0.3} and set(corners[:, 1]) == {-0.7, 0.2}


def test_overflow_is_reported():
    system = UncertainLinearSystem(
        1e3 * np.eye(2),
        np.zeros((1, 2, 2)),
        np.ones((2, 1)),
        w=Box.from_center(np.zeros(2), 1.0),
        theta=Box(np.zeros(1), np.ones(1)),
    )
    with pytest.raises(NonFiniteError, match=r"the tube's bounds overflowed at step 10\d of 200"):
        predict_tube(system, Box.from_center(np.zeros(2), 1.0), np.zeros((200, 1)))


@given(seed=st.integers(0, 2**32 - 1), p=st.integers(1, 3), d=st.integers(1, 2), dt=st.floats(0.01, 1.0))
def test_one_step_is_the_tightest_box(seed, p, d, dt):
    # The one-step bound equals the extremes over parameter vertices x initial corners x
    # disturbance corners, where the exact reachable set's extremes lie.
    rng = np.random.default_rng(seed)
    system = random_system(rng, p, d, 1, p, dt, metzler=False)
    x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.5, size=p))
    u = rng.normal(size=(1, 1))
    tube = predict_tube(system, x0, u)
    combos = list(itertools.product(system.theta.vertices(), x0.vertices(), system.w.vertices()))
    successors = np.array([system.step(x, u[0], theta, w) for theta, x, w in combos])
    scale = 1e-12 * (1 + np.abs(successors).max())
    np.testing.assert_allclose(tube.lower[1], successors.min(axis=0), rtol=0, atol=scale)
    np.testing.assert_allclose(tube.upper[1], successors.max(axis=0), rtol=0, atol=scale)


def errata_step(system, vertices, lower, upper, u):
    """The errata's predictor, for comparison: A_N plus the elementwise max of X_k+ and X_k-."""
    nominal = system.A(vertices.mean(axis=0))
    deviations = system.A(vertices) - nominal
    Xp, Xn = np.max(np.maximum(deviations, 0), axis=0), np.max(np.maximum(-deviations, 0), axis=0)
    pos, neg = np.maximum(nominal, 0), np.maximum(-nominal, 0)
    Dp, Dn = np.maximum(system.D, 0), np.maximum(-system.D, 0)
    lo_m, hi_p = np.maximum(-lower, 0), np.maximum(upper, 0)
    hi_m, lo_p = np.maximum(-upper, 0), np.maximum(lower, 0)
    bu = system.B @ u
    new_lower = pos @ lower - neg @ upper - Xp @ lo_m - Xn @ hi_p + bu + Dp @ system.w.low - Dn @ system.w.high
    new_upper = pos @ upper - neg @ lower + Xp @ hi_p + Xn @ lo_m + bu + Dp @ system.w.high - Dn @ system.w.low
    del hi_m, lo_p
    return new_lower, new_upper


@given(seed=st.integers(0, 2**32 - 1), p=st.integers(1, 5), d=st.integers(1, 3), dt=st.floats(0.01, 1.0))
def test_at_least_as_tight_as_the_errata_predictor(seed, p, d, dt):
    rng = np.random.default_rng(seed)
    system = random_system(rng, p, d, 1, p, dt, metzler=bool(rng.integers(2)))
    x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.5, size=p))
    controls = rng.normal(size=(HORIZON, 1))
    tube = predict_tube(system, x0, controls)
    vertices = parameter_vertices(system.theta)
    lower, upper = x0.low, x0.high
    for n in range(HORIZON):
        lower, upper = errata_step(system, vertices, lower, upper, controls[n])
        slack = 1e-9 * (1 + np.abs(lower) + np.abs(upper))
        assert np.all(tube.lower[n + 1] >= lower - slack) and np.all(tube.upper[n + 1] <= upper + slack)


@given(
    seed=st.integers(0, 2**32 - 1),
    p=st.integers(1, 6),
    d=st.integers(1, 4),
    dt=st.floats(0.01, 1.0),
    basis=st.sampled_from([None, "random"]),
)
def test_tube_of_a_point_without_uncertainty_is_the_simulation(seed, p, d, dt, basis):
    rng = np.random.default_rng(seed)
    system = random_system(rng, p, d, 2, 3, dt, metzler=False)
    theta = rng.normal(size=d)
    w = rng.normal(size=3)
    point_system = UncertainLinearSystem(
        system.A0, system.phi, system.B, D=system.D, w=Box(w, w), theta=Box(theta, theta)
    )
    x = rng.normal(size=p)
    controls = rng.normal(size=(HORIZON, 2))
    tube = predict_tube(point_system, Box(x, x), controls, basis=random_basis(rng, p) if basis else None)
    states = [x]
    for u in controls:
        states.append(point_system.step(states[-1], u, theta, w))
    states = np.array(states)
    assert tube.contains(states)
    if basis is None:
        # The tube is the simulation up to its outward rounding, whose width obeys
        # W+ = |A| W + 2 c (|A|_formed |x| + |B| |u| + |D| |w|), c a generous multiple of eps.
        formed = np.abs(system.A0) + np.tensordot(np.abs(theta), np.abs(system.phi), axes=1)
        c = 1e-13
        bound = np.zeros(p)
        for n in range(HORIZON):
            assert np.all(tube.widths[n] <= bound)
            bound = np.abs(point_system.A(theta)) @ bound + 2 * c * (
                formed @ np.abs(states[n]) + np.abs(system.B) @ np.abs(controls[n]) + np.abs(system.D) @ np.abs(w)
            )
        assert np.all(tube.widths[HORIZON] <= bound)


@given(
    seed=st.integers(0, 2**32 - 1),
    p=st.integers(1, 5),
    d=st.integers(1, 3),
    dt=st.floats(0.01, 1.0),
    fixed_basis=st.booleans(),
)
def test_a_smaller_parameter_set_gives_a_nested_tube(seed, p, d, dt, fixed_basis):
    rng = np.random.default_rng(seed)
    system = random_system(rng, p, d, 1, p, dt, metzler=bool(rng.integers(2)))
    x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.5, size=p))
    controls = rng.normal(size=(HORIZON, 1))
    basis = random_basis(rng, p) if fixed_basis else None
    big = system.theta
    small = Box(rng.uniform(big.low, big.center), rng.uniform(big.center, big.high))
    ellipsoid = random_ellipsoid(rng, d)
    smaller_ellipsoid = Ellipsoid(ellipsoid.center, ellipsoid.gramian, ellipsoid.radius * rng.uniform(0.1, 1.0))
    vertices = rng.normal(size=(5, d))
    sub_vertices = rng.dirichlet(np.ones(5), size=4) @ vertices
    for larger, subset in ((big, small), (ellipsoid, smaller_ellipsoid), (vertices, sub_vertices)):
        wide = predict_tube(system, x0, controls, larger, basis=basis)
        narrow = predict_tube(system, x0, controls, subset, basis=basis)
        slack = 1e-9 * (1 + np.abs(wide.lower) + np.abs(wide.upper))
        assert np.all(narrow.lower >= wide.lower - slack) and np.all(narrow.upper <= wide.upper + slack)
        assert np.all(narrow.widths <= wide.widths + 2 * slack)


def test_auto_basis_narrows_a_non_metzler_system_and_says_so():
    # Real eigenvalues 0.82 and 0.28, but |A| has spectral radius 0.965: the wrapping effect.
    A = np.array([[0.9, 0.5], [-0.1, 0.2]])
    phi = np.zeros((1, 2, 2))
    phi[0, 0, 0] = 0.01
    system = UncertainLinearSystem(
        A, phi, np.ones((2, 1)), w=Box.from_center(np.zeros(2), 0.01), theta=Box.from_center(np.zeros(1), 1.0)
    )
    x0 = Box.from_center(np.ones(2), 0.1)
    controls = np.zeros((40, 1))
    plain = predict_tube(system, x0, controls)
    auto = predict_tube(system, x0, controls, basis="auto")
    assert "eigenvector basis" in auto.note
    assert auto.widths[-1].sum() < 0.5 * plain.widths[-1].sum()
    predictor = IntervalPredictor(system, basis="auto")
    transformed = np.linalg.inv(predictor.basis) @ system.A0 @ predictor.basis
    assert np.all(transformed >= -1e-12)  # T^-1 A_N T nonnegative (here: diagonal, positive)


def test_auto_basis_keeps_the_identity_when_nothing_helps():
    system = UncertainLinearSystem(
        np.array([[0.9, 0.1], [0.0, 0.8]]),
        np.zeros((1, 2, 2)),
        np.ones((2, 1)),
        w=Box.from_center(np.zeros(2), 0.01),
        theta=Box.from_center(np.zeros(1), 1.0),
    )
    predictor = IntervalPredictor(system, basis="auto")
    assert "kept the identity" in predictor.basis_note
    np.testing.assert_array_equal(predictor.basis, np.eye(2))


# ----------------------------------------------------------------------------- low-level interface
@given(seed=st.integers(0, 2**32 - 1), p=st.integers(1, 4), basis=st.sampled_from([None, "random"]))
def test_batched_steps_equal_single_steps(seed, p, basis):
    rng = np.random.default_rng(seed)
    system = random_system(rng, p, 2, 2, p, 0.2, metzler=False)
    predictor = IntervalPredictor(system, basis=random_basis(rng, p) if basis == "random" else None)
    centres = rng.normal(size=(7, p))
    lower, upper = predictor.enter(centres - 0.1, centres + 0.1)
    u = rng.normal(size=(7, 2))
    batch_lower, batch_upper = predictor.step(lower, upper, u)
    for i in range(7):
        single_lower, single_upper = predictor.step(lower[i], upper[i], u[i])
        np.testing.assert_allclose(batch_lower[i], single_lower, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(batch_upper[i], single_upper, rtol=1e-13, atol=1e-13)
    x_lower, x_upper = predictor.leave(batch_lower, batch_upper)
    assert x_lower.shape == x_upper.shape == (7, p)
    assert np.all(x_lower <= x_upper)


def test_enter_and_leave_contain_the_box():
    rng = np.random.default_rng(2)
    system = random_system(rng, 3, 1, 1, 3, 0.2, metzler=False)
    predictor = IntervalPredictor(system, basis=random_basis(rng, 3))
    box = Box.from_center(rng.normal(size=3), 0.3)
    z_lower, z_upper = predictor.enter(box.low, box.high)
    x_lower, x_upper = predictor.leave(z_lower, z_upper)
    assert np.all(x_lower <= box.low + 1e-12) and np.all(x_upper >= box.high - 1e-12)
    inside = box.vertices() @ np.linalg.inv(predictor.basis).T
    assert np.all(inside >= z_lower - 1e-12) and np.all(inside <= z_upper + 1e-12)


# ----------------------------------------------------------------------------- Tube value
def test_tube_contains_and_to_dict():
    tube = Tube(np.zeros((3, 2)), np.ones((3, 2)))
    assert tube.horizon == 2
    assert tube.contains(np.full((3, 2), 0.5))
    assert tube.contains(np.full((5, 3, 2), 0.5))
    assert not tube.contains(np.full((3, 2), 1.01))
    assert tube.contains(np.full((3, 2), 1.0 + 1e-10))
    assert not tube.contains(np.full((3, 2), 1.0 + 1e-10), tol=0.0)
    np.testing.assert_array_equal(tube.widths, np.ones((3, 2)))
    assert tube.to_dict() == {
        "lower": np.zeros((3, 2)).tolist(),
        "upper": np.ones((3, 2)).tolist(),
        "guaranteed": True,
        "note": "",
    }
    with pytest.raises(DimensionError, match=r"states must have shape \(3, 2\) .*got shape \(2, 2\)"):
        tube.contains(np.zeros((2, 2)))
    with pytest.raises(DimensionError, match=r"lower and upper must have the same shape, got \(3, 2\) and \(2, 2\)"):
        Tube(np.zeros((3, 2)), np.ones((2, 2)))
    with pytest.raises(ValueError):
        tube.lower[0, 0] = 5.0  # read-only


# ----------------------------------------------------------------------------- errors
def test_bad_arguments_are_rejected(small_system):
    x0 = Box.from_center(np.zeros(2), 0.1)
    with pytest.raises(DimensionError, match=r"controls must have shape \(\*, 1\), got shape \(3, 2\)"):
        predict_tube(small_system, x0, np.zeros((3, 2)))
    with pytest.raises(DimensionError, match=r"controls must be 2-dimensional, got shape \(3,\)"):
        predict_tube(small_system, x0, np.zeros(3))
    with pytest.raises(NonFiniteError, match="controls contains NaN"):
        predict_tube(small_system, x0, np.array([[np.nan]]))
    with pytest.raises(DimensionError, match=r"x0 must have dimension 2 \(A0 has shape \(2, 2\)\), got 3"):
        predict_tube(small_system, Box.from_center(np.zeros(3), 0.1), np.zeros((3, 1)))
    with pytest.raises(InputError, match="x0 must be a Box, got ndarray"):
        predict_tube(small_system, np.zeros(2), np.zeros((3, 1)))
    with pytest.raises(InputError, match="system must be an UncertainLinearSystem, got dict"):
        predict_tube({}, x0, np.zeros((3, 1)))
    with pytest.raises(
        DimensionError,
        match=r"parameters must have dimension 1 \(phi has shape \(1, 2, 2\)\), got vertices of shape \(4, 2\)",
    ):
        predict_tube(small_system, x0, np.zeros((3, 1)), Box.from_center(np.zeros(2), 0.1))
    with pytest.raises(NonFiniteError, match="parameters contains NaN"):
        predict_tube(small_system, x0, np.zeros((3, 1)), np.array([[np.nan]]))
    with pytest.raises(InputError, match="basis must be None, \"auto\" or a \\(p, p\\) matrix, got 'eig'"):
        predict_tube(small_system, x0, np.zeros((3, 1)), basis="eig")
    with pytest.raises(DimensionError, match=r"basis must have shape \(2, 2\), got shape \(3, 3\)"):
        predict_tube(small_system, x0, np.zeros((3, 1)), basis=np.eye(3))
    with pytest.raises(InputError, match="basis must be invertible with condition number"):
        predict_tube(small_system, x0, np.zeros((3, 1)), basis=np.ones((2, 2)))


@given(
    a=st.tuples(st.floats(-50, 50), st.floats(0, 50)),
    b=st.tuples(st.floats(-50, 50), st.floats(0, 50)),
    seed=st.integers(0, 2**31),
)
def test_interval_product_is_the_hull_of_every_product(a, b, seed):
    """`interval_product` contains every product of points of the two intervals and is attained at corners."""
    a_lo, a_hi = a[0], a[0] + a[1]
    b_lo, b_hi = b[0], b[0] + b[1]
    lo, hi = interval_product(np.array([a_lo]), np.array([a_hi]), np.array([b_lo]), np.array([b_hi]))
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(a_lo, a_hi, 500), rng.uniform(b_lo, b_hi, 500)
    assert np.all(x * y >= lo[0]) and np.all(x * y <= hi[0])
    corners = [p * q for p in (a_lo, a_hi) for q in (b_lo, b_hi)]
    assert lo[0] == min(corners) and hi[0] == max(corners)
    # broadcasting: a scalar interval against an array of intervals
    lo2, hi2 = interval_product(a_lo, a_hi, np.array([b_lo, b_lo]), np.array([b_hi, b_hi]))
    assert lo2.shape == (2,) and np.all(lo2 == lo[0]) and np.all(hi2 == hi[0])
