"""Checks and in-process measurements, each in a fresh interpreter: `python benchmarks/worker.py TASK ARGS...`.

Each task prints one line `RESULT <json>` last. run.py times whole processes itself (the
`lagrange` CLI and `peer.py`); this worker only looks at the modules they wrote:

    check KIND N MODULE                   the module against the hand-written reference
    rhs KIND N MODULE [PEER_MODULE]       per-call time of the module's rhs against the peer's
                                          (and the hand-written `math` rhs at N = 2)
    numba-first KIND N MODULE             import and first call of a `--numba` module (its
                                          numba compile when NUMBA_CACHE_DIR is empty), then check
"""

from __future__ import annotations

import importlib.util
import json
import math
import sys
import time
import timeit
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import pendulum

AGREE = 1e-9  # max relative deviation from the reference for a module to count as right
SEEDS = (2024, 2025, 2026)  # random states; the last one with perturbed parameters


def result(value: dict[str, Any]) -> None:
    print("RESULT " + json.dumps(value), flush=True)


def load_module(path: str | Path, name: str | None = None) -> Any:
    spec = importlib.util.spec_from_file_location(name or f"emitted_{Path(path).stem}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _floats(values: Any) -> list[float]:
    return [float(v) for v in (values.tolist() if hasattr(values, "tolist") else values)]


def _relative(found: Sequence[float], expected: Sequence[float]) -> float:
    if len(found) != len(expected):
        return math.inf
    scale = max(abs(v) for v in expected) or 1.0
    worst = max(abs(a - b) for a, b in zip(found, expected, strict=True))
    return worst / scale if math.isfinite(worst) else math.inf


def residual(mass: list[list[float]], force: list[float], accel: Sequence[float]) -> float:
    """Backward error of accelerations a for M a = F: |M a - F| / (|M| |a| + |F|) in the
    infinity norm. Independent of M's condition number, which grows large in long chains."""
    n = len(force)
    if len(accel) != n or not all(math.isfinite(v) for v in accel):
        return math.inf
    worst = max(abs(sum(mass[i][j] * accel[j] for j in range(n)) - force[i]) for i in range(n))
    norm_m = max(sum(abs(v) for v in row) for row in mass)
    return worst / (norm_m * max(abs(v) for v in accel) + max(abs(v) for v in force) or 1.0)


def check_module(module: Any, chain: pendulum.Chain) -> dict[str, Any]:
    """Evaluate a module's mass_matrix, forcing (when it has them) and rhs (y a list and a numpy
    array) at random states, the last with perturbed parameters, against the hand-written
    reference. `ok` is True when every deviation is below AGREE."""
    import numpy

    n = chain.n
    worst = {"M": 0.0, "F": 0.0, "rhs velocities": 0.0, "rhs residual": 0.0}
    has_matrices = hasattr(module, "mass_matrix") and hasattr(module, "forcing")
    if not has_matrices:
        del worst["M"], worst["F"]
    for k, seed in enumerate(SEEDS):
        y = pendulum.state(n, seed)
        p = chain.perturbed(seed) if k == len(SEEDS) - 1 else chain.parameters()
        mass, force = chain.reference_matrices(y, p)
        if has_matrices:
            found = [_floats(row) for row in module.mass_matrix(y[:n], p)]
            flat = [v for row in found for v in row] if len(found) == n else []
            worst["M"] = max(worst["M"], _relative(flat, [v for row in mass for v in row]))
            worst["F"] = max(worst["F"], _relative(_floats(module.forcing(y[:n], y[n:], p)), force))
        for given in (list(y), numpy.array(y)):
            out = _floats(module.rhs(0.0, given, p))
            if len(out) != 2 * n:
                worst["rhs velocities"] = math.inf
                continue
            worst["rhs velocities"] = max(worst["rhs velocities"], _relative(out[:n], y[n:]))
            worst["rhs residual"] = max(worst["rhs residual"], residual(mass, force, out[n:]))
    return {"deviation": worst, "ok": all(v < AGREE for v in worst.values()), "states": len(SEEDS)}


def check(kind: str, n: int, path: str) -> None:
    result(check_module(load_module(path), pendulum.Chain(kind, n)))


def per_call(candidates: dict[str, Callable[..., Any]], y: Any, p: dict[str, float], rounds: int = 25, sample: float = 0.04) -> dict[str, float]:
    """Seconds per call rhs(0.0, y, p), min over `rounds` samples of ~`sample` s each.
    The candidates are sampled in turn within each round, so load drift hits them alike."""
    timers = {name: timeit.Timer("rhs(t, y, p)", globals={"rhs": fn, "t": 0.0, "y": y, "p": p}) for name, fn in candidates.items()}
    numbers = {}
    for name, timer in timers.items():
        number, seconds = timer.autorange()
        numbers[name] = max(1, int(number * sample / seconds))
    best = dict.fromkeys(timers, float("inf"))
    for _ in range(rounds):
        for name, timer in timers.items():
            best[name] = min(best[name], timer.timeit(numbers[name]) / numbers[name])
    return best


class _Namespace:
    def __init__(self, rhs: Callable[..., Any]) -> None:
        self.rhs = rhs


def rhs(kind: str, n: int, module_path: str, peer_path: str | None = None) -> None:
    import numpy

    chain = pendulum.Chain(kind, n)
    modules: dict[str, Any] = {"lagrange": load_module(module_path)}
    if peer_path:
        modules["peer"] = load_module(peer_path, "peer_module")
    if n == 2:
        modules["hand"] = _Namespace(pendulum.hand_rhs)
    checks = {name: check_module(module, chain) for name, module in modules.items()}
    p = chain.parameters()
    y = pendulum.state(n)
    candidates = {name: module.rhs for name, module in modules.items()}
    result({"checks": checks, "list": per_call(candidates, list(y), p), "ndarray": per_call(candidates, numpy.array(y), p)})


def numba_first(kind: str, n: int, path: str) -> None:
    import numpy

    start = time.perf_counter()
    import numba  # noqa: F401

    imported = time.perf_counter()
    module = load_module(path)
    loaded = time.perf_counter()
    cpu = time.process_time()
    module.rhs(0.0, numpy.array(pendulum.state(n)))
    called = time.perf_counter()
    cpu = time.process_time() - cpu
    again = time.perf_counter()
    module.rhs(0.0, numpy.array(pendulum.state(n)))
    second = time.perf_counter() - again
    result(
        {
            "import numba": imported - start,
            "import module": loaded - imported,
            "first call": called - loaded,
            "first call cpu": cpu,
            "second call": second,
            "check": check_module(module, pendulum.Chain(kind, n)),
        }
    )


TASKS: dict[str, Callable[..., None]] = {"check": check, "rhs": rhs, "numba-first": numba_first}

if __name__ == "__main__":
    task, kind, n, *rest = sys.argv[1:]
    TASKS[task](kind, int(n), *rest)
