"""The frontend: a system file (YAML) in, a validated `SystemSpec` of sympy expressions out.

The file is composed, not constructed, so every node keeps its line and column.
Every problem in the file is collected and reported at once.
"""

from __future__ import annotations

import dataclasses
import keyword
import os
import re
import sys
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import sympy as sp
import yaml

from lagrange_cli.errors import Diagnostic, LagrangeError, Span, SpecError, fail
from lagrange_cli.expr import CONSTANTS, RESERVED, Scope, _closest, numeric_value, parse_equation, parse_expression, real_derivative
from lagrange_cli.inputs import ExpectedStateSpace, check_usage, read_inputs, read_outputs, read_state_space
from lagrange_cli.model import Input, Parameter
from lagrange_cli.rigid import BODY_KEYS as BODY_KEYS
from lagrange_cli.rigid import Places
from lagrange_cli.units import UNIT_HELP, UnitError, Units, parse_unit

MAX_FILE_BYTES = 1_000_000
MAX_YAML_DEPTH = 40
MAX_YAML_VALUES = 20_000
NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
TOP_KEYS = (
    "title", "description", "coordinates", "parameters", "functions", "gravity", "particles",
    "bodies", "kinetic", "potential", "lagrangian", "dissipation", "forces", "constraints",
    "eliminate", "initial", "simulate", "exact", "expect", "draw", "inputs", "outputs", "symmetries", "units",
)  # fmt: skip
PARTICLE_KEYS = ("mass", "position", "force", "damping")
FUNCTION_KEYS = ("arguments", "definition", "description")
DRAW_KEYS = ("segments", "trails")
SYMMETRY_KEYS = ("coordinates", "time")
EXPECT_KEYS = ("equations", "accelerations", "momenta", "conserved", "hamiltonian", "hamilton_equations", "state_space")
SIMULATE_KEYS = ("t_end", "method", "rtol", "atol", "step", "samples")
METHODS = ("auto", "RK45", "DOP853", "Radau", "BDF", "LSODA", "symplectic")  # as in numeric/settings.py
DEFAULT_T_END = 10.0  # numeric/settings.py's default
MAX_STEPS = 10**8
MAX_COORDINATES = 300
LIMITS = {
    "t_end": (1e-9, 1e9, "the end time of a run, in the system's units"),
    "step": (1e-12, 1e9, "the fixed step of the symplectic method"),
    "rtol": (100 * sys.float_info.epsilon, 1.0, "the relative tolerance (below 100 machine epsilons double precision cannot deliver it)"),
    "atol": (1e-300, 1e300, "the absolute tolerance"),
    "samples": (2, 10**6, "the number of sample times in the output"),
}
"""Allowed ranges of the `simulate` settings (inclusive), each with what it means; see docs/format.md."""
STANDARD_TAGS = {f"tag:yaml.org,2002:{kind}" for kind in ("str", "int", "float", "bool", "null", "seq", "map")}
IMPLICIT_TAGS = {"tag:yaml.org,2002:timestamp": "a date", "tag:yaml.org,2002:merge": "a merge key", "tag:yaml.org,2002:value": "a value key"}
LINE_BREAK = re.compile("\r\n|[\r\n\x85\u2028\u2029]")
ESCAPES = {
    "0": "\0", "a": "\a", "b": "\b", "t": "\t", "\t": "\t", "n": "\n", "v": "\v", "f": "\f", "r": "\r", "e": "\x1b", " ": " ",
    '"': '"', "/": "/", "\\": "\\", "N": "\x85", "_": "\xa0", "L": "\u2028", "P": "\u2029",
}  # fmt: skip
COMMA_AFTER = re.compile(r"[ \t\r\n]*,")
FLOW_HINT = '; a comma inside a flow list `[...]` or map `{...}` splits an expression in two: quote it (`"atan2(y, x)"`) or write the list as a block list, one `- item` per line'


@dataclass(frozen=True)
class Particle:
    name: str
    mass: sp.Expr
    position: tuple[sp.Expr, ...]
    force: tuple[sp.Expr, ...] | None = None
    damping: sp.Expr | None = None
    spans: Mapping[str, Span] = field(default_factory=dict, compare=False)
    """Where each field (`mass`, `position`, ...) is written in the file."""


@dataclass(frozen=True)
class Body:
    """A rigid body: planar when `inertia` and `angular_velocity` are scalars, spatial when 3-tuples."""

    name: str
    mass: sp.Expr
    position: tuple[sp.Expr, ...]
    inertia: tuple[sp.Expr, ...]
    angular_velocity: tuple[sp.Expr, ...]
    spans: Mapping[str, Span] = field(default_factory=dict, compare=False)
    """Where each field (`mass`, `inertia`, ...) is written in the file."""
    rotation: tuple[tuple[sp.Expr, ...], ...] | None = None
    """With `orientation` (FORMAT.md version 2): the rotation to world axes (2x2 planar, 3x3 spatial), whose
    columns are the body axes; `angular_velocity` is then the tool's body-axes omega (planar: omega_z).
    `inertia` has 9 entries (row by row) for a full tensor."""
    points: Mapping[str, tuple[sp.Expr, ...]] = field(default_factory=dict)
    """The body's `points`, as world positions."""
    forces: tuple[tuple[tuple[sp.Expr, ...], tuple[sp.Expr, ...]], ...] = ()
    """Each `force` load: (the force in world axes, the world position where it acts)."""
    torques: tuple[tuple[sp.Expr, ...], ...] = ()
    """Each `torque` load in body axes (a planar body's: its z component alone)."""
    local: tuple[tuple[sp.Expr, ...], ...] | None = None
    """With `orientation`: the rotation relative to the parent (`relative_to`, else the world)."""
    parent: str | None = None
    """The body named by `relative_to`."""
    velocity: tuple[sp.Expr, ...] | None = None
    """With `orientation`: the velocity of the centre of mass in body axes."""
    frame_forces: tuple[tuple[tuple[sp.Expr, ...], tuple[sp.Expr, ...]], ...] = ()
    """With `orientation`, each `force` load as (the force in body axes, the velocity of the point where it acts in body axes)."""
    anchor: tuple[str | None, tuple[sp.Expr, ...], tuple[sp.Expr, ...]] | None = None
    """With `orientation` and a `pivot` that is a point (or the centre) of the `relative_to` parent: (the parent, the
    pivot from the parent's centre of mass in the parent's axes, this body's centre from its pivot in its own axes),
    all constant: the body is then rigidly hinged to its parent (derive.py's composite bodies). Without
    `relative_to`, a pivot fixed in the world: (None, zeros, the centre from the pivot)."""


