"""Sphinx configuration of minimaxplan's documentation (`make docs`).

The API reference is generated here, at every build, from the package itself: one page per
subpackage (its docstring and every name of its ``__all__``, documented under the path users
import it from, e.g. ``minimaxplan.models.Box``) and one page per public module (its
docstring, and the documented names it defines that its subpackage does not export). A
module added to the package therefore gets its page without editing this file. The
notebooks are copied in and rendered with the outputs stored in them; nothing is executed.
"""

from __future__ import annotations

import importlib
import inspect
import pathlib
import pkgutil
import shutil
import sys

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the package's own dependency
    import tomli as tomllib

import minimaxplan

DOCS = pathlib.Path(__file__).resolve().parent
ROOT = DOCS.parent
#: The installed subpackages, as pyproject.toml lists them (a new one gets its pages too).
SUBPACKAGES = [
    name.split(".", 1)[1]
    for name in tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]["packages"]
    if name.startswith("minimaxplan.")
]

project = "minimaxplan"
author = "the minimaxplan authors"
copyright = "the minimaxplan authors, MIT licence"
release = version = minimaxplan.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_nb",  # Markdown pages (it includes myst-parser) and the notebooks
]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "**.ipynb_checkpoints"]
root_doc = "index"
default_role = "py:obj"  # `name` in a docstring: a link where it resolves, code otherwise
html_theme = "alabaster"
html_title = f"minimaxplan {release}"
html_theme_options = {"description": "Robust motion planning under model uncertainty", "page_width": "1100px"}

# Notebooks: render what is stored in them, never execute at build time.
nb_execution_mode = "off"
nb_render_markdown_format = "myst"  # Markdown outputs (the reports) with their tables
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3

# numpydoc renders the docstrings; class members are documented by autodoc itself.
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"  # the signatures and numpydoc's "Parameters" carry the types
autodoc_preserve_defaults = True
autosummary_generate = False


def _exported(package) -> list[str]:
    names = []
    for name in package.__all__:
        try:
            getattr(package, name)
        except ImportError:  # a name behind an optional extra that is not installed
            continue
        names.append(name)
    return names


def _directive(obj) -> str:
    if inspect.isclass(obj):
        return "autoclass"
    if callable(obj):
        return "autofunction"
    return "autodata"


def _public_modules(package) -> list[str]:
    return sorted(
        info.name
        for info in pkgutil.iter_modules(package.__path__, prefix=package.__name__ + ".")
        if not info.name.rsplit(".", 1)[1].startswith("_")
    )


def _title(text: str) -> str:
    return f"{text}\n{'=' * len(text)}\n"


def _write_api_pages() -> None:
    api = DOCS / "api"
    if api.exists():
        shutil.rmtree(api)
    api.mkdir()
    index = [
        _title("API reference"),
        ".. automodule:: minimaxplan",
        "   :no-members:",
        "",
        ".. toctree::",
        "   :maxdepth: 1",
        "",
    ]
    for sub in SUBPACKAGES:
        name = f"minimaxplan.{sub}"
        package = importlib.import_module(name)
        exported = _exported(package)
        modules = _public_modules(package)
        index.append(f"   {name}")
        page = [_title(f"``{name}``"), f".. automodule:: {name}", "   :no-members:", ""]
        page += [".. rubric:: Exported names", "", f".. currentmodule:: {name}", "", ".. autosummary::", ""]
        page += [f"   {n}" for n in exported] + [""]
        page += [".. rubric:: Modules", "", ".. toctree::", "   :maxdepth: 1", ""]
        page += [f"   {m}" for m in modules] + [""]
        for n in exported:
            obj = getattr(package, n)
            page += [f".. {_directive(obj)}:: {name}.{n}"]
            if inspect.isclass(obj):
                page += ["   :members:", "   :show-inheritance:"]
            page += [""]
        (api / f"{name}.rst").write_text("\n".join(page))
        for module_name in modules:
            defined_and_exported = [
                n for n in exported if getattr(getattr(package, n), "__module__", None) == module_name
            ]
            text = [_title(f"``{module_name}``"), f".. automodule:: {module_name}", "   :members:"]
            if exported:
                text.append(f"   :exclude-members: {', '.join(exported)}")
            text.append("")
            if defined_and_exported:
                links = ", ".join(f":obj:`~{name}.{n}`" for n in defined_and_exported)
                text += [f"Defined here and exported by :mod:`{name}`: {links}.", ""]
            (api / f"{module_name}.rst").write_text("\n".join(text))
    (api / "index.rst").write_text("\n".join(index) + "\n")


def _copy_notebooks() -> None:
    target = DOCS / "notebooks"
    if target.exists():
        shutil.rmtree(target)
    target.mkdir()
    for notebook in sorted((ROOT / "notebooks").glob("*.ipynb")):
        shutil.copy2(notebook, target / notebook.name)


_write_api_pages()
_copy_notebooks()
