"""The Octave target in its real toolchain: one `octave --no-gui --eval` process (Octave starts slowly)
runs `ode45` on the double pendulum, which agrees with `lagrange simulate` at the end time, and
evaluates `eom(t, y, p)` of a few systems (kept constraints, time dependence, defined functions,
hostile names and titles) at seeded random states, which agree with the Python module."""

from __future__ import annotations

import csv
import functools
import math
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.emit import octave, python
from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model

from .conftest import ROOT
from .helpers import model_from, model_of
from .limits import DEADLOCK
from .test_target_c import C_HOSTILE, HOSTILE, PENDULUM, Case, given_inputs, hamilton_cases, python_values, readme_block, states

RTOL = 1e-9
T_END = 2.0
ODE_TOL = 1e-6
"""ode45 (RelTol 1e-10, AbsTol 1e-12) and simulate (rtol 1e-10, atol 1e-12) agree this closely at T_END."""

SYSTEMS = ["double_pendulum", *sorted(p.stem for p in (ROOT / "systems").glob("*.yaml") if p.stem != "double_pendulum")]
"""Every bundled system (the double pendulum first: ode45 and the README example use it)."""
FEATURES = sorted(p.stem for p in (ROOT / "tests" / "matrix").glob("*.yaml") if not p.stem.startswith("functions_undefined"))
"""Every feature of the matrix that code can express (undefined functions are refused, see test_an_undefined_function_is_refused)."""
NAMES = """title: "MATLAB names: end, function, pi, e, i, sqrt, realpow, dydt, lambda, M, x as user names %{ ... '"
coordinates: [x, end_, M]
parameters: {pi_: 1.0, e: 2.0, i: 1.5, dydt: 9.81, realpow: 0.5, nargin: 1.0, b: 3.0, h: 1.0, M_dot_: 1.0}
particles:
  a: {mass: e*i, position: [x, end_]}
  c: {mass: dydt + nargin, position: [M*realpow + b*h]}
potential: pi_*x**2/2 + end_**2 + M_dot_*M**2
"""


def toolchain() -> str:
    found = shutil.which("octave")
    if found is None:
        pytest.fail("octave is not installed: `make test` installs it (the toolchains target of the Makefile)")
    return found


def matrix(values: list[float], column: bool) -> str:
    return "[" + ("; " if column else ", ").join(repr(float(v)) for v in values) + "]"


