"""Where Assumption 4 holds: conflicting vertices and region maps, checked against the
Shorten-Narendra test on ``A(k) = [[0, 1], [-k, -c]]``, c = 0.2, k in [1, 4] (continuous time).

For two Hurwitz 2x2 matrices a common quadratic Lyapunov function exists iff
``A1 A2`` and ``A1 A2^-1`` have no negative real eigenvalue (Shorten-Narendra); for this
family that is ``(k2 - k1)^2 < 2 c^2 (k1 + k2) - c^4`` over [k1, k2].
"""

from __future__ import annotations

import numpy as np
import pytest

from minimaxplan.models import Box, InputError, UncertainLinearSystem
from minimaxplan.verify import LMIStatus, certified_region, check_assumption4, conflicting_vertices

C = 0.2
BOX = Box([1.0], [4.0])


def matrix(k: float) -> np.ndarray:
    return np.array([[0.0, 1.0], [-k, -C]])


def matrices(theta: np.ndarray) -> np.ndarray:
    return np.array([matrix(k) for k in theta[:, 0]])


def shorten_narendra(k1: float, k2: float) -> bool:
    return (k2 - k1) ** 2 < 2 * C**2 * (k1 + k2) - C**4


def no_negative_real_eigenvalue(M: np.ndarray) -> bool:
    ev = np.linalg.eigvals(M)
    return not np.any((np.abs(ev.imag) <= 1e-12 * np.abs(ev)) & (ev.real < 0))


def shorten_narendra_by_eigenvalues(k1: float, k2: float) -> bool:
    A1, A2 = matrix(k1), matrix(k2)
    return no_negative_real_eigenvalue(A1 @ A2) and no_negative_real_eigenvalue(A1 @ np.linalg.inv(A2))


@pytest.fixture(scope="module")
def region_map():
    return certified_region(matrices, BOX, form="continuous", max_depth=3)


@pytest.mark.parametrize("k1, k2", [(1, 4), (1, 1.375), (1, 1.75), (3.25, 4), (2.5, 3.25), (1, 1.4)])
def test_the_closed_form_agrees_with_the_eigenvalue_test(k1, k2):
    assert shorten_narendra(k1, k2) == shorten_narendra_by_eigenvalues(k1, k2)


def test_the_whole_box_is_not_certified_and_its_conflict_is_the_two_endpoints(region_map):
    assert not shorten_narendra(1.0, 4.0)
    assert not region_map.holds and len(region_map.pieces) > 1
    conflict = region_map.conflict
    assert conflict is not None
    assert conflict.indices == (0, 1)
    np.testing.assert_array_equal(conflict.matrices, matrices(BOX.vertices()))
    assert conflict.infeasible.status is LMIStatus.INFEASIBLE and conflict.infeasible.dual is not None
    # dropping either endpoint leaves one Hurwitz matrix: a certificate, re-checked exactly
    assert conflict.irreducible and all(result.holds for result in conflict.drop_one)
    assert conflict.to_dict()["indices"] == [0, 1]


def test_every_certified_piece_satisfies_shorten_narendra(region_map):
    assert region_map.certified_pieces
    for piece in region_map.certified_pieces:
        assert shorten_narendra(piece.box.low[0], piece.box.high[0]), piece.box
        assert piece.condition_P is not None and piece.condition_P >= 1


def test_the_map_agrees_with_shorten_narendra_on_its_partition(region_map):
    pieces = region_map.pieces
    # the leaves tile [1, 4] in order
    assert pieces[0].box.low[0] == 1.0 and pieces[-1].box.high[0] == 4.0
    assert all(a.box.high[0] == b.box.low[0] for a, b in zip(pieces, pieces[1:]))
    assert sum(piece.fraction for piece in pieces) == pytest.approx(1.0)
    for piece in pieces:
        low, high = piece.box.low[0], piece.box.high[0]
        assert piece.certified == shorten_narendra(low, high), (low, high, piece.status)
        if high - low < 0.4:
            assert piece.certified
    sn_measure = sum(p.box.high[0] - p.box.low[0] for p in pieces if shorten_narendra(p.box.low[0], p.box.high[0]))
    assert region_map.certified_fraction == pytest.approx(sn_measure / 3.0)
    # at depth 3 every piece is narrower than 0.4, or certified already at depth 2
    assert region_map.certified_fraction == pytest.approx(1.0)
    document = region_map.to_dict()
    assert document["certified_fraction"] == pytest.approx(1.0) and len(document["pieces"]) == len(pieces)


def test_a_volume_tolerance_stops_the_split_and_leaves_uncovered_pieces():
    coarse = certified_region(matrices, BOX, form="continuous", max_depth=5, min_volume=0.25)
    widths = [p.box.high[0] - p.box.low[0] for p in coarse.pieces]
    assert widths == [0.75] * 4
    assert [p.certified for p in coarse.pieces] == [
        shorten_narendra(p.box.low[0], p.box.high[0]) for p in coarse.pieces
    ]
    assert [p.certified for p in coarse.pieces] == [False, False, False, True]
    assert coarse.certified_fraction == pytest.approx(0.25)
    assert coarse.infeasible_fraction + coarse.inconclusive_fraction == pytest.approx(0.75)
    assert all(p.status is LMIStatus.INFEASIBLE for p in coarse.uncovered_pieces)


def test_a_system_gives_its_own_box_and_a_certified_box_is_one_piece():
    phi = np.array([[[0.0, 0.0], [-1.0, 0.0]]])
    system = UncertainLinearSystem(
        A0=matrix(0.0), phi=phi, B=np.zeros((2, 1)), w=Box([-1.0, -1.0], [1.0, 1.0]), theta=Box([3.5], [3.8])
    )
    one = certified_region(system, form="continuous", max_depth=3)
    assert one.holds and one.certified_fraction == 1.0 and one.conflict is None
    assert one.pieces[0].box.low[0] == 3.5 and one.pieces[0].depth == 0


def test_conflicting_vertices_drops_the_matrices_that_do_not_conflict():
    # the endpoints conflict; -I shares every P (its L(P) = -2 P), so the filter drops it
    sequence = [-np.eye(2), matrix(1.0), matrix(4.0)]
    conflict = conflicting_vertices(sequence, form="continuous")
    assert conflict.indices == (1, 2) and conflict.irreducible
    assert check_assumption4(list(conflict.matrices), form="continuous").status is LMIStatus.INFEASIBLE


def test_an_unstable_matrix_is_a_conflict_by_itself():
    conflict = conflicting_vertices([matrix(1.0), np.array([[0.1, 0.0], [0.0, -1.0]])], form="continuous")
    assert conflict.indices == (1,) and conflict.irreducible


def test_a_set_with_a_common_certificate_has_no_conflict():
    with pytest.raises(InputError, match="no conflict"):
        conflicting_vertices([matrix(1.0), matrix(1.2)], form="continuous")


@pytest.mark.parametrize(
    "kwargs, message",
    [({"max_depth": -1}, "max_depth"), ({"min_volume": 2.0}, "min_volume"), ({"form": "hybrid"}, "form")],
)
def test_bad_options_are_rejected(kwargs, message):
    options = {"form": "continuous", **kwargs}
    with pytest.raises(InputError, match=message):
        certified_region(matrices, BOX, **options)


def test_a_matrix_function_needs_a_box():
    with pytest.raises(InputError, match="box"):
        certified_region(matrices, form="continuous")
