"""Issue 13's spatial chain: lagrange against sympy.physics.mechanics, whole processes, CPU time.

    .venv/bin/python benchmarks/spatial_bench.py                  # N = 2..6, peer at 2..4; writes BENCHMARKS.md
    .venv/bin/python benchmarks/spatial_bench.py --sizes 2,3 --peer-sizes 2 --no-write

The system is the general N-link spatial chain a user writes with the version 2 body keys
(benchmarks/spatial_chain_6.yaml is N = 6 of this family): link i turns by a ZYX body-fixed
sequence (a_i, b_i, c_i) relative to link i-1, its pivot at link i-1's tip, centre of mass at
-l_i/2 along its z axis, its own m_i and l_i and a full inertia tensor with products of inertia;
gravity along -z. 3N coordinates.

Every time is the CPU time (user + system, from wait4's rusage) of a WHOLE PROCESS:

- lagrange: `python -m lagrange_cli derive FILE --to python -o OUT` (fresh LAGRANGE_CACHE_DIR);
- the peer: `python benchmarks/spatial_bench.py peer kane|lagrange N OUT`: frames with
  `orient_body_fixed(parent, (a, b, c), 'ZYX')`, `locatenew` + `v2pt_theory`, `RigidBody` with
  an inertia dyadic, then `KanesMethod` (u = q_dot, gravity as loads) or `LagrangesMethod`
  (potential energies), then `lambdify(cse=True)` of M and F written out as a module.

Each process runs under RLIMIT_CPU (`--cpu-limit`, default 600 s) and is reported as "did not
finish within X s of CPU" when it hits it. Before any time is compared the modules are checked
(`check`, its own process): the accelerations solve(M, F) of every module agree at random states
(one with perturbed parameters) to 1e-8. Sub-commands used by the harness itself:

    spatial_bench.py yaml N                       the chain file
    spatial_bench.py peer kane|lagrange N OUT     the peer as a whole process
    spatial_bench.py check N MODULE...            accelerations of the modules agree
    spatial_bench.py rhs SPATIAL_N SPATIAL PLANAR per-call rhs, spatial vs planar chain of 3N links
    spatial_bench.py ops N                        operations of the generated rhs (and of M, F), same pair
"""

from __future__ import annotations

import argparse
import concurrent.futures
import datetime
import inspect
import json
import math
import os
import platform
import random
import resource
import shlex
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PYTHON = sys.executable
SIZES = (2, 3, 4, 5, 6)
PEER_SIZES = (2, 3, 4)
METHODS = ("kane", "lagrange")
CPU_LIMIT = 600.0
AGREE = 1e-8
BEGIN, END = "<!-- spatial:begin -->", "<!-- spatial:end -->"
G = 9.81


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


# -- the chain ---------------------------------------------------------------------------------


def parameters(n: int) -> dict[str, float]:
    """g, then m_i, l_i per link (the values of benchmarks/spatial_chain_6.yaml)."""
    values = {"g": G}
    for i in range(1, n + 1):
        values[f"m{i}"] = round(1.0 + 0.1 * i, 10)
        values[f"l{i}"] = round(0.5 + 0.05 * i, 10)
    return values


def coordinates(n: int) -> list[str]:
    return [f"{axis}{i}" for i in range(1, n + 1) for axis in "abc"]


def inertia_entries(m: str, ln: str) -> dict[str, str]:
    """The body-axes tensor about the centre of mass: Ixx, Iyy, Izz, Ixy, Iyz, Izx."""
    unit = f"{m}*{ln}**2"
    return {"xx": f"{unit}/12", "yy": f"{unit}/12", "zz": f"{unit}/50", "xy": f"{unit}/100", "yz": f"{unit}/200", "zx": "0"}


