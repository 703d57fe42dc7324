"""Audit 7 F3: a model whose mass matrix becomes singular in time, whatever the state (a crane reeling its rope in
to zero length at t = 13.33), was reported after four reference runs of up to 2e6 steps as "no reference" and
"near a coordinate singularity", a singularity no coordinates remove; `simulate` past it stopped at its step
budget with a hint to raise it. `diagnostics.time_singularity` finds such a time; `stress` runs nothing past it
(the long horizon has no verdict: "beyond the model"; a regime over the file's own time span is not met) and
`simulate` says the model ends there. Counted in runs and steps, never time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lagrange_cli.numeric import diagnostics, stress
from lagrange_cli.numeric.runs import Setup
from lagrange_cli.numeric.settings import validate
from lagrange_cli.numeric.simulate import model_end, simulate

from .conftest import ROOT
from .helpers import model_from, model_of

CRANE = ROOT / "tests/numeric_audit7/crane_reeling_in_on_sprung_trolley.yaml"
BEAD = """title: a bead on a rod whose scale shrinks to zero at t = 2
coordinates: [s]
parameters: {m: 0.7, L0: 2.0, u: 1.0, k: 3.0}
particles:
  bead: {mass: m, position: [(L0 - u*t)*s, 0]}
potential: k*s**2/2
initial: {s: 0.3}
simulate: {t_end: 3}
"""


def _end(model, t1: float) -> float | None:
    start = validate(model, method="DOP853", backend="python")
    mass = diagnostics.mass_at(model, start.values)
    return diagnostics.time_singularity(mass, start.t0, t1, start.y0[: model.n], diagnostics.coordinate_sizes(start.y0, model.n))


def test_the_crane_ends_where_its_rope_has_no_length() -> None:
    assert _end(model_from(CRANE), 100.0) == pytest.approx(2.0 / 0.15, rel=1e-6)  # L0 - u t = 0
    assert _end(model_from(CRANE), 13.0) is None  # the span stops short of it


def test_a_mass_matrix_shrinking_as_a_whole_is_found() -> None:
    # m (L0 - u t)^2: cond M stays 1 all the way to zero, so the test is M's size against the start
    assert _end(model_of(BEAD), 3.0) == pytest.approx(2.0, rel=1e-6)


@pytest.mark.parametrize(
    "text",
    [
        # a rope whose length swings between 0.5 and 1.5: never zero
        "coordinates: [th]\nparameters: {m: 1.0, g: 9.81}\nparticles:\n  p: {mass: m, position: [(1 + 0.5*sin(3*t))*sin(th), -(1 + 0.5*sin(3*t))*cos(th)]}\n"
        "gravity: [0, -g]\ninitial: {th: 0.4}\nsimulate: {t_end: 10}\n",
        # a spherical pendulum of oscillating length: singular at its pole (the coordinates), not in time
        "coordinates: [th, ph]\nparameters: {m: 1.0}\nparticles:\n  p: {mass: m, position: [(2 + sin(t))*sin(th)*cos(ph), (2 + sin(t))*sin(th)*sin(ph), -(2 + sin(t))*cos(th)]}\n"
        "initial: {th: 0.7, ph: 0.1, ph_dot: 1.0}\nsimulate: {t_end: 10}\n",
    ],
)
def test_no_time_singularity_where_the_model_has_none(text: str) -> None:
    assert _end(model_of(text), 100.0) is None


def test_the_parametric_swing_has_none() -> None:
    assert _end(model_from(ROOT / "tests/numeric_audit5/parametric_swing_sprung_support.yaml"), 400.0) is None


def test_stress_runs_nothing_past_the_end_of_the_model() -> None:
    model = model_from(CRANE)
    long, defaults = stress.Regime("long horizon (t_end x 10)", 100.0, {}, {}, horizon=True), stress.Regime("defaults", 20.0, {}, {})
    budget = Setup(10.0, (), {}, {}, 60000)
    beyond = stress._regime(model, long, 1e-6, (stress.AUTO,), budget, None)
    assert beyond.beyond and not beyond.points and beyond.verdict == "beyond the model"
    assert not beyond.undecided and not beyond.met
    assert beyond.diagnosis.findings[0].kind == "singular in time"
    assert "t = 13.3333" in beyond.diagnosis.findings[0].detail
    over = stress._regime(model, defaults, 1e-6, (stress.AUTO,), budget, None)
    assert not over.points and over.verdict == "not met"  # the file's own span past the model's end: no method can
    report = stress.Report("crane", 1e-6, (beyond,))
    assert report.passed and not report.failed
    assert stress.Report("crane", 1e-6, (beyond, over)).failed


def test_a_model_without_time_in_its_mass_matrix_is_not_searched() -> None:
    model = model_from(ROOT / "systems/double_pendulum.yaml")
    start = validate(model, method="DOP853", backend="python")
    assert model_end(model, start, 3.0) is None
    assert stress._model_end(model, Setup(10.0, (), {}, {}, 60000)) is None


def test_simulate_says_the_model_ends_there() -> None:
    model = model_of(BEAD, "bead.yaml")
    for method in ("DOP853", "Radau"):
        run = simulate(model, method=method, backend="python", max_steps=1000)
        assert run.status == "failed"
        assert abs(run.t_last - 2.0) < 1e-3
        assert "where the model itself ends: its mass matrix is singular at t = 2 whatever the state" in run.message, run.message
    shorter = simulate(model, method="DOP853", backend="python", t_end=1.9)
    assert shorter.status == "finished" and math.isclose(shorter.t_last, 1.9)
    assert np.all(np.isfinite(shorter.y))
