"""The reports of a study: rows for CSV and JSON, and the work-precision figure.

Everything here reads typed points (`runs.Point`): the backend and method a point ran on come from
its `ran` record, never from its text.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from lagrange_cli.numeric.output import figure_title, inert, plain_text, plot_text
from lagrange_cli.numeric.runs import Point, exact_text
from lagrange_cli.numeric.settings import STAGES

if TYPE_CHECKING:
    from collections.abc import Mapping

    from matplotlib.figure import Figure

    from lagrange_cli.model import Model
    from lagrange_cli.numeric.accuracy import Study


def simulate_options(point: Point) -> list[str] | None:
    """The options of `lagrange simulate` that repeat the run of `point` exactly (method and backend
    as they ran, every number as it round-trips: the symplectic step and stages, or rtol, atol and a
    bound on the step), without the time span and the start (`simulate_command`); None when nothing ran."""
    s = point.settings
    if s is None or point.ran is None:
        return None
    options = ["--method", point.ran.method, "--backend", point.ran.backend]
    if point.ran.method == "symplectic" and s.step is not None:
        options += ["--step", exact_text(s.step), "--stages", str(s.stages if s.stages is not None else STAGES)]
    else:
        options += ["--rtol", exact_text(s.rtol), "--atol", exact_text(s.atol)]
        if math.isfinite(s.max_step):
            options += ["--max-step", exact_text(s.max_step)]
    from lagrange_cli.numeric.integrators import MAX_STEPS

    if point.steps > MAX_STEPS.get(point.ran.backend, 0):  # the study's budget is larger than simulate's default
        options += ["--max-steps", str(2 * point.steps)]  # any budget above what the run took gives the same run
    return options


def simulate_command(file: str, model: Model, point: Point) -> str | None:
    """A `lagrange simulate` command line that repeats the run of `point`: `file`, the time span
    and the sample count, the parameters and initial values where they differ from the file's, and
    `simulate_options`; every word shell-quoted (file text is never shell input). None when nothing ran."""
    import shlex

    options, s = simulate_options(point), point.settings
    if options is None or s is None:
        return None
    words = ["lagrange", "simulate", file, "--t-end", exact_text(s.t_end)]
    if len(s.t_eval) >= 2 and s.t_eval[0] == s.t0 and s.t_eval[-1] == s.t_end:
        words += ["--samples", str(len(s.t_eval))]
    names = [*model.coordinates, *(f"{c}_dot" for c in model.coordinates)]
    words += _start_words(model, dict(s.parameters), dict(zip(names, s.y0, strict=True)))
    return shlex.join([*words, *options])


def start_options(model: Model, parameters: Mapping[str, float], initial: Mapping[str, float]) -> str:
    """The options (`--set`, `--initial`, shell-quoted, every number as it round-trips) that start a run where a stress
    regime starts: its parameter and initial values that differ from the file's ("" where none do). Printed for every
    regime, also one whose reference could not be made and that so has no `try:` line (audit 11, F3)."""
    import shlex

    return shlex.join(_start_words(model, parameters, initial))


def _start_words(model: Model, parameters: Mapping[str, float], initial: Mapping[str, float]) -> list[str]:
    """`--set` and `--initial` with the values that differ from the file's, every number as it round-trips."""
    defaults = {p.name: p.value for p in model.parameters}
    changed = [f"{name}={exact_text(value)}" for name, value in parameters.items() if defaults.get(name) is None or float(defaults[name]) != value]  # type: ignore[arg-type]
    moved = [f"{name}={exact_text(value)}" for name, value in initial.items() if float(model.initial.get(name, 0.0)) != value]
    return [*(["--set", ",".join(changed)] if changed else []), *(["--initial", ",".join(moved)] if moved else [])]


COLUMNS = (
    "method",
    "ran",
    "setting",
    "simulate",
    "status",
    "final_error",
    "rms_error",
    "max_error",
    "energy_error",
    "constraint_drift",
    "seconds",
    "runs",
    "compile_seconds",
    "nfev",
    "njev",
    "steps",
    "reason",
)


def rows(result: Study) -> list[dict[str, object]]:
    """One plain dict per point (for CSV and JSON)."""
    out: list[dict[str, object]] = []
    for p in result.points:
        out.append(
            {
                "method": p.method,
                "ran": p.resolved,
                "setting": p.setting,
                "simulate": simulate_options(p),
                "status": p.status,
                "final_error": p.final_error,
                "rms_error": p.rms_error,
                "max_error": p.max_error,
                "energy_error": p.energy_error,
                "constraint_drift": p.constraint_drift,
                "seconds": p.seconds,
                "runs": p.runs,
                "compile_seconds": p.compile_seconds,
                "nfev": p.nfev,
                "njev": p.njev,
                "steps": p.steps,
                "reason": p.reason,
            }
        )
    return out


def csv_text(result: Study) -> str:
    import csv
    import io
    import shlex

    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows(result):
        writer.writerow({k: ("" if v is None else repr(v) if isinstance(v, float) else shlex.join(v) if isinstance(v, list) else v) for k, v in row.items()})
    return buffer.getvalue()


def _json_number(value: object) -> object:
    return None if isinstance(value, float) and not math.isfinite(value) else value


