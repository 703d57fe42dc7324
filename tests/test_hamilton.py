"""Hamilton's equations (`derive --form hamilton`, lagrange_cli/hamilton.py): agreement with the
Lagrange form for every bundled system, the generated Python module in (q, p), the numeric route
for large systems, the refusals, and `check`'s `hamiltonian` and `hamilton_equations` keys."""

from __future__ import annotations

import inspect
import random
from pathlib import Path

import pytest
import sympy as sp
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.errors import LagrangeError
from lagrange_cli.hamilton import hamilton
from lagrange_cli.model import Model
from lagrange_cli.spec import time_derivative

from .conftest import SYSTEMS
from .helpers import load_module, model_from, model_of, random_point
from .test_latex_layout import PDFLATEX, overflows

CHAIN_4 = """title: 4-link chain
coordinates: [a1, a2, a3, a4]
parameters: {m: 1.0, l: 1.0, g: 9.81}
gravity: [0, -g]
particles:
  b1: {mass: m, position: [l*sin(a1), -l*cos(a1)]}
  b2: {mass: m, position: [l*sin(a1) + l*sin(a2), -l*cos(a1) - l*cos(a2)]}
  b3: {mass: m, position: [l*sin(a1) + l*sin(a2) + l*sin(a3), -l*cos(a1) - l*cos(a2) - l*cos(a3)]}
  b4: {mass: 2*m, position: [l*sin(a1) + l*sin(a2) + l*sin(a3) + l*sin(a4), -l*cos(a1) - l*cos(a2) - l*cos(a3) - l*cos(a4)]}
dissipation: (a1_dot**2 + a4_dot**2)/10
"""


def _lagrange_side(model: Model, point: dict[sp.Symbol, float]) -> tuple[list[float], list[float]]:
    """p = dL/dq_dot and p_dot = d/dt dL/dq_dot (with the Lagrange accelerations) at `point`."""
    mass = sp.Matrix(model.mass_matrix).xreplace(point)
    accelerations = mass.LUsolve(sp.Matrix(model.forcing).xreplace(point))
    full = {**point, **dict(zip(model.qdd, accelerations, strict=True))}
    momenta = [float(p.xreplace(point)) for p in model.momenta]
    rates = [float(time_derivative(p, model.q, model.qd, model.qdd, model.t).xreplace(full)) for p in model.momenta]
    return momenta, rates


def _with_inputs(model: Model, point: dict[sp.Symbol, float], seed: int) -> dict[sp.Symbol, float]:
    """`point` with random values for the model's inputs (given values at time t)."""
    rng = random.Random(100 + seed)
    return {**point, **{i.symbol: rng.uniform(-2.0, 2.0) for i in model.inputs}}


def _agree(model: Model, seeds: range) -> None:
    ham = hamilton(model)
    for seed in seeds:
        point = _with_inputs(model, random_point(model, seed), seed)
        momenta, rates = _lagrange_side(model, point)
        state = {**point, **dict(zip(ham.p, momenta, strict=True))}
        if ham.symbolic:
            velocities = [float(v.xreplace(state)) for v in ham.velocities]
            got = [float(r.xreplace(state)) for r in ham.rates]
        else:  # the numeric route: q_dot solved from M q_dot = p - b
            mass = sp.Matrix(ham.mass).xreplace(state)
            velocities = [float(v) for v in mass.LUsolve(sp.Matrix([p - b for p, b in zip(momenta, ham.bias, strict=True)]).xreplace(state))]
            got = [float(r.xreplace({**state, **dict(zip(model.qd, velocities, strict=True))})) for r in ham.rates]
        assert velocities == pytest.approx([point[v] for v in model.qd], rel=1e-9, abs=1e-9)
        assert got == pytest.approx(rates, rel=1e-8, abs=1e-8)


@pytest.mark.parametrize("path", SYSTEMS, ids=lambda p: p.stem)
def test_every_bundled_system_agrees_with_the_lagrange_form(path: Path) -> None:
    model = model_from(path).with_definitions()
    if model.constraints:
        with pytest.raises(LagrangeError, match="kept constraints"):
            hamilton(model)
        return
    if any(e.atoms(sp.core.function.AppliedUndef) for e in (model.lagrangian, *model.generalized_forces)):
        pytest.skip("a function left undefined")
    _agree(model, range(2))


