"""The Figure 6 analogue: suboptimality of the robust planner against the number of samples N.

For each N, the robust planner learns only from N transitions of excitation data
recorded before the episode (model elimination and LP parameter boxes, then frozen),
and drives the robot for a fixed number of decisions from the start of a static world.
The oracle planner (OPD on the true friction, same K) drives the same world, whose
disturbance and measurement-noise sequences are identical for both (they are seeded by
the world, not by the actions). Suboptimality is the oracle's discounted return minus
the robust planner's over those decisions, ``r_i`` being the smallest true goal reward
over the sub-steps of decision i.
"""

from __future__ import annotations

import argparse
import json
import pathlib
from dataclasses import replace

import numpy as np

from minimaxplan.models.errors import InputError

from .episode import DEFAULT_CONFIG, LoopConfig
from .experiment import run_experiment

__all__ = ["suboptimality_study", "fit_trend", "plot_study", "register"]

DEFAULT_SAMPLES = (2, 5, 10, 20, 50, 100, 200, 400)


def fit_trend(ns, values) -> dict:
    """Least-squares fit of ``a + b log(N) / N`` (the shape of eq. (14)'s estimation term)."""
    n = np.asarray(ns, dtype=float)
    design = np.stack([np.ones_like(n), np.log(n) / n], axis=1)
    coef, *_ = np.linalg.lstsq(design, np.asarray(values, dtype=float), rcond=None)
    return {"a": float(coef[0]), "b": float(coef[1])}


def suboptimality_study(samples=DEFAULT_SAMPLES, *, episodes: int = 20, seed: int = 0, horizon: int = 24,
                        scenario: str = "static", workers: int | None = None, progress: bool = True,
                        config: LoopConfig = DEFAULT_CONFIG) -> dict:
    """Run the study; returns per-N mean, max and per-episode suboptimality, and the trend."""
    samples = [int(n) for n in samples]
    if not samples or min(samples) < 1:
        raise InputError(f"samples must be positive integers, got {samples}")
    base = replace(config, max_decisions=horizon)
    oracle = run_experiment([scenario], ["oracle"], episodes=episodes, seed=seed, config=base, workers=workers,
                            progress=progress)
    oracle_return = {r.seed: r.discounted_return for r in oracle.records}
    rows = []
    for n in samples:
        robust = run_experiment([scenario], ["robust"], episodes=episodes, seed=seed,
                                config=replace(base, prior_samples=n), workers=workers, progress=progress)
        gaps = [oracle_return[r.seed] - r.discounted_return for r in robust.records]
        outcomes = [r.outcome for r in robust.records]
        rows.append({"n": n, "mean": float(np.mean(gaps)), "max": float(np.max(gaps)), "min": float(np.min(gaps)),
                     "per_episode": gaps, "failures": sum(o not in ("goal", "horizon") for o in outcomes)})
    return {"scenario": scenario, "episodes": episodes, "horizon_decisions": horizon, "seed": seed,
            "rows": rows, "fit": fit_trend([r["n"] for r in rows], [r["mean"] for r in rows])}


def plot_study(study: dict, path) -> pathlib.Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = np.array([r["n"] for r in study["rows"]], dtype=float)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(n, [r["mean"] for r in study["rows"]], "o-", label="mean over episodes")
    ax.plot(n, [r["max"] for r in study["rows"]], "s--", label="max over episodes")
    grid = np.geomspace(n.min(), n.max(), 200)
    fit = study["fit"]
    ax.plot(grid, fit["a"] + fit["b"] * np.log(grid) / grid, "k:", label="fit a + b log(N)/N")
    ax.set_xscale("log")
    ax.set_xlabel("N, transitions observed before planning")
    ax.set_ylabel("oracle return - robust return")
    ax.set_title(f"Suboptimality over {study['horizon_decisions']} decisions, {study['episodes']} episodes")
    ax.legend()
    fig.tight_layout()
    out = pathlib.Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def markdown(study: dict) -> str:
    lines = ["| N | mean suboptimality | max | min | failures |", "|---:|---:|---:|---:|---:|"]
    for r in study["rows"]:
        lines.append(f"| {r['n']} | {r['mean']:.4f} | {r['max']:.4f} | {r['min']:.4f} | {r['failures']}/{study['episodes']} |")
    fit = study["fit"]
    lines.append(f"\nTrend fit: suboptimality ~ {fit['a']:.4f} + {fit['b']:.4f} log(N)/N")
    return "\n".join(lines) + "\n"


def _run(args: argparse.Namespace) -> int:
    study = suboptimality_study(args.samples, episodes=args.episodes, seed=args.seed, horizon=args.horizon,
                                workers=args.workers, progress=not args.no_progress)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "suboptimality.json").write_text(json.dumps(study, indent=2) + "\n")
    (out / "suboptimality.md").write_text(markdown(study))
    plot_study(study, out / "suboptimality.png")
    print(markdown(study))
    print(f"outputs written to {out}/")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("suboptimality", help="Figure 6: suboptimality against the number of samples N")
    parser.add_argument("--samples", type=lambda s: [int(x) for x in s.split(",")], default=list(DEFAULT_SAMPLES),
                        help="comma-separated values of N")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--horizon", type=int, default=24, help="decisions per episode")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("out/suboptimality"))
    parser.add_argument("--no-progress", action="store_true")
    parser.set_defaults(func=_run)
