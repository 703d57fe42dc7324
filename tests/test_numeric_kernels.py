"""The pieces under `simulate`: tableaux, the linear solvers, the generated Jacobian, the on-disk cache,
and that numba is loaded only by runs that use it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lagrange_cli.numeric import compile, tableaux

from .conftest import ROOT
from .helpers import model_from, model_of
from .limits import DEADLOCK


def test_tableaux_are_scipys() -> None:
    from scipy.integrate._ivp import dop853_coefficients as dop
    from scipy.integrate._ivp.rk import RK45

    for ours, theirs in [(tableaux.RK45_A, RK45.A), (tableaux.RK45_B, RK45.B), (tableaux.RK45_E, RK45.E), (tableaux.RK45_P, RK45.P)]:
        assert np.array_equal(np.array(ours), theirs)
    for ours, theirs in [(tableaux.DOP853_A, dop.A), (tableaux.DOP853_C, dop.C), (tableaux.DOP853_D, dop.D), (tableaux.DOP853_E3, dop.E3), (tableaux.DOP853_E5, dop.E5)]:
        assert np.array_equal(np.array(ours), theirs)


@pytest.mark.parametrize("stages", [1, 2, 3])
def test_gauss_tableaux_satisfy_the_order_conditions(stages: int) -> None:
    """sum_j a_ij c_j^(k-1) = c_i^k / k and sum_i b_i c_i^(k-1) = 1/k for k <= s (collocation, order 2s)."""
    c, a, b = (np.array(x) for x in tableaux.GAUSS[stages])
    for k in range(1, stages + 1):
        assert np.allclose(a @ c ** (k - 1), c**k / k) and np.isclose(b @ c ** (k - 1), 1 / k)
    for k in range(stages + 1, 2 * stages + 1):
        assert np.isclose(b @ c ** (k - 1), 1 / k)


def test_python_solver_and_jacobian(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The generated analytic Jacobian equals a central finite difference of the generated rhs."""
    monkeypatch.setenv("LAGRANGE_CACHE_DIR", str(tmp_path))
    for name in ("double_pendulum", "rolling_disk_pendulum_multiplier", "charged_particle_magnetic", "pendulum_moving_support"):
        model = model_from(ROOT / "systems" / f"{name}.yaml")
        module = compile.build(model, "python", jacobian=True).module
        p = [q.value or 1.0 for q in model.parameters] + ([2.0] if model.constraints else [])
        y = np.random.default_rng(3).uniform(0.2, 1.2, 2 * model.n)

        def f(y: np.ndarray, module: object = module, n: int = model.n, p: list[float] = p) -> np.ndarray:
            return np.array([*y[n:], *module._accel(0.7, y.tolist(), p)[:n]])  # type: ignore[attr-defined]

        numeric = np.column_stack([(f(y + h) - f(y - h)) / 2e-6 for h in np.eye(len(y)) * 1e-6])
        assert np.allclose(module._jac(0.7, y.tolist(), p), numeric, rtol=1e-6, atol=1e-6), name


WALL = """
title: a ball on a spring against a one-sided wall (a penalty |u|)
coordinates: [x, y]
parameters: {k: 100.0, R: 1.3, c: 0.4}
kinetic: (x_dot**2 + y_dot**2)/2
potential: k/2*((sqrt(x**2 + (R - y)**2) - R + Abs(sqrt(x**2 + (R - y)**2) - R))/2)**2 + y
dissipation: c*Abs(x - y)*x_dot**2/2
initial: {x: 1.0, y: 0.1}
"""


