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
import keyword
import math
import re
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from lagrange_cli import __version__
from lagrange_cli._symengine import se, to_symengine
from lagrange_cli.algebra import check_invertible
from lagrange_cli.emit.common import require_defined
from lagrange_cli.emit.printer import ATOM, Code, Printer
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

# Above this many unknowns the linear solve is numpy's; below, straight-line Python is faster.
NUMPY_SIZE = 9
GENERATED = frozenset(
    {
        *("t", "y", "p", "q", "q_dot", "math", "numpy", "numba", "njit", "tolist", "hasattr", "float", "abs", "pow", "copysign", "inf", "nan"),
        *("COORDINATES", "PARAMETERS", "mass_matrix", "forcing", "energy", "rhs", "accelerations", "multipliers", "constraint_residuals"),
    }
)
"""Names without a leading `_` that generated code uses: arguments, modules, public functions."""
RESERVED = frozenset({*keyword.kwlist, *keyword.softkwlist, *dir(builtins), *dir(math), *GENERATED})
"""What no user symbol may be called in generated Python (besides any name starting with `_`)."""
AMBIGUOUS = frozenset({"l", "I", "O"})
MATH_NAMES = frozenset(dir(math))


class CodePrinter(PythonCodePrinter):
    """Bare `math` names (recorded in `module_imports`), symbols by a fixed name map, constants as literals."""

    def __init__(self, names: dict[sp.Symbol, str]) -> None:
        super().__init__({"fully_qualified_modules": False, "strict": True})
        self.names = names

    def _print_Symbol(self, expr: sp.Symbol) -> str:
        if expr not in self.names:
            raise DerivationError(f"cannot write code for the symbol '{literal(str(expr))[1:-1]}', which is not a coordinate, velocity, parameter or t")
        return self.names[expr]

    def _print_ImaginaryUnit(self, expr: sp.Expr) -> str:
        raise DerivationError("the equations contain the imaginary unit; generated code computes with real numbers only")

    def _print_Integer(self, expr: sp.Integer) -> str:
        """Exact below 2**53; larger integers as floats (numba has no big integers)."""
        return str(expr.p) if abs(expr.p) < 2**53 else self._float(expr)

    def _print_Rational(self, expr: sp.Rational) -> str:
        return str(super()._print_Rational(expr)) if max(abs(expr.p), expr.q) < 2**53 else self._float(expr)

    def _float(self, expr: sp.Expr) -> str:
        value = float(expr)
        return repr(value) if math.isfinite(value) else ("-" if value < 0 else "") + self._module_format("math.inf")

    def _print_Pi(self, expr: sp.Expr) -> str:
        return repr(math.pi)

    def _print_Exp1(self, expr: sp.Expr) -> str:
        return repr(math.e)

    def _print_Pow(self, expr: sp.Pow, rational: bool = False) -> str:
        """`x*x` for squares, `**` for other integer powers, sqrt(x) and 1/sqrt(x), and
        math.pow otherwise: real powers, a ValueError for a negative base where `**` would
        silently give a complex number."""
        if _squared(expr):
            b = self._print(expr.base)
            return f"{b}*{b}"
        if expr.exp.is_Integer or expr.exp in (sp.S.Half, -sp.S.Half):
            return str(super()._print_Pow(expr, rational))
        return f"{self._module_format('math.pow')}({self._print(expr.base)}, {self._print(expr.exp)})"

    def _print_Mul(self, expr: sp.Mul) -> str:
        """sympy's, except that a lone divisor printed as a product is parenthesized: `k/(r*r)`, not `k/r*r`."""
        text = str(super()._print_Mul(expr))
        below = [f for f in expr.args if f.is_Pow and f.exp.is_Rational and f.exp.is_negative]
        if len(below) == 1 and _squared(1 / below[0]):
            square = self._print(1 / below[0])
            if text.endswith("/" + square):
                text = f"{text[: -len(square)]}({square})"
        return text


@dataclass(frozen=True)
class Block:
    """Straight-line code: assignments of common subexpressions, then the results."""

    lines: tuple[str, ...]
    results: tuple[str, ...]


