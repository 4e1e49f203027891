"""``minimaxplan sweep``: where each method breaks, beyond the paper's pedestrian world.

    minimaxplan sweep --scenario pedestrian --pedestrians 1,3,5,8 --velocity-uncertainty 0.1,0.3,0.6
                      --methods robust,dwa,teb --episodes N [--seed S] [--workers W] --out DIR

The paper's pedestrian world has 1-3 pedestrians whose velocity is known within +-0.3 m/s
per axis, and there robust, DWA and TEB all stay near 0 failures in 100. The sweep runs
every method over a grid of crowd sizes and velocity uncertainties (`CrowdWorld`: the
pedestrian world's layout, friction, disturbances and noise for a seed, with a crowd of
exactly that many pedestrians whose true velocity stays within the stated uncertainty of
the announced one) and reports, per cell and method, the failure rate with its exact
(Clopper-Pearson) 95% interval and the travel time of the successful episodes with a
Student-t 95% interval: where robustness pays, and what it costs. Outputs in DIR:
``sweep.md`` (the table), ``sweep.json``, ``sweep.csv`` (one row per episode) and
``sweep.png`` (failure rate and travel time against the crowd size, one panel per
uncertainty).

Exit codes: 0 done; 2 a bad option (one line on stderr, before any episode runs).
"""

from __future__ import annotations

import argparse
import math
import pathlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .arguments import count, count_list, name_list, output_directory, report_error

if TYPE_CHECKING:
    from minimaxplan.scenarios import RobotWorld

    from .episode import EpisodeRecord, LoopConfig
    from .robot_scenario import RobotScenario

__all__ = [
    "SWEEP_SCENARIOS",
    "DEFAULT_PEDESTRIANS",
    "DEFAULT_UNCERTAINTIES",
    "DEFAULT_METHODS",
    "HEADING_MARGIN",
    "CrowdScenarioFactory",
    "cell_name",
    "make_crowd_world",
    "crowd_scenario",
    "run_sweep",
    "summarise_sweep",
    "sweep_markdown",
    "plot_sweep",
    "register",
]

#: The scenarios the sweep can vary (the driving worlds come with the driving issue).
SWEEP_SCENARIOS = ("pedestrian",)
DEFAULT_PEDESTRIANS = (1, 3, 5, 8)
#: Per-axis bounds on the pedestrians' velocity error, m/s (the paper's world: 0.3).
DEFAULT_UNCERTAINTIES = (0.1, 0.3, 0.6)
DEFAULT_METHODS = ("robust", "dwa", "teb")
#: The true heading deviates from the announced one by at most ``HEADING_MARGIN * u / s_max``
#: (s_max = 1.5 m/s the fastest pedestrian), so the per-axis velocity error ``s |e|``
#: stays strictly inside the announced bound u; at u = 0.3 m/s this is the paper world's
#: 0.18 rad, and its random-walk step (0.03 rad per sub-step) scales the same way.
HEADING_MARGIN = 0.9


def cell_name(scenario: str, pedestrians: int, velocity_uncertainty: float) -> str:
    """The registered scenario name of one grid cell, e.g. ``"pedestrian[5 ped +-0.3 m/s]"``.

    Parameters
    ----------
    scenario : str
        The swept scenario (`SWEEP_SCENARIOS`).
    pedestrians : int
        Pedestrians in every world of the cell.
    velocity_uncertainty : float
        Per-axis bound on the pedestrians' velocity error, m/s.

    Returns
    -------
    str
        A name without commas (the registry's rule).
    """
    return f"{scenario}[{pedestrians} ped +-{velocity_uncertainty:g} m/s]"


def make_crowd_world(
    seed: int,
    *,
    pedestrians: int,
    velocity_uncertainty: float,
    measurement: str = "uniform",
) -> RobotWorld:
    """The pedestrian world of ``seed`` with a crowd of ``pedestrians`` and the given uncertainty.

    Parameters
    ----------
    seed : int
        World seed (>= 0): layout, friction, disturbances and measurement noise are
        those of ``make_world("pedestrian", seed)``; the crowd is drawn from a stream of
        its own (seeded by the seed and the count), so the cells of a sweep share
        everything else.
    pedestrians : int
        Number of crossing pedestrians (>= 0).
    velocity_uncertainty : float
        Per-axis bound u on ``true - announced`` velocity, m/s (>= 0); the world's
        ``pedestrians`` (what planners know) announce it, and the true heading stays
        within ``HEADING_MARGIN * u / 1.5`` rad of the announced one.
    measurement : {"uniform", "gaussian"}
        As in `make_world`.

    Returns
    -------
    RobotWorld
        A ``CrowdWorld`` (a `RobotWorld` whose ``crowd`` and ``pedestrians`` are the
        cell's).

    Raises
    ------
    InputError
        For a seed, count or uncertainty out of range.
    """
    world_class, _ = _classes()
    return world_class(
        seed, pedestrians=pedestrians, velocity_uncertainty=velocity_uncertainty, measurement=measurement
    )


