"""Equations that fit the page: an estimate of the printed width of LaTeX math, and a line
breaker that splits an expression (symengine, printed by a `common.SymenginePrinter`, for the
equations; sympy, printed by a sympy printer, for the solved form and `info`) at its terms (and, when one term is still too wide,
inside its parentheses and fractions) so that every line of an `align*` fits the `\\linewidth`
of a standard `article` (345 pt at 10 pt).

The estimate reads the LaTeX text once (linear in its length) and counts in units of about
one math-italic letter; each term is printed and measured once, and a term too wide for a line
once more in its pieces (whose operators and parentheses add their widths without re-reading
the pieces), so laying out an equation costs about as much as printing it.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import sympy as sp

from lagrange_cli._symengine import se
from lagrange_cli.emit import common

# One unit is about the width of an average math-italic letter at 10 pt (calibrated against
# pdflatex on the bundled systems' terms; see tests/test_latex_layout.py).
UNIT_PT = 5.0
# \linewidth of a standard article at 10 pt, in units, with a margin for the estimate's error.
LINE_WIDTH = 345.0 / UNIT_PT * 0.92
QUAD = 2.0  # \quad (1 em)
# Between logical rows of an environment with more lines than this, a page may break.
BREAKABLE_LINES = 24

_SCALE = (1.0, 1.0, 0.7, 0.5)  # display, text, script, scriptscript
_SCRIPT = (2, 2, 3, 3)  # the style of a superscript or subscript
_FRACTION = (1, 2, 3, 3)  # the style of a numerator or denominator
_BINARY = {"+": 2.45, "-": 2.45, "=": 2.7, "<": 2.7, ">": 2.7, "cdot": 1.55, "times": 2.45, "pm": 2.45, "mp": 2.45, "le": 2.7, "ge": 2.7}
_UNARY = 1.56
_SPACES = {",": 0.33, ":": 0.44, ";": 0.56, "!": -0.33, "quad": QUAD, "qquad": 2 * QUAD, " ": 0.66}
_DELIMITER = 0.78
_SIZED = {"bigl": 0.9, "bigr": 0.9, "Bigl": 1.15, "Bigr": 1.15, "big": 0.9, "Big": 1.15, "biggl": 1.4, "biggr": 1.4}
_WRAPPERS = frozenset(["mathit", "mathrm", "mathbf", "boldsymbol", "mathcal", "mathscr", "mathsf", "text", "operatorname", "dot", "ddot", "hat", "bar", "tilde", "vec", "overline"])
_UPRIGHT = frozenset(["sin", "cos", "tan", "cot", "sec", "csc", "arcsin", "arccos", "arctan", "sinh", "cosh", "tanh", "coth", "log", "ln", "exp", "det", "min", "max"])
_MATRICES = frozenset(["matrix", "pmatrix", "bmatrix", "vmatrix", "Bmatrix", "smallmatrix", "array"])
# Widths of math-italic letters and digits at 10 pt (cmmi10, cmr10), in points.
_LETTERS_PT = dict(
    zip(
        "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ",
        (
            5.3,
            4.3,
            4.3,
            5.2,
            4.7,
            4.9,
            4.8,
            5.8,
            3.5,
            4.1,
            5.2,
            3.0,
            8.8,
            6.0,
            4.9,
            5.0,
            4.5,
            4.5,
            4.7,
            3.6,
            5.7,
            4.9,
            7.2,
            5.7,
            4.9,
            4.7,
            7.5,
            7.6,
            7.2,
            8.3,
            7.4,
            6.4,
            7.9,
            8.3,
            4.4,
            5.5,
            8.5,
            6.8,
            9.7,
            8.0,
            7.6,
            6.4,
            7.9,
            7.6,
            6.1,
            5.8,
            6.8,
            5.8,
            9.4,
            8.3,
            5.8,
            6.8,
        ),
        strict=True,
    )
)
_COMMAND = re.compile(r"\\([A-Za-z]+|.)")
# The width of each letter and digit in units at display size (the reader's fast path).
_PLAIN = {char: _LETTERS_PT.get(char, 5.0) * 1.04 / UNIT_PT for char in "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"}


def width(tex: str) -> float:
    """The estimated width of the math `tex` in display style, in units (`UNIT_PT` points).
    Monotone: appending anything never makes it narrower. Short texts (the pieces of broken
    sums, `+ m_{17}`, recur by the thousand in a big system) are measured once."""
    if len(tex) > _SHORT:
        return _Reader(tex).sequence(0)
    found = _measured.get(tex)
    if found is None:
        if len(_measured) > 100_000:
            _measured.clear()
        found = _measured[tex] = _Reader(tex).sequence(0)
    return found


_SHORT = 48
_PARENTHESIS = 1.0  # `\\left(` or `\\right)` at display size
_measured: dict[str, float] = {}


class _Reader:
    """A one-pass reader of the LaTeX that sympy's printer and this package write."""

    def __init__(self, tex: str) -> None:
        self.tex = tex
        self.i = 0

    def sequence(self, style: int, stop: str = "}") -> float:
        """Read up to an unmatched `stop` (consumed) or the end; return the width."""
        total = 0.0
        operand = False  # the previous atom is an operand: a following + or - is binary
        tex, scale = self.tex, _SCALE[style]
        end = len(tex)
        while self.i < end:
            char = tex[self.i]
            plain = _PLAIN.get(char)
            if plain is not None:  # a letter or digit (most of the text): the fast path
                self.i += 1
                total += plain * scale
                operand = True
                continue
            if char == " ":
                self.i += 1
                continue
            if char in stop:
                self.i += 1
                return max(total, 0.0)
            self.i += 1
            if char == "{":
                total += self.sequence(style)
                operand = True
            elif char in "^_":
                total += self.argument(_SCRIPT[style])
            elif char == "\\":
                name = self.command()
                added, operand = self.macro(name, style, operand)
                total += added
            elif char in "+-=<>":
                total += (_BINARY[char] if operand and style < 2 else _UNARY if char in "+-" else 1.56) * scale
                operand = False
            elif char in "()[]|":
                total += _DELIMITER * scale
                operand = char in ")]|"
            elif char == ",":
                total += 0.55 * scale
                operand = False
            elif char in " &\n\t~'":
                total += 0.55 * scale if char == "'" else 0.0
            else:
                total += _LETTERS_PT.get(char, 5.0) * 1.04 / UNIT_PT * scale
                operand = True
        return max(total, 0.0)

    def command(self) -> str:
        match = _COMMAND.match(self.tex, self.i - 1)
        if match is None:
            return ""
        self.i = match.end()
        return match.group(1)

    def argument(self, style: int) -> float:
        """One argument: a `{...}` group, a command, or a character."""
        while self.i < len(self.tex) and self.tex[self.i] == " ":
            self.i += 1
        if self.i >= len(self.tex):
            return 0.0
        char = self.tex[self.i]
        self.i += 1
        if char == "{":
            return self.sequence(style)
        if char == "\\":
            return self.macro(self.command(), style, False)[0]
        return _LETTERS_PT.get(char, 5.0) * 1.04 / UNIT_PT * _SCALE[style]

    def delimiter(self) -> None:
        while self.i < len(self.tex) and self.tex[self.i] == " ":
            self.i += 1
        if self.i < len(self.tex):
            self.i += 1
            if self.tex[self.i - 1] == "\\":
                self.command()

    def macro(self, name: str, style: int, operand: bool) -> tuple[float, bool]:
        """The width of the command `name` (its arguments read) and whether it is an operand."""
        scale = _SCALE[style]
        if name in ("frac", "dfrac", "tfrac"):
            inner = _FRACTION[0 if name == "dfrac" else 1 if name == "tfrac" else style]
            return max(self.argument(inner), self.argument(inner)) + 0.4 * scale, True
        if name in ("left", "right"):
            self.delimiter()
            return 1.0 * scale, name == "right"
        if name in _SIZED:
            self.delimiter()
            return _SIZED[name] * scale, name.endswith("r")
        if name in _BINARY:
            return (_BINARY[name] if operand and style < 2 else 1.0) * scale, False
        if name in _SPACES:
            return _SPACES[name] * scale, operand
        if name in _WRAPPERS:
            return self.argument(style) * (0.95 if name in ("text", "mathrm", "operatorname") else 1.0) + (0.33 * scale if name == "operatorname" else 0.0), True
        if name in _UPRIGHT:
            return (0.85 * len(name) + 0.33) * scale, True
        if name == "begin":
            return self.environment(style), True
        if name in ("ldots", "cdots", "dots"):
            return 2.8 * scale, True
        if name == "displaybreak":
            if self.tex.startswith("[", self.i):
                self.i = self.tex.find("]", self.i) + 1 or len(self.tex)
            return 0.0, operand
        if name in ("limits", "nolimits", "displaystyle", "textstyle"):
            return 0.0, operand
        return (1.55 if name == "perp" else 1.25) * scale, True  # a Greek letter, \perp, \{, ...

    def environment(self, style: int) -> float:
        """A matrix: the sum of its widest cell per column, plus the gaps between columns."""
        match = re.match(r"\{(\w+\*?)\}", self.tex[self.i :])
        if match is None:
            return 0.0
        env = match.group(1)
        self.i += match.end()
        end = self.tex.find(f"\\end{{{env}}}", self.i)
        body = self.tex[self.i : end if end >= 0 else len(self.tex)]
        self.i = end + len(f"\\end{{{env}}}") if end >= 0 else len(self.tex)
        if env.rstrip("*") not in _MATRICES:
            return width(body)
        if env == "array":
            body = re.sub(r"^\{[^}]*\}", "", body)
        inner = 2 if env == "smallmatrix" else 1 if style == 0 else style
        columns: list[float] = []
        for row in _split_top(body, "\\\\"):
            for k, cell in enumerate(_split_top(row, "&")):
                reader = _Reader(cell)
                cell_width = reader.sequence(inner)
                if k < len(columns):
                    columns[k] = max(columns[k], cell_width)
                else:
                    columns.append(cell_width)
        return sum(columns) + 2.0 * max(len(columns) - 1, 0) * _SCALE[style] + (1.6 if env != "matrix" else 0.0)


