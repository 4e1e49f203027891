"""``minimaxplan sweep``: where each method breaks, beyond the paper's worlds.

Usage::

    minimaxplan sweep --scenario pedestrian --pedestrians 1,3,5,8 --velocity-uncertainty 0.1,0.3,0.6
                      --methods robust,dwa,teb --episodes N [--seed S] [--workers W] --out DIR
    minimaxplan sweep --scenario highway --vehicles 5,10,15,25 --episodes N --out DIR
    minimaxplan sweep --scenario tjunction --arrival-rate 300,600,900,1200 --episodes N --out DIR

A cell of the sweep is a variant of one world, set by the values of that world's sweep
axes (`SweepAxis`; each world's are in `SWEEP_WORLDS`):

- ``pedestrian``: the crowd size and the pedestrians' velocity uncertainty. The paper's
  pedestrian world has 1-3 pedestrians whose velocity is known within +-0.3 m/s per axis,
  and there robust, DWA and TEB all stay near 0 failures in 100. `make_crowd_world` keeps
  the world's layout, friction, disturbances and noise for a seed and gives it a crowd of
  exactly that many pedestrians whose true velocity stays within the stated uncertainty
  of the announced one (`RobotWorld.with_crowd`).
- ``highway``: the traffic density as the number of other vehicles
  (`HighwayScenario.vehicle_count`; 15 in the default world), placed lane by lane from
  100 m behind the ego with the world's spacing rule.
- ``tjunction``: the traffic density as the arrival rate of main-road vehicles per
  direction, veh/h (600 in the default world): headways ``headway_min +
  Exponential(headway_mean_extra)`` s with ``headway_min`` kept at 3 s and
  ``headway_mean_extra = 3600 / rate - headway_min`` (`road_density_scenario`), so that
  the rate ranges over (0, 1200] veh/h (at 1200 every headway is 3 s).

Everything else of a seed is the same in every cell (paired comparison). Per cell and
method the sweep reports the failure rate with its exact (Clopper-Pearson) 95% interval,
the failures by outcome and the travel time of the successful episodes with a Student-t
95% interval: where robustness pays, and what it costs. Outputs in DIR: ``sweep.md`` (the
table), ``sweep.json``, ``sweep.csv`` (one row per episode) and ``sweep.png`` (failure
rate and travel time against the first axis, one column of panels per value of the
second).

Exit codes: 0 done; 2 a bad option (one line on stderr, before any episode runs).
"""

from __future__ import annotations

import argparse
import math
import numbers
import pathlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .arguments import (
    Subcommand,
    add_run_options,
    count_list,
    distinct,
    name_list,
    number_list,
    output_directory,
    report_error,
)

if TYPE_CHECKING:
    from minimaxplan.scenarios import RobotWorld
    from minimaxplan.scenarios.road_world import HighwayScenario, TJunctionScenario

    from .episode import EpisodeRecord, LoopConfig
    from .registry import Scenario
    from .road_scenario import RoadScenario
    from .robot_scenario import RobotScenario

__all__ = [
    "SweepAxis",
    "SweepWorld",
    "SWEEP_WORLDS",
    "SWEEP_SCENARIOS",
    "DEFAULT_PEDESTRIANS",
    "DEFAULT_UNCERTAINTIES",
    "DEFAULT_VEHICLES",
    "DEFAULT_ARRIVAL_RATES",
    "DEFAULT_METHODS",
    "DEFAULT_ROAD_METHODS",
    "HEADING_MARGIN",
    "TJUNCTION_HEADWAY_MIN",
    "CrowdScenarioFactory",
    "RoadDensityFactory",
    "cell_name",
    "make_crowd_world",
    "crowd_scenario",
    "road_density_scenario",
    "density_road_scenario",
    "run_sweep",
    "summarise_sweep",
    "sweep_markdown",
    "plot_sweep",
    "COMMAND",
]

