"""`info`, `equilibria` and `linearize` of systems with kept constraints, cross-checked against
hand-derived answers and against the same systems with the constraints eliminated; values at a
point substituted without breaking derivatives of declared functions; sympy's solve and simplify
bounded by size, never by time."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import sympy as sp
from typer.testing import CliRunner

from lagrange_cli import analysis
from lagrange_cli.cli import app
from lagrange_cli.errors import DerivationError

from .conftest import ROOT
from .helpers import model_from

runner = CliRunner()


def system(name: str):
    return model_from(ROOT / "systems" / f"{name}.yaml")


def write(tmp_path: Path, name: str, text: str):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text, encoding="utf-8")
    return model_from(path)


def point(model, **values: object) -> dict[sp.Symbol, sp.Expr]:
    return {q: sp.sympify(values.get(str(q), 0)) for q in model.q}


CARTESIAN_PENDULUM = """title: Cartesian pendulum
coordinates: [x, y]
parameters: {m: 1.3, l: 2.0, g: 9.81}
gravity: [0, -g]
particles:
  bob: {mass: m, position: [x, y]}
constraints:
  rod: x**2 + y**2 = l**2
"""

PARABOLA = """title: Bead on a parabola
coordinates: [x, y]
parameters: {m: 0.7, g: 9.81, a: 0.8}
gravity: [0, -g]
particles:
  bead: {mass: m, position: [x, y]}
constraints:
  wire: y = a*x**2
"""


def test_cartesian_pendulum_swings_at_sqrt_g_over_l(tmp_path: Path) -> None:
    model = write(tmp_path, "pendulum", CARTESIAN_PENDULUM)
    lin = analysis.linearize(model, point(model, y="-l"))
    assert lin.coordinates == ("x",) and dict(lin.dependent) == {"dy": 0}
    (lam,) = lin.multipliers.values()
    assert sp.simplify(lam - sp.sympify("-g*m/(2*l)", locals={str(s): s for s in lam.free_symbols})) == 0
    assert lin.frequencies == pytest.approx((math.sqrt(9.81 / 2.0),), rel=1e-12)
    assert lin.stability.startswith("stable")
    # the same pendulum with its rod eliminated (theta): frequencies agree to 1e-10
    polar = write(tmp_path, "polar", CARTESIAN_PENDULUM.replace("coordinates: [x, y]", "coordinates: [theta]").replace("[x, y]}", "[l*sin(theta), -l*cos(theta)]}").split("constraints:")[0])
    assert abs(analysis.linearize(polar, point(polar)).frequencies[0] - lin.frequencies[0]) < 1e-10
    assert analysis.linearize(model, point(model, y="l")).stability == "unstable"


def test_pendulum_equilibria_report_the_rod_tension(tmp_path: Path) -> None:
    model = write(tmp_path, "pendulum", CARTESIAN_PENDULUM)
    found = sorted(analysis.equilibria(model), key=lambda p: float(p[model.q[1]].subs({sp.Symbol("l"): 2})))
    l_ = next(iter(found[0][model.q[1]].free_symbols))
    assert [p[model.q[1]] for p in found] == [-l_, l_] and all(p[model.q[0]] == 0 for p in found)
    result = runner.invoke(app, ["equilibria", str(tmp_path / "pendulum.yaml"), "--json"])
    assert result.exit_code == 0, result.output
    items = json.loads(result.stdout)["equilibria"]
    assert [item["multipliers"] for item in items] == [{"lambda_rod": "-g*m/(2*l)"}, {"lambda_rod": "g*m/(2*l)"}]
    assert [item["coordinates"] for item in items] == [["x"], ["x"]]


def test_bead_on_a_parabola_at_sqrt_2ag(tmp_path: Path) -> None:
    model = write(tmp_path, "parabola", PARABOLA)
    (rest,) = analysis.equilibria(model)
    assert rest == {model.q[0]: 0, model.q[1]: 0}
    lin = analysis.linearize(model, rest)
    assert lin.frequencies == pytest.approx((math.sqrt(2 * 0.8 * 9.81),), rel=1e-12)
    eliminated = write(tmp_path, "eliminated", PARABOLA + "eliminate: [y]\n")
    assert abs(analysis.linearize(eliminated, point(eliminated)).frequencies[0] - lin.frequencies[0]) < 1e-10


def test_cartesian_double_pendulum_matches_the_angles(tmp_path: Path) -> None:
    """Two rods, four coordinates: independent coordinates chosen by pivoting, the two normal
    modes equal to those of the double pendulum in angles."""
    model = write(
        tmp_path,
        "double",
        """title: Cartesian double pendulum
coordinates: [x1, y1, x2, y2]
parameters: {m: 1.0, l: 1.0, g: 9.81}
gravity: [0, -g]
particles:
  upper: {mass: m, position: [x1, y1]}
  lower: {mass: m, position: [x2, y2]}
constraints:
  upper_rod: x1**2 + y1**2 = l**2
  lower_rod: (x2 - x1)**2 + (y2 - y1)**2 = l**2
