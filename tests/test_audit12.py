"""Audit 12's last open finding: a heavy top in Euler angles whose axis passes within 3e-7 of the vertical stopped
every reference method on "the mass matrix is singular" at the same state, and `stress` called that a blow-up of the
system ("blow-up (both reference methods stop there)", no method meets it, exit 1). The motion passes there; its
coordinates end. Now the reference failure says so (`ReferenceFailed.coordinates`), `accuracy` names the state, the
coordinate and the advice, and `stress` leaves the regime undecided. A true blow-up (V = -x^4) stays one
(tests/test_stress.py). No clock: statuses and messages only."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.numeric import stress
from lagrange_cli.numeric.reference import ReferenceFailed, computed_reference
from lagrange_cli.numeric.runs import Setup, starting

from .helpers import model_from

runner = CliRunner()

TOP = """\
title: Heavy top in Euler angles, its axis passing within 3e-7 of the vertical
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
initial: {theta: 0.01, phi: 0.0, psi: 0.0, theta_dot: -2.0, phi_dot: 1.0e-5, psi_dot: -1.0e-5}
simulate: {t_end: 0.01}
"""


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
