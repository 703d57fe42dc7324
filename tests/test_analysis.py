"""info, equilibria and linearize answer the chapter's questions."""

from __future__ import annotations

import json
import math

import pytest
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


ELASTIC_IN_R = """title: elastic pendulum in r
coordinates: [r, phi]
parameters: {m: 0.7, k: 230.0, L: 0.8, g: 9.81, c: 0.05}
gravity: [0, -g]
particles:
  bob: {mass: m, position: [r*sin(phi), -r*cos(phi)]}
potential: k*(r - L)**2/2
dissipation: c*r_dot**2/2
"""


def test_about_takes_the_equilibrium_as_equilibria_prints_it(tmp_path) -> None:
    """`equilibria` prints r = L + g*m/k; `--about` accepts that text, and the linearization is in
    the parameters (the same matrices as `equilibria` gives about that point)."""
    path = tmp_path / "elastic.yaml"
    path.write_text(ELASTIC_IN_R)
    listed = runner.invoke(app, ["equilibria", str(path), "--json"])
    assert listed.exit_code == 0, listed.output
    result = runner.invoke(app, ["linearize", str(path), "--about", "r=L + g*m/k", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["point"] == {"r": "L + g*m/k", "phi": "0"}
    m, k, L, g = sp.symbols("m k L g")
    assert sp.simplify(sp.sympify(data["K0"][1][1]) - g * m * (L * k + g * m) / k) == 0
    assert sp.sympify(data["K0"][0][0]) == k and sp.sympify(data["C0"][0][0]) == sp.Symbol("c")
    # numbers still work and give the same stiffness at the parameters' values
    numeric = json.loads(runner.invoke(app, ["linearize", str(path), "--about", f"r={0.8 + 9.81 * 0.7 / 230.0!r}", "--json"]).stdout)
    at_values = {m: 0.7, k: 230.0, L: 0.8, g: 9.81}
    assert float(sp.sympify(numeric["K0"][1][1]).xreplace(at_values)) == pytest.approx(9.81 * 0.7 * (0.8 * 230 + 9.81 * 0.7) / 230)


@pytest.mark.parametrize(
    ("about", "message"),
    [
        ("r=phi", "'phi' is a coordinate, which cannot appear here"),
        ("r=r_dot", "'r_dot' is a velocity"),
        ("r=q", "unknown name 'q'"),
        ("r=1/(k - 230)", "must be a finite real number at the parameters' values"),
        ("r=L + g*m/k,phi=pi", "is not an equilibrium"),
    ],
)
def test_about_with_parameters_refuses_bad_values(tmp_path, about: str, message: str) -> None:
    path = tmp_path / "elastic.yaml"
    path.write_text(ELASTIC_IN_R)
    result = runner.invoke(app, ["linearize", str(path), "--about", about])
    assert result.exit_code == 2 and message in result.output, result.output
    assert "Traceback" not in result.output


def test_default_point_not_an_equilibrium_says_how_to_find_one(tmp_path) -> None:
    path = tmp_path / "elastic.yaml"
    path.write_text(ELASTIC_IN_R)
    result = runner.invoke(app, ["linearize", str(path)])
    assert result.exit_code == 2
    assert "the default point (every coordinate 0) is not an equilibrium" in result.output
    assert "lagrange equilibria" in result.output and "--about" in result.output


def test_forces_off_equilibrium_are_simplified_with_positive_parameters_and_given_as_numbers(tmp_path) -> None:
    # the wall's penalty max(0, d - R) written (e + Abs(e))/2: at the bottom of the cup d = R, and
    # the forces there were printed as a Piecewise in R - sqrt(R**2); parameters are positive
    path = tmp_path / "cup.yaml"
    path.write_text(
        "coordinates: [x, y]\nparameters: {m: 2.0, R: 1.5, k: 1000.0, g: 9.81}\ngravity: [0, -g]\n"
        "particles:\n  ball: {mass: m, position: [x, y]}\n"
        "potential: k/2*((sqrt(x**2 + (y - R)**2) - R + Abs(sqrt(x**2 + (y - R)**2) - R))/2)**2\n"
    )
    result = runner.invoke(app, ["linearize", str(path)])
    assert result.exit_code == 2, result.output
    assert "the generalized forces there are ['0', '-g*m'], that is [0.0, -19.62] at the parameters' values" in result.output
    assert "Piecewise" not in result.output and "sqrt(R**2)" not in result.output


def test_api_linearize_about_parameters(tmp_path) -> None:
    from lagrange_cli.api import load

    path = tmp_path / "elastic.yaml"
    path.write_text(ELASTIC_IN_R)
    system = load(path)
    report = system.linearize({"r": "L + g*m/k"})
    assert "about r = L + g*m/k, phi = 0" in str(report)
    with pytest.raises(Exception, match="'phi' is a coordinate"):
        system.linearize({"r": "phi"})
