"""Issue 15 (audit 6 F5): switching surfaces located. A right-hand side with Abs, sign, Piecewise,
Max or Min is smooth only piecewise; the integrators land a step on each zero crossing of the
switching functions and restart there (switching.py, kernels.erk_switched, kernels.radau_switched, integrators.run_scipy).
Counted, never timed: errors against an exact solution, crossings against the true contacts, steps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lagrange_cli import api
from lagrange_cli._symengine import se
from lagrange_cli.numeric import codegen, compile, integrators, switching

from .conftest import ROOT
from .helpers import benchmark_module, model_from, model_of

HERE = Path(__file__).parent
BOUNCE = HERE / "nonsmooth" / "bouncing_mass.yaml"
NS = benchmark_module("nonsmooth")
SAMPLES = 301


def _error(y: np.ndarray, exact: np.ndarray) -> float:
    if y.shape != exact.shape:
        return np.inf
    return float(np.max(np.abs(y - exact) / np.maximum(1.0, np.max(np.abs(exact), axis=0))))


def test_switching_functions_are_collected_once_up_to_sign() -> None:
    x, y, v, k = se.symbols("x y v k")
    exprs = [
        k * se.Abs(x - 1) + se.sign(1 - x) * v,  # one surface, x - 1, written twice with opposite signs
        se.Max(x, y**2),  # x - y^2
        se.Piecewise((x, se.Lt(v, 2)), (y, True)),  # v - 2
        se.Abs(k - 3) * x,  # the parameters alone never switch
    ]
    found = switching.collect(exprs, frozenset({"k"}))
    assert len(found) == 3
    for expected in (x - 1, x - y**2, v - 2):
        assert sum(1 for g in found if se.expand(g - expected) == 0 or se.expand(g + expected) == 0) == 1


def test_a_surface_written_with_opposite_signs_is_one_surface() -> None:
    # audit 7's gated damper: the wall's Abs(d - l sin(theta) + w) and the gate's sign(l sin(theta) - d - w);
    # symengine keeps -(d - l sin(theta) + w) as a product, which never equalled the other's expanded form
    theta, w, d, length = se.symbols("theta w d l")
    gap = length * se.sin(theta) - d - w
    found = switching.collect([se.Abs(d - length * se.sin(theta) + w) * theta, se.sign(gap) * w], frozenset({"d", "l"}))
    assert len(found) == 1


GATED = """
coordinates: [theta, w]
parameters: {m: 1.0, l: 1.0, mw: 0.5, kw: 200.0, d: 0.3, kc: 1.0e6, cc: 300.0, g: 9.81}
gravity: [0, -g]
particles:
  bob: {mass: m, position: [l*sin(theta), -l*cos(theta)]}
  plate: {mass: mw, position: [d + w, 0]}
potential: kw*w**2/2 + kc/2*((l*sin(theta) - d - w + Abs(l*sin(theta) - d - w))/2)**2
dissipation: cc/2*(1 + sign(l*sin(theta) - d - w))/2*(l*cos(theta)*theta_dot - w_dot)**2
initial: {theta: -1.2, w: 0.0}
simulate: {t_end: 1}
"""


def test_a_jump_in_the_force_is_stepped_across_at_a_tight_tolerance() -> None:
    """A pendulum strikes a sprung plate whose contact damper sign(gap) switches on: the force jumps by
    cc x the closing speed at the first touch (t = 0.638). At rtol 1e-12 every step across the surface
    is rejected and the steps shrink onto it until they collapse; the compiled loop then hops across
    (kernels._hop, helper jump17: the run stopped there, SURFACE_JUMP, before) and finishes, as the run at
    rtol 1e-8 does, which lands on the crossings from accepted steps. A sliding mode, which still stops
    SURFACE_JUMP, is tests/test_jump17.py's."""
    from lagrange_cli.numeric.simulate import simulate

    model = model_of(GATED)
    loose = simulate(model, method="DOP853", backend="compiled", rtol=1e-8, atol=1e-10, samples=3)
    assert loose.status == "finished" and "1 switching surface (" in loose.notes[-1]
    tight = simulate(model, method="DOP853", backend="compiled", rtol=1e-12, atol=1e-14, samples=3)
    assert tight.status == "finished" and tight.t_last == 1.0, tight.message
    assert np.max(np.abs(tight.y_last - loose.y_last)) < 1e-4


