"""Where stiffness is judged, per system and `stress` regime; and `auto` against every method where its choice moved.

    PYTHONPATH=. python benchmarks/stiffness_judgement.py judge FILE... [--json out.json]
    PYTHONPATH=. python benchmarks/stiffness_judgement.py auto FILE REGIME [--rounds 3]
    PYTHONPATH=. python benchmarks/stiffness_judgement.py measure FILE... [--json out.json]

`judge`: for each file and each of `stress`'s regimes but the long horizon (the defaults, high energy,
near singular; the long horizon's pilot is the defaults' one over 10 x the span): whether the reference
must be implicit (`reference.stiff_start`, from `auto`'s pilot run), the steps `stress` expects RK45 to
need for stability alone (`stress.stability_steps`: 0 when the pilot finds the system not stiff, and
an explicit run above 2 x its budget is not run), and what `simulate --method auto` picks there
(`policy.resolve`). Nothing is timed: run it in two trees (PYTHONPATH) and compare.

`measure`: `stress`'s diagnosis (`stress._measure`: decay x t_end, stiffness ratio, whether it finds the
regime stiff) along a trajectory of each of those regimes made here by scipy's LSODA at rtol 1e-8,
atol 1e-11, 2001 samples (not `stress`'s reference: the same states in both trees), without the
resampling of cond M peaks.

`auto`: `simulate` of one regime (its t_end, parameters and initial values; rtol 1e-8, atol 1e-10,
101 samples) by auto and by every method, interleaved over rounds, the minimum CPU time
(time.process_time: the machine is shared) of the whole `simulate` call kept, compile and code
generation done in a warm-up; auto's memo is cleared before each of its runs, so its time includes
its attempt, pilot and probe (as in benchmarks/auto_bench.py). scipy's Radau and BDF stop after
IMPLICIT_CAP steps.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli.numeric import memo, policy, reference, stress  # noqa: E402
from lagrange_cli.numeric.runs import Setup  # noqa: E402
from lagrange_cli.numeric.simulate import simulate  # noqa: E402

METHODS = ["auto", "DOP853", "RK45", "Radau", "BDF", "LSODA"]
BUDGET = 3_000_000
IMPLICIT_CAP = 20_000
"""scipy's Radau and BDF (Python steps, 0.1-0.3 ms each) stop after this many: on the regimes timed here
LSODA needs about 1600, so beyond that they cannot be the fastest (auto_bench.py's 50 x auto's steps let
Radau run for minutes where auto takes compiled DOP853's 1e6 steps)."""


def load(path: str):  # type: ignore[no-untyped-def]
    return derive.derive(spec.load(Path(path))).with_definitions()


def judge(files: list[str], out: str | None) -> None:
    import lagrange_cli

    print(f"lagrange_cli from {Path(lagrange_cli.__file__).parent}, load {os.getloadavg()[0]:.1f}\n")
    print("| file | regime | reference implicit (stiff_start) | RK45 stability steps | auto picks |")
    print("|---|---|---|---|---|")
    rows = {}
    for path in files:
        model = load(path)
        for regime in stress.regimes(model, ()):
            if regime.name.startswith("long"):
                continue
            setup = Setup(regime.t_end, (), regime.parameters, regime.initial)
            implicit = bool(reference.stiff_start(model, setup))
            steps = round(stress.stability_steps(model, setup, "RK45"))
            s = policy.resolve(model, method="auto", t_end=regime.t_end, parameters=dict(regime.parameters), initial=dict(regime.initial))
            picks = f"{s.method} ({s.backend})"
            rows[f"{Path(path).name} | {regime.name}"] = {"implicit": implicit, "rk45_stability_steps": steps, "auto": picks}
            print(f"| {Path(path).name} | {regime.name} | {implicit} | {steps} | {picks} |", flush=True)
    if out:
        Path(out).write_text(json.dumps(rows, indent=1))


CAP = 200_000
"""LSODA steps after which `measure` gives a regime up (Kepler started at r = 0.01 passes r ~ 1e-6)."""


def _trajectory(rhs, y0, t_end):  # type: ignore[no-untyped-def]
    """2001 samples of LSODA at rtol 1e-8, atol 1e-11 over [0, t_end]; (None, None) where it fails or takes over CAP steps."""
    import warnings

    import numpy as np
    import scipy.integrate

    times = np.linspace(0.0, t_end, 2001)
    out = [y0]

    def f(t, y):  # type: ignore[no-untyped-def]
        value = rhs(t, y)
        if value is None or not np.all(np.isfinite(value)):
            raise FloatingPointError
        return value

    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        solver = scipy.integrate.LSODA(f, 0.0, y0, t_end, rtol=1e-8, atol=1e-11)
        k, steps = 1, 0
        while k < len(times):
            if solver.status != "running" or steps >= CAP:
                return None, None
            t0 = solver.t
            try:
                solver.step()
            except FloatingPointError:  # a blow-up: no trajectory to t_end
                return None, None
            steps += 1
            if solver.status == "failed":
                return None, None
            dense = solver.dense_output()
            while k < len(times) and (times[k] <= solver.t or solver.status == "finished"):
                out.append(dense(times[k]) if times[k] >= t0 else dense(t0))
                k += 1
    return times, np.array(out)


def measure(files: list[str], out: str | None) -> None:
    import numpy as np

    from lagrange_cli.numeric import compile
    from lagrange_cli.numeric.settings import code_parameters

    print("| file | regime | decay x t_end | stiffness ratio | stiff finding |")
    print("|---|---|---|---|---|")
    rows = {}
    for path in files:
        model = load(path)
        for regime in stress.regimes(model, ()):
            if regime.name.startswith("long"):
                continue
            setup = Setup(regime.t_end, (), regime.parameters, regime.initial)
            s = reference.start_of(model, setup)
            rhs = policy.safe_rhs(compile.build(model, "python").module, code_parameters(s.values, 0.0 if model.constraints else None))
            times, states = _trajectory(rhs, np.array(s.y0), regime.t_end)
            if times is None:
                print(f"| {Path(path).name} | {regime.name} | - | - | (LSODA did not reach t_end: a blow-up, or over {CAP} steps) |", flush=True)
                continue
            found = stress._measure(model, setup, times, states, None, regime.t_end)
            stiff = next((f.kind for f in found.findings if f.kind.startswith("stiff")), "")
            rows[f"{Path(path).name} | {regime.name}"] = {"decay_x_t_end": found.decay_span, "stiffness_ratio": found.stiffness_ratio, "stiff": stiff}
            print(f"| {Path(path).name} | {regime.name} | {found.decay_span:.3g} | {found.stiffness_ratio:.3g} | {stiff or '-'} |", flush=True)
    if out:
        Path(out).write_text(json.dumps(rows, indent=1))


def bench_auto(path: str, which: str, rounds: int) -> None:
    model = load(path)
    regime = next(r for r in stress.regimes(model, ()) if r.name.startswith(which))
    common = {"t_end": regime.t_end, "parameters": dict(regime.parameters), "initial": dict(regime.initial), "rtol": 1e-8, "atol": 1e-10}
    print(f"{Path(path).name}, {regime.name}: t_end {regime.t_end:g}, initial {dict(regime.initial)}; load {os.getloadavg()[0]:.1f}")
    for method in METHODS:  # warm-up: code generation and compilation out of the timed rounds
        simulate(model, method=method, samples=11, **{**common, "t_end": 1e-3})
    simulate(model, method="DOP853", backend="compiled", samples=11, **{**common, "t_end": 1e-3})
    best: dict[str, tuple[float, int, str, str]] = {}
    for _ in range(rounds):
        for method in METHODS:
            if method == "auto":
                model.__dict__.pop(memo.SLOT, None)
            cap = BUDGET if method in ("auto", "DOP853", "RK45", "LSODA") else IMPLICIT_CAP
            began = time.process_time()
            run = simulate(model, method=method, samples=101, max_steps=cap, **common)
            seconds = time.process_time() - began
            ran = f"{run.settings.method} ({run.settings.backend})"
            if run.status != "finished":
                best.setdefault(method, (math.inf, run.stats.steps, ran, f"{run.outcome} at t = {run.t_last:.3g}"))
                continue
            if method not in best or seconds < best[method][0]:
                best[method] = (seconds, run.stats.steps, ran, run.status)
    others = {m: v for m, v in best.items() if m != "auto" and math.isfinite(v[0])}
    winner = min(others, key=lambda m: others[m][0])
    auto = best["auto"]
    print(f"auto picks {auto[2]}: {auto[1]} steps, {auto[0]:.3f} s CPU; best other {winner} {others[winner][0]:.3f} s; auto / best {auto[0] / others[winner][0]:.2f}")
    for m, v in best.items():
        print(f"  {m}: {v[2]}, {v[1]} steps, " + (f"{v[0]:.3f} s" if math.isfinite(v[0]) else v[3]))
    print(f"load {os.getloadavg()[0]:.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="what", required=True)
    j = sub.add_parser("judge")
    j.add_argument("files", nargs="+")
    j.add_argument("--json")
    m = sub.add_parser("measure")
    m.add_argument("files", nargs="+")
    m.add_argument("--json")
    a = sub.add_parser("auto")
    a.add_argument("file")
    a.add_argument("regime", help="the start of a regime's name: defaults, high, near")
    a.add_argument("--rounds", type=int, default=3)
    arguments = parser.parse_args()
    if arguments.what == "judge":
        judge(arguments.files, arguments.json)
    elif arguments.what == "measure":
        measure(arguments.files, arguments.json)
    else:
        bench_auto(arguments.file, arguments.regime, arguments.rounds)


if __name__ == "__main__":
    main()
