"""Bad input, everywhere: every public entry point rejects an invalid argument (issue 10 item 5).

The contract, for every argument of every entry point of DESIGN.md's public API (plus the
reward families and `make_world`): an invalid value raises a `MinimaxplanError` subclass
(`InputError`, `DimensionError`, `NonFiniteError`, ...) whose message names the argument,
while the other arguments are valid. Never a builtin error from deep inside numpy, never a
silent acceptance, never a crash. Valid edge inputs must not raise.

Two layers of inputs:

* a fixed catalogue (`CASES`): for each argument, the invalid values of its kind (wrong
  shapes, 0x0 and empty arrays, NaN/inf, strings, numeric strings and lists of them,
  bools where numbers are meant, None, huge integers, negative counts, objects), run by
  `test_entry_point_rejects_catalogue` and counted by `test_inputs_tried`: the count is
  deterministic (no randomness in the catalogue) and does not depend on how pytest-xdist
  distributes the tests;
* hypothesis-drawn values per argument kind (`test_entry_point_rejects_drawn`; the ``ci``
  profile is derandomised), on top of the catalogue.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from minimaxplan.models import (
    Box,
    ConfidenceEllipsoidEstimator,
    Ellipsoid,
    MinimaxplanError,
    SetMembershipEstimator,
    UncertainLinearSystem,
    confidence_ellipsoid,
    predict_tube,
)
from minimaxplan.planners import IntervalModel, OpenLoop, OptimisticPlanner, RobustTreePlanner
from minimaxplan.scenarios import GoalReward, SpeedLaneReward, make_world
from minimaxplan.verify import ModelSelector, check_assumption4, eliminate_models, feasible_parameter_box

# --------------------------------------------------------------------------- valid values

A0 = np.array([[0.9, 0.1], [0.0, 0.8]])
PHI = np.array([[[0.1, 0.0], [0.0, 0.0]]])
B = np.array([[0.0], [1.0]])
W = Box(np.array([-0.01, -0.01]), np.array([0.01, 0.01]))
THETA = Box(np.array([-0.1]), np.array([0.1]))


def system() -> UncertainLinearSystem:
    return UncertainLinearSystem(A0, PHI, B, w=W, theta=THETA)


SYSTEM = system()
X0 = Box(np.array([0.0, 0.0]), np.array([0.1, 0.1]))
CONTROLS = np.zeros((3, 1))
STATES = np.array([[0.0, 0.0], [0.0, 0.1], [0.01, 0.18]])
INPUTS = np.array([[0.1], [0.1]])
REGRESSORS = np.ones((3, 2, 1))
TARGETS = np.ones((3, 2))
GOAL = np.array([1.0, 1.0])


class ScalarModel:
    """A planner model on a scalar state: two actions, reward in [0, 1]."""

    def __init__(self, reward: Any = 0.5, next_state: Any = None) -> None:
        self.reward = reward
        self.next_state = next_state

    def step(self, state, action):
        nxt = state + action if self.next_state is None else self.next_state
        return nxt, self.reward


def interval_model(**changes: Any) -> IntervalModel:
    arguments: dict[str, Any] = {
        "system": SYSTEM,
        "parameters": THETA,
        "reward": GoalReward(GOAL),
        "controllers": [OpenLoop(np.array([0.0])), OpenLoop(np.array([1.0]))],
    }
    arguments.update(changes)
    return IntervalModel(**arguments)


# --------------------------------------------------------------------------- invalid values


class Opaque:
    """An object of no numeric kind."""

    def __repr__(self) -> str:
        return "Opaque()"


class Pool(list):
    """A list of (label, invalid value) pairs that remembers its kind (for the drawn test)."""

    def __init__(self, items, kind: str | None = None) -> None:
        super().__init__(items)
        self.kind = kind

    def __add__(self, other):  # type: ignore[override]
        return Pool(list(self) + list(other), self.kind)


NAN, INF = float("nan"), float("inf")
HUGE = 10**400
#: Values that are never a valid argument of any kind here.
ALWAYS_BAD: list[tuple[str, Any]] = [
    ("None", None),
    ("text", "abc"),
    ("empty text", ""),
    ("object", Opaque()),
    ("dict", {}),
    ("function", lambda: 0),
    ("complex", 1j),
]
#: Invalid values for a real scalar (any sign); ``scalar_bad`` adds the sign rules.
SCALAR_BAD: list[tuple[str, Any]] = ALWAYS_BAD + [
    ("numeric text", "0.5"),
    ("integer text", "1"),
    ("True", True),
    ("False", False),
    ("numpy bool", np.True_),
    ("nan", NAN),
    ("inf", INF),
    ("-inf", -INF),
    ("numpy nan", np.float64("nan")),
    ("huge int", HUGE),
    ("list", [0.5]),
    ("pair", np.array([0.5, 0.5])),
    ("list of text", ["0.5"]),
    ("empty array", np.empty(0)),
]


def positive_bad(allow_zero: bool = False) -> list[tuple[str, Any]]:
    extra = [("negative", -1.0), ("tiny negative", -1e-300), ("negative int", -3)]
    if not allow_zero:
        extra += [("zero", 0.0), ("int zero", 0), ("-0.0", -0.0)]
    return Pool(SCALAR_BAD + extra, "nonneg" if allow_zero else "positive")


def unit_interval_bad() -> list[tuple[str, Any]]:
    """Invalid values for a number in the open interval (0, 1)."""
    return Pool(positive_bad() + [("one", 1.0), ("above one", 1.5), ("int one", 1), ("large", 1e300)], "unit")


def count_bad(minimum: int = 1, *, seed: bool = False) -> list[tuple[str, Any]]:
    """Invalid values for an integer count >= minimum (a seed: any size is valid)."""
    cases = ALWAYS_BAD + [
        ("below minimum", minimum - 1),
        ("negative", -5),
        ("float", 2.5),
        ("integral float", 2.0),
        ("numeric text", "3"),
        ("True", True),
        ("False", False),
        ("nan", NAN),
        ("inf", INF),
        ("list", [3]),
        ("array", np.array([3, 3])),
    ]
    return Pool(cases if seed else cases + [("huge int", 10**30), ("huger int", HUGE)], f"count:{minimum}")


def array_bad(shape: tuple[int, ...]) -> list[tuple[str, Any]]:
    """Invalid values for a finite real array of ``shape`` (every entry free)."""
    good = np.zeros(shape)
    cases = ALWAYS_BAD + [
        ("list of numeric text", np.full(shape, "0.5").tolist() if shape else ["0.5"]),
        ("numeric text", "0.5"),
        ("text array", np.full(shape, "1")),
        ("nan entry", np.where(np.arange(good.size).reshape(shape) == 0, NAN, good) if good.size else NAN),
        ("inf entry", np.full(shape, INF)),
        ("-inf entry", np.full(shape, -INF)),
        ("complex array", good + 1j),
        ("bools", np.ones(shape, dtype=bool)),
        ("empty", np.empty(0)),
        ("0x0", np.empty((0, 0))),
        ("extra axis", good[..., None] if shape else np.zeros((1, 1))),
        ("ragged", [[1.0], [1.0, 2.0]]),
        ("object array", np.array([Opaque()] * max(good.size, 1), dtype=object)),
        ("list with None", [None] * max(good.size, 1)),
        ("huge int", [HUGE] * max(good.size, 1)),
    ]
    if len(shape) >= 1 and shape[0] > 0:
        cases.append(("one short", good[:-1]))
        cases.append(("one long", np.concatenate([good, good[:1]])))
    if len(shape) >= 1:
        cases.append(("scalar", 0.5))
    if len(shape) >= 2:
        cases.append(("transposed", np.zeros(shape[::-1] + (1,)) if shape[0] == shape[1] else good.T))
        cases.append(("flattened", good.ravel()))
    return Pool(cases, "array:" + ",".join(map(str, shape)))


def box_bad(dim: int) -> list[tuple[str, Any]]:
    """Invalid values for a `Box` argument of dimension ``dim``."""
    return ALWAYS_BAD + [
        ("array", np.zeros(dim)),
        ("list", [0.0] * dim),
        ("pair of arrays", (np.zeros(dim), np.ones(dim))),
        ("wrong dimension", Box(np.zeros(dim + 1), np.ones(dim + 1))),
        ("ellipsoid", Ellipsoid(np.zeros(dim), np.eye(dim), 1.0)),
        ("numeric text", "1"),
        ("True", True),
    ]


def choice_bad(choices: tuple[str, ...]) -> list[tuple[str, Any]]:
    """Invalid values for one of ``choices``."""
    return [
        ("None", None),
        ("unknown", "nonsense"),
        ("empty", ""),
        ("padded", f" {choices[0]} "),
        ("int", 1),
        ("True", True),
        ("list", [choices[0]]),
        ("object", Opaque()),
        ("bytes", choices[0].encode()),
    ]


# --------------------------------------------------------------------------- the catalogue


@dataclass(frozen=True)
class Case:
    """One invalid input: the entry point, the argument it is given to, and the call."""

    entry: str
    argument: str
    label: str
    value: Any
    call: Callable[[Any], Any]
    names: tuple[str, ...]

    @property
    def id(self) -> str:
        return f"{self.entry}:{self.argument}:{self.label}"


CASES: list[Case] = []
#: One row per argument whose pool has a kind: (entry, argument, kind, call, names).
DRAWN: dict[str, tuple[str, Callable[[Any], Any], tuple[str, ...]]] = {}


def add(entry: str, argument: str, values: list[tuple[str, Any]], call: Callable[[Any], Any], *names: str) -> None:
    """Register the invalid ``values`` of ``argument``; the message must name one of ``names``."""
    for label, value in values:
        CASES.append(Case(entry, argument, label, value, call, names or (argument,)))
    kind = getattr(values, "kind", None)
    if kind is not None:
        DRAWN.setdefault(f"{entry}:{argument}", (kind, call, names or (argument,)))


def kwargs_call(factory: Callable[..., Any], base: dict[str, Any], argument: str) -> Callable[[Any], Any]:
    return lambda value: factory(**{**base, argument: value})


# Box and its methods
add("Box", "low", array_bad((2,)), lambda v: Box(v, np.ones(2)))
add("Box", "high", array_bad((2,)), lambda v: Box(np.zeros(2), v))
add("Box", "low/high", [("low > high", (np.ones(2), np.zeros(2)))], lambda v: Box(*v), "low", "high")
add("Box.from_center", "center", array_bad((2,)), lambda v: Box.from_center(v, np.ones(2)), "center", "radius")
add(
    "Box.from_center",
    "radius",
    [c for c in array_bad((2,)) if c[0] != "scalar"] + [("negative", -np.ones(2)), ("negative scalar", -1.0)],
    lambda v: Box.from_center(np.zeros(2), v),
)
add("Box.contains", "x", array_bad((2,)), lambda v: X0.contains(v))
add("Box.contains", "tol", positive_bad(allow_zero=True), lambda v: X0.contains(np.zeros(2), tol=v))
add("Box.intersect", "other", box_bad(2), lambda v: X0.intersect(v))

# Ellipsoid
ELLIPSOID = Ellipsoid(np.zeros(2), np.eye(2), 1.0)
add("Ellipsoid", "center", array_bad((2,)), lambda v: Ellipsoid(v, np.eye(2), 1.0), "center", "gramian")
add(
    "Ellipsoid",
    "gramian",
    array_bad((2, 2)) + [("not symmetric", np.array([[1.0, 1.0], [0.0, 1.0]])), ("indefinite", -np.eye(2))],
    lambda v: Ellipsoid(np.zeros(2), v, 1.0),
)
add("Ellipsoid", "radius", positive_bad(), lambda v: Ellipsoid(np.zeros(2), np.eye(2), v))
add("Ellipsoid.contains", "t", array_bad((2,)), lambda v: ELLIPSOID.contains(v))
add("Ellipsoid.contains", "tol", positive_bad(allow_zero=True), lambda v: ELLIPSOID.contains(np.zeros(2), tol=v))

# UncertainLinearSystem and its constructors and methods
SYSTEM_ARGS: dict[str, Any] = {"A0": A0, "phi": PHI, "B": B, "w": W, "theta": THETA}
add("UncertainLinearSystem", "A0", array_bad((2, 2)), kwargs_call(UncertainLinearSystem, SYSTEM_ARGS, "A0"))
add("UncertainLinearSystem", "phi", array_bad((1, 2, 2)), kwargs_call(UncertainLinearSystem, SYSTEM_ARGS, "phi"))
# B of shape (p,) is a single input column: valid
B_BAD = [c for c in array_bad((2, 1)) if c[0] != "flattened"]
D_BAD = [c for c in array_bad((2, 2)) if c[0] != "None"]  # None: the identity
add("UncertainLinearSystem", "B", B_BAD, kwargs_call(UncertainLinearSystem, SYSTEM_ARGS, "B"))
add("UncertainLinearSystem", "D", D_BAD, kwargs_call(UncertainLinearSystem, SYSTEM_ARGS, "D"))
add("UncertainLinearSystem", "w", box_bad(2), kwargs_call(UncertainLinearSystem, SYSTEM_ARGS, "w"))
add("UncertainLinearSystem", "theta", box_bad(1), kwargs_call(UncertainLinearSystem, SYSTEM_ARGS, "theta"))
CONTINUOUS_ARGS: dict[str, Any] = {"A": -np.eye(2), "phi": PHI, "B": B, "w": W, "theta": THETA, "dt": 0.1}
FROM_CONTINUOUS = UncertainLinearSystem.from_continuous
add("from_continuous", "A", array_bad((2, 2)), kwargs_call(FROM_CONTINUOUS, CONTINUOUS_ARGS, "A"))
add("from_continuous", "phi", array_bad((1, 2, 2)), kwargs_call(FROM_CONTINUOUS, CONTINUOUS_ARGS, "phi"))
add("from_continuous", "B", B_BAD, kwargs_call(FROM_CONTINUOUS, CONTINUOUS_ARGS, "B"))
add("from_continuous", "D", D_BAD, kwargs_call(FROM_CONTINUOUS, CONTINUOUS_ARGS, "D"))
add("from_continuous", "w", box_bad(2), kwargs_call(FROM_CONTINUOUS, CONTINUOUS_ARGS, "w"))
add("from_continuous", "theta", box_bad(1), kwargs_call(FROM_CONTINUOUS, CONTINUOUS_ARGS, "theta"))
add("from_continuous", "dt", positive_bad(), kwargs_call(FROM_CONTINUOUS, CONTINUOUS_ARGS, "dt"))


def _statespace_args() -> dict[str, Any]:
    import control

    return {
        "sys": control.ss(-np.eye(2), B, np.eye(2), np.zeros((2, 1))),
        "phi": PHI,
        "w": W,
        "theta": THETA,
        "dt": 0.1,
    }


STATESPACE_ARGS = _statespace_args()
FROM_STATESPACE = UncertainLinearSystem.from_statespace
add(
    "from_statespace",
    "sys",
    ALWAYS_BAD + [("matrix", -np.eye(2))],
    kwargs_call(FROM_STATESPACE, STATESPACE_ARGS, "sys"),
)
add("from_statespace", "phi", array_bad((1, 2, 2)), kwargs_call(FROM_STATESPACE, STATESPACE_ARGS, "phi"))
add("from_statespace", "dt", positive_bad(), kwargs_call(FROM_STATESPACE, STATESPACE_ARGS, "dt"))
add("from_statespace", "w", box_bad(2), kwargs_call(FROM_STATESPACE, STATESPACE_ARGS, "w"))
add(
    "from_statespace",
    "phi_time",
    [c for c in choice_bad(("continuous", "discrete")) if c[0] != "None"],  # None: continuous sys
    kwargs_call(FROM_STATESPACE, STATESPACE_ARGS, "phi_time"),
)
THETA_BAD = [c for c in array_bad((1,)) if c[0] != "extra axis"]  # (k, d): k parameter vectors
add("UncertainLinearSystem.A", "theta", THETA_BAD, lambda v: SYSTEM.A(v))
add("UncertainLinearSystem.step", "x", array_bad((2,)), lambda v: SYSTEM.step(v, np.zeros(1), np.zeros(1)))
add("UncertainLinearSystem.step", "u", array_bad((1,)), lambda v: SYSTEM.step(np.zeros(2), v, np.zeros(1)))
add("UncertainLinearSystem.step", "theta", THETA_BAD, lambda v: SYSTEM.step(np.zeros(2), np.zeros(1), v))
add(
    "UncertainLinearSystem.step",
    "w",
    [c for c in array_bad((2,)) if c[0] != "None"],
    lambda v: SYSTEM.step(np.zeros(2), np.zeros(1), np.zeros(1), v),
)
add("UncertainLinearSystem.regressor", "x", array_bad((2,)), lambda v: SYSTEM.regressor(v))

# predict_tube
add("predict_tube", "system", ALWAYS_BAD + [("box", X0)], lambda v: predict_tube(v, X0, CONTROLS))
add("predict_tube", "x0", box_bad(2), lambda v: predict_tube(SYSTEM, v, CONTROLS))
add(
    "predict_tube",
    "controls",
    [c for c in array_bad((3, 1)) if c[0] not in ("one short", "one long")],
    lambda v: predict_tube(SYSTEM, X0, v),
)
add(
    "predict_tube",
    "parameters",
    # None (the prior box), an ellipsoid and a vertex array are valid
    [c for c in box_bad(1) if c[0] not in ("None", "array", "list", "pair of arrays", "ellipsoid")]
    + [
        ("vertices wrong dim", np.zeros((3, 2))),
        ("nan vertices", np.full((2, 1), NAN)),
        ("no vertex", np.empty((0, 1))),
    ],
    lambda v: predict_tube(SYSTEM, X0, CONTROLS, v),
)

# estimation
CE_ARGS: dict[str, Any] = {"sigma": 0.1, "lam": 1.0, "delta": 0.05, "bound": 1.0}
add("confidence_ellipsoid", "regressors", array_bad((3, 2, 1)), lambda v: confidence_ellipsoid(v, TARGETS, **CE_ARGS))
add("confidence_ellipsoid", "targets", array_bad((3, 2)), lambda v: confidence_ellipsoid(REGRESSORS, v, **CE_ARGS))
for _name in ("sigma", "lam", "bound"):
    add(
        "confidence_ellipsoid",
        _name,
        positive_bad(),
        lambda v, n=_name: confidence_ellipsoid(REGRESSORS, TARGETS, **{**CE_ARGS, n: v}),
    )
    add(
        "ConfidenceEllipsoidEstimator",
        _name,
        positive_bad(),
        lambda v, n=_name: ConfidenceEllipsoidEstimator(1, **{**CE_ARGS, n: v}),
    )
add(
    "confidence_ellipsoid",
    "delta",
    unit_interval_bad(),
    lambda v: confidence_ellipsoid(REGRESSORS, TARGETS, **{**CE_ARGS, "delta": v}),
)
add(
    "ConfidenceEllipsoidEstimator",
    "delta",
    unit_interval_bad(),
    lambda v: ConfidenceEllipsoidEstimator(1, **{**CE_ARGS, "delta": v}),
)
add("ConfidenceEllipsoidEstimator", "nparams", count_bad(), lambda v: ConfidenceEllipsoidEstimator(v, **CE_ARGS))


def _ce_update(argument: str) -> Callable[[Any], Any]:
    def call(value: Any) -> Any:
        estimator = ConfidenceEllipsoidEstimator(1, **CE_ARGS)
        regressor, target = (value, np.ones(2)) if argument == "regressor" else (np.ones((2, 1)), value)
        return estimator.update(regressor, target)

    return call


add(
    "ConfidenceEllipsoidEstimator.update",
    "regressor",
    array_bad((2, 1)),
    _ce_update("regressor"),
    "regressor",
    "target",
)
add("ConfidenceEllipsoidEstimator.update", "target", array_bad((2,)), _ce_update("target"))
add("SetMembershipEstimator", "nparams", count_bad(), lambda v: SetMembershipEstimator(v, noise_bound=0.1, prior=THETA))
add(
    "SetMembershipEstimator",
    "noise_bound",
    [c for c in positive_bad() if c[0] not in ("list", "pair")],  # one bound per row is valid
    lambda v: SetMembershipEstimator(1, noise_bound=v, prior=THETA),
)
add("SetMembershipEstimator", "prior", box_bad(1), lambda v: SetMembershipEstimator(1, noise_bound=0.1, prior=v))


def _sm_update(argument: str) -> Callable[[Any], Any]:
    def call(value: Any) -> Any:
        estimator = SetMembershipEstimator(1, noise_bound=0.1, prior=THETA)
        regressor, target = (value, np.ones(2)) if argument == "regressor" else (np.ones((2, 1)), value)
        return estimator.update(regressor, target)

    return call


add("SetMembershipEstimator.update", "regressor", array_bad((2, 1)), _sm_update("regressor"), "regressor", "target")
add("SetMembershipEstimator.update", "target", array_bad((2,)), _sm_update("target"))

# verify
add("check_assumption4", "A", array_bad((2, 2)), lambda v: check_assumption4(v, form="discrete"))
add(
    "check_assumption4",
    "form",
    choice_bad(("continuous", "discrete")),
    lambda v: check_assumption4(0.5 * np.eye(2), form=v),
)
add(
    "check_assumption4",
    "Q0",
    [c for c in array_bad((2, 2)) if c[0] != "None"] + [("indefinite", -np.eye(2))],
    lambda v: check_assumption4(0.5 * np.eye(2), form="discrete", Q0=v),
)
add(
    "check_assumption4",
    "D",
    [c for c in array_bad((2, 2)) if c[0] != "None"],
    lambda v: check_assumption4(0.5 * np.eye(2), form="discrete", D=v),
)
add(
    "check_assumption4",
    "margin",
    positive_bad(),
    lambda v: check_assumption4(0.5 * np.eye(2), form="discrete", margin=v),
)
add(
    "check_assumption4",
    "solver",
    choice_bad(("CLARABEL",)),
    lambda v: check_assumption4(0.5 * np.eye(2), form="discrete", solver=v),
)
SELECT_OPTIONS: dict[str, Any] = {}
for _entry, _call in (
    ("eliminate_models", lambda options: eliminate_models([SYSTEM], STATES, INPUTS, **options)),
    ("feasible_parameter_box", lambda options: feasible_parameter_box(SYSTEM, STATES, INPUTS, **options)),
    ("ModelSelector", lambda options: ModelSelector([SYSTEM], **options)),
):
    # None (no noise) and one bound per state coordinate are valid
    noise_bad = [c for c in positive_bad(allow_zero=True) if c[0] not in ("None", "pair")]
    add(
        _entry,
        "measurement_noise",
        noise_bad + [("negative entry", np.array([0.1, -0.1]))],
        lambda v, c=_call: c({"measurement_noise": v}),
    )
    add(_entry, "tolerance", positive_bad(allow_zero=True), lambda v, c=_call: c({"tolerance": v}))
    add(_entry, "rounding_allowance", positive_bad(allow_zero=True), lambda v, c=_call: c({"rounding_allowance": v}))
    add(_entry, "max_rounds", count_bad(minimum=0, seed=True), lambda v, c=_call: c({"max_rounds": v}))
add(
    "eliminate_models",
    "hypotheses",
    ALWAYS_BAD + [("empty", []), ("not systems", [1, 2])],
    lambda v: eliminate_models(v, STATES, INPUTS),
)
add("eliminate_models", "states", array_bad((3, 2)), lambda v: eliminate_models([SYSTEM], v, INPUTS))
add("eliminate_models", "controls", array_bad((2, 1)), lambda v: eliminate_models([SYSTEM], STATES, v))
add(
    "feasible_parameter_box",
    "hypothesis",
    ALWAYS_BAD + [("list", [SYSTEM])],
    lambda v: feasible_parameter_box(v, STATES, INPUTS),
)
add("feasible_parameter_box", "states", array_bad((3, 2)), lambda v: feasible_parameter_box(SYSTEM, v, INPUTS))
add("feasible_parameter_box", "controls", array_bad((2, 1)), lambda v: feasible_parameter_box(SYSTEM, STATES, v))
add("ModelSelector", "hypotheses", ALWAYS_BAD + [("empty", []), ("not systems", [1, 2])], lambda v: ModelSelector(v))
for _argument, _position in (("state", 0), ("control", 1), ("next_state", 2)):

    def _selector_add(value: Any, position: int = _position) -> Any:
        arguments: list[Any] = [np.zeros(2), np.zeros(1), np.zeros(2)]
        arguments[position] = value
        return ModelSelector([SYSTEM]).add(*arguments)

    add("ModelSelector.add", _argument, array_bad((1,) if _position == 1 else (2,)), _selector_add)

# planners
ACTIONS = [-1.0, 1.0]
add(
    "RobustTreePlanner",
    "gamma",
    unit_interval_bad(),
    lambda v: RobustTreePlanner([ScalarModel()], ACTIONS, gamma=v, budget=5),
)
add(
    "RobustTreePlanner",
    "budget",
    count_bad(),
    lambda v: RobustTreePlanner([ScalarModel()], ACTIONS, gamma=0.9, budget=v),
)
add(
    "RobustTreePlanner",
    "seed",
    count_bad(minimum=0, seed=True),
    lambda v: RobustTreePlanner([ScalarModel()], ACTIONS, gamma=0.9, budget=5, seed=v),
)
add(
    "RobustTreePlanner",
    "engine",
    choice_bad(("auto", "compiled", "python")),
    lambda v: RobustTreePlanner([ScalarModel()], ACTIONS, gamma=0.9, budget=5, engine=v),
)
add(
    "RobustTreePlanner",
    "models",
    ALWAYS_BAD + [("empty", []), ("no step", [Opaque()])],
    lambda v: RobustTreePlanner(v, ACTIONS, gamma=0.9, budget=5),
)
add(
    "RobustTreePlanner",
    "actions",
    [("None", None), ("empty", []), ("int", 3), ("object", Opaque())],
    lambda v: RobustTreePlanner([ScalarModel()], v, gamma=0.9, budget=5),
)
add(
    "OptimisticPlanner",
    "gamma",
    unit_interval_bad(),
    lambda v: OptimisticPlanner(ScalarModel(), ACTIONS, gamma=v, budget=5),
)
add(
    "OptimisticPlanner", "budget", count_bad(), lambda v: OptimisticPlanner(ScalarModel(), ACTIONS, gamma=0.9, budget=v)
)
add(
    "OptimisticPlanner",
    "model",
    ALWAYS_BAD + [("a list of models", [ScalarModel()])],
    lambda v: OptimisticPlanner(v, ACTIONS, gamma=0.9, budget=5),
)
# a model whose reward or state is bad is reported when planning
REWARD_BAD = SCALAR_BAD + [("negative", -0.1), ("above one", 1.5)]
add(
    "RobustTreePlanner.plan",
    "reward",
    REWARD_BAD,
    lambda v: RobustTreePlanner([ScalarModel(reward=v)], ACTIONS, gamma=0.9, budget=5).plan(0.0),
)
add(
    "OptimisticPlanner.plan",
    "reward",
    REWARD_BAD,
    lambda v: OptimisticPlanner(ScalarModel(reward=v), ACTIONS, gamma=0.9, budget=5).plan(0.0),
)
add("IntervalModel", "system", ALWAYS_BAD + [("box", X0)], lambda v: interval_model(system=v))
add(
    "IntervalModel",
    "parameters",
    # None (the system's prior box), an ellipsoid and a vertex array are valid
    [c for c in box_bad(1) if c[0] not in ("None", "array", "list", "pair of arrays", "ellipsoid")]
    + [
        ("vertices wrong dim", np.zeros((3, 2))),
        ("nan vertices", np.full((2, 1), NAN)),
        ("no vertex", np.empty((0, 1))),
    ],
    lambda v: interval_model(parameters=v),
)
add("IntervalModel", "reward", ALWAYS_BAD + [("float", 0.5)], lambda v: interval_model(reward=v))
add(
    "IntervalModel",
    "controllers",
    ALWAYS_BAD + [("empty", []), ("not controllers", [1, 2])],
    lambda v: interval_model(controllers=v),
)
add(
    "IntervalModel",
    "substeps",
    count_bad() + [("one-item array", np.array([2]))],
    lambda v: interval_model(substeps=v),
)
# OpenLoop does not know the input dimension (IntervalModel checks it against B)
add(
    "OpenLoop",
    "u",
    [c for c in array_bad((1,)) if c[0] not in ("empty", "one short", "one long")],
    lambda v: OpenLoop(v),
)
add(
    "IntervalModel",
    "controllers",
    [("wrong input dimension", [OpenLoop(np.zeros(2))]), ("empty input", [OpenLoop(np.zeros(0))])],
    lambda v: interval_model(controllers=v),
)

# scenarios: reward families and worlds
add("GoalReward", "goal", array_bad((2,)), lambda v: GoalReward(v))
add("GoalReward", "robot_radius", positive_bad(allow_zero=True), lambda v: GoalReward(GOAL, robot_radius=v))
add(
    "GoalReward",
    "position_indices",
    ALWAYS_BAD
    + [
        ("too short", (0,)),
        ("negative", (-1, 0)),
        ("floats", (0.0, 1.0)),
        ("text items", ("0", "1")),
        ("bools", (True, False)),
    ],
    lambda v: GoalReward(GOAL, position_indices=v),
)
add(
    "GoalReward",
    "obstacles",
    [("array", np.zeros((2, 3))), ("text", "abc"), ("object", Opaque())],
    lambda v: GoalReward(GOAL, obstacles=v),
)
SPEED_ARGS: dict[str, Any] = {"target_speed": 1.0, "speed_range": 1.0}
add("SpeedLaneReward", "target_speed", SCALAR_BAD, kwargs_call(SpeedLaneReward, SPEED_ARGS, "target_speed"))
add("SpeedLaneReward", "speed_range", positive_bad(), kwargs_call(SpeedLaneReward, SPEED_ARGS, "speed_range"))
add("SpeedLaneReward", "lane_width", positive_bad(), kwargs_call(SpeedLaneReward, SPEED_ARGS, "lane_width"))
add(
    "SpeedLaneReward",
    "n_lanes",
    count_bad(minimum=2, seed=True) + [("huge int", HUGE)],
    kwargs_call(SpeedLaneReward, SPEED_ARGS, "n_lanes"),
)
add(
    "SpeedLaneReward",
    "speed_weight",
    positive_bad(allow_zero=True) + [("above one", 1.5)],
    kwargs_call(SpeedLaneReward, SPEED_ARGS, "speed_weight"),
)
add(
    "SpeedLaneReward",
    "robot_radius",
    positive_bad(allow_zero=True),
    kwargs_call(SpeedLaneReward, SPEED_ARGS, "robot_radius"),
)
add("make_world", "kind", choice_bad(("static", "pedestrian")), lambda v: make_world(v, 0))
add("make_world", "seed", count_bad(minimum=0, seed=True), lambda v: make_world("static", v))
add("make_world", "measurement", choice_bad(("uniform", "gaussian")), lambda v: make_world("static", 0, measurement=v))
add(
    "make_world",
    "params",
    ALWAYS_BAD + [("dict of parameters", {"dt": 0.1})],
    lambda v: make_world("static", 0, params=v),
)


class ScalarBoxReward:
    """A user reward family whose box minimum returns ``value`` instead of arrays (S, M, n)."""

    def __init__(self, value: Any) -> None:
        self.value = value

    def box_minimum(self, lower, upper, t):
        return self.value


def _plan_interval(model: IntervalModel) -> Any:
    return RobustTreePlanner([model], [0, 1], gamma=0.9, budget=3).plan(model.initial_state(X0.low, X0.high))


class ExpandingModel(ScalarModel):
    """A vectorised model whose ``expand`` returns ``value`` as the rewards."""

    def __init__(self, value: Any) -> None:
        super().__init__()
        self.value = value

    def expand(self, state, actions):
        return [state + a for a in actions], self.value, np.zeros(len(actions), dtype=bool)


add(
    "IntervalModel.step",
    "reward",
    [("scalars", (0.5, False)), ("one row", (np.full(2, 0.5), np.zeros(2, dtype=bool))), ("None", None)],
    lambda v: _plan_interval(interval_model(reward=ScalarBoxReward(v))),
)
add(
    "RobustTreePlanner.plan",
    "rewards",
    [("scalar", 0.5), ("text", ["0.5", "0.5"]), ("bools", np.array([True, False])), ("too many", np.full(3, 0.5))],
    lambda v: RobustTreePlanner([ExpandingModel(v)], ACTIONS, gamma=0.9, budget=5).plan(0.0),
)
NO_ROWS = [("no rows", np.empty((0, 1))), ("no rows, no columns", np.empty((0, 0)))]
add("ConfidenceEllipsoidEstimator.update", "regressor", NO_ROWS, _ce_update("regressor"), "regressor", "target")
add("SetMembershipEstimator.update", "regressor", NO_ROWS, _sm_update("regressor"), "regressor", "target")
add(
    "confidence_ellipsoid",
    "regressors",
    [("no rows", np.empty((3, 0, 1)))],  # no samples at all (N = 0) is valid: the prior-only set
    lambda v: confidence_ellipsoid(v, np.empty((v.shape[0], v.shape[1])), **CE_ARGS),
)


# --------------------------------------------------------------------------- the contract


def outcome(call: Callable[[Any], Any], value: Any, names: tuple[str, ...]) -> str:
    """``"ok"`` if ``call(value)`` raises a named `MinimaxplanError`, else what went wrong."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            call(value)
    except MinimaxplanError as exc:
        message = str(exc)
        if any(name in message for name in names):
            return "ok"
        return f"unnamed: {type(exc).__name__}: {message}"
    except Exception as exc:  # noqa: BLE001 -- an untyped error is what this test reports
        return f"untyped: {type(exc).__name__}: {exc}"
    return "accepted"


