"""Issue 15, audit 9 on unseen systems (tests/numeric_audit9/): each file loads and derives, and
`simulate --method auto` agrees with an independent reference on a short run; counted, never timed.

The references are benchmarks/numeric_audit9.py's, each its own formulation (nothing of lagrange_cli is
imported there): the pendulum whose length a kept time-dependent constraint pumps, in its angle alone; the
e = 0.99 Kepler orbit exactly (Kepler's equation); the hanging chain of soft and stiff springs exactly (the
linear flow's eigen-decomposition); the double pendulum with Abs() drag by a derivation of its own; the
absorber under a chirp from equations written by hand; the fast top by Euler's equations with the rotation
matrix; the FPU chain by forces written by hand; the rolling disk by Chaplygin's reduced equations. The full audit (stress, accuracy, their recommendations
re-run, CPU seconds) is that script; its findings are in BENCHMARKS.md."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from lagrange_cli import api

from .helpers import benchmark_module

HERE = Path(__file__).parent

A9 = benchmark_module("numeric_audit9")
A3 = benchmark_module("numeric_audit3")
SYSTEMS = A9.systems()

# (system, t_end, the reference's method): short spans that keep each file's difficulty: two pumping periods
# of the kept l(t) constraint; the first pass through periapsis (r = 0.008, phi_dot = 3117) and back out;
# 100 periods of the undamped 9.6e3 rad/s spring; the tumble through the drag's kinks; the chirp through
# both resonances' lower edge; 5 nutations (36 spin turns) of the top; two periods of the FPU chain's lowest mode;
# five rolling turns of the disk (its heading through 7 rad) with both velocity constraints kept.
CASES = [
    ("pumped_pendulum", 3.0, "DOP853"),
    ("kepler099", 0.5, "exact"),
    ("soft_hard_chain", 0.06, "exact"),
    ("drag_pendulum", 3.0, "DOP853"),
    ("chirp", 3.0, "DOP853"),
    ("fast_top", 0.15, "DOP853"),
    ("fpu", 30.0, "DOP853"),
    ("rolling_disk", 2.0, "DOP853"),
]


def test_audit_files_load() -> None:
    files = sorted((HERE / "numeric_audit9").glob("*.yaml"))
    assert [f.name for f in files] == sorted(s.file for s in SYSTEMS.values())
    for path in files:
        assert api.load(path).model.n >= 1


def test_top_reference_angular_velocity_is_the_axial_vector_of_r_transpose_r_dot() -> None:
    """The reference's hand-written R = R_z(psi) R_x(theta) R_z(phi) and body angular velocity are sympy's
    (the axial vector of R^T dR/dt) at random states, so the reference starts where the file does."""
    ts = sp.Symbol("ts")
    f = [sp.Function(f"f{i}")(ts) for i in range(3)]

    def rz(x: sp.Expr) -> sp.Matrix:
        return sp.Matrix([[sp.cos(x), -sp.sin(x), 0], [sp.sin(x), sp.cos(x), 0], [0, 0, 1]])

    rx = sp.Matrix([[1, 0, 0], [0, sp.cos(f[1]), -sp.sin(f[1])], [0, sp.sin(f[1]), sp.cos(f[1])]])
    R = rz(f[0]) * rx * rz(f[2])
    W = R.T * R.diff(ts)
    om = sp.Matrix([W[2, 1], W[0, 2], W[1, 0]])
    rng = np.random.default_rng(9)
    for _ in range(3):
        ang, rt = rng.uniform(0.2, 2.5, 3), rng.normal(size=3)
        at = {**{sp.Derivative(fi, ts): float(r) for fi, r in zip(f, rt, strict=True)}}
        values = {fi: float(x) for fi, x in zip(f, ang, strict=True)}
        want = np.array(om.subs(at).subs(values), dtype=float).ravel()
        assert np.allclose(A9._top_omega(*ang, rt), want, rtol=0, atol=1e-12)
        assert np.allclose(A9._zxz(*ang), np.array(R.subs(values), dtype=float), rtol=0, atol=1e-14)


@pytest.mark.parametrize(("name", "t_end", "method"), CASES)
def test_auto_meets_1e_6_against_the_independent_reference(name: str, t_end: float, method: str) -> None:
    """`simulate --method auto --rtol 1e-9 --atol 1e-12` on a short run: its largest error over 201 samples
    (lagrange's scaling) is within 1e-6 of the reference, and the run is not reported failed."""
    s = SYSTEMS[name]
    run = api.load(HERE / "numeric_audit9" / s.file).simulate(t_end=t_end, method="auto", rtol=1e-9, atol=1e-12, samples=201).run
    assert not run.failed, run.message
    ref = s.run(list(s.y0), np.linspace(0.0, t_end, 201), method)
    error = A3._error(np.asarray(run.y), ref, s.wrap)
    assert math.isfinite(error)
    assert error <= 1e-6
