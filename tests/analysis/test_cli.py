"""The ``lmi`` and ``select`` subcommands: happy paths checked against the library, and every error path."""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.analysis import cli
from minimaxplan.analysis.data_file import load_data_file
from minimaxplan.analysis.lmi_command import check_model
from minimaxplan.analysis.model_file import format_model_file, load_model_file
from minimaxplan.verify import check_assumption4, eliminate_models, feasible_parameter_box, lmi_matrix

ROOT = pathlib.Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
HYPOTHESES = EXAMPLES / "robot_hypotheses.toml"
ROBOT_MODEL = EXAMPLES / "robot_model.toml"
ROBOT_DATA = EXAMPLES / "robot_data.csv"

SCALAR = """
name = "scalar"
A0 = [[0.5]]
phi = [[[1.0]]]
B = [[1.0]]
w = { low = [-0.1], high = [0.1] }
theta = { low = [-0.2], high = [0.2] }
"""


def write(tmp_path, name, text) -> pathlib.Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_both_subcommands_are_registered():
    help_text = cli.build_parser().format_help()
    assert "lmi" in help_text and "select" in help_text


def test_each_subcommand_module_adds_its_command_with_its_job():
    import importlib

    subparsers = cli.build_parser()._subparsers._group_actions[0]
    for module_name in cli.SUBCOMMAND_MODULES:
        command = importlib.import_module(f"minimaxplan.analysis.{module_name}").COMMAND
        parser = subparsers.choices[command.name]
        assert parser.description == command.description and parser.epilog == command.epilog
        assert parser.get_default("func") is command.run
    assert list(subparsers.choices) == [
        importlib.import_module(f"minimaxplan.analysis.{name}").COMMAND.name for name in cli.SUBCOMMAND_MODULES
    ]


# ------------------------------------------------------------------------ lmi
def test_lmi_vertices_json_matches_the_library(run_cli):
    code, out, err = run_cli("lmi", ROBOT_MODEL, "--vertices", "--json")
    assert (code, err) == (0, "")
    document = json.loads(out)
    assert document["command"] == "lmi" and document["exit_code"] == 0 and document["all_hold"] is True
    (report,) = document["models"]
    model = load_model_file(ROBOT_MODEL).hypotheses[0]
    matrices, D = model.state_matrices("continuous", vertices=True)
    direct = check_assumption4(list(matrices), form="continuous", D=D)
    assert report["form"] == "continuous" and report["holds"] is True
    assert report["result"]["status"] == direct.status == "feasible"
    assert report["result"]["certified"] is True and direct.certified
    np.testing.assert_allclose(report["result"]["rho"], direct.rho, rtol=1e-6)
    np.testing.assert_allclose(np.array([m["A"] for m in report["matrices"]]), matrices, rtol=0, atol=0)
    np.testing.assert_allclose(np.array([m["parameters"] for m in report["matrices"]]), model.system.theta.vertices())
    # the report's margins are the LMI's largest eigenvalues at the library's certificate
    for entry, A in zip(report["matrices"], matrices):
        expected = np.linalg.eigvalsh(lmi_matrix(A, direct.P, direct.Q0, direct.rho, D, "continuous"))[-1]
        assert entry["lmi_max_eigenvalue"] < 0
        np.testing.assert_allclose(entry["lmi_max_eigenvalue"], expected, rtol=1e-5, atol=1e-8)
        np.testing.assert_allclose(sorted(entry["eigenvalues"]["real"]), sorted(np.linalg.eigvals(A).real), atol=1e-12)
    np.testing.assert_allclose(report["P_eigenvalues"], np.linalg.eigvalsh(direct.P), rtol=1e-5, atol=1e-8)


def test_lmi_markdown_report_to_file(tmp_path, run_cli):
    out_file = tmp_path / "report.md"
    code, out, err = run_cli("lmi", ROBOT_MODEL, "--form", "discrete", "--out", out_file)
    assert (code, out, err) == (0, "", "")
    text = out_file.read_text()
    assert text.startswith("# Assumption 4 (LMI) report")
    assert "**Assumption 4 holds: feasible, certificate re-checked exactly**" in text
    assert "spectral radius of A" in text and "eigenvalues of P" in text
    assert "discrete: `[[A^T P A - P + Q0" in text


