"""`--method auto` against every method on stiff, extreme and non-stiff cases; projection on long constrained runs.

    PYTHONPATH=. python benchmarks/auto_bench.py [--rounds 2] [--skip-projection] [--only "k=1e8"]

Whole runs through the library (`simulate`), interleaved (round r runs every method once before
round r + 1), the minimum over rounds kept. For each case: every method's CPU time for the whole
`simulate` call (time.process_time: the machine is shared; compile and code generation are done
in a warm-up first, so they are excluded: one-time costs kept in a cache), steps and right-hand
side evaluations. auto's memo is cleared before each of its runs, so its time includes its pilot
run, explicit probe and the compiled run it starts with (`policy.decide`, also timed on its own). Ratios are against the fastest
method that finished. The cases: the audit's (tests/numeric_audit_pilot, tests/numeric_audit2)
the bundled stiff springs and the other bundled stiff and extreme systems (README: the chaotic double
pendulum, the spherical pendulum near the pole, the sleeping top, Kapitza's pendulum; not the
multiplier pendulum: kept constraints, so `auto` cannot start compiled there, and scipy's implicit
methods over its t_end = 1000 take minutes); each file's own t_end.
The second part runs the multiplier pendulum to t = 1e4 with and without projection and
measures the error against the exact solution (the simple pendulum's elliptic-function formula).
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
from lagrange_cli.numeric import memo, policy  # noqa: E402
from lagrange_cli.numeric.simulate import simulate  # noqa: E402

AUDIT = ROOT / "tests" / "numeric_audit_pilot"
AUDIT2 = ROOT / "tests" / "numeric_audit2"
SYSTEMS = ROOT / "systems"
CASES = [
    ("cart, damping 1e6/s, moving", AUDIT / "cart_pendulum_damped.yaml", {}),
    ("cart, damping 1e6/s, at rest", AUDIT / "cart_pendulum_damped_rest.yaml", {}),
    ("stiff spring k=1e6 (undamped)", SYSTEMS / "stiff_spring_pendulum.yaml", {}),
    ("damped stiff spring k=1e8", SYSTEMS / "stiff_spring_pendulum_damped.yaml", {}),
    ("damped stiff spring k=1e10", SYSTEMS / "stiff_spring_pendulum_damped.yaml", {"k": 1e10}),
    ("damped elastic pendulum in r, k=1e10", AUDIT / "stiff_elastic_pendulum_r.yaml", {}),
    ("double pendulum (non-stiff)", AUDIT / "double_pendulum_nonstiff.yaml", {}),
    *((f"audit 2: {path.stem}", path, {}) for path in sorted(AUDIT2.glob("*.yaml"))),
    *((f"bundled: {name}", SYSTEMS / f"{name}.yaml", {}) for name in ("double_pendulum_chaotic", "spherical_pendulum_near_pole", "heavy_top", "kapitza_pendulum")),
]
METHODS = ["auto", "DOP853", "RK45", "Radau", "BDF", "LSODA"]
BUDGET = 3_000_000
IMPLICIT_FLOOR, IMPLICIT_OVER_AUTO = 5000, 50
"""scipy's implicit methods (Python steps, 80-300 us each) stop after 50 x auto's steps (at least
5000): beyond that they cannot be the fastest, and Radau on an undamped stiff spring would take minutes."""


def load(path: Path):  # type: ignore[no-untyped-def]
    return derive.derive(spec.load(path))


def bench_auto(rounds: int, only: str | None = None, warm_compiled: bool = False) -> None:
    warm = "; each system compiled in the warm-up (numba's code cached, as on a second call)" if warm_compiled else ""
    print(f"## auto against every method (each file's t_end; rtol 1e-8, atol 1e-10; min of {rounds} interleaved rounds; CPU seconds of the whole `simulate` call{warm})\n")
    print("| case | auto picks | auto steps | auto+pilot CPU s | decide CPU s (attempt, pilot, probe) | best method | best steps | best CPU s | auto+pilot / best |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, path, parameters in CASES:
        if only is not None and only not in name:
            continue
        model = load(path)
        for method in METHODS:  # warm: code generation and compilation out of the timed rounds
            simulate(model, method=method, parameters=parameters, samples=11, t_end=1e-3)
        if warm_compiled:
            simulate(model, method="DOP853", backend="compiled", parameters=parameters, samples=11, t_end=1e-3)
        best: dict[str, tuple[float, int, int, str, str]] = {}
        pilot_seconds = math.inf
        for _ in range(rounds):
            for method in METHODS:
                if method == "auto":
                    model.__dict__.pop(memo.SLOT, None)  # auto pays for its pilot and probe in every round
                cap = BUDGET if method in ("auto", "DOP853", "RK45") else max(IMPLICIT_FLOOR, IMPLICIT_OVER_AUTO * best.get("auto", (0, BUDGET))[1])
                began = time.process_time()
                run = simulate(model, method=method, parameters=parameters, samples=101, max_steps=cap)
                seconds = time.process_time() - began
                if run.status != "finished":
                    best.setdefault(method, (math.inf, run.stats.steps, run.stats.nfev, f"{run.settings.method} ({run.settings.backend})", f"{run.outcome} at t = {run.t_last:.3g}"))
                    continue
                if method not in best or seconds < best[method][0]:
                    best[method] = (seconds, run.stats.steps, run.stats.nfev, f"{run.settings.method} ({run.settings.backend})", run.status)
            model.__dict__.pop(memo.SLOT, None)
            settings = policy.validate(model, method="auto", parameters=parameters)
            began = time.process_time()
            policy.decide(model, settings)
            pilot_seconds = min(pilot_seconds, time.process_time() - began)
        others = {m: v for m, v in best.items() if m != "auto" and math.isfinite(v[0])}
        winner = min(others, key=lambda m: others[m][0])
        auto = best["auto"]
        w = others[winner]
        print(
            f"| {name} | {auto[3]} | {auto[1]} | {auto[0]:.3f} | {pilot_seconds:.3f} | {winner} | {w[1]} | {w[0]:.3f} | {auto[0] / w[0]:.2f} |",
            flush=True,
        )
        detail = ", ".join(f"{m} {v[0]:.3f} s/{v[1]} steps/{v[2]} fev" if math.isfinite(v[0]) else f"{m} {v[4]}" for m, v in best.items())
        print(f"|  | {detail} ||||||||", flush=True)


def exact_angle(t: np.ndarray, theta0: float = 1.0, g: float = 9.81) -> np.ndarray:
    from scipy.special import ellipj

    k = math.sin(theta0 / 2)
    _, cn, dn, _ = ellipj(math.sqrt(g) * t, k * k)
    return 2 * np.arcsin(k * cn / dn)  # type: ignore[no-any-return]


def bench_projection() -> None:
    print("\n## the multiplier pendulum to t = 1e4 (compiled DOP853, 1001 samples), error against the exact solution\n")
    model = load(SYSTEMS / "pendulum_multiplier.yaml")
    simple = load(SYSTEMS / "simple_pendulum.yaml")
    print("| rtol | projection | steps | run s | max error (x, y) | constraint residual | energy drift (rel.) | meets 1e-6 |")
    print("|---|---|---|---|---|---|---|---|")
    for rtol in (1e-8, 1e-10, 1e-12):
        for on in (False, True):
            run = simulate(model, t_end=1e4, method="DOP853", rtol=rtol, atol=rtol * 1e-2, samples=1001, projection=on, max_steps=10_000_000)
            theta = exact_angle(run.t)
            error = float(np.max(np.abs(run.y[:, :2] - np.column_stack([np.sin(theta), -np.cos(theta)]))))
            residual = next(i.max_change for i in run.invariants if i.kind == "constraint")
            energy = run.invariants[0].relative
            print(f"| {rtol:g} | {'on' if on else 'off'} | {run.stats.steps} | {run.timing.run:.2f} | {error:.2e} | {residual:.1e} | {energy:.1e} | {'yes' if error <= 1e-6 else 'no'} |", flush=True)
    check = simulate(simple, t_end=1e4, method="DOP853", rtol=2.5e-14, atol=1e-16, samples=1001, max_steps=10_000_000)
    print(f"\n(reference check: simple_pendulum.yaml at rtol 2.5e-14 differs from the exact formula by {float(np.max(np.abs(check.y[:, 0] - exact_angle(check.t)))):.1e} rad)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--skip-projection", action="store_true")
    parser.add_argument("--only", help="run only the cases whose name contains this text")
    parser.add_argument("--warm-compiled", action="store_true", help="compile each system in the warm-up (numba's code cached, as on a second call)")
    arguments = parser.parse_args()
    bench_auto(arguments.rounds, arguments.only, arguments.warm_compiled)
    if not arguments.skip_projection:
        bench_projection()


if __name__ == "__main__":
    main()
