"""Issue 15 (one explicit loop): the compiled explicit loop before and after a change to kernels.py.

`kernels.erk_run`, `erk_switched` and `erk_projected` became one loop (`_erk_loop`). This measures
(1) the CPU time per step of compiled DOP853 plain runs (`integrators.run_erk`) with the kernels of a
git revision ("before"), of a second copy of them ("control": the same code compiled separately, so
placed elsewhere in memory: the spread that layout alone makes) and of the working tree ("after"),
interleaved in one process, ROUNDS rounds, the order rotating (time.process_time: the machine is shared; medians reported), and the two runs'
steps (they must be equal); (2) numba's first-time compile of each entry point, in a fresh process per
measurement with empty LAGRANGE_CACHE_DIR and NUMBA_CACHE_DIR (process_time of `kernels.compiled(name)`),
before and after interleaved.

    PYTHONPATH=. python benchmarks/erk_loop_bench.py [REVISION]    # REVISION: the "before" kernels (default main)
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli.numeric import compile, integrators, settings  # noqa: E402

ROUNDS = 9
SYSTEMS = [
    ("double pendulum", ROOT / "systems" / "double_pendulum.yaml", 2000.0, 1e-10),
    ("elastic pendulum", ROOT / "systems" / "elastic_pendulum.yaml", 2000.0, 1e-10),
]
ENTRIES = ("erk_run", "erk_switched", "erk_projected")


def kernels_at(revision: str, control: bool = False):  # type: ignore[no-untyped-def]
    """The kernels of `revision` as a module of their own; `control`: the same source with a comment added, a
    second copy of the same code (compiled separately: the spread between identical code placed elsewhere)."""
    text = subprocess.run(["git", "show", f"{revision}:lagrange_cli/numeric/kernels.py"], cwd=ROOT, check=True, capture_output=True, text=True).stdout
    return compile.cached_module("lagrange_kernels_bench_", text + ("\n# the layout control: the same code\n" if control else ""))


def per_step(revision: str) -> None:
    contestants = {"before": kernels_at(revision), "control": kernels_at(revision, control=True), "after": compile.kernels_module()}
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load {os.getloadavg()}; before = {revision}, after = working tree")
    print("| system | steps | before us/step (median) | after us/step (median) | after / before (median of rounds; min-max) | control / before (the same code compiled again; min-max) |")
    print("|---|---|---|---|---|---|")
    for name, path, t_end, rtol in SYSTEMS:
        model = derive.derive(spec.load(path))
        s = settings.validate(model, method="DOP853", backend="compiled", t_end=t_end, samples=1001, rtol=rtol)
        problem = integrators.Problem(s.t0, s.t_end, np.array(s.y0), np.array(s.t_eval), np.array(s.p), False, 10**7)
        numba = compile.build(model, "numba")
        functions = {who: dataclasses.replace(numba, kernels=k) for who, k in contestants.items()}
        steps = {who: integrators.run_erk(f, problem, "DOP853", s.rtol, s.atol, math.inf).stats.steps for who, f in functions.items()}  # warm: compiled or loaded
        assert steps["before"] == steps["after"] == steps["control"], steps
        times: dict[str, list[float]] = {who: [] for who in contestants}
        order = list(contestants)
        for r in range(ROUNDS):
            for who in order[r % 3 :] + order[: r % 3]:  # the order rotates
                began = time.process_time()
                run = integrators.run_erk(functions[who], problem, "DOP853", s.rtol, s.atol, math.inf)
                times[who].append((time.process_time() - began) / run.stats.steps)
        ratios = [a / b for a, b in zip(times["after"], times["before"], strict=True)]
        controls = [a / b for a, b in zip(times["control"], times["before"], strict=True)]
        print(
            f"| {name} (t_end {t_end:g}, rtol {rtol:g}) | {steps['after']} | {1e6 * statistics.median(times['before']):.3f} | {1e6 * statistics.median(times['after']):.3f} | "
            f"{statistics.median(ratios):.3f} ({min(ratios):.3f}-{max(ratios):.3f}) | {statistics.median(controls):.3f} ({min(controls):.3f}-{max(controls):.3f}) |",
            flush=True,
        )
    print(f"# load {os.getloadavg()}")


def compile_once(which: str, revision: str) -> None:
    """In a fresh process: compile each entry point (empty caches) and print the CPU seconds as JSON."""
    from lagrange_cli.numeric import kernels as _  # noqa: F401  (numba imported before timing)

    module = kernels_at(revision) if which == "before" else compile.kernels_module()
    out = {}
    for entry in ENTRIES:
        began = time.process_time()
        module.compiled(entry)
        out[entry] = time.process_time() - began
    print(json.dumps(out))


def compile_times(revision: str, rounds: int = 3) -> None:
    found: dict[str, list[dict[str, float]]] = {"before": [], "after": []}
    for r in range(rounds):
        for which in ("before", "after") if r % 2 == 0 else ("after", "before"):
            with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as numba_cache:
                env = dict(os.environ, LAGRANGE_CACHE_DIR=cache, NUMBA_CACHE_DIR=numba_cache, PYTHONPATH=str(ROOT))
                done = subprocess.run([sys.executable, __file__, "--compile", which, revision], env=env, check=True, capture_output=True, text=True)
                found[which].append(json.loads(done.stdout.strip().splitlines()[-1]))
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load {os.getloadavg()}; first-time compile (empty caches), CPU s, median of {rounds} fresh processes")
    print("| entry | before | after | after / before |")
    print("|---|---|---|---|")
    for entry in ENTRIES:
        b, a = statistics.median(x[entry] for x in found["before"]), statistics.median(x[entry] for x in found["after"])
        print(f"| {entry} | {b:.2f} | {a:.2f} | {a / b:.2f} |")
    b, a = statistics.median(sum(x.values()) for x in found["before"]), statistics.median(sum(x.values()) for x in found["after"])
    print(f"| all three | {b:.2f} | {a:.2f} | {a / b:.2f} |")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--compile":
        compile_once(sys.argv[2], sys.argv[3])
    else:
        revision = sys.argv[1] if len(sys.argv) > 1 else "main"
        per_step(revision)
        compile_times(revision)
