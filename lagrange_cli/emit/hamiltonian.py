"""`derive --form hamilton`: Hamilton's equations (lagrange_cli/hamilton.py) as text, LaTeX and Python
(the code targets c, octave, jax and json have their own `emit_hamilton`).

Text and LaTeX print H(q, p) and q_dot = dH/dp, p_dot = -dH/dq + Q on the symbolic route; on the
numeric route (more than `hamilton.MAX_SYMBOLIC` coordinates with a full mass matrix) they print
p = M q_dot + b, M and b, and p_dot as a function of (q, q_dot) with q_dot = M^-1 (p - b).

The Python module takes the state y = [q..., p_<q>...] (coordinates and momenta, not velocities)
and says so in its docstring. It uses the Python emitter's public pieces (`mangle`, `literal`,
`docstring`, `define`, `PythonPrinter`), so file text stays data exactly as in `--to python`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import sympy as sp
from sympy.printing.str import StrPrinter

from lagrange_cli import __version__
from lagrange_cli._symengine import to_symengine
from lagrange_cli.emit.common import printable, require_defined, written_definitions
from lagrange_cli.errors import fail
from lagrange_cli.hamilton import hamilton
from lagrange_cli.model import Model

TARGETS = ("text", "latex", "python")
"""The targets whose `--form hamilton` this module writes; c, octave, jax and json write it by their
module's `emit_hamilton` (lagrange_cli/emit/<target>.py, the same lagrange_cli.hamilton equations)."""


def refuse(target: str) -> None:
    """Exit 2 for a target that does not write Hamilton's equations (one without `emit_hamilton`)."""
    raise fail(None, f"--form hamilton is not available for --to {target}", "--to text, latex, python, c, octave, jax or json with --form hamilton (or another --form for --to " + target + ")")


# -- text -----------------------------------------------------------------------------------------


def text(model: Model) -> str:
    ham = hamilton(model)
    printer = StrPrinter()
    show = printer.doprint
    lines = [f"state = [{', '.join(map(str, ham.state))}]"]
    if ham.symbolic:
        assert ham.hamiltonian is not None
        lines.append(f"H = {show(ham.hamiltonian)}")
        lines += [f"{qd} = {show(v)}" for qd, v in zip(model.qd, ham.velocities, strict=True)]
    else:
        lines.append(f"H = p . q_dot - L, with q_dot = M^-1 (p - b) solved numerically ({model.n} coordinates: no symbolic inverse)")
        lines.append("momenta: p = mass matrix * velocities + b")
        lines.append("velocities = [" + ", ".join(map(str, model.qd)) + "]")
        lines.append("mass matrix =")
        lines += ["  [" + ", ".join(show(x) for x in ham.mass.row(i)) + "]" for i in range(model.n)]
        lines.append("b =")
        lines += [f"  [{show(b)}]" for b in ham.bias]
    lines += [f"{pd} = {show(r)}" for pd, r in zip(ham.pd, ham.rates, strict=True)]
    return "\n".join(map(printable, lines)) + "\n"


# -- LaTeX ----------------------------------------------------------------------------------------


def latex(model: Model, standalone: bool = False) -> str:
    """An `align*` (or with `standalone` a document) of H and Hamilton's equations, laid out by
    the LaTeX emitter's line breaker (`latex.align`, `layout.pieces`) so that every line fits an
    article, with its symbol namer (momenta `p_{q}`, rates `\\dot{p}_{q}`)."""
    from lagrange_cli.emit import latex as tex
    from lagrange_cli.emit import layout

    ham = hamilton(model)
    doprint = tex.names(model, ham.p).printer().doprint
    momenta = [doprint(p) for p in ham.p]
    rates = ["\\dot{p}" + name[1:] for name in momenta]
    if ham.symbolic:
        assert ham.hamiltonian is not None
        items = [("H", ham.hamiltonian), *((doprint(qd), v) for qd, v in zip(model.qd, ham.velocities, strict=True))]
    else:
        items = [(name, sum((ham.mass[i, j] * model.qd[j] for j in range(model.n)), ham.bias[i])) for i, name in enumerate(momenta)]
    items += list(zip(rates, ham.rates, strict=True))
    space = tex.room([lhs for lhs, _ in items])
    body = tex.align([tex.Row(lhs, layout.pieces(expr, doprint, space)) for lhs, expr in items])
    route = "" if ham.symbolic else "; q_dot = M^-1 (p - b) is solved numerically (no symbolic inverse for this many coordinates)"
    header = tex.comment(f"{model.title}: Hamilton's equations in the state (q, p){route}, from {Path(model.source).name}")
    return tex.document(model.title, header, body) if standalone else header + body


