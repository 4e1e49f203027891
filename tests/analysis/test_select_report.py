"""Reports that explain their verdict: ``select`` (first inconsistent transition, violated
state, margin per state, margins against N, ``--lmi``) and ``suboptimality`` (a degenerate
trend fit is a warning, not a fitted line)."""

from __future__ import annotations

import dataclasses
import json
import pathlib
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.analysis import suboptimality
from minimaxplan.analysis.data_file import load_data_file
from minimaxplan.analysis.elimination_history import first_inconsistency, margin_sample_sizes
from minimaxplan.analysis.model_file import ModelHypothesis, format_model_file, load_model_file
from minimaxplan.analysis.select_command import select_models
from minimaxplan.models import Box, InputError, UncertainLinearSystem
from minimaxplan.verify import check_assumption4, eliminate_models, feasible_parameter_box

ROOT = pathlib.Path(__file__).resolve().parents[2]
HYPOTHESES = ROOT / "examples" / "robot_hypotheses.toml"
ROBOT_DATA = ROOT / "examples" / "robot_data.csv"
MODELS = load_model_file(HYPOTHESES)
DATA = load_data_file(ROBOT_DATA)


def brute_force_first(hypothesis, states, controls, measurement_noise=None) -> int | None:
    """The smallest n whose prefix 0..n is eliminated, by scanning every prefix; None if never."""
    verdicts = [
        0
        in eliminate_models([hypothesis], states[: k + 1], controls[:k], measurement_noise=measurement_noise).eliminated
        for k in range(1, controls.shape[0] + 1)
    ]
    if not any(verdicts):
        return None
    first = verdicts.index(True)
    assert all(verdicts[first:]), "elimination must persist on longer prefixes"
    return first


# A plant whose first state is an exact integrator: the disturbance acts on x1 only.
A0 = np.array([[1.0, 0.1], [0.0, 0.9]])
PHI = np.array([[[0.0, 0.0], [0.0, -0.1]]])
B = np.array([[0.0], [0.1]])
D = np.array([[0.0], [1.0]])
W = Box([-0.01], [0.01])
THETA = Box([0.0], [1.0])


