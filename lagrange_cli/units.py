"""Dimensional checking: the `units` key, and a dimension for every term of a file's expressions.

A dimension is an exponent vector over the SI base quantities (M, L, T, I, Theta, N, J),
a tuple of integers (each exponent times `SCALE`, so that 1/2 and 1/3 are whole numbers too):
comparing two is comparing tuples, and multiplying adds machine integers. Unit strings are read
with their own whitelisted `ast` walk (never `eval`) in their own namespace: a parameter
called `m` does not clash with the metre. Only coherent SI units are known (`kg`, `m`, `s`,
`N`, `J`, ...; no prefixes such as `g` or `cm`): the tool converts no values, so a file in
grams and metres could be dimensionally consistent and numerically wrong. Angles (`rad`)
and `1` are dimensionless.

No dependency beyond the standard library: pint or sympy.physics.units would parse the same
strings, but pint is a new dependency, sympy.physics.units treats angles as a dimension of
their own, and both need a safe reader for the unit strings anyway; the table below is the
whole of what a mechanics file uses.

The rules (`Dimensions.of`):
- a coordinate q has unit(q), q_dot unit(q)/s, q_ddot unit(q)/s^2; `t` is in seconds;
- every term of a sum has the same dimension; a product adds exponents; `x**n` multiplies
  them by a number n (a symbolic exponent and its base must be dimensionless);
- the arguments of sin, cos, tan, ..., exp, log (and their results) are dimensionless;
  atan2's two arguments share a dimension; Abs keeps it; sign is dimensionless;
- a declared function with a `definition` has the dimension of its definition evaluated at
  the dimensions of its arguments; an undefined declared function (`U(r)`), a Lagrange
  multiplier and anything else unknown is a wildcard: it matches every dimension (its
  arguments are still checked inside);
- energy-like entries (kinetic energies, potentials, `lagrangian`, gravity terms) share one
  dimension, that of energy: the one most of them have (ties: kg*m^2/s^2 if it is among
  them, else the first in file order);
  a dissipation function has energy/s, a generalized force on q energy/unit(q), a Cartesian
  force energy/length of its particle's position;
- bodies (version 2): each inertia entry times omega^2 is an energy; the rotation an
  orientation gives is dimensionless entry by entry (angles, an axis in one dimension);
  the centre of mass (pivot + R center) and each point share the position's dimension;
  a force load times that length and a torque load times an angle are energies;
- each output is one consistent expression (any dimension);
- a symmetry's changes delta q / unit(q) and delta t / s share one dimension (epsilon's).
"""

from __future__ import annotations

import ast
from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from typing import TYPE_CHECKING, Any

import sympy as sp
from sympy.core.function import AppliedUndef

from lagrange_cli.errors import Diagnostic, Span, SpecError

if TYPE_CHECKING:
    from lagrange_cli.frontend.nodes import Body, Particle, SystemSpec

Dim = tuple[int, ...]
SCALE = 720720  # the least common multiple of 1..16: exponents with those denominators are exact
BASE = ("kg", "m", "s", "A", "K", "mol", "cd")


def _d(kg: int = 0, m: int = 0, s: int = 0, a: int = 0, k: int = 0, mol: int = 0, cd: int = 0) -> Dim:
    return tuple(SCALE * x for x in (kg, m, s, a, k, mol, cd))


NONE: Dim = _d()
SECOND: Dim = _d(s=1)
ENERGY: Dim = _d(kg=1, m=2, s=-2)
UNITS: dict[str, Dim] = {
    "kg": _d(kg=1), "m": _d(m=1), "s": _d(s=1), "A": _d(a=1), "K": _d(k=1), "mol": _d(mol=1), "cd": _d(cd=1),
    "rad": NONE, "sr": NONE, "N": _d(kg=1, m=1, s=-2), "J": ENERGY, "W": _d(kg=1, m=2, s=-3), "Pa": _d(kg=1, m=-1, s=-2),
    "Hz": _d(s=-1), "C": _d(s=1, a=1), "V": _d(kg=1, m=2, s=-3, a=-1), "T": _d(kg=1, s=-2, a=-1), "Wb": _d(kg=1, m=2, s=-2, a=-1),
    "ohm": _d(kg=1, m=2, s=-3, a=-2), "F": _d(kg=-1, m=-2, s=4, a=2), "H": _d(kg=1, m=2, s=-2, a=-2),
}  # fmt: skip
"""The coherent SI units a `units` entry may use, each with its dimension."""
NOT_COHERENT = {"g": "kg", "cm": "m", "mm": "m", "km": "m", "ms": "s", "min": "s", "h": "s", "deg": "rad", "degree": "rad", "kN": "N", "kJ": "J"}
UNIT_HELP = "a product of powers of coherent SI units (" + ", ".join(UNITS) + "), e.g. `kg*m**2/s**2`, `m/s**2`, `N*m`, `rad` or `1`"
DIMENSIONLESS = frozenset({"sin", "cos", "tan", "cot", "sec", "csc", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "log"})