def crowd_scenario(pedestrians: int, velocity_uncertainty: float) -> RobotScenario:
    """The robot scenario of one grid cell: `make_crowd_world` worlds, every robot method supported.

    Parameters
    ----------
    pedestrians : int
        Pedestrians per world (>= 0).
    velocity_uncertainty : float
        Per-axis velocity-error bound, m/s (>= 0).

    Returns
    -------
    RobotScenario
        A ``CrowdScenario``, whose ``make_world(seed, config)`` returns `make_crowd_world`.
    """
    _, scenario_class = _classes()
    return scenario_class(pedestrians, velocity_uncertainty)


_CLASSES: list[tuple[type, type]] = []


def _classes() -> tuple[type, type]:
    """``(CrowdWorld, CrowdScenario)``, built once on first use.

    They subclass `RobotWorld` and `RobotScenario`, which import numpy: defining them
    at import time would make ``minimaxplan --help`` import the library.
    """
    if _CLASSES:
        return _CLASSES[0]
    import dataclasses

    import numpy as np

    from minimaxplan.models.validation import as_count, as_positive_scalar
    from minimaxplan.scenarios import MovingObstacles, RobotWorld
    from minimaxplan.scenarios import worlds as robot_worlds

    from .robot_scenario import RobotScenario

    @dataclasses.dataclass(eq=False)
    class BoundedCrowd(robot_worlds.PedestrianCrowd):
        """A `PedestrianCrowd` whose heading deviation bound and random-walk step are its own."""

        max_deviation: float = robot_worlds.PEDESTRIAN_HEADING_DEVIATION
        deviation_step: float = robot_worlds.PEDESTRIAN_HEADING_STEP

        def advance(self, dt: float) -> None:
            self.positions = self.positions + self.velocities * dt
            step = self.rng.uniform(-self.deviation_step, self.deviation_step, size=self.deviations.shape)
            self.deviations = np.clip(self.deviations + step, -self.max_deviation, self.max_deviation)

    class CrowdWorld(RobotWorld):
        """The pedestrian world of a seed with a crowd of a given size and velocity uncertainty."""

        def __init__(self, seed: int, *, pedestrians: int, velocity_uncertainty: float, measurement: str = "uniform"):
            count = as_count("pedestrians", pedestrians, minimum=0)
            # read by `pedestrians` while RobotWorld builds its own crowd, which is replaced below
            self.velocity_uncertainty = as_positive_scalar(
                "velocity_uncertainty", velocity_uncertainty, allow_zero=True
            )
            super().__init__("pedestrian", seed, measurement=measurement)
            rng = np.random.default_rng(np.random.SeedSequence([self.seed, 0xC20D, count]))
            base = robot_worlds._crowd(rng, count, self.start, self.goal)
            bound = HEADING_MARGIN * self.velocity_uncertainty / robot_worlds.PEDESTRIAN_SPEED[1]
            ratio = bound / robot_worlds.PEDESTRIAN_HEADING_DEVIATION
            fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(robot_worlds.PedestrianCrowd)}
            self.crowd = BoundedCrowd(
                **fields, max_deviation=bound, deviation_step=robot_worlds.PEDESTRIAN_HEADING_STEP * ratio
            )
            # The world's record and its true reward are built from the crowd: rebuild them.
            self._initial_pedestrians = (self.crowd.positions.copy(), self.crowd.announced.copy())
            self._true_reward = (
                self.goal_reward.with_obstacles(moving_obstacles=self.pedestrians)
                if len(self.crowd)
                else self.goal_reward
            )

        @property
        def pedestrians(self) -> MovingObstacles:
            """As `RobotWorld.pedestrians`, with this world's velocity uncertainty."""
            return MovingObstacles(
                self.crowd.positions.copy(),
                self.crowd.announced.copy(),
                self.crowd.radii.copy(),
                velocity_uncertainty=self.velocity_uncertainty,
                dt=self.params.dt,
                time0=self.step_index,
            )

    class CrowdScenario(RobotScenario):
        """The robot scenario whose worlds are `make_crowd_world` worlds of one grid cell."""

        def __init__(self, pedestrians: int, velocity_uncertainty: float) -> None:
            super().__init__("pedestrian")
            self.pedestrians, self.velocity_uncertainty = pedestrians, velocity_uncertainty

        def __repr__(self) -> str:
            return f"CrowdScenario(pedestrians={self.pedestrians}, velocity_uncertainty={self.velocity_uncertainty})"

        def make_world(self, seed: int, config: LoopConfig) -> RobotWorld:
            return CrowdWorld(
                seed,
                pedestrians=self.pedestrians,
                velocity_uncertainty=self.velocity_uncertainty,
                measurement=config.measurement,
            )

    for cls in (BoundedCrowd, CrowdWorld, CrowdScenario):
        cls.__module__, cls.__qualname__ = __name__, cls.__name__
    _CLASSES.append((CrowdWorld, CrowdScenario))
    return _CLASSES[0]


