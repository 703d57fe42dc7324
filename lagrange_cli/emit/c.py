"""C: one header-only C99 file with the equations of motion, for a controller or an integrator loop.

`lagrange derive FILE --to c [--prefix NAME]` writes (with the prefix `eom`):

- `EOM_NQ` (coordinates), `EOM_NP` (parameters), `EOM_NC` (kept constraints, i.e. multipliers);
- `eom_default_parameters[EOM_NP]`: the file's defaults, in the file's order (listed in the
  header comment; a parameter without a default is NAN there, to be given in `p`);
- `void eom_mass_matrix(double t, const double *y, const double *p, double *out)`: M, row-major n x n;
- `void eom_forcing(double t, const double *y, const double *p, double *out)`: F of M q_ddot = F (+ A^T lambda);
- `double eom_energy(double t, const double *y, const double *p)`: h = sum p_i q_dot_i - L;
- with kept constraints, `int eom_accelerations(t, y, p, out)`: [q_ddot, lambda] (n + k values) from
  [[M, -A^T], [A, 0]] x = [F, -c] (index-1 form);
- `int eom_rhs(double t, const double *y, const double *p, double *dydt)`: dy/dt for y = [q, q_dot],
  0 on success, 1 when the (augmented) mass matrix is singular at that state, 2 when a result is
  not finite (outside a function's domain, an overflow); on failure the accelerations are NAN.

Everything is `static inline` (the file can be included in several translation units), nothing is
allocated, the only global is the `const` default array, and the only header is `<math.h>`. The
solve is Gaussian elimination with scaled partial pivoting (rows divided by their largest entry,
then the largest pivot; a pivot below 1e-13 of its row is singular), as the Python module's `_solve`;
an unconstrained system (M symmetric, positive definite wherever the motion is defined) first tries
a straight-line LDL^T (up to `LDLT_SIZE` coordinates) and falls back to the LU solve when a pivot
is not clearly positive. Each function's expressions go through the printer core's `restructure`
(sin and cos of each angle once, sin/cos of differences as products, collected coefficients) and
one CSE. The code compiles cleanly as C99 (`gcc -std=c99 -Wall -Wextra -Werror -pedantic`) and as C++.

Safe with any system file: file text (title, file name, names) enters only comments, as printable
ASCII in which `*/`, `/*` and `??` (a trigraph) are broken apart and no line ends in a backslash;
user names are mangled (`mangle`) apart from C and C++ keywords, `<math.h>` names and macros, and
every name the file defines itself (its own locals start with `_`, which no user name does).
"""

from __future__ import annotations

import math
import re
from collections.abc import Collection, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

from lagrange_cli import __version__
from lagrange_cli._symengine import to_symengine
from lagrange_cli.algebra import check_solvable
from lagrange_cli.emit.common import printable, require_defined, written_definitions
from lagrange_cli.emit.printer import ATOM, EXACT, MUL, Code, Printer
from lagrange_cli.emit.python import code_lines, mangle, needed
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

# -- the printer -----------------------------------------------------------------------------------


class CPrinter(Printer):
    """C99 with <math.h>: a lone rational as `1.0/3.0`, so that no integer division can happen
    (everywhere else an integer meets a double: `x/2`, `2*x`, `1/x`, `pow(x, 3)`); `sign` as a
    conditional; a non-integer power as `pow`; 1/tan as `(1.0/tan(x))`."""

    functions: ClassVar[Mapping[str, str]] = {**Printer.functions, "pow": "pow"}
    power_operator: ClassVar[str | None] = None

    def rational(self, p: int, q: int) -> Code:
        if max(p, q) >= EXACT:
            return self.real(p / q)
        return f"{p}.0/{q}.0", MUL

    def nonfinite(self, value: float) -> Code:
        return ("NAN" if math.isnan(value) else "HUGE_VAL"), ATOM

    def _print_sign(self, expr: Any) -> Code:
        x = self.parenthesize(expr.args[0], ATOM)
        return f"({x} > 0.0 ? 1.0 : ({x} < 0.0 ? -1.0 : 0.0))", ATOM

    def _print_Function(self, expr: Any) -> Code:
        name = type(expr).__name__
        if name in self.reciprocals:  # 1.0/tan(x), never the integer 1
            text, _ = self.call(self.function_name(self.reciprocals[name]), [self.doprint(a) for a in expr.args])
            return f"(1.0/{text})", ATOM
        return super()._print_Function(expr)


# -- names ------------------------------------------------------------------------------------------

