"""Issue 15 (helper radproj): compiled Radau projected onto kept constraints with the analytic Jacobian (its own
compiled module) against forward differences (the explicit pairs' module): steps, evaluations, Jacobians, rejections,
the largest sample error against projected DOP853 at rtol 1e-13, and CPU of each run (the first analytic run includes
its module's compilation).  PYTHONPATH=. python benchmarks/radproj_jacobian.py"""

import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, ".")
from lagrange_cli.numeric import compile, integrators, policy, projection
from tests.helpers import model_from

for f, t_end in (("tests/numeric_audit4/trammel_kept_rod.yaml", None), ("systems/rolling_disk_3d.yaml", None), ("systems/pendulum_multiplier.yaml", 100.0)):
    m = model_from(Path(f))
    opts = dict(method="Radau", backend="compiled", samples=2001)
    if t_end:
        opts["t_end"] = t_end
    s = policy.resolve(m, **opts)
    problem = integrators.Problem(s.t0, s.t_end, np.array(s.y0, dtype=float), np.array(s.t_eval), np.array(s.p, dtype=float), False, 10**7)
    from lagrange_cli.numeric.simulate import _bounds

    bounds = np.array(_bounds(problem))
    ref = integrators.run_erk_projected(compile.build(m, "numba"), problem, "DOP853", 1e-13, 1e-16, math.inf, bounds, projection.holonomic_rows(m), projection.record(None))
    for rtol in (1e-5, 1e-7):
        for jac in (True, False):
            numba = compile.build(m, "numba", jacobian=jac)
            c = time.process_time()
            run = integrators.run_radau_projected(numba, problem, rtol, rtol * 1e-3, math.inf, bounds, projection.holonomic_rows(m), projection.record(None))
            cpu = time.process_time() - c
            err = float(np.max(np.abs(run.y - ref.y)))
            print(f, rtol, "analytic" if jac else "differences", run.status, run.stats.steps, run.stats.nfev, run.stats.njev, run.stats.rejected, f"err {err:.2g}", f"{cpu * 1e3:.1f} ms", flush=True)
