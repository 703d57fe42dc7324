"""Noether's theorem: conserved charges from continuous symmetries.

A symmetry changes each coordinate by eps * eta_i(q, t) and time by eps * tau(q, t). It is a
symmetry of the Lagrangian when the first-order change of the action density,

    delta L = sum_i dL/dq_i eta_i + dL/dq_dot_i (D eta_i - q_dot_i D tau) + dL/dt tau + L D tau

(D the total time derivative), is the total derivative D G of a function G(q, t). Then

    C = sum_i p_i eta_i - h tau - G        (p_i = dL/dq_dot_i, h = sum p q_dot - L)

is conserved, provided nothing else does work along the symmetry: the non-conservative
generalized forces Q_i (applied forces and -dR/dq_dot_i of the dissipation) satisfy
sum_i Q_i (eta_i - q_dot_i tau) = 0, and the symmetry preserves every kept constraint
a . q_dot + b = 0 (a . eta + b tau = 0, so that the constraint forces do no work along it).
G is found when it is a polynomial in the coordinates and t (by integrating the polynomial
coefficients of delta L, then checking D G = delta L exactly).

`declared` checks the file's `symmetries` (a `SpecError` at the symmetry's name when one is not
a symmetry, with the change of L that is left); `search` tries a small built-in family:
translations and rotations of Cartesian particles, and the time shift.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import sympy as sp
from sympy.core.function import AppliedUndef

from lagrange_cli.algebra import expandable
from lagrange_cli.errors import fail, printable
from lagrange_cli.model import Model

if TYPE_CHECKING:
    from lagrange_cli.spec import SystemSpec

SIMPLIFY_OPS = 150
"""Expressions up to this many operations are simplified when expanding does not show them zero."""


@dataclass(frozen=True)
class Charge:
    """A symmetry that holds and its conserved Noether charge."""

    name: str
    changes: tuple[tuple[str, sp.Expr], ...]
    """(coordinate, eta) for each coordinate the symmetry moves."""
    time: sp.Expr
    gauge: sp.Expr
    """G: delta L = dG/dt."""
    charge: sp.Expr
    builtin: bool = False


class NotASymmetry(Exception):
    """Why a candidate is not a symmetry; `left` is the first-order change of L that is left (or
    the work done, for forces and constraints)."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


def _ddt(expr: sp.Expr, model: Model) -> sp.Expr:
    """The total time derivative of an expression of q, q_dot (without accelerations) and t."""
    result = sp.diff(expr, model.t)
    for q, qd, qdd in zip(model.q, model.qd, model.qdd, strict=True):
        result += sp.diff(expr, q) * qd + sp.diff(expr, qd) * qdd
    return result


def _is_zero(expr: sp.Expr) -> bool:
    """True when `expr` vanishes identically: expanding shows it, or simplifying (small
    expressions), or else its values at ZERO_POINTS random states (DIGITS digits, undefined
    functions replaced by a smooth function) are all zero to round-off of its terms' sizes."""
    if not expandable(expr):  # expanding would blow up (large powers of sums): decide by values
        return _numerically_zero(expr)
    expanded = sp.expand(expr)
    if expanded == 0:
        return True
    if sp.count_ops(expanded) <= SIMPLIFY_OPS and sp.simplify(expanded) == 0:
        return True
    return _numerically_zero(expanded)


ZERO_POINTS = 4
DIGITS = 30


def _numerically_zero(expr: sp.Expr) -> bool:
    """`expr` (expanded) is zero at ZERO_POINTS seeded random states, relative to the sum of its
    terms' magnitudes; states where it is not a finite real number are skipped (too few good
    states: not zero)."""
    import random

    rng = random.Random(20261123)
    concrete = expr.replace(lambda e: isinstance(e, AppliedUndef), lambda e: sp.exp(-sum(e.args, sp.Integer(0)) / 3) + sp.sin(sum(e.args, sp.Integer(0))) / 2)
    if concrete.has(sp.Derivative, sp.Subs):
        concrete = concrete.doit()
    symbols = sorted(concrete.free_symbols, key=str)
    terms = sp.Add.make_args(concrete)
    good = 0
    for _ in range(3 * ZERO_POINTS):
        values = {s: sp.Float(rng.uniform(0.3, 1.4), DIGITS) for s in symbols}
        try:
            numbers = [sp.N(term.xreplace(values), DIGITS) for term in terms]
            total = sp.N(sp.Add(*numbers), DIGITS)
        except (ArithmeticError, ValueError, TypeError):
            continue
        if not all(n.is_real and n.is_finite for n in [*numbers, total]):
            continue
        scale = sum((abs(n) for n in numbers), sp.Float(0))
        if abs(total) > sp.Float(10) ** (10 - DIGITS) * max(scale, 1):
            return False
        good += 1
        if good == ZERO_POINTS:
            return True
    return False


