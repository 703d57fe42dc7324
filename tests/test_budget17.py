"""Issue 15, `stress` within its budget: a compiled explicit confirmation of a reference was probed with a tenth of its
budget, stopped there and made again from t = 0 with the whole budget, where a finished run it follows over the same
window (the primary at a tighter rtol) already said how many steps it needs (the stiff elastic pendulum in r over
t = 100: DOP853 at 1e-7 probed with 6e6 steps, 8 s, then made in full with 7.9e6; RK45 at 1e-8 likewise, 5 s). The
probe is now sized by those steps (`reference._bounded`). Counted in integrations and steps, never timed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lagrange_cli.numeric import compile, reference
from lagrange_cli.numeric.accuracy import Candidate
from lagrange_cli.numeric.runs import COMPILED_STEPS, Setup, run
from lagrange_cli.numeric.simulate import Trajectory
from lagrange_cli.numeric.status import Status

from .conftest import ROOT
from .helpers import model_from

pytestmark = [pytest.mark.usefixtures("private_cache"), pytest.mark.skipif(not compile.numba_available(), reason="compiled explicit reference runs")]

DOUBLE = ROOT / "systems" / "double_pendulum.yaml"
RK45 = Candidate("RK45", "compiled")
DOP853 = Candidate("DOP853", "compiled")


def _counting(monkeypatch: pytest.MonkeyPatch) -> list[Trajectory]:
    """Every run the reference module makes from now on, in order."""
    made: list[Trajectory] = []

    def counted(*args: object, **kwargs: object) -> Trajectory:
        trajectory = run(*args, **kwargs)  # type: ignore[arg-type]
        made.append(trajectory)
        return trajectory

    monkeypatch.setattr(reference, "run", counted)
    return made


def test_a_confirmation_bounded_by_its_primary_is_made_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """The floor's run (RK45 a decade looser than the primary RK45) needs more steps than a tenth of a budget that
    holds PACE_ROOM x the primary's: it was probed, stopped at that tenth, and made again from t = 0; it is now made
    once, and is the same run (same steps, same disagreement) as one made straight through with the whole budget."""
    model = model_from(DOUBLE).with_definitions()
    setup = Setup(1000.0, tuple(np.linspace(0.0, 1000.0, 1001).tolist()), max_steps=60_000)  # 1.5e5 and 9.5e4 steps: past status.PAUSE_STEPS
    main = run(model, RK45, 1e-10, setup, reference=True)
    assert main.outcome == Status.FINISHED
    budget = math.ceil(reference.PACE_ROOM * main.stats.steps / COMPILED_STEPS) + 1  # scipy steps: the primary's fit
    tight = Setup(setup.t_end, setup.times, max_steps=setup.steps, reference_max_steps=budget)
    straight = run(model, RK45, 1e-9, tight, reference=True)
    assert straight.outcome == Status.FINISHED
    assert straight.stats.steps > reference.PACE_PROBE * budget * COMPILED_STEPS  # a tenth of the budget would stop it
    assert reference._bounded(main, RK45, 1e-9) == main.stats.steps
    made = _counting(monkeypatch)
    found = reference._confirmed(model, tight, main, 1e-10, [(RK45, 1e-9)], 0.0)
    looser = [t for t in made if (t.settings.method, t.settings.rtol) == ("RK45", 1e-9)]
    assert len(looser) == 1 and looser[0].outcome == Status.FINISHED, [(t.settings.method, t.settings.rtol, t.outcome, t.stats.steps) for t in made]
    assert looser[0].stats.steps == straight.stats.steps
    assert found.confirmer == RK45 and found.confirmed_rtol == 1e-9 and math.isfinite(found.own_error)
    # without the bound (a run that is not known to need fewer steps) the probe is stopped at its tenth and the run made again
    made.clear()
    again = reference.explicit_attempt(model, RK45, 1e-9, tight)
    assert [t.outcome for t in made] == [Status.BUDGET, Status.FINISHED]
    assert again.trajectory.stats.steps == straight.stats.steps


def test_the_bound_holds_only_for_a_run_that_cannot_take_more_steps() -> None:
    """A decade looser rtol of the same method, or DOP853 (higher order, wider stability interval) after RK45 two decades
    looser, is bounded by the primary's steps; a tighter or equal-to-a-decade rtol, RK45 after DOP853, a Python run, or a failed primary is not."""
    model = model_from(DOUBLE).with_definitions()
    setup = Setup(2.0, tuple(np.linspace(0.0, 2.0, 51).tolist()), max_steps=60_000)
    main = run(model, RK45, 1e-9, setup, reference=True)
    dop = run(model, DOP853, 1e-9, setup, reference=True)
    assert main.outcome == dop.outcome == Status.FINISHED
    assert reference._bounded(main, RK45, 1e-8) == main.stats.steps
    assert reference._bounded(main, DOP853, 1e-7) == main.stats.steps
    assert reference._bounded(main, RK45, 1e-9) == 0  # the same rtol: a second opinion, not a looser run
    assert reference._bounded(main, RK45, 2e-9) == 0
    assert reference._bounded(dop, RK45, 1e-7) == 0  # a narrower stability interval: more steps where stiff
    assert reference._bounded(main, DOP853, 1e-8) == 0  # DOP853 a decade looser only: its error estimate may reject more
    assert reference._bounded(main, Candidate("RK45", "python"), 1e-7) == 0
    long = tuple(np.linspace(0.0, 1000.0, 1001).tolist())  # 9.5e4 steps: past status.PAUSE_STEPS, where a budget is checked
    stopped = run(model, RK45, 1e-9, Setup(1000.0, long, max_steps=60_000, reference_max_steps=1), reference=True)
    assert stopped.outcome == Status.BUDGET
    assert reference._bounded(stopped, RK45, 1e-7) == 0
