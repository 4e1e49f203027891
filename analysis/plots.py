"""Figures of an experiment: trajectories with obstacles, pedestrians and predicted boxes."""

from __future__ import annotations

import pathlib
from collections.abc import Sequence

import numpy as np

from .episode import EpisodeRecord

__all__ = ["plot_trajectories"]


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
    colors = {
        "robust": "tab:green",
        "nominal": "tab:orange",
        "oracle": "tab:blue",
        "dwa": "tab:red",
        "teb": "tab:purple",
    }
    for ax, seed in zip(axes[0], seeds):
        group = [r for r in records if r.seed == seed]
        world = group[0].extra.get("world", {})
        obstacles = world.get("obstacles", {})
        for c, rad in zip(obstacles.get("centers", []), obstacles.get("radii", [])):
            ax.add_patch(Circle(c, rad, color="0.6"))
        for p in world.get("pedestrians", {}).get("positions", []):
            ax.plot(*p, "k^", ms=7)
        if "start" in world and "goal" in world:  # a robot world's map
            ax.plot(*world["start"], "ks", ms=7)
            ax.add_patch(Circle(world["goal"], world["params"]["goal_tolerance"], fill=False, ec="k", ls="--"))
        planar = all(np.shape(r.trajectory)[1:] == (2,) for r in group if r.trajectory)
        for r in group:
            trajectory = np.array(r.trajectory)
            if trajectory.size:
                # planar positions as a path; any other dimension against the sub-step index
                x, y = (
                    (trajectory[:, 0], trajectory[:, 1]) if planar else (np.arange(len(trajectory)), trajectory[:, 0])
                )
                ax.plot(x, y, color=colors.get(r.method, "k"), lw=1.5, label=f"{r.method} ({r.outcome})")
            for _, lower, upper in r.extra.get("plans", []):
                for lo, hi in zip(lower[1:], upper[1:]):
                    ax.add_patch(
                        Rectangle(lo, hi[0] - lo[0], hi[1] - lo[1], fill=False, ec=colors["robust"], lw=0.4, alpha=0.6)
                    )
        if planar:
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
