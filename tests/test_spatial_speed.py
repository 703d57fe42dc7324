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

import pytest

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


TREE = """
title: A floating base with two hinged arms, one with a forearm, a tag turned by a base angle and a spinner driven in time
coordinates: [x, y, a, b, p1, p2, r1, r2, s1]
parameters: {g: 9.81, M: 3.0, m1: 1.2, m2: 0.8, m3: 0.5, L: 0.7}
gravity: [0, -g, -g/2]
bodies:
  base:
    mass: M
    orientation: {sequence: ZYX, angles: [a, b, 0.3]}
    position: [x, y, 0.2*x]
    inertia: [[0.3, 0.01, 0.02], [0.01, 0.4, 0.03], [0.02, 0.03, 0.5]]
    points: {left: [0.2, 0.1, -0.3], right: [-0.25, 0.05, 0.1]}
  arm1:
    mass: m1
    orientation: {sequence: XYZ, angles: [p1, p2, 0], relative_to: base}
    pivot: base.left
    center: [0.1, -0.2, L/2]
    points: {tip: [0.05, 0, L]}
    inertia: [[0.05, 0.001, 0], [0.001, 0.06, 0.002], [0, 0.002, 0.02]]
  arm2:
    mass: m2
    orientation: {axis: [0.6, 0, 0.8], angle: r1, relative_to: base}
    pivot: base.right
    center: [0, 0.3, 0]
    inertia: [[0.04, 0, 0], [0, 0.03, 0], [0, 0, 0.02]]
  forearm:
    mass: m3
    orientation: {sequence: ZXZ, angles: [r2, s1, 0.2], relative_to: arm1}
    pivot: arm1.tip
    center: [0.1, 0.1, 0.2]
    inertia: [[0.01, 0.002, 0.001], [0.002, 0.02, 0], [0.001, 0, 0.015]]
  tag:
    mass: 0.1
    orientation: {axis: [0, 0, 1], angle: a + r2, relative_to: forearm}
    pivot: forearm
    center: [0.05, 0, 0]
    inertia: [[0.001, 0, 0], [0, 0.001, 0], [0, 0, 0.001]]
  spinner:
    mass: 0.2
    orientation: {axis: [0, 1, 0], angle: 3*t + s1, relative_to: arm2}
    pivot: arm2
    center: [0, 0, 0.1]
    inertia: [[0.002, 0, 0], [0, 0.003, 0], [0, 0, 0.001]]
"""


@pytest.mark.parametrize("case", ["tree", "chain"])
def test_composite_bodies_give_the_body_by_body_equations(case: str) -> None:
    """A tree (a floating base, two arms hinged at its points, a forearm at an arm's tip; sequences and an axis and
    angle; full tensors, offset centres, gravity): M, F, the momenta and the energy summed by composite bodies agree
    with body by body at random states. The tag turns by a base angle, so it is not hinged (it stays body by body)."""
    import random

    import sympy as sp

    from lagrange_cli import derive, spec
    from lagrange_cli._symengine import se

    text = TREE if case == "tree" else _load("spatial_bench").chain_yaml(3)  # the chain: its first link turns about a fixed pivot
    system = derive.eliminate(spec.parse(text, f"{case}.yaml"))
    ours, _ = derive._derive(system, True, composite=True)
    plain, _ = derive._derive(system, True, composite=False)
    a, b = ours.symengine, plain.symengine
    assert a.mass != b.mass and a.forcing != b.forcing  # the composite sums are in use
    by_name = {body.name: body for body in system.bodies}
    hinged = ("arm1", "arm2", "forearm", "tag", "spinner") if case == "tree" else ("link1", "link2", "link3")
    assert all(by_name[name].anchor is not None for name in hinged)
    assert (by_name["base"] if case == "tree" else by_name["link1"]).anchor == (None if case == "tree" else (None, (0, 0, 0), (0, 0, -sp.Symbol("l1") / 2)))
    pairs = [
        *zip([e for row in a.mass for e in row], [e for row in b.mass for e in row], strict=True),
        *zip(a.forcing, b.forcing, strict=True),
        *zip(a.momenta, b.momenta, strict=True),
        (a.energy, b.energy),
    ]
    rng = random.Random(13)
    for _ in range(3):
        point = {v: rng.uniform(-1.0, 1.0) for v in (*a.q, *a.qd, a.t)}
        point.update({se.Symbol(p.name): p.value * rng.uniform(0.8, 1.2) for p in ours.parameters})
        for x, y in pairs:
            assert abs(float(x.subs(point)) - float(y.subs(point))) < 1e-11 * max(1.0, abs(float(y.subs(point))))


def _module(text: str, name: str) -> str:
    """`lagrange derive FILE --to python`: derived with the equations shared."""
    from lagrange_cli import derive, spec
    from lagrange_cli.emit import python

    return python.emit(derive.derive(spec.parse(text, name), shared=True))


def test_spatial_chain_rhs_operations_near_the_planar_chain() -> None:
    """The 4-link and 6-link spatial chains (12 and 18 coordinates) against the planar general chain of 12 and 18
    links: the generated rhs's operations (4386 against 974 and 11177 against 2159 body by body: 4.5 and 5.2 times)."""
    spatial = _load("spatial_bench")
    pendulum = _load("pendulum")
    for links in (4, 6):
        ours = rhs_operations(_module(spatial.chain_yaml(links), "spatial.yaml"))
        planar = rhs_operations(_module(pendulum.Chain("general", 3 * links).yaml(), "planar.yaml"))
        assert ours <= 2.2 * planar, (links, ours, planar)


def test_spatial_chain_written_out_in_full_falls_back_to_body_by_body() -> None:
    """Composite sums are long written out in full: where that is refused (the 4-link chain outside `derive --to
    python`), the equations are derived body by body, as before, with the same accelerations."""
    import random

    from lagrange_cli import derive, spec
    from lagrange_cli._symengine import se

    text = _load("spatial_bench").chain_yaml(4)
    plain = derive.derive(spec.parse(text, "chain.yaml"))  # not refused
    shared = derive.derive(spec.parse(text, "chain.yaml"), shared=True)
    a, b = shared.symengine, plain.symengine
    assert a.forcing != b.forcing
    rng = random.Random(4)
    point = {v: rng.uniform(-1.0, 1.0) for v in (*a.q, *a.qd)}
    point.update({se.Symbol(p.name): p.value for p in plain.parameters})
    for x, y in zip(a.forcing, b.forcing, strict=True):
        assert abs(float(x.subs(point)) - float(y.subs(point))) < 1e-9 * max(1.0, abs(float(y.subs(point))))
