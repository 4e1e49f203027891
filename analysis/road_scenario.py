"""The driving scenarios ("highway", "tjunction") behind the registry, and their plots.

`RoadScenario` makes one seeded `RoadWorld` (`minimaxplan.scenarios.road_world`) per
episode behind `DrivingWorld`, the registry's `World` adapter: its measurement is the
`Observation` (the ego and every other vehicle on the road, with their ids), its control
``(acceleration m/s^2, steering rad)``, its outcomes "goal" (the only success),
"collision" and "off_road" (failures) and "timeout". The scenario also builds what the
baselines are told of the road (`RoadScenario.scene`: a `RoadScene` of
`minimaxplan.planners.dwa`, whose lane frame and road test are callables over the
world's `Road`, so that the planners never import `scenarios`).

`road_trajectory_figure` draws the lanes' edges, the ego's path and the other vehicles'
true paths of episode records (m, with a legend), like `minimaxplan.analysis.plots`
does for the robot.

Importing this module registers one scenario per road world kind (`ROAD_WORLD_KINDS`).
"""

from __future__ import annotations

import functools
import pathlib
from collections.abc import Sequence
from typing import Any

import numpy as np

from minimaxplan.models.errors import InputError
from minimaxplan.planners.dwa import RoadScene
from minimaxplan.scenarios.driving_reward import true_reward, world_reward
from minimaxplan.scenarios.road import HighwayGeometry, Road, TJunctionGeometry, highway_road, tjunction_road
from minimaxplan.scenarios.road_world import ROAD_WORLD_KINDS, Observation, RoadWorld, make_road_world

from .episode import EpisodeRecord, LoopConfig
from .registry import Scenario, register_scenario

__all__ = [
    "DrivingWorld",
    "RoadScenario",
    "RoadFrame",
    "HIGHWAY_SPEED_LIMIT",
    "TJUNCTION_SPEED_LIMIT",
    "road_trajectory_figure",
    "plot_road_trajectories",
]

#: v_max of the highway reward (the paper's Section IV), m/s.
HIGHWAY_SPEED_LIMIT = 30.0
#: v_max of the T-junction (the top of the ego's target speeds {0, 4.5, 9}), m/s.
TJUNCTION_SPEED_LIMIT = 9.0
#: Colour of the other vehicles' paths in the road figures.
_TRAFFIC_COLOR = "tab:brown"
#: Rounding of the recorded vehicle paths, m.
_PATH_DECIMALS = 2