def test_the_reference_of_a_jump_is_made_at_its_tightest_tolerance() -> None:
    """Audit 7 F5: stress called the first touch of the gated damper a blow-up (both reference methods
    stopped there); then (SURFACE_JUMP) the reference stepped back to a looser rtol, DOP853 at 2.5e-10. With
    the compiled loops hopping across the jump (helper jump17), the reference is made at its tightest rtol,
    confirmed by a second method, and reaches t = 1."""
    from lagrange_cli.numeric import reference, stress
    from lagrange_cli.numeric.runs import Setup
    from lagrange_cli.numeric.status import Status

    model = model_of(GATED).with_definitions()
    setup = Setup(1.0, tuple(np.linspace(0.0, 1.0, 101).tolist()), max_steps=stress.MAX_STEPS)
    found = reference.computed_reference(model, setup, stress.reference_tolerance(1e-6), implicit=stress.implicit_reference_tolerances(1e-6))
    assert found.settings is not None and found.settings.rtol <= 2.5e-13, found.description
    assert "blow" not in found.description and "confirmed by" in found.description
    assert reference.BLOWUP.count(Status.SURFACE_JUMP) == 0
    assert found.t[-1] == 1.0 and np.isfinite(found.own_error) and found.own_error < 1e-8


def test_only_a_system_with_kinks_gets_a_switch_function() -> None:
    smooth = model_from(ROOT / "systems" / "double_pendulum.yaml")
    for target in ("numba", "python"):
        assert "_switch" not in codegen.source(smooth, target) and "_SWITCHES" not in codegen.source(smooth, target)
    bounce = api.load(BOUNCE).model
    assert "_SWITCHES = 1" in codegen.source(bounce, "numba") and "def _switch(t, _y, _p):" in codegen.source(bounce, "python")


def test_a_smooth_system_takes_the_steps_it_took_before() -> None:
    """Without switching functions the compiled loop is erk_run, unchanged: the same steps and
    evaluations as scipy's DOP853 (the loop's contract), whatever switching.LOCATE says."""
    from scipy.integrate import DOP853

    model = model_from(ROOT / "systems" / "double_pendulum.yaml")
    trajectory = api.load(ROOT / "systems" / "double_pendulum.yaml").simulate(t_end=5.0, method="DOP853", backend="compiled", rtol=1e-8, atol=1e-11, samples=11)
    python = compile.build(model, "python").module
    p = [q.value for q in model.parameters]
    rhs = integrators.python_rhs(python, p)
    y0 = np.array(trajectory.run.y[0])
    solver, steps = DOP853(rhs, 0.0, y0, 5.0, rtol=1e-8, atol=1e-11), 0
    while solver.status == "running":
        solver.step()
        steps += 1
    assert trajectory.run.stats.steps == steps
    assert np.max(np.abs(trajectory.run.y_last - solver.y)) < 1e-9  # round-off apart (numba and Python arithmetic)
    assert not any("switching" in note for note in trajectory.run.notes)


@pytest.mark.parametrize(
    ("method", "backend", "bound"),
    [("DOP853", "compiled", 2e-6), ("RK45", "compiled", 2e-5), ("LSODA", "python", 1e-5), ("Radau", "python", 1e-6), ("Radau", "compiled", 1e-6)],
)
def test_the_bouncing_mass_meets_its_exact_solution(method: str, backend: str, bound: float) -> None:
    """Dropped from 1 m on a one-sided spring (1000 rad/s) for 3 s: 3 contacts, so 6 crossings; at rtol
    1e-8 each method lands on every one, and its error against the exact solution is that of a smooth
    problem's (`test_the_bouncing_mass_is_as_accurate_as_a_smooth_problem`); stepping over the kinks
    left 1.6e-4 (DOP853 compiled)."""
    ts = np.linspace(0.0, 3.0, SAMPLES)
    run = api.load(BOUNCE).simulate(method=method, backend=backend, rtol=1e-8, atol=1e-11, samples=SAMPLES).run
    assert not run.failed, run.message
    assert NS.bouncing_contacts(3.0) == 3
    assert f"1 switching surface (Abs, sign, Piecewise, Max, Min) located: {2 * 3} crossings" in run.notes[-1]
    assert _error(np.asarray(run.y), NS.bouncing_exact(ts)) <= bound


