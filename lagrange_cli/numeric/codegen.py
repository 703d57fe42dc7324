"""Source code of a system's numeric functions, for numba (arrays in, arrays out) or plain Python.

Every function evaluates one piece of the model, printed from the symengine forms of the model
(`Model.symengine`: the sympy fields are never read for an unconstrained system without defined
functions, so a big system never pays their conversion) by the printer core, restructured and
with its common subexpressions eliminated by the same `code_lines` as the Python emitter. For
numba, a long function is cut into parts compiled one by one (`emit.python.split`):

- `accel`: x = [q_ddot; lambda] from the index-1 system [[M, -A^T], [A, 0]] x = [F; -c_s], where
  c_s = c + 2 alpha (A q_dot + b) + alpha^2 f (Baumgarte stabilisation of a holonomic f(q, t) = 0;
  c + alpha (A q_dot + b) for a velocity constraint), alpha being the extra parameter `_alpha`;
- `jac`: d(q_dot, q_ddot)/d(q, q_dot), from differentiating Aug(y) x = r(y) with x held fixed:
  Aug dx = d(r - Aug x) = dPhi, Phi = [F + A^T lambda - M q_ddot; -c_s - A q_ddot];
- `hamilton`: (q_dot, p_dot) at (q, p) for the symplectic integrator: M q_dot = p - p(q, 0, t),
  p_dot = dL/dq - dR/dq_dot + Q;
- `rows` (numba, kept constraints): f, A, b and M at the positions, and `energy` (numba too, kept
  constraints), for the projection inside the compiled loop (kernels.erk_projected);
- `switch` (only for a system whose equations have Abs, sign, Piecewise, Max or Min: switching.py):
  the switching functions g(t, y), whose zero crossings the integrators land on, and `_SWITCHES`;
- `energy`, `momenta`, `residuals`, `event`: the monitored quantities and the stop condition; a
  constraint's residual (its drift) is f(q, t) when holonomic and a(q, t) . q_dot + b(q, t) for a
  velocity constraint, whose `expr` is that expression (and so needs the velocities bound).

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
from typing import Any

import sympy as sp

from lagrange_cli._symengine import se, to_symengine
from lagrange_cli.emit import python as emit_python
from lagrange_cli.emit.python import PythonPrinter, Rows, code_lines, define, free_names, symbol_names, vectorize
from lagrange_cli.inputs import substitute
from lagrange_cli.model import Model
from lagrange_cli.numeric import switching

ALPHA = se.Symbol("_alpha")


@dataclass(frozen=True)
class Symbols:
    """The symbols of the generated code besides the model's: accelerations, multipliers, alpha."""

    acc: tuple[Any, ...]
    lam: tuple[Any, ...]


def parameter_names(model: Model) -> tuple[str, ...]:
    """The order of the parameter vector p: the model's parameters, then `_alpha` with constraints."""
    return tuple(p.name for p in model.parameters) + (("_alpha",) if model.constraints else ())


def ignorable(model: Model) -> tuple[int, ...]:
    """Indices of the ignorable coordinates, whose momenta are conserved (with the file's
    definitions written out, as in the generated `_momenta`): dL/dq_i = 0, dR/dq_dot_i = 0,
    Q_i = 0 and no constraint row along q_i (Model.ignorable, from the symengine forms), with the
    inputs as the run has them (`inputs.substitute`)."""
    model = substitute(model).with_definitions()
    forms, rows = model.symengine, Rows.of(model)
    return tuple(
        i
        for i in range(model.n)
        if forms.lagrangian.diff(forms.q[i]) == 0 and forms.dissipation.diff(forms.qd[i]) == 0 and forms.generalized_forces[i] == 0 and all(row[i] == 0 for row in rows.jacobian)
    )


def stabilised_bias(model: Model) -> list[Any]:
    """c_s for each constraint row: c + 2 alpha (A q_dot + b) + alpha^2 f, or c + alpha (A q_dot + b)."""
    forms, rows = model.symengine, Rows.of(model)
    result = []
    for r, row in enumerate(model.constraints):
        velocity = se.Add(*(a * v for a, v in zip(rows.jacobian[r], forms.qd, strict=True))) + rows.bias[r]
        extra = 2 * ALPHA * velocity + ALPHA**2 * rows.expr[r] if row.holonomic else ALPHA * velocity
        result.append(rows.acceleration_bias[r] + extra)
    return result


