"""The quadratic contraction bound of the lateral closed loop (`lateral_contraction`)."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.models.errors import DimensionError, InputError
from minimaxplan.scenarios.lateral_contraction import (
    contraction_factor,
    contraction_metrics,
    ellipse_hull,
    metric_radius,
)
from minimaxplan.scenarios.vehicles import (
    BehaviourParameters,
    VehicleParameters,
    bicycle_step,
    linear_steering,
    steering_features,
)

VEHICLE = VehicleParameters()
BEHAVIOUR = BehaviourParameters()


def _world_step(e, chi, v, theta_b, dt):
    """The world's step of vehicles on a lane along +x at y = 0 (e = y, chi = psi): its law, its bicycle."""
    n = e.shape[0]
    g = steering_features(np.zeros(n), chi, e, v, VEHICLE.length, BEHAVIOUR.speed_epsilon)
    steer = linear_steering(theta_b, g, VEHICLE.max_steering)
    nxt = bicycle_step(np.stack([np.zeros(n), e, v, chi], 1), np.zeros(n), steer, dt, VEHICLE)
    return nxt[:, 1], nxt[:, 3]


def _norm2(metric, e, chi):
    return metric[0, 0] * e**2 + 2 * metric[0, 1] * e * chi + metric[1, 1] * chi**2


@given(
    e=st.tuples(st.floats(-4.0, 4.0), st.floats(0.0, 3.0)),
    chi=st.tuples(st.floats(-0.9, 0.9), st.floats(0.0, 0.6)),
    v=st.tuples(st.floats(1.0, 35.0), st.floats(1.0, 3.0)),
    b1=st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)),
    b2=st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)),
    dt=st.floats(0.02, 0.3),
    table=st.booleans(),
    seed=st.integers(0, 2**31),
)
def test_contraction_factor_bounds_the_world_step(e, chi, v, b1, b2, dt, table, seed):
    """Every state, speed and gain of the box: ``||x+||_P^2 <= lambda ||x||_P^2`` through the world's own step.

    Boxes reach the steering bound (large offsets, headings, low speeds); the metric is a table's or a
    random one (the bound holds for any P); the box's corners are always among the samples.
    """
    rng = np.random.default_rng(seed)
    lo_b, hi_b = np.asarray(BEHAVIOUR.theta_b_prior[0]), np.asarray(BEHAVIOUR.theta_b_prior[1])
    g_lo = lo_b + (hi_b - lo_b) * np.array([min(b1), min(b2)])
    g_hi = lo_b + (hi_b - lo_b) * np.array([max(b1), max(b2)])
    v_box = (v[0], min(v[0] * v[1], VEHICLE.max_speed))
    v_box = (min(v_box), max(v_box))
    e_box, c_box = (e[0], e[0] + e[1]), (chi[0], chi[0] + chi[1])
    if table:
        speeds, metrics, _ = contraction_metrics(dt, VEHICLE, BEHAVIOUR)
        metric = metrics[int(np.argmin(np.abs(np.log(speeds / np.sqrt(v_box[0] * v_box[1])))))]
    else:
        a = rng.normal(size=(2, 2))
        metric = a @ a.T + 0.05 * np.eye(2)
    lam = contraction_factor(
        metric[None],
        *[(np.array([lo]), np.array([hi])) for lo, hi in (e_box, c_box, v_box)],
        (np.array([g_lo[0]]), np.array([g_hi[0]])),
        (np.array([g_lo[1] / v_box[1]]), np.array([g_hi[1] / v_box[0]])),
        dt,
        VEHICLE,
    )[0]
    assert lam > 0.0
    k = 400
    es, cs, vs = (rng.uniform(lo, hi, k) for lo, hi in (e_box, c_box, v_box))
    gains = rng.uniform(g_lo, g_hi, (k, 2))
    corners = np.array(np.meshgrid(*[[0, 1]] * 5, indexing="ij")).reshape(5, -1).T
    for j, (ie, ic, iv, i1, i2) in enumerate(corners):
        es[j], cs[j], vs[j] = e_box[ie], c_box[ic], v_box[iv]
        gains[j] = [(g_lo[0], g_hi[0])[i1], (g_lo[1], g_hi[1])[i2]]
    e1, c1 = _world_step(es, cs, vs, gains, dt)
    before, after = _norm2(metric, es, cs), _norm2(metric, e1, c1)
    assert np.all(after <= lam * before + 1e-12 * (1.0 + before))


