"""Numeric runs never crash on values outside a function's domain, and never run without bound:
a failed run names the time, the state and the cause, keeps its trajectory, and exits 1."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lagrange_cli import analysis, derive, spec
from lagrange_cli.errors import DerivationError, LagrangeError
from lagrange_cli.numeric import integrators, simulate

from .conftest import ROOT
from .limits import DEADLOCK

pytestmark = pytest.mark.usefixtures("private_cache")


def particle(potential: str, x0: float = 0.5, v0: float = -2.0, t_end: float = 3.0, extra: str = "") -> str:
    return f"""
coordinates: [x]
parameters: {{m: 1.0, k: 1.0}}
particles:
  p: {{mass: m, position: [x, 0]}}
potential: {potential}
initial: {{x: {x0}, x_dot: {v0}}}
simulate: {{t_end: {t_end}}}
{extra}"""


def model_of(text: str, name: str = "guard.yaml") -> object:
    return derive.derive(spec.parse(text, name))


DOMAIN_ERRORS = [
    # potential, cause the message must give; each run leaves the domain
    ("-sqrt(x)", ("math domain error",)),
    ("x + log(x)", ("step size collapsed", "domain", "division by zero")),  # 1/x grows without bound before log(x) fails
    ("-x**(1/3)", ("complex", "nan", "domain", "step size collapsed")),  # the force x**(-2/3)/3 is infinite at 0; beyond it complex (or NaN after the codegen fix)
    ("-k*acos(x)/10", ("math domain error", "division by zero")),  # 1/sqrt(1 - x**2) at x = 1, or acos beyond it
    ("x**(4/3)", ("complex", "nan", "domain")),  # the force -4/3 x**(1/3) is finite at 0, complex (or NaN) beyond
]


@pytest.mark.parametrize(("potential", "cause"), DOMAIN_ERRORS, ids=["sqrt", "log", "cube-root", "acos", "four-thirds"])
@pytest.mark.parametrize("method", ["DOP853", "Radau"])
def test_leaving_a_domain_is_a_failed_run_with_time_state_and_cause(potential: str, cause: tuple[str, ...], method: str) -> None:
    trajectory = simulate(model_of(particle(potential, v0=2.0 if "acos" in potential else -2.0)), backend="python", method=method)
    assert trajectory.failed, trajectory.message
    assert "guard.yaml" in trajectory.message and "t = " in trajectory.message and "x = " in trajectory.message and "x_dot = " in trajectory.message
    assert any(c in trajectory.message for c in cause), trajectory.message
    assert len(trajectory.t) > 10 and np.all(np.isfinite(trajectory.y)), "the trajectory so far is kept"


def test_every_exception_of_generated_code_is_named() -> None:
    """What a generated function may raise or return at a state, as a cause in words."""

    def raising(error: Exception) -> object:
        def function(t: float, y: list[float], p: list[float]) -> list[float]:
            raise error

        return function

    cases = [
        (raising(ValueError("math domain error")), "math domain error"),
        (raising(ZeroDivisionError("float division by zero")), "division by zero"),
        (raising(OverflowError("math range error")), "overflow"),
        (raising(TypeError("float() argument must be a string or a real number, not 'complex'")), "complex"),
        (lambda t, y, p: [1.0, complex(0.5, 0.5)], "complex"),
        (lambda t, y, p: [1.0, float("nan")], "nan"),
        (lambda t, y, p: float("inf"), "inf"),
    ]
    for function, cause in cases:
        with pytest.raises(integrators.EvaluationError) as caught:
            integrators.evaluate(function, 1.5, [0.25, -1.0], [], "the energy")
        assert caught.value.t == 1.5 and list(caught.value.y) == [0.25, -1.0]
        assert cause in caught.value.cause and "the energy" in str(caught.value)
    assert integrators.evaluate(lambda t, y, p: 2.0, 0.0, [1.0], [], "the energy") == [2.0]


@pytest.mark.parametrize("method", ["DOP853", "RK45", "Radau", "BDF", "LSODA"])
def test_a_start_where_the_forces_divide_by_zero_fails_at_once(method: str) -> None:
    """NaN at the initial state made scipy's step size NaN, and its step loop retried forever."""
    trajectory = simulate(model_of(particle("k*log(x**2)", x0=0.0, v0=1.0)), backend="python", method=method)
    assert trajectory.failed and "at t = 0 (x = 0, x_dot = 1): a division by zero" in trajectory.message, trajectory.message


def test_an_energy_that_cannot_be_evaluated_ends_the_run_at_that_sample() -> None:
    """acos(t - 1) leaves the energy's domain at t = 2 while the forces stay defined."""
    trajectory = simulate(model_of(particle("k*x**2/2 + acos(t - 1)", v0=0.0)), backend="python")
    assert trajectory.failed
    assert "the energy cannot be evaluated at t = 2" in trajectory.message and "math domain error" in trajectory.message
    assert trajectory.t[-1] <= 2.0 and trajectory.t[-1] > 1.9 and len(trajectory.energy) == len(trajectory.t)


def test_a_stop_condition_outside_its_domain_is_a_failure() -> None:
    trajectory = simulate(model_of(particle("k*x**2/2", v0=0.0)), backend="python", until="log(x + 0.1)")
    assert trajectory.failed and "stop condition" in trajectory.message and "math domain error" in trajectory.message


