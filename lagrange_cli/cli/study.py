"""`accuracy` (a work-precision study) and `stress` (stiff and extreme regimes) for one system."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from lagrange_cli.cli import app, check_outputs, fail_with, write_atomically
from lagrange_cli.cli.boundary import check_fraction, check_positive, check_repeats, check_samples, check_steps, inert, plain

if TYPE_CHECKING:
    from rich.console import Console

    from lagrange_cli.cli.boundary import Item
    from lagrange_cli.model import Model
    from lagrange_cli.numeric.accuracy import Candidate, Point, Study
    from lagrange_cli.numeric.stress import Diagnosis, Outcome, Report


def _candidates(methods: list[str] | None) -> list[Candidate] | None:
    from lagrange_cli.numeric.accuracy import parse_candidate

    if not methods:
        return None
    return [parse_candidate(part) for entry in methods for part in entry.split(",") if part.strip()]


MAX_LADDER = 20  # values in --tolerances or in one --scale sweep


def _tolerances(text: str | None) -> list[float] | None:
    """`1e-3..1e-8` (every decade) or `1e-4,1e-6,1e-9`: each a finite number between 0 and 1."""
    from lagrange_cli.errors import LagrangeError

    if text is None:
        return None
    usage = "a range such as 1e-3..1e-8 or a list such as 1e-4,1e-6,1e-9, each between 0 and 1 (both excluded)"
    try:
        values = [float(v) for v in (text.split("..") if ".." in text else text.split(",")) if v.strip()]
    except ValueError:
        raise LagrangeError(f"error: --tolerances {plain(repr(text))}: not a number\n  expected: {usage}") from None
    if not values or (".." in text and len(values) != 2) or not all(math.isfinite(v) and 0 < v < 1 for v in values):
        raise LagrangeError(f"error: --tolerances {plain(repr(text))}: every value must be a finite number between 0 and 1\n  expected: {usage}")
    if ".." in text:
        a, b = sorted(math.log10(v) for v in values)
        values = [10.0 ** (a + k) for k in range(round(b - a) + 1)]
    if len(values) > MAX_LADDER:
        raise LagrangeError(f"error: --tolerances {plain(repr(text))}: {len(values)} tolerances\n  expected: at most {MAX_LADDER}")
    return values


def _scales(entries: list[str]) -> list[tuple[Item, tuple[float, ...]]]:
    """Each `--scale name=values` item (repeated or separated by commas: `k=1e2..1e8,m=1,2`) parsed,
    its values finite and at most MAX_LADDER of them."""
    from lagrange_cli.cli.boundary import assignments
    from lagrange_cli.errors import LagrangeError
    from lagrange_cli.numeric.stress import parse_scale

    result = []
    for item in assignments("--scale", entries, "k=1e2..1e8", lists=True):
        text = f"{item.name}={item.value.strip()}"
        given = item.value.replace("..", ",").split(",")
        if not all(math.isfinite(_number(v)) for v in given):  # before the decades of low..high are counted
            raise LagrangeError(f"error: --scale {plain(repr(text))}: every value must be a finite number\n  expected: name=low..high (both positive) or name=v1,v2,..., e.g. --scale k=1e2..1e8")
        values = parse_scale(text)[1]
        if len(values) > MAX_LADDER:
            raise LagrangeError(f"error: --scale {plain(repr(text))}: {len(values)} values\n  expected: at most {MAX_LADDER}")
        result.append((item, values))
    return result


def _number(text: str) -> float:
    """`text` as a float, or 0.0 when it is not a number (the caller's parser says why)."""
    try:
        return float(text)
    except ValueError:
        return 0.0


STUDY_STEPS, STRESS_STEPS = 200_000, 60_000  # accuracy.MAX_STEPS and stress.MAX_STEPS, here so that --help does not import numpy
STEPS_HELP = "Step budget of one run, counted (never timed) so that results do not depend on the machine's load: scipy steps; compiled runs may take 100 x as many, reference runs 10 x."
TIME_LIMIT_HELP = "Optional safety net: seconds after which one measured run is stopped and reported as undecided (never as failed). Default: none."
QUIET_HELP = "Show no progress on stderr."


def _write_text(path: Path, text: str) -> None:
    write_atomically(path, text)  # - is stdout


@app.command()
def accuracy(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system (e.g. double_pendulum).")],
    method: Annotated[list[str] | None, typer.Option("--method", help="Methods to study (repeatable or comma-separated; METHOD:python forces scipy). Default: all.")] = None,
    tolerances: Annotated[str | None, typer.Option(help="rtol ladder, e.g. 1e-3..1e-8 (every decade) or 1e-4,1e-6 (default 1e-3..1e-8).")] = None,
    t_end: Annotated[float | None, typer.Option("--t-end", help="Final time (default: the file's).", callback=check_positive)] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", help="Override parameters: name=value, repeated or separated by commas (k=1,m=2).")] = None,
    initial: Annotated[list[str] | None, typer.Option("--initial", help="Override initial values: q=value,q_dot=value, repeated or separated by commas.")] = None,
    samples: Annotated[int, typer.Option(help="Evenly spaced times the errors (largest, RMS, final) are taken at.", callback=check_samples)] = 2001,
    repeats: Annotated[int, typer.Option(help="Timed runs after the warm-up (fewer for slow runs).", callback=check_repeats)] = 3,
    max_steps: Annotated[int, typer.Option("--max-steps", help=STEPS_HELP, callback=check_steps)] = STUDY_STEPS,
    budget: Annotated[float | None, typer.Option(help=TIME_LIMIT_HELP, callback=check_positive)] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help=QUIET_HELP)] = False,
    csv: Annotated[Path | None, typer.Option("--csv", help="Write the table as CSV (- for stdout).")] = None,
    json: Annotated[Path | None, typer.Option("--json", help="Write the study as JSON (- for stdout).")] = None,
    plot: Annotated[Path | None, typer.Option(help="Plot error against run time and against evaluations: .png, .svg or .pdf.")] = None,
) -> None:
    """Error against run time for every method over a ladder of tolerances, against an exact or confirmed reference."""
    check_outputs(csv, json, plot, reading=file, options=("--csv", "--json", "--plot"))
    from lagrange_cli.cli.progress import Reporter
    from lagrange_cli.errors import LagrangeError

    try:
        from lagrange_cli.cli.numeric import assignments_of
        from lagrange_cli.derive import load_model
        from lagrange_cli.numeric import accuracy as core
        from lagrange_cli.numeric import output as out

        if plot is not None:
            out.check_plot(plot)
        ladder = _tolerances(tolerances)  # before any work
        model = load_model(file, shared=True)  # compiled from the symengine forms
        with Reporter("accuracy", "run", quiet) as reporter:
            result = core.study(
                model,
                candidates=_candidates(method),
                tolerances=ladder if ladder is not None else core.TOLERANCES,
                t_end=t_end,
                parameters=assignments_of(model, set_ or [], "--set"),
                initial=assignments_of(model, initial or [], "--initial"),
                samples=samples,
                repeats=repeats,
                max_steps=max_steps,
                time_limit=budget,
                progress=reporter,
            )
        if csv is not None:
            _write_text(csv, core.csv_text(result))
        if json is not None:
            _write_text(json, core.json_text(result))
        if plot is not None:
            core.write_plot(result, plot)
    except LagrangeError as error:
        fail_with(error)
    _report_study(result, to_stderr=str(csv) == "-" or str(json) == "-", file=file, model=model)


