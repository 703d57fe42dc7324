"""A safe expression parser: Python/SymPy syntax in, sympy expressions out.

Text is parsed with `ast.parse` and the tree is walked against a whitelist; nothing
is ever passed to `eval` or `sympify`. Every error points at the offending column.
"""

from __future__ import annotations

import ast
import math
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import sympy as sp
from sympy.core.function import AppliedUndef

from lagrange_cli.errors import LagrangeError, Span, fail

FUNCTIONS: dict[str, tuple[Callable[..., sp.Expr], int]] = {
    "sin": (sp.sin, 1),
    "cos": (sp.cos, 1),
    "tan": (sp.tan, 1),
    "cot": (sp.cot, 1),
    "sec": (sp.sec, 1),
    "csc": (sp.csc, 1),
    "asin": (sp.asin, 1),
    "acos": (sp.acos, 1),
    "atan": (sp.atan, 1),
    "atan2": (sp.atan2, 2),
    "sinh": (sp.sinh, 1),
    "cosh": (sp.cosh, 1),
    "tanh": (sp.tanh, 1),
    "exp": (sp.exp, 1),
    "log": (sp.log, 1),
    "sqrt": (sp.sqrt, 1),
    "Abs": (sp.Abs, 1),
    "sign": (sp.sign, 1),
}
CONSTANTS: dict[str, sp.Expr] = {"pi": sp.pi, "E": sp.E}
SUPPORTED_FUNCTIONS = frozenset({sp.sin, sp.cos, sp.tan, sp.cot, sp.sec, sp.csc, sp.asin, sp.acos, sp.atan, sp.atan2, sp.sinh, sp.cosh, sp.tanh, sp.exp, sp.log, sp.Abs, sp.sign})
DERIVATIVES = ("Derivative", "diff")
RESERVED = frozenset({"t", *FUNCTIONS, *CONSTANTS, *DERIVATIVES})

MAX_LENGTH = 4000
MAX_DEPTH = 50
MAX_NODES = 4000
MAX_EXPONENT = 1000
MAX_DIGITS = 40
MAX_BITS = 1000  # exact numbers computed from literals stay below about 1e300
UNDEFINED = (sp.zoo, sp.nan, sp.oo, -sp.oo)


@dataclass(frozen=True)
class Scope:
    """What an expression may name: symbols, undefined functions, and d/dt."""

    symbols: Mapping[str, sp.Expr]
    functions: Mapping[str, sp.FunctionClass]
    time: sp.Symbol
    time_derivative: Callable[[sp.Expr], sp.Expr]
    what: str = "the coordinates, parameters, `t`"
    elsewhere: Mapping[str, str] = field(default_factory=dict)
    """Declared names that may not appear here, each with what it is (e.g. `x_dot` -> "a velocity")."""
    note: str = ""
    """Advice for when one of those appears, e.g. where velocity-dependent terms belong."""
    arities: Mapping[str, int] = field(default_factory=dict)
    """The number of arguments of each declared function that states it (map form of `functions`)."""

    def refusal(self) -> str:
        """The `expected:` text for a name from `elsewhere`."""
        return self.what + (f"; {self.note}" if self.note else "")


def parse_expression(text: str, span: Span, scope: Scope) -> sp.Expr:
    """Parse one expression, e.g. `l*sin(theta)`, into sympy.

    Columns in errors count characters from the start of `text` as given (leading blanks
    included); line breaks (from a YAML block scalar) are read as spaces."""
    stripped = text.lstrip()
    span = span.shifted(len(text) - len(stripped))
    text = stripped.rstrip().replace("\r", " ").replace("\n", " ")
    if not text:
        raise fail(span, "empty expression", "an expression such as `m*g*l*cos(theta)`")
    if len(text) > MAX_LENGTH:
        raise fail(span, f"expression is {len(text)} characters long", f"at most {MAX_LENGTH} characters")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # `1if x else 2` warns; make it an error at its place, not stray stderr output
            tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        column = (exc.offset - 1 if exc.offset else len(text)) if (exc.lineno or 1) == 1 else 0
        if "too many nested" in exc.msg or "too complex" in exc.msg:
            raise fail(span.shifted(column), "expression is nested too deeply", f"at most {MAX_DEPTH} levels of nesting") from None
        message = exc.msg if exc.offset else "the expression ends too early"
        raise fail(span.shifted(column), f"invalid expression syntax: {message}", "Python/SymPy syntax such as `l*sin(theta)`") from None
    except (RecursionError, MemoryError, ValueError):
        raise fail(span, "expression is nested too deeply", f"at most {MAX_DEPTH} levels of nesting") from None
    nodes = sum(1 for _ in ast.walk(tree))
    if nodes > MAX_NODES:
        raise fail(span, f"expression has {nodes} syntax nodes", f"at most {MAX_NODES} syntax nodes (a shorter expression)")
    builder = _Builder(text, span, scope)
    result = builder.build(tree.body, 0)
    builder.supported(tree.body, result)
    for power in result.atoms(sp.Pow):
        if power.exp.is_Number and abs(power.exp) > MAX_EXPONENT:
            raise fail(span, f"the expression amounts to a power with exponent {power.exp}", f"an exponent of at most {MAX_EXPONENT}")
    return result


