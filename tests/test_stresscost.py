"""Where `stress`'s budget goes: explicit reference attempts paced by a probe (`reference.explicit_attempt`),
and scipy runs that can only lose to a compiled run stopped by their pace. Counted in steps, never timed."""

from __future__ import annotations

import numpy as np
import pytest

from lagrange_cli.numeric import compile, reference, runs, stress
from lagrange_cli.numeric.runs import Candidate, Setup, starting
from lagrange_cli.numeric.status import PAUSE_STEPS

from .conftest import ROOT
from .helpers import model_from

pytestmark = pytest.mark.usefixtures("private_cache")

DOP853 = Candidate("DOP853", "compiled")


@pytest.mark.skipif(not compile.numba_available(), reason="compiled runs need numba")
def test_an_explicit_reference_attempt_is_judged_by_its_probe_and_the_last_one_gets_the_steps_its_pace_needs() -> None:
    model = model_from(ROOT / "tests" / "numeric_audit_pilot" / "double_pendulum_nonstiff.yaml")
    times = tuple(np.linspace(0.0, 5000.0, 11).tolist())  # long enough for budgets well above status.PAUSE_STEPS, at which a compiled run checks its budget

    def setup(budget: int) -> Setup:
        return starting(model, Setup(5000.0, times, reference_max_steps=budget))

    full = runs.run(model, DOP853, 1e-12, setup(10_000), reference=True)
    needed = full.stats.steps
    assert not full.failed and 2e5 < needed < 6e5, needed
    # the probe (PACE_PROBE of the budget) finishes: it is the run, step for step
    same = reference.explicit_attempt(model, DOP853, 1e-12, setup(10_000))
    assert same.needed is None and not same.trajectory.failed and same.trajectory.stats.steps == needed
    np.testing.assert_array_equal(same.trajectory.y, full.y)
    # a budget of a third of what it needs: only the probe runs, and its pace says about what the run needs
    small = needed // 3 // runs.COMPILED_STEPS
    skipped = reference.explicit_attempt(model, DOP853, 1e-12, setup(small))
    assert skipped.needed is not None and skipped.trajectory.failed
    assert skipped.trajectory.stats.steps <= np.ceil(reference.PACE_PROBE * small) * runs.COMPILED_STEPS + PAUSE_STEPS
    assert needed / 3 < skipped.needed < 3 * needed
    assert "a probe of" in reference._stopped(model, DOP853, 1e-12, setup(small), skipped.trajectory, skipped.needed)
    # the last attempt before Radau in Python (a ceiling above the budget): up to PACE_EXTENSION x the budget, it finishes
    extended = reference.explicit_attempt(model, DOP853, 1e-12, setup(small), ceiling=10 * small)
    assert extended.needed is None and not extended.trajectory.failed and extended.trajectory.stats.steps == needed
    # ... but not past the ceiling (--max-steps' reference budget) nor PACE_EXTENSION x the budget
    tiny = needed // 10 // runs.COMPILED_STEPS
    assert reference.explicit_attempt(model, DOP853, 1e-12, setup(tiny), ceiling=100 * tiny).needed is not None
    assert reference.explicit_attempt(model, DOP853, 1e-12, setup(small), ceiling=small).needed is not None


def test_a_scipy_methods_first_capped_run_gets_the_steps_its_work_cap_buys() -> None:
    """Radau's first rung after a compiled run met the accuracy: PYTHON_AFTER_COMPILED x that work at about
    18 evaluations a step (6 before: it spent 3 x its cap, 19 a step on the penalty pendulum)."""
    best = runs.replace(runs.unrun(Candidate("DOP853", "compiled"), 1e-6), status=runs.PointStatus.FINISHED, ran=runs.Ran("DOP853", "compiled"), nfev=1_200_000, steps=100_000)
    assert stress._losing(Candidate("Radau", "python"), best) == stress.PYTHON_AFTER_COMPILED
    cap = stress._cap(Candidate("Radau", "python"), best, None, Setup(1.0, (0.0, 1.0)))
    assert cap == int(np.ceil(stress.PYTHON_AFTER_COMPILED * 12_000 / runs.EVALUATIONS_PER_STEP["Radau"]))
    assert runs.EVALUATIONS_PER_STEP["Radau"] >= 15


def test_the_horizon_of_a_system_with_kept_constraints_runs_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    """Moving the state would violate the constraints, so there is no horizon: decided before any run
    (its base run, 2e6 steps at 2.5e-14 on the multiplier pendulum, used to be run and thrown away)."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("a run")

    monkeypatch.setattr(reference, "run", refuse)
    monkeypatch.setattr(reference, "explicit_attempt", refuse)
    model = model_from(ROOT / "systems" / "pendulum_multiplier.yaml")
    assert model.constraints
    assert reference._horizon(model, starting(model, Setup(1.0, (0.0, 0.5, 1.0))), 1e-12) is None
