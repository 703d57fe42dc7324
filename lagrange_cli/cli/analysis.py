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
    from lagrange_cli.errors import Span
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
    ranges: Annotated[list[str] | None, typer.Option("--range", help="Search range for a numeric search, e.g. theta=-3.2..3.2 (default -pi..pi).")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="JSON instead of text.")] = False,
) -> None:
    """Equilibrium points (symbolic where possible, else numeric), each with its stability."""
    import json

    from lagrange_cli import analysis, report
    from lagrange_cli.errors import LagrangeError

    try:
        model = _model(file)
        bounds = {_coordinate(model, name): (low, high) for name, low, high in (_range(r) for r in ranges or [])}
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
        items = [{"point": {str(k): str(v) for k, v in p.items()}, **({"error": lin} if isinstance(lin, str) else report.linearization_json(model, lin))} for p, lin in results]
        motions = [{"velocity": str(v), "equals": str(x)} for v, x in steady]
        output(json.dumps({"title": model.title, "equilibria": items, "steady_motions": motions}, indent=2) + "\n", None)
        return
    lines = [f"{model.title}: {len(points)} equilibri{'um' if len(points) == 1 else 'a'}" + (" (none found)" if not points else "")]
    for point, lin in results:
        lines.append(report.linearization_text(model, lin) if not isinstance(lin, str) else f"at {point}: {lin}\n")
    if steady:
        lines.append("steady motions (the other coordinates at rest, ignorable ones turning steadily):")
        lines += [f"  {v} = {x}" for v, x in steady]
    output("\n".join(lines) + "\n", None)


@app.command()
def linearize(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system.")],
    about: Annotated[str, typer.Option("--about", help="The equilibrium, e.g. theta=0,phi=pi (unnamed coordinates are 0).")] = "",
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


def _coordinate(model: Model, name: str) -> sp.Symbol:
    from lagrange_cli.errors import fail

    if name not in model.coordinates:
        raise fail(None, f"'{name}' is not a coordinate of {model.source}", "one of " + ", ".join(model.coordinates))
    return model.q[model.coordinates.index(name)]


def _value(text: str, what: str, span: Span) -> sp.Expr:
    """A constant such as 0, pi/2 or -1.5, parsed safely; `span` places `text` in its option's
    value, so that a mistake is shown with the option's name and a caret."""
    import sympy as sp

    from lagrange_cli.errors import fail
    from lagrange_cli.expr import Scope, numeric_value, parse_expression

    value = parse_expression(text, span, Scope({}, {}, sp.Symbol("t"), lambda e: e, what="numbers, pi and E"))
    if not value.is_number:
        raise fail(span, f"{what} must be a number, got '{text.strip()}'", "a number such as 0, pi/2 or -1.5")
    try:
        numeric_value(value)
    except (ValueError, OverflowError, TypeError):
        raise fail(span, f"{what} must be a finite real number, got '{text.strip()}'", "a number such as 0, pi/2 or -1.5") from None
    return value


def _point(model: Model, about: str) -> dict[sp.Symbol, sp.Expr]:
    from lagrange_cli.errors import Span, fail

    point = {}
    for item in filter(None, (part.strip() for part in about.split(","))):
        name, sep, text = item.partition("=")
        if not sep:
            raise fail(Span("--about", 1, 1, item), f"'{item}' in --about is not of the form name=value", "e.g. --about theta=0,phi=pi")
        point[_coordinate(model, name.strip())] = _value(text, f"the value of '{name.strip()}'", Span("--about", 1, len(name) + 2, item))
    return point


def _range(text: str) -> tuple[str, float, float]:
    from lagrange_cli.errors import Span, fail
    from lagrange_cli.expr import numeric_value

    name, sep, span = text.partition("=")
    low, dots, high = span.partition("..")
    if not sep or not dots:
        raise fail(Span("--range", 1, 1, text), f"'{text}' is not a range", "name=low..high, e.g. theta=-3.2..3.2")
    first = numeric_value(_value(low, "a range bound", Span("--range", 1, len(name) + 2, text)))
    second = numeric_value(_value(high, "a range bound", Span("--range", 1, len(name) + len(low) + 4, text)))
    if not first < second:
        raise fail(Span("--range", 1, len(name) + 2, text), f"the range {text!r} is empty: its low end must be below its high end", "name=low..high with low < high, e.g. theta=-3.2..3.2")
    return name.strip(), first, second
