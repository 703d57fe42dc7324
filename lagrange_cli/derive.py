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
from itertools import combinations

import sympy as sp

from lagrange_cli._symengine import se, to_symengine
from lagrange_cli.errors import DerivationError, fail
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
        force.append(se.expand(fi))
    return [[se.expand(m) for m in row] for row in mass], force


def energy_function(lagrangian: se.Basic, p: Sequence[se.Basic], qd: Sequence[se.Basic]) -> se.Basic:
    """h = sum p_i q_dot_i - L, conserved when L has no explicit t and nothing dissipates."""
    return se.expand(sum((pi * v for pi, v in zip(p, qd, strict=True)), se.Integer(0)) - lagrangian)


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
            raise fail(span, f"no holonomic constraint can be solved for '{name}'", f"a holonomic constraint under `constraints` that involves '{name}' and can be solved for it")
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


def combine_trig(expr: se.Basic) -> se.Basic:
    """Targeted, linear-time trigonometric simplification of an expanded sum:
    c cos a cos b + c sin a sin b -> c cos(a - b), c cos a cos b - c sin a sin b -> c cos(a + b),
    c sin a cos b +- c cos a sin b -> c sin(a +- b), c sin^2 a + c cos^2 a -> c.
    It only ever shortens the sum, so it is safe on expressions of any size."""
    expr = se.expand(expr)
    for _ in range(6):
        combined = _combine_once(expr)
        if combined == expr:
            break
        expr = se.expand(combined)
    return expr


def _combine_once(expr: se.Basic) -> se.Basic:
    terms = list(expr.args) if isinstance(expr, se.Add) else [expr]
    parsed = [_factors(term) for term in terms]
    groups: dict[tuple[object, ...], list[tuple[int, str]]] = {}
    for index, (_, factors) in enumerate(parsed):
        trig = [f for f in factors if isinstance(f, (se.sin, se.cos))]
        for f in trig:
            if factors[f] == 2:
                rest = frozenset((b, e) for b, e in factors.items() if b != f)
                groups.setdefault(("square", f.args[0], rest), []).append((index, "s" if isinstance(f, se.sin) else "c"))
        single = sorted((f for f in trig if factors[f] == 1), key=lambda f: (str(f.args[0]), isinstance(f, se.sin)))
        for f, g in combinations(single, 2):
            if f.args[0] == g.args[0]:
                continue
            if str(f.args[0]) > str(g.args[0]):
                f, g = g, f
            rest = frozenset((b, e) for b, e in factors.items() if b not in (f, g))
            kind = ("s" if isinstance(f, se.sin) else "c") + ("s" if isinstance(g, se.sin) else "c")
            groups.setdefault(("pair", f.args[0], g.args[0], rest), []).append((index, kind))
    used: set[int] = set()
    extra: list[se.Basic] = []
    for key, members in groups.items():
        by_kind: dict[str, int] = {}
        for index, kind in members:
            if index not in used:
                by_kind.setdefault(kind, index)
        rest = se.Mul(*(b**e for b, e in key[-1]))  # type: ignore[attr-defined]
        for k1, k2 in (("s", "c"),) if key[0] == "square" else (("cc", "ss"), ("sc", "cs")):
            if k1 in by_kind and k2 in by_kind:
                i, j = by_kind[k1], by_kind[k2]
                merged = _merge(k1, parsed[i][0], parsed[j][0], key)
                if merged is not None:
                    used.update((i, j))
                    extra.append(merged * rest)
    if not used:
        return expr
    return se.Add(*(term for index, term in enumerate(terms) if index not in used), *extra)


def _merge(kind: str, c1: se.Basic, c2: se.Basic, key: tuple[object, ...]) -> se.Basic | None:
    """The single term replacing c1 f + c2 g, if the identity for this pair applies."""
    if kind == "s":
        return c1 if c1 == c2 else None
    a, b = se.sympify(key[1]), se.sympify(key[2])
    if kind == "cc":
        return c1 * se.cos(a - b) if c1 == c2 else (c1 * se.cos(a + b) if c1 == -c2 else None)
    return c1 * se.sin(a + b) if c1 == c2 else (c1 * se.sin(a - b) if c1 == -c2 else None)


def _factors(term: se.Basic) -> tuple[se.Basic, dict[se.Basic, se.Basic]]:
    """A product as (numeric coefficient, {base: exponent})."""
    coefficient: se.Basic = se.Integer(1)
    factors: dict[se.Basic, se.Basic] = {}
    for factor in term.args if isinstance(term, se.Mul) else (term,):
        if factor.is_Number:
            coefficient *= factor
        elif isinstance(factor, se.Pow):
            base, exponent = factor.args
            factors[base] = factors.get(base, 0) + exponent
        else:
            factors[factor] = factors.get(factor, 0) + 1
    return coefficient, factors