""",
    )
    lin = analysis.linearize(model, point(model, y1="-l", y2="-2*l"))
    assert sorted(lin.coordinates) == ["x1", "x2"]
    # six unknowns (four coordinates, two multipliers): beyond sympy's bound, found numerically
    found = analysis.equilibria(model, {q: (-2.5, 2.5) for q in model.q})
    heights = sorted((round(float(p[model.q[1]]), 6), round(float(p[model.q[3]]), 6)) for p in found)
    assert heights == [(-1.0, -2.0), (-1.0, 0.0), (1.0, 0.0), (1.0, 2.0)]
    assert all(abs(float(p[model.q[0]])) < 1e-7 and abs(float(p[model.q[2]])) < 1e-7 for p in found)
    angles = analysis.linearize(system("double_pendulum"), point(system("double_pendulum")))
    assert len(lin.frequencies) == 2
    assert max(abs(a - b) for a, b in zip(lin.frequencies, angles.frequencies, strict=True)) < 1e-10


@pytest.mark.parametrize("name", ["rolling_coin", "knife_edge_incline", "chaplygin_sleigh"])
def test_velocity_constraints_linearize_about_rest(name: str) -> None:
    model = system(name)
    about = point(model, phi="pi/2") if name == "knife_edge_incline" else point(model)
    lin = analysis.linearize(model, about)
    rows = sum(1 for c in model.constraints if not c.holonomic)
    assert len(lin.velocities) == model.n - len(model.constraints) and len(lin.coordinates) == model.n
    assert len(lin.eigenvalues) == len(lin.coordinates) + len(lin.velocities)
    assert all(math.isfinite(e.real) and math.isfinite(e.imag) for e in lin.eigenvalues)
    zero = sum(1 for e in lin.eigenvalues if abs(e) < 1e-9)
    assert zero >= rows and "manifold of equilibria" in lin.note
    assert "unstable" not in lin.stability and "unknown" not in lin.stability


def test_knife_edge_on_an_incline_rests_across_the_slope() -> None:
    """Resting needs the blade across the slope (phi = +-pi/2), the plane's sideways force
    lambda = +-m g sin(alpha) holding it; a blade along the slope slides."""
    model = system("knife_edge_incline")
    found = analysis.equilibria(model)
    phi = model.q[2]
    assert sorted(p[phi] for p in found) == [sp.pi / 2, 3 * sp.pi / 2]
    lin = analysis.linearize(model, point(model, phi="pi/2"))
    (lam,) = lin.multipliers.values()
    assert str(lam) == "g*m*sin(alpha)"
    with pytest.raises(DerivationError, match="not an equilibrium"):
        analysis.linearize(model, point(model))


def test_chaplygin_sleigh_state_matrix_is_finite_and_drifts() -> None:
    result = runner.invoke(app, ["linearize", "chaplygin_sleigh", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["velocities"] and data["state_matrix"] and len(data["eigenvalues"]) == len(data["state_matrix"])
    assert "zero eigenvalue" in data["note"]


def test_points_off_the_constraint_surface_and_moving_constraints_are_refused(tmp_path: Path) -> None:
    write(tmp_path, "pendulum", CARTESIAN_PENDULUM)
    result = runner.invoke(app, ["linearize", str(tmp_path / "pendulum.yaml"), "--about", "x=0,y=-1"])
    assert result.exit_code == 2 and "is not on the constraint surface: rod leaves" in result.stderr
    result = runner.invoke(app, ["equilibria", str(ROOT / "tests" / "matrix" / "time_dependent_constraints.yaml")])
    assert result.exit_code == 2 and "depends explicitly on time" in result.stderr


def test_info_gives_the_hamiltonian_and_says_how_the_constraints_enter(tmp_path: Path) -> None:
    write(tmp_path, "pendulum", CARTESIAN_PENDULUM)
    data = json.loads(runner.invoke(app, ["info", str(tmp_path / "pendulum.yaml"), "--json"]).stdout)
    assert data["hamiltonian"] and "rod" in data["hamiltonian_note"] and "lambda" in data["hamiltonian_note"]
    assert data["degrees_of_freedom"] == 1
    text = runner.invoke(app, ["info", "rolling_coin"]).stdout  # four coordinates, a diagonal mass matrix
    assert "Hamiltonian H(q, p) =" in text and "note: H is the Legendre transform of the Lagrangian without its kept constraints" in text
    assert "eliminate them first" not in text


POTENTIAL = """title: Radial oscillator
coordinates: [r, theta]
parameters: {m: 2.0, k: 3.0, c: 1.5}
functions:
  U: {arguments: [s], definition: k*(s - c)**2/2}
particles:
  p: {mass: m, position: [r*cos(theta), r*sin(theta)]}
