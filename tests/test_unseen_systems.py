"""Systems that are not bundled (tests/unseen/): a rotating wire, a chaotic driven pendulum, a
Duffing double well, coupled pendula, a torus, rigid rods, a kept constraint, Rayleigh damping,
a Cartesian drag force, SI units at the scale of an orbit and of a MEMS device, a start at an
exact equilibrium and one at zero. Each runs through `simulate`, `accuracy` and `stress` in
quick settings: no traceback, the right exit code and sections, and the physics the file's
description states (energy conserved, dissipated, exact solutions met)."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from lagrange_cli.cli import app

from .conftest import ROOT
from .helpers import model_from

runner = CliRunner()
UNSEEN = ROOT / "tests" / "unseen"
FILES = sorted(UNSEEN.glob("*.yaml"))
CONSERVES_ENERGY = {
    "bead_rotating_parabola",  # rheonomic, but L has no explicit t: the Jacobi integral
    "compound_double_pendulum",
    "coupled_pendula_spring",
    "incline_multiplier",
    "particle_on_torus",
    "physical_pendulum_at_rest",
    "satellite_orbit_si",
    "zero_start_springs",
}
DISSIPATES = {"mems_resonator", "projectile_quadratic_drag", "rayleigh_two_masses"}  # autonomous, dE/dt = -2R <= 0


pytestmark = pytest.mark.usefixtures("private_cache")


def invoke(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args))
    assert "Traceback" not in result.output, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    return result.exit_code, result.output


def trajectory(path: Path) -> dict[str, np.ndarray]:
    rows = list(csv.reader(io.StringIO(path.read_text())))
    data = np.array(rows[1:], dtype=float)
    return {name: data[:, i] for i, name in enumerate(rows[0])}


def invariant(output: str, name: str) -> tuple[str, float, float]:
    """(expected, max change, relative) of one row of simulate's invariants table."""
    for line in output.splitlines():
        cells = [c.strip() for c in line.split("│")]
        if len(cells) == 7 and cells[1] == name:
            return cells[2], float(cells[4]), float(cells[5])
    raise AssertionError(f"no invariant {name!r} in:\n{output}")


def test_every_file_is_described_and_its_expectations_hold() -> None:
    for path in FILES:
        document = yaml.safe_load(path.read_text())
        assert len(document["description"]) > 200, path.name
    code, output = invoke("check", str(UNSEEN))
    assert code == 0 and f"{len(FILES)} files: {len(FILES)} passed, 0 failed" in output, output


