"""Python: a self-contained module for numerical work, with common subexpressions eliminated.

The module defines COORDINATES, PARAMETERS (defaults), mass_matrix, forcing, energy and
rhs(t, y, p) with y = [q..., q_dot...], ready for scipy.integrate.solve_ivp. It imports
only what it uses: `math` functions, and numpy only for large systems. Functions of an
autonomous system take no time argument (except rhs, whose signature solve_ivp fixes).
Functions the file defines (`functions: {U: {arguments: [s], definition: -k/s}}`) are written
out from their definitions, which the module's docstring states.

Safe with any system file (shared with numeric/codegen.py, and meant for every future target):

- File text is data. Titles, file names, definitions and names reach the code only through
  `docstring` and `literal`, which escape backslashes, double quotes and every character that
  is not printable ASCII, so nothing in a file can end a string, break the syntax or run.
- User names cannot meet generated names. `mangle` gives each user symbol an identifier
  distinct from every other user name, every Python keyword and builtin, every `math` name and
  every name the generated code uses (`RESERVED`); the generator's own helpers and temporaries
  start with `_`, which no user name does.
- Real arithmetic. A power with a non-integer exponent is printed as `math.pow`, so a negative
  base raises ValueError ("math domain error") instead of going complex, like sqrt, log and acos
  out of their domains. Generated Python thus fails with ValueError (outside a function's domain),
  ZeroDivisionError (division by zero, a singular matrix in `_solve`) or OverflowError (too large),
  never with a complex or silently wrong number; numba-compiled code (error_model="numpy")
  gives NaN or inf instead, which the integration loops report as non-finite.
"""

from __future__ import annotations

import builtins
import functools
import keyword
import math
import re
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import sympy as sp

from lagrange_cli import __version__
from lagrange_cli._symengine import to_symengine
from lagrange_cli.algebra import check_solvable
from lagrange_cli.emit.common import require_defined, written_definitions
from lagrange_cli.emit.printer import ATOM, Code, Printer, restructure
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

# Above this many unknowns the linear solve is numpy's; below, straight-line Python is faster.
NUMPY_SIZE = 9
SPLIT = 1000
"""Statements of a numba function above which it is generated as loops over tables (`vectorize`)."""
GENERATED = frozenset(
    {
        *("t", "y", "p", "q", "q_dot", "math", "numpy", "numba", "njit", "tolist", "hasattr", "float", "abs", "pow", "copysign", "inf", "nan"),
        *("COORDINATES", "PARAMETERS", "mass_matrix", "forcing", "energy", "rhs", "accelerations", "multipliers", "constraint_residuals", "constraint_forces"),
    }
)
"""Names without a leading `_` that generated code uses: arguments, modules, public functions."""
RESERVED = frozenset({*keyword.kwlist, *keyword.softkwlist, *dir(builtins), *dir(math), *GENERATED})
"""What no user symbol may be called in generated Python (besides any name starting with `_`)."""
AMBIGUOUS = frozenset({"l", "I", "O"})
MATH_NAMES = frozenset(dir(math))


def code_lines(
    printer: Printer, exprs: Sequence[Any], constants: Collection[str], velocities: Collection[str] = (), *, prefix: str = "_c", tag: str = "", products: bool = True
) -> tuple[list[tuple[str, str]], list[str]]:
    """Straight-line code computing `exprs` (symengine): `restructure` (trig temporaries, collected
    and factored coefficients), then CSE once over all of them, printed by `printer`:
    ([(name, code), ...] in order, [result code, ...]). Several blocks in one function need
    distinct `prefix` and `tag` (see `restructure`). Shared with numeric/codegen.py."""
    definitions, reduced = restructure(exprs, constants, velocities, products=products, tag=tag)
    printer.names.update((name, name) for name, _ in definitions)
    lines = [(name, printer.doprint(value)) for name, value in definitions]
    temporaries, results = printer.block(reduced, prefix, {name for name, _ in definitions})
    return lines + temporaries, results


@dataclass(frozen=True)
class Rows:
    """The constraint rows of a model as symengine expressions (constrained systems are small:
    converting their rows costs nothing next to the rest)."""

    expr: tuple[Any, ...]
    jacobian: tuple[tuple[Any, ...], ...]
    bias: tuple[Any, ...]
    acceleration_bias: tuple[Any, ...]

    @classmethod
    def of(cls, model: Model) -> Rows:
        rows = model.constraints
        return cls(
            tuple(to_symengine(c.expr) for c in rows),
            tuple(tuple(to_symengine(a) for a in c.jacobian) for c in rows),
            tuple(to_symengine(c.bias) for c in rows),
            tuple(to_symengine(c.acceleration_bias) for c in rows),
        )


def symbol_names(model: Model) -> dict[str, str]:
    """`python_names` keyed by the symbols' names, as the printer core looks them up."""
    return {str(symbol): name for symbol, name in python_names(model).items()}


