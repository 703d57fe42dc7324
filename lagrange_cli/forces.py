"""Constraint forces by name: the physical force (and torque) each kept constraint exerts.

Sign convention. A constraint written `lhs = rhs` has g = lhs - rhs (for a velocity constraint,
the coefficients of the velocities play the role of dg/dq), and the equations are
`M q_ddot = F + A^T lambda`: the generalized constraint force of constraint k is lambda_k a_k,
a_k = dg_k/dq. On the particles and bodies it is the force (and, on a body, the torque about its
centre) W_k lambda_k that does the same virtual work: with J the Jacobian of the carriers'
velocities (each particle's and body centre's position components, each body's angular velocity
components, rows that are identically zero dropped),

    J^T W_k = a_k^T.

When J is square and invertible (the coordinates describe the carriers freely, e.g. a
Cartesian pendulum, a knife edge in (x, y, phi)), W_k = J^-T a_k^T is exact: the force on a
particle is lambda_k times the gradient of g_k with respect to that particle's position.
With fewer independent rows than coordinates the solution is unique when it exists. Otherwise
(more rows than coordinates: the coordinates already constrain the carriers, e.g. an upright
coin, a pendulum in angles) W_k is the minimum-norm solution J (J^T J)^-1 a_k^T: the part of the
constraint force that acts along the motions the coordinates allow (the rest is balanced by the
constraints built into the coordinates); `Forces.status` says which.

The signed size of the force on carrier c is N = lambda_k |W_kc| (its force rows only, not the
torque): positive when the force points along the gradient of g_k, i.e. when lambda_k > 0. For the
pendulum x^2 + y^2 = l^2, the gradient points outward, so a taut string has N < 0 and its
tension is -N = -2 l lambda.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import sympy as sp

from lagrange_cli.model import Carrier, Model

MAX_SYMBOLIC = 4
"""Most coordinates for which the force directions are solved symbolically (text and LaTeX);
beyond that only generated code gives them (numerically)."""

CONVENTION = "force on each particle/body = lambda * W, where W gives the same generalized force as lambda * d(lhs - rhs)/dq; N = lambda * |W| is positive along the gradient of lhs - rhs (lambda > 0)"
"""The sign convention, stated in every output that shows constraint forces."""


DESCRIPTIONS = {
    "exact": "exact: the only forces on the particles and bodies with this generalized force",
    "projected": "the part along the motions the coordinates allow (minimum norm): the coordinates constrain the particles or bodies too",
    "partial": "the part on the particles and bodies only: the constraint also acts along a coordinate that none of them carries",
}


@dataclass(frozen=True)
class Row:
    """One row of J: carrier `carrier`, `kind` "force" or "torque", component `index`, and the
    row's entries d(component)/dq (position rows) or d(omega)/dq_dot (angular rows)."""

    carrier: str
    kind: str
    index: int
    entries: tuple[sp.Expr, ...]


@dataclass(frozen=True)
class Forces:
    """The rows of J and, when computed symbolically, W_k (one column per constraint): the
    force of constraint k on the carriers is lambda_k * directions[k]."""

    model: Model
    rows: tuple[Row, ...]
    status: str
    """"exact" (J^T W = a has the one solution W), "projected" (more rows than coordinates: the
    minimum-norm W) or "partial" (the constraint acts on a coordinate that no carrier's rows hold,
    e.g. an angle whose energy is written under `kinetic`: W is the least-squares part on the carriers)."""
    directions: tuple[tuple[sp.Expr, ...], ...] | None
    """Per constraint, one entry per row of `rows`; None when not solved symbolically."""

    def on(self, k: int, keep_zero: bool = False) -> dict[tuple[str, str], list[object]]:
        """(carrier, kind) -> every component of W_k for that carrier (0 for rows dropped from J),
        carriers with W = 0 left out unless `keep_zero`."""
        assert self.directions is not None
        return spread(self.model, self.rows, self.directions[k], keep_zero)

    def describe(self) -> str:
        return DESCRIPTIONS[self.status]


