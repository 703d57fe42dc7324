"""`derive --form reduced`: Maggi's equations in the independent velocities, multipliers eliminated.

The generated module's trajectories are compared with the multiplier form's (`--python`), and its
accelerations with sympy.physics.mechanics' KanesMethod (u_dependent, velocity_constraints) built
here independently for the knife edge, the Chaplygin sleigh and the rolling coin."""

from __future__ import annotations

import math
import random
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.emit import python as pyemit
from lagrange_cli.emit import reduced as emit_reduced
from lagrange_cli.errors import LagrangeError
from lagrange_cli.reduced import choose, reduced

from .conftest import ROOT
from .helpers import load_module, model_from, model_of

runner = CliRunner()
pytestmark = pytest.mark.usefixtures("private_cache")

SYSTEMS = ("knife_edge_incline", "chaplygin_sleigh", "rolling_coin")


def modules(name: str, tmp_path: Path):  # type: ignore[no-untyped-def]
    model = model_from(ROOT / "systems" / f"{name}.yaml")
    full = load_module(pyemit.emit(model), tmp_path / f"{name}_full.py")
    red = load_module(emit_reduced.python(model), tmp_path / f"{name}_reduced.py")
    return model, full, red


@pytest.mark.parametrize("name", SYSTEMS)
def test_trajectories_agree_with_the_multiplier_form(name: str, tmp_path: Path) -> None:
    model, full, red = modules(name, tmp_path)
    n = model.n
    rng = random.Random(3)
    q0 = [rng.uniform(-0.5, 0.5) for _ in range(n)]
    u0 = [rng.uniform(-1.0, 1.0) for _ in red.INDEPENDENT]
    z0 = np.array([*q0, *u0])
    qd0 = red.velocities(0.0, z0)
    y0 = np.array([*q0, *qd0])
    assert np.allclose(full.constraint_residuals(q0, qd0), 0, atol=1e-12)
    t = np.linspace(0, 3, 31)
    a = solve_ivp(full.rhs, (0, 3), y0, method="DOP853", rtol=1e-11, atol=1e-12, t_eval=t)
    b = solve_ivp(red.rhs, (0, 3), z0, method="DOP853", rtol=1e-11, atol=1e-12, t_eval=t)
    assert a.success and b.success
    assert np.max(np.abs(a.y[:n] - b.y[:n])) < 1e-7
    velocities = np.array([red.velocities(0.0, b.y[:, i]) for i in range(len(t))]).T
    assert np.max(np.abs(a.y[n:] - velocities)) < 1e-7
    assert red.reduce(list(qd0)) == pytest.approx(u0)


# -- KanesMethod, written here ----------------------------------------------------------------------


def kane(name: str):  # type: ignore[no-untyped-def]
    """(q, u, independent indices, rhs function (q, u) -> [q_dot, u_dot], parameter values) from
    KanesMethod with the same dependent speeds as lagrange chose."""
    from sympy.physics.mechanics import KanesMethod, Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia

    N = ReferenceFrame("N")
    origin = Point("O")
    origin.set_vel(N, 0)
    if name == "rolling_coin":
        x, y, phi, theta = q = dynamicsymbols("x y phi theta")
        ux, uy, wp, wt = u = dynamicsymbols("ux uy wp wt")
        m, R = sp.symbols("m R")
        B = ReferenceFrame("B")
        B.set_ang_vel(N, wp * sp.sin(theta) * B.x + wp * sp.cos(theta) * B.y + wt * B.z)
        G = origin.locatenew("G", x * N.x + y * N.y + R * N.z)
        G.set_vel(N, ux * N.x + uy * N.y)
        body = RigidBody("coin", G, B, m, (inertia(B, m * R**2 / 4, m * R**2 / 4, m * R**2 / 2), G))
        constraints = [ux - R * sp.cos(phi) * wt, uy - R * sp.sin(phi) * wt]
        dependent = [0, 1]
        values = {m: 1.0, R: 0.5}
        loads: list = []
    else:
        x, y, phi = q = dynamicsymbols("x y phi")
        ux, uy, w = u = dynamicsymbols("ux uy w")
        m, inertia_z = sp.symbols("m I")
        B = ReferenceFrame("B")
        B.orient_axis(N, N.z, phi)
        B.set_ang_vel(N, w * N.z)
        P = origin.locatenew("P", x * N.x + y * N.y)
        P.set_vel(N, ux * N.x + uy * N.y)
        if name == "chaplygin_sleigh":
            a = sp.Symbol("a")
            G = P.locatenew("G", a * B.x)
            G.v2pt_theory(P, N, B)
            constraints = [-sp.sin(phi) * ux + sp.cos(phi) * uy]
            values = {m: 1.0, inertia_z: 0.2, a: 0.5}
            loads = []
        else:
            g, alpha = sp.symbols("g alpha")
            G = P
            constraints = [ux * sp.sin(phi) - uy * sp.cos(phi)]
            values = {m: 1.0, inertia_z: 0.1, g: 9.81, alpha: 0.3}
            values = {**values}
            loads = [(G, m * g * sp.sin(alpha) * N.x)]
        body = RigidBody("b", G, B, m, (inertia(B, 0, 0, inertia_z), G))
        dependent = [1]
    independent = [i for i in range(len(q)) if i not in dependent]
    kd = [qi.diff() - ui for qi, ui in zip(q, u, strict=True)]
    km = KanesMethod(
        N,
        q_ind=q,
        u_ind=[u[i] for i in independent],
        u_dependent=[u[i] for i in dependent],
        kd_eqs=kd,
        velocity_constraints=constraints,
    )
    km.kanes_equations([body], loads)
    rhs = km.rhs()
    f = sp.lambdify([list(q), list(u)], rhs.xreplace(values), "numpy")
    return q, u, independent, f, values


