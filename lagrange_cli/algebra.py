"""Algebra on expressions and models that every stage shares: the targeted trigonometric
rewrite, the augmented (index-1) matrix of a constrained system, its invertibility, and
the symbolically solved accelerations."""

from __future__ import annotations

import math
from itertools import combinations

import sympy as sp
from sympy.core.function import AppliedUndef

from lagrange_cli._symengine import se, to_symengine
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

MAX_TERMS = 2000
"""Largest number of terms an expansion may produce (estimated before expanding); beyond it the
expression is kept as it is, which is correct, only less tidy."""
MAX_POWER = 6
"""Largest integer power of a sum that is multiplied out (`(a + b)**7` stays a power)."""
MAX_NODES = 5_000
"""Largest expression (distinct nodes) that is expanded at all: beyond it, the estimate itself stops early."""


def expansion_size(expr: object, limit: int = MAX_TERMS) -> int:
    """An upper estimate of the number of terms `expand(expr)` makes (of any sub-expression,
    since expand works inside function arguments too), counted without expanding: a sum adds
    its terms' counts, a product multiplies them, a power n of a k-term sum has C(n + k - 1, k - 1)
    terms. Saturates at `limit + 1`; works on sympy and symengine expressions alike.

    The walk visits each distinct node once and stops at the first sub-expression over `limit`,
    or after `MAX_NODES` nodes (counted as over the limit), so it costs at most O(MAX_NODES)."""
    sizes: dict[object, int] = {}
    largest = 1
    stack: list[tuple[object, bool]] = [(expr, False)]
    while stack:
        node, ready = stack.pop()
        if node in sizes:
            continue
        if len(sizes) > MAX_NODES or largest > limit:
            return limit + 1
        args = node.args  # type: ignore[attr-defined]
        if not ready and args:
            stack.append((node, True))
            stack.extend((a, False) for a in args if a not in sizes)
            continue
        kind = type(node).__name__
        if kind == "Add":
            size = min(limit + 1, sum(sizes[a] for a in args))
        elif kind == "Mul":
            size = 1
            for a in args:
                size = min(limit + 1, size * sizes[a])
        elif kind == "Pow" and args[1].is_Integer and sizes[args[0]] > 1:
            size = _multinomial_terms(sizes[args[0]], abs(int(args[1])), limit)
        else:
            size = 1
        sizes[node] = size
        largest = max(largest, size)
    return min(largest, limit + 1)


def _multinomial_terms(k: int, n: int, limit: int) -> int:
    """C(n + k - 1, k - 1), the number of terms of a k-term sum to the n-th power, saturating at limit + 1."""
    if n > MAX_POWER:
        return limit + 1
    count = 1
    for i in range(1, min(n, k - 1) + 1):
        count = count * (n + k - 1 - i + 1) // i
        if count > limit:
            return limit + 1
    return count


def expandable(expr: object) -> bool:
    """True when expanding `expr` stays within `MAX_TERMS` terms and multiplies out no power above `MAX_POWER`."""
    return expansion_size(expr) <= MAX_TERMS


def expand_bounded(expr: sp.Expr, max_power: int = MAX_POWER) -> sp.Expr:
    """sympy's expand, unless the result would exceed `MAX_TERMS` terms or multiply out a power above `max_power`."""
    if any(p.base.is_Add and p.exp.is_Integer and abs(int(p.exp)) > max_power for p in expr.atoms(sp.Pow)) or not expandable(expr):
        return expr
    return sp.expand(expr)


def se_expand_bounded(expr: se.Basic) -> se.Basic:
    """symengine's expand, within the same bounds as `expand_bounded`."""
    return se.expand(expr) if expandable(expr) else expr


KINKS = (se.Abs, se.sign, se.Piecewise, se.Max, se.Min)
"""Functions whose argument's sign switches the expression (a one-sided wall, Coulomb friction)."""


def _kinked(term: se.Basic) -> bool:
    return any(term.atoms(kind) for kind in KINKS)


