"""A symplectic run whose fixed step cannot reach t_end within the step budget is refused before it
starts, saying why and what to use instead (issue 15, audit 3: on a damped stiff chain the pilot's
step, chosen for the fast modes at the start, took the whole 1e6-step budget to reach t = 2.9 of 20).
Counted in steps and evaluations, never timed."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.numeric import integrators, policy
from lagrange_cli.numeric.simulate import fixed_steps, simulate
from lagrange_cli.numeric.status import Status

from .conftest import ROOT
from .helpers import model_from

pytestmark = pytest.mark.usefixtures("private_cache")
CHAIN = ROOT / "tests" / "numeric_audit3" / "spring_chain_4_damped.yaml"


@pytest.fixture(scope="module")
def chain():  # type: ignore[no-untyped-def]
    return model_from(CHAIN)


def test_the_damped_chain_is_refused_before_it_runs(chain) -> None:  # type: ignore[no-untyped-def]
    trajectory = simulate(chain, method="symplectic", samples=11)
    s = trajectory.settings
    assert s.step is not None and s.stages in (2, 3)
    needed = fixed_steps(s)
    assert needed == pytest.approx(s.t_end / s.step, abs=1) and needed > integrators.MAX_STEPS["compiled"]
    assert trajectory.failed and trajectory.outcome == Status.BUDGET
    assert trajectory.stats.steps == 0 and trajectory.stats.nfev == 0  # the run spent nothing ...
    pilot = policy.chosen_pilot(chain, s)
    assert pilot is not None and 0 < pilot.steps < needed / 100  # ... beyond the pilot that chose the step
    message = trajectory.message
    assert f"{needed} steps" in message and str(integrators.MAX_STEPS["compiled"]) in message and repr(s.step) in message
    assert "dissipates" in message and "conservative" in message and "LSODA" in message
    assert any(note.startswith("warning: this system dissipates") for note in trajectory.notes)
    assert len(trajectory.t) == 1 and trajectory.t_last == 0.0  # the start, kept


def test_the_prediction_is_the_step_count(chain) -> None:  # type: ignore[no-untyped-def]
    """10 steps of 0.02 to t = 0.2: a budget of 9 refuses, 10 runs to the end in exactly 10 steps."""
    refused = simulate(chain, method="symplectic", step=0.02, stages=2, t_end=0.2, samples=3, max_steps=9)
    assert refused.failed and refused.stats.steps == 0 and "needs 10 steps" in refused.message
    ran = simulate(chain, method="symplectic", step=0.02, stages=2, t_end=0.2, samples=3, max_steps=10)
    assert not ran.failed and ran.stats.steps == 10 and ran.t_last == pytest.approx(0.2)


def test_a_conservative_system_is_told_to_lengthen_the_step() -> None:
    trajectory = simulate(model_from(ROOT / "systems" / "simple_pendulum.yaml"), method="symplectic", step=1e-6, t_end=10.0, samples=11)
    assert trajectory.failed and trajectory.stats.nfev == 0 and "needs 10000000 steps" in trajectory.message
    assert "larger --step" in trajectory.message and "dissipates" not in trajectory.message
    assert not any("dissipates" in note for note in trajectory.notes)


def test_the_cli_exits_1_at_once() -> None:
    result = CliRunner().invoke(app, ["simulate", str(CHAIN), "--method", "symplectic", "--step", "1e-6", "--samples", "11", "-q"])
    assert result.exit_code == 1, result.output
    assert "needs 20000000 steps" in result.output and "work: 0 steps, 0 evaluations" in result.output