@pytest.mark.parametrize("name", SYSTEMS)
def test_accelerations_agree_with_kanes_method(name: str, tmp_path: Path) -> None:
    model, _, red = modules(name, tmp_path)
    _, _, independent, f, _ = kane(name)
    assert [model.coordinates[i] for i in independent] == list(red.INDEPENDENT)
    params = dict(red.PARAMETERS)
    if name == "knife_edge_incline":  # the same numbers as the Kane model
        assert params["I"] == pytest.approx(0.1) and params["alpha"] == pytest.approx(0.3)
    rng = random.Random(7)
    for _ in range(5):
        q = [rng.uniform(-0.7, 0.7) for _ in range(model.n)]
        u = [rng.uniform(-1.5, 1.5) for _ in independent]
        z = np.array([*q, *u])
        ours = np.array(red.rhs(0.0, z), dtype=float)
        qd = red.velocities(0.0, z)
        theirs = np.array(f(q, qd), dtype=float).ravel()
        n = model.n
        assert np.allclose(ours[:n], theirs[:n], rtol=0, atol=1e-12)  # q_dot
        assert np.allclose(ours[n:], theirs[n : n + len(independent)], rtol=0, atol=1e-9), (ours, theirs)  # Kane orders u as [independent, dependent]


# -- the choice, the refusals and the emitters --------------------------------------------------------

KNIFE = """
title: knife
coordinates: [x, y, phi]
parameters: {m: 1.0, I: 0.1}
bodies:
  blade: {mass: m, position: [x, y], inertia: I, angular_velocity: phi_dot}
constraints:
  knife: x_dot*sin(phi) = y_dot*cos(phi)
initial: {PHI}
"""


def test_the_dependent_velocity_is_the_best_pivot_at_the_initial_coordinates() -> None:
    along_x = reduced(model_of(KNIFE.replace("{PHI}", "{phi: 0.0}")))
    along_y = reduced(model_of(KNIFE.replace("{PHI}", "{phi: 1.5}")))
    assert along_x.dependent == (1,) and along_y.dependent == (0,)
    assert "phi = 1.5" in along_y.summary()
    model = model_of(KNIFE.replace("{PHI}", "{phi: 1.5}"))
    assert choose(model, sp.Matrix(model.constraint_matrix))[0] == (0,)


def test_a_system_without_velocity_constraints_is_refused() -> None:
    result = runner.invoke(app, ["derive", "simple_pendulum", "--form", "reduced"])
    assert result.exit_code == 2
    assert "--form reduced needs a velocity (nonholonomic) constraint" in result.stderr
    result = runner.invoke(app, ["derive", "pendulum_multiplier", "--form", "reduced"])
    assert result.exit_code == 2 and "holonomic: eliminate them" in result.stderr


def test_dependent_constraints_are_refused() -> None:
    text = KNIFE.replace("{PHI}", "{phi: 0.0}").replace("knife: x_dot*sin(phi) = y_dot*cos(phi)", "knife: x_dot*sin(phi) = y_dot*cos(phi)\n  again: 2*x_dot*sin(phi) = 2*y_dot*cos(phi)")
    with pytest.raises(LagrangeError, match="do not determine 2 velocities"):
        reduced(model_of(text))