def exact_plant_data(coupling: float, n: int = 30, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Data of the plant with x0+ = x0 + coupling * x1 (0.1 in the hypothesis)."""
    truth = UncertainLinearSystem(np.array([[1.0, coupling], [0.0, 0.9]]), PHI, B, D=D, w=W, theta=THETA)
    rng = np.random.default_rng(seed)
    controls = rng.uniform(-1, 1, (n, 1))
    states = [np.zeros(2)]
    for u in controls:
        states.append(truth.step(states[-1], u, [0.5], rng.uniform(W.low, W.high)))
    return np.array(states), controls


def write_exact_case(tmp_path) -> tuple[pathlib.Path, pathlib.Path]:
    """A model file (a right and an exact-equation-wrong hypothesis) and its data file."""
    right = UncertainLinearSystem(np.array([[1.0, 0.1004], [0.0, 0.9]]), PHI, B, D=D, w=W, theta=THETA)
    wrong = UncertainLinearSystem(A0, PHI, B, D=D, w=W, theta=THETA)
    hypotheses = [
        ModelHypothesis("right", right, "discrete", None),
        ModelHypothesis("integrator off by 0.4%", wrong, "discrete", None),
    ]
    model = tmp_path / "exact.toml"
    model.write_text(format_model_file(hypotheses))
    states, controls = exact_plant_data(0.1004)
    data = tmp_path / "exact.npz"
    np.savez(data, states=states, controls=controls)
    return model, data


# ------------------------------------------------ the first inconsistent transition
@pytest.mark.parametrize("name", ["isotropic friction", "wrong input gain"])
def test_first_transition_equals_a_brute_force_prefix_scan_on_the_robot(name):
    index = MODELS.names.index(name)
    system = MODELS.systems[index]
    explanation = first_inconsistency(system, DATA.states, DATA.controls, index=index, name=name)
    n = explanation.first_transition
    assert n == brute_force_first(system, DATA.states, DATA.controls)
    # the certificate is the prefix's own, re-checked there, and refers to no later transition
    assert explanation.certificate.verify(system, DATA.states[: n + 2], DATA.controls[: n + 1])
    assert explanation.certificate.transitions.max() <= n
    assert explanation.recheck_bound > explanation.certificate.tolerance
    assert explanation.prefixes_checked <= int(np.ceil(np.log2(DATA.ntransitions))) + 1
    # the robot's disturbance acts on the velocities only: the witness rests on one of them
    assert explanation.violated in (2, 3) and not explanation.exact
    np.testing.assert_allclose(explanation.weights.sum(), 1.0)
    np.testing.assert_array_equal(explanation.reachable, [False, False, True, True])


def test_consistent_hypotheses_have_no_explanation():
    for name in ("anisotropic friction", "coupled friction"):
        system = MODELS.select(name).systems[0]
        assert first_inconsistency(system, DATA.states, DATA.controls) is None


@settings(max_examples=12, deadline=None)
@given(
    coupling=st.floats(0.095, 0.105).filter(lambda c: abs(c - 0.1) > 5e-4),
    gain=st.floats(0.5, 1.5),
    seed=st.integers(0, 2**16),
    noise=st.sampled_from([None, 1e-4]),
)
def test_first_transition_equals_a_brute_force_prefix_scan_on_random_data(coupling, gain, seed, noise):
    states, controls = exact_plant_data(coupling, n=16, seed=seed)
    hypothesis = UncertainLinearSystem(A0, PHI, gain * B, D=D, w=W, theta=THETA)
    expected = brute_force_first(hypothesis, states, controls, measurement_noise=noise)
    explanation = first_inconsistency(hypothesis, states, controls, measurement_noise=noise)
    if expected is None:
        assert explanation is None
        return
    assert explanation.first_transition == expected
    n = expected
    assert explanation.certificate.recheck(hypothesis, states[: n + 2], controls[: n + 1]) > 1e-7
    if noise is None:
        assert explanation.exact == (explanation.violated == 0)


def test_an_unreachable_state_is_contradicted_exactly():
    states, controls = exact_plant_data(0.1004)
    hypothesis = UncertainLinearSystem(A0, PHI, B, D=D, w=W, theta=THETA)
    explanation = first_inconsistency(hypothesis, states, controls)
    assert explanation.first_transition == brute_force_first(hypothesis, states, controls)
    assert explanation.violated == 0 and explanation.exact
    assert explanation.margin < 0.01  # the LP's relative number is small: not what the report says
    assert np.isnan(explanation.margin_in_state_units()[0])
    document = explanation.to_dict()
    assert document["contradicted_exactly"] is True and document["margin_in_state_units"][0] is None
    with pytest.raises(InputError, match="which must be 'full' or 'prefix'"):
        explanation.margin_in_state_units("half")


def test_exact_contradiction_wording_in_the_markdown_and_json(tmp_path, run_cli):
    model, data = write_exact_case(tmp_path)
    code, out, err = run_cli("select", model, data)
    assert (code, err) == (0, "")
    row = next(line for line in out.splitlines() if line.startswith("| 1 | integrator off by 0.4% |"))
    assert "| **eliminated** | contradicted exactly | contradicted exactly |" in row
    assert "| x0 (state 0) | no disturbance reaches it |" in row
    assert "the data **contradicts it exactly** (no disturbance bound, however large, explains it)" in out
    direct = eliminate_models(load_model_file(model).systems, *np.load(data).values())
    states, controls = np.load(data).values()
    prefix = first_inconsistency(load_model_file(model).systems[1], states, controls)
    for small in (direct.margins[1], direct.eliminated[1].lower_bound, prefix.recheck_bound, prefix.prefix_margin):
        assert small < 0.01 and f"{small:.6g}" not in out and f"{small:.4g}" not in out
    code, out, _ = run_cli("select", model, data, "--json")
    entry = json.loads(out)["hypotheses"][1]
    assert entry["explanation"]["contradicted_exactly"] is True and entry["explanation"]["violated_state"] == 0


# --------------------------------------------------------- units and the Markdown
def test_markdown_states_the_margin_per_state_in_its_unit():
    named_by_the_file = select_models(MODELS, DATA)  # the example file names its states and units
    assert named_by_the_file.state_units == ("m", "m", "m/s", "m/s")
    report = dataclasses.replace(named_by_the_file, state_names=None, state_units=None)
    e = report.explanations[0]  # isotropic friction
    assert "| 0 | isotropic friction | **eliminated** |" in report.to_markdown()
    assert f"| {e.first_transition} | x{e.violated} (state {e.violated}) |" in report.to_markdown()
    assert "state units" in report.to_markdown()
    named = dataclasses.replace(report, state_names=("px", "py", "vx", "vy"), state_units=("m", "m", "m/s", "m/s"))
    text = named.to_markdown()
    label = ("vx", "vy")[e.violated - 2]
    excess = e.margin * e.unit_radius[e.violated]
    np.testing.assert_allclose(excess, e.margin * 0.01)  # radius of dt * w on a velocity: 0.01 m/s
    assert f"| {label} (state {e.violated}) | {excess:.4g} m/s |" in text
    assert "state units" not in text
    assert named.to_dict()["states"][2] == {"name": "vx", "unit": "m/s"}


def test_margin_sample_sizes_hold_each_jump_and_the_whole_trajectory():
    sizes = margin_sample_sizes(120, [6, 0])
    assert sizes[0] == 1 and sizes[-1] == 120 and np.all(np.diff(sizes) > 0)
    assert {1, 6, 7, 120} <= set(sizes.tolist())
    assert margin_sample_sizes(0).size == 0


# ------------------------------------------------------------- the PNG and the JSON
def test_margin_png_is_written_beside_the_report_and_named_in_it(tmp_path, run_cli):
    code, _, err = run_cli("select", HYPOTHESES, ROBOT_DATA, "--out", tmp_path / "select.md")
    assert (code, err) == (0, "")
    png = tmp_path / "select-margins.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    assert "![inconsistency margins against N](select-margins.png)" in (tmp_path / "select.md").read_text()
    code, _, _ = run_cli("select", HYPOTHESES, ROBOT_DATA, "--json", "--out", tmp_path / "select.json")
    document = json.loads((tmp_path / "select.json").read_text())
    assert document["margin_image"] == "select-margins.png"
    history = document["margin_history"]
    assert history["sample_sizes"][-1] == DATA.ntransitions
    direct = eliminate_models(MODELS.systems, DATA.states, DATA.controls)
    np.testing.assert_allclose(np.array(history["margins"])[:, -1], direct.margins, rtol=1e-9, atol=1e-12)
    for entry in document["hypotheses"]:
        if entry["survives"]:
            assert entry["explanation"] is None
        else:
            n = entry["explanation"]["first_transition"]
            assert n == brute_force_first(MODELS.systems[entry["index"]], DATA.states, DATA.controls)
            survives = history["survives"][entry["index"]]
            k = history["sample_sizes"].index(n + 1)  # the jump: kept on 0..n-1, eliminated on 0..n
            assert not survives[k] and (n == 0 or (history["sample_sizes"][k - 1] == n and survives[k - 1]))


def test_without_out_no_png_is_written(tmp_path, run_cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, _ = run_cli("select", HYPOTHESES, ROBOT_DATA)
    assert code == 0 and "margins against N" not in out and list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------- --lmi
def test_select_lmi_checks_each_survivors_feasible_box(run_cli):
    code, out, err = run_cli("select", HYPOTHESES, ROBOT_DATA, "--lmi", "--lmi-states", "2,3", "--json")
    assert (code, err) == (0, "")
    document = json.loads(out)
    assert document["lmi_states"] == [2, 3]
    for entry in document["hypotheses"]:
        if not entry["survives"]:
            assert entry["assumption4"] is None
            continue
        system = MODELS.hypotheses[entry["index"]].continuous_system
        box = feasible_parameter_box(MODELS.systems[entry["index"]], DATA.states, DATA.controls)
        np.testing.assert_allclose(entry["feasible_box"]["low"], box.low)
        vertices = system.A(box.vertices())[:, 2:, 2:]
        direct = check_assumption4(list(vertices), form="continuous", D=system.D[2:])
        lmi = entry["assumption4"]
        assert lmi["status"] == direct.status.value == "feasible"
        assert lmi["certified"] and lmi["holds"] and lmi["proof"] == "primal certificate re-checked exactly"
        assert len(lmi["report"]["matrices"]) == 2**box.dim
    code, out, _ = run_cli("select", HYPOTHESES, ROBOT_DATA, "--lmi", "--lmi-states", "2,3")
    assert "## Assumption 4 on each survivor's feasible parameter box" in out
    assert "| anisotropic friction | continuous | 4 | feasible | True | primal certificate re-checked exactly |" in out
    assert "| coupled friction | continuous | 8 | feasible | True |" in out


def test_select_lmi_on_the_full_robot_is_proven_infeasible(run_cli):
    """The positions integrate the velocities: no common P exists, and the report says it is proven."""
    code, out, _ = run_cli("select", HYPOTHESES, ROBOT_DATA, "--lmi", "--json")
    assert code == 0
    verdicts = [h["assumption4"] for h in json.loads(out)["hypotheses"] if h["survives"]]
    assert len(verdicts) == 2
    for lmi in verdicts:
        assert lmi["status"] == "infeasible" and not lmi["holds"]
        assert lmi["proof"] == "dual certificate re-checked exactly"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--lmi", "--lmi-states", "0,1"], r"argument --lmi-states: states \[0, 1\] are not an invariant subsystem"),
        (["--lmi", "--lmi-states", "2,9"], r"argument --lmi-states: states must be distinct state indices in 0\.\.3"),
        (["--lmi", "--lmi-states", "2,2"], r"argument --lmi-states: states must be distinct"),
        (["--lmi", "--lmi-states", "a"], r"argument --lmi-states: expected comma-separated integers"),
        (["--lmi-states", "2,3"], r"--lmi-form and --lmi-states need --lmi"),
        (["--lmi-form", "discrete"], r"--lmi-form and --lmi-states need --lmi"),
        (["--lmi", "--lmi-form", "sideways"], r"argument --lmi-form: invalid choice"),
    ],
)
def test_bad_lmi_options_exit_2_with_one_line(run_cli, argv, message):
    code, out, err = run_cli("select", HYPOTHESES, ROBOT_DATA, *argv)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith("minimaxplan select: error: ")
    assert re.search(message, err)


def test_lmi_form_continuous_of_a_discrete_model_exits_2(tmp_path, run_cli):
    model, data = write_exact_case(tmp_path)
    code, _, err = run_cli("select", model, data, "--lmi", "--lmi-form", "continuous", "--lmi-states", "1")
    assert code == 2 and "continuous form of Assumption 4 needs a continuous-time model" in err


# ------------------------------------------------------------ suboptimality's fit
@pytest.mark.parametrize(
    ("ns", "values", "reason"),
    [
        ([5], [0.3], r"1 distinct value\(s\) of N, fewer than the 2 parameters"),
        ([5, 5, 5], [0.1, 0.2, 0.3], r"1 distinct value\(s\) of N"),
        ([2, 5, 10], [0.0, 0.0, 0.0], r"the suboptimality is exactly 0 at all 3 values of N"),
    ],
)
def test_a_degenerate_fit_is_a_warning_not_a_line(ns, values, reason):
    fit = suboptimality.fit_trend(ns, values)
    assert fit["a"] is None and fit["b"] is None
    assert re.search(reason, fit["warning"])
    study = {"rows": [], "episodes": 1, "fit": fit}
    text = suboptimality.markdown(study)
    assert "**Warning: no trend fitted:" in text and "Trend fit" not in text and "0.0000 log" not in text


def test_a_proper_fit_has_no_warning():
    fit = suboptimality.fit_trend([1, 2, 4, 8], [2 + 3 * np.log(n) / n for n in (1, 2, 4, 8)])
    assert fit["warning"] is None and fit["a"] == pytest.approx(2.0) and fit["b"] == pytest.approx(3.0)


def test_the_cli_warns_on_stderr_and_in_the_report(tmp_path, run_cli, monkeypatch):
    def study(samples, **kwargs):
        rows = [{"n": n, "mean": 0.0, "max": 0.0, "min": 0.0, "per_episode": [0.0], "failures": 0} for n in samples]
        return {
            "scenario": "static",
            "episodes": 1,
            "horizon_decisions": 1,
            "seed": 0,
            "rows": rows,
            "fit": suboptimality.fit_trend([r["n"] for r in rows], [r["mean"] for r in rows]),
        }

    monkeypatch.setattr(suboptimality, "suboptimality_study", study)
    code, out, err = run_cli("suboptimality", "--samples", "5", "--out", tmp_path)
    assert code == 0
    assert err.strip() == (
        "minimaxplan suboptimality: warning: no trend fitted: 1 distinct value(s) of N, "
        "fewer than the 2 parameters of a + b log(N)/N"
    )
    assert (
        "**Warning: no trend fitted:" in out
        and "**Warning: no trend fitted:" in (tmp_path / "suboptimality.md").read_text()
    )
    assert json.loads((tmp_path / "suboptimality.json").read_text())["fit"]["a"] is None
    assert (tmp_path / "suboptimality.png").read_bytes()[:4] == b"\x89PNG"
    code, _, err = run_cli("suboptimality", "--samples", "2,5", "--out", tmp_path)
    assert code == 0 and "exactly 0 at all 2 values of N" in err
