"""JAX: a module of pure `jax.numpy` functions for differentiable and batched simulation.

The module defines COORDINATES, PARAMETER_NAMES, PARAMETERS (defaults), NQ, NP,
`default_parameters()`, `mass_matrix(t, q, p)`, `forcing(t, q, q_dot, p)`, `energy(t, q, q_dot, p)`
and `rhs(t, y, p)` with y = [q..., q_dot...] (with kept constraints also `accelerations`,
`multipliers` and `constraint_residuals`). Every function is straight-line jnp code (no Python
control flow on values, no in-place updates), so `jax.jit`, `jax.vmap` and `jax.grad` apply;
the accelerations solve M q_ddot = F (or [[M, -A^T], [A, 0]] [q_ddot, lambda] = [F, -c] for kept
constraints, as in the Python module): without kept constraints, from `COLUMNS_MIN` coordinates, by the
module's `_spd_solve` (`columns_helper`: L D L^T a column at a time, each column one array, the batch last under
`jax.vmap`, inside `jax.lax.custom_linear_solve` for the derivatives); otherwise by unrolled scalar L D L^T code
(`unrolled_solve`; the Schur complement for kept constraints) up to `UNROLLED_MAX` unknowns, which `jax.vmap`
turns into elementwise operations over the batch, and by `jnp.linalg.solve` above (one LAPACK call per state on
CPU, the slowest of the three over a batch: BENCHMARKS.md). From n + k = `CHUNKED_MIN` the
module's `rhs` goes through `_in_chunks`, so that `jax.vmap` over many states evaluates it `CHUNK` states at a
time (same values; derivatives of the plain function); below `KEEP_MIN` nothing is stored through `_kept`. `emit_hamilton` writes
Hamilton's equations (`derive --to jax --form hamilton`). `p` is optional everywhere: None means the file's
defaults, a dict gives values by name (missing ones take their defaults), and an array gives
them all in PARAMETER_NAMES order (what `jax.grad` with respect to the parameters takes).
A file with `inputs` gives INPUT_NAMES, INPUTS (defaults), NU and `default_inputs()`, and every function
whose result depends on an input takes `u=None` after `p`, read as `p` is: None for the defaults, a dict by
name, or an array in INPUT_NAMES order (so `jax.jit`, `jax.vmap` and `jax.grad` apply with respect to u
too); a file with `outputs` gives `outputs(t, y, p, u)`, an array in the file's order. A file without
either generates what it did (the names `u`, `INPUTS`, ... are reserved only then).

Float64 is the user's choice, stated in the generated docstring: JAX computes in float32 unless
`jax.config.update("jax_enable_x64", True)` runs first; the module never changes that setting.
On CPU, XLA splits each loop over a batch between as many threads as the process may use CPUs; the CPU time
per call is lower with one thread (XLA's client created while the process sees one CPU: README, "JAX";
benchmarks/jax_bench.py --threads both), which is what several processes batching at once want.

Safe with any system file, by the same means as the Python module: file text reaches the code
only through `docstring` and `literal`, and user names go through `mangle` with a reserved set
holding Python's keywords and builtins, `jnp`, `jax`, `lax` and every name the module defines;
the generator's own helpers and temporaries start with `_`, which no user name does.
"""

from __future__ import annotations

import builtins
import keyword
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import sympy as sp

from lagrange_cli import __version__
from lagrange_cli._symengine import to_symengine
from lagrange_cli.algebra import check_invertible, check_solvable
from lagrange_cli.emit.common import require_defined, written_definitions
from lagrange_cli.emit.printer import ATOM, Code, Printer, restructure
from lagrange_cli.emit.python import define, docstring, literal, mangle
from lagrange_cli.model import Model

GENERATED = frozenset(
    {
        *("jnp", "jax", "lax", "numpy", "np", "t", "y", "p", "q", "q_dot"),
        *("COORDINATES", "PARAMETER_NAMES", "PARAMETERS", "NQ", "NP", "default_parameters"),
        *("mass_matrix", "forcing", "energy", "rhs", "accelerations", "multipliers", "constraint_residuals"),
    }
)
"""Names without a leading `_` that the generated module uses or defines."""
RESERVED = frozenset({*keyword.kwlist, *keyword.softkwlist, *dir(builtins), *GENERATED})
"""What no user symbol may be called in the generated module (besides any name starting with `_`)."""


class JaxPrinter(Printer):
    """Symengine expressions as `jax.numpy` code: `jnp.sin`, `jnp.arctan2`, `x**3` (lax.integer_pow,
    exact derivatives at 0), `jnp.power` for real powers (NaN for a negative base, as jnp gives
    NaN outside every function's domain: nothing can raise inside `jit`)."""

    functions: ClassVar[dict[str, str]] = {
        **{name: f"jnp.{name}" for name in ("sin", "cos", "tan", "sinh", "cosh", "tanh", "exp", "log", "sqrt", "sign")},
        **{"asin": "jnp.arcsin", "acos": "jnp.arccos", "atan": "jnp.arctan", "atan2": "jnp.arctan2", "Abs": "jnp.abs", "pow": "jnp.power"},
    }

    def nonfinite(self, value: float) -> Code:
        return ("jnp.nan" if math.isnan(value) else "jnp.inf"), ATOM

    def _print_sign(self, expr: Any) -> Code:
        return self.call(self.function_name("sign"), [self.doprint(a) for a in expr.args])


def emit(model: Model, *, name: str = "eom") -> str:
    """The module's source (`name` is not used: a module is named by its file). The file's function
    definitions are written out (`Model.with_definitions`); undefined functions are refused."""
    definitions = model.definitions
    require_defined(model, "JAX code")
    model = model.with_definitions()
    check_solvable(model)
    return _Writer(model, definitions).module()


INPUT_GENERATED = frozenset({"u", "INPUT_NAMES", "INPUTS", "NU", "default_inputs", "outputs"})
"""The names a module of a file with inputs or outputs also uses or defines (reserved only then: a file
without them keeps its names and its module byte for byte)."""


def jax_names(model: Model, extra: Sequence[str] = (), reserved: frozenset[str] = frozenset()) -> dict[str, str]:
    """Identifiers for the coordinates, velocities, parameters and inputs (`mangle` against `RESERVED`), and `t`."""
    symbols = [str(s) for s in (*model.q, *model.qd, *(p.symbol for p in model.parameters), *(i.symbol for i in model.inputs))] + list(extra)
    signals = INPUT_GENERATED if model.inputs or model.outputs else frozenset()
    return {**mangle(symbols, RESERVED | reserved | signals), str(model.t): "t"}


def _free_names(exprs: Sequence[Any]) -> set[str]:
    """The names of the free symbols of symengine expressions."""
    return {str(s) for e in exprs for s in getattr(e, "free_symbols", ())}