@pytest.mark.parametrize("target", ["text", "latex", "python", "c", "octave", "jax", "json"])
def test_every_target_writes_it(target: str) -> None:
    """Each target's code is run in its toolchain by tests/test_reduced_c.py and tests/test_reduced_targets.py."""
    result = runner.invoke(app, ["derive", "rolling_coin", "--to", target, "--form", "reduced"])
    assert result.exit_code == 0, result.output
    assert result.stdout.strip() and ("lambda_roll" not in result.stdout) is (target != "json")  # JSON keeps the model's constraints


def test_text_and_latex_name_the_choice() -> None:
    result = runner.invoke(app, ["derive", "chaplygin_sleigh", "--form", "reduced"])
    assert result.exit_code == 0, result.output
    assert "independent velocities: x_dot, phi_dot; dependent: y_dot" in result.stdout
    assert "y_dot = " in result.stdout and "lambda" not in result.stdout
    result = runner.invoke(app, ["derive", "chaplygin_sleigh", "--latex", "--form", "reduced", "--standalone"])
    assert result.exit_code == 0 and "\\end{document}" in result.stdout and "lambda" not in result.stdout


def test_the_coin_rolls_at_constant_rates(tmp_path: Path) -> None:
    """The reduced coin: phi_dot and theta_dot constant, x_dot = R cos(phi) theta_dot."""
    _, _, red = modules("rolling_coin", tmp_path)
    z = np.array([0.1, 0.2, 0.3, 0.4, 1.0, 2.0])
    dz = red.rhs(0.0, z)
    assert dz[4:] == pytest.approx([0.0, 0.0], abs=1e-14)
    assert dz[0] == pytest.approx(0.5 * math.cos(0.3) * 2.0)


MIXED = """
title: a particle on a growing ring with a velocity constraint
coordinates: [x, y, z]
parameters: {m: 1.0, g: 9.81, k: 0.1}
gravity: [0, 0, -g]
particles:
  p: {mass: m, position: [x, y, z]}
constraints:
  ring: x**2 + y**2 = (1 + k*t)**2
  twist: z_dot = x*y_dot - y*x_dot
initial: {x: 1.0}
"""


def test_a_kept_rheonomic_holonomic_constraint_joins_the_velocity_one(tmp_path: Path) -> None:
    """The ring (holonomic, time-dependent) is differentiated into a velocity row with a bias b(t)
    and an acceleration bias: the reduced trajectories still follow the multiplier form's."""
    model = model_of(MIXED)
    red = reduced(model)
    assert [model.coordinates[i] for i in red.dependent] == ["x", "z"]
    full = load_module(pyemit.emit(model), tmp_path / "mixed_full.py")
    mod = load_module(emit_reduced.python(model), tmp_path / "mixed_reduced.py")
    z0 = np.array([1.0, 0.0, 0.0, 0.7])
    qd0 = mod.velocities(0.0, z0)
    assert qd0[0] == pytest.approx(0.1) and qd0[2] == pytest.approx(0.7)
    t = np.linspace(0, 0.6, 13)  # x stays away from 0, where the chosen block A_D (det 2 x) is singular
    a = solve_ivp(full.rhs, (0, 0.6), [1.0, 0.0, 0.0, *qd0], method="DOP853", rtol=1e-11, atol=1e-12, t_eval=t)
    b = solve_ivp(mod.rhs, (0, 0.6), z0, method="DOP853", rtol=1e-11, atol=1e-12, t_eval=t)
    assert a.success and b.success
    assert np.min(np.abs(b.y[0])) > 0.5
    assert np.max(np.abs(a.y[:3] - b.y[:3])) < 1e-7
    assert "valid where 2*x != 0" in red.summary()
    assert np.allclose(np.hypot(b.y[0], b.y[1]), 1 + 0.1 * t, atol=1e-7)  # on the growing ring


def test_a_parameter_without_a_default_is_refused() -> None:
    """The choice is made at the default parameters: a list of names gives none."""
    text = KNIFE.replace("{PHI}", "{phi: 0.0}").replace("parameters: {m: 1.0, I: 0.1}", "parameters: [m, I]")
    with pytest.raises(LagrangeError, match="chooses the independent velocities at the default parameters, and m, I have no default"):
        reduced(model_of(text))


def test_the_api_writes_the_reduced_form() -> None:
    from lagrange_cli.api import load

    system = load("chaplygin_sleigh")
    assert system.reduced.dependent == (1,)
    assert "def rhs(" in system.to("python", form="reduced")
    assert "static inline int eom_rhs(" in system.to("c", form="reduced")
    assert "function [dydt, qdot, Mr, Fr] = eom(t, y, p)" in system.to("octave", form="reduced")
    with pytest.raises(LagrangeError, match="--form reduced is not available for --to nowhere"):
        from lagrange_cli.reduced import refuse_target

        refuse_target("nowhere")