def test_hamilton_equations_are_the_derivatives_of_h() -> None:
    """q_dot = dH/dp and p_dot = -dH/dq - dR/dq_dot + Q, with H differentiated (not the shortcut)."""
    for name in ("damped_oscillator_rayleigh", "charged_particle_magnetic", "double_pendulum", "kapitza_pendulum"):
        model = model_from(Path("systems") / f"{name}.yaml")
        ham = hamilton(model)
        assert ham.hamiltonian is not None
        solved = dict(zip(model.qd, ham.velocities, strict=True))
        point = random_point(model, 3)
        state = {**point, **{p: 0.3 + 0.2 * i for i, p in enumerate(ham.p)}}
        for i in range(model.n):
            assert float(sp.diff(ham.hamiltonian, ham.p[i]).xreplace(state)) == pytest.approx(float(ham.velocities[i].xreplace(state)), rel=1e-9)
            extra = (model.generalized_forces[i] - sp.diff(model.dissipation, model.qd[i])).xreplace(solved)
            assert float((-sp.diff(ham.hamiltonian, model.q[i]) + extra).xreplace(state)) == pytest.approx(float(ham.rates[i].xreplace(state)), rel=1e-8, abs=1e-10)


def test_large_systems_take_the_numeric_route_and_agree() -> None:
    model = model_of(CHAIN_4, "chain_4.yaml")
    ham = hamilton(model)
    assert not ham.symbolic and ham.hamiltonian is None
    _agree(model, range(2))


@pytest.mark.parametrize("source", ["kepler", "heavy_top", "damped_oscillator_rayleigh", "chain"])
def test_generated_module_in_q_and_p_agrees_with_the_library(source: str, tmp_path: Path) -> None:
    from lagrange_cli.emit import hamiltonian

    model = model_of(CHAIN_4, "chain_4.yaml") if source == "chain" else model_from(Path("systems") / f"{source}.yaml")
    code = hamiltonian.python(model)
    assert "y = [" in code and "momenta p = dL/dq_dot (not the velocities)" in code
    module = load_module(code, tmp_path / f"ham_{source}.py")
    assert tuple(f"p_{c}" for c in model.coordinates) == module.MOMENTA
    parameters = dict(module.PARAMETERS)
    for seed in range(2):
        point = random_point(model, seed)
        q = [point[s] for s in model.q]
        qd = [point[s] for s in model.qd]
        momenta, rates = _lagrange_side(model, point)
        assert module.momenta(point[model.t], q, qd, parameters) == pytest.approx(momenta, rel=1e-9)
        y = [*q, *momenta]
        assert module.rhs(point[model.t], y, parameters) == pytest.approx([*qd, *rates], rel=1e-8, abs=1e-8)
        assert module.hamiltonian(point[model.t], y, parameters) == pytest.approx(float(model.energy.xreplace(point)), rel=1e-9)


CHAIN_4_DRIVEN = CHAIN_4.replace("dissipation:", "inputs: {tau: {value: 0.5}, f: {value: -1.0}}\npotential: -tau*a1 - f*a4*a2\ndissipation:")
"""The numeric route (a full 4 x 4 M) with inputs in the potential."""


@pytest.mark.parametrize("source", ["cart_pole_state_space", "quadrotor", "arm_3dof", "chain"])
def test_generated_module_with_inputs_takes_u_after_p_and_agrees(source: str, tmp_path: Path) -> None:
    """Hamilton's equations treat inputs as given values: the module has INPUTS and takes `u=INPUTS` after p on
    every function whose result depends on one; at random states and random inputs rhs, velocities and H agree
    with the Python module of the Lagrange form (q_dot, its energy) and with p_dot = d/dt dL/dq_dot, for
    both routes (symbolic, and numeric for the 4-link chain)."""
    from lagrange_cli.emit import hamiltonian, python

    model = model_of(CHAIN_4_DRIVEN, "chain_4_driven.yaml") if source == "chain" else model_from(Path("systems") / f"{source}.yaml")
    module = load_module(hamiltonian.python(model), tmp_path / f"ham_{source}.py")
    lagrange = load_module(python.emit(model), tmp_path / f"lag_{source}.py")
    assert module.INPUTS == lagrange.INPUTS and list(module.INPUTS) == [i.name for i in model.inputs]
    assert list(inspect.signature(module.rhs).parameters) == ["t", "y", "p", "u"]
    assert inspect.signature(module.rhs).parameters["u"].default == module.INPUTS
    assert hamilton(model).symbolic == (source in ("cart_pole_state_space", "arm_3dof"))  # quadrotor and the chain: the numeric route
    parameters = dict(module.PARAMETERS)
    for seed in range(2):
        point = _with_inputs(model, random_point(model, seed), seed)
        u = {i.name: point[i.symbol] for i in model.inputs}
        t = point[model.t]
        q, qd = [point[s] for s in model.q], [point[s] for s in model.qd]
        momenta, rates = _lagrange_side(model, point)
        assert module.momenta(t, q, qd, parameters) == pytest.approx(momenta, rel=1e-9)
        y = [*q, *momenta]
        got = module.rhs(t, y, parameters, u)
        assert got == pytest.approx([*qd, *rates], rel=1e-8, abs=1e-8)
        assert got != pytest.approx(module.rhs(t, y, parameters), rel=1e-6)  # the inputs matter (the defaults differ)
        accelerations = lagrange.rhs(t, [*q, *qd], parameters, u)[model.n :]
        lagrange_rates = [float(time_derivative(p, model.q, model.qd, model.qdd, model.t).xreplace({**point, **dict(zip(model.qdd, accelerations, strict=True))})) for p in model.momenta]
        assert got[model.n :] == pytest.approx(lagrange_rates, rel=1e-8, abs=1e-8)
        assert module.velocities(t, y, parameters, **({"u": u} if "u" in inspect.signature(module.velocities).parameters else {})) == pytest.approx(qd, rel=1e-9, abs=1e-9)
        energy = lagrange.energy(
            *([t] if "t" in inspect.signature(lagrange.energy).parameters else []), q, qd, parameters, **({"u": u} if "u" in inspect.signature(lagrange.energy).parameters else {})
        )
        h = module.hamiltonian(t, y, parameters, **({"u": u} if "u" in inspect.signature(module.hamiltonian).parameters else {}))
        assert h == pytest.approx(float(energy), rel=1e-9, abs=1e-9)


