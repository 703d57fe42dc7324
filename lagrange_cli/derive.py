"""The core: Lagrange's equations from a `SystemSpec`, computed with symengine.

Everything here follows the textbook derivation term by term:

    K = 1/2 sum m x_dot^2,   x_dot = sum dx/dq q_dot + dx/dt        (Eqs. 6.10-6.11)
    L = K - U (+ extra Lagrangian terms)                              (Eq. 6.21)
    Q_i = sum_j f_j dx_j/dq_i                                         (Eq. 6.6)
    d/dt(dL/dq_dot_i) - dL/dq_i + dR/dq_dot_i = Q_i (+ sum_k lambda_k a_ki)

The time derivative is taken by the chain rule with q, q_dot, q_ddot as plain symbols,
which splits each equation into `M q_ddot - F`. Symengine does the differentiation
(two orders of magnitude faster than sympy); results are handed back as sympy.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence

import sympy as sp

from lagrange_cli._symengine import se, to_symengine
from lagrange_cli.algebra import combine_trig
from lagrange_cli.errors import fail
from lagrange_cli.model import ConstraintRow, Model
from lagrange_cli.spec import Body, Constraint, Particle, SystemSpec, time_derivative

Vector = list[se.Basic]


def derive(spec: SystemSpec) -> Model:
    """File to equations: eliminate constraints, build L and R, apply Lagrange's equation."""
    spec = eliminate(spec)
    q, qd, t = _se(spec.q), _se(spec.qd), to_symengine(spec.t)
    kinetic = combine_trig(kinetic_energy(spec) + to_symengine(spec.kinetic))
    potential = potential_energy(spec)
    lagrangian = kinetic - potential + to_symengine(spec.lagrangian)
    dissipation = combine_trig(rayleigh(spec))
    forces = generalized_forces(spec)
    if any(_has(lagrangian, s) for s in _se(spec.qdd)):
        raise fail(None, f"{spec.path}: the Lagrangian depends on accelerations", "a Lagrangian of coordinates, velocities and time")
    p = momenta(lagrangian, qd)
    mass, force = euler_lagrange(lagrangian, dissipation, forces, q, qd, t)
    for i, name in enumerate(spec.coordinates):
        if all(m == 0 for m in mass[i]) and force[i] == 0 and not any(_has(c.expr, se.Symbol(name)) or _has(c.expr, qd[i]) for c in map(_se_constraint, spec.constraints)):
            raise fail(
                spec.spans.get(name), f"coordinate '{name}' appears nowhere in the energies or forces: its equation would be 0 = 0", "a coordinate that the positions, energies or forces depend on"
            )
    return Model(
        title=spec.title,
        source=spec.path,
        coordinates=spec.coordinates,
        q=spec.q,
        qd=spec.qd,
        qdd=spec.qdd,
        t=spec.t,
        parameters=spec.parameters,
        kinetic=_sp(kinetic),
        potential=_sp(potential),
        lagrangian=_sp(lagrangian),
        dissipation=_sp(dissipation),
        generalized_forces=tuple(_sp(f) for f in forces),
        mass_matrix=sp.ImmutableMatrix(len(q), len(q), [_sp(m) for row in mass for m in row]),
        forcing=sp.ImmutableMatrix([_sp(f) for f in force]),
        momenta=tuple(_sp(x) for x in p),
        energy=_sp(energy_function(lagrangian, p, qd)),
        constraints=tuple(constraint_row(c, spec) for c in spec.constraints),
        eliminated=getattr(spec, "_eliminated", ()),
        description=spec.description,
        initial=spec.initial,
        simulate=spec.simulate,
        exact=spec.exact,
        spans=spec.spans,
        definitions=spec.definitions,
    )


def kinetic_energy(spec: SystemSpec) -> se.Basic:
    """K = sum 1/2 m |x_dot|^2 over particles and bodies, plus 1/2 I omega^2 (planar)
    or 1/2 sum I_k omega_k^2 (spatial, principal body axes) for bodies."""
    q, qd, t = _se(spec.q), _se(spec.qd), to_symengine(spec.t)
    total = se.Integer(0)
    for item in _masses(spec):
        v = velocity(_se(item.position), q, qd, t)
        total += to_symengine(item.mass) * sum((vi**2 for vi in v), se.Integer(0)) / 2
    for body in spec.bodies:
        inertia, omega = _se(body.inertia), _se(body.angular_velocity)
        total += sum((i * w**2 for i, w in zip(inertia, omega, strict=True)), se.Integer(0)) / 2
    return total


