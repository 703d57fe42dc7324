"""The C target in its real toolchain: every bundled system (and every feature of tests/matrix) emits a
header that compiles cleanly as C99 (`gcc -std=c99 -Wall -Wextra -Werror -pedantic -O2`) and as C++
(`g++ -Wall -Wextra -Werror`), and whose `eom_rhs` and `eom_energy` agree with the Python module at
seeded random states. All headers go into one generated harness per compiler (one compile each), so
the file stays fast. Hostile titles and names compile and inject nothing."""

from __future__ import annotations

import functools
import inspect
import math
import random
import re
import shutil
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.emit import c, python
from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model

from .conftest import ROOT
from .helpers import load_module, model_from, model_of

GCC = ["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2"]
GXX = ["g++", "-Wall", "-Wextra", "-Werror", "-x", "c++"]
COMPILERS = {"gcc-c99": GCC, "g++": GXX}
STATES = 4
RTOL = 1e-9

SYSTEMS = sorted((ROOT / "systems").glob("*.yaml"))
FEATURES = sorted((ROOT / "tests" / "matrix").glob("*.yaml"))
HOSTILE = sorted(p for p in (ROOT / "tests" / "hostile").glob("*.yaml") if p.name.startswith(("name_", "title_", "filename_", "params_", "standalone_", "path_", "junit_", "expression_")))
"""The hostile files about titles, names and file names."""

C_HOSTILE = {
    "comment_close": 'title: "*/ #error injected /* ??/ ??= ??) trailing \\\\"\n',
    "backslash_end": 'title: "ends in a backslash \\\\"\n',
    "control": 'title: "nul \\0 esc \\e[2J bidi \\u202e sep \\u2028 */\\n#error second line"\n',
}
"""Titles aimed at C: ending the comment, trigraphs (`??/` is a line splice under -std=c99), a line
splice by a trailing backslash, control and bidi characters, a line break followed by a directive."""
C_NAMES = """title: C keywords, macros, math.h names and the generated names as user names
coordinates: [int, unix, M_PI, dydt, linux]
parameters: {eom_rhs: 1.0, EOM_NQ: 2.0, NAN: 1.5, double: 9.81, y: 1.0, out: 0.5, errno: 2.0, x0: 1.0, HUGE_VAL: 1.0, WNOHANG: 1.0, asm: 2.0}
particles:
  a: {mass: eom_rhs*asm, position: [int, unix]}
  b: {mass: EOM_NQ + NAN, position: [M_PI*double, dydt*y + out + errno*x0]}
  c: {mass: 1, position: [linux]}
potential: double*int**2/2 + HUGE_VAL*unix**2/2 + WNOHANG*M_PI**2 + dydt**2 + linux**2
"""
PENDULUM = "coordinates: [theta]\nparameters: {m: 1.0, l: 2.0, g: 9.81}\ngravity: [0, -g]\nparticles:\n  bob: {mass: m, position: [l*sin(theta), -l*cos(theta)]}\n"


@dataclass
class Case:
    label: str
    model: Model
    prefix: str
    states: list[tuple[float, list[float], dict[str, float]]]
    compare: bool = True

    @functools.cached_property
    def code(self) -> str:
        return c.emit(self.model, name=self.prefix)

    @functools.cached_property
    def python(self) -> Any:
        """The Python module (`lagrange derive --python`), imported."""
        import tempfile

        with tempfile.TemporaryDirectory() as folder:
            return load_module(python.emit(self.model), Path(folder) / f"py_{self.prefix}.py")


def toolchain(name: str) -> str:
    found = shutil.which(name)
    if found is None:
        pytest.fail(f"{name} is not installed: `make test` installs it (the toolchains target of the Makefile)")
    return found


def states(model: Model, seed: int, count: int = STATES) -> list[tuple[float, list[float], dict[str, float]]]:
    """Seeded random states: coordinates in [0.2, 1.3], velocities in [-1, 1], t in [0, 2], and the
    parameters' defaults each scaled by a random factor in [0.8, 1.25]."""
    rng = random.Random(seed)
    out = []
    for _ in range(count):
        p = {q.name: (q.value if q.value is not None else 1.0) * rng.uniform(0.8, 1.25) for q in model.parameters}
        y = [rng.uniform(0.2, 1.3) for _ in model.q] + [rng.uniform(-1.0, 1.0) for _ in model.qd]
        out.append((rng.uniform(0.0, 2.0), y, p))
    return out