def _split_kinked(expr: se.Basic) -> tuple[se.Basic, se.Basic]:
    """(the terms of the sum `expr` without a kink, those with one); `expr` itself and 0 when none has one
    (the sum is not rebuilt: its order, and so the generated code's round-off, stays as it was)."""
    terms = se.Add.make_args(expr)
    if not any(_kinked(t) for t in terms):
        return expr, se.Integer(0)
    return se.Add(*(t for t in terms if not _kinked(t))), se.Add(*(t for t in terms if _kinked(t)))


def smooth_expand(expr: se.Basic) -> se.Basic:
    """symengine's expand of the terms of `expr` without a kink (Abs, sign, Piecewise, Max, Min); the
    terms with one are kept as they are. Multiplied out, a one-sided wall k ((e + |e|)/2)^2 becomes
    k e^2/4 + k e |e|/2 + k |e|^2/4, terms of size k that cancel where the wall is not touched and leave
    round-off of k x 1e-16 (1e-8 at k = 1e8) in a force that is exactly 0.0 in the product form
    (e + |e| is 0.0 in floating point for e < 0): an implicit method's Newton iteration, or LSODA's error
    estimate, then chases that noise (issue 15: the ball in the cup)."""
    smooth, kinked = _split_kinked(expr)
    return se.expand(smooth) + kinked if kinked != 0 else se.expand(smooth)


def combine_trig(expr: se.Basic) -> se.Basic:
    """Targeted, linear-time trigonometric simplification of an expanded sum:
    c cos a cos b + c sin a sin b -> c cos(a - b), c cos a cos b - c sin a sin b -> c cos(a + b),
    c sin a cos b +- c cos a sin b -> c sin(a +- b), c sin^2 a + c cos^2 a -> c.
    It only ever shortens the sum, so it is safe on expressions of any size; an expression whose
    expansion would be too large (`expandable`) is returned as it is, and so are its terms with a kink
    (`smooth_expand`)."""
    if not expandable(expr):
        return expr
    expr, kinked = _split_kinked(expr)
    expr = se.expand(expr)
    for _ in range(6):
        combined = _combine_once(expr)
        if combined == expr:
            break
        expr = se_expand_bounded(combined)
    return expr + kinked if kinked != 0 else expr


def _combine_once(expr: se.Basic) -> se.Basic:
    terms = list(expr.args) if isinstance(expr, se.Add) else [expr]
    parsed = [_factors(term) for term in terms]
    groups: dict[tuple[object, ...], list[tuple[int, str]]] = {}
    for index, (_, factors) in enumerate(parsed):
        trig = [f for f in factors if isinstance(f, (se.sin, se.cos))]
        for f in trig:
            if factors[f] == 2:
                rest = frozenset((b, e) for b, e in factors.items() if b != f)
                groups.setdefault(("square", f.args[0], rest), []).append((index, "s" if isinstance(f, se.sin) else "c"))
        single = sorted((f for f in trig if factors[f] == 1), key=lambda f: (str(f.args[0]), isinstance(f, se.sin)))
        for f, g in combinations(single, 2):
            if f.args[0] == g.args[0]:
                continue
            if str(f.args[0]) > str(g.args[0]):
                f, g = g, f
            rest = frozenset((b, e) for b, e in factors.items() if b not in (f, g))
            kind = ("s" if isinstance(f, se.sin) else "c") + ("s" if isinstance(g, se.sin) else "c")
            groups.setdefault(("pair", f.args[0], g.args[0], rest), []).append((index, kind))
    used: set[int] = set()
    extra: list[se.Basic] = []
    for key, members in groups.items():
        by_kind: dict[str, int] = {}
        for index, kind in members:
            if index not in used:
                by_kind.setdefault(kind, index)
        rest = se.Mul(*(b**e for b, e in key[-1]))  # type: ignore[attr-defined]
        for k1, k2 in (("s", "c"),) if key[0] == "square" else (("cc", "ss"), ("sc", "cs")):
            if k1 in by_kind and k2 in by_kind:
                i, j = by_kind[k1], by_kind[k2]
                merged = _merge(k1, parsed[i][0], parsed[j][0], key)
                if merged is not None:
                    used.update((i, j))
                    extra.append(merged * rest)
    if not used:
        return expr
    return se.Add(*(term for index, term in enumerate(terms) if index not in used), *extra)