def chain_yaml(n: int) -> str:
    values = ", ".join(f"{k}: {v!r}" for k, v in parameters(n).items())
    lines = [
        f"title: {n}-link spatial chain (ZYX orientations relative to the previous link, full inertia)",
        "description: Each link turns by a ZYX sequence relative to the one before, its pivot at the previous link's tip; full inertia tensors with products of inertia.",
        f"coordinates: [{', '.join(coordinates(n))}]",
        f"parameters: {{{values}}}",
        "gravity: [0, 0, -g]",
        "bodies:",
    ]
    for i in range(1, n + 1):
        m, ln = f"m{i}", f"l{i}"
        e = inertia_entries(m, ln)
        tensor = f"[[{e['xx']}, {e['xy']}, {e['zx']}], [{e['xy']}, {e['yy']}, {e['yz']}], [{e['zx']}, {e['yz']}, {e['zz']}]]"
        relative = f", relative_to: link{i - 1}" if i > 1 else ""
        lines += [
            f"  link{i}:",
            f"    mass: {m}",
            f"    orientation: {{sequence: ZYX, angles: [a{i}, b{i}, c{i}]{relative}}}",
            f"    pivot: {f'link{i - 1}.tip' if i > 1 else '[0, 0, 0]'}",
            f"    center: [0, 0, -{ln}/2]",
            f"    points: {{tip: [0, 0, -{ln}]}}",
            f"    inertia: {tensor}",
        ]
    lines.append("initial: {a1: 0.3, b1: 0.2" + (", c2: 0.5" if n > 1 else "") + "}")
    return "\n".join(lines) + "\n"


# -- the peer (its own process) ------------------------------------------------------------------

MODULE = '''"""{title}: M and F by sympy.physics.mechanics ({method}) and sympy.lambdify(modules="numpy", cse=True)."""

import numpy
from numpy import *  # noqa: F403 (the namespace lambdify(modules="numpy") evaluates in)

N = {n}
PARAMETERS = {parameters!r}
NAMES = {names!r}

{source}

_evaluate = {function}
_solve, _concatenate = numpy.linalg.solve, numpy.concatenate


def mass_matrix(q, p=PARAMETERS):
    return _evaluate(q, [0.0] * N, [p[k] for k in NAMES])[0]


def forcing(q, q_dot, p=PARAMETERS):
    return _evaluate(q, q_dot, [p[k] for k in NAMES])[1][:, 0]


def rhs(t, y, p=PARAMETERS):
    m, f = _evaluate(y[:N], y[N:], [p[k] for k in NAMES])
    return _concatenate((y[N:], _solve(m, f[:, 0])))
'''


def peer_derive(method: str, n: int) -> tuple[Any, Any, list[Any], list[Any], list[Any]]:
    """M and F of M q_ddot = F by KanesMethod (u_i = q_i') or LagrangesMethod, in plain symbols
    (q, u, parameters)."""
    import sympy as sp
    from sympy.physics.mechanics import KanesMethod, LagrangesMethod, Lagrangian, Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia

    symbols = {name: sp.Symbol(name, positive=True) for name in parameters(n)}
    g = symbols["g"]
    q = list(dynamicsymbols(" ".join(coordinates(n))))
    world = ReferenceFrame("N")
    origin = Point("O")
    origin.set_vel(world, 0)
    parent, pivot = world, origin
    bodies, loads = [], []
    for i in range(1, n + 1):
        m, ln = symbols[f"m{i}"], symbols[f"l{i}"]
        frame = ReferenceFrame(f"B{i}")
        frame.orient_body_fixed(parent, tuple(q[3 * i - 3 : 3 * i]), "ZYX")
        center = pivot.locatenew(f"C{i}", -ln / 2 * frame.z)
        center.v2pt_theory(pivot, world, frame)
        tip = pivot.locatenew(f"T{i}", -ln * frame.z)
        tip.v2pt_theory(pivot, world, frame)
        unit = m * ln**2
        dyadic = inertia(frame, unit / 12, unit / 12, unit / 50, unit / 100, unit / 200, 0)
        body = RigidBody(f"link{i}", center, frame, m, (dyadic, center))
        body.potential_energy = m * g * center.pos_from(origin).dot(world.z)
        bodies.append(body)
        loads.append((center, -m * g * world.z))
        parent, pivot = frame, tip
    t = dynamicsymbols._t
    if method == "kane":
        u = list(dynamicsymbols(" ".join("u_" + c for c in coordinates(n))))
        kane = KanesMethod(world, q_ind=q, u_ind=u, kd_eqs=[qi.diff(t) - ui for qi, ui in zip(q, u, strict=True)])
        kane.kanes_equations(bodies, loads)
        mass, force, speeds = kane.mass_matrix, kane.forcing, u
    else:
        lagrange = LagrangesMethod(Lagrangian(world, *bodies), q)
        lagrange.form_lagranges_equations()
        mass, force, speeds = lagrange.mass_matrix, lagrange.forcing, [qi.diff(t) for qi in q]
    qs = list(sp.symbols(coordinates(n)))
    us = list(sp.symbols([c + "_dot" for c in coordinates(n)]))
    mapping = {**{qi.diff(t): ui for qi, ui in zip(q, us, strict=True)}, **dict(zip(speeds, us, strict=True)), **dict(zip(q, qs, strict=True))}
    return mass.xreplace(mapping), force.xreplace(mapping), qs, us, list(symbols.values())


