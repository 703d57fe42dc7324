"""Noether charges: declared `symmetries` are checked (invariance up to dG/dt, no work by forces or
constraints), their charges derived; `info` searches translations, rotations and the time shift;
`check` verifies `expect: conserved:` expressions and symmetry names along the motion."""

from __future__ import annotations

import json

import pytest
import sympy as sp
import yaml
from typer.testing import CliRunner

from lagrange_cli import api, check, derive, noether, spec
from lagrange_cli.cli import app
from lagrange_cli.errors import SpecError

from .conftest import ROOT

CENTRAL = """
coordinates: [x, y]
parameters: {m: 1.0, k: 1.0}
functions:
  U: {arguments: [s], definition: -k/s}
particles:
  p: {mass: m, position: [x, y]}
potential: U(sqrt(x**2 + y**2))
"""

m, g, x, y, z, t = sp.symbols("m g x y z t")
x_dot, y_dot, z_dot = sp.symbols("x_dot y_dot z_dot")


def load(text: str, filename: str = "sym.yaml") -> tuple[spec.SystemSpec, derive.Model]:
    parsed = spec.parse(text, filename)
    return parsed, derive.derive(parsed)


def with_keys(system: str, **keys: object) -> str:
    return system + yaml.safe_dump(keys, width=1000, sort_keys=False)


def test_rotation_of_a_central_force_gives_the_angular_momentum() -> None:
    parsed, model = load(with_keys(CENTRAL, symmetries={"rot": {"coordinates": {"x": "-y", "y": "x"}}}))
    (charge,) = noether.declared(parsed, model)
    assert sp.expand(charge.charge - m * (x * y_dot - y * x_dot)) == 0 and charge.gauge == 0


def test_time_shift_gives_minus_the_energy() -> None:
    parsed, model = load(with_keys(CENTRAL, symmetries={"shift": {"time": 1}}))
    (charge,) = noether.declared(parsed, model)
    assert sp.expand(charge.charge + model.energy) == 0


def test_a_galilean_boost_needs_a_polynomial_gauge_term() -> None:
    """A free particle under a boost x -> x + eps t: delta L = m x_dot = d(m x)/dt, so G = m x and the
    charge m x_dot t - m x (the centre of mass moves uniformly)."""
    system = "coordinates: [x]\nparameters: {m: 1.0}\nparticles:\n  p: {mass: m, position: [x]}\n"
    parsed, model = load(with_keys(system, symmetries={"boost": {"coordinates": {"x": "t"}}}))
    (charge,) = noether.declared(parsed, model)
    assert sp.expand(charge.gauge - m * x) == 0
    assert sp.expand(charge.charge - (m * x_dot * t - m * x)) == 0


def test_translation_in_uniform_gravity_has_the_gauge_term_minus_m_g_t() -> None:
    system = "coordinates: [x, z]\nparameters: {m: 1.0, g: 9.81}\ngravity: [0, -g]\nparticles:\n  p: {mass: m, position: [x, z]}\n"
    parsed, model = load(with_keys(system, symmetries={"up": {"coordinates": {"z": 1}}}))
    (charge,) = noether.declared(parsed, model)
    assert sp.expand(charge.gauge + m * g * t) == 0
    assert sp.expand(charge.charge - (m * z_dot + m * g * t)) == 0


def test_a_symmetry_that_is_not_one_names_the_change_left() -> None:
    text = with_keys(
        "coordinates: [x, y]\nparameters: {m: 1.0, k: 2.0}\nparticles:\n  p: {mass: m, position: [x, y]}\npotential: k*(x**2 + 2*y**2)/2\n", symmetries={"rot": {"coordinates": {"x": "-y", "y": "x"}}}
    )
    parsed, model = load(text)
    with pytest.raises(SpecError) as error:
        noether.declared(parsed, model)
    shown = str(error.value)
    assert "sym.yaml:7:3" in shown and "'rot' is not a symmetry" in shown and "-k*x*y" in shown


def test_dissipation_spoils_a_symmetry_of_l() -> None:
    text = with_keys("coordinates: [x]\nparameters: {m: 1.0, c: 0.5}\nparticles:\n  p: {mass: m, position: [x], damping: c}\n", symmetries={"shift": {"coordinates": {"x": 1}}})
    parsed, model = load(text)
    with pytest.raises(SpecError, match="do work along it"):
        noether.declared(parsed, model)