def spread(model: Model, found: tuple[Row, ...], values: tuple[object, ...], keep_zero: bool = False) -> dict[tuple[str, str], list[object]]:
    """Values given per row of J -> (carrier, kind) -> full component lists (zeros where J's row
    was dropped), in the order of the carriers, forces before torques; all-zero entries left out
    unless `keep_zero` (then every carrier and kind with a row of J is there)."""
    given = {(row.carrier, row.kind, row.index): v for row, v in zip(found, values, strict=True)}
    out: dict[tuple[str, str], list[object]] = {}
    for carrier in model.carriers:
        for kind, size in (("force", len(carrier.position)), ("torque", len(carrier.angular_velocity))):
            components = [given.get((carrier.name, kind, i), sp.Integer(0)) for i in range(size)]
            if any((carrier.name, kind, i) in given and (keep_zero or components[i] != 0) for i in range(size)):
                out[(carrier.name, kind)] = components
    return out


def rows(model: Model) -> tuple[Row, ...]:
    """The rows of J that are not identically zero."""
    out = []
    for carrier in model.carriers:
        out += _rows(model, carrier)
    return tuple(out)


def _rows(model: Model, carrier: Carrier) -> list[Row]:
    found = []
    for i, r in enumerate(carrier.position):
        entries = tuple(sp.diff(r, q) for q in model.q)
        if any(e != 0 for e in entries):
            found.append(Row(carrier.name, "force", i, entries))
    for i, w in enumerate(carrier.angular_velocity):
        entries = tuple(sp.diff(w, qd) for qd in model.qd)
        if any(e != 0 for e in entries):
            found.append(Row(carrier.name, "torque", i, entries))
    return found


def forces(model: Model, symbolic: bool = True) -> Forces:
    """The constraint-force map of `model` (which must keep constraints); `symbolic` solves W
    as expressions for at most `MAX_SYMBOLIC` coordinates: W = (J J^T)^-1 J a^T when J has at
    most as many rows as coordinates (the unique solution when one exists), else the minimum-norm
    J (J^T J)^-1 a^T. The status is decided numerically at a sample point (`_status`)."""
    found = rows(model)
    n = model.n
    J = sp.Matrix(len(found), n, [e for row in found for e in row.entries]) if found else sp.zeros(0, n)
    A = sp.Matrix(model.constraint_matrix)
    status = _status(model, J, A)
    directions = None
    if symbolic and n <= MAX_SYMBOLIC and found:
        try:
            W = J.T.LUsolve(A.T) if J.rows == n else ((J * J.T).LUsolve(J * A.T) if J.rows < n else J * (J.T * J).LUsolve(A.T))
        except (ValueError, ZeroDivisionError):  # singular: no symbolic directions
            W = None
        if W is not None:
            directions = tuple(tuple(_tidy(W[i, k]) for i in range(J.rows)) for k in range(A.rows))
    return Forces(model, found, status, directions)


def _status(model: Model, J: sp.Matrix, A: sp.Matrix) -> str:
    """ "projected" with more rows than coordinates; else "exact" when J^T W = A^T has a solution
    at a sample point (default parameters, coordinates 0.3, 0.4, ...; numbers only, no symbolic
    solve), "partial" when it has none (or J's rows are dependent there)."""
    if J.rows > model.n:
        return "projected"
    if J.rows == 0:
        return "partial"
    point: dict[sp.Symbol, sp.Float] = {model.t: sp.Float(0.1)}
    point.update({p.symbol: sp.Float(p.value if p.value is not None else 1.3) for p in model.parameters})
    point.update({q: sp.Float(0.3 + 0.1 * i) for i, q in enumerate(model.q)})
    point.update({v: sp.Float(0.2 - 0.1 * i) for i, v in enumerate(model.qd)})
    try:
        Jn = J.xreplace(point).evalf()
        An = A.xreplace(point).evalf()
        W = (Jn * Jn.T).LUsolve(Jn * An.T)
        residual = Jn.T * W - An.T
        scale = max([1.0, *(abs(complex(x)) for x in An)])
        return "exact" if all(abs(complex(x)) < 1e-9 * scale for x in residual) else "partial"
    except (TypeError, ValueError, ZeroDivisionError):
        return "partial"


