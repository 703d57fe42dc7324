"""Dimensional checking (`units`): unit strings, bad input at its place, the bundled systems'
units, and dimensional mistakes introduced into bundled files, each caught with the term named."""

from __future__ import annotations

from pathlib import Path

import pytest

from lagrange_cli import check, derive, spec
from lagrange_cli.errors import SpecError
from lagrange_cli.units import ENERGY, SCALE, UnitError, parse_unit, show

from .conftest import ROOT

SYSTEMS = sorted((ROOT / "systems").glob("*.yaml"))


def _d(kg: int = 0, m: int = 0, s: int = 0) -> tuple[int, ...]:
    return tuple(SCALE * x for x in (kg, m, s, 0, 0, 0, 0))


@pytest.mark.parametrize(
    ("text", "dim"),
    [
        ("kg", _d(kg=1)),
        ("m/s**2", _d(m=1, s=-2)),
        ("N*m", ENERGY),
        ("J", ENERGY),
        ("kg*m^2/s^2", ENERGY),
        ("rad", _d()),
        ("1", _d()),
        ("1/s", _d(s=-1)),
        ("rad/s", _d(s=-1)),
        ("(kg*m)/(s*s)", _d(kg=1, m=1, s=-2)),
        ("m**(1/2)", (0, SCALE // 2, 0, 0, 0, 0, 0)),
    ],
)
def test_unit_strings(text: str, dim: tuple[int, ...]) -> None:
    assert parse_unit(text) == dim


@pytest.mark.parametrize("text", ["cm", "g", "foo", "m/", "2*m", "m**x", "__import__('os')", "m.real", "m**1000", "[m]", "m**(1/17)"])
def test_bad_unit_strings(text: str) -> None:
    with pytest.raises(UnitError):
        parse_unit(text)


def test_show() -> None:
    assert show(ENERGY) == "kg*m^2/s^2"
    assert show(_d(s=-1)) == "1/s"
    assert show(_d()) == "1"
    assert show(_d(kg=1, s=-2, m=-1)) == "kg/(m*s^2)"
    assert show(parse_unit("m**(1/2)/s**(2/3)")) == "m^(1/2)/s^(2/3)"


@pytest.mark.parametrize("path", SYSTEMS, ids=[p.stem for p in SYSTEMS])
def test_bundled_systems_have_consistent_units(path: Path) -> None:
    system = spec.load(path)
    assert system.units is not None, f"{path.name} has no units"
    from lagrange_cli.units import check_answer, check_file

    energy = check_file(system)
    assert energy == ENERGY
    for expr, _ in system.expect.equations:
        assert check_answer(system, expr, "equation", energy) == ""
    for q, expr, _ in system.expect.momenta:
        assert check_answer(system, expr, "momentum", energy, q) == ""
    for q, expr, _ in system.expect.accelerations:
        assert check_answer(system, expr, "acceleration", energy, q) == ""


def test_every_bundled_system_has_units() -> None:
    with_units = [p.stem for p in SYSTEMS if "\nunits:" in p.read_text()]
    assert with_units == [p.stem for p in SYSTEMS], sorted({p.stem for p in SYSTEMS} - set(with_units))


def _mutated(tmp_path: Path, name: str, old: str, new: str) -> tuple[Path, int]:
    """A bundled file with `old` replaced by `new` (once), and the line the change is on."""
    text = (ROOT / "systems" / f"{name}.yaml").read_text()
    assert text.count(old) >= 1, f"{old!r} not in {name}"
    index = text.index(old)
    path = tmp_path / f"{name}.yaml"
    path.write_text(text[:index] + new + text[index + len(old) :])
    return path, text[:index].count("\n") + 1


MUTATIONS = [
    # (file, old, new, words the message must contain)
    ("harmonic_oscillator", "potential: k*x**2/2", "potential: k*x/2", ["potential", "term `k*x/2`", "kg*m/s^2", "the others kg*m^2/s^2", "missing x?"]),
    ("simple_pendulum", "gravity: [0, -g]", "potential: -m*l*cos(theta)", ["potential", "term `-l*m*cos(theta)`", "has dimension kg*m,", "missing g?"]),
    ("kepler", "potential: -k/r", "potential: -k/r**2", ["potential", "term `-k/r**2`", "missing r?"]),
    ("rolling_disk_pendulum", "inertia: M*R**2/2", "inertia: M*R/2", ["rotational energy of body 'disk'", "`M*R*phi_dot**2/4`", "has dimension kg*m/s^2, the others kg*m^2/s^2; missing s or R or l?"]),
    ("kapitza_pendulum", "a*cos(omega*t)", "a*cos(omega*t + l)", ["the position of particle 'bob'", "term `l` of the argument of cos, `l + omega*t`, has dimension m; it must be dimensionless"]),
    (
        "elastic_pendulum",
        "position: [(l + x)*sin(theta)",
        "position: [(l + x)*sin(theta*l)",
        ["the position of particle 'bob'", "the argument of sin, `l*theta`, has dimension m; it must be dimensionless"],
    ),
    ("simple_pendulum", "g: m/s**2", "g: m/s", ["the weight of particle 'bob'", "has dimension kg*m^2/s,"]),
    ("rolling_disk_pendulum", "rolling: s = R*phi", "rolling: s = phi", ["constraint 'rolling'", "`-phi`", "has dimension 1, the other m"]),
    ("cart_pole", "u: N", "u: N*m", ["the generalized force on 'x'", "term `u`", "kg*m^2/s^2", "one x or l too many?"]),
    ("stiff_spring_pendulum_damped", "zeta*sqrt(k*m)*x_dot**2", "zeta*k*m*x_dot**2", ["dissipation", "term `k*m*x_dot**2*zeta`", "energy per s"]),
    ("central_potential", "definition: -k/s", "definition: -k/s**2", ["potential", "term `U(r)` (with 'U' as defined at line 24) has dimension kg*m/s^2", "missing r?"]),
    ("charged_particle_magnetic", "qc: C", "qc: A", ["lagrangian", "has dimension kg*m^2/s^3,"]),
    # version 2 bodies (orientation, full inertia tensors, pivot/center/points, force and torque loads) and outputs
    ("quadrotor", "[0, 0, k*(f1 - f2 + f3 - f4)]", "[0, 0, f1 - f2 + f3 - f4]", ["the torque on body 'frame'", "`[0, 0, f1 - f2 + f3 - f4]`", "has dimension kg*m/s^2, the others kg*m^2/s^2"]),
    ("arm_3dof", "tau3: N*m}", "tau3: N}", ["the torque on body 'upper'", "the torque on body 'fore'", "`[0, tau3, 0]` times an angle has dimension kg*m/s^2"]),
    ("arm_3dof", "[[m0*h**2/12, 0, 0]", "[[m0*h/12, 0, 0]", ["rotational energy of body 'base'", "inertia entry `h*m0/12`", "has dimension kg*m/s^2, the others kg*m^2/s^2; missing h"]),
    ("heavy_top_offaxis_disk", "m*r**2/4*cos(beta)**2 +", "m*r/4*cos(beta)**2 +", ["the inertia of body 'top'", "term `m*r*cos(beta)**2/4`", "has dimension kg*m, the other kg*m^2"]),
    ("heavy_top_offaxis_disk", "center: [e, 0, l]", "center: [e, 0, m]", ["centre of mass of body 'top'", "term `m*sin(phi)*sin(theta)`", "has dimension kg, the other m"]),
    ("cart_pole_state_space", "center: [l, 0]", "center: [M, 0]", ["centre of mass of body 'pole'", "term `M*sin(theta)` of `M*sin(theta) + x` has dimension kg, the other m"]),
    ("rolling_disk_3d", "rim_c: [0, 0, R]", "rim_c: [0, 0, m]", ["point 'rim_c' of body 'coin'", "has dimension kg, the others m"]),
    ("quadrotor", "altitude: z", "altitude: z + psi", ["output 'altitude'", "term `z` of `psi + z` has dimension m, the other 1"]),
    ("arm_3dof", "tip_reach: l1*cos(q2)", "tip_reach: l1*cos(q2*l1)", ["output 'tip_reach'", "the argument of cos, `l1*q2`, has dimension m"]),
    ("quadrotor", "{vector: [0, 0, f1], axes: body", "{vector: [0, 0, f1*L], axes: body", ["the force on body 'frame'", "`[0, 0, L*f1]` times a displacement has dimension kg*m^3/s^2"]),
    ("gyroscope_gimbals", "{axis: [1, 0, 0], angle: beta,", "{axis: [1, 0, 0], angle: beta*J,", ["the orientation of body 'inner'", "`J*beta`", "must be dimensionless"]),
    ("gyroscope_gimbals", "{axis: [1, 0, 0], angle: beta,", "{axis: [M_i, 0, J], angle: beta,", ["the orientation of body 'inner'", "term `M_i**2` of `J**2 + M_i**2`"]),
    ("central_force_cartesian", "rotation_z: {coordinates: {x: -y, y: x}}", "rotation_z: {coordinates: {x: -y, y: x*m}}", ["symmetry 'rotation_z'", "delta y = `m*x`", "one m too many?"]),
    ("gyroscope_gimbals", "{axis: [1, 0, 0], angle: beta,", "{axis: [M_i, 0, 0.5], angle: beta,", ["the orientation of body 'inner'", "term `M_i**2` of `M_i**2 + 0.25`"]),
]


@pytest.mark.parametrize(("name", "old", "new", "words"), MUTATIONS, ids=[f"{m[0]}:{m[2]}" for m in MUTATIONS])
def test_introduced_dimensional_errors_are_caught(tmp_path: Path, name: str, old: str, new: str, words: list[str]) -> None:
    path, line = _mutated(tmp_path, name, old, new)
    system = spec.load(path)
    with pytest.raises(SpecError) as caught:
        derive.derive(system)
    message = str(caught.value)
    for word in words:
        assert word in message, message
    first = caught.value.diagnostics[0]
    assert first.span is not None and first.span.file == str(path)
    # (a unit's error is where it is used; a definition's where it is called; a block-style inertia matrix is reported at its first row)
    if not old.startswith(("g: ", "u: ", "qc: ", "tau3: ", "gravity", "definition", "m*r**2/4")):
        assert first.span.line == line, message  # the error is at the mutated line


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ("{axis: [1, 0, 0], angle: beta,", "{axis: [0.6, 0.8, 0], angle: beta,"),  # numbers in an axis
        ("{axis: [1, 0, 0], angle: beta,", "{axis: [M_i, 0, M_i], angle: beta,"),  # an axis in kg: any one dimension
        ("pivot: [0, 0, 0]\n    inertia: [[B1", "pivot: [0, 0, 0*M_i]\n    inertia: [[B1"),  # 0 has every dimension
    ],
)
def test_v2_bodies_without_false_errors(tmp_path: Path, old: str, new: str) -> None:
    path, _ = _mutated(tmp_path, "gyroscope_gimbals", old, new)
    derive.derive(spec.load(path))