def mul(a: Dim, b: Dim, k: int = 1) -> Dim:
    """The dimension of a * b**k."""
    return tuple(x + k * y for x, y in zip(a, b, strict=True))


def power(a: Dim, k: int) -> Dim:
    return tuple(k * x for x in a)


def root(a: Dim, k: Fraction) -> Dim | None:
    """The dimension of a**k for a fraction k, or None when an exponent would not be a multiple of 1/SCALE."""
    if any(x * k.numerator % k.denominator for x in a):
        return None
    return tuple(x * k.numerator // k.denominator for x in a)


def show(dim: Dim | None) -> str:
    """`kg*m^2/s^2`, `1/s`, `1` (dimensionless), `any` (a wildcard)."""
    if dim is None:
        return "any"

    def part(name: str, e: Fraction) -> str:
        return name if e == 1 else f"{name}^{e}" if e.denominator == 1 else f"{name}^({e})"

    exponents = [Fraction(x, SCALE) for x in dim]
    top = [part(n, e) for n, e in zip(BASE, exponents, strict=True) if e > 0]
    bottom = [part(n, -e) for n, e in zip(BASE, exponents, strict=True) if e < 0]
    text = "*".join(top) or "1"
    return text + ("/" + ("*".join(bottom) if len(bottom) == 1 else "(" + "*".join(bottom) + ")") if bottom else "")


class UnitError(ValueError):
    """A unit string that is not a product of powers of known units (`message`, column offset)."""

    def __init__(self, message: str, offset: int = 0) -> None:
        super().__init__(message)
        self.offset = offset


def parse_unit(text: str) -> Dim:
    """A unit string (`kg*m**2/s**2`, `m/s^2`, `1/s`, `rad`, `1`) as a dimension, read with a
    whitelisted `ast` walk: names from `UNITS`, `*`, `/`, `**` (or `^`) with a rational
    exponent, parentheses and the number 1."""
    if len(text) > 200:
        raise UnitError("the unit is too long (over 200 characters)")
    written = text.strip()
    source = written.replace("^", "**")  # `^` binds like `**`, not like Python's xor

    def back(offset: int) -> int:  # an offset in `source` as one in `written`
        return offset - source[:offset].count("**") + written[: offset - source[:offset].count("**")].count("**")

    try:
        tree = ast.parse(source, mode="eval")
        return _unit(tree.body, 0)
    except SyntaxError as exc:
        raise UnitError(f"'{written}' is not a unit", back(max((exc.offset or 1) - 1, 0))) from None
    except UnitError as exc:
        exc.offset = back(exc.offset)
        raise


def _unit(node: ast.AST, depth: int) -> Dim:
    if depth > 20:
        raise UnitError("the unit is nested too deeply")
    if isinstance(node, ast.Name):
        if node.id in UNITS:
            return UNITS[node.id]
        hint = NOT_COHERENT.get(node.id)
        extra = f" ('{node.id}' is not a coherent SI unit and the tool converts no values: use {hint})" if hint else ""
        raise UnitError(f"unknown unit '{node.id}'{extra}", node.col_offset)
    if isinstance(node, ast.Constant) and type(node.value) is int and node.value == 1:
        return NONE
    if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Mult, ast.Div)):
        left, right = _unit(node.left, depth + 1), _unit(node.right, depth + 1)
        return mul(left, right, 1 if isinstance(node.op, ast.Mult) else -1)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
        result = root(_unit(node.left, depth + 1), _exponent(node.right))
        if result is None:
            raise UnitError(f"the exponent '{ast.unparse(node.right)}' has too large a denominator", node.right.col_offset)
        return result
    raise UnitError(f"'{ast.unparse(node)}' is not a unit", getattr(node, "col_offset", 0))


