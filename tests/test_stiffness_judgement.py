"""Stiffness is a decay far faster than the solution itself changes, not any decaying eigenvalue.

audit4 F4: on Kepler's orbit e = 0.8 in polar coordinates, `stress`'s high-energy regime (an escape)
was judged stiff ("stiffness ratio 387"), so its reference was implicit and RK45 was "not run: stiff".
There phi_dot = L / r^2 falls as r grows: the Jacobian's eigenvalue -2 r_dot / r is the solution's
own motion (it changes at about r_dot / r itself), which an explicit method resolves for accuracy
anyway. The audits' stiff systems (dampers of 1e5-1e6/s, springs of k = 1e8-1e11 written in their
length, a chain of mixed stiffness) must still be judged stiff. Everything is counted (rates, steps,
judgements), never timed.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate

from lagrange_cli.numeric import compile, diagnostics, policy, reference, stress
from lagrange_cli.numeric.runs import Setup
from lagrange_cli.numeric.settings import code_parameters
from tests.conftest import ROOT
from tests.helpers import model_from

pytestmark = pytest.mark.usefixtures("private_cache")
KEPLER = ROOT / "tests" / "numeric_audit4" / "kepler_e08_polar.yaml"
PERIAPSIS_RATE = 21.516574145596763
ESCAPE = {"phi_dot": 3 * PERIAPSIS_RATE}  # `stress`'s high-energy regime: the file's velocities x 3
T_END = 87.60353237


def _rhs(model, setup: Setup):  # type: ignore[no-untyped-def]
    s = reference.start_of(model, setup)
    return policy.safe_rhs(compile.build(model, "python").module, code_parameters(s.values, None)), s


def test_a_decay_slower_than_own_times_the_solutions_rate_is_its_motion_not_stiffness() -> None:
    jacobian = np.diag([-1e4, -1.0])  # a fast decay and a slow one
    assert diagnostics.OWN * 1.0 < 1e4 < diagnostics.OWN * 5e3
    fast = diagnostics.spectrum(jacobian, own=1.0)  # the solution moves at 1/s: the 1e4/s mode is one it has left
    assert fast is not None and fast.decay == 1e4 and fast.followed == 1.0 and diagnostics.stiff(fast, 10.0)  # the slow decay is its motion
    moving = diagnostics.spectrum(jacobian, own=5e3)  # the solution itself changes at 5e3/s: the decay is its own motion
    assert moving is not None and moving.decay == 0 and moving.followed == 1e4 and not diagnostics.stiff(moving, 10.0)
    unknown = diagnostics.spectrum(jacobian)  # no rate given: every decay counts, as before
    assert unknown is not None and unknown.decay == 1e4 and diagnostics.stiff(unknown, 10.0)
    y = np.array([3.0, 4.0])
    assert diagnostics.own_rate(np.array([0.6, 0.8]), y) == pytest.approx(0.2)
    assert diagnostics.own_rate(np.zeros(2), y) == 0.0 and diagnostics.own_rate(None, y) == 0.0


def _escape(model, setup: Setup, times: np.ndarray):  # type: ignore[no-untyped-def]
    rhs, s = _rhs(model, setup)
    solved = scipy.integrate.solve_ivp(lambda t, y: rhs(t, y), (0.0, float(times[-1])), np.array(s.y0), method="DOP853", rtol=1e-10, atol=1e-13, t_eval=times)
    assert solved.success
    return rhs, solved.t, solved.y.T


def test_a_polar_orbits_falling_angular_velocity_is_not_stiffness() -> None:
    """Along the escape's first 0.6 s (r from 0.18 to about 5): phi_ddot = -2 r_dot phi_dot / r, an
    eigenvalue near -2 r_dot / r, up to 17/s where no growth matches it (x t_end = 1.5e3: 'stiff' by
    the decay alone), while the solution itself changes at about r_dot / r."""
    model = model_from(KEPLER)
    setup = Setup(T_END, (), {}, ESCAPE)
    rhs, times, states = _escape(model, setup, np.linspace(0.0, 0.6, 61))
    raw = [diagnostics.spectrum(diagnostics.jacobian(rhs, float(t), y)) for t, y in zip(times, states, strict=True)]  # type: ignore[arg-type]
    k = int(np.argmax([x.decay if x is not None else 0.0 for x in raw]))
    t, y, before = float(times[k]), states[k], raw[k]
    assert before is not None and before.decay * T_END > diagnostics.STIFF  # the decay alone, counted as before
    r, r_dot = y[0], y[2]
    assert 0.3 < before.decay / (2 * r_dot / r) < 3  # of the order of 2 r_dot / r (coupled to r through phi_dot^2)
    own = diagnostics.own_rate(rhs(t, y), y)
    judged = diagnostics.spectrum(diagnostics.jacobian(rhs, t, y), own)  # type: ignore[arg-type]
    assert judged is not None and judged.decay == 0 and judged.followed == pytest.approx(before.decay)
    assert before.decay <= 0.5 * diagnostics.OWN * own  # with room: within half the line
    assert not reference.stiff_at(model, setup, t, y)


def test_keplers_escape_is_not_stiff_along_its_pilot_nor_in_stress_diagnosis() -> None:
    model = model_from(KEPLER).with_definitions()
    setup = Setup(T_END, (), {}, ESCAPE)
    assert not reference.stiff_start(model, setup)  # so the reference is explicit (was Radau, "stiff at the start")
    assert reference.stable_steps(model, setup, "RK45") == 0  # and RK45 is run (was "not run: stiff ... 759 steps")
    s = reference.start_of(model, setup)
    measured = policy.pilot(model, s)
    assert measured is not None and measured.followed * T_END > diagnostics.STIFF and not diagnostics.stiff(measured.worst, T_END)
    _, times, states = _escape(model, setup, np.linspace(0.0, 0.6, 25))  # the escape's start, judged over the regime's t_end
    found = stress._measure(model, setup, times, states, None, T_END)
    assert found.decay_span == 0 and found.stiffness_ratio == 0, found  # was "decay x t_end 48.1, stiffness ratio 387" over the whole run
    assert found.followed > diagnostics.STIFF  # the decay is there, and said to be the orbit's own motion
    assert not any(f.kind.startswith("stiff") for f in found.findings), found.findings
    from lagrange_cli.cli.study import _measurements

    assert "own motion" in _measurements(found)


STIFF_FILES = [
    ROOT / "tests" / "numeric_audit_pilot" / "stiff_elastic_pendulum_r.yaml",  # k = 1e10 in r, damped
    ROOT / "tests" / "numeric_audit2" / "elastic_pendulum_r_k1e8.yaml",
    ROOT / "tests" / "numeric_audit2" / "elastic_pendulum_r_k1e11.yaml",
    ROOT / "tests" / "numeric_audit4" / "cart_pendulum_damper_1e5_driven.yaml",
    ROOT / "tests" / "numeric_audit2" / "chain_mixed_stiffness.yaml",
]


@pytest.mark.parametrize("path", STIFF_FILES, ids=lambda p: p.stem)
def test_true_stiffness_is_still_stiff(path: object) -> None:
    """After its transient the solution moves at 1-50/s, the fast mode decays at 3e3-1e6/s."""
    model = model_from(path).with_definitions()  # type: ignore[arg-type]
    s = policy.resolve(model, method="DOP853", backend="python")
    setup = Setup(s.t_end, (), {}, {})
    assert reference.stiff_start(model, setup)
    rhs, _ = _rhs(model, setup)
    y = np.array(s.y0)
    solved = scipy.integrate.solve_ivp(lambda t, y: rhs(t, y), (0.0, 0.05 * s.t_end), y, method="LSODA", rtol=1e-8, atol=1e-11)
    assert solved.success
    t, here = float(solved.t[-1]), solved.y[:, -1]
    assert reference.stiff_at(model, setup, t, here)  # past the transient, on the slow motion
    judged = diagnostics.spectrum(diagnostics.jacobian(rhs, t, here), diagnostics.own_rate(rhs(t, here), here))  # type: ignore[arg-type]
    assert judged is not None and judged.decay > 3 * diagnostics.OWN * judged.own  # with room: a factor 3 beyond the line (the chain: 5)


def test_a_fast_transient_is_the_solutions_motion_only_while_it_lasts() -> None:
    """Audit 1's cart with a 1e6/s damper, started moving (where `auto` once took DOP853, 21 x slower than
    Radau): at t = 0 the cart's velocity itself dies at that rate (own rate ~1e6/s), so one linearisation
    there sees its own motion; along the pilot, past the transient, the solution moves at a few per
    second and the same decay is stiffness: the reference is implicit, `auto` takes a stiff method and
    `stress`'s diagnosis says stiff."""
    model = model_from(ROOT / "tests" / "numeric_audit_pilot" / "cart_pendulum_damped.yaml").with_definitions()
    s = policy.resolve(model, method="DOP853", backend="python")
    start = policy.initial_spectrum(model, s.values, s.y0)
    assert start is not None and start.decay == 0 and start.followed > 1e5  # the transient, at t = 0
    measured = policy.pilot(model, s)
    assert measured is not None and measured.t_worst > 0 and measured.worst.decay > 1e5 and diagnostics.stiff(measured.worst, s.t_end)
    setup = Setup(s.t_end, (), {}, {})
    assert reference.stiff_start(model, setup)
    assert policy.resolve(model, method="auto", backend="python").method in ("LSODA", "Radau", "BDF")  # the pilot decides (no compiled attempt)
    rhs, _ = _rhs(model, setup)
    solved = scipy.integrate.solve_ivp(lambda t, y: rhs(t, y), (0.0, s.t_end), np.array(s.y0), method="LSODA", rtol=1e-8, atol=1e-11, t_eval=np.linspace(0.0, s.t_end, 201))
    assert solved.success
    found = stress._measure(model, setup, solved.t, solved.y.T, None, s.t_end)
    assert any(f.kind.startswith("stiff") for f in found.findings) and found.decay_span is not None and found.decay_span > 1e6, found


