"""Errors raised by the library; the CLI catches `LagrangeError` and nothing else."""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass

# Characters that steer a terminal or change how text reads rather than show as themselves: the
# controls (C0, DEL, C1), the format characters (bidi embeddings, overrides, marks and isolates,
# zero-width spaces and joiners, the BOM), lone surrogates (an undecodable file name), and the
# line and paragraph separators. Candidates are found by a fast pattern, then told by category.
_CANDIDATE = re.compile(r"[^\x20-\x7e]")
_STEERING = frozenset(("Cc", "Cf", "Cs", "Zl", "Zp"))


def printable(text: str, *, keep: str = "\n\t") -> str:
    """`text` with every character that could steer a terminal or disguise text (an escape
    sequence, a carriage return, a backspace, a bidi override, a zero-width space, a C1 control,
    an undecodable byte) written as a visible escape such as `\\x1b` or `\\u202e`, so that file
    text shown to a user is only ever text. The characters in `keep` stay: newlines and tabs in a
    message; none in a name or a path (`keep=""`), so that a name cannot start a fake line."""

    def visible(match: re.Match[str]) -> str:
        char = match.group()
        if char in keep or unicodedata.category(char) not in _STEERING:
            return char
        code = ord(char)
        return {9: "\\t", 10: "\\n", 13: "\\r"}.get(code) or (f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}")

    return _CANDIDATE.sub(visible, text)


@dataclass(frozen=True)
class Span:
    """A place in a source file: 1-based line and column, plus that line's text."""

    file: str
    line: int
    column: int
    text: str = ""

    def shifted(self, columns: int) -> Span:
        """The same line, `columns` characters further right."""
        return Span(self.file, self.line, self.column + columns, self.text)

    def __str__(self) -> str:
        return f"{printable(self.file, keep='')}:{self.line}:{self.column}"


@dataclass(frozen=True)
class Diagnostic:
    """One problem: where, what is wrong, and what was expected instead."""

    span: Span | None
    message: str
    expected: str = ""

    def render(self) -> str:
        """`file:line:col: error: message`, the source line with a caret under the column, and
        `expected: ...`; file text in any part is shown through `printable`."""
        where = f"{self.span}: " if self.span else ""
        lines = [f"{where}error: {printable(self.message) or 'invalid input here'}"]
        if self.span and self.span.text:
            before = [printable(c, keep="\t") for c in self.span.text[: self.span.column - 1]]
            lines.append("    " + "".join(before) + printable(self.span.text[self.span.column - 1 :], keep="\t"))
            pad = "".join(c if c == "\t" else " " * len(c) for c in before)  # tabs stay tabs and escapes take their width, so the caret lines up
            lines.append("    " + pad.ljust(self.span.column - 1) + "^")
        if self.expected:
            lines.append(f"  expected: {printable(self.expected)}")
        return "\n".join(lines)


class LagrangeError(Exception):
    """Base of every error this package raises on purpose; its text says how to fix it."""

    exit_code = 2


class SpecError(LagrangeError, ValueError):
    """A system file is not valid; carries every problem found, not just the first."""

    def __init__(self, diagnostics: Iterable[Diagnostic]) -> None:
        self.diagnostics = tuple(diagnostics)
        super().__init__("\n".join(d.render() for d in self.diagnostics))


class DerivationError(LagrangeError, ValueError):
    """The equations cannot be put in the requested form (e.g. a singular mass matrix)."""


def fail(span: Span | None, message: str, expected: str = "") -> SpecError:
    """The one helper for a single-problem error: `raise fail(span, "...", "...")`."""
    return SpecError([Diagnostic(span, message, expected)])
