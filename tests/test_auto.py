"""`--method auto` decides from a short pilot run (policy.pilot), not from one linearisation at t = 0.

The audit's case: a cart-pendulum whose cart is damped at 1e6/s, started with the cart moving.
The old rule picked compiled DOP853 there (1.46e6 stability-limited steps); an implicit method
needs about 1200. Counted in steps, never in seconds.
"""

from __future__ import annotations

import numpy as np
import pytest

from lagrange_cli.numeric import compile, integrators, memo, policy, status
from lagrange_cli.numeric.simulate import simulate
from tests.conftest import ROOT
from tests.helpers import model_from

pytestmark = pytest.mark.usefixtures("private_cache")
AUDIT = ROOT / "tests" / "numeric_audit_pilot"
STIFF_CAPABLE = ("LSODA", "Radau", "BDF")


def test_fast_damped_cart_with_a_transient_picks_a_stiff_method_and_far_fewer_steps_than_dop853() -> None:
    model = model_from(AUDIT / "cart_pendulum_damped.yaml")
    auto = simulate(model, method="auto", samples=11)
    assert auto.status == "finished", auto.message
    assert auto.settings.method in STIFF_CAPABLE, auto.notes
    # DOP853 on the same run: stability-limited, it stops at a 3000-step budget after a sliver of the span
    explicit = simulate(model, method="DOP853", backend="python", samples=11, max_steps=3000)
    assert explicit.outcome == "budget" and explicit.t_last < 0.1, explicit.message
    projected_steps = explicit.stats.steps * auto.settings.t_end / explicit.t_last
    assert projected_steps > 100 * auto.stats.steps, (projected_steps, auto.stats.steps)
    note = next(n for n in auto.notes if n.startswith("method auto ->"))
    assert "pilot run" in note and "decay" in note and "steps" in note, note  # says why, with the measured numbers


@pytest.mark.parametrize("name", ["cart_pendulum_damped_rest.yaml", "stiff_elastic_pendulum_r.yaml"])
def test_stiff_audit_cases_pick_a_stiff_method(name: str) -> None:
    # the cart at rest; the damped elastic pendulum at k = 1e10 written in r (Radau fails on it, LSODA takes ~1500 steps)
    settings = policy.resolve(model_from(AUDIT / name), method="auto")
    assert settings.method in STIFF_CAPABLE, settings.notes


@pytest.mark.parametrize("path", [AUDIT / "double_pendulum_nonstiff.yaml", ROOT / "systems" / "double_pendulum.yaml", ROOT / "systems" / "stiff_spring_pendulum.yaml"])
def test_non_stiff_systems_keep_the_explicit_method(path: object) -> None:
    # the double pendulum; the undamped stiff spring (fast but oscillatory: an implicit method buys nothing)
    settings = policy.resolve(model_from(path), method="auto")  # type: ignore[arg-type]
    assert settings.method == "DOP853", settings.notes
    assert any("not stiff along a pilot run" in note for note in settings.notes), settings.notes


def test_the_pilot_measures_stiffness_along_the_run_not_only_at_the_start() -> None:
    """A damper that acts only once the cart has moved (R = c x^2 x_dot^2 / 2, c = 1e15): at t = 0
    (x = 0) the linearisation has no decay at all; along the pilot the cart stops near x = 1.4e-5,
    where the decay c x^2 / M is about 2e5/s."""
    from tests.helpers import model_of

    text = (AUDIT / "cart_pendulum_damped.yaml").read_text().replace("dissipation: c*x_dot**2/2", "dissipation: c*x**2*x_dot**2/2")
    model = model_of(text, "cart_late_damper.yaml")
    settings = policy.resolve(model, method="auto", parameters={"c": 1e15})
    start = policy.initial_spectrum(model, settings.values, settings.y0)
    assert start is not None and start.decay == 0.0  # one linearisation at t = 0 sees nothing
    found = policy.pilot(model, settings)
    assert found is not None and found.worst.decay > 1e4 and found.t_worst > 0
    assert settings.method in STIFF_CAPABLE, settings.notes


AUDIT2 = ROOT / "tests" / "numeric_audit2"
IMPLICIT = ("Radau", "compiled") if compile.numba_available() else ("LSODA", "python")
"""What `auto` runs a stiff system with: compiled Radau where numba runs (issue 15), else LSODA."""


def test_the_pilot_runs_until_lsoda_steps_with_bdf_on_a_stiff_start() -> None:
    """The damped elastic pendulum in r at k = 1e11 (moving start): LSODA steps with Adams,
    stability-limited at ~1.5e-6, for its first ~230 steps, then switches to BDF. A pilot stopped
    before the switch extrapolated Adams's step to 3.2e6 LSODA steps (the whole run takes ~1200) and
    `auto` took compiled DOP853, which needs 1.2e6 step attempts (a third of them rejected)."""
    model = model_from(AUDIT2 / "elastic_pendulum_r_k1e11.yaml")
    settings = policy.resolve(model, method="auto")
    assert (settings.method, settings.backend) == IMPLICIT, settings.notes
    measured = policy.pilot(model, settings)
    assert measured is not None and measured.bdf and measured.switches >= 1
    assert measured.implicit_steps(settings.t_end) < 5000, measured
    note = next(n for n in settings.notes if n.startswith("method auto ->"))
    assert "in BDF" in note, note


