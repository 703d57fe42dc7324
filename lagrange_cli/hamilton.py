"""Hamilton's equations: the Legendre transform of a derived model.

For L = 1/2 q_dot^T M(q, t) q_dot + b(q, t) . q_dot + L0(q, t) the momenta are p = M q_dot + b, so
q_dot = M^-1 (p - b) and H(q, p, t) = 1/2 (p - b)^T M^-1 (p - b) - L0. Hamilton's equations are

    q_dot = dH/dp,    p_dot = -dH/dq + Q - dR/dq_dot,

with the generalized forces Q and the Rayleigh function R written in (q, p). Since -dH/dq at
fixed p equals dL/dq at fixed q_dot, p_dot is computed as (dL/dq + Q - dR/dq_dot) at
q_dot = q_dot(q, p): the same function, without differentiating the inverse.

Two routes, chosen by a bounded size test (never an unbounded symbolic inverse):

- symbolic (`Hamilton.symbolic`): at most `MAX_SYMBOLIC` coordinates and `MAX_SYMBOLIC_OPS` operations in M, or a diagonal mass matrix
  (then M^-1 is the reciprocal of its diagonal): H, q_dot(q, p) and p_dot(q, p) as expressions;
- numeric: beyond that, generated code solves M q_dot = p - b numerically at each call and
  evaluates H = p . q_dot - L and p_dot from q_dot; the text and LaTeX forms state the
  equations in that shape (M, b and p_dot(q, q_dot)).

Kept constraints are refused (exit 2): eliminate them first (FORMAT.md, version 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from lagrange_cli.algebra import expandable, tame_numbers
from lagrange_cli.errors import LagrangeError, fail
from lagrange_cli.model import Model

MAX_SYMBOLIC = 3
"""Largest number of coordinates whose (non-diagonal) mass matrix is inverted symbolically."""
MAX_SYMBOLIC_OPS = 200
"""Largest size (operations summed over its entries) of a non-diagonal mass matrix inverted
symbolically: a 3 x 3 matrix of long entries (a top with products of inertia) has an adjugate of
thousands of operations, which no page holds; it takes the numeric route instead."""
SIMPLIFY_MAX_OPS = 200
"""Largest determinant that is trig-simplified (a bounded step, for readability only)."""


@dataclass(frozen=True)
class Hamilton:
    """Hamilton's equations of `model` in the state (q, p), p named `p_<q>`.

    On the symbolic route `hamiltonian` is H(q, p, t), `velocities` q_dot(q, p, t) and `rates`
    p_dot(q, p, t). On the numeric route `hamiltonian` is None, `velocities` is empty and
    `rates` are p_dot(q, q_dot, t), to be evaluated at q_dot = M^-1 (p - b) solved numerically."""

    model: Model
    p: tuple[sp.Symbol, ...]
    pd: tuple[sp.Symbol, ...]
    symbolic: bool
    hamiltonian: sp.Expr | None
    velocities: tuple[sp.Expr, ...]
    rates: tuple[sp.Expr, ...]
    mass: sp.ImmutableMatrix
    bias: tuple[sp.Expr, ...]
    rest: sp.Expr
    """L0 = L at q_dot = 0."""

    @property
    def state(self) -> tuple[sp.Symbol, ...]:
        return (*self.model.q, *self.p)


def momentum_symbols(coordinates: tuple[str, ...]) -> tuple[tuple[sp.Symbol, ...], tuple[sp.Symbol, ...]]:
    """`p_<q>` and `p_<q>_dot` for each coordinate."""
    return tuple(sp.Symbol(f"p_{c}") for c in coordinates), tuple(sp.Symbol(f"p_{c}_dot") for c in coordinates)


def clashes(coordinates: tuple[str, ...], names: list[str]) -> list[str]:
    """The declared `names` that have the form of a momentum (`p_<q>`, `p_<q>_dot`)."""
    taken = {f"p_{c}" for c in coordinates} | {f"p_{c}_dot" for c in coordinates}
    return [name for name in names if name in taken]


def declared(model: Model) -> list[str]:
    """Every name the file declares: coordinates and their velocities, parameters, inputs, functions."""
    functions = {str(f.func) for e in (model.lagrangian, *model.generalized_forces, model.dissipation) for f in e.atoms(sp.core.function.AppliedUndef)}
    return [*model.coordinates, *(str(v) for v in model.qd), *(p.name for p in model.parameters), *(i.name for i in model.inputs), *sorted(functions | set(model.definitions))]


def hamilton(model: Model, symbolic: bool = True) -> Hamilton:
    """Hamilton's equations of `model` (see the module's docstring); a `LagrangeError` (exit 2)
    saying why where they cannot be written: kept constraints, a declared name of the form `p_<q>`,
    a mass matrix that depends on the velocities or is singular. `symbolic=False` takes the numeric
    route whatever the size (what generated code that solves M q_dot = p - b itself needs)."""
    where = model.source
    if model.constraints:
        names = ", ".join(c.name for c in model.constraints)
        raise fail(
            None, f"{where}: Hamilton's equations are not written for a system with kept constraints ({names})", "a system without kept constraints: eliminate them first (`eliminate:` in the file)"
        )
    clash = clashes(model.coordinates, declared(model))
    if clash:
        raise fail(
            None,
            f"{where}: '{clash[0]}' is declared in the file, but Hamilton's equations name the momentum of '{clash[0][2:].removesuffix('_dot')}' so",
            "no coordinate, parameter or function named p_<coordinate>",
        )
    mass = sp.ImmutableMatrix(model.mass_matrix)
    if any(mass.has(v) for v in model.qd):
        raise fail(
            None,
            f"{where}: the Lagrangian is not quadratic in the velocities (its mass matrix depends on them), so the momenta cannot be solved for the velocities by the Legendre transform",
            "a Lagrangian quadratic in the velocities",
        )
    p, pd = momentum_symbols(model.coordinates)
    zero = {v: 0 for v in model.qd}
    bias = tuple(sp.diff(model.lagrangian, v).xreplace(zero) for v in model.qd)
    rest = model.lagrangian.xreplace(zero)
    qd = model.qd
    in_velocities = rates_in_velocities(model)
    n = model.n
    if not symbolic or (not mass.is_diagonal() and (n > MAX_SYMBOLIC or sum(sp.count_ops(e) for e in mass) > MAX_SYMBOLIC_OPS)):
        return Hamilton(model, p, pd, False, None, (), in_velocities, mass, bias, rest)
    adjugate, det = _inverse(mass, where)
    shifted = sp.Matrix([p[i] - bias[i] for i in range(n)])
    velocities = tuple(_over(v, det) for v in adjugate * shifted)
    hamiltonian = _over((shifted.T * adjugate * shifted)[0], 2 * det) - _tidy(rest)
    solved = dict(zip(qd, velocities, strict=True))
    rates = tuple(_combined(r.xreplace(solved)) for r in in_velocities)
    return Hamilton(model, p, pd, True, hamiltonian, velocities, rates, mass, bias, rest)


def rates_in_velocities(model: Model) -> tuple[sp.Expr, ...]:
    """p_dot = dL/dq + Q - dR/dq_dot as functions of (q, q_dot, t): F + d/dt(p) without the
    accelerations, from the derived forcing, whose derivatives of sign, Abs and the file's
    functions the deriver has already taken (what generated code evaluates at q_dot = M^-1 (p - b))."""
    qd = model.qd
    return tuple(model.forcing[i] + sum((sp.diff(model.momenta[i], model.q[j]) * qd[j] for j in range(model.n)), sp.diff(model.momenta[i], model.t)) for i in range(model.n))


def _inverse(mass: sp.ImmutableMatrix, where: str) -> tuple[sp.Matrix, sp.Expr]:
    """(adjugate, determinant) of a small M, so that M^-1 = adjugate / determinant; for a diagonal
    M, (diag(1/M_ii), 1). The determinant is simplified by bounded steps only."""
    n = mass.rows
    singular = fail(None, f"{where}: the mass matrix is singular, so the Legendre transform (p = M q_dot + b) cannot be inverted", "a system whose kinetic energy involves every velocity")
    if mass.is_diagonal():
        if any(mass[i, i] == 0 for i in range(n)):
            raise singular
        return sp.diag(*[1 / mass[i, i] for i in range(n)]), sp.Integer(1)
    det = sp.Matrix(mass).det(method="berkowitz")
    det = sp.factor_terms(sp.trigsimp(det) if sp.count_ops(det) <= SIMPLIFY_MAX_OPS and tame_numbers(det) else det)
    if det == 0:
        raise singular
    return sp.Matrix(mass).adjugate(), det


def _over(numerator: sp.Expr, denominator: sp.Expr) -> sp.Expr:
    """numerator / denominator, the numerator expanded and its common factors pulled out (bounded)."""
    if denominator == 1:
        return _tidy(numerator)
    return _tidy(numerator) / denominator if _cheap(numerator, 400) else numerator / denominator


def _tidy(expr: sp.Expr) -> sp.Expr:
    from lagrange_cli.emit.common import tidy

    return tidy(sp.expand(expr) if _cheap(expr, 400) else expr)


def _cheap(expr: sp.Expr, ops: int) -> bool:
    """Whether expanding `expr` stays small: at most `ops` operations and a bounded expansion
    (`algebra.expandable`: (1 + x)**90 is a few operations but thousands of terms)."""
    return sp.count_ops(expr) <= ops and expandable(expr)


def _combined(expr: sp.Expr) -> sp.Expr:
    """`expr` with its quotients over a common denominator when that is cheap (bounded), the
    other terms tidied apart; else tidied term by term."""
    if _cheap(expr, 300):
        terms = sp.Add.make_args(sp.expand(expr, multinomial=False))  # denominators (a + b)**2 stay squares
        plain = sp.Add(*(t for t in terms if sp.fraction(t)[1].is_number))  # `g*l*m*cos(q)/2` is no quotient to combine
        quotients = sp.Add(*(t for t in terms if not sp.fraction(t)[1].is_number))
        numerator, denominator = sp.fraction(sp.factor_terms(sp.together(quotients)))
        if _cheap(numerator, 400):
            return _tidy(plain) + _over(numerator, denominator)
    return _tidy(expr)


def hamilton_or_none(model: Model) -> tuple[Hamilton | None, str]:
    """`hamilton(model)`, or None and the reason."""
    try:
        return hamilton(model), ""
    except LagrangeError as error:
        return None, str(error)
