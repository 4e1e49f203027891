"""Run every benchmark script (benchmarks/bench_*.py) in turn; each writes its
figures to benchmarks/results/<name>.md and .json and prints them."""

from __future__ import annotations

import pathlib
import runpy
import sys

HERE = pathlib.Path(__file__).parent


def main() -> int:
    scripts = sorted(HERE.glob("bench_*.py"))
    if len(sys.argv) > 1:
        scripts = [s for s in scripts if any(key in s.stem for key in sys.argv[1:])]
    if not scripts:
        print("no benchmark matched", file=sys.stderr)
        return 1
    (HERE / "results").mkdir(exist_ok=True)
    for script in scripts:
        print(f"== {script.stem}", flush=True)
        sys.argv = [str(script)]  # each script parses its own (default) options, not run_all's filter
        runpy.run_path(str(script), run_name="__main__")
    return 0


if __name__ == "__main__":
    sys.exit(main())