def test_a_run_without_end_stops_at_its_step_budget() -> None:
    model = model_of(particle("k*x**2/2", v0=0.0))
    trajectory = simulate(model, backend="python", t_end=1e300, max_steps=300)
    assert trajectory.failed and trajectory.stats.steps == 300
    assert "stopped after 300 steps" in trajectory.message and "of t_end = 1e+300" in trajectory.message and "--max-steps" in trajectory.message
    assert integrators.MAX_STEPS["python"] <= 100_000 and integrators.MAX_STEPS["compiled"] <= 10_000_000


def test_a_tiny_time_span_finishes() -> None:
    trajectory = simulate(model_of(particle("k*x**2/2", v0=0.0)), backend="python", t_end=5e-324, progress=lambda fraction: None)
    assert trajectory.status == "finished"


class FakeLoop:
    """A compiled loop's contract: advance(t_stop) moves t towards min(t_stop, t_end) by at most
    `pause` steps of size h, returning 0 at t_end and -1 when paused or at t_stop."""

    def __init__(self, t_end: float, h: float, pause: int = 20000) -> None:
        self.t, self.t_end, self.h, self.pause, self.steps, self.calls = 0.0, t_end, h, pause, 0, 0

    def advance(self, t_stop: float) -> int:
        self.calls += 1
        assert self.calls < 1000, "the driver calls the loop without end"
        for _ in range(self.pause):
            if self.t >= min(t_stop, self.t_end):
                break
            self.t, self.steps = min(self.t + self.h, self.t_end), self.steps + 1
        return 0 if self.t >= self.t_end else -1


@pytest.mark.parametrize("progress", [None, lambda fraction: None], ids=["quiet", "progress"])
def test_the_compiled_driver_stops_at_the_step_budget(progress: object) -> None:
    loop = FakeLoop(1e300, 1.0)
    problem = integrators.Problem(0.0, 1e300, np.zeros(2), np.zeros(2), np.zeros(0), False, max_steps=100_000)
    assert integrators._drive(loop.advance, lambda: loop.t, lambda: loop.steps, problem, progress) == 6  # type: ignore[arg-type]
    assert 100_000 <= loop.steps < 200_000


def test_the_compiled_driver_moves_ahead_when_the_span_underflows() -> None:
    """span / 100 of t_end = 5e-324 is 0: the progress target never moved, and the driver looped."""
    loop = FakeLoop(5e-324, 5e-324)
    problem = integrators.Problem(0.0, 5e-324, np.zeros(2), np.zeros(2), np.zeros(0), False)
    assert integrators._drive(loop.advance, lambda: loop.t, lambda: loop.steps, problem, lambda fraction: None) == 0


@pytest.mark.parametrize("bad", [{"parameters": {"k": float("nan")}}, {"initial": {"x": float("inf")}}, {"initial": {"x": "one"}}, {"samples": 10**12}, {"max_steps": 0}])
def test_bad_values_are_refused(bad: dict) -> None:
    with pytest.raises(LagrangeError):
        simulate(model_of(particle("k*x**2/2")), backend="python", **bad)


def test_numeric_equilibria_skip_starts_outside_the_domain() -> None:
    # x**(3/2) is complex for x < 0: half the starts cannot be evaluated; sympy cannot solve it
    found = analysis.equilibria(model_of(particle("x**(3/2) + cos(3*x)")), seconds=1.0)
    assert found and all(float(point[sp_x]) > 0 for point in found for sp_x in point)


def test_numeric_equilibria_with_no_evaluable_start_say_so() -> None:
    with pytest.raises(DerivationError, match="cannot be evaluated from any of"):
        analysis.equilibria(model_of(particle("(x - 5)**(3/2) + cos(3*x)")), seconds=1.0)


def test_cli_failed_run_exits_1_with_time_and_state(tmp_path: Path) -> None:
    path = tmp_path / "root.yaml"
    path.write_text(particle("-sqrt(x)"))
    output = tmp_path / "out.csv"
    result = subprocess.run([sys.executable, "-m", "lagrange_cli", "simulate", str(path), "--backend", "python", "-o", str(output)], capture_output=True, text=True, cwd=ROOT, timeout=DEADLOCK)
    assert result.returncode == 1, result.stderr
    assert "Traceback" not in result.stderr
    assert "root.yaml" in result.stderr and "t = " in result.stderr and "x = " in result.stderr and "math domain error" in result.stderr
    assert len(output.read_text().splitlines()) > 10


def test_a_fixed_step_with_the_python_backend_is_refused_not_a_crash(tmp_path: Path) -> None:
    """`simulate: {step: ...}` picks the symplectic method, which has no scipy (python) form."""
    text = "coordinates: [x]\nparameters: {m: 1.0, k: 2.0}\nparticles:\n  p: {mass: m, position: [x]}\npotential: k*x**2/2\ninitial: {x: 1.0}\nsimulate: {step: 0.01}\n"
    model = derive.derive(spec.parse(text, "fixed_step.yaml"))
    with pytest.raises(LagrangeError, match=r"fixed step .* symplectic method, which runs only compiled"):
        simulate(model, t_end=0.05, samples=11, backend="python")
