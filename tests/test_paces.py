"""Paces that stop runs which cannot finish: compiled measured runs (`runs._compiled_pace`, told by the compiled
loop each time it returns to Python), the earliest judgement of a Python run (`runs.EARLY_LEVELS`), LSODA's early
judgement where its pilot ended in Adams steps (`runs._lsoda_judged_early`), and a reference that its own convergence
already shows unable to vouch, made without a second method (`reference._unvouched`). All counted in steps; nothing
here reads a clock."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from lagrange_cli.numeric import compile, reference, runs, stress
from lagrange_cli.numeric.runs import Candidate, PointStatus, Setup
from lagrange_cli.numeric.status import PAUSE_STEPS, Failure

from .conftest import ROOT
from .helpers import model_from

numba = pytest.mark.skipif(not compile.numba_available(), reason="the compiled methods need numba")
KEPLER = ROOT / "tests" / "numeric_audit2" / "kepler_e09.yaml"
OSCILLATORS = ROOT / "tests" / "numeric_audit7" / "coupled_oscillators_weak_damping_t1e5.yaml"
STIFF = ROOT / "tests" / "numeric_audit_pilot" / "stiff_elastic_pendulum_r.yaml"


def _stopped_at(pace: Any, reports: list[tuple[int, float]]) -> int | None:
    try:
        for taken, fraction in reports:
            pace(taken, fraction)
    except runs.Unaffordable as over:
        return over.steps
    return None


def test_a_compiled_pace_is_judged_from_a_quarter_of_its_budget_at_its_margin() -> None:
    """Reports every PAUSE_STEPS steps: a steady pace at 8 x the budget is stopped at the first report past
    PACE_AFTER of the budget, never before; one at 2 x (within PACE_MARGIN) runs on; a pace that was slow only in
    the first half of the steps is judged from the latter half."""
    budget = 1_000_000
    reports = [(k * PAUSE_STEPS, k * PAUSE_STEPS / (8 * budget)) for k in range(1, 51)]
    first = next(taken for taken, _ in reports if taken >= runs.PACE_AFTER * budget)
    assert _stopped_at(runs._compiled_pace(budget), reports) == first
    within = [(taken, taken / (2 * budget)) for taken, _ in reports]
    assert _stopped_at(runs._compiled_pace(budget), within) is None
    # the first half of the steps nearly standing still, the latter half at 2 x the budget's pace: not stopped
    slow_then_fast: list[tuple[int, float]] = []
    done = 0.0
    for k in range(1, 51):
        done += 1e-9 if k <= 7 else PAUSE_STEPS / (2 * budget)
        slow_then_fast.append((k * PAUSE_STEPS, done))
    assert _stopped_at(runs._compiled_pace(budget), slow_then_fast) is None
    assert runs._left([(100, 0.5)]) == pytest.approx(100.0)
    assert runs._left([(50, 0.0), (100, 0.0)]) == float("inf")


def test_the_earliest_judgement_of_a_python_run_needs_64_x_its_budget_and_100_steps() -> None:
    """A steady pace at 128 x the budget stops at PACE_EARLIEST of it (100 steps of 6400); at 32 x, at PACE_EARLY;
    at 8 x, at PACE_AFTER. With a budget of 400 the earliest judgement waits for PACE_EARLIEST_STEPS, after PACE_EARLY."""
    budget = 6400

    def stopped(times: float, budget: int = budget) -> int | None:
        progress = runs._paced(budget, None)
        try:
            for k in range(budget):
                progress((k + 1) / (times * budget))
        except runs.Unaffordable as over:
            return over.steps
        return None

    assert stopped(128) == round(runs.PACE_EARLIEST * budget) == runs.PACE_EARLIEST_STEPS
    assert stopped(32) == round(runs.PACE_EARLY * budget)
    assert stopped(8) == round(runs.PACE_AFTER * budget)
    assert stopped(2) is None
    assert stopped(128, 400) == round(runs.PACE_EARLY * 400)  # 25 steps: the early level comes first


@pytest.mark.usefixtures("private_cache")
def test_lsoda_is_judged_early_only_where_its_pilot_ended_in_adams_steps_on_a_problem_not_stiff() -> None:
    """The weakly damped oscillators: LSODA's pilot at rtol 1e-5 ends in Adams steps, nothing stiff, so a paced LSODA run
    with a budget of 6400 is stopped at the earliest judgement (100 steps: its pace needs far more than 64 x its budget).
    The stiff elastic pendulum in r (k = 1e10): its pilot finds it stiff, and LSODA waits for PACE_AFTER of its budget."""
    model = model_from(OSCILLATORS)
    setup = runs.starting(model, Setup(1e5, tuple(np.linspace(0.0, 1e5, 201).tolist()), max_steps=6400))
    settings = runs.settings_for(model, Candidate("LSODA"), 1e-5, setup)
    assert settings.method == "LSODA" and runs._lsoda_judged_early(model, settings)
    point = runs.measure(model, Candidate("LSODA"), 1e-5, setup, None, np.ones(4), repeats=0, paced=True)  # type: ignore[arg-type]
    assert point.status == PointStatus.OVER_BUDGET and point.steps == runs.PACE_EARLIEST_STEPS == round(runs.PACE_EARLIEST * 6400), point.reason
    assert "64 x its step budget (6400)" in point.reason
    stiff = model_from(STIFF)
    stiff_setup = runs.starting(stiff, Setup(10.0, tuple(np.linspace(0.0, 10.0, 11).tolist()), max_steps=6400))
    assert not runs._lsoda_judged_early(stiff, runs.settings_for(stiff, Candidate("LSODA"), 1e-5, stiff_setup))


@numba
@pytest.mark.usefixtures("private_cache")
def test_a_compiled_measured_run_that_cannot_finish_is_stopped_by_its_pace_and_an_unpaced_one_is_not() -> None:
    """Kepler e = 0.9 started at r = 0.01 (a near collision every orbit): compiled RK45 at rtol 1e-5 creeps. Paced, with a
    budget of 2000 scipy steps (200000 compiled), it is stopped at the first report past a quarter of that budget,
    reported over budget with its pace; unpaced, the same run takes its whole budget. A reference-side run is never paced."""
    model = model_from(KEPLER)
    t_end = 18.84955592153876
    setup = runs.starting(model, Setup(t_end, tuple(np.linspace(0.0, t_end, 11).tolist()), {}, {"r": 0.01}, max_steps=2000))
    compiled = Candidate("RK45", "compiled")
    budget = 2000 * runs.COMPILED_STEPS
    paced = runs.measure(model, compiled, 1e-5, setup, None, np.ones(4), repeats=0, paced=True)  # type: ignore[arg-type]
    assert paced.status == PointStatus.OVER_BUDGET and paced.failure == Failure.BUDGET, paced.reason
    assert paced.steps == -(-round(runs.PACE_AFTER * budget) // PAUSE_STEPS) * PAUSE_STEPS, paced.steps
    assert "at that pace" in paced.reason and f"its step budget ({budget})" in paced.reason
    assert paced.reached is not None and paced.reached < 0.05
    full = runs.measure(model, compiled, 1e-5, setup, None, np.ones(4), repeats=0)  # type: ignore[arg-type]
    assert full.status == PointStatus.OVER_BUDGET and full.steps == budget and "at that pace" not in full.reason
    side = runs.run(model, compiled, 1e-5, setup, reference=True, paced=True)
    assert side.stats.steps > paced.steps  # a reference-side run: not paced


@numba
@pytest.mark.usefixtures("private_cache")
def test_a_reference_its_own_convergence_cannot_let_vouch_asks_no_second_method(monkeypatch: pytest.MonkeyPatch) -> None:
    """Kepler e = 0.9 started at r = 0.01 over t = 1, with a reference budget that leaves compiled DOP853 only rtol
    2.5e-10: DOP853 at 2.5e-9 disagrees with it by far more than 0.1 x the accuracy (1e-7), so `stress`'s reference is
    that confirmation (own error its convergence), and neither compiled RK45 nor Radau is run. Made the old way (the
    second method first), it cannot vouch either."""
    made: list[tuple[str, float]] = []
    real = runs.run

    def recording(model: Any, candidate: Candidate, tolerance: float, setup: Setup, **options: Any) -> Any:
        out = real(model, candidate, tolerance, setup, **options)
        made.append((out.settings.method, out.settings.rtol))
        return out

    monkeypatch.setattr(reference, "run", recording)
    setup = Setup(1.0, tuple(np.linspace(0.0, 1.0, 2001).tolist()), {}, {"r": 0.01}, max_steps=100)
    tolerance, implicit = stress.reference_tolerance(1e-6), stress.implicit_reference_tolerances(1e-6)
    model = model_from(KEPLER)
    found = reference.computed_reference(model, runs.starting(model, setup), tolerance, implicit=implicit)
    assert {method for method, _ in made} == {"DOP853"}, made
    assert found.settings is not None and found.settings.rtol == pytest.approx(2.5e-10)
    assert found.confirmer == Candidate("DOP853", "compiled") and found.confirmed_rtol == pytest.approx(2.5e-9)
    assert found.own_error == found.convergence > 0.1 * 1e-6
    assert "no second method was asked" in found.description
    outcome_text = stress._why_own(found)
    assert "no second method was asked" in outcome_text
    monkeypatch.setattr(reference, "_unvouched", lambda *args, **options: None)
    made.clear()
    old_model = model_from(KEPLER)
    old = reference.computed_reference(old_model, runs.starting(old_model, setup), tolerance, implicit=implicit)
    assert {"RK45", "Radau"} & {method for method, _ in made}, made
    assert not old.own_error <= 0.1 * 1e-6  # nan (unconfirmed) or above: it could not vouch either
