"""Why the robust ego never reaches highway-env's intersection goal: what blocks each decision (issue 12).

Runs robust ``highway-env:intersection-v0`` episodes (the registered scenario and method,
the experiment's loop and seeds) and, at every decision, reads the method's own forecast
and the ego's boxes along every action sequence it searched (`sequence_reach`). A
decision is *blocked* when every sequence may collide within the horizon (the method
then takes the one clear longest, `latest_clear_sequence`); it is attributed to the
vehicles whose boxes the ego's box meets at the first possible collision of a sequence
clear longest (the first in the search's order when several are):

* ``follower``: a vehicle measured behind the ego in the ego's lane (heading within 0.3
  rad of the ego's, centre within half a lane of the ego's line, behind it);
* ``other``: any other vehicle (crossing or oncoming traffic);

each ``fine`` or ``coarse`` by the forecast's ``guaranteed`` flag at that sub-step (and, if
coarse, the sub-step from which it is).
A decision may count for both kinds. The diagnosis reads the method's forecasts and the
observation only (the measured positions are exact in highway-env). A vehicle coarse from
the observation itself gets the largest heading error ``|chi|`` of its belief's lanes at
its measured position (the fine model holds for ``|chi| <= CHI_MAX``): at the intersection
the beliefs are the priors of each observation (`prior_belief`: every lane whose strip
holds the centre), which inside the junction include lanes crossing the vehicle's path.

``--lane-history`` (diagnosis only, not the registered method) restricts each vehicle's
prior lanes, from its second observation on, to those of its previous sub-step, their
successors and their predecessors (sound while highway-env's vehicles move along their
lanes' successions, reversing included, by less than a lane per sub-step), to measure
what the crossing lanes cost.

``--true-routes`` (diagnosis only, privileged) cuts each vehicle's prior routes to those
that end on the last lane of its true highway-env route (``vehicle.route``, which the
registered method never reads) and its lanes to that route's and its current lane, to
measure what not knowing the routes costs.

Usage::

    python benchmarks/trace_highway_env_stalls.py --seeds 0,1,2 [--out benchmarks/results/trace_highway_env_stalls.md]
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import pathlib
import time

import numpy as np

from minimaxplan.analysis import highway_env_scenario as hes
from minimaxplan.analysis.arguments import count_list
from minimaxplan.analysis.episode import run_episode
from minimaxplan.scenarios.road import wrap_to_pi
from minimaxplan.scenarios.traffic_models import CHI_MAX

ENV = "highway-env:intersection-v0"
#: The largest heading error of each vehicle forecast coarse at step 0 (rad), over the run.
CHI_RANGE: list = []
#: Every removal made by ``--lane-history`` (lanes taken out of a prior; priors left whole).
LANE_HISTORY = collections.Counter()
#: What ``--true-routes`` did to the priors (cut to the true route; left whole).
TRUE_ROUTES = collections.Counter()
#: A vehicle is the ego's follower when its heading is within this of the ego's (rad) ...
SAME_HEADING = 0.3
#: ... and its centre within this of the ego's line (m: half of highway-env's 4 m lane).
SAME_LINE = 2.0


def _follower(ego: np.ndarray, other: np.ndarray) -> bool:
    """Whether ``other`` (x, y, v, psi) is behind ``ego`` in its lane."""
    u = np.array([np.cos(ego[3]), np.sin(ego[3])])
    d = other[:2] - ego[:2]
    heading = abs(float(np.angle(np.exp(1j * (other[3] - ego[3])))))
    return heading < SAME_HEADING and abs(float(d @ np.array([-u[1], u[0]]))) < SAME_LINE and float(d @ u) < 0.0


def _largest_heading_error(road, lanes, state: np.ndarray) -> float:
    """The largest ``|chi|`` (rad) of a measured state against the lanes, at its projection on each."""
    errors = []
    for lane in lanes:
        s, _ = road.frenet(np.array([lane]), np.array([state[0]]), np.array([state[1]]))
        heading = float(road.heading_at(lane, float(np.clip(s[0], 0.0, road.lengths[lane]))))
        errors.append(abs(float(wrap_to_pi(state[3] - heading))))
    return max(errors, default=0.0)


def _neighbour_lanes(road, lanes) -> set:
    """``lanes``, their successors and their predecessors."""
    return set(lanes) | {b for a, b in road.connections if a in lanes} | {a for a, b in road.connections if b in lanes}


def _lane_history_beliefs(method, observation) -> dict:
    """The priors of ``observation`` with each vehicle's lanes restricted by its previous sub-step's."""
    adapter = method.world.adapter
    history = method.__dict__.setdefault("_lane_history", {})
    beliefs = {}
    for agent, state in zip(np.asarray(observation.ids).tolist(), np.asarray(observation.vehicles, dtype=float)):
        prior = adapter.prior(agent, state)
        previous = history.get(agent)
        lanes = set(prior.lanes)
        if previous is not None and abs(previous[0] - observation.time) < 1e-9:
            lanes = set(previous[1])
        elif previous is not None and abs(observation.time - previous[0] - adapter.dt) < 1e-6:
            kept = lanes & _neighbour_lanes(adapter.road, previous[1])
            if kept:
                LANE_HISTORY["lanes removed"] += len(lanes) - len(kept)
                lanes = kept
            else:
                LANE_HISTORY["priors left whole"] += 1
        history[agent] = (observation.time, frozenset(lanes))
        beliefs[agent] = dataclasses.replace(prior, lanes=tuple(sorted(lanes)))
    return beliefs


def _true_route_beliefs(method, observation) -> dict:
    """The priors of ``observation`` cut to each vehicle's true highway-env route (diagnosis, privileged)."""
    adapter = method.world.adapter
    base = adapter.env.unwrapped
    vehicles = {adapter.agent_id(v): v for v in base.road.vehicles if v is not base.vehicle}
    beliefs = {}
    for agent, state in zip(np.asarray(observation.ids).tolist(), np.asarray(observation.vehicles, dtype=float)):
        prior = adapter.prior(agent, state)
        vehicle = vehicles[agent]
        route = [adapter.lane_index[(a, b, 0 if i is None else i)] for a, b, i in (vehicle.route or [])]
        on_route = set(route) | {adapter.lane_index[tuple(vehicle.lane_index)]}
        routes = tuple(r for r in prior.routes if route and r[-1] == route[-1])
        lanes = tuple(lane for lane in prior.lanes if lane in on_route)
        if routes and lanes:
            TRUE_ROUTES["priors cut to the true route"] += 1
            beliefs[agent] = dataclasses.replace(prior, lanes=lanes, routes=routes)
        else:
            TRUE_ROUTES["priors left whole"] += 1
            beliefs[agent] = prior
    return beliefs


