"""Simulation benchmarks (issue 4): lagrange's `simulate` against the peer workflow, at equal error.

    .venv/bin/python benchmarks/simulate_bench.py            # everything, about 3 minutes
    .venv/bin/python benchmarks/simulate_bench.py --quick    # no 10-link chain
    .venv/bin/python benchmarks/simulate_bench.py --write    # also update BENCHMARKS.md

1. Double pendulum, t = 0..10, final error 1e-8 against a reference (the hand-written
   equations, scipy DOP853 at rtol 1e-13, confirmed by lagrange's compiled DOP853 at rtol 1e-13):
   the peer (sympy.physics.mechanics LagrangesMethod + lambdify(cse=True) + solve_ivp, with
   RK45, DOP853 and LSODA), lagrange compiled (numba DOP853 and RK45) and through scipy, and the
   floor: the same compiled DOP853 loop with a hand-written compiled right-hand side.
2. 10-link chain (benchmarks/pendulum.py's state), t = 0..10, final error 1e-6, same contestants.
3. Double pendulum to t = 1e4: the symplectic method against compiled RK45 at rtol 1e-6,
   run time and relative energy error early and late in the run.

Each contestant runs a ladder of tolerances; the loosest one meeting the error is timed (the
minimum of several runs, after a warm-up), so every time is "at equal final error". One-time
costs (derivation, lambdify, numba compilation cold and cached) are reported separately.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT))

import pendulum  # noqa: E402

from lagrange_cli import derive, spec  # noqa: E402
from lagrange_cli.numeric import simulate  # noqa: E402

BEGIN, END = "<!-- simulate:begin -->", "<!-- simulate:end -->"
LADDER = [10.0**-k for k in range(5, 14)]


def best_time(run: Callable[[], Any], repeats: int = 5) -> float:
    """The minimum wall time of `run` over repeats, after one warm-up call."""
    run()
    times = []
    for _ in range(repeats):
        began = time.perf_counter()
        run()
        times.append(time.perf_counter() - began)
    return min(times)


def at_error(name: str, solve: Callable[[float], np.ndarray], y_ref: np.ndarray, target: float, repeats: int = 5) -> dict[str, Any]:
    """The loosest tolerance of the ladder whose final error is at most `target`, and its time."""
    for rtol in LADDER:
        error = float(np.max(np.abs(solve(rtol) - y_ref)))
        if error <= target:
            seconds = best_time(lambda rtol=rtol: solve(rtol), repeats)
            return {"name": name, "rtol": rtol, "error": error, "seconds": seconds}
    return {"name": name, "rtol": None, "error": None, "seconds": math.inf}


def peer(n: int) -> tuple[Callable[..., Any], float]:
    """The peer's rhs for the N-link pendulum, and its derivation + lambdify time."""
    import peer as sympy_peer

    began = time.perf_counter()
    mass, forcing, q = sympy_peer.derive(n)
    mass, forcing, qs, us = sympy_peer.plain(mass, forcing, q)
    rhs = sympy_peer.make_rhs(mass, forcing, qs, us)
    return rhs, time.perf_counter() - began


def model(n: int) -> Any:
    return derive.derive(spec.parse(pendulum.system_yaml(n), f"chain_{n}.yaml"))


def contestants(n: int, y0: list[float], t_end: float, y_ref: np.ndarray, target: float, peer_rhs: Callable[..., Any]) -> list[dict[str, Any]]:
    """Every contestant at equal final error."""
    from scipy.integrate import solve_ivp

    m = model(n)
    initial = dict(zip([*pendulum.coordinates(n), *(f"{c}_dot" for c in pendulum.coordinates(n))], y0, strict=True))
    rows = []
    for method in ("RK45", "DOP853", "LSODA"):

        def run_peer(rtol: float, method: str = method) -> np.ndarray:
            return solve_ivp(peer_rhs, (0, t_end), y0, method=method, rtol=rtol, atol=rtol * 1e-3).y[:, -1]

        rows.append(at_error(f"peer: LagrangesMethod + lambdify(cse) + solve_ivp {method}", run_peer, y_ref, target, repeats=2 if n > 2 else 5))
    for method, backend in (("DOP853", "compiled"), ("RK45", "compiled"), ("DOP853", "python")):

        def run_ours(rtol: float, method: str = method, backend: str = backend) -> np.ndarray:
            trajectory = simulate(m, t_end=t_end, method=method, backend=backend, rtol=rtol, atol=rtol * 1e-3, samples=2, initial=initial)
            run_ours.last = trajectory  # type: ignore[attr-defined]
            return trajectory.y[-1]

        row = at_error(f"lagrange simulate --method {method} --backend {backend} (simulate() call)", run_ours, y_ref, target)
        if row["rtol"] is not None:
            inner = []
            for _ in range(5):
                run_ours(row["rtol"])
                inner.append(run_ours.last.timing.run)  # type: ignore[attr-defined]
            row["integration_seconds"] = min(inner)
            row["nfev"] = run_ours.last.stats.nfev  # type: ignore[attr-defined]
        rows.append(row)
    if n == 2:
        rows.append(floor(y0, t_end, y_ref, target))
    return rows