DEFAULT_PEDESTRIANS = (1, 3, 5, 8)
#: Per-axis bounds on the pedestrians' velocity error, m/s (the paper's world: 0.3).
DEFAULT_UNCERTAINTIES = (0.1, 0.3, 0.6)
#: Other vehicles on the highway (the default world: 15).
DEFAULT_VEHICLES = (5, 10, 15, 25)
#: Main-road arrival rates at the T-junction, veh/h per direction (the default world: 600).
DEFAULT_ARRIVAL_RATES = (300.0, 600.0, 900.0, 1200.0)
DEFAULT_METHODS = ("robust", "dwa", "teb")
DEFAULT_ROAD_METHODS = ("robust", "nominal", "oracle", "dwa", "teb")
#: The true heading deviates from the announced one by at most ``HEADING_MARGIN * u / s_max``
#: (s_max = 1.5 m/s the fastest pedestrian), so the per-axis velocity error ``s |e|``
#: stays strictly inside the announced bound u; at u = 0.3 m/s this is the paper world's
#: 0.18 rad, and its random-walk step (0.03 rad per sub-step) scales the same way.
HEADING_MARGIN = 0.9
#: The T-junction's minimum headway between main-road arrivals, s, kept in every cell
#: (`TJunctionScenario.headway_min`): the arrival rate is at most 3600 / 3 = 1200 veh/h.
TJUNCTION_HEADWAY_MIN = 3.0
#: Column names of the failure outcomes in the rows and their Markdown headers.
_OUTCOME_COLUMNS = {
    "collision": ("collisions", "collisions"),
    "off_road": ("off_road", "off road"),
    "timeout": ("timeouts", "timeouts"),
}


@dataclass(frozen=True)
class SweepAxis:
    """One quantity a sweep varies in a world, with its unit and its range.

    Attributes
    ----------
    name : str
        Its key in the grid, the rows and the CSV, and the keyword of `run_sweep`
        (``"pedestrians"``).
    label : str
        Words for the table's header and the plot's axis (``"velocity uncertainty"``).
    unit : str
        Its unit (``"m/s"``; ``""`` for a count).
    integer : bool
        Whether the values are counts.
    minimum : float
        The smallest value (excluded if ``strict``).
    strict : bool
        Whether ``minimum`` itself is refused.
    maximum : float or None
        The largest value (included), if any.
    defaults : tuple
        The values swept when none are given.
    help : str
        What a value sets in the world (the option's help).
    """

    name: str
    label: str
    unit: str
    integer: bool
    minimum: float
    strict: bool = False
    maximum: float | None = None
    defaults: tuple = ()
    help: str = ""

    @property
    def option(self) -> str:
        """The command-line option, e.g. ``"--velocity-uncertainty"``."""
        return "--" + self.name.replace("_", "-")

    @property
    def title(self) -> str:
        """The label with its unit, e.g. ``"velocity uncertainty (m/s)"``."""
        return f"{self.label} ({self.unit})" if self.unit else self.label

    @property
    def relation(self) -> str:
        """The range in words, e.g. ``"> 0 and <= 1200"``."""
        low = f"{'>' if self.strict else '>='} {self.minimum:g}"
        return low if self.maximum is None else f"{low} and <= {self.maximum:g}"

    def parser(self) -> Callable[[str], list]:
        """The argparse type of the option: comma-separated distinct values in range."""
        if self.integer:
            return distinct(count_list(int(self.minimum)))
        return distinct(number_list(self.minimum, strict=self.strict, maximum=self.maximum, unit=self.unit))

    def check(self, values: Sequence) -> list:
        """``values`` checked: at least one, each in range, none repeated.

        Parameters
        ----------
        values : sequence
            The values of one sweep.

        Returns
        -------
        list
            ``int`` or ``float`` values, in the given order.

        Raises
        ------
        InputError
            For a value out of range or repeated, or no value.
        """
        from minimaxplan.models import InputError
        from minimaxplan.models.validation import as_count

        checked: list = []
        for i, value in enumerate(values):
            name = f"{self.name}[{i}]"
            if self.integer:
                checked.append(as_count(name, value, minimum=int(self.minimum)))
                continue
            if not isinstance(value, numbers.Real) or isinstance(value, bool) or not math.isfinite(value):
                raise InputError(f"{name} must be a finite number{_unit(self.unit)}, got {value!r}")
            number = float(value)
            below = number <= self.minimum if self.strict else number < self.minimum
            if below or (self.maximum is not None and number > self.maximum):
                raise InputError(f"{name} must be {self.relation}{_unit(self.unit)}, got {value!r}")
            checked.append(number)
        if not checked:
            raise InputError(f"{self.name} must hold at least one value, got none")
        if len(set(checked)) != len(checked):
            raise InputError(f"{self.name} must not repeat a value, got {list(values)}")
        return checked

    def format(self, value: float) -> str:
        """A value as the table shows it (``5``, ``0.3``).

        Parameters
        ----------
        value : float
            A value of the axis, in its unit.
        """
        return str(int(value)) if self.integer else f"{value:g}"


def _unit(unit: str) -> str:
    return f" {unit}" if unit else ""


