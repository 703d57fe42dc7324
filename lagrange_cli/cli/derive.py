"""`derive` and `check`: from a system file to its equations, and answers checked against them."""

from __future__ import annotations

import re
from enum import Enum
from pathlib import Path
from typing import Annotated, Any

import typer

from lagrange_cli.cli import app, check_outputs, fail_with, output, write_atomically
from lagrange_cli.cli._app import keeping_verdict

TARGETS = {
    "text": "lagrange_cli.emit.text",
    "latex": "lagrange_cli.emit.latex",
    "python": "lagrange_cli.emit.python",
    "c": "lagrange_cli.emit.c",
    "octave": "lagrange_cli.emit.octave",
    "jax": "lagrange_cli.emit.jax",
    "json": "lagrange_cli.emit.jsonmodel",
}
"""`--to TARGET` -> the module that emits it, imported only when asked for (each has `emit`)."""

SHARED_TARGETS = frozenset({"python", "c", "octave", "jax"})
"""Targets that print the equations with their common subexpressions shared (`derive(shared=True)`): a
system whose equations are too long only when written out in full (a spatial chain) is accepted for them."""


class Form(str, Enum):
    """`derive --form`: the shape of the equations."""

    lagrange = "lagrange"
    matrix = "matrix"
    solved = "solved"
    hamilton = "hamilton"
    reduced = "reduced"


class Target(str, Enum):
    text = "text"
    latex = "latex"
    python = "python"
    c = "c"
    octave = "octave"
    jax = "jax"
    json = "json"


@app.command()
def derive(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system (e.g. double_pendulum).")],
    to: Annotated[
        Target | None,
        typer.Option(
            "--to",
            metavar="TARGET",
            help="The output: text (equations, the default), latex, python (a module for solve_ivp), c (a header-only C99 file), octave (a function file for ode45), jax or json.",
        ),
    ] = None,
    text: Annotated[bool, typer.Option("--text", help="Plain-text equations (the default); same as --to text.")] = False,
    latex: Annotated[bool, typer.Option("--latex", help="A LaTeX align* fragment; same as --to latex.")] = False,
    python: Annotated[bool, typer.Option("--python", help="A Python module for numerical work; same as --to python.")] = False,
    form: Annotated[
        Form,
        typer.Option(
            help="lagrange: one equation per coordinate; matrix: M q_ddot = F; solved: q_ddot = ...; hamilton: H(q, p) and Hamilton's equations in the state (q, p) (every target); reduced: with velocity constraints, the equations in the independent velocities, multipliers eliminated (every target)."
        ),
    ] = Form.lagrange,
    standalone: Annotated[bool, typer.Option(help="With --latex: a whole compilable document.")] = False,
    numba: Annotated[bool, typer.Option("--numba", help="With --python: compile rhs with numba (needs numba where the module runs).")] = False,
    prefix: Annotated[str | None, typer.Option("--prefix", metavar="NAME", help="With --to c: the prefix of the generated names (default eom: eom_rhs, EOM_NQ, ...).")] = None,
    output_path: Annotated[Path | None, typer.Option("-o", "--output", help="Write here (atomically) instead of to stdout. With --to octave, a FILE.m defines the function FILE.")] = None,
) -> None:
    """Derive the equations of motion of a system."""
    check_outputs(output_path, reading=file)
    from lagrange_cli.errors import LagrangeError

    try:
        target, name = _target(to, text, latex, python, numba, standalone, prefix, output_path)
        from lagrange_cli.derive import load_model

        model = load_model(file, shared=target in SHARED_TARGETS and form is not Form.hamilton)
        if form is Form.hamilton:
            output(_hamilton(model, target, numba, standalone, name), output_path)
            return
        if form is Form.reduced:
            output(_reduced(model, target, numba, standalone, name), output_path)
            return
        emitter = _emitter(target)
        if target == "python":
            result = emitter.emit(model, numba=numba)
        elif target == "latex":
            result = emitter.emit(model, form.value, standalone=standalone)
        elif target == "text":
            result = emitter.emit(model, form.value)
        else:
            result = emitter.emit(model, name=name)
        output(result, output_path)
    except LagrangeError as error:
        fail_with(error)