def cse_block(exprs: Sequence[sp.Expr], prefix: str, printer: CodePrinter) -> Block:
    """Straight-line code computing `exprs`: CSE by symengine on renamed symbols (so that its
    x0, x1 cannot clash with the user's names), temporaries `_<prefix>0, ...` added to
    `printer.names`. Shared with the numeric package, which compiles the same code."""
    free = sorted(set().union(*(e.free_symbols for e in exprs)), key=str) if exprs else []
    safe = {to_symengine(s): se.Symbol(f"_s{i}") for i, s in enumerate(free)}
    back = {v: s for s, v in zip(free, safe.values(), strict=True)}
    converted = [to_symengine(e).xreplace(safe) if e.free_symbols else to_symengine(e) for e in exprs]
    replacements, reduced = se.cse(converted)
    temporaries = {lhs: sp.Symbol(f"_{prefix}{i}") for i, (lhs, _) in enumerate(replacements)}
    mapping = {**back, **temporaries}
    for symbol in temporaries.values():
        printer.names[symbol] = str(symbol)

    renames = {sp.sympify(a): b for a, b in mapping.items()}

    def convert(e: se.Basic) -> sp.Expr:
        return sp.sympify(e).xreplace(renames)

    lines = tuple(f"{temporaries[lhs]} = {printer.doprint(convert(rhs))}" for lhs, rhs in replacements)
    return Block(lines, tuple(printer.doprint(convert(e)) for e in reduced))


def emit(model: Model, numba: bool = False) -> str:
    """The module's source; with `numba=True` its rhs is compiled by numba (cached on disk).
    The file's function definitions are written out (`Model.with_definitions`)."""
    definitions = model.definitions
    model = model.with_definitions()
    require_defined(model, "Python code")
    check_invertible(model)
    return _Writer(model, numba, definitions).module()