def free_names(exprs: Sequence[Any]) -> set[str]:
    """The names of the symbols in `exprs` (symengine), each distinct sub-expression visited once (symengine's
    `free_symbols` walks a shared sub-expression once per occurrence: exponential work on a spatial chain)."""
    names: set[str] = set()
    seen: set[Any] = set()
    stack = list(exprs)
    while stack:
        e = stack.pop()
        if e in seen:
            continue
        seen.add(e)
        if e.is_Symbol:
            names.add(str(e))
        else:
            stack.extend(e.args)
    return names


def emit(model: Model, numba: bool = False) -> str:
    """The module's source; with `numba=True` its rhs is compiled by numba (cached on disk).
    The file's function definitions are written out (`Model.with_definitions`). Printed from
    `model.symengine` by the printer core: the sympy fields are not read (a model with defined
    functions or constraints, always small, converts what it needs)."""
    definitions = model.definitions
    if model.constraints:
        require_defined(model, "Python code")
    numeric = model.with_definitions()
    try:
        check_solvable(numeric)
        return _Writer(numeric, numba, definitions).module()
    except DerivationError:
        require_defined(model, "Python code")  # a function left general: say so, by name
        raise


class _Writer:
    def __init__(self, model: Model, numba: bool = False, definitions: Mapping[str, sp.Lambda] | None = None) -> None:
        self.model = model
        self.forms = model.symengine
        self.rows = Rows.of(model)
        self.definitions = definitions or {}
        self.numba = numba
        self.names = symbol_names(model)
        self.printer = PythonPrinter(self.names)
        self.constants = frozenset([*(p.name for p in model.parameters), *(i.name for i in model.inputs)])
        self.signals = frozenset(i.name for i in model.inputs)
        self.velocities = frozenset(str(v) for v in self.forms.qd)
        self.uses_numpy = False
        self.uses_solve = False
        n, k = model.n, len(model.constraints)
        self.size = n + k
        self.upper = [(i, j) for i in range(n) for j in range(i, n)]
        self.mass = [self.forms.mass[i][j] for i, j in self.upper]

    # -- pieces ---------------------------------------------------------------------------------

    @functools.cached_property
    def shared(self) -> tuple[list[tuple[str, str]], dict[Any, str]]:
        """Everything the module computes (M, F, the energy, the constraint rows), restructured
        and CSE'd once: (lines, expression -> its result code). Each function keeps the lines
        its results need (`block`)."""
        rows = self.rows
        exprs = [*self.mass, *self.forms.forcing, self.forms.energy, *(-a for row in rows.jacobian for a in row), *(-c for c in rows.acceleration_bias), *rows.expr]
        exprs = list(dict.fromkeys(exprs))
        lines, results = code_lines(self.printer, exprs, self.constants, self.velocities)
        return lines, dict(zip(exprs, results, strict=True))

    def block(self, exprs: Sequence[Any]) -> tuple[list[str], list[str]]:
        """The lines computing `exprs` (all among `shared`'s), and their result codes."""
        lines, codes = self.shared
        results = [codes[e] for e in exprs]
        return [f"{name} = {code}" for name, code in needed(lines, results)], results

    def unpack(self, exprs: Sequence[Any], state: str) -> list[str]:
        """Lines binding the parameters used, then the coordinates/velocities from `state`."""
        used = free_names(exprs)
        lines = []
        for parameter in self.model.parameters:
            if parameter.name in used:
                name = self.names[parameter.name]
                lines.append(f"{name} = p[{literal(parameter.name)}]" + _noqa(name))
        for signal in self.model.inputs:
            if signal.name in used:
                name = self.names[signal.name]
                lines.append(f"{name} = u[{literal(signal.name)}]" + _noqa(name))
        forms = self.forms
        groups = [("y", [*forms.q, *forms.qd])] if state == "y" else [(g, v) for g, v in (("q", forms.q), ("q_dot", forms.qd)) if g in state.split(",")]
        for group, variables in groups:
            keep = [str(v) in used or (group == "y" and v in forms.qd) for v in variables]
            if any(keep):
                targets = [self.names[str(v)] if k else "_" for v, k in zip(variables, keep, strict=True)]
                source = f'{group}.tolist() if hasattr({group}, "tolist") else {group}' if group == "y" else group
                lines.append(f"{', '.join(targets)}{',' * (len(targets) == 1)} = {source}" + _noqa(*targets))
        return lines

    def signature(self, exprs: Sequence[Any], state: str) -> str:
        has_t = str(self.forms.t) in free_names(exprs)
        return ", ".join(["t"] * has_t + state.split(",") + ["p=PARAMETERS"] + ["u=INPUTS"] * self.uses_inputs(exprs))

    def uses_inputs(self, exprs: Sequence[Any]) -> bool:
        """Whether `exprs` (symengine) hold an input: then their function takes `u=INPUTS` after `p`."""
        return bool(self.signals and self.signals & free_names(exprs))

    def function(self, name: str, doc: str, exprs: Sequence[Any], state: str, shape: str) -> str:
        lines, results = self.block(exprs)
        body = [*self.unpack(exprs, state), *lines]
        if shape == "matrix":
            n = self.model.n
            cell = dict(zip(self.upper, results, strict=True))
            for (i, j), code in list(cell.items()):
                if i != j and not _simple(code):  # each off-diagonal entry computed once, used twice
                    body.append(f"_m{i}_{j} = {code}")
                    cell[(i, j)] = f"_m{i}_{j}"
            rows = ["[" + ", ".join(cell[(min(i, j), max(i, j))] for j in range(n)) + "]" for i in range(n)]
            body.append("return [" + ", ".join(rows) + "]")
        elif shape == "vector":
            body.append("return [" + ", ".join(results) + "]")
        else:
            body.append(f"return {results[0]}")
        return define(name, self.signature(exprs, state), doc, body)

    def rhs(self) -> str:
        model, n, rows = self.model, self.model.n, self.rows
        force = list(self.forms.forcing)
        extra = [-a for row in rows.jacobian for a in row] + [-c for c in rows.acceleration_bias]
        exprs = [*self.mass, *force, *extra]  # the order of `shared`
        if self.numba:
            return self.compiled_rhs(exprs)
        arguments, values = ("t, y, p=PARAMETERS, u=INPUTS", "t, y, p, u") if self.uses_inputs(exprs) else ("t, y, p=PARAMETERS", "t, y, p")
        lines, results = self.block(exprs)
        m = dict(zip(self.upper, results[: len(self.mass)], strict=True))
        f = list(results[len(self.mass) : len(self.mass) + n])
        body = [*self.unpack(exprs, "y"), *lines]
        velocities = [self.names[str(v)] for v in self.forms.qd]
        if rows.expr or n > 2:
            body += [f"_m{i}_{j} = {code}" for (i, j), code in m.items() if not _simple(code)]
            m = {(i, j): code if _simple(code) else f"_m{i}_{j}" for (i, j), code in m.items()}
        if rows.expr:
            a = results[len(self.mass) + n : len(self.mass) + n + n * len(rows.expr)]
            c = results[len(self.mass) + n + n * len(rows.expr) :]
            k = len(rows.expr)
            matrix = [[m[(min(i, j), max(i, j))] for j in range(n)] + [a[r * n + i] for r in range(k)] for i in range(n)]
            matrix += [[_negate(a[r * n + j]) for j in range(n)] + ["0.0"] * k for r in range(k)]
            body += self.solve(matrix, [*f, *c], "_x")
            body.append("return _x")
            names = ", ".join(str(x) for x in model.multipliers)
            solver = define("accelerations", arguments, f"[{', '.join(map(str, model.qdd))}, {names}] from [[M, -A^T], [A, 0]] x = [F, -c] (index-1 form).", body)
            rhs = define("rhs", arguments, _rhs_doc(model), [f"_x = accelerations({values})", f'return [*(y.tolist() if hasattr(y, "tolist") else y)[{n}:], *_x[:{n}]]'])
            multipliers = define("multipliers", arguments, f"The multipliers [{names}]; A^T lambda is the generalized constraint force.", [f"return accelerations({values})[{n}:]"])
            return "\n\n\n".join([solver, rhs, multipliers])
        if n == 1:
            body.append(f"return [{velocities[0]}, ({f[0]})/({m[(0, 0)]})]")
        elif n == 2:
            body += [f"_m00 = {m[(0, 0)]}", f"_m01 = {m[(0, 1)]}", f"_m11 = {m[(1, 1)]}", f"_f0 = {f[0]}", f"_f1 = {f[1]}", "_det = _m00*_m11 - _m01*_m01"]
            body.append(f"return [{velocities[0]}, {velocities[1]}, (_m11*_f0 - _m01*_f1)/_det, (_m00*_f1 - _m01*_f0)/_det]")
        else:
            matrix = [[m[(min(i, j), max(i, j))] for j in range(n)] for i in range(n)]
            body += self.solve(matrix, f, "_x", symmetric=True)
            body.append(f"return [{', '.join(velocities)}, *_x]")
        return define("rhs", arguments, _rhs_doc(model), body)

    def compiled_rhs(self, exprs: Sequence[Any]) -> str:
        """rhs as a thin wrapper around a numba kernel taking y and the used parameters as arrays,
        which fills [M, -A^T; A, 0] and solves with numpy. A big system's kernel is written as
        loops over tables (`vectorize`): numba's compile time grows with the statements."""
        model, n = self.model, self.model.n
        k = len(self.rows.expr)
        size = n + k
        used = free_names(exprs)
        parameters = [p for p in model.parameters if p.name in used]
        signals = [i for i in model.inputs if i.name in used]
        lines, results = self.block(exprs)
        m = dict(zip(self.upper, results[: len(self.mass)], strict=True))
        f = list(results[len(self.mass) : len(self.mass) + n])
        inputs = [f"{self.names[name]} = _p[{i}]" + _noqa(self.names[name]) for i, name in enumerate([*(p.name for p in parameters), *(u.name for u in signals)])]
        inputs += [f"{self.names[str(v)]} = y[{i}]" + _noqa(self.names[str(v)]) for i, v in enumerate([*self.forms.q, *self.forms.qd]) if str(v) in used]
        prologue = [f"_a = numpy.zeros(({size}, {size}))", f"_b = numpy.empty({size})"]
        fill = []
        for i, j in self.upper:
            if m[(i, j)] != "0":
                fill += [f"_a[{i}, {j}] = {m[(i, j)]}"] + ([f"_a[{j}, {i}] = _a[{i}, {j}]"] if i != j else [])
        if k:
            a = results[len(self.upper) + n : len(self.upper) + n + n * k]
            c = results[len(self.upper) + n + n * k :]
            for r in range(k):
                for j in range(n):
                    if a[r * n + j] != "0":
                        fill += [f"_a[{j}, {n + r}] = {a[r * n + j]}", f"_a[{n + r}, {j}] = -_a[{j}, {n + r}]"]
            f = [*f, *c]
        fill += [f"_b[{i}] = {value}" for i, value in enumerate(f)]
        tail = ["_x = _lu_solve(_a, _b)", f"_out = numpy.empty({2 * n})", f"_out[:{n}] = y[{n}:]", f"_out[{n}:] = _x[:{n}]", "return _out"]
        if len(lines) + len(fill) > SPLIT:
            tables, code = vectorize(inputs, [*lines, *fill], tail, "_rhs")
            body = [*prologue, *code]
        else:
            tables, body = [], [*inputs, *prologue, *lines, *fill, *tail]
        kernels = ["\n".join(tables)] if tables else []
        kernels.append(LU_SOLVE)
        kernels.append("@numba.njit(cache=True)\n" + define("_rhs", "t, y, _p", "The compiled right-hand side.", body))
        entries = [f"float(p[{literal(p.name)}])" for p in parameters] + [f"float(u[{literal(i.name)}])" for i in signals]
        vector = "numpy.array([" + ", ".join(entries) + "])" if entries else "numpy.empty(0)"
        arguments = ", ".join(["t", "numpy.asarray(y, dtype=numpy.float64)", vector])
        signature = "t, y, p=PARAMETERS" + (", u=INPUTS" if signals else "")
        wrapper = define("rhs", signature, _rhs_doc(model) + " Compiled by numba; returns an array.", [f"return _rhs({arguments})"])
        self.uses_numpy = True
        return "\n\n\n".join([*kernels, wrapper])

    def solve(self, matrix: list[list[str]], vector: list[str], target: str, symmetric: bool = False) -> list[str]:
        n = len(matrix)
        if n >= NUMPY_SIZE:
            self.uses_numpy = True
            flat = ", ".join(x for row in matrix for x in row)
            return [f"{target} = numpy.linalg.solve(numpy.fromiter(({flat}), float, {n * n}).reshape({n}, {n}), numpy.fromiter(({', '.join(vector)}), float, {n})).tolist()"]
        self.uses_solve = True
        rows = "[" + ", ".join("[" + ", ".join(row) + "]" for row in matrix) + "]"
        return [f"{target} = _solve({rows}, [{', '.join(vector)}])"]

    def residuals(self) -> str:
        return self.function("constraint_residuals", "Each constraint's residual: f(q, t) for holonomic ones, a . q_dot + b for velocity ones.", list(self.rows.expr), "q,q_dot", "vector")

    # -- the module -----------------------------------------------------------------------------

    def module(self) -> str:
        model, forms = self.model, self.forms
        functions = [
            self.function("mass_matrix", "The mass matrix M as a list of rows.", self.mass, "q", "matrix"),
            self.function("forcing", "The forcing F of M q_ddot = F" + (" + A^T lambda" if model.constraints else "") + ".", list(forms.forcing), "q,q_dot", "vector"),
            self.function("energy", "The energy function h = sum p_i q_dot_i - L.", [forms.energy], "q,q_dot", "scalar"),
        ]
        if model.constraints:
            functions.append(self.residuals())
        functions.append(self.rhs())
        if model.outputs:
            functions.append(self.outputs())
        if model.constraints and not self.numba:
            from lagrange_cli.forces import python_function

            functions.append(python_function(model, self.printer, self.unpack))
        if self.uses_solve:
            functions.append(SOLVE)
        imports = []
        math_names = self.printer.imports()
        if math_names:
            imports.append(f"from math import {', '.join(math_names)}")
        if self.numba:
            imports.append("import numba")
        if self.uses_numpy:
            imports.append("import numpy")
        parameters = ", ".join(f"{literal(p.name)}: {_number(p.value)}" for p in model.parameters if p.value is not None)
        missing = [p.name for p in model.parameters if p.value is None]
        time = "" if self.autonomous() else ", t"
        header = [
            f"{model.title}: equations of motion generated by lagrange {__version__} from {Path(model.source).name}.",
            "",
            f"M(q{time}) q_ddot = F(q, q_dot{time})" + (" + A^T lambda" if model.constraints else "") + f", with y = [{', '.join(map(str, (*model.q, *model.qd)))}].",
        ]
        if self.definitions:
            header.append(written_definitions(self.definitions))
        if missing:
            header.append(f"Parameters without a default, to be given in p: {', '.join(missing)}.")
        parts = [docstring("\n".join([*header, ""])), "\n".join(imports)] if imports else [docstring("\n".join([*header, ""]))]
        coordinates = ", ".join(literal(c) for c in model.coordinates)
        parts.append(f"COORDINATES = ({coordinates}{',' * (model.n == 1)})\nPARAMETERS = {{{parameters}}}")
        if model.inputs:
            parts[-1] += "\nINPUTS = {" + ", ".join(f"{literal(i.name)}: {_number(i.value)}" for i in model.inputs) + "}"
        return "\n\n".join(parts) + "\n\n\n" + "\n\n\n".join(functions) + "\n"

    def outputs(self) -> str:
        """`outputs(t, y, p=PARAMETERS, u=INPUTS)`: the file's outputs, in its order (FORMAT.md version 2)."""
        from lagrange_cli._symengine import to_symengine

        model = self.model.with_definitions()
        exprs = [to_symengine(e) for _, e in model.outputs]
        lines, results = code_lines(self.printer, exprs, self.constants, self.velocities, prefix="_o", tag="o")
        body = [*self.unpack(exprs, "y"), *(f"{name} = {code}" for name, code in lines), "return [" + ", ".join(results) + "]"]
        names = ", ".join(name for name, _ in model.outputs)
        signature = "t, y, p=PARAMETERS" + (", u=INPUTS" if model.inputs else "")
        return define("outputs", signature, f"The outputs [{names}] at time t and state y.", body)

    def autonomous(self) -> bool:
        """No explicit t in M, F or the constraint rows (from the symengine forms)."""
        forms, rows = self.forms, self.rows
        exprs = [*self.mass, *forms.forcing, *(a for row in rows.jacobian for a in row), *rows.bias, *rows.acceleration_bias]
        return str(forms.t) not in free_names(exprs)