def json_text(result: Study) -> str:
    import json

    h = result.horizon
    document = {
        "system": result.title,
        "source": result.source,
        "t_end": result.t_end,
        "full_t_end": result.full_t_end,
        "reference": {"kind": result.reference.kind, "description": result.reference.description, "own_error": _json_number(result.reference.own_error), "seconds": result.reference.seconds},
        "horizon": None if h is None else {"delta": h.delta, "chaotic": h.chaotic, "lyapunov": h.lyapunov, "horizon": _json_number(h.horizon), "growth": h.growth},
        "points": [{k: _json_number(v) for k, v in row.items()} for row in rows(result)],
        "fastest": [
            {
                "error": level,
                "method": p.method,
                "setting": p.setting,
                "simulate": simulate_options(p),
                "seconds": p.seconds,
                "error_reached": p.error,
                "ties": [t.method for t in result.ties(level, p)],
            }
            for level, p in result.fastest
        ],
        "notes": list(result.notes),
    }
    return json.dumps(document, indent=2, allow_nan=False) + "\n"


BACKEND_STYLES = {"compiled": ("-", "o", "full"), "python": ("--", "s", "none")}
"""Line style, marker and marker fill of each backend, so that a method's compiled and pure-Python runs differ at a glance."""
BACKEND_NAMES = {"compiled": "compiled (numba)", "python": "pure Python (scipy)"}


def run_backend(point: Point) -> str:
    """The backend a point ran on, "compiled" or "python" ("" when nothing ran)."""
    if point.ran is not None:
        return point.ran.backend
    return point.candidate.backend if point.candidate is not None and point.candidate.backend != "auto" else ""


def plot_label(point: Point) -> str:
    """`DOP853 (compiled)`, `RK45 (python)`; `auto -> DOP853 (compiled)` when the request named another method."""
    requested = point.candidate.method if point.candidate is not None else point.method
    ran = point.ran.method if point.ran is not None else requested
    backend = run_backend(point)
    label = f"{ran} ({backend})" if backend else ran
    return label if requested == ran else f"{requested} -> {label}"


@plain_text()
def study_figure(result: Study) -> Figure:
    """Two log-log panels, error against run time and against right-hand side evaluations, one
    line per method and backend: compiled runs solid with filled circles, pure-Python runs dashed
    with open squares, one colour per method; the reference's own error dotted. The legend is
    outside the panels. File text is shown as written."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    figure = Figure(figsize=(12.0, 5.0), layout="constrained")
    left, right = figure.subplots(1, 2)
    colours: dict[str, str] = {}
    cycle = [entry["color"] for entry in matplotlib_cycle()]
    handles: list[Any] = []
    labels: list[str] = []
    for method in dict.fromkeys(p.method for p in result.points):
        good = [p for p in result.points if p.method == method and p.ok and p.error > 0]
        if not good:
            continue
        label, backend = plot_label(good[0]), run_backend(good[0])
        if label in labels:
            label = f"{label} [{plot_text(method)}]"
        requested = good[0].candidate.method if good[0].candidate is not None else good[0].method  # one colour a method, its backends told apart by style
        colour = colours.setdefault(requested, cycle[len(colours) % len(cycle)])
        style, marker, fill = BACKEND_STYLES.get(backend, (":", "^", "full"))
        errors_ = [p.error for p in good]
        options = {"color": colour, "linestyle": style, "marker": marker, "fillstyle": fill, "label": label}
        (line,) = left.loglog([p.seconds for p in good], errors_, **options)
        right.loglog([max(p.nfev, 1) for p in good], errors_, **options)
        handles.append(line)
        labels.append(label)
    finished = bool(handles)
    own = result.reference.own_error
    if finished and math.isfinite(own) and own > 0:
        for axes in (left, right):
            axes.axhline(own, color="grey", linestyle=":", linewidth=1.0)
        handles.append(Line2D([], [], color="grey", linestyle=":", linewidth=1.0))
        labels.append("reference's own error")
    titles = ("error against run time", "error against work (independent of the machine)")
    for axes, xlabel, title in zip((left, right), ("run time [s] (one-time compile excluded)", "right-hand side evaluations"), titles, strict=True):
        axes.set_xlabel(xlabel)
        axes.set_ylabel("error (largest over the samples, scaled)")
        axes.set_title(title, fontsize="medium")
        axes.grid(True, which="both", alpha=0.3)
        if not finished:
            axes.text(0.5, 0.5, "no run finished", transform=axes.transAxes, ha="center", va="center")
    if finished:
        backends = sorted({run_backend(p) for p in result.points if p.ok} & set(BACKEND_NAMES))
        key = "; ".join(f"{'solid' if b == 'compiled' else 'dashed'}: {BACKEND_NAMES[b]}" for b in backends)
        order = sorted(range(len(labels)), key=lambda i: (labels[i] == "reference's own error", labels[i]))
        legend = figure.legend(
            [handles[i] for i in order], [labels[i] for i in order], loc="outside lower center", ncols=min(len(labels), 4), fontsize="small", title=key or None, title_fontsize="small"
        )
        inert(*legend.get_texts())
    window = f"t = 0..{result.t_end:.3g}" + (" (predictability horizon)" if result.t_end < result.full_t_end else "")
    figure_title(figure, f"{plot_text(result.title)}: work-precision, {window}")
    return figure


def matplotlib_cycle() -> list[dict[str, Any]]:
    import matplotlib

    return list(matplotlib.rcParams["axes.prop_cycle"])


@plain_text()
def write_plot(result: Study, path: object) -> None:
    """`study_figure`, written atomically (.png, .svg or .pdf)."""
    from pathlib import Path

    import matplotlib

    from lagrange_cli.files import atomic_write

    matplotlib.use("Agg")
    target = Path(str(path)).resolve()
    figure = study_figure(result)
    atomic_write(target, lambda stream: figure.savefig(stream, format=target.suffix.lstrip(".").lower(), dpi=120))
