"""Issue 15: projection onto kept constraints inside the compiled loop (kernels.erk_projected).

Counted, never timed: a projected compiled run is one compiled run (one start, one call of the loop
below PAUSE_STEPS steps), it projects once at each sample time, the compiled projection of one state
agrees with `projection.Projector` to round-off, and the run keeps the constraint at round-off and
meets the accuracy against the exact solution, as the scipy backend's stretch-by-stretch projection does.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from lagrange_cli.numeric import compile, integrators, projection, status
from lagrange_cli.numeric.projection import Projector
from lagrange_cli.numeric.settings import Settings
from lagrange_cli.numeric.simulate import InvariantKind, simulate
from tests.conftest import ROOT
from tests.helpers import model_from
from tests.test_projection import exact_angle

pytestmark = pytest.mark.usefixtures("private_cache")


@pytest.fixture(scope="module")
def pendulum():  # type: ignore[no-untyped-def]
    return model_from(ROOT / "systems" / "pendulum_multiplier.yaml")


def _parameters(model, settings: Settings) -> np.ndarray:  # type: ignore[no-untyped-def]
    return np.array(settings.p, dtype=float)


def test_a_projected_compiled_run_is_one_run_projected_at_each_sample(pendulum, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    """One start (no restart per stretch), one call of the compiled loop (fewer steps than PAUSE_STEPS),
    and one projection per sample time after the start (the last one at t_end)."""
    calls: dict[str, int] = {}
    real = integrators._compile

    def counted(functions, kernel, pieces):  # type: ignore[no-untyped-def]
        entry, compiled, seconds = real(functions, kernel, pieces)

        def wrapped(*args):  # type: ignore[no-untyped-def]
            calls[kernel] = calls.get(kernel, 0) + 1
            return entry(*args)

        return wrapped, compiled, seconds

    monkeypatch.setattr(integrators, "_compile", counted)
    samples = 201
    run = simulate(pendulum, t_end=20.0, method="DOP853", backend="compiled", rtol=1e-9, atol=1e-12, samples=samples)
    assert run.status == "finished", run.message
    assert run.stats.steps < status.PAUSE_STEPS
    assert calls.get("erk_start") == 1 and calls.get("erk_projected") == 1 and "erk_run" not in calls, calls
    note = next(n for n in run.notes if n.startswith("projection onto the kept constraints and the energy level"))
    assert int(re.search(r"at each of (\d+) sample times, inside the compiled loop", note).group(1)) == samples - 1, note  # type: ignore[union-attr]
    constraint = run.invariant(InvariantKind.CONSTRAINT)
    assert constraint is not None and constraint.max_change < 1e-14  # every sample after the start is a projected state
    assert len(run.t) == samples and run.t[-1] == 20.0


def test_the_loop_records_its_projections_and_lands_a_step_on_each_time(pendulum) -> None:  # type: ignore[no-untyped-def]
    """The record counts one projection per bound; a step ends exactly on each (so there are at least
    as many steps as bounds), and a bound that is not a sample is projected too."""
    settings = _settings(pendulum)
    numba = compile.build(pendulum, "numba")
    ts = np.linspace(0.0, 5.0, 11)
    problem = integrators.Problem(0.0, 5.0, np.array(settings.y0, dtype=float), ts, _parameters(pendulum, settings), False, 10**6)
    bounds = np.linspace(0.05, 5.0, 100)  # 100 projections, 10 samples inside
    found = projection.record(None)
    run = integrators.run_erk_projected(numba, problem, "DOP853", 1e-3, 1e-6, math.inf, bounds, projection.holonomic_rows(pendulum), found)
    assert run.status == "finished" and run.t_last == 5.0
    assert int(found[status.PROJECTIONS]) == 100 and int(found[status.FAILURES]) == 0 and math.isnan(found[status.FAILED_AT])
    assert run.stats.steps >= 100
    x, y = run.y_last[0], run.y_last[1]
    assert abs(x * x + y * y - 1.0) < 1e-15  # projected at t_end
    assert found[status.POSITION] > 1e-12  # at rtol 1e-3 the drift between two projections is real, and was corrected


def _settings(model) -> Settings:  # type: ignore[no-untyped-def]
    from lagrange_cli.numeric.policy import resolve

    return resolve(model, t_end=1.0, method="DOP853", backend="compiled")


@pytest.mark.parametrize(
    ("name", "state", "with_level"),
    [
        ("pendulum_multiplier", [math.sin(0.7) + 3e-6, -math.cos(0.7) - 2e-6, 1.3 * math.cos(0.7) + 4e-6, 1.3 * math.sin(0.7) + 1e-6], True),
        ("pendulum_multiplier", [math.sin(0.7) + 3e-6, -math.cos(0.7) - 2e-6, 1.3 * math.cos(0.7) + 4e-6, 1.3 * math.sin(0.7) + 1e-6], False),
        ("chaplygin_sleigh", [0.1, 0.2, 0.3, 0.5, 0.7, 2.0], False),
        ("rolling_disk_pendulum_multiplier", [0.015 + 1e-6, 0.03, 0.4, 0.45 + 2e-6, 0.9, 1.1], True),  # s = R phi and s_dot = R phi_dot both off
    ],
)
def test_the_compiled_projection_of_a_state_agrees_with_the_projector(name: str, state: list[float], with_level: bool) -> None:
    """kernels.project_state (what the loop does at each projection time) against projection.Projector:
    the same state to round-off, the same corrections."""
    model = model_from(ROOT / "systems" / f"{name}.yaml")
    settings = _settings(model)
    p = _parameters(model, settings)
    numba, python = compile.build(model, "numba"), compile.build(model, "python")
    y = np.array(state, dtype=float)
    level = None
    energy = None
    if with_level:
        level = float(python.module._energy(0.0, y.tolist(), p.tolist())) * (1 + 1e-7)

        def energy(t: float, z: np.ndarray) -> float:
            return float(python.module._energy(t, z.tolist(), p.tolist()))

    expected, correction = Projector(model, settings.values, energy, level).project(0.0, y)
    found = projection.record(level)
    got = integrators.project_compiled(numba, 0.0, y, p, projection.holonomic_rows(model), found)
    assert got is not None
    assert np.max(np.abs(got - expected)) <= 1e-14 * max(1.0, float(np.max(np.abs(expected)))), (got, expected)
    compiled = projection.correction(found)
    for field in ("position", "velocity", "moved", "energy"):
        a, b = getattr(compiled, field), getattr(correction, field)
        assert abs(a - b) <= 1e-9 * max(abs(b), 1e-300) + 1e-16, (field, a, b)
    if with_level:
        assert compiled.energy > 0.0  # the level was off by 1e-7 relative, and was corrected
    assert compiled.moved > 1e-7


def test_a_compiled_projected_run_meets_the_accuracy_as_the_python_one_does(pendulum) -> None:  # type: ignore[no-untyped-def]
    """The multiplier pendulum to t = 100 against its exact solution: compiled and scipy backends, both
    projected, keep the rod at round-off and meet 1e-6 (without projection the residual drifts)."""
    runs = {backend: simulate(pendulum, t_end=100.0, method="DOP853", rtol=1e-8, atol=1e-10, samples=101, backend=backend) for backend in ("compiled", "python")}
    theta = exact_angle(runs["compiled"].t)
    exact = np.column_stack([np.sin(theta), -np.cos(theta)])
    for backend, run in runs.items():
        assert run.status == "finished", (backend, run.message)
        constraint = run.invariant(InvariantKind.CONSTRAINT)
        assert constraint is not None and constraint.max_change < 1e-14, backend
        assert float(np.max(np.abs(run.y[:, :2] - exact))) < 1e-6, backend
    free = simulate(pendulum, t_end=100.0, method="DOP853", rtol=1e-8, atol=1e-10, samples=101, backend="compiled", projection=False)
    residual = free.invariant(InvariantKind.CONSTRAINT)
    assert residual is not None and residual.max_change > 1e-10


def test_a_projection_that_cannot_be_applied_is_refused(pendulum) -> None:  # type: ignore[no-untyped-def]
    """A zero mass makes M singular: the compiled projection says so (the loop then keeps the state as
    it was and counts it in record[FAILURES]) instead of returning non-finite values."""
    settings = _settings(pendulum)
    numba = compile.build(pendulum, "numba")
    p = _parameters(pendulum, settings).copy()
    found = projection.record(None)
    y = np.array([math.sin(0.7), -math.cos(0.7), 0.0, 0.0])
    names = [par.name for par in pendulum.parameters]
    p[names.index("m")] = 0.0
    assert integrators.project_compiled(numba, 0.0, y, p, projection.holonomic_rows(pendulum), found) is None
