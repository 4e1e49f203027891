"""Probe: is there a contraction metric for a lane change at highway-env's 5 Hz step?

`forecast_traffic` bounds each fine lateral unit by an ellipse ``x' P x <= rho^2`` of the
LinearVehicle's ``x = (e, chi)`` (`scenarios.lateral_contraction`), with ``P`` from a table
tuned for lane keeping (``|e| <= 0.5`` m, ``|chi| <= 0.1`` rad). A lane-change cohort's
fresh entries start about a lane width from the lane they steer to; its radius is renewed
by each one, and on highway-fast-v0 the ellipse through such a start allows more heading
error than `CHI_MAX`, so the row leaves the fine model (docs/highway-env.md).

This probe asks whether another metric would keep such a row fine: over a grid of
``P = [[1, c sqrt(r)], [c sqrt(r), r]]`` it evaluates `contraction_factor` on a
lane-change box (``|e| <= 4.2`` m, ``|chi| <= X``, a speed box, highway-env's
``LinearVehicle`` gains, ``dt = 0.2`` s) and reports, among the metrics with
``lambda < 1`` whose ellipse through a lane-change start (``e`` in [3.9, 4.1] m,
``|chi| <= 0.02`` rad) stays inside ``|chi| <= X`` (so that the bound is self-consistent),
the smallest heading half-width of that ellipse, next to the library's table metric at
the same speed. It changes nothing in the library; its figures are a design input.

Second table: why a box bound alone cannot keep the row fine at this step. From the same
start, the per-step box hull of the lateral step's image (sampled on a grid of 9 values
per coordinate of ``(e, chi, v, theta_b1, theta_b2)``: an inner approximation of the exact
hull, so any sound box iteration in the same coordinates is at least as wide), in the lane frame and in
the eigenbasis of the loop linearised at the box's centre; the heading half-width at 1, 3
and 5 s.

Writes benchmarks/results/lane_change_metric.md. Needs the ``vehicle`` extra (highway-env's
``LinearVehicle`` constants). Usage: ``python benchmarks/probe_lane_change_metric.py``.
"""

from __future__ import annotations

import datetime
import pathlib

import numpy as np

from minimaxplan.scenarios.highway_env_adapter import require_highway_env
from minimaxplan.scenarios.lateral_contraction import (
    contraction_factor,
    contraction_metrics,
    ellipse_hull,
    metric_radius,
)
from minimaxplan.scenarios.vehicles import BehaviourParameters, VehicleParameters

RESULTS = pathlib.Path(__file__).parent / "results"
#: highway-fast-v0's simulation step, s.
DT = 0.2
#: Speed boxes (m/s) and heading bounds X (rad) of the lane-change box.
SPEED_BOXES = ((23.0, 27.0), (20.0, 30.0), (15.0, 25.0))
HEADING_BOUNDS = (0.3, 0.5, 0.7, 1.0)
#: Largest |e| of the box, m (a lane of 4 m and the start's spread).
OFFSET = 4.2
#: A lane-change start: (e, chi) box.
START = (np.array([3.9, -0.02]), np.array([4.1, 0.02]))


def _candidates() -> np.ndarray:
    r = np.geomspace(1e-3, 1e3, 61)
    c = np.linspace(-0.98, 0.98, 99)
    rr, cc = np.meshgrid(r, c, indexing="ij")
    cand = np.empty((rr.size, 2, 2))
    cand[:, 0, 0], cand[:, 1, 1] = 1.0, rr.ravel()
    cand[:, 0, 1] = cand[:, 1, 0] = cc.ravel() * np.sqrt(rr.ravel())
    return cand


def _lateral_step(e, chi, v, b1, b2, vehicle: VehicleParameters):
    """The LinearVehicle's lateral step on a straight lane (`scenarios.lateral_contraction`'s equations)."""
    delta = np.clip(-(vehicle.length / v) * (b1 * chi + b2 * e / v), -vehicle.max_steering, vehicle.max_steering)
    beta = np.arctan(np.tan(delta) / 2.0)
    return e + v * DT * np.sin(chi + beta), chi + (2.0 * v * DT / vehicle.length) * np.sin(beta)


def _hull_growth(speeds, gains, vehicle: VehicleParameters, basis: np.ndarray) -> list[float]:
    """Heading half-width (rad) of the sampled box-hull iteration in ``basis`` (x = basis z) at 1, 3 and 5 s."""
    inverse = np.linalg.inv(basis)
    corners = np.array(np.meshgrid(*zip(START[0], START[1]), indexing="ij")).reshape(2, -1)
    z = inverse @ corners
    z_box = [(z[i].min(), z[i].max()) for i in range(2)]
    widths = []
    for step in range(1, int(round(5.0 / DT)) + 1):
        grid = [np.linspace(lo, hi, 9) for lo, hi in (*z_box, speeds, gains[0], gains[1])]
        z1, z2, v, b1, b2 = np.meshgrid(*grid, indexing="ij")
        e, chi = basis[0, 0] * z1 + basis[0, 1] * z2, basis[1, 0] * z1 + basis[1, 1] * z2
        e, chi = _lateral_step(e, chi, v, b1, b2, vehicle)
        nz = inverse[0, 0] * e + inverse[0, 1] * chi, inverse[1, 0] * e + inverse[1, 1] * chi
        z_box = [(float(c.min()), float(c.max())) for c in nz]
        if step in (int(round(1.0 / DT)), int(round(3.0 / DT)), int(round(5.0 / DT))):
            zc = np.array(np.meshgrid(*z_box, indexing="ij")).reshape(2, -1)
            widths.append(float(np.abs(basis[1] @ zc).max()))
    return widths


