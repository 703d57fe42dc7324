"""Where a parallel sweep's time goes besides its runs (issue 18), measured by CPU time where it can be, so that a
loaded machine reads about the same as a quiet one:

    PYTHONPATH=. .venv/bin/python benchmarks/sweep_overheads.py

The sweep is benchmarks/sweep_bench.py's (10^4 double-pendulum runs to t = 10, rtol 1e-9, batches of 250).
1. Python outside the compiled calls, per sweep, with 1 and 2 workers: the process's CPU time less the CPU time of
   the threads inside the compiled lane loop (time.thread_time around each call); this part holds the GIL.
2. The fixed cost of a sweep through a 2-worker LocalCluster: a sweep of 8 runs, wall and CPU of this process
   (client and scheduler), median of 15.
3. An idle LocalCluster's CPU per second (its scheduler and its nannies in this process, its workers: psutil).
4. During a 10^4-run sweep's tasks through the cluster: the workers' CPU, and the part of it outside the thread running
   the sweep's tasks (Dask's event loop, heartbeats, its statistical profiler, transfers); the tasks as they are
   (`sweep._dask_task`: a task's runs in one compiled call, one `Ended` back) and as they were (a compiled call and an
   `Ended` per batch), interleaved.
5. The same with Dask's statistical profiler stopped on the workers (what it costs; Dask's, not the sweep's: users keep it).
6. The lane loop's work (lane evaluations, idle lanes included: a count, independent of load) of the sweep's runs cut
   as each contestant cuts them: a call per batch (1 worker), --workers 2 (its last batches in pieces), a call per
   Dask task (`_task_groups` with 2 workers), and one call for all.
"""

from __future__ import annotations

import itertools
import os
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import pendulum  # noqa: E402

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli import sweep as library  # noqa: E402


def _task_thread_cpu(job: Any, indices: Any, chunk: Any, sizes: list[int]) -> tuple[Any, float]:
    """sweep._dask_task on a worker, and the CPU time of the thread that ran it."""
    began = time.thread_time()
    result = library._dask_task(indices, chunk, sizes, job)
    return result, time.thread_time() - began


def _per_batch_task_thread_cpu(job: Any, indices: Any, chunk: Any, sizes: list[int]) -> tuple[Any, float]:
    """The task as it was before (a compiled call and an `Ended` per batch), and the CPU time of its thread."""
    began = time.thread_time()
    runner = library.runner_for(job)
    bounds = np.cumsum([0, *sizes]).tolist()
    result = [runner.ended(indices[a:b].tolist(), chunk[a:b]) for a, b in itertools.pairwise(bounds)]
    return result, time.thread_time() - began


def _profiler(on: bool, dask_worker: Any = None) -> bool:
    """Start or stop Dask's statistical profiler on this worker (section 5 only)."""
    callback = dask_worker.periodic_callbacks["profile"]
    (callback.start if on else callback.stop)()
    return True