def test_a_kept_constraint_must_be_preserved() -> None:
    base = "coordinates: [x, y]\nparameters: {m: 1.0, l: 1.0}\nparticles:\n  p: {mass: m, position: [x, y]}\n"
    ring = with_keys(base, constraints={"ring": "x**2 + y**2 = l**2"}, symmetries={"rot": {"coordinates": {"x": "-y", "y": "x"}}})
    parsed, model = load(ring)
    (charge,) = noether.declared(parsed, model)
    assert sp.expand(charge.charge - m * (x * y_dot - y * x_dot)) == 0
    line = with_keys(base, constraints={"line": "y = 1"}, symmetries={"rot": {"coordinates": {"x": "-y", "y": "x"}}})
    parsed, model = load(line)
    with pytest.raises(SpecError, match="does not preserve the constraint 'line'"):
        noether.declared(parsed, model)


def test_the_search_finds_rotations_and_translations_of_cartesian_particles() -> None:
    text = "coordinates: [x1, y1, x2, y2]\nparameters: {m: 1.0, k: 1.0}\nparticles:\n  a: {mass: m, position: [x1, y1]}\n  b: {mass: m, position: [x2, y2]}\npotential: k*((x1 - x2)**2 + (y1 - y2)**2)/2\n"
    parsed, model = load(text)
    found = {c.name: c.charge for c in noether.search(parsed, model)}
    assert set(found) == {"translation_x", "translation_y", "rotation_z", "time_translation"}
    x1, y1, x2, y2, x1d, y1d, x2d, y2d = sp.symbols("x1 y1 x2 y2 x1_dot y1_dot x2_dot y2_dot")
    assert sp.expand(found["rotation_z"] - m * (x1 * y1d - y1 * x1d + x2 * y2d - y2 * x2d)) == 0
    assert sp.expand(found["translation_x"] - m * (x1d + x2d)) == 0


def test_the_search_in_polar_coordinates_tries_only_the_time_shift() -> None:
    parsed, model = load((ROOT / "systems" / "kepler.yaml").read_text())
    assert [c.name for c in noether.search(parsed, model)] == ["time_translation"]


def test_the_search_skips_what_is_not_a_symmetry() -> None:
    text = "coordinates: [x, y, z]\nparameters: {m: 1.0, g: 9.81}\ngravity: [0, 0, -g]\nparticles:\n  p: {mass: m, position: [x, y, z]}\n"
    parsed, model = load(text)
    names = {c.name for c in noether.search(parsed, model)}
    assert names == {"translation_x", "translation_y", "translation_z", "rotation_z", "time_translation"}  # z: G = -m g t


def verdicts(system: str, **keys: object) -> list[check.Result]:
    parsed, model = load(with_keys(system, **keys))
    return check.check(parsed, model)


def test_check_accepts_conserved_expressions_and_symmetry_names() -> None:
    results = verdicts(CENTRAL, symmetries={"rot": {"coordinates": {"x": "-y", "y": "x"}}}, expect={"conserved": ["rot", "m*(x*y_dot - y*x_dot)", "(x*y_dot - y*x_dot)**2", "energy"]})
    assert [r.passed for r in results] == [True, True, True, True], results


@pytest.mark.parametrize("wrong", ["m*(x*y_dot + y*x_dot)", "m*x_dot", "x*y_dot"])
def test_check_rejects_quantities_that_change(wrong: str) -> None:
    (result,) = verdicts(CENTRAL, expect={"conserved": [wrong]})
    assert not result.passed and "not constant along the motion" in result.detail


def test_check_refuses_a_declared_symmetry_that_is_not_one() -> None:
    with pytest.raises(SpecError, match="'shift' is not a symmetry"):
        verdicts(CENTRAL, symmetries={"shift": {"coordinates": {"x": 1}}}, expect={"conserved": ["energy"]})


def test_conserved_on_a_constrained_system_uses_the_constrained_motion() -> None:
    """A bead on a ring (kept constraint): its angular momentum is conserved on the motion, which
    only the constraint makes true (x*y_dot - y*x_dot is not constant for a free particle in gravity)."""
    base = "coordinates: [x, y]\nparameters: {m: 1.0, l: 1.0}\nparticles:\n  p: {mass: m, position: [x, y]}\nconstraints:\n  ring: x**2 + y**2 = l**2\n"
    assert all(r.passed for r in verdicts(base, expect={"conserved": ["m*(x*y_dot - y*x_dot)"]}))


