"""Routh's reduction: the ignorable coordinates removed, their momenta kept as parameters.

For ignorable coordinates c (`Model.ignorable`: dL/dc = 0 and nothing else acts along c) the
momenta p_c = dL/dc_dot are constants beta_c. With L = 1/2 q_dot^T M q_dot + b . q_dot + L0, p_c
is linear in c_dot: M_cc c_dot = beta - M_cr r_dot - b_c, solved for c_dot (a bounded symbolic
inverse: at most `hamilton.MAX_SYMBOLIC` ignorable coordinates, or a diagonal M_cc). The Routhian

    R(r, r_dot, t; beta) = L - beta . c_dot    at c_dot = c_dot(r, r_dot; beta)

is a Lagrangian of the remaining coordinates r: its Lagrange equations are the reduced equations.
The effective potential is V_eff = -R(r, 0; beta) (the r_dot-linear, gyroscopic part of R does no
work), so the equilibria of the reduced system - relative equilibria of the full one (a top's
steady precession, a circular orbit) - are where dV_eff/dr = 0, and their stability is that of the
reduced system's linearization.

The momenta are named `p_<c>`; their values default to those of the file's initial state.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import sympy as sp

from lagrange_cli.errors import fail
from lagrange_cli.hamilton import MAX_SYMBOLIC, _combined, _inverse, _tidy, clashes, declared
from lagrange_cli.model import Model, Parameter


@dataclass(frozen=True)
class Routh:
    """The reduction of `model` by its ignorable coordinates."""

    model: Model
    ignorable: tuple[str, ...]
    momenta: tuple[sp.Symbol, ...]
    """beta: the conserved momenta `p_<c>`, parameters of the reduced system."""
    values: dict[str, float]
    """beta's values at the file's initial state (where it gives one)."""
    ignorable_velocities: tuple[sp.Expr, ...]
    """c_dot(r, r_dot, t; beta)."""
    routhian: sp.Expr
    effective_potential: sp.Expr
    reduced: Model | None
    """The reduced system (None when every coordinate is ignorable)."""


def routh(model: Model) -> Routh:
    """Routh's reduction of `model`; a `LagrangeError` (exit 2) where it does not apply: no
    ignorable coordinate, kept constraints, a momentum name declared in the file, or a Lagrangian
    not quadratic in the velocities."""
    where = model.source
    if model.constraints:
        raise fail(None, f"{where}: Routh's reduction is not written for a system with kept constraints", "a system without kept constraints: eliminate them first")
    ignorable = [i for i in range(model.n) if model.ignorable(i)]
    if not ignorable:
        raise fail(
            None, f"{where}: no coordinate is ignorable, so there is nothing for Routh's reduction to remove", "a system with a coordinate that L does not depend on (its momentum is then conserved)"
        )
    names = tuple(model.coordinates[i] for i in ignorable)
    clash = clashes(model.coordinates, declared(model))
    if clash:
        raise fail(
            None,
            f"{where}: '{clash[0]}' is declared in the file, but Routh's reduction names the momentum of '{clash[0][2:].removesuffix('_dot')}' so",
            "no coordinate, parameter or function named p_<coordinate>",
        )
    mass = sp.Matrix(model.mass_matrix)
    if any(mass.has(v) for v in model.qd):
        raise fail(None, f"{where}: the Lagrangian is not quadratic in the velocities, so the ignorable velocities cannot be solved for from their momenta", "a Lagrangian quadratic in the velocities")
    rest = [i for i in range(model.n) if i not in ignorable]
    block = mass.extract(ignorable, ignorable)
    if len(ignorable) > MAX_SYMBOLIC and not block.is_diagonal():
        raise fail(
            None,
            f"{where}: Routh's reduction by {len(ignorable)} ignorable coordinates with coupled velocities is not written (no symbolic inverse beyond {MAX_SYMBOLIC})",
            f"at most {MAX_SYMBOLIC} ignorable coordinates",
        )
    beta = tuple(sp.Symbol(f"p_{c}") for c in names)
    zero = {model.qd[i]: 0 for i in ignorable}
    # p_c = M_cc c_dot + (M_cr r_dot + b_c): the part without c_dot, then c_dot
    others = [model.momenta[i].xreplace(zero) for i in ignorable]
    adjugate, det = _inverse(sp.ImmutableMatrix(block), where)
    shifted = sp.Matrix([beta[k] - others[k] for k in range(len(ignorable))])
    velocities = tuple(_tidy(v) / det for v in adjugate * shifted)
    solved = {model.qd[i]: v for i, v in zip(ignorable, velocities, strict=True)}
    routhian = _combined(model.lagrangian.xreplace(solved) - sum((b * v for b, v in zip(beta, velocities, strict=True)), sp.Integer(0)))
    at_rest = {model.qd[i]: 0 for i in rest}
    effective = _combined(-routhian.xreplace(at_rest))
    values = _momentum_values(model, ignorable)
    reduced = _reduced(model, rest, beta, values, routhian, solved) if rest else None
    return Routh(model, names, beta, values, velocities, routhian, effective, reduced)


def _momentum_values(model: Model, ignorable: list[int]) -> dict[str, float]:
    """p_c at the file's initial state and parameter values (where both are complete)."""
    state = {**model.parameter_values()}
    for c in model.coordinates:
        state[c] = model.initial.get(c, 0.0)
        state[f"{c}_dot"] = model.initial.get(f"{c}_dot", 0.0)
    state.setdefault("t", 0.0)
    out = {}
    numeric = model.with_definitions()
    for i in ignorable:
        momentum = numeric.momenta[i]
        value = momentum.xreplace({s: state[str(s)] for s in momentum.free_symbols if str(s) in state})
        try:
            number = float(value)
        except (TypeError, ValueError):
            continue
        out[f"p_{model.coordinates[i]}"] = number
    return out


