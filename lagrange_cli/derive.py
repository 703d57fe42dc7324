"""The core: Lagrange's equations from a `SystemSpec`, computed with symengine.

Everything here follows the textbook derivation term by term:

    K = 1/2 sum m x_dot^2,   x_dot = sum dx/dq q_dot + dx/dt        (Eqs. 6.10-6.11)
    L = K - U (+ extra Lagrangian terms)                              (Eq. 6.21)
    Q_i = sum_j f_j dx_j/dq_i                                         (Eq. 6.6)
    d/dt(dL/dq_dot_i) - dL/dq_i + dR/dq_dot_i = Q_i (+ sum_k lambda_k a_ki)

The time derivative is taken by the chain rule with q, q_dot, q_ddot as plain symbols,
which splits each equation into `M q_ddot - F`. Everything is computed in symengine (two
orders of magnitude faster than sympy) and kept there: the model's `symengine` forms are the
result, and its sympy fields are converted only when something reads them (`Model.from_symengine`).

The point masses (a particle or a body's centre, its mass and position of q and t only) are
done by structure rather than by differentiating their expanded kinetic energy:
M_ij = sum_p m_p (dx_p/dq_i . dx_p/dq_j) from the Jacobian columns, each distinct pair of
columns dotted and trig-combined once and the masses sharing it added first (the general
chain's M_ij = l_i l_j cos(q_i - q_j) (m_max(i,j) + ... + m_N)); their velocity terms in F
come from the Christoffel symbols of M, their weight from g . dx_p/dq_i grouped the same way.
Everything else (extra kinetic and Lagrangian terms, rotational energy, the velocity-linear
and constant parts of moving positions, potentials, dissipation, forces) goes through the
general route above.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import sympy as sp

from lagrange_cli._symengine import se, to_symengine
from lagrange_cli.algebra import combine_trig, expand_bounded, expandable, smooth_expand
from lagrange_cli.errors import Span, fail
from lagrange_cli.expr import numeric_value, real_derivative
from lagrange_cli.kinematics import Rate
from lagrange_cli.model import Carrier, ConstraintRow, Model, SymengineForms
from lagrange_cli.spec import Body, Constraint, Particle, SystemSpec, time_derivative
from lagrange_cli.validate import Source, first_refusal, forms_parts, refusal, survey, validate

Vector = list[se.Basic]
ZERO = se.Integer(0)


def load_model(file: str, shared: bool = False) -> Model:
    """The model of a system file, or a bundled system's name (`spec.resolve`): read, validated and
    derived (`shared` as for `derive`). What every command that needs the equations starts with."""
    return load_system_and_model(file, shared)[1]


def load_system_and_model(file: str, shared: bool = False) -> tuple[SystemSpec, Model]:
    """`load_model` for a command that also needs the validated file (its symmetries, its `draw` block)."""
    from lagrange_cli.spec import load, resolve

    system = load(resolve(file))
    return system, derive(system, shared=shared)


def derive(spec: SystemSpec, shared: bool = False) -> Model:
    """File to equations: eliminate constraints, build L and R, apply Lagrange's equation, and
    validate the result (`validate.validate`), so that every later stage sees a sound model.

    `shared`: the caller prints the equations with their common subexpressions shared (generated code),
    so equations that are too long only when written out in full (a spatial chain with `relative_to`)
    are accepted; their sympy fields then refuse to be read (`Model.from_symengine`'s `refuse`)."""
    check_size(spec, input_work(spec), MAX_INPUT_WORK, "the file's expressions, each times the number of coordinates and velocities in it,")
    energy = None
    if spec.units is not None:  # dimensions first, so that a mismatch is reported at the file's line
        from lagrange_cli import units

        energy = units.check_file(spec)
    try:
        spec = eliminate(spec)
        check_masses(spec)
        try:
            model, cleared = _derive(spec, shared)
        finally:
            _CONVERTED.clear()
    except TypeError as exc:
        if "NaN" not in str(exc):
            raise
        # sympy evaluating an undefined value on the way (atan2 of a zoo after a substitution)
        raise fail(None, f"{spec.path}: an expression became undefined (not a number) while deriving the equations", "expressions with finite values wherever they are evaluated") from None
    validate(model, sources(spec), (*spec.q, *spec.qd, spec.t), cleared)
    if spec.units is not None:
        units.check_equations(spec, model, energy)
    return model


def _derive(spec: SystemSpec, shared: bool = False, composite: bool = True) -> tuple[Model, bool]:
    """The model and whether `validate.survey` cleared its symengine forms. `composite`: hinged oriented bodies
    summed as composite bodies (`Trees`: far fewer operations, but longer written out in full)."""
    q, qd, t = _se(spec.q), _se(spec.qd), _to_se(spec.t)
    qdd = _se(spec.qdd)
    free = [item for item in _masses(spec) if not (isinstance(item, Body) and item.rotation is not None)]  # oriented bodies: `oriented_bodies`
    points = [item for item in free if _structured(item, qd, qdd)]
    others = [item for item in free if not _structured(item, qd, qdd)]
    quad = point_masses(points, q, qd, t, _se(spec.gravity) if spec.gravity is not None else None)
    rigid = oriented_bodies(spec, quad, q, t, composite)  # Kane's form for bodies with an orientation; their weight joins `quad`
    potential = potential_energy(spec, others) + quad.gravity_potential
    # everything but the point masses' quadratic kinetic energy and gravity: differentiated as written
    rest_kinetic = combine_trig(quad.linear + quad.constant + kinetic_energy(spec, others) + rotational_energy(spec) + _to_se(spec.kinetic))
    quadratic = quad.quadratic()
    kinetic = quadratic + rest_kinetic + rigid.kinetic
    rest = rest_kinetic - potential_energy(spec, others) + _to_se(spec.lagrangian)
    lagrangian = kinetic - potential + _to_se(spec.lagrangian)
    dissipation = combine_trig(rayleigh(spec))
    forces = generalized_forces(spec)
    if set(qdd) & rest.free_symbols:  # the point masses' part has none (`_structured`)
        raise fail(None, f"{spec.path}: the Lagrangian depends on accelerations", "a Lagrangian of coordinates, velocities and time")
    rest_p = momenta(rest, qd)
    rest_mass, rest_force = euler_lagrange(rest, dissipation, forces, q, qd, t)
    n = len(q)
    mass = [[quad.mass[i][j] + rest_mass[i][j] + rigid.mass[i][j] for j in range(n)] for i in range(n)]
    velocity_force = quad.forces(q, qd, t)
    force = [velocity_force[i] + quad.gravity[i] + rest_force[i] + rigid.forcing[i] for i in range(n)]
    p = [se.Add(*(quad.mass[i][j] * qd[j] for j in range(n) if quad.mass[i][j] != 0)) + rest_p[i] + rigid.momenta[i] for i in range(n)]
    energy = quadratic + quad.gravity_potential + energy_function(rest, rest_p, qd) + rigid.energy
    force, p, kinetic, energy = [_tidy(f) for f in force], [_tidy(x) for x in p], _tidy(kinetic), _tidy(energy)
    for i, name in enumerate(spec.coordinates):
        if all(m == ZERO for m in mass[i]) and force[i] == ZERO and not any(_has(c.expr, se.Symbol(name)) or _has(c.expr, qd[i]) for c in map(_se_constraint, spec.constraints)):
            raise fail(
                spec.spans.get(name), f"coordinate '{name}' appears nowhere in the energies or forces: its equation would be 0 = 0", "a coordinate that the positions, energies or forces depend on"
            )
    forms = SymengineForms(
        q=tuple(q),
        qd=tuple(qd),
        qdd=tuple(qdd),
        t=t,
        mass=tuple(tuple(row) for row in mass),
        forcing=tuple(force),
        kinetic=kinetic,
        potential=potential,
        lagrangian=lagrangian,
        dissipation=dissipation,
        energy=energy,
        momenta=tuple(p),
        generalized_forces=tuple(forces),
    )
    size, tree, cleared = survey(forms_parts(forms), MAX_EQUATION_NODES)
    check_size(spec, size, MAX_EQUATION_NODES, "the equations of motion")
    refuse = None
    if tree > MAX_EQUATION_TREE:  # fine where they are printed with their common subexpressions shared; refused where written in full
        refuse = fail(
            None,
            f"{spec.path}: the equations of motion, written out without sharing, amount to more than {MAX_EQUATION_TREE} terms and factors",
            "a smaller system; or a command whose code shares common subexpressions: `derive --to python|c|octave|jax`, `simulate`, `accuracy`, `stress`, `sweep`, `animate`",
        )
        if not cleared or not shared:
            if rigid.composite:  # body by body, the equations are shorter written out
                return _derive(spec, shared, composite=False)
            raise refuse
    forms, given = (forms, {}) if cleared else _kinks(forms, spec)
    model = Model.from_symengine(
        forms,
        given,
        refuse,
        title=spec.title,
        source=spec.path,
        coordinates=spec.coordinates,
        q=spec.q,
        qd=spec.qd,
        qdd=spec.qdd,
        t=spec.t,
        parameters=spec.parameters,
        constraints=tuple(constraint_row(c, spec) for c in spec.constraints),
        eliminated=getattr(spec, "_eliminated", ()),
        description=spec.description,
        carriers=(*(Carrier(p.name, False, p.position) for p in spec.particles), *(Carrier(b.name, True, b.position, b.angular_velocity) for b in spec.bodies)),
        initial=spec.initial,
        simulate=spec.simulate,
        exact=spec.exact,
        spans=spec.spans,
        definitions=spec.definitions,
        functions=spec.functions,
        inputs=spec.inputs,
        outputs=spec.outputs,
    )
    return model, cleared and not given


def _structured(item: Particle | Body, qd: Sequence[se.Basic], qdd: Sequence[se.Basic]) -> bool:
    """Whether a mass's translational kinetic energy is a quadratic form in the velocities (its mass and
    position depend on coordinates and time only), which `point_masses` builds from its Jacobian."""
    rates = {*qd, *qdd}
    return not any(rates & _to_se(e).free_symbols for e in (item.mass, *item.position))


@dataclass
class PointMasses:
    """The point masses' kinetic energy `1/2 q_dot^T M q_dot + linear + constant` and their weight.

    M_ij = sum_p m_p (dx_p/dq_i . dx_p/dq_j), linear = sum_p m_p (dx_p/dt . J_p q_dot), constant =
    sum_p m_p |dx_p/dt|^2 / 2; the generalized gravity force Q_i = sum_p m_p (g . dx_p/dq_i). Each of M_ij
    and Q_i is a sum over geometric terms, each times the sum of the masses that share it (`_grouped`):
    the general chain's M_ij is l_i l_j cos(q_i - q_j) (m_max(i,j) + ... + m_N), not N products."""

    mass: list[list[se.Basic]]
    linear: se.Basic
    constant: se.Basic
    gravity: list[se.Basic]
    gravity_potential: se.Basic
    qd: Sequence[se.Basic]

    def quadratic(self) -> se.Basic:
        """1/2 q_dot^T M q_dot, each pair of velocities once."""
        m, v, n = self.mass, self.qd, len(self.mass)
        return se.Add(*(m[i][i] * v[i] ** 2 / 2 for i in range(n)), *(m[i][j] * v[i] * v[j] for i in range(n) for j in range(i + 1, n)))

    def forces(self, q: Sequence[se.Basic], qd: Sequence[se.Basic], t: se.Basic) -> Vector:
        """The velocity terms of the equations from the quadratic form, by the Christoffel symbols:
        F_i = 1/2 sum_jk dM_jk/dq_i qd_j qd_k - sum_jk dM_ij/dq_k qd_j qd_k - sum_j dM_ij/dt qd_j,
        differentiating each entry of M only by the coordinates it has."""
        n = len(q)
        terms: list[list[se.Basic]] = [[] for _ in range(n)]
        index = {s: k for k, s in enumerate(q)}
        coordinates = set(q)
        half = se.Rational(1, 2)
        for a in range(n):
            for b in range(a, n):
                entry = self.mass[a][b]
                if entry == ZERO:
                    continue
                free = entry.free_symbols
                for c in sorted(index[s] for s in free & coordinates):
                    d = se.diff(entry, q[c])
                    if d == ZERO:
                        continue
                    terms[a].append(-d * qd[b] * qd[c])
                    if a != b:
                        terms[b].append(-d * qd[a] * qd[c])
                        terms[c].append(d * qd[a] * qd[b])
                    else:
                        terms[c].append(half * d * qd[a] ** 2)
                if t in free:
                    d = se.diff(entry, t)
                    terms[a].append(-d * qd[b])
                    if a != b:
                        terms[b].append(-d * qd[a])
        return [se.Add(*row) for row in terms]


def point_masses(items: Sequence[Particle | Body], q: Sequence[se.Basic], qd: Sequence[se.Basic], t: se.Basic, gravity: Sequence[se.Basic] | None) -> PointMasses:
    """`PointMasses` of `items` (each with a mass and position of coordinates and time only).

    Each distinct Jacobian column dx/dq_i (the same for every link below a joint of a chain) is numbered
    once; M_ij collects, per pair of column numbers, the masses that have it, and each dot product of
    two distinct columns is formed and trig-combined once."""
    n = len(q)
    zero = se.Integer(0)
    numbers: dict[tuple[se.Basic, ...], int] = {}
    columns_seen: list[tuple[se.Basic, ...]] = []
    pairs: dict[tuple[int, int], dict[tuple[int, int], list[se.Basic]]] = {}
    weights: dict[int, dict[int, list[se.Basic]]] = {}
    linear: list[se.Basic] = []
    constant: list[se.Basic] = []
    potential: list[se.Basic] = []

    def number(column: tuple[se.Basic, ...]) -> int:
        if column not in numbers:
            numbers[column] = len(columns_seen)
            columns_seen.append(column)
        return numbers[column]

    for item in items:
        m = _to_se(item.mass)
        x = _se(item.position)
        free = set().union(*(xk.free_symbols for xk in x))
        columns = [(i, number(col)) for i, col in jacobian(x, q) if any(c != ZERO for c in col)]
        for k, (i, a) in enumerate(columns):
            for j, b in columns[k:]:
                pairs.setdefault((i, j), {}).setdefault((a, b), []).append(m)
        rate = [se.diff(xk, t) for xk in x] if t in free else []
        if any(r != ZERO for r in rate):
            linear.append(m * se.Add(*(_dot(columns_seen[a], rate) * qd[i] for i, a in columns)))
            constant.append(m * _dot(rate, rate) / 2)
        if gravity is not None:
            potential.append(-m * _dot(gravity, x))
            for i, a in columns:
                weights.setdefault(i, {}).setdefault(a, []).append(m)
    mass = [[zero] * n for _ in range(n)]
    dots: dict[tuple[int, int], se.Basic] = {}
    for (i, j), members in pairs.items():
        for key in members:
            if key not in dots:
                dots[key] = combine_trig(_dot(columns_seen[key[0]], columns_seen[key[1]]))
        mass[i][j] = mass[j][i] = _grouped([(dots[key], ms) for key, ms in members.items()])
    forces = [zero] * n
    if gravity is not None:
        lifts = {a: combine_trig(_dot(gravity, columns_seen[a])) for a in range(len(columns_seen))}
        forces = [_grouped([(lifts[a], ms) for a, ms in weights.get(i, {}).items()]) for i in range(n)]
    return PointMasses(mass, se.Add(*linear), se.Add(*constant), forces, se.Add(*potential), qd)


def jacobian(x: Sequence[se.Basic], q: Sequence[se.Basic]) -> list[tuple[int, tuple[se.Basic, ...]]]:
    """The columns (i, dx/dq_i) for the coordinates x has, each component differentiated term by term
    and only in the terms that have q_i: a chain link's position has N terms, one of them with q_i."""
    index = {s: i for i, s in enumerate(q)}
    parts: list[dict[int, list[se.Basic]]] = []
    for xk in x:
        by_coordinate: dict[int, list[se.Basic]] = {}
        for term in se.Add.make_args(xk):
            for s in term.free_symbols:
                if s in index:
                    by_coordinate.setdefault(index[s], []).append(term)
        parts.append(by_coordinate)
    found = sorted(set().union(*parts))
    zero = se.Integer(0)
    return [(i, tuple(se.diff(se.Add(*terms[i]), q[i]) if i in terms else zero for terms in parts)) for i in found]


def _dot(a: Sequence[se.Basic], b: Sequence[se.Basic]) -> se.Basic:
    return se.Add(*(x * y for x, y in zip(a, b, strict=True)))


MAX_TIDY_NODES = 400
"""Largest expression (operations, `symengine.count_ops`) that `_tidy` tries to expand."""


def _tidy(expr: se.Basic) -> se.Basic:
    """`expr` expanded when that makes it shorter (fewer operations), else as it is: combining only
    what pays. `2*l*m*x_dot*theta_dot + 2*m*x*x_dot*theta_dot` beats `x_dot*theta_dot*(2*l*m + 2*m*x)`,
    but `l1*l2*cos(th1 - th2)*(m2 + m3)` stays (its expansion repeats the geometric factor per mass)."""
    if tree_size(expr, 4 * MAX_TIDY_NODES) > 4 * MAX_TIDY_NODES:  # surely over MAX_TIDY_NODES operations, found without walking all of a shared tree
        return expr
    size = se.count_ops(expr)
    if size > MAX_TIDY_NODES or not expandable(expr):
        return expr
    expanded = se.expand(expr)
    return expanded if se.count_ops(expanded) < size else expr


def _grouped(terms: Sequence[tuple[se.Basic, Sequence[se.Basic]]]) -> se.Basic:
    """sum_k g_k (sum of the weights w_k), written as sum over the distinct terms r of the g_k of r times
    the sum of the weights (with their numeric coefficients) that multiply r: the masses that share a
    geometric term are added before multiplying."""
    by_term: dict[se.Basic, list[se.Basic]] = {}
    for g, ws in terms:
        for term in se.Add.make_args(g):
            coefficient, rest = _split(term)
            by_term.setdefault(rest, []).extend(ws if coefficient == 1 else [coefficient * w for w in ws])
    return se.Add(*(_times(rest, ws) for rest, ws in by_term.items()))


def _times(factor: se.Basic, weights: Sequence[se.Basic]) -> se.Basic:
    """factor * (sum of weights), with the sign outside when every weight is negative: -g*(m1 + m2)."""
    if len(weights) > 1 and all(_split(w)[0].is_negative for w in weights):
        return -factor * se.Add(*(-w for w in weights))
    return factor * se.Add(*weights)


def _split(term: se.Basic) -> tuple[se.Basic, se.Basic]:
    """A term as (numeric coefficient, the rest)."""
    if term.is_Number:
        return term, se.Integer(1)
    if isinstance(term, se.Mul):
        args = term.args
        if args[0].is_Number:
            return args[0], se.Mul(*args[1:])
    return se.Integer(1), term


MAX_INPUT_WORK = 100_000
"""Largest sum over the file's expressions of (terms and factors) x (coordinates and velocities in it + 1)."""
MAX_EQUATION_NODES = 250_000
"""Largest number of distinct terms and factors (shared ones counted once) of the derived equations, energies
and momenta (the general 60-link chain has about 17,000; the bundled systems at most a few hundred)."""
MAX_EQUATION_TREE = 3_000_000
"""Largest size of the same written out as trees (each repetition of a shared part counted: what printing
them in sympy costs); the general 60-link chain has about 550,000."""


def tree_size(expr: object, limit: int = 10**9) -> int:
    """The number of nodes of an expression tree (sympy or symengine; a list counts its items'
    trees), counting stops just past `limit`."""
    count, stack = 0, list(expr) if isinstance(expr, list) else [expr]
    while stack and count <= limit:
        node = stack.pop()
        count += 1
        stack.extend(node.args)  # type: ignore[union-attr]
    return count


def input_work(spec: SystemSpec) -> int:
    """What differentiation multiplies: the size of each term of each entry times (the coordinates and
    velocities it has + 1), a term without a coordinate differentiating to nothing. A sub-expression met
    before (in this term or another: a spatial chain's bodies share their rotations) is counted once."""
    state = {*spec.q, *spec.qd}
    seen: set[sp.Basic] = set()
    return sum(_new_nodes(term, seen) * (len(term.free_symbols & state) + 1) for source in sources(spec) for e in source.exprs for term in sp.Add.make_args(e))


def _new_nodes(expr: sp.Basic, seen: set[sp.Basic]) -> int:
    """The number of distinct nodes of `expr` not in `seen` (which they join)."""
    count, stack = 0, [expr]
    while stack:
        node = stack.pop()
        if node in seen:
            continue
        seen.add(node)
        count += 1
        stack.extend(node.args)
    return count


def check_size(spec: SystemSpec, size: int, limit: int, what: str) -> None:
    """Refuse a file whose derivation would be too large to finish in seconds (counted, not timed)."""
    if size > limit:
        raise fail(None, f"{spec.path}: {what} amount to more than {limit} terms and factors", "a smaller system: fewer or shorter expressions, or fewer coordinates")


def sources(spec: SystemSpec) -> list[Source]:
    """Every entry of the file that goes into the equations, with where it is written."""
    found: list[Source] = []

    def add(what: str, span: Span | None, *exprs: sp.Expr | None) -> None:
        kept = tuple(e for e in exprs if e is not None and e != 0)
        if kept:
            found.append(Source(what, span, kept))

    for item in _masses(spec):
        kind = "particle" if isinstance(item, Particle) else "body"
        add(f"the mass of {kind} '{item.name}'", item.spans.get("mass"), item.mass)
        add(f"the position of {kind} '{item.name}'", item.spans.get("position"), *item.position)
        if isinstance(item, Particle):
            add(f"the force on particle '{item.name}'", item.spans.get("force"), *(item.force or ()))
            add(f"the damping of particle '{item.name}'", item.spans.get("damping"), item.damping)
        else:
            add(f"the inertia of body '{item.name}'", item.spans.get("inertia"), *item.inertia)
            if item.rotation is None:
                add(f"the angular velocity of body '{item.name}'", item.spans.get("angular_velocity"), *item.angular_velocity)
            else:
                add(f"the orientation of body '{item.name}'", item.spans.get("orientation"), *item.angular_velocity)
            add(f"the force on body '{item.name}'", item.spans.get("force"), *(e for f, x in (*item.forces, *item.frame_forces) for e in (*f, *x)))
            add(f"the torque on body '{item.name}'", item.spans.get("torque"), *(e for v in item.torques for e in v))
    for key, what in (("kinetic", "'kinetic'"), ("potential", "the potential"), ("lagrangian", "'lagrangian'"), ("dissipation", "the dissipation function")):
        add(what, spec.sources.get(key), getattr(spec, key))
    add("'gravity'", spec.sources.get("gravity"), *(spec.gravity or ()))
    for name, force in zip(spec.coordinates, spec.generalized_forces, strict=False):
        add(f"the generalized force on '{name}'", spec.sources.get(f"forces.{name}"), force)
    for constraint in spec.constraints:
        add(f"constraint '{constraint.name}'", constraint.span, constraint.expr)
    for name, exact in spec.exact.items():
        add(f"the exact solution for '{name}'", spec.sources.get(f"exact.{name}"), exact)
    for name, definition in spec.definitions.items():
        add(f"the definition of '{name}'", spec.sources.get(f"functions.{name}"), definition.expr)
        if found and found[-1].what == f"the definition of '{name}'":
            found[-1] = dataclasses.replace(found[-1], variables=tuple(definition.variables))
    return found


def check_masses(spec: SystemSpec) -> None:
    """A mass or inertia written non-zero must not be 0 where the equations are computed (in
    double precision): `m*exp(-800)` would silently leave a coordinate without inertia. Its
    written constants are evaluated with every parameter at 1 (a parameter's own value is the
    user's to choose)."""
    for item in _masses(spec):
        values = [("mass", item.mass)] + ([("inertia", i) for i in item.inertia] if isinstance(item, Body) else [])
        for key, value in values:
            if value == 0:
                continue
            vanishes = _to_se(value) == 0
            if not vanishes:
                try:  # its written constants, at parameters of 1, in floating point (no sympy evaluation of huge numbers)
                    vanishes = numeric_value(value, dict.fromkeys(value.free_symbols, 1.0)) == 0.0
                except (OverflowError, ValueError):
                    vanishes = False
            if vanishes:
                raise fail(item.spans.get(key), f"the {key} of '{item.name}' is written non-zero ({value}) but is 0 in double precision", "a value between 1e-300 and 1e300 in size")


def kinetic_energy(spec: SystemSpec, items: Sequence[Particle | Body]) -> se.Basic:
    """K = sum 1/2 m |x_dot|^2 over `items` (particles and bodies), by differentiating their positions."""
    q, qd, t = _se(spec.q), _se(spec.qd), _to_se(spec.t)
    total = se.Integer(0)
    for item in items:
        v = velocity(_se(item.position), q, qd, t)
        total += _to_se(item.mass) * sum((vi**2 for vi in v), se.Integer(0)) / 2
    return total


def rotational_energy(spec: SystemSpec) -> se.Basic:
    """1/2 I omega^2 (planar) or 1/2 sum I_k omega_k^2 (spatial, principal body axes) over bodies whose
    angular velocity the file gives (those with an `orientation` are `oriented_rotation`'s)."""
    total = se.Integer(0)
    for body in spec.bodies:
        if body.rotation is not None:
            continue
        if len(body.inertia) == 9:  # a full tensor with the file's angular velocity (body axes)
            w = _se(body.angular_velocity)
            inertia = inertia_matrix(body)
            total += _dot(w, [_dot(row, w) for row in inertia]) / 2
            continue
        inertia, omega = _se(body.inertia), _se(body.angular_velocity)
        total += sum((i * w**2 for i, w in zip(inertia, omega, strict=True)), se.Integer(0)) / 2
    return total


def inertia_matrix(body: Body) -> list[list[se.Basic]]:
    """The body's inertia tensor in body axes: 1x1 (planar), diagonal (principal moments) or full."""
    values = _se(body.inertia)
    if len(values) == 9:
        return [values[3 * i : 3 * i + 3] for i in range(3)]
    return [[values[i] if i == j else ZERO for j in range(len(values))] for i in range(len(values))]


def partial_rates(omega: Sequence[se.Basic], qd: Sequence[se.Basic]) -> tuple[dict[int, Vector], Vector]:
    """omega = sum_i w_i q_dot_i + w_0 (linear in the velocities): the partial angular velocities w_i
    (those not zero, by index) and w_0."""
    partial: dict[int, Vector] = {}
    for i, v in enumerate(qd):
        if any(v in w.free_symbols for w in omega):
            partial[i] = [se.diff(w, v) for w in omega]
    rest = [w.subs({qd[i]: ZERO for i in partial}) if partial else w for w in omega]
    return partial, rest


MAX_COMBINED = 150
"""Largest mass-matrix entry of oriented bodies (operations) that is trig-combined."""


@dataclass
class Rigid:
    """What the bodies with an `orientation` add: to M, to F (velocity terms, Kane's form), the kinetic energy,
    the momenta and the energy function."""

    mass: list[list[se.Basic]]
    forcing: Vector
    kinetic: se.Basic
    momenta: Vector
    energy: se.Basic
    composite: bool = False
    """Whether some bodies were summed as composite bodies (`Trees`)."""


def oriented_bodies(spec: SystemSpec, quad: PointMasses, q: Sequence[se.Basic], t: se.Basic, composite: bool = True) -> Rigid:
    """Bodies with an `orientation`, in Kane's form with every vector in body axes, where it is short. With the
    centre's velocity v = sum_i v_i q_dot_i + v_0 and omega = sum_i w_i q_dot_i + w_0 (body axes; `rigid.Places`
    builds both down the references without differentiating a composed rotation):

        M_ij += m v_i . v_j + w_i . I w_j
        F_i  -= m v_i . (a_0 + omega x v) + w_i . (I alpha_0 + omega x I omega)

    where a_0 and alpha_0 are dv/dt and d omega/dt without the accelerations (chain rule: sum_k dv/dq_k q_dot_k + dv/dt).
    The weight m (R^T g) . v_i joins `quad.gravity` (R^T g carried down `relative_to` chains, R^T g = L^T (R_parent^T g))
    and -m g . x the potential. T = 1/2 (m v . v + omega . I omega), p_i = m v_i . v + w_i . I omega, h = sum p_i q_dot_i - T."""
    qd = quad.qd
    n = len(qd)
    mass: list[list[se.Basic]] = [[ZERO] * n for _ in range(n)]
    forcing: Vector = [ZERO] * n
    momenta: Vector = [ZERO] * n
    kinetic: list[se.Basic] = []
    gravity = _se(spec.gravity) if spec.gravity is not None else None
    local_gravity: dict[str, Vector] = {}
    by_name = {b.name: b for b in spec.bodies}

    def down(body: Body) -> Vector:
        """R^T g in the body's axes."""
        if body.name not in local_gravity:
            assert gravity is not None and body.local is not None
            outer = down(by_name[body.parent]) if body.parent is not None else gravity
            local = [_se(row) for row in body.local]
            local_gravity[body.name] = [se.Add(*(local[k][i] * outer[k] for k in range(len(outer)))) for i in range(len(outer))]
        return local_gravity[body.name]

    time_rate = Rate(q, qd, t)

    def rate(vector: Vector) -> Vector:
        """d/dt without the accelerations: sum_k dx/dq_k q_dot_k + dx/dt (`kinematics.Rate`: each shared part once)."""
        return [time_rate(x) for x in vector]

    entries: dict[tuple[int, int], list[se.Basic]] = {}
    parts: dict[str, Part] = {}
    for body in spec.bodies:
        if body.rotation is None or body.velocity is None:
            continue
        m = _to_se(body.mass)
        inertia = inertia_matrix(body)
        omega = _se(body.angular_velocity)
        velocity = _se(body.velocity)
        w, _ = partial_rates(omega, qd)
        v, _ = partial_rates(velocity, qd)
        keys = sorted(set(w) | set(v))
        zero_w, zero_v = [ZERO] * len(omega), [ZERO] * len(velocity)
        spin = [_dot(row, omega) for row in inertia]  # I omega
        acceleration = _plus(rate(velocity), _cross(omega, velocity))
        torque = [_dot(row, rate(omega)) for row in inertia]
        if len(omega) == 3:  # a planar body's omega x I omega is 0
            torque = _plus(torque, _cross(omega, spin))
        g_body = down(body) if gravity is not None else None
        parts[body.name] = Part(m, inertia, {i: (w.get(i, zero_w), v.get(i, zero_v)) for i in keys}, velocity, spin, acceleration, torque, g_body, omega)
        kinetic.append((m * _dot(velocity, velocity) + _dot(omega, spin)) / 2)
        if gravity is not None:
            quad.gravity_potential = quad.gravity_potential - m * _dot(gravity, _se(body.position))
    trees = Trees(spec, parts, q, qd, t, composite)
    for name, part in parts.items():
        if name in trees.tree:
            continue
        m = part.mass
        keys = sorted(part.columns)
        moments = {i: [_dot(row, part.columns[i][0]) for row in part.inertia] for i in keys}  # I w_i
        for k, i in enumerate(keys):
            for j in keys[k:]:
                entries.setdefault((i, j), []).append(m * _dot(part.columns[i][1], part.columns[j][1]) + _dot(part.columns[j][0], moments[i]))
        for i, (wi, vi) in part.columns.items():  # Kane's form body by body
            forcing[i] = forcing[i] - m * _dot(vi, part.acceleration) - _dot(wi, part.torque)
            if part.weight is not None:
                quad.gravity[i] = quad.gravity[i] + m * _dot(part.weight, vi)
    for part in parts.values():  # the momenta body by body (read by energy and momenta, not by rhs): shorter written out
        for i, (wi, vi) in part.columns.items():
            momenta[i] = momenta[i] + part.mass * _dot(vi, part.velocity) + _dot(wi, part.spin)
    # in trees, each body's load once, carried up to where each coordinate's column is (recursive Newton-Euler)
    if trees.hinges:
        parts = trees.accelerations(rate)
    inertial = trees.project(
        {name: (part.torque, [part.mass * (a - g) for a, g in zip(part.acceleration, part.weight or [ZERO] * 3, strict=True)]) for name, part in parts.items() if name in trees.tree}
    )
    for i, value in inertial.items():
        forcing[i] = forcing[i] - value
    nested = trees.mass(entries)
    for (i, j), terms in entries.items():
        entry = se.Add(*terms)
        if se.count_ops(entry) <= MAX_COMBINED and (i, j) not in nested:  # a composite entry shares its parts with the others'; combined, it would not
            entry = combine_trig(entry)
        mass[i][j] = mass[j][i] = entry
    total = se.Add(*kinetic) if kinetic else ZERO
    energy = se.Add(*(momenta[i] * qd[i] for i in range(n) if momenta[i] != ZERO)) - total
    return Rigid(mass, forcing, total, momenta, energy, bool(trees.tree))


@dataclass
class Part:
    """An oriented body: its mass, inertia tensor, by coordinate its partial angular velocity and partial velocity of
    the centre (its column of the Jacobian J; J^T diag(m, I) J is its share of M), its velocity, I omega, the
    acceleration of its centre and I alpha + omega x I omega without the accelerations, and gravity, all in its axes."""

    mass: se.Basic
    inertia: list[list[se.Basic]]
    columns: dict[int, tuple[Vector, Vector]]
    velocity: Vector
    spin: Vector
    acceleration: Vector
    torque: Vector
    weight: Vector | None
    omega: Vector


class Trees:
    """Oriented bodies hinged to their parents, summed by composite bodies.

    A body hinged to its `relative_to` parent (`Body.anchor`: its pivot a point of the parent, both spatial) moves
    with its parent but for the coordinates of its rotation L relative to the parent (which the parent's motion
    must not have): its Jacobian is the parent's carried over to it, plus its own columns, pure turns about its
    pivot. Each body of a tree has a reference point P, its pivot (hinged, or a root turning about a fixed pivot) or
    its centre (any other root), and a column
    is introduced where its coordinate first moves a body (its own coordinates; at a root, all its columns).
    Then sums over the bodies below a column (Featherstone's composite-rigid-body and recursive Newton-Euler
    algorithms) are carried up the tree once, not taken body by body:

    - M (`mass`): K_b, the composite inertia of b and the bodies below it (mass, first moment h and inertia I
      about P, in b's axes), is D_b moved to P plus each child's K carried over (rotated by L, moved by rho, the
      child's P from this P in this body's axes). A column S_l introduced at body a gives the force K_a S_l,
      carried up the ancestors (f -> L f, tau -> L tau + rho x L f), and M_kl = S_k . (force) for each column
      S_k introduced there: one dot product per entry, not one per body below it (O(N^2) for a chain, not O(N^3)).
    - F and the momenta (`project`): a load per body (torque about the centre, force), summed up the tree the
      same way, and S_k . (sum) for each column: O(N) for a chain, not O(N^2).

    A body in no tree is left to the caller (body by body, Kane's form)."""

    def __init__(self, spec: SystemSpec, parts: Mapping[str, Part], q: Sequence[se.Basic], qd: Sequence[se.Basic], t: se.Basic, composite: bool = True) -> None:
        self.parts, self.qd = parts, qd
        self.hinges: dict[str, tuple[str, list[list[se.Basic]], Vector, Vector]] = {}  # parent, L, this centre from P, P from the parent's centre
        self.fixed: dict[str, Vector] = {}  # a root turning about a fixed pivot: its centre from the pivot
        for body in spec.bodies if composite else ():
            part = parts.get(body.name)
            if part is None or body.anchor is None or body.local is None or len(part.inertia) != 3:
                continue
            parent, offset, center = body.anchor
            if parent is None:  # its velocity is omega x c: each column a turn about the pivot
                self.fixed[body.name] = _se(center)
                continue
            above = parts.get(parent)
            if above is None or len(above.inertia) != 3:
                continue
            local = [_se(row) for row in body.local]
            moved = {k for k, qk in enumerate(q) if any(qk in e.free_symbols for row in local for e in row)}
            if t in set().union(*(e.free_symbols for row in local for e in row)):
                continue  # a rotation relative to the parent given in time: its relative angular velocity is not all in its columns
            if moved & set(above.columns) or not set(above.columns) <= set(part.columns) or not set(part.columns) - set(above.columns) <= moved:
                continue  # the parent's motion has a coordinate of the relative rotation: J = X J_parent + S does not hold
            self.hinges[body.name] = (parent, local, _se(center), _se(offset))
        parents = {hinge[0] for hinge in self.hinges.values()}
        self.tree = {name for name in parts if name in self.hinges or name in parents}
        self.introduced = {name: sorted(set(parts[name].columns) - set(parts[self.hinges[name][0]].columns)) if name in self.hinges else sorted(parts[name].columns) for name in self.tree}
        self.order = sorted(self.tree, key=self.depth, reverse=True)  # children before their parents

    def accelerations(self, rate: Callable[[Vector], Vector]) -> dict[str, Part]:
        """The parts with each hinged body's acceleration and torque (without the accelerations q_ddot) carried
        down from its parent's (Newton-Euler), not by differentiating its nested velocity: with omega_b =
        L^T omega_p + omega_rel (omega_rel = sum of its own columns times their rates),

            alpha_b = L^T alpha_p + (L^T omega_p) x omega_rel + d(omega_rel)/dt
            a_b = L^T (a_p + alpha_p x d + omega_p x (omega_p x d)) + alpha_b x c + omega_b x (omega_b x c)

        (d the pivot from the parent's centre, c the centre from the pivot), torque = I alpha_b + omega_b x I omega_b.
        Gravity joins as the root's acceleration a - g (Luh, Walker and Paul's trick): each body's weight is then in its a."""
        found = dict(self.parts)
        bias: dict[str, tuple[Vector, Vector]] = {}
        for name in sorted(self.tree, key=self.depth):  # parents first
            part = self.parts[name]
            if name not in self.hinges:  # gravity as an acceleration of the root: carried down with the rest
                acc = part.acceleration if part.weight is None else [a - g for a, g in zip(part.acceleration, part.weight, strict=True)]
                bias[name] = (rate(part.omega), acc)
                found[name] = dataclasses.replace(part, acceleration=acc, weight=None)
                continue
            parent, local, center, offset = self.hinges[name]
            alpha_p, acc_p = bias[parent]
            omega_p = self.parts[parent].omega
            turn = [[local[j][i] for j in range(3)] for i in range(3)]  # L^T
            rel = [se.Add(*(self.parts[name].columns[k][0][i] * self.qd[k] for k in self.introduced[name])) for i in range(3)]
            carried = [_dot(row, omega_p) for row in turn]
            alpha = _plus(_plus([_dot(row, alpha_p) for row in turn], _cross(carried, rel)), rate(rel))
            at_pivot = _plus(_plus(acc_p, _cross(alpha_p, offset)), _cross(omega_p, _cross(omega_p, offset)))
            omega = part.omega
            acc = _plus(_plus([_dot(row, at_pivot) for row in turn], _cross(alpha, center)), _cross(omega, _cross(omega, center)))
            torque = _plus([_dot(row, alpha) for row in part.inertia], _cross(omega, part.spin))
            bias[name] = (alpha, acc)
            found[name] = dataclasses.replace(part, acceleration=acc, torque=torque, weight=None)
        return found

    def depth(self, name: str) -> int:
        return 1 + self.depth(self.hinges[name][0]) if name in self.hinges else 0

    def center(self, name: str) -> Vector:
        """The centre from P, in the body's axes."""
        if name in self.hinges:
            return self.hinges[name][2]
        return self.fixed.get(name, [ZERO] * 3)

    def turns(self, name: str) -> bool:
        """Whether the columns introduced at `name` are turns about its P (hinged, or a root about a fixed pivot)."""
        return name in self.hinges or name in self.fixed

    def up(self, name: str, torque: Vector, force: Vector) -> tuple[str, Vector, Vector]:
        """A force (torque about P, force; body axes) carried to the parent's P and axes: (parent, torque, force)."""
        parent, local, _, offset = self.hinges[name]
        force = [_dot(row, force) for row in local]
        return parent, _plus([_dot(row, torque) for row in local], _cross(_plus(offset, self.center(parent)), force)), force

    def dot(self, name: str, k: int, torque: Vector, force: Vector) -> se.Basic:
        """S_k . (torque about P, force) for a column introduced at `name` (`turns`: w_k . torque)."""
        w, v = self.parts[name].columns[k]
        return _dot(w, torque) if self.turns(name) else _dot(w, torque) + _dot(v, force)

    def project(self, loads: Mapping[str, tuple[Vector, Vector]]) -> dict[int, se.Basic]:
        """sum_b J_bk . (torque_b, force_b) over the bodies of the trees (each load about its body's centre, body axes), by k."""
        total: dict[str, tuple[Vector, Vector]] = {}
        for name in self.order:
            torque, force = loads[name]
            torque = _plus(torque, _cross(self.center(name), force))  # about P
            if name in total:
                below = total[name]
                torque, force = _plus(torque, below[0]), _plus(force, below[1])
            total[name] = (torque, force)
            if name in self.hinges:
                parent, up_torque, up_force = self.up(name, torque, force)
                if parent in total:
                    up_torque, up_force = _plus(up_torque, total[parent][0]), _plus(up_force, total[parent][1])
                total[parent] = (up_torque, up_force)
        found: dict[int, list[se.Basic]] = {}
        for name in self.order:
            for k in self.introduced[name]:
                found.setdefault(k, []).append(self.dot(name, k, *total[name]))
        return {k: se.Add(*terms) for k, terms in found.items()}

    def mass(self, entries: dict[tuple[int, int], list[se.Basic]]) -> set[tuple[int, int]]:
        """The trees' share of M, as terms of `entries` (keyed by (i, j), i <= j); the keys it added to."""
        added: set[tuple[int, int]] = set()
        composite = {name: _moved(self.parts[name].mass, [ZERO] * 3, self.parts[name].inertia, self.center(name)) for name in self.tree}
        for name in self.order:
            if name not in self.hinges:
                continue
            parent, local, _, offset = self.hinges[name]
            m, h, inertia = composite[name]
            turned = _similar(local, inertia)
            pm, ph, pi = composite[parent]
            cm, ch, ci = _moved(m, [_dot(row, h) for row in local], turned, _plus(offset, self.center(parent)))
            composite[parent] = (pm + cm, _plus(ph, ch), [_plus(pi[i], ci[i]) for i in range(3)])
        for name in self.order:
            m, h, inertia = composite[name]
            for col in self.introduced[name]:
                w, v = self.parts[name].columns[col]
                if self.turns(name):  # a turn about P: v at P is 0
                    torque, force = [_dot(row, w) for row in inertia], [-c for c in _cross(h, w)]  # I w, -h x w
                else:  # the root: P is its centre
                    torque = _plus([_dot(row, w) for row in inertia], _cross(h, v))  # I w + h x v
                    force = [m * v[i] - c for i, c in enumerate(_cross(h, w))]  # m v - h x w
                at = name
                while True:
                    for k in self.introduced[at]:
                        if at != name or k <= col:
                            entries.setdefault((min(k, col), max(k, col)), []).append(self.dot(at, k, torque, force))
                            added.add((min(k, col), max(k, col)))
                    if at not in self.hinges:
                        break
                    at, torque, force = self.up(at, torque, force)
        return added


def _symmetric(entry: Callable[[int, int], se.Basic]) -> list[list[se.Basic]]:
    """The symmetric 3x3 matrix with these entries, each pair i < j formed once."""
    upper = {(i, j): entry(i, j) for i in range(3) for j in range(i, 3)}
    return [[upper[(min(i, j), max(i, j))] for j in range(3)] for i in range(3)]


def _similar(local: list[list[se.Basic]], inertia: list[list[se.Basic]]) -> list[list[se.Basic]]:
    """L I L^T of a symmetric I."""
    columns = [[_dot(inertia[k], local[j]) for k in range(3)] for j in range(3)]  # I L^T, by column
    return _symmetric(lambda i, j: _dot(local[i], columns[j]))


def _moved(m: se.Basic, h: Vector, inertia: list[list[se.Basic]], r: Vector) -> tuple[se.Basic, Vector, list[list[se.Basic]]]:
    """Mass, first moment and inertia about a point O (h = m (centre - O)) carried to O' = O - r:
    h' = h + m r, I' = I + m (r.r 1 - r r^T) + 2 (r.h) 1 - r h^T - h r^T (parallel axes, O not the centre)."""
    if all(x == ZERO for x in r):
        return m, h, inertia
    rr, rh = _dot(r, r), _dot(r, h)
    moved = _symmetric(lambda i, j: inertia[i][j] - m * r[i] * r[j] - r[i] * h[j] - h[i] * r[j] + ((m * rr + 2 * rh) if i == j else ZERO))
    return m, _plus(h, [m * x for x in r]), moved


def _cross(a: Vector, b: Vector) -> Vector:
    """a x b; planar (a = (omega_z,), b 2-D): omega_z e_z x b."""
    if len(b) == 2:
        return [-a[0] * b[1], a[0] * b[0]]
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _plus(a: Vector, b: Vector) -> Vector:
    return [x + y for x, y in zip(a, b, strict=True)]


def velocity(position: Sequence[se.Basic], q: Sequence[se.Basic], qd: Sequence[se.Basic], t: se.Basic) -> Vector:
    """x_dot_j = sum_i dx_j/dq_i q_dot_i + dx_j/dt  (Eq. 6.11)."""
    return [sum((se.diff(x, qi) * qdi for qi, qdi in zip(q, qd, strict=True)), se.diff(x, t)) for x in position]


def potential_energy(spec: SystemSpec, items: Sequence[Particle | Body] | None = None) -> se.Basic:
    """U = U_file - sum m g . x over `items` (default: every particle and body; a uniform field g)."""
    total = _to_se(spec.potential)
    if spec.gravity is not None:
        g = _se(spec.gravity)
        for item in _masses(spec) if items is None else items:
            total -= _to_se(item.mass) * sum((gi * xi for gi, xi in zip(g, _se(item.position), strict=True)), se.Integer(0))
    return total


def rayleigh(spec: SystemSpec) -> se.Basic:
    """R = R_file + sum 1/2 k |x_dot|^2 over damped particles (Exercise 6.9)."""
    q, qd, t = _se(spec.q), _se(spec.qd), _to_se(spec.t)
    total = _to_se(spec.dissipation)
    for particle in spec.particles:
        if particle.damping is not None:
            v = velocity(_se(particle.position), q, qd, t)
            total += _to_se(particle.damping) * sum((vi**2 for vi in v), se.Integer(0)) / 2
    return total


def generalized_forces(spec: SystemSpec) -> Vector:
    """Q_i = Q_file,i + sum_j f_j dx_j/dq_i over particles with a force (Eq. 6.6)."""
    q = _se(spec.q)
    forces = [_to_se(f) for f in spec.generalized_forces] or [se.Integer(0)] * len(q)
    for particle in spec.particles:
        if particle.force is not None:
            f, x = _se(particle.force), _se(particle.position)
            for i, qi in enumerate(q):
                forces[i] += sum((fj * se.diff(xj, qi) for fj, xj in zip(f, x, strict=True)), se.Integer(0))
    qd = _se(spec.qd)
    for body in spec.bodies:
        for force, at in body.forces:  # f . dv_at/dq_dot_i = f . dx_at/dq_i
            f, x = _se(force), _se(at)
            for i, qi in enumerate(q):
                forces[i] += se.Add(*(fj * se.diff(xj, qi) for fj, xj in zip(f, x, strict=True)))
        for force, rate in body.frame_forces:  # f . dv_at/dq_dot_i, both in body axes
            f, v = _se(force), _se(rate)
            partial, _ = partial_rates(v, qd)
            for i, vi in partial.items():
                forces[i] += _dot(f, vi)
        if body.torques:  # tau . d(omega)/dq_dot_i, both in body axes
            partial, _ = partial_rates(_se(body.angular_velocity), qd)
            for torque in body.torques:
                tau = _se(torque)
                for i, w in partial.items():
                    forces[i] += _dot(tau, w)
    return forces


def momenta(lagrangian: se.Basic, qd: Sequence[se.Basic]) -> Vector:
    """p_i = dL/dq_dot_i  (Eq. 6.35)."""
    return [se.diff(lagrangian, v) for v in qd]


def euler_lagrange(lagrangian: se.Basic, dissipation: se.Basic, forces: Sequence[se.Basic], q: Sequence[se.Basic], qd: Sequence[se.Basic], t: se.Basic) -> tuple[list[Vector], Vector]:
    """Split d/dt(dL/dq_dot) - dL/dq + dR/dq_dot = Q into M q_ddot = F by the chain rule:

    d/dt p_i = sum_j dp_i/dq_dot_j q_ddot_j + sum_k dp_i/dq_k q_dot_k + dp_i/dt
    M_ij = dp_i/dq_dot_j,  F_i = dL/dq_i - sum_k dp_i/dq_k q_dot_k - dp_i/dt - dR/dq_dot_i + Q_i
    """
    p = momenta(lagrangian, qd)
    mass = [[se.diff(pi, v) for v in qd] for pi in p]
    force = []
    for i, pi in enumerate(p):
        fi = se.diff(lagrangian, q[i]) - se.diff(pi, t) - se.diff(dissipation, qd[i]) + forces[i]
        fi -= sum((se.diff(pi, qk) * qdk for qk, qdk in zip(q, qd, strict=True)), se.Integer(0))
        force.append(_expand(fi))
    return [[_expand(m) for m in row] for row in mass], force


def _expand(expr: se.Basic) -> se.Basic:
    """Expand so that like terms cancel, unless the expansion would explode (`algebra.expandable`:
    a power of a sum above 6, or more than `algebra.MAX_TERMS` terms); terms with a kink stay as they are
    (`algebra.smooth_expand`)."""
    return smooth_expand(expr) if expandable(expr) else expr


def energy_function(lagrangian: se.Basic, p: Sequence[se.Basic], qd: Sequence[se.Basic]) -> se.Basic:
    """h = sum p_i q_dot_i - L, conserved when L has no explicit t and nothing dissipates."""
    return _expand(sum((pi * v for pi, v in zip(p, qd, strict=True)), se.Integer(0)) - lagrangian)


def constraint_row(constraint: Constraint, spec: SystemSpec) -> ConstraintRow:
    """Velocity form a . q_dot + b = 0 (a = df/dq, b = df/dt when holonomic) and its derivative
    a . q_ddot + c = 0 with c = (da/dt) . q_dot + db/dt."""
    q, qd, qdd, t = spec.q, spec.qd, spec.qdd, spec.t
    expr = constraint.expr
    velocity_form = total_derivative(expr, q, qd, qdd, t) if constraint.holonomic else expr
    a = tuple(expand_bounded(sp.diff(velocity_form, v)) for v in qd)
    b = expand_bounded(velocity_form.subs({v: 0 for v in qd}))
    c = total_derivative(expand_bounded(velocity_form), q, qd, qdd, t).subs({v: 0 for v in qdd})
    return ConstraintRow(constraint.name, expr, constraint.holonomic, sp.Symbol(f"lambda_{constraint.name}"), a, b, expand_bounded(c))


def total_derivative(expr: sp.Expr, q: tuple[sp.Symbol, ...], qd: tuple[sp.Symbol, ...], qdd: tuple[sp.Symbol, ...], t: sp.Symbol) -> sp.Expr:
    """d/dt expr by the chain rule (`spec.time_derivative`), with every quantity real, as in the
    parser: sympy differentiates `Abs(x)` of a symbol of unknown kind into `re` and `im` terms."""

    def chain(e: sp.Expr, real: Mapping[sp.Symbol, sp.Symbol]) -> sp.Expr:
        rq, rqd, rqdd = (tuple(real.get(s, s) for s in v) for v in (q, qd, qdd))
        return time_derivative(e, rq, rqd, rqdd, real.get(t, t))

    return real_derivative(expr, chain)


MAX_SOLVES = 64
"""Most (constraint, coordinate) pairs `eliminate` tries to solve, so that its work is bounded for any file."""


@dataclass(frozen=True)
class _Attempt:
    """Solving one constraint for one coordinate: the solution when it is unique and usable, else why not."""

    solution: sp.Expr | None
    why: str
    expected: str = ""


def eliminate(spec: SystemSpec) -> SystemSpec:
    """Remove each coordinate listed under `eliminate` by solving a holonomic constraint for it
    and substituting q = g(...), q_dot = dg/dt everywhere; its generalized force is carried over
    by virtual work, Q_j += Q_q dg/dq_j.

    The pairing of coordinates with constraints does not depend on the order of the list: at each
    step every remaining (coordinate, constraint) pair is tried, and the coordinate with the fewest
    constraints that determine it uniquely goes first (ties by the order of `coordinates`), solved
    by the first such constraint in the file. The work is bounded: `MAX_SOLVES` attempts in all."""
    cache: dict[tuple[sp.Expr, sp.Symbol], _Attempt] = {}
    while spec.eliminate:
        options: dict[str, list[tuple[Constraint, sp.Expr]]] = {}
        failures: dict[str, list[tuple[Constraint, _Attempt]]] = {}
        for name, span in spec.eliminate:
            qk = spec.q[spec.coordinates.index(name)]
            for constraint in spec.constraints:
                if not (constraint.holonomic and constraint.expr.has(qk)):
                    continue
                key = (constraint.expr, qk)
                if key not in cache:
                    if len(cache) >= MAX_SOLVES:
                        raise fail(
                            span,
                            f"eliminating these coordinates needs more than {MAX_SOLVES} attempts to solve a constraint",
                            "fewer eliminated coordinates or constraints; keep the others with their multipliers",
                        )
                    cache[key] = _attempt(constraint, qk, spec)
                attempt = cache[key]
                if attempt.solution is not None:
                    options.setdefault(name, []).append((constraint, attempt.solution))
                else:
                    failures.setdefault(name, []).append((constraint, attempt))
        if not options:
            name, span = spec.eliminate[0]
            raise _unsolvable(spec, name, span, failures.get(name, []))
        name = min(options, key=lambda n: (len(options[n]), spec.coordinates.index(n)))
        constraint, solution = options[name][0]
        span = next(s for n, s in spec.eliminate if n == name)
        spec = _substitute(spec, spec.coordinates.index(name), solution, constraint)
        _check_substituted(spec, name, span, solution, constraint)
    return spec


def _attempt(constraint: Constraint, symbol: sp.Symbol, spec: SystemSpec) -> _Attempt:
    """Solve `constraint` for `symbol`: unique, in the supported functions, and differentiable twice."""
    solutions, why = _solve(constraint.expr, symbol)
    if not solutions:
        return _Attempt(None, f"constraint '{constraint.name}' cannot be solved for '{symbol}'" + (f": {why}" if why else ""))
    if len(solutions) > 1:
        message = f"constraint '{constraint.name}' has {len(solutions)} solutions for '{symbol}' ({why})"
        return _Attempt(None, message, "a constraint with a single solution for the eliminated coordinate, or keep the multiplier")
    variables = [v for v in (*spec.q, spec.t) if v != symbol]
    found = first_refusal(f"the solution {symbol} = {_short(solutions[0])} of constraint '{constraint.name}'", solutions, variables, spec.definitions)
    if found is not None:
        where, problem = found
        return _Attempt(None, f"{where} contains {_short(problem.node)} ({problem.reason})", "a constraint whose solution is a smooth expression of the supported functions, or keep the multiplier")
    return _Attempt(solutions[0], "")


def _unsolvable(spec: SystemSpec, name: str, span: Span, failures: list[tuple[Constraint, _Attempt]]) -> Exception:
    """The error for a coordinate that no constraint determines: the most telling reason found."""
    if failures:
        best = next((a for _, a in failures if a.expected), failures[0][1])
        others = len(failures) - 1
        more = f" (and {others} other constraint{'s' * (others > 1)} {'do' if others > 1 else 'does'} not determine it either)" if others else ""
        return fail(span, f"cannot eliminate '{name}': {best.why}{more}", best.expected or f"a holonomic constraint under `constraints` that involves '{name}' and can be solved for it")
    k = spec.coordinates.index(name)
    velocity = [c.name for c in spec.constraints if not c.holonomic and c.expr.has(spec.qd[k])]
    hint = f"; '{velocity[0]}' is a velocity constraint: if it integrates to a relation between coordinates, write that relation instead" if velocity else ""
    return fail(span, f"no holonomic constraint can be solved for '{name}'", f"a holonomic constraint under `constraints` that involves '{name}' and can be solved for it{hint}")


def _check_substituted(spec: SystemSpec, name: str, span: Span, solution: sp.Expr, used: Constraint) -> None:
    """After substituting name = solution: no entry became undefined (`1/(x - y)` with x = y), and
    no kept constraint became 0 = 0 (it repeats `used`) or c = 0 (it contradicts it)."""
    for source in sources(spec):
        for expr in source.exprs:
            found = refusal(expr, spec.definitions)
            if found is not None:
                raise fail(
                    span,
                    f"eliminating '{name}' = {_short(solution)} (from constraint '{used.name}') turns {source.what} into an expression with {_short(found.node)} ({found.reason})",
                    "an elimination that keeps every expression defined, or keep the constraint with its multiplier",
                )
    for constraint in spec.constraints:
        if constraint.expr == 0:
            raise fail(
                constraint.span, f"constraint '{constraint.name}' says nothing once '{name}' is eliminated with '{used.name}' (it repeats it)", f"each constraint once; remove '{constraint.name}'"
            )
        if constraint.expr.is_number:
            raise fail(
                constraint.span,
                f"constraint '{constraint.name}' cannot hold once '{name}' is eliminated with '{used.name}' (it becomes {constraint.expr} = 0)",
                "constraints that agree with each other",
            )


def _solve(expr: sp.Expr, symbol: sp.Symbol) -> tuple[list[sp.Expr], str]:
    """The solutions of expr = 0 for `symbol`, or [] and why not, in a number of steps bounded by
    the size of `expr` (no `sympy.solve` or `sympy.simplify`, which can take minutes on a constraint of a few dozen operations): a linear
    constraint is solved directly, a polynomial of degree n has n solutions, and otherwise the one
    place where `symbol` occurs is isolated by undoing the functions around it (`_isolate`)."""
    try:
        if sp.diff(expr, symbol, 2) == 0:
            slope = sp.diff(expr, symbol)
            if slope == 0:
                return [], ""
            return [sp.factor_terms(-expr.subs(symbol, 0) / slope)], ""
    except (TypeError, ValueError, ZeroDivisionError):  # sympy compares a NaN (e.g. atan2(0, cot(0)))
        return [], f"it is undefined at {symbol} = 0"
    degree = _degree(expr, symbol)
    if degree is not None and degree > 1:
        return _several(degree), f"it is a polynomial of degree {degree} in '{symbol}'"
    return _isolate(expr, sp.Integer(0), symbol)


def _several(count: int) -> list[sp.Expr]:
    """Stand-ins for `count` solutions that are not worth computing: only their number is reported."""
    return [sp.Symbol(f"root{i}") for i in range(count)]


def _degree(expr: sp.Expr, symbol: sp.Symbol) -> int | None:
    """The degree of a polynomial in `symbol` as written (without expanding), None if not a polynomial."""
    if not expr.has(symbol):
        return 0
    if expr == symbol:
        return 1
    if isinstance(expr, (sp.Add, sp.Mul)):
        degrees = [_degree(a, symbol) for a in expr.args]
        if any(d is None for d in degrees):
            return None
        known = [d for d in degrees if d is not None]
        return max(known) if isinstance(expr, sp.Add) else sum(known)
    if isinstance(expr, sp.Pow) and expr.exp.is_Integer and expr.exp > 0:
        base = _degree(expr.base, symbol)
        return None if base is None else base * int(expr.exp)
    return None


_INVERSES: dict[type, tuple[Callable[[sp.Expr], sp.Expr] | None, str]] = {
    sp.exp: (sp.log, ""),
    sp.log: (sp.exp, ""),
    sp.tan: (sp.atan, ""),
    sp.atan: (sp.tan, ""),
    sp.asin: (sp.sin, ""),
    sp.acos: (sp.cos, ""),
    sp.sin: (None, "sin takes each value twice in a period"),
    sp.cos: (None, "cos takes each value twice in a period"),
    sp.sec: (None, "sec takes each value twice in a period"),
    sp.csc: (None, "csc takes each value twice in a period"),
    sp.cosh: (None, "cosh takes each value twice"),
    sp.Abs: (None, "Abs takes each value twice"),
    sp.cot: (None, "its inverse acot is not one of the supported functions"),
    sp.sinh: (None, "its inverse asinh is not one of the supported functions"),
    sp.tanh: (None, "its inverse atanh is not one of the supported functions"),
    sp.sign: (None, "sign takes only the values -1, 0 and 1"),
}


def _isolate(lhs: sp.Expr, rhs: sp.Expr, symbol: sp.Symbol) -> tuple[list[sp.Expr], str]:
    """Solve lhs = rhs where `symbol` occurs in one place of lhs: peel off sums, products, powers
    and invertible functions around it, one layer per step, keeping only inverses that give a
    unique solution in the supported functions (LambertW, Piecewise or a polynomial's RootOf
    never arise)."""
    while lhs != symbol:
        if isinstance(lhs, (sp.Add, sp.Mul)):
            inside = [a for a in lhs.args if a.has(symbol)]
            if len(inside) > 1:
                return [], f"'{symbol}' appears in more than one {'term' if isinstance(lhs, sp.Add) else 'factor'} of {_short(lhs)}, which has no solution in the supported functions"
            rest = lhs.func(*(a for a in lhs.args if not a.has(symbol)))
            rhs = rhs - rest if isinstance(lhs, sp.Add) else rhs / rest
            lhs = inside[0]
        elif isinstance(lhs, sp.Pow) and not lhs.exp.has(symbol):
            exponent = lhs.exp
            if not (exponent.is_Rational and abs(exponent.p) == 1):
                return _several(2), f"the power {_short(lhs)} takes some values more than once"
            lhs, rhs = lhs.base, rhs ** (1 / exponent)
        elif isinstance(lhs, sp.Pow) and lhs.base.is_number and lhs.base.is_positive:
            lhs, rhs = lhs.exp, sp.log(rhs) / sp.log(lhs.base)
        elif type(lhs) in _INVERSES and len(lhs.args) == 1:
            inverse, why = _INVERSES[type(lhs)]
            if inverse is None:
                return (_several(2) if "twice" in why else []), f"'{symbol}' is inside {type(lhs).__name__}, and {why}"
            lhs, rhs = lhs.args[0], inverse(rhs)
        else:
            return [], f"'{symbol}' is inside {_short(lhs)}, which cannot be inverted in the supported functions"
    return [rhs], ""


def _short(expr: sp.Expr) -> str:
    text = str(expr)
    return text if len(text) <= 60 else text[:57] + "..."


def _substitute(spec: SystemSpec, k: int, solution: sp.Expr, used: Constraint) -> SystemSpec:
    q, qd, qdd, t = spec.q, spec.qd, spec.qdd, spec.t
    keep = [i for i in range(len(q)) if i != k]
    rq, rqd, rqdd = (tuple(v[i] for i in keep) for v in (q, qd, qdd))
    rate = total_derivative(solution, rq, rqd, rqdd, t)
    mapping = {q[k]: solution, qd[k]: rate, qdd[k]: total_derivative(rate, rq, rqd, rqdd, t)}

    def sub(expr: sp.Expr) -> sp.Expr:
        return expr.xreplace(mapping)

    def subs_all(values: Iterable[sp.Expr]) -> tuple[sp.Expr, ...]:
        return tuple(sub(v) for v in values)

    forces = spec.generalized_forces
    if forces:
        forces = tuple(sub(forces[i]) + sub(forces[k]) * sp.diff(solution, q[i]) for i in keep)
    changed = dataclasses.replace(
        spec,
        coordinates=tuple(spec.coordinates[i] for i in keep),
        q=rq,
        qd=rqd,
        qdd=rqdd,
        particles=tuple(dataclasses.replace(p, mass=sub(p.mass), position=subs_all(p.position), force=None if p.force is None else subs_all(p.force)) for p in spec.particles),
        bodies=tuple(_substitute_body(b, sub) for b in spec.bodies),
        kinetic=sub(spec.kinetic),
        potential=sub(spec.potential),
        lagrangian=sub(spec.lagrangian),
        dissipation=sub(spec.dissipation),
        generalized_forces=forces,
        constraints=tuple(dataclasses.replace(c, expr=sub(c.expr)) for c in spec.constraints if c is not used),
        eliminate=tuple(e for e in spec.eliminate if e[0] != spec.coordinates[k]),
        initial={key: v for key, v in spec.initial.items() if key not in (spec.coordinates[k], f"{spec.coordinates[k]}_dot")},
        outputs=tuple((name, sub(e)) for name, e in spec.outputs),
    )
    earlier = tuple((name, sub(e)) for name, e in getattr(spec, "_eliminated", ()))  # in the coordinates that remain
    object.__setattr__(changed, "_eliminated", (*earlier, (spec.coordinates[k], solution)))
    return changed


def _substitute_body(body: Body, sub: Callable[[sp.Expr], sp.Expr]) -> Body:
    def many(values: Iterable[sp.Expr]) -> tuple[sp.Expr, ...]:
        return tuple(sub(v) for v in values)

    return dataclasses.replace(
        body,
        position=many(body.position),
        mass=sub(body.mass),
        inertia=many(body.inertia),
        angular_velocity=many(body.angular_velocity),
        rotation=None if body.rotation is None else tuple(many(row) for row in body.rotation),
        points={k: many(v) for k, v in body.points.items()},
        forces=tuple((many(f), many(x)) for f, x in body.forces),
        torques=tuple(many(v) for v in body.torques),
        local=None if body.local is None else tuple(many(row) for row in body.local),
        velocity=None if body.velocity is None else many(body.velocity),
        frame_forces=tuple((many(f), many(v)) for f, v in body.frame_forces),
    )


def _kinks(forms: SymengineForms, spec: SystemSpec) -> tuple[SymengineForms, dict[str, object]]:
    """Derivatives of Abs and sign, which symengine leaves as `Derivative(Abs(u), v)`, taken in sympy
    (`_sp`): d|u|/dv = sign(u) du/dv, and a Dirac delta that vanishes where it sits dropped. Only a file
    with Abs or sign has them; its fields are then computed in sympy here (and the symengine forms
    converted back), the rest of the time nothing is converted. Called only for forms that
    `validate.survey` did not clear (a derivative of Abs is one of the nodes it does not clear)."""
    if not any(e.has(sp.Abs, sp.sign) for source in sources(spec) for e in source.exprs):
        return forms, {}
    converted: dict[str, object] = {}

    def one(value: se.Basic) -> tuple[se.Basic, sp.Expr]:
        result = _sp(value)
        try:
            return to_symengine(result), result
        except TypeError:  # a Dirac delta that stays: `validate` refuses it at the entry it comes from
            return value, result

    def many(values: Sequence[se.Basic]) -> tuple[tuple[se.Basic, ...], tuple[sp.Expr, ...]]:
        pairs = [one(v) for v in values]
        return tuple(a for a, _ in pairs), tuple(b for _, b in pairs)

    changes: dict[str, Any] = {}
    for name in ("kinetic", "potential", "lagrangian", "dissipation", "energy"):
        changes[name], converted[name] = one(getattr(forms, name))
    for name in ("momenta", "generalized_forces"):
        changes[name], converted[name] = many(getattr(forms, name))
    changes["forcing"], forcing = many(forms.forcing)
    converted["forcing"] = sp.ImmutableMatrix(len(forcing), 1, forcing)
    rows = [many(row) for row in forms.mass]
    changes["mass"] = tuple(a for a, _ in rows)
    converted["mass_matrix"] = sp.ImmutableMatrix(len(rows), len(rows), [e for _, b in rows for e in b])
    return dataclasses.replace(forms, **changes), converted


def _se_constraint(constraint: Constraint) -> Constraint:
    return dataclasses.replace(constraint, expr=to_symengine(constraint.expr))


def _masses(spec: SystemSpec) -> tuple[Particle | Body, ...]:
    return (*spec.particles, *spec.bodies)


def _se(values: Iterable[sp.Expr]) -> list[se.Basic]:
    return [_to_se(v) for v in values]


_CONVERTED: dict[int, tuple[object, se.Basic]] = {}
"""`_to_se`'s results during one `derive` (by the identity of the sympy expression, kept alive here)."""


def _to_se(expr: object) -> se.Basic:
    """`to_symengine`, each expression of the file converted once per derivation (a chain link's
    position is read for its kinetic energy, its weight and its kind)."""
    hit = _CONVERTED.get(id(expr))
    if hit is not None and hit[0] is expr:
        return hit[1]
    value = to_symengine(expr, _CONVERTED)  # also each shared sub-expression once
    return value


def _sp(value: se.Basic) -> sp.Expr:
    """Back to sympy; derivatives of Abs and sign (real arguments) taken explicitly: the
    derivative of sign is a Dirac delta, which `validate` refuses at the entry it comes from."""
    result = sp.sympify(value)
    if result.has(sp.Derivative):
        result = result.replace(
            lambda e: isinstance(e, sp.Derivative) and isinstance(e.expr, (sp.Abs, sp.sign)),
            _kink_derivative,
        )
        if result.has(sp.DiracDelta):
            result = result.replace(lambda e: isinstance(e, sp.Mul) and e.has(sp.DiracDelta), _null_delta)
    return result


def _null_delta(term: sp.Mul) -> sp.Expr:
    """c(v) DiracDelta(u(v)) is 0 when c is continuous and vanishes where u does (x**2 DiracDelta(x),
    from the derivative of sign(x)*x**2, which is smooth): only for u linear in one variable."""
    deltas = [f for f in term.args if isinstance(f, sp.DiracDelta) and len(f.args) == 1]
    if len(deltas) != 1:
        return term
    u = deltas[0].args[0]
    variables = u.free_symbols
    if len(variables) != 1:
        return term
    (v,) = variables
    slope = sp.diff(u, v)
    if slope == 0 or slope.has(v):
        return term
    root = v - u / slope
    coefficient = sp.Mul(*(f for f in term.args if f is not deltas[0]))
    if coefficient.has(sp.sign):  # not continuous where u = 0: sign(x) DiracDelta(x) has no value
        return term
    at_root = coefficient.subs(v, sp.expand(root))
    return sp.Integer(0) if at_root == 0 else term


def _kink_derivative(e: sp.Derivative) -> sp.Expr:
    """d|u|/dv = sign(u) du/dv; anything more (d sign(u)/dv, d^2|u|/dv^2) has a Dirac delta at u = 0."""
    u = e.expr.args[0]
    if isinstance(e.expr, sp.Abs) and len(e.variables) == 1:
        return sp.sign(u) * sp.diff(u, e.variables[0])
    return 2 * sp.DiracDelta(u) * sp.diff(u, e.variables[0])


def _has(expr: se.Basic, symbol: se.Basic) -> bool:
    return symbol in expr.free_symbols
