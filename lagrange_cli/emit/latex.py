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
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import sympy as sp
from sympy.printing.latex import LatexPrinter

from lagrange_cli._symengine import se, to_symengine
from lagrange_cli.algebra import check_invertible, solved_accelerations
from lagrange_cli.emit import layout
from lagrange_cli.emit.common import Expr, SymenginePrinter, collected, common_factor, constraint_equations, equation_terms, printable, state_symbols, tidy
from lagrange_cli.emit.text import TextPrinter
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

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
    """The equations of `model` in `form` (`lagrange`, `matrix` or `solved`) as an `align*` whose
    every line fits a standard article (see `layout`)."""
    known = names(model)
    doprint = known.printer().doprint
    if form == "lagrange":
        space = room()
        printer = TexPrinter(known)
        rows = [Row("", layout.terms(terms, printer.doprint, space), zero=True) for terms in equation_terms(model, printer.keys)]
        rows += [Row("", layout.pieces(to_symengine(expr), printer.doprint, space), zero=True) for _, expr in constraint_equations(model)]
        body = align(rows)
    elif form == "matrix":
        check_invertible(model)
        body = _matrix_form(model, TexPrinter(known))
    else:
        values = [tidy(v) for v in solved_accelerations(model)]
        lhs = [doprint(s) for s in (*model.qdd, *model.multipliers)]
        items = list(zip(lhs, values, strict=True))
        if model.constraints:
            from lagrange_cli.forces import latex_items

            items += latex_items(model, escape_text)
        body = align([Row(name, layout.pieces(v, doprint, room([n for n, _ in items]))) for name, v in items])
    header = comment(f"{model.title}: {'Lagrange' if form == 'lagrange' else form} form, from {Path(model.source).name}")
    if form == "solved" and model.constraints:
        from lagrange_cli.forces import CONVENTION

        header += comment(f"constraint forces F (torques tau) on each particle/body: {CONVENTION}")
    return document(model.title, header, body) if standalone else header + body


def document(title: str, header: str, body: str) -> str:
    """`body` as a whole article under a section named by `title` (escaped as text), `header`'s comments first:
    what `--standalone` writes for every form."""
    return (
        f"{header}\\documentclass{{article}}\n\\usepackage{{amsmath}}\n\\usepackage[margin=2cm]{{geometry}}\n\\allowdisplaybreaks\n\\begin{{document}}\n\\section*{{{escape_text(title)}}}\n"
        + body
        + "\\end{document}\n"
    )


# --- layout ------------------------------------------------------------------------------------

_EQUALS = layout.width("a = 0") - layout.width("a")


def room(lhs: Sequence[str] = ()) -> float:
    """The width of a continuation line in an `align` whose left-hand sides are `lhs` (none: rows
    `... &= 0`): a piece wider than this is split further."""
    if not lhs:
        return layout.LINE_WIDTH - _EQUALS - layout.QUAD
    return layout.LINE_WIDTH - max(layout.width(tex) for tex in lhs) - layout.QUAD


@dataclass(frozen=True)
class Row:
    """One equation of an `align*`, its right-hand side as pieces that the line breaker packs
    into lines: `lhs &= rhs`, or with `zero` (and no `lhs`) `rhs &= 0`, or with neither a line
    of its own starting at the alignment point."""

    lhs: str
    rhs: Sequence[layout.Piece]
    zero: bool = False


