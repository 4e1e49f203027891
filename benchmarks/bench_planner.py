"""Decision latency of the multi-model robust planner against a simulator-per-node reference.

Setting (the paper's robot, Section IV): a 2-D double integrator with anisotropic
friction (p = 4, q = 2), forward Euler at dt = 0.1 s; |A| = 4 open-loop actions
(u in {-1, 1}^2); M = 4 structural hypotheses (anisotropic friction with the
confidence box, isotropic friction, a wrong input gain, anisotropic friction with the
prior box); 10 circular obstacles; the goal reward with the robot's footprint; gamma =
0.9 and K = 100 expansions; 1 and 5 sub-steps per action.

Ours: `multi_model_robust_planner` (linked `IntervalModel`s), which runs the compiled
engine (`minimaxplan.planners.compiled_search`: search loop, box arithmetic and
reward minima in one numba kernel); its Python engine, which builds the same tree,
is timed next to it. Reference: the same search
with a simulator object per node deep-copied at every expansion and stepped by
per-step Python interval code, as rl-agents' planners with highway-env's interval
models do (`benchmarks/reference_planner.py`). Both must reach the same decision:
same action and the same root bounds to 1e-9 (asserted for every measured root).

Writes benchmarks/results/planner.md and .json (environment variables: BENCH_ROOTS,
the number of roots per row, default 6; BENCH_RESULTS, another output directory).
"""

from __future__ import annotations

import datetime
import importlib.util
import json
import os
import pathlib
import platform
import statistics
import time

import numpy as np

from minimaxplan.models import Box, UncertainLinearSystem
from minimaxplan.planners import OpenLoop, multi_model_robust_planner

HERE = pathlib.Path(__file__).parent
RESULTS = pathlib.Path(os.environ.get("BENCH_RESULTS", HERE / "results"))
SEED = 20261122
GAMMA, BUDGET, DT = 0.9, 100, 0.1
N_ROOTS, OUR_REPEATS, REFERENCE_REPEATS = int(os.environ.get("BENCH_ROOTS", 6)), 7, 1
GOALS = {1: 5.0, 5: 20.0}  # latency goals in ms
SPEEDUP_GOAL = 100.0

_spec = importlib.util.spec_from_file_location("reference_planner", HERE / "reference_planner.py")
reference = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(reference)


FRICTION_PRIOR = Box([0.2, 0.2], [0.8, 0.8])


def robot(phi, B_scale=1.0, theta=FRICTION_PRIOR):
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    B = np.zeros((4, 2))
    B[2, 0] = B[3, 1] = 1.0
    return UncertainLinearSystem.from_continuous(
        A, phi, B_scale * B, D=B.copy(), w=Box([-0.1, -0.1], [0.1, 0.1]), theta=theta, dt=DT
    )


def hypotheses():
    anisotropic = np.zeros((2, 4, 4))
    anisotropic[0, 2, 2] = anisotropic[1, 3, 3] = -1.0
    isotropic = np.zeros((1, 4, 4))
    isotropic[0, 2, 2] = isotropic[0, 3, 3] = -1.0
    return [
        (robot(anisotropic), Box([0.3, 0.4], [0.5, 0.6])),
        (robot(isotropic, theta=Box([0.2], [0.8])), Box([0.35], [0.55])),
        (robot(anisotropic, B_scale=0.6), Box([0.3, 0.4], [0.5, 0.6])),
        (robot(anisotropic), Box([0.2, 0.2], [0.8, 0.8])),
    ]


def scene(rng):
    from minimaxplan.scenarios import CircularObstacles, GoalReward

    centers = rng.uniform(1.5, 8.5, (10, 2))
    radii = rng.uniform(0.4, 1.0, 10)
    return GoalReward([10.0, 10.0], obstacles=CircularObstacles(centers, radii), robot_radius=0.3)


def reference_envs(pairs, reward, controls, substeps, lower, upper, time_index):
    from minimaxplan.models.prediction import IntervalPredictor

    obstacles = [(c[0], c[1], r) for c, r in zip(reward.obstacles.centers, reward.obstacles.radii)]
    envs = []
    for system, parameters in pairs:
        vertex_matrices = list(IntervalPredictor(system, parameters).vertex_matrices)
        envs.append(
            reference.ReferenceIntervalEnv(
                vertex_matrices,
                system.B,
                system.D,
                system.w.low,
                system.w.high,
                controls,
                substeps,
                reward.goal,
                obstacles,
                reward.robot_radius,
                lower,
                upper,
                time_index,
            )
        )
    return envs


