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
from lagrange_cli.numeric import compile, integrators, policy, status, tableaux
from lagrange_cli.numeric.simulate import simulate
from lagrange_cli.numeric.status import Status

from .conftest import ROOT
from .helpers import damped_stiff_spring, model_from, model_of

runner = CliRunner()
# the shared cache (no private_cache): radau_run compiles once per machine (20-40 s), not once per test run

SPRING = damped_stiff_spring(k=1.0e8, c=2.0e4)
"""x decays at about k / c = 5e3/s and c = 2e4/s (stiffness ratio 1e4 against y's swing at 1 rad/s): linear, so exactly solvable."""


def _problem(model, t_end: float, samples: int, rtol: float, **options: object) -> tuple[integrators.Problem, object]:
    settings = policy.validate(model, method="DOP853", backend="compiled", t_end=t_end, samples=samples, rtol=rtol, **options)
    problem = integrators.Problem(0.0, t_end, np.array(settings.y0), np.array(settings.t_eval), np.array(settings.p), False, 10**6)
    return problem, settings


def _error(y: np.ndarray, reference: np.ndarray, rtol: float, atol: float) -> float:
    """The largest error over the samples, in units of the tolerance (atol + rtol |y|)."""
    return float(np.max(np.abs(y - reference) / (atol + rtol * np.abs(reference))))


def _compare(model, t_end: float, rtol: float, reference: np.ndarray | None = None, samples: int = 21, analytic: bool = True) -> tuple[integrators.Run, integrators.Run, float, float]:
    """Compiled Radau (with the analytic Jacobian, or by differences) and scipy's against `reference` (default: compiled DOP853 at rtol 1e-13)."""
    problem, settings = _problem(model, t_end, samples, rtol)
    numba, python = compile.build(model, "numba", jacobian=analytic), compile.build(model, "python", jacobian=True)
    assert hasattr(numba.module, "_jac") == analytic
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


def test_the_lu_factors_solve_real_and_complex_systems() -> None:
    """kernels._lu_factor / _lu_back against numpy, on matrices whose pivoting swaps rows at several steps."""
    kernels = compile.kernels_module()
    rng = np.random.default_rng(7)
    for n in (1, 2, 4, 7):
        for dtype in (np.float64, np.complex128):
            a = rng.normal(size=(n, n)) + (1j * rng.normal(size=(n, n)) if dtype == np.complex128 else 0)
            a[np.arange(n), np.arange(n)] *= 1e-3  # small diagonal: pivoting needed
            b = rng.normal(size=n).astype(dtype)
            factors, pivots, x = a.astype(dtype).copy(), np.empty(n, dtype=np.int64), b.copy()
            assert kernels._lu_factor(factors, pivots) == 0
            kernels._lu_back(factors, pivots, x)
            assert np.allclose(x, np.linalg.solve(a, b), rtol=1e-10, atol=1e-12), (n, dtype)
    assert kernels._lu_factor(np.zeros((2, 2)), np.empty(2, dtype=np.int64)) == 1


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


@pytest.mark.parametrize(("rtol", "analytic"), [(1e-6, True), (1e-8, True), (1e-10, True), (1e-6, False)])
def test_the_stiff_elastic_pendulum_against_a_tight_reference(rtol: float, analytic: bool) -> None:
    """k = 1e10, decay 2e6/s against a swing of 3 rad/s; the reference is compiled DOP853 at rtol 1e-13 (to t = 0.2).
    Without the analytic Jacobian (a module built without it) the loop takes forward differences. The generated code
    evaluates the spring's force as k (l - r) (printer.restructure's offsets): as k l - k r it carried round-off of a
    spacing of 1e10, which the Newton iterations met at rtol 1e-8 and 1e-10, where scipy's Radau with the exact Jacobian
    took 11371 and 6611 steps on an AMD EPYC (54 and 83 for the compiled Radau); now both take about as many steps."""
    model = model_from(ROOT / "tests" / "numeric_audit" / "stiff_elastic_pendulum_r.yaml")
    ours, theirs, error, scipy_error = _compare(model, 0.2, rtol, analytic=analytic)
    assert error < 10.0 and error < 5.0 * max(scipy_error, 1.0), (error, scipy_error)
    assert abs(ours.stats.steps - theirs.stats.steps) <= 0.3 * theirs.stats.steps, (ours.stats, theirs.stats)
    if analytic:
        assert ours.stats.njev <= theirs.stats.njev + 2, (ours.stats, theirs.stats)


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
    numba = compile.build(model, "numba", jacobian=True)
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
    run = integrators.run_radau(compile.build(model, "numba", jacobian=True), small, 1e-10, settings.atol, progress=lambda done: None)  # returns to Python every 1% of the span
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


