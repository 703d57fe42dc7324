"""CPU per lane evaluation of the same compiled calls on `--workers 2`'s threads and in a 2-worker LocalCluster's
worker processes (issue 18), interleaved round by round (order alternating):

    PYTHONPATH=. .venv/bin/python benchmarks/sweep_cluster_perwork.py 8    # rounds

Each Runner's lane loop is wrapped (in this process and, through `client.run`, in each worker) to add the CPU time of
the calling thread inside each compiled call (time.thread_time) and the lane evaluations the call counts; per sweep of
benchmarks/sweep_bench.py's 10^4 runs: ns of CPU per lane evaluation (the same 11 calls, the same 40 061 568
evaluations either way).
"""

from __future__ import annotations

import itertools
import os
import sys
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


def wrap(dask_worker: Any = None) -> bool:
    """Wrap the lane loop of every Runner of this process (once): each call adds (CPU s, evaluations, runs) to a list
    kept on the sweep module (this function travels to the workers by value; the list stays in their module)."""
    from lagrange_cli import sweep as lib

    calls = lib.__dict__.setdefault("_BENCH_CALLS", [])
    for runner in lib._RUNNERS.values():
        if getattr(runner, "_bench_wrapped", False) or runner.lanes_entry is None:
            continue
        inner = runner.lanes_entry

        def wrapped(*arguments: Any, inner: Any = inner) -> Any:
            began = time.thread_time()
            out = inner(*arguments)
            calls.append((time.thread_time() - began, int(out[5]), len(arguments[1])))
            return out

        runner.lanes_entry = wrapped
        runner._bench_wrapped = True
    return True


def take(dask_worker: Any = None) -> list[tuple[float, int, int]]:
    from lagrange_cli import sweep as lib

    calls = lib.__dict__.setdefault("_BENCH_CALLS", [])
    out = list(calls)
    calls.clear()
    return out


def main() -> None:
    from distributed import LocalCluster

    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    text = pendulum.system_yaml(2)
    model = derive.derive(spec.parse(text, "chain_2.yaml"))
    q1, q2 = model.coordinates
    axes = [library.Axis("initial", q1, -1.5, 1.5), library.Axis("initial", q2, -1.5, 1.5)]
    options = {"text": text, "sample": 10_000, "seed": 0, "measures": ["final"], "t_end": 10.0, "rtol": 1e-9, "atol": 1e-12, "method": "DOP853", "backend": "compiled", "batch": 250}
    library.sweep(model, axes, **{**options, "sample": 8})
    wrap()
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average {', '.join(f'{x:.1f}' for x in os.getloadavg())}; {rounds} rounds", flush=True)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        library.sweep(model, axes, scheduler=address, **{**options, "sample": 8})
        client = library._client(address)
        client.run(wrap)
        results: dict[str, list[float]] = {"--workers 2": [], "LocalCluster": []}
        for r in range(rounds):
            for kind in list(results) if r % 2 == 0 else list(results)[::-1]:
                take()
                client.run(take)
                library.sweep(model, axes, **({"workers": 2} if kind == "--workers 2" else {"scheduler": address}), **options)
                calls = take() if kind == "--workers 2" else list(itertools.chain.from_iterable(client.run(take).values()))
                cpu, evaluations = sum(c[0] for c in calls), sum(c[1] for c in calls)
                results[kind].append(cpu / evaluations * 1e9)
                print(f"  {kind}: {len(calls)} calls, {sum(c[2] for c in calls)} runs, CPU {cpu:.3f} s, {evaluations} lane evaluations, {cpu / evaluations * 1e9:.2f} ns each", flush=True)
        library.close_clients()
    medians = {kind: float(np.median(values)) for kind, values in results.items()}
    print(f"medians: {', '.join(f'{k} {v:.2f} ns' for k, v in medians.items())}; LocalCluster / --workers 2: {medians['LocalCluster'] / medians['--workers 2']:.3f}; load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
