"""The compiled Radau method's round-off floor (kernels._radau_floor): a tolerance asking a component for
less than double precision resolves there no longer makes the run crawl. The audit's stiff pendulum in r
(k = 1e10, critically damped) is the case: each stage sees r rounded to its spacing, so the spring force
carries k eps |r| = 2e-6 and r_dot's Newton corrections about h k eps / 3.6, far above an atol of 1e-12.
Before the floor, compiled Radau at atol <= 1e-11 took its whole budget of 1e6 steps (1e-9 s each) to
cover t < 0.3, and `stress` fell back on an explicit reference of ~2.6e7 steps. Steps counted, never timed."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.numeric import compile, integrators, policy
from lagrange_cli.numeric.status import Status

from .conftest import ROOT
from .helpers import model_from

runner = CliRunner()
PILOT = ROOT / "tests" / "numeric_audit_pilot" / "stiff_elastic_pendulum_r.yaml"


def _run(path: Path, rtol: float, atol: float, t_end: float = 2.0, budget: int = 200_000) -> integrators.Run:
    model = model_from(path)
    settings = policy.validate(model, method="Radau", backend="compiled", t_end=t_end, samples=201, rtol=rtol, atol=atol)
    problem = integrators.Problem(0.0, t_end, np.array(settings.y0), np.array(settings.t_eval), np.array(settings.p), False, budget)
    return integrators.run_radau(compile.build(model, "numba", jacobian=True), problem, rtol, atol, math.inf)


@pytest.mark.parametrize(("rtol", "atol"), [(1e-8, 1e-12), (1e-10, 1e-13), (1e-12, 1e-15)])
def test_a_tolerance_below_round_off_does_not_crawl(rtol: float, atol: float) -> None:
    """Each of these took the 1e6-step budget before (t = 0.29, 0.20 and 0.12 of 2 reached); now a few
    hundred to a few thousand steps, and the steps held at the floor are counted."""
    run = _run(PILOT, rtol, atol)
    assert run.status == Status.FINISHED, (run.status, run.t_last)
    assert run.stats.steps < 5000, run.stats.steps
    assert run.stats.rejected is not None and run.stats.rejected < 50
    assert run.stats.floored > 0


def test_the_floored_runs_converge_with_the_tolerance() -> None:
    """The slow swing (theta, theta_dot) converges as rtol tightens: each run is closer to the tightest
    than the one before, the last within 1e-10; r_dot agrees to its round-off floor (k / c x eps |r|
    = 1e5 x 2.2e-16, a few 1e-11 with the safety factor) in every run."""
    runs = {rtol: _run(PILOT, rtol, rtol * 1e-3) for rtol in (1e-6, 1e-8, 1e-10, 1e-12)}
    tightest = runs[1e-12].y
    gaps = [float(np.max(np.abs(runs[rtol].y[:, [1, 3]] - tightest[:, [1, 3]]))) for rtol in (1e-6, 1e-8, 1e-10)]
    assert gaps[0] > gaps[1] > gaps[2], gaps
    assert gaps[0] < 1e-5 and gaps[2] < 1e-10, gaps
    for rtol in (1e-6, 1e-8, 1e-10):
        assert float(np.max(np.abs(runs[rtol].y[:, 2] - tightest[:, 2]))) < 1e-10


def test_a_smooth_system_never_reaches_the_floor() -> None:
    """On the double pendulum the floor stays far below every scale: no step is held there (and the run
    takes the steps it took before the floor existed: 2862 at the defaults, to t = 10, on the machine that
    measured it; 2867 on another CPU, whose compiled sin and cos round differently: within 1%, not to the step)."""
    run = _run(ROOT / "systems" / "double_pendulum.yaml", 1e-8, 1e-10, t_end=10.0)
    assert run.status == Status.FINISHED
    assert run.stats.floored == 0
    assert abs(run.stats.steps - 2862) <= 0.01 * 2862, run.stats


def test_simulate_says_where_the_tolerance_was_floored() -> None:
    result = runner.invoke(app, ["simulate", str(PILOT), "--method", "Radau", "--backend", "compiled", "--rtol", "1e-10", "--atol", "1e-14", "--t-end", "1", "-q"])
    assert result.exit_code == 0, result.output
    assert "held some component's error to its round-off floor" in result.output
    quiet = runner.invoke(app, ["simulate", str(PILOT), "--method", "Radau", "--backend", "compiled", "--t-end", "1", "-q"])
    assert quiet.exit_code == 0, quiet.output
    assert "round-off floor" not in quiet.output


def test_stress_finds_an_implicit_reference_for_every_regime_of_the_pilot() -> None:
    """The long horizon used the explicit fallback (compiled RK45, ~2.6e7 steps) because compiled Radau's
    tighter probes crawled; every regime's reference is compiled Radau now, and Radau meets 1e-6 in each."""
    result = runner.invoke(app, ["stress", str(PILOT)])
    assert result.exit_code == 0, result.output
    references = [line for line in result.output.splitlines() if line.strip().startswith("reference:")]
    assert len(references) == 4, references
    assert all(line.strip().startswith("reference: Radau (compiled)") for line in references), references
    recommended = [line for line in result.output.splitlines() if line.strip().startswith("recommended:")]
    assert len(recommended) == 4 and all("Radau (compiled)" in line for line in recommended), recommended