class Storage:
    """The `_sincos` and `_kept` choices of one module whose linear solve has `unknowns` unknowns (n + k, or the
    reduced form's independent velocities): what it stores (`KEEP_MIN`) and which helpers it then defines
    (`uses_kept`, `uses_sincos`); shared by the Lagrange and Hamilton writers and `--form reduced`."""

    def __init__(self, unknowns: int) -> None:
        self.uses_kept = False
        self.uses_sincos = False
        self.storing = KEEP and unknowns >= KEEP_MIN

    def sincos(self, code: str) -> str:
        """`_sincos(x)[0]` for `jnp.sin(x)` and `_sincos(x)[1]` for `jnp.cos(x)` of a name `x` (the sines and
        cosines of the coordinates that `restructure` computes once) when `FAST_TRIG`; the module then defines `_sincos`."""
        match = SINCOS.fullmatch(code)
        if not (FAST_TRIG and match):
            return code
        self.uses_sincos = True
        return f"_sincos({match[2]})[{int(match[1] == 'cos')}]"

    def keep(self, code: str) -> str:
        """`_kept(code)` (for `unrolled_solve`); the module then defines `_kept`."""
        self.uses_kept = True
        return f"_kept({code})"

    def kept(self, code: str) -> str:
        """`code`, through `_kept` when it calls a function XLA counts as cheap but which costs a libm call
        (`kept`); the module then defines `_kept`."""
        wrapped = kept(code) if self.storing else code
        self.uses_kept = self.uses_kept or wrapped != code
        return wrapped

    def solve_keep(self) -> Callable[[str], str] | None:
        """What `unrolled_solve` takes as `keep`: `keep` when this module stores values, else None."""
        return self.keep if self.storing else None


