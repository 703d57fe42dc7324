"""The benchmark suite (`make bench`): lagrange against its peers, on the planar N-link pendulum.

    .venv/bin/python benchmarks/run.py            # everything (several minutes)
    .venv/bin/python benchmarks/run.py --quick    # no peer derivation at N >= 10
    .venv/bin/python benchmarks/run.py --only derive,rhs --no-write

1. derivation (file to M, F): `spec.load` + `derive.derive` vs sympy.physics.mechanics'
   LagrangesMethod, N = 2, 5, 10, 15 (the peer is not run at N = 30: extrapolated only);
2. file to Python module (spec.load + derive + python.emit) for every N, and the CLI
   `lagrange derive FILE --python -o out.py` at N = 30;
3. the emitted rhs per call: N = 2 against a hand-written `math` rhs, N = 15 against
   lambdify(cse=True, numpy) of LagrangesMethod's M and F + numpy.linalg.solve;
4. start-up of `lagrange --help` against `python -c pass`, and what the commands import.

Every number is a minimum over repeats; every claim is a ratio to a peer measured in the
same run. Results are printed as markdown and written between the markers in
BENCHMARKS.md (a full run writes by default, `--quick` only with `--write`).
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import re
import shlex
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from functools import partial
from importlib import metadata
from pathlib import Path
from typing import Any

import pendulum

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PYTHON = sys.executable
LAGRANGE = str(Path(PYTHON).parent / "lagrange")
SIZES = (2, 5, 10, 15, 30)
PEER_MAX = 15  # the peer takes over a minute at N = 15 and grows ~N^3.3
SLOW = 30.0  # a measurement slower than this is not repeated
TIMEOUT = 1800
BEGIN, END = "<!-- bench:begin -->", "<!-- bench:end -->"
SECTIONS = ("derive", "e2e", "rhs", "startup")
AGREE = 1e-9  # max relative deviation for two results to count as the same


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


# -- running things ---------------------------------------------------------------------------


def worker(*args: object) -> dict[str, Any]:
    """Run benchmarks/worker.py in a fresh interpreter; its RESULT line, or {"error": ...}."""
    command = [PYTHON, str(HERE / "worker.py"), *map(str, args)]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=TIMEOUT, cwd=ROOT)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {TIMEOUT} s"}
    for line in reversed(done.stdout.splitlines()):
        if line.startswith("RESULT "):
            value: dict[str, Any] = json.loads(line[len("RESULT ") :])
            return value
    lines = [line for line in done.stderr.strip().splitlines() if line.strip()]
    return {"error": lines[-1] if lines else f"exit status {done.returncode}"}


def best(runs: int, measure: Callable[[], dict[str, Any]], key: str = "seconds") -> dict[str, Any]:
    """The fastest of up to `runs` measurements; stops early when one fails or is slower than SLOW."""
    found: dict[str, Any] | None = None
    for run in range(1, runs + 1):
        value = measure()
        if "error" in value:
            return value
        if found is None or value[key] < found[key]:
            found = value
        found["runs"] = run
        if value[key] > SLOW:
            break
    assert found is not None
    return found


def wall(command: Sequence[str], runs: int, env: dict[str, str] | None = None, warmup: bool = True) -> dict[str, Any]:
    """Wall time of a command (min over runs), after one untimed warm-up run."""

    def once() -> dict[str, Any]:
        start = time.perf_counter()
        done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=TIMEOUT, cwd=ROOT, env=env)
        seconds = time.perf_counter() - start
        if done.returncode != 0:
            lines = done.stderr.strip().splitlines()
            return {"error": lines[-1] if lines else f"exit status {done.returncode}"}
        return {"seconds": seconds}

    if warmup:
        first = once()
        if "error" in first:
            return first
        if first["seconds"] > SLOW:
            return first
    return best(runs, once)


MODULES = """
import atexit, json, sys
def report():
    names = sorted({m.split(".")[0] for m, v in sys.modules.items() if v is not None})
    print("MODULES " + json.dumps(names), file=sys.__stderr__)