def trace(
    seed: int, lane_history: bool = False, true_routes: bool = False
) -> tuple[str, collections.Counter, list[str]]:
    """One robust episode: its outcome, the counts of verdicts per decision, and one line per decision."""
    counts: collections.Counter = collections.Counter()
    lines: list[str] = []
    captured: dict = {}
    sequence_reach, forecast, decide = hes.sequence_reach, hes.HighwayEnvRobustMethod.forecast, hes._SearchMethod.decide
    observe, beliefs = hes.HighwayEnvRobustMethod.observe, hes.HighwayEnvRobustMethod._beliefs

    def observe_lanes(self, transition):
        observe(self, transition)
        _lane_history_beliefs(self, transition.next_measured)

    def history_beliefs(self, observation):
        captured["beliefs"] = _lane_history_beliefs(self, observation)
        return captured["beliefs"]

    def route_beliefs(self, observation):
        captured["beliefs"] = _true_route_beliefs(self, observation)
        return captured["beliefs"]

    def prior_beliefs(self, observation):
        result = beliefs(self, observation)
        captured["beliefs"] = result
        return result

    def keep_reach(trajectories, vehicle):
        out = sequence_reach(trajectories, vehicle)
        captured.setdefault("boxes", out[0])  # the first call of a decision: every sequence
        return out

    def keep_forecast(self, observation, reach, speed, heading):
        result = forecast(self, observation, reach, speed, heading)
        captured.setdefault("forecast", result)  # the forecast from the reach of every sequence
        captured.setdefault("observation", observation)
        return result

    def probe(self, measurement):
        captured.clear()
        policy = decide(self, measurement)
        if not isinstance(self, hes.HighwayEnvRobustMethod):
            return policy
        boxes, fc, obs = captured["boxes"], captured["forecast"], captured["observation"]
        states = dict(zip(np.asarray(obs.ids).tolist(), np.asarray(obs.vehicles, dtype=float)))
        adapter = self.world.adapter
        chi_at_step_0 = {}  # the largest heading error of each vehicle coarse from the observation
        for j, agent in enumerate(np.asarray(fc.ids).tolist()):  # every vehicle forecast, blocking or not
            counts["vehicle forecasts"] += 1
            if fc.guaranteed[0, j] or agent not in states:
                continue
            belief = captured["beliefs"].get(agent) or adapter.prior(agent, states[agent])
            chi = chi_at_step_0[agent] = _largest_heading_error(adapter.road, belief.lanes, states[agent])
            counts["coarse at step 0"] += 1
            counts["coarse at step 0, a lane beyond CHI_MAX"] += chi > CHI_MAX
            CHI_RANGE.append(chi)
        hit = hes.box_overlaps(boxes, fc.boxes)
        hit[:, 0] = False
        first = np.where(hit.any(axis=1), hit.argmax(axis=1), hit.shape[1])
        ego = np.asarray(obs.ego, dtype=float)
        if first.max() == hit.shape[1]:
            counts["free"] += 1
            lines.append(f"| {seed} | {obs.time:.1f} | {ego[0]:.1f}, {ego[1]:.1f} | free | |")
            return policy
        k = int(first.max())
        s = int(np.argmax(first))
        b = boxes[s, k]
        o = fc.boxes[k]
        meets = np.flatnonzero((o[:, 0] <= b[2]) & (b[0] <= o[:, 2]) & (o[:, 1] <= b[3]) & (b[1] <= o[:, 3]))
        kinds = set()
        who = []
        for j in meets:
            agent = int(fc.ids[j])
            role = "follower" if agent in states and _follower(ego, states[agent]) else "other"
            grade = "fine" if fc.guaranteed[k, j] else "coarse"
            kinds.add(f"{role}, {grade}")
            lost = np.flatnonzero(~np.asarray(fc.guaranteed[:, j], dtype=bool))
            since = f", coarse from {lost[0] * fc.dt:.1f} s" if lost.size else ""
            if agent in chi_at_step_0:
                since += f" (its lanes' largest \\|chi\\| {chi_at_step_0[agent]:.2f} rad)"
            at = f" at {states[agent][0]:.0f}, {states[agent][1]:.0f}" if agent in states else ""
            who.append(
                f"{agent}{at} {role} {grade}{since}, v [{fc.state_lower[k, j, 2]:.1f}, {fc.state_upper[k, j, 2]:.1f}]"
            )
        for kind in kinds:
            counts[f"blocked: {kind}"] += 1
        counts["blocked"] += 1
        lines.append(
            f"| {seed} | {obs.time:.1f} | {ego[0]:.1f}, {ego[1]:.1f} | "
            f"blocked at {k * fc.dt:.1f} s | {'; '.join(who)} |"
        )
        return policy

    hes.sequence_reach = keep_reach
    hes.HighwayEnvRobustMethod.forecast = keep_forecast
    hes._SearchMethod.decide = probe
    if lane_history:
        hes.HighwayEnvRobustMethod.observe = observe_lanes
        hes.HighwayEnvRobustMethod._beliefs = history_beliefs
    elif true_routes:
        hes.HighwayEnvRobustMethod._beliefs = route_beliefs
    else:
        hes.HighwayEnvRobustMethod._beliefs = prior_beliefs
    try:
        record = run_episode(ENV, "robust", seed)
    finally:
        hes.sequence_reach = sequence_reach
        hes.HighwayEnvRobustMethod.forecast = forecast
        hes._SearchMethod.decide = decide
        hes.HighwayEnvRobustMethod.observe, hes.HighwayEnvRobustMethod._beliefs = observe, beliefs
    return record.outcome, counts, lines


