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
    system,
    parameters,
    reward,
    controllers,
    *,
    gamma: float = PAPER_GAMMA,
    budget: int = PAPER_BUDGET,
    substeps: int = 1,
) -> RobustTreePlanner:
    """The robust planner on one interval model (surrogate objective (11)).

    Parameters
    ----------
    system : UncertainLinearSystem
        The plant ``x+ = A(theta) x + B u + D w`` (one sub-step).
    parameters : Box, Ellipsoid, array_like of shape (k, d), or None
        The parameter confidence set (as for `IntervalModel`); None means
        ``system.theta``.
    reward : BoxReward
        The reward family (rewards in [0, 1]), e.g. `minimaxplan.scenarios.GoalReward`.
    controllers : sequence of OpenLoop or LinearFeedback
        One low-level controller per action (Section III-B).
    gamma : float, optional
        Discount factor eta, 0 < gamma < 1 (default 0.9, the paper's).
    budget : int, optional
        Number of tree expansions K >= 1 (default 100, the paper's).
    substeps : int, optional
        Sub-steps of the system per decision (>= 1, default 1).

    Returns
    -------
    RobustTreePlanner
        A planner over one `IntervalModel` (M = 1); its actions are the controller
        indices.

    Raises
    ------
    InputError
        If an argument is invalid (see `IntervalModel` and `RobustTreePlanner`).

    Notes
    -----
    The planner maximises the surrogate objective (11), a lower bound of the robust
    objective (10) (Theorem 1), with the optimistic upper bound (12).
    """
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

    Parameters
    ----------
    systems_with_parameters : sequence of (UncertainLinearSystem, parameter set or None)
        The M >= 1 surviving hypotheses, as for `IntervalModel.linked`.
    reward : BoxReward
        The reward family (rewards in [0, 1]), e.g. `minimaxplan.scenarios.GoalReward`.
    controllers : sequence of OpenLoop or LinearFeedback
        One low-level controller per action (Section III-B).
    gamma : float, optional
        Discount factor eta, 0 < gamma < 1 (default 0.9, the paper's).
    budget : int, optional
        Number of tree expansions K >= 1 (default 100, the paper's).
    substeps : int, optional
        Sub-steps of the system per decision (>= 1, default 1).

    Returns
    -------
    RobustTreePlanner
        A planner over the M linked models.

    Raises
    ------
    InputError
        If an argument is invalid (see `IntervalModel.linked` and `RobustTreePlanner`).
    DimensionError
        If the systems' numbers of states and inputs differ.

    Notes
    -----
    The robust objective (15) over the hypotheses, searched with the robust bounds
    (16)-(18); Theorem 3 (eq. (19)) bounds its value.
    """
    models = IntervalModel.linked(systems_with_parameters, reward, controllers, substeps=substeps)
    return RobustTreePlanner(models, models[0].actions, gamma=gamma, budget=budget)


def nominal_planner(
    system, theta_hat, reward, controllers, *, gamma: float = PAPER_GAMMA, budget: int = PAPER_BUDGET, substeps: int = 1
) -> OptimisticPlanner:
    """OPD with the estimated parameters (certainty equivalence, w = 0).

    Parameters
    ----------
    system : UncertainLinearSystem
        The plant (one sub-step).
    theta_hat : array_like, shape (d,)
        The parameter estimate the plant is simulated with.
    reward : BoxReward
        The reward family (rewards in [0, 1]), e.g. `minimaxplan.scenarios.GoalReward`.
    controllers : sequence of OpenLoop or LinearFeedback
        One low-level controller per action (Section III-B).
    gamma : float, optional
        Discount factor eta, 0 < gamma < 1 (default 0.9, the paper's).
    budget : int, optional
        Number of tree expansions K >= 1 (default 100, the paper's).
    substeps : int, optional
        Sub-steps of the system per decision (>= 1, default 1).

    Returns
    -------
    OptimisticPlanner
        OPD (eq. (12)) on a `PointModel` at ``theta_hat``.

    Raises
    ------
    InputError
        If an argument is invalid (see `PointModel` and `RobustTreePlanner`).
    """
    model = PointModel(system, theta_hat, reward, controllers, substeps=substeps)
    return OptimisticPlanner(model, model.actions, gamma=gamma, budget=budget)


def oracle_planner(
    system,
    theta_true,
    reward,
    controllers,
    *,
    gamma: float = PAPER_GAMMA,
    budget: int = PAPER_BUDGET,
    substeps: int = 1,
) -> OptimisticPlanner:
    """OPD with the true parameters (w = 0): the oracle of the suboptimality study.

    Parameters
    ----------
    system : UncertainLinearSystem
        The plant (one sub-step).
    theta_true : array_like, shape (d,)
        The true parameters.
    reward : BoxReward
        The reward family (rewards in [0, 1]), e.g. `minimaxplan.scenarios.GoalReward`.
    controllers : sequence of OpenLoop or LinearFeedback
        One low-level controller per action (Section III-B).
    gamma : float, optional
        Discount factor eta, 0 < gamma < 1 (default 0.9, the paper's).
    budget : int, optional
        Number of tree expansions K >= 1 (default 100, the paper's).
    substeps : int, optional
        Sub-steps of the system per decision (>= 1, default 1).

    Returns
    -------
    OptimisticPlanner
        OPD (eq. (12)) on a `PointModel` at ``theta_true``.

    Raises
    ------
    InputError
        If an argument is invalid (see `PointModel` and `RobustTreePlanner`).

    Notes
    -----
    Its value is the reference ``J-bar`` of the suboptimality of Theorem 2 (eq. (14))
    and Section IV.
    """
    return nominal_planner(system, theta_true, reward, controllers, gamma=gamma, budget=budget, substeps=substeps)


def root_state(planner: RobustTreePlanner, lower, upper=None, *, time: int = 0):
    """The root state for a planner made by these factories.

    Parameters
    ----------
    planner : RobustTreePlanner
        A planner made by `interval_robust_planner`, `multi_model_robust_planner`,
        `nominal_planner` or `oracle_planner`.
    lower : Box or array_like, shape (p,)
        For interval models, a `Box` or the box's lower corner; for point models,
        the measured state.
    upper : array_like, shape (p,), optional
        For interval models, the upper corner (None: the degenerate box
        ``[lower, lower]``); must be None for point models.
    time : int, optional
        The absolute sub-step index (>= 0, default 0).

    Returns
    -------
    BoxState or PointState
        The state to pass to ``planner.plan``.

    Raises
    ------
    InputError
        If ``upper`` is given for a point-model planner, or as for
        `IntervalModel.initial_state` and `PointModel.initial_state`.
    """
    model = planner.models[0]
    if isinstance(model, PointModel):
        if upper is not None:
            raise InputError("a point-model planner starts from one state: give lower only")
        return model.initial_state(lower, time=time)
    return model.initial_state(lower, upper, time=time)
