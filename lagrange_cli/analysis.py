"""What the equations say beyond themselves: generalized momenta and conserved quantities,
the Hamiltonian, equilibrium points, the linearization about them, and stability.

    p_i = dL/dq_dot_i                            (Eq. 6.35)
    q_k ignorable (dL/dq_k = 0)  =>  p_k = const  (Eqs. 6.37-6.38)
    h = sum p_i q_dot_i - L,  H(q, p) = h at q_dot = M^-1 (p - b)
    M0 x_ddot + C0 x_dot + K0 x = 0,  K0 = -dF/dq,  C0 = -dF/dq_dot  at (q0, 0)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import sympy as sp
from sympy.core.function import AppliedUndef

from lagrange_cli.algebra import expandable, tame_numbers
from lagrange_cli.errors import DerivationError, Span, fail
from lagrange_cli.expr import Scope, numeric_value, parse_expression
from lagrange_cli.model import Model

HAMILTONIAN_MAX_N = 3


@dataclass(frozen=True)
class Info:
    """The structure of a system: what is conserved, and its Hamiltonian where it can be written."""

    coordinates: tuple[str, ...]
    degrees_of_freedom: int
    momenta: tuple[sp.Expr, ...]
    ignorable: tuple[str, ...]
    energy: sp.Expr
    energy_conserved: bool
    hamiltonian: sp.Expr | None
    hamiltonian_note: str
    momentum_symbols: tuple[sp.Symbol, ...]
    autonomous: bool
    conservative: bool
    constraints: tuple[tuple[str, str, str], ...]


def info(model: Model) -> Info:
    """Momenta, ignorable coordinates, energy function, Hamiltonian and the system's kind."""
    ignorables = tuple(c for i, c in enumerate(model.coordinates) if model.ignorable(i))
    symbols = tuple(sp.Symbol(f"p_{c}") for c in model.coordinates)
    hamiltonian, note = _hamiltonian(model, symbols)
    kinds = tuple((c.name, "holonomic" if c.holonomic else "velocity", str(c.multiplier)) for c in model.constraints)
    return Info(
        coordinates=model.coordinates,
        degrees_of_freedom=model.n - sum(1 for c in model.constraints),
        momenta=tuple(sp.factor_terms(p) for p in model.momenta),
        ignorable=ignorables,
        energy=sp.factor_terms(model.energy),
        energy_conserved=model.energy_conserved,
        hamiltonian=hamiltonian,
        hamiltonian_note=note,
        momentum_symbols=symbols,
        autonomous=model.autonomous,
        conservative=not model.dissipative and not model.forced,
        constraints=kinds,
    )


def _hamiltonian(model: Model, p: tuple[sp.Symbol, ...]) -> tuple[sp.Expr | None, str]:
    """H(q, p) = 1/2 (p - b)^T M^-1 (p - b) - L0 for L = 1/2 q_dot^T M q_dot + b . q_dot + L0."""
    if any(model.mass_matrix.has(v) for v in model.qd):
        return None, "the Lagrangian is not quadratic in the velocities"
    if model.n > HAMILTONIAN_MAX_N and not sp.Matrix(model.mass_matrix).is_diagonal():
        return None, f"not written for more than {HAMILTONIAN_MAX_N} coordinates with a mass matrix that is not diagonal (M^-1 grows too large)"
    zero = {v: 0 for v in model.qd}
    b = sp.Matrix([sp.diff(model.lagrangian, v).xreplace(zero) for v in model.qd])
    l0 = model.lagrangian.xreplace(zero)
    mass = sp.Matrix(model.mass_matrix)
    det = mass.det()
    det = sp.factor_terms(sp.trigsimp(det) if sp.count_ops(det) <= SIMPLIFY_MAX_OPS and tame_numbers(det) else det)
    if det == 0:
        return None, "the mass matrix is singular (the Legendre transform does not exist)"
    shifted = sp.Matrix(p) - b
    adjugate = mass.adjugate()
    quadratic = (shifted.T * adjugate * shifted)[0]
    hamiltonian = sp.factor_terms(sp.expand(quadratic) / (2 * det) - l0)
    if model.constraints:
        names = ", ".join(c.name for c in model.constraints)
        return hamiltonian, (
            f"H is the Legendre transform of the Lagrangian without its kept constraints ({names}); they hold separately, "
            "and their forces enter Hamilton's equations through the multipliers: q_dot = dH/dp, p_dot = -dH/dq + A^T lambda, with A q_dot + b = 0"
        )
    return hamiltonian, ""


# -- equilibria and linearization -----------------------------------------------------------


@dataclass(frozen=True)
class Linearization:
    """M0 x_ddot + C0 x_dot + K0 x = 0 about `point`, with its numeric modes at `values`.

    With kept holonomic constraints x holds the perturbations of the independent coordinates
    `coordinates` (the others follow from the tangent space, `dependent`); with velocity
    constraints the motion is the first-order system z_dot = `state` z (numeric), where z holds
    the perturbations of `coordinates` and of the independent velocities `velocities`."""

    point: Mapping[sp.Symbol, sp.Expr]
    mass: sp.Matrix
    damping: sp.Matrix
    stiffness: sp.Matrix
    stability: str
    condition: tuple[sp.Expr, ...] = ()
    neutral: tuple[str, ...] = ()
    frequencies: tuple[float, ...] = ()
    modes: tuple[tuple[float, ...], ...] = ()
    eigenvalues: tuple[complex, ...] = ()
    values: Mapping[str, float] = field(default_factory=dict)
    coordinates: tuple[str, ...] = ()
    multipliers: Mapping[sp.Symbol, sp.Expr] = field(default_factory=dict)
    dependent: tuple[tuple[str, sp.Expr], ...] = ()
    velocities: tuple[str, ...] = ()
    dependent_velocities: tuple[tuple[str, sp.Expr], ...] = ()
    state: tuple[tuple[float, ...], ...] = ()
    note: str = ""


