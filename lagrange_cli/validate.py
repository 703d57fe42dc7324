"""One validation pass over a derived model, so that emitters, `check` and numeric code only
ever see expressions the parser itself would let in.

Differentiation, solving and float arithmetic can make objects that no system file may
contain: `zoo`, `oo` and `nan` (`0**x`, `1/0` after a substitution), `DiracDelta` from the
derivative of `sign`, `re`/`im`/`Piecewise`/`LambertW` from solving, derivatives of a
general function at a compound argument, floats that overflow or underflow to 0. Every
expression of a finished `Model` is walked against an allow-list of node types, and every
number is checked to be a finite double of its own size. When a node is refused, each entry
of the file (a particle's mass, the potential, a constraint, ...) is differentiated as the
deriver does, and the first entry that produces the refused node is named, with its line and
column.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass

import sympy as sp
from sympy.core.function import AppliedUndef

from lagrange_cli.errors import Span, fail
from lagrange_cli.expr import SUPPORTED_FUNCTIONS, float_problem, real_derivative
from lagrange_cli.model import Model, SymengineForms, apply_definitions

MAX_CANDIDATES = 400
"""Most expressions and derivatives examined to find the entry a refused node comes from (only on the
error path); beyond them the error names the part of the model instead of a line."""
MAX_EXPONENT = 10_000
"""Largest integer exponent a derived power may have (the parser allows 1000; products of such powers add up)."""

CAUSES: dict[str, str] = {
    "DiracDelta": "from the derivative of sign/Abs",
    "Heaviside": "from the derivative of sign/Abs",
    "re": "the real part of a complex quantity",
    "im": "the imaginary part of a complex quantity",
    "arg": "the argument of a complex quantity",
    "conjugate": "a complex conjugate",
    "Piecewise": "a case distinction",
    "LambertW": "the inverse of x*exp(x), from solving a constraint",
    "CRootOf": "the root of a polynomial, from solving a constraint",
    "RootOf": "the root of a polynomial, from solving a constraint",
}
HINTS: dict[str, str] = {
    "DiracDelta": "a differentiable expression (write sqrt(x**2) for a smooth |x| away from 0, or split the motion into regions)",
    "Heaviside": "a differentiable expression (write sqrt(x**2) for a smooth |x| away from 0, or split the motion into regions)",
    "Subs": "declared functions applied to a single coordinate or parameter, e.g. `U(r)`, or a function with `arguments` and a `definition`",
    "Derivative": "declared functions applied to a single coordinate or parameter, e.g. `U(r)`",
}
DEFAULT_HINT = "an expression of numbers, names, + - * / ** and the listed functions, whose derivatives are of the same kind"


@dataclass(frozen=True)
class Source:
    """An entry of the file: what it is, where it is written, its expressions, and the variables
    the deriver differentiates it by."""

    what: str
    span: Span | None
    exprs: tuple[sp.Expr, ...]
    variables: tuple[sp.Symbol, ...] | None = None
    """What it is differentiated by, when not the coordinates, velocities and time (a definition's arguments)."""


@dataclass(frozen=True)
class Refusal:
    """A refused node, why (for the message) and what would be right (for `expected:`)."""

    node: sp.Basic
    reason: str
    hint: str


def refusal(expr: sp.Basic, defined: Iterable[str] = ()) -> Refusal | None:
    """The first node of `expr` outside the allow-list, with why it is refused; None if all is well.

    Allowed: symbols, finite numbers (pi, E, integers, rationals and floats a double holds),
    + * **, the parser's functions, declared functions, their derivatives at plain symbols,
    and (for functions with a definition, which numeric code writes out) their derivatives at
    compound arguments (`Subs`)."""
    defined = frozenset(defined)
    stack: list[sp.Basic] = [expr]
    seen: set[sp.Basic] = set()
    while stack:
        node = stack.pop()
        if node in seen:
            continue
        seen.add(node)
        found = _check_node(node, defined)
        if found is not None:
            return found
        if isinstance(node, sp.Subs):
            stack.extend(node.point)
            stack.extend(a for a in node.expr.expr.args if not isinstance(a, sp.Dummy))
        elif isinstance(node, sp.Derivative):
            stack.append(node.expr)
        else:
            stack.extend(node.args)
    return None


def _check_node(node: sp.Basic, defined: frozenset[str]) -> Refusal | None:
    name = type(node).__name__
    if node.is_Symbol or node in (sp.pi, sp.E):
        return None
    if node in (sp.zoo, sp.oo, -sp.oo, sp.nan) or name in ("Infinity", "NegativeInfinity", "ComplexInfinity", "NaN"):
        return Refusal(node, "an undefined value (a division by zero or an infinite value)", "an expression with a finite value everywhere it is used")
    if node is sp.I or name == "ImaginaryUnit":
        return Refusal(node, "the imaginary unit", "real expressions")
    if node.is_Number:
        problem = float_problem(node)
        return Refusal(node, f"a number that {problem}", "numbers between 1e-300 and 1e300 in size (or 0)") if problem else None
    if isinstance(node, (sp.Add, sp.Mul)):
        return None
    if isinstance(node, sp.Pow):
        if node.base == 0:
            return Refusal(node, "a power of zero, undefined where the exponent is not positive", "a non-zero base")
        if node.exp.is_Integer and abs(int(node.exp)) > MAX_EXPONENT:
            return Refusal(node, f"a power with exponent {node.exp}", f"exponents of at most {MAX_EXPONENT}")
        return None
    if type(node) in SUPPORTED_FUNCTIONS or isinstance(node, AppliedUndef):
        return None
    if isinstance(node, sp.Derivative):
        inner = node.expr
        if isinstance(inner, (sp.sign, sp.Abs)):
            return Refusal(sp.DiracDelta(inner.args[0]), CAUSES["DiracDelta"], HINTS["DiracDelta"])
        if isinstance(inner, AppliedUndef) and all(isinstance(v, sp.Symbol) and v in inner.args for v in node.variables):
            return None
        return Refusal(node, "a derivative that cannot be taken", HINTS["Derivative"])
    if isinstance(node, sp.Subs):
        inner = node.expr.expr if isinstance(node.expr, sp.Derivative) else node.expr
        if isinstance(inner, AppliedUndef) and isinstance(node.expr, sp.Derivative) and str(inner.func) in defined:
            return None
        function = inner.func if isinstance(inner, AppliedUndef) else inner
        return Refusal(node, f"the derivative of '{function}' at a compound argument ({', '.join(map(str, node.point))}), which needs a definition of '{function}'", HINTS["Subs"])
    cause = CAUSES.get(name)
    return Refusal(node, cause or f"the function '{name}', which is not one of the supported functions", HINTS.get(name, DEFAULT_HINT))


def symengine_parts(model: Model) -> list[object]:
    """The expressions of `model.symengine`: the parts of `model_parts` that `derive` computes in symengine."""
    return forms_parts(model.symengine)


def forms_parts(forms: SymengineForms) -> list[object]:
    """The expressions of symengine forms, in the order of `model_parts`."""
    return [forms.kinetic, forms.potential, forms.lagrangian, forms.dissipation, forms.energy, *forms.generalized_forces, *forms.momenta, *forms.forcing, *(m for row in forms.mass for m in row)]


def _sympy_parts(model: Model) -> Iterator[tuple[str, sp.Basic]]:
    """The parts of `model_parts` that are sympy from the start (constraints, eliminated coordinates, exact solutions)."""
    for row in model.constraints:
        for part in (row.expr, *row.jacobian, row.bias, row.acceleration_bias):
            yield f"constraint '{row.name}'", part
    for name, solution in model.eliminated:
        yield f"the solution for the eliminated '{name}'", solution
    for name, exact in model.exact.items():
        yield f"the exact solution for '{name}'", exact


def _symengine_functions() -> frozenset[str]:
    """The symengine class names of the parser's functions (exp becomes a power of E in symengine)."""
    from lagrange_cli._symengine import to_symengine

    x, y = sp.symbols("x y")
    names = set()
    for function in SUPPORTED_FUNCTIONS:
        converted = to_symengine(function(x, y) if function is sp.atan2 else function(x))
        if converted.is_Function:
            names.add(type(converted).__name__)
    return frozenset(names)


_SE_FUNCTIONS: frozenset[str] | None = None


def survey(exprs: Iterable[object], limit: int = 10**9) -> tuple[int, bool]:
    """One walk over the distinct nodes of symengine expressions: (their number, counting stops past
    `limit`; whether every node is one that `refusal` allows once converted to sympy: symbols, pi, E,
    numbers with no `float_problem`, + * ** (no power of 0, no exponent above `MAX_EXPONENT`), the
    parser's functions, declared functions and their derivatives at their own plain symbols).

    Anything else (a `Subs`, an infinity, a derivative of Abs, ...) is not cleared here, and the caller
    checks the sympy form, which decides and says where it comes from."""
    from lagrange_cli._symengine import se

    global _SE_FUNCTIONS
    if _SE_FUNCTIONS is None:
        _SE_FUNCTIONS = _symengine_functions()
    functions = _SE_FUNCTIONS
    plain = (se.Add, se.Mul, se.Symbol)
    seen: set[object] = set()
    stack = list(exprs)
    cleared = True
    while stack and len(seen) <= limit:
        node = stack.pop()
        if node in seen:
            continue
        seen.add(node)
        if isinstance(node, plain):
            stack.extend(node.args)
            continue
        if cleared:
            cleared = _cleared(node, functions)
        stack.extend(node.args)  # type: ignore[attr-defined]
    return len(seen), cleared


def _cleared(node: object, functions: frozenset[str]) -> bool:
    """Whether one symengine node (not an Add, Mul or Symbol) is allowed; see `survey`."""
    from lagrange_cli._symengine import se

    kind = type(node).__name__
    if node.is_Number:  # type: ignore[attr-defined]
        return kind in ("Integer", "Rational", "RealDouble", "Zero", "One", "NegativeOne", "Half") and not float_problem(sp.sympify(node))
    if kind == "Pow":
        base, exponent = node.args  # type: ignore[attr-defined]
        return not (base == 0 or (exponent.is_Integer and abs(int(exponent)) > MAX_EXPONENT))
    if node.is_Symbol or kind == "FunctionSymbol" or kind in functions or node == se.pi or node == se.E:  # type: ignore[attr-defined]
        return True
    if kind == "Derivative":
        inner, *variables = node.args  # type: ignore[attr-defined]
        return type(inner).__name__ == "FunctionSymbol" and all(v.is_Symbol and v in inner.args for v in variables)
    return False


def clean(exprs: Iterable[object]) -> bool:
    """Whether every node of these symengine expressions is cleared by `survey`."""
    return survey(exprs)[1]


def model_parts(model: Model) -> Iterator[tuple[str, sp.Basic]]:
    """Every expression of a model, each with where it is in the model."""
    yield "the kinetic energy", model.kinetic
    yield "the potential energy", model.potential
    yield "the Lagrangian", model.lagrangian
    yield "the dissipation function", model.dissipation
    yield "the energy function", model.energy
    for name, force, momentum in zip(model.coordinates, model.generalized_forces, model.momenta, strict=True):
        yield f"the generalized force on '{name}'", force
        yield f"the momentum of '{name}'", momentum
    for i, name in enumerate(model.coordinates):
        yield f"the equation of '{name}'", model.forcing[i]
        for j in range(model.n):
            yield f"the equation of '{name}'", model.mass_matrix[i, j]
    for row in model.constraints:
        for part in (row.expr, *row.jacobian, row.bias, row.acceleration_bias):
            yield f"constraint '{row.name}'", part
    for name, solution in model.eliminated:
        yield f"the solution for the eliminated '{name}'", solution
    for name, exact in model.exact.items():
        yield f"the exact solution for '{name}'", exact
    for name, definition in model.definitions.items():
        yield f"the definition of '{name}'", definition.expr


def validate(model: Model, sources: Sequence[Source], variables: Sequence[sp.Symbol], cleared: bool | None = None) -> None:
    """Raise a `SpecError` at the entry of the file that a refused node comes from; see the module docstring.

    A model made by `derive` is first checked on its symengine forms (`clean`, an allow-list no wider than
    `refusal`'s), which needs no sympy conversion; only when that finds a node it does not clear, or the
    model has definitions, are the sympy fields checked (and the culprit located) as below. `cleared`
    is `survey`'s verdict on `symengine_parts(model)` when the caller has it already."""
    defined = set(model.definitions)
    if model.native and not model.definitions and (cleared if cleared is not None else clean(symengine_parts(model))):
        for part, expr in _sympy_parts(model):
            found = refusal(expr, defined)
            if found is not None:
                raise _located(model, part, found, sources, variables, defined)
        return
    for part, expr in model_parts(model):
        found = refusal(expr, defined)
        if found is not None:
            raise _located(model, part, found, sources, variables, defined)
    if model.definitions:
        written = model.with_definitions()
        for part, expr in model_parts(written):
            found = refusal(expr)
            if found is not None:
                # the definitions first: a refused node there is found in the definition, where it is written
                spelled = [dataclasses.replace(s, exprs=tuple(apply_definitions(e, model.definitions) for e in s.exprs)) for s in sorted(sources, key=lambda s: s.variables is None)]
                raise _located(written, part + " (with the functions' definitions written out)", found, spelled, variables, set())


def _located(model: Model, part: str, found: Refusal, sources: Sequence[Source], variables: Sequence[sp.Symbol], defined: set[str]) -> Exception:
    """The error for a refused node: at the first entry that has it, or whose derivative has it
    (an entry with a refused node of the same kind first, then any)."""
    fallback = None
    suspects = [s for s in sources if _may_produce(s, found.node)]
    for source, derivative, respect in itertools.islice(_candidates(suspects, variables), MAX_CANDIDATES):
        local = refusal(derivative, defined)
        if local is None:
            continue
        error = fail(source.span, f"{_phrase(source.what, respect)} contains {_short(local.node)} ({local.reason}), which the equations cannot use", local.hint)
        if type(local.node) is type(found.node) or local.reason == found.reason:
            return error
        fallback = fallback or error
    if fallback is not None:
        return fallback
    return fail(None, f"{model.source}: {part} contains {_short(found.node)} ({found.reason}), which the equations cannot use", found.hint)


def _may_produce(source: Source, node: sp.Basic) -> bool:
    """Whether differentiating `source` can give `node`: a Dirac delta needs a sign or Abs, a
    derivative of a general function needs a general function, and a node with free symbols needs
    one of them (anything may give an undefined value). Keeps the search for the culprit short."""
    exprs = source.exprs
    if isinstance(node, (sp.DiracDelta, sp.Heaviside)) and not any(e.has(sp.sign, sp.Abs) for e in exprs):
        return False
    if isinstance(node, (sp.Subs, sp.Derivative)) and not any(e.has(AppliedUndef) for e in exprs):
        return False
    names = {str(s) for s in getattr(node, "free_symbols", ())}
    return not names or source.variables is not None or any(str(s) in names for e in exprs for s in e.free_symbols)


def first_refusal(what: str, exprs: Sequence[sp.Expr], variables: Sequence[sp.Symbol], defined: Iterable[str] = ()) -> tuple[str, Refusal] | None:
    """The first refused node of `exprs` or of their first and second derivatives, with a phrase
    saying where it is ('the second derivative of <what> with respect to x'); None if all is well."""
    for _, derivative, respect in _candidates([Source(what, None, tuple(exprs), tuple(variables))], variables):
        found = refusal(derivative, defined)
        if found is not None:
            return _phrase(what, respect), found
    return None


def _phrase(what: str, respect: str) -> str:
    if not respect:
        return what
    if " and " in respect:
        v, w = respect.removeprefix("with respect to ").split(" and ")
        return f"the second derivative of {what} with respect to {v}" + ("" if v == w else f" and {w}")
    return f"the derivative of {what} {respect}"


def _candidates(sources: Sequence[Source], variables: Sequence[sp.Symbol]) -> Iterator[tuple[Source, sp.Expr, str]]:
    """Each entry's expressions, then their first and second derivatives (as the deriver takes them),
    each with a description: '' for the expression itself, else 'the derivative of ... with respect to x'."""
    for source in sources:
        for expr in source.exprs:
            yield source, expr, ""
    for source in sources:
        for expr in source.exprs:
            for first, v in _derivatives(expr, source.variables or variables):
                yield source, first, f"with respect to {v}"
    for source in sources:
        by = source.variables or variables
        for expr in source.exprs:
            for first, v in _derivatives(expr, by):
                for second, w in _derivatives(first, by):
                    yield source, second, f"with respect to {v} and {w}"


def _derivatives(expr: sp.Expr, variables: Sequence[sp.Symbol]) -> Iterator[tuple[sp.Expr, sp.Symbol]]:
    """d expr / d v for each variable v that `expr` has, with real stand-ins as the parser differentiates."""

    def by(v: sp.Symbol) -> Callable[[sp.Expr, Mapping[sp.Symbol, sp.Symbol]], sp.Expr]:
        return lambda e, real: sp.diff(e, real.get(v, v))

    for v in [v for v in variables if expr.has(v)]:
        yield real_derivative(expr, by(v)), v


def _short(node: sp.Basic) -> str:
    text = str(node)
    return text if len(text) <= 80 else text[:77] + "..."
