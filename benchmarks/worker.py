"""One measurement in a fresh interpreter: `python benchmarks/worker.py TASK ARGS...`.

Each task prints one line `RESULT <json>` last. Library imports happen before the clock
starts, so the times are of the work, not of importing sympy; every derivation runs in
its own process so that no run profits from caches warmed by another (sympy's cache in
particular).

Tasks:
    derive-lagrange N FILE          spec.load + derive.derive; M, F at the reference state
    derive-peer N [PICKLE]          LagrangesMethod; M, F at the reference state; optionally
                                    pickles M, F (plain symbols) for the rhs benchmark
    emit N FILE OUT                 spec.load + derive + python.emit, module written to OUT
    rhs N MODULE [PICKLE]           per-call time of the emitted rhs against its peer
"""

from __future__ import annotations

import importlib.util
import json
import sys
import time
import timeit
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pendulum


def result(value: dict[str, Any]) -> None:
    print("RESULT " + json.dumps(value), flush=True)


def model_numeric(model: Any, y: list[float]) -> tuple[list[list[float]], list[float]]:
    import sympy as sp

    n = model.n
    parameters = [p.symbol for p in model.parameters]
    f = sp.lambdify([list(model.q), list(model.qd), parameters], (model.mass_matrix.tolist(), list(model.forcing)), modules="math", cse=True)
    m, F = f(y[:n], y[n:], [pendulum.PARAMETERS[p.name] for p in model.parameters])
    return [[float(x) for x in row] for row in m], [float(x) for x in F]


def derive_lagrange(n: int, path: str) -> None:
    from lagrange_cli import derive, spec

    start = time.perf_counter()
    system = spec.load(Path(path))
    loaded = time.perf_counter()
    model = derive.derive(system)
    done = time.perf_counter()
    m, f = model_numeric(model, pendulum.state(n))
    result({"seconds": done - start, "load": loaded - start, "derive": done - loaded, "M": m, "F": f})


def derive_peer(n: int, save: str | None = None) -> None:
    import peer

    start = time.perf_counter()
    mass, forcing, q = peer.derive(n)
    done = time.perf_counter()
    mass, forcing, qs, us = peer.plain(mass, forcing, q)
    if save:
        import pickle

        Path(save).write_bytes(pickle.dumps((mass, forcing, qs, us)))
    m, f = peer.numeric(mass, forcing, qs, us, pendulum.state(n))
    result({"seconds": done - start, "M": m, "F": f})


def emit(n: int, path: str, out: str) -> None:
    from lagrange_cli import derive, spec
    from lagrange_cli.emit import python

    start = time.perf_counter()
    system = spec.load(Path(path))
    loaded = time.perf_counter()
    model = derive.derive(system)
    derived = time.perf_counter()
    code = python.emit(model)
    done = time.perf_counter()
    Path(out).write_text(code)
    Path(out).with_name(Path(out).stem + "_numba.py").write_text(python.emit(model, numba=True))
    result({"seconds": done - start, "load": loaded - start, "derive": derived - loaded, "emit": done - derived, "lines": code.count("\n")})


def load_module(path: str) -> Any:
    spec = importlib.util.spec_from_file_location(f"emitted_{Path(path).stem}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def per_call(candidates: dict[str, Callable[..., Any]], y: Any, rounds: int = 25, sample: float = 0.04) -> dict[str, float]:
    """Seconds per call rhs(0.0, y, p), min over `rounds` samples of ~`sample` s each.
    The candidates are sampled in turn within each round, so load drift hits them alike."""
    p = dict(pendulum.PARAMETERS)
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


def rhs(n: int, module_path: str, pickle_path: str | None = None) -> None:
    import numpy

    candidates: dict[str, Callable[..., Any]] = {"lagrange": load_module(module_path).rhs}
    compiled = Path(module_path).with_name(Path(module_path).stem + "_numba.py")
    info: dict[str, Any] = {}
    if compiled.exists():
        candidates["numba"] = load_module(str(compiled)).rhs
        start = time.perf_counter()
        candidates["numba"](0.0, pendulum.state(n), dict(pendulum.PARAMETERS))
        info["numba_first_call_seconds"] = time.perf_counter() - start
    if n == 2:
        candidates["hand"] = pendulum.hand_rhs
    if pickle_path:
        import pickle

        import peer

        mass, forcing, qs, us = pickle.loads(Path(pickle_path).read_bytes())
        start = time.perf_counter()
        candidates["peer"] = peer.make_rhs(mass, forcing, qs, us)
        info["peer_lambdify_seconds"] = time.perf_counter() - start
    y = pendulum.state(n)
    reference = pendulum.reference_rhs(y)
    scale = max(abs(v) for v in reference)
    info["max_error"] = {name: max(abs(float(a) - b) for a, b in zip(fn(0.0, list(y)), reference, strict=True)) / scale for name, fn in candidates.items()}
    if "peer" in candidates:
        peer_values = candidates["peer"](0.0, list(y))
        info["lagrange_vs_peer"] = max(abs(float(a) - float(b)) for a, b in zip(candidates["lagrange"](0.0, list(y)), peer_values, strict=True)) / scale
    info["list"] = per_call(candidates, list(y))
    info["ndarray"] = per_call(candidates, numpy.array(y))
    result(info)


TASKS: dict[str, Callable[..., None]] = {"derive-lagrange": derive_lagrange, "derive-peer": derive_peer, "emit": emit, "rhs": rhs}

if __name__ == "__main__":
    task, n, *rest = sys.argv[1:]
    TASKS[task](int(n), *rest)
