"""The peer: the same chains done the way sympy.physics.mechanics users do it today.

Derivation: ReferenceFrame / Point / Particle with dynamicsymbols, `Lagrangian`, then
`LagrangesMethod(L, q).form_lagranges_equations()` and `.mass_matrix`, `.forcing`.
Numerics: `sympy.lambdify(..., modules="numpy", cse=True)` of M and F (one function, so
the two share their common subexpressions) and `numpy.linalg.solve` in the rhs.

As a whole process ("file to Python module", what run.py times against
`lagrange derive FILE --python -o OUT`):

    python benchmarks/peer.py KIND N OUT.py      # KIND: general or equal

imports sympy, derives, lambdifies, and writes the lambdified source as a module OUT.py
with `mass_matrix(q, p)`, `forcing(q, q_dot, p)` and `rhs(t, y, p)`; its last line on
stdout is `RESULT {json}` with the seconds of each phase.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pendulum

MODULE_HEAD = '''"""{title}: M and F by sympy.physics.mechanics (LagrangesMethod) and sympy.lambdify(modules="numpy", cse=True)."""

import numpy
from numpy import *  # noqa: F403 (the namespace lambdify(modules="numpy") evaluates in)

N = {n}
PARAMETERS = {parameters!r}
NAMES = {names!r}

'''

MODULE_TAIL = """

_evaluate = {function}
_solve, _concatenate = numpy.linalg.solve, numpy.concatenate


def mass_matrix(q, p=PARAMETERS):
    return _evaluate(q, [0.0] * N, [p[k] for k in NAMES])[0]


def forcing(q, q_dot, p=PARAMETERS):
    return _evaluate(q, q_dot, [p[k] for k in NAMES])[1][:, 0]


def rhs(t, y, p=PARAMETERS):
    m, f = _evaluate(y[:N], y[N:], [p[k] for k in NAMES])
    return _concatenate((y[N:], _solve(m, f[:, 0])))
"""


def derive_chain(chain: pendulum.Chain) -> tuple[Any, Any, list[Any], list[Any]]:
    """M and F of M q_ddot = F (in dynamicsymbols), the coordinates q1(t)..qn(t), and the
    parameter symbols in the order of `chain.parameters()`."""
    import sympy as sp
    from sympy.physics.mechanics import LagrangesMethod, Lagrangian, Particle, Point, ReferenceFrame, dynamicsymbols

    symbols = {name: sp.Symbol(name, positive=True) for name in chain.parameters()}
    g = symbols["g"]
    q = dynamicsymbols(f"q1:{chain.n + 1}")
    frame = ReferenceFrame("N")
    origin = Point("O")
    origin.set_vel(frame, 0)
    previous, particles = origin, []
    for i, (mass, length) in enumerate(zip(chain.mass_names(), chain.length_names(), strict=True)):
        m, ln = symbols[mass], symbols[length]
        point = previous.locatenew(f"P{i + 1}", ln * sp.sin(q[i]) * frame.x - ln * sp.cos(q[i]) * frame.y)
        point.set_vel(frame, point.pos_from(origin).dt(frame))
        particle = Particle(f"pa{i + 1}", point, m)
        particle.potential_energy = m * g * point.pos_from(origin).dot(frame.y)
        particles.append(particle)
        previous = point
    method = LagrangesMethod(Lagrangian(frame, *particles), q)
    method.form_lagranges_equations()
    return method.mass_matrix, method.forcing, q, list(symbols.values())


def plain(mass: Any, forcing: Any, q: list[Any]) -> tuple[Any, Any, list[Any], list[Any]]:
    """Replace q_i(t) and q_i'(t) by plain symbols (derivatives first: xreplace works top-down)."""
    import sympy as sp
    from sympy.physics.mechanics import dynamicsymbols

    t = dynamicsymbols._t
    qs = list(sp.symbols(f"q1:{len(q) + 1}"))
    us = list(sp.symbols(f"u1:{len(q) + 1}"))
    mapping = {**{qi.diff(t): ui for qi, ui in zip(q, us, strict=True)}, **dict(zip(q, qs, strict=True))}
    return mass.xreplace(mapping), forcing.xreplace(mapping), qs, us


def module_source(chain: pendulum.Chain) -> tuple[str, dict[str, float]]:
    """The whole workflow: derive, lambdify(cse=True), and the module's text; phase seconds."""
    import inspect

    import sympy as sp

    phases: dict[str, float] = {}
    start = time.perf_counter()
    mass, forcing, q, parameters = derive_chain(chain)
    phases["derive"] = time.perf_counter() - start
    start = time.perf_counter()
    mass, forcing, qs, us = plain(mass, forcing, q)
    function = sp.lambdify([qs, us, parameters], (mass, forcing), modules="numpy", cse=True)
    source = inspect.getsource(function)
    phases["lambdify"] = time.perf_counter() - start
    names = [str(s) for s in parameters]
    title = f"Planar {chain.n}-link {chain.kind} chain"
    text = MODULE_HEAD.format(title=title, n=chain.n, parameters=chain.parameters(), names=names) + source + MODULE_TAIL.format(function=function.__name__)
    return text, phases


def main(argv: list[str]) -> None:
    start = time.perf_counter()
    kind, n, out = argv
    import sympy  # the import is timed as its own phase
    import sympy.physics.mechanics  # noqa: F401

    phases = {"import": time.perf_counter() - start}
    text, more = module_source(pendulum.Chain(kind, int(n)))
    phases.update(more)
    start = time.perf_counter()
    Path(out).write_text(text)
    phases["write"] = time.perf_counter() - start
    print("RESULT " + json.dumps({"phases": phases, "lines": text.count("\n")}), flush=True)


# -- in-process use by simulate_bench.py (the equal chain, parameters m, l, g) ----------------


def derive(n: int) -> tuple[Any, Any, list[Any]]:
    mass, forcing, q, _ = derive_chain(pendulum.Chain("equal", n))
    return mass, forcing, q


def make_rhs(mass: Any, forcing: Any, qs: list[Any], us: list[Any]) -> Callable[..., Any]:
    """rhs(t, y, p) from lambdified M and F (numpy module, cse=True) and numpy.linalg.solve."""
    import numpy
    import sympy as sp

    n = len(qs)
    symbols = [sp.Symbol(name, positive=True) for name in pendulum.PARAMETERS]
    evaluate = sp.lambdify([qs, us, *symbols], (mass, forcing), modules="numpy", cse=True)
    solve, concatenate = numpy.linalg.solve, numpy.concatenate

    def rhs(t: float, y: Any, p: dict[str, float] = pendulum.PARAMETERS) -> Any:
        m, f = evaluate(y[:n], y[n:], p["m"], p["l"], p["g"])
        return concatenate((y[n:], solve(m, f[:, 0])))

    return rhs


if __name__ == "__main__":
    main(sys.argv[1:])