SIZE_MAX_CHARACTERS = 60
"""Longest |W| printed as N in text and LaTeX (a longer one is left to the generated code)."""


def _size(ws: list[object]) -> sp.Expr | None:
    """|W| for the printed N, when it is short and plain (no negative power, which reads badly and
    may not fit a line); None otherwise (N is then given by the generated `constraint_forces`)."""
    size = _tidy(sp.sqrt(sum((sp.sympify(w) ** 2 for w in ws), sp.Integer(0))))
    text = sp.sstr(size)
    if len(text) > SIZE_MAX_CHARACTERS or "**(-" in text or "/(-" in text:
        return None
    return size


def _tidy(expr: sp.Expr) -> sp.Expr:
    if sp.count_ops(expr) <= 150:
        return sp.trigsimp(sp.cancel(expr))
    return expr


def lines(model: Model, printer: Callable[[sp.Expr], str]) -> list[str]:
    """Plain-text lines: for each kept constraint and carrier, the force (and torque) as
    lambda * W and the signed size N, with the convention first. `printer` prints an expression."""
    out = [f"constraint forces ({CONVENTION}):"]
    fm = forces(model)
    if not fm.rows:
        return [*out, "  (no particles or bodies to act on: the generalized forces are A^T lambda)"]
    if fm.directions is None:
        return [*out, f"  (computed numerically by the generated Python's constraint_forces(t, y, p): {model.n} coordinates)"]
    for k, c in enumerate(model.constraints):
        lam = c.multiplier
        for (carrier, kind), ws in fm.on(k).items():
            vector = "[" + ", ".join(printer(sp.factor_terms(lam * sp.sympify(w))) for w in ws) + "]"
            line = f"  {c.name} on {carrier}: {kind} = {vector}"
            size = _size(ws) if kind == "force" else None
            if size is not None:
                line += f", N = {printer(lam * size)}"
            out.append(line)
    out.append(f"  ({fm.describe()})")
    return out


