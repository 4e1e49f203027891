"""Interval prediction against the reference predictor (highway-env's ``interval.LPV``).

Three figures, all measured in the same run:

1. tube width: on random Metzler continuous-time systems at a small dt, where the
   reference's Euler predictor is sound, the mean final width of our discrete-time
   tube (for the Euler-discretised plant, which both predict) over the reference's;
2. inclusion violations at a large dt (0.4): the share of random runs whose true
   trajectory leaves the predicted interval, for the reference and for ours;
3. speed of one predictor step (p = 4), as the reference's time over ours, for one
   box and for 1000 boxes (one batched call against 1000 ``LPV.step`` calls).

Writes benchmarks/results/prediction.md and .json. Needs the ``bench`` extra.
"""

from __future__ import annotations

import contextlib
import datetime
import io
import json
import pathlib
import platform
import time

import numpy as np
from highway_env.interval import LPV, polytope

from minimaxplan.models import Box, UncertainLinearSystem, predict_tube
from minimaxplan.models.continuous_predictor import predict_tube_continuous
from minimaxplan.models.prediction import IntervalPredictor

RESULTS = pathlib.Path(__file__).parent / "results"
SEED = 20261122
P, D_PARAMS = 4, 2


def random_metzler_model(rng, p=P, d=D_PARAMS, margin=(0.2, 1.5)):
    """Continuous-time (A, phi, B, D, w, theta) whose nominal matrix A(centre) is Metzler and Hurwitz.

    The diagonal is minus the row's off-diagonal sum minus a random margin (strict
    diagonal dominance), so the nominal plant is stable and widths stay bounded.
    """
    A = np.abs(rng.normal(size=(p, p))) * 0.5
    A[np.diag_indices(p)] = 0.0
    A[np.diag_indices(p)] = -A.sum(axis=1) - rng.uniform(*margin, size=p)
    phi = rng.normal(size=(d, p, p)) * 0.1
    B = rng.normal(size=(p, 1))
    D = rng.normal(size=(p, p)) * 0.5
    w = Box.from_center(np.zeros(p), 0.1)
    theta = Box.from_center(np.zeros(d), 1.0)  # centre 0: A_N = A, Metzler
    return A, phi, B, D, w, theta


def make_lpv(A, phi, B, D, w, theta, x0: Box) -> LPV:
    a0, da = polytope(lambda t: A + np.tensordot(t, phi, axes=1), np.array([theta.low, theta.high]))
    with contextlib.redirect_stdout(io.StringIO()):  # LPV prints when it cannot find a Metzler basis
        return LPV(
            x0=x0.center, a0=a0, da=da, b=B, d=D, omega_i=np.array([w.low, w.high]), x_i=np.array([x0.low, x0.high])
        )


def lpv_tube(lpv: LPV, controls, dt) -> tuple[np.ndarray, np.ndarray]:
    """The reference predictor's intervals in original coordinates, shape (H+1, p) each."""
    lower, upper = [lpv.x_i[0]], [lpv.x_i[1]]
    for u in controls:
        lpv.set_control(u[:, None])
        lpv.step(dt)
        box = lpv.change_coordinates(lpv.x_i_t, back=True, interval=True)
        lower.append(box[0])
        upper.append(box[1])
    return np.array(lower), np.array(upper)


def width_comparison(rng, runs=20, dt=0.01, horizon=300):
    ratios, corrected_ratios = [], []
    for _ in range(runs):
        A, phi, B, D, w, theta = random_metzler_model(rng)
        x0 = Box.from_center(rng.normal(size=P), 0.1)
        controls = rng.normal(size=(horizon, 1))
        ref_lower, ref_upper = lpv_tube(make_lpv(A, phi, B, D, w, theta, x0), controls, dt)
        system = UncertainLinearSystem.from_continuous(A, phi, B, D=D, w=w, theta=theta, dt=dt)
        ours = predict_tube(system, x0, controls)
        corrected = predict_tube_continuous(A, phi, B, D=D, w=w, x0=x0, controls=controls, dt=dt, parameters=theta)
        assert corrected.guaranteed  # dt is small enough for the Euler predictors to be sound
        ratios.append(np.mean(ours.widths[-1]) / np.mean(ref_upper[-1] - ref_lower[-1]))
        corrected_ratios.append(np.mean(corrected.widths[-1]) / np.mean(ref_upper[-1] - ref_lower[-1]))
    return {
        "runs": runs,
        "dt": dt,
        "horizon": horizon,
        "ratio_mean": float(np.mean(ratios)),
        "ratio_max": float(np.max(ratios)),
        "ratio_min": float(np.min(ratios)),
        "corrected_eq9_ratio_mean": float(np.mean(corrected_ratios)),
    }


