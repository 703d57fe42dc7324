"""Small helpers shared by the tests."""

from __future__ import annotations

import importlib.util
import random
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import sympy as sp

from lagrange_cli import derive, spec
from lagrange_cli.model import Model


def damped_stiff_spring(k: float, c: float) -> str:
    """A linear system file (so exactly solvable): x on a spring k damped by c (decay rates about k / c and c), coupled
    by a unit spring to y, which swings at 1 rad/s; t_end 5."""
    return f"""
title: damped stiff spring (linear)
coordinates: [x, y]
parameters: {{k: {k!r}, c: {c!r}, kc: 1.0}}
particles:
  a: {{mass: 1, position: [x]}}
  b: {{mass: 1, position: [y]}}
potential: k*x**2/2 + kc*(x - y)**2/2 + y**2/2
dissipation: c*x_dot**2/2
initial: {{x: 1.0, y: 0.5}}
simulate: {{t_end: 5}}
"""


def model_of(text: str, name: str = "test.yaml") -> Model:
    return derive.derive(spec.parse(text, name))


def model_from(path: Path) -> Model:
    return derive.derive(spec.load(path))


def random_point(model: Model, seed: int) -> dict[sp.Symbol, float]:
    """Parameters and inputs at their defaults (or random positive), coordinates and velocities at random."""
    rng = random.Random(seed)
    point: dict[sp.Symbol, float] = {}
    for p in model.parameters:
        point[p.symbol] = p.value if p.value is not None else rng.uniform(0.5, 2.0)
    for q in model.q:
        point[q] = rng.uniform(0.2, 1.3)
    for v in model.qd:
        point[v] = rng.uniform(-1.0, 1.0)
    point[model.t] = rng.uniform(0.0, 2.0)
    for i in model.inputs:  # at their defaults, as the generated code's INPUTS has them
        point[i.symbol] = float(i.value)
    return point


def load_module(code: str, path: Path) -> ModuleType:
    """Write `code` to `path` and import it as a module."""
    path.write_text(code)
    found = importlib.util.spec_from_file_location(path.stem, path)
    assert found and found.loader
    module = importlib.util.module_from_spec(found)
    found.loader.exec_module(module)
    return module


BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"


def benchmark_module(name: str) -> ModuleType:
    """benchmarks/NAME.py imported once as the module `name` (benchmarks/ on sys.path, for the scripts' imports of each other)."""
    if str(BENCHMARKS) not in sys.path:
        sys.path.insert(0, str(BENCHMARKS))
    if name in sys.modules:
        return sys.modules[name]
    found = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
    assert found is not None and found.loader is not None
    module = importlib.util.module_from_spec(found)
    sys.modules[name] = module
    found.loader.exec_module(module)
    return module


def audit_reference(system: Any, rhs: Any, t_end: float, samples: int, method: str) -> Any:
    """An audit system's independent reference at `samples` times over [0, t_end], in lagrange's coordinates:
    its exact solution (`method` "exact"), or scipy's `method` at rtol 1e-12 on the audit's own equations `rhs(system)`."""
    import numpy as np
    from scipy.integrate import solve_ivp

    ts = np.linspace(0.0, t_end, samples)
    if method == "exact":
        return system.exact(ts)
    done = solve_ivp(rhs(system), (0.0, t_end), system.y0, method=method, rtol=1e-12, atol=1e-14, t_eval=ts)
    assert done.status == 0, done.message
    return system.to_lagrange(done.y.T)


def counting_integrations(monkeypatch: Any) -> list[tuple[str, str, float, int, int, str]]:
    """Every integration made through `runs.integrate` from now on, in order: (method, backend, rtol, budget, steps,
    outcome), a paced run that was stopped with the outcome "paced"."""
    from lagrange_cli.numeric import runs

    made: list[tuple[str, str, float, int, int, str]] = []
    real = runs.integrate

    def counted(model: Any, settings: Any, progress: Any = None, budget: Any = None, *more: Any, **options: Any) -> Any:
        try:
            found = real(model, settings, progress, budget, *more, **options)
        except runs.Unaffordable as over:
            made.append((settings.method, settings.backend, settings.rtol, budget, over.steps, "paced"))
            raise
        made.append((settings.method, settings.backend, settings.rtol, budget, found.stats.steps, str(found.outcome)))
        return found

    monkeypatch.setattr(runs, "integrate", counted)
    return made
