"""The shared printer core (emit/printer.py) and its Python subclass: printed code evaluates to the
expression's value, numbers round-trip exactly, parentheses follow the grammar, CSE names never
collide, and what cannot be printed is an error."""

from __future__ import annotations

import math
import random
from collections.abc import Mapping
from fractions import Fraction
from typing import ClassVar

import pytest
import sympy as sp

from lagrange_cli._symengine import se
from lagrange_cli.emit.printer import ATOM, Printer, common_subexpressions
from lagrange_cli.emit.python import PythonPrinter
from lagrange_cli.errors import DerivationError

SYMBOLS = se.symbols("x y z w")
NAMES = {"x": "x", "y": "y", "z": "z", "w": "w"}
UNARY = [se.sin, se.cos, se.tan, se.atan, se.sinh, se.tanh, se.Abs, se.sign, se.cot, se.sec, se.csc]


def leaf(rng: random.Random) -> se.Basic:
    kind = rng.randrange(7)
    if kind <= 2:
        return rng.choice(SYMBOLS)
    if kind == 3:
        return se.Integer(rng.randint(-5, 5))
    if kind == 4:
        return se.Rational(rng.randint(-9, 9), rng.randint(2, 9))
    if kind == 5:
        return se.RealDouble(rng.choice([-1, 1]) * rng.uniform(0.1, 10.0))
    return rng.choice([se.pi, se.E])


def tree(rng: random.Random, depth: int, scaled: bool = True) -> se.Basic:
    """A random expression; huge and tiny floats only as factors outside function arguments, so
    that double and high-precision evaluation see the same arguments."""
    if depth == 0:
        return leaf(rng)
    kind = rng.randrange(11)
    if kind == 0:
        return se.Add(*(tree(rng, depth - 1, scaled) for _ in range(rng.randint(2, 4))))
    if kind == 1:
        return se.Mul(*(tree(rng, depth - 1, scaled) for _ in range(rng.randint(2, 3))))
    if kind == 2:
        return -tree(rng, depth - 1, scaled)
    if kind == 3:
        return tree(rng, depth - 1, scaled) ** rng.choice([-3, -2, -1, 2, 3, 4])
    if kind == 4:  # a real power of a positive base, nested powers included
        base = se.Abs(tree(rng, depth - 1, False)) + 1
        return base ** se.Rational(rng.choice([-5, -3, -1, 1, 3, 5]), rng.choice([2, 3]))
    if kind == 5:
        return se.sqrt(se.Abs(tree(rng, depth - 1, False)) + se.Rational(1, 2))
    if kind == 6:
        return rng.choice(UNARY)(tree(rng, depth - 1, False))
    if kind == 7:
        return se.atan2(tree(rng, depth - 1, False), tree(rng, depth - 1, False))
    if kind == 8:
        inner = tree(rng, depth - 1, False)
        return se.exp(se.sin(inner)) if rng.random() < 0.5 else se.log(se.Abs(inner) + 1)
    if kind == 9 and scaled:
        return tree(rng, depth - 1, scaled) * se.RealDouble(10.0 ** rng.randint(-300, 300))
    return tree(rng, depth - 1, scaled) ** (-1)


def evaluate(code: str, values: dict[str, float]) -> float:
    namespace = {name: getattr(math, name) for name in dir(math) if not name.startswith("_")}
    namespace.update(values)
    namespace["abs"] = abs
    return eval(code, {"__builtins__": {}}, namespace)


def reference(expr: se.Basic, values: dict[str, float]) -> complex:
    """The value by sympy at 40 digits, an evaluation independent of the printer."""
    converted = sp.sympify(expr)
    return complex(converted.evalf(40, subs={sp.Symbol(k): sp.Float(v, 40) for k, v in values.items()}))


def test_random_expressions_evaluate_to_their_value() -> None:
    rng = random.Random(20261123)
    compared = 0
    for _ in range(800):
        try:
            expr = tree(rng, rng.randint(1, 4))
        except RuntimeError:  # symengine refuses e.g. sin(oo) while building
            continue
        values = {name: rng.choice([-1, 1]) * rng.uniform(0.2, 3.0) for name in NAMES}
        printer = PythonPrinter(NAMES)
        try:
            code = printer.doprint(expr)
        except DerivationError:  # only the complex infinity or nan that symengine makes of 1/0
            assert any(word in str(expr) for word in ("zoo", "nan", "I")), expr
            continue
        expected = reference(expr, values)
        if abs(expected.imag) > 1e-30 or not math.isfinite(expected.real) or not 1e-250 < abs(expected.real) < 1e250:
            continue
        try:
            value = evaluate(code, values)
        except (ZeroDivisionError, OverflowError, ValueError) as error:  # pragma: no cover - a failure message
            raise AssertionError(f"{expr} printed as {code} fails with {error!r}; expected {expected.real}") from None
        assert math.isclose(value, expected.real, rel_tol=1e-7, abs_tol=0.0), (str(expr), code, value, expected.real)
        compared += 1
    assert compared > 500


@pytest.mark.parametrize("value", [0.1, 1 / 3, 2.0**-1074, 1.7976931348623157e308, 1e-300, 1e300, 123456789.123456789, 5e-324, 2.0**60])
def test_float_literals_round_trip(value: float) -> None:
    printer = PythonPrinter({})
    for signed in (value, -value):
        code = printer.doprint(se.RealDouble(signed))
        assert float(eval(code)) == signed