def _exponent(node: ast.AST) -> Fraction:
    """An integer exponent, possibly negative or a fraction in parentheses: `2`, `-1`, `(1/2)`."""
    if isinstance(node, ast.Constant) and type(node.value) is int and abs(node.value) <= 12:
        return Fraction(node.value)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        return -_exponent(node.operand)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
        num, den = _exponent(node.left), _exponent(node.right)
        if den != 0:
            return num / den
    raise UnitError(f"the exponent '{ast.unparse(node)}' is not a small whole number or fraction", getattr(node, "col_offset", 0))


@dataclass(frozen=True)
class Units:
    """A file's `units`: the dimension of each declared name, and where its unit is written."""

    dims: Mapping[str, Dim]
    spans: Mapping[str, Span] = field(default_factory=dict, compare=False)
    text: Mapping[str, str] = field(default_factory=dict)


class Mismatch(Exception):
    """A term whose dimension does not fit, found while computing a dimension."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


class Dimensions:
    """The dimension of sympy expressions in one file's names (`of`), wildcards as None."""

    def __init__(self, env: Mapping[str, Dim | None], definitions: Mapping[str, sp.Lambda] | None = None, hints: Mapping[str, Dim] | None = None, numbers: bool = False) -> None:
        self.numbers = numbers  # numbers other than 0 and +-1 are wildcards (in `exact`: they stand for initial values and rates)
        self.env = dict(env)
        self.definitions = dict(definitions or {})
        self.hints = dict(hints or {})

    def of(self, expr: Any) -> Dim | None:
        """The dimension of `expr`; raises `Mismatch` at the first inconsistency inside it."""
        return self._of(expr, self.env, 0)

    def _of(self, e: Any, env: Mapping[str, Dim | None], depth: int) -> Dim | None:
        if depth > 200:
            return None
        if isinstance(e, sp.Symbol):
            return env.get(e.name)
        if isinstance(e, sp.Number):
            return None if e == 0 or (self.numbers and abs(e) != 1) else NONE  # 0 has every dimension
        if isinstance(e, sp.NumberSymbol):
            return NONE
        if isinstance(e, sp.Add):
            return self.same([(term, self._of(term, env, depth + 1)) for term in e.args], f"`{e}`")
        if isinstance(e, sp.Mul):
            total: Dim = NONE
            unknown = False
            for factor in e.args:
                d = self._of(factor, env, depth + 1)
                if d is None:
                    unknown = True
                else:
                    total = mul(total, d)
            return None if unknown else total
        if isinstance(e, sp.Pow):
            base = self._of(e.base, env, depth + 1)
            if e.exp.is_Rational:
                return None if base is None else root(base, Fraction(int(e.exp.p), int(e.exp.q)))
            if e.exp.is_Float:
                return None if base is None else root(base, Fraction(float(e.exp)).limit_denominator(1000))
            exponent = self._of(e.exp, env, depth + 1)
            for part, d in ((e.base, base), (e.exp, exponent)):
                if d is not None and d != NONE:
                    raise Mismatch(f"`{part}` in the power `{e}` has dimension {show(d)}; a power with a symbolic exponent needs a dimensionless base and exponent")
            return NONE
        if isinstance(e, sp.Derivative):
            inner = self._of(e.expr, env, depth + 1)
            for variable, count in e.variable_count:
                d = self._of(variable, env, depth + 1)
                if inner is None or d is None:
                    return None
                inner = mul(inner, d, -int(count))
            return inner
        name = getattr(e.func, "__name__", "")
        if isinstance(e, AppliedUndef):
            args = [self._of(a, env, depth + 1) for a in e.args]
            definition = self.definitions.get(name)
            if definition is None:
                return None
            local = dict(env) | {v.name: d for v, d in zip(definition.variables, args, strict=False)}
            try:
                return self._of(definition.expr, local, depth + 1)
            except Mismatch as exc:
                raise Mismatch(f"in the definition of '{name}' (called as `{e}`): {exc.message}") from None
        if name in DIMENSIONLESS:
            for arg in e.args:
                for term in sp.Add.make_args(arg) if isinstance(arg, sp.Add) else ():  # name the term that is not dimensionless
                    d = self._of(term, env, depth + 1)
                    if d is not None and d != NONE:
                        raise Mismatch(f"term `{term}` of the argument of {name}, `{arg}`, has dimension {show(d)}; it must be dimensionless{self.hint(d, NONE)}")
                d = self._of(arg, env, depth + 1)
                if d is not None and d != NONE:
                    raise Mismatch(f"the argument of {name}, `{arg}`, has dimension {show(d)}; it must be dimensionless{self.hint(d, NONE)}")
            return NONE
        if name == "atan2":
            self.same([(a, self._of(a, env, depth + 1)) for a in e.args], f"`{e}`", what="argument")
            return NONE
        if name == "Abs":
            return self._of(e.args[0], env, depth + 1)
        if name == "sign":
            self._of(e.args[0], env, depth + 1)
            return NONE
        for arg in getattr(e, "args", ()):
            self._of(arg, env, depth + 1)
        return None

    def same(self, terms: list[tuple[Any, Dim | None]], where: str, what: str = "term") -> Dim | None:
        """The one dimension of `terms` (wildcards aside), or a `Mismatch` naming the odd one out:
        the dimension most terms share is taken as right (ties: the first)."""
        known = [(t, d) for t, d in terms if d is not None]
        if not known:
            return None
        counts = Counter(d for _, d in known)
        best = max(counts.values())
        right = next(d for _, d in known if counts[d] == best)
        for term, d in known:
            if d != right:
                others = "the other" if len(terms) == 2 else "the others"
                raise Mismatch(f"{what} `{term}` of {where} has dimension {show(d)}, {others} {show(right)}{self.hint(d, right)}")
        return right

    def hint(self, got: Dim, wanted: Dim) -> str:
        """`; missing g?` when one declared name (or its inverse) makes up the difference."""
        gap = mul(wanted, got, -1)
        missing = [n for n, d in self.hints.items() if d == gap and d != NONE]
        extra = [n for n, d in self.hints.items() if power(d, -1) == gap and d != NONE]
        if missing:
            return "; missing " + " or ".join(missing[:3]) + "?"
        if extra:
            return "; one " + " or ".join(extra[:3]) + " too many?"
        return ""


