"""`inputs` and `outputs` (FORMAT.md version 2): the frontend, the derived model, the generated
Python (`INPUTS`, `u=INPUTS`, `outputs`) and `simulate --input NAME=EXPR`."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import sympy as sp
from typer.testing import CliRunner

from lagrange_cli import inputs, spec
from lagrange_cli.cli import app
from lagrange_cli.emit import python
from lagrange_cli.errors import SpecError

from .helpers import load_module, model_of

runner = CliRunner()

CART_POLE = """\
title: Cart-pole with a force input
coordinates: [x, theta]
parameters: {M: 1.0, m: 0.1, l: 0.5, g: 9.81, k1: 40.0, k2: 10.0}
inputs:
  F: {value: 0.5, description: horizontal force on the cart}
outputs:
  position: x
  angle: theta
  tip: x + l*sin(theta)
gravity: [0, -g]
particles:
  cart: {mass: M, position: [x, 0], force: [F, 0]}
  bob: {mass: m, position: [x + l*sin(theta), l*cos(theta)]}
"""

SPRING = """\
coordinates: [x]
parameters: {m: 2.0, k: 3.0}
inputs: [a, b]
potential: k*x**2/2 - a*x
lagrangian: b*x
particles:
  p: {mass: m, position: [x]}
"""


def problem(text: str) -> str:
    with pytest.raises(SpecError) as caught:
        spec.parse(text, "sys.yaml")
    return str(caught.value)


def test_list_and_map_forms_with_defaults_in_file_order() -> None:
    model = model_of(CART_POLE)
    assert [(i.name, i.value, i.description) for i in model.inputs] == [("F", 0.5, "horizontal force on the cart")]
    assert [name for name, _ in model.outputs] == ["position", "angle", "tip"]
    plain = model_of(SPRING)
    assert [(i.name, i.value) for i in plain.inputs] == [("a", 0.0), ("b", 0.0)]
    a, b, x, k = sp.symbols("a b x k")
    # both inputs push on x: m x_ddot = -k x + a + b
    assert sp.simplify(plain.forcing[0] - (-k * x + a + b)) == 0


def test_an_input_used_nowhere_is_an_error_at_its_name() -> None:
    text = SPRING.replace("inputs: [a, b]", "inputs: [a, b, c]")
    message = problem(text)
    assert "sys.yaml:3:" in message and "input 'c' is used nowhere" in message
    # an input used only in an output is used nowhere in the dynamics
    message = problem(text + "outputs: {y: c*x}\n")
    assert "input 'c' is used nowhere" in message


@pytest.mark.parametrize(
    ("change", "where"),
    [
        (("position: [x]", "position: [x + a]"), "the position of 'p'"),
        (("lagrangian: b*x", "lagrangian: b*x*x_dot"), "velocity-dependent part of 'lagrangian'"),
        (("lagrangian: b*x", "lagrangian: b*x\nkinetic: b*x_dot**2"), "velocity-dependent part of 'kinetic'"),
        (("lagrangian: b*x", "lagrangian: b*x\nconstraints: {c: x = b}"), "constraint 'c'"),
    ],
)
def test_an_input_where_its_derivative_would_be_needed_is_refused(change: tuple[str, str], where: str) -> None:
    message = problem(SPRING.replace(*change))
    assert where in message and "u_dot" in message and "sys.yaml:" in message


def test_outputs_may_not_use_accelerations_or_unknown_names() -> None:
    assert "an acceleration" in problem(SPRING + "outputs: {y: x_ddot}\n")
    assert "unknown name 'z'" in problem(SPRING + "outputs: {y: z}\n")
    assert "inputs" in problem(SPRING.replace("inputs: [a, b]", "inputs: 3"))


def test_a_system_without_inputs_generates_what_it_did() -> None:
    code = python.emit(model_of(SPRING.replace("inputs: [a, b]\n", "").replace(" - a*x", "").replace("lagrangian: b*x\n", "")))
    assert "INPUTS" not in code and "u=" not in code and "def outputs" not in code


def test_generated_python_takes_inputs_after_p(tmp_path: Path) -> None:
    model = model_of(CART_POLE)
    module = load_module(python.emit(model), tmp_path / "cart.py")
    assert module.INPUTS == {"F": 0.5}
    assert "u=INPUTS" in python.emit(model).split("def rhs(")[1].split(")")[0]
    assert "u=" not in python.emit(model).split("def mass_matrix(")[1].split(")")[0]  # M does not depend on F
    y = [0.0, 0.0, 0.0, 0.0]
    # at rest and upright, the cart's acceleration is F / M... plus the pole's reaction: solve the 2x2 by hand
    M, m, length = 1.0, 0.1, 0.5
    for force in (0.5, 2.0):
        det = (M + m) * m * length**2 - (m * length) ** 2
        x_ddot = (m * length**2 * force) / det
        theta_ddot = -(m * length * force) / det
        got = module.rhs(0.0, y, u={"F": force}) if force != 0.5 else module.rhs(0.0, y)
        assert got[2] == pytest.approx(x_ddot) and got[3] == pytest.approx(theta_ddot)
    assert module.outputs(0.0, [0.3, 0.2, 1.0, 2.0]) == pytest.approx([0.3, 0.2, 0.3 + 0.5 * math.sin(0.2)])
    assert module.forcing([0.0, 0.0], [0.0, 0.0], u={"F": 3.0})[0] == pytest.approx(3.0)


def test_energy_takes_inputs_when_the_potential_holds_one(tmp_path: Path) -> None:
    module = load_module(python.emit(model_of(SPRING)), tmp_path / "spring.py")
    assert module.energy([1.0], [0.0], u={"a": 2.0, "b": 0.0}) == pytest.approx(1.5 - 2.0)
    assert module.energy([1.0], [0.0]) == pytest.approx(1.5)


def test_numeric_substitution_uses_defaults_and_given_expressions() -> None:
    model = model_of(CART_POLE)
    plain = inputs.substitute(model)
    assert not plain.inputs and not any(e.has(sp.Symbol("F")) for e in plain.forcing)
    assert plain.forcing[0].has(sp.Float(0.5)) or sp.Rational(1, 2) in plain.forcing[0].atoms(sp.Number)
    given = inputs.signal_expressions(model, [("F", "-k1*theta - k2*theta_dot", None, None)])
    fed = inputs.substitute(model, given)
    assert fed.forcing[0].has(sp.Symbol("theta_dot")) and fed.forcing[0].has(sp.Symbol("k1"))


def test_simulate_input_closes_the_loop(tmp_path: Path) -> None:
    path = tmp_path / "cart.yaml"
    path.write_text(CART_POLE)
    out = tmp_path / "run.csv"
    # PD on the pole angle keeps it up; without it (F at its default) it falls
    args = ["simulate", str(path), "--t-end", "4", "--initial", "theta=0.1", "-q", "-o", str(out)]
    result = runner.invoke(app, [*args, "--input", "F=40*theta + 10*theta_dot + 2*x + 3*x_dot"])
    assert result.exit_code == 0, result.output
    last = [float(v) for v in out.read_text().strip().splitlines()[-1].split(",")]
    assert abs(last[2]) < 0.05
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    angles = [abs(float(row.split(",")[2])) for row in out.read_text().strip().splitlines()[1:]]
    assert max(angles) > 1.0


@pytest.mark.parametrize(
    ("value", "message"),
    [("G=1", "'G' is not an input"), ("F=zz*x", "unknown name 'zz'"), ("F=x_ddot", "an acceleration"), ("F=__import__('os')", "error")],
)
def test_simulate_input_refuses_bad_names(tmp_path: Path, value: str, message: str) -> None:
    path = tmp_path / "cart.yaml"
    path.write_text(CART_POLE)
    result = runner.invoke(app, ["simulate", str(path), "--t-end", "0.1", "-q", "--input", value])
    assert result.exit_code == 2 and message in result.output and "Traceback" not in result.output


CONSTRAINED = """\
coordinates: [x, y]
parameters: {m: 1.0, g: 9.81, l: 1.0}
inputs: {tau: {value: 0.3}}
gravity: [0, -g]
particles:
  bob: {mass: m, position: [x, y], force: [-tau*y/l, tau*x/l]}