_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def needed(lines: Sequence[tuple[str, str]], results: Sequence[str]) -> list[tuple[str, str]]:
    """The assignments `lines` that `results` need, directly or through other lines, in order."""
    wanted = set().union(*(_IDENTIFIER.findall(code) for code in results)) if results else set()
    kept = []
    for name, code in reversed(lines):
        if name in wanted:
            kept.append((name, code))
            wanted.update(_IDENTIFIER.findall(code))
    return kept[::-1]


SOLVE = '''def _solve(a, b):
    """Solve a x = b by Gaussian elimination with partial pivoting (a, b are overwritten), each
    row first divided by its largest entry so that rows in different units compare fairly;
    ZeroDivisionError when a pivot is below 1e-13 of its row's largest entry."""
    n = len(b)
    for i in range(n):
        largest = max(abs(v) for v in a[i])
        if not largest > 0.0:
            raise ZeroDivisionError("singular matrix")
        a[i] = [v / largest for v in a[i]]
        b[i] /= largest
    for k in range(n):
        pivot = max(range(k, n), key=lambda i: abs(a[i][k]))
        if not abs(a[pivot][k]) > 1e-13:
            raise ZeroDivisionError("singular matrix")
        a[k], a[pivot] = a[pivot], a[k]
        b[k], b[pivot] = b[pivot], b[k]
        row, inverse = a[k], 1.0 / a[k][k]
        for i in range(k + 1, n):
            factor = a[i][k] * inverse
            if factor:
                other = a[i]
                for j in range(k + 1, n):
                    other[j] -= factor * row[j]
                b[i] -= factor * b[k]
    x = [0.0] * n
    for i in range(n - 1, -1, -1):
        row = a[i]
        x[i] = (b[i] - sum(row[j] * x[j] for j in range(i + 1, n))) / row[i]
    return x'''