@pytest.mark.parametrize(
    "new",
    [
        "time_shift: {time: 1, coordinates: {x: 1}}",  # numbers are in whatever unit epsilon needs
        "time_shift: {time: t, coordinates: {x: x, y: y, z: z}}",  # a scaling: epsilon dimensionless in all four
    ],
)
def test_symmetries_without_false_errors(tmp_path: Path, new: str) -> None:
    path, _ = _mutated(tmp_path, "central_force_cartesian", "time_shift: {time: 1}", new)
    from lagrange_cli.units import check_file

    assert check_file(spec.load(path)) == ENERGY


def test_the_unmutated_file_passes(tmp_path: Path) -> None:
    path, _ = _mutated(tmp_path, "simple_pendulum", "gravity: [0, -g]", "gravity: [0, -g]")
    derive.derive(spec.load(path))


ANSWERS = [
    ("simple_pendulum", "- theta_ddot + g/l*sin(theta) = 0", "- theta_ddot + g*sin(theta) = 0", "equations", "equation 1 is not dimensionally consistent: term `g*sin(theta)`"),
    (
        "double_pendulum",
        "- phi_ddot + cos(theta - phi)*theta_ddot",
        "- phi_ddot + cos(theta - phi*l)*theta_ddot",
        "equations",
        "equation 2 is not dimensionally consistent: term `l*phi` of the argument of cos, `l*phi - theta`, has dimension m",
    ),
    ("simple_pendulum", "theta: m*l**2*theta_dot", "theta: m*l*theta_dot", "momenta.theta", "it has dimension kg*m/s, but the momentum of 'theta' has kg*m^2/s; missing l?"),
    (
        "rolling_coin",
        "x_ddot: -R*sin(phi)*phi_dot*theta_dot",
        "x_ddot: -sin(phi)*phi_dot*theta_dot",
        "accelerations.x_ddot",
        "it has dimension 1/s^2, but the acceleration of 'x' has m/s^2; missing x or y or R?",
    ),
]


