"""`info`, `equilibria` and `linearize`: what the equations say about momenta, conserved
quantities, equilibrium points and small oscillations."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from lagrange_cli.cli import app, check_outputs, fail_with, output

if TYPE_CHECKING:
    import sympy as sp

    from lagrange_cli.model import Model


def _model(file: str) -> Model:
    from lagrange_cli import derive, spec

    return derive.derive(spec.load(spec.resolve(file)))


@app.command()
def info(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system.")],
    latex: Annotated[bool, typer.Option("--latex", help="LaTeX instead of text.")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="JSON instead of text.")] = False,
    output_path: Annotated[Path | None, typer.Option("-o", "--output", help="Write here (atomically).")] = None,
    routh: Annotated[
        bool,
        typer.Option(
            "--routh",
            help="Routh's reduction: the Routhian for the ignorable coordinates (their momenta, e.g. p_theta, as parameters), the reduced equations, the effective potential and the relative equilibria with their stability.",
        ),
    ] = False,
) -> None:
    """Degrees of freedom, generalized momenta, ignorable coordinates, the energy function and the Hamiltonian."""
    check_outputs(output_path, reading=file)
    from lagrange_cli import analysis, derive, noether, report, spec
    from lagrange_cli.errors import LagrangeError, fail

    try:
        system = spec.load(spec.resolve(file))
        model = derive.derive(system)
        if routh:
            from lagrange_cli import routh as reduction

            if latex or as_json:
                raise fail(None, "--routh writes text only", "lagrange info FILE --routh (without --latex or --json)")
            output(reduction.text(reduction.routh(model)), output_path)
            return
        result = analysis.info(model)
        render = report.info_json if as_json else report.info_latex if latex else report.info_text
        form = "json" if as_json else "latex" if latex else "text"
        output(noether.with_charges(system, model, render(model, result), form), output_path)
    except LagrangeError as error:
        fail_with(error)


@app.command()
def equilibria(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system.")],
    ranges: Annotated[
        list[str] | None, typer.Option("--range", help="Search ranges for a numeric search: name=low..high, repeated or separated by commas, e.g. theta=-3.2..3.2 (default -pi..pi).")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="JSON instead of text.")] = False,
) -> None:
    """Equilibrium points (symbolic where possible, else numeric), each with its stability."""
    from lagrange_cli import report
    from lagrange_cli.errors import LagrangeError

    try:
        model = _model(file)
        found = report.equilibria(model, _ranges(model, ranges))
    except LagrangeError as error:
        fail_with(error)
    output(report.equilibria_json(model, found) if as_json else report.equilibria_text(model, found), None)


@app.command()
def linearize(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system.")],
    about: Annotated[list[str] | None, typer.Option("--about", help="The equilibrium: name=value, repeated or separated by commas, e.g. theta=0,phi=pi (unnamed coordinates are 0).")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="JSON instead of text.")] = False,
) -> None:
    """The linearization M0 x_ddot + C0 x_dot + K0 x = 0 about an equilibrium, its stability and normal modes."""
    import json

    from lagrange_cli import analysis, report
    from lagrange_cli.errors import LagrangeError

    try:
        model = _model(file)
        lin = analysis.linearize(model, _point(model, about))
    except LagrangeError as error:
        fail_with(error)
    output(json.dumps(report.linearization_json(model, lin), indent=2) + "\n" if as_json else report.linearization_text(model, lin), None)


def _point(model: Model, about: list[str] | None) -> dict[sp.Symbol, sp.Expr]:
    """The coordinates' values of `--about` (exact: pi stays pi)."""
    from lagrange_cli.cli.boundary import assignments, check_names, constant

    items = assignments("--about", about, f"{model.coordinates[0]}=0")
    check_names(items, list(model.coordinates), "coordinate", model.source)
    return {model.q[model.coordinates.index(item.name)]: constant(item, f"the value of '{item.name}'")[0] for item in items}


def _ranges(model: Model, ranges: list[str] | None) -> dict[sp.Symbol, tuple[float, float]]:
    """The search box of `--range name=low..high`, each range checked to be finite and not empty."""
    from lagrange_cli.cli.boundary import assignments, check_names, constant
    from lagrange_cli.errors import fail

    items = assignments("--range", ranges, f"{model.coordinates[0]}=-3.2..3.2")
    check_names(items, list(model.coordinates), "coordinate", model.source)
    bounds = {}
    expected = "name=low..high with low < high, e.g. theta=-3.2..3.2"
    for item in items:
        low, dots, high = item.value.partition("..")
        if not dots:
            raise fail(item.span(), f"'{item.value.strip()}' is not a range", expected)
        first = constant(item, "a range bound", low)[1]
        second = constant(item, "a range bound", high, len(low) + 2)[1]
        if not first < second:
            raise fail(item.span(), f"the range '{item.name}={item.value.strip()}' is empty: its low end must be below its high end", expected)
        bounds[model.q[model.coordinates.index(item.name)]] = (first, second)
    return bounds
