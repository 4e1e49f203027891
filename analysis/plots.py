"""Figures of an experiment: trajectories (with obstacles, pedestrians and predicted boxes)
and the robot's speed and heading over time (the paper's Figures 3 and 4).

Every figure is built by a ``*_figure`` function that returns the matplotlib `Figure`
(what the tests inspect) and written by the matching ``plot_*`` function.
"""

from __future__ import annotations

import pathlib
from collections.abc import Sequence
from typing import Any

import numpy as np

from .episode import EpisodeRecord
from .figures import pyplot, save_png

__all__ = [
    "METHOD_STYLES",
    "method_style",
    "trajectory_figure",
    "plot_trajectories",
    "motion_figure",
    "plot_motion",
    "plot_experiment",
    "speed_and_heading",
]

#: Line style of every robot method: colour, dash pattern, width and drawing order, chosen
#: so that methods on the same path stay apart (oracle wide and pale under nominal's dashes).
METHOD_STYLES: dict[str, dict[str, Any]] = {
    "oracle": {"color": "tab:blue", "ls": "-", "lw": 4.0, "alpha": 0.45, "zorder": 3},
    "nominal": {"color": "tab:orange", "ls": (0, (5, 2)), "lw": 2.6, "alpha": 1.0, "zorder": 5},
    "robust": {"color": "tab:green", "ls": "-", "lw": 1.2, "alpha": 1.0, "zorder": 6},
    "dwa": {"color": "tab:red", "ls": "-.", "lw": 1.5, "alpha": 1.0, "zorder": 4},
    "teb": {"color": "tab:purple", "ls": ":", "lw": 2.0, "alpha": 1.0, "zorder": 4},
}
#: Speeds below this (m/s) have no meaningful heading: the heading is not drawn there.
HEADING_MIN_SPEED = 0.05
PEDESTRIAN_BOX_COLOR = "tab:pink"


def method_style(method: str) -> dict[str, Any]:
    """The line style of ``method`` (a grey solid line for a method not in `METHOD_STYLES`).

    Parameters
    ----------
    method : str
        A registered method name.

    Returns
    -------
    dict
        Keyword arguments of `matplotlib.axes.Axes.plot`: ``color``, ``ls``, ``lw``,
        ``alpha``, ``zorder``.
    """
    return dict(METHOD_STYLES.get(method, {"color": "0.3", "ls": "-", "lw": 1.5, "alpha": 1.0, "zorder": 4}))


def _pedestrian_paths(group: Sequence[EpisodeRecord]) -> np.ndarray:
    """The pedestrians' positions per sub-step, shape (steps, m, 2), from the longest episode
    (they ignore the robot, so every method of a seed sees the same walk)."""
    longest = max((np.asarray(r.trace.get("pedestrians", []), dtype=float) for r in group), key=len, default=None)
    if longest is None or longest.ndim != 3 or longest.shape[1] == 0:
        return np.zeros((0, 0, 2))
    return longest


def _draw_map(ax, group: Sequence[EpisodeRecord], handles: dict) -> None:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle, Patch

    world = group[0].extra.get("world", {})
    obstacles = world.get("obstacles", {})
    for c, rad in zip(obstacles.get("centers", []), obstacles.get("radii", [])):
        ax.add_patch(Circle(c, rad, color="0.6", zorder=1))
    if obstacles.get("centers"):
        handles.setdefault("static obstacle", Patch(color="0.6"))
    if "start" in world and "goal" in world:  # a robot world's map
        ax.plot(*world["start"], "ks", ms=7, zorder=7)
        handles.setdefault("start", Line2D([], [], color="k", marker="s", ls="none"))
        tolerance = world.get("params", {}).get("goal_tolerance", 0.5)
        ax.add_patch(Circle(world["goal"], tolerance, fill=False, ec="k", ls="--", zorder=7))
        handles.setdefault("goal region", Line2D([], [], color="k", marker="o", mfc="none", ls="--", ms=9))
    paths = _pedestrian_paths(group)
    for j in range(paths.shape[1]):
        ax.plot(paths[:, j, 0], paths[:, j, 1], color="k", ls=":", lw=1.0, zorder=2, gid="pedestrian path")
        ax.plot(*paths[0, j], "k^", ms=7, zorder=7)
        ax.annotate(
            "",
            xy=paths[-1, j],
            xytext=paths[max(0, len(paths) - 4), j],
            arrowprops={"arrowstyle": "->", "color": "k", "lw": 1.0},
            zorder=7,
        )
    if paths.shape[1]:
        handles.setdefault("pedestrian path (true)", Line2D([], [], color="k", ls=":", lw=1.0))
        handles.setdefault("pedestrian start", Line2D([], [], color="k", marker="^", ls="none"))


