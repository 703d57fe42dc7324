"""`info`, `equilibria` and `linearize`: what the equations say about momenta, conserved
quantities, equilibrium points and small oscillations."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from lagrange_cli.cli import app, check_outputs, fail_with, output

if TYPE_CHECKING:
    import sympy as sp

    from lagrange_cli.errors import LagrangeError
    from lagrange_cli.model import Model


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
    from lagrange_cli import analysis, noether, report
    from lagrange_cli.derive import load_system_and_model
    from lagrange_cli.errors import LagrangeError, fail

    try:
        system, model = load_system_and_model(file)
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
    from lagrange_cli.derive import load_model
    from lagrange_cli.errors import LagrangeError

    try:
        model = load_model(file)
        found = report.equilibria(model, _ranges(model, ranges))
    except LagrangeError as error:
        fail_with(error)
    output(report.equilibria_json(model, found) if as_json else report.equilibria_text(model, found), None)


@app.command()
def linearize(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system.")],
    about: Annotated[
        list[str] | None,
        typer.Option(
            "--about",
            help="The operating point: name=value for coordinates and inputs, repeated or separated by commas, e.g. theta=0,phi=pi; a coordinate's value may use the parameters, e.g. r=l+m*g/k (unnamed coordinates are 0, inputs their default).",
        ),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="JSON instead of text.")] = False,
    state_space: Annotated[bool, typer.Option("--state-space", help="Also the state-space matrices A, B, C, D (always given for a file with inputs or outputs).")] = False,
    latex: Annotated[bool, typer.Option("--latex", help="The state-space matrices A, B, C, D in LaTeX.")] = False,
    lqr: Annotated[bool, typer.Option("--lqr", help="Also an LQR gain K (du = -K x) for diagonal weights Q and R (default identities; needs scipy).")] = False,
    lqr_q: Annotated[str | None, typer.Option("--lqr-q", help="Diagonal of Q: one weight per state (comma-separated) or one for all; implies --lqr.")] = None,
    lqr_r: Annotated[str | None, typer.Option("--lqr-r", help="Diagonal of R: one weight per input (comma-separated) or one for all; implies --lqr.")] = None,
) -> None:
    """The linearization M0 x_ddot + C0 x_dot + K0 x = 0 about an equilibrium, its stability and normal modes; with inputs or outputs also dx/dt = A x + B du, y - y0 = C x + D du."""
    import json

    from lagrange_cli import analysis, report, statespace
    from lagrange_cli.derive import load_model
    from lagrange_cli.errors import LagrangeError

    if latex and as_json:
        fail_with(_usage("choose one of --latex, --json", "a single output format"))
    try:
        model = load_model(file)
        point, given = _operating_point(model, about)
        wanted = state_space or latex or lqr or lqr_q is not None or lqr_r is not None or bool(model.inputs or model.outputs)
        if wanted:
            ss = statespace.state_space(model, point, given)
            lin = analysis.linearize(inputs_at(model, given), point)
            gain = statespace.lqr(ss, _weights("--lqr-q", lqr_q), _weights("--lqr-r", lqr_r)) if lqr or lqr_q is not None or lqr_r is not None else None
        else:
            lin = analysis.linearize(model, point)
    except analysis.NotAnEquilibrium as error:
        where = "the point of --about" if about else "the default point (every coordinate 0)"
        fail_with(analysis.NotAnEquilibrium(f"{error}\n  {where} is not an equilibrium; `lagrange equilibria {file}` lists the equilibria: give one with --about (its values may use the parameters)"))
    except LagrangeError as error:
        fail_with(error)
    if latex:
        output(statespace.latex(ss), None)
    elif as_json:
        data = report.linearization_json(model, lin)
        if wanted:
            data.update(statespace.as_json(ss, gain))
        output(json.dumps(data, indent=2) + "\n", None)
    else:
        output(report.linearization_text(model, lin) + (statespace.text(ss, gain) if wanted else ""), None)


def inputs_at(model: Model, given: dict[str, sp.Expr]) -> Model:
    """The model with its inputs at the operating point's values (lagrange_cli/inputs.py)."""
    from lagrange_cli import inputs

    return inputs.substitute(model, given)


def _usage(message: str, expected: str) -> LagrangeError:
    from lagrange_cli.errors import fail

    return fail(None, message, expected)


def _weights(option: str, text: str | None) -> list[float] | None:
    """The comma-separated numbers of --lqr-q / --lqr-r."""
    from lagrange_cli.cli.boundary import Item, constant

    if text is None:
        return None
    values, start = [], 0
    for piece in text.split(","):
        item = Item(option, text, option, piece, start, start)
        values.append(constant(item, f"a weight of {option}")[1])
        start += len(piece) + 1
    return values


def _point(model: Model, about: list[str] | None) -> dict[sp.Symbol, sp.Expr]:
    """The coordinates' values of `--about` (exact: pi stays pi)."""
    return _operating_point(model, about)[0]


def _operating_point(model: Model, about: list[str] | None) -> tuple[dict[sp.Symbol, sp.Expr], dict[str, sp.Expr]]:
    """The coordinates' and the inputs' values of `--about` (exact: pi stays pi)."""
    from lagrange_cli import analysis
    from lagrange_cli.cli.boundary import assignments, check_names, constant

    items = assignments("--about", about, f"{model.coordinates[0]}=0")
    signals = [i.name for i in model.inputs]
    check_names(items, [*model.coordinates, *signals], "coordinate or input" if signals else "coordinate", model.source)
    point = {model.q[model.coordinates.index(item.name)]: analysis.point_value(model, item.name, item.value, item.span()) for item in items if item.name in model.coordinates}
    given = {item.name: constant(item, f"the value of '{item.name}'")[0] for item in items if item.name in signals}
    return point, given


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
