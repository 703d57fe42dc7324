"""Audit 12's last open finding: a heavy top in Euler angles whose axis passes within 3e-7 of the vertical stopped
every reference method on "the mass matrix is singular" at the same state, and `stress` called that a blow-up of the
system ("blow-up (both reference methods stop there)", no method meets it, exit 1). The motion passes there; its
coordinates end. Now the reference failure says so (`ReferenceFailed.coordinates`), `accuracy` names the state, the
coordinate and the advice, and `stress` leaves the regime undecided. A true blow-up (V = -x^4) stays one
(tests/test_stress.py). No clock: statuses and messages only."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.numeric import stress
from lagrange_cli.numeric.reference import ReferenceFailed, computed_reference
from lagrange_cli.numeric.runs import Setup, starting
from lagrange_cli.numeric.simulate import coordinates_end, simulate
from lagrange_cli.numeric.status import Status

from . import test_audit11 as audit11
from .conftest import ROOT
from .helpers import model_from, model_of

runner = CliRunner()

TOP = audit11.TOP.replace("theta: 0.3,", "theta: 0.01,").replace("t_end: 0.2", "t_end: 0.01")
"""Audit 11's top started at theta = 0.01: its axis passes within 3e-7 of the vertical at t = 0.005."""


@pytest.fixture
def top(tmp_path: Path) -> Path:
    path = tmp_path / "top.yaml"
    path.write_text(TOP, encoding="utf-8")
    return path


def test_a_reference_stopped_where_euler_angles_end_says_so(top: Path) -> None:
    result = runner.invoke(app, ["accuracy", str(top), "-q"])
    flat = " ".join(result.output.split())
    assert result.exit_code == 1, flat
    assert "Traceback" not in flat and "blows up" not in flat, flat
    assert "both stop near t = 0.005" in flat and "the coordinates end there, not the motion" in flat, flat
    found = re.search(r"it changes fastest with theta = ([0-9.e+-]+)\)", flat)
    assert found is not None and 0 < float(found.group(1)) < 1e-5, flat  # the pass's closest approach to theta = 0
    assert "M's inertia vanishes" in flat and "quaternion" in flat and "--t-end" in flat, flat


def test_stress_leaves_such_a_regime_undecided_not_a_blow_up(top: Path) -> None:
    model = model_from(top).with_definitions()
    setup = starting(model, Setup(0.01, tuple(np.linspace(0.0, 0.01, 11).tolist())))
    with pytest.raises(ReferenceFailed) as caught:
        computed_reference(model, setup, 1e-11)
    error = caught.value
    assert error.coordinates and not error.blowup, str(error)
    assert error.trajectory is not None and float(error.trajectory.y_last[0]) < 1e-5  # stopped at theta ~ 0
    outcome = stress._without_reference(model, stress.Regime("defaults", 0.01, {}, {}), setup, error)
    kinds = [finding.kind for finding in outcome.diagnosis.findings]
    assert "no reference: the coordinates end" in kinds and not any(kind.startswith("blow-up") for kind in kinds), kinds
    assert outcome.open_reason and outcome.undecided and not outcome.met, outcome


ACOS = """\
title: A pendulum whose angle is acos(c)
coordinates: [c]
parameters: {m: 1.0, L: 1.0, g: 9.81}
gravity: [0, -g]
particles:
  bob: {mass: m, position: [L*sin(acos(c)), -L*cos(acos(c))]}
initial: {c: 0.5, c_dot: 9.4}
simulate: {t_end: 0.2}
"""


def test_one_coordinate_whose_inertia_grows_without_bound_ends_there(tmp_path: Path) -> None:
    """cond of a 1 x 1 M is 1: the singular stop itself (and M's one entry) says the coordinates end, at c = 1."""
    path = tmp_path / "acos.yaml"
    path.write_text(ACOS, encoding="utf-8")
    model = model_from(path).with_definitions()
    run = simulate(model, backend="compiled", method="DOP853", t_end=0.2, rtol=1e-10, atol=1e-13)
    assert run.failed and run.outcome == Status.SINGULAR and abs(float(run.y_last[0]) - 1.0) < 1e-6, run.message
    found = coordinates_end(model, run.settings, run.t, run.y, run.t_last, run.y_last, singular=True)
    assert found is not None and "its one entry grows without bound at c = 1" in found and "the coordinates end there" in found, found
    # a true blow-up is not taken for one: V = -x^4 sends x to infinity in finite time (its state not finite, or T unbounded)
    blow = model_of("coordinates: [x]\nparticles:\n  p: {mass: 1, position: [x]}\npotential: -x**4\ninitial: {x: 1.0}\n").with_definitions()
    gone = simulate(blow, backend="compiled", method="DOP853", t_end=5.0)
    assert gone.failed and coordinates_end(blow, gone.settings, gone.t, gone.y, gone.t_last, gone.y_last, singular=gone.outcome == Status.SINGULAR) is None