def peer(method: str, n: str, out: str) -> None:
    start = time.perf_counter()
    import sympy as sp
    import sympy.physics.mechanics

    phases = {"import": time.perf_counter() - start}
    size = int(n)
    start = time.perf_counter()
    mass, force, qs, us, symbols = peer_derive(method, size)
    phases["derive"] = time.perf_counter() - start
    start = time.perf_counter()
    function = sp.lambdify([qs, us, symbols], (mass, force), modules="numpy", cse=True)
    source = inspect.getsource(function)
    phases["lambdify"] = time.perf_counter() - start
    names = [str(s) for s in symbols]
    title = f"{size}-link spatial chain"
    text = MODULE.format(
        title=title, method={"kane": "KanesMethod", "lagrange": "LagrangesMethod"}[method], n=3 * size, parameters=parameters(size), names=names, source=source, function=function.__name__
    )
    Path(out).write_text(text)
    print("RESULT " + json.dumps({"phases": phases, "lines": text.count("\n")}), flush=True)


# -- checks and per-call times (each its own process) --------------------------------------------


def load_module(path: str | Path, name: str) -> Any:
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def states(n: int) -> list[tuple[list[float], dict[str, float]]]:
    """Three random states of the 3N coordinates and velocities; the last with every parameter
    scaled by 0.7..1.3."""
    rng = random.Random(1300 + n)
    found = []
    for k in range(3):
        y = [rng.uniform(-1.2, 1.2) for _ in range(6 * n)]
        p = parameters(n)
        if k == 2:
            p = {name: value * rng.uniform(0.7, 1.3) for name, value in p.items()}
        found.append((y, p))
    return found


def check(n: str, *paths: str) -> None:
    """solve(M, F) of every module, and the accelerations of each module's rhs, against the
    first module's: the largest |a - a_first| / max(1, |a_first|)."""
    import numpy

    size = 3 * int(n)
    modules = [load_module(path, f"module{k}") for k, path in enumerate(paths)]
    worst = [0.0] * len(modules)
    worst_rhs = [0.0] * len(modules)
    for y, p in states(int(n)):
        q, qd = numpy.array(y[:size]), numpy.array(y[size:])
        found = []
        for k, module in enumerate(modules):
            mass = numpy.array(module.mass_matrix(q, p), dtype=float).reshape(size, size)
            force = numpy.array(module.forcing(q, qd, p), dtype=float).reshape(size)
            found.append(numpy.linalg.solve(mass, force))
            out = numpy.array(module.rhs(0.0, numpy.array(y), p), dtype=float)
            worst_rhs[k] = max(worst_rhs[k], float(numpy.max(numpy.abs(out[size:] - found[k]))) / max(1.0, float(numpy.max(numpy.abs(found[k])))))
        scale = max(1.0, float(numpy.max(numpy.abs(found[0]))))
        for k, a in enumerate(found):
            worst[k] = max(worst[k], float(numpy.max(numpy.abs(a - found[0]))) / scale)
    ok = all(v < AGREE for v in worst + worst_rhs)
    print("RESULT " + json.dumps({"deviation": worst, "rhs": worst_rhs, "ok": ok}), flush=True)


def rhs(n: str, spatial: str, planar: str) -> None:
    """Per-call seconds of rhs(0.0, y, p) of the spatial chain's module (3N coordinates) and the
    planar general chain's module with 3N links, y a list and a numpy array (worker.per_call)."""
    import numpy
    import pendulum
    import worker

    size = 3 * int(n)
    chain = pendulum.Chain("general", size)
    modules = {"spatial": load_module(spatial, "spatial"), "planar": load_module(planar, "planar")}
    planar_check = worker.check_module(modules["planar"], chain)
    y_spatial, p_spatial = states(int(n))[0]
    y_planar = pendulum.state(size)
    found: dict[str, Any] = {"planar check": planar_check["ok"]}
    for kind, convert in (("list", list), ("ndarray", numpy.array)):
        ys, yp = convert(y_spatial), convert(y_planar)
        spatial_rhs, planar_rhs, pp = modules["spatial"].rhs, modules["planar"].rhs, chain.parameters()
        # sampled in turn within each round (worker.per_call), so load drift hits both alike; each with its own y and p
        found[kind] = worker.per_call({"spatial": lambda t, y, p, f=spatial_rhs, ys=ys: f(t, ys, p_spatial), "planar": lambda t, y, p, f=planar_rhs, yp=yp, pp=pp: f(t, yp, pp)}, None, {})
    print("RESULT " + json.dumps(found), flush=True)


