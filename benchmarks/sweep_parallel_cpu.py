"""Two local workers' CPU against one's (issue 18's 1.7x target), with controls in the same run:

    PYTHONPATH=. .venv/bin/python benchmarks/sweep_parallel_cpu.py [ROUNDS]
    PYTHONPATH=. .venv/bin/python benchmarks/sweep_parallel_cpu.py --counts

    chrt -f 10 env PYTHONPATH=. .venv/bin/python benchmarks/sweep_parallel_cpu.py --neighbour [ROUNDS]

`--neighbour`: one thread's CPU for the same work (the control loop; the sweep with 1 worker), pinned to CPU 0, while CPU 1
runs, pinned, a neighbour process of ours: `light` (a loop of sched_yield system calls: no floating point) or `simd`
(the control loop itself). Under a real-time priority (chrt), other jobs get little of either CPU. If the work costs
more CPU beside a busy neighbour, the two vCPUs share a core's resources (the VM's hardware, not the sweep's code).

`--counts`: how the sweep's runs are cut into compiled calls with 1 and 2 workers, before this branch and now, counted
(load-independent): calls, lane evaluations (idle lanes included), and the makespan of 2 threads taking the calls in
order (each call's cost its lane evaluations; the thread free first takes the next): one worker's evaluations over that
makespan is the speed-up the cut allows on two free cores.

Each round runs, interleaved, 1 thread then 2 threads of:
- `threads`: a trivially parallel compiled loop (numba, nogil, 32 lanes of arithmetic in registers and L1, no memory
  traffic) called from Python threads (a ThreadPoolExecutor): the sweep's own thread layer (`--workers N`);
- `prange`: the same loop under numba's `prange` (`numba.set_num_threads(1)` against 2; numba's threading layer);
- `sweep`: benchmarks/sweep_bench.py's sweep (10^4 double-pendulum runs, batches of 250), 1 worker against `--workers 2`.
For each: wall, this process's CPU (time.process_time), the CPU of the threads that did the work (time.thread_time
around each piece of work: only the work), /proc/stat's steal time over the contestant (clock ticks of both CPUs) and
the machine's busy time outside this process (/proc/stat busy less this process's CPU: other jobs). The work is
the same with 1 and 2 threads, so CPU(2) / CPU(1) above 1 is CPU that two threads spend for nothing: if the control
loses as much as the sweep, the machine (two vCPUs sharing a core or its clock, the hypervisor) is the ceiling.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import numba  # noqa: E402
import pendulum  # noqa: E402
from numba import njit, prange  # noqa: E402

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli import sweep as library  # noqa: E402

TICK = os.sysconf("SC_CLK_TCK")


@njit(nogil=True, cache=True)
def spin(steps: int) -> float:  # pragma: no cover - compiled
    """`steps` rounds of arithmetic on 32 lanes held in registers and L1 (a damped rotation: stays bounded)."""
    x = np.empty(32)
    y = np.empty(32)
    for k in range(32):
        x[k], y[k] = 1.0 + k * 1e-3, 0.5
    c, s = 0.9999, 0.0141
    for _ in range(steps):
        for k in range(32):
            a = c * x[k] - s * y[k]
            b = s * x[k] + c * y[k]
            x[k], y[k] = a * 1.0000001, b
    total = 0.0
    for k in range(32):
        total += x[k] + y[k]
    return total


@njit(parallel=True, cache=True)
def spin_prange(steps: int, parts: int) -> float:  # pragma: no cover - compiled
    out = np.zeros(parts)
    for j in prange(parts):
        out[j] = spin(steps // parts)
    return out.sum()


def stat() -> tuple[int, int]:
    """(busy ticks of all CPUs, steal ticks) from /proc/stat."""
    with open("/proc/stat") as handle:
        fields = [int(v) for v in handle.readline().split()[1:]]
    user, nice, system, _idle, _iowait, irq, softirq, steal = fields[:8]
    return user + nice + system + irq + softirq, steal


def tasks() -> dict[str, float]:
    """CPU seconds (user + system) of every thread of this process so far (/proc/self/task/*/stat, clock ticks)."""
    found = {}
    for task in Path("/proc/self/task").iterdir():
        try:
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:  # a thread that has just ended
            continue
        found[task.name] = (int(fields[11]) + int(fields[12])) / TICK
    return found


class Measured:
    def __init__(self) -> None:
        self.work = 0.0
        self.lock = threading.Lock()

    def add(self, seconds: float) -> None:
        with self.lock:
            self.work += seconds


def contestant(run: Any, measured: Measured) -> dict[str, float]:
    busy0, steal0 = stat()
    threads0 = tasks()
    wall, cpu = time.perf_counter(), time.process_time()
    run()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    threads1 = tasks()
    busy1, steal1 = stat()
    spent = sorted((threads1[k] - threads0.get(k, 0.0) for k in threads1), reverse=True)
    return {"wall": wall, "cpu": cpu, "work": measured.work, "steal": (steal1 - steal0) / TICK, "others": max(0.0, (busy1 - busy0) / TICK - cpu), "top2": sum(spent[:2])}


def counts(model: Any, axes: Any, options: dict[str, Any]) -> None:
    import heapq

    from lagrange_cli.numeric.lanes import LANES

    runner = next(r for r in library._RUNNERS.values() if r.model is model)
    grid = library.points(axes, 10_000, 0)
    y0s, ps = runner.points(grid)
    control, ts = runner._control(0.0, options["t_end"]), np.array(runner.settings.t_eval, dtype=float)
    batches = [list(range(k, k + 250)) for k in range(0, 10_000, 250)]

    def evaluations(piece: list[int]) -> int:
        ix = np.asarray(piece)
        return int(runner.lanes_entry(runner.pair, y0s[ix], ps[ix], control, ts, runner.budget, LANES, runner.accel, runner.lanes_accel)[5])

    def makespan(costs: list[int]) -> int:
        free = [0, 0]
        for cost in costs:
            heapq.heappush(free, heapq.heappop(free) + cost)
        return max(free)

    def flat(group: list[list[int]]) -> list[int]:
        return [i for b in group for i in b]

    cuts = {
        "before, 1 worker: a call per batch": batches,
        "before, --workers 2: a call per batch, the last 2 in halves": batches[:-2] + [b[h : h + 125] for b in batches[-2:] for h in (0, 125)],
        "now, 1 worker: a call per group (_task_groups(.., 1))": [flat(g) for g in library._task_groups(batches, 1)],
        "now, --workers 2: a call per group (_task_groups(.., 2))": [flat(g) for g in library._task_groups(batches, 2)],
        "(not kept) --workers 2 groups, the last 2 in halves": [flat(g) for g in library._task_groups(batches, 2)[:-2]]
        + [b[h : h + 125] for g in library._task_groups(batches, 2)[-2:] for b in g for h in (0, 125)],
    }
    found = {}
    for name, pieces in cuts.items():
        costs = [evaluations(piece) for piece in pieces]
        found[name] = (sum(costs), makespan(costs))
        print(f"{name}: {len(costs)} calls, {sum(costs)} lane evaluations ({sum(costs) / 10_000:.1f} a run), 2-thread makespan {makespan(costs)}")
    names = list(found)
    for one, two in ((names[0], names[1]), (names[2], names[3]), (names[2], names[4])):
        print(f"speed-up allowed, {one.split(':')[0]} over {two.split(':')[0]}: {found[one][0] / found[two][1]:.3f} (work {found[two][0] / found[one][0]:.4f}x)")


NEIGHBOURS = {
    "light": "import os\nwhile True:\n    os.sched_yield()\n",
    "simd": "import sys\nsys.path.insert(0, {here!r})\nfrom sweep_parallel_cpu import spin\nwhile True:\n    spin(200000)\n",
}


def neighbours(model: Any, axes: Any, options: dict[str, Any], rounds: int) -> None:
    import subprocess

    os.sched_setaffinity(0, {0})  # this (main) thread, which runs the 1-worker sweep and the control
    steps = 120_000_000  # about 0.8 s of one thread
    spin(1000)
    found: dict[tuple[str, str], list[float]] = {}
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average {', '.join(f'{x:.2f}' for x in os.getloadavg())}; scheduler policy {os.sched_getscheduler(0)} (1 = FIFO)")
    for r in range(rounds):
        for name in ("light", "simd") if r % 2 == 0 else ("simd", "light"):
            # on CPU 1 from the start (preexec_fn): under FIFO, a spinning child left on this CPU would never give it back
            process = subprocess.Popen([sys.executable, "-c", NEIGHBOURS[name].format(here=str(HERE))], preexec_fn=lambda: os.sched_setaffinity(0, {1}))
            time.sleep(4.0)  # started (imports, the control's cached machine code)
            busy0, _ = stat()
            began = time.thread_time()
            spin(steps)
            control = time.thread_time() - began
            began = time.thread_time()
            library.sweep(model, axes, **options)
            swept = time.thread_time() - began
            busy1, _ = stat()
            process.kill()
            process.wait()
            found.setdefault((name, "control"), []).append(control)
            found.setdefault((name, "sweep"), []).append(swept)
            print(f"  {r + 1} neighbour {name:5s}: control {control:.3f} s, sweep (1 worker) {swept:.3f} s; machine busy {(busy1 - busy0) / TICK:.2f} CPU s", flush=True)
    for work in ("control", "sweep"):
        light, simd = found[("light", work)], found[("simd", work)]
        ratios = [b / a for a, b in zip(light, simd, strict=True)]
        print(
            f"  {work}: median {np.median(light):.3f} s beside light, {np.median(simd):.3f} s beside simd; simd/light per round {', '.join(f'{x:.3f}' for x in ratios)} (median {np.median(ratios):.3f})"
        )


def main() -> None:
    numbers = [a for a in sys.argv[1:] if a.isdigit()]
    rounds = int(numbers[0]) if numbers else 7
    text = pendulum.system_yaml(2)
    model = derive.derive(spec.parse(text, "chain_2.yaml"))
    q1, q2 = model.coordinates
    axes = [library.Axis("initial", q1, -1.5, 1.5), library.Axis("initial", q2, -1.5, 1.5)]
    options = {"text": text, "sample": 10_000, "seed": 0, "measures": ["final"], "t_end": 10.0, "rtol": 1e-9, "atol": 1e-12, "method": "DOP853", "backend": "compiled", "batch": 250}
    library.sweep(model, axes, **{**options, "sample": 8})
    if "--counts" in sys.argv:
        counts(model, axes, options)
        return
    if "--neighbour" in sys.argv:
        neighbours(model, axes, options, rounds)
        return
    spin(10)
    spin_prange(10, 2)
    layer = numba.threading_layer()
    steps = 1000
    began = time.thread_time()
    spin(steps)
    while time.thread_time() - began < 0.02:
        steps *= 2
        began = time.thread_time()
        spin(steps)
    steps = int(steps * 0.9 / (time.thread_time() - began))  # about 0.9 s of one thread, like the sweep

    # the sweep's work in its threads: time.thread_time around each group of batches (library._run_group: its compiled call and rows)
    hook = "_run_group" if hasattr(library, "_run_group") else "_rows"  # _rows: a batch's call before sweeppar (to measure that tree)
    original_rows = getattr(library, hook)

    def sweep_with(workers: int) -> Any:
        measured = Measured()

        def rows(runner: Any, grid: Any, group: Any) -> Any:
            began = time.thread_time()
            result = original_rows(runner, grid, group)
            measured.add(time.thread_time() - began)
            return result

        def run() -> None:
            setattr(library, hook, rows)
            try:
                library.sweep(model, axes, workers=workers, **options)
            finally:
                setattr(library, hook, original_rows)

        return run, measured

    def threads_with(workers: int) -> Any:
        measured = Measured()

        def piece(n: int) -> float:
            began = time.thread_time()
            value = spin(n)
            measured.add(time.thread_time() - began)
            return value

        def run() -> None:
            if workers == 1:
                piece(steps)
            else:
                with ThreadPoolExecutor(workers) as pool:
                    list(pool.map(piece, [steps // workers] * workers))

        return run, measured

    def prange_with(workers: int) -> Any:
        measured = Measured()  # numba's pool threads: /proc/self/task (contestant's top2)

        def run() -> None:
            numba.set_num_threads(workers)
            spin_prange(steps, 2)
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)

        return run, measured

    print(
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at the start {', '.join(f'{x:.2f}' for x in os.getloadavg())}; numba {numba.__version__}, threading layer {layer}, NUMBA_NUM_THREADS {numba.config.NUMBA_NUM_THREADS}"
    )
    print(
        "per round and contestant, 1 thread | 2 threads: wall s, CPU s (process), work CPU s (the working threads: time.thread_time; prange: the busiest two of /proc/self/task, 10 ms ticks), steal s, others' CPU s; then speed-up and CPU(2)/CPU(1)"
    )
    results: dict[str, list[tuple[dict[str, float], dict[str, float]]]] = {"threads": [], "prange": [], "sweep": []}
    makers = {"threads": threads_with, "prange": prange_with, "sweep": sweep_with}
    for r in range(rounds):
        order = list(results) if r % 2 == 0 else list(results)[::-1]
        for name in order:
            one = contestant(*makers[name](1))
            two = contestant(*makers[name](2))
            if name == "prange":  # numba's pool threads outlive the call: their CPU from /proc/self/task (the busiest two threads)
                one["work"], two["work"] = one["top2"], two["top2"]
            results[name].append((one, two))
            print(
                f"  {r + 1} {name:7s} "
                + " | ".join(f"{m['wall']:.3f} {m['cpu']:.3f} {m['work']:.3f} {m['steal']:.2f} {m['others']:.2f}" for m in (one, two))
                + f"; {one['wall'] / two['wall']:.2f}x, CPU {two['cpu'] / one['cpu']:.3f}, work {two['work'] / one['work']:.3f}; load {os.getloadavg()[0]:.2f}",
                flush=True,
            )
    print("medians over the rounds (speed-up; CPU(2)/CPU(1) of the process; of the working threads; steal s and others' CPU s with 2 threads):")
    for name, pairs in results.items():
        speed = np.median([a["wall"] / b["wall"] for a, b in pairs])
        cpu = [b["cpu"] / a["cpu"] for a, b in pairs]
        work = [b["work"] / a["work"] for a, b in pairs]
        print(
            f"  {name:7s} speed-up {speed:.2f}x (rounds {min(a['wall'] / b['wall'] for a, b in pairs):.2f}-{max(a['wall'] / b['wall'] for a, b in pairs):.2f}); CPU {np.median(cpu):.3f} ({min(cpu):.3f}-{max(cpu):.3f});"
            f" work {np.median(work):.3f} ({min(work):.3f}-{max(work):.3f}); steal {np.median([b['steal'] for _, b in pairs]):.2f} s; others {np.median([b['others'] for _, b in pairs]):.2f} s"
        )
    print(f"load average at the end {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