class _Writer(Storage):
    def __init__(self, model: Model, definitions: Any) -> None:
        self.model = model
        self.definitions = definitions
        self.names = jax_names(model)
        self.signals = frozenset(i.name for i in model.inputs)
        Storage.__init__(self, model.n + len(model.constraints))
        self.uses_chunks = False
        self.uses_columns = False
        n = model.n
        self.upper = [(i, j) for i in range(n) for j in range(i, n)]
        forms = model.symengine
        self.mass = [forms.mass[i][j] for i, j in self.upper]
        self.forcing = list(forms.forcing)
        rows = model.constraints
        self.jacobian = [to_symengine(a) for c in rows for a in c.jacobian]
        self.bias = [to_symengine(c.acceleration_bias) for c in rows]
        self.residuals = [to_symengine(c.expr) for c in rows]

    def printer(self) -> JaxPrinter:
        return JaxPrinter(self.names)

    def uses_inputs(self, exprs: Sequence[Any]) -> bool:
        """Whether `exprs` (symengine) hold an input: then their function takes `u=None` after `p`."""
        return bool(self.signals and self.signals & _free_names(exprs))

    def arguments(self, state: str, exprs: Sequence[Any]) -> str:
        """`t, <state>, p=None`, and `u=None` when `exprs` hold an input."""
        return f"t, {', '.join(state.split(','))}, p=None" + (", u=None" if self.uses_inputs(exprs) else "")

    def unpack_parameters(self, inputs: bool = False) -> list[str]:
        """Lines binding the parameters (and, when `inputs`, the inputs) to the user's names."""
        model = self.model
        lines = []
        if model.parameters:
            targets = [self.names[p.name] for p in model.parameters]
            lines.append(f"{', '.join(targets)}{',' * (len(targets) == 1)} = _parameters(p)")
        if inputs and model.inputs:
            targets = [self.names[i.name] for i in model.inputs]
            lines.append(f"{', '.join(targets)}{',' * (len(targets) == 1)} = _inputs(u)")
        return lines

    def unpack(self, state: str, inputs: bool = False) -> list[str]:
        """Lines binding the parameters (the inputs too when `inputs`) and the state (`y`, or `q` and `q_dot`) to the user's names."""
        model = self.model
        lines = self.unpack_parameters(inputs)
        groups = [("y", [*model.q, *model.qd])] if state == "y" else [(g, v) for g, v in (("q", model.q), ("q_dot", model.qd)) if g in state.split(",")]
        for group, variables in groups:
            lines.append(f"{group} = jnp.asarray({group})")
            targets = [self.names[str(v)] for v in variables]
            lines.append(f"{', '.join(targets)}{',' * (len(targets) == 1)} = " + ", ".join(f"{group}[{i}]" for i in range(len(variables))) + ("," * (len(variables) == 1)))
        return lines

    def block(self, exprs: Sequence[Any], tag: str = "") -> tuple[list[str], list[str]]:
        """Straight-line code for `exprs`: the printer core's `restructure` (sin and cos of each
        angle once, those of differences as products, sums collected by their varying part), then
        one CSE over everything; the lines and the result of each expression. Blocks with distinct
        `tag`s can share a function."""
        printer = self.printer()
        definitions, rewritten = restructure(exprs, [p.name for p in self.model.parameters], tag=tag)
        lines = []
        for lhs, value in definitions:
            lines.append(f"{lhs} = {self.kept(self.sincos(printer.doprint(value)))}")
            printer.names[lhs] = lhs
        temporaries, results = printer.block(rewritten, f"_c{tag}", [*self.names.values(), *(lhs for lhs, _ in definitions)])
        return lines + [f"{lhs} = {self.kept(code)}" for lhs, code in temporaries], results

    def function(self, name: str, doc: str, exprs: Sequence[Any], state: str, shape: str) -> str:
        lines, results = self.block(exprs)
        body = [*self.unpack(state, self.uses_inputs(exprs)), *lines]
        if shape == "matrix":
            n = self.model.n
            cell = dict(zip(self.upper, results, strict=True))
            body.append("return _array([" + ", ".join("[" + ", ".join(cell[(min(i, j), max(i, j))] for j in range(n)) + "]" for i in range(n)) + "])")
        elif shape == "vector":
            body.append("return _array([" + ", ".join(results) + "])")
        else:
            body.append(f"return _array({results[0]})")
        return define(name, self.arguments(state, exprs), doc, body)

    def accelerations(self) -> list[str]:
        """The body lines computing `_x`, the solution of the (augmented) linear system."""
        n, k = self.model.n, len(self.model.constraints)
        exprs = [*self.mass, *self.forcing, *self.jacobian, *self.bias]
        lines, results = self.block(exprs)
        m = dict(zip(self.upper, results[: len(self.mass)], strict=True))
        f = results[len(self.mass) : len(self.mass) + n]
        a = results[len(self.mass) + n : len(self.mass) + n + n * k]
        c = results[len(self.mass) + n + n * k :]
        body = [*self.unpack("y", self.uses_inputs(exprs)), *lines]
        zero = {ij for ij, expr in zip(self.upper, self.mass, strict=True) if expr == 0}
        if not k and n >= COLUMNS_MIN and 2 * len(zero) <= len(self.upper):
            self.uses_columns = self.uses_kept = True
            rows = ", ".join("(" + ", ".join(m[(min(i, j), max(i, j))] for j in range(n)) + ",)" for i in range(n))
            return [*body, f"_x = _spd_solve(({rows},), _array([{', '.join(f)}]))"]
        if n + k <= UNROLLED_MAX:
            mass = {ij: (None if ij in zero else code) for ij, code in m.items()}
            jacobian = [[None if self.jacobian[r * n + j] == 0 else a[r * n + j] for j in range(n)] for r in range(k)]
            forcing = [None if expr == 0 else code for expr, code in zip(self.forcing, f, strict=True)]
            bias = [None if expr == 0 else _negate(code) for expr, code in zip(self.bias, c, strict=True)]
            solved = unrolled_solve(n, mass, forcing, jacobian, bias, self.solve_keep())
            return body + solved.lines + ["_x = _array([" + ", ".join(solved.results) + "])"]
        matrix = [[m[(min(i, j), max(i, j))] for j in range(n)] + [_negate(a[r * n + i]) for r in range(k)] for i in range(n)]
        matrix += [[a[r * n + j] for j in range(n)] + ["0.0"] * k for r in range(k)]
        vector = [*f, *(_negate(x) for x in c)]
        rows = ", ".join("[" + ", ".join(row) + "]" for row in matrix)
        body.append(f"_a = _array([{rows}])")
        body.append(f"_b = _array([{', '.join(vector)}])")
        body.append("_x = jnp.linalg.solve(_a, _b)")
        return body

    def rhs(self) -> list[str]:
        model, n = self.model, self.model.n
        state = ", ".join(map(str, (*model.q, *model.qd)))
        doc = f"dy/dt for y = [{state}]: an array of {2 * n} values (jit-, vmap- and grad-compatible)."
        arguments = self.arguments("y", [*self.mass, *self.forcing, *self.jacobian, *self.bias])
        values = "t, y, p, u" if arguments.endswith("u=None") else "t, y, p"
        if not model.constraints:
            return [self.chunked("rhs", arguments, doc, [*self.accelerations(), f"return jnp.concatenate([y[{n}:], _x])"], values)]
        names = ", ".join(str(x) for x in model.multipliers)
        accelerations = define(
            "accelerations",
            arguments,
            f"[{', '.join(map(str, model.qdd))}, {names}] from [[M, -A^T], [A, 0]] x = [F, -c] (index-1 form).",
            [*self.accelerations(), "return _x"],
        )
        rhs = self.chunked("rhs", arguments, doc, ["y = jnp.asarray(y)", f"return jnp.concatenate([y[{n}:], accelerations({values})[:{n}]])"], values)
        multipliers = define("multipliers", arguments, f"The multipliers [{names}]; A^T lambda is the generalized constraint force.", [f"return accelerations({values})[{n}:]"])
        residuals = self.function("constraint_residuals", "Each constraint's residual: f(q, t) for holonomic ones, a . q_dot + b for velocity ones.", self.residuals, "q,q_dot", "vector")
        return [residuals, accelerations, rhs, multipliers]

    def chunked(self, name: str, arguments: str, doc: str, body: list[str], values: str) -> str:
        """`name` defined by `body`, or, for n + k >= `CHUNKED_MIN`, `_<name>` defined so and `name` calling it through
        `_in_chunks` (jax.vmap over many states runs it on CHUNK states at a time); the module then defines `_in_chunks`."""
        model = self.model
        if model.n + len(model.constraints) < CHUNKED_MIN:
            return define(name, arguments, doc, body)
        self.uses_chunks = True
        inner = define(f"_{name}", arguments, f"{name} itself; {name} runs it through _in_chunks.", body)
        return f"{inner}\n\n\n_{name}_in_chunks = _in_chunks(_{name})\n\n\n" + define(name, arguments, doc, [f"return _{name}_in_chunks({values})"])

    def module(self) -> str:
        model = self.model
        functions = [
            self.function("mass_matrix", "The mass matrix M, an NQ x NQ array.", self.mass, "q", "matrix"),
            self.function("forcing", "The forcing F of M q_ddot = F" + (" + A^T lambda" if model.constraints else "") + ", an array of NQ values.", self.forcing, "q,q_dot", "vector"),
            self.function("energy", "The energy function h = sum p_i q_dot_i - L, a scalar.", [model.symengine.energy], "q,q_dot", "scalar"),
            *self.rhs(),
        ]
        if model.outputs:
            functions.append(self.outputs())
        missing = [p.name for p in model.parameters if p.value is None]
        defaults = ", ".join(f"{literal(p.name)}: {_number(p.value)}" for p in model.parameters if p.value is not None)
        parameter_names = ", ".join(literal(p.name) for p in model.parameters) + ("," if len(model.parameters) == 1 else "")
        coordinates = ", ".join(literal(c) for c in model.coordinates) + ("," if model.n == 1 else "")
        header = [
            f"{model.title}: equations of motion generated by lagrange {__version__} from {Path(model.source).name}, for JAX.",
            "",
            "M(q, t) q_ddot = F(q, q_dot, t)" + (" + A^T lambda, A q_ddot + c = 0" if model.constraints else "") + f", with y = [{', '.join(map(str, (*model.q, *model.qd)))}].",
            "",
            "Every function takes the time first, then the state, then p (optional): rhs(t, y, p), mass_matrix(t, q, p),",
            "forcing(t, q, q_dot, p), energy(t, q, q_dot, p); each is pure jax.numpy, so jax.jit, jax.vmap and jax.grad apply.",
            "p is None (the file's defaults, PARAMETERS), a dict by name (missing names take their defaults) or an array",
            "of NP values in PARAMETER_NAMES order (default_parameters() gives the defaults so).",
            "",
            "Float64: JAX computes in float32 unless 64-bit mode is on. For results that agree with the other targets",
            'to about 1e-12, run `import jax; jax.config.update("jax_enable_x64", True)` before creating any array;',
            "this module leaves that global setting to you.",
            "",
            "Outside a function's domain (the square root or logarithm of a negative number, a negative base to a",
            "real power) the result is NaN, and a singular mass matrix gives inf or NaN: code under jax.jit cannot raise.",
            *SINCOS_NOTE * self.uses_sincos,
            *CHUNKS_NOTE * self.uses_chunks,
            *COLUMNS_NOTE * self.uses_columns,
        ]
        if self.definitions:
            header += ["", written_definitions(self.definitions)]
        if missing:
            header += ["", f"Parameters without a default, to be given in p: {', '.join(missing)}."]
        header += input_header(model)
        constants = [
            f"COORDINATES = ({coordinates})",
            f"PARAMETER_NAMES = ({parameter_names})",
            f"PARAMETERS = {{{defaults}}}",
            f"NQ = {model.n}",
            f"NP = {len(model.parameters)}",
            *input_constants(model),
        ]
        head = (
            docstring("\n".join([*header, ""])) + "\n\n" + ("import jax\n" if self.uses_sincos or self.uses_chunks or self.uses_columns else "") + "import jax.numpy as jnp\n\n" + "\n".join(constants)
        )
        helpers = [*_helpers(model), *kept_helper(self.uses_kept), *sincos_helper(self.uses_sincos), *chunks_helper(self.uses_chunks), *columns_helper(self.uses_columns)]
        return head + "\n\n\n" + "\n\n\n".join([*helpers, *functions]) + "\n"

    def outputs(self) -> str:
        """`outputs(t, y, p=None, u=None)`: the file's outputs in its order, an array (FORMAT.md version 2)."""
        model = self.model
        exprs = [to_symengine(e) for _, e in model.outputs]
        lines, results = self.block(exprs, "o")
        body = [*self.unpack("y", bool(model.inputs)), *lines, "return _array([" + ", ".join(results) + "])"]
        names = ", ".join(name for name, _ in model.outputs)
        return define("outputs", "t, y, p=None" + (", u=None" if model.inputs else ""), f"The outputs [{names}] at time t and state y, an array.", body)


