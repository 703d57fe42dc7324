"""JSON: the model as data for other tools (a web page, a course platform, another solver).

One JSON object (schema `docs/model.schema.json`, documented in `docs/json.md`) with the
coordinates, the parameters and their defaults, the file's functions, and the equations
`M(q, t) q_ddot = F(q, q_dot, t) + A^T lambda` with `A q_ddot + c = 0`: M, F, the constraint
rows (A, b, c and the residual), the energy function, the momenta, the Lagrangian and its
parts, and with `inputs` or `outputs` in the file the inputs (name, default, description) and the
outputs (name, expression). Every expression is an object `{"text": ..., "latex": ...}`: `text` in the system-file
syntax, which lagrange's own parser (`lagrange_cli.expr.parse_expression`) reads back into the
same expression, and `latex` from the LaTeX emitter's printer and symbol names.

File text is data: titles, descriptions and names are JSON strings, written by `json.dumps`
with every character outside printable ASCII escaped (`ensure_ascii`), so they round-trip
exactly and cannot end a string or add a key. The output is deterministic: keys in a fixed
order, lists in the file's order where order means something (coordinates, parameters,
constraints) and sorted by name elsewhere (functions).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import sympy as sp
from sympy.core.function import AppliedUndef
from sympy.printing.str import StrPrinter

from lagrange_cli import __version__
from lagrange_cli.emit import latex
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model, apply_definitions

FUNCTIONS = frozenset({sp.sin, sp.cos, sp.tan, sp.cot, sp.sec, sp.csc, sp.asin, sp.acos, sp.atan, sp.atan2, sp.sinh, sp.cosh, sp.tanh, sp.exp, sp.log, sp.Abs, sp.sign})
"""The functions of the system-file syntax (the parser's, `expr.SUPPORTED_FUNCTIONS`; emitters do not import the frontend)."""
FORMAT = "lagrange-model"
SCHEMA_VERSION = 1
"""Raised when a key changes meaning or disappears; adding keys keeps the version."""


def emit(model: Model, *, name: str = "eom") -> str:
    """The model as a JSON document (`name` is not used: JSON has no names of its own)."""
    return json.dumps(document(model), indent=2, ensure_ascii=True, allow_nan=False) + "\n"


def emit_hamilton(model: Model, *, name: str = "eom") -> str:
    """`derive --to json --form hamilton`: the model's document with the key `hamilton` added
    (Hamilton's equations, lagrange_cli/hamilton.py; its refusals are its own)."""
    return json.dumps(document(model, hamilton=True), indent=2, ensure_ascii=True, allow_nan=False) + "\n"


def emit_reduced(model: Model, *, name: str = "eom") -> str:
    """`derive --to json --form reduced`: the model's document with the key `reduced` added (Maggi's
    equations for velocity constraints, lagrange_cli/reduced.py; its refusals are its own)."""
    return json.dumps(document(model, reduced=True), indent=2, ensure_ascii=True, allow_nan=False) + "\n"


def document(model: Model, hamilton: bool = False, reduced: bool = False) -> dict[str, Any]:
    """The JSON document as Python data (what `emit` writes); with `hamilton`, also the key `hamilton`
    (what `emit_hamilton` writes); with `reduced`, also the key `reduced` (what `emit_reduced` writes)."""
    from lagrange_cli import hamilton as legendre
    from lagrange_cli import reduced as maggi

    ham = legendre.hamilton(model) if hamilton else None
    red = maggi.reduced(model) if reduced else None
    functions = _functions(model)
    namer = latex.names(model, ham.p if ham is not None else ())
    tex = namer.printer().doprint

    def expression(expr: sp.Expr) -> dict[str, str]:
        written = _subs_written(expr, model)
        return {"text": text(written), "latex": tex(written)}

    def expressions(exprs: Iterable[sp.Expr]) -> list[dict[str, str]]:
        return [expression(e) for e in exprs]

    symbols = namer.symbols
    n = model.n
    signals: dict[str, Any] = {}
    if model.inputs:  # only then: a file without inputs or outputs gives the document it did
        signals["inputs"] = [
            {
                "name": i.name,
                "default": _finite(i.value, f"the default of input '{i.name}'"),
                "description": i.description,
                "latex": symbols.get(i.symbol, latex.symbol_tex(i.name)),
            }
            for i in model.inputs
        ]
    if model.outputs:
        signals["outputs"] = [{"name": name, "expression": expression(expr)} for name, expr in model.outputs]
    initial = {key: _finite(value, f"the initial value of '{key}'") for key, value in model.initial.items()}
    extra: dict[str, Any] = {}
    if ham is not None:
        extra["hamilton"] = {
            "momenta": [{"name": str(p), "latex": symbols[p], "rate": str(pd), "rate_latex": f"\\dot{{{symbols[p]}}}"} for p, pd in zip(ham.p, ham.pd, strict=True)],
            "route": "symbolic" if ham.symbolic else "numeric",
            "bias": expressions(ham.bias),
            "rates": expressions(legendre.rates_in_velocities(model)),
            "hamiltonian": expression(ham.hamiltonian) if ham.hamiltonian is not None else None,
            "velocities": expressions(ham.velocities) if ham.symbolic else None,
            "momentum_rates": expressions(ham.rates) if ham.symbolic else None,
        }
    if red is not None:
        k = len(red.independent)
        extra["reduced"] = {
            "independent": [model.coordinates[i] for i in red.independent],
            "dependent": [model.coordinates[i] for i in red.dependent],
            "state": [str(s) for s in red.state],
            "chosen": red.where,
            "determinant": expression(red.determinant),
            "velocities": expressions(red.velocities),
            "mass_matrix": [expressions(red.mass[i, j] for j in range(k)) for i in range(k)],
            "forcing": expressions(red.rhs),
        }
    return (
        {
            "format": FORMAT,
            "schema_version": SCHEMA_VERSION,
            "generator": f"lagrange {__version__}",
            "title": model.title,
            "description": model.description,
            "source": Path(model.source).name,
            "time": {"name": str(model.t), "latex": symbols[model.t]},
            "autonomous": model.autonomous,
            "coordinates": [
                {
                    "name": name,
                    "velocity": str(qd),
                    "acceleration": str(qdd),
                    "latex": symbols[q],
                    "velocity_latex": symbols[qd],
                    "acceleration_latex": symbols[qdd],
                }
                for name, q, qd, qdd in zip(model.coordinates, model.q, model.qd, model.qdd, strict=True)
            ],
            "parameters": [
                {
                    "name": p.name,
                    "default": None if p.value is None else _finite(p.value, f"the default of '{p.name}'"),
                    "real": p.real,
                    "description": p.description,
                    "latex": symbols[p.symbol],
                }
                for p in model.parameters
            ],
            "functions": [
                {
                    "name": function,
                    "latex": namer.functions.get(function, latex.symbol_tex(function)),
                    "arguments": [str(a) for a in model.definitions[function].variables] if function in model.definitions else None,
                    "definition": expression(model.definitions[function].expr) if function in model.definitions else None,
                }
                for function in functions
            ],
            "mass_matrix": [expressions(model.mass_matrix[i, j] for j in range(n)) for i in range(n)],
            "forcing": expressions(model.forcing),
            "constraints": [
                {
                    "name": c.name,
                    "multiplier": {"name": str(c.multiplier), "latex": symbols[c.multiplier]},
                    "holonomic": c.holonomic,
                    "residual": expression(c.expr),
                    "A": expressions(c.jacobian),
                    "b": expression(c.bias),
                    "c": expression(c.acceleration_bias),
                }
                for c in model.constraints
            ],
            "energy": expression(model.energy),
            "momenta": expressions(model.momenta),
            "lagrangian": expression(model.lagrangian),
            "kinetic": expression(model.kinetic),
            "potential": expression(model.potential),
            "dissipation": expression(model.dissipation),
            "generalized_forces": expressions(model.generalized_forces),
            "eliminated": [{"coordinate": coordinate, "expression": expression(expr)} for coordinate, expr in model.eliminated],
            "initial": {
                "q": [initial.get(c, 0.0) for c in model.coordinates],
                "q_dot": [initial.get(f"{c}_dot", 0.0) for c in model.coordinates],
            },
        }
        | signals
        | extra
    )


def _functions(model: Model) -> list[str]:
    """The names of the file's functions that the model uses or defines, sorted."""
    exprs: list[sp.Expr] = [*model.mass_matrix, *model.forcing, model.energy, model.lagrangian, model.kinetic, model.potential, model.dissipation]
    exprs += [*model.momenta, *model.generalized_forces, *(e for c in model.constraints for e in (c.expr, *c.jacobian, c.bias, c.acceleration_bias))]
    exprs += [e for _, e in model.eliminated] + [e for _, e in model.outputs]
    used = {str(f.func) for e in exprs for f in e.atoms(AppliedUndef)}
    return sorted(used | set(model.definitions))


def _finite(value: float, what: str) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise DerivationError(f"{what} is {value}, which JSON cannot hold")
    return value


# --- expressions in the system-file syntax ------------------------------------------------------


def _subs_written(expr: sp.Expr, model: Model) -> sp.Expr:
    """`expr` with each derivative of a defined function at a compound argument (`Subs`, e.g. U' at
    sqrt(x^2 + y^2)), which the system-file syntax cannot say, written out from the definition; the
    file's parser refuses such a derivative of an undefined function, so every `Subs` here has one."""
    if not expr.has(sp.Subs) or not model.definitions:
        return expr
    return expr.replace(lambda e: isinstance(e, sp.Subs), lambda e: apply_definitions(e, model.definitions))


def text(expr: sp.Expr) -> str:
    """`expr` in the system-file syntax (FORMAT.md "Expressions"): `+ - * / **`, the allowed
    function names, `pi`, `E`, the declared names and `Derivative(U(r), r)`, numbers as Python
    literals (floats by `repr`, exact). `parse_expression` with the model's names reads it back
    into an equal expression. Anything the syntax cannot say is a DerivationError, never text
    that reads back as something else."""
    _check_supported(expr)
    return _FilePrinter().doprint(expr)


def _check_supported(expr: sp.Expr) -> None:
    stack: list[sp.Basic] = [expr]
    while stack:
        item = stack.pop()
        if item.is_Symbol or item.is_Rational or item.is_Float or item in (sp.pi, sp.E):
            continue
        if isinstance(item, sp.Derivative):
            if not all(isinstance(v, sp.Symbol) for v in item.variables):
                raise DerivationError(f"cannot write the derivative {item} in the system-file syntax")
            stack.append(item.expr)
            continue
        if isinstance(item, (sp.Add, sp.Mul, sp.Pow, AppliedUndef)) or type(item) in FUNCTIONS:
            stack.extend(item.args)
            continue
        raise DerivationError(f"cannot write '{type(item).__name__}' in the system-file syntax")


class _FilePrinter(StrPrinter):
    """sympy's str printer with exact float literals and derivatives the file's parser takes:
    `Derivative(U(r), r, 2)`, one variable at a time."""

    def __init__(self) -> None:
        super().__init__({"full_prec": True})

    def _print_Float(self, expr: sp.Float) -> str:
        return repr(float(expr))

    def _print_Derivative(self, expr: sp.Derivative) -> str:
        inner = self._print(expr.expr)
        for variable, count in expr.variable_count:
            inner = f"Derivative({inner}, {self._print(variable)}" + (f", {count})" if count != 1 else ")")
        return inner
