"""Sweep benchmarks (issue 18): 10^4 double-pendulum runs to t = 10 at error 1e-6.

    .venv/bin/python benchmarks/sweep_bench.py               # 10^4 runs, a few minutes on a loaded machine
    .venv/bin/python benchmarks/sweep_bench.py --runs 2000   # fewer
    .venv/bin/python benchmarks/sweep_bench.py --write       # also append this run to the section of BENCHMARKS.md

The system: benchmarks/pendulum.py's 2-link chain (the double pendulum, m = l = 1, g = 9.81,
absolute angles), started at rest at angles drawn uniformly from [-1.5, 1.5]^2 (seed 0), run to
t = 10 at rtol 1e-9, atol 1e-12 (so that runs end within about 1e-6 of the true state: see the
report's true-error line), recording the final state. Contestants:
1. `lagrange_cli.sweep.sweep` (compiled DOP853, batches of BATCH runs grouped as `sweep._task_groups` groups them, one
   compiled call a group, the runs in lockstep lanes:
   numeric/lanes.py) on 1 thread, 2 threads, and a 2-worker `dask.distributed.LocalCluster` (processes, 1 thread each),
   every run; and on 1 thread without lanes (`sweep.LANES = False`: ensemble.batch, the path before lanes), each round;
2. the peer: a Python loop over `scipy.integrate.solve_ivp` (DOP853, same tolerances) on the
   sympy.physics.mechanics + lambdify(cse=True) right-hand side (benchmarks/peer.py), timed on a
   sample of PEER_SAMPLE runs and extrapolated linearly to all runs (stated as such);
3. a Python loop over lagrange's own API `simulate`: tuned (compiled DOP853, samples=2: the least
   work it can be asked for), timed on API_SAMPLE runs, and as documented (`simulate(model,
   t_end, rtol, atol, initial)`, method and backend auto, 1001 samples) on DEFAULT_SAMPLE runs,
   both extrapolated.
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
RTOL, ATOL, T_END = 1e-9, 1e-12, 10.0  # defaults: the median run's final state within 1e-6 (see the report's true error)
PEER_SAMPLE, API_SAMPLE, DEFAULT_SAMPLE = 40, 300, 60
REFERENCE_RTOL = 1e-13  # the reference sweep's tolerance (atol 1e-2 x that)
BATCH = 250  # runs per batch (task) for all three sweep contestants


CPU: dict[int, float] = {}


def timed(run: Any) -> tuple[float, Any]:
    """Wall-clock seconds of run() and its value; its CPU seconds (this process) go to CPU[id(value)]."""
    began, cpu = time.perf_counter(), time.process_time()
    value = run()
    CPU[id(value)] = time.process_time() - cpu
    return time.perf_counter() - began, value


def cluster_processes(address: str) -> tuple[list[Any], list[Any]]:
    """The psutil processes of a local cluster's workers and of their nannies (empty lists without psutil). The nannies
    of a LocalCluster run in the process that made it (this one: its CPU is this process's, counted once as the client's
    and scheduler's), so only a nanny in another process is listed."""
    try:
        import psutil
    except ImportError:
        return [], []
    from distributed import Client

    with Client(address, set_as_default=False) as client:
        pids = list(client.run(os.getpid).values())
    workers = [psutil.Process(pid) for pid in pids]
    parents = {process.parent().pid for process in workers} - {os.getpid()}
    return workers, [psutil.Process(pid) for pid in sorted(parents)]


def thread_cpu(processes: list[Any]) -> list[dict[int, float]]:
    """User + system CPU seconds of every thread of each of `processes` so far."""
    return [{t.id: t.user_time + t.system_time for t in process.threads()} for process in processes]


def task_and_rest(before: list[dict[int, float]], after: list[dict[int, float]]) -> tuple[float, float]:
    """CPU seconds between `before` and `after` (thread_cpu) of the workers' busiest thread each (the one running the
    tasks: one thread a worker) and of all their other threads (Dask's event loop: messages, transfers, heartbeats,
    its profiler and system monitor)."""
    task = rest = 0.0
    for a, b in zip(before, after, strict=True):
        spent = sorted((b[k] - a.get(k, 0.0) for k in b), reverse=True)
        task += spent[0] if spent else 0.0
        rest += sum(spent[1:])
    return task, rest


def cpu_of(processes: list[Any]) -> float:
    """User + system CPU seconds of `processes` so far."""
    return sum(sum(process.cpu_times()[:2]) for process in processes)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--rtol", type=float, default=RTOL)
    parser.add_argument("--atol", type=float, default=ATOL)
    parser.add_argument("--rounds", type=int, default=7, help="rounds of each parallel comparison (1 worker against 2; 2 workers against LocalCluster), all reported, medians in the table")
    parser.add_argument("--write", action="store_true")
    parser.add_argument("--parallel-only", action="store_true", help="only the two parallel comparisons (a quick pass), printed round by round; no sequential contestants")
    arguments = parser.parse_args()
    rtol, atol = arguments.rtol, arguments.atol
    load_start = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    n = arguments.runs
    text = pendulum.system_yaml(2)
    model = derive.derive(spec.parse(text, "chain_2.yaml"))
    q1, q2 = model.coordinates
    axes = [library.Axis("initial", q1, -1.5, 1.5), library.Axis("initial", q2, -1.5, 1.5)]
    points = library.points(axes, n, seed=0)
    options = {"text": text, "sample": n, "seed": 0, "measures": ["final"], "t_end": T_END, "rtol": rtol, "atol": atol, "method": "DOP853", "backend": "compiled", "batch": BATCH}
    library.sweep(model, axes, **{**options, "sample": 8})  # compile or load once, outside the timings

    from distributed import LocalCluster

    # The parallel comparisons need two free cores. Each is run `--rounds` times, its contestants interleaved, each round
    # with the load average at its end; the table shows the medians of the rounds' times and ratios, the list below every round.
    # 1 worker against 2 runs with no Dask cluster up: an idle LocalCluster (a scheduler in this process, two workers and
    # their nannies) takes about 15% of a core between them (heartbeats, its profiler), which would be charged to the threads.
    # LocalCluster against --workers 2 runs with the cluster up, both contestants beside the same idle processes.
    local_rounds: list[tuple[float, float, float, float, str]] = []  # wall 1 worker, wall 2 workers, CPU 1, CPU 2, load
    dask_rounds: list[
        tuple[float, float, str, float, float, float, float, float, float]
    ] = []  # wall 2 workers, wall LocalCluster, load; CPU: 2 workers, this process, workers, nannies elsewhere, workers' task threads, their other threads
    before: list[tuple[float, float, Any]] = []  # (wall, CPU, table) of the sweep without lanes (library.LANES = False), each round

    def load_now() -> str:
        return ", ".join(f"{x:.1f}" for x in os.getloadavg())

    def without_lanes() -> None:
        library.LANES = False
        library._RUNNERS.clear()
        library.sweep(model, axes, **{**options, "sample": 8})  # the runner without lanes, built outside the timing
        wall, table_before = timed(lambda: library.sweep(model, axes, **options))
        before.append((wall, CPU[id(table_before)], table_before))
        library.LANES = True
        library._RUNNERS.clear()
        library.sweep(model, axes, **{**options, "sample": 8})

    rounds = max(1, arguments.rounds)
    for _ in range(rounds):
        one, table = timed(lambda: library.sweep(model, axes, **options))
        two, table_two = timed(lambda: library.sweep(model, axes, workers=2, **options))
        if not arguments.parallel_only:
            without_lanes()
        assert table.rows == table_two.rows
        local_rounds.append((one, two, CPU[id(table)], CPU[id(table_two)], load_now()))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        library.sweep(model, axes, scheduler=cluster.scheduler_address, **{**options, "sample": 8})  # every worker derives and loads once
        workers, nannies = cluster_processes(cluster.scheduler_address)
        for _ in range(rounds):
            two_beside, table_two = timed(lambda: library.sweep(model, axes, workers=2, **options))
            before_workers, before_nannies, before_threads = cpu_of(workers), cpu_of(nannies), thread_cpu(workers)
            dask, table_dask = timed(lambda: library.sweep(model, axes, scheduler=cluster.scheduler_address, **options))
            task, rest = task_and_rest(before_threads, thread_cpu(workers))
            assert table_dask.rows == table.rows and table_two.rows == table.rows
            dask_rounds.append((two_beside, dask, load_now(), CPU[id(table_two)], CPU[id(table_dask)], cpu_of(workers) - before_workers, cpu_of(nannies) - before_nannies, task, rest))
        library.close_clients()  # the sweeps' kept client, before the cluster goes
    if arguments.parallel_only:
        print(parallel_report(local_rounds, dask_rounds, load_start))
        return
    one, two = float(np.median([r[0] for r in local_rounds])), float(np.median([r[1] for r in local_rounds]))
    speedup = float(np.median([r[0] / r[1] for r in local_rounds]))
    two_beside, dask = float(np.median([r[0] for r in dask_rounds])), float(np.median([r[1] for r in dask_rounds]))
    dask_ratio = float(np.median([r[1] / r[0] for r in dask_rounds]))
    cpu_one = float(np.median([r[2] for r in local_rounds]))  # the sequential contestants compare by CPU time: the rounds' median
    cpu_two = float(np.median([r[3] for r in local_rounds]))
    cpu_before = float(np.median([b[1] for b in before]))
    wall_before, table_before = before[0][0], before[0][2]
    lane_runner = next(r for r in library._RUNNERS.values() if r.model is model and r.lanes_entry is not None)
    from lagrange_cli.numeric.lanes import LANES

    y0s, ps = lane_runner.points(points)
    control = lane_runner._control(0.0, T_END)
    ts = np.array(lane_runner.settings.t_eval, dtype=float)
    lane_cpu = time.process_time()
    cuts = [[i for b in group for i in b] for group in library._task_groups([list(range(k, min(k + BATCH, n))) for k in range(0, n, BATCH)], 1)]  # as 1 worker cuts them
    lane_evaluations = sum(int(lane_runner.lanes_entry(lane_runner.pair, y0s[c], ps[c], control, ts, lane_runner.budget, LANES, lane_runner.accel, lane_runner.lanes_accel)[5]) for c in cuts)
    lane_cpu = time.process_time() - lane_cpu

    import peer as sympy_peer
    from scipy.integrate import solve_ivp

    mass, forcing, q = sympy_peer.derive(2)
    rhs = sympy_peer.make_rhs(*sympy_peer.plain(mass, forcing, q))
    starts = [np.array([a, b, 0.0, 0.0]) for a, b in points[:PEER_SAMPLE]]
    rhs(0.0, starts[0])
    peer_wall, finals = timed(lambda: [solve_ivp(rhs, (0.0, T_END), y0, method="DOP853", rtol=rtol, atol=atol).y[:, -1] for y0 in starts])
    columns = [table.columns.index(f"{name}_final") for name in (q1, q2, f"{q1}_dot", f"{q2}_dot")]
    ours = np.array([[row[k] for k in columns] for row in table.rows[:PEER_SAMPLE]])
    agreement = np.abs(ours - np.array(finals)).max(axis=1)
    # the true error of every run: its final state against the same sweep at rtol 1e-13 (DOP853 converges; chaotic runs amplify any tolerance)
    tight = library.sweep(model, axes, **{**options, "rtol": REFERENCE_RTOL, "atol": REFERENCE_RTOL * 1e-2})
    exact = np.array([[row[k] for k in columns] for row in tight.rows])
    every = np.array([[row[k] for k in columns] for row in table.rows])
    true_error = np.abs(every - exact).max(axis=1)
    every_before = np.array([[row[k] for k in columns] for row in table_before.rows])
    true_error_before = np.abs(every_before - exact).max(axis=1)
    lanes_against_before = (np.abs(every - every_before) / np.maximum(1.0, np.abs(every_before))).max(axis=1)
    status_column = table.columns.index("status")
    same_status = all(a[status_column] == b[status_column] for a, b in zip(table.rows, table_before.rows, strict=True))
    peer_error = np.abs(np.array(finals) - exact[:PEER_SAMPLE]).max(axis=1)

    simulate(model, t_end=T_END, method="DOP853", backend="compiled", rtol=rtol, atol=atol, samples=2)
    api_wall, api_runs = timed(lambda: [simulate(model, t_end=T_END, method="DOP853", backend="compiled", rtol=rtol, atol=atol, samples=2, initial={q1: a, q2: b}) for a, b in points[:API_SAMPLE]])

    default_wall, default_runs = timed(lambda: [simulate(model, t_end=T_END, rtol=rtol, atol=atol, initial={q1: a, q2: b}) for a, b in points[:DEFAULT_SAMPLE]])

    peer_time, api_time, default_time = CPU[id(finals)], CPU[id(api_runs)], CPU[id(default_runs)]
    default_method = f"{default_runs[0].settings.method} ({default_runs[0].settings.backend})"
    peer_all, api_all, default_all = peer_time / PEER_SAMPLE * n, api_time / API_SAMPLE * n, default_time / DEFAULT_SAMPLE * n
    failed = sum(1 for row in table.rows if row[table.columns.index("status")] == "failed")
    lines = [
        "## Sweeps (issue 18)",
        "",
        f"`benchmarks/sweep_bench.py --runs {n} --rtol {rtol:g} --atol {atol:g}`: {n} double-pendulum runs (2-link chain, m = l = 1, g = 9.81, at rest from angles",
        f"uniform in [-1.5, 1.5]^2, seed 0) to t = {T_END:g}, rtol {rtol:g}, atol {atol:g}, final state recorded ({failed} failed).",
        f"Measured {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} on the 2-core machine (os.getloadavg at the end = {', '.join(f'{x:.1f}' for x in os.getloadavg())}): read the ratios.",
        "",
        "The sequential contestants are compared by the CPU time of this process (`time.process_time`), which load from other",
        "jobs does not inflate; the parallel ones by wall-clock time, which needs a quiet machine (load average well under 1).",
        "",
        "| contestant | runs timed | CPU s (all runs) | wall s (all runs) | CPU per run | the sweep (1 worker) is faster by |",
        "|---|---|---|---|---|---|",
        f"| `lagrange sweep` compiled DOP853, 1 worker (medians of the rounds) | {n} | {cpu_one:.2f} | {one:.2f} | {cpu_one / n * 1e3:.3f} ms | 1x |",
        f"| before: `lagrange sweep` without lanes (`sweep.LANES = False`: ensemble.batch, run by run in one compiled call), 1 worker (CPU: median of the rounds) | {n} | {cpu_before:.2f} | {wall_before:.2f} | {cpu_before / n * 1e3:.3f} ms | {cpu_before / cpu_one:.2f}x |",
        f"| `lagrange sweep --workers 2` (2 threads, GIL released in the compiled loop; medians) | {n} | {cpu_two:.2f} | {two:.2f} | | wall: speed-up {speedup:.2f}x over 1 worker (median of the rounds' ratios) |",
        f"| `lagrange sweep --scheduler` (2-worker LocalCluster, processes; medians) | {n} | (in the workers) | {dask:.2f} | | wall: {dask_ratio:.2f}x the time of --workers 2 beside the same cluster ({two_beside:.2f} s; median of the rounds' ratios) |",
        f"| peer: Python loop over `solve_ivp` (DOP853) on lambdify(cse=True) | {PEER_SAMPLE}, extrapolated | {peer_all:.1f} | {peer_wall / PEER_SAMPLE * n:.1f} | {peer_time / PEER_SAMPLE * 1e3:.2f} ms | {peer_all / cpu_one:.0f}x (wall {peer_wall / PEER_SAMPLE * n / one:.0f}x) |",
        f"| Python loop over lagrange's API `simulate`, tuned (compiled DOP853, samples=2) | {API_SAMPLE}, extrapolated | {api_all:.1f} | {api_wall / API_SAMPLE * n:.1f} | {api_time / API_SAMPLE * 1e3:.3f} ms | {api_all / cpu_one:.1f}x (wall {api_wall / API_SAMPLE * n / one:.1f}x) |",
        f"| Python loop over `simulate` as documented (auto: {default_method}, 1001 samples) | {DEFAULT_SAMPLE}, extrapolated | {default_all:.1f} | {default_wall / DEFAULT_SAMPLE * n:.1f} | {default_time / DEFAULT_SAMPLE * 1e3:.3f} ms | {default_all / cpu_one:.1f}x |",
        "",
        f"- Against the peer: {peer_all / cpu_one:.0f}x in CPU time (target >= 100x); against a loop over `simulate`: {api_all / cpu_one:.1f}x tuned, {default_all / cpu_one:.1f}x with its defaults (target >= 5x).",
        f"- Lanes ({LANES} runs in lockstep, numeric/lanes.py) against the same sweep without them: {cpu_before / cpu_one:.2f}x (CPU, median of the rounds: "
        + ", ".join(f"{b[1]:.2f} s" for b in before)
        + f" without, {', '.join(f'{r[2]:.2f} s' for r in local_rounds)} with); the tuned `simulate` loop against the sweep without lanes: {api_all / cpu_before:.1f}x.",
        f"- Per evaluation: {lane_evaluations / n:.0f} lane evaluations a run (idle lanes at the end of each of 1 worker's {len(cuts)} compiled calls included), the whole run"
        f" {lane_cpu / lane_evaluations * 1e9:.1f} ns a lane evaluation (the lane loop called directly, call by call, CPU {lane_cpu:.2f} s); without lanes"
        f" {cpu_before / lane_evaluations * 1e9:.1f} ns an evaluation at the same count.",
        f"- Lanes against no lanes: statuses {'identical' if same_status else 'DIFFERENT'}; final states (relative, largest component) median {np.median(lanes_against_before):.1e},"
        f" 90% {np.quantile(lanes_against_before, 0.9):.1e}, max {lanes_against_before.max():.1e} (the right-hand side differs by round-off, which the"
        f" step-size controller and the chaotic runs amplify); true error without lanes: median {np.median(true_error_before):.1e}, {100 * np.mean(true_error_before <= 1e-6):.0f}% of runs within 1e-6.",
        f"- Two local workers: {speedup:.2f}x one worker, the median of {rounds} rounds (target >= 1.7x). The CPU time of the process was {cpu_one:.1f} s with one worker and",
        f"  {cpu_two:.1f} s with two (the threads run the compiled loop with the GIL released); load average at the start {load_start}. No Dask cluster was up.",
        "  Every round (wall s: 1 worker, --workers 2; speed-up; CPU s of this process with 1 and 2 workers; os.getloadavg at the round's end): "
        + "; ".join(f"{a:.2f}, {b:.2f} ({a / b:.2f}x; CPU {c:.2f}, {d:.2f}; load {g})" for a, b, c, d, g in local_rounds)
        + ".",
        f"- 2-worker LocalCluster: {dask_ratio:.2f}x the time of `--workers 2`, the median of {rounds} rounds' ratios ({dask / two_beside:.2f}x as the ratio of the medians; target <= 1.3x; Dask adds its scheduling,",
        "  transfers and its idle processes' heartbeats); its rows equal the local run's exactly. Every round (wall s: --workers 2 beside the idle",
        "  cluster, LocalCluster; ratio; os.getloadavg at the round's end; CPU s: --workers 2's process, and the LocalCluster sweep's in this process",
        "  (client, scheduler and the LocalCluster's nannies), its two workers (psutil; of which their task threads, and their other threads: Dask's event loop): "
        + "; ".join(
            f"{a:.2f}, {b:.2f} ({b / a:.2f}x; load {g}; CPU {c:.2f} against {d:.2f} + {w:.2f} (tasks {t:.2f}, the rest {r:.2f}){f' + nannies {m:.2f}' if m else ''})"
            for a, b, g, c, d, w, m, t, r in dask_rounds
        )
        + ".",
        f"  CPU (load-independent companion, medians): --workers 2 {np.median([r[3] for r in dask_rounds]):.2f} s; the LocalCluster sweep {np.median([r[4] + r[5] + r[6] for r in dask_rounds]):.2f} s in all"
        f" ({np.median([r[4] for r in dask_rounds]):.2f} s client, scheduler and nannies, {np.median([r[5] for r in dask_rounds]):.2f} s workers: tasks {np.median([r[7] for r in dask_rounds]):.2f} s, the rest {np.median([r[8] for r in dask_rounds]):.2f} s): {np.median([(r[4] + r[5] + r[6]) / r[3] for r in dask_rounds]):.2f}x.",
        f"- `simulate` as documented picks its own method ({default_method}) and keeps 1001 samples with their invariants: more",
        "  than the sweep computes, so the tuned loop is the fair comparison.",
        f"- The sweep's final states agree with the peer's on its {PEER_SAMPLE} runs to a median of {np.median(agreement):.1e} (max {agreement.max():.1e}: chaotic runs amplify the tolerance).",
        f"- True error (largest component of the final state against the same sweep at rtol {REFERENCE_RTOL:g}): the sweep's median {np.median(true_error):.1e}, 90% {np.quantile(true_error, 0.9):.1e},",
        f"  {100 * np.mean(true_error <= 1e-6):.0f}% of runs within 1e-6; the peer's on its {PEER_SAMPLE} runs: median {np.median(peer_error):.1e}. Both run DOP853 with scipy's step control at the",
        "  same tolerances, so they are compared at the same error (a tolerance is not an error: chaotic runs amplify it).",
        "",
    ]
    report = "\n".join(lines)
    print(report)
    if arguments.write:
        write_section(report)


def parallel_report(local_rounds: list[Any], dask_rounds: list[Any], load_start: str) -> str:
    """The two parallel comparisons, every round and the medians (`--parallel-only`)."""
    lines = [
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at the start {load_start}",
        "1 worker against --workers 2 (no cluster up): wall s, wall s, speed-up; CPU s of the process; load",
    ]
    lines += [f"  {a:.3f} {b:.3f} {a / b:.2f}x; CPU {c:.3f} {d:.3f}; load {g}" for a, b, c, d, g in local_rounds]
    lines.append(
        f"  median speed-up {np.median([r[0] / r[1] for r in local_rounds]):.2f}x (target >= 1.7x); median CPU {np.median([r[2] for r in local_rounds]):.3f} s, {np.median([r[3] for r in local_rounds]):.3f} s"
    )
    lines.append(
        "--workers 2 against the LocalCluster (beside the idle cluster): wall s, wall s, ratio; CPU s: --workers 2, then the cluster sweep's"
        " client+scheduler+nannies (this process), workers (their task threads, their other threads)[, nannies in other processes]; load"
    )
    lines += [f"  {a:.3f} {b:.3f} {b / a:.2f}x; CPU {c:.3f} against {d:.3f} + {w:.3f} ({t:.3f}, {r:.3f}){f' + {m:.3f}' if m else ''}; load {g}" for a, b, g, c, d, w, m, t, r in dask_rounds]
    lines.append(
        f"  median ratio {np.median([r[1] / r[0] for r in dask_rounds]):.2f}x (target <= 1.3x); CPU of the cluster sweep in all over --workers 2's: {np.median([(r[4] + r[5] + r[6]) / r[3] for r in dask_rounds]):.2f}x"
        f" (medians: this process {np.median([r[4] for r in dask_rounds]):.3f} s, the workers' task threads {np.median([r[7] for r in dask_rounds]):.3f} s, their other threads {np.median([r[8] for r in dask_rounds]):.3f} s;"
        f" --workers 2 {np.median([r[3] for r in dask_rounds]):.3f} s)"
    )
    return "\n".join(lines)


def write_section(text: str) -> None:
    """Append this run's report to this benchmark's section of BENCHMARKS.md (before its end marker;
    earlier runs stay, for comparison), or start the section."""
    path = ROOT / "BENCHMARKS.md"
    current = path.read_text() if path.exists() else "# Benchmarks\n"
    if BEGIN not in current or END not in current:
        path.write_text(current.rstrip("\n") + "\n\n" + f"{BEGIN}\n{text}{END}\n")
        return
    at = current.index(END)
    text = text.split("\n", 2)[2] if text.startswith("## ") else text  # the section has its heading
    path.write_text(current[:at] + "\n### Run of " + time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()) + "\n\n" + text + current[at:])


if __name__ == "__main__":
    main()
