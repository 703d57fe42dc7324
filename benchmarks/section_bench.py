"""Poincare sections batched (issue 18): the README's elastic-pendulum section, its runs integrated in
one compiled call per batch (`Runner.section_batch`) against run by run from Python (`Runner.run_point`,
which restarts the compiled loop at every crossing). CPU time of this process (time.process_time),
best of --repeat; the two paths' rows are checked equal first.

    .venv/bin/python benchmarks/section_bench.py             # 16 runs to t = 300, as in the README
    .venv/bin/python benchmarks/section_bench.py --runs 64 --t-end 100
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli import sweep as library  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--t-end", type=float, default=300.0)
    parser.add_argument("--repeat", type=int, default=3)
    arguments = parser.parse_args()
    model = derive.derive(spec.load(spec.resolve("elastic_pendulum")))
    axes = [library.Axis("initial", "theta", 0.2, 1.4, arguments.runs)]
    section = "theta=0, theta_dot>0"
    options = {"initial": {"x": 0.3}, "t_end": arguments.t_end, "method": "DOP853", "backend": "compiled"}
    job = library.Job("", model.source, tuple(axes), (), section, tuple(sorted(options.items())))
    runner = library.runner_for(job, model)
    grid = library.points(axes)
    indices = list(range(len(grid)))
    batched = runner.batch(indices, grid)
    by_run = [row for k in indices for row in runner.run_point(k, grid[k])]
    assert repr(batched) == repr(by_run), "the two paths differ"

    def best(run) -> float:  # type: ignore[no-untyped-def]
        times = []
        for _ in range(arguments.repeat):
            began = time.process_time()
            run()
            times.append(time.process_time() - began)
        return min(times)

    one_call = best(lambda: runner.batch(indices, grid))
    each = best(lambda: [runner.run_point(k, grid[k]) for k in indices])
    crossings = len(batched)
    print(
        f"`benchmarks/section_bench.py --runs {arguments.runs} --t-end {arguments.t_end:g}` ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, os.getloadavg {', '.join(f'{x:.1f}' for x in os.getloadavg())}):"
    )
    print(f"{arguments.runs} elastic-pendulum runs, {crossings} rows (kept crossings), identical rows in both paths; CPU s, best of {arguments.repeat}:")
    print(f"batched (one compiled call) {one_call:.3f} s, run by run {each:.3f} s: {each / one_call:.2f}x")


if __name__ == "__main__":
    main()