def _hamilton(model: Any, target: str, numba: bool, standalone: bool, name: str) -> str:
    """`--form hamilton`: text, latex and python write Hamilton's equations (emit/hamiltonian.py), the
    other targets by their module's `emit_hamilton`; a target without one refuses (exit 2)."""
    from lagrange_cli.emit import hamiltonian

    emitter = _emitter(target) if target not in ("text", "latex", "python") else None
    if emitter is not None and hasattr(emitter, "emit_hamilton"):
        return str(emitter.emit_hamilton(model, name=name))

    if target == "text":
        return hamiltonian.text(model)
    if target == "latex":
        return hamiltonian.latex(model, standalone=standalone)
    if target == "python":
        return hamiltonian.python(model, numba=numba)
    hamiltonian.refuse(target)
    raise AssertionError("unreachable")


def _reduced(model: Any, target: str, numba: bool, standalone: bool, name: str) -> str:
    """`--form reduced`: every target writes Maggi's equations (emit/reduced.py `TARGETS`): text, latex,
    python and jax by emit/reduced.py, the others by their module's `emit_reduced`."""
    from lagrange_cli.emit import reduced

    if target in ("c", "octave", "json"):
        return str(_emitter(target).emit_reduced(model, name=name))
    if target == "jax":
        return reduced.jax(model, name=name)
    if target == "text":
        return reduced.text(model)
    if target == "latex":
        return reduced.latex(model, standalone=standalone)
    if target == "python":
        return reduced.python(model, numba=numba)
    reduced.refuse(target)
    raise AssertionError("unreachable")


def _target(to: Target | None, text: bool, latex: bool, python: bool, numba: bool, standalone: bool, prefix: str | None, output_path: Path | None) -> tuple[str, str]:
    """The target asked for (`--to` or one of its aliases) and the name its code defines (the C
    prefix, the Octave function); exit 2 for options that contradict each other or a bad name."""
    from lagrange_cli.errors import fail
    from lagrange_cli.files import shown

    chosen = {flag for flag, given in (("text", text), ("latex", latex), ("python", python)) if given}
    if to is not None:
        chosen.add(to.value)
    if len(chosen) > 1:
        raise fail(None, "choose one of --to, --text, --latex, --python", "a single output format, e.g. --to c")
    target = chosen.pop() if chosen else "text"
    if numba and target != "python":
        raise fail(None, "--numba applies to --python output", "--python --numba")
    if standalone and target != "latex":
        raise fail(None, "--standalone applies to --latex output", "--latex --standalone")
    if prefix is not None and target != "c":
        raise fail(None, "--prefix applies to --to c output", "--to c --prefix NAME")
    if target == "c":
        name = "eom" if prefix is None else prefix
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,30}", name) or name in C_WORDS:
            raise fail(None, f"--prefix {shown(name)} is not usable as the prefix of C names", "a C identifier of at most 31 characters, starting with a letter, not a C keyword (e.g. pendulum)")
        return target, name
    if target == "octave" and output_path is not None and output_path.suffix == ".m":
        name = output_path.name[: -len(".m")]
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,62}", name) or name in MATLAB_KEYWORDS:
            raise fail(
                None,
                f"the output file {shown(str(output_path))} cannot hold an Octave function: its name, {shown(name)}, is not a MATLAB identifier",
                "a file name that is a letter followed by letters, digits or _ (at most 63), not a keyword, then .m (e.g. pendulum_eom.m)",
            )
        return target, name
    return target, "eom"


C_WORDS = frozenset(
    {
        *("auto", "break", "case", "char", "const", "continue", "default", "do", "double", "else", "enum", "extern", "float", "for", "goto", "if"),
        *("inline", "int", "long", "register", "restrict", "return", "short", "signed", "sizeof", "static", "struct", "switch", "typedef", "union"),
        *("unsigned", "void", "volatile", "while", "bool", "true", "false", "asm", "class", "new", "delete", "this", "template", "typename"),
        *("namespace", "operator", "private", "public", "protected", "virtual", "friend", "try", "catch", "throw", "and", "or", "not", "xor"),
    }
)
"""C and C++ keywords, which are no prefix."""

MATLAB_KEYWORDS = frozenset(
    {
        *("break", "case", "catch", "classdef", "continue", "else", "elseif", "end", "for", "function", "global", "if", "otherwise", "parfor"),
        *("persistent", "return", "spmd", "switch", "try", "while", "do", "until", "unwind_protect", "unwind_protect_cleanup", "end_try_catch"),
        *("endfor", "endfunction", "endif", "endswitch", "endwhile", "end_unwind_protect", "methods", "properties", "events", "enumeration"),
        *("endclassdef", "endenumeration", "endevents", "endmethods", "endparfor", "endproperties", "endspmd", "arguments", "__FILE__", "__LINE__"),
    }
)
"""MATLAB's and Octave's keywords: not a function's name."""