def floor(y0: list[float], t_end: float, y_ref: np.ndarray, target: float) -> dict[str, Any]:
    """The same compiled DOP853 loop with a hand-written numba right-hand side (the floor)."""
    from numba import njit

    from lagrange_cli.numeric import compile as compiled

    kernels = compiled.kernels_module()

    @njit(kernels.ACCEL_SIG, cache=False)
    def accel(t: float, y: np.ndarray, p: np.ndarray, x: np.ndarray, a: np.ndarray) -> int:
        s, c = math.sin(y[0] - y[1]), math.cos(y[0] - y[1])
        f1 = -s * y[3] * y[3] - 2 * 9.81 * math.sin(y[0])
        f2 = s * y[2] * y[2] - 9.81 * math.sin(y[1])
        x[0] = (f1 - c * f2) / (2 - c * c)
        x[1] = (2 * f2 - c * f1) / (2 - c * c)
        return 0

    @njit(kernels.EVENT_SIG, cache=False)
    def event(t: float, y: np.ndarray, p: np.ndarray, x: np.ndarray, a: np.ndarray) -> float:
        return 1.0

    start, run = kernels.compiled("erk_start"), kernels.compiled("erk_run")

    def solve(rtol: float) -> np.ndarray:
        y, f, stats = np.array(y0), np.empty(4), np.array([0.0, 0, 0, 0, math.inf, 0])
        p, ts, ys, counters = np.zeros(1), np.array([t_end]), np.empty((1, 4)), np.zeros(1, dtype=np.int64)
        h0 = start(True, 0.0, y, f, t_end, math.inf, rtol, rtol * 1e-3, p, stats, 2, accel)
        state = np.array([0.0, h0, 1.0])
        run(True, y, f, state, ts, ys, counters, p, rtol, rtol * 1e-3, math.inf, t_end, t_end, False, stats, 2, accel, event)
        return ys[0]

    return at_error("floor: the compiled DOP853 loop + hand-written numba rhs", solve, y_ref, target)


