"""The compiled Radau IIA method (kernels.radau_run, integrators.run_radau): the RADAU5 algorithm in numba,
checked against exact solutions, tight references and scipy's Radau (steps and errors counted, never timed)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from scipy.integrate._ivp import radau as scipy_radau
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.errors import LagrangeError
from lagrange_cli.numeric import compile, integrators, policy, tableaux
from lagrange_cli.numeric.simulate import simulate
from lagrange_cli.numeric.status import Status

from .conftest import ROOT
from .helpers import model_from, model_of

runner = CliRunner()
pytestmark = pytest.mark.usefixtures("private_cache")

SPRING = """
title: damped stiff spring (linear)
coordinates: [x, y]
parameters: {k: 1.0e8, c: 2.0e4, kc: 1.0}
particles:
  a: {mass: 1, position: [x]}
  b: {mass: 1, position: [y]}
potential: k*x**2/2 + kc*(x - y)**2/2 + y**2/2
dissipation: c*x_dot**2/2
initial: {x: 1.0, y: 0.5}
simulate: {t_end: 5}
"""
"""x decays at about k / c = 5e3/s and c = 2e4/s (stiffness ratio 1e4 against y's swing at 1 rad/s): linear, so exactly solvable."""


def _problem(model, t_end: float, samples: int, rtol: float, **options: object) -> tuple[integrators.Problem, object]:
    settings = policy.validate(model, method="DOP853", backend="compiled", t_end=t_end, samples=samples, rtol=rtol, **options)
    problem = integrators.Problem(0.0, t_end, np.array(settings.y0), np.array(settings.t_eval), np.array(settings.p), False, 10**6)
    return problem, settings


def _error(y: np.ndarray, reference: np.ndarray, rtol: float, atol: float) -> float:
    """The largest error over the samples, in units of the tolerance (atol + rtol |y|)."""
    return float(np.max(np.abs(y - reference) / (atol + rtol * np.abs(reference))))


def _compare(model, t_end: float, rtol: float, reference: np.ndarray | None = None, samples: int = 21) -> tuple[integrators.Run, integrators.Run, float, float]:
    problem, settings = _problem(model, t_end, samples, rtol)
    numba, python = compile.build(model, "numba"), compile.build(model, "python", jacobian=True)
    ours = integrators.run_radau(numba, problem, rtol, settings.atol)
    theirs = integrators.run_scipy(python, problem, "Radau", rtol, settings.atol, math.inf)
    assert ours.status == theirs.status == Status.FINISHED, (ours.status, theirs.status)
    if reference is None:
        long = integrators.Problem(problem.t0, problem.t_end, problem.y0, problem.ts, problem.p, False, 10**7)
        tight = integrators.run_erk(numba, long, "DOP853", 1e-13, settings.atol * 1e-3, math.inf)
        assert tight.status == Status.FINISHED
        reference = tight.y
    return ours, theirs, _error(ours.y, reference, rtol, settings.atol), _error(theirs.y, reference, rtol, settings.atol)


def test_the_constants_are_the_methods() -> None:
    """T^-1 A^-1 T is block diagonal with A^-1's eigenvalues, and the constants equal scipy's."""
    a, t, ti = np.array(tableaux.RADAU_A), np.array(tableaux.RADAU_T), np.array(tableaux.RADAU_TI)
    assert np.allclose(t @ ti, np.eye(3), atol=1e-14)
    block = ti @ np.linalg.inv(a) @ t
    expected = np.array([[tableaux.MU_REAL, 0, 0], [0, tableaux.MU_COMPLEX_REAL, -tableaux.MU_COMPLEX_IMAG], [0, tableaux.MU_COMPLEX_IMAG, tableaux.MU_COMPLEX_REAL]])
    assert np.allclose(block, expected, atol=1e-12)
    assert np.allclose(a.sum(axis=1), tableaux.RADAU_C, atol=1e-15)
    assert np.allclose(t, scipy_radau.T) and np.allclose(ti, scipy_radau.TI) and np.allclose(tableaux.RADAU_E, scipy_radau.E)
    assert pytest.approx(scipy_radau.MU_REAL) == tableaux.MU_REAL and complex(tableaux.MU_COMPLEX_REAL, tableaux.MU_COMPLEX_IMAG) == pytest.approx(scipy_radau.MU_COMPLEX)
    kernels = compile.kernels_module()
    assert np.allclose(kernels._RP, scipy_radau.P, atol=1e-12)


@pytest.mark.parametrize("rtol", [1e-6, 1e-9])
def test_a_linear_stiff_spring_against_its_exact_solution(rtol: float) -> None:
    model = model_of(SPRING)
    problem, _ = _problem(model, 5.0, 21, rtol)
    python = compile.build(model, "python", jacobian=True)
    jac = np.array(python.module._jac(0.0, list(problem.y0), list(problem.p)))  # constant: the system is linear
    exact = np.array([scipy.linalg.expm(jac * t) @ problem.y0 for t in problem.ts])
    ours, theirs, error, scipy_error = _compare(model, 5.0, rtol, exact)
    assert error < 10.0 and error < 5.0 * max(scipy_error, 1.0), (error, scipy_error)
    assert abs(ours.stats.steps - theirs.stats.steps) <= 0.3 * theirs.stats.steps, (ours.stats, theirs.stats)


@pytest.mark.parametrize("rtol", [1e-6, 1e-8])
def test_the_stiff_elastic_pendulum_against_a_tight_reference(rtol: float) -> None:
    """k = 1e10, decay 2e6/s against a swing of 3 rad/s; the reference is compiled DOP853 at rtol 1e-13 (to t = 0.2)."""
    model = model_from(ROOT / "tests" / "numeric_audit" / "stiff_elastic_pendulum_r.yaml")
    ours, theirs, error, scipy_error = _compare(model, 0.2, rtol)
    assert error < 10.0 and error < 5.0 * max(scipy_error, 1.0), (error, scipy_error)
    assert abs(ours.stats.steps - theirs.stats.steps) <= 0.3 * theirs.stats.steps, (ours.stats, theirs.stats)


def test_van_der_pol_mu_1000() -> None:
    """Relaxation oscillations with fast jumps (to t = 1000: a slow phase and a jump)."""
    model = model_from(ROOT / "tests" / "numeric_audit5" / "van_der_pol_mu1000_coupled.yaml")
    ours, theirs, error, scipy_error = _compare(model, 1000.0, 1e-6)
    assert error < 50.0 and error < 5.0 * max(scipy_error, 1.0), (error, scipy_error)
    assert abs(ours.stats.steps - theirs.stats.steps) <= 0.3 * theirs.stats.steps, (ours.stats, theirs.stats)


def test_an_event_and_the_samples_from_the_collocation_polynomial() -> None:
    """--until on the simple pendulum: the crossing time and the samples before it match DOP853 at rtol 1e-12."""
    model = model_from(ROOT / "systems" / "simple_pendulum.yaml")
    ours = simulate(model, method="Radau", backend="compiled", until="theta", samples=201, rtol=1e-8)
    tight = simulate(model, method="DOP853", backend="python", until="theta", samples=201, rtol=1e-12, atol=1e-13)
    assert ours.status == tight.status == "event" and ours.settings.backend == "compiled", ours.message
    assert ours.t_last == pytest.approx(tight.t_last, abs=1e-7)
    assert len(ours.t) == len(tight.t) > 5 and np.max(np.abs(ours.y[:, :2] - tight.y[:, :2])) < 1e-6


def test_a_paused_run_is_the_run_made_straight_through() -> None:
    """With progress reports the loop returns to Python every stretch; the steps and samples are the same."""
    model = model_from(ROOT / "tests" / "numeric_audit" / "stiff_elastic_pendulum_r.yaml")
    problem, settings = _problem(model, 2.0, 41, 1e-6)
    numba = compile.build(model, "numba")
    straight = integrators.run_radau(numba, problem, 1e-6, settings.atol)
    seen: list[float] = []
    paused = integrators.run_radau(numba, problem, 1e-6, settings.atol, progress=seen.append)
    assert len(seen) > 1 and straight.stats == paused.stats and np.array_equal(straight.y, paused.y)


def test_failures_are_reported_with_their_status() -> None:
    top = model_from(ROOT / "systems" / "free_symmetric_top.yaml")
    singular = simulate(top, initial={"theta": 0.0}, backend="compiled", method="Radau")
    assert singular.failed and "singular" in singular.message and "t = 0" in singular.message and "theta = 0" in singular.message
    blowup = simulate(model_of("coordinates: [x]\nparticles:\n  p: {mass: 1, position: [x]}\npotential: -x**4\ninitial: {x: 1.0}\n"), backend="compiled", method="Radau", t_end=5.0)
    assert blowup.failed and ("step size collapsed" in blowup.message or "infinite" in blowup.message), blowup.message
    assert 0 < blowup.t_last < 1.0 and len(blowup.t) > 1 and np.all(np.isfinite(blowup.y))


def test_the_step_budget_stops_the_run() -> None:
    model = model_from(ROOT / "tests" / "numeric_audit" / "stiff_elastic_pendulum_r.yaml")
    problem, settings = _problem(model, 10.0, 11, 1e-10)
    small = integrators.Problem(problem.t0, problem.t_end, problem.y0, problem.ts, problem.p, False, 50)
    run = integrators.run_radau(compile.build(model, "numba"), small, 1e-10, settings.atol, progress=lambda done: None)  # returns to Python every 1% of the span
    assert run.status == Status.BUDGET and run.stats.steps >= 50 and run.t_last < 10.0


def test_simulate_through_the_command_line(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    result = runner.invoke(
        app, ["simulate", str(ROOT / "tests" / "numeric_audit" / "stiff_elastic_pendulum_r.yaml"), "--method", "Radau", "--backend", "compiled", "--rtol", "1e-6", "--samples", "11", "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert "Radau (compiled)" in result.output and "Jacobian" in result.output
    rows = out.read_text().splitlines()
    assert len(rows) == 12 and rows[0].startswith("t,r,theta")


METHODS_DOC = ROOT / "docs" / "methods.md"


@pytest.mark.parametrize("command", ["simulate", "sweep"])
@pytest.mark.parametrize("method", ["Radau", "BDF", "LSODA"])
def test_every_implicit_method_with_the_compiled_backend_runs_or_is_refused_as_documented(command: str, method: str) -> None:
    """Every command that takes --method and --backend: Radau runs compiled, BDF and LSODA exit 2 with the message
    docs/methods.md gives (the explicit pairs and the symplectic method run compiled: tests/test_simulate.py, test_symplectic.py)."""
    options = ["--method", method, "--backend", "compiled", "--t-end", "0.5", "--samples", "3"]
    extra = ["--initial", "theta=0.5..1:2", "--measure", "energy_error", "-q"] if command == "sweep" else []
    result = runner.invoke(app, [command, str(ROOT / "systems" / "simple_pendulum.yaml"), *options, *extra])
    if method in ("BDF", "LSODA"):
        assert result.exit_code == 2 and f"{method} runs through scipy" in result.output, result.output
        assert "runs through scipy; use --backend python (or auto), or --method Radau, which runs compiled too" in METHODS_DOC.read_text()
    else:
        assert result.exit_code == 0, result.output


def test_auto_backend_runs_radau_compiled_with_numba() -> None:
    model = model_from(ROOT / "systems" / "simple_pendulum.yaml")
    decided = policy.resolve(model, method="Radau", t_end=1.0)
    assert decided.backend == "compiled" and any("Radau runs compiled" in note for note in decided.notes), decided.notes
    with pytest.raises(LagrangeError, match="LSODA runs through scipy"):
        policy.resolve(model, method="LSODA", backend="compiled")