SHOWN = 600
"""Characters of an expression a message shows at most."""


def _shown(expr: sp.Expr) -> str:
    """`expr` tidied, as text cut at SHOWN characters (saying how long it is) for a message."""
    text = str(_tidy(expr))
    return text if len(text) <= SHOWN else f"{text[:SHOWN]} ... ({len(text)} characters in all)"


def _tidy(expr: sp.Expr) -> sp.Expr:
    """`expr` expanded with common factors pulled out where it is small (cheap: no `simplify`); a
    large one as it is (expanding it could blow it up)."""
    if sp.count_ops(expr) > SIMPLIFY_OPS or not expandable(expr):
        return expr
    return sp.factor_terms(sp.expand(expr))


def variation(model: Model, eta: Sequence[sp.Expr], tau: sp.Expr) -> sp.Expr:
    """delta L: the first-order change of L dt under q -> q + eps eta, t -> t + eps tau."""
    lagrangian, t = model.lagrangian, model.t
    dtau = _ddt(tau, model)
    change = (sp.diff(lagrangian, t) * tau if tau != 0 else sp.Integer(0)) + lagrangian * dtau
    for q, qd, e in zip(model.q, model.qd, eta, strict=True):
        if e != 0:
            change += sp.diff(lagrangian, q) * e
        if e != 0 or dtau != 0:
            change += sp.diff(lagrangian, qd) * (_ddt(e, model) - qd * dtau)
    return change


def gauge(model: Model, change: sp.Expr) -> sp.Expr | None:
    """G(q, t), a polynomial in the coordinates and t with dG/dt = `change`, or None when there is none."""
    if not expandable(change):  # too large to expand into polynomial coefficients: only G = 0 is tried
        return sp.Integer(0) if _numerically_zero(change) else None
    change = sp.expand(change)
    if change == 0:
        return sp.Integer(0)
    slopes = [sp.diff(change, qd) for qd in model.qd]
    rest = sp.expand(change - sum((a * qd for a, qd in zip(slopes, model.qd, strict=True)), sp.Integer(0)))
    variables = (*model.q, model.t)
    parts = [*slopes, rest]
    if any(p.has(*model.qd) or not p.is_polynomial(*variables) for p in parts):
        return None
    found = sp.Integer(0)
    for variable, part in zip(variables, parts, strict=True):
        remainder = sp.expand(part - sp.diff(found, variable))
        if remainder != 0:
            found += sp.Poly(remainder, variable).integrate().as_expr()
    return found if _is_zero(change - _ddt(found, model)) else None


def analyse(model: Model, name: str, changes: Mapping[str, sp.Expr], time: sp.Expr, builtin: bool = False) -> Charge:
    """The charge of one candidate symmetry; `NotASymmetry` says why it is not one."""
    eta = [sp.sympify(changes.get(c, 0)) for c in model.coordinates]
    tau = sp.sympify(time)
    change = variation(model, eta, tau)
    found = gauge(model, change)
    if found is None:
        raise NotASymmetry(f"the Lagrangian is not invariant: its first-order change delta L = {_shown(change)} is neither zero nor the time derivative of a polynomial G(q, t)")
    forces = [q - sp.diff(model.dissipation, qd) for q, qd in zip(model.generalized_forces, model.qd, strict=True)]
    work = sum((f * (e - qd * tau) for f, e, qd in zip(forces, eta, model.qd, strict=True)), sp.Integer(0))
    if not _is_zero(work):
        raise NotASymmetry(f"the non-conservative forces (applied forces and dissipation) do work along it: sum Q_i (delta q_i - q_dot_i delta t) = {_shown(work)}")
    for constraint in model.constraints:
        moved = sum((a * e for a, e in zip(constraint.jacobian, eta, strict=True)), sp.Integer(0)) + constraint.bias * tau
        if not _is_zero(moved):
            raise NotASymmetry(f"it does not preserve the constraint '{constraint.name}': a . delta q + b delta t = {_shown(moved)}")
    charge = sum((p * e for p, e in zip(model.momenta, eta, strict=True)), sp.Integer(0)) - model.energy * tau - found
    kept = tuple((c, e) for c, e in zip(model.coordinates, eta, strict=True) if e != 0)
    return Charge(name, kept, tau, found, _tidy(charge), builtin)


