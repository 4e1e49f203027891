"""``minimaxplan demo``: a short end-to-end run of the library on its embedded default.

Part 1 walks through the pipeline once: it simulates an uncertain 2D robot (a double
integrator with unknown anisotropic friction), learns a confidence set for the
friction, discards the structural hypotheses that the data contradicts, checks
Assumption 4 on the velocity subsystem, and predicts an interval tube that contains
every possible future trajectory. Part 2 is a short version of the paper's experiments:
5 episodes per method in every registered world (the robot's static and pedestrian
worlds, the road's highway and T-junction), the Table 3 layout printed, the trajectory
and speed/heading plots and an animated GIF of the robust method among pedestrians
written to ``out/demo``.
"""

from __future__ import annotations

import argparse
import pathlib
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

from .arguments import Subcommand, count, output_directory, report_error

if TYPE_CHECKING:
    from .episode import EpisodeRecord

__all__ = [
    "DT",
    "run",
    "report",
    "COMMAND",
]

#: Time step of the demo's robot, in seconds.
DT = 0.1


def run(seed: int = 0, steps: int = 200, horizon: int = 20) -> dict:
    """Part 1 of the demo: learn, select, certify and predict on a simulated robot.

    Parameters
    ----------
    seed : int
        Seed of the controls, disturbances and sampled trajectories (>= 0).
    steps : int
        Transitions simulated for learning (>= 1).
    horizon : int
        Steps of the predicted interval tube (>= 1).

    Returns
    -------
    dict
        ``theta_true``, ``ellipsoid`` (confidence ellipsoid), ``box`` (LP feasible
        parameter box), ``survivors`` and ``eliminated`` (hypothesis names, the latter
        with certificates), ``lmi`` (Assumption 4 on the velocity block), ``tube``,
        ``contained`` (every sampled trajectory inside the tube), ``elapsed`` (seconds
        of library time) and ``steps``.

    Raises
    ------
    InputError
        If ``seed``, ``steps`` or ``horizon`` is out of range.

    Notes
    -----
    The confidence set is that of eq. (3)-(5), the tube the interval predictor of
    Remark 2 (inclusion property (7)); Assumption 4 is the LMI of Section III.
    """
    import numpy as np

    from minimaxplan.models import Box, ConfidenceEllipsoidEstimator, predict_tube
    from minimaxplan.models.validation import as_count
    from minimaxplan.scenarios import robot_hypotheses
    from minimaxplan.verify import check_assumption4, eliminate_models, feasible_parameter_box

    seed = as_count("seed", seed, minimum=0)
    steps = as_count("steps", steps)
    horizon = as_count("horizon", horizon)
    rng = np.random.default_rng(seed)
    hypotheses = {name: system for name, system in robot_hypotheses(DT)}
    truth = hypotheses["anisotropic friction"]
    theta_true = np.array([0.3, 0.7])
    # Simulate with persistently exciting random controls and uniform disturbances.
    states = np.zeros((steps + 1, 4))
    controls = rng.uniform(-1, 1, size=(steps, 2))
    for n in range(steps):
        w = rng.uniform(truth.w.low, truth.w.high)
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
            x = truth.step(x, u, corner, rng.choice([-1.0, 1.0], size=2) * truth.w.high)
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
    """Part 1's result as the lines the demo prints.

    Parameters
    ----------
    result : dict
        A `run` result.

    Returns
    -------
    str
        One line per fact, without a final newline.
    """
    import numpy as np

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


def _run(args: argparse.Namespace) -> int:
    from minimaxplan.models import MinimaxplanError

    from .animate import animate_episode
    from .experiment import markdown_table, run_experiment, supported_methods, write_outputs
    from .plots import plot_experiment
    from .registry import default_scenario_names

    print(report(run(seed=args.seed)), flush=True)
    if args.episodes == 0:
        return 0
    print(f"\nShort experiment: {args.episodes} episodes per method in each world (paper: 100)", flush=True)
    scenarios = default_scenario_names()
    try:
        methods = supported_methods(scenarios)
        result = run_experiment(scenarios, methods, episodes=args.episodes, seed=args.seed, workers=args.workers)
        out = write_outputs(result, args.out)
        plot_experiment(result.records, out, scenarios=scenarios)
        animated = _animated_record(result.records, args.seed)
        if animated is not None:
            gif = animate_episode(animated, out / f"episode_{animated.scenario}_{animated.method}_{animated.seed}.gif")
    except MinimaxplanError as exc:
        return report_error("demo", exc)
    print(markdown_table(result.summary) + f"\nWall time of the run: {result.wall_time_s:.1f} s\n")
    print(f"plots and per-episode data written to {out}/")
    if animated is not None:
        print(f"animation of {animated.method} in the {animated.scenario} world, seed {animated.seed}: {gif}")
    return 0


def _animated_record(records: Sequence[EpisodeRecord], seed: int) -> EpisodeRecord | None:
    """The episode the demo animates: the robust method among pedestrians, world seed ``seed``
    (else the first robust episode, else none)."""
    robust = [r for r in records if r.method == "robust"]
    chosen = [r for r in robust if r.scenario == "pedestrian" and r.seed == seed] or robust
    return chosen[0] if chosen else None


def _add_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=count(0), default=0, help="seed of part 1 and world seed of part 2 (>= 0)")
    parser.add_argument(
        "--episodes", type=count(0), default=5, help="episodes per method and world (>= 0; 0: part 1 only)"
    )
    parser.add_argument("--workers", type=count(1), default=None, help="local processes (>= 1; default: all cores)")
    parser.add_argument("--out", type=output_directory, default=pathlib.Path("out/demo"), help="output directory")


COMMAND = Subcommand(
    "demo",
    help="a short end-to-end run on the embedded default",
    description="Part 1: learn, select, certify and predict on a simulated robot. Part 2: a short "
    "experiment, EPISODES per method in every registered world (e.g. 5 x 2 worlds x 5 methods = 50 "
    "episodes with the defaults), plots written to OUT.",
    epilog="Exit codes: 0 done; 2 a bad option (one line on stderr, before any work).",
    add_options=_add_options,
    run=_run,
)
