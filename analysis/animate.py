"""``minimaxplan animate``: an animated GIF of one episode.

Each frame shows the robot (its disc and its path so far), the static discs, the goal,
the pedestrians (discs and paths so far) and, for the robust method, the position boxes
of the plan being executed, the pedestrians' predicted boxes it was planned against
and the hypotheses still surviving model elimination. Each frame is drawn once by
matplotlib and the GIF is written by Pillow (a matplotlib dependency).
"""

from __future__ import annotations

import argparse
import pathlib
from typing import TYPE_CHECKING

from .arguments import Subcommand, count, output_directory, report_error

if TYPE_CHECKING:
    from .episode import EpisodeRecord

__all__ = [
    "MAX_FRAMES",
    "animate_episode",
    "COMMAND",
]

#: Frames of an animation at most: long episodes show every k-th sub-step.
MAX_FRAMES = 80


def animate_episode(
    record: EpisodeRecord, path: str | pathlib.Path, *, fps: int = 8, max_frames: int = MAX_FRAMES
) -> pathlib.Path:
    """Write an animated GIF of a robot episode.

    Parameters
    ----------
    record : EpisodeRecord
        A robot episode (its ``trace`` and ``extra["world"]``; for the robust
        method also ``extra["decisions"]``).
    path : str or pathlib.Path
        The GIF file.
    fps : int
        Frames per second (>= 1).
    max_frames : int
        At most this many frames (>= 2); every k-th sub-step is shown, and the last one.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        If the record has no trace of true planar states, or ``fps`` / ``max_frames``
        is out of range.

    Notes
    -----
    The boxes drawn are those of eqs. (16)-(18) for the executed decision sequence,
    and the pedestrians' growing boxes of `MovingObstacles` (velocity uncertainty
    integrated over the horizon, grown by their radii).
    """
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Circle, Rectangle
    from PIL import Image

    from minimaxplan.models import InputError
    from minimaxplan.models.validation import as_count
    from minimaxplan.scenarios.worlds import PEDESTRIAN_RADIUS

    from .figures import pyplot
    from .plots import PEDESTRIAN_BOX_COLOR, method_style

    plt = pyplot()

    fps = as_count("fps", fps)
    max_frames = as_count("max_frames", max_frames, minimum=2)
    trace = record.trace
    states = np.asarray(trace.get("states", []), dtype=float)
    if states.ndim != 2 or states.shape[0] < 2 or states.shape[1] < 2:
        raise InputError(f"the record of {record.method} in {record.scenario} has no trace of planar states to animate")
    peds = np.asarray(trace.get("pedestrians", []), dtype=float)
    if peds.ndim != 3:
        peds = np.zeros((len(states), 0, 2))
    dt = float(trace.get("dt", 1.0))
    world = record.extra.get("world", {})
    params = world.get("params", {})
    robot_radius = float(params.get("robot_radius", 0.3))
    decisions = record.extra.get("decisions", [])
    steps = sorted(set(np.linspace(0, len(states) - 1, min(max_frames, len(states))).round().astype(int).tolist()))
    style = method_style(record.method)

    fig, ax = plt.subplots(figsize=(6, 6), dpi=80)
    obstacles = world.get("obstacles", {})
    for c, rad in zip(obstacles.get("centers", []), obstacles.get("radii", [])):
        ax.add_patch(Circle(c, rad, color="0.6"))
    if "goal" in world:
        ax.add_patch(Circle(world["goal"], params.get("goal_tolerance", 0.5), fill=False, ec="k", ls="--"))
        ax.plot(*world["start"], "ks", ms=6)
    everything = np.concatenate([states[:, :2], peds.reshape(-1, 2)]) if peds.size else states[:, :2]
    low, high = everything.min(axis=0) - 2.0, everything.max(axis=0) + 2.0
    ax.set_xlim(low[0], high[0])
    ax.set_ylim(low[1], high[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    (path_line,) = ax.plot([], [], color=style["color"], lw=1.5, label=f"{record.method} path")
    robot = Circle(
        (float(states[0, 0]), float(states[0, 1])), robot_radius, color=style["color"], zorder=6, label="robot"
    )
    ax.add_patch(robot)
    ped_paths = [ax.plot([], [], "k:", lw=1.0)[0] for _ in range(peds.shape[1])]
    ped_discs = [Circle((float(p[0]), float(p[1])), PEDESTRIAN_RADIUS, color="k", alpha=0.8, zorder=6) for p in peds[0]]
    for disc in ped_discs:
        ax.add_patch(disc)
    plan_boxes = PatchCollection([], match_original=False, facecolor="none", edgecolor=style["color"], lw=0.6)
    ped_boxes = PatchCollection([], match_original=False, facecolor="none", edgecolor=PEDESTRIAN_BOX_COLOR, lw=0.6)
    ax.add_collection(plan_boxes)
    ax.add_collection(ped_boxes)
    text = ax.text(0.02, 0.98, "", transform=ax.transAxes, va="top", fontsize=8, family="monospace")
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = [
        Line2D([], [], color=style["color"], lw=1.5),
        Line2D([], [], color="k", marker="o", ls=":", ms=6),
        Patch(color="0.6"),
    ]
    labels = [f"robot ({record.method}) and its path", "pedestrian and its path", "static obstacle"]
    if decisions:
        handles += [Patch(fill=False, ec=style["color"]), Patch(fill=False, ec=PEDESTRIAN_BOX_COLOR)]
        labels += ["predicted robot boxes (executed plan)", "predicted pedestrian boxes"]
    ax.legend(handles, labels, loc="lower right", fontsize=7)
    ax.set_title(f"{record.scenario} world, seed {record.seed}, {record.method}: {record.outcome}", fontsize=9)
    fig.tight_layout()

    def boxes(lower, upper) -> list:
        return [Rectangle(lo, hi[0] - lo[0], hi[1] - lo[1]) for lo, hi in zip(lower, upper)]

    def draw(step: int) -> list:
        path_line.set_data(states[: step + 1, 0], states[: step + 1, 1])
        robot.center = tuple(states[step, :2])
        for j, (line, disc) in enumerate(zip(ped_paths, ped_discs)):
            line.set_data(peds[: step + 1, j, 0], peds[: step + 1, j, 1])
            disc.center = tuple(peds[min(step, len(peds) - 1), j])
        current = [d for d in decisions if d["step"] <= step]
        lines = [f"t = {step * dt:5.1f} s"]
        if len(states[0]) >= 4:
            lines.append(f"speed = {np.linalg.norm(states[step, 2:4]):.2f} m/s")
        if current:
            decision = current[-1]
            plan_boxes.set_paths(boxes(decision["lower"][1:], decision["upper"][1:]))
            ped_lower, ped_upper = np.asarray(decision["pedestrian_lower"]), np.asarray(decision["pedestrian_upper"])
            shown = ped_lower[1 :: max(1, len(ped_lower) // 4)]
            shown_upper = ped_upper[1 :: max(1, len(ped_upper) // 4)]
            ped_boxes.set_paths(boxes(shown.reshape(-1, 2), shown_upper.reshape(-1, 2)) if shown.size else [])
            lines.append("surviving hypotheses: " + ", ".join(decision["survivors"]))
        if step == len(states) - 1:
            lines.append(f"outcome: {record.outcome}")
        text.set_text("\n".join(lines))
        return [path_line, robot, text, plan_boxes, ped_boxes, *ped_paths, *ped_discs]

    # One draw per frame, straight into Pillow (matplotlib's animation writers draw each
    # frame two or three times).
    canvas = FigureCanvasAgg(fig)
    frames = []
    for step in steps:
        draw(step)
        canvas.draw()
        frames.append(Image.fromarray(np.asarray(canvas.buffer_rgba())[..., :3]).quantize(colors=64))
    plt.close(fig)
    out = pathlib.Path(path)
    frames[0].save(out, save_all=True, append_images=frames[1:], duration=int(1000 / fps), loop=0)
    return out


def _run(args: argparse.Namespace) -> int:
    from minimaxplan.models import MinimaxplanError

    from .episode import LoopConfig, make_job, run_job

    try:
        config = LoopConfig(max_decisions=args.max_decisions)
        job = make_job(args.scenario, args.method, args.seed, config)
        record = run_job(job)
        args.out.mkdir(parents=True, exist_ok=True)
        path = animate_episode(record, args.out / f"episode_{args.scenario}_{args.method}_{args.seed}.gif")
    except MinimaxplanError as exc:
        return report_error("animate", exc)
    print(f"{args.scenario} world, seed {args.seed}, {args.method}: {record.outcome} after {record.time_s:.1f} s")
    print(f"animation written to {path}")
    return 0


def _add_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", required=True, help="a registered scenario (e.g. static, pedestrian)")
    parser.add_argument("--method", required=True, help="a registered method (e.g. robust, nominal, oracle, dwa, teb)")
    parser.add_argument("--seed", type=count(0), default=0, help="world seed (>= 0)")
    parser.add_argument(
        "--max-decisions",
        type=count(1),
        default=None,
        help="stop after this many decisions (default: the whole episode)",
    )
    parser.add_argument("--out", type=output_directory, default=pathlib.Path("out/animate"), help="output directory")


COMMAND = Subcommand(
    "animate",
    help="an animated GIF of one episode",
    description="Run one seeded episode of METHOD in SCENARIO and write an animated GIF of it to OUT: "
    "the robot, the obstacles, the pedestrians and (robust method) the predicted boxes of the "
    "executed plan and the surviving hypotheses over time.",
    epilog="Exit codes: 0 done; 2 a bad option or an unknown name (one line on stderr, before any work).",
    add_options=_add_options,
    run=_run,
)
