"""The shared validators of minimaxplan.models.validation: typed errors that name the argument."""

from __future__ import annotations

import numpy as np
import pytest

from minimaxplan.models import Box, DimensionError, InputError, NonFiniteError
from minimaxplan.models.validation import (
    as_choice,
    as_count,
    as_discount,
    as_finite_array,
    as_points,
    as_positive_scalar,
    as_probability,
    as_real_scalar,
    check_dimension,
    check_instance,
    check_same_shape,
    check_shape,
)


def test_counts_accept_integers_and_reject_bools_floats_and_strings():
    assert as_count("n", 3) == 3 and type(as_count("n", np.int64(3))) is int
    assert as_count("rounds", 0, minimum=0) == 0
    for bad in (True, False, 2.0, "3", None, 0, -1):
        with pytest.raises(InputError, match=rf"n must be a positive integer, got {bad!r}"):
            as_count("n", bad)
    with pytest.raises(InputError, match=r"rounds must be an integer >= 0, got -1"):
        as_count("rounds", -1, minimum=0)


def test_choices():
    assert as_choice("form", "discrete", ("continuous", "discrete")) == "discrete"
    assert as_choice("solver", "scs", ("CLARABEL", "SCS"), ignore_case=True) == "SCS"
    with pytest.raises(InputError, match=r"form must be one of \('continuous', 'discrete'\), got 'hybrid'"):
        as_choice("form", "hybrid", ("continuous", "discrete"))
    with pytest.raises(InputError, match=r"solver must be one of \('CLARABEL', 'SCS'\), got 3"):
        as_choice("solver", 3, ("CLARABEL", "SCS"), ignore_case=True)
    with pytest.raises(InputError, match=r"got \[1\]"):
        as_choice("form", [1], {"a", "b"})


def test_discounts_lie_strictly_between_0_and_1():
    assert as_discount("gamma", 0.9) == 0.9 and as_discount("gamma", np.float32(0.5)) == 0.5
    for bad in (0.0, 1.0, -0.5, 2):
        with pytest.raises(InputError, match=r"gamma must be in the open interval \(0, 1\)"):
            as_discount("gamma", bad)
    with pytest.raises(NonFiniteError, match=r"gamma must be finite and in \(0, 1\), got nan"):
        as_discount("gamma", float("nan"))
    for bad in ("x", "0.5", b"0.5", True, 0.5 + 0j, None, 10**400):
        with pytest.raises(InputError, match=r"gamma must be a real number in \(0, 1\)"):
            as_discount("gamma", bad)


def test_real_scalars_refuse_numeric_strings_and_huge_integers():
    """A numeric string is not a number, and 10**400 has no float: typed errors naming the argument."""
    for bad in ("0.5", b"2", True):
        with pytest.raises(InputError, match=r"sigma must be a real scalar"):
            as_positive_scalar("sigma", bad)
    with pytest.raises(NonFiniteError, match=r"sigma must be finite, got an integer too large for a float"):
        as_positive_scalar("sigma", 10**400)


def test_probabilities():
    assert as_probability("delta", 0.05) == 0.05
    with pytest.raises(InputError, match=r"delta must lie in \(0, 1\), got 1.0"):
        as_probability("delta", 1.0)
    with pytest.raises(InputError, match=r"delta must be > 0, got 0.0"):
        as_probability("delta", 0.0)
    with pytest.raises(NonFiniteError, match="delta must be finite"):
        as_probability("delta", float("inf"))


def test_shapes_and_dimensions_raise_dimension_errors_naming_both():
    with pytest.raises(DimensionError, match=r"A must have shape \(2, \*\), got shape \(3, 1\)"):
        check_shape("A", np.zeros((3, 1)), (2, None))
    with pytest.raises(DimensionError, match=r"low and high must have the same shape, got \(2,\) and \(3,\)"):
        check_same_shape("low", np.zeros(2), "high", np.zeros(3))
    with pytest.raises(DimensionError, match=r"x0 must have dimension 2 \(A0 has shape \(2, 2\)\), got 3"):
        check_dimension("x0", 3, 2, "A0 has shape (2, 2)")
    with pytest.raises(DimensionError, match=r"other must have dimension 2, got 1"):
        check_dimension("other", 1, 2)
    check_dimension("x0", 2, 2)
    assert as_points("x", [[1, 2], [3, 4]], 2).shape == (2, 2)
    with pytest.raises(DimensionError, match=r"x must have shape \(3,\) or \(N, 3\), got shape \(2, 2\)"):
        as_points("x", np.zeros((2, 2)), 3, batch="N")
    with pytest.raises(DimensionError, match=r"got shape \(1, 1, 3\)"):
        as_points("x", np.zeros((1, 1, 3)), 3)


def test_instances():
    check_instance("prior", Box([0.0], [1.0]), Box)
    check_instance("prior", None, (Box, type(None)), "a Box or None")
    with pytest.raises(InputError, match=r"prior must be a Box, got tuple"):
        check_instance("prior", (0, 1), Box)
    with pytest.raises(InputError, match=r"system must be an UncertainLinearSystem, got dict"):
        from minimaxplan.models import UncertainLinearSystem

        check_instance("system", {}, UncertainLinearSystem)


def test_finite_arrays_refuse_text_bools_and_integers_too_large_for_a_float():
    assert as_finite_array("x", [1, 2]).dtype == np.float64
    assert as_finite_array("x", np.array([1.5], dtype=object))[0] == 1.5
    for bad in (["0.5", "1"], np.array(["1"]), np.array(["1"], dtype=object), [1.0, "2"]):
        with pytest.raises(InputError, match=r"^x must be a real numeric array, got text$"):
            as_finite_array("x", bad)
    for bad in ([True, False], np.ones(2, dtype=bool), np.array([1.0, True], dtype=object)):
        with pytest.raises(InputError, match=r"^x must be a real numeric array, got booleans$"):
            as_finite_array("x", bad)
    with pytest.raises(NonFiniteError, match=r"^x contains an integer too large for a float$"):
        as_finite_array("x", [10**400])


def test_real_scalars_of_any_sign():
    assert as_real_scalar("speed", -2) == -2.0 and as_real_scalar("speed", np.float32(0.5)) == 0.5
    for bad in ("0.5", True, None, [1.0], 1j):
        with pytest.raises(InputError, match=r"^speed must be a real scalar, got "):
            as_real_scalar("speed", bad)
    with pytest.raises(NonFiniteError, match=r"^speed must be finite"):
        as_real_scalar("speed", float("-inf"))
