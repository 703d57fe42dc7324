"""`info`, `equilibria` and `linearize`: what the equations say about momenta, conserved
quantities, equilibrium points and small oscillations."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from lagrange_cli.cli import app, check_outputs, fail_with, output

if TYPE_CHECKING:
    import sympy as sp

    from lagrange_cli import analysis
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
) -> None:
    """Degrees of freedom, generalized momenta, ignorable coordinates, the energy function and the Hamiltonian."""
    check_outputs(output_path, reading=file)
    from lagrange_cli import analysis, report
    from lagrange_cli.errors import LagrangeError

    try:
        model = _model(file)
        result = analysis.info(model)
        render = report.info_json if as_json else report.info_latex if latex else report.info_text
        output(render(model, result), output_path)
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
    import json

    from lagrange_cli import analysis, report
    from lagrange_cli.errors import LagrangeError

    try:
        model = _model(file)
        bounds = _ranges(model, ranges)
        points = analysis.equilibria(model, bounds)
        steady = analysis.steady_motions(model)
        results: list[tuple[dict[sp.Symbol, sp.Expr], analysis.Linearization | str]] = []
        for point in points:
            try:
                results.append((point, analysis.linearize(model, point)))
            except LagrangeError as error:
                results.append((point, str(error)))
    except LagrangeError as error:
        fail_with(error)
    if as_json:
        items = [
            {
                "point": {str(k): str(v) for k, v in p.items()},
                "free": [str(k) for k, v in p.items() if v == sp_symbol(f"{k}_0")],
                **({"error": lin} if isinstance(lin, str) else report.linearization_json(model, lin)),
            }
            for p, lin in results
        ]
        motions = [{"velocity": str(v), "equals": str(x)} for v, x in steady]
        output(json.dumps({"title": model.title, "equilibria": items, "steady_motions": motions}, indent=2) + "\n", None)
        return
    lines = [f"{model.title}: {len(points)} equilibri{'um' if len(points) == 1 else 'a'}" + (" (none found)" if not points else "")]
    if len(points) >= analysis.MAX_NUMERIC_POINTS and all(v.is_Float for p in points for v in p.values()):
        lines.append(f"(the numeric search stops at {analysis.MAX_NUMERIC_POINTS} distinct points: the equilibria may form a curve or surface; narrow the search with --range)")
    free = sorted({str(q) for p in points for q, v in p.items() if v == sp_symbol(f"{q}_0")})
    if free:
        lines.append(f"(a manifold of equilibria: {', '.join(f'{q}_0' for q in free)} may take any value)")
    for point, lin in results:
        lines.append(report.linearization_text(model, lin) if not isinstance(lin, str) else f"at {point}: {lin}\n")
    if steady:
        lines.append("steady motions (the other coordinates at rest, ignorable ones turning steadily):")
        lines += [f"  {v} = {x}" for v, x in steady]
    output("\n".join(lines) + "\n", None)


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


def sp_symbol(name: str) -> sp.Symbol:
    import sympy

    return sympy.Symbol(name)


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