@dataclass
class _Entry:
    """Energy-like terms of one entry of the file: (shown text, dimension); each times `scale` is an energy."""

    what: str
    span: Span | None
    terms: list[tuple[str, Dim]]
    scale: Dim = NONE


def environment(spec: SystemSpec, units: Units) -> dict[str, Dim | None]:
    """The dimension of every name of the file: coordinates, their rates, parameters, inputs, t."""
    env: dict[str, Dim | None] = {"t": SECOND}
    env.update(units.dims)
    for name in spec.coordinates:
        dim = units.dims.get(name)
        if dim is not None:
            env[f"{name}_dot"] = mul(dim, SECOND, -1)
            env[f"{name}_ddot"] = mul(dim, SECOND, -2)
    return env


class _FileCheck:
    """The dimensions of a file's entries, collecting every problem with the entry's line."""

    def __init__(self, spec: SystemSpec, units: Units) -> None:
        self.spec = spec
        self.env = environment(spec, units)
        self.dims = Dimensions(self.env, spec.definitions, units.dims)
        self.problems: list[Diagnostic] = []
        self.entries: list[_Entry] = []

    def of(self, what: str, span: Span | None, expr: Any, dims: Dimensions | None = None) -> Dim | None:
        try:
            return (dims or self.dims).of(expr)
        except Mismatch as exc:
            self.problems.append(Diagnostic(span, f"{what}: {exc.message}", "every term of a sum in one dimension, and dimensionless arguments of sin, cos, exp and log"))
            return None

    def terms(self, what: str, span: Span | None, expr: Any, scale: Dim = NONE) -> None:
        """The top-level terms of an energy-like entry (`scale`: what to multiply them by for an energy)."""
        found = [(f"term `{term}`{self.defined(term)}", self.of(what, span, term)) for term in sp.Add.make_args(expr) if term != 0]
        self.entries.append(_Entry(what, span, [(t, d) for t, d in found if d is not None], scale))

    def defined(self, term: Any) -> str:
        """` (with 'U' as defined at line 9)` for the declared functions with a definition in `term`."""
        used = sorted({f.func.__name__ for f in term.atoms(AppliedUndef)} & set(self.spec.definitions))
        lines = [f"'{f}' as defined at line {span.line}" for f in used if (span := self.spec.sources.get(f"functions.{f}")) is not None]
        return f" (with {', '.join(lines)})" if lines else ""

    def vector(self, what: str, span: Span | None, components: Iterable[Any], dims: Dimensions | None = None) -> Dim | None:
        before = len(self.problems)
        parts = []
        for c in components:
            if c != 0:
                parts.append((c, self.of(what, span, c, dims)))
            if len(self.problems) > before:
                return None  # one report per vector, and no one dimension to compare it with
        try:
            return (dims or self.dims).same(parts, what, what="component")
        except Mismatch as exc:
            self.problems.append(Diagnostic(span, f"{what}: {exc.message}", "Cartesian components in one dimension"))
            return None

    def item(self, item: Particle | Body, gravity: Dim | None) -> None:
        """A particle's or body's kinetic energy 1/2 m v^2 (+ 1/2 I w^2), weight m g.x, damping and force."""
        kind, name, spans = ("body" if hasattr(item, "inertia") else "particle"), item.name, item.spans
        mass = self.of(f"the mass of {kind} '{name}'", spans.get("mass"), item.mass)
        placed = spans.get("center") or spans.get("pivot") or spans.get("position")  # a body's centre: pivot + R center
        what = f"the position of {kind} '{name}'" if "center" not in spans else f"the centre of mass of {kind} '{name}' (pivot + rotated center)"
        length = self.vector(what, placed, item.position)
        speed = None if length is None else mul(length, SECOND, -1)
        if mass is not None and length is not None and speed is not None:
            self.entries.append(_Entry(f"the kinetic energy of {kind} '{name}'", spans.get("mass"), [("m*v**2/2", mul(mass, power(speed, 2)))]))
            if gravity is not None:
                self.entries.append(_Entry(f"the weight of {kind} '{name}'", self.spec.sources.get("gravity"), [("m*g.x", mul(mul(mass, gravity), length))]))
        from lagrange_cli.frontend.nodes import Particle  # the frontend imports this module

        if isinstance(item, Particle):
            if item.damping is not None and speed is not None:
                k = self.of(f"the damping of particle '{name}'", spans.get("damping"), item.damping)
                if k is not None:
                    self.entries.append(_Entry(f"the damping of particle '{name}'", spans.get("damping"), [("k*v**2/2", mul(k, power(speed, 2)))], SECOND))
            if item.force is not None and length is not None:
                f = self.vector(f"the force on particle '{name}'", spans.get("force"), item.force)
                if f is not None:
                    self.entries.append(_Entry(f"the force on particle '{name}'", spans.get("force"), [("f.dx", mul(f, length))]))
            return
        self.body(item, length)

    def body(self, item: Body, length: Dim | None) -> None:
        """A body's rotational energy (each inertia entry times omega^2), its orientation (dimensionless
        entries: angles, and an axis in any one dimension), its points (in the dimension of its position)
        and its loads: a force times a length and a torque times an angle are energies."""
        name, spans = item.name, item.spans
        before = len(self.problems)
        for entry in (e for row in item.local or () for e in row):  # the rotation relative to the parent, as written
            d = self.of(f"the orientation of body '{name}'", spans.get("orientation"), entry)
            if d is not None and d != NONE:
                why = f"the orientation of body '{name}': the rotation entry `{entry}` has dimension {show(d)}"
                self.problems.append(Diagnostic(spans.get("orientation"), why, "dimensionless angles (rad), an axis in one dimension"))
            if len(self.problems) > before:
                break  # one report per orientation (its angular velocity would repeat it)
        rate = spans.get("orientation") or spans.get("angular_velocity")
        omega = self.vector(f"the angular velocity of body '{name}'", rate, item.angular_velocity) if len(self.problems) == before else None
        if omega is not None:
            terms = []
            paired = len(item.inertia) == len(item.angular_velocity)  # principal moments: I_k w_k**2/2; a full tensor: I_jk w_j w_k/2
            for k, i in enumerate(item.inertia):
                di = self.of(f"the inertia of body '{name}'", spans.get("inertia"), i)
                w = item.angular_velocity[k] if paired else 0
                if di is not None and i != 0:
                    terms.append((f"`{i * w**2 / 2}`" if w != 0 else f"the inertia entry `{i}` times w**2/2", mul(di, power(omega, 2))))
            self.entries.append(_Entry(f"the rotational energy of body '{name}'", spans.get("inertia"), terms))
        for point, where in item.points.items():
            d = self.vector(f"point '{point}' of body '{name}'", spans.get("points"), where)
            if d is not None and length is not None and d != length:
                self.problems.append(
                    Diagnostic(
                        spans.get("points"),
                        f"point '{point}' of body '{name}' has dimension {show(d)}, but the body's position has {show(length)}{self.dims.hint(d, length)}",
                        "points in the units of the positions",
                    )
                )
        if length is not None:
            loads = [f for f, _ in (*item.forces, *item.frame_forces)]
            for f in loads:
                df = self.vector(f"the force on body '{name}'", spans.get("force"), f)
                if df is not None:
                    self.entries.append(_Entry(f"the force on body '{name}'", spans.get("force"), [(f"the force `{list(f)}` times a displacement", mul(df, length))]))
        if omega is not None:
            for torque in item.torques:
                dt = self.vector(f"the torque on body '{name}'", spans.get("torque"), torque)
                if dt is not None:
                    self.entries.append(_Entry(f"the torque on body '{name}'", spans.get("torque"), [(f"the torque `{list(torque)}` times an angle", mul(dt, mul(omega, SECOND)))]))

    def symmetry(self, symmetry: Any) -> None:
        """A symmetry's changes are one parameter epsilon times each: delta q / unit(q) (and delta t / s)
        share one dimension, that of epsilon."""
        what = f"symmetry '{symmetry.name}'"
        changes = [(f"delta {q} = `{e}`", e, span, self.spec.units.dims.get(q) if self.spec.units else None) for q, e, span in symmetry.coordinates]
        if symmetry.time is not None:
            changes.append((f"delta t = `{symmetry.time}`", symmetry.time, symmetry.time_span or symmetry.span, SECOND))
        ratios: list[tuple[str, Dim, Span | None]] = []
        for text, e, span, unit in changes:
            d = self.of(what, span, e)
            if d is not None and unit is not None and not e.is_Number:  # a number (`time: 1`) is in whatever unit epsilon needs
                ratios.append((text, mul(d, unit, -1), span))
        if not ratios:
            return
        counts = Counter(d for _, d, _ in ratios)
        right = next(d for _, d, _ in ratios if counts[d] == max(counts.values()))
        for text, d, span in ratios:
            if d != right:
                self.problems.append(
                    Diagnostic(
                        span,
                        f"{what}: {text} is epsilon times {show(d)} of its unit, the other changes epsilon times {show(right)}{self.dims.hint(d, right)}",
                        "each change in the unit of its coordinate (delta t in s) times one parameter epsilon",
                    )
                )
                break

    def energy(self) -> Dim:
        """Every energy-like term (times its entry's scale) in one dimension: the one most terms have
        (ties: kg*m^2/s^2 if it is among them, else the first in file order); each that differs is
        reported at its entry's line."""
        scaled = [(entry, term, mul(d, entry.scale)) for entry in self.entries for term, d in entry.terms]
        if not scaled:
            return ENERGY
        counts = Counter(d for _, _, d in scaled)
        energy = ENERGY if counts[ENERGY] == max(counts.values()) else next(d for _, _, d in scaled if counts[d] == max(counts.values()))
        for entry, term, d in scaled:
            if d != energy:
                want, got = mul(energy, entry.scale, -1), mul(d, entry.scale, -1)
                others = f"the others {show(want)}" if entry.scale == NONE else f"it should be {show(want)} (energy per {show(entry.scale)})"
                expected = f"terms in units of energy ({show(energy)})" + ("" if entry.scale == NONE else f" per {show(entry.scale)}")
                self.problems.append(Diagnostic(entry.span, f"{entry.what}: {term} has dimension {show(got)}, {others}{self.dims.hint(got, want)}", expected))
        return energy


