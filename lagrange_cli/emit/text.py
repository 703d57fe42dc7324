"""Plain-text equations, one per line, with `theta_ddot`-style names. Each line passes through
`common.printable`: whatever a name contains, no control character reaches the output."""

from __future__ import annotations

from sympy.printing.str import StrPrinter

from lagrange_cli.algebra import check_invertible, solved_accelerations
from lagrange_cli.emit.common import constraint_equations, lagrange_terms, printable
from lagrange_cli.model import Model


def emit(model: Model, form: str = "lagrange") -> str:
    printer = StrPrinter()
    lines = []
    if form == "lagrange":
        for terms in lagrange_terms(model):
            lines.append(join_terms([printer.doprint(term) for term in terms]) + " = 0")
        lines += [f"{printer.doprint(expr)} = 0" for _, expr in constraint_equations(model)]
    elif form == "matrix":
        check_invertible(model)
        lines.append("M*q_ddot = F" + (" + A^T*lambda,  A*q_ddot + c = 0" if model.constraints else ""))
        lines.append("q_ddot = [" + ", ".join(map(str, model.qdd)) + "]")
        if model.constraints:
            lines.append("lambda = [" + ", ".join(map(str, model.multipliers)) + "]")
        lines.append("M =")
        lines += ["  [" + ", ".join(printer.doprint(x) for x in model.mass_matrix.row(i)) + "]" for i in range(model.n)]
        lines.append("F =")
        lines += [f"  [{printer.doprint(x)}]" for x in model.forcing]
        if model.constraints:
            lines.append("A =")
            lines += ["  [" + ", ".join(printer.doprint(a) for a in c.jacobian) + "]" for c in model.constraints]
            lines.append("c =")
            lines += [f"  [{printer.doprint(c.acceleration_bias)}]" for c in model.constraints]
    else:
        values = solved_accelerations(model)
        for symbol, value in zip((*model.qdd, *model.multipliers), values, strict=True):
            lines.append(f"{symbol} = {printer.doprint(value)}")
    return "\n".join(map(printable, lines)) + "\n"


def join_terms(parts: list[str]) -> str:
    """Join printed terms with ' + ' / ' - ' so that a leading minus becomes the operator."""
    out = ""
    for i, part in enumerate(parts):
        if i == 0:
            out = part
        elif part.startswith("-"):
            out += " - " + part[1:].lstrip()
        else:
            out += " + " + part
    return out or "0"
