"""Audit 11's findings on the numeric commands' diagnoses and advice, each checked in the program's output:

- F1: a run that reaches the edge of the region its coordinates describe (a pendulum bob written in x, y with its
  height -sqrt(L^2 - x^2 - y^2), given the energy to reach the pivot's height) stalls there, whatever the method: it
  says so (`simulate.Status.STALLED`), names the state (on x^2 + y^2 = L^2) and advises other coordinates, never more
  steps; `stress` reports the regime undecided with that cause and tries no further reference method;
- F2: `--max-steps` raises the fixed step caps of one reference attempt (`reference.scaled`), as the messages say;
- F3: every stress regime prints where it starts, also one without a reference;
- F4: a claimed error below the reference's own error is shown as the bound it is;
- F5: budget advice that fits the method; a capped symplectic rung passed on with its own rtol.
No clock: statuses, messages and step counts only."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.cli.study import _claimed
from lagrange_cli.numeric import reference
from lagrange_cli.numeric.runs import Setup

from .conftest import ROOT

runner = CliRunner()

BOWL = """\
title: A pendulum bob written in x, y (below the pivot)
coordinates: [x, y]
parameters:
  m: {value: 1.5}
  L: {value: 2.0}
  g: {value: 9.81}
particles:
  bob:
    mass: m
    position: [x, y, -sqrt(L**2 - x**2 - y**2)]
potential: -m*g*sqrt(L**2 - x**2 - y**2)
initial: {x: 0.5, y: 0.0, x_dot: 0.0, y_dot: 7.0}
simulate: {t_end: 2}
"""
L = 2.0


def _bowl(tmp_path: Path) -> Path:
    path = tmp_path / "bowl.yaml"
    path.write_text(BOWL, encoding="utf-8")
    return path


def _flat(text: str) -> str:
    return " ".join(text.split())


def _state(message: str) -> dict[str, float]:
    found = re.search(r"state: (.*?)(?:;|$)", message)
    assert found, message
    return {name: float(value) for name, value in re.findall(r"(\w+) = ([-+0-9.e]+)", found.group(1))}


def test_a_run_reaching_the_edge_of_its_coordinates_says_so_whatever_the_method(tmp_path: Path) -> None:
    system = _bowl(tmp_path)
    for method in (["--method", "RK45", "--backend", "python"], ["--method", "Radau", "--backend", "python"], ["--method", "LSODA"]):
        result = runner.invoke(app, ["simulate", str(system), *method, "--max-steps", "3000", "-o", str(tmp_path / "t.csv")])
        assert result.exit_code == 1, result.output
        text = _flat(result.stderr)
        assert "the coordinates end there" in text and "grows without bound" in text, text
        assert "raise the budget" not in text and "--step" not in text and "Traceback" not in text, text
        state = _state(text.split("error: ", 1)[1])
        assert math.isclose(state["x"] ** 2 + state["y"] ** 2, L**2, rel_tol=1e-4), state  # on the edge: x^2 + y^2 = L^2


INFALL = """\
title: Radial infall in polar coordinates
coordinates: [r, th]
parameters:
  k: {value: 1.0}
particles:
  p:
    mass: 1
    position: [r*cos(th), r*sin(th), 0]
potential: -k/r
initial: {r: 1.0, th: 0.0, r_dot: 0.0, th_dot: 0.0}
simulate: {t_end: 3}
"""


def test_a_collision_is_not_taken_for_coordinates_that_end(tmp_path: Path) -> None:
    """At r = 1e-9 cond M = 1/r^2 is 1e18, as where coordinates end, but the kinetic energy is 1e8 x its largest along the
    run: the motion itself blows up (`simulate.STALL_KINETIC`)."""
    system = tmp_path / "infall.yaml"
    system.write_text(INFALL, encoding="utf-8")
    result = runner.invoke(app, ["simulate", str(system), "--method", "RK45", "--backend", "python", "-o", str(tmp_path / "t.csv")])
    assert result.exit_code == 1, result.output
    text = _flat(result.stderr)
    assert "the step size collapsed" in text and "coordinates end" not in text, text


TOP = """\
title: Heavy top in Euler angles whose axis passes within 1e-6 of the vertical
coordinates: [theta, phi, psi]
parameters: {m: 1.0, l: 1.0, g: 9.81, I_perp: 1.0, I_par: 2.0}
gravity: [0, 0, -g]
bodies:
  top:
    mass: m
    position: [l*sin(theta)*sin(phi), -l*sin(theta)*cos(phi), l*cos(theta)]
    inertia: [I_perp, I_perp, I_par]
    angular_velocity:
      - phi_dot*sin(theta)*sin(psi) + theta_dot*cos(psi)
      - phi_dot*sin(theta)*cos(psi) - theta_dot*sin(psi)
      - phi_dot*cos(theta) + psi_dot
