"""Checking `expect` answers against the derived model.

Two sets of equations are equivalent when they give the same accelerations (and multipliers):
any order, any non-zero factors, any invertible recombination. That is decided by solving
the derived system at random points with 40-digit arithmetic, requiring each expected
equation to vanish there and the expected set to determine the same unknowns.
"""

from __future__ import annotations

import random
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import sympy as sp

from lagrange_cli.algebra import augmented, expandable
from lagrange_cli.errors import Span, SpecError, fail
from lagrange_cli.model import Model
from lagrange_cli.spec import SystemSpec

if TYPE_CHECKING:
    from xml.etree import ElementTree

DIGITS = 40
POINTS = 6
SEED = 20261121
MAX_DRAWS = 60
"""random states drawn at most (for all entries together) before an entry counts as undecidable."""
PROJECTION_STEPS = 30
TOLERANCE = sp.Float(10) ** (-(DIGITS - 12))


@dataclass(frozen=True)
class Result:
    """One `expect` entry's verdict; `detail` says what is wrong (empty when it passes)."""

    entry: str
    passed: bool
    detail: str = ""
    span: Span | None = None
    method: str = "numeric"


@dataclass(frozen=True)
class Point:
    """A sampled state: `values` of the parameters, coordinates, velocities and t (on the
    constraints), the functions standing in for undefined ones, the unknowns solved there, and
    `off`, the state as drawn before it was moved onto the constraints."""

    values: dict[sp.Symbol, sp.Float]
    functions: dict[sp.Expr, Callable[..., sp.Expr]]
    unknowns: dict[sp.Symbol, sp.Float]
    off: dict[sp.Symbol, sp.Float]


def check(spec: SystemSpec, model: Model) -> list[Result]:
    """Every entry of the file's `expect` block, in file order. An entry that cannot be decided
    (no sampled state where it and the model evaluate to finite real numbers) raises a
    `SpecError` at the entry: bad input, never a wrong-answer verdict."""
    expected = [e for e, _ in spec.expect.equations] + [e for _, e, _ in spec.expect.accelerations] + [e for _, e, _ in spec.expect.momenta]
    expected += [e for e, _ in spec.expect.hamilton_equations] + ([spec.expect.hamiltonian[0]] if spec.expect.hamiltonian else [])
    points = Samples(model, extra=expected)
    wrong = _dimensions(spec)
    results = [wrong.get("equations") or _equations(spec, model, points)] if spec.expect.equations else []
    for coordinate, expected_value, span in spec.expect.accelerations:
        if f"accelerations.{coordinate}_ddot" in wrong:
            results.append(wrong[f"accelerations.{coordinate}_ddot"])
            continue
        i = model.coordinates.index(coordinate) if coordinate in model.coordinates else None
        if i is None:
            results.append(Result(f"accelerations.{coordinate}_ddot", False, f"'{coordinate}' was eliminated", span))
            continue
        results.append(_compare(f"accelerations.{coordinate}_ddot", expected_value, model.qdd[i], points, span, solved=True))
    for coordinate, expected_value, span in spec.expect.momenta:
        if f"momenta.{coordinate}" in wrong:
            results.append(wrong[f"momenta.{coordinate}"])
            continue
        i = model.coordinates.index(coordinate) if coordinate in model.coordinates else None
        if i is None:
            results.append(Result(f"momenta.{coordinate}", False, f"'{coordinate}' was eliminated", span))
            continue
        results.append(_compare(f"momenta.{coordinate}", expected_value, model.momenta[i], points, span))
    for name, span in spec.expect.conserved:
        results.append(_conserved(model, name, span))
    if spec.expect.conserved_expressions or spec.symmetries:
        results += [wrong.get(result.entry) or result for result in _conserved_expressions(spec, model)]
    if spec.expect.hamiltonian is not None:
        results.append(wrong.get("hamiltonian") or _hamiltonian(model, *spec.expect.hamiltonian, points))
    if spec.expect.hamilton_equations:
        results.append(wrong.get("hamilton_equations") or _hamilton_equations(spec, model, points))
    if spec.expect.state_space is not None:
        results.append(_state_space(model, spec.expect.state_space))
    return results


def _dimensions(spec: SystemSpec) -> dict[str, Result]:
    """With `units`, the answers that are not dimensionally consistent, by entry, as failed results
    (a wrong answer, exit 1): checked before they are compared, so that the verdict says why."""
    if spec.units is None:
        return {}
    from lagrange_cli.units import answer_problems

    return {entry: Result(entry, False, detail, span) for entry, (detail, span) in answer_problems(spec).items()}


def _state_space(model: Model, expected: Any) -> Result:
    """`expect.state_space` against `statespace.state_space` (a point that is not an equilibrium is bad input, exit 2)."""
    from lagrange_cli import statespace

    passed, detail = statespace.compare(model, expected)
    return Result("state_space", passed, detail, expected.span, "symbolic")


