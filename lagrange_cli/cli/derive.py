"""`derive` and `check`: from a system file to its equations, and answers checked against them."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from lagrange_cli.cli import Form, app, check_outputs, fail_with, output, write_atomically
from lagrange_cli.cli._app import keeping_verdict


@app.command()
def derive(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system (e.g. double_pendulum).")],
    text: Annotated[bool, typer.Option("--text", help="Plain-text equations (the default).")] = False,
    latex: Annotated[bool, typer.Option("--latex", help="A LaTeX align* fragment.")] = False,
    python: Annotated[bool, typer.Option("--python", help="A Python module for numerical work.")] = False,
    form: Annotated[Form, typer.Option(help="lagrange: one equation per coordinate; matrix: M q_ddot = F; solved: q_ddot = ...")] = Form.lagrange,
    standalone: Annotated[bool, typer.Option(help="With --latex: a whole compilable document.")] = False,
    numba: Annotated[bool, typer.Option("--numba", help="With --python: compile rhs with numba (needs numba where the module runs).")] = False,
    output_path: Annotated[Path | None, typer.Option("-o", "--output", help="Write here (atomically) instead of to stdout.")] = None,
) -> None:
    """Derive the equations of motion of a system."""
    check_outputs(output_path, reading=file)
    from lagrange_cli.errors import LagrangeError, fail

    try:
        if text + latex + python > 1:
            raise fail(None, "choose one of --text, --latex, --python", "a single output format")
        if numba and not python:
            raise fail(None, "--numba applies to --python output", "--python --numba")
        if standalone and not latex:
            raise fail(None, "--standalone applies to --latex output", "--latex --standalone")
        from lagrange_cli import derive as core
        from lagrange_cli import spec

        model = core.derive(spec.load(spec.resolve(file)))
        if python:
            from lagrange_cli.emit import python as emitter_py

            result = emitter_py.emit(model, numba=numba)
        elif latex:
            from lagrange_cli.emit import latex as emitter_tex

            result = emitter_tex.emit(model, form.value, standalone=standalone)
        else:
            from lagrange_cli.emit import text as emitter_txt

            result = emitter_txt.emit(model, form.value)
        output(result, output_path)
    except LagrangeError as error:
        fail_with(error)


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