def parse_equation(text: str, span: Span, scope: Scope) -> sp.Expr:
    """Parse `lhs = rhs` (or a bare expression meaning `= 0`) into `lhs - rhs`."""
    positions = [i for i, c in enumerate(text) if c == "=" and text[i - 1 : i] not in ("<", ">", "!", "=") and text[i + 1 : i + 2] != "="]
    if "==" in text:
        raise fail(span.shifted(text.index("==")), "'==' in an equation", "a single '=' between the two sides")
    if len(positions) > 1:
        raise fail(span.shifted(positions[1]), "more than one '=' in an equation", "`lhs = rhs`")
    if not positions:
        return parse_expression(text, span, scope)
    cut = positions[0]
    lhs = parse_expression(text[:cut], span, scope)
    rhs = parse_expression(text[cut + 1 :], span.shifted(cut + 1), scope)
    return lhs - rhs


class _Builder:
    def __init__(self, text: str, span: Span, scope: Scope) -> None:
        self.encoded = text.encode("utf-8")
        self.span = span
        self.scope = scope

    def at(self, node: ast.AST) -> Span:
        """Where `node` starts; `ast` counts UTF-8 bytes, spans count characters."""
        offset = getattr(node, "col_offset", 0)
        return self.span.shifted(len(self.encoded[:offset].decode("utf-8", errors="ignore")))

    def build(self, node: ast.AST, depth: int) -> sp.Expr:
        if depth > MAX_DEPTH:
            raise fail(self.at(node), "expression is nested too deeply", f"at most {MAX_DEPTH} levels of nesting")
        method = getattr(self, "_" + type(node).__name__, None)
        if method is None:
            raise fail(self.at(node), f"{_describe(node)} is not allowed in an expression", "numbers, names, + - * / **, and the listed functions")
        result: sp.Expr = method(node, depth + 1)
        return self.checked(node, result)

    def checked(self, node: ast.AST, value: sp.Expr) -> sp.Expr:
        """`value`, unless it is undefined (`log(0)`), a huge exact number, or a number that
        double precision cannot hold (`1e300*1e300` overflows, `1e-200*1e-200` underflows to 0).
        Literals are folded as the tree is built, so each product or sum of numbers passes here:
        looking at the number itself and at the numeric coefficient of a sum or product suffices."""
        if value.is_Atom and value in UNDEFINED:  # the undefined values are atoms: no comparisons of a whole sum
            raise fail(self.at(node), f"this is undefined ({value})", "an expression with a finite value, e.g. no `log(0)` or `tan(pi/2)`")
        if value.is_Rational and max(abs(value.p), value.q).bit_length() > MAX_BITS:
            raise fail(self.at(node), "number is too large", "numbers below 1e300")
        for number in (value, value.as_coeff_Mul()[0], value.as_coeff_Add()[0]) if value.is_Add or value.is_Mul else (value,):
            problem = float_problem(number)
            if problem:
                raise fail(self.at(node), f"this number {problem}", "numbers between 1e-300 and 1e300 in size (or 0)")
        return value

    def real_number(self, node: ast.AST, value: sp.Expr, what: str) -> None:
        """Fail unless the constant `value` is a real number of a sensible size."""
        try:
            numeric_value(value)
        except OverflowError:
            raise fail(self.at(node), f"the value of {what} is too large", "numbers below 1e300") from None
        except ValueError:
            raise fail(self.at(node), f"{what} is not a real number", "real values: e.g. `sqrt` and `log` of positive numbers, `asin` and `acos` of numbers from -1 to 1") from None

    def supported(self, node: ast.AST, value: sp.Expr) -> None:
        """Fail if sympy turned `value` into something the deriver cannot take, e.g. the
        imaginary unit, `re`/`im`, a Dirac delta, or `Subs` (a derivative of `U` at `2*x`)."""
        stack = [value]
        while stack:
            item = stack.pop()
            if isinstance(item, sp.Derivative):
                stack.extend((item.expr, *item.variables))
                continue
            if item.is_Symbol or item.is_Rational or item.is_Float or item in (sp.pi, sp.E):
                continue
            if isinstance(item, (sp.Add, sp.Mul, sp.Pow, AppliedUndef)) or type(item) in SUPPORTED_FUNCTIONS:
                stack.extend(item.args)
                continue
            if item is sp.I:
                raise fail(self.at(node), "this is not a real number (it involves the imaginary unit)", "real values: e.g. `sqrt` and `log` of positive quantities")
            if isinstance(item, sp.Subs):
                function = item.expr.expr.func if isinstance(item.expr, sp.Derivative) else item.expr
                raise fail(
                    self.at(node),
                    f"the derivative of '{function}' at a compound argument ({', '.join(map(str, item.point))}) is not supported",
                    "declared functions applied to a single coordinate or parameter, e.g. `U(r)`",
                )
            raise fail(self.at(node), f"this leads to '{type(item).__name__}' ({item}), which is not supported", "smooth real expressions of the listed functions")

    def _Constant(self, node: ast.Constant, depth: int) -> sp.Expr:
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise fail(self.at(node), f"{value!r} is not a number", "a real number")
        if isinstance(value, int):
            if len(str(abs(value))) > MAX_DIGITS:
                raise fail(self.at(node), "integer literal is too long", f"at most {MAX_DIGITS} digits")
            return sp.Integer(value)
        if not math.isfinite(value):
            raise fail(self.at(node), "number is not finite", "a finite real number")
        if value == 0.0 and any(c in "123456789" for c in self.literal(node).lower().split("e")[0]):
            raise fail(self.at(node), f"number {self.literal(node)} underflows to 0 in double precision", "numbers between 1e-300 and 1e300 in size (or 0)")
        return sp.Float(value)

    def literal(self, node: ast.AST) -> str:
        """The source text of `node` (a number literal)."""
        start, end = getattr(node, "col_offset", 0), getattr(node, "end_col_offset", None)
        return self.encoded[start:end].decode("utf-8", errors="ignore")

    def _Name(self, node: ast.Name, depth: int) -> sp.Expr:
        name = node.id
        if name in self.scope.symbols:
            return self.scope.symbols[name]
        if name in self.scope.elsewhere:
            raise fail(self.at(node), f"'{name}' is {self.scope.elsewhere[name]}, which cannot appear here", self.scope.refusal())
        if name == "t":
            return self.scope.time
        if name in CONSTANTS:
            return CONSTANTS[name]
        if name in FUNCTIONS or name in self.scope.functions or name in DERIVATIVES:
            raise fail(self.at(node), f"function '{name}' used without arguments", f"a call such as `{name}(x)`")
        hint = _closest(name, [*self.scope.symbols, "t", *CONSTANTS])
        raise fail(self.at(node), f"unknown name '{name}'", self.scope.what + (" or a function" if "function" not in self.scope.what else "") + (f"; did you mean '{hint}'?" if hint else ""))

    def _UnaryOp(self, node: ast.UnaryOp, depth: int) -> sp.Expr:
        operand = self.build(node.operand, depth)
        if isinstance(node.op, ast.USub):
            return -operand
        if isinstance(node.op, ast.UAdd):
            return operand
        raise fail(self.at(node), f"operator {type(node.op).__name__} is not allowed", "+ - * / **")

    def _BinOp(self, node: ast.BinOp, depth: int) -> sp.Expr:
        # `a + b + c + ...` nests to the left; walk that spine in a loop so that a long sum
        # or product counts as one level of nesting, not one level per term.
        spine = [node]
        while isinstance(spine[-1].left, ast.BinOp):
            spine.append(spine[-1].left)
        value = self.build(spine[-1].left, depth)
        for item in reversed(spine):
            value = self.checked(item, self._binary(item, value, self.build(item.right, depth)))
        return value

    def _binary(self, node: ast.BinOp, left: sp.Expr, right: sp.Expr) -> sp.Expr:
        op = node.op
        if isinstance(op, ast.Add):
            return left + right
        if isinstance(op, ast.Sub):
            return left - right
        if isinstance(op, ast.Mult):
            return left * right
        if isinstance(op, ast.Div):
            if right == 0:
                raise fail(self.at(node.right), "division by zero", "a non-zero divisor")
            return left / right
        if isinstance(op, ast.Pow):
            if right.is_Number and (abs(right) > MAX_EXPONENT or (left.is_Number and abs(right) * sp.log(abs(left) + 2, 10) > 300)):
                raise fail(self.at(node.right), f"exponent {right} is too large", f"an exponent of at most {MAX_EXPONENT} (and a result below 1e300)")
            if left == 0 and right.is_Number and right <= 0:
                raise fail(self.at(node), "zero to a non-positive power", "a defined power")
            if left == 0 and not right.is_Number:
                raise fail(self.at(node), "zero to a variable power, which is undefined where the exponent is not positive and has no derivative", "a non-zero base, or 0")
            power = left**right
            if isinstance(power, sp.Pow) and power.exp.is_Number and abs(power.exp) > MAX_EXPONENT:
                raise fail(self.at(node), f"this power amounts to an exponent of {power.exp}", f"an exponent of at most {MAX_EXPONENT}")
            if power.is_number and power not in UNDEFINED:
                self.real_number(node, power, "this power")
            return power
        raise fail(self.at(node), f"operator {type(op).__name__} is not allowed", "+ - * / **")

    def _Call(self, node: ast.Call, depth: int) -> sp.Expr:
        if not isinstance(node.func, ast.Name):
            raise fail(self.at(node), "only plain function names can be called", "a call such as `sin(theta)`")
        name = node.func.id
        if node.keywords:
            raise fail(self.at(node), f"keyword arguments in a call to '{name}'", "positional arguments only")
        args = [self.build(arg, depth) for arg in node.args]
        if name in DERIVATIVES:
            derivative = self._derivative(node, name, args)
            self.supported(node, derivative)
            return derivative
        if name in FUNCTIONS:
            function, arity = FUNCTIONS[name]
            if len(args) != arity:
                raise fail(self.at(node), f"'{name}' takes {arity} argument{'s' * (arity > 1)}, got {len(args)}", f"{name}({', '.join('xy'[:arity])})")
            result = function(*args)
            if all(a.is_number for a in args) and result not in UNDEFINED:
                self.real_number(node, result, f"'{name}(...)'")
            return result
        if name in self.scope.functions:
            if not args:
                raise fail(self.at(node), f"'{name}' called without arguments", f"`{name}(x)`")
            declared = self.scope.arities.get(name)
            if declared is not None and len(args) != declared:
                plural = "s" * (declared > 1)
                raise fail(self.at(node), f"'{name}' takes {declared} argument{plural}, got {len(args)}", f"{declared} argument{plural}, as declared under `functions`")
            return self.scope.functions[name](*args)
        if name in self.scope.elsewhere:
            raise fail(self.at(node.func), f"'{name}' is {self.scope.elsewhere[name]}, which cannot appear here", self.scope.refusal())
        hint = _closest(name, [*FUNCTIONS, *self.scope.functions, *DERIVATIVES])
        raise fail(self.at(node.func), f"unknown function '{name}'", "one of " + ", ".join(sorted(FUNCTIONS)) + ", or a name listed under `functions`" + (f"; did you mean '{hint}'?" if hint else ""))

    def _derivative(self, node: ast.Call, name: str, args: list[sp.Expr]) -> sp.Expr:
        usage = f"`{name}(expr, t)` for the total time derivative, or `{name}(U(r), r)`"
        if len(args) not in (2, 3):
            raise fail(self.at(node), f"'{name}' takes an expression and a variable", usage)
        expr, variable = args[0], args[1]
        order = args[2] if len(args) == 3 else sp.Integer(1)
        if not (order.is_Integer and 1 <= int(order) <= 3):
            raise fail(self.at(node.args[2]), "derivative order must be 1, 2 or 3", usage)
        if variable == self.scope.time:
            try:
                for _ in range(int(order)):
                    expr = self.scope.time_derivative(expr)
            except LagrangeError as exc:
                raise fail(self.at(node), str(exc), "a time derivative of an expression without accelerations (at most second derivatives of the coordinates)") from None
            return expr
        if not isinstance(variable, sp.Symbol):
            raise fail(self.at(node.args[1]), "can only differentiate with respect to a name", usage)
        return real_derivative(expr, lambda e, real: sp.diff(e, real.get(variable, variable), int(order)))


