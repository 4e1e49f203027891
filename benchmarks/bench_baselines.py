"""Decision latency of the DWA and TEB baselines, against in-repo references.

1. Closed-loop episodes of both worlds (benchmark seeds 20000+, apart from the tuning
   seeds 10000+ and the evaluation seeds 0-999): median and 90th percentile of the time
   per `plan` call (goal: DWA < 5 ms, TEB < 50 ms typical), with the final goal as the
   scene's goal, and inside the episode loop of `analysis.episode` (methods of
   `analysis.robot_methods`), whose goal is a sliding waypoint.
2. DWA against a per-sample reference: the same window, rollouts and score written as
   plain loops over samples, sub-steps and discs with ``system.step`` (how a direct
   transcription of the algorithm runs). Same scores (to 1e-9) and same choice,
   asserted at every compared decision; the ratio is reference time / vectorised time.
3. TEB's L-BFGS-B with the analytic gradient of `band_cost` against the same
   optimisation with scipy's finite-difference gradient (``jac=None``), from the same
   initial bands; the ratio is reference time / analytic time, with both final costs.

Writes benchmarks/results/baselines.md.
"""

from __future__ import annotations

import datetime
import pathlib
import platform
import time

import numpy as np
from scipy.optimize import minimize

from minimaxplan.planners.dwa import DynamicWindowPlanner, NavigationScene
from minimaxplan.planners.teb import TimedElasticBand, band_cost
from minimaxplan.scenarios.worlds import make_world

BENCH_SEED0 = 20_000
EPISODES_PER_WORLD = 5
RESULTS = pathlib.Path(__file__).parent / "results"


def scene_of(world) -> NavigationScene:
    crowd = world.crowd
    return NavigationScene(
        world.goal, world.obstacles.centers, world.obstacles.radii, crowd.positions, crowd.announced, crowd.radii
    )


def closed_loop_latencies(make_planner) -> tuple[np.ndarray, dict]:
    latencies, outcomes = [], {}
    for kind in ("static", "pedestrian"):
        for seed in range(BENCH_SEED0, BENCH_SEED0 + EPISODES_PER_WORLD):
            world = make_world(kind, seed)
            planner = make_planner(world)
            while not world.done:
                state = world.measure()
                started = time.perf_counter()
                u = planner.plan(state, scene_of(world))
                latencies.append(time.perf_counter() - started)
                world.apply_held(u)
            outcomes[world.outcome] = outcomes.get(world.outcome, 0) + 1
    return np.array(latencies), outcomes


def waypoint_loop_latencies(cls) -> tuple[np.ndarray, dict]:
    """The same, inside `minimaxplan.analysis.episode.run_episode`, whose scene goal is a
    waypoint sliding 3 m ahead on its global path (timing wrapped around ``cls.plan``)."""
    from minimaxplan.analysis.episode import run_episode

    latencies, outcomes = [], {}
    original = cls.plan

    def timed(self, state, scene):
        started = time.perf_counter()
        u = original(self, state, scene)
        latencies.append(time.perf_counter() - started)
        return u

    cls.plan = timed
    try:
        method = "dwa" if cls is DynamicWindowPlanner else "teb"
        for kind in ("static", "pedestrian"):
            for seed in range(BENCH_SEED0, BENCH_SEED0 + EPISODES_PER_WORLD):
                record = run_episode(kind, method, seed)
                outcomes[record.outcome] = outcomes.get(record.outcome, 0) + 1
    finally:
        cls.plan = original
    return np.array(latencies), outcomes