def main() -> None:
    """Trace the seeds given and write the tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", required=True, type=count_list(0), help="comma-separated episode seeds, each >= 0")
    parser.add_argument("--out", default="benchmarks/results/trace_highway_env_stalls.md")
    parser.add_argument(
        "--lane-history",
        action="store_true",
        help="diagnosis only: restrict each vehicle's prior lanes by its previous sub-step's (see the docstring)",
    )
    parser.add_argument(
        "--true-routes",
        action="store_true",
        help="diagnosis only: cut each vehicle's prior routes to its true highway-env route (see the docstring)",
    )
    args = parser.parse_args()
    if args.lane_history and args.true_routes:
        parser.error("--lane-history and --true-routes are two diagnoses: give one")
    start = time.time()
    total: collections.Counter = collections.Counter()
    summary = [
        "| seed | outcome | decisions | free | blocked | follower, fine | follower, coarse | other, fine | other, coarse |"
    ]
    summary.append("|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    detail = [
        "| seed | t (s) | ego x, y (m) | verdict | boxes met (id, measured x, y, role, grade, speed box m/s at the collision) |",
        "|---:|---:|---|---|---|",
    ]
    for seed in args.seeds:
        outcome, counts, lines = trace(seed, args.lane_history, args.true_routes)
        total.update(counts)
        n = counts["free"] + counts["blocked"]
        cells = [
            counts[f"blocked: {k}"] for k in ("follower, fine", "follower, coarse", "other, fine", "other, coarse")
        ]
        summary.append(
            f"| {seed} | {outcome} | {n} | {counts['free']} | {counts['blocked']} | "
            + " | ".join(map(str, cells))
            + " |"
        )
        detail.extend(lines)
    n = total["free"] + total["blocked"]
    cells = [total[f"blocked: {k}"] for k in ("follower, fine", "follower, coarse", "other, fine", "other, coarse")]
    summary.append(f"| all | | {n} | {total['free']} | {total['blocked']} | " + " | ".join(map(str, cells)) + " |")
    variant = (
        " (diagnosis: lanes restricted by their history)"
        if args.lane_history
        else " (diagnosis: priors cut to the true routes)"
        if args.true_routes
        else ""
    )
    removed = (
        f"Lane history: {LANE_HISTORY['lanes removed']} lanes removed from priors, "
        f"{LANE_HISTORY['priors left whole']} priors left whole.\n\n"
        if args.lane_history
        else f"True routes: {TRUE_ROUTES['priors cut to the true route']} priors cut to the true route, "
        f"{TRUE_ROUTES['priors left whole']} left whole.\n\n"
        if args.true_routes
        else ""
    )
    coarse = (
        f"Vehicle forecasts coarse from the observation (step 0), blocking or not: {total['coarse at step 0']} of "
        f"{total['vehicle forecasts']}; {total['coarse at step 0, a lane beyond CHI_MAX']} of them with a belief lane "
        f"whose heading differs from the vehicle's by more than CHI_MAX = {CHI_MAX} rad"
        + (f" ({min(CHI_RANGE):.2f}-{max(CHI_RANGE):.2f} rad)" if CHI_RANGE else "")
        + ".\n\n"
    )
    text = (
        f"# Robust on {ENV}: what blocks each decision{variant}\n\n"
        + "\n".join(summary)
        + f"\n\n{len(args.seeds)} episodes, {time.time() - start:.0f} s wall "
        + f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}).\n\n"
        + removed
        + coarse
        + "\n".join(detail)
        + "\n"
    )
    pathlib.Path(args.out).write_text(text)
    print("\n".join(summary))


if __name__ == "__main__":
    main()
