"""Issue 15, audit 7 on unseen systems (tests/numeric_audit7/): `simulate --method auto` against
independent references on short runs; counted, never timed.

The references are benchmarks/numeric_audit7.py's: each system's equations derived there by plain
sympy from a Lagrangian written by hand, in other coordinates where that makes them independent
(the rolling wheel with its kept rolling constraint eliminated; the near-upright double pendulum in
angles from the upward vertical; the wall contact with sympy's Max and Heaviside, integrated piece by
piece between located contact switches), integrated here by scipy at rtol 1e-12; the two linear
systems (the charged particle in a strong field, the weakly damped coupled oscillators) are solved
exactly. Nothing of lagrange_cli is imported there. The full audit (stress, accuracy, their
recommendations re-run, CPU seconds) is that script; its findings are in BENCHMARKS.md."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lagrange_cli import api

from .helpers import audit_reference, benchmark_module

HERE = Path(__file__).parent

A7 = benchmark_module("numeric_audit7")
A3 = benchmark_module("numeric_audit3")
SYSTEMS = A7.systems()

# (system, t_end, the reference: scipy's method at rtol 1e-12, or "exact"): short spans that keep each
# file's difficulty: the kicked block's 2e4/s damper transient; the kept rolling constraint under the
# 1e6 spring; 100 gyrations at 100 rad/s; the fall from the upright; the rope reeled in; the stiff
# tire; 300 periods of the weakly damped pair.
CASES = [
    ("vertical_damper", 1.0, "Radau"),
    ("wheel", 0.5, "Radau"),
    ("charged", 6.0, "exact"),
    ("dp_upright", 4.0, "DOP853"),
    ("crane", 10.0, "DOP853"),
    ("half_car", 1.0, "Radau"),
    ("weak_damping_1e5", 1000.0, "exact"),
]


def test_audit_files_load() -> None:
    files = sorted((HERE / "numeric_audit7").glob("*.yaml"))
    assert [f.name for f in files] == sorted(s.file for s in SYSTEMS.values())
    for path in files:
        assert api.load(path).model.n >= 1


def _reference(name: str, t_end: float, samples: int, method: str) -> np.ndarray:
    return audit_reference(SYSTEMS[name], A3._rhs, t_end, samples, method)  # type: ignore[no-any-return]


@pytest.mark.parametrize(("name", "t_end", "method"), CASES)
def test_auto_meets_1e_6_against_the_independent_reference(name: str, t_end: float, method: str) -> None:
    """`simulate --method auto --rtol 1e-8 --atol 1e-11` on a short run: its largest error over 201
    samples (lagrange's scaling) is within 1e-6 of the reference, and the run is not reported failed."""
    s = SYSTEMS[name]
    run = api.load(HERE / "numeric_audit7" / s.file).simulate(t_end=t_end, method="auto", rtol=1e-8, atol=1e-11, samples=201).run
    assert not run.failed, run.message
    ref = _reference(name, t_end, 201, method)
    assert A3._error(np.asarray(run.y), ref, s.wrap) <= 1e-6
