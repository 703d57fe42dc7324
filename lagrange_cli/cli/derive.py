"""`derive` and `check`: from a system file to its equations, and answers checked against them."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from lagrange_cli.cli import Form, app, fail_with, output


@app.command()
def derive(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system (e.g. double_pendulum).")],
    text: Annotated[bool, typer.Option("--text", help="Plain-text equations (the default).")] = False,
    latex: Annotated[bool, typer.Option("--latex", help="A LaTeX align* fragment.")] = False,
    python: Annotated[bool, typer.Option("--python", help="A Python module for numerical work.")] = False,
    form: Annotated[Form, typer.Option(help="lagrange: one equation per coordinate; matrix: M q_ddot = F; solved: q_ddot = ...")] = Form.lagrange,
    standalone: Annotated[bool, typer.Option(help="With --latex: a whole compilable document.")] = False,
    output_path: Annotated[Path | None, typer.Option("-o", "--output", help="Write here (atomically) instead of to stdout.")] = None,
) -> None:
    """Derive the equations of motion of a system."""
    from lagrange_cli.errors import LagrangeError, fail

    try:
        if text + latex + python > 1:
            raise fail(None, "choose one of --text, --latex, --python", "a single output format")
        from lagrange_cli import derive as core
        from lagrange_cli import spec

        model = core.derive(spec.load(spec.resolve(file)))
        if python:
            from lagrange_cli.emit import python as emitter_py

            result = emitter_py.emit(model)
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
) -> None:
    """Check the answers under `expect` against the derived equations (exit 1 if any is wrong)."""
    from rich.console import Console
    from rich.table import Table

    from lagrange_cli import check as checker
    from lagrange_cli import derive as core
    from lagrange_cli import spec
    from lagrange_cli.errors import LagrangeError

    console = Console(highlight=False)
    errors = Console(stderr=True, highlight=False, soft_wrap=True)
    table = Table(title="lagrange check")
    for column in ("file", "entry", "result", "how"):
        table.add_column(column)
    wrong = bad = 0
    try:
        files = list(spec.iter_files(paths))
    except LagrangeError as error:
        fail_with(error)
    for path in files:
        try:
            system = spec.load(path)
            results = checker.check(system, core.derive(system))
        except LagrangeError as error:
            errors.print(str(error), markup=False)
            table.add_row(str(path), "-", "[red]error[/red]", "bad input")
            bad += 1
            continue
        if not results:
            table.add_row(str(path), "-", "[dim]no expect[/dim]", "")
        for result in results:
            if not result.passed:
                wrong += 1
                where = f"{result.span}: " if result.span else f"{path}: "
                errors.print(f"{where}wrong: {result.entry}: {result.detail}", markup=False)
            table.add_row(str(path), result.entry, "[green]pass[/green]" if result.passed else "[red]FAIL[/red]", result.method)
    console.print(table)
    raise typer.Exit(2 if bad else 1 if wrong else 0)