def test_table_metrics_contract_on_moderate_boxes():
    """The tuned metrics make the bound a contraction (lambda < 1) on the boxes they are tuned for, dt = 0.1 s."""
    speeds, metrics, conversion = contraction_metrics(0.1, VEHICLE, BEHAVIOUR)
    lo_b, hi_b = BEHAVIOUR.theta_b_prior
    fast = speeds >= 3.0
    n = int(fast.sum())
    v = (speeds[fast] / 1.12, speeds[fast] * 1.12)
    lam = contraction_factor(
        metrics[fast],
        (np.full(n, -0.5), np.full(n, 0.5)),
        (np.full(n, -0.1), np.full(n, 0.1)),
        v,
        (np.full(n, lo_b[0]), np.full(n, hi_b[0])),
        (lo_b[1] / v[1], hi_b[1] / v[0]),
        0.1,
        VEHICLE,
    )
    assert np.all(lam < 1.0), lam
    assert np.all(np.diag(conversion) >= 1.0) and np.all(np.diag(conversion) < 1.0 + 1e-6)
    assert not metrics.flags.writeable


@given(
    lo=st.tuples(st.floats(-3, 3), st.floats(-1, 1)),
    width=st.tuples(st.floats(0, 2), st.floats(0, 1)),
    seed=st.integers(0, 2**31),
)
def test_radius_hull_and_conversion_are_sound(lo, width, seed):
    """The box lies in its radius's ellipse; the ellipse in its hull (both bases); conversions bound norms."""
    rng = np.random.default_rng(seed)
    speeds, metrics, conversion = contraction_metrics(0.1, VEHICLE, BEHAVIOUR)
    i, j = rng.integers(0, speeds.size, 2)
    metric = metrics[i][None]
    box_lo, box_hi = np.array([lo]), np.array([lo]) + np.array([width])
    rho = metric_radius(metric, box_lo, box_hi)
    pts = rng.uniform(box_lo[0], box_hi[0], (300, 2))
    assert np.all(np.sqrt(_norm2(metric[0], pts[:, 0], pts[:, 1])) <= rho[0])
    # points on the ellipse's boundary
    ang = rng.uniform(0, 2 * np.pi, 300)
    c = np.linalg.cholesky(metric[0])  # P = c c'
    ring = np.linalg.solve(c.T, np.stack([np.cos(ang), np.sin(ang)]) * rho[0]).T
    assert np.allclose(_norm2(metric[0], ring[:, 0], ring[:, 1]), rho[0] ** 2)
    half = ellipse_hull(metric, rho)[0]
    assert np.all(np.abs(ring) <= half)
    basis = rng.normal(size=(2, 2)) + 2 * np.eye(2)
    half_z = ellipse_hull(metric, rho, to_basis=np.linalg.inv(basis)[None])[0]
    assert np.all(np.abs(np.linalg.solve(basis, ring.T).T) <= half_z)
    unit = np.linalg.solve(c.T, np.stack([np.cos(ang), np.sin(ang)])).T  # ||x||_{P_i} = 1
    ratio = np.sqrt(_norm2(metrics[j], unit[:, 0], unit[:, 1]))
    assert np.all(ratio <= conversion[i, j])
    assert np.isinf(metric_radius(metric, np.array([[1.0, 0.0]]), np.array([[0.0, 1.0]]))[0])


