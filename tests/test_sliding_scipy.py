"""Audit 8 F1: dry friction written with sign() sticks: the field on both sides of x_dot = v points into the
surface (a sliding mode, no classical solution). Through scipy (the python backend) each landing restarted the
solver, which crossed back at once: 1302 landings in 2617 steps, to the step budget, with the advice to raise it.
The scipy loop now stops after status.CHATTER landings in a row each at most status.QUICK_STEPS steps after the one
before, as the compiled loops do, or at once where Filippov's condition holds at a landing or after a tiny step next
to the surface (the field points into it from both sides and truly jumps across it: `_Switches.attracting`; scipy's
RK45 crawled along the surface in 19558 steps of 6e-11 with one landing): Status.SURFACE_JUMP, where the block
sticks. Counted in steps, never time."""

from __future__ import annotations

import numpy as np
import pytest

from lagrange_cli.numeric import compile, integrators
from lagrange_cli.numeric.simulate import simulate
from lagrange_cli.numeric.status import Status

from .conftest import ROOT
from .helpers import model_from, model_of

BLOCK = ROOT / "tests/nonsmooth/block_dry_friction_sticks.yaml"


@pytest.mark.parametrize("method", ["DOP853", "RK45", "Radau", "BDF", "LSODA"])
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


def _switches(force: str) -> integrators._Switches:
    model = model_of(f"""
title: a block, a switching force on its velocity
coordinates: [x]
parameters: {{m: {{value: 2.0}}, c: {{value: 0.7}}}}
kinetic: m*x_dot**2/2
forces: {{generalized: {{x: {force}}}}}
initial: {{x: 0.0}}
""")
    python = compile.build(model, "python").module
    p = [q.value for q in model.parameters]
    return integrators._Switches(python, p, integrators.python_rhs(python, p))


def test_filippov_asks_for_a_jump_not_only_for_rates_of_opposite_signs() -> None:
    """At v = 0 both a dry friction -c sign(v) and a quadratic drag -c v |v| make the rate of v negative just above
    the surface and positive just below: only the first jumps (a sliding mode); the drag is continuous, v only tends
    to 0, and a run there must go on."""
    at_rest = np.array([0.3, 0.0])
    assert _switches("-c*sign(x_dot)").attracting(0.0, at_rest, 0)
    assert not _switches("-c*x_dot*Abs(x_dot)").attracting(0.0, at_rest, 0)
    moving = np.array([0.3, 1.0])  # far from the surface: not tested there
    assert not _switches("-c*sign(x_dot)").attracting(0.0, moving, 0)
    pushed = "-c*sign(x_dot) + 3*c"  # a force larger than the friction bound: it crosses v = 0, no sliding
    assert not _switches(pushed).attracting(0.0, at_rest, 0)