HENON_HEILES = """\
title: Henon-Heiles at energy 1/8, in polar coordinates (audit 5's system)
coordinates: [r, phi]
parameters:
  m: {value: 1.0}
  lam: {value: 1.0}
particles:
  p: {mass: m, position: [r*cos(phi), r*sin(phi)]}
potential: m*r**2/2 + lam*r**3*sin(3*phi)/3
initial: {r: 0.1, phi: -1.5707963267948966, r_dot: 0.25, phi_dot: 4.205155565889725}
simulate: {t_end: 60}
"""


def test_a_conservative_orbit_passing_the_polar_origin_is_not_stiff() -> None:
    """audit5 F2: Henon-Heiles (no dissipation at all) started at r = 0.01 (`stress`'s near-singular regime)
    was found "stiff (explicit affordable): a mode decays at up to 47.7/s (x t_end = 2.86e+03), stiffness
    ratio 2.48e+05"; its defaults showed "decay x t_end 471, stiffness ratio 936". Each passage near r = 0
    makes phi_dot = L / r^2 rise and fall at about r_dot / r: the orbit's own motion."""
    from tests.helpers import model_of

    model = model_of(HENON_HEILES, "henon_heiles_polar.yaml").with_definitions()
    regime = next(r for r in stress.regimes(model, ()) if r.name.startswith("near singular"))
    assert regime.initial.get("r") == 0.01
    setup = Setup(regime.t_end, (), regime.parameters, regime.initial)
    rhs, s = _rhs(model, setup)
    solved = scipy.integrate.solve_ivp(lambda t, y: rhs(t, y), (0.0, regime.t_end), np.array(s.y0), method="LSODA", rtol=1e-8, atol=1e-11, t_eval=np.linspace(0.0, regime.t_end, 2001))
    assert solved.success
    found = stress._measure(model, setup, solved.t, solved.y.T, None, regime.t_end)
    assert found.decay_span == 0 and found.followed > diagnostics.STIFF, found  # the decay is there, as the orbit's own motion
    assert not any(f.kind.startswith("stiff") for f in found.findings), found.findings
    assert not reference.stiff_start(model, setup)