@dataclass(frozen=True)
class Constraint:
    """`expr = 0`: holonomic when it has no velocities, else linear in the velocities."""

    name: str
    expr: sp.Expr
    holonomic: bool
    span: Span


@dataclass(frozen=True)
class DrawPoint:
    """A point an animation draws: `label` is the particle or body it names (empty for a position
    list), `position` its Cartesian position in the file's coordinates, parameters and `t`."""

    label: str
    position: tuple[sp.Expr, ...]
    span: Span


@dataclass(frozen=True)
class Drawing:
    """The `draw` block: segments (pairs of points joined by a line) and trails (points whose
    recent path is drawn)."""

    segments: tuple[tuple[DrawPoint, DrawPoint], ...] = ()
    trails: tuple[DrawPoint, ...] = ()


@dataclass(frozen=True)
class Symmetry:
    """A declared continuous symmetry (`symmetries: {name: {coordinates: {q: delta_q}, time: delta_t}}`):
    the infinitesimal change of the listed coordinates (others unchanged) and of time, each an
    expression of the coordinates, parameters and `t`; lagrange_cli/noether.py checks it."""

    name: str
    coordinates: tuple[tuple[str, sp.Expr, Span], ...]
    time: sp.Expr | None
    span: Span
    time_span: Span | None = None


@dataclass(frozen=True)
class Expect:
    equations: tuple[tuple[sp.Expr, Span], ...] = ()
    accelerations: tuple[tuple[str, sp.Expr, Span], ...] = ()
    momenta: tuple[tuple[str, sp.Expr, Span], ...] = ()
    conserved: tuple[tuple[str, Span], ...] = ()
    """Coordinate names and `energy` (their conservation is decided symbolically)."""
    hamiltonian: tuple[sp.Expr, Span] | None = None
    """H in the coordinates and the momenta `p_<q>` (FORMAT.md version 2)."""
    hamilton_equations: tuple[tuple[sp.Expr, Span], ...] = ()
    """Equations in `<q>_dot`, `p_<q>` and `p_<q>_dot` (each `lhs - rhs`)."""
    state_space: ExpectedStateSpace | None = None
    """`expect.state_space` (FORMAT.md version 2; lagrange_cli/inputs.py)."""
    conserved_expressions: tuple[tuple[str, sp.Expr | None, Span], ...] = ()
    """`conserved` entries that are expressions (text, expression) or the name of a declared
    symmetry (name, None: its Noether charge); each is checked to be constant along every motion."""

    def __bool__(self) -> bool:
        return bool(self.equations or self.accelerations or self.momenta or self.conserved or self.conserved_expressions or self.hamiltonian or self.hamilton_equations or self.state_space)


@dataclass(frozen=True)
class SystemSpec:
    """A validated system file. Symbols are plain (no assumptions); `q_dot` names are `<q>_dot`."""

    path: str
    title: str
    description: str
    coordinates: tuple[str, ...]
    q: tuple[sp.Symbol, ...]
    qd: tuple[sp.Symbol, ...]
    qdd: tuple[sp.Symbol, ...]
    t: sp.Symbol
    parameters: tuple[Parameter, ...]
    functions: tuple[str, ...] = ()
    definitions: Mapping[str, sp.Lambda] = field(default_factory=dict)
    """Functions given a numeric definition (map form of `functions`): name -> Lambda(arguments, expression)."""
    gravity: tuple[sp.Expr, ...] | None = None
    particles: tuple[Particle, ...] = ()
    bodies: tuple[Body, ...] = ()
    kinetic: sp.Expr = sp.S.Zero
    potential: sp.Expr = sp.S.Zero
    lagrangian: sp.Expr = sp.S.Zero
    dissipation: sp.Expr = sp.S.Zero
    generalized_forces: tuple[sp.Expr, ...] = ()
    constraints: tuple[Constraint, ...] = ()
    eliminate: tuple[tuple[str, Span], ...] = ()
    initial: Mapping[str, float] = field(default_factory=dict)
    simulate: Mapping[str, Any] = field(default_factory=dict)
    exact: Mapping[str, sp.Expr] = field(default_factory=dict)
    spans: Mapping[str, Span] = field(default_factory=dict)
    sources: Mapping[str, Span] = field(default_factory=dict)
    """Where the other expressions are written: `potential`, `kinetic`, `lagrangian`, `dissipation`,
    `gravity`, `forces.<q>`, `functions.<f>`, `exact.<q>` (so that a bad term found after
    derivation is reported at its source)."""
    expect: Expect = Expect()
    draw: Drawing | None = None
    """The `draw` block (None without one: an animation then draws particles and bodies as dots)."""
    inputs: tuple[Input, ...] = ()
    """The `inputs` (lagrange_cli/inputs.py), in the file's order."""
    outputs: tuple[tuple[str, sp.Expr], ...] = ()
    """The `outputs`, name -> expression of q, q_dot, t and the inputs, in the file's order."""
    symmetries: tuple[Symmetry, ...] = ()
    """The declared continuous symmetries, in file order (checked by lagrange_cli/noether.py)."""
    units: Units | None = None
    """The `units` block (None without one: no dimensional checking); see units.py."""


def time_derivative(expr: sp.Expr, q: tuple[sp.Symbol, ...], qd: tuple[sp.Symbol, ...], qdd: tuple[sp.Symbol, ...], t: sp.Symbol) -> sp.Expr:
    """Total time derivative: d/dt f = sum df/dq q_dot + df/dq_dot q_ddot + df/dt."""
    if any(expr.has(a) for a in qdd):
        raise LagrangeError("cannot take the time derivative of an expression with accelerations")
    result = sp.diff(expr, t)
    for qi, qdi, qddi in zip(q, qd, qdd, strict=True):
        result += sp.diff(expr, qi) * qdi + sp.diff(expr, qdi) * qddi
    return result


def bundled_systems() -> Path:
    """The folder of bundled systems: inside the installed package, or beside it in a checkout."""
    here = Path(__file__).resolve().parent
    for candidate in (here / "systems", here.parent / "systems"):
        if candidate.is_dir():
            return candidate
    return here / "systems"


def resolve(name: str) -> Path:
    """A path to a system file: `name` itself if it exists, else a bundled system of that name.
    A name no file can have (a NUL byte, too long, not UTF-8) is a `LagrangeError`, not a crash."""
    from lagrange_cli.files import check_name, shown

    path = Path(check_name(name))
    if os.path.lexists(path):
        return path  # whatever it is: `load` says why it cannot be read
    folder = bundled_systems()
    if "/" not in name and name not in ("", ".", ".."):
        for candidate in (folder / name, folder / f"{name}.yaml"):
            if candidate.is_file():
                return candidate
    known = sorted(p.stem for p in folder.glob("*.yaml"))
    hint = _closest(path.stem, known)
    raise fail(None, f"no such file: {shown(name)}, and no bundled system of that name", f"a path to a .yaml file or one of: {', '.join(known)}" + (f" (did you mean '{hint}'?)" if hint else ""))