@dataclass(frozen=True)
class CrowdScenarioFactory:
    """A picklable scenario factory of one grid cell (equal cells compare equal).

    Attributes
    ----------
    pedestrians : int
        Pedestrians per world.
    velocity_uncertainty : float
        Per-axis velocity-error bound, m/s.
    """

    pedestrians: int
    velocity_uncertainty: float

    def __call__(self) -> RobotScenario:
        """The cell's scenario (`crowd_scenario`)."""
        return crowd_scenario(self.pedestrians, self.velocity_uncertainty)


def run_sweep(
    *,
    scenario: str = "pedestrian",
    pedestrians: Sequence[int] = DEFAULT_PEDESTRIANS,
    velocity_uncertainty: Sequence[float] = DEFAULT_UNCERTAINTIES,
    methods: Sequence[str] = DEFAULT_METHODS,
    episodes: int = 20,
    seed: int = 0,
    workers: int | None = None,
    progress: bool = True,
    config: LoopConfig | None = None,
) -> dict:
    """Run every method on every cell of the grid and summarise.

    Parameters
    ----------
    scenario : str
        One of `SWEEP_SCENARIOS`.
    pedestrians : sequence of int
        Crowd sizes (each >= 0, distinct).
    velocity_uncertainty : sequence of float
        Per-axis velocity-error bounds, m/s (each >= 0, finite, distinct).
    methods : sequence of str
        Registered methods that drive robot worlds.
    episodes : int
        Episodes per cell and method (>= 1); world seeds ``seed .. seed + episodes - 1``
        in every cell (paired comparison).
    seed : int
        World seed of the first episode (>= 0).
    workers : int, optional
        Local processes (default: all cores).
    progress : bool
        Show a progress bar.
    config : LoopConfig, optional
        Loop settings (default `episode.DEFAULT_CONFIG`).

    Returns
    -------
    dict
        ``grid`` (the inputs), ``rows`` (`summarise_sweep`), ``records`` (the episodes'
        CSV rows with the cell's ``pedestrians`` and ``velocity_uncertainty``) and
        ``wall_time_s``.

    Raises
    ------
    InputError
        Before any episode runs, for a value out of range or repeated, or an unknown scenario.
    UnknownMethod, UnsupportedScenario
        Before any episode runs, for a method that is not registered or cannot drive the worlds.
    """
    from minimaxplan.models import InputError
    from minimaxplan.models.validation import as_choice, as_count, as_positive_scalar

    from .episode import DEFAULT_CONFIG
    from .experiment import run_experiment
    from .registry import register_scenario

    as_choice("scenario", scenario, SWEEP_SCENARIOS)
    counts = [as_count(f"pedestrians[{i}]", n, minimum=0) for i, n in enumerate(pedestrians)]
    bounds = [
        as_positive_scalar(f"velocity_uncertainty[{i}]", u, allow_zero=True) for i, u in enumerate(velocity_uncertainty)
    ]
    for name, values in (("pedestrians", counts), ("velocity_uncertainty", bounds), ("methods", list(methods))):
        if not values:
            raise InputError(f"{name} must hold at least one value, got none")
        if len(set(values)) != len(values):
            raise InputError(f"{name} must not repeat a value, got {list(values)}")
    cells = {}
    for n in counts:
        for u in bounds:
            name = cell_name(scenario, n, u)
            register_scenario(name, CrowdScenarioFactory(n, u))
            cells[name] = (n, u)
    result = run_experiment(
        list(cells),
        list(methods),
        episodes=episodes,
        seed=seed,
        config=DEFAULT_CONFIG if config is None else config,
        workers=workers,
        progress=progress,
    )
    records = []
    for record in result.records:
        n, u = cells[record.scenario]
        records.append({"pedestrians": n, "velocity_uncertainty": u, **record.row()})
    return {
        "grid": {
            "scenario": scenario,
            "pedestrians": counts,
            "velocity_uncertainty": bounds,
            "methods": list(methods),
            "episodes": as_count("episodes", episodes),
            "seed": seed,
        },
        "rows": summarise_sweep(result.records, cells),
        "records": records,
        "wall_time_s": result.wall_time_s,
    }


