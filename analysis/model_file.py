"""Model files (TOML) for the command-line tools.

A model file describes one uncertain linear system, or several competing structural
hypotheses about the same plant, in TOML; `load_model_file` turns it into
`UncertainLinearSystem` values and `format_model_file` writes them back. Observed
trajectories are data files (`minimaxplan.analysis.data_file`). The format is
documented in ``docs/model-format.md``.
"""

from __future__ import annotations

import math
import pathlib
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from minimaxplan.models import Box, InputError, UncertainLinearSystem

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - python 3.10 only
    import tomli as tomllib

__all__ = [
    "ModelFileError",
    "ModelHypothesis",
    "ModelFile",
    "load_model_file",
    "parse_model_file",
    "format_model_file",
    "DISCRETE",
    "CONTINUOUS",
]

DISCRETE = "discrete"
CONTINUOUS = "continuous"

# Keys a model (a hypothesis table, or the top level of a single-model file) may hold.
_MODEL_KEYS = {"name", "time", "dt", "A0", "A", "phi", "B", "D", "w", "theta"}
# Keys only the top level may hold.
_FILE_KEYS = {"hypothesis", "measurement_noise", "state_names", "state_units"}
_BOX_KEYS = {"low", "high"}


class ModelFileError(InputError):
    """A model file is missing, unreadable or malformed (the message names the file and the key)."""


@dataclass(frozen=True, eq=False)
class ModelHypothesis:
    """One model of a model file.

    Parameters
    ----------
    name
        The model's name (defaults to ``"hypothesis <index>"``).
    system
        The discrete-time system that the library works with. For a continuous-time
        model it is the forward-Euler discretisation of eq. (1) with step ``dt``.
    time
        ``"discrete"`` (the file gave ``A0``) or ``"continuous"`` (the file gave ``A``).
    dt
        The sampling time, or None (allowed only for discrete-time models).
    continuous_system
        For a continuous-time model, the continuous-time matrices as given in the file
        (``A0`` holds the file's ``A``, ``D`` the file's ``D``), kept so that Assumption 4
        can be checked in its continuous form; None for a discrete-time model.
    """

    name: str
    system: UncertainLinearSystem
    time: str
    dt: float | None
    continuous_system: UncertainLinearSystem | None = None

    def system_for(self, form: str) -> UncertainLinearSystem:
        """The system whose matrices the ``form`` of Assumption 4 is checked on.

        Parameters
        ----------
        form : {"discrete", "continuous"}
            The LMI's form.

        Returns
        -------
        UncertainLinearSystem
            `system` for "discrete", `continuous_system` for "continuous".

        Raises
        ------
        ModelFileError
            If ``form`` is "continuous" and the model is discrete-time.
        InputError
            If ``form`` is neither.
        """
        if form == CONTINUOUS:
            if self.continuous_system is None:
                raise ModelFileError(
                    f"model {self.name!r} is discrete-time (it gives A0); the continuous form of "
                    'Assumption 4 needs a continuous-time model (time = "continuous" with A and dt)'
                )
            return self.continuous_system
        if form == DISCRETE:
            return self.system
        raise InputError(f"form must be 'discrete' or 'continuous', got {form!r}")

    def state_matrices(self, form: str, *, vertices: bool) -> tuple[np.ndarray, np.ndarray]:
        """The state matrices to certify and the disturbance matrix, for ``form``.

        Returns ``(A, D)`` where ``A`` has shape (k, p, p): the nominal matrix
        ``A(theta.center)`` (k = 1), or with ``vertices`` the matrices at the 2^d
        vertices of the prior box ``theta``, whose convex hull contains every
        ``A(theta)`` because ``A`` is affine in theta (eq. (2)).

        Parameters
        ----------
        form : {"discrete", "continuous"}
            The LMI's form (`system_for`).
        vertices : bool
            The matrices at the vertices of ``theta`` (True) or at its centre (False).

        Raises
        ------
        ModelFileError
            If ``form`` is "continuous" and the model is discrete-time.
        """
        system = self.system_for(form)
        points = system.theta.vertices() if vertices else system.theta.center[None, :]
        return system.A(points), np.array(system.D)

    def to_dict(self) -> dict:
        """The model as a dict of plain Python values (systems as `UncertainLinearSystem.to_dict`), for JSON."""
        out = {"name": self.name, "time": self.time, "dt": self.dt, "system": self.system.to_dict()}
        if self.continuous_system is not None:
            out["continuous_system"] = self.continuous_system.to_dict()
        return out


