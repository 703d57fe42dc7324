"""The benchmark suite (`make bench`): lagrange against sympy.physics.mechanics, whole processes.

    .venv/bin/python benchmarks/run.py                       # everything; writes BENCHMARKS.md
    .venv/bin/python benchmarks/run.py --quick               # no peer at N >= 10
    .venv/bin/python benchmarks/run.py --only general,rhs --sizes 2,5,15 --no-write
    .venv/bin/python benchmarks/run.py --tree /path/to/other/checkout --no-write

The main system is the GENERAL planar N-link chain (its own m_i and l_i per link,
benchmarks/pendulum.py); the equal-parameter chain is the second row. Every time is the wall
time of a WHOLE PROCESS (fresh interpreter, imports included: what a user waits for):

- lagrange: `lagrange derive FILE --python -o OUT` (and `--text`, `--latex`, `--numba`), the
  installed CLI with PYTHONPATH set to the tree under test;
- the peer: `python benchmarks/peer.py KIND N OUT` (LagrangesMethod, then
  `sympy.lambdify(..., cse=True)` of M and F written out as a Python module).

Every module either tool writes is checked (benchmarks/worker.py `check`, its own process)
against the hand-written reference M and F at random states, at every size, N = 60 included.
Rows (`--only`): general, equal, print, rhs, numba, startup. Each process has a hard timeout
(`--timeout`, default 900 s) and is then reported as "over T s".
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import re
import resource
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

import pendulum

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PYTHON = sys.executable
SIZES = (2, 5, 10, 15, 30, 60)
PEER_MAX = {"general": 15, "equal": 10}  # the general peer takes ~45 s at N = 15 and grows ~N^3.3
QUICK_PEER_MAX = 9  # --quick: no peer at N >= 10
FIT_SIZES = (15, 30, 60)
RHS_SIZE, NUMBA_SIZE, PRINT_TARGET = 15, 30, 30
SLOW = 10.0  # a measurement slower than this is not repeated
TIMEOUT = 900.0
BEGIN, END = "<!-- bench:begin -->", "<!-- bench:end -->"
ROWS = ("general", "equal", "print", "rhs", "numba", "startup")
METHODS = {"print": "text_latex"}
NEWLINE = b"\n"


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


# -- running things ---------------------------------------------------------------------------


class Runner:
    """Runs whole processes with the tree under test on PYTHONPATH, a fresh cache directory
    each, a hard timeout, and wall + CPU time."""

    def __init__(self, tree: Path, tmp: Path, timeout: float, clock: str = "wall") -> None:
        self.tree = tree
        self.clock = "cpu" if clock == "cpu" else "seconds"  # the key the targets and ratios use
        self.tmp = tmp
        self.timeout = timeout
        self.loads: list[float] = []
        self.count = 0
        script = Path(PYTHON).parent / "lagrange"
        self.lagrange = [str(script)] if script.exists() else [PYTHON, "-m", "lagrange_cli"]

    def env(self, **extra: str) -> dict[str, str]:
        self.count += 1
        cache = self.tmp / "caches" / str(self.count)
        cache.mkdir(parents=True)
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR", "PYTHONPROFILEIMPORTTIME")}
        return {**env, "PYTHONPATH": str(self.tree), "LAGRANGE_CACHE_DIR": str(cache / "lagrange"), "NUMBA_CACHE_DIR": str(cache / "numba"), **extra}

    def run(self, command: Sequence[str], **extra: str) -> dict[str, Any]:
        """One process: {"seconds", "cpu", ...its RESULT json} or {"error", "timeout"?}."""
        self.loads.append(os.getloadavg()[0])
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        process = subprocess.Popen(list(command), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=self.tmp, env=self.env(**extra), start_new_session=True)
        try:
            out, err = process.communicate(timeout=self.timeout)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.communicate()
            return {"error": f"over {self.timeout:g} s", "timeout": True}
        seconds = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        if process.returncode != 0:
            return {"error": f"exit {process.returncode}: " + failure(err)}
        value: dict[str, Any] = {"seconds": seconds, "cpu": cpu}
        for line in reversed(out.splitlines()):
            if line.startswith("RESULT "):
                value.update(json.loads(line[len("RESULT ") :]))
                break
        return value

    def best(self, command: Sequence[str], repeats: int, **extra: str) -> dict[str, Any]:
        """The fastest of up to `repeats` runs; one run only when it fails or takes over SLOW."""
        found: dict[str, Any] | None = None
        for run in range(1, repeats + 1):
            value = self.run(command, **extra)
            if "error" in value:
                return value
            if found is None or value[self.clock] < found[self.clock]:
                found = value
            found["runs"] = run
            if value["seconds"] > SLOW:
                break
        assert found is not None
        return found

    def worker(self, *args: object) -> dict[str, Any]:
        return self.run([PYTHON, str(HERE / "worker.py"), *map(str, args)])


def failure(stderr: str) -> str:
    """The gist of a failed process's stderr: its `error:` line (lagrange's diagnostics) with the
    `expected:` line after it, or else the last line (a traceback's exception)."""
    lines = [" ".join(line.split()) for line in stderr.splitlines() if line.strip()]
    errors = [i for i, line in enumerate(lines) if "error:" in line.lower()]
    if errors:
        gist = lines[errors[0]]
        gist = gist[gist.lower().index("error:") :]
        expected = [line for line in lines[errors[0] + 1 :] if line.lower().startswith("expected:")]
        return (gist + ("; " + expected[0] if expected else ""))[:300]
    return (lines[-1] if lines else "no output")[:300]


# -- formatting -------------------------------------------------------------------------------


def seconds(value: float | None) -> str:
    if value is None or math.isnan(value):
        return "-"
    if value >= 1:
        return f"{value:.2f} s"
    if value >= 1e-3:
        return f"{value * 1e3:.1f} ms"
    return f"{value * 1e6:.2f} µs"


def ratio(value: float | None) -> str:
    return "-" if value is None else (f"{value:.0f}x" if value >= 20 else f"{value:.2f}x")


def table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def error_text(value: dict[str, Any]) -> str:
    if value.get("timeout"):
        return str(value["error"])
    return "failed: " + str(value["error"]).replace("|", "/")[:220]


def timed(value: dict[str, Any]) -> str:
    """Wall time (CPU time) of a process, or what went wrong."""
    if "error" in value:
        return error_text(value)
    return f"{seconds(value['seconds'])} ({seconds(value['cpu'])})"


def verdict(check: dict[str, Any] | None) -> str:
    if check is None:
        return "-"
    if "error" in check:
        return "**check failed**: " + error_text(check)
    worst = max(check["deviation"].values())
    return ("ok" if check["ok"] else "**WRONG**") + f" {worst:.0e}"


def power_fit(points: Sequence[tuple[int, float]]) -> tuple[float, float] | None:
    """t = c N^k by least squares in log-log; (c, k)."""
    if len(points) < 2:
        return None
    xs = [math.log(n) for n, _ in points]
    ys = [math.log(t) for _, t in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    k = sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True)) / sum((x - mx) ** 2 for x in xs)
    return math.exp(my - k * mx), k