SOLVE_MAX_OPS = 120
"""Largest system (sympy operation count of all its equations) handed to `sympy.solve`; beyond
it the search for equilibria is numeric. A size bound, not a time limit: the answer never
depends on the machine's load."""
SOLVE_MAX_UNKNOWNS = 4
"""Most unknowns (coordinates and multipliers) solved for symbolically."""
SIMPLIFY_MAX_OPS = 150
"""Largest expression `sympy.simplify` is applied to; larger ones get linear-time tidying only."""


def simplified(expr: sp.Expr) -> sp.Expr:
    """`sympy.simplify` for small expressions, `factor_terms` beyond `SIMPLIFY_MAX_OPS` operations
    (a size bound: simplify's time on a large expression has no bound)."""
    expr = sp.sympify(expr)
    if expr.is_number and expr.is_Atom:
        return expr
    if sp.count_ops(expr) > SIMPLIFY_MAX_OPS or not expandable(expr) or not tame_numbers(expr):
        return sp.factor_terms(expr)
    return sp.simplify(expr)


def factored(expr: sp.Expr) -> sp.Expr:
    """`sympy.factor` within the same size bound as `simplified`, else `factor_terms`."""
    expr = sp.sympify(expr)
    if sp.count_ops(expr) > SIMPLIFY_MAX_OPS or not expandable(expr) or not tame_numbers(expr):
        return sp.factor_terms(expr)
    return sp.factor(expr)


def at(expr: sp.Expr, values: Mapping[sp.Symbol, sp.Expr]) -> sp.Expr:
    """`expr` at `values`, keeping derivatives of functions valid: `Derivative(U(r), r)` at r = 1
    becomes `Subs(Derivative(U(r), r), r, 1)` (xreplace would differentiate with respect to 1)."""
    expr = sp.sympify(expr)
    if not expr.has(sp.Derivative, sp.Subs):
        return expr.xreplace(dict(values))
    return expr.subs(dict(values), simultaneous=True)


def _undefined(expressions: Sequence[sp.Expr]) -> list[str]:
    return sorted({str(f.func) for e in expressions for f in sp.sympify(e).atoms(AppliedUndef)})


def _refuse_undefined(model: Model, what: str, expressions: Sequence[sp.Expr]) -> None:
    undefined = _undefined(expressions)
    if undefined:
        one = len(undefined) == 1
        raise DerivationError(
            f"{model.source}: {what} needs every function defined, but {', '.join(undefined)} {'is' if one else 'are'} left undefined; "
            f"give {'it' if one else 'each'} a `definition` under `functions:` (whether the point is an equilibrium depends on {'its' if one else 'their'} values there)"
        )


def _check_constraints_allow_rest(model: Model) -> None:
    """Time-dependent constraints move the equilibria; a velocity constraint with a term free of
    velocities (a ≠ 0 b) does not allow rest at all."""
    if not model.autonomous:
        raise DerivationError(f"{model.source}: the system depends explicitly on time, so it has no fixed equilibria (a moving support, a driving force or a time-dependent constraint)")
    rest = {v: 0 for v in model.qd}
    for c in model.constraints:
        if not c.holonomic and c.bias.xreplace(rest) != 0 and not any(c.bias.has(q) for q in model.q):
            raise DerivationError(f"{model.source}: the velocity constraint '{c.name}' does not allow rest (its velocity-free term {c.bias} is not zero), so the system has no equilibria")


def point_value(model: Model, name: str, text: str, span: Span) -> sp.Expr:
    """A coordinate's value at an operating point, given as text: a number (`pi/2`) or an
    expression in the file's parameters (`L + g*m/k`, as `equilibria` prints it), kept exact, so
    that the linearization is in those parameters. Coordinates, velocities and `t` are refused with
    a caret at `span`, and so is a value that is not a finite real number at the parameters' values."""
    symbols = {p.name: p.symbol for p in model.parameters}
    others = {c: "a coordinate" for c in model.coordinates} | {f"{c}_dot": "a velocity" for c in model.coordinates} | {"t": "the time"}
    scope = Scope(symbols, {}, sp.Symbol("t"), lambda e: e, what="numbers, pi, E, the parameters and functions of them", elsewhere={k: v for k, v in others.items() if k not in symbols})
    value = parse_expression(text, span, scope)
    values = {p.symbol: p.value for p in model.parameters if p.value is not None}
    if value.free_symbols - set(values):
        return value  # a parameter without a value: the point stays symbolic in it
    try:
        number = numeric_value(value, values)
    except (ValueError, OverflowError, TypeError):
        number = math.nan
    if not math.isfinite(number):
        example = f", or an expression in the parameters such as {' + '.join(list(symbols)[:2])}" if symbols else ""
        raise fail(span, f"the value of '{name}' must be a finite real number at the parameters' values, got '{text.strip()}'", f"a number such as 0 or pi/2{example}")
    return value


class NotAnEquilibrium(DerivationError):
    """The point asked for is not an equilibrium (the CLI adds how to find one)."""