initial: {theta: 0.3, phi: 0.0, psi: 0.0, theta_dot: -2.0, phi_dot: 1.0e-5, psi_dot: -1.0e-5}
simulate: {t_end: 0.2}
"""
FLYING = """\
title: A free particle in polar coordinates flying out to r = 1000, and an oscillator whose stiffness grows with t
coordinates: [r, theta, z]
parameters: {m: 1.0, K: 1.0, a: 20000.0}
particles:
  p: {mass: m, position: [r*cos(theta), r*sin(theta)]}
  q: {mass: m, position: [0, 0, z]}
potential: K/2*exp(a*(t - 1))*z**2
initial: {r: 1.0, r_dot: 1000.0, theta: 0.0, theta_dot: 1.0, z: 0.001, z_dot: 0.0}
simulate: {t_end: 5}
"""


def test_a_budget_that_ends_inside_a_close_pass_or_a_stiff_stretch_is_no_stall(tmp_path: Path) -> None:
    """Audit 12: the top's axis passes within 1e-6 of the vertical at t = 0.156, which 16578 scipy steps pass; with 500
    the run stops inside the pass, cond M 1e12, and the probe is still going when its evaluations run out: not shown to
    be stuck, so the budget is named. The particle's r grows to 1000 (cond M = r^2 in the start's sizes, 1 in its own)
    while the oscillator's stiffness shrinks Radau's steps to 5e-10: a budget, not coordinates that end."""
    top, flying = tmp_path / "top.yaml", tmp_path / "flying.yaml"
    top.write_text(TOP, encoding="utf-8")
    flying.write_text(FLYING, encoding="utf-8")
    for system, options in ((top, ["--backend", "python", "--max-steps", "500"]), (flying, ["--method", "Radau", "--backend", "compiled", "--max-steps", "100000"])):
        result = runner.invoke(app, ["simulate", str(system), *options, "-o", str(tmp_path / "t.csv")])
        assert result.exit_code == 1, result.output
        text = _flat(result.stderr)
        assert "(the step budget)" in text and "coordinates end" not in text, text


def test_a_run_merely_over_its_budget_is_advised_what_fits_its_method(tmp_path: Path) -> None:
    system = str(ROOT / "systems" / "harmonic_oscillator.yaml")
    adaptive = runner.invoke(app, ["simulate", system, "--method", "RK45", "--backend", "python", "--max-steps", "5", "-o", str(tmp_path / "a.csv")])
    assert adaptive.exit_code == 1, adaptive.output
    text = _flat(adaptive.stderr)
    assert "(the step budget)" in text and "raise the budget (--max-steps)" in text and "--rtol" in text, text
    assert "--step" not in text and "coordinates end" not in text, text


def test_stress_calls_a_regime_whose_coordinates_end_undecided_and_says_where_each_regime_starts(tmp_path: Path) -> None:
    out = tmp_path / "r.json"
    result = runner.invoke(app, ["stress", str(_bowl(tmp_path)), "-q", "--json", str(out)])
    assert result.exit_code == 0, result.output  # undecided: no reference could be made, never a blow-up
    regimes = json.loads(out.read_text(encoding="utf-8"))["regimes"]
    assert [r["verdict"] for r in regimes] == ["undecided"] * 3, [r["verdict"] for r in regimes]
    for regime in regimes:
        cause = regime["findings"][0]
        assert cause.startswith("no reference: the coordinates end: ") and "blow-up" not in cause, cause
        assert "a larger --max-steps" not in cause and "also at rtol" not in cause, cause  # no looser or implicit reattempts
        assert any(f.startswith("near a coordinate singularity") and "grows without bound" in f for f in regime["findings"]), regime["findings"]
    energetic = regimes[2]
    assert energetic["regime"].startswith("high energy") and energetic["initial"]["y_dot"] == 21.0, energetic  # F3: the start, in JSON ...
    flat = _flat(result.output)
    assert "start: --initial y_dot=21 " in flat  # ... and in the text, where no `try:` line gives it
    summary = flat.split("summary", 1)[1]
    assert "not run" not in summary  # F5: notes about runs are no diagnosis of the system


def test_max_steps_raises_the_caps_of_a_reference_attempt() -> None:
    plain = Setup(1.0, (0.0, 1.0), max_steps=60_000)
    raised = Setup(1.0, (0.0, 1.0), max_steps=600_000, raised=10.0)
    for cap in (reference.COMPILED_RADAU_STEPS, reference.EXPLICIT_REFERENCE_STEPS, reference.CONFIRMATION_STEPS, reference.TIGHTER_RADAU_STEPS):
        assert reference.scaled(plain, cap) == cap and reference.scaled(raised, cap) == 10 * cap
    assert reference.scaled(Setup(1.0, (0.0, 1.0), max_steps=6000, raised=0.1), reference.COMPILED_RADAU_STEPS) == reference.COMPILED_RADAU_STEPS  # never below


def test_a_claimed_error_below_the_references_own_error_is_shown_as_a_bound() -> None:
    assert _claimed(7.85e-9, 1.9e-8) == "<2.7e-08"  # audit 11's fast-pivot double pendulum: 2.1e-8 against an independent reference
    assert _claimed(4.7e-7, 1.9e-8) == "4.7e-07"
    assert _claimed(4.7e-7, math.nan) == "4.7e-07"
    assert _claimed(math.nan, 1e-8) == "-"
