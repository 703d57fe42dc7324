"""Errors raised by the library; the CLI catches `LagrangeError` and nothing else."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass


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
        return f"{self.file}:{self.line}:{self.column}"


@dataclass(frozen=True)
class Diagnostic:
    """One problem: where, what is wrong, and what was expected instead."""

    span: Span | None
    message: str
    expected: str = ""

    def render(self) -> str:
        where = f"{self.span}: " if self.span else ""
        lines = [f"{where}error: {self.message}"]
        if self.span and self.span.text:
            lines.append("    " + self.span.text)
            pad = "".join(c if c == "\t" else " " for c in self.span.text[: self.span.column - 1])  # tabs stay tabs, so the caret lines up
            lines.append("    " + pad.ljust(self.span.column - 1) + "^")
        if self.expected:
            lines.append(f"  expected: {self.expected}")
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