def real_diff(expr: Any, variable: Any) -> Any:
    """d expr / d variable for real quantities (by symengine): d|u| = sign(u) du, d sign(u) = 0
    (as derive.py takes them), never an unprintable Derivative(Abs(u), x) or Subs (the Jacobian of a
    force with |u|: the derivative of sign(u))."""
    result = expr.diff(variable)
    if not result.atoms(se.Derivative):
        return result
    converted = sp.sympify(result).replace(
        lambda e: isinstance(e, sp.Derivative) and isinstance(e.expr, (sp.Abs, sp.sign)),
        lambda e: sp.sign(e.expr.args[0]) * sp.diff(e.expr.args[0], *e.variables) if isinstance(e.expr, sp.Abs) else sp.Integer(0),
    )
    # symengine writes d f(u)/dx as Subs(Derivative(f(_xi), _xi), _xi, u) * du/dx (a second derivative of |u|: d sign(u)):
    # the Subs left once its derivative is taken, Subs(0, _xi, u) or Subs(sign(_xi), _xi, u), evaluated
    converted = converted.replace(lambda e: isinstance(e, sp.Subs), lambda e: e.doit())
    return to_symengine(converted)


class Generator:
    """Writes the functions of one model, its defined functions written out, for one target ("numba" or "python")."""

    def __init__(self, model: Model, target: str) -> None:
        model = substitute(model).with_definitions()  # inputs at their defaults unless the caller substituted them (`simulate --input`)
        self.model, self.target = model, target
        self.forms, self.rows = model.symengine, Rows.of(model)
        n, k = model.n, len(model.constraints)
        self.n, self.k, self.size = n, k, n + k
        self.symbols = Symbols(tuple(se.Symbol(f"_acc{i}") for i in range(n)), tuple(se.Symbol(f"_lam{i}") for i in range(k)))
        names = symbol_names(model)
        names.update({str(s): str(s) for s in (*self.symbols.acc, *self.symbols.lam, ALPHA)})
        names.update({str(c.multiplier): f"_lam{i}" for i, c in enumerate(model.constraints)})
        names.update({str(qdd): f"_acc{i}" for i, qdd in enumerate(self.forms.qdd)})
        self.printer = PythonPrinter(names)
        self.tags = iter(f"{i}_" for i in range(1000))
        self.upper = [(i, j) for i in range(n) for j in range(i, n)]
        self.mass = [self.forms.mass[i][j] for i, j in self.upper]
        self.constants = frozenset([*(p.name for p in model.parameters), "_alpha"])
        self.velocities = frozenset(str(s) for s in (*self.forms.qd, *self.forms.qdd, *self.symbols.acc, *self.symbols.lam, *model.multipliers))

    # -- helpers --------------------------------------------------------------------------------

    def block(self, exprs: Sequence[Any]) -> tuple[list[str], list[str]]:
        tag = next(self.tags)
        lines, results = code_lines(self.printer, list(exprs), self.constants, self.velocities, prefix=f"_c{tag}", tag=tag)
        return [f"{name} = {code}" for name, code in lines], results

    def unpack(self, exprs: Sequence[Any], state: str = "_y", velocities: bool = True) -> list[str]:
        """Bind the parameters and state variables that `exprs` use (p and y are vectors)."""
        used = free_names(exprs)
        names = self.printer.names
        lines = [f"{names[p.name]} = _p[{i}]" for i, p in enumerate(self.model.parameters) if p.name in used]
        if "_alpha" in used:
            lines.append(f"_alpha = _p[{len(self.model.parameters)}]")
        variables = [*self.forms.q, *(self.forms.qd if velocities else ())]
        lines += [f"{names[str(v)]} = {state}[{i}]" for i, v in enumerate(variables) if str(v) in used]
        return lines

    def augmented(self) -> tuple[list[Any], list[tuple[int, int, int]]]:
        """The distinct entries of [[M, -A^T], [A, 0]] and where each goes: (index, row, col)."""
        n = self.n
        entries: list[Any] = list(self.mass)
        places = [(e, i, j) for e, (i, j) in enumerate(self.upper)] + [(e, j, i) for e, (i, j) in enumerate(self.upper) if i != j]
        for r, row in enumerate(self.rows.jacobian):
            for j, a in enumerate(row):
                places += [(len(entries), n + r, j), (-len(entries) - 1, j, n + r)]
                entries.append(a)
        return entries, places

    def fill(self, matrix: str, results: Sequence[str], places: Sequence[tuple[int, int, int]]) -> list[str]:
        """Assignments of a dense s x s matrix (numba: into `matrix`, zeroed first)."""
        lines = [f"{matrix}[:, :] = 0.0"]
        for e, i, j in places:
            value = results[e] if e >= 0 else f"-({results[-e - 1]})"
            if value not in ("0", "-(0)"):
                lines.append(f"{matrix}[{i}, {j}] = {value}")
        return lines

    def python_matrix(self, results: Sequence[str], places: Sequence[tuple[int, int, int]]) -> str:
        cells = [["0.0"] * self.size for _ in range(self.size)]
        for e, i, j in places:
            cells[i][j] = results[e] if e >= 0 else f"-({results[-e - 1]})"
        return "[" + ", ".join("[" + ", ".join(row) + "]" for row in cells) + "]"

    def numba_function(self, name: str, signature: str, doc: str, inputs: list[str], lines: list[str], tail: list[str]) -> str:
        """A numba function; a long one as loops over tables (`vectorize`), the tables kept for the module's top."""
        if len(lines) <= emit_python.SPLIT:
            return define(name, signature, doc, [*inputs, *lines, *tail])
        tables, body = vectorize(inputs, lines, tail, name)
        self.tables += tables
        return define(name, signature, doc, body)

    # -- functions ------------------------------------------------------------------------------

    def accel(self) -> str:
        """x = [q_ddot; lambda] solving the augmented system."""
        entries, places = self.augmented()
        exprs = [*entries, *self.forms.forcing, *(-c for c in stabilised_bias(self.model))]
        lines, results = self.block(exprs)
        inputs = self.unpack(exprs)
        vector = list(results[len(entries) :])
        if self.target == "numba":
            statements = [*lines, *self.fill("_a", results, places), *(f"_x[{i}] = {v}" for i, v in enumerate(vector))]
            return self.numba_function("_accel", "t, _y, _p, _x, _a", "x = [q_ddot; lambda]; returns 1 when the matrix is singular.", inputs, statements, ["return _lu_solve(_a, _x)"])
        body = [*inputs, *lines, f"return _solve({self.python_matrix(results, places)}, [{', '.join(vector)}])"]
        return define("_accel", "t, _y, _p", "x = [q_ddot; lambda] (ZeroDivisionError when the matrix is singular).", body)

    def jac(self) -> str:
        """d(q_dot, q_ddot)/d(q, q_dot) by differentiating the augmented system (Python target)."""
        n = self.n
        entries, places = self.augmented()
        phi = self.residual()
        columns = [real_diff(f, v) for f in phi for v in (*self.forms.q, *self.forms.qd)]
        exprs = [*entries, *columns]
        lines, results = self.block(exprs)
        unpack_x = [f"_acc{i} = _x[{i}]" for i in range(n)] + [f"_lam{r} = _x[{n + r}]" for r in range(self.k)]
        body = ["_x = _accel(t, _y, _p)", *self.unpack(exprs), *unpack_x, *lines]
        d = results[len(entries) :]
        rows = "[" + ", ".join("[" + ", ".join(d[i * 2 * n : (i + 1) * 2 * n]) + "]" for i in range(self.size)) + "]"
        body += [f"_d = numpy.linalg.solve({self.python_matrix(results, places)}, {rows})", f"_j = numpy.zeros(({2 * n}, {2 * n}))"]
        body += [f"_j[:{n}, {n}:] = numpy.eye({n})", f"_j[{n}:, :] = _d[:{n}, :]", "return _j"]
        return define("_jac", "t, _y, _p", "The Jacobian of rhs.", body)

    def jac_numba(self) -> str:
        """`_jac(t, _y, _p, _dphi, _x, _a)` (numba, for the compiled Radau method): the same derivative as `jac`,
        left for the kernel to solve (kernels._radau_analytic): x = [q_ddot; lambda] by `_accel`, then the
        augmented matrix [[M, -A^T], [A, 0]] into `_a` and dPhi/d(q, q_dot) into `_dphi` (size x 2n), so that
        J's lower rows are the first n rows of _a^-1 _dphi (not `_r`: `vectorize`'s loops use that name); returns `_accel`'s status (1: singular)."""
        n, size = self.n, self.size
        entries, places = self.augmented()
        columns = [real_diff(f, v) for f in self.residual() for v in (*self.forms.q, *self.forms.qd)]
        exprs = [*entries, *columns]
        lines, results = self.block(exprs)
        d = results[len(entries) :]
        head = ["_status = _accel(t, _y, _p, _x, _a)"] + [f"_acc{i} = _x[{i}]" for i in range(n)] + [f"_lam{r} = _x[{n + r}]" for r in range(self.k)]
        statements = [*lines, *self.fill("_a", results, places), "_dphi[:, :] = 0.0"]
        statements += [f"_dphi[{i}, {c}] = {d[i * 2 * n + c]}" for i in range(size) for c in range(2 * n) if d[i * 2 * n + c] != "0"]
        doc = "The augmented matrix into _a and dPhi/d(q, q_dot) into _dphi (the Jacobian is the first n rows of _a^-1 _dphi); returns 1 when singular."
        return self.numba_function("_jac", "t, _y, _p, _dphi, _x, _a", doc, [*head, *self.unpack(exprs)], statements, ["return int(_status)"])

    def residual(self) -> list[Any]:
        """Phi = [F + A^T lambda - M q_ddot; -c_s - A q_ddot] with q_ddot, lambda as symbols."""
        forms, rows, acc, lam = self.forms, self.rows, self.symbols.acc, self.symbols.lam
        result = []
        for i in range(self.n):
            value = forms.forcing[i] - se.Add(*(forms.mass[i][j] * acc[j] for j in range(self.n)))
            result.append(value + se.Add(*(rows.jacobian[r][i] * lam[r] for r in range(self.k))))
        for r, bias in enumerate(stabilised_bias(self.model)):
            result.append(-bias - se.Add(*(a * acc[j] for j, a in enumerate(rows.jacobian[r]))))
        return result

    def hamilton(self) -> str:
        """(q_dot, p_dot) at z = (q, p): M q_dot = p - p(q, 0, t), then p_dot = dL/dq - dR/dq_dot + Q."""
        forms, n = self.forms, self.n
        zero = {v: se.Integer(0) for v in forms.qd}
        offsets = [m.xreplace(zero) for m in forms.momenta]
        force = [real_diff(forms.lagrangian, q) - real_diff(forms.dissipation, qd) + forms.generalized_forces[i] for i, (q, qd) in enumerate(zip(forms.q, forms.qd, strict=True))]
        first_lines, first = self.block([*self.mass, *offsets])
        places = [(e, i, j) for e, (i, j) in enumerate(self.upper)] + [(e, j, i) for e, (i, j) in enumerate(self.upper) if i != j]
        statements = [*first_lines, *self.fill("_a", first, places)]
        statements += [f"_x[{i}] = _z[{n + i}] - ({first[len(self.mass) + i]})" for i in range(n)]
        statements.append("_status = _lu_solve(_a, _x)")
        second_lines, second = self.block(force)
        used = free_names(force)
        statements += [f"{self.printer.names[str(forms.qd[i])]} = _x[{i}]" for i in range(n) if str(forms.qd[i]) in used]
        statements += second_lines
        statements += [f"_out[{i}] = _x[{i}]" for i in range(n)] + [f"_out[{n + i}] = {v}" for i, v in enumerate(second)]
        inputs = self.unpack([*self.mass, *offsets, *force], "_z", velocities=False)
        return self.numba_function("_hamilton", "t, _z, _p, _out, _x, _a", "(q_dot, p_dot) at z = (q, p) into _out; returns 1 when M is singular.", inputs, statements, ["return int(_status)"])

    def projection_rows(self) -> str:
        """`_rows(t, _q, _p, _f, _A, _b, _M)` (numba, kept constraints): what the projection onto them
        needs at the positions q (projection.py, kernels.erk_projected): f(q, t) of each holonomic row (0
        for a velocity row), the gradient rows A (k x n, row by row), the biases b and the mass matrix M
        (n x n, row by row)."""
        n, rows = self.n, self.rows
        f = [expr if c.holonomic else se.Integer(0) for expr, c in zip(rows.expr, self.model.constraints, strict=True)]
        a = [entry for row in rows.jacobian for entry in row]
        exprs = [*f, *a, *rows.bias, *self.mass]
        lines, results = self.block(exprs)
        k, m = len(f), len(a)
        body = [*self.unpack(exprs, "_q", velocities=False), *lines]
        body += [f"_f[{i}] = {v}" for i, v in enumerate(results[:k])]
        body += [f"_A[{i}] = {v}" for i, v in enumerate(results[k : k + m])]
        body += [f"_b[{i}] = {v}" for i, v in enumerate(results[k + m : 2 * k + m])]
        mass = results[2 * k + m :]
        for e, (i, j) in enumerate(self.upper):
            body += [f"_M[{i * n + j}] = {mass[e]}"] + ([f"_M[{j * n + i}] = {mass[e]}"] if i != j else [])
        return define("_rows", "t, _q, _p, _f, _A, _b, _M", "f, A, b and M of the kept constraints at the positions q (projection).", [*body, "return 0"])

    def surfaces(self) -> list[Any]:
        """The switching functions of what `_accel` evaluates (switching.collect)."""
        entries, _ = self.augmented()
        return switching.collect([*entries, *self.forms.forcing, *stabilised_bias(self.model)], self.constants)

    def vector(self, name: str, doc: str, exprs: Sequence[Any]) -> str:
        """A function of (t, y, p) writing `exprs` into _out (numba) or returning them as a list."""
        exprs = list(exprs)
        lines, results = self.block(exprs)
        body = [*self.unpack(exprs), *lines]
        if self.target == "numba":
            body += [f"_out[{i}] = {v}" for i, v in enumerate(results)] + ["return 0"]
            return define(name, "t, _y, _p, _out", doc, body)
        body.append(f"return [{', '.join(results)}]")
        return define(name, "t, _y, _p", doc, body)

    def scalar(self, name: str, doc: str, expr: Any, needs_accel: bool) -> str:
        """A scalar function of (t, y, p), solving for q_ddot and lambda first when it uses them."""
        lines, results = self.block([expr])
        body = [*self.unpack([expr]), *lines, f"return float({results[0]})"]
        if needs_accel:
            n = self.n
            first = "_status = _accel(t, _y, _p, _x, _a)" if self.target == "numba" else "_x = _accel(t, _y, _p)"
            body = [first] + [f"_acc{i} = _x[{i}]" for i in range(n)] + [f"_lam{r} = _x[{n + r}]" for r in range(self.k)] + body
        signature = "t, _y, _p, _x, _a" if self.target == "numba" else "t, _y, _p"
        return define(name, signature, doc, body)

    def module(self, jacobian: bool, event: sp.Expr | None) -> str:
        """The functions a target needs, the constants _N, _K, _SIZE, and the `math` imports.

        numba: `_accel`, `_hamilton` (unconstrained systems), `_rows` and `_energy` (kept
        constraints: the projection), `_jac` (with `jacobian`: the compiled Radau method) and `_event`, which the compiled loops call; Python: `_accel` (and `_jac`) for scipy, and the monitored quantities."""
        model, forms = self.model, self.forms
        self.tables: list[str] = []
        stop_expr = to_symengine(event) if event is not None else se.RealDouble(1.0)
        uses_accel = bool(free_names([stop_expr]) & {*(str(a) for a in forms.qdd), *(str(m) for m in model.multipliers)})
        stop = self.scalar("_event", "The stop condition, whose sign change ends the run.", stop_expr, uses_accel)
        parts = [self.accel()]
        if self.target == "numba":
            parts += [self.hamilton()] if not model.constraints else [self.projection_rows(), self.scalar("_energy", "The energy function h = sum p q_dot - L.", forms.energy, False)]
            parts += [self.jac_numba()] if jacobian else []
        else:
            parts += [self.jac()] if jacobian else []
            parts += [
                self.scalar("_energy", "The energy function h = sum p q_dot - L.", forms.energy, False),
                self.vector("_momenta", "The momenta of the ignorable coordinates.", [forms.momenta[i] for i in ignorable(model)] or [se.Integer(0)]),
                self.vector("_residuals", "Each kept constraint's residual: f(q, t), or a . q_dot + b for a velocity constraint.", list(self.rows.expr) or [se.Integer(0)]),
                self.vector("_canonical", "The momenta p = dL/dq_dot of every coordinate.", forms.momenta),
            ]
        parts.append(stop)
        surfaces = self.surfaces()
        if surfaces:  # only then: a smooth system's code is what it was
            parts.append(self.vector("_switch", "The switching functions: where one changes sign the right-hand side is not smooth.", surfaces))
        math_names = self.printer.imports()
        header = [f"_N = {self.n}", f"_K = {self.k}", f"_SIZE = {self.size}"] + ([f"_SWITCHES = {len(surfaces)}"] if surfaces else [])
        if self.tables:
            header += self.tables
            header.insert(0, "import numpy")
        if math_names:
            header.insert(0, f"from math import {', '.join(math_names)}")
        return "\n".join(header) + "\n\n\n" + "\n\n\n".join(parts) + "\n"


def source(model: Model, target: str, jacobian: bool = False, event: sp.Expr | None = None) -> str:
    """The generated functions of `model` for `target` ("numba" or "python")."""
    return Generator(model, target).module(jacobian, event)
