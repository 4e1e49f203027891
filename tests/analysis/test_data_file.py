"""Data files (CSV/NPZ): the example and its generator, parsing and every malformed input."""

from __future__ import annotations

import pathlib
import runpy

import numpy as np
import pytest

from minimaxplan.analysis.data_file import DataFileError, load_data_file

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"


def test_example_data_is_reproduced_by_its_generator():
    generator = runpy.run_path(str(EXAMPLES / "make_robot_data.py"))
    states, controls = generator["make_robot_data"]()
    data = load_data_file(EXAMPLES / "robot_data.csv")
    np.testing.assert_allclose(data.states, states, rtol=0, atol=1e-12)
    np.testing.assert_allclose(data.controls, controls, rtol=0, atol=1e-12)


def test_generator_csv_round_trips(tmp_path):
    generator = runpy.run_path(str(EXAMPLES / "make_robot_data.py"))
    states, controls = generator["make_robot_data"](steps=7, seed=3)
    generator["write_csv"](tmp_path / "d.csv", states, controls)
    data = load_data_file(tmp_path / "d.csv")
    np.testing.assert_array_equal(data.states, states)
    np.testing.assert_array_equal(data.controls, controls)


# ------------------------------------------------------------------ data files
def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_csv_columns_in_any_order_and_last_controls_optional(tmp_path):
    path = _write(tmp_path, "d.csv", "u0,x1,x0\n1.5,2,1\n-1,4,3\n,6,5\n")
    data = load_data_file(path)
    np.testing.assert_array_equal(data.states, [[1, 2], [3, 4], [5, 6]])
    np.testing.assert_array_equal(data.controls, [[1.5], [-1]])
    # the last row's controls may be given (they are unused) or left out entirely
    assert np.array_equal(load_data_file(_write(tmp_path, "e.csv", "x0,u0\n1,2\n3,9\n")).controls, [[2]])
    assert np.array_equal(load_data_file(_write(tmp_path, "f.csv", "x0,x1,u0\n1,2,3\n4,5\n")).states, [[1, 2], [4, 5]])


def test_npz_round_trip_and_extra_arrays_ignored(tmp_path):
    rng = np.random.default_rng(0)
    states, controls = rng.normal(size=(6, 3)), rng.normal(size=(5, 2))
    np.savez(tmp_path / "d.npz", states=states, controls=controls, theta_true=np.ones(2))
    data = load_data_file(tmp_path / "d.npz")
    np.testing.assert_array_equal(data.states, states)
    np.testing.assert_array_equal(data.controls, controls)
    assert data.ntransitions == 5 and not data.states.flags.writeable


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x0,v0\n1,2\n3,4\n", r"unknown column 'v0'"),
        ("x0,x2,u0\n1,2,3\n4,5,6\n", r"x columns must be numbered 0\.\.1, got \[0, 2\]"),
        ("x0,x0,u0\n1,2,3\n4,5,6\n", r"column 'x0' appears twice"),
        ("x0,x1\n1,2\n3,4\n", r"no u columns"),
        ("x0,u0\n1,2\n", r"need at least 2 data rows \(one transition\), got 1"),
        ("x0,u0\n1,nan\n3,\n", r"line 2, column 'u0' is not finite: 'nan'"),
        ("x0,u0\n1,2\ninf,\n", r"line 3, column 'x0' is not finite: 'inf'"),
        ("x0,u0\n1,\n3,\n", r"line 2, column 'u0' is empty"),
        ("x0,u0\n1,abc\n3,\n", r"line 2, column 'u0' is not a number: 'abc'"),
        ("x0,u0\n1,2,3\n3,\n", r"line 2 has 3 cells, the header has 2"),
        ("x0,u0\n1,2\n3,oops\n", r"line 3, column 'u0' is not a number"),
        ("", r"empty file"),
    ],
)
def test_malformed_csv_is_rejected_naming_the_cell(tmp_path, text, message):
    with pytest.raises(DataFileError, match=message):
        load_data_file(_write(tmp_path, "d.csv", text))


@pytest.mark.parametrize(
    ("arrays", "message"),
    [
        ({"states": np.zeros((3, 2))}, r"missing array\(s\) \['controls'\]"),
        (
            {"states": np.zeros((3, 2)), "controls": np.zeros((3, 1))},
            r"one row more than controls.*states shape \(3, 2\) and controls shape \(3, 1\)",
        ),
        (
            {"states": np.zeros(3), "controls": np.zeros((2, 1))},
            r"states must be a non-empty 2-dimensional array, got shape \(3,\)",
        ),
        (
            {"states": np.array([[0.0], [np.nan]]), "controls": np.zeros((1, 1))},
            r"states contains NaN or infinite entries \(first at index \[1, 0\]\)",
        ),
        (
            {"states": np.zeros((2, 1)), "controls": np.array([["a"]])},
            r"controls must be a real numeric array, got dtype <U1",
        ),
        ({"states": np.zeros((2, 1)), "controls": np.array([[None]], dtype=object)}, r"cannot read data file .*pickle"),
    ],
)
def test_malformed_npz_is_rejected_naming_the_array(tmp_path, arrays, message):
    np.savez(tmp_path / "d.npz", **arrays)
    with pytest.raises(DataFileError, match=message):
        load_data_file(tmp_path / "d.npz")


def test_data_file_error_is_an_input_error():
    from minimaxplan.models import InputError

    assert issubclass(DataFileError, InputError) and issubclass(DataFileError, ValueError)


def test_data_file_extension_and_existence(tmp_path):
    with pytest.raises(DataFileError, match=r"must end in \.csv or \.npz, got '\.txt'"):
        load_data_file(_write(tmp_path, "d.txt", "x0,u0\n"))
    with pytest.raises(DataFileError, match=r"must end in \.csv or \.npz, got 'no extension'"):
        load_data_file(tmp_path / "data")
    with pytest.raises(DataFileError, match=r"data file '.*absent\.npz' does not exist"):
        load_data_file(tmp_path / "absent.npz")
    (tmp_path / "bad.npz").write_bytes(b"not a zip file")
    with pytest.raises(DataFileError, match=r"cannot read data file"):
        load_data_file(tmp_path / "bad.npz")
