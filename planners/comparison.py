"""Factories for the planners the paper compares (Section IV).

* `interval_robust_planner`: the proposed robust planner, one `IntervalModel` over the
  parameter confidence set, searched by `RobustTreePlanner` (M = 1);
* `multi_model_robust_planner`: one `IntervalModel` per surviving structural
  hypothesis, maximising the worst case over them (eqs. (15)-(18));
* `nominal_planner`: certainty equivalence, OPD on a `PointModel` at the estimate;
* `oracle_planner`: OPD on a `PointModel` at the true parameters (the reference of the
  suboptimality study).

All take the paper's defaults gamma = 0.9 and K = 100 expansions. Start a search with
``planner.plan(root_state(planner, lower, upper, time=t))``.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..models.errors import InputError
from .interval_model import IntervalModel
from .point_model import PointModel
from .search import OptimisticPlanner, RobustTreePlanner

__all__ = [
    "interval_robust_planner",
    "multi_model_robust_planner",
    "nominal_planner",
    "oracle_planner",
    "root_state",
]

#: The paper's discount (eta) and planning budget (K), Section IV.
PAPER_GAMMA = 0.9
PAPER_BUDGET = 100


def interval_robust_planner(
    system, parameters, reward, controllers, *, gamma: float = PAPER_GAMMA, budget: int = PAPER_BUDGET, substeps: int = 1
) -> RobustTreePlanner:
    """The robust planner on one interval model (surrogate objective (11))."""
    model = IntervalModel(system, parameters, reward, controllers, substeps=substeps)
    return RobustTreePlanner([model], model.actions, gamma=gamma, budget=budget)


def multi_model_robust_planner(
    systems_with_parameters: Sequence,
    reward,
    controllers,
    *,
    gamma: float = PAPER_GAMMA,
    budget: int = PAPER_BUDGET,
    substeps: int = 1,
) -> RobustTreePlanner:
    """The multi-model robust planner: one interval model per ``(system, parameters)`` pair.

    The systems must share the state and input dimensions (the same plant under
    different structural hypotheses); every model starts from the same box. The
    models are linked (`IntervalModel.linked`): one batched computation per expansion
    steps every hypothesis under every action.
    """
    models = IntervalModel.linked(systems_with_parameters, reward, controllers, substeps=substeps)
    return RobustTreePlanner(models, models[0].actions, gamma=gamma, budget=budget)


def nominal_planner(
    system, theta_hat, reward, controllers, *, gamma: float = PAPER_GAMMA, budget: int = PAPER_BUDGET, substeps: int = 1
) -> OptimisticPlanner:
    """OPD with the estimated parameters (certainty equivalence, w = 0)."""
    model = PointModel(system, theta_hat, reward, controllers, substeps=substeps)
    return OptimisticPlanner(model, model.actions, gamma=gamma, budget=budget)


def oracle_planner(
    system, theta_true, reward, controllers, *, gamma: float = PAPER_GAMMA, budget: int = PAPER_BUDGET, substeps: int = 1
) -> OptimisticPlanner:
    """OPD with the true parameters (w = 0): the oracle of the suboptimality study."""
    return nominal_planner(system, theta_true, reward, controllers, gamma=gamma, budget=budget, substeps=substeps)


def root_state(planner: RobustTreePlanner, lower, upper=None, *, time: int = 0):
    """The root state for a planner made by these factories.

    For interval models, the box ``[lower, upper]`` (or a `Box`); for point models, the
    state ``lower`` (``upper`` must then be None).
    """
    model = planner.models[0]
    if isinstance(model, PointModel):
        if upper is not None:
            raise InputError("a point-model planner starts from one state: give lower only")
        return model.initial_state(lower, time=time)
    return model.initial_state(lower, upper, time=time)