@dataclass(frozen=True)
class SweepWorld:
    """A world the sweep can vary: its axes, its methods and its failure outcomes.

    Attributes
    ----------
    scenario : str
        The registered scenario whose variants the cells are.
    axes : tuple of SweepAxis
        What a cell sets (one or two axes; the plot's x axis is the first).
    methods : tuple of str
        The methods run when none are given.
    failure_outcomes : tuple of str
        The world's outcomes other than success, counted per row.
    cell_format : str
        `str.format` pattern of a cell's registered name over the axis values.
    """

    scenario: str
    axes: tuple[SweepAxis, ...]
    methods: tuple[str, ...]
    failure_outcomes: tuple[str, ...]
    cell_format: str


#: The worlds `run_sweep` can vary, by scenario name.
SWEEP_WORLDS: dict[str, SweepWorld] = {
    "pedestrian": SweepWorld(
        "pedestrian",
        (
            SweepAxis(
                "pedestrians", "pedestrians", "", True, 0, defaults=DEFAULT_PEDESTRIANS, help="pedestrian counts"
            ),
            SweepAxis(
                "velocity_uncertainty",
                "velocity uncertainty",
                "m/s",
                False,
                0.0,
                defaults=DEFAULT_UNCERTAINTIES,
                help="per-axis bounds on the pedestrians' velocity error",
            ),
        ),
        DEFAULT_METHODS,
        ("collision", "timeout"),
        "pedestrian[{0} ped +-{1:g} m/s]",
    ),
    "highway": SweepWorld(
        "highway",
        (
            SweepAxis(
                "vehicles",
                "vehicles",
                "",
                True,
                0,
                defaults=DEFAULT_VEHICLES,
                help="counts of other vehicles on the highway (HighwayScenario.vehicle_count)",
            ),
        ),
        DEFAULT_ROAD_METHODS,
        ("collision", "off_road", "timeout"),
        "highway[{0} vehicles]",
    ),
    "tjunction": SweepWorld(
        "tjunction",
        (
            SweepAxis(
                "arrival_rate",
                "arrival rate",
                "veh/h per direction",
                False,
                0.0,
                strict=True,
                maximum=3600.0 / TJUNCTION_HEADWAY_MIN,
                defaults=DEFAULT_ARRIVAL_RATES,
                help="main-road arrival rates at the T-junction, vehicles per hour per direction "
                f"(mean headway 3600 / rate s, at least {TJUNCTION_HEADWAY_MIN:g} s)",
            ),
        ),
        DEFAULT_ROAD_METHODS,
        ("collision", "off_road", "timeout"),
        "tjunction[{0:g} veh/h]",
    ),
}
#: The scenarios the sweep can vary.
SWEEP_SCENARIOS = tuple(SWEEP_WORLDS)
#: Every axis of every world, by name (the keywords of `run_sweep`).
_AXES = {axis.name: (world.scenario, axis) for world in SWEEP_WORLDS.values() for axis in world.axes}