def _reduced(model: Model, rest: list[int], beta: tuple[sp.Symbol, ...], values: dict[str, float], routhian: sp.Expr, solved: dict[sp.Symbol, sp.Expr]) -> Model:
    """The reduced system: the Lagrange equations of R in the remaining coordinates, derived by
    the project's deriver from a system whose `lagrangian` is R."""
    from lagrange_cli import derive, spec

    coordinates = tuple(model.coordinates[i] for i in rest)
    functions = tuple(sorted({str(f.func) for f in routhian.atoms(sp.core.function.AppliedUndef)}))
    parameters = (*model.parameters, *(Parameter(b, values.get(str(b)), True, f"conserved momentum of {str(b)[2:]}") for b in beta))
    system = spec.SystemSpec(
        path=model.source,
        title=f"{model.title} (reduced by Routh: {', '.join(str(b)[2:] for b in beta)} removed)",
        description="",
        coordinates=coordinates,
        q=tuple(model.q[i] for i in rest),
        qd=tuple(model.qd[i] for i in rest),
        qdd=tuple(model.qdd[i] for i in rest),
        t=model.t,
        parameters=parameters,
        functions=functions,
        definitions=dict(model.definitions),
        lagrangian=routhian,
        dissipation=model.dissipation.xreplace(solved),
        generalized_forces=tuple(model.generalized_forces[i].xreplace(solved) for i in rest),
        initial={k: v for k, v in model.initial.items() if k in coordinates or k.removesuffix("_dot") in coordinates},
    )
    reduced = derive.derive(system)
    return dataclasses.replace(reduced, initial=system.initial)


def relative_equilibria(result: Routh) -> tuple[Model, Any]:
    """The equilibria of the reduced system (relative equilibria of the full one), each with the
    linearization that gives its stability: (the model they refer to, `report.Equilibria`).
    Symbolic where the project's solver finds them and each linearizes (Kepler's r0 = p^2/(k m));
    otherwise a numeric search (`analysis`'s many-start root search, bounded) on the reduced system
    with every parameter and momentum at its value, linearized there."""
    from lagrange_cli import analysis, report
    from lagrange_cli.errors import LagrangeError

    if result.reduced is None:
        raise fail(None, f"{result.model.source}: every coordinate is ignorable: the reduced system has no coordinates left", "a system with a coordinate that is not ignorable")
    reduced = result.reduced
    if _solvable(reduced):
        found = report.equilibria(reduced)
        if found.points and all(not isinstance(lin, str) for lin in found.linearizations):
            return reduced, found
    numeric = numeric_reduced(result)
    if numeric is None:
        return reduced, report.equilibria(reduced)
    rest = {v: 0 for v in numeric.qd}
    forces = [f.xreplace(rest) for f in numeric.forcing]
    points: list[dict[sp.Symbol, sp.Expr]] = []
    for point in analysis._numeric_equilibria(numeric, forces, {}):
        refined = _refine(numeric, forces, point)
        if refined is not None and not any(all(abs(refined[x] - other[x]) < 1e-12 for x in numeric.q) for other in points):
            points.append(refined)
    linearizations: list[Any] = []
    potential = result.effective_potential.xreplace({p.symbol: sp.Float(p.value) for p in result.reduced.parameters if p.value is not None})
    for point in points:
        try:
            linearizations.append(analysis.linearize(numeric, {x: sp.Float(v, 15) for x, v in point.items()}))
        except LagrangeError:  # its equilibrium test, in double precision, fails where many digits cancel
            linearizations.append(stability_by_potential(potential, numeric, point))
    return numeric, report.Equilibria(tuple({x: sp.Float(v, 15) for x, v in p.items()} for p in points), tuple(linearizations), ())