C_KEYWORDS = frozenset(
    {
        *("auto", "break", "case", "char", "const", "continue", "default", "do", "double", "else", "enum", "extern", "float", "for", "goto", "if"),
        *("inline", "int", "long", "register", "restrict", "return", "short", "signed", "sizeof", "static", "struct", "switch", "typedef", "union"),
        *("unsigned", "void", "volatile", "while", "_Bool", "_Complex", "_Imaginary", "bool", "true", "false", "complex", "imaginary", "I"),
        # C++ (the header compiles as C++ too), its alternative tokens, and common predefined macros
        *("alignas", "alignof", "and", "and_eq", "asm", "bitand", "bitor", "catch", "char16_t", "char32_t", "char8_t", "class", "compl", "concept"),
        *("consteval", "constexpr", "constinit", "const_cast", "co_await", "co_return", "co_yield", "decltype", "delete", "dynamic_cast", "explicit"),
        *("export", "friend", "mutable", "namespace", "new", "noexcept", "not", "not_eq", "nullptr", "operator", "or", "or_eq", "private"),
        *("protected", "public", "reinterpret_cast", "requires", "static_assert", "static_cast", "template", "this", "thread_local", "throw"),
        *("try", "typeid", "typename", "using", "virtual", "wchar_t", "xor", "xor_eq", "std", "linux", "unix", "i386", "NULL", "main", "errno"),
        *("assert", "alloca", "offsetof", "size_t", "ptrdiff_t", "fortran", "asm"),
    }
)
MATH_H = frozenset(
    {
        *("acos", "asin", "atan", "atan2", "cos", "sin", "tan", "acosh", "asinh", "atanh", "cosh", "sinh", "tanh", "exp", "exp2", "expm1", "frexp"),
        *("ilogb", "ldexp", "log", "log10", "log1p", "log2", "logb", "modf", "scalbn", "scalbln", "cbrt", "fabs", "hypot", "pow", "sqrt", "erf"),
        *("erfc", "lgamma", "tgamma", "ceil", "floor", "nearbyint", "rint", "lrint", "llrint", "round", "lround", "llround", "trunc", "fmod"),
        *("remainder", "remquo", "copysign", "nan", "nextafter", "nexttoward", "fdim", "fmax", "fmin", "fma", "gamma", "j0", "j1", "jn", "y0"),
        *("y1", "yn", "drem", "finite", "significand", "scalb", "signgam", "isinf", "isnan", "fpclassify", "isfinite", "isnormal", "signbit"),
        *("isgreater", "isgreaterequal", "isless", "islessequal", "islessgreater", "isunordered", "issubnormal", "iszero", "issignaling"),
        *("math_errhandling", "double_t", "float_t", "INFINITY", "NAN", "HUGE_VAL", "HUGE_VALF", "HUGE_VALL", "MAXFLOAT", "PLOSS", "TLOSS"),
        *("DOMAIN", "SING", "OVERFLOW", "UNDERFLOW", "exception", "matherr"),
    }
)
MACROS = frozenset(
    {
        *("WCONTINUED", "WEXITED", "WEXITSTATUS", "WIFCONTINUED", "WIFEXITED", "WIFSIGNALED", "WIFSTOPPED", "WNOHANG", "WNOWAIT", "WSTOPPED"),
        *("WSTOPSIG", "WTERMSIG", "WUNTRACED", "SNAN", "SNANF", "SNANL", "NFDBITS", "be16toh", "be32toh", "be64toh", "htobe16", "htobe32"),
        *("htobe64", "htole16", "htole32", "htole64", "le16toh", "le32toh", "le64toh"),
    }
)
"""Macros without an underscore family that glibc's <math.h> defines in C++ (GNU) mode."""
MACRO_FAMILIES = re.compile(r"(M|FP|HUGE_VAL|SNAN|MATH_ERR|FD|EXIT|BYTE|BIG|LITTLE|PDP|RAND|MB|INT|UINT|SIZE|PTRDIFF)_[A-Za-z0-9_]*[A-Za-z0-9]")
"""Macro families of glibc's <math.h> in C++ or GNU mode (M_PI, M_PIf, FP_NAN, HUGE_VAL_F64, ...). A
name ending in `_` never matches, so that `mangle` (which appends `_`) always finds a free name."""


class Reserved(Collection[str]):
    """A set of names plus the names a pattern matches (for `mangle`)."""

    def __init__(self, names: Collection[str], pattern: re.Pattern[str] | None = None) -> None:
        self.names = frozenset(names)
        self.pattern = pattern

    def __contains__(self, name: object) -> bool:
        if not isinstance(name, str):
            return False
        return name in self.names or (self.pattern is not None and bool(self.pattern.fullmatch(name)))

    def __iter__(self) -> Iterator[str]:
        return iter(self.names)

    def __len__(self) -> int:
        return len(self.names)


WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
LOCALS = ("t", "y", "p", "u", "out", "dydt")
"""The generated functions' arguments (every other local starts with `_`)."""


def generated(prefix: str) -> list[str]:
    """The names the C file defines for `prefix`."""
    upper = prefix.upper()
    return [
        *(f"{prefix}_{n}" for n in ("rhs", "mass_matrix", "forcing", "energy", "accelerations", "default_parameters", "default_inputs", "solve", "ldlt")),
        *(f"{upper}_{n}" for n in ("NQ", "NP", "NC", "NU", "H_INCLUDED")),
    ]


def c_names(model: Model, prefix: str, momenta: Sequence[str] = ()) -> dict[str, str]:
    """symbol name -> C identifier for the coordinates, velocities and parameters (and `momenta`,
    with the Hamilton form's function names reserved too) (`mangle`), and t."""
    symbols = [str(s) for s in (*model.q, *model.qd, *(p.symbol for p in model.parameters), *(i.symbol for i in model.inputs))] + list(momenta)
    extra = [f"{prefix}_{n}" for n in HAMILTON_FUNCTIONS] if momenta else []
    names = mangle(symbols, Reserved({*C_KEYWORDS, *MATH_H, *MACROS, *LOCALS, *generated(prefix), *extra}, MACRO_FAMILIES))
    return {**names, str(model.t): "t"}


def comment(text: str) -> str:
    """`text` for a C block comment: printable ASCII (others as U+XXXX, line breaks as spaces),
    with `*/`, `/*` and `??` broken apart by a space and a trailing backslash followed by a dot,
    so that it can neither end the comment, open a nested one, form a trigraph nor splice lines."""
    out = "".join(c if " " <= c <= "~" else f"U+{ord(c):04X}" for c in printable(text))
    for pair in ("*/", "/*", "??"):
        while pair in out:
            out = out.replace(pair, f"{pair[0]} {pair[1]}")
    return out + "." if out.endswith("\\") else out


# -- the file -------------------------------------------------------------------------------------