def input_header(model: Model) -> list[str]:
    """The docstring's paragraph on the inputs and outputs (nothing for a file without them)."""
    lines = []
    if model.inputs:
        lines += [
            "",
            f"Inputs u = [{', '.join(i.name for i in model.inputs)}] (given values at time t): every function whose result depends on an input takes",
            "u after p, as p: None (the file's defaults, INPUTS), a dict by name (missing names take their defaults) or an",
            "array of NU values in INPUT_NAMES order (default_inputs() gives the defaults so; what jax.grad or jax.vmap",
            "with respect to the inputs takes).",
        ]
    if model.outputs:
        lines += ["", f"outputs(t, y, p{', u' if model.inputs else ''}) gives the outputs [{', '.join(name for name, _ in model.outputs)}] in the file's order."]
    return lines


def input_constants(model: Model) -> list[str]:
    """INPUT_NAMES, INPUTS (the defaults) and NU (nothing for a file without inputs)."""
    if not model.inputs:
        return []
    names = ", ".join(literal(i.name) for i in model.inputs) + ("," if len(model.inputs) == 1 else "")
    defaults = ", ".join(f"{literal(i.name)}: {_number(i.value)}" for i in model.inputs)
    return [f"INPUT_NAMES = ({names})", f"INPUTS = {{{defaults}}}", f"NU = {len(model.inputs)}"]


def helpers(model: Model) -> list[str]:
    """The definitions every module of this target starts with: default_parameters, _parameters and _array
    (and default_inputs and _inputs for a file with inputs); for the other writers of JAX modules (`--form reduced`)."""
    return _helpers(model)


KEPT_CALLS = re.compile(r"\bjnp\.(sin|cos|tan)\(|^_sincos\(")
"""The calls whose values `kept` stores: XLA counts sin, cos and tan of reals as cheap (as a multiplication)
and so recomputes them in every fused loop that uses them, though each is a libm-grade evaluation (about
8.5 ns per float64 value on CPU). Other costly functions (exp, log, sqrt, a real power, atan2, a division)
XLA counts as expensive and computes once by itself."""


SINCOS = re.compile(r"jnp\.(sin|cos)\(([A-Za-z_][A-Za-z0-9_]*)\)")
FAST_TRIG = True
"""Whether the sines and cosines of the coordinates (`restructure`'s `_sin<k>`, `_cos<k>`) are computed by the
module's `_sincos` (float64: a shared argument reduction and two polynomials, elementwise and vectorized by XLA,
7x faster than XLA's sin plus cos) rather than by `jnp.sin` and `jnp.cos`; False for benchmarks/jax_bench.py --no-fast-trig."""

SINCOS_NOTE = [
    "",
    "In float64 the sines and cosines of the coordinates come from _sincos (arithmetic XLA vectorizes, several",
    "times faster than jnp.sin and jnp.cos): within 1e-14 of them for angles below 1e15 in magnitude, NaN beyond.",
]
"""The module docstring's paragraph on `_sincos`."""

SINE = ("-1.66666666666666324348e-01", "8.33333333332248946124e-03", "-1.98412698298579493134e-04", "2.75573137070700676789e-06", "-2.50507602534068634195e-08", "1.58969099521155010221e-10")
COSINE = ("4.16666666666666019037e-02", "-1.38888888888741095749e-03", "2.48015872894767294178e-05", "-2.75573143513906633035e-07", "2.08757232129817482790e-09", "-1.13596475577881948265e-11")
"""The minimax coefficients of fdlibm's __kernel_sin and __kernel_cos (sin r = r + r^3 S(r^2), cos r = 1 - r^2/2 + r^4 C(r^2) on |r| <= pi/4)."""


def sincos_helper(used: bool = True) -> list[str]:
    """The definitions of `_sincos` and its derivative rule (nothing when not `used`); the module imports `jax`."""
    if not used:
        return []

    def horner(coefficients: Sequence[str]) -> str:
        text = coefficients[-1]
        for c in reversed(coefficients[:-1]):
            text = f"{c} + _z * ({text})"
        return text

    body = [
        "x = jnp.asarray(x)",
        "if x.dtype != jnp.float64:",
        "    return jnp.sin(x), jnp.cos(x)",
        "_k = jnp.round(x * 0.6366197723675814)",
        "_r = ((x - _k * 1.5707963267341256) - _k * 6.077100506303966e-11) - _k * 2.0222662487111665e-21",
        "_z = _r * _r",
        f"_s = _r + _r * _z * ({horner(SINE)})",
        f"_c = 1.0 - 0.5 * _z + _z * _z * ({horner(COSINE)})",
        "_n = jnp.where(jnp.abs(x) < 1e15, _k, 0.0).astype(jnp.int64) & 3",
        "_sin = jnp.where(x == 0, x, jnp.where(_n == 0, _s, jnp.where(_n == 1, _c, jnp.where(_n == 2, -_s, -_c))))",
        "_cos = jnp.where(_n == 0, _c, jnp.where(_n == 1, -_s, jnp.where(_n == 2, -_c, _s)))",
        "_far = ~(jnp.abs(x) < 1e15)",
        "return jnp.where(_far, jnp.nan, _sin), jnp.where(_far, jnp.nan, _cos)",
    ]
    doc = (
        "(sin x, cos x), elementwise. Float64: x - k pi/2 (k the nearest integer to x 2/pi, pi/2 in three parts as\n"
        "in fdlibm) and fdlibm's polynomials on |r| <= pi/4, all of it arithmetic that XLA vectorizes (about 7x faster\n"
        "than jnp.sin and jnp.cos together on CPU). Within 1 ulp of the correctly rounded values for |x| < 1.6e6 and,\n"
        "as measured, within 1e-14 up to |x| = 1e15; NaN for |x| >= 1e15 (where consecutive floats are more than 0.1\n"
        "apart, so the angle has no phase left) and for NaN or infinite x; sin(-0.0) is -0.0. Other dtypes: jnp.sin and jnp.cos.\n"
        "Its derivative is (cos x, -sin x) from the same values (`_sincos_jvp`)."
    )
    return [
        "@jax.custom_jvp\n" + define("_sincos", "x", doc, body),
        "@_sincos.defjvp\n"
        + define("_sincos_jvp", "primals, tangents", "d(sin x, cos x) = (cos x dx, -sin x dx).", ["(x,), (dx,) = primals, tangents", "_s, _c = _sincos(x)", "return (_s, _c), (_c * dx, -_s * dx)"]),
    ]


