"""The symplectic (Gauss-Legendre) method: no energy drift over long runs, stage equations solved to
round-off, compensated summation, a step chosen from an error estimate and a warning where the fixed
step does not control the error (issue 15). Everything is counted (steps, evaluations), never timed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lagrange_cli.model import Model
from lagrange_cli.numeric import compile, integrators, status
from lagrange_cli.numeric.simulate import simulate
from lagrange_cli.numeric.status import Status

from .conftest import ROOT
from .helpers import model_from, model_of

ECCENTRIC = {"theta_dot": math.sqrt(1.5)}
"""Kepler's problem (systems/kepler.yaml, m = k = 1) from r = 1 at pericentre: eccentricity 0.5."""

FREE = """
title: free particle
coordinates: [x]
parameters:
  m: {value: 1.0}
particles:
  body: {mass: m, position: [x]}
initial: {x: 0.0, x_dot: 0.1}
"""


def _kepler() -> Model:
    return model_from(ROOT / "systems" / "kepler.yaml")


def test_energy_error_does_not_drift_over_a_long_run() -> None:
    """Kepler e = 0.5 to t = 2000 at the coarse step 0.1 (20000 steps, ~64 steps an orbit): the mean
    energy error of the last tenth equals that of the first tenth. With the stages solved only to
    1e-11 (the old TOLERANCE) the mean drifts by about half its size over this run (-3.95e-8 to
    -1.99e-8), which this test rejects."""
    trajectory = simulate(_kepler(), method="symplectic", step=0.1, t_end=2000.0, samples=4001, initial=ECCENTRIC)
    assert trajectory.stats.steps == 20000 and trajectory.status == "finished"
    error = trajectory.energy - trajectory.energy[0]
    windows = np.array_split(error, 10)
    means = np.array([w.mean() for w in windows])
    amplitude = np.abs(error).max()
    assert amplitude > 1e-9  # the method's own (bounded) energy error is visible at this step
    slope = np.polyfit(np.arange(10), means, 1)[0]
    assert abs(means[-1] - means[0]) < 0.02 * amplitude, means
    assert abs(slope) * 10 < 0.02 * amplitude, (slope, amplitude)
    running = np.maximum.accumulate(np.abs(error))
    assert running[-1] <= 1.01 * running[len(running) // 10]  # the error's running maximum stays flat after the first tenth


def _one_step(model: Model, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, compile.Functions]:
    """One Gauss step (kernels.gauss_run called directly) from the model's initial state: z0, the
    stage derivatives FZ it converged to, the parameters and the loop's memory."""
    numba, python = compile.build(model, "numba"), compile.build(model, "python")
    kernels = numba.kernels
    assert kernels is not None
    entry = kernels.compiled("gauss_run")
    module = numba.module
    hamilton, event = module._hamilton, module._event
    hamilton.compile(kernels.HAMILTON_SIG.args)
    event.compile(kernels.EVENT_SIG.args)
    y0 = np.array([1.0, 0.0, 0.0, math.sqrt(1.5)])
    p = np.array([1.0, 1.0])
    z0 = np.concatenate([y0[:2], np.array(python.module._canonical(0.0, y0.tolist(), p.tolist()), dtype=float)])
    problem = integrators.Problem(0.0, h, y0, np.empty(0), p, False, 10)
    control = integrators._control(problem, module._SIZE, step=h, steps=1)
    state = integrators._state(0.0, 0.0, 1.0)
    stats = integrators._new_stats(h, h)
    memory, pivots = np.zeros(kernels.memory_size(2, 4)), np.zeros(8, dtype=np.int64)
    z = z0.copy()
    code = entry(2, z, state, control, np.empty(0), np.empty((0, 4)), p, stats, np.abs(z0), memory, pivots, hamilton, event)
    assert code == status.DONE and stats[status.NSTEPS] == 1
    return z0, memory[:8].reshape(2, 4).copy(), p, stats, numba


def test_stage_equations_are_solved_to_round_off_in_a_bounded_number_of_iterations() -> None:
    """After one step of 0.2 on an eccentric orbit, the stage equations F_i = F(z + h sum_j a_ij F_j)
    hold to a few ulps of F (with the old 1e-11 tolerance the residual is ~1e-12 of F), in at most
    MAX_ITERATIONS sweeps (counted: evaluations = 2 per sweep plus the Jacobian's)."""
    from lagrange_cli.numeric.tableaux import GAUSS

    h = 0.2
    z0, fz, p, stats, numba = _one_step(_kepler(), h)
    kernels = numba.kernels
    assert kernels is not None
    _, a, _ = GAUSS[2]
    size = numba.module._SIZE
    worst = 0.0
    for i in range(2):
        stage = z0 + h * sum(a[i][j] * fz[j] for j in range(2))
        out = np.empty(4)
        numba.module._hamilton(0.0 + h * GAUSS[2][0][i], stage, p, out, np.empty(size), np.empty((size, size)))
        worst = max(worst, float(np.max(np.abs(out - fz[i])) / np.max(np.abs(fz))))
    assert worst < 2e-15, worst
    # solved by fixed-point iteration (Kepler is not stiff): no Jacobian, 2 evaluations a sweep
    assert stats[status.NJEV] == 0 and stats[status.NFEV] % 2 == 0
    assert 1 <= stats[status.NFEV] / 2 <= kernels.MAX_ITERATIONS


def test_a_long_run_converges_every_step_to_round_off() -> None:
    """Every step of a run reaches the round-off level (the largest last correction at most STAGNATION)
    within MAX_ITERATIONS sweeps, and a converging step takes a handful of them."""
    model = _kepler()
    runs: list[integrators.Run] = []
    original = integrators.run_gauss

    def spy(*args: object, **kwargs: object) -> integrators.Run:
        run = original(*args, **kwargs)  # type: ignore[arg-type]
        runs.append(run)
        return run

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(integrators, "run_gauss", spy)
        trajectory = simulate(model, method="symplectic", step=0.05, t_end=200.0, samples=11, initial=ECCENTRIC)
    report = runs[-1].gauss
    assert report is not None and trajectory.status == "finished"
    numba = compile.build(model, "numba")
    assert numba.kernels is not None
    assert report.correction_max <= 4 * numba.kernels.ROUNDOFF or report.correction_max <= numba.kernels.STAGNATION
    assert report.iterations_max <= 20 and report.fallbacks == 0 and trajectory.stats.njev == 0  # fixed-point iteration, never Newton
    assert trajectory.stats.nfev / trajectory.stats.steps < 16  # about 6 sweeps of 2 stages a step


STIFF = """
title: stiff oscillator
coordinates: [x]
parameters:
  m: {value: 1.0}
  k: {value: 10000.0}
particles:
  body: {mass: m, position: [x]}
potential: k*x**2/2
initial: {x: 0.01, x_dot: 0.0}
"""


@pytest.mark.parametrize("stages", [2, 3])
def test_where_fixed_point_iteration_diverges_newton_takes_over(stages: int) -> None:
    """A stiff oscillator (omega = 100) at h = 0.05 (h omega = 5: fixed-point iteration diverges, the
    Gauss method is A-stable): each step that tries fixed-point iteration fails and is solved by
    Newton, which is then used for the next RETRY steps; so over 1000 steps exactly 1000 / RETRY
    fall back. The energy, a quadratic invariant of a linear system, is kept to round-off."""
    model = model_of(STIFF, "stiff.yaml")
    runs: list[integrators.Run] = []
    original = integrators.run_gauss

    def spy(*args: object, **kwargs: object) -> integrators.Run:
        run = original(*args, **kwargs)  # type: ignore[arg-type]
        runs.append(run)
        return run

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(integrators, "run_gauss", spy)
        trajectory = simulate(model, method="symplectic", step=0.05, stages=stages, t_end=50.0, samples=101)
    kernels = compile.build(model, "numba").kernels
    assert kernels is not None
    report = runs[-1].gauss
    assert report is not None and trajectory.status == "finished" and trajectory.stats.steps == 1000
    assert report.fallbacks == 1000 // kernels.RETRY and trajectory.stats.njev >= report.fallbacks
    energy = trajectory.energy
    assert np.max(np.abs(energy - energy[0])) < 1e-12 * abs(energy[0])


def test_compensated_summation_keeps_time_and_state_exact_over_a_million_steps() -> None:
    """A free particle (x' = 0.1, exactly, at every stage) over 10^6 steps of h = 1e-3 (not a binary
    fraction): the run ends at t = 1000 exactly and x = 100 to a few ulps. Summed without
    compensation, x collects 10^6 roundings (an error of ~1e-10)."""
    model = model_of(FREE, "free.yaml")
    trajectory = simulate(model, method="symplectic", step=1e-3, t_end=1000.0, t_eval=[250.0, 1000.0], max_steps=2_000_000)
    assert trajectory.stats.steps == 1_000_000 and trajectory.status == "finished"
    assert trajectory.t_last == 1000.0
    assert abs(trajectory.y_last[0] - 100.0) <= 4 * math.ulp(100.0), trajectory.y_last[0] - 100.0
    assert abs(trajectory.y[0, 0] - 25.0) <= 4 * math.ulp(100.0)


def _position_error(model: Model, trajectory: object, reference: object) -> float:
    n = len(model.coordinates)
    return float(np.max(np.abs(trajectory.y[:, :n] - reference.y[:, :n])))  # type: ignore[attr-defined]


@pytest.mark.parametrize("step", [None, 0.002, 0.005])
def test_through_the_pole_the_run_meets_the_accuracy_or_warns(step: float | None) -> None:
    """The spherical pendulum in (theta, phi) passing within 0.0074 of the pole (phi_dot ~ 210/s
    there): with the step chosen by the pilot the run meets rtol 1e-8 against a tight DOP853 reference;
    with a given step that does not resolve the passage (0.002: a 4e-3 error, which used to finish
    silently with exit 0) the run warns, typed, in its notes, or fails with a typed status."""
    model = model_from(ROOT / "systems" / "spherical_pendulum_near_pole.yaml")
    t_end = 2.5
    trajectory = simulate(model, method="symplectic", step=step, t_end=t_end, samples=101)
    reference = simulate(model, method="DOP853", rtol=1e-13, atol=1e-13, t_end=t_end, samples=101)
    if trajectory.failed:
        assert trajectory.outcome == Status.NO_CONVERGENCE and trajectory.warnings
        return
    error = _position_error(model, trajectory, reference)
    if step is None:
        assert error < 1e-7 and not trajectory.warnings, (error, trajectory.notes)
        assert any("pilot run" in note for note in trajectory.notes)
    else:
        assert error > 1e-4  # the step truly does not resolve the passage ...
        assert trajectory.warnings and trajectory.warnings[0].t < t_end  # ... and the run says so
        assert any("not controlled" in note and "--step" in note for note in trajectory.notes)


@pytest.mark.parametrize("name", ["kepler", "double_pendulum", "spherical_pendulum"])
def test_the_pilot_step_meets_the_accuracy_without_false_warnings(name: str) -> None:
    """On regular motions the pilot's step meets rtol (1e-8, positions against DOP853 at 1e-13, within
    a factor 10) and the monitor stays quiet."""
    model = model_from(ROOT / "systems" / f"{name}.yaml")
    trajectory = simulate(model, method="symplectic", t_end=10.0, samples=101)
    reference = simulate(model, method="DOP853", rtol=1e-13, atol=1e-13, t_end=10.0, samples=101)
    assert not trajectory.warnings, trajectory.notes
    assert _position_error(model, trajectory, reference) < 1e-7


def test_accuracy_measures_the_symplectic_method_with_the_step_simulate_chooses() -> None:
    """`accuracy` (and `stress`, through runs.measure) runs the symplectic method at the step
    `policy.decide` picks for `simulate` (the pilot run's), not at the pilot's unchecked first guess."""
    from lagrange_cli.numeric import policy
    from lagrange_cli.numeric.accuracy import study
    from lagrange_cli.numeric.runs import Candidate

    model = model_from(ROOT / "systems" / "kepler.yaml")
    tolerance, t_end = 1e-8, 10.0
    result = study(model, candidates=[Candidate("symplectic")], tolerances=[tolerance], t_end=t_end, samples=21, repeats=0)
    (point,) = result.points
    chosen = simulate(model, method="symplectic", rtol=tolerance, atol=tolerance * 1e-3, t_end=t_end, samples=21)
    guess = policy.symplectic_step(policy.initial_rate(model, chosen.settings), t_end, tolerance)
    assert chosen.settings.step is not None and chosen.settings.step != pytest.approx(guess)  # the pilot changed the guess: the test can tell them apart
    assert point.step == pytest.approx(chosen.settings.step, rel=1e-12)
    assert point.ok and point.max_error < 10 * tolerance


def test_every_method_runs_behind_one_solver_interface() -> None:
    """simulate's integrators share one interface (integrators.Solver, scipy's OdeSolver as the
    anchor): the solver of each decided method runs a Problem to a typed Run with named counters,
    and it is the run simulate reports."""
    from lagrange_cli.numeric import policy
    from lagrange_cli.numeric.settings import validate
    from lagrange_cli.numeric.simulate import solver_for

    model = model_from(ROOT / "systems" / "kepler.yaml")
    kinds = {("DOP853", "compiled"): integrators.ExplicitRK, ("symplectic", "compiled"): integrators.Gauss, ("Radau", "python"): integrators.Scipy}
    for (method, backend), kind in kinds.items():
        settings = policy.decide(model, validate(model, method=method, backend=backend, t_end=2.0, samples=5, rtol=1e-8, atol=1e-10))
        python = compile.build(model, "python", jacobian=method == "Radau")
        solver = solver_for(settings, python, compile.build(model, "numba") if backend == "compiled" else None)
        assert isinstance(solver, kind) and method in solver.name
        problem = integrators.Problem(0.0, 2.0, np.array(settings.y0), np.array(settings.t_eval), np.array(settings.p), False, 10**6)
        run = solver.run(problem)
        assert run.status == Status.FINISHED and isinstance(run.stats, integrators.Stats) and run.stats.steps > 0
        reported = simulate(model, method=method, backend=backend, t_end=2.0, samples=5, rtol=1e-8, atol=1e-10, step=settings.step, stages=settings.stages)
        assert np.array_equal(run.y, reported.y) and run.stats.steps == reported.stats.steps


@pytest.mark.parametrize(("stages", "step"), [(2, 0.1), (3, 0.2)])
def test_samples_between_steps_are_as_accurate_as_the_steps(stages: int, step: float) -> None:
    """Kepler e = 0.5 to t = 100: the samples midway between steps (each by a Gauss step from the step's
    start, kernels._gauss_sample) are within 2x the error of the samples at the steps themselves (the
    method's own; measured: within 0.5%), both against DOP853 at rtol 1e-13, and in energy. The cubic
    Hermite interpolant of one step put a 100x (s = 2) and 1e4x (s = 3) larger energy error mid-step,
    the degree-7 interpolant (kernels.NODES) still 200x at s = 3."""
    model = _kepler()
    t_end = 100.0
    at_steps = np.arange(1, 1000) * step
    at_steps = at_steps[at_steps < t_end - step]
    midway = at_steps + step / 2
    errors = {}
    for name, times in (("steps", at_steps), ("midway", midway)):
        run = simulate(model, method="symplectic", step=step, stages=stages, t_end=t_end, t_eval=times.tolist(), initial=ECCENTRIC)
        reference = simulate(model, method="DOP853", rtol=1e-13, atol=1e-15, t_end=t_end, t_eval=times.tolist(), initial=ECCENTRIC)
        energy = run.energy
        errors[name] = (_position_error(model, run, reference), float(np.max(np.abs(energy - energy[0]))))
    assert errors["steps"][0] > 1e-9  # the method's own error is visible at this step
    assert errors["midway"][0] <= 2 * errors["steps"][0], errors
    assert errors["midway"][1] <= 2 * errors["steps"][1], errors


def test_the_pilot_chooses_the_stage_count_that_costs_fewer_evaluations() -> None:
    """Kepler e = 0.5 to t = 1000 at rtol 1e-8: the pilot runs both Gauss methods (2 and 3 stages) and
    picks 3 stages at a step more than twice as long; the run at its choice meets the tolerance (positions
    against DOP853 at rtol 1e-13, within 10x) in fewer evaluations (counted) than the run the pilot
    chooses when held to 2 stages, and the notes say so. Bad stage counts are refused."""
    from lagrange_cli.errors import LagrangeError

    model = _kepler()
    t_end, rtol = 1000.0, 1e-8
    options = {"method": "symplectic", "rtol": rtol, "atol": rtol * 1e-3, "t_end": t_end, "samples": 201, "initial": ECCENTRIC}
    chosen = simulate(model, **options)  # type: ignore[arg-type]
    two = simulate(model, stages=2, **options)  # type: ignore[arg-type]
    reference = simulate(model, method="DOP853", rtol=1e-13, atol=1e-15, t_end=t_end, samples=201, initial=ECCENTRIC)
    assert chosen.settings.stages == 3 and two.settings.stages == 2
    assert chosen.settings.step is not None and two.settings.step is not None and chosen.settings.step > 2 * two.settings.step
    assert chosen.stats.nfev < two.stats.nfev, (chosen.stats.nfev, two.stats.nfev)
    scale = np.max(np.abs(reference.y[:, :2]), axis=0)
    for run in (chosen, two):
        assert np.max(np.abs(run.y[:, :2] - reference.y[:, :2]) / (rtol * scale + rtol * 1e-3)) < 10.0
        assert not run.warnings
    assert any("3 stages (order 6)" in note and "2 stages, 3 stages" in note for note in chosen.notes), chosen.notes
    for bad in (0, 4, True):
        with pytest.raises(LagrangeError, match="stages must be 1, 2 or 3"):
            simulate(model, method="symplectic", stages=bad, t_end=1.0)
