"""Issue 15, `stress` and `accuracy` within their budget on unseen systems: no run made twice in a regime,
and budgets spent only where the verdict is still open. Counted: assertions are on runs, steps and
evaluations, never on time."""

from __future__ import annotations

from typing import Any

import pytest

from lagrange_cli.numeric import compile, policy, runs, stress
from lagrange_cli.numeric.runs import Candidate, Setup
from lagrange_cli.numeric.simulate import Trajectory

from .conftest import ROOT
from .helpers import model_from

pytestmark = pytest.mark.usefixtures("private_cache")


@pytest.mark.skipif(not compile.numba_available(), reason="auto resolves to compiled DOP853 here")
def test_a_regime_makes_no_run_twice(monkeypatch: pytest.MonkeyPatch) -> None:
    """auto's ladder resolves to compiled DOP853 at each rtol: DOP853's own ladder takes those runs, not
    the same runs again (the trammel's defaults made each of the four twice, a quarter of the regime)."""
    model = model_from(ROOT / "systems" / "double_pendulum.yaml").with_definitions()
    # auto picks the compiled backend for a system compiled already (else, for a short run, Python); whether its file is in
    # this cache depends on what ran before in the worker (a module imported once is kept), so it is said here
    monkeypatch.setattr(policy, "_backend", lambda *_: ("compiled", "this system is compiled already (cached)"))
    made: list[tuple[object, ...]] = []
    real = runs.run

    def counted(model: Any, candidate: Candidate, tolerance: float, setup: Setup, **options: Any) -> Trajectory:
        found = real(model, candidate, tolerance, setup, **options)
        if not options.get("reference"):
            s = found.settings
            made.append((s.method, s.backend, s.rtol, s.atol, s.t_end, s.step))
        return found

    monkeypatch.setattr(runs, "run", counted)
    regime = stress.regimes(model, ())[0]
    outcome = stress._regime(model, regime, 1e-6, stress.default_candidates(model), Setup(0.0, (), max_steps=stress.MAX_STEPS), None)
    assert len(made) == len(set(made)), sorted(made)
    auto = outcome.auto
    dop = next(p for p in outcome.points if p.candidate == Candidate("DOP853"))
    assert auto is not None and auto.resolved == "DOP853 (compiled)" and auto.ok
    # the same run, reported under each name: the same steps, evaluations and error
    assert dop.ok and (dop.tolerance, dop.steps, dop.nfev, dop.error) == (auto.tolerance, auto.steps, auto.nfev, auto.error)
    assert dop.method == "DOP853" and auto.method == "auto"


def test_a_python_run_that_cannot_finish_is_stopped_by_its_pace_before_anything_meets() -> None:
    """No run has met the accuracy yet (no cap): a scipy run is still stopped once its pace shows it cannot
    finish within PACE_MARGIN x its budget, after PACE_AFTER of it, not run to the end of its budget
    (audit4 F7: the trammel's long horizon ran four scipy methods to 60000 steps each)."""
    model = model_from(ROOT / "systems" / "double_pendulum.yaml").with_definitions()
    budget = 400
    setup = runs.starting(model, Setup(1000.0, (0.0, 1000.0), max_steps=budget))
    unused: Any = None  # the run never finishes, so it is never compared with a reference
    point = stress._capped(model, Candidate("Radau", "python"), 1e-8, setup, unused, unused, None, None)
    assert point.status == runs.PointStatus.OVER_BUDGET and "at that pace" in point.reason, point.reason
    assert point.steps <= max(runs.PACE_STEPS, runs.PACE_AFTER * budget) + 1, point.steps
    # a user's method in `accuracy` still gets its whole budget: the same run, not paced, spends it
    whole = runs.measure(model, Candidate("Radau", "python"), 1e-8, setup, unused, unused, repeats=0)
    assert whole.status == runs.PointStatus.OVER_BUDGET and whole.steps >= budget


def test_where_the_verdict_can_only_stay_open_a_python_run_stops_once_its_pace_exceeds_its_budget() -> None:
    """The reference's own error above REFERENCE_ROOM x the accuracy (`open_only`): no run met it yet, so a
    run out of its budget changes nothing, and one whose pace needs more than OPEN_PACE_MARGIN x its budget
    is stopped after PACE_AFTER of it; elsewhere such a run (needing about 2 x its budget) runs to its end."""
    model = model_from(ROOT / "systems" / "double_pendulum.yaml").with_definitions()
    setup = runs.starting(model, Setup(40.0, (0.0, 40.0), max_steps=stress.MAX_STEPS))
    needed = runs.run(model, Candidate("Radau", "python"), 1e-6, setup).stats.steps
    assert needed > 200, needed
    budget = needed // 2
    small = runs.replace(setup, max_steps=budget)
    unused: Any = None  # neither run finishes, so neither is compared with a reference
    wide = stress._capped(model, Candidate("Radau", "python"), 1e-6, small, unused, unused, None, None)
    assert wide.status == runs.PointStatus.OVER_BUDGET and wide.steps >= budget, (wide.steps, budget, wide.reason)
    tight = stress._capped(model, Candidate("Radau", "python"), 1e-6, small, unused, unused, None, None, open_only=True)
    assert tight.status == runs.PointStatus.OVER_BUDGET and tight.steps < budget, (tight.steps, budget)
    assert f"within {stress.OPEN_PACE_MARGIN:g} x its step budget ({budget})" in tight.reason, tight.reason
