"""What the section readers share: the problems found so far, and reading a node as a map, a list,
a name, a number or an expression, each problem recorded at its place in the file."""

from __future__ import annotations

import keyword
import re
from collections.abc import Callable
from typing import TYPE_CHECKING

import sympy as sp
import yaml

from lagrange_cli.errors import Diagnostic, Span, SpecError
from lagrange_cli.expr import CONSTANTS, RESERVED, Scope, _closest, numeric_value, parse_equation, parse_expression
from lagrange_cli.frontend.source import IMPLICIT_TAGS, MAX_YAML_DEPTH, STANDARD_TAGS, Source
from lagrange_cli.frontend.source import kind as _kind

if TYPE_CHECKING:
    from lagrange_cli.rigid import Places

NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
FLOW_HINT = '; a comma inside a flow list `[...]` or map `{...}` splits an expression in two: quote it (`"atan2(y, x)"`) or write the list as a block list, one `- item` per line'


class ReaderCore(Source):
    """Walks the composed YAML tree, collecting diagnostics instead of stopping at the first."""

    places: Places

    def __init__(self, filename: str, text: str) -> None:
        super().__init__(filename, text)
        self.problems: list[Diagnostic] = []
        self.spans: dict[str, Span] = {}
        self.sources: dict[str, Span] = {}
        self.split_head: int | None = None  # where the last reported `f(x` of a split `[f(x, y)]` ends

    def parsed(self, node: yaml.ScalarNode, text: str, parser: Callable[[str, Span, Scope], sp.Expr], scope: Scope) -> sp.Expr | None:
        """Run an expression parser on a scalar, recording its problems at their place in the file."""
        base = self.text_span(node)
        try:
            return parser(text, base, scope)
        except SpecError as exc:
            split = self.split_by_comma(node)
            if split and node.value.count("(") > node.value.count(")"):
                self.split_head = node.end_mark.index
            elif split and self.split_head is not None and not any(c in "[]{}" for c in self.text[self.split_head : node.start_mark.index]):
                return None  # the second half of an expression whose first half was reported
            for d in exc.diagnostics:
                span = d.span
                if span is not None and span.file == base.file and span.line == base.line:
                    span = self.locate(node, span.column - base.column)
                self.problems.append(Diagnostic(span, d.message, d.expected + (FLOW_HINT if split else "")))
            return None

    def problem(self, node: yaml.Node | None, message: str, expected: str = "") -> None:
        self.problems.append(Diagnostic(self.span(node) if node is not None else None, message, expected))

    def check_tags(self, node: yaml.Node, depth: int = 0) -> None:
        if depth > MAX_YAML_DEPTH:
            self.problem(node, "YAML is nested too deeply", f"at most {MAX_YAML_DEPTH} levels")
            return
        if node.tag in IMPLICIT_TAGS and not self.text.startswith("!", node.start_mark.index):
            self.problem(node, f"YAML reads '{node.value}' as {IMPLICIT_TAGS[node.tag]}", "a number, a name or an expression; put it in quotes if it is meant as text")
        elif node.tag not in STANDARD_TAGS:
            self.problem(node, f"YAML tag '{node.tag}' is not allowed", "plain values without tags")
        if isinstance(node, yaml.SequenceNode):
            for item in node.value:
                self.check_tags(item, depth + 1)
        elif isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                self.check_tags(key, depth + 1)
                self.check_tags(value, depth + 1)

    def mapping(self, node: yaml.Node, what: str, keys: tuple[str, ...] | None = None) -> list[tuple[str, yaml.Node, yaml.Node]]:
        """The entries of a YAML map, checking for a map, string keys, duplicates and unknown keys."""
        if not isinstance(node, yaml.MappingNode):
            self.problem(node, f"{what} must be a map, got {_kind(node)}", f"a map of `key: value` lines for {what}")
            return []
        entries: list[tuple[str, yaml.Node, yaml.Node]] = []
        seen: set[str] = set()
        for key_node, value_node in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag != "tag:yaml.org,2002:str":
                self.problem(key_node, f"a key in {what} must be a name, got {_kind(key_node)}", "a name")
                continue
            key = key_node.value
            if key in seen:
                self.problem(key_node, f"duplicate key '{key}' in {what}", "each key once")
                continue
            seen.add(key)
            if keys is not None and key not in keys:
                if self.split_by_comma(key_node) and value_node.tag == "tag:yaml.org,2002:null":
                    continue  # `y)` from `{mass: f(x, y)}`, reported with its first half
                hint = _closest(key, list(keys))
                self.problem(key_node, f"unknown key '{key}' in {what}", (f"did you mean '{hint}'? " if hint else "") + "one of " + ", ".join(keys))
                continue
            entries.append((key, key_node, value_node))
        return entries

    def near_misses(self, node: yaml.MappingNode, keys: tuple[str, ...]) -> set[str | None]:
        """The known keys that the unknown keys of a map look like misspellings of."""
        return {_closest(k.value, list(keys)) for k, _ in node.value if isinstance(k, yaml.ScalarNode) and k.value not in keys}

    def sequence(self, node: yaml.Node, what: str) -> list[yaml.Node]:
        if not isinstance(node, yaml.SequenceNode):
            self.problem(node, f"{what} must be a list, got {_kind(node)}", f"a list such as `[a, b]` for {what}")
            return []
        return list(node.value)

    def scalar_text(self, node: yaml.Node, what: str) -> str | None:
        if not isinstance(node, yaml.ScalarNode):
            self.problem(node, f"{what} must be an expression, got {_kind(node)}", "an expression such as `m*g*l*cos(theta)`")
            return None
        if node.tag == "tag:yaml.org,2002:null":
            self.problem(node, f"{what} is empty", "an expression")
            return None
        if node.tag == "tag:yaml.org,2002:bool":
            self.problem(node, f"{what} is the boolean '{node.value}'", "an expression")
            return None
        return str(node.value)

    def expression(self, node: yaml.Node, what: str, scope: Scope, equation: bool = False) -> sp.Expr | None:
        text = self.scalar_text(node, what)
        if text is None:
            return None
        assert isinstance(node, yaml.ScalarNode)
        result = self.parsed(node, text, parse_equation if equation else parse_expression, scope)
        if result is not None and scope.elsewhere:
            # a total time derivative can bring in a velocity, e.g. `diff(x, t)` in a position
            found = sorted(str(s) for s in result.free_symbols if str(s) in scope.elsewhere)
            if found:
                self.problem(node, f"{what} depends on {scope.elsewhere[found[0]]} ('{found[0]}')", scope.refusal())
                return None
        return result

    def vector(self, node: yaml.Node, what: str, scope: Scope, lengths: tuple[int, ...] = (1, 2, 3)) -> tuple[sp.Expr, ...] | None:
        items = self.sequence(node, what)
        if not items:
            if isinstance(node, yaml.SequenceNode):
                self.problem(node, f"{what} is an empty list", f"a list of {' or '.join(map(str, lengths))} components")
            return None
        if len(items) not in lengths and not any(self.split_by_comma(item) for item in items):
            self.problem(node, f"{what} has {len(items)} components", f"{' or '.join(map(str, lengths))} components")
            return None
        values = [self.expression(item, f"a component of {what}", scope) for item in items]
        if any(v is None for v in values):
            return None
        return tuple(v for v in values if v is not None)

    def number(self, node: yaml.Node, what: str) -> float | None:
        """A finite number; a constant expression such as `pi/4` is accepted too."""
        text = self.scalar_text(node, what)
        if text is None:
            return None
        assert isinstance(node, yaml.ScalarNode)
        expected = "a number such as 9.81, or a constant expression such as `pi/4`"
        if NAME.match(text.strip()) and text.strip() not in CONSTANTS:
            self.problem(node, f"{what} must be a number, got '{text.strip()}'", expected)
            return None
        if node.tag == "tag:yaml.org,2002:float" and text.strip().lower().lstrip("+-") in (".inf", ".nan"):
            self.problem(node, f"{what} must be a finite real number, got '{text}'", expected)
            return None
        scope = Scope({}, {}, sp.Symbol("t"), lambda e: e, what="numbers, `pi`, `E` and the listed functions (a default must be a number)")
        value = self.parsed(node, text, parse_expression, scope)
        if value is None:
            return None
        if not value.is_number or value.has(sp.Symbol("t")):
            self.problem(node, f"{what} must be a number, got '{text}'", expected)
            return None
        try:
            return numeric_value(value)
        except (OverflowError, ValueError):
            self.problem(node, f"{what} must be a finite real number, got '{text}'", expected)
            return None

    def name(self, node: yaml.Node, what: str, taken: dict[str, str]) -> str | None:
        if not isinstance(node, yaml.ScalarNode) or node.tag != "tag:yaml.org,2002:str":
            self.problem(node, f"{what} must be a name, got {_kind(node)}", "a name such as `theta` or `x1`")
            return None
        name = node.value
        if not NAME.match(name) or keyword.iskeyword(name):
            self.problem(node, f"'{name}' is not a valid {what}", "letters, digits and _ starting with a letter, not a Python keyword")
            return None
        if name in RESERVED:
            self.problem(node, f"'{name}' is reserved and cannot be a {what}", "another name (`t` is time; function names and pi, E are built in)")
            return None
        if name.endswith(("_dot", "_ddot")):
            self.problem(node, f"'{name}' ends in _dot or _ddot, which name velocities and accelerations", "a name without that ending")
            return None
        if name in taken:
            self.problem(node, f"'{name}' is already declared as a {taken[name]}", "each name declared once")
            return None
        taken[name] = what
        return name

    def string(self, node: yaml.Node | None, what: str) -> str | None:
        if node is None:
            return None
        if not isinstance(node, yaml.ScalarNode) or node.tag == "tag:yaml.org,2002:null":
            self.problem(node, f"{what} must be text, got {_kind(node)}", "a line of text")
            return None
        return str(node.value)
