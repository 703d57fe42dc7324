"""The printer core shared by every code target: symengine expressions to code, one subclass per language.

In the spirit of sympy's printers (`sympy/printing/printer.py`): a `Printer` dispatches on the
class of each node, `_print_<ClassName>`, walking the class's MRO (so `sin` falls back to
`_print_Function`, `Zero` to `_print_Integer`). Unlike sympy's, it prints *symengine* expressions
directly (the big-system path never converts to sympy), and every handler returns the text
together with its precedence, so that parentheses are exactly the ones the grammar needs:

    class PythonPrinter(Printer):
        functions = {**Printer.functions, "Abs": "abs"}
        def _print_Pi(self, expr): return "pi_literal", ATOM

Subclasses override only what differs between languages, through these hooks:

- `functions`: symengine function class name (`sin`, `atan2`, `Abs`, ...) -> the language's
  name; every name printed is recorded in `used` (for imports). `cot`, `sec` and `csc` print
  as `1/tan(x)`, `1/cos(x)`, `1/sin(x)` through the table; `sign` and anything not in the
  table raise `DerivationError` unless the subclass defines `_print_sign` / `_print_<Name>`.
- `integer(n)`, `rational(p, q)`, `real(x)`, `nonfinite(x)`: number literals. The defaults
  round-trip exactly: integers below 2**53 as they are, larger ones (and rationals with a
  part that large) as the nearest double; a rational as the exact division `p/q` (IEEE
  division of two exact doubles is correctly rounded, so `1/3` *is* the double nearest 1/3
  in any language with float division; C-like languages override `rational` to `1.0/3.0`);
  a float as `repr`, the shortest text that reads back as the same double.
- `integer_power(base, n)` (integer n >= 2): `b**n` with `power_operator`, else `pow(b, n)`;
  `power(base, exponent)` for every other real power: `pow(b, e)`. Squares of names print as
  `b*b`, x**(1/2) as `sqrt(x)`, negative powers as divisions `1/...`, E**x as `exp(x)`.
- `call(name, args)`: a function call, `name(a, b)` by default.

Precedence levels (`ATOM` > `POWER` > `UNARY` > `MUL` > `ADD`) follow Python's and C's grammar:
unary minus binds looser than `**` (so `-x**2` is `-(x**2)`), `a*b/c` is left-associative, and
a divisor is parenthesised unless it is an atom or a power. Sums print their positive terms
first (`a + b - c`); products their numerator, then `/` and the denominator (`2*x/(3*y)`).

`common_subexpressions` runs CSE once over everything a function computes (M and F together),
naming the temporaries `<prefix>0, <prefix>1, ...` while skipping any name in `taken` and any
symbol already in the expressions, so that no temporary can meet a user's (mangled) name.
`Printer.block` is CSE plus printing: the (name, code) assignments in order and the results.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from typing import Any, ClassVar

from lagrange_cli._symengine import se, to_symengine
from lagrange_cli.errors import DerivationError

ATOM = 100
"""A name, a call, a non-negative number: never needs parentheses."""
POWER = 60
UNARY = 50
MUL = 40
ADD = 30

OFFSET_TERMS = 12
"""The most monomials `restructure` factors at once around a constant offset (a spring's energy has 6)."""
EXACT = 2**53
"""Integers below this are exact doubles (and fit every language's integer type we print)."""

Code = tuple[str, int]
"""Printed text and its precedence."""


class Printer:
    """Prints symengine expressions as code in one language; one subclass per language.

    `names` maps a symbol's name (`str(symbol)`) to its identifier in the generated code (after
    `mangle`). A symbol not in `names` is an error, never printed under its own name. Dispatch
    is by node class name (`_print_Add`, `_print_Mul`, `_print_Pow`, `_print_Symbol`,
    `_print_Integer`, `_print_Rational`, `_print_RealDouble`, `_print_Function`, `_print_Pi`,
    `_print_Exp1`, ...), each handler returning `(text, precedence)`."""

    functions: ClassVar[Mapping[str, str]] = {
        **{name: name for name in ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp", "log", "sqrt")},
        "Abs": "fabs",
    }
    """symengine function class name -> the target language's function name."""
    reciprocals: ClassVar[Mapping[str, str]] = {"cot": "tan", "sec": "cos", "csc": "sin"}
    power_operator: ClassVar[str | None] = "**"
    """The infix power operator (`**`), or None for languages where integer powers are `pow(b, n)` too."""

    def __init__(self, names: Mapping[str, str]) -> None:
        self.names: dict[str, str] = dict(names)
        self.used: set[str] = set()
        """The language names of the functions and constants printed so far (for imports)."""
        self._handlers: dict[type, Callable[[Any], Code]] = {}

    # -- entry points -----------------------------------------------------------------------------

    def doprint(self, expr: Any) -> str:
        """The code of `expr`."""
        return self._print(expr)[0]

    def block(self, exprs: Sequence[Any], prefix: str, taken: Collection[str] = ()) -> tuple[list[tuple[str, str]], list[str]]:
        """CSE once over `exprs`, then printing: ([(temporary, code), ...] in order, [result code, ...]).
        The temporaries are added to `names`, and avoid `taken`, the names already known to this
        printer and the symbols of `exprs` (see `common_subexpressions`)."""
        temporaries, reduced = common_subexpressions(exprs, prefix, {*taken, *self.names.values()})
        self.names.update((name, name) for name, _ in temporaries)
        return [(name, self.doprint(value)) for name, value in temporaries], [self.doprint(e) for e in reduced]

    # -- dispatch ---------------------------------------------------------------------------------

    def _print(self, expr: Any) -> Code:
        handler = self._handlers.get(type(expr))
        if handler is None:
            handler = self._handler(type(expr))
            self._handlers[type(expr)] = handler
        return handler(expr)

    def _handler(self, cls: type) -> Callable[[Any], Code]:
        for klass in cls.__mro__:
            method = getattr(self, f"_print_{klass.__name__}", None)
            if method is not None:
                return method  # type: ignore[no-any-return]
        return self._unsupported

    def parenthesize(self, expr: Any, level: int) -> str:
        """The code of `expr`, in parentheses when it binds looser than `level`."""
        text, precedence = self._print(expr)
        return f"({text})" if precedence < level else text

    def _unsupported(self, expr: Any) -> Code:
        raise DerivationError(f"cannot write code for {type(expr).__name__} ({_short(expr)}): not supported by this target")

    # -- hooks ------------------------------------------------------------------------------------

    def integer(self, value: int) -> Code:
        """An integer literal (non-negative `value`): exact below 2**53, else the nearest double."""
        return (str(value), ATOM) if value < EXACT else self.real(float(value))

    def rational(self, p: int, q: int) -> Code:
        """p/q (p, q > 0, q > 1) as an exact division, correctly rounded by any float division."""
        if max(p, q) >= EXACT:
            return self.real(p / q)
        return f"{p}/{q}", MUL

    def real(self, value: float) -> Code:
        """A non-negative float literal that reads back as the same double."""
        return (repr(value), ATOM) if math.isfinite(value) else self.nonfinite(value)

    def nonfinite(self, value: float) -> Code:
        """Infinity or NaN; no default, since each language spells them differently."""
        raise DerivationError(f"cannot write the number {value} in this target")

    def call(self, name: str, args: Iterable[str]) -> Code:
        self.used.add(name)
        return f"{name}({', '.join(args)})", ATOM

    def function_name(self, name: str) -> str:
        """The language's name of symengine's function `name` (a DerivationError when it has none)."""
        try:
            return self.functions[name]
        except KeyError:
            raise DerivationError(f"cannot write code for the function '{name}': not supported by this target") from None

    def integer_power(self, base: Any, n: int) -> Code:
        """base**n for an integer n >= 2 (squares of names print as `x*x` before this is asked):
        `b**n` with `power_operator`, else `pow(b, n)`."""
        if self.power_operator is None:
            return self.call(self.functions.get("pow", "pow"), [self.doprint(base), self.integer(n)[0]])
        return f"{self.parenthesize(base, ATOM)}{self.power_operator}{self.integer(n)[0]}", POWER

    def power(self, base: Any, exponent: Any) -> Code:
        """A real power with a non-integer (or symbolic) exponent: `pow(b, e)`."""
        return self.call(self.functions.get("pow", "pow"), [self.doprint(base), self.doprint(exponent)])

    # -- atoms ------------------------------------------------------------------------------------

    def _print_Symbol(self, expr: Any) -> Code:
        name = str(expr)
        try:
            return self.names[name], ATOM
        except KeyError:
            raise DerivationError(f"cannot write code for the symbol '{_short(name)}', which is not a coordinate, velocity, parameter or t") from None

    def _print_Integer(self, expr: Any) -> Code:
        value = int(expr)
        if value < 0:
            text, _ = self.integer(-value)
            return "-" + text, UNARY
        return self.integer(value)

    def _print_Rational(self, expr: Any) -> Code:
        p, q = (int(v) for v in expr.get_num_den())
        if p < 0:
            text, _ = self.rational(-p, q)
            return "-" + text, UNARY
        return self.rational(p, q)

    def _print_RealDouble(self, expr: Any) -> Code:
        value = float(expr)
        if value < 0 or (value == 0 and math.copysign(1.0, value) < 0):
            text, _ = self.real(-value)
            return "-" + text, UNARY
        return self.real(value)

    _print_Float = _print_RealDouble

    def _print_Infinity(self, expr: Any) -> Code:
        return self.nonfinite(math.inf)

    def _print_NegativeInfinity(self, expr: Any) -> Code:
        text, _ = self.nonfinite(math.inf)
        return "-" + text, UNARY

    def _print_NaN(self, expr: Any) -> Code:
        return self.nonfinite(math.nan)

    def _print_Pi(self, expr: Any) -> Code:
        return self.real(math.pi)

    def _print_Exp1(self, expr: Any) -> Code:
        return self.real(math.e)

    def _print_Complex(self, expr: Any) -> Code:
        raise DerivationError("the equations contain the imaginary unit; generated code computes with real numbers only")

    _print_ImaginaryUnit = _print_Complex
    _print_ComplexDouble = _print_Complex
    _print_ComplexInfinity = _print_Complex

    # -- arithmetic -------------------------------------------------------------------------------

    def _print_Add(self, expr: Any) -> Code:
        positive: list[str] = []
        negative: list[str] = []
        for term in expr.args:
            minus, text = self._signed(term)
            (negative if minus else positive).append(text)
        if positive:
            return " + ".join(positive) + "".join(" - " + text for text in negative), ADD
        return "-" + " - ".join(negative), ADD

    def _signed(self, term: Any) -> tuple[bool, str]:
        """(True, text of -term) when `term` is negative in form (a negative number or product), else (False, text of term)."""
        if term.is_Mul:
            minus, text, _ = self._product(term)
            return minus, text
        text, precedence = self._print(term)
        if precedence == UNARY and text.startswith("-"):
            return True, text[1:]
        return False, text

    def _print_Mul(self, expr: Any) -> Code:
        minus, text, precedence = self._product(expr)
        return ("-" + text, UNARY) if minus else (text, precedence)

    def _product(self, expr: Any) -> tuple[bool, str, int]:
        """(sign, text of the product without its sign, its precedence): the coefficient and the
        other factors, then `/` and the denominator (negative powers and the coefficient's q)."""
        numerator: list[Code] = []
        denominator: list[Any] = []
        coefficient_q = ""
        minus = False
        for factor in expr.args:
            if factor.is_Number:
                minus, top, coefficient_q = self._coefficient(factor)
                if top != ("1", ATOM):
                    numerator.insert(0, top)
            elif factor.is_Pow and _negative_number(factor.args[1]):
                denominator.append(factor.args[0] if factor.args[1] == -1 else se.Pow(factor.args[0], -factor.args[1]))
            else:
                numerator.append(self._print(factor))
        if not numerator:
            text, precedence = "1", ATOM
        elif len(numerator) == 1:
            text, precedence = numerator[0]
            if precedence < MUL:  # -(a + b), (a + b)/c
                text, precedence = f"({text})", ATOM
        else:
            text, precedence = "*".join(f"({t})" if p < MUL else t for t, p in numerator), MUL
        parts = ([coefficient_q] if coefficient_q else []) + [self.parenthesize(d, MUL) for d in denominator]
        if not parts:
            return minus, text, precedence
        if len(parts) == 1:
            below = parts[0] if coefficient_q else self.parenthesize(denominator[0], POWER)
            return minus, f"{text}/{below}", MUL
        return minus, f"{text}/({'*'.join(parts)})", MUL

    def _coefficient(self, number: Any) -> tuple[bool, Code, str]:
        """(negative, numerator code, denominator text or "") of a product's numeric coefficient."""
        if isinstance(number, se.Integer):
            value = int(number)
            return value < 0, self.integer(abs(value)), ""
        if isinstance(number, se.Rational):
            p, q = (int(v) for v in number.get_num_den())
            if max(abs(p), q) >= EXACT:
                return p < 0, self.real(abs(p) / q), ""
            return p < 0, self.integer(abs(p)), self.integer(q)[0]
        text, precedence = self._print(number)
        if precedence == UNARY and text.startswith("-"):
            return True, (text[1:], ATOM), ""
        return False, (text, precedence), ""

    def _print_Pow(self, expr: Any) -> Code:
        base, exponent = expr.args
        if type(base) is _EXP1:
            return self.call(self.function_name("exp"), [self.doprint(exponent)])
        if _negative_number(exponent):
            below = base if exponent == -1 else se.Pow(base, -exponent)
            return f"1/{self.parenthesize(below, POWER)}", MUL
        if isinstance(exponent, se.Integer):
            n = int(exponent)
            if n == 1:
                return self._print(base)
            if n == 2 and (base.is_Symbol or (base.is_Number and not base.is_negative)):
                text = self.doprint(base)
                return f"{text}*{text}", MUL
            return self.integer_power(base, n)
        if isinstance(exponent, se.Rational) and exponent == _HALF:
            return self.call(self.function_name("sqrt"), [self.doprint(base)])
        return self.power(base, exponent)

    # -- functions --------------------------------------------------------------------------------

    def _print_Function(self, expr: Any) -> Code:
        name = type(expr).__name__
        if name in self.reciprocals:
            text, _ = self.call(self.function_name(self.reciprocals[name]), [self.doprint(a) for a in expr.args])
            return f"1/{text}", MUL
        return self.call(self.function_name(name), [self.doprint(a) for a in expr.args])

    def _print_FunctionSymbol(self, expr: Any) -> Code:
        raise DerivationError(f"cannot write code for the undefined function {_short(expr)}; give it a definition in the file's `functions`")

    def _print_Derivative(self, expr: Any) -> Code:
        raise DerivationError(f"cannot write code for the derivative {_short(expr)} of an undefined function; give the function a definition in the file's `functions`")

    _print_Subs = _print_Derivative


def common_subexpressions(exprs: Sequence[Any], prefix: str, taken: Collection[str] = ()) -> tuple[list[tuple[str, Any]], list[Any]]:
    """CSE once over all of `exprs` (e.g. M and F together): ([(temporary name, value), ...] in
    order of computation, the reduced expressions), values and reduced expressions referring to
    earlier temporaries as symbols of those names. The names are `<prefix>0, <prefix>1, ...`,
    skipping any name in `taken` (the user's names after mangle) or of a symbol of `exprs`."""
    exprs = [se.sympify(e) if not isinstance(e, se.Basic) else e for e in exprs]
    if not exprs:
        return [], []
    replacements, reduced = se.cse(exprs)
    if not replacements:
        return [], list(reduced)
    avoid = set(taken)
    for e in exprs:
        avoid.update(str(s) for s in e.free_symbols)
    rename: dict[Any, Any] = {}
    counter = 0
    for symbol, _ in replacements:
        while f"{prefix}{counter}" in avoid:
            counter += 1
        rename[symbol] = se.Symbol(f"{prefix}{counter}")
        counter += 1

    def renamed(value: Any) -> Any:  # only the temporaries it has: xreplace converts its whole map on each call
        return value.xreplace({s: rename[s] for s in value.free_symbols if s in rename})

    temporaries = [(str(rename[symbol]), renamed(value)) for symbol, value in replacements]
    return temporaries, [renamed(e) for e in reduced]


_EXP1 = type(se.E)
_HALF = se.Rational(1, 2)


def _negative_number(value: Any) -> bool:
    return bool(value.is_Number and value.is_negative)


def _short(value: Any, limit: int = 60) -> str:
    """A short, printable rendering of a symbol or expression for an error message (file text stays data)."""
    text = str(value)
    text = "".join(char if " " <= char <= "~" else "?" for char in text)
    return text if len(text) <= limit else text[: limit - 3] + "..."


# -- structure-aware rewriting ------------------------------------------------------------------


def restructure(exprs: Sequence[Any], constants: Collection[str], velocities: Collection[str] = (), *, products: bool = True, tag: str = "") -> tuple[list[tuple[str, Any]], list[Any]]:
    """Cheaper-to-evaluate forms of `exprs`, for any target: ([(name, value), ...] to compute
    first, in order, the rewritten expressions using those names as symbols). Linear in the
    number of terms (it never runs a CSE over the big expressions, only over their constant
    coefficients), so that it scales to big systems.

    - sin and cos of a single varying symbol (a coordinate, a velocity, t) become the
      temporaries `_sin<k>`, `_cos<k>`, computed once; sin and cos of a difference of two such
      symbols, `a - b`, become `_sd<k>_<l>`, `_cd<k>_<l>` (one per unordered pair, the reversed
      difference being `-_sd` and `_cd`), computed from them as products when `products`
      (cos(a - b) = cos a cos b + sin a sin b, sin(a - b) = sin a cos b - cos a sin b: no
      further calls) or by one call each otherwise. Only factors of the terms of a sum (or of a
      product) are rewritten; trig nested deeper stays as it is;
    - each sum is collected by its varying part, sum_k c_k v_k(q_dot) x_k(q, t) K_k(constants),
      each K_k, a polynomial in the constants (symbol names `constants`), factored greedily
      (Horner: l1*l2*m2 + l1*l2*m3 = l1*l2*(m2 + m3)) and all of them CSE'd together (sharing
      the suffix sums m2 + m3 within m1 + m2 + m3, and products of constants);
    - except around a constant offset: the terms of a sum polynomial in the varying symbols
      that hold a coordinate-free term are factored first (k*l - k*r -> -k*(r - l), k/2 r^2 -
      k l r + k/2 l^2 -> k/2 (r - l)^2, see `_Restructure.offsets`), since collected they are
      terms of size k cancelling to the force near r = l (round-off of a spacing of k);
    - a product x_k K_k met more than once (e.g. l_i l_j S sin(q_i - q_j) in F_i and F_j) is
      the temporary `_pk<i>`, computed once.

    Symbols named in `velocities` (velocities, accelerations, multipliers) are kept out of the
    x_k. `tag` goes into every name made here (`_sin<tag><k>`, `_k<tag><i>`, ...), so that several
    restructured blocks can share one function. The values are exact rewrites (the same real function), so `exprs` and the result agree
    up to rounding."""
    work = _Restructure(frozenset(constants), frozenset(velocities), tag)
    terms = [work.collect(e) for e in exprs]
    definitions = work.definitions(products)
    taken = {name for name, _ in definitions}
    distinct = list(dict.fromkeys(k for rows in terms for _, _, _, k in rows if not (k.is_Number or k.is_Symbol)))
    temporaries, reduced = common_subexpressions(distinct, f"_k{tag}", taken)
    definitions += temporaries
    counts: dict[tuple[Any, Any], int] = {}
    uses: dict[Any, int] = {}
    for rows in terms:
        for _, _, x, k in rows:
            counts[(x, k)] = counts.get((x, k), 0) + 1
            uses[k] = uses.get(k, 0) + 1
    coefficient = {}
    shared = 0
    for k, value in zip(distinct, reduced, strict=True):
        if uses[k] > 1 and not value.is_Symbol:  # a product of constants used twice is computed once
            definitions.append((name := f"_kk{tag}{shared}", value))
            shared += 1
            value = se.Symbol(name)
        coefficient[k] = value
    bound: dict[tuple[Any, Any], Any] = {}
    result = []
    for rows in terms:
        parts = []
        for c, v, x, k in rows:
            if counts[(x, k)] > 1 and not (x == 1 or k == 1):
                if (x, k) not in bound:
                    bound[(x, k)] = symbol = se.Symbol(f"_pk{tag}{len(bound)}")
                    definitions.append((str(symbol), x * coefficient.get(k, k)))
                parts.append(c * v * bound[(x, k)])
            else:
                parts.append(c * v * x * coefficient.get(k, k))
        result.append(se.Add(*parts))
    return definitions, result


class _Restructure:
    def __init__(self, constant: frozenset[str], velocities: frozenset[str], tag: str) -> None:
        self.constant = constant
        self.tag = tag
        self.velocities = velocities
        self.factors: dict[Any, tuple[int, Any, int]] = {}
        """factor -> (sign, replacement, 0 constant / 1 position / 2 velocity)"""
        self.index: dict[str, int] = {}
        """angle name -> k of `_sin<k>`, in order of first sight"""
        self.angles: dict[str, Any] = {}
        self.singles: dict[str, set[str]] = {}
        self.pairs: dict[tuple[str, str], set[str]] = {}
        self.made: set[str] = set()
        """names of the temporaries made here (`_sin0`, `_cd1_2`, ...)"""

    def collect(self, expr: Any) -> list[tuple[Any, Any, Any, Any]]:
        """`expr` as terms (c, v, x, K): number, velocity part, position part, constant part
        (factored, numeric coefficient moved into c), one per distinct varying part."""
        terms = expr.args if expr.is_Add else (expr,)
        groups: dict[tuple[Any, Any], list[tuple[Any, dict[Any, Any]]]] = {}
        for term in terms:
            coefficient: Any = _ONE
            position: list[Any] = []
            velocity: list[Any] = []
            fixed: dict[Any, Any] = {}
            for factor in term.args if term.is_Mul else (term,):
                if factor.is_Number:
                    coefficient = coefficient * factor
                    continue
                info = self.factors.get(factor)
                if info is None:
                    info = self.classify(factor)
                    self.factors[factor] = info
                sign, replacement, kind = info
                if sign < 0:
                    coefficient = -coefficient
                if kind == 2:
                    velocity.append(replacement)
                elif kind == 1:
                    position.append(replacement)
                elif replacement.is_Pow and replacement.args[1].is_Number and replacement.args[1].is_positive:
                    fixed[replacement.args[0]] = replacement.args[1]
                else:
                    fixed[replacement] = _ONE
            groups.setdefault((se.Mul(*velocity), se.Mul(*position)), []).append((coefficient, fixed))
        rows = []
        for (v, x), items in groups.items():
            c, k = _number_apart(_horner(items))
            rows.append((c, v, x, k))
        return self.offsets(rows) if len(rows) > 1 else rows

    def offsets(self, rows: list[tuple[Any, Any, Any, Any]]) -> list[tuple[Any, Any, Any, Any]]:
        """`rows` with the terms polynomial in the varying symbols around a constant offset factored:
        k*l - k*r -> -k*(r - l), k/2*r**2 - k*l*r + k/2*l**2 -> k/2*(r - l)**2, k*x1 - k*x2 - k*l ->
        k*(x1 - x2 - l), the same under a common varying factor (k*r*sin(th) - k*l*sin(th) -> k*(r - l)*sin(th)).

        Collected by varying part, k*l and k*r are two terms of size k whose difference, near
        r = l, is the force: with k = 1e10 it carries round-off of a spacing of 1e10, where
        k*(r - l) is exact to a few ulps of itself. A group is the terms sharing their velocity
        part and their non-polynomial position factors (trig temporaries, roots, ...); only a group
        whose polynomial parts, divided by their common monomial, hold a 1 (a coordinate-free
        offset, the only source of this cancellation) and a varying monomial is looked at
        (`factored`); every other sum costs one pass over its terms."""
        groups: dict[tuple[Any, Any], list[tuple[tuple[Any, Any, Any, Any], dict[Any, int]]]] = {}
        for row in rows:
            powers, rest = self.polynomial(row[2])
            groups.setdefault((row[1], rest), []).append((row, powers))
        result: list[tuple[Any, Any, Any, Any]] = []
        for (v, rest), members in groups.items():
            if len(members) < 2 or not _offset([powers for _, powers in members]):
                result += [row for row, _ in members]
                continue
            result += self.factored(v, rest, members)
        return result

    def polynomial(self, x: Any) -> tuple[dict[Any, int], Any]:
        """({varying symbol: power}, the other factors) of a position part `x`: its factors that are a
        coordinate or t (not a temporary made here) to a positive integer power, and the rest."""
        powers: dict[Any, int] = {}
        rest: list[Any] = []
        for factor in x.args if x.is_Mul else (x,):
            base, exponent = factor.args if factor.is_Pow else (factor, _ONE)
            if base.is_Symbol and str(base) not in self.made and exponent.is_Integer and int(exponent) > 0:
                powers[base] = int(exponent)
            elif not factor.is_Number:
                rest.append(factor)
        return powers, se.Mul(*rest)

    def factored(self, v: Any, rest: Any, members: list[tuple[tuple[Any, Any, Any, Any], dict[Any, int]]]) -> list[tuple[Any, Any, Any, Any]]:
        """The rows of one group with an offset (see `offsets`), as monomials (the constant parts
        expanded), factored where that pulls out a common factor (`_content`): the whole group
        first when it has at most `OFFSET_TERMS` monomials, then, once each, the monomials sharing
        a constant symbol, the most shared first (k1*l1 - k1*x1 + k2*x2 - k2*x1 - k2*l2 - g*m ->
        -k1*(x1 - l1) + k2*(x2 - x1 - l2) - g*m): at most one try of at most `OFFSET_TERMS` terms
        per constant symbol. Monomials left over stay collected by varying part. A group with
        floating-point coefficients is left as it is."""
        monomials: list[tuple[Any, dict[Any, int], int]] = []
        for index, ((c, _, _, k), powers) in enumerate(members):
            constant = se.expand(c * k)
            if any(isinstance(part, se.RealDouble) for part in _atoms(constant)):
                return [row for row, _ in members]
            monomials += [(part, powers, index) for part in (constant.args if constant.is_Add else (constant,))]
        names = [{s for s in term.free_symbols if str(s) in self.constant} for term, _, _ in monomials]
        counts: dict[Any, int] = {}
        for found in names:
            for symbol in found:
                counts[symbol] = counts.get(symbol, 0) + 1
        left = list(range(len(monomials)))
        result: list[tuple[Any, Any, Any, Any]] = []
        for symbol in [None, *sorted(counts, key=lambda s: (-counts[s], str(s)))]:
            subset = [i for i in left if symbol is None or symbol in names[i]]
            if not 2 <= len(subset) <= OFFSET_TERMS or not _offset([monomials[i][1] for i in subset]):
                continue
            factored = _content([(monomials[i][0], monomials[i][1]) for i in subset], self.constant)
            if factored is None:
                continue
            coefficient, constant_part, varying = factored
            result.append((coefficient, v, rest * varying, constant_part))
            left = [i for i in left if i not in subset]
        if len(left) == len(monomials):
            return [row for row, _ in members]
        kept: dict[int, list[Any]] = {}
        for i in left:
            kept.setdefault(monomials[i][2], []).append(monomials[i][0])
        for index, parts in kept.items():
            (_, _, x, _), _ = members[index]
            number, k = _number_apart(se.Add(*parts))
            result.append((number, v, x, k))
        return result

    def classify(self, factor: Any) -> tuple[int, Any, int]:
        """(sign, replacement, kind) of one factor of a term: kind 0 constant, 1 position, 2 velocity."""
        base, exponent = factor.args if factor.is_Pow else (factor, None)
        names = {str(s) for s in factor.free_symbols}
        kind = 2 if names & self.velocities else 1 if names - self.constant else 0
        if kind != 0 and base.is_Add:  # a sum inside a product, e.g. g*m3*(-l1*cos(th1) - l2*cos(th2)): rewritten too
            inner = se.Add(*(c * v * x * k for c, v, x, k in self.collect(base)))
            return 1, inner if exponent is None else inner**exponent, kind
        if kind != 1 or not isinstance(base, (se.sin, se.cos)):
            return 1, factor, kind
        sign, symbol = self.trig(base)
        if symbol is None:
            return 1, factor, kind
        if exponent is None:
            return sign, symbol, 1
        if sign < 0 and exponent.is_Integer and int(exponent) % 2 == 1:
            return -1, symbol**exponent, 1
        return 1, symbol**exponent, 1

    def number(self, angle: Any) -> int:
        name = str(angle)
        if name not in self.index:
            self.index[name] = len(self.index)
            self.angles[name] = angle
        return self.index[name]

    def trig(self, node: Any) -> tuple[int, Any]:
        """(sign, temporary) standing for sin/cos `node`, or (1, None) when it is of another argument."""
        (argument,) = node.args
        kind = "sin" if isinstance(node, se.sin) else "cos"
        if argument.is_Symbol and str(argument) not in self.constant:
            k = self.number(argument)
            self.singles.setdefault(str(argument), set()).add(kind)
            return 1, self.temporary(f"_{kind}{self.tag}{k}")
        if not (argument.is_Add and len(argument.args) == 2):
            return 1, None
        difference = _difference(argument, self.constant)
        if difference is None:
            return 1, None
        a, b, sign = difference
        k, j = self.number(a), self.number(b)
        self.pairs.setdefault((str(a), str(b)), set()).add(kind)
        symbol = self.temporary(f"_{'sd' if kind == 'sin' else 'cd'}{self.tag}{k}_{j}")
        return (sign if kind == "sin" else 1), symbol

    def temporary(self, name: str) -> Any:
        """The symbol of a temporary made here (never a polynomial variable in `offsets`)."""
        self.made.add(name)
        return se.Symbol(name)

    def definitions(self, products: bool) -> list[tuple[str, Any]]:
        """The temporaries in order: sin and cos of single angles, then of the differences."""
        needed = {name: set(kinds) for name, kinds in self.singles.items()}
        if products:
            for a, b in self.pairs:
                needed.setdefault(a, set()).update(("sin", "cos"))
                needed.setdefault(b, set()).update(("sin", "cos"))
        result: list[tuple[str, Any]] = []
        for name in sorted(needed, key=self.index.__getitem__):
            k, angle = self.index[name], self.angles[name]
            result += [(f"_{kind}{self.tag}{k}", se.sin(angle) if kind == "sin" else se.cos(angle)) for kind in ("sin", "cos") if kind in needed[name]]
        for (a, b), kinds in sorted(self.pairs.items(), key=lambda item: (self.index[item[0][0]], self.index[item[0][1]])):
            k, j = self.index[a], self.index[b]
            sa, ca, sb, cb = (se.Symbol(f"_{kind}{self.tag}{i}") for i, kind in ((k, "sin"), (k, "cos"), (j, "sin"), (j, "cos")))
            if "sin" in kinds:
                result.append((f"_sd{self.tag}{k}_{j}", sa * cb - ca * sb if products else se.sin(self.angles[a] - self.angles[b])))
            if "cos" in kinds:
                result.append((f"_cd{self.tag}{k}_{j}", ca * cb + sa * sb if products else se.cos(self.angles[a] - self.angles[b])))
        return result


def _difference(argument: Any, constant: frozenset[str]) -> tuple[Any, Any, int] | None:
    """(a, b, sign) with argument = sign*(a - b), a before b by name, for a difference of two varying symbols."""
    first, second = argument.args
    plus = [t for t in (first, second) if t.is_Symbol]
    minus = [t.args[1] for t in (first, second) if t.is_Mul and len(t.args) == 2 and t.args[0] == -1 and t.args[1].is_Symbol]
    if len(plus) != 1 or len(minus) != 1:
        return None
    a, b = plus[0], minus[0]
    if str(a) in constant or str(b) in constant:
        return None
    return (a, b, 1) if str(a) < str(b) else (b, a, -1)


def _offset(parts: list[dict[Any, int]]) -> bool:
    """Whether polynomial parts ({symbol: power}), divided by their common monomial, hold both a 1
    (a coordinate-free offset) and a varying monomial."""
    common = {s: min(p.get(s, 0) for p in parts) for s in parts[0]}
    reduced = [any(power > common.get(s, 0) for s, power in p.items()) for p in parts]
    return any(reduced) and not all(reduced)


def _content(terms: list[tuple[Any, dict[Any, int]]], constant: frozenset[str]) -> tuple[Any, Any, Any] | None:
    """(number, constant factor, varying factor) of sum(K * prod(symbol**power)) over `terms`
    (K a monomial in the constants), their common factor pulled out: k*l - k*r -> (1, k, l - r);
    a polynomial left of degree 2 in the varying symbols that is a square of a linear form is
    written so (`_square`: k/2*(r**2 - 2*l*r + l**2) -> (1/2, k, (r - l)**2)), any other of degree
    2 or more is given to sympy's `factor` (at most `OFFSET_TERMS` terms); None when nothing factors."""
    bases: list[dict[Any, Any]] = []
    numbers: list[Any] = []
    for k, powers in terms:
        number: Any = _ONE
        factors: dict[Any, Any] = {}
        for factor in k.args if k.is_Mul else (k,):
            if factor.is_Number:
                number = number * factor
                continue
            base, exponent = factor.args if factor.is_Pow and factor.args[1].is_Number else (factor, _ONE)
            factors[base] = factors.get(base, 0) + exponent
        factors.update(powers)
        numbers.append(number)
        bases.append(factors)
    common = {b: min(f.get(b, 0) for f in bases) for b in bases[0] if all(b in f for f in bases)}
    inside = se.Add(*(n * _monomial(_ONE, {b: e - common.get(b, 0) for b, e in f.items() if e != common.get(b, 0)}) for n, f in zip(numbers, bases, strict=True)))
    outside = _monomial(_ONE, common)
    coefficient: Any = _ONE
    degree = _degree([{s: p for s, p in f.items() if s.is_Symbol and str(s) not in constant} for f in bases])
    square = _square(inside, constant) if degree == 2 else None
    if square is not None:
        coefficient, inside = square[0], square[1] ** 2
    elif degree >= 2:
        import sympy as sp

        product = sp.factor(sp.sympify(inside))
        pieces = product.as_ordered_factors() if product.is_Mul else [product]
        if any(f.is_Pow and f.args[0].is_Add for f in pieces) or len([f for f in pieces if not f.is_Number]) >= 2:
            inside = _ONE
            for f in pieces:
                if f.is_Number:
                    coefficient = coefficient * to_symengine(f)
                else:
                    inside = inside * to_symengine(f)
        elif not common:
            return None
    elif not common:
        return None
    fixed, varying = _split(outside * inside, constant)
    if fixed.is_Number:
        coefficient, fixed = coefficient * fixed, _ONE
    elif fixed.is_Mul and fixed.args[0].is_Number:
        coefficient, fixed = coefficient * fixed.args[0], fixed / fixed.args[0]
    return coefficient, fixed, varying


def _square(polynomial: Any, constant: frozenset[str]) -> tuple[Any, Any] | None:
    """(a, L) with `polynomial` = a*L**2, a a number and L linear in the varying symbols (those not
    in `constant`), when it is such a square (r**2 - 2*l*r + l**2 -> (1, r - l)), else None: the
    shape of every spring's energy, recognised without sympy (one expansion to check it)."""
    rows: dict[tuple[tuple[str, int], ...], list[Any]] = {}
    symbols: dict[str, Any] = {}
    for term in polynomial.args if polynomial.is_Add else (polynomial,):
        key: list[tuple[str, int]] = []
        fixed: list[Any] = []
        for factor in term.args if term.is_Mul else (term,):
            base, exponent = factor.args if factor.is_Pow else (factor, _ONE)
            if base.is_Symbol and str(base) not in constant and exponent.is_Integer:
                key.append((str(base), int(exponent)))
                symbols[str(base)] = base
            else:
                fixed.append(factor)
        rows.setdefault(tuple(sorted(key)), []).append(se.Mul(*fixed))
    squares = sorted(name for ((name, power),) in (k for k in rows if len(k) == 1) if power == 2)
    if not squares:
        return None
    name = squares[0]
    a = se.Add(*rows[((name, 2),)])
    if not a.is_Number or a == 0:
        return None
    linear = se.Add(symbols[name])
    for powers, parts in rows.items():
        if (name, 1) in powers:
            others = se.Mul(*(symbols[n] ** p for n, p in powers if n != name))
            linear = linear + se.Add(*parts) * others / (2 * a)
    if se.expand(a * linear**2 - polynomial) != 0:
        return None
    return a, linear


def _split(product: Any, constant: frozenset[str]) -> tuple[Any, Any]:
    """(the factors of `product` free of varying symbols, the others)."""
    fixed: list[Any] = []
    varying: list[Any] = []
    for factor in product.args if product.is_Mul else (product,):
        (fixed if all(str(s) in constant for s in factor.free_symbols) else varying).append(factor)
    return se.Mul(*fixed), se.Mul(*varying)


def _atoms(expr: Any) -> list[Any]:
    """The numbers of `expr`, at any depth."""
    stack, found = [expr], []
    while stack:
        e = stack.pop()
        if e.is_Number:
            found.append(e)
        else:
            stack.extend(e.args)
    return found


def _degree(parts: list[dict[Any, int]]) -> int:
    """The largest total degree of polynomial parts ({symbol: power}) divided by their common monomial."""
    common = {s: min(p.get(s, 0) for p in parts) for s in parts[0]}
    return max(sum(power - common.get(s, 0) for s, power in p.items()) for p in parts)


def _horner(items: list[tuple[Any, dict[Any, Any]]]) -> Any:
    """sum of coefficient * prod(base**exponent) over `items`, common factors pulled out greedily
    (the most frequent first), a shared numeric coefficient too: -a - b = -(a + b)."""
    if len(items) == 1:
        return _monomial(*items[0])
    coefficients = {c for c, _ in items}
    if len(coefficients) == 1 and (shared := next(iter(coefficients))) != 1:
        return shared * _horner([(_ONE, powers) for _, powers in items])
    counts: dict[Any, int] = {}
    for _, powers in items:
        for base in powers:
            counts[base] = counts.get(base, 0) + 1
    if not counts or max(counts.values()) < 2:
        return se.Add(*(_monomial(c, p) for c, p in items))
    top = max(counts.values())
    best = min((base for base, count in counts.items() if count == top), key=str)
    inside = [item for item in items if best in item[1]]
    exponent = min(powers[best] for _, powers in inside)
    reduced = []
    for c, powers in inside:
        rest = dict(powers)
        left = rest.pop(best) - exponent
        if left != 0:
            rest[best] = left
        reduced.append((c, rest))
    common = best**exponent * _horner(reduced)
    without = [item for item in items if best not in item[1]]
    return common + _horner(without) if without else common


def _number_apart(k: Any) -> tuple[Any, Any]:
    """(number, rest) with k = number * rest: 2*l*m -> (2, l*m), 3 -> (3, 1), l + m -> (1, l + m)."""
    if k.is_Number:
        return k, _ONE
    if k.is_Mul and k.args[0].is_Number:
        return k.args[0], k / k.args[0]
    return _ONE, k


def _monomial(coefficient: Any, powers: dict[Any, Any]) -> Any:
    return se.Mul(coefficient, *(base if exponent == 1 else base**exponent for base, exponent in powers.items()))


_ONE = se.Integer(1)