def align(rows: Sequence[Row]) -> str:
    """An `align*` whose rows all align on their `=`: `lhs &= ...` with continuation lines
    `&\\quad ...` under the `=`; an equation `... &= 0` too long for a line becomes a bottom-
    aligned block of lines (`\\begin{aligned}[b]`) left of the `=`, and one taller than
    `layout.BREAKABLE_LINES` lines (a block cannot break across pages) is written `0 &= ...`
    in environments of its own. Lines are broken so that the widest left column plus any line
    fits `layout.LINE_WIDTH`. An `align*` never breaks across pages: a long one is split between
    rows (or between the lines of a long row) into several, between which a page may break."""
    equals = _EQUALS
    left = max((layout.width(row.lhs) for row in rows if row.lhs), default=0.0)
    if any(row.zero for row in rows):
        left = max(left, layout.LINE_WIDTH - equals)
    environments: list[str] = []
    group: list[str] = []
    used = 0
    for row in rows:
        if row.zero:
            lines = layout.lines(row.rhs, layout.LINE_WIDTH - equals, layout.LINE_WIDTH - equals - layout.QUAD)
            if len(lines) > layout.BREAKABLE_LINES:
                if group:
                    environments.append(_environment(group))
                    group, used = [], 0
                environments.append(align([Row("0", row.rhs)]))
                continue
            if len(lines) == 1:
                chunk = [f"{lines[0]} &= 0"]
            else:
                block = " \\\\\n".join([f"&{lines[0]}", *(rf"&\quad {line}" for line in lines[1:])])
                chunk = [f"\\begin{{aligned}}[b]\n{block}\n\\end{{aligned}} &= 0"]
        else:
            first = layout.LINE_WIDTH - left - (equals if row.lhs else 0.0)
            lines = layout.lines(row.rhs, first, layout.LINE_WIDTH - left - layout.QUAD)
            head = f"{row.lhs} &= " if row.lhs else "&"
            chunk = [head + lines[0], *(rf"&\quad {line}" for line in lines[1:])]
        size = len(chunk) + chunk[0].count("\\\\")
        parts = [chunk] if size <= layout.BREAKABLE_LINES else [chunk[k : k + layout.BREAKABLE_LINES] for k in range(0, len(chunk), layout.BREAKABLE_LINES)]
        for part in parts:
            size = len(part) + part[0].count("\\\\")
            if group and used + size > layout.BREAKABLE_LINES:
                environments.append(_environment(group))
                group, used = [], 0
            group.append(" \\\\\n".join(part))
            used += size
    if group:
        environments.append(_environment(group))
    return "".join(environments)


def _environment(rows: Sequence[str]) -> str:
    return "\\begin{align*}\n" + " \\\\\n".join(rows) + "\n\\end{align*}\n"


def _matrix_form(model: Model, printer: TexPrinter) -> str:
    """`M q_ddot = F (+ A^T lambda)` with whole matrices when they fit the line, else entry by
    entry: `\\mathbf{M}_{ij}` for i <= j (M is symmetric), `\\mathbf{F}_{i}`, ... Bold names
    cannot be confused with a parameter (`M`). Each entry is printed and measured once."""
    n, k = model.n, len(model.constraints)
    doprint = printer.doprint
    forms, state = model.symengine, state_symbols(model)
    factored = {(i, j): common_factor(forms.mass[i][j]) for i in range(n) for j in range(i, n)}
    entries = {ij: (entry, doprint(entry)) for ij, entry in factored.items()}
    forcing = [collected(f, state, printer.keys) for f in forms.forcing]
    jacobians = [[to_symengine(a) for a in c.jacobian] for c in model.constraints]
    biases = [collected(to_symengine(c.acceleration_bias), state, printer.keys) for c in model.constraints]
    columns = [max(layout.width(entries[min(i, j), max(i, j)][1]) for i in range(n)) for j in range(n)]
    if sum(columns) + 2.0 * (n + 4) + (4.0 * (n + 2) if k else 0.0) <= layout.LINE_WIDTH:
        qdd = _column([doprint(s) for s in forms.qdd])
        mass = _matrix([[entries[min(i, j), max(i, j)][1] for j in range(n)] for i in range(n)])
        lhs = mass + " " + qdd
        rhs = _column([printer.add(terms) for terms in forcing])
        if k:
            rhs += " + " + _matrix([[doprint(a) for a in row] for row in zip(*jacobians, strict=True)]) + " " + _column([doprint(to_symengine(s)) for s in model.multipliers])
        rows = [(lhs, rhs)]
        if k:
            rows.append((f"{_matrix([[doprint(a) for a in row] for row in jacobians])} {qdd} + {_column([printer.add(terms) for terms in biases])}", "0"))
        # an align* is as wide as its widest left side plus its widest right side
        if max(layout.width(a) for a, _ in rows) + _EQUALS + max(layout.width(b) for _, b in rows) <= layout.LINE_WIDTH:
            return "\\begin{align*}\n" + " \\\\\n".join(f"{a} &= {b}" for a, b in rows) + "\n\\end{align*}\n"
    return _matrix_entries(model, printer, entries, forcing, jacobians, biases)


def _matrix(rows: Sequence[Sequence[str]]) -> str:
    """A bracketed matrix of printed entries (as sympy's LaTeX printer writes one)."""
    body = " \\\\ ".join(" & ".join(row) for row in rows)
    return rf"\left[\begin{{matrix}}{body}\end{{matrix}}\right]"


