"""Tests of the Assumption 4 LMI (verify.lmi.check_assumption4)."""

from __future__ import annotations

import json
from dataclasses import replace as dataclasses_replace

import cvxpy as cp
import numpy as np
import pytest
import scipy.linalg as sla
from hypothesis import given
from hypothesis import strategies as st

import minimaxplan.verify.lmi as lmi
from minimaxplan.models.errors import DimensionError, InputError, NonFiniteError
from minimaxplan.verify import LMIResult, LMIStatus, check_assumption4
from minimaxplan.verify import lmi_matrix as library_lmi_matrix

from .test_lmi_verdicts import exact_lmi, positive_definite

# ----------------------------------------------------------------- helpers


def lmi_matrix(form, A, D, P, Q0, rho):
    """The LMI of Assumption 4 (continuous) or its discrete analogue, built here in numpy."""
    r = D.shape[1]
    if form == "continuous":
        M = np.block([[A.T @ P + P @ A + Q0, P @ D], [D.T @ P, -rho * np.eye(r)]])
    else:
        M = np.block([[A.T @ P @ A - P + Q0, A.T @ P @ D], [D.T @ P @ A, D.T @ P @ D - rho * np.eye(r)]])
    return (M + M.T) / 2


def linear_discrete_lmi(A, D, P, Q0, rho):
    """The Schur-complement (linear) form of the discrete LMI."""
    p, r = D.shape
    M = np.block(
        [
            [Q0 - P, np.zeros((p, r)), A.T @ P],
            [np.zeros((r, p)), -rho * np.eye(r), D.T @ P],
            [P @ A, P @ D, -P],
        ]
    )
    return (M + M.T) / 2


def assert_certificate(result: LMIResult, vertices, D, form):
    """Independent numpy check: P > 0, Q0 > 0, rho > 0, and every vertex's LMI < 0."""
    assert result.status == "feasible" and result.certified and not result.inaccurate
    P, Q0, rho = np.asarray(result.P), np.asarray(result.Q0), result.rho
    assert np.array_equal(P, P.T) and np.array_equal(Q0, Q0.T)
    eig_p = np.linalg.eigvalsh(P)
    assert eig_p[0] > 1e-12 * eig_p[-1]
    np.testing.assert_allclose(result.eigenvalues_P, eig_p, rtol=1e-12, atol=0)
    assert np.linalg.eigvalsh(Q0)[0] > 0
    assert rho > 0
    worst = -np.inf
    for A in np.asarray(vertices).reshape(-1, P.shape[0], P.shape[0]):
        M = lmi_matrix(form, A, D, P, Q0, rho)
        # Negative definite, proven in Fractions: a float eigenvalue within rounding of 0
        # can neither prove nor refute it (the library certifies exactly too).
        exact = exact_lmi(form, A, D, P, Q0, rho)
        assert positive_definite([[-x for x in row] for row in exact])
        top = np.linalg.eigvalsh(M)[-1]
        worst = max(worst, top)
        if form == "discrete":
            L = linear_discrete_lmi(A, D, P, Q0, rho)
            assert np.linalg.eigvalsh(L)[-1] < 0
    assert result.max_eigenvalue < 0
    assert result.max_eigenvalue == pytest.approx(worst, rel=1e-6, abs=1e-12 * np.linalg.norm(P))


def assert_dual(result: LMIResult, vertices, form, margin=1e-6):
    """Independent numpy check of an infeasible verdict's dual certificate (see DualCertificate)."""
    assert result.status == "infeasible" and result.P is None and not result.certified
    dual = result.dual
    assert dual is not None and result.margin == dual.margin and 0 <= dual.margin < margin
    T, Y, Z = np.asarray(dual.T), np.asarray(dual.Y), np.asarray(dual.Z)
    vertices = np.asarray(vertices).reshape(-1, T.shape[0], T.shape[0])
    assert Z.shape == vertices.shape
    for S in (Y, *Z):
        assert np.linalg.eigvalsh(S)[0] >= -1e-12 * max(1.0, np.abs(S).max())
    W = T @ Y @ T.T
    for A, Zk in zip(vertices, Z):
        X = T @ Zk @ T.T
        W = W + (A @ X + X @ A.T if form == "continuous" else A @ X @ A.T - X)
    assert np.linalg.eigvalsh((W + W.T) / 2)[0] > 0
    assert np.trace(Y) <= dual.margin * np.trace(Z, axis1=1, axis2=2).sum() * (1 + 1e-12)
    assert "no certificate with normalised margin above" in result.reason


