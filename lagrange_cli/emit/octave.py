"""Octave/MATLAB: a function file `eom.m` defining `dydt = eom(t, y, p)`, ready for `ode45`.

`lagrange derive FILE --to octave -o NAME.m` writes one function, named after the file (MATLAB's
rule; `eom` when written to stdout):

    function [dydt, h, lambda] = eom(t, y, p)

with y = [q; q_dot] (a column, as ode45 passes it), p the parameters as a vector in the file's
order (optional: without it, the file's defaults), dydt a column; on request also the energy
h = sum p_i q_dot_i - L and, with kept constraints, the multipliers lambda (index-1 form:
[[M, -A^T], [A, 0]] [q_ddot; lambda] = [F; -c]). The accelerations come from `\\`; a singular
matrix (reciprocal condition number of the row-scaled matrix below eps, since `\\` would quietly
give a least-squares answer) is the error `NAME:singular` naming t, a non-finite solution `NAME:nonfinite`. Arithmetic stays real: `realsqrt`,
`reallog` and `realpow` raise an error where the result would be complex (acos/asin out of
[-1, 1] are Octave's own, complex). The file is valid MATLAB: the function name matches the
file name, every block closes with `end`, and there are no Octave-only operators.

Safe with any system file: file text enters only `%` comments, as printable ASCII (others as
U+XXXX, line breaks as spaces); user names are mangled apart from MATLAB's and Octave's
keywords, the functions and constants the code calls, and the code's own variables.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

from lagrange_cli import __version__
from lagrange_cli._symengine import to_symengine
from lagrange_cli.algebra import check_solvable
from lagrange_cli.emit.common import printable, require_defined, written_definitions
from lagrange_cli.emit.printer import ATOM, Code, Printer, restructure
from lagrange_cli.emit.python import mangle, needed
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

KEYWORDS = frozenset(
    {
        *("break", "case", "catch", "classdef", "continue", "else", "elseif", "end", "for", "function", "global", "if", "otherwise", "parfor"),
        *("persistent", "return", "spmd", "switch", "try", "while", "do", "until", "unwind_protect", "unwind_protect_cleanup", "end_try_catch"),
        *("endfor", "endfunction", "endif", "endswitch", "endwhile", "end_unwind_protect", "methods", "properties", "events", "enumeration"),
        *("endclassdef", "endenumeration", "endevents", "endmethods", "endparfor", "endproperties", "endspmd", "arguments", "__FILE__", "__LINE__"),
    }
)
"""MATLAB's and Octave's keywords."""
BUILTINS = frozenset(
    {
        *("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp", "log", "sqrt", "abs", "sign", "realsqrt"),
        *("reallog", "realpow", "power", "mpower", "cot", "sec", "csc", "zeros", "ones", "isfinite", "all", "any", "error", "nargin", "nargout"),
        *("rcond", "max", "min", "numel", "pi", "e", "Inf", "inf", "NaN", "nan", "NA", "eps", "i", "j", "I", "J", "true", "false", "ans", "end", "varargin", "varargout"),
        *("disp", "size", "length", "reshape", "double", "isempty", "ode45", "exist", "mfilename", "feval", "eval", "evalin", "assignin", "clear"),
        *("who", "whos", "load", "save", "system", "input", "keyboard", "exit", "quit", "format", "more", "warning", "lasterr", "nthargout"),
    }
)
"""Functions and constants: the ones the generated code calls, and ones a reader would not expect a variable to hide."""
LOCALS = ("t", "y", "p", "dydt", "h", "lambda", "M", "b", "x", "r")
"""The generated function's arguments, outputs and variables."""
IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,62}")
"""A MATLAB identifier (at most 63 characters, `namelengthmax`)."""