def given_inputs(model: Model, t: float, y: Sequence[float]) -> dict[str, float]:
    """Random input values at the state (t, y), the same for every target's test (seeded by the state):
    what the Python module's `u=` and the C and Octave `u` get ({} for a model without inputs)."""
    rng = random.Random(repr((t, [float(v) for v in y])))
    return {i.name: rng.uniform(-2.0, 2.0) for i in model.inputs}


def with_inputs(function: Any, *args: Any, u: dict[str, float]) -> Any:
    """Call a Python-module function with `u` when it takes inputs."""
    return function(*args, u=u) if u and "u" in inspect.signature(function).parameters else function(*args)


def literal(values: Sequence[float]) -> str:
    return "{" + ", ".join(repr(float(v)) for v in values) + "}" if values else "{0.0}"


def harness(cases: list[Case]) -> str:
    """A C program calling each case's rhs, multipliers (with kept constraints) and energy at its
    states (one loop per case, so that each header's functions are inlined once), printing
    `case state status dydt... lambda... energy` with 17 significant digits."""
    lines = ["#include <stdio.h>", *(f'#include "{case.prefix}.h"' for case in cases), "", "int main(void)", "{", "    int k, j;"]
    for i, case in enumerate(cases):
        n, count, np_ = case.model.n, len(case.states), max(1, len(case.model.parameters))
        u = ", u[k]" if case.model.inputs else ""  # random inputs at each state (given_inputs), as the Python module's `u=`
        ys = ", ".join(literal(y) for _, y, _ in case.states)
        ps = ", ".join(literal([p[q.name] for q in case.model.parameters]) for _, _, p in case.states)
        us = ", ".join(literal(list(given_inputs(case.model, t, y).values())) for t, y, _ in case.states)
        lines += [
            "    {",
            f"        static const double t[{count}] = {literal([t for t, _, _ in case.states])};",
            f"        static const double y[{count}][{2 * n}] = {{{ys}}};",
            f"        static const double p[{count}][{np_}] = {{{ps}}};",
            *([f"        static const double u[{count}][{len(case.model.inputs)}] = {{{us}}};"] if case.model.inputs else []),
            f"        for (k = 0; k < {count}; ++k) {{",
            f"            double d[{2 * n}];",
            f"            const int status = {case.prefix}_rhs(t[k], y[k], p[k]{u}, d);",
            f'            printf("{i} %d %d", k, status);',
            f'            for (j = 0; j < {2 * n}; ++j) printf(" %.17g", d[j]);',
            *(
                [
                    "            {",
                    f"                double x[{n + len(case.model.constraints)}];",
                    f"                {case.prefix}_accelerations(t[k], y[k], p[k]{u}, x);",
                    f'                for (j = {n}; j < {n + len(case.model.constraints)}; ++j) printf(" %.17g", x[j]);',
                    "            }",
                ]
                if case.model.constraints
                else []
            ),
            f'            printf(" %.17g\\n", {case.prefix}_energy(t[k], y[k], p[k]{u}));',
            "        }",
            "    }",
        ]
    return "\n".join([*lines, "    return 0;", "}", ""])


def build_and_run(cases: list[Case], folder: Path, compiler: list[str]) -> dict[tuple[int, int], tuple[int, list[float], float]]:
    """Write the headers and the harness, compile once, run: (case, state) -> (status, dydt, energy)."""
    folder.mkdir(parents=True, exist_ok=True)
    for case in cases:
        (folder / f"{case.prefix}.h").write_text(case.code, encoding="ascii")
    (folder / "harness.c").write_text(harness(cases), encoding="ascii")
    toolchain(compiler[0])
    executable = folder / f"harness-{compiler[0]}"
    built = subprocess.run([*compiler, "-I", str(folder), str(folder / "harness.c"), "-o", str(executable), "-lm"], capture_output=True, text=True, check=False)
    assert built.returncode == 0 and not built.stderr, f"{' '.join(compiler)} failed:\n{built.stderr[-4000:]}"
    ran = subprocess.run([str(executable)], capture_output=True, text=True, check=True)
    results = {}
    for line in ran.stdout.splitlines():
        i, k, status, *values = line.split()
        numbers = [float(v) for v in values]
        results[(int(i), int(k))] = (int(status), numbers[:-1], numbers[-1])
    return results