def _in_velocities(model: Model, expr: sp.Expr, span: Span, key: str) -> sp.Expr:
    """`expr` (in q, p_<q>, p_<q>_dot, q_dot, t) with the momenta written as p = dL/dq_dot and their
    rates as d/dt (dL/dq_dot) (with the accelerations as unknowns): what the check samples.
    Kept constraints are refused (FORMAT.md: eliminate them first)."""
    from lagrange_cli.hamilton import momentum_symbols
    from lagrange_cli.spec import time_derivative

    if model.constraints:
        names = ", ".join(c.name for c in model.constraints)
        raise fail(
            span, f"'expect.{key}' cannot be checked for a system with kept constraints ({names})", "a system without kept constraints (eliminate them first), or the Lagrange form under `equations`"
        )
    p, pd = momentum_symbols(model.coordinates)
    rates = [time_derivative(m, model.q, model.qd, model.qdd, model.t) for m in model.momenta]
    return expr.xreplace({**dict(zip(p, model.momenta, strict=True)), **dict(zip(pd, rates, strict=True))})


def _hamiltonian(model: Model, expected: sp.Expr, span: Span, points: Samples) -> Result:
    """H(q, p) is right when H(q, p(q, q_dot)) equals the energy function h(q, q_dot) at sampled
    states (no inverse of the mass matrix is needed)."""
    difference = _in_velocities(model, expected, span, "hamiltonian") - model.energy
    for _, ((residual, scale),) in points.where([difference], "'hamiltonian'", span, with_unknowns=False):
        if abs(residual) > TOLERANCE * max(scale, 1):
            return Result("hamiltonian", False, f"differs from the Legendre transform of the Lagrangian (expected H - derived H = {_number_text(residual)} at a random state)", span)
    return Result("hamiltonian", True, "", span)


def _hamilton_equations(spec: SystemSpec, model: Model, points: Samples) -> Result:
    """The expected equations hold along the motion (with p = dL/dq_dot and p_dot = d/dt dL/dq_dot)
    and determine the rates: their Jacobian in (q_dot, p_dot) has rank 2n at the sampled states."""
    from lagrange_cli.hamilton import momentum_symbols

    entries = spec.expect.hamilton_equations
    span = entries[0][1]
    n = model.n
    if len(entries) < 2 * n:
        return Result("hamilton_equations", False, f"expected {2 * n} equations (q_dot = dH/dp and p_dot = -dH/dq for each of {', '.join(model.coordinates)}), got {len(entries)}", span)
    _, pd = momentum_symbols(model.coordinates)
    rates = [*model.qd, *pd]
    jacobian = [sp.diff(e, r) for e, _ in entries for r in rates]
    rows = [_in_velocities(model, e, where, "hamilton_equations") for e, where in entries]
    columns = [_in_velocities(model, j, span, "hamilton_equations") for j in jacobian]
    for _, values in points.where([*rows, *columns], "the expected Hamilton equations", span, with_unknowns=True):
        for k, (residual, scale) in enumerate(values[: len(rows)]):
            if abs(residual) > TOLERANCE * max(scale, 1):
                return Result("hamilton_equations", False, f"equation {k + 1} does not hold along the motion (residual {_number_text(residual)} at a random state)", entries[k][1])
        concrete = sp.Matrix(len(rows), 2 * n, [v for v, _ in values[len(rows) :]])
        if concrete.rank(iszerofunc=lambda x: abs(x) < TOLERANCE) < 2 * n:
            return Result("hamilton_equations", False, "the expected equations do not determine q_dot and p_dot (they are dependent)", span)
    return Result("hamilton_equations", True, "", span)


def _conserved(model: Model, name: str, span: Span) -> Result:
    if name == "energy":
        ok = model.energy_conserved
        why = "" if ok else "the energy function is not conserved: " + _why_not_energy(model)
        return Result("conserved.energy", ok, why, span, "symbolic")
    if name not in model.coordinates:
        return Result(f"conserved.{name}", False, f"'{name}' was eliminated", span, "symbolic")
    i = model.coordinates.index(name)
    ok = model.ignorable(i)
    why = "" if ok else f"'{name}' is not ignorable: dL/d{name} = {_shown(sp.diff(model.lagrangian, model.q[i]))}"
    if not ok and sp.diff(model.lagrangian, model.q[i]) == 0 and model.generalized_forces[i] != 0:
        why = f"'{name}' is not ignorable: a generalized force {_shown(model.generalized_forces[i])} acts on it"
    return Result(f"conserved.{name}", ok, why, span, "symbolic")


