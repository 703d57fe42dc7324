"""Issue 15, audit 5 on unseen systems (tests/numeric_audit5/): `simulate --method auto` against
independent references on short runs; counted, never timed.

The references are benchmarks/numeric_audit5.py's: each system's equations derived there by plain
sympy from a Lagrangian written by hand, in other coordinates where that makes them independent
(the swinging Atwood machine in Cartesian X, Y; the charge in a magnetic field in Cartesian x, y, z;
Henon-Heiles in Cartesian x, y), the tennis racket by Euler's equations with its rotation matrix;
integrated here by scipy at rtol 1e-12. Nothing of lagrange_cli is imported there. The full audit
(stress, accuracy, their recommendations re-run, CPU seconds) is that script."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lagrange_cli import api

from .helpers import audit_reference, benchmark_module

HERE = Path(__file__).parent


A5 = benchmark_module("numeric_audit5")
A3 = benchmark_module("numeric_audit3")
SYSTEMS = A5.systems()

# (system, t_end, the reference's scipy method): short spans that keep each file's difficulty: the
# Atwood machine's first close approach to its pulley (r = 0.04 near t = 2.6, theta_dot 159 rad/s);
# the charge's first gyrations; Henon-Heiles through the origin's neighbourhood; the Van der Pol slow
# branch (stiff: x_dot ~ 1e-3, rate ~ 3000/s); the chain's light mass ringing at 140 rad/s while
# it decays; the sleigh's turning; one flip of the racket (exact: Euler's equations); the
# swing's parametric growth.
CASES = [
    ("atwood", 3.0, "DOP853"),
    ("diamagnetic", 5.0, "DOP853"),
    ("henon_heiles", 10.0, "DOP853"),
    ("vdp", 5.0, "Radau"),
    ("chain", 0.5, "DOP853"),
    ("sleigh", 5.0, "DOP853"),
    ("racket", 10.0, "exact"),
    ("swing", 10.0, "DOP853"),
]


def test_audit_files_load() -> None:
    files = sorted((HERE / "numeric_audit5").glob("*.yaml"))
    assert [f.name for f in files] == sorted(s.file for s in SYSTEMS.values())
    for path in files:
        assert api.load(path).model.n >= 1


def _reference(name: str, t_end: float, samples: int, method: str) -> np.ndarray:
    return audit_reference(SYSTEMS[name], A3._rhs, t_end, samples, method)  # type: ignore[no-any-return]


@pytest.mark.parametrize(("name", "t_end", "method"), CASES)
def test_auto_meets_1e_6_against_the_independent_reference(name: str, t_end: float, method: str) -> None:
    """`simulate --method auto --rtol 1e-8 --atol 1e-11` on a short run: its largest error over 201
    samples (lagrange's scaling, angles modulo 2 pi where the reference wraps them) is within 1e-6
    of the reference, and the run is not reported failed."""
    s = SYSTEMS[name]
    run = api.load(HERE / "numeric_audit5" / s.file).simulate(t_end=t_end, method="auto", rtol=1e-8, atol=1e-11, samples=201).run
    assert not run.failed, run.message
    ref = _reference(name, t_end, 201, method)
    assert A3._error(np.asarray(run.y), ref, s.wrap) <= 1e-6
