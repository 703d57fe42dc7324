"""The cluster sweep's CPU by process and thread (issue 18), this branch's Dask tasks against the tasks before it
(a29faf6: a compiled call and an `Ended` per batch), each with Dask's statistical profiler on and stopped, interleaved
round by round through one 2-worker LocalCluster:

    PYTHONPATH=. .venv/bin/python benchmarks/sweep_cluster_cpu.py 15    # rounds

CPU per 10^4-run sweep (benchmarks/sweep_bench.py's): this process (client, scheduler and the LocalCluster's nannies,
which are objects of this process), the workers' task threads (each worker's busiest thread) and their other threads
(Dask's event loop). Stopping the profiler (`client.run`) is for attribution only: users keep Dask's defaults.
Every sweep's rows are checked against the local run's.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import pendulum  # noqa: E402

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli import sweep as library  # noqa: E402

AFTER = library._dask


def task_before(job: Any, group: list[tuple[np.ndarray, np.ndarray]]) -> list[Any]:
    """a29faf6's task: a compiled call and an `Ended` per batch of the group."""
    from lagrange_cli import sweep

    runner = sweep.runner_for(job)
    return [runner.ended(indices.tolist(), chunk) for indices, chunk in group]


def dask_before(address: str, job: Any, runner: Any, grid: np.ndarray, batches: list[list[int]]) -> Iterator[tuple[list[list[Any]], int]]:
    """a29faf6's client side of the tasks (a list of (indices, points) per task; rows per batch)."""
    client = library._client(address)
    workers = list(client.scheduler_info()["workers"])
    futures = [(client.submit(task_before, job, [(np.asarray(ix, dtype=np.int64), grid[ix]) for ix in group], pure=False), group) for group in library._task_groups(batches, len(workers))]
    for future, group in futures:
        for result, ix in zip(future.result(), group, strict=True):
            yield (runner.rows(result) if isinstance(result, library.Ended) else result), len(ix)


def profiler(on: bool, dask_worker: Any = None) -> bool:
    callback = dask_worker.periodic_callbacks["profile"]
    (callback.start if on else callback.stop)()
    return True


VARIANTS = {
    "after (this branch)": (AFTER, True),
    "before (a29faf6's tasks)": (dask_before, True),
    "after, Dask profiler off": (AFTER, False),
    "before, Dask profiler off": (dask_before, False),
}


def main() -> None:
    import psutil
    from distributed import Client, LocalCluster

    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    text = pendulum.system_yaml(2)
    model = derive.derive(spec.parse(text, "chain_2.yaml"))
    q1, q2 = model.coordinates
    axes = [library.Axis("initial", q1, -1.5, 1.5), library.Axis("initial", q2, -1.5, 1.5)]
    options = {"text": text, "sample": 10_000, "seed": 0, "measures": ["final"], "t_end": 10.0, "rtol": 1e-9, "atol": 1e-12, "method": "DOP853", "backend": "compiled", "batch": 250}
    reference = library.sweep(model, axes, **options).rows
    me = psutil.Process()
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        library.sweep(model, axes, scheduler=address, **{**options, "sample": 8})
        with Client(address, set_as_default=False) as probe:
            workers = [psutil.Process(pid) for pid in probe.run(os.getpid).values()]
        print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average {os.getloadavg()}; the workers' parent: { ({w.parent().pid for w in workers}) }, this process {me.pid}", flush=True)
        client = library._client(address)
        results: dict[str, list[tuple[float, float, float, float]]] = {name: [] for name in VARIANTS}

        def threads(worker: Any) -> dict[int, float]:
            return {t.id: t.user_time + t.system_time for t in worker.threads()}

        for _ in range(rounds):
            for name, (function, profiled) in VARIANTS.items():
                client.run(profiler, profiled)
                library._dask = function  # type: ignore[assignment]
                before, cpu, began = [threads(w) for w in workers], sum(me.cpu_times()[:2]), time.perf_counter()
                rows = library.sweep(model, axes, scheduler=address, **options).rows
                wall, cpu, after = time.perf_counter() - began, sum(me.cpu_times()[:2]) - cpu, [threads(w) for w in workers]
                assert rows == reference, name
                task = other = 0.0
                for a, b in zip(before, after, strict=True):
                    spent = sorted((b[k] - a.get(k, 0.0) for k in b), reverse=True)
                    task, other = task + spent[0], other + sum(spent[1:])
                results[name].append((wall, cpu, task, other))
                time.sleep(0.2)
        library._dask = AFTER
        client.run(profiler, True)
        library.close_clients()
    print(f"medians of {rounds} rounds, CPU s per 10^4-run sweep: this process | workers' task threads | their other threads | all; wall s")
    for name, values in results.items():
        a = np.array(values)
        m = np.median(a, axis=0)
        print(f"  {name:28s} {m[1]:.3f} | {m[2]:.3f} | {m[3]:.3f} | {np.median(a[:, 1] + a[:, 2] + a[:, 3]):.3f}; wall {m[0]:.3f}")


if __name__ == "__main__":
    main()