def _conserved_expressions(spec: SystemSpec, model: Model) -> list[Result]:
    """`expect.conserved` entries that are expressions or names of declared symmetries (their
    Noether charges, lagrange_cli/noether.py): each is right when its total time derivative
    vanishes on the equations of motion, at random states (on the constraints, with the
    accelerations solved there). Every declared symmetry is checked (one that is not a symmetry
    is a `SpecError` at its name), also when no entry names it."""
    from lagrange_cli import noether
    from lagrange_cli.spec import time_derivative

    charges = {c.name: c.charge for c in noether.declared(spec, model)}
    if not spec.expect.conserved_expressions:
        return []
    eliminated = {sp.Symbol(name): value for name, value in model.eliminated}
    rates = {sp.Symbol(f"{name}_dot"): time_derivative(value, model.q, model.qd, model.qdd, model.t) for name, value in model.eliminated}
    quantities = []
    for text, expr, span in spec.expect.conserved_expressions:
        quantity = charges[text] if expr is None else expr.xreplace({**eliminated, **rates})
        quantities.append((f"conserved.{text}", time_derivative(quantity, model.q, model.qd, model.qdd, model.t), span))
    points = Samples(model, extra=[rate for _, rate, _ in quantities])
    results = []
    for entry, rate, span in quantities:
        result = Result(entry, True, "", span)
        for _, ((value, scale),) in points.where([rate], f"the time derivative of '{entry.removeprefix('conserved.')}'", span, with_unknowns=True):
            if abs(value) > TOLERANCE * max(scale, 1):
                result = Result(entry, False, f"not constant along the motion: its time derivative on the equations of motion is {_number_text(value)} at a random state", span)
                break
        results.append(result)
    return results


def _why_not_energy(model: Model) -> str:
    if model.lagrangian.has(model.t):
        return "the Lagrangian depends explicitly on time"
    if model.dissipation != 0:
        return "there is dissipation"
    if model.forced:
        return "applied forces do work"
    return "a constraint depends on time"


def _equations(spec: SystemSpec, model: Model, points: Samples) -> Result:
    """The expected equations hold at the derived accelerations and multipliers, and together
    with the constraints of the multipliers they use, they determine those unknowns."""
    expected = [e for e, _ in spec.expect.equations]
    span = spec.expect.equations[0][1]
    unknowns = [*model.qdd, *model.multipliers]
    dynamic = [e for e in expected if any(e.has(u) for u in unknowns)]
    multipliers = [c for c in model.constraints if any(e.has(c.multiplier) for e in dynamic)]
    if len(dynamic) < model.n:
        return Result("equations", False, f"expected {model.n} equations of motion (one per coordinate: {', '.join(model.coordinates)}), got {len(dynamic)}", span)
    for equation in expected:
        if equation not in dynamic and not _is_a_constraint(equation, points, spec.expect.equations[expected.index(equation)][1]):
            where = spec.expect.equations[expected.index(equation)][1]
            return Result("equations", False, f"'{equation} = 0' has no accelerations and is not one of the constraints", where)
    rows = dynamic + [sum((a * u for a, u in zip(c.jacobian, model.qdd, strict=True)), c.acceleration_bias) for c in multipliers]
    used = [*model.qdd, *(c.multiplier for c in multipliers)]
    method = "symbolic" if all(_matching_equation(e, model) is not None for e in dynamic) else "numeric"
    jacobian = sp.Matrix([[sp.diff(e, u) for u in used] for e in rows])
    for _, values in points.where([*dynamic, *jacobian], "the expected equations", span, with_unknowns=True):
        for k, equation in enumerate(dynamic):
            residual, scale = values[k]
            if abs(residual) > TOLERANCE * max(scale, 1):
                where = spec.expect.equations[expected.index(equation)][1]
                return Result("equations", False, f"equation {k + 1}: " + diagnose_equation(equation, model, residual), where)
        concrete = sp.Matrix(len(rows), len(used), [v for v, _ in values[len(dynamic) :]])
        if concrete.rank(iszerofunc=lambda x: abs(x) < TOLERANCE) < len(used):
            return Result("equations", False, "the expected equations do not determine the accelerations (they are dependent)", span)
    return Result("equations", True, "", span, method)


def _matching_equation(expected: sp.Expr, model: Model) -> int | None:
    """The derived equation that `expected` is a multiple of, shown symbolically, if any."""
    for j, (scale, difference) in enumerate(_scaled_differences(expected, model)):
        if scale is not None and _is_zero(difference):
            return j
    return None


def _scaled_differences(expected: sp.Expr, model: Model) -> list[tuple[sp.Expr | None, sp.Expr]]:
    """For each derived equation E_j: the factor r matching the leading unknown of `expected`,
    and r E_j - expected (what the expected equation lacks)."""
    unknowns = [*model.qdd, *model.multipliers]
    if not _small_multiples(expected):  # cancelling or expanding it would not end: no symbolic comparison
        return [(None, sp.Integer(0)) for _ in model.equations()]
    out: list[tuple[sp.Expr | None, sp.Expr]] = []
    for derived in model.equations():
        ratio = None
        for u in unknowns:
            a, b = sp.diff(expected, u), sp.diff(derived, u)
            if a != 0 and b != 0:
                ratio = sp.cancel(a / b) if _cancellable(a / b) else None
                break
        if ratio is not None and not expandable(ratio * derived - expected):
            ratio = None
        out.append((ratio, sp.expand(ratio * derived - expected) if ratio is not None else sp.Integer(0)))
    return out