class _Writer:
    def __init__(self, model: Model, numba: bool = False, definitions: Mapping[str, sp.Lambda] | None = None) -> None:
        self.model = model
        self.definitions = definitions or {}
        self.numba = numba
        self.names = python_names(model)
        self.printer = CodePrinter(self.names)
        self.uses_numpy = False
        self.uses_solve = False
        n, k = model.n, len(model.constraints)
        self.size = n + k
        self.upper = [(i, j) for i in range(n) for j in range(i, n)]

    # -- pieces ---------------------------------------------------------------------------------

    def block(self, exprs: Sequence[sp.Expr], prefix: str) -> Block:
        return cse_block(exprs, prefix, self.printer)

    def unpack(self, exprs: Sequence[sp.Expr], state: str) -> list[str]:
        """Lines binding the parameters used, then the coordinates/velocities from `state`."""
        used = set().union(*(e.free_symbols for e in exprs)) if exprs else set()
        lines = []
        for parameter in self.model.parameters:
            if parameter.symbol in used:
                lines.append(f"{self.names[parameter.symbol]} = p[{literal(parameter.name)}]" + _noqa(self.names[parameter.symbol]))
        groups = [("y", [*self.model.q, *self.model.qd])] if state == "y" else [(g, v) for g, v in (("q", self.model.q), ("q_dot", self.model.qd)) if g in state.split(",")]
        for group, variables in groups:
            keep = [v in used or (group == "y" and v in self.model.qd) for v in variables]
            if any(keep):
                targets = [self.names[v] if k else "_" for v, k in zip(variables, keep, strict=True)]
                source = f'{group}.tolist() if hasattr({group}, "tolist") else {group}' if group == "y" else group
                lines.append(f"{', '.join(targets)}{',' * (len(targets) == 1)} = {source}" + _noqa(*targets))
        return lines

    def signature(self, exprs: Sequence[sp.Expr], state: str) -> str:
        has_t = any(e.has(self.model.t) for e in exprs)
        return ", ".join(["t"] * has_t + state.split(",") + ["p=PARAMETERS"])

    def function(self, name: str, doc: str, exprs: Sequence[sp.Expr], state: str, shape: str) -> str:
        block = self.block(exprs, "c")
        body = [*self.unpack(exprs, state), *block.lines]
        results = list(block.results)
        if shape == "matrix":
            n = self.model.n
            cell = dict(zip(self.upper, results, strict=True))
            rows = ["[" + ", ".join(cell[(min(i, j), max(i, j))] for j in range(n)) + "]" for i in range(n)]
            body.append("return [" + ", ".join(rows) + "]")
        elif shape == "vector":
            body.append("return [" + ", ".join(results) + "]")
        else:
            body.append(f"return {results[0]}")
        return define(name, self.signature(exprs, state), doc, body)

    def rhs(self) -> str:
        model, n = self.model, self.model.n
        mass = [model.mass_matrix[i, j] for i, j in self.upper]
        force = list(model.forcing)
        rows = model.constraints
        extra = [-a for c in rows for a in c.jacobian] + [-c.acceleration_bias for c in rows]
        exprs = [*mass, *force, *extra]
        block = self.block(exprs, "c")
        m = dict(zip(self.upper, block.results[: len(mass)], strict=True))
        f = list(block.results[len(mass) : len(mass) + n])
        if self.numba:
            return self.compiled_rhs(exprs, block, m, f)
        body = [*self.unpack(exprs, "y"), *block.lines]
        velocities = [self.names[v] for v in model.qd]
        if rows or n > 2:
            body += [f"_m{i}_{j} = {code}" for (i, j), code in m.items() if not _simple(code)]
            m = {(i, j): code if _simple(code) else f"_m{i}_{j}" for (i, j), code in m.items()}
        if rows:
            a = block.results[len(mass) + n : len(mass) + n + n * len(rows)]
            c = block.results[len(mass) + n + n * len(rows) :]
            k = len(rows)
            matrix = [[m[(min(i, j), max(i, j))] for j in range(n)] + [a[r * n + i] for r in range(k)] for i in range(n)]
            matrix += [[_negate(a[r * n + j]) for j in range(n)] + ["0.0"] * k for r in range(k)]
            body += self.solve(matrix, [*f, *c], "_x")
            body.append("return _x")
            names = ", ".join(str(x) for x in model.multipliers)
            solver = define("accelerations", "t, y, p=PARAMETERS", f"[{', '.join(map(str, model.qdd))}, {names}] from [[M, -A^T], [A, 0]] x = [F, -c] (index-1 form).", body)
            rhs = define("rhs", "t, y, p=PARAMETERS", _rhs_doc(model), ["_x = accelerations(t, y, p)", f'return [*(y.tolist() if hasattr(y, "tolist") else y)[{n}:], *_x[:{n}]]'])
            multipliers = define("multipliers", "t, y, p=PARAMETERS", f"The multipliers [{names}]; A^T lambda is the generalized constraint force.", [f"return accelerations(t, y, p)[{n}:]"])
            return "\n\n\n".join([solver, rhs, multipliers])
        if n == 1:
            body.append(f"return [{velocities[0]}, ({f[0]})/({m[(0, 0)]})]")
        elif n == 2:
            body += [f"_m00 = {m[(0, 0)]}", f"_m01 = {m[(0, 1)]}", f"_m11 = {m[(1, 1)]}", f"_f0 = {f[0]}", f"_f1 = {f[1]}", "_det = _m00*_m11 - _m01*_m01"]
            body.append(f"return [{velocities[0]}, {velocities[1]}, (_m11*_f0 - _m01*_f1)/_det, (_m00*_f1 - _m01*_f0)/_det]")
        else:
            matrix = [[m[(min(i, j), max(i, j))] for j in range(n)] for i in range(n)]
            body += self.solve(matrix, f, "_x")
            body.append(f"return [{', '.join(velocities)}, *_x]")
        return define("rhs", "t, y, p=PARAMETERS", _rhs_doc(model), body)

    def compiled_rhs(self, exprs: Sequence[sp.Expr], block: Block, m: dict[tuple[int, int], str], f: list[str]) -> str:
        """rhs as a thin wrapper around a numba kernel taking y as an array and the used
        parameters as scalars; the kernel fills [M, -A^T; A, 0] and solves with numpy."""
        model, n = self.model, self.model.n
        rows = model.constraints
        k = len(rows)
        used = set().union(*(e.free_symbols for e in exprs))
        parameters = [p for p in model.parameters if p.symbol in used]
        names = [self.names[p.symbol] for p in parameters]
        state = [*model.q, *model.qd]
        body = [f"{self.names[v]} = y[{i}]" + _noqa(self.names[v]) for i, v in enumerate(state) if v in used]
        body += list(block.lines)
        size = n + k
        body.append(f"_a = numpy.zeros(({size}, {size}))")
        body += [f"_a[{i}, {j}] = {m[(i, j)]}" + (f"\n_a[{j}, {i}] = _a[{i}, {j}]" if i != j else "") for i, j in self.upper if m[(i, j)] != "0"]
        if rows:
            a = block.results[len(self.upper) + n : len(self.upper) + n + n * k]
            c = block.results[len(self.upper) + n + n * k :]
            for r in range(k):
                for j in range(n):
                    if a[r * n + j] != "0":
                        body += [f"_a[{j}, {n + r}] = {a[r * n + j]}", f"_a[{n + r}, {j}] = -_a[{j}, {n + r}]"]
            f = [*f, *c]
        body.append(f"_b = numpy.empty({size})")
        body += [f"_b[{i}] = {value}" for i, value in enumerate(f)]
        body += ["_x = numpy.linalg.solve(_a, _b)", f"_out = numpy.empty({2 * n})", f"_out[:{n}] = y[{n}:]", f"_out[{n}:] = _x[:{n}]", "return _out"]
        kernel = "@numba.njit(cache=True)\n" + define("_rhs", ", ".join(["t", "y", *names]), "The compiled right-hand side.", body).replace("\n_a[", "\n    _a[")
        arguments = ", ".join(["t", "numpy.asarray(y, dtype=numpy.float64)", *(f"p[{literal(p.name)}]" for p in parameters)])
        wrapper = define("rhs", "t, y, p=PARAMETERS", _rhs_doc(model) + " Compiled by numba; returns an array.", [f"return _rhs({arguments})"])
        self.uses_numpy = True
        return kernel + "\n\n\n" + wrapper

    def solve(self, matrix: list[list[str]], vector: list[str], target: str) -> list[str]:
        rows = "[" + ", ".join("[" + ", ".join(row) + "]" for row in matrix) + "]"
        if len(matrix) >= NUMPY_SIZE:
            self.uses_numpy = True
            n = len(matrix)
            flat = ", ".join(x for row in matrix for x in row)
            return [f"{target} = numpy.linalg.solve(numpy.fromiter(({flat}), float, {n * n}).reshape({n}, {n}), numpy.fromiter(({', '.join(vector)}), float, {n})).tolist()"]
        self.uses_solve = True
        return [f"{target} = _solve({rows}, [{', '.join(vector)}])"]

    def residuals(self) -> str:
        model = self.model
        exprs = [c.expr for c in model.constraints]
        return self.function("constraint_residuals", "Each constraint's residual: f(q, t) for holonomic ones, a . q_dot + b for velocity ones.", exprs, "q,q_dot", "vector")

    # -- the module -----------------------------------------------------------------------------

    def module(self) -> str:
        model = self.model
        functions = [
            self.function("mass_matrix", "The mass matrix M as a list of rows.", [model.mass_matrix[i, j] for i, j in self.upper], "q", "matrix"),
            self.function("forcing", "The forcing F of M q_ddot = F" + (" + A^T lambda" if model.constraints else "") + ".", list(model.forcing), "q,q_dot", "vector"),
            self.function("energy", "The energy function h = sum p_i q_dot_i - L.", [model.energy], "q,q_dot", "scalar"),
        ]
        if model.constraints:
            functions.append(self.residuals())
        functions.append(self.rhs())
        if self.uses_solve:
            functions.append(SOLVE)
        imports = []
        math_names = sorted(self.printer.module_imports.get("math", set()))
        if math_names:
            imports.append(f"from math import {', '.join(math_names)}")
        if self.numba:
            imports.append("import numba")
        if self.uses_numpy:
            imports.append("import numpy")
        parameters = ", ".join(f"{literal(p.name)}: {_number(p.value)}" for p in model.parameters if p.value is not None)
        missing = [p.name for p in model.parameters if p.value is None]
        header = [
            f"{model.title}: equations of motion generated by lagrange {__version__} from {Path(model.source).name}.",
            "",
            "M(q"
            + (", t" if not model.autonomous else "")
            + ") q_ddot = F(q, q_dot"
            + (", t" if not model.autonomous else "")
            + ")"
            + (" + A^T lambda" if model.constraints else "")
            + f", with y = [{', '.join(map(str, (*model.q, *model.qd)))}].",
        ]
        if self.definitions:
            written = "; ".join(f"{name}({', '.join(map(str, f.variables))}) = {sp.sstr(f.expr)}" for name, f in sorted(self.definitions.items()))
            header.append(f"Functions written out from their definitions in the file: {written}.")
        if missing:
            header.append(f"Parameters without a default, to be given in p: {', '.join(missing)}.")
        parts = [docstring("\n".join([*header, ""])), "\n".join(imports)] if imports else [docstring("\n".join([*header, ""]))]
        coordinates = ", ".join(literal(c) for c in model.coordinates)
        parts.append(f"COORDINATES = ({coordinates}{',' * (model.n == 1)})\nPARAMETERS = {{{parameters}}}")
        return "\n\n".join(parts) + "\n\n\n" + "\n\n\n".join(functions) + "\n"


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
    symbols = [*model.q, *model.qd, *(p.symbol for p in model.parameters)]
    names = mangle([str(s) for s in symbols])
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


def _squared(expr: sp.Expr) -> bool:
    """`x**2` of a name or a function call, which prints as `x*x`."""
    return isinstance(expr, sp.Pow) and expr.exp == 2 and bool(expr.base.is_Symbol or expr.base.is_Function)


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
