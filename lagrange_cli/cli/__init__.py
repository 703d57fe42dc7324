"""The command line: parse options, call one library function, render the result.

Only this package imports typer and rich; library modules are imported inside each command
so that `lagrange --help` stays fast (no sympy, numpy or scipy).
"""

from __future__ import annotations

import sys
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

import typer

from lagrange_cli.cli._app import Group, Typer, print_version

if TYPE_CHECKING:
    from lagrange_cli.errors import LagrangeError

app = Typer(
    cls=Group,
    help="Equations of motion from a small YAML description of a mechanical system.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"]},
)


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=print_version, is_eager=True, help="Print the version and exit.")) -> None:
    """Equations of motion from a small YAML description of a mechanical system."""


class Form(str, Enum):
    lagrange = "lagrange"
    matrix = "matrix"
    solved = "solved"


def fail_with(error: LagrangeError) -> NoReturn:
    from rich.console import Console

    Console(stderr=True, highlight=False, soft_wrap=True).print(str(error), markup=False)
    raise typer.Exit(error.exit_code)


def check_outputs(*paths: Path | None) -> None:
    """Exit 2 with a clear message unless every output path given (not None, not - for stdout)
    can be written; commands call it before doing any work."""
    from lagrange_cli.errors import LagrangeError
    from lagrange_cli.files import check_writable

    for path in paths:
        if path is not None and str(path) != "-":
            try:
                check_writable(path)
            except LagrangeError as error:
                fail_with(error)


def write_atomically(path: Path, text: str) -> None:
    """Write `text` to `path` so that readers see the old file or the whole new one, never half."""
    from lagrange_cli.files import write_text

    write_text(path, text)


def output(text: str, path: Path | None) -> None:
    if path is None:
        sys.stdout.write(text)
    else:
        write_atomically(path, text)


def main() -> None:
    from lagrange_cli.errors import LagrangeError

    try:
        app()
    except LagrangeError as error:  # one a command did not catch itself (an output that failed late)
        sys.stderr.write(f"{error}\n")
        sys.exit(error.exit_code)


# Each module registers its commands on `app`; they import only typer at module level.
from lagrange_cli.cli import analysis as _analysis  # noqa: E402, F401
from lagrange_cli.cli import derive as _derive  # noqa: E402, F401
from lagrange_cli.cli import numeric as _numeric  # noqa: E402, F401
from lagrange_cli.cli import study as _study  # noqa: E402, F401