def roots(rng, n, reward, clearance=1.0):
    """Measured boxes (half-width 0.01 in position and velocity) in free space.

    Positions uniform in the arena [0, 9]^2, at least ``clearance`` from every obstacle
    (beyond the robot's radius), velocities uniform in [-0.5, 0.5]^2: the robot is not
    already trapped, so no search ends before its K expansions.
    """
    out = []
    while len(out) < n:
        position = rng.uniform(0.0, 9.0, 2)
        if reward.obstacles.clearance(position) - reward.robot_radius < clearance:
            continue
        centre = np.concatenate([position, rng.uniform(-0.5, 0.5, 2)])
        out.append((centre - 0.01, centre + 0.01))
    return out


class _PrecomputedModel:
    """A model whose transitions cost nothing: fixed rewards, one shared next state.

    Timing the planner on M of these isolates the tree search's own bookkeeping
    (heap, back-ups, protocol checks) from the models' arithmetic.
    """

    def __init__(self, rng, n_actions):
        self.rewards = rng.uniform(0.1, 0.9, n_actions)
        self.terminals = np.zeros(n_actions, dtype=bool)
        self.states = [None] * n_actions

    def step(self, state, action):
        return None, float(self.rewards[action]), False

    def expand(self, state, actions):
        return self.states, self.rewards, self.terminals


class _PrecomputedGroup:
    """M linked models whose joint transition costs nothing (a `BatchedTransitions`, as `IntervalModel.linked`'s)."""

    def __init__(self, rng, n_models, n_actions):
        self.size = n_models
        self.rewards = rng.uniform(0.1, 0.9, (n_models, n_actions))
        self.terminals = np.zeros((n_models, n_actions), dtype=bool)
        self.states = [None] * n_actions

    def expand_all(self, state, actions):
        return self.states, self.rewards, self.terminals


class _PrecomputedMember:
    """Member ``member`` of a `_PrecomputedGroup` (a `LinkedModel`)."""

    def __init__(self, group, member):
        self.group, self.member = group, member

    def step(self, state, action):
        return None, float(self.group.rewards[self.member, action]), False

    def expand(self, state, actions):
        return self.group.states, self.group.rewards[self.member], self.group.terminals[self.member]


def _search_cpu_ms(models, n_actions):
    """Median CPU time (ms) of `RobustTreePlanner.plan` (Python engine) on models whose transitions cost nothing."""
    from minimaxplan.planners import RobustTreePlanner

    planner = RobustTreePlanner(models, range(n_actions), gamma=GAMMA, budget=BUDGET)
    times = []
    for _ in range(OUR_REPEATS * N_ROOTS):
        started = time.process_time()
        decision = planner.plan(None)
        times.append(time.process_time() - started)
    assert decision.expansions == BUDGET and planner.engine_used == "python"
    return statistics.median(times) * 1e3


def linked_search_alone(rng, n_models=4, n_actions=4):
    """The search's bookkeeping with one joint transition per expansion (the path of linked models)."""
    group = _PrecomputedGroup(rng, n_models, n_actions)
    return _search_cpu_ms([_PrecomputedMember(group, m) for m in range(n_models)], n_actions)


def tree_search_alone(rng, n_models=4, n_actions=4):
    """The search's bookkeeping through the per-model protocol."""
    return _search_cpu_ms([_PrecomputedModel(rng, n_actions) for _ in range(n_models)], n_actions)


def measure(substeps, rng):
    pairs = hypotheses()
    reward = scene(rng)
    controls = [np.array(u) for u in ([-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0])]
    from minimaxplan.planners import RobustTreePlanner

    planner = multi_model_robust_planner(
        pairs, reward, [OpenLoop(u) for u in controls], gamma=GAMMA, budget=BUDGET, substeps=substeps
    )
    python_planner = RobustTreePlanner(planner.models, planner.actions, gamma=GAMMA, budget=BUDGET, engine="python")
    ref_planner = reference.ReferenceRobustPlanner(len(controls), gamma=GAMMA, budget=BUDGET)
    ours, theirs, ours_cpu, theirs_cpu, python_engine, depths, checks = [], [], [], [], [], [], 0
    for lower, upper in roots(rng, N_ROOTS, reward):
        root = planner.models[0].initial_state(lower, upper)
        for _ in range(OUR_REPEATS):
            started, started_cpu = time.perf_counter(), time.process_time()
            decision = planner.plan(root)
            ours.append(time.perf_counter() - started)
            ours_cpu.append(time.process_time() - started_cpu)
        assert planner.engine_used == "compiled"
        for _ in range(OUR_REPEATS):
            started = time.perf_counter()
            python_decision = python_planner.plan(root)
            python_engine.append(time.perf_counter() - started)
        assert python_decision == decision  # the two engines build the same tree
        for _ in range(REFERENCE_REPEATS):
            envs = reference_envs(pairs, reward, controls, substeps, lower, upper, 0)
            started, started_cpu = time.perf_counter(), time.process_time()
            ref = ref_planner.plan(envs)
            theirs.append(time.perf_counter() - started)
            theirs_cpu.append(time.process_time() - started_cpu)
        # the same tree search must reach the same decision
        assert ref["action"] == decision.action_index, (ref, decision)
        assert abs(ref["lower"] - decision.lower) <= 1e-9 and abs(ref["upper"] - decision.upper) <= 1e-9, (
            ref,
            decision,
        )
        assert ref["expansions"] == decision.expansions == BUDGET, (ref["expansions"], decision.expansions)
        depths.append(decision.depth)
        checks += 1
    our_ms, ref_ms = statistics.median(ours) * 1e3, statistics.median(theirs) * 1e3
    our_cpu_ms, ref_cpu_ms = statistics.median(ours_cpu) * 1e3, statistics.median(theirs_cpu) * 1e3
    return {
        "substeps": substeps,
        "ours_median_ms": our_ms,
        "reference_median_ms": ref_ms,
        "speedup": ref_ms / our_ms,
        "ours_cpu_median_ms": our_cpu_ms,
        "reference_cpu_median_ms": ref_cpu_ms,
        "cpu_speedup": ref_cpu_ms / our_cpu_ms,
        "python_engine_median_ms": statistics.median(python_engine) * 1e3,
        "goal_ms": GOALS[substeps],
        "same_decisions": f"{checks}/{checks}",
        "median_depth": statistics.median(depths),
        "our_runs": len(ours),
        "reference_runs": len(theirs),
    }


