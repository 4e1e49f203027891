"""Assumption 4 LMI: first call (build + DPP compile) vs re-solve of the cached problem.

`check_assumption4` builds one primal cvxpy problem per (form, p, number of vertices)
with the matrices as cvxpy Parameters, caches it, and re-solves it with new parameter
values (the dual SDP, solved only when no certificate came out, is built per call). The reference, measured in the same run, is the first call, i.e.
what every call would cost without the cache (build the problem, canonicalise it,
solve). Cases: one 4x4 matrix and a 4-vertex polytope of 4x4 matrices, both forms;
every call decides a different random matrix (half of them stable).

Writes benchmarks/results/lmi.md.
"""

from __future__ import annotations

import datetime
import pathlib
import platform
import time

import numpy as np

import minimaxplan.verify.lmi as lmi
from minimaxplan.verify import check_assumption4

SEED = 20261122
P = 4
VERTICES = 4
FIRST_REPEATS = 7
RESOLVE_REPEATS = 30
RESULTS = pathlib.Path(__file__).parent / "results"


def random_case(rng, form: str, nvertices: int) -> np.ndarray:
    """A random 4x4 matrix at spectral abscissa (radius) +-[0.05, 0.3] from the boundary,
    or a polytope of small perturbations around one."""
    M = rng.standard_normal((P, P))
    edge = rng.uniform(0.05, 0.3) * rng.choice([-1.0, 1.0])
    if form == "continuous":
        centre = M - (np.linalg.eigvals(M).real.max() - edge) * np.eye(P)
    else:
        centre = M * (1.0 + edge) / np.abs(np.linalg.eigvals(M)).max()
    if nvertices == 1:
        return centre
    return centre + 0.02 * rng.standard_normal((nvertices, P, P))


def timed(A, form: str) -> tuple[float, float, str]:
    start = time.perf_counter()
    result = check_assumption4(A, form=form)
    return time.perf_counter() - start, result.solve_time, result.status


def measure(rng, form: str, nvertices: int) -> dict:
    first, resolve, solves, statuses = [], [], [], []
    for _ in range(FIRST_REPEATS):
        lmi._PROGRAMS.clear()
        seconds, _, status = timed(random_case(rng, form, nvertices), form)
        first.append(seconds)
        statuses.append(status)
    for _ in range(RESOLVE_REPEATS):
        seconds, solve_seconds, status = timed(random_case(rng, form, nvertices), form)
        resolve.append(seconds)
        solves.append(solve_seconds)
        statuses.append(status)
    return {
        "first": float(np.median(first)),
        "resolve": float(np.median(resolve)),
        "solve_calls": float(np.median(solves)),
        "statuses": {s: statuses.count(s) for s in sorted(set(statuses))},
    }


def main() -> dict:
    started = time.perf_counter()
    rng = np.random.default_rng(SEED)
    check_assumption4(-np.eye(2), form="continuous")  # import/JIT warm-up outside the timings
    rows = []
    for nvertices in (1, VERTICES):
        for form in ("continuous", "discrete"):
            rows.append((nvertices, form, measure(rng, form, nvertices)))
    machine = f"{platform.machine()} {platform.processor() or ''} {platform.python_implementation()} {platform.python_version()}".strip()
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    total = time.perf_counter() - started
    lines = [
        "# Assumption 4 LMI: first call (build) vs re-solve (DPP cache)",
        "",
        f"Machine: {machine}; date: {date}; seed {SEED}; run time {total:.1f} s; solver CLARABEL.",
        f"Median wall time of `check_assumption4` per call: first call after clearing the cache "
        f"({FIRST_REPEATS} runs) and cached re-solves with new random matrices ({RESOLVE_REPEATS} runs). "
        "Every call solves the primal SDP twice (normalised and caller's coordinates) on the "
        "same cached problem and re-checks its certificates exactly; a call without a "
        "certificate also builds and solves the dual SDP (infeasible verdicts).",
        "",
        "| case | form | first call (build) | re-solve (cached) | ratio | of which cvxpy solve calls | outcomes |",
        "|---|---|---|---|---|---|---|",
    ]
    for nvertices, form, m in rows:
        case = f"one {P}x{P} matrix" if nvertices == 1 else f"{nvertices}-vertex polytope, {P}x{P}"
        outcomes = ", ".join(f"{k} {v}" for k, v in m["statuses"].items())
        lines.append(
            f"| {case} | {form} | {1e3 * m['first']:.1f} ms | {1e3 * m['resolve']:.1f} ms | "
            f"{m['first'] / m['resolve']:.1f}x | {1e3 * m['solve_calls']:.1f} ms | {outcomes} |"
        )
    text = "\n".join(lines) + "\n"
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "lmi.md").write_text(text)
    print(text)
    return {"rows": rows}


if __name__ == "__main__":
    main()
