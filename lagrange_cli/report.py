"""Text, LaTeX and JSON renderings of `info` and of linearizations (the analysis results)."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass

import sympy as sp

from lagrange_cli.analysis import Info, Linearization
from lagrange_cli.emit import layout
from lagrange_cli.emit.common import printable, tidy
from lagrange_cli.emit.latex import Row, align, comment, room
from lagrange_cli.emit.latex import names as latex_names
from lagrange_cli.model import Model


def info_text(model: Model, info: Info) -> str:
    lines = [f"{model.title}", f"degrees of freedom: {info.degrees_of_freedom} ({len(info.coordinates)} coordinates: {', '.join(info.coordinates)})"]
    lines.append(f"autonomous: {_yes(info.autonomous)}; free of dissipation and applied forces: {_yes(info.conservative)}; constrained: {_yes(bool(info.constraints))}")
    for name, kind, multiplier in info.constraints:
        lines.append(f"  constraint {name}: {kind}, multiplier {multiplier}")
    lines.append("generalized momenta p = dL/dq_dot:")
    lines += [f"  p_{c} = {p}" for c, p in zip(info.coordinates, info.momenta, strict=True)]
    if info.ignorable:
        lines.append("ignorable coordinates (their momenta are conserved): " + ", ".join(info.ignorable))
    else:
        lines.append("ignorable coordinates: none")
    lines.append(f"energy function h = sum p q_dot - L = {info.energy}")
    lines.append(f"h is conserved: {_yes(info.energy_conserved)}")
    lines.append(f"Hamiltonian H(q, p) = {tidy(info.hamiltonian)}" if info.hamiltonian is not None else f"Hamiltonian: {info.hamiltonian_note}")
    if info.hamiltonian is not None and info.hamiltonian_note:
        lines.append(f"  note: {info.hamiltonian_note}")
    return "\n".join(map(printable, lines)) + "\n"


def info_latex(model: Model, info: Info) -> str:
    """Momenta, the energy function and the Hamiltonian as an `align*` laid out like `derive
    --latex` (every line fits a standard article)."""
    doprint = latex_names(model, info.momentum_symbols).printer().doprint
    space = room([doprint(s) for s in info.momentum_symbols])
    rows = [Row(doprint(s), layout.pieces(p, doprint, space)) for s, p in zip(info.momentum_symbols, info.momenta, strict=True)]
    rows.append(Row("h", layout.pieces(info.energy, doprint, space)))
    if info.hamiltonian is not None:
        rows.append(Row("H", layout.pieces(tidy(info.hamiltonian), doprint, space)))
    momenta = dict(zip(model.coordinates, info.momentum_symbols, strict=True))
    conserved = ", ".join(f"${doprint(momenta[c])}$" for c in info.ignorable) or "none"
    note = comment(info.hamiltonian_note) if info.hamiltonian is not None and info.hamiltonian_note else ""
    return comment(f"{model.title}: momenta and conserved quantities") + align(rows) + comment(f"conserved momenta: {conserved}; h conserved: {_yes(info.energy_conserved)}") + note


def info_json(model: Model, info: Info) -> str:
    data = {
        "title": model.title,
        "coordinates": list(info.coordinates),
        "degrees_of_freedom": info.degrees_of_freedom,
        "momenta": {c: str(p) for c, p in zip(info.coordinates, info.momenta, strict=True)},
        "ignorable": list(info.ignorable),
        "energy_function": str(info.energy),
        "energy_conserved": info.energy_conserved,
        "hamiltonian": str(tidy(info.hamiltonian)) if info.hamiltonian is not None else None,
        "hamiltonian_note": info.hamiltonian_note or None,
        "autonomous": info.autonomous,
        "conservative": info.conservative,
        "constraints": [{"name": n, "kind": k, "multiplier": m} for n, k, m in info.constraints],
    }
    return json.dumps(data, indent=2) + "\n"


def linearization_text(model: Model, lin: Linearization) -> str:
    point = ", ".join(f"{q} = {v}" for q, v in lin.point.items())
    names = lin.coordinates or model.coordinates
    symbols = {str(q): q for q in model.q}
    lines = []
    if lin.velocities:
        lines.append(f"about {point} (velocities zero), with velocity constraints: z_dot = S z")
    else:
        lines.append(f"about {point} (velocities zero): M0 x_ddot + C0 x_dot + K0 x = 0")
    if lin.multipliers:
        lines.append("  constraint forces (multipliers) at rest: " + ", ".join(f"{m} = {v}" for m, v in lin.multipliers.items()))
    if lin.velocities:
        lines.append(f"  z = [{', '.join([*(f'd{c}' for c in names), *(f'd{v}' for v in lin.velocities)])}]: the coordinates' perturbations and the independent velocities {', '.join(lin.velocities)}")
        lines += [f"  {name} = {value}" for name, value in lin.dependent_velocities]
        lines.append(f"  M0 = {lin.mass.tolist()} (all coordinates)")
        if not lin.damping.is_zero_matrix:
            lines.append(f"  C0 = {lin.damping.tolist()}")
        lines.append(f"  K0 = {lin.stiffness.tolist()} (K0 = -d(F + A^T lambda)/dq)")
        if lin.state:
            lines.append(f"  S = {[[float(f'{x:.6g}') for x in row] for row in lin.state]} (default parameter values)")
            lines.append(f"  eigenvalues: {', '.join(_complex(e) for e in lin.eigenvalues)}")
    else:
        if lin.dependent:
            lines.append(f"  independent coordinates: {', '.join(names)}; the others follow on the constraint surface:")
            lines += [f"    {name} = {value}" for name, value in lin.dependent]
        lines.append(f"  x = [{', '.join(str(symbols[c] - lin.point.get(symbols[c], 0)) for c in names)}]")
        for name, matrix in (("M0", lin.mass), ("C0", lin.damping), ("K0", lin.stiffness)):
            if name == "C0" and matrix.is_zero_matrix:
                continue
            lines.append(f"  {name} = {matrix.tolist()}")
    lines.append(f"  stability (default parameter values): {lin.stability}")
    if lin.note:
        lines.append(f"  note: {lin.note}")
    if lin.condition and lin.condition != (sp.true,):
        if lin.condition == (sp.false,):
            lines.append("  stable for no parameter values (K0 is never positive definite)")
        else:
            lines.append("  stable when: " + " and ".join(str(c) for c in lin.condition))
    elif lin.condition == (sp.true,):
        lines.append("  stable for all (positive) parameter values")
    if lin.frequencies:
        for frequency, mode in zip(lin.frequencies, lin.modes, strict=True):
            text = "none (exponential growth)" if math.isnan(frequency) else "0 (free drift)" if frequency == 0 else f"{frequency:.6g} rad/s"
            lines.append(f"  mode: frequency {text}, shape [{', '.join(f'{x:.4g}' for x in mode)}]")
    return "\n".join(map(printable, lines)) + "\n"


def linearization_json(model: Model, lin: Linearization) -> dict[str, object]:
    data: dict[str, object] = {
        "point": {str(q): str(v) for q, v in lin.point.items()},
        "coordinates": list(lin.coordinates or model.coordinates),
        "M0": [[str(x) for x in row] for row in lin.mass.tolist()],
        "C0": [[str(x) for x in row] for row in lin.damping.tolist()],
        "K0": [[str(x) for x in row] for row in lin.stiffness.tolist()],
        "stability": lin.stability,
        "condition": [str(c) for c in lin.condition],
        "frequencies": [None if math.isnan(f) else f for f in lin.frequencies],
        "modes": [list(m) for m in lin.modes],
    }
    if lin.multipliers:
        data["multipliers"] = {str(m): str(v) for m, v in lin.multipliers.items()}
    if lin.dependent:
        data["dependent"] = {name: str(v) for name, v in lin.dependent}
    if lin.velocities:
        data["velocities"] = list(lin.velocities)
        data["dependent_velocities"] = {name: str(v) for name, v in lin.dependent_velocities}
        data["state_matrix"] = [list(row) for row in lin.state]
        data["eigenvalues"] = [[e.real, e.imag] for e in lin.eigenvalues]
    if lin.note:
        data["note"] = lin.note
    return data


def _complex(value: complex) -> str:
    if abs(value.imag) <= 1e-12 * max(1.0, abs(value)):
        return f"{value.real:.6g}"
    return f"{value.real:.6g}{value.imag:+.6g}i"


def _yes(value: bool) -> str:
    return "yes" if value else "no"


# -- equilibria: the points, each linearized, and the steady motions (the `equilibria` command and the API) --


@dataclass(frozen=True)
class Equilibria:
    """The equilibrium points found, each with its linearization (or why there is none), and the
    steady motions of ignorable coordinates."""

    points: tuple[Mapping[sp.Symbol, sp.Expr], ...]
    linearizations: tuple[Linearization | str, ...]
    steady: tuple[tuple[sp.Symbol, sp.Expr], ...]


def equilibria(model: Model, ranges: Mapping[sp.Symbol, tuple[float, float]] | None = None) -> Equilibria:
    """`analysis.equilibria` in `ranges`, each point linearized (a point that cannot be is kept
    with the reason), and `analysis.steady_motions`."""
    from lagrange_cli.analysis import equilibria as find
    from lagrange_cli.analysis import linearize, steady_motions
    from lagrange_cli.errors import LagrangeError

    points = find(model, ranges or {})
    steady = steady_motions(model)
    results: list[Linearization | str] = []
    for point in points:
        try:
            results.append(linearize(model, point))
        except LagrangeError as error:
            results.append(str(error))
    return Equilibria(tuple(points), tuple(results), tuple(steady))


def _free(point: Mapping[sp.Symbol, sp.Expr]) -> list[str]:
    """The coordinates a manifold of equilibria leaves free (their value is the symbol `<q>_0`)."""
    return [str(k) for k, v in point.items() if v == sp.Symbol(f"{k}_0")]


def equilibria_json(model: Model, found: Equilibria) -> str:
    items = [
        {"point": {str(k): str(v) for k, v in p.items()}, "free": _free(p), **({"error": lin} if isinstance(lin, str) else linearization_json(model, lin))}
        for p, lin in zip(found.points, found.linearizations, strict=True)
    ]
    motions = [{"velocity": str(v), "equals": str(x)} for v, x in found.steady]
    return json.dumps({"title": model.title, "equilibria": items, "steady_motions": motions}, indent=2) + "\n"


def equilibria_text(model: Model, found: Equilibria) -> str:
    from lagrange_cli.analysis import MAX_NUMERIC_POINTS

    points = found.points
    lines = [f"{model.title}: {len(points)} equilibri{'um' if len(points) == 1 else 'a'}" + (" (none found)" if not points else "")]
    if len(points) >= MAX_NUMERIC_POINTS and all(v.is_Float for p in points for v in p.values()):
        lines.append(f"(the numeric search stops at {MAX_NUMERIC_POINTS} distinct points: the equilibria may form a curve or surface; narrow the search with --range)")
    free = sorted({q for p in points for q in _free(p)})
    if free:
        lines.append(f"(a manifold of equilibria: {', '.join(f'{q}_0' for q in free)} may take any value)")
    for point, lin in zip(points, found.linearizations, strict=True):
        lines.append(linearization_text(model, lin) if not isinstance(lin, str) else f"at {dict(point)}: {lin}\n")
    if found.steady:
        lines.append("steady motions (the other coordinates at rest, ignorable ones turning steadily):")
        lines += [f"  {v} = {x}" for v, x in found.steady]
    return "\n".join(lines) + "\n"
