"""Where a LocalCluster sweep's extra time goes (issue 18), by counts and CPU, the Dask path as it is against the path
before helper cluster's changes, interleaved round by round beside one 2-worker LocalCluster (the scheduler and the
nannies live in this process, as in benchmarks/sweep_bench.py):

    PYTHONPATH=. .venv/bin/python benchmarks/sweep_cluster_overhead.py 9    # rounds

Contestants, each round in this order: `--workers 2` and the LocalCluster sweep as they are ("after"), then both as they
were ("before": the heap not frozen during the sweep, a `client.submit` per task, the points sent back with each
task's results). Per sweep of benchmarks/sweep_bench.py's 10^4 runs:
- full garbage collections (generation 2) in this process during the sweep, and their CPU (gc.callbacks, the thread
  that ran them): each holds the GIL, so an in-process scheduler stops handing out tasks;
- messages the scheduler got to add tasks (`update_graph`, counted by a scheduler plugin) and tasks added;
- bytes pickled per run: sent to the workers (the tasks' arguments, the job included) and sent back (the results);
- CPU: this process (client, scheduler, nannies), the workers' task threads and their other threads (psutil);
- wall: the sweep, and when each worker started its first task (the scheduler's task stream), informational.
Every sweep's rows are checked against the one-worker run's.
"""

from __future__ import annotations

import contextlib
import gc
import itertools
import os
import pickle
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

AFTER_DASK, AFTER_FROZEN = library._dask, library._heap_frozen
SENT: list[int] = []  # bytes of each task's arguments, as pickled (this process)
BACK: list[int] = []  # bytes of each task's result


def task_before(job: Any, indices: np.ndarray, chunk: np.ndarray, sizes: list[int]) -> Any:
    """The task before: the whole `Ended` back (indices and points included)."""
    from lagrange_cli import sweep

    return sweep._group_task(sweep.runner_for(job), indices, chunk, sizes)


def dask_before(address: str, job: Any, runner: Any, grid: np.ndarray, batches: list[list[int]]) -> Iterator[tuple[list[list[Any]], int]]:
    """The client side before: a `client.submit` per task (a message to the scheduler each), results used as sent."""
    client = library._client(address)
    workers = list(client.scheduler_info()["workers"])
    futures = []
    for group in library._task_groups(batches, len(workers)):
        indices = np.fromiter(itertools.chain.from_iterable(group), dtype=np.int64, count=sum(map(len, group)))
        arguments = (job, indices, grid[indices], [len(b) for b in group])
        SENT.append(len(pickle.dumps(arguments, protocol=5)))
        futures.append((client.submit(task_before, *arguments, pure=False), group))
    for future, group in futures:
        result = future.result()
        BACK.append(len(pickle.dumps(result, protocol=5)))
        yield from library._group_rows(runner, result, group)


def dask_after(address: str, job: Any, runner: Any, grid: np.ndarray, batches: list[list[int]]) -> Iterator[tuple[list[list[Any]], int]]:
    """The Dask path as it is, with the bytes of its tasks' arguments and results counted on the side."""
    client = library._client(address)
    submit = client.map

    def counted_map(function: Any, indices: list[Any], chunks: list[Any], sizes: list[Any], **keywords: Any) -> Any:
        SENT.extend(len(pickle.dumps((keywords["job"], ix, c, z), protocol=5)) for ix, c, z in zip(indices, chunks, sizes, strict=True))
        futures = submit(function, indices, chunks, sizes, **keywords)
        for future in futures:
            future.add_done_callback(lambda f: BACK.append(len(pickle.dumps(f.result(), protocol=5))))
        return futures

    client.map = counted_map  # type: ignore[method-assign]
    try:
        yield from AFTER_DASK(address, job, runner, grid, batches)
    finally:
        del client.map


def graphs_plugin() -> Any:
    """A scheduler plugin counting `update_graph` calls and the tasks they add."""
    from distributed.diagnostics.plugin import SchedulerPlugin

    class Graphs(SchedulerPlugin):
        name = "lagrange-benchmark-graphs"

        def __init__(self) -> None:
            self.calls = self.tasks = 0

        def update_graph(self, scheduler: Any, *, keys: Any = (), **kwargs: Any) -> None:
            self.calls += 1
            self.tasks += len(keys)

    return Graphs()


FULL: list[float] = []  # CPU s of each full collection in this process


def _collections(phase: str, info: dict[str, Any], began: list[float] = [0.0]) -> None:  # noqa: B006 (the start time, kept between the two calls)
    if info["generation"] == 2:
        if phase == "start":
            began[0] = time.thread_time()
        else:
            FULL.append(time.thread_time() - began[0])