def operations(source: str) -> int:
    """Arithmetic operations and calls in a generated module's `rhs` (its solve helper not counted)."""
    import ast

    tree = ast.parse(source)
    function = next(node for node in tree.body if isinstance(node, ast.FunctionDef) and node.name == "rhs")
    return sum(isinstance(node, ast.BinOp | ast.UnaryOp | ast.Call) for node in ast.walk(function))


def ops(n: str) -> None:
    """Operations of lagrange's generated rhs (as `derive --to python` writes it) for the spatial chain of N links
    and the planar general chain of 3N links, and of M alone and F alone (each CSE'd by itself): where the work goes,
    independent of machine load."""
    import pendulum

    from lagrange_cli import derive, spec
    from lagrange_cli.emit import python

    found: dict[str, dict[str, int]] = {}
    for kind, text in (("spatial", chain_yaml(int(n))), ("planar", pendulum.Chain("general", 3 * int(n)).yaml())):
        model = derive.derive(spec.parse(text, f"{kind}.yaml"), shared=True)
        forms, size = model.symengine, model.n
        constants = {p.name for p in model.parameters}
        velocities = {str(v) for v in forms.qd}
        counts = {"rhs": operations(python.emit(model))}
        for part, exprs in (("M", [forms.mass[i][j] for i in range(size) for j in range(i, size)]), ("F", list(forms.forcing))):
            lines, results = python.code_lines(python.PythonPrinter(python.symbol_names(model)), exprs, constants, velocities)
            code = "\n".join(f"{name} = {value}" for name, value in lines) + "\n" + "\n".join(f"_ = {r}" for r in results)
            counts[part] = operations("def rhs():\n" + "\n".join("    " + line for line in code.splitlines()))
        found[kind] = counts
    print("RESULT " + json.dumps(found), flush=True)


# -- running whole processes ---------------------------------------------------------------------


class Runner:
    """Whole processes, the tree under test on PYTHONPATH, a fresh cache each, RLIMIT_CPU, and the
    CPU time of exactly that process (wait4's rusage: user + system)."""

    def __init__(self, tree: Path, tmp: Path, cpu_limit: float) -> None:
        self.tree, self.tmp, self.cpu_limit = tree, tmp, cpu_limit
        self.count = 0
        self.lock = threading.Lock()

    def env(self) -> dict[str, str]:
        with self.lock:
            self.count += 1
            cache = self.tmp / "caches" / str(self.count)
        cache.mkdir(parents=True)
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR")}
        return {**env, "PYTHONPATH": f"{self.tree}{os.pathsep}{HERE}", "LAGRANGE_CACHE_DIR": str(cache / "lagrange"), "NUMBA_CACHE_DIR": str(cache / "numba")}

    def run(self, command: Sequence[str]) -> dict[str, Any]:
        limit = int(self.cpu_limit)

        def cap() -> None:
            resource.setrlimit(resource.RLIMIT_CPU, (limit, limit + 5))

        env = self.env()
        with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
            start = time.perf_counter()
            process = subprocess.Popen(list(command), stdout=out, stderr=err, text=True, cwd=self.tmp, env=env, start_new_session=True, preexec_fn=cap)
            guard = threading.Timer(8 * self.cpu_limit + 60, lambda: os.killpg(process.pid, signal.SIGKILL))  # a process stuck off the CPU
            guard.start()
            try:
                _, status, usage = os.wait4(process.pid, 0)
            finally:
                guard.cancel()
            process.returncode = os.waitstatus_to_exitcode(status)
            wall = time.perf_counter() - start
            cpu = usage.ru_utime + usage.ru_stime
            out.seek(0)
            err.seek(0)
            stdout, stderr = out.read(), err.read()
        if process.returncode == -signal.SIGXCPU or (process.returncode == -signal.SIGKILL and cpu >= limit - 1):
            return {"error": f"did not finish within {limit} s of CPU", "limit": True, "cpu": cpu, "seconds": wall}
        if process.returncode != 0:
            lines = [line.strip() for line in stderr.splitlines() if line.strip()]
            return {"error": f"exit {process.returncode}: " + (lines[-1] if lines else "no output")[:300], "cpu": cpu, "seconds": wall, "stderr": stderr[-3000:]}
        value: dict[str, Any] = {"seconds": wall, "cpu": cpu}
        for line in reversed(stdout.splitlines()):
            if line.startswith("RESULT "):
                value.update(json.loads(line[len("RESULT ") :]))
                break
        return value

    def me(self, *args: object) -> dict[str, Any]:
        return self.run([PYTHON, str(Path(__file__).resolve()), *map(str, args)])