def emit(model: Model, *, name: str = "eom") -> str:
    """The header's text; `name` is the prefix of every name it defines. The file's functions are
    written out from their definitions (`Model.with_definitions`); undefined ones are refused."""
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name):
        raise DerivationError(f"the C prefix '{printable(name)}' is not a C identifier")
    definitions = model.definitions
    model = model.with_definitions()
    require_defined(model, "C code")
    check_solvable(model)
    return _Writer(model, name, definitions).file()


class _Writer:
    def __init__(self, model: Model, prefix: str, definitions: Mapping[str, Any], momenta: Sequence[str] = ()) -> None:
        self.model = model
        self.prefix = prefix
        self.upper = prefix.upper()
        self.definitions = definitions
        self.names = c_names(model, prefix, momenta)
        n = model.n
        forms = model.symengine
        self.upper_cells = [(i, j) for i in range(n) for j in range(i, n)]
        self.mass = [forms.mass[i][j] for i, j in self.upper_cells]
        self.forcing = list(forms.forcing)
        self.energy = forms.energy
        self.jacobian = [to_symengine(a) for c in model.constraints for a in c.jacobian]
        self.bias = [to_symengine(c.acceleration_bias) for c in model.constraints]
        self.index = {str(s): f"y[{i}]" for i, s in enumerate((*model.q, *model.qd))}
        self.index |= {p.name: f"p[{i}]" for i, p in enumerate(model.parameters)}
        self.index |= {i.name: f"u[{k}]" for k, i in enumerate(model.inputs)}  # inputs: `const double *u` after p (FORMAT.md version 2)
        self.constants = frozenset([*(p.name for p in model.parameters), *(i.name for i in model.inputs)])
        self.signals = ["const double *u"] if model.inputs else []
        self.velocities = frozenset(str(v) for v in forms.qd)

    def block(self, exprs: Sequence[Any], used: set[str]) -> tuple[list[str], list[str]]:
        """Lines binding what `exprs` use (state, parameters), the temporaries, then the results:
        the printer core's restructuring (sin/cos of each angle once, differences as products,
        collected coefficients) and CSE, keeping only the lines the results need."""
        printer = CPrinter(self.names)
        lines, results = code_lines(printer, exprs, self.constants, self.velocities)
        lines = needed(lines, results)
        words = {w for code in [*results, *(code for _, code in lines)] for w in WORD.findall(code)}
        bound = [s for s in self.index if self.names[s] in words]
        used.update(bound)
        if "t" in words:
            used.add(str(self.model.t))
        return [f"const double {self.names[s]} = {self.index[s]};" for s in bound] + [f"const double {name} = {code};" for name, code in lines], results

    def function(self, returns: str, name: str, doc: str, body: list[str], used: set[str], out: str = "out") -> str:
        arguments = ["double t", "const double *y", "const double *p", *self.signals] + ([f"double *{out}"] if out else [])
        reads = {"t": str(self.model.t) in used, **{a: any(self.index.get(s, "").startswith(a + "[") for s in used) for a in ("y", "p", "u"[: len(self.signals)]) if a}}
        lines = [f"/* {comment(doc)} */", f"static inline {returns} {self.prefix}_{name}({', '.join(arguments)})", "{"]
        lines += [f"    (void){a};" for a, read in reads.items() if not read]
        lines += [f"    {line}" for line in body]
        return "\n".join([*lines, "}"])

    def mass_matrix(self) -> str:
        n = self.model.n
        used: set[str] = set()
        lines, results = self.block(self.mass, used)
        cell = dict(zip(self.upper_cells, results, strict=True))
        for i, j in self.upper_cells:
            lines.append(f"out[{i * n + j}] = {cell[(i, j)]};")
            if i != j:
                lines.append(f"out[{j * n + i}] = out[{i * n + j}];")
        return self.function("void", "mass_matrix", f"M (row-major, {n} x {n}; symmetric) at y's coordinates.", lines, used)

    def forcing_function(self) -> str:
        used: set[str] = set()
        lines, results = self.block(self.forcing, used)
        lines += [f"out[{i}] = {r};" for i, r in enumerate(results)]
        plus = " + A^T lambda" if self.model.constraints else ""
        return self.function("void", "forcing", f"F of M q_ddot = F{plus} ({self.model.n} values).", lines, used)

    def energy_function(self) -> str:
        used: set[str] = set()
        lines, results = self.block([self.energy], used)
        lines.append(f"return {results[0]};")
        return self.function("double", "energy", "The energy function h = sum p_i q_dot_i - L.", lines, used, out="")

    def solve_into(self, size: int) -> tuple[list[str], set[str]]:
        """Lines that fill `_a` (size x size) and `_b` and solve, leaving the solution in `_b`."""
        n, k = self.model.n, len(self.model.constraints)
        used: set[str] = set()
        lines, results = self.block([*self.mass, *self.forcing, *self.jacobian, *self.bias], used)
        mass = dict(zip(self.upper_cells, results[: len(self.mass)], strict=True))
        rest = results[len(self.mass) :]
        force, jacobian, bias = rest[:n], rest[n : n + n * k], rest[n + n * k :]
        lines.insert(0, f"double _a[{size * size}];")
        lines.insert(1, f"double _b[{size}];")
        lines.insert(2, "int _status;")
        for i, j in self.upper_cells:
            lines.append(f"_a[{i * size + j}] = {mass[(i, j)]};")
            if i != j:
                lines.append(f"_a[{j * size + i}] = _a[{i * size + j}];")
        for r in range(k):
            for j in range(n):
                lines.append(f"_a[{(n + r) * size + j}] = {jacobian[r * n + j]};")
                lines.append(f"_a[{j * size + n + r}] = -_a[{(n + r) * size + j}];")
            for s in range(k):
                lines.append(f"_a[{(n + r) * size + n + s}] = 0.0;")
        lines += [f"_b[{i}] = {f};" for i, f in enumerate(force)]
        lines += [f"_b[{n + r}] = -{_parenthesized(c)};" for r, c in enumerate(bias)]
        lines.append(f"_status = {self.prefix}_solve({size}, _a, _b);")
        return lines, used

    def accelerations(self) -> str:
        n, k = self.model.n, len(self.model.constraints)
        lines, used = self.solve_into(n + k)
        lines += [
            f"for (_i = 0; _i < {n + k}; ++_i) {{",
            "    out[_i] = _status ? NAN : _b[_i];",
            "    if (!_status && !isfinite(out[_i])) _status = 2;",
            "}",
            "return _status;",
        ]
        lines.insert(0, "int _i;")
        qdd = ", ".join(map(str, self.model.qdd))
        multipliers = ", ".join(map(str, self.model.multipliers))
        doc = f"[{qdd}, {multipliers}] ({n + k} values) from [[M, -A^T], [A, 0]] x = [F, -c] (index-1 form); 0, or 1 when singular, 2 when not finite."
        return self.function("int", "accelerations", doc, lines, used)

    def rhs(self) -> str:
        n, k = self.model.n, len(self.model.constraints)
        if k:
            lines = [
                "int _i;",
                f"double _x[{n + k}];",
                f"const int _status = {self.prefix}_accelerations(t, y, p, {'u, ' if self.signals else ''}_x);",
                f"for (_i = 0; _i < {n}; ++_i) {{",
                "    dydt[_i] = y[_i + EOM_NQ];".replace("EOM", self.upper),
                "    dydt[_i + EOM_NQ] = _x[_i];".replace("EOM", self.upper),
                "}",
                "return _status;",
            ]
            return self.function("int", "rhs", "dy/dt for y = [q, q_dot]: 0, or 1 when singular at y, 2 when not finite.", lines, {str(self.model.t), *self.index}, out="dydt")
        lines, used = self.solve_into(n)
        if n <= LDLT_SIZE:  # M is symmetric (positive definite where the motion is defined): LDL^T first, LU when it fails
            lines[-1] = f"_status = {self.prefix}_ldlt(_a, _b) == 0 ? 0 : {self.prefix}_solve({n}, _a, _b);"
        lines.insert(0, "int _i;")
        lines += [
            f"for (_i = 0; _i < {n}; ++_i) {{",
            f"    dydt[_i] = y[_i + {n}];",
            f"    dydt[_i + {n}] = _status ? NAN : _b[_i];",
            "}",
            f"for (_i = 0; _i < {2 * n} && !_status; ++_i) if (!isfinite(dydt[_i])) _status = 2;",
            "return _status;",
        ]
        used |= {s for s in self.index if self.index[s].startswith("y[")}
        return self.function("int", "rhs", "dy/dt for y = [q, q_dot]: 0, or 1 when M is singular at y, 2 when a value is not finite.", lines, used, out="dydt")

    def header(self) -> str:
        model = self.model
        t = "" if model.autonomous else ", t"
        coordinates = ", ".join(f"y[{i}] = {c}" for i, c in enumerate(model.coordinates))
        n = model.n
        lines = [
            f"{model.title}: equations of motion generated by lagrange {__version__} from {Path(model.source).name}.",
            "",
            f"M(q{t}) q_ddot = F(q, q_dot{t})" + (" + A^T lambda, with A q_ddot + c = 0 for the kept constraints" if model.constraints else "") + ".",
            f"State y = [q, q_dot] ({2 * n} values): {coordinates}, and their velocities y[{n}] ... y[{2 * n - 1}].",
        ]
        notes = []
        if model.constraints:
            notes.append("Kept constraints (their multipliers follow q_ddot in " + f"{self.prefix}_accelerations): " + ", ".join(c.name for c in model.constraints) + ".")
        return self.comment_block(lines, notes)

    def comment_block(self, opening: list[str], notes: list[str]) -> str:
        """The header comment: `opening` (what the form computes), the parameters and inputs, `notes`, the functions
        written out, the names changed, and what `<prefix>_rhs` returns."""
        model = self.model
        lines = list(opening)
        if model.parameters:
            lines.append(f"Parameters p ({self.upper}_NP = {len(model.parameters)}, in the file's order, defaults in {self.prefix}_default_parameters):")
            for i, p in enumerate(model.parameters):
                default = "no default: give it in p" if p.value is None else f"default {p.value!r}"
                lines.append(f"  p[{i}] = {p.name} ({default})")
        else:
            lines.append(f"No parameters ({self.upper}_NP = 0; p is not read).")
        if model.inputs:
            lines.append(f"Inputs u ({self.upper}_NU = {len(model.inputs)}, in the file's order, after p in every function; defaults in {self.prefix}_default_inputs):")
            lines += [f"  u[{i}] = {u.name} (default {u.value!r})" for i, u in enumerate(model.inputs)]
        lines += notes
        if self.definitions:
            lines.append(written_definitions(self.definitions))
        names = {c: v for c, v in self.names.items() if c != v and c != str(model.t)}
        if names:
            lines.append("Names changed to C identifiers: " + ", ".join(f"{c} -> {v}" for c, v in names.items()) + ".")
        lines += [
            "",
            f"int {self.prefix}_rhs(double t, const double *y, const double *p, {'const double *u, ' if self.signals else ''}double *dydt) returns 0 on success,",
            "1 when the mass matrix is singular at y, 2 when a result is not finite.",
        ]
        return "/*\n" + "\n".join((" * " + comment(line.rstrip())).rstrip() for line in lines) + "\n */"

    def inputs_block(self) -> list[str]:
        """`<PREFIX>_NU` and the inputs' defaults (nothing for a file without inputs: its header is unchanged)."""
        model = self.model
        if not model.inputs:
            return []
        values = ", ".join(_c_number(i.value) for i in model.inputs)
        return [
            f"#define {self.upper}_NU {len(model.inputs)}\n/* The inputs' defaults, in the file's order (see above). */\nstatic const double {self.prefix}_default_inputs[{len(model.inputs)}] = {{{values}}};"
        ]

    def file(self) -> str:
        model = self.model
        n, k, np_ = model.n, len(model.constraints), len(model.parameters)
        guard = f"{self.upper}_H_INCLUDED"
        defaults = ", ".join(_c_number(p.value) for p in model.parameters) if model.parameters else "0.0"
        parts = [
            self.header(),
            f"#ifndef {guard}\n#define {guard}\n\n#include <math.h>",
            f"#define {self.upper}_NQ {n}\n#define {self.upper}_NP {np_}\n#define {self.upper}_NC {k}",
            f"/* The parameters' defaults, in the file's order (see above). */\nstatic const double {self.prefix}_default_parameters[{max(np_, 1)}] = {{{defaults}}};",
            *self.inputs_block(),
            SOLVE.replace("eom_", f"{self.prefix}_"),
            self.mass_matrix(),
            self.forcing_function(),
            self.energy_function(),
        ]
        if k:
            parts.append(self.accelerations())
        elif n <= LDLT_SIZE:
            parts.append(ldlt(self.prefix, n))
        parts.append(self.rhs())
        parts.append(f"#endif /* {guard} */")
        return "\n\n".join(parts) + "\n"


