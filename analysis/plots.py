"""Figures of an experiment: trajectories with obstacles and predicted boxes, and the
Figure 6 analogue (suboptimality against the number of samples N)."""

from __future__ import annotations

import pathlib
from typing import Sequence

import numpy as np

from .experiment import EpisodeRecord

__all__ = ["plot_trajectories", "plot_suboptimality", "suboptimality_trend"]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_trajectories(records: Sequence[EpisodeRecord], path: str | pathlib.Path, *, title: str = "") -> pathlib.Path:
    """One panel per world seed: every method's path, the obstacles, the pedestrians'
    start positions and (robust method) a few predicted position boxes."""
    plt = _pyplot()
    from matplotlib.patches import Circle, Rectangle

    seeds = sorted({r.seed for r in records})
    fig, axes = plt.subplots(1, len(seeds), figsize=(5 * len(seeds), 5), squeeze=False)
    colors = {"robust": "tab:green", "nominal": "tab:orange", "oracle": "tab:blue", "dwa": "tab:red", "teb": "tab:purple"}
    for ax, seed in zip(axes[0], seeds):
        group = [r for r in records if r.seed == seed]
        world = group[0].extra.get("world", {})
        obstacles = world.get("obstacles", {})
        for c, rad in zip(obstacles.get("centers", []), obstacles.get("radii", [])):
            ax.add_patch(Circle(c, rad, color="0.6"))
        for p in world.get("pedestrians", {}).get("positions", []):
            ax.plot(*p, "k^", ms=7)
        if world:
            ax.plot(*world["start"], "ks", ms=7)
            ax.add_patch(Circle(world["goal"], world["params"]["goal_tolerance"], fill=False, ec="k", ls="--"))
        for r in group:
            trajectory = np.array(r.trajectory)
            if trajectory.size:
                ax.plot(trajectory[:, 0], trajectory[:, 1], color=colors.get(r.method, "k"), lw=1.5, label=f"{r.method} ({r.outcome})")
            for _, lower, upper in r.extra.get("plans", []):
                for lo, hi in zip(lower[1:], upper[1:]):
                    ax.add_patch(Rectangle(lo, hi[0] - lo[0], hi[1] - lo[1], fill=False, ec=colors["robust"], lw=0.4, alpha=0.6))
        ax.set_aspect("equal")
        ax.set_title(f"{group[0].scenario} world, seed {seed}")
        ax.legend(fontsize=7, loc="best")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out = pathlib.Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def suboptimality_trend(records: Sequence[EpisodeRecord], bins: int = 12) -> dict:
    """Bin the (N, suboptimality) points of all robust episodes by N.

    Returns the bin centres, mean and max per bin, and a least-squares fit of
    ``a + b log(N) / N`` (the shape of eq. (14)'s estimation term) to the means.
    """
    points = np.array([p for r in records for p in r.suboptimality], dtype=float).reshape(-1, 2)
    points = points[points[:, 0] > 0]
    if points.shape[0] == 0:
        return {"n": [], "mean": [], "max": [], "fit": None}
    edges = np.unique(np.geomspace(points[:, 0].min(), points[:, 0].max() + 1, bins + 1).round())
    centres, means, maxima = [], [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (points[:, 0] >= lo) & (points[:, 0] < hi)
        if sel.any():
            centres.append(float(np.sqrt(lo * hi)))
            means.append(float(points[sel, 1].mean()))
            maxima.append(float(points[sel, 1].max()))
    n = np.array(centres)
    design = np.stack([np.ones_like(n), np.log(n) / n], axis=1)
    coef, *_ = np.linalg.lstsq(design, np.array(means), rcond=None)
    return {"n": centres, "mean": means, "max": maxima, "fit": {"a": float(coef[0]), "b": float(coef[1])}}


def plot_suboptimality(records: Sequence[EpisodeRecord], path: str | pathlib.Path) -> pathlib.Path:
    """The Figure 6 analogue: mean and max suboptimality against N, with the fitted trend."""
    plt = _pyplot()
    trend = suboptimality_trend(records)
    fig, ax = plt.subplots(figsize=(6, 4))
    if trend["n"]:
        n = np.array(trend["n"])
        ax.plot(n, trend["mean"], "o-", label="mean over episodes")
        ax.plot(n, trend["max"], "s--", label="max over episodes")
        grid = np.geomspace(n.min(), n.max(), 100)
        fit = trend["fit"]
        ax.plot(grid, fit["a"] + fit["b"] * np.log(grid) / grid, "k:", label="fit a + b log(N)/N")
    ax.set_xscale("log")
    ax.set_xlabel("N, transitions observed")
    ax.set_ylabel("oracle value - discounted return to go")
    ax.set_title("Suboptimality of the robust planner")
    ax.legend()
    fig.tight_layout()
    out = pathlib.Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
