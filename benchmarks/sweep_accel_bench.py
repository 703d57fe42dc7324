"""Where a sweep's run spends its time (issue 18): the batch loop (numeric/ensemble.py) over the
double pendulum with the system's generated `accel` against the same loop with a hand-written
`accel` (closed-form 2x2 LDL^T solve instead of the generated code's pivoted, row-scaled LU),
and each `accel` alone in a tight compiled loop. CPU time of this process (time.process_time),
best of --repeat, the contestants interleaved; the steps taken and the final states are compared.

    .venv/bin/python benchmarks/sweep_accel_bench.py            # 2000 runs as in sweep_bench.py (rtol 1e-9, atol 1e-12, t = 10)

The hand-written accel is an experiment, not lagrange's code: it shows what the batch would gain
from a cheaper right-hand side (code generation), which no change of the batch loop can give.
The lanes (numeric/lanes.py, what a sweep runs now): the same runs LANES at a time in lockstep, the
generated `_accel_lanes` over the lanes in one vectorised loop; and `_accel_lanes` alone (LANES states a call).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from math import cos, sin
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import pendulum  # noqa: E402
from numba import njit  # noqa: E402

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli import sweep as library  # noqa: E402
from lagrange_cli.numeric import compile as compiled  # noqa: E402
from lagrange_cli.numeric import status as st  # noqa: E402

KERNELS = compiled.kernels_module()


@njit(KERNELS.ACCEL_SIG, error_model="numpy")
def closed_form(t, y, p, x, a):  # type: ignore[no-untyped-def]
    """The 2-link chain (absolute angles): M(q) q_ddot = b, M = l^2 m [[2, c], [c, 1]], solved by LDL^T."""
    m, length, g = p[0], p[1], p[2]
    s1, c1, s2, c2 = sin(y[0]), cos(y[0]), sin(y[1]), cos(y[1])
    sd, cd = s1 * c2 - s2 * c1, s1 * s2 + c1 * c2
    k0, k1 = length * length * m, g * length * m
    pk = k0 * sd
    a00, a01, a11 = 2 * k0, k0 * cd, k0
    b0 = -2 * k1 * s1 - pk * y[3] * y[3]
    b1 = pk * y[2] * y[2] - k1 * s2
    l10 = a01 / a00
    x1 = (b1 - l10 * b0) / (a11 - l10 * a01)
    x[1] = x1
    x[0] = b0 / a00 - l10 * x1
    return 0


@njit(error_model="numpy")
def tight(accel, y, p, x, a, n):  # type: ignore[no-untyped-def]
    """n calls of accel along a chain (each input depends on the last output, as the stages of a step do)."""
    for _ in range(n):
        accel(0.0, y, p, x, a)
        y[0] = 0.3 + 1e-12 * x[0]
        y[2] = 0.2 + 1e-12 * x[1]
    return y[0]


@njit(error_model="numpy")
def tight_lanes(accel_lanes, T, Y, P, X, S, active, n):  # type: ignore[no-untyped-def]
    """n calls of accel_lanes along a chain (as `tight`, every lane)."""
    for _ in range(n):
        accel_lanes(T, Y, P, X, S, active)
        for lane in range(Y.shape[1]):
            Y[0, lane] = 0.3 + 1e-12 * X[0, lane]
            Y[2, lane] = 0.2 + 1e-12 * X[1, lane]
    return Y[0, 0]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=2000)
    parser.add_argument("--repeat", type=int, default=3)
    arguments = parser.parse_args()
    text = pendulum.system_yaml(2)
    model = derive.derive(spec.parse(text, "chain_2.yaml"))
    q1, q2 = model.coordinates
    axes = [library.Axis("initial", q1, -1.5, 1.5), library.Axis("initial", q2, -1.5, 1.5)]
    options = {"t_end": 10.0, "rtol": 1e-9, "atol": 1e-12, "method": "DOP853", "backend": "compiled"}
    runner = library.runner_for(library.Job(text, "chain_2.yaml", tuple(axes), ("final",), None, tuple(sorted(options.items()))), model)
    starts = [runner.point(values) for values in library.points(axes, arguments.runs, seed=0)]
    y0s, ps = np.array([y for y, _ in starts]), np.array([p for _, p in starts])
    ts = np.array(runner.settings.t_eval, dtype=float)
    control = runner._control(runner.settings.t0, runner.settings.t_end)
    contestants = {"generated accel (pivoted LU)": runner.accel, "hand-written accel (closed-form LDL^T)": closed_form}
    best: dict[str, float] = dict.fromkeys(contestants, np.inf)
    alone: dict[str, float] = dict.fromkeys(contestants, np.inf)
    results = {}
    calls = 1_000_000
    for accel in contestants.values():
        runner.batch_entry(runner.pair, y0s[:2], ps[:2], control, ts, runner.budget, accel, runner.event)
        tight(accel, y0s[0].copy(), ps[0].copy(), np.empty(runner.size), np.empty((runner.size, runner.size)), 10)
    from lagrange_cli.numeric.lanes import LANES

    width = LANES
    lane_state = (np.zeros(width), np.ascontiguousarray(np.tile(y0s[0], (width, 1)).T), np.ascontiguousarray(np.tile(ps[0], (width, 1)).T))
    lane_work = (np.empty((runner.size, width)), np.empty(width), np.ones(width, dtype=np.int64))
    runner.lanes_entry(runner.pair, y0s[:2], ps[:2], control, ts, runner.budget, width, runner.accel, runner.lanes_accel)
    tight_lanes(runner.lanes_accel, *lane_state, *lane_work, 10)
    lane_best, lane_alone = np.inf, np.inf
    for _ in range(arguments.repeat):
        began = time.process_time()
        lane_results = runner.lanes_entry(runner.pair, y0s, ps, control, ts, runner.budget, width, runner.accel, runner.lanes_accel)
        lane_best = min(lane_best, time.process_time() - began)
        began = time.process_time()
        tight_lanes(runner.lanes_accel, *lane_state, *lane_work, calls // width)
        lane_alone = min(lane_alone, time.process_time() - began)
        for name, accel in contestants.items():
            began = time.process_time()
            results[name] = runner.batch_entry(runner.pair, y0s, ps, control, ts, runner.budget, accel, runner.event)
            best[name] = min(best[name], time.process_time() - began)
            began = time.process_time()
            tight(accel, y0s[0].copy(), ps[0].copy(), np.empty(runner.size), np.empty((runner.size, runner.size)), calls)
            alone[name] = min(alone[name], time.process_time() - began)
    # evaluations a run: run a sample one by one with the counters (the batch does not return them)
    evaluations = []
    for b in range(min(200, arguments.runs)):
        y, f, stats, state = y0s[b].copy(), np.empty(4), np.zeros(st.STATS_SIZE), np.zeros(st.STATE_SIZE)
        stats[st.HMIN] = np.inf
        state[st.H] = runner.start_entry(runner.pair, 0.0, y, f, control, ps[b], stats, runner.accel)
        state[st.EVENT_VALUE] = 1.0
        while runner.run_entry(runner.pair, y, f, state, control, ts, np.full((len(ts), 4), np.nan), ps[b], stats, runner.accel, runner.event) == st.RUNNING:
            pass
        evaluations.append(stats[st.NFEV])
    per_run = float(np.mean(evaluations))
    generated, hand = contestants
    print(
        f"`benchmarks/sweep_accel_bench.py --runs {arguments.runs}` ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, os.getloadavg {', '.join(f'{x:.1f}' for x in os.getloadavg())}), CPU time, best of {arguments.repeat}:"
    )
    print(f"{per_run:.0f} right-hand side evaluations a run (mean of {len(evaluations)} runs), {results[generated][4].mean():.2f} steps a run")
    for name in contestants:
        print(
            f"- {name}: batch {best[name] / arguments.runs * 1e3:.4f} ms a run ({best[name] / arguments.runs / per_run * 1e9:.1f} ns an evaluation); accel alone {alone[name] / calls * 1e9:.1f} ns a call"
        )
    print(
        f"- lanes ({width} runs in lockstep, `_accel_lanes`): batch {lane_best / arguments.runs * 1e3:.4f} ms a run ({lane_best / arguments.runs / per_run * 1e9:.1f} ns an evaluation;"
        f" {lane_results[5] / arguments.runs:.0f} lane evaluations a run, idle lanes included: {lane_best / lane_results[5] * 1e9:.1f} ns each); `_accel_lanes` alone"
        f" {lane_alone / (calls // width * width) * 1e9:.1f} ns a lane evaluation; {best[generated] / lane_best:.2f}x the batch with the generated accel"
    )
    same_steps = np.array_equal(results[generated][4], results[hand][4])
    gap = np.abs(results[generated][2] - results[hand][2]).max()
    print(
        f"batch with the hand-written accel {best[generated] / best[hand]:.2f}x faster; same steps in every run: {same_steps}; largest final-state difference {gap:.1e} (round-off, amplified by chaos)"
    )


if __name__ == "__main__":
    main()
