"""`--method auto` decides from a short pilot run (policy.pilot), not from one linearisation at t = 0.

The audit's case: a cart-pendulum whose cart is damped at 1e6/s, started with the cart moving.
The old rule picked compiled DOP853 there (1.46e6 stability-limited steps); an implicit method
needs about 1200. Counted in steps, never in seconds.
"""

from __future__ import annotations

import pytest

from lagrange_cli.numeric import policy
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


def test_the_pilot_runs_until_lsoda_steps_with_bdf_on_a_stiff_start() -> None:
    """The damped elastic pendulum in r at k = 1e11 (moving start): LSODA steps with Adams,
    stability-limited at ~1.5e-6, for its first ~230 steps, then switches to BDF. A pilot stopped
    before the switch extrapolated Adams's step to 3.2e6 LSODA steps (the whole run takes ~1200) and
    `auto` took compiled DOP853, which needs 1.2e6 step attempts (a third of them rejected)."""
    model = model_from(AUDIT2 / "elastic_pendulum_r_k1e11.yaml")
    settings = policy.resolve(model, method="auto")
    assert settings.method == "LSODA", settings.notes
    measured = policy.pilot(model, settings)
    assert measured is not None and measured.bdf and measured.switches >= 1
    assert measured.implicit_steps(settings.t_end) < 5000, measured
    note = next(n for n in settings.notes if n.startswith("method auto ->"))
    assert "in BDF" in note, note


def test_the_explicit_probe_counts_the_step_attempts_dop853_really_takes() -> None:
    """Where the decay alone would let compiled DOP853 win (the same pendulum at k = 2e8 over t = 5:
    decay 1e4/s, ~8300 stability-limited steps against 20 x ~750 LSODA steps), a short DOP853
    probe measures the attempts, rejections included: ~2.5 x the decay's estimate, so LSODA. The
    probe's rate agrees with a budget-limited DOP853 run from the start (counted in evaluations)."""
    model = model_from(AUDIT2 / "elastic_pendulum_r_k1e11.yaml")
    settings = policy.resolve(model, method="auto", parameters={"k": 2e8})
    measured = policy.pilot(model, settings)
    assert measured is not None
    estimate, implicit = measured.explicit_steps(settings.t_end), measured.implicit_steps(settings.t_end)
    assert estimate <= policy.IMPLICIT_COST * implicit  # the decay's estimate alone would pick DOP853
    probe = policy.explicit_probe(model, settings, measured)
    assert not probe.failed and probe.steps == policy.PROBE_STEPS
    attempts = probe.attempts(settings.t_end)
    assert attempts > 2 * estimate, (attempts, estimate)
    assert attempts > policy.IMPLICIT_COST * implicit and settings.method == "LSODA", settings.notes
    assert any("DOP853 probe" in n for n in settings.notes), settings.notes
    explicit = simulate(model, method="DOP853", backend="python", parameters={"k": 2e8}, samples=11, max_steps=3000)
    assert explicit.outcome == "budget"
    measured_attempts = explicit.stats.nfev / policy.DOP853_EVALUATIONS * settings.t_end / explicit.t_last
    assert 0.5 < attempts / measured_attempts < 2.0, (probe, measured_attempts)


@pytest.mark.parametrize("name", ["chain_mixed_stiffness.yaml", "van_der_pol_force.yaml", "driven_coupled_oscillators.yaml"])
def test_mildly_stiff_cases_keep_dop853_when_the_probe_finds_it_cheaper(name: str) -> None:
    # benchmarks/auto_bench.py: on these compiled DOP853 is the fastest or within 2x of it
    settings = policy.resolve(model_from(AUDIT2 / name), method="auto")
    assert settings.method == "DOP853", settings.notes
    note = next(n for n in settings.notes if n.startswith("method auto ->"))
    assert "DOP853 probe" in note, note