# -- --form hamilton ----------------------------------------------------------------------------------

HAMILTON_FUNCTIONS = ("momenta", "velocities", "hamiltonian")


def emit_hamilton(model: Model, *, name: str = "eom") -> str:
    """`derive --to c --form hamilton`: the header of Hamilton's equations in the state y = [q, p]
    (lagrange_cli/hamilton.py; its refusals are its own). `NAME_velocities` solves M q_dot = p - b
    numerically (the straight-line LDL^T, the LU solve when it fails, as `NAME_rhs` of the Lagrange
    form), never by a symbolic inverse; `NAME_rhs` gives [q_dot, p_dot] with p_dot = dL/dq + Q - dR/dq_dot
    at that q_dot; `NAME_hamiltonian` H = p . q_dot - L; `NAME_momenta` maps [q, q_dot] to p."""
    from lagrange_cli.hamilton import hamilton

    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name):
        raise DerivationError(f"the C prefix '{printable(name)}' is not a C identifier")
    definitions = model.definitions
    model = model.with_definitions()
    require_defined(model, "C code")
    ham = hamilton(model, symbolic=False)
    check_solvable(model)
    return _HamiltonWriter(model, name, definitions, ham.p, ham.bias, ham.rates).file()


class _HamiltonWriter(_Writer):
    def __init__(self, model: Model, prefix: str, definitions: Mapping[str, Any], momenta: Sequence[Any], bias: Sequence[Any], rates: Sequence[Any]) -> None:
        super().__init__(model, prefix, definitions, [str(m) for m in momenta])
        self.momenta = list(momenta)
        self.lagrange_index = self.index
        self.index = {str(s): f"y[{i}]" for i, s in enumerate((*model.q, *momenta))}
        self.index |= {p.name: f"p[{i}]" for i, p in enumerate(model.parameters)}
        self.index |= {i.name: f"u[{k}]" for k, i in enumerate(model.inputs)}  # inputs: given values, `const double *u` after p
        self.given = "u, " if model.inputs else ""
        self.shifted = [to_symengine(m - b) for m, b in zip(momenta, bias, strict=True)]
        self.rates = [to_symengine(r) for r in rates]
        self.momentum_exprs = [to_symengine(sum((model.mass_matrix[i, j] * model.qd[j] for j in range(model.n)), b)) for i, b in enumerate(bias)]
        self.hamiltonian = to_symengine(sum((m * v for m, v in zip(momenta, model.qd, strict=True)), -model.lagrangian))

    def bind_velocities(self, lines: list[str], results: list[str], source: str) -> list[str]:
        """Declarations of the velocities that `lines` and `results` read, from `source`."""
        words = {w for code in [*results, *lines] for w in WORD.findall(code)}
        return [f"const double {self.names[str(v)]} = {source}[{i}];" for i, v in enumerate(self.model.qd) if self.names[str(v)] in words]

    def momenta_function(self) -> str:
        self.index, hamilton_index = self.lagrange_index, self.index
        try:
            used: set[str] = set()
            lines, results = self.block(self.momentum_exprs, used)
            lines += [f"out[{i}] = {r};" for i, r in enumerate(results)]
            return self.function("void", "momenta", f"The momenta p = dL/dq_dot = M q_dot + b ({self.model.n} values) of y = [q, q_dot]: the map to this file's state.", lines, used)
        finally:
            self.index = hamilton_index

    def velocities_function(self) -> str:
        n = self.model.n
        used: set[str] = set()
        lines, results = self.block([*self.mass, *self.shifted], used)
        mass = dict(zip(self.upper_cells, results[: len(self.mass)], strict=True))
        lines[:0] = [f"double _a[{n * n}];", f"double _b[{n}];", "int _status;", "int _i;"]
        for i, j in self.upper_cells:
            lines.append(f"_a[{i * n + j}] = {mass[(i, j)]};")
            if i != j:
                lines.append(f"_a[{j * n + i}] = _a[{i * n + j}];")
        lines += [f"_b[{i}] = {v};" for i, v in enumerate(results[len(self.mass) :])]
        solve = f"{self.prefix}_solve({n}, _a, _b)"
        lines.append(f"_status = {self.prefix}_ldlt(_a, _b) == 0 ? 0 : {solve};" if n <= LDLT_SIZE else f"_status = {solve};")
        lines += [
            f"for (_i = 0; _i < {n}; ++_i) {{",
            "    out[_i] = _status ? NAN : _b[_i];",
            "    if (!_status && !isfinite(out[_i])) _status = 2;",
            "}",
            "return _status;",
        ]
        doc = f"q_dot = M^-1 (p - b) ({n} values), solved numerically, at y = [q, p]: 0, or 1 when M is singular, 2 when not finite."
        return self.function("int", "velocities", doc, lines, used)

    def hamiltonian_function(self) -> str:
        n = self.model.n
        used: set[str] = set()
        lines, results = self.block([self.hamiltonian], used)
        head = [f"double _v[{n}];", f"if ({self.prefix}_velocities(t, y, p, {self.given}_v) == 1) return NAN;", *self.bind_velocities(lines, results, "_v")]
        return self.function("double", "hamiltonian", "H = p . q_dot - L at y = [q, p] (NAN where M is singular).", [*head, *lines, f"return {results[0]};"], {str(self.model.t), *self.index}, out="")

    def rhs(self) -> str:
        n = self.model.n
        used: set[str] = set()
        lines, results = self.block(self.rates, used)
        head = ["int _i;", f"double _v[{n}];", f"int _status = {self.prefix}_velocities(t, y, p, {self.given}_v);", *self.bind_velocities(lines, results, "_v")]
        body = [*head, *lines]
        body += [f"dydt[{i}] = _v[{i}];" for i in range(n)]
        body += [f"dydt[{n + i}] = _status ? NAN : {r};" for i, r in enumerate(results)]
        body += [f"for (_i = 0; _i < {2 * n} && !_status; ++_i) if (!isfinite(dydt[_i])) _status = 2;", "return _status;"]
        doc = "dy/dt = [dH/dp, -dH/dq + Q] for y = [q, p]: 0, or 1 when M is singular at y, 2 when a value is not finite."
        return self.function("int", "rhs", doc, body, {str(self.model.t), *self.index}, out="dydt")

    def header(self) -> str:
        model, n = self.model, self.model.n
        state = ", ".join(f"y[{i}] = {c}" for i, c in enumerate([*model.coordinates, *map(str, self.momenta)]))
        lines = [
            f"{model.title}: Hamilton's equations generated by lagrange {__version__} from {Path(model.source).name}.",
            "",
            f"State y = [q, p] ({2 * n} values): {state}: the coordinates and their momenta p = dL/dq_dot = M q_dot + b (not the velocities).",
            f"{self.prefix}_rhs gives dy/dt = [dH/dp, -dH/dq + Q]; {self.prefix}_velocities q_dot = M^-1 (p - b), solved numerically at each call",
            f"(no symbolic inverse); {self.prefix}_hamiltonian H = p . q_dot - L; {self.prefix}_momenta maps [q, q_dot] to p.",
        ]
        notes = ["Hamilton's equations treat the inputs as given functions of time: pass their values at t."] if model.inputs else []
        return self.comment_block(lines, notes)

    def file(self) -> str:
        model = self.model
        n, np_ = model.n, len(model.parameters)
        guard = f"{self.upper}_H_INCLUDED"
        defaults = ", ".join(_c_number(p.value) for p in model.parameters) if model.parameters else "0.0"
        parts = [
            self.header(),
            f"#ifndef {guard}\n#define {guard}\n\n#include <math.h>",
            f"#define {self.upper}_NQ {n}\n#define {self.upper}_NP {np_}\n#define {self.upper}_NC 0",
            f"/* The parameters' defaults, in the file's order (see above). */\nstatic const double {self.prefix}_default_parameters[{max(np_, 1)}] = {{{defaults}}};",
            *self.inputs_block(),
            SOLVE.replace("eom_", f"{self.prefix}_"),
            *([ldlt(self.prefix, n)] if n <= LDLT_SIZE else []),
            self.momenta_function(),
            self.velocities_function(),
            self.hamiltonian_function(),
            self.rhs(),
            f"#endif /* {guard} */",
        ]
        return "\n\n".join(parts) + "\n"


