"""Execute every notebook in notebooks/ so that none can go stale.

Nothing here is skipped: a missing nbclient/nbformat/ipykernel, a missing kernel or an
empty notebooks/ folder is a failure.
"""

from __future__ import annotations

import json
import pathlib
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
TIMEOUT_PER_CELL = 120  # seconds; each notebook must run in well under a minute
#: Text that a notebook's printed output must contain once executed (what it must show).
EXPECTED_OUTPUT = {
    "assumption4_regions.ipynb": [
        "infeasible - no certificate with normalised margin above",
        "certified fraction: 1.0",
        "conflicting vertices: (0, 1) irreducible: True",
    ],
}


def test_there_are_notebooks_to_run():
    assert NOTEBOOKS, f"no notebooks found in {ROOT / 'notebooks'}"


def _printed(cells) -> list[str]:
    return ["".join(o.get("text", "") for o in c["outputs"] if o.get("output_type") == "stream") for c in cells]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_is_committed_with_its_outputs(path):
    # make docs renders the stored outputs and executes nothing: every code cell carries
    # them, from one run in order (`make notebooks` stores them).
    notebook = json.loads(path.read_text(encoding="utf-8"))
    counts = [cell.get("execution_count") for cell in notebook["cells"] if cell["cell_type"] == "code"]
    assert counts == list(range(1, len(counts) + 1)), f"{path.name}: run `make notebooks` and commit the outputs"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_executes(path, monkeypatch):
    import nbformat
    from nbclient import NotebookClient

    # The kernel must run this interpreter (the venv's), whatever is first on PATH:
    # jupyter_client replaces a kernelspec's bare "python" by sys.executable, and we put
    # the interpreter's folder first on PATH for any other launcher.
    monkeypatch.setenv("PATH", str(pathlib.Path(sys.executable).parent), prepend=":")
    notebook = nbformat.read(path, as_version=4)
    stored = _printed([cell for cell in notebook.cells if cell.cell_type == "code"])
    client = NotebookClient(
        notebook,
        timeout=TIMEOUT_PER_CELL,
        kernel_name="python3",
        resources={"metadata": {"path": str(path.parent)}},
    )
    client.execute()  # raises CellExecutionError, naming the cell, if any cell fails
    executed = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert executed and all(cell.execution_count is not None for cell in executed)
    assert _printed(executed) == stored, f"{path.name}: the stored outputs are stale: run `make notebooks`"
    printed = "".join(
        output.get("text", "") for cell in executed for output in cell.outputs if output.get("output_type") == "stream"
    )
    for expected in EXPECTED_OUTPUT.get(path.name, []):
        assert expected in printed, f"{path.name}: the output lacks {expected!r}"
    if path.name == "assumption4_regions.ipynb":
        # every piece's verdict agrees with the Shorten-Narendra test for its interval
        verdicts = [line.split() for line in printed.splitlines() if "Shorten-Narendra:" in line]
        assert len(verdicts) >= 2
        assert all(words[3] == words[5] for words in verdicts), verdicts
