"""Constraint forces by name (lagrange_cli/forces.py): the force and torque each kept constraint
exerts on each particle and body, with the sign convention of docs/format.md, in the text and
LaTeX solved forms, the generated Python's `constraint_forces(t, y, p)` and the API.

The physical answers are written here by hand: a pendulum string's tension m g cos(theta) +
m l theta_dot^2, the Chaplygin sleigh's sideways blade force and its torque about the centre
of mass (the force acts at the contact point, a behind it)."""

from __future__ import annotations

import math
import random
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lagrange_cli import forces as cf
from lagrange_cli.api import from_text, load
from lagrange_cli.cli import app
from lagrange_cli.emit import python as pyemit

from .conftest import ROOT
from .helpers import load_module, model_from, model_of

runner = CliRunner()
pytestmark = pytest.mark.usefixtures("private_cache")

MULTIPLIER_SYSTEMS = ("pendulum_multiplier", "chaplygin_sleigh", "knife_edge_incline", "rolling_coin", "atwood_machine_multiplier", "rolling_disk_pendulum_multiplier")


def module(name: str, tmp_path: Path):  # type: ignore[no-untyped-def]
    model = model_from(ROOT / "systems" / f"{name}.yaml")
    return model, load_module(pyemit.emit(model), tmp_path / f"{name}_forces.py")


def test_the_pendulum_string_tension(tmp_path: Path) -> None:
    """x^2 + y^2 = l^2: the gradient points outward, a taut string pulls inward, so N < 0 and the
    tension -N is m g cos(theta) + m l theta_dot^2; the force is lambda * (2x, 2y)."""
    _, mod = module("pendulum_multiplier", tmp_path)
    p = mod.PARAMETERS
    m, length, g = p["m"], p["l"], p["g"]
    for theta, w in ((0.0, 0.0), (0.4, 1.3), (-1.1, -0.7), (2.5, 3.0)):
        y = [length * math.sin(theta), -length * math.cos(theta), length * math.cos(theta) * w, length * math.sin(theta) * w]
        out = mod.constraint_forces(0.0, y)
        rod = out["rod"]
        bob = rod["on"]["bob"]
        tension = m * g * math.cos(theta) + m * length * w * w
        assert -bob["N"] == pytest.approx(tension, rel=1e-12, abs=1e-12)
        assert bob["force"] == pytest.approx([-tension * math.sin(theta), tension * math.cos(theta)], abs=1e-12)
        assert rod["lambda"] == pytest.approx(-tension / (2 * length))
        assert rod["generalized"] == pytest.approx(bob["force"])  # Cartesian coordinates: the same numbers


def test_the_sleigh_blade_force_and_its_torque(tmp_path: Path) -> None:
    """The blade's sideways force lambda (-sin(phi), cos(phi)) acts at the contact point, a behind
    the centre of mass along the blade: its torque about the centre is -a lambda, and lambda is
    Chaplygin's m I v omega / (I + m a^2)."""
    model, mod = module("chaplygin_sleigh", tmp_path)
    m, inertia, a = (mod.PARAMETERS[k] for k in ("m", "I", "a"))
    assert cf.forces(model).status == "exact"
    rng = random.Random(5)
    for _ in range(4):
        phi, v, w = rng.uniform(-3, 3), rng.uniform(-1, 1), rng.uniform(-2, 2)
        y = [rng.uniform(-1, 1), rng.uniform(-1, 1), phi, v * math.cos(phi), v * math.sin(phi), w]
        out = mod.constraint_forces(0.0, y)["blade"]
        lam = m * inertia * v * w / (inertia + m * a * a)
        assert out["lambda"] == pytest.approx(lam, abs=1e-12)
        sleigh = out["on"]["sleigh"]
        assert sleigh["force"] == pytest.approx([-lam * math.sin(phi), lam * math.cos(phi)], abs=1e-12)
        contact = [-a * math.cos(phi), -a * math.sin(phi)]  # from the centre of mass
        torque = contact[0] * sleigh["force"][1] - contact[1] * sleigh["force"][0]
        assert sleigh["torque"] == pytest.approx([torque], abs=1e-12)
        assert sleigh["N"] == pytest.approx(lam, abs=1e-12)


@pytest.mark.parametrize("name", MULTIPLIER_SYSTEMS)
def test_the_forces_do_the_virtual_work_of_the_generalized_force(name: str, tmp_path: Path) -> None:
    """J^T [forces; torques] = A^T lambda at random states, for every bundled system with kept
    constraints (exact or minimum-norm alike), with J computed here from the file's positions."""
    model, mod = module(name, tmp_path)
    import sympy as sp

    fm = cf.forces(model)
    assert fm.rows
    values = {p.symbol: p.value for p in model.parameters}
    rng = random.Random(11)
    for _ in range(3):
        y = [rng.uniform(-0.8, 0.8) for _ in range(2 * model.n)]
        state = dict(zip((*model.q, *model.qd), y, strict=True))
        out = mod.constraint_forces(0.0, y)
        for c in model.constraints:
            entry = out[c.name]
            total = np.zeros(model.n)
            for row in fm.rows:
                component = entry["on"].get(row.carrier, {}).get(row.kind, None)
                if component is None:
                    continue
                jac = np.array([float(sp.sympify(e).xreplace({**values, **state, model.t: 0.0})) for e in row.entries])
                total += component[row.index] * jac
            generalized = np.array(entry["generalized"], dtype=float)
            assert np.allclose(generalized, [entry["lambda"] * float(sp.sympify(a).xreplace({**values, **state, model.t: 0.0})) for a in c.jacobian], atol=1e-12)
            assert np.allclose(total, generalized, atol=1e-9), (c.name, total, generalized)