@pytest.mark.parametrize(("name", "old", "new", "entry", "words"), ANSWERS, ids=[a[3] + ":" + a[0] for a in ANSWERS])
def test_answers_are_dimension_checked_before_comparing(tmp_path: Path, name: str, old: str, new: str, entry: str, words: str) -> None:
    path, line = _mutated(tmp_path, name, old, new)
    report = check.check_file(str(path))
    assert report.status == "fail" and check.exit_code([report]) == 1
    failed = [r for r in report.results if not r.passed]
    assert [r.entry for r in failed] == [entry]
    assert words in failed[0].detail, failed[0].detail
    assert failed[0].span is not None and failed[0].span.line == line


def test_hamiltonian_answer_dimension(tmp_path: Path) -> None:
    path = tmp_path / "h.yaml"
    path.write_text(
        "coordinates: [x]\nparameters: {m: 1.0, k: 1.0}\nunits: {x: m, m: kg, k: N/m}\nparticles: {p: {mass: m, position: [x]}}\npotential: k*x**2/2\nexpect:\n  hamiltonian: p_x**2/(2*m) + k*x\n"
    )
    report = check.check_file(str(path))
    assert report.status == "fail"
    assert "the answer is not dimensionally consistent: term `k*x` has dimension kg*m/s^2, but a Hamiltonian (an energy) has kg*m^2/s^2; missing x?" in report.results[0].detail