@dataclass(frozen=True, eq=False)
class ModelFile:
    """The contents of a model file: its models and the data's measurement-noise bound.

    ``measurement_noise`` is None, or the bound ``v_bar`` (shape (p,)) on the
    measurement noise of every state coordinate (DESIGN errata). ``state_names`` and
    ``state_units`` are None or p strings (the reports label states and margins with
    them).

    Attributes
    ----------
    hypotheses : tuple of ModelHypothesis
        The file's models, in file order (unique names, same numbers of states and inputs).
    measurement_noise : numpy.ndarray or None
        Shape (p,), state units: the bound ``v_bar``, or None (no measurement noise).
    source : str
        Where the text came from: the file's path, or ``"<string>"``.
    state_names, state_units : tuple of str or None
        p labels and p units of the states, or None.
    """

    hypotheses: tuple[ModelHypothesis, ...]
    measurement_noise: np.ndarray | None = None
    source: str = "<string>"
    state_names: tuple[str, ...] | None = None
    state_units: tuple[str, ...] | None = None

    @property
    def names(self) -> list[str]:
        """The models' names, in file order."""
        return [h.name for h in self.hypotheses]

    @property
    def systems(self) -> list[UncertainLinearSystem]:
        """The models' discrete-time systems (`ModelHypothesis.system`), in file order."""
        return [h.system for h in self.hypotheses]

    def select(self, name: str) -> ModelFile:
        """The same file restricted to the model called ``name``.

        Parameters
        ----------
        name : str
            The name of one of the file's models (`names`).

        Raises
        ------
        ModelFileError
            If no model has that name.
        """
        chosen = tuple(h for h in self.hypotheses if h.name == name)
        if not chosen:
            raise ModelFileError(f"{self.source}: no model named {name!r}; the file holds {self.names}")
        return ModelFile(chosen, self.measurement_noise, self.source, self.state_names, self.state_units)

    def to_dict(self) -> dict:
        """The file's contents as a dict of plain Python values (`ModelHypothesis.to_dict` per model), for JSON."""
        return {
            "source": self.source,
            "hypotheses": [h.to_dict() for h in self.hypotheses],
            "measurement_noise": None if self.measurement_noise is None else self.measurement_noise.tolist(),
            "state_names": None if self.state_names is None else list(self.state_names),
            "state_units": None if self.state_units is None else list(self.state_units),
        }