def _console(to_stderr: bool) -> Console:
    """A console wide enough for the tables, also when the output is a pipe or a file."""
    from lagrange_cli.cli.boundary import console as make_console

    console = make_console(stderr=to_stderr)
    if not console.is_terminal:
        console = make_console(stderr=to_stderr, width=160)
    return console


def _e(value: float | None) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.1e}"


def _claimed(error: float, own: float | None) -> str:
    """A measured error as stress claims it: where it is below the reference's own error, which it cannot resolve, the
    bound error + own error ("<2.7e-08"; audit 11, F4: a claim of 7.8e-9 against a reference of own error 1.9e-8 was
    2.1e-8 against an independent one)."""
    if own is not None and math.isfinite(own) and math.isfinite(error) and error < own:
        return f"<{error + own:.1e}"
    return _e(error)


def _seconds(value: float) -> str:
    if not math.isfinite(value):
        return "-"
    return f"{value * 1e3:.3g} ms" if value < 1 else f"{value:.3g} s"


def _report_study(result: Study, to_stderr: bool, file: str, model: Model) -> None:
    from rich.table import Table

    from lagrange_cli.numeric.accuracy import HORIZON_THRESHOLD, TIE_MARGIN, tol_text
    from lagrange_cli.numeric.reference import CHAOS_GROWTH

    console = _console(to_stderr)
    window = f"t = 0 .. {result.t_end:.4g}" + (f" (of {result.full_t_end:g})" if result.t_end < result.full_t_end else "")
    console.print(f"[bold]{inert(result.title)}[/bold]: work-precision study, {window}")
    ref = result.reference
    own = "exact" if ref.kind == "exact" else f"its own error {_e(ref.own_error)}"
    console.print(plain(f"reference: {ref.description} ({own})"), markup=False)
    if result.horizon is not None:
        h = result.horizon
        if h.chaotic and math.isfinite(h.horizon):
            console.print(f"chaotic: runs started {tol_text(h.delta)} apart are {HORIZON_THRESHOLD:.0e} apart at t = {h.horizon:.3g}, growth rate about {h.lyapunov:.2g}/s")
        elif h.chaotic:
            console.print(f"chaotic: runs started {tol_text(h.delta)} apart separate exponentially (about {h.lyapunov:.2g}/s) but stay within {HORIZON_THRESHOLD:.0e} up to t = {result.full_t_end:g}")
        else:
            console.print(
                f"not counted as chaotic: runs started {tol_text(h.delta)} apart separate by {h.growth * h.delta:.1e} by the end ({h.growth:.2g} x),"
                f" growing less than {CHAOS_GROWTH:g} x over the second half"
            )
    for note in result.notes:
        console.print(f"  [dim]{inert(note)}[/dim]", markup=True)
    table = Table(title="runs", title_justify="left", box=None, padding=(0, 1))
    for column in ("method", "setting", "final err", "RMS err", "max err", "energy", "constraint", "run time", "runs", "evals (jac)", "steps", "status"):
        table.add_column(column, justify="left" if column in ("method", "setting", "status") else "right")
    compile_costs: dict[str, float] = {}
    for p in result.points:
        compile_costs[p.resolved] = max(compile_costs.get(p.resolved, 0.0), p.compile_seconds)
        if p.status == "finished":
            status = "ok" if p.ok else "[yellow]finished[/yellow]: its error could not be measured (samples missing or not finite)"
        else:
            status = f"[red]{inert(p.status)}[/red]: {inert(p.reason)}"
        evals = f"{p.nfev} ({p.njev})" if p.njev else str(p.nfev)
        name = _shown(p)
        table.add_row(
            inert(name),
            inert(p.setting),
            _e(p.final_error),
            _e(p.rms_error),
            _e(p.max_error),
            _e(p.energy_error),
            _e(p.constraint_drift),
            _seconds(p.seconds),
            str(p.runs),
            evals,
            str(p.steps),
            status,
        )
    console.print(table)
    costs = ", ".join(f"{name} {_seconds(value)}" for name, value in compile_costs.items() if value > 0.01)
    console.print(f"one-time costs (code generation, import, compile or load), not in the run times: {inert(costs) or 'none above 10 ms'}")
    fastest = result.fastest
    if fastest:
        summary = Table(title="fastest method for each accuracy (error = largest over the samples)", title_justify="left")
        for column in ("error <=", "fastest", "setting", "run time", "error reached"):
            summary.add_column(column)
        for level, p in fastest:
            tied = result.ties(level, p)
            name = p.method + (f" (tie within {TIE_MARGIN:.0%}: {', '.join(t.method for t in tied)})" if tied else "")
            summary.add_row(f"{level:.0e}", inert(name), inert(p.setting), _seconds(p.seconds), _e(p.error))
        console.print(summary)
        for level, p in fastest:
            _reproduce(console, file, model, p, f"error <= {level:.0e}: ")
    elif result.unconfirmed:
        console.print("no fastest method: the reference is one run that no second method confirmed (see its line), so it vouches for no run's error; the errors above are against that run alone")
    else:
        console.print("[red]no run finished with a finite error[/red]")