def _split_top(text: str, separator: str) -> list[str]:
    """`text` split at `separator` outside braces and nested environments."""
    parts, depth, start, i = [], 0, 0, 0
    while i < len(text):
        if text.startswith("\\begin", i):
            depth += 1
        elif text.startswith("\\end", i):
            depth -= 1
        char = text[i]
        if char == "\\" and not text.startswith(separator, i):
            i += 2
            continue
        if char == "{":
            depth += 1
        elif char == "}":
            depth -= 1
        elif depth == 0 and text.startswith(separator, i):
            parts.append(text[start:i])
            i += len(separator)
            start = i
            continue
        i += 1
    parts.append(text[start:])
    return parts


# --- breaking -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Piece:
    """A run of printed math that is never broken, and its estimated width. A piece after the
    first of a sum starts with its operator (`+ ...`, `- ...`)."""

    tex: str
    width: float


Printer = Callable[[Any], str]


def piece(tex: str) -> Piece:
    return Piece(tex, width(tex))


def pieces(expr: Any, doprint: Printer, room: float) -> list[Piece]:
    """`expr` as pieces that a line of `room` units can hold where possible: the terms of a
    sum, and inside a term too wide for a line, the terms of its widest parenthesized sum or of
    its numerator (`\\frac{1}{D} \\left( N \\right)`). `expr` is a sympy expression printed by a
    sympy printer, or a symengine one printed by a `common.SymenginePrinter` (big systems)."""
    if expr.is_Add:
        return _sum(expr, doprint, room)
    if _at_least(expr) > room:  # surely too wide: only its pieces are measured
        negative = _negative(expr)
        inner = _term(-expr if negative else expr, doprint, room)
        if inner:
            return [Piece("- " + inner[0].tex, inner[0].width + _UNARY), *inner[1:]] if negative else inner
    measured = piece(doprint(expr))
    if measured.width <= room:
        return [measured]
    if _negative(expr):  # the sign goes in front: - \frac{1}{D} (...), not \frac{1}{D} - (...)
        inner = _term(-expr, doprint, room)
        return [Piece("- " + inner[0].tex, inner[0].width + _UNARY), *inner[1:]] if inner else [measured]
    return _term(expr, doprint, room) or [measured]


