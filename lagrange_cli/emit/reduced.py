"""`derive --form reduced`: Maggi's equations (lagrange_cli/reduced.py) as text, LaTeX, Python and JAX
(C, Octave and JSON: `emit_reduced` in their emitters).

Text and LaTeX state which velocities are independent (and where they were chosen), the dependent
velocities q_dot_D = ... as functions of (q, u), and the k reduced equations
(C^T M C u_dot - C^T (F - M e))_i = 0 without multipliers.

The Python module takes the reduced state y = [q..., u...] (all coordinates, then the independent
velocities) and says so in its docstring; `velocities(t, y, p)` gives every q_dot, `reduce(q_dot)`
picks u from a full velocity vector. It uses the Python emitter's public pieces (`mangle`,
`literal`, `docstring`, `define`, `PythonPrinter`), so file text stays data as in `--to python`.
The JAX module (`jax`) has the same functions on the same state, in pure `jax.numpy` with the JAX
target's conventions and public pieces (`jax_names`, `JaxPrinter`, `unrolled_solve`, `helpers`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import sympy as sp
from sympy.printing.str import StrPrinter

from lagrange_cli import __version__
from lagrange_cli._symengine import to_symengine
from lagrange_cli.emit.common import printable, require_defined, written_definitions
from lagrange_cli.errors import fail
from lagrange_cli.model import Model
from lagrange_cli.reduced import reduced, refuse_target

TARGETS = ("text", "latex", "python", "c", "octave", "jax", "json")
"""The targets that write `--form reduced` (every target; `refuse` is for a target outside this list)."""

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
        header.append(written_definitions(model.definitions))
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


# -- JAX ------------------------------------------------------------------------------------------

JAX_GENERATED = frozenset({"velocities", "reduce", "reduced_mass_matrix", "reduced_forcing", "INDEPENDENT", "DEPENDENT", "NI"})
"""The names a reduced JAX module defines besides those of the JAX target's `GENERATED`."""


