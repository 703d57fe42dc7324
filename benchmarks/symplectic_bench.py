"""Symplectic benchmark (issue 15): long-run energy error of the Gauss method, and its cost against
compiled DOP853 at the same energy error.

    .venv/bin/python benchmarks/symplectic_bench.py                      # t = 1e5 (a few minutes)
    .venv/bin/python benchmarks/symplectic_bench.py --horizon 1e6        # the issue's horizon (long)
    .venv/bin/python benchmarks/symplectic_bench.py --horizon 1e4 --systems kepler
    .venv/bin/python benchmarks/symplectic_bench.py --horizon 1e6 --systems kepler --steps 3:0.25 --tolerances 1e-11,3e-12,1e-12

Whole runs through the library (`lagrange_cli.numeric.simulate.simulate`), compiled, on
- Kepler's problem with eccentricity 0.5 (systems/kepler.yaml from r = 1 at pericentre,
  theta_dot = sqrt(1.5)), and
- the double pendulum (systems/double_pendulum.yaml, its default state: regular, not chaotic).

For each: the symplectic method at the given stages and steps (`--steps 3:0.25,2:0.1`: 3 stages at
h = 0.25, 2 at h = 0.1; a bare step means 2 stages), and DOP853 at a ladder of rtol (atol = rtol /
100, half decades). Each run reports steps, right-hand side evaluations (counted, the samples'
included), CPU time of the process (time.process_time: the machine is shared, wall time is not the
run's own) and the loop's wall time, and the relative energy error: its maximum over the first 10% of
the run, over the whole run, and their ratio (the issue asks for at most 2 up to t = 1e6). Then, for
each symplectic run, the cheapest DOP853 run (in CPU time) whose maximum energy error is at most the
symplectic one's, and the cost ratios (symplectic / DOP853) in evaluations and CPU time.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli.numeric.simulate import simulate  # noqa: E402

SYSTEMS = {
    "kepler": ("kepler.yaml", {"theta_dot": math.sqrt(1.5)}, ((2, 0.1), (2, 0.05), (3, 0.25), (3, 0.2), (3, 0.125)), (1e-9, 1e-10, 3e-11, 1e-11, 3e-12, 1e-12, 3e-13)),
    "double_pendulum": ("double_pendulum.yaml", {}, ((2, 0.05), (2, 0.02), (3, 0.05), (3, 0.025)), (1e-9, 3e-10, 1e-10, 3e-11, 1e-11, 3e-12, 1e-12)),
}


def measure(model: object, horizon: float, initial: dict[str, float], samples: int, **options: object) -> dict[str, float]:
    began, cpu = time.perf_counter(), time.process_time()
    trajectory = simulate(model, t_end=horizon, samples=samples, initial=initial, max_steps=10**9, **options)  # type: ignore[arg-type]
    wall, cpu = time.perf_counter() - began, time.process_time() - cpu
    energy = trajectory.energy
    error = np.abs(energy - energy[0]) / max(abs(energy[0]), 1e-300)
    first = float(error[: max(2, len(error) // 10)].max())
    whole = float(error.max())
    return {
        "status": trajectory.status,
        "steps": trajectory.stats.steps,
        "nfev": trajectory.stats.nfev,
        "run": trajectory.timing.run,
        "wall": wall,
        "cpu": cpu,
        "first": first,
        "max": whole,
        "ratio": whole / first if first > 0 else math.inf,
        "last": float(error[-max(2, len(error) // 10) :].max()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--horizon", type=float, default=1e5, help="t_end of every run (default 1e5; the issue asks for 1e6)")
    parser.add_argument("--systems", default=",".join(SYSTEMS), help="comma-separated: " + ", ".join(SYSTEMS))
    parser.add_argument("--samples", type=int, default=20001, help="samples of each run (the energy is measured there)")
    parser.add_argument("--steps", help="comma-separated symplectic STAGES:STEP (or STEP: 2 stages; default: each system's own)")
    parser.add_argument("--tolerances", help="comma-separated DOP853 rtols (default: each system's own)")
    args = parser.parse_args()
    print(f"horizon t_end = {args.horizon:g}, {args.samples} samples")
    for name in args.systems.split(","):
        file, initial, steps, tolerances = SYSTEMS[name]
        steps = tuple((int(v.split(":")[0]), float(v.split(":")[1])) if ":" in v else (2, float(v)) for v in args.steps.split(",")) if args.steps else steps
        tolerances = tuple(float(v) for v in args.tolerances.split(",")) if args.tolerances else tolerances
        model = derive.derive(spec.load(ROOT / "systems" / file))
        for stages in {stages for stages, _ in steps}:
            simulate(model, method="symplectic", step=0.1, stages=stages, t_end=1.0, backend="compiled")  # compile (or load) outside the timing
        simulate(model, method="DOP853", t_end=1.0, backend="compiled")
        print(f"\n## {name} ({file}{', ' + str(initial) if initial else ''})")
        print(f"{'run':<22} {'status':<9} {'steps':>10} {'evals':>11} {'cpu s':>8} {'run s':>8} {'E err first10%':>15} {'E err max':>10} {'max/first':>9} {'last10%':>10}")
        results: dict[tuple[str, object], dict[str, float]] = {}
        for stages, step in steps:
            results[("symplectic", (stages, step))] = measure(model, args.horizon, initial, args.samples, method="symplectic", step=step, stages=stages, backend="compiled")
        for rtol in tolerances:
            results[("DOP853", rtol)] = measure(model, args.horizon, initial, args.samples, method="DOP853", rtol=rtol, atol=rtol / 100, backend="compiled")
        for (method, knob), r in results.items():
            label = f"Gauss{knob[0]} h={knob[1]:g}" if isinstance(knob, tuple) else f"{method} rtol={knob:g}"  # type: ignore[index]
            print(f"{label:<22} {r['status']:<9} {r['steps']:>10} {r['nfev']:>11} {r['cpu']:>8.2f} {r['run']:>8.2f} {r['first']:>15.3g} {r['max']:>10.3g} {r['ratio']:>9.2f} {r['last']:>10.3g}")
        print("\nsymplectic vs the cheapest DOP853 with an energy error at most as large:")
        for stages, step in steps:
            s = results[("symplectic", (stages, step))]
            matching = [(k, r) for k, r in results.items() if k[0] == "DOP853" and r["status"] == "finished" and r["max"] <= s["max"]]
            if not matching:
                print(f"  Gauss{stages} h={step:g}: no DOP853 run of the ladder reaches its energy error {s['max']:.3g}")
                continue
            key, d = min(matching, key=lambda item: item[1]["cpu"])
            print(
                f"  Gauss{stages} h={step:g} (E err {s['max']:.3g}) vs DOP853 rtol={key[1]:g} (E err {d['max']:.3g}): "
                f"evaluations x{s['nfev'] / d['nfev']:.2f}, CPU time x{s['cpu'] / d['cpu']:.2f}, run time x{s['run'] / d['run']:.2f}"
            )


if __name__ == "__main__":
    main()