@app.command()
def stress(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system (e.g. stiff_spring_pendulum_damped).")],
    scale: Annotated[list[str] | None, typer.Option("--scale", help="Sweep parameters: k=1e2..1e8 (every decade) or k=1,10,100, repeated or separated by commas (k=1..100,m=1,2).")] = None,
    accuracy_: Annotated[
        float | None, typer.Option("--accuracy", help="Required error; exit 1 when in some regime no method meets it (default: 1e-6, reported only).", callback=check_fraction)
    ] = None,
    method: Annotated[list[str] | None, typer.Option("--method", help="Methods to try (default: RK45:python, every method, auto).")] = None,
    t_end: Annotated[float | None, typer.Option("--t-end", help="Final time (default: the file's).", callback=check_positive)] = None,
    long: Annotated[float, typer.Option(help="The long-horizon regime runs this many times t_end.", callback=check_positive)] = 10.0,
    energy: Annotated[float, typer.Option(help="The high-energy regime multiplies the initial velocities by this.", callback=check_positive)] = 3.0,
    max_steps: Annotated[int, typer.Option("--max-steps", help=STEPS_HELP, callback=check_steps)] = STRESS_STEPS,
    budget: Annotated[float | None, typer.Option(help=TIME_LIMIT_HELP + " A regime that no run met because of it is undecided (exit 0).", callback=check_positive)] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help=QUIET_HELP)] = False,
    json: Annotated[Path | None, typer.Option("--json", help="Write the report as JSON (- for stdout).")] = None,
) -> None:
    """Push a system towards its hard regimes; diagnose stiffness, singular coordinates, drift and blow-ups; recommend a method."""
    check_outputs(json, reading=file, options=("--json",))
    from lagrange_cli.cli.progress import Reporter
    from lagrange_cli.errors import LagrangeError

    try:
        from lagrange_cli.cli.boundary import check_names
        from lagrange_cli.derive import load_model
        from lagrange_cli.numeric import stress as core

        scales = _scales(scale or [])  # before any work
        model = load_model(file, shared=True)  # compiled from the symengine forms
        check_names([item for item, _ in scales], [p.name for p in model.parameters], "parameter", model.source)
        with Reporter("stress", "regime", quiet) as reporter:
            report = core.stress(
                model,
                scales=[(item.name, values) for item, values in scales],
                target=accuracy_ if accuracy_ is not None else 1e-6,
                candidates=_candidates(method),
                t_end=t_end,
                long_factor=long,
                energy_factor=energy,
                max_steps=max_steps,
                time_limit=budget,
                progress=reporter,
            )
        if json is not None:
            _write_text(json, core.json_text(report))
    except LagrangeError as error:
        fail_with(error)
    _report_stress(report, to_stderr=str(json) == "-", file=file, model=model)
    if accuracy_ is not None and report.failed:
        raise typer.Exit(1)