def _run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, list(args))
    return result.exit_code, result.stdout, result.stderr


def test_cli_text_form() -> None:
    code, out, _ = _run("derive", "kepler", "--form", "hamilton")
    assert code == 0
    assert "H = -k/r + p_r**2/(2*m) + p_theta**2/(2*m*r**2)" in out
    assert "p_r_dot = (-k*m*r + p_theta**2)/(m*r**3)" in out and "p_theta_dot = 0" in out


WRITTEN = {"jax": "def rhs(t, y, p=None):", "octave": "function [dydt, H, qdot] = eom(t, y, p)", "c": "static inline int eom_velocities(", "json": '"momentum_rates"'}
"""The targets besides text, latex and python that write `--form hamilton`, and a line of their output
(the targets' own tests, tests/test_target_*.py, check the equations numerically)."""


@pytest.mark.parametrize("target", ["c", "octave", "jax", "json"])
def test_every_target_writes_the_form_or_refuses_it(target: str) -> None:
    code, out, err = _run("derive", "kepler", "--form", "hamilton", "--to", target)
    if target in WRITTEN:
        assert code == 0 and WRITTEN[target] in out and "p_r" in out, err
    else:
        assert code == 2 and f"--form hamilton is not available for --to {target}" in err


def test_kept_constraints_are_refused() -> None:
    code, _, err = _run("derive", "rolling_coin", "--form", "hamilton")
    assert code == 2 and "kept constraints" in err and "Traceback" not in err


def test_numba_is_refused_with_the_form() -> None:
    code, _, err = _run("derive", "kepler", "--form", "hamilton", "--python", "--numba")
    assert code == 2 and "--numba is not available with --form hamilton" in err


KEPLER = """title: Kepler
coordinates: [r, theta]
parameters: {m: 1.0, k: 1.0}
particles:
  body: {mass: m, position: [r*cos(theta), r*sin(theta)]}
potential: -k/r
expect:
  hamiltonian: HAMILTONIAN
  hamilton_equations:
    - r_dot = p_r/m
    - theta_dot = p_theta/(m*r**2)
    - p_r_dot = RATE
    - p_theta_dot = 0
"""
RIGHT = {"HAMILTONIAN": "p_r**2/(2*m) + p_theta**2/(2*m*r**2) - k/r", "RATE": "p_theta**2/(m*r**3) - k/r**2"}


def _check(tmp_path: Path, **changes: str) -> tuple[int, str]:
    text = KEPLER
    for key, value in {**RIGHT, **changes}.items():
        text = text.replace(key, value)
    path = tmp_path / "kepler_h.yaml"
    path.write_text(text)
    code, out, err = _run("check", str(path))
    return code, out + err


def test_check_accepts_right_answers(tmp_path: Path) -> None:
    code, out = _check(tmp_path)
    assert code == 0, out


def test_check_rejects_a_wrong_hamiltonian(tmp_path: Path) -> None:
    code, out = _check(tmp_path, HAMILTONIAN="p_r**2/(2*m) + p_theta**2/(2*m*r**2) + k/r")
    assert code == 1 and "hamiltonian: differs from the Legendre transform" in out


def test_check_rejects_wrong_hamilton_equations(tmp_path: Path) -> None:
    code, out = _check(tmp_path, RATE="p_theta**2/(m*r**3) + k/r**2")
    assert code == 1 and "equation 3 does not hold" in out