# ----------------------------------------------------------------- reading models
def load_model_file(path) -> ModelFile:
    """Read a TOML model file (format: ``docs/model-format.md``).

    Parameters
    ----------
    path : str or os.PathLike
        The model file (UTF-8 TOML).

    Raises
    ------
    ModelFileError
        If the file is missing or unreadable, is not valid TOML, has an unknown or
        missing key, a non-numeric, non-finite or wrongly shaped value, or describes an
        invalid system (the message names the file, the model and the key).
    """
    path = pathlib.Path(path)
    if path.is_dir():
        raise ModelFileError(f"model file {str(path)!r} is a directory, not a file")
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ModelFileError(f"model file {str(path)!r} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelFileError(f"cannot read model file {str(path)!r}: {exc}") from None
    return parse_model_file(text, source=str(path))


def parse_model_file(text: str, *, source: str = "<string>") -> ModelFile:
    """Parse the text of a TOML model file; see `load_model_file`.

    Parameters
    ----------
    text : str
        The TOML text.
    source : str
        Where the text came from, used in error messages and as `ModelFile.source`
        (and, for a single-model file without ``name``, its stem names the model).
    """
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ModelFileError(f"{source}: not valid TOML: {exc}") from None
    unknown = sorted(set(document) - _MODEL_KEYS - _FILE_KEYS)
    if unknown:
        raise ModelFileError(
            f"{source}: unknown key(s) {unknown} at the top level; allowed: {sorted(_MODEL_KEYS | _FILE_KEYS)}"
        )
    defaults = {k: v for k, v in document.items() if k in _MODEL_KEYS}
    if "hypothesis" in document:
        tables = document["hypothesis"]
        if not isinstance(tables, list) or not tables or not all(isinstance(t, dict) for t in tables):
            raise ModelFileError(f"{source}: 'hypothesis' must be one or more [[hypothesis]] tables")
        hypotheses = []
        for index, table in enumerate(tables):
            where = f"{source}: hypothesis[{index}]"
            if "measurement_noise" in table:
                raise ModelFileError(
                    f"{where}: measurement_noise describes the sensor, not a hypothesis; give it at the top level"
                )
            unknown = sorted(set(table) - _MODEL_KEYS)
            if unknown:
                raise ModelFileError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(_MODEL_KEYS)}")
            merged = {**defaults, **table}
            hypotheses.append(_parse_model(merged, where, default_name=f"hypothesis {index}"))
    else:
        hypotheses = [_parse_model(defaults, f"{source}: top level", default_name=pathlib.Path(source).stem)]
    names = [h.name for h in hypotheses]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ModelFileError(f"{source}: model names must be unique, repeated: {duplicates}")
    sizes = {(h.system.nstates, h.system.ninputs) for h in hypotheses}
    if len(sizes) > 1:
        shapes = [(h.name, h.system.nstates, h.system.ninputs) for h in hypotheses]
        raise ModelFileError(
            f"{source}: every hypothesis must have the same numbers of states and inputs, got (name, p, q) = {shapes}"
        )
    noise = None
    if "measurement_noise" in document:
        p = hypotheses[0].system.nstates
        noise = _numeric(document["measurement_noise"], f"{source}: measurement_noise")
        if noise.ndim == 0:
            noise = np.full(p, float(noise))
        if noise.shape != (p,):
            raise ModelFileError(
                f"{source}: measurement_noise must be a number or have shape ({p},) (one bound per state), "
                f"got shape {noise.shape}"
            )
        if np.any(noise < 0):
            raise ModelFileError(f"{source}: measurement_noise must be >= 0, got {noise.tolist()}")
    labels = {}
    for key in ("state_names", "state_units"):
        if key in document:
            value = document[key]
            p = hypotheses[0].system.nstates
            if not isinstance(value, list) or not all(isinstance(v, str) and v.strip() for v in value):
                raise ModelFileError(f"{source}: {key} must be a list of non-empty strings, got {value!r}")
            if len(value) != p:
                raise ModelFileError(f"{source}: {key} must have {p} entries (one per state), got {len(value)}")
            labels[key] = tuple(value)
    return ModelFile(tuple(hypotheses), noise, source, labels.get("state_names"), labels.get("state_units"))