def test_rationals_are_exact_divisions() -> None:
    printer = PythonPrinter({"x": "x"})
    assert printer.doprint(se.Rational(1, 3)) == "1/3"
    assert printer.doprint(se.Rational(-2, 3) * SYMBOLS[0]) == "-2*x/3"
    big = se.Rational(2**60 + 1, 3)
    assert eval(printer.doprint(big)) == float(Fraction(2**60 + 1, 3))
    assert eval(printer.doprint(se.Integer(2**70))) == float(2**70)


@pytest.mark.parametrize(
    ("expr", "code"),
    [
        (-(SYMBOLS[0] ** 2), "-x*x"),
        (SYMBOLS[0] ** -2, "1/(x*x)"),
        (SYMBOLS[0] ** 3, "x**3"),
        (1 / (SYMBOLS[0] * SYMBOLS[1]), "1/(x*y)"),
        (SYMBOLS[2] / (SYMBOLS[0] + SYMBOLS[1]) ** 2, "z/(y + x)**2"),
        (-(SYMBOLS[0] + SYMBOLS[1]) * SYMBOLS[2], "-z*(y + x)"),
        (SYMBOLS[0] ** se.Rational(-1, 2), "1/sqrt(x)"),
        (se.exp(-SYMBOLS[0]), "exp(-x)"),
        (SYMBOLS[0] ** SYMBOLS[1], "pow(x, y)"),
        (SYMBOLS[0] - SYMBOLS[1], "x - y"),
        (se.sin(SYMBOLS[0]) ** 2, "sin(x)**2"),
    ],
)
def test_parentheses_follow_the_grammar(expr: se.Basic, code: str) -> None:
    assert PythonPrinter(NAMES).doprint(expr) == code


def test_used_names_are_recorded_for_imports() -> None:
    printer = PythonPrinter(NAMES)
    printer.doprint(se.sin(SYMBOLS[0]) + se.Abs(SYMBOLS[1]) + SYMBOLS[2] ** se.Rational(1, 3) + se.sign(SYMBOLS[3]))
    assert printer.imports() == ["copysign", "pow", "sin"]


def test_what_cannot_be_printed_is_an_error() -> None:
    printer = PythonPrinter(NAMES)
    u = se.Function("U")(SYMBOLS[0])
    for bad in (u, se.diff(u, SYMBOLS[0]), se.I * SYMBOLS[0], se.Symbol("secret")):
        with pytest.raises(DerivationError):
            printer.doprint(bad)
    with pytest.raises(DerivationError):  # the base class has no spelling of infinity
        Printer(NAMES).doprint(se.oo)


def test_a_subclass_overrides_only_what_differs() -> None:
    class CLike(Printer):
        functions: ClassVar[Mapping[str, str]] = {**Printer.functions, "pow": "pow"}
        power_operator = None

        def rational(self, p: int, q: int) -> tuple[str, int]:
            return f"{p}.0/{q}.0", 40

        def _print_Pi(self, expr: se.Basic) -> tuple[str, int]:
            return "M_PI", ATOM

    printer = CLike(NAMES)
    x, y = SYMBOLS[:2]
    assert sorted(printer.doprint(se.pi * x**3 + se.Rational(1, 3) + se.Abs(y)).split(" + ")) == sorted(["1.0/3.0", printer.doprint(se.pi * x**3), "fabs(y)"])
    assert printer.doprint(x**3) == "pow(x, 3)"
    assert printer.doprint(se.Rational(-1, 3)) == "-1.0/3.0"
    assert printer.doprint(se.pi * x) in {"M_PI*x", "x*M_PI"}
    assert {"pow", "fabs"} <= printer.used


def test_common_subexpressions_once_over_all_and_collision_free() -> None:
    x, y = SYMBOLS[:2]
    c0 = se.Symbol("_c0")  # a symbol that looks like a temporary
    shared = se.sin(x - y) * se.cos(x - y)
    exprs = [shared + c0, shared * x + se.sin(x - y), se.cos(x - y) ** 2]
    temporaries, reduced = common_subexpressions(exprs, "_c", taken={"_c1"})
    names = [name for name, _ in temporaries]
    assert len(names) == len(set(names)) and not {"_c0", "_c1"} & set(names)
    assert sum(str(value) == "x - y" for _, value in temporaries) == 1  # the difference, once for all three
    values = {"x": 0.3, "y": -1.1, "_c0": 2.5}
    env = dict(values)
    printer = PythonPrinter({**NAMES, "_c0": "_c0"})
    for name, value in temporaries:
        printer.names[name] = name
        env[name] = evaluate(printer.doprint(value), env)
    for original, short in zip(exprs, reduced, strict=True):
        assert math.isclose(evaluate(printer.doprint(short), env), reference(original, values).real, rel_tol=1e-12)


def test_block_prints_assignments_and_results() -> None:
    x, y = SYMBOLS[:2]
    printer = PythonPrinter(NAMES)
    lines, results = printer.block([se.sin(x + y) ** 2, se.sin(x + y) * x], "_t")
    env = {"x": 0.7, "y": 0.2}
    for name, code in lines:
        env[name] = evaluate(code, env)
    assert [evaluate(r, env) for r in results] == pytest.approx([math.sin(0.9) ** 2, math.sin(0.9) * 0.7])
    assert all(name.startswith("_t") for name, _ in lines)