def summarise_sweep(records: Sequence[EpisodeRecord], cells: dict[str, tuple[int, float]]) -> list[dict]:
    """One row per (cell, method): failure rate and travel time with 95% intervals.

    Parameters
    ----------
    records : sequence of EpisodeRecord
        The episodes, their ``scenario`` the cell names of ``cells``.
    cells : dict
        Cell name -> (pedestrians, velocity_uncertainty).

    Returns
    -------
    list of dict
        ``pedestrians``, ``velocity_uncertainty``, ``method``, ``episodes``,
        ``failures``, ``failure_rate``, ``failure_ci95`` (exact Clopper-Pearson),
        ``collisions``, ``timeouts``, ``successes``, ``mean_time_s`` and
        ``time_ci95`` (Student-t interval of the mean over the successful episodes;
        NaN without two of them), ``mean_return`` and, for methods that check their
        predictions, ``boxes_missed``.
    """
    import numpy as np
    from scipy import stats

    groups: dict[tuple[str, str], list[EpisodeRecord]] = {}
    for record in records:
        groups.setdefault((record.scenario, record.method), []).append(record)
    rows = []
    for (name, method), group in groups.items():
        n, u = cells[name]
        failures = sum(not r.success for r in group)
        ci = stats.binomtest(failures, len(group)).proportion_ci(confidence_level=0.95, method="exact")
        times = np.array([r.time_s for r in group if r.success], dtype=float)
        if times.size >= 2:
            half = float(stats.t.ppf(0.975, times.size - 1) * times.std(ddof=1) / math.sqrt(times.size))
            time_ci = [float(times.mean()) - half, float(times.mean()) + half]
        else:
            time_ci = [math.nan, math.nan]
        missed = [int(r.extra["boxes_missed"]) for r in group if "boxes_missed" in r.extra]
        rows.append(
            {
                "pedestrians": n,
                "velocity_uncertainty": u,
                "method": method,
                "episodes": len(group),
                "failures": failures,
                "failure_rate": failures / len(group),
                "failure_ci95": [float(ci.low), float(ci.high)],
                "collisions": sum(r.outcome == "collision" for r in group),
                "timeouts": sum(r.outcome == "timeout" for r in group),
                "successes": int(times.size),
                "mean_time_s": float(times.mean()) if times.size else math.nan,
                "time_ci95": time_ci,
                "mean_return": float(np.mean([r.discounted_return for r in group])),
                "boxes_missed": int(sum(missed)) if missed else None,
            }
        )
    rows.sort(key=lambda r: (r["pedestrians"], r["velocity_uncertainty"]))
    return rows


