"""info, equilibria and linearize answer the chapter's questions."""

from __future__ import annotations

import json
import math

import sympy as sp
from typer.testing import CliRunner

from lagrange_cli import analysis
from lagrange_cli.cli import app

from .conftest import ROOT
from .helpers import model_from

runner = CliRunner()


def system(name: str):
    return model_from(ROOT / "systems" / f"{name}.yaml")


def test_exercise_6_1_stability_condition() -> None:
    model = system("rotating_rod_strings")
    theta = model.q[0]
    lin = analysis.linearize(model, {theta: sp.Integer(0)})
    g, length, omega = sp.symbols("g l omega")
    assert lin.condition == (sp.StrictLessThan(omega**2, g / length),)
    result = runner.invoke(app, ["equilibria", "rotating_rod_strings"])
    assert result.exit_code == 0 and "stable when: omega**2 < g/l" in result.stdout


def test_exercise_6_6_conserved_momenta_and_steady_precession() -> None:
    model = system("free_symmetric_top")
    info = analysis.info(model)
    assert set(info.ignorable) == {"phi", "psi"} and info.energy_conserved
    (velocity, value), *_ = analysis.steady_motions(model)
    i_perp, i_par, theta, phi_dot = sp.symbols("I_perp I_par theta phi_dot")
    assert str(velocity) == "psi_dot"
    assert sp.simplify(value - (i_perp - i_par) / i_par * sp.cos(theta) * phi_dot) == 0


def test_hamiltonian_of_the_central_potential() -> None:
    model = system("central_potential")
    info = analysis.info(model)
    m, r = sp.symbols("m r")
    p_r, p_theta = info.momentum_symbols
    expected = p_r**2 / (2 * m) + p_theta**2 / (2 * m * r**2) + sp.Function("U")(r)
    assert info.hamiltonian is not None and sp.simplify(info.hamiltonian - expected) == 0
    assert info.ignorable == ("theta",)


def test_double_pendulum_normal_modes() -> None:
    model = system("double_pendulum")
    lin = analysis.linearize(model, {q: sp.Integer(0) for q in model.q})
    g, length = 9.81, 1.0
    expected = sorted(math.sqrt((2 + s * math.sqrt(2)) * g / length) for s in (-1, 1))
    assert [round(f, 9) for f in lin.frequencies] == [round(f, 9) for f in expected]
    assert lin.stability.startswith("stable")
    upright = analysis.linearize(model, {model.q[0]: sp.pi, model.q[1]: sp.pi})
    assert upright.stability == "unstable"


def test_no_equilibrium_on_a_slope() -> None:
    assert analysis.equilibria(system("rolling_disk_pendulum")) == []


def test_info_outputs_and_errors() -> None:
    data = json.loads(runner.invoke(app, ["info", "kepler", "--json"]).stdout)
    assert data["ignorable"] == ["theta"] and data["energy_conserved"] is True and data["hamiltonian"]
    assert "\\begin{align*}" in runner.invoke(app, ["info", "kepler", "--latex"]).stdout
    text = runner.invoke(app, ["info", "atwood_machine_multiplier"]).stdout
    assert "constraint string: holonomic" in text
    result = runner.invoke(app, ["linearize", "double_pendulum", "--about", "theta=1"])
    assert result.exit_code == 2 and "not an equilibrium" in result.output
    result = runner.invoke(app, ["linearize", "double_pendulum", "--about", "nope=1"])
    assert result.exit_code == 2 and "not a coordinate" in result.output
    result = runner.invoke(app, ["equilibria", "pendulum_moving_support"])
    assert result.exit_code == 2 and "depends explicitly on time" in result.output


def test_numeric_search_when_sympy_cannot_solve(tmp_path) -> None:
    path = tmp_path / "washboard.yaml"
    path.write_text("coordinates: [x]\nparameters: {m: 1.0, a: 0.3}\nkinetic: m*x_dot**2/2\npotential: cos(x) + a*x**2 + x*exp(x/7)\n")
    model = model_from(path)
    points = analysis.equilibria(model, {model.q[0]: (-3.0, 3.0)}, seconds=0.5)
    for point in points:
        x = float(point[model.q[0]])
        assert abs(-math.sin(x) + 0.6 * x + math.exp(x / 7) * (1 + x / 7)) < 1e-8
    assert points