atexit.register(report)
sys.argv = ["lagrange", *sys.argv[1:]]
from lagrange_cli.cli import main
main()
"""


def loaded_modules(arguments: Sequence[str]) -> set[str]:
    """Top-level packages in sys.modules when the CLI exits (run in-process via cli.main)."""
    done = subprocess.run([PYTHON, "-c", MODULES, *arguments], capture_output=True, text=True, timeout=TIMEOUT, cwd=ROOT)
    for line in done.stderr.splitlines():
        if line.startswith("MODULES "):
            return set(json.loads(line[len("MODULES ") :]))
    raise RuntimeError(f"no module list from lagrange {' '.join(arguments)}: {done.stderr[-300:]}")


def imported(command: Sequence[str]) -> tuple[set[str], list[tuple[str, float]]]:
    """Top-level packages a command imports (PYTHONPROFILEIMPORTTIME, i.e. -X importtime),
    and the slowest top-level imports with their cumulative seconds."""
    env = {**os.environ, "PYTHONPROFILEIMPORTTIME": "1"}
    done = subprocess.run(command, capture_output=True, text=True, timeout=TIMEOUT, cwd=ROOT, env=env)
    packages: set[str] = set()
    top: list[tuple[str, float]] = []
    for line in done.stderr.splitlines():
        match = re.match(r"import time:\s+(\d+) \|\s+(\d+) \|( *)(\S+)", line)
        if match:
            name = match.group(4)
            packages.add(name.split(".")[0])
            if len(match.group(3)) == 1:
                top.append((name, int(match.group(2)) / 1e6))
    return packages, sorted(top, key=lambda item: -item[1])[:5]


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
    return "error: " + str(value["error"]).replace("|", "/")[:160]


def relative_error(a: Sequence[Any], b: Sequence[Any]) -> float:
    def flat(x: Any) -> list[float]:
        return [v for row in x for v in (row if isinstance(row, list) else [row])]

    fa, fb = flat(a), flat(b)
    scale = max(abs(v) for v in fb) or 1.0
    return max(abs(x - y) for x, y in zip(fa, fb, strict=True)) / scale


def power_fit(points: Sequence[tuple[int, float]]) -> tuple[float, float] | None:
    """t = c N^k by least squares in log-log; (c, k)."""
    if len(points) < 2:
        return None
    xs = [math.log(n) for n, _ in points]
    ys = [math.log(t) for _, t in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    k = sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True)) / sum((x - mx) ** 2 for x in xs)
    return math.exp(my - k * mx), k


# -- the sections ------------------------------------------------------------------------------


class Bench:
    def __init__(self, quick: bool, tmp: Path) -> None:
        self.quick = quick
        self.tmp = tmp
        self.targets: list[tuple[str, str, str, bool | None]] = []  # (what, target, measured, passed)
        self.parts: list[str] = []
        self.files: dict[int, Path] = {}
        for n in SIZES:
            path = tmp / f"pendulum_{n}.yaml"
            path.write_text(pendulum.system_yaml(n))
            self.files[n] = path
        self.modules: dict[int, Path] = {}
        self.peer_pickle: Path | None = None

    def target(self, what: str, goal: str, measured: str, passed: bool | None) -> None:
        self.targets.append((what, goal, measured, passed))

    def section(self, title: str, text: str) -> None:
        self.parts.append(f"### {title}\n\n{text}")
        log(f"\n### {title}\n\n{text}\n")

    # 1 ---------------------------------------------------------------------------------------

    def derive(self) -> None:
        rows: list[list[object]] = []
        fits: dict[str, list[tuple[int, float]]] = {"lagrange": [], "peer": []}
        found: dict[int, tuple[dict[str, Any], dict[str, Any] | None]] = {}
        for n in SIZES:
            log(f"derive N={n}: lagrange")
            ours = best(5, partial(worker, "derive-lagrange", n, self.files[n]))
            theirs: dict[str, Any] | None = None
            if n <= PEER_MAX and not (self.quick and n >= 10):
                log(f"derive N={n}: peer (LagrangesMethod)")
                save = self.tmp / f"peer_{n}.pickle" if n == 15 else ""
                theirs = best(3 if n <= 5 else 1, partial(worker, "derive-peer", n, save))
                if save and "error" not in theirs:
                    self.peer_pickle = Path(save)
            found[n] = (ours, theirs)
            y = pendulum.state(n)
            mass, force = pendulum.reference_matrices(y)
            agree = []
            for name, value in (("lagrange", ours), ("peer", theirs)):
                if value is not None and "error" not in value:
                    fits[name].append((n, value["seconds"]))
                    agree.append(f"{name} {max(relative_error(value['M'], mass), relative_error(value['F'], force)):.0e}")
            row: list[object] = [n]
            row += [error_text(ours), "", ""] if "error" in ours else [seconds(ours["seconds"]), seconds(ours["load"]), seconds(ours["derive"])]
            if theirs is None:
                row += ["not run" + (" (--quick)" if self.quick and n <= PEER_MAX else ""), "-"]
            elif "error" in theirs:
                row += [error_text(theirs), "-"]
            else:
                row += [seconds(theirs["seconds"]), ratio(theirs["seconds"] / ours["seconds"]) if "error" not in ours else "-"]
            rows.append([*row, ", ".join(agree) or "-"])
        peer_fit = power_fit([(n, t) for n, t in fits["peer"] if n >= 5])
        ours_fit = power_fit([(n, t) for n, t in fits["lagrange"] if n >= 5])
        notes = []
        if peer_fit:
            c, k = peer_fit
            lag30 = found[30][0]
            extrapolated = c * 30**k
            note = f"Peer at N = 30 **not run**; extrapolated from its N >= 5 points as t = {c:.3g} N^{k:.2f}: about {seconds(extrapolated)}"
            if "error" not in lag30:
                note += f", i.e. about {ratio(extrapolated / lag30['seconds'])} lagrange's measured {seconds(lag30['seconds'])} (an extrapolation, not a measurement)"
            notes.append(note + ".")
        if ours_fit:
            notes.append(f"lagrange's own growth over N >= 5: t ~ N^{ours_fit[1]:.2f}.")
        text = table(
            ["N", "lagrange load+derive", "of which spec.load", "of which derive", "peer LagrangesMethod", "peer / lagrange", "max rel. deviation of M, F from the hand-written reference"], rows
        )
        text += "\n\nlagrange: min of 5 fresh processes; peer: min of 3 fresh processes at N <= 5, a single run at N >= 10. Imports are excluded from both clocks. " + " ".join(notes)
        self.section("1. Derivation: system to mass matrix and forcing", text)
        ours, theirs = found[15]
        if theirs is not None and "error" not in theirs and "error" not in ours:
            r = theirs["seconds"] / ours["seconds"]
            y = pendulum.state(15)
            mass, force = pendulum.reference_matrices(y)
            same = all(max(relative_error(v["M"], mass), relative_error(v["F"], force)) < AGREE for v in (ours, theirs))
            self.target("derivation at N = 15, peer / lagrange", ">= 100x", ratio(r) if same else "results disagree", same and r >= 100)
        else:
            self.target("derivation at N = 15, peer / lagrange", ">= 100x", "not measured" + (" (--quick)" if self.quick else ""), None)

    # 2 ---------------------------------------------------------------------------------------

    def e2e(self) -> None:
        rows: list[list[object]] = []
        for n in SIZES:
            log(f"file to module N={n}")
            out = self.tmp / f"pendulum_{n}_eom.py"
            value = best(3, partial(worker, "emit", n, self.files[n], out))
            if "error" in value:
                rows.append([n, error_text(value), "", "", "", ""])
                if n == 30:
                    self.target("file to Python module at N = 30 (library)", "< 10 s", "failed", False)
                continue
            self.modules[n] = out
            rows.append([n, seconds(value["seconds"]), seconds(value["load"]), seconds(value["derive"]), seconds(value["emit"]), value["lines"]])
            if n == 30:
                self.target("file to Python module at N = 30 (library)", "< 10 s", seconds(value["seconds"]), value["seconds"] < 10)
        text = table(["N", "load + derive + emit", "spec.load", "derive.derive", "python.emit", "lines of code"], rows)
        text += "\n\nMin of up to 3 fresh processes (a single run when one takes over 30 s), imports excluded."
        log("CLI N=30")
        out = self.tmp / "cli_30.py"
        command = [LAGRANGE, "derive", str(self.files[30]), "--python", "-o", str(out)]
        cli = wall(command, 3, warmup=False)
        shown = "lagrange derive pendulum_30.yaml --python -o out.py"
        if "error" in cli:
            text += f"\n\nCLI `{shown}`: {error_text(cli)}"
            self.target("CLI at N = 30, wall time (info)", "< 10 s", "failed", False)
        else:
            text += f"\n\nCLI `{shown}` at N = 30: **{seconds(cli['seconds'])}** wall (min of up to 3; includes interpreter start and imports)."
            self.target("CLI at N = 30, wall time (info)", "< 10 s", seconds(cli["seconds"]), cli["seconds"] < 10)
        self.section("2. End to end: system file to Python module", text)

    # 3 ---------------------------------------------------------------------------------------

    def rhs(self) -> None:
        for n in (2, 15, 30):
            if n not in self.modules:
                out = self.tmp / f"pendulum_{n}_eom.py"
                log(f"file to module N={n} (for rhs)")
                value = worker("emit", n, self.files[n], out)
                if "error" not in value:
                    self.modules[n] = out
        rows: list[list[object]] = []
        checks = []
        for n, peer_name in ((2, "hand"), (15, "peer"), (30, None)):
            if n not in self.modules:
                rows.append([n, "no module (emit failed)", "", "", "", "", ""])
                continue
            args: list[object] = ["rhs", n, self.modules[n]]
            if peer_name == "peer":
                if self.peer_pickle is None:
                    rows.append([n, "peer not derived" + (" (--quick)" if self.quick else ""), "", "", "", "", ""])
                    self.target("rhs per call at N = 15, peer / lagrange", ">= 5x", "not measured" + (" (--quick)" if self.quick else ""), None)
                    continue
                args.append(self.peer_pickle)
            log(f"rhs N={n}")
            value = worker(*args)
            if "error" in value:
                rows.append([n, error_text(value), "", "", "", "", ""])
                continue
            label = {"hand": "hand-written `math` rhs", "peer": "lambdify(cse) + numpy.linalg.solve", None: "(none)"}[peer_name]
            row: list[object] = [n, label]
            for kind in ("list", "ndarray"):
                times = value[kind]
                row.append(seconds(times["lagrange"]))
                if peer_name:
                    row.append(seconds(times[peer_name]))
                    row.append(ratio(times["lagrange"] / times[peer_name]) if peer_name == "hand" else ratio(times[peer_name] / times["lagrange"]))
                else:
                    row += ["-", "-"]
            rows.append(row)
            errors = ", ".join(f"{k} {v:.0e}" for k, v in value["max_error"].items())
            check = f"N = {n}: max relative deviation from the numeric reference at a random state: {errors}"
            if "lagrange_vs_peer" in value:
                check += f"; lagrange vs peer {value['lagrange_vs_peer']:.0e}; lambdify itself took {seconds(value['peer_lambdify_seconds'])}"
            checks.append(check)
            agree = all(v < AGREE for v in value["max_error"].values()) and value.get("lagrange_vs_peer", 0.0) < AGREE
            if not agree:
                check += " -- **the values disagree, so the timings below are not comparable**"
            checks[-1:] = [check]
            if "numba" in value["list"]:
                compiled = value["list"]["numba"]
                note = f"N = {n}: `lagrange derive --python --numba` rhs: {seconds(compiled)} per call (list y), {seconds(value['ndarray']['numba'])} (ndarray y); first call, compiling or loading the cache: {seconds(value['numba_first_call_seconds'])}"
                if peer_name == "peer":
                    note += f"; peer / numba: {ratio(value['list']['peer'] / compiled)}"
                    self.target("rhs per call at N = 15 with --numba, peer / lagrange", ">= 5x", ratio(value["list"]["peer"] / compiled), value["list"]["peer"] / compiled >= 5)
                checks.append(note)
            if peer_name == "hand":
                r = value["list"]["lagrange"] / value["list"]["hand"]
                measured = ratio(r) + f" (ndarray y: {ratio(value['ndarray']['lagrange'] / value['ndarray']['hand'])})"
                self.target("rhs per call at N = 2, lagrange / hand-written", "<= 1.5x", measured if agree else "values disagree", agree and r <= 1.5)
            elif peer_name == "peer":
                r = value["list"]["peer"] / value["list"]["lagrange"]
                measured = ratio(r) + f" (ndarray y: {ratio(value['ndarray']['peer'] / value['ndarray']['lagrange'])})"
                self.target("rhs per call at N = 15, peer / lagrange", ">= 5x", measured if agree else "values disagree", agree and r >= 5)
        text = table(["N", "peer", "lagrange (y list)", "peer (y list)", "ratio", "lagrange (y ndarray)", "peer (y ndarray)", "ratio"], rows)
        text += (
            "\n\nSeconds per call of `rhs(0.0, y, p)`, timeit, min over 25 interleaved samples of ~40 ms each, "
            "with y a list of floats and with y a numpy array (what solve_ivp passes). "
            "Ratio at N = 2 is lagrange / hand-written (lower is better, target <= 1.5), at N = 15 peer / lagrange (target >= 5). "
            "Same parameter values (m = 1, l = 1, g = 9.81) everywhere.\n\n" + "\n".join(f"- {c}" for c in checks)
        )
        self.section("3. The emitted rhs, per call", text)

    # 4 ---------------------------------------------------------------------------------------

    def startup(self) -> None:
        log("start-up")
        rows: list[list[object]] = []
        measured: dict[str, dict[str, Any]] = {}
        commands = {
            "python -c pass": [PYTHON, "-c", "pass"],
            "python -c 'import sympy'": [PYTHON, "-c", "import sympy"],
            "lagrange --help": [LAGRANGE, "--help"],
            "lagrange derive double_pendulum": [LAGRANGE, "derive", "double_pendulum"],
        }
        for name, command in commands.items():
            runs = 10 if "derive" not in name else 5
            value = wall(command, runs)
            measured[name] = value
            if "error" in value:
                rows.append([name, error_text(value), "", ""])
                continue
            base = measured["python -c pass"].get("seconds")
            rows.append([name, seconds(value["seconds"]), ratio(value["seconds"] / base) if base else "-", runs])
        text = table(["command", "wall (min)", "vs python -c pass", "runs"], rows)
        help_time = measured["lagrange --help"].get("seconds")
        self.target("`lagrange --help` wall time", "< 0.25 s", seconds(help_time) if help_time else "failed", help_time is not None and help_time < 0.25)
        found = []
        for name, arguments, banned in (
            ("lagrange --help", ["--help"], ("sympy", "numpy", "scipy")),
            ("lagrange derive double_pendulum", ["derive", "double_pendulum"], ("numpy", "scipy", "matplotlib")),
        ):
            packages, top = imported([LAGRANGE, *arguments])
            modules = loaded_modules(arguments)
            bad = [b for b in banned if b in packages or b in modules]
            verdict = "imports " + ", ".join(bad) if bad else "imports none of " + ", ".join(banned)
            verdict += f" (-X importtime: {', '.join(b for b in banned if b in packages) or 'none'}; sys.modules at exit: {', '.join(b for b in banned if b in modules) or 'none'})"
            slowest = ", ".join(f"{module} {seconds(t)}" for module, t in top)
            found.append(f"- `{name}`: {verdict}; slowest top-level imports under -X importtime: {slowest}")
            self.target(f"`{name}` imports no {'/'.join(banned)}", "none", ", ".join(bad) or "none", not bad)
        text += (
            "\n\nWall time of a subprocess, after one untimed warm-up run. Imports traced twice: `PYTHONPROFILEIMPORTTIME=1` (= `python -X importtime`) on the installed `lagrange` script, and `sys.modules` at exit of `cli.main()` run in-process:\n\n"
            + "\n".join(found)
        )
        self.section("4. Start-up", text)


# -- the report --------------------------------------------------------------------------------


def machine() -> list[str]:
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
    for package in ("lagrange-cli", "sympy", "symengine", "numpy", "scipy", "typer"):
        try:
            versions.append(f"{package} {metadata.version(package)}")
        except metadata.PackageNotFoundError:
            versions.append(f"{package} (not installed)")

    def git(*args: str) -> str:
        try:
            return subprocess.run(["git", *args], capture_output=True, text=True, cwd=ROOT, timeout=30).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    commit = git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = git("status", "--porcelain", "--", "lagrange_cli")
    return [
        f"- CPU: {cpu}; nproc = {os.cpu_count()} (usable: {len(os.sched_getaffinity(0))}); memory {memory}",
        f"- OS: {platform.platform()}; Python {platform.python_version()} ({platform.python_implementation()})",
        f"- Libraries: {', '.join(versions)}",
        f"- lagrange source: commit {commit}" + (" plus uncommitted changes in lagrange_cli/" if dirty else ""),
    ]


def report(bench: Bench, started: datetime.datetime, elapsed: float, loads: tuple[Sequence[float], Sequence[float]], argv: Sequence[str]) -> str:
    rows = [[what, goal, measured, {True: "PASS", False: "**FAIL**", None: "not measured"}[passed]] for what, goal, measured, passed in bench.targets]
    before, after = loads
    command = ".venv/bin/python benchmarks/run.py" + "".join(" " + shlex.quote(a) for a in argv)
    lines = [
        f"Run on {started:%Y-%m-%d %H:%M} UTC with `{command}` (took {elapsed / 60:.1f} min).",
        "",
        *machine(),
        f"- Load average (1 min) at start / end: {before[0]:.2f} / {after[0]:.2f}: the machine was "
        + ("shared with other work, so absolute times are noisy; the ratios are measured side by side." if max(before[0], after[0]) > 1 else "quiet."),
        "",
        "### Targets",
        "",
        table(["what", "target", "measured", "result"], rows),
        "",
        *(part + "\n" for part in bench.parts),
    ]
    return "\n".join(lines).rstrip() + "\n"


HEADER = """# Benchmarks