# -- the report ----------------------------------------------------------------------------------


def seconds(value: float | None) -> str:
    if value is None or math.isnan(value):
        return "-"
    if value >= 1:
        return f"{value:.2f} s"
    if value >= 1e-3:
        return f"{value * 1e3:.1f} ms"
    return f"{value * 1e6:.1f} µs"


def ratio(value: float | None) -> str:
    return "-" if value is None else (f"{value:.0f}x" if value >= 20 else f"{value:.2f}x")


def table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    return "\n".join(lines + ["| " + " | ".join(str(c) for c in row) + " |" for row in rows])


def power_fit(points: Sequence[tuple[int, float]]) -> tuple[float, float] | None:
    """t = c N^k by least squares in log-log; (c, k)."""
    if len(points) < 2:
        return None
    xs = [math.log(n) for n, _ in points]
    ys = [math.log(t) for _, t in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    k = sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True)) / sum((x - mx) ** 2 for x in xs)
    return math.exp(my - k * mx), k


def cell(value: dict[str, Any] | None) -> str:
    if value is None:
        return "not run"
    if "error" in value:
        return str(value["error"]).replace("|", "/")
    return f"{seconds(value['cpu'])} (wall {seconds(value['seconds'])})"


def git(*args: str) -> str:
    try:
        return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def machine() -> str:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    versions = ", ".join(f"{p} {metadata.version(p)}" for p in ("sympy", "symengine", "numpy"))
    return f"{cpu}, {os.cpu_count()} cores (shared with other work); {platform.platform()}; Python {platform.python_version()}; {versions}; lagrange commit {git('rev-parse', '--short', 'HEAD') or 'unknown'}"


def bench(args: argparse.Namespace) -> str:
    started = datetime.datetime.now(datetime.timezone.utc)
    clock = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix="lagrange-spatial-"))
    runner = Runner(ROOT, tmp, args.cpu_limit)
    subprocess.run([PYTHON, "-m", "compileall", "-q", str(ROOT / "lagrange_cli")], capture_output=True, check=False)  # as an install does
    ours: dict[int, dict[str, Any]] = {}
    theirs: dict[tuple[str, int], dict[str, Any]] = {}
    files: dict[int, Path] = {}
    for n in args.sizes:
        files[n] = tmp / f"spatial_chain_{n}.yaml"
        files[n].write_text(chain_yaml(n))
    jobs: list[tuple[str, int]] = [(m, n) for n in sorted(args.peer_sizes, reverse=True) for m in ("lagrange", "kane") if m in args.methods] + [
        ("lagrange_cli", n) for n in args.sizes
    ]  # the slowest first

    def one(job: tuple[str, int]) -> tuple[tuple[str, int], dict[str, Any]]:
        tool, n = job
        log(f"start {tool} N = {n}")
        if tool == "lagrange_cli":
            out = tmp / f"lagrange_{n}.py"
            value = runner.run([PYTHON, "-m", "lagrange_cli", "derive", str(files[n]), "--to", "python", "-o", str(out)])
        else:
            out = tmp / f"peer_{tool}_{n}.py"
            value = runner.me("peer", tool, n, out)
        value["module"] = str(out)
        log(f"done {tool} N = {n}: {cell(value)}")
        return job, value

    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        for (tool, n), value in pool.map(one, jobs):
            if tool == "lagrange_cli":
                ours[n] = value
            else:
                theirs[(tool, n)] = value
    checks = run_checks(runner, args.sizes, ours, theirs)
    rhs_rows: list[list[object]] = []
    rhs_ratios: list[float] = []
    if args.rhs:
        for n in args.rhs_sizes:
            if n not in ours or "error" in ours[n]:
                continue
            planar = tmp / f"planar_{3 * n}.py"
            planar_file = tmp / f"general_chain_{3 * n}.yaml"
            sys.path.insert(0, str(HERE))
            import pendulum

            planar_file.write_text(pendulum.Chain("general", 3 * n).yaml())
            made = runner.run([PYTHON, "-m", "lagrange_cli", "derive", str(planar_file), "--to", "python", "-o", str(planar)])
            if "error" in made:
                rhs_rows.append([n, 3 * n, "planar module failed: " + made["error"], "-", "-", "-", "-", "-"])
                continue
            value = runner.me("rhs", n, ours[n]["module"], planar)
            if "error" in value:
                rhs_rows.append([n, 3 * n, "failed: " + value["error"], "-", "-", "-", "-", "-"])
                continue
            rows = [n, 3 * n]
            for kind in ("list", "ndarray"):
                s, p = value[kind]["spatial"], value[kind]["planar"]
                rows += [seconds(s), seconds(p), ratio(s / p)]
                rhs_ratios.append(s / p)
            rows.append("ok" if value["planar check"] else "**planar module WRONG**")
            rhs_rows.append(rows)
    elapsed = time.perf_counter() - clock
    raw = tmp / "raw.json"
    raw.write_text(
        json.dumps(
            {"started": started.isoformat(), "elapsed": elapsed, "ours": ours, "theirs": [[k, v] for k, v in theirs.items()], "checks": checks, "rhs_rows": rhs_rows, "rhs_ratios": rhs_ratios},
            default=str,
        )
    )
    log(f"raw results in {raw}")
    return report(args, started, elapsed, ours, theirs, checks, rhs_rows, rhs_ratios)