def test_bad_input_is_a_typed_error():
    box = (np.zeros(1), np.ones(1))
    speed = (np.ones(1), np.ones(1))
    eye = np.eye(2)[None]
    with pytest.raises(DimensionError, match="metric"):
        contraction_factor(np.eye(2), box, box, speed, box, box, 0.1)
    with pytest.raises(InputError, match="v must"):
        contraction_factor(eye, box, box, (np.zeros(1), np.ones(1)), box, box, 0.1)
    with pytest.raises(InputError, match="dt"):
        contraction_factor(eye, box, box, speed, box, box, 0.0)
    with pytest.raises(DimensionError, match="chi"):
        contraction_factor(eye, box, (np.zeros(3), np.ones(3)), speed, box, box, 0.1)
    with pytest.raises(InputError, match="e must"):
        contraction_factor(eye, (np.ones(1), np.zeros(1)), box, speed, box, box, 0.1)
    with pytest.raises(InputError, match="positive definite"):
        contraction_factor(np.array([[[1.0, 2.0], [2.0, 1.0]]]), box, box, speed, box, box, 0.1)
    with pytest.raises(InputError, match="symmetric"):
        metric_radius(np.array([[[1.0, 0.1], [0.0, 1.0]]]), np.zeros((1, 2)), np.ones((1, 2)))
    with pytest.raises(DimensionError, match="lo, hi"):
        metric_radius(eye, np.zeros(2), np.ones(2))
    with pytest.raises(DimensionError, match="radius"):
        ellipse_hull(eye, np.ones(2))
    with pytest.raises(InputError, match="radius"):
        ellipse_hull(eye, np.array([np.nan]))
    with pytest.raises(DimensionError, match="to_basis"):
        ellipse_hull(eye, np.ones(1), to_basis=np.eye(2))
    with pytest.raises(InputError, match="dt"):
        contraction_metrics(-0.1)


@given(
    speeds=st.lists(st.tuples(st.floats(3.0, 35.0), st.floats(1.0, 1.6)), min_size=5, max_size=25),
    e0=st.floats(-1.5, 1.5),
    chi0=st.floats(-0.3, 0.3),
    dt=st.floats(0.03, 0.25),
    seed=st.integers(0, 2**31),
)
def test_a_radius_carried_over_switching_speeds_contains_the_world(speeds, e0, chi0, dt, seed):
    """The forecast's recursion over many steps: the radius contracted by the factor over the ellipse's
    hull, converted whenever the speed box moves to another metric, holds every state of the world's
    law and bicycle, each vehicle's speed switching inside each step's box and its gains fixed."""
    rng = np.random.default_rng(seed)
    nodes, metrics, conversion = contraction_metrics(dt, VEHICLE, BEHAVIOUR)
    lo_b, hi_b = np.asarray(BEHAVIOUR.theta_b_prior[0]), np.asarray(BEHAVIOUR.theta_b_prior[1])
    k = 200
    gains = rng.uniform(lo_b, hi_b, (k, 2))
    e = e0 + rng.uniform(-0.05, 0.05, k)
    chi = chi0 + rng.uniform(-0.02, 0.02, k)
    e[:2], chi[:2] = e0 - 0.05, chi0 + 0.02  # box corners
    box_lo, box_hi = np.array([[e0 - 0.05, chi0 - 0.02]]), np.array([[e0 + 0.05, chi0 + 0.02]])
    index, rho = 0, None
    for v_lo, ratio in speeds:
        v_hi = min(v_lo * ratio, VEHICLE.max_speed)
        node = int(np.argmin(np.abs(np.log(nodes) - 0.5 * np.log(v_lo * v_hi))))
        metric = metrics[node][None]
        if rho is None:
            rho = metric_radius(metric, box_lo, box_hi)[0]
        else:
            rho = rho * conversion[index, node]
            half = ellipse_hull(metric, np.array([rho]))[0]
            box_lo, box_hi = -half[None], half[None]
        index = node
        lam = contraction_factor(
            metric,
            (box_lo[:, 0], box_hi[:, 0]),
            (box_lo[:, 1], box_hi[:, 1]),
            (np.array([v_lo]), np.array([v_hi])),
            (np.array([lo_b[0]]), np.array([hi_b[0]])),
            (np.array([lo_b[1] / v_hi]), np.array([hi_b[1] / v_lo])),
            dt,
            VEHICLE,
        )[0]
        assert np.all(np.sqrt(_norm2(metric[0], e, chi)) <= rho * (1 + 1e-12))
        if not np.isfinite(lam):
            return
        e, chi = _world_step(e, chi, rng.uniform(v_lo, v_hi, k), gains, dt)
        rho = np.sqrt(lam) * rho
    assert np.all(np.sqrt(_norm2(metrics[index], e, chi)) <= rho * (1 + 1e-12))