def check_file(spec: SystemSpec) -> Dim | None:
    """Every expression written in the file, each at its line (before deriving anything): raises a
    `SpecError` listing every dimensional mismatch. Returns the dimension of energy they agree on."""
    units = spec.units
    if units is None:
        return None
    run = _FileCheck(spec, units)
    gravity = run.vector("'gravity'", spec.sources.get("gravity"), spec.gravity) if spec.gravity is not None else None
    items: tuple[Particle | Body, ...] = (*spec.particles, *spec.bodies)
    for item in items:
        run.item(item, gravity)
    for key in ("kinetic", "potential", "lagrangian"):
        run.terms(key, spec.sources.get(key), getattr(spec, key))
    run.terms("dissipation", spec.sources.get("dissipation"), spec.dissipation, SECOND)
    for name, force in zip(spec.coordinates, spec.generalized_forces, strict=False):
        run.terms(f"the generalized force on '{name}'", spec.sources.get(f"forces.{name}"), force, units.dims.get(name, NONE))
    for constraint in spec.constraints:
        run.of(f"constraint '{constraint.name}'", constraint.span, constraint.expr)
    numbers = Dimensions(run.env, spec.definitions, numbers=True)
    for name, exact in spec.exact.items():
        where = spec.sources.get(f"exact.{name}")
        got, want = run.of(f"the exact solution for '{name}'", where, exact, numbers), units.dims.get(name)
        if got is not None and want is not None and got != want:
            run.problems.append(
                Diagnostic(where, f"the exact solution for '{name}' has dimension {show(got)}, but '{name}' is in {show(want)}", f"an expression in {units.text.get(name, show(want))}")
            )
    for symmetry in spec.symmetries:
        run.symmetry(symmetry)
    for name, output in spec.outputs:
        run.of(f"output '{name}'", spec.sources.get(f"outputs.{name}"), output)
    energy = run.energy()
    if run.problems:
        raise SpecError(sorted(run.problems, key=lambda d: (d.span.line, d.span.column) if d.span else (0, 0)))
    return energy