def test_the_bouncing_mass_is_as_accurate_as_a_smooth_problem() -> None:
    """Compiled DOP853 at rtol 1e-8 on the bouncing mass is within 30x (measured 18x) of its error on
    the smooth problem its contacts are made of: the spring's swing at 1000 rad/s from the impact
    velocity, over three half periods (the flights between are parabolas, which DOP853 integrates
    exactly). What is left is a timing error, which the contact's 1000 rad/s turns into a velocity
    error at a sample inside a contact. Without locating the crossings the error is over 1000x
    (measured 8000x) the smooth problem's."""
    from lagrange_cli.numeric.simulate import simulate

    speed = float(np.sqrt(2 * 9.81))
    smooth = model_of(f"coordinates: [x]\nparameters: {{w: 1000.0}}\nkinetic: x_dot**2/2\npotential: w**2*x**2/2\ninitial: {{x: 0.0, x_dot: {-speed!r}}}\n")
    span = float(3 * np.pi / 1000)
    ts = np.linspace(0.0, span, SAMPLES)
    run = simulate(smooth, t_end=span, method="DOP853", backend="compiled", rtol=1e-8, atol=1e-11, samples=SAMPLES)
    smooth_error = _error(np.asarray(run.y), np.column_stack([-speed / 1000 * np.sin(1000 * ts), -speed * np.cos(1000 * ts)]))
    ts = np.linspace(0.0, 3.0, SAMPLES)
    bounce = api.load(BOUNCE)
    located = _error(np.asarray(bounce.simulate(method="DOP853", backend="compiled", rtol=1e-8, atol=1e-11, samples=SAMPLES).run.y), NS.bouncing_exact(ts))
    assert located <= 30 * smooth_error
    switching.LOCATE = False
    try:
        over = _error(np.asarray(bounce.simulate(method="DOP853", backend="compiled", rtol=1e-8, atol=1e-11, samples=SAMPLES).run.y), NS.bouncing_exact(ts))
    finally:
        switching.LOCATE = True
    assert over > 1000 * smooth_error


def test_compiled_radau_lands_on_the_crossings() -> None:
    """kernels.radau_switched on the bouncing mass at rtol 1e-8: the 6 crossings landed on, each a restart
    (a fresh Jacobian: at least one per crossing); the error 100x below the run that steps over them
    (switching.LOCATE off: kernels.radau_run; measured 1.5e-8 against 1.5e-5 on one machine, 1.6e-8 against
    2.1e-6 on an AMD EPYC: how a run that steps over a kink lands depends on the last bits of its arithmetic)."""
    ts = np.linspace(0.0, 3.0, SAMPLES)
    bounce = api.load(BOUNCE)
    run = bounce.simulate(method="Radau", backend="compiled", rtol=1e-8, atol=1e-11, samples=SAMPLES).run
    assert "located: 6 crossings" in run.notes[-1] and run.stats.njev >= 1 + 6, run.stats
    switching.LOCATE = False
    try:
        over = bounce.simulate(method="Radau", backend="compiled", rtol=1e-8, atol=1e-11, samples=SAMPLES).run
    finally:
        switching.LOCATE = True
    assert not any("located" in note for note in over.notes)
    exact = NS.bouncing_exact(ts)
    assert _error(np.asarray(run.y), exact) < 1e-7
    assert 100 * _error(np.asarray(run.y), exact) < _error(np.asarray(over.y), exact)


def test_a_sign_switch_is_located_too() -> None:
    """Dry friction, sign(x_dot): a discontinuous force; each reversal of the velocity is a crossing,
    and both backends meet the exact solution."""
    text = "coordinates: [x]\nparameters: {k: 1.0, f: 0.1}\nkinetic: x_dot**2/2\npotential: k*x**2/2\nforces: {generalized: {x: -f*sign(x_dot)}}\ninitial: {x: 1.0}\nsimulate: {t_end: 6}\n"
    model = model_of(text)
    from lagrange_cli.numeric.simulate import simulate

    run = simulate(model, method="DOP853", backend="compiled", rtol=1e-8, atol=1e-11, samples=3)
    assert "located: 1 crossing," in run.notes[-1]  # the velocity reverses once in 6 s (half a period is pi)
    python = simulate(model, method="LSODA", backend="python", rtol=1e-8, atol=1e-11, samples=3)
    assert "located: 1 crossing," in python.notes[-1]
    exact = np.array([-0.1 + 0.7 * np.cos(6.0), -0.7 * np.sin(6.0)])  # x = 0.1 + 0.9 cos t to t = pi (x = -0.8), then -0.1 + 0.7 cos t
    assert np.max(np.abs(run.y[-1] - exact)) < 1e-6 and np.max(np.abs(python.y[-1] - exact)) < 1e-6


def test_a_sweep_runs_a_switching_file() -> None:
    """`sweep` on the bouncing mass: the batched compiled runs (which step over the crossings) and the
    Python backend's (which locate them) both finish; the located one meets the exact state at t = 1."""
    bounce = api.load(BOUNCE)
    exact = NS.bouncing_exact(np.array([1.0]))[0]
    compiled = bounce.sweep(parameters={"k": (1e6, 1e6, 1)}, t_end=1.0, rtol=1e-8, atol=1e-11)
    python = bounce.sweep(parameters={"k": (1e6, 1e6, 1)}, t_end=1.0, rtol=1e-8, atol=1e-11, backend="python", method="DOP853")
    assert list(compiled["status"]) == ["finished"] and list(python["status"]) == ["finished"]
    assert abs(float(python["x_final"][0]) - exact[0]) < 1e-6 and abs(float(python["x_dot_final"][0]) - exact[1]) < 1e-5