class OctavePrinter(Printer):
    """Octave/MATLAB on scalars: `^` for integer powers; realsqrt, reallog and realpow, which raise
    an error instead of going complex; sign and abs as they are; Inf and NaN."""

    functions: ClassVar[Mapping[str, str]] = {**Printer.functions, "Abs": "abs", "sqrt": "realsqrt", "log": "reallog", "pow": "realpow", "sign": "sign"}
    power_operator: ClassVar[str | None] = "^"

    def nonfinite(self, value: float) -> Code:
        return ("NaN" if math.isnan(value) else "Inf"), ATOM

    def power(self, base: Any, exponent: Any) -> Code:
        return self.call("realpow", [self.doprint(base), self.doprint(exponent)])

    def _print_sign(self, expr: Any) -> Code:
        return self.call("sign", [self.doprint(expr.args[0])])


def octave_names(model: Model, function: str, momenta: Sequence[str] = (), local: Sequence[str] = LOCALS) -> dict[str, str]:
    """symbol name -> Octave identifier (`mangle`) for the coordinates, velocities, parameters (and
    `momenta`), apart from the function's `local` variables; and t."""
    symbols = [str(s) for s in (*model.q, *model.qd, *(p.symbol for p in model.parameters), *(i.symbol for i in model.inputs))] + list(momenta)
    names = mangle(symbols, {*KEYWORDS, *BUILTINS, *local, function, *("u" for _ in model.inputs[:1])})
    long = [n for n in names.values() if len(n) > 63]
    if long:
        shown = printable(long[0])
        shown = shown if len(shown) <= 80 else shown[:77] + "..."
        raise DerivationError(f"{model.source}: the name '{shown}' is longer than 63 characters, the most MATLAB allows in an identifier")
    return {**names, str(model.t): "t"}


def comment(text: str) -> str:
    """`text` for a `%` comment: printable ASCII (others as U+XXXX, line breaks as spaces)."""
    return "".join(c if " " <= c <= "~" else f"U+{ord(c):04X}" for c in printable(text))


def emit(model: Model, *, name: str = "eom") -> str:
    """The function file's text; `name` is the function's (and so the file's) name."""
    if not IDENTIFIER.fullmatch(name) or name in KEYWORDS:
        raise DerivationError(f"'{printable(name)}' is not a MATLAB function name")
    definitions = model.definitions
    model = model.with_definitions()
    require_defined(model, "Octave code")
    check_solvable(model)
    return _Writer(model, name, definitions).file()