def reference(rhs: Callable[..., Any], y0: list[float], t_end: float, n: int) -> tuple[np.ndarray, float]:
    """y(t_end) by scipy DOP853 at rtol 1e-13 on hand-written equations, and its disagreement
    with lagrange's compiled DOP853 at rtol 1e-13 (a second method on the generated equations)."""
    from scipy.integrate import solve_ivp

    y_ref = solve_ivp(rhs, (0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-15).y[:, -1]
    names = [*pendulum.coordinates(n), *(f"{c}_dot" for c in pendulum.coordinates(n))]
    check = simulate(model(n), t_end=t_end, method="DOP853", backend="compiled", rtol=1e-13, atol=1e-15, samples=2, initial=dict(zip(names, y0, strict=True)))
    return y_ref, float(np.max(np.abs(check.y[-1] - y_ref)))


def symplectic_study(t_end: float = 1e4) -> list[dict[str, Any]]:
    """Run time and relative energy error, early (first 10%) and late (last 10%)."""
    m = model(2)
    initial = {"th1": 1.0, "th2": 0.5}
    rows = []
    for label, kwargs in (
        ("RK45 compiled, rtol 1e-6, atol 1e-9", {"method": "RK45", "backend": "compiled", "rtol": 1e-6, "atol": 1e-9}),
        ("DOP853 compiled, rtol 1e-6, atol 1e-9", {"method": "DOP853", "backend": "compiled", "rtol": 1e-6, "atol": 1e-9}),
        ("symplectic (Gauss-Legendre 4), step 0.06", {"method": "symplectic", "step": 0.06}),
        ("symplectic (Gauss-Legendre 4), step 0.05", {"method": "symplectic", "step": 0.05}),
    ):
        runs = [simulate(m, t_end=t_end, samples=10001, initial=initial, **kwargs) for _ in range(3)]
        trajectory = runs[-1]
        error = np.abs(trajectory.energy - trajectory.energy[0]) / abs(trajectory.energy[0])
        tenth = len(error) // 10
        rows.append(
            {
                "name": label,
                "seconds": min(r.timing.run for r in runs[1:]),
                "energy_early": float(error[:tenth].max()),
                "energy_late": float(error[-tenth:].max()),
                "energy_max": float(error.max()),
                "nfev": trajectory.stats.nfev,
            }
        )
    return rows


def one_time_costs() -> dict[str, float]:
    """Wall times of the CLI: cold (empty cache: numba compiles everything) and warm."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "LAGRANGE_CACHE_DIR": cache}
        command = [str(Path(sys.executable).parent / "lagrange"), "simulate", "double_pendulum", "--backend", "compiled", "--method", "DOP853"]
        times = {}
        for label in ("cold", "warm"):
            began = time.perf_counter()
            subprocess.run(command, env=env, check=True, capture_output=True)
            times[label] = time.perf_counter() - began
        began = time.perf_counter()
        subprocess.run([*command[:3], "--backend", "python", "--method", "DOP853"], env=env, check=True, capture_output=True)
        times["python"] = time.perf_counter() - began
    return times


def table(rows: list[dict[str, Any]], best_peer: float) -> list[str]:
    lines = ["| contestant | rtol | final error | time | vs best peer |", "|---|---|---|---|---|"]
    for row in rows:
        seconds = row.get("integration_seconds", row["seconds"])
        inner = f" (integration {row['integration_seconds'] * 1e3:.3g} ms)" if "integration_seconds" in row else ""
        ratio = f"{best_peer / row['seconds']:.1f}x" + (f" ({best_peer / seconds:.0f}x)" if inner else "") if math.isfinite(row["seconds"]) else "-"
        error = f"{row['error']:.1e}" if row["error"] is not None else "not reached"
        lines.append(f"| {row['name']} | {row['rtol'] or '-'} | {error} | {row['seconds'] * 1e3:.3g} ms{inner} | {ratio} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="skip the 10-link chain")
    parser.add_argument("--write", action="store_true", help="write the results into BENCHMARKS.md")
    args = parser.parse_args()
    out = [
        "## Simulation (issue 4)",
        "",
        f"`{' '.join(['.venv/bin/python', 'benchmarks/simulate_bench.py', *sys.argv[1:]])}` on {os.cpu_count()} cores; times are minima over repeats after a warm-up.",
        "",
    ]
    results: dict[str, Any] = {}

    peer_rhs, peer_setup = peer(2)
    y0 = [1.0, 0.5, 0.0, 0.0]
    y_ref, disagreement = reference(pendulum.hand_rhs, y0, 10.0, 2)
    rows = contestants(2, y0, 10.0, y_ref, 1e-8, peer_rhs)
    best_peer = min(r["seconds"] for r in rows if r["name"].startswith("peer"))
    out += [
        "### Double pendulum, t = 0..10, final error <= 1e-8",
        "",
        f"Reference disagreement (scipy on hand-written equations vs compiled lagrange, both rtol 1e-13): {disagreement:.1e}. Peer derivation + lambdify: {peer_setup:.2f} s.",
        "",
    ]
    out += [*table(rows, best_peer), ""]
    results["double"] = rows

    if not args.quick:
        n = 10
        peer_rhs, peer_setup = peer(n)
        y0 = pendulum.state(n)
        y_ref, disagreement = reference(lambda t, y: pendulum.reference_rhs(list(y)), y0, 10.0, n)
        rows = contestants(n, y0, 10.0, y_ref, 1e-6, peer_rhs)
        best_peer = min(r["seconds"] for r in rows if r["name"].startswith("peer"))
        out += [
            "### 10-link chain, t = 0..10, final error <= 1e-6",
            "",
            f"Initial state `pendulum.state(10)`. Reference disagreement: {disagreement:.1e}. Peer derivation + lambdify: {peer_setup:.1f} s.",
            "",
        ]
        out += [*table(rows, best_peer), ""]
        results["chain"] = rows

    rows = symplectic_study()
    out += ["### Double pendulum to t = 1e4: energy", "", "| method | run time | rel. energy error, first 10% | last 10% | max | evaluations |", "|---|---|---|---|---|---|"]
    out += [f"| {r['name']} | {r['seconds']:.3g} s | {r['energy_early']:.1e} | {r['energy_late']:.1e} | {r['energy_max']:.1e} | {r['nfev']} |" for r in rows]
    results["symplectic"] = rows
    costs = one_time_costs()
    out += ["", "### One-time costs (CLI wall time, `lagrange simulate double_pendulum`)", ""]
    out += [
        f"- compiled, empty cache (numba compiles the loops and the system): {costs['cold']:.2f} s",
        f"- compiled, cached: {costs['warm']:.2f} s",
        f"- scipy path (no numba loaded): {costs['python']:.2f} s",
    ]
    results["one_time"] = costs
    text = "\n".join(out) + "\n"
    print(text)
    print(json.dumps(results, default=str), file=sys.stderr)
    if args.write:
        write_section(text)


def write_section(text: str) -> None:
    """Replace (or append) this benchmark's section of BENCHMARKS.md, between its markers."""
    path = ROOT / "BENCHMARKS.md"
    current = path.read_text() if path.exists() else "# Benchmarks\n"
    block = f"{BEGIN}\n{text}{END}\n"
    if BEGIN not in current or END not in current:
        path.write_text(current.rstrip("\n") + "\n\n" + block)
        return
    path.write_text(current[: current.index(BEGIN)] + block + current[current.index(END) + len(END) + 1 :])


if __name__ == "__main__":
    main()
