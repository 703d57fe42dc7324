"""Fuzzing machinery shared by tests/test_fuzz.py and benchmarks/fuzz.py.

- Hypothesis strategies: `mutated_systems()` takes a bundled system file apart (as YAML data),
  changes one to three things in it (a scalar made hostile, a key deleted or duplicated, a number
  swapped for 0, -1, 1e308, 1e-320, nan or inf, a name swapped for a Python builtin or a name the
  generated code uses, a hostile title, an expression replaced by a generated one) and writes it
  back as text; `expressions(names)` generates expressions from the grammar `lagrange_cli.expr`
  accepts (sums, products, powers with rational and float exponents, every whitelisted function,
  divisions by expressions that can be 0, huge and tiny literals, bounded nesting).
- `run_case(text, folder) -> Outcome`: everything a user can do with a file, in this process,
  through the library functions the commands call: load, derive, every emitter (text and LaTeX in
  every form, standalone LaTeX, Python), the written module imported and its `rhs` called at the
  initial state, `check` (with its JSON and JUnit reports), `info`, a short simulation (scipy,
  t_end <= 0.05) and its report as the CLI renders it; every output written through the CLI's
  atomic writer. Each step ends normally, with the project's own error (`LagrangeError`), or in a
  FAILURE: any other exception, code from the file executed (a PWNED* file appears), file text
  that reaches a sink as live syntax (LaTeX commands, terminal control characters), a complex
  number from the generated `rhs`, a file written by a step that failed, or a hang (a step still
  running after `LIMIT` seconds: a safety net, every case is expected to end far sooner).
"""

from __future__ import annotations

import contextlib
import copy
import functools
import importlib.util
import io
import json
import os
import re
import signal
import sys
import time
import traceback
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parent.parent
SYSTEMS = sorted((ROOT / "systems").glob("*.yaml"))
LIMIT = 90.0
"""Seconds before a command counts as hung: a safety net far above any case (the slowest take a few
seconds on a quiet machine), so that a loaded machine cannot fail the test."""
MARKER = "PWNED"
SIMULATE_T_END = 0.05

# --- what the strategies draw from ------------------------------------------------------------

HOSTILE_TITLES = (
    '"""; import os; os.system(\'touch PWNED\') #',
    'x"""; __import__(\'os\').system(\'touch PWNED\'); """y',
    "x'''; __import__('os').system('touch PWNED'); '''y",
    "C:\\Users\\x\\new\\table",
    "Pendulum\n\\input{/etc/passwd}",
    "Pendulum\n\\immediate\\openout15=PWNED.tex\\immediate\\write15{x}\\immediate\\closeout15",
    "a\n\nb",
    "[/x] [bold]unclosed",
    "$x$ costs $\\notacommand$",
    "\x1b[2J\x1b[Hall checks passed\x1b[0m",
    "nul\x00byte",
    "line\u2028separator\u2029",
    "emoji 🙂 ünïcödé ℏ",
    "\\\\ \\end{document} \\def\\x{y}",
    "% comment } { & # ^ _ ~",
    "\r\ncarriage\r",
    "\x7f\x85\x9b2J",
    "{{ jinja }} ${shell} `backtick` $(touch PWNED)",
    "",
    " ",
)
HOSTILE_NUMBERS = (0, -1, 1, 1e308, -1e308, 1e-320, 5e-324, float("nan"), float("inf"), -float("inf"), 1e300, 1e12, 0.5, "1e300*1e300", "0**x")
HOSTILE_NAMES = (
    "float", "abs", "copysign", "numpy", "np", "math", "hasattr", "p", "p_", "q", "q_", "y", "t_", "None_", "lambda_", "print",
    "PARAMETERS", "COORDINATES", "rhs", "mass_matrix", "forcing", "energy", "_c0", "x0", "xdot", "ymathscr", "hbar", "theta", "range", "len", "sum", "min", "max",
    "int", "list", "tuple", "pi_", "E_", "e", "I", "N", "S", "Q", "O", "beta", "gamma", "zeta", "lambda", "class", "def", "ab", "a" * 200,
)  # fmt: skip
HOSTILE_SCALARS = (*HOSTILE_TITLES, *HOSTILE_NUMBERS, True, None, [], {}, [1, 2], {"a": 1}, "x" * 5000)
FUNCTIONS = {
    "sin": 1,
    "cos": 1,
    "tan": 1,
    "cot": 1,
    "sec": 1,
    "csc": 1,
    "asin": 1,
    "acos": 1,
    "atan": 1,
    "atan2": 2,
    "sinh": 1,
    "cosh": 1,
    "tanh": 1,
    "exp": 1,
    "log": 1,
    "sqrt": 1,
    "Abs": 1,
    "sign": 1,
}
LITERALS = ("0", "1", "2", "-1", "0.5", "3.0", "1e300", "1e-300", "1e-320", "1e308", "123456789012345678901234567890", "pi", "E")
EXPONENTS = ("2", "3", "-1", "-2", "(1/3)", "(2/3)", "(-1/2)", "0.5", "1.5", "0", "20", "(1/7)")