KEEP = True
"""Whether `kept` wraps anything (False: the previous modules, for benchmarks/jax_bench.py --no-kept)."""
KEEP_MIN = 3
"""Smallest n + k (coordinates plus kept constraints) whose module stores values through `_kept`. Below it
(n + k = 1 or 2) XLA's recomputation costs less than the stores: without them the double pendulum's rhs is two
fused loops instead of seven, 0.15 against 0.19-0.20 ms CPU for 10^4 states, while at n = 3 and 5 storing wins
(0.35 against 0.41 ms, 0.76 against 1.50 ms; BENCHMARKS.md, helper `jax50`, 2026-11-26)."""

CHUNKED_MIN = 10
"""Smallest n + k whose `rhs` runs through `_in_chunks` (`chunks_helper`): above it the unrolled solve's stored
values of 10^4 states no longer fit in the caches: 713 ns per state at 1000 to 2000 states against 1062 at 10^4
for the 15-link chain, and 10.7 against 12.2-12.8 ms for its rhs over 10^4 states, through `_in_chunks` or not;
the same at 10 links (benchmarks/jax_bench.py --no-chunks; BENCHMARKS.md, helper `jax50`, 2026-11-26)."""
CHUNK = 1000
"""States per chunk under `_in_chunks` (1000: the 15-link chain's stored values of one chunk, about 400 arrays
of 8 kB, stay in the caches; 500 and 2000 measured the same within the noise, BENCHMARKS.md, helper `jax50`)."""

CHUNKS_NOTE = [
    "",
    "rhs is evaluated through _in_chunks: jax.vmap over a batch of states (only y batched) computes it",
    "_CHUNK states at a time, in turn (jax.lax.map), so that its many intermediate values stay in the",
    "processor's caches; the values are those of the plain function, and jax.grad and jax.jvp differentiate",
    "the plain function (a custom_jvp rule).",
]
"""The module docstring's paragraph on `_in_chunks`."""


def chunks_helper(used: bool = True) -> list[str]:
    """`CHUNK` and the definition of `_in_chunks` (nothing when not `used`); the module imports `jax`."""
    if not used:
        return []
    doc = (
        "f (a function of (t, y, ...) for one state y), with a batching rule: jax.vmap over y alone (t and the other\n"
        "arguments not batched) with at least 2 * _CHUNK states runs jax.vmap(f) on _CHUNK states at a time (jax.lax.map)\n"
        "and the rest at once, so that f's intermediate values stay in the caches; any other jax.vmap is jax.vmap(f).\n"
        "The values are f's. Derivatives (jax.grad, jax.jvp, jax.jacfwd) are f's: a custom_jvp rule calls jax.jvp(f)."
    )
    body = [
        "@jax.custom_batching.custom_vmap",
        "def _batched(*args):",
        "    return f(*args)",
        "@_batched.def_vmap",
        "def _rule(size, batched, *args):",
        "    _others = [_b for _i, _tree in enumerate(batched) if _i != 1 for _b in jax.tree.leaves(_tree)]",
        "    if batched[1] is True and not any(_others) and size >= 2 * _CHUNK:",
        "        _axes = [None, 0, *[None] * (len(args) - 2)]",
        "        _y = args[1]",
        "        _head = size // _CHUNK * _CHUNK",
        "        _chunks = _y[:_head].reshape(size // _CHUNK, _CHUNK, *_y.shape[1:])",
        "        _out = jax.lax.map(lambda _c: jax.vmap(f, _axes)(args[0], _c, *args[2:]), _chunks)",
        "        _out = _out.reshape(_head, *_out.shape[2:])",
        "        if _head < size:",
        "            _out = jnp.concatenate([_out, jax.vmap(f, _axes)(args[0], _y[_head:], *args[2:])])",
        "        return _out, True",
        "    _axes = [jax.tree.map(lambda _b: 0 if _b else None, _tree) for _tree in batched]",
        "    return jax.vmap(f, _axes)(*args), True",
        "@jax.custom_jvp",
        "def _chunked(*args):",
        "    return _batched(*args)",
        "@_chunked.defjvp",
        "def _jvp(primals, tangents):",
        "    return jax.jvp(f, primals, tangents)",
        "return _chunked",
    ]
    return [f"_CHUNK = {CHUNK}", define("_in_chunks", "f", doc, body)]


COLUMNS_MIN = 11
"""Smallest n (coordinates; no kept constraints) whose rhs solves M q_ddot = F by `_spd_solve` (`columns_helper`: L D L^T
one column of L at a time, each column one fused loop over the batch) rather than by `unrolled_solve` or `jnp.linalg.solve`.
Measured (benchmarks/jax_bench.py --ab-columns-min 1000; BENCHMARKS.md, helper `jaxvec`, 2026-11-27): CPU time 10-25%
lower at 15 and 20 links in every interleaved run; at 5 and 10 links faster in one run and slower or equal in another, so
not used there (11 to 14 not measured). Only for a mass matrix with at most half its upper triangle structurally zero:
`_spd_solve` does the dense work, where `unrolled_solve` skips the zeros (a diagonal M costs n divisions); that bound is a
judgement, not a measurement."""

COLUMNS_NOTE = [
    "",
    "rhs solves M q_ddot = F by _spd_solve: L D L^T without pivoting (M is symmetric positive definite), a column",
    "of L at a time as one array, so that under jax.vmap each column is one loop over the batch; it is wrapped in",
    "jax.lax.custom_linear_solve, so jax.grad and jax.jvp differentiate x = M^-1 F (through M and F) with the same",
    "solve. (Not jnp.linalg.solve: XLA on CPU runs that as one LAPACK call per state, several times slower here.)",
]
"""The module docstring's paragraph on `_spd_solve`."""


