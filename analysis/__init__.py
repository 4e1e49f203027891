"""minimaxplan.analysis: orchestration, reports and plots (nothing imports it).

Scenario and method registries (`register_scenario`, `register_method`; the interfaces
`Scenario`, `World`, `Method`, `Policy` in `registry`, pinned in ``docs/extending.md``),
the one episode loop of the paper's Figure 1 (`episode.run_episode`), the robot
scenarios and their methods (`robot_scenario`, `robot_methods`), the road scenarios
"highway" and "tjunction" with their DWA and TEB baselines and road figures
(`road_scenario`, `road_methods`), Monte-Carlo
experiments (`experiment.run_experiment`, Table 3), the suboptimality study
(`suboptimality`, Figure 6), model files, data files and reports (`model_file`,
`data_file`, `reports`), and the ``minimaxplan`` console script (`cli`). The only layer
that prints or plots.

The registry names below are loaded on first use (PEP 562), so that importing
`minimaxplan.analysis.cli` for ``minimaxplan --help`` imports neither numpy nor the
rest of the library.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .registry import (
        CrowdedWorld,
        EpisodeFailure,
        GroundTruthWorld,
        Method,
        Policy,
        PredictingPolicy,
        Scenario,
        TracedWorld,
        Transition,
        UnknownMethod,
        UnknownScenario,
        UnsupportedScenario,
        World,
        box_kind,
        default_scenario_names,
        method_names,
        register_method,
        register_scenario,
        scenario_names,
    )

__all__ = [
    "register_scenario",
    "register_method",
    "scenario_names",
    "default_scenario_names",
    "method_names",
    "Scenario",
    "World",
    "Method",
    "Policy",
    "PredictingPolicy",
    "GroundTruthWorld",
    "TracedWorld",
    "CrowdedWorld",
    "box_kind",
    "Transition",
    "EpisodeFailure",
    "UnknownScenario",
    "UnknownMethod",
    "UnsupportedScenario",
]


def __getattr__(name: str) -> Any:
    if name in __all__:
        value = getattr(importlib.import_module(".registry", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
