"""The long fuzz run (`make fuzz`): tests/fuzzing.py's cases by the ten thousand.

    python benchmarks/fuzz.py --count 100000 --workers 2 --seed 1 --write

Each worker draws cases from `tests.fuzzing.cases()` (mutated bundled files and systems built from
generated expressions) with its own hypothesis seed, and runs each through `run_case`: load,
derive, the Lagrange form in text and LaTeX, standalone LaTeX, Python and the written module's
rhs; one case in `--full-every` also gets the matrix and solved forms, check and info, and one in
`--simulate-every` a short simulation (code generation, import and scipy: the expensive steps).
Failures are deduplicated by step, kind (the exception type) and the innermost frame in
lagrange_cli (or the generated module); the first file text of each is kept, and with `--save DIR`
written there as a reproducer. `--write` refreshes the results section of FUZZ.md.
"""

from __future__ import annotations

import argparse
import multiprocessing
import platform
import re
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
BEGIN, END = "<!-- fuzz:begin -->", "<!-- fuzz:end -->"


@dataclass
class Tally:
    executions: int = 0
    full: int = 0
    simulated: int = 0
    failing_cases: int = 0
    seconds: float = 0.0
    cpu: float = 0.0
    """CPU seconds of the workers (the rate per CPU second does not depend on the machine's load)."""
    failures: dict[str, tuple[int, str, str]] = field(default_factory=dict)
    """key -> (count, first detail, first file text)."""

    def add(self, other: Tally) -> None:
        self.executions += other.executions
        self.full += other.full
        self.simulated += other.simulated
        self.failing_cases += other.failing_cases
        self.seconds = max(self.seconds, other.seconds)
        self.cpu += other.cpu
        for key, (count, detail, text) in other.failures.items():
            mine = self.failures.get(key)
            self.failures[key] = (count + (mine[0] if mine else 0), mine[1] if mine else detail, mine[2] if mine else text)