def texts() -> dict[Path, str]:
    return {path: path.read_text(encoding="utf-8") for path in SYSTEMS}


# --- expressions ------------------------------------------------------------------------------


@functools.cache
def expressions(names: tuple[str, ...], max_leaves: int = 12) -> st.SearchStrategy[str]:
    """Expression text from the parser's grammar over `names` (coordinates, parameters, t)."""
    leaves = st.sampled_from([*names, "t"]) | st.sampled_from(LITERALS) if names else st.sampled_from(LITERALS)

    def extend(inner: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
        binary = st.tuples(inner, st.sampled_from(("+", "-", "*", "/")), inner).map(lambda t: f"({t[0]} {t[1]} {t[2]})")
        power = st.tuples(inner, st.sampled_from(EXPONENTS)).map(lambda t: f"({t[0]})**{t[1]}")
        zero_division = st.tuples(inner, inner).map(lambda t: f"{t[0]}/({t[1]} - {t[1]})")
        unary = st.tuples(st.sampled_from(sorted(f for f, n in FUNCTIONS.items() if n == 1)), inner).map(lambda t: f"{t[0]}({t[1]})")
        binary_call = st.tuples(inner, inner).map(lambda t: f"atan2({t[0]}, {t[1]})")
        negate = inner.map(lambda e: f"-({e})")
        return binary | power | unary | binary_call | zero_division | negate

    return st.recursive(leaves, extend, max_leaves=max_leaves)


# --- mutations of bundled files ---------------------------------------------------------------

Path_ = tuple[Any, ...]


def scalar_paths(node: Any, here: Path_ = ()) -> Iterator[Path_]:
    """Every place in the YAML data that holds a scalar (and every mapping key's place)."""
    if isinstance(node, dict):
        for key, value in node.items():
            yield from scalar_paths(value, (*here, key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from scalar_paths(value, (*here, i))
    else:
        yield here


def container_paths(node: Any, here: Path_ = ()) -> Iterator[Path_]:
    if isinstance(node, (dict, list)):
        yield here
        for key, value in node.items() if isinstance(node, dict) else enumerate(node):
            yield from container_paths(value, (*here, key))


def get(node: Any, path: Path_) -> Any:
    for key in path:
        node = node[key]
    return node


def names_of(data: Any) -> tuple[str, ...]:
    """The coordinates and parameters a system file declares."""
    if not isinstance(data, dict):
        return ()
    names = list(data.get("coordinates") or []) if isinstance(data.get("coordinates"), list) else []
    if isinstance(data.get("parameters"), dict):
        names += list(data["parameters"])
    return tuple(str(n) for n in names if isinstance(n, str))


def rename(node: Any, old: str, new: str) -> Any:
    """`old` -> `new` as a whole word in every string and key (x -> float, x_dot -> float_dot)."""
    pattern = re.compile(rf"(?<![A-Za-z0-9_]){re.escape(old)}(?=(_dot|_ddot)?(?![A-Za-z0-9_]))")
    if isinstance(node, dict):
        return {rename(k, old, new): rename(v, old, new) for k, v in node.items()}
    if isinstance(node, list):
        return [rename(v, old, new) for v in node]
    if isinstance(node, str):
        return pattern.sub(new, node)
    return node


KINDS = ("scalar", "number", "name", "title", "expression", "delete", "duplicate", "simulate")


def rotated(items: tuple[Any, ...], by: int) -> tuple[Any, ...]:
    """`items` starting at `by`: hypothesis tries the first choice first, so a rotation per file
    makes the first few examples of each file different from every other file's."""
    by %= len(items)
    return items[by:] + items[:by]


@st.composite
def mutation(draw: st.DrawFn, data: Any, rotate: int = 0) -> tuple[Any, str]:
    """One change to the YAML data: (new data, a word on what changed); a duplicated key is
    marked in the data (DUPLICATE) and written twice by `dump`."""
    kind = draw(st.sampled_from(rotated(KINDS, rotate)))
    if not isinstance(data, dict):
        return data, "none"
    scalars = [p for p in scalar_paths(data) if p]
    if kind == "title":
        data["title" if draw(st.booleans()) else "description"] = draw(st.sampled_from(rotated(HOSTILE_TITLES, rotate)))
        return data, "title"
    if kind == "name":
        names = names_of(data)
        if names:
            old, new = draw(st.sampled_from(names)), draw(st.sampled_from(rotated(HOSTILE_NAMES, rotate)))
            return rename(data, old, new), f"name {old}->{new}"
    if kind == "simulate":
        block = data.setdefault("simulate", {}) if isinstance(data.get("simulate", {}), dict) else {}
        key = draw(st.sampled_from(("t_end", "step", "samples", "rtol", "atol", "method", "max_step")))
        block[key] = draw(st.sampled_from((1e300, 1e-300, 1e12, 5e-324, 0, -1, float("nan"), "symplectic", "Radau", "bogus", [1], 0.01)))
        return data, f"simulate.{key}"
    if kind == "delete" or kind == "duplicate":
        containers = [p for p in container_paths(data) if isinstance(get(data, p), dict) and get(data, p)]
        where = draw(st.sampled_from(containers))
        mapping = get(data, where)
        key = draw(st.sampled_from(sorted(map(str, mapping))))
        if kind == "delete":
            mapping.pop(key, None)
            return data, f"delete {key}"
        mapping[DUPLICATE + key] = mapping.get(key)
        return data, f"duplicate {key}"
    if not scalars:
        return data, "none"
    path = draw(st.sampled_from(scalars))
    parent, last = get(data, path[:-1]), path[-1]
    if kind == "number":
        parent[last] = draw(st.sampled_from(rotated(HOSTILE_NUMBERS, rotate)))
    elif kind == "expression":
        parent[last] = draw(expressions(names_of(data), max_leaves=10))
    else:
        parent[last] = draw(st.sampled_from(rotated(HOSTILE_SCALARS, rotate)))
    return data, f"{kind} at {'.'.join(map(str, path))}"


DUPLICATE = "\x00dup\x00"


def dump(data: Any) -> str:
    """YAML text of the data; a key marked DUPLICATE appears twice in its mapping."""
    text = yaml.safe_dump(data, allow_unicode=True, sort_keys=False, width=10**6)
    return re.sub(r'"\\0dup\\0([^"]*)"', r"\1", text)


@functools.cache
def _data(path: Path) -> Any:
    return yaml.safe_load(path.read_text(encoding="utf-8"))


@st.composite
def mutated_systems(draw: st.DrawFn, max_mutations: int = 3, path: Path | None = None, rotate: int = 0) -> str:
    """A bundled system file (`path`, else any) with one to `max_mutations` hostile changes, as
    text; `rotate` shifts the order of the choices (see `rotated`)."""
    path = path if path is not None else draw(st.sampled_from(SYSTEMS))
    data = copy.deepcopy(_data(path))
    for i in range(draw(st.integers(1, max_mutations))):
        data, _ = draw(mutation(data, rotate + 3 * i))
    return dump(data)


@st.composite
def generated_systems(draw: st.DrawFn) -> str:
    """A small system whose potential, mass and dissipation are generated expressions."""
    coordinates = draw(st.sampled_from((("x",), ("x", "y"), ("theta",))))
    parameters = draw(st.lists(st.sampled_from(("m", "k", "g", "l", "p", "p_", "float", "abs", "numpy")), min_size=1, max_size=3, unique=True))
    names = (*coordinates, *parameters)
    data: dict[str, Any] = {
        "title": draw(st.sampled_from(("Generated", *HOSTILE_TITLES))),
        "coordinates": list(coordinates),
        "parameters": {p: {"value": draw(st.sampled_from((1.0, 2.0, 0.5, 1e-3)))} for p in parameters},
        "particles": {"a": {"mass": draw(st.sampled_from(("1", parameters[0], *(draw(expressions(names, 4)),)))), "position": list(coordinates)}},
        "potential": draw(expressions(names)),
        "initial": {c: draw(st.sampled_from((0.0, 0.5, 1.0, -0.3))) for c in coordinates},
    }
    if draw(st.booleans()):
        data["dissipation"] = draw(expressions((*names, *(f"{c}_dot" for c in coordinates)), 6))
    if draw(st.booleans()):
        data["expect"] = {"equations": [f"{coordinates[0]}_ddot = {draw(expressions(names, 6))}"], "conserved": ["energy"]}
    return dump(data)


def cases() -> st.SearchStrategy[str]:
    return mutated_systems() | generated_systems()


# --- running one case -------------------------------------------------------------------------


class Hang(BaseException):
    """A step ran past LIMIT (a BaseException, so that no `except Exception` in the code swallows it)."""


@dataclass
class Failure:
    step: str
    kind: str
    detail: str
    where: str = ""

    @property
    def key(self) -> str:
        """What makes two failures the same: the kind (exception type) and where it came from."""
        return f"{self.step.split(':')[0]}: {self.kind} at {self.where}" if self.where else f"{self.step.split(':')[0]}: {self.kind}"


@dataclass
class Outcome:
    steps: dict[str, str] = field(default_factory=dict)
    """step -> "ok" or "error: <first line of the LagrangeError>"."""
    failures: list[Failure] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)
    """step -> seconds it took (for benchmarks/fuzz.py's profile)."""

    @property
    def failed(self) -> bool:
        return bool(self.failures)

    def summary(self) -> str:
        return "\n".join(f"{f.step}: {f.kind} at {f.where}: {f.detail}" for f in self.failures)


CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")  # C0 but tab and newline (\r rewrites the line), DEL, C1 (\x9b is CSI)
LATEX_PRIMITIVES = re.compile(r"\\(input|include|openout|openin|write|immediate|read|csname|catcode|def|edef|gdef|let|newcommand|renewcommand|special|end\{document\})")


def innermost(error: BaseException) -> str:
    """The innermost frame in lagrange_cli (or in a generated module): file:function."""
    if isinstance(error, SyntaxError):  # the expression parser turns its own into SpecError: this one is a generated module's
        return "<generated>:import"
    frames = traceback.extract_tb(error.__traceback__)
    for frame in reversed(frames):
        name = frame.filename.replace("\\", "/")
        if "/lagrange_cli/" in name:
            return f"{name.rsplit('/lagrange_cli/', 1)[1]}:{frame.name}"
        if "lagrange_" in Path(name).name or name.endswith("module.py"):
            return f"<generated>:{frame.name}"
    return f"{Path(frames[-1].filename).name}:{frames[-1].name}" if frames else "?"


@contextlib.contextmanager
def alarm(seconds: float) -> Iterator[None]:
    """Raise Hang after `seconds` of this process's CPU time (a safety net; main thread only).

    CPU time (ITIMER_PROF), not wall time, so that the load of other programs cannot trip it."""

    def expire(signum: int, frame: object) -> None:
        raise Hang

    if not hasattr(signal, "setitimer") or seconds <= 0:
        yield
        return
    previous = signal.signal(signal.SIGPROF, expire)
    signal.setitimer(signal.ITIMER_PROF, seconds, 1.0)  # again every CPU second: an exception raised in a gc callback is dropped
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, previous)


class Runner:
    """The steps of one case, each judged as it ends."""

    def __init__(self, folder: Path, limit: float) -> None:
        self.folder, self.out, self.limit = folder, folder / "out", limit
        self.out.mkdir(parents=True, exist_ok=True)
        self.outcome = Outcome()

    def step(self, name: str, action: Callable[[], Any]) -> Any:
        """Run one step; None unless it ended normally."""
        from lagrange_cli.errors import LagrangeError

        before = self.written()
        start = time.perf_counter()
        try:
            with alarm(self.limit):
                result = action()
        except LagrangeError as error:
            message = str(error)
            self.outcome.steps[name] = "error: " + (message.splitlines()[0] if message else "")
            if not message.strip():
                self.fail(name, "empty error message", "", "")
            elif CONTROL.search(message):
                self.fail(name, "control character in an error message", repr(CONTROL.search(message).group()), "")  # type: ignore[union-attr]
            if self.written() - before:
                self.fail(name, "file written by a step that failed", str(sorted(self.written() - before)), "")
            return None
        except Hang:
            self.fail(name, "hang", f"over {self.limit:g} s", "")
            return None
        except RecursionError as error:
            self.fail(name, "RecursionError", str(error)[:200], innermost(error))
            return None
        except Exception as error:
            self.fail(name, type(error).__name__, f"{error}"[:300], innermost(error))
            return None
        finally:
            self.outcome.seconds[name] = time.perf_counter() - start
        self.outcome.steps[name] = "ok"
        return result

    def fail(self, step: str, kind: str, detail: str, where: str) -> None:
        self.outcome.failures.append(Failure(step, kind, detail, where))

    def written(self) -> set[str]:
        return {p.name for p in self.out.iterdir()}

    def write(self, name: str, text: str) -> None:
        from lagrange_cli.files import write_text

        write_text(self.out / name, text)


def run_case(text: str, folder: Path, limit: float = LIMIT, simulate: bool = True, full: bool = True) -> Outcome:
    """Everything a user can do with the system file `text`, in this process (see the module
    docstring); with `full=False` only the cheap steps: load, derive, the Lagrange form in text and
    LaTeX, standalone LaTeX, Python and its rhs (`simulate` needs `full`)."""
    folder.mkdir(parents=True, exist_ok=True)
    saved_cwd, saved_cache = os.getcwd(), os.environ.get("LAGRANGE_CACHE_DIR")
    os.chdir(folder)
    os.environ["LAGRANGE_CACHE_DIR"] = str(folder / "cache")
    runner = Runner(folder, limit)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # as on the command line, a warning (numpy's overflow, say) is not a failure, also under pytest's "error" filter
            _steps(runner, text, simulate and full, full)
    finally:
        os.chdir(saved_cwd)
        if saved_cache is None:
            os.environ.pop("LAGRANGE_CACHE_DIR", None)
        else:
            os.environ["LAGRANGE_CACHE_DIR"] = saved_cache
        _forget_generated()
    for marker in [*folder.rglob(f"{MARKER}*"), *Path(saved_cwd).glob(f"{MARKER}*")]:
        runner.fail("any", "code from the file executed", str(marker), "")
        marker.unlink(missing_ok=True)
    return runner.outcome


def _steps(runner: Runner, text: str, simulate: bool, full: bool) -> None:
    from lagrange_cli import analysis, derive, report, spec
    from lagrange_cli import check as checker
    from lagrange_cli.emit import latex, python
    from lagrange_cli.emit import text as plain

    path = runner.folder / "case.yaml"
    path.write_text(text, encoding="utf-8")
    system = runner.step("load", lambda: spec.load(path))
    if system is None:
        return
    model = runner.step("derive", lambda: derive.derive(system))
    if model is None:
        return
    for form in ("lagrange", "matrix", "solved") if full else ("lagrange",):
        result = runner.step(f"text:{form}", lambda form=form: plain.emit(model, form))
        if result is not None:
            _terminal(runner, f"text:{form}", result)
            runner.step(f"write:text:{form}", lambda result=result, form=form: runner.write(f"{form}.txt", result))
        result = runner.step(f"latex:{form}", lambda form=form: latex.emit(model, form))
        if result is not None:
            _latex(runner, f"latex:{form}", result, standalone=False)
            runner.step(f"write:latex:{form}", lambda result=result, form=form: runner.write(f"{form}.tex", result))
    document = runner.step("latex:standalone", lambda: latex.emit(model, "lagrange", standalone=True))
    if document is not None:
        _latex(runner, "latex:standalone", document, standalone=True)
        runner.step("write:latex:standalone", lambda: runner.write("standalone.tex", document))
    module = runner.step("python", lambda: python.emit(model))
    if module is not None:
        runner.step("write:python", lambda: runner.write("module.py", module))
        if runner.outcome.steps.get("write:python") == "ok":
            _rhs(runner, model)
    if not full:
        return
    reports = runner.step("check", lambda: [checker.FileReport(str(path), tuple(checker.check(system, model)))])  # what check_file does after load and derive
    if reports is not None:
        for item in reports:
            if item.error:
                _terminal(runner, "check", item.error)
        junit = runner.step("check:junit", lambda: checker.to_junit(reports))
        if junit is not None:
            runner.step("check:junit:xml", lambda: ET.fromstring(junit.split("\n", 1)[1]))
        runner.step("check:json", lambda: json.loads(checker.to_json(reports)))
    found = runner.step("info", lambda: analysis.info(model))
    if found is not None:
        rendered = runner.step("info:text", lambda: report.info_text(model, found))
        if rendered is not None:
            _terminal(runner, "info:text", rendered)
    if simulate:
        _simulate(runner, model)


def _terminal(runner: Runner, step: str, text: str) -> None:
    if CONTROL.search(text):
        runner.fail(step, "control character in terminal output", repr(CONTROL.search(text).group()), "")  # type: ignore[union-attr]


def _latex(runner: Runner, step: str, text: str, standalone: bool) -> None:
    """File text must not become LaTeX: no primitives beyond the template's, comments stay comments."""
    lines = re.split(r"\r\n|\r|\n", text)  # what TeX reads as line ends (not Python's splitlines: \x85, U+2028)
    code = "\n".join(re.sub(r"(?<!\\)%.*", "", line) for line in lines)  # comments removed
    code = code.replace("\\end{document}\n", "") if standalone else code
    if LATEX_PRIMITIVES.search(code):
        runner.fail(step, "LaTeX command from file text", LATEX_PRIMITIVES.search(code).group(), "")  # type: ignore[union-attr]
    head = text.split("\\begin{align*}")[0]
    lines = [line for line in re.split(r"\r\n|\r|\n", head) if line]
    if not standalone and any(not line.startswith("%") for line in lines):
        runner.fail(step, "file text outside the LaTeX comment", repr(head[:120]), "")
    if standalone and re.search(r"\\section\*\{[^}]*\n\s*\n", head):
        runner.fail(step, "blank line in the LaTeX section title", repr(head[-120:]), "")


def _rhs(runner: Runner, model: Any) -> None:
    """Import the written module and call rhs at the initial state: a real list of numbers, or an
    arithmetic error of the point (ZeroDivisionError, math domain error), nothing else."""
    path = runner.out / "module.py"

    def call() -> list[Any]:
        found = importlib.util.spec_from_file_location("lagrange_fuzz_module", path)
        assert found is not None and found.loader is not None
        module = importlib.util.module_from_spec(found)
        found.loader.exec_module(module)
        y = [float(model.initial.get(c, 0.0)) for c in model.coordinates] + [float(model.initial.get(f"{c}_dot", 0.0)) for c in model.coordinates]
        p = {q.name: 1.0 if q.value is None else q.value for q in model.parameters}  # the module's PARAMETERS lack those without a value
        try:
            return list(module.rhs(0.0, y, p))
        except (ArithmeticError, ValueError) as error:
            if isinstance(error, ValueError) and "math domain error" not in str(error):
                raise
            return []

    values = runner.step("python:rhs", call)
    if values and any(isinstance(v, complex) for v in values):
        runner.fail("python:rhs", "complex value from the generated rhs", str(values)[:200], "")
    elif values and not all(isinstance(v, (int, float)) for v in values):
        runner.fail("python:rhs", "non-number from the generated rhs", str([type(v).__name__ for v in values]), "")


def _simulate(runner: Runner, model: Any) -> None:
    from lagrange_cli.numeric import output
    from lagrange_cli.numeric.simulate import simulate

    configured = model.simulate.get("t_end") if isinstance(model.simulate, dict) or hasattr(model.simulate, "get") else None
    t_end = configured if isinstance(configured, (int, float)) and not isinstance(configured, bool) and 0 < configured < SIMULATE_T_END else SIMULATE_T_END
    trajectory = runner.step("simulate", lambda: simulate(model, t_end=t_end, backend="python", samples=11))
    if trajectory is None:
        return
    if trajectory.failed and not trajectory.message:
        runner.fail("simulate", "failed run without a message", "", "")
    runner.step("simulate:csv", lambda: runner.write("trajectory.csv", output.csv_text(trajectory)))
    from lagrange_cli.cli.numeric import _report

    printed = io.StringIO()

    def render() -> None:
        with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(printed):
            _report(trajectory, to_stderr=False)

    runner.step("simulate:report", render)
    _terminal(runner, "simulate:report", printed.getvalue())


def _forget_generated() -> None:
    """Each case is a fresh run of the tool: drop the modules that lagrange_cli.numeric.compile
    remembers in this process (they would also keep every case's model alive)."""
    compile_module = sys.modules.get("lagrange_cli.numeric.compile")
    if compile_module is not None:
        for name in ("_LOADED", "_FINGERPRINTS"):
            remembered = getattr(compile_module, name, None)
            if isinstance(remembered, dict):
                remembered.clear()
    for name in [n for n in sys.modules if n.startswith(("lagrange_python_", "lagrange_numba_", "lagrange_fuzz_"))]:
        del sys.modules[name]