def _parse_model(table: Mapping[str, Any], where: str, *, default_name: str) -> ModelHypothesis:
    name = table.get("name", default_name)
    if not isinstance(name, str) or not name.strip():
        raise ModelFileError(f"{where}: name must be a non-empty string, got {name!r}")
    where = f"{where} ({name!r})" if "name" in table else where
    time = table.get("time", DISCRETE)
    if time not in (DISCRETE, CONTINUOUS):
        raise ModelFileError(f'{where}: time must be "discrete" or "continuous", got {time!r}')
    dt = None
    if "dt" in table:
        dt = _finite_positive(table["dt"], f"{where}: dt")
    state_key = "A" if time == CONTINUOUS else "A0"
    other_key = "A0" if time == CONTINUOUS else "A"
    if other_key in table:
        raise ModelFileError(
            f"{where}: time = {time!r} takes the state matrix as key '{state_key}', found '{other_key}' "
            f'(A0 is a discrete-time matrix; A with time = "continuous" and dt is discretised by forward Euler)'
        )
    for key in (state_key, "phi", "B", "w", "theta"):
        if key not in table:
            raise ModelFileError(f"{where}: missing required key '{key}'")
    if time == CONTINUOUS and dt is None:
        raise ModelFileError(
            f"{where}: missing required key 'dt' (a continuous-time model is discretised with step dt)"
        )
    A = _matrix(table[state_key], f"{where}: {state_key}", ndim=2)
    p = A.shape[0]
    if A.shape != (p, p):
        raise ModelFileError(f"{where}: {state_key} must be square, got shape {A.shape}")
    phi = _matrix(table["phi"], f"{where}: phi", ndim=3, hint="a list of d matrices, each p x p")
    if phi.shape[1:] != (p, p):
        raise ModelFileError(
            f"{where}: phi must have shape (d, {p}, {p}) to match {state_key} {A.shape}, got shape {phi.shape}"
        )
    B = _matrix(table["B"], f"{where}: B", ndim=2)
    if B.shape[0] != p:
        raise ModelFileError(f"{where}: B must have shape ({p}, q) to match {state_key} {A.shape}, got shape {B.shape}")
    D = None
    if "D" in table:
        D = _matrix(table["D"], f"{where}: D", ndim=2)
        if D.shape[0] != p:
            raise ModelFileError(
                f"{where}: D must have shape ({p}, r) to match {state_key} {A.shape}, got shape {D.shape}"
            )
    r = p if D is None else D.shape[1]
    w = _box(
        table["w"],
        f"{where}: w",
        r,
        f"the columns of D {D.shape}" if D is not None else f"the {p} states (D is the identity)",
    )
    theta = _box(table["theta"], f"{where}: theta", phi.shape[0], f"the {phi.shape[0]} matrices of phi")
    try:
        if time == CONTINUOUS:
            assert dt is not None  # checked above: a continuous-time model needs dt
            system = UncertainLinearSystem.from_continuous(A, phi, B, D=D, w=w, theta=theta, dt=dt)
            continuous = UncertainLinearSystem(A, phi, B, D=D, w=w, theta=theta)
        else:
            system = UncertainLinearSystem(A, phi, B, D=D, w=w, theta=theta)
            continuous = None
    except InputError as exc:
        raise ModelFileError(f"{where}: {exc}") from None
    return ModelHypothesis(name=name, system=system, time=time, dt=dt, continuous_system=continuous)


def _finite_positive(value: Any, where: str) -> float:
    """A TOML number that is finite and > 0, as a float (integers too large for a float rejected)."""
    message = f"{where} must be a finite number > 0, got {value!r}"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ModelFileError(message)
    try:
        x = float(value)
    except OverflowError:
        raise ModelFileError(f"{where} must be a finite number > 0, got an integer too large for a float") from None
    if not math.isfinite(x) or x <= 0:
        raise ModelFileError(message)
    return x


def _numeric(value: Any, where: str, hint: str = "") -> np.ndarray:
    """A TOML number or (nested) array of numbers as a finite float array."""

    def check(item: Any) -> None:
        if isinstance(item, list):
            for element in item:
                check(element)
        elif isinstance(item, bool) or not isinstance(item, (int, float)):
            raise ModelFileError(f"{where} must hold only numbers{hint}, found {item!r}")

    check(value)
    try:
        array = np.array(value, dtype=float)
    except OverflowError:
        raise ModelFileError(
            f"{where} holds an integer too large for a float (largest: {sys.float_info.max:.6g})"
        ) from None
    except ValueError:
        raise ModelFileError(f"{where} is ragged: its rows must all have the same length{hint}") from None
    if not np.all(np.isfinite(array)):
        raise ModelFileError(f"{where} contains NaN or infinite entries (TOML nan/inf are not allowed)")
    return array