def _reproduce(console: Console, file: str, model: Model, point: Point, indent: str) -> None:
    """The `lagrange simulate` command line that repeats `point`'s run exactly (`reports.simulate_command`)."""
    from lagrange_cli.numeric.reports import simulate_command

    command = simulate_command(file, model, point)
    if command is not None:
        console.print(plain(f"{indent}try: {command}"), markup=False)


def _report_stress(report: Report, to_stderr: bool, file: str, model: Model) -> None:
    from rich.table import Table

    from lagrange_cli.numeric.accuracy import TIE_MARGIN, tol_text
    from lagrange_cli.numeric.reports import start_options

    console = _console(to_stderr)
    console.print(f"[bold]{inert(report.title)}[/bold]: stress test, required error {tol_text(report.accuracy)}")
    summary = Table(title="summary", title_justify="left")
    for column in ("regime", "diagnosis", "naive (scipy RK45)", "auto", "recommended"):
        summary.add_column(column)
    for o in report.outcomes:
        console.print()
        window = f", measured to t = {o.t_end:.3g} (predictability horizon)" if o.t_end < o.regime.t_end else ""
        console.print(f"[bold]{inert(o.regime.name)}[/bold]: t_end = {o.regime.t_end:g}{window}")
        start = start_options(model, o.regime.parameters, o.regime.initial)
        if start:
            console.print(plain(f"  start: {start}"), markup=False)
        console.print(plain(f"  reference: {o.reference} (own error {_e(o.reference_error)})"), markup=False)
        d = o.diagnosis
        console.print(plain(f"  {_measurements(d)}"), markup=False)
        for finding in d.findings:
            console.print(plain(f"  - {finding}"), markup=False)
        for known in o.known:
            console.print(plain(f"  - {known}"), markup=False)
        table = Table(box=None, padding=(0, 1))
        for column in ("method", "setting", "error", "final/RMS", "energy", "constraint", "run time", "steps", "evals (jac)", "status"):
            table.add_column(column, justify="left" if column in ("method", "setting", "status") else "right")
        for p in (o.naive_default, *o.points) if o.naive_default is not None else o.points:
            met = o.meets(p, report.accuracy)
            missed = "[yellow]misses[/yellow]" + (f": {inert(p.reason)}" if p.reason else "")  # and why it was not run tighter
            status = ("[green]meets[/green]" if met else missed) if p.ok else f"[red]{inert(p.status)}[/red]: {inert(p.reason)}"
            status += f" ({inert(p.reason)})" if p.predicted and met else ""  # not run: its compiled twin's steps and errors, its time predicted
            name = _shown(p)
            evals = f"{p.nfev} ({p.njev})" if p.njev else str(p.nfev)
            setting = f"{p.setting} (default)" if p is o.naive_default else p.setting
            table.add_row(
                inert(name), inert(setting), _claimed(p.error, o.reference_error), _e(p.final_rms_error), _e(p.energy_error), _e(p.constraint_drift), _seconds(p.seconds), str(p.steps), evals, status
            )
        console.print(table)
        best = o.recommended
        if best is not None:
            console.print(f"  recommended: [bold]{inert(best.resolved)}[/bold] at {inert(best.setting)} (error {_claimed(best.error, o.reference_error)} in {_seconds(best.seconds)})")
            _reproduce(console, file, model, best, "  ")
            for other in o.ties:
                console.print(
                    f"  tie (within {TIE_MARGIN:.0%} of its run time): {inert(other.resolved)} at {inert(other.setting)} (error {_claimed(other.error, o.reference_error)} in {_seconds(other.seconds)})"
                )
                _reproduce(console, file, model, other, "    ")
        elif o.beyond:
            console.print(plain(f"  beyond the model: {o.beyond}"), markup=False)
        elif o.undecided and o.open_reason:
            console.print(plain(f"  undecided: no method was shown to meet error {tol_text(report.accuracy)}: {o.open_reason}"), markup=False)
        elif o.undecided:
            console.print(f"  [yellow]undecided: no method met error {tol_text(report.accuracy)}, but some run was stopped by the time limit (--budget)[/yellow]")
        else:
            console.print(f"  [red]no method meets error {tol_text(report.accuracy)} in this regime[/red]")
        summary.add_row(
            inert(o.regime.name),
            inert("; ".join(f.kind for f in d.findings if not f.note) or "benign"),
            inert(_naive(o, report.accuracy)),
            inert(_brief(o.auto, report.accuracy, o.reference_error)),
            inert(_brief(best, report.accuracy, o.reference_error) + (f" (tie: {', '.join(t.method for t in o.ties)})" if o.ties else "")) if best else _open(o),
        )
    console.print()
    console.print(summary)
    if report.passed:
        verdict = "every regime has a method that meets it" if not any(o.beyond for o in report.outcomes) else "every regime the model reaches has a method that meets it"
    elif report.failed:
        verdict = "[red]some regime has no method that meets it[/red]"
    else:
        verdict = "[yellow]undecided: in some regime it is open whether a method meets it (no reference could be made, the reference's own error leaves it open, or the time limit (--budget) stopped its runs); no regime failed[/yellow]"
    console.print(f"required error {tol_text(report.accuracy)}: {verdict}")


