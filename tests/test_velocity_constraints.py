"""Velocity (nonholonomic) constraints through the numerics: `simulate` with each method family,
the Baumgarte stabilisation alpha (A q_dot + b), the analytic Jacobian, the symplectic method's
refusal, and `accuracy`/`stress` end to end.

The references are written here by hand, independently of lagrange: each system in its
independent velocities (the speed along the blade and the turning rate for the knife edge and
the Chaplygin sleigh, the rolling and turning rates for the coin), integrated by scipy."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model
from lagrange_cli.numeric import compile, simulate

from .conftest import ROOT
from .helpers import load_module, model_from, model_of

runner = CliRunner()
pytestmark = pytest.mark.usefixtures("private_cache")

T_END = 5.0
G, ALPHA_INCLINE = 9.81, 0.3  # knife_edge_incline.yaml's defaults
R_COIN = 0.5  # rolling_coin.yaml
M_SLEIGH, I_SLEIGH, A_SLEIGH = 1.0, 0.2, 0.5  # chaplygin_sleigh.yaml


def along(y: np.ndarray, n: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """(v, u): the velocity of (x, y) along the blade at angle phi and across it, for y = [x, y,
    phi, ... (n coordinates), x_dot, y_dot, ...]."""
    phi, xd, yd = y[:, 2], y[:, n], y[:, n + 1]
    return np.cos(phi) * xd + np.sin(phi) * yd, -np.sin(phi) * xd + np.cos(phi) * yd


# -- the reduced equations, by hand ---------------------------------------------------------------


def knife(t: float, z: np.ndarray) -> list[float]:
    """Knife edge on the incline in (x, y, phi, v, omega): v_dot = g sin(alpha) cos(phi), omega constant."""
    _, _, phi, v, w = z
    return [v * math.cos(phi), v * math.sin(phi), w, G * math.sin(ALPHA_INCLINE) * math.cos(phi), 0.0]


def coin(t: float, z: np.ndarray) -> list[float]:
    """Upright rolling coin in (x, y, phi, theta, phi_dot, theta_dot): both rates constant."""
    _, _, phi, _, w, s = z
    return [R_COIN * s * math.cos(phi), R_COIN * s * math.sin(phi), w, s, 0.0, 0.0]


def sleigh(t: float, z: np.ndarray) -> list[float]:
    """Chaplygin sleigh in (x, y, phi, v, omega): v_dot = a omega^2, (I + m a^2) omega_dot = -m a v omega."""
    _, _, phi, v, w = z
    return [v * math.cos(phi), v * math.sin(phi), w, A_SLEIGH * w * w, -M_SLEIGH * A_SLEIGH * v * w / (I_SLEIGH + M_SLEIGH * A_SLEIGH**2)]


def blade_state(y: np.ndarray) -> np.ndarray:
    """(x, y, phi, v, omega) from [x, y, phi, x_dot, y_dot, phi_dot]."""
    v, _ = along(y)
    return np.column_stack([y[:, 0], y[:, 1], y[:, 2], v, y[:, 5]])


def coin_state(y: np.ndarray) -> np.ndarray:
    return y[:, [0, 1, 2, 3, 6, 7]]


def blade_residual(y: np.ndarray) -> np.ndarray:
    return along(y)[1]


def coin_residual(y: np.ndarray) -> np.ndarray:
    phi, xd, yd, sd = y[:, 2], y[:, 4], y[:, 5], y[:, 7]
    return np.maximum(np.abs(xd - R_COIN * np.cos(phi) * sd), np.abs(yd - R_COIN * np.sin(phi) * sd))


def knife_energy(y: np.ndarray) -> np.ndarray:
    return 0.5 * (y[:, 3] ** 2 + y[:, 4] ** 2) + 0.5 * 0.1 * y[:, 5] ** 2 - G * math.sin(ALPHA_INCLINE) * y[:, 0]


def coin_energy(y: np.ndarray) -> np.ndarray:
    return 0.5 * (y[:, 4] ** 2 + y[:, 5] ** 2) + R_COIN**2 / 8 * y[:, 6] ** 2 + R_COIN**2 / 4 * y[:, 7] ** 2


def sleigh_energy(y: np.ndarray) -> np.ndarray:
    v, _ = along(y)
    return 0.5 * M_SLEIGH * v**2 + 0.5 * (I_SLEIGH + M_SLEIGH * A_SLEIGH**2) * y[:, 5] ** 2


Case = tuple[str, dict[str, float], Callable[..., list[float]], Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], np.ndarray]]

# Starts away from the files' defaults (and from their exact solutions), on the constraints.
CASES: dict[str, Case] = {
    "knife_edge_incline": (
        "knife_edge_incline",
        {"x": 0.2, "y": -0.1, "phi": 0.4, "x_dot": 0.7 * math.cos(0.4), "y_dot": 0.7 * math.sin(0.4), "phi_dot": 1.3},
        knife,
        blade_state,
        blade_residual,
        knife_energy,
    ),
    "rolling_coin": (
        "rolling_coin",
        {"phi": 0.7, "theta": 0.1, "x_dot": R_COIN * 1.6 * math.cos(0.7), "y_dot": R_COIN * 1.6 * math.sin(0.7), "phi_dot": -0.8, "theta_dot": 1.6},
        coin,
        coin_state,
        coin_residual,
        coin_energy,
    ),
    "chaplygin_sleigh": (
        "chaplygin_sleigh",
        {"phi": 0.3, "x_dot": -0.4 * math.cos(0.3), "y_dot": -0.4 * math.sin(0.3), "phi_dot": 1.5},
        sleigh,
        blade_state,
        blade_residual,
        sleigh_energy,
    ),
}

METHODS = [("RK45", "python"), ("DOP853", "compiled"), ("Radau", "python")]


def _model(name: str) -> Model:
    return model_from(ROOT / "systems" / f"{name}.yaml")


@pytest.mark.parametrize(("method", "backend"), METHODS, ids=[f"{m}-{b}" for m, b in METHODS])
@pytest.mark.parametrize("case", sorted(CASES))
def test_simulation_follows_the_reduced_equations(case: str, method: str, backend: str) -> None:
    """Each method family: the constraint residual stays below 1e-8 over t = 5 at rtol 1e-10, the
    energy is conserved, and the motion is that of the hand-written reduced equations."""
    if backend == "compiled" and not compile.numba_available():
        pytest.skip("numba is not installed")
    name, initial, reduced, state, residual, energy = CASES[case]
    trajectory = simulate(_model(name), method=method, backend=backend, t_end=T_END, samples=51, rtol=1e-10, atol=1e-12, initial=initial)
    assert trajectory.status == "finished", trajectory.message
    assert trajectory.settings.method == method and trajectory.settings.backend == backend
    assert np.max(np.abs(residual(trajectory.y))) < 1e-8
    start = state(trajectory.y[:1])[0]
    reference = solve_ivp(reduced, (0.0, T_END), start, method="DOP853", rtol=1e-13, atol=1e-14, t_eval=trajectory.t)
    assert np.max(np.abs(state(trajectory.y) - reference.y.T)) < (1e-7 if method != "Radau" else 1e-6)
    h = energy(trajectory.y)
    assert np.max(np.abs(h - h[0])) < 1e-8 * max(1.0, abs(h[0]))
    monitored = {i.name: i for i in trajectory.invariants}
    assert monitored["energy"].conserved and monitored["energy"].max_change < 1e-8
    assert all(monitored[f"constraint {c.name}"].max_change < 1e-8 for c in _model(name).constraints)


def test_closed_form_motions() -> None:
    """The textbook closed forms: the knife edge started at rest along the blade stays within
    x <= g sin(alpha)/(2 omega^2) and drifts across the slope; the coin runs round a circle of
    radius R theta_dot/phi_dot; the sleigh's speed is V tanh(m a V t/(I + m a^2) + atanh(v0/V))."""
    t = np.linspace(0.0, T_END, 51)
    run = simulate(_model("knife_edge_incline"), method="DOP853", backend="python", t_eval=t, t_end=T_END, rtol=1e-11, atol=1e-12)
    gs, w = G * math.sin(ALPHA_INCLINE), 2.0
    assert np.max(np.abs(run.column("x") - gs * np.sin(w * t) ** 2 / (2 * w * w))) < 1e-8
    assert np.max(np.abs(run.column("y") - gs * (t - np.sin(2 * w * t) / (2 * w)) / (2 * w))) < 1e-8
    run = simulate(_model("rolling_coin"), method="DOP853", backend="python", t_eval=t, t_end=T_END, rtol=1e-11, atol=1e-12)
    radius = R_COIN * 2.0 / 1.0
    assert np.max(np.abs(np.hypot(run.column("x"), run.column("y") - radius) - radius)) < 1e-8
    run = simulate(_model("chaplygin_sleigh"), method="DOP853", backend="python", t_eval=t, t_end=T_END, rtol=1e-11, atol=1e-12)
    j, v0, w0 = I_SLEIGH + M_SLEIGH * A_SLEIGH**2, 0.2, 2.0
    speed = math.sqrt(v0**2 + j * w0**2 / M_SLEIGH)
    v, _ = along(run.y)
    assert np.max(np.abs(v - speed * np.tanh(M_SLEIGH * A_SLEIGH * speed * t / j + math.atanh(v0 / speed)))) < 1e-8
    assert np.max(np.abs(run.column("phi_dot") ** 2 - M_SLEIGH * (speed**2 - v**2) / j)) < 1e-8


