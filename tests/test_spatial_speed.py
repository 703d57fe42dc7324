"""Issue 13's generated-code evaluation of the spatial chain, by counting operations (never by timing):
the time derivative of the nested body velocities (`kinematics.Rate`) is the chain rule exactly, and
visits each shared part once, so the generated rhs of the spatial chain stays near the planar chain's."""

from __future__ import annotations

import ast
import importlib.util
import random
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "benchmarks"


def _load(name: str) -> Any:
    if str(BENCH) not in sys.path:
        sys.path.insert(0, str(BENCH))
    return importlib.import_module(name)


def rhs_operations(source: str) -> int:
    """Arithmetic operations and calls in the generated module's `rhs` (its solve helper not counted)."""
    tree = ast.parse(source)
    function = next(node for node in tree.body if isinstance(node, ast.FunctionDef) and node.name == "rhs")
    return sum(isinstance(node, ast.BinOp | ast.UnaryOp | ast.Call) for node in ast.walk(function))


def _distinct(exprs: list[Any]) -> int:
    seen: set[Any] = set()
    stack = list(exprs)
    while stack:
        e = stack.pop()
        if e not in seen:
            seen.add(e)
            stack.extend(e.args)
    return len(seen)


def test_rate_is_the_chain_rule_without_accelerations() -> None:
    from lagrange_cli._symengine import se
    from lagrange_cli.kinematics import Rate

    q = se.symbols("x y z")
    qd = se.symbols("x_dot y_dot z_dot")
    t, a, f = se.Symbol("t"), se.Symbol("a"), se.Function("f")
    x, y, z = q
    exprs = [
        a * se.sin(x) * se.cos(y) ** 2 + t * z,
        (x * qd[1] + se.exp(y * t)) / (1 + z**2),
        se.sqrt(x**2 + a) * se.cos(se.sin(y) - z) * qd[0] ** 2,
        se.atan2(y, x) + f(t) + se.Integer(3),
        se.Integer(7),
    ]
    rate = Rate(q, qd, t)
    rng = random.Random(13)
    for e in exprs:
        expected = se.Add(*(se.diff(e, qk) * v for qk, v in zip(q, qd, strict=True)), se.diff(e, t))
        found = rate(e)
        for _ in range(3):
            point = {s: rng.uniform(0.2, 1.2) for s in (*q, *qd, t, a)}
            difference = (found - expected).subs({se.Derivative(f(t), t): se.Symbol("f_dot"), f(t): se.Symbol("f_t")}).subs({**point, se.Symbol("f_dot"): 0.3, se.Symbol("f_t"): 0.7})
            assert abs(complex(difference.n())) < 1e-12, (e, found, expected)


def test_rate_differentiates_a_shared_nested_chain_once() -> None:
    """A nested chain x_k = cos(q_k) x_{k-1} + sin(q_k) y_{k-1} (as a body's velocity down `relative_to`): the
    derivative has O(N) distinct parts, where differentiating by each coordinate in turn writes out O(N^2)."""
    from lagrange_cli._symengine import se
    from lagrange_cli.kinematics import Rate

    n = 24
    q, qd = se.symbols(" ".join(f"q{k}" for k in range(n))), se.symbols(" ".join(f"q{k}_dot" for k in range(n)))
    x, y = se.Symbol("l"), se.Integer(0)
    for k in range(n):
        x, y = se.cos(q[k]) * x + se.sin(q[k]) * y, se.cos(q[k]) * y - se.sin(q[k]) * x
    found = Rate(q, qd, se.Symbol("t"))(x)
    by_coordinate = se.Add(*(se.diff(x, qk) * v for qk, v in zip(q, qd, strict=True)))
    assert _distinct([found]) < 30 * n < _distinct([by_coordinate])


def test_spatial_chain_rhs_operations_near_the_planar_chain() -> None:
    """The 4-link spatial chain (12 coordinates) against the planar general chain of 12 links: the generated rhs's
    operations (4386 against 974 before `Rate`: 4.5 times)."""
    from lagrange_cli import api

    spatial = _load("spatial_bench")
    pendulum = _load("pendulum")
    ours = rhs_operations(api.from_text(spatial.chain_yaml(4)).to("python"))
    planar = rhs_operations(api.from_text(pendulum.Chain("general", 12).yaml()).to("python"))
    assert ours <= 4.0 * planar, (ours, planar)
