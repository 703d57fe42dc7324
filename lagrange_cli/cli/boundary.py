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
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

import typer

if TYPE_CHECKING:
    from rich.console import Console

    from lagrange_cli.errors import Span

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
check_stages = _checker("a whole number from 1 to 3 (Gauss-Legendre stages: order 2, 4 or 6)", lambda x: x in (1, 2, 3))
MAX_RUNS = 100_000_000  # sweep --sample: far more runs than a sweep can finish, and a bounded table
check_runs = _checker(f"a whole number from 1 to {MAX_RUNS}", lambda x: 1 <= x <= MAX_RUNS)
check_seed = _checker("a whole number from 0 to 2**32 - 1", lambda x: 0 <= x <= 2**32 - 1)
check_workers = _checker("a whole number from 1 to 256", lambda x: 1 <= x <= 256)
check_batch = _checker("a whole number from 1 to 1000000", lambda x: 1 <= x <= 1_000_000)
check_steps = _checker("a whole number from 1 to 1000000000", lambda x: 1 <= x <= 1e9)


# --- NAME=VALUE options --------------------------------------------------------------------------

_NAME = re.compile(r"\s*([A-Za-z_][A-Za-z0-9_]*)\s*=")
_OPEN, _CLOSE = "([{", ")]}"


@dataclass(frozen=True)
class Item:
    """One `name=value` of an option such as `--set`: the name, the value's text, and where the
    value starts in the option's argument (`text`), so that a mistake in it gets a caret."""

    option: str
    text: str
    name: str
    value: str
    start: int  # 0-based column of the name in `text`
    value_start: int  # 0-based column of the value in `text`

    def span(self, offset: int = 0) -> Span:
        """The place `offset` characters into the value."""
        from lagrange_cli.errors import Span

        return Span(self.option, 1, self.value_start + offset + 1, self.text)


def _pieces(text: str) -> list[tuple[int, str]]:
    """`text` split at the commas outside parentheses, brackets and braces, each piece with its
    0-based start: `theta=atan2(1,2),phi=0` is two pieces."""
    pieces, depth, start = [], 0, 0
    for at, char in enumerate(text):
        if char in _OPEN:
            depth += 1
        elif char in _CLOSE:
            depth = max(depth - 1, 0)
        elif char == "," and depth == 0:
            pieces.append((start, text[start:at]))
            start = at + 1
    pieces.append((start, text[start:]))
    return pieces


def assignments(option: str, entries: list[str] | None, example: str, lists: bool = False) -> list[Item]:
    """The `name=value` items of a repeatable option (`--set k=1 --set m=2`), each argument also a
    comma list (`--set k=1,m=2`); a comma inside parentheses belongs to the value
    (`--about theta=atan2(1,2)`). With `lists`, a piece that is not `name=...` continues the value
    before it (`--scale k=1,10,100,m=2..3`). A piece that is not `name=value`, an empty one, or a
    name given twice is a `SpecError` naming the option, the item, with a caret under it (exit 2)."""
    from lagrange_cli.errors import Span, fail

    items: list[Item] = []
    usage = f"name=value items, repeated or separated by commas, e.g. {option} {example}"
    for text in entries or []:
        if not text.strip():
            continue
        first = len(items)  # the items of this argument
        for start, piece in _pieces(text):
            found = _NAME.match(piece)
            if found is None and lists and len(items) > first and piece.strip():
                last = items[-1]
                items[-1] = Item(option, text, last.name, text[last.value_start : start + len(piece)], last.start, last.value_start)
                continue
            column = start + len(piece) - len(piece.lstrip()) + 1
            if not piece.strip():
                raise fail(Span(option, 1, min(column, len(text)) or 1, text), f"an empty item in {option}", usage)
            if found is None or not piece[found.end() :].strip():
                raise fail(Span(option, 1, column, text), f"'{piece.strip()}' is not an assignment: expected name=value", usage)
            name = found.group(1)
            twice = next((item for item in items if item.name == name), None)
            if twice is not None:
                raise fail(Span(option, 1, column, text), f"'{name}' is given twice in {option} (also as '{twice.name}={twice.value.strip()}')", "each name once")
            items.append(Item(option, text, name, piece[found.end() :], start + found.start(1), start + found.end()))
    return items


def check_names(items: list[Item], names: list[str], kind: str, source: str) -> None:
    """Each item names one of `names` (a `kind` of the system in `source`), or a `SpecError` with
    a caret under the name and a "did you mean"."""
    import difflib

    from lagrange_cli.errors import Span, fail

    for item in items:
        if item.name not in names:
            close = difflib.get_close_matches(item.name, names, n=1, cutoff=0.6)
            choices = f"one of {', '.join(names)}" if names else f"nothing: the system has no {kind}s"
            raise fail(Span(item.option, 1, item.start + 1, item.text), f"'{item.name}' is not a {kind} of {source}", choices + (f" (did you mean '{close[0]}'?)" if close else ""))


def constant(item: Item, what: str, text: str | None = None, offset: int = 0) -> tuple[Any, float]:
    """A constant value (`0`, `pi/2`, `-1.5`, `atan2(1, 2)`) parsed safely, as (sympy number,
    float); `text` (default: the whole value) starts `offset` characters into the value. A value
    that is not a finite real number is a `SpecError` with a caret in the option's argument."""
    import sympy as sp

    from lagrange_cli.errors import fail
    from lagrange_cli.expr import Scope, numeric_value, parse_expression

    text = item.value if text is None else text
    span = item.span(offset)
    value = parse_expression(text, span, Scope({}, {}, sp.Symbol("t"), lambda e: e, what="numbers, pi, E and functions of them"))
    expected = "a number such as 0, pi/2 or -1.5"
    if not value.is_number:
        raise fail(span, f"{what} must be a number, got '{text.strip()}'", expected)
    try:
        number = numeric_value(value)
    except (ValueError, OverflowError, TypeError):
        number = math.nan
    if not math.isfinite(number):
        raise fail(span, f"{what} must be a finite real number, got '{text.strip()}'", expected)
    return value, number


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