def declared(spec: SystemSpec, model: Model) -> tuple[Charge, ...]:
    """The charges of the file's declared symmetries (`spec.symmetries`); a symmetry that is not one
    is a `SpecError` at its name, saying what is left of the change of L (or which force or
    constraint spoils it)."""
    symmetries = spec.symmetries
    eliminated = dict(model.eliminated)
    found = []
    for symmetry in symmetries:
        changes: dict[str, sp.Expr] = {}
        for coordinate, delta, span in symmetry.coordinates:
            if coordinate in eliminated:
                raise fail(span, f"symmetry '{symmetry.name}' moves '{coordinate}', which is eliminated", "a symmetry declared in the remaining coordinates " + ", ".join(model.coordinates))
            changes[coordinate] = _in_model(delta, model)
        time = _in_model(symmetry.time, model) if symmetry.time is not None else sp.Integer(0)
        try:
            found.append(analyse(model, symmetry.name, changes, time))
        except NotASymmetry as bad:
            raise fail(
                symmetry.span,
                f"'{symmetry.name}' is not a symmetry: {bad.message}",
                "a change of the coordinates (and time) that leaves L unchanged up to dG/dt, with G a polynomial in the coordinates and t",
            ) from None
    return tuple(found)


def _in_model(expr: sp.Expr, model: Model) -> sp.Expr:
    """`expr` with the eliminated coordinates written in the remaining ones."""
    eliminated = {sp.Symbol(name): value for name, value in model.eliminated}
    return expr.xreplace(eliminated) if eliminated else expr


def cartesian(spec: SystemSpec, model: Model) -> tuple[list[tuple[str | None, ...]], bool] | None:
    """The positions of the particles (and bodies' centres) as coordinate names, one per component
    (None for a constant component, e.g. the 0 of `[x, y, 0]`), and whether rigid bodies are among
    them; None unless every component is a coordinate of the model or a constant, no coordinate
    serves twice and all positions have one length. (Coordinates that no position uses, such as
    an angle in `kinetic`, stay unchanged by the family; the check decides.)"""
    points = [p.position for p in spec.particles] + [b.position for b in spec.bodies]
    if not points:
        return None
    names: list[tuple[str | None, ...]] = []
    used: list[str] = []
    for position in points:
        row: list[str | None] = []
        for component in position:
            if isinstance(component, sp.Symbol) and str(component) in model.coordinates:
                row.append(str(component))
                used.append(str(component))
            elif component.free_symbols <= {p.symbol for p in model.parameters}:
                row.append(None)
            else:
                return None
        names.append(tuple(row))
    if len({len(p) for p in names}) != 1 or len(set(used)) != len(used) or not used:
        return None
    return names, bool(spec.bodies)