constraints:
  rod: x**2 + y**2 = l**2
"""


@pytest.mark.parametrize("text", [CART_POLE, CONSTRAINED], ids=["cart_pole", "constrained"])
def test_c_target_takes_u_after_p_and_agrees_with_python(text: str, tmp_path: Path) -> None:
    import shutil
    import subprocess

    from lagrange_cli.emit import c

    from .limits import DEADLOCK

    compiler = shutil.which("gcc") or shutil.which("cc")
    if compiler is None:
        pytest.skip("no C compiler")
    model = model_of(text)
    header = c.emit(model)
    assert "const double *p, const double *u, double *dydt)" in header and "eom_default_inputs" in header
    (tmp_path / "eom.h").write_text(header)
    n = model.n
    y = [0.3, -0.9, 0.2, 0.1][: 2 * n] if n == 2 else [0.3, 0.2]
    u = [1.7] * len(model.inputs)
    driver = f"""#include <stdio.h>
#include "eom.h"
int main(void) {{
    const double y[{2 * n}] = {{{", ".join(map(repr, y))}}};
    const double u[{len(u)}] = {{{", ".join(map(repr, u))}}};
    double dydt[{2 * n}];
    int i, status = eom_rhs(0.0, y, eom_default_parameters, u, dydt);
    for (i = 0; i < {2 * n}; ++i) printf("%.17g\\n", dydt[i]);
    printf("%.17g\\n", eom_energy(0.0, y, eom_default_parameters, eom_default_inputs));
    return status;
}}
"""
    (tmp_path / "main.c").write_text(driver)
    subprocess.run([compiler, "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-o", str(tmp_path / "main"), str(tmp_path / "main.c"), "-lm"], check=True, timeout=DEADLOCK)
    out = subprocess.run([str(tmp_path / "main")], check=True, capture_output=True, text=True, timeout=DEADLOCK).stdout.split()
    module = load_module(python.emit(model), tmp_path / "reference.py")
    names = [i.name for i in model.inputs]
    want = module.rhs(0.0, y, u=dict(zip(names, u, strict=True)))
    assert [float(v) for v in out[: 2 * n]] == pytest.approx(want, rel=1e-12, abs=1e-12)
    energy = module.energy(y[:n], y[n:], **({"u": module.INPUTS} if "u" in module.energy.__code__.co_varnames else {}))
    assert float(out[-1]) == pytest.approx(energy, rel=1e-12, abs=1e-12)


def test_octave_target_takes_u_after_p() -> None:
    from lagrange_cli.emit import octave

    code = octave.emit(model_of(CART_POLE))
    assert code.startswith("function [dydt, h, lambda] = eom(t, y, p, u)") and "F = u(1);" in code and "u = [0.5];" in code
    plain = octave.emit(model_of(CART_POLE.replace("inputs:\n  F: {value: 0.5, description: horizontal force on the cart}\n", "").replace("force: [F, 0]", "force: [1, 0]")))
    assert plain.split("\n")[0].endswith("eom(t, y, p)") and "nargin < 4" not in plain


TARGETS_WITH_U = {
    ("--to", "jax"): "def rhs(t, y, p=None, u=None):",
    ("--to", "json"): '"inputs": [',
    ("--python", "--form", "hamilton"): "def rhs(t, y, p=PARAMETERS, u=INPUTS):",
    ("--to", "c", "--form", "hamilton"): "eom_rhs(double t, const double *y, const double *p, const double *u, double *dydt)",
    ("--to", "octave", "--form", "hamilton"): "function [dydt, H, qdot] = eom(t, y, p, u)",
    ("--to", "jax", "--form", "hamilton"): "def rhs(t, y, p=None, u=None):",
    ("--to", "json", "--form", "hamilton"): '"inputs": [',
}
"""Every code target and form takes inputs (no target refuses a file with `inputs`): what each writes."""


@pytest.mark.parametrize("args", list(TARGETS_WITH_U), ids=" ".join)
def test_every_target_takes_inputs(tmp_path: Path, args: tuple[str, ...]) -> None:
    path = tmp_path / "cart.yaml"
    path.write_text(CART_POLE)
    result = runner.invoke(app, ["derive", str(path), *args])
    assert result.exit_code == 0, result.output
    assert TARGETS_WITH_U[args] in result.output


def test_a_time_derivative_of_an_input_is_refused_at_its_place() -> None:
    message = problem(SPRING.replace("lagrangian: b*x", "lagrangian: b*x\nforces: {generalized: {x: 'diff(a*x, t)'}}"))
    assert "sys.yaml:6:" in message and "would need u_dot" in message


def test_input_names_that_shadow_generated_names_are_mangled(tmp_path: Path) -> None:
    text = """\
