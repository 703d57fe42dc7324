"""A safe expression parser: Python/SymPy syntax in, sympy expressions out.

Text is parsed with `ast.parse` and the tree is walked against a whitelist; nothing
is ever passed to `eval` or `sympify`. Every error points at the offending column.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import sympy as sp

from lagrange_cli.errors import Span, fail

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
DERIVATIVES = ("Derivative", "diff")
RESERVED = frozenset({"t", *FUNCTIONS, *CONSTANTS, *DERIVATIVES})

MAX_LENGTH = 4000
MAX_DEPTH = 50
MAX_NODES = 4000
MAX_EXPONENT = 1000
MAX_DIGITS = 40


@dataclass(frozen=True)
class Scope:
    """What an expression may name: symbols, undefined functions, and d/dt."""

    symbols: Mapping[str, sp.Expr]
    functions: Mapping[str, sp.FunctionClass]
    time: sp.Symbol
    time_derivative: Callable[[sp.Expr], sp.Expr]
    what: str = "the coordinates, parameters, `t`"


def parse_expression(text: str, span: Span, scope: Scope) -> sp.Expr:
    """Parse one expression, e.g. `l*sin(theta)`, into sympy."""
    text = text.strip()
    if not text:
        raise fail(span, "empty expression", "an expression such as `m*g*l*cos(theta)`")
    if len(text) > MAX_LENGTH:
        raise fail(span, f"expression is {len(text)} characters long", f"at most {MAX_LENGTH}")
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        column = (exc.offset or 1) - 1
        raise fail(span.shifted(column), f"invalid expression syntax: {exc.msg}", "Python/SymPy syntax such as `l*sin(theta)`") from None
    except (RecursionError, MemoryError, ValueError):
        raise fail(span, "expression is nested too deeply", f"at most {MAX_DEPTH} levels of nesting") from None
    nodes = sum(1 for _ in ast.walk(tree))
    if nodes > MAX_NODES:
        raise fail(span, f"expression has {nodes} syntax nodes", f"at most {MAX_NODES}")
    return _Builder(span, scope).build(tree.body, 0)


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
    rhs_text = text[cut + 1 :]
    offset = cut + 1 + len(rhs_text) - len(rhs_text.lstrip())
    rhs = parse_expression(rhs_text, span.shifted(offset), scope)
    return lhs - rhs


class _Builder:
    def __init__(self, span: Span, scope: Scope) -> None:
        self.span = span
        self.scope = scope

    def at(self, node: ast.AST) -> Span:
        return self.span.shifted(getattr(node, "col_offset", 0))

    def build(self, node: ast.AST, depth: int) -> sp.Expr:
        if depth > MAX_DEPTH:
            raise fail(self.at(node), "expression is nested too deeply", f"at most {MAX_DEPTH} levels of nesting")
        method = getattr(self, "_" + type(node).__name__, None)
        if method is None:
            raise fail(self.at(node), f"{_describe(node)} is not allowed in an expression", "numbers, names, + - * / **, and the listed functions")
        result: sp.Expr = method(node, depth + 1)
        return result

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
        return sp.Float(value)

    def _Name(self, node: ast.Name, depth: int) -> sp.Expr:
        name = node.id
        if name in self.scope.symbols:
            return self.scope.symbols[name]
        if name == "t":
            return self.scope.time
        if name in CONSTANTS:
            return CONSTANTS[name]
        if name in FUNCTIONS or name in self.scope.functions or name in DERIVATIVES:
            raise fail(self.at(node), f"function '{name}' used without arguments", f"a call such as `{name}(x)`")
        hint = _closest(name, [*self.scope.symbols, "t", *CONSTANTS])
        raise fail(self.at(node), f"unknown name '{name}'", f"{self.scope.what} or a function" + (f"; did you mean '{hint}'?" if hint else ""))

    def _UnaryOp(self, node: ast.UnaryOp, depth: int) -> sp.Expr:
        operand = self.build(node.operand, depth)
        if isinstance(node.op, ast.USub):
            return -operand
        if isinstance(node.op, ast.UAdd):
            return operand
        raise fail(self.at(node), f"operator {type(node.op).__name__} is not allowed", "+ - * / **")

    def _BinOp(self, node: ast.BinOp, depth: int) -> sp.Expr:
        left = self.build(node.left, depth)
        right = self.build(node.right, depth)
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
            return left**right
        raise fail(self.at(node), f"operator {type(op).__name__} is not allowed", "+ - * / **")

    def _Call(self, node: ast.Call, depth: int) -> sp.Expr:
        if not isinstance(node.func, ast.Name):
            raise fail(self.at(node), "only plain function names can be called", "a call such as `sin(theta)`")
        name = node.func.id
        if node.keywords:
            raise fail(self.at(node), f"keyword arguments in a call to '{name}'", "positional arguments only")
        args = [self.build(arg, depth) for arg in node.args]
        if name in DERIVATIVES:
            return self._derivative(node, name, args)
        if name in FUNCTIONS:
            function, arity = FUNCTIONS[name]
            if len(args) != arity:
                raise fail(self.at(node), f"'{name}' takes {arity} argument{'s' * (arity > 1)}, got {len(args)}", f"{name}({', '.join('xy'[:arity])})")
            return function(*args)
        if name in self.scope.functions:
            if not args:
                raise fail(self.at(node), f"'{name}' called without arguments", f"`{name}(x)`")
            return self.scope.functions[name](*args)
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
            for _ in range(int(order)):
                expr = self.scope.time_derivative(expr)
            return expr
        if not isinstance(variable, sp.Symbol):
            raise fail(self.at(node.args[1]), "can only differentiate with respect to a name", usage)
        return sp.diff(expr, variable, int(order))


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
