"""The planner's boxes contain the EXACT reachable sets: its arithmetic is rounded outward.

A nilpotent closed loop with a large absolute value, ``M = 7 [[1, -1], [1, -1]]``
(``M^2 = 0`` but ``rho(|M|) = 14``): from the second step on the exact state is 0,
while any rounding that lets a point box's bounds cross by one ulp grows 14-fold per
step in the interval recursion. The exact trajectory is computed in rational
arithmetic, and inclusion is checked with no tolerance, on the open-loop path and on
the saturating-feedback path.
"""

from fractions import Fraction

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from minimaxplan.models import Box, UncertainLinearSystem
from minimaxplan.planners.controllers import LinearFeedback, OpenLoop
from minimaxplan.planners.interval_model import IntervalModel
from minimaxplan.scenarios.rewards import GoalReward

NILPOTENT = 7.0 * np.array([[1.0, -1.0], [1.0, -1.0]])
STEPS = 14


def exact_trajectory(matrix, x0, steps):
    """x_{n+1} = matrix x_n in rational arithmetic, as Fractions."""
    x = [Fraction(v) for v in x0]
    rows = [[Fraction(v) for v in row] for row in matrix]
    out = [x]
    for _ in range(steps):
        x = [sum((a * b for a, b in zip(row, x)), Fraction(0)) for row in rows]
        out.append(x)
    return out


def assert_contains_exactly(lower, upper, trajectory):
    for n, x in enumerate(trajectory):
        for i, value in enumerate(x):
            assert Fraction(lower[n, i]) <= value <= Fraction(upper[n, i]), (
                n,
                i,
                lower[n, i],
                float(value),
                upper[n, i],
            )


def system_with(A0):
    """``x+ = A0 x + u`` with no parameter effect and no disturbance (one dummy parameter)."""
    return UncertainLinearSystem(
        A0, np.zeros((1, 2, 2)), np.eye(2), D=np.eye(2), w=Box([0.0, 0.0], [0.0, 0.0]), theta=Box([0.0], [1.0])
    )


points = st.lists(
    st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False, allow_subnormal=False), min_size=2, max_size=2
)


@given(points)
def test_open_loop_boxes_contain_the_exact_trajectory(x0):
    model = IntervalModel(system_with(NILPOTENT), None, GoalReward([0.0, 0.0]), [OpenLoop([0.0, 0.0])])
    lower, upper, _, _ = model.rollout(model.initial_state(x0, x0), [0] * STEPS)
    assert_contains_exactly(lower, upper, exact_trajectory(NILPOTENT, x0, STEPS))


@given(points)
def test_saturating_feedback_boxes_contain_the_exact_trajectory(x0):
    # u = K (0 - x) with K = -NILPOTENT: x+ = NILPOTENT x; the limits are computed but never reached
    controller = LinearFeedback(-NILPOTENT, np.zeros(2), u_low=-1e9, u_high=1e9)
    model = IntervalModel(system_with(np.zeros((2, 2))), None, GoalReward([0.0, 0.0]), [controller])
    lower, upper, _, _ = model.rollout(model.initial_state(x0, x0), [0] * STEPS)
    assert_contains_exactly(lower, upper, exact_trajectory(NILPOTENT, x0, STEPS))


def test_the_boxes_stay_tight():
    """Outward rounding costs ulps, not width: the boxes stay within 1e-9 of the exact points' scale."""
    x0 = [0.3, -0.7]
    model = IntervalModel(system_with(NILPOTENT), None, GoalReward([0.0, 0.0]), [OpenLoop([0.0, 0.0])])
    lower, upper, _, _ = model.rollout(model.initial_state(x0, x0), [0] * 3)
    assert np.all(upper - lower <= 1e-9 * 14.0 ** np.arange(4)[:, None]), upper - lower