def _matrix(value: Any, where: str, *, ndim: int, hint: str = "") -> np.ndarray:
    hint = f" ({hint})" if hint else ""
    array = _numeric(value, where, hint)
    if array.ndim != ndim or 0 in array.shape:
        raise ModelFileError(f"{where} must be a non-empty {ndim}-dimensional array{hint}, got shape {array.shape}")
    return array


def _box(value: Any, where: str, dim: int, what: str) -> Box:
    if not isinstance(value, dict):
        raise ModelFileError(f"{where} must be a table {{low = [...], high = [...]}}, got {value!r}")
    keys = set(value)
    if keys != _BOX_KEYS:
        missing, extra = sorted(_BOX_KEYS - keys), sorted(keys - _BOX_KEYS)
        raise ModelFileError(
            f"{where} must have exactly the keys 'low' and 'high' (missing {missing}, unknown {extra})"
        )
    low = _numeric(value["low"], f"{where}.low")
    high = _numeric(value["high"], f"{where}.high")
    for side, array in (("low", low), ("high", high)):
        if array.shape != (dim,):
            raise ModelFileError(f"{where}.{side} must have shape ({dim},) to match {what}, got shape {array.shape}")
    if np.any(low > high):
        raise ModelFileError(f"{where} is empty: low > high at indices {np.flatnonzero(low > high).tolist()}")
    return Box(low, high)


# ----------------------------------------------------------------- writing models
def format_model_file(
    hypotheses: Sequence[ModelHypothesis], *, measurement_noise=None, header: str | None = None
) -> str:
    """The TOML text of a model file holding ``hypotheses``; `parse_model_file` inverts it.

    Numbers are written with ``repr``, which round-trips float64 exactly. A
    continuous-time hypothesis is written with its continuous-time matrices and ``dt``.

    Parameters
    ----------
    hypotheses : sequence of ModelHypothesis
        The models, written as ``[[hypothesis]]`` tables in this order.
    measurement_noise : float or array_like, optional
        The bound ``v_bar`` (a number, or shape (p,), state units); omitted if None.
    header : str, optional
        Text written first, each line as a TOML comment (``# ...``).
    """
    lines = [f"# {line}" for line in (header or "").splitlines()]
    if measurement_noise is not None:
        lines.append(f"measurement_noise = {_toml_value(np.asarray(measurement_noise, dtype=float))}")
    for hypothesis in hypotheses:
        lines += ["", "[[hypothesis]]"] + _model_lines(hypothesis)
    return "\n".join(lines).lstrip("\n") + "\n"


def _model_lines(h: ModelHypothesis) -> list[str]:
    lines = [f"name = {_toml_string(h.name)}", f'time = "{h.time}"']
    if h.dt is not None:
        lines.append(f"dt = {_toml_value(np.asarray(h.dt, dtype=float))}")
    system = h.system_for(h.time)
    state_key = "A" if h.time == CONTINUOUS else "A0"
    lines += [
        f"{state_key} = {_toml_value(system.A0)}",
        f"phi = {_toml_value(system.phi)}",
        f"B = {_toml_value(system.B)}",
        f"D = {_toml_value(system.D)}",
        f"w = {{ low = {_toml_value(system.w.low)}, high = {_toml_value(system.w.high)} }}",
        f"theta = {{ low = {_toml_value(system.theta.low)}, high = {_toml_value(system.theta.high)} }}",
    ]
    return lines


def _toml_value(array: np.ndarray) -> str:
    if array.ndim == 0:
        return repr(float(array))
    return "[" + ", ".join(_toml_value(item) for item in array) + "]"


def _toml_string(text: str) -> str:
    """A TOML basic string: backslash, quote and control characters escaped."""
    out = []
    for char in text:
        if char in '"\\':
            out.append("\\" + char)
        elif ord(char) < 0x20 or ord(char) == 0x7F:
            out.append(f"\\u{ord(char):04X}")
        else:
            out.append(char)
    return '"' + "".join(out) + '"'
