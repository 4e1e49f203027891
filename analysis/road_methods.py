"""The baselines that drive the road scenarios (`RoadScenario`): dwa and teb on the kinematic bicycle.

Each is a `Method` of `minimaxplan.analysis.registry`, run by the one episode loop;
importing this module registers ``dwa`` and ``teb`` for the road scenarios (the robot's
factories of the same names raise `UnsupportedScenario` for them, and these for the
robot's scenarios).

The planners (`minimaxplan.planners.dwa.VehicleDynamicWindow`,
`minimaxplan.planners.teb.VehicleElasticBand`) get the ego's measured state, the other
vehicles' measured states (predicted at constant velocity, as the robot's baselines
treat pedestrians) and the road as a `RoadScene`; the bicycle rollout is the worlds'
own `minimaxplan.scenarios.vehicles.bicycle_step` with the ego's known parameters (no
second bicycle implementation). Their parameters are frozen in `ROAD_DWA_PARAMETERS`
and `ROAD_TEB_PARAMETERS` (tuned on seeds >= 10000, docs/baselines.md).
"""

from __future__ import annotations

import functools

import numpy as np

from minimaxplan.planners.dwa import VehicleDWAParameters, VehicleDynamicWindow
from minimaxplan.planners.teb import VehicleElasticBand, VehicleTEBParameters
from minimaxplan.scenarios.road_world import Observation
from minimaxplan.scenarios.vehicles import bicycle_step

from .episode import LoopConfig
from .registry import Method, Policy, UnsupportedScenario, register_method
from .road_scenario import DrivingWorld, RoadScenario

__all__ = ["RoadBaselineMethod", "RoadDWAMethod", "RoadTEBMethod", "ROAD_DWA_PARAMETERS", "ROAD_TEB_PARAMETERS"]

#: The frozen DWA parameters per road world (docs/baselines.md, driving section).
ROAD_DWA_PARAMETERS = {
    "highway": VehicleDWAParameters(),
    "tjunction": VehicleDWAParameters(),
}

#: The frozen TEB parameters per road world (docs/baselines.md, driving section).
ROAD_TEB_PARAMETERS = {
    "highway": VehicleTEBParameters(),
    "tjunction": VehicleTEBParameters(),
}


class _HeldControl:
    """A baseline's ``(acceleration, steering)``, held for one decision period."""

    def __init__(self, u):
        self.u = np.asarray(u, dtype=float)

    def control(self, measurement) -> np.ndarray:
        return self.u


class RoadBaselineMethod(Method[DrivingWorld]):
    """What the road baselines share: the bicycle rollout, the scene, the held control.

    Parameters
    ----------
    scenario
        A `RoadScenario`; anything else raises `UnsupportedScenario`.
    config
        The loop settings (unused by the baselines).
    params
        The planner's parameters (default: the frozen ones of the scenario's kind).
    """

    #: Local goals are this far ahead in ``lookahead_time`` seconds (TEB only).
    uses_local_goals = False

    def __init__(self, scenario: RoadScenario, config: LoopConfig, params=None):
        if not isinstance(scenario, RoadScenario):
            raise UnsupportedScenario(
                f"{type(self).__name__} drives only RoadScenario worlds, got {type(scenario).__name__}"
            )
        self.scenario = scenario
        self.config = config
        self.params = params

    def start(self, world: DrivingWorld) -> None:
        """Keep the world and build the planner on the ego's bicycle.

        Parameters
        ----------
        world : DrivingWorld
            The episode's world.
        """
        self.world = world
        road_scenario = world.world.scenario
        vehicle = road_scenario.vehicle
        self.planner = self.make_planner(
            functools.partial(bicycle_step, vehicle=vehicle),
            dt=road_scenario.dt,
            substeps=road_scenario.substeps,
            acceleration_bound=road_scenario.ego_acceleration_bound,
            max_steering=vehicle.max_steering,
            length=vehicle.length,
            width=vehicle.width,
        )
        self.calls = 0

    def make_planner(self, dynamics, **kwargs):  # pragma: no cover - abstract
        """The planner for this episode.

        Parameters
        ----------
        dynamics : callable
            The ego's bicycle step (`VehicleDynamics`).
        **kwargs
            dt, substeps, control bounds and the ego's rectangle.
        """
        raise NotImplementedError

    def lookahead(self, observation: Observation) -> float:
        """Distance of the local goals ahead, m (0: none).

        Parameters
        ----------
        observation : Observation
            The current measurement.
        """
        return 0.0

    def decide(self, measurement: Observation) -> Policy:
        """Plan on the measured ego and vehicles; hold the control for the decision period.

        Parameters
        ----------
        measurement : Observation
            The current measurement.
        """
        scene = self.world.scene(measurement, self.lookahead(measurement))
        self.calls += 1
        return _HeldControl(self.planner.plan(measurement.ego, scene))

    def report(self) -> dict:
        """The planner's parameters (no Assumption 4 report, no predicted boxes)."""
        return {"lmi": None, "plans": [], "planner": self.planner.params.to_dict()}


class RoadDWAMethod(RoadBaselineMethod):
    """`VehicleDynamicWindow` on the ego's bicycle."""

    def make_planner(self, dynamics, **kwargs) -> VehicleDynamicWindow:
        """`VehicleDynamicWindow` with the frozen parameters of the scenario's kind.

        Parameters
        ----------
        dynamics : callable
            The ego's bicycle step.
        **kwargs
            See `RoadBaselineMethod.make_planner`.
        """
        params = self.params or ROAD_DWA_PARAMETERS[self.scenario.kind]
        return VehicleDynamicWindow(dynamics, params=params, **kwargs)


class RoadTEBMethod(RoadBaselineMethod):
    """`VehicleElasticBand` on the ego's bicycle, towards local goals ahead in each usable lane."""

    def make_planner(self, dynamics, **kwargs) -> VehicleElasticBand:
        """`VehicleElasticBand` with the frozen parameters of the scenario's kind.

        Parameters
        ----------
        dynamics : callable
            The ego's bicycle step.
        **kwargs
            See `RoadBaselineMethod.make_planner`.
        """
        params = self.params or ROAD_TEB_PARAMETERS[self.scenario.kind]
        return VehicleElasticBand(dynamics, params=params, **kwargs)

    def lookahead(self, observation: Observation) -> float:
        """``max(v, min_speed) * lookahead_time`` ahead of the measured ego, m.

        Parameters
        ----------
        observation : Observation
            The current measurement.
        """
        p = self.planner.params
        return max(float(observation.ego[2]), p.min_speed) * p.lookahead_time


register_method("dwa", RoadDWAMethod)
register_method("teb", RoadTEBMethod)