def _open(o: Outcome) -> str:
    """The summary's recommendation cell of a regime without one."""
    return "beyond the model" if o.beyond else "undecided" if o.undecided else "[red]none[/red]"


def _measurements(d: Diagnosis) -> str:
    """The diagnosis's measurements and where they were made; one that could not be made is
    said to be not measured, with why (never a placeholder number)."""
    if d.rate is None:
        spectrum = f"stiffness and time scales not measured ({d.unmeasured or 'no state was reached'})"
    else:
        own = f" (decays up to {d.followed:.3g} x t_end are the solution's own motion, as fast as it changes: not stiffness)" if d.followed > (d.decay_span or 0.0) else ""
        spectrum = f"decay x t_end {d.decay_span:.3g}{own}, stiffness ratio {d.stiffness_ratio:.3g}, time scales {d.scale_ratio:.3g}, fastest rate {d.rate:.3g}/s"
    if d.condition is None:
        conditioning = "cond M not measured (M could not be evaluated at any state reached)"
    elif not math.isfinite(d.condition):
        conditioning = "M singular" + (f" at t = {d.condition_at:.4g}" if d.condition_at is not None else "")
    else:
        conditioning = f"max cond M {d.condition:.2g}" + (f" (at t = {d.condition_at:.4g})" if d.condition_at is not None else "")
    return f"{spectrum}, {conditioning}, {d.where}"