def random_basis(rng, p, condition):
    """A real (p, p) matrix with singular values spread from 1 to 1/condition."""
    U, _ = np.linalg.qr(rng.standard_normal((p, p)))
    W, _ = np.linalg.qr(rng.standard_normal((p, p)))
    return U @ np.diag(np.logspace(0, -np.log10(condition), p)) @ W.T


def near_boundary_matrix(rng, p, form, distance, stable, condition):
    """A = V J V^-1, J real block diagonal, cond(V) = condition, at +-distance from the boundary.

    Continuous: spectral abscissa -distance (stable) or +distance. Discrete: spectral
    radius 1 -+ distance. The extreme eigenvalue (or complex pair) is the first block.
    """
    blocks, n, first = [], 0, True
    while n < p:
        pair = p - n >= 2 and rng.random() < 0.5
        if form == "continuous":
            edge = -distance if stable else distance
            real = edge if first else edge - rng.uniform(0.0, 2.0)
            block = np.array([[real, w := rng.uniform(0.1, 2.0)], [-w, real]]) if pair else np.array([[real]])
        else:
            edge = 1.0 - distance if stable else 1.0 + distance
            modulus = edge if first else edge * rng.uniform(0.0, 1.0)
            angle = rng.uniform(0.1, 3.0)
            block = (
                modulus * np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
                if pair
                else np.array([[modulus * rng.choice([-1.0, 1.0])]])
            )
        blocks.append(block)
        n += block.shape[0]
        first = False
    V = random_basis(rng, p, condition)
    return V @ sla.block_diag(*blocks) @ np.linalg.inv(V)


@st.composite
def boundary_cases(draw, form):
    p = draw(st.integers(2, 5))
    distance = draw(st.floats(0.01, 0.05))
    stable = draw(st.booleans())
    condition = 10.0 ** draw(st.floats(0.0, 3.0))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    A = near_boundary_matrix(rng, p, form, distance, stable, condition)
    r = draw(st.integers(1, 3))
    D = np.eye(p) if draw(st.booleans()) else rng.standard_normal((p, r))
    return A, D, stable


# ----------------------------------------------------------------- truth on random matrices


@pytest.mark.parametrize("form", ["continuous", "discrete"])
def test_decision_matches_stability_near_the_boundary(form):
    @given(boundary_cases(form))
    def check(case):
        A, D, stable = case
        result = check_assumption4(A, form=form, D=D)
        assert result.status != "inconclusive", result.reason
        assert result.status == ("feasible" if stable else "infeasible"), result.reason
        if stable:
            assert_certificate(result, A, D, form)
        else:
            assert_dual(result, A, form)

    check()


@pytest.mark.parametrize("form", ["continuous", "discrete"])
def test_boundary_generator_places_the_spectrum_as_claimed(form):
    rng = np.random.default_rng(3)
    for stable in (True, False):
        A = near_boundary_matrix(rng, 4, form, 0.02, stable, 1e3)
        eigenvalues = np.linalg.eigvals(A)
        edge = eigenvalues.real.max() if form == "continuous" else np.abs(eigenvalues).max()
        target = (-0.02 if stable else 0.02) if form == "continuous" else (0.98 if stable else 1.02)
        assert edge == pytest.approx(target, abs=1e-8)