LDLT_SIZE = 24
"""Up to this many coordinates, an unconstrained rhs solves with a straight-line LDL^T first."""


def ldlt(prefix: str, n: int) -> str:
    """A straight-line LDL^T solve of the symmetric n x n `a` (row-major, read only; its lower
    triangle is used): b is overwritten with the solution and 0 returned, or 1 returned with b
    untouched as soon as a pivot d_j is not above 1e-13 a_jj (not positive definite, singular, or
    not finite), for the LU solve to decide."""
    lines = [
        "/* Solves a x = b for the symmetric a (n x n row-major, read only) by LDL^T without pivoting; x is left in b.",
        "   Returns 1 with b untouched when a pivot d_j is not above 1e-13 a_jj (then the LU solve decides). */",
        f"static inline int {prefix}_ldlt(const double *a, double *b)",
        "{",
    ]

    def minus(terms: list[str]) -> str:
        return "".join(f" - {t}" for t in terms)

    for j in range(n):
        lines.append(f"    const double _d{j} = a[{j * n + j}]{minus([f'_w{j}_{k}*_l{j}_{k}' for k in range(j)])};")
        lines.append(f"    if (!(_d{j} > 1e-13 * a[{j * n + j}])) return 1;")
        lines.append(f"    const double _r{j} = 1.0/_d{j};")
        for i in range(j + 1, n):
            lines.append(f"    const double _w{i}_{j} = a[{i * n + j}]{minus([f'_w{i}_{k}*_l{j}_{k}' for k in range(j)])};")
            lines.append(f"    const double _l{i}_{j} = _w{i}_{j}*_r{j};")
    for i in range(n):
        lines.append(f"    const double _z{i} = b[{i}]{minus([f'_l{i}_{k}*_z{k}' for k in range(i)])};")
    for i in reversed(range(n)):
        lines.append(f"    const double _x{i} = _z{i}*_r{i}{minus([f'_l{k}_{i}*_x{k}' for k in range(i + 1, n)])};")
    lines += [f"    b[{i}] = _x{i};" for i in range(n)]
    return "\n".join([*lines, "    return 0;", "}"])


