"""Issue 15, decisive verdicts (helper verdicts16): where compiled Radau's reference at the tightest of its rtols finished
but left the verdict open, compiled Radau a decade or two tighter, confirmed by its own convergence (`reference._tighter`);
a compiled reference run made already is not made again (`runs.run`, `runs.kept_runs`). Counted: assertions are on runs,
rtols, steps and errors, never on time."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from lagrange_cli.numeric import reference, runs, stress
from lagrange_cli.numeric.runs import Candidate, Setup
from lagrange_cli.numeric.simulate import Trajectory

from .conftest import ROOT
from .helpers import model_from

pytestmark = [pytest.mark.skipif(not runs.compiled_radau(), reason="the compiled Radau method needs numba")]

CART = ROOT / "tests" / "numeric_audit2" / "cart_pendulum_fast_damping_long.yaml"


def _counting(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, str, float, float, int, str]]:
    """Every integration made through `runs.integrate`: (method, backend, rtol, t_end, steps, outcome)."""
    made: list[tuple[str, str, float, float, int, str]] = []
    real = runs.integrate

    def counted(model: Any, settings: Any, progress: Any = None, budget: Any = None, *more: Any, **options: Any) -> Trajectory:
        found = real(model, settings, progress, budget, *more, **options)
        made.append((settings.method, settings.backend, settings.rtol, settings.t_end, found.stats.steps, str(found.outcome)))
        return found

    monkeypatch.setattr(runs, "integrate", counted)
    return made


def _high_energy_setup() -> tuple[Any, Setup]:
    model = model_from(CART).with_definitions()
    regime = next(r for r in stress.regimes(model, []) if r.name.startswith("high energy"))
    times = tuple(np.linspace(0.0, regime.t_end, regime.samples).tolist())
    return model, runs.starting(model, Setup(regime.t_end, times, dict(regime.parameters), dict(regime.initial), stress.MAX_STEPS))


def test_tighter_compiled_radau_confirms_the_fast_damping_carts_high_energy(monkeypatch: pytest.MonkeyPatch) -> None:
    """claims15's tree left it unconfirmed: compiled Radau at 1e-10 (the tightest of 1e-10 .. 1e-7) did not converge as
    its order says against 1e-9 and 1e-8, no explicit run could confirm it (3e7 stability-limited steps) and scipy's did
    not finish. A decade tighter, 1e-11 against 1e-10 and 1e-9 converges (3.3 x): own error 2e-8, within 0.1 x 1e-6."""
    model, setup = _high_energy_setup()
    made = _counting(monkeypatch)
    rtols = stress.implicit_reference_tolerances(1e-6)
    assert rtols[0] == pytest.approx(1e-10)
    found = reference.computed_reference(model, setup, stress.reference_tolerance(1e-6), ", a looser --accuracy", rtols)
    assert found.settings is not None and (found.settings.method, found.settings.backend) == ("Radau", "compiled")
    assert found.settings.rtol == pytest.approx(1e-11)
    assert math.isfinite(found.own_error) and found.own_error <= 0.1 * 1e-6
    assert found.confirmer == Candidate("Radau", "compiled") and found.confirmed_rtol == pytest.approx(1e-10)
    assert "the same method 10 x looser" in found.description and "at rtol 1e-10" in found.description
    whole = [m for m in made if m[3] == pytest.approx(setup.t_end) and m[:2] == ("Radau", "compiled")]
    assert sum(1 for m in whole if m[2] == pytest.approx(1e-10)) == 1  # the primary at 1e-10, reused as the confirmation of 1e-11
    assert sum(1 for m in whole if m[2] == pytest.approx(1e-11)) == 1
    assert not [m for m in made if m[1] == "python" and m[3] == pytest.approx(setup.t_end)]  # no scipy confirmation was needed


def test_tighter_stops_where_the_verdict_is_decided(monkeypatch: pytest.MonkeyPatch) -> None:
    """A reference whose own error already vouches (within `enough`) is returned as it is: no tighter run."""
    model, setup = _high_energy_setup()
    made = _counting(monkeypatch)
    decided = reference.Reference("computed", "x", 1e-9, np.zeros(2), np.zeros((2, 4)), np.zeros(2), 0.0)
    assert reference._tighter(model, setup, 1e-10, decided, 1e-7, 0.0) is decided
    assert made == []


def test_a_compiled_reference_run_is_made_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """The same compiled reference-side run asked for again (the same decided settings, a budget at least its steps) is
    the run kept (`runs.kept_runs`), not made again; with a smaller budget it is made (it may not finish there)."""
    model, setup = _high_energy_setup()
    short = replace(setup, t_end=1.0, times=tuple(np.linspace(0.0, 1.0, 11).tolist()))
    made = _counting(monkeypatch)
    first = runs.run(model, Candidate("Radau", "compiled"), 1e-9, short, reference=True)
    again = runs.run(model, Candidate("Radau", "compiled"), 1e-9, short, reference=True)
    assert len(made) == 1 and not first.failed
    assert again.stats.steps == first.stats.steps and np.array_equal(again.y, first.y)
    runs.run(model, Candidate("Radau", "compiled"), 1e-9, replace(short, reference_max_steps=max(1, first.stats.steps // (2 * runs.COMPILED_STEPS))), reference=True)
    assert len(made) == 2


def test_the_recommended_run_under_another_name_is_no_tie() -> None:
    """Audit 7's cosmetic: `auto` resolved to the recommended run's method and settings is the same run, not a tie."""
    model, setup = _high_energy_setup()
    decided = runs.settings_for(model, Candidate("DOP853", "compiled"), 1e-7, setup)

    def point(candidate: Candidate, seconds: float, settings: Any) -> runs.Point:
        ran = runs.Ran("DOP853", "compiled")
        return runs.Point(candidate.label, str(ran), 1e-7, None, "finished", "", 1e-7, 1e-7, 0.0, None, seconds, 1, 0.0, 10, 0, 5, candidate=candidate, ran=ran, max_error=1e-7, settings=settings)

    best = point(Candidate("DOP853", "compiled"), 0.1, decided)
    same = point(Candidate("auto"), 0.101, replace(decided, notes=("auto: not stiff",)))
    other = point(Candidate("RK45", "compiled"), 0.105, replace(decided, method="RK45"))
    assert runs.ties([best, same, other], best, 1e-6) == (other,)
