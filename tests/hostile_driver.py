"""Run several `lagrange` command lines in one process, as the shell would run them one by one.

    python -m tests.hostile_driver RESULTS.jsonl -- derive case.yaml -o out/a.txt -- check case.yaml ...

Each command line goes through `lagrange_cli.cli.main` (the console script's entry point) with
its own captured stdout and stderr; an exception that escapes it is written to that stderr as a
traceback, as Python would print it. One JSON line per command is appended to RESULTS.jsonl as
soon as the command ends (argv, exit code, stdout, stderr, seconds), so that a command that hangs
is found by its missing line: a watchdog ends the whole process (exit 124) after `--limit` seconds
for one command, naming it on stderr. Starting Python and importing sympy once per case instead of
once per command keeps tests/test_hostile.py within a minute.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import sys
import threading
import time
import traceback


def run(argv: list[str]) -> tuple[int, str, str]:
    """One command line: (exit code, stdout, stderr); a traceback counts as exit 1 (Python's own)."""
    from lagrange_cli.cli import main

    out, err = io.StringIO(), io.StringIO()
    code = 0
    saved = sys.argv
    sys.argv = ["lagrange", *argv]
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main()
            except SystemExit as done:
                code = done.code if isinstance(done.code, int) else (0 if done.code is None else 1)
            except BaseException:
                traceback.print_exc()
                code = 1
    finally:
        sys.argv = saved
    return code, out.getvalue(), err.getvalue()


class Watchdog:
    """Ends the whole process (exit 124) when one command has used `limit` seconds of CPU time.

    CPU time, not wall time: another program loading the machine slows a command down but does
    not add to its CPU time, so the verdict does not depend on the load. A command that hangs
    without using CPU (a deadlock) is caught by the far longer wall-clock net of the caller."""

    def __init__(self, limit: float, argv: list[str]) -> None:
        self.limit, self.argv, self.start = limit, argv, time.process_time()
        self.done = threading.Event()
        self.thread = threading.Thread(target=self.watch, daemon=True)
        self.thread.start()

    def watch(self) -> None:
        while not self.done.wait(0.25):
            if time.process_time() - self.start > self.limit:
                sys.__stderr__.write(f"HANG: lagrange {' '.join(self.argv)} used over {self.limit:g} s of CPU time\n")
                os._exit(124)

    def stop(self) -> None:
        self.done.set()
        self.thread.join()


def main(args: list[str]) -> int:
    limit = 20.0
    if args and args[0] == "--limit":
        limit, args = float(args[1]), args[2:]
    results, commands = args[0], []
    for item in args[1:]:
        if item == "--":
            commands.append([])
        else:
            commands[-1].append(item)
    for argv in commands:
        watchdog = Watchdog(limit, argv)
        start = time.perf_counter()
        code, out, err = run(argv)
        watchdog.stop()
        with open(results, "a", encoding="utf-8") as stream:
            stream.write(json.dumps({"argv": argv, "code": code, "stdout": out, "stderr": err, "seconds": time.perf_counter() - start}) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
