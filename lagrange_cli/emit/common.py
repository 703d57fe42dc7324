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


def constraint_equations(model: Model) -> list[tuple[str, sp.Expr]]:
    """Each kept constraint as written (holonomic f(q, t) or velocity a . q_dot + b)."""
    return [(c.name, expand_bounded(c.expr)) for c in model.constraints]


def require_defined(model: Model, what: str) -> None:
    """Numeric code needs every function defined, by a `definition` in the file (numeric code
    evaluates `model.with_definitions()`); undefined ones (e.g. U(r)) cannot be emitted."""
    numeric = model.with_definitions()
    undefined = sorted({str(f.func) for f in sp.Matrix([*numeric.mass_matrix, *numeric.forcing, numeric.energy]).atoms(sp.core.function.AppliedUndef)})
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
