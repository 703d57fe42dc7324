"""Bad system files, run through the CLI: each must end in a clean, located error.

For every case: exit code 2, no traceback, the message on stderr starts with
`file:line:col` at the right place (computed from the text of the case), the source
line and a caret follow, an `expected:` hint says what would be right, `-o out.txt`
leaves no file behind, and the run takes seconds even for the bombs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.spec import MAX_YAML_DEPTH

runner = CliRunner()

TIME_LIMIT = 60.0  # CPU seconds for a whole invocation: a safety net that only catches hangs (CPU time: the load of other programs does not count)
PYTHON_PAREN_LIMIT = 200  # CPython's parser refuses the 201st nested parenthesis


def position(text: str, anchor: str, shift: int = 0, nth: int = 0) -> tuple[int, int]:
    """1-based line and column of the `nth` occurrence of `anchor` in `text`, moved `shift` characters right."""
    index = -1
    for _ in range(nth + 1):
        index = text.index(anchor, index + 1)
    index += shift
    line_start = text.rfind("\n", 0, index) + 1
    return text.count("\n", 0, index) + 1, index - line_start + 1


def derive_bad(tmp_path: Path, text: str, *options: str) -> tuple[str, str]:
    """Run `lagrange derive FILE [options] -o out.txt` on `text`, check the common promises,
    and return stderr and the file name as it appears in messages."""
    path = tmp_path / "system.yaml"
    path.write_text(text, encoding="utf-8")
    out = tmp_path / "out.txt"
    start = time.process_time()
    result = runner.invoke(app, ["derive", str(path), *options, "-o", str(out)])
    elapsed = time.process_time() - start
    assert elapsed < TIME_LIMIT, f"used {elapsed:.1f} s of CPU time"
    assert result.exit_code == 2, result.output
    assert isinstance(result.exception, SystemExit), result.exception
    assert "Traceback" not in result.output
    assert result.stdout == ""
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["system.yaml"], "a temporary output file was left behind"
    return result.stderr, str(path)


def assert_located(stderr: str, path: str, text: str, line: int, column: int) -> list[str]:
    """The first diagnostic is at `path:line:col`, quotes that source line and puts a caret under the column;
    returns its lines."""
    lines = stderr.splitlines()
    assert lines[0].startswith(f"{path}:{line}:{column}: error: "), lines[0]
    source = text.splitlines()[line - 1] if text.strip() else ""
    if source:
        assert lines[1] == "    " + source
        assert lines[2] == "    " + " " * (column - 1) + "^"
    return lines


@dataclass(frozen=True)
class Bad:
    id: str
    text: str
    at: tuple[str, int] | tuple[str, int, int]  # anchor, shift[, nth]: see `position`
    says: str  # part of the first error message
    expected: str  # part of its `expected:` line


PENDULUM = """\
coordinates: [theta]
parameters: {m: 1.0, l: 1.0, g: 9.81}
gravity: [0, -g]
particles:
  bob: {mass: m, position: [l*sin(theta), -l*cos(theta)]}
"""
SPRING = """\
coordinates: [x]
parameters: {m: 1.0, k: 1.0}
particles:
  bob: {mass: m, position: [x]}
"""
PLANE = """\
coordinates: [x, y]
parameters: {m: 1.0, g: 9.81}
particles:
  bob: {mass: m, position: [x, y]}
