"""What the command line lets in and out: numeric option values checked where they are parsed,
file text made inert before a terminal or rich sees it, and a last-resort net that turns an
unexpected exception into one line instead of a traceback.

Imports only typer at module level (rich and the library lazily), like the rest of `cli`.
"""

from __future__ import annotations

import functools
import math
import os
import re
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

import typer

if TYPE_CHECKING:
    from rich.console import Console

INTERNAL_ERROR = "internal error"  # in the one line the safety net prints; tests assert it never appears
DEBUG_VARIABLE = "LAGRANGE_DEBUG"  # =1: let an unexpected exception through with its traceback
MAX_SAMPLES = 1_000_000  # --samples: more output times than anyone plots, and a bounded memory

# --- option values -------------------------------------------------------------------------------


def _checker(kind: str, test: Callable[[float], bool]) -> Callable[[Any], Any]:
    """A typer callback that passes None and values for which `test` holds, and otherwise stops
    with `Invalid value for '--option': must be <kind>, got <value>` (exit 2)."""

    def check(value: Any) -> Any:
        if value is None:
            return None
        try:
            number = float(value)
        except OverflowError:  # an int of hundreds of digits
            number = math.inf
        if not (math.isfinite(number) and test(number)):
            raise typer.BadParameter(f"must be {kind}, got {value!r}")
        return value

    check.__doc__ = f"Allowed: {kind}."
    return check


check_positive = _checker("a finite number above 0", lambda x: x > 0)
check_fraction = _checker("a number between 0 and 1 (both excluded)", lambda x: 0 < x < 1)
check_samples = _checker(f"a whole number from 2 to {MAX_SAMPLES}", lambda x: 2 <= x <= MAX_SAMPLES)
check_repeats = _checker("a whole number from 0 to 100", lambda x: 0 <= x <= 100)


# --- file text on the terminal --------------------------------------------------------------------


def inert(text: object) -> str:
    """File text (a title, a name, a path, a note) for a rich string with markup: control
    characters shown as escapes (no line breaks either) and rich markup escaped, so that
    `[bold]`, `[/x]` or `\\x1b[2J` print as themselves."""
    from rich.markup import escape

    from lagrange_cli.errors import printable

    return escape(printable(str(text), keep=""))


def plain(text: object) -> str:
    """A message (several lines allowed) for a print with markup=False: control characters shown
    as escapes."""
    from lagrange_cli.errors import printable

    return printable(str(text))


_LABELLED = re.compile(r"([^\n]*: )?error: ")


def message(error: BaseException) -> str:
    """An error as printed: control characters shown as escapes, and an `error: ` label in front
    unless it already has one (`file:line:col: error: ...`), so that every message looks alike."""
    text = plain(error)
    return text if _LABELLED.match(text) else f"error: {text}"


def console(stderr: bool = False, width: int | None = None) -> Console:
    """A rich console that adds no meaning to text: no highlighting, no `:emoji:` codes."""
    from rich.console import Console

    return Console(stderr=stderr, highlight=False, soft_wrap=True, emoji=False, width=width)


# --- the safety net ------------------------------------------------------------------------------

Command = TypeVar("Command", bound=Callable[..., Any])


def internal_error(where: str, error: BaseException) -> str:
    """The one line a user sees for a bug: what was being done, the exception, and a request."""
    from lagrange_cli.errors import printable

    text = printable(f"{type(error).__name__}: {error}" if str(error) else type(error).__name__, keep="")
    if len(text) > 500:
        text = text[:500] + "..."
    return f"error: {INTERNAL_ERROR} while processing {printable(where, keep='')}: {text} (please report this)"


def guarded(command: Command) -> Command:
    """`command` with a last-resort net: a `LagrangeError` it let through is printed as usual; any
    other exception (a bug, a RecursionError, a MemoryError) becomes one line on stderr and exit 2,
    with no traceback unless LAGRANGE_DEBUG=1. typer's own exits, a broken pipe (handled by
    `main`) and Ctrl-C pass through."""

    @functools.wraps(command)
    def run(*args: Any, **kwargs: Any) -> Any:
        from lagrange_cli.errors import LagrangeError

        try:
            return command(*args, **kwargs)
        except (typer.Exit, typer.Abort, typer.TyperException, BrokenPipeError):
            raise
        except LagrangeError as error:
            from lagrange_cli.cli import fail_with

            fail_with(error)
        except Exception as error:  # the point of the net
            if os.environ.get(DEBUG_VARIABLE) == "1":
                raise
            where = kwargs.get("file") or ", ".join(kwargs.get("paths") or ()) or command.__name__
            sys.stdout.flush()
            console(stderr=True).print(internal_error(str(where), error), markup=False)
            raise typer.Exit(2) from None

    return run  # type: ignore[return-value]


def install_safety_net(app: typer.Typer) -> None:
    """Every command registered on `app` (now and by the modules imported before this call) runs
    inside `guarded`."""
    for info in app.registered_commands:
        if info.callback is not None and not getattr(info.callback, "_guarded", False):
            info.callback = guarded(info.callback)
            info.callback._guarded = True  # type: ignore[attr-defined]