potential: U(r)
"""


def test_linearize_through_a_defined_function(tmp_path: Path) -> None:
    """Derivative(U(r), r) at r = c: evaluated through the definition, not xreplace'd into a
    derivative with respect to a number (which raised `Can't calculate derivative wrt 1.5`)."""
    model = write(tmp_path, "radial", POTENTIAL)
    lin = analysis.linearize(model, {model.q[0]: sp.Rational(3, 2), model.q[1]: 0})
    assert max(lin.frequencies) == pytest.approx(math.sqrt(3.0 / 2.0), rel=1e-12)
    (rest,) = [p for p in analysis.equilibria(model)]
    assert float(rest[model.q[0]].subs({sp.Symbol("c"): 1.5})) == pytest.approx(1.5)


def test_an_undefined_function_is_kept_or_refused_with_a_documented_message(tmp_path: Path) -> None:
    model = write(tmp_path, "general", POTENTIAL.replace("functions:\n  U: {arguments: [s], definition: k*(s - c)**2/2}", "functions: [U]"))
    with pytest.raises(DerivationError, match="linearize needs every function defined, but U is left undefined"):
        analysis.linearize(model, {model.q[0]: 1, model.q[1]: 0})
    assert analysis.at(sp.Derivative(sp.Function("U")(model.q[0]), model.q[0]), {model.q[0]: 1}).has(sp.Subs)


def test_solve_and_simplify_are_bounded_by_size_not_time(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Beyond the size bounds sympy's solve and simplify are not called (the search is numeric,
    the tidying linear), so the answer never depends on the machine's load."""
    assert not hasattr(analysis, "time_limit")
    big = sum(sp.Symbol(f"a{i}") * sp.cos(i * sp.Symbol("x")) for i in range(1, 60))

    def refuse(*args: object, **kwargs: object) -> object:
        raise AssertionError("called beyond the size bound")

    monkeypatch.setattr(sp, "simplify", refuse)
    assert analysis.simplified(big) == sp.factor_terms(big)
    monkeypatch.setattr(sp, "solve", refuse)
    terms = " + ".join(f"{i}*cos({i}*x)/{i + 1}" for i in range(1, 30))
    model = write(tmp_path, "long", f"coordinates: [x]\nparameters: {{m: 1.0}}\nkinetic: m*x_dot**2/2\npotential: {terms} + x**2\n")
    assert sum(sp.count_ops(f) for f in model.forcing) > analysis.SOLVE_MAX_OPS
    found = analysis.equilibria(model, {model.q[0]: (-1.0, 1.0)})
    assert found and all(abs(float(model.forcing[0].subs({model.q[0]: p[model.q[0]], model.qd[0]: 0}))) < 1e-8 for p in found)


def test_holonomic_and_velocity_constraints_together(tmp_path: Path) -> None:
    """A knife edge with a redundant coordinate s held to phi by a kept holonomic constraint
    linearizes like the knife edge itself: the coordinates reduce to x, y and one of s, phi."""
    model = write(
        tmp_path,
        "mixed",
        """title: Knife edge with a copy of its angle
coordinates: [x, y, phi, s]
parameters: {m: 1.0, I: 0.1, J: 0.05, k: 2.0}
bodies:
  blade: {mass: m, position: [x, y], inertia: I, angular_velocity: phi_dot}
kinetic: J*s_dot**2/2
potential: k*s**2/2
constraints:
  copy: s = phi
  knife: x_dot*sin(phi) = y_dot*cos(phi)
""",
    )
    lin = analysis.linearize(model, point(model))
    assert len(lin.coordinates) == 3 and len(lin.velocities) == 2 and len(lin.eigenvalues) == 5
    # the angle oscillates with k / (I + J), the rest is the knife edge's zero modes
    frequencies = sorted(abs(e.imag) for e in lin.eigenvalues)
    assert frequencies[-1] == pytest.approx(math.sqrt(2.0 / 0.15), rel=1e-10)
    assert sum(1 for e in lin.eigenvalues if abs(e) < 1e-9) == 3


def test_a_manifold_of_equilibria_is_named() -> None:
    result = runner.invoke(app, ["equilibria", "rolling_coin"])
    assert result.exit_code == 0 and "(a manifold of equilibria: phi_0, theta_0, x_0, y_0 may take any value)" in result.stdout
    data = json.loads(runner.invoke(app, ["equilibria", "rolling_coin", "--json"]).stdout)
    assert sorted(data["equilibria"][0]["free"]) == ["phi", "theta", "x", "y"]


def test_a_velocity_constraint_that_forbids_rest_is_refused(tmp_path: Path) -> None:
    """x_dot = v (v a nonzero constant) cannot hold at rest: no equilibria, said so (exit 2)."""
    write(
        tmp_path,
        "conveyor",
        """title: Block carried at a steady speed
coordinates: [x, y]
parameters: {m: 1.0, v: 2.0, k: 1.0}
particles:
  block: {mass: m, position: [x, y]}
potential: k*y**2/2
constraints:
  belt: x_dot = v
""",
    )
    for command in ("equilibria", "linearize"):
        result = runner.invoke(app, [command, str(tmp_path / "conveyor.yaml")])
        assert result.exit_code == 2 and "the velocity constraint 'belt' does not allow rest" in result.stderr, result.output
