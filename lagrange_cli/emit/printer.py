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

from lagrange_cli._symengine import se
from lagrange_cli.errors import DerivationError

ATOM = 100
"""A name, a call, a non-negative number: never needs parentheses."""
POWER = 60
UNARY = 50
MUL = 40
ADD = 30

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
    temporaries = [(str(rename[symbol]), value.xreplace(rename)) for symbol, value in replacements]
    return temporaries, [e.xreplace(rename) for e in reduced]


_EXP1 = type(se.E)
_HALF = se.Rational(1, 2)


def _negative_number(value: Any) -> bool:
    return bool(value.is_Number and value.is_negative)


def _short(value: Any, limit: int = 60) -> str:
    """A short, printable rendering of a symbol or expression for an error message (file text stays data)."""
    text = str(value)
    text = "".join(char if " " <= char <= "~" else "?" for char in text)
    return text if len(text) <= limit else text[: limit - 3] + "..."