def linearize(model: Model, point: Mapping[sp.Symbol, sp.Expr], values: Mapping[str, float] | None = None) -> Linearization:
    """Linearize about an equilibrium (q0, q_dot = 0): K0 = -d(F + A^T lambda0)/dq, C0 = -dF/dq_dot,
    M0 = M(q0), reduced to independent coordinates (and velocities) when constraints are kept."""
    _check_constraints_allow_rest(model)
    general = model
    model = model.with_definitions()
    point = {q: sp.sympify(point.get(q, sp.Integer(0))) for q in model.q}  # coordinates not given are 0
    full = {**point, **{v: sp.Integer(0) for v in model.qd}}
    values = dict(values if values is not None else model.parameter_values())
    forcing = [at(f, full) for f in model.forcing]
    rows = model.constraint_matrix
    a0 = sp.Matrix(rows.rows, rows.cols, [simplified(at(a, full)) for a in rows]) if model.constraints else sp.zeros(0, model.n)
    off = [(c.name, simplified(at(c.expr, full))) for c in model.constraints if c.holonomic]
    off += [(c.name, simplified(at(c.bias, full))) for c in model.constraints if not c.holonomic]
    off = [(name, r) for name, r in off if r != 0 and not _numerically_zero([r], values)]
    if off:
        _refuse_undefined(general, "linearize", [r for _, r in off])
        raise DerivationError(f"{model.source}: {_point_text(point)} is not on the constraint surface: {', '.join(f'{name} leaves {r}' for name, r in off)}")
    multipliers: dict[sp.Symbol, sp.Expr] = {}
    dependent_rows: list[int] = []
    if model.constraints:
        dependent_rows = _pivots(a0, values, model)
        block = a0.extract(list(range(a0.rows)), dependent_rows)
        lam = block.T.LUsolve(-sp.Matrix([forcing[j] for j in dependent_rows]))
        multipliers = {m: simplified(x) for m, x in zip(model.multipliers, lam, strict=True)}
    residual = [simplified(f + sum((a0[k, i] * multipliers[m] for k, m in enumerate(model.multipliers)), sp.Integer(0))) for i, f in enumerate(forcing)]
    if any(r != 0 for r in residual) and not _numerically_zero(residual, values):
        _refuse_undefined(general, "linearize", residual)
        raise NotAnEquilibrium(f"{model.source}: {_point_text(point)} is not an equilibrium: the generalized forces there are {_forces_text(residual, model, values)}")
    total = [f + sum((c.jacobian[i] * multipliers[c.multiplier] for c in model.constraints), sp.Integer(0)) for i, f in enumerate(model.forcing)]
    stiffness = sp.Matrix([[simplified(-at(sp.diff(f, q), full)) for q in model.q] for f in total])
    damping = sp.Matrix([[simplified(-at(sp.diff(f, v), full)) for v in model.qd] for f in model.forcing])
    mass = sp.Matrix(model.mass_matrix).applyfunc(lambda e: simplified(at(e, full)))
    if any(not c.holonomic for c in model.constraints):
        return _nonholonomic(model, point, mass, damping, stiffness, a0, multipliers, values, full)
    names = model.coordinates
    dependent: tuple[tuple[str, sp.Expr], ...] = ()
    if model.constraints:
        tangent, independent = _tangent(a0, dependent_rows)
        names = tuple(model.coordinates[i] for i in independent)
        dq = [sp.Symbol(f"d{c}") for c in names]
        dependent = tuple((f"d{model.coordinates[j]}", simplified((tangent.row(j) * sp.Matrix(dq))[0])) for j in dependent_rows)
        mass = (tangent.T * mass * tangent).applyfunc(simplified)
        damping = (tangent.T * damping * tangent).applyfunc(simplified)
        stiffness = (tangent.T * stiffness * tangent).applyfunc(simplified)
    common = {"values": values, "coordinates": names, "multipliers": multipliers, "dependent": dependent}
    if simplified(mass.det()) == 0:
        return Linearization(point, mass, damping, stiffness, "degenerate (the mass matrix is singular at this point: a coordinate singularity)", **common)  # type: ignore[arg-type]
    size = len(names)
    neutral = [i for i in range(size) if all(stiffness[i, j] == 0 and stiffness[j, i] == 0 for j in range(size))]
    keep = [i for i in range(size) if i not in neutral]
    condition = stability_condition(stiffness.extract(keep, keep), damping.extract(keep, keep), model) if keep else (sp.true,)
    lin = Linearization(point, mass, damping, stiffness, "", condition, tuple(names[i] for i in neutral), **common)  # type: ignore[arg-type]
    if _undefined([*mass, *damping, *stiffness]):
        return _replace(lin, stability=f"unknown (the functions {', '.join(_undefined([*mass, *damping, *stiffness]))} are left undefined: give them a `definition`)")
    return _modes(lin, model)


def _numbers(model: Model, values: Mapping[str, float], matrix: sp.Matrix) -> dict[sp.Symbol, float]:
    """Parameter values, with generic values for parameters without one and for a point's free
    symbols (x_0 of a manifold of equilibria): only to choose pivots."""
    numbers = {p.symbol: float(values.get(p.name, 1.0)) for p in model.parameters}
    free = sorted({s for e in matrix for s in e.free_symbols} - set(numbers), key=str)
    return {**numbers, **{s: 0.3 + 0.1 * k for k, s in enumerate(free)}}