# -- the rows ---------------------------------------------------------------------------------


class Bench:
    def __init__(self, runner: Runner, sizes: Sequence[int], quick: bool, repeats: int) -> None:
        self.runner = runner
        self.tmp = runner.tmp
        self.sizes = list(sizes)
        self.quick = quick
        self.repeats = repeats
        self.targets: list[tuple[str, str, str, bool | None]] = []  # (what, target, measured, passed)
        self.parts: list[str] = []
        self.commands: list[str] = []
        self.modules: dict[tuple[str, int], Path] = {}  # lagrange's checked modules
        self.peers: dict[tuple[str, int], Path] = {}  # the peer's checked modules
        self.results: dict[tuple[str, int], dict[str, Any]] = {}

    def target(self, what: str, goal: str, measured: str, passed: bool | None) -> None:
        self.targets.append((what, goal, measured, passed))

    def section(self, title: str, text: str) -> None:
        self.parts.append(f"### {title}\n\n{text}")
        log(f"\n### {title}\n\n{text}\n")

    def command(self, text: str) -> None:
        if text not in self.commands:
            self.commands.append(text)

    def file(self, chain: pendulum.Chain) -> Path:
        path = self.tmp / f"{chain.name}.yaml"
        if not path.exists():
            path.write_text(chain.yaml())
        return path

    def peer_allowed(self, kind: str, n: int) -> bool:
        return n <= (QUICK_PEER_MAX if self.quick else PEER_MAX[kind])

    # file to module --------------------------------------------------------------------------

    def lagrange_module(self, chain: pendulum.Chain) -> dict[str, Any]:
        key = (chain.kind, chain.n)
        if key in self.results:
            return self.results[key]
        out = self.tmp / f"{chain.name}_lagrange.py"
        log(f"{chain.name}: lagrange derive --python")
        self.command("lagrange derive CHAIN.yaml --python -o out.py")
        value = self.runner.best([*self.runner.lagrange, "derive", str(self.file(chain)), "--python", "-o", str(out)], self.repeats)
        if "error" not in value:
            value["lines"] = out.read_text().count("\n")
            value["check"] = self.runner.worker("check", chain.kind, chain.n, out)
            if value["check"].get("ok"):
                self.modules[key] = out
        self.results[key] = value
        return value

    def peer_module(self, chain: pendulum.Chain) -> dict[str, Any]:
        key = ("peer " + chain.kind, chain.n)
        if key in self.results:
            return self.results[key]
        out = self.tmp / f"{chain.name}_peer.py"
        log(f"{chain.name}: peer (LagrangesMethod + lambdify)")
        self.command("python benchmarks/peer.py KIND N out.py")
        value = self.runner.best([PYTHON, str(HERE / "peer.py"), chain.kind, str(chain.n), str(out)], self.repeats)
        if "error" not in value:
            value["check"] = self.runner.worker("check", chain.kind, chain.n, out)
            if value["check"].get("ok"):
                self.peers[(chain.kind, chain.n)] = out
        self.results[key] = value
        return value

    def chain_row(self, kind: str) -> None:
        clock = self.runner.clock
        rows: list[list[object]] = []
        ours: dict[int, dict[str, Any]] = {}
        theirs: dict[int, dict[str, Any]] = {}
        for n in self.sizes:
            chain = pendulum.Chain(kind, n)
            value = ours[n] = self.lagrange_module(chain)
            row: list[object] = [n, timed(value), value.get("lines", "-"), verdict(value.get("check"))]
            if self.peer_allowed(kind, n):
                peer = theirs[n] = self.peer_module(chain)
                phases = peer.get("phases", {})
                split = " / ".join(seconds(phases.get(k)) for k in ("import", "derive", "lambdify")) if phases else "-"
                fair = "error" not in value and "error" not in peer and value["check"].get("ok") and peer["check"].get("ok")
                row += [timed(peer), split, verdict(peer.get("check")), ratio(peer[clock] / value[clock]) if fair else "-"]
            else:
                row += ["not run" + (" (--quick)" if self.quick and n <= PEER_MAX[kind] else ""), "-", "-", "-"]
            rows.append(row)
        text = table(
            ["N", "lagrange: wall (CPU)", "lines", "module vs reference", "peer: wall (CPU)", "peer: import / derive / lambdify", "peer module vs reference", "peer / lagrange"],
            rows,
        )
        notes = [
            f"Whole processes: wall time (CPU time in parentheses), the fastest of up to {self.repeats} (one run when it takes over {SLOW:g} s). "
            "lagrange: `lagrange derive FILE --python -o out.py`; peer: `python benchmarks/peer.py "
            f"{kind} N out.py` (LagrangesMethod, lambdify(cse=True) of M and F, the module written). "
            "`module vs reference`: the largest relative deviation of M, F and the rhs (list and numpy y; accelerations as the backward error |M a - F| / (|M| |a| + |F|)) "
            "from the hand-written M and F at 3 random states, one with perturbed parameters, in its own process; `ok` below 1e-9."
        ]
        measured = {n: v[clock] for n, v in ours.items() if "error" not in v}
        timeouts = {n for n, v in ours.items() if v.get("timeout")}
        fit_points = [(n, measured[n]) for n in FIT_SIZES if n in measured]
        fit = power_fit(fit_points)
        if fit:
            notes.append(f"lagrange's growth, power law fitted over N = {', '.join(str(n) for n, _ in fit_points)}: t = {fit[0]:.3g} N^{fit[1]:.2f}.")
        local: tuple[float, bool] | None = None  # (exponent, is a lower bound)
        if 30 in measured and 60 in measured:
            local = (math.log(measured[60] / measured[30]) / math.log(2), False)
        elif 30 in measured and 60 in timeouts:
            local = (math.log(self.runner.timeout / ours[30]["seconds"]) / math.log(2), True)  # wall: the timeout is wall
        if local:
            notes.append(f"Local exponent from N = 30 to 60: log2(t60 / t30) = {'over ' if local[1] else ''}{local[0]:.2f}.")
        peer_points = [(n, v[clock]) for n, v in theirs.items() if "error" not in v and n >= 5]
        peer_fit = power_fit(peer_points)
        if peer_fit and len(peer_points) >= 2:
            c, k = peer_fit
            beyond = [n for n in self.sizes if n not in theirs and n > max(n for n, _ in peer_points)]
            guesses = []
            for n in beyond:
                guess = c * n**k
                text_n = f"N = {n}: about {seconds(guess)}"
                if n in measured:
                    text_n += f", about {ratio(guess / measured[n])} lagrange's measured {seconds(measured[n])}"
                guesses.append(text_n)
            if guesses:
                notes.append(
                    f"The peer is **not run** beyond N = {max(n for n, _ in peer_points)}; a power law fitted to its whole-process times at N = {', '.join(str(n) for n, _ in peer_points)} "
                    f"(t = {c:.3g} N^{k:.2f}) **extrapolates** to " + "; ".join(guesses) + " (extrapolations, not measurements)."
                )
        label = {"general": "1. File to Python module: the general chain", "equal": "2. File to Python module: the equal-parameter chain"}[kind]
        self.section(label, text + "\n\n" + "\n\n".join(notes))
        if kind != "general":
            return
        value = ours.get(15)
        peer = theirs.get(15)
        if value is None:
            self.target("general chain N = 15, file to Python module, peer / lagrange", ">= 60x", "not measured (N = 15 not in --sizes)", None)
        elif peer is None or "error" in peer or "error" in value:
            why = error_text(value) if "error" in value else (error_text(peer) if peer else "peer not run" + (" (--quick)" if self.quick else ""))
            self.target("general chain N = 15, file to Python module, peer / lagrange", ">= 60x", why, False if "error" in value else None)
        else:
            fair = value["check"].get("ok") and peer["check"].get("ok")
            r = peer[clock] / value[clock]
            self.target(
                "general chain N = 15, file to Python module, peer / lagrange",
                ">= 60x",
                f"{ratio(r)} ({seconds(peer[clock])} / {seconds(value[clock])})" if fair else "modules disagree with the reference",
                bool(fair and r >= 60),
            )
        for n, limit in ((30, 3.0), (60, 20.0)):
            what = f"general chain N = {n}, file to Python module (whole process)"
            value = ours.get(n)
            if value is None:
                self.target(what, f"< {limit:g} s", f"not measured (N = {n} not in --sizes)", None)
            elif "error" in value:
                self.target(what, f"< {limit:g} s", error_text(value), False)
            else:
                ok = bool(value["check"].get("ok"))
                self.target(what, f"< {limit:g} s", timed(value) + ("" if ok else ", module disagrees with the reference"), ok and value[clock] < limit)
        fitted = f"; fitted over N = {', '.join(str(n) for n, _ in fit_points)}: N^{fit[1]:.2f}" if fit else ""
        if local:
            shown = ("over " if local[1] else "") + f"N^{local[0]:.2f}{fitted}"
            self.target("growth of the general chain from N = 30 to 60", "at most N^3", shown, False if local[1] and local[0] > 3 else (None if local[1] else local[0] <= 3))
        else:
            self.target("growth of the general chain from N = 30 to 60", "at most N^3", "not measured" + fitted, None)

    def general(self) -> None:
        self.chain_row("general")

    def equal(self) -> None:
        self.chain_row("equal")

    # text and LaTeX ------------------------------------------------------------------------

    def text_latex(self) -> None:
        rows: list[list[object]] = []
        sizes = [n for n in self.sizes if n >= 15] or [PRINT_TARGET]
        for n in sizes:
            chain = pendulum.Chain("general", n)
            for flag in ("--text", "--latex"):
                out = self.tmp / f"{chain.name}{'.tex' if flag == '--latex' else '.txt'}"
                log(f"{chain.name}: lagrange derive {flag}")
                self.command(f"lagrange derive CHAIN.yaml {flag} -o out")
                value = self.runner.best([*self.runner.lagrange, "derive", str(self.file(chain)), flag, "-o", str(out)], self.repeats)
                size = "-"
                if "error" not in value:
                    data = out.read_bytes()
                    size = f"{len(data) / 1024:.0f} KiB, {data.count(NEWLINE)} lines"
                    if not data.strip():
                        value = {"error": "empty output"}
                rows.append([n, f"`{flag}`", timed(value), size])
                if n == PRINT_TARGET:
                    what = f"general chain N = 30, `lagrange derive {flag}` (whole process)"
                    self.target(what, "< 3 s", timed(value), "error" not in value and value[self.runner.clock] < 3)
        if PRINT_TARGET not in sizes:
            self.target("general chain N = 30, `--text` and `--latex`", "< 3 s", "not measured (N = 30 not in --sizes)", None)
        text = table(["N", "output", "wall (CPU)", "size"], rows)
        text += f"\n\n`lagrange derive FILE --text -o out` and `--latex -o out` on the general chain, whole processes, the fastest of up to {self.repeats}."
        self.section("3. Text and LaTeX: the general chain", text)

    # rhs per call ----------------------------------------------------------------------------

    def rhs(self) -> None:
        rows: list[list[object]] = []
        notes: list[str] = []
        for n, against in ((2, "hand"), (RHS_SIZE, "peer")):
            chain = pendulum.Chain("general", n)
            self.lagrange_module(chain)
            module = self.modules.get(("general", n))
            peer: Path | None = None
            if against == "peer":
                if self.peer_allowed("general", n):
                    self.peer_module(chain)
                peer = self.peers.get(("general", n))
            if module is None or (against == "peer" and peer is None):
                why = "no checked lagrange module" if module is None else ("peer not run (--quick)" if not self.peer_allowed("general", n) else "no checked peer module")
                rows.append([n, why, "", "", "", "", "", ""])
                if against == "peer":
                    for kind in ("list", "numpy array"):
                        self.target(f"pure-Python rhs per call at N = 15 (y a {kind}), peer / lagrange", ">= 5x", "not measured: " + why, None if "quick" in why else False)
                continue
            log(f"{chain.name}: rhs per call")
            value = self.runner.worker("rhs", "general", n, module, *([peer] if peer else []))
            if "error" in value:
                rows.append([n, error_text(value), "", "", "", "", "", ""])
                continue
            label = {"hand": "hand-written `math` rhs", "peer": "lambdify(cse) + numpy.linalg.solve"}[against]
            fair = all(c["ok"] for c in value["checks"].values())
            row: list[object] = [n, label]
            found: dict[str, float] = {}
            for kind in ("list", "ndarray"):
                times = value[kind]
                r = times["lagrange"] / times[against] if against == "hand" else times[against] / times["lagrange"]
                found[kind] = r
                row += [seconds(times["lagrange"]), seconds(times[against]), ratio(r) if fair else "values disagree"]
            rows.append(row)
            notes.append(f"N = {n}: " + ", ".join(f"{name} {verdict(c)}" for name, c in value["checks"].items()) + " against the reference (3 random states)")
            if against == "peer":
                for kind, shown in (("list", "list"), ("ndarray", "numpy array")):
                    self.target(f"pure-Python rhs per call at N = 15 (y a {shown}), peer / lagrange", ">= 5x", ratio(found[kind]) if fair else "values disagree", fair and found[kind] >= 5)
            else:
                shown = f"{ratio(found['list'])} (numpy y: {ratio(found['ndarray'])})"
                self.target("rhs per call at N = 2, lagrange / hand-written (earlier target)", "<= 1.5x", shown if fair else "values disagree", fair and found["list"] <= 1.5)
        text = table(["N", "against", "lagrange (y list)", "peer (y list)", "ratio", "lagrange (y ndarray)", "peer (y ndarray)", "ratio"], rows)
        text += (
            "\n\nSeconds per call of `rhs(0.0, y, p)` of the modules written above (general chain, their default parameters), timeit, "
            "min over 25 rounds of ~40 ms, the candidates interleaved within each round so that machine load hits them alike; "
            "y a list of floats, and a numpy array (what solve_ivp passes). Ratio at N = 2 is lagrange / hand-written "
            "(lower is better), at N = 15 peer / lagrange (target >= 5).\n\n" + "\n".join(f"- {note}" for note in notes)
        )
        self.section("4. The emitted rhs, per call", text)

    # numba -----------------------------------------------------------------------------------

    def numba(self) -> None:
        n = NUMBA_SIZE
        chain = pendulum.Chain("general", n)
        out = self.tmp / f"{chain.name}_numba.py"
        log(f"{chain.name}: lagrange derive --python --numba, then the first call")
        self.command("lagrange derive CHAIN.yaml --python --numba -o out.py")
        self.command("python benchmarks/worker.py numba-first general 30 out.py  (NUMBA_CACHE_DIR empty)")
        derive = self.runner.run([*self.runner.lagrange, "derive", str(self.file(chain)), "--python", "--numba", "-o", str(out)])
        what = "`--numba` first compile at N = 30 (general chain)"
        if "error" in derive:
            self.section("5. `--numba` at N = 30", f"`lagrange derive --python --numba`: {error_text(derive)}")
            self.target(what, "< 20 s", error_text(derive), False)
            return
        first = self.runner.worker("numba-first", "general", n, out)
        if "error" in first:
            self.section("5. `--numba` at N = 30", f"`lagrange derive --python --numba`: {timed(derive)}; first call: {error_text(first)}")
            self.target(what, "< 20 s", error_text(first), False)
            return
        ok = bool(first["check"]["ok"])
        compile_time = first["first call cpu" if self.runner.clock == "cpu" else "first call"]
        rows = [
            ["`lagrange derive CHAIN.yaml --python --numba -o out.py` (whole process)", timed(derive)],
            ["fresh process, empty numba cache: `import numba`", seconds(first["import numba"])],
            ["... import the module", seconds(first["import module"])],
            ["... **first call of rhs (numba compiles the generated module)**: wall (CPU)", f"{seconds(first['first call'])} ({seconds(first['first call cpu'])})"],
            ["... second call", seconds(first["second call"])],
            ["that whole process, wall (CPU)", timed(first)],
            ["everything: derive process + first-call process", seconds(derive["seconds"] + first["seconds"])],
        ]
        text = table(["step", "time"], rows)
        text += f"\n\nThe module checked against the reference after the calls: {verdict(first['check'])}. The target is judged on the first call (the numba compile of the generated module, in a process with an empty NUMBA_CACHE_DIR); the whole chain of processes is shown beside it."
        self.section("5. `--numba` at N = 30", text)
        self.target(
            what,
            "< 20 s",
            f"{seconds(compile_time)} (first call; derive + first-call processes {seconds(derive['seconds'] + first['seconds'])})" if ok else "module disagrees with the reference",
            ok and compile_time < 20,
        )

    # start-up --------------------------------------------------------------------------------

    def startup(self) -> None:
        log("start-up")
        rows: list[list[object]] = []
        measured: dict[str, dict[str, Any]] = {}
        commands = {
            "python -c pass": [PYTHON, "-c", "pass"],
            "python -c 'import sympy'": [PYTHON, "-c", "import sympy"],
            "lagrange --help": [*self.runner.lagrange, "--help"],
            "lagrange derive double_pendulum": [*self.runner.lagrange, "derive", "double_pendulum"],
        }
        for name, command in commands.items():
            runs = 10 if "derive" not in name else 5
            self.runner.run(command)  # warm-up: the OS file cache
            value = min((self.runner.run(command) for _ in range(runs)), key=lambda v: v.get("seconds", math.inf))
            measured[name] = value
            base = measured["python -c pass"].get("seconds")
            rows.append([name, error_text(value) if "error" in value else seconds(value["seconds"]), ratio(value["seconds"] / base) if base and "error" not in value else "-", runs])
        text = table(["command", "wall (min)", "vs python -c pass", "runs"], rows)
        help_time = measured["lagrange --help"].get("seconds")
        self.target("`lagrange --help` wall time (earlier target)", "< 0.25 s", seconds(help_time) if help_time else "failed", help_time is not None and help_time < 0.25)
        found = []
        for name, arguments, banned in (
            ("lagrange --help", ["--help"], ("sympy", "numpy", "scipy")),
            ("lagrange derive double_pendulum", ["derive", "double_pendulum"], ("numpy", "scipy", "matplotlib")),
        ):
            packages = self.imported([*self.runner.lagrange, *arguments])
            bad = [b for b in banned if b in packages]
            found.append(f"- `{name}` imports " + (", ".join(bad) if bad else "none of " + ", ".join(banned)) + " (`PYTHONPROFILEIMPORTTIME=1`)")
            self.target(f"`{name}` imports no {'/'.join(banned)} (earlier target)", "none", ", ".join(bad) or "none", not bad)
        text += "\n\nWall time of a whole process, the minimum of the runs after one untimed warm-up.\n\n" + "\n".join(found)
        self.section("6. Start-up", text)

    def imported(self, command: Sequence[str]) -> set[str]:
        env = self.runner.env(PYTHONPROFILEIMPORTTIME="1")
        done = subprocess.run(list(command), capture_output=True, text=True, timeout=self.runner.timeout, cwd=self.tmp, env=env)
        return {m.group(1).split(".")[0] for m in re.finditer(r"import time:\s+\d+ \|\s+\d+ \| *(\S+)", done.stderr)}


