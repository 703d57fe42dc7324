"""Generated code evaluates a spring's offset without cancelling: k*(l - r), not k*l - k*r (printer.restructure).

Collected by varying part, a stiff spring's force k*l - k*r is two terms of size k whose difference near r = l is the
force, so with k = 1e10 it carries round-off of a spacing of 1e10 (about 2e-6); factored, it is exact to a few ulps of
itself. The rewrite is checked on its own (the same real function, the factor there) and through the generated code
of every target that restructures, against exact rational arithmetic at the equilibrium."""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import pytest

from lagrange_cli._symengine import se
from lagrange_cli.emit import python as emit_python
from lagrange_cli.emit.printer import restructure

from .conftest import ROOT
from .helpers import model_from

k, l, r, m, g, th, x1, x2, k1, k2, l1, l2, c = (se.Symbol(n) for n in ("k", "l", "r", "m", "g", "th", "x1", "x2", "k1", "k2", "l1", "l2", "c"))  # noqa: E741
r_dot = se.Symbol("r_dot")
CONSTANTS = ["k", "l", "m", "g", "k1", "k2", "l1", "l2", "c"]


def rewritten(expr: Any) -> Any:
    """`expr` restructured, its temporaries substituted back (the value the generated code computes, as an expression)."""
    definitions, (result,) = restructure([expr], CONSTANTS, ["r_dot"])
    for name, value in reversed(definitions):
        result = result.xreplace({se.Symbol(name): value})
    assert se.expand(result - expr) == 0, (result, expr)
    return result


def has_factor(expr: Any, factor: Any) -> bool:
    """Whether `factor` or its negative is a sub-expression of `expr` (as a factor, possibly squared)."""
    stack = [expr]
    while stack:
        e = stack.pop()
        if se.expand(e - factor) == 0 or se.expand(e + factor) == 0:
            return True
        stack.extend(e.args)
    return False


@pytest.mark.parametrize(
    ("expr", "factor"),
    [
        (k * l - k * r, r - l),  # the force
        (k * r**2 / 2 - k * l * r + k * l**2 / 2, r - l),  # the energy: k (r - l)^2 / 2
        (k * x1 - k * x2 - k * l, x1 - x2 - l),  # between two coordinates
        (k * r * se.sin(th) - k * l * se.sin(th), r - l),  # under a common varying factor
        (k * l * r**2 - k * l**2 * r, r - l),  # under a common varying monomial
        (k * l - k * r - g * m + m * r * se.cos(th), r - l),  # beside other terms
        (k1 * l1 - k1 * x1 + k2 * x2 - k2 * x1 - k2 * l2 - g * m, x2 - x1 - l2),  # a chain of springs: both springs
        (k1 * l1 - k1 * x1 + k2 * x2 - k2 * x1 - k2 * l2 - g * m, x1 - l1),
        (k * l - k * r - 2 * r_dot * se.sqrt(k * m) + c * r_dot * l - c * r_dot * r, r - l),  # a velocity part alike
    ],
)
def test_an_offset_is_factored(expr: Any, factor: Any) -> None:
    assert has_factor(rewritten(expr), factor)


@pytest.mark.parametrize(
    "expr",
    [
        -k * r - g * m,  # no common factor: nothing to pull out
        k * x1 - k * x2,  # no offset
        g * m * l * se.cos(th) - k * r * se.sin(th),  # no polynomial group with an offset
        1.5 * k * l - 1.5 * k * r,  # a floating-point coefficient: left as it is
    ],
)
def test_without_an_offset_nothing_is_factored(expr: Any) -> None:
    result = rewritten(expr)
    assert not any(a.is_Add for e in (result.args if result.is_Add else (result,)) for a in e.args), result


def force_and_energy(path: str) -> tuple[dict[str, Any], dict[str, float]]:
    namespace: dict[str, Any] = {}
    exec(emit_python.emit(model_from(ROOT / path)), namespace)  # generated code, file text escaped as data
    return namespace, dict(namespace["PARAMETERS"])


@pytest.mark.parametrize("path", ["tests/numeric_audit_pilot/stiff_elastic_pendulum_r.yaml", "tests/numeric_audit2/elastic_pendulum_r_k1e11.yaml"])
def test_the_force_near_equilibrium_is_exact_to_its_own_size(path: str) -> None:
    """F_r and the energy at r = l + s m g / k (stretched by 1, 2 and 1001 times the sag): within 4 ulps of their own size,
    where k*l - k*r was off by up to 4e-6 (k = 1e11) in a force of size 1."""
    module, p = force_and_energy(path)
    for s in (1.0, 2.0, 1001.0):
        r_value = p["l"] + s * p["m"] * p["g"] / p["k"]
        theta, theta_dot = 0.3, 0.7
        R, M, L, G, K, C, W = (Fraction(v) for v in (r_value, p["m"], p["l"], p["g"], p["k"], math.cos(theta), theta_dot))
        force = M * R * W * W + G * M * C + K * (L - R)  # r_dot = 0: no damping
        energy = M * R * R * W * W / 2 + K * (R - L) ** 2 / 2 - M * G * R * C
        f_r = module["forcing"]([r_value, theta], [0.0, theta_dot])[0]
        h = module["energy"]([r_value, theta], [0.0, theta_dot])
        assert abs(Fraction(f_r) - force) <= 4 * math.ulp(float(abs(force)) + float(M * R * W * W + G * M)), (s, f_r, float(force))
        assert abs(Fraction(h) - energy) <= 4 * math.ulp(float(M * R * R * W * W / 2 + M * G * R)), (s, h, float(energy))
