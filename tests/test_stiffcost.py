"""Issue 15, `stress` and `accuracy` on stiff files within their budget (helper stiffcost): reference-side
Python runs stopped by their pace, measured compiled runs taken from the reference's side, scipy's RK45
ladder from its compiled twin once shown equal, scipy's implicit methods first where compiled explicit
ones are stability-limited. Counted: assertions are on runs, steps and evaluations, never on time."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from lagrange_cli.numeric import compile, reference, runs, stress
from lagrange_cli.numeric.runs import Candidate, PointStatus, Setup
from lagrange_cli.numeric.simulate import Trajectory

from .conftest import ROOT
from .helpers import model_from

pytestmark = pytest.mark.usefixtures("private_cache")

STIFF = ROOT / "tests" / "numeric_audit" / "stiff_elastic_pendulum_r.yaml"
numba = pytest.mark.skipif(not compile.numba_available(), reason="compiled runs need numba")


def _counting(monkeypatch: pytest.MonkeyPatch, module: Any) -> list[tuple[str, str, float, int, int]]:
    """Every integration made through `module.integrate`: (method, backend, rtol, budget, steps)."""
    made: list[tuple[str, str, float, int, int]] = []
    real = module.integrate

    def counted(model: Any, settings: Any, progress: Any = None, budget: Any = None, *more: Any, **options: Any) -> Trajectory:
        try:
            found = real(model, settings, progress, budget, *more, **options)
        except runs.Unaffordable as over:
            made.append((settings.method, settings.backend, settings.rtol, budget, over.steps))
            raise
        made.append((settings.method, settings.backend, settings.rtol, budget, found.stats.steps))
        return found

    monkeypatch.setattr(module, "integrate", counted)
    return made


def test_a_reference_probe_that_cannot_cover_its_span_is_stopped_by_its_pace(monkeypatch: pytest.MonkeyPatch) -> None:
    """`_doomed`'s probe of Radau at rtol 1e-8 on the stiff spring written in its length (round-off-limited there)
    stops once its pace needs more than REFERENCE_PACE_MARGIN x its share of the budget, after PACE_AFTER of it,
    not at the end of its share (15 s over the long horizon's first tenth before)."""
    model = model_from(STIFF).with_definitions()
    setup = runs.starting(model, Setup(10.0, tuple(np.linspace(0.0, 10.0, 201).tolist()), max_steps=stress.MAX_STEPS))
    attempt = replace(setup, reference_max_steps=11803)
    made = _counting(monkeypatch, runs)
    why = reference._doomed(model, attempt, 1e-8, Candidate("Radau", "python"))  # scipy's: a compiled run is not paced
    assert "at that pace" in why, why
    share = max(reference.PROBE_STEPS, int(reference.PROBE_SHARE * 11803) + 1)
    radau = [m for m in made if m[0] == "Radau"]
    assert len(radau) == 1 and radau[0][4] < share, (radau, share)  # stopped before its share of the budget


@numba
def test_a_measured_compiled_run_made_by_the_reference_already_is_not_made_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """A compiled run with the same decided settings as a finished reference-side run (a confirmation) is
    that run: `measure` takes its steps, samples and errors without integrating again."""
    model = model_from(ROOT / "systems" / "double_pendulum.yaml").with_definitions()
    setup = runs.starting(model, Setup(5.0, tuple(np.linspace(0.0, 5.0, 201).tolist()), max_steps=stress.MAX_STEPS))
    dop = Candidate("DOP853", "compiled")
    kept = runs.run(model, dop, 1e-9, setup, reference=True)
    ref = reference.computed_reference(model, setup, 1e-12)
    made = _counting(monkeypatch, runs)
    point = runs.measure(model, dop, 1e-9, setup, ref, runs.component_scale(ref.y), repeats=0)
    assert made == [], made
    assert point.ok and point.steps == kept.stats.steps and point.nfev == kept.stats.nfev
    # another rtol is a new run
    other = runs.measure(model, dop, 1e-8, setup, ref, runs.component_scale(ref.y), repeats=0)
    assert other.ok and len(made) == 1 and made[0][2] == 1e-8


@numba
def test_scipy_rk45_later_rungs_come_from_its_compiled_twin_once_shown_equal(monkeypatch: pytest.MonkeyPatch) -> None:
    """scipy's RK45 (NAIVE) runs its first rung; shown equal there to compiled RK45 (steps, evaluations, error),
    its later rungs are not run in Python: their steps and errors are the twin's, the points `predicted`, never
    recommended. A real scipy run at such a rung takes exactly the predicted steps and evaluations."""
    model = model_from(ROOT / "systems" / "double_pendulum.yaml").with_definitions()
    regime = stress.regimes(model, ())[0]
    made = _counting(monkeypatch, runs)
    # scipy's RK45 first, so that no run meeting the accuracy caps it (as in an open regime: the swinging Atwood machine's long horizon)
    monkeypatch.setattr(stress, "_order", lambda model, setup, candidates: list(candidates))
    outcome = stress._regime(model, regime, 1e-6, (stress.NAIVE, stress.TWIN), Setup(0.0, (), max_steps=stress.MAX_STEPS), None)
    naive = outcome.naive
    assert naive is not None and naive.predicted and naive.ok, naive
    assert outcome.recommended is None or not outcome.recommended.predicted
    python = [m for m in made if m[:2] == ("RK45", "python")]
    rungs = [t for t in stress.ladder(1e-6) if t >= naive.tolerance * (1 - 1e-9)]
    assert len(rungs) >= 2, rungs
    # scipy ran its first rung (the proof) only, not the later rungs; at its default rtol 1e-3, capped at 2 x the work of the
    # compiled run that meets the accuracy (14 steps), it is not run either: its twin there takes 68 (`stress._beyond_twin`)
    assert sorted({m[2] for m in python}) == [rungs[0]], python
    default = outcome.naive_default
    assert default is not None and default.status == PointStatus.CAPPED and default.steps == 0 and "compiled twin" in default.reason, default
    times = tuple(np.linspace(0.0, regime.t_end, regime.samples).tolist())
    setup = runs.starting(model, Setup(regime.t_end, times, dict(regime.parameters), dict(regime.initial), stress.MAX_STEPS))
    real = runs.run(model, stress.NAIVE, naive.tolerance, setup)
    assert (real.stats.steps, real.stats.nfev) == (naive.steps, naive.nfev)
    # scipy's RK45 named alone (`--method RK45:python`) is run at every rung, as asked
    made.clear()
    alone = stress._regime(model, regime, 1e-6, (stress.NAIVE,), Setup(0.0, (), max_steps=stress.MAX_STEPS), None)
    assert alone.naive is not None and not alone.naive.predicted and alone.recommended is not None
    assert {m[2] for m in made if m[:2] == ("RK45", "python")} >= set(rungs), made


def test_stiff_elastic_pendulum_tries_implicit_methods_before_stability_limited_compiled_ones() -> None:
    """The pilot puts compiled DOP853 at millions of stability-limited steps over the window: scipy's implicit
    methods come before the compiled explicit ones in `stress`'s order, so that one meeting the accuracy caps them."""
    model = model_from(STIFF).with_definitions()
    regime = stress.regimes(model, ())[0]
    times = tuple(np.linspace(0.0, regime.t_end, regime.samples).tolist())
    setup = runs.starting(model, Setup(regime.t_end, times, dict(regime.parameters), dict(regime.initial), stress.MAX_STEPS))
    assert reference.stable_steps(model, setup, "DOP853") > reference.IMPLICIT_FIRST_STEPS
    candidates = stress._order(model, setup, stress.default_candidates(model))
    order = [c.method for c in candidates]
    if runs.compiled_radau():  # compiled Radau first, before auto; scipy's implicit methods after the compiled explicit ones (test_radstress.py)
        assert order[:2] == ["Radau", "auto"], order
        assert candidates.index(Candidate("DOP853")) < candidates.index(Candidate("BDF")), order
        return
    assert order[0] == "auto"
    assert max(order.index(m) for m in ("Radau", "BDF", "LSODA")) < min(order.index(m) for m in ("RK45", "DOP853")), order
    # a system that is not stiff keeps compiled candidates first
    plain = model_from(ROOT / "systems" / "double_pendulum.yaml").with_definitions()
    calm = runs.starting(plain, Setup(10.0, (0.0, 10.0), max_steps=stress.MAX_STEPS))
    assert not reference.implicit_first(plain, calm)


@numba
def test_accuracy_skips_a_capped_compiled_run_its_stability_limit_puts_past_its_cap(monkeypatch: pytest.MonkeyPatch) -> None:
    """In `accuracy`, a compiled explicit run capped at LOSING x the cheapest run's work whose stability-limited
    steps exceed STABILITY_MARGIN x that cap is not run (no integration), and is `capped`."""
    from lagrange_cli.numeric import accuracy

    model = model_from(STIFF).with_definitions()
    setup = runs.starting(model, Setup(10.0, tuple(np.linspace(0.0, 10.0, 201).tolist()), max_steps=stress.MAX_STEPS))
    made = _counting(monkeypatch, runs)
    unused: Any = None  # not run, so never compared with a reference
    point = accuracy._capped(model, Candidate("DOP853", "compiled"), 1e-6, setup, unused, unused, None, 2000.0)
    assert point.status == runs.PointStatus.CAPPED and "stability-limited" in point.reason, point.reason
    assert [m for m in made if m[1] == "compiled"] == []


def _finished(method: str, tolerance: float, steps: int, nfev: int, error: float) -> runs.Point:
    point = runs.unrun(Candidate(method), tolerance)
    ran = runs.Ran(method, "python")
    return replace(point, ran=ran, resolved=str(ran), status=runs.PointStatus.FINISHED, reason="", steps=steps, nfev=nfev, max_error=error, final_error=error, rms_error=error)


def test_a_scipy_ladder_whose_error_falls_too_slowly_stops_where_meeting_would_cost_more_than_it_may_spend() -> None:
    """BDF's error falling 1.2 x a rung, its work 2 x: even at FASTEST_FALL a rung 1e-6 is 3 rungs on. After a compiled run meets
    the accuracy, the ladder stops where those runs would take more than its cap; before anything meets, where
    the last of them would exceed its step budget. A fast-falling error (10 x a rung) or a next rung that meets
    is left to the ladder."""
    setup = Setup(2000.0, (0.0, 2000.0), max_steps=stress.MAX_STEPS)
    bdf = Candidate("BDF")
    first = _finished("BDF", 1e-5, 13004, 30000, 2.0e-4)
    second = _finished("BDF", 1e-6, 18447, 60000, 1.7e-4)
    compiled = replace(_finished("DOP853", 1e-8, 573458, 6901601, 5e-7), ran=runs.Ran("DOP853", "compiled"))
    spent = runs.work(first) + runs.work(second)
    why = stress._out_of_reach(bdf, first, second, 9e-7, compiled, spent, setup)
    assert "more rtols" in why and "above what it may spend" in why, why
    alone = stress._out_of_reach(bdf, first, second, 9e-7, None, spent, setup)
    assert "above its step budget" in alone, alone
    # before anything meets, only where the regime can at most stay open: elsewhere these runs may decide the verdict
    assert stress._out_of_reach(bdf, first, second, 9e-7, None, spent, setup, open_only=False) == ""
    quick = _finished("BDF", 1e-6, 18447, 42000, 2.0e-5)  # 10 x a rung: two rungs on, within its step budget
    assert stress._out_of_reach(bdf, first, quick, 9e-7, None, spent, setup) == ""
    near = _finished("BDF", 1e-6, 18447, 42000, 1.5e-6)  # the next rung may meet: the ladder's own rules decide
    assert stress._out_of_reach(bdf, _finished("BDF", 1e-5, 13004, 30000, 1.5e-5), near, 9e-7, compiled, spent, setup) == ""
    # before anything meets, compiled runs are left to their own rules
    assert stress._out_of_reach(Candidate("DOP853", "compiled"), first, second, 9e-7, None, spent, setup) == ""


def _compiled(method: str, tolerance: float, steps: int, nfev: int, error: float) -> runs.Point:
    return replace(_finished(method, tolerance, steps, nfev, error), candidate=Candidate(method, "compiled"), ran=runs.Ran(method, "compiled"))


def test_a_compiled_ladder_stops_where_the_run_that_would_meet_alone_costs_more_than_it_may() -> None:
    """The weakly damped coupled oscillators over t = 1e5 (audit 7): compiled RK45 at rtol 1e-5 and 1e-6, 2.9e-2 and
    2.6e-3 off, its work 1.65 x a rung. Even at FASTEST_FALL the run meeting 1e-6 is 4 rungs on, 7.4 x the work at 1e-6,
    above SAME_BACKEND_LOSING x that of compiled DOP853, which meets: its ladder stops (it ran to 1e-8, 3.4 s more per regime).
    Where that run would cost no more than that, or nothing meets yet, or the candidate is auto, the ladder goes on."""
    setup = Setup(1e5, (0.0, 1e5), max_steps=stress.MAX_STEPS)
    rk45 = Candidate("RK45", "compiled")
    first = _compiled("RK45", 1e-5, 400307, 2_401_842, 2.9e-2)
    second = _compiled("RK45", 1e-6, 660656, 3_963_936, 2.6e-3)
    best = _compiled("DOP853", 1e-10, 461513, 5_711_597, 2.6e-7)
    spent = runs.work(first) + runs.work(second)
    why = stress._out_of_reach(rk45, first, second, 9.99e-7, best, spent, setup)
    assert "4 more rtols" in why and "the last of them alone" in why and "above what it may spend" in why, why
    assert stress._out_of_reach(rk45, first, second, 9.99e-7, None, spent, setup) == ""  # nothing meets yet: its runs may decide
    assert stress._out_of_reach(stress.AUTO, first, second, 9.99e-7, best, spent, setup) == ""  # auto's own ladder is measured in full
    cheap = _compiled("DOP853", 1e-10, 461513, 60_000_000, 2.6e-7)  # a best whose work leaves room for the 4 rungs' last
    assert stress._out_of_reach(rk45, first, second, 9.99e-7, cheap, spent, setup) == ""


def test_a_high_energy_regime_from_rest_is_not_set_by_a_creeping_mode() -> None:
    """audit 6's F1: a file at rest whose slowest mode creeps (Van der Pol, mu = 1000: 4.2e-4/s, against its
    oscillation's 1.5/s) got "high energy" velocities of about 1e-3 x each size, the defaults again. The
    velocities now come from the slowest oscillation, and the regime's name says so; a system whose slowest
    mode swings keeps it (the double pendulum)."""
    model = model_from(ROOT / "tests" / "numeric_audit5" / "van_der_pol_mu1000_coupled.yaml")
    high = next(r for r in stress.regimes(model, ()) if r.name.startswith("high energy"))
    assert "slowest oscillation's rate" in high.name, high.name
    start = runs.start_of(model, runs.starting(model, Setup(1.0, (0.0, 1.0))))
    found = stress.policy.initial_spectrum(model, start.values, start.y0)
    assert found is not None and found.slowest < stress.CREEPING * found.oscillation
    sizes = stress.diagnostics.coordinate_sizes(start.y0, model.n)
    assert np.allclose(list(high.initial.values()), 3 * found.oscillation * sizes)
    plain = next(r for r in stress.regimes(model_from(ROOT / "systems" / "double_pendulum.yaml"), ()) if r.name.startswith("high energy"))
    assert "slowest mode's rate" in plain.name, plain.name