def _pivots(a0: sp.Matrix, values: Mapping[str, float], model: Model) -> list[int]:
    """The dependent coordinates: the columns of A at the point that form its best-conditioned
    square block, chosen by QR with column pivoting on the numeric A (one per constraint)."""
    import numpy as np
    from scipy.linalg import qr

    try:
        numeric = np.array(a0.xreplace(_numbers(model, values, a0)).evalf(), dtype=float)
    except (TypeError, ValueError) as error:
        raise DerivationError(f"{model.source}: the constraint rows at this point are not numbers ({error}); give every parameter a value") from None
    norms = np.linalg.norm(numeric, axis=1, keepdims=True)
    if not np.all(np.isfinite(numeric)) or np.any(norms == 0):
        raise DerivationError(f"{model.source}: the constraints are singular at this point (a constraint row of A vanishes), so they do not define independent coordinates there")
    _, r, pivots = qr(numeric / norms, pivoting=True)
    m = numeric.shape[0]
    if abs(r[m - 1, m - 1]) < 1e-9 * abs(r[0, 0]):
        raise DerivationError(f"{model.source}: the constraints are singular at this point (their rows of A are dependent), so they do not define independent coordinates there")
    return sorted(int(i) for i in pivots[:m])


def _tangent(a0: sp.Matrix, dependent: list[int]) -> tuple[sp.Matrix, list[int]]:
    """T with A T = 0 whose rows for the independent coordinates are the identity: dq = T dz."""
    n = a0.cols
    independent = [j for j in range(n) if j not in dependent]
    block = a0.extract(list(range(a0.rows)), dependent)
    solved = block.LUsolve(-a0.extract(list(range(a0.rows)), independent))
    tangent = sp.zeros(n, len(independent))
    for k, j in enumerate(independent):
        tangent[j, k] = 1
    for k, j in enumerate(dependent):
        tangent[j, :] = solved[k, :]
    return tangent.applyfunc(simplified), independent


def _nonholonomic(
    model: Model,
    point: dict[sp.Symbol, sp.Expr],
    mass: sp.Matrix,
    damping: sp.Matrix,
    stiffness: sp.Matrix,
    a0: sp.Matrix,
    multipliers: dict[sp.Symbol, sp.Expr],
    values: Mapping[str, float],
    full: Mapping[sp.Symbol, sp.Expr],
) -> Linearization:
    """The reduced first-order system with velocity constraints. Holonomic rows restrict the
    coordinates to dq = T dz; all rows restrict the velocities: A0 dq_dot + B0 dq = 0 (B0 = db/dq
    of each velocity constraint a . q_dot + b = 0), solved for the dependent velocities,
    dq_dot = S u + P dq, with u the independent velocities. Projecting the equations onto S
    (S^T A0^T = 0 removes the multipliers): S^T M0 S u_dot = -S^T ((M0 P + C0) dq_dot + K0 dq).
    The state is (dz, u); a velocity constraint leaves a coordinate free without a velocity of its
    own, so the rest points form a manifold and the state matrix has a zero eigenvalue for each."""
    import numpy as np

    holonomic = [k for k, c in enumerate(model.constraints) if c.holonomic]
    velocity_rows = [k for k, c in enumerate(model.constraints) if not c.holonomic]
    columns = list(range(model.n))
    bias = sp.zeros(a0.rows, model.n)
    for k in velocity_rows:
        for j, q in enumerate(model.q):
            bias[k, j] = simplified(at(sp.diff(model.constraints[k].bias, q), full))
    if holonomic:
        a_h = a0.extract(holonomic, columns)
        tangent, kept = _tangent(a_h, _pivots(a_h, values, model))
    else:
        tangent, kept = sp.eye(model.n), columns
    dependent = _pivots(a0, values, model)
    speeds, independent = _tangent(a0, dependent)
    block = a0.extract(list(range(a0.rows)), dependent)
    shift_rows = block.LUsolve(-bias)
    shift = sp.zeros(model.n, model.n)
    for k, j in enumerate(dependent):
        shift[j, :] = shift_rows[k, :]
    names = tuple(model.coordinates[i] for i in kept)
    velocity_names = tuple(f"{model.coordinates[i]}_dot" for i in independent)
    u = [sp.Symbol(f"d{model.coordinates[i]}_dot") for i in independent]
    relations = tuple((f"d{model.coordinates[j]}_dot", simplified((speeds.row(j) * sp.Matrix(u) + shift.row(j) * sp.Matrix([sp.Symbol(f"d{c}") for c in model.coordinates]))[0])) for j in dependent)
    lin = Linearization(
        point,
        mass,
        damping,
        stiffness,
        "",
        values=values,
        coordinates=names,
        multipliers=multipliers,
        velocities=velocity_names,
        dependent_velocities=relations,
    )
    numbers = {p.symbol: values[p.name] for p in model.parameters if p.name in values}
    parts = [tangent, speeds, shift, mass, damping, stiffness]
    if _undefined([e for p in parts for e in p]):
        return _replace(lin, stability=f"unknown (the functions {', '.join(_undefined([e for p in parts for e in p]))} are left undefined: give them a `definition`)")
    loose = sorted({str(x) for p in parts for e in p for x in sp.sympify(e).free_symbols} - {p.name for p in model.parameters})
    if loose:
        return _replace(lin, stability=f"unknown at a general point of the manifold of equilibria (it depends on {', '.join(loose)}): linearize about a particular point with --about")
    try:
        tn, sn, pn, mn, cn, kn = (np.array(x.xreplace(numbers).evalf(), dtype=float).reshape(x.shape) for x in parts)
    except (TypeError, ValueError):
        return _replace(lin, stability="unknown (give every parameter a value)")
    reduced_mass = sn.T @ mn @ sn
    try:
        inverse = np.linalg.inv(reduced_mass)
    except np.linalg.LinAlgError:
        return _replace(lin, stability="degenerate (the reduced mass matrix is singular at this point)")
    pick = np.eye(model.n)[kept]
    velocity = np.hstack([pn @ tn, sn])  # dq_dot = P T dz + S u
    drive = mn @ pn + cn
    state = np.vstack([pick @ velocity, -inverse @ sn.T @ (drive @ velocity + np.hstack([kn @ tn, np.zeros((model.n, sn.shape[1]))]))])
    eigenvalues = np.linalg.eigvals(state)
    scale = max(1.0, float(np.max(np.abs(eigenvalues)))) if eigenvalues.size else 1.0
    zero = int(np.sum(np.abs(eigenvalues) <= 1e-9 * scale))
    largest = float(np.max(eigenvalues.real)) if eigenvalues.size else 0.0
    if largest > 1e-9 * scale:
        stability = "unstable"
    elif zero == 0 and largest < -1e-9 * scale:
        stability = "asymptotically stable"
    else:
        stability = "stable in the linear approximation (marginally: no eigenvalue has a positive real part)"
        if np.linalg.matrix_rank(state, tol=1e-9 * scale) > state.shape[0] - zero:
            stability += ", with drift growing linearly in time along the manifold of equilibria (a zero eigenvalue with a Jordan block)"
    expected = len(velocity_rows)
    note = (
        f"{zero} zero eigenvalue{'s' if zero != 1 else ''}, {min(zero, expected)} of them expected from the velocity constraint{'s' if expected != 1 else ''}: "
        "each leaves a coordinate without an independent velocity, so the rest points form a manifold of equilibria and a perturbation along it neither grows nor decays"
        + ("; the others belong to directions without a restoring force" if zero > expected else "")
    )
    return _replace(lin, stability=stability, eigenvalues=tuple(complex(e) for e in eigenvalues), state=tuple(tuple(float(x) for x in row) for row in state), note=note)


