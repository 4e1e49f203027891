"""Execute notebooks in place and store their outputs (`make notebooks`).

The documentation renders the notebooks with the outputs stored in them (`make docs`
executes nothing); after changing a notebook, or the code it calls, run this to refresh
them. Each notebook runs in its own folder, as `tests/test_notebooks.py` runs it, on this
interpreter's kernel; the per-cell timing metadata that Jupyter adds is dropped, so that
re-running an unchanged notebook changes nothing but what its code prints and draws.

    python docs/execute_notebooks.py [NOTEBOOK.ipynb ...]   # default: notebooks/*.ipynb
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

import nbformat
from nbclient import NotebookClient

ROOT = pathlib.Path(__file__).resolve().parents[1]
TIMEOUT_PER_CELL = 300  # seconds


def execute_in_place(path: pathlib.Path) -> None:
    """Run every cell of the notebook at ``path`` in order and write it back with its outputs."""
    notebook = nbformat.read(path, as_version=4)
    NotebookClient(
        notebook, timeout=TIMEOUT_PER_CELL, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}}
    ).execute()
    for cell in notebook.cells:
        cell.metadata.pop("execution", None)
    nbformat.validate(notebook)
    nbformat.write(notebook, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("notebooks", nargs="*", type=pathlib.Path)
    args = parser.parse_args()
    # the kernel must run this interpreter (the venv's), whatever is first on PATH
    os.environ["PATH"] = str(pathlib.Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", "")
    for path in args.notebooks or sorted((ROOT / "notebooks").glob("*.ipynb")):
        execute_in_place(path.resolve())
        print(f"executed {path}")


if __name__ == "__main__":
    main()
