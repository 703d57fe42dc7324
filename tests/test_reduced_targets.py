"""`derive --form reduced` for Octave, JAX and JSON, each in its real consumer, against the reduced Python
module (`--python --form reduced`) at seeded random reduced states y = [q, u] (random parameters and inputs):

- Octave: one `octave` process evaluates `[dydt, qdot, Mr, Fr] = NAME(t, y, p[, u])` of every case and runs
  ode45 on the rolling disk, whose end state agrees with `lagrange simulate` of the multiplier form;
- JAX (64-bit): jit, vmap over states, and grad with respect to a parameter (and an input) against central
  finite differences;
- JSON: valid against docs/model.schema.json; the `reduced` expressions read back with lagrange's parser
  evaluate to the Python module's velocities and accelerations.

The cases: every bundled system with a velocity constraint, the matrix feature, a knife edge pushed by an
input force, and the same with a hostile title, file name and coordinate, parameter and input names."""

from __future__ import annotations

import csv
import dataclasses
import functools
import json
import math
import random
import re
import subprocess
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
import sympy as sp
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.emit import jsonmodel, octave
from lagrange_cli.emit import reduced as reduced_emit
from lagrange_cli.errors import LagrangeError, Span
from lagrange_cli.expr import Scope, parse_expression
from lagrange_cli.model import Model
from lagrange_cli.reduced import reduced

from .conftest import ROOT
from .helpers import load_module, model_from, model_of
from .limits import DEADLOCK
from .test_target_octave import toolchain

PUSHED_KNIFE = """title: knife edge pushed by an input force
coordinates: [x, y, phi]
parameters: {m: 1.0, J: 0.5, c: 0.3}
inputs: [F]
kinetic: m*(x_dot**2 + y_dot**2)/2 + J*phi_dot**2/2
forces:
  generalized:
    x: F*cos(phi) - c*x_dot
    y: F*sin(phi)
constraints:
  blade: sin(phi)*x_dot - cos(phi)*y_dot = 0
"""
HOSTILE_NAMES = """title: hostile
coordinates: [y, qdot, jnp]
parameters: {reduce: 1.0, Fr: 0.5, lambda_: 0.3, INDEPENDENT: 0.7}
inputs: [u]
kinetic: reduce*(y_dot**2 + qdot_dot**2)/2 + Fr*jnp_dot**2/2
potential: INDEPENDENT*y**2/2
forces:
  generalized:
    y: u*cos(jnp) - lambda_*y_dot
    qdot: u*sin(jnp)
constraints:
  blade: sin(jnp)*y_dot - cos(jnp)*qdot_dot = 0
"""
"""Names the reduced writers use: y and p (every target), qdot, Fr, Mr (Octave), jnp, reduce, INDEPENDENT (JAX,
Python), u (the inputs' argument)."""
HOSTILE_TITLE = "'); system('touch PWNED'); %{\n\"\"\"; raise SystemExit(3) #\n*/ ends in a backslash \\ \u202e \U0001f600 \x00"
SOURCE = "/some/dir/evil'); system('touch PWNED');%{\n.yaml"


@functools.lru_cache(maxsize=1)
def cases() -> dict[str, Model]:
    found = {"pushed_knife": model_of(PUSHED_KNIFE, "pushed_knife.yaml")}
    found["hostile"] = dataclasses.replace(model_of(HOSTILE_NAMES, "hostile.yaml"), title=HOSTILE_TITLE, description=HOSTILE_TITLE, source=SOURCE)
    for path in [*sorted((ROOT / "systems").glob("*.yaml")), ROOT / "tests" / "matrix" / "velocity_constraints.yaml"]:
        if "_dot" not in path.read_text(encoding="utf-8").split("\nconstraints:", 1)[-1].split("\ninitial:", 1)[0] or "\nconstraints:" not in path.read_text(encoding="utf-8"):
            continue  # no constraint in the velocities (a quick filter; `reduced` decides below)
        model = model_from(path)
        try:
            reduced(model)
        except LagrangeError:
            continue  # no velocity constraint: `--form reduced` refuses it
        found[path.stem] = model
    assert {"chaplygin_sleigh", "knife_edge_incline", "rolling_coin", "rolling_disk_3d", "velocity_constraints"} <= set(found)
    return found