BAD = [
    ({"rot": {"coordinates": {"w": "-y"}}}, "'w' in symmetry 'rot' is not a coordinate"),
    ({"rot": {"coordinates": ["x", "y"]}}, "'symmetries.rot.coordinates' must be a map"),
    ({"rot": {"time": [1]}}, "the change of time in symmetry 'rot' must be an expression"),
    ({"rot": {"coordinates": {"x": "x_dot"}}}, "is a velocity, which cannot appear here"),
    ({"rot": {"coord": {"x": 1}}}, "unknown key 'coord'"),
    ({"rot": 3}, "symmetry 'rot' must be a map"),
    ({"x": {"time": 1}}, "'x' is already declared"),
    ({"rot": {}}, "symmetry 'rot' changes nothing"),
]


@pytest.mark.parametrize(("symmetries", "message"), BAD)
def test_bad_symmetries_are_errors_at_their_place(symmetries: object, message: str) -> None:
    with pytest.raises(SpecError, match=message) as error:
        spec.parse(with_keys(CENTRAL, symmetries=symmetries), "sym.yaml")
    assert "sym.yaml:" in str(error.value)


def test_info_prints_declared_and_found_charges() -> None:
    runner = CliRunner()
    path = ROOT / "systems" / "central_force_cartesian.yaml"
    out = runner.invoke(app, ["info", str(path)]).stdout
    assert "rotation_z: delta x = -y, delta y = x; conserved charge m*(x*y_dot - x_dot*y)" in out
    assert "rotation_y: delta x = z, delta z = -x" in out
    data = json.loads(runner.invoke(app, ["info", str(path), "--json"]).stdout)
    assert {s["name"] for s in data["symmetries"]} == {"rotation_z", "rotation_x", "time_shift"}
    assert "translation_x" not in {s["name"] for s in data["symmetries_found"]}
    assert "C_{1} &= m" in runner.invoke(app, ["info", str(path), "--latex"]).stdout


def test_the_bundled_central_force_system_passes_check() -> None:
    result = CliRunner().invoke(app, ["check", str(ROOT / "systems" / "central_force_cartesian.yaml")])
    assert result.exit_code == 0 and "1 passed" in result.stdout


def test_api_noether() -> None:
    system = api.load(str(ROOT / "systems" / "central_force_cartesian.yaml"))
    charges = system.noether()
    assert sp.expand(charges["rotation_z"] - m * (x * y_dot - y * x_dot)) == 0
    assert "rotation_y" in system.noether(search=True)


