"""The Dask path's two idle-time changes (issue 18), interleaved in one process beside one 2-worker LocalCluster:
--workers 2; the LocalCluster with guided task sizes and the kept client (this branch); with 5e9fb1b's equal task
sizes (about 4 tasks a worker) and the kept client; with guided sizes and a fresh client each sweep (closed before).

    PYTHONPATH=. .venv/bin/python benchmarks/sweep_dask_variants.py 7    # rounds
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))
import pendulum  # noqa: E402

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli import sweep as library  # noqa: E402


def equal_groups(batches: list[list[int]], workers: int) -> list[list[list[int]]]:
    """5e9fb1b's grouping: equal tasks, about 4 a worker."""
    per = max(1, min(64, len(batches) // (4 * max(1, workers))))
    return [batches[i : i + per] for i in range(0, len(batches), per)]


def main() -> None:
    from distributed import LocalCluster

    text = pendulum.system_yaml(2)
    model = derive.derive(spec.parse(text, "chain_2.yaml"))
    q1, q2 = model.coordinates
    axes = [library.Axis("initial", q1, -1.5, 1.5), library.Axis("initial", q2, -1.5, 1.5)]
    options = {"text": text, "sample": 10000, "seed": 0, "measures": ["final"], "t_end": 10.0, "rtol": 1e-9, "atol": 1e-12, "method": "DOP853", "backend": "compiled", "batch": 250}
    guided = library._task_groups
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        addr = cluster.scheduler_address
        library.sweep(model, axes, scheduler=addr, **{**options, "sample": 8})
        res = {"2w": [], "guided+kept": [], "equal+kept": [], "guided+fresh": []}
        for _ in range(int(sys.argv[1]) if len(sys.argv) > 1 else 5):
            for name in res:
                library._task_groups = equal_groups if name.startswith("equal") else guided
                if name.endswith("fresh"):
                    library.close_clients()
                t = time.perf_counter()
                library.sweep(model, axes, **({"workers": 2} if name == "2w" else {"scheduler": addr}), **options)
                res[name].append(time.perf_counter() - t)
            print("  ".join(f"{k} {v[-1]:.3f}" for k, v in res.items()), f"load {os.getloadavg()[0]:.2f}", flush=True)
        print("medians:", "  ".join(f"{k} {np.median(v):.3f}" for k, v in res.items()))
        print("median ratios to 2w:", "  ".join(f"{k} {np.median(np.array(v) / np.array(res['2w'])):.2f}" for k, v in res.items()))
        library.close_clients()


if __name__ == "__main__":
    main()