def stability_by_potential(potential: sp.Expr, model: Model, point: dict[sp.Symbol, sp.Expr]) -> str:
    """The stability of a relative equilibrium from the Hessian of the effective potential in
    30-digit arithmetic (Routh): a strict minimum is stable; with one coordinate left (no gyroscopic
    coupling) anything else is unstable; with more, a saddle may still be stabilized gyroscopically."""
    q = list(model.q)
    hessian = sp.Matrix(len(q), len(q), lambda i, j: sp.diff(potential, q[i], q[j]).xreplace(point).evalf(30))
    eigenvalues = [sp.re(sp.N(e, 15)) for e in hessian.eigenvals()] if len(q) > 1 else [sp.N(hessian[0, 0], 15)]
    shown = ", ".join(f"{float(e):.6g}" for e in eigenvalues)
    if all(e > 0 for e in eigenvalues):
        return f"stable (a minimum of the effective potential; Hessian eigenvalues {shown})"
    if len(q) == 1:
        return f"unstable (not a minimum of the effective potential; V_eff'' = {shown})"
    return f"not a minimum of the effective potential (Hessian eigenvalues {shown}): unstable unless stabilized gyroscopically"


def _refine(model: Model, forces: list[sp.Expr], point: dict[sp.Symbol, sp.Expr]) -> dict[sp.Symbol, sp.Expr] | None:
    """A root of the numeric search polished by Newton's method in 30-digit arithmetic (a top near
    its vertical cancels many digits), or None where it is not a root after all."""
    import mpmath

    q = list(model.q)
    try:
        with mpmath.workdps(30):
            root = sp.nsolve(forces, q, [point[x] for x in q], prec=30, verify=True)
    except (ValueError, ZeroDivisionError, TypeError):
        return None
    return {x: sp.Float(root[i], 30) for i, x in enumerate(q)}


SOLVE_MAX_OPS = 120
"""Largest reduced force (operations) handed to the symbolic equilibrium search; beyond, the
numeric search decides (sympy's solve on a heavy top's effective potential does not finish soon)."""


def _solvable(reduced: Model) -> bool:
    rest = {v: 0 for v in reduced.qd}
    return all(sp.count_ops(f.xreplace(rest)) <= SOLVE_MAX_OPS for f in reduced.forcing)


def numeric_reduced(result: Routh) -> Model | None:
    """The reduced system with every parameter and momentum at its value (the file's defaults, the
    initial state's momenta), or None where one has no value."""
    if result.reduced is None:
        return None
    values = {p.symbol: sp.Float(p.value) for p in result.reduced.parameters if p.value is not None}
    if len(values) < len(result.reduced.parameters):
        return None
    model = result.model
    rest = [i for i, c in enumerate(model.coordinates) if c not in result.ignorable]
    solved = {model.qd[model.coordinates.index(c)]: v.xreplace(values) for c, v in zip(result.ignorable, result.ignorable_velocities, strict=True)}
    reduced = _reduced(model, rest, result.momenta, result.values, result.routhian.xreplace(values), solved)
    return dataclasses.replace(reduced, parameters=tuple(p for p in reduced.parameters if p.symbol not in values))


def text(result: Routh, equilibria: bool = True) -> str:
    """`info --routh`: the Routhian, the ignorable velocities, the reduced equations, the effective
    potential and the relative equilibria with their stability."""
    from lagrange_cli import report
    from lagrange_cli.emit import text as plain
    from lagrange_cli.emit.common import printable

    lines = [f"Routh's reduction of {result.model.title}", f"ignorable: {', '.join(result.ignorable)}; their conserved momenta are parameters: {', '.join(map(str, result.momenta))}"]
    if result.values:
        lines.append("momenta at the initial state: " + ", ".join(f"{k} = {v:.6g}" for k, v in result.values.items()))
    lines += [f"{result.model.qd[result.model.coordinates.index(c)]} = {v}" for c, v in zip(result.ignorable, result.ignorable_velocities, strict=True)]
    lines.append(f"R = {result.routhian}")
    lines.append(f"V_eff = {result.effective_potential}")
    out = "\n".join(map(printable, lines)) + "\n"
    if result.reduced is not None:
        out += "reduced equations:\n" + plain.emit(result.reduced)
        if equilibria:
            from lagrange_cli.errors import LagrangeError

            try:
                model, found = relative_equilibria(result)
                out += "relative equilibria (equilibria of the reduced system):\n" + report.equilibria_text(model, found)
            except LagrangeError as error:  # a rheonomic reduced system, an undefined function, ...
                out += printable(f"relative equilibria: none computed: {error}") + "\n"
    return out