@given(st.integers(2, 4), st.floats(0.0, 0.9), st.integers(0, 2**32 - 1))
def test_given_q0_is_returned_and_certified(p, scale_exponent, seed):
    rng = np.random.default_rng(seed)
    A = near_boundary_matrix(rng, p, "discrete", 0.05 + 0.5 * rng.random(), True, 10.0**scale_exponent)
    G = rng.standard_normal((p, p))
    Q0 = G @ G.T + 0.1 * np.eye(p)
    result = check_assumption4(A, form="discrete", Q0=Q0)
    np.testing.assert_array_equal(result.Q0, Q0)
    assert_certificate(result, A, np.eye(p), "discrete")
    continuous = check_assumption4(A - np.eye(p), form="continuous", Q0=Q0)
    np.testing.assert_array_equal(continuous.Q0, Q0)
    assert_certificate(continuous, A - np.eye(p), np.eye(p), "continuous")


def test_zero_disturbance_matrix_still_gives_a_certificate():
    A = np.array([[-1.0, 3.0], [0.0, -2.0]])
    D = np.zeros((2, 1))
    assert_certificate(check_assumption4(A, form="continuous", D=D), A, D, "continuous")


# ----------------------------------------------------------------- polytopes (common P)


@st.composite
def polytopes_with_known_common_p(draw, form):
    p = draw(st.integers(2, 4))
    k = draw(st.integers(2, 4))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    G = random_basis(rng, p, 10.0 ** draw(st.floats(0.0, 1.0)))
    P0 = G @ G.T
    vertices = []
    for _ in range(k):
        if form == "continuous":
            # A = P0^-1 S with S + S^T < 0: A^T P0 + P0 A = S^T + S < 0.
            H = rng.standard_normal((p, p))
            K = rng.standard_normal((p, p)) * draw(st.floats(0.0, 5.0))
            S = -(H @ H.T + 0.05 * np.eye(p)) + (K - K.T)
            vertices.append(np.linalg.solve(P0, S))
        else:
            # A = P0^-1/2 C P0^1/2 with ||C|| < 1: A^T P0 A - P0 = P0^1/2 (C^T C - I) P0^1/2 < 0.
            C = rng.standard_normal((p, p))
            C *= draw(st.floats(0.1, 0.95)) / np.linalg.norm(C, 2)
            root = sla.sqrtm(P0).real
            vertices.append(np.linalg.solve(root, C @ root))
    return np.array(vertices)


@pytest.mark.parametrize("form", ["continuous", "discrete"])
def test_polytope_sharing_a_known_p_is_feasible(form):
    @given(polytopes_with_known_common_p(form))
    def check(vertices):
        result = check_assumption4(vertices, form=form)
        assert result.nvertices == len(vertices)
        assert_certificate(result, vertices, np.eye(vertices.shape[1]), form)

    check()


def test_liberzon_pair_has_no_common_quadratic_lyapunov_function():
    # Liberzon, Switching in Systems and Control (2003), sec. 2.1.5: both Hurwitz, every
    # convex combination Hurwitz, yet switching can destabilise. For 2x2 Hurwitz matrices a
    # common quadratic Lyapunov function exists iff A1 A2 and A1 A2^-1 have no negative
    # real eigenvalue (Shorten & Narendra 2003); here A1 A2 has two.
    A1 = np.array([[-0.1, -1.0], [2.0, -0.1]])
    A2 = np.array([[-0.1, -2.0], [1.0, -0.1]])
    for gamma in np.linspace(0, 1, 101):
        assert np.linalg.eigvals(gamma * A1 + (1 - gamma) * A2).real.max() < 0
    product = np.linalg.eigvals(A1 @ A2)
    assert np.all(np.abs(product.imag) < 1e-12) and np.all(product.real < 0)
    assert_dual(check_assumption4([A1, A2], form="continuous"), [A1, A2], "continuous")
    for A in (A1, A2):
        assert_certificate(check_assumption4(A, form="continuous"), A, np.eye(2), "continuous")


def test_unstable_midpoint_means_no_common_p():
    A1 = np.array([[-1.0, 4.0], [0.0, -1.0]])
    A2 = A1.T
    assert np.linalg.eigvals((A1 + A2) / 2).real.max() > 0
    assert_dual(check_assumption4(np.stack([A1, A2]), form="continuous"), [A1, A2], "continuous")