def _number_text(value: sp.Expr) -> str:
    """`value` to three digits for a message; its plain text where sympy cannot round it (a number
    beyond the decimal module's range)."""
    try:
        return str(sp.N(value, 3))
    except (ArithmeticError, ValueError, TypeError):
        return str(value)[:40]


def _shown(expr: sp.Expr) -> sp.Expr:
    """`expr` simplified for a message when that is cheap (the bounds of `_cancellable`), else as it is."""
    return sp.simplify(expr) if _cancellable(expr) and sp.count_ops(expr) <= 150 else expr


def _cancellable(expr: sp.Expr) -> bool:
    """Whether `cancel` stays cheap on `expr`: bounded size and expansion, no root of a function
    (`algebra.solved_accelerations` uses the same bounds); beyond, the numeric comparison decides."""
    from lagrange_cli.algebra import MAX_CANCEL_OPS, MAX_CANCEL_TERMS, expansion_size, nested_roots, tame_numbers

    return sp.count_ops(expr) <= MAX_CANCEL_OPS and expansion_size(expr, MAX_CANCEL_TERMS) <= MAX_CANCEL_TERMS and not nested_roots(expr) and tame_numbers(expr)


def _is_zero(expr: sp.Expr) -> bool:
    """Targeted normalisation: expand, combine products of sines and cosines, cancel."""
    if expr == 0:
        return True
    if sp.count_ops(expr) > 400 or not _small_multiples(expr) or not _cancellable(expr):
        return False  # left to the numeric comparison
    from lagrange_cli._symengine import to_symengine
    from lagrange_cli.algebra import combine_trig

    try:
        return sp.sympify(combine_trig(to_symengine(sp.expand_trig(sp.together(expr))))) == 0 or sp.cancel(sp.expand_trig(expr)) == 0
    except (TypeError, ValueError, ArithmeticError, sp.PolynomialError):
        return False


MAX_MULTIPLE = 12
"""Largest multiple n of an angle, sin(n x), that `_is_zero` expands (into a polynomial of degree
n in sin x and cos x): tanh(1000*theta) in an answer would take minutes."""


def _small_multiples(expr: sp.Expr) -> bool:
    """Whether every trigonometric or hyperbolic function and every power in `expr` expands to a
    bounded size: arguments at most MAX_MULTIPLE times a term, exponents at most MAX_MULTIPLE."""
    from sympy.functions.elementary.hyperbolic import HyperbolicFunction
    from sympy.functions.elementary.trigonometric import TrigonometricFunction

    for f in expr.atoms(TrigonometricFunction, HyperbolicFunction):
        for term in sp.Add.make_args(f.args[0]):
            coefficient, _ = term.as_coeff_Mul()
            if abs(coefficient) > MAX_MULTIPLE:
                return False
    return all(not (p.exp.is_Number and abs(p.exp) > MAX_MULTIPLE and p.base.is_Add) for p in expr.atoms(sp.Pow))


def diagnose_equation(expected: sp.Expr, model: Model, residual: sp.Expr) -> str:
    """Name the coordinate and the terms the expected equation gets wrong: compared with the
    derived equation that has the same acceleration terms (after scaling), what is missing
    and what is extra. Falls back to the residual at a random state."""
    unknowns = [*model.qdd, *model.multipliers]
    candidates = []
    for j, (ratio, difference) in enumerate(_scaled_differences(expected, model)):
        if ratio is None:
            continue
        if any(_depends(difference, u) for u in unknowns):
            continue
        candidates.append((sp.count_ops(difference), j, difference))
    if not candidates:
        return f"does not hold for the derived motion (it is not equivalent to any combination of the derived equations; residual {_number_text(residual)} at a random state)"
    _, j, difference = min(candidates, key=lambda c: (c[0], c[1]))
    difference = _tidy(difference)
    return f"for '{model.coordinates[j]}': " + describe_terms(expected, difference)


def describe_terms(expected: sp.Expr, difference: sp.Expr) -> str:
    """Say how `expected` differs, given `difference` = right - expected, term by term:
    a wrong sign (difference holds -2 t for an expected term t), extra terms, missing terms."""
    expected_terms = set(sp.Add.make_args(sp.expand(expected)))
    signs, extra, missing = [], [], []
    for term in sp.Add.make_args(difference):
        if -term / 2 in expected_terms:
            signs.append(-term / 2)
        elif -term in expected_terms:
            extra.append(-term)
        else:
            missing.append(term)
    parts = [f"expected has the wrong sign on {_sum(signs)}"] if signs else []
    if extra:
        parts.append(f"expected has the extra term{'s' * (len(extra) > 1)} {_sum(extra)}")
    if missing:
        parts.append(f"expected is missing {_sum(missing)}")
    return "; ".join(parts)


