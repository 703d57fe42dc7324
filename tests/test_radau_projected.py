"""Issue 15: compiled Radau projected onto kept constraints inside its loop (kernels.radau_projected).

Counted, never timed: one compiled start and one call of the loop per run (no Python stretches), one
projection per projection time crossed, a projected state as erk_projected leaves it (the same `_project`:
the constraint residuals at round-off after each projection), no projection time but t_end gives radau_run's
steps bit for bit, the multiplier pendulum meets its exact solution, and the studies measure compiled Radau
on systems with kept constraints.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from lagrange_cli.numeric import compile, integrators, policy, projection, runs, status
from lagrange_cli.numeric.simulate import InvariantKind, simulate
from tests.conftest import ROOT
from tests.helpers import model_from
from tests.test_projection import exact_angle

# the shared cache (no private_cache), as test_radau_compiled: the Radau entry points compile once per machine


@pytest.fixture(scope="module")
def pendulum():  # type: ignore[no-untyped-def]
    return model_from(ROOT / "systems" / "pendulum_multiplier.yaml")


def _problem(model, t_end: float, ts: np.ndarray, max_steps: int = 10**6) -> integrators.Problem:  # type: ignore[no-untyped-def]
    settings = policy.resolve(model, t_end=t_end, method="Radau", backend="compiled")
    return integrators.Problem(0.0, t_end, np.array(settings.y0, dtype=float), ts, np.array(settings.p, dtype=float), False, max_steps)


def _residuals(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rod's residuals x^2 + y^2 - 1 (positions) and x x_dot + y y_dot (velocities) at each state."""
    return y[:, 0] ** 2 + y[:, 1] ** 2 - 1.0, y[:, 0] * y[:, 2] + y[:, 1] * y[:, 3]


