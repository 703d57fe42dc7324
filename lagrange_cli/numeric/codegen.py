"""Source code of a system's numeric functions, for numba (arrays in, arrays out) or plain Python.

Every function evaluates one piece of the model, its common subexpressions eliminated by the
same `cse_block` as the Python emitter:

- `accel`: x = [q_ddot; lambda] from the index-1 system [[M, -A^T], [A, 0]] x = [F; -c_s], where
  c_s = c + 2 alpha (A q_dot + b) + alpha^2 f (Baumgarte stabilisation of a holonomic f(q, t) = 0;
  c + alpha (A q_dot + b) for a velocity constraint), alpha being the extra parameter `_alpha`;
- `jac`: d(q_dot, q_ddot)/d(q, q_dot), from differentiating Aug(y) x = r(y) with x held fixed:
  Aug dx = d(r - Aug x) = dPhi, Phi = [F + A^T lambda - M q_ddot; -c_s - A q_ddot];
- `hamilton`: (q_dot, p_dot) at (q, p) for the symplectic integrator: M q_dot = p - p(q, 0, t),
  p_dot = dL/dq - dR/dq_dot + Q;
- `energy`, `momenta`, `residuals`, `event`: the monitored quantities and the stop condition.

Generated names start with `_`; user names are given identifiers by `emit.python.mangle`, which
keeps them apart from each other, from Python's keywords and builtins, from `math` and from the
few unprefixed names generated code uses (`t`, `float`, `numpy`, ...): no user name can clash.
File text reaches the code only through `emit.python.docstring`/`literal`. Arithmetic is real: a
non-integer power is `math.pow` (see emit/python.py), so the Python target raises ValueError,
ZeroDivisionError or OverflowError where a value is undefined, and the numba target (compiled
with error_model="numpy") gives NaN or inf, which the loops report as non-finite.
Functions the file defines (`functions: {U: {arguments: [s], definition: -k/s}}`) are written
out here, from `Model.with_definitions()`: the symbolic model keeps the general U(r).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import sympy as sp

from lagrange_cli._symengine import to_symengine
from lagrange_cli.emit.python import Block, CodePrinter, cse_block, define, python_names
from lagrange_cli.model import Model

ALPHA = sp.Symbol("_alpha")


@dataclass(frozen=True)
class Symbols:
    """The symbols of the generated code besides the model's: accelerations, multipliers, alpha."""

    acc: tuple[sp.Symbol, ...]
    lam: tuple[sp.Symbol, ...]


def parameter_names(model: Model) -> tuple[str, ...]:
    """The order of the parameter vector p: the model's parameters, then `_alpha` with constraints."""
    return tuple(p.name for p in model.parameters) + (("_alpha",) if model.constraints else ())


def ignorable(model: Model) -> tuple[int, ...]:
    """Indices of the ignorable coordinates, whose momenta are conserved (with the file's
    definitions written out, as in the generated `_momenta`)."""
    model = model.with_definitions()
    return tuple(i for i in range(model.n) if model.ignorable(i))


def stabilised_bias(model: Model) -> list[sp.Expr]:
    """c_s for each constraint row: c + 2 alpha (A q_dot + b) + alpha^2 f, or c + alpha (A q_dot + b)."""
    result = []
    for row in model.constraints:
        velocity = sum((a * v for a, v in zip(row.jacobian, model.qd, strict=True)), sp.Integer(0)) + row.bias
        extra = 2 * ALPHA * velocity + ALPHA**2 * row.expr if row.holonomic else ALPHA * velocity
        result.append(row.acceleration_bias + extra)
    return result


def real_diff(expr: sp.Expr, variable: sp.Symbol) -> sp.Expr:
    """d expr / d variable for real quantities (by symengine): d|u| = sign(u) du, d sign(u) = 0
    (as derive.py takes them), never an unprintable Derivative(Abs(u), x)."""
    result = sp.sympify(to_symengine(expr).diff(to_symengine(variable)))
    if result.has(sp.Derivative):
        result = result.replace(
            lambda e: isinstance(e, sp.Derivative) and isinstance(e.expr, (sp.Abs, sp.sign)),
            lambda e: sp.sign(e.expr.args[0]) * sp.diff(e.expr.args[0], *e.variables) if isinstance(e.expr, sp.Abs) else sp.Integer(0),
        )
    return result