def stability_condition(stiffness: sp.Matrix, damping: sp.Matrix, model: Model) -> tuple[sp.Expr, ...]:
    """Sylvester's criterion on K0 (stable when K0 is positive definite and there are no
    gyroscopic terms): each leading principal minor > 0, positive factors removed."""
    if damping != damping.T or any(m.free_symbols - {p.symbol for p in model.parameters} for m in stiffness):
        return ()
    conditions = []
    for k in range(1, stiffness.rows + 1):
        minor = stiffness[:k, :k].det()
        if sp.count_ops(minor) > SIMPLIFY_MAX_OPS:
            return ()  # too large to discuss symbolically: the numeric stability stands alone
        minor = factored(minor)
        condition = _positive(minor, model)
        if condition is sp.false:
            return (sp.false,)
        if condition is not sp.true:
            conditions.append(condition)
    return tuple(conditions) or (sp.true,)


def _positive(expr: sp.Expr, model: Model) -> sp.Basic:
    """`expr > 0` with factors known to be positive divided out, written as `a < b`."""
    positive = {p.symbol for p in model.parameters if not p.real}
    factors = sp.Mul.make_args(factored(expr))
    sign = 1
    kept = []
    for f in factors:
        if f.is_number:
            sign *= 1 if f > 0 else -1
        elif f.free_symbols <= positive and (f.is_Symbol or (f.is_Pow and f.exp.is_even) or (f.is_Pow and f.base.is_Symbol)):
            continue
        else:
            kept.append(f)
    if not kept:
        return sp.true if sign > 0 else sp.false
    body = sp.expand(sign * sp.Mul(*kept))
    terms = sp.Add.make_args(body)
    negative = [-t for t in terms if t.could_extract_minus_sign()]
    positive_terms = [t for t in terms if not t.could_extract_minus_sign()]
    if body.free_symbols <= positive and not negative:
        return sp.true
    if body.free_symbols <= positive and not positive_terms:
        return sp.false
    if not negative or not positive_terms:
        return sp.StrictGreaterThan(body, 0)
    return _isolate(sp.Add(*negative), sp.Add(*positive_terms), positive)


def _isolate(lhs: sp.Expr, rhs: sp.Expr, positive: set[sp.Symbol]) -> sp.Basic:
    """`lhs < rhs` for positive monomials, made readable: common square roots taken
    (g**2 < l**2*omega**4 -> g < l*omega**2), then the highest power isolated (omega**2 > g/l)."""
    if not (lhs.is_Mul or lhs.is_Pow or lhs.is_Symbol) or not (rhs.is_Mul or rhs.is_Pow or rhs.is_Symbol) or not (lhs.free_symbols | rhs.free_symbols) <= positive:
        return sp.StrictLessThan(lhs, rhs)
    dummies = {s: sp.Symbol(s.name, positive=True) for s in positive}
    back = {v: k for k, v in dummies.items()}
    a, b = lhs.xreplace(dummies), rhs.xreplace(dummies)
    while all(e % 2 == 0 for side in (a, b) for _, e in side.as_powers_dict().items() if not _.is_number):
        a, b = sp.sqrt(a), sp.sqrt(b)
    powers = [(e, str(f), f**e, side) for side, expr in (("left", a), ("right", b)) for f, e in expr.as_powers_dict().items() if f.free_symbols]
    if not powers:
        return sp.StrictLessThan(a.xreplace(back), b.xreplace(back))
    _, _, target, side = max(powers, key=lambda p: (p[0], p[1]))
    if side == "left":
        return sp.StrictLessThan(target.xreplace(back), sp.cancel(b / (a / target)).xreplace(back))
    return sp.StrictGreaterThan(target.xreplace(back), sp.cancel(a / (b / target)).xreplace(back))