def test_conserved_expression_answers_are_dimension_checked(tmp_path: Path) -> None:
    """An `expect.conserved` expression is a quantity of its own dimension, but its terms must agree:
    `m*(x*y_dot - y)` (a length where a length times a speed belongs) fails with the term named,
    while the angular momentum passes."""
    path = tmp_path / "c.yaml"
    path.write_text(
        "coordinates: [x, y]\nparameters: {m: 1.0, k: 1.0}\nunits: {x: m, y: m, m: kg, k: kg*m**3/s**2}\nparticles: {p: {mass: m, position: [x, y]}}\n"
        "potential: -k/sqrt(x**2 + y**2)\nexpect:\n  conserved: [m*(x*y_dot - y*x_dot), m*(x*y_dot - y)]\n"
    )
    report = check.check_file(str(path))
    verdicts = {r.entry: r for r in report.results}
    assert verdicts["conserved.m*(x*y_dot - y*x_dot)"].passed
    wrong = verdicts["conserved.m*(x*y_dot - y)"]
    assert not wrong.passed and "not dimensionally consistent: term `x*y_dot` of `x*y_dot - y` has dimension m^2/s, the other m" in wrong.detail


BAD = [
    ("units: {x: m}\n", "'units' has no unit for 'm', 'k'", 4, 1),
    ("units: {x: m, m: kg, k: N/m, y: m}\n", "'units' gives a unit for 'y', which is not a coordinate, parameter or input", 4, 30),
    ("units: {x: m, m: kg, k: N/cm}\n", "the unit of 'k': unknown unit 'cm'", 4, 27),
    ("units: {x: m, m: g, k: N/m}\n", "unknown unit 'g' ('g' is not a coherent SI unit and the tool converts no values: use kg)", 4, 18),
    ("units: {x: m, m: kg, k: N/}\n", "the unit of 'k': 'N/' is not a unit", 4, 25),
    ("units: {x: m, m: kg, k: [N]}\n", "the unit of 'k' must be a unit, got a list", 4, 25),
    ("units: {x: m, m: kg, k: __import__('os')}\n", "the unit of 'k'", 4, 25),
    ("units: [m, kg]\n", "'units' must be a map", 4, 8),
]


