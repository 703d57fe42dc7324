"""LaTeX: an `align*` fragment to `\\input`, or with `standalone=True` a whole document.

File text is data here. It reaches the output in three places, each through one function:
`comment` (a single `%` line: control characters and line separators cannot end it),
`escape_text` (the `\\section*` title: every special character, control character, blank
line and non-ASCII character becomes plain-LaTeX text that typesets as itself), and the
symbol namer (`names`), which gives every symbol and function an explicit LaTeX name built
from an allow-list of macros (Greek letters, `\\dot`, `\\mathit`, ...), never sympy's
guesses (`xdot` -> `\\dot{x}`, `ymathscr` -> `\\mathscr{y}`).
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import sympy as sp
from sympy.printing.latex import LatexPrinter

from lagrange_cli.algebra import check_invertible, solved_accelerations
from lagrange_cli.emit.common import constraint_equations, lagrange_terms, printable
from lagrange_cli.emit.text import join_terms
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

TERMS_PER_LINE = 4
# Greek letters by their full name, as plain LaTeX (amsmath not needed) defines them.
_GREEK_NAMES = (
    "alpha beta gamma delta epsilon varepsilon zeta eta theta vartheta iota kappa lambda mu nu xi pi varpi rho varrho sigma varsigma tau upsilon "
    "phi varphi chi psi omega Gamma Delta Theta Lambda Xi Pi Sigma Upsilon Phi Psi Omega"
)
GREEK = frozenset(_GREEK_NAMES.split())
# Subscripts that read better as symbols: I_perp -> I_{\perp}, I_par -> I_{\parallel}.
SUBSCRIPTS = {"perp": r"\perp", "par": r"\parallel", "parallel": r"\parallel"}
# Every macro a (valid) name can turn into; the tests hold the output to this set.
NAME_MACROS = frozenset({*GREEK, *(m.lstrip("\\") for m in SUBSCRIPTS.values()), "dot", "ddot", "mathit", "mathrm", "operatorname"})
NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
MATHIT = r"\mathit{"


def emit(model: Model, form: str = "lagrange", standalone: bool = False) -> str:
    printer = names(model).printer()
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
    header = comment(f"{model.title}: {'Lagrange' if form == 'lagrange' else form} form, from {Path(model.source).name}")
    if not standalone:
        return header + body
    return (
        f"{header}\\documentclass{{article}}\n\\usepackage{{amsmath}}\n\\usepackage[margin=2cm]{{geometry}}\n\\begin{{document}}\n\\section*{{{escape_text(model.title)}}}\n"
        + body
        + "\\end{document}\n"
    )


def _broken(parts: list[str], tail: str) -> str:
    """Join terms; a long equation is broken into left-aligned lines of a few terms each."""
    lines = [join_terms(parts[i : i + TERMS_PER_LINE]) for i in range(0, len(parts), TERMS_PER_LINE)]
    if len(lines) == 1:
        return f"{lines[0]} {tail}"
    rest = [("" if line.startswith("-") else "+ ") + line for line in lines[1:]]
    return "&" + lines[0] + "".join(f" \\\\\n&\\quad {line}" for line in rest) + " " + tail.removeprefix("&")


# --- file text -------------------------------------------------------------------------------


def comment(text: str) -> str:
    """`text` as one `%` comment line: every run of whitespace (newlines, form feeds, U+2028,
    ...) becomes one space, and every other control or format character is shown as `U+XXXX`
    (`common.printable`), so that nothing can end the comment and start live LaTeX."""
    return "% " + re.sub(" +", " ", printable(text)).strip() + "\n"


# Text-mode replacements for the ten special characters (and a few ASCII characters that OT1
# fonts do not show as themselves).
_TEXT_SPECIALS = {
    "\\": r"\textbackslash{}",
    "{": r"\{",
    "}": r"\}",
    "$": r"\$",
    "&": r"\&",
    "#": r"\#",
    "^": r"\textasciicircum{}",
    "_": r"\_",
    "%": r"\%",
    "~": r"\textasciitilde{}",
    "<": r"\textless{}",
    ">": r"\textgreater{}",
    "|": r"\textbar{}",
    '"': "''",
    "-": "-{}",
    "'": "'{}",
    "`": "{}`{}",
}
# Combining marks that the LaTeX kernel's OT1 encoding can put over (or under) a letter.
_ACCENTS = {
    "\u0300": "`",
    "\u0301": "'",
    "\u0302": "^",
    "\u0303": "~",
    "\u0304": "=",
    "\u0306": "u",
    "\u0307": ".",
    "\u0308": '"',
    "\u030a": "r",
    "\u030b": "H",
    "\u030c": "v",
    "\u0323": "d",
    "\u0327": "c",
    "\u0331": "b",
}
# Letters and punctuation that OT1 has (or builds) without a combining mark.
_LETTERS = {
    "ß": r"\ss{}",
    "æ": r"\ae{}",
    "Æ": r"\AE{}",
    "œ": r"\oe{}",
    "Œ": r"\OE{}",
    "ø": r"\o{}",
    "Ø": r"\O{}",
    "ł": r"\l{}",
    "Ł": r"\L{}",
    "ı": r"\i{}",
    "ȷ": r"\j{}",
    "\u2013": "--",
    "\u2014": "---",
    "\u2018": "`",
    "\u2019": "'",
    "\u201c": "``",
    "\u201d": "''",
    "\u2026": r"\ldots{}",
    "¡": "!`",
    "¿": "?`",
    "§": r"\S{}",
    "¶": r"\P{}",
    "©": r"\copyright{}",
    "†": r"\dag{}",
    "‡": r"\ddag{}",
    "£": r"\pounds{}",
    "°": r"\ensuremath{^\circ}",
    "×": r"\ensuremath{\times}",
    "÷": r"\ensuremath{\div}",
    "±": r"\ensuremath{\pm}",
    "·": r"\ensuremath{\cdot}",
    "µ": r"\ensuremath{\mu}",
    "\u2212": r"\ensuremath{-}",
    "\u2032": r"\ensuremath{'}",
}


def escape_text(text: str) -> str:
    """`text` as LaTeX text that typesets as itself with plain pdflatex and the default OT1
    fonts: the ten special characters escaped, any whitespace (a blank line would end a
    `\\section*` argument) one space, control and format characters dropped, accented Latin
    letters as accent commands, Greek letters in math, and anything else as `U+XXXX` in sans
    serif. The result is ASCII, so it also survives any input encoding."""
    text = unicodedata.normalize("NFD", re.sub(r"\s+", " ", text).strip())
    out: list[str] = []
    for i, char in enumerate(text):
        if char in _ACCENTS and i > 0 and text[i - 1].isascii() and text[i - 1].isalpha():
            continue  # written with its letter below
        if char.isascii():
            mark = text[i + 1] if i + 1 < len(text) else ""
            if char.isalpha() and mark in _ACCENTS:
                letter = {"i": r"\i", "j": r"\j"}.get(char, char) if _ACCENTS[mark] not in "cdb" else char
                out.append(f"\\{_ACCENTS[mark]}{{{letter}}}")
            elif 32 <= ord(char) < 127:
                out.append(_TEXT_SPECIALS.get(char, char))
        elif char in _LETTERS:
            out.append(_LETTERS[char])
        elif (greek := _greek_letter(char)) is not None:
            out.append(rf"\ensuremath{{\{greek}}}")
        elif unicodedata.category(char)[0] != "C":
            out.append(rf"\textsf{{U+{ord(char):04X}}}")
    return "".join(out)


def _greek_letter(char: str) -> str | None:
    """`theta` for θ, `Theta` for Θ (where LaTeX has the macro), else None."""
    name = unicodedata.name(char, "")
    match = re.fullmatch(r"GREEK (SMALL|CAPITAL) LETTER ([A-Z]+)", name)
    if not match:
        return "varsigma" if name == "GREEK SMALL LETTER FINAL SIGMA" else None
    letter = match.group(2).lower()
    letter = "lambda" if letter == "lamda" else letter
    letter = letter.capitalize() if match.group(1) == "CAPITAL" else letter
    return letter if letter in GREEK else None


# --- names of symbols -------------------------------------------------------------------------


@dataclass(frozen=True)
class Names:
    """The LaTeX name of every symbol and function of a model; distinct symbols get distinct names."""

    symbols: dict[sp.Symbol, str]
    functions: dict[str, str]

    def printer(self) -> LatexPrinter:
        return _Printer(self)


class _Printer(LatexPrinter):
    """sympy's LaTeX printer with every name from `Names` (or, for a symbol it does not know,
    from the same rule), never from sympy's name guessing."""

    def __init__(self, known: Names) -> None:
        super().__init__({"symbol_names": known.symbols})
        self._functions = known.functions

    def _print_Symbol(self, expr: sp.Symbol, style: str = "plain") -> str:
        name = self._settings["symbol_names"].get(expr)
        return name if name is not None else symbol_tex(expr.name.lstrip("_"))

    def _hprint_Function(self, func: str) -> str:
        if func in self._functions:
            return self._functions[func]
        return super()._hprint_Function(func)


