"""Projection onto kept constraints (numeric/projection.py) and its use by `simulate`.

The multiplier pendulum (Cartesian, the rod kept as x^2 + y^2 = l^2) is checked against the
exact solution of the same pendulum in its angle (`systems/simple_pendulum.yaml` with the same
parameters; released from rest at theta0, theta(t) = 2 arcsin(k cd(omega t | k^2)), k =
sin(theta0 / 2)): with projection its constraint residual stays at round-off and it meets the
accuracy asked for; without, the residual and the error drift (the contrast is part of the test).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ellipj

from lagrange_cli.numeric.projection import Projector
from lagrange_cli.numeric.simulate import InvariantKind, simulate
from tests.conftest import ROOT
from tests.helpers import model_from

pytestmark = pytest.mark.usefixtures("private_cache")


@pytest.fixture(scope="module")
def pendulum():  # type: ignore[no-untyped-def]
    return model_from(ROOT / "systems" / "pendulum_multiplier.yaml")


def exact_angle(t: np.ndarray, theta0: float = 1.0, g: float = 9.81, length: float = 1.0) -> np.ndarray:
    k = math.sin(theta0 / 2)
    _, cn, dn, _ = ellipj(math.sqrt(g / length) * t, k * k)
    return 2 * np.arcsin(k * cn / dn)  # type: ignore[no-any-return]


def test_the_exact_solution_is_the_simple_pendulum() -> None:
    """The reference itself: the simple pendulum file integrated tightly agrees with the formula."""
    simple = model_from(ROOT / "systems" / "simple_pendulum.yaml")
    run = simulate(simple, t_end=5.0, method="DOP853", rtol=1e-12, atol=1e-14, samples=51, backend="python")
    assert np.max(np.abs(run.y[:, 0] - exact_angle(run.t))) < 1e-9


def test_projection_puts_a_perturbed_state_back_on_the_constraints(pendulum) -> None:  # type: ignore[no-untyped-def]
    projector = Projector(pendulum, [1.0, 1.0, 9.81])  # m, l, g
    theta, omega = 0.7, 1.3
    exact = np.array([math.sin(theta), -math.cos(theta), omega * math.cos(theta), omega * math.sin(theta)])
    off = exact + np.array([3e-6, -2e-6, 4e-6, 1e-6])
    projected, correction = projector.project(0.0, off)
    x, y, vx, vy = projected
    assert abs(x * x + y * y - 1.0) < 1e-15 and abs(x * vx + y * vy) < 1e-15
    assert correction.position > 1e-6 and correction.velocity > 1e-6  # what it corrected, before
    assert np.max(np.abs(projected - exact)) < 1e-5  # a small correction, not a jump elsewhere on the circle


def test_projection_fixes_velocity_constraints_of_a_nonholonomic_system() -> None:
    sleigh = model_from(ROOT / "systems" / "chaplygin_sleigh.yaml")
    values = [p.value for p in sleigh.parameters]
    projector = Projector(sleigh, values)  # type: ignore[arg-type]
    y = np.array([0.1, 0.2, 0.3, 0.5, 0.7, 2.0])  # x, y, phi, x_dot, y_dot, phi_dot: off the blade's constraint
    projected, correction = projector.project(0.0, y)
    phi, vx, vy = projected[2], projected[3], projected[4]
    assert correction.velocity > 0.1
    assert abs(-math.sin(phi) * vx + math.cos(phi) * vy) < 1e-15
    assert np.array_equal(projected[:3], y[:3])  # no position constraint: positions untouched


def test_long_run_stays_on_the_constraint_and_meets_the_accuracy_only_with_projection(pendulum) -> None:  # type: ignore[no-untyped-def]
    t_end, rtol = 100.0, 1e-8
    runs = {on: simulate(pendulum, t_end=t_end, method="DOP853", rtol=rtol, atol=1e-10, samples=101, backend="python", projection=on) for on in (True, False)}
    theta = exact_angle(runs[True].t)
    errors, residuals = {}, {}
    for on, run in runs.items():
        assert run.status == "finished", run.message
        errors[on] = float(np.max(np.abs(run.y[:, :2] - np.column_stack([np.sin(theta), -np.cos(theta)]))))
        constraint = run.invariant(InvariantKind.CONSTRAINT)
        assert constraint is not None
        residuals[on] = constraint.max_change
    assert residuals[True] < 1e-14, residuals  # round-off
    assert residuals[False] > 1e-10, residuals  # Baumgarte alone: the residual drifts
    assert errors[True] < 1e-6 < errors[False], errors
    assert any("projection onto the kept constraints" in note for note in runs[True].notes)
    assert not any("projection" in note for note in runs[False].notes)


def test_no_projection_without_constraints() -> None:
    simple = model_from(ROOT / "systems" / "simple_pendulum.yaml")
    run = simulate(simple, t_end=1.0, method="RK45", samples=11, backend="python")
    assert not run.settings.projection and not any("projection" in note for note in run.notes)


def test_projection_must_be_a_boolean(pendulum) -> None:  # type: ignore[no-untyped-def]
    from lagrange_cli.errors import LagrangeError

    with pytest.raises(LagrangeError, match="projection must be true or false"):
        simulate(pendulum, t_end=1.0, projection="yes")  # type: ignore[arg-type]


def test_many_samples_are_projected_in_at_most_max_stretches(pendulum) -> None:  # type: ignore[no-untyped-def]
    import re

    from lagrange_cli.numeric.simulate import MAX_STRETCHES

    run = simulate(pendulum, t_end=2.0, method="DOP853", samples=2 * MAX_STRETCHES + 501, backend="python")
    assert run.status == "finished" and len(run.t) == 2 * MAX_STRETCHES + 501
    note = next(n for n in run.notes if n.startswith("projection"))
    stretches = int(re.search(r"after each of (\d+) stretches", note).group(1))  # type: ignore[union-attr]
    assert 100 < stretches <= MAX_STRETCHES, note
    constraint = run.invariant(InvariantKind.CONSTRAINT)
    assert constraint is not None and constraint.final_change < 1e-14  # projected at the end


def test_the_cli_turns_projection_on_and_off(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """`simulate --projection/--no-projection`: the note of the projection (on by default for kept
    constraints) appears or not, and the constraint residual of the written trajectory follows."""
    from typer.testing import CliRunner

    from lagrange_cli.cli import app

    runner = CliRunner()
    path = str(ROOT / "systems" / "pendulum_multiplier.yaml")
    common = ["simulate", path, "--t-end", "20", "--samples", "41", "--method", "DOP853", "--backend", "python", "--rtol", "1e-5", "--atol", "1e-7", "-q"]
    results = {flag: runner.invoke(app, [*common, *([flag] if flag else []), "-o", str(tmp_path / f"{flag or 'default'}.csv")]) for flag in ("--projection", "--no-projection", "")}
    for flag, result in results.items():
        assert result.exit_code == 0, (flag, result.output)
    assert "projection onto the kept constraints" in results["--projection"].output
    assert "projection onto the kept constraints" in results[""].output  # the default for kept constraints
    assert "projection onto the kept constraints" not in results["--no-projection"].output

    def residual(name: str) -> float:
        data = np.genfromtxt(tmp_path / f"{name}.csv", delimiter=",", names=True)
        return float(np.max(np.abs(data["x"] ** 2 + data["y"] ** 2 - 1.0)))

    assert residual("--projection") < 1e-12 < residual("--no-projection")