def python_function(model: Model, printer: Any, unpack: Callable[[list[Any], str], list[str]]) -> str:
    """The generated module's `constraint_forces(t, y, p)` (`u=INPUTS` after `p` when the multipliers
    depend on an input: with the inputs' values they are the forces; emit/python.py passes its printer and
    its `unpack`): for each kept constraint, by name, its multiplier, the generalized force
    lambda * a and the force (and torque) on each particle and body, with the signed size N.
    Solved numerically at each call (numpy lstsq: the unique solution, or the minimum-norm or
    least-squares one as `Forces.status` says), so that no symbolic solve slows the emitter."""
    from lagrange_cli._symengine import to_symengine
    from lagrange_cli.emit.python import define, literal

    fm = forces(model, symbolic=False)  # numbers at run time: no symbolic solve for the generated code
    k = len(model.constraints)
    lams = [sp.Symbol(f"_lam{i}") for i in range(k)]
    for lam in lams:
        printer.names[str(lam)] = str(lam)
    swap = {c.multiplier: lam for c, lam in zip(model.constraints, lams, strict=True)}
    exprs: list[sp.Expr] = []
    for i, c in enumerate(model.constraints):
        exprs += [lams[i] * a for a in c.jacobian]
    exprs += [e for row in fm.rows for e in row.entries] + [a for c in model.constraints for a in c.jacobian]
    converted = [to_symengine(sp.sympify(e).xreplace(swap)) for e in exprs]
    temporaries, results = printer.block(converted, "_f", set())
    signals = takes_inputs(model)  # then `multipliers` takes the inputs, and so does this function (they set lambda)
    call = "multipliers(t, y, p, u)" if signals else "multipliers(t, y, p)"
    body = [f"{', '.join(map(str, lams))}{',' * (k == 1)} = {call}", *unpack(converted, "y"), *(f"{name} = {code}" for name, code in temporaries)]
    n = model.n
    out = iter(results)
    entries: list[tuple[str, int, list[tuple[str, str, str]]]] = []
    generalized = [[next(out) for _ in range(n)] for _ in range(k)]
    r = len(fm.rows)
    jac = [next(out) for _ in range(r * n)]
    amat = [next(out) for _ in range(k * n)]
    body.append("import numpy")
    body.append("_J = numpy.array([" + ", ".join("[" + ", ".join(jac[i * n : (i + 1) * n]) + "]" for i in range(r)) + f"], dtype=float).reshape({r}, {n})")
    body.append("_A = numpy.array([" + ", ".join("[" + ", ".join(amat[i * n : (i + 1) * n]) + "]" for i in range(k)) + f"], dtype=float).reshape({k}, {n})")
    body.append("_W = numpy.linalg.lstsq(_J.T, _A.T, rcond=None)[0].tolist()")
    for i, c in enumerate(model.constraints):
        parts = []
        for (carrier, kind), codes in spread(model, fm.rows, tuple(f"{lams[i]} * _W[{j}][{i}]" for j in range(r)), keep_zero=True).items():
            vector = "[" + ", ".join(str(x) if isinstance(x, str) else "0.0" for x in codes) + "]"
            parts.append((carrier, kind, vector))
        entries.append((c.name, i, parts))
    items = []
    for name, i, parts in entries:
        carriers: dict[str, list[str]] = {}
        for carrier, kind, vector in parts:
            fields = carriers.setdefault(carrier, [])
            fields.append(f'"{kind}": {vector}')
            if kind == "force":  # N = lambda |W| = sign(lambda) |lambda W|
                fields.append(f'"N": (1.0 if {lams[i]} >= 0 else -1.0) * sum(_v * _v for _v in {vector}) ** 0.5')
        on = ", ".join(f"{literal(carrier)}: {{{', '.join(fields)}}}" for carrier, fields in carriers.items())
        items.append(f'{literal(name)}: {{"lambda": {lams[i]}, "generalized": [{", ".join(generalized[i])}], "on": {{{on}}}}}')
    body.append("return {" + ", ".join(items) + "}")
    doc = (
        f"Each kept constraint's force by name: lambda, the generalized force lambda * d(lhs - rhs)/dq and, on each particle/body, the force (and torque about its centre) that does the same virtual work ({DESCRIPTIONS[fm.status]})."
        " N = lambda * |force / lambda| is positive along the gradient of lhs - rhs."
    )
    return define("constraint_forces", "t, y, p=PARAMETERS" + (", u=INPUTS" if signals else ""), doc, body)


def takes_inputs(model: Model) -> bool:
    """Whether the generated `multipliers` (the `rhs` family) takes `u=INPUTS`: an input in the forcing
    (inputs never enter the mass matrix or the constraints), read from the symengine forms."""
    names = {i.name for i in model.inputs}
    return bool(names) and any(str(s) in names for f in model.symengine.forcing for s in f.free_symbols)


def latex_items(model: Model, escape_text: Callable[[str], str]) -> list[tuple[str, sp.Expr]]:
    """(left-hand side, expression) rows for the LaTeX solved form: each component of each
    constraint's force F (torque tau) on each carrier, and N; none when not solved symbolically."""
    fm = forces(model)
    if fm.directions is None:
        return []
    items: list[tuple[str, sp.Expr]] = []
    for k, c in enumerate(model.constraints):
        lam = c.multiplier
        for (carrier, kind), ws in fm.on(k).items():
            where = f"\\text{{{escape_text(c.name)}}}\\to\\text{{{escape_text(carrier)}}}"
            letter = "F" if kind == "force" else "\\tau"
            items += [(f"{letter}_{{{where},{i + 1}}}", sp.factor_terms(lam * sp.sympify(w))) for i, w in enumerate(ws)]
            size = _size(ws) if kind == "force" else None
            if size is not None:
                items.append((f"N_{{{where}}}", lam * size))
    return items