class _Writer:
    def __init__(self, model: Model, name: str, definitions: Mapping[str, Any], momenta: Sequence[str] = (), local: Sequence[str] = LOCALS) -> None:
        self.model = model
        self.name = name
        self.definitions = definitions
        self.names = octave_names(model, name, momenta, local)
        self.taken = {*KEYWORDS, *BUILTINS, *local, name, *self.names.values()}
        self.constants = frozenset([*(p.name for p in model.parameters), *(i.name for i in model.inputs)])
        self.velocities = frozenset(str(v) for v in model.qd)
        n = model.n
        self.upper = [(i, j) for i in range(n) for j in range(i, n)]
        self.index = {str(s): f"y({i + 1})" for i, s in enumerate((*model.q, *model.qd))}
        self.index |= {p.name: f"p({i + 1})" for i, p in enumerate(model.parameters)}
        self.index |= {u.name: f"u({i + 1})" for i, u in enumerate(model.inputs)}  # inputs: an argument u after p (FORMAT.md version 2)

    def notes(self) -> list[str]:
        """The help text's lines on parameters without defaults, functions written out and names changed."""
        model, lines = self.model, []
        missing = [p.name for p in model.parameters if p.value is None]
        if missing:
            lines.append(f"  Parameters without a default (NaN unless given in p): {', '.join(missing)}.")
        if self.definitions:
            lines.append("  " + written_definitions(self.definitions))
        renamed = {c: v for c, v in self.names.items() if c != v and c != str(model.t)}
        if renamed:
            lines.append("  Names changed to MATLAB identifiers: " + ", ".join(f"{c} -> {v}" for c, v in renamed.items()) + ".")
        return lines

    def block(self, exprs: list[Any], prefix: str) -> tuple[list[str], list[str]]:
        """Assignments computing `exprs` and their result codes: the printer core's restructuring
        (sin/cos of each angle once, differences as products, collected coefficients) and CSE,
        its temporaries renamed to `<prefix>0, <prefix>1, ...` (a MATLAB name cannot start with
        `_`) apart from every name taken, keeping only the lines the results need."""
        printer = OctavePrinter(self.names)
        definitions, reduced = restructure(exprs, self.constants, self.velocities)
        lines: list[tuple[str, str]] = []
        counter = 0
        for name, value in definitions:
            while f"{prefix}{counter}" in self.taken:
                counter += 1
            fresh = f"{prefix}{counter}"
            self.taken.add(fresh)
            printer.names[name] = fresh  # printed under its new name: no xreplace, which would unshare a big DAG for the CSE
            lines.append((fresh, printer.doprint(value)))
        temporaries, results = printer.block(reduced, prefix, self.taken | {name for name, _ in definitions})
        self.taken |= {name for name, _ in temporaries}
        return [f"{name} = {code};" for name, code in needed(lines + temporaries, results)], results

    def body(self) -> list[str]:
        model, n, k = self.model, self.model.n, len(self.model.constraints)
        forms = model.symengine
        mass = [forms.mass[i][j] for i, j in self.upper]
        jacobian = [to_symengine(a) for c in model.constraints for a in c.jacobian]
        bias = [to_symengine(c.acceleration_bias) for c in model.constraints]
        exprs = [*mass, *forms.forcing, *jacobian, *bias]
        used = {str(s) for e in [*exprs, forms.energy] for s in e.free_symbols}
        lines = [f"{self.names[s]} = {self.index[s]};" for s in self.index if s in used]
        temporaries, results = self.block(exprs, "c")
        lines += temporaries
        cell = dict(zip(self.upper, results[: len(mass)], strict=True))
        rest = results[len(mass) :]
        force, a, c = rest[:n], rest[n : n + n * k], rest[n + n * k :]
        size = n + k
        lines.append(f"M = zeros({size}, {size});")
        for i, j in self.upper:
            if cell[(i, j)] != "0":
                lines.append(f"M({i + 1}, {j + 1}) = {cell[(i, j)]};")
                if i != j:
                    lines.append(f"M({j + 1}, {i + 1}) = M({i + 1}, {j + 1});")
        for r in range(k):
            for j in range(n):
                if a[r * n + j] != "0":
                    lines.append(f"M({n + r + 1}, {j + 1}) = {a[r * n + j]};")
                    lines.append(f"M({j + 1}, {n + r + 1}) = -M({n + r + 1}, {j + 1});")
        entries = [*force, *(f"-({v})" if not re.fullmatch(r"[A-Za-z0-9_.]+", v) else f"-{v}" for v in c)]
        lines.append(f"b = [{'; '.join(entries)}];")
        lines += [
            "r = rcond(M ./ max(abs(M), [], 2));",
            "if ~(r >= eps)",
            f"  error('{self.name}:singular', 'the mass matrix is singular at t = %g (reciprocal condition number %g)', t, r);",
            "end",
            "x = M \\ b;",
            "if ~all(isfinite(x))",
            f"  error('{self.name}:nonfinite', 'the accelerations are not finite at t = %g', t);",
            "end",
            f"dydt = [y({n + 1}:{2 * n}); x(1:{n})];",
            "if nargout > 1",
        ]
        energy_lines, energy = self.block([forms.energy], "e")
        lines += [f"  {line}" for line in energy_lines]
        lines += [f"  h = {energy[0]};", f"  lambda = x({n + 1}:end);", "end"]
        return lines

    def file(self) -> str:
        model, n = self.model, self.model.n
        t = "" if model.autonomous else ", t"
        state = "; ".join([*model.coordinates, *(str(v) for v in model.qd)])
        parameters = ", ".join(p.name for p in model.parameters)
        defaults = ", ".join(_number(p.value) for p in model.parameters)
        help_lines = [
            f"{self.name.upper()}  {model.title}: equations of motion generated by lagrange {__version__} from {Path(model.source).name}.",
            f"  dydt = {self.name}(t, y) with the file's parameters, or {self.name}(t, y, p) with p = [{parameters}].",
            f"  y = [q; q_dot] = [{state}] ({2 * n} values); M(q{t}) q_ddot = F(q, q_dot{t})" + (" + A^T lambda." if model.constraints else "."),
            f"  [dydt, h, lambda] = {self.name}(t, y, p) also gives the energy h = sum p_i q_dot_i - L and the multipliers"
            + (f" ({', '.join(map(str, model.multipliers))})." if model.constraints else " (none here: no kept constraints)."),
            f"  Example: [tt, yy] = ode45(@{self.name}, [0 10], y0, odeset('RelTol', 1e-8, 'AbsTol', 1e-10));",
        ]
        help_lines += self.notes()
        arguments = "t, y, p, u" if model.inputs else "t, y, p"
        if model.inputs:
            help_lines.append(f"  Inputs u = [{', '.join(i.name for i in model.inputs)}] after p: {self.name}(t, y, p, u) (default [{', '.join(_number(i.value) for i in model.inputs)}]).")
        lines = [f"function [dydt, h, lambda] = {self.name}({arguments})", *(f"% {comment(line)}".rstrip() for line in help_lines)]
        lines += ["  if nargin < 3 || isempty(p)", f"    p = [{defaults}];", "  end"] if model.inputs else ["  if nargin < 3", f"    p = [{defaults}];", "  end"]
        if model.inputs:
            lines += ["  if nargin < 4", f"    u = [{', '.join(_number(i.value) for i in model.inputs)}];", "  end"]
        lines += [f"  {line}" for line in self.body()]
        lines.append("end")
        return "\n".join(lines) + "\n"


