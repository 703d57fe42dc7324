"""Reading bodies and point references (FORMAT.md version 2: orientation, full inertia, pivot, center,
points, force and torque loads), for the frontend's `Reader` (frontend/reader.py).

Bodies are read on demand (`Places.body`), so that a pivot, a position or a `relative_to` may name any
other body or particle whatever the order of the file; the names being read form a stack, and a name
met again on it is a cycle, reported at the reference that closes it. Every rotation and position is a
plain sympy construction (`kinematics`): nothing is simplified here.
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import sympy as sp
import yaml

from lagrange_cli import kinematics as kin
from lagrange_cli.expr import Scope, _closest, numeric_value

if TYPE_CHECKING:
    from lagrange_cli.frontend.nodes import Body
    from lagrange_cli.frontend.reader import Reader as _Reader

BODY_KEYS = ("mass", "position", "inertia", "angular_velocity", "orientation", "pivot", "center", "points", "force", "torque")
ORIENTATION_KEYS = ("axis", "angle", "sequence", "angles", "kind", "matrix", "relative_to")
LOAD_KEYS = ("vector", "axes", "at")
ROTATION_TOLERANCE = 1e-9
PSD_TOLERANCE = 1e-12
SAMPLES = 3

Vec = tuple[sp.Expr, ...]


class Places:
    """The file's particles and bodies by name, read on demand, and point references resolved against them."""

    def __init__(self, reader: _Reader, particles: yaml.Node | None, bodies: yaml.Node | None, config: Scope, state: Scope, constants: Scope, parameters: Mapping[sp.Symbol, float]) -> None:
        self.reader = reader
        self.config, self.state, self.constants = config, state, constants
        self.values = dict(parameters)
        self.particle_nodes: dict[str, yaml.Node] = {}
        self.body_nodes: dict[str, yaml.Node] = {}
        if isinstance(particles, yaml.MappingNode):
            for key, value in particles.value:
                if isinstance(key, yaml.ScalarNode) and isinstance(value, yaml.MappingNode):
                    position = next((v for k, v in value.value if isinstance(k, yaml.ScalarNode) and k.value == "position"), None)
                    if position is not None:
                        self.particle_nodes.setdefault(str(key.value), position)
        particle_names = {str(k.value) for k, _ in particles.value if isinstance(k, yaml.ScalarNode)} if isinstance(particles, yaml.MappingNode) else set()
        if isinstance(bodies, yaml.MappingNode):
            for key, value in bodies.value:
                if isinstance(key, yaml.ScalarNode):
                    if str(key.value) in particle_names:  # `BODY` and a particle's name are both point references, and both name a carrier
                        reader.problem(
                            key,
                            f"body '{key.value}' has the name of a particle",
                            "a name used by one particle or body only (point references, constraint forces and drawings name particles and bodies alike)",
                        )
                    if "." in str(key.value) or not str(key.value).strip():
                        reader.problem(key, f"'{key.value}' cannot name a body: a point reference `BODY.POINT` splits at the first '.'", "a name of letters, digits and '_' (no '.')")
                    self.body_nodes.setdefault(str(key.value), value)
        self.positions: dict[str, Vec | None] = {}
        self.bodies: dict[str, Body | None] = {}
        self.reading: list[str] = []
        self.frames: dict[int, tuple[str, Vec]] = {}
        """By the identity of a body's centre or point (a world position): the body and the point's velocity in its axes."""
        self.point_velocities: dict[str, dict[str, Vec]] = {}
        self.offsets: dict[int, tuple[str, Vec]] = {}
        """By the identity of a body's centre or point: the body and the point from its centre of mass, in its axes."""

    # -- names --------------------------------------------------------------------------------

    def enter(self, name: str, node: yaml.Node) -> bool:
        """Start reading `name`; False (and a cycle reported at `node`) if it is being read already."""
        if name in self.reading:
            loop = " -> ".join([*self.reading[self.reading.index(name) :], name])
            self.reader.problem(node, f"point references and 'relative_to' form a cycle: {loop}", "references that end at positions written as lists (a chain, not a loop)")
            return False
        self.reading.append(name)
        return True

    def particle(self, name: str, node: yaml.Node) -> Vec | None:
        """A particle's position (its list, or the point it refers to)."""
        if name not in self.positions:
            if not self.enter(name, node):
                return None
            try:
                self.positions[name] = self.place(self.particle_nodes[name], f"the position of '{name}'", self.config)
            finally:
                self.reading.pop()
        return self.positions[name]

    def body(self, name: str, node: yaml.Node | None = None) -> Body | None:
        if name not in self.bodies:
            if not self.enter(name, node if node is not None else self.body_nodes[name]):
                return None
            try:
                self.bodies[name] = self.read_body(name, self.body_nodes[name])
            finally:
                self.reading.pop()
        return self.bodies[name]

    def place(self, node: yaml.Node, what: str, scope: Scope, lengths: tuple[int, ...] = (1, 2, 3)) -> Vec | None:
        """A position list, or a point reference (`BODY.POINT`, `BODY`, a particle's name)."""
        if isinstance(node, yaml.ScalarNode) and node.tag == "tag:yaml.org,2002:str":
            found = self.reference(node, " in 'draw'" if "'draw'" in what else f" ({what})")
            if found is not None and len(found) not in lengths:
                self.reader.problem(node, f"{what} refers to '{node.value}', which has {len(found)} components", f"a point with {' or '.join(map(str, lengths))} components")
                return None
            return found
        return self.reader.vector(node, what, scope, lengths)

    def reference(self, node: yaml.ScalarNode, where: str = "") -> Vec | None:
        text = str(node.value).strip()
        body, dot, point = text.partition(".")
        known = [*self.particle_nodes, *self.body_nodes]
        expected = "a particle's name, a body's name (its centre of mass), `BODY.POINT` for a point under a body's `points`, or a position list"
        if dot:
            if body not in self.body_nodes:
                hint = _closest(body, list(self.body_nodes))
                self.reader.problem(node, f"unknown point '{text}'{where}: there is no body '{body}'", (f"did you mean '{hint}.{point}'? " if hint else "") + expected)
                return None
            found = self.body(body, node)
            if found is None:
                return None
            if point not in found.points:
                names = ", ".join(found.points) or "none declared"
                hint = _closest(point, list(found.points))
                self.reader.problem(node, f"unknown point '{text}'{where}: body '{body}' has no point '{point}'", (f"did you mean '{body}.{hint}'? " if hint else "") + f"one of its points ({names})")
                return None
            return found.points[point]
        if text in self.body_nodes:
            found = self.body(text, node)
            return None if found is None else found.position
        if text in self.particle_nodes:
            return self.particle(text, node)
        hint = _closest(text, known)
        self.reader.problem(node, f"unknown point '{text}'{where}", (f"did you mean '{hint}'? " if hint else "") + expected)
        return None

    def fixed(self, node: yaml.Node, what: str, dim: int) -> Vec | None:
        """A point fixed in a body (its `center` or one of its `points`), in body axes: numbers and parameters.
        Its velocity is taken as v_reference + omega x p, so a `t` in it (a point sliding in the body) is refused."""
        value = self.reader.vector(node, what, self.constants, (dim,))
        if value is not None and self.varying(value):
            self.reader.problem(
                node,
                f"{what} depends on time `t`, but it is fixed in the body (its velocity is that of the body's reference point plus omega x p)",
                "numbers and parameters; a point that moves in the body is a particle with its own `position`",
            )
            return None
        return value

    def varying(self, value: Any) -> str:
        """'' when `value` (an expression or a tuple of them) holds no coordinate and no time, else what it holds."""
        if value is None:
            return ""
        free = set().union(*(sp.sympify(e).free_symbols for e in (value if isinstance(value, tuple) else (value,))))
        names = sorted(str(x) for x in free if self.constants.elsewhere.get(str(x)) == "a coordinate")
        if names:
            return f"the coordinate '{names[0]}'"
        return "time `t`" if self.config.time in free else ""

    def holds_input(self, exprs: Any, node: yaml.Node, what: str) -> bool:
        """Whether `exprs`, which this module is about to differentiate (angles, matrices, the positions of
        reference points), hold an input; if so the problem is recorded at `node`: every derivative taken
        here is guarded by this, so an input where the equations would need its u_dot is reported at its
        line and column, not as a bare error from inside the derivative."""
        from lagrange_cli.inputs import U_DOT, WHERE

        free = set().union(*(sp.sympify(e).free_symbols for e in exprs)) if exprs else set()
        signals = sorted(str(s) for s in free if self.constants.elsewhere.get(str(s)) == "an input")
        if signals:
            self.reader.problem(node, f"input '{signals[0]}' appears in {what}, whose time derivative the equations would need", f"inputs in {WHERE} only; {U_DOT}")
        return bool(signals)

    # -- a body -------------------------------------------------------------------------------

    def read_body(self, name: str, value: yaml.Node) -> Body | None:
        from lagrange_cli.frontend.nodes import Body

        r = self.reader
        fields = {k: v for k, _, v in r.mapping(value, f"body '{name}'", BODY_KEYS)}
        if not isinstance(value, yaml.MappingNode):
            return None
        oriented = "orientation" in fields
        needed = ["mass", "inertia", *([] if oriented else ["angular_velocity"]), *([] if "pivot" in fields else ["position"])]
        absent = [k for k in needed if k not in fields]
        misspelt = r.near_misses(value, BODY_KEYS)
        missing = [k for k in absent if k not in misspelt]
        if missing:
            r.problem(value, f"body '{name}' has no {', '.join(repr(m) for m in missing)}", "mass, position, inertia and angular_velocity (or `orientation` instead of angular_velocity)")
        if absent:
            return None
        ok = True
        if oriented and "angular_velocity" in fields:
            r.problem(fields["angular_velocity"], f"body '{name}' gives both 'angular_velocity' and 'orientation'", "one of them: with `orientation` the tool computes the angular velocity")
            ok = False
        for key in ("pivot", "center", "points"):
            if key in fields and not oriented:
                r.problem(
                    fields[key],
                    f"'{key}' of body '{name}' needs an 'orientation' (a body without one has no axes to measure it in)",
                    "`orientation:` an axis and angle, a sequence, a matrix, or `{angle: EXPR}` for a planar body",
                )
                ok = False
        if "pivot" in fields and "position" in fields:
            r.problem(fields["position"], f"body '{name}' has a 'pivot', so its centre of mass is given by 'center' (body axes, from the pivot), not 'position'", "`center:` instead of `position:`")
            ok = False
        if "center" in fields and "pivot" not in fields and oriented:
            r.problem(
                fields["center"],
                f"'center' of body '{name}' is measured from its 'pivot', which is not given",
                "`pivot:` (a position list or a point reference) beside `center:`, or `position:` alone",
            )
            ok = False
        mass = r.expression(fields["mass"], f"the mass of '{name}'", self.constants)
        inertia = self.inertia(fields["inertia"], name)
        if oriented:  # a rigid body: Kane's form (derive.oriented_bodies) takes m and I constant, as they are
            for key, held in (("mass", mass), ("inertia", inertia)):
                varying = self.varying(held)
                if varying:
                    r.problem(
                        fields[key],
                        f"the {key} of '{name}' depends on {varying}, but a body with an 'orientation' is rigid: its {key} is constant",
                        "numbers and parameters; a body whose mass or inertia changes can be written with `angular_velocity` (and its kinetic energy is then differentiated as written)",
                    )
                    ok = False
        if not ok or mass is None or inertia is None:
            return None
        spans = {k: r.where(v) for k, v in fields.items()}
        if not oriented:
            return self.plain_body(name, fields, mass, inertia, spans)
        dim = 2 if len(inertia) == 1 else 3
        orientation = self.orientation(fields["orientation"], name, dim)
        if orientation is None:
            return None
        rotation, omega, local, parent = orientation
        center: Vec | None = (sp.Integer(0),) * dim
        if "pivot" in fields:
            anchor = reference = self.place(fields["pivot"], f"the pivot of '{name}'", self.config, (dim,))
            if "center" in fields:
                center = self.fixed(fields["center"], f"the centre of mass of '{name}'", dim)
            if reference is None or center is None:
                return None
            position = _add(reference, kin.matvec(rotation, center))
        else:
            anchor = self.place(fields["position"], f"the position of '{name}'", self.config, (dim,))
            if anchor is None:
                return None
            reference = position = tuple(list(anchor))  # its own object: `frames` keys points by identity
        assert anchor is not None and center is not None
        moving = self.reference_velocity(anchor, rotation, local, parent, fields["pivot" if "pivot" in fields else "position"], name)
        if moving is None:
            return None
        velocity = _add(moving, _cross(omega, center))
        self.frames[id(position)] = (name, velocity)
        self.offsets[id(position)] = (name, (sp.Integer(0),) * dim)
        points: dict[str, Vec] = {}
        point_velocities: dict[str, Vec] = {}
        if "points" in fields:
            for point, key_node, node in r.mapping(fields["points"], f"'points' of body '{name}'"):
                if "." in point or not point.strip():
                    r.problem(key_node, f"'{point}' cannot name a point of '{name}': a point reference `BODY.POINT` splits at the '.'", "a name of letters, digits and '_' (no '.')")
                    ok = False
                    continue
                offset = self.fixed(node, f"point '{point}' of '{name}'", dim)
                if offset is None:
                    ok = False
                else:
                    points[point] = _add(reference, kin.matvec(rotation, offset))
                    point_velocities[point] = _add(moving, _cross(omega, offset))
                    self.frames[id(points[point])] = (name, point_velocities[point])
                    self.offsets[id(points[point])] = (name, tuple(o - c for o, c in zip(offset, center, strict=True)))
        attached = self.offsets.get(id(anchor)) if "pivot" in fields else None
        hinge: tuple[str | None, Vec, Vec] | None = None
        if attached is not None and parent is not None and attached[0] == parent:
            hinge = (parent, attached[1], center)
        elif "pivot" in fields and parent is None and id(anchor) not in self.frames and all(self.config.time_derivative(x) == 0 for x in anchor):
            hinge = (None, (sp.Integer(0),) * dim, center)  # a fixed pivot
        if not ok:
            return None
        body = Body(name, mass, position, inertia, omega, spans, rotation=rotation, points=points, local=local, parent=parent, velocity=velocity, anchor=hinge)
        self.point_velocities[name] = point_velocities
        return self.loads(body, fields)

    def reference_velocity(self, reference: Vec, rotation: kin.Matrix, local: kin.Matrix, parent: str | None, node: yaml.Node, name: str) -> Vec | None:
        """The velocity of a body's reference point in its own axes: carried over from the body whose point
        it is (through the rotation relative to that body when it is the parent), else R^T dx/dt of the world position."""
        zero = sp.Integer(0)
        found = self.frames.get(id(reference))
        if found is not None:
            owner, velocity = found
            if owner == parent:
                return kin.matvec(kin.transpose(local), velocity)
            owner_body = self.bodies.get(owner)
            if owner_body is not None and owner_body.rotation is not None:
                return kin.matvec(kin.transpose(rotation), kin.matvec(owner_body.rotation, velocity))
        if self.holds_input(reference, node, f"the position of the reference point of '{name}'"):
            return None
        rate = tuple(self.config.time_derivative(x) for x in reference)
        if all(v == 0 for v in rate):
            return (zero,) * len(reference)
        return kin.matvec(kin.transpose(rotation), rate)

    def plain_body(self, name: str, fields: dict[str, yaml.Node], mass: sp.Expr, inertia: Vec, spans: dict[str, Any]) -> Body | None:
        """A body without orientation (version 1), which may still take loads at its centre of mass."""
        from lagrange_cli.frontend.nodes import Body

        r = self.reader
        position = self.place(fields["position"], f"the position of '{name}'", self.config)
        omega = r.scalar_or_triple(fields["angular_velocity"], f"the angular velocity of '{name}'", self.state)
        if position is None or omega is None:
            return None
        if len(omega) != (3 if len(inertia) == 9 else len(inertia)):
            r.problem(fields["angular_velocity"], f"body '{name}': inertia has {len(inertia)} component(s) but angular_velocity has {len(omega)}", "both scalars (planar) or both 3-lists (spatial)")
            return None
        return self.loads(Body(name, mass, position, inertia, omega, spans), fields)

    def inertia(self, node: yaml.Node, name: str) -> Vec | None:
        """A scalar, a list of 3 (principal moments) or a symmetric 3x3 matrix (9 entries, row by row),
        positive semi-definite at the default parameters (coordinates at 0)."""
        r = self.reader
        what = f"the inertia of '{name}'"
        if not (isinstance(node, yaml.SequenceNode) and node.value and all(isinstance(item, yaml.SequenceNode) for item in node.value)):
            return r.scalar_or_triple(node, what, self.config)
        if len(node.value) != 3:
            r.problem(node, f"{what} has {len(node.value)} rows", "a 3x3 matrix `[[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]]`")
            return None
        rows = [r.vector(row, f"a row of {what}", self.config, (3,)) for row in node.value]
        if any(row is None for row in rows):
            return None
        matrix = [list(row) for row in rows if row is not None]
        for i in range(3):
            for j in range(i + 1, 3):
                if sp.expand(matrix[i][j] - matrix[j][i]) != 0:
                    r.problem(
                        node.value[j].value[i],
                        f"{what} is not symmetric: entry ({j + 1}, {i + 1}) is {matrix[j][i]} but entry ({i + 1}, {j + 1}) is {matrix[i][j]}",
                        "a symmetric matrix (I_ji = I_ij)",
                    )
                    return None
        values = self.sample(matrix, random_coordinates=False)
        if values is not None:
            scale = max(abs(v) for row in values for v in row) or 1.0
            minors = [values[i][i] / scale for i in range(3)]
            minors += [(values[i][i] * values[j][j] - values[i][j] ** 2) / scale**2 for i in range(3) for j in range(i + 1, 3)]
            worst = min([*minors, _det(values) / scale**3])
            if worst < -PSD_TOLERANCE:
                shown = "[" + ", ".join("[" + ", ".join(f"{v:.6g}" for v in row) + "]" for row in values) + "]"
                r.problem(node, f"{what} is not positive semi-definite at the default parameters (it is {shown} there)", "an inertia tensor about the centre of mass: all its principal minors >= 0")
                return None
        return tuple(e for row in matrix for e in row)

    def sample(self, matrix: list[list[sp.Expr]], random_coordinates: bool, seed: int = 0) -> list[list[float]] | None:
        """The entries at the default parameters (1 where none is given) and coordinates at 0 (or random values
        in [-pi, pi]), t at 0; None when some entry has no value there (an undefined function)."""
        rng = random.Random(seed)
        values: dict[sp.Basic, float] = {}
        for row in matrix:
            for e in row:
                for s in e.free_symbols:
                    if s not in values:
                        values[s] = self.values.get(s) or (rng.uniform(-math.pi, math.pi) if random_coordinates else 0.0)
        try:
            return [[numeric_value(e, values) for e in row] for row in matrix]
        except (OverflowError, ValueError, ZeroDivisionError, TypeError):
            return None

    # -- orientation --------------------------------------------------------------------------

    def orientation(self, node: yaml.Node, name: str, dim: int) -> tuple[kin.Matrix, Vec, kin.Matrix, str | None] | None:
        """(world rotation, body-axes angular velocity (planar: omega_z alone), rotation relative to the parent,
        the parent's name or None) of body `name`."""
        r = self.reader
        what = f"the orientation of '{name}'"
        fields = {k: v for k, _, v in r.mapping(node, what, ORIENTATION_KEYS)}
        if not isinstance(node, yaml.MappingNode):
            return None
        forms: list[str] = [k for k in ("axis", "sequence", "matrix") if k in fields]
        expected = "`{axis: [x, y, z], angle: EXPR}`, `{sequence: ZYX, angles: [a1, a2, a3], kind: body}` or `{matrix: [[...], [...], [...]]}`"
        if dim == 2:
            expected = "`{angle: EXPR}` (a rotation about z) for a planar body (scalar inertia)"
            if forms or "angles" in fields or "kind" in fields:
                key = (forms or [k for k in ("angles", "kind") if k in fields])[0]
                r.problem(fields[key], f"body '{name}' is planar (scalar inertia), so {what} is a rotation about z", expected)
                return None
            if "angle" not in fields:
                r.problem(node, f"{what} has no 'angle'", expected)
                return None
            angle = r.expression(fields["angle"], f"the angle of '{name}'", self.config)
            if angle is None:
                return None
            if self.holds_input([angle], fields["angle"], f"the angle of '{name}'"):
                return None
            local, rate = kin.planar(angle), (self.config.time_derivative(angle),)
        else:
            if len(forms) != 1:
                if len(forms) > 1:
                    r.problem(fields[forms[1]], f"{what} gives both '{forms[0]}' and '{forms[1]}'", "one of " + expected)
                elif "angle" in fields:
                    r.problem(
                        node, f"{what} has 'angle' but no 'axis' (a spatial body: its inertia is a list or a matrix)", expected + "; `{angle: EXPR}` alone is for a planar body with a scalar inertia"
                    )
                else:
                    r.problem(node, f"{what} has none of 'axis', 'sequence', 'matrix'", expected)
                return None
            found = {"axis": self.axis_angle, "sequence": self.sequence, "matrix": self.matrix}[forms[0]](fields, node, name)
            if found is None:
                return None
            local, rate = found
        if "relative_to" not in fields:
            return local, rate, local, None
        parent_node = fields["relative_to"]
        parent_name = r.string(parent_node, f"'relative_to' of '{name}'")
        if parent_name is None:
            return None
        if parent_name not in self.body_nodes:
            hint = _closest(parent_name, list(self.body_nodes))
            r.problem(parent_node, f"'relative_to' names '{parent_name}', which is not a body", (f"did you mean '{hint}'? " if hint else "") + "the name of another body with an `orientation`")
            return None
        parent = self.body(parent_name, parent_node)
        if parent is None:
            return None
        if parent.rotation is None or len(parent.rotation) != dim:
            r.problem(
                parent_node,
                f"'relative_to' names '{parent_name}', which has no {'planar ' if dim == 2 else 'spatial '}orientation",
                "another body with an `orientation` of the same kind (planar or spatial)",
            )
            return None
        rotation = kin.matmul(parent.rotation, local)
        if dim == 2:
            return rotation, (parent.angular_velocity[0] + rate[0],), local, parent_name
        return rotation, _add(kin.matvec(kin.transpose(local), parent.angular_velocity), rate), local, parent_name

    def constant_vector(self, node: yaml.Node, what: str) -> Vec | None:
        value = self.reader.vector(node, what, self.constants, (3,))
        if value is not None and any(e.has(self.config.time) for e in value):
            self.reader.problem(node, f"{what} depends on time", "a constant vector (numbers and parameters)")
            return None
        return value

    def axis_angle(self, fields: dict[str, yaml.Node], node: yaml.Node, name: str) -> tuple[kin.Matrix, Vec] | None:
        r = self.reader
        if "angle" not in fields:
            r.problem(node, f"the orientation of '{name}' has an 'axis' but no 'angle'", "`angle:` an expression of the coordinates, parameters and `t`")
            return None
        extra = [k for k in ("angles", "kind") if k in fields]
        if extra:
            r.problem(fields[extra[0]], f"'{extra[0]}' belongs to a sequence, not to an axis and angle", "`{axis: [x, y, z], angle: EXPR}`")
            return None
        axis = self.constant_vector(fields["axis"], f"the axis of '{name}'")
        angle = r.expression(fields["angle"], f"the angle of '{name}'", self.config)
        if axis is None or angle is None:
            return None
        squared = sp.Add(*(a**2 for a in axis))
        values = self.sample([[squared]], random_coordinates=False)
        if sp.expand(squared) == 0 or (values is not None and values[0][0] == 0.0):
            r.problem(fields["axis"], f"the axis of '{name}' is zero", "a non-zero constant vector (the tool normalises it)")
            return None
        length = sp.sqrt(squared)
        unit = tuple(a / length for a in axis)
        if self.holds_input([angle], fields["angle"], f"the angle of '{name}'"):
            return None
        rate = self.config.time_derivative(angle)
        return kin.rodrigues(unit, angle), tuple(u * rate for u in unit)

    def sequence(self, fields: dict[str, yaml.Node], node: yaml.Node, name: str) -> tuple[kin.Matrix, Vec] | None:
        r = self.reader
        text = r.string(fields["sequence"], f"the sequence of '{name}'")
        if text is None:
            return None
        sequence = text.strip().upper()
        if sequence not in kin.SEQUENCES:
            hint = _closest(sequence, list(kin.SEQUENCES))
            r.problem(
                fields["sequence"], f"unknown sequence '{text}' in the orientation of '{name}'", (f"did you mean '{hint}'? " if hint else "") + "one of " + ", ".join(kin.SEQUENCES) + " (any case)"
            )
            return None
        kind = "body"
        if "kind" in fields:
            given = r.string(fields["kind"], f"the kind of '{name}''s sequence")
            if given is None:
                return None
            if given.strip().lower() not in ("body", "space"):
                r.problem(fields["kind"], f"unknown kind '{given}' of a sequence", "`body` (intrinsic, the default) or `space` (extrinsic)")
                return None
            kind = given.strip().lower()
        if "angles" not in fields:
            r.problem(node, f"the orientation of '{name}' has a 'sequence' but no 'angles'", "`angles: [a1, a2, a3]` (three angles; 0 for one not used)")
            return None
        if "angle" in fields:
            r.problem(fields["angle"], "'angle' belongs to an axis and angle, not to a sequence", "`angles: [a1, a2, a3]`")
            return None
        angles = r.vector(fields["angles"], f"the angles of '{name}'", self.config, (3,))
        if angles is None:
            return None
        if self.holds_input(angles, fields["angles"], f"the angles of '{name}'"):
            return None
        pairs = kin.factors(sequence, angles, kind)
        rates = [self.config.time_derivative(a) for _, a in pairs]
        return kin.product(pairs), kin.product_omega(pairs, rates)

    def matrix(self, fields: dict[str, yaml.Node], node: yaml.Node, name: str) -> tuple[kin.Matrix, Vec] | None:
        r = self.reader
        extra = [k for k in ("angle", "angles", "kind") if k in fields]
        if extra:
            r.problem(fields[extra[0]], f"'{extra[0]}' does not go with 'matrix'", "`{matrix: [[r11, r12, r13], [r21, r22, r23], [r31, r32, r33]]}`")
            return None
        rows_node = fields["matrix"]
        rows = r.sequence(rows_node, f"the orientation matrix of '{name}'")
        if not rows:
            return None
        if len(rows) != 3:
            r.problem(rows_node, f"the orientation matrix of '{name}' has {len(rows)} rows", "3 rows of 3 entries")
            return None
        parsed = [r.vector(row, f"a row of the orientation matrix of '{name}'", self.config, (3,)) for row in rows]
        if any(row is None for row in parsed):
            return None
        matrix = tuple(tuple(row) for row in parsed if row is not None)
        if self.holds_input([e for row in matrix for e in row], rows_node, f"the orientation matrix of '{name}'"):
            return None
        problem = self.not_rotation(matrix)
        if problem:
            r.problem(rows_node, f"the orientation matrix of '{name}' is not a rotation: {problem}", "a rotation matrix (orthonormal columns, the body axes in parent coordinates, determinant +1)")
            return None
        return matrix, kin.matrix_omega(matrix, self.config.time_derivative)

    def not_rotation(self, matrix: kin.Matrix) -> str:
        """Why `matrix` is not a rotation ('' when it is): R^T R = 1 and det R = +1, exactly when the
        entries expand to it, else to ROTATION_TOLERANCE at the default parameters and random coordinates."""
        gram = kin.matmul(kin.transpose(matrix), matrix)
        checks = [(f"column {i + 1} . column {j + 1} = {gram[i][j]}", gram[i][j] - (1 if i == j else 0), 1 if i == j else 0) for i in range(3) for j in range(i, 3)]
        checks.append(("its determinant", sp.Matrix(matrix).det(method="berkowitz") - 1, 1))
        pending = [(text, e, target) for text, e, target in checks if sp.expand(e) != 0]
        if not pending:
            return ""
        for seed in range(SAMPLES):
            values = self.sample([[e for _, e, _ in pending]], random_coordinates=True, seed=seed)
            if values is None:
                return ""  # no value to check it at (an undefined function): accepted as written
            for (text, _, target), value in zip(pending, values[0], strict=True):
                if abs(value) > ROTATION_TOLERANCE:
                    if text == "its determinant":
                        return f"its determinant is {value + 1:.6g}, not 1" + (" (a reflection)" if abs(value + 2) < 1e-6 else "")
                    i, j = (int(c) for c in text.split(" = ")[0].replace("column ", "").split(" . "))
                    return f"column {i} . column {j} is {value + target:.6g}, not {target}" + (" (at sample coordinate values)" if seed else "")
        return ""

    # -- loads --------------------------------------------------------------------------------

    def loads(self, body: Body, fields: dict[str, yaml.Node]) -> Body | None:
        """The body's `force` and `torque` entries: forces in world axes with the world point where they
        act, torques in body axes (a planar body's as its z component)."""
        import dataclasses

        forces: list[tuple[Vec, Vec]] = []  # world force and point, or (oriented body) body-axes force and the point's body-axes velocity
        torques: list[Vec] = []
        ok = True
        for key in ("force", "torque"):
            if key not in fields:
                continue
            for item in self.load_items(fields[key]):
                found = self.load(body, key, item)
                if found is None:
                    ok = False
                elif key == "force":
                    forces.append(found)
                else:
                    torques.append(found[0])
        if not ok:
            return None
        if not forces and not torques:
            return body
        if body.rotation is not None:
            return dataclasses.replace(body, frame_forces=tuple(forces), torques=tuple(torques))
        return dataclasses.replace(body, forces=tuple(forces), torques=tuple(torques))

    @staticmethod
    def load_items(node: yaml.Node) -> list[yaml.Node]:
        """One load (a vector list or a map) or a list of loads."""
        if isinstance(node, yaml.SequenceNode) and node.value and all(isinstance(item, (yaml.SequenceNode, yaml.MappingNode)) for item in node.value):
            return list(node.value)
        return [node]

    def load(self, body: Body, key: str, node: yaml.Node) -> tuple[Vec, Vec] | None:
        r = self.reader
        name = body.name
        planar = len(body.inertia) == 1
        what = f"the {key} on '{name}'"
        axes, at_node, vector_node = "world", None, node
        if isinstance(node, yaml.MappingNode):
            entries = {k: v for k, _, v in r.mapping(node, what, LOAD_KEYS if key == "force" else LOAD_KEYS[:2])}
            if "vector" not in entries:
                if "vector" not in r.near_misses(node, LOAD_KEYS):
                    r.problem(node, f"{what} has no 'vector'", "`vector: [fx, fy, fz]`")
                return None
            vector_node, at_node = entries["vector"], entries.get("at")
            if "axes" in entries:
                given = r.string(entries["axes"], f"the axes of {what}")
                if given is None:
                    return None
                if given.strip().lower() not in ("world", "body"):
                    r.problem(entries["axes"], f"unknown axes '{given}' of {what}", "`world` (the default) or `body`")
                    return None
                axes = given.strip().lower()
                if axes == "body" and body.rotation is None and not (key == "torque" and not planar):
                    r.problem(entries["axes"], f"{what} is in body axes, but '{name}' has no 'orientation'", "`axes: world`, or give the body an `orientation`")
                    return None
        elif not isinstance(node, yaml.SequenceNode) and not (planar and key == "torque"):
            r.problem(node, f"{what} must be a list of components or a map `{{vector, axes{', at' if key == 'force' else ''}}}`, got {_kind(node)}", "a list such as `[0, 0, tau]`")
            return None
        if key == "torque":
            return self.torque(body, vector_node, axes, what)
        dim = len(body.position)
        vector = r.vector(vector_node, f"the vector of {what}", self.state, (dim,))
        if vector is None:
            return None
        where = body.position
        if at_node is not None:
            found = self.at(body, at_node)
            if found is None:
                return None
            where = found
        if body.rotation is None:
            return vector, where
        # in body axes, with the body-axes velocity of the point where it acts
        if axes == "world":
            vector = kin.matvec(kin.transpose(body.rotation), vector)
        return vector, self.frames[id(where)][1]

    def torque(self, body: Body, node: yaml.Node, axes: str, what: str) -> tuple[Vec, Vec] | None:
        r = self.reader
        if len(body.inertia) == 1:  # planar: about z, the same in world and body axes
            if isinstance(node, yaml.SequenceNode):
                vector = r.vector(node, f"the vector of {what}", self.state, (3,))
                if vector is None:
                    return None
                if vector[0] != 0 or vector[1] != 0:
                    r.problem(node, f"{what} has x or y components, but '{body.name}' is planar (it turns about z only)", "`[0, 0, tau]` or the z component alone")
                    return None
                return (vector[2],), ()
            value = r.expression(node, f"{what}", self.state)
            return None if value is None else ((value,), ())
        vector = r.vector(node, f"the vector of {what}", self.state, (3,))
        if vector is None:
            return None
        if axes == "world":
            if body.rotation is None:
                r.problem(node, f"{what} is in world axes, but '{body.name}' has no 'orientation' to turn it into body axes", "`{vector: [..], axes: body}`, or give the body an `orientation`")
                return None
            vector = kin.matvec(kin.transpose(body.rotation), vector)
        return vector, ()

    def at(self, body: Body, node: yaml.Node) -> Vec | None:
        """Where a force acts: a point of this body (`tip` or `BODY.tip`), or the body's name (its centre)."""
        r = self.reader
        expected = f"a point of '{body.name}' (" + (", ".join(body.points) or "none declared under `points`") + f") or '{body.name}' for its centre of mass"
        text = r.string(node, f"'at' of a force on '{body.name}'")
        if text is None:
            return None
        text = text.strip()
        owner, dot, point = text.partition(".")
        if not dot:
            owner, point = body.name, text
        if owner != body.name:
            r.problem(node, f"a force on '{body.name}' acts at '{text}', which is not a point of '{body.name}'", expected)
            return None
        if point == body.name and not dot:
            return body.position
        if point not in body.points:
            hint = _closest(point, list(body.points))
            r.problem(node, f"body '{body.name}' has no point '{point}'", (f"did you mean '{hint}'? " if hint else "") + expected)
            return None
        return body.points[point]


def _cross(omega: Vec, p: Vec) -> Vec:
    """omega x p (planar: omega_z e_z x p)."""
    if len(p) == 2:
        return (-omega[0] * p[1], omega[0] * p[0])
    return (omega[1] * p[2] - omega[2] * p[1], omega[2] * p[0] - omega[0] * p[2], omega[0] * p[1] - omega[1] * p[0])


def _add(a: Vec, b: Vec) -> Vec:
    return tuple(x + y for x, y in zip(a, b, strict=True))


def _det(m: list[list[float]]) -> float:
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])


def _kind(node: yaml.Node) -> str:
    from lagrange_cli.frontend.source import kind

    return kind(node)