def run_checks(runner: Runner, sizes: Sequence[int], ours: dict[int, dict[str, Any]], theirs: dict[tuple[str, int], dict[str, Any]]) -> dict[int, dict[str, Any]]:
    """lagrange's module against every peer module that was written, at each N."""
    checks: dict[int, dict[str, Any]] = {}
    for n in sizes:
        peers = [theirs[(m, n)] for m in METHODS if (m, n) in theirs and "error" not in theirs[(m, n)]]
        if "error" not in ours[n] and peers:
            checks[n] = runner.me("check", n, ours[n]["module"], *(v["module"] for v in peers))
    return checks


def rerender(args: argparse.Namespace) -> str:
    """The report again from a run's raw.json (its modules still in place): a process killed by
    SIGXCPU counts as over the CPU limit, and the checks are run for every N with a peer module."""
    raw = json.loads(Path(args.rerender).read_text())
    ours = {int(k): v for k, v in raw["ours"].items()}
    theirs: dict[tuple[str, int], dict[str, Any]] = {}
    for (m, n), value in raw["theirs"]:
        if str(value.get("error", "")).startswith(f"exit {-signal.SIGXCPU}"):
            value = {**value, "error": f"did not finish within {int(args.cpu_limit)} s of CPU", "limit": True}
        theirs[(m, int(n))] = value
    runner = Runner(ROOT, Path(tempfile.mkdtemp(prefix="lagrange-spatial-checks-")), args.cpu_limit)
    checks = run_checks(runner, args.sizes, ours, theirs)
    started = datetime.datetime.fromisoformat(raw["started"]) if "started" in raw else datetime.datetime.now(datetime.timezone.utc)
    return report(args, started, float(raw.get("elapsed", 0.0)), ours, theirs, checks, raw["rhs_rows"], raw["rhs_ratios"])


