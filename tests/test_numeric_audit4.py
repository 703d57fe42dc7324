"""Issue 15, audit 4 on unseen systems (tests/numeric_audit4/): `simulate --method auto` against
independent references on short runs; counted, never timed.

The references are benchmarks/numeric_audit4.py's: each system's equations derived there by plain
sympy from a Lagrangian written by hand (often in other coordinates than the file's: the elastic
pendulum in Cartesian X, Y, the spherical pendulum in X, Y, Z with its rod as a multiplier, the
trammel in its one angle, the stiff spring in its extension), integrated here by scipy at rtol
1e-12, or Kepler's exact solution; nothing of lagrange_cli is imported there. The full audit
(stress, accuracy, their recommendations re-run, CPU seconds) is that script."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lagrange_cli import api

from .helpers import audit_reference, benchmark_module

HERE = Path(__file__).parent
AUDIT = HERE / "numeric_audit4"


A = benchmark_module("numeric_audit4")
SYSTEMS = A.systems()

# (system, t_end, the reference's scipy method): short spans that still hold each file's
# difficulty: the elastic swing, a passage of the spherical pendulum within 4e-4 rad of its pole
# (t ~ 1.6), one Kepler period (e = 0.8: periapsis at 0 and 4.38), the cart's 1e5/s damper (Radau:
# explicit steps are stability-limited there), the trammel through y = 0, the bead through the
# bottom, two chaotic Duffing hops, 0.05 s of the k = 5e7 spring (~100 oscillations, lightly damped:
# DOP853 resolves them cheaper than Radau at 1e-12).
CASES = [
    ("elastic", 3.0, "DOP853"),
    ("spherical_pole", 2.5, "DOP853"),
    ("kepler_e08", 4.5, "exact"),
    ("cart_damper", 0.3, "Radau"),
    ("trammel", 3.0, "DOP853"),
    ("bead_parabola", 5.0, "DOP853"),
    ("duffing_chaos", 10.0, "DOP853"),
    ("stiff_double", 0.05, "DOP853"),
]


def test_audit_files_load() -> None:
    files = sorted(AUDIT.glob("*.yaml"))
    assert [f.name for f in files] == sorted(s.file for s in SYSTEMS.values())
    for path in files:
        assert api.load(path).model.n >= 1


def _reference(name: str, t_end: float, samples: int, method: str) -> np.ndarray:
    return audit_reference(SYSTEMS[name], A._rhs, t_end, samples, method)  # type: ignore[no-any-return]


@pytest.mark.parametrize(("name", "t_end", "method"), CASES)
def test_auto_meets_1e_6_against_the_independent_reference(name: str, t_end: float, method: str) -> None:
    """`simulate --method auto --rtol 1e-8 --atol 1e-11` on a short run: its largest error over 201
    samples (lagrange's scaling, angles modulo 2 pi where the reference wraps them) is within 1e-6
    of the reference, and the run is not reported failed."""
    s = SYSTEMS[name]
    run = api.load(AUDIT / s.file).simulate(t_end=t_end, method="auto", rtol=1e-8, atol=1e-11, samples=201).run
    assert not run.failed, run.message
    ref = _reference(name, t_end, 201, method)
    assert A._error(np.asarray(run.y), ref, s.wrap) <= 1e-6
