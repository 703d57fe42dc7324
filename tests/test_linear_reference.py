"""The exact reference of a linear system (exp(A t)) and the rungs a longer regime need not run again.

A linear, autonomous system's reference is its exact solution, checked here against closed forms the
test writes itself (not against the code's own numbers). A regime over a longer span with the same
start skips the rungs an earlier regime showed to miss: the rule rests on every such method taking the
same steps over the shared span, checked here bit for bit, and each skipped rung is run here to show
that it does miss.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from lagrange_cli.numeric import compile
from lagrange_cli.numeric.reference import autonomous_linear, exact_reference, linear_reference
from lagrange_cli.numeric.runs import Candidate, Setup, component_scale, run, scaled_errors, starting
from lagrange_cli.numeric.stress import PREFIX_METHODS, PREFIX_SLACK, stress

from .conftest import ROOT
from .helpers import model_from, model_of

needs_numba = pytest.mark.skipif(not compile.numba_available(), reason="numba (the fast extra) is not installed")

FALLING = """
title: A stone thrown up, and a damped block pushed by a constant force
coordinates: [z, x]
parameters:
  m: {value: 2.0}
  g: {value: 9.81}
  k: {value: 3.0}
  c: {value: 0.4}
  F: {value: 1.5}
kinetic: m*z_dot**2/2 + m*x_dot**2/2
potential: m*g*z + k*x**2/2 - F*x
dissipation: c*x_dot**2/2
initial: {z: 1.0, z_dot: 4.0, x: 0.2, x_dot: -0.1}
simulate: {t_end: 6}
"""


def _setup(model: object, t_end: float, samples: int, initial: dict[str, float] | None = None) -> Setup:
    return starting(model, Setup(t_end, tuple(np.linspace(0.0, t_end, samples).tolist()), initial=initial or {}))  # type: ignore[arg-type]


def test_the_linear_reference_is_the_closed_form_solution() -> None:
    """A free coordinate under a constant force (A singular, exp(B t) a Jordan block) and a damped spring under
    a constant force: against the closed forms, to round-off."""
    model = model_from_text = model_of(FALLING)
    assert autonomous_linear(model_from_text)
    setup = _setup(model, 6.0, 301)
    found = linear_reference(model, setup)
    assert found is not None and found.kind == "linear"
    t = np.array(setup.times)
    z = 1.0 + 4.0 * t - 9.81 * t**2 / 2
    # m x'' + c x' + k x = F: underdamped about x* = F/k
    m, k, c, force = 2.0, 3.0, 0.4, 1.5
    rate, omega = c / (2 * m), math.sqrt(k / m - (c / (2 * m)) ** 2)
    x0, v0, rest = 0.2, -0.1, force / k
    a, b = x0 - rest, (v0 + rate * (x0 - rest)) / omega
    x = rest + np.exp(-rate * t) * (a * np.cos(omega * t) + b * np.sin(omega * t))
    assert np.max(np.abs(found.y[:, 0] - z)) < 1e-11 * np.max(np.abs(z))
    assert np.max(np.abs(found.y[:, 1] - x)) < 1e-12
    assert np.max(np.abs(found.y[:, 2] - (4.0 - 9.81 * t))) < 1e-11
    assert 0 < found.own_error < 1e-11


def test_it_agrees_with_the_files_exact_solution_and_holds_for_any_start() -> None:
    model = model_from(ROOT / "systems" / "harmonic_oscillator.yaml")
    setup = _setup(model, 20.0, 401)
    exact = exact_reference(model, setup)
    found = linear_reference(model, setup)
    assert exact is not None and found is not None
    off = float(np.max(scaled_errors(found.y, exact.y, component_scale(exact.y))))
    assert off <= found.own_error < 1e-11  # its own error bounds how far it is from the closed form
    moved = linear_reference(model, _setup(model, 20.0, 401, {"x": 0.3, "x_dot": -2.0}))
    assert moved is not None
    t = np.array(setup.times)
    assert np.max(np.abs(moved.y[:, 0] - (0.3 * np.cos(2 * t) - 1.0 * np.sin(2 * t)))) < 1e-12


def test_only_linear_autonomous_systems_have_one() -> None:
    pendulum = model_from(ROOT / "systems" / "simple_pendulum.yaml")
    assert not autonomous_linear(pendulum) and linear_reference(pendulum, _setup(pendulum, 5.0, 11)) is None
    driven = model_of(FALLING.replace("potential: m*g*z + k*x**2/2 - F*x", "potential: m*g*z + k*x**2/2 - F*cos(t)*x"))
    assert not autonomous_linear(driven) and linear_reference(driven, _setup(driven, 5.0, 11)) is None
    # dry friction: piecewise constant in the state, which the generated Jacobian (d sign = 0) cannot tell from linear
    friction = model_of(FALLING.replace("dissipation: c*x_dot**2/2", "forces:\n  generalized: {x: -c*m*g*sign(x_dot)}"))
    assert not autonomous_linear(friction) and linear_reference(friction, _setup(friction, 5.0, 11)) is None
    gated = model_of(FALLING.replace("dissipation: c*x_dot**2/2", "forces:\n  generalized: {x: -c*Abs(x)*x_dot}"))
    assert not autonomous_linear(gated)


def test_a_solution_past_what_a_double_holds_has_none() -> None:
    """An inverted spring grows as exp(t): over t = 1000 no double holds it, and the reference is left to the runs."""
    model = model_of(FALLING.replace("k*x**2/2 - F*x", "-k*x**2/2 - F*x"))
    assert linear_reference(model, _setup(model, 1000.0, 101)) is None
    assert linear_reference(model, _setup(model, 2.0, 101)) is not None
    assert linear_reference(model, _setup(model, 2.0, 0)) is None  # no samples: nothing to measure against


@needs_numba
@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_a_longer_run_takes_the_same_steps_over_the_shorter_span(backend: str) -> None:
    """What the rungs skipped in a longer regime rest on: over the shorter span the samples before the shorter run's
    last step (clipped to end on its t_end; here from t = 1.89) are the same, bit for bit, for each method of
    PREFIX_METHODS, and those within it differ by far less than PREFIX_SLACK x rtol."""
    model = model_from(ROOT / "systems" / "double_pendulum.yaml").with_definitions()
    for method in PREFIX_METHODS:
        if backend == "compiled" and method == "BDF":
            continue  # scipy only
        short = run(model, Candidate(method, backend), 1e-6, _setup(model, 2.0, 41))
        longer = run(model, Candidate(method, backend), 1e-6, _setup(model, 20.0, 401))
        assert not short.failed and not longer.failed
        assert np.array_equal(short.y[:35], longer.y[:35]), method  # t <= 1.7
        assert np.max(np.abs(short.y - longer.y[:41]) / component_scale(longer.y)) < PREFIX_SLACK * 1e-6 / 10, method


@needs_numba
def test_the_long_horizon_skips_only_rungs_that_miss() -> None:
    """The weakly damped oscillators over t = 3000 and their long horizon (3e4): compiled DOP853's loose rungs missed
    over 3000 already, so the long horizon does not run them; each is run here over 3e4 and misses, by at least the
    bound the report gives."""
    model = model_from(ROOT / "tests" / "numeric_audit7" / "coupled_oscillators_weak_damping_t1e5.yaml")
    dop853 = Candidate("DOP853", "compiled")
    report = stress(model, candidates=[dop853], t_end=3000.0)
    defaults, longer = report.outcomes[0], report.outcomes[1]
    assert "exact solution of the linear equations" in longer.reference
    assert defaults.known == () and len(longer.known) >= 2
    assert longer.met and longer.recommended is not None
    setup = _setup(model, 30000.0, 20001)
    reference = linear_reference(model, setup)
    assert reference is not None
    scale = component_scale(reference.y)
    for note in longer.known:
        rtol = float(note.split("at rtol ")[1].split(" ")[0])
        bound = float(note.split("at least ")[1].rstrip(")"))
        assert rtol > longer.recommended.tolerance
        trajectory = run(model.with_definitions(), dop853, rtol, setup)
        error = float(np.max(scaled_errors(trajectory.y, reference.y, scale)))
        assert error >= bound > report.accuracy, note


@needs_numba
def test_a_sweep_skips_nothing() -> None:
    """Regimes of different parameters take different steps: nothing is carried from one to another."""
    model = model_from(ROOT / "tests" / "numeric_audit7" / "coupled_oscillators_weak_damping_t1e5.yaml")
    report = stress(model, candidates=[Candidate("DOP853", "compiled")], t_end=300.0, scales=[("kc", (0.5, 0.6))])
    assert all(o.known == () for o in report.outcomes)


def test_over_a_long_horizon_its_own_error_bounds_the_true_one() -> None:
    """The weakly damped oscillators over t = 1e6 (3e5 periods, 20001 samples) against their eigen-solution in
    40-digit arithmetic (mpmath), written here from the file's numbers."""
    import mpmath as mp

    model = model_from(ROOT / "tests" / "numeric_audit7" / "coupled_oscillators_weak_damping_t1e5.yaml")
    setup = _setup(model, 1e6, 20001)
    found = linear_reference(model, setup)
    assert found is not None
    with mp.workdps(40):
        m1, m2, k1, k2, kc, c = (mp.mpf(x) for x in ("1", "2", "1", "3", "0.5", "2e-5"))
        a = mp.matrix([[0, 0, 1, 0], [0, 0, 0, 1], [-(k1 + kc) / m1, kc / m1, -c / m1, 0], [kc / m2, -(k2 + kc) / m2, 0, -c / m2]])
        values, vectors = mp.eig(a)
        weights = vectors**-1 * mp.matrix([1, 0, 0, mp.mpf("0.5")])
        picked = [*range(0, 20001, 1499), 20000]
        exact = np.array([[float(mp.re(v)) for v in vectors * mp.matrix([mp.exp(values[i] * mp.mpf(setup.times[k])) * weights[i] for i in range(4)])] for k in picked])
    error = float(np.max(scaled_errors(found.y[picked], exact, component_scale(found.y))))
    assert error <= found.own_error < 1e-7