def test_discrete_switching_unstable_pair_has_no_common_p():
    # Each vertex is Schur (spectral radius 0.5), but rho(A1 A2) > 1, so the joint spectral
    # radius exceeds 1 and no common P (which would make every product contract) exists.
    A1 = np.array([[0.5, 1.2], [0.0, 0.5]])
    A2 = A1.T
    assert max(np.abs(np.linalg.eigvals(A)).max() for A in (A1, A2)) < 1
    assert np.abs(np.linalg.eigvals(A1 @ A2)).max() > 1
    assert_dual(check_assumption4([A1, A2], form="discrete"), [A1, A2], "discrete")


@pytest.mark.parametrize("form", ["continuous", "discrete"])
def test_one_unstable_vertex_makes_the_polytope_infeasible(form):
    rng = np.random.default_rng(11)
    # Stable vertices sharing P = I: -I + skew (continuous), 0.8 x orthogonal (discrete).
    skews = [(K - K.T) for K in rng.standard_normal((3, 3, 3))]
    if form == "continuous":
        stable = [-np.eye(3) + K for K in skews]
    else:
        stable = [0.8 * sla.expm(K) for K in skews]
    unstable = near_boundary_matrix(rng, 3, form, 0.02, False, 5.0)
    assert check_assumption4(np.stack(stable), form=form).status == "feasible"
    result = check_assumption4(np.stack(stable + [unstable]), form=form)
    assert result.nvertices == 4
    assert_dual(result, np.stack(stable + [unstable]), form)


# ----------------------------------------------------------------- results, bound constants


def test_result_to_dict_is_json_ready():
    A = np.array([[0.5, 1.0], [0.0, 0.6]])
    result = check_assumption4(A, form="discrete")
    data = json.loads(json.dumps(result.to_dict()))
    assert data["status"] == "feasible" and data["certified"] is True and data["solver"] == "CLARABEL"
    np.testing.assert_array_equal(np.array(data["P"]), result.P)
    assert data["bound_constants"] == list(result.bound_constants())
    infeasible = json.loads(json.dumps(check_assumption4(2 * A, form="discrete").to_dict()))
    assert infeasible["status"] == "infeasible" and infeasible["P"] is None and "bound_constants" not in infeasible
    assert infeasible["margin"] < 1e-6 and np.array(infeasible["dual"]["Z"]).shape == (1, 2, 2)


def test_result_arrays_are_read_only():
    result = check_assumption4(np.array([[0.5, 1.0], [0.0, 0.6]]), form="discrete")
    with pytest.raises(ValueError):
        result.P[0, 0] = 1.0


def test_bound_constants_follow_their_formula():
    result = check_assumption4(np.array([[0.5, 1.0], [0.0, 0.6]]), form="discrete")
    eig_p = np.linalg.eigvalsh(result.P)
    lmin_q0 = np.linalg.eigvalsh(result.Q0)[0]
    c0, cw = result.bound_constants()
    assert c0 == pytest.approx(np.sqrt(eig_p[-1] / eig_p[0]), rel=1e-12)
    assert cw == pytest.approx(np.sqrt(result.rho * eig_p[-1] / (eig_p[0] * lmin_q0)), rel=1e-12)
    assert result.width_bound(2.0, 3.0) == pytest.approx(2 * c0 + 3 * cw, rel=1e-12)
    steps = np.arange(6)
    stepwise = result.width_bound(2.0, 3.0, steps=steps)
    assert stepwise[0] == pytest.approx(2 * c0, rel=1e-12)
    assert np.all(stepwise <= 2 * c0 + 3 * cw + 1e-12)
    assert 0 < result.decay_factor() < 1


def test_statuses_are_a_str_enum_with_the_contracts_strings():
    assert [s.value for s in LMIStatus] == ["feasible", "infeasible", "inconclusive"]
    feasible = check_assumption4(np.array([[0.5]]), form="discrete")
    infeasible = check_assumption4(np.array([[1.5, 0.0], [0.0, 0.2]]), form="discrete")
    assert feasible.status is LMIStatus.FEASIBLE and feasible.status == "feasible"
    assert infeasible.status is LMIStatus.INFEASIBLE and infeasible.status == "infeasible"
    assert str(feasible.status) == f"{feasible.status}" == "feasible"
    # to_dict emits the plain string, so JSON documents are unchanged
    document = feasible.to_dict()
    assert type(document["status"]) is str and json.loads(json.dumps(document))["status"] == "feasible"
    assert feasible.holds and not infeasible.holds