# ------------------------------------------------------------ DWA reference
def reference_dwa_scores(planner: DynamicWindowPlanner, x: np.ndarray, scene: NavigationScene) -> np.ndarray:
    """The DWA score of every sample, one sample, sub-step and disc at a time."""
    p = planner.params
    system = planner.system
    theta = system.theta.center
    dt = planner._dt
    centers, radii, velocities = scene.centers, scene.radii, scene.velocities
    n_static = scene.obstacle_centers.shape[0]
    horizon = planner._horizon_steps
    nav = planner._navigation(scene, x[None, :2]) if p.navigation_function else None
    scores = []
    for u in planner.controls:
        held, state = [], x.copy()
        for _ in range(horizon):
            state = system.step(state, u, theta)
            held.append(state)
        stopping, state = list(held[: planner.substeps]), held[planner.substeps - 1]
        for _ in range(planner._brake_steps):
            state = system.step(state, np.clip(-state[2:] / dt, -planner.control_bound, planner.control_bound), theta)
            stopping.append(state)
        admissible = True
        for n, s in enumerate(stopping):
            t = dt * (n + 1)
            for j in range(centers.shape[0]):
                need = planner.robot_radius + p.safety_margin + (p.pedestrian_margin if j >= n_static else 0.0)
                if np.linalg.norm(s[:2] - (centers[j] + t * velocities[j])) - radii[j] < need:
                    admissible = False
        speed_after = np.linalg.norm(held[planner.substeps - 1][2:])
        if not (speed_after <= p.max_speed or speed_after < np.linalg.norm(x[2:])):
            admissible = False
        if not admissible:
            scores.append(-np.inf)
            continue
        clearance = np.inf
        for n, s in enumerate(held):
            t = dt * (n + 1)
            for j in range(centers.shape[0]):
                footprint = planner.robot_radius + (p.pedestrian_margin if j >= n_static else 0.0)
                clearance = min(
                    clearance, np.linalg.norm(s[:2] - (centers[j] + t * velocities[j])) - radii[j] - footprint
                )
        end = held[-1]
        speed_end = np.linalg.norm(end[2:])
        if nav is not None:
            d0, d_end = float(nav.cost_to_go(x[:2])), float(nav.cost_to_go(end[:2]))
            cosine = float(end[2:] @ nav.descent(end[:2])) / max(speed_end, 1e-9)
        else:
            d0, d_end = np.linalg.norm(scene.goal - x[:2]), np.linalg.norm(scene.goal - end[:2])
            cosine = float(end[2:] @ (scene.goal - end[:2])) / max(speed_end * d_end, 1e-9)
        scores.append(
            p.progress_weight * (d0 - d_end) / (p.max_speed * p.horizon)
            + p.heading_weight * (1 + cosine) / 2
            + p.clearance_weight * min(max(clearance, 0.0), p.clearance_cap) / p.clearance_cap
            + p.velocity_weight * min(speed_end / p.max_speed, 1.0)
        )
    return np.array(scores)