def work(job: tuple[int, int, int, int, float, int]) -> Tally:
    """One worker: `count` cases from hypothesis seed `seed`."""
    count, seed, full_every, every, limit, max_seconds = job
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as with_seed

    from tests.fuzzing import cases, run_case

    tally = Tally()
    start, cpu = time.perf_counter(), time.process_time()
    with tempfile.TemporaryDirectory(prefix="lagrange-fuzz-") as scratch:

        @with_seed(seed)
        @settings(max_examples=count, database=None, deadline=None, suppress_health_check=list(HealthCheck), phases=[Phase.generate])
        @given(cases())
        def one(text: str) -> None:
            if max_seconds and time.perf_counter() - start > max_seconds:
                return
            simulate = every > 0 and tally.executions % every == 0
            full = simulate or (full_every > 0 and tally.executions % full_every == 0)
            outcome = run_case(text, Path(scratch) / str(tally.executions), limit=limit, simulate=simulate, full=full)
            tally.executions += 1
            tally.simulated += simulate
            tally.full += full
            tally.failing_cases += outcome.failed
            for failure in outcome.failures:
                found = tally.failures.get(failure.key)
                tally.failures[failure.key] = (found[0] + 1, found[1], found[2]) if found else (1, failure.detail, text)
            import shutil

            shutil.rmtree(Path(scratch) / str(tally.executions - 1), ignore_errors=True)

        one()
    tally.seconds, tally.cpu = time.perf_counter() - start, time.process_time() - cpu
    return tally


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--count", type=int, default=20000, help="cases in all (default 20000)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=20261123)
    parser.add_argument(
        "--full-every",
        type=int,
        default=4,
        help="run every step (check, info, matrix and solved forms) on one case in this many; the others get load, derive, Lagrange form, LaTeX, Python and its rhs",
    )
    parser.add_argument("--simulate-every", type=int, default=20, help="also simulate one case in this many (0: never)")
    parser.add_argument("--limit", type=float, default=20.0, help="seconds after which a step counts as a hang")
    parser.add_argument("--max-seconds", type=int, default=0, help="stop each worker after this long (0: no limit)")
    parser.add_argument("--save", type=Path, help="write the first file of each distinct failure here")
    parser.add_argument("--write", action="store_true", help="refresh the results section of FUZZ.md")
    args = parser.parse_args()
    per_worker = [args.count // args.workers + (i < args.count % args.workers) for i in range(args.workers)]
    jobs = [(n, args.seed + i, args.full_every, args.simulate_every, args.limit, args.max_seconds) for i, n in enumerate(per_worker)]
    start = time.perf_counter()
    if args.workers == 1:
        results = [work(jobs[0])]
    else:
        with multiprocessing.get_context("fork").Pool(args.workers, maxtasksperchild=1) as pool:
            results = pool.map(work, jobs)
    total = Tally()
    for result in results:
        total.add(result)
    wall = time.perf_counter() - start
    rate = total.executions / wall if wall else 0.0
    print(f"{total.executions} executions ({total.full} with every step, {total.simulated} with a simulation) in {wall:.0f} s on {args.workers} worker(s): {rate:.1f}/s")
    print(f"{total.cpu:.0f} CPU seconds in the workers: {total.executions / max(total.cpu, 1e-9):.1f} executions per CPU second")
    print(f"{total.failing_cases} failing cases, {len(total.failures)} distinct failures")
    for key, (count, detail, _) in sorted(total.failures.items(), key=lambda kv: -kv[1][0]):
        print(f"  {count:6d}  {key}: {detail[:160]}")
    if args.save:
        args.save.mkdir(parents=True, exist_ok=True)
        for key, (_, _, text) in total.failures.items():
            (args.save / (re.sub(r"[^A-Za-z0-9]+", "_", key).strip("_")[:80] + ".yaml")).write_text(text, encoding="utf-8")
    if args.write:
        write_section(args, total, wall, rate)
    return 1 if total.failures else 0


def _cell(text: str) -> str:
    """Text for a Markdown table cell: no pipes, line breaks or HTML."""
    return text.replace("|", "\\|").replace("\n", " ").replace("<", "&lt;").replace(">", "&gt;")


def write_section(args: argparse.Namespace, total: Tally, wall: float, rate: float) -> None:
    import subprocess

    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip() or "?"
    lines = [
        BEGIN,
        f"Last run: commit {commit}, `python benchmarks/fuzz.py --count {args.count} --workers {args.workers} --seed {args.seed} --full-every {args.full_every} --simulate-every {args.simulate_every}`",
        f"on {platform.machine()} / Python {platform.python_version()}.",
        "",
        f"- executions: {total.executions} ({total.full} with every step, {total.simulated} with a simulation), in {wall:.0f} s: {rate:.1f} executions/s",
        f"- CPU time of the workers: {total.cpu:.0f} s, {total.executions / max(total.cpu, 1e-9):.1f} executions per CPU second (independent of the machine's load)",
        f"- failing cases: {total.failing_cases}",
        f"- distinct failures: {len(total.failures)}",
    ]
    if total.failures:
        lines += ["", "| count | failure (step: kind at innermost frame) | first detail |", "|---:|---|---|"]
        for key, (count, detail, _) in sorted(total.failures.items(), key=lambda kv: -kv[1][0]):
            cell = _cell(detail[:120])
            name = _cell(key)
            lines.append(f"| {count} | {name} | {cell} |")
    lines.append(END)
    path = ROOT / "FUZZ.md"
    text = path.read_text(encoding="utf-8") if path.exists() else f"# Fuzzing\n\n{BEGIN}\n{END}\n"
    if BEGIN not in text:
        text += f"\n{BEGIN}\n{END}\n"
    head, rest = text.split(BEGIN, 1)
    path.write_text(head + "\n".join(lines) + rest.split(END, 1)[1], encoding="utf-8")


if __name__ == "__main__":
    sys.exit(main())