def columns_helper(used: bool = True) -> list[str]:
    """The definitions of `_ldl_columns`, `_ldl_batched` and `_spd_solve` (nothing when not `used`); the module imports
    `jax` and defines `_kept`."""
    if not used:
        return []
    columns = [
        "_n = len(a)",
        "_lows, _scaled = [], []",
        "for _j in range(_n):",
        "    _v = jnp.stack([a[_i][_j] for _i in range(_j, _n)] + [b[_j]])",
        "    for _k in range(_j):",
        "        _v = _v - _lows[_k][_j - _k - 1 :] * _scaled[_k][_j - _k - 1]",
        "    _v = _kept(_v)",
        "    _scaled.append(_v[1:])",
        "    _lows.append(_v[1:] / _v[0])",
        "_x = [b[0]] * _n",
        "for _j in reversed(range(_n)):",
        "    _s = _lows[_j][_n - _j - 1]",
        "    for _i in range(_j + 1, _n):",
        "        _s = _s - _lows[_j][_i - _j - 1] * _x[_i]",
        "    _x[_j] = _kept(_s) if _j else _s",
        "return jnp.stack(_x)",
    ]
    columns_doc = (
        "x of a x = b, for a (rows of n scalars, symmetric positive definite: only a[i][j] with i >= j is read) and b (n\n"
        "values); each scalar may be an array of a batch (the batch last), and so is each component of x. Left-looking\n"
        "L D L^T of the bordered matrix [[a, b], [b^T, 0]] without pivoting (no square roots): column j of L and D L^T\n"
        "is one array a[j:, j] - sum_k L[j:, k] (D L^T)[k, j] (stored, `_kept`), and the bordered row gives\n"
        "w = D^-1 L^-1 b; then x = L^-T w, one component at a time."
    )
    batched_doc = (
        "_ldl_columns(a, b), with a batching rule: under jax.vmap each scalar of a is an array of the batch and b\n"
        "is moved to (n, batch), so that every column of L is one loop over n - j times the batch values."
    )
    rule = [
        "a = jax.tree.map(lambda _e, _t: _e if _t else jnp.broadcast_to(_e, (size,)), a, batched[0])",
        "b = jnp.moveaxis(b, 0, -1) if batched[1] else jnp.broadcast_to(b[..., None], (*b.shape, size))",
        "return jnp.moveaxis(_ldl_columns(a, b), -1, 0), True",
    ]
    solve_doc = (
        "x of a x = b for a symmetric positive definite a (rows of n scalars) and an array b of n values, by\n"
        "_ldl_batched inside jax.lax.custom_linear_solve (symmetric): jax.jvp and jax.grad differentiate x = a^-1 b\n"
        "through a and b by the same solve."
    )
    solve = [
        "_matvec = lambda _v: jnp.stack([sum(_e * _v[_j] for _j, _e in enumerate(_row)) for _row in a])",
        "return jax.lax.custom_linear_solve(_matvec, b, lambda _f, _r: _ldl_batched(a, _r), symmetric=True)",
    ]
    return [
        define("_ldl_columns", "a, b", columns_doc, columns),
        "@jax.custom_batching.custom_vmap\n" + define("_ldl_batched", "a, b", batched_doc, ["return _ldl_columns(a, b)"]),
        "@_ldl_batched.def_vmap\n" + define("_ldl_batched_rule", "size, batched, a, b", "The batching rule of _ldl_batched.", rule),
        define("_spd_solve", "a, b", solve_doc, solve),
    ]


def kept(code: str) -> str:
    """`_kept(code)` when the printed expression `code` calls sin, cos or tan (`KEPT_CALLS`), else `code`.
    Meant for the right-hand side of a temporary (a value used more than once): under `jax.jit` of
    `jax.vmap` on CPU, XLA otherwise recomputes it in each fused loop that reads it (the 10-link
    chain's rhs: each of its 20 sines and cosines about 28 times; benchmarks/jax_bench.py --no-kept)."""
    return f"_kept({code})" if KEEP and KEPT_CALLS.search(code) else code


def kept_helper(used: bool = True) -> list[str]:
    """The definition of `_kept` (nothing when not `used`)."""
    if not used:
        return []
    return [
        define(
            "_kept",
            "value",
            "`value` itself, divided by value * 0 + 1: XLA computes a division once and stores it, where it would\n"
            "recompute a sine or cosine in every fused loop that uses it, and it cannot fold this divisor (a\n"
            "constant 1.0 it would). The divisor is exactly 1.0 for a finite value, and dividing by 1.0 is exact, so\n"
            "the value and its derivative are unchanged (a NaN or infinite value gives NaN).",
            ["return value / (value * 0.0 + 1.0)"],
        )
    ]


def _helpers(model: Model) -> list[str]:
    """default_parameters, _parameters and _array, as every module defines them."""
    return [
        define(
            "default_parameters",
            "",
            "The file's defaults as an array in PARAMETER_NAMES order (ValueError for a parameter without one).",
            [
                "_missing = [_name for _name in PARAMETER_NAMES if _name not in PARAMETERS]",
                "if _missing:",
                '    raise ValueError("no default for the parameters " + ", ".join(_missing))',
                "return jnp.asarray([PARAMETERS[_name] for _name in PARAMETER_NAMES], dtype=jnp.result_type(float))",
            ],
        ),
        define(
            "_parameters",
            "p",
            "The parameter values in PARAMETER_NAMES order, from None, a dict by name, or an array.",
            [
                "if p is None:",
                "    p = PARAMETERS",
                "if isinstance(p, dict):",
                "    return tuple(p[_name] if _name in p else PARAMETERS[_name] for _name in PARAMETER_NAMES)",
                "p = jnp.asarray(p)",
                "return tuple(p[_i] for _i in range(NP))",
            ],
        ),
        define("_array", "values", "A float array of `values` (nested lists of numbers and traced scalars).", ["return jnp.asarray(values, dtype=jnp.result_type(float))"]),
        *_input_helpers(model),
    ]


def _input_helpers(model: Model) -> list[str]:
    """default_inputs and _inputs, for a file with inputs."""
    if not model.inputs:
        return []
    return [
        define(
            "default_inputs",
            "",
            "The inputs' defaults as an array in INPUT_NAMES order.",
            ["return jnp.asarray([INPUTS[_name] for _name in INPUT_NAMES], dtype=jnp.result_type(float))"],
        ),
        define(
            "_inputs",
            "u",
            "The input values in INPUT_NAMES order, from None, a dict by name, or an array.",
            [
                "if u is None:",
                "    u = INPUTS",
                "if isinstance(u, dict):",
                "    return tuple(u[_name] if _name in u else INPUTS[_name] for _name in INPUT_NAMES)",
                "u = jnp.asarray(u)",
                "return tuple(u[_i] for _i in range(NU))",
            ],
        ),
    ]


# -- --form hamilton ----------------------------------------------------------------------------------

HAMILTON_GENERATED = frozenset({"MOMENTA", "momenta", "velocities", "hamiltonian"})
"""The names a Hamilton module defines besides those of `GENERATED`."""


def emit_hamilton(model: Model, *, name: str = "eom") -> str:
    """`derive --to jax --form hamilton`: the module of Hamilton's equations in the state y = [q..., p...]
    (lagrange_cli/hamilton.py; the refusals are its own: kept constraints, a name of the form `p_<q>`,
    a mass matrix depending on the velocities or singular). q_dot = M^-1 (p - b) is solved numerically
    at each call (the unrolled L D L^T up to `UNROLLED_MAX` coordinates, `jnp.linalg.solve` above),
    never inverted symbolically; then p_dot = dL/dq + Q - dR/dq_dot at that q_dot and H = p . q_dot - L."""
    from lagrange_cli.hamilton import hamilton

    definitions = model.definitions
    require_defined(model, "JAX code")
    model = model.with_definitions()
    ham = hamilton(model, symbolic=False)
    check_invertible(model)
    return _HamiltonWriter(model, definitions, ham.p, ham.bias, ham.rates).module()