def names(model: Model, momenta: Sequence[sp.Symbol] = ()) -> Names:
    """Coordinates, their velocities and accelerations (`\\dot{\\theta}_{1}`), parameters, time,
    multipliers (`\\lambda_{\\mathrm{roll},x}`), functions, and the momenta `p_{q}` of `info`
    when given. Names that would print alike (`x_1` and `x1`) are written out literally
    (`\\mathit{x\\_1}`, `\\mathit{x1}`)."""
    functions = sorted({str(f.func) for f in _applied_functions(model)} | set(model.definitions))
    literal: set[str] = set()
    while True:
        owners: list[tuple[str, sp.Basic | str, str]] = []
        for q, qd, qdd in zip(model.q, model.qd, model.qdd, strict=True):
            head, sub = _parts(q.name, q.name in literal)
            owners += [(q.name, q, head + sub), (q.name, qd, rf"\dot{{{head}}}{sub}"), (q.name, qdd, rf"\ddot{{{head}}}{sub}")]
        for q, p in zip(model.q, momenta, strict=False):
            owners.append((q.name, p, f"p_{{{''.join(_parts(q.name, q.name in literal))}}}"))
        owners += [(p.name, p.symbol, "".join(_parts(p.name, p.name in literal))) for p in model.parameters]
        owners.append((model.t.name, model.t, "".join(_parts(model.t.name, False))))
        owners += [(c.multiplier.name, c.multiplier, _multiplier(c.name, c.multiplier.name in literal)) for c in model.constraints]
        owners += [(f, f, _function(f, f in literal)) for f in functions]
        by_text: dict[str, set[str]] = {}
        for owner, _key, tex in owners:
            by_text.setdefault(tex, set()).add(owner)
        clashing = {o for group in by_text.values() if len(group) > 1 for o in group}
        if not clashing:
            break
        if clashing <= literal:
            raise DerivationError(f"{model.source}: the names {', '.join(sorted(clashing))} print alike in LaTeX; rename one of them")
        literal |= clashing
    return Names({key: tex for _, key, tex in owners if isinstance(key, sp.Symbol)}, {key: tex for _, key, tex in owners if isinstance(key, str)})


