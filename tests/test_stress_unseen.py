"""Issue 15, `stress` on a system the project had not seen (an elastic pendulum in r and phi, k = 230,
damped): no finding from a run stopped after its first steps, no pace judged from them, and an implicit
reference vouched for by a confirmation near its own tolerance, not by a looser run's own error.
Counted: assertions are on steps, errors and texts, never on time."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from lagrange_cli.numeric import compile, reference, runs, stress
from lagrange_cli.numeric.accuracy import Candidate
from lagrange_cli.numeric.runs import PointStatus, Setup, component_scale, run, scaled_errors, unrun

from .conftest import ROOT
from .helpers import model_from

pytestmark = pytest.mark.usefixtures("private_cache")

ELASTIC = ROOT / "tests" / "numeric_stressq" / "elastic_pendulum_r_damped.yaml"


def _point(method: str, backend: str, tolerance: float, steps: int, status: PointStatus) -> runs.Point:
    return replace(unrun(Candidate(method, backend), tolerance), status=status, steps=steps)


def test_the_step_count_explodes_only_between_finished_runs() -> None:
    """Radau stopped by its cap after 2 steps is no count against DOP853's 153 to t_end; finished, it is."""
    tolerance = stress.ladder(1e-6)[1]
    explicit = _point("DOP853", "compiled", tolerance, 153, PointStatus.FINISHED)
    stopped = _point("Radau", "python", tolerance, 2, PointStatus.OVER_BUDGET)
    found = {(Candidate("DOP853", "compiled"), tolerance): explicit, (Candidate("Radau"), tolerance): stopped}
    assert stress._explosion(found, 1e-6) is None
    finished = replace(stopped, status=PointStatus.FINISHED)
    explosion = stress._explosion({**found, (Candidate("Radau"), tolerance): finished}, 1e-6)
    assert explosion is not None and explosion.kind == "explicit step count explodes" and "153 steps against Radau's 2" in explosion.detail


def _steps_until_stopped(budget: int, fractions: list[float]) -> int | None:
    progress = runs._paced(budget, None)
    try:
        for fraction in fractions:
            progress(fraction)
    except runs.Unaffordable as stopped:
        return stopped.steps
    return None


def test_a_pace_far_beyond_its_budget_is_judged_early_and_a_growing_one_is_not() -> None:
    """From PACE_EARLY of its budget a paced run is stopped where its pace needs more than PACE_AFTER /
    PACE_EARLY x PACE_MARGIN x its budget, judged from the faster of the paces of the latter half and the last
    quarter of its steps; between that and PACE_MARGIN x, it is judged at PACE_AFTER as before."""
    budget = 400
    early, late = round(runs.PACE_EARLY * budget), round(runs.PACE_AFTER * budget)
    wide = runs.PACE_MARGIN * runs.PACE_AFTER / runs.PACE_EARLY
    steady = [(k + 1) / (2 * wide * budget) for k in range(budget)]  # a steady pace: 2 x the wide margin x the budget to t_end
    assert _steps_until_stopped(budget, steady) == early
    unjudged = runs._paced(budget, None, early=False)  # LSODA's and reference-side runs: from PACE_AFTER only
    with pytest.raises(runs.Unaffordable) as stopped:
        for fraction in steady:
            unjudged(fraction)
    assert stopped.value.steps == late
    beyond = [(k + 1) / (8 * budget) for k in range(budget)]  # 8 x its budget: beyond PACE_MARGIN, within the wide margin
    assert _steps_until_stopped(budget, beyond) == late
    # a transient: 80 % of the early steps at a pace of 1e9 steps to t_end, the last ones at 2 x the budget's pace
    slow, fast = 1e-9, 1 / (2 * budget)
    growing: list[float] = []
    for k in range(budget):
        growing.append((growing[-1] if growing else 0.0) + (slow if k < 0.8 * early else fast))
    assert _steps_until_stopped(budget, growing) is None  # the last quarter's pace: it finishes within its budget
    assert runs.remaining(growing[:early], 4) < runs.remaining(growing[:early])