@needs_numba
def test_what_an_earlier_ladder_says_decides_what_is_skipped() -> None:
    """`_missed_before` on a real run of compiled DOP853 at 1e-5 over t = 3000 that missed: nothing is skipped where the
    earlier ladder neither went on nor stopped for want of a chance (its reference could not vouch, say); the rung is
    skipped where it went on, and the ladder stops there where it stopped; never for other parameters or a start
    whose samples are not among the longer regime's."""
    from dataclasses import replace

    from lagrange_cli.numeric.runs import measure
    from lagrange_cli.numeric.stress import _Earlier, _missed_before

    model = model_from(ROOT / "tests" / "numeric_audit7" / "coupled_oscillators_weak_damping_t1e5.yaml").with_definitions()
    dop853 = Candidate("DOP853", "compiled")
    short, longer = _setup(model, 3000.0, 3001), _setup(model, 6000.0, 6001)
    found = linear_reference(model, short)
    assert found is not None
    scale = component_scale(found.y)
    point = measure(model, dop853, 1e-5, short, found, scale, repeats=0)
    assert point.ok and point.error > 1e-3  # it misses 1e-6 by far, and by more than the slack (1e-3 at rtol 1e-5)
    far = linear_reference(model, longer)
    assert far is not None
    wide = component_scale(far.y)

    def asked(runs: dict[tuple[Candidate, float], object], ended: frozenset[tuple[Candidate, float]], setup: Setup = longer) -> tuple[str, bool]:
        return _missed_before(model, dop853, 1e-5, 1e-6, setup, [_Earlier("defaults", short, scale, found.own_error, runs, ended)], wide, far.own_error, 1e-6)  # type: ignore[arg-type]

    assert asked({(dop853, 1e-5): point}, frozenset()) == ("", False)
    why, stopped = asked({(dop853, 1e-5): point, (dop853, 1e-6): point}, frozenset())
    assert not stopped and "not run: it misses over t = 0 .. 3e+03 already" in why
    why, stopped = asked({(dop853, 1e-5): point}, frozenset({(dop853, 1e-5)}))
    assert stopped and "there its ladder stopped" in why
    assert asked({(dop853, 1e-5): point, (dop853, 1e-6): point}, frozenset(), replace(longer, parameters={"c": 3e-5})) == ("", False)
    assert asked({(dop853, 1e-5): point, (dop853, 1e-6): point}, frozenset(), _setup(model, 6000.0, 4000)) == ("", False)