CHAIN = """
title: two-link chain in Cartesian coordinates, a bead on a rail
coordinates: [x1, y1, x2, y2, s]
parameters: {m: 1.0, l: 1.0, g: 9.81}
gravity: [0, -g]
particles:
  a: {mass: m, position: [x1, y1]}
  b: {mass: m, position: [x2, y2]}
  bead: {mass: m, position: [s, 0]}
constraints:
  rod1: x1**2 + y1**2 = l**2
  rod2: (x2 - x1)**2 + (y2 - y1)**2 = l**2
"""


def test_the_generated_code_agrees_with_the_symbolic_directions(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Five coordinates: the generated code solves J^T W = a numerically (numpy lstsq); the
    symbolic W (with the symbolic limit raised) times the module's lambda gives the same forces."""
    import sympy as sp

    model = model_of(CHAIN)
    assert model.n > cf.MAX_SYMBOLIC and cf.forces(model).directions is None
    mod = load_module(pyemit.emit(model), tmp_path / "chain.py")
    monkeypatch.setattr(cf, "MAX_SYMBOLIC", 6)
    fm = cf.forces(model)
    assert fm.status == "exact" and fm.directions is not None
    y = [0.6, -0.8, 1.2, -1.6, 0.3, 0.5, 0.375, 0.1, 0.2, -0.4]
    point = {**dict(zip((*model.q, *model.qd), y, strict=True)), **{p.symbol: p.value for p in model.parameters}}
    out = mod.constraint_forces(0.0, y)
    assert set(out) == {"rod1", "rod2"}
    for k, c in enumerate(model.constraints):
        lam = out[c.name]["lambda"]
        expected = {key: [lam * float(sp.sympify(w).xreplace(point)) for w in ws] for key, ws in fm.on(k, keep_zero=True).items()}
        got = {(carrier, kind): values for carrier, entry in out[c.name]["on"].items() for kind, values in entry.items() if kind != "N"}
        assert set(got) == set(expected)
        for key in expected:
            assert got[key] == pytest.approx(expected[key], abs=1e-9)
    # rod2 pulls a and b with equal and opposite forces; rod1 acts on a only (every particle is listed, 0 where nothing acts)
    assert out["rod2"]["on"]["a"]["force"] == pytest.approx([-f for f in out["rod2"]["on"]["b"]["force"]])
    assert out["rod1"]["on"]["b"]["force"] == pytest.approx([0, 0]) and out["rod1"]["on"]["bead"]["N"] == 0
    assert out["rod1"]["on"]["a"]["N"] == pytest.approx(2 * out["rod1"]["lambda"] * math.hypot(0.6, -0.8))


def test_text_and_latex_solved_forms_state_the_forces_and_the_convention() -> None:
    result = runner.invoke(app, ["derive", "pendulum_multiplier", "--form", "solved"])
    assert result.exit_code == 0, result.output
    assert "rod on bob: force = [2*lambda_rod*x, 2*lambda_rod*y], N = 2*lambda_rod*sqrt(x**2 + y**2)" in result.stdout
    assert "positive along the gradient of lhs - rhs" in result.stdout
    result = runner.invoke(app, ["derive", "pendulum_multiplier", "--form", "solved", "--latex"])
    assert result.exit_code == 0, result.output
    assert "F_{\\text{rod}\\to\\text{bob},1} &= 2 \\lambda_{\\mathrm{rod}} x" in result.stdout
    assert "positive along the gradient" in result.stdout.splitlines()[1]


UNDERSCORES = """
title: names with underscores
coordinates: [x, y]
parameters: {m: 1.0, l: 1.0, g: 9.81}
gravity: [0, -g]
particles:
  bob_1: {mass: m, position: [x, y]}
constraints:
  first_rod: x**2 + y**2 = l**2
"""


def test_names_with_underscores_are_escaped_in_latex() -> None:
    tex = from_text(UNDERSCORES).to("latex", form="solved")
    assert "\\text{first\\_rod}\\to\\text{bob\\_1}" in tex


def test_the_api_gives_the_force_map() -> None:
    system = load("pendulum_multiplier")
    fm = system.constraint_forces
    assert fm.status == "exact"
    (key, components), *_ = fm.on(0).items()
    assert key == ("bob", "force") and [str(c) for c in components] == ["2*x", "2*y"]