def _merge(kind: str, c1: se.Basic, c2: se.Basic, key: tuple[object, ...]) -> se.Basic | None:
    """The single term replacing c1 f + c2 g, if the identity for this pair applies."""
    if kind == "s":
        return c1 if c1 == c2 else None
    a, b = se.sympify(key[1]), se.sympify(key[2])
    if kind == "cc":
        return c1 * se.cos(a - b) if c1 == c2 else (c1 * se.cos(a + b) if c1 == -c2 else None)
    return c1 * se.sin(a + b) if c1 == c2 else (c1 * se.sin(a - b) if c1 == -c2 else None)


def _factors(term: se.Basic) -> tuple[se.Basic, dict[se.Basic, se.Basic]]:
    """A product as (numeric coefficient, {base: exponent})."""
    coefficient: se.Basic = se.Integer(1)
    factors: dict[se.Basic, se.Basic] = {}
    for factor in term.args if isinstance(term, se.Mul) else (term,):
        if factor.is_Number:
            coefficient *= factor
        elif isinstance(factor, se.Pow):
            base, exponent = factor.args
            factors[base] = factors.get(base, 0) + exponent
        else:
            factors[factor] = factors.get(factor, 0) + 1
    return coefficient, factors


MAX_CANCEL_OPS = 1000
MAX_CANCEL_TERMS = 1000
"""Above this many operations in a solved form's numerator and determinant, or terms in their
expansion, no `cancel` (its polynomial gcds are quick on textbook systems, unbounded beyond)."""


def solved_accelerations(model: Model, max_size: int = 4) -> tuple[sp.Expr, ...]:
    """q_ddot (and the multipliers) solved symbolically by Cramer's rule, only for small systems.

    The solved form grows explosively (hundreds of operations at two coordinates, millions
    at six), so larger systems are refused; numeric code solves M q_ddot = F at run time.
    """
    size = model.n + len(model.constraints)
    if size > max_size:
        raise DerivationError(
            f"{model.source}: the solved form of a system with {size} unknowns would be enormous "
            f"(at most {max_size} are solved symbolically); use `--form matrix`, or `--python`, "
            "whose code solves M q_ddot = F numerically"
        )
    matrix, rhs = augmented(model)
    check_invertible(model, matrix)
    # symengine has no `Subs` (a derivative of a declared function at a compound argument, U'(sqrt(x^2
    # + y^2))): each stands in the determinants as a symbol whose name no file can write, and is put back.
    opaque = {node: sp.Symbol(f"Subs#{index}") for index, node in enumerate(sorted(matrix.atoms(sp.Subs) | rhs.atoms(sp.Subs), key=sp.default_sort_key))}
    if opaque:
        matrix, rhs = matrix.xreplace(opaque), rhs.xreplace(opaque)
    back = {symbol: node for node, symbol in opaque.items()}
    entries = [[to_symengine(matrix[i, j]) for j in range(size)] for i in range(size)]
    det = _sp(combine_trig(se.DenseMatrix(entries).det()))
    result = []
    for i in range(size):
        replaced = [[to_symengine(rhs[r]) if j == i else entries[r][j] for j in range(size)] for r in range(size)]
        numerator = _sp(combine_trig(se.DenseMatrix(replaced).det()))
        quotient = numerator / det
        # cancel finds polynomial gcds: cheap on textbook sizes, unbounded on big ones (a nested
        # atan2 under a 7th root took minutes); past the bound the quotient stays as it is.
        small = (
            sp.count_ops(numerator) + sp.count_ops(det) <= MAX_CANCEL_OPS and expansion_size(quotient, MAX_CANCEL_TERMS) <= MAX_CANCEL_TERMS and not nested_roots(quotient) and tame_numbers(quotient)
        )
        result.append(sp.factor_terms(sp.cancel(quotient)) if small else quotient)
    return tuple(r.xreplace(back) for r in result) if back else tuple(result)