def check_answer(spec: SystemSpec, expr: Any, kind: str, energy: Dim | None = None, coordinate: str | None = None) -> str:
    """Why an `expect` answer is not dimensionally consistent, or "" when it is. `kind` is one of
    equation (its terms agree), acceleration / momentum of `coordinate`, hamiltonian, hamilton."""
    units = spec.units
    if units is None:
        return ""
    energy = energy or ENERGY
    env = environment(spec, units)
    for name in spec.coordinates:
        q = units.dims.get(name)
        if q is not None:
            env[f"p_{name}"] = mul(mul(energy, SECOND), q, -1)
            env[f"p_{name}_dot"] = mul(energy, q, -1)
    dims = Dimensions(env, spec.definitions, units.dims)
    q = units.dims.get(coordinate or "")
    want = {"acceleration": None if q is None else mul(q, SECOND, -2), "momentum": None if q is None else mul(mul(energy, SECOND), q, -1), "hamiltonian": energy}.get(kind)
    try:
        if want is not None and isinstance(expr, sp.Add):  # the answer's terms against what it must be
            for term in expr.args:
                d = dims.of(term)
                if d is not None and d != want:
                    return f"not dimensionally consistent: term `{term}` has dimension {show(d)}, but {_kind(kind, coordinate)} has {show(want)}{dims.hint(d, want)}"
        got = dims.of(expr)
    except Mismatch as exc:
        return f"not dimensionally consistent: {exc.message}"
    if got is not None and want is not None and got != want:
        return f"not dimensionally consistent: it has dimension {show(got)}, but {_kind(kind, coordinate)} has {show(want)}{dims.hint(got, want)}"
    return ""


