"""Issue 15, `stress` within 30 s (session 20): the per-sample work done at once. The invariants along each run's samples (energy,
momenta, constraint residuals) took 5 us a sample through `integrators.evaluate`, a fifth of `stress`'s time on
Kepler's orbit of e = 0.99; cond M along the reference one SVD a sample. Both are now evaluated for all samples at
once, with the same values, and the samples one at a time still say where and why a value is bad. Also: a reference
confirmed by its own convergence before a looser second method, scipy's RK45 not run where its compiled twin shows it
cannot finish, and a compiled run stopped next to a sliding surface called that."""

from __future__ import annotations

import importlib
import math
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lagrange_cli.errors import LagrangeError
from lagrange_cli.numeric import compile, diagnostics, integrators, reference, settings, stress
from lagrange_cli.numeric import runs as runs_module
from lagrange_cli.numeric.runs import PointStatus, Setup, component_scale, run
from lagrange_cli.numeric.simulate import simulate
from lagrange_cli.numeric.status import Status
from lagrange_cli.numeric.stress import implicit_reference_tolerances

from .conftest import ROOT
from .helpers import model_from
from .test_budget17 import _counting

DOUBLE = ROOT / "systems" / "double_pendulum.yaml"
simulate_module = importlib.import_module("lagrange_cli.numeric.simulate")
OSCILLATORS = ROOT / "tests" / "numeric_audit7" / "coupled_oscillators_weak_damping_t1e5.yaml"


def _one_at_a_time(function: object, t: np.ndarray, y: np.ndarray, p: list[float]) -> np.ndarray:
    return np.array([integrators.evaluate(function, float(tk), yk.tolist(), p, "x") for tk, yk in zip(t, y, strict=True)])  # type: ignore[arg-type]


def test_invariants_at_once_equal_those_one_sample_at_a_time() -> None:
    """The double pendulum's energy (sin and cos) and canonical momenta along a run: the same numbers either way (math's
    own functions at each element; the arithmetic is IEEE's in both)."""
    model = model_from(DOUBLE)
    trajectory = simulate(model, t_end=3.0, samples=301, backend="python")
    module = compile.build(model.with_definitions(), "python").module
    p = list(trajectory.settings.p)
    for function in (module._energy, module._canonical):
        at_once = integrators.evaluate_samples(function, trajectory.t, trajectory.y, p)
        assert at_once is not None
        assert np.array_equal(at_once, _one_at_a_time(function, trajectory.t, trajectory.y, p))
    energy = trajectory.invariants[0]
    assert energy.kind is not None and energy.kind.name == "ENERGY" and energy.initial == float(_one_at_a_time(module._energy, trajectory.t[:1], trajectory.y[:1], p)[0, 0])