def _column(entries: Sequence[str]) -> str:
    return _matrix([[entry] for entry in entries])


def _matrix_entries(model: Model, printer: TexPrinter, entries: dict[tuple[int, int], tuple[Expr, str]], forcing: list[list[Expr]], jacobians: list[list[Expr]], biases: list[list[Expr]]) -> str:
    n, k = model.n, len(model.constraints)
    doprint = printer.doprint
    bold_q = r"\ddot{\mathbf{q}}"
    multiplier_symbols = [to_symengine(s) for s in model.multipliers]
    statement = [layout.piece(r"\mathbf{F}")]
    if k:
        multipliers = _vector(multiplier_symbols, doprint) if k > 1 else [layout.piece(doprint(multiplier_symbols[0]))]
        statement += [layout.piece(r"+ \mathbf{A}^{T}"), *multipliers[:-1], layout.piece(multipliers[-1].tex + ","), layout.piece(rf"\quad \mathbf{{A}} {bold_q} + \mathbf{{c}} = 0")]
    rows = [Row(rf"\mathbf{{M}} {bold_q}", statement), Row(bold_q, _vector(model.symengine.qdd, doprint))]

    def index(*ij: int) -> str:
        return ("," if max(n, k) > 9 else "").join(str(i + 1) for i in ij)

    space = room([rf"\mathbf{{M}} {bold_q}", rf"\mathbf{{M}}_{{{index(n - 1, n - 1)}}}", rf"\mathbf{{A}}_{{{index(max(k - 1, 0), n - 1)}}}"])

    zero = False
    for i in range(n):
        for j in range(i, n):
            entry, tex = entries[i, j]
            if entry == 0:
                zero = True
                continue
            fits = layout.width(tex) <= space
            rows.append(Row(rf"\mathbf{{M}}_{{{index(i, j)}}}", [layout.piece(tex)] if fits else layout.pieces(entry, doprint, space)))
    rows.append(Row("", [layout.piece(r"\mathbf{M}_{ji} = \mathbf{M}_{ij}" + (r", \quad \mathrm{other}\ \mathbf{M}_{ij} = 0" if zero else ""))]))
    rows += [Row(rf"\mathbf{{F}}_{{{index(i)}}}", layout.terms(forcing[i] or [se.Integer(0)], doprint, space)) for i in range(n)]
    for r in range(k):
        rows += [Row(rf"\mathbf{{A}}_{{{index(r, j)}}}", layout.pieces(common_factor(a), doprint, space)) for j, a in enumerate(jacobians[r]) if a != 0]
        rows.append(Row(rf"\mathbf{{c}}_{{{index(r)}}}", layout.terms(biases[r] or [se.Integer(0)], doprint, space)))
    return align(rows)


def _vector(symbols: Sequence[Expr], doprint: layout.Printer) -> list[layout.Piece]:
    """`(s_1, s_2, ...)^T` as pieces, broken between components."""
    parts = [layout.piece(doprint(s) + ("," if i < len(symbols) - 1 else "")) for i, s in enumerate(symbols)]
    parts[0] = layout.piece(r"\left(" + parts[0].tex)
    parts[-1] = layout.piece(parts[-1].tex + r"\right)^{T}")
    return parts


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


