"""Uncertain linear systems: A(theta), step, regressor identity, constructors, bad input."""

import control
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.models import Box, DimensionError, InputError, NonFiniteError, UncertainLinearSystem

SEEDS = st.integers(0, 2**32 - 1)


def _random_system(rng, p, q, d, r):
    return UncertainLinearSystem(
        rng.normal(size=(p, p)),  # not Metzler, not stable: nothing here may assume either
        rng.normal(size=(d, p, p)),
        rng.normal(size=(p, q)),
        D=rng.normal(size=(p, r)),
        w=Box.from_center(rng.normal(size=r), rng.uniform(0, 1, size=r)),
        theta=Box.from_center(rng.normal(size=d), rng.uniform(0, 1, size=d)),
    )


@given(seed=SEEDS, p=st.integers(1, 4), q=st.integers(1, 3), d=st.integers(1, 4), r=st.integers(1, 3))
def test_dynamics_match_their_definition(seed, p, q, d, r):
    rng = np.random.default_rng(seed)
    system = _random_system(rng, p, q, d, r)
    assert (system.nstates, system.ninputs, system.nparams, system.ndisturbances) == (p, q, d, r)
    theta = rng.normal(size=d)
    x, u, w = rng.normal(size=p), rng.normal(size=q), rng.normal(size=r)
    A = system.A0.copy()
    for i in range(d):
        A += theta[i] * system.phi[i]
    np.testing.assert_allclose(system.A(theta), A, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(system.step(x, u, theta, w), A @ x + system.B @ u + system.D @ w, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(system.step(x, u, theta), A @ x + system.B @ u, rtol=1e-12, atol=1e-12)
    # batched parameters
    thetas = rng.normal(size=(5, d))
    stacked = system.A(thetas)
    assert stacked.shape == (5, p, p)
    for k in range(5):
        np.testing.assert_allclose(stacked[k], system.A(thetas[k]), rtol=1e-12, atol=1e-12)


@given(seed=SEEDS, p=st.integers(1, 4), d=st.integers(1, 4))
def test_regressor_identity(seed, p, d):
    """``A(theta) x == A0 x + regressor(x) @ theta``; column i of the regressor is ``phi[i] @ x``."""
    rng = np.random.default_rng(seed)
    system = _random_system(rng, p, 1, d, 1)
    theta, x = rng.normal(size=d), rng.normal(size=p) * 10.0 ** rng.uniform(-3, 3)
    E = system.regressor(x)
    assert E.shape == (p, d)
    scale = np.abs(system.A0) @ np.abs(x) + np.abs(E) @ np.abs(theta)
    assert np.all(np.abs(system.A(theta) @ x - (system.A0 @ x + E @ theta)) <= 1e-13 * scale)
    for i in range(d):
        np.testing.assert_allclose(E[:, i], system.phi[i] @ x, rtol=1e-14, atol=0)
    xs = rng.normal(size=(7, p))
    batch = system.regressor(xs)
    assert batch.shape == (7, p, d)
    for n in range(7):
        np.testing.assert_allclose(batch[n], system.regressor(xs[n]), rtol=1e-14, atol=0)


@given(seed=SEEDS, p=st.integers(1, 3), d=st.integers(1, 3), log_dt=st.floats(-3, 0))
def test_from_continuous_is_forward_euler(seed, p, d, log_dt):
    rng = np.random.default_rng(seed)
    dt = 10.0**log_dt
    A, phi, B, D = rng.normal(size=(p, p)), rng.normal(size=(d, p, p)), rng.normal(size=(p, 2)), rng.normal(size=(p, 1))
    w, theta_box = Box([-0.1], [0.2]), Box(-np.ones(d), np.ones(d))
    system = UncertainLinearSystem.from_continuous(A, phi, B, D=D, w=w, theta=theta_box, dt=dt)
    theta, x, u, wv = rng.normal(size=d), rng.normal(size=p), rng.normal(size=2), rng.normal(size=1)
    A_theta = A + np.tensordot(theta, phi, axes=1)
    euler = x + dt * (A_theta @ x + B @ u + D @ wv)
    np.testing.assert_allclose(system.step(x, u, theta, wv), euler, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(system.A0, np.eye(p) + dt * A, rtol=1e-15, atol=0)
    assert system.w == w and system.theta == theta_box
    # D defaults to the identity, scaled by dt
    default = UncertainLinearSystem.from_continuous(
        A, phi, B, w=Box.from_center(np.zeros(p), 1.0), theta=theta_box, dt=dt
    )
    np.testing.assert_allclose(default.D, dt * np.eye(p), rtol=1e-15, atol=0)


def test_from_statespace_continuous_needs_dt_and_uses_euler():
    A, B = np.array([[0.0, 1.0], [-2.0, -0.3]]), np.array([[0.0], [1.0]])
    sys = control.ss(A, B, np.eye(2), np.ones((2, 1)))  # nonzero feedthrough: must be ignored
    phi = np.array([[[0.0, 0.0], [1.0, 0.0]]])
    boxes = dict(w=Box([-0.1, -0.1], [0.1, 0.1]), theta=Box([-0.5], [0.5]))
    system = UncertainLinearSystem.from_statespace(sys, phi, dt=0.05, **boxes)
    reference = UncertainLinearSystem.from_continuous(A, phi, B, dt=0.05, **boxes)
    for name in ("A0", "phi", "B", "D"):
        np.testing.assert_array_equal(getattr(system, name), getattr(reference, name))
    np.testing.assert_allclose(system.D, 0.05 * np.eye(2), rtol=1e-15, atol=0)
    with pytest.raises(InputError, match=r"sys is continuous-time: give dt= to discretise it"):
        UncertainLinearSystem.from_statespace(sys, phi, **boxes)


def test_from_statespace_discrete_uses_its_own_matrices_and_dt():
    A, B = np.array([[1.0, 0.1], [0.0, 0.9]]), np.array([[0.0], [0.1]])
    sys = control.ss(A, B, np.eye(2), 5 * np.ones((2, 1)), dt=0.1)
    phi = np.array([[[0.0, 0.1], [0.0, 0.0]]])
    D = np.array([[1.0], [0.5]])
    boxes = dict(w=Box([-0.1], [0.1]), theta=Box([-0.5], [0.5]))
    system = UncertainLinearSystem.from_statespace(sys, phi, D=D, phi_time="discrete", **boxes)
    np.testing.assert_array_equal(system.A0, A)
    np.testing.assert_array_equal(system.phi, phi)  # a discrete-time phi is used as given
    np.testing.assert_array_equal(system.B, B)
    np.testing.assert_array_equal(system.D, D)  # our disturbance matrix, not the feedthrough
    same_dt = UncertainLinearSystem.from_statespace(sys, phi, D=D, dt=0.1, phi_time="discrete", **boxes)
    np.testing.assert_array_equal(same_dt.A0, A)
    with pytest.raises(InputError, match=r"sys is discrete-time with dt=0.1; dt=0.2 contradicts it"):
        UncertainLinearSystem.from_statespace(sys, phi, D=D, dt=0.2, phi_time="discrete", **boxes)
    with pytest.raises(InputError, match=r"dt must be > 0, got -0.1"):
        UncertainLinearSystem.from_statespace(sys, phi, D=D, dt=-0.1, phi_time="discrete", **boxes)
    unspecified = control.ss(A, B, np.eye(2), np.zeros((2, 1)), dt=True)
    np.testing.assert_array_equal(
        UncertainLinearSystem.from_statespace(unspecified, phi, D=D, phi_time="discrete", **boxes).A0, A
    )
    ambiguous = control.ss(A, B, np.eye(2), np.zeros((2, 1)), dt=None)
    with pytest.raises(InputError, match=r"sys has an unspecified timebase \(dt=None\)"):
        UncertainLinearSystem.from_statespace(ambiguous, phi, D=D, dt=0.1, phi_time="discrete", **boxes)
    with pytest.raises(InputError, match=r"sys must be a python-control StateSpace, got ndarray"):
        UncertainLinearSystem.from_statespace(A, phi, **boxes)


def test_from_statespace_never_adds_a_continuous_phi_to_a_discrete_sys():
    """Issue 10 item 8: the time base of phi is explicit; the old code silently added a rate to sys.A."""
    A_c, B_c = np.array([[0.0, 1.0], [-2.0, -0.3]]), np.array([[0.0], [1.0]])
    phi_c = np.array([[[0.0, 0.0], [-1.0, 0.0]]])  # continuous-time: a stiffness uncertainty, per second
    boxes = dict(w=Box([-0.1, -0.1], [0.1, 0.1]), theta=Box([-0.5], [0.5]))
    discrete = control.sample_system(control.ss(A_c, B_c, np.eye(2), np.zeros((2, 1))), 0.1)
    # phi_time is required for a discrete sys: phi's time base cannot be guessed
    with pytest.raises(InputError, match=r"phi_time is required when sys is discrete-time \(dt=0.1\)"):
        UncertainLinearSystem.from_statespace(discrete, phi_c, **boxes)
    # a continuous phi with a discrete sys is refused: its discretisation depends on how sys.A was made
    with pytest.raises(
        InputError,
        match=r"phi_time='continuous' with a discrete-time sys \(dt=0.1\).*continuous-time StateSpace with dt=",
    ):
        UncertainLinearSystem.from_statespace(discrete, phi_c, phi_time="continuous", **boxes)
    with pytest.raises(InputError, match=r"phi_time must be one of \('continuous', 'discrete', None\), got 'ct'"):
        UncertainLinearSystem.from_statespace(discrete, phi_c, phi_time="ct", **boxes)
    # a discrete phi with a continuous sys is refused too
    continuous = control.ss(A_c, B_c, np.eye(2), np.zeros((2, 1)))
    with pytest.raises(InputError, match=r"phi_time='discrete' but sys is continuous-time"):
        UncertainLinearSystem.from_statespace(continuous, 0.1 * phi_c, phi_time="discrete", dt=0.1, **boxes)
    # the consistent routes: continuous sys and phi with dt= (forward Euler for all), or phi_time="discrete"
    euler = UncertainLinearSystem.from_statespace(continuous, phi_c, phi_time="continuous", dt=0.1, **boxes)
    np.testing.assert_array_equal(euler.phi, 0.1 * phi_c)
    np.testing.assert_array_equal(euler.A0, np.eye(2) + 0.1 * A_c)
    same = UncertainLinearSystem.from_statespace(continuous, phi_c, dt=0.1, **boxes)
    np.testing.assert_array_equal(same.phi, euler.phi)
    explicit = UncertainLinearSystem.from_statespace(discrete, 0.1 * phi_c, phi_time="discrete", **boxes)
    np.testing.assert_array_equal(explicit.A0, discrete.A)
    np.testing.assert_array_equal(explicit.phi, 0.1 * phi_c)


def test_system_is_immutable_and_does_not_alias():
    A0, phi, B = np.eye(2), np.zeros((1, 2, 2)), np.ones((2, 1))
    system = UncertainLinearSystem(A0, phi, B, w=Box([-1.0, -1.0], [1.0, 1.0]), theta=Box([0.0], [1.0]))
    A0[0, 0], phi[0, 0, 0], B[0, 0] = 9.0, 9.0, 9.0
    np.testing.assert_array_equal(system.A0, np.eye(2))
    np.testing.assert_array_equal(system.phi, np.zeros((1, 2, 2)))
    np.testing.assert_array_equal(system.B, np.ones((2, 1)))
    for array in (system.A0, system.phi, system.B, system.D):
        with pytest.raises(ValueError, match="read-only"):
            array.flat[0] = 1.0
    with pytest.raises(AttributeError):
        system.A0 = np.zeros((2, 2))
    assert set(system.to_dict()) == {"A0", "phi", "B", "D", "w", "theta"}


def test_one_dimensional_input_matrix_is_a_column():
    system = UncertainLinearSystem(
        np.eye(3), np.zeros((1, 3, 3)), np.ones(3), w=Box.from_center(np.zeros(3), 1.0), theta=Box([0.0], [1.0])
    )
    assert system.B.shape == (3, 1) and system.ninputs == 1


def test_bad_input_is_rejected():
    w2, t1 = Box([-1.0, -1.0], [1.0, 1.0]), Box([0.0], [1.0])
    ok = dict(w=w2, theta=t1)
    with pytest.raises(DimensionError, match=r"A0 must have shape \(2, 2\), got shape \(2, 3\)"):
        UncertainLinearSystem(np.ones((2, 3)), np.zeros((1, 2, 2)), np.ones((2, 1)), **ok)
    with pytest.raises(DimensionError, match=r"phi must have shape \(\*, 2, 2\), got shape \(1, 3, 3\)"):
        UncertainLinearSystem(np.eye(2), np.zeros((1, 3, 3)), np.ones((2, 1)), **ok)
    with pytest.raises(DimensionError, match=r"phi must be 3-dimensional, got shape \(2, 2\)"):
        UncertainLinearSystem(np.eye(2), np.zeros((2, 2)), np.ones((2, 1)), **ok)
    with pytest.raises(DimensionError, match=r"B must have shape \(2, \*\), got shape \(3, 1\)"):
        UncertainLinearSystem(np.eye(2), np.zeros((1, 2, 2)), np.ones((3, 1)), **ok)
    with pytest.raises(DimensionError, match=r"D must have shape \(2, \*\), got shape \(3, 2\)"):
        UncertainLinearSystem(np.eye(2), np.zeros((1, 2, 2)), np.ones((2, 1)), D=np.ones((3, 2)), **ok)
    with pytest.raises(DimensionError, match=r"w must have dimension 1 \(columns of D, shape \(2, 1\)\), got 2"):
        UncertainLinearSystem(np.eye(2), np.zeros((1, 2, 2)), np.ones((2, 1)), D=np.ones((2, 1)), **ok)
    with pytest.raises(DimensionError, match=r"theta must have dimension 2 \(phi has shape \(2, 2, 2\)\), got 1"):
        UncertainLinearSystem(np.eye(2), np.zeros((2, 2, 2)), np.ones((2, 1)), **ok)
    with pytest.raises(InputError, match=r"w must be a Box, got tuple"):
        UncertainLinearSystem(np.eye(2), np.zeros((1, 2, 2)), np.ones((2, 1)), w=(-1, 1), theta=t1)
    with pytest.raises(InputError, match=r"theta must be a Box, got list"):
        UncertainLinearSystem(np.eye(2), np.zeros((1, 2, 2)), np.ones((2, 1)), w=w2, theta=[0, 1])
    with pytest.raises(NonFiniteError, match=r"A0 contains NaN or infinite entries"):
        UncertainLinearSystem(np.array([[np.nan, 0.0], [0.0, 1.0]]), np.zeros((1, 2, 2)), np.ones((2, 1)), **ok)
    with pytest.raises(TypeError):
        UncertainLinearSystem(np.eye(2), np.zeros((1, 2, 2)), np.ones((2, 1)), np.eye(2), w2, t1)  # keyword-only
    system = UncertainLinearSystem(np.eye(2), np.zeros((1, 2, 2)), np.ones((2, 1)), **ok)
    with pytest.raises(DimensionError, match=r"theta must have shape \(1,\) or \(k, 1\), got shape \(2,\)"):
        system.A([0.0, 1.0])
    with pytest.raises(DimensionError, match=r"x must have shape \(2,\), got shape \(3,\)"):
        system.step(np.zeros(3), np.zeros(1), [0.0])
    with pytest.raises(DimensionError, match=r"u must have shape \(1,\), got shape \(2,\)"):
        system.step(np.zeros(2), np.zeros(2), [0.0])
    with pytest.raises(DimensionError, match=r"w must have shape \(2,\), got shape \(1,\)"):
        system.step(np.zeros(2), np.zeros(1), [0.0], [0.0])
    with pytest.raises(NonFiniteError, match=r"u contains NaN"):
        system.step(np.zeros(2), [np.nan], [0.0])
    with pytest.raises(DimensionError, match=r"x must have shape \(2,\) or \(N, 2\), got shape \(4,\)"):
        system.regressor(np.zeros(4))
    with pytest.raises(InputError, match=r"dt must be > 0, got 0.0"):
        UncertainLinearSystem.from_continuous(np.eye(2), np.zeros((1, 2, 2)), np.ones((2, 1)), dt=0.0, **ok)
    with pytest.raises(DimensionError, match=r"A must have shape \(2, 2\), got shape \(2, 1\)"):
        UncertainLinearSystem.from_continuous(np.ones((2, 1)), np.zeros((1, 2, 2)), np.ones((2, 1)), dt=0.1, **ok)


def test_ragged_and_complex_arrays_are_input_errors():
    from minimaxplan.models import InputError
    from minimaxplan.models.validation import as_finite_array

    with pytest.raises(InputError, match="x must be a real numeric array"):
        as_finite_array("x", [[1.0, 2.0], [3.0]])
    with pytest.raises(InputError, match="x must be a real numeric array, got complex"):
        as_finite_array("x", [1.0 + 2.0j])