def _fmt(x: float, digits: int) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def sweep_markdown(study: dict) -> str:
    """The sweep as a Markdown table, one row per (pedestrians, uncertainty, method).

    Parameters
    ----------
    study : dict
        A `run_sweep` result.

    Returns
    -------
    str
        The table and the run's wall time.
    """
    grid = study["grid"]
    lines = [
        f"Sweep of the {grid['scenario']} world: {grid['episodes']} episodes per cell and method "
        f"(world seeds {grid['seed']}-{grid['seed'] + grid['episodes'] - 1}, the same in every cell). "
        "Failure interval: exact (Clopper-Pearson) 95%; travel time over the episodes that reached the "
        "goal, mean and Student-t 95% interval.",
        "",
        "| pedestrians | velocity uncertainty (m/s) | method | failures / episodes | failure 95% CI "
        "| collisions | timeouts | mean time (s) | time 95% CI (s) | mean return |",
        "|---:|---:|---|---|---|---:|---:|---:|---|---:|",
    ]
    for r in study["rows"]:
        low, high = r["failure_ci95"]
        t_low, t_high = r["time_ci95"]
        time_ci = "-" if math.isnan(t_low) else f"[{t_low:.1f}, {t_high:.1f}]"
        lines.append(
            f"| {r['pedestrians']} | {r['velocity_uncertainty']:g} | {r['method']} | {r['failures']}/{r['episodes']} "
            f"| [{low:.3f}, {high:.3f}] | {r['collisions']} | {r['timeouts']} | {_fmt(r['mean_time_s'], 1)} "
            f"| {time_ci} | {r['mean_return']:.3f} |"
        )
    missed = [r["boxes_missed"] for r in study["rows"] if r["boxes_missed"] is not None]
    if missed:
        lines += ["", f"Predicted boxes missed by the true states (robust): {sum(missed)} (a miss is a bug)."]
    lines += ["", f"Wall time of the run: {study['wall_time_s']:.1f} s"]
    return "\n".join(lines) + "\n"