# -- --form hamilton ----------------------------------------------------------------------------------

HAMILTON_LOCALS = ("t", "y", "p", "dydt", "H", "qdot", "M", "b", "r")
"""The Hamilton function's arguments, outputs and variables."""


def emit_hamilton(model: Model, *, name: str = "eom") -> str:
    """`derive --to octave --form hamilton`: `function [dydt, H, qdot] = NAME(t, y, p)` (`NAME(t, y, p, u)` with inputs) for y = [q; p]
    (coordinates and momenta p = M q_dot + b), dydt = [dH/dp; -dH/dq + Q] (lagrange_cli/hamilton.py;
    its refusals are its own). q_dot = M \\ (p - b) is solved numerically at each call (never a symbolic
    inverse), with the same singularity check as the Lagrange form; p_dot = dL/dq + Q - dR/dq_dot at that
    q_dot; H = p . q_dot - L on request."""
    from lagrange_cli.hamilton import hamilton

    if not IDENTIFIER.fullmatch(name) or name in KEYWORDS:
        raise DerivationError(f"'{printable(name)}' is not a MATLAB function name")
    definitions = model.definitions
    model = model.with_definitions()
    require_defined(model, "Octave code")
    ham = hamilton(model, symbolic=False)
    check_solvable(model)
    return _HamiltonWriter(model, name, definitions, ham.p, ham.bias, ham.rates).file()