def test_a_pace_is_never_judged_from_a_runs_first_steps() -> None:
    """A paced run's first PACE_STEPS steps are not judged (scipy's first steps are tiny by design): with a
    budget of 6 it runs to its budget, not stopped after 2 with a pace of 'about 7.96e+04 steps to t_end'."""
    small = runs._paced(6, None)
    for _ in range(6):
        small(1e-7)  # no Unaffordable: 6 steps are below PACE_STEPS
    large = runs._paced(400, None)
    with pytest.raises(runs.Unaffordable) as stopped:
        for _ in range(400):
            large(1e-7)
    assert stopped.value.steps == max(round(runs.PACE_EARLY * 400), runs.PACE_STEPS)  # no progress at all: far beyond, judged early
    # the pace is the latter half's: 10 tiny first steps, then 10 of 1% each, leave 90 such steps to t_end (not 180)
    done = [1e-9 * (k + 1) for k in range(10)] + [0.01 * (k + 1) for k in range(10)]
    assert runs.remaining(done) == pytest.approx(90.0, rel=1e-6)
    assert runs.remaining([0.0, 0.0]) == math.inf
    model = model_from(ELASTIC)
    setup = Setup(10.0, tuple(np.linspace(0.0, 10.0, 11).tolist()), max_steps=6)
    point = runs.measure(model, Candidate("Radau", "python"), 1e-5, setup, None, np.ones(4), repeats=0, paced=True)  # type: ignore[arg-type]
    assert point.status == PointStatus.OVER_BUDGET and point.steps == 6 and "at that pace" not in point.reason
    # where it stopped is a field (`Point.reached`, the share of the span), which `stress._capped`'s reason uses
    assert point.reached is not None and 0.0 < point.reached < 1.0 and f"at {100 * point.reached:.0f}% of the time span" in point.reason


@pytest.mark.skipif(not compile.numba_available(), reason="the tighter confirmations are compiled runs")
def test_an_implicit_reference_is_vouched_for_near_its_own_tolerance(monkeypatch: pytest.MonkeyPatch) -> None:
    """Started at r = 0.01, over t = 5, with an implicit reference (Radau at rtol 1e-10), whose first
    confirmation (compiled RK45 at 0.1 x the accuracy, 1e-7) is itself about 9e-6 off. That looser run's own
    error is not the reference's: compiled DOP853 confirms it again a decade tighter at a time, and the own
    error then bounds the reference's true error (against compiled DOP853 at 1e-12, 1e3 x more accurate).
    The start is not stiff (its falling phi_dot is its own motion, `diagnostics.own_rate`: the reference
    `stress` makes is compiled DOP853), so the implicit reference is asked for here as a stiff start would."""
    model = model_from(ELASTIC).with_definitions()
    target = 1e-6
    setup = Setup(5.0, tuple(np.linspace(0.0, 5.0, 501).tolist()), initial={"r": 0.01}, max_steps=stress.MAX_STEPS)
    assert not reference.stiff_start(model, setup)
    monkeypatch.setattr(reference, "stiff_start", lambda model, setup: True)
    found = reference.computed_reference(model, setup, stress.reference_tolerance(target), implicit=stress.implicit_reference_tolerances(target))
    assert found.settings is not None and found.settings.method == "Radau"
    assert found.own_error <= stress.REFERENCE_ROOM * target, found.description
    assert found.confirmed_rtol < 0.1 * target and "first confirmed by RK45 (compiled) at rtol 1e-07" in found.description
    tight = run(model, Candidate("DOP853", "compiled"), 1e-12, setup, reference=True)
    assert not tight.failed
    truth = float(np.max(scaled_errors(found.y, tight.y, component_scale(tight.y))))
    assert truth <= found.own_error


def test_an_open_verdict_names_why_the_own_error_is_what_it_is() -> None:
    """A looser confirmation is named as the cause, not round-off; an own error set by the primary's own
    method 10 x looser says so; a pair at equal terms is what round-off or sensitivity limits."""
    model = model_from(ELASTIC)
    settings = runs.settings_for(model, Candidate("Radau"), 1e-10, Setup(1.0, (0.0, 1.0)))
    empty = np.zeros((1, 4))
    base = reference.Reference("computed", "", 1.7e-5, np.zeros(1), empty, np.zeros(1), 0.0, settings, 1e-7, "RK45 (compiled) at rtol 1e-07")
    assert "ran looser than the reference's rtol 1e-10" in stress._why_own(base) and "round-off" not in stress._why_own(base)
    same = replace(base, confirmed_rtol=1e-10, confirmation="LSODA (python) at the same tolerance")
    assert "round-off" in stress._why_own(same)
    floored = replace(same, own_error=4e-8, convergence=4e-8)
    assert "10 x looser" in stress._why_own(floored) and not math.isnan(floored.convergence)


