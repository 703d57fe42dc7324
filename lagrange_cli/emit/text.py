"""Plain-text equations, one per line, with `theta_ddot`-style names. Each line passes through
`common.printable`: whatever a name contains, no control character reaches the output.

The Lagrange and matrix forms are printed from `Model.symengine` by `TextPrinter` (each distinct
subexpression once), so that a big system costs about as much as its output; the solved form
(small systems only) is printed by sympy's printer."""

from __future__ import annotations

from collections.abc import Sequence

from sympy.printing.str import StrPrinter

from lagrange_cli._symengine import to_symengine
from lagrange_cli.algebra import check_invertible, solved_accelerations
from lagrange_cli.emit.common import Expr, SymenginePrinter, collected, common_factor, constraint_equations, equation_terms, printable, state_symbols, tidy
from lagrange_cli.model import Model


class TextPrinter(SymenginePrinter):
    """Symengine expressions in the notation of sympy's `str` (`l**2*m*theta_ddot`, `k/r**2`,
    `sqrt(k*m)`, `sin(theta)`); what it has no rule for is printed by sympy's `StrPrinter`."""

    def __init__(self) -> None:
        super().__init__()
        self._sympy = StrPrinter()

    def mul(self, expr: Expr) -> str:
        number, above, below = self.split(expr)
        sign = ""
        if number.is_negative:
            sign, number = "-", -number
        top = [self._factor(f) for f in above]
        bottom = [self._factor(f) for f in below]
        if number != 1:
            if number.is_Rational and not number.is_Integer:
                if int(number.p) != 1:
                    top.insert(0, str(int(number.p)))
                bottom.insert(0, str(int(number.q)))
            else:
                top.insert(0, self.doprint(number))
        text = "*".join(top) or "1"
        if bottom:
            text += "/" + (bottom[0] if len(bottom) == 1 else "(" + "*".join(bottom) + ")")
        return sign + text

    def _factor(self, factor: Expr) -> str:
        printed = self.doprint(factor)
        return f"({printed})" if factor.is_Add else printed

    def power(self, base: Expr, exponent: Expr) -> str:
        if exponent.is_Rational and not exponent.is_Integer and int(exponent.q) == 2 and abs(int(exponent.p)) == 1:
            return ("1/" if exponent.is_negative else "") + f"sqrt({self.doprint(base)})"
        if exponent == -1:
            return "1/" + self._base(base)
        if exponent.is_Integer and not exponent.is_negative:
            power = str(int(exponent))
        elif exponent.is_Symbol:
            power = self.doprint(exponent)
        else:
            power = f"({self.doprint(exponent)})"
        return f"{self._base(base)}**{power}"

    def _base(self, base: Expr) -> str:
        printed = self.doprint(base)
        atomic = base.is_Symbol or (base.is_Integer and not base.is_negative) or (not base.is_Add and not base.is_Mul and not base.is_Pow and not base.is_Number)
        return printed if atomic else f"({printed})"

    def exp(self, exponent: Expr) -> str:
        return f"exp({self.doprint(exponent)})"

    def function(self, name: str, args: Sequence[Expr], undefined: bool = False) -> str:
        return f"{self.functions.get(name, name)}({', '.join(self.doprint(a) for a in args)})"

    def fallback(self, expr: object) -> str:
        return str(self._sympy.doprint(expr))


def emit(model: Model, form: str = "lagrange") -> str:
    lines = []
    if form == "lagrange":
        printer = TextPrinter()
        for terms in equation_terms(model, printer):
            lines.append(join_terms([printer.doprint(term) for term in terms]) + " = 0")
        lines += [f"{printer.doprint(to_symengine(expr))} = 0" for _, expr in constraint_equations(model)]
    elif form == "matrix":
        check_invertible(model)
        printer = TextPrinter()
        forms, state = model.symengine, state_symbols(model)
        # Names of several words, which no parameter can have (a parameter may be called `M`).
        lines.append("mass matrix * accelerations = forcing" + (" + constraint matrix^T * multipliers" if model.constraints else ""))
        if model.constraints:
            lines.append("constraint matrix * accelerations + constraint bias = 0")
        lines.append("accelerations = [" + ", ".join(map(str, model.qdd)) + "]")
        if model.constraints:
            lines.append("multipliers = [" + ", ".join(map(str, model.multipliers)) + "]")
        lines.append("mass matrix =")
        lines += ["  [" + ", ".join(printer.doprint(common_factor(x)) for x in row) + "]" for row in forms.mass]
        lines.append("forcing =")
        lines += [f"  [{join_terms([printer.doprint(t) for t in collected(f, state, printer)])}]" for f in forms.forcing]
        if model.constraints:
            lines.append("constraint matrix =")
            lines += ["  [" + ", ".join(printer.doprint(to_symengine(a)) for a in c.jacobian) + "]" for c in model.constraints]
            lines.append("constraint bias =")
            lines += [f"  [{printer.doprint(to_symengine(c.acceleration_bias))}]" for c in model.constraints]
    else:
        sympy_printer = StrPrinter()
        values = [tidy(v) for v in solved_accelerations(model)]
        for symbol, value in zip((*model.qdd, *model.multipliers), values, strict=True):
            lines.append(f"{symbol} = {sympy_printer.doprint(value)}")
        if model.constraints:
            from lagrange_cli.forces import lines as force_lines

            lines += force_lines(model, sympy_printer.doprint)
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