LU_SOLVE = '''@numba.njit(cache=True)
def _lu_solve(a, b):
    """Solve a x = b by Gaussian elimination with partial pivoting (a and b are overwritten; b
    becomes x); ZeroDivisionError when a pivot is exactly 0, as the plain module's _solve. A few
    loops that numba compiles in a fraction of the time numpy.linalg.solve's LAPACK binding takes."""
    n = b.shape[0]
    for k in range(n):
        pivot = k
        largest = abs(a[k, k])
        for i in range(k + 1, n):
            if abs(a[i, k]) > largest:
                largest = abs(a[i, k])
                pivot = i
        if not largest > 0.0:
            raise ZeroDivisionError("singular matrix")
        if pivot != k:
            for j in range(k, n):
                a[k, j], a[pivot, j] = a[pivot, j], a[k, j]
            b[k], b[pivot] = b[pivot], b[k]
        inverse = 1.0 / a[k, k]
        for i in range(k + 1, n):
            factor = a[i, k] * inverse
            if factor != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= factor * a[k, j]
                b[i] -= factor * b[k]
    for i in range(n - 1, -1, -1):
        total = b[i]
        for j in range(i + 1, n):
            total -= a[i, j] * b[j]
        b[i] = total / a[i, i]
    return b'''


def mangle(names: Sequence[str], reserved: Collection[str] = RESERVED) -> dict[str, str]:
    """Each user name -> its identifier in generated code, for any target (`reserved` being what
    that target's code names itself). A name stays as it is when it is free; otherwise `_` is
    appended until the result is none of `reserved`, no other user name and no name already
    given (so `p` and `p_` stay apart). Characters outside [A-Za-z0-9_] become `_` and a name
    not starting with a letter gets a `v` in front, so that no result starts with `_`, the
    prefix of the generator's own names."""
    users = set(names)
    given: dict[str, str] = {}
    for name in names:
        if name in given:
            continue
        candidate = re.sub(r"[^A-Za-z0-9_]", "_", name)
        if not re.match(r"[A-Za-z]", candidate):
            candidate = "v" + candidate
        while candidate in reserved or keyword.iskeyword(candidate) or (candidate != name and candidate in users) or candidate in given.values():
            candidate += "_"
        given[name] = candidate
    return given