def velocity(position: Sequence[se.Basic], q: Sequence[se.Basic], qd: Sequence[se.Basic], t: se.Basic) -> Vector:
    """x_dot_j = sum_i dx_j/dq_i q_dot_i + dx_j/dt  (Eq. 6.11)."""
    return [sum((se.diff(x, qi) * qdi for qi, qdi in zip(q, qd, strict=True)), se.diff(x, t)) for x in position]


def potential_energy(spec: SystemSpec) -> se.Basic:
    """U = U_file - sum m g . x over particles and bodies (a uniform field g)."""
    total = to_symengine(spec.potential)
    if spec.gravity is not None:
        g = _se(spec.gravity)
        for item in _masses(spec):
            total -= to_symengine(item.mass) * sum((gi * xi for gi, xi in zip(g, _se(item.position), strict=True)), se.Integer(0))
    return total


def rayleigh(spec: SystemSpec) -> se.Basic:
    """R = R_file + sum 1/2 k |x_dot|^2 over damped particles (Exercise 6.9)."""
    q, qd, t = _se(spec.q), _se(spec.qd), to_symengine(spec.t)
    total = to_symengine(spec.dissipation)
    for particle in spec.particles:
        if particle.damping is not None:
            v = velocity(_se(particle.position), q, qd, t)
            total += to_symengine(particle.damping) * sum((vi**2 for vi in v), se.Integer(0)) / 2
    return total


def generalized_forces(spec: SystemSpec) -> Vector:
    """Q_i = Q_file,i + sum_j f_j dx_j/dq_i over particles with a force (Eq. 6.6)."""
    q = _se(spec.q)
    forces = [to_symengine(f) for f in spec.generalized_forces] or [se.Integer(0)] * len(q)
    for particle in spec.particles:
        if particle.force is not None:
            f, x = _se(particle.force), _se(particle.position)
            for i, qi in enumerate(q):
                forces[i] += sum((fj * se.diff(xj, qi) for fj, xj in zip(f, x, strict=True)), se.Integer(0))
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
    """Expand so that like terms cancel, unless a high power of a sum would explode."""
    if any(isinstance(a, se.Pow) and isinstance(a.args[0], se.Add) and a.args[1].is_Integer and abs(int(a.args[1])) > 6 for a in _atoms(expr)):
        return expr
    return se.expand(expr)


def _atoms(expr: se.Basic) -> list[se.Basic]:
    stack, seen = [expr], []
    while stack:
        node = stack.pop()
        seen.append(node)
        stack.extend(node.args)
    return seen


def energy_function(lagrangian: se.Basic, p: Sequence[se.Basic], qd: Sequence[se.Basic]) -> se.Basic:
    """h = sum p_i q_dot_i - L, conserved when L has no explicit t and nothing dissipates."""
    return _expand(sum((pi * v for pi, v in zip(p, qd, strict=True)), se.Integer(0)) - lagrangian)


def constraint_row(constraint: Constraint, spec: SystemSpec) -> ConstraintRow:
    """Velocity form a . q_dot + b = 0 (a = df/dq, b = df/dt when holonomic) and its derivative
    a . q_ddot + c = 0 with c = (da/dt) . q_dot + db/dt."""
    q, qd, qdd, t = spec.q, spec.qd, spec.qdd, spec.t
    expr = constraint.expr
    velocity_form = time_derivative(expr, q, qd, qdd, t) if constraint.holonomic else expr
    a = tuple(sp.expand(sp.diff(velocity_form, v)) for v in qd)
    b = sp.expand(velocity_form.subs({v: 0 for v in qd}))
    c = time_derivative(sp.expand(velocity_form), q, qd, qdd, t).subs({v: 0 for v in qdd})
    return ConstraintRow(constraint.name, expr, constraint.holonomic, sp.Symbol(f"lambda_{constraint.name}"), a, b, sp.expand(c))