def cell_name(scenario: str, *values: float) -> str:
    """The registered scenario name of one cell, e.g. ``"pedestrian[5 ped +-0.3 m/s]"``.

    Parameters
    ----------
    scenario : str
        The swept scenario (`SWEEP_SCENARIOS`).
    *values : float
        The cell's value on each of the world's axes, in order (pedestrians and velocity
        uncertainty, m/s; vehicles; arrival rate, veh/h per direction).

    Returns
    -------
    str
        A name without commas (the registry's rule): ``"highway[10 vehicles]"``,
        ``"tjunction[600 veh/h]"``.
    """
    return SWEEP_WORLDS[scenario].cell_format.format(*values)


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
        those of ``make_world("pedestrian", seed)``; the crowd is drawn
        (`crossing_crowd`) from a stream of its own, seeded by the seed and the count,
        so the cells of a sweep share everything else.
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
        `RobotWorld.with_crowd` of the pedestrian world (its ``crowd`` is a
        ``BoundedCrowd``, a `PedestrianCrowd` whose heading walk is bounded by the
        uncertainty).

    Raises
    ------
    InputError
        For a seed, count or uncertainty out of range.
    """
    import numpy as np

    from minimaxplan.models.validation import as_count, as_positive_scalar
    from minimaxplan.scenarios import RobotWorld
    from minimaxplan.scenarios import worlds as robot_worlds

    seed = as_count("seed", seed, minimum=0)
    count = as_count("pedestrians", pedestrians, minimum=0)
    bound = as_positive_scalar("velocity_uncertainty", velocity_uncertainty, allow_zero=True)
    crowd_class = _classes()["BoundedCrowd"]

    def crowd(start: np.ndarray, goal: np.ndarray) -> robot_worlds.PedestrianCrowd:
        rng = np.random.default_rng(np.random.SeedSequence([seed, 0xC20D, count]))
        base = robot_worlds.crossing_crowd(rng, count, start, goal)
        deviation = HEADING_MARGIN * bound / robot_worlds.PEDESTRIAN_SPEED[1]
        ratio = deviation / robot_worlds.PEDESTRIAN_HEADING_DEVIATION
        return crowd_class(
            **vars(base), max_deviation=deviation, deviation_step=robot_worlds.PEDESTRIAN_HEADING_STEP * ratio
        )

    return RobotWorld.with_crowd("pedestrian", seed, crowd, velocity_uncertainty=bound, measurement=measurement)


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
    return _classes()["CrowdScenario"](pedestrians, velocity_uncertainty)


def road_density_scenario(kind: str, density: float) -> HighwayScenario | TJunctionScenario:
    """The constants of a driving world at a traffic density, the others the defaults.

    Parameters
    ----------
    kind : {"highway", "tjunction"}
        The driving world.
    density : float
        ``"highway"``: the number of other vehicles (an integer >= 0, the world's
        ``vehicle_count``). ``"tjunction"``: the main-road arrival rate per direction,
        veh/h, in (0, 3600 / `TJUNCTION_HEADWAY_MIN`]: ``headway_min`` = 3 s and
        ``headway_mean_extra = 3600 / density - 3`` s (mean headway ``3600 / density`` s).

    Returns
    -------
    HighwayScenario or TJunctionScenario
        The default world's constants but for the density (the defaults at 15 vehicles
        and 600 veh/h).

    Raises
    ------
    InputError
        For an unknown kind or a density out of range.
    """
    from minimaxplan.models.validation import as_choice
    from minimaxplan.scenarios.road_world import HighwayScenario, TJunctionScenario

    as_choice("kind", kind, ("highway", "tjunction"))
    axis = SWEEP_WORLDS[kind].axes[0]
    (value,) = axis.check([density])
    if kind == "highway":
        return HighwayScenario(vehicle_count=value)
    return TJunctionScenario(
        headway_min=TJUNCTION_HEADWAY_MIN, headway_mean_extra=3600.0 / value - TJUNCTION_HEADWAY_MIN
    )


def density_road_scenario(kind: str, density: float) -> RoadScenario:
    """The road scenario of one cell: the driving world of `road_density_scenario`.

    Parameters
    ----------
    kind : {"highway", "tjunction"}
        The driving world.
    density : float
        As in `road_density_scenario`.

    Returns
    -------
    RoadScenario
        A ``DensityRoadScenario`` (its ``kind`` the world's, so every road method
        drives it), whose ``make_world(seed, config)`` is the world of ``seed`` with
        those constants.
    """
    return _classes()["DensityRoadScenario"](kind, density)


_CLASSES: dict[str, type] = {}


def _classes() -> dict[str, type]:
    """``BoundedCrowd``, ``CrowdScenario`` and ``DensityRoadScenario``, built once on first use.

    They subclass library classes that import numpy: defining them at import time would
    make ``minimaxplan --help`` import the library.
    """
    if _CLASSES:
        return _CLASSES
    import dataclasses

    import numpy as np

    from minimaxplan.models import InputError
    from minimaxplan.scenarios import worlds as robot_worlds
    from minimaxplan.scenarios.road_world import make_road_world

    from .road_scenario import DrivingWorld, RoadScenario
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

    class CrowdScenario(RobotScenario):
        """The robot scenario whose worlds are `make_crowd_world` worlds of one grid cell."""

        def __init__(self, pedestrians: int, velocity_uncertainty: float) -> None:
            super().__init__("pedestrian")
            self.pedestrians, self.velocity_uncertainty = pedestrians, velocity_uncertainty

        def __repr__(self) -> str:
            return f"CrowdScenario(pedestrians={self.pedestrians}, velocity_uncertainty={self.velocity_uncertainty})"

        def make_world(self, seed: int, config: LoopConfig) -> RobotWorld:
            return make_crowd_world(
                seed,
                pedestrians=self.pedestrians,
                velocity_uncertainty=self.velocity_uncertainty,
                measurement=config.measurement,
            )

    class DensityRoadScenario(RoadScenario):
        """The road scenario whose worlds have the traffic density of one cell."""

        def __init__(self, kind: str, density: float) -> None:
            super().__init__(kind)
            self.density = density
            self.constants = road_density_scenario(kind, density)

        def __repr__(self) -> str:
            return f"DensityRoadScenario({self.kind!r}, density={self.density:g})"

        def make_world(self, seed: int, config: LoopConfig) -> DrivingWorld:
            if config.measurement != "uniform":
                raise InputError(f"the road worlds measure with bounded uniform noise only, got {config.measurement!r}")
            return DrivingWorld(make_road_world(self.kind, seed, scenario=self.constants))

    for cls in (BoundedCrowd, CrowdScenario, DensityRoadScenario):
        cls.__module__, cls.__qualname__ = __name__, cls.__name__
        _CLASSES[cls.__name__] = cls
    return _CLASSES


@dataclass(frozen=True)
class CrowdScenarioFactory:
    """A picklable scenario factory of one pedestrian cell (equal cells compare equal).

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


