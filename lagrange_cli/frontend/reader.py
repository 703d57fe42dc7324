"""The whole file: the top-level keys, then each section by its reader, every problem collected."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import sympy as sp
import yaml

from lagrange_cli.errors import LagrangeError, SpecError
from lagrange_cli.expr import Scope, real_derivative
from lagrange_cli.frontend.checks import Checks
from lagrange_cli.frontend.declarations import Declarations
from lagrange_cli.frontend.mechanics import Mechanics
from lagrange_cli.frontend.nodes import Expect, SystemSpec, time_derivative
from lagrange_cli.frontend.runs import Runs
from lagrange_cli.inputs import check_usage, read_inputs, read_outputs
from lagrange_cli.rigid import Places

TOP_KEYS = (
    "title", "description", "coordinates", "parameters", "functions", "gravity", "particles",
    "bodies", "kinetic", "potential", "lagrangian", "dissipation", "forces", "constraints",
    "eliminate", "initial", "simulate", "exact", "expect", "draw", "inputs", "outputs", "symmetries", "units",
)  # fmt: skip


class Reader(Declarations, Mechanics, Runs, Checks):
    """Reads a composed system file into a `SystemSpec`."""

    def read(self, root: yaml.Node) -> SystemSpec:
        self.check_tags(root)
        if self.problems:
            raise SpecError(self.problems)
        entries = {key: (key_node, value) for key, key_node, value in self.mapping(root, "the system file", TOP_KEYS)}
        if "coordinates" not in entries and isinstance(root, yaml.MappingNode):
            self.problem(root, "missing required key 'coordinates'", "`coordinates: [q1, q2, ...]`, the generalized coordinates")
        taken: dict[str, str] = {}

        coordinates = self.coordinates(entries, taken)
        parameters = self.parameters(entries, taken)
        functions, arities, definitions = self.functions(entries, taken, coordinates, parameters)
        inputs = read_inputs(self, entries["inputs"][1] if "inputs" in entries else None, taken)
        signals = {i.name: i.symbol for i in inputs}
        q = tuple(sp.Symbol(c) for c in coordinates)
        qd = tuple(sp.Symbol(f"{c}_dot") for c in coordinates)
        qdd = tuple(sp.Symbol(f"{c}_ddot") for c in coordinates)
        t = sp.Symbol("t")
        undefined = {f: sp.Function(f) for f in functions}

        def ddt(expr: sp.Expr) -> sp.Expr:
            if signals and expr.free_symbols & set(signals.values()):
                raise LagrangeError(
                    f"the time derivative of an expression holding an input ({', '.join(sorted(str(u) for u in expr.free_symbols & set(signals.values())))}) would need u_dot, and inputs are not differentiated"
                )

            def total(e: sp.Expr, real: Mapping[sp.Symbol, sp.Symbol]) -> sp.Expr:
                rq, rqd, rqdd = (tuple(real.get(s, s) for s in v) for v in (q, qd, qdd))
                return time_derivative(e, rq, rqd, rqdd, real.get(t, t))

            return real_derivative(expr, total)

        names = {str(s): s for s in (*q, *qd, *(p.symbol for p in parameters))} | signals
        velocities = {str(s): "a velocity" for s in qd}
        accelerations = {str(s): "an acceleration" for s in qdd}
        state = Scope(names, undefined, t, ddt, "a coordinate, a velocity (`<q>_dot`), a parameter, `t`", accelerations, arities=arities)
        config = Scope({str(s): s for s in (*q, *(p.symbol for p in parameters))} | signals, undefined, t, ddt, "a coordinate, a parameter, `t`", {**velocities, **accelerations}, arities=arities)
        constants = Scope(
            {p.name: p.symbol for p in parameters},
            undefined,
            t,
            ddt,
            "a parameter, `t`",
            {**{c: "a coordinate" for c in coordinates}, **velocities, **accelerations, **dict.fromkeys(signals, "an input")},
            arities=arities,
        )
        potential_scope = dataclasses.replace(config, note="velocity-dependent terms belong under `lagrangian`")

        def value(key: str) -> yaml.Node | None:
            return entries[key][1] if key in entries else None

        def expr(key: str, scope: Scope) -> sp.Expr:
            node = value(key)
            if node is not None:
                self.sources[key] = self.where(node)
            return (self.expression(node, f"'{key}'", scope) if node is not None else None) or sp.Integer(0)

        gravity_node = value("gravity")
        gravity = self.vector(gravity_node, "'gravity'", constants) if gravity_node is not None else None
        if gravity_node is not None:
            self.sources["gravity"] = self.where(gravity_node)
        self.places = Places(self, value("particles"), value("bodies"), config, state, constants, {p.symbol: p.value for p in parameters if p.value is not None})
        particles = self.particles(value("particles"), config, state, constants)
        bodies = self.bodies(value("bodies"), config, state, constants)
        self.check_dimensions(gravity, particles, bodies, value)
        potential = expr("potential", potential_scope)
        spec = SystemSpec(
            path=self.filename,
            title=self.string(value("title"), "'title'") or Path(self.filename).stem.replace("_", " ").capitalize(),
            description=self.string(value("description"), "'description'") or "",
            coordinates=coordinates,
            spans=self.spans,
            sources=self.sources,
            q=q,
            qd=qd,
            qdd=qdd,
            t=t,
            parameters=parameters,
            functions=functions,
            definitions=definitions,
            gravity=gravity,
            particles=particles,
            bodies=bodies,
            kinetic=expr("kinetic", state),
            potential=potential,
            lagrangian=expr("lagrangian", state),
            dissipation=expr("dissipation", state),
            generalized_forces=self.forces(value("forces"), coordinates, state),
            constraints=self.constraints(value("constraints"), state, qd, taken),
            eliminate=self.eliminate(value("eliminate"), coordinates),
            initial=self.initial(value("initial"), coordinates),
            simulate=self.simulate(value("simulate")),
            exact=self.exact(value("exact"), coordinates, constants),
            expect=Expect(),
            draw=self.draw(value("draw"), particles, bodies, config),
            units=self.units(value("units"), entries, coordinates, parameters),
        )
        if inputs or "outputs" in entries:
            spec = _replace(spec, inputs=inputs, outputs=read_outputs(self, value("outputs"), state, taken))
            check_usage(self, spec)
        symmetries_node = value("symmetries")
        if symmetries_node is not None:
            spec = _replace(spec, symmetries=self.symmetries(symmetries_node, coordinates, config, taken))
        expect_node = value("expect")
        if expect_node is not None:
            spec = _replace(spec, expect=self.expect(expect_node, spec, state))
        if spec.eliminate and not spec.constraints:
            self.problem(value("eliminate"), "'eliminate' given but there are no constraints", "a holonomic constraint under `constraints` for each eliminated coordinate")
        if self.problems:
            raise SpecError(sorted(self.problems, key=lambda d: (d.span.line, d.span.column) if d.span else (0, 0)))
        return spec


def _replace(spec: SystemSpec, **changes: Any) -> SystemSpec:
    return dataclasses.replace(spec, **changes)