def _at_least(expr: Any) -> float:
    """A lower bound of the printed width of a product: each sum among its factors is printed in
    parentheses at full size, with a binary operator (`_BINARY`) between its terms."""
    if not expr.is_Mul:
        return 0.0
    return sum(_BINARY["+"] * (len(factor.args) - 1) for factor in expr.args if factor.is_Add)


def _sum(expr: Any, doprint: Printer, room: float) -> list[Piece]:
    return terms(_ordered(expr, doprint), doprint, room)


def terms(summands: Sequence[Any], doprint: Printer, room: float) -> list[Piece]:
    """The sum of `summands`, in their order, as pieces (see `pieces`)."""
    out: list[Piece] = []
    for term in summands:
        negative = _negative(term)
        inner = pieces(-term if negative else term, doprint, room)
        sign = "- " if negative else "+ " if out else ""
        first = inner[0]
        if first.tex.startswith("- "):  # a piece that carries its own minus (a product whose other factors print negative): the signs combine
            first = Piece(first.tex[2:], first.width - _UNARY)
            sign = "+ " if negative and out else "" if negative else "- "
        if sign:  # measured alone its operator is unary (a sign in front of a text adds exactly that); between terms it is binary, wider
            first = Piece(sign + first.tex, first.width + _UNARY + (_BINARY["+"] - _UNARY if out else 0.0))
        out += [first, *inner[1:]]
    return out