class _HamiltonWriter(_Writer):
    def __init__(self, model: Model, definitions: Any, momenta: Sequence[sp.Symbol], bias: Sequence[sp.Expr], rates: Sequence[sp.Expr]) -> None:
        super().__init__(model, definitions)
        self.names = jax_names(model, [str(s) for s in momenta], HAMILTON_GENERATED)
        self.momenta = list(momenta)
        self.shifted = [to_symengine(m - b) for m, b in zip(momenta, bias, strict=True)]
        self.momentum_exprs = [to_symengine(sum((model.mass_matrix[i, j] * model.qd[j] for j in range(model.n)), b)) for i, b in enumerate(bias)]
        self.rates = [to_symengine(r) for r in rates]
        self.energy = to_symengine(sum((m * v for m, v in zip(momenta, model.qd, strict=True)), -model.lagrangian))

    def unpack_state(self, inputs: bool = False) -> list[str]:
        """Lines binding the parameters (the inputs too when `inputs`) and y = [q..., p...] to the user's names and the momenta."""
        model = self.model
        lines = self.unpack_parameters(inputs)
        state = [*model.q, *self.momenta]
        lines.append("y = jnp.asarray(y)")
        lines.append(", ".join(self.names[str(v)] for v in state) + " = " + ", ".join(f"y[{i}]" for i in range(len(state))))
        return lines

    def velocity_lines(self, inputs: bool = False) -> list[str]:
        """The body lines binding the velocities' names to M^-1 (p - b) (and the inputs' names when `inputs`)."""
        n = self.model.n
        lines, results = self.block([*self.mass, *self.shifted], "m")
        m = dict(zip(self.upper, results[: len(self.mass)], strict=True))
        velocities = [self.names[str(v)] for v in self.model.qd]
        body = [*self.unpack_state(inputs), *lines]
        if n <= UNROLLED_MAX:
            zero = {ij for ij, expr in zip(self.upper, self.mass, strict=True) if expr == 0}
            mass = {ij: (None if ij in zero else code) for ij, code in m.items()}
            shifted = [None if expr == 0 else code for expr, code in zip(self.shifted, results[len(self.mass) :], strict=True)]
            solved = unrolled_solve(n, mass, shifted, [], [], self.solve_keep())
            return body + solved.lines + [", ".join(velocities) + " = " + ", ".join(solved.results)]
        rows = ", ".join("[" + ", ".join(m[(min(i, j), max(i, j))] for j in range(n)) + "]" for i in range(n))
        body.append(f"_v = jnp.linalg.solve(_array([{rows}]), _array([{', '.join(results[len(self.mass) :])}]))")
        return [*body, ", ".join(velocities) + " = " + ", ".join(f"_v[{i}]" for i in range(n))]

    def module(self) -> str:
        model = self.model
        qd = ", ".join(self.names[str(v)] for v in model.qd)
        state = ", ".join(map(str, (*model.q, *self.momenta)))
        rate_lines, rates = self.block(self.rates, "r")
        energy_lines, energy = self.block([self.energy], "h")
        speeds = [*self.mass, *self.shifted]
        functions = [
            self.function("momenta", "The momenta p = dL/dq_dot = M q_dot + b of the state (q, q_dot): the map to this module's state.", self.momentum_exprs, "q,q_dot", "vector"),
            define(
                "velocities",
                self.arguments("y", speeds),
                "q_dot = M^-1 (p - b), solved numerically, at y = [q..., p...].",
                [*self.velocity_lines(self.uses_inputs(speeds)), f"return _array([{qd}])"],
            ),
            define(
                "hamiltonian",
                self.arguments("y", [*speeds, self.energy]),
                "H = p . q_dot - L at y = [q..., p...], q_dot solved numerically.",
                [*self.velocity_lines(self.uses_inputs([*speeds, self.energy])), *energy_lines, f"return _array({energy[0]})"],
            ),
            define(
                "rhs",
                self.arguments("y", [*speeds, *self.rates]),
                f"dy/dt = [dH/dp, -dH/dq + Q] for y = [{state}]: an array of {2 * model.n} values (jit-, vmap- and grad-compatible).",
                [*self.velocity_lines(self.uses_inputs([*speeds, *self.rates])), *rate_lines, f"return _array([{qd}, {', '.join(rates)}])"],
            ),
        ]
        missing = [p.name for p in model.parameters if p.value is None]
        defaults = ", ".join(f"{literal(p.name)}: {_number(p.value)}" for p in model.parameters if p.value is not None)
        parameter_names = ", ".join(literal(p.name) for p in model.parameters) + ("," if len(model.parameters) == 1 else "")
        coordinates = ", ".join(literal(c) for c in model.coordinates) + ("," if model.n == 1 else "")
        momenta = ", ".join(literal(str(p)) for p in self.momenta) + ("," if model.n == 1 else "")
        header = [
            f"{model.title}: Hamilton's equations generated by lagrange {__version__} from {Path(model.source).name}, for JAX.",
            "",
            f"The state is y = [{state}]: the coordinates and their momenta p = dL/dq_dot (not the velocities).",
            "rhs(t, y, p) gives dy/dt = [dH/dp, -dH/dq + Q]; hamiltonian(t, y, p) and velocities(t, y, p) give H and q_dot;",
            "momenta(t, q, q_dot, p) maps a state (q, q_dot) to its momenta. q_dot = M^-1 (p - b) is solved numerically at each",
            "call (no symbolic inverse). Each function is pure jax.numpy, so jax.jit, jax.vmap and jax.grad apply.",
            "p is None (the file's defaults, PARAMETERS), a dict by name (missing names take their defaults) or an array",
            "of NP values in PARAMETER_NAMES order (default_parameters() gives the defaults so).",
            "",
            "Float64: JAX computes in float32 unless 64-bit mode is on. For results that agree with the other targets",
            'to about 1e-12, run `import jax; jax.config.update("jax_enable_x64", True)` before creating any array;',
            "this module leaves that global setting to you.",
        ]
        if self.definitions:
            header += ["", written_definitions(self.definitions)]
        if missing:
            header += ["", f"Parameters without a default, to be given in p: {', '.join(missing)}."]
        if model.inputs:
            header += [
                "",
                f"Inputs u = [{', '.join(i.name for i in model.inputs)}] are given values at time t (Hamilton's equations treat them as given",
                "functions of time): every function whose result depends on one takes u after p, as p: None (INPUTS, the",
                "defaults), a dict by name or an array of NU values in INPUT_NAMES order (default_inputs()).",
            ]
        constants = [
            f"COORDINATES = ({coordinates})",
            f"MOMENTA = ({momenta})",
            f"PARAMETER_NAMES = ({parameter_names})",
            f"PARAMETERS = {{{defaults}}}",
            f"NQ = {model.n}",
            f"NP = {len(model.parameters)}",
            *input_constants(model),
        ]
        head = docstring("\n".join([*header, ""])) + "\n\n" + ("import jax\n" if self.uses_sincos else "") + "import jax.numpy as jnp\n\n" + "\n".join(constants)
        return head + "\n\n\n" + "\n\n\n".join([*_helpers(model), *kept_helper(self.uses_kept), *sincos_helper(self.uses_sincos), *functions]) + "\n"