def python_names(model: Model) -> dict[sp.Symbol, str]:
    """Identifiers for the model's coordinates, velocities and parameters (`mangle`), and `t`."""
    symbols = [*model.q, *model.qd, *(p.symbol for p in model.parameters), *(i.symbol for i in model.inputs)]
    signals = frozenset({"u", "INPUTS", "outputs"}) if model.inputs or model.outputs else frozenset()  # only then: a file without inputs keeps its names
    names = mangle([str(s) for s in symbols], RESERVED | signals)
    return {**{s: names[str(s)] for s in symbols}, model.t: "t"}


def escape(text: str, newlines: bool = True) -> str:
    """`text` as the inside of a double-quoted Python string literal, in printable ASCII:
    backslashes and double quotes escaped, every other character outside ' '..'~' written as an
    escape (`\\n`, `\\x00`, `\\u202e`, ...); line breaks kept as they are when `newlines` is
    False (for triple-quoted strings). Nothing in `text` can end the literal or become code."""
    out = []
    for char in text:
        if char in '\\"':
            out.append("\\" + char)
        elif " " <= char <= "~" or (char == "\n" and not newlines):
            out.append(char)
        elif char in "\n\r\t":
            out.append({"\n": "\\n", "\r": "\\r", "\t": "\\t"}[char])
        else:
            code = ord(char)
            out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}")
    return "".join(out)