def test_lmi_open_loop_robot_fails_with_exit_1(run_cli):
    code, out, err = run_cli("lmi", HYPOTHESES, "--model", "anisotropic friction", "--json")
    assert (code, err) == (1, "")
    document = json.loads(out)
    assert document["exit_code"] == 1 and document["all_hold"] is False
    (report,) = document["models"]
    assert report["holds"] is False and report["result"]["status"] in ("infeasible", "inconclusive")
    # the positions integrate: a zero eigenvalue, so no strict Lyapunov certificate can exist
    assert max(m["stability_margin"] for m in report["matrices"]) == 0.0


def test_lmi_checks_every_hypothesis_of_a_file(run_cli):
    code, out, _ = run_cli("lmi", HYPOTHESES, "--json")
    document = json.loads(out)
    assert [m["model"] for m in document["models"]] == load_model_file(HYPOTHESES).names
    assert code == 1


@settings(max_examples=15)
@given(
    st.integers(1, 3),
    st.floats(0.05, 0.95),
    st.sampled_from(["discrete", "continuous"]),
    st.integers(0, 2**31 - 1),
)
def test_certified_results_have_negative_lmi_margins_in_the_report(p, size, form, seed):
    """Cross-check: the report's LMI matrix convention agrees with the library's certificate."""
    rng = np.random.default_rng(seed)
    M = rng.normal(size=(p, p))  # not Metzler in general
    radius = np.max(np.abs(np.linalg.eigvals(M)))
    A = size * M / radius if form == "discrete" else M - (radius + size) * np.eye(p)
    D = rng.normal(size=(p, 2))
    result = check_assumption4(A, form=form, D=D)
    assert result.status == "feasible" and result.certified  # A is stable, so the LMI is feasible
    margin = np.linalg.eigvalsh(lmi_matrix(A, result.P, result.Q0, result.rho, D, form))[-1]
    assert margin < 0
    np.testing.assert_allclose(margin, result.max_eigenvalue, rtol=1e-9, atol=1e-12)


# --------------------------------------------------------------------- select
def test_select_json_matches_the_library(run_cli):
    code, out, err = run_cli("select", HYPOTHESES, ROBOT_DATA, "--json")
    assert (code, err) == (0, "")
    document = json.loads(out)
    model_file = load_model_file(HYPOTHESES)
    data = load_data_file(ROBOT_DATA)
    direct = eliminate_models(model_file.systems, data.states, data.controls)
    assert document["survivors"] == [model_file.names[i] for i in direct.survivors]
    # the true plant is "anisotropic friction"; "coupled friction" contains it
    assert document["survivors"] == ["anisotropic friction", "coupled friction"]
    assert document["eliminated"] == ["isotropic friction", "wrong input gain"]
    for entry in document["hypotheses"]:
        i = entry["index"]
        if entry["survives"]:
            box = feasible_parameter_box(model_file.systems[i], data.states, data.controls)
            np.testing.assert_allclose(entry["feasible_box"]["low"], box.low, rtol=1e-9, atol=1e-12)
            np.testing.assert_allclose(entry["feasible_box"]["high"], box.high, rtol=1e-9, atol=1e-12)
            assert entry["certificate"] is None
        else:
            certificate = direct.eliminated[i]
            assert entry["certificate"]["margin"] > 0
            np.testing.assert_allclose(entry["certificate"]["margin"], certificate.margin, rtol=1e-6)
            assert entry["feasible_box"] is None
    assert document["data"] == {"transitions": 120, "states": 4, "inputs": 2}
    assert document["timing"]["elimination"] > 0