def candidates(spec: SystemSpec, model: Model) -> list[tuple[str, dict[str, sp.Expr], sp.Expr]]:
    """The built-in family: translations along the axes (when every particle and body has a
    coordinate along that axis) and rotations about them (when every particle has coordinates in
    the plane of the rotation, and there are no bodies, whose orientation would turn too), of
    Cartesian particles only; and the time shift."""
    found: list[tuple[str, dict[str, sp.Expr], sp.Expr]] = []
    layout = cartesian(spec, model)
    if layout is not None:
        positions, bodies = layout
        dimension = len(positions[0])
        for k, axis in enumerate("xyz"[:dimension]):
            moved = [p[k] for p in positions]
            if all(moved):
                found.append((f"translation_{axis}", {q: sp.Integer(1) for q in moved if q}, sp.Integer(0)))
        planes = {"z": (0, 1)} if dimension == 2 else {"x": (1, 2), "y": (2, 0), "z": (0, 1)} if dimension == 3 else {}
        for axis, (i, j) in planes.items():
            if bodies or not all(p[i] and p[j] for p in positions):
                continue
            changes: dict[str, sp.Expr] = {}
            for p in positions:
                first, second = p[i], p[j]
                if first and second:
                    changes[first] = -sp.Symbol(second)
                    changes[second] = sp.Symbol(first)
            found.append((f"rotation_{axis}", changes, sp.Integer(0)))
    found.append(("time_translation", {}, sp.Integer(1)))
    return found


def search(spec: SystemSpec, model: Model) -> tuple[Charge, ...]:
    """The symmetries of the built-in family that hold, with their charges."""
    found = []
    for name, changes, time in candidates(spec, model):
        try:
            found.append(analyse(model, name, changes, time, builtin=True))
        except NotASymmetry:
            continue
    return tuple(found)


def describe(charge: Charge) -> str:
    moves = ", ".join(f"delta {c} = {e}" for c, e in charge.changes)
    if charge.time != 0:
        moves = ", ".join(filter(None, [moves, f"delta t = {charge.time}"]))
    gauge_text = f" (L changes by dG/dt, G = {charge.gauge})" if charge.gauge != 0 else ""
    return f"{charge.name}: {moves}{gauge_text}; conserved charge {charge.charge}"


def text(declared_charges: Sequence[Charge], found: Sequence[Charge]) -> str:
    """The lines `info` appends: the declared symmetries' charges and what the search found."""
    lines = []
    if declared_charges:
        lines.append("declared symmetries (Noether charges sum p delta q - h delta t - G):")
        lines += [f"  {describe(c)}" for c in declared_charges]
    lines.append("symmetries found (translations and rotations of Cartesian particles, time shift):" + ("" if found else " none"))
    lines += [f"  {describe(c)}" for c in found]
    return "\n".join(map(printable, lines)) + "\n"


def to_json(declared_charges: Sequence[Charge], found: Sequence[Charge]) -> dict[str, object]:
    def one(c: Charge) -> dict[str, object]:
        return {"name": c.name, "coordinates": {q: str(e) for q, e in c.changes}, "time": str(c.time), "gauge": str(c.gauge), "charge": str(c.charge)}

    return {"symmetries": [one(c) for c in declared_charges], "symmetries_found": [one(c) for c in found]}


def latex(model: Model, declared_charges: Sequence[Charge], found: Sequence[Charge]) -> str:
    """The charges as an `align*` (C_1, C_2, ... with a comment naming each symmetry), laid out
    like `info --latex`."""
    from lagrange_cli.emit import layout
    from lagrange_cli.emit.latex import Row, align, comment, room
    from lagrange_cli.emit.latex import names as latex_names

    charges = [*declared_charges, *found]
    if not charges:
        return comment("symmetries found (translations and rotations of Cartesian particles, time shift): none")
    doprint = latex_names(model).printer().doprint
    labels = [f"C_{{{k + 1}}}" for k in range(len(charges))]
    space = room(labels)
    named = "; ".join(f"C{k + 1}: {'found' if c.builtin else 'declared'} {c.name}" for k, c in enumerate(charges))
    rows = [Row(label, layout.pieces(c.charge, doprint, space)) for label, c in zip(labels, charges, strict=True)]
    return comment(f"Noether charges: {named}") + align(rows)


def with_charges(spec: SystemSpec, model: Model, rendered: str, form: str = "text") -> str:
    """`info`'s output (`form` "text", "json" or "latex") with the declared symmetries' charges and
    what the built-in search found added (the CLI and `System.info` both use this)."""
    import json

    declared_charges, found = declared(spec, model), search(spec, model)
    if form == "json":
        return json.dumps({**json.loads(rendered), **to_json(declared_charges, found)}, indent=2) + "\n"
    return rendered + (latex(model, declared_charges, found) if form == "latex" else text(declared_charges, found))