@pytest.mark.parametrize(("line", "message", "row", "column"), BAD, ids=[b[1][:40] for b in BAD])
def test_bad_units_are_reported_at_their_place(tmp_path: Path, line: str, message: str, row: int, column: int) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("coordinates: [x]\nparameters: {m: 1.0, k: 1.0}\nparticles: {p: {mass: m, position: [x]}}\n" + line + "potential: k*x**2/2\n")
    with pytest.raises(SpecError) as caught:
        spec.load(path)
    found = [d for d in caught.value.diagnostics if message in d.message]
    assert found, str(caught.value)
    assert found[0].span is not None and (found[0].span.line, found[0].span.column) == (row, column), str(caught.value)
    assert f"{path}:{row}:{column}: error:" in str(caught.value)


def test_cli_exit_code_and_message(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from lagrange_cli.cli import app

    path, line = _mutated(tmp_path, "harmonic_oscillator", "potential: k*x**2/2", "potential: k*x/2")
    result = CliRunner().invoke(app, ["derive", str(path)])
    assert result.exit_code == 2
    assert f"{path}:{line}:" in result.output and "term `k*x/2`" in result.output
    assert "Traceback" not in result.output


def test_unit_names_have_their_own_namespace(tmp_path: Path) -> None:
    """A parameter `m` (a mass in kg) and the metre `m` are different things; `s` may be a coordinate."""
    path = tmp_path / "ns.yaml"
    path.write_text("coordinates: [s]\nparameters: {m: 1.0, N: 2.0}\nunits: {s: m, m: kg, N: kg/s**2}\nparticles: {p: {mass: m, position: [s]}}\npotential: N*s**2/2\n")
    system = spec.load(path)
    derive.derive(system)
    assert system.units is not None and system.units.dims["m"] == _d(kg=1)


def test_undefined_functions_and_multipliers_match_any_dimension(tmp_path: Path) -> None:
    path = tmp_path / "u.yaml"
    path.write_text("coordinates: [r]\nparameters: {m: 1.0, l: 1.0}\nfunctions: [U]\nunits: {r: m, m: kg, l: m}\nparticles: {p: {mass: m, position: [r]}}\npotential: U(r) + U(cos(r))\n")
    with pytest.raises(SpecError, match=r"the argument of cos, `r`, has dimension m"):
        derive.derive(spec.load(path))
    path.write_text(path.read_text().replace("U(cos(r))", "U(r)*r/l"))
    derive.derive(spec.load(path))


def test_without_units_nothing_is_checked(tmp_path: Path) -> None:
    path = tmp_path / "n.yaml"
    path.write_text("coordinates: [x]\nparameters: {m: 1.0, k: 1.0}\nparticles: {p: {mass: m, position: [x]}}\npotential: k*x/2\n")
    system = spec.load(path)
    assert system.units is None
    derive.derive(system)


def test_derived_equations_are_checked_term_by_term() -> None:
    """The check of the derivation itself: the model of a consistent file passes; the same model
    read with a wrong unit for g has a term of the wrong dimension in the equation of theta."""
    import dataclasses

    from lagrange_cli.units import Units, check_equations

    system = spec.load(ROOT / "systems" / "simple_pendulum.yaml")
    model = derive.derive(system)
    check_equations(system, model, ENERGY)
    assert system.units is not None
    wrong = dataclasses.replace(system, units=Units({**system.units.dims, "g": parse_unit("m/s")}))
    with pytest.raises(SpecError, match=r"the derived equation of 'theta': term `.*g.*` has dimension kg\*m\^2/s, the others kg\*m\^2/s\^2"):
        check_equations(wrong, model, ENERGY)


def test_a_tie_is_decided_for_the_si_energy(tmp_path: Path) -> None:
    """One kinetic and one potential term that disagree: the one in kg*m^2/s^2 is right, whatever the order."""
    path = tmp_path / "tie.yaml"
    path.write_text("coordinates: [x]\nparameters: {m: 1.0, k: 1.0}\nunits: {x: m, m: kg, k: N/m}\npotential: k*x**2/2\nkinetic: m*x*x_dot**2/2\n")
    with pytest.raises(SpecError) as caught:
        derive.derive(spec.load(path))
    assert len(caught.value.diagnostics) == 1
    assert "kinetic: term `m*x*x_dot**2/2` has dimension kg*m^3/s^2, the others kg*m^2/s^2; one x too many?" in str(caught.value)