class Generator:
    """Writes the functions of one model, its defined functions written out, for one target ("numba" or "python")."""

    def __init__(self, model: Model, target: str) -> None:
        model = model.with_definitions()
        self.model, self.target = model, target
        n, k = model.n, len(model.constraints)
        self.n, self.k, self.size = n, k, n + k
        self.symbols = Symbols(tuple(sp.Symbol(f"_acc{i}") for i in range(n)), tuple(sp.Symbol(f"_lam{i}") for i in range(k)))
        names = python_names(model)
        names.update({s: str(s) for s in (*self.symbols.acc, *self.symbols.lam, ALPHA)})
        names.update({c.multiplier: f"_lam{i}" for i, c in enumerate(model.constraints)})
        names.update({qdd: f"_acc{i}" for i, qdd in enumerate(model.qdd)})
        self.printer = CodePrinter(names)
        self.prefixes = iter(f"c{i}_" for i in range(1000))
        self.upper = [(i, j) for i in range(n) for j in range(i, n)]

    # -- helpers --------------------------------------------------------------------------------

    def block(self, exprs: Sequence[sp.Expr]) -> Block:
        return cse_block(list(exprs), next(self.prefixes), self.printer)

    def unpack(self, exprs: Sequence[sp.Expr], state: str = "_y", velocities: bool = True) -> list[str]:
        """Bind the parameters and state variables that `exprs` use (p and y are vectors)."""
        used = set().union(*(e.free_symbols for e in exprs)) if exprs else set()
        names = self.printer.names
        lines = [f"{names[p.symbol]} = _p[{i}]" for i, p in enumerate(self.model.parameters) if p.symbol in used]
        if ALPHA in used:
            lines.append(f"_alpha = _p[{len(self.model.parameters)}]")
        variables = [*self.model.q, *(self.model.qd if velocities else ())]
        lines += [f"{names[v]} = {state}[{i}]" for i, v in enumerate(variables) if v in used]
        return lines

    def augmented(self) -> tuple[list[sp.Expr], list[tuple[int, int, int]]]:
        """The distinct entries of [[M, -A^T], [A, 0]] and where each goes: (index, row, col)."""
        model, n = self.model, self.n
        entries: list[sp.Expr] = [model.mass_matrix[i, j] for i, j in self.upper]
        places = [(e, i, j) for e, (i, j) in enumerate(self.upper)] + [(e, j, i) for e, (i, j) in enumerate(self.upper) if i != j]
        for r, row in enumerate(model.constraints):
            for j, a in enumerate(row.jacobian):
                places += [(len(entries), n + r, j), (-len(entries) - 1, j, n + r)]
                entries.append(a)
        return entries, places

    def fill(self, matrix: str, results: Sequence[str], places: Sequence[tuple[int, int, int]]) -> list[str]:
        """Assignments of a dense s x s matrix (numba: into `matrix`, zeroed first)."""
        lines = [f"{matrix}[:, :] = 0.0"]
        for e, i, j in places:
            value = results[e] if e >= 0 else f"-({results[-e - 1]})"
            lines.append(f"{matrix}[{i}, {j}] = {value}")
        return lines

    def python_matrix(self, results: Sequence[str], places: Sequence[tuple[int, int, int]]) -> str:
        cells = [["0.0"] * self.size for _ in range(self.size)]
        for e, i, j in places:
            cells[i][j] = results[e] if e >= 0 else f"-({results[-e - 1]})"
        return "[" + ", ".join("[" + ", ".join(row) + "]" for row in cells) + "]"

    # -- functions ------------------------------------------------------------------------------

    def accel(self) -> str:
        """x = [q_ddot; lambda] solving the augmented system."""
        entries, places = self.augmented()
        exprs = [*entries, *self.model.forcing, *(-c for c in stabilised_bias(self.model))]
        block = self.block(exprs)
        body = [*self.unpack(exprs), *block.lines]
        vector = list(block.results[len(entries) :])
        if self.target == "numba":
            body += self.fill("_a", block.results, places)
            body += [f"_x[{i}] = {v}" for i, v in enumerate(vector)]
            body.append("return _lu_solve(_a, _x)")
            return define("_accel", "t, _y, _p, _x, _a", "x = [q_ddot; lambda]; returns 1 when the matrix is singular.", body)
        body.append(f"return _solve({self.python_matrix(block.results, places)}, [{', '.join(vector)}])")
        return define("_accel", "t, _y, _p", "x = [q_ddot; lambda] (ZeroDivisionError when the matrix is singular).", body)

    def jac(self) -> str:
        """d(q_dot, q_ddot)/d(q, q_dot) by differentiating the augmented system (Python target)."""
        model, n = self.model, self.n
        entries, places = self.augmented()
        phi = self.residual()
        columns = [real_diff(f, v) for f in phi for v in (*model.q, *model.qd)]
        exprs = [*entries, *columns]
        block = self.block(exprs)
        unpack_x = [f"_acc{i} = _x[{i}]" for i in range(n)] + [f"_lam{r} = _x[{n + r}]" for r in range(self.k)]
        body = [*self.unpack(exprs), *unpack_x, *block.lines]
        d = block.results[len(entries) :]
        body.insert(0, "_x = _accel(t, _y, _p)")
        rows = "[" + ", ".join("[" + ", ".join(d[i * 2 * n : (i + 1) * 2 * n]) + "]" for i in range(self.size)) + "]"
        body += [f"_d = numpy.linalg.solve({self.python_matrix(block.results, places)}, {rows})", f"_j = numpy.zeros(({2 * n}, {2 * n}))"]
        body += [f"_j[:{n}, {n}:] = numpy.eye({n})", f"_j[{n}:, :] = _d[:{n}, :]", "return _j"]
        return define("_jac", "t, _y, _p", "The Jacobian of rhs.", body)

    def residual(self) -> list[sp.Expr]:
        """Phi = [F + A^T lambda - M q_ddot; -c_s - A q_ddot] with q_ddot, lambda as symbols."""
        model, acc, lam = self.model, self.symbols.acc, self.symbols.lam
        rows = []
        for i in range(self.n):
            value = model.forcing[i] - sum((model.mass_matrix[i, j] * acc[j] for j in range(self.n)), sp.Integer(0))
            rows.append(value + sum((c.jacobian[i] * lam[r] for r, c in enumerate(model.constraints)), sp.Integer(0)))
        for row, bias in zip(model.constraints, stabilised_bias(model), strict=True):
            rows.append(-bias - sum((a * acc[j] for j, a in enumerate(row.jacobian)), sp.Integer(0)))
        return rows

    def hamilton(self) -> str:
        """(q_dot, p_dot) at z = (q, p): M q_dot = p - p(q, 0, t), then p_dot = dL/dq - dR/dq_dot + Q."""
        model, n = self.model, self.n
        zero = dict.fromkeys(model.qd, sp.Integer(0))
        offsets = [sp.sympify(m).xreplace(zero) for m in model.momenta]
        mass = [model.mass_matrix[i, j] for i, j in self.upper]
        force = [real_diff(model.lagrangian, q) - real_diff(model.dissipation, qd) + model.generalized_forces[i] for i, (q, qd) in enumerate(zip(model.q, model.qd, strict=True))]
        first = self.block([*mass, *offsets])
        body = [*self.unpack([*mass, *offsets, *force], "_z", velocities=False), *first.lines]
        places = [(e, i, j) for e, (i, j) in enumerate(self.upper)] + [(e, j, i) for e, (i, j) in enumerate(self.upper) if i != j]
        body += self.fill("_a", first.results, places)
        body += [f"_x[{i}] = _z[{n + i}] - ({first.results[len(mass) + i]})" for i in range(n)]
        body.append("_status = _lu_solve(_a, _x)")
        second = self.block(force)
        used = set().union(*(f.free_symbols for f in force))
        body += [f"{self.printer.names[model.qd[i]]} = _x[{i}]" for i in range(n) if model.qd[i] in used]
        body += second.lines
        body += [f"_out[{i}] = _x[{i}]" for i in range(n)] + [f"_out[{n + i}] = {v}" for i, v in enumerate(second.results)]
        body.append("return _status")
        return define("_hamilton", "t, _z, _p, _out, _x, _a", "(q_dot, p_dot) at z = (q, p) into _out; returns 1 when M is singular.", body)

    def vector(self, name: str, doc: str, exprs: Sequence[sp.Expr]) -> str:
        """A function of (t, y, p) writing `exprs` into _out (numba) or returning them as a list."""
        exprs = list(exprs)
        block = self.block(exprs)
        body = [*self.unpack(exprs), *block.lines]
        if self.target == "numba":
            body += [f"_out[{i}] = {v}" for i, v in enumerate(block.results)] + ["return 0"]
            return define(name, "t, _y, _p, _out", doc, body)
        body.append(f"return [{', '.join(block.results)}]")
        return define(name, "t, _y, _p", doc, body)

    def scalar(self, name: str, doc: str, expr: sp.Expr, needs_accel: bool) -> str:
        """A scalar function of (t, y, p), solving for q_ddot and lambda first when it uses them."""
        block = self.block([expr])
        body = [*self.unpack([expr]), *block.lines, f"return float({block.results[0]})"]
        if needs_accel:
            n = self.n
            first = "_status = _accel(t, _y, _p, _x, _a)" if self.target == "numba" else "_x = _accel(t, _y, _p)"
            body = [first] + [f"_acc{i} = _x[{i}]" for i in range(n)] + [f"_lam{r} = _x[{n + r}]" for r in range(self.k)] + body
        signature = "t, _y, _p, _x, _a" if self.target == "numba" else "t, _y, _p"
        return define(name, signature, doc, body)

    def module(self, jacobian: bool, event: sp.Expr | None) -> str:
        """The functions a target needs, the constants _N, _K, _SIZE, and the `math` imports.

        numba: `_accel`, `_hamilton` (unconstrained systems) and `_event`, which the compiled
        loops call; Python: `_accel` (and `_jac`) for scipy, and the monitored quantities."""
        model = self.model
        uses_accel = event is not None and bool(event.free_symbols & {*model.qdd, *model.multipliers})
        stop = self.scalar("_event", "The stop condition, whose sign change ends the run.", event if event is not None else sp.Float(1.0), uses_accel)
        parts = [self.accel()]
        if self.target == "numba":
            parts += [self.hamilton()] if not model.constraints else []
        else:
            parts += [self.jac()] if jacobian else []
            parts += [
                self.scalar("_energy", "The energy function h = sum p q_dot - L.", model.energy, False),
                self.vector("_momenta", "The momenta of the ignorable coordinates.", [model.momenta[i] for i in ignorable(model)] or [sp.Integer(0)]),
                self.vector("_residuals", "Each kept constraint's residual.", [c.expr for c in model.constraints] or [sp.Integer(0)]),
                self.vector("_canonical", "The momenta p = dL/dq_dot of every coordinate.", model.momenta),
            ]
        parts.append(stop)
        math_names = sorted(self.printer.module_imports.get("math", set()))
        header = [f"_N = {self.n}", f"_K = {self.k}", f"_SIZE = {self.size}"]
        if math_names:
            header.insert(0, f"from math import {', '.join(math_names)}")
        return "\n".join(header) + "\n\n\n" + "\n\n\n".join(parts) + "\n"


def source(model: Model, target: str, jacobian: bool = False, event: sp.Expr | None = None) -> str:
    """The generated functions of `model` for `target` ("numba" or "python")."""
    return Generator(model, target).module(jacobian, event)
