"""Fixtures shared by the tests of `minimaxplan.models`."""

import numpy as np
import pytest

from minimaxplan.models import Box, UncertainLinearSystem


@pytest.fixture
def small_system():
    """A 2-state, 1-input, 1-parameter system with small boxes (for the error paths)."""
    return UncertainLinearSystem(
        np.eye(2),
        np.ones((1, 2, 2)),
        np.ones((2, 1)),
        w=Box.from_center(np.zeros(2), 0.1),
        theta=Box.from_center(np.zeros(1), 0.1),
    )
