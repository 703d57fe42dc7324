"""Audit 8 F1: dry friction written with sign() sticks: the field on both sides of x_dot = v points into the
surface (a sliding mode, no classical solution). Through scipy (the python backend) each landing restarted the
solver, which crossed back at once: 1302 landings in 2617 steps, to the step budget, with the advice to raise it.
The scipy loop now stops after status.CHATTER landings in a row each at most status.QUICK_STEPS steps after the one
before, as the compiled loops do: Status.SURFACE_JUMP, where the block sticks. Counted in steps, never time."""

from __future__ import annotations

import pytest

from lagrange_cli.numeric.simulate import simulate
from lagrange_cli.numeric.status import Status

from .conftest import ROOT
from .helpers import model_from

BLOCK = ROOT / "tests/nonsmooth/block_dry_friction_sticks.yaml"


@pytest.mark.parametrize("method", ["DOP853", "Radau", "BDF"])
def test_scipy_stops_where_the_block_sticks(method: str) -> None:
    run = simulate(model_from(BLOCK), method=method, backend="python")
    assert run.outcome == Status.SURFACE_JUMP, run.message
    assert run.stats.steps < 1000  # not the step budget (20000)
    assert run.t_last == pytest.approx(1.98692, abs=1e-4)  # where x_dot = 0 with |k x| below mu m g: it sticks
    assert "sliding mode" in run.message


def test_a_bouncing_mass_is_not_a_sliding_mode() -> None:
    # many landings, each a resolved contact: the run goes on to t_end
    run = simulate(model_from(ROOT / "tests/nonsmooth/bouncing_mass.yaml"), method="DOP853", backend="python")
    assert run.outcome == Status.FINISHED, run.message
