"""Lemma 1 / Theorem 3 in practice: the root gap ``upper - lower`` against the budget K.

Two robust multi-model problems, solved by `RobustTreePlanner` with K expansions:

1. *double integrator*: a 1-D point mass ``x+ = x + dt v``, ``v+ = v + dt (b u - c v)``
   with three hypotheses (c, b) on friction and actuator gain, actions
   ``u in {-1, 0, 1}``, reward ``1 / (1 + |x - goal|)`` and a terminal reward 0 when
   the mass leaves ``|x| <= 6``; gamma = 0.9, M = 3, |A| = 3.
2. *random trees*: M = 3 models whose rewards are i.i.d. uniform on [0, 1] per
   (model, action path), |A| = 2, gamma = 0.9, averaged over 10 random trees.

For each K the script reports the root bounds, the gap (which bounds the robust
regret of the chosen action), the tree depth d and the depth bound
``gamma^(d-1) / (1 - gamma)`` of Appendix C (the gap never exceeds it; asserted),
and the median planning time (each plan repeated 5 times). The empirical rate is the least-squares slope s of
``log gap`` against ``log K`` for K >= 10; Lemma 1 predicts
``gap = O(K^(-log(1/gamma) / log kappa))``, so ``kappa_eff = gamma^(1/s)``.

Writes benchmarks/results/lemma1.md and lemma1.png.
"""

from __future__ import annotations

import datetime
import pathlib
import platform
import time

import numpy as np

from minimaxplan.planners import RobustTreePlanner

BUDGETS = (1, 2, 5, 10, 20, 50, 100, 200, 500)
GAMMA = 0.9
TIMING_RUNS = 5  # plan() is deterministic: repeated only to take a median time
RESULTS = pathlib.Path(__file__).parent / "results"


class DoubleIntegrator:
    """One hypothesis of the 1-D double integrator; vectorised over the actions."""

    def __init__(self, friction: float, gain: float, *, dt: float = 0.5, goal: float = 4.0, wall: float = 6.0):
        self.friction, self.gain, self.dt, self.goal, self.wall = friction, gain, dt, goal, wall

    def expand(self, state, actions):
        x, v = state
        u = np.asarray(actions, dtype=float)
        v_next = v + self.dt * (self.gain * u - self.friction * v)
        x_next = np.full_like(u, x + self.dt * v)
        crashed = np.abs(x_next) > self.wall
        rewards = np.where(crashed, 0.0, 1.0 / (1.0 + np.abs(x_next - self.goal)))
        return list(zip(x_next.tolist(), v_next.tolist())), rewards, crashed

    def step(self, state, action):
        next_states, rewards, terminals = self.expand(state, [action])
        return next_states[0], float(rewards[0]), bool(terminals[0])


class RandomTree:
    """Rewards i.i.d. uniform per (seed, action path), from Python's deterministic int-tuple hash."""

    def __init__(self, seed: int):
        self.seed = seed

    def step(self, path, action):
        child = path + (action,)
        reward = (hash((self.seed,) + child) & ((1 << 53) - 1)) / float(1 << 53)
        return child, reward


def sweep(make_models, actions, state, repeats=1):
    rows = []
    for budget in BUDGETS:
        gaps, lowers, uppers, depths, times = [], [], [], [], []
        for r in range(repeats):
            planner = RobustTreePlanner(make_models(r), actions, gamma=GAMMA, budget=budget)
            for _ in range(TIMING_RUNS):
                start = time.perf_counter()
                decision = planner.plan(state)
                times.append(time.perf_counter() - start)
            bound = GAMMA ** (decision.depth - 1) / (1 - GAMMA)
            assert decision.gap <= bound + 4 * np.finfo(float).eps / (1 - GAMMA), (budget, decision.gap, bound)
            gaps.append(decision.gap)
            lowers.append(decision.lower)
            uppers.append(decision.upper)
            depths.append(decision.depth)
        rows.append(
            {
                "K": budget,
                "lower": float(np.mean(lowers)),
                "upper": float(np.mean(uppers)),
                "gap": float(np.mean(gaps)),
                "depth": float(np.mean(depths)),
                "depth_bound": float(np.mean([GAMMA ** (d - 1) / (1 - GAMMA) for d in depths])),
                "ms": 1e3 * float(np.median(times)),
            }
        )
    for previous, row in zip(rows, rows[1:]):
        if repeats == 1:  # one fixed problem: the bounds are monotone in K (Theorem 3)
            assert row["lower"] >= previous["lower"] and row["upper"] <= previous["upper"]
    return rows


def rate(rows):
    ks = np.array([r["K"] for r in rows if r["K"] >= 10], dtype=float)
    gaps = np.array([r["gap"] for r in rows if r["K"] >= 10])
    slope = float(np.polyfit(np.log(ks), np.log(gaps), 1)[0])
    kappa = GAMMA ** (1.0 / slope) if slope < 0 else float("inf")
    return slope, kappa


def table(title, rows, slope, kappa):
    lines = [
        f"### {title}",
        "",
        "| K | lower | upper | gap = upper - lower | depth d | gamma^(d-1)/(1-gamma) | time per plan (ms) |",
        "|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['K']} | {r['lower']:.4f} | {r['upper']:.4f} | {r['gap']:.4f} | {r['depth']:.1f} | "
            f"{r['depth_bound']:.4f} | {r['ms']:.2f} |"
        )
    lines += ["", f"Empirical rate (K >= 10): gap ~ K^{slope:.3f}, i.e. kappa_eff = gamma^(1/slope) = {kappa:.2f}.", ""]
    return lines


def main():
    integrator = sweep(
        lambda r: [DoubleIntegrator(0.0, 1.0), DoubleIntegrator(0.3, 0.8), DoubleIntegrator(0.6, 1.2)],
        (-1.0, 0.0, 1.0),
        (0.0, 0.0),
    )
    trees = sweep(lambda r: [RandomTree(1000 * r + m) for m in range(3)], (0, 1), (), repeats=10)
    results = [
        (
            "Double integrator, M = 3 hypotheses (c, b) in {(0, 1), (0.3, 0.8), (0.6, 1.2)}, |A| = 3, gamma = 0.9",
            integrator,
            *rate(integrator),
        ),
        ("Random reward trees, M = 3, |A| = 2, gamma = 0.9 (mean of 10 trees)", trees, *rate(trees)),
    ]
    lines = [
        "# Lemma 1: root gap upper - lower against the budget K (RobustTreePlanner)",
        "",
        f"Machine: {platform.processor() or platform.machine()}, {platform.system()} {platform.release()}, "
        f"Python {platform.python_version()}; date: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC.",
        "The gap bounds the robust regret of the chosen action (Theorem 3); K = number of expansions, "
        "each stepping every model for every action.",
        "",
    ]
    for title, rows, slope, kappa in results:
        lines += table(title, rows, slope, kappa)
    text = "\n".join(lines)
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "lemma1.md").write_text(text)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for (title, rows, slope, _), marker in zip(results, "os"):
        ks = [r["K"] for r in rows]
        ax.loglog(ks, [r["gap"] for r in rows], marker=marker, label=f"{title.split(',')[0]} (slope {slope:.2f})")
        ax.loglog(ks, [r["depth_bound"] for r in rows], linestyle=":", color=ax.lines[-1].get_color())
    ax.set_xlabel("budget K (expansions)")
    ax.set_ylabel("upper - lower at the root")
    ax.set_title("Lemma 1: gap vs budget (dotted: gamma^(d-1)/(1-gamma))", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(RESULTS / "lemma1.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