ENTRIES = sorted({case.entry for case in CASES})


@pytest.mark.parametrize("entry", ENTRIES)
def test_entry_point_rejects_catalogue(entry: str) -> None:
    """Every catalogued invalid input of ``entry`` raises a typed error naming its argument."""
    failures = []
    for case in CASES:
        if case.entry != entry:
            continue
        result = outcome(case.call, case.value, case.names)
        if result != "ok":
            failures.append(f"{case.id} ({case.value!r:.60}): {result}")
    assert not failures, "\n".join(failures)


def test_inputs_tried() -> None:
    """The catalogue alone holds >= 1,000 invalid inputs over >= 15 entry points."""
    assert len({case.id for case in CASES}) == len(CASES)  # every case is distinct
    assert len(CASES) >= 1000, len(CASES)
    assert len(ENTRIES) >= 15


# --------------------------------------------------------------------------- drawn inputs

_TEXT = st.text(max_size=8)
_NUMERIC_TEXT = st.one_of(st.floats(allow_nan=False).map(repr), st.integers().map(str))
#: Invalid values for any real scalar.
_NOT_A_SCALAR = st.one_of(
    _TEXT,
    _NUMERIC_TEXT,
    st.booleans(),
    st.none(),
    st.sampled_from([NAN, INF, -INF]),
    st.integers(min_value=2**1024, max_value=2**1100),  # too large for a float
    st.lists(st.floats(allow_nan=False), min_size=2, max_size=3).map(np.array),
    st.complex_numbers(min_magnitude=1e-3, allow_nan=False, allow_infinity=False),
)
_NONPOSITIVE = st.one_of(st.floats(max_value=0.0, allow_nan=False, allow_infinity=False), st.integers(max_value=0))
_NEGATIVE = st.one_of(st.floats(max_value=-1e-300, allow_nan=False, allow_infinity=False), st.integers(max_value=-1))


