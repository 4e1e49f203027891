"""Generate examples/robot_data.csv: one trajectory of the planar robot (seeded, reproducible).

The plant is the "anisotropic friction" hypothesis of robot_hypotheses.toml with the
true friction theta* = (0.4, 1.1); controls are uniform on [-1, 1]^2 (persistently
exciting) and disturbances uniform on the box w of the model file. Run

    python examples/make_robot_data.py [--steps 120] [--seed 0] [--out examples/robot_data.csv]
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

from minimaxplan.analysis.model_file import load_model_file

HERE = pathlib.Path(__file__).resolve().parent
TRUE_HYPOTHESIS = "anisotropic friction"
TRUE_THETA = np.array([0.4, 1.1])


def make_robot_data(steps: int = 120, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """States (steps+1, 4) and controls (steps, 2) of the true plant, from x0 = 0."""
    system = load_model_file(HERE / "robot_hypotheses.toml").select(TRUE_HYPOTHESIS).systems[0]
    rng = np.random.default_rng(seed)
    controls = rng.uniform(-1.0, 1.0, size=(steps, system.ninputs))
    disturbances = rng.uniform(system.w.low, system.w.high, size=(steps, system.ndisturbances))
    states = np.zeros((steps + 1, system.nstates))
    for n in range(steps):
        states[n + 1] = system.step(states[n], controls[n], TRUE_THETA, disturbances[n])
    return states, controls


def write_csv(path, states: np.ndarray, controls: np.ndarray) -> None:
    """One row per time step: x0..x{p-1}, u0..u{q-1}; the last row's controls are left empty."""
    p, q = states.shape[1], controls.shape[1]
    lines = [",".join([f"x{i}" for i in range(p)] + [f"u{j}" for j in range(q)])]
    for n, state in enumerate(states):
        control = controls[n] if n < len(controls) else [None] * q
        cells = [repr(float(v)) for v in state] + ["" if v is None else repr(float(v)) for v in control]
        lines.append(",".join(cells))
    pathlib.Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=120)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=pathlib.Path, default=HERE / "robot_data.csv")
    args = parser.parse_args()
    states, controls = make_robot_data(args.steps, args.seed)
    write_csv(args.out, states, controls)
    print(f"wrote {args.out}: {len(controls)} transitions")


if __name__ == "__main__":
    main()
