"""`simulate`: integrate a system from its file, write the trajectory, and report how far to trust it."""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from lagrange_cli.cli import app, check_outputs, fail_with, write_atomically
from lagrange_cli.cli.boundary import check_fraction, check_positive, check_samples, check_stages, check_steps

if TYPE_CHECKING:
    from lagrange_cli.model import Model
    from lagrange_cli.numeric.simulate import Trajectory

PROGRESS_AFTER = 1.0  # seconds before a progress bar appears (on a terminal only)


@app.command()
def simulate(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system (e.g. double_pendulum).")],
    t_end: Annotated[float | None, typer.Option("--t-end", help="Final time (default: the file's simulate.t_end, else 10).", callback=check_positive)] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", help="Override parameters: name=value, repeated or separated by commas (k=1,m=2).")] = None,
    initial: Annotated[list[str] | None, typer.Option("--initial", help="Override initial values: q=value,q_dot=value, repeated or separated by commas.")] = None,
    method: Annotated[str | None, typer.Option(help="auto, RK45, DOP853, Radau, BDF, LSODA or symplectic.")] = None,
    backend: Annotated[str, typer.Option(help="auto, compiled (numba) or python (scipy).")] = "auto",
    rtol: Annotated[float | None, typer.Option(help="Relative tolerance of adaptive methods (default 1e-8).", callback=check_fraction)] = None,
    atol: Annotated[float | None, typer.Option(help="Absolute tolerance of adaptive methods (default 1e-10).", callback=check_positive)] = None,
    step: Annotated[float | None, typer.Option(help="Fixed step of the symplectic method.", callback=check_positive)] = None,
    stages: Annotated[
        int | None, typer.Option(help="Gauss-Legendre stages of the symplectic method: 1, 2 or 3 (order 2, 4, 6; default: the pilot's choice, or 2 with --step).", callback=check_stages)
    ] = None,
    max_step: Annotated[float | None, typer.Option("--max-step", help="Largest step of adaptive methods.", callback=check_positive)] = None,
    samples: Annotated[int | None, typer.Option(help="Number of evenly spaced output times (default 1001).", callback=check_samples)] = None,
    max_steps: Annotated[
        int | None, typer.Option("--max-steps", callback=check_steps, help="Step budget of the run: it stops (exit 1) after this many steps (default 20000 through scipy, 1000000 compiled).")
    ] = None,
    until: Annotated[str | None, typer.Option(help='Stop when this expression of the state crosses zero, e.g. "lambda_c" or "x - 1".')] = None,
    input_: Annotated[
        list[str] | None,
        typer.Option(
            "--input", help="An input as an expression of t, the coordinates, the velocities (q_dot) and the parameters: NAME=EXPR, repeatable, e.g. tau=-k1*q1-k2*q1_dot (others keep their default)."
        ),
    ] = None,
    output_path: Annotated[Path | None, typer.Option("-o", "--output", help="Write the trajectory: .csv or .npz, or - for CSV on stdout.")] = None,
    plot: Annotated[Path | None, typer.Option(help="Plot coordinates, phase portrait and energy error: .png, .svg or .pdf.")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Show no progress bar on stderr.")] = False,
    projection: Annotated[
        bool | None,
        typer.Option("--projection/--no-projection", help="Project the state onto the kept constraints (and the energy level) at each sample (default: on when the file keeps constraints)."),
    ] = None,
) -> None:
    """Simulate a system and report energy, momenta and constraint drift (exit 1 if the run fails)."""
    check_outputs(output_path, plot, reading=file, options=("-o", "--plot"))
    from lagrange_cli.errors import LagrangeError

    try:
        from lagrange_cli.derive import load_model
        from lagrange_cli.numeric import output as out
        from lagrange_cli.numeric.simulate import simulate as run

        if output_path is not None and str(output_path) != "-":
            out.check_suffix(output_path, out.DATA_SUFFIXES, "output")
        if plot is not None:
            out.check_plot(plot)
        model = load_model(file, shared=True)  # compiled from the symengine forms
        parameters, values = assignments_of(model, set_ or [], "--set"), assignments_of(model, initial or [], "--initial")
        model = inputs_of(model, input_ or [])
        with _Progress(quiet) as progress:
            trajectory = run(
                model,
                t_end=t_end,
                method=method,
                rtol=rtol,
                atol=atol,
                step=step,
                stages=stages,
                samples=samples,
                parameters=parameters,
                initial=values,
                until=until,
                backend=backend,
                max_step=max_step,
                max_steps=max_steps,
                progress=progress,
                projection=projection,
            )
        _write(trajectory, output_path, plot, model)
    except LagrangeError as error:
        fail_with(error)
    _report(trajectory, to_stderr=output_path is not None and str(output_path) == "-")
    if trajectory.failed:
        raise typer.Exit(1)


def inputs_of(model: Model, items: list[str]) -> Model:
    """The model with the inputs of `--input NAME=EXPR` (expressions of t and the state) and the
    others at their defaults (lagrange_cli/inputs.py)."""
    from lagrange_cli import inputs
    from lagrange_cli.cli.boundary import assignments
    from lagrange_cli.errors import Span

    example = f"{model.inputs[0].name}=-{model.coordinates[0]}" if model.inputs else "u=0"
    parsed = assignments("--input", items, example)
    given = inputs.signal_expressions(model, [(item.name, item.value, item.span(), Span(item.option, 1, item.start + 1, item.text)) for item in parsed])
    return inputs.substitute(model, given)


def assignments_of(model: Model, items: list[str], option: str) -> dict[str, float]:
    """`name=value` pairs (repeated or separated by commas) of `--set` (parameters) or `--initial`
    (coordinates and velocities); values are constant expressions such as pi/2."""
    from lagrange_cli.cli.boundary import assignments, check_names, constant

    if option == "--initial":
        names, kind, example = [*model.coordinates, *(f"{c}_dot" for c in model.coordinates)], "coordinate or velocity", f"{model.coordinates[0]}=0.5,{model.coordinates[0]}_dot=0"
    else:
        names, kind, example = [p.name for p in model.parameters], "parameter", f"{model.parameters[0].name if model.parameters else 'g'}=1.5"
    parsed = assignments(option, items, example)
    check_names(parsed, names, kind, model.source)
    return {item.name: constant(item, f"the value of '{item.name}'")[1] for item in parsed}


def _write(trajectory: Trajectory, output_path: Path | None, plot: Path | None, model: Model) -> None:
    """The trajectory (also the part before a failure) to its file or stdout, and the plot (of `model`'s run)."""
    from lagrange_cli.numeric import output as out

    if output_path is not None and str(output_path) == "-":
        write_atomically(output_path, out.csv_text(trajectory))
    elif output_path is not None and output_path.suffix.lower() == ".npz":
        out.write_npz(trajectory, output_path)
    elif output_path is not None:
        write_atomically(output_path, out.csv_text(trajectory))
    if plot is not None:
        out.write_plot(trajectory, plot, model)


def _report(trajectory: Trajectory, to_stderr: bool) -> None:
    """What ran, how it ended, the work and time it took, and every monitored invariant."""
    from rich.table import Table

    from lagrange_cli.cli.boundary import console as make_console
    from lagrange_cli.cli.boundary import inert, plain
    from lagrange_cli.numeric.simulate import InvariantKind

    console = make_console(stderr=to_stderr)
    s, stats, timing = trajectory.settings, trajectory.stats, trajectory.timing
    accuracy = f"step {s.step!r}, {s.stages} stages" if s.method == "symplectic" and s.step else f"rtol {s.rtol!r}, atol {s.atol!r}"
    console.print(f"[bold]{inert(trajectory.title)}[/bold]: {inert(s.method)} ({inert(s.backend)}), t = {s.t0:g} .. {s.t_end:g}, {accuracy}")
    for note in trajectory.notes:
        console.print(f"  [dim]{inert(note)}[/dim]")
    if trajectory.failed:
        kept = "the trajectory up to there is kept" if stats.steps else "nothing was integrated"
        make_console(stderr=True).print(plain(f"error: {trajectory.message}; {kept}"), markup=False)
    else:
        console.print(plain(f"{trajectory.status}: {trajectory.message}"), markup=False)
    rejected = f" ({stats.rejected} rejected)" if stats.rejected else ""
    smallest = f", smallest step {stats.min_step:.3g}" if stats.min_step else ""
    jacobians = f", {stats.njev} Jacobian{'s' * (stats.njev != 1)}, {stats.nlu} LU" if stats.njev or stats.nlu else ""
    console.print(f"work: {stats.steps} steps{rejected}, {stats.nfev} evaluations{jacobians}{smallest}")
    if stats.floored:
        console.print(
            f"  [dim]{stats.floored} step{'s' * (stats.floored != 1)} held some component's error to its round-off floor, above rtol/atol: the tolerance asks for less than double precision resolves there[/dim]"
        )
    once = f", one-time: compile/load {_seconds(timing.compile)}, import {_seconds(timing.load)}, codegen {_seconds(timing.generate)}"
    console.print(f"time: run {_seconds(timing.run)}{once}")
    if trajectory.invariants:
        table = Table(title="invariants", title_justify="left")
        for column in ("quantity", "expected", "initial", "max change", "relative"):
            table.add_column(column)
        for inv in trajectory.invariants:
            table.add_row(inert(inv.name), "conserved" if inv.conserved else "not conserved", f"{inv.initial:.6g}", f"{inv.max_change:.2e}", f"{inv.relative:.2e}")
        energy = trajectory.invariant(InvariantKind.ENERGY)
        if energy is not None and energy.scale > abs(energy.initial):
            table.caption = f"energy: relative to the largest |sum p q_dot| = {energy.scale:.6g} (twice the kinetic energy of a natural system), which exceeds |initial|"
            table.caption_justify = "left"
        console.print(table)


def _seconds(value: float) -> str:
    return f"{value * 1e3:.3g} ms" if value < 1 else f"{value:.3g} s"


class _Progress:
    """A progress callback that shows a rich bar on stderr once a run has taken a second, on a
    terminal (not when `quiet`). Until the run reports, the bar says what takes the time before
    it: loading or compiling (the first compiled run on a machine compiles numba's loops, some 10 s)."""

    def __init__(self, quiet: bool = False) -> None:
        self.start = time.perf_counter()
        self.bar: Any = None
        self.task: Any = None
        self.quiet = quiet
        self.lock = threading.Lock()
        self.timer: threading.Timer | None = None

    def __enter__(self) -> _Progress:
        if not self.quiet and sys.stderr.isatty():
            self.timer = threading.Timer(PROGRESS_AFTER, self._show, ("preparing (the first compiled run compiles numba's loops, about 10 s)",))
            self.timer.daemon = True
            self.timer.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.timer is not None:
            self.timer.cancel()
        with self.lock:
            if self.bar is not None:
                self.bar.stop()
                self.bar = None
            self.quiet = True  # a timer that fires now shows nothing

    def _show(self, description: str) -> None:
        with self.lock:
            if self.bar is None and not self.quiet:
                from rich.progress import Progress

                from lagrange_cli.cli.boundary import console

                self.bar = Progress(console=console(stderr=True), transient=True)
                self.bar.start()
                self.task = self.bar.add_task(description, total=1.0)

    def __call__(self, fraction: float) -> None:
        if self.quiet or not sys.stderr.isatty():
            return
        if self.bar is None:
            if time.perf_counter() - self.start < PROGRESS_AFTER:
                return
            self._show("simulating")
        with self.lock:
            if self.bar is not None:
                self.bar.update(self.task, completed=fraction, description="simulating")