"""
DEEP = 1999  # parentheses: "thousands deep", yet under the 4000-character limit on an expression
LAUGHS = "coordinates: [x]\na: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + "".join(f"{b}: &{b} [{', '.join([f'*{a}'] * 9)}]\n" for a, b in zip("abcdefgh", "bcdefghi", strict=True))

CASES = [
    # -- YAML ---------------------------------------------------------------------------------
    Bad(
        "malformed-yaml",
        "coordinates: [x\nparameters: {m: 1}\n",
        (": {m", 0),
        "malformed YAML: expected ',' or ']', but got ':' (while parsing a flow sequence that starts at line 1, column 14)",
        "valid YAML",
    ),
    Bad("empty-file", "", ("", 0), "the file is empty", "at least `coordinates:`"),
    Bad("comment-only-file", "# nothing here\n", ("#", 0), "the file is empty", "at least `coordinates:`"),
    Bad(
        "python-tag",
        "coordinates: [x]\npotential: !!python/object/apply:os.system ['echo hi']\n",
        ("!!python", 0),
        "YAML tag 'tag:yaml.org,2002:python/object/apply:os.system' is not allowed",
        "without tags",
    ),
    Bad("custom-tag", "coordinates: [x]\npotential: !foo x\n", ("!foo", 0), "YAML tag '!foo' is not allowed", "without tags"),
    Bad("alias-bomb", LAUGHS, ("&a", 0), "YAML anchors and aliases are not supported", "written out in full"),
    Bad("deep-yaml-list", "coordinates: " + "[" * 5000 + "x" + "]" * 5000 + "\n", ("[", MAX_YAML_DEPTH - 1), f"nested more than {MAX_YAML_DEPTH} levels deep", "nested a few levels at most"),
    Bad("duplicate-yaml-key", SPRING + "parameters: {k: 2.0}\n", ("parameters", 0, 1), "duplicate key 'parameters' in the system file", "each key once"),
    Bad("yaml-date", SPRING + "initial: {x: 2024-01-01}\n", ("2024", 0), "YAML reads '2024-01-01' as a date", "put it in quotes"),
    # -- keys ---------------------------------------------------------------------------------
    Bad("unknown-top-level-key", SPRING.replace("particles", "particels"), ("particels", 0), "unknown key 'particels' in the system file", "did you mean 'particles'?"),
    Bad("unknown-particle-key", SPRING.replace("{mass", "{mas"), ("mas:", 0), "unknown key 'mas' in particle 'bob'", "did you mean 'mass'?"),
    Bad("missing-coordinates", "parameters: {m: 1.0}\n", ("parameters", 0), "missing required key 'coordinates'", "`coordinates: [q1, q2, ...]`"),
    # -- names --------------------------------------------------------------------------------
    Bad("coordinate-named-t", "coordinates: [x, t]\n", ("t]", 0), "'t' is reserved and cannot be a coordinate", "`t` is time"),
    Bad("coordinate-twice", "coordinates: [x, y, x]\n", ("x]", 0), "'x' is already declared as a coordinate", "each name declared once"),
    Bad("parameter-named-like-a-coordinate", "coordinates: [x]\nparameters: {m: 1.0, x: 2.0}\n", ("x: 2.0", 0), "'x' is already declared as a coordinate", "each name declared once"),
    Bad("parameter-named-like-a-velocity", "coordinates: [x]\nparameters: {m: 1.0, x_dot: 2.0}\n", ("x_dot", 0), "'x_dot' ends in _dot or _ddot", "a name without that ending"),
    Bad(
        "multiplier-name-clash",
        PLANE.replace("g: 9.81", "lambda_c: 2.0") + "constraints:\n  c: x = y\n",
        ("c: x", 0),
        "the multiplier 'lambda_c' of this constraint clashes with a parameter",
        "another constraint name",
    ),
    Bad("non-numeric-default", "coordinates: [x]\nparameters: {m: heavy}\n", ("heavy", 0), "the value of 'm' must be a number, got 'heavy'", "a number such as 9.81"),
    # -- expressions --------------------------------------------------------------------------
    Bad("unknown-name", PENDULUM.replace("-l*cos(theta)", "-l*cos(thetta)"), ("thetta", 0), "unknown name 'thetta'", "did you mean 'theta'?"),
    Bad("syntax-ends-early", SPRING + "potential: k*x**2 +\n", ("k*x**2 +", len("k*x**2 +")), "invalid expression syntax", "Python/SymPy syntax"),
    Bad("syntax-unclosed-paren", PENDULUM + "potential: m*g*(1 - cos(theta)\n", ("(1 - cos", 0), "invalid expression syntax: '(' was never closed", "Python/SymPy syntax"),
    Bad("syntax-stray-character", SPRING + "potential: k $ x\n", ("$", 0), "invalid expression syntax", "Python/SymPy syntax"),
    Bad("inject-import", SPRING + "potential: \"__import__('os').system('echo hi')\"\n", ("__import__", 0), "only plain function names can be called", "a call such as `sin(theta)`"),
    Bad("inject-subclasses", SPRING + 'potential: "().__class__.__bases__[0].__subclasses__()"\n', ("().__class__", 0), "only plain function names can be called", "a call such as `sin(theta)`"),
    Bad("inject-attribute", SPRING + "potential: x.__class__\n", ("x.__class__", 0), "attribute access is not allowed", "numbers, names, + - * / **"),
    Bad("inject-lambda", SPRING + 'potential: "lambda: x"\n', ("lambda", 0), "a lambda is not allowed", "numbers, names, + - * / **"),
    Bad("inject-subscript", SPRING + "potential: x[0]\n", ("x[0]", 0), "indexing is not allowed", "numbers, names, + - * / **"),
    Bad("inject-f-string", SPRING + "potential: f'{x}'\n", ("f'{x}'", 0), "an f-string is not allowed", "numbers, names, + - * / **"),
    Bad("inject-dunder-name", SPRING + "potential: __builtins__\n", ("__builtins__", 0), "unknown name '__builtins__'", "a coordinate, a parameter, `t`"),
    Bad("exponent-tower", SPRING + "potential: 9**9**9**9\n", ("9**9**9**9", 6), "exponent 387420489 is too large", "an exponent of at most 1000"),
    Bad("exponent-huge", SPRING + "potential: 2**(10**10)\n", ("10**10", 0), "exponent 10000000000 is too large", "an exponent of at most 1000"),
    Bad("exponent-compounded", SPRING + "potential: ((x + 1)**999)**999\n", ("((x", 0), "exponent of 998001", "an exponent of at most 1000"),
    Bad("deep-parentheses", SPRING + "potential: " + "(" * DEEP + "x" + ")" * DEEP + "\n", ("(", PYTHON_PAREN_LIMIT), "expression is nested too deeply", "levels of nesting"),
    Bad("deep-parentheses-long", SPRING + "potential: " + "(" * 5000 + "x" + ")" * 5000 + "\n", ("(", 0), "expression is 10001 characters long", "at most 4000 characters"),
    Bad("undefined-value", SPRING + "potential: k*log(0)*x\n", ("log(0)", 0), "this is undefined (zoo)", "a finite value"),
    Bad("overflowing-default", "coordinates: [x]\nparameters: {m: exp(exp(exp(1000)))}\n", ("exp(1000)", 0), "the value of 'exp(...)' is too large", "numbers below 1e300"),
    Bad("not-real", SPRING + "potential: k*x**2 + sqrt(-1)*x\n", ("sqrt", 0), "'sqrt(...)' is not a real number", "`sqrt` and `log` of positive numbers"),
    Bad("literal-glued-to-keyword", SPRING + "potential: 1if x else 0\n", ("1if", 0), "invalid expression syntax: invalid decimal literal", "Python/SymPy syntax"),
    Bad(
        "derivative-at-compound-argument",
        SPRING.replace("coordinates", "functions: [U]\ncoordinates") + "lagrangian: x_dot*diff(U(2*x), x)\n",
        ("diff", 0),
        "the derivative of 'U' at a compound argument (2*x) is not supported",
        "e.g. `U(r)`",
    ),
    Bad("third-time-derivative", SPRING + "lagrangian: diff(x, t, 3)\n", ("diff", 0), "cannot take the time derivative of an expression with accelerations", "without accelerations"),
    Bad("flow-list-split-by-comma", PLANE.replace("[x, y]}", "[atan2(y, x), 0]}"), ("(y, x)", 0), "'(' was never closed", "quote it"),
    Bad("block-scalar-position", SPRING + "potential: |\n  k*x**2/2\n  + q*x\n", ("q*x", 0), "unknown name 'q'", "a coordinate, a parameter, `t`"),
    Bad("folded-crlf-position", SPRING.replace("\n", "\r\n") + "potential: k*x**2/2 +\r\n  q*x\r\n", ("q*x", 0), "unknown name 'q'", "a coordinate, a parameter, `t`"),
    Bad("escaped-quoted-position", SPRING + 'potential: "\\t k*x**2 + q"\n', ('q"', 0), "unknown name 'q'", "a coordinate, a parameter, `t`"),
    # -- vectors ------------------------------------------------------------------------------
    Bad(
        "gravity-3d-position-2d", PLANE.replace("particles", "gravity: [0, 0, -g]\nparticles"), ("[0, 0, -g]", 0), "'gravity' has 3 components but the position of 'bob' has 2", "vectors of one length"
    ),
    Bad(
        "position-4d",
        "coordinates: [x, y, z, w]\nparameters: {m: 1.0}\nparticles:\n  bob: {mass: m, position: [x, y, z, w]}\n",
        ("[x, y, z, w]", 0, 1),
        "the position of 'bob' has 4 components",
        "1 or 2 or 3 components",
    ),
    Bad(
        "force-length-mismatch",
        PLANE.replace("position: [x, y]}", "position: [x, y], force: [0, -m*g, 0]}"),
        ("[0, -m*g", 0),
        "the force on 'bob' has 3 components but its position has 2",
        "2 components",
    ),
    # -- physics ------------------------------------------------------------------------------
    Bad("potential-with-velocity", SPRING + "potential: k*x_dot**2/2\n", ("x_dot", 0), "'x_dot' is a velocity, which cannot appear here", "velocity-dependent terms belong under `lagrangian`"),
    Bad(
        "position-with-velocity",
        "coordinates: [x]\nparameters: {m: 1.0}\nparticles:\n  bob:\n    mass: m\n    position:\n      - diff(x, t)\n",
        ("diff", 0),
        "depends on a velocity ('x_dot')",
        "a coordinate, a parameter, `t`",
    ),
    Bad("nonlinear-velocity-constraint", PLANE + "constraints:\n  c: x_dot**2 + y_dot**2 = 1\n", ("x_dot**2 +", 0), "constraint 'c' is not linear in the velocities", "linear in the velocities"),
    Bad("eliminate-without-constraints", PLANE + "eliminate: [y]\n", ("[y]", 0), "'eliminate' given but there are no constraints", "a holonomic constraint"),
    Bad("eliminate-unsolvable", PLANE + "constraints:\n  c: x_dot = y_dot\neliminate: [y]\n", ("[y]", 1), "no holonomic constraint can be solved for 'y'", "a holonomic constraint"),
]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_is_reported_in_place(tmp_path: Path, capfd: pytest.CaptureFixture[str], case: Bad) -> None:
    stderr, path = derive_bad(tmp_path, case.text)
    line, column = position(case.text, *case.at)
    lines = assert_located(stderr, path, case.text, line, column)
    assert case.says in lines[0]
    expected = next(item for item in lines if item.startswith("  expected: "))
    assert case.expected in expected
    assert stderr.count(": error: ") == 1, stderr  # one problem, one message: no follow-on noise
    assert "hi" not in capfd.readouterr().out  # nothing ran a shell command


SINGULAR = """\
coordinates: [x, y]
parameters: {m: 1.0, k: 1.0}
particles:
  bob: {mass: m, position: [x]}