def _modes(lin: Linearization, model: Model) -> Linearization:
    """Numeric eigen-analysis with the default parameter values (when all are known)."""
    import numpy as np

    symbols = {p.symbol: sp.Float(lin.values[p.name]) for p in model.parameters if p.name in lin.values}
    if any(not sp.sympify(v).xreplace(symbols).is_real for v in lin.point.values() if sp.sympify(v).xreplace(symbols).is_number):
        return _replace(lin, stability="does not exist for the default parameter values (the point is not real)")
    try:
        m = np.array(lin.mass.xreplace(symbols).evalf(), dtype=float)
        c = np.array(lin.damping.xreplace(symbols).evalf(), dtype=float)
        k = np.array(lin.stiffness.xreplace(symbols).evalf(), dtype=float)
    except (TypeError, ValueError, ArithmeticError):
        if any(e.free_symbols for e in (*lin.mass, *lin.damping, *lin.stiffness) for e in [sp.sympify(e).xreplace(symbols)]):
            return _replace(lin, stability="unknown (give every parameter a value)")
        return _replace(lin, stability="unknown (M0, C0 or K0 is not a finite real number at this point: it lies on the edge of a function's domain)")
    if not (np.all(np.isfinite(m)) and np.all(np.isfinite(c)) and np.all(np.isfinite(k))):
        return _replace(lin, stability="unknown (M0, C0 or K0 is not finite at this point: it lies on the edge of a function's domain)")
    n = m.shape[0]
    try:
        system = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(m, k), -np.linalg.solve(m, c)]])
        eigenvalues = np.linalg.eigvals(system)
    except np.linalg.LinAlgError:
        return _replace(lin, stability="degenerate (the mass matrix is singular at this point)")
    if not np.all(np.isfinite(eigenvalues)):
        return _replace(lin, stability="degenerate (the mass matrix is nearly singular at this point)")
    scale = max(1.0, float(np.max(np.abs(eigenvalues))))
    largest = float(np.max(eigenvalues.real))
    if largest > 1e-9 * scale:
        stability = "unstable"
    elif largest < -1e-9 * scale:
        stability = "asymptotically stable"
    else:
        stability = "stable (marginally: undamped oscillations)"
    if lin.neutral and stability != "unstable":
        stability += f", with free drift along {', '.join(lin.neutral)}"
    frequencies: tuple[float, ...] = ()
    modes: tuple[tuple[float, ...], ...] = ()
    if np.allclose(c, 0) and np.allclose(k, k.T):
        squared, vectors = np.linalg.eig(np.linalg.solve(m, k))
        order = np.argsort(squared.real)
        frequencies = tuple(float(np.sqrt(s)) if s > 1e-12 * scale**2 else 0.0 if s > -1e-12 * scale**2 else float("nan") for s in squared.real[order])
        modes = tuple(tuple(float(x) for x in vectors[:, i].real / np.max(np.abs(vectors[:, i].real))) for i in order)
    return _replace(lin, stability=stability, frequencies=frequencies, modes=modes, eigenvalues=tuple(complex(e) for e in eigenvalues))


def equilibria(model: Model, ranges: Mapping[sp.Symbol, tuple[float, float]] | None = None, seconds: float | None = None) -> list[dict[sp.Symbol, sp.Expr]]:
    """Points where the system can rest (q_dot = 0 and F(q, 0) + A(q)^T lambda = 0, on the
    holonomic constraints f(q) = 0): symbolically when the system is small enough for sympy
    (`SOLVE_MAX_OPS`, a size bound), otherwise numerically from many starts inside `ranges`.
    `seconds` is accepted for older callers and unused: no answer depends on time."""
    _check_constraints_allow_rest(model)
    model = model.with_definitions()
    rest = {v: 0 for v in model.qd}
    equations = [factored(f.xreplace(rest)) for f in model.forcing]
    multipliers = list(model.multipliers)
    if multipliers:
        equations = [e + sum((c.jacobian[i].xreplace(rest) * c.multiplier for c in model.constraints), sp.Integer(0)) for i, e in enumerate(equations)]
        equations += [c.expr for c in model.constraints if c.holonomic]
        equations += [c.bias.xreplace(rest) for c in model.constraints if not c.holonomic and c.bias.xreplace(rest) != 0]
    if all(e == 0 for e in equations):
        return [{q: sp.Symbol(f"{q}_0") for q in model.q}]
    found = _symbolic_equilibria(model, equations, multipliers)
    if found is not None:
        return _in_ranges(found, ranges, model)
    return _numeric_equilibria(model, equations, ranges or {})


def _symbolic_equilibria(model: Model, equations: list[sp.Expr], multipliers: list[sp.Symbol]) -> list[dict[sp.Symbol, sp.Expr]] | None:
    """sympy.solve, for systems within `SOLVE_MAX_OPS` operations and `SOLVE_MAX_UNKNOWNS` unknowns
    (None beyond: the caller searches numerically)."""
    unknowns = [q for q in (*model.q, *multipliers) if any(e.has(q) for e in equations)]
    nonzero = [e for e in equations if e != 0]
    if any(not any(e.has(q) for q in model.q) and not any(e.has(m) for m in multipliers) for e in nonzero):
        return []  # a generalized force that no configuration can cancel (e.g. a slope)
    if len(unknowns) > SOLVE_MAX_UNKNOWNS or sum(sp.count_ops(e) for e in nonzero) > SOLVE_MAX_OPS or not all(_solvable(e, unknowns) and tame_numbers(e) for e in nonzero):
        return None
    try:
        solutions = sp.solve(nonzero, unknowns, dict=True)
    except NotImplementedError:
        return None
    solutions = [s for s in solutions if _consistent(s, nonzero, unknowns, model)]
    if not solutions:
        return []
    if any(value.has(*multipliers) for s in solutions for q, value in s.items() if q in model.q) if multipliers else False:
        return None
    free = [q for q in model.q if q not in unknowns]
    points = []
    for s in solutions:
        point = {**{q: sp.Symbol(f"{q}_0") for q in free}, **{q: simplified(s.get(q, sp.Symbol(f"{q}_0"))) for q in model.q if q in unknowns}}
        points.append({q: point[q] for q in model.q})
    return points