@pytest.mark.skipif(not compile.numba_available(), reason="the compiled run that caps scipy's is compiled")
def test_a_bundled_non_stiff_system_gets_no_finding_from_runs_that_could_only_lose() -> None:
    """audit4's F0: on the double pendulum every regime said "explicit step count explodes: DOP853 took 86 steps
    against Radau's 1", and listed scipy's runs, stopped after 1-8 steps at a cap of 4-31 steps set by compiled
    DOP853's meeting run, as findings ("over step budget"). Capped runs are "capped", not findings."""
    model = model_from(ROOT / "systems" / "double_pendulum.yaml")
    defaults = replace(stress.regimes(model, ())[0], t_end=2.0, samples=201)  # a shorter window: the same caps, a cheaper test
    outcome = stress._regime(model, defaults, 1e-6, stress.default_candidates(model), Setup(0.0, (), max_steps=stress.MAX_STEPS), None)
    assert outcome.verdict == "met" and outcome.recommended is not None and outcome.recommended.ran is not None
    assert outcome.recommended.ran.backend == "compiled"
    kinds = [f.kind for f in outcome.diagnosis.findings]
    assert "explicit step count explodes" not in kinds, kinds
    python = [p for p in outcome.points if p.ran is not None and p.ran.backend == "python"]
    assert python and all(p.status in (PointStatus.CAPPED, PointStatus.FINISHED) for p in python), [(p.method, p.status, p.reason) for p in python]
    capped = [p for p in python if p.status == PointStatus.CAPPED]
    assert capped and all("which meets the accuracy" in p.reason for p in capped)
    assert not any(p.method in f for p in capped for f in outcome.diagnosis.findings)


def test_accuracy_marks_a_losing_run_capped(monkeypatch: pytest.MonkeyPatch) -> None:
    """`accuracy`'s run stopped at LOSING x the cheapest run's work at its rtol is "capped", with why (audit4's F1:
    no Radau row, "over budget after 3 steps"); a run the user's budget stops stays "over step budget"."""
    from lagrange_cli.numeric import accuracy

    model = model_from(ROOT / "tests" / "numeric_audit2" / "elastic_pendulum_r_k1e8.yaml")
    monkeypatch.setattr(accuracy, "default_candidates", lambda model: (Candidate("RK45", "python"), Candidate("LSODA")))
    found = accuracy.study(model, tolerances=[1e-4, 1e-5], t_end=0.5, samples=11, repeats=0)
    at = {(p.candidate.method, p.tolerance): p for p in found.points if p.candidate is not None}
    explicit, lsoda, tighter = at[("RK45", 1e-4)], at[("LSODA", 1e-4)], at[("RK45", 1e-5)]
    assert lsoda.ok and explicit.status == PointStatus.CAPPED and "x the work of the cheapest run at rtol 1e-04" in explicit.reason
    assert tighter.method == explicit.method and tighter.status == PointStatus.CAPPED and "was capped already" in tighter.reason
    starved = accuracy.study(model, candidates=[Candidate("RK45", "python")], tolerances=[1e-4], t_end=0.5, samples=11, repeats=0, max_steps=3)
    assert starved.points[0].status == PointStatus.OVER_BUDGET


def test_a_high_energy_regime_from_rest_says_how_its_velocities_were_set() -> None:
    """audit4's F3: a file at rest got "high energy (velocities x 3)" with velocities that are not 3 x 0."""
    rest = next(r for r in stress.regimes(model_from(ELASTIC), ()) if r.name.startswith("high energy"))
    assert "at rest in the file" in rest.name and any(rest.initial.values())
    moving = next(r for r in stress.regimes(model_from(ROOT / "systems" / "spherical_pendulum.yaml"), ()) if r.name.startswith("high energy"))
    assert moving.name == "high energy (velocities x 3)"


def test_growing_modes_of_an_orbit_that_is_not_chaotic_are_not_called_instability() -> None:
    """audit4's F4, F7: "unstable modes: growth rate up to 7.33/s" on Kepler's orbit and a trammel, both integrable.
    The finding is "growing modes in the linearization", and where runs started apart were not found chaotic it says
    so, with the growth measured (not "no exponential growth": a 3400 x growth is not none, audit4 F6)."""
    found = stress.Finding(stress.GROWING, "growth rate up to 7.33/s (a saddle, chaos or constraint drift; not stiffness: decays matched by growth are not counted)")
    parting = reference.Horizon(2.5e-14, False, 0.0, math.inf, 3.4e3)
    local = stress._local(found, parting)
    assert local.kind == stress.GROWING and local.detail.startswith(found.detail)
    assert "end 3.4e+03 x farther apart, growing less than 100 x over the window's second half: not counted as chaos" in local.detail
    assert "unstable" not in str(local)
