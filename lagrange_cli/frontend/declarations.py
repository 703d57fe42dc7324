"""The sections that declare names: `coordinates`, `parameters`, `functions` and their `units`."""

from __future__ import annotations

import sympy as sp
import yaml

from lagrange_cli.errors import Diagnostic
from lagrange_cli.expr import Scope, _closest
from lagrange_cli.frontend.core import NAME, ReaderCore
from lagrange_cli.frontend.source import kind as _kind
from lagrange_cli.model import Parameter
from lagrange_cli.units import UNIT_HELP, UnitError, Units, parse_unit

FUNCTION_KEYS = ("arguments", "definition", "description")
MAX_COORDINATES = 300


class Declarations(ReaderCore):
    """`coordinates`, `parameters`, `functions` (with their definitions) and `units`."""

    def coordinates(self, entries: dict[str, tuple[yaml.Node, yaml.Node]], taken: dict[str, str]) -> tuple[str, ...]:
        if "coordinates" not in entries:
            return ()
        node = entries["coordinates"][1]
        items = self.sequence(node, "'coordinates'")
        if isinstance(node, yaml.SequenceNode) and not items:
            self.problem(node, "'coordinates' is empty", "at least one generalized coordinate")
        if len(items) > MAX_COORDINATES:
            self.problem(node, f"'coordinates' lists {len(items)} coordinates", f"at most {MAX_COORDINATES} (the mass matrix has one entry per pair)")
        names = [self.name(item, "coordinate", taken) for item in items]
        self.spans.update({n: self.span(item) for n, item in zip(names, items, strict=True) if n})
        return tuple(n for n in names if n)

    def parameters(self, entries: dict[str, tuple[yaml.Node, yaml.Node]], taken: dict[str, str]) -> tuple[Parameter, ...]:
        if "parameters" not in entries:
            return ()
        node = entries["parameters"][1]
        if isinstance(node, yaml.SequenceNode):
            names = [self.name(item, "parameter", taken) for item in node.value]
            return tuple(Parameter(sp.Symbol(n), None) for n in names if n)
        result = []
        for key, key_node, value in self.mapping(node, "'parameters'"):
            name = self.name(key_node, "parameter", taken)
            if name is None:
                continue
            if isinstance(value, yaml.MappingNode):
                fields = {k: v for k, _, v in self.mapping(value, f"parameter '{key}'", ("value", "sign", "description"))}
                number = self.number(fields["value"], f"the value of '{key}'") if "value" in fields else None
                sign = self.string(fields.get("sign"), "'sign'") or "positive"
                if sign not in ("positive", "real"):
                    self.problem(fields["sign"], f"sign '{sign}' is not known", "`positive` (the default) or `real`")
                if number is not None and sign == "positive" and number <= 0:
                    self.problem(fields["value"], f"'{key}' is positive by default but its value is {number}", "a positive value, or `sign: real`")
                description = self.string(fields.get("description"), "'description'") or ""
                result.append(Parameter(sp.Symbol(name), number, sign == "real", description))
            elif isinstance(value, yaml.ScalarNode) and value.tag == "tag:yaml.org,2002:null":
                result.append(Parameter(sp.Symbol(name), None))
            else:
                number = self.number(value, f"the value of '{key}'")
                result.append(Parameter(sp.Symbol(name), number, number is not None and number <= 0))
        return tuple(result)

    def functions(
        self, entries: dict[str, tuple[yaml.Node, yaml.Node]], taken: dict[str, str], coordinates: tuple[str, ...], parameters: tuple[Parameter, ...]
    ) -> tuple[tuple[str, ...], dict[str, int], dict[str, sp.Lambda]]:
        """`functions`: a list of names (undefined functions), or a map name -> {arguments, definition,
        description}. Returns the names, the number of arguments of those that state them, and the
        definitions, each `Lambda(arguments, expression)` of its arguments and the parameters."""
        if "functions" not in entries:
            return (), {}, {}
        node = entries["functions"][1]
        if isinstance(node, yaml.SequenceNode):
            listed = [self.name(item, "function", taken) for item in node.value]
            return tuple(n for n in listed if n), {}, {}
        if not isinstance(node, yaml.MappingNode):
            self.problem(node, f"'functions' must be a list or a map, got {_kind(node)}", "a list of names such as `[U]`, or a map such as `{U: {arguments: [s], definition: -k/s}}`")
            return (), {}, {}
        items = self.mapping(node, "'functions'")
        declared = {key for key, _, _ in items}
        names, arities, definitions = [], {}, {}
        for key, key_node, value in items:
            name = self.name(key_node, "function", taken)
            fields = {k: v for k, _, v in self.mapping(value, f"function '{key}'", FUNCTION_KEYS)}
            self.string(fields.get("description"), "'description'")
            if name is None:
                continue
            names.append(name)
            if "arguments" not in fields:
                if isinstance(value, yaml.MappingNode) and "arguments" not in self.near_misses(value, FUNCTION_KEYS):
                    self.problem(value, f"function '{key}' has no 'arguments'", "`arguments:` a list of names, e.g. `[s]`")
                continue
            arguments = self.arguments(fields["arguments"], key, parameters)
            if arguments is None:
                continue
            arities[name] = len(arguments)
            scope = _definition_scope(name, arguments, coordinates, parameters, declared)
            expr = self.expression(fields["definition"], f"the definition of '{key}'", scope) if "definition" in fields else None
            if expr is not None:
                self.sources[f"functions.{name}"] = self.where(fields["definition"])
                definitions[name] = sp.Lambda(tuple(sp.Symbol(a) for a in arguments), expr)
        return tuple(names), arities, definitions

    def arguments(self, node: yaml.Node, function: str, parameters: tuple[Parameter, ...]) -> tuple[str, ...] | None:
        """The argument names of a function: new names, local to its definition (so they may
        repeat a coordinate's name), but not a parameter's, which they would hide there."""
        items = self.sequence(node, f"the arguments of '{function}'")
        if not items:
            if isinstance(node, yaml.SequenceNode):
                self.problem(node, f"function '{function}' has no arguments", "at least one argument name, e.g. `[s]` (a constant belongs under `parameters`)")
            return None
        local: dict[str, str] = {}
        names = [self.name(item, "function argument", local) for item in items]
        if any(n is None for n in names):
            return None
        result = tuple(n for n in names if n)
        hidden = {p.name for p in parameters}
        for item, name in zip(items, result, strict=True):
            if name in hidden:
                self.problem(item, f"argument '{name}' of '{function}' is also a parameter, which it would hide in the definition", "another name for the argument, e.g. `s`")
                return None
        return result

    def units(self, node: yaml.Node | None, entries: dict[str, tuple[yaml.Node, yaml.Node]], coordinates: tuple[str, ...], parameters: tuple[Parameter, ...]) -> Units | None:
        """`units: {name: unit}` for every coordinate, parameter and input (see units.py): a missing
        name, a unit on an undeclared name and an unknown unit are each an error at their place."""
        if node is None:
            return None
        raw = entries["inputs"][1] if "inputs" in entries else None  # read by name only: `inputs` is a list or a map of names
        items = raw.value if isinstance(raw, (yaml.SequenceNode, yaml.MappingNode)) else []
        inputs = [str(getattr(i[0] if isinstance(i, tuple) else i, "value", "")) for i in items]
        declared = [*coordinates, *(p.name for p in parameters), *(i for i in inputs if NAME.match(i))]
        dims, spans, texts = {}, {}, {}
        given = self.mapping(node, "'units'")
        for key, key_node, value in given:
            if key not in declared:
                hint = _closest(key, declared)
                self.problem(
                    key_node, f"'units' gives a unit for '{key}', which is not a coordinate, parameter or input", (f"did you mean '{hint}'? " if hint else "") + "one of " + ", ".join(declared)
                )
                continue
            if not isinstance(value, yaml.ScalarNode) or value.tag in ("tag:yaml.org,2002:null", "tag:yaml.org,2002:bool"):
                self.problem(value, f"the unit of '{key}' must be a unit, got {_kind(value)}", UNIT_HELP)
                continue
            try:
                dims[key] = parse_unit(str(value.value))
            except UnitError as exc:
                offset = len(str(value.value)) - len(str(value.value).lstrip()) + exc.offset
                self.problems.append(Diagnostic(self.locate(value, offset), f"the unit of '{key}': {exc}", UNIT_HELP))
                continue
            spans[key], texts[key] = self.where(value), str(value.value)
        missing = [n for n in declared if n not in {k for k, _, _ in given}]
        if missing and isinstance(node, yaml.MappingNode):
            self.problem(
                entries["units"][0],
                f"'units' has no unit for {', '.join(repr(n) for n in missing)}",
                "a unit for every coordinate, parameter and input (`1` for a dimensionless one), e.g. " + ", ".join(f"`{n}: m`" for n in missing[:2]),
            )
        return Units(dims, spans, texts)


def _definition_scope(function: str, arguments: tuple[str, ...], coordinates: tuple[str, ...], parameters: tuple[Parameter, ...], functions: set[str]) -> Scope:
    """What a function's definition may name: its arguments and the parameters, nothing that
    changes along the motion (coordinates, velocities, `t`) and no declared function."""
    elsewhere = {c: "a coordinate" for c in coordinates if c not in arguments}
    elsewhere |= {f"{c}_dot": "a velocity" for c in coordinates} | {f"{c}_ddot": "an acceleration" for c in coordinates}
    elsewhere |= {f: "a declared function" for f in functions} | {"t": "time"}
    symbols = {p.name: p.symbol for p in parameters} | {a: sp.Symbol(a) for a in arguments}
    what = f"the arguments of '{function}' ({', '.join(arguments)}) or a parameter"
    note = f"a definition depends on nothing else; make it an argument (e.g. `arguments: [{', '.join(arguments)}, tau]` and `{function}(..., t)`)"
    return Scope(symbols, {}, sp.Symbol("t"), lambda e: e, what, elsewhere, note)