MIXED = """title: blade with a prescribed side slip and a prescribed height
coordinates: [x, y, phi, z]
parameters: {m: 1.0, I: 0.5, w: 1.5, l: 1.0, g: 9.81}
gravity: [0, 0, -g]
particles:
  c: {mass: m, position: [x, y, z]}
kinetic: I*phi_dot**2/2
constraints:
  blade: -sin(phi)*x_dot + cos(phi)*y_dot = 0.3*cos(w*t)
  rod: z = l*sin(t)
initial: {x_dot: 1.0, y_dot: 0.3, phi_dot: 0.5, z_dot: 1.0}
"""


def mixed(t: float, s: np.ndarray) -> list[float]:
    """In (x, y, phi, v): u = 0.3 cos(1.5 t) across the blade, v_dot = phi_dot u (no force along it)."""
    _, _, phi, v = s
    u = 0.3 * math.cos(1.5 * t)
    return [v * math.cos(phi) - u * math.sin(phi), v * math.sin(phi) + u * math.cos(phi), 0.5, 0.5 * u]


@pytest.mark.parametrize(("method", "backend"), METHODS, ids=[f"{m}-{b}" for m, b in METHODS])
def test_time_dependent_velocity_constraint_with_a_holonomic_one(method: str, backend: str) -> None:
    """a . q_dot + b(t) = 0 with b != 0, next to a rheonomic holonomic constraint."""
    if backend == "compiled" and not compile.numba_available():
        pytest.skip("numba is not installed")
    trajectory = simulate(model_of(MIXED, "mixed.yaml"), method=method, backend=backend, t_end=T_END, samples=51, rtol=1e-10, atol=1e-12)
    assert trajectory.status == "finished" and not any("violates" in note for note in trajectory.notes), trajectory.notes
    y, t = trajectory.y, trajectory.t
    v, u = along(y, 4)
    assert np.max(np.abs(u - 0.3 * np.cos(1.5 * t))) < 1e-8
    assert np.max(np.abs(y[:, 3] - np.sin(t))) < 1e-8 and np.max(np.abs(y[:, 7] - np.cos(t))) < 1e-8
    reference = solve_ivp(mixed, (0.0, T_END), [0.0, 0.0, 0.0, 1.0], method="DOP853", rtol=1e-13, atol=1e-14, t_eval=t)
    assert np.max(np.abs(np.column_stack([y[:, :3], v]) - reference.y.T)) < (1e-7 if method != "Radau" else 1e-6)