def _depends(expr: sp.Expr, symbol: sp.Symbol) -> bool:
    return expr.has(symbol) and not _is_zero(sp.diff(expr, symbol))


def _tidy(expr: sp.Expr) -> sp.Expr:
    """A readable form of a (small) difference."""
    if sp.count_ops(expr) > 200:
        return expr
    from lagrange_cli._symengine import to_symengine
    from lagrange_cli.algebra import combine_trig

    try:
        return sp.expand(sp.sympify(combine_trig(to_symengine(sp.expand(expr)))))
    except (TypeError, ValueError):
        return expr


def _sum(terms: list[sp.Expr]) -> str:
    return str(sp.Add(*terms))


def _is_a_constraint(equation: sp.Expr, points: Samples, span: Span) -> bool:
    """True when `equation` holds on the constraint surface (at every sampled state, which
    satisfies the constraints) without holding everywhere (it fails at some state off it)."""
    off_surface = False
    for point, ((value, scale),) in points.where([equation], f"'{equation} = 0'", span, with_unknowns=False):
        if abs(value) > TOLERANCE * max(scale, 1):
            return False
        off_value = _finite(_concrete(sp.Matrix([equation]), point.off, point.functions)[0])
        off_surface = off_surface or (off_value is not None and abs(off_value) > TOLERANCE * max(scale, 1))
    return off_surface


def _compare(entry: str, expected: sp.Expr, derived: sp.Expr, points: Samples, span: Span, solved: bool = False) -> Result:
    if not solved and _small_multiples(expected) and _is_zero(sp.expand(expected - derived)):
        return Result(entry, True, "", span, "symbolic")
    for _, ((residual, scale),) in points.where([expected - derived], f"'{entry}'", span, with_unknowns=solved):
        if abs(residual) > TOLERANCE * max(scale, 1):
            return Result(entry, False, _describe_difference(expected, derived, solved, residual), span)
    return Result(entry, True, "", span)


def _describe_difference(expected: sp.Expr, derived: sp.Expr, solved: bool, residual: sp.Expr) -> str:
    if solved or not _small_multiples(expected):
        return f"differs from the derived {'acceleration' if solved else 'momentum'} (expected - derived = {sp.N(residual, 3)} at a random state)"
    return describe_terms(expected, _tidy(sp.expand(derived - expected))) + f" (derived: {derived})"


class _BadPoint(Exception):
    """A sampled state where something cannot be evaluated to a finite real number; its text says what."""


def _evaluate(expr: sp.Expr, point: Point, with_unknowns: bool) -> tuple[sp.Float, sp.Float]:
    """The value of `expr` at the point, and the sum of its terms' magnitudes (its scale);
    `_BadPoint` where it is not a finite real number (0/0, log of a negative number, ...)."""
    values = {**point.values, **(point.unknowns if with_unknowns else {})}
    try:
        concrete = _concrete(sp.Matrix([expr]), values, point.functions, evaluate=False)[0]
        terms = sp.Add.make_args(sp.expand(concrete)) if sp.count_ops(concrete) < 2000 else (concrete,)
        evaluated = [sp.N(term, DIGITS) for term in terms]
        total = _finite(sp.Add(*evaluated).evalf(DIGITS))
        sizes = [_finite(abs(v)) for v in evaluated]
    except (ArithmeticError, ValueError, TypeError) as error:
        raise _BadPoint(f"the value cannot be computed ({error or type(error).__name__})") from None
    if total is None or any(size is None for size in sizes):
        raise _BadPoint("the value is not a finite real number (0/0, a division by zero, or a function such as sqrt or log outside its domain)")
    return total, sum(sizes, sp.Float(0))  # type: ignore[arg-type]


def _finite(value: sp.Expr) -> sp.Float | None:
    """`value` as a real Float, or None when it is not a finite real number (complex beyond
    round-off, infinite, NaN or still symbolic)."""
    try:
        real, imaginary = sp.N(value, DIGITS).as_real_imag()
    except (ArithmeticError, ValueError, TypeError):
        return None
    if not (real.is_Number and imaginary.is_Number) or real.has(sp.nan, sp.zoo, sp.oo, -sp.oo) or imaginary.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
        return None
    if abs(imaginary) > TOLERANCE * max(abs(real), 1):
        return None
    return sp.Float(real, DIGITS)