TAME_MAGNITUDE = 1e30
"""Floats beyond this size (or nonzero below its inverse) make sympy's polynomial algorithms
(factor, cancel, trigsimp, solve) work with integers of hundreds of digits, without bound."""


def tame_numbers(expr: object) -> bool:
    """True when every float in `expr` is 0 or between 1/TAME_MAGNITUDE and TAME_MAGNITUDE in size:
    the condition, with a size bound, for handing it to a sympy simplification (a mass of 1e308 with
    one of 1e-320 made `trigsimp` of a 3x3 determinant run for minutes)."""
    floats = sp.sympify(expr).atoms(sp.Float)
    return all(f == 0 or 1 / TAME_MAGNITUDE <= abs(f) <= TAME_MAGNITUDE for f in floats)


def nested_roots(expr: sp.Expr) -> bool:
    """A non-integer power of something containing a function (atan2(-1, y)**(1/7)): its derivatives
    bring new generators with large integer coefficients, on which cancel's gcds run away."""
    return any(not p.exp.is_Integer and p.base.has(sp.Function) for p in expr.atoms(sp.Pow))


def augmented(model: Model) -> tuple[sp.Matrix, sp.Matrix]:
    """[[M, -A^T], [A, 0]] [q_ddot; lambda] = [F; -c], the index-1 form of a constrained system."""
    a = model.constraint_matrix
    k = len(model.constraints)
    top = sp.Matrix(model.mass_matrix).row_join(-a.T) if k else sp.Matrix(model.mass_matrix)
    matrix = top.col_join(a.row_join(sp.zeros(k, k))) if k else top
    rhs = sp.Matrix(model.forcing).col_join(sp.Matrix([-c.acceleration_bias for c in model.constraints])) if k else sp.Matrix(model.forcing)
    return matrix, rhs


def check_invertible(model: Model, matrix: sp.Matrix | None = None) -> None:
    """Raise a `DerivationError` naming the coordinates without inertia if M (or the augmented
    matrix of a constrained system) is singular at a generic point."""
    if matrix is None:
        matrix = augmented(model)[0]
    zero_rows = [model.coordinates[i] for i in range(model.n) if all(matrix[i, j] == 0 for j in range(matrix.cols))]
    if zero_rows:
        from lagrange_cli.errors import fail

        names = ", ".join(repr(z) for z in zero_rows)
        message = f"the mass matrix is singular: coordinate{'s' * (len(zero_rows) > 1)} {names} {'have' if len(zero_rows) > 1 else 'has'} no inertia (no kinetic energy depends on {'their velocities' if len(zero_rows) > 1 else 'its velocity'})"
        expected = "give it a mass, or remove it with a constraint and `eliminate`"
        span = model.spans.get(zero_rows[0])
        if span is not None:
            raise fail(span, message, expected)
        raise DerivationError(f"{model.source}: {message}; {expected}")
    if pivot_ratio(matrix, model) < 1e-12:
        raise DerivationError(
            f"{model.source}: the mass matrix{' (with the constraint rows)' if model.constraints else ''} is singular: "
            "the coordinates are not independent, or some have no inertia; the accelerations cannot be solved for"
        )