def dwa_against_reference(decisions: int = 40) -> dict:
    fast_times, slow_times, compared = [], [], 0
    for kind in ("static", "pedestrian"):
        world = make_world(kind, BENCH_SEED0)
        planner = DynamicWindowPlanner(world.system)
        for _ in range(decisions // 2):
            if world.done:
                break
            x, scene = world.measure(), scene_of(world)
            planner.evaluate(x, scene)  # builds the cached navigation function outside the timing
            started = time.perf_counter()
            evaluation = planner.evaluate(x, scene)
            fast_times.append(time.perf_counter() - started)
            started = time.perf_counter()
            reference = reference_dwa_scores(planner, x, scene)
            slow_times.append(time.perf_counter() - started)
            assert np.array_equal(np.isfinite(reference), evaluation.admissible), "admissible sets differ"
            finite = np.isfinite(reference)
            assert np.allclose(reference[finite], evaluation.scores[finite], rtol=0, atol=1e-9), "scores differ"
            if finite.any():
                assert reference[np.argmax(evaluation.scores)] >= reference.max() - 1e-9, "choices differ"
            compared += 1
            world.apply_held(evaluation.control)
    fast, slow = np.median(fast_times), np.median(slow_times)
    return {"compared": compared, "fast_ms": 1e3 * fast, "slow_ms": 1e3 * slow, "ratio": slow / fast}


# ------------------------------------------------------------ TEB reference
def teb_against_finite_differences(bands: int = 10) -> dict:
    analytic_times, numeric_times, analytic_costs, numeric_costs = [], [], [], []
    world = make_world("static", BENCH_SEED0)
    planner = TimedElasticBand(world.system)
    scene = scene_of(world)
    rng = np.random.default_rng(BENCH_SEED0)
    p = planner.params
    for _ in range(bands):
        start = world.start + rng.uniform(-0.5, 0.5, 2)
        velocity = rng.uniform(-1, 1, 2)
        X, dT = planner._fresh_band(start, world.goal, 0.0, planner._guide(start, scene))
        n = len(dT)
        z0 = np.concatenate([X[1:-1].ravel(), dT])
        bounds = [(None, None)] * (2 * (n - 1)) + [(p.dt_min, p.dt_max)] * n
        args = (start, velocity, world.goal, n, planner.friction, planner._discs(scene), p, planner.control_bound)
        options = {"maxiter": p.max_iterations}
        started = time.perf_counter()
        fast = minimize(band_cost, z0, args=args, jac=True, method="L-BFGS-B", bounds=bounds, options=options)
        analytic_times.append(time.perf_counter() - started)
        started = time.perf_counter()
        slow = minimize(
            lambda z, *a: band_cost(z, *a)[0], z0, args=args, method="L-BFGS-B", bounds=bounds, options=options
        )
        numeric_times.append(time.perf_counter() - started)
        analytic_costs.append(fast.fun)
        numeric_costs.append(slow.fun)
    fast_t, slow_t = np.median(analytic_times), np.median(numeric_times)
    return {
        "bands": bands,
        "variables": int(z0.size),
        "fast_ms": 1e3 * fast_t,
        "slow_ms": 1e3 * slow_t,
        "ratio": slow_t / fast_t,
        "fast_cost": float(np.median(analytic_costs)),
        "slow_cost": float(np.median(numeric_costs)),
    }


def main() -> None:
    dwa_lat, dwa_out = closed_loop_latencies(lambda w: DynamicWindowPlanner(w.system))
    teb_lat, teb_out = closed_loop_latencies(lambda w: TimedElasticBand(w.system))
    dwa_way, dwa_way_out = waypoint_loop_latencies(DynamicWindowPlanner)
    teb_way, teb_way_out = waypoint_loop_latencies(TimedElasticBand)
    dwa_ref = dwa_against_reference()
    teb_ref = teb_against_finite_differences()
    lines = [
        "# Baselines: decision latency",
        "",
        f"Machine: {platform.machine()}, {platform.processor() or 'unknown cpu'}, Python {platform.python_version()}; "
        f"date {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC. "
        f"Closed loop: {EPISODES_PER_WORLD} episodes per world, seeds {BENCH_SEED0}+.",
        "",
        "| planner | calls | median (ms) | p90 (ms) | goal | outcomes | target |",
        "|---|---|---|---|---|---|---|",
        f"| DWA | {dwa_lat.size} | {1e3 * np.median(dwa_lat):.2f} | {1e3 * np.percentile(dwa_lat, 90):.2f} | "
        f"{dwa_out.get('goal', 0)}/{2 * EPISODES_PER_WORLD} | {dwa_out} | < 5 ms |",
        f"| TEB | {teb_lat.size} | {1e3 * np.median(teb_lat):.2f} | {1e3 * np.percentile(teb_lat, 90):.2f} | "
        f"{teb_out.get('goal', 0)}/{2 * EPISODES_PER_WORLD} | {teb_out} | < 50 ms |",
        f"| DWA, waypoint goal (analysis.episode) | {dwa_way.size} | {1e3 * np.median(dwa_way):.2f} | "
        f"{1e3 * np.percentile(dwa_way, 90):.2f} | {dwa_way_out.get('goal', 0)}/{2 * EPISODES_PER_WORLD} | {dwa_way_out} | < 5 ms |",
        f"| TEB, waypoint goal (analysis.episode) | {teb_way.size} | {1e3 * np.median(teb_way):.2f} | "
        f"{1e3 * np.percentile(teb_way, 90):.2f} | {teb_way_out.get('goal', 0)}/{2 * EPISODES_PER_WORLD} | {teb_way_out} | < 50 ms |",
        "",
        "| comparison | reference (ms) | ours (ms) | ratio | check |",
        "|---|---|---|---|---|",
        f"| DWA vectorised vs per-sample loops ({dwa_ref['compared']} decisions) | {dwa_ref['slow_ms']:.1f} | "
        f"{dwa_ref['fast_ms']:.2f} | {dwa_ref['ratio']:.0f}x | same scores (1e-9) and choices |",
        f"| TEB analytic vs finite-difference gradient ({teb_ref['bands']} bands, {teb_ref['variables']} variables) | "
        f"{teb_ref['slow_ms']:.1f} | {teb_ref['fast_ms']:.1f} | {teb_ref['ratio']:.1f}x | "
        f"median final cost {teb_ref['fast_cost']:.3f} (analytic) vs {teb_ref['slow_cost']:.3f} (numeric) |",
        "",
    ]
    text = "\n".join(lines)
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "baselines.md").write_text(text)


if __name__ == "__main__":
    main()
