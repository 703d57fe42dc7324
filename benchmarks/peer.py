"""The peer: the same N-link pendulum done the way sympy.physics.mechanics users do it today.

Derivation: ReferenceFrame / Point / Particle with dynamicsymbols, `Lagrangian`, then
`LagrangesMethod(L, q).form_lagranges_equations()` and `.mass_matrix`, `.forcing`.
Numerics: `sympy.lambdify(..., modules="numpy", cse=True)` of M and F (one function, so
the two share their common subexpressions) and `numpy.linalg.solve` in the rhs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import sympy as sp
from pendulum import PARAMETERS
from sympy.physics.mechanics import LagrangesMethod, Lagrangian, Particle, Point, ReferenceFrame, dynamicsymbols

SYMBOLS = sp.symbols("m l g", positive=True)


def derive(n: int) -> tuple[sp.Matrix, sp.Matrix, list[Any]]:
    """M and F of M q_ddot = F (in dynamicsymbols) and the coordinates q1(t)..qn(t)."""
    m, length, g = SYMBOLS
    q = dynamicsymbols(f"q1:{n + 1}")
    frame = ReferenceFrame("N")
    origin = Point("O")
    origin.set_vel(frame, 0)
    previous, particles = origin, []
    for i in range(n):
        point = previous.locatenew(f"P{i + 1}", length * sp.sin(q[i]) * frame.x - length * sp.cos(q[i]) * frame.y)
        point.set_vel(frame, point.pos_from(origin).dt(frame))
        particle = Particle(f"pa{i + 1}", point, m)
        particle.potential_energy = m * g * point.pos_from(origin).dot(frame.y)
        particles.append(particle)
        previous = point
    method = LagrangesMethod(Lagrangian(frame, *particles), q)
    method.form_lagranges_equations()
    return method.mass_matrix, method.forcing, q


def plain(mass: sp.Matrix, forcing: sp.Matrix, q: list[Any]) -> tuple[sp.Matrix, sp.Matrix, list[sp.Symbol], list[sp.Symbol]]:
    """Replace q_i(t) and q_i'(t) by plain symbols (derivatives first: xreplace works top-down)."""
    t = dynamicsymbols._t
    qs = list(sp.symbols(f"q1:{len(q) + 1}"))
    us = list(sp.symbols(f"u1:{len(q) + 1}"))
    mapping = {**{qi.diff(t): ui for qi, ui in zip(q, us, strict=True)}, **dict(zip(q, qs, strict=True))}
    return mass.xreplace(mapping), forcing.xreplace(mapping), qs, us


def make_rhs(mass: sp.Matrix, forcing: sp.Matrix, qs: list[sp.Symbol], us: list[sp.Symbol]) -> Callable[..., Any]:
    """rhs(t, y, p) from lambdified M and F (numpy module, cse=True) and numpy.linalg.solve."""
    import numpy

    n = len(qs)
    evaluate = sp.lambdify([qs, us, *SYMBOLS], (mass, forcing), modules="numpy", cse=True)
    solve, concatenate = numpy.linalg.solve, numpy.concatenate

    def rhs(t: float, y: Any, p: dict[str, float] = PARAMETERS) -> Any:
        m, f = evaluate(y[:n], y[n:], p["m"], p["l"], p["g"])
        return concatenate((y[n:], solve(m, f[:, 0])))

    return rhs


def numeric(mass: sp.Matrix, forcing: sp.Matrix, qs: list[sp.Symbol], us: list[sp.Symbol], y: list[float]) -> tuple[list[list[float]], list[float]]:
    """M and F evaluated at state y (with the default parameters), for the agreement check."""
    n = len(qs)
    f = sp.lambdify([qs, us, *SYMBOLS], (mass.tolist(), list(forcing)), modules="math", cse=True)
    m, F = f(y[:n], y[n:], *(PARAMETERS[str(s)] for s in SYMBOLS))
    return [[float(x) for x in row] for row in m], [float(x) for x in F]