def python_values(module: Any, model: Model, t: float, y: list[float], p: dict[str, float]) -> tuple[list[float] | None, float | None]:
    """rhs (followed by the multipliers, with kept constraints) and energy from the Python module
    (None where it raises: a singular matrix or a domain error), at the inputs `given_inputs(model, t, y)`."""
    n = model.n
    u = given_inputs(model, t, y)
    arguments: list[Any] = [y[:n], y[n:], p]
    if "t" in inspect.signature(module.energy).parameters:
        arguments.insert(0, t)
    values: list[Any] = []
    multipliers = (lambda: list(with_inputs(module.multipliers, t, y, p, u=u))) if model.constraints else list
    for call in (lambda: [float(v) for v in [*with_inputs(module.rhs, t, y, p, u=u), *multipliers()]], lambda: float(with_inputs(module.energy, *arguments, u=u))):
        try:
            values.append(call())
        except (ZeroDivisionError, ValueError, OverflowError):
            values.append(None)
    return values[0], values[1]


def compare(cases: list[Case], results: dict[tuple[int, int], tuple[int, list[float], float]]) -> None:
    """C and Python agree to RTOL, or both fail: Python raises where C returns non-zero (rhs) or NaN (energy)."""
    problems = []
    for i, case in enumerate(cases):
        if not case.compare:
            continue
        for k, (t, y, p) in enumerate(case.states):
            status, dydt, energy = results[(i, k)]
            want, want_energy = python_values(case.python, case.model, t, y, p)
            if want is None:
                if status == 0:
                    problems.append(f"{case.label} state {k}: Python's rhs raises, C returns 0")
            elif status != 0 or not all(math.isclose(a, b, rel_tol=RTOL, abs_tol=RTOL * max(abs(v) for v in want)) for a, b in zip(dydt, want, strict=True)):
                problems.append(f"{case.label} state {k}: C status {status} {dydt} != Python {want}")
            if want_energy is None:
                if math.isfinite(energy):
                    problems.append(f"{case.label} state {k}: Python's energy raises, C gives {energy}")
            elif not math.isclose(energy, want_energy, rel_tol=RTOL, abs_tol=RTOL * max(1.0, abs(want_energy))):
                problems.append(f"{case.label} state {k}: C energy {energy} != Python {want_energy}")
    assert not problems, "\n".join(problems)


@pytest.fixture(scope="module")
def bundled() -> list[Case]:
    """Every bundled system and every matrix feature C can express (all but undefined functions)."""
    cases = []
    for seed, path in enumerate([*SYSTEMS, *FEATURES]):
        if path.stem.startswith("functions_undefined"):
            continue
        model = model_from(path)
        cases.append(Case(path.name, model, f"s{seed}", states(model, seed)))
    return cases


@pytest.mark.parametrize("compiler", COMPILERS)
def test_every_bundled_system_compiles_and_agrees_with_python(compiler: str, bundled: list[Case], tmp_path: Path) -> None:
    assert len(bundled) >= len(SYSTEMS) + 10
    results = build_and_run(bundled, tmp_path, COMPILERS[compiler])
    assert len(results) == STATES * len(bundled)
    compare(bundled, results)


def test_a_singular_mass_matrix_or_a_nan_state_returns_nonzero(tmp_path: Path) -> None:
    """The spherical pendulum's M = diag(m l^2, m l^2 sin^2 theta) is singular at theta = 0 (1);
    a NaN in the state is not finite (2); an ordinary state is 0."""
    model = model_from(ROOT / "systems" / "spherical_pendulum.yaml")
    p = {q.name: q.value for q in model.parameters}
    case = Case("spherical", model, "sph", [(0.0, [0.0, 0.3, 0.1, 0.2], p), (0.0, [math.nan, 0.3, 0.1, 0.2], p), (0.0, [0.5, 0.3, 0.1, 0.2], p)])
    (tmp_path / "sph.h").write_text(c.emit(model, name="sph"))
    text = harness([case]).replace("{nan, ", "{NAN, ")
    (tmp_path / "harness.c").write_text(text)
    toolchain("gcc")
    subprocess.run([*GCC, str(tmp_path / "harness.c"), "-o", str(tmp_path / "h"), "-lm"], check=True)
    out = subprocess.run([str(tmp_path / "h")], capture_output=True, text=True, check=True).stdout.splitlines()
    assert [line.split()[2] for line in out] == ["1", "2", "0"]
    with pytest.raises(ZeroDivisionError):
        load_module(python.emit(model), tmp_path / "sph.py").rhs(0.0, [0.0, 0.3, 0.1, 0.2])


