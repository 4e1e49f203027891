"""Every public name has a numpydoc docstring (the check python-control runs on its API).

Public names are those in a subpackage's ``__all__``, and the public methods and
properties of the public classes. Each has a docstring with a one-line summary; every
parameter of a public function, method or constructor is documented in its
``Parameters`` section (numpydoc: ``name : type``, several names may share a line, a
constructor's parameters are documented in the class docstring, a dataclass's fields may
be documented under ``Attributes``).
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil
import re

import pytest

SUBPACKAGES = [
    "minimaxplan.models",
    "minimaxplan.kernels",
    "minimaxplan.verify",
    "minimaxplan.planners",
    "minimaxplan.scenarios",
    "minimaxplan.analysis",
]
SECTION_UNDERLINE = re.compile(r"^-{3,}$")
ENTRY = re.compile(r"^\*{0,2}([A-Za-z_][A-Za-z0-9_]*(?:\s*,\s*\*{0,2}[A-Za-z_][A-Za-z0-9_]*)*)\s*(?::.*)?$")


def _optional_exports(module) -> list[str]:
    # Names behind a lazy __getattr__ need their optional extra: check them where it is installed.
    names = []
    for name in module.__all__:
        try:
            getattr(module, name)
        except ImportError:
            continue
        names.append(name)
    return names


def _public_modules(package: str):
    # The subpackage and every public module in it: a module's __all__ is public API too,
    # whether or not the subpackage re-exports it.
    root = importlib.import_module(package)
    yield root
    for info in pkgutil.iter_modules(root.__path__, package + "."):
        if info.name.rsplit(".", 1)[1].startswith("_"):
            continue
        try:
            yield importlib.import_module(info.name)
        except ImportError:  # a module that needs an optional extra not installed here
            continue


def _public_objects(package: str):
    for module in _public_modules(package):
        assert hasattr(module, "__all__"), f"{module.__name__} defines no __all__"
        for name in _optional_exports(module):
            obj = getattr(module, name)
            home = getattr(obj, "__module__", module.__name__)
            if home != module.__name__ and module.__name__ != package:
                continue  # re-exported from where it is defined: checked there
            yield f"{module.__name__}.{name}", obj


def _sections(doc: str) -> dict[str, list[str]]:
    lines = doc.splitlines()
    sections: dict[str, list[str]] = {}
    current = None
    for i, line in enumerate(lines):
        if i + 1 < len(lines) and SECTION_UNDERLINE.match(lines[i + 1].strip()) and line.strip():
            current = line.strip()
            sections[current] = []
            continue
        if current is not None and not SECTION_UNDERLINE.match(line.strip()):
            sections[current].append(line)
    return sections


def documented_parameters(doc: str) -> set[str]:
    """The names a numpydoc ``Parameters`` (or ``Attributes``) section documents."""
    names: set[str] = set()
    sections = _sections(doc)
    for title in ("Parameters", "Other Parameters", "Attributes"):
        for line in sections.get(title, []):
            if not line or line[0].isspace():
                continue
            match = ENTRY.match(line.strip())
            if match:
                names.update(n.strip().lstrip("*") for n in match.group(1).split(","))
    return names


def _signature_parameters(func, *, skip_first: bool) -> list[str]:
    try:
        signature = inspect.signature(func)
    except (TypeError, ValueError):
        return []
    params = list(signature.parameters.values())
    if skip_first and params:
        params = params[1:]
    return [p.name for p in params if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]


def _problems(qualname: str, obj) -> list[str]:
    problems = []
    doc = inspect.getdoc(obj)
    if not doc or not doc.strip().splitlines()[0].strip():
        return [f"{qualname}: no docstring"]
    if inspect.isfunction(obj):
        missing = set(_signature_parameters(obj, skip_first=False)) - documented_parameters(doc)
        if missing:
            problems.append(f"{qualname}: parameters not documented: {sorted(missing)}")
    elif inspect.isclass(obj) and not issubclass(obj, BaseException):
        problems.extend(_class_problems(qualname, obj, doc))
    return problems


def _own_members(cls):
    for klass in cls.__mro__:
        if klass is object or not klass.__module__.startswith("minimaxplan"):
            continue
        for name, member in vars(klass).items():
            if not name.startswith("_"):
                yield name, member


def _class_problems(qualname: str, cls, doc: str) -> list[str]:
    problems = []
    init = cls.__dict__.get("__init__")
    if init is not None or dataclasses.is_dataclass(cls):
        constructor = init if init is not None else cls.__init__
        init_doc = inspect.getdoc(init) if init is not None else None
        documented = documented_parameters(doc) | (documented_parameters(init_doc) if init_doc else set())
        missing = set(_signature_parameters(constructor, skip_first=True)) - documented
        if missing:
            problems.append(f"{qualname}: constructor parameters not documented: {sorted(missing)}")
    seen = set()
    for name, member in _own_members(cls):
        if name in seen:
            continue
        seen.add(name)
        target = member.fget if isinstance(member, property) else member
        if isinstance(member, (staticmethod, classmethod)):
            target = member.__func__
        if not callable(target) and not isinstance(member, property):
            continue
        member_doc = inspect.getdoc(target)
        if not member_doc:
            problems.append(f"{qualname}.{name}: no docstring")
            continue
        if isinstance(member, property) or not inspect.isfunction(target):
            continue
        skip_first = not isinstance(member, staticmethod)
        missing = set(_signature_parameters(target, skip_first=skip_first)) - documented_parameters(member_doc)
        if missing:
            problems.append(f"{qualname}.{name}: parameters not documented: {sorted(missing)}")
    return problems


def test_documented_parameters_reads_numpydoc_sections():
    doc = """Summary.

    Parameters
    ----------
    a, b : float
        Two.
    c
        Three.

    Returns
    -------
    d : float
    """
    assert documented_parameters(inspect.cleandoc(doc)) == {"a", "b", "c"}


def test_the_check_catches_an_undocumented_parameter():
    def documented(x, y):
        """Summary.

        Parameters
        ----------
        x : float
        """

    assert _problems("documented", documented) == ["documented: parameters not documented: ['y']"]
    assert _problems("nodoc", lambda: None) == ["nodoc: no docstring"]


@pytest.mark.parametrize("package", SUBPACKAGES)
def test_every_public_name_has_a_numpydoc_docstring(package):
    problems = []
    for qualname, obj in _public_objects(package):
        problems.extend(_problems(qualname, obj))
    assert not problems, f"{len(problems)} problems:\n" + "\n".join(problems)
