"""What the text and LaTeX emitters share: the terms of each equation, in a stable order."""

from __future__ import annotations

import unicodedata

import sympy as sp

from lagrange_cli.algebra import expand_bounded
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model


def lagrange_terms(model: Model) -> list[list[sp.Expr]]:
    """Each equation as a list of terms, accelerations first, then the rest, then multipliers."""
    rows = []
    for i in range(model.n):
        terms = [sp.factor_terms(model.mass_matrix[i, j]) * model.qdd[j] for j in range(model.n) if model.mass_matrix[i, j] != 0]
        terms += ordered_terms(-model.forcing[i])
        terms += [-sp.factor_terms(c.jacobian[i]) * c.multiplier for c in model.constraints if c.jacobian[i] != 0]
        rows.append(terms or [sp.Integer(0)])
    return rows


def ordered_terms(expr: sp.Expr) -> list[sp.Expr]:
    """The terms of a sum in sympy's printing order (deterministic)."""
    expr = expand_bounded(expr)
    return [] if expr == 0 else list(expr.as_ordered_terms())


# Tidying (factor_terms, sign flips) is skipped above this many operations: it is cheap but
# never needed to read an expression that size.
TIDY_OPS = 3000


def tidy(expr: sp.Expr) -> sp.Expr:
    """`expr` as a reader expects it, by bounded, targeted steps (never a blanket simplify): the
    terms without a denominator expanded and their common factors pulled out
    (`-g l m (cos(phi) + cos(theta)) - g l m cos(theta)` -> `-g l m (cos(phi) + 2 cos(theta))`),
    every quotient over a single denominator, with positive leading denominators
    (`positive_denominator`). Left as it
    is when larger than `TIDY_OPS` operations."""
    if sp.count_ops(expr) > TIDY_OPS:
        return expr
    plain: list[sp.Expr] = []
    quotients: list[sp.Expr] = []
    for term in sp.Add.make_args(expr):
        (plain if sp.fraction(term)[1] == 1 else quotients).append(term)
    return sp.Add(sp.factor_terms(expand_bounded(sp.Add(*plain))), *(positive_denominator(_unnested(q)) for q in quotients))


def _unnested(quotient: sp.Expr) -> sp.Expr:
    """A quotient over one denominator when its numerator or denominator holds quotients
    itself (`(-k + (p**2 + ...)/(2*m*r))/r` -> `(-2*k*m*r + p**2 + ...)/(2*m*r**2)`), so that
    no fraction is printed inside another at script size."""
    parts = sp.fraction(quotient)
    if any(sp.fraction(term)[1] != 1 for part in parts for term in sp.Add.make_args(part)):
        return sp.together(quotient)
    return quotient


def positive_denominator(expr: sp.Expr) -> sp.Expr:
    """A quotient with each sum in its denominator written with a positive leading term, and its
    numerator's common factors pulled out: `(a - b)/(-M + m)` -> `-(a - b)/(M - m)`."""
    if sp.count_ops(expr) > TIDY_OPS:
        return expr
    numerator, denominator = sp.fraction(sp.factor_terms(expr))
    sign, factors = 1, []
    for factor in sp.Mul.make_args(denominator):
        base, exponent = factor.as_base_exp()
        if isinstance(base, sp.Add) and exponent.is_Integer and base.as_ordered_terms()[0].could_extract_minus_sign():
            factors.append(sp.Pow(-base, exponent))
            sign *= (-1) ** int(exponent)
        else:
            factors.append(factor)
    if factors == list(sp.Mul.make_args(denominator)):
        return expr
    # unevaluated, so that a number and a sum (2 (x + y)) are not multiplied out
    return sp.factor_terms(sign * numerator) / sp.Mul(*factors, evaluate=False)


def constraint_equations(model: Model) -> list[tuple[str, sp.Expr]]:
    """Each kept constraint as written (holonomic f(q, t) or velocity a . q_dot + b)."""
    return [(c.name, expand_bounded(c.expr)) for c in model.constraints]


def require_defined(model: Model, what: str) -> None:
    """Numeric code needs every function defined, by a `definition` in the file (numeric code
    evaluates `model.with_definitions()`); undefined ones (e.g. U(r)) cannot be emitted."""
    numeric = model.with_definitions()
    rows = [part for c in numeric.constraints for part in (c.expr, *c.jacobian, c.bias, c.acceleration_bias)]
    exprs = [*numeric.mass_matrix, *numeric.forcing, numeric.energy, *numeric.momenta, *rows]
    undefined = sorted({str(f.func) for e in exprs for f in sp.sympify(e).atoms(sp.core.function.AppliedUndef)})
    if undefined:
        one = len(undefined) == 1
        raise DerivationError(
            f"{model.source}: {what} needs every function defined, but {', '.join(undefined)} {'is' if one else 'are'} left undefined; "
            f"give {'it' if one else 'each'} a definition under `functions` (e.g. `functions: {{{undefined[0]}: {{arguments: [s], definition: -k/s}}}}`) "
            f"or write {'it' if one else 'them'} out as an expression in the system file"
        )


def printable(text: str) -> str:
    """`text` with nothing a terminal, an editor or a TeX comment acts on: a tab, newline or any
    other whitespace character becomes a space, and every other control, format, surrogate,
    private-use or unassigned character (ESC, U+2028, U+200B, ...) is shown as `U+XXXX`."""
    out = []
    for char in text:
        if char.isspace():
            out.append(" ")
        elif unicodedata.category(char)[0] == "C":
            out.append(f"U+{ord(char):04X}")
        else:
            out.append(char)
    return "".join(out)