@functools.lru_cache(maxsize=1)
def cases() -> list[Case]:
    found = []
    for seed, name in enumerate(SYSTEMS):
        model = model_from(ROOT / "systems" / f"{name}.yaml")
        found.append(Case(name, model, f"eom_{seed}", states(model, 100 + seed)))
    assert len(FEATURES) >= 13
    for seed, name in enumerate(FEATURES):
        model = model_from(ROOT / "tests" / "matrix" / f"{name}.yaml")
        found.append(Case(name, model, f"feature_{seed}", states(model, 200 + seed)))
    for seed, (name, title) in enumerate(C_HOSTILE.items()):
        model = model_of(title + PENDULUM, name=f"{name}.yaml")
        found.append(Case(name, model, f"hostile_{seed}", states(model, 300 + seed, 1)))
    names = model_of(NAMES)
    found.append(Case("names", names, "names", states(names, 400)))
    for seed, path in enumerate(HOSTILE):  # the hostile files about titles, names and file names
        try:
            model = model_of(path.read_text(encoding="utf-8", errors="surrogateescape"), name=path.name)
            octave.emit(model)
            python.emit(model)
        except (LagrangeError, UnicodeError, TypeError):
            continue
        found.append(Case(f"hostile/{path.name}", model, f"file_{seed}", states(model, 500 + seed, 1)))
    return found


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Write every case's function file and one script; run Octave once; parse what it printed."""
    toolchain()
    folder = tmp_path_factory.mktemp("octave")
    script = ["more off;", "warning('off', 'all');"]
    for i, case in enumerate(cases()):
        (folder / f"{case.prefix}.m").write_text(octave.emit(case.model, name=case.prefix), encoding="ascii")
        for k, (t, y, p) in enumerate(case.states):
            values = [p[q.name] for q in case.model.parameters]
            given = f", {matrix(list(given_inputs(case.model, t, y).values()), False)}" if case.model.inputs else ""  # as python_values gives the Python module
            script += [
                "try",
                f"  [d, h, lam] = {case.prefix}({t!r}, {matrix(y, True)}, {matrix(values, False)}{given});",
                f"  printf('value {i} {k}'); printf(' %.17g', d); printf(' %.17g', lam); printf(' %.17g\\n', h);",
                "catch err",
                f"  printf('failed {i} {k} %s\\n', err.identifier);",
                "end",
            ]
    dp = cases()[0]
    script += [
        f"[tt, yy] = ode45(@{dp.prefix}, [0 {T_END!r}], [1; 0.5; 0; 0], odeset('RelTol', 1e-10, 'AbsTol', 1e-12));",
        "printf('ode45 %.17g', tt(end)); printf(' %.17g', yy(end, :)); printf('\\n');",
        "[d, h] = eom_0(0, [1; 0.5; 0; 0]);",  # p omitted: the file's defaults
        "printf('defaults'); printf(' %.17g', d); printf(' %.17g\\n', h);",
    ]
    singular = model_from(ROOT / "systems" / "spherical_pendulum.yaml")
    (folder / "singular.m").write_text(octave.emit(singular, name="singular"), encoding="ascii")
    script += ["try", "  singular(0, [0; 0.3; 0.1; 0.2]);", "  printf('singular none\\n');", "catch err", "  printf('singular %s\\n', err.identifier);", "end"]
    readme = readme_block("### Generated Octave/MATLAB", "matlab")
    assert len(readme.strip().splitlines()) <= 12
    (folder / "pendulum.m").write_text(octave.emit(dp.model, name="pendulum"), encoding="ascii")
    (folder / "readme_example.m").write_text("\n".join(line for line in readme.splitlines() if not line.startswith(("plot", "legend"))) + "\n", encoding="ascii")
    script.append("readme_example")
    (folder / "run_all.m").write_text("\n".join(script) + "\n", encoding="ascii")
    done = subprocess.run([toolchain(), "--no-gui", "--no-window-system", "--quiet", "--no-init-file", "--eval", "run_all"], cwd=folder, capture_output=True, text=True, check=False, timeout=DEADLOCK)
    assert done.returncode == 0, f"octave failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    values: dict[tuple[int, int], list[float]] = {}
    found: dict[str, Any] = {"values": values, "folder": folder, "stdout": done.stdout}
    for line in done.stdout.splitlines():
        head, *rest = line.split()
        if head == "value":
            values[(int(rest[0]), int(rest[1]))] = [float(v) for v in rest[2:]]
        elif head in ("ode45", "defaults"):
            found[head] = [float(v) for v in rest]
        elif head == "singular":
            found[head] = rest[0]
        elif head.startswith("theta(10)") and "energy" in line:
            found[head] = line
    return found