def test_holds_needs_the_exact_recheck(monkeypatch):
    monkeypatch.setattr(lmi, "_exact_positive_definite", lambda M: False)
    result = check_assumption4(np.array([[0.5]]), form="discrete")
    assert result.status == "inconclusive" and not result.holds
    assert dataclasses_replace(result, status="feasible", certified=False).holds is False
    assert dataclasses_replace(result, status="feasible", certified=True).holds is True


def test_library_lmi_matrix_agrees_with_the_independent_one():
    rng = np.random.default_rng(3)
    A, P, Q0, D = rng.normal(size=(3, 3)), rng.normal(size=(3, 3)), rng.normal(size=(3, 3)), rng.normal(size=(3, 2))
    P, Q0 = P @ P.T, Q0 + Q0.T  # symmetric, as certificates are
    for form in ("continuous", "discrete"):
        # equal up to the association order of the triple products
        np.testing.assert_allclose(
            library_lmi_matrix(A, P, Q0, 0.7, D, form), lmi_matrix(form, A, D, P, Q0, 0.7), rtol=1e-14, atol=1e-14
        )
    np.testing.assert_allclose(
        library_lmi_matrix(A, P, Q0, 0.7, None, "discrete"),
        lmi_matrix("discrete", A, np.eye(3), P, Q0, 0.7),
        rtol=1e-14,
        atol=1e-14,
    )
    with pytest.raises(InputError, match=r"form must be one of \('continuous', 'discrete'\), got 'hybrid'"):
        library_lmi_matrix(A, P, Q0, 0.7, D, "hybrid")


def test_bound_constants_need_a_certificate():
    result = check_assumption4(np.array([[1.5, 0.0], [0.0, 0.2]]), form="discrete")
    assert result.status == "infeasible"
    with pytest.raises(InputError, match="certified feasible"):
        result.bound_constants()
    with pytest.raises(InputError, match="certified feasible"):
        result.width_bound(1.0, 1.0)


@given(st.integers(2, 4), st.integers(0, 2**32 - 1))
def test_discrete_bound_holds_along_random_disturbed_trajectories(p, seed):
    rng = np.random.default_rng(seed)
    A = near_boundary_matrix(rng, p, "discrete", rng.uniform(0.05, 0.5), True, 10 ** rng.uniform(0, 1.5))
    D = rng.standard_normal((p, 2))
    result = check_assumption4(A, form="discrete", D=D)
    assert_certificate(result, A, D, "discrete")
    e = rng.standard_normal(p)
    e0_norm = np.linalg.norm(e)
    w_norm = 0.5
    P = np.asarray(result.P)
    for n in range(1, 60):
        # Disturbances on the sphere ||w|| = W, pushing V = e^T P e up (worst case).
        w = D.T @ P @ A @ e if n % 4 else rng.standard_normal(2)
        e = A @ e + D @ (w * w_norm / np.linalg.norm(w))
        bound = result.width_bound(e0_norm, w_norm, steps=n)
        assert np.linalg.norm(e) <= bound * (1 + 1e-9)
        assert bound <= result.width_bound(e0_norm, w_norm) * (1 + 1e-12)


# ----------------------------------------------------------------- SCS, caching


def test_scs_is_selectable():
    A = np.array([[-1.0, 2.0], [0.0, -0.5]])
    result = check_assumption4(A, form="continuous", solver="scs")
    assert result.solver == "SCS"
    assert_certificate(result, A, np.eye(2), "continuous")


