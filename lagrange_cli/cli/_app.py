"""The typer application object: plain, readable help, `-h`, `--version`, and a quiet exit when
the reader of stdout goes away (`lagrange derive ... | head -1`).

Help is rendered here from the commands' own parameters and annotations, the way `git` and
`pip` print it: `Usage: lagrange derive [OPTIONS] FILE`, then one line per option with a
metavar only where the option takes a value (`--t-end NUMBER`, `--form [lagrange|matrix|solved]`),
and descriptions using the whole width. typer's own rendering varies between its versions
(`<bool>` on flags, `{file}` in usage lines, a six-column table squeezing descriptions); this
one depends only on click's stable formatter API and on the signatures in this package.
"""

from __future__ import annotations

import enum
import inspect
import os
import sys
import types
import typing
from pathlib import Path
from typing import Any

import typer
from typer.core import TyperCommand, TyperGroup

ORDER = ("derive", "check", "info", "equilibria", "linearize", "simulate", "animate", "accuracy", "stress", "sweep")
"""The order of the command list in `lagrange --help`: the pipeline from a file to numbers."""

METAVARS: dict[Any, str] = {float: "NUMBER", int: "INTEGER", Path: "FILE", str: "TEXT"}


def _value_type(command: Any, name: str | None) -> Any:
    """The Python type a parameter takes, from the command function's annotation (without
    Annotated, None and list[...]); None when it cannot be read."""
    try:
        hints = typing.get_type_hints(inspect.unwrap(command.callback))
    except Exception:  # an annotation that does not evaluate: fall back to TEXT
        return None
    annotation = hints.get(name or "")
    while True:
        origin = typing.get_origin(annotation)
        if origin in (typing.Union, types.UnionType):
            annotation = next(a for a in typing.get_args(annotation) if a is not type(None))
        elif origin in (list, tuple):
            annotation = typing.get_args(annotation)[0]
        else:
            return annotation


def _metavar(command: Any, param: Any) -> str:
    if param.metavar:
        return str(param.metavar)
    value_type = _value_type(command, param.name)
    if isinstance(value_type, type) and issubclass(value_type, enum.Enum):
        return "[" + "|".join(str(member.value) for member in value_type) + "]"
    if param.param_type_name == "argument":
        return (param.name or "ARG").upper() + ("..." if param.nargs != 1 else "")
    return METAVARS.get(value_type, "TEXT")


def _default(param: Any) -> str:
    """` [default: x]` for an option whose help does not already say its default."""
    value = getattr(param.default, "value", param.default)
    if value is None or isinstance(value, bool) or value in ("", [], ()) or "default" in (param.help or "") or getattr(param, "show_default", True) is False:
        return ""
    return f"  [default: {value:g}]" if isinstance(value, float) else f"  [default: {value}]"


def _usage(command: Any, ctx: Any, formatter: Any, tail: str = "") -> None:
    pieces = ["[OPTIONS]"]
    for param in command.get_params(ctx):
        if param.param_type_name == "argument":
            metavar = _metavar(command, param)
            pieces.append(metavar if param.required else f"[{metavar}]")
    formatter.write_usage(ctx.command_path, " ".join([*pieces, tail] if tail else pieces))


def _parameters(command: Any, ctx: Any, formatter: Any) -> None:
    arguments, options = [], []
    for param in command.get_params(ctx):
        if getattr(param, "hidden", False):
            continue
        if param.param_type_name == "argument":
            if param.help:
                arguments.append((_metavar(command, param), param.help))
            continue
        names = ", ".join(sorted(param.opts, key=lambda opt: opt.startswith("--")))  # -h, --help
        if param.secondary_opts:
            names += " / " + ", ".join(param.secondary_opts)
        if not getattr(param, "is_flag", False) and not getattr(param, "count", False):
            names += " " + _metavar(command, param)
        options.append((names, (param.help or "") + _default(param)))
    for title, rows in (("Arguments", arguments), ("Options", options)):
        if rows:
            with formatter.section(title):
                formatter.write_dl(rows)


class Command(TyperCommand):
    """A command whose help and usage lines are rendered by this module."""

    def format_usage(self, ctx: Any, formatter: Any) -> None:
        _usage(self, ctx, formatter)

    def format_help(self, ctx: Any, formatter: Any) -> None:
        self.format_usage(ctx, formatter)
        self.format_help_text(ctx, formatter)
        _parameters(self, ctx, formatter)


class Group(TyperGroup):
    """The `lagrange` command: the same help style, commands listed with their whole first
    paragraph, and a broken pipe on stdout ending the run quietly with exit 0."""

    def list_commands(self, ctx: Any) -> list[str]:
        names = list(super().list_commands(ctx))
        return sorted(names, key=lambda name: ORDER.index(name) if name in ORDER else len(ORDER))

    def format_usage(self, ctx: Any, formatter: Any) -> None:
        _usage(self, ctx, formatter, "COMMAND [ARGS]...")

    def format_help(self, ctx: Any, formatter: Any) -> None:
        self.format_usage(ctx, formatter)
        self.format_help_text(ctx, formatter)
        _parameters(self, ctx, formatter)
        rows = []
        for name in self.list_commands(ctx):
            command = self.get_command(ctx, name)
            if command is not None and not command.hidden:
                rows.append((name, inspect.cleandoc(command.help or "").split("\n\n")[0].replace("\n", " ")))
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def make_context(self, *args: Any, **kwargs: Any) -> Any:
        try:  # `lagrange --help | head -1`: help and --version print while the context is made
            return super().make_context(*args, **kwargs)
        except BrokenPipeError:
            _stdout_gone()

    def invoke(self, ctx: Any) -> Any:
        try:
            try:
                return super().invoke(ctx)
            finally:  # what is still buffered goes out now, so that a closed pipe shows here
                if sys.stdout is not None:
                    sys.stdout.flush()
        except BrokenPipeError:
            _stdout_gone()
        except SystemExit as exit:  # rich's Console.on_broken_pipe exits 1 in place of the BrokenPipeError
            if isinstance(exit.__context__, BrokenPipeError) and not isinstance(exit, _Gone):
                _stdout_gone()
            raise


def _stdout_gone(code: int = 0) -> typing.NoReturn:
    """The reader of stdout stopped reading (`| head`): it has what it wanted, so exit `code` (0, or
    a verdict already decided, such as check's) without a message, and send whatever is still
    buffered to /dev/null instead of failing at exit."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # no real file descriptor (a test runner's stream)
        pass
    raise _Gone(code)


class _Gone(SystemExit):
    """The exit of a run whose stdout reader left, with its code already decided."""


def keeping_verdict(code: int, show: typing.Callable[[], object]) -> typing.NoReturn:
    """Run `show` (printing a report whose verdict `code` is decided) and exit `code`, also when the
    reader of stdout stops early: `lagrange check ... | head` must still fail a wrong answer."""
    try:
        show()
        if sys.stdout is not None:
            sys.stdout.flush()
    except BrokenPipeError:
        _stdout_gone(code)
    except SystemExit as exit:  # rich's Console.on_broken_pipe
        if isinstance(exit.__context__, BrokenPipeError) and not isinstance(exit, _Gone):
            _stdout_gone(code)
        raise
    raise SystemExit(code)


class Typer(typer.Typer):
    """typer.Typer whose commands are `Command`s unless a command asks for another class."""

    def command(self, *args: Any, **kwargs: Any) -> Any:
        kwargs.setdefault("cls", Command)
        return super().command(*args, **kwargs)


def print_version(value: bool) -> None:
    if value:
        from lagrange_cli import __version__

        typer.echo(f"lagrange {__version__}")
        raise typer.Exit()
