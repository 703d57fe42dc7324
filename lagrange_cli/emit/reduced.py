"""`derive --form reduced`: Maggi's equations (lagrange_cli/reduced.py) as text, LaTeX and Python.

Text and LaTeX state which velocities are independent (and where they were chosen), the dependent
velocities q_dot_D = ... as functions of (q, u), and the k reduced equations
(C^T M C u_dot - C^T (F - M e))_i = 0 without multipliers.

The Python module takes the reduced state y = [q..., u...] (all coordinates, then the independent
velocities) and says so in its docstring; `velocities(t, y, p)` gives every q_dot, `reduce(q_dot)`
picks u from a full velocity vector. It uses the Python emitter's public pieces (`mangle`,
`literal`, `docstring`, `define`, `PythonPrinter`), so file text stays data as in `--to python`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import sympy as sp
from sympy.printing.str import StrPrinter

from lagrange_cli import __version__
from lagrange_cli._symengine import to_symengine
from lagrange_cli.emit.common import printable, require_defined
from lagrange_cli.errors import fail
from lagrange_cli.model import Model
from lagrange_cli.reduced import reduced, refuse_target

TARGETS = ("text", "latex", "python", "c")
"""The targets that write `--form reduced`; the others refuse it (exit 2)."""

refuse = refuse_target


# -- text -----------------------------------------------------------------------------------------


def text(model: Model) -> str:
    red = reduced(model)
    show = StrPrinter().doprint
    lines = [
        "Maggi's equations (multipliers eliminated): C^T (M q_ddot - F) = 0 with q_dot = C u + d",
        red.summary(),
        f"state = [{', '.join(map(str, red.state))}]",
    ]
    lines += [f"{model.qd[i]} = {show(red.velocities[i])}" for i in red.dependent]
    lines += [f"{show(eq)} = 0" for eq in red.equations()]
    return "\n".join(map(printable, lines)) + "\n"


# -- LaTeX ----------------------------------------------------------------------------------------


def latex(model: Model, standalone: bool = False) -> str:
    """An `align*` (or with `standalone` a document) of the dependent velocities and the reduced
    equations, laid out by the LaTeX emitter's line breaker."""
    from lagrange_cli.emit import latex as tex
    from lagrange_cli.emit import layout

    red = reduced(model)
    doprint = tex.names(model).printer().doprint
    items = [(doprint(model.qd[i]), red.velocities[i]) for i in red.dependent]
    space = tex.room([lhs for lhs, _ in items])
    rows = [tex.Row(lhs, layout.pieces(expr, doprint, space)) for lhs, expr in items]
    rows += [tex.Row("", layout.pieces(eq, doprint, tex.room()), zero=True) for eq in red.equations()]
    body = tex.align(rows)
    header = tex.comment(f"{model.title}: reduced (Maggi) form, multipliers eliminated, from {Path(model.source).name}; {red.summary()}")
    return tex.document(model.title, header, body) if standalone else header + body


# -- Python ---------------------------------------------------------------------------------------

Y_SOURCE = 'y.tolist() if hasattr(y, "tolist") else y'
GENERATED = frozenset({"velocities", "reduce", "INDEPENDENT", "DEPENDENT", "y_dot"})
SIGNALS = frozenset({"u", "INPUTS"})
"""Reserved only in the module of a file with inputs (the others keep their names)."""


