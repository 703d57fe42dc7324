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
    """Print `error` on stderr (control characters from file text shown as escapes) and exit with its code."""
    from lagrange_cli.cli.boundary import console, message

    console(stderr=True).print(message(error), markup=False)
    raise typer.Exit(error.exit_code)


def check_outputs(*paths: Path | None, reading: str | Path | list[Path] | None = None, options: tuple[str, ...] = ()) -> None:
    """Exit 2 with a clear message unless every output path given (not None, not - for stdout)
    can be written, none is the input (`reading`: a file argument, possibly a bundled name, or a
    list of files) and no two are the same file; commands call it before doing any work.
    `options` names the outputs in messages (default: -o)."""
    from lagrange_cli.errors import LagrangeError
    from lagrange_cli.files import check_outputs as check

    named = [(option, path) for option, path in zip(options or ("-o",) * len(paths), paths, strict=True) if path is not None and str(path) != "-"]
    try:
        check(named, _inputs(reading) if named else [])
    except LagrangeError as error:
        fail_with(error)


def _inputs(reading: str | Path | list[Path] | None) -> list[Path]:
    """The files a command will read: a file argument as `spec.resolve` finds it (nothing when it
    cannot: the command then reports that itself)."""
    if reading is None:
        return []
    if isinstance(reading, list):
        return reading
    from lagrange_cli.errors import LagrangeError
    from lagrange_cli.spec import resolve

    try:
        return [resolve(str(reading))]
    except LagrangeError:
        return []


def write_atomically(path: Path, text: str) -> None:
    """Write `text` to `path` (- is stdout) so that readers see the old file or the whole new one,
    never half; control characters from file text are written as visible escapes."""
    from lagrange_cli.errors import printable
    from lagrange_cli.files import write_text

    if str(path) == "-":
        sys.stdout.write(printable(text))
    else:
        write_text(path, printable(text))


def output(text: str, path: Path | None) -> None:
    """`text` to stdout (no path, or -) or atomically to the file `path`."""
    write_atomically(path if path is not None else Path("-"), text)


def main() -> None:
    from lagrange_cli.errors import LagrangeError

    try:
        app()
    except LagrangeError as error:  # one a command did not catch itself (an output that failed late)
        from lagrange_cli.cli.boundary import message

        sys.stderr.write(f"{message(error)}\n")
        sys.exit(error.exit_code)
    except Exception as error:  # outside every command (each one has its own net)
        _last_resort(error)


def _last_resort(error: Exception) -> None:
    """An exception outside the commands' nets: one line and exit 2 (LAGRANGE_DEBUG=1: re-raise)."""
    import os

    from lagrange_cli.cli.boundary import DEBUG_VARIABLE, internal_error

    if isinstance(error, BrokenPipeError) or os.environ.get(DEBUG_VARIABLE) == "1":
        raise error
    sys.stderr.write(internal_error(" ".join(sys.argv[1:]) or "the command line", error) + "\n")
    sys.exit(2)


# Each module registers its commands on `app`; they import only typer at module level.
from lagrange_cli.cli import analysis as _analysis  # noqa: E402, F401
from lagrange_cli.cli import animate as _animate  # noqa: E402, F401
from lagrange_cli.cli import derive as _derive  # noqa: E402, F401
from lagrange_cli.cli import numeric as _numeric  # noqa: E402, F401
from lagrange_cli.cli import study as _study  # noqa: E402, F401
from lagrange_cli.cli import sweep as _sweep  # noqa: E402, F401
from lagrange_cli.cli.boundary import install_safety_net  # noqa: E402

install_safety_net(app)