def main() -> None:
    import psutil
    from distributed import LocalCluster, get_task_stream

    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    text = pendulum.system_yaml(2)
    model = derive.derive(spec.parse(text, "chain_2.yaml"))
    q1, q2 = model.coordinates
    axes = [library.Axis("initial", q1, -1.5, 1.5), library.Axis("initial", q2, -1.5, 1.5)]
    options = {"text": text, "sample": 10_000, "seed": 0, "measures": ["final"], "t_end": 10.0, "rtol": 1e-9, "atol": 1e-12, "method": "DOP853", "backend": "compiled", "batch": 250}
    reference = library.sweep(model, axes, **options).rows
    me = psutil.Process()
    gc.callbacks.append(_collections)
    kept: list[Any] = []  # the tables, kept as a user's script keeps them (their rows stay on the heap)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        graphs = graphs_plugin()
        cluster.scheduler.add_plugin(graphs)
        library.sweep(model, axes, scheduler=address, **{**options, "sample": 8})
        client = library._client(address)
        workers = [psutil.Process(pid) for pid in client.run(os.getpid).values()]
        print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average {', '.join(f'{x:.1f}' for x in os.getloadavg())}; {rounds} rounds", flush=True)
        variants = {"--workers 2 (after)": (None, True), "LocalCluster (after)": (dask_after, True), "--workers 2 (before)": (None, False), "LocalCluster (before)": (dask_before, False)}
        results: dict[str, list[dict[str, float]]] = {name: [] for name in variants}

        def threads(worker: Any) -> dict[int, float]:
            return {t.id: t.user_time + t.system_time for t in worker.threads()}

        for r in range(rounds):
            for name, (dask, frozen) in variants.items():
                library._heap_frozen = AFTER_FROZEN if frozen else contextlib.nullcontext  # type: ignore[assignment]
                library._dask = dask or AFTER_DASK  # type: ignore[assignment]
                SENT.clear(), BACK.clear(), FULL.clear()
                calls, tasks = graphs.calls, graphs.tasks
                before, cpu = [threads(w) for w in workers], sum(me.cpu_times()[:2])
                with get_task_stream(client=client) if dask else contextlib.nullcontext() as stream:
                    began = time.time()
                    table = library.sweep(model, axes, **({"scheduler": address} if dask else {"workers": 2}), **options)
                    wall = time.time() - began
                cpu, after = sum(me.cpu_times()[:2]) - cpu, [threads(w) for w in workers]
                assert table.rows == reference, name
                kept.append(table)
                task = other = 0.0
                for a, b in zip(before, after, strict=True):
                    spent = sorted((b[k] - a.get(k, 0.0) for k in b), reverse=True)
                    task, other = task + spent[0], other + sum(spent[1:])
                first: dict[str, float] = {}
                for d in stream.data if dask else []:
                    start = min(s["start"] for s in d["startstops"] if s["action"] == "compute") - began
                    first[d["worker"]] = min(start, first.get(d["worker"], start))
                firsts = sorted(first.values())
                results[name].append(
                    {
                        "wall": wall,
                        "cpu": cpu + (task + other if dask else 0.0),
                        "me": cpu,
                        "task": task,
                        "other": other,
                        "full": len(FULL),
                        "full_cpu": sum(FULL),
                        "graphs": graphs.calls - calls,
                        "tasks": graphs.tasks - tasks,
                        "sent": sum(SENT) / len(reference),
                        "back": sum(BACK) / len(reference),
                        "first": firsts[0] if firsts else np.nan,
                        "second": firsts[1] if len(firsts) > 1 else np.nan,
                    }
                )
                if len(kept) > 8:
                    kept.pop(0)
                time.sleep(0.2)
            print(f"round {r + 1}: " + "; ".join(f"{name} {results[name][-1]['wall']:.3f} s" for name in variants) + f"; load {os.getloadavg()[0]:.1f}", flush=True)
        library._dask, library._heap_frozen = AFTER_DASK, AFTER_FROZEN  # type: ignore[assignment]
        library.close_clients()
    print(f"medians of {rounds} rounds (per sweep of 10^4 runs):")
    print(
        "variant | wall s | CPU s in all | this process | workers' task threads | their other threads | full GCs (rounds) | their CPU s | update_graph | tasks | bytes a run out | back | 1st and 2nd worker's first task, ms"
    )
    for name, values in results.items():
        m = {k: float(np.nanmedian([v[k] for v in values])) for k in values[0]}
        fulls = ",".join(str(int(v["full"])) for v in values)
        print(
            f"  {name:22s} | {m['wall']:.3f} | {m['cpu']:.3f} | {m['me']:.3f} | {m['task']:.3f} | {m['other']:.3f} | {fulls} | {np.sum([v['full_cpu'] for v in values]) / len(values):.3f} (mean)"
            f" | {m['graphs']:.0f} | {m['tasks']:.0f} | {m['sent']:.1f} | {m['back']:.1f} | {m['first'] * 1e3:.1f}, {m['second'] * 1e3:.1f}"
        )
    for when in ("after", "before"):
        ratio = [c["wall"] / w["wall"] for c, w in zip(results[f"LocalCluster ({when})"], results[f"--workers 2 ({when})"], strict=True)]
        cpu = [c["cpu"] / w["cpu"] for c, w in zip(results[f"LocalCluster ({when})"], results[f"--workers 2 ({when})"], strict=True)]
        print(f"  {when}: LocalCluster / --workers 2, wall: median {np.median(ratio):.2f}x (rounds {', '.join(f'{x:.2f}' for x in ratio)}); CPU: median {np.median(cpu):.2f}x")


if __name__ == "__main__":
    main()
