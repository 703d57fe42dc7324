"""Where no run can decide a regime, `stress` spends no more on it: each compiled ladder stops after its first run
once the reference cannot vouch for the accuracy; and a reference probe that ran out of its budget is not made
again for the predictability horizon's finer samples."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from lagrange_cli.numeric import compile, reference, runs, stress
from lagrange_cli.numeric.runs import Candidate, Setup

from .conftest import ROOT
from .helpers import counting_integrations, model_from

pytestmark = [pytest.mark.usefixtures("private_cache"), pytest.mark.skipif(not compile.numba_available(), reason="the compiled methods need numba")]


def test_a_regime_whose_reference_cannot_vouch_runs_each_compiled_ladder_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """The double pendulum, its reference's own error set to 2e-6 against an accuracy of 1e-6: whatever the runs do,
    the regime is undecided, so each compiled method (auto too) runs its first rung only and says why; scipy's
    methods are not run, as before. With the reference's own error as computed, the ladders go on."""
    model = model_from(ROOT / "systems" / "double_pendulum.yaml")
    real = stress.prepare

    def doubtful(*args: Any, **kwargs: Any) -> Any:
        setup, found, horizon, notes = real(*args, **kwargs)
        return setup, replace(found, own_error=2e-6), horizon, notes

    candidates = (Candidate("RK45", "compiled"), Candidate("DOP853", "compiled"), Candidate("BDF"), stress.AUTO)
    regime = stress.Regime("defaults", 2.0, {}, {})
    budget = Setup(0.0, (), max_steps=stress.MAX_STEPS)
    monkeypatch.setattr(stress, "prepare", doubtful)
    made = counting_integrations(monkeypatch)
    outcome = stress._regime(model, regime, 1e-6, candidates, budget, None)
    measured = [m for m in made if m[1] == "compiled" and m[2] >= 1e-5 * (1 - 1e-9)]  # the ladders' (not the reference's)
    assert sorted((m[0], m[2]) for m in measured) == [("DOP853", 1e-5), ("RK45", 1e-5)], made  # auto's first run is DOP853's
    assert outcome.recommended is None and outcome.open_reason
    for point in outcome.points:
        if point.candidate in (Candidate("RK45", "compiled"), Candidate("DOP853", "compiled"), stress.AUTO):
            assert point.tolerance == 1e-5 and "cannot vouch" in point.reason, point
    assert not [m for m in made if m[0] == "BDF"]
    monkeypatch.setattr(stress, "prepare", real)
    vouched = stress._regime(model, regime, 1e-6, candidates, budget, None)
    assert vouched.recommended is not None and vouched.recommended.tolerance < 1e-5


def test_a_reference_probe_out_of_budget_is_not_made_again_for_the_horizons_samples(monkeypatch: pytest.MonkeyPatch) -> None:
    """Compiled DOP853 at 2.5e-14 over the double pendulum's t = 2000 (some 1.9e5 steps), given 5 reference steps,
    runs out of its probe's (the compiled kernels' least budget, 20000 steps): at its pace it is not run. The predictability horizon asks for it with
    4 x the samples, the reference with the study's: one probe (the Euler-angle top near its pole made it twice in
    three regimes, 1.1 s each). Its steps do not depend on the samples (checked here: both grids reach the same
    state after the same steps)."""
    model = model_from(ROOT / "systems" / "double_pendulum.yaml").with_definitions()
    made = counting_integrations(monkeypatch)
    study = runs.starting(model, Setup(2000.0, tuple(np.linspace(0.0, 2000.0, 2001).tolist()), max_steps=stress.MAX_STEPS, reference_max_steps=5))
    fine = replace(study, times=tuple(np.linspace(0.0, 2000.0, 8001).tolist()))
    dop = Candidate("DOP853", "compiled")
    first = reference.explicit_attempt(model, dop, 2.5e-14, fine)
    again = reference.explicit_attempt(model, dop, 2.5e-14, study)
    assert first.needed is not None and again.needed == first.needed and again.trajectory.outcome == runs.Status.BUDGET
    assert [m[4:] for m in made if m[:3] == ("DOP853", "compiled", 2.5e-14)] == [(20000, "budget")], made  # once
    probes = [runs.run(model, dop, 2.5e-14, replace(s, reference_max_steps=1), reference=True) for s in (fine, study)]
    assert probes[0].stats.steps == probes[1].stats.steps == 20000 and probes[0].outcome == runs.Status.BUDGET
    assert (probes[0].t_last, probes[0].y_last.tolist()) == (probes[1].t_last, probes[1].y_last.tolist())