def _kind(kind: str, coordinate: str | None) -> str:
    return {"acceleration": f"the acceleration of '{coordinate}'", "momentum": f"the momentum of '{coordinate}'", "hamiltonian": "a Hamiltonian (an energy)"}.get(kind, kind)


SE_DIMENSIONLESS = DIMENSIONLESS | {"exp"}


class _Derived:
    """Dimensions of symengine expressions (the derived equations), memoized by subexpression so that
    the shared subtrees of a big system are visited once. Undefined functions and their derivatives
    (and anything unknown) are wildcards."""

    def __init__(self, env: Mapping[str, Dim | None]) -> None:
        self.env = env
        self.memo: dict[Any, Dim | None] = {}

    def of(self, e: Any) -> Dim | None:
        if e in self.memo:
            return self.memo[e]
        kind = type(e).__name__
        result: Dim | None
        if kind == "Symbol":
            result = self.env.get(str(e))
        elif kind in ("Integer", "Rational", "Half", "RealDouble", "Pi", "Exp1", "Zero", "One", "NegativeOne", "Float", "EulerGamma"):
            result = None if e == 0 else NONE
        elif kind == "Add":
            result = self.same(e)
        elif kind == "Mul":
            parts = [self.of(a) for a in e.args]
            result = None if any(p is None for p in parts) else _product(parts)  # type: ignore[arg-type]
        elif kind == "Pow":
            base, exponent = e.args
            if type(exponent).__name__ in ("Integer", "Rational", "Half", "RealDouble", "NegativeOne", "One"):
                b = self.of(base)
                result = None if b is None else root(b, Fraction(str(exponent)).limit_denominator(1000) if "." in str(exponent) else Fraction(str(exponent)))
            else:
                for part in (base, exponent):
                    d = self.of(part)
                    if d is not None and d != NONE:
                        raise Mismatch(f"`{part}` in the power `{e}` has dimension {show(d)}; a symbolic power needs a dimensionless base and exponent")
                result = NONE
        elif kind in SE_DIMENSIONLESS or kind in ("atan2", "sign"):
            for arg in e.args:
                d = self.of(arg)
                if d is not None and d != NONE and kind != "atan2":
                    raise Mismatch(f"the argument of {kind}, `{arg}`, has dimension {show(d)}; it must be dimensionless")
            result = NONE
        elif kind == "Abs":
            result = self.of(e.args[0])
        else:  # an undefined function, a derivative or substitution of one: any dimension
            for arg in e.args:
                self.of(arg)
            result = None
        self.memo[e] = result
        return result

    def same(self, e: Any) -> Dim | None:
        known = [(t, d) for t in e.args if (d := self.of(t)) is not None]
        if not known:
            return None
        counts = Counter(d for _, d in known)
        right = next(d for _, d in known if counts[d] == max(counts.values()))
        for term, d in known:
            if d != right:
                raise Mismatch(f"term `{term}` has dimension {show(d)}, the others {show(right)}")
        return right


