"""Sweep benchmarks (issue 18): 10^4 double-pendulum runs to t = 10 at rtol 1e-6.

    .venv/bin/python benchmarks/sweep_bench.py               # 10^4 runs, a few minutes on a loaded machine
    .venv/bin/python benchmarks/sweep_bench.py --runs 2000   # fewer
    .venv/bin/python benchmarks/sweep_bench.py --write       # also append/replace the section of BENCHMARKS.md

The system: benchmarks/pendulum.py's 2-link chain (the double pendulum, m = l = 1, g = 9.81,
absolute angles), started at rest at angles drawn uniformly from [-1.5, 1.5]^2 (seed 0), run to
t = 10 at rtol 1e-6, atol 1e-9, recording the final state. Contestants:
1. `lagrange_cli.sweep.sweep` (compiled DOP853, batches of 64) on 1 thread, 2 threads, and a
   2-worker `dask.distributed.LocalCluster` (processes, 1 thread each), every run;
2. the peer: a Python loop over `scipy.integrate.solve_ivp` (DOP853, same tolerances) on the
   sympy.physics.mechanics + lambdify(cse=True) right-hand side (benchmarks/peer.py), timed on a
   sample of PEER_SAMPLE runs and extrapolated linearly to all runs (stated as such);
3. a Python loop over lagrange's own API `simulate` (compiled DOP853, samples=2), timed on a
   sample of API_SAMPLE runs and extrapolated.
Wall-clock times on a machine shared with other jobs: the ratios (taken in the same run) are
what to read. The sweep's final states are checked against the peer's on the peer's sample.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT))

import pendulum  # noqa: E402

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli import sweep as library  # noqa: E402
from lagrange_cli.numeric.simulate import simulate  # noqa: E402

BEGIN, END = "<!-- sweep:begin -->", "<!-- sweep:end -->"
RTOL, ATOL, T_END = 1e-6, 1e-9, 10.0
PEER_SAMPLE, API_SAMPLE = 40, 300


def timed(run: Any) -> tuple[float, Any]:
    began = time.perf_counter()
    value = run()
    return time.perf_counter() - began, value


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--write", action="store_true")
    arguments = parser.parse_args()
    n = arguments.runs
    text = pendulum.system_yaml(2)
    model = derive.derive(spec.parse(text, "chain_2.yaml"))
    q1, q2 = model.coordinates
    axes = [library.Axis("initial", q1, -1.5, 1.5), library.Axis("initial", q2, -1.5, 1.5)]
    points = library.points(axes, n, seed=0)
    options = {"text": text, "sample": n, "seed": 0, "measures": ["final"], "t_end": T_END, "rtol": RTOL, "atol": ATOL, "method": "DOP853", "backend": "compiled"}
    library.sweep(model, axes, **{**options, "sample": 8})  # compile or load once, outside the timings
    one, table = timed(lambda: library.sweep(model, axes, **options))
    two, table_two = timed(lambda: library.sweep(model, axes, workers=2, **options))
    assert table.rows == table_two.rows

    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        library.sweep(model, axes, scheduler=cluster.scheduler_address, **{**options, "sample": 8})  # workers derive and load once
        dask, table_dask = timed(lambda: library.sweep(model, axes, scheduler=cluster.scheduler_address, **options))
    assert table_dask.rows == table.rows

    import peer as sympy_peer
    from scipy.integrate import solve_ivp

    mass, forcing, q = sympy_peer.derive(2)
    rhs = sympy_peer.make_rhs(*sympy_peer.plain(mass, forcing, q))
    starts = [np.array([a, b, 0.0, 0.0]) for a, b in points[:PEER_SAMPLE]]
    rhs(0.0, starts[0])
    peer_time, finals = timed(lambda: [solve_ivp(rhs, (0.0, T_END), y0, method="DOP853", rtol=RTOL, atol=ATOL).y[:, -1] for y0 in starts])
    columns = [table.columns.index(f"{name}_final") for name in (q1, q2, f"{q1}_dot", f"{q2}_dot")]
    ours = np.array([[row[k] for k in columns] for row in table.rows[:PEER_SAMPLE]])
    agreement = np.abs(ours - np.array(finals)).max(axis=1)

    simulate(model, t_end=T_END, method="DOP853", backend="compiled", rtol=RTOL, atol=ATOL, samples=2)
    api_time, _ = timed(lambda: [simulate(model, t_end=T_END, method="DOP853", backend="compiled", rtol=RTOL, atol=ATOL, samples=2, initial={q1: a, q2: b}) for a, b in points[:API_SAMPLE]])

    peer_all, api_all = peer_time / PEER_SAMPLE * n, api_time / API_SAMPLE * n
    failed = sum(1 for row in table.rows if row[table.columns.index("status")] == "failed")
    lines = [
        "## Sweeps (issue 18)",
        "",
        f"`benchmarks/sweep_bench.py --runs {n}`: {n} double-pendulum runs (2-link chain, m = l = 1, g = 9.81, at rest from angles",
        f"uniform in [-1.5, 1.5]^2, seed 0) to t = {T_END:g}, rtol {RTOL:g}, atol {ATOL:g}, final state recorded ({failed} failed).",
        f"Measured {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} on the 2-core machine while other jobs ran (os.getloadavg = {', '.join(f'{x:.1f}' for x in os.getloadavg())}): read the ratios.",
        "",
        "| contestant | runs timed | seconds (all runs) | per run | sweep (1 worker) is faster by |",
        "|---|---|---|---|---|",
        f"| `lagrange sweep` compiled DOP853, 1 worker | {n} | {one:.2f} | {one / n * 1e3:.3f} ms | 1x |",
        f"| `lagrange sweep --workers 2` (2 threads, GIL released in the compiled loop) | {n} | {two:.2f} | {two / n * 1e3:.3f} ms | {two / one:.2f}x the time: speed-up {one / two:.2f}x |",
        f"| `lagrange sweep --scheduler` (2-worker LocalCluster, processes) | {n} | {dask:.2f} | {dask / n * 1e3:.3f} ms | {dask / two:.2f}x the time of --workers 2 |",
        f"| peer: Python loop over `solve_ivp` (DOP853) on lambdify(cse=True) | {PEER_SAMPLE}, extrapolated | {peer_all:.1f} | {peer_time / PEER_SAMPLE * 1e3:.2f} ms | {peer_all / one:.0f}x |",
        f"| Python loop over lagrange's API `simulate` (compiled DOP853) | {API_SAMPLE}, extrapolated | {api_all:.1f} | {api_time / API_SAMPLE * 1e3:.3f} ms | {api_all / one:.1f}x |",
        "",
        f"- Against the peer: {peer_all / one:.0f}x (target >= 100x); against a loop over `simulate`: {api_all / one:.1f}x (target >= 5x).",
        f"- Two local workers: {one / two:.2f}x one worker (target >= 1.7x; the machine was shared, so two free cores were not available).",
        f"- 2-worker LocalCluster: {dask / two:.2f}x the time of `--workers 2` (target <= 1.3x); its rows equal the local run's exactly.",
        f"- The sweep's final states agree with the peer's on its {PEER_SAMPLE} runs to a median of {np.median(agreement):.1e} (max {agreement.max():.1e}: chaotic runs amplify the 1e-6 tolerance).",
        "",
    ]
    report = "\n".join(lines)
    print(report)
    if arguments.write:
        write_section(report)


def write_section(text: str) -> None:
    """Replace (or append) this benchmark's section of BENCHMARKS.md, between its markers."""
    path = ROOT / "BENCHMARKS.md"
    current = path.read_text() if path.exists() else "# Benchmarks\n"
    block = f"{BEGIN}\n{text}{END}\n"
    if BEGIN not in current or END not in current:
        path.write_text(current.rstrip("\n") + "\n\n" + block)
        return
    path.write_text(current[: current.index(BEGIN)] + block + current[current.index(END) + len(END) + 1 :])


if __name__ == "__main__":
    main()
