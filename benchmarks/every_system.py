"""`lagrange accuracy` and `lagrange stress` on every bundled system, through the real CLI.

For each file in systems/ it runs, as subprocesses with the numba cache warm:

    lagrange accuracy FILE --json -        (every method x 1e-3..1e-8)
    lagrange stress FILE --json -          (every method, the default regimes, error 1e-6)

and records the exit code, the wall time, the fastest method per accuracy level, and per stress
regime the diagnosis, scipy's default RK45, and the recommended method. The table goes to
stdout, and with --write into BENCHMARKS.md between the `every-system` markers.

    .venv/bin/python benchmarks/every_system.py [--write] [NAME ...]

With NAMEs, --write replaces only those systems' rows of the table already there.

A full sweep takes about an hour on a 2-core machine (stress spends most of it on scipy's methods on
long horizons, which run until their counted step budget, `--max-steps`).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LAGRANGE = ROOT / ".venv" / "bin" / "lagrange"
BEGIN, END = "<!-- every-system:begin -->", "<!-- every-system:end -->"


def run(*args: str) -> tuple[int, float, dict[str, object] | None, str]:
    began = time.perf_counter()
    done = subprocess.run([str(LAGRANGE), *args, "--json", "-"], capture_output=True, text=True)
    seconds = time.perf_counter() - began
    try:
        document = json.loads(done.stdout)
    except json.JSONDecodeError:
        document = None
    tail = (done.stderr.strip().splitlines() or [""])[-1]
    return done.returncode, seconds, document, tail


def accuracy_cell(code: int, seconds: float, document: dict[str, object] | None, tail: str) -> str:
    if document is None:
        return f"exit {code}: {tail}"
    fastest = document["fastest"]
    assert isinstance(fastest, list)
    best = {f["error"]: f for f in fastest}
    levels = [level for level in (1e-4, 1e-6, 1e-8) if level in best] or sorted(best)[:1]  # else the tightest reached
    parts = [f"{level:.0e}: {best[level]['method']} {best[level]['seconds'] * 1e3:.3g} ms" for level in levels]
    horizon = document.get("horizon")
    chaotic = f" (chaotic, to t = {document['t_end']:.3g})" if isinstance(horizon, dict) and horizon.get("chaotic") else ""
    return f"exit {code}, {seconds:.0f} s{chaotic}; " + ("; ".join(parts) or "no level reached")


def stress_cells(code: int, seconds: float, document: dict[str, object] | None, tail: str) -> list[str]:
    if document is None:
        return [f"exit {code}: {tail}"]
    regimes = document["regimes"]
    assert isinstance(regimes, list)
    cells = []
    for r in regimes:
        findings = "; ".join(f.split(": ")[0] for f in r["findings"] if not f.startswith(("RK45:python", "Radau", "BDF", "LSODA"))) or "benign"
        naive = r.get("naive_default")
        naive_text = "-" if naive is None else (f"{naive['error']:.1e} in {naive['seconds'] * 1e3:.3g} ms" if naive["error"] is not None else naive["status"])
        best = r["recommended"]
        best_text = f"{best['ran']} {best['setting']}: {best['error']:.1e} in {best['seconds'] * 1e3:.3g} ms" if best else "**none**"
        cells.append(f"{r['regime']} [{findings}]: RK45 default {naive_text} -> {best_text}")
    return cells


def main() -> None:
    write = "--write" in sys.argv
    names = [a for a in sys.argv[1:] if not a.startswith("--")]
    files = sorted((ROOT / "systems").glob("*.yaml")) if not names else [ROOT / "systems" / f"{n}.yaml" for n in names]
    subprocess.run([str(LAGRANGE), "simulate", "double_pendulum", "--t-end", "0.1"], capture_output=True)  # fills numba's kernel cache
    lines = [
        "| system | accuracy: exit, wall time; fastest per error level | stress: exit, wall time | stress regimes: [diagnosis] scipy RK45 at its defaults -> recommended (error 1e-6) |",
        "|---|---|---|---|",
    ]
    total = time.perf_counter()
    for path in files:
        a = run("accuracy", str(path))
        s = run("stress", str(path))
        regimes = stress_cells(*s)
        met = isinstance(s[2], dict) and s[2].get("passed")
        line = f"| {path.stem} | {accuracy_cell(*a)} | exit {s[0]}, {s[1]:.0f} s, {'all regimes met' if met else 'not all met'} | {'<br>'.join(regimes)} |"
        print(line, flush=True)
        lines.append(line)
    minutes = (time.perf_counter() - total) / 60
    command = "`.venv/bin/python benchmarks/every_system.py --write`"
    lines.append(f"\n{len(files)} systems in {minutes:.0f} min ({command}).")
    if write:
        target = ROOT / "BENCHMARKS.md"
        text = target.read_text()
        if names and BEGIN in text:  # replace only the rows of the systems run now
            start, stop = text.index(BEGIN) + len(BEGIN), text.index(END)
            fresh = {line.split(" | ")[0]: line for line in lines[2:-1]}
            kept = [fresh.pop(line.split(" | ")[0], line) for line in text[start:stop].strip("\n").splitlines()]
            last_row = max(i for i, line in enumerate(kept) if line.startswith("|"))
            kept[last_row + 1 : last_row + 1] = fresh.values()
            text = text[:start] + "\n" + "\n".join(kept) + "\n" + text[stop:]
        else:
            block = BEGIN + "\n" + "\n".join(lines) + "\n" + END
            text = text[: text.index(BEGIN)] + block + text[text.index(END) + len(END) :] if BEGIN in text else text.rstrip() + "\n\n" + block + "\n"
        target.write_text(text)


if __name__ == "__main__":
    main()