def _product(parts: Iterable[Dim]) -> Dim:
    total = NONE
    for part in parts:
        total = mul(total, part)
    return total


def check_equations(spec: SystemSpec, model: Any, energy: Dim | None) -> None:
    """Every term of every derived equation M q_ddot = F in one dimension, energy/unit(q_i) for the
    equation of q_i (a check of the derivation itself: the file's terms were checked before it)."""
    units = spec.units
    if units is None:
        return
    forms = model.symengine
    derived = _Derived(environment(spec, units))
    energy = energy or ENERGY
    problems = []
    for i, name in enumerate(model.coordinates):
        q = units.dims.get(name)
        if q is None:
            continue
        want = mul(energy, q, -1)
        terms = [m * a for m, a in zip(forms.mass[i], forms.qdd, strict=True) if m != 0] + [t for t in _se_terms(forms.forcing[i])]
        for term in terms:
            try:
                d = derived.of(term)
            except Mismatch as exc:
                problems.append(
                    Diagnostic(spec.spans.get(name), f"the derived equation of '{name}': {exc.message}", "a file whose terms are consistent gives consistent equations; please report this")
                )
                break
            if d is not None and d != want:
                problems.append(Diagnostic(spec.spans.get(name), f"the derived equation of '{name}': term `{term}` has dimension {show(d)}, the others {show(want)}", "consistent equations"))
                break
    if problems:
        raise SpecError(problems)


def _se_terms(expr: Any) -> list[Any]:
    return list(expr.args) if type(expr).__name__ == "Add" else [expr] if expr != 0 else []


def answer_problems(spec: SystemSpec) -> dict[str, tuple[str, Span]]:
    """The `expect` answers that are not dimensionally consistent: entry (as `check` names it) ->
    (why, where); for `equations` and `hamilton_equations`, the first such equation."""
    energy = check_file(spec)
    wrong: dict[str, tuple[str, Span]] = {}
    for key, items in (("equations", spec.expect.equations), ("hamilton_equations", spec.expect.hamilton_equations)):
        for k, (expr, span) in enumerate(items):
            why = check_answer(spec, expr, "equation", energy)
            if why and key not in wrong:
                wrong[key] = (f"equation {k + 1} is {why}", span)
    for kind, key, answers in (("acceleration", "accelerations.{}_ddot", spec.expect.accelerations), ("momentum", "momenta.{}", spec.expect.momenta)):
        for coordinate, expr, span in answers:
            why = check_answer(spec, expr, kind, energy, coordinate)
            if why:
                wrong[key.format(coordinate)] = (f"the answer is {why}", span)
    if spec.expect.hamiltonian is not None:
        why = check_answer(spec, spec.expect.hamiltonian[0], "hamiltonian", energy)
        if why:
            wrong["hamiltonian"] = (f"the answer is {why}", spec.expect.hamiltonian[1])
    for text, expr, span in spec.expect.conserved_expressions:  # an expression (not a symmetry's name): its terms agree
        why = check_answer(spec, expr, "equation", energy) if expr is not None else ""
        if why:
            wrong[f"conserved.{text}"] = (f"the answer is {why}", span)
    return wrong
