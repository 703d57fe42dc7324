"""Switching surfaces: where a system's right-hand side is not smooth (issue 15, audit 6 F5).

A one-sided wall written with Abs, a dry-friction sign(v), a Piecewise force or a Max/Min make the
equations of motion smooth only piecewise: across the surface g(t, y) = 0 where the argument of
Abs or sign changes sign (or a Piecewise condition, lhs - rhs, or a Max/Min's a - b) the force
or its derivative jumps. An integrator that steps over such a kink sees an error far larger than
its estimate of order h^(p+1) assumes (a multistep method carries it in its history for many
steps after). The remedy is the classical one (Hairer, Norsett and Wanner I, section II.6): locate
each crossing on the dense output, land a step on it and restart there with a fresh step size.

`surfaces(model)` collects the distinct g's from the expressions the generated `_accel` evaluates
(the mass matrix, the forces, the constraint biases: the model's expressions after derivation,
inputs at their defaults and defined functions written out, in symengine form), each once up to
its sign; codegen.py writes them as `_switch(t, _y, _p, _out)` (numba) or `_switch(t, _y, _p)`
(Python) with `_SWITCHES = m`, only for a system that has some: a system without them gets
exactly the code, and the integrators exactly the steps, it had before.
"""

from __future__ import annotations

from typing import Any

from lagrange_cli._symengine import se

LOCATE = True
"""Whether the integrators locate the crossings (False only to measure what locating them changes:
benchmarks/nonsmooth.py; the integrators then step over the kinks as they did before issue 15)."""
KINDS = ("Abs", "sign", "Heaviside", "Piecewise", "Max", "Min")
"""The functions whose arguments switch (symengine class names, also sympy's)."""
_RELATIONS = ("StrictLessThan", "LessThan", "StrictGreaterThan", "GreaterThan", "Equality", "Unequality")


def _relations(condition: Any, out: list[Any]) -> None:
    """lhs - rhs of each relation inside a Piecewise condition (And, Or, Not of relations)."""
    if type(condition).__name__ in _RELATIONS:
        lhs, rhs = condition.args
        out.append(lhs - rhs)
        return
    for arg in getattr(condition, "args", ()):
        _relations(arg, out)


def _collect(expr: Any, seen: set[Any], out: list[Any]) -> None:
    if expr in seen:
        return
    seen.add(expr)
    kind = type(expr).__name__
    args = list(expr.args)
    if kind in ("Abs", "sign", "Heaviside"):
        out.append(args[0])
    elif kind == "Piecewise":
        for condition in args[1::2]:
            _relations(condition, out)
        args = args[0::2]
    elif kind in ("Max", "Min"):
        out += [a - b for i, a in enumerate(args) for b in args[i + 1 :]]
    for arg in args:
        _collect(arg, seen, out)


def collect(exprs: list[Any], constants: frozenset[str] = frozenset()) -> list[Any]:
    """The distinct switching functions in `exprs` (symengine), in order of appearance, each once up to
    sign; a function of the parameters (`constants`) alone never switches and is left out."""
    found: list[Any] = []
    seen: set[Any] = set()
    for expr in exprs:
        _collect(expr, seen, found)
    result: list[Any] = []
    keys: set[Any] = set()
    for g in found:
        key = se.expand(g)
        names = {str(s) for s in key.free_symbols}
        if not names or names <= constants or key in keys or se.expand(-key) in keys:  # -key itself is Mul(-1, Add), never equal to an expanded key
            continue
        keys.add(key)
        result.append(g)
    return result


def located(module: Any) -> int:
    """The switching functions a generated module's integrators land on: its `_SWITCHES` (0 without any, or with
    LOCATE off)."""
    return int(getattr(module, "_SWITCHES", 0)) if LOCATE else 0


def note(surfaces: int, crossings: int) -> str:
    """What `simulate` says of a run that located its switching surfaces' crossings."""
    return (
        f"{surfaces} switching surface{'s' if surfaces != 1 else ''} (Abs, sign, Piecewise, Max, Min) located: {crossings} crossing{'s' if crossings != 1 else ''},"
        " each landed on by a step and the integrator restarted there"
    )


def notes(located: tuple[int, int] | None, surfaces: int, locate: bool) -> tuple[str, ...]:
    """`simulate`'s note on a system with switching surfaces: the crossings located, or that this run
    (the symplectic method's fixed step, a projected run, a run with LOCATE off) stepped over them."""
    if located is not None:
        return (note(*located),)
    if not surfaces or not locate:
        return ()
    return (
        f"{surfaces} switching surface{'s' if surfaces != 1 else ''} (Abs, sign, Piecewise, Max, Min): this method steps over their crossings without locating them (RK45, DOP853, Radau, BDF and LSODA land a step on each)",
    )