@functools.cache
def python_code(label: str) -> str:
    return reduced_emit.python(cases()[label])


@functools.cache
def independent(label: str) -> int:
    return len(reduced(cases()[label].with_definitions()).independent)


def python_module(label: str, folder: Path) -> ModuleType:
    stem = re.sub(r"\W", "_", label)
    return load_module(python_code(label), folder / f"{stem}_reduced_reference.py")


@dataclasses.dataclass
class State:
    t: float
    y: list[float]
    p: dict[str, float]
    u: dict[str, float]


def states(label: str, seed: int, count: int = 3) -> list[State]:
    """Random reduced states (coordinates in [-0.6, 0.6], away from where a chosen A_D turns singular),
    parameters within 20 % of their defaults and inputs in [-2, 2]."""
    model, k = cases()[label], independent(label)
    rng = random.Random(seed)
    found = []
    for _ in range(count):
        y = [rng.uniform(-0.6, 0.6) for _ in range(model.n)] + [rng.uniform(-1.0, 1.0) for _ in range(k)]
        p = {q.name: float(q.value) * rng.uniform(0.8, 1.2) for q in model.parameters if q.value is not None}
        found.append(State(rng.uniform(0.0, 2.0), y, p, {i.name: rng.uniform(-2.0, 2.0) for i in model.inputs}))
    return found


def expected(module: ModuleType, model: Model, state: State) -> tuple[list[float], list[float]]:
    """The Python module's dy/dt and q_dot at `state`."""
    given = {"u": state.u} if model.inputs else {}
    return [float(v) for v in module.rhs(state.t, state.y, state.p, **given)], [float(v) for v in module.velocities(state.t, state.y, state.p, **given)]


def close(got: list[float], want: list[float], rtol: float = 1e-9) -> bool:
    scale = max([1.0, *(abs(v) for v in want)])
    return len(got) == len(want) and all(math.isclose(a, b, rel_tol=rtol, abs_tol=rtol * scale) for a, b in zip(got, want, strict=True))


# -- Octave ---------------------------------------------------------------------------------------------

T_END = 2.0
ODE_TOL = 1e-6
"""ode45 (RelTol 1e-10, AbsTol 1e-12) and simulate (rtol 1e-10, atol 1e-12) agree this closely at T_END."""


def matrix(values: list[float], column: bool) -> str:
    return "[" + ("; " if column else ", ").join(repr(float(v)) for v in values) + "]"