@dataclass(frozen=True)
class RoadDensityFactory:
    """A picklable scenario factory of one driving cell (equal cells compare equal).

    Attributes
    ----------
    kind : str
        ``"highway"`` or ``"tjunction"``.
    density : float
        Vehicles (highway) or arrival rate, veh/h per direction (T-junction).
    """

    kind: str
    density: float

    def __call__(self) -> RoadScenario:
        """The cell's scenario (`density_road_scenario`)."""
        return density_road_scenario(self.kind, self.density)


def _cell_factory(scenario: str, values: tuple) -> Callable[[], Scenario]:
    if scenario == "pedestrian":
        return CrowdScenarioFactory(*values)
    return RoadDensityFactory(scenario, *values)


def run_sweep(
    *,
    scenario: str = "pedestrian",
    pedestrians: Sequence[int] | None = None,
    velocity_uncertainty: Sequence[float] | None = None,
    vehicles: Sequence[int] | None = None,
    arrival_rate: Sequence[float] | None = None,
    methods: Sequence[str] | None = None,
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
        One of `SWEEP_SCENARIOS`; only its axes may be given.
    pedestrians : sequence of int, optional
        ``"pedestrian"``: crowd sizes (each >= 0, distinct; default `DEFAULT_PEDESTRIANS`).
    velocity_uncertainty : sequence of float, optional
        ``"pedestrian"``: per-axis velocity-error bounds, m/s (each >= 0, finite,
        distinct; default `DEFAULT_UNCERTAINTIES`).
    vehicles : sequence of int, optional
        ``"highway"``: other vehicles (each >= 0, distinct; default `DEFAULT_VEHICLES`).
    arrival_rate : sequence of float, optional
        ``"tjunction"``: main-road arrival rates, veh/h per direction (each in (0, 1200],
        distinct; default `DEFAULT_ARRIVAL_RATES`).
    methods : sequence of str, optional
        Registered methods that drive the world (default: the world's
        `SweepWorld.methods`).
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
        ``grid`` (the scenario, each axis's values, the methods, episodes and seed),
        ``rows`` (`summarise_sweep`), ``records`` (the episodes' CSV rows, each with the
        cell's axis values first) and ``wall_time_s``.

    Raises
    ------
    InputError
        Before any episode runs, for a value out of range or repeated, an axis of
        another world, or an unknown scenario.
    UnknownMethod, UnsupportedScenario
        Before any episode runs, for a method that is not registered or cannot drive the worlds.

    Notes
    -----
    A cell's value on an axis is its registered scenario's constant (`cell_name`), so a
    sweep of 1 value per axis at the default world's value (15 vehicles, 600 veh/h)
    runs the default world's episodes.
    """
    import itertools

    from minimaxplan.models import InputError
    from minimaxplan.models.validation import as_choice, as_count

    from .episode import DEFAULT_CONFIG
    from .experiment import run_experiment
    from .registry import register_scenario

    as_choice("scenario", scenario, SWEEP_SCENARIOS)
    world = SWEEP_WORLDS[scenario]
    given: dict[str, Sequence[float] | None] = {
        "pedestrians": pedestrians,
        "velocity_uncertainty": velocity_uncertainty,
        "vehicles": vehicles,
        "arrival_rate": arrival_rate,
    }
    for name, values in given.items():
        if values is not None and _AXES[name][0] != scenario:
            raise InputError(f"{name} is an axis of the {_AXES[name][0]} sweep, not of the {scenario} sweep")
    grid = {}
    for axis in world.axes:
        values = given[axis.name]
        grid[axis.name] = axis.check(axis.defaults if values is None else values)
    methods = list(world.methods if methods is None else methods)
    if not methods:
        raise InputError("methods must hold at least one value, got none")
    if len(set(methods)) != len(methods):
        raise InputError(f"methods must not repeat a value, got {methods}")
    cells: dict[str, dict[str, float]] = {}
    for values in itertools.product(*grid.values()):
        name = cell_name(scenario, *values)
        register_scenario(name, _cell_factory(scenario, values))
        cells[name] = dict(zip(grid, values))
    result = run_experiment(
        list(cells),
        methods,
        episodes=episodes,
        seed=seed,
        config=DEFAULT_CONFIG if config is None else config,
        workers=workers,
        progress=progress,
    )
    records = [{**cells[record.scenario], **record.row()} for record in result.records]
    return {
        "grid": {
            "scenario": scenario,
            **grid,
            "methods": methods,
            "episodes": as_count("episodes", episodes),
            "seed": seed,
        },
        "rows": summarise_sweep(result.records, cells, failure_outcomes=world.failure_outcomes),
        "records": records,
        "wall_time_s": result.wall_time_s,
    }


def summarise_sweep(
    records: Sequence[EpisodeRecord],
    cells: Mapping[str, Mapping[str, float]],
    *,
    failure_outcomes: Sequence[str] = ("collision", "timeout"),
) -> list[dict]:
    """One row per (cell, method): failure rate and travel time with 95% intervals.

    Parameters
    ----------
    records : sequence of EpisodeRecord
        The episodes, their ``scenario`` the cell names of ``cells``.
    cells : mapping
        Cell name -> the cell's value per axis (``{"pedestrians": 3,
        "velocity_uncertainty": 0.6}``), in the axes' order.
    failure_outcomes : sequence of str
        The world's failure outcomes, each counted in a column (``collision`` ->
        ``collisions``, ``off_road`` -> ``off_road``, ``timeout`` -> ``timeouts``).

    Returns
    -------
    list of dict
        Sorted by the axis values: the axis values, ``method``, ``episodes``,
        ``failures``, ``failure_rate``, ``failure_ci95`` (exact Clopper-Pearson), the
        failure outcomes' counts, ``successes``, ``mean_time_s`` and ``time_ci95``
        (Student-t interval of the mean over the successful episodes; NaN without two
        of them), ``mean_return``, and ``boxes_missed`` and ``boxes_checked``: the
        run-time check's counts of predicted boxes (`EpisodeRecord.boxes_checked`)
        summed over the episodes, None for a method that checked none.
    """
    import numpy as np
    from scipy import stats

    groups: dict[tuple[str, str], list[EpisodeRecord]] = {}
    for record in records:
        groups.setdefault((record.scenario, record.method), []).append(record)
    rows = []
    for (name, method), group in groups.items():
        failures = sum(not r.success for r in group)
        ci = stats.binomtest(failures, len(group)).proportion_ci(confidence_level=0.95, method="exact")
        times = np.array([r.time_s for r in group if r.success], dtype=float)
        if times.size >= 2:
            half = float(stats.t.ppf(0.975, times.size - 1) * times.std(ddof=1) / math.sqrt(times.size))
            time_ci = [float(times.mean()) - half, float(times.mean()) + half]
        else:
            time_ci = [math.nan, math.nan]
        checked = sum(r.boxes_checked for r in group)
        rows.append(
            {
                **cells[name],
                "method": method,
                "episodes": len(group),
                "failures": failures,
                "failure_rate": failures / len(group),
                "failure_ci95": [float(ci.low), float(ci.high)],
                **{_OUTCOME_COLUMNS[o][0]: sum(r.outcome == o for r in group) for o in failure_outcomes},
                "successes": int(times.size),
                "mean_time_s": float(times.mean()) if times.size else math.nan,
                "time_ci95": time_ci,
                "mean_return": float(np.mean([r.discounted_return for r in group])),
                "boxes_missed": sum(r.boxes_missed for r in group) if checked else None,
                "boxes_checked": checked if checked else None,
            }
        )
    axes = list(next(iter(cells.values()), {}))
    rows.sort(key=lambda r: tuple(r[axis] for axis in axes))
    return rows


def _fmt(x: float, digits: int) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def _world(study: dict) -> SweepWorld:
    return SWEEP_WORLDS[study["grid"]["scenario"]]


def _outcomes(world: SweepWorld, rows: Sequence[dict]) -> list[str]:
    """The failure outcomes whose columns the rows hold (all of the world's for a run's rows)."""
    return [o for o in world.failure_outcomes if all(_OUTCOME_COLUMNS[o][0] in r for r in rows)]


def sweep_markdown(study: dict) -> str:
    """The sweep as a Markdown table, one row per cell and method.

    Parameters
    ----------
    study : dict
        A `run_sweep` result.

    Returns
    -------
    str
        The table (a column per axis, then the method, the failures with their exact
        interval, the failures by outcome, the travel time with its interval and the
        mean return) and the run's wall time.
    """
    grid = study["grid"]
    world = _world(study)
    outcomes = _outcomes(world, study["rows"])
    lines = [
        f"Sweep of the {grid['scenario']} world: {grid['episodes']} episodes per cell and method "
        f"(world seeds {grid['seed']}-{grid['seed'] + grid['episodes'] - 1}, the same in every cell). "
        "Failure interval: exact (Clopper-Pearson) 95%; travel time over the episodes that reached the "
        "goal, mean and Student-t 95% interval.",
        "",
        "| "
        + " | ".join([a.title for a in world.axes] + ["method", "failures / episodes", "failure 95% CI"])
        + " | "
        + " | ".join(_OUTCOME_COLUMNS[o][1] for o in outcomes)
        + " | mean time (s) | time 95% CI (s) | mean return |",
        "|" + "---:|" * len(world.axes) + "---|---|---|" + "---:|" * len(outcomes) + "---:|---|---:|",
    ]
    for r in study["rows"]:
        low, high = r["failure_ci95"]
        t_low, t_high = r["time_ci95"]
        time_ci = "-" if math.isnan(t_low) else f"[{t_low:.1f}, {t_high:.1f}]"
        cells = [a.format(r[a.name]) for a in world.axes]
        cells += [r["method"], f"{r['failures']}/{r['episodes']}", f"[{low:.3f}, {high:.3f}]"]
        cells += [str(r[_OUTCOME_COLUMNS[o][0]]) for o in outcomes]
        cells += [_fmt(r["mean_time_s"], 1), time_ci, f"{r['mean_return']:.3f}"]
        lines.append("| " + " | ".join(cells) + " |")
    checking = [r for r in study["rows"] if r.get("boxes_checked")]
    if checking:
        methods = ", ".join(dict.fromkeys(r["method"] for r in checking))
        lines += [
            "",
            f"Run-time check ({methods}): {sum(r['boxes_checked'] for r in checking)} predicted boxes checked "
            f"against the true states, {sum(r['boxes_missed'] for r in checking)} missed (a miss is a bug).",
        ]
    lines += ["", f"Wall time of the run: {study['wall_time_s']:.1f} s"]
    return "\n".join(lines) + "\n"


def plot_sweep(study: dict, path: str | pathlib.Path) -> pathlib.Path:
    """Failure rate and travel time against the first axis, one column per value of the second.

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

    Notes
    -----
    The pedestrian sweep plots against the crowd size, one column per velocity
    uncertainty; a driving sweep against its density (vehicles, or arrival rate in
    veh/h per direction), in one column, with a tick at each swept value. Each method's
    points are shifted sideways by a little (at most 12% of the closest spacing of the x
    values) so that their intervals do not hide one another; the travel-time axis does
    not reach below 0 s.
    """
    from .figures import pyplot, save_png

    plt = pyplot()
    import numpy as np

    from .plots import method_style

    grid = study["grid"]
    world = _world(study)
    x_axis = world.axes[0]
    column_axis = world.axes[1] if len(world.axes) > 1 else None
    columns = grid[column_axis.name] if column_axis else [None]
    fig, axes = plt.subplots(
        2, len(columns), figsize=(4.2 * max(len(columns), 1.5), 7), sharex=True, sharey="row", squeeze=False
    )
    xs = np.unique(np.asarray(grid[x_axis.name], dtype=float))
    spacing = 1.0 if x_axis.integer or xs.size < 2 else float(np.min(np.diff(xs)))
    n = len(grid["methods"])
    offsets = np.linspace(-0.12, 0.12, n) * spacing if n > 1 else [0.0]
    for c, value in enumerate(columns):
        for offset, method in zip(offsets, grid["methods"]):
            rows = [
                r
                for r in study["rows"]
                if r["method"] == method and (column_axis is None or r[column_axis.name] == value)
            ]
            x = np.array([r[x_axis.name] for r in rows], dtype=float) + offset
            style = method_style(method)
            colour = style.get("color")
            rate = np.array([r["failure_rate"] for r in rows])
            ci = np.array([r["failure_ci95"] for r in rows]).reshape(-1, 2)
            axes[0, c].errorbar(
                x, rate, yerr=[rate - ci[:, 0], ci[:, 1] - rate], fmt="o-", color=colour, capsize=3, label=method
            )
            mean = np.array([r["mean_time_s"] for r in rows], dtype=float)
            tci = np.array([r["time_ci95"] for r in rows], dtype=float).reshape(-1, 2)
            err = np.where(np.isnan(tci), 0.0, np.abs(tci - mean[:, None])).T
            axes[1, c].errorbar(x, mean, yerr=err, fmt="s-", color=colour, capsize=3, label=method)
        if column_axis is not None:
            axes[0, c].set_title(f"{column_axis.label} +-{column_axis.format(value)} {column_axis.unit} per axis")
        axes[1, c].set_xlabel(x_axis.title)
        axes[1, c].set_xticks(xs, [x_axis.format(x) for x in xs])
        axes[0, c].grid(alpha=0.3)
        axes[1, c].grid(alpha=0.3)
    top = max((r["failure_ci95"][1] for r in study["rows"]), default=1.0)
    axes[0, 0].set_ylim(-0.02, min(1.02, 1.1 * top + 0.02))  # the rows share it (sharey)
    axes[0, 0].set_ylabel("failure rate (95% CI)")
    axes[1, 0].set_ylabel("travel time of successes, s (95% CI)")
    if axes[1, 0].get_ylim()[0] < 0:  # a wide t interval of few successes reaches below 0 s
        axes[1, 0].set_ylim(bottom=0.0)
    axes[0, 0].legend()
    fig.suptitle(f"Where each method breaks: {grid['scenario']} world, {grid['episodes']} episodes per point")
    fig.tight_layout()
    return save_png(fig, path)


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


def _scenario(text: str) -> str:
    if text not in SWEEP_SCENARIOS:
        raise argparse.ArgumentTypeError(f"the sweep varies the scenarios {list(SWEEP_SCENARIOS)}, got {text!r}")
    return text


def _run(args: argparse.Namespace) -> int:
    from minimaxplan.models import MinimaxplanError

    from .registry import UnknownMethod, UnsupportedScenario

    for name, (scenario, axis) in _AXES.items():
        if getattr(args, name) is not None and scenario != args.scenario:
            args.parser.error(f"argument {axis.option}: varies the {scenario} world, not the {args.scenario} world")
    try:
        study = run_sweep(
            scenario=args.scenario,
            **{name: getattr(args, name) for name in _AXES},
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


def _add_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--scenario", type=_scenario, default="pedestrian", help=f"the world to vary: {', '.join(SWEEP_SCENARIOS)}"
    )
    for world in SWEEP_WORLDS.values():
        for axis in world.axes:
            parser.add_argument(
                axis.option,
                type=axis.parser(),
                default=None,
                metavar="N,..." if axis.integer else "X,...",
                help=f"--scenario {world.scenario}: comma-separated {axis.help}, each "
                f"{axis.relation}{_unit(axis.unit)} (default: {','.join(axis.format(v) for v in axis.defaults)})",
            )
    parser.add_argument(
        "--methods",
        type=distinct(name_list),
        default=None,
        help="comma-separated registered methods (default: "
        + "; ".join(f"{w.scenario}: {','.join(w.methods)}" for w in SWEEP_WORLDS.values())
        + ")",
    )
    add_run_options(parser, episodes=20, episodes_help="episodes per cell and method (>= 1)")
    parser.add_argument("--out", type=output_directory, default=pathlib.Path("out/sweep"), help="output directory")


COMMAND = Subcommand(
    "sweep",
    help="failure rate and travel time per method over crowd size and uncertainty, or traffic density",
    description="Run every method over a grid of variants of one world: pedestrian counts and velocity "
    "uncertainties of the pedestrian world, the number of vehicles on the highway, or the main-road "
    "arrival rate at the T-junction; write the failure rate (exact 95% interval) and the travel time "
    "(95% interval) per cell and method as a table, a plot, JSON and CSV. A run has EPISODES x cells x "
    "methods episodes (20 x 4 x 3 x 3 = 720 for the pedestrian defaults with --episodes 20).",
    epilog="Exit codes: 0 done; 2 a bad option, an unknown method, an axis of another world (one line on "
    "stderr, before any episode runs).",
    add_options=_add_options,
    run=_run,
)
