"""LMI verdicts proven both ways (issue 10, item 2).

"feasible" only with a certificate that is exactly valid (checked here again, in
`fractions.Fraction` arithmetic independent of the library's), "infeasible" only with a
re-checked dual certificate, the same verdicts whatever Q0 is given and whatever basis
the matrix is written in. Every test here fails on the code before the fix.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.verify import LMIResult, check_assumption4

DELTAS = np.geomspace(1e-3, 1e-1, 4)
COUPLINGS = np.geomspace(0.1, 10.0, 4)


# ----------------------------------------------------------------- independent checks


def fractions(M) -> list[list[Fraction]]:
    return [[Fraction(float(x)) for x in row] for row in np.atleast_2d(np.asarray(M, dtype=float))]


def matmul(X, Y):
    return [
        [sum((X[i][k] * Y[k][j] for k in range(len(Y))), Fraction(0)) for j in range(len(Y[0]))] for i in range(len(X))
    ]


def transpose(X):
    return [list(row) for row in zip(*X)]


def combine(X, Y, sign=1):
    return [[x + sign * y for x, y in zip(rx, ry)] for rx, ry in zip(X, Y)]


def positive_definite(M) -> bool:
    """Gaussian elimination without pivoting on a symmetric rational matrix: all pivots > 0."""
    a = [list(row) for row in M]
    n = len(a)
    for k in range(n):
        if a[k][k] <= 0:
            return False
        for i in range(k + 1, n):
            f = a[i][k] / a[k][k]
            for j in range(k, n):
                a[i][j] -= f * a[k][j]
    return True


def exact_lmi(form, A, D, P, Q0, rho):
    """The LMI of Assumption 4 at (P, Q0, rho), in exact rational arithmetic."""
    A, D, P, Q0 = fractions(A), fractions(D), fractions(P), fractions(Q0)
    r = len(D[0])
    rho_i = [[Fraction(float(rho)) * (i == j) for j in range(r)] for i in range(r)]
    At, Dt = transpose(A), transpose(D)
    if form == "continuous":
        top = combine(combine(matmul(At, P), matmul(P, A)), Q0)
        coupling = matmul(P, D)
        corner = [[-x for x in row] for row in rho_i]
    else:
        top = combine(combine(matmul(matmul(At, P), A), P, -1), Q0)
        coupling = matmul(matmul(At, P), D)
        corner = combine(matmul(matmul(Dt, P), D), rho_i, -1)
    return [t + c for t, c in zip(top, coupling)] + [c + k for c, k in zip(transpose(coupling), corner)]


def assert_exact_certificate(result: LMIResult, A, form, D=None):
    """P > 0, Q0 > 0 and the full LMI < 0, proven here in Fractions."""
    assert result.status == "feasible" and result.certified and result.holds, result.reason
    A = np.asarray(A)
    D = np.eye(A.shape[-1]) if D is None else D
    assert positive_definite(fractions(result.P)) and positive_definite(fractions(result.Q0))
    for vertex in A.reshape(-1, A.shape[-1], A.shape[-1]):
        M = exact_lmi(form, vertex, D, result.P, result.Q0, result.rho)
        assert positive_definite([[-x for x in row] for row in M])


def assert_dual(result: LMIResult, A, form, margin=1e-6):
    """The dual certificate, re-checked in Fractions: W = T Y T^T + sum L*(T Z T^T) > 0, tr Y < m tr Z."""
    assert result.status == "infeasible" and result.P is None and not result.certified
    dual = result.dual
    assert dual is not None and dual.margin == result.margin and 0 <= dual.margin < margin
    assert "no certificate with normalised margin above" in result.reason
    assert "no certificate exists" not in result.reason
    A = np.asarray(A)
    T = fractions(dual.T)
    Tt = transpose(T)
    W = matmul(matmul(T, fractions(dual.Y)), Tt)
    for vertex, Z in zip(A.reshape(-1, A.shape[-1], A.shape[-1]), dual.Z):
        Av, X = fractions(vertex), matmul(matmul(T, fractions(Z)), Tt)
        if form == "continuous":
            W = combine(W, combine(matmul(Av, X), matmul(X, transpose(Av))))
        else:
            W = combine(W, combine(matmul(matmul(Av, X), transpose(Av)), X, -1))
    W = [[(W[i][j] + W[j][i]) / 2 for j in range(len(W))] for i in range(len(W))]
    assert positive_definite(W)
    trace_y = sum(np.diag(dual.Y))
    trace_z = sum(np.trace(Z) for Z in dual.Z)
    assert trace_y <= dual.margin * trace_z * (1 + 1e-12)
    for S in (dual.Y, *dual.Z):
        assert np.linalg.eigvalsh(S)[0] >= -1e-12 * max(1.0, np.abs(S).max())


def jordan(form, delta, c, stable):
    a = (1 - delta if stable else 1 + delta) if form == "discrete" else (-delta if stable else delta)
    return np.array([[a, c], [0.0, a]])


# ----------------------------------------------------------------- the cases


@pytest.mark.parametrize("q0", [None, "identity"])
@pytest.mark.parametrize("form", ["discrete", "continuous"])
def test_clear_cut_verdicts(form, q0):
    """[[a, c], [0, a]], a = 1 -+ delta or -+delta, delta in [1e-3, 1e-1], c in [0.1, 10]."""
    Q0 = None if q0 is None else np.eye(2)
    for delta in DELTAS:
        for c in COUPLINGS:
            stable = jordan(form, delta, c, True)
            result = check_assumption4(stable, form=form, Q0=Q0)
            assert_exact_certificate(result, stable, form)
            if Q0 is not None:
                np.testing.assert_array_equal(result.Q0, Q0)
            unstable = jordan(form, delta, c, False)
            assert_dual(check_assumption4(unstable, form=form, Q0=Q0), unstable, form)


@pytest.mark.parametrize(
    ("form", "A"),
    [
        ("discrete", [[0.999, 1.0], [0.0, 0.999]]),
        ("continuous", [[-0.001, 1.0], [0.0, -0.001]]),
        ("continuous", [[-0.001, 100.0], [0.0, -0.001]]),
    ],
)
def test_exactly_valid_certificates_are_not_thrown_away(form, A):
    # Before: "inconclusive: numpy re-check failed" (free Q0) and "infeasible ... no
    # certificate exists" (Q0 = I), both false.
    A = np.array(A)
    for Q0 in (None, np.eye(2)):
        assert_exact_certificate(check_assumption4(A, form=form, Q0=Q0), A, form)


def test_an_exact_integrator_is_infeasible_with_a_dual_certificate():
    # The robot's full model: eigenvalue exactly 1. No strict dual of the homogeneous
    # problem exists (the velocity block alone has a certificate); the normalised one does.
    A = np.array([[1.0, 0.1], [0.0, 0.9]])
    result = check_assumption4(A, form="discrete", D=np.array([[0.0], [0.1]]))
    assert_dual(result, A, "discrete")


# ----------------------------------------------------------------- invariances


@pytest.mark.parametrize("form", ["discrete", "continuous"])
def test_a_given_q0_does_not_change_the_verdict(form):
    rng = np.random.default_rng(2)
    G = rng.standard_normal((2, 2))
    spd = G @ G.T + 1e-4 * np.eye(2)
    for delta, c in [(1e-3, 10.0), (1e-2, 1.0), (1e-1, 0.1)]:
        for stable in (True, False):
            A = jordan(form, delta, c, stable)
            free = check_assumption4(A, form=form)
            for Q0 in (1e-6 * np.eye(2), np.eye(2), 1e6 * np.eye(2), spd):
                given_q0 = check_assumption4(A, form=form, Q0=Q0)
                assert given_q0.status == free.status == ("feasible" if stable else "infeasible")
                if stable:
                    assert_exact_certificate(given_q0, A, form)
                    np.testing.assert_array_equal(given_q0.Q0, Q0)
                else:
                    assert_dual(given_q0, A, form)


@pytest.mark.parametrize("form", ["discrete", "continuous"])
def test_the_verdict_does_not_depend_on_the_basis(form):
    # Before: [[0.99, 1], [0, 0.99]] feasible, the same map in z = diag(1, 1e4)^-1 x infeasible.
    rng = np.random.default_rng(4)
    Q, _ = np.linalg.qr(rng.standard_normal((2, 2)))
    bases = [np.diag([1.0, 1e4]), np.diag([1e-3, 1.0]), Q @ np.diag([1.0, 1e2]) @ Q.T]
    for delta, c in [(1e-2, 1.0), (1e-3, 10.0), (5e-2, 3.0)]:
        for stable in (True, False):
            A = jordan(form, delta, c, stable)
            for S in bases:
                B = np.linalg.solve(S, A @ S)
                result = check_assumption4(B, form=form)
                if stable:
                    assert_exact_certificate(result, B, form)
                else:
                    assert_dual(result, B, form)


def _six_bases():
    rng = np.random.default_rng(4)
    Q, _ = np.linalg.qr(rng.standard_normal((2, 2)))
    return [
        np.eye(2),
        np.diag([1.0, 1e4]),
        np.diag([1e-3, 1.0]),
        np.diag([3.7, 1e-2]),
        Q @ np.diag([1.0, 1e2]) @ Q.T,
        Q,
    ]


@pytest.mark.parametrize("form, agreement", [("discrete", 2.2e-2), ("continuous", 0.47)])
def test_the_normalisation_is_used_in_every_basis_and_agrees_as_documented(form, agreement):
    """The preconditioner's Lyapunov solution is positive definite in every basis (no
    fall-back to the balancing alone), and the normalised matrices agree across bases
    within the figures that `check_assumption4`'s Notes and the README state.

    Before: scipy's Kronecker solve of the discrete equation returned an indefinite
    matrix for the rotated Jordan block (delta 1e-3, c 10), the normalisation fell back
    to the balancing, and that basis's verdict was "infeasible at margin 5e-7" on one
    CPU and "feasible" on another.
    """
    from minimaxplan.verify.lmi import _preconditioner

    for delta, c in [(1e-2, 1.0), (1e-3, 10.0), (5e-2, 3.0)]:
        A = jordan(form, delta, c, True)
        singular_values = []
        for S in _six_bases():
            B = np.linalg.solve(S, A @ S)
            T, T_inv = _preconditioner(B[None], form)
            assert not np.allclose(T, np.diag(np.diag(T)), rtol=0, atol=0), (delta, c, S)
            np.testing.assert_allclose(T @ T_inv, np.eye(2), atol=1e-9)
            singular_values.append(np.linalg.svd(T_inv @ B @ T, compute_uv=False))
        ratios = np.array(singular_values) / singular_values[0]
        assert np.abs(ratios - 1).max() <= agreement, (delta, c, ratios)


# ----------------------------------------------------------------- never an unproven verdict


@st.composite
def random_cases(draw):
    p = draw(st.integers(2, 4))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    form = draw(st.sampled_from(["continuous", "discrete"]))
    A = rng.standard_normal((p, p)) * 10.0 ** draw(st.floats(-1.0, 1.0))
    # move the spectrum to a distance in [1e-3, 1e-1] on either side of the boundary
    eigenvalues = np.linalg.eigvals(A)
    distance = 10.0 ** draw(st.floats(-3.0, -1.0)) * draw(st.sampled_from([-1.0, 1.0]))
    if form == "continuous":
        A = A - (eigenvalues.real.max() - distance) * np.eye(p)
    else:
        A = A * (1.0 + distance) / np.abs(eigenvalues).max()
    Q0 = None if draw(st.booleans()) else np.diag(10.0 ** rng.uniform(-3, 3, p))
    return form, A, Q0, distance < 0


@given(random_cases())
def test_no_verdict_without_its_proof(case):
    form, A, Q0, stable = case
    result = check_assumption4(A, form=form, Q0=Q0)
    if result.status == "feasible":
        assert_exact_certificate(result, A, form)
    elif result.status == "infeasible":
        assert_dual(result, A, form)
    else:
        assert result.P is None and result.dual is None and result.reason
    # and the proofs agree with the truth (neither is ever wrong)
    assert result.status != ("infeasible" if stable else "feasible")


# ----------------------------------------------------------------- invariance, as a property


@st.composite
def invariance_cases(draw):
    form, A, _, stable = draw(random_cases())
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    p = A.shape[0]
    S = np.diag(10.0 ** rng.uniform(-2.0, 2.0, p))  # a change of units of the state
    G = rng.standard_normal((p, p))
    Q0 = G @ G.T + 10.0 ** rng.uniform(-3.0, 0.0) * np.eye(p)  # any Q0 > 0
    return form, A, stable, S, Q0


@settings(max_examples=25)
@given(invariance_cases())
def test_a_conclusive_verdict_is_the_same_in_other_units_and_with_any_given_q0(case):
    """DESIGN: verdicts do not depend on the coordinates, and a given Q0 > 0 gives the same
    verdict as a free one (each verdict on its own re-checked proof)."""
    form, A, stable, S, Q0 = case
    free = check_assumption4(A, form=form)
    if free.status == "inconclusive":
        return
    assert free.status == ("feasible" if stable else "infeasible")
    scaled_A = np.linalg.solve(S, A @ S)
    for result, matrix in (
        (check_assumption4(scaled_A, form=form), scaled_A),
        (check_assumption4(A, form=form, Q0=Q0), A),
    ):
        assert result.status == free.status, result.reason
        if stable:
            assert_exact_certificate(result, matrix, form)
        else:
            assert_dual(result, matrix, form)