def _system(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "system.yaml"
    path.write_text(text)
    return path


def test_a_branch_on_a_value_is_evaluated_one_sample_at_a_time(tmp_path: Path) -> None:
    """sign(v) prints as a conditional, which an array cannot decide: None, and the samples go one at a time."""
    path = _system(
        tmp_path,
        "coordinates: [x]\nparameters: {m: 1, k: 3, f: 0.2}\nkinetic: m*x_dot**2/2\npotential: k*x**2/2 + f*x*sign(x)\ninitial: {x: 1}\nsimulate: {t_end: 1}\n",
    )
    model = model_from(path)
    module = compile.build(model.with_definitions(), "python").module
    t = np.linspace(0.0, 1.0, 5)
    y = np.array([[0.5 - 0.25 * k, 0.1] for k in range(5)])
    assert integrators.evaluate_samples(module._energy, t, y, [1.0, 3.0, 0.2]) is None
    trajectory = simulate(model, backend="python", samples=51)
    assert trajectory.status == "finished" and math.isfinite(trajectory.invariants[0].max_change)


def test_a_value_outside_its_domain_still_ends_the_run_where_it_is_met(tmp_path: Path) -> None:
    """sqrt of a negative number: at once it is NaN (None: not finite), and one sample at a time names the sample,
    as before: the run fails at the first sample where the energy cannot be evaluated."""
    path = _system(
        tmp_path,
        "coordinates: [x]\nparameters: {m: 1}\nkinetic: m*x_dot**2/2\npotential: -sqrt(1 - x)\ninitial: {x: 0, x_dot: 0.5}\nsimulate: {t_end: 4}\n",
    )
    model = model_from(path)
    module = compile.build(model.with_definitions(), "python").module
    t = np.array([0.0, 1.0])
    y = np.array([[0.0, 0.5], [2.0, 0.5]])
    assert integrators.evaluate_samples(module._energy, t, y, [1.0]) is None
    with pytest.raises(integrators.EvaluationError):
        integrators.evaluate(module._energy, 1.0, [2.0, 0.5], [1.0], "the energy")


def test_cond_m_at_once_equals_one_state_at_a_time() -> None:
    """`MassCondition.many` (one batched SVD) gives each state's cond M as a call for that state does, inf where M is singular."""
    model = model_from(DOUBLE).with_definitions()
    values = [1.0, 1.0, 1.0, 1.0, 9.81]
    condition = diagnostics.mass_condition(model, values, [0.3, -0.2, 0.0, 0.0])
    rng = np.random.default_rng(7)
    y = rng.uniform(-3, 3, size=(40, 4))
    t = np.linspace(0.0, 1.0, 40)
    many = condition.many(t, y)
    single = np.array([condition(float(tk), yk) for tk, yk in zip(t, y, strict=True)])
    assert np.array_equal(many, single) and np.all(np.isfinite(many))
    direct = np.linalg.cond(np.array(diagnostics.mass_at(model, values)(0.0, y[3])))
    assert many[3] == pytest.approx(direct, rel=1e-12)


def test_sample_times_are_checked_as_before() -> None:
    """t_eval converted at once where every time is a finite number; a bad one is still named."""
    assert settings._finite_times((0.0, 0.5, 1)) == [0.0, 0.5, 1.0]
    assert settings._finite_times(np.linspace(0.0, 1.0, 3)) == [0.0, 0.5, 1.0]  # type: ignore[arg-type]
    for bad in ((0.0, math.nan), (0.0, "later"), (0.0, math.inf)):
        with pytest.raises(LagrangeError, match="a time of t_eval must be a"):
            settings._finite_times(bad)  # type: ignore[arg-type]


@pytest.mark.skipif(not compile.numba_available(), reason="compiled explicit reference runs")
def test_stress_confirms_by_convergence_before_a_looser_second_method(monkeypatch: pytest.MonkeyPatch) -> None:
    """The weakly damped oscillators over t = 5e4: DOP853 at 2.5e-14 finishes, RK45 cannot at that rtol (1.2e7 steps). Its own runs
    10 x and 100 x looser converge and bound its error, so RK45 is not run 100 x and 10^4 x looser to disagree by its own
    error first (4.5 s, 3.8e6 steps over t = 1e5); the reference is the same, confirmed by DOP853's convergence."""
    model = model_from(OSCILLATORS).with_definitions()
    setup = Setup(5e4, tuple(np.linspace(0.0, 5e4, 201).tolist()), max_steps=60_000)
    made = _counting(monkeypatch)
    found = reference.computed_reference(model, setup, 2.5e-14, implicit=implicit_reference_tolerances(1e-6))
    assert found.settings is not None and found.settings.method == "DOP853" and found.settings.rtol == 2.5e-14
    assert "converges with the tolerance" in found.description and found.own_error <= 1e-7, found.description
    rk45 = [t.settings.rtol for t in made if t.settings.method == "RK45"]
    assert rk45 and all(r == 2.5e-14 for r in rk45), rk45  # only its probe at the primary's rtol
    looser = sorted(t.settings.rtol for t in made if t.settings.method == "DOP853" and t.outcome.name == "FINISHED")
    assert looser == [2.5e-14, 2.5e-13, 2.5e-12]


@pytest.mark.skipif(not compile.numba_available(), reason="compiled RK45, scipy's RK45's twin")
def test_scipys_rk45_is_not_run_where_its_twin_shows_it_cannot_finish(monkeypatch: pytest.MonkeyPatch) -> None:
    """The double pendulum over t = 10 at rtol 1e-5: scipy's RK45 takes exactly its compiled twin's steps. Within a budget
    below them it is not run (no Python run made) and says why; within one above them it runs as before."""
    model = model_from(DOUBLE).with_definitions()
    setup = Setup(10.0, tuple(np.linspace(0.0, 10.0, 201).tolist()), max_steps=60_000)
    found = reference.computed_reference(model, setup, 2.5e-14)
    scale = component_scale(found.y)
    twin = run(model, stress.TWIN, 1e-5, setup)
    scipy = run(model, stress.NAIVE, 1e-5, setup)
    assert twin.outcome == scipy.outcome == Status.FINISHED and twin.stats.steps == scipy.stats.steps
    made: list[str] = []
    real = runs_module.run

    def counted(*args: object, **kwargs: object) -> object:
        trajectory = real(*args, **kwargs)  # type: ignore[arg-type]
        made.append(trajectory.settings.backend)
        return trajectory

    monkeypatch.setattr(runs_module, "run", counted)
    below = twin.stats.steps // 2
    point = stress._capped(model, stress.NAIVE, 1e-5, replace(setup, max_steps=below), found, scale, None, None)
    assert "python" not in made and point.status == PointStatus.OVER_BUDGET and point.steps == 0
    assert "compiled RK45 at this rtol" in point.reason and f"took {twin.stats.steps} steps" in point.reason and f"({below})" in point.reason
    made.clear()
    point = stress._capped(model, stress.NAIVE, 1e-5, setup, found, scale, None, None)
    assert "python" in made and point.status == PointStatus.FINISHED and point.steps == twin.stats.steps


@pytest.mark.skipif(not compile.numba_available(), reason="the compiled explicit loop")
def test_a_compiled_run_that_creeps_onto_a_sliding_surface_says_so() -> None:
    """The block on a belt (dry friction mu m g sign(v0 - x_dot)) sticks at t = 0.117: compiled DOP853's steps collapse
    3.7e-9 short of x_dot = v0, above SURFACE_TOLERANCE, which its flow reaches in about 1e-9 s. It is the sliding mode's
    stop, not a singularity; a state farther from the surface, at its rate, is not called on it."""
    model = model_from(ROOT / "tests" / "numeric_audit8" / "stick_slip_block_on_belt_shaken_wall.yaml")
    stopped = simulate(model, method="DOP853", backend="compiled")
    assert stopped.outcome == Status.SURFACE_JUMP and "sliding mode" in stopped.message, stopped.message
    assert abs(stopped.y_last[1] - 0.4) > 1.4e-9 * (1 + 0.4)  # the old test alone (|g| <= SURFACE_TOLERANCE x scale) missed it
    module = compile.build(model.with_definitions(), "python").module
    p = list(stopped.settings.p)

    def at(x_dot: float) -> bool:
        return simulate_module._on_surface(module, SimpleNamespace(t_last=stopped.t_last, y_last=np.array([stopped.y_last[0], x_dot])), p)  # type: ignore[arg-type]

    assert at(float(stopped.y_last[1])) and at(0.4 - 1e-12)
    assert not at(0.3) and not at(0.4 - 1e-5)  # reached in 0.03 s and 3e-6 s at its rate (~3 m/s^2): not next to it
