"""Issue 15 (helper radproj): sha256 of t, y and the counters of unprojected compiled Radau runs (the stiff spring, the
double pendulum, the ball in the cup at k = 1e8 (switching), the multiplier pendulum without projection); run on
two trees, the digests must be equal.  PYTHONPATH=. python benchmarks/radproj_same_steps.py"""

import hashlib
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, ".")
from lagrange_cli.numeric import compile, integrators, policy
from tests.helpers import damped_stiff_spring, model_from, model_of


def digest(run):
    h = hashlib.sha256()
    for a in (run.t, run.ys if hasattr(run, "ys") else run.y, run.y_last):
        h.update(np.ascontiguousarray(a, dtype=float).tobytes())
    h.update(repr(run.stats).encode())
    h.update(repr(run.status).encode())
    h.update(repr(run.t_last).encode())
    return h.hexdigest()[:16]


cases = [
    ("spring1e8", model_of(damped_stiff_spring(1e8, 2e4)), 5.0, 1e-6),
    ("double_pendulum", model_from(Path("systems/double_pendulum.yaml")), 10.0, 1e-8),
    ("ball_k1e8", model_from(Path("tests/numeric_audit6/ball_in_cup_penalty_k1e8.yaml")), None, 1e-6),
    ("pendulum_multiplier_unprojected", model_from(Path("systems/pendulum_multiplier.yaml")), 10.0, 1e-8),
]
for name, model, t_end, rtol in cases:
    opts = dict(method="Radau", backend="compiled", rtol=rtol, samples=201)
    if t_end is not None:
        opts["t_end"] = t_end
    s = policy.validate(model, **opts)
    s = policy.decide(model, s) if hasattr(policy, "decide") else s
    numba = compile.build(model, "numba", jacobian=True)
    problem = integrators.Problem(s.t0, s.t_end, np.array(s.y0, dtype=float), np.array(s.t_eval), np.array(s.p, dtype=float), False, 10**6)
    run = integrators.run_radau(numba, problem, rtol, s.atol)
    print(name, run.status, run.stats.steps, run.switching, digest(run))