def float_problem(number: sp.Expr) -> str:
    """What is wrong with a number in double precision ('overflows', 'underflows to 0'), or ''."""
    if not (number.is_Float or number.is_Rational):
        return ""
    if number.is_Rational:
        if max(abs(number.p), number.q).bit_length() > 4 * MAX_BITS:
            return "is too large to compute with"
        try:
            value = float(number)
        except OverflowError:
            return "overflows double precision"
    else:
        value = float(number)
    if not math.isfinite(value):
        return "overflows double precision"
    if value == 0.0 and not number.is_zero:
        return "underflows to 0 in double precision"
    return ""


def real_derivative(expr: sp.Expr, differentiate: Callable[[sp.Expr, Mapping[sp.Symbol, sp.Symbol]], sp.Expr]) -> sp.Expr:
    """`differentiate(expr, real)` with every symbol of `expr` replaced by a real one (`real`
    maps each symbol to its stand-in), then put back: all quantities in a system file are real,
    and sympy differentiates `Abs(x)` of a symbol of unknown kind into `re(x)` and `im(x)` terms."""
    real = {s: sp.Dummy(s.name, real=True) for s in expr.free_symbols if isinstance(s, sp.Symbol)}
    back = {stand_in: s for s, stand_in in real.items()}
    return differentiate(expr.xreplace(real), real).xreplace(back)