def shown_name(path: str | Path) -> str:
    """How messages and reports name a system file: a bundled one (an absolute path into the
    installed package, as `resolve` finds it) as `systems/<name>.yaml`, any other path as given."""
    text = str(path)
    if os.path.isabs(text):
        folder = bundled_systems()
        if Path(text).parent == folder:
            return f"{folder.name}/{Path(text).name}"
    return text


def load(path: str | Path) -> SystemSpec:
    """Read and validate a system file; raises `SpecError` listing every problem. Only a regular
    file is read (a FIFO, a device or a directory is refused) and at most MAX_FILE_BYTES of it.
    Messages and the spec name it by `shown_name`."""
    from lagrange_cli.files import read_limited

    raw = read_limited(path, MAX_FILE_BYTES)
    name = shown_name(path)
    if len(raw) > MAX_FILE_BYTES:
        raise fail(Span(name, 1, 1), f"file is over {MAX_FILE_BYTES} bytes", f"a system file under {MAX_FILE_BYTES} bytes")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise fail(Span(name, 1, 1), f"file is not UTF-8 (byte {exc.start})", "a UTF-8 text file") from None
    return parse(text, name)


def parse(text: str, filename: str = "<string>") -> SystemSpec:
    """Validate system-file text; `filename` is used in messages."""
    root = _compose(text, filename)
    return _Reader(filename, text).read(root)


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