coordinates: [x]
parameters: {m: 2.0, k: 3.0}
inputs: {u: {value: 1.0}, INPUTS: {value: 2.0}, p: {value: 4.0}, outputs: {value: 8.0}}
outputs: {y: x + u, INPUTS_out: p*x}
potential: k*x**2/2 - u*x - INPUTS*x - p*x - outputs*x
particles:
  a: {mass: m, position: [x]}
"""
    module = load_module(python.emit(model_of(text)), tmp_path / "hostile.py")
    assert module.INPUTS == {"u": 1.0, "INPUTS": 2.0, "p": 4.0, "outputs": 8.0}
    assert module.rhs(0.0, [0.0, 0.0])[1] == pytest.approx(15.0 / 2.0)
    assert module.rhs(0.0, [0.0, 0.0], u={"u": 0.0, "INPUTS": 0.0, "p": 0.0, "outputs": 2.0})[1] == pytest.approx(1.0)
    assert module.outputs(0.0, [1.0, 0.0]) == pytest.approx([2.0, 4.0])
    # the same names in the JAX module, the Python Hamilton module and the JAX Hamilton module (y = [x, p_x], p_x = m x_dot)
    import numpy as np

    from lagrange_cli.emit import hamiltonian, jax

    pytest.importorskip("jax")
    given = {"u": 0.0, "INPUTS": 0.0, "p": 0.0, "outputs": 2.0}
    target = load_module(jax.emit(model_of(text)), tmp_path / "hostile_jax.py")
    assert target.INPUTS == module.INPUTS and target.INPUT_NAMES == ("u", "INPUTS", "p", "outputs")
    assert float(target.rhs(0.0, [0.0, 0.0])[1]) == pytest.approx(15.0 / 2.0) and float(target.rhs(0.0, [0.0, 0.0], None, given)[1]) == pytest.approx(1.0)
    assert float(target.rhs(0.0, [0.0, 0.0], None, np.asarray([0.0, 0.0, 0.0, 2.0]))[1]) == pytest.approx(1.0)
    np.testing.assert_allclose(np.asarray(target.outputs(0.0, [1.0, 0.0])), [2.0, 4.0])
    for code, name in ((hamiltonian.python(model_of(text)), "hostile_ham.py"), (jax.emit_hamilton(model_of(text)), "hostile_jax_ham.py")):
        ham = load_module(code, tmp_path / name)
        assert ham.INPUTS == module.INPUTS
        assert [float(v) for v in ham.rhs(0.0, [0.0, 0.0])] == pytest.approx([0.0, 15.0])
        assert [float(v) for v in ham.rhs(0.0, [0.0, 0.0], None if "jax" in name else ham.PARAMETERS, given)] == pytest.approx([0.0, 2.0])


def test_outputs_follow_an_eliminated_coordinate() -> None:
    text = """\