def literal(text: str) -> str:
    """A Python string literal whose value is `text` (see `escape`)."""
    return f'"{escape(text)}"'


def docstring(text: str, indent: str = "") -> str:
    """A triple-quoted docstring of `text` (see `escape`), its lines after the first indented by
    `indent`: the one way any text, file text included, enters generated code as prose."""
    lines = escape(text, newlines=False).split("\n")
    return '"""' + "\n".join([lines[0], *(indent + line if line else line for line in lines[1:])]) + '"""'


def _number(value: float) -> str:
    """A float literal; a non-finite value as `float("inf")`, never a bare name."""
    return repr(float(value)) if math.isfinite(value) else f'float("{value}")'


def _simple(code: str) -> bool:
    """A name or a number: nothing to gain from binding it to a temporary."""
    return code.replace("_", "a").replace(".", "0").lstrip("-").isalnum()


def _negate(code: str) -> str:
    """The negation of a printed expression, without double signs."""
    if code.startswith("-") and all(ch.isalnum() or ch in "_.*" for ch in code[1:]):
        return code[1:]
    return "-" + code if all(ch.isalnum() or ch in "_.*" for ch in code) else f"-({code})"


def _noqa(*names: str) -> str:
    return "  # noqa: E741" if AMBIGUOUS.intersection(names) else ""


def define(name: str, signature: str, doc: str, body: list[str]) -> str:
    """A function definition; shared with numeric/codegen.py."""
    lines = [f"def {name}({signature}):", "    " + docstring(doc, "    ")] + [f"    {line}" for line in body]
    return "\n".join(lines)


def _rhs_doc(model: Model) -> str:
    state = ", ".join(map(str, (*model.q, *model.qd)))
    return f"dy/dt for y = [{state}] (for scipy.integrate.solve_ivp)."