@pytest.fixture(scope="module")
def hostile_cases() -> tuple[list[Case], list[str]]:
    cases, refused = [], []
    texts = {f"hostile/{p.name}": p.read_text(encoding="utf-8", errors="surrogateescape") for p in HOSTILE}
    texts |= {f"c/{name}.yaml": title + PENDULUM for name, title in C_HOSTILE.items()}
    texts["c/names.yaml"] = C_NAMES
    for seed, (label, text) in enumerate(sorted(texts.items())):
        try:
            model = model_of(text, name=label.split("/")[1])
            c.emit(model)
        except (LagrangeError, UnicodeError):
            refused.append(label)
            continue
        try:
            python.emit(model)
            comparable = True
        except Exception:  # the Python target's own limits (not this file's subject): compile only
            comparable = False
        cases.append(Case(label, model, f"h{seed}", states(model, seed, 1), comparable))
    return cases, refused


@pytest.mark.parametrize("compiler", COMPILERS)
def test_hostile_titles_and_names_compile_and_inject_nothing(compiler: str, hostile_cases: tuple[list[Case], list[str]], tmp_path: Path) -> None:
    """Every file of tests/hostile that C can express, and titles and names aimed at C: the header is
    printable ASCII, the title is in a comment that it cannot close, and the code still agrees."""
    cases, refused = hostile_cases
    assert len(cases) >= 20
    assert {"c/comment_close.yaml", "c/backslash_end.yaml", "c/control.yaml", "c/names.yaml"} <= {case.label for case in cases}, refused
    for case in cases:
        code = c.emit(case.model, name=case.prefix)
        assert all(ch == "\n" or " " <= ch <= "~" for ch in code), case.label
        comments = re.sub(r"/\*.*?\*/", "", code, flags=re.S)
        assert "#error" not in comments and "??" not in code and not re.search(r"\\\n", code), case.label
    results = build_and_run(cases, tmp_path, COMPILERS[compiler])
    compare(cases, results)


def test_user_names_never_meet_c_names() -> None:
    model = model_of(C_NAMES)
    names = c.c_names(model, "eom")
    taken = {*c.C_KEYWORDS, *c.MATH_H, *c.MACROS, *c.LOCALS, *c.generated("eom")}
    assert not taken & {v for k, v in names.items() if k != "t"}
    assert len(set(names.values())) == len(names)
    assert names["M_PI"] != "M_PI" and names["EOM_NQ"] != "EOM_NQ" and names["eom_rhs"] != "eom_rhs" and names["unix"] != "unix"
    pendulum = c.c_names(model_of("coordinates: [pend_rhs]\nparameters: {m: 1.0}\nparticles:\n  a: {mass: m, position: [pend_rhs]}\n"), "pend")
    assert pendulum["pend_rhs"] != "pend_rhs"


def test_comment_text_cannot_end_a_comment_or_form_a_trigraph() -> None:
    for text in ["*/", "/*", "??/", "???/", "a\\", "*/*/", "x\n#error", "\u202e"]:
        out = c.comment(text)
        assert "*/" not in out and "/*" not in out and "??" not in out and not out.endswith("\\") and out.isascii() and "\n" not in out


# -- the command line ---------------------------------------------------------------------------------

runner = CliRunner()


