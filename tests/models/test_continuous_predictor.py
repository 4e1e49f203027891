"""Tests of the paper's continuous-time predictor (eq. (9) corrected), integrated by Euler."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.models import Box, DimensionError, Ellipsoid, InputError, UncertainLinearSystem, predict_tube
from minimaxplan.models.continuous_predictor import euler_keeps_inclusion, predict_tube_continuous
from minimaxplan.models.polytope import parameter_vertices

HORIZON = 15


def metzler_model(rng, p, d, kind):
    """Continuous-time (A, phi, B, D, w, parameters, thetas) with a Metzler nominal matrix A_N."""
    A = rng.normal(size=(p, p))
    phi = rng.normal(size=(d, p, p)) * 0.3
    B = rng.normal(size=(p, 1))
    D = rng.normal(size=(p, p))
    w = Box.from_center(rng.normal(size=p) * 0.1, rng.uniform(0, 0.3, size=p))
    if kind == "box":
        parameters = Box.from_center(rng.normal(size=d) * 0.2, rng.uniform(0.05, 0.5, size=d))
        thetas = np.vstack(
            [
                parameters.vertices()[rng.integers(2**d, size=20)],
                rng.uniform(parameters.low, parameters.high, size=(20, d)),
            ]
        )
    elif kind == "ellipsoid":
        factor = rng.normal(size=(d, d))
        parameters = Ellipsoid(rng.normal(size=d) * 0.2, factor @ factor.T + 0.5 * np.eye(d), 0.4)
        directions = rng.normal(size=(40, d))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        directions[20:] *= rng.uniform(0, 1, size=(20, 1))
        thetas = (
            parameters.center
            + np.linalg.solve(np.linalg.cholesky(parameters.gramian).T, directions.T).T * parameters.radius
        )
    else:
        parameters = rng.normal(size=(int(rng.integers(1, 5)), d)) * 0.3
        thetas = np.vstack(
            [
                parameters[rng.integers(len(parameters), size=20)],
                rng.dirichlet(np.ones(len(parameters)), size=20) @ parameters,
            ]
        )
    # Shift A's off-diagonal entries so that A_N = A(mean vertex) is Metzler.
    nominal = A + np.tensordot(parameter_vertices(parameters).mean(axis=0), phi, axes=1)
    off_diagonal = ~np.eye(p, dtype=bool)
    A[off_diagonal] += max(0.0, -nominal[off_diagonal].min(initial=0.0)) + rng.uniform(0, 0.5)
    A -= np.eye(p) * rng.uniform(0.5, 2.0)
    return A, phi, B, D, w, parameters, thetas


def simulate_euler(A, phi, B, D, w, thetas, x0s, controls, disturbances, dt):
    system = UncertainLinearSystem.from_continuous(
        A, phi, B, D=D, w=w, theta=Box(thetas.min(axis=0), thetas.max(axis=0)), dt=dt
    )
    matrices = system.A(thetas)
    states = [x0s]
    for n in range(controls.shape[0]):
        states.append(
            np.einsum("nij,nj->ni", matrices, states[-1]) + controls[n] @ system.B.T + disturbances[:, n] @ system.D.T
        )
    return np.stack(states, axis=1)


def extreme_disturbances(rng, w, n, horizon):
    signs = rng.integers(0, 2, size=(n // 2, horizon, w.dim))
    return np.concatenate(
        [np.where(signs == 1, w.high, w.low), rng.uniform(w.low, w.high, size=(n - n // 2, horizon, w.dim))]
    )


@given(
    seed=st.integers(0, 2**32 - 1),
    p=st.integers(1, 5),
    d=st.integers(1, 3),
    fraction=st.floats(0.05, 1.0),
    kind=st.sampled_from(["box", "ellipsoid", "vertices"]),
)
def test_euler_predictor_keeps_inclusion_when_I_plus_dt_AN_is_nonnegative(seed, p, d, fraction, kind):
    rng = np.random.default_rng(seed)
    A, phi, B, D, w, parameters, thetas = metzler_model(rng, p, d, kind)
    nominal = A + np.tensordot(parameter_vertices(parameters).mean(axis=0), phi, axes=1)
    dt = fraction / max(1.0, float(np.max(-np.diag(nominal))))  # the largest admissible dt, scaled down
    x0 = Box.from_center(rng.normal(size=p), rng.uniform(0, 0.5, size=p))
    controls = rng.normal(size=(HORIZON, 1))
    tube = predict_tube_continuous(A, phi, B, D=D, w=w, x0=x0, controls=controls, dt=dt, parameters=parameters)
    assert tube.guaranteed and euler_keeps_inclusion(nominal, dt)
    x0s = np.vstack([x0.vertices()[rng.integers(2**p, size=20)], rng.uniform(x0.low, x0.high, size=(20, p))])
    states = simulate_euler(A, phi, B, D, w, thetas, x0s, controls, extreme_disturbances(rng, w, 40, HORIZON), dt)
    assert tube.contains(states)


def test_euler_predictor_loses_trajectories_at_large_dt():
    # A Metzler system with a fast mode: I + dt A_N has a negative diagonal at dt = 0.4.
    A = np.array([[-4.0, 1.0], [0.5, -1.0]])
    phi = np.zeros((1, 2, 2))
    phi[0, 0, 1] = 0.2
    B = np.zeros((2, 1))
    w = Box.from_center(np.zeros(2), 0.05)
    parameters = Box(np.array([-1.0]), np.array([1.0]))
    x0 = Box(np.array([0.5, 0.5]), np.array([1.5, 1.0]))
    controls = np.zeros((HORIZON, 1))
    dt = 0.4
    tube = predict_tube_continuous(A, phi, B, w=w, x0=x0, controls=controls, dt=dt, parameters=parameters)
    assert not tube.guaranteed and "fails" in tube.note
    rng = np.random.default_rng(0)
    thetas = rng.uniform(-1, 1, size=(200, 1))
    x0s = rng.uniform(x0.low, x0.high, size=(200, 2))
    states = simulate_euler(
        A, phi, B, np.eye(2), w, thetas, x0s, controls, extreme_disturbances(rng, w, 200, HORIZON), dt
    )
    assert not tube.contains(states)  # the counterexample: some trajectory leaves the tube
    # The discrete-time predictor on the same Euler plant contains every one of them.
    system = UncertainLinearSystem.from_continuous(A, phi, B, w=w, theta=parameters, dt=dt)
    assert predict_tube(system, x0, controls).contains(states)


@given(seed=st.integers(0, 2**32 - 1), p=st.integers(1, 4))
def test_without_parameter_uncertainty_it_equals_the_discrete_predictor(seed, p):
    # X = 0 and I + dt A_N >= 0: both predictors compute (I + dt A_N) x_lo + dt (B u + D+ w_lo - D- w_hi).
    rng = np.random.default_rng(seed)
    A, phi, B, D, w, parameters, _ = metzler_model(rng, p, 1, "box")
    theta = Box(parameters.center, parameters.center)  # A_N = A(centre) is Metzler by construction
    nominal = A + parameters.center[0] * phi[0]
    dt = 0.9 / max(1.0, float(np.max(-np.diag(nominal))))
    assert euler_keeps_inclusion(nominal, dt)
    x0 = Box.from_center(rng.normal(size=p), 0.2)
    controls = rng.normal(size=(HORIZON, 1))
    continuous = predict_tube_continuous(A, phi, B, D=D, w=w, x0=x0, controls=controls, dt=dt, parameters=theta)
    discrete = predict_tube(
        UncertainLinearSystem.from_continuous(A, phi, B, D=D, w=w, theta=theta, dt=dt), x0, controls
    )
    np.testing.assert_allclose(continuous.lower, discrete.lower, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(continuous.upper, discrete.upper, rtol=1e-10, atol=1e-10)


def test_condition_and_errors():
    assert euler_keeps_inclusion(np.array([[-2.0, 1.0], [0.0, -1.0]]), 0.5)
    assert not euler_keeps_inclusion(np.array([[-2.0, 1.0], [0.0, -1.0]]), 0.6)
    assert not euler_keeps_inclusion(np.array([[-1.0, -0.1], [0.0, -1.0]]), 0.01)  # not Metzler
    args = dict(
        w=Box.from_center(np.zeros(2), 0.1),
        x0=Box.from_center(np.zeros(2), 0.1),
        controls=np.zeros((3, 1)),
        parameters=Box(np.zeros(1), np.ones(1)),
    )
    A, phi, B = -np.eye(2), np.zeros((1, 2, 2)), np.ones((2, 1))
    with pytest.raises(InputError, match="dt must be > 0, got 0.0"):
        predict_tube_continuous(A, phi, B, dt=0.0, **args)
    with pytest.raises(DimensionError, match=r"phi must have shape \(\*, 2, 2\), got shape \(1, 3, 3\)"):
        predict_tube_continuous(A, np.zeros((1, 3, 3)), B, dt=0.1, **args)
    with pytest.raises(DimensionError, match=r"controls must have shape \(\*, 1\), got shape \(3, 2\)"):
        predict_tube_continuous(A, phi, B, dt=0.1, **{**args, "controls": np.zeros((3, 2))})
    with pytest.raises(DimensionError, match=r"x0 must have dimension 2 \(A has shape \(2, 2\)\), got 1"):
        predict_tube_continuous(A, phi, B, dt=0.1, **{**args, "x0": Box(np.zeros(1), np.ones(1))})
    with pytest.raises(DimensionError, match=r"parameters must have dimension 1 .*got vertices of shape \(4, 2\)"):
        predict_tube_continuous(A, phi, B, dt=0.1, **{**args, "parameters": Box(np.zeros(2), np.ones(2))})
    with pytest.raises(DimensionError, match=r"w must have dimension 2 \(columns of D, shape \(2, 2\)\), got 3"):
        predict_tube_continuous(A, phi, B, dt=0.1, **{**args, "w": Box(np.zeros(3), np.ones(3))})
    with pytest.raises(DimensionError, match=r"nominal must have shape \(2, 2\), got shape \(2, 3\)"):
        euler_keeps_inclusion(np.zeros((2, 3)), 0.1)
