"""Argument parsing for the ``minimaxplan`` console script (standard library only).

Every option of every subcommand is checked while the command line is parsed, before
any work starts, so that a bad value costs no episode: each type below raises
`argparse.ArgumentTypeError`, which `CommandParser` turns into one line on stderr
naming the option, and exit status 2. Nothing here imports numpy, scipy, cvxpy or
numba: ``minimaxplan --help`` stays fast, and the subcommands import the library where
they use it.
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import NoReturn

__all__ = [
    "CommandParser",
    "DefaultsHelpFormatter",
    "Subcommand",
    "EXIT_USAGE",
    "count",
    "count_list",
    "number_list",
    "distinct",
    "name_list",
    "add_run_options",
    "output_directory",
    "output_file",
    "report_error",
    "one_line",
]

#: Exit status of a usage error (a bad option or value), as argparse's own.
EXIT_USAGE = 2


class DefaultsHelpFormatter(argparse.HelpFormatter):
    """A help formatter that appends ``(default: VALUE)`` to an option's help.

    Unlike `argparse.ArgumentDefaultsHelpFormatter`, it leaves alone an option whose
    help already says what its default is, and one without a default (``None``,
    ``False``).
    """

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if "default" in text or default is None or default is False or default == argparse.SUPPRESS:
            return text
        if not action.option_strings:
            return text
        return f"{text} (default: %(default)s)"


class CommandParser(argparse.ArgumentParser):
    """An `argparse.ArgumentParser` that reports a usage error on one line.

    The line reads ``PROG: error: MESSAGE (see 'PROG --help')``, where ``PROG`` is the
    parser of the subcommand at fault (``minimaxplan experiment``), and the exit status
    is `EXIT_USAGE`. Every subparser of a `CommandParser` is one too, and shows the
    defaults of its options in its ``--help``.

    Parameters
    ----------
    *args, **kwargs
        As for `argparse.ArgumentParser`; ``formatter_class`` defaults to
        `DefaultsHelpFormatter`.
    """

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", DefaultsHelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        """Print ``message`` on one line of stderr and exit with status 2.

        Parameters
        ----------
        message : str
            What is wrong, naming the option (argparse prefixes ``argument --name:``).
            A character that is not printable (a newline in a stray argument) is shown
            escaped, so that the message stays on one line.
        """
        self.exit(EXIT_USAGE, f"{self.prog}: error: {one_line(message)} (see '{self.prog} --help')\n")


@dataclass(frozen=True)
class Subcommand:
    """One subcommand of the ``minimaxplan`` console script: its parser's texts, options and job.

    Each subcommand module of `minimaxplan.analysis` defines one, ``COMMAND``, which
    `minimaxplan.analysis.cli.build_parser` adds to the command line.

    Attributes
    ----------
    name : str
        The subcommand's name (``minimaxplan NAME``).
    help : str
        Its one-line summary in ``minimaxplan --help``.
    description : str
        The paragraph of its own ``--help``.
    epilog : str
        The last paragraph of its ``--help`` (its exit codes).
    add_options : callable
        ``add_options(parser)`` adds the subcommand's arguments to its parser.
    run : callable
        ``run(args)``: the job, given the parsed namespace; returns the exit status.
    """

    name: str
    help: str
    description: str
    epilog: str
    add_options: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]

    def add_to(self, subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
        """Add this subcommand's parser to ``subparsers``, with ``func`` set to `run`.

        Parameters
        ----------
        subparsers : argparse._SubParsersAction
            The subcommands of the ``minimaxplan`` parser (`minimaxplan.analysis.cli`).

        Returns
        -------
        argparse.ArgumentParser
            The subcommand's parser.
        """
        parser = subparsers.add_parser(self.name, help=self.help, description=self.description, epilog=self.epilog)
        self.add_options(parser)
        parser.set_defaults(func=self.run)
        return parser


def one_line(text: str) -> str:
    """``text`` with every non-printable character escaped (``"\\n"`` for a newline).

    Parameters
    ----------
    text : str
        A message that may quote user input.

    Returns
    -------
    str
        The same text on one line: printable characters are kept, the others are
        replaced by their Python escape (as in `repr`).
    """
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def count(minimum: int = 1) -> Callable[[str], int]:
    """An argparse type: an integer >= ``minimum``.

    Parameters
    ----------
    minimum : int
        The smallest accepted value.

    Returns
    -------
    callable
        ``str -> int``, raising `argparse.ArgumentTypeError` for text that is not an
        integer or is below ``minimum``.
    """

    def parse(text: str) -> int:
        value = _integer(text)
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {text!r}")
        return value

    parse.__name__ = f"integer >= {minimum}"
    return parse


def count_list(minimum: int = 1) -> Callable[[str], list[int]]:
    """An argparse type: a comma-separated, non-empty list of integers >= ``minimum``.

    Parameters
    ----------
    minimum : int
        The smallest accepted value of every item.

    Returns
    -------
    callable
        ``str -> list[int]``, raising `argparse.ArgumentTypeError` naming the first bad
        item.
    """

    def parse(text: str) -> list[int]:
        items = [item.strip() for item in text.split(",")]
        if not any(items):
            raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}")
        values = []
        for item in items:
            try:
                value = int(item)
            except ValueError:
                raise argparse.ArgumentTypeError(
                    f"expected comma-separated integers, got {item!r} in {text!r}"
                ) from None
            if value < minimum:
                raise argparse.ArgumentTypeError(
                    f"every value must be an integer >= {minimum}, got {item!r} in {text!r}"
                )
            values.append(value)
        return values

    parse.__name__ = "comma-separated integers"
    return parse


def number_list(
    minimum: float = 0.0, *, strict: bool = False, maximum: float | None = None, unit: str = ""
) -> Callable[[str], list[float]]:
    """An argparse type: a comma-separated, non-empty list of finite numbers in a range.

    Parameters
    ----------
    minimum : float
        The smallest accepted value (excluded if ``strict``).
    strict : bool
        Refuse ``minimum`` itself.
    maximum : float, optional
        The largest accepted value (included).
    unit : str
        The values' unit, named in the messages (e.g. ``"m/s"``).

    Returns
    -------
    callable
        ``str -> list[float]``, raising `argparse.ArgumentTypeError` naming the first bad
        item.
    """
    relation = f"{'>' if strict else '>='} {minimum:g}" + ("" if maximum is None else f" and <= {maximum:g}")
    suffix = f" ({unit})" if unit else ""

    def parse(text: str) -> list[float]:
        values = [_number(item, text) for item in _items(text, f"numbers {relation}{suffix}")]
        for item, value in zip(text.split(","), values):
            below = value <= minimum if strict else value < minimum
            if not math.isfinite(value) or below or (maximum is not None and value > maximum):
                raise argparse.ArgumentTypeError(
                    f"every value must be a finite number {relation}{suffix}, got {item.strip()!r}"
                )
        return values

    parse.__name__ = "comma-separated numbers"
    return parse


def _items(text: str, what: str) -> list[str]:
    """The comma-separated items of ``text``, stripped; an error naming ``what`` if there are none."""
    items = [item.strip() for item in text.split(",")]
    if any(items):
        return items
    raise argparse.ArgumentTypeError(f"expected comma-separated {what}, got {text!r}")


def _number(item: str, text: str) -> float:
    try:
        return float(item)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {item!r} in {text!r}") from None


def distinct(parse: Callable[[str], list]) -> Callable[[str], list]:
    """An argparse type: the list type ``parse``, whose values must not repeat.

    Parameters
    ----------
    parse : callable
        A list type (`count_list`, `number_list`, `name_list`).

    Returns
    -------
    callable
        ``str -> list``, raising `argparse.ArgumentTypeError` (``values must not
        repeat``) for a repeated value.
    """

    def checked(text: str) -> list:
        values = parse(text)
        if len(set(values)) != len(values):
            raise argparse.ArgumentTypeError(f"values must not repeat, got {text!r}")
        return values

    checked.__name__ = getattr(parse, "__name__", "list")
    return checked


def add_run_options(
    parser: argparse.ArgumentParser,
    *,
    episodes: int,
    episodes_help: str,
    seed_help: str = "world seed of the first episode (>= 0)",
) -> None:
    """Add the options of a command that runs seeded episodes in local processes.

    ``--episodes`` (an integer >= 1), ``--seed`` (>= 0), ``--workers`` (>= 1; default
    all cores) and ``--no-progress``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    episodes : int
        The default of ``--episodes``.
    episodes_help : str
        Its help (what one episode count counts).
    seed_help : str
        The help of ``--seed``.
    """
    parser.add_argument("--episodes", type=count(1), default=episodes, help=episodes_help)
    parser.add_argument("--seed", type=count(0), default=0, help=seed_help)
    parser.add_argument("--workers", type=count(1), default=None, help="local processes (>= 1; default: all cores)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def name_list(text: str) -> list[str]:
    """An argparse type: a comma-separated, non-empty list of names.

    Parameters
    ----------
    text : str
        The option's value, e.g. ``"robust,nominal"``.

    Returns
    -------
    list of str
        The names, stripped of surrounding blanks; empty items are dropped.

    Raises
    ------
    argparse.ArgumentTypeError
        If no name is given.
    """
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items:
        raise argparse.ArgumentTypeError(f"expected comma-separated names, got {text!r}")
    return items


def output_directory(text: str) -> pathlib.Path:
    """An argparse type: a directory that exists or can be created, and is writable.

    Nothing is created here: the check only looks at the nearest existing ancestor, so
    that a run whose outputs cannot be written fails before its first episode.

    Parameters
    ----------
    text : str
        The option's value, a path.

    Returns
    -------
    pathlib.Path
        The path as given.

    Raises
    ------
    argparse.ArgumentTypeError
        If the path or one of its ancestors is an existing non-directory, or the
        nearest existing ancestor is not writable.
    """
    path = pathlib.Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"'{path}' exists and is not a directory")
    ancestor = path.absolute()
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise argparse.ArgumentTypeError(f"cannot create '{path}': '{ancestor}' is not a directory")
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"cannot write to '{ancestor}' (permission denied)")
    return path


def output_file(text: str) -> pathlib.Path:
    """An argparse type: a file that can be written (its directory exists and is writable).

    Parameters
    ----------
    text : str
        The option's value, a path.

    Returns
    -------
    pathlib.Path
        The path as given.

    Raises
    ------
    argparse.ArgumentTypeError
        If the path is a directory, its parent directory does not exist, or the file
        (if it exists) or its directory is not writable.
    """
    path = pathlib.Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"'{path}' is a directory, not a file")
    parent = path.absolute().parent
    if not parent.is_dir():
        raise argparse.ArgumentTypeError(f"cannot write '{path}': directory '{parent}' does not exist")
    if path.exists() and not os.access(path, os.W_OK):
        raise argparse.ArgumentTypeError(f"cannot write '{path}' (permission denied)")
    if not path.exists() and not os.access(parent, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"cannot write to '{parent}' (permission denied)")
    return path


def report_error(command: str, exc: BaseException, *, option: str | None = None) -> int:
    """Print ``minimaxplan COMMAND: error: ...`` on one line of stderr; return `EXIT_USAGE`.

    Parameters
    ----------
    command : str
        The subcommand's name.
    exc : BaseException
        The error; its message is printed with line breaks folded to spaces.
    option : str, optional
        The option at fault (e.g. ``"--methods"``): the message is then prefixed
        ``argument OPTION:``, as argparse's own errors are.

    Returns
    -------
    int
        `EXIT_USAGE` (2).
    """
    message = " ".join(str(exc).split())
    if option is not None:
        message = f"argument {option}: {message}"
    print(f"minimaxplan {command}: error: {message}", file=sys.stderr)
    return EXIT_USAGE