def test_stabilisation_pulls_a_velocity_constraint_back() -> None:
    """Started off the blade's constraint, the residual r = A q_dot + b obeys r_dot = -alpha r
    (the stabilised acceleration row A q_ddot + c + alpha (A q_dot + b) = 0), and the run is told.
    Without projection (which would put the state back on the constraint at the first sample)."""
    r0 = 1e-3
    trajectory = simulate(_model("knife_edge_incline"), method="DOP853", backend="python", t_end=2.0, samples=21, rtol=1e-12, atol=1e-14, initial={"y_dot": r0}, projection=False)
    alpha = trajectory.settings.p[-1]
    assert alpha > 0
    assert any("violates constraint 'blade'" in note and "in the velocities" in note for note in trajectory.notes), trajectory.notes
    assert np.max(np.abs(blade_residual(trajectory.y) - r0 * np.exp(-alpha * trajectory.t))) < 1e-10


def test_a_start_on_the_constraints_gets_no_note() -> None:
    trajectory = simulate(_model("rolling_coin"), backend="python", t_end=0.5)
    assert not any("violates" in note for note in trajectory.notes), trajectory.notes


@pytest.mark.parametrize("name", ["knife_edge_incline", "rolling_coin", "chaplygin_sleigh", "mixed"])
def test_analytic_jacobian_matches_finite_differences(name: str) -> None:
    """The Jacobian given to Radau/BDF/LSODA, stabilisation included (alpha = 3), against central
    differences of the right-hand side, at a state off the constraints (so every term counts)."""
    model = model_of(MIXED, "mixed.yaml") if name == "mixed" else _model(name)
    module = compile.build(model, "python", jacobian=True).module
    n = model.n
    p = [*(parameter.value for parameter in model.parameters), 3.0]
    rng = np.random.default_rng(7)
    y, t = rng.uniform(-1.0, 1.0, 2 * n), 0.4

    def rhs(y: np.ndarray) -> np.ndarray:
        return np.array([*y[n:], *module._accel(t, y.tolist(), p)[:n]])

    jacobian = np.asarray(module._jac(t, y.tolist(), p), dtype=float)
    h = 1e-6
    differences = np.column_stack([(rhs(y + h * e) - rhs(y - h * e)) / (2 * h) for e in np.eye(2 * n)])
    assert np.max(np.abs(jacobian - differences)) < 1e-6 * max(1.0, float(np.max(np.abs(differences))))