def test_auto_runs_compiled_radau_where_lsoda_ran_out_of_budget() -> None:
    """Audit 6 F3: the angle-damped spring pendulum started at r = 0.011 (decay 8e6/s): `auto` took LSODA,
    which stopped at its step budget at 34% of the span; now it takes compiled Radau, which finishes, and
    agrees with compiled Radau at rtol 1e-11 to well within 1e-6 of each component's size."""
    model = model_from(ROOT / "tests" / "numeric_audit6" / "spring_pendulum_angle_damper.yaml")
    auto = simulate(model, method="auto", initial={"r": 0.011}, samples=101)
    assert (auto.settings.method, auto.settings.backend, auto.status) == ("Radau", "compiled", "finished"), auto.notes
    tight = simulate(model, method="Radau", backend="compiled", initial={"r": 0.011}, samples=101, rtol=1e-11, atol=1e-14)
    assert tight.status == "finished"
    size = np.max(np.abs(tight.y), axis=0)
    assert np.max(np.abs(auto.y - tight.y) / size) < 1e-6


def test_a_long_jacobian_generated_as_loops_over_tables_gives_the_same_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """A system whose `_jac` exceeds emit.python.SPLIT statements is generated as loops over tables
    (`vectorize`); forced here on the double pendulum, the run is the same, step for step."""
    from lagrange_cli.emit import python as emit_python

    runs = []
    for split in (emit_python.SPLIT, 3):
        monkeypatch.setattr(emit_python, "SPLIT", split)
        model = model_from(ROOT / "systems" / "double_pendulum.yaml")
        problem, _ = _problem(model, 2.0, 11, 1e-8)
        numba = compile.build(model, "numba", jacobian=True)
        assert ("_jac_T" in numba.path.read_text()) == (split == 3)
        runs.append(integrators.run_radau(numba, problem, 1e-8, 1e-10))
    assert runs[0].stats == runs[1].stats and np.array_equal(runs[0].y, runs[1].y)


@pytest.mark.parametrize("name", ["pendulum_multiplier", "arm_3dof"])
def test_the_steps_are_scipys_on_a_kept_constraint_and_a_three_link_arm(name: str) -> None:
    """The same decisions as scipy's Radau: with the analytic Jacobian, the same steps and Jacobians (kept
    constraints: the Baumgarte-stabilised equations, projected at the samples on both backends)."""
    model = model_from(ROOT / "systems" / f"{name}.yaml")
    ours = simulate(model, method="Radau", backend="compiled", t_end=2.0, samples=5)
    theirs = simulate(model, method="Radau", backend="python", t_end=2.0, samples=5)
    assert ours.status == theirs.status == "finished"
    assert abs(ours.stats.steps - theirs.stats.steps) <= 0.05 * theirs.stats.steps and abs(ours.stats.njev - theirs.stats.njev) <= 2, (ours.stats, theirs.stats)
    assert np.max(np.abs(ours.y - theirs.y)) < 1e-6 * max(1.0, float(np.max(np.abs(theirs.y))))


def _stretch(control: np.ndarray) -> np.ndarray:
    """A compiled loop's controls set to pause after every step attempt."""
    control[status.STRETCH] = 1.0
    return control


def test_the_crossings_are_landed_on_as_scipys_radau_does_and_a_pause_changes_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    """kernels.radau_switched on the bouncing mass (a one-sided spring written with Abs; rtol 1e-8): the 6
    crossings that scipy's Radau (integrators.run_scipy, located by brentq) lands on, within 5% of its steps
    (measured 357 and 354); paused at each 1% of the span a step passes (progress reports, PROGRESS_PERIOD 0:
    16 returns to Python), or after every step attempt (control STRETCH 1: also between a step discarded
    at a crossing and the step landing on it, the record carrying it), the same run, step for step."""
    model = model_from(ROOT / "tests" / "nonsmooth" / "bouncing_mass.yaml")
    problem, _ = _problem(model, 3.0, 31, 1e-8)
    numba = compile.build(model, "numba", jacobian=True)
    ours = integrators.run_radau(numba, problem, 1e-8, 1e-11)
    monkeypatch.setattr(integrators, "PROGRESS_PERIOD", 0.0)
    reports: list[float] = []
    paused = integrators.run_radau(numba, problem, 1e-8, 1e-11, progress=reports.append)
    control = integrators._control
    monkeypatch.setattr(integrators, "_control", lambda *args, **options: _stretch(control(*args, **options)))
    every = integrators.run_radau(numba, problem, 1e-8, 1e-11)
    monkeypatch.setattr(integrators, "_control", control)
    theirs = integrators.run_scipy(compile.build(model, "python", jacobian=True), problem, "Radau", 1e-8, 1e-11, math.inf)
    assert ours.status == theirs.status == Status.FINISHED
    assert ours.switching == theirs.switching == (1, 6), (ours.switching, theirs.switching)
    assert abs(ours.stats.steps - theirs.stats.steps) <= 0.05 * theirs.stats.steps, (ours.stats, theirs.stats)
    for run in (paused, every):
        assert run.stats == ours.stats and run.switching == ours.switching and np.array_equal(run.y, ours.y)
    assert len(reports) >= 10
    assert np.max(np.abs(ours.y - theirs.y)) < 1e-6