def _eigenbasis(speeds, gains, vehicle: VehicleParameters) -> np.ndarray:
    """Eigenvectors of the lateral step's Jacobian at the origin, speed and gains at their centres."""
    v, b1, b2 = np.mean(speeds), np.mean(gains[0]), np.mean(gains[1])
    eps, jac = 1e-6, np.empty((2, 2))
    for j in range(2):
        x = np.zeros(2)
        x[j] = eps
        plus, minus = _lateral_step(*x, v, b1, b2, vehicle), _lateral_step(*(-x), v, b1, b2, vehicle)
        jac[:, j] = (np.array(plus) - np.array(minus)) / (2 * eps)
    return np.linalg.eig(jac)[1].real


def _start_extent(metrics: np.ndarray) -> np.ndarray:
    """Half-widths (e, chi) of the ellipse of each metric through the lane-change start, shape (n, 2)."""
    n = metrics.shape[0]
    rho = metric_radius(metrics, np.tile(START[0], (n, 1)), np.tile(START[1], (n, 1)))
    return ellipse_hull(metrics, rho)


def main() -> list[dict]:
    hw = require_highway_env()
    cls = hw.vehicle.behavior.LinearVehicle
    vehicle = VehicleParameters(
        length=float(cls.LENGTH),
        width=float(cls.WIDTH),
        max_speed=float(cls.MAX_SPEED),
        max_steering=float(cls.MAX_STEERING_ANGLE),
    )
    b_lo, b_hi = (np.asarray(r, dtype=float) for r in cls.STEERING_RANGE)
    behaviour = BehaviourParameters(
        theta_b_nominal=tuple(float(v) for v in (b_lo + b_hi) / 2),
        theta_b_spread=tuple(float(v) for v in (b_hi - b_lo) / 2),
    )
    cand = _candidates()
    extents = _start_extent(cand)
    speeds, table, _ = contraction_metrics(DT, vehicle, behaviour)
    rows = []
    for v_lo, v_hi in SPEED_BOXES:
        node = int(np.argmin(np.abs(np.log(speeds / np.sqrt(v_lo * v_hi)))))
        library = _start_extent(table[node][None])[0]
        for bound in HEADING_BOUNDS:
            lam = contraction_factor(
                cand,
                (-OFFSET, OFFSET),
                (-bound, bound),
                (v_lo, v_hi),
                (b_lo[0], b_hi[0]),
                (b_lo[1] / v_hi, b_hi[1] / v_lo),
                DT,
                vehicle,
            )
            ok = (lam < 1.0) & (extents[:, 1] <= bound)
            best = int(np.flatnonzero(ok)[np.argmin(extents[ok, 1])]) if ok.any() else None
            rows.append(
                {
                    "speeds": (v_lo, v_hi),
                    "heading_bound": bound,
                    "contracting": int(np.sum(lam < 1.0)),
                    "min_lambda": float(lam.min()),
                    "best_chi": None if best is None else float(extents[best, 1]),
                    "best_e": None if best is None else float(extents[best, 0]),
                    "best_lambda": None if best is None else float(lam[best]),
                    "library_node": float(speeds[node]),
                    "library_chi": float(library[1]),
                    "library_e": float(library[0]),
                }
            )
    growth = []
    gains = ((b_lo[0], b_hi[0]), (b_lo[1], b_hi[1]))
    for box in SPEED_BOXES:
        growth.append(
            {
                "speeds": box,
                "lane_frame": _hull_growth(box, gains, vehicle, np.eye(2)),
                "eigenbasis": _hull_growth(box, gains, vehicle, _eigenbasis(box, gains, vehicle)),
            }
        )
    _write(rows, growth)
    return rows + growth


def _write(rows: list[dict], growth: list[dict]) -> None:
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = [
        "# A contraction metric for a lane change at highway-env's 5 Hz step (probe)",
        "",
        f"Measured {stamp} by `benchmarks/probe_lane_change_metric.py` (see its docstring): {len(_candidates())} "
        f"candidate metrics, the lane-change box |e| <= {OFFSET} m, highway-env's `LinearVehicle` gains, dt = {DT} s. "
        "Best: among the metrics with lambda < 1 on the box whose ellipse through the lane-change start stays inside "
        "|chi| <= X, the smallest heading half-width of that ellipse. Library: the table metric of "
        "`contraction_metrics` nearest the box's speeds (tuned for lane keeping), its ellipse through the same start.",
        "",
        "| speeds (m/s) | X (rad) | metrics with lambda < 1 | smallest lambda | best: chi, e half-widths (rad, m), "
        "lambda | library metric (node m/s): chi, e half-widths |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        best = "none" if r["best_chi"] is None else f"{r['best_chi']:.3f}, {r['best_e']:.2f}, {r['best_lambda']:.3f}"
        lines.append(
            f"| {r['speeds'][0]:g}-{r['speeds'][1]:g} | {r['heading_bound']:g} | {r['contracting']} | "
            f"{r['min_lambda']:.3f} | {best} | ({r['library_node']:.1f}) {r['library_chi']:.3f}, "
            f"{r['library_e']:.2f} |"
        )
    lines += [
        "",
        "Box iteration from the same start (the sampled per-step hull: any sound box iteration in the same "
        "coordinates is at least this wide): the heading half-width at 1 / 3 / 5 s, rad.",
        "",
        "| speeds (m/s) | lane frame | eigenbasis of the linearised loop |",
        "|---|---|---|",
    ]
    for g in growth:
        lines.append(
            f"| {g['speeds'][0]:g}-{g['speeds'][1]:g} | {' / '.join(f'{w:.2f}' for w in g['lane_frame'])} | "
            f"{' / '.join(f'{w:.3g}' for w in g['eigenbasis'])} |"
        )
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "lane_change_metric.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    for row in main():
        print(row)