Generated by `benchmarks/run.py` (`make bench`); the part between the markers below is
rewritten by each full run.

"""


def write(markdown: str) -> Path:
    path = ROOT / "BENCHMARKS.md"
    block = f"{BEGIN}\n{markdown}{END}"
    text = path.read_text() if path.exists() else HEADER + f"{BEGIN}\n{END}\n"
    if BEGIN in text and END in text:
        head, rest = text.split(BEGIN, 1)
        text = head + block + rest.split(END, 1)[1]
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    path.write_text(text)
    return path


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="skip the peer derivation at N >= 10 (and so the N = 15 rhs comparison)")
    parser.add_argument("--only", default=",".join(SECTIONS), help=f"comma-separated sections to run, from {','.join(SECTIONS)} (rhs needs derive for its N = 15 peer)")
    parser.add_argument("--write", action="store_true", help="write BENCHMARKS.md even with --quick or --only")
    parser.add_argument("--no-write", action="store_true", help="print only")
    args = parser.parse_args(argv)
    only = [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = set(only) - set(SECTIONS)
    if unknown:
        parser.error(f"unknown section(s): {', '.join(sorted(unknown))}")
    started = datetime.datetime.now(datetime.timezone.utc)
    clock = time.perf_counter()
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="lagrange-bench-") as tmp:
        bench = Bench(args.quick, Path(tmp))
        for name in SECTIONS:
            if name in only:
                getattr(bench, name)()
        markdown = report(bench, started, time.perf_counter() - clock, (load_before, os.getloadavg()), sys.argv[1:] if argv is None else argv)
    print(markdown)
    complete = not args.quick and set(only) == set(SECTIONS)
    if not args.no_write and (complete or args.write):
        log(f"written to {write(markdown)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
