"""What the text and LaTeX emitters share: the terms of each equation, in a stable order, and
the walk that prints symengine expressions.

Big systems (a 60-link chain has millions of nodes) are printed from `Model.symengine` without
converting anything to sympy: the terms are built and grouped in symengine (`equation_terms`,
`collected`, `common_factor`, each linear in the size of the equation), and printed by
`SymenginePrinter`, which prints every distinct subexpression once (memoized) and orders terms
and factors by the text of their parts, so that the work grows with the size of the output."""

from __future__ import annotations

import re
import sys
import unicodedata
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, ClassVar

import sympy as sp

from lagrange_cli._symengine import se, to_symengine
from lagrange_cli.algebra import expand_bounded
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

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
    evaluates `model.with_definitions()`); undefined ones (e.g. U(r)) cannot be emitted. A file that
    declares none (or defines all it declares) has none: its equations, which may be too long to
    convert to sympy (a spatial chain), are then not read."""
    if model.native and set(model.functions) <= set(model.definitions):
        return
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
    if text.isascii() and text.isprintable():
        return text  # printable ASCII (the space included) has nothing to replace: checked in C
    out = []
    for char in text:
        if char.isspace():
            out.append(" ")
        elif unicodedata.category(char)[0] == "C":
            out.append(f"U+{ord(char):04X}")
        else:
            out.append(char)
    return "".join(out)


# --- terms of big systems, in symengine -------------------------------------------------------------

Expr = Any  # a symengine expression
_Function = sys.modules["symengine.lib.symengine_wrapper"].Function  # the class of every applied function


def equation_terms(model: Model, printer: SymenginePrinter) -> list[list[Expr]]:
    """Each equation `M q_ddot - F - A^T lambda = 0` as a list of symengine terms: the
    accelerations in coordinate order, each with its mass entry's common factors pulled out
    (`l1*l2*(m2 + m3)*cos(theta1 - theta2)*theta2_ddot`), then the rest collected by the part
    that depends on the state (`g*l1*(m1 + m2)*sin(theta1)`, see `collected`), then the
    multipliers. Reads only `model.symengine` (and the constraint rows, which are small)."""
    forms = model.symengine
    state = state_symbols(model)
    rows = []
    for i in range(model.n):
        terms = [common_factor(se.Add(*pythagorean(summands(flat_arguments(forms.mass[i][j]))))) * forms.qdd[j] for j in range(model.n) if forms.mass[i][j] != 0]
        terms += collected(-forms.forcing[i], state, printer)
        for c in model.constraints:
            if c.jacobian[i] != 0:
                terms.append(-common_factor(to_symengine(c.jacobian[i])) * to_symengine(c.multiplier))
        rows.append(terms or [se.Integer(0)])
    return rows


def state_symbols(model: Model) -> frozenset[Expr]:
    """The symbols that vary along a motion (coordinates, velocities, accelerations, time,
    multipliers): everything but the parameters."""
    forms = model.symengine
    return frozenset([*forms.q, *forms.qd, *forms.qdd, forms.t, *(to_symengine(c.multiplier) for c in model.constraints)])


def collected(expr: Expr, state: frozenset[Expr], printer: SymenginePrinter) -> list[Expr]:
    """The terms of `expr` (as the deriver gives them: expanded within `algebra`'s bounds) with
    those that differ only in a constant factor added up: `g*l*m1*sin(theta) + g*l*m2*sin(theta)` -> `g*l*(m1 + m2)*sin(theta)`.
    Terms are keyed by their state-dependent factors; the constant ones (no state) come last.
    Linear in the number of terms; ordered by the printer's key of their state-dependent part."""
    if expr == 0:
        return []
    groups: dict[Expr, list[Expr]] = {}
    for term in pythagorean(summands(flat_arguments(expr))):
        constant: list[Expr] = []
        varying: list[Expr] = []
        for factor in se.Mul.make_args(term):
            if not factor.free_symbols & state:
                constant.append(factor)
            else:  # a sum with the state in it (`2*l*m + 2*m*x`) with its common factors out
                varying.append(common_factor(factor) if factor.is_Add else factor)
        groups.setdefault(se.Mul(*varying), []).append(se.Mul(*constant))
    order = sorted(groups, key=lambda key: (key == 1, printer.key(key)))
    return [common_factor(se.Add(*groups[key])) * key for key in order]


def pythagorean(terms: Sequence[Expr]) -> list[Expr]:
    """The terms with every pair `R*sin(x)**2 + R*cos(x)**2` (the same R, coefficient included)
    replaced by `R`, as a reader would write them: spatial bodies give such pairs (the products of
    rotation matrices). Pairs are found by hashing each term with one sin(x)**2 or cos(x)**2
    divided out, so a pass is linear in the number of terms and their factors. A merged term can
    pair again (`(s1**2 + c1**2)*(s2**2 + c2**2)` written out gives 1): passes repeat while they
    merge, each at least halving a pair, so there are at most as many passes as squared sines
    and cosines in a term."""
    alive = list(terms)
    while True:
        halves: dict[tuple[bool, Expr, Expr], int] = {}
        used: set[int] = set()
        merged: list[Expr] = []
        for index, term in enumerate(alive):
            for factor in se.Mul.make_args(term):
                if not (factor.is_Pow and factor.args[1].is_Integer and int(factor.args[1]) >= 2 and isinstance(factor.args[0], (se.sin, se.cos))):
                    continue
                base = factor.args[0]
                rest = term / base**2
                partner = halves.get((not isinstance(base, se.sin), base.args[0], rest))
                if partner is not None and partner not in used:
                    used.update((partner, index))
                    merged.append(rest)
                    break
                halves.setdefault((isinstance(base, se.sin), base.args[0], rest), index)
        if not merged:
            return alive
        alive = [term for k, term in enumerate(alive) if k not in used] + merged


def flat_arguments(expr: Expr) -> Expr:
    """`expr` with the arguments of its functions multiplied out where a sum holds a multiple
    of another sum (`sin(w*t - (w*t + theta))` -> `-sin(theta)`), as a reader writes them."""
    nested = {f: f.func(*(se.expand(a) for a in f.args)) for f in expr.atoms(_Function) if any(_nested(a) for a in f.args)}
    return expr.xreplace(nested) if nested else expr


def _nested(arg: Expr) -> bool:
    return bool(arg.is_Add and any(t.is_Mul and any(a.is_Add for a in t.args) for t in arg.args))


def summands(expr: Expr) -> list[Expr]:
    """The terms of a sum, also of a number times a sum (symengine keeps `-(a + b)` as a product)."""
    if expr.is_Mul and len(expr.args) == 2 and expr.args[0].is_Number and expr.args[1].is_Add:
        return [expr.args[0] * term for term in expr.args[1].args]
    return list(se.Add.make_args(expr))


def common_factor(expr: Expr) -> Expr:
    """A sum with the factors common to all its terms pulled out, as `factor_terms` does for the
    simple cases (and in linear time): `l1*l2*m2*c + l1*l2*m3*c` -> `l1*l2*c*(m2 + m3)`,
    `2*a*x + 4*a*y` -> `2*a*(x + 2*y)`, `-a - b` -> `-(a + b)`; integers as their gcd,
    powers to the lowest exponent shared (exponents that are numbers of one sign)."""
    if not expr.is_Add:
        return expr
    terms = [_powers(t) for t in expr.args]
    shared = dict(terms[0][1])
    for _, powers in terms[1:]:
        for base in list(shared):
            if base not in powers:
                del shared[base]
                continue
            a, b = shared[base], powers[base]
            if not (a.is_Number and b.is_Number) or a.is_negative != b.is_negative:
                del shared[base]
            else:
                shared[base] = a if abs(float(a)) <= abs(float(b)) else b
    coefficients = [c for c, _ in terms]
    number: Expr = se.Integer(1)
    if all(c.is_Integer for c in coefficients):  # `(3*M/2 + m)` stays: a fraction pulled out reads worse
        content = 0
        for c in coefficients:
            content = _gcd(content, abs(int(c)))
        number = se.Integer(content)
    if all(c.is_Number and c.is_negative for c in coefficients):
        number = -number
    common = se.Mul(number, *(se.Pow(b, e) for b, e in shared.items()))
    if common == 1:
        return expr
    return common * se.Add(*(t / common for t in expr.args))


def negative(term: Expr) -> bool:
    """A term printed with a minus in front: a negative number, or a product with one."""
    if term.is_Number:
        return bool(term.is_negative)
    return bool(term.is_Mul and term.args[0].is_Number and term.args[0].is_negative)


def _powers(term: Expr) -> tuple[Expr, dict[Expr, Expr]]:
    coefficient: Expr = se.Integer(1)
    powers: dict[Expr, Expr] = {}
    for factor in se.Mul.make_args(term):
        if factor.is_Number:
            coefficient = coefficient * factor
        elif factor.is_Pow:
            base, exponent = factor.args
            powers[base] = exponent
        else:
            powers[factor] = se.Integer(1)
    return coefficient, powers


def _gcd(a: int, b: int) -> int:
    while b:
        a, b = b, a % b
    return a


_DIGITS = re.compile(r"(\d+)")
_COEFFICIENT = re.compile(r"^-?(\d+\*)?")
KEY_CHARS = 60


def natural(text: str) -> tuple[Any, ...]:
    """A sort key that orders the numbers inside names by value: `m2` before `m10`."""
    return tuple(int(part) if k % 2 else part for k, part in enumerate(_DIGITS.split(text)))


class SymenginePrinter:
    """The walk shared by the text and LaTeX printers of symengine expressions: one method per
    kind of node, every distinct subexpression printed once (memoized), terms of a sum and
    factors of a product in a fixed, readable order (see `order`, `factor_order`). Nodes it has
    no rule for (derivatives, `Subs`, floats, ...; rare and small) are converted to sympy and
    printed by `fallback`, the sympy printer of the same output format."""

    # symengine function class -> the name the output uses (text: the sympy name)
    functions: ClassVar[dict[str, str]] = {
        name: name for name in ["sin", "cos", "tan", "cot", "sec", "csc", "asin", "acos", "atan", "acot", "sinh", "cosh", "tanh", "coth", "asinh", "acosh", "atanh", "log"]
    }

    def __init__(self) -> None:
        self._memo: dict[Expr, str] = {}
        self._keys: dict[Expr, tuple[Any, ...]] = {}
        self._ranks: dict[Expr, tuple[int, tuple[Any, ...]]] = {}
        self.calls = 0  # nodes printed (not counting memo hits): linear in the size of the output

    def doprint(self, expr: Expr) -> str:
        if isinstance(expr, sp.Basic):
            return self.fallback(expr)
        found = self._memo.get(expr)
        if found is None:
            self.calls += 1
            found = self._memo[expr] = self._print(expr)
        return found

    __call__ = doprint

    def _print(self, expr: Expr) -> str:
        if expr.is_Add:
            return self.add(self.order(expr.args))
        if expr.is_Mul:
            return self.mul(expr)
        if expr.is_Pow:
            base, exponent = expr.args
            if base == se.E:
                return self.exp(exponent)
            return self.power(base, exponent)
        if expr.is_Symbol:
            return self.symbol(expr.name)
        if expr.is_Integer:
            return str(int(expr))
        if expr.is_Rational:
            return self.rational(int(expr.p), int(expr.q))
        if expr == se.pi:
            return self.pi()
        kind = type(expr).__name__
        if kind == "FunctionSymbol":
            return self.function(expr.get_name(), expr.args, undefined=True)
        if kind in self.functions and len(expr.args) == 1:
            return self.function(kind, expr.args)
        return self.fallback(expr._sympy_())

    # --- order ---

    def key(self, expr: Expr) -> tuple[Any, ...]:
        """The sort key of a term: the start of its text without the sign and the number in
        front, in natural order (a prefix keeps keys short: a sum is printed once, not compared
        at its full length)."""
        found = self._keys.get(expr)
        if found is None:
            found = self._keys[expr] = natural(_COEFFICIENT.sub("", self.text(expr), count=1)[:KEY_CHARS])
        return found

    def text(self, expr: Expr) -> str:
        """The text on which orders are based (the same for every output format)."""
        return self.doprint(expr)

    def order(self, terms: Iterable[Expr]) -> list[Expr]:
        """Terms by `key`, except that a difference of two terms starts with the positive one
        (`m2 - m1`, `cos(theta2 - theta1)`)."""
        out = sorted(terms, key=self.key)
        if len(out) != 2:
            return out
        positive = next((k for k, term in enumerate(out) if not negative(term)), 0)
        return [out[positive], *out[:positive], *out[positive + 1 :]]

    def factor_order(self, factors: Iterable[Expr]) -> list[Expr]:
        """Symbols and their powers by name, then sums, then functions, then anything else."""

        def rank(factor: Expr) -> tuple[int, tuple[Any, ...]]:
            found = self._ranks.get(factor)
            if found is None:
                found = self._ranks[factor] = _rank(factor)
            return found

        def _rank(factor: Expr) -> tuple[int, tuple[Any, ...]]:
            base = factor.args[0] if factor.is_Pow and factor.args[0] != se.E else factor
            if base.is_Symbol:
                return 0, natural(base.name)
            if base.is_Add:
                return 1, self.key(base)
            if type(base).__name__ in self.functions or type(base).__name__ == "FunctionSymbol":
                return 2, natural(self.text(base)[:KEY_CHARS])
            return 3, natural(self.text(base)[:KEY_CHARS])

        return sorted(factors, key=rank)

    def split(self, expr: Expr) -> tuple[Expr, list[Expr], list[Expr]]:
        """A product as (its number, the factors above the line, the factors below it)."""
        number: Expr = se.Integer(1)
        above: list[Expr] = []
        below: list[Expr] = []
        for factor in expr.args:
            if factor.is_Number:
                number = number * factor
            elif factor.is_Pow and factor.args[1].is_Number and factor.args[1].is_negative and factor.args[0] != se.E:
                base, exponent = factor.args
                below.append(base if exponent == -1 else se.Pow(base, -exponent))
            else:
                above.append(factor)
        return number, self.factor_order(above), self.factor_order(below)

    # --- per format ---

    def add(self, terms: Sequence[Expr]) -> str:
        out = ""
        for term in terms:
            printed = self.doprint(term)
            if not out:
                out = printed
            elif printed.startswith("-"):
                out += " - " + printed[1:].lstrip()
            else:
                out += " + " + printed
        return out or "0"

    def mul(self, expr: Expr) -> str:
        raise NotImplementedError

    def power(self, base: Expr, exponent: Expr) -> str:
        raise NotImplementedError

    def exp(self, exponent: Expr) -> str:
        raise NotImplementedError

    def symbol(self, name: str) -> str:
        return name

    def rational(self, p: int, q: int) -> str:
        return f"{p}/{q}"

    def pi(self) -> str:
        return "pi"

    def function(self, name: str, args: Sequence[Expr], undefined: bool = False) -> str:
        raise NotImplementedError

    def fallback(self, expr: sp.Basic) -> str:
        raise NotImplementedError


def written_definitions(definitions: Mapping[str, Any]) -> str:
    """The generated files' sentence naming the functions written out from the file's definitions
    (`U(s) = -k/s; ...`, sorted by name): every target states it the same way."""
    listed = "; ".join(f"{name}({', '.join(map(str, f.variables))}) = {sp.sstr(f.expr)}" for name, f in sorted(definitions.items()))
    return f"Functions written out from their definitions in the file: {listed}."
