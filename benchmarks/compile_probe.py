"""Where a command's first compile goes (helper compile18): run the lagrange CLI in this process with numba's event
API listening, and print per numba dispatcher the number of compiles (one per signature) and their CPU (process time,
exclusive of the helpers each compiles, and inclusive for the top-level ones), to stderr.

    rm -rf C; PYTHONPATH=. LAGRANGE_CACHE_DIR=C .venv/bin/python benchmarks/compile_probe.py stress FILE -q

With PROBE_DUPS=1 set, the argument types of every helper compiled more than once."""

from __future__ import annotations

import collections
import os
import sys
import time

from numba.core import event

stack: list[list] = []
records: list[tuple[str, str, float, float, int]] = []  # (name, argument types, inclusive, exclusive, depth)


class Listener(event.Listener):
    def on_start(self, e: event.Event) -> None:
        stack.append([e.data["dispatcher"].py_func.__qualname__, str(e.data["args"]), time.process_time(), 0.0])

    def on_end(self, e: event.Event) -> None:
        name, args, start, children = stack.pop()
        inclusive = time.process_time() - start
        if stack:
            stack[-1][3] += inclusive
        records.append((name, args, inclusive, inclusive - children, len(stack)))


def main() -> None:
    event.register("numba:compile", Listener())
    start = time.process_time()
    sys.argv = ["lagrange", *sys.argv[1:]]
    from lagrange_cli.cli import main as cli

    code: object = 0
    try:
        cli()
    except SystemExit as stop:
        code = stop.code
    total = time.process_time() - start
    table: dict[str, list] = collections.defaultdict(lambda: [0, 0.0, 0.0])
    for name, _, inclusive, exclusive, depth in records:
        row = table[name]
        row[0] += 1
        row[1] += exclusive
        row[2] += inclusive if depth == 0 else 0.0
    compiling = sum(r[2] for r in records if r[4] == 0)
    print(f"## exit {code} CPU {total:.1f} s (after imports), compiling (top level, inclusive) {compiling:.1f} s", file=sys.stderr)
    if os.environ.get("PROBE_DUPS"):
        for name, args, *_ in records:
            if table[name][0] > 1 and not name.startswith(("ol_", "_ol")):
                print(f"  twice or more {name}: {args}", file=sys.stderr)
    for name, (count, exclusive, top) in sorted(table.items(), key=lambda kv: -kv[1][1]):
        if exclusive > 0.05 or top > 0.05:
            print(f"  {name:32s} compiles {count:3d} exclusive {exclusive:6.2f} s top-level inclusive {top:6.2f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
