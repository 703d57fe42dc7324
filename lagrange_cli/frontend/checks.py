"""The sections that state what to check or show: `expect`, `symmetries` and `draw`."""

from __future__ import annotations

import sympy as sp
import yaml

from lagrange_cli.errors import Diagnostic, Span
from lagrange_cli.expr import Scope, _closest
from lagrange_cli.frontend.core import ReaderCore
from lagrange_cli.frontend.nodes import Body, Drawing, DrawPoint, Expect, Particle, Symmetry, SystemSpec
from lagrange_cli.frontend.source import kind as _kind
from lagrange_cli.inputs import read_state_space

DRAW_KEYS = ("segments", "trails")
SYMMETRY_KEYS = ("coordinates", "time")
EXPECT_KEYS = ("equations", "accelerations", "momenta", "conserved", "hamiltonian", "hamilton_equations", "state_space")


class Checks(ReaderCore):
    """`expect` (equations, accelerations, momenta, conserved quantities, Hamilton's), `symmetries` and `draw`."""

    def expect(self, node: yaml.Node, spec: SystemSpec, state: Scope) -> Expect:
        fields = {k: v for k, _, v in self.mapping(node, "'expect'", EXPECT_KEYS)}
        multipliers = {f"lambda_{c.name}": sp.Symbol(f"lambda_{c.name}") for c in spec.constraints}
        full = Scope(
            {**state.symbols, **{str(s): s for s in spec.qdd}, **multipliers},
            state.functions,
            state.time,
            state.time_derivative,
            "a coordinate, velocity, acceleration (`<q>_ddot`), parameter, multiplier or `t`",
            arities=state.arities,
        )
        equations = []
        for item in self.sequence(fields["equations"], "'expect.equations'") if "equations" in fields else []:
            expr = self.expression(item, "an expected equation", full, equation=True)
            if expr is not None:
                equations.append((expr, self.text_span(item) if isinstance(item, yaml.ScalarNode) else self.span(item)))
        accelerations = []
        for key, key_node, value in self.mapping(fields["accelerations"], "'expect.accelerations'") if "accelerations" in fields else []:
            coordinate = key.removesuffix("_ddot")
            if not key.endswith("_ddot") or coordinate not in spec.coordinates:
                self.problem(key_node, f"'{key}' is not an acceleration", "one of " + ", ".join(f"{c}_ddot" for c in spec.coordinates))
                continue
            expr = self.expression(value, f"the expected '{key}'", full)
            if expr is not None:
                accelerations.append((coordinate, expr, self.span(value)))
        momenta = []
        for key, key_node, value in self.mapping(fields["momenta"], "'expect.momenta'") if "momenta" in fields else []:
            if key not in spec.coordinates:
                self.problem(key_node, f"'{key}' is not a coordinate", "one of " + ", ".join(spec.coordinates))
                continue
            expr = self.expression(value, f"the expected momentum of '{key}'", state)
            if expr is not None:
                momenta.append((key, expr, self.span(value)))
        conserved, conserved_expressions = self.conserved_expect(fields, spec, state)
        hamiltonian, hamilton_equations = self.hamilton_expect(fields, spec, state)
        state_space = read_state_space(self, fields["state_space"], spec) if "state_space" in fields else None
        return Expect(tuple(equations), tuple(accelerations), tuple(momenta), conserved, hamiltonian, hamilton_equations, state_space, conserved_expressions)

    def conserved_expect(self, fields: dict[str, yaml.Node], spec: SystemSpec, state: Scope) -> tuple[tuple[tuple[str, Span], ...], tuple[tuple[str, sp.Expr | None, Span], ...]]:
        """`expect.conserved`: coordinate names and `energy` (decided symbolically), the names of
        declared symmetries (their Noether charges) and expressions of the state (e.g.
        `m*(x*y_dot - y*x_dot)`), the last two checked to be constant along every motion."""
        names, expressions = [], []
        symmetries = {s.name for s in spec.symmetries}
        expected = "coordinate names, `energy`, names of declared symmetries, or expressions of the coordinates, velocities, parameters and `t`"
        for item in self.sequence(fields["conserved"], "'expect.conserved'") if "conserved" in fields else []:
            name = getattr(item, "value", None)
            if not isinstance(item, yaml.ScalarNode):
                self.problem(item, f"{_kind(item)} is not a coordinate, 'energy', a symmetry or an expression", expected)
            elif name in spec.coordinates or name == "energy":
                names.append((str(name), self.span(item)))
            elif name in symmetries:
                expressions.append((str(name), None, self.span(item)))
            else:
                expr = self.expression(item, "an expected conserved quantity", state)
                if expr is not None:
                    expressions.append((str(name), expr, self.text_span(item)))
        return tuple(names), tuple(expressions)

    def hamilton_expect(self, fields: dict[str, yaml.Node], spec: SystemSpec, state: Scope) -> tuple[tuple[sp.Expr, Span] | None, tuple[tuple[sp.Expr, Span], ...]]:
        """`expect.hamiltonian` (an expression of q, p_<q>, the parameters and t) and
        `expect.hamilton_equations` (a list of equations in <q>_dot, p_<q> and p_<q>_dot). A declared
        name of the form p_<q> (which would mean two things) is an error at the key."""
        from lagrange_cli.hamilton import clashes, momentum_symbols

        keys = [k for k in ("hamiltonian", "hamilton_equations") if k in fields]
        if not keys:
            return None, ()
        clash = clashes(spec.coordinates, [*spec.coordinates, *(str(v) for v in spec.qd), *(p.name for p in spec.parameters), *spec.functions])
        if clash:
            self.problem(
                fields[keys[0]],
                f"'{clash[0]}' is declared in the file, but 'expect.{keys[0]}' names the momentum of '{clash[0][2:].removesuffix('_dot')}' so",
                "no coordinate, parameter or function named p_<coordinate> in a file that uses `hamiltonian` or `hamilton_equations`",
            )
            return None, ()
        p, pd = momentum_symbols(spec.coordinates)
        constants = {s: v for s, v in state.symbols.items() if s not in {str(x) for x in spec.qd}}
        velocities = {str(v): "a velocity" for v in spec.qd}
        accelerations = {str(a): "an acceleration" for a in spec.qdd}
        hamiltonian = None
        if "hamiltonian" in fields:
            scope = Scope(
                {**constants, **{str(x): x for x in p}},
                state.functions,
                state.time,
                state.time_derivative,
                "a coordinate, a momentum (`p_<q>`), a parameter, `t`",
                {**velocities, **accelerations},
                note="H is a function of the coordinates and momenta",
                arities=state.arities,
            )
            node = fields["hamiltonian"]
            expr = self.expression(node, "the expected Hamiltonian", scope)
            if expr is not None:
                hamiltonian = (expr, self.span(node))
        equations = []
        if "hamilton_equations" in fields:
            scope = Scope(
                {**state.symbols, **{str(x): x for x in (*p, *pd)}},
                state.functions,
                state.time,
                state.time_derivative,
                "a coordinate, a velocity (`<q>_dot`), a momentum (`p_<q>`), its rate (`p_<q>_dot`), a parameter, `t`",
                accelerations,
                arities=state.arities,
            )
            for item in self.sequence(fields["hamilton_equations"], "'expect.hamilton_equations'"):
                expr = self.expression(item, "an expected Hamilton equation", scope, equation=True)
                if expr is not None:
                    equations.append((expr, self.text_span(item) if isinstance(item, yaml.ScalarNode) else self.span(item)))
        return hamiltonian, tuple(equations)

    def symmetries(self, node: yaml.Node, coordinates: tuple[str, ...], config: Scope, taken: dict[str, str]) -> tuple[Symmetry, ...]:
        """`symmetries: {name: {coordinates: {q: delta_q, ...}, time: delta_t}}`: each change an
        expression of the coordinates, parameters and `t`; at least one change per symmetry."""
        found = []
        expected = "`{coordinates: {x: -y, y: x}}` (the change of each listed coordinate) and/or `time: 1` (a time shift)"
        for key, key_node, value in self.mapping(node, "'symmetries'"):
            before = len(self.problems)
            name = self.name(key_node, "symmetry", taken)
            if name == "energy":
                self.problem(key_node, "'energy' cannot name a symmetry: `expect: conserved: [energy]` means the energy function", "another name, e.g. `time_shift`")
                name = None
            fields = {k: (kn, v) for k, kn, v in self.mapping(value, f"symmetry '{key}'", SYMMETRY_KEYS)}
            if name is None or not isinstance(value, yaml.MappingNode):
                continue
            changes = []
            if "coordinates" in fields:
                for q, q_node, delta in self.mapping(fields["coordinates"][1], f"'symmetries.{key}.coordinates'"):
                    if q not in coordinates:
                        hint = _closest(q, list(coordinates))
                        self.problem(q_node, f"'{q}' in symmetry '{key}' is not a coordinate", (f"did you mean '{hint}'? " if hint else "") + "one of " + ", ".join(coordinates))
                        continue
                    expr = self.expression(delta, f"the change of '{q}' in symmetry '{key}'", config)
                    if expr is not None:
                        changes.append((q, expr, self.span(delta)))
            time = None
            if "time" in fields:
                time = self.expression(fields["time"][1], f"the change of time in symmetry '{key}'", config)
            if not changes and time is None and len(self.problems) == before:
                self.problem(value, f"symmetry '{key}' changes nothing", expected)
                continue
            found.append(Symmetry(name, tuple(changes), time, self.span(key_node), self.span(fields["time"][1]) if "time" in fields else None))
        return tuple(found)

    def draw(self, node: yaml.Node | None, particles: tuple[Particle, ...], bodies: tuple[Body, ...], config: Scope) -> Drawing | None:
        """`draw: {segments: [[A, B], ...], trails: [A, ...]}`, each point a particle's name, a body's
        name (its centre of mass) or a position list; every point as long as the system's positions."""
        if node is None:
            return None
        fields = {k: v for k, _, v in self.mapping(node, "'draw'", DRAW_KEYS)}
        items: tuple[Particle | Body, ...] = (*particles, *bodies)
        length = next((len(item.position) for item in items), None)
        segments: list[tuple[DrawPoint, DrawPoint]] = []
        for entry in self.sequence(fields["segments"], "'draw.segments'") if "segments" in fields else []:
            if not isinstance(entry, yaml.SequenceNode) or len(entry.value) != 2:
                got = f"{len(entry.value)} item{'s' * (len(entry.value) != 1)}" if isinstance(entry, yaml.SequenceNode) else _kind(entry)
                self.problem(entry, f"a segment of 'draw.segments' must be a pair of points, got {got}", "`[A, B]`, each a particle or body name or a position list such as `[0, 0]`")
                continue
            ends = [self.draw_point(item, particles, bodies, config, length) for item in entry.value]
            if ends[0] is not None and ends[1] is not None:
                segments.append((ends[0], ends[1]))
        trails = [self.draw_point(item, particles, bodies, config, length) for item in (self.sequence(fields["trails"], "'draw.trails'") if "trails" in fields else [])]
        drawn = [*(p for pair in segments for p in pair), *(t for t in trails if t is not None)]
        for point in drawn:  # without particles or bodies, the first point sets the length
            if len(point.position) != len(drawn[0].position):
                self.problems.append(
                    Diagnostic(point.span, f"a point of 'draw' has {len(point.position)} components, but the first one has {len(drawn[0].position)}", "points of one length throughout")
                )
                break
        return Drawing(tuple(segments), tuple(t for t in trails if t is not None))

    def draw_point(self, node: yaml.Node, particles: tuple[Particle, ...], bodies: tuple[Body, ...], config: Scope, length: int | None) -> DrawPoint | None:
        expected = "a particle name (" + (", ".join(p.name for p in particles) or "none declared") + "), a body name (" + (", ".join(b.name for b in bodies) or "none declared") + ")"
        expected += " or a position list such as `[0, 0]`"
        if isinstance(node, yaml.SequenceNode):
            position = self.vector(node, "a point of 'draw'", config, lengths=(length,) if length else (1, 2, 3))
            return DrawPoint("", position, self.span(node)) if position is not None else None
        if not isinstance(node, yaml.ScalarNode) or node.tag != "tag:yaml.org,2002:str":
            self.problem(node, f"a point of 'draw' must be a name or a position list, got {_kind(node)}", expected)
            return None
        name = str(node.value).strip()
        position = self.places.place(node, "a point of 'draw'", config, lengths=(length,) if length else (1, 2, 3))
        return DrawPoint(name, position, self.text_span(node)) if position is not None else None