# -- Python ---------------------------------------------------------------------------------------

GENERATED = frozenset({"velocities", "hamiltonian", "momenta", "MOMENTA", "y_dot"})


def python(model: Model, numba: bool = False) -> str:
    """A module with COORDINATES, MOMENTA, PARAMETERS, momenta(q, q_dot), velocities(y),
    hamiltonian(y) and rhs(t, y, p) for y = [q..., p...]; with inputs also INPUTS, and `u=INPUTS`
    after p on every function whose result depends on an input (as the Lagrange module)."""
    from lagrange_cli.emit.python import RESERVED, PythonPrinter, define, docstring, literal, mangle

    if numba:
        raise fail(None, "--numba is not available with --form hamilton", "--python --form hamilton without --numba")
    require_defined(model, "Python code")
    numeric = model.with_definitions()
    ham = hamilton(numeric)
    symbols = [*numeric.q, *numeric.qd, *(p.symbol for p in numeric.parameters), *(i.symbol for i in numeric.inputs), *ham.p]
    signals = frozenset({"u", "INPUTS"}) if numeric.inputs else frozenset()  # only then: a file without inputs keeps its names
    names = mangle([str(s) for s in symbols], RESERVED | GENERATED | signals)
    inputs = {i.name for i in numeric.inputs}
    names[str(numeric.t)] = "t"
    used_math: set[str] = set()
    uses_numpy = False

    def block(exprs: Sequence[sp.Expr], prefix: str, taken: set[str]) -> tuple[list[str], list[str], set[str]]:
        printer = PythonPrinter(names)
        converted = [to_symengine(sp.sympify(e)) for e in exprs]
        temporaries, results = printer.block(converted, prefix, taken)
        used_math.update(printer.imports())
        free = {str(s) for e in converted for s in e.free_symbols}
        return [f"{name} = {code}" for name, code in temporaries], results, free

    def signature(free: set[str], state: str = "y") -> str:
        """`t, <state>, p=PARAMETERS`, then `u=INPUTS` when the function uses an input (as the Lagrange module)."""
        return f"t, {state}, p=PARAMETERS" + (", u=INPUTS" if free & inputs else "")

    def unpack(free: set[str], state: Sequence[sp.Symbol], source: str) -> list[str]:
        lines = [f"{names[p.name]} = p[{literal(p.name)}]" for p in numeric.parameters if p.name in free]
        lines += [f"{names[i.name]} = u[{literal(i.name)}]" for i in numeric.inputs if i.name in free]
        targets = [names[str(s)] if str(s) in free else "_" for s in state]
        if any(t != "_" for t in targets):
            lines.append(f"{', '.join(targets)}{',' * (len(targets) == 1)} = {source}")
        return lines

    y_source = 'y.tolist() if hasattr(y, "tolist") else y'
    n = numeric.n
    functions = []
    # momenta(q, q_dot): p = M q_dot + b, to map a state (q, q_dot) to (q, p)
    momenta_exprs = [sum((ham.mass[i, j] * numeric.qd[j] for j in range(n)), ham.bias[i]) for i in range(n)]
    lines, results, free = block(momenta_exprs, "_c", set())
    body = unpack(free, numeric.q, "q") + unpack(free - {p.name for p in numeric.parameters} - inputs, numeric.qd, "q_dot") + lines + ["return [" + ", ".join(results) + "]"]
    functions.append(define("momenta", signature(free, "q, q_dot"), "The momenta p = dL/dq_dot = M q_dot + b of the state (q, q_dot): the map to this module's state.", body))
    if ham.symbolic:
        assert ham.hamiltonian is not None
        lines, results, free = block(ham.velocities, "_c", set())
        body = unpack(free, ham.state, y_source) + lines + ["return [" + ", ".join(results) + "]"]
        functions.append(define("velocities", signature(free), "q_dot = dH/dp at y = [q..., p...].", body))
        lines, results, free = block([ham.hamiltonian], "_c", set())
        body = unpack(free, ham.state, y_source) + lines + [f"return {results[0]}"]
        functions.append(define("hamiltonian", signature(free), "H(q, p) at y = [q..., p...].", body))
        lines, results, free = block([*ham.velocities, *ham.rates], "_c", set())
        body = unpack(free, ham.state, y_source) + lines + ["return [" + ", ".join(results) + "]"]
        rhs_free = free
    else:
        uses_numpy = True
        matrix = [ham.mass[i, j] for i in range(n) for j in range(n)]
        shifted = [ham.p[i] - ham.bias[i] for i in range(n)]
        lines, results, free = block([*matrix, *shifted], "_c", set())
        taken = {line.split(" = ")[0] for line in lines}
        h_lines, h_results, h_free = block([sum((ham.p[i] * numeric.qd[i] for i in range(n)), -numeric.lagrangian)], "_h", taken)
        r_lines, r_results, r_free = block(list(ham.rates), "_d", taken)
        velocity_names = {str(v) for v in numeric.qd}
        everything = (free | h_free | r_free | {str(s) for s in ham.p}) - velocity_names
        rows = "[" + ", ".join("[" + ", ".join(results[i * n : (i + 1) * n]) + "]" for i in range(n)) + "]"
        vector = "[" + ", ".join(results[n * n :]) + "]"
        solve = f"_v = numpy.linalg.solve(numpy.array({rows}, dtype=float), numpy.array({vector}, dtype=float)).tolist()"
        bind = f"{', '.join(names[str(v)] for v in numeric.qd)}{',' * (n == 1)} = _v"
        head = unpack(everything, ham.state, y_source) + lines + [solve]
        functions.append(define("velocities", signature(everything), "q_dot = M^-1 (p - b), solved numerically, at y = [q..., p...].", [*head, "return _v"]))
        body = [*head, bind, *h_lines, f"return {h_results[0]}"]
        functions.append(define("hamiltonian", signature(everything), "H = p . q_dot - L at y = [q..., p...], q_dot solved numerically.", body))
        body = [*head, bind, *r_lines, "return [*_v, " + ", ".join(r_results) + "]"]
        rhs_free = everything
    functions.append(define("rhs", signature(rhs_free), f"dy/dt = [dH/dp, -dH/dq + Q] for y = [{', '.join(map(str, ham.state))}] (for scipy.integrate.solve_ivp).", body))
    parameters = ", ".join(f"{literal(p.name)}: {float(p.value)!r}" for p in model.parameters if p.value is not None)
    header = [
        f"{model.title}: Hamilton's equations generated by lagrange {__version__} from {Path(model.source).name}.",
        "",
        f"The state is y = [{', '.join(map(str, ham.state))}]: the coordinates and their momenta p = dL/dq_dot (not the velocities).",
        "rhs(t, y, p) gives dy/dt = [dH/dp, -dH/dq + Q]; momenta(t, q, q_dot) maps a state (q, q_dot) to its momenta.",
    ]
    if not ham.symbolic:
        header.append("q_dot = M^-1 (p - b) is solved numerically at each call (no symbolic inverse for this many coordinates).")
    if model.definitions:
        header.append(written_definitions(model.definitions))
    missing = [p.name for p in model.parameters if p.value is None]
    if missing:
        header.append(f"Parameters without a default, to be given in p: {', '.join(missing)}.")
    if model.inputs:
        header.append(f"Inputs u = [{', '.join(i.name for i in model.inputs)}] are given values at time t (Hamilton's equations treat them as given functions of time):")
        header.append("every function whose result depends on one takes u=INPUTS (a dict by name, the defaults in INPUTS) after p.")
    imports = []
    math_names = sorted(used_math)
    if math_names:
        imports.append(f"from math import {', '.join(math_names)}")
    if uses_numpy:
        imports.append("import numpy")
    parts = [docstring("\n".join([*header, ""]))] + (["\n".join(imports)] if imports else [])
    coordinates = ", ".join(literal(c) for c in model.coordinates)
    momenta_names = ", ".join(literal(str(p)) for p in ham.p)
    parts.append(f"COORDINATES = ({coordinates}{',' * (n == 1)})\nMOMENTA = ({momenta_names}{',' * (n == 1)})\nPARAMETERS = {{{parameters}}}")
    if model.inputs:
        parts[-1] += "\nINPUTS = {" + ", ".join(f"{literal(i.name)}: {float(i.value)!r}" for i in model.inputs) + "}"
    return "\n\n".join(parts) + "\n\n\n" + "\n\n\n".join(functions) + "\n"
