"""Which methods' episode records depend on the CPU-dispatched code: OpenBLAS's kernel, numpy's SIMD loops.

OpenBLAS chooses its kernels at load time from the CPU (``OPENBLAS_CORETYPE`` overrides
the choice), numpy its SIMD loops (``NPY_DISABLE_CPU_FEATURES`` caps them). The same
episodes are run once per variant of `RECORDS_ENVIRONMENT`, each in fresh processes of
``minimaxplan experiment``, and every record is compared, cell by cell (wall time aside),
with the run under `RECORDS_ENVIRONMENT` itself. Each run's ``environment.json`` shows
that the variant took effect (the kernel loaded, the SIMD targets used). The variants
are those an x86-64 CPU with AVX2 can run (an AVX-512 kernel would need such a CPU): the
point is which results move with the dispatched code, which is why the records are made
and replayed under one.

Usage::

    python benchmarks/blas_kernel_sensitivity.py [--seeds 0-9] [--out FILE]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

from minimaxplan.analysis.arguments import count_list
from minimaxplan.analysis.numerical_environment import RECORDS_BLAS_KERNEL, RECORDS_ENVIRONMENT

WORLDS = ("static", "pedestrian")
METHODS = ("robust", "nominal", "oracle", "dwa", "teb")
#: (label, overrides of RECORDS_ENVIRONMENT, the BLAS kernel and numpy SIMD targets it must show)
VARIANTS = (
    ("records", {}, RECORDS_BLAS_KERNEL, ["X86_V3"]),
    ("OpenBLAS Sandybridge", {"OPENBLAS_CORETYPE": "Sandybridge"}, "Sandybridge", ["X86_V3"]),
    ("OpenBLAS Nehalem", {"OPENBLAS_CORETYPE": "Nehalem"}, "Nehalem", ["X86_V3"]),
    ("numpy SIMD X86_V2", {"NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR"}, RECORDS_BLAS_KERNEL, []),
)
RESULT = pathlib.Path(__file__).parent / "results" / "blas_kernel_sensitivity.md"


def run_variant(variant: tuple, seeds: list[int], out: pathlib.Path) -> tuple[dict, dict, float]:
    """Run the worlds and methods on ``seeds`` under one variant; records by key, environment, wall time."""
    label, overrides, kernel, targets = variant
    env = {**os.environ, **RECORDS_ENVIRONMENT, **overrides}
    records: dict = {}
    environment: dict = {}
    start = time.perf_counter()
    for seed in seeds:
        directory = out / f"{label.replace(' ', '_')}-{seed}"
        command = [sys.executable, "-m", "minimaxplan.analysis.cli", "experiment", "--scenario", ",".join(WORLDS)]
        command += ["--methods", ",".join(METHODS), "--episodes", "1", "--seed", str(seed), "--workers", "1"]
        command += ["--no-progress", "--out", str(directory)]
        subprocess.run(command, env=env, check=True, stdout=subprocess.DEVNULL)
        with open(directory / "episodes.csv", newline="") as handle:
            for row in csv.DictReader(handle):
                records[(row["scenario"], row["method"], int(row["seed"]))] = row
        environment = json.loads((directory / "environment.json").read_text())
        shown = (set(environment["blas_kernels"].values()), environment["numpy_simd_targets"])
        if shown != ({kernel}, targets):
            raise RuntimeError(f"{label}: the variant did not take effect (this CPU?): {shown}")
    return records, environment, time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=count_list(0), default=list(range(10)), help="seeds (default 0-9)")
    parser.add_argument("--out", type=pathlib.Path, default=RESULT)
    args = parser.parse_args(argv)
    runs = {}
    with tempfile.TemporaryDirectory() as scratch:
        for variant in VARIANTS:
            label = variant[0]
            runs[label] = run_variant(variant, args.seeds, pathlib.Path(scratch))
            print(f"{label}: {len(runs[label][0])} episodes, {runs[label][2]:.0f} s", file=sys.stderr)
    reference, reference_environment, _ = runs[VARIANTS[0][0]]
    lines = [
        "# Episode records against the CPU-dispatched code (OpenBLAS kernel, numpy SIMD)",
        "",
        f"`python benchmarks/blas_kernel_sensitivity.py`, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
        f"load {os.getloadavg()[0]:.1f}; CPU {reference_environment['cpu']}, numpy "
        f"{reference_environment['numpy']} (SIMD targets {', '.join(reference_environment['numpy_simd_targets'])}), "
        f"scipy {reference_environment['scipy']}. Seeds {args.seeds[0]}-{args.seeds[-1]} of both robot worlds, "
        f"each variant in fresh processes; an episode differs when any cell but the wall time does. "
        f"Reference: the records' environment ({', '.join(f'{k}={v}' for k, v in RECORDS_ENVIRONMENT.items())}); "
        "each variant changes one variable.",
        "",
        "| variant | method | episodes | differing episodes | differing columns | wall time of the variant's run (s) |",
        "|---|---|---|---|---|---|",
    ]
    for label, *_ in VARIANTS[1:]:
        records, _, wall = runs[label]
        for method in METHODS:
            keys = [key for key in reference if key[1] == method]
            differing = [key for key in keys if _differs(reference[key], records[key])]
            columns = sorted(
                {c for key in differing for c in reference[key] if _differs_in(reference[key], records[key], c)}
            )
            lines.append(
                f"| {label} | {method} | {len(keys)} | {len(differing)} | {', '.join(columns) or '-'} | {wall:.0f} |"
            )
    args.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


def _differs_in(a: dict, b: dict, column: str) -> bool:
    return column != "wall_time_s" and a[column] != b.get(column)


def _differs(a: dict, b: dict) -> bool:
    return any(_differs_in(a, b, column) for column in a)


if __name__ == "__main__":
    raise SystemExit(main())