def test_symplectic_method_refuses_a_velocity_constraint() -> None:
    """No canonical (q, p) form exists for a nonholonomic system: exit 2 naming method and constraint."""
    with pytest.raises(LagrangeError, match=r"symplectic.*'blade'"):
        simulate(_model("chaplygin_sleigh"), method="symplectic")
    result = runner.invoke(app, ["simulate", "rolling_coin", "--method", "symplectic"])
    assert result.exit_code == 2, result.output
    assert "symplectic" in result.output and "'roll_x'" in result.output and "Traceback" not in result.output and "internal error" not in result.output


def test_cli_simulate_reports_constraint_drift(tmp_path: Path) -> None:
    out = tmp_path / "coin.csv"
    result = runner.invoke(app, ["simulate", "rolling_coin", "--t-end", "1", "--method", "RK45", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "constraint roll_x" in result.output and "constraint roll_y" in result.output
    header = out.read_text().splitlines()[0]
    assert "theta_dot" in header


def test_accuracy_and_stress_run_end_to_end() -> None:
    result = runner.invoke(app, ["accuracy", "chaplygin_sleigh", "--method", "DOP853,Radau", "--tolerances", "1e-4,1e-7", "--t-end", "0.5", "--repeats", "0", "--samples", "11", "--json", "-"])
    assert result.exit_code == 0, result.output
    points = json.loads(result.stdout)["points"]
    assert len(points) == 4 and all(p["status"] == "finished" and math.isfinite(p["rms_error"]) for p in points), points
    result = runner.invoke(app, ["stress", "knife_edge_incline", "--method", "RK45:python,DOP853", "--t-end", "0.5", "--long", "2", "--accuracy", "1e-6", "--json", "-"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert document["passed"] is True and all(r["recommended"]["error"] <= 1e-6 for r in document["regimes"])


def test_the_sleighs_multiplier_is_the_textbook_side_force() -> None:
    """lambda_blade = m I v omega/(I + m a^2): a stop condition on it ends the run where the closed
    form says (on the way down, after its maximum at tanh(u) = 1/sqrt(2))."""
    from scipy.optimize import brentq

    j, v0, w0 = I_SLEIGH + M_SLEIGH * A_SLEIGH**2, 0.2, 2.0
    speed = math.sqrt(v0**2 + j * w0**2 / M_SLEIGH)
    k, c0 = M_SLEIGH * A_SLEIGH * speed / j, math.atanh(v0 / speed)

    def side_force(t: float) -> float:
        u = k * t + c0
        v, w = speed * math.tanh(u), math.sqrt(M_SLEIGH / j) * speed / math.cosh(u)
        return M_SLEIGH * I_SLEIGH * v * w / j - 0.1

    crossing = brentq(side_force, (math.atanh(1 / math.sqrt(2)) - c0) / k, 10.0, xtol=1e-14)
    trajectory = simulate(_model("chaplygin_sleigh"), method="DOP853", backend="python", rtol=1e-11, atol=1e-12, until="lambda_blade - 0.1")
    assert trajectory.status == "event", trajectory.message
    assert trajectory.t_last == pytest.approx(crossing, abs=1e-7)


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_derive_python_module_under_solve_ivp(case: str, tmp_path: Path) -> None:
    """`derive --python`'s `rhs` (unstabilised index-1 form), integrated by scipy, follows the
    reduced equations too, and its `multipliers` and `constraint_residuals` are consistent."""
    name, initial, reduced, state, residual, _ = CASES[case]
    out = tmp_path / f"{name}_eom.py"
    result = runner.invoke(app, ["derive", name, "--python", "-o", str(out)])
    assert result.exit_code == 0, result.output
    module = load_module(out.read_text(), out)
    n = len(module.COORDINATES)
    names = [*module.COORDINATES, *(f"{c}_dot" for c in module.COORDINATES)]
    y0 = [initial.get(k, 0.0) for k in names]
    t = np.linspace(0.0, T_END, 51)
    run = solve_ivp(module.rhs, (0.0, T_END), y0, method="DOP853", rtol=1e-11, atol=1e-12, t_eval=t)
    y = run.y.T
    reference = solve_ivp(reduced, (0.0, T_END), state(np.array([y0]))[0], method="DOP853", rtol=1e-13, atol=1e-14, t_eval=t)
    assert np.max(np.abs(state(y) - reference.y.T)) < 1e-7
    assert np.max(np.abs(residual(y))) < 1e-8
    assert max(abs(r) for r in module.constraint_residuals(y[-1, :n].tolist(), y[-1, n:].tolist())) < 1e-8
    assert len(module.multipliers(T_END, y[-1])) == len(_model(name).constraints)
