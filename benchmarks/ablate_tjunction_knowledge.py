"""What the robust T-junction ego would do if it knew what the learner could learn (issue 11; diagnosis only).

Runs robust T-junction episodes (the registered world and method, the experiment's loop
and seeds) with every vehicle's belief replaced, at every decision, by the world's hidden
truth at one of three levels, and reports the outcomes:

- ``parameters``: theta_a and theta_b the vehicle's own (to a relative `PAD`), its routes
  and the target-speed range the learner's;
- ``parameters+route``: also only the routes the learner kept that are part of the
  vehicle's true route;
- ``parameters+route+target``: also its target speed, exactly.

Everything the learner cannot know stays uncertain in all three: the disturbances, the
measurement noise, whether a main-road vehicle yields (courtesy and the stop rule are
hidden switches) and when. The beliefs read the simulator's hidden state, so these runs
are **unsound** (the run-time box check still counts misses: a miss here is a belief
that does not hold the truth, which would be a bug of this script) and are not a method:
they bound what better learning of these quantities could buy.

Usage::

    python benchmarks/ablate_tjunction_knowledge.py --level parameters --seeds 1,3,5 [--workers 2]
"""

from __future__ import annotations

import argparse
import multiprocessing
import time

import numpy as np

from minimaxplan.analysis import road_planning, traffic_learning
from minimaxplan.analysis.arguments import count, count_list
from minimaxplan.analysis.episode import run_episode
from minimaxplan.models.sets import Box
from minimaxplan.scenarios.traffic_models import VehicleBelief

LEVELS = ("parameters", "parameters+route", "parameters+route+target")
#: Relative half-width of the true parameters' boxes.
PAD = 1e-6


def _on_route(route: tuple, true_route: list) -> bool:
    """Whether ``route`` is a contiguous part of ``true_route``."""
    n = len(route)
    return any(tuple(true_route[i : i + n]) == tuple(route) for i in range(len(true_route) - n + 1))


def told_beliefs(beliefs: dict, traffic, level: str) -> dict:
    """The learner's ``beliefs`` with the true quantities of ``level`` written in (hulled inside the learner's boxes).

    Parameters
    ----------
    beliefs : dict
        ``agent -> VehicleBelief`` from the learner.
    traffic : TrafficState
        The world's true traffic (hidden from the methods).
    level : str
        One of `LEVELS`.
    """
    out = {}
    for agent, belief in beliefs.items():
        ta, tb = np.asarray(traffic.theta_a[agent], float), np.asarray(traffic.theta_b[agent], float)
        theta_a = Box(
            np.maximum(ta - PAD * np.abs(ta), belief.theta_a.low),
            np.minimum(ta + PAD * np.abs(ta), belief.theta_a.high),
        )
        theta_b = Box(
            np.maximum(tb - PAD * np.abs(tb), belief.theta_b.low),
            np.minimum(tb + PAD * np.abs(tb), belief.theta_b.high),
        )
        routes, target = belief.routes, None
        if level != "parameters":
            true_route = [int(lane) for lane in traffic.routes[agent] if lane >= 0]
            routes = tuple(r for r in belief.routes if _on_route(r, true_route)) or belief.routes
        if level == "parameters+route+target":
            v_t = float(traffic.target_speed[agent])
            target = (v_t, v_t)
        out[agent] = VehicleBelief(belief.agent, theta_a, theta_b, belief.lanes, routes, target_speed=target)
    return out


def run(seed: int, level: str) -> tuple[int, str, float, int, int]:
    """One robust T-junction episode with told beliefs: (seed, outcome, time s, boxes missed, boxes checked)."""
    beliefs = traffic_learning.TrafficLearner.beliefs
    learn = road_planning._LearningMethod._learn
    episode: dict = {}

    def learn_and_keep_world(self, observation):
        episode["world"] = self.world.world
        return learn(self, observation)

    def told(self, agents=None):
        return told_beliefs(beliefs(self, agents), episode["world"].traffic, level)

    road_planning._LearningMethod._learn = learn_and_keep_world
    traffic_learning.TrafficLearner.beliefs = told
    try:
        record = run_episode("tjunction", "robust", seed)
    finally:
        road_planning._LearningMethod._learn = learn
        traffic_learning.TrafficLearner.beliefs = beliefs
    return seed, record.outcome, record.time_s, record.boxes_missed, record.boxes_checked


def main() -> None:
    """Run the seeds given at one level and print one line per episode and the totals."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--level", required=True, choices=LEVELS)
    parser.add_argument("--seeds", required=True, type=count_list(0), help="comma-separated episode seeds, each >= 0")
    parser.add_argument("--workers", type=count(1), default=2, help="worker processes, >= 1")
    args = parser.parse_args()
    start = time.time()
    jobs = [(seed, args.level) for seed in args.seeds]
    with multiprocessing.get_context("fork").Pool(args.workers) as pool:
        results = sorted(pool.starmap(run, jobs))
    for seed, outcome, time_s, missed, checked in results:
        print(f"seed {seed}: {outcome} at {time_s:.1f} s, boxes missed {missed} of {checked}")
    goals = [r[0] for r in results if r[1] == "goal"]
    print(
        f"{args.level}: {len(goals)} of {len(results)} reach the goal (seeds {','.join(map(str, goals))}); "
        f"boxes missed {sum(r[3] for r in results)} of {sum(r[4] for r in results)}; {time.time() - start:.0f} s wall"
    )


if __name__ == "__main__":
    main()