def test_ode45_on_the_double_pendulum_agrees_with_simulate(run: dict[str, Any], tmp_path: Path) -> None:
    out = tmp_path / "sim.csv"
    args = ["simulate", "double_pendulum", "--t-end", repr(T_END), "--rtol", "1e-10", "--atol", "1e-12", "--samples", "3", "--backend", "python", "-o", str(out), "-q"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    with out.open() as handle:
        rows = list(csv.DictReader(handle))
    expected = [float(rows[-1][key]) for key in ("theta", "phi", "theta_dot", "phi_dot")]
    t_end, *state = run["ode45"]
    assert t_end == T_END
    assert all(math.isclose(a, b, abs_tol=ODE_TOL) for a, b in zip(state, expected, strict=True)), (state, expected)


def test_eom_agrees_with_the_python_module_at_random_states(run: dict[str, Any]) -> None:
    problems = []
    for i, case in enumerate(cases()):
        for k, (t, y, p) in enumerate(case.states):
            want, want_energy = python_values(case.python, case.model, t, y, p)
            if want is None or want_energy is None:  # Octave must fail too (an error, or a non-finite value)
                got = run["values"].get((i, k))
                assert got is None or not all(math.isfinite(v) for v in got), case.label
                continue
            got = run["values"][(i, k)]
            dydt, energy = got[:-1], got[-1]
            scale = max(abs(v) for v in want)
            if not all(math.isclose(a, b, rel_tol=RTOL, abs_tol=RTOL * scale) for a, b in zip(dydt, want, strict=True)):
                problems.append(f"{case.label} state {k}: Octave {dydt} != Python {want}")
            if not math.isclose(energy, want_energy, rel_tol=RTOL, abs_tol=RTOL * max(1.0, abs(want_energy))):
                problems.append(f"{case.label} state {k}: Octave energy {energy} != Python {want_energy}")
    assert not problems, "\n".join(problems)
    assert len(run["values"]) >= sum(len(case.states) for case in cases()) - 2


def test_p_is_optional_and_a_singular_matrix_is_an_error(run: dict[str, Any]) -> None:
    module = cases()[0].python
    model: Model = cases()[0].model
    want = module.rhs(0.0, [1.0, 0.5, 0.0, 0.0])
    assert all(math.isclose(a, b, rel_tol=RTOL, abs_tol=1e-12) for a, b in zip(run["defaults"][:-1], want, strict=True))
    assert model.n == 2
    assert run["singular"] == "singular:singular"


def test_the_readme_example_runs(run: dict[str, Any]) -> None:
    """The README's ode45 example (without its plot) runs, and the energy at the end is the initial one."""
    line = run["theta(10)"]
    energy = float(re.search(r"energy (\S+)", line).group(1))  # type: ignore[union-attr]
    assert energy == pytest.approx(cases()[0].python.energy([1.0, 0.5], [0.0, 0.0]), abs=1e-4)
    assert "theta(10) there = " in run["stdout"]


def test_the_file_is_a_matlab_function_file(run: dict[str, Any]) -> None:
    """The function is named as its file, blocks close with `end`, and file text stays in comments."""
    for case in cases():
        text = (run["folder"] / f"{case.prefix}.m").read_text()
        assert text.startswith(f"function [dydt, h, lambda] = {case.prefix}(t, y, p{', u' if case.model.inputs else ''})\n")
        assert all(ch == "\n" or " " <= ch <= "~" for ch in text), case.label
        code = [line for line in text.splitlines() if not line.lstrip().startswith("%")]
        opened = sum(1 for line in code if re.match(r"\s*(function|if|for|while|try)\b", line))
        assert opened == sum(1 for line in code if line.strip() == "end"), case.label
        assert not any("%" in line.split("'")[0] for line in code if "printf" not in line and "error(" not in line), case.label
        assert "#" not in "".join(code) and "!=" not in "".join(code) and "+=" not in "".join(code), case.label


def test_names_are_mangled_apart_from_matlab_names() -> None:
    names = octave.octave_names(model_of(NAMES), "eom")
    taken = {*octave.KEYWORDS, *octave.BUILTINS, *octave.LOCALS, "eom"}
    assert not taken & {v for k, v in names.items() if k != "t"}
    assert len(set(names.values())) == len(names)
    assert all(octave.IDENTIFIER.fullmatch(v) for v in names.values())
    assert octave.octave_names(model_of("coordinates: [foo]\nparameters: {m: 1.0}\nparticles:\n  a: {mass: m, position: [foo]}\n"), "foo")["foo"] != "foo"


def test_comments_hold_any_text() -> None:
    for text in ["%{", "\n%}\nerror('x')", "nul \x00 \u202e", "'); system('rm -rf /'); %"]:
        out = octave.comment(text)
        assert out.isascii() and "\n" not in out and "\r" not in out


# -- the command line ---------------------------------------------------------------------------------

runner = CliRunner()


def test_the_function_is_named_after_the_output_file(tmp_path: Path) -> None:
    out = tmp_path / "pendulum_eom.m"
    result = runner.invoke(app, ["derive", "double_pendulum", "--to", "octave", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert out.read_text().startswith("function [dydt, h, lambda] = pendulum_eom(t, y, p)\n")
    shown = runner.invoke(app, ["derive", "double_pendulum", "--to", "octave"])
    assert shown.exit_code == 0 and shown.stdout.startswith("function [dydt, h, lambda] = eom(t, y, p)\n")


@pytest.mark.parametrize("name", ["1bad.m", "bad-name.m", "end.m", "a.b.m", "x" * 64 + ".m"])
def test_a_file_name_that_is_no_matlab_identifier_is_exit_2(name: str, tmp_path: Path) -> None:
    out = tmp_path / name
    result = runner.invoke(app, ["derive", "double_pendulum", "--to", "octave", "-o", str(out)])
    assert result.exit_code == 2 and "cannot hold an Octave function" in result.output, result.output
    assert "Traceback" not in result.output and not out.exists()


def test_an_undefined_function_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "eom.m"
    result = runner.invoke(app, ["derive", str(ROOT / "tests" / "matrix" / "functions_undefined_energy.yaml"), "--to", "octave", "-o", str(out)])
    assert result.exit_code == 2 and "Octave code needs every function defined" in result.output and not out.exists()
    with pytest.raises(LagrangeError):
        octave.emit(model_from(ROOT / "tests" / "matrix" / "functions_undefined_energy.yaml"))


def test_python_module_is_the_reference() -> None:
    """The reference of these tests is `lagrange derive --python`, unchanged."""
    assert "def rhs(" in python.emit(cases()[0].model)


def test_a_name_longer_than_matlab_allows_is_refused(tmp_path: Path) -> None:
    name = "a" * 64
    path = tmp_path / "long.yaml"
    path.write_text(f"coordinates: [{name}]\nparameters: {{m: 1.0}}\nparticles:\n  a: {{mass: m, position: [{name}]}}\n")
    result = runner.invoke(app, ["derive", str(path), "--to", "octave", "-o", str(tmp_path / "eom.m")])
    assert result.exit_code == 2 and f"the name '{name}' is longer than 63 characters, the most MATLAB allows in an identifier" in result.output, result.output
    assert not (tmp_path / "eom.m").exists()
    short = tmp_path / "short.yaml"
    short.write_text(path.read_text().replace(name, name[:59]))  # its velocity a..a_dot has 63 characters
    assert runner.invoke(app, ["derive", str(short), "--to", "octave"]).exit_code == 0


# -- --form hamilton ------------------------------------------------------------------------------------


def test_hamilton_agrees_with_the_python_hamilton_module_and_the_lagrange_form(tmp_path: Path) -> None:
    """`--to octave --form hamilton` of every bundled system Hamilton's equations are written for, in one Octave
    process: dy/dt agrees with the Python Hamilton module at random (q, p), q_dot is the state's velocities,
    and H is the Lagrange form's energy; ode45 on the double pendulum's Hamilton form ends where the
    Lagrange form's does (p mapped back to q_dot)."""
    toolchain()
    script = ["more off;", "warning('off', 'all');"]
    cases = []
    for seed, (stem, model, points) in enumerate(hamilton_cases()):
        if points is None:
            with pytest.raises(LagrangeError):
                octave.emit_hamilton(model)
            continue
        prefix = f"ham_{seed}"
        (tmp_path / f"{prefix}.m").write_text(octave.emit_hamilton(model, name=prefix), encoding="ascii")
        for k, point in enumerate(points):
            values = [point.p[q.name] for q in model.parameters]
            given = f", {matrix(list(point.u.values()), False)}" if model.inputs else ""
            script += [
                f"[d, H, v] = {prefix}({point.t!r}, {matrix(point.y, True)}, {matrix(values, False)}{given});",
                f"printf('value {len(cases)} {k}'); printf(' %.17g', d); printf(' %.17g', v); printf(' %.17g\\n', H);",
            ]
        cases.append((stem, model, points))
    assert len(cases) >= 20
    dp = model_from(ROOT / "systems" / "double_pendulum.yaml")
    (tmp_path / "dph.m").write_text(octave.emit_hamilton(dp, name="dph"), encoding="ascii")
    (tmp_path / "dpl.m").write_text(octave.emit(dp, name="dpl"), encoding="ascii")
    script += [
        "opts = odeset('RelTol', 1e-10, 'AbsTol', 1e-12);",
        f"[~, yl] = ode45(@dpl, [0 {T_END!r}], [1; 0.5; 0; 0], opts);",
        f"[~, yh] = ode45(@dph, [0 {T_END!r}], [1; 0.5; 0; 0], opts);",
        "[~, ~, v] = dph(0, yh(end, :)');",
        "printf('ode45'); printf(' %.17g', yl(end, :)); printf(' %.17g', yh(end, 1:2)); printf(' %.17g', v); printf('\\n');",
    ]
    (tmp_path / "run_all.m").write_text("\n".join(script) + "\n", encoding="ascii")
    done = subprocess.run(
        [toolchain(), "--no-gui", "--no-window-system", "--quiet", "--no-init-file", "--eval", "run_all"], cwd=tmp_path, capture_output=True, text=True, check=False, timeout=DEADLOCK
    )
    assert done.returncode == 0, f"octave failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    values = {}
    for line in done.stdout.splitlines():
        head, *rest = line.split()
        if head == "value":
            values[(int(rest[0]), int(rest[1]))] = [float(v) for v in rest[2:]]
        elif head == "ode45":
            ode = [float(v) for v in rest]
    problems = []
    for i, (label, model, points) in enumerate(cases):
        n = model.n
        for k, point in enumerate(points):
            got = values[(i, k)]
            want = [*point.rhs, *point.velocities, point.hamiltonian]
            scale = max(abs(v) for v in want)
            if not all(math.isclose(a, b, rel_tol=RTOL, abs_tol=RTOL * scale) for a, b in zip(got, want, strict=True)):
                problems.append(f"{label} state {k}: Octave {got} != Python {want}")
            if not math.isclose(got[-1], point.energy, rel_tol=RTOL, abs_tol=RTOL * max(1.0, abs(point.energy))):
                problems.append(f"{label} state {k}: H {got[-1]} != the Lagrange form's energy {point.energy}")
            assert len(got) == 3 * n + 1
    assert not problems, "\n".join(problems)
    assert all(math.isclose(a, b, abs_tol=ODE_TOL) for a, b in zip(ode[:4], ode[4:], strict=True)), ode


def test_hamilton_file_is_a_matlab_function_file_and_names_stay_apart() -> None:
    text = octave.emit_hamilton(model_of(NAMES), name="eom")
    assert text.startswith("function [dydt, H, qdot] = eom(t, y, p)\n")
    assert all(ch == "\n" or " " <= ch <= "~" for ch in text)
    shadowing = NAMES.replace("h: 1.0", "h: 1.0, H: 1.0, qdot: 2.0").replace("b*h", "b*h*H*qdot")
    assert "qdot" in shadowing
    names = octave.octave_names(model_of(shadowing), "eom", ["p_x"], octave.HAMILTON_LOCALS)
    assert names["H"] != "H" and names["qdot"] != "qdot"
    assert not {v for k, v in names.items() if k != "t"} & {*octave.KEYWORDS, *octave.BUILTINS, *octave.HAMILTON_LOCALS, "eom"}
