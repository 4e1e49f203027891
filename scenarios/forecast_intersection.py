"""The intersection of two sound traffic forecasts of the same vehicles, at the sub-steps they share.

A `TrafficForecast` made at sub-step t0 contains every vehicle's true rectangle and state
at every sub-step ``t0 .. t0 + H`` for every parameter, intention, switch, disturbance and
noise its data allow, and for any ego trajectory inside the ego reach it was made with. A
forecast made later, at t1 > t0, from new measurements, is sound in the same sense. Both
contain the same true vehicle at an absolute sub-step t in ``[t1, t0 + H]``, so their
intersection does too: it is a sound forecast at least as tight as either. The two are
not nested in general. Each starts from its own measurement, whose noise box the later one
does not inherit, so the later one can be wider in some coordinate at some sub-step.

Validity: the earlier forecast is sound for the later decision's plans only if every one
of them keeps the ego inside the reach the earlier one was made with. That holds for a
forecast made from the ego's reach over *every* action sequence (`ego_reach`): a plan from
t1 continues the executed path, and its path from t0 is an action sequence. It does not
hold for a forecast from the lane-keeping family's reach (three free decisions, then one
held): a lane-keeping plan from t1 has one free decision more from t0. So the later
forecasts, for any ego and for a lane-keeping ego, are both intersected with the earlier
forecast for any ego only.

What is intersected: the rectangle boxes (the planner's obstacles) and the state boxes'
x, y and v (the run-time check's boxes). Headings are kept from the later forecast: each
forecast unwraps its heading near its own measurement, so two heading intervals of one
vehicle may differ by a multiple of 2 pi. A row empty in either forecast (the vehicle not
on the road there) keeps the later forecast's row: each forecast's claim that a vehicle has
left is sound by itself. Where both rows are finite and do not meet, at least one forecast
is not sound; the later forecast's row is kept and the case is counted
(`ForecastIntersection.inconsistent`). In the library's worlds that count is a bug to find.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from minimaxplan.models.errors import InputError

from .traffic_models import TrafficForecast

__all__ = ["ForecastIntersection", "intersect_forecasts"]

#: State coordinates intersected: x, y and v (psi is kept from the later forecast).
INTERSECTED_STATES = (0, 1, 2)


@dataclass(frozen=True)
class ForecastIntersection:
    """The later forecast tightened by an earlier one (`intersect_forecasts`).

    Attributes
    ----------
    forecast : TrafficForecast
        The later forecast's vehicles and sub-steps, each box intersected with the earlier
        forecast's box of the same vehicle at the same absolute sub-step where both exist.
    shared_steps : int
        The later forecast's sub-steps ``0 .. shared_steps - 1`` that the earlier one covers.
    shared_vehicles : int
        Vehicles present in both.
    inconsistent : int
        (sub-step, vehicle) pairs where both boxes were finite and disjoint: the later row
        was kept. 0 unless a forecast is not sound.
    """

    forecast: TrafficForecast
    shared_steps: int
    shared_vehicles: int
    inconsistent: int

    def to_dict(self) -> dict:
        """The counts (not the forecast's arrays)."""
        return {
            "shared_steps": self.shared_steps,
            "shared_vehicles": self.shared_vehicles,
            "inconsistent": self.inconsistent,
        }


def _meet(lo_new, hi_new, lo_old, hi_old):
    """Elementwise intersection of interval boxes, and where both are finite and do not meet."""
    lo, hi = np.maximum(lo_new, lo_old), np.minimum(hi_new, hi_old)
    finite = np.isfinite(lo_new).all(-1) & np.isfinite(hi_new).all(-1)
    finite &= np.isfinite(lo_old).all(-1) & np.isfinite(hi_old).all(-1)
    empty = finite & (lo > hi).any(-1)
    use = finite & ~empty
    return np.where(use[..., None], lo, lo_new), np.where(use[..., None], hi, hi_new), empty


def intersect_forecasts(later: TrafficForecast, later_step: int, earlier: TrafficForecast, earlier_step: int):
    """The later forecast intersected with the earlier one where they share a vehicle and a sub-step.

    Parameters
    ----------
    later, earlier : TrafficForecast
        Two forecasts of one world, sound for the later decision's plans (module docstring:
        the earlier one made from the ego's reach over every action sequence).
    later_step, earlier_step : int
        The absolute sub-steps of their row 0, ``earlier_step <= later_step``.

    Returns
    -------
    ForecastIntersection

    Raises
    ------
    InputError
        If the steps are not integers with ``0 <= earlier_step <= later_step``, or the two
        forecasts have different sub-steps ``dt``.
    """
    for name, value in (("later_step", later_step), ("earlier_step", earlier_step)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise InputError(f"{name} must be a non-negative integer, got {value!r}")
    if earlier_step > later_step:
        raise InputError(f"earlier_step must be <= later_step, got {earlier_step} > {later_step}")
    if not isinstance(later, TrafficForecast) or not isinstance(earlier, TrafficForecast):
        raise InputError(
            f"later and earlier must be TrafficForecasts, got {type(later).__name__} and {type(earlier).__name__}"
        )
    if later.dt != earlier.dt:
        raise InputError(f"the forecasts' dt must be equal, got {later.dt} and {earlier.dt}")
    offset = int(later_step) - int(earlier_step)
    shared = max(0, min(later.steps + 1, earlier.steps + 1 - offset))
    columns = {int(agent): j for j, agent in enumerate(earlier.ids)}
    pairs = [(j, columns[int(agent)]) for j, agent in enumerate(later.ids) if int(agent) in columns]
    boxes = np.array(later.boxes)
    lower, upper = np.array(later.state_lower), np.array(later.state_upper)
    inconsistent = 0
    if shared and pairs:
        new_cols = np.array([j for j, _ in pairs])
        old_cols = np.array([k for _, k in pairs])
        rows = slice(offset, offset + shared)
        b_new, b_old = boxes[:shared, new_cols], earlier.boxes[rows][:, old_cols]
        lo, hi, empty_boxes = _meet(b_new[..., :2], b_new[..., 2:], b_old[..., :2], b_old[..., 2:])
        boxes[:shared, new_cols] = np.concatenate([lo, hi], axis=-1)
        states = list(INTERSECTED_STATES)
        s_lo, s_hi, empty_states = _meet(
            lower[:shared][:, new_cols][..., states],
            upper[:shared][:, new_cols][..., states],
            earlier.state_lower[rows][:, old_cols][..., states],
            earlier.state_upper[rows][:, old_cols][..., states],
        )
        block_lo, block_hi = lower[:shared, new_cols], upper[:shared, new_cols]
        block_lo[..., states], block_hi[..., states] = s_lo, s_hi
        lower[:shared, new_cols], upper[:shared, new_cols] = block_lo, block_hi
        inconsistent = int(np.sum(empty_boxes | empty_states))
    forecast = TrafficForecast(
        boxes=boxes,
        state_lower=lower,
        state_upper=upper,
        guaranteed=later.guaranteed,
        ids=later.ids,
        dt=later.dt,
    )
    return ForecastIntersection(forecast, shared, len(pairs), inconsistent)
