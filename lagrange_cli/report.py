"""Text, LaTeX and JSON renderings of `info` and of linearizations (the analysis results)."""

from __future__ import annotations

import json
import math

import sympy as sp

from lagrange_cli.analysis import Info, Linearization
from lagrange_cli.emit.common import printable
from lagrange_cli.emit.latex import comment
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
    lines.append(f"Hamiltonian H(q, p) = {info.hamiltonian}" if info.hamiltonian is not None else f"Hamiltonian: {info.hamiltonian_note}")
    return "\n".join(map(printable, lines)) + "\n"


def info_latex(model: Model, info: Info) -> str:
    printer = latex_names(model, info.momentum_symbols).printer()
    rows = [f"{printer.doprint(s)} &= {printer.doprint(p)}" for s, p in zip(info.momentum_symbols, info.momenta, strict=True)]
    rows.append(f"h &= {printer.doprint(info.energy)}")
    if info.hamiltonian is not None:
        rows.append(f"H &= {printer.doprint(info.hamiltonian)}")
    momenta = dict(zip(model.coordinates, info.momentum_symbols, strict=True))
    conserved = ", ".join(f"${printer.doprint(momenta[c])}$" for c in info.ignorable) or "none"
    return (
        comment(f"{model.title}: momenta and conserved quantities")
        + "\\begin{align*}\n"
        + " \\\\\n".join(rows)
        + "\n\\end{align*}\n"
        + comment(f"conserved momenta: {conserved}; h conserved: {_yes(info.energy_conserved)}")
    )


def info_json(model: Model, info: Info) -> str:
    data = {
        "title": model.title,
        "coordinates": list(info.coordinates),
        "degrees_of_freedom": info.degrees_of_freedom,
        "momenta": {c: str(p) for c, p in zip(info.coordinates, info.momenta, strict=True)},
        "ignorable": list(info.ignorable),
        "energy_function": str(info.energy),
        "energy_conserved": info.energy_conserved,
        "hamiltonian": str(info.hamiltonian) if info.hamiltonian is not None else None,
        "hamiltonian_note": info.hamiltonian_note or None,
        "autonomous": info.autonomous,
        "conservative": info.conservative,
        "constraints": [{"name": n, "kind": k, "multiplier": m} for n, k, m in info.constraints],
    }
    return json.dumps(data, indent=2) + "\n"


def linearization_text(model: Model, lin: Linearization) -> str:
    point = ", ".join(f"{q} = {v}" for q, v in lin.point.items())
    lines = [f"about {point} (velocities zero): M0 x_ddot + C0 x_dot + K0 x = 0", f"  x = [{', '.join(str(q - lin.point.get(q, 0)) for q in model.q)}]"]
    for name, matrix in (("M0", lin.mass), ("C0", lin.damping), ("K0", lin.stiffness)):
        if name == "C0" and matrix.is_zero_matrix:
            continue
        lines.append(f"  {name} = {matrix.tolist()}")
    lines.append(f"  stability (default parameter values): {lin.stability}")
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
    return "\n".join(lines) + "\n"


def linearization_json(model: Model, lin: Linearization) -> dict[str, object]:
    return {
        "point": {str(q): str(v) for q, v in lin.point.items()},
        "M0": [[str(x) for x in row] for row in lin.mass.tolist()],
        "C0": [[str(x) for x in row] for row in lin.damping.tolist()],
        "K0": [[str(x) for x in row] for row in lin.stiffness.tolist()],
        "stability": lin.stability,
        "condition": [str(c) for c in lin.condition],
        "frequencies": [None if math.isnan(f) else f for f in lin.frequencies],
        "modes": [list(m) for m in lin.modes],
    }


def _yes(value: bool) -> str:
    return "yes" if value else "no"