def test_the_derivation_agrees_about_energy() -> None:
    """The bead's wire turns with time, but its Lagrangian does not depend on t: h is conserved."""
    for path in FILES:
        assert model_from(path).energy_conserved == (path.stem in CONSERVES_ENERGY), path.name


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_simulate_with_the_files_defaults(path: Path, tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    code, output = invoke("simulate", str(path), "--backend", "python", "--samples", "101", "-o", str(out))
    assert code == 0 and "finished: reached t = " in output, output
    data = trajectory(out)
    t_end = model_from(path).simulate.get("t_end", 10.0)
    assert len(data["t"]) == 101 and data["t"][-1] == pytest.approx(t_end) and all(np.all(np.isfinite(v)) for v in data.values())
    expected, change, relative = invariant(output, "energy")
    if path.stem in CONSERVES_ENERGY:
        assert expected == "conserved" and relative < 1e-6, output
    else:
        assert expected == "not conserved" and change > 0, output
    if path.stem in DISSIPATES:
        assert np.all(np.diff(data["energy"]) <= 1e-9 * abs(data["energy"][0]) + 1e-300) and data["energy"][-1] < data["energy"][0]


def test_satellite_runs_on_the_python_backend() -> None:
    code, output = invoke("simulate", str(UNSEEN / "satellite_orbit_si.yaml"), "--backend", "python", "--samples", "11")
    assert code == 0 and "finished" in output, output


def test_satellite_in_si_units_conserves_energy_and_angular_momentum_compiled() -> None:
    """A mass matrix diag(m, m r^2) = diag(500, 2.45e16) is not singular (each row is measured
    against itself), and the symplectic method's stage equations converge for every component
    (r ~ 7e6, p_theta ~ 3e13, theta ~ 1) although their sizes differ by 13 orders."""
    satellite = str(UNSEEN / "satellite_orbit_si.yaml")
    code, output = invoke("simulate", satellite, "--method", "DOP853", "--backend", "compiled", "--samples", "11")
    assert code == 0 and invariant(output, "energy")[2] < 1e-8 and invariant(output, "p_theta")[2] < 1e-8, output
    code, output = invoke("simulate", satellite, "--method", "symplectic", "--step", "6.3", "--samples", "11")
    assert code == 0 and invariant(output, "energy")[2] < 1e-11 and invariant(output, "p_theta")[2] < 1e-13, output


def test_symplectic_method_meets_the_exact_solution_at_the_scale_of_a_mems_device(tmp_path: Path) -> None:
    """x ~ 1e-8 m and p = m x_dot ~ 1e-13: the stage equations are solved relative to each
    component's own size (before, a 1e-11 absolute test stopped Newton at once: error 2e-4)."""
    out = tmp_path / "mems.csv"
    code, output = invoke("simulate", str(UNSEEN / "mems_resonator.yaml"), "--method", "symplectic", "--samples", "201", "-o", str(out))
    assert code == 0, output
    data = trajectory(out)
    m, k, c, t = 1e-10, 1.0, 1e-8, data["t"]
    damped, rate = math.sqrt(k / m - c**2 / (4 * m * m)), c / (2 * m)
    exact = 1e-8 * np.exp(-rate * t) * (np.cos(damped * t) + rate / damped * np.sin(damped * t))
    assert np.max(np.abs(data["x"] - exact)) < 1e-6 * 1e-8


def test_symplectic_run_ends_with_a_sample_at_t_end(tmp_path: Path) -> None:
    """100 / 0.0632 steps do not land on t_end in floating point: the last step is snapped to it."""
    out = tmp_path / "driven.csv"
    code, output = invoke("simulate", str(UNSEEN / "driven_damped_pendulum.yaml"), "--method", "symplectic", "--step", "0.0632", "--samples", "201", "-o", str(out))
    assert code == 0 and "reached t = 100" in output, output
    data = trajectory(out)
    assert len(data["t"]) == 201 and data["t"][-1] == 100.0


def test_a_start_at_zero_gets_a_meaningful_relative_energy_error() -> None:
    code, output = invoke("simulate", str(UNSEEN / "zero_start_springs.yaml"), "--backend", "python")
    assert code == 0 and "sum p q_dot" in output, output
    _, change, relative = invariant(output, "energy")
    assert change > 0 and relative < change / 10 and relative < 1e-6


def test_a_start_at_an_exact_equilibrium_stays_there(tmp_path: Path) -> None:
    out = tmp_path / "rest.csv"
    for method in ("DOP853", "Radau", "symplectic"):
        code, output = invoke("simulate", str(UNSEEN / "physical_pendulum_at_rest.yaml"), "--method", method, "-o", str(out))
        assert code == 0 and invariant(output, "energy")[1] == 0.0, output
        data = trajectory(out)
        assert np.all(data["theta"] == 0.0) and np.all(data["theta_dot"] == 0.0)


def test_drag_started_at_rest_runs_with_the_implicit_methods() -> None:
    """d(|v| v)/dv is 0/0 at v = 0 in its formula: the Jacobian falls back to differences, and
    the failure is not blamed on the mass matrix."""
    for method in ("Radau", "BDF", "LSODA"):
        code, output = invoke("simulate", str(UNSEEN / "projectile_quadratic_drag.yaml"), "--initial", "x_dot=0,y_dot=0", "--method", method, "--samples", "11")
        assert code == 0 and "finished" in output and "singular" not in output, (method, output)


def test_the_ball_lands_where_the_description_says() -> None:
    code, output = invoke("simulate", str(UNSEEN / "projectile_quadratic_drag.yaml"), "--until", "y", "--backend", "python")
    assert code == 0 and "event: stopped at t = 3.7" in output, output


def test_an_initial_state_off_the_constraint_is_reported() -> None:
    code, output = invoke("simulate", str(UNSEEN / "incline_multiplier.yaml"), "--initial", "x=1", "--backend", "python", "--samples", "11")
    assert code == 0 and "violates constraint 'plane' (residual 0.479 in the positions" in output, output
    code, output = invoke("simulate", str(UNSEEN / "incline_multiplier.yaml"), "--backend", "python", "--samples", "11")
    assert code == 0 and "violates" not in output, output


def test_a_negative_value_for_a_positive_parameter_is_refused() -> None:
    code, output = invoke("simulate", str(UNSEEN / "mems_resonator.yaml"), "--set", "m=-1e-10")
    assert code == 2 and "'m' is positive" in output and "sign: real" in output, output
    code, output = invoke("simulate", str(UNSEEN / "duffing_double_well.yaml"), "--set", "alpha=-2", "--t-end", "1", "--backend", "python")
    assert code == 0, output


QUICK_STUDY = ("--method", "DOP853:python,RK45:python", "--tolerances", "1e-4,1e-6", "--repeats", "0", "--max-steps", "20000", "--samples", "51")


@pytest.mark.parametrize("name", ["mems_resonator", "zero_start_springs", "incline_multiplier", "physical_pendulum_at_rest"])
def test_accuracy_against_the_files_exact_solutions(name: str) -> None:
    code, output = invoke("accuracy", str(UNSEEN / f"{name}.yaml"), *QUICK_STUDY)
    assert code == 0, output
    assert "reference: the file's exact solution" in output and "fastest method for each accuracy" in output
    assert "nan" not in output.lower() and "inf" not in output.split("runs", 1)[1].lower()
    rows = [line for line in output.splitlines() if line.lstrip().startswith(("DOP853", "RK45"))]
    assert len(rows) == 4 and all(line.rstrip().endswith("ok") for line in rows), output


def test_accuracy_of_a_chaotic_driven_pendulum_states_its_window() -> None:
    code, output = invoke("accuracy", str(UNSEEN / "driven_damped_pendulum.yaml"), *QUICK_STUDY, "--t-end", "60")
    assert code == 0 and "fastest method for each accuracy" in output, output
    assert "t = inf" not in output and "chaotic" in output


def test_accuracy_of_a_system_in_si_units() -> None:
    code, output = invoke("accuracy", str(UNSEEN / "satellite_orbit_si.yaml"), "--method", "DOP853", "--tolerances", "1e-5,1e-7", "--repeats", "0", "--samples", "51")
    assert code == 0 and "fastest method for each accuracy" in output, output
    rows = [line for line in output.splitlines() if line.lstrip().startswith("DOP853")]
    assert len(rows) == 2 and all(line.rstrip().endswith("ok") for line in rows), output


QUICK_STRESS = ("--method", "DOP853:python", "--method", "RK45:python", "--max-steps", "20000", "--long", "2")


@pytest.mark.parametrize(("name", "t_end"), [("rayleigh_two_masses", "5"), ("incline_multiplier", "1.5"), ("physical_pendulum_at_rest", "2")])
def test_stress_in_quick_mode(name: str, t_end: str) -> None:
    code, output = invoke("stress", str(UNSEEN / f"{name}.yaml"), *QUICK_STRESS, "--t-end", t_end, "--accuracy", "1e-4")
    assert code == 0, output
    for section in ("defaults: t_end = ", "long horizon (t_end x 2)", "high energy", "summary", "recommended: "):
        assert section in output, (section, output)
    assert "every regime has a method that meets it" in output


def test_stress_regimes_are_built_in_the_systems_own_units() -> None:
    """An SI orbit (r = 7e6 m): the near-singular start is 1% of r from the centre, not 1 cm."""
    from lagrange_cli.numeric import stress

    satellite = model_from(UNSEEN / "satellite_orbit_si.yaml")
    near = next(r for r in stress.regimes(satellite, []) if r.name.startswith("near singular"))
    assert near.initial == {"r": pytest.approx(7e4)}
    pendulum = model_from(ROOT / "systems" / "spherical_pendulum.yaml")
    near = next(r for r in stress.regimes(pendulum, []) if r.name.startswith("near singular"))
    assert near.initial == {"theta": pytest.approx(0.01)}


def test_mass_condition_does_not_depend_on_the_units() -> None:
    """diag(m, m r^2) at r = 7e6 m is as well conditioned as at r = 1: no coordinate singularity."""
    from lagrange_cli.numeric import diagnostics
    from lagrange_cli.numeric.settings import resolve

    satellite = model_from(UNSEEN / "satellite_orbit_si.yaml")
    s = resolve(satellite)
    condition = diagnostics.mass_condition(satellite, s.p, s.y0)
    assert condition(0.0, np.array(s.y0)) == pytest.approx(1.0)
    near = np.array(s.y0)
    near[0] = 7e4
    assert condition(0.0, near) == pytest.approx(1e4)


def test_a_compiled_run_returns_to_its_caller_before_the_first_percent() -> None:
    """A near-collision orbit (r = 7e4 m, nearly radial) takes millions of tiny steps: the compiled
    loop pauses every kernels.PAUSE_STEPS steps, so that progress is shown and a step budget or a time limit can stop it early."""
    from lagrange_cli.numeric import simulate

    class Stop(Exception):
        pass

    fractions: list[float] = []

    def progress(fraction: float) -> None:
        fractions.append(fraction)
        raise Stop

    with pytest.raises(Stop):
        simulate(model_from(UNSEEN / "satellite_orbit_si.yaml"), method="DOP853", backend="compiled", rtol=1e-6, initial={"r": 7e4}, progress=progress)
    assert len(fractions) == 1 and fractions[0] < 0.01