def _naive(outcome: Outcome, target: float) -> str:
    """scipy's RK45 at its default tolerances (its error and run time, and how many times the
    recommended run time it costs when it meets the accuracy only by brute force), then at the
    loosest tolerance that met the accuracy (if any)."""
    from lagrange_cli.numeric.accuracy import tol_text

    first, best = outcome.naive_default, outcome.naive
    if first is None:
        return _brief(best, target)
    if first.ok:
        verdict = "ok" if first.error <= target else "misses"
        rec = outcome.recommended
        if first.error <= target and rec is not None and rec.seconds > 0 and first.seconds >= 10 * rec.seconds:
            verdict = f"ok, but {first.seconds / rec.seconds:.0f}x the recommended run time"
        text = f"default rtol {tol_text(first.tolerance)}: {_e(first.error)} in {_seconds(first.seconds)} ({verdict})"
    else:
        text = f"default rtol {tol_text(first.tolerance)}: {first.status}"
    if best is not None and best is not first and best.ok and not (first.ok and first.error <= target):
        text += f"; {_brief(best, target)}"
    return text


def _brief(p: object, target: float, own: float | None = None) -> str:
    from lagrange_cli.numeric.accuracy import Point

    if not isinstance(p, Point):
        return "-"
    if not p.ok:
        return f"{p.status}"
    mark = "ok" if p.error <= target else "misses"
    ran = p.ran.method if p.ran is not None else p.method
    return f"{ran} {p.setting}: {_claimed(p.error, own)} in {_seconds(p.seconds)} ({mark})"


def _shown(p: Point) -> str:
    """What ran, preceded by what was asked when that named another method (`auto -> DOP853 (compiled)`)."""
    if p.ran is None or p.candidate is None or p.candidate.method == p.ran.method:
        return p.resolved
    return f"{p.method} -> {p.resolved}"
