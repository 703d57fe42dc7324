"""LaTeX: an `align*` fragment to `\\input`, or with `standalone=True` a whole document."""

from __future__ import annotations

from pathlib import Path

import sympy as sp
from sympy.printing.latex import LatexPrinter

from lagrange_cli.algebra import check_invertible, solved_accelerations
from lagrange_cli.emit.common import constraint_equations, lagrange_terms
from lagrange_cli.emit.text import join_terms
from lagrange_cli.model import Model

TERMS_PER_LINE = 4
# Subscripts that read better as symbols: I_perp -> I_{\perp}, I_par -> I_{\parallel}.
SUBSCRIPTS = {"perp": r"\perp", "par": r"\parallel", "parallel": r"\parallel"}


def symbol_names(model: Model) -> dict[sp.Symbol, str]:
    """Dots over coordinates: theta_dot -> \\dot{\\theta}, theta1_ddot -> \\ddot{\\theta}_{1}."""
    names: dict[sp.Symbol, str] = {}
    for q, qd, qdd in zip(model.q, model.qd, model.qdd, strict=True):
        base = sp.latex(q)
        head, _, sub = base.partition("_")
        names[qd] = rf"\dot{{{head}}}" + (f"_{sub}" if sub else "")
        names[qdd] = rf"\ddot{{{head}}}" + (f"_{sub}" if sub else "")
    for p in model.parameters:
        head, _, sub = p.name.partition("_")
        if sub in SUBSCRIPTS and head:
            names[p.symbol] = f"{sp.latex(sp.Symbol(head))}_{{{SUBSCRIPTS[sub]}}}"
    for c in model.constraints:
        names[c.multiplier] = rf"\lambda_{{\mathrm{{{_escape(c.name)}}}}}"
    return names


def emit(model: Model, form: str = "lagrange", standalone: bool = False) -> str:
    printer = LatexPrinter({"symbol_names": symbol_names(model)})
    rows: list[str] = []
    if form == "lagrange":
        for terms in lagrange_terms(model):
            rows.append(_broken([printer.doprint(term) for term in terms], "&= 0"))
        rows += [f"{printer.doprint(expr)} &= 0" for _, expr in constraint_equations(model)]
    elif form == "matrix":
        check_invertible(model)
        qdd = sp.Matrix(model.qdd)
        lhs = printer.doprint(sp.Matrix(model.mass_matrix)) + " " + printer.doprint(qdd)
        rhs = printer.doprint(sp.Matrix(model.forcing))
        if model.constraints:
            rhs += " + " + printer.doprint(model.constraint_matrix.T) + " " + printer.doprint(sp.Matrix(model.multipliers))
        rows.append(f"{lhs} &= {rhs}")
        if model.constraints:
            c = sp.Matrix([row.acceleration_bias for row in model.constraints])
            rows.append(f"{printer.doprint(model.constraint_matrix)} {printer.doprint(qdd)} + {printer.doprint(c)} &= 0")
    else:
        values = solved_accelerations(model)
        for symbol, value in zip((*model.qdd, *model.multipliers), values, strict=True):
            rows.append(f"{printer.doprint(symbol)} &= {printer.doprint(value)}")
    body = "\\begin{align*}\n" + " \\\\\n".join(rows) + "\n\\end{align*}\n"
    header = f"% {model.title}: {'Lagrange' if form == 'lagrange' else form} form, from {Path(model.source).name}\n"
    if not standalone:
        return header + body
    return f"\\documentclass{{article}}\n\\usepackage{{amsmath}}\n\\usepackage[margin=2cm]{{geometry}}\n\\begin{{document}}\n\\section*{{{_escape(model.title)}}}\n" + body + "\\end{document}\n"


def _broken(parts: list[str], tail: str) -> str:
    """Join terms; a long equation is broken into left-aligned lines of a few terms each."""
    lines = [join_terms(parts[i : i + TERMS_PER_LINE]) for i in range(0, len(parts), TERMS_PER_LINE)]
    if len(lines) == 1:
        return f"{lines[0]} {tail}"
    rest = [("" if line.startswith("-") else "+ ") + line for line in lines[1:]]
    return "&" + lines[0] + "".join(f" \\\\\n&\\quad {line}" for line in rest) + " " + tail.removeprefix("&")


def _escape(text: str) -> str:
    for char, replacement in (("\\", r"\textbackslash{}"), ("_", r"\_"), ("&", r"\&"), ("%", r"\%"), ("$", r"\$"), ("#", r"\#"), ("{", r"\{"), ("}", r"\}"), ("^", r"\^{}"), ("~", r"\~{}")):
        text = text.replace(char, replacement)
    return text