def plot_sweep(study: dict, path: str | pathlib.Path) -> pathlib.Path:
    """Failure rate and travel time against the crowd size, one column per velocity uncertainty.

    Parameters
    ----------
    study : dict
        A `run_sweep` result.
    path : str or pathlib.Path
        The PNG to write.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from .plots import method_style

    grid = study["grid"]
    bounds = grid["velocity_uncertainty"]
    fig, axes = plt.subplots(2, len(bounds), figsize=(4.2 * len(bounds), 7), sharex=True, sharey="row", squeeze=False)
    offsets = np.linspace(-0.12, 0.12, len(grid["methods"])) if len(grid["methods"]) > 1 else [0.0]
    for c, u in enumerate(bounds):
        for offset, method in zip(offsets, grid["methods"]):
            rows = [r for r in study["rows"] if r["velocity_uncertainty"] == u and r["method"] == method]
            x = np.array([r["pedestrians"] for r in rows], dtype=float) + offset
            style = method_style(method)
            colour = style.get("color")
            rate = np.array([r["failure_rate"] for r in rows])
            ci = np.array([r["failure_ci95"] for r in rows])
            axes[0, c].errorbar(
                x, rate, yerr=[rate - ci[:, 0], ci[:, 1] - rate], fmt="o-", color=colour, capsize=3, label=method
            )
            mean = np.array([r["mean_time_s"] for r in rows], dtype=float)
            tci = np.array([r["time_ci95"] for r in rows], dtype=float)
            err = np.where(np.isnan(tci), 0.0, np.abs(tci - mean[:, None])).T
            axes[1, c].errorbar(x, mean, yerr=err, fmt="s-", color=colour, capsize=3, label=method)
        axes[0, c].set_title(f"velocity uncertainty +-{u:g} m/s per axis")
        axes[1, c].set_xlabel("pedestrians")
        axes[0, c].grid(alpha=0.3)
        axes[1, c].grid(alpha=0.3)
    top = max((r["failure_ci95"][1] for r in study["rows"]), default=1.0)
    axes[0, 0].set_ylim(-0.02, min(1.02, 1.1 * top + 0.02))  # the rows share it (sharey)
    axes[0, 0].set_ylabel("failure rate (95% CI)")
    axes[1, 0].set_ylabel("travel time of successes, s (95% CI)")
    axes[0, 0].legend()
    fig.suptitle(f"Where each method breaks: {grid['scenario']} world, {grid['episodes']} episodes per point")
    fig.tight_layout()
    out = pathlib.Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _write_outputs(study: dict, out: pathlib.Path) -> None:
    import csv
    import json

    from .reports import to_json

    out.mkdir(parents=True, exist_ok=True)
    (out / "sweep.md").write_text(sweep_markdown(study), encoding="utf-8")
    summary = {k: v for k, v in study.items() if k != "records"}
    (out / "sweep.json").write_text(to_json(summary), encoding="utf-8")
    if study["records"]:
        columns = list(dict.fromkeys(key for row in study["records"] for key in row))  # every method's fields
        with open(out / "sweep.csv", "w", newline="", encoding="utf-8") as handle:
            writer = csv.DictWriter(handle, fieldnames=columns, extrasaction="ignore")
            writer.writeheader()
            for row in study["records"]:
                writer.writerow({k: json.dumps(v) if isinstance(v, (dict, list)) else v for k, v in row.items()})
    plot_sweep(study, out / "sweep.png")


def _uncertainty_list(text: str) -> list[float]:
    """``--velocity-uncertainty``: comma-separated finite numbers >= 0, distinct (m/s)."""
    items = [item.strip() for item in text.split(",")]
    if not any(items):
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers >= 0 (m/s), got {text!r}")
    values = []
    for item in items:
        try:
            value = float(item)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {item!r} in {text!r}") from None
        if not math.isfinite(value) or value < 0:
            raise argparse.ArgumentTypeError(f"every value must be a finite number >= 0 (m/s), got {item!r}")
        values.append(value)
    return _distinct(values, text)


def _distinct(values: list, text: str) -> list:
    if len(set(values)) != len(values):
        raise argparse.ArgumentTypeError(f"values must not repeat, got {text!r}")
    return values


def _distinct_of(parse: Callable[[str], list]) -> Callable[[str], list]:
    def checked(text: str) -> list:
        return _distinct(parse(text), text)

    checked.__name__ = getattr(parse, "__name__", "list")
    return checked


def _scenario(text: str) -> str:
    if text not in SWEEP_SCENARIOS:
        raise argparse.ArgumentTypeError(f"the sweep varies the scenarios {list(SWEEP_SCENARIOS)}, got {text!r}")
    return text


def _run(args: argparse.Namespace) -> int:
    from minimaxplan.models import MinimaxplanError

    from .registry import UnknownMethod, UnsupportedScenario

    try:
        study = run_sweep(
            scenario=args.scenario,
            pedestrians=args.pedestrians,
            velocity_uncertainty=args.velocity_uncertainty,
            methods=args.methods,
            episodes=args.episodes,
            seed=args.seed,
            workers=args.workers,
            progress=not args.no_progress,
        )
    except (UnknownMethod, UnsupportedScenario) as exc:
        return report_error("sweep", exc, option="--methods")
    except MinimaxplanError as exc:
        return report_error("sweep", exc)
    _write_outputs(study, args.out)
    print(sweep_markdown(study))
    print(f"outputs written to {args.out}/")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``sweep`` subcommand to ``subparsers``.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The subcommands of the ``minimaxplan`` parser (`minimaxplan.analysis.cli`).
    """
    parser = subparsers.add_parser(
        "sweep",
        help="failure rate and travel time per method over crowd size and velocity uncertainty",
        description="Run every method over a grid of pedestrian counts and velocity uncertainties of the "
        "pedestrian world; write the failure rate (exact 95%% interval) and the travel time (95%% interval) "
        "per cell and method as a table, a plot, JSON and CSV. A run has EPISODES x pedestrians x "
        "uncertainties x methods episodes (20 x 4 x 3 x 3 = 720 with --episodes 20 and the defaults).",
        epilog="Exit codes: 0 done; 2 a bad option, an unknown method (one line on stderr, before any episode runs).",
    )
    parser.add_argument(
        "--scenario", type=_scenario, default="pedestrian", help=f"the world to vary: {', '.join(SWEEP_SCENARIOS)}"
    )
    parser.add_argument(
        "--pedestrians",
        type=_distinct_of(count_list(0)),
        default=list(DEFAULT_PEDESTRIANS),
        help=f"comma-separated pedestrian counts, each >= 0 (default: {','.join(map(str, DEFAULT_PEDESTRIANS))})",
    )
    parser.add_argument(
        "--velocity-uncertainty",
        type=_uncertainty_list,
        default=list(DEFAULT_UNCERTAINTIES),
        metavar="U,...",
        help="comma-separated per-axis bounds on the pedestrians' velocity error, m/s, each >= 0 "
        f"(default: {','.join(map(str, DEFAULT_UNCERTAINTIES))})",
    )
    parser.add_argument(
        "--methods",
        type=_distinct_of(name_list),
        default=list(DEFAULT_METHODS),
        help=f"comma-separated registered methods (default: {','.join(DEFAULT_METHODS)})",
    )
    parser.add_argument("--episodes", type=count(1), default=20, help="episodes per cell and method (>= 1)")
    parser.add_argument("--seed", type=count(0), default=0, help="world seed of the first episode (>= 0)")
    parser.add_argument("--workers", type=count(1), default=None, help="local processes (>= 1; default: all cores)")
    parser.add_argument("--out", type=output_directory, default=pathlib.Path("out/sweep"), help="output directory")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(func=_run)