def _sympy(expr: Any) -> bool:
    return isinstance(expr, sp.Basic)


def _negative(expr: Any) -> bool:
    """The term is printed with a minus in front."""
    return bool(expr.could_extract_minus_sign()) if _sympy(expr) else common.negative(expr)


def _ordered(expr: Any, doprint: Printer) -> list[Any]:
    """The terms of a sum in the order the printer writes them."""
    owner = doprint if isinstance(doprint, common.SymenginePrinter) else getattr(doprint, "__self__", None)
    if isinstance(owner, common.SymenginePrinter):
        return owner.order(expr.args)
    if not _sympy(expr):
        return sorted(expr.args, key=str)
    if owner is not None and hasattr(owner, "_as_ordered_terms"):
        return list(owner._as_ordered_terms(expr, order=None))
    return list(expr.as_ordered_terms())


def _fraction(expr: Any) -> tuple[Any, Any]:
    """(numerator, denominator) as written, without combining anything."""
    if _sympy(expr):
        return sp.fraction(expr, exact=True)
    if expr.is_Pow and expr.args[1].is_Number and expr.args[1].is_negative and expr.args[0] != se.E:
        return se.Integer(1), se.Pow(expr.args[0], -expr.args[1])
    if not expr.is_Mul:
        return expr, se.Integer(1)
    top, bottom = [], []
    for factor in expr.args:
        if factor.is_Rational and not factor.is_Integer:
            top.append(se.Integer(int(factor.p)))
            bottom.append(se.Integer(int(factor.q)))
        elif factor.is_Pow and factor.args[1].is_Number and factor.args[1].is_negative and factor.args[0] != se.E:
            bottom.append(se.Pow(factor.args[0], -factor.args[1]))
        else:
            top.append(factor)
    return se.Mul(*top), se.Mul(*bottom)


def _product(factors: Sequence[Any], like: Any) -> Any:
    if _sympy(like):
        return sp.Mul(*factors, evaluate=False) if factors else sp.Integer(1)
    return se.Mul(*factors)


def _power_of_sum(expr: Any) -> bool:
    return bool(expr.is_Pow and expr.args[0].is_Add and expr.args[1].is_Rational and expr.args[1].is_positive)


