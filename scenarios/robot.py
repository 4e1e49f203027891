"""The planar mobile robot: a holonomic point mass with unknown anisotropic friction.

State ``x = (px, py, vx, vy)`` (metres, metres per second), control
``u = (ux, uy) in [-1, 1]^2`` (an acceleration command, m/s^2), continuous time

    d(pos)/dt = vel,    d(vel)/dt = -diag(xi_x, xi_y) vel + u + w,

with the friction ``theta = (xi_x, xi_y)`` unknown (drawn per episode from the prior
box ``[0.2, 0.8]^2``) and a bounded disturbance ``w in [-0.1, 0.1]^2`` on the
accelerations. The worlds step this with forward Euler at ``dt = 0.1`` s, with one
decision every 0.5 s (5 sub-steps); `robot_system` returns exactly that discrete model
as an `UncertainLinearSystem`, and the worlds step *through* it, so the model is exact
for them (only the value of theta and the disturbances are unknown).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np

from minimaxplan.models.errors import InputError
from minimaxplan.models.sets import Box
from minimaxplan.models.system import UncertainLinearSystem
from minimaxplan.models.validation import as_count, as_positive_scalar

__all__ = [
    "RobotParameters",
    "DEFAULT_ROBOT",
    "Hypothesis",
    "robot_system",
    "robot_hypotheses",
]


@dataclass(frozen=True)
class RobotParameters:
    """Every physical and episode constant of the robot scenario (SI units).

    Attributes
    ----------
    dt
        Simulation sub-step, s (forward Euler).
    substeps
        Sub-steps per decision: a control is held for ``substeps * dt`` = 0.5 s.
    friction_low, friction_high
        The prior box of the friction ``(xi_x, xi_y)``, the same bounds on both axes, 1/s.
    disturbance_bound
        ``w`` is uniform in ``[-disturbance_bound, disturbance_bound]^2``, m/s^2, added
        to the accelerations (the continuous-time D is the 4x2 velocity-input matrix).
    measurement_noise
        Half-width of the uniform noise on every measured state component
        (``|v| <= measurement_noise``), the ``v_bar`` of the DESIGN errata.
    gaussian_measurement_std
        Standard deviation used by the Gaussian measurement option (robustness studies
        only: outside the guarantees).
    control_bound
        ``u in [-control_bound, control_bound]^2``.
    robot_radius
        Radius of the robot's disc footprint, m.
    goal_tolerance
        The episode succeeds when the robot's centre is within this distance of the goal, m.
    time_limit
        Episode length limit, s.
    arena_size
        The square ``[0, arena_size]^2`` in which start, goal and obstacles are placed, m.
        It has no walls: the robot may leave it (and then usually times out).
    goal_distance_low, goal_distance_high
        The goal is drawn at a distance in this range from the start, m.
    """

    dt: float = 0.1
    substeps: int = 5
    friction_low: float = 0.2
    friction_high: float = 0.8
    disturbance_bound: float = 0.1
    measurement_noise: float = 0.01
    gaussian_measurement_std: float = 0.1
    control_bound: float = 1.0
    robot_radius: float = 0.3
    goal_tolerance: float = 0.5
    time_limit: float = 60.0
    arena_size: float = 20.0
    goal_distance_low: float = 14.0
    goal_distance_high: float = 18.0

    def __post_init__(self) -> None:
        for name in (
            "dt",
            "friction_high",
            "disturbance_bound",
            "control_bound",
            "robot_radius",
            "goal_tolerance",
            "time_limit",
            "arena_size",
            "goal_distance_high",
            "gaussian_measurement_std",
        ):
            as_positive_scalar(name, getattr(self, name))
        for name in ("friction_low", "measurement_noise", "goal_distance_low"):
            as_positive_scalar(name, getattr(self, name), allow_zero=True)
        as_count("substeps", self.substeps)
        if self.friction_low > self.friction_high:
            raise InputError(f"friction_low must be <= friction_high, got {self.friction_low} > {self.friction_high}")
        if self.goal_distance_low > self.goal_distance_high:
            raise InputError(
                "goal_distance_low must be <= goal_distance_high, "
                f"got {self.goal_distance_low} > {self.goal_distance_high}"
            )
        if self.goal_distance_high >= self.arena_size * np.sqrt(2):
            raise InputError(
                f"goal_distance_high={self.goal_distance_high} does not fit in the arena of side {self.arena_size}"
            )

    @property
    def decision_period(self) -> float:
        """Duration a control is held, ``substeps * dt`` (s)."""
        return self.substeps * self.dt

    @property
    def max_steps(self) -> int:
        """Number of sub-steps in the time limit."""
        return int(round(self.time_limit / self.dt))

    @property
    def friction_prior(self) -> Box:
        """The prior box of ``(xi_x, xi_y)``."""
        return Box(np.full(2, self.friction_low), np.full(2, self.friction_high))

    @property
    def disturbance_box(self) -> Box:
        """The box of admissible disturbances ``w``."""
        return Box.from_center(np.zeros(2), self.disturbance_bound)

    def to_dict(self) -> dict:
        """Every parameter by name (JSON-ready).

        Returns
        -------
        dict
            The dataclass's fields.
        """
        return asdict(self)


DEFAULT_ROBOT = RobotParameters()

# Continuous-time matrices of eq. (1) for this robot.
_A_INTEGRATOR = np.array([[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
_VELOCITY_INPUT = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])


def _friction_structure(isotropic: bool) -> np.ndarray:
    """phi: -1 on the (vx, vx) and (vy, vy) entries, one matrix per axis or one shared."""
    phi_x = np.zeros((4, 4))
    phi_x[2, 2] = -1.0
    phi_y = np.zeros((4, 4))
    phi_y[3, 3] = -1.0
    return (phi_x + phi_y)[None] if isotropic else np.stack([phi_x, phi_y])


def robot_system(
    params: RobotParameters = DEFAULT_ROBOT,
    *,
    isotropic: bool = False,
    input_gain: float = 1.0,
    dt: float | None = None,
) -> UncertainLinearSystem:
    """The robot's discrete-time model ``x+ = A(theta) x + B u + D w``.

    Parameters
    ----------
    params
        Robot constants (friction prior, disturbance bound, dt).
    isotropic
        False (the truth): ``theta = (xi_x, xi_y)``, d = 2. True: one friction ``xi``
        shared by both axes, d = 1, prior ``[friction_low, friction_high]``.
    input_gain
        Scales the continuous input matrix (1 is the truth).
    dt
        Overrides ``params.dt``.

    Notes
    -----
    Eq. (1)-(2) with ``A0`` the double integrator, ``phi_i`` the friction structure
    (``-1`` on a velocity's diagonal entry), ``B = D = [0; I]``, discretised by
    `UncertainLinearSystem.from_continuous` (forward Euler):
    ``A(theta) = I + dt (A0 + sum_i theta_i phi_i)``, ``B = dt g [0; I]``, ``D = dt [0; I]``.
    """
    step = params.dt if dt is None else as_positive_scalar("dt", dt)
    gain = as_positive_scalar("input_gain", input_gain)
    prior = params.friction_prior
    if isotropic:
        prior = Box(prior.low[:1], prior.high[:1])
    return UncertainLinearSystem.from_continuous(
        _A_INTEGRATOR,
        _friction_structure(isotropic),
        gain * _VELOCITY_INPUT,
        D=_VELOCITY_INPUT,
        w=params.disturbance_box,
        theta=prior,
        dt=step,
    )


class Hypothesis(NamedTuple):
    """A named structural hypothesis about the robot (unpacks as ``name, system``)."""

    name: str
    system: UncertainLinearSystem

    def to_dict(self) -> dict:
        """The hypothesis as plain data (JSON-ready).

        Returns
        -------
        dict
            ``{"name": ..., "system": UncertainLinearSystem.to_dict()}``.
        """
        return {"name": self.name, "system": self.system.to_dict()}


#: Input gain of the "wrong input gain" hypothesis.
WRONG_INPUT_GAIN = 0.6


def robot_hypotheses(dt: float = 0.1, params: RobotParameters = DEFAULT_ROBOT) -> list[Hypothesis]:
    """The competing structural hypotheses for model selection, the truth first.

    Parameters
    ----------
    dt : float
        Time step of the discretised systems, in seconds (> 0).
    params : RobotParameters
        The robot (friction prior, disturbance and control bounds).

    Returns
    -------
    list of Hypothesis
        ``"anisotropic friction"`` (the truth's structure, theta = (xi_x, xi_y)),
        ``"isotropic friction"`` (one xi for both axes: contradicted by data as soon
        as the true frictions differ enough on the two axes), and
        ``"wrong input gain"`` (anisotropic friction, B scaled by 0.6).
    """
    return [
        Hypothesis("anisotropic friction", robot_system(params, dt=dt)),
        Hypothesis("isotropic friction", robot_system(params, isotropic=True, dt=dt)),
        Hypothesis("wrong input gain", robot_system(params, input_gain=WRONG_INPUT_GAIN, dt=dt)),
    ]
