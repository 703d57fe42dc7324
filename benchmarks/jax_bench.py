"""JAX target benchmark (issue 16): `jax.vmap` of the generated `rhs` over 10^4 states against a
Python loop over the pure-Python module's `rhs`, both in the same run.

    .venv/bin/python benchmarks/jax_bench.py                    # double pendulum, general chain N = 2, 5, 10, 15
    .venv/bin/python benchmarks/jax_bench.py --states 2000 --sizes 2 5
    .venv/bin/python benchmarks/jax_bench.py --unrolled-max 0   # every solve by jnp.linalg.solve (the old code)
    .venv/bin/python benchmarks/jax_bench.py --no-kept          # nothing through `_kept` (XLA recomputes shared values)
    .venv/bin/python benchmarks/jax_bench.py --no-fast-trig     # jnp.sin and jnp.cos rather than the module's `_sincos`
    .venv/bin/python benchmarks/jax_bench.py --no-chunks        # rhs never through `_in_chunks` (the whole batch at once)
    .venv/bin/python benchmarks/jax_bench.py --keep-min 1       # `_kept` at every size (the module before `KEEP_MIN`)
    .venv/bin/python benchmarks/jax_bench.py --threads both     # XLA's default threads and one thread, each in its own process
    .venv/bin/python benchmarks/jax_bench.py --columns-min 1000 # never the module's `_spd_solve` (the unrolled solve up to UNROLLED_MAX)
    .venv/bin/python benchmarks/jax_bench.py --ab-columns-min 1000 --sizes 5 10 15 20   # that module against the default one,
                                                                # one process, interleaved rounds (CPU time medians)
    .venv/bin/python benchmarks/jax_bench.py --array-solve left # the first array solves tried (ARRAY_SOLVES; helper `jaxvec`): not kept

For each system: `derive --to jax` (64-bit mode) and `derive --to python`; 10^4 states drawn with
seed 0 (angles in [-1, 1], rates in [-1, 1]); the JAX side is `jax.jit(jax.vmap(rhs, (None, 0, None)))`
with its first call (tracing and XLA compilation) timed apart and excluded, then ROUNDS rounds of
`calls` back-to-back calls each (the last result waited for by `block_until_ready`; `calls` makes a round
last about ROUND_SECONDS by the fastest of 5 single calls, between 1 and MAX_CALLS calls, so that a 0.1 ms call is timed over about 20 ms,
not at the clock's and the dispatcher's resolution), reported as the median round's time per call; the
Python side (unchanged) is the best of LOOP_REPEATS loops over the states.
Times are CPU time (`time.process_time`, all threads of this process) and wall; XLA on CPU may use
more than one thread, so the CPU ratio is the fair one on a shared machine. The results agree to
1e-9 (checked). The generated module solves M q_ddot = F by unrolled L D L^T code for
n + k <= `jax.UNROLLED_MAX`, by `jnp.linalg.solve` above (`--unrolled-max` changes it here).

`--threads one` gives XLA's CPU client one thread for its loops: the process is restricted to one CPU while jax
creates the client (XLA sizes its intra-op thread pool by the CPUs the process may use, and splits each fused
loop over 10^4 states into that many parts) and given all of them back at once (the Python thread that
dispatches the next call still runs beside XLA's). `--threads both` runs this script in a subprocess per mode and
system, the modes interleaved (default, one, default, one, ... `--repeats` times each), and prints every row with
its mode. (XLA_FLAGS="--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1" does not do this: the
loops stay split in two, `outer_dimension_partitions` in the compiled HLO.)
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT))

import pendulum  # noqa: E402

ROUNDS = 15
ROUND_SECONDS = 0.02
MAX_CALLS = 200
LOOP_REPEATS = 3
ARRAY_SOLVES = {
    "right": '''
def _vec_kept(value):
    return value / (value * 0.0 + 1.0)


def _vec_solve(a, b):
    """a x = b for a symmetric positive definite (n, n) a: right-looking L D L^T on arrays (under jax.vmap each
    step is a few fused loops over (batch, n - k, n - k) elements), the trailing matrices stored (_vec_kept)."""
    n = a.shape[0]
    a, b = _vec_kept(a), _vec_kept(b)
    lows, pivots = [], []
    for _k in range(n):
        pivots.append(a[0, 0])
        if _k + 1 < n:
            _c = a[1:, 0]
            _l = _c / a[0, 0]
            lows.append(_l)
            a = _vec_kept(a[1:, 1:] - _l[:, None] * _c[None, :])
    z = []
    for _k in range(n):
        z.append(b[0])
        if _k + 1 < n:
            b = _vec_kept(b[1:] - lows[_k] * b[0])
    w = [z[_k] / pivots[_k] for _k in range(n)]
    x = w[n - 1][None]
    for _k in reversed(range(n - 1)):
        x = jnp.concatenate([(w[_k] - jnp.sum(lows[_k] * x))[None], x])
    return x
''',
    "left": '''
def _vec_kept(value):
    return value / (value * 0.0 + 1.0)


def _vec_last(a, b):
    """a (n, n, B), b (n, B), the batch last: left-looking L D L^T of the bordered [[a, b], [b^T, 0]] (its last
    row of L is D^-1 L^-1 b), one fused loop per column over (n - j, B) elements, then the back substitution."""
    n = a.shape[0]
    a = jnp.concatenate([a, b[None]], axis=0)
    lows, scaled = [], []
    for _j in range(n):
        _v = a[_j:, _j]
        for _k in range(_j):
            _v = _v - lows[_k][_j - _k - 1 :] * scaled[_k][_j - _k - 1]
        _v = _vec_kept(_v)
        scaled.append(_v[1:])
        lows.append(_v[1:] / _v[0])
    x = [None] * n
    for _j in reversed(range(n)):
        _s = lows[_j][n - _j - 1]
        for _i in range(_j + 1, n):
            _s = _s - lows[_j][_i - _j - 1] * x[_i]
        x[_j] = _vec_kept(_s) if _j else _s
    return jnp.stack(x)


@jax.custom_batching.custom_vmap
def _vec_solve(a, b):
    """a x = b; under jax.vmap the batch is moved last (one transpose) for _vec_last (values only: no derivative rule)."""
    return _vec_last(a[..., None], b[..., None])[..., 0]


@_vec_solve.def_vmap
def _vec_rule(size, batched, a, b):
    a = jnp.moveaxis(a, 0, -1) if batched[0] else jnp.broadcast_to(a[..., None], (*a.shape, size))
    b = jnp.moveaxis(b, 0, -1) if batched[1] else jnp.broadcast_to(b[..., None], (*b.shape, size))
    return jnp.moveaxis(_vec_last(a, b), -1, 0), True
''',
}
"""`--array-solve`: the generated module with `jnp.linalg.solve` (UNROLLED_MAX = 0) replaced by one of these
array solves (issue 16, helper `jaxvec`, BENCHMARKS.md: both slower than the unrolled solve at n = 15, so the
emitter does not write them; values only, for this benchmark). What the emitter writes instead is `_spd_solve`."""
ARRAY_SOLVE: str | None = None


def array_solved(code: str) -> str:
    """The module `code` (written with UNROLLED_MAX = 0) calling ARRAY_SOLVES[ARRAY_SOLVE] instead of jnp.linalg.solve."""
    assert ARRAY_SOLVE is not None and "jnp.linalg.solve(" in code
    code = code.replace("jnp.linalg.solve(", "_vec_solve(")
    if "\nimport jax\n" not in code:
        code = code.replace("\nimport jax.numpy as jnp\n", "\nimport jax\nimport jax.numpy as jnp\n", 1)
    return code + "\n" + ARRAY_SOLVES[ARRAY_SOLVE]


HEADER = f"| system | n | XLA threads | first call (compile), CPU / wall s | calls per round | vmap (median of {ROUNDS} rounds), CPU / wall ms | Python loop, CPU / wall ms | ratio CPU | ratio wall |"
RULE = "|---|---|---|---|---|---|---|---|---|"


def load(code: str, path: Path) -> ModuleType:
    path.write_text(code)
    found = importlib.util.spec_from_file_location(path.stem, path)
    assert found and found.loader
    module = importlib.util.module_from_spec(found)
    found.loader.exec_module(module)
    return module


def timed(function: Any) -> tuple[Any, float, float]:
    """(result, cpu seconds, wall seconds) of one call."""
    cpu, wall = time.process_time(), time.perf_counter()
    result = function()
    return result, time.process_time() - cpu, time.perf_counter() - wall


def bench(label: str, text: str, states: int, folder: Path) -> dict[str, Any]:
    import jax
    import jax.numpy as jnp

    from lagrange_cli import derive, spec
    from lagrange_cli.emit import jax as jax_target
    from lagrange_cli.emit import python

    model = derive.derive(spec.parse(text, f"{label}.yaml"))
    reference = load(python.emit(model), folder / f"{label}_py.py")
    code = jax_target.emit(model)
    target = load(array_solved(code) if ARRAY_SOLVE else code, folder / f"{label}_jax.py")
    rng = np.random.default_rng(0)
    y = rng.uniform(-1.0, 1.0, (states, 2 * model.n))
    batched = jax.jit(jax.vmap(target.rhs, in_axes=(None, 0, None)))
    ys = jnp.asarray(y)
    _, compile_cpu, compile_wall = timed(lambda: batched(0.0, ys, None).block_until_ready())
    once = min(timed(lambda: batched(0.0, ys, None).block_until_ready())[2] for _ in range(5))
    calls = max(1, min(MAX_CALLS, round(ROUND_SECONDS / max(once, 1e-9))))

    def round_of_calls() -> Any:
        for _ in range(calls - 1):
            batched(0.0, ys, None)
        return batched(0.0, ys, None).block_until_ready()

    rounds = [timed(round_of_calls) for _ in range(ROUNDS)]
    result = rounds[-1][0]
    vmap_cpu = statistics.median(cpu for _, cpu, _ in rounds) / calls
    vmap_wall = statistics.median(wall for _, _, wall in rounds) / calls
    rows = y.tolist()
    rhs = reference.rhs
    loop_cpu = loop_wall = float("inf")
    for _ in range(LOOP_REPEATS):
        loop, cpu, wall = timed(lambda: [rhs(0.0, row) for row in rows])
        loop_cpu, loop_wall = min(loop_cpu, cpu), min(loop_wall, wall)
    np.testing.assert_allclose(np.asarray(result), np.asarray(loop, dtype=float), rtol=1e-9, atol=1e-11)
    return {
        "system": label,
        "n": model.n,
        "compile": (compile_cpu, compile_wall),
        "vmap": (vmap_cpu, vmap_wall),
        "calls": calls,
        "loop": (loop_cpu, loop_wall),
    }


def ab_columns(sizes: list[int], other: int, states: int, rounds: int = 21, calls: int = 4) -> None:
    """The general chain of each size written with COLUMNS_MIN = `other` ("other") and as by default ("default"), both
    jitted in this process and timed in interleaved rounds of `calls` calls (CPU time, `time.process_time`); prints the
    median and the least round per call of each, and checks that the two agree."""
    import jax
    import jax.numpy as jnp

    from lagrange_cli import derive, spec
    from lagrange_cli.emit import jax as jax_target

    default = jax_target.COLUMNS_MIN
    print(f"interleaved in one process, {rounds} rounds of {calls} calls, {states} states, CPU ms per call (median / least), load average {os.getloadavg()}")
    print(f"| n | COLUMNS_MIN = {other} | COLUMNS_MIN = {default} (default) | default / other |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for n in sizes:
            model = derive.derive(spec.parse(pendulum.Chain("general", n).yaml(), f"chain_{n}.yaml"))
            functions = {}
            for label, value in (("other", other), ("default", default)):
                jax_target.COLUMNS_MIN = value
                module = load(jax_target.emit(model), Path(folder) / f"chain_{n}_{label}.py")
                functions[label] = jax.jit(jax.vmap(module.rhs, in_axes=(None, 0, None)))
            jax_target.COLUMNS_MIN = default
            ys = jnp.asarray(np.random.default_rng(0).uniform(-1.0, 1.0, (states, 2 * n)))
            results = {label: f(0.0, ys, None).block_until_ready() for label, f in functions.items()}
            np.testing.assert_allclose(np.asarray(results["default"]), np.asarray(results["other"]), rtol=1e-9, atol=1e-11)
            times: dict[str, list[float]] = {label: [] for label in functions}
            for _ in range(rounds):
                for label, f in functions.items():
                    start = time.process_time()
                    for _ in range(calls - 1):
                        f(0.0, ys, None)
                    f(0.0, ys, None).block_until_ready()
                    times[label].append((time.process_time() - start) / calls)
            cells = {label: f"{statistics.median(v) * 1e3:.3f} / {min(v) * 1e3:.3f}" for label, v in times.items()}
            ratio = statistics.median(times["default"]) / statistics.median(times["other"])
            print(f"| {n} | {cells['other']} | {cells['default']} | {ratio:.2f} |", flush=True)
    print(f"load average at the end {os.getloadavg()}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", type=int, default=10_000)
    parser.add_argument("--sizes", type=int, nargs="*", default=[2, 5, 10, 15])
    parser.add_argument("--unrolled-max", type=int, default=None, help="override lagrange_cli.emit.jax.UNROLLED_MAX (0: jnp.linalg.solve everywhere)")
    parser.add_argument("--no-kept", action="store_true", help="lagrange_cli.emit.jax.KEEP = False: nothing stored through `_kept` (XLA recomputes shared values)")
    parser.add_argument("--no-fast-trig", action="store_true", help="lagrange_cli.emit.jax.FAST_TRIG = False: jnp.sin and jnp.cos rather than `_sincos`")
    parser.add_argument("--no-chunks", action="store_true", help="lagrange_cli.emit.jax.CHUNKED_MIN = infinity: rhs evaluates the whole batch at once")
    parser.add_argument("--keep-min", type=int, default=None, help="override lagrange_cli.emit.jax.KEEP_MIN (1: `_kept` at every size)")
    parser.add_argument("--columns-min", type=int, default=None, help="override lagrange_cli.emit.jax.COLUMNS_MIN (1000: never `_spd_solve`)")
    parser.add_argument("--ab-columns-min", type=int, default=None, help="only: the chains of --sizes with this COLUMNS_MIN against the default, interleaved in one process")
    parser.add_argument("--array-solve", choices=sorted(ARRAY_SOLVES), default=None, help="the solve on arrays (ARRAY_SOLVES) instead of the unrolled one, at every n")
    parser.add_argument("--chunk", type=int, default=None, help="override lagrange_cli.emit.jax.CHUNK (states per chunk)")
    parser.add_argument(
        "--threads", choices=["default", "one", "both"], default="default", help="XLA's threads: its default, one (the client created on one CPU), or both modes interleaved in subprocesses"
    )
    parser.add_argument("--repeats", type=int, default=1, help="with --threads both: runs per mode and system")
    parser.add_argument("--only", default=None, help="only the system with this label (e.g. general_chain_15)")
    parser.add_argument("--no-header", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.threads == "both":
        both(args)
        return
    cpus = os.sched_getaffinity(0)
    if args.threads == "one":
        os.sched_setaffinity(0, {min(cpus)})
    import jax

    jax.config.update("jax_enable_x64", True)
    jax.devices()  # the CPU client and its thread pool, sized now
    os.sched_setaffinity(0, cpus)
    from lagrange_cli.emit import jax as jax_target

    if args.ab_columns_min is not None:
        ab_columns(args.sizes, args.ab_columns_min, args.states)
        return
    if args.unrolled_max is not None:
        jax_target.UNROLLED_MAX = args.unrolled_max
    jax_target.KEEP = not args.no_kept
    if args.no_chunks:
        jax_target.CHUNKED_MIN = 1 << 30
    if args.keep_min is not None:
        jax_target.KEEP_MIN = args.keep_min
    if args.chunk is not None:
        jax_target.CHUNK = args.chunk
    jax_target.FAST_TRIG = not args.no_fast_trig
    if args.columns_min is not None:
        jax_target.COLUMNS_MIN = args.columns_min
    if args.array_solve:
        jax_target.COLUMNS_MIN = 1 << 30
        global ARRAY_SOLVE
        ARRAY_SOLVE = args.array_solve
        jax_target.UNROLLED_MAX = 0
    systems = [("double_pendulum", (ROOT / "systems" / "double_pendulum.yaml").read_text())]
    systems += [(f"general_chain_{n}", pendulum.Chain("general", n).yaml()) for n in args.sizes]
    systems = [(label, text) for label, text in systems if args.only is None or label == args.only]
    if not args.no_header:
        print(
            f"jax {jax.__version__}, {args.states} states, unrolled solve for n + k <= {jax_target.UNROLLED_MAX}, _kept {'on' if jax_target.KEEP else 'off'}, _sincos {'on' if jax_target.FAST_TRIG else 'off'}, _kept from n + k = {jax_target.KEEP_MIN}, chunks of {jax_target.CHUNK} from n + k = {jax_target.CHUNKED_MIN}, XLA threads {args.threads}, `_spd_solve` from n = {jax_target.COLUMNS_MIN}, array solve {args.array_solve or 'no'}, load average {os.getloadavg()}"
        )
        print(HEADER)
        print(RULE)
    with tempfile.TemporaryDirectory() as folder:
        for label, text in systems:
            r = bench(label, text, args.states, Path(folder))
            (cc, cw), (vc, vw), (lc, lw) = r["compile"], r["vmap"], r["loop"]
            print(
                f"| {label} | {r['n']} | {args.threads} | {cc:.2f} / {cw:.2f} | {r['calls']} | {vc * 1e3:.3f} / {vw * 1e3:.3f} | {lc * 1e3:.0f} / {lw * 1e3:.0f} | {lc / vc:.0f}x | {lw / vw:.0f}x |",
                flush=True,
            )


def both(args: argparse.Namespace) -> None:
    """Each system in a subprocess per XLA thread mode (XLA_FLAGS is read once, when jax starts), the modes
    interleaved, `--repeats` times; the subprocesses get this run's other options."""
    forwarded = [f"--states={args.states}", "--no-header"]
    forwarded += [] if args.unrolled_max is None else [f"--unrolled-max={args.unrolled_max}"]
    forwarded += ["--no-kept"] * args.no_kept + ["--no-fast-trig"] * args.no_fast_trig + ["--no-chunks"] * args.no_chunks
    forwarded += [] if args.keep_min is None else [f"--keep-min={args.keep_min}"]
    forwarded += [] if args.chunk is None else [f"--chunk={args.chunk}"]
    forwarded += [] if args.columns_min is None else [f"--columns-min={args.columns_min}"]
    forwarded += [] if args.array_solve is None else [f"--array-solve={args.array_solve}"]
    labels = ["double_pendulum"] + [f"general_chain_{n}" for n in args.sizes]
    print(f"XLA threads: default and one (the CPU client created on one CPU), each system in its own process per mode, interleaved, {args.repeats} run(s) each, load average {os.getloadavg()}")
    print(HEADER)
    print(RULE, flush=True)
    for label in labels:
        for _ in range(args.repeats):
            for mode in ("default", "one"):
                command = [sys.executable, str(Path(__file__).resolve()), "--threads", mode, "--only", label, "--sizes", *map(str, args.sizes), *forwarded]
                subprocess.run(command, check=True)
    print(f"load average at the end {os.getloadavg()}")


if __name__ == "__main__":
    main()