def symbol_names(model: Model) -> dict[sp.Symbol, str]:
    """The LaTeX name of every symbol of `model` (see `names`)."""
    return names(model).symbols


def symbol_tex(name: str) -> str:
    """The LaTeX of one name by the rule alone: `theta` -> `\\theta`, `th1` -> `\\mathit{th}_{1}`,
    `k_x` -> `k_{x}`, `x_max` -> `x_{\\mathrm{max}}`, `a_b_c` -> `a_{b,c}`."""
    return "".join(_parts(name, False))


def _parts(name: str, literal: bool) -> tuple[str, str]:
    """The head and the subscript (`""` or `_{...}`) of a name. The head carries any dot; a
    name's trailing digits and its `_`-separated parts are the subscript."""
    if not NAME.match(name):
        return rf"\text{{{escape_text(name)}}}", ""
    pieces = name.split("_")
    if literal or "" in pieces:
        return rf"\mathit{{{_underscores(name)}}}", ""
    head, subs = pieces[0], pieces[1:]
    digits = re.fullmatch(r"(.*?[A-Za-z])([0-9]+)", head)
    if digits:
        head, subs = digits.group(1), [digits.group(2), *subs]
    head_tex = f"\\{head}" if head in GREEK else head if len(head) == 1 else rf"\mathit{{{head}}}"
    return head_tex, (f"_{{{','.join(_subscript(s) for s in subs)}}}" if subs else "")


def _subscript(part: str) -> str:
    if part.isdigit() or len(part) == 1:
        return part
    if part in GREEK:
        return f"\\{part}"
    return SUBSCRIPTS.get(part, rf"\mathrm{{{part}}}")


def _multiplier(constraint: str, literal: bool) -> str:
    """`\\lambda_{\\mathrm{rod}}`, `\\lambda_{\\mathrm{roll},x}`."""
    pieces = constraint.split("_")
    if literal or not NAME.match(constraint) or "" in pieces:
        return rf"\lambda_{{\mathrm{{{_underscores(constraint)}}}}}" if NAME.match(constraint) else rf"\lambda_{{\text{{{escape_text(constraint)}}}}}"
    return rf"\lambda_{{{','.join(_subscript(p) for p in pieces)}}}"


def _function(name: str, literal: bool) -> str:
    """`U`, `\\Phi`, `V_{1}`, `\\operatorname{pot}`."""
    if not NAME.match(name):
        return rf"\text{{{escape_text(name)}}}"
    if literal or "" in name.split("_"):
        return rf"\operatorname{{{_underscores(name)}}}"
    head, sub = _parts(name, False)
    if head.startswith(MATHIT):
        head = r"\operatorname" + head.removeprefix(MATHIT[:-1])
    return head + sub


def _underscores(name: str) -> str:
    return name.replace("_", r"\_")


def _applied_functions(model: Model) -> set[sp.Expr]:
    exprs = [*model.mass_matrix, *model.forcing, model.energy, model.lagrangian, *(c.expr for c in model.constraints)]
    return set(sp.Matrix(exprs).atoms(sp.core.function.AppliedUndef))