def solved_accelerations(model: Model, max_size: int = 4) -> tuple[sp.Expr, ...]:
    """q_ddot (and the multipliers) solved symbolically by Cramer's rule, only for small systems.

    The solved form grows explosively (hundreds of operations at two coordinates, millions
    at six), so larger systems are refused; numeric code solves M q_ddot = F at run time.
    """
    size = model.n + len(model.constraints)
    if size > max_size:
        raise DerivationError(
            f"{model.source}: the solved form of a system with {size} unknowns would be enormous "
            f"(at most {max_size} are solved symbolically); use `--form matrix`, or `--python`, "
            "whose code solves M q_ddot = F numerically"
        )
    matrix, rhs = augmented(model)
    check_invertible(model, matrix)
    det = _sp(combine_trig(to_symengine(matrix.det(method="berkowitz"))))
    result = []
    for i in range(size):
        replaced = matrix.copy()
        replaced[:, i] = rhs
        numerator = _sp(combine_trig(to_symengine(replaced.det(method="berkowitz"))))
        result.append(sp.factor_terms(sp.cancel(numerator / det)))
    return tuple(result)


def augmented(model: Model) -> tuple[sp.Matrix, sp.Matrix]:
    """[[M, -A^T], [A, 0]] [q_ddot; lambda] = [F; -c], the index-1 form of a constrained system."""
    a = model.constraint_matrix
    k = len(model.constraints)
    top = sp.Matrix(model.mass_matrix).row_join(-a.T) if k else sp.Matrix(model.mass_matrix)
    matrix = top.col_join(a.row_join(sp.zeros(k, k))) if k else top
    rhs = sp.Matrix(model.forcing).col_join(sp.Matrix([-c.acceleration_bias for c in model.constraints])) if k else sp.Matrix(model.forcing)
    return matrix, rhs


def check_invertible(model: Model, matrix: sp.Matrix | None = None) -> None:
    """Raise a `DerivationError` naming the coordinates without inertia if M (or the augmented
    matrix of a constrained system) is singular at a generic point."""
    if matrix is None:
        matrix = augmented(model)[0]
    zero_rows = [model.coordinates[i] for i in range(model.n) if all(matrix[i, j] == 0 for j in range(matrix.cols))]
    if zero_rows:
        raise DerivationError(
            f"{model.source}: the mass matrix is singular: coordinate{'s' * (len(zero_rows) > 1)} "
            f"{', '.join(repr(z) for z in zero_rows)} {'have' if len(zero_rows) > 1 else 'has'} no inertia "
            "(no kinetic energy depends on its velocity); give it a mass, or remove it with a constraint and `eliminate`"
        )
    if pivot_ratio(matrix, model) < 1e-12:
        raise DerivationError(
            f"{model.source}: the mass matrix{' (with the constraint rows)' if model.constraints else ''} is singular: "
            "the coordinates are not independent, or some have no inertia; the accelerations cannot be solved for"
        )


def pivot_ratio(matrix: sp.Matrix, model: Model, seed: int = 1) -> float:
    """Smallest over largest pivot of A (rows scaled to unit norm) at a random point: about
    1/condition number, and at rounding level when A is singular.

    Evaluated in floating point with a pure-Python LU (no numpy in the derive path)."""
    import random

    rng = random.Random(seed)
    point = {to_symengine(s): se.RealDouble(p.value if p.value else rng.uniform(0.5, 2.0)) for p in model.parameters for s in (p.symbol,)}
    point.update({to_symengine(s): se.RealDouble(rng.uniform(0.2, 1.3)) for s in (*model.q, *model.qd, model.t)})
    rows = [[float(to_symengine(matrix[i, j]).subs(point)) if matrix[i, j] != 0 else 0.0 for j in range(matrix.cols)] for i in range(matrix.rows)]
    pivots = []
    for row in rows:
        norm = sum(x * x for x in row) ** 0.5
        if norm == 0.0:
            return 0.0
        row[:] = [x / norm for x in row]
    n = len(rows)
    for k in range(n):
        pivot = max(range(k, n), key=lambda i: abs(rows[i][k]))
        if rows[pivot][k] == 0.0:
            return 0.0
        rows[k], rows[pivot] = rows[pivot], rows[k]
        pivots.append(abs(rows[k][k]))
        for i in range(k + 1, n):
            factor = rows[i][k] / rows[k][k]
            for j in range(k, n):
                rows[i][j] -= factor * rows[k][j]
    return min(pivots) / max(pivots)


def _masses(spec: SystemSpec) -> tuple[Particle | Body, ...]:
    return (*spec.particles, *spec.bodies)


def _se(values: Iterable[sp.Expr]) -> list[se.Basic]:
    return [to_symengine(v) for v in values]


def _sp(value: se.Basic) -> sp.Expr:
    return sp.sympify(value)


def _has(expr: se.Basic, symbol: se.Basic) -> bool:
    return symbol in expr.free_symbols