def check_solvable(model: Model) -> None:
    """`check_invertible` without the sympy fields for an unconstrained model: M evaluated by
    symengine at a random point, pivots by `pivot_ratio`'s rule; only a doubtful M (a zero row, a
    tiny pivot, no finite value) goes to `check_invertible` for its verdict and message."""
    if model.constraints:
        check_invertible(model)
        return
    import random

    forms = model.symengine
    rng = random.Random(1)
    point = {se.Symbol(p.name): se.RealDouble(p.value if p.value else rng.uniform(0.5, 2.0)) for p in model.parameters}
    point.update({se.Symbol(i.name): se.RealDouble(rng.uniform(0.5, 2.0)) for i in model.inputs})
    point.update({s: se.RealDouble(rng.uniform(0.2, 1.3)) for s in (*forms.q, *forms.qd, forms.t)})
    try:
        rows = [[float(m.xreplace(point)) if m != 0 else 0.0 for m in row] for row in forms.mass]
    except (RuntimeError, TypeError, ValueError, OverflowError, ZeroDivisionError):
        check_invertible(model)
        return
    if not all(math.isfinite(x) for row in rows for x in row) or row_pivot_ratio(rows) < 1e-12:
        check_invertible(model)


def pivot_ratio(matrix: sp.Matrix, model: Model, seed: int = 1) -> float:
    """Smallest over largest pivot of A (rows scaled to unit norm) at a random point: about
    1/condition number, and at rounding level when A is singular.

    Evaluated in floating point with a pure-Python LU (no numpy in the derive path). Where the
    matrix is not real or not finite at the point, up to three other points are tried; if none
    serves, there is no verdict (1.0): the numeric run reports where it fails."""
    import random

    rng = random.Random(seed)
    point = {to_symengine(s): se.RealDouble(p.value if p.value else rng.uniform(0.5, 2.0)) for p in model.parameters for s in (p.symbol,)}
    point.update({to_symengine(s): se.RealDouble(rng.uniform(0.2, 1.3)) for s in (*model.q, *model.qd, model.t)})
    # a function left general (U(r), its derivatives) is generic too: a random value of its own
    # (xreplace matches Derivative(U(x), x) before the U(x) inside it)
    unknowns = sorted(matrix.atoms(sp.Derivative, sp.Subs), key=sp.default_sort_key) + sorted(matrix.atoms(AppliedUndef), key=sp.default_sort_key)
    generic = {u: sp.Float(rng.uniform(0.5, 2.0)) for u in unknowns}
    if generic:
        matrix = matrix.xreplace(generic)
    try:
        rows = [[float(to_symengine(matrix[i, j]).subs(point)) if matrix[i, j] != 0 else 0.0 for j in range(matrix.cols)] for i in range(matrix.rows)]
    except (RuntimeError, TypeError, ValueError, OverflowError, ZeroDivisionError):
        # not real or not defined at this point (sqrt of a negative): another point, or no verdict
        return pivot_ratio(matrix, model, seed + 1) if seed < 3 else 1.0
    if not all(math.isfinite(x) for row in rows for x in row):
        return pivot_ratio(matrix, model, seed + 1) if seed < 3 else 1.0
    return row_pivot_ratio(rows)


def row_pivot_ratio(rows: list[list[float]]) -> float:
    """Smallest over largest pivot of Gaussian elimination with partial pivoting on the
    row-normalised matrix `rows` (changed in place): 0 for a zero row or pivot."""
    pivots = []
    for row in rows:
        norm = sum(x * x for x in row) ** 0.5
        if norm == 0.0:
            return 0.0
        row[:] = [x / norm for x in row]
    n = len(rows)
    for k in range(n):
        pivot = max(range(k, n), key=lambda i: abs(rows[i][k]))
        if rows[pivot][k] == 0.0:
            return 0.0
        rows[k], rows[pivot] = rows[pivot], rows[k]
        pivots.append(abs(rows[k][k]))
        for i in range(k + 1, n):
            factor = rows[i][k] / rows[k][k]
            if factor:
                for j in range(k, n):
                    rows[i][j] -= factor * rows[k][j]
    return min(pivots) / max(pivots)


def _sp(value: se.Basic) -> sp.Expr:
    return sp.sympify(value)