potential: k*y**2/2
"""


@pytest.mark.parametrize("options", [("--form", "solved"), ("--python",)], ids=["solved", "python"])
def test_coordinate_without_inertia_is_named(tmp_path: Path, options: tuple[str, ...]) -> None:
    stderr, path = derive_bad(tmp_path, SINGULAR, *options)
    assert_located(stderr, path, SINGULAR, *position(SINGULAR, "y]"))
    assert "the mass matrix is singular: coordinate 'y' has no inertia" in stderr
    assert "give it a mass" in stderr  # what would be right


def test_coordinate_without_inertia_points_at_its_declaration(tmp_path: Path) -> None:
    stderr, path = derive_bad(tmp_path, SINGULAR, "--form", "solved")
    assert_located(stderr, path, SINGULAR, *position(SINGULAR, "y]"))
    assert "  expected: " in stderr


def test_every_problem_is_reported_at_once(tmp_path: Path) -> None:
    text = """\
title: Broken in many places
coordinates: [x, t]
parameters: {m: heavy, k: 1.0}
particels: {}
gravity: [0, -9.81]
particles:
  bob: {mas: m, position: [x, 0, 0, 0]}
potential: k*x**2/2 + q
constraints:
  c: x_dot**2 = 1
"""
    stderr, path = derive_bad(tmp_path, text)
    wanted = [
        (position(text, "t]"), "'t' is reserved"),
        (position(text, "heavy"), "the value of 'm' must be a number"),
        (position(text, "particels"), "unknown key 'particels'"),
        (position(text, "mas:"), "unknown key 'mas'"),
        (position(text, "[x, 0, 0, 0]"), "the position of 'bob' has 4 components"),
        (position(text, "q\n"), "unknown name 'q'"),
        (position(text, "x_dot**2"), "constraint 'c' is not linear in the velocities"),
    ]
    errors = [line for line in stderr.splitlines() if ": error: " in line]
    assert len(errors) == len(wanted), stderr
    for error, ((line, column), message) in zip(errors, wanted, strict=True):
        assert error.startswith(f"{path}:{line}:{column}: error: ")
        assert message in error
    assert stderr.count("  expected: ") == len(wanted)


def test_long_sum_is_not_mistaken_for_deep_nesting(tmp_path: Path) -> None:
    """A sum of many terms nests to the left in Python's syntax tree; it is not deep nesting."""
    path = tmp_path / "system.yaml"
    path.write_text(SPRING + "potential: " + " + ".join(f"k*x**{i}/{i}" for i in range(2, 80)) + "\n", encoding="utf-8")
    result = runner.invoke(app, ["derive", str(path)])
    assert result.exit_code == 0, result.output
    assert "x_ddot" in result.stdout