def test_select_markdown_and_npz_agree_with_csv(tmp_path, run_cli):
    data = load_data_file(ROBOT_DATA)
    np.savez(tmp_path / "robot.npz", states=data.states, controls=data.controls)
    code_csv, out_csv, _ = run_cli("select", HYPOTHESES, ROBOT_DATA, "--json")
    code_npz, out_npz, _ = run_cli("select", HYPOTHESES, tmp_path / "robot.npz", "--json")
    assert code_csv == code_npz == 0
    csv_doc, npz_doc = json.loads(out_csv), json.loads(out_npz)
    assert csv_doc["survivors"] == npz_doc["survivors"]
    assert [h["feasible_box"] for h in csv_doc["hypotheses"]] == [h["feasible_box"] for h in npz_doc["hypotheses"]]
    code, _, err = run_cli("select", HYPOTHESES, ROBOT_DATA, "--out", tmp_path / "select.md")
    text = (tmp_path / "select.md").read_text()
    assert code == 0 and err == ""
    assert "| 0 | isotropic friction | **eliminated** |" in text
    assert "| 1 | anisotropic friction | survives |" in text
    assert "## Feasible parameter boxes of the survivors" in text


def test_select_exits_1_when_no_hypothesis_survives(tmp_path, run_cli):
    model_file = load_model_file(HYPOTHESES)
    wrong = [model_file.select(n).hypotheses[0] for n in ("isotropic friction", "wrong input gain")]
    path = write(tmp_path, "wrong.toml", format_model_file(wrong))
    code, out, err = run_cli("select", path, ROBOT_DATA, "--json")
    assert (code, err) == (1, "")
    document = json.loads(out)
    assert document["survivors"] == [] and document["exit_code"] == 1
    code, out, _ = run_cli("select", path, ROBOT_DATA)
    assert code == 1 and "**No hypothesis is consistent with the data.**" in out


# ---------------------------------------------------------------- error paths
@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("phi = [[[1.0]]]", "", r"missing required key 'phi'"),
        ("B = [[1.0]]", "B = [[1.0], [1.0]]", r"B must have shape \(1, q\) to match A0 \(1, 1\), got shape \(2, 1\)"),
        ("A0 = [[0.5]]", "A0 = [[nan]]", r"A0 contains NaN or infinite entries"),
        ("high = [0.2]", "high = [inf]", r"theta\.high contains NaN or infinite entries"),
        ("phi = [[[1.0]]]", "phi = [[[1.0]]]\ncolour = 3", r"unknown key\(s\) \['colour'\]"),
    ],
)
@pytest.mark.parametrize("command", ["lmi", "select"])
def test_malformed_model_file_exits_2_naming_the_key(tmp_path, run_cli, command, old, new, message):
    assert old in SCALAR
    model = write(tmp_path, "bad.toml", SCALAR.replace(old, new))
    data = write(tmp_path, "d.csv", "x0,u0\n0,1\n1,\n")
    argv = ("lmi", model) if command == "lmi" else ("select", model, data)
    code, out, err = run_cli(*argv)
    assert code == 2 and out == ""
    assert err.startswith(f"minimaxplan {command}: error: ")
    assert "bad.toml" in err
    assert __import__("re").search(message, err), err


@pytest.mark.parametrize("command", ["lmi", "select"])
def test_missing_model_file_exits_2(tmp_path, run_cli, command):
    argv = ("lmi", tmp_path / "nope.toml") if command == "lmi" else ("select", tmp_path / "nope.toml", ROBOT_DATA)
    code, out, err = run_cli(*argv)
    assert (code, out) == (2, "")
    assert err.startswith(f"minimaxplan {command}: error: model file '") and "nope.toml' does not exist" in err


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("d.txt", "x0,u0\n", r"must end in \.csv or \.npz, got '\.txt'"),
        ("absent.csv", None, r"data file '.*absent\.csv' does not exist"),
        ("nan.csv", "x0,x1,x2,x3,u0,u1\n0,0,0,0,nan,0\n0,0,0,0,,\n", r"line 2, column 'u0' is not finite: 'nan'"),
        (
            "short.csv",
            "x0,x1,u0\n0,0,1\n0,0,\n",
            r"the models have 4 states and 2 inputs.*got states shape \(2, 2\) and controls shape \(1, 1\)",
        ),
        (
            "gap.csv",
            "x0,x1,x2,x4,u0,u1\n0,0,0,0,0,0\n0,0,0,0,,\n",
            r"x columns must be numbered 0\.\.3, got \[0, 1, 2, 4\]",
        ),
    ],
)
def test_bad_data_file_exits_2(tmp_path, run_cli, name, content, message):
    if content is not None:
        write(tmp_path, name, content)
    code, out, err = run_cli("select", HYPOTHESES, tmp_path / name)
    assert (code, out) == (2, "")
    assert err.startswith("minimaxplan select: error: ")
    assert __import__("re").search(message, err), err


