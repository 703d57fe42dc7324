"""YAML in, a composed node tree out, and where each node is written in the file.

The file is composed, not constructed, so every node keeps its line and column; `Source`
maps a node (or a character of a scalar's value) back to its file:line:col, also when YAML
changed the text on the way (folded or block scalars, escapes in quotes)."""

from __future__ import annotations

import re
from typing import Any

import yaml

from lagrange_cli.errors import LagrangeError, Span, fail

MAX_YAML_DEPTH = 40
MAX_YAML_VALUES = 20_000
STANDARD_TAGS = {f"tag:yaml.org,2002:{kind}" for kind in ("str", "int", "float", "bool", "null", "seq", "map")}
IMPLICIT_TAGS = {"tag:yaml.org,2002:timestamp": "a date", "tag:yaml.org,2002:merge": "a merge key", "tag:yaml.org,2002:value": "a value key"}
LINE_BREAK = re.compile("\r\n|[\r\n\x85\u2028\u2029]")
ESCAPES = {
    "0": "\0", "a": "\a", "b": "\b", "t": "\t", "\t": "\t", "n": "\n", "v": "\v", "f": "\f", "r": "\r", "e": "\x1b", " ": " ",
    '"': '"', "/": "/", "\\": "\\", "N": "\x85", "_": "\xa0", "L": "\u2028", "P": "\u2029",
}  # fmt: skip
COMMA_AFTER = re.compile(r"[ \t\r\n]*,")


def _compose(text: str, filename: str) -> yaml.Node:
    """The YAML tree of `text`. An ASCII file that libyaml reads without a problem is read by libyaml
    (30 times faster: it matters for a 60-link chain); anything else, and every error message, comes
    from pyyaml's own reader, whose marks count characters (libyaml's count bytes)."""
    fast = getattr(yaml, "CSafeLoader", None)
    if fast is not None and text.isascii():
        try:
            root = _composed(text, filename, fast)
        except (yaml.YAMLError, LagrangeError, RecursionError):
            pass
        else:
            _plain_style(root)
            return root
    return _composed(text, filename, yaml.SafeLoader)


def _plain_style(root: yaml.Node) -> None:
    """libyaml marks a plain scalar with style '' where pyyaml has None: make them alike."""
    stack = [root]
    while stack:
        node = stack.pop()
        if isinstance(node, yaml.ScalarNode):
            if node.style == "":
                node.style = None
        elif isinstance(node, yaml.SequenceNode):
            stack.extend(node.value)
        elif isinstance(node, yaml.MappingNode):
            stack.extend(item for pair in node.value for item in pair)