class RoadFrame:
    """Progress, lane offset and lane heading of points along the lanes an ego may use.

    Parameters
    ----------
    road : Road
        The lanes.
    lanes : sequence of int
        The lanes the ego may drive on.
    progress_offsets : sequence of float
        Per lane, the progress (m) at its start: 0 for parallel lanes (the highway), the
        cumulative route length for a route (the T-junction).

    Notes
    -----
    A point belongs to the lane nearest to it, measured as ``|offset|`` plus how far its
    arc length lies outside ``[0, length]``; its progress is that lane's
    ``progress_offset + s``. Called as ``frame(points)`` it returns ``(progress, offset,
    heading)``: a `minimaxplan.planners.dwa.RoadReference`.
    """

    def __init__(self, road: Road, lanes: Sequence[int], progress_offsets: Sequence[float] | np.ndarray):
        self.road = road
        self.lanes = np.asarray(lanes, dtype=int)
        self.progress_offsets = np.asarray(progress_offsets, dtype=float)
        if self.lanes.ndim != 1 or self.lanes.shape != self.progress_offsets.shape or not self.lanes.size:
            raise InputError("lanes and progress_offsets must be non-empty sequences of the same length")

    def __call__(self, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(progress, offset, heading)`` of points (..., 2), each of shape (...)."""
        p = np.asarray(points, dtype=float)
        s, offset = self.road.frenet(self.lanes, p[..., 0:1], p[..., 1:2])  # (..., n_lanes)
        lengths = self.road.lengths[self.lanes]
        outside = np.maximum(np.maximum(-s, s - lengths), 0.0)
        best = np.argmin(np.abs(offset) + outside, axis=-1)[..., None]
        s_best = np.take_along_axis(s, best, axis=-1)[..., 0]
        lane = self.lanes[best[..., 0]]
        progress = self.progress_offsets[best[..., 0]] + s_best
        heading = self.road.heading_at(lane, np.clip(s_best, 0.0, self.road.lengths[lane]))
        return progress, np.take_along_axis(offset, best, axis=-1)[..., 0], heading

    def point(self, lane_position: int, progress: float) -> np.ndarray:
        """The centre-line point (2,) of a lane at a progress, clipped to the lane.

        Parameters
        ----------
        lane_position : int
            Position of the lane in ``lanes``.
        progress : float
            Progress, m.
        """
        lane = int(self.lanes[lane_position])
        s = float(np.clip(progress - self.progress_offsets[lane_position], 0.0, self.road.lengths[lane]))
        return np.asarray(self.road.position_at(lane, s), dtype=float)


def route_frame(world: RoadWorld) -> RoadFrame:
    """The lanes the ego may use: every lane of the highway, the ego's route at the T-junction."""
    road = world.road
    if world.kind == "highway":
        return RoadFrame(road, range(len(road)), np.zeros(len(road)))
    route = [int(lane) for lane in world.traffic.routes[0] if lane >= 0]
    offsets = np.concatenate([[0.0], np.cumsum(road.lengths[route[:-1]])])
    return RoadFrame(road, route, offsets)


def goal_progress(world: RoadWorld) -> float:
    """The progress (as `route_frame` measures it) at which the ego reaches its goal, m."""
    if world.kind == "highway":
        return float(world.goal_s)
    frame = route_frame(world)
    return float(frame.progress_offsets[-1] + world.goal_s)


class DrivingWorld:
    """A `RoadWorld` as the registry's `World` (see the module docstring).

    Parameters
    ----------
    world : RoadWorld
        A fresh world with an ego.

    Attributes
    ----------
    world : RoadWorld
        The wrapped world.
    frame : RoadFrame
        The ego's lanes (`route_frame`).
    goal_progress, start_progress : float
        The goal's and the ego's initial progress, m.
    speed_limit : float
        `HIGHWAY_SPEED_LIMIT` or `TJUNCTION_SPEED_LIMIT`, m/s.
    """

    def __init__(self, world: RoadWorld):
        if not isinstance(world, RoadWorld) or not world.include_ego:
            raise InputError("world must be a RoadWorld with an ego")
        self.world = world
        self.frame = route_frame(world)
        self.goal_progress = goal_progress(world)
        self.speed_limit = HIGHWAY_SPEED_LIMIT if world.kind == "highway" else TJUNCTION_SPEED_LIMIT
        self.start_progress = float(self.frame(world.ego_state[:2])[0])
        self._reward = world_reward(world)
        self._paths: dict[int, list[list[float]]] = {}
        self._record_paths()

    # -------------------------------------------------------------- World protocol
    @property
    def substeps(self) -> int:
        """Sub-steps per decision (5)."""
        return int(self.world.scenario.substeps)

    @property
    def done(self) -> bool:
        """True once the episode has ended."""
        return self.world.done

    @property
    def outcome(self) -> str:
        """ "running", then "goal", "collision", "off_road" or "timeout"."""
        return self.world.outcome

    @property
    def time(self) -> float:
        """Simulated time, s."""
        return self.world.time

    @property
    def step_index(self) -> int:
        """Sub-steps so far."""
        return self.world.step_index

    @property
    def position(self) -> np.ndarray:
        """The ego's true ``(x, y)``, m."""
        return self.world.ego_state[:2]

    @property
    def state(self) -> np.ndarray:
        """The ego's true ``(x, y, v, psi)``."""
        return self.world.ego_state

    @property
    def params(self) -> Any:
        """The episode's constants (`HighwayScenario` or `TJunctionScenario`; ``dt`` for the trace)."""
        return self.world.scenario

    def measure(self) -> Observation:
        """The noisy `Observation` of the ego and of every other vehicle on the road."""
        return self.world.measure()

    def apply(self, u: np.ndarray) -> str:
        """Hold ``u`` for one sub-step; returns the outcome.

        Parameters
        ----------
        u : numpy.ndarray, shape (2,)
            ``(acceleration m/s^2, steering rad)`` in the admissible box.
        """
        outcome = self.world.apply(u)
        self._record_paths()
        return outcome

    def reward(self) -> float:
        """The true reward of the current state (`minimaxplan.scenarios.driving_reward.true_reward`)."""
        return true_reward(self.world, self._reward)

    def true_states(self) -> dict[str, np.ndarray]:
        """The true states for the run-time check: ``"ego"`` and ``"vehicle j"`` (agent j on the road), ``(x, y, v, psi)``."""
        traffic = self.world.traffic
        states = {"ego": traffic.states[0].copy()}
        for j in np.flatnonzero(traffic.active):
            if j:
                states[f"vehicle {int(j)}"] = traffic.states[j].copy()
        return states

    def to_dict(self) -> dict:
        """The world's setup, the other vehicles' true paths and, after a collision, whom the ego hit.

        ``traffic_paths`` maps every other vehicle's agent index to its ``[step, x, y]``
        rows (m, 0.01 m) while on the road; ``collided_with`` lists the agents whose
        rectangle met the ego's at the end (empty otherwise).
        """
        world = self.world
        return {
            **world.to_dict(),
            "traffic_paths": {str(i): rows for i, rows in self._paths.items()},
            "collided_with": world.ego_collisions() if world.outcome == "collision" else [],
            "traffic_collisions": [list(c) for c in world.traffic_collisions],
            "traffic_off_road": [list(c) for c in world.traffic_off_road],
        }

    # -------------------------------------------------------------- helpers
    def _record_paths(self) -> None:
        traffic = self.world.traffic
        step = self.world.step_index
        for i in np.flatnonzero(traffic.active):
            if i == 0:
                continue
            x, y = np.round(traffic.states[i, :2], _PATH_DECIMALS)
            self._paths.setdefault(int(i), []).append([step, float(x), float(y)])

    def local_goals(self, progress: float, lookahead: float) -> np.ndarray:
        """Candidate local goals ahead: one per lane of the highway, one on the route at
        the T-junction (never past the last lane's end), shape (g, 2).

        Parameters
        ----------
        progress : float
            The ego's progress, m.
        lookahead : float
            How far ahead, m.
        """
        ahead = progress + lookahead
        if self.world.kind == "highway":
            return np.stack([self.frame.point(k, ahead) for k in range(len(self.frame.lanes))])
        offsets = self.frame.progress_offsets
        k = int(np.clip(np.searchsorted(offsets, ahead, side="right") - 1, 0, len(offsets) - 1))
        return self.frame.point(k, ahead)[None]

    def scene(self, observation: Observation, lookahead: float = 0.0) -> RoadScene:
        """What the baselines are told at this measurement: the lane frame, the road test,
        the other vehicles' measured states, the goal's progress, the speed limit and
        (``lookahead`` > 0) the local goals that far ahead of the ego.

        Parameters
        ----------
        observation : Observation
            The current measurement.
        lookahead : float
            Distance of the local goals ahead of the ego, m (0: none).
        """
        world = self.world
        goals = np.zeros((0, 2))
        if lookahead > 0:
            progress = float(self.frame(observation.ego[None, :2])[0][0])
            goals = self.local_goals(progress, lookahead)
        vehicle = world.scenario.vehicle
        return RoadScene(
            reference=self.frame,
            on_road=functools.partial(world.road.on_road, margin=world.scenario.off_road_margin),
            vehicles=observation.vehicles,
            goal_progress=self.goal_progress,
            speed_limit=self.speed_limit,
            lane_width=float(world.road.widths[self.frame.lanes[0]]),
            local_goals=goals,
            vehicle_length=vehicle.length,
            vehicle_width=vehicle.width,
        )


class RoadScenario(Scenario[DrivingWorld]):
    """The ego on the highway (``kind="highway"``) or turning left at the T-junction (``"tjunction"``).

    Parameters
    ----------
    kind : str
        One of `ROAD_WORLD_KINDS`.
    """

    def __init__(self, kind: str):
        if kind not in ROAD_WORLD_KINDS:
            raise InputError(f"kind must be one of {ROAD_WORLD_KINDS}, got {kind!r}")
        self.kind = kind

    def __repr__(self) -> str:
        return f"RoadScenario({self.kind!r})"

    def make_world(self, seed: int, config: LoopConfig) -> DrivingWorld:
        """`make_road_world` of ``kind`` and ``seed`` behind `DrivingWorld` (bounded uniform noise only).

        Parameters
        ----------
        seed : int
            The episode's seed.
        config : LoopConfig
            The loop settings (``measurement`` must be "uniform").

        Raises
        ------
        InputError
            If ``config.measurement`` is not "uniform" (the road worlds have no other model).
        """
        if config.measurement != "uniform":
            raise InputError(f"the road worlds measure with bounded uniform noise only, got {config.measurement!r}")
        return DrivingWorld(make_road_world(self.kind, seed))


# ------------------------------------------------------------------- plots
def _road_of(world: dict) -> Road:
    geometry = dict(world.get("scenario", {}).get("geometry", {}))
    if world.get("kind") == "highway":
        return highway_road(HighwayGeometry(**geometry))
    return tjunction_road(TJunctionGeometry(**geometry))


def _draw_road(ax, road: Road) -> None:
    for lane in range(len(road)):
        right, left = road.lane_edges(lane)
        for edge in (right, left):
            ax.plot(edge[:, 0], edge[:, 1], color="0.7", lw=0.8, zorder=1, gid="lane edge")


def road_trajectory_figure(records: Sequence[EpisodeRecord], *, title: str = "") -> Any:
    """One panel per world seed: the road, every method's ego path and the other vehicles' paths.

    Parameters
    ----------
    records : sequence of EpisodeRecord
        Episodes of one road scenario (any methods and seeds) whose ``extra["world"]`` is
        `DrivingWorld.to_dict`; one panel per seed.
    title : str
        Figure title (none if empty).

    Returns
    -------
    matplotlib.figure.Figure
        Axes in metres: the lane edges (grey), the other vehicles' true paths of the
        longest episode of the seed (thin black, a triangle at their first position), one
        line per method for the ego (`minimaxplan.analysis.plots.METHOD_STYLES`, labelled
        with the outcome), a square at the ego's start and a cross where an episode ended
        in a collision or off the road. The view spans the ego's paths with 30 m around
        (8 m across the highway).
    """
    from matplotlib.lines import Line2D

    from .figures import pyplot
    from .plots import method_style

    plt = pyplot()
    seeds = sorted({r.seed for r in records})
    fig, axes = plt.subplots(max(1, len(seeds)), 1, figsize=(11, 3.6 * max(1, len(seeds))), squeeze=False)
    handles: dict = {}
    for ax, seed in zip(axes[:, 0], seeds):
        group = [r for r in records if r.seed == seed]
        world = group[0].extra.get("world", {})
        _draw_road(ax, _road_of(world))
        handles.setdefault("lane edges", Line2D([], [], color="0.7", lw=0.8))
        longest = max(group, key=lambda r: len(r.trajectory))
        for rows in longest.extra.get("world", {}).get("traffic_paths", {}).values():
            path = np.asarray(rows, dtype=float)[:, 1:]
            ax.plot(path[:, 0], path[:, 1], color=_TRAFFIC_COLOR, lw=0.9, ls="--", zorder=2, gid="vehicle path")
            ax.plot(*path[0], "^", color=_TRAFFIC_COLOR, ms=4, zorder=2)
        handles.setdefault("other vehicles (true paths)", Line2D([], [], color=_TRAFFIC_COLOR, lw=0.9, ls="--"))
        handles.setdefault("vehicle first seen", Line2D([], [], color=_TRAFFIC_COLOR, marker="^", ms=4, ls="none"))
        spans = []
        for r in group:
            path = np.asarray(r.trajectory, dtype=float)
            if not path.size:
                continue
            spans.append(path)
            (line,) = ax.plot(path[:, 0], path[:, 1], label=f"{r.method} ({r.outcome})", **method_style(r.method))
            handles.setdefault(f"method {r.method}", line)
            if r.outcome in ("collision", "off_road"):
                ax.plot(*path[-1], marker="X", color="red", mec="k", ms=10, ls="none", zorder=9, gid="failure")
                handles.setdefault("collision / off road", Line2D([], [], marker="X", color="red", mec="k", ls="none"))
        if spans:
            points = np.concatenate(spans)
            ax.plot(*points[0], "ks", ms=6, zorder=8)
            handles.setdefault("ego start", Line2D([], [], color="k", marker="s", ls="none"))
            around = np.array([30.0, 8.0 if world.get("kind") == "highway" else 30.0])
            low, high = points.min(axis=0) - around, points.max(axis=0) + around
            ax.set_xlim(low[0], high[0])
            ax.set_ylim(low[1], high[1])
        if world.get("kind") == "tjunction":
            ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title(
            f"{group[0].scenario} world, seed {seed}: " + ", ".join(f"{r.method}: {r.outcome}" for r in group),
            fontsize=9,
        )
    height = 3.6 * max(1, len(seeds))
    labels = [label.removeprefix("method ") for label in handles]
    rows = -(-len(labels) // 4)
    fig.legend(list(handles.values()), labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    if title:
        fig.suptitle(title)
    fig.tight_layout(rect=(0, min(0.5, (0.22 * rows + 0.1) / height), 1, 0.95 if title else 1))
    return fig


def plot_road_trajectories(
    records: Sequence[EpisodeRecord], path: str | pathlib.Path, *, title: str = ""
) -> pathlib.Path:
    """Write `road_trajectory_figure` of ``records`` to ``path`` (PNG, 110 dpi).

    Parameters
    ----------
    records : sequence of EpisodeRecord
        Episodes of one road scenario.
    path : str or pathlib.Path
        The image file.
    title : str
        Figure title (none if empty).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from .figures import save_png

    return save_png(road_trajectory_figure(records, title=title), path)


for _kind in ROAD_WORLD_KINDS:
    register_scenario(_kind, functools.partial(RoadScenario, _kind))