def test_lmi_continuous_form_of_a_discrete_model_exits_2(tmp_path, run_cli):
    code, out, err = run_cli("lmi", write(tmp_path, "m.toml", SCALAR), "--form", "continuous")
    assert (code, out) == (2, "")
    assert "model 'scalar' is discrete-time" in err


def test_lmi_unknown_model_name_exits_2(run_cli):
    code, out, err = run_cli("lmi", HYPOTHESES, "--model", "frictionless")
    assert (code, out) == (2, "")
    assert "no model named 'frictionless'" in err


def test_usage_errors_exit_2(run_cli):
    code, _, err = run_cli("lmi", ROBOT_MODEL, "--form", "hybrid")
    assert code == 2 and "invalid choice: 'hybrid'" in err
    code, _, err = run_cli("select", HYPOTHESES)
    assert code == 2 and "the following arguments are required: data" in err


def test_lmi_json_to_file_and_markdown_of_an_uncertified_result(tmp_path, run_cli):
    out_file = tmp_path / "report.json"
    code, out, err = run_cli("lmi", HYPOTHESES, "--model", "isotropic friction", "--json", "--out", out_file)
    assert (code, out) == (1, "")
    document = json.loads(out_file.read_text())
    (report,) = document["models"]
    assert report["result"]["status"] == "infeasible" and report["holds"] is False
    assert report["P_eigenvalues"] is None and report["matrices"][0]["lmi_max_eigenvalue"] is None
    code, out, _ = run_cli("lmi", HYPOTHESES, "--model", "isotropic friction", "--form", "discrete")
    assert code == 1
    assert "**Assumption 4 fails: no certificate with normalised margin above" in out
    assert "(dual certificate re-checked exactly)**" in out and "| 0 | [0.85] | 1 | - |" in out


def test_lmi_matrix_rejects_an_unknown_form():
    from minimaxplan.models import InputError

    with pytest.raises(InputError, match=r"form must be one of \('continuous', 'discrete'\), got 'hybrid'"):
        lmi_matrix(np.eye(1), np.eye(1), np.eye(1), 1.0, np.eye(1), "hybrid")


