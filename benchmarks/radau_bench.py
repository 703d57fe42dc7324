"""Compiled Radau IIA (kernels.radau_run) against scipy's Radau (the python backend) on three stiff systems.

For each system and rtol: the steps, the CPU time of the integration (time.process_time: the machine is
shared), the cost per step, and the largest error over the samples against a tight reference (compiled
DOP853 at rtol 1e-13), in units of the tolerance. The two contestants run interleaved, REPEATS times each,
in one process (scipy with the python backend's step budget, 20000 steps); the best CPU time of each is kept. Compilation is done before timing (a warm cache).

    PYTHONPATH=. python benchmarks/radau_bench.py
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli.numeric import compile, integrators, policy  # noqa: E402

SYSTEMS = [
    ("stiff elastic pendulum (k = 1e10)", ROOT / "tests" / "numeric_audit" / "stiff_elastic_pendulum_r.yaml", 10.0),
    ("Van der Pol mu = 1000, coupled", ROOT / "tests" / "numeric_audit5" / "van_der_pol_mu1000_coupled.yaml", 2000.0),
    ("angle-damped spring pendulum from r = 0.011", ROOT / "tests" / "numeric_audit6" / "spring_pendulum_angle_damper.yaml", 1.0),
]
RTOLS = (1e-6, 1e-8, 1e-10)
REPEATS = 2


def main() -> None:
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load {os.getloadavg()}")
    print("| system | rtol | compiled steps | scipy steps | compiled CPU s | scipy CPU s | scipy / compiled | us/step compiled | us/step scipy | error compiled | error scipy |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, path, t_end in SYSTEMS:
        model = derive.derive(spec.load(path))
        initial = {"r": 0.011} if "angle" in name else None
        settings = policy.validate(model, method="DOP853", backend="compiled", t_end=t_end, samples=101, initial=initial)
        problem = integrators.Problem(0.0, settings.t_end, np.array(settings.y0), np.array(settings.t_eval), np.array(settings.p), False, 10**6)
        numba, python = compile.build(model, "numba"), compile.build(model, "python", jacobian=True)
        scipy_problem = integrators.Problem(problem.t0, problem.t_end, problem.y0, problem.ts, problem.p, False, integrators.MAX_STEPS["python"])
        long = integrators.Problem(problem.t0, problem.t_end, problem.y0, problem.ts, problem.p, False, 10**7)
        reference = integrators.run_erk(numba, long, "DOP853", 1e-13, settings.atol * 1e-3, math.inf)
        for rtol in RTOLS:
            best = {"compiled": math.inf, "scipy": math.inf}
            runs = {}
            for _ in range(REPEATS):
                for who in ("compiled", "scipy"):
                    began = time.process_time()
                    run = integrators.run_radau(numba, problem, rtol, settings.atol) if who == "compiled" else integrators.run_scipy(python, scipy_problem, "Radau", rtol, settings.atol, math.inf)
                    best[who] = min(best[who], time.process_time() - began)
                    runs[who] = run
            errors = {}
            for who, run in runs.items():
                m = min(len(run.y), len(reference.y))
                scale = settings.atol + rtol * np.abs(reference.y[:m])
                errors[who] = float(np.max(np.abs(run.y[:m] - reference.y[:m]) / scale)) if m else math.nan
                if run.status != "finished":
                    errors[who] = math.nan
            c, s = runs["compiled"], runs["scipy"]
            print(
                f"| {name} | {rtol:g} | {c.stats.steps} ({c.status}) | {s.stats.steps} ({s.status}) | {best['compiled']:.4f} | {best['scipy']:.3f} | "
                f"{best['scipy'] / max(best['compiled'], 1e-9):.0f} | {1e6 * best['compiled'] / max(c.stats.steps, 1):.1f} | {1e6 * best['scipy'] / max(s.stats.steps, 1):.0f} | "
                f"{errors['compiled']:.3g} | {errors['scipy']:.3g} |",
                flush=True,
            )
    print(f"# reference: compiled DOP853 rtol 1e-13 (status {reference.status}); load {os.getloadavg()}")


if __name__ == "__main__":
    main()