class _Reader:
    """Walks the composed YAML tree, collecting diagnostics instead of stopping at the first."""

    def __init__(self, filename: str, text: str) -> None:
        self.filename = filename
        self.text = text
        self.lines = text.splitlines()
        self.problems: list[Diagnostic] = []
        self.spans: dict[str, Span] = {}
        self.sources: dict[str, Span] = {}
        self.split_head: int | None = None  # where the last reported `f(x` of a split `[f(x, y)]` ends

    # -- helpers ------------------------------------------------------------------------------

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

    # -- the file -----------------------------------------------------------------------------

    def read(self, root: yaml.Node) -> SystemSpec:
        self.check_tags(root)
        if self.problems:
            raise SpecError(self.problems)
        entries = {key: (key_node, value) for key, key_node, value in self.mapping(root, "the system file", TOP_KEYS)}
        if "coordinates" not in entries and isinstance(root, yaml.MappingNode):
            self.problem(root, "missing required key 'coordinates'", "`coordinates: [q1, q2, ...]`, the generalized coordinates")
        taken: dict[str, str] = {}

        coordinates = self.coordinates(entries, taken)
        parameters = self.parameters(entries, taken)
        functions, arities, definitions = self.functions(entries, taken, coordinates, parameters)
        inputs = read_inputs(self, entries["inputs"][1] if "inputs" in entries else None, taken)
        signals = {i.name: i.symbol for i in inputs}
        q = tuple(sp.Symbol(c) for c in coordinates)
        qd = tuple(sp.Symbol(f"{c}_dot") for c in coordinates)
        qdd = tuple(sp.Symbol(f"{c}_ddot") for c in coordinates)
        t = sp.Symbol("t")
        undefined = {f: sp.Function(f) for f in functions}

        def ddt(expr: sp.Expr) -> sp.Expr:
            if signals and expr.free_symbols & set(signals.values()):
                raise LagrangeError(
                    f"the time derivative of an expression holding an input ({', '.join(sorted(str(u) for u in expr.free_symbols & set(signals.values())))}) would need u_dot, and inputs are not differentiated"
                )

            def total(e: sp.Expr, real: Mapping[sp.Symbol, sp.Symbol]) -> sp.Expr:
                rq, rqd, rqdd = (tuple(real.get(s, s) for s in v) for v in (q, qd, qdd))
                return time_derivative(e, rq, rqd, rqdd, real.get(t, t))

            return real_derivative(expr, total)

        names = {str(s): s for s in (*q, *qd, *(p.symbol for p in parameters))} | signals
        velocities = {str(s): "a velocity" for s in qd}
        accelerations = {str(s): "an acceleration" for s in qdd}
        state = Scope(names, undefined, t, ddt, "a coordinate, a velocity (`<q>_dot`), a parameter, `t`", accelerations, arities=arities)
        config = Scope({str(s): s for s in (*q, *(p.symbol for p in parameters))} | signals, undefined, t, ddt, "a coordinate, a parameter, `t`", {**velocities, **accelerations}, arities=arities)
        constants = Scope(
            {p.name: p.symbol for p in parameters},
            undefined,
            t,
            ddt,
            "a parameter, `t`",
            {**{c: "a coordinate" for c in coordinates}, **velocities, **accelerations, **dict.fromkeys(signals, "an input")},
            arities=arities,
        )
        potential_scope = dataclasses.replace(config, note="velocity-dependent terms belong under `lagrangian`")

        def value(key: str) -> yaml.Node | None:
            return entries[key][1] if key in entries else None

        def expr(key: str, scope: Scope) -> sp.Expr:
            node = value(key)
            if node is not None:
                self.sources[key] = self.where(node)
            return (self.expression(node, f"'{key}'", scope) if node is not None else None) or sp.Integer(0)

        gravity_node = value("gravity")
        gravity = self.vector(gravity_node, "'gravity'", constants) if gravity_node is not None else None
        if gravity_node is not None:
            self.sources["gravity"] = self.where(gravity_node)
        self.places = Places(self, value("particles"), value("bodies"), config, state, constants, {p.symbol: p.value for p in parameters if p.value is not None})
        particles = self.particles(value("particles"), config, state, constants)
        bodies = self.bodies(value("bodies"), config, state, constants)
        self.check_dimensions(gravity, particles, bodies, value)
        potential = expr("potential", potential_scope)
        spec = SystemSpec(
            path=self.filename,
            title=self.string(value("title"), "'title'") or Path(self.filename).stem.replace("_", " ").capitalize(),
            description=self.string(value("description"), "'description'") or "",
            coordinates=coordinates,
            spans=self.spans,
            sources=self.sources,
            q=q,
            qd=qd,
            qdd=qdd,
            t=t,
            parameters=parameters,
            functions=functions,
            definitions=definitions,
            gravity=gravity,
            particles=particles,
            bodies=bodies,
            kinetic=expr("kinetic", state),
            potential=potential,
            lagrangian=expr("lagrangian", state),
            dissipation=expr("dissipation", state),
            generalized_forces=self.forces(value("forces"), coordinates, state),
            constraints=self.constraints(value("constraints"), state, qd, taken),
            eliminate=self.eliminate(value("eliminate"), coordinates),
            initial=self.initial(value("initial"), coordinates),
            simulate=self.simulate(value("simulate")),
            exact=self.exact(value("exact"), coordinates, constants),
            expect=Expect(),
            draw=self.draw(value("draw"), particles, bodies, config),
            units=self.units(value("units"), entries, coordinates, parameters),
        )
        if inputs or "outputs" in entries:
            spec = _replace(spec, inputs=inputs, outputs=read_outputs(self, value("outputs"), state, taken))
            check_usage(self, spec)
        symmetries_node = value("symmetries")
        if symmetries_node is not None:
            spec = _replace(spec, symmetries=self.symmetries(symmetries_node, coordinates, config, taken))
        expect_node = value("expect")
        if expect_node is not None:
            spec = _replace(spec, expect=self.expect(expect_node, spec, state))
        if spec.eliminate and not spec.constraints:
            self.problem(value("eliminate"), "'eliminate' given but there are no constraints", "a holonomic constraint under `constraints` for each eliminated coordinate")
        if self.problems:
            raise SpecError(sorted(self.problems, key=lambda d: (d.span.line, d.span.column) if d.span else (0, 0)))
        return spec

    def symmetries(self, node: yaml.Node, coordinates: tuple[str, ...], config: Scope, taken: dict[str, str]) -> tuple[Symmetry, ...]:
        """`symmetries: {name: {coordinates: {q: delta_q, ...}, time: delta_t}}`: each change an
        expression of the coordinates, parameters and `t`; at least one change per symmetry."""
        found = []
        expected = "`{coordinates: {x: -y, y: x}}` (the change of each listed coordinate) and/or `time: 1` (a time shift)"
        for key, key_node, value in self.mapping(node, "'symmetries'"):
            before = len(self.problems)
            name = self.name(key_node, "symmetry", taken)
            if name == "energy":
                self.problem(key_node, "'energy' cannot name a symmetry: `expect: conserved: [energy]` means the energy function", "another name, e.g. `time_shift`")
                name = None
            fields = {k: (kn, v) for k, kn, v in self.mapping(value, f"symmetry '{key}'", SYMMETRY_KEYS)}
            if name is None or not isinstance(value, yaml.MappingNode):
                continue
            changes = []
            if "coordinates" in fields:
                for q, q_node, delta in self.mapping(fields["coordinates"][1], f"'symmetries.{key}.coordinates'"):
                    if q not in coordinates:
                        hint = _closest(q, list(coordinates))
                        self.problem(q_node, f"'{q}' in symmetry '{key}' is not a coordinate", (f"did you mean '{hint}'? " if hint else "") + "one of " + ", ".join(coordinates))
                        continue
                    expr = self.expression(delta, f"the change of '{q}' in symmetry '{key}'", config)
                    if expr is not None:
                        changes.append((q, expr, self.span(delta)))
            time = None
            if "time" in fields:
                time = self.expression(fields["time"][1], f"the change of time in symmetry '{key}'", config)
            if not changes and time is None and len(self.problems) == before:
                self.problem(value, f"symmetry '{key}' changes nothing", expected)
                continue
            found.append(Symmetry(name, tuple(changes), time, self.span(key_node), self.span(fields["time"][1]) if "time" in fields else None))
        return tuple(found)

    def units(self, node: yaml.Node | None, entries: dict[str, tuple[yaml.Node, yaml.Node]], coordinates: tuple[str, ...], parameters: tuple[Parameter, ...]) -> Units | None:
        """`units: {name: unit}` for every coordinate, parameter and input (see units.py): a missing
        name, a unit on an undeclared name and an unknown unit are each an error at their place."""
        if node is None:
            return None
        raw = entries["inputs"][1] if "inputs" in entries else None  # read by name only: `inputs` is a list or a map of names
        items = raw.value if isinstance(raw, (yaml.SequenceNode, yaml.MappingNode)) else []
        inputs = [str(getattr(i[0] if isinstance(i, tuple) else i, "value", "")) for i in items]
        declared = [*coordinates, *(p.name for p in parameters), *(i for i in inputs if NAME.match(i))]
        dims, spans, texts = {}, {}, {}
        given = self.mapping(node, "'units'")
        for key, key_node, value in given:
            if key not in declared:
                hint = _closest(key, declared)
                self.problem(
                    key_node, f"'units' gives a unit for '{key}', which is not a coordinate, parameter or input", (f"did you mean '{hint}'? " if hint else "") + "one of " + ", ".join(declared)
                )
                continue
            if not isinstance(value, yaml.ScalarNode) or value.tag in ("tag:yaml.org,2002:null", "tag:yaml.org,2002:bool"):
                self.problem(value, f"the unit of '{key}' must be a unit, got {_kind(value)}", UNIT_HELP)
                continue
            try:
                dims[key] = parse_unit(str(value.value))
            except UnitError as exc:
                offset = len(str(value.value)) - len(str(value.value).lstrip()) + exc.offset
                self.problems.append(Diagnostic(self.locate(value, offset), f"the unit of '{key}': {exc}", UNIT_HELP))
                continue
            spans[key], texts[key] = self.where(value), str(value.value)
        missing = [n for n in declared if n not in {k for k, _, _ in given}]
        if missing and isinstance(node, yaml.MappingNode):
            self.problem(
                entries["units"][0],
                f"'units' has no unit for {', '.join(repr(n) for n in missing)}",
                "a unit for every coordinate, parameter and input (`1` for a dimensionless one), e.g. " + ", ".join(f"`{n}: m`" for n in missing[:2]),
            )
        return Units(dims, spans, texts)

    def draw(self, node: yaml.Node | None, particles: tuple[Particle, ...], bodies: tuple[Body, ...], config: Scope) -> Drawing | None:
        """`draw: {segments: [[A, B], ...], trails: [A, ...]}`, each point a particle's name, a body's
        name (its centre of mass) or a position list; every point as long as the system's positions."""
        if node is None:
            return None
        fields = {k: v for k, _, v in self.mapping(node, "'draw'", DRAW_KEYS)}
        items: tuple[Particle | Body, ...] = (*particles, *bodies)
        length = next((len(item.position) for item in items), None)
        segments: list[tuple[DrawPoint, DrawPoint]] = []
        for entry in self.sequence(fields["segments"], "'draw.segments'") if "segments" in fields else []:
            if not isinstance(entry, yaml.SequenceNode) or len(entry.value) != 2:
                got = f"{len(entry.value)} item{'s' * (len(entry.value) != 1)}" if isinstance(entry, yaml.SequenceNode) else _kind(entry)
                self.problem(entry, f"a segment of 'draw.segments' must be a pair of points, got {got}", "`[A, B]`, each a particle or body name or a position list such as `[0, 0]`")
                continue
            ends = [self.draw_point(item, particles, bodies, config, length) for item in entry.value]
            if ends[0] is not None and ends[1] is not None:
                segments.append((ends[0], ends[1]))
        trails = [self.draw_point(item, particles, bodies, config, length) for item in (self.sequence(fields["trails"], "'draw.trails'") if "trails" in fields else [])]
        drawn = [*(p for pair in segments for p in pair), *(t for t in trails if t is not None)]
        for point in drawn:  # without particles or bodies, the first point sets the length
            if len(point.position) != len(drawn[0].position):
                self.problems.append(
                    Diagnostic(point.span, f"a point of 'draw' has {len(point.position)} components, but the first one has {len(drawn[0].position)}", "points of one length throughout")
                )
                break
        return Drawing(tuple(segments), tuple(t for t in trails if t is not None))

    def draw_point(self, node: yaml.Node, particles: tuple[Particle, ...], bodies: tuple[Body, ...], config: Scope, length: int | None) -> DrawPoint | None:
        expected = "a particle name (" + (", ".join(p.name for p in particles) or "none declared") + "), a body name (" + (", ".join(b.name for b in bodies) or "none declared") + ")"
        expected += " or a position list such as `[0, 0]`"
        if isinstance(node, yaml.SequenceNode):
            position = self.vector(node, "a point of 'draw'", config, lengths=(length,) if length else (1, 2, 3))
            return DrawPoint("", position, self.span(node)) if position is not None else None
        if not isinstance(node, yaml.ScalarNode) or node.tag != "tag:yaml.org,2002:str":
            self.problem(node, f"a point of 'draw' must be a name or a position list, got {_kind(node)}", expected)
            return None
        name = str(node.value).strip()
        position = self.places.place(node, "a point of 'draw'", config, lengths=(length,) if length else (1, 2, 3))
        return DrawPoint(name, position, self.text_span(node)) if position is not None else None

    def string(self, node: yaml.Node | None, what: str) -> str | None:
        if node is None:
            return None
        if not isinstance(node, yaml.ScalarNode) or node.tag == "tag:yaml.org,2002:null":
            self.problem(node, f"{what} must be text, got {_kind(node)}", "a line of text")
            return None
        return str(node.value)

    def coordinates(self, entries: dict[str, tuple[yaml.Node, yaml.Node]], taken: dict[str, str]) -> tuple[str, ...]:
        if "coordinates" not in entries:
            return ()
        node = entries["coordinates"][1]
        items = self.sequence(node, "'coordinates'")
        if isinstance(node, yaml.SequenceNode) and not items:
            self.problem(node, "'coordinates' is empty", "at least one generalized coordinate")
        if len(items) > MAX_COORDINATES:
            self.problem(node, f"'coordinates' lists {len(items)} coordinates", f"at most {MAX_COORDINATES} (the mass matrix has one entry per pair)")
        names = [self.name(item, "coordinate", taken) for item in items]
        self.spans.update({n: self.span(item) for n, item in zip(names, items, strict=True) if n})
        return tuple(n for n in names if n)

    def parameters(self, entries: dict[str, tuple[yaml.Node, yaml.Node]], taken: dict[str, str]) -> tuple[Parameter, ...]:
        if "parameters" not in entries:
            return ()
        node = entries["parameters"][1]
        if isinstance(node, yaml.SequenceNode):
            names = [self.name(item, "parameter", taken) for item in node.value]
            return tuple(Parameter(sp.Symbol(n), None) for n in names if n)
        result = []
        for key, key_node, value in self.mapping(node, "'parameters'"):
            name = self.name(key_node, "parameter", taken)
            if name is None:
                continue
            if isinstance(value, yaml.MappingNode):
                fields = {k: v for k, _, v in self.mapping(value, f"parameter '{key}'", ("value", "sign", "description"))}
                number = self.number(fields["value"], f"the value of '{key}'") if "value" in fields else None
                sign = self.string(fields.get("sign"), "'sign'") or "positive"
                if sign not in ("positive", "real"):
                    self.problem(fields["sign"], f"sign '{sign}' is not known", "`positive` (the default) or `real`")
                if number is not None and sign == "positive" and number <= 0:
                    self.problem(fields["value"], f"'{key}' is positive by default but its value is {number}", "a positive value, or `sign: real`")
                description = self.string(fields.get("description"), "'description'") or ""
                result.append(Parameter(sp.Symbol(name), number, sign == "real", description))
            elif isinstance(value, yaml.ScalarNode) and value.tag == "tag:yaml.org,2002:null":
                result.append(Parameter(sp.Symbol(name), None))
            else:
                number = self.number(value, f"the value of '{key}'")
                result.append(Parameter(sp.Symbol(name), number, number is not None and number <= 0))
        return tuple(result)

    def functions(
        self, entries: dict[str, tuple[yaml.Node, yaml.Node]], taken: dict[str, str], coordinates: tuple[str, ...], parameters: tuple[Parameter, ...]
    ) -> tuple[tuple[str, ...], dict[str, int], dict[str, sp.Lambda]]:
        """`functions`: a list of names (undefined functions), or a map name -> {arguments, definition,
        description}. Returns the names, the number of arguments of those that state them, and the
        definitions, each `Lambda(arguments, expression)` of its arguments and the parameters."""
        if "functions" not in entries:
            return (), {}, {}
        node = entries["functions"][1]
        if isinstance(node, yaml.SequenceNode):
            listed = [self.name(item, "function", taken) for item in node.value]
            return tuple(n for n in listed if n), {}, {}
        if not isinstance(node, yaml.MappingNode):
            self.problem(node, f"'functions' must be a list or a map, got {_kind(node)}", "a list of names such as `[U]`, or a map such as `{U: {arguments: [s], definition: -k/s}}`")
            return (), {}, {}
        items = self.mapping(node, "'functions'")
        declared = {key for key, _, _ in items}
        names, arities, definitions = [], {}, {}
        for key, key_node, value in items:
            name = self.name(key_node, "function", taken)
            fields = {k: v for k, _, v in self.mapping(value, f"function '{key}'", FUNCTION_KEYS)}
            self.string(fields.get("description"), "'description'")
            if name is None:
                continue
            names.append(name)
            if "arguments" not in fields:
                if isinstance(value, yaml.MappingNode) and "arguments" not in self.near_misses(value, FUNCTION_KEYS):
                    self.problem(value, f"function '{key}' has no 'arguments'", "`arguments:` a list of names, e.g. `[s]`")
                continue
            arguments = self.arguments(fields["arguments"], key, parameters)
            if arguments is None:
                continue
            arities[name] = len(arguments)
            scope = _definition_scope(name, arguments, coordinates, parameters, declared)
            expr = self.expression(fields["definition"], f"the definition of '{key}'", scope) if "definition" in fields else None
            if expr is not None:
                self.sources[f"functions.{name}"] = self.where(fields["definition"])
                definitions[name] = sp.Lambda(tuple(sp.Symbol(a) for a in arguments), expr)
        return tuple(names), arities, definitions

    def arguments(self, node: yaml.Node, function: str, parameters: tuple[Parameter, ...]) -> tuple[str, ...] | None:
        """The argument names of a function: new names, local to its definition (so they may
        repeat a coordinate's name), but not a parameter's, which they would hide there."""
        items = self.sequence(node, f"the arguments of '{function}'")
        if not items:
            if isinstance(node, yaml.SequenceNode):
                self.problem(node, f"function '{function}' has no arguments", "at least one argument name, e.g. `[s]` (a constant belongs under `parameters`)")
            return None
        local: dict[str, str] = {}
        names = [self.name(item, "function argument", local) for item in items]
        if any(n is None for n in names):
            return None
        result = tuple(n for n in names if n)
        hidden = {p.name for p in parameters}
        for item, name in zip(items, result, strict=True):
            if name in hidden:
                self.problem(item, f"argument '{name}' of '{function}' is also a parameter, which it would hide in the definition", "another name for the argument, e.g. `s`")
                return None
        return result

    def particles(self, node: yaml.Node | None, config: Scope, state: Scope, constants: Scope) -> tuple[Particle, ...]:
        if node is None:
            return ()
        result = []
        for name, _, value in self.mapping(node, "'particles'"):
            fields = {k: v for k, _, v in self.mapping(value, f"particle '{name}'", PARTICLE_KEYS)}
            for required in ("mass", "position"):
                if required not in fields and isinstance(value, yaml.MappingNode) and required not in self.near_misses(value, PARTICLE_KEYS):
                    self.problem(value, f"particle '{name}' has no '{required}'", f"`{required}:` " + ("an expression" if required == "mass" else "a list of 1 to 3 components"))
            mass = self.expression(fields["mass"], f"the mass of '{name}'", constants) if "mass" in fields else None
            position = self.places.particle(name, fields["position"]) if "position" in fields else None
            force = self.vector(fields["force"], f"the force on '{name}'", state) if "force" in fields else None
            damping = self.expression(fields["damping"], f"the damping of '{name}'", constants) if "damping" in fields else None
            if mass is not None and position is not None:
                if force is not None and len(force) != len(position):
                    self.problem(fields["force"], f"the force on '{name}' has {len(force)} components but its position has {len(position)}", f"{len(position)} components")
                    continue
                result.append(Particle(name, mass, position, force, damping, {k: self.where(v) for k, v in fields.items()}))
        return tuple(result)

    def bodies(self, node: yaml.Node | None, config: Scope, state: Scope, constants: Scope) -> tuple[Body, ...]:
        """Each body, read by `rigid.Places` (on demand, so that pivots, positions and `relative_to` may
        refer to bodies and particles anywhere in the file)."""
        if node is None:
            return ()
        result = []
        for name, _, _ in self.mapping(node, "'bodies'"):
            body = self.places.body(name)
            if body is not None:
                result.append(body)
        return tuple(result)

    def scalar_or_triple(self, node: yaml.Node, what: str, scope: Scope) -> tuple[sp.Expr, ...] | None:
        if isinstance(node, yaml.SequenceNode):
            return self.vector(node, what, scope, lengths=(3,))
        value = self.expression(node, what, scope)
        return None if value is None else (value,)

    def check_dimensions(self, gravity: tuple[sp.Expr, ...] | None, particles: tuple[Particle, ...], bodies: tuple[Body, ...], value: Callable[[str], yaml.Node | None]) -> None:
        if gravity is None:
            return
        items: tuple[Particle | Body, ...] = (*particles, *bodies)
        for item in items:
            if len(item.position) != len(gravity):
                self.problem(value("gravity"), f"'gravity' has {len(gravity)} components but the position of '{item.name}' has {len(item.position)}", "vectors of one length throughout the file")
                return

    def forces(self, node: yaml.Node | None, coordinates: tuple[str, ...], state: Scope) -> tuple[sp.Expr, ...]:
        forces = [sp.Integer(0)] * len(coordinates)
        if node is None:
            return ()
        for _, _, value in self.mapping(node, "'forces'", ("generalized",)):
            for coordinate, key_node, force in self.mapping(value, "'forces.generalized'"):
                if coordinate not in coordinates:
                    hint = _closest(coordinate, list(coordinates))
                    self.problem(key_node, f"'{coordinate}' is not a coordinate", "one of " + ", ".join(coordinates) + (f"; did you mean '{hint}'?" if hint else ""))
                    continue
                expr = self.expression(force, f"the generalized force on '{coordinate}'", state)
                self.sources[f"forces.{coordinate}"] = self.where(force)
                if expr is not None:
                    forces[coordinates.index(coordinate)] = expr
        return tuple(forces)

    def constraints(self, node: yaml.Node | None, state: Scope, qd: tuple[sp.Symbol, ...], taken: dict[str, str]) -> tuple[Constraint, ...]:
        if node is None:
            return ()
        result = []
        for name, key_node, value in self.mapping(node, "'constraints'"):
            if not NAME.match(name) or keyword.iskeyword(name):
                self.problem(key_node, f"'{name}' is not a valid constraint name", "letters, digits and _")
                continue
            multiplier = f"lambda_{name}"
            if multiplier in taken:
                self.problem(key_node, f"the multiplier '{multiplier}' of this constraint clashes with a {taken[multiplier]}", "another constraint name")
                continue
            expr = self.expression(value, f"constraint '{name}'", state, equation=True)
            if expr is None:
                continue
            span = self.text_span(value) if isinstance(value, yaml.ScalarNode) else self.span(value)
            velocities = [v for v in qd if expr.has(v)]
            if velocities and any(sp.diff(expr, a, b) != 0 for a in velocities for b in velocities):
                self.problem(value, f"constraint '{name}' is not linear in the velocities", "a holonomic constraint f(q, t) = 0 or a velocity constraint linear in the velocities")
                continue
            if expr == 0:
                self.problem(value, f"constraint '{name}' is always satisfied", "an equation relating the coordinates")
                continue
            result.append(Constraint(name, expr, not velocities, span))
        return tuple(result)

    def eliminate(self, node: yaml.Node | None, coordinates: tuple[str, ...]) -> tuple[tuple[str, Span], ...]:
        if node is None:
            return ()
        result: list[tuple[str, Span]] = []
        for item in self.sequence(node, "'eliminate'"):
            if not isinstance(item, yaml.ScalarNode):
                self.problem(item, f"an entry of 'eliminate' must be a coordinate name, got {_kind(item)}", "one of " + ", ".join(coordinates))
                continue
            if item.value not in coordinates:
                hint = _closest(str(item.value), list(coordinates))
                self.problem(item, f"'{item.value}' is not a coordinate", "one of " + ", ".join(coordinates) + (f"; did you mean '{hint}'?" if hint else ""))
                continue
            earlier = next((span for name, span in result if name == item.value), None)
            if earlier is not None:
                self.problem(item, f"'{item.value}' is listed twice in 'eliminate' (first at line {earlier.line}, column {earlier.column})", "each coordinate once")
                continue
            result.append((str(item.value), self.span(item)))
        if coordinates and len(result) == len(coordinates):
            self.problem(
                node.value[-1] if isinstance(node, yaml.SequenceNode) else node,
                "'eliminate' lists every coordinate, which would leave no equation of motion",
                "keep at least one coordinate: eliminate one coordinate per holonomic constraint, fewer than there are coordinates",
            )
            return ()
        return tuple(result)

    def initial(self, node: yaml.Node | None, coordinates: tuple[str, ...]) -> dict[str, float]:
        if node is None:
            return {}
        allowed = [*coordinates, *(f"{c}_dot" for c in coordinates)]
        result = {}
        for key, key_node, value in self.mapping(node, "'initial'"):
            if key not in allowed:
                hint = _closest(key, allowed)
                self.problem(key_node, f"'{key}' is not a coordinate or velocity", "one of " + ", ".join(allowed) + (f"; did you mean '{hint}'?" if hint else ""))
                continue
            number = self.number(value, f"the initial value of '{key}'")
            if number is not None:
                result[key] = number
        return result

    def simulate(self, node: yaml.Node | None) -> dict[str, Any]:
        """The `simulate` block, each value checked against its documented range (`LIMITS`), and
        the number of fixed steps `t_end / step` against `MAX_STEPS`, so that no file can ask for
        a run that never ends."""
        if node is None:
            return {}
        result: dict[str, Any] = {}
        nodes: dict[str, yaml.Node] = {}
        for key, _, value in self.mapping(node, "'simulate'", SIMULATE_KEYS):
            nodes[key] = value
            if key == "method":
                method = self.string(value, "'simulate.method'")
                known = next((m for m in METHODS if method is not None and m.lower() == method.lower()), None)
                if method is not None and known is None:
                    hint = _closest(method, list(METHODS))
                    self.problem(value, f"unknown method '{method}' in 'simulate.method'", "one of " + ", ".join(METHODS) + (f" (did you mean '{hint}'?)" if hint else ""))
                elif known is not None:
                    result[key] = known
                continue
            number = self.number(value, f"'simulate.{key}'")
            if number is None:
                continue
            low, high, meaning = LIMITS[key]
            if key == "samples" and number != int(number):
                self.problem(value, f"'simulate.samples' must be a whole number, got {number:g}", f"a whole number from {low:g} to {high:g}: {meaning}")
            elif not low <= number <= high:
                self.problem(value, f"'simulate.{key}' is {number:g}, outside the allowed range", f"a number from {low:g} to {high:g}: {meaning}")
            else:
                result[key] = int(number) if key == "samples" else number
        if "step" in result:
            t_end = result.get("t_end", DEFAULT_T_END)
            if t_end / result["step"] > MAX_STEPS:
                self.problem(
                    nodes["step"],
                    f"'simulate.step' {result['step']:g} would take {t_end / result['step']:.3g} steps to reach t_end = {t_end:g}",
                    f"at most {MAX_STEPS:.0e} steps: a step of at least {t_end / MAX_STEPS:.3g}, or a shorter t_end",
                )
        return result

    def exact(self, node: yaml.Node | None, coordinates: tuple[str, ...], constants: Scope) -> dict[str, sp.Expr]:
        if node is None:
            return {}
        result = {}
        for key, key_node, value in self.mapping(node, "'exact'"):
            if key not in coordinates:
                self.problem(key_node, f"'{key}' is not a coordinate", "one of " + ", ".join(coordinates))
                continue
            expr = self.expression(value, f"the exact solution for '{key}'", constants)
            self.sources[f"exact.{key}"] = self.where(value)
            if expr is not None:
                result[key] = expr
        return result

    def expect(self, node: yaml.Node, spec: SystemSpec, state: Scope) -> Expect:
        fields = {k: v for k, _, v in self.mapping(node, "'expect'", EXPECT_KEYS)}
        multipliers = {f"lambda_{c.name}": sp.Symbol(f"lambda_{c.name}") for c in spec.constraints}
        full = Scope(
            {**state.symbols, **{str(s): s for s in spec.qdd}, **multipliers},
            state.functions,
            state.time,
            state.time_derivative,
            "a coordinate, velocity, acceleration (`<q>_ddot`), parameter, multiplier or `t`",
            arities=state.arities,
        )
        equations = []
        for item in self.sequence(fields["equations"], "'expect.equations'") if "equations" in fields else []:
            expr = self.expression(item, "an expected equation", full, equation=True)
            if expr is not None:
                equations.append((expr, self.text_span(item) if isinstance(item, yaml.ScalarNode) else self.span(item)))
        accelerations = []
        for key, key_node, value in self.mapping(fields["accelerations"], "'expect.accelerations'") if "accelerations" in fields else []:
            coordinate = key.removesuffix("_ddot")
            if not key.endswith("_ddot") or coordinate not in spec.coordinates:
                self.problem(key_node, f"'{key}' is not an acceleration", "one of " + ", ".join(f"{c}_ddot" for c in spec.coordinates))
                continue
            expr = self.expression(value, f"the expected '{key}'", full)
            if expr is not None:
                accelerations.append((coordinate, expr, self.span(value)))
        momenta = []
        for key, key_node, value in self.mapping(fields["momenta"], "'expect.momenta'") if "momenta" in fields else []:
            if key not in spec.coordinates:
                self.problem(key_node, f"'{key}' is not a coordinate", "one of " + ", ".join(spec.coordinates))
                continue
            expr = self.expression(value, f"the expected momentum of '{key}'", state)
            if expr is not None:
                momenta.append((key, expr, self.span(value)))
        conserved, conserved_expressions = self.conserved_expect(fields, spec, state)
        hamiltonian, hamilton_equations = self.hamilton_expect(fields, spec, state)
        state_space = read_state_space(self, fields["state_space"], spec) if "state_space" in fields else None
        return Expect(tuple(equations), tuple(accelerations), tuple(momenta), conserved, hamiltonian, hamilton_equations, state_space, conserved_expressions)

    def conserved_expect(self, fields: dict[str, yaml.Node], spec: SystemSpec, state: Scope) -> tuple[tuple[tuple[str, Span], ...], tuple[tuple[str, sp.Expr | None, Span], ...]]:
        """`expect.conserved`: coordinate names and `energy` (decided symbolically), the names of
        declared symmetries (their Noether charges) and expressions of the state (e.g.
        `m*(x*y_dot - y*x_dot)`), the last two checked to be constant along every motion."""
        names, expressions = [], []
        symmetries = {s.name for s in spec.symmetries}
        expected = "coordinate names, `energy`, names of declared symmetries, or expressions of the coordinates, velocities, parameters and `t`"
        for item in self.sequence(fields["conserved"], "'expect.conserved'") if "conserved" in fields else []:
            name = getattr(item, "value", None)
            if not isinstance(item, yaml.ScalarNode):
                self.problem(item, f"{_kind(item)} is not a coordinate, 'energy', a symmetry or an expression", expected)
            elif name in spec.coordinates or name == "energy":
                names.append((str(name), self.span(item)))
            elif name in symmetries:
                expressions.append((str(name), None, self.span(item)))
            else:
                expr = self.expression(item, "an expected conserved quantity", state)
                if expr is not None:
                    expressions.append((str(name), expr, self.text_span(item)))
        return tuple(names), tuple(expressions)

    def hamilton_expect(self, fields: dict[str, yaml.Node], spec: SystemSpec, state: Scope) -> tuple[tuple[sp.Expr, Span] | None, tuple[tuple[sp.Expr, Span], ...]]:
        """`expect.hamiltonian` (an expression of q, p_<q>, the parameters and t) and
        `expect.hamilton_equations` (a list of equations in <q>_dot, p_<q> and p_<q>_dot). A declared
        name of the form p_<q> (which would mean two things) is an error at the key."""
        from lagrange_cli.hamilton import clashes, momentum_symbols

        keys = [k for k in ("hamiltonian", "hamilton_equations") if k in fields]
        if not keys:
            return None, ()
        clash = clashes(spec.coordinates, [*spec.coordinates, *(str(v) for v in spec.qd), *(p.name for p in spec.parameters), *spec.functions])
        if clash:
            self.problem(
                fields[keys[0]],
                f"'{clash[0]}' is declared in the file, but 'expect.{keys[0]}' names the momentum of '{clash[0][2:].removesuffix('_dot')}' so",
                "no coordinate, parameter or function named p_<coordinate> in a file that uses `hamiltonian` or `hamilton_equations`",
            )
            return None, ()
        p, pd = momentum_symbols(spec.coordinates)
        constants = {s: v for s, v in state.symbols.items() if s not in {str(x) for x in spec.qd}}
        velocities = {str(v): "a velocity" for v in spec.qd}
        accelerations = {str(a): "an acceleration" for a in spec.qdd}
        hamiltonian = None
        if "hamiltonian" in fields:
            scope = Scope(
                {**constants, **{str(x): x for x in p}},
                state.functions,
                state.time,
                state.time_derivative,
                "a coordinate, a momentum (`p_<q>`), a parameter, `t`",
                {**velocities, **accelerations},
                note="H is a function of the coordinates and momenta",
                arities=state.arities,
            )
            node = fields["hamiltonian"]
            expr = self.expression(node, "the expected Hamiltonian", scope)
            if expr is not None:
                hamiltonian = (expr, self.span(node))
        equations = []
        if "hamilton_equations" in fields:
            scope = Scope(
                {**state.symbols, **{str(x): x for x in (*p, *pd)}},
                state.functions,
                state.time,
                state.time_derivative,
                "a coordinate, a velocity (`<q>_dot`), a momentum (`p_<q>`), its rate (`p_<q>_dot`), a parameter, `t`",
                accelerations,
                arities=state.arities,
            )
            for item in self.sequence(fields["hamilton_equations"], "'expect.hamilton_equations'"):
                expr = self.expression(item, "an expected Hamilton equation", scope, equation=True)
                if expr is not None:
                    equations.append((expr, self.text_span(item) if isinstance(item, yaml.ScalarNode) else self.span(item)))
        return hamiltonian, tuple(equations)


