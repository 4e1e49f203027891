"""The robot's model: matrices, hypotheses, parameters."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import Box, InputError, UncertainLinearSystem
from minimaxplan.scenarios.robot import DEFAULT_ROBOT, RobotParameters, robot_hypotheses, robot_system

finite = dict(allow_nan=False, allow_infinity=False)


def test_robot_system_is_forward_euler_of_the_friction_double_integrator():
    sys = robot_system()
    dt = 0.1
    assert isinstance(sys, UncertainLinearSystem)
    assert (sys.nstates, sys.ninputs, sys.nparams, sys.ndisturbances) == (4, 2, 2, 2)
    xi = np.array([0.3, 0.7])
    expected_A = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1 - dt * xi[0], 0], [0, 0, 0, 1 - dt * xi[1]]])
    np.testing.assert_allclose(sys.A(xi), expected_A, rtol=0, atol=1e-15)
    np.testing.assert_allclose(sys.B, dt * np.array([[0, 0], [0, 0], [1, 0], [0, 1]]))
    np.testing.assert_allclose(sys.D, dt * np.array([[0, 0], [0, 0], [1, 0], [0, 1]]))
    assert sys.theta == Box([0.2, 0.2], [0.8, 0.8])
    assert sys.w == Box([-0.1, -0.1], [0.1, 0.1])


@given(
    x=st.lists(st.floats(-50, 50, **finite), min_size=4, max_size=4),
    u=st.lists(st.floats(-1, 1, **finite), min_size=2, max_size=2),
    xi=st.lists(st.floats(0.2, 0.8, **finite), min_size=2, max_size=2),
    w=st.lists(st.floats(-0.1, 0.1, **finite), min_size=2, max_size=2),
    dt=st.floats(0.01, 0.5, **finite),
)
def test_discrete_step_matches_the_continuous_dynamics_euler_step(x, u, xi, w, dt):
    x, u, xi, w = map(np.array, (x, u, xi, w))
    sys = robot_system(dt=dt)
    pos, vel = x[:2], x[2:]
    expected = np.concatenate([pos + dt * vel, vel + dt * (-xi * vel + u + w)])
    np.testing.assert_allclose(sys.step(x, u, xi, w), expected, rtol=1e-12, atol=1e-12)


def test_hypotheses_have_names_and_the_expected_structures():
    hyps = robot_hypotheses()
    names = [name for name, _ in hyps]
    assert names == ["anisotropic friction", "isotropic friction", "wrong input gain"]
    truth, iso, gain = (h.system for h in hyps)
    assert truth.nparams == 2 and iso.nparams == 1 and gain.nparams == 2
    np.testing.assert_allclose(iso.A([0.5]), truth.A([0.5, 0.5]))
    np.testing.assert_allclose(gain.B, 0.6 * truth.B)
    assert iso.theta == Box([0.2], [0.8])
    assert hyps[0].to_dict()["name"] == "anisotropic friction"


def test_hypotheses_follow_dt():
    gains = {"anisotropic friction": 1.0, "isotropic friction": 1.0, "wrong input gain": 0.6}
    for name, sys in robot_hypotheses(dt=0.05):
        np.testing.assert_allclose(sys.B[2:], 0.05 * gains[name] * np.eye(2))
        np.testing.assert_allclose(sys.D[2:], 0.05 * np.eye(2))
        assert np.isclose(sys.A0[0, 2], 0.05)


def test_parameters_derived_values_and_dict():
    p = DEFAULT_ROBOT
    assert p.decision_period == pytest.approx(0.5)
    assert p.max_steps == 600
    assert p.friction_prior == Box([0.2, 0.2], [0.8, 0.8])
    assert p.to_dict()["robot_radius"] == 0.3


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"dt": 0.0}, "dt must be > 0"),
        ({"substeps": 0}, "substeps must be a positive integer"),
        ({"substeps": 2.5}, "substeps must be a positive integer"),
        ({"friction_low": 0.9}, "friction_low must be <= friction_high"),
        ({"goal_distance_low": 19.0}, "goal_distance_low must be <= goal_distance_high"),
        ({"robot_radius": float("nan")}, "robot_radius must be finite"),
        ({"goal_distance_high": 30.0}, "does not fit in the arena"),
    ],
)
def test_parameters_reject_bad_values(kwargs, message):
    with pytest.raises(InputError, match=message):
        RobotParameters(**kwargs)


def test_robot_system_rejects_bad_gain_and_dt():
    with pytest.raises(InputError, match="input_gain must be > 0"):
        robot_system(input_gain=-1.0)
    with pytest.raises(InputError, match="dt must be > 0"):
        robot_system(dt=0.0)


@given(seed=st.integers(0, 10_000), xi_x=st.floats(0.2, 0.8, **finite), xi_y=st.floats(0.2, 0.8, **finite))
@settings(max_examples=15)
def test_world_data_keeps_the_truth_and_rejects_the_wrong_gain(seed, xi_x, xi_y):
    """The hypotheses are usable for model selection on data from the worlds: the true
    structure survives any world trajectory (noise-free states, disturbances inside w),
    the wrong input gain is eliminated by a long enough excitation, and the isotropic
    hypothesis is eliminated once the two frictions differ clearly."""
    from minimaxplan.scenarios.worlds import make_world
    from minimaxplan.verify import eliminate_models

    world = make_world("static", seed)
    world.obstacles = type(world.obstacles).empty()
    world.true_theta = np.array([xi_x, xi_y])
    rng = np.random.default_rng(seed)
    states, controls = [world.state.copy()], []
    for _ in range(60):
        u = rng.choice([-1.0, 1.0], size=2)
        world.apply(u)
        controls.append(u)
        states.append(world.state.copy())
        if world.done:
            break
    result = eliminate_models([h.system for h in robot_hypotheses()], np.array(states), np.array(controls))
    assert 0 in result.survivors
    assert 2 in result.eliminated
    if abs(xi_x - xi_y) > 0.3:
        assert 1 in result.eliminated
