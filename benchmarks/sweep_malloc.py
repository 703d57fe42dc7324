"""CPU per lane evaluation of the sweep's compiled lane loop in a fresh process, with and without the environment a
Dask nanny gives its worker processes (`MALLOC_TRIM_THRESHOLD_=65536`, Dask's `distributed.nanny.pre-spawn-environ`),
pairs of processes interleaved (issue 18: a LocalCluster worker ran the same calls for 13-14% less CPU per evaluation
than `--workers 2`'s threads):

    PYTHONPATH=. .venv/bin/python benchmarks/sweep_malloc.py 6    # pairs

Each process: benchmarks/sweep_bench.py's 10^4 double-pendulum runs, 4 calls of 2500 runs, 6 times; the median of
the CPU seconds inside the calls (time.thread_time) over the lane evaluations they count.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def measure() -> float:
    import numpy as np

    sys.path.insert(0, str(HERE))
    sys.path.insert(0, str(HERE.parent))
    import pendulum

    from lagrange_cli import derive, spec
    from lagrange_cli import sweep as library
    from lagrange_cli.numeric.lanes import LANES

    text = pendulum.system_yaml(2)
    model = derive.derive(spec.parse(text, "chain_2.yaml"))
    q1, q2 = model.coordinates
    axes = (library.Axis("initial", q1, -1.5, 1.5), library.Axis("initial", q2, -1.5, 1.5))
    options = (("atol", 1e-12), ("backend", "compiled"), ("method", "DOP853"), ("rtol", 1e-9), ("t_end", 10.0))
    runner = library.runner_for(library.Job(text, "chain_2.yaml", axes, ("final",), None, options), model)
    grid = library.points(list(axes), 10_000, 0)
    ts, control = np.array(runner.settings.t_eval, dtype=float), runner._control(0.0, 10.0)
    per: list[float] = []
    for _ in range(6):
        cpu = evaluations = 0.0
        for k in range(0, 10_000, 2500):
            y0s, ps = runner.points(grid[k : k + 2500])
            began = time.thread_time()
            out = runner.lanes_entry(runner.pair, y0s, ps, control, ts, runner.budget, LANES, runner.accel, runner.lanes_accel)
            cpu += time.thread_time() - began
            evaluations += int(out[5])
        per.append(cpu / evaluations * 1e9)
    return float(np.median(per))


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--one":
        print(f"{measure():.3f}")
        return
    pairs = int(sys.argv[1]) if len(sys.argv) > 1 else 6
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average {', '.join(f'{x:.1f}' for x in os.getloadavg())}; ns per lane evaluation (median of 6 sweeps a process)")
    plain, trimmed = [], []
    for k in range(pairs):
        for env, into in ((None, plain), ("65536", trimmed)) if k % 2 == 0 else (("65536", trimmed), (None, plain)):
            environ = {key: value for key, value in os.environ.items() if key != "MALLOC_TRIM_THRESHOLD_"}
            if env is not None:
                environ["MALLOC_TRIM_THRESHOLD_"] = env
            into.append(float(subprocess.run([sys.executable, __file__, "--one"], env=environ, capture_output=True, text=True, check=True).stdout.split()[-1]))
        print(f"  pair {k + 1}: default malloc {plain[-1]:.2f}, MALLOC_TRIM_THRESHOLD_=65536 {trimmed[-1]:.2f}; load {os.getloadavg()[0]:.1f}", flush=True)
    import numpy as np

    ratio = [t / p for t, p in zip(trimmed, plain, strict=True)]
    print(f"medians: default {np.median(plain):.2f} ns, trim threshold set {np.median(trimmed):.2f} ns; ratio median {np.median(ratio):.3f} (pairs {', '.join(f'{r:.2f}' for r in ratio)})")


if __name__ == "__main__":
    main()