class PythonPrinter(Printer):
    """Python with bare `math` names (those used are in `used`; `abs` is the builtin): real
    arithmetic, a non-integer power as `pow` (math.pow, a ValueError for a negative base)."""

    functions: ClassVar[Mapping[str, str]] = {**Printer.functions, "Abs": "abs", "pow": "pow"}

    def nonfinite(self, value: float) -> Code:
        name = "nan" if math.isnan(value) else "inf"
        self.used.add(name)
        return name, ATOM

    def _print_sign(self, expr: Any) -> Code:
        (argument,) = expr.args
        x = self.doprint(argument)
        self.used.add("copysign")
        return f"(0.0 if {x} == 0 else copysign(1.0, {x}))", ATOM

    def imports(self) -> list[str]:
        """The `math` names the printed code uses."""
        return sorted(self.used & MATH_NAMES)


_TOKEN = re.compile(r"(\d+\.?\d*(?:[eE][-+]?\d+)?)|([A-Za-z_]\w*)(\[[\d, ]+\])?")
_STATEMENT = re.compile(r"^([A-Za-z_]\w*(?:\[[\d, ]+\])?) = (.*)$")


def vectorize(inputs: list[str], lines: list[str], tail: list[str], name: str, family: int = 4) -> tuple[list[str], list[str]]:
    """Long straight-line numba code as a few loops over index tables, so that numba compiles a
    handful of loop bodies instead of thousands of statements or hundreds of loops (its type
    inference and LLVM's optimizer grow with the statements and with the loops of a function).

    Every scalar (an input or a temporary) gets a slot of a work array `_w`. Statements are
    scheduled by level (1 + the highest level of the scalars they read), and the statements of
    one level with the same shape (the code with its scalars and constant array indices taken
    out: `{0}*{1} + {2}*{3}`, `_a[{0}, {1}] = {2}`) form a run: statements of one level never read
    each other, so the order within a level is free. Each shape is written once, as a loop over
    its table (a module-level int64 array `<name>_T<k>` of its members' slots and indices, the
    runs of the shape one after another), and a dispatch loop walks the runs in order (a table
    `<name>_R` of shape, first row, end row): the function has one loop body per shape however
    many levels there are. A statement of another form (a call such as `_lu_solve(_a, _x)`, a
    slice) is a barrier: the code before and after it is scheduled apart. `family` is kept for
    the callers' signature; every run is a loop. Returns (the module-level tables, the body:
    `_w`, the code, the tail)."""
    statements = [piece for line in [*inputs, *lines] for piece in _accumulate(line.split("  #", 1)[0])]
    slots: dict[str, int] = {}
    for line in statements:
        match = _STATEMENT.match(line)
        if match and match.group(1).isidentifier():
            slots.setdefault(match.group(1), len(slots))
    program = _Program(name)
    body = [f"_w = numpy.empty({max(len(slots), 1)})"]
    segment: list[tuple[str, str]] = []
    level: dict[str, int] = {}

    def flush() -> None:
        body.extend(_schedule(segment, slots, level, program))
        segment.clear()

    for line in statements:
        match = _STATEMENT.match(line)
        if match and _pure(match.group(2)):
            segment.append((match.group(1), match.group(2)))
        else:
            flush()
            body.append(_substitute(line, slots))
    flush()
    body += [_substitute(line, slots) for line in tail]
    return program.tables(), body


@dataclass
class _Program:
    """The tables of a vectorized function: per shape (left, right) its rows of operands, and the
    runs (shape, first row, end row) in the order they execute."""

    name: str
    shapes: dict[tuple[str, str], int] = field(default_factory=dict)
    rows: list[list[list[int]]] = field(default_factory=list)
    runs: list[tuple[int, int, int]] = field(default_factory=list)

    def run(self, shape: tuple[str, str], members: list[list[int]]) -> int:
        """Append a run of `shape` with these members' operands; the shape's number."""
        k = self.shapes.setdefault(shape, len(self.shapes))
        if k == len(self.rows):
            self.rows.append([])
        first = len(self.rows[k])
        self.rows[k].extend(members)
        self.runs.append((k, first, len(self.rows[k])))
        return k

    def tables(self) -> list[str]:
        result = []
        for k, rows in enumerate(self.rows):
            flat = ", ".join(str(v) for operands in rows for v in operands)
            result.append(f"{self.name}_T{k} = numpy.array([{flat}], dtype=numpy.int64).reshape({len(rows)}, {len(rows[0])})")
        if self.runs:
            flat = ", ".join(str(v) for run in self.runs for v in run)
            result.append(f"{self.name}_R = numpy.array([{flat}], dtype=numpy.int64).reshape({len(self.runs)}, 3)")
        return result


_CALL = re.compile(r"([A-Za-z_][\w.]*)\(")
MATH_CALLS = frozenset({*MATH_NAMES, "abs", "float"})