class TexPrinter(SymenginePrinter):
    """Symengine expressions as LaTeX in the notation of sympy's LaTeX printer (`\\frac{k}{r^{2}}`,
    `\\sin{\\left(\\theta \\right)}`, `\\sqrt{k m}`), every name from `Names`; what it has no rule
    for is printed by `_Printer`. Terms and factors are ordered as in the text output (`keys`)."""

    _UNARY = frozenset(["sin", "cos", "tan", "cot", "sec", "csc", "sinh", "cosh", "tanh", "coth", "log"])
    functions: ClassVar[dict[str, str]] = {name: name for name in _UNARY}  # the others (asin, ...) as sympy writes them

    def __init__(self, known: Names) -> None:
        super().__init__()
        self._names = {str(symbol): tex for symbol, tex in known.symbols.items()}
        self._function_names = known.functions
        self._sympy = _Printer(known)
        self.keys = TextPrinter()

    def key(self, expr: Expr) -> tuple[object, ...]:
        return self.keys.key(expr)

    def factor_order(self, factors: Iterable[Expr]) -> list[Expr]:
        return self.keys.factor_order(factors)

    def symbol(self, name: str) -> str:
        found = self._names.get(name)
        return found if found is not None else symbol_tex(name.lstrip("_"))

    def rational(self, p: int, q: int) -> str:
        return ("- " if p < 0 else "") + rf"\frac{{{abs(p)}}}{{{q}}}"

    def pi(self) -> str:
        return r"\pi"

    def add(self, terms: Sequence[Expr]) -> str:
        out = ""
        for term in terms:
            printed = self.doprint(term)
            if not out:
                out = printed
            elif printed.startswith("-"):
                out += " - " + printed[1:].lstrip()
            else:
                out += " + " + printed
        return out or "0"

    def mul(self, expr: Expr) -> str:
        number, above, below = self.split(expr)
        sign = ""
        if number.is_negative:
            sign, number = "- ", -number
        top = [self._factor(f) for f in above]
        bottom = [self._factor(f) if len(below) > 1 else self.doprint(f) for f in below]
        if number != 1:
            if number.is_Rational and not number.is_Integer:
                if int(number.p) != 1:
                    top.insert(0, str(int(number.p)))
                bottom.insert(0, str(int(number.q)))
            else:
                top.insert(0, self.doprint(number))
        text = " ".join(top) or "1"
        if bottom:
            text = rf"\frac{{{text}}}{{{' '.join(bottom)}}}"
        return sign + text

    def _factor(self, factor: Expr) -> str:
        printed = self.doprint(factor)
        return rf"\left({printed}\right)" if factor.is_Add else printed

    def power(self, base: Expr, exponent: Expr) -> str:
        if exponent.is_Number and exponent.is_negative:
            return rf"\frac{{1}}{{{self.doprint(se.Pow(base, -exponent))}}}"
        if exponent.is_Rational and not exponent.is_Integer and int(exponent.q) == 2 and int(exponent.p) == 1:
            return rf"\sqrt{{{self.doprint(base)}}}"
        power = rf"\frac{{{int(exponent.p)}}}{{{int(exponent.q)}}}" if exponent.is_Rational and not exponent.is_Integer else self.doprint(exponent)
        kind = type(base).__name__
        if exponent.is_Integer and (kind in self._UNARY or kind == "FunctionSymbol"):
            return self._call(base, power)
        atomic = base.is_Symbol or (base.is_Integer and not base.is_negative) or (not base.is_Add and not base.is_Mul and not base.is_Pow and not base.is_Number)
        printed = self.doprint(base) if atomic else r"\left(" + self.doprint(base) + r"\right)"
        return f"{printed}^{{{power}}}"

    def exp(self, exponent: Expr) -> str:
        return f"e^{{{self.doprint(exponent)}}}"

    def function(self, name: str, args: Sequence[Expr], undefined: bool = False) -> str:
        head = (self._function_names.get(name) or _function(name, False)) if undefined else f"\\{name}"
        return head + r"{\left(" + ",".join(self.doprint(a) for a in args) + r" \right)}"

    def _call(self, base: Expr, power: str) -> str:
        name = base.get_name() if type(base).__name__ == "FunctionSymbol" else type(base).__name__
        head = (self._function_names.get(name) or _function(name, False)) if type(base).__name__ == "FunctionSymbol" else f"\\{name}"
        return head + f"^{{{power}}}" + r"{\left(" + ",".join(self.doprint(a) for a in base.args) + r" \right)}"

    def fallback(self, expr: object) -> str:
        return str(self._sympy.doprint(expr))


def names(model: Model, momenta: Sequence[sp.Symbol] = ()) -> Names:
    """Coordinates, their velocities and accelerations (`\\dot{\\theta}_{1}`), parameters, time,
    multipliers (`\\lambda_{\\mathrm{roll},x}`), functions, and the momenta `p_{q}` of `info`
    when given. Names that would print alike (`x_1` and `x1`) are written out literally
    (`\\mathit{x\\_1}`, `\\mathit{x1}`)."""
    functions = sorted(_applied_functions(model) | set(model.definitions))
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


def _applied_functions(model: Model) -> set[str]:
    """The names of the undefined functions the equations apply (read from `Model.symengine`)."""
    forms = model.symengine
    found = {f.get_name() for e in (*(m for row in forms.mass for m in row), *forms.forcing, forms.lagrangian, forms.dissipation, *forms.generalized_forces) for f in e.atoms(se.FunctionSymbol)}
    return found | {str(f.func) for c in model.constraints for f in c.expr.atoms(sp.core.function.AppliedUndef)}
