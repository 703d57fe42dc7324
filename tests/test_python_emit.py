"""Emitted Python: imported and run against an independent evaluation of the same equations."""

from __future__ import annotations

import inspect
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from lagrange_cli._symengine import to_symengine
from lagrange_cli.algebra import augmented
from lagrange_cli.emit import python
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

from .conftest import ROOT, SYSTEMS
from .helpers import load_module, model_from, model_of, random_point


def reference_accelerations(model: Model, point: dict[sp.Symbol, float]) -> np.ndarray:
    """Solve [[M, -A^T], [A, 0]] [q_ddot; lambda] = [F; -c] numerically from the sympy model."""
    matrix, rhs = augmented(model)
    a = np.array(matrix.xreplace(point).evalf(20).tolist(), dtype=float)
    b = np.array(rhs.xreplace(point).evalf(20), dtype=float).ravel()
    return np.linalg.solve(a, b)[: model.n]


def emittable(path: Path) -> bool:
    try:
        python.emit(model_from(path))
    except DerivationError:
        return False
    return True


@pytest.mark.parametrize("path", SYSTEMS, ids=lambda p: p.stem)
def test_rhs_agrees_with_independent_evaluation(path: Path, tmp_path: Path) -> None:
    model = model_from(path).with_definitions()  # functions the file defines, written out as the module has them
    try:
        code = python.emit(model)
    except DerivationError as error:
        assert "undefined" in str(error) or "left undefined" in str(error)
        return
    module = load_module(code, tmp_path / f"{path.stem}_eom.py")
    assert model.coordinates == module.COORDINATES
    for seed in range(3):
        point = random_point(model, seed)
        parameters = {p.name: point[p.symbol] for p in model.parameters}
        y = [point[s] for s in (*model.q, *model.qd)]
        t = point[model.t]
        derivative = module.rhs(t, y, parameters)
        assert np.allclose(derivative[: model.n], y[model.n :])
        assert np.allclose(derivative[model.n :], reference_accelerations(model, point), rtol=1e-9, atol=1e-12)
        q, qd = y[: model.n], y[model.n :]
        args = (t,) if not model.autonomous else ()
        mass = module.mass_matrix(*(args if model.mass_matrix.has(model.t) else ()), q, parameters)
        assert np.allclose(mass, np.array(model.mass_matrix.xreplace(point).evalf(), dtype=float))
        energy_args = (t,) if model.energy.has(model.t) else ()
        assert np.isclose(module.energy(*energy_args, q, qd, parameters), float(model.energy.xreplace(point)))


