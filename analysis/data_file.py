"""Data files (CSV, NPZ) for the command-line tools: one observed trajectory each.

A data file holds the states ``x_0 .. x_N`` and the controls ``u_0 .. u_{N-1}`` of one
trajectory; `load_data_file` reads it into a `TransitionData`. Model files are
`minimaxplan.analysis.model_file`. The format is documented in ``docs/model-format.md``.
"""

from __future__ import annotations

import csv
import math
import pathlib
import re
from dataclasses import dataclass

import numpy as np

from minimaxplan.models import InputError

__all__ = ["DataFileError", "TransitionData", "load_data_file"]


class DataFileError(InputError):
    """A data file is missing, unreadable or malformed (the message names the file and the column)."""


@dataclass(frozen=True, eq=False)
class TransitionData:
    """One observed trajectory: ``states`` (N+1, p) and ``controls`` (N, q).

    Attributes
    ----------
    states : numpy.ndarray
        Shape (N+1, p): the states ``x_0 .. x_N`` (state units).
    controls : numpy.ndarray
        Shape (N, q): the controls ``u_0 .. u_{N-1}``, ``u_n`` applied after ``x_n``.
    source : str
        Where the data came from: the file's path, or ``"<arrays>"``.
    """

    states: np.ndarray
    controls: np.ndarray
    source: str = "<arrays>"

    @property
    def ntransitions(self) -> int:
        """N, the number of transitions (rows of ``controls``)."""
        return self.controls.shape[0]

    def to_dict(self) -> dict:
        """The trajectory as a dict of plain Python values (``source``, ``states``, ``controls``), for JSON."""
        return {"source": self.source, "states": self.states.tolist(), "controls": self.controls.tolist()}


_COLUMN = re.compile(r"^([xu])(\d+)$")


def load_data_file(path) -> TransitionData:
    """Read one observed trajectory from a ``.csv`` or ``.npz`` file.

    CSV: a header row naming the columns ``x0 .. x{p-1}`` and ``u0 .. u{q-1}`` (any
    order), then one row per time step n = 0..N with the state x_n and the control u_n
    applied after it. The last row's controls are not used (there is no next state):
    leave them empty or give any finite number. NPZ: arrays ``states`` (N+1, p) and
    ``controls`` (N, q); other arrays in the file are ignored.

    Parameters
    ----------
    path : str or os.PathLike
        The data file, ending in ``.csv`` or ``.npz`` (any case).

    Returns
    -------
    TransitionData
        The trajectory, read-only float arrays; ``source`` is the path.

    Raises
    ------
    DataFileError
        If the file is missing, has another extension, or is malformed (the message
        names the column or array, the row and the shapes).
    """
    path = pathlib.Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".npz"):
        raise DataFileError(f"data file {str(path)!r} must end in .csv or .npz, got {suffix or 'no extension'!r}")
    if path.is_dir():
        raise DataFileError(f"data file {str(path)!r} is a directory, not a file")
    if not path.is_file():
        raise DataFileError(f"data file {str(path)!r} does not exist")
    try:
        states, controls = _read_csv(path) if suffix == ".csv" else _read_npz(path)
    except DataFileError:
        raise
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise DataFileError(f"cannot read data file {str(path)!r}: {exc}") from None
    return _checked_data(states, controls, str(path))


def _read_csv(path: pathlib.Path) -> tuple[np.ndarray, np.ndarray]:
    with path.open(newline="", encoding="utf-8") as handle:
        reader = csv.reader(handle)
        numbered = [(reader.line_num, row) for row in reader if any(cell.strip() for cell in row)]
    where = str(path)
    if not numbered:
        raise DataFileError(f"{where}: empty file; expected a header row x0,..,u0,..")
    header = [cell.strip() for cell in numbered[0][1]]
    columns: dict[str, dict[int, int]] = {"x": {}, "u": {}}
    for position, label in enumerate(header):
        match = _COLUMN.match(label)
        if match is None:
            raise DataFileError(f"{where}: unknown column {label!r}; columns must be named x0, x1, .. and u0, u1, ..")
        kind, index = match.group(1), int(match.group(2))
        if index in columns[kind]:
            raise DataFileError(f"{where}: column {label!r} appears twice")
        columns[kind][index] = position
    for kind in ("x", "u"):
        indices = sorted(columns[kind])
        if not indices:
            raise DataFileError(f"{where}: no {kind} columns; expected {kind}0, {kind}1, ..")
        if indices != list(range(len(indices))):
            raise DataFileError(f"{where}: {kind} columns must be numbered 0..{len(indices) - 1}, got {indices}")
    body = numbered[1:]
    if len(body) < 2:
        raise DataFileError(f"{where}: need at least 2 data rows (one transition), got {len(body)}")
    p, q = len(columns["x"]), len(columns["u"])
    states = np.empty((len(body), p))
    controls = np.empty((len(body) - 1, q))
    for n, (line, row) in enumerate(body):
        last = n == len(body) - 1
        if last and len(row) < len(header):
            row = row + [""] * (len(header) - len(row))  # the unused last controls may be left out
        if len(row) != len(header):
            raise DataFileError(f"{where}: line {line} has {len(row)} cells, the header has {len(header)}")
        for kind, target in (("x", states), ("u", controls)):
            for index, position in columns[kind].items():
                cell = row[position].strip()
                if kind == "u" and last:
                    if cell:
                        _cell_value(cell, where, line, header[position])
                    continue
                target[n, index] = _cell_value(cell, where, line, header[position])
    return states, controls


def _cell_value(cell: str, where: str, line: int, column: str) -> float:
    if not cell:
        raise DataFileError(f"{where}: line {line}, column {column!r} is empty")
    try:
        value = float(cell)
    except ValueError:
        raise DataFileError(f"{where}: line {line}, column {column!r} is not a number: {cell!r}") from None
    if not math.isfinite(value):
        raise DataFileError(f"{where}: line {line}, column {column!r} is not finite: {cell!r}")
    return value


def _read_npz(path: pathlib.Path) -> tuple[np.ndarray, np.ndarray]:
    with np.load(path, allow_pickle=False) as archive:
        missing = [key for key in ("states", "controls") if key not in archive.files]
        if missing:
            raise DataFileError(f"{path}: missing array(s) {missing}; the file holds {sorted(archive.files)}")
        return archive["states"], archive["controls"]


def _checked_data(states, controls, where: str) -> TransitionData:
    arrays = {}
    for name, value in (("states", states), ("controls", controls)):
        array = np.asarray(value)
        if array.dtype.kind not in "iuf":
            raise DataFileError(f"{where}: {name} must be a real numeric array, got dtype {array.dtype}")
        array = array.astype(float)
        if array.ndim != 2 or 0 in array.shape:
            raise DataFileError(f"{where}: {name} must be a non-empty 2-dimensional array, got shape {array.shape}")
        if not np.all(np.isfinite(array)):
            bad = np.argwhere(~np.isfinite(array))[0].tolist()
            raise DataFileError(f"{where}: {name} contains NaN or infinite entries (first at index {bad})")
        array.setflags(write=False)
        arrays[name] = array
    states, controls = arrays["states"], arrays["controls"]
    if states.shape[0] != controls.shape[0] + 1:
        raise DataFileError(
            f"{where}: states must have one row more than controls (N+1 states, N controls), "
            f"got states shape {states.shape} and controls shape {controls.shape}"
        )
    return TransitionData(states, controls, where)
