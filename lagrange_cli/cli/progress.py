"""Progress of the long commands (`accuracy`, `stress`) on stderr, never on stdout (which may carry --json).

On a terminal a rich progress bar (cleared when done); otherwise one plain line per finished unit
with an estimate of the time left, e.g. `stress: regime 3/7 (high energy) done, about 40 s left`.
`--quiet` shows nothing. The library reports through a callback (`accuracy.Step`); only this
module draws. File text in the progress (regime names carry parameter names) is shown as data.
"""

from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING, Any

from lagrange_cli.cli.boundary import inert, plain

if TYPE_CHECKING:
    from lagrange_cli.numeric.accuracy import Step


def left(seconds: float) -> str:
    """An estimate of the time left, rounded as a person would say it."""
    if seconds < 1.5:
        return "about 1 s left"
    if seconds < 60:
        return f"about {seconds:.0f} s left"
    return f"about {seconds / 60:.0f} min left" if seconds >= 90 else f"about {seconds:.0f} s left"


class Reporter:
    """A progress callback for `accuracy.study` and `stress.stress`; use as a context manager so
    that a bar is cleared (also on errors)."""

    def __init__(self, command: str, unit: str, quiet: bool = False, terminal: bool | None = None) -> None:
        self.command, self.unit, self.quiet = command, unit, quiet
        self.terminal = sys.stderr.isatty() if terminal is None else terminal
        self.start = time.perf_counter()
        from lagrange_cli.numeric.compile import compiling_seconds

        self._compiling = compiling_seconds
        self._once = compiling_seconds()  # compiling done before this command (a notebook's earlier studies): not its own
        self._bar: Any = None
        self._task: Any = None
        self._share = 0.0  # of the work, at the last finished unit

    def __enter__(self) -> Reporter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()
            self._bar = None

    def __call__(self, step: Step) -> None:
        if self.quiet:
            return
        if not step.running:
            self._share = step.share
        if self.terminal:
            self._draw(step)
        elif not step.running:
            self._line(step)

    def eta(self, step: Step) -> str:
        """The time left at the pace so far, the one-off compiling left out of that pace (the first run on a
        machine compiles the loops: counted in, the first of seven regimes would promise minutes for seconds)."""
        elapsed, share = max(time.perf_counter() - self.start - (self._compiling() - self._once), 0.0), self._share if step.running else step.share
        if step.done >= step.total:
            return "finished"
        if share <= 0:
            return ""
        return left(elapsed / share * (1 - share))

    def _line(self, step: Step) -> None:
        eta = self.eta(step)
        tail = f", {eta}" if eta and eta != "finished" else ""
        sys.stderr.write(plain(f"{self.command}: {self.unit} {step.done}/{step.total} ({step.what}) done{tail}").replace("\n", " ") + "\n")
        sys.stderr.flush()

    def _draw(self, step: Step) -> None:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        from lagrange_cli.cli.boundary import console

        if self._bar is None:
            self._bar = Progress(
                TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), TextColumn("{task.fields[left]}"), console=console(stderr=True), transient=True
            )
            self._bar.start()
            self._task = self._bar.add_task("", total=step.total, left="")
        what = f"{step.what}: {step.running}" if step.running and step.running != step.what else step.what
        eta = self.eta(step)
        self._bar.update(self._task, completed=step.done, total=step.total, description=f"{self.command}: {inert(what)}", left=eta if eta != "finished" else "")
