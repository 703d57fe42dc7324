"""The `inputs` and `outputs` keys (FORMAT.md version 2, "Inputs and outputs").

Inputs u(t) are plain symbols in the derived equations, like parameters, but with a default
value (0 unless given) and the meaning of a given function of time. They may appear in forces,
torques, generalized forces, the potential, the dissipation and Lagrangian terms, but never where
the equations would need their time derivative: not in a position, an angular velocity, a mass,
an inertia or a constraint, and not in a Lagrangian or kinetic term whose derivative with respect
to a velocity depends on them (d/dt of that derivative would bring in u_dot). Those are refused
with the file, line and column (exit 2), as is an input used nowhere.

Outputs y = h(q, q_dot, t, u) are expressions of the state, time and inputs (no accelerations).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import sympy as sp

from lagrange_cli.model import Input

if TYPE_CHECKING:
    import yaml

    from lagrange_cli.expr import Scope
    from lagrange_cli.frontend.nodes import Body, Particle, SystemSpec
    from lagrange_cli.model import Model

INPUT_KEYS = ("value", "description")
LOAD_FIELDS = ("force", "torque", "forces", "torques", "frame_forces")
"""Fields of a particle or body that may hold inputs (loads enter through the virtual power): a particle's `force`, an oriented body's `forces`, `torques` and `frame_forces`."""
WHERE = "forces, torques, generalized forces, the potential, the dissipation and Lagrangian terms"
U_DOT = (
    "the tool treats inputs as given functions of time but does not differentiate them: an input may not appear where the equations "
    "would need its time derivative u_dot; write the term as a generalized force, or make the quantity a coordinate"
)


def read_inputs(reader: Any, node: yaml.Node | None, taken: dict[str, str]) -> tuple[Input, ...]:
    """`inputs`: a list of names, or a map name -> {value, description} (value a number, default 0)."""
    import yaml

    if node is None:
        return ()
    result = []
    if isinstance(node, yaml.SequenceNode):
        for item in node.value:
            name = reader.name(item, "input", taken)
            if name:
                result.append(Input(sp.Symbol(name), 0.0, "", reader.where(item)))
        return tuple(result)
    if not isinstance(node, yaml.MappingNode):
        reader.problem(node, "'inputs' must be a list or a map", "a list of names such as `[tau]`, or a map such as `{tau: {value: 0, description: motor torque}}`")
        return ()
    for key, key_node, value in reader.mapping(node, "'inputs'"):
        name = reader.name(key_node, "input", taken)
        if name is None:
            continue
        number: float | None = 0.0
        description = ""
        if isinstance(value, yaml.MappingNode):
            fields = {k: v for k, _, v in reader.mapping(value, f"input '{key}'", INPUT_KEYS)}
            number = reader.number(fields["value"], f"the value of '{key}'") if "value" in fields else 0.0
            description = reader.string(fields.get("description"), "'description'") or ""
        elif not (isinstance(value, yaml.ScalarNode) and value.tag == "tag:yaml.org,2002:null"):
            number = reader.number(value, f"the value of '{key}'")
        if number is not None:
            result.append(Input(sp.Symbol(name), number, description, reader.where(key_node)))
    return tuple(result)


def read_outputs(reader: Any, node: yaml.Node | None, scope: Scope, taken: dict[str, str]) -> tuple[tuple[str, sp.Expr], ...]:
    """`outputs`: a map name -> expression of the coordinates, velocities, parameters, inputs and t."""
    import yaml

    if node is None:
        return ()
    if not isinstance(node, yaml.MappingNode):
        reader.problem(node, "'outputs' must be a map", "a map name -> expression, such as `{x_cart: x, angle: theta}`")
        return ()
    result = []
    names: set[str] = set()
    for key, key_node, value in reader.mapping(node, "'outputs'"):
        if key in names:
            continue
        name = reader.name(key_node, "output", dict(taken))  # outputs may share a name with what they measure
        if name is None:
            continue
        names.add(name)
        expr = reader.expression(value, f"output '{key}'", scope)
        reader.sources[f"outputs.{name}"] = reader.where(value)
        if expr is not None:
            result.append((name, expr))
    return tuple(result)


def check_usage(reader: Any, spec: SystemSpec) -> None:
    """Record a problem for each input used nowhere in the dynamics, and for each place that would
    need an input's time derivative (see the module's docstring)."""
    if not spec.inputs:
        return
    symbols = {i.symbol for i in spec.inputs}

    def found(expr: Any) -> list[str]:
        return sorted(str(s) for s in _free(expr) & symbols)

    def refuse(span: Any, what: str, names: list[str]) -> None:
        from lagrange_cli.errors import Diagnostic

        reader.problems.append(Diagnostic(span, f"input '{names[0]}' appears in {what}", f"inputs in {WHERE} only; {U_DOT}"))

    items: tuple[Particle | Body, ...] = (*spec.particles, *spec.bodies)
    for item in items:
        for key in (f.name for f in dataclasses.fields(item)):
            if key in ("name", "spans", *LOAD_FIELDS):
                continue
            names = found(getattr(item, key))
            if names:
                refuse(item.spans.get(key), f"the {key.replace('_', ' ')} of '{item.name}'", names)
    for c in spec.constraints:
        names = found(c.expr)
        if names:
            refuse(c.span, f"constraint '{c.name}'", names)
    for key in ("kinetic", "lagrangian"):
        expr = getattr(spec, key)
        names = sorted({n for v in spec.qd for n in found(sp.diff(expr, v))})
        if names:
            refuse(spec.sources.get(key), f"the velocity-dependent part of '{key}' (its derivative with respect to a velocity holds the input)", names)
    used = _free(_dynamics(spec))
    for i in spec.inputs:
        if i.symbol not in used:
            reader.problems.append(_diagnostic(i.span, f"input '{i.name}' is used nowhere", f"an input that appears in {WHERE}; remove it from 'inputs' if the system does not depend on it"))


def _diagnostic(span: Any, message: str, expected: str) -> Any:
    from lagrange_cli.errors import Diagnostic

    return Diagnostic(span, message, expected)


def _dynamics(spec: SystemSpec) -> list[Any]:
    """Every expression of the file that enters the equations of motion (not `outputs`, `expect`,
    `exact`, `initial` or `draw`)."""
    values: list[Any] = [spec.kinetic, spec.potential, spec.lagrangian, spec.dissipation, *spec.generalized_forces, spec.gravity]
    items: tuple[Particle | Body, ...] = (*spec.particles, *spec.bodies)
    values += [getattr(item, f.name) for item in items for f in dataclasses.fields(item) if f.name not in ("name", "spans")]
    values += [c.expr for c in spec.constraints]
    return values


def _free(value: Any) -> set[sp.Symbol]:
    """The free symbols of an expression, or of every expression in nested tuples, lists, maps and dataclasses."""
    if isinstance(value, sp.Basic):
        return set(value.free_symbols)  # type: ignore[arg-type]
    if isinstance(value, Mapping):
        return _free(list(value.values()))
    if isinstance(value, (tuple, list)):
        return set().union(*(_free(v) for v in value)) if value else set()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _free([getattr(value, f.name) for f in dataclasses.fields(value) if f.name != "spans"])
    return set()


def substitute(model: Model, values: Mapping[str, sp.Expr] | None = None) -> Model:
    """The model with every input replaced by `values[name]` (an expression of t, the coordinates
    and velocities), or by its default when not given: what numeric code evaluates. A model without
    inputs comes back as it is."""
    if not model.inputs:
        return model
    given = dict(values or {})
    table = {i.symbol: sp.sympify(given.get(i.name, sp.Float(i.value) if i.value != int(i.value) else sp.Integer(int(i.value)))) for i in model.inputs}

    def sub(expr: sp.Expr) -> sp.Expr:
        return sp.sympify(expr).xreplace(table) if table else expr

    def subs_all(values: Iterable[sp.Expr]) -> tuple[sp.Expr, ...]:
        return tuple(sub(v) for v in values)

    rows = tuple(dataclasses.replace(c, expr=sub(c.expr), jacobian=subs_all(c.jacobian), bias=sub(c.bias), acceleration_bias=sub(c.acceleration_bias)) for c in model.constraints)
    return dataclasses.replace(
        model,
        kinetic=sub(model.kinetic),
        potential=sub(model.potential),
        lagrangian=sub(model.lagrangian),
        dissipation=sub(model.dissipation),
        generalized_forces=subs_all(model.generalized_forces),
        mass_matrix=model.mass_matrix.applyfunc(sub),
        forcing=model.forcing.applyfunc(sub),
        momenta=subs_all(model.momenta),
        energy=sub(model.energy),
        constraints=rows,
        outputs=tuple((name, sub(e)) for name, e in model.outputs),
        inputs=(),
    )


def depends(model: Model, *exprs: Any) -> bool:
    """Whether any of `exprs` holds an input of `model`."""
    symbols = {i.symbol for i in model.inputs}
    return bool(symbols and _free(list(exprs)) & symbols)


def signal_expressions(model: Model, entries: Iterable[tuple[str, str, Any, Any]]) -> dict[str, sp.Expr]:
    """The expressions of `simulate --input NAME=EXPR`: each `(name, text, span, where)` names an input of
    `model` (`where` its place) and gives an expression of t, the coordinates, the velocities `<q>_dot` and the
    parameters (a state-feedback law such as `tau=-k1*q1-k2*q1_dot`), parsed by the safe
    expression parser. An unknown input or name is a `SpecError` at its place in the option."""
    from lagrange_cli.errors import Span, fail
    from lagrange_cli.expr import Scope, parse_expression
    from lagrange_cli.frontend.nodes import time_derivative

    known = [i.name for i in model.inputs]
    symbols: dict[str, sp.Expr] = {str(s): s for s in (*model.q, *model.qd, *(p.symbol for p in model.parameters))}
    elsewhere = {**{str(a): "an acceleration" for a in model.qdd}, **dict.fromkeys(known, "an input")}
    scope = Scope(symbols, {}, model.t, lambda e: time_derivative(e, model.q, model.qd, model.qdd, model.t), "t, a coordinate, a velocity (`<q>_dot`), a parameter", elsewhere)
    result: dict[str, sp.Expr] = {}
    for name, text, given_span, given_where in entries:
        span = given_span or Span(f"input {name}", 1, 1, text)
        where = given_where or span
        if name not in known:
            from lagrange_cli.expr import _closest

            hint = _closest(name, known) if known else None
            expected = ("one of " + ", ".join(known) + (f"; did you mean '{hint}'?" if hint else "")) if known else "a system with `inputs:` (this one has none)"
            raise fail(where, f"'{name}' is not an input of {model.source}", expected)
        expr = parse_expression(text, span, scope)
        bad = sorted(str(s) for s in expr.free_symbols if str(s) in elsewhere)
        if bad:
            raise fail(span, f"the expression of input '{name}' depends on {elsewhere[bad[0]]} ('{bad[0]}')", scope.what)
        result[name] = expr
    return result


@dataclass(frozen=True)
class ExpectedStateSpace:
    """`expect.state_space`: the operating point (`about`: name -> exact value, coordinates and
    inputs) and any of A, B, C, D as rows of expressions of the parameters, each with its place."""

    about: tuple[tuple[str, sp.Expr], ...]
    matrices: tuple[tuple[str, tuple[tuple[sp.Expr, ...], ...], Any], ...]
    span: Any = None


STATE_SPACE_KEYS = ("about", "A", "B", "C", "D")


def read_state_space(reader: Any, node: yaml.Node, spec: SystemSpec) -> ExpectedStateSpace | None:
    """Read `expect.state_space` (FORMAT.md version 2): entries are expressions of the parameters."""
    import yaml

    from lagrange_cli.expr import Scope

    fields = {k: v for k, _, v in reader.mapping(node, "'expect.state_space'", STATE_SPACE_KEYS)}
    names = [*spec.coordinates, *(i.name for i in spec.inputs)]
    about = []
    for key, key_node, value in reader.mapping(fields["about"], "'expect.state_space.about'") if "about" in fields else []:
        if key not in names:
            reader.problem(key_node, f"'{key}' is not a coordinate or an input", "one of " + ", ".join(names))
            continue
        number = reader.number(value, f"the value of '{key}'")
        if number is not None:
            text = str(value.value) if isinstance(value, yaml.ScalarNode) else str(number)
            about.append((key, _exact_number(text, number)))
    elsewhere = {**{c: "a coordinate" for c in spec.coordinates}, **{str(v): "a velocity" for v in spec.qd}, **{i.name: "an input" for i in spec.inputs}}
    scope = Scope({p.name: p.symbol for p in spec.parameters}, {}, spec.t, lambda e: e, "a parameter (the matrices are evaluated at the operating point)", {**elsewhere, "t": "time"})
    matrices = []
    for key in "ABCD":
        if key not in fields:
            continue
        rows = []
        for row in reader.sequence(fields[key], f"'expect.state_space.{key}'"):
            items = reader.sequence(row, f"a row of 'expect.state_space.{key}'")
            values = [reader.expression(item, f"an entry of 'expect.state_space.{key}'", scope) for item in items]
            if all(v is not None for v in values):
                rows.append(tuple(v for v in values if v is not None))
        if len({len(r) for r in rows}) > 1:
            reader.problem(fields[key], f"the rows of 'expect.state_space.{key}' have different lengths", "a matrix: a list of rows of equal length")
            continue
        matrices.append((key, tuple(rows), reader.where(fields[key])))
    return ExpectedStateSpace(tuple(about), tuple(matrices), reader.where(node))


def _exact_number(text: str, number: float) -> sp.Expr:
    """`pi/2` stays exact; a decimal is kept as written."""
    try:
        from lagrange_cli.errors import Span
        from lagrange_cli.expr import Scope, parse_expression

        value = parse_expression(text, Span("", 1, 1, text), Scope({}, {}, sp.Symbol("t"), lambda e: e))
        return value if value.is_number else sp.Float(number)
    except Exception:
        return sp.Float(number)