def test_the_explicit_probe_counts_the_step_attempts_dop853_really_takes() -> None:
    """Where the decay alone would let compiled DOP853 win (the same pendulum at k = 2e8 over t = 5:
    decay 1e4/s, ~8300 stability-limited steps against 25 x ~750 LSODA steps), a short DOP853
    probe (used where `auto` cannot start with the compiled run: kept constraints) measures the
    attempts, rejections included: ~1.9 x the decay's estimate (2.5 x when the force was computed k*l - k*r). The probe's rate agrees with a
    budget-limited DOP853 run from the start (counted in evaluations), and with the rate `auto`
    measures on the compiled run it started with, gone on past the stiffness; the attempts that run
    needs for the rest of the run against IMPLICIT_COST x the pilot's LSODA steps decide (there:
    DOP853, 14 098 steps; 0.017 s CPU against LSODA's 0.027 s)."""
    model = model_from(AUDIT2 / "elastic_pendulum_r_k1e11.yaml")
    settings = policy.resolve(model, method="auto", parameters={"k": 2e8})
    measured = policy.pilot(model, settings)
    assert measured is not None
    estimate, implicit = measured.explicit_steps(settings.t_end), measured.implicit_steps(settings.t_end)
    assert estimate <= policy.IMPLICIT_COST * implicit  # the decay's estimate alone would pick DOP853
    probe = policy.explicit_probe(model, settings, measured)
    assert not probe.failed and probe.steps == policy.PROBE_STEPS
    attempts = probe.attempts(settings.t_end)
    assert attempts > 1.5 * estimate, (attempts, estimate)  # 1.9 x since the spring force is k*(l - r) (offset18), 2.5 x with k*l - k*r
    explicit = simulate(model, method="DOP853", backend="python", parameters={"k": 2e8}, samples=11, max_steps=3000)
    assert explicit.outcome == "budget"
    measured_attempts = explicit.stats.nfev / policy.DOP853_EVALUATIONS * settings.t_end / explicit.t_last
    assert 0.5 < attempts / measured_attempts < 2.0, (probe, measured_attempts)
    compiled = policy.measure_attempt(model, settings, policy.explicit_attempt(model, settings))  # as `auto` measured it (once per settings)
    assert compiled.rate is not None and 0.5 < compiled.rate / probe.rate < 2.0, (compiled, probe)
    cost = policy.RADAU_COST if compile.numba_available() else policy.IMPLICIT_COST
    close = estimate <= cost * implicit  # else the decay's estimate alone picks the implicit method
    cheaper = close and compiled.left(settings.t_end) <= cost * implicit
    assert settings.method == ("DOP853" if cheaper else IMPLICIT[0]), settings.notes
    note = next(n for n in settings.notes if n.startswith("method auto ->"))
    assert not close or ("the compiled DOP853 run, gone on to" in note and "more step attempts at its measured rate" in note), note


@pytest.mark.parametrize(("name", "cached"), [("chain_mixed_stiffness.yaml", False), ("van_der_pol_force.yaml", False), ("driven_coupled_oscillators.yaml", False), ("kepler_e09.yaml", True)])
def test_a_run_compiled_dop853_does_cheaply_is_the_run_auto_starts_with_and_no_pilot_runs(name: str, cached: bool) -> None:
    """`auto` starts the run itself with compiled DOP853 and Hairer's stiffness test (at most
    ATTEMPT_STEPS steps) where it would run DOP853 compiled: a long run for its rates, or a system
    compiled already (Kepler: a short run, compiled once first). On these (160-6000 steps; the chain and
    van der Pol have a few steps limited by stability, then need fewer than ATTEMPT_STEPS more) that run
    goes on to the end: the same steps and samples as `--method DOP853 --backend compiled`, and no
    LSODA pilot or Python probe is spent."""
    model = model_from(AUDIT2 / name)
    if cached:
        simulate(model, method="DOP853", backend="compiled", samples=2, t_end=1e-3)
        model.__dict__.pop(memo.SLOT, None)
    auto = simulate(model, method="auto", samples=21, backend="compiled" if cached else "auto")  # the cache check of a short run depends on the suite's cache dir
    assert (auto.settings.method, auto.settings.backend) == ("DOP853", "compiled"), auto.notes
    store = model.__dict__[memo.SLOT]
    assert not any(isinstance(key, tuple) and key[0] in ("pilot", "explicit probe") for key in store), list(store)  # decided without them
    note = next(n for n in auto.notes if n.startswith("method auto ->"))
    assert "the compiled DOP853 run itself finished" in note or "more steps at its step" in note, note
    alone = simulate(model, method="DOP853", backend="compiled", samples=21)
    assert auto.stats.steps == alone.stats.steps and auto.stats.nfev == alone.stats.nfev
    assert np.array_equal(auto.t, alone.t) and np.array_equal(auto.y, alone.y)  # one run, paused and gone on: the same run


