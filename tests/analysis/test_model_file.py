"""Model files (TOML): parsing, round trips and every malformed input."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.analysis.model_file import (
    ModelFileError,
    ModelHypothesis,
    format_model_file,
    load_model_file,
    parse_model_file,
)
from minimaxplan.models import Box, InputError, UncertainLinearSystem
from minimaxplan.models.sets import hypercube_signs

ROOT = pathlib.Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"

ROBOT_A = np.array([[0.0, 0, 1, 0], [0, 0, 0, 1], [0, 0, 0, 0], [0, 0, 0, 0]])
ROBOT_B = np.vstack([np.zeros((2, 2)), np.eye(2)])

MINIMAL = """
name = "scalar"
A0 = [[0.5]]
phi = [[[1.0]]]
B = [[1.0]]
w = { low = [-0.1], high = [0.1] }
theta = { low = [-0.2], high = [0.2] }
"""


def _replace(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new)


# ------------------------------------------------------------------ examples
def test_robot_hypotheses_example_matches_a_direct_construction():
    model_file = load_model_file(EXAMPLES / "robot_hypotheses.toml")
    assert model_file.names == ["isotropic friction", "anisotropic friction", "coupled friction", "wrong input gain"]
    assert model_file.measurement_noise is None
    phi = np.zeros((2, 4, 4))
    phi[0, 2, 2] = phi[1, 3, 3] = -1.0
    expected = UncertainLinearSystem.from_continuous(
        ROBOT_A, phi, ROBOT_B, D=ROBOT_B, w=Box([-0.1, -0.1], [0.1, 0.1]), theta=Box([0.2, 0.2], [1.5, 1.5]), dt=0.1
    )
    anisotropic = model_file.select("anisotropic friction").hypotheses[0]
    assert anisotropic.time == "continuous" and anisotropic.dt == 0.1
    for key in ("A0", "phi", "B", "D"):
        np.testing.assert_array_equal(getattr(anisotropic.system, key), getattr(expected, key))
    assert anisotropic.system.w == expected.w and anisotropic.system.theta == expected.theta
    np.testing.assert_array_equal(anisotropic.continuous_system.A0, ROBOT_A)
    wrong_gain = model_file.select("wrong input gain").systems[0]
    np.testing.assert_array_equal(wrong_gain.B, 0.5 * expected.B)
    assert [s.nparams for s in model_file.systems] == [1, 2, 3, 2]


def test_robot_model_example_is_one_continuous_model():
    model_file = load_model_file(EXAMPLES / "robot_model.toml")
    assert model_file.names == ["robot under PD control"]
    (model,) = model_file.hypotheses
    np.testing.assert_array_equal(model.system.A0, np.eye(4) + 0.1 * model.continuous_system.A0)


def test_select_names_an_unknown_model():
    model_file = load_model_file(EXAMPLES / "robot_hypotheses.toml")
    with pytest.raises(ModelFileError, match=r"no model named 'nope'.*isotropic friction"):
        model_file.select("nope")


# ---------------------------------------------------------------- round trips
finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
# Any text, including quotes, backslashes, control and non-ASCII characters (no surrogates).
names = st.text(st.characters(blacklist_categories=("Cs",)), min_size=1, max_size=12).filter(lambda t: t.strip())


@st.composite
def hypotheses(draw):
    p = draw(st.integers(1, 3))
    q = draw(st.integers(1, 2))
    r = draw(st.integers(1, 3))
    d = draw(st.integers(1, 3))
    count = draw(st.integers(1, 3))

    def arr(*shape):
        return np.array(draw(st.lists(finite, min_size=int(np.prod(shape)), max_size=int(np.prod(shape))))).reshape(
            shape
        )

    out = []
    for index in range(count):
        low_w, low_t = arr(r), arr(d)
        w = Box(low_w, low_w + np.abs(arr(r)))
        theta = Box(low_t, low_t + np.abs(arr(d)))
        A, phi, B, D = arr(p, p), arr(d, p, p), arr(p, q), arr(p, r)
        if draw(st.booleans()):
            dt = draw(st.floats(1e-4, 10.0))
            system = UncertainLinearSystem.from_continuous(A, phi, B, D=D, w=w, theta=theta, dt=dt)
            cont = UncertainLinearSystem(A, phi, B, D=D, w=w, theta=theta)
            out.append(ModelHypothesis(f"{draw(names)} {index}", system, "continuous", dt, cont))
        else:
            dt = draw(st.none() | st.floats(1e-4, 10.0))
            system = UncertainLinearSystem(A, phi, B, D=D, w=w, theta=theta)
            out.append(ModelHypothesis(f"{draw(names)} {index}", system, "discrete", dt))
    noise = draw(st.none() | st.lists(st.floats(0, 1e3), min_size=p, max_size=p))
    return out, noise


@settings(max_examples=40)
@given(hypotheses())
def test_format_then_parse_round_trips_exactly(case):
    models, noise = case
    parsed = parse_model_file(format_model_file(models, measurement_noise=noise, header="a\nheader"))
    assert parsed.names == [m.name for m in models]
    if noise is None:
        assert parsed.measurement_noise is None
    else:
        np.testing.assert_array_equal(parsed.measurement_noise, noise)
    for original, back in zip(models, parsed.hypotheses):
        assert (back.time, back.dt) == (original.time, original.dt)
        pairs = [(original.system, back.system)]
        if original.time == "continuous":
            pairs.append((original.continuous_system, back.continuous_system))
        for a, b in pairs:
            for key in ("A0", "phi", "B", "D"):
                np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
            assert a.w == b.w and a.theta == b.theta


@settings(max_examples=30)
@given(hypotheses(), st.data())
def test_vertex_matrices_hold_every_model_matrix_in_their_convex_hull(case, data):
    """A(theta) is affine in theta, so it is the multilinear interpolation of the vertex matrices."""
    model = case[0][0]
    A_vertices, D = model.state_matrices("discrete", vertices=True)
    system = model.system
    assert A_vertices.shape == (2**system.nparams, system.nstates, system.nstates)
    np.testing.assert_array_equal(D, system.D)
    fractions = np.array(data.draw(st.lists(st.floats(0, 1), min_size=system.nparams, max_size=system.nparams)))
    theta = system.theta.low + fractions * (system.theta.high - system.theta.low)
    signs = hypercube_signs(system.nparams)
    weights = np.prod(np.where(signs > 0, fractions, 1 - fractions), axis=1)
    combination = np.tensordot(weights, A_vertices, axes=1)
    scale = 1 + np.abs(A_vertices).max()
    np.testing.assert_allclose(combination, system.A(theta), rtol=0, atol=1e-9 * scale)
    nominal, _ = model.state_matrices("discrete", vertices=False)
    np.testing.assert_allclose(nominal[0], system.A(system.theta.center), rtol=0, atol=1e-12 * scale)
    if model.time == "continuous":
        cont, D_cont = model.state_matrices("continuous", vertices=True)
        np.testing.assert_allclose(cont, model.continuous_system.A(system.theta.vertices()), rtol=0, atol=0)
        np.testing.assert_array_equal(D_cont, model.continuous_system.D)
    else:
        with pytest.raises(ModelFileError, match=r"is discrete-time.*continuous form"):
            model.state_matrices("continuous", vertices=False)


def test_measurement_noise_scalar_is_broadcast():
    parsed = parse_model_file("measurement_noise = 0.05\n" + MINIMAL)
    np.testing.assert_array_equal(parsed.measurement_noise, [0.05])


def test_defaults_are_inherited_and_overridden():
    text = (
        MINIMAL.replace('name = "scalar"', "")
        + '[[hypothesis]]\nname = "a"\n[[hypothesis]]\nname = "b"\nA0 = [[0.25]]\n'
    )
    parsed = parse_model_file(text)
    assert parsed.names == ["a", "b"]
    assert parsed.systems[0].A0[0, 0] == 0.5 and parsed.systems[1].A0[0, 0] == 0.25


def test_single_model_default_name_is_the_file_stem(tmp_path):
    path = tmp_path / "my_plant.toml"
    path.write_text(MINIMAL.replace('name = "scalar"', ""))
    assert load_model_file(path).names == ["my_plant"]


# ------------------------------------------------------------ malformed models
@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("phi = [[[1.0]]]", "", r"top level \('scalar'\): missing required key 'phi'"),
        ("A0 = [[0.5]]", "", r"missing required key 'A0'"),
        ("theta = { low = [-0.2], high = [0.2] }", "", r"missing required key 'theta'"),
        ("phi = [[[1.0]]]", "phy = [[[1.0]]]\nphi = [[[1.0]]]", r"unknown key\(s\) \['phy'\]"),
        ("B = [[1.0]]", "B = [[1.0], [2.0]]", r"B must have shape \(1, q\) to match A0 \(1, 1\), got shape \(2, 1\)"),
        ("B = [[1.0]]", "B = [1.0]", r"B must be a non-empty 2-dimensional array, got shape \(1,\)"),
        ("A0 = [[0.5]]", "A0 = [[0.5, 1.0]]", r"A0 must be square, got shape \(1, 2\)"),
        ("phi = [[[1.0]]]", "phi = [[1.0]]", r"phi must be a non-empty 3-dimensional array \(a list of d matrices"),
        (
            "phi = [[[1.0]]]",
            "phi = [[[1.0, 0.0], [0.0, 1.0]]]",
            r"phi must have shape \(d, 1, 1\).*got shape \(1, 2, 2\)",
        ),
        ("A0 = [[0.5]]", "A0 = [[nan]]", r"A0 contains NaN or infinite entries"),
        ("A0 = [[0.5]]", "A0 = [[-inf]]", r"A0 contains NaN or infinite entries"),
        ("low = [-0.2]", "low = [-inf]", r"theta\.low contains NaN or infinite entries"),
        ("high = [0.1]", "high = [nan]", r"w\.high contains NaN or infinite entries"),
        ("A0 = [[0.5]]", 'A0 = [["0.5"]]', r"A0 must hold only numbers, found '0.5'"),
        ("A0 = [[0.5]]", "A0 = [[true]]", r"A0 must hold only numbers, found True"),
        ("A0 = [[0.5]]", "A0 = [[0.5], [0.5, 1.0]]", r"A0 is ragged"),
        (
            "high = [0.1]",
            "high = [0.1, 0.2]",
            r"w\.high must have shape \(1,\) to match the 1 states \(D is the identity\), got shape \(2,\)",
        ),
        (
            "low = [-0.2], high = [0.2]",
            "low = [-0.2, 0.0], high = [0.2, 0.1]",
            r"theta\.low must have shape \(1,\) to match the 1 matrices of phi",
        ),
        ("high = [0.2]", "high = [-0.3]", r"theta is empty: low > high at indices \[0\]"),
        (
            "w = { low = [-0.1], high = [0.1] }",
            "w = { low = [-0.1] }",
            r"w must have exactly the keys 'low' and 'high' \(missing \['high'\]",
        ),
        ("w = { low = [-0.1], high = [0.1] }", "w = [0.1]", r"w must be a table"),
        (
            "B = [[1.0]]",
            "B = [[1.0]]\nD = [[1.0, 0.0]]",
            r"w\.low must have shape \(2,\) to match the columns of D \(1, 2\)",
        ),
        ("B = [[1.0]]", "B = [[1.0]]\nD = [[1.0], [0.0]]", r"D must have shape \(1, r\)"),
        (
            'name = "scalar"',
            'name = "scalar"\ntime = "continuous"\ndt = 0.1',
            r"time = 'continuous' takes the state matrix as key 'A', found 'A0'",
        ),
        ('name = "scalar"\nA0', 'name = "scalar"\ntime = "continuous"\nA', r"missing required key 'dt'"),
        (
            'name = "scalar"\nA0',
            'name = "scalar"\nA',
            r"time = 'discrete' takes the state matrix as key 'A0', found 'A'",
        ),
        (
            'name = "scalar"',
            'name = "scalar"\ntime = "hybrid"',
            r'time must be "discrete" or "continuous", got \'hybrid\'',
        ),
        ('name = "scalar"', 'name = "scalar"\ndt = -1.0', r"dt must be a finite number > 0, got -1.0"),
        ('name = "scalar"', 'name = "scalar"\ndt = inf', r"dt must be a finite number > 0, got inf"),
        ('name = "scalar"', "name = 3", r"name must be a non-empty string, got 3"),
        (
            'name = "scalar"',
            'name = "scalar"\nmeasurement_noise = [0.1, 0.2]',
            r"measurement_noise must be a number or have shape \(1,\)",
        ),
        ('name = "scalar"', 'name = "scalar"\nmeasurement_noise = -0.1', r"measurement_noise must be >= 0"),
        ('name = "scalar"', 'name = "scalar"\nmeasurement_noise = nan', r"measurement_noise contains NaN"),
        ("A0 = [[0.5]]", "A0 = [[0.5]", r"not valid TOML"),
    ],
)
def test_malformed_model_is_rejected_naming_the_key(old, new, message):
    with pytest.raises(ModelFileError, match=message):
        parse_model_file(_replace(MINIMAL, old, new))


def test_model_file_error_is_an_input_error():
    assert issubclass(ModelFileError, InputError) and issubclass(ModelFileError, ValueError)


def test_hypothesis_tables_are_checked_one_by_one():
    base = MINIMAL.replace('name = "scalar"', "")
    with pytest.raises(ModelFileError, match=r"hypothesis\[1\] \('b'\): B must have shape \(1, q\)"):
        parse_model_file(base + '[[hypothesis]]\nname = "a"\n[[hypothesis]]\nname = "b"\nB = [[1.0], [1.0]]\n')
    with pytest.raises(ModelFileError, match=r"hypothesis\[0\]: unknown key\(s\) \['Bee'\]"):
        parse_model_file(base + "[[hypothesis]]\nBee = 1\n")
    with pytest.raises(ModelFileError, match=r"hypothesis\[0\]: measurement_noise describes the sensor"):
        parse_model_file(base + "[[hypothesis]]\nmeasurement_noise = 0.1\n")
    with pytest.raises(ModelFileError, match=r"model names must be unique, repeated: \['a'\]"):
        parse_model_file(base + '[[hypothesis]]\nname = "a"\n[[hypothesis]]\nname = "a"\n')
    with pytest.raises(ModelFileError, match=r"same numbers of states and inputs.*\('a', 1, 1\), \('b', 2, 1\)"):
        parse_model_file(
            base
            + '[[hypothesis]]\nname = "a"\n[[hypothesis]]\nname = "b"\nA0 = [[1.0, 0.0], [0.0, 1.0]]\n'
            + "phi = [[[1.0, 0.0], [0.0, 1.0]]]\nB = [[1.0], [0.0]]\nw = { low = [0.0, 0.0], high = [0.0, 0.0] }\n"
        )
    with pytest.raises(ModelFileError, match=r"'hypothesis' must be one or more \[\[hypothesis\]\] tables"):
        parse_model_file(base + "hypothesis = 3\n")


def test_missing_and_unreadable_model_files(tmp_path):
    with pytest.raises(ModelFileError, match=r"model file '.*absent\.toml' does not exist"):
        load_model_file(tmp_path / "absent.toml")
    (tmp_path / "binary.toml").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ModelFileError, match=r"cannot read model file"):
        load_model_file(tmp_path / "binary.toml")


def test_every_toml_example_in_the_documentation_parses():
    import re

    text = (ROOT / "docs" / "model-format.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```toml\n(.*?)```", text, flags=re.DOTALL)
    assert len(blocks) >= 2
    parsed = [parse_model_file(block, source="docs") for block in blocks]
    assert parsed[0].names == ["isotropic friction", "wrong input gain"]
    np.testing.assert_array_equal(parsed[0].measurement_noise, np.zeros(4))
    full = load_model_file(EXAMPLES / "robot_hypotheses.toml")
    for name in parsed[0].names:  # the abridged example agrees with the example file
        for key in ("A0", "phi", "B", "D"):
            np.testing.assert_array_equal(
                getattr(parsed[0].select(name).systems[0], key), getattr(full.select(name).systems[0], key)
            )


_TWO_STATES = """
{labels}
[[hypothesis]]
A0 = [[1.0, 0.1], [0.0, 0.9]]
phi = [[[0.0, 0.0], [0.0, 0.1]]]
theta = { low = [0.0], high = [1.0] }
B = [[0.0], [0.1]]
w = { low = [-0.01, -0.01], high = [0.01, 0.01] }
"""


def test_state_names_and_units_label_the_states():
    text = _TWO_STATES.replace("{labels}", 'state_names = ["angle", "speed"]\nstate_units = ["rad", "rad/s"]')
    model_file = parse_model_file(text)
    assert model_file.state_names == ("angle", "speed") and model_file.state_units == ("rad", "rad/s")
    assert model_file.to_dict()["state_units"] == ["rad", "rad/s"]
    assert model_file.select(model_file.names[0]).state_names == ("angle", "speed")
    plain = parse_model_file(_TWO_STATES.replace("{labels}", ""))
    assert plain.state_names is None and plain.state_units is None


@pytest.mark.parametrize(
    "labels, message",
    [
        ('state_names = ["angle"]', "state_names must have 2 entries"),
        ('state_units = ["rad", 3]', "state_units must be a list of non-empty strings"),
        ('state_units = "rad"', "state_units must be a list of non-empty strings"),
        ('state_names = ["angle", " "]', "state_names must be a list of non-empty strings"),
    ],
)
def test_bad_state_labels_are_refused(labels, message):
    with pytest.raises(InputError, match=message):
        parse_model_file(_TWO_STATES.replace("{labels}", labels))


def test_the_select_report_states_margins_in_the_file_s_units():
    from minimaxplan.analysis.cli import main

    root = pathlib.Path(__file__).resolve().parents[2]
    model_file = load_model_file(root / "examples" / "robot_hypotheses.toml")
    assert model_file.state_units == ("m", "m", "m/s", "m/s")
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(
            ["select", str(root / "examples" / "robot_hypotheses.toml"), str(root / "examples" / "robot_data.csv")]
        )
    assert code == 0
    text = out.getvalue()
    assert "| 3 | wrong input gain | **eliminated** |" in text and "vy (state 3) | 0.04386 m/s |" in text
