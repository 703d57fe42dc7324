"""Reduced equations for velocity constraints (Maggi's form): the multipliers eliminated.

A model with kept constraints has `M q_ddot = F + A^T lambda` and `A q_dot + b = 0` (every kept
constraint, a holonomic one differentiated once), `A q_ddot + c = 0` differentiated again. The
velocities are split into m dependent ones q_dot_D and k = n - m independent ones u = q_dot_I, so that

    A_D q_dot_D + A_I u + b = 0    gives    q_dot = C(q, t) u + d(q, t),

with the rows of C for I the identity and those for D equal to -A_D^-1 A_I (d: 0 and -A_D^-1 b).
Likewise q_ddot = C u_dot + e with e_D = -A_D^-1 c (c at q_dot = C u + d). Since A C = 0, C^T A^T = 0,
and projecting the equations of motion on C removes the multipliers (Maggi's equations):

    C^T (M q_ddot - F) = 0,    i.e.    (C^T M C) u_dot = C^T (F - M e),

all at q_dot = C u + d. The state is (q, u): n + k first-order equations, q_dot = C u + d and the
line above. The dependent velocities are chosen by column pivoting on A at the default parameters
and the initial coordinates (`choose`): deterministic, and the best-conditioned A_D that greedy
pivoting finds there (ties go to the later coordinate, so that with A = [1, -R cos(phi)] the
coordinate with the unit coefficient is dependent).

Systems without a velocity (nonholonomic) constraint are refused (exit 2): their kept holonomic
constraints are better eliminated (`eliminate`), and a system without constraints has no
multipliers to eliminate.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import sympy as sp

from lagrange_cli.errors import fail
from lagrange_cli.model import Model

MAX_DEPENDENT = 4
"""Most dependent velocities whose block A_D is inverted symbolically."""
TRIGSIMP_MAX_OPS = 60
"""Largest entry (in sympy's count_ops) that is trig-simplified for readability."""
PIVOT_TOLERANCE = 1e-9
"""A column whose remaining norm is below this (relative to A's largest entry) does not pivot."""


@dataclass(frozen=True)
class Reduced:
    """Maggi's equations of `model` in the state (q, u), u the independent velocities.

    `velocities` are q_dot = C u + d (one expression per coordinate, in q, u, t), `mass` is C^T M C
    and `rhs` C^T (F - M e), both at q_dot = C u + d: `mass * u_dot = rhs`. The symbols of u are the
    model's `<q>_dot` of the independent coordinates, those of u_dot their `<q>_ddot`."""

    model: Model
    independent: tuple[int, ...]
    dependent: tuple[int, ...]
    velocities: tuple[sp.Expr, ...]
    mass: sp.ImmutableMatrix
    rhs: tuple[sp.Expr, ...]
    where: str
    """Where the pivoting was done, for the output ("at the defaults and x = 0, ...")."""
    determinant: sp.Expr
    """det A_D: the equations hold where it is not 0."""

    @property
    def u(self) -> tuple[sp.Symbol, ...]:
        return tuple(self.model.qd[i] for i in self.independent)

    @property
    def ud(self) -> tuple[sp.Symbol, ...]:
        return tuple(self.model.qdd[i] for i in self.independent)

    @property
    def state(self) -> tuple[sp.Symbol, ...]:
        return (*self.model.q, *self.u)

    def equations(self) -> tuple[sp.Expr, ...]:
        """The k reduced equations, each `= 0`: (C^T M C u_dot - C^T (F - M e))_i."""
        k = len(self.independent)
        return tuple(sum((self.mass[i, j] * self.ud[j] for j in range(k)), sp.Integer(0)) - self.rhs[i] for i in range(k))

    def summary(self) -> str:
        names = self.model.coordinates
        ind = ", ".join(f"{names[i]}_dot" for i in self.independent) or "none"
        dep = ", ".join(f"{names[i]}_dot" for i in self.dependent)
        valid = "valid everywhere: det A_D is constant" if self.determinant.is_number else f"valid where {sp.sstr(self.determinant)} != 0"
        return f"independent velocities: {ind}; dependent: {dep} (chosen by pivoting on the constraint matrix {self.where}; {valid})"


def reduced(model: Model) -> Reduced:
    """Maggi's equations of `model`; exit 2 when it has no velocity constraint, or when the
    constraints do not determine m velocities at the pivoting point (dependent or singular rows)."""
    if not any(not c.holonomic for c in model.constraints):
        raise fail(
            None,
            "--form reduced needs a velocity (nonholonomic) constraint: this system has none" + (" (its kept constraints are holonomic: eliminate them)" if model.constraints else ""),
            "a system with a velocity constraint under `constraints`, or another --form (lagrange, matrix, solved)",
        )
    n, m = model.n, len(model.constraints)
    if m > MAX_DEPENDENT:
        raise fail(
            None,
            f"--form reduced inverts the constraint block symbolically for at most {MAX_DEPENDENT} constraints; this system keeps {m}",
            "fewer kept constraints (eliminate holonomic ones), or --form lagrange",
        )
    A = sp.Matrix(model.constraint_matrix)
    dependent, where = choose(model, A)
    independent = tuple(i for i in range(n) if i not in dependent)
    AD = A.extract(list(range(m)), list(dependent))
    AI = A.extract(list(range(m)), list(independent))
    b = sp.Matrix([c.bias for c in model.constraints])
    c = sp.Matrix([c.acceleration_bias for c in model.constraints])
    u = [model.qd[i] for i in independent]
    solve = _solver(AD)
    dep_rows = solve(-(AI * sp.Matrix(u) + b))  # q_dot_D = -A_D^-1 (A_I u + b)
    velocity = list(model.qd)
    for row, i in enumerate(dependent):
        velocity[i] = dep_rows[row]
    on = {model.qd[i]: velocity[i] for i in dependent}
    e_dep = solve(-c).xreplace(on)
    C = sp.zeros(n, len(independent))
    for col, i in enumerate(independent):
        C[i, col] = 1
    coupling = solve(-AI)
    for row, i in enumerate(dependent):
        for col in range(len(independent)):
            C[i, col] = coupling[row, col]
    e = sp.zeros(n, 1)
    for row, i in enumerate(dependent):
        e[i] = e_dep[row]
    M = sp.Matrix(model.mass_matrix).xreplace(on)
    F = sp.Matrix(model.forcing).xreplace(on)
    mass = (C.T * M * C).applyfunc(_tidy)
    rhs = (C.T * (F - M * e)).applyfunc(_tidy)
    return Reduced(model, independent, tuple(dependent), tuple(_tidy(v) for v in velocity), sp.ImmutableMatrix(mass), tuple(rhs), where, _tidy(AD.det(method="berkowitz")))


def _tidy(expr: sp.Expr) -> sp.Expr:
    """A bounded clean-up for readability: small entries trig-simplified (sin^2 + cos^2 = 1),
    medium ones expanded, big ones left as they are."""
    ops = sp.count_ops(expr)
    try:
        if ops <= TRIGSIMP_MAX_OPS and expr.has(sp.sin, sp.cos):
            return sp.trigsimp(sp.cancel(expr))
        if ops <= 400:
            return sp.expand(expr)
    except (TypeError, ValueError):  # pragma: no cover - sympy on odd input
        pass
    return expr


def _solver(AD: sp.Matrix) -> Callable[[sp.Matrix], sp.Matrix]:
    """x -> A_D^-1 x, symbolically: by LU on A_D (at most `MAX_DEPENDENT` rows)."""
    if AD.shape == (1, 1):
        pivot = AD[0, 0]
        return lambda rhs: rhs / pivot
    return lambda rhs: AD.LUsolve(rhs)


def choose(model: Model, A: sp.Matrix) -> tuple[tuple[int, ...], str]:
    """The m dependent coordinates: greedy column pivoting (Gram-Schmidt with largest remaining
    norm, ties to the later column) on A evaluated at the default parameters and the initial
    coordinates (0 where not given) and t = 0. Exit 2 when A has rank < m there."""
    values: dict[sp.Symbol, float] = {model.t: 0.0}
    missing = [p.name for p in model.parameters if p.value is None]
    if missing:
        raise fail(
            None,
            f"--form reduced chooses the independent velocities at the default parameters, and {', '.join(missing)} {'has' if len(missing) == 1 else 'have'} no default",
            "a `value` for every parameter",
        )
    values.update({p.symbol: float(p.value) for p in model.parameters if p.value is not None})
    values.update({q: float(model.initial.get(name, 0.0)) for name, q in zip(model.coordinates, model.q, strict=True)})
    try:
        point = {symbol: sp.Float(value) for symbol, value in values.items()}
        numeric = [[float(sp.sympify(a).xreplace(point).evalf()) for a in A.row(i)] for i in range(A.rows)]
    except (TypeError, ValueError) as error:
        raise fail(None, f"--form reduced cannot evaluate the constraint matrix at the defaults: {error}", "constraints defined at the default parameters and initial coordinates") from None
    where = "at the default parameters and " + ", ".join(f"{name} = {float(model.initial.get(name, 0.0)):g}" for name in model.coordinates)
    if not all(math.isfinite(x) for row in numeric for x in row):
        raise fail(None, f"--form reduced: the constraint matrix is not finite {where}", "constraints defined at the default parameters and initial coordinates")
    rows, n = A.rows, A.cols
    scale = max([1.0, *(abs(x) for row in numeric for x in row)])
    columns = [[numeric[i][j] for i in range(rows)] for j in range(n)]  # what is left of each column
    chosen: list[int] = []
    for _ in range(rows):
        norms = [-1.0 if j in chosen else math.sqrt(sum(x * x for x in columns[j])) for j in range(n)]
        best = max(norms)
        if best <= PIVOT_TOLERANCE * scale:
            names = ", ".join(c.name for c in model.constraints)
            raise fail(
                None,
                f"--form reduced: the kept constraints ({names}) do not determine {rows} velocities {where} (their matrix has rank {len(chosen)})",
                "independent constraints, or initial coordinates where they are independent",
            )
        j = max(k for k in range(n) if norms[k] >= best * (1 - 1e-12))
        chosen.append(j)
        unit = [x / best for x in columns[j]]
        columns = [[x - unit[i] * sum(unit[r] * column[r] for r in range(rows)) for i, x in enumerate(column)] for column in columns]
    return tuple(sorted(chosen)), where


def refuse_target(target: str) -> None:
    """Exit 2 for a target that does not write the reduced equations."""
    raise fail(None, f"--form reduced is not available for --to {target}", f"--to text, latex, python, c, octave, jax or json with --form reduced (or another --form for --to {target})")