def _composed(text: str, filename: str, loader: Any) -> yaml.Node:
    lines = text.splitlines()

    def span(mark: Any) -> Span:
        line = lines[mark.line] if mark.line < len(lines) else ""
        return Span(filename, mark.line + 1, mark.column + 1, line)

    span_at_start = Span(filename, 1, 1, lines[0] if lines else "")

    try:
        # Check the event stream before building anything: aliases (billion laughs), deep
        # nesting (the composer recurses) and sheer size are refused at their first sign.
        depth = 0
        for count, event in enumerate(yaml.parse(text, Loader=loader)):
            if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None):
                raise fail(span(event.start_mark), "YAML anchors and aliases are not supported", "plain values written out in full")
            if isinstance(event, yaml.CollectionStartEvent):
                depth += 1
                if depth > MAX_YAML_DEPTH:
                    raise fail(span(event.start_mark), f"YAML is nested more than {MAX_YAML_DEPTH} levels deep", "a map of the documented keys, with lists and maps nested a few levels at most")
            elif isinstance(event, yaml.CollectionEndEvent):
                depth -= 1
            if count > MAX_YAML_VALUES:
                raise fail(span(event.start_mark), f"the file holds more than {MAX_YAML_VALUES} YAML values", "a system file of a reasonable size")
        root = yaml.compose(text, Loader=loader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        message = f"malformed YAML: {exc.problem or exc.context}"
        if exc.problem and exc.context and exc.context_mark and exc.problem_mark and exc.context_mark.line != exc.problem_mark.line:
            message += f" ({exc.context} that starts at line {exc.context_mark.line + 1}, column {exc.context_mark.column + 1})"
        raise fail(span(mark) if mark else span_at_start, message, "valid YAML, a map of keys such as `coordinates:`") from None
    except yaml.reader.ReaderError as exc:
        before = LINE_BREAK.split(text[: exc.position])
        where = Span(filename, len(before), len(before[-1]) + 1, lines[len(before) - 1] if len(before) <= len(lines) else "")
        code = exc.character if isinstance(exc.character, int) else ord(exc.character)
        raise fail(where, f"control character U+{code:04X} is not allowed in YAML", "printable text (tabs and line breaks are fine)") from None
    except yaml.YAMLError as exc:
        raise fail(span_at_start, f"malformed YAML: {exc}", "valid YAML") from None
    except RecursionError:
        raise fail(span_at_start, "YAML is nested too deeply", "a flat map of the documented keys") from None
    if root is None:
        raise fail(span_at_start, "the file is empty", "a map with at least `coordinates:`")
    return root


class Source:
    """The text of a system file and the positions of its composed nodes."""

    def __init__(self, filename: str, text: str) -> None:
        self.filename = filename
        self.text = text
        self.lines = text.splitlines()

    def span(self, node: yaml.Node) -> Span:
        mark = node.start_mark
        line = self.lines[mark.line] if mark.line < len(self.lines) else ""
        return Span(self.filename, mark.line + 1, mark.column + 1, line)

    def where(self, node: yaml.Node) -> Span:
        """Where a value is written: the start of a scalar's text, or of a list or map."""
        return self.text_span(node) if isinstance(node, yaml.ScalarNode) else self.span(node)

    def text_span(self, node: yaml.ScalarNode) -> Span:
        """Where the scalar's text starts (after an opening quote)."""
        return self.span(node).shifted(1 if node.style in ("'", '"') else 0)

    def locate(self, node: yaml.ScalarNode, offset: int) -> Span:
        """Where character `offset` of the scalar's value is in the file, also when YAML changed
        the text on the way: a folded multi-line or block scalar, or escapes in quotes.

        The value's non-blank characters appear in the source in the same order (after
        undoing escapes), so the two are walked side by side, skipping blanks."""
        units = self._source_units(node)
        value = node.value
        wanted = sum(1 for c in value[:offset] if not c.isspace())
        visible = [c for c in value if not c.isspace()]
        if units is None or [c for _, _, c in units] != visible:
            return self.text_span(node)
        if offset < len(value) and not value[offset].isspace() and wanted < len(units):
            index = units[wanted][0]
        elif wanted > 0:
            index = units[wanted - 1][1]  # just after the last thing before `offset`
        else:
            return self.text_span(node)
        start = node.start_mark
        breaks = list(LINE_BREAK.finditer(self.text, start.index, index))
        line = start.line + len(breaks)
        column = index - breaks[-1].end() if breaks else start.column + index - start.index
        return Span(self.filename, line + 1, column + 1, self.lines[line] if line < len(self.lines) else "")

    def _source_units(self, node: yaml.ScalarNode) -> list[tuple[int, int, str]] | None:
        """The non-blank characters of a scalar's source as (start, end, character), escapes decoded."""
        text, i, end = self.text, node.start_mark.index, node.end_mark.index
        if node.style in ("|", ">"):
            header = LINE_BREAK.search(text, i, end)
            if header is None:
                return None
            i = header.end()
        elif node.style in ("'", '"'):
            i, end = i + 1, end - 1
        units = []
        while i < end:
            c, size = text[i], 1
            if node.style == "'" and text.startswith("''", i):
                size = 2
            elif node.style == '"' and c == "\\" and i + 1 < end:
                kind = text[i + 1]
                width = {"x": 2, "u": 4, "U": 8}.get(kind)
                if width is not None:
                    try:
                        c, size = chr(int(text[i + 2 : i + 2 + width], 16)), 2 + width
                    except ValueError:
                        return None
                elif kind in ESCAPES:
                    c, size = ESCAPES[kind], 2
                elif LINE_BREAK.match(text, i + 1):
                    c, size = " ", 1 + len(LINE_BREAK.match(text, i + 1).group())  # type: ignore[union-attr]
                else:
                    return None
            if not c.isspace():
                units.append((i, i + size, c))
            i += size
        return units

    def split_by_comma(self, node: yaml.Node) -> bool:
        """A plain scalar of a flow list or map that a comma cut out of a longer expression,
        e.g. `f(x` and `y)` from `[f(x, y)]`: its brackets do not balance and a comma is next to it."""
        if not isinstance(node, yaml.ScalarNode) or node.style is not None:
            return False
        balance = sum(node.value.count(c) for c in "([{") - sum(node.value.count(c) for c in ")]}")
        if balance == 0:
            return False
        if balance > 0:
            return COMMA_AFTER.match(self.text, node.end_mark.index) is not None
        i = node.start_mark.index - 1
        while i >= 0 and self.text[i] in " \t\r\n":
            i -= 1
        return i >= 0 and self.text[i] == ","


def kind(node: yaml.Node | None) -> str:
    if isinstance(node, yaml.SequenceNode):
        return "a list"
    if isinstance(node, yaml.MappingNode):
        return "a map"
    if isinstance(node, yaml.ScalarNode):
        kind = node.tag.rsplit(":", 1)[-1]
        return {"null": "nothing", "str": f"the text '{node.value}'", "bool": f"the boolean '{node.value}'"}.get(kind, f"the number {node.value}")
    return "nothing"