class _HamiltonWriter(_Writer):
    def __init__(self, model: Model, name: str, definitions: Mapping[str, Any], momenta: Sequence[Any], bias: Sequence[Any], rates: Sequence[Any]) -> None:
        super().__init__(model, name, definitions, [str(m) for m in momenta], HAMILTON_LOCALS)
        n = model.n
        self.momenta = list(momenta)
        self.index = {str(s): f"y({i + 1})" for i, s in enumerate((*model.q, *momenta))}
        self.index |= {p.name: f"p({i + 1})" for i, p in enumerate(model.parameters)}
        self.index |= {u.name: f"u({i + 1})" for i, u in enumerate(model.inputs)}  # inputs: given values, an argument u after p
        self.shifted = [to_symengine(m - b) for m, b in zip(momenta, bias, strict=True)]
        self.rates = [to_symengine(r) for r in rates]
        self.energy = to_symengine(sum((m * v for m, v in zip(momenta, model.qd, strict=True)), -model.lagrangian))
        self.mass = [model.symengine.mass[i][j] for i, j in self.upper]
        assert len(self.shifted) == n

    def body(self) -> list[str]:
        model, n = self.model, self.model.n
        exprs = [*self.mass, *self.shifted]
        used = {str(s) for e in [*exprs, *self.rates, self.energy] for s in e.free_symbols}
        lines = [f"{self.names[s]} = {self.index[s]};" for s in self.index if s in used]
        temporaries, results = self.block(exprs, "c")
        lines += temporaries
        cell = dict(zip(self.upper, results[: len(self.mass)], strict=True))
        lines += _symmetric("M", n, cell)
        lines.append(f"b = [{'; '.join(results[len(self.mass) :])}];")
        lines += [
            "r = rcond(M ./ max(abs(M), [], 2));",
            "if ~(r >= eps)",
            f"  error('{self.name}:singular', 'the mass matrix is singular at t = %g (reciprocal condition number %g)', t, r);",
            "end",
            "qdot = M \\ b;",
            "if ~all(isfinite(qdot))",
            f"  error('{self.name}:nonfinite', 'the velocities are not finite at t = %g', t);",
            "end",
        ]
        later = {str(s) for e in [*self.rates, self.energy] for s in e.free_symbols}
        lines += [f"{self.names[str(v)]} = qdot({i + 1});" for i, v in enumerate(model.qd) if str(v) in later]
        rate_lines, rates = self.block(self.rates, "d")
        lines += rate_lines
        lines.append(f"dydt = [qdot; {'; '.join(rates)}];")
        energy_lines, energy = self.block([self.energy], "e")
        lines += ["if nargout > 1", *(f"  {line}" for line in energy_lines), f"  H = {energy[0]};", "end"]
        return lines

    def file(self) -> str:
        model, n = self.model, self.model.n
        state = "; ".join([*model.coordinates, *(str(m) for m in self.momenta)])
        parameters = ", ".join(p.name for p in model.parameters)
        defaults = ", ".join(_number(p.value) for p in model.parameters)
        help_lines = [
            f"{self.name.upper()}  {model.title}: Hamilton's equations generated by lagrange {__version__} from {Path(model.source).name}.",
            f"  dydt = {self.name}(t, y) with the file's parameters, or {self.name}(t, y, p) with p = [{parameters}].",
            f"  y = [q; p] = [{state}] ({2 * n} values): the coordinates and their momenta p = dL/dq_dot = M q_dot + b (not the velocities).",
            f"  dydt = [dH/dp; -dH/dq + Q]; [dydt, H, qdot] = {self.name}(t, y, p) also gives H = p . q_dot - L and the velocities.",
            "  q_dot = M \\ (p - b) is solved numerically at each call (no symbolic inverse).",
            f"  Example: [tt, yy] = ode45(@{self.name}, [0 10], y0, odeset('RelTol', 1e-8, 'AbsTol', 1e-10));",
        ]
        help_lines += self.notes()
        if model.inputs:
            help_lines.append(
                f"  Inputs u = [{', '.join(i.name for i in model.inputs)}] after p, given values at t: {self.name}(t, y, p, u) (default [{', '.join(_number(i.value) for i in model.inputs)}])."
            )
        arguments = "t, y, p, u" if model.inputs else "t, y, p"
        lines = [f"function [dydt, H, qdot] = {self.name}({arguments})", *(f"% {comment(line)}".rstrip() for line in help_lines)]
        lines += ["  if nargin < 3 || isempty(p)", f"    p = [{defaults}];", "  end"] if model.inputs else ["  if nargin < 3", f"    p = [{defaults}];", "  end"]
        if model.inputs:
            lines += ["  if nargin < 4", f"    u = [{', '.join(_number(i.value) for i in model.inputs)}];", "  end"]
        lines += [f"  {line}" for line in self.body()]
        lines.append("end")
        return "\n".join(lines) + "\n"