def test_check_model_reports_the_library_result_for_each_form():
    model = load_model_file(ROBOT_MODEL).hypotheses[0]
    for form in ("continuous", "discrete"):
        report = check_model(model, form=form)
        matrices, D = model.state_matrices(form, vertices=False)
        direct = check_assumption4(matrices[0], form=form, D=D)
        assert report.holds and report.result.status == direct.status == "feasible"
        np.testing.assert_allclose(report.result.P, direct.P, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(report.lmi_max_eigenvalues().max(), direct.max_eigenvalue, rtol=1e-6)


def test_select_passes_the_measurement_noise_bound(tmp_path, run_cli):
    model_file = load_model_file(HYPOTHESES)
    noisy = write(tmp_path, "noisy.toml", format_model_file(model_file.hypotheses, measurement_noise=[0.001] * 4))
    code, out, err = run_cli("select", noisy, ROBOT_DATA, "--json")
    assert (code, err) == (0, "")
    document = json.loads(out)
    assert document["measurement_noise"] == [0.001] * 4
    data = load_data_file(ROBOT_DATA)
    direct = eliminate_models(model_file.systems, data.states, data.controls, measurement_noise=0.001)
    np.testing.assert_allclose([h["margin"] for h in document["hypotheses"]], direct.margins, rtol=1e-9, atol=1e-12)
    quiet = eliminate_models(model_file.systems, data.states, data.controls)
    assert direct.margins[0] < quiet.margins[0]  # the noise allowance explains part of the misfit
    i = model_file.names.index("anisotropic friction")
    box = feasible_parameter_box(model_file.systems[i], data.states, data.controls, measurement_noise=0.001)
    assert document["hypotheses"][i]["feasible_box"] == box.to_dict()


# ------------------------------------------------------------- lmi --regions
# A(k) = [[0, 1], [-k, -c]], c = 0.2, k in [1, 4]: every vertex is Hurwitz, but by the
# Shorten-Narendra test a common P over [k1, k2] exists iff
# (k2 - k1)^2 < 2 c^2 (k1 + k2) - c^4 (tests/verify/test_regions.py checks the library).
OSCILLATOR = """
name = "damped oscillator"
time = "continuous"
dt = 0.1
A = [[0.0, 1.0], [0.0, -0.2]]
phi = [[[0.0, 0.0], [-1.0, 0.0]]]
B = [[0.0], [1.0]]
w = { low = [-0.1, -0.1], high = [0.1, 0.1] }
theta = { low = [1.0], high = [4.0] }
"""


def shorten_narendra(k1: float, k2: float, c: float = 0.2) -> bool:
    return (k2 - k1) ** 2 < 2 * c**2 * (k1 + k2) - c**4


def test_lmi_regions_json_and_png_map_where_assumption4_holds(tmp_path, run_cli):
    model = write(tmp_path, "oscillator.toml", OSCILLATOR)
    out_file = tmp_path / "report.json"
    code, out, err = run_cli("lmi", model, "--vertices", "--regions", "--depth", "2", "--json", "--out", out_file)
    assert (code, out, err) == (1, "", "")  # one P over the whole box does not exist
    (report,) = json.loads(out_file.read_text())["models"]
    assert report["result"]["status"] == "infeasible"
    regions = report["regions"]
    assert regions["conflict"]["indices"] == [0, 1] and regions["conflict"]["irreducible"] is True
    assert [(p["low"], p["high"]) for p in regions["pieces"]] == [
        ([1.0], [1.75]),
        ([1.75], [2.5]),
        ([2.5], [3.25]),
        ([3.25], [4.0]),
    ]
    assert [p["certified"] for p in regions["pieces"]] == [
        shorten_narendra(p["low"][0], p["high"][0]) for p in regions["pieces"]
    ]
    assert regions["certified_fraction"] == pytest.approx(0.25)
    image = tmp_path / report["region_image"]
    assert image.name == "report-damped-oscillator-regions.png"
    assert image.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_lmi_regions_markdown_names_the_conflict_and_the_pieces(tmp_path, run_cli):
    model = write(tmp_path, "oscillator.toml", OSCILLATOR)
    out_file = tmp_path / "report.md"
    code, _, _ = run_cli("lmi", model, "--regions", "--depth", "2", "--out", out_file)
    text = out_file.read_text()
    assert code == 0  # the exit code is the main check's: here the nominal matrix, which is stable
    assert "### Where Assumption 4 holds" in text
    assert "| 0.25 | 0.75 | 0 | 4 |" in text
    assert "Conflicting vertices of the whole box: 0, 1" in text and "proven irreducible" in text
    assert "| 3 | [3.25] | [4] | 2 | 0.25 | **certified** |" in text
    assert "![where Assumption 4 holds](report-damped-oscillator-regions.png)" in text
    assert (tmp_path / "report-damped-oscillator-regions.png").is_file()


def test_lmi_depth_must_be_a_count(tmp_path, run_cli):
    model = write(tmp_path, "oscillator.toml", OSCILLATOR)
    code, _, err = run_cli("lmi", model, "--regions", "--depth", "-1")
    assert code == 2 and "--depth: expected an integer >= 0, got -1" in err
    code, out, err = run_cli("lmi", model, "--depth", "2")
    assert (code, out) == (2, "") and err == "minimaxplan lmi: error: --depth needs --regions\n"


def test_lmi_markdown_prints_the_digits_that_matter(tmp_path, run_cli):
    model = write(
        tmp_path, "slow.toml", SCALAR.replace("A0 = [[0.5]]", "A0 = [[0.9999975]]").replace("[[[1.0]]]", "[[[0.0]]]")
    )
    code, out, _ = run_cli("lmi", model)
    assert code == 0
    assert "| 0 | [0] | 0.9999975 |" in out
    assert "| normalised slack t* of the primal SDP |" in out and "| cond(P) |" in out