def report(
    args: argparse.Namespace,
    started: datetime.datetime,
    elapsed: float,
    ours: dict[int, dict[str, Any]],
    theirs: dict[tuple[str, int], dict[str, Any]],
    checks: dict[int, dict[str, Any]],
    rhs_rows: list[list[object]],
    rhs_ratios: Sequence[float] = (),
) -> str:
    rows = []
    common: dict[int, float] = {}
    for n in args.sizes:
        row: list[object] = [n, 3 * n, cell(ours[n])]
        best = None
        for m in METHODS:
            value = theirs.get((m, n))
            row.append(cell(value))
            if value is not None and "error" not in value:
                best = value["cpu"] if best is None else min(best, value["cpu"])
        found = checks.get(n)
        if found is None:
            row.append("-")
        elif "error" in found:
            row.append("**check failed**: " + found["error"])
        else:
            row.append(("ok" if found["ok"] else "**DISAGREE**") + f" {max(found['deviation'] + found['rhs']):.0e}")
        fair = best is not None and found is not None and found.get("ok") and "error" not in ours[n]
        if fair:
            assert best is not None
            common[n] = best / ours[n]["cpu"]
        row.append(ratio(common.get(n)))
        rows.append(row)
    command = "PYTHONPATH=. .venv/bin/python benchmarks/spatial_bench.py" + "".join(" " + shlex.quote(a) for a in (args.argv or []))
    lines = [
        f"Run on {started:%Y-%m-%d %H:%M} UTC with `{command}` (took {elapsed / 60:.1f} min, {args.jobs} processes at a time); {machine()}."
        + (
            " Report re-rendered from that run's raw results (`--rerender RAW.json`): the accelerations check (which the run itself had skipped at every N where LagrangesMethod did not finish, a harness bug since fixed) was run then, on the modules the run wrote."
            if getattr(args, "rerender", None)
            else ""
        ),
        "",
        "CPU time (user + system of that process alone, from `wait4`) of whole processes, each with a fresh cache and RLIMIT_CPU "
        f"{args.cpu_limit:g} s; wall time beside it (the machine is shared, so wall is noisy). Commands (FILE from `spatial_bench.py yaml N`, N = 6 is benchmarks/spatial_chain_6.yaml):",
        "",
        "- lagrange: `python -m lagrange_cli derive FILE --to python -o OUT`",
        "- peer: `python benchmarks/spatial_bench.py peer kane N OUT` and `... peer lagrange N OUT` (frames with orient_body_fixed ZYX relative to the previous frame, "
        "locatenew + v2pt_theory, RigidBody with inertia dyadics; KanesMethod or LagrangesMethod; lambdify(cse=True) of M and F written out as a module)",
        "- check: `python benchmarks/spatial_bench.py check N LAGRANGE_MODULE PEER_MODULES...`: solve(M, F) and each rhs's accelerations agree at 3 random states (one with perturbed parameters); `ok` below 1e-8 (largest |a - a_lagrange| / max(1, |a_lagrange|) shown)",
        "",
        table(["N links", "coordinates", "lagrange: CPU (wall)", "KanesMethod: CPU (wall)", "LagrangesMethod: CPU (wall)", "accelerations agree", "faster peer / lagrange (CPU)"], rows),
        "",
    ]
    fits: dict[str, tuple[float, float] | None] = {}
    labels = {"ours": "lagrange", "kane": "KanesMethod", "lagrange": "LagrangesMethod"}
    series = {"ours": [(n, ours[n]["cpu"]) for n in args.sizes if "error" not in ours[n]]}
    for m in METHODS:
        series[m] = [(n, theirs[(m, n)]["cpu"]) for n in args.peer_sizes if (m, n) in theirs and "error" not in theirs[(m, n)]]
    for label, points in series.items():
        fits[label] = fit = power_fit(points)
        if fit:
            lines.append(f"- {labels[label]}: CPU time fitted over N = {', '.join(str(n) for n, _ in points)} (log-log least squares): t = {fit[0]:.3g} N^{fit[1]:.2f}.")
    six = ours.get(6)
    peer_fits = {m: fits[m] for m in METHODS if fits.get(m)}
    if peer_fits:
        guesses = {m: f[0] * 6 ** f[1] for m, f in peer_fits.items() if f}
        faster = min(guesses, key=lambda m: guesses[m])
        text = ", ".join(f"{'KanesMethod' if m == 'kane' else 'LagrangesMethod'} about {seconds(v)}" for m, v in guesses.items())
        lines.append(f"- **Extrapolation** (not a measurement) of the peer to N = 6 from those fits: {text}.")
        if six and "error" not in six:
            lines.append(
                f"- Target (issue 13): file to Python module at least 50x faster than the faster of KanesMethod / LagrangesMethod at N = 6. "
                f"By extrapolation: {ratio(guesses[faster] / six['cpu'])} ({seconds(guesses[faster])} extrapolated / {seconds(six['cpu'])} measured): "
                f"**{'met' if guesses[faster] / six['cpu'] >= 50 else 'NOT met'} by extrapolation**."
            )
    biggest = max(common) if common else None
    if biggest is not None:
        lines.append(f"- Measured ratio at the largest N where both finished (N = {biggest}): {ratio(common[biggest])} (faster peer / lagrange, CPU).")
    if six and "error" not in six:
        lines.append(
            f"- Target (issue 13): the 6-link chain, file to Python module, under 10 s whole process: {seconds(six['cpu'])} CPU ({seconds(six['seconds'])} wall): **{'met' if six['cpu'] < 10 else 'NOT met'}**."
        )
    for m in METHODS:
        for n in args.peer_sizes:
            value = theirs.get((m, n))
            if value and "error" in value:
                lines.append(f"- {labels[m]} at N = {n}: {value['error']} (left out of its fit).")
    for n in args.peer_sizes:
        values = [theirs[(m, n)] for m in METHODS if (m, n) in theirs]
        if values and all(v.get("limit") for v in values) and n in ours and "error" not in ours[n]:
            spent = min(float(v["cpu"]) for v in values)
            lines.append(
                f"- At N = {n} no peer method run finished ({', '.join(labels[m] for m in METHODS if (m, n) in theirs)}): faster peer / lagrange is at least "
                f"{ratio(spent / ours[n]['cpu'])} ({seconds(spent)} of CPU when stopped / lagrange's {seconds(ours[n]['cpu'])}), a measured lower bound."
            )
    for n, value in ours.items():
        if "error" in value:
            lines.append(f"- lagrange at N = {n} failed: {value['error']}")
    if rhs_rows:
        lines += [
            "",
            "Generated-code evaluation (issue 13: within 2x of the planar chain at equal size): seconds per call of `rhs(0.0, y, p)` of lagrange's module for the "
            "spatial chain (3N coordinates) and for the planar general chain with 3N links (`benchmarks/pendulum.py`, the chain issue 14 optimised), "
            "`python benchmarks/spatial_bench.py rhs N SPATIAL PLANAR` (timeit, best of 25 rounds, benchmarks/worker.py `per_call`):",
            "",
            table(
                ["N links", "coordinates", "spatial, y list", "planar, y list", "spatial / planar", "spatial, y ndarray", "planar, y ndarray", "spatial / planar", "planar module vs reference"],
                rhs_rows,
            ),
        ]
    if rhs_ratios:
        worst = max(rhs_ratios)
        lines += [
            "",
            f"Target (issue 13): generated-code evaluation within 2x of the planar chain at equal size: the largest spatial / planar ratio above is {ratio(worst)}: **{'met' if worst <= 2 else 'NOT met'}**.",
        ]
    return "\n".join(lines).rstrip() + "\n"


