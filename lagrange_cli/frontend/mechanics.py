"""The sections that make the mechanics: `particles`, `bodies` (read by rigid.Places), `gravity`'s
length, generalized `forces`, `constraints` and the coordinates to `eliminate`."""

from __future__ import annotations

import keyword
from collections.abc import Callable

import sympy as sp
import yaml

from lagrange_cli.errors import Span
from lagrange_cli.expr import Scope, _closest
from lagrange_cli.frontend.core import NAME, ReaderCore
from lagrange_cli.frontend.nodes import Body, Constraint, Particle
from lagrange_cli.frontend.source import kind as _kind

PARTICLE_KEYS = ("mass", "position", "force", "damping")


class Mechanics(ReaderCore):
    """`particles`, `bodies`, `forces`, `constraints` and `eliminate`."""

    def particles(self, node: yaml.Node | None, config: Scope, state: Scope, constants: Scope) -> tuple[Particle, ...]:
        if node is None:
            return ()
        result = []
        for name, _, value in self.mapping(node, "'particles'"):
            fields = {k: v for k, _, v in self.mapping(value, f"particle '{name}'", PARTICLE_KEYS)}
            for required in ("mass", "position"):
                if required not in fields and isinstance(value, yaml.MappingNode) and required not in self.near_misses(value, PARTICLE_KEYS):
                    self.problem(value, f"particle '{name}' has no '{required}'", f"`{required}:` " + ("an expression" if required == "mass" else "a list of 1 to 3 components"))
            mass = self.expression(fields["mass"], f"the mass of '{name}'", constants) if "mass" in fields else None
            position = self.places.particle(name, fields["position"]) if "position" in fields else None
            force = self.vector(fields["force"], f"the force on '{name}'", state) if "force" in fields else None
            damping = self.expression(fields["damping"], f"the damping of '{name}'", constants) if "damping" in fields else None
            if mass is not None and position is not None:
                if force is not None and len(force) != len(position):
                    self.problem(fields["force"], f"the force on '{name}' has {len(force)} components but its position has {len(position)}", f"{len(position)} components")
                    continue
                result.append(Particle(name, mass, position, force, damping, {k: self.where(v) for k, v in fields.items()}))
        return tuple(result)

    def bodies(self, node: yaml.Node | None, config: Scope, state: Scope, constants: Scope) -> tuple[Body, ...]:
        """Each body, read by `rigid.Places` (on demand, so that pivots, positions and `relative_to` may
        refer to bodies and particles anywhere in the file)."""
        if node is None:
            return ()
        result = []
        for name, _, _ in self.mapping(node, "'bodies'"):
            body = self.places.body(name)
            if body is not None:
                result.append(body)
        return tuple(result)

    def scalar_or_triple(self, node: yaml.Node, what: str, scope: Scope) -> tuple[sp.Expr, ...] | None:
        if isinstance(node, yaml.SequenceNode):
            return self.vector(node, what, scope, lengths=(3,))
        value = self.expression(node, what, scope)
        return None if value is None else (value,)

    def check_dimensions(self, gravity: tuple[sp.Expr, ...] | None, particles: tuple[Particle, ...], bodies: tuple[Body, ...], value: Callable[[str], yaml.Node | None]) -> None:
        if gravity is None:
            return
        items: tuple[Particle | Body, ...] = (*particles, *bodies)
        for item in items:
            if len(item.position) != len(gravity):
                self.problem(value("gravity"), f"'gravity' has {len(gravity)} components but the position of '{item.name}' has {len(item.position)}", "vectors of one length throughout the file")
                return

    def forces(self, node: yaml.Node | None, coordinates: tuple[str, ...], state: Scope) -> tuple[sp.Expr, ...]:
        forces = [sp.Integer(0)] * len(coordinates)
        if node is None:
            return ()
        for _, _, value in self.mapping(node, "'forces'", ("generalized",)):
            for coordinate, key_node, force in self.mapping(value, "'forces.generalized'"):
                if coordinate not in coordinates:
                    hint = _closest(coordinate, list(coordinates))
                    self.problem(key_node, f"'{coordinate}' is not a coordinate", "one of " + ", ".join(coordinates) + (f"; did you mean '{hint}'?" if hint else ""))
                    continue
                expr = self.expression(force, f"the generalized force on '{coordinate}'", state)
                self.sources[f"forces.{coordinate}"] = self.where(force)
                if expr is not None:
                    forces[coordinates.index(coordinate)] = expr
        return tuple(forces)

    def constraints(self, node: yaml.Node | None, state: Scope, qd: tuple[sp.Symbol, ...], taken: dict[str, str]) -> tuple[Constraint, ...]:
        if node is None:
            return ()
        result = []
        for name, key_node, value in self.mapping(node, "'constraints'"):
            if not NAME.match(name) or keyword.iskeyword(name):
                self.problem(key_node, f"'{name}' is not a valid constraint name", "letters, digits and _")
                continue
            multiplier = f"lambda_{name}"
            if multiplier in taken:
                self.problem(key_node, f"the multiplier '{multiplier}' of this constraint clashes with a {taken[multiplier]}", "another constraint name")
                continue
            expr = self.expression(value, f"constraint '{name}'", state, equation=True)
            if expr is None:
                continue
            span = self.text_span(value) if isinstance(value, yaml.ScalarNode) else self.span(value)
            velocities = [v for v in qd if expr.has(v)]
            if velocities and any(sp.diff(expr, a, b) != 0 for a in velocities for b in velocities):
                self.problem(value, f"constraint '{name}' is not linear in the velocities", "a holonomic constraint f(q, t) = 0 or a velocity constraint linear in the velocities")
                continue
            if expr == 0:
                self.problem(value, f"constraint '{name}' is always satisfied", "an equation relating the coordinates")
                continue
            result.append(Constraint(name, expr, not velocities, span))
        return tuple(result)

    def eliminate(self, node: yaml.Node | None, coordinates: tuple[str, ...]) -> tuple[tuple[str, Span], ...]:
        if node is None:
            return ()
        result: list[tuple[str, Span]] = []
        for item in self.sequence(node, "'eliminate'"):
            if not isinstance(item, yaml.ScalarNode):
                self.problem(item, f"an entry of 'eliminate' must be a coordinate name, got {_kind(item)}", "one of " + ", ".join(coordinates))
                continue
            if item.value not in coordinates:
                hint = _closest(str(item.value), list(coordinates))
                self.problem(item, f"'{item.value}' is not a coordinate", "one of " + ", ".join(coordinates) + (f"; did you mean '{hint}'?" if hint else ""))
                continue
            earlier = next((span for name, span in result if name == item.value), None)
            if earlier is not None:
                self.problem(item, f"'{item.value}' is listed twice in 'eliminate' (first at line {earlier.line}, column {earlier.column})", "each coordinate once")
                continue
            result.append((str(item.value), self.span(item)))
        if coordinates and len(result) == len(coordinates):
            self.problem(
                node.value[-1] if isinstance(node, yaml.SequenceNode) else node,
                "'eliminate' lists every coordinate, which would leave no equation of motion",
                "keep at least one coordinate: eliminate one coordinate per holonomic constraint, fewer than there are coordinates",
            )
            return ()
        return tuple(result)