def python(model: Model, numba: bool = False) -> str:
    """A module with COORDINATES, INDEPENDENT, DEPENDENT, PARAMETERS, velocities(t, y, p),
    reduce(q_dot) and rhs(t, y, p) for y = [q..., u...]."""
    from lagrange_cli.emit.python import RESERVED, PythonPrinter, define, docstring, literal, mangle

    if numba:
        raise fail(None, "--numba is not available with --form reduced", "--python --form reduced without --numba")
    require_defined(model, "Python code")
    numeric = model.with_definitions()
    red = reduced(numeric)
    symbols = [*numeric.q, *numeric.qd, *numeric.qdd, *(p.symbol for p in numeric.parameters), *(i.symbol for i in numeric.inputs)]
    names = mangle([str(s) for s in symbols], RESERVED | GENERATED | (SIGNALS if numeric.inputs else frozenset()))
    names[str(numeric.t)] = "t"
    used_math: set[str] = set()

    def block(exprs: Sequence[sp.Expr], prefix: str, taken: set[str]) -> tuple[list[str], list[str], set[str]]:
        printer = PythonPrinter(names)
        converted = [to_symengine(sp.sympify(e)) for e in exprs]
        temporaries, results = printer.block(converted, prefix, taken)
        used_math.update(printer.imports())
        free = {str(s) for e in converted for s in e.free_symbols}
        return [f"{name} = {code}" for name, code in temporaries], results, free

    def unpack(free: set[str]) -> list[str]:
        lines = [f"{names[p.name]} = p[{literal(p.name)}]" for p in numeric.parameters if p.name in free]
        lines += [f"{names[i.name]} = u[{literal(i.name)}]" for i in numeric.inputs if i.name in free]
        targets = [names[str(s)] if str(s) in free else "_" for s in red.state]
        if any(t != "_" for t in targets):
            lines.append(f"{', '.join(targets)}{',' * (len(targets) == 1)} = {Y_SOURCE}")
        return lines

    n, k = numeric.n, len(red.independent)
    signature = "t, y, p=PARAMETERS" + (", u=INPUTS" if numeric.inputs else "")
    functions = []
    lines, results, free = block(red.velocities, "_c", set())
    body = [*unpack(free), *lines, "return [" + ", ".join(results) + "]"]
    functions.append(define("velocities", signature, "Every q_dot = C u + d at the reduced state y = [q..., u...].", body))
    picks = ", ".join(f"q_dot[{i}]" for i in red.independent)
    functions.append(define("reduce", "q_dot", "The independent velocities u of a full velocity vector q_dot (which must satisfy the constraints).", [f"return [{picks}]"]))
    matrix = [red.mass[i, j] for i in range(k) for j in range(k)]
    lines, results, free = block([*red.velocities, *matrix, *red.rhs], "_c", set())
    body = [*unpack(free), *lines]
    velocities = results[:n]
    entries = results[n : n + k * k]
    forcing = results[n + k * k :]
    uses_numpy = k > 1
    if k == 1:
        body.append(f"return [{', '.join(velocities)}, ({forcing[0]}) / ({entries[0]})]")
    else:
        rows = "[" + ", ".join("[" + ", ".join(entries[i * k : (i + 1) * k]) + "]" for i in range(k)) + "]"
        body.append(f"_u_dot = numpy.linalg.solve(numpy.array({rows}, dtype=float), numpy.array([{', '.join(forcing)}], dtype=float)).tolist()")
        body.append(f"return [{', '.join(velocities)}, *_u_dot]")
    functions.append(define("rhs", signature, f"dy/dt = [q_dot..., u_dot...] for y = [{', '.join(map(str, red.state))}] (for scipy.integrate.solve_ivp).", body))
    parameters = ", ".join(f"{literal(p.name)}: {float(p.value)!r}" for p in model.parameters if p.value is not None)
    header = [
        f"{model.title}: reduced (Maggi) equations generated by lagrange {__version__} from {Path(model.source).name}.",
        "",
        f"The state is y = [{', '.join(map(str, red.state))}]: the coordinates and the independent velocities u (the multipliers are eliminated).",
        red.summary() + ".",
        "rhs(t, y, p) gives dy/dt = [q_dot..., u_dot...]; velocities(t, y, p) gives every q_dot; reduce(q_dot) picks u.",
    ]
    if model.inputs:
        header.append(f"Inputs [{', '.join(i.name for i in model.inputs)}] are given values at time t: rhs and velocities take them as a dict by name, u=INPUTS (the defaults), after p.")
    if model.definitions:
        written = "; ".join(f"{name}({', '.join(map(str, f.variables))}) = {sp.sstr(f.expr)}" for name, f in sorted(model.definitions.items()))
        header.append(f"Functions written out from their definitions in the file: {written}.")
    imports = []
    if used_math:
        imports.append(f"from math import {', '.join(sorted(used_math))}")
    if uses_numpy:
        imports.append("import numpy")
    parts = [docstring("\n".join([*header, ""]))] + (["\n".join(imports)] if imports else [])
    coordinates = ", ".join(literal(c) for c in model.coordinates)
    independent = ", ".join(literal(model.coordinates[i]) for i in red.independent)
    dependent = ", ".join(literal(model.coordinates[i]) for i in red.dependent)
    parts.append(
        f"COORDINATES = ({coordinates}{',' * (n == 1)})\nINDEPENDENT = ({independent}{',' * (k == 1)})\nDEPENDENT = ({dependent}{',' * (len(red.dependent) == 1)})\nPARAMETERS = {{{parameters}}}"
        + ("\nINPUTS = {" + ", ".join(f"{literal(i.name)}: {float(i.value)!r}" for i in model.inputs) + "}" if model.inputs else "")
    )
    return "\n\n".join(parts) + "\n\n\n" + "\n\n\n".join(functions) + "\n"