def test_a_stiff_start_stops_the_compiled_run_within_a_few_hundred_steps() -> None:
    """The damped cart (decay 9e5/s): compiled DOP853 would take 1.46e6 steps; Hairer's test stops it
    after a few hundred, the pilot then picks LSODA."""
    model = model_from(AUDIT / "cart_pendulum_damped.yaml")
    settings = policy.validate(model, method="auto")
    found = policy.explicit_attempt(model, settings)
    assert found.stiff_at is not None and not found.ended and found.h_lambda > status.STIFF_H_LAMBDA, found
    assert found.steps < 1000, found
    decided = policy.decide(model, settings)
    assert (decided.method, decided.backend) == IMPLICIT, decided.notes


def test_the_kernel_pauses_on_stiffness_and_goes_on_to_the_same_run() -> None:
    """kernels._stiffness_test: on the damped stiff spring at k = 1e10 (decay 1e6/s), DOP853's accepted
    steps sit at h |lambda| ~ 6-7 and the loop pauses after STIFF_STEPS of them; going on from the pause
    gives exactly the run made straight through (pausing changes no step)."""
    model = model_from(ROOT / "systems" / "stiff_spring_pendulum_damped.yaml")
    settings = policy.validate(model, method="DOP853", backend="compiled", parameters={"k": 1e10}, t_end=0.01, samples=5)
    numba = compile.build(model, "numba")
    problem = integrators.Problem(0.0, settings.t_end, np.array(settings.y0), np.array(settings.t_eval), np.array(settings.p), False, 10**6)
    loop = integrators.ErkLoop(numba, problem, "DOP853", settings.rtol, settings.atol, settings.max_step)
    assert loop.advance(policy.ATTEMPT_STEPS, stiffness=True) == status.RUNNING
    assert loop.stiff and loop.stats[status.H_LAMBDA] > status.STIFF_H_LAMBDA and loop.steps < 1000, loop.stats
    paused = loop.finish()
    straight = integrators.run_erk(numba, problem, "DOP853", settings.rtol, settings.atol, settings.max_step)
    assert paused.status == straight.status == "finished"
    assert paused.stats == straight.stats and np.array_equal(paused.y, straight.y)
    free = integrators.ErkLoop(numba, problem, "DOP853", settings.rtol, settings.atol, settings.max_step)
    assert free.advance(100) == status.RUNNING and free.steps == 100 and not free.stiff  # no test asked: pauses by its step count only


def test_a_close_choice_is_made_from_the_measured_cost_of_the_rest_of_the_run() -> None:
    """The damped stiff spring at k = 1e8 (decay 1e4/s over t = 10): the compiled run is found stiff early,
    the pilot too, and the decay's estimate is close; the paused run goes on MEASURE_STEPS steps, and its
    measured attempts for the rest of the run against IMPLICIT_COST x the pilot's LSODA steps decide
    (what is already done is not counted: it is paid either way)."""
    model = model_from(ROOT / "systems" / "stiff_spring_pendulum_damped.yaml")
    settings = policy.validate(model, method="auto")
    decided = policy.decide(model, settings)
    found = policy.explicit_attempt(model, settings)
    assert found.stiff_at is not None
    measured = policy.pilot(model, settings)
    assert measured is not None
    after = policy.measure_attempt(model, settings, found)  # as `decide` measured it (once per settings)
    assert after.rate is not None and after.steps > found.steps
    cost = policy.RADAU_COST if compile.numba_available() else policy.IMPLICIT_COST
    close = measured.explicit_steps(settings.t_end) <= cost * measured.implicit_steps(settings.t_end)  # else the decay's estimate decides
    cheaper = close and after.left(settings.t_end) <= cost * measured.implicit_steps(settings.t_end)
    assert decided.method == ("DOP853" if cheaper else IMPLICIT[0]), decided.notes
    note = next(n for n in decided.notes if n.startswith("method auto ->"))
    assert not close or "more step attempts at its measured rate" in note, note


def test_a_paused_run_past_the_step_budget_stops_there() -> None:
    """The undamped stiff spring (14 868 DOP853 steps): the compiled run `auto` starts with pauses at
    ATTEMPT_STEPS, the pilot finds it not stiff and it goes on, unless the caller's budget is smaller: then
    the run starts afresh and stops at its budget, to the step (audit 12: --max-steps 50 took 2000)."""
    model = model_from(ROOT / "systems" / "stiff_spring_pendulum.yaml")
    short = simulate(model, method="auto", samples=11, max_steps=5000)
    assert short.outcome == "budget" and short.stats.steps == 5000 < policy.ATTEMPT_STEPS, (short.stats, short.notes)
    assert any("took 10000 steps, more than the step budget (5000): the run started afresh" in note for note in short.notes), short.notes
    whole = simulate(model, method="auto", samples=11)
    assert whole.status == "finished" and whole.settings.method == "DOP853" and whole.stats.steps > policy.ATTEMPT_STEPS, whole.notes
    assert any("goes on from t =" in note for note in whole.notes), whole.notes
