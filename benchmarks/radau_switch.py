"""Compiled Radau landing on switching surfaces (kernels.radau_switched) against stepping over them
(switching.LOCATE off: kernels.radau_run) and against scipy's Radau and compiled DOP853, which locate
them too: the bouncing mass (exact solution) and audit 6's ball in the cup (the audit's reference,
LSODA rtol 1e-12 on its own Max equations). CPU time (time.process_time), best of `repeats`, not located
and located interleaved; atol = rtol / 1000.

Run: PYTHONPATH=$PWD python benchmarks/radau_switch.py [repeats]
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import nonsmooth as NS  # noqa: E402
import numeric_audit3 as A3  # noqa: E402
import numeric_audit6 as A6  # noqa: E402

CONTESTANTS = (("Radau", "compiled", (1e-6, 1e-8, 1e-10)), ("Radau", "python", (1e-8,)), ("DOP853", "compiled", (1e-8,)))


def main(repeats: int) -> None:
    from lagrange_cli import api
    from lagrange_cli.numeric import switching
    from tests.helpers import audit_reference

    ts = np.linspace(0.0, 3.0, 301)
    cases = [
        ("bouncing mass, t 3", api.load(NS.BOUNCE), 3.0, 301, NS.bouncing_exact(ts)),
        ("ball, t 0.4", api.load(NS.BALL), 0.4, 201, audit_reference(A6.systems()["ball_cup"], A3._rhs, 0.4, 201, "LSODA")),
    ]
    for name, system, t_end, samples, ref in cases:
        print(f"{name}: error (max over samples, audit-3 scaling) / steps / crossings / CPU ms, not located -> located")
        for method, backend, rtols in CONTESTANTS:
            for rtol in rtols:
                result: dict[bool, tuple[float, int, str, float]] = {}
                for _ in range(repeats):
                    for locate in (False, True):
                        switching.LOCATE = locate
                        try:
                            began = time.process_time()
                            run = system.simulate(t_end=t_end, method=method, backend=backend, rtol=rtol, atol=rtol * 1e-3, samples=samples, max_steps=10**6).run
                            cpu = time.process_time() - began
                        finally:
                            switching.LOCATE = True
                        error = A3._error(np.asarray(run.y), ref) if not run.failed else math.inf
                        located = [note.split("located: ")[1].split(" ")[0] for note in run.notes if "located: " in note]
                        if locate not in result or cpu < result[locate][3]:
                            result[locate] = (error, run.stats.steps, located[0] if located else "-", cpu)
                (e0, s0, k0, c0), (e1, s1, k1, c1) = result[False], result[True]
                print(f"  {method} ({backend}) rtol {rtol:g}: {e0:.2e}/{s0}/{k0}/{1e3 * c0:.0f} -> {e1:.2e}/{s1}/{k1}/{1e3 * c1:.0f}", flush=True)


if __name__ == "__main__":
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load {os.getloadavg()}")
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
    print(f"# end {time.strftime('%H:%M UTC', time.gmtime())}, load {os.getloadavg()}")
