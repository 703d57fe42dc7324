"""Issue 15 (helper jump17): the compiled loops step across a jump of the forces at tight tolerances.

Where the force jumps across a switching surface, every step whose stages straddle it is rejected at a
tight rtol and the steps shrink onto the surface until they collapse; the compiled loops then hop across
(kernels._hop: the crossing located on the line y + (t - t0) f within a few spacings of t, the state moved
to its far side, the method restarted there). A sliding mode (the field on both sides pointing into the
surface: dry friction where the block sticks) cannot be followed: the run stops there after a number of
quick crossings (kernels.CHATTER), SURFACE_JUMP. Counted, never timed: crossings, steps, differences."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lagrange_cli import api
from lagrange_cli.numeric import kernels, status
from lagrange_cli.numeric.simulate import SURFACE_COLLAPSE, simulate
from lagrange_cli.numeric.status import Status

from .helpers import model_of
from .test_nonsmooth import GATED

HERE = Path(__file__).parent
BLOCK = HERE / "nonsmooth" / "block_dry_friction_sticks.yaml"


def _crossings(notes: tuple[str, ...]) -> int:
    note = next(n for n in notes if "located: " in n)
    return int(note.split("located: ")[1].split(" crossing")[0])


def test_the_gated_damper_is_stepped_across_at_tight_tolerances() -> None:
    """The gated damper (the force jumps by ~970 at the first touch, t = 0.638): compiled DOP853 at rtol 1e-12 and
    compiled Radau at 1e-10 (both collapsed at the first touch before) reach t = 1 with the same 12 crossings and agree
    with each other to 1e-7 at the samples (measured 2.7e-9); the looser DOP853 run at 1e-9, which lands on them from
    accepted steps, is further from them (measured 1.6e-6): the tight runs converge."""
    model = model_of(GATED)
    runs = {}
    for method, rtol in (("DOP853", 1e-12), ("Radau", 1e-10), ("DOP853", 1e-9)):
        run = simulate(model, method=method, backend="compiled", rtol=rtol, atol=rtol * 1e-3, samples=101)
        assert run.status == "finished" and run.t_last == 1.0, run.message
        assert _crossings(run.notes) == 12, run.notes  # the plate's contacts, each touch and separation a crossing
        runs[method, rtol] = np.asarray(run.y)
    tight = float(np.max(np.abs(runs["DOP853", 1e-12] - runs["Radau", 1e-10])))
    loose = float(np.max(np.abs(runs["DOP853", 1e-9] - runs["Radau", 1e-10])))
    assert tight < 1e-7 and tight < loose, (tight, loose)


@pytest.mark.parametrize(("method", "rtol"), [("DOP853", 1e-8), ("DOP853", 1e-12), ("Radau", 1e-8), ("Radau", 1e-11)])
def test_a_block_that_sticks_stops_on_the_surface(method: str, rtol: float) -> None:
    """Dry friction mu m g sign(v) and a spring: the block stops sliding for good at t = 2 pi / sqrt(k / m), where the
    spring force is below the friction bound (a sliding mode). The run stops there, SURFACE_JUMP with its message,
    after a few hundred steps (it chattered across v = 0 until the step budget, a million steps, before)."""
    trajectory = api.load(BLOCK).simulate(method=method, backend="compiled", rtol=rtol, atol=rtol * 1e-2, samples=11).run
    assert trajectory.outcome == Status.SURFACE_JUMP and SURFACE_COLLAPSE in trajectory.message, trajectory.message
    assert abs(trajectory.t_last - 2 * np.pi / np.sqrt(10.0)) < 1e-6
    assert abs(trajectory.y_last[1]) < 1e-9  # on the surface v = 0
    assert abs(trajectory.y_last[0] - (1.0 - 4 * 0.3 * 9.81 / 10.0)) < 1e-6  # x = 1 - 4 mu g / k after two half swings
    assert trajectory.stats.steps < 5000, trajectory.stats
    chatter = status.RADAU_CHATTER if method == "Radau" else kernels.CHATTER  # Radau's sliding modes take longer to tell (status.py)
    assert _crossings(trajectory.notes) <= 4 * chatter, trajectory.notes


def test_crossings_of_different_surfaces_close_together_are_no_sliding_mode() -> None:
    """Audit 9 F2: a double pendulum with drag |v| v on three velocities (continuous forces: only a kink) crosses its
    three surfaces close together at each turn of the swing; at rtol 1e-5 the compiled loop counted 8 quick crossings
    in a row as a sliding mode and stopped at t = 4.99 with a false "step size collapsed". Only crossings of one
    surface back and forth count now: the run reaches t_end, and the sticking block still stops where it sticks."""
    drag = simulate(api.load(HERE / "numeric_audit9" / "double_pendulum_quadratic_air_drag_abs.yaml").model, method="DOP853", backend="compiled", rtol=1e-5, atol=1e-8)
    assert drag.outcome == Status.FINISHED, drag.message
    stuck = simulate(api.load(BLOCK).model, method="DOP853", backend="compiled")
    assert stuck.outcome != Status.FINISHED and stuck.t_last == pytest.approx(1.98692, abs=1e-4)


BELT = Path(__file__).parent / "numeric_audit8" / "stick_slip_block_on_belt_shaken_wall.yaml"


@pytest.mark.parametrize("method", ["DOP853", "Radau"])
def test_a_block_that_sticks_to_a_moving_belt_stops_where_it_sticks(method: str) -> None:
    """Audit 8's stick-slip block: dry friction mu m g sign(v0 - x_dot) holds it on the belt (x_dot = v0) from
    t = 0.1168. Compiled Radau's implicit steps take 3 or 4 accepted steps between crossings of that sliding mode,
    not 1 or 2: with the explicit pairs' window it crossed 412589 times in a million steps (16 s) to stop at the step
    budget; with its own (status.RADAU_QUICK_STEPS) it stops there after CHATTER crossings, as DOP853 does."""
    trajectory = api.load(BELT).simulate(method=method, backend="compiled", samples=11).run
    assert trajectory.outcome == Status.SURFACE_JUMP and SURFACE_COLLAPSE in trajectory.message, trajectory.message
    assert abs(trajectory.t_last - 0.116794) < 1e-5 and abs(trajectory.y_last[1] - 0.4) < 1e-7  # on the belt (to the step control tolerance)
    assert trajectory.stats.steps < 1000, trajectory.stats
    assert _crossings(trajectory.notes) <= max(kernels.CHATTER, status.RADAU_CHATTER), trajectory.notes


def test_a_reference_that_stops_in_a_sliding_mode_asks_for_a_shorter_span_only() -> None:
    """`accuracy` on the stick-slip block: no reference passes the sliding mode (exit 1, the cause and where), and the
    advice is a --t-end before it, not more steps or looser tolerances (neither passes it)."""
    from typer.testing import CliRunner

    from lagrange_cli.cli import app

    result = CliRunner().invoke(app, ["accuracy", str(BELT), "-q"])
    assert result.exit_code == 1, result.output
    text = " ".join(result.output.split())
    assert "sliding mode" in text and "give a --t-end before t = 0.116794, where it stops" in text, text
    assert "--max-steps" not in text.split("sliding mode")[-1], text


@pytest.mark.parametrize("rtol", [1e-3, 1e-5, 1e-8])
def test_a_ball_rattling_on_a_penalty_wall_is_no_sliding_mode_for_radau(rtol: float) -> None:
    """Audit 6's ball in a cup (a one-sided penalty wall, k = 1e8): compiled Radau crosses the wall's surface every few
    steps while the ball rattles, a resolved contact each time. With Radau's window of 4 steps and 8 crossings in a row
    it was stopped as a sliding mode at t = 0.425 (rtol 1e-5); 64 in a row (status.RADAU_CHATTER) it finishes."""
    ball = Path(__file__).parent / "numeric_audit6" / "ball_in_cup_penalty_k1e8.yaml"
    trajectory = api.load(ball).simulate(method="Radau", backend="compiled", rtol=rtol, atol=rtol * 1e-3, samples=11).run
    assert trajectory.outcome == Status.FINISHED, trajectory.message
