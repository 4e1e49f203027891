"""minimaxplan.analysis: orchestration, reports and plots (nothing imports it).

Scenario and method registries (`register_scenario`, `register_method`; the interfaces
`Scenario`, `World`, `Method`, `Policy` in `registry`, pinned in ``docs/extending.md``),
the one episode loop of the paper's Figure 1 (`episode.run_episode`), the robot
scenarios and their methods (`robot_scenario`, `robot_methods`), Monte-Carlo
experiments (`experiment.run_experiment`, Table 3), the suboptimality study
(`suboptimality`, Figure 6), model files, data files and reports (`model_file`,
`data_file`, `reports`), and the ``minimaxplan`` console script (`cli`). The only layer
that prints or plots.
"""

from .registry import (
    EpisodeFailure,
    Method,
    Policy,
    Scenario,
    Transition,
    UnknownMethod,
    UnknownScenario,
    UnsupportedScenario,
    World,
    method_names,
    register_method,
    register_scenario,
    scenario_names,
)

__all__ = [
    "register_scenario",
    "register_method",
    "scenario_names",
    "method_names",
    "Scenario",
    "World",
    "Method",
    "Policy",
    "Transition",
    "EpisodeFailure",
    "UnknownScenario",
    "UnknownMethod",
    "UnsupportedScenario",
]
