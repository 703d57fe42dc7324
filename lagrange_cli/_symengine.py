"""symengine, imported without dragging numpy in.

symengine imports numpy eagerly when it is installed, only for its `lambdify`, which this
package never uses. Hiding numpy for the duration of the import keeps `lagrange derive`
free of numpy (about 0.15 s of start-up); commands that need numpy import it themselves.
"""

from __future__ import annotations

import sys

if "numpy" in sys.modules or "symengine" in sys.modules:
    import symengine
else:
    sys.modules["numpy"] = None  # type: ignore[assignment]
    try:
        import symengine
    finally:
        del sys.modules["numpy"]
    # symengine believes numpy is there and would look it up when converting foreign objects.
    import symengine.lib.symengine_wrapper as _wrapper

    _wrapper.have_numpy = False

se = symengine


def to_symengine(expr: object, cache: dict[int, tuple[object, symengine.Basic]] | None = None) -> symengine.Basic:
    """Convert a sympy expression by walking its tree.

    `symengine.sympify` of a sympy object consults numpy, which is hidden above; the
    expressions converted here (positions, energies, forces) use only what the safe parser
    can produce, so a small walk covers them, and anything else is an error. With `cache`
    (by the identity of the sympy object, which it keeps alive), a sub-expression shared by
    several parents is converted once (a spatial chain's rotations share their factors).
    """
    if cache is not None:
        hit = cache.get(id(expr))
        if hit is not None and hit[0] is expr:
            return hit[1]
        value = _to_symengine(expr, cache)
        cache[id(expr)] = (expr, value)
        return value
    return _to_symengine(expr, None)


def _to_symengine(expr: object, cache: dict[int, tuple[object, symengine.Basic]] | None) -> symengine.Basic:
    import sympy as sp

    if isinstance(expr, int):
        return se.Integer(expr)
    if isinstance(expr, float):
        return se.RealDouble(expr)
    if isinstance(expr, sp.Symbol):
        return se.Symbol(expr.name)
    if isinstance(expr, sp.Integer):
        return se.Integer(int(expr))
    if isinstance(expr, sp.Rational):
        return se.Rational(int(expr.p), int(expr.q))
    if isinstance(expr, sp.Float):
        return se.RealDouble(float(expr))
    if expr is sp.pi:
        return se.pi
    if expr is sp.E:
        return se.E
    if isinstance(expr, sp.Add):
        return se.Add(*(to_symengine(a, cache) for a in expr.args))
    if isinstance(expr, sp.Mul):
        return se.Mul(*(to_symengine(a, cache) for a in expr.args))
    if isinstance(expr, sp.Pow):
        base, exponent = expr.args
        return se.Pow(to_symengine(base, cache), to_symengine(exponent, cache))
    if isinstance(expr, sp.Derivative):
        result = to_symengine(expr.expr, cache)
        for variable, count in expr.variable_count:
            for _ in range(int(count)):
                result = se.diff(result, to_symengine(variable, cache))
        return result
    if isinstance(expr, sp.core.function.AppliedUndef):
        return se.Function(str(expr.func))(*(to_symengine(a, cache) for a in expr.args))
    if isinstance(expr, sp.Function) and hasattr(se, type(expr).__name__):
        return getattr(se, type(expr).__name__)(*(to_symengine(a, cache) for a in expr.args))
    raise TypeError(f"cannot convert {type(expr).__name__} to symengine: {expr}")


def to_sympy(expr: symengine.Basic, cache: dict[symengine.Basic, object] | None = None) -> object:
    """`sympy.sympify(expr)`, with each distinct sub-expression converted once (`cache`, which may be
    shared by the expressions of one model): the equations of a big system repeat their mass matrix
    entries in the kinetic energy, the momenta and the energy, and sympify converts every repetition.
    Sums, products, powers and the named functions are rebuilt with sympy's own constructors, as
    sympify does; anything else is converted by sympify itself."""
    import sympy as sp

    memo: dict[symengine.Basic, object] = {} if cache is None else cache

    def convert(node: symengine.Basic) -> object:
        found = memo.get(node)
        if found is not None:
            return found
        kind = type(node).__name__
        if kind == "Add":
            value = sp.Add(*(convert(a) for a in node.args))
        elif kind == "Mul":
            value = sp.Mul(*(convert(a) for a in node.args))
        elif kind == "Pow":
            base, exponent = node.args
            value = sp.Pow(convert(base), convert(exponent))
        elif node.is_Function and kind != "FunctionSymbol" and isinstance(getattr(sp, kind, None), type) and issubclass(getattr(sp, kind), sp.Function):
            value = getattr(sp, kind)(*(convert(a) for a in node.args))
        else:
            value = sp.sympify(node)
        memo[node] = value
        return value

    return convert(expr)