def test_problem_is_dpp_built_once_and_reused():
    A = np.array([[0.5, 1.0], [0.0, 0.6]])
    check_assumption4(A, form="discrete")
    key = ("discrete", 2, 1)
    program = lmi._PROGRAMS[key]
    assert program.problem.is_dpp()
    check_assumption4(0.9 * A.T, form="discrete")
    assert lmi._PROGRAMS[key] is program


def test_program_cache_evicts_the_least_recently_used(monkeypatch):
    monkeypatch.setattr(lmi, "_PROGRAMS", type(lmi._PROGRAMS)())
    monkeypatch.setattr(lmi, "PROBLEM_CACHE_SIZE", 2)
    for p in (2, 3, 4):
        check_assumption4(-np.eye(p), form="continuous")
    assert list(lmi._PROGRAMS) == [("continuous", 3, 1), ("continuous", 4, 1)]


# ----------------------------------------------------------------- solver statuses


def fake_status(monkeypatch, status):
    monkeypatch.setattr(cp.Problem, "solve", lambda self, *args, **kwargs: None)
    monkeypatch.setattr(cp.Problem, "status", property(lambda self: status))


UNSTABLE = np.array([[1.2, 1.0], [0.0, 0.5]])  # no Lyapunov-equation certificate either


@pytest.mark.parametrize("status", [cp.OPTIMAL_INACCURATE, cp.INFEASIBLE_INACCURATE])
def test_inaccurate_statuses_without_a_proof_are_inconclusive_and_flagged(monkeypatch, status):
    fake_status(monkeypatch, status)
    result = check_assumption4(UNSTABLE, form="discrete")
    assert result.status == "inconclusive" and result.inaccurate and not result.certified
    assert result.solver_status == status and result.dual is None
    assert "no proof either way" in result.reason and status in result.reason


@pytest.mark.parametrize(
    "status", [cp.INFEASIBLE, cp.UNBOUNDED, cp.UNBOUNDED_INACCURATE, cp.SOLVER_ERROR, cp.USER_LIMIT]
)
def test_other_statuses_are_reported_not_raised(monkeypatch, status):
    fake_status(monkeypatch, status)
    result = check_assumption4(UNSTABLE, form="discrete")
    assert result.status == "inconclusive" and not result.inaccurate
    assert result.reason.count(f"solver status {status!r}") == 4  # primal and dual, in both coordinates
    # a stable matrix is still certified, by the Lyapunov equation, whatever the solver says
    stable = check_assumption4(np.array([[0.5, 1.0], [0.0, 0.5]]), form="discrete")
    assert_certificate(stable, np.array([[0.5, 1.0], [0.0, 0.5]]), np.eye(2), "discrete")
    assert stable.solver_status == "not solved (Lyapunov equation)"


def test_solver_error_is_reported_not_raised(monkeypatch):
    def broken(self, *args, **kwargs):
        raise cp.error.SolverError("numerical trouble")

    monkeypatch.setattr(cp.Problem, "solve", broken)
    result = check_assumption4(UNSTABLE, form="continuous")
    assert result.status == "inconclusive" and "CLARABEL failed: numerical trouble" in result.reason
    stable = check_assumption4(-UNSTABLE, form="continuous")
    assert_certificate(stable, -UNSTABLE, np.eye(2), "continuous")


def test_failed_exact_recheck_is_inconclusive(monkeypatch):
    # A re-check that refuses everything: no certificate, no dual certificate.
    monkeypatch.setattr(lmi, "_exact_positive_definite", lambda M: False)
    for A in (np.array([[0.5, 0.0], [0.0, 0.5]]), UNSTABLE):
        result = check_assumption4(A, form="discrete")
        assert result.status == "inconclusive" and not result.certified and not result.inaccurate
        assert result.P is None and result.dual is None
    assert "P is not positive definite (exact re-check)" in check_assumption4(np.array([[0.5]]), form="discrete").reason
    assert "the dual certificate failed the exact re-check" in result.reason