def write(markdown: str) -> Path:
    path = ROOT / "BENCHMARKS.md"
    text = path.read_text()
    if BEGIN not in text or END not in text:
        raise SystemExit(f"{path} has no {BEGIN} ... {END} markers")
    head, rest = text.split(BEGIN, 1)
    path.write_text(head + f"{BEGIN}\n{markdown}{END}" + rest.split(END, 1)[1])
    return path


def sizes_list(text: str) -> list[int]:
    try:
        values = sorted({int(v) for v in text.split(",") if v.strip()})
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if not values or values[0] < 1:
        raise argparse.ArgumentTypeError("sizes must be positive integers")
    return values


TASKS = {"peer": peer, "check": check, "rhs": rhs, "ops": ops}


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "yaml":
        print(chain_yaml(int(argv[1])), end="")
        return 0
    if argv and argv[0] in TASKS:
        TASKS[argv[0]](*argv[1:])
        return 0
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=sizes_list, default=list(SIZES), help="lagrange's chain sizes (links)")
    parser.add_argument("--peer-sizes", type=sizes_list, default=list(PEER_SIZES), help="the peer's chain sizes (links)")
    parser.add_argument("--rhs-sizes", type=sizes_list, default=[2, 4, 6], help="sizes of the per-call rhs comparison")
    parser.add_argument("--no-rhs", dest="rhs", action="store_false", help="skip the per-call rhs comparison")
    parser.add_argument("--methods", default=",".join(METHODS), help="the peer's methods: kane, lagrange or both")
    parser.add_argument("--cpu-limit", type=float, default=CPU_LIMIT, help="RLIMIT_CPU of each process, seconds")
    parser.add_argument("--jobs", type=int, default=1, help="processes at a time (CPU times are per process)")
    parser.add_argument("--rerender", help="a run's raw.json: its report again (the run's own options must be given too)")
    parser.add_argument("--no-write", action="store_true", help="print only")
    args = parser.parse_args(argv)
    args.argv = argv
    if "--rerender" in argv:  # the run's own command line; the note says it was re-rendered
        k = argv.index("--rerender")
        args.argv = argv[:k] + argv[k + 2 :]
    args.methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    if set(args.methods) - set(METHODS):
        parser.error(f"--methods: expected kane, lagrange or both, got {','.join(args.methods)}")
    args.sizes = sorted(set(args.sizes) | set(args.peer_sizes))
    markdown = rerender(args) if args.rerender else bench(args)
    print(markdown)
    if not args.no_write:
        log(f"written to {write(markdown)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