def _accumulate(line: str, longest: int = 4) -> list[str]:
    """`x = a + b - c + ...` (a sum of more than `longest` terms) as `x = a`, `x = x + b`,
    `x = x - c`, ...: one statement per term, which `vectorize` turns into loops across the
    sums of the same shape (the rows of F). Other statements as they are."""
    match = _STATEMENT.match(line)
    if not match:
        return [line]
    left, right = match.groups()
    terms: list[str] = []
    depth, start = 0, 0
    for i, char in enumerate(right):
        if char in "([":
            depth += 1
        elif char in ")]":
            depth -= 1
        elif depth == 0 and i > start and right[i - 1] == " " and char in "+-" and i + 1 < len(right) and right[i + 1] == " ":
            terms.append(right[start : i - 1])
            start = i
    terms.append(right[start:])
    if len(terms) <= longest:
        return [line]
    return [f"{left} = {terms[0]}"] + [f"{left} = {left} {term[0]} {term[2:]}" for term in terms[1:]]


def _pure(code: str) -> bool:
    """True when the only calls in `code` are of math functions (no side effects, no arrays made)."""
    return all(call in MATH_CALLS for call in _CALL.findall(code))


def _substitute(line: str, slots: Mapping[str, int]) -> str:
    """`line` with each slotted scalar read or written as `_w[k]`."""

    def replace(match: re.Match[str]) -> str:
        number, word, index = match.groups()
        if number is not None:
            return number
        if index is None and word in slots:
            return f"_w[{slots[word]}]"
        return match.group(0)

    return _TOKEN.sub(replace, line)


def _schedule(segment: list[tuple[str, str]], slots: Mapping[str, int], level: dict[str, int], program: _Program) -> list[str]:
    """The statements of one segment (see `vectorize`) as a dispatch loop over its runs."""
    groups: dict[tuple[int, str, str], list[list[int]]] = {}
    for left, right in segment:
        operands: list[int] = []
        depth = 0

        def take(match: re.Match[str], operands: list[int] = operands) -> str:
            nonlocal depth
            number, word, index = match.groups()
            if number is not None:
                return number
            if index is not None:
                depth = max(depth, level.get(word + index, 0))  # an array element written before
                parts = []
                for value in index[1:-1].split(","):
                    operands.append(int(value))
                    parts.append(f"{{i{len(operands) - 1}}}")
                return f"{word}[{', '.join(parts)}]"
            if word in slots:
                operands.append(slots[word])
                depth = max(depth, level.get(word, 0))
                return f"{{w{len(operands) - 1}}}"
            return word

        shape_right = _TOKEN.sub(take, right)
        shape_left = _TOKEN.sub(take, left)
        level[left] = depth + 1
        groups.setdefault((depth, shape_left, shape_right), []).append(operands)
    if not groups:
        return []
    first = len(program.runs)
    used: dict[int, tuple[str, str]] = {}
    for (_, shape_left, shape_right), members in sorted(groups.items(), key=lambda item: item[0][0]):
        used[program.run((shape_left, shape_right), members)] = (shape_left, shape_right)
    count = {k: sum(1 for run in program.runs[first:] if run[0] == k) for k in used}
    runs = f"{program.name}_R"
    code = [f"for _k in range({first}, {len(program.runs)}):", f"    _s = {runs}[_k, 0]"]
    for position, k in enumerate(sorted(used, key=lambda k: (-count[k], k))):
        shape_left, shape_right = used[k]
        table = f"{program.name}_T{k}"
        width = len(program.rows[k][0])
        values = {f"w{j}": f"_w[{table}[_r, {j}]]" for j in range(width)} | {f"i{j}": f"{table}[_r, {j}]" for j in range(width)}
        code += [
            f"    {'if' if position == 0 else 'elif'} _s == {k}:",
            f"        for _r in range({runs}[_k, 1], {runs}[_k, 2]):",
            f"            {shape_left.format(**values)} = {shape_right.format(**values)}",
        ]
    return code


@dataclass(frozen=True)
class Block:
    """Straight-line code: assignments of common subexpressions, then the results."""

    lines: tuple[str, ...]
    results: tuple[str, ...]


class CodePrinter(PythonPrinter):
    """`PythonPrinter` with a map keyed by sympy symbols, for small sympy expressions (animate's
    positions): `module_imports["math"]` lists the `math` names used, as sympy's printers do."""

    def __init__(self, names: Mapping[sp.Symbol, str]) -> None:
        super().__init__({str(symbol): name for symbol, name in names.items()})

    @property
    def module_imports(self) -> dict[str, set[str]]:
        return {"math": set(self.imports())}


def cse_block(exprs: Sequence[sp.Expr], prefix: str, printer: Printer) -> Block:
    """Straight-line code computing the sympy expressions `exprs` (converted to symengine), CSE once,
    temporaries `_<prefix>0, ...`."""
    lines, results = printer.block([to_symengine(e) for e in exprs], f"_{prefix}")
    return Block(tuple(f"{name} = {code}" for name, code in lines), tuple(results))