def _parenthesized(code: str) -> str:
    return code if re.fullmatch(r"[A-Za-z0-9_.]+", code) else f"({code})"


def _c_number(value: float | None) -> str:
    if value is None or math.isnan(value):
        return "NAN"
    if math.isinf(value):
        return "HUGE_VAL" if value > 0 else "-HUGE_VAL"
    return repr(float(value))


SOLVE = """/* Solves a x = b for x (left in b; a is n x n row-major, both overwritten) by Gaussian elimination
   with scaled partial pivoting: each row divided by its largest entry, then the largest pivot.
   Returns 1 when a pivot is below 1e-13 of its row's largest entry (a singular matrix), 2 when
   an entry of a is not finite, else 0. */
static inline int eom_solve(int n, double *a, double *b)
{
    int i, j, k;
    for (i = 0; i < n * n; ++i)
        if (!isfinite(a[i]))
            return 2;
    for (i = 0; i < n; ++i) {
        double largest = 0.0;
        for (j = 0; j < n; ++j)
            if (fabs(a[i * n + j]) > largest)
                largest = fabs(a[i * n + j]);
        if (!(largest > 0.0))
            return 1;
        for (j = 0; j < n; ++j)
            a[i * n + j] /= largest;
        b[i] /= largest;
    }
    for (k = 0; k < n; ++k) {
        int pivot = k;
        for (i = k + 1; i < n; ++i)
            if (fabs(a[i * n + k]) > fabs(a[pivot * n + k]))
                pivot = i;
        if (!(fabs(a[pivot * n + k]) > 1e-13))
            return 1;
        if (pivot != k) {
            double swap;
            for (j = 0; j < n; ++j) {
                swap = a[k * n + j];
                a[k * n + j] = a[pivot * n + j];
                a[pivot * n + j] = swap;
            }
            swap = b[k];
            b[k] = b[pivot];
            b[pivot] = swap;
        }
        for (i = k + 1; i < n; ++i) {
            const double factor = a[i * n + k] / a[k * n + k];
            if (factor != 0.0) {
                for (j = k + 1; j < n; ++j)
                    a[i * n + j] -= factor * a[k * n + j];
                b[i] -= factor * b[k];
            }
        }
    }
    for (i = n - 1; i >= 0; --i) {
        double sum = b[i];
        for (j = i + 1; j < n; ++j)
            sum -= a[i * n + j] * b[j];
        b[i] = sum / a[i * n + i];
    }
    return 0;
}"""


