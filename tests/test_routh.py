"""Routh's reduction (lagrange_cli/routh.py, `info --routh`, `System.routhian`): the heavy top's
steady precession and Kepler's circular orbits against the textbook formulas, with stability."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
import sympy as sp
from typer.testing import CliRunner

from lagrange_cli import api
from lagrange_cli.cli import app
from lagrange_cli.errors import LagrangeError
from lagrange_cli.routh import Routh, relative_equilibria, routh

from .helpers import model_from, model_of


def _routh(name: str) -> Routh:
    return routh(model_from(Path("systems") / f"{name}.yaml"))


def _symbols(result: Routh) -> dict[str, sp.Symbol]:
    return {str(s): s for s in (*result.model.q, *result.model.qd, *(p.symbol for p in result.model.parameters), *result.momenta)}


def test_heavy_top_precession_rate_and_steady_precession_condition() -> None:
    """Textbook (Goldstein 5.7; I1 = I_perp + m l^2 about the tip, I3 = I_par): the precession rate
    phi_dot = (p_phi - p_psi cos theta)/(I1 sin^2 theta), and V_eff'(theta) = -sin(theta) (I1 cos(theta)
    phi_dot^2 - p_psi phi_dot + m g l), so steady precession at theta0 is m g l = phi_dot (p_psi - I1 phi_dot cos theta0)."""
    result = _routh("heavy_top")
    assert result.ignorable == ("phi", "psi")
    s = _symbols(result)
    theta, p_phi, p_psi = s["theta"], s["p_phi"], s["p_psi"]
    i1 = s["I_perp"] + s["m"] * s["l"] ** 2
    rate = (p_phi - p_psi * sp.cos(theta)) / (i1 * sp.sin(theta) ** 2)
    textbook = -sp.sin(theta) * (i1 * sp.cos(theta) * rate**2 - p_psi * rate + s["m"] * s["g"] * s["l"])
    rng = random.Random(5)
    for _ in range(5):
        point = {x: sp.Float(rng.uniform(0.3, 2.0)) for x in (theta, p_phi, p_psi, s["I_perp"], s["I_par"], s["m"], s["g"], s["l"])}
        assert float(result.ignorable_velocities[0].xreplace(point)) == pytest.approx(float(rate.xreplace(point)), rel=1e-10)
        assert float(sp.diff(result.effective_potential, theta).xreplace(point)) == pytest.approx(float(textbook.xreplace(point)), rel=1e-9, abs=1e-12)


def test_heavy_top_steady_precession_is_an_equilibrium_of_the_reduced_system() -> None:
    """Choose theta0 and a precession rate, take the spin from the textbook condition: the reduced
    equation is satisfied at rest there; a spin off the condition is not."""
    result = _routh("heavy_top")
    s = _symbols(result)
    values = {s[k]: v for k, v in {"I_perp": 1.0, "I_par": 2.0, "m": 1.0, "g": 9.81, "l": 1.0}.items()}
    i1, mgl = 2.0, 9.81
    theta0, rate = 0.7, 1.5
    spin_momentum = mgl / rate + i1 * rate * sp.cos(theta0)  # p_psi = I3 omega3 from the condition
    p_phi = i1 * sp.sin(theta0) ** 2 * rate + spin_momentum * sp.cos(theta0)
    assert result.reduced is not None
    force = result.reduced.forcing[0].xreplace({**values, s["theta"]: theta0, s["theta_dot"]: 0, s["p_phi"]: p_phi, s["p_psi"]: spin_momentum})
    assert abs(float(force)) < 1e-9
    assert float(result.ignorable_velocities[0].xreplace({**values, s["theta"]: theta0, s["p_phi"]: p_phi, s["p_psi"]: spin_momentum})) == pytest.approx(rate)
    wrong = result.reduced.forcing[0].xreplace({**values, s["theta"]: theta0, s["theta_dot"]: 0, s["p_phi"]: p_phi, s["p_psi"]: 1.1 * spin_momentum})
    assert abs(float(wrong)) > 1e-3


def test_heavy_top_relative_equilibria_have_a_stability() -> None:
    model, found = relative_equilibria(_routh("heavy_top"))
    assert found.points
    for point, lin in zip(found.points, found.linearizations, strict=True):
        assert "stable" in (lin if isinstance(lin, str) else lin.stability)
        force = model.forcing[0].xreplace({**point, model.qd[0]: 0})
        assert abs(float(force)) < 1e-3  # a root (the default sleeping top cancels many digits)


def test_kepler_effective_potential_and_circular_orbit() -> None:
    """V_eff = p_theta^2/(2 m r^2) - k/r; the circular orbit r0 = p_theta^2/(k m) is stable."""
    result = _routh("kepler")
    s = _symbols(result)
    r, p, m, k = s["r"], s["p_theta"], s["m"], s["k"]
    assert sp.simplify(result.effective_potential - (p**2 / (2 * m * r**2) - k / r)) == 0
    _, found = relative_equilibria(result)
    assert len(found.points) == 1
    (point,) = found.points
    assert sp.simplify(point[r] - p**2 / (k * m)) == 0
    (lin,) = found.linearizations
    assert not isinstance(lin, str) and lin.stability.startswith("stable")
    assert sp.simplify(lin.stiffness[0, 0] - k**4 * m**3 / p**6) == 0  # V_eff''(r0) > 0
    assert result.values == {"p_theta": pytest.approx(1.2)}  # m r^2 theta_dot at the file's initial state


def test_cli_info_routh() -> None:
    result = CliRunner().invoke(app, ["info", "kepler", "--routh"])
    assert result.exit_code == 0, result.stderr
    assert "V_eff = " in result.stdout and "r = p_theta**2/(k*m)" in result.stdout and "stable" in result.stdout


def test_cli_info_routh_refuses_without_ignorable_coordinates() -> None:
    result = CliRunner().invoke(app, ["info", "simple_pendulum", "--routh"])
    assert result.exit_code == 2 and "no coordinate is ignorable" in result.stderr


def test_api_routhian() -> None:
    system = api.load("kepler")
    assert system.routhian.ignorable == ("theta",)
    assert system.hamilton.symbolic
    with pytest.raises(LagrangeError, match="no coordinate is ignorable"):
        _ = api.load("simple_pendulum").routhian


def test_kept_constraints_are_refused() -> None:
    with pytest.raises(LagrangeError, match="kept constraints"):
        _routh("rolling_coin")


def test_dissipation_on_the_rest_is_kept() -> None:
    model = model_of("coordinates: [r, theta]\nparameters: {m: 1.0, c: 0.5}\nparticles:\n  b: {mass: m, position: [r*cos(theta), r*sin(theta)]}\npotential: r**2\ndissipation: c*r_dot**2/2\n")
    result = routh(model)
    assert result.reduced is not None and result.reduced.dissipation != 0