def _definition_scope(function: str, arguments: tuple[str, ...], coordinates: tuple[str, ...], parameters: tuple[Parameter, ...], functions: set[str]) -> Scope:
    """What a function's definition may name: its arguments and the parameters, nothing that
    changes along the motion (coordinates, velocities, `t`) and no declared function."""
    elsewhere = {c: "a coordinate" for c in coordinates if c not in arguments}
    elsewhere |= {f"{c}_dot": "a velocity" for c in coordinates} | {f"{c}_ddot": "an acceleration" for c in coordinates}
    elsewhere |= {f: "a declared function" for f in functions} | {"t": "time"}
    symbols = {p.name: p.symbol for p in parameters} | {a: sp.Symbol(a) for a in arguments}
    what = f"the arguments of '{function}' ({', '.join(arguments)}) or a parameter"
    note = f"a definition depends on nothing else; make it an argument (e.g. `arguments: [{', '.join(arguments)}, tau]` and `{function}(..., t)`)"
    return Scope(symbols, {}, sp.Symbol("t"), lambda e: e, what, elsewhere, note)


def _replace(spec: SystemSpec, **changes: Any) -> SystemSpec:
    return dataclasses.replace(spec, **changes)


def _kind(node: yaml.Node | None) -> str:
    if isinstance(node, yaml.SequenceNode):
        return "a list"
    if isinstance(node, yaml.MappingNode):
        return "a map"
    if isinstance(node, yaml.ScalarNode):
        kind = node.tag.rsplit(":", 1)[-1]
        return {"null": "nothing", "str": f"the text '{node.value}'", "bool": f"the boolean '{node.value}'"}.get(kind, f"the number {node.value}")
    return "nothing"


def iter_files(paths: list[str]) -> Iterator[Path]:
    """System files named by paths, directories (their *.yaml, sorted) and globs."""
    import glob

    for item in paths:
        path = Path(item)
        if path.is_dir():
            yield from sorted(path.glob("*.yaml"))
        elif any(c in item for c in "*?["):
            yield from (Path(p) for p in sorted(glob.glob(item, recursive=True)))
        else:
            yield resolve(item)