def test_a_projected_compiled_radau_run_is_one_run_projected_at_each_sample(pendulum, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    """simulate with compiled Radau: one start, one call of radau_projected (fewer steps than PAUSE_STEPS), no
    radau_run, one projection per sample time after the start (the note says how many), the rod at round-off; the
    Jacobian by differences, from the module the explicit pairs use."""
    calls: dict[str, int] = {}
    given: dict[str, list[str]] = {}
    real = integrators._compile

    def counted(functions, kernel, pieces):  # type: ignore[no-untyped-def]
        entry, compiled, seconds = real(functions, kernel, pieces)
        given[kernel] = [name for name, _ in pieces]

        def wrapped(*args):  # type: ignore[no-untyped-def]
            calls[kernel] = calls.get(kernel, 0) + 1
            return entry(*args)

        return wrapped, compiled, seconds

    monkeypatch.setattr(integrators, "_compile", counted)
    samples = 101
    run = simulate(pendulum, t_end=5.0, method="Radau", backend="compiled", rtol=1e-6, samples=samples)
    assert run.status == "finished", run.message
    assert run.stats.steps < status.PAUSE_STEPS
    assert calls.get("radau_start") == 1 and calls.get("radau_projected") == 1 and "radau_run" not in calls and "radau_switched" not in calls, calls
    assert "_jac" not in given["radau_projected"]  # the Jacobian by differences: no second compiled module beside the explicit pairs' (simulate._integrated)
    note = next(n for n in run.notes if n.startswith("projection onto the kept constraints and the energy level"))
    assert int(re.search(r"at each of (\d+) sample times, inside the compiled loop", note).group(1)) == samples - 1, note  # type: ignore[union-attr]
    assert "Radau restarts there" in note, note
    constraint = run.invariant(InvariantKind.CONSTRAINT)
    assert constraint is not None and constraint.max_change < 1e-14
    assert len(run.t) == samples and run.t[-1] == 5.0


def test_the_projections_counted_are_the_bounds_crossed(pendulum) -> None:  # type: ignore[no-untyped-def]
    """record[PROJECTIONS] is the number of projection times reached, whether the run finishes (all of them,
    bounds that are not samples too) or stops at its step budget part way (those before where it stopped)."""
    numba = compile.build(pendulum, "numba", jacobian=True)
    ts = np.linspace(0.0, 5.0, 11)
    bounds = np.linspace(0.05, 5.0, 100)  # 100 projection times, 10 samples among them
    found = projection.record(None)
    run = integrators.run_radau_projected(numba, _problem(pendulum, 5.0, ts), 1e-4, 1e-7, math.inf, bounds, projection.holonomic_rows(pendulum), found)
    assert run.status == "finished" and run.t_last == 5.0
    assert int(found[status.PROJECTIONS]) == 100 == int(found[status.NEXT_BOUND]) and int(found[status.FAILURES]) == 0 and math.isnan(found[status.FAILED_AT])
    assert run.stats.steps >= 100  # a step ends on each
    assert found[status.POSITION] > 1e-12  # at rtol 1e-4 the drift between two projections is real, and was corrected
    x, y = run.y_last[0], run.y_last[1]
    assert abs(x * x + y * y - 1.0) < 1e-15  # projected at t_end
    # a run stopped part way (its stop condition x = 0, the pendulum's first pass under the pivot): the sample times before the stop
    stopped = simulate(pendulum, t_end=5.0, method="Radau", backend="compiled", rtol=1e-6, samples=101, until="x")
    assert stopped.status == "event" and 0.0 < stopped.t[-1] < 5.0, (stopped.status, stopped.t[-1:])
    crossed = int(np.count_nonzero((np.linspace(0.0, 5.0, 101) > 0.0) & (np.linspace(0.0, 5.0, 101) <= stopped.t[-1])))
    note = next(n for n in stopped.notes if n.startswith("projection onto the kept constraints"))
    assert crossed > 0 and int(re.search(r"at each of (\d+) sample times", note).group(1)) == crossed, (crossed, note)  # type: ignore[union-attr]


def test_radau_and_the_explicit_pair_leave_the_same_residuals_after_a_projection(pendulum) -> None:  # type: ignore[no-untyped-def]
    """The same projection routine (`_project`) after each landing: compiled Radau's and DOP853's samples
    (each one a projected state) keep the rod's position and velocity residuals at round-off, the two runs
    agreeing on them to round-off, though both corrected real drift."""
    numba = compile.build(pendulum, "numba", jacobian=True)
    ts = np.linspace(0.0, 5.0, 51)
    bounds = ts[1:].copy()
    problem = _problem(pendulum, 5.0, ts)
    radau_record, erk_record = projection.record(None), projection.record(None)
    holonomic = projection.holonomic_rows(pendulum)
    radau = integrators.run_radau_projected(numba, problem, 1e-5, 1e-8, math.inf, bounds, holonomic, radau_record)
    erk = integrators.run_erk_projected(numba, problem, "DOP853", 1e-5, 1e-8, math.inf, bounds, holonomic, erk_record)
    assert radau.status == erk.status == "finished"
    assert int(radau_record[status.PROJECTIONS]) == int(erk_record[status.PROJECTIONS]) == 50
    assert radau_record[status.POSITION] > 1e-13 and erk_record[status.POSITION] > 1e-13  # both had drift to correct
    eps = float(np.finfo(float).eps)
    for ours, theirs in zip(_residuals(radau.y), _residuals(erk.y), strict=True):
        assert float(np.max(np.abs(ours))) <= 8 * eps and float(np.max(np.abs(theirs))) <= 8 * eps, (np.max(np.abs(ours)), np.max(np.abs(theirs)))
        assert float(np.max(np.abs(ours - theirs))) <= 16 * eps
    assert float(np.max(np.abs(radau.y - erk.y))) < 1e-3  # the same motion (each to its own rtol)


def test_with_no_projection_time_before_t_end_the_steps_are_radau_runs(pendulum) -> None:  # type: ignore[no-untyped-def]
    """bounds = [t_end]: radau_projected lands where radau_run ends anyway and projects only there, so every
    step, count and sample before t_end is radau_run's bit for bit (the shared loop is unchanged without a
    projection time), and only the state at t_end is the projected one."""
    numba = compile.build(pendulum, "numba", jacobian=True)
    ts = np.linspace(0.0, 3.0, 31)
    problem = _problem(pendulum, 3.0, ts)
    plain = integrators.run_radau(numba, problem, 1e-6, 1e-9)
    found = projection.record(None)
    projected = integrators.run_radau_projected(numba, problem, 1e-6, 1e-9, math.inf, np.array([3.0]), projection.holonomic_rows(pendulum), found)
    assert plain.status == projected.status == "finished"
    assert plain.stats == projected.stats
    assert np.array_equal(plain.t, projected.t) and np.array_equal(plain.y[:-1], projected.y[:-1])
    assert int(found[status.PROJECTIONS]) == 1 and found[status.MOVED] > 0.0
    assert np.array_equal(projected.y[-1], projected.y_last) and not np.array_equal(plain.y_last, projected.y_last)


def test_compiled_radau_meets_the_multiplier_pendulums_exact_solution(pendulum) -> None:  # type: ignore[no-untyped-def]
    """To t = 100 at rtol 1e-9: compiled Radau projected meets 1e-6 against the exact pendulum, the rod at round-off."""
    run = simulate(pendulum, t_end=100.0, method="Radau", backend="compiled", rtol=1e-9, atol=1e-12, samples=101)
    assert run.status == "finished", run.message
    theta = exact_angle(run.t)
    exact = np.column_stack([np.sin(theta), -np.cos(theta)])
    assert float(np.max(np.abs(run.y[:, :2] - exact))) < 1e-6
    constraint = run.invariant(InvariantKind.CONSTRAINT)
    assert constraint is not None and constraint.max_change < 1e-14


def test_the_studies_measure_compiled_radau_with_kept_constraints(pendulum) -> None:  # type: ignore[no-untyped-def]
    """`stress` and `accuracy` try Radau compiled on a system with kept constraints (scipy's only as `Radau:python`)."""
    radau = next(c for c in runs.default_candidates(pendulum) if c.method == "Radau")
    assert runs.backend_for(radau) == ("compiled" if runs.compiled_radau() else "python")
    assert runs.backend_for(runs.parse_candidate("Radau:python")) == "python"