def _not_a_count(minimum: int) -> st.SearchStrategy:
    return st.one_of(
        st.integers(max_value=minimum - 1),
        st.floats(),
        st.integers(min_value=minimum, max_value=10**6).map(float),
        st.integers(min_value=minimum, max_value=10**6).map(str),
        _TEXT,
        st.booleans(),
        st.none(),
    )


def _not_a_finite_array(shape: tuple[int, ...]) -> st.SearchStrategy:
    finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
    any_float = st.floats(allow_nan=True, allow_infinity=True, width=64)
    return st.one_of(
        hnp.arrays(np.float64, shape, elements=any_float).filter(lambda a: not np.all(np.isfinite(a))),
        hnp.arrays(np.float64, shape, elements=finite).map(lambda a: a.astype(str).tolist()),
        hnp.arrays(np.bool_, shape),
        hnp.arrays(np.float64, shape, elements=finite).map(lambda a: a + 1j),
    )


def strategy(kind: str) -> st.SearchStrategy:
    """The hypothesis strategy of invalid values for an argument of ``kind``."""
    name, _, detail = kind.partition(":")
    if name == "nonneg":
        return st.one_of(_NOT_A_SCALAR, _NEGATIVE)
    if name == "positive":
        return st.one_of(_NOT_A_SCALAR, _NONPOSITIVE)
    if name == "unit":
        return st.one_of(
            _NOT_A_SCALAR, _NONPOSITIVE, st.floats(min_value=1.0, allow_nan=False), st.integers(min_value=1)
        )
    if name == "count":
        return _not_a_count(int(detail))
    if name == "array":
        return _not_a_finite_array(tuple(int(n) for n in detail.split(",") if n))
    raise AssertionError(kind)


