"""`sweep`: many runs of one system over grids or samples of parameters and initial values."""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from lagrange_cli.cli import app, check_outputs, fail_with, write_atomically
from lagrange_cli.cli.boundary import check_batch, check_fraction, check_positive, check_runs, check_samples, check_seed, check_stages, check_workers

if TYPE_CHECKING:
    from lagrange_cli.model import Model
    from lagrange_cli.sweep import Axis

OUTPUT_SUFFIXES = (".csv", ".parquet")
_RANGE = re.compile(r"^(?P<lo>.+?)\.\.(?P<hi>[^:]+)(?::(?P<count>[^:]*))?(?::(?P<spacing>[^:]*))?$", re.S)


@app.command()
def sweep(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system (e.g. double_pendulum).")],
    set_: Annotated[list[str] | None, typer.Option("--set", help="Parameters: name=value, or a range name=LO..HI:COUNT (linear), name=LO..HI:COUNT:log, or name=LO..HI (with --sample).")] = None,
    initial: Annotated[list[str] | None, typer.Option("--initial", help="Initial values, like --set: theta=0..3.14:200; several ranges make a grid.")] = None,
    sample: Annotated[int | None, typer.Option("--sample", help="Monte Carlo: N points drawn uniformly (log-uniformly for :log) from the ranges.", callback=check_runs)] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of --sample.", callback=check_seed)] = 0,
    measure: Annotated[
        list[str] | None, typer.Option("--measure", help="What to record, repeated: final, an expression, max(EXPR), min(EXPR), mean(EXPR), t_event, energy_error, lyapunov, period.")
    ] = None,
    section: Annotated[str | None, typer.Option("--section", help="A Poincaré section: 'theta=0, theta_dot>0' (one row per crossing).")] = None,
    until: Annotated[str | None, typer.Option(help="Stop each run when this expression crosses zero (its time: the t_event measure).")] = None,
    t_end: Annotated[float | None, typer.Option("--t-end", help="Final time (default: the file's simulate.t_end, else 10).", callback=check_positive)] = None,
    method: Annotated[str | None, typer.Option(help="auto, RK45, DOP853, Radau, BDF, LSODA or symplectic.")] = None,
    backend: Annotated[str, typer.Option(help="auto, compiled (numba) or python (scipy).")] = "auto",
    rtol: Annotated[float | None, typer.Option(help="Relative tolerance (default 1e-8).", callback=check_fraction)] = None,
    atol: Annotated[float | None, typer.Option(help="Absolute tolerance (default 1e-10).", callback=check_positive)] = None,
    step: Annotated[float | None, typer.Option(help="Fixed step of the symplectic method.", callback=check_positive)] = None,
    stages: Annotated[
        int | None, typer.Option(help="Gauss-Legendre stages of the symplectic method: 1, 2 or 3 (order 2, 4, 6; default: the pilot's choice, or 2 with --step).", callback=check_stages)
    ] = None,
    max_step: Annotated[float | None, typer.Option("--max-step", help="Largest step of adaptive methods.", callback=check_positive)] = None,
    samples: Annotated[int | None, typer.Option(help="Samples per run for max/min/mean/energy_error/period (default 201).", callback=check_samples)] = None,
    workers: Annotated[int, typer.Option("--workers", help="Local threads running the compiled loops in parallel (default 1).", callback=check_workers)] = 1,
    scheduler: Annotated[str | None, typer.Option("--scheduler", help="A dask.distributed scheduler address (tcp://host:8786): batches run on its workers.")] = None,
    batch: Annotated[int, typer.Option("--batch", help="Runs per batch (the unit of writing and resuming; batches run in groups).", callback=check_batch)] = 64,
    output_path: Annotated[Path | None, typer.Option("-o", "--output", help="The table: .csv, or .parquet (pyarrow); - or none for CSV on stdout.")] = None,
    resume: Annotated[bool, typer.Option("--resume", help="Continue an interrupted sweep into -o (from its OUTPUT.partial.csv).")] = False,
    plot: Annotated[Path | None, typer.Option(help="A picture: a line (one axis), a heat map (two), a scatter (a section): .png, .svg or .pdf.")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Show no progress bar on stderr.")] = False,
) -> None:
    """Run a system over a grid or a sample of parameters and initial values, one row per run (failed runs too)."""
    check_outputs(output_path, plot, reading=file, options=("-o", "--plot"))
    from lagrange_cli.errors import LagrangeError

    try:
        from lagrange_cli import derive as core
        from lagrange_cli import spec
        from lagrange_cli import sweep as library
        from lagrange_cli.numeric import output as out

        to_file = output_path is not None and str(output_path) != "-"
        if to_file:
            assert output_path is not None
            out.check_suffix(output_path, OUTPUT_SUFFIXES, "output")
            if output_path.suffix.lower() == ".parquet" and not library.pyarrow_available():
                raise LagrangeError(f"-o {output_path}: Parquet needs pyarrow (`pip install pyarrow`); or write .csv")
        if resume and not to_file:
            raise LagrangeError("--resume continues the sweep written to -o FILE: give -o")
        if plot is not None:
            out.check_plot(plot)
        for option, value in (("--workers", workers), ("--batch", batch)):
            if value < 1:
                raise LagrangeError(f"{option} must be a whole number of at least 1, got {value}")
        if sample is not None and sample < 1:
            raise LagrangeError(f"--sample must be a whole number of at least 1, got {sample}")
        path = spec.resolve(file)
        text = path.read_text(encoding="utf-8")
        model = core.derive(spec.parse(text, str(path)), shared=True)  # compiled from the symengine forms
        fixed_p, axes_p = ranges_of(model, set_ or [], "--set")
        fixed_y, axes_y = ranges_of(model, initial or [], "--initial")
        axes = [*axes_p, *axes_y]
        library.check_axes(model, axes, sample)
        given = {"t_end": t_end, "method": method, "rtol": rtol, "atol": atol, "step": step, "stages": stages, "samples": samples, "until": until, "backend": backend, "max_step": max_step}
        options: dict[str, Any] = {k: v for k, v in given.items() if v is not None}
        options.update(parameters=fixed_p, initial=fixed_y)
        job = library.Job(text, model.source, tuple(axes), tuple(measure or ()), section, tuple(sorted(options.items(), key=lambda kv: kv[0])))
        runner = library.runner_for(job, model)  # every option checked (and the system compiled) before any file is touched
        journal = _journal(output_path) if to_file else None
        done: set[int] = set()
        if journal is not None:
            mark = library.identity(job, sample, seed)
            if resume and journal.exists():
                done, length = library.read_done(journal, runner.columns, mark)
                with journal.open("r+b") as handle:
                    handle.truncate(length)  # a cut last line of an interrupted write
                if length == 0:
                    library.append_rows(journal, [], runner.columns, mark)
            else:
                journal.unlink(missing_ok=True)
                library.append_rows(journal, [], runner.columns, mark)
        table = _run(model, job, axes, sample, seed, workers, scheduler, batch, done, journal, quiet, options)
        for note in runner.notes:
            _say(f"note: {note}")
        if journal is not None:
            assert output_path is not None
            whole = library.sorted_table(library.read_table(journal))
            _write(library, whole, output_path)
            journal.unlink()
            table = whole
        else:
            write_atomically(Path("-"), "".join(library.csv_line(r) for r in [table.columns, *library.sorted_table(table).rows]))
        if plot is not None:
            coords = list(model.coordinates)
            library.write_figure(library.figure(table, axes, model.title, coords, section or ""), plot)
    except LagrangeError as error:
        fail_with(error)
    failed = sum(1 for row in table.rows if row[table.columns.index("status")] == "failed")
    runs = len({row[0] for row in table.rows})
    _say(f"sweep: {runs} runs, {failed} failed" + (f" (rows with their reasons in {output_path})" if failed and to_file else ""))


def _say(text: str) -> None:
    from lagrange_cli.cli.boundary import console, plain

    console(stderr=True).print(plain(text), markup=False)


def _journal(path: Path | None) -> Path:
    assert path is not None
    return path.with_name(path.name + ".partial.csv")


def _write(library: Any, table: Any, path: Path) -> None:
    if path.suffix.lower() == ".parquet":
        import tempfile

        with tempfile.TemporaryDirectory(dir=path.parent) as folder:
            scratch = Path(folder) / "table.parquet"
            library.write_parquet(table, scratch)
            scratch.replace(path)
    else:
        write_atomically(path, "".join(library.csv_line(r) for r in [table.columns, *table.rows]))


def _run(
    model: Model, job: Any, axes: list[Axis], sample: int | None, seed: int, workers: int, scheduler: str | None, batch: int, done: set[int], journal: Path | None, quiet: bool, options: dict[str, Any]
) -> Any:
    from lagrange_cli import sweep as library
    from lagrange_cli.cli.progress import Reporter
    from lagrange_cli.numeric.accuracy import Step

    with Reporter("sweep", "runs", quiet) as reporter:
        shown = [-1]

        def on_batch(rows: list[list[Any]], count: int, total: int) -> None:
            if journal is not None:
                library.append_rows(journal, rows)
            tenth = 10 * count // max(total, 1)
            if reporter.terminal or tenth > shown[0]:  # a bar on a terminal; otherwise a line every tenth of the runs
                shown[0] = tenth
                reporter(Step(count, total, f"{count} of {total} runs"))

        try:
            return library.sweep(
                model,
                axes,
                text=job.text,
                sample=sample,
                seed=seed,
                measures=job.measures,
                section=job.section,
                workers=workers,
                scheduler=scheduler,
                batch=batch,
                done=sorted(done),
                on_batch=on_batch,
                **options,
            )
        except KeyboardInterrupt:
            if journal is not None:
                _say(f"interrupted: the finished batches are in {journal}; run the same command with --resume to continue")
            raise typer.Exit(130) from None


def ranges_of(model: Model, items: list[str], option: str) -> tuple[dict[str, float], list[Axis]]:
    """Fixed values and ranges of `--set` (parameters) or `--initial` (coordinates and velocities):
    `name=VALUE`, `name=LO..HI:COUNT[:log|:linear]`, or `name=LO..HI` (for --sample)."""
    from lagrange_cli.cli.boundary import assignments, check_names, constant
    from lagrange_cli.errors import fail
    from lagrange_cli.sweep import Axis

    if option == "--initial":
        names, kind, example = [*model.coordinates, *(f"{c}_dot" for c in model.coordinates)], "coordinate or velocity", f"{model.coordinates[0]}=0..3.14:50"
    else:
        names, kind, example = [p.name for p in model.parameters], "parameter", f"{model.parameters[0].name if model.parameters else 'g'}=1..100:50:log"
    parsed = assignments(option, items, example)
    check_names(parsed, names, kind, model.source)
    fixed: dict[str, float] = {}
    axes: list[Axis] = []
    expected = f"NAME=VALUE, NAME=LO..HI:COUNT, NAME=LO..HI:COUNT:log or NAME=LO..HI (with --sample), e.g. {option} {example}"
    for item in parsed:
        found = _RANGE.match(item.value) if ".." in item.value else None
        if found is None:
            if ".." in item.value:
                raise fail(item.span(), f"'{item.value.strip()}' is not a range", expected)
            fixed[item.name] = constant(item, f"the value of '{item.name}'")[1]
            continue
        lo = constant(item, f"the start of the range of '{item.name}'", found.group("lo"), found.start("lo"))[1]
        hi = constant(item, f"the end of the range of '{item.name}'", found.group("hi"), found.start("hi"))[1]
        count: int | None = None
        if found.group("count") is not None:
            digits = found.group("count").strip()
            if not digits.isdigit() or int(digits) < 1:
                raise fail(item.span(found.start("count")), f"the count of '{item.name}' must be a whole number of at least 1, got '{digits}'", expected)
            count = int(digits)
        spacing = (found.group("spacing") or "linear").strip().lower()
        if spacing not in ("linear", "lin", "log"):
            raise fail(item.span(found.start("spacing")), f"unknown spacing '{spacing}' for '{item.name}'", "linear (the default) or log")
        if spacing == "log" and not (lo > 0 and hi > 0):
            raise fail(item.span(), f"log spacing of '{item.name}' needs a positive range, got {lo:g}..{hi:g}", "0 < LO and 0 < HI")
        axes.append(Axis("set" if option == "--set" else "initial", item.name, lo, hi, count, spacing == "log"))
    return fixed, axes
