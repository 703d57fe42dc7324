"""Benchmarks of issue 5 (standalone; `make bench` runs it):

1. the damped stiff spring pendulum at k = 1e8: `--method auto` against scipy's default RK45
   (`RK45:python`), each over a ladder of tolerances in the same `lagrange accuracy` study; the
   time each needs to reach error 1e-6 (the fastest of its runs whose error is at most 1e-6);
2. the wall time of a full `lagrange accuracy double_pendulum` (5 methods x 6 tolerances) as a
   subprocess, after one warm-up so that numba's on-disk cache is filled.

    .venv/bin/python benchmarks/study_bench.py
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

TARGET = 1e-6


def stiff() -> None:
    from lagrange_cli import derive, spec
    from lagrange_cli.numeric import accuracy
    from lagrange_cli.numeric.accuracy import Candidate

    model = derive.derive(spec.load(ROOT / "systems" / "stiff_spring_pendulum_damped.yaml"))
    began = time.perf_counter()
    result = accuracy.study(
        model, candidates=[Candidate("auto"), Candidate("RK45", "python")], tolerances=[1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9], parameters={"k": 1e8}, repeats=3, max_steps=1_000_000
    )
    print(f"## 1. damped stiff spring pendulum, k = 1e8, t = 0..{result.t_end:g} (study took {time.perf_counter() - began:.1f} s)")
    print(f"reference: {result.reference.description}, own error {result.reference.own_error:.1e}")
    print("| method | ran | rtol | error | run time | steps | evaluations (Jacobians) |")
    print("|---|---|---|---|---|---|---|")
    for p in result.points:
        print(f"| {p.method} | {p.resolved} | {p.tolerance:.0e} | {p.error:.1e} | {p.seconds * 1e3:.3g} ms | {p.steps} | {p.nfev} ({p.njev}) | {'' if p.ok else p.status + ': ' + p.reason}")
    best = {}
    for method in ("auto", "RK45:python"):
        reaching = [p for p in result.points if p.method == method and p.ok and p.error <= TARGET]
        best[method] = min(reaching, key=lambda p: p.seconds) if reaching else None
    auto, rk45 = best["auto"], best["RK45:python"]
    if auto and rk45:
        ratio = rk45.seconds / auto.seconds
        print(
            f"\nerror <= {TARGET:.0e}: auto ({auto.resolved}, rtol {auto.tolerance:.0e}) {auto.seconds * 1e3:.3g} ms; scipy RK45 (rtol {rk45.tolerance:.0e}) {rk45.seconds * 1e3:.3g} ms: {ratio:.1f}x -> {'PASS' if ratio >= 5 else 'FAIL'} (target >= 5x)"
        )
    else:
        print(f"\nerror <= {TARGET:.0e} not reached by: {[m for m, p in best.items() if p is None]} -> FAIL")


def double_pendulum() -> None:
    command = [str(ROOT / ".venv" / "bin" / "lagrange"), "accuracy", "double_pendulum", "--method", "RK45,DOP853,Radau,BDF,LSODA", "--tolerances", "1e-3..1e-8"]
    subprocess.run(command, capture_output=True, check=True)  # warm-up: fills numba's cache
    began = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=True)
    seconds = time.perf_counter() - began
    print(f"\n## 2. `{' '.join(['lagrange', *command[1:]])}`")
    print(done.stdout)
    print(f"wall time {seconds:.1f} s on {os.cpu_count()} cores -> {'PASS' if seconds < 60 else 'FAIL'} (target < 60 s); load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    stiff()
    double_pendulum()
