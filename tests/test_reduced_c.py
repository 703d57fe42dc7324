"""`derive --to c --form reduced`: Maggi's equations as a C99 header, compiled by gcc (-std=c99
-Wall -Wextra -Werror -pedantic) and g++, agree with the Python module of `--form reduced` at seeded
random reduced states y = [q, u] (and random inputs) for every bundled system with a velocity
constraint, a matrix feature and a file with an input."""

from __future__ import annotations

import random
import subprocess
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.emit import c
from lagrange_cli.emit import reduced as reduced_emit
from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model
from lagrange_cli.reduced import reduced

from .conftest import ROOT
from .helpers import load_module, model_from, model_of
from .test_target_c import GCC, GXX, toolchain

PUSHED_KNIFE = """title: knife edge pushed by an input force
coordinates: [x, y, phi]
parameters: {m: 1.0, J: 0.5}
inputs: [F]
kinetic: m*(x_dot**2 + y_dot**2)/2 + J*phi_dot**2/2
forces:
  generalized:
    x: F*cos(phi)
    y: F*sin(phi)
constraints:
  blade: sin(phi)*x_dot - cos(phi)*y_dot = 0
"""


def _cases() -> dict[str, Model]:
    hostile = (
        PUSHED_KNIFE.replace("title: knife edge pushed by an input force", 'title: "*/ #error injected /* ??/ ends in a backslash \\\\"')
        .replace("{m: 1.0, J: 0.5}", "{double: 1.0, red_rhs: 0.5}")
        .replace("m*(", "double*(")
        .replace("J*", "red_rhs*")
    )
    models = {"pushed_knife": model_of(PUSHED_KNIFE, "pushed_knife.yaml"), "hostile": model_of(hostile, "hostile */.yaml")}
    for path in [*sorted((ROOT / "systems").glob("*.yaml")), ROOT / "tests" / "matrix" / "velocity_constraints.yaml"]:
        model = model_from(path)
        try:
            reduced(model)
        except LagrangeError:
            continue  # no velocity constraint: `--form reduced` refuses it
        models[path.stem] = model
    return models


CASES = _cases()


def _literal(values: list[float]) -> str:
    return "{" + ", ".join(repr(float(v)) for v in values) + "}" if values else "{0.0}"


def _harness(name: str, model: Model, k: int, states: list[tuple[float, list[float], list[float]]]) -> str:
    n, count = model.n, len(states)
    u = ", u[i]" if model.inputs else ""
    lines = [
        "#include <stdio.h>",
        f'#include "{name}.h"',
        "int main(void)",
        "{",
        "    int i, j;",
        f"    static const double t[{count}] = {_literal([t for t, _, _ in states])};",
        f"    static const double y[{count}][{n + k}] = {{{', '.join(_literal(y) for _, y, _ in states)}}};",
        *([f"    static const double u[{count}][{len(model.inputs)}] = {{{', '.join(_literal(v) for _, _, v in states)}}};"] if model.inputs else []),
        f"    for (i = 0; i < {count}; ++i) {{",
        f"        double d[{n + k}];",
        f"        const int status = {name}_rhs(t[i], y[i], {name}_default_parameters{u}, d);",
        '        printf("%d", status);',
        f'        for (j = 0; j < {n + k}; ++j) printf(" %.17g", d[j]);',
        '        printf("\\n");',
        "    }",
        "    return 0;",
        "}",
    ]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("label", sorted(CASES))
@pytest.mark.parametrize("compiler", [GCC, GXX], ids=["gcc-c99", "g++"])
def test_reduced_c_agrees_with_the_reduced_python_module(label: str, compiler: list[str], tmp_path: Path) -> None:
    model = CASES[label]
    k = len(reduced(model.with_definitions()).independent)
    module = load_module(reduced_emit.python(model), tmp_path / f"{label}_reduced.py")
    rng = random.Random(label)
    states = [(rng.uniform(0.0, 2.0), [rng.uniform(-1.0, 1.0) for _ in range(model.n + k)], [rng.uniform(-2.0, 2.0) for _ in model.inputs]) for _ in range(4)]
    name = "red"
    (tmp_path / f"{name}.h").write_text(c.emit_reduced(model, name=name), encoding="ascii")
    (tmp_path / "harness.c").write_text(_harness(name, model, k, states), encoding="ascii")
    toolchain(compiler[0])
    built = subprocess.run([*compiler, "-I", str(tmp_path), str(tmp_path / "harness.c"), "-o", str(tmp_path / "harness"), "-lm"], capture_output=True, text=True, check=False)
    assert built.returncode == 0 and not built.stderr, built.stderr[-3000:]
    out = subprocess.run([str(tmp_path / "harness")], capture_output=True, text=True, check=True).stdout.splitlines()
    for line, (t, y, u) in zip(out, states, strict=True):
        status, *values = line.split()
        given = {i.name: v for i, v in zip(model.inputs, u, strict=True)}
        expected = module.rhs(t, y, u=given) if model.inputs else module.rhs(t, y)
        assert status == "0"
        for got, want in zip(map(float, values), expected, strict=True):
            assert abs(got - want) <= 1e-9 * max(1.0, abs(want)), (label, got, want)


def test_the_cli_writes_it_with_a_prefix() -> None:
    result = CliRunner().invoke(app, ["derive", "chaplygin_sleigh", "--to", "c", "--form", "reduced", "--prefix", "sleigh"])
    assert result.exit_code == 0, result.output
    assert "static inline int sleigh_rhs(double t, const double *y, const double *p, double *dydt)" in result.stdout
    assert "eom_" not in result.stdout


def test_the_python_module_takes_inputs_after_p() -> None:
    import inspect
    import types

    module = types.ModuleType("pushed")
    exec(compile(reduced_emit.python(CASES["pushed_knife"]), "pushed.py", "exec"), module.__dict__)
    assert list(inspect.signature(module.rhs).parameters) == ["t", "y", "p", "u"]
    pushed, free = module.rhs(0.0, [0.1, 0.2, 0.3, 0.5, 0.7], u={"F": 1.0}), module.rhs(0.0, [0.1, 0.2, 0.3, 0.5, 0.7], u={"F": 0.0})
    assert pushed[:3] == free[:3] and pushed[3:] != free[3:]  # the force changes the accelerations only


def test_reduced_with_inputs_agrees_with_the_multiplier_form(tmp_path: Path) -> None:
    """The pushed knife edge: the reduced module's u_dot are the multiplier form's accelerations of the
    independent coordinates, with the same input."""
    from lagrange_cli.emit import python

    model = CASES["pushed_knife"]
    small = load_module(reduced_emit.python(model), tmp_path / "pushed_reduced.py")
    full = load_module(python.emit(model), tmp_path / "pushed_full.py")
    rng = random.Random(5)
    for _ in range(3):
        y = [rng.uniform(-1.0, 1.0) for _ in range(5)]
        u = {"F": rng.uniform(-2.0, 2.0)}
        q_dot = small.velocities(0.0, y, u=u)
        accelerations = full.rhs(0.0, [*y[:3], *q_dot], u=u)[3:]
        u_dot = small.rhs(0.0, y, u=u)[3:]
        independent = [small.COORDINATES.index(name) for name in small.INDEPENDENT]
        assert all(abs(accelerations[i] - a) <= 1e-10 for i, a in zip(independent, u_dot, strict=True))