@pytest.fixture(scope="module")
def octave_run(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Every case's function file and one script, run by one Octave process; what it printed, parsed."""
    toolchain()
    folder = tmp_path_factory.mktemp("octave_reduced")
    script = ["more off;"]
    labels = sorted(cases())
    for i, label in enumerate(labels):
        model = cases()[label]
        (folder / f"red_{i}.m").write_text(octave.emit_reduced(model, name=f"red_{i}"), encoding="ascii")
        for k, state in enumerate(states(label, i)):
            p = [state.p[q.name] for q in model.parameters]
            given = f", {matrix(list(state.u.values()), False)}" if model.inputs else ""
            script += [
                f"[d, v, Mr, Fr] = red_{i}({state.t!r}, {matrix(state.y, True)}, {matrix(p, False)}{given});",
                f"printf('value {i} {k}'); printf(' %.17g', d); printf(' |'); printf(' %.17g', v); printf(' |'); printf(' %.17g', Mr * (Mr \\ Fr) - Fr); printf('\\n');",
            ]
        script += [f"d = red_{i}(0, {matrix(states(label, i)[0].y, True)});", f"printf('defaults {i}'); printf(' %.17g', d); printf('\\n');"]
    disk = labels.index("rolling_disk_3d")
    script += [
        f"[tt, yy] = ode45(@red_{disk}, [0 {T_END!r}], [0; 0; 0; 0.1; 0; 0; 0; 5], odeset('RelTol', 1e-10, 'AbsTol', 1e-12));",
        f"[d, v] = red_{disk}(tt(end), yy(end, :)');",
        "printf('ode45 %.17g', tt(end)); printf(' %.17g', yy(end, :)); printf(' |'); printf(' %.17g', v); printf('\\n');",
    ]
    (folder / "run_all.m").write_text("\n".join(script) + "\n", encoding="ascii")
    done = subprocess.run([toolchain(), "--no-gui", "--no-window-system", "--quiet", "--no-init-file", "--eval", "run_all"], cwd=folder, capture_output=True, text=True, check=False, timeout=DEADLOCK)
    assert done.returncode == 0, f"octave failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    found: dict[str, Any] = {"labels": labels, "folder": folder, "values": {}, "defaults": {}}
    for line in done.stdout.splitlines():
        head, *rest = line.split()
        if head == "value":
            found["values"][(int(rest[0]), int(rest[1]))] = [[float(v) for v in part.split()] for part in " ".join(rest[2:]).split("|")]
        elif head == "defaults":
            found["defaults"][int(rest[0])] = [float(v) for v in rest[1:]]
        elif head == "ode45":
            found["ode45"] = [[float(v) for v in part.split()] for part in " ".join(rest).split("|")]
    return found


def test_octave_agrees_with_the_python_module(octave_run: dict[str, Any], tmp_path: Path) -> None:
    problems = []
    for i, label in enumerate(octave_run["labels"]):
        model = cases()[label]
        module = python_module(label, tmp_path)
        for k, state in enumerate(states(label, i)):
            dydt, velocities = expected(module, model, state)
            got_dydt, got_velocities, residual = octave_run["values"][(i, k)]
            if not close(got_dydt, dydt) or not close(got_velocities, velocities):
                problems.append(f"{label} state {k}: Octave {got_dydt} {got_velocities} != Python {dydt} {velocities}")
            assert got_velocities == got_dydt[: model.n]  # qdot is the first part of dydt
            assert all(abs(r) <= 1e-9 * max(1.0, *map(abs, dydt)) for r in residual), (label, residual)  # Mr u_dot = Fr
        defaults = module.rhs(0.0, states(label, i)[0].y)  # p (and u) omitted: the file's defaults
        assert close(octave_run["defaults"][i], [float(v) for v in defaults]), label
    assert not problems, "\n".join(problems)


def test_ode45_on_the_rolling_disk_agrees_with_simulate(octave_run: dict[str, Any], tmp_path: Path) -> None:
    """ode45 on the reduced state y = [q; u] against `lagrange simulate` of the multiplier form (all velocities)."""
    out = tmp_path / "sim.csv"
    args = ["simulate", "rolling_disk_3d", "--t-end", repr(T_END), "--rtol", "1e-10", "--atol", "1e-12", "--samples", "3", "--backend", "python", "--method", "DOP853", "-o", str(out), "-q"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    with out.open() as handle:
        rows = list(csv.DictReader(handle))
    model = cases()["rolling_disk_3d"]
    red = reduced(model)
    assert [model.coordinates[i] for i in red.independent] == ["psi", "theta", "phi"]
    end, velocities = octave_run["ode45"]
    t_end, *state = end
    assert t_end == T_END
    want_q = [float(rows[-1][c]) for c in model.coordinates]
    want_u = [float(rows[-1][f"{model.coordinates[i]}_dot"]) for i in red.independent]
    want_velocities = [float(rows[-1][f"{c}_dot"]) for c in model.coordinates]
    assert all(math.isclose(a, b, abs_tol=ODE_TOL) for a, b in zip(state, want_q + want_u, strict=True)), (state, want_q + want_u)
    assert all(math.isclose(a, b, abs_tol=ODE_TOL) for a, b in zip(velocities, want_velocities, strict=True)), (velocities, want_velocities)


def test_the_octave_file_is_a_matlab_function_file_and_text_stays_data(octave_run: dict[str, Any]) -> None:
    folder = octave_run["folder"]
    assert not (folder / "PWNED").exists()
    for i, label in enumerate(octave_run["labels"]):
        model = cases()[label]
        text = (folder / f"red_{i}.m").read_text(encoding="ascii")
        assert text.startswith(f"function [dydt, qdot, Mr, Fr] = red_{i}(t, y, p{', u' if model.inputs else ''})\n"), label
        assert all(ch == "\n" or " " <= ch <= "~" for ch in text), label
        code = [line for line in text.splitlines() if not line.lstrip().startswith("%")]
        assert sum(1 for line in code if re.match(r"\s*(function|if|for|while|try)\b", line)) == sum(1 for line in code if line.strip() == "end"), label
        assert "PWNED" not in "\n".join(code) and "#" not in "".join(code) and "!=" not in "".join(code), label
    hostile = (folder / f"red_{octave_run['labels'].index('hostile')}.m").read_text(encoding="ascii")
    assert "y -> y_, qdot -> qdot_, Fr -> Fr_, u -> u_" in hostile


# -- JAX ------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def jax() -> Any:
    found = pytest.importorskip("jax")
    found.config.update("jax_enable_x64", True)
    return found


def test_the_jax_module_uses_the_lagrange_forms_sincos_and_kept(jax: Any, tmp_path: Path) -> None:
    """`--form reduced` shares the JAX target's `Storage`: the sines and cosines of the coordinates from `_sincos`
    (in every case that has them), values stored through `_kept` when the reduced solve has at least `KEEP_MIN`
    unknowns; the values agree with the Python module's reduced form (test_jax_jit_vmap_and_grad, every case)."""
    from lagrange_cli.emit import jax as jax_target

    codes = {label: reduced_emit.jax(model) for label, model in cases().items()}
    for label, code in codes.items():
        functions = code.split("def velocities", 1)[1]
        assert not any(f"jnp.{f}({q})" in functions for q in cases()[label].coordinates for f in ("sin", "cos")), label
    assert all("_sincos(" in codes[label].split("def velocities", 1)[1] for label in ("rolling_disk_3d", "rolling_coin", "chaplygin_sleigh"))
    stored = [label for label in codes if independent(label) >= jax_target.KEEP_MIN]
    assert stored and all("_kept(" in codes[label].split("def rhs", 1)[1] for label in stored)
    assert all("_kept" not in codes[label] for label in codes if independent(label) < jax_target.KEEP_MIN)


@pytest.mark.parametrize("label", sorted(cases()))
def test_jax_jit_vmap_and_grad(label: str, jax: Any, tmp_path: Path) -> None:
    model = cases()[label]
    n = model.n
    module = python_module(label, tmp_path)
    target = load_module(reduced_emit.jax(model), tmp_path / "reduced_jax.py")
    assert tuple(model.coordinates) == target.COORDINATES and target.INDEPENDENT == module.INDEPENDENT and target.DEPENDENT == module.DEPENDENT
    k = target.NI
    names = list(target.PARAMETER_NAMES)
    inputs = list(getattr(target, "INPUT_NAMES", ()))
    rhs = jax.jit(target.rhs)
    draws = states(label, 7, 4)
    for state in draws:
        p = jax.numpy.asarray([state.p[name] for name in names])
        u = jax.numpy.asarray([state.u[name] for name in inputs]) if inputs else None
        given = {"u": u} if inputs else {}
        dydt, velocities = expected(module, model, state)
        assert close([float(v) for v in rhs(state.t, jax.numpy.asarray(state.y), p, **given)], dydt), label
        assert close([float(v) for v in target.velocities(state.t, state.y, state.p, **({"u": state.u} if inputs else {}))], velocities), label  # p and u as dicts
        assert [float(v) for v in target.reduce(velocities)] == pytest.approx(state.y[n:], abs=1e-12)
        mass = np.asarray(target.reduced_mass_matrix(state.t, state.y, p, **given))
        force = np.asarray(target.reduced_forcing(state.t, state.y, p, **given))
        assert mass.shape == (k, k) and np.allclose(mass, mass.T)
        assert np.allclose(mass @ np.asarray(dydt[n:]), force, rtol=1e-9, atol=1e-9 * max(1.0, float(np.max(np.abs(force)))))
    # vmap over states (and inputs) equals the loop
    ys = jax.numpy.asarray([s.y for s in draws])
    ts = jax.numpy.asarray([s.t for s in draws])
    p0 = target.default_parameters()
    if inputs:
        us = jax.numpy.asarray([[s.u[name] for name in inputs] for s in draws])
        batch = jax.jit(jax.vmap(target.rhs, in_axes=(0, 0, None, 0)))(ts, ys, p0, us)
        loop = [target.rhs(t, y, p0, u) for t, y, u in zip(ts, ys, us, strict=True)]
    else:
        batch = jax.jit(jax.vmap(target.rhs, in_axes=(0, 0, None)))(ts, ys, p0)
        loop = [target.rhs(t, y, p0) for t, y in zip(ts, ys, strict=True)]
    assert np.allclose(np.asarray(batch), np.asarray(loop), rtol=1e-13, atol=1e-13)
    # grad of the accelerations with respect to each parameter (and input) against central differences
    state = draws[0]
    u0 = jax.numpy.asarray([state.u[name] for name in inputs]) if inputs else None

    def accelerations(p: Any, u: Any) -> Any:
        return jax.numpy.sum(target.rhs(state.t, jax.numpy.asarray(state.y), p, *([u] if inputs else []))[n:] * jax.numpy.arange(1, k + 1))

    p = jax.numpy.asarray([state.p[name] for name in names])
    gradient = jax.grad(accelerations, argnums=(0, 1) if inputs else 0)(p, u0)
    accelerations = jax.jit(accelerations)  # for the finite differences
    by_p, by_u = gradient if inputs else (gradient, None)
    for i in range(len(names)):
        h = 1e-6 * max(1.0, abs(float(p[i])))
        step = jax.numpy.zeros(len(names)).at[i].set(h)
        difference = (float(accelerations(p + step, u0)) - float(accelerations(p - step, u0))) / (2 * h)
        assert float(by_p[i]) == pytest.approx(difference, rel=1e-6, abs=1e-7), (label, names[i])
    for i in range(len(inputs)):
        step = jax.numpy.zeros(len(inputs)).at[i].set(1e-6)
        difference = (float(accelerations(p, u0 + step)) - float(accelerations(p, u0 - step))) / 2e-6
        assert float(by_u[i]) == pytest.approx(difference, rel=1e-6, abs=1e-7), (label, inputs[i])


def test_the_jax_module_keeps_file_text_as_data(jax: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    code = reduced_emit.jax(cases()["hostile"])
    assert all(c == "\n" or " " <= c <= "~" for c in code)
    monkeypatch.chdir(tmp_path)
    module = load_module(code, tmp_path / "hostile_reduced.py")
    assert not (tmp_path / "PWNED").exists()
    assert HOSTILE_TITLE in module.__doc__ and Path(SOURCE).name in module.__doc__
    assert module.PARAMETER_NAMES == ("reduce", "Fr", "lambda_", "INDEPENDENT") and module.INPUT_NAMES == ("u",) and module.INDEPENDENT == ("y", "jnp")
    assert "def velocities(t, y, p=None, u=None)" in code


# -- JSON -----------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def validator() -> Any:
    jsonschema = pytest.importorskip("jsonschema")
    return jsonschema.Draft202012Validator(json.loads((ROOT / "docs" / "model.schema.json").read_text()))


@pytest.mark.parametrize("label", sorted(cases()))
def test_json_is_valid_and_reads_back_into_the_python_modules_values(label: str, validator: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for limit in ("MAX_LENGTH", "MAX_NODES"):  # the rolling disk's C^T (F - M e) is longer than a file's expression may be
        monkeypatch.setattr(f"lagrange_cli.expr.{limit}", 10**6)
    model = cases()[label]
    n = model.n
    text = jsonmodel.emit_reduced(model)
    assert text.isascii()
    data = json.loads(text)
    validator.validate(data)
    assert list(data)[-1] == "reduced" and {key: value for key, value in data.items() if key != "reduced"} == json.loads(jsonmodel.emit(model))
    assert data["title"] == model.title
    section = data["reduced"]
    red = reduced(model)
    k = len(red.independent)
    assert section["independent"] == [model.coordinates[i] for i in red.independent] and section["dependent"] == [model.coordinates[i] for i in red.dependent]
    assert section["state"] == [*model.coordinates, *(f"{model.coordinates[i]}_dot" for i in red.independent)]
    names = [c["name"] for c in data["coordinates"]] + [c["velocity"] for c in data["coordinates"]] + [p["name"] for p in data["parameters"]] + [i["name"] for i in data.get("inputs", [])]
    symbols = {name: sp.Symbol(name) for name in names}
    scope = Scope(symbols, {f["name"]: sp.Function(f["name"]) for f in data["functions"]}, sp.Symbol(data["time"]["name"]), lambda e: e)

    def read(expression: dict[str, str]) -> sp.Expr:
        return parse_expression(expression["text"], Span("model.json", 1, 1), scope)

    velocities = [read(e) for e in section["velocities"]]
    mass = [[read(e) for e in row] for row in section["mass_matrix"]]
    forcing = [read(e) for e in section["forcing"]]
    assert len(velocities) == n and len(mass) == k and all(len(row) == k for row in mass) and len(forcing) == k
    assert read(section["determinant"]).free_symbols <= set(symbols.values()) | {sp.Symbol("t")}
    module = python_module(label, tmp_path)
    for state in states(label, 11):
        point = {symbols[name]: value for name, value in zip(section["state"], state.y, strict=True)}
        point |= {symbols[name]: value for name, value in (*state.p.items(), *state.u.items())} | {sp.Symbol("t"): state.t}
        dydt, want = expected(module, model, state)
        got = [float(v.xreplace(point)) for v in velocities]
        u_dot = np.linalg.solve(np.array([[float(e.xreplace(point)) for e in row] for row in mass]), np.array([float(f.xreplace(point)) for f in forcing]))
        assert close(got, want) and close([*got, *map(float, u_dot)], dydt), label


def test_the_reduced_key_is_in_the_schema_and_documented() -> None:
    schema = json.loads((ROOT / "docs" / "model.schema.json").read_text())
    documentation = (ROOT / "docs" / "json.md").read_text()
    assert "`reduced`" in documentation
    for key in schema["properties"]["reduced"]["required"]:
        assert f"`{key}`" in documentation, key


# -- the CLI --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("target", "shows"), [("octave", "function [dydt, qdot, Mr, Fr] = sleigh(t, y, p)"), ("jax", "def rhs(t, y, p=None):"), ("json", '"reduced": {')])
def test_the_cli_writes_every_target(target: str, shows: str, tmp_path: Path) -> None:
    out = tmp_path / ("sleigh.m" if target == "octave" else f"sleigh.{target}")
    result = CliRunner().invoke(app, ["derive", "chaplygin_sleigh", "--to", target, "--form", "reduced", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert shows in out.read_text()
    refused = CliRunner().invoke(app, ["derive", "double_pendulum", "--to", target, "--form", "reduced"])
    assert refused.exit_code == 2 and "--form reduced needs a velocity (nonholonomic) constraint" in refused.stderr and "Traceback" not in refused.output


def test_system_to_writes_every_target() -> None:
    from lagrange_cli import api

    system = api.load("chaplygin_sleigh")
    assert system.to("octave", form="reduced").startswith("function [dydt, qdot, Mr, Fr] = eom(t, y, p)")
    assert "def reduced_forcing(t, y, p=None):" in system.to("jax", form="reduced")
    assert json.loads(system.to("json", form="reduced"))["reduced"]["independent"] == ["x", "phi"]


def test_system_to_writes_hamilton_for_every_target_too() -> None:
    """System.to(target, form=...) reaches the same writers as `derive --to TARGET --form ...`."""
    from lagrange_cli import api

    system = api.load("double_pendulum")
    for target in ("text", "latex", "python", "c", "octave", "jax", "json"):
        result = CliRunner().invoke(app, ["derive", "double_pendulum", "--to", target, "--form", "hamilton"])
        assert result.exit_code == 0, result.output
        assert system.to(target, form="hamilton").rstrip("\n") == result.stdout.rstrip("\n"), target