def _draw_collision(ax, record: EpisodeRecord, trajectory: np.ndarray, handles: dict) -> None:
    from matplotlib.lines import Line2D

    if record.outcome != "collision" or not trajectory.size:
        return
    ax.plot(*trajectory[-1], marker="X", color="red", mec="k", ms=11, ls="none", zorder=9, gid="collision")
    handles.setdefault("collision", Line2D([], [], marker="X", color="red", mec="k", ms=9, ls="none"))
    peds = np.asarray(record.trace.get("pedestrians", []), dtype=float)
    if peds.ndim == 3 and peds.shape[1]:
        ax.plot(peds[-1, :, 0], peds[-1, :, 1], "o", mfc="none", mec="red", ms=9, zorder=9)
        handles.setdefault("pedestrians at the collision", Line2D([], [], marker="o", mfc="none", mec="red", ls="none"))


def _draw_predicted_boxes(ax, record: EpisodeRecord, handles: dict) -> None:
    from matplotlib.patches import Patch, Rectangle

    color = method_style(record.method)["color"]
    shown = {int(t) for t, _, _ in record.extra.get("plans", [])}
    for _, lower, upper in record.extra.get("plans", []):
        for lo, hi in zip(lower[1:], upper[1:]):
            ax.add_patch(Rectangle(lo, hi[0] - lo[0], hi[1] - lo[1], fill=False, ec=color, lw=0.4, alpha=0.6))
    if record.extra.get("plans"):
        handles.setdefault(f"{record.method}: predicted robot boxes", Patch(fill=False, ec=color, lw=0.8))
    drew = False
    for decision in record.extra.get("decisions", []):
        if decision["step"] not in shown:
            continue
        lower, upper = np.asarray(decision["pedestrian_lower"]), np.asarray(decision["pedestrian_upper"])
        if lower.ndim != 3 or lower.shape[1] == 0:
            continue
        for k in (len(lower) // 2, len(lower) - 1):  # the middle and the end of the plan's horizon
            for lo, hi in zip(lower[k], upper[k]):
                ax.add_patch(
                    Rectangle(lo, hi[0] - lo[0], hi[1] - lo[1], fill=False, ec=PEDESTRIAN_BOX_COLOR, lw=0.6, alpha=0.7)
                )
                drew = True
    if drew:
        handles.setdefault(
            f"{record.method}: predicted pedestrian boxes", Patch(fill=False, ec=PEDESTRIAN_BOX_COLOR, lw=0.8)
        )


def _identical_paths(group: Sequence[EpisodeRecord]) -> list[list[str]]:
    """The methods whose paths coincide exactly (lines drawn on top of each other), in groups."""
    paths: dict[tuple, list[str]] = {}
    for r in group:
        if r.trajectory:
            paths.setdefault(tuple(r.trajectory), []).append(r.method)
    return [methods for methods in paths.values() if len(methods) > 1]


def trajectory_figure(records: Sequence[EpisodeRecord], *, title: str = "") -> Any:
    """One panel per world seed: every method's path and what it met.

    Parameters
    ----------
    records : sequence of EpisodeRecord
        Episodes of one scenario (any methods and seeds); one panel per seed.
    title : str
        Figure title (none if empty).

    Returns
    -------
    matplotlib.figure.Figure
        Axes in metres; one line per method (styles `METHOD_STYLES`, labelled with the
        outcome; methods whose paths coincide are named in the panel's corner), the
        static discs, start, goal region, the pedestrians' true paths and
        starts, a cross where an episode ended in a collision (and the pedestrians then),
        and the robust method's predicted position boxes and the pedestrians' predicted
        boxes it planned against (every eighth decision, eqs. (16)-(18)). One legend
        below the panels names every kind of mark.
    """
    plt = pyplot()
    seeds = sorted({r.seed for r in records})
    fig, axes = plt.subplots(1, max(1, len(seeds)), figsize=(max(7.5, 5 * len(seeds)), 5.6), squeeze=False)
    handles: dict = {}
    for ax, seed in zip(axes[0], seeds):
        group = [r for r in records if r.seed == seed]
        _draw_map(ax, group, handles)
        planar = all(np.shape(r.trajectory)[1:] == (2,) for r in group if r.trajectory)
        for r in group:
            trajectory = np.array(r.trajectory, dtype=float)
            if trajectory.size:
                # planar positions as a path; any other dimension against the sub-step index
                x, y = (
                    (trajectory[:, 0], trajectory[:, 1]) if planar else (np.arange(len(trajectory)), trajectory[:, 0])
                )
                (line,) = ax.plot(
                    x, y, label=f"{r.method} ({r.outcome})", gid=f"method {r.method}", **method_style(r.method)
                )
                handles.setdefault(f"method {r.method}", line)
            _draw_predicted_boxes(ax, r, handles)
            if planar:
                _draw_collision(ax, r, trajectory, handles)
        same = _identical_paths(group)
        if same:
            ax.text(
                0.02,
                0.02,
                "same path: " + "; ".join(" = ".join(m) for m in same),
                transform=ax.transAxes,
                fontsize=7,
                va="bottom",
                gid="identical paths",
            )
        if planar:
            ax.set_aspect("equal")
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
        else:
            ax.set_xlabel("sub-step")
            ax.set_ylabel("state[0]")
        ax.set_title(
            f"{group[0].scenario} world, seed {seed}\n" + ", ".join(f"{r.method}: {r.outcome}" for r in group),
            fontsize=9,
        )
    _legend_below(fig, handles, ncol=max(3, min(6, 3 * len(seeds))), height=5.6)
    if title:
        fig.suptitle(title)
    return fig


def _legend_below(fig: Any, handles: dict, *, ncol: int, height: float) -> None:
    """One legend for every kind of mark, below the panels (``height`` the figure's, inches)."""
    labels = [label.removeprefix("method ") for label in handles]
    ncol = max(1, min(ncol, len(labels)))
    rows = -(-len(labels) // ncol)
    fig.legend(list(handles.values()), labels, loc="lower center", ncol=ncol, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, min(0.5, (0.22 * rows + 0.1) / height), 1, 1))


def plot_trajectories(records: Sequence[EpisodeRecord], path: str | pathlib.Path, *, title: str = "") -> pathlib.Path:
    """Write `trajectory_figure` of ``records`` to ``path`` (PNG, 110 dpi).

    Parameters
    ----------
    records : sequence of EpisodeRecord
        Episodes of one scenario.
    path : str or pathlib.Path
        The image file.
    title : str
        Figure title (none if empty).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    return save_png(trajectory_figure(records, title=title), path)


def speed_and_heading(states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Speed (m/s) and heading of the velocity (degrees) of planar states.

    Parameters
    ----------
    states : numpy.ndarray
        Shape (n, 4): px, py, vx, vy.

    Returns
    -------
    speed, heading : numpy.ndarray
        Shape (n,). The heading is unwrapped (continuous across +-180 degrees, starting
        in (-180, 180]), and NaN where the speed is below `HEADING_MIN_SPEED` (standing
        still has no heading).
    """
    velocity = np.asarray(states, dtype=float)[:, 2:4]
    speed = np.linalg.norm(velocity, axis=1)
    heading = np.full(speed.shape, np.nan)
    moving = speed >= HEADING_MIN_SPEED
    heading[moving] = np.degrees(np.unwrap(np.arctan2(velocity[moving, 1], velocity[moving, 0])))
    return speed, heading


def motion_figure(records: Sequence[EpisodeRecord], *, title: str = "") -> Any:
    """The paper's Figures 3 and 4: path, speed and heading over time per method, one row per seed.

    Parameters
    ----------
    records : sequence of EpisodeRecord
        Episodes of one robot scenario whose ``trace`` holds the true states.
    title : str
        Figure title (none if empty).

    Returns
    -------
    matplotlib.figure.Figure
        Per seed: the paths (m), the speed (m/s) and the heading of the velocity (deg)
        against time (s), one line per method; dots mark the decisions on the speed
        curve (a flat stretch at 0 m/s is the robot stopping or waiting for a
        pedestrian, a step in heading a turn), a cross the collision of an episode that
        ended in one. The robot is holonomic: its heading is that of its velocity.
    """
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MultipleLocator

    plt = pyplot()
    seeds = sorted({r.seed for r in records})
    rows = max(1, len(seeds))
    fig, axes = plt.subplots(
        rows, 3, figsize=(15, 3.6 * rows), squeeze=False, gridspec_kw={"width_ratios": [1, 1.4, 1.4]}
    )
    handles: dict = {}
    for row, seed in zip(axes, seeds):
        group = [r for r in records if r.seed == seed]
        path_ax, speed_ax, heading_ax = row
        _draw_map(path_ax, group, handles)
        for r in group:
            states = np.asarray(r.trace.get("states", []), dtype=float)
            if states.ndim != 2 or states.shape[1] < 4:
                continue
            style = method_style(r.method)
            dt = float(r.trace.get("dt", 1.0))
            time = np.arange(len(states)) * dt
            speed, heading = speed_and_heading(states)
            (line,) = path_ax.plot(states[:, 0], states[:, 1], gid=f"method {r.method}", **style)
            handles.setdefault(f"method {r.method}", line)
            speed_ax.plot(time, speed, gid=f"method {r.method}", **style)
            heading_ax.plot(time, heading, gid=f"method {r.method}", **style)
            steps = np.asarray(r.trace.get("decision_steps", []), dtype=int)
            steps = steps[steps < len(states)]
            speed_ax.plot(time[steps], speed[steps], "o", ms=2.5, color=style["color"], zorder=7, gid="decisions")
            if r.outcome == "collision":
                for ax, series in ((speed_ax, speed), (heading_ax, heading)):
                    value = series[-1] if np.isfinite(series[-1]) else 0.0
                    ax.plot(
                        time[-1], value, marker="X", color="red", mec="k", ms=10, ls="none", zorder=9, gid="collision"
                    )
                _draw_collision(path_ax, r, states[:, :2], handles)
        handles.setdefault("decision", Line2D([], [], marker="o", ms=3, color="0.3", ls="none"))
        path_ax.set_aspect("equal")
        path_ax.set_xlabel("x (m)")
        path_ax.set_ylabel("y (m)")
        path_ax.set_title(f"{group[0].scenario} world, seed {seed}: path", fontsize=9)
        speed_ax.set_xlabel("time (s)")
        speed_ax.set_ylabel("speed (m/s)")
        speed_ax.set_title("speed, decisions marked", fontsize=9)
        heading_ax.set_xlabel("time (s)")
        heading_ax.set_ylabel("heading of the velocity (deg)")
        heading_ax.yaxis.set_major_locator(MultipleLocator(90))
        heading_ax.set_title("heading (not drawn below 0.05 m/s)", fontsize=9)
        for ax in (speed_ax, heading_ax):
            ax.grid(alpha=0.3)
    _legend_below(fig, handles, ncol=7, height=3.6 * rows)
    if title:
        fig.suptitle(title)
    return fig


def plot_motion(records: Sequence[EpisodeRecord], path: str | pathlib.Path, *, title: str = "") -> pathlib.Path:
    """Write `motion_figure` of ``records`` to ``path`` (PNG, 110 dpi).

    Parameters
    ----------
    records : sequence of EpisodeRecord
        Episodes of one robot scenario.
    path : str or pathlib.Path
        The image file.
    title : str
        Figure title (none if empty).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    return save_png(motion_figure(records, title=title), path)


def plot_experiment(
    records: Sequence[EpisodeRecord], out: str | pathlib.Path, *, scenarios: Sequence[str], plot_seeds: int = 3
) -> list[pathlib.Path]:
    """Every figure of an experiment: ``trajectories_S.png`` and ``motion_S.png`` per scenario S.

    For the road worlds, ``trajectories_S.png`` draws the road, the ego's and the other
    vehicles' paths (`road_scenario.plot_road_trajectories`) and there is no motion figure.

    Parameters
    ----------
    records : sequence of EpisodeRecord
        The experiment's episodes.
    out : str or pathlib.Path
        The output directory (it must exist).
    scenarios : sequence of str
        The scenarios to draw.
    plot_seeds : int
        How many world seeds per scenario (the first ones) the figures show.

    Returns
    -------
    list of pathlib.Path
        The files written, in order.
    """
    out = pathlib.Path(out)
    written = []
    for scenario in scenarios:
        shown = sorted({r.seed for r in records if r.scenario == scenario})[:plot_seeds]
        group = [r for r in records if r.scenario == scenario and r.seed in shown]
        if not group:
            continue
        if all("traffic_paths" in r.extra.get("world", {}) for r in group):
            # a road world: the lanes, the ego's and the other vehicles' paths (its state is (x, y, v, psi))
            from .road_scenario import plot_road_trajectories

            written.append(plot_road_trajectories(group, out / f"trajectories_{scenario}.png", title=scenario))
            continue
        written.append(plot_trajectories(group, out / f"trajectories_{scenario}.png"))
        if any(np.shape(r.trace.get("states", []))[1:] == (4,) for r in group):
            written.append(plot_motion(group, out / f"motion_{scenario}.png"))
    return written