def jax(model: Model, *, name: str = "eom") -> str:
    """`derive --to jax --form reduced`: a module of pure `jax.numpy` functions on the reduced state
    y = [q..., u...]: `rhs(t, y, p)`, `velocities(t, y, p)` (every q_dot = C u + d), `reduce(q_dot)`,
    `reduced_mass_matrix` (C^T M C) and `reduced_forcing` (C^T (F - M e)), with the JAX target's
    conventions (lagrange_cli/emit/jax.py): p None, a dict by name or an array in PARAMETER_NAMES
    order; with inputs, every state function takes u=None after p, read as p is. u_dot solves the
    k x k system by the target's unrolled L D L^T (`unrolled_solve`; C^T M C is symmetric positive
    definite) up to `UNROLLED_MAX` independent velocities, `jnp.linalg.solve` above. `name` is not
    used (a module is named by its file)."""
    from lagrange_cli.emit import jax as target
    from lagrange_cli.emit.printer import restructure
    from lagrange_cli.emit.python import define, docstring, literal

    definitions = model.definitions
    require_defined(model, "JAX code")
    numeric = model.with_definitions()
    red = reduced(numeric)
    names = target.jax_names(numeric, reserved=JAX_GENERATED)
    n, k = numeric.n, len(red.independent)
    store = target.Storage(k)
    constants = [p.name for p in numeric.parameters]
    cells = [(i, j) for i in range(k) for j in range(i, k)]
    qdot = [to_symengine(sp.sympify(v)) for v in red.velocities]
    mass = [to_symengine(sp.sympify(red.mass[i, j])) for i, j in cells]
    force = [to_symengine(sp.sympify(f)) for f in red.rhs]

    def block(exprs: Sequence[Any]) -> tuple[list[str], list[str]]:
        printer = target.JaxPrinter(dict(names))
        rewritten_definitions, rewritten = restructure(exprs, constants)
        lines = []
        for lhs, value in rewritten_definitions:
            lines.append(f"{lhs} = {store.kept(store.sincos(printer.doprint(value)))}")
            printer.names[lhs] = lhs
        temporaries, results = printer.block(rewritten, "_c", [*names.values(), *(lhs for lhs, _ in rewritten_definitions)])
        return lines + [f"{lhs} = {store.kept(code)}" for lhs, code in temporaries], results

    def unpack(exprs: Sequence[Any]) -> list[str]:
        free = {str(s) for e in exprs for s in getattr(e, "free_symbols", ())}
        lines = []
        if numeric.parameters:
            targets = [names[p.name] for p in numeric.parameters]
            lines.append(f"{', '.join(targets)}{',' * (len(targets) == 1)} = _parameters(p)")
        if numeric.inputs:
            targets = [names[i.name] for i in numeric.inputs]
            lines.append(f"{', '.join(targets)}{',' * (len(targets) == 1)} = _inputs(u)")
        lines.append("y = jnp.asarray(y)")
        lines += [f"{names[str(s)]} = y[{i}]" for i, s in enumerate(red.state) if str(s) in free]
        return lines

    signature = "t, y, p=None" + (", u=None" if numeric.inputs else "")
    state = ", ".join(map(str, red.state))
    lines, results = block(qdot)
    functions = [define("velocities", signature, f"Every q_dot = C u + d ({n} values) at the reduced state y = [{state}].", [*unpack(qdot), *lines, f"return _array([{', '.join(results)}])"])]
    functions.append(
        define(
            "reduce",
            "q_dot",
            "The independent velocities u of a full velocity vector q_dot (which must satisfy the constraints).",
            ["q_dot = jnp.asarray(q_dot)", f"return _array([{', '.join(f'q_dot[{i}]' for i in red.independent)}])"],
        )
    )
    lines, results = block(mass)
    cell = dict(zip(cells, results, strict=True))
    rows = ", ".join("[" + ", ".join(cell[(min(i, j), max(i, j))] for j in range(k)) + "]" for i in range(k))
    functions.append(define("reduced_mass_matrix", signature, f"C^T M C, an NI x NI array ({k} x {k}, symmetric) at the reduced state.", [*unpack(mass), *lines, f"return _array([{rows}])"]))
    lines, results = block(force)
    functions.append(
        define(
            "reduced_forcing",
            signature,
            "C^T (F - M e), an array of NI values at the reduced state: reduced_mass_matrix(...) u_dot = reduced_forcing(...).",
            [*unpack(force), *lines, f"return _array([{', '.join(results)}])"],
        )
    )
    everything = [*qdot, *mass, *force]
    lines, results = block(everything)
    velocities, entries, forcing = results[:n], dict(zip(cells, results[n : n + len(cells)], strict=True)), results[n + len(cells) :]
    body = [*unpack(everything), *lines]
    zero = {ij for ij, expr in zip(cells, mass, strict=True) if expr == 0}
    if k == 0:
        body.append(f"return _array([{', '.join(velocities)}])")
    elif k <= target.UNROLLED_MAX and not any((i, i) in zero for i in range(k)):
        solved = target.unrolled_solve(
            k,
            {ij: (None if ij in zero else code) for ij, code in entries.items()},
            [None if expr == 0 else code for expr, code in zip(force, forcing, strict=True)],
            [],
            [],
            store.solve_keep(),
        )
        body += [*solved.lines, f"return _array([{', '.join([*velocities, *solved.results])}])"]
    else:
        rows = ", ".join("[" + ", ".join(entries[(min(i, j), max(i, j))] for j in range(k)) + "]" for i in range(k))
        body += [f"_u_dot = jnp.linalg.solve(_array([{rows}]), _array([{', '.join(forcing)}]))", f"return jnp.concatenate([_array([{', '.join(velocities)}]), _u_dot])"]
    functions.append(define("rhs", signature, f"dy/dt = [q_dot..., u_dot...] for y = [{state}]: an array of {n + k} values (jit-, vmap- and grad-compatible).", body))

    missing = [p.name for p in model.parameters if p.value is None]
    header = [
        f"{model.title}: reduced (Maggi) equations generated by lagrange {__version__} from {Path(model.source).name}, for JAX.",
        "",
        f"The state is y = [{state}]: the coordinates and the independent velocities u (the multipliers are eliminated).",
        red.summary() + ".",
        "rhs(t, y, p) gives dy/dt = [q_dot..., u_dot...] with q_dot = C u + d and (C^T M C) u_dot = C^T (F - M e);",
        "velocities(t, y, p) gives every q_dot, reduced_mass_matrix and reduced_forcing give C^T M C and C^T (F - M e),",
        "reduce(q_dot) picks u from a full velocity vector. Each function is pure jax.numpy, so jax.jit, jax.vmap and",
        "jax.grad apply. p is None (the file's defaults, PARAMETERS), a dict by name (missing names take their defaults)",
        "or an array of NP values in PARAMETER_NAMES order (default_parameters() gives the defaults so).",
        "",
        "Float64: JAX computes in float32 unless 64-bit mode is on. For results that agree with the other targets",
        'to about 1e-12, run `import jax; jax.config.update("jax_enable_x64", True)` before creating any array;',
        "this module leaves that global setting to you. Code under jax.jit cannot raise: where C^T M C is singular",
        "or a function is outside its domain, the result is inf or NaN.",
        *target.SINCOS_NOTE * store.uses_sincos,
    ]
    if definitions:
        header += ["", written_definitions(definitions)]
    if missing:
        header += ["", f"Parameters without a default, to be given in p: {', '.join(missing)}."]
    if model.inputs:
        header += [
            "",
            f"Inputs u = [{', '.join(i.name for i in model.inputs)}] are given values at time t: rhs, velocities, reduced_mass_matrix and",
            "reduced_forcing take u after p, as p: None (the file's defaults, INPUTS), a dict by name or an array of NU",
            "values in INPUT_NAMES order (default_inputs() gives the defaults so).",
        ]

    def names_tuple(items: Sequence[str]) -> str:
        return "(" + ", ".join(literal(x) for x in items) + ("," if len(items) == 1 else "") + ")"

    defaults = ", ".join(f"{literal(p.name)}: {float(p.value)!r}" for p in model.parameters if p.value is not None)
    constants_block = [
        f"COORDINATES = {names_tuple(model.coordinates)}",
        f"INDEPENDENT = {names_tuple([model.coordinates[i] for i in red.independent])}",
        f"DEPENDENT = {names_tuple([model.coordinates[i] for i in red.dependent])}",
        f"PARAMETER_NAMES = {names_tuple([p.name for p in model.parameters])}",
        f"PARAMETERS = {{{defaults}}}",
        f"NQ = {n}",
        f"NI = {k}",
        f"NP = {len(model.parameters)}",
        *target.input_constants(model),
    ]
    head = docstring("\n".join([*header, ""])) + "\n\n" + ("import jax\n" if store.uses_sincos else "") + "import jax.numpy as jnp\n\n" + "\n".join(constants_block)
    helpers = [*target.helpers(model), *target.kept_helper(store.uses_kept), *target.sincos_helper(store.uses_sincos)]
    return head + "\n\n\n" + "\n\n\n".join([*helpers, *functions]) + "\n"