def test_derive_to_c_writes_the_header(tmp_path: Path) -> None:
    out = tmp_path / "pendulum.h"
    result = runner.invoke(app, ["derive", "double_pendulum", "--to", "c", "--prefix", "dp", "-o", str(out)])
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert "static inline int dp_rhs(double t, const double *y, const double *p, double *dydt)" in text
    assert "#define DP_NQ 2" in text and "#define DP_NP 3" in text and "dp_default_parameters[3] = {1.0, 1.0, 9.81}" in text
    assert text == c.emit(model_from(ROOT / "systems" / "double_pendulum.yaml"), name="dp")
    assert "#include" in text and set(re.findall(r"#include <(\w+\.h)>", text)) == {"math.h"}


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--to", "c", "--prefix", "2bad"], "--prefix '2bad' is not usable as the prefix of C names"),
        (["--to", "c", "--prefix", "a-b"], "is not usable as the prefix of C names"),
        (["--to", "c", "--prefix", "int"], "is not usable as the prefix of C names"),
        (["--to", "text", "--prefix", "x"], "--prefix applies to --to c output"),
        (["--to", "c", "--python"], "choose one of --to, --text, --latex, --python"),
        (["--to", "c", "--numba"], "--numba applies to --python output"),
        (["--to", "c", "--standalone"], "--standalone applies to --latex output"),
        (["--to", "fortran"], "Invalid value for '--to'"),
    ],
)
def test_bad_options_are_exit_2_with_nothing_written(args: list[str], message: str, tmp_path: Path) -> None:
    out = tmp_path / "x.h"
    result = runner.invoke(app, ["derive", "double_pendulum", *args, "-o", str(out)])
    assert result.exit_code == 2 and message in result.output, result.output
    assert "Traceback" not in result.output and not out.exists()


