"""`extras.require_extra`: the tests of an optional extra fail, not skip, when CI=true."""

import json

import pytest
from extras import require_extra

MISSING = "minimaxplan_test_no_such_extra"


def test_a_missing_extra_fails_when_ci_is_true(monkeypatch):
    monkeypatch.setenv("CI", "true")
    with pytest.raises(ModuleNotFoundError, match=MISSING):
        require_extra(MISSING)


@pytest.mark.parametrize("ci", [None, "false", "1"])
def test_a_missing_extra_skips_elsewhere(monkeypatch, ci):
    if ci is None:
        monkeypatch.delenv("CI", raising=False)
    else:
        monkeypatch.setenv("CI", ci)
    with pytest.raises(pytest.skip.Exception):
        require_extra(MISSING)


@pytest.mark.parametrize("ci", [None, "true"])
def test_an_installed_module_is_returned(monkeypatch, ci):
    if ci is None:
        monkeypatch.delenv("CI", raising=False)
    else:
        monkeypatch.setenv("CI", ci)
    assert require_extra("json") is json