def _term(expr: Any, doprint: Printer, room: float) -> list[Piece] | None:
    """A too-wide product or quotient broken inside its widest sum, or None."""
    numerator, denominator = _fraction(expr)
    if denominator != 1:
        top = pieces(numerator, doprint, room)
        # a sum is wrapped in parentheses; a product's pieces already hold their own
        wrapped = _wrap(top, "", "") if numerator.is_Add else top
        bottom_tex = doprint(denominator)
        if width(bottom_tex) <= room / 2:
            if len(top) == 1:
                return None
            prefix = rf"\frac{{1}}{{{bottom_tex}}} "
            return _wrap(top, prefix, "") if numerator.is_Add else [piece(prefix + top[0].tex), *top[1:]]
        bottom = pieces(denominator, doprint, room)
        if len(top) == 1 and len(bottom) == 1:
            return None
        return [*wrapped, *(_wrap(bottom, "/ ", "") if denominator.is_Add or len(bottom) == 1 else [piece("/ " + bottom[0].tex), *bottom[1:]])]
    if not expr.is_Mul:
        if _power_of_sum(expr):
            return _wrap(_sum(expr.args[0], doprint, room), "", f"^{{{doprint(expr.args[1])}}}")
        return None
    factors = list(expr.args)
    widest = max(range(len(factors)), key=lambda k: len(doprint(factors[k])) if factors[k].is_Add or factors[k].is_Pow else -1)
    target = factors[widest]
    if not (target.is_Add or _power_of_sum(target)):
        return None
    rest = _product(factors[:widest] + factors[widest + 1 :], expr)
    before: list[Piece] = []
    prefix = "" if rest == 1 else "- " if rest == -1 else doprint(rest) + " "
    if width(prefix) > room / 2:  # the other factors hold sums of their own (a product of several long sums): broken too
        before = pieces(rest, doprint, room)
        prefix, before = before[-1].tex + " ", before[:-1]
    if target.is_Add:
        return [*before, *_wrap(_sum(target, doprint, room), prefix, "")]
    return [*before, *_wrap(_sum(target.args[0], doprint, room), prefix, f"^{{{doprint(target.args[1])}}}")]


def _wrap(inner: list[Piece], prefix: str, suffix: str) -> list[Piece]:
    """`prefix ( inner ) suffix`; when `inner` spans pieces, its parentheses may end up on
    different lines, which `lines` balances with `\\right.` and `\\left.`. Widths add up (the
    reader's state does not cross `\\left(` or `\\right)`), so `inner` is not measured again."""
    before = width(prefix) + _PARENTHESIS
    after = _PARENTHESIS + width(suffix)
    if len(inner) == 1:
        return [Piece(rf"{prefix}\left({inner[0].tex}\right){suffix}", before + inner[0].width + after)]
    # nested products would pile their factors onto one first piece: a wide opening stands apart
    apart = before + inner[0].width > LINE_WIDTH / 2
    opening = [Piece(prefix + r"\left(", before), inner[0]] if apart else [Piece(prefix + r"\left(" + inner[0].tex, before + inner[0].width)]
    return [*opening, *inner[1:-1], Piece(inner[-1].tex + rf"\right){suffix}", inner[-1].width + after)]


def lines(parts: Sequence[Piece], first: float, rest: float) -> list[str]:
    """Pack pieces greedily into lines, the first `first` units wide and the others `rest`.
    Never an empty line: a piece wider than its line stands alone on it."""
    out: list[list[str]] = []
    used = 0.0
    for part in parts:
        if out and used + part.width <= (first if len(out) == 1 else rest):
            out[-1].append(part.tex)
            used += part.width
        else:
            out.append([part.tex])
            used = part.width
    texts = [" ".join(line) for line in out]
    # `{}` before the operator that starts a continuation line keeps it binary (spaced).
    texts[1:] = ["{}" + text if text.startswith(("+ ", "- ")) else text for text in texts[1:]]
    return _balanced(texts) or ["0"]


_LEFT_RIGHT = re.compile(r"\\(left|right)(?![A-Za-z])")


def _balanced(texts: list[str]) -> list[str]:
    """Close the `\\left` delimiters still open at the end of a line with `\\right.` and open
    them again on the next line with `\\left.` (each line of an `align*` is typeset alone)."""
    out, carried = [], 0
    for text in texts:
        depth = carried
        for match in _LEFT_RIGHT.finditer(text):
            depth += 1 if match.group(1) == "left" else -1
        out.append(r"\left. " * carried + text + r" \right." * max(depth, 0))
        carried = max(depth, 0)
    return out