def test_the_jacobian_of_a_force_with_abs_is_its_derivative(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A potential or dissipation with |u| of an expression: the Jacobian differentiates sign(u) (0 where u != 0), which
    symengine writes as a Subs; it builds and equals a central finite difference of the rhs (audit 6 F4: exit 2, "cannot
    convert Subs to symengine", for every implicit method)."""
    monkeypatch.setenv("LAGRANGE_CACHE_DIR", str(tmp_path))
    model = model_of(WALL, "wall.yaml")
    module = compile.build(model, "python", jacobian=True).module
    p = [q.value for q in model.parameters]
    for y in (np.array([1.0, 0.1, 0.3, -0.2]), np.array([0.2, 0.4, -0.5, 0.7])):  # the wall pressed (u > 0), and not (u < 0)

        def f(y: np.ndarray) -> np.ndarray:
            return np.array([*y[2:], *module._accel(0.7, y.tolist(), p)[:2]])

        numeric = np.column_stack([(f(y + h) - f(y - h)) / 2e-6 for h in np.eye(4) * 1e-6])
        assert np.allclose(module._jac(0.7, y.tolist(), p), numeric, rtol=1e-6, atol=1e-6), y


def test_python_solver_refuses_a_singular_matrix(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LAGRANGE_CACHE_DIR", str(tmp_path))
    module = compile.build(model_from(ROOT / "systems" / "double_pendulum.yaml"), "python").module
    with pytest.raises(ZeroDivisionError):
        module._solve([[1.0, 2.0], [2.0, 4.0]], [1.0, 1.0])
    assert module._solve([[0.0, 2.0], [3.0, 1.0]], [2.0, 4.0]) == pytest.approx([1.0, 1.0])


SCRIPT = """
import json, sys
from lagrange_cli import derive, spec
from lagrange_cli.numeric import simulate
model = derive.derive(spec.load(sys.argv[1]))
trajectory = simulate(model, method=sys.argv[2], backend=sys.argv[3], t_end=1.0)
print(json.dumps({"numba": "numba" in sys.modules, "scipy": "scipy.integrate" in sys.modules, "status": trajectory.status,
                  "generate": trajectory.timing.generate, "nfev": trajectory.stats.nfev}))
"""


def run_script(tmp_path: Path, *args: str) -> dict[str, object]:
    env = {"LAGRANGE_CACHE_DIR": str(tmp_path), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    result = subprocess.run([sys.executable, "-c", SCRIPT, str(ROOT / "systems" / "simple_pendulum.yaml"), *args], capture_output=True, text=True, env=env, cwd=ROOT, timeout=DEADLOCK)
    assert result.returncode == 0, result.stderr
    return dict(json.loads(result.stdout))


def test_the_cache_serves_a_second_process_and_scipy_runs_load_no_numba(tmp_path: Path) -> None:
    first = run_script(tmp_path, "DOP853", "compiled")
    second = run_script(tmp_path, "DOP853", "compiled")
    assert first["numba"] and not first["scipy"] and first["generate"] > 0 and second["generate"] == 0
    assert first["nfev"] == second["nfev"]
    assert any(tmp_path.glob("__pycache__/lagrange_numba_*.nbi")) and any(tmp_path.glob("__pycache__/lagrange_kernels_*.nbi"))
    python = run_script(tmp_path, "RK45", "python")
    assert not python["numba"] and python["scipy"] and python["status"] == "finished"


def test_a_paused_symplectic_run_takes_the_steps_of_a_straight_one(monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled loops pause for progress at times that depend on the clock: a resumed Gauss loop
    must carry its predictor and Newton matrix over, so that where it paused changes nothing."""
    from lagrange_cli.numeric import integrators, simulate

    model = model_from(ROOT / "systems" / "kepler.yaml")
    straight = simulate(model, method="symplectic", t_end=5.0)

    def chunked(advance: object, now: object, taken: object, problem: integrators.Problem, progress: object) -> int:
        code = -1
        for k in range(1, 51):  # 50 pauses, as a slow machine's progress reports would make
            code = advance(problem.t0 + (problem.t_end - problem.t0) * k / 50)  # type: ignore[operator]
            if code != -1:
                return code
        return code

    monkeypatch.setattr(integrators, "_drive", chunked)
    paused = simulate(model, method="symplectic", t_end=5.0)
    assert paused.stats == straight.stats and np.array_equal(paused.y, straight.y), (paused.stats, straight.stats)