# ----------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("A", "error", "pattern"),
    [
        (np.ones((2, 3)), DimensionError, r"A must have shape \(p, p\) or \(k, p, p\).*got shape \(2, 3\)"),
        (np.ones(3), DimensionError, r"got shape \(3,\)"),
        (np.ones((2, 2, 3)), DimensionError, r"got shape \(2, 2, 3\)"),
        (np.ones((0, 2, 2)), DimensionError, r"got shape \(0, 2, 2\)"),
        ([], DimensionError, "at least one matrix"),
        (
            [np.eye(2), np.eye(3)],
            DimensionError,
            r"A's matrices must all have one shape \(p, p\), got shapes \[\(2, 2\), \(3, 3\)\]",
        ),
        ([[1.0, "x"], [0.0, 1.0]], InputError, "A must be a real numeric array"),
        (np.array([[1j, 0.0], [0.0, -1.0]]), InputError, "A must be a real numeric array"),
        (np.array([[np.nan, 0.0], [0.0, -1.0]]), NonFiniteError, "A contains NaN"),
        (np.array([[np.inf, 0.0], [0.0, -1.0]]), NonFiniteError, "A contains NaN or infinite"),
    ],
)
def test_bad_matrices_are_rejected(A, error, pattern):
    with pytest.raises(error, match=pattern):
        check_assumption4(A, form="continuous")


def test_form_is_required_and_checked():
    with pytest.raises(TypeError, match="form"):
        check_assumption4(-np.eye(2))
    for bad in ("Continuous", "ct", None, 1):
        with pytest.raises(InputError, match=r"form must be one of \('continuous', 'discrete'\)"):
            check_assumption4(-np.eye(2), form=bad)


def test_unknown_solver_is_rejected():
    with pytest.raises(InputError, match=r"solver must be one of \('CLARABEL', 'SCS'\), got 'MOSEK'"):
        check_assumption4(-np.eye(2), form="continuous", solver="MOSEK")
    with pytest.raises(InputError, match="solver must be one of"):
        check_assumption4(-np.eye(2), form="continuous", solver=None)


def test_bad_q0_d_and_margin_are_rejected():
    A = -np.eye(2)
    with pytest.raises(DimensionError, match=r"Q0 must have shape \(2, 2\), got shape \(3, 3\)"):
        check_assumption4(A, form="continuous", Q0=np.eye(3))
    with pytest.raises(InputError, match="Q0 must be symmetric"):
        check_assumption4(A, form="continuous", Q0=np.array([[1.0, 0.5], [0.0, 1.0]]))
    with pytest.raises(InputError, match="Q0 must be positive definite"):
        check_assumption4(A, form="continuous", Q0=np.diag([1.0, -1.0]))
    with pytest.raises(NonFiniteError, match="Q0 contains NaN"):
        check_assumption4(A, form="continuous", Q0=np.full((2, 2), np.nan))
    with pytest.raises(DimensionError, match=r"D must have shape \(2, \*\), got shape \(3, 1\)"):
        check_assumption4(A, form="discrete", D=np.ones((3, 1)))
    with pytest.raises(DimensionError, match=r"D must have shape \(2, r\) with r >= 1, got shape \(2, 0\)"):
        check_assumption4(A, form="discrete", D=np.ones((2, 0)))
    with pytest.raises(InputError, match="margin must be > 0"):
        check_assumption4(A, form="continuous", margin=0.0)
    with pytest.raises(NonFiniteError, match="margin must be finite"):
        check_assumption4(A, form="continuous", margin=np.nan)


def test_width_bound_rejects_bad_norms():
    result = check_assumption4(np.array([[0.5, 1.0], [0.0, 0.6]]), form="discrete")
    with pytest.raises(InputError, match="e0_norm must be >= 0"):
        result.width_bound(-1.0, 1.0)
    with pytest.raises(InputError, match="steps must be >= 0"):
        result.width_bound(1.0, 1.0, steps=[-1, 2])