def test_check_rejects_dependent_hamilton_equations(tmp_path: Path) -> None:
    text = KEPLER.replace("- p_theta_dot = 0", "- 2*r_dot = 2*p_r/m")
    for key, value in RIGHT.items():
        text = text.replace(key, value)
    path = tmp_path / "dependent.yaml"
    path.write_text(text)
    code, _, err = _run("check", str(path))
    assert code == 1 and "do not determine" in err


def test_check_refuses_malformed_answers_with_file_line_column(tmp_path: Path) -> None:
    code, out = _check(tmp_path, HAMILTONIAN="p_r**2/(2*m*r_dot)")
    assert code == 2 and "kepler_h.yaml:8:28: error: 'r_dot' is a velocity" in out
    code, out = _check(tmp_path, RATE="p_q**2")
    assert code == 2 and "kepler_h.yaml:12:17: error:" in out


def test_check_refuses_a_declared_momentum_name(tmp_path: Path) -> None:
    path = tmp_path / "clash.yaml"
    path.write_text(KEPLER.replace("{m: 1.0, k: 1.0}", "{m: 1.0, k: 1.0, p_r: 2.0}").replace("HAMILTONIAN", RIGHT["HAMILTONIAN"]).replace("RATE", RIGHT["RATE"]))
    code, _, err = _run("check", str(path))
    assert code == 2 and "'p_r' is declared in the file" in err and "clash.yaml:8:" in err


def _latex_parts() -> dict[str, str]:
    from lagrange_cli.emit import hamiltonian

    parts = {}
    for path in SYSTEMS:
        model = model_from(path)
        if not model.constraints:
            parts[path.stem] = hamiltonian.latex(model)
    parts["chain_4"] = hamiltonian.latex(model_of(CHAIN_4, "chain_4.yaml"))
    return parts


@pytest.mark.latex
@pytest.mark.skipif(PDFLATEX is None, reason="pdflatex not installed")
def test_latex_of_every_system_compiles_and_fits_an_article(tmp_path: Path) -> None:
    parts = _latex_parts()
    assert "heavy_top" in parts and "chain_4" in parts
    assert overflows(tmp_path, "hamilton", parts) == {}


@pytest.mark.latex
@pytest.mark.skipif(PDFLATEX is None, reason="pdflatex not installed")
def test_latex_standalone_document_compiles(tmp_path: Path) -> None:
    code, out, _ = _run("derive", "heavy_top", "--form", "hamilton", "--latex", "--standalone")
    assert code == 0 and out.rstrip().endswith("\\end{document}")
    assert overflows(tmp_path, "doc", {"heavy_top_h": out}, standalone=True) == {}


def test_hostile_files_are_bounded_and_safe(tmp_path: Path) -> None:
    """A potential whose expansion is huge ((1 + x + ...)**90) is tidied without expanding it; Abs
    and sign are differentiated by the deriver (no re/im in the rates); names are mangled."""
    from lagrange_cli.emit import hamiltonian

    huge = model_from(Path("tests/hostile/huge_expand.yaml"))
    ham = hamilton(huge)
    assert ham.symbolic and all(sp.count_ops(r) < 5000 for r in ham.rates)
    model = model_from(Path("tests/hostile/name_builtin_abs.yaml"))
    ham = hamilton(model)
    assert not any(r.has(sp.re, sp.im) for r in ham.rates)
    module = load_module(hamiltonian.python(model), tmp_path / "ham_abs.py")
    point = random_point(model, 1)
    momenta, rates = _lagrange_side(model, point)
    assert module.rhs(0.0, [point[model.q[0]], *momenta], dict(module.PARAMETERS)) == pytest.approx([point[model.qd[0]], *rates], rel=1e-9)


def test_api_to_with_the_hamilton_form() -> None:
    from lagrange_cli import api

    system = api.load("kepler")
    assert "H = -k/r + p_r**2/(2*m) + p_theta**2/(2*m*r**2)" in system.to("text", form="hamilton")
    assert "MOMENTA = " in system.to("python", form="hamilton")
    assert "\\dot{p}_{r}" in system.to("latex", form="hamilton")
    assert "_velocities(" in system.to("c", form="hamilton")  # every target, as `derive --form hamilton`


def test_p_dot_keeps_plain_terms_apart_and_its_denominator_a_square() -> None:
    """-dH/dq of the double pendulum reads as gravity plus one quotient over det(M)**2 (as written by
    hand), not everything over the expanded square of the determinant."""
    result = CliRunner().invoke(app, ["derive", str(SYSTEMS[0].parent / "double_pendulum.yaml"), "--form", "hamilton"])
    assert result.exit_code == 0, result.output
    p_theta_dot = next(line for line in result.output.splitlines() if line.startswith("p_theta_dot = "))
    assert p_theta_dot.startswith("p_theta_dot = -2*g*l*m*sin(theta) + ")
    assert p_theta_dot.endswith("/(l**2*m*(3 - cos(2*(phi - theta)))**2)")
