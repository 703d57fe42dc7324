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