SOLVE_MAX_POWER = 4
"""Highest power of an unknown, and highest multiple of an angle, handed to `sympy.solve`."""
SOLVE_MAX_GENERATORS = 4
"""Most distinct unknowns' terms (q, sin(q), cos(q), ...) in one system handed to `sympy.solve`."""


def _solvable(expr: sp.Expr, unknowns: list[sp.Symbol]) -> bool:
    """True when `expr` is a small polynomial in the unknowns and in sin, cos or tan of small
    integer multiples of them: the shapes sympy.solve answers promptly. Anything else (exp, log,
    Abs, a function, cos(29 x), a high power) goes to the numeric search: a decision on the
    expression's shape and size, never on time."""
    generators: set[sp.Expr] = set()

    def walk(e: sp.Basic) -> bool:
        if not any(e.has(u) for u in unknowns):
            return True
        if e.is_Symbol:
            generators.add(e)
            return True
        if isinstance(e, (sp.Add, sp.Mul)):
            return all(walk(a) for a in e.args)
        if isinstance(e, sp.Pow):
            exponent = e.exp
            return bool(exponent.is_Integer and abs(int(exponent)) <= SOLVE_MAX_POWER) and walk(e.base)
        if isinstance(e, (sp.sin, sp.cos, sp.tan)):
            argument = sp.expand(e.args[0])
            coefficients = [argument.coeff(u) for u in unknowns]
            rest = argument - sum((c * u for c, u in zip(coefficients, unknowns, strict=True)), sp.Integer(0))
            if any(rest.has(u) for u in unknowns) or not all(c.is_Integer and abs(int(c)) <= SOLVE_MAX_POWER for c in coefficients):
                return False
            generators.add(e)
            return True
        return False

    return walk(expr) and len(generators) <= 2 * SOLVE_MAX_GENERATORS


def _consistent(solution: Mapping[sp.Symbol, sp.Expr], equations: list[sp.Expr], unknowns: list[sp.Symbol], model: Model) -> bool:
    """False when a solution sympy returned leaves an equation that no unknown can satisfy, a
    condition on the parameters only (sympy returns lambda = 0 for `g sin(alpha) - lambda sin(phi)
    = 0, lambda cos(phi) = 0`, true only on a level plane)."""
    values = {p.symbol: sp.Float(v) for p in model.parameters if (v := model.parameter_values().get(p.name)) is not None}
    for e in equations:
        left = simplified(e.xreplace(dict(solution)))
        if left == 0 or any(left.has(u) for u in unknowns):
            continue
        number = left.xreplace(values)
        if not number.is_number or abs(complex(sp.N(number))) > 1e-9:
            return False
    return True


def _numeric_equilibria(model: Model, equations: list[sp.Expr], ranges: Mapping[sp.Symbol, tuple[float, float]]) -> list[dict[sp.Symbol, sp.Expr]]:
    """Many starts of a root search inside the box. With constraints the multipliers are
    eliminated at each q by least squares (the force left over is F + A^T lambda projected off
    the rows of A), and the search is a least-squares one on that and f(q) = 0."""
    import numpy as np
    from scipy.optimize import root

    values = {p.symbol: v for p in model.parameters if (v := model.parameter_values().get(p.name)) is not None}
    missing = [p.name for p in model.parameters if p.symbol not in values and any(e.has(p.symbol) for e in equations)]
    if missing:
        raise DerivationError(f"{model.source}: sympy could not solve for the equilibria symbolically, and a numeric search needs values for {', '.join(missing)}")
    _refuse_undefined(model, "a numeric search for equilibria", equations)
    rest = {v: 0 for v in model.qd}
    forces = sp.lambdify([model.q], [f.xreplace(rest).xreplace(values) for f in model.forcing], "math")
    rows = sp.lambdify([model.q], [[a.xreplace(rest).xreplace(values) for a in c.jacobian] for c in model.constraints], "math")
    surface = sp.lambdify([model.q], [e.xreplace(values) for e in equations[model.n :]], "math")
    constrained = bool(model.constraints)

    def residual(x: Sequence[float]) -> list[float]:
        force = np.array(_forces(forces, x))
        if not constrained:
            return list(force)
        a = np.array(_forces(lambda y: [v for row in rows(y) for v in row], x)).reshape(len(model.constraints), model.n)
        lam = np.linalg.lstsq(a.T, -force, rcond=None)[0]
        return [*(force + a.T @ lam), *_forces(surface, x)]

    bounds = [ranges.get(q, (-np.pi, np.pi)) for q in model.q]
    rng = np.random.default_rng(0)
    points: list[np.ndarray] = []
    failures: dict[str, int] = {}
    for _ in range(STARTS):
        start = np.array([rng.uniform(a, b) for a, b in bounds])
        try:
            with np.errstate(all="ignore"):
                result = root(residual, start, method="lm", options={"xtol": 1e-15, "ftol": 1e-15}) if constrained else root(residual, start, method="hybr")
                if constrained and result.success:
                    result.success = bool(np.max(np.abs(residual(result.x))) < 1e-9)
        except _Unevaluable as bad:  # a start (or the search from it) where the forces cannot be evaluated
            failures[str(bad)] = failures.get(str(bad), 0) + 1
            continue
        if not (result.success and np.all(np.isfinite(result.x))):
            continue
        if all(a - 1e-9 <= x <= b + 1e-9 for x, (a, b) in zip(result.x, bounds, strict=True)) and not any(np.allclose(result.x, p, atol=1e-7) for p in points):
            points.append(result.x)
    if failures and sum(failures.values()) == STARTS:
        where = ", ".join(f"{q} in [{a:g}, {b:g}]" for q, (a, b) in zip(model.q, bounds, strict=True))
        raise DerivationError(
            f"{model.source}: the forces cannot be evaluated from any of {STARTS} starting points of the numeric search ({where}): {max(failures, key=lambda k: failures[k])}; give ranges inside their domain (--range)"
        )
    points.sort(key=lambda x: tuple(x))
    return [{q: sp.Float(x, 12) for q, x in zip(model.q, p, strict=True)} for p in points[:MAX_NUMERIC_POINTS]]


