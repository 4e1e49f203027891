"""Why the robust ego stalls or collides at the T-junction: what blocks each decision (issue 11).

Runs robust T-junction episodes (the registered ``tjunction`` world and method, the
experiment's loop and seeds) and, at every decision, holds each action for the rest of
the forecast (10 decisions, the planner's own `BicycleModel`) and finds its first
sub-step with a possible collision on the decision's obstacle table (the planner's
reward: 0 where the ego's rectangle meets a box). A decision is *blocked* when every held
action may collide; it is then attributed to the box of the held action that collides
last: ``coarse`` when that vehicle's forecast has left the fine model there
(``guaranteed`` False), else ``fine``. Counts are per route lane of the ego (``south_in``
before the stop line, the arc ``south_west``, ``west_out``).

The held actions are a probe, not the planner's tree (which also switches actions): a
blocked decision means no action held to the end of the forecast is free of possible
collisions. The diagnosis reads the method's own tables and forecasts only.

Usage::

    python benchmarks/trace_stalls.py --seeds 5,11,20 [--out benchmarks/results/trace_stalls.md]
"""

from __future__ import annotations

import argparse
import collections
import pathlib
import time

import numpy as np

from minimaxplan.analysis import road_planning
from minimaxplan.analysis.arguments import count_list
from minimaxplan.analysis.episode import run_episode

HELD_DECISIONS = 10


def trace(seed: int) -> tuple[str, collections.Counter]:
    """One robust T-junction episode: its outcome and the counts of (ego lane, verdict) per decision."""
    counts: collections.Counter = collections.Counter()
    forecasts: list = []
    tables: list = []
    forecast_traffic = road_planning.forecast_traffic
    obstacles = road_planning.RoadRobustMethod.obstacles
    decide = road_planning.RoadPlanningMethod.decide

    def keep_forecast(*args, **kwargs):
        forecasts.append(forecast_traffic(*args, **kwargs))
        return forecasts[-1]

    def keep_tables(self, observation):
        tables.append(obstacles(self, observation))
        return tables[-1]

    def probe(self, measurement):
        level, lane = self.level, self.lane
        policy = decide(self, measurement)
        world = self.world.world
        t = world.step_index
        table, forecast = tables[-1].table, forecasts[-1]
        reward = self.ego.reward.with_obstacles(table, t)
        model = self.model.with_reward(reward)
        last = (-1, True)
        blocked = True
        for action in range(model.n_actions):
            state = model.initial_state(measurement.ego, level=level, lane=lane, time=t)
            hit = None
            for d in range(HELD_DECISIONS):
                states, _, state = model.predict(state, action)
                k = d * len(states) + 1 + np.arange(len(states))
                _, collided = reward.evaluate(states, t + k)
                if np.any(collided):
                    i = int(np.argmax(collided))
                    hit = (int(k[i]), states[i])
                    break
            if hit is None:
                blocked = False
                break
            step, ego = hit
            if step > last[0]:
                row = table[min(step, len(table) - 1)]
                x, y = ego[0], ego[1]
                near = (row[:, 0] <= x + 3) & (row[:, 2] >= x - 3) & (row[:, 1] <= y + 3) & (row[:, 3] >= y - 3)
                fine = bool(np.all(forecast.guaranteed[min(step, forecast.steps), near]))
                last = (step, fine)
        route_lane = world.road.names[int(world.traffic.lane[0])]
        verdict = ("blocked, " + ("fine" if last[1] else "coarse")) if blocked else "free"
        counts[(route_lane, verdict)] += 1
        return policy

    road_planning.forecast_traffic = keep_forecast
    road_planning.RoadRobustMethod.obstacles = keep_tables
    road_planning.RoadPlanningMethod.decide = probe
    try:
        record = run_episode("tjunction", "robust", seed)
    finally:
        road_planning.forecast_traffic = forecast_traffic
        road_planning.RoadRobustMethod.obstacles = obstacles
        road_planning.RoadPlanningMethod.decide = decide
    return record.outcome, counts


def main() -> None:
    """Trace the seeds given and write the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", required=True, type=count_list(0), help="comma-separated episode seeds, each >= 0")
    parser.add_argument("--out", default="benchmarks/results/trace_stalls.md")
    args = parser.parse_args()
    seeds = args.seeds
    start = time.time()
    total: collections.Counter = collections.Counter()
    lines = ["| seed | outcome | decisions: ego lane, verdict |", "|---:|---|---|"]
    for seed in seeds:
        outcome, counts = trace(seed)
        total.update(counts)
        cells = ", ".join(f"{lane} {verdict}: {n}" for (lane, verdict), n in sorted(counts.items()))
        lines.append(f"| {seed} | {outcome} | {cells} |")
    lanes = sorted({lane for lane, _ in total})
    summary = ["", "| ego lane | decisions | blocked, coarse | blocked, fine | free |", "|---|---:|---:|---:|---:|"]
    for lane in lanes:
        row = {verdict: n for (ln, verdict), n in total.items() if ln == lane}
        n = sum(row.values())
        summary.append(
            f"| {lane} | {n} | {row.get('blocked, coarse', 0)} | {row.get('blocked, fine', 0)} | {row.get('free', 0)} |"
        )
    text = "\n".join(lines + summary) + f"\n\n{len(seeds)} episodes, {time.time() - start:.0f} s wall.\n"
    pathlib.Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
