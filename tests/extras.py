"""The one rule for tests of an optional extra: they fail, not skip, when ``CI=true``.

CI installs every extra (`make test`), so a missing one there is a broken set-up, not a
reason to skip; elsewhere a developer without the extra sees the tests skipped.
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType

import pytest


def require_extra(module: str) -> ModuleType:
    """Import ``module`` of an optional extra for a test module or a test.

    Parameters
    ----------
    module : str
        The module's import name, e.g. ``"highway_env"`` (the ``vehicle`` extra).

    Returns
    -------
    ModuleType
        The imported module.

    Raises
    ------
    ModuleNotFoundError
        If it is missing and ``CI=true``.
    pytest.skip.Exception
        If it is missing elsewhere (the test, or the whole module at import, is skipped).
    """
    if os.environ.get("CI") == "true":
        return importlib.import_module(module)
    return pytest.importorskip(module)