_MATH: dict[Any, Callable[..., float]] = {
    sp.sin: math.sin,
    sp.cos: math.cos,
    sp.tan: math.tan,
    sp.cot: lambda x: 1 / math.tan(x),
    sp.sec: lambda x: 1 / math.cos(x),
    sp.csc: lambda x: 1 / math.sin(x),
    sp.asin: math.asin,
    sp.acos: math.acos,
    sp.atan: math.atan,
    sp.atan2: math.atan2,
    sp.sinh: math.sinh,
    sp.cosh: math.cosh,
    sp.tanh: math.tanh,
    sp.exp: math.exp,
    sp.log: math.log,
    sp.Abs: abs,
    sp.sign: lambda x: float((x > 0) - (x < 0)),
}


def numeric_value(expr: sp.Expr, values: Mapping[sp.Basic, float] | None = None) -> float:
    """The value of a constant expression in floating point, computed bottom-up so that it
    never hangs (unlike `evalf` on `exp(exp(exp(9)))`). Raises `OverflowError` when it is
    too large for a float and `ValueError` when it is not a real number. Symbols take their
    `values` (a symbol without one is not a number)."""
    if values is not None and expr in values:
        value = float(values[expr])
    elif expr.is_Rational or expr.is_Float:
        value = float(expr)
    elif expr is sp.pi:
        value = math.pi
    elif expr is sp.E:
        value = math.e
    elif isinstance(expr, sp.Add):
        value = math.fsum(numeric_value(a, values) for a in expr.args)
    elif isinstance(expr, sp.Mul):
        value = math.prod(numeric_value(a, values) for a in expr.args)
    elif isinstance(expr, sp.Pow):
        base, exponent = numeric_value(expr.base, values), numeric_value(expr.exp, values)
        if base == 0 and exponent <= 0:
            raise ValueError("zero to a non-positive power")
        value = math.pow(base, exponent)
    elif type(expr) in _MATH:
        try:
            value = _MATH[type(expr)](*(numeric_value(a, values) for a in expr.args))
        except ZeroDivisionError:
            raise ValueError("undefined") from None
    else:
        raise ValueError(f"{expr} is not a real number")
    if math.isinf(value):
        raise OverflowError("too large")
    if math.isnan(value):
        raise ValueError("undefined")
    return value


def _describe(node: ast.AST) -> str:
    names = {
        "Attribute": "attribute access",
        "Subscript": "indexing",
        "Lambda": "a lambda",
        "Compare": "a comparison",
        "BoolOp": "a boolean operator",
        "IfExp": "a conditional",
        "List": "a list",
        "Tuple": "a tuple",
        "Dict": "a dict",
        "Set": "a set",
        "JoinedStr": "an f-string",
        "NamedExpr": "an assignment",
        "Starred": "unpacking",
        "ListComp": "a comprehension",
        "GeneratorExp": "a generator",
    }
    return names.get(type(node).__name__, f"syntax '{type(node).__name__}'")


def _closest(name: str, candidates: list[str]) -> str | None:
    import difflib

    matches = difflib.get_close_matches(name, candidates, n=1, cutoff=0.6)
    return matches[0] if matches else None
