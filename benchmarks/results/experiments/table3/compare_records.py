"""Compare a re-run of Table 3 with the committed records.

Every column of the old ``episodes.csv`` and every key of the old ``summary.json`` must
come back unchanged (the wall time aside); the script names each difference, lists the
columns and keys the new run adds, prints the run-time check's totals (boxes checked and
missed) and exits with status 1 on any difference or any missed box.

Usage::

    python compare_records.py OLD_DIR NEW_DIR
"""

from __future__ import annotations

import csv
import json
import math
import pathlib
import sys


def _rows(directory: pathlib.Path) -> list[dict[str, str]]:
    with open(directory / "episodes.csv", newline="") as handle:
        return list(csv.DictReader(handle))


def _same(a, b) -> bool:
    return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))


def main(old_dir: pathlib.Path, new_dir: pathlib.Path) -> int:
    old, new = _rows(old_dir), _rows(new_dir)
    differences = 0
    if len(old) != len(new):
        print(f"episodes: {len(old)} committed, {len(new)} re-run")
        return 1
    for a, b in zip(old, new):
        for key in a:
            if key != "wall_time_s" and a[key] != b.get(key):
                differences += 1
                print("differs:", a["scenario"], a["method"], a["seed"], key, a[key], b.get(key))
    print(f"episodes {len(old)}, cells of the old columns differing (wall time ignored): {differences}")
    print("new columns:", [key for key in new[0] if key not in old[0]])
    old_summary = json.loads((old_dir / "summary.json").read_text())
    new_summary = json.loads((new_dir / "summary.json").read_text())
    for a, b in zip(old_summary, new_summary):
        for key in a:
            if not _same(a[key], b.get(key)):
                differences += 1
                print("summary differs:", a["scenario"], a["method"], key, a[key], b.get(key))
    print("summary keys added:", [key for key in new_summary[0] if key not in old_summary[0]])
    for s in new_summary:
        print(s["scenario"], s["method"], "boxes_checked", s["boxes_checked"], "boxes_missed", s["boxes_missed"])
    checked = sum(int(r["boxes_checked"]) for r in new)
    missed = sum(int(r["boxes_missed"]) for r in new)
    print(f"total: boxes checked {checked}, missed {missed}")
    return 1 if differences or missed else 0


if __name__ == "__main__":
    sys.exit(main(pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])))