def test_a_missing_target_module_is_a_clean_exit_2(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from lagrange_cli.cli import derive as command

    monkeypatch.setitem(command.TARGETS, "jax", "lagrange_cli.emit.no_such_target")
    out = tmp_path / "x.py"
    result = runner.invoke(app, ["derive", "double_pendulum", "--to", "jax", "-o", str(out)])
    assert result.exit_code == 2 and "the jax target is not available in this installation" in result.output, result.output
    assert not out.exists()


def test_an_undefined_function_is_refused_with_nothing_written(tmp_path: Path) -> None:
    out = tmp_path / "x.h"
    result = runner.invoke(app, ["derive", str(ROOT / "tests" / "matrix" / "functions_undefined_energy.yaml"), "--to", "c", "-o", str(out)])
    assert result.exit_code == 2 and "C code needs every function defined, but U is left undefined" in result.output, result.output
    assert not out.exists()


def test_the_aliases_are_the_targets() -> None:
    for alias in ("text", "latex", "python"):
        assert runner.invoke(app, ["derive", "simple_pendulum", f"--{alias}"]).stdout == runner.invoke(app, ["derive", "simple_pendulum", "--to", alias]).stdout


def readme_block(heading: str, language: str) -> str:
    """The first ```language block after `heading` in README.md."""
    text = (ROOT / "README.md").read_text(encoding="utf-8").split(heading, 1)[1]
    found = re.search(rf"```{language}\n(.*?)```", text, re.S)
    assert found, f"README.md has no {language} example under {heading}"
    return found.group(1)


def test_the_readme_rk4_example_compiles_runs_and_conserves_energy(tmp_path: Path) -> None:
    source = readme_block("### Generated C", "c")
    assert len(source.strip().splitlines()) <= 20
    model = model_from(ROOT / "systems" / "double_pendulum.yaml")
    (tmp_path / "eom.h").write_text(c.emit(model))
    (tmp_path / "rk4.c").write_text(source)
    toolchain("gcc")
    built = subprocess.run([*GCC, str(tmp_path / "rk4.c"), "-o", str(tmp_path / "rk4"), "-lm"], capture_output=True, text=True, check=False)
    assert built.returncode == 0 and not built.stderr, built.stderr
    out = subprocess.run([str(tmp_path / "rk4")], capture_output=True, text=True, check=True).stdout
    energy = float(re.search(r"energy (\S+)", out).group(1))  # type: ignore[union-attr]
    initial = python.emit(model)
    module = load_module(initial, tmp_path / "dp.py")
    assert energy == pytest.approx(module.energy([1.0, 0.5], [0.0, 0.0]), abs=1e-6)


def test_ldlt_hands_an_indefinite_matrix_to_the_lu_solve(tmp_path: Path) -> None:
    """The straight-line LDL^T refuses [[0, 1], [1, 0]] (no positive pivot) and leaves b alone; the LU
    solve with pivoting then solves it; a singular [[1, 1], [1, 1]] is 1 for both."""
    (tmp_path / "eom.h").write_text(c.emit(model_from(ROOT / "systems" / "double_pendulum.yaml")))
    (tmp_path / "t.c").write_text(
        '#include <stdio.h>\n#include "eom.h"\nint main(void)\n{\n'
        "    double a[4] = {0.0, 1.0, 1.0, 0.0}, b[2] = {2.0, 3.0}, s[4] = {1.0, 1.0, 1.0, 1.0}, c[2] = {1.0, 2.0};\n"
        "    const int first = eom_ldlt(a, b);\n"
        '    printf("%d %g %g ", first, b[0], b[1]);\n'
        "    const int second = eom_solve(2, a, b);\n"
        '    printf("%d %g %g ", second, b[0], b[1]);\n'
        "    const int third = eom_ldlt(s, c);\n"
        '    printf("%d %d\\n", third, eom_solve(2, s, c));\n'
        "    return 0;\n}\n"
    )
    toolchain("gcc")
    subprocess.run([*GCC, str(tmp_path / "t.c"), "-o", str(tmp_path / "t"), "-lm"], check=True)
    assert subprocess.run([str(tmp_path / "t")], capture_output=True, text=True, check=True).stdout.split() == ["1", "2", "3", "0", "3", "2", "1", "1"]


# -- --form hamilton (shared with tests/test_target_octave.py) ------------------------------------------


@dataclass
class HamiltonPoint:
    """A state (q, q_dot) mapped to y = [q, p] by the Python Hamilton module, with that module's dy/dt and H
    there, and the Lagrange form's energy (which H must equal)."""

    t: float
    y: list[float]
    p: dict[str, float]
    velocities: list[float]
    rhs: list[float]
    hamiltonian: float
    energy: float
    u: dict[str, float]


@functools.lru_cache(maxsize=1)
def hamilton_cases() -> list[tuple[str, Model, list[HamiltonPoint] | None]]:
    """Every bundled system with its Hamilton points (None where `--form hamilton` refuses it), computed
    once for the C and Octave tests."""
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        return [(path.stem, model, hamilton_points(model, Path(folder), 700 + seed)) for seed, path in enumerate(SYSTEMS) for model in [model_from(path)]]


def hamilton_points(model: Model, folder: Path, seed: int, count: int = 2) -> list[HamiltonPoint] | None:
    """Seeded random Hamilton states of `model` (None where `--form hamilton` refuses the model)."""
    from lagrange_cli.emit import hamiltonian

    try:
        reference = load_module(hamiltonian.python(model), folder / f"hamilton_reference_{seed}.py")
    except LagrangeError:
        return None
    lagrange = load_module(python.emit(model), folder / f"lagrange_reference_{seed}.py")
    n = model.n
    found = []
    for t, state, p in states(model, seed, count):
        q, qd = state[:n], state[n:]
        u = given_inputs(model, t, state)
        y = [*q, *(float(v) for v in with_inputs(reference.momenta, t, q, qd, p, u=u))]
        energy = with_inputs(lagrange.energy, *(([t] if "t" in inspect.signature(lagrange.energy).parameters else []) + [q, qd, p]), u=u)
        rhs = [float(v) for v in with_inputs(reference.rhs, t, y, p, u=u)]
        found.append(HamiltonPoint(t, y, p, qd, rhs, float(with_inputs(reference.hamiltonian, t, y, p, u=u)), float(energy), u))
    return found


@pytest.mark.parametrize("compiler", sorted(COMPILERS))
def test_hamilton_headers_compile_and_agree_with_the_python_hamilton_module(compiler: str, tmp_path: Path) -> None:
    """`--to c --form hamilton` of every bundled system Hamilton's equations are written for: one harness,
    compiled cleanly (-Werror) as C99 and C++, whose rhs agrees with the Python Hamilton module at random
    (q, p), whose velocities are the state's q_dot, whose H is the Lagrange form's energy, and whose momenta
    map (q, q_dot) back to p."""
    toolchain(COMPILERS[compiler][0])
    cases = []
    for seed, (stem, model, points) in enumerate(hamilton_cases()):
        if points is None:
            with pytest.raises(LagrangeError):
                c.emit_hamilton(model)
            continue
        prefix = f"ham{seed}"
        (tmp_path / f"{prefix}.h").write_text(c.emit_hamilton(model, name=prefix), encoding="ascii")
        cases.append((stem, prefix, model, points))
    assert len(cases) >= 20
    lines = ["#include <stdio.h>", *(f'#include "{prefix}.h"' for _, prefix, _, _ in cases), "", "int main(void)", "{", "    int j;"]
    for i, (_, prefix, model, points) in enumerate(cases):
        n, np_ = model.n, max(1, len(model.parameters))
        u = ", u" if model.inputs else ""
        for k, point in enumerate(points):
            lagrange_state = [*point.y[:n], *point.velocities]
            lines += [
                "    {",
                f"        const double y[{2 * n}] = {literal(point.y)};",
                f"        const double s[{2 * n}] = {literal(lagrange_state)};",
                f"        const double p[{np_}] = {literal([point.p[q.name] for q in model.parameters])};",
                *([f"        const double u[{len(model.inputs)}] = {literal(list(point.u.values()))};"] if model.inputs else []),
                f"        double d[{2 * n}], v[{n}], m[{n}];",
                f"        const int status = {prefix}_rhs({point.t!r}, y, p{u}, d);",
                f"        {prefix}_velocities({point.t!r}, y, p{u}, v);",
                f"        {prefix}_momenta({point.t!r}, s, p{u}, m);",
                f'        printf("{i} {k} %d", status);',
                f'        for (j = 0; j < {2 * n}; ++j) printf(" %.17g", d[j]);',
                f'        for (j = 0; j < {n}; ++j) printf(" %.17g", v[j]);',
                f'        for (j = 0; j < {n}; ++j) printf(" %.17g", m[j]);',
                f'        printf(" %.17g\\n", {prefix}_hamiltonian({point.t!r}, y, p{u}));',
                "    }",
            ]
    (tmp_path / "harness.c").write_text("\n".join([*lines, "    return 0;", "}", ""]), encoding="ascii")
    executable = tmp_path / "harness"
    built = subprocess.run([*COMPILERS[compiler], "-I", str(tmp_path), str(tmp_path / "harness.c"), "-o", str(executable), "-lm"], capture_output=True, text=True, check=False)
    assert built.returncode == 0 and not built.stderr, built.stderr[-4000:]
    ran = subprocess.run([str(executable)], capture_output=True, text=True, check=True)
    got = {(int(line.split()[0]), int(line.split()[1])): [float(v) for v in line.split()[2:]] for line in ran.stdout.splitlines()}
    problems = []
    for i, (label, _, model, points) in enumerate(cases):
        n = model.n
        for k, point in enumerate(points):
            status, *values = got[(i, k)]
            want = [*point.rhs, *point.velocities, *point.y[n:], point.hamiltonian]
            scale = max(abs(v) for v in want)
            if status != 0 or not all(math.isclose(a, b, rel_tol=RTOL, abs_tol=RTOL * scale) for a, b in zip(values, want, strict=True)):
                problems.append(f"{label} state {k}: C status {status} {values} != Python {want}")
            if not math.isclose(values[-1], point.energy, rel_tol=RTOL, abs_tol=RTOL * max(1.0, abs(point.energy))):
                problems.append(f"{label} state {k}: H {values[-1]} != the Lagrange form's energy {point.energy}")
    assert not problems, "\n".join(problems)


def test_hamilton_names_stay_apart_from_c_names() -> None:
    model = model_of(PENDULUM.replace("{m: 1.0", "{eom_velocities: 1.0, eom_hamiltonian: 2.0, m: 1.0").replace("mass: m", "mass: m*eom_velocities*eom_hamiltonian"))
    names = c.c_names(model, "eom", ["p_theta"])
    assert names["eom_velocities"] != "eom_velocities" and names["eom_hamiltonian"] != "eom_hamiltonian"
    assert "double eom_velocities_ = p[0];" in c.emit_hamilton(model).replace("const ", "")
