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


def to_symengine(expr: object) -> symengine.Basic:
    """Convert a sympy expression by walking its tree.

    `symengine.sympify` of a sympy object consults numpy, which is hidden above; the
    expressions converted here (positions, energies, forces) use only what the safe parser
    can produce, so a small walk covers them, and anything else is an error.
    """
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
        return se.Add(*(to_symengine(a) for a in expr.args))
    if isinstance(expr, sp.Mul):
        return se.Mul(*(to_symengine(a) for a in expr.args))
    if isinstance(expr, sp.Pow):
        base, exponent = expr.args
        return se.Pow(to_symengine(base), to_symengine(exponent))
    if isinstance(expr, sp.Derivative):
        result = to_symengine(expr.expr)
        for variable, count in expr.variable_count:
            for _ in range(int(count)):
                result = se.diff(result, to_symengine(variable))
        return result
    if isinstance(expr, sp.core.function.AppliedUndef):
        return se.Function(str(expr.func))(*(to_symengine(a) for a in expr.args))
    if isinstance(expr, sp.Function) and hasattr(se, type(expr).__name__):
        return getattr(se, type(expr).__name__)(*(to_symengine(a) for a in expr.args))
    raise TypeError(f"cannot convert {type(expr).__name__} to symengine: {expr}")