def _symmetric(name: str, size: int, cell: Mapping[tuple[int, int], str]) -> list[str]:
    """`name = zeros(size, size)` and the nonzero entries of a symmetric matrix from its upper triangle
    `cell[(i, j)]` (i <= j, in the order given), each lower entry copied from its mirror."""
    lines = [f"{name} = zeros({size}, {size});"]
    for (i, j), value in cell.items():
        if value != "0":
            lines.append(f"{name}({i + 1}, {j + 1}) = {value};")
            if i != j:
                lines.append(f"{name}({j + 1}, {i + 1}) = {name}({i + 1}, {j + 1});")
    return lines


def _number(value: float | None) -> str:
    if value is None or math.isnan(value):
        return "NaN"
    if math.isinf(value):
        return "Inf" if value > 0 else "-Inf"
    return repr(float(value))


# -- --form reduced -----------------------------------------------------------------------------------

REDUCED_LOCALS = ("t", "y", "p", "dydt", "qdot", "Mr", "Fr", "r", "x")
"""The reduced function's arguments, outputs and variables (`u`, the inputs' argument, is reserved with inputs)."""


def emit_reduced(model: Model, *, name: str = "eom") -> str:
    """`derive --to octave --form reduced`: `function [dydt, qdot, Mr, Fr] = NAME(t, y, p)` (`NAME(t, y, p, u)`
    with inputs) for the reduced state y = [q; u], u the independent velocities (Maggi's equations,
    lagrange_cli/reduced.py; its refusals are its own). dydt = [qdot; u_dot] with qdot = C u + d every
    velocity and u_dot from (C^T M C) u_dot = C^T (F - M e), solved by `\\` with the Lagrange form's
    singularity check (`NAME:singular`, `NAME:nonfinite`); Mr = C^T M C and Fr = C^T (F - M e) on request."""
    from lagrange_cli.reduced import reduced

    if not IDENTIFIER.fullmatch(name) or name in KEYWORDS:
        raise DerivationError(f"'{printable(name)}' is not a MATLAB function name")
    definitions = model.definitions
    model = model.with_definitions()
    require_defined(model, "Octave code")
    return _ReducedWriter(model, name, definitions, reduced(model)).file()