def test_an_unconfirmed_reference_vouches_for_no_fastest_method(tmp_path: Path) -> None:
    """Only Radau passes c = 1 (every other method stops there): its run is the reference, unconfirmed, and `accuracy`
    claimed Radau met 1e-5 against it. Now it names no fastest method, and says why."""
    path = tmp_path / "acos.yaml"
    path.write_text(ACOS, encoding="utf-8")
    result = runner.invoke(app, ["accuracy", str(path), "-q", "--json", "-"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert document["reference"]["own_error"] is None and "unconfirmed" in document["reference"]["description"], document["reference"]
    assert document["fastest"] == []
    text = " ".join(runner.invoke(app, ["accuracy", str(path), "-q"]).output.split())
    assert "no fastest method: the reference is one run that no second method confirmed" in text and "try:" not in text, text


SQRT = """\
title: A pendulum written in x, its height -sqrt(L^2 - x^2), given the energy to pass the horizontal
coordinates: [x]
parameters: {m: 1.0, L: 1.0, g: 9.81}
gravity: [0, -g]
particles:
  bob: {mass: m, position: [x, -sqrt(L**2 - x**2)]}
initial: {x: 0.0, x_dot: 6.0}
simulate: {t_end: 1}
"""

SPHERE = """\
title: A spherical pendulum in x, y, its height -sqrt(L^2 - x^2 - y^2), given the energy to rise above the pivot
coordinates: [x, y]
parameters: {m: 1.0, L: 1.0, g: 9.81}
gravity: [0, 0, -g]
particles:
  bob: {mass: m, position: [x, y, -sqrt(L**2 - x**2 - y**2)]}
initial: {x: 0.0, y: 0.0, x_dot: 6.0, y_dot: 0.5}
simulate: {t_end: 1}
"""


def test_a_run_reflected_at_the_edge_of_its_coordinates_is_warned_about(tmp_path: Path) -> None:
    """scipy's RK45 steps past x = L (where M's one entry is infinite) and comes back, and "finished" with its energy
    changed by 23 %: it is warned about, with where; an accurate run of a regular system is not, at a loose rtol either."""
    path = tmp_path / "sqrt.yaml"
    path.write_text(SQRT, encoding="utf-8")
    run = simulate(model_from(path).with_definitions(), backend="python", method="RK45")
    assert not run.failed, run.message
    (warned,) = [note for note in run.notes if note.startswith("warning: the energy, which this system conserves")]
    found = re.search(r"jumping by ([0-9.e+-]+) between t = ([0-9.e+-]+) and ([0-9.e+-]+)\)", warned)
    assert found is not None and float(found.group(1)) > 0.1 and float(found.group(2)) < 0.29795 < float(found.group(3)), warned  # x reaches L at t = 0.29795
    result = runner.invoke(app, ["simulate", str(path), "--backend", "python", "--method", "RK45", "-o", str(tmp_path / "out.csv")])
    assert result.exit_code == 0 and "not to be trusted" in " ".join(result.output.split()), result.output
    for name, rtol in (("double_pendulum_chaotic", 1e-3), ("kepler", 1e-4), ("spherical_pendulum_near_pole", 1e-3)):
        regular = simulate(model_from(ROOT / "systems" / f"{name}.yaml").with_definitions(), t_end=50.0, rtol=rtol)
        assert not regular.failed and not any("which this system conserves" in note for note in regular.notes), (name, regular.notes)


def test_a_run_stopped_where_x_y_coordinates_of_a_sphere_end_says_so(tmp_path: Path) -> None:
    """Audit 12, F6: the docs' own example class ended on "the mass matrix is singular", never the diagnosis."""
    path = tmp_path / "sphere.yaml"
    path.write_text(SPHERE, encoding="utf-8")
    run = simulate(model_from(path).with_definitions(), backend="compiled", method="DOP853")
    assert run.failed and run.outcome == Status.SINGULAR, run.message
    flat = " ".join(run.message.split())
    assert "the coordinates end there, not the motion" in flat and "grows without bound" in flat and "it changes fastest with" in flat, flat
    x, y = float(run.y_last[0]), float(run.y_last[1])
    assert abs(math.hypot(x, y) - 1.0) < 1e-3, (x, y)  # on x^2 + y^2 = L^2


def test_a_step_budget_is_honoured_exactly_by_compiled_and_auto_runs() -> None:
    """--max-steps 50 ran `auto`'s attempt to 1668 steps (and "finished"); a compiled run paused every 20000 steps
    stopped "after 20001 steps" under --max-steps 5000. Each now stops at its budget, to the step."""
    kepler = model_from(ROOT / "systems" / "kepler.yaml").with_definitions()
    for method, backend, budget in ((None, "auto", 50), ("DOP853", "compiled", 5000), ("RK45", "compiled", 25000), ("Radau", "compiled", 3000)):
        run = simulate(kepler, t_end=1e4, max_steps=budget, backend=backend, **({"method": method} if method else {}))
        assert run.failed and run.stats.steps == budget and "the step budget" in run.message, (method, budget, run.stats.steps, run.message)
    whole = simulate(kepler, t_end=1e3)
    assert not whole.failed and simulate(kepler, t_end=1e3, max_steps=whole.stats.steps).stats.steps == whole.stats.steps


FAR = audit11.FLYING


def test_a_singular_stop_at_a_regular_far_state_is_not_called_the_end_of_the_coordinates(tmp_path: Path) -> None:
    """At r = 956 M = diag(1, r^2, 1) is regular (cond 9e5 in the sizes there). The compiled run stopped there on "the
    mass matrix is singular": a trial stage's force K exp(2e4 (t - 1)) z overflowed, the LU's back substitution made
    every acceleration NaN (0 x inf), the next stage's M NaN, and accel's LU found no pivot. That is not where the
    coordinates end (ENDED_CONDITION), nor a singular M: a stage that is not finite now rejects the step, as scipy's
    DOP853 does, and the run goes on into the stiff stretch after t = 1, where its step budget stops it."""
    path = tmp_path / "far.yaml"
    path.write_text(FAR, encoding="utf-8")
    run = simulate(model_from(path).with_definitions(), backend="compiled", method="DOP853")
    assert run.failed and float(run.y_last[0]) > 100, run.message
    assert "the coordinates end" not in run.message and "mass matrix" not in run.message, run.message
    assert run.outcome == Status.BUDGET and run.t_last > 1.0, run.message