def eliminate(spec: SystemSpec) -> SystemSpec:
    """Remove each coordinate listed under `eliminate` by solving a holonomic constraint for it
    and substituting q = g(...), q_dot = dg/dt everywhere; its generalized force is carried over
    by virtual work, Q_j += Q_q dg/dq_j."""
    for name, span in spec.eliminate:
        k = spec.coordinates.index(name)
        qk = spec.q[k]
        solution, used = None, None
        for constraint in spec.constraints:
            if constraint.holonomic and constraint.expr.has(qk):
                solutions = _solve(constraint.expr, qk)
                if len(solutions) == 1:
                    solution, used = solutions[0], constraint
                    break
                if len(solutions) > 1:
                    raise fail(
                        span, f"constraint '{constraint.name}' has {len(solutions)} solutions for '{name}'", "a constraint with a single solution for the eliminated coordinate, or keep the multiplier"
                    )
        if solution is None or used is None:
            velocity = [c.name for c in spec.constraints if not c.holonomic and c.expr.has(spec.qd[k])]
            hint = f"; '{velocity[0]}' is a velocity constraint: if it integrates to a relation between coordinates, write that relation instead" if velocity else ""
            raise fail(span, f"no holonomic constraint can be solved for '{name}'", f"a holonomic constraint under `constraints` that involves '{name}' and can be solved for it{hint}")
        spec = _substitute(spec, k, solution, used)
    return spec


def _solve(expr: sp.Expr, symbol: sp.Symbol) -> list[sp.Expr]:
    if sp.diff(expr, symbol, 2) == 0:
        slope = sp.diff(expr, symbol)
        return [sp.simplify(-expr.subs(symbol, 0) / slope)] if slope != 0 else []
    if sp.count_ops(expr) > 60:
        return []
    try:
        return list(sp.solve(expr, symbol))
    except NotImplementedError:
        return []


def _substitute(spec: SystemSpec, k: int, solution: sp.Expr, used: Constraint) -> SystemSpec:
    q, qd, qdd, t = spec.q, spec.qd, spec.qdd, spec.t
    keep = [i for i in range(len(q)) if i != k]
    rq, rqd, rqdd = (tuple(v[i] for i in keep) for v in (q, qd, qdd))
    rate = time_derivative(solution, rq, rqd, rqdd, t)
    mapping = {q[k]: solution, qd[k]: rate, qdd[k]: time_derivative(rate, rq, rqd, rqdd, t)}

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
        bodies=tuple(dataclasses.replace(b, position=subs_all(b.position), mass=sub(b.mass), inertia=subs_all(b.inertia), angular_velocity=subs_all(b.angular_velocity)) for b in spec.bodies),
        kinetic=sub(spec.kinetic),
        potential=sub(spec.potential),
        lagrangian=sub(spec.lagrangian),
        dissipation=sub(spec.dissipation),
        generalized_forces=forces,
        constraints=tuple(dataclasses.replace(c, expr=sub(c.expr)) for c in spec.constraints if c is not used),
        eliminate=tuple(e for e in spec.eliminate if e[0] != spec.coordinates[k]),
        initial={key: v for key, v in spec.initial.items() if key not in (spec.coordinates[k], f"{spec.coordinates[k]}_dot")},
    )
    object.__setattr__(changed, "_eliminated", (*getattr(spec, "_eliminated", ()), (spec.coordinates[k], solution)))
    return changed


def _se_constraint(constraint: Constraint) -> Constraint:
    return dataclasses.replace(constraint, expr=to_symengine(constraint.expr))


def _masses(spec: SystemSpec) -> tuple[Particle | Body, ...]:
    return (*spec.particles, *spec.bodies)


def _se(values: Iterable[sp.Expr]) -> list[se.Basic]:
    return [to_symengine(v) for v in values]


def _sp(value: se.Basic) -> sp.Expr:
    """Back to sympy; derivatives of Abs and sign (real arguments) taken explicitly."""
    result = sp.sympify(value)
    if result.has(sp.Derivative):
        result = result.replace(
            lambda e: isinstance(e, sp.Derivative) and isinstance(e.expr, (sp.Abs, sp.sign)),
            lambda e: sp.sign(e.expr.args[0]) * sp.diff(e.expr.args[0], *e.variables) if isinstance(e.expr, sp.Abs) else sp.Integer(0),
        )
    return result


def _has(expr: se.Basic, symbol: se.Basic) -> bool:
    return symbol in expr.free_symbols
