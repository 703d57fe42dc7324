"""Simulation: every bundled system runs, trajectories agree with independent solutions, failures
are explained, events are located, and the command writes what it says it writes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.errors import LagrangeError
from lagrange_cli.numeric import simulate

from .conftest import ROOT, SYSTEMS
from .helpers import model_from, model_of

runner = CliRunner()


pytestmark = pytest.mark.usefixtures("private_cache")


@pytest.mark.parametrize("path", SYSTEMS, ids=lambda p: p.stem)
def test_every_bundled_system_simulates_with_its_defaults(path: Path) -> None:
    trajectory = simulate(model_from(path), backend="python")
    assert trajectory.status == "finished", trajectory.message
    assert trajectory.t[-1] == pytest.approx(trajectory.settings.t_end) and np.all(np.isfinite(trajectory.y))
    for invariant in trajectory.invariants:
        if invariant.conserved:
            assert invariant.relative < 1e-5 or invariant.max_change < 1e-6, invariant


def test_undefined_function_is_refused_by_name(tmp_path: Path) -> None:
    path = tmp_path / "undefined.yaml"
    path.write_text("coordinates: [r]\nparameters: {m: 1.0}\nfunctions: [U]\nkinetic: m*r_dot**2/2\npotential: U(r)\n")
    result = runner.invoke(app, ["simulate", str(path)])
    assert result.exit_code == 2 and "U is left undefined" in result.output and "Traceback" not in result.output


def hand_double_pendulum(t: float, y: np.ndarray) -> list[float]:
    """The double pendulum (m = l = 1, g = 9.81) written out by hand, independently of lagrange."""
    th1, th2, w1, w2 = y
    s, c = math.sin(th1 - th2), math.cos(th1 - th2)
    f1 = -s * w2 * w2 - 2 * 9.81 * math.sin(th1)
    f2 = s * w1 * w1 - 9.81 * math.sin(th2)
    return [w1, w2, (f1 - c * f2) / (2 - c * c), (2 * f2 - c * f1) / (2 - c * c)]


@pytest.mark.parametrize(("method", "backend"), [("DOP853", "compiled"), ("RK45", "compiled"), ("DOP853", "python"), ("Radau", "python"), ("LSODA", "python"), ("BDF", "python")])
def test_double_pendulum_agrees_with_a_hand_written_reference(method: str, backend: str) -> None:
    """The reference: the hand-written equations, integrated by scipy's DOP853 at rtol 1e-13."""
    model = model_from(ROOT / "systems" / "double_pendulum.yaml")
    tight = method in ("DOP853", "RK45")
    trajectory = simulate(model, method=method, backend=backend, t_end=5.0, samples=51, rtol=1e-11 if tight else 1e-9, atol=1e-12)
    reference = solve_ivp(hand_double_pendulum, (0, 5), [1.0, 0.5, 0.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-14, t_eval=trajectory.t)
    assert np.max(np.abs(trajectory.y - reference.y.T)) < (1e-8 if tight else 1e-5)
    assert trajectory.stats.nfev > 0 and (trajectory.stats.njev > 0) == (method in ("Radau", "BDF"))


def test_compiled_and_scipy_take_the_same_steps() -> None:
    model = model_from(ROOT / "systems" / "chain_3.yaml")
    compiled = simulate(model, method="DOP853", backend="compiled", rtol=1e-9)
    scipy = simulate(model, method="DOP853", backend="python", rtol=1e-9)
    assert compiled.stats.steps == scipy.stats.steps and compiled.stats.nfev == scipy.stats.nfev
    assert np.max(np.abs(compiled.y - scipy.y)) < 1e-9


def test_harmonic_oscillator_matches_its_exact_solution() -> None:
    trajectory = simulate(model_from(ROOT / "systems" / "harmonic_oscillator.yaml"), method="DOP853", backend="compiled", rtol=1e-12, atol=1e-14)
    exact = np.cos(2 * trajectory.t) + 0.25 * np.sin(2 * trajectory.t)
    assert np.max(np.abs(trajectory.column("x") - exact)) < 1e-10


def test_symplectic_energy_error_stays_bounded_where_rk45_drifts() -> None:
    model = model_from(ROOT / "systems" / "double_pendulum.yaml")
    gauss = simulate(model, method="symplectic", step=0.02, t_end=400.0, samples=401)
    error = np.abs(gauss.energy - gauss.energy[0]) / abs(gauss.energy[0])
    assert gauss.stats.steps == 20000 and error.max() < 1e-4
    assert error[200:].max() < 3 * error[:200].max()  # no drift: the second half is no worse
    rk45 = simulate(model, method="RK45", backend="compiled", rtol=1e-6, atol=1e-9, t_end=400.0, samples=401)
    drift = np.abs(rk45.energy - rk45.energy[0]) / abs(rk45.energy[0])
    assert drift[-1] > 10 * error.max() and drift[300:].mean() > 2 * drift[50:150].mean()


def test_symplectic_agrees_with_dop853_over_a_short_run() -> None:
    model = model_from(ROOT / "systems" / "spherical_pendulum.yaml")
    gauss = simulate(model, method="symplectic", step=1e-3, t_end=2.0, samples=21)
    dop = simulate(model, method="DOP853", backend="compiled", t_end=2.0, samples=21, rtol=1e-12, atol=1e-13)
    assert np.max(np.abs(gauss.y - dop.y)) < 1e-8
    assert next(i for i in gauss.invariants if i.name == "p_phi").max_change < 1e-12


def test_constraint_drift_stays_small_with_stabilisation() -> None:
    trajectory = simulate(model_from(ROOT / "systems" / "rolling_disk_pendulum_multiplier.yaml"), t_end=50.0, backend="compiled", method="DOP853")
    drift = next(i for i in trajectory.invariants if i.name == "constraint rolling")
    assert trajectory.status == "finished" and drift.max_change < 1e-8


SPHERE = """
title: Particle on a sphere, kept with a multiplier
coordinates: [r, theta]
parameters: {m: 1.0, R: 1.0, g: 9.81}
gravity: [0, -g]
particles:
  p: {mass: m, position: [r*sin(theta), r*cos(theta)]}
constraints:
  surface: r = R
initial: {r: 1.0, theta: 0.1}
"""


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_until_multiplier_finds_where_the_particle_leaves_the_sphere(backend: str) -> None:
    """From rest at angle theta0 on top of a sphere, the normal force vanishes where cos(theta) = (2/3) cos(theta0)."""
    trajectory = simulate(model_of(SPHERE), until="lambda_surface", backend=backend, method="DOP853", rtol=1e-11, atol=1e-12)
    assert trajectory.status == "event" and trajectory.t[-1] <= trajectory.t_last < trajectory.settings.t_end
    assert math.cos(trajectory.y_last[1]) == pytest.approx(2 / 3 * math.cos(0.1), abs=1e-7)


def test_until_in_the_symplectic_method() -> None:
    model = model_from(ROOT / "systems" / "simple_pendulum.yaml")
    trajectory = simulate(model, method="symplectic", step=1e-3, until="theta")
    period = simulate(model, method="DOP853", backend="python", rtol=1e-12, atol=1e-13, until="theta")
    assert trajectory.status == period.status == "event"
    assert trajectory.t_last == pytest.approx(period.t_last, abs=1e-8)


def test_singular_mass_matrix_is_reported_with_time_and_state() -> None:
    model = model_from(ROOT / "systems" / "free_symmetric_top.yaml")
    for backend in ("compiled", "python"):
        trajectory = simulate(model, initial={"theta": 0.0}, backend=backend, method="DOP853")
        assert trajectory.failed and "the mass matrix is singular" in trajectory.message and "t = 0" in trajectory.message and "theta = 0" in trajectory.message


BLOWUP = """
coordinates: [x]
particles:
  p: {mass: 1, position: [x]}
potential: -x**4
initial: {x: 1.0}
"""


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_blow_up_keeps_the_trajectory_so_far(backend: str) -> None:
    trajectory = simulate(model_of(BLOWUP), backend=backend, method="DOP853", t_end=5.0)
    assert trajectory.failed and ("step size collapsed" in trajectory.message or "infinite" in trajectory.message)
    assert 0 < trajectory.t_last < 1.0 and len(trajectory.t) > 1 and np.all(np.isfinite(trajectory.y))


def test_bad_settings_raise_lagrange_errors() -> None:
    model = model_from(ROOT / "systems" / "double_pendulum.yaml")
    cases = [
        ({"method": "RK4"}, "unknown method"),
        ({"parameters": {"gg": 1.0}}, "did you mean 'g'"),
        ({"initial": {"theta_dt": 1.0}}, "theta_dot"),
        ({"t_end": -1.0}, "positive"),
        ({"step": 0.1, "method": "RK45"}, "--step"),
        ({"until": "theta +"}, "--until"),
        ({"until": "import os"}, "--until"),
        ({"rtol": 1e-20}, "rtol"),
    ]
    for kwargs, text in cases:
        with pytest.raises(LagrangeError, match=text):
            simulate(model, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(LagrangeError, match="'k' has no value"):
        simulate(model_of("coordinates: [x]\nparameters: [k]\nparticles: {p: {mass: 1, position: [x]}}\npotential: k*x**2\n"))
    with pytest.raises(LagrangeError, match="symplectic method needs a system without kept constraints"):
        simulate(model_from(ROOT / "systems" / "atwood_machine_multiplier.yaml"), method="symplectic")


def test_repeated_calls_reuse_the_compiled_functions() -> None:
    model = model_from(ROOT / "systems" / "simple_pendulum.yaml")
    simulate(model, method="DOP853", backend="compiled")
    again = simulate(model, method="DOP853", backend="compiled", rtol=1e-6)
    assert again.timing.generate == 0.0 and again.timing.load == 0.0
    assert again.stats.nfev > 0 and again.stats.min_step is not None


# -- the command --------------------------------------------------------------------------------


def test_simulate_writes_csv_and_reports(tmp_path: Path) -> None:
    out = tmp_path / "dp.csv"
    result = runner.invoke(app, ["simulate", "double_pendulum", "--t-end", "2", "--samples", "11", "-o", str(out), "--set", "g=9.81", "--initial", "theta=pi/4,phi_dot=0.1"])
    assert result.exit_code == 0, result.output
    assert "energy" in result.stdout and "finished" in result.stdout
    lines = out.read_text().splitlines()
    assert lines[0] == "t,theta,phi,theta_dot,phi_dot,energy" and len(lines) == 12
    assert float(lines[1].split(",")[1]) == pytest.approx(math.pi / 4)
    assert [p.name for p in tmp_path.iterdir()] == ["dp.csv"]


def test_simulate_writes_npz_and_a_plot(tmp_path: Path) -> None:
    result = runner.invoke(app, ["simulate", "spherical_pendulum", "--t-end", "1", "-o", str(tmp_path / "s.npz"), "--plot", str(tmp_path / "s.png")])
    assert result.exit_code == 0, result.output
    with np.load(tmp_path / "s.npz") as data:
        assert data["y"].shape == (1001, 4) and str(data["status"]) == "finished" and list(data["names"])[:2] == ["theta", "phi"]
    assert (tmp_path / "s.png").read_bytes()[:4] == b"\x89PNG"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.npz", "s.png"]


def test_failure_exits_1_and_keeps_the_trajectory(tmp_path: Path) -> None:
    system = tmp_path / "blowup.yaml"
    system.write_text(BLOWUP)
    out = tmp_path / "b.csv"
    result = runner.invoke(app, ["simulate", str(system), "--t-end", "5", "--backend", "python", "-o", str(out)])
    assert result.exit_code == 1 and "failed at t = " in result.output and "x = " in result.output and "Traceback" not in result.output
    assert len(out.read_text().splitlines()) > 2


@pytest.mark.parametrize(
    ("args", "text"),
    [
        (["--set", "g"], "expected name=value"),
        (["--set", "g=__import__('os')"], "error"),
        (["--method", "euler"], "unknown method"),
        (["-o", "out.txt"], "format"),
        (["--plot", "out.gif"], "format"),
        (["--backend", "gpu"], "unknown backend"),
    ],
)
def test_bad_options_exit_2(args: list[str], text: str, tmp_path: Path) -> None:
    result = runner.invoke(app, ["simulate", "double_pendulum", *args])
    assert result.exit_code == 2 and text in result.output and "Traceback" not in result.output


def test_csv_to_stdout() -> None:
    result = runner.invoke(app, ["simulate", "harmonic_oscillator", "--samples", "3", "-o", "-"])
    assert result.exit_code == 0
    assert result.stdout.splitlines()[0] == "t,x,x_dot,energy" and len(result.stdout.splitlines()) == 4


def test_cached_modules_are_not_reused_after_the_code_generator_changes(monkeypatch: pytest.MonkeyPatch) -> None:
    """A fix to the generator (e.g. the printer) gives new cache keys, so no stale module is loaded."""
    from lagrange_cli.numeric import compile

    keys = []
    for source in ("generator as it was", "generator as fixed"):
        monkeypatch.setattr(compile, "_generator_source", lambda source=source: source)
        keys.append(compile.fingerprint(model_from(ROOT / "systems" / "kepler.yaml"), "python", False, None))
    assert keys[0] != keys[1]


def test_settings_only_validate_and_the_policy_decides(monkeypatch: pytest.MonkeyPatch) -> None:
    """`settings.validate` compiles nothing and leaves `auto` as asked; `policy.decide` resolves it,
    and Baumgarte's alpha enters the generated code's parameters in one place (`Settings.p`)."""
    from lagrange_cli.numeric import compile, policy, settings

    model = model_from(ROOT / "systems" / "pendulum_multiplier.yaml")

    def no_compiling(*args: object, **kwargs: object) -> object:
        raise AssertionError("validate compiled something")

    with monkeypatch.context() as patched:
        patched.setattr(compile, "build", no_compiling)
        asked = settings.validate(model, t_end=2.0)
    assert asked.method == "auto" and asked.backend == "auto" and asked.alpha is None and asked.p == asked.values
    decided = policy.decide(model, asked)
    assert decided.method != "auto" and decided.backend != "auto" and decided.alpha is not None and decided.alpha > 0
    assert decided.p == (*asked.values, decided.alpha) and len(decided.values) == len(model.parameters)


def test_a_run_refused_before_its_first_step_says_nothing_was_integrated(tmp_path: Path) -> None:
    """A fixed symplectic step that needs more steps than the budget is refused before it starts (exit 1,
    a numerical outcome, not bad input): the message must not claim a trajectory "up to there" (audit 8 F4)."""
    out = tmp_path / "run.csv"
    result = runner.invoke(app, ["simulate", str(ROOT / "systems" / "damped_oscillator_rayleigh.yaml"), "--step", "1e-9", "--t-end", "10", "-o", str(out)])
    assert result.exit_code == 1, result.output
    assert "more than the step budget" in result.stderr and "not run" in result.stderr
    assert "nothing was integrated" in result.stderr
    assert "up to there is kept" not in result.stderr