def violation_count(rng, runs=200, dt=0.4, horizon=20):
    lpv_violations = ours_violations = condition_fails = 0
    for _ in range(runs):
        A, phi, B, D, w, theta = random_metzler_model(rng, margin=(0.2, 4.0))
        x0 = Box.from_center(rng.normal(size=P), 0.1)
        controls = rng.normal(size=(horizon, 1))
        system = UncertainLinearSystem.from_continuous(A, phi, B, D=D, w=w, theta=theta, dt=dt)
        condition_fails += not np.all(system.A0 >= 0)  # I + dt A_N >= 0 fails: Euler predictors may lose inclusion
        true_theta = rng.uniform(theta.low, theta.high)
        x = rng.uniform(x0.low, x0.high)
        states = [x]
        for u in controls:
            x = system.step(x, u, true_theta, np.where(rng.integers(0, 2, size=P) == 1, w.high, w.low))
            states.append(x)
        states = np.array(states)
        slack = 1e-9 * (1 + np.abs(states))
        ref_lower, ref_upper = lpv_tube(make_lpv(A, phi, B, D, w, theta, x0), controls, dt)
        lpv_violations += not (np.all(states >= ref_lower - slack) and np.all(states <= ref_upper + slack))
        ours_violations += not predict_tube(system, x0, controls).contains(states)
    return {
        "runs": runs,
        "dt": dt,
        "horizon": horizon,
        "lpv": int(lpv_violations),
        "ours": int(ours_violations),
        "condition_fails": int(condition_fails),
    }


def best_time(function, repeats=5, number=200) -> float:
    """Best mean time per call over `repeats` rounds of `number` calls."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(number):
            function()
        best = min(best, (time.perf_counter() - start) / number)
    return best


def speed(rng, dt=0.05, boxes=1000):
    A, phi, B, D, w, theta = random_metzler_model(rng)
    x0 = Box.from_center(rng.normal(size=P), 0.1)
    lpv = make_lpv(A, phi, B, D, w, theta, x0)
    lpv.set_control(np.array([[0.3]]))
    system = UncertainLinearSystem.from_continuous(A, phi, B, D=D, w=w, theta=theta, dt=dt)
    predictor = IntervalPredictor(system)
    lower, upper = predictor.enter(x0.low, x0.high)
    u = np.array([0.3])

    def lpv_step():
        lpv.x_i_t = np.array([x0.low, x0.high])  # keep the numbers bounded across repeats
        lpv.step(dt)

    t_lpv = best_time(lpv_step)
    t_ours = best_time(lambda: predictor.step(lower, upper, u))
    centres = rng.normal(size=(boxes, P))
    batch_lower, batch_upper = predictor.enter(centres - 0.1, centres + 0.1)
    batch_u = rng.normal(size=(boxes, 1))
    t_batch = best_time(lambda: predictor.step(batch_lower, batch_upper, batch_u), repeats=5, number=20)
    return {
        "p": P,
        "vertices": predictor.nvertices,
        "lpv_step_us": t_lpv * 1e6,
        "ours_step_us": t_ours * 1e6,
        "single_speedup": t_lpv / t_ours,
        "boxes": boxes,
        "lpv_boxes_ms": t_lpv * boxes * 1e3,
        "ours_batch_ms": t_batch * 1e3,
        "batch_speedup": t_lpv * boxes / t_batch,
    }


def main() -> dict:
    rng = np.random.default_rng(SEED)
    started = time.perf_counter()
    results = {"width": width_comparison(rng), "violations": violation_count(rng), "speed": speed(rng)}
    results["machine"] = (
        f"{platform.machine()} {platform.processor() or ''} {platform.python_implementation()} {platform.python_version()}".strip()
    )
    results["date"] = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    results["seconds"] = time.perf_counter() - started
    width, violations, spd = results["width"], results["violations"], results["speed"]
    lines = [
        "# Interval prediction vs highway-env `interval.LPV`",
        "",
        f"Machine: {results['machine']}; date: {results['date']}; seed {SEED}; run time {results['seconds']:.1f} s.",
        f"Systems: random Metzler continuous-time, p = {P}, d = {D_PARAMS} (box prior, 4 vertices), D w with |w| <= 0.1; "
        "ours predicts the forward-Euler discretisation, the plant both bound.",
        "",
        "| figure | reference (LPV) | ours | ratio |",
        "|---|---|---|---|",
        f"| mean final width, dt = {width['dt']}, {width['horizon']} steps, {width['runs']} systems (ours / LPV) | 1 | "
        f"{width['ratio_mean']:.4f} | mean {width['ratio_mean']:.4f}, min {width['ratio_min']:.4f}, max {width['ratio_max']:.4f} |",
        f"| runs leaving the interval, dt = {violations['dt']}, {violations['horizon']} steps | {violations['lpv']} / {violations['runs']} | "
        f"{violations['ours']} / {violations['runs']} | I + dt A_N >= 0 fails in {violations['condition_fails']} runs |",
        f"| one step, one box (LPV.step / ours) | {spd['lpv_step_us']:.1f} us | {spd['ours_step_us']:.1f} us | {spd['single_speedup']:.1f}x |",
        f"| one step, {spd['boxes']} boxes ({spd['boxes']} LPV.step / one batched call) | {spd['lpv_boxes_ms']:.2f} ms | "
        f"{spd['ours_batch_ms']:.3f} ms | {spd['batch_speedup']:.0f}x |",
        f"| mean final width, same runs, corrected eq. (9) with elementwise max (errata) / LPV | 1 | - | "
        f"{width['corrected_eq9_ratio_mean']:.4f} |",
        "",
        "LPV.step also advances its nominal state (one extra matrix-vector product); ours is the",
        "raw-array `IntervalPredictor.step` that planners call.",
    ]
    text = "\n".join(lines) + "\n"
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "prediction.md").write_text(text)
    (RESULTS / "prediction.json").write_text(json.dumps(results, indent=2) + "\n")
    return results


if __name__ == "__main__":
    main()