class _ReducedWriter(_Writer):
    def __init__(self, model: Model, name: str, definitions: Mapping[str, Any], red: Any) -> None:
        super().__init__(model, name, definitions, (), REDUCED_LOCALS)
        self.red = red
        n, k = model.n, len(red.independent)
        self.index = {str(q): f"y({i + 1})" for i, q in enumerate(model.q)}
        self.index |= {str(v): f"y({n + j + 1})" for j, v in enumerate(red.u)}
        self.index |= {p.name: f"p({i + 1})" for i, p in enumerate(model.parameters)}
        self.index |= {u.name: f"u({i + 1})" for i, u in enumerate(model.inputs)}
        self.cells = [(i, j) for i in range(k) for j in range(i, k)]
        self.qdot = [to_symengine(v) for v in red.velocities]
        self.mass = [to_symengine(red.mass[i, j]) for i, j in self.cells]
        self.force = [to_symengine(f) for f in red.rhs]

    def body(self) -> list[str]:
        n, k = self.model.n, len(self.red.independent)
        exprs = [*self.qdot, *self.mass, *self.force]
        used = {str(s) for e in exprs for s in e.free_symbols}
        lines = [f"{self.names[s]} = {self.index[s]};" for s in self.index if s in used]
        temporaries, results = self.block(exprs, "c")
        lines += temporaries
        qdot, cell, force = results[:n], dict(zip(self.cells, results[n : n + len(self.cells)], strict=True)), results[n + len(self.cells) :]
        lines.append(f"qdot = [{'; '.join(qdot)}];")
        if not k:  # every velocity is dependent: nothing to solve
            return [*lines, "dydt = qdot;", "if nargout > 2", "  Mr = zeros(0, 0);", "  Fr = zeros(0, 1);", "end"]
        lines += _symmetric("Mr", k, cell)
        lines.append(f"Fr = [{'; '.join(force)}];")
        lines += [
            "r = rcond(Mr ./ max(abs(Mr), [], 2));",
            "if ~(r >= eps)",
            f"  error('{self.name}:singular', 'the reduced mass matrix C''*M*C is singular at t = %g (reciprocal condition number %g)', t, r);",
            "end",
            "x = Mr \\ Fr;",
            "dydt = [qdot; x];",
            "if ~all(isfinite(dydt))",
            f"  error('{self.name}:nonfinite', 'the velocities or accelerations are not finite at t = %g', t);",
            "end",
        ]
        return lines

    def file(self) -> str:
        model, red = self.model, self.red
        n, k = model.n, len(red.independent)
        state = "; ".join([*model.coordinates, *(str(v) for v in red.u)])
        parameters = ", ".join(p.name for p in model.parameters)
        defaults = ", ".join(_number(p.value) for p in model.parameters)
        picks = ", ".join(str(i + 1) for i in red.independent)
        help_lines = [
            f"{self.name.upper()}  {model.title}: reduced (Maggi) equations generated by lagrange {__version__} from {Path(model.source).name}.",
            f"  dydt = {self.name}(t, y) with the file's parameters, or {self.name}(t, y, p) with p = [{parameters}].",
            f"  y = [q; u] = [{state}] ({n + k} values): the coordinates and the independent velocities u (the multipliers are eliminated).",
            f"  {red.summary()}.",
            f"  [dydt, qdot, Mr, Fr] = {self.name}(t, y, p) also gives every velocity qdot = C u + d ({n} values) and the reduced",
            "  mass matrix Mr = C^T M C and forcing Fr = C^T (F - M e), with Mr u_dot = Fr.",
            f"  From a full velocity vector qdot (which satisfies the constraints), u = qdot([{picks}]).",
            f"  Example: [tt, yy] = ode45(@{self.name}, [0 10], y0, odeset('RelTol', 1e-8, 'AbsTol', 1e-10));",
        ]
        help_lines += self.notes()
        arguments = "t, y, p, u" if model.inputs else "t, y, p"
        if model.inputs:
            help_lines.append(
                f"  Inputs u = [{', '.join(i.name for i in model.inputs)}] after p, given values at t: {self.name}(t, y, p, u) (default [{', '.join(_number(i.value) for i in model.inputs)}])."
            )
        lines = [f"function [dydt, qdot, Mr, Fr] = {self.name}({arguments})", *(f"% {comment(line)}".rstrip() for line in help_lines)]
        lines += ["  if nargin < 3 || isempty(p)", f"    p = [{defaults}];", "  end"] if model.inputs else ["  if nargin < 3", f"    p = [{defaults}];", "  end"]
        if model.inputs:
            lines += ["  if nargin < 4", f"    u = [{', '.join(_number(i.value) for i in model.inputs)}];", "  end"]
        lines += [f"  {line}" for line in self.body()]
        lines.append("end")
        return "\n".join(lines) + "\n"