STARTS = 200
"""Starting points of the numeric search for equilibria."""
MAX_NUMERIC_POINTS = 16
"""At most this many equilibria from the numeric search (the first in lexicographic order): more
distinct points mean a curve or surface of equilibria, which the report says, and each point
shown is linearized."""


class _Unevaluable(Exception):
    """The forces cannot be evaluated at a point to finite real numbers; the text says why."""


def _forces(function: Callable[[list[float]], list[float]], x: Sequence[float]) -> list[float]:
    """F(q, 0) at q = x as finite floats, or `_Unevaluable` (a math domain error, a division by
    zero, an overflow, a complex or NaN value)."""
    try:
        values = [float(v) for v in function([float(v) for v in x])]
    except (ArithmeticError, ValueError, TypeError) as error:
        raise _Unevaluable(f"{type(error).__name__}: {error}" if str(error) else type(error).__name__) from None
    if not all(math.isfinite(v) for v in values):
        raise _Unevaluable("a force is not finite (a division by zero or an overflow)")
    return values


def _in_ranges(found: list[dict[sp.Symbol, sp.Expr]], ranges: Mapping[sp.Symbol, tuple[float, float]] | None, model: Model) -> list[dict[sp.Symbol, sp.Expr]]:
    if not ranges:
        return found
    values = {p.symbol: v for p in model.parameters if (v := model.parameter_values().get(p.name)) is not None}
    kept = []
    for point in found:
        ok = True
        for q, (a, b) in ranges.items():
            x = point.get(q)
            if x is None:
                continue
            number = x.xreplace(values)
            if number.is_number and number.is_real and not (a - 1e-12 <= float(number) <= b + 1e-12):
                ok = False
        if ok:
            kept.append(point)
    return kept


def steady_motions(model: Model, seconds: float | None = None) -> list[tuple[sp.Symbol, sp.Expr]]:
    """Steady motions: the other coordinates at rest while ignorable ones turn at constant
    rates. With q_ddot = 0 and the non-ignorable velocities zero, each non-ignorable
    equation F_i = 0 becomes a relation among the ignorable rates, solved for the last one
    (e.g. the free top's steady precession psi_dot = (I_perp - I_par)/I_par cos(theta) phi_dot)."""
    cyclic = [i for i in range(model.n) if model.ignorable(i)]
    if not cyclic or len(cyclic) == model.n or model.constraints:
        return []
    rest = {model.qd[i]: 0 for i in range(model.n) if i not in cyclic}
    target = model.qd[cyclic[-1]]
    relations = []
    for i in range(model.n):
        if i in cyclic:
            continue
        equation = factored(model.forcing[i].xreplace(rest))
        if not equation.has(target):
            continue
        if sp.count_ops(equation) > SOLVE_MAX_OPS or not _solvable(equation, [target]) or not tame_numbers(equation):
            continue
        try:
            solutions = sp.solve(equation, target)
        except NotImplementedError:
            continue
        relations += [(target, sp.factor_terms(simplified(x))) for x in solutions]
    return relations


def _numerically_zero(values: Sequence[sp.Expr], parameters: Mapping[str, float]) -> bool:
    numbers = {sp.Symbol(k): v for k, v in parameters.items()}
    try:
        return all(abs(complex(sp.N(v.xreplace(numbers)))) < 1e-9 for v in values)
    except (TypeError, ValueError):
        return False


def _forces_text(residual: Sequence[sp.Expr], model: Model, values: Mapping[str, float]) -> str:
    """The generalized forces at a point that is not an equilibrium, in words: simplified with the
    parameters positive (as the format declares them unless `sign: real`), and as numbers at the
    parameters' values when every one has a value."""
    positive = {p.symbol: sp.Dummy(p.name, positive=True) for p in model.parameters if not p.real}
    back = {d: s for s, d in positive.items()}
    shown = [simplified(sp.sympify(r).xreplace(positive)).xreplace(back) for r in residual]
    text = str([str(r) for r in shown])
    numbers = {sp.Symbol(k): v for k, v in values.items()}
    try:
        evaluated = [complex(sp.N(r.xreplace(numbers))) for r in shown]
    except (TypeError, ValueError):
        return text
    if any(e.imag != 0 or not math.isfinite(e.real) for e in evaluated):
        return text
    return f"{text}, that is {[float(f'{e.real:.6g}') + 0.0 for e in evaluated]} at the parameters' values"


def _point_text(point: Mapping[sp.Symbol, sp.Expr]) -> str:
    return ", ".join(f"{k} = {v}" for k, v in point.items())


def _replace(lin: Linearization, **changes: object) -> Linearization:
    import dataclasses

    return dataclasses.replace(lin, **changes)  # type: ignore[arg-type]
