"""``minimaxplan demo``: a short end-to-end run of the library on its embedded default.

Simulates an uncertain 2D robot (a double integrator with unknown anisotropic
friction), learns a confidence set for the friction from the observed transitions,
discards the structural hypotheses that the data contradicts, checks Assumption 4 on
the velocity subsystem, and predicts an interval tube that contains every possible
future trajectory; then prints what happened.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from minimaxplan.models import Box, ConfidenceEllipsoidEstimator, UncertainLinearSystem, predict_tube
from minimaxplan.verify import check_assumption4, eliminate_models, feasible_parameter_box

DT = 0.1
FRICTION_PRIOR = Box([0.2, 0.2], [0.8, 0.8])
DISTURBANCE = Box([-0.1, -0.1], [0.1, 0.1])


def robot_system(input_gain: float = 1.0, isotropic: bool = False) -> UncertainLinearSystem:
    """The point-mass robot ``dpos = vel, dvel = -diag(theta) vel + g u + w`` (Euler, dt=0.1)."""
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    if isotropic:
        phi = np.zeros((1, 4, 4))
        phi[0, 2, 2] = phi[0, 3, 3] = -1.0
        theta = Box([0.2], [0.8])
    else:
        phi = np.zeros((2, 4, 4))
        phi[0, 2, 2] = phi[1, 3, 3] = -1.0
        theta = FRICTION_PRIOR
    B = np.vstack([np.zeros((2, 2)), input_gain * np.eye(2)])
    D = np.vstack([np.zeros((2, 2)), np.eye(2)])
    return UncertainLinearSystem.from_continuous(A, phi, B, D=D, w=DISTURBANCE, theta=theta, dt=DT)


def run(seed: int = 0, steps: int = 200, horizon: int = 20) -> dict:
    rng = np.random.default_rng(seed)
    truth = robot_system()
    theta_true = np.array([0.3, 0.7])
    hypotheses = {
        "anisotropic friction": truth,
        "isotropic friction": robot_system(isotropic=True),
        "wrong input gain (x0.6)": robot_system(input_gain=0.6),
    }
    # Simulate with persistently exciting random controls and disturbances at their extremes.
    states = np.zeros((steps + 1, 4))
    controls = rng.uniform(-1, 1, size=(steps, 2))
    for n in range(steps):
        w = rng.choice([-0.1, 0.1], size=2)
        states[n + 1] = truth.step(states[n], controls[n], theta_true, w)

    started = time.perf_counter()
    estimator = ConfidenceEllipsoidEstimator(2, sigma=0.1 * DT, lam=1.0, delta=0.1, bound=2.0)
    targets = states[1:] - states[:-1] @ truth.A0.T - controls @ truth.B.T
    for x, y in zip(states[:-1], targets):
        estimator.update(truth.regressor(x), y)
    ellipsoid = estimator.ellipsoid()
    selection = eliminate_models(list(hypotheses.values()), states, controls)
    box = feasible_parameter_box(truth, states, controls)
    velocity_block = truth.A(box.center)[2:, 2:]
    lmi = check_assumption4(velocity_block, form="discrete", D=truth.D[2:, :])
    plan = np.tile([1.0, -1.0], (horizon, 1))
    tube = predict_tube(truth, Box.from_center(states[-1], 0.0), plan, parameters=box)
    elapsed = time.perf_counter() - started
    # Check the guarantee on fresh realisations: parameters at the box corners, w at its extremes.
    contained = True
    for corner in box.vertices():
        x = states[-1].copy()
        path = [x]
        for u in plan:
            x = truth.step(x, u, corner, rng.choice([-0.1, 0.1], size=2))
            path.append(x)
        contained &= tube.contains(np.array(path))
    names = list(hypotheses)
    return {
        "theta_true": theta_true,
        "ellipsoid": ellipsoid,
        "box": box,
        "survivors": [names[i] for i in selection.survivors],
        "eliminated": {names[i]: cert for i, cert in selection.eliminated.items()},
        "lmi": lmi,
        "tube": tube,
        "contained": contained,
        "elapsed": elapsed,
        "steps": steps,
    }


def report(result: dict) -> str:
    box, ell, tube, lmi = result["box"], result["ellipsoid"], result["tube"], result["lmi"]
    ebox = ell.bounding_box()
    lines = [
        f"minimaxplan demo: {result['steps']} transitions of a 2D robot with unknown friction",
        f"  true friction theta*            = {np.round(result['theta_true'], 3).tolist()}",
        f"  confidence ellipsoid (1-delta=0.9) box: low {np.round(ebox.low, 3).tolist()} high {np.round(ebox.high, 3).tolist()}",
        f"  feasible parameter box (LP)    : low {np.round(box.low, 3).tolist()} high {np.round(box.high, 3).tolist()}",
        f"  surviving hypotheses           : {', '.join(result['survivors'])}",
    ]
    for name, cert in result["eliminated"].items():
        lines.append(f"  eliminated                     : {name} (inconsistency margin {cert.margin:.3g})")
    lines += [
        f"  Assumption 4 (velocity block)  : {lmi.status}, certified={lmi.certified}",
        f"  tube width after {tube.lower.shape[0] - 1} steps       : {np.round(tube.upper[-1] - tube.lower[-1], 3).tolist()}",
        f"  every sampled trajectory inside: {result['contained']}",
        f"  library time                   : {result['elapsed'] * 1e3:.1f} ms",
    ]
    return "\n".join(lines)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("demo", help="a short end-to-end run on the embedded default")
    parser.add_argument("--seed", type=int, default=0)
    parser.set_defaults(func=lambda args: print(report(run(seed=args.seed))) or 0)