def _emitter(target: str) -> Any:
    """The module of `target`, imported now; a target this installation lacks is exit 2."""
    import importlib

    from lagrange_cli.errors import fail

    module = TARGETS[target]
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as error:
        if error.name != module:
            raise
        raise fail(None, f"the {target} target is not available in this installation ({module} is missing)", "one of the targets it has: " + ", ".join(_available())) from None


def _available() -> list[str]:
    import importlib.util

    return [t for t, m in TARGETS.items() if importlib.util.find_spec(m) is not None]


@app.command()
def check(
    paths: Annotated[list[str], typer.Argument(help="System files, directories or globs with `expect` blocks.")],
    junit: Annotated[Path | None, typer.Option("--junit", help="Also write a JUnit XML report here (one test case per expect entry).")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON report instead of the table.")] = False,
) -> None:
    """Check the answers under `expect` against the derived equations.

    Exit code 0: all pass; 1: some answer is wrong; 2: bad input.
    """
    from lagrange_cli import check as checker
    from lagrange_cli.cli.boundary import console, inert, plain
    from lagrange_cli.errors import LagrangeError

    try:
        files = _system_files(paths)
    except LagrangeError as error:
        fail_with(error)
    check_outputs(junit, reading=files, options=("--junit",))
    from rich.table import Table

    reports = [_check_file(checker, path) for path in files]
    if junit is not None:
        write_atomically(junit, checker.to_junit(reports))
    code = checker.exit_code(reports)
    if as_json:
        keeping_verdict(code, lambda: output(checker.to_json(reports), None))
    errors = console(stderr=True)
    table = Table(title="lagrange check")
    for column in ("file", "entry", "result", "decided"):
        table.add_column(column)
    for report in reports:
        if report.error:
            errors.print(plain(report.error), markup=False)
            table.add_row(inert(report.path), "-", "[red]error[/red]", "bad input")
        elif not report.results:
            table.add_row(inert(report.path), "-", "[dim]skipped[/dim]", "nothing to check")
        for result in report.results:
            if not result.passed:
                errors.print(f"[bold red]wrong[/bold red] {inert(result.span or report.path)}: [bold]{inert(result.entry)}[/bold]: {escape(plain(result.detail))}")
            table.add_row(inert(report.path), inert(result.entry), "[green]pass[/green]" if result.passed else "[red]FAIL[/red]", inert(result.method))
    out = console(stderr=junit is not None and str(junit) == "-")
    counts = {status: sum(1 for r in reports if r.status == status) for status in ("pass", "fail", "error", "skip")}
    summary = f"{len(reports)} file{'s' * (len(reports) != 1)}: {counts['pass']} passed, {counts['fail']} failed, {counts['error']} with errors" + (
        f", {counts['skip']} skipped" if counts["skip"] else ""
    )

    def show() -> None:
        out.print(table)
        out.print(summary)

    keeping_verdict(code, show)


def _system_files(paths: list[str]) -> list[Path]:
    """The files `check` reads: each argument (a file, a directory, a glob) must name at least one,
    so that a mistyped glob or an empty directory is an error (exit 2), never a pass."""
    from lagrange_cli import spec
    from lagrange_cli.errors import fail
    from lagrange_cli.files import check_name, shown

    if not paths:
        raise fail(None, "no system files given", "files, directories or globs, e.g. lagrange check 'systems/*.yaml'")
    files: list[Path] = []
    for item in paths:
        check_name(item)
        found = list(spec.iter_files([item]))
        if not found:
            what = "the directory" if Path(item).is_dir() else "the pattern"
            raise fail(None, f"no system files matched {shown(item)}: {what} names no .yaml file", "a path, a directory with .yaml files, or a glob that matches some")
        files += [path for path in found if path not in files]
    return files


def _check_file(checker: Any, path: Path) -> Any:
    """`check.check_file`, with a bug in it reported for this file (exit 2) instead of a traceback;
    the report names the file as messages do (a bundled system as `systems/<name>.yaml`)."""
    import dataclasses
    import os

    from lagrange_cli.cli.boundary import DEBUG_VARIABLE, internal_error
    from lagrange_cli.spec import shown_name

    name = shown_name(path)
    try:
        return dataclasses.replace(checker.check_file(str(path)), path=name)
    except Exception as error:  # the safety net, per file
        if os.environ.get(DEBUG_VARIABLE) == "1":
            raise
        return checker.FileReport(name, error=internal_error(name, error))


def escape(text: str) -> str:
    from rich.markup import escape as rich_escape

    return rich_escape(text)