@pytest.mark.skipif(shutil.which("ruff") is None and not (Path(sys.executable).parent / "ruff").exists(), reason="ruff not installed")
def test_emitted_code_passes_ruff(tmp_path: Path) -> None:
    ruff = shutil.which("ruff") or str(Path(sys.executable).parent / "ruff")
    for path in SYSTEMS:
        if emittable(path):
            (tmp_path / f"{path.stem}_eom.py").write_text(python.emit(model_from(path)))
    result = subprocess.run([ruff, "check", "--isolated", "--select", "E,F,W", "--line-length", "1000", str(tmp_path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout


PENDULUM = """
coordinates: [theta]
parameters: {m: 1.0, l: 2.0, g: 9.81}
gravity: [0, -g]
particles:
  bob: {mass: m, position: [l*sin(theta), -l*cos(theta)]}
"""


def test_autonomous_code_has_no_time_argument_and_only_math_imports(tmp_path: Path) -> None:
    code = python.emit(model_of(PENDULUM))
    module = load_module(code, tmp_path / "pendulum.py")
    assert list(inspect.signature(module.mass_matrix).parameters) == ["q", "p"]
    assert list(inspect.signature(module.forcing).parameters) == ["q", "q_dot", "p"]
    assert list(inspect.signature(module.rhs).parameters) == ["t", "y", "p"]
    assert "numpy" not in code and "_solve" not in code and "constraint" not in code
    assert "from math import cos, sin" in code
    assert module.rhs(0.0, [0.3, 0.0], module.PARAMETERS)[1] == pytest.approx(-9.81 / 2.0 * np.sin(0.3))


def test_time_dependent_system_takes_time(tmp_path: Path) -> None:
    code = python.emit(model_of(PENDULUM.replace("l*sin(theta)", "l*sin(theta) + sin(3*t)")))
    module = load_module(code, tmp_path / "driven.py")
    assert list(inspect.signature(module.forcing).parameters) == ["t", "q", "q_dot", "p"]
    assert list(inspect.signature(module.mass_matrix).parameters) == ["q", "p"]


def test_names_that_would_clash_are_renamed(tmp_path: Path) -> None:
    text = "coordinates: [y, p]\nparameters: {q: 2.0, rhs: 3.0}\nkinetic: q*y_dot**2/2 + rhs*p_dot**2/2\npotential: y**2 + p**2\n"
    module = load_module(python.emit(model_of(text)), tmp_path / "clash.py")
    assert module.rhs(0.0, [1.0, 1.0, 0.0, 0.0], {"q": 2.0, "rhs": 3.0})[2:] == pytest.approx([-1.0, -2.0 / 3.0])


def test_large_systems_solve_with_numpy(tmp_path: Path) -> None:
    n = 10
    coordinates = ", ".join(f"x{i}" for i in range(n))
    kinetic = " + ".join(f"x{i}_dot**2/2" for i in range(n)) + " + x0_dot*x1_dot/4"
    potential = " + ".join(f"(x{i} - x{i + 1})**2/2" for i in range(n - 1)) + " + x0**2/2"
    code = python.emit(model_of(f"coordinates: [{coordinates}]\nkinetic: {kinetic}\npotential: {potential}\n"))
    assert "import numpy" in code
    module = load_module(code, tmp_path / "chain.py")
    assert len(module.rhs(0.0, [0.1] * n + [0.0] * n)) == 2 * n


def test_numba_module_agrees_with_the_plain_one(tmp_path: Path) -> None:
    pytest.importorskip("numba")
    for name in ("double_pendulum", "rolling_disk_pendulum_multiplier", "chain_3"):
        model = model_from(ROOT / "systems" / f"{name}.yaml")
        plain = load_module(python.emit(model), tmp_path / f"{name}_plain.py")
        compiled = load_module(python.emit(model, numba=True), tmp_path / f"{name}_numba.py")
        for seed in range(2):
            point = random_point(model, seed)
            parameters = {p.name: point[p.symbol] for p in model.parameters}
            y = [point[s] for s in (*model.q, *model.qd)]
            assert np.allclose(compiled.rhs(0.0, np.array(y), parameters), plain.rhs(0.0, y, parameters), rtol=1e-12, atol=1e-12)


def test_constrained_module_returns_the_multipliers(tmp_path: Path) -> None:
    """A pendulum at rest, hanging: the rod tension is m g, and lambda_rod = -T/(2 l)."""
    model = model_from(ROOT / "systems" / "pendulum_multiplier.yaml")
    module = load_module(python.emit(model), tmp_path / "pm.py")
    p = dict(module.PARAMETERS)
    length = p["l"]
    (value,) = module.multipliers(0.0, [0.0, -length, 0.0, 0.0], p)
    assert value == pytest.approx(-p["m"] * p["g"] / (2 * length))


@pytest.mark.parametrize(
    "text",
    ["k/r**2", "-k*x/r**2", "k/sin(q)**2", "k/(r**2*s)", "1/r**2", "k*r**2/s**2", "(a + b)/r**2", "k/r**2 + a/s**2", "a/(b*r**2)", "a**2/r**3"],
)
def test_printed_squares_keep_their_division(text: str, tmp_path: Path) -> None:
    """A square printed as a product (`r*r`) under a division keeps its parentheses."""
    names = ["k", "r", "x", "q", "s", "a", "b"]
    symbols = sp.symbols(names)
    expr = sp.sympify(text, locals=dict(zip(names, symbols, strict=True)))
    printer = python.PythonPrinter({str(s): str(s) for s in symbols})
    code = printer.doprint(to_symengine(expr))
    module = load_module(f"from math import sin\n\n\ndef f({', '.join(names)}):\n    return {code}\n", tmp_path / "printed.py")
    values = (1.3, 0.7, 2.1, 0.4, 1.9, -0.6, 1.7)
    expected = float(expr.subs(dict(zip(symbols, values, strict=True))))
    assert module.f(*values) == pytest.approx(expected, rel=1e-12), code