def main() -> None:
    import psutil
    from distributed import Client, LocalCluster

    text = pendulum.system_yaml(2)
    model = derive.derive(spec.parse(text, "chain_2.yaml"))
    q1, q2 = model.coordinates
    axes = [library.Axis("initial", q1, -1.5, 1.5), library.Axis("initial", q2, -1.5, 1.5)]
    options = {"text": text, "sample": 10_000, "seed": 0, "measures": ["final"], "t_end": 10.0, "rtol": 1e-9, "atol": 1e-12, "method": "DOP853", "backend": "compiled", "batch": 250}
    small = {**options, "sample": 8}
    library.sweep(model, axes, **small)
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; lagrange_cli from {library.__file__}; load average {os.getloadavg()}")

    runner = next(r for r in library._RUNNERS.values() if r.model is model)
    inside = [0.0]
    lock = threading.Lock()
    entry = runner.lanes_entry

    def counted(*arguments: Any) -> Any:
        began = time.thread_time()
        value = entry(*arguments)
        with lock:
            inside[0] += time.thread_time() - began
        return value

    runner.lanes_entry = counted
    for workers in (1, 2) * 3:
        inside[0] = 0.0
        began = time.process_time()
        library.sweep(model, axes, workers=workers, **options)
        total = time.process_time() - began
        print(f"1. workers {workers}: process CPU {total:.3f} s, in the compiled calls {inside[0]:.3f} s, Python outside them {total - inside[0]:.3f} s")
    runner.lanes_entry = entry

    from lagrange_cli.numeric.lanes import LANES

    grid = library.points(axes, 10_000, 0)
    ts, control = np.array(runner.settings.t_eval, dtype=float), runner._control(runner.settings.t0, runner.settings.t_end)
    batches = [list(range(k, k + 250)) for k in range(0, 10_000, 250)]
    cuts = {
        "a call per batch (1 worker before sweeppar)": batches,
        "--workers 2 before sweeppar (the last 2 batches in 2 halves each)": batches[:-2] + [b[h : h + 125] for b in batches[-2:] for h in (0, 125)],
        "a call per group of 1 worker (`_task_groups` with 1)": [[i for b in group for i in b] for group in library._task_groups(batches, 1)],
        "a call per Dask task or --workers 2 group (`_task_groups` with 2)": [[i for b in group for i in b] for group in library._task_groups(batches, 2)],
        "one call for all runs": [list(range(10_000))],
    }
    for name, pieces in cuts.items():
        evaluations = sum(int(runner.lanes_entry(runner.pair, *runner.points(grid[piece]), control, ts, runner.budget, LANES, runner.accel, runner.lanes_accel)[5]) for piece in pieces)
        print(f"6. {name}: {len(pieces)} calls, {evaluations} lane evaluations ({evaluations / 10_000:.1f} a run)")

    close = getattr(library, "close_clients", lambda: None)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        library.sweep(model, axes, scheduler=address, **small)
        walls, cpus = [], []
        for _ in range(15):
            began, cpu = time.perf_counter(), time.process_time()
            library.sweep(model, axes, scheduler=address, **small)
            walls.append(time.perf_counter() - began)
            cpus.append(time.process_time() - cpu)
        print(f"2. a sweep of 8 runs through the cluster: wall median {1e3 * np.median(walls):.1f} ms (min {1e3 * min(walls):.1f}), CPU of this process median {1e3 * np.median(cpus):.1f} ms")

        with Client(address, set_as_default=False) as client:
            workers = [psutil.Process(pid) for pid in client.run(os.getpid).values()]
        # A LocalCluster's nannies are objects of the process that made it (this one), not processes of their own:
        # counting the workers' parent processes would count this process again (once per worker).
        nannies = [psutil.Process(pid) for pid in sorted({worker.parent().pid for worker in workers} - {os.getpid()})]
        print(f"   the workers' nannies run in {'this process' if not nannies else 'processes ' + str([n.pid for n in nannies])}")

        def cpu(processes: list[Any]) -> float:
            return sum(sum(process.cpu_times()[:2]) for process in processes)

        w0, n0, c0, t0 = cpu(workers), cpu(nannies), time.process_time(), time.perf_counter()
        time.sleep(3.0)
        seconds = time.perf_counter() - t0
        print(
            f"3. idle cluster, CPU s per second: workers {(cpu(workers) - w0) / seconds:.3f}, nannies {(cpu(nannies) - n0) / seconds:.3f},"
            f" this process (scheduler) {(time.process_time() - c0) / seconds:.3f}"
        )

        job = library.Job(text, "chain_2.yaml", tuple(axes), ("final",), None, tuple(sorted((k, v) for k, v in options.items() if k not in ("text", "sample", "seed", "measures", "batch"))))
        grid = library.points(axes, 10_000, 0)
        batches = [list(range(k, k + 250)) for k in range(0, 10_000, 250)]
        tasks = [(np.asarray([i for b in group for i in b], dtype=np.int64), [len(b) for b in group]) for group in library._task_groups(batches, 2)]
        kinds = {"4. tasks as they are (one compiled call a task)": _task_thread_cpu, "4. tasks as they were (a call per batch)": _per_batch_task_thread_cpu}
        with Client(address, set_as_default=False) as client:
            for profiled in (True, False):
                client.run(_profiler, profiled)
                for _ in range(3):
                    for name, task in kinds.items():
                        w0 = cpu(workers)
                        futures = [client.submit(task, job, indices, grid[indices], sizes, pure=False) for indices, sizes in tasks]
                        in_tasks = sum(seconds for _, seconds in client.gather(futures))
                        spent = cpu(workers) - w0
                        label = name if profiled else "5. " + name[3:] + ", Dask's profiler stopped"
                        print(f"{label}: workers' CPU {spent:.3f} s, in the tasks' thread {in_tasks:.3f} s, outside it {spent - in_tasks:.3f} s")
            client.run(_profiler, True)
        close()


if __name__ == "__main__":
    main()
