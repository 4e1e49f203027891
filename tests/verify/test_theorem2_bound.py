"""Theorem 2 (corrected, see DESIGN.md errata): the interval predictor's widths stay within
the bound that an Assumption 4 certificate of ``(|A_N|, |D|)`` buys, when there is no
parametric uncertainty."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.models import Box, UncertainLinearSystem, predict_tube
from minimaxplan.verify import check_assumption4

HORIZON = 50


def random_plant(rng, p, r, radius):
    """A_N with rho(|A_N|) = radius (so A_N is Schur too: rho(A) <= rho(|A|)), mixed signs."""
    M = rng.standard_normal((p, p)) * (rng.random((p, p)) < 0.8)
    M[np.diag_indices(p)] += 0.1  # never the zero matrix
    A_N = M * (radius / np.abs(np.linalg.eigvals(np.abs(M))).max())
    phi = rng.standard_normal((2, p, p))
    theta = rng.uniform(-1, 1, 2)
    A0 = A_N - np.tensordot(theta, phi, axes=1)  # A(theta) = A_N exactly at this theta
    D = rng.standard_normal((p, r))
    w_low = rng.uniform(-1, 0, r)
    w_high = w_low + rng.uniform(0, 1, r)
    system = UncertainLinearSystem(
        A0, phi, rng.standard_normal((p, 1)), D=D, w=Box(w_low, w_high), theta=Box(theta - 1, theta + 1)
    )
    return system, theta


@given(
    p=st.integers(2, 4),
    r=st.integers(1, 3),
    radius=st.floats(0.2, 0.97),
    seed=st.integers(0, 2**32 - 1),
)
def test_predicted_widths_stay_within_the_certified_bound(p, r, radius, seed):
    rng = np.random.default_rng(seed)
    system, theta = random_plant(rng, p, r, radius)
    A_N = system.A(theta)
    assert np.abs(np.linalg.eigvals(np.abs(A_N))).max() < 1
    certificate = check_assumption4(np.abs(A_N), form="discrete", D=np.abs(system.D))
    assert certificate.status == "feasible" and certificate.certified, certificate.reason

    center = rng.standard_normal(p) * 3
    x0 = Box.from_center(center, rng.uniform(0, 2, p))
    controls = rng.uniform(-1, 1, (HORIZON, 1))
    tube = predict_tube(system, x0, controls, parameters=Box(theta, theta))

    widths = tube.upper - tube.lower
    assert np.all(widths >= 0)
    width_norms = np.linalg.norm(widths, axis=1)
    e0_norm = width_norms[0]
    w_width_norm = float(np.linalg.norm(system.w.high - system.w.low))
    stepwise = certificate.width_bound(e0_norm, w_width_norm, steps=np.arange(HORIZON + 1))
    uniform = certificate.width_bound(e0_norm, w_width_norm)
    tol = 1e-9 * (1 + np.abs(tube.upper).max() + np.abs(tube.lower).max())
    assert np.all(width_norms <= stepwise + tol), (width_norms - stepwise).max()
    assert np.all(stepwise <= uniform * (1 + 1e-12))
    # The comparison system e+ = |A_N| e + |D| dw is what the bound is proved for;
    # the predictor's widths never exceed it (equality in exact arithmetic).
    e = widths[0].copy()
    dw = system.w.high - system.w.low
    for n in range(1, HORIZON + 1):
        e = np.abs(A_N) @ e + np.abs(system.D) @ dw
        assert np.all(widths[n] <= e + tol)


def test_bound_is_not_vacuous_on_a_tight_example():
    # Diagonal nonnegative A_N: widths follow e+ = a e + dw exactly; the steady width
    # dw / (1 - a) must lie below the bound, which must be finite and of the same order.
    a, dw = 0.9, 0.2
    system = UncertainLinearSystem(
        np.array([[a]]), np.zeros((1, 1, 1)), np.ones((1, 1)), w=Box([-dw / 2], [dw / 2]), theta=Box([0.0], [0.0])
    )
    certificate = check_assumption4(np.array([[a]]), form="discrete")
    tube = predict_tube(system, Box([0.0], [0.0]), np.zeros((200, 1)), parameters=Box([0.0], [0.0]))
    steady = (tube.upper - tube.lower)[-1, 0]
    assert steady == np.float64(steady) and abs(steady - dw / (1 - a)) < 1e-6
    bound = certificate.width_bound(0.0, dw)
    assert steady <= bound < 20 * steady


@given(
    p=st.integers(2, 4),
    dt=st.floats(0.01, 1.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_bound_holds_for_forward_euler_plants_at_any_dt(p, dt, seed):
    # dx/dt = (-a I + E) x + B u + D w with rho(|E|) < a, a dt <= 1: then
    # |I + dt A| <= (1 - a dt) I + dt |E| is Schur for every such dt (non-Metzler E).
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.2, 1.0 / dt)  # dt <= 1, so 0.2 < 1 / dt
    E = rng.standard_normal((p, p))
    E *= rng.uniform(0.1, 0.9) * a / np.abs(np.linalg.eigvals(np.abs(E))).max()
    theta = np.array([0.3])
    phi = rng.standard_normal((1, p, p))
    A_c = -a * np.eye(p) + E - theta[0] * phi[0]  # A(theta) = -a I + E
    D = rng.standard_normal((p, 2))
    system = UncertainLinearSystem.from_continuous(
        A_c,
        phi,
        np.ones((p, 1)),
        D=D,
        w=Box.from_center(np.zeros(2), rng.uniform(0.01, 1, 2)),
        theta=Box(theta, theta),
        dt=dt,
    )
    A_N = system.A(theta)
    certificate = check_assumption4(np.abs(A_N), form="discrete", D=np.abs(system.D))
    assert certificate.status == "feasible" and certificate.certified, certificate.reason
    x0 = Box.from_center(rng.standard_normal(p), rng.uniform(0, 1, p))
    tube = predict_tube(system, x0, np.zeros((HORIZON, 1)), parameters=Box(theta, theta))
    width_norms = np.linalg.norm(tube.upper - tube.lower, axis=1)
    w_width = float(np.linalg.norm(system.w.high - system.w.low))
    bound = certificate.width_bound(width_norms[0], w_width, steps=np.arange(HORIZON + 1))
    tol = 1e-9 * (1 + np.abs(tube.upper).max() + np.abs(tube.lower).max())
    assert np.all(width_norms <= bound + tol)