def main() -> dict:
    started = time.perf_counter()
    rows = [measure(substeps, np.random.default_rng(SEED + substeps)) for substeps in (1, 5)]
    results = {
        "rows": rows,
        "tree_search_alone_cpu_ms": tree_search_alone(np.random.default_rng(SEED)),
        "linked_search_alone_cpu_ms": linked_search_alone(np.random.default_rng(SEED)),
        "setting": f"K={BUDGET} expansions, |A|=4, M=4 hypotheses, p=4, 10 obstacles, gamma={GAMMA}",
        "machine": f"{platform.machine()} {platform.processor() or ''} {platform.python_implementation()} {platform.python_version()}".strip(),
        "cpus": os.cpu_count(),
        "load_average": os.getloadavg()[0],
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "numpy": np.__version__,
    }
    results["seconds"] = time.perf_counter() - started
    lines = [
        "# Planner decision latency",
        "",
        f"{results['setting']}; roots: {N_ROOTS} measured boxes per row; ours timed {OUR_REPEATS}x per root, "
        f"the reference {REFERENCE_REPEATS}x. Every root: same action, same root bounds (to 1e-9) and the full K "
        "expansions for both (roots in free space, at least 1 m from every obstacle).",
        "",
        "Latency is the median wall-clock time of one `plan` call; the CPU columns give the median process CPU time "
        "of the same calls (less sensitive to other jobs on a shared machine).",
        "",
        "| sub-steps | ours, median (ms) | goal (ms) | reference, median (ms) | speed-up (goal >= "
        f"{SPEEDUP_GOAL:.0f}x) | ours, CPU (ms) | reference, CPU (ms) | CPU speed-up | our Python engine (ms) "
        "| median depth | same decisions |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in rows:
        lines.append(
            f"| {row['substeps']} | {row['ours_median_ms']:.2f} | <= {row['goal_ms']:.0f} | {row['reference_median_ms']:.1f} "
            f"| {row['speedup']:.1f}x | {row['ours_cpu_median_ms']:.2f} | {row['reference_cpu_median_ms']:.1f} "
            f"| {row['cpu_speedup']:.1f}x | {row['python_engine_median_ms']:.2f} | {row['median_depth']:.0f} "
            f"| {row['same_decisions']} |"
        )
    lines += [
        "",
        f"The tree search alone (the same K, M and |A| with models whose transitions cost nothing) takes "
        f"{results['tree_search_alone_cpu_ms']:.2f} ms CPU (median) through the per-model protocol, and "
        f"{results['linked_search_alone_cpu_ms']:.2f} ms with one linked group (one joint transition per "
        "expansion, the path the Python engine takes): that part of the Python engine's latency is the search's "
        "bookkeeping, the rest is the interval models' arithmetic. Ours is the compiled engine (the default for "
        "these models); the Python engine builds the same tree (asserted) and is timed for comparison.",
        "",
        f"Machine: {results['machine']}, {results['cpus']} CPUs, 1-minute load average {results['load_average']:.2f} "
        f"at the end (the machine is shared); numpy {results['numpy']}; date: {results['date']}; seed {SEED}; "
        f"run time {results['seconds']:.0f} s.",
        "",
    ]
    text = "\n".join(lines)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "planner.md").write_text(text)
    (RESULTS / "planner.json").write_text(json.dumps(results, indent=2) + "\n")
    print(text)
    return results


if __name__ == "__main__":
    main()