OUTPUTS = [
    ["derive", "simple_pendulum", "-o", "{bad}/eq.tex"],
    ["info", "simple_pendulum", "-o", "{bad}/info.txt"],
    ["check", "systems/simple_pendulum.yaml", "--junit", "{bad}/report.xml"],
    ["simulate", "simple_pendulum", "-o", "{good}/run.csv", "--plot", "{bad}/run.png"],
    ["accuracy", "simple_pendulum", "--method", "DOP853", "--tolerances", "1e-3", "--csv", "{good}/study.csv", "--plot", "{bad}/study.png"],
    ["stress", "simple_pendulum", "--json", "{bad}/stress.json"],
]


@pytest.mark.parametrize("args", OUTPUTS, ids=lambda a: a[0])
def test_an_output_in_a_missing_directory_is_refused_before_any_work(args: list[str], tmp_path: Path) -> None:
    """Exit 2 naming the path and the missing directory; no traceback, and no other output written."""
    bad = tmp_path / "missing"
    filled = [a.format(bad=bad, good=tmp_path) for a in args]
    result = runner.invoke(app, filled)
    assert result.exit_code == 2, result.output
    assert f"the directory {bad} does not exist" in result.output and "Traceback" not in result.output
    assert not isinstance(result.exception, Exception) or isinstance(result.exception, SystemExit)
    assert list(tmp_path.iterdir()) == []


def test_an_output_that_is_a_directory_is_refused(tmp_path: Path) -> None:
    result = runner.invoke(app, ["derive", "simple_pendulum", "-o", str(tmp_path)])
    assert result.exit_code == 2 and "it is a directory" in result.output


def test_a_write_that_fails_late_is_an_error_not_a_traceback(tmp_path: Path) -> None:
    from lagrange_cli.errors import LagrangeError
    from lagrange_cli.files import write_text

    with pytest.raises(LagrangeError, match="cannot write"):
        write_text(tmp_path / "missing" / "file.txt", "text")
    assert list(tmp_path.iterdir()) == []