# -- the report --------------------------------------------------------------------------------


def git(tree: Path, *args: str) -> str:
    try:
        return subprocess.run(["git", "-C", str(tree), *args], capture_output=True, text=True, timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def imported_from(runner: Runner) -> str:
    done = subprocess.run([PYTHON, "-c", "import lagrange_cli; print(lagrange_cli.__file__)"], capture_output=True, text=True, env=runner.env(), cwd=runner.tmp, timeout=120)
    return done.stdout.strip() or done.stderr.strip().splitlines()[-1]


def machine(runner: Runner, source: str) -> list[str]:
    cpu = "unknown"
    memory = "unknown"
    try:
        info = Path("/proc/cpuinfo").read_text()
        cpu = re.search(r"model name\s*:\s*(.*)", info).group(1).strip()  # type: ignore[union-attr]
        kb = int(re.search(r"MemTotal:\s*(\d+)", Path("/proc/meminfo").read_text()).group(1))  # type: ignore[union-attr]
        memory = f"{kb / 2**20:.1f} GiB"
    except (OSError, AttributeError):
        pass
    versions = []
    for package in ("sympy", "symengine", "numpy", "scipy", "numba", "typer"):
        try:
            versions.append(f"{package} {metadata.version(package)}")
        except metadata.PackageNotFoundError:
            versions.append(f"{package} (not installed)")
    commit = git(runner.tree, "rev-parse", "--short", "HEAD") or "unknown"
    changed = git(runner.tree, "log", "-1", "--format=%h", "--", "lagrange_cli")
    branch = git(runner.tree, "rev-parse", "--abbrev-ref", "HEAD")
    dirty = git(runner.tree, "status", "--porcelain", "--", "lagrange_cli")
    return [
        f"- CPU: {cpu}; nproc = {os.cpu_count()} (usable: {len(os.sched_getaffinity(0))}); memory {memory}",
        f"- OS: {platform.platform()}; Python {platform.python_version()} ({platform.python_implementation()})",
        f"- Libraries: {', '.join(versions)}",
        f"- lagrange source: commit {commit}"
        + (f" (branch {branch})" if branch and branch != "HEAD" else "")
        + (f", lagrange_cli/ last changed in {changed}" if changed else "")
        + (" plus uncommitted changes in lagrange_cli/" if dirty else "")
        + f"; `lagrange_cli` imported from `{source}`",
    ]


def report(bench: Bench, info: list[str], started: datetime.datetime, elapsed: float, loads: tuple[float, float], argv: Sequence[str]) -> str:
    rows = [[what, goal, measured, {True: "PASS", False: "**FAIL**", None: "not measured"}[passed]] for what, goal, measured, passed in bench.targets]
    during = bench.runner.loads or [loads[0]]
    command = ".venv/bin/python benchmarks/run.py" + "".join(" " + shlex.quote(a) for a in argv)
    busy = max(loads[0], loads[1], *during) > 1
    lines = [
        f"Run on {started:%Y-%m-%d %H:%M} UTC with `{command}` (took {elapsed / 60:.1f} min).",
        "",
        *info,
        f"- Load average (1 min) at start / end: {loads[0]:.2f} / {loads[1]:.2f}; at the start of each measured process: {min(during):.2f} to {max(during):.2f}"
        + (": the machine was shared with other work, so absolute times are noisy (CPU times are shown beside wall times); the ratios are measured side by side." if busy else ": quiet."),
        "",
        "### Targets",
        "",
        f"Times, ratios and fits are judged on the **{'CPU' if bench.runner.clock == 'cpu' else 'wall'} time** of whole processes (`--clock`); both are shown.",
        "",
        table(["what", "target", "measured (whole processes: wall, CPU in parentheses)", "result"], rows),
        "",
        "### Commands",
        "",
        "Each a fresh process with `PYTHONPATH` set to the tree under test (its `lagrange_cli` byte-compiled first, as an install does, unless `--no-compile`) and an empty `LAGRANGE_CACHE_DIR` and `NUMBA_CACHE_DIR`, "
        f"killed after {bench.runner.timeout:g} s (then reported as over {bench.runner.timeout:g} s); CHAIN.yaml is written by `benchmarks/pendulum.py` (`Chain(KIND, N).yaml()`):",
        "",
        *(f"- `{c}`" for c in bench.commands),
        "- `python benchmarks/worker.py check KIND N out.py` (every module, both tools)",
        "",
        *(part + "\n" for part in bench.parts),
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


def byte_compile(tree: Path) -> None:
    """Write lagrange_cli's bytecode (`__pycache__`, ignored by git), as `pip install` does for the
    installed CLI: with PYTHONDONTWRITEBYTECODE set, a fresh process would otherwise compile every
    module of lagrange_cli from source each time (about 0.05 s of CPU), which the peer, imported
    from site-packages, never pays."""
    done = subprocess.run([PYTHON, "-m", "compileall", "-q", str(tree / "lagrange_cli")], capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"could not byte-compile {tree / 'lagrange_cli'}: {failure(done.stdout + done.stderr)}")


def sizes_list(text: str) -> list[int]:
    try:
        values = sorted({int(v) for v in text.split(",") if v.strip()})
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if not values or values[0] < 1:
        raise argparse.ArgumentTypeError("sizes must be positive integers")
    return values


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="no peer at N >= 10 (so no N = 15 ratios)")
    parser.add_argument("--only", default=",".join(ROWS), help=f"comma-separated rows to run, from {','.join(ROWS)}")
    parser.add_argument("--sizes", type=sizes_list, default=list(SIZES), help=f"chain sizes of the general and equal rows (default {','.join(map(str, SIZES))})")
    parser.add_argument("--repeats", type=int, default=3, help="runs per measurement (the fastest is kept; one run when it takes over 10 s)")
    parser.add_argument("--timeout", type=float, default=TIMEOUT, help="seconds after which a process is killed and reported as over that time")
    parser.add_argument("--clock", choices=("wall", "cpu"), default="wall", help="the time targets, ratios and fits use: wall (default) or CPU time of the processes (both are always shown)")
    parser.add_argument("--tree", type=Path, default=ROOT, help="the lagrange tree under test (put on PYTHONPATH); default: this checkout")
    parser.add_argument(
        "--compile",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="byte-compile the tree under test first, as installing the package does (default); --no-compile measures processes that compile lagrange_cli from source when PYTHONDONTWRITEBYTECODE is set",
    )
    parser.add_argument("--write", action="store_true", help="write BENCHMARKS.md even when not a complete run")
    parser.add_argument("--no-write", action="store_true", help="print only")
    args = parser.parse_args(argv)
    only = [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = set(only) - set(ROWS)
    if unknown:
        parser.error(f"unknown row(s): {', '.join(sorted(unknown))} (expected {', '.join(ROWS)})")
    started = datetime.datetime.now(datetime.timezone.utc)
    clock = time.perf_counter()
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="lagrange-bench-") as tmp:
        runner = Runner(args.tree.resolve(), Path(tmp), args.timeout, args.clock)
        if args.compile:
            byte_compile(runner.tree)
        source = imported_from(runner)
        if not Path(source).resolve().is_relative_to(runner.tree):
            parser.error(f"lagrange_cli is imported from {source}, not from the tree under test {runner.tree}")
        info = machine(runner, source)  # at the start: the commit measured, not one made during the run
        bench = Bench(runner, args.sizes, args.quick, args.repeats)
        for name in ROWS:
            if name in only:
                getattr(bench, METHODS.get(name, name))()
        markdown = report(bench, info, started, time.perf_counter() - clock, (load_before, os.getloadavg()[0]), sys.argv[1:] if argv is None else argv)
    print(markdown)
    complete = not args.quick and set(only) == set(ROWS) and args.sizes == list(SIZES) and args.tree.resolve() == ROOT
    if not args.no_write and (complete or args.write):
        log(f"written to {write(markdown)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