UNROLLED_MAX = 20
"""Largest n + k (coordinates plus kept constraints) whose linear system is solved by unrolled
scalar code (`unrolled_solve`) rather than `jnp.linalg.solve`; measured by benchmarks/jax_bench.py
(BENCHMARKS.md, 2026-11-26: with `_kept`, unrolled code takes 12 against 45 ms for 10^4 states of the
15-link chain and 39-48 against 80 ms at 20 links, for a first call of 5.2 against 3.9 s and 9.3 against 6.4 s)."""


@dataclass
class Solved:
    """Straight-line code for a solve: the lines, and the printed solution components."""

    lines: list[str]
    results: list[str]
    pivots: list[str] = field(default_factory=list)
    """The pivots D of M's factors (the sweep's lane code tests them: numeric/lanes.py)."""


def unrolled_solve(
    n: int,
    mass: dict[tuple[int, int], str | None],
    forcing: Sequence[str | None],
    jacobian: Sequence[Sequence[str | None]],
    bias: Sequence[str | None],
    keep: Callable[[str], str] | None = None,
) -> Solved:
    """Scalar code for M x = F (and, with rows of A, for M x - A^T lam = F, A x = bias): the solution
    [x..., lam...] as one line per scalar, so that under `jax.vmap` every operation is elementwise over
    the batch (`jnp.linalg.solve` runs one LAPACK call per matrix on CPU).

    M (its upper triangle, None for a structural zero) is symmetric positive definite, so it is
    factored as L D L^T without pivoting (no square roots: smooth for `jax.grad`; structural zeros
    are skipped, so a diagonal M costs n divisions). Kept constraints use the Schur complement
    rather than an unpivoted LU of the saddle-point matrix [[M, -A^T], [A, 0]], whose zero block
    needs pivoting: with Y = M^-1 A^T and x0 = M^-1 F (the same factors), S = A Y is symmetric
    positive definite when A has full rank, lam solves S lam = bias - A x0 (L D L^T again), and
    x = x0 + Y lam. Both factorizations are of positive definite matrices, where L D L^T without
    pivoting is backward stable.

    `keep` (the writers pass `_Writer.keep`: `_kept(code)`), when given, wraps each value computed here other
    than a division (the sums of products: pivots, updated entries, substitutions), so that XLA stores it
    rather than recomputing it in every fused loop that reads it (XLA computes a division once by itself)."""
    lines: list[str] = []
    counter = iter(range(1 << 30))

    def let(code: str) -> str:
        name = f"_u{next(counter)}"
        stored = keep is not None and " / " not in code and not code.isidentifier()
        lines.append(f"{name} = {keep(code) if stored and keep is not None else code}")
        return name

    def combine(base: str | None, terms: Sequence[str]) -> str | None:
        """base - sum(terms), None for a structural zero."""
        if not terms:
            return base
        sub = " - ".join(terms)
        return let(f"{base} - {sub}" if base is not None else f"-({' + '.join(terms)})")

    def factor(size: int, matrix: Callable[[int, int], str | None]) -> tuple[dict[tuple[int, int], str], list[str]]:
        """L (strictly lower, by (i, j); absent entries are zero) and D of L D L^T."""
        low: dict[tuple[int, int], str] = {}
        diagonal: list[str] = []
        products: dict[tuple[int, int], str] = {}  # L_ik D_k
        for j in range(size):
            d = combine(matrix(j, j), [f"{low[(j, k)]} * {products[(j, k)]}" for k in range(j) if (j, k) in low])
            assert d is not None, "a structurally zero pivot"
            diagonal.append(d)
            for i in range(j + 1, size):
                value = combine(matrix(i, j), [f"{low[(i, k)]} * {products[(j, k)]}" for k in range(j) if (i, k) in low and (j, k) in low])
                if value is not None:
                    products[(i, j)] = value
                    low[(i, j)] = let(f"{value} / {diagonal[j]}")
        return low, diagonal

    def substitute(size: int, low: dict[tuple[int, int], str], diagonal: list[str], vector: Sequence[str | None]) -> list[str | None]:
        """(L D L^T)^-1 vector."""
        forward: list[str | None] = []
        for i in range(size):
            forward.append(combine(vector[i], [f"{low[(i, k)]} * {forward[k]}" for k in range(i) if (i, k) in low and forward[k] is not None]))
        scaled = [None if v is None else let(f"{v} / {diagonal[i]}") for i, v in enumerate(forward)]
        back: list[str | None] = [None] * size
        for i in reversed(range(size)):
            back[i] = combine(scaled[i], [f"{low[(k, i)]} * {back[k]}" for k in range(i + 1, size) if (k, i) in low and back[k] is not None])
        return back

    def bound(code: str | None) -> str | None:
        """A printed input as a name of its own, so that it is an operand anywhere."""
        return None if code is None else let(code)

    mass = {ij: bound(code) for ij, code in mass.items()}
    forcing = [bound(code) for code in forcing]
    jacobian = [[bound(code) for code in row] for row in jacobian]
    bias = [bound(code) for code in bias]

    def entry(i: int, j: int) -> str | None:
        return mass[(min(i, j), max(i, j))]

    low, diagonal = factor(n, entry)
    x0 = substitute(n, low, diagonal, list(forcing))
    k = len(jacobian)
    if not k:
        return Solved(lines, [v if v is not None else "0.0" for v in x0], diagonal)
    columns = [substitute(n, low, diagonal, list(row)) for row in jacobian]  # Y = M^-1 A^T, by column
    schur: dict[tuple[int, int], str | None] = {}
    for r in range(k):
        for s in range(r, k):
            terms = [f"{jacobian[r][j]} * {columns[s][j]}" for j in range(n) if jacobian[r][j] is not None and columns[s][j] is not None]
            schur[(r, s)] = let(" + ".join(terms)) if terms else None
    reduced = [combine(bias[r], [f"{jacobian[r][j]} * {x0[j]}" for j in range(n) if jacobian[r][j] is not None and x0[j] is not None]) for r in range(k)]
    low_s, diagonal_s = factor(k, lambda r, s: schur[(min(r, s), max(r, s))])
    lam = substitute(k, low_s, diagonal_s, reduced)
    x: list[str] = []
    for j in range(n):
        start = x0[j]
        terms = [f"{columns[r][j]} * {lam[r]}" for r in range(k) if columns[r][j] is not None and lam[r] is not None]
        x.append(let(" + ".join(([start] if start is not None else []) + terms)) if terms else (start if start is not None else "0.0"))
    return Solved(lines, [*x, *(v if v is not None else "0.0" for v in lam)], diagonal)


def _negate(code: str) -> str:
    """The negation of a printed expression."""
    if code.startswith("-") and code[1:].replace("_", "a").replace(".", "0").isalnum():
        return code[1:]
    return "-" + code if code.replace("_", "a").replace(".", "0").isalnum() else f"-({code})"


def _number(value: float | None) -> str:
    assert value is not None
    return repr(float(value)) if math.isfinite(value) else f'float("{value}")'