@pytest.mark.parametrize("simplify_ops", [noether.SIMPLIFY_OPS, 0])
def test_a_symmetry_hidden_behind_trigonometry_is_recognized(simplify_ops: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """A free particle in polar coordinates, translated along x: delta r = cos(theta),
    delta theta = -sin(theta)/r. delta L vanishes only through sin**2 + cos**2 = 1: decided by
    simplifying, and (with simplification off, as for a large expression) by the numeric zero
    test; the charge is m*x_dot in polar form."""
    monkeypatch.setattr(noether, "SIMPLIFY_OPS", simplify_ops)
    system = "coordinates: [r, theta]\nparameters: {m: 1.0}\nparticles:\n  p: {mass: m, position: [r*cos(theta), r*sin(theta)]}\n"
    parsed, model = load(with_keys(system, symmetries={"slide": {"coordinates": {"r": "cos(theta)", "theta": "-sin(theta)/r"}}}))
    (charge,) = noether.declared(parsed, model)
    r, theta, r_dot, theta_dot = sp.symbols("r theta r_dot theta_dot")
    assert sp.simplify(charge.charge - m * (r_dot * sp.cos(theta) - r * theta_dot * sp.sin(theta))) == 0


def test_the_numeric_zero_test_tells_zero_from_small() -> None:
    a, b = sp.symbols("a b")
    assert noether._numerically_zero(sp.expand((sp.sin(a) ** 2 + sp.cos(a) ** 2 - 1) * (a + b) ** 6))
    assert not noether._numerically_zero(sp.expand((sp.sin(a) ** 2 + sp.cos(a) ** 2 - 1 + sp.Rational(1, 10**12)) * (a + b) ** 6))


def test_scaling_symmetry_of_an_inverse_square_potential() -> None:
    """V = k/x**2 is invariant under x -> (1 + eps) x, t -> (1 + 2 eps) t: the charge m*x*x_dot - 2*t*h."""
    system = "coordinates: [x]\nparameters: {m: 1.0, k: 1.0}\nparticles:\n  p: {mass: m, position: [x]}\npotential: k/x**2\n"
    parsed, model = load(with_keys(system, symmetries={"dilation": {"coordinates": {"x": "x"}, "time": "2*t"}}))
    (charge,) = noether.declared(parsed, model)
    assert sp.expand(charge.charge - (m * x * x_dot - 2 * t * model.energy)) == 0
    assert all(r.passed for r in verdicts(system, symmetries={"dilation": {"coordinates": {"x": "x"}, "time": "2*t"}}, expect={"conserved": ["dilation"]}))


def test_energy_cannot_name_a_symmetry() -> None:
    with pytest.raises(SpecError, match="'energy' cannot name a symmetry"):
        spec.parse(with_keys(CENTRAL, symmetries={"energy": {"time": 1}}), "sym.yaml")


ELIMINATED = """
coordinates: [x, y, theta]
parameters: {m: 1.0, l: 1.0}
particles:
  p: {mass: m, position: [x, y]}
constraints:
  cx: x = l*cos(theta)
  cy: y = l*sin(theta)
eliminate: [x, y]
"""


def test_conserved_expressions_in_eliminated_coordinates_are_written_in_the_rest() -> None:
    results = verdicts(ELIMINATED, symmetries={"turn": {"coordinates": {"theta": 1}}}, expect={"conserved": ["turn", "m*(x*y_dot - y*x_dot)", "m*x_dot"]})
    assert [r.passed for r in results] == [True, True, False]
    assert results[2].entry == "conserved.m*x_dot" and "not constant along the motion" in results[2].detail


def test_a_symmetry_may_not_move_an_eliminated_coordinate() -> None:
    parsed, model = load(with_keys(ELIMINATED, symmetries={"rot": {"coordinates": {"x": "-y", "y": "x"}}}))
    with pytest.raises(SpecError, match="moves 'x', which is eliminated"):
        noether.declared(parsed, model)


def test_an_empty_symmetry_is_reported_also_next_to_other_problems() -> None:
    text = with_keys(CENTRAL, symmetries={"rot": {"coordinates": {}}}, initial={"w": 1})
    with pytest.raises(SpecError) as error:
        spec.parse(text, "sym.yaml")
    assert "symmetry 'rot' changes nothing" in str(error.value) and "'w'" in str(error.value)


def test_the_search_takes_constant_components_and_other_coordinates() -> None:
    """A particle at [x, y, h] on a spring to the z axis, with a flywheel angle in `kinetic`: the
    z translation is not tried (no coordinate along z), the rotation about z holds, and so does
    the translation along x only if nothing pulls (here it does not hold)."""
    text = "coordinates: [x, y, phi]\nparameters: {m: 1.0, h: 1.0, k: 1.0, J: 1.0}\nparticles:\n  p: {mass: m, position: [x, y, h]}\nkinetic: J*phi_dot**2/2\npotential: k*(x**2 + y**2)/2\n"
    parsed, model = load(text)
    assert [c.name for c in noether.search(parsed, model)] == ["rotation_z", "time_translation"]
    assert [name for name, _, _ in noether.candidates(parsed, model)] == ["translation_x", "translation_y", "rotation_z", "time_translation"]


def test_the_two_body_problem_has_its_ten_classical_integrals() -> None:
    """Two gravitating particles in space: the search finds the three translations (momentum),
    the three rotations (angular momentum) and the time shift (energy); with `boost_x` declared
    (delta x_i = t, G = sum m_i x_i) the centre of mass's uniform motion is conserved too."""
    coordinates = [f"{a}{i}" for i in range(2) for a in "xyz"]
    particles = "\n".join(f"  p{i}: {{mass: m{i}, position: [x{i}, y{i}, z{i}]}}" for i in range(2))
    potential = " + ".join(f"-m{i}*m{j}/sqrt((x{i} - x{j})**2 + (y{i} - y{j})**2 + (z{i} - z{j})**2)" for i in range(2) for j in range(i + 1, 2))
    text = f"coordinates: [{', '.join(coordinates)}]\nparameters: {{m0: 1.0, m1: 2.0}}\nparticles:\n{particles}\npotential: {potential}\n"
    parsed, model = load(with_keys(text, symmetries={"boost_x": {"coordinates": {f"x{i}": "t" for i in range(2)}}}))
    assert [c.name for c in noether.search(parsed, model)] == ["translation_x", "translation_y", "translation_z", "rotation_x", "rotation_y", "rotation_z", "time_translation"]
    (boost,) = noether.declared(parsed, model)
    masses, xs, vs = sp.symbols("m0 m1"), sp.symbols("x0 x1"), sp.symbols("x0_dot x1_dot")
    assert sp.expand(boost.charge - sum(mi * (t * vi - xi) for mi, xi, vi in zip(masses, xs, vs, strict=True))) == 0