coordinates: [x, y]
parameters: {m: 1.0, g: 9.81}
inputs: [f]
outputs: {height: y}
gravity: [0, -g]
particles:
  a: {mass: m, position: [x, y], force: [f, 0]}
constraints:
  incline: y = x
eliminate: [y]
"""
    model = model_of(text)
    assert model.outputs == (("height", sp.Symbol("x")),)


def test_each_input_expression_gets_its_own_compiled_module(tmp_path: Path) -> None:
    """The compile cache is keyed by the generated source, which holds the substituted inputs."""
    path = tmp_path / "cart.yaml"
    path.write_text(CART_POLE)
    finals = []
    for value in ("1", "2", "1"):
        out = tmp_path / f"run{len(finals)}.csv"
        result = runner.invoke(app, ["simulate", str(path), "--t-end", "1", "-q", "--backend", "python", "--samples", "11", "--input", f"F={value}", "-o", str(out)])
        assert result.exit_code == 0, result.output
        finals.append(float(out.read_text().strip().splitlines()[-1].split(",")[1]))
    assert finals[0] == finals[2] and finals[1] != pytest.approx(finals[0], rel=1e-3)


def test_octave_function_runs_with_and_without_u(tmp_path: Path) -> None:
    import shutil
    import subprocess

    from lagrange_cli.emit import octave

    from .limits import DEADLOCK

    toolchain = shutil.which("octave")
    if toolchain is None:
        pytest.skip("octave is not installed")
    model = model_of(CART_POLE)
    (tmp_path / "eom.m").write_text(octave.emit(model), encoding="ascii")
    script = "y = [0; 0.1; 0.2; 0.3]; printf('%.17g\\n', eom(0, y)); printf('%.17g\\n', eom(0, y, [], [2]));"
    (tmp_path / "run_inputs.m").write_text(script, encoding="ascii")
    done = subprocess.run(
        [toolchain, "--no-gui", "--no-window-system", "--quiet", "--no-init-file", "--eval", "run_inputs"], cwd=tmp_path, capture_output=True, text=True, check=False, timeout=DEADLOCK
    )
    values = [float(v) for v in done.stdout.split()]
    module = load_module(python.emit(model), tmp_path / "reference.py")
    y = [0.0, 0.1, 0.2, 0.3]
    assert values == pytest.approx([*module.rhs(0.0, y), *module.rhs(0.0, y, u={"F": 2.0})], rel=1e-12, abs=1e-12), done.stderr


def test_conserved_answers_hold_with_the_inputs_held_constant(tmp_path: Path) -> None:
    """An input in the potential keeps the energy conserved (held constant it is a parameter); an
    input force does work, so neither the energy nor the cart's momentum is conserved."""
    path = tmp_path / "spring.yaml"
    path.write_text(SPRING + "expect:\n  conserved: [energy]\n  accelerations: {x_ddot: (a + b - k*x)/m}\n")
    result = runner.invoke(app, ["check", str(path)])
    assert result.exit_code == 0, result.output
    path.write_text(CART_POLE + "expect:\n  conserved: [x]\n")
    result = runner.invoke(app, ["check", str(path)])
    assert result.exit_code == 1 and "a generalized force F acts on it" in result.output