def test_returned_certificate_is_the_one_with_smaller_constants():
    rng = np.random.default_rng(5)
    for _ in range(4):
        A = rng.uniform(0, 1, (3, 3))
        A *= 0.9 / np.abs(np.linalg.eigvals(A)).max()
        result = check_assumption4(A, form="discrete")
        assert_certificate(result, A, np.eye(3), "discrete")
        assert result.coordinates in ("caller", "preconditioned")
        T, T_inv = lmi._preconditioner(A[None], "discrete")
        log = lmi._Log()
        for candidate in (
            lmi._lyapunov_candidate("discrete", A[None], T, T_inv, "preconditioned"),
            lmi._primal_sdp("discrete", A[None], T, T_inv, "preconditioned", 1e-6, "CLARABEL", log),
            lmi._primal_sdp("discrete", A[None], np.eye(3), np.eye(3), "caller", 1e-6, "CLARABEL", log),
        ):
            P, Q0, rho = lmi._certify("discrete", A[None], np.eye(3), None, candidate)
            top = np.linalg.eigvalsh(lmi_matrix("discrete", A, np.eye(3), P, Q0, rho))[-1]
            other = dataclasses_replace(
                result, P=P, Q0=Q0, rho=rho, eigenvalues_P=np.linalg.eigvalsh(P), max_eigenvalue=top
            )
            assert_certificate(other, A, np.eye(3), "discrete")
            assert sum(result.bound_constants()) <= sum(other.bound_constants()) * (1 + 1e-9)


def test_concurrent_calls_share_the_cache_safely():
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(17)
    cases = [(near_boundary_matrix(rng, 3, "discrete", 0.03, i % 2 == 0, 30.0), i % 2 == 0) for i in range(8)]
    with ThreadPoolExecutor(max_workers=4) as pool:
        results = list(pool.map(lambda case: check_assumption4(case[0], form="discrete"), cases))
    for (A, stable), result in zip(cases, results):
        assert result.status == ("feasible" if stable else "infeasible")
        if stable:
            assert_certificate(result, A, np.eye(3), "discrete")


@given(st.integers(2, 4), st.integers(0, 2**32 - 1))
def test_continuous_bound_holds_along_exactly_integrated_trajectories(p, seed):
    # e' = A e + D w with w piecewise constant, integrated exactly
    # (matrix exponential of the augmented system) and sampled every h.
    rng = np.random.default_rng(seed)
    A = near_boundary_matrix(rng, p, "continuous", rng.uniform(0.05, 0.5), True, 10 ** rng.uniform(0, 1.5))
    D = rng.standard_normal((p, 2))
    result = check_assumption4(A, form="continuous", D=D)
    assert_certificate(result, A, D, "continuous")
    h = 0.1
    augmented = np.zeros((p + 2, p + 2))
    augmented[:p, :p], augmented[:p, p:] = A, D
    flow = sla.expm(h * augmented)
    Phi, Gamma = flow[:p, :p], flow[:p, p:]
    e = rng.standard_normal(p)
    e0_norm, w_norm = np.linalg.norm(e), 0.5
    P = np.asarray(result.P)
    for n in range(1, 200):
        # On the sphere ||w|| = W, along D^T P e: the direction that makes dV/dt largest.
        w = D.T @ P @ e if n % 4 else rng.standard_normal(2)
        e = Phi @ e + Gamma @ (w * w_norm / np.linalg.norm(w))
        assert np.linalg.norm(e) <= result.width_bound(e0_norm, w_norm, steps=n * h) * (1 + 1e-9)


@pytest.mark.parametrize("a", [0.1, 1.0, 7.0])
def test_continuous_bound_is_tight_for_a_scalar_system(a):
    # e' = -a e + w, |w| <= W: the worst steady state is W / a, reached by w = W. The
    # bound's cw is at least 1 / a (else this trajectory breaks it) and, with the tuned Q0,
    # at most RHO_FACTOR^(1/2) / a up to the scalar search's tolerance.
    result = check_assumption4(np.array([[-a]]), form="continuous")
    c0, cw = result.bound_constants()
    assert c0 == pytest.approx(1.0)
    assert 1.0 / a <= cw <= 1.01 / a
    t = np.linspace(0, 20 / a, 50)
    exact = (1 - np.exp(-a * t)) / a  # e(0) = 0, w = 1
    assert np.all(exact <= result.width_bound(0.0, 1.0, steps=t) * (1 + 1e-12))