# -- --form reduced -------------------------------------------------------------------------------------

REDUCED_FUNCTIONS = ("velocities", "reduce", "reduced_mass_matrix", "reduced_forcing", "independent", "dependent")
"""The reduced form's names besides those of `generated` (reserved against user names too)."""


def emit_reduced(model: Model, *, name: str = "eom") -> str:
    """`derive --to c --form reduced`: the header of Maggi's equations (lagrange_cli/reduced.py; its
    refusals are its own) in the state y = [q, u], u the independent velocities, as the Python module
    of `--form reduced` has them: `NAME_velocities` (every q_dot = C u + d), `NAME_reduce` (u from a
    full q_dot), `NAME_reduced_mass_matrix` (C^T M C, k x k), `NAME_reduced_forcing` (C^T (F - M e))
    and `NAME_rhs` ([q_dot, u_dot], the k x k system solved numerically: the straight-line LDL^T,
    the LU solve when it fails)."""
    from lagrange_cli.reduced import reduced

    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name):
        raise DerivationError(f"the C prefix '{printable(name)}' is not a C identifier")
    definitions = model.definitions
    model = model.with_definitions()
    require_defined(model, "C code")
    return _ReducedWriter(model, name, definitions, reduced(model)).file()


class _ReducedWriter(_Writer):
    def __init__(self, model: Model, prefix: str, definitions: Mapping[str, Any], red: Any) -> None:
        super().__init__(model, prefix, definitions)
        self.red = red
        n, k = model.n, len(red.independent)
        symbols = [str(s) for s in (*model.q, *model.qd, *(p.symbol for p in model.parameters), *(i.symbol for i in model.inputs))]
        extra = [*(f"{prefix}_{f}" for f in REDUCED_FUNCTIONS), f"{self.upper}_NI", f"{self.upper}_NY"]
        self.names = {**mangle(symbols, Reserved({*C_KEYWORDS, *MATH_H, *MACROS, *LOCALS, "qdot", *generated(prefix), *extra}, MACRO_FAMILIES)), str(model.t): "t"}
        self.index = {str(q): f"y[{i}]" for i, q in enumerate(model.q)}
        self.index |= {str(v): f"y[{n + j}]" for j, v in enumerate(red.u)}
        self.index |= {p.name: f"p[{i}]" for i, p in enumerate(model.parameters)}
        self.index |= {i.name: f"u[{j}]" for j, i in enumerate(model.inputs)}
        self.cells = [(i, j) for i in range(k) for j in range(i, k)]
        self.qdot = [to_symengine(v) for v in red.velocities]
        self.reduced_mass = [to_symengine(red.mass[i, j]) for i, j in self.cells]
        self.reduced_force = [to_symengine(f) for f in red.rhs]

    def velocities_function(self) -> str:
        used: set[str] = set()
        lines, results = self.block(self.qdot, used)
        lines += [f"out[{i}] = {r};" for i, r in enumerate(results)]
        return self.function("void", "velocities", f"Every q_dot = C u + d ({self.model.n} values) at the reduced state y = [q, u].", lines, used)

    def reduce_function(self) -> str:
        picks = [f"    out[{j}] = qdot[{i}];" for j, i in enumerate(self.red.independent)]
        doc = "The independent velocities u of a full velocity vector qdot (which must satisfy the constraints)."
        return "\n".join([f"/* {comment(doc)} */", f"static inline void {self.prefix}_reduce(const double *qdot, double *out)", "{", *picks, "}"])

    def mass_function(self) -> str:
        k = len(self.red.independent)
        used: set[str] = set()
        lines, results = self.block(self.reduced_mass, used)
        for (i, j), r in zip(self.cells, results, strict=True):
            lines.append(f"out[{i * k + j}] = {r};")
            if i != j:
                lines.append(f"out[{j * k + i}] = out[{i * k + j}];")
        return self.function("void", "reduced_mass_matrix", f"C^T M C (row-major, {k} x {k}; symmetric) at the reduced state y = [q, u].", lines, used)

    def force_function(self) -> str:
        used: set[str] = set()
        lines, results = self.block(self.reduced_force, used)
        lines += [f"out[{i}] = {r};" for i, r in enumerate(results)]
        return self.function("void", "reduced_forcing", f"C^T (F - M e) ({len(self.red.independent)} values) at the reduced state y = [q, u].", lines, used)

    def rhs(self) -> str:
        n, k = self.model.n, len(self.red.independent)
        used: set[str] = set()
        lines, results = self.block([*self.qdot, *self.reduced_mass, *self.reduced_force], used)
        qdot, rest = results[:n], results[n:]
        mass = dict(zip(self.cells, rest[: len(self.cells)], strict=True))
        force = rest[len(self.cells) :]
        lines[:0] = ["int _i;", "int _status;", f"double _a[{k * k}];", f"double _b[{k}];"]
        for i, j in self.cells:
            lines.append(f"_a[{i * k + j}] = {mass[(i, j)]};")
            if i != j:
                lines.append(f"_a[{j * k + i}] = _a[{i * k + j}];")
        lines += [f"_b[{i}] = {f};" for i, f in enumerate(force)]
        solve = f"{self.prefix}_solve({k}, _a, _b)"
        lines.append(f"_status = {self.prefix}_ldlt(_a, _b) == 0 ? 0 : {solve};" if k <= LDLT_SIZE else f"_status = {solve};")
        lines += [f"dydt[{i}] = {v};" for i, v in enumerate(qdot)]
        lines += [
            f"for (_i = 0; _i < {k}; ++_i) dydt[_i + {n}] = _status ? NAN : _b[_i];",
            f"for (_i = 0; _i < {n + k} && !_status; ++_i) if (!isfinite(dydt[_i])) _status = 2;",
            "return _status;",
        ]
        doc = "dy/dt = [q_dot, u_dot] for y = [q, u]: 0, or 1 when C^T M C is singular at y, 2 when a value is not finite."
        return self.function("int", "rhs", doc, lines, used, out="dydt")

    def header(self) -> str:
        model, red = self.model, self.red
        n, k = model.n, len(red.independent)
        state = ", ".join(f"y[{i}] = {s}" for i, s in enumerate(red.state))
        lines = [
            f"{model.title}: reduced (Maggi) equations generated by lagrange {__version__} from {Path(model.source).name}.",
            "",
            f"State y = [q, u] ({n + k} values): {state}: the coordinates and the independent velocities u (the multipliers are eliminated).",
            red.summary() + ".",
            f"q_dot = C u + d ({self.prefix}_velocities) and (C^T M C) u_dot = C^T (F - M e) ({self.prefix}_reduced_mass_matrix, {self.prefix}_reduced_forcing);",
            f"{self.prefix}_rhs gives dy/dt = [q_dot, u_dot]; {self.prefix}_reduce picks u from a full q_dot; {self.prefix}_independent and",
            f"{self.prefix}_dependent hold the coordinates' indices.",
        ]
        notes = ["The inputs are given values at time t."] if model.inputs else []
        return self.comment_block(lines, notes)

    def file(self) -> str:
        model, red = self.model, self.red
        n, k, np_ = model.n, len(red.independent), len(model.parameters)
        guard = f"{self.upper}_H_INCLUDED"
        defaults = ", ".join(_c_number(p.value) for p in model.parameters) if model.parameters else "0.0"
        parts = [
            self.header(),
            f"#ifndef {guard}\n#define {guard}\n\n#include <math.h>",
            f"#define {self.upper}_NQ {n}\n#define {self.upper}_NI {k}\n#define {self.upper}_NY {n + k}\n#define {self.upper}_NP {np_}\n#define {self.upper}_NC {len(model.constraints)}",
            f"/* The parameters' defaults, in the file's order (see above). */\nstatic const double {self.prefix}_default_parameters[{max(np_, 1)}] = {{{defaults}}};",
            *self.inputs_block(),
            "/* The indices in q of the independent velocities u and of the dependent ones. */\n"
            f"static const int {self.prefix}_independent[{max(k, 1)}] = {{{', '.join(map(str, red.independent)) or '0'}}};\n"
            f"static const int {self.prefix}_dependent[{max(len(red.dependent), 1)}] = {{{', '.join(map(str, red.dependent)) or '0'}}};",
            SOLVE.replace("eom_", f"{self.prefix}_"),
            *([ldlt(self.prefix, k)] if k <= LDLT_SIZE else []),
            self.velocities_function(),
            self.reduce_function(),
            self.mass_function(),
            self.force_function(),
            self.rhs(),
            f"#endif /* {guard} */",
        ]
        return "\n\n".join(parts) + "\n"