class Samples:
    """Random states of a model, drawn one by one (seeded) as the entries ask for them: positive
    parameters positive, each undefined function replaced by a random smooth one (a function the
    file defines by its definition), the positions
    moved onto the holonomic constraints, the velocities satisfying every constraint, and the
    derived unknowns solved there. States where the model cannot be evaluated (a singular mass
    matrix, a complex or undefined value) are skipped, up to MAX_DRAWS draws in all; the first
    draws lie in a small box of positive coordinates, later ones in wider, symmetric boxes."""

    def __init__(self, model: Model, extra: Sequence[sp.Expr] = (), seed: int = SEED) -> None:
        self.model = model
        self.rng = random.Random(seed)
        self.matrix, self.rhs = augmented(model)
        self.functions = sorted({f.func for f in _undefined(model, extra)}, key=str)
        self.points: list[Point] = []
        self.draws = 0
        self.causes: dict[str, int] = {}

    def __getitem__(self, index: int) -> Point | None:
        """The index-th good state, or None when MAX_DRAWS draws gave fewer."""
        while len(self.points) <= index and self.draws < MAX_DRAWS:
            self.draws += 1
            try:
                self.points.append(self._draw())
            except _BadPoint as bad:
                self.causes[str(bad)] = self.causes.get(str(bad), 0) + 1
        return self.points[index] if index < len(self.points) else None

    def where(self, exprs: Sequence[sp.Expr], what: str, span: Span, with_unknowns: bool) -> Iterator[tuple[Point, list[tuple[sp.Float, sp.Float]]]]:
        """POINTS states with the values (and scales) of `exprs` there, skipping states where one
        of them is not a finite real number; a `SpecError` at `span` when too few are found."""
        found, index, causes = 0, 0, dict[str, int]()
        while found < POINTS:
            point = self[index]
            index += 1
            if point is None:
                raise self._undecided(what, span, causes)
            try:
                values = [_evaluate(e, point, with_unknowns) for e in exprs]
            except _BadPoint as bad:
                causes[str(bad)] = causes.get(str(bad), 0) + 1
                continue
            found += 1
            yield point, values

    def _undecided(self, what: str, span: Span, causes: dict[str, int]) -> SpecError:
        if causes:
            reason = f"{what} cannot be evaluated at the sampled states: {max(causes, key=lambda c: causes[c])}"
        else:
            common = max(self.causes, key=lambda c: self.causes[c]) if self.causes else "no state was drawn"
            reason = f"the equations of motion cannot be evaluated at {self.draws} random states: {common}"
        return fail(span, f"cannot check this entry: {reason}", "equations and answers that are finite real numbers at generic states (the check evaluates them at random states)")

    def _draw(self) -> Point:
        model, rng = self.model, self.rng
        spread = 0.0 if self.draws <= 2 * POINTS else (3.0 if self.draws <= MAX_DRAWS // 2 else 10.0)
        values: dict[sp.Symbol, sp.Float] = {}
        for parameter in model.parameters:
            values[parameter.symbol] = sp.Float(rng.uniform(-1.5, 1.5) if parameter.real else rng.uniform(0.5, 2.0), DIGITS)
        for q in model.q:
            values[q] = sp.Float(rng.uniform(0.2, 1.3) if not spread else rng.uniform(-spread, spread), DIGITS)
        for v in model.qd:
            values[v] = sp.Float(rng.uniform(-1.5, 1.5) * max(spread, 1.0), DIGITS)
        values[model.t] = sp.Float(rng.uniform(0.1, 2.0), DIGITS)
        for signal in model.inputs:  # a given function of time, sampled like one (its derivatives never enter: lagrange_cli/inputs.py)
            values[signal.symbol] = sp.Float(rng.uniform(-1.5, 1.5), DIGITS)
        replacements: dict[sp.Expr, Callable[..., sp.Expr]] = {}
        for f in self.functions:
            a, b, c = (sp.Float(rng.uniform(0.5, 1.5), DIGITS) for _ in range(3))
            definition = model.definitions.get(str(f))
            replacements[f] = _smooth(a, b, c) if definition is None else _defined(definition)
        off = dict(values)
        if model.constraints:
            values = _on_constraints(model, values, replacements)
        unknowns = {u: value for u, value in zip((*model.qdd, *model.multipliers), _solve(self.matrix, self.rhs, values, replacements, bool(model.constraints)), strict=True)}
        return Point(values, replacements, unknowns, off)


def _solve(matrix: sp.Matrix, rhs: sp.Matrix, values: dict[sp.Symbol, sp.Float], functions: dict[sp.Expr, Callable[..., sp.Expr]], constrained: bool) -> list[sp.Float]:
    """The solution of matrix x = rhs at a state; `_BadPoint` where the matrix is singular
    (relative to its rows' sizes) or an entry is not a finite real number."""
    import mpmath

    with mpmath.workdps(DIGITS):
        a = _numbers(matrix, values, functions, "the mass matrix")
        b = _numbers(rhs, values, functions, "the forces")
        try:
            sizes = [mpmath.sqrt(sum(x**2 for x in a[i, :])) for i in range(a.rows)]
            singular = any(size == 0 for size in sizes) or abs(mpmath.det(a)) <= mpmath.mpf(10) ** (12 - DIGITS) * mpmath.fprod(sizes)
            solution = None if singular else mpmath.lu_solve(a, b)
            unknowns = None if solution is None else [sp.Float(solution[i], DIGITS) for i in range(a.rows)]
        except (ArithmeticError, ValueError, TypeError) as error:  # mpmath on entries near its range's ends
            raise _BadPoint(f"the mass matrix cannot be solved there ({error or type(error).__name__})") from None
        if unknowns is None or not all(_finite(u) is not None for u in unknowns):
            raise _BadPoint("the mass matrix is singular there" + (" (with the constraint rows)" if constrained else ""))
        return unknowns


def _numbers(matrix: sp.Matrix, values: dict[sp.Symbol, sp.Float], functions: dict[sp.Expr, Callable[..., sp.Expr]], what: str) -> Any:
    """A matrix of mpmath reals, or `_BadPoint` naming `what` where an entry is not finite and real."""
    import mpmath

    try:
        concrete = _concrete(matrix, values, functions)
    except (ArithmeticError, ValueError, TypeError) as error:
        raise _BadPoint(f"{what} cannot be evaluated there ({error or type(error).__name__})") from None
    entries = [_finite(e) for e in concrete]
    if any(e is None for e in entries):
        raise _BadPoint(f"{what} is not a finite real number there (0/0, a division by zero, or a function such as sqrt or log outside its domain)")
    return mpmath.matrix([[mpmath.mpf(str(entries[i * concrete.cols + j])) for j in range(concrete.cols)] for i in range(concrete.rows)])


def _on_constraints(model: Model, values: dict[sp.Symbol, sp.Float], functions: dict[sp.Expr, Callable[..., sp.Expr]]) -> dict[sp.Symbol, sp.Float]:
    """The state moved onto the constraints: positions by Gauss-Newton steps of least length
    onto f(q, t) = 0 (dq = -A^T (A A^T)^-1 f, A = df/dq), then velocities by the least change
    that makes A q_dot + b = 0 for every constraint (`_BadPoint` when that does not converge)."""
    import mpmath

    holonomic = [c for c in model.constraints if c.holonomic]
    values = dict(values)
    with mpmath.workdps(DIGITS):
        if holonomic:
            f = sp.Matrix([c.expr for c in holonomic])
            a = sp.Matrix([list(c.jacobian) for c in holonomic])
            for _ in range(PROJECTION_STEPS):
                residual = _numbers(f, values, functions, "a constraint")
                gradient = _numbers(a, values, functions, "the constraint gradient")
                size = mpmath.mpf(1) + sum(abs(values[q]) for q in model.q)
                if mpmath.norm(residual) <= mpmath.mpf(10) ** (8 - DIGITS) * size:
                    break
                step = _least_change(gradient, residual)
                values.update({q: values[q] - sp.Float(step[i], DIGITS) for i, q in enumerate(model.q)})
            else:
                raise _BadPoint("no state on the constraint surface was found near it")
        a = sp.Matrix([list(c.jacobian) for c in model.constraints])
        b = sp.Matrix([c.bias for c in model.constraints])
        gradient = _numbers(a, values, functions, "the constraint gradient")
        velocity = mpmath.matrix([[mpmath.mpf(str(values[v]))] for v in model.qd])
        change = _least_change(gradient, gradient * velocity + _numbers(b, values, functions, "a constraint"))
        values.update({v: values[v] - sp.Float(change[i], DIGITS) for i, v in enumerate(model.qd)})
    return values


def _least_change(a: Any, r: Any) -> Any:
    """The shortest x with a x = r: a^T (a a^T)^-1 r (`_BadPoint` where the rows of a are dependent)."""
    import mpmath

    try:
        return a.T * mpmath.lu_solve(a * a.T, r)
    except ZeroDivisionError:
        raise _BadPoint("the constraints are dependent there (their gradients are not independent)") from None


def _concrete(matrix: sp.Matrix, values: dict[sp.Symbol, sp.Float], functions: dict[sp.Expr, Callable[..., sp.Expr]], evaluate: bool = True) -> sp.Matrix:
    """Numbers for symbols and concrete functions for undefined ones (matched by name)."""
    m = matrix
    if functions:
        by_name = {str(f): g for f, g in functions.items()}
        m = m.replace(lambda e: isinstance(e, sp.core.function.AppliedUndef) and str(e.func) in by_name, lambda e: by_name[str(e.func)](*e.args)).doit()
    m = m.xreplace(values)
    return m.evalf(DIGITS) if evaluate else m


def _smooth(a: sp.Float, b: sp.Float, c: sp.Float) -> Callable[..., sp.Expr]:
    """A concrete smooth function of any number of arguments, standing in for U(...)."""

    def function(*args: sp.Expr) -> sp.Expr:
        return sp.Add(*(a * sp.sin(b * x + c) + c * x**2 + a * b * x for x in args))

    return function


def _defined(definition: sp.Lambda) -> Callable[..., sp.Expr]:
    """The file's definition of a function (`U -> Lambda(s, -k/s)`) as a stand-in: an answer may
    use the general U(r) or what it is defined as."""

    def function(*args: sp.Expr) -> sp.Expr:
        return definition(*args)

    return function


def _undefined(model: Model, extra: Sequence[sp.Expr] = ()) -> set[sp.Expr]:
    """Every undefined function the model or the answers use: in the equations, the energy,
    the momenta, the constraints (a bead on y = H(x)) and the expected entries."""
    parts = [*model.mass_matrix, *model.forcing, model.lagrangian, model.energy, *model.momenta, *extra]
    for c in model.constraints:
        parts += [c.expr, *c.jacobian, c.bias, c.acceleration_bias]
    return set(sp.Matrix(parts).atoms(sp.core.function.AppliedUndef))


@dataclass(frozen=True)
class FileReport:
    """The results of one file, or the bad-input error that stopped it."""

    path: str
    results: tuple[Result, ...] = ()
    error: str = ""

    @property
    def status(self) -> str:
        """One of error (bad input), fail, pass, or skip (a file with nothing to check)."""
        if self.error:
            return "error"
        if not self.results:
            return "skip"
        return "fail" if any(not r.passed for r in self.results) else "pass"


def check_file(path: str) -> FileReport:
    """Load, derive and check one file; bad input becomes the report's `error`."""
    from lagrange_cli import derive, spec
    from lagrange_cli.errors import LagrangeError

    try:
        system = spec.load(path)
        return FileReport(str(path), tuple(check(system, derive.derive(system))))
    except LagrangeError as error:
        return FileReport(str(path), error=str(error))


def exit_code(reports: list[FileReport]) -> int:
    """0 when every answer is right, 1 when some answer is wrong, 2 for bad input."""
    statuses = {r.status for r in reports}
    return 2 if "error" in statuses else 1 if "fail" in statuses else 0


def to_json(reports: list[FileReport]) -> str:
    import json

    files = []
    for report in reports:
        entries = [
            {"entry": r.entry, "passed": r.passed, "method": r.method, "detail": r.detail, "line": r.span.line if r.span else None, "column": r.span.column if r.span else None} for r in report.results
        ]
        files.append({"path": report.path, "status": report.status, "error": report.error or None, "results": entries})
    counts = {status: sum(1 for r in reports if r.status == status) for status in ("pass", "fail", "error", "skip")}
    return json.dumps({"files": files, "summary": {"files": len(reports), **counts, "exit_code": exit_code(reports)}}, indent=2) + "\n"


def to_junit(reports: list[FileReport]) -> str:
    """JUnit XML: one test suite per file, one test case per `expect` entry; a file that cannot
    be loaded is one case with an `<error>`, a file without `expect` one `<skipped>` case. Every
    count attribute is the count of its cases, and all file text passes through `_xml_text`, so
    the document is well-formed whatever the file's names, title or messages contain."""
    import xml.etree.ElementTree as ET

    root = ET.Element("testsuites", name="lagrange check")
    for report in reports:
        path = _xml_text(report.path)
        suite = ET.SubElement(root, "testsuite", name=path)
        if report.error:
            case = ET.SubElement(suite, "testcase", classname=path, name="load")
            ET.SubElement(case, "error", message=_xml_text(report.error.splitlines()[0] if report.error.strip() else "error")).text = _xml_text(report.error)
        elif not report.results:
            case = ET.SubElement(suite, "testcase", classname=path, name="expect")
            ET.SubElement(case, "skipped", message="no `expect` block: nothing to check")
        for result in report.results:
            case = ET.SubElement(suite, "testcase", classname=path, name=_xml_text(result.entry))
            if result.span:
                case.set("file", _xml_text(result.span.file))
                case.set("line", str(result.span.line))
            if not result.passed:
                ET.SubElement(case, "failure", message=_xml_text(result.detail)).text = _xml_text(result.detail)
        _count(suite)
    _count(root)
    ET.indent(root)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _count(element: ElementTree.Element) -> None:
    """tests, failures, errors and skipped of a suite (or of all suites): counted from its cases."""
    cases = list(element.iter("testcase"))
    element.set("tests", str(len(cases)))
    for attribute, tag in (("failures", "failure"), ("errors", "error"), ("skipped", "skipped")):
        element.set(attribute, str(sum(1 for case in cases if case.find(tag) is not None)))


# XML 1.0 allows tab, newline, carriage return and U+0020..U+D7FF, U+E000..U+FFFD, U+10000 up;
# of these, DEL and the C1 controls (U+007F..U+009F) are discouraged and replaced as well.
_NOT_XML = re.compile("[^\t\n\r\u0020-\u007e\u00a0-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def _xml_text(text: str) -> str:
    """`text` with every character XML 1.0 cannot hold or discourages (control characters other
    than tab, newline and carriage return, lone surrogates, U+FFFE, U+FFFF) shown as `U+XXXX`."""
    return _NOT_XML.sub(lambda match: f"U+{ord(match.group()):04X}", text)