DRAWN_TRIED: list[str] = []


@pytest.mark.parametrize("row", sorted(DRAWN))
@settings(max_examples=12)
@given(data=st.data())
def test_entry_point_rejects_drawn(row: str, data: st.DataObject) -> None:
    """Hypothesis-drawn invalid values of each argument raise a typed error naming it."""
    kind, call, names = DRAWN[row]
    value = data.draw(strategy(kind), label=row)
    DRAWN_TRIED.append(row)
    result = outcome(call, value, names)
    assert result == "ok", f"{row} ({value!r:.80}): {result}"


def test_drawn_rows_cover_the_arguments() -> None:
    """Most arguments get drawn values too (those whose catalogue has a kind)."""
    assert len(DRAWN) >= 60, len(DRAWN)


# --------------------------------------------------------------------------- valid edges

VALID_EDGES: list[tuple[str, Callable[[], bool]]] = [
    ("degenerate box", lambda: Box(np.zeros(2), np.zeros(2)).contains(np.zeros(2)) is True),
    ("float32 bounds", lambda: Box(np.zeros(2, dtype=np.float32), np.ones(2, dtype=np.float32)).dim == 2),
    ("integer bounds", lambda: Box([0, 0], [1, 1]).high.dtype == np.float64),
    ("scalar radius", lambda: np.array_equal(Box.from_center(np.zeros(2), 0.5).high, [0.5, 0.5])),
    ("zero radius", lambda: np.array_equal(Box.from_center(np.ones(2), 0).low, [1.0, 1.0])),
    ("batch of points", lambda: X0.contains(np.zeros((5, 2)), tol=1e-9) is True),
    ("no points", lambda: X0.contains(np.zeros((0, 2))) is True),
    ("numpy scalar tol", lambda: X0.contains(np.full(2, 0.15), tol=np.float64(0.1)) is True),
    ("integer tol", lambda: ELLIPSOID.contains(np.array([1.2, 0.0]), tol=1) is True),
    ("0-d array radius", lambda: Ellipsoid(np.zeros(2), np.eye(2), np.array(2.0)).radius == 2.0),
    ("B as a vector", lambda: UncertainLinearSystem(A0, PHI, np.array([0.0, 1.0]), w=W, theta=THETA).ninputs == 1),
    (
        "one state",
        lambda: UncertainLinearSystem([[0.5]], [[[1.0]]], [[1.0]], w=Box([-0.1], [0.1]), theta=THETA).nstates == 1,
    ),
    ("batch of thetas", lambda: SYSTEM.A(np.zeros((4, 1))).shape == (4, 2, 2)),
    ("horizon zero", lambda: predict_tube(SYSTEM, X0, np.zeros((0, 1))).lower.shape == (1, 2)),
    (
        "ellipsoid parameters",
        lambda: predict_tube(SYSTEM, X0, CONTROLS, Ellipsoid(np.zeros(1), np.eye(1) * 100, 1.0)).horizon == 3,
    ),
    ("vertex parameters", lambda: predict_tube(SYSTEM, X0, CONTROLS, np.array([[-0.1], [0.1]])).horizon == 3),
    ("no samples", lambda: confidence_ellipsoid(np.empty((0, 2, 1)), np.empty((0, 2)), **CE_ARGS).dim == 1),
    ("numpy count", lambda: ConfidenceEllipsoidEstimator(np.int64(2), **CE_ARGS).nparams == 2),
    ("per-row noise bound", lambda: SetMembershipEstimator(1, noise_bound=[0.1, 0.2], prior=THETA).nparams == 1),
    ("tiny margin", lambda: check_assumption4(0.5 * np.eye(2), form="discrete", margin=1e-12).status == "feasible"),
    ("no transitions", lambda: eliminate_models([SYSTEM], STATES[:1], INPUTS[:0]).survivors == [0]),
    (
        "per-state noise",
        lambda: eliminate_models([SYSTEM], STATES, INPUTS, measurement_noise=[0.0, 0.001]).survivors == [0],
    ),
    ("max_rounds zero", lambda: feasible_parameter_box(SYSTEM, STATES, INPUTS, max_rounds=0).dim == 1),
    ("budget one", lambda: RobustTreePlanner([ScalarModel()], ACTIONS, gamma=1e-9, budget=1).plan(0.0).expansions == 1),
    (
        "integer rewards",
        lambda: OptimisticPlanner(ScalarModel(reward=1), ACTIONS, gamma=0.5, budget=4).plan(0.0).lower > 0,
    ),
    (
        "numpy reward",
        lambda: (
            OptimisticPlanner(ScalarModel(reward=np.float32(0.25)), ACTIONS, gamma=0.5, budget=4).plan(0.0).lower > 0
        ),
    ),
    (
        "huge seed",
        lambda: (
            RobustTreePlanner([ScalarModel()], ACTIONS, gamma=0.9, budget=3, seed=10**30).plan(0.0).action in ACTIONS
        ),
    ),
    ("many substeps", lambda: interval_model(substeps=50).substeps == 50),
    ("numpy indices", lambda: GoalReward(GOAL, position_indices=np.array([1, 0])).position_indices == (1, 0)),
    ("many lanes", lambda: SpeedLaneReward(1.0, 1.0, n_lanes=10**30).n_lanes == 10**30),
    ("numpy seed", lambda: make_world("pedestrian", np.int64(3)).seed == 3),
]


@pytest.mark.parametrize(("label", "check"), VALID_EDGES, ids=[label for label, _ in VALID_EDGES])
def test_valid_edge_inputs_are_accepted(label: str, check: Callable[[], bool]) -> None:
    """Edge values that are valid are accepted and give the expected result (the checks are not too eager)."""
    assert check(), label
