"""Fixtures shared by the tests of `minimaxplan.analysis`."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from minimaxplan.analysis import cli


@pytest.fixture
def run_cli(capsys) -> Callable[..., tuple[int, str, str]]:
    """``run_cli(*argv)`` runs ``minimaxplan ARGV`` in this process: ``(exit code, stdout, stderr)``.

    The arguments are passed as strings; argparse's exit (``--help``, a usage error) is
    returned as its code.
    """

    def run(*argv) -> tuple[int, str, str]:
        try:
            code = cli.main([str(a) for a in argv])
        except SystemExit as exc:  # argparse: --help and usage errors
            code = exc.code
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    return run
