"""Sweeps and ensembles: many runs of one system over grids or samples of parameters and initial values.

    table = sweep(model, axes=[Axis("set", "k", 1, 100, 50, log=True)], measures=["max(theta)"])

A sweep is a list of points (a grid: every combination of the axes' values, the last axis
fastest; or `sample` points drawn uniformly, log-uniformly for log axes, from the axes' ranges
with a seed). Each point is one run from the file's state with its parameters and initial
values replaced; each run gives one row (`index`, the axes' values, `status`, `reason`, the
measures) or, for a Poincaré section, one row per crossing. A run that fails is a row with
its reason, never a lost sweep.

Execution: the system's compiled right-hand side (the compile cache, numeric/compile.py) is
built once per process and a batch's runs are integrated in one compiled call (numeric/ensemble.py:
`batch`, or `sections` for a Poincaré section, whose runs go on after each crossing; a Lyapunov
exponent takes one call per segment), with the GIL released, so that a run costs its integration
and a few microseconds more. Consecutive batches are grouped (large first, `_task_groups`) and a group's runs
share one compiled call when every measure is read off a run's end. `workers > 1` runs the groups on that many threads; `scheduler` sends
the groups to a `dask.distributed` cluster instead (imported only then), whose workers all build
the system at the start of the sweep (once per worker process) and return rows collected in order.
Methods other than the compiled explicit pairs (symplectic, the scipy methods, or the python
backend) run each point through `simulate.integrate`, the same as `lagrange simulate`.

Measures (`measures`, strings):
- `final`: the final state, one column per coordinate and velocity (`theta_final`, ...);
- an expression of `t`, the coordinates, velocities and parameters (the safe parser): its value at the end;
- `max(EXPR)`, `min(EXPR)`, `mean(EXPR)`: over the samples (`samples`, evenly spaced);
- `t_event`: the time the `until` condition crossed zero (NaN when it did not);
- `energy_error`: the largest change of the energy over the samples, relative to its scale;
- `lyapunov`: the largest finite-time Lyapunov exponent, from a second run 1e-8 away in
  the state, renormalised every `LYAPUNOV_SEGMENTS`-th of the interval (Benettin's method);
- `period`, `period(EXPR)`: the mean time between successive upward crossings of EXPR's mean
  (default: the first velocity through 0), by linear interpolation of the samples; NaN with fewer than two.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import gc
import hashlib
import itertools
import json
import math
import os
import re
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import sympy as sp

from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model

if TYPE_CHECKING:
    import numpy as np

BATCH = 64
"""Runs per batch: a batch is the unit of delivery, writing and resuming; a thread's or a Dask task's work is a group
of consecutive batches (`_task_groups`), its runs in one compiled call where the measures allow (`_group_task`)."""
LANES = True
"""Whether a batch on the compiled explicit path runs in lockstep lanes where it can (numeric/lanes.py); False:
run by run in one compiled call (ensemble.batch), as before (benchmarks/sweep_bench.py measures both)."""
LYAPUNOV_SEGMENTS = 50
LYAPUNOV_SEPARATION = 1e-8
MAX_CROSSINGS = 100_000
SWEEP_SAMPLES = 201
"""Samples of a run when a measure needs them and `samples` is not given."""
CONNECT_TIMEOUT = 10  # seconds to reach a Dask scheduler
TASKS_PER_WORKER = 2
"""A Dask task (and a thread's piece of work with --workers, or one worker's) carries several batches: each takes 1/(TASKS_PER_WORKER x workers) of the batches left (`_task_groups`),
so about 5 tasks a worker, large first: Dask's fixed cost per task (scheduling, transfers; a few ms) is then small
against the task's runs, which lockstep lanes make cheap (benchmarks/sweep_bench.py), the last tasks are small (the
workers finish together), a lost worker's tasks stay small to rerun and rows still stream back batch by batch."""
MAX_BATCHES_PER_TASK = 64
_CALL = re.compile(r"^\s*(max|min|mean|period)\s*\((.*)\)\s*$", re.S)


@dataclass(frozen=True)
class Axis:
    """One swept quantity: a parameter (`kind` "set") or an initial coordinate or velocity
    ("initial"), from `lo` to `hi` in `count` values (linear, or geometric with `log`); `count`
    None for a range to sample (`--sample`)."""

    kind: str
    name: str
    lo: float
    hi: float
    count: int | None = None
    log: bool = False

    @property
    def column(self) -> str:
        """Its column in the table: the parameter's name, or `theta(0)` for an initial value."""
        return self.name if self.kind == "set" else f"{self.name}(0)"

    def values(self) -> np.ndarray:
        import numpy as np

        assert self.count is not None
        if self.log:
            return np.geomspace(self.lo, self.hi, self.count)
        return np.linspace(self.lo, self.hi, self.count)

    def draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        import numpy as np

        if self.log:
            return np.exp(rng.uniform(math.log(self.lo), math.log(self.hi), n))
        return rng.uniform(self.lo, self.hi, n)


@dataclass(frozen=True)
class Section:
    """A Poincaré section: where `surface` (an expression) crosses zero, kept when every one of
    `conditions` (expressions) is positive there."""

    text: str
    surface: sp.Expr
    conditions: tuple[sp.Expr, ...]


@dataclass
class Table:
    """The rows of a sweep in index order: `columns`, and `rows` (lists of values). `to_pandas()`
    gives a DataFrame (pandas installed); `column(name)` a numpy array."""

    columns: list[str]
    rows: list[list[Any]] = field(default_factory=list)

    def column(self, name: str) -> np.ndarray:
        import numpy as np

        k = self.columns.index(name)
        return np.array([row[k] for row in self.rows], dtype=object if name in ("status", "reason") else float)

    def __len__(self) -> int:
        return len(self.rows)

    def to_pandas(self) -> Any:
        import pandas as pd

        return pd.DataFrame(self.rows, columns=self.columns)


def check_axes(model: Model, axes: Sequence[Axis], sample: int | None) -> None:
    """Every axis names a parameter or a coordinate/velocity, has a valid range, and a count
    exactly when there is no `sample`; raises `LagrangeError`."""
    states = [*model.coordinates, *(f"{c}_dot" for c in model.coordinates)]
    params = [p.name for p in model.parameters]
    seen = set()
    for axis in axes:
        option = "--set" if axis.kind == "set" else "--initial"
        names = params if axis.kind == "set" else states
        if axis.name not in names:
            raise LagrangeError(f"{option} {axis.name}: not a {'parameter' if axis.kind == 'set' else 'coordinate or velocity'} of {model.source}; choose one of {', '.join(names) or 'none'}")
        if (axis.kind, axis.name) in seen:
            raise LagrangeError(f"{option} {axis.name}: given twice; give each swept quantity once")
        seen.add((axis.kind, axis.name))
        if not (math.isfinite(axis.lo) and math.isfinite(axis.hi)):
            raise LagrangeError(f"{option} {axis.name}: the range must be finite, got {axis.lo:g}..{axis.hi:g}")
        if axis.log and not (axis.lo > 0 and axis.hi > 0):
            raise LagrangeError(f"{option} {axis.name}: log spacing needs a positive range, got {axis.lo:g}..{axis.hi:g}")
        if sample is None and axis.count is None:
            raise LagrangeError(f"{option} {axis.name}={axis.lo:g}..{axis.hi:g}: a range needs a count to make a grid (e.g. {axis.name}={axis.lo:g}..{axis.hi:g}:50), or give --sample N")
        if sample is not None and axis.count is not None:
            raise LagrangeError(f"{option} {axis.name}: with --sample, give ranges without a count (e.g. {axis.name}={axis.lo:g}..{axis.hi:g})")
        if axis.count is not None and (isinstance(axis.count, bool) or not isinstance(axis.count, int) or axis.count < 1):
            raise LagrangeError(f"{option} {axis.name}: the count must be a whole number of at least 1, got {axis.count!r}")
    if sample is not None and (isinstance(sample, bool) or not isinstance(sample, int) or sample < 1):
        raise LagrangeError(f"--sample must be a whole number of at least 1, got {sample!r}")
    if not axes:
        raise LagrangeError("nothing to sweep: give at least one range, e.g. --set k=1..10:20 or --initial theta=0..3:50")


def points(axes: Sequence[Axis], sample: int | None = None, seed: int = 0) -> np.ndarray:
    """The sweep's points, one row each (one column per axis): a grid (last axis fastest) or a sample."""
    import numpy as np

    if sample is not None:
        rng = np.random.default_rng(seed)
        return np.column_stack([axis.draw(rng, sample) for axis in axes]) if axes else np.empty((sample, 0))
    grid = list(itertools.product(*(axis.values().tolist() for axis in axes)))
    return np.array(grid, dtype=float).reshape(len(grid), len(axes))


# -- expressions ---------------------------------------------------------------------------------


def _scope_symbols(model: Model) -> list[sp.Symbol]:
    return [model.t, *model.q, *model.qd, *(p.symbol for p in model.parameters)]


def parse_quantity(model: Model, text: str, option: str) -> sp.Expr:
    """An expression of t, the coordinates, velocities and parameters, parsed safely."""
    from lagrange_cli.errors import Span
    from lagrange_cli.expr import Scope, parse_expression

    symbols: dict[str, sp.Expr] = {str(s): s for s in (*model.q, *model.qd, model.t)}
    symbols.update({p.name: p.symbol for p in model.parameters})

    def no_derivative(expr: sp.Expr) -> sp.Expr:
        raise LagrangeError(f"{option}: time derivatives are not allowed; write velocities as `<q>_dot`")

    scope = Scope(symbols, {}, model.t, no_derivative, "a coordinate, velocity (`<q>_dot`), parameter or `t`")
    return parse_expression(text, Span(option, 1, 1, text), scope)


def _vectorised(model: Model, expr: sp.Expr) -> Callable[..., Any]:
    """expr as a numpy function of (t, q..., q_dot..., parameters...), arrays broadcast."""
    return sp.lambdify(_scope_symbols(model), expr, modules="numpy", dummify=True)  # type: ignore[no-any-return]


def parse_section(model: Model, text: str) -> Section:
    """`theta=0, theta_dot>0`: the surface (an equation, or an expression crossing zero) and
    conditions (`A>B` or `A<B`) that must hold at a crossing for it to be kept."""
    pieces = [piece.strip() for piece in _split_top(text)]
    if not pieces or not pieces[0]:
        raise LagrangeError(f"--section {text!r}: expected a surface such as 'theta=0' followed by conditions such as 'theta_dot>0'")
    first = pieces[0]
    if first.count("=") == 1:
        left, right = first.split("=")
        surface = parse_quantity(model, left, "--section") - parse_quantity(model, right, "--section")
    elif "=" in first or "<" in first or ">" in first:
        raise LagrangeError(f"--section {text!r}: the surface must be one equation such as 'theta=0', got {first!r}")
    else:
        surface = parse_quantity(model, first, "--section")
    conditions = []
    for piece in pieces[1:]:
        match = re.fullmatch(r"([^<>=]+)(<|>)([^<>=]+)", piece)
        if match is None:
            raise LagrangeError(f"--section {text!r}: {piece!r} is not a condition; expected A>B or A<B, e.g. theta_dot>0")
        a, b = parse_quantity(model, match.group(1), "--section"), parse_quantity(model, match.group(3), "--section")
        conditions.append(a - b if match.group(2) == ">" else b - a)
    return Section(text, surface, tuple(conditions))


def _split_top(text: str) -> list[str]:
    pieces, depth, start = [], 0, 0
    for at, char in enumerate(text):
        if char in "([{":
            depth += 1
        elif char in ")]}":
            depth = max(depth - 1, 0)
        elif char == "," and depth == 0:
            pieces.append(text[start:at])
            start = at + 1
    pieces.append(text[start:])
    return pieces


@dataclass(frozen=True)
class Measure:
    """One measure: its column names and what it needs."""

    text: str
    kind: str  # final, value, max, min, mean, t_event, energy_error, lyapunov, period
    expr: sp.Expr | None = None

    @property
    def sampled(self) -> bool:
        return self.kind in ("max", "min", "mean", "energy_error", "period")


def parse_measures(model: Model, texts: Sequence[str], until: str | None) -> tuple[Measure, ...]:
    """The measures asked for (default: the final state, and t_event with `until`)."""
    result: list[Measure] = []
    for text in texts or (["final", "t_event"] if until else ["final"]):
        bare = text.strip()
        call = _CALL.match(bare)
        if bare in ("final", "t_event", "energy_error", "lyapunov", "period"):
            if bare == "t_event" and until is None:
                raise LagrangeError("--measure t_event: the time of an event needs --until CONDITION")
            expr = model.qd[0] - 0 if bare == "period" else None
            result.append(Measure(bare, bare, expr))
        elif call is not None:
            result.append(Measure(bare, call.group(1), parse_quantity(model, call.group(2), "--measure")))
        elif not bare:
            raise LagrangeError("--measure: an empty measure; expected an expression or one of final, max(EXPR), min(EXPR), mean(EXPR), t_event, energy_error, lyapunov, period")
        else:
            result.append(Measure(bare, "value", parse_quantity(model, bare, "--measure")))
    return tuple(result)


# -- one process's runner ------------------------------------------------------------------------


@dataclass(frozen=True)
class Job:
    """Everything a worker needs to run points of a sweep: plain data (the file's text, not a path)."""

    text: str
    filename: str
    axes: tuple[Axis, ...]
    measures: tuple[str, ...]
    section: str | None
    options: tuple[tuple[str, Any], ...]
    """Settings of `settings.validate` (t_end, method, rtol, atol, step, samples, parameters, initial, until, backend, max_step)."""

    @functools.cached_property
    def key(self) -> str:
        return hashlib.sha256(json.dumps([self.text, self.filename, [dataclasses.astuple(a) for a in self.axes], self.measures, self.section, self.options], default=repr).encode()).hexdigest()[:24]


_RUNNERS: dict[str, Runner] = {}
_RUNNERS_LOCK = threading.Lock()


def runner_for(job: Job, model: Model | None = None) -> Runner:
    """The runner of `job`, built once per process (a Dask worker builds it at its first batch)."""
    with _RUNNERS_LOCK:
        if job.key not in _RUNNERS:
            if model is None:
                from lagrange_cli import derive, spec

                model = derive.derive(spec.parse(job.text, job.filename), shared=True)
            _RUNNERS[job.key] = Runner(model, job)
        return _RUNNERS[job.key]


def run_batch(job: Job, indices: Sequence[int], chunk: np.ndarray) -> list[list[Any]]:
    """Rows of the points `chunk` (numbered `indices`): what a thread or a Dask task runs."""
    return runner_for(job).batch(indices, chunk)


class Runner:
    """A sweep's compiled system and settings, prepared once; `rows` runs a batch of points."""

    def __init__(self, model: Model, job: Job) -> None:
        from lagrange_cli.numeric import compile, policy
        from lagrange_cli.numeric.settings import validate

        self.model, self.job = model, job
        options = dict(job.options)
        base_parameters, base_initial = dict(options.pop("parameters", None) or {}), dict(options.pop("initial", None) or {})
        self.section = parse_section(model, job.section) if job.section else None
        if self.section is not None and options.get("until"):
            raise LagrangeError("--section and --until both use the run's event: give one of them")
        self.measures = parse_measures(model, job.measures, options.get("until"))
        if self.section is not None and job.measures:
            raise LagrangeError("--section writes one row per crossing (the time and state there): give no --measure with it")
        sampled = any(m.sampled for m in self.measures)
        if options.get("samples") is None and options.get("t_eval") is None:
            options["samples"] = SWEEP_SAMPLES if sampled else 2
        # the range's ends are validated too (a positive parameter swept to 0 is refused before any run)
        for end in (0, 1):
            validate(
                model,
                **{k: v for k, v in options.items() if k != "until"},
                parameters={**base_parameters, **{a.name: (a.lo, a.hi)[end] for a in job.axes if a.kind == "set"}},
                initial={**base_initial, **{a.name: (a.lo, a.hi)[end] for a in job.axes if a.kind == "initial"}},
            )
        asked = validate(model, **options, parameters=base_parameters, initial=base_initial)
        if self.section is not None:
            asked = dataclasses.replace(asked, event=self.section.surface, until=self.section.text)
        settings = policy.decide(model, asked)
        self.notes = list(settings.notes)
        if asked.method == "auto" and settings.method == "symplectic":
            settings = dataclasses.replace(settings, method="DOP853", backend="compiled" if compile.numba_available() else "python")
            self.notes.append("auto: DOP853 (adaptive, error-controlled per run) rather than the symplectic method, for a sweep")
        if asked.backend == "auto" and settings.method in ("RK45", "DOP853") and compile.numba_available():
            settings = dataclasses.replace(settings, backend="compiled")  # many runs: compiling once pays
            self.notes = [n for n in self.notes if not n.startswith("backend auto")] + ["backend auto -> compiled: a sweep's runs share one compiled system"]
        self.settings = settings
        if self.section is not None and not (settings.backend == "compiled" and settings.method in ("RK45", "DOP853")):
            raise LagrangeError(f"--section needs the compiled explicit methods (RK45 or DOP853, with numba): {settings.method} ({settings.backend}) stops at the first crossing")
        self.fast = settings.backend == "compiled" and settings.method in ("RK45", "DOP853")
        self.names = (*model.coordinates, *(f"{c}_dot" for c in model.coordinates))
        self.parameter_names = [name for name, _ in settings.parameters]
        self.python = compile.build(model, "python", jacobian=settings.method in ("Radau", "BDF", "LSODA"), event=settings.event)
        if self.fast:
            from lagrange_cli.numeric import integrators
            from lagrange_cli.numeric.tableaux import EXPLICIT

            numba = compile.build(model, "numba", event=settings.event)
            kernels = numba.kernels
            assert kernels is not None
            self.pair = EXPLICIT[settings.method].code
            self.start_entry = kernels.compiled("erk_start")
            self.run_entry = kernels.compiled("erk_run")
            self.accel = numba.module._accel
            self.accel.compile(kernels.ACCEL_SIG.args)
            self.event = numba.module._event
            self.event.compile(kernels.EVENT_SIG.args)
            self.size = numba.module._SIZE
            self.budget = integrators.MAX_STEPS["compiled"]
            from lagrange_cli.numeric.ensemble import erk_batch, erk_sections

            self.batch_entry = erk_batch()
            self.sections_entry: Any = erk_sections() if self.section is not None else None
            self.lanes_entry, self.lanes_accel = self._lanes(model, settings)
            if hasattr(numba.module, "_SWITCHES"):  # switching.py: the batched loops are erk_run's
                self.notes.append(
                    f"{numba.module._SWITCHES} switching surface(s) (Abs, sign, Piecewise, Max, Min): the batched compiled runs step over their crossings without locating them"
                    " (`simulate`, or a sweep with --backend python, lands a step on each)"
                )
        full = model.with_definitions()
        self.vector: dict[str, Callable[..., Any]] = {}
        for m in self.measures:
            if m.expr is not None:
                self.vector[m.text] = _vectorised(model, m.expr)
        if any(m.kind == "energy_error" for m in self.measures):
            self.vector["__energy"] = _vectorised(model, full.energy)
            self.vector["__kinetic"] = _vectorised(model, full.kinetic)
        if self.section is not None:
            self.conditions = [_vectorised(model, c) for c in self.section.conditions]
        self.columns = self._columns()
        self.plain = all(m.kind in ("final", "t_event") for m in self.measures)
        """Every measure is read off the run's end: a batch's rows are made from its arrays (`ended`, `rows`)."""
        self.arrays = self.fast and self.section is None and self.plain
        """How a batch's runs ended comes back from the compiled explicit path as arrays (`ended`: an `Ended`)."""

    def _lanes(self, model: Model, settings: Any) -> tuple[Any, Any]:
        """(the lane loop, the system's `_accel_lanes`) when the batch can run in lockstep lanes (numeric/lanes.py:
        no event or section, no inputs, no kept constraints, a small system), else (None, None): ensemble.batch."""
        if not LANES or self.section is not None or settings.event is not None or model.inputs or model.constraints:
            return None, None
        from lagrange_cli.numeric import lanes

        module = lanes.build(model)
        if module is None:
            return None, None
        loop = lanes.lane_loop()
        module._accel_lanes.compile(lanes.loop_module().LANES_SIG.args)
        return loop, module._accel_lanes

    def _columns(self) -> list[str]:
        axes = [axis.column for axis in self.job.axes]
        if self.section is not None:
            return ["index", *axes, "status", "reason", "crossing", "t", *self.names]
        measured: list[str] = []
        for m in self.measures:
            measured += [f"{n}_final" for n in self.names] if m.kind == "final" else [m.text]
        return ["index", *axes, "status", "reason", *measured]

    # -- running ---------------------------------------------------------------------------------

    def point(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(y0, p) of a point: the base state and parameters with the axes' values."""
        y0s, ps = self.points(values.reshape(1, -1))
        return y0s[0], ps[0]

    def points(self, chunk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The (y0, p) of every point of `chunk` as two arrays, row k that of `point(chunk[k])`."""
        import numpy as np

        from lagrange_cli.numeric.settings import code_parameters

        y0s = np.tile(np.array(self.settings.y0, dtype=float), (len(chunk), 1))
        ps = np.tile(np.array(code_parameters(self.settings.values, self.settings.alpha), dtype=float), (len(chunk), 1))
        for j, axis in enumerate(self.job.axes):
            if axis.kind == "set":
                ps[:, self.parameter_names.index(axis.name)] = chunk[:, j]
            else:
                y0s[:, self.names.index(axis.name)] = chunk[:, j]
        return y0s, ps

    def batch(self, indices: Sequence[int], chunk: np.ndarray) -> list[list[Any]]:
        """The rows of points `chunk` (numbered `indices`): one compiled call for the whole batch
        (numeric/ensemble.py) on the compiled explicit path (a section's crossings too), else run by run."""
        if self.fast and self.section is not None and len(indices) > 0:
            return self.section_batch(indices, chunk)
        if not (self.fast and self.section is None) or len(indices) == 0:
            result: list[list[Any]] = []
            for k, values in zip(indices, chunk, strict=True):
                result += self.run_point(k, values)
            return result
        if self.plain:
            return self.rows(self._ended(indices, chunk))
        return self._measured_batch(indices, chunk)

    def ended(self, indices: Sequence[int], chunk: np.ndarray) -> list[list[Any]] | Ended:
        """`batch`: its rows, or, when every measure is read off a run's end (`final`, `t_event`) on the compiled
        explicit path, how its runs ended as a few arrays (`Ended`: what a Dask task sends back; `rows` makes the rows)."""
        if not self.arrays or len(indices) == 0:
            return self.batch(indices, chunk)
        return self._ended(indices, chunk)

    def _ended(self, indices: Sequence[int], chunk: np.ndarray) -> Ended:
        import numpy as np

        y0s, ps = self.points(chunk)
        codes, t_last, y_last, _ = self._integrate_batch(y0s, ps)
        return Ended(np.asarray(indices, dtype=np.int64), chunk, codes, t_last, y_last)

    def rows(self, ended: Ended) -> list[list[Any]]:
        """The rows of `ended` (the rows `batch` gives), built from its arrays a list at a time: a row costs a
        microsecond or so of Python, not a run's `measured_rows` (an Outcome, numpy's errstate, measures one by one)."""
        import numpy as np

        from lagrange_cli.numeric import status as st

        rows: list[list[Any]] = []
        finals = [m.kind == "final" for m in self.measures]
        only_final = finals == [True]
        for b, (k, head, code, t, y) in enumerate(zip(ended.indices.tolist(), ended.chunk.tolist(), ended.codes.tolist(), ended.t_last.tolist(), ended.y_last.tolist(), strict=True)):
            if code == st.DONE and only_final:
                rows.append([k, *head, "finished", "", *y])
            elif code in (st.DONE, st.EVENT):
                row = [k, *head, "event" if code == st.EVENT else "finished", ""]
                for final in finals:
                    if final:
                        row += y
                    else:
                        row.append(t if code == st.EVENT else math.nan)
                rows.append(row)
            else:  # a failed run: its reason, and NaN for every measure (as `_measured` gives)
                no_samples = np.empty((0, ended.y_last.shape[1]))
                reason = Outcome.failed(self, code, t, ended.y_last[b], no_samples[:, 0], no_samples, []).reason
                rows.append([k, *head, "failed", reason, *([math.nan] * (len(self.columns) - len(head) - 3))])
        return rows

    def _integrate_batch(self, y0s: np.ndarray, ps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(codes, t_last, y_last, ys) of the runs from y0s with ps: one compiled call (lanes where they apply)."""
        import numpy as np

        ts = np.array(self.settings.t_eval, dtype=float)
        control = self._control(self.settings.t0, self.settings.t_end)
        if self.lanes_entry is not None:
            from lagrange_cli.numeric.lanes import LANES as width

            codes, t_last, y_last, ys, _, _ = self.lanes_entry(self.pair, y0s, ps, control, ts, self.budget, width, self.accel, self.lanes_accel)
        else:
            codes, t_last, y_last, ys, _ = self.batch_entry(self.pair, y0s, ps, control, ts, self.budget, self.accel, self.event)
        return codes, t_last, y_last, ys

    def _measured_batch(self, indices: Sequence[int], chunk: np.ndarray) -> list[list[Any]]:
        """`batch`'s rows on the compiled explicit path, run by run through `measured_rows` (any measure)."""
        import numpy as np

        from lagrange_cli.numeric import status as st

        y0s, ps = self.points(chunk)
        ts = np.array(self.settings.t_eval, dtype=float)
        codes, t_last, y_last, ys = self._integrate_batch(y0s, ps)
        exponents = self.lyapunov_batch(y0s, ps) if any(m.kind == "lyapunov" for m in self.measures) else None
        rows: list[list[Any]] = []
        for b, (k, values) in enumerate(zip(indices, chunk, strict=True)):
            code = int(codes[b])
            m = int(np.count_nonzero(~np.isnan(ys[b, :, 0])))
            if code in (st.DONE, st.EVENT):
                outcome = Outcome("event" if code == st.EVENT else "finished", "", float(t_last[b]), y_last[b], ts[:m], ys[b, :m], [], float(t_last[b]) if code == st.EVENT else math.nan)
            else:
                outcome = Outcome.failed(self, code, float(t_last[b]), y_last[b], ts[:m], ys[b, :m], [])
            rows += self.measured_rows([k, *values.tolist()], outcome, y0s[b], ps[b], None if exponents is None else float(exponents[b]))
        return rows

    def section_batch(self, indices: Sequence[int], chunk: np.ndarray) -> list[list[Any]]:
        """The rows of a Poincare section's runs, the whole batch in one compiled call
        (ensemble.sections): the runs and crossings of `_erk(..., crossings=True)`, run by run, so the same rows."""
        import numpy as np

        from lagrange_cli.numeric import status as st

        y0s, ps = self.points(chunk)
        ts = np.array(self.settings.t_eval, dtype=float)
        control = self._control(self.settings.t0, self.settings.t_end)
        codes, t_last, y_last, counts, times, states = self.sections_entry(self.pair, y0s, ps, control, ts, self.budget, MAX_CROSSINGS, self.accel, self.event)
        rows: list[list[Any]] = []
        first = 0
        for b, (k, values) in enumerate(zip(indices, chunk, strict=True)):
            code = int(codes[b])
            events = [(float(times[j]), states[j].copy()) for j in range(first, first + int(counts[b]))]
            first += int(counts[b])
            no_samples = np.empty((0, y0s.shape[1]))
            if code in (st.DONE, st.EVENT):
                outcome = Outcome("event" if code == st.EVENT else "finished", "", float(t_last[b]), y_last[b], ts[:0], no_samples, events, float(t_last[b]) if code == st.EVENT else math.nan)
            else:
                outcome = Outcome.failed(self, code, float(t_last[b]), y_last[b], ts[:0], no_samples, events)
            rows += self.measured_rows([k, *values.tolist()], outcome, y0s[b], ps[b])
        return rows

    def _control(self, t0: float, t1: float) -> np.ndarray:
        import numpy as np

        from lagrange_cli.numeric import status as st

        s = self.settings
        control = np.zeros(st.CONTROL_SIZE)
        control[st.RTOL], control[st.ATOL], control[st.MAX_STEP] = s.rtol, s.atol, s.max_step
        control[st.T_BOUND], control[st.T_STOP], control[st.USE_EVENT] = t1, t1, float(s.event is not None)
        control[st.SIZE], control[st.T0] = self.size, t0
        return control

    def run_point(self, index: int, values: np.ndarray) -> list[list[Any]]:
        import numpy as np

        head = [index, *values.tolist()]
        try:
            y0, p = self.point(values)
            ts = np.array(self.settings.t_eval, dtype=float)
            outcome = self.integrate(y0, p, self.settings.t0, self.settings.t_end, ts, self.section is not None)
        except LagrangeError as error:
            return [[*head, "failed", str(error), *([math.nan] * (len(self.columns) - len(head) - 2))]]
        except Exception as error:  # a run never loses the sweep: its row says what happened
            return [[*head, "failed", f"the run raised {type(error).__name__}: {error}", *([math.nan] * (len(self.columns) - len(head) - 2))]]
        return self.measured_rows(head, outcome, y0, p)

    def measured_rows(self, head: list[Any], outcome: Outcome, y0: np.ndarray, p: np.ndarray, lyapunov: float | None = None) -> list[list[Any]]:
        """The row (or a section's rows) of a run that ended as `outcome` (`lyapunov`: its exponent when computed with its batch)."""
        import numpy as np

        try:
            with np.errstate(all="ignore"):  # a measure undefined somewhere is NaN there
                if self.section is not None:
                    return self._section_rows(head, outcome, p)
                measured = self._measured(outcome, y0, p, lyapunov)
        except Exception as error:
            return [[*head, "failed", f"a measure cannot be evaluated: {type(error).__name__}: {error}", *([math.nan] * (len(self.columns) - len(head) - 2))]]
        return [[*head, outcome.status, outcome.reason, *measured]]

    def integrate(self, y0: np.ndarray, p: np.ndarray, t0: float, t1: float, ts: np.ndarray, crossings: bool = False) -> Outcome:
        if self.fast:
            return self._erk(y0, p, t0, t1, ts, crossings)
        return self._general(y0, p, t0, t1, ts, crossings)

    def _erk(self, y0: np.ndarray, p: np.ndarray, t0: float, t1: float, ts: np.ndarray, crossings: bool) -> Outcome:
        import numpy as np

        from lagrange_cli.numeric import status as st

        y, f = y0.copy(), np.empty_like(y0)
        stats = np.zeros(st.STATS_SIZE)
        stats[st.HMIN] = math.inf
        ys = np.full((len(ts), len(y)), np.nan)
        control = self._control(t0, t1)
        s = self.settings
        x, a = np.empty(self.size), np.empty((self.size, self.size))
        state = np.zeros(st.STATE_SIZE)
        events: list[tuple[float, np.ndarray]] = []
        h0 = self.start_entry(self.pair, t0, y, f, control, p, stats, self.accel)
        if h0 < 0:
            return Outcome.failed(self, st.SINGULAR, t0, y, ts[:0], ys[:0], events)
        state[st.T], state[st.H] = t0, h0
        state[st.EVENT_VALUE] = self.event(t0, y, p, x, a) if s.event is not None else 1.0
        while True:
            code = int(self.run_entry(self.pair, y, f, state, control, ts, ys, p, stats, self.accel, self.event))
            if code == st.RUNNING:
                if stats[st.NSTEPS] >= self.budget:
                    code = st.BUDGET
                else:
                    continue
            if code == st.EVENT and crossings and len(events) < MAX_CROSSINGS:
                events.append((float(state[st.T]), y.copy()))
                h = self.start_entry(self.pair, float(state[st.T]), y, f, control, p, stats, self.accel)  # f at the crossing, a fresh step
                if h < 0:
                    code = st.SINGULAR
                else:
                    state[st.H], state[st.EVENT_VALUE] = h, 0.0  # 0: the next step does not see this crossing again
                    continue
            m = int(state[st.NEXT_SAMPLE])
            if code in (st.DONE, st.EVENT):
                return Outcome("event" if code == st.EVENT else "finished", "", float(state[st.T]), y, ts[:m], ys[:m], events, float(state[st.T]) if code == st.EVENT else math.nan)
            return Outcome.failed(self, code, float(state[st.T]), y, ts[:m], ys[:m], events)

    def _general(self, y0: np.ndarray, p: np.ndarray, t0: float, t1: float, ts: np.ndarray, crossings: bool) -> Outcome:
        """Any other method: `simulate.integrate` (one event: sections need the compiled path)."""
        from lagrange_cli.numeric.simulate import integrate

        if crossings:
            raise LagrangeError(f"--section needs the compiled explicit methods (RK45 or DOP853 with numba); {self.settings.method} ({self.settings.backend}) stops at the first crossing")
        n = len(self.parameter_names)
        settings = dataclasses.replace(self.settings, t0=t0, t_end=t1, y0=tuple(y0.tolist()), t_eval=tuple(ts.tolist()), parameters=tuple(zip(self.parameter_names, p[:n].tolist(), strict=True)))
        trajectory = integrate(self.model, settings)
        if trajectory.failed:
            return Outcome("failed", trajectory.message, trajectory.t_last, trajectory.y_last, trajectory.t, trajectory.y, [])
        return Outcome(trajectory.status, "", trajectory.t_last, trajectory.y_last, trajectory.t, trajectory.y, [], trajectory.t_last if trajectory.status == "event" else math.nan)

    # -- measures --------------------------------------------------------------------------------

    def _arguments(self, t: Any, y: np.ndarray, p: np.ndarray) -> list[Any]:
        n = len(self.parameter_names)
        return [t, *(y[..., k] for k in range(y.shape[-1])), *p[:n].tolist()]

    def _measured(self, outcome: Outcome, y0: np.ndarray, p: np.ndarray, lyapunov: float | None = None) -> list[float]:
        import numpy as np

        values: list[float] = []
        failed = outcome.status == "failed"
        for m in self.measures:
            if m.kind == "final":
                values += [math.nan] * len(self.names) if failed else outcome.y_last.tolist()
            elif m.kind == "t_event":
                values.append(outcome.t_event)
            elif failed:
                values.append(math.nan)
            elif m.kind == "value":
                values.append(_scalar(self.vector[m.text](*self._arguments(np.float64(outcome.t_last), outcome.y_last, p))))
            elif m.kind in ("max", "min", "mean"):
                series = self._series(m.text, outcome, p)
                values.append(_reduce(m.kind, series))
            elif m.kind == "period":
                values.append(_period(outcome.t, self._series(m.text, outcome, p)))
            elif m.kind == "energy_error":
                energy = self._series("__energy", outcome, p)
                kinetic = self._series("__kinetic", outcome, p)
                scale = max(abs(float(energy[0])), 2 * float(np.max(np.abs(kinetic)))) if len(energy) else 0.0
                change = float(np.max(np.abs(energy - energy[0]))) if len(energy) else math.nan
                values.append(change / scale if scale > 0 else change)
            elif m.kind == "lyapunov":
                values.append(self._lyapunov(y0, p) if lyapunov is None else lyapunov)
        return values

    def _series(self, key: str, outcome: Outcome, p: np.ndarray) -> np.ndarray:
        import numpy as np

        value = self.vector[key](*self._arguments(outcome.t, outcome.y, p))
        return np.broadcast_to(np.asarray(value, dtype=float), outcome.t.shape)

    def _lyapunov(self, y0: np.ndarray, p: np.ndarray) -> float:
        """Benettin's method: a neighbour LYAPUNOV_SEPARATION away, renormalised every segment."""
        import numpy as np

        s = self.settings
        d0 = LYAPUNOV_SEPARATION * max(1.0, float(np.max(np.abs(y0))))
        direction = np.ones_like(y0) / math.sqrt(len(y0))
        a, b = y0.copy(), y0 + d0 * direction
        edges = np.linspace(s.t0, s.t_end, LYAPUNOV_SEGMENTS + 1)
        total = 0.0
        for t0, t1 in itertools.pairwise(edges.tolist()):
            ends = np.array([t1])
            first, second = self.integrate(a, p, t0, t1, ends), self.integrate(b, p, t0, t1, ends)
            if first.status != "finished" or second.status != "finished":
                return math.nan
            a, gap = first.y_last, second.y_last - first.y_last
            distance = float(np.linalg.norm(gap))
            if not (distance > 0 and math.isfinite(distance)):
                return math.nan
            total += math.log(distance / d0)
            b = a + gap * (d0 / distance)
        return total / (s.t_end - s.t0)

    def lyapunov_batch(self, y0s: np.ndarray, ps: np.ndarray) -> np.ndarray:
        """`_lyapunov` for every run of a batch at once (the compiled explicit path): each segment is
        one compiled call over the batch's trajectories and their neighbours (numeric/ensemble.py),
        not two calls from Python per run and segment; the same runs, so the same exponents."""
        import numpy as np

        from lagrange_cli.numeric import status as st

        s = self.settings
        count, n = y0s.shape
        d0 = LYAPUNOV_SEPARATION * np.maximum(1.0, np.max(np.abs(y0s), axis=1))
        direction = np.ones(n) / math.sqrt(n)
        a, b = y0s.copy(), y0s + d0[:, None] * direction
        pairs = np.vstack([ps, ps])
        total = np.zeros(count)
        alive = np.ones(count, dtype=bool)
        edges = np.linspace(s.t0, s.t_end, LYAPUNOV_SEGMENTS + 1)
        for t0, t1 in itertools.pairwise(edges.tolist()):
            codes, _, y_last, _, _ = self.batch_entry(self.pair, np.vstack([a, b]), pairs, self._control(t0, t1), np.array([t1]), self.budget, self.accel, self.event)
            alive &= (codes[:count] == st.DONE) & (codes[count:] == st.DONE)
            a, gap = y_last[:count].copy(), y_last[count:] - y_last[:count]
            b = a.copy()  # a dead run's pair is kept finite (its exponent is NaN anyway)
            for k in np.flatnonzero(alive).tolist():
                # row by row with `_lyapunov`'s own functions: np.linalg.norm(gap, axis=1) and np.log of an array
                # round differently in the last bit (another summation, SIMD logarithms), and chaos amplifies it
                distance = float(np.linalg.norm(gap[k]))
                if not (distance > 0 and math.isfinite(distance)):
                    alive[k] = False
                    continue
                total[k] += math.log(distance / d0[k])
                b[k] = a[k] + gap[k] * (d0[k] / distance)
        return np.where(alive, total / (s.t_end - s.t0), math.nan)

    def _section_rows(self, head: list[Any], outcome: Outcome, p: np.ndarray) -> list[list[Any]]:
        import numpy as np

        rows = []
        kept = 0
        for t, y in outcome.events:
            if all(_scalar(c(*self._arguments(np.float64(t), y, p))) > 0 for c in self.conditions):
                kept += 1
                rows.append([*head, outcome.status if outcome.status == "failed" else "finished", outcome.reason, kept, t, *y.tolist()])
        if outcome.status == "failed" or not rows:
            rows.append([*head, outcome.status if outcome.status == "failed" else "finished", outcome.reason or "no crossing", 0, math.nan, *([math.nan] * len(self.names))])
        return rows


@dataclass(frozen=True)
class Ended:
    """How a batch's runs ended, as arrays: the points' indices and values (`chunk`), and per run its status code,
    last time and last state (`Runner.ended`; `Runner.rows` makes the rows). A Dask task sends these back rather than
    rows: a few arrays pickle and travel at memory speed, where a list per row costs the client a Python object each."""

    indices: np.ndarray
    chunk: np.ndarray
    codes: np.ndarray
    t_last: np.ndarray
    y_last: np.ndarray

    def part(self, start: int, stop: int) -> Ended:
        """The runs start..stop-1 (views of the arrays)."""
        return Ended(self.indices[start:stop], self.chunk[start:stop], self.codes[start:stop], self.t_last[start:stop], self.y_last[start:stop])


@dataclass
class Outcome:
    """How one run ended: status (finished, event, failed), the reason of a failure, the last
    time and state, the samples, the crossings (sections) and the event time (NaN without one)."""

    status: str
    reason: str
    t_last: float
    y_last: np.ndarray
    t: np.ndarray
    y: np.ndarray
    events: list[tuple[float, np.ndarray]]
    t_event: float = math.nan

    @classmethod
    def failed(cls, runner: Runner, code: int, t: float, y: np.ndarray, ts: np.ndarray, ys: np.ndarray, events: list[tuple[float, np.ndarray]]) -> Outcome:
        from lagrange_cli.numeric import status as st
        from lagrange_cli.numeric.simulate import BUDGET_HINT, FAILURES, state_text
        from lagrange_cli.numeric.status import Status

        if code == st.BUDGET:
            reason = f"stopped after the step budget at t = {t:.6g}; {BUDGET_HINT}"
        else:
            reason = FAILURES.get(Status.of_code(code), f"status {code}").format(" (with the constraint rows)" if runner.model.constraints else "")
        return cls("failed", f"failed at t = {t:.6g}: {reason}; state: {state_text(runner.model, y)}", t, y, ts, ys, events)


def _reduce(kind: str, series: np.ndarray) -> float:
    import numpy as np

    if not len(series):
        return math.nan
    return float(np.max(series) if kind == "max" else np.min(series) if kind == "min" else np.mean(series))


def _scalar(value: Any) -> float:
    import numpy as np

    return float(np.asarray(value, dtype=float).reshape(-1)[0]) if np.size(value) else math.nan


def _period(t: np.ndarray, series: np.ndarray) -> float:
    """The mean interval between upward crossings of the series' mean, linearly interpolated."""
    import numpy as np

    if len(t) < 3:
        return math.nan
    centred = series - float(np.mean(series))
    up = np.nonzero((centred[:-1] < 0) & (centred[1:] >= 0))[0]
    if len(up) < 2:
        return math.nan
    times = t[up] + (t[up + 1] - t[up]) * (-centred[up]) / (centred[up + 1] - centred[up])
    return float((times[-1] - times[0]) / (len(times) - 1))


# -- the sweep -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Progress:
    done: int
    total: int


def sweep(
    model: Model,
    axes: Sequence[Axis],
    *,
    text: str | None = None,
    sample: int | None = None,
    seed: int = 0,
    measures: Sequence[str] = (),
    section: str | None = None,
    workers: int = 1,
    scheduler: str | None = None,
    batch: int = BATCH,
    done: Sequence[int] = (),
    on_batch: Callable[[list[list[Any]], int, int], None] | None = None,
    **options: Any,
) -> Table:
    """Run the sweep; `options` are `simulate`'s settings (t_end, method, rtol, atol, step,
    samples, parameters, initial, until, backend, max_step). `done` are point indices to skip
    (a resumed sweep); `on_batch(rows, done, total)` is called with each batch's rows in order.
    `text`: the file's text (read from model.source when None), for Dask workers."""
    check_axes(model, axes, sample)
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise LagrangeError(f"--workers must be a whole number of at least 1, got {workers!r}")
    if not isinstance(batch, int) or isinstance(batch, bool) or batch < 1:
        raise LagrangeError(f"batch must be a whole number of at least 1, got {batch!r}")
    if text is None and scheduler is not None:
        text = _source_text(model)
    job = Job(text or "", model.source, tuple(axes), tuple(measures), section, tuple(sorted(options.items())))
    runner = runner_for(job, model)
    grid = points(axes, sample, seed)
    skip = set(done)
    todo = [k for k in range(len(grid)) if k not in skip]
    batches = [todo[i : i + batch] for i in range(0, len(todo), batch)]
    table = Table(runner.columns)
    count = len(grid) - len(todo)

    def deliver(rows: list[list[Any]], size: int) -> None:
        nonlocal count
        count += size
        table.rows.extend(rows)
        if on_batch is not None:
            on_batch(rows, count, len(grid))

    with _heap_frozen():
        if scheduler is not None:
            for rows, size in _dask(scheduler, job, runner, grid, batches):
                deliver(rows, size)
        elif workers == 1:
            for rows, size in _local(None, runner, grid, batches, 1):
                deliver(rows, size)
        else:
            with ThreadPoolExecutor(workers) as pool:
                for rows, size in _local(pool, runner, grid, batches, workers):
                    deliver(rows, size)
    return table


_FROZEN = 0
"""Sweeps of this process running inside `_heap_frozen` (the heap was frozen by the first and is thawed by the last)."""
_FROZEN_LOCK = threading.Lock()


@contextlib.contextmanager
def _heap_frozen() -> Iterator[None]:
    """Python's garbage collector leaves the objects made before the sweep alone until it ends (`gc.freeze`, then
    `gc.unfreeze`). A sweep keeps a row per run, a list each, so every few 10^4 rows it triggers a full collection,
    which traverses the whole heap: in a process holding sympy, numba and Dask (about 2e5 objects) that is 0.1-0.15 CPU s
    with the GIL held (benchmarks/sweep_cluster_overhead.py counts them), stalling a Dask scheduler living in this process
    (a LocalCluster made here: its workers then wait for their next task) and the threads handing back results. Objects
    made during the sweep are collected as usual; garbage among the older ones waits for the first full collection after
    it. A heap frozen by someone else (`gc.get_freeze_count()`) is left as it is; concurrent sweeps freeze it once."""
    global _FROZEN
    with _FROZEN_LOCK:
        ours = _FROZEN > 0 or gc.get_freeze_count() == 0
        if ours:
            if _FROZEN == 0:
                gc.freeze()
            _FROZEN += 1
    try:
        yield
    finally:
        if ours:
            with _FROZEN_LOCK:
                _FROZEN -= 1
                if _FROZEN == 0:
                    gc.unfreeze()


def _source_text(model: Model) -> str:
    """The text of the file `model` came from (Dask workers derive it again from the text)."""
    from lagrange_cli import spec

    for path in (Path(model.source), spec.bundled_systems() / Path(model.source).name):
        if path.is_file():
            return path.read_text(encoding="utf-8")
    raise LagrangeError(f"{model.source}: cannot read the system file to send to the Dask workers; pass its text (text=...)")


def _local(pool: ThreadPoolExecutor | None, runner: Runner, grid: np.ndarray, batches: list[list[int]], workers: int) -> Iterator[tuple[list[list[Any]], int]]:
    """The batches as groups of consecutive batches (`_task_groups`, the Dask tasks' grouping: large first, single
    batches last, so that the threads finish within a batch of each other), each group in one compiled call where its
    measures allow (`_group_task`: the lanes refilled across its batches, fewer idle lanes at the end of each call), on
    this thread (`pool` None) or on the pool's threads (every group submitted at once, taken in order by whichever
    thread is free); rows delivered batch by batch, in order. (The last batches are no longer cut in pieces: counted
    on benchmarks/sweep_bench.py's sweep, pieces cost more idle lanes than they save at the end: sweep_parallel_cpu.py.)"""
    groups = _task_groups(batches, workers)
    if pool is None:
        for group in groups:
            yield from zip(_run_group(runner, grid, group), map(len, group), strict=True)
        return
    futures = [pool.submit(_run_group, runner, grid, group) for group in groups]
    for future, group in zip(futures, groups, strict=True):
        yield from zip(future.result(), map(len, group), strict=True)


def _run_group(runner: Runner, grid: np.ndarray, group: list[list[int]]) -> list[list[list[Any]]]:
    """The rows of each batch of `group` (consecutive batches), its runs in one compiled call where they can be (`_group_task`)."""
    import numpy as np

    indices = np.fromiter(itertools.chain.from_iterable(group), dtype=np.int64, count=sum(map(len, group)))
    return [rows for rows, _ in _group_rows(runner, _group_task(runner, indices, grid[indices], [len(b) for b in group]), group)]


_CLIENTS: dict[str, Any] = {}
"""A `distributed.Client` per scheduler address, kept for the next sweep of this process (connecting and closing
cost about 20-45 ms, against a sweep of 10^4 double-pendulum runs of about 0.5 s on two workers); closed at exit."""
_PREPARED: set[tuple[str, str, str]] = set()
"""(scheduler address, worker address, Job.key): a worker known to have built the runner of the job."""
_CLIENTS_LOCK = threading.Lock()


def _client(address: str) -> Any:
    """The kept client of `address`, or a new one (a client whose scheduler went away is replaced: connecting again
    then fails with a clean error)."""
    from distributed import Client

    with _CLIENTS_LOCK:
        client = _CLIENTS.get(address)
        if client is not None and client.status == "running":
            return client
        if client is not None:
            _forget(address)
        try:
            client = Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as error:
            raise LagrangeError(f"--scheduler {address}: cannot connect to a Dask scheduler ({error})") from None
        if not _CLIENTS:
            import atexit

            atexit.register(close_clients)
        _CLIENTS[address] = client
        return client


def _forget(address: str) -> None:
    """Drop (and close) the kept client of `address` (call with _CLIENTS_LOCK held)."""
    client = _CLIENTS.pop(address, None)
    for prepared in [p for p in _PREPARED if p[0] == address]:
        _PREPARED.discard(prepared)
    if client is not None:
        with contextlib.suppress(Exception):  # a client of a scheduler that is gone may fail to close: it is dropped anyway
            client.close(timeout=CONNECT_TIMEOUT)


def close_clients() -> None:
    """Close the Dask clients kept for later sweeps (at exit; or before their cluster is shut down)."""
    with _CLIENTS_LOCK:
        for address in list(_CLIENTS):
            _forget(address)


def _dask(address: str, job: Job, runner: Runner, grid: np.ndarray, batches: list[list[int]]) -> Iterator[tuple[list[list[Any]], int]]:
    """Batches as tasks of a `dask.distributed` cluster (lost workers' tasks are rerun by Dask), in order. A task sends
    back how its runs ended as arrays where it can (`Ended`), and `runner` (this process's) makes their rows."""
    import numpy as np

    try:
        import distributed  # noqa: F401
    except ImportError:
        raise LagrangeError("--scheduler needs dask.distributed: install it with `pip install 'dask[distributed]'`") from None
    from concurrent.futures import CancelledError

    client = _client(address)
    futures: list[Any] = []
    finished = False
    try:
        # The job (the file's text and settings, a few kB) goes with each task: no scatter, whose round trip to every
        # worker cost more than the copies. Every worker builds the system at the start, all at once, ahead of its
        # batches (priority): not at its first batch, which a short sweep (or the first sweep of a session) may never
        # send it, leaving the cost to the next sweep; a worker known to have built it (a kept client) is not asked again.
        workers = list(client.scheduler_info()["workers"])
        ready = [client.submit(_dask_prepare, job, workers=[worker], allow_other_workers=True, priority=1, pure=False) for worker in workers if (address, worker, job.key) not in _PREPARED]
        # A task's batches travel as two arrays (its points' indices and values, one after the other) and their sizes: Dask
        # walks every element of a list argument looking for futures, and pickles each array as frames of its own. All
        # the tasks go in one graph (`map`: one message to the scheduler, which hands every worker its first task at
        # once, and the job pickled once), run in the order given.
        groups = _task_groups(batches, len(workers))
        indices = [np.fromiter(itertools.chain.from_iterable(group), dtype=np.int64, count=sum(map(len, group))) for group in groups]
        futures = client.map(_dask_task, indices, [grid[ix] for ix in indices], [[len(b) for b in group] for group in groups], job=job, pure=False)
        for future, ix, group in zip(futures, indices, groups, strict=True):
            result = future.result()
            if isinstance(result, tuple):  # how the runs ended, without the points the task was sent
                result = Ended(ix, grid[ix], *result)
            yield from _group_rows(runner, result, group)
        if ready:  # every worker built (one that failed says so through its batches' results)
            _PREPARED.update((address, worker, job.key) for worker in client.gather(ready, errors="skip"))
        finished = True
    except (CancelledError, OSError, TimeoutError) as error:
        if client.status == "running" and not isinstance(error, CancelledError):
            raise  # a task's own error, not the connection's
        with _CLIENTS_LOCK:
            _forget(address)
        raise LagrangeError(f"--scheduler {address}: the Dask scheduler was lost during the sweep ({type(error).__name__}: {error}); run it again") from None
    finally:
        if not finished and futures and address in _CLIENTS and _CLIENTS[address] is client:
            with contextlib.suppress(Exception):  # an interrupted sweep's tasks stop (the kept client would hold them)
                client.cancel(futures, force=True)


def _dask_prepare(job: Job) -> str:
    """Build the job's runner on this worker: its address."""
    from distributed import get_worker

    runner_for(job)
    return str(get_worker().address)


def _task_groups(batches: list[list[int]], workers: int) -> list[list[list[int]]]:
    """Consecutive batches grouped into Dask tasks, large first and smaller towards the end (guided): each task takes
    1/(TASKS_PER_WORKER x workers) of the batches left, at least one and at most MAX_BATCHES_PER_TASK. Few tasks keep
    Dask's fixed cost per task small; small last tasks keep the workers finishing together (with equal tasks, one
    worker idled about half a task at the end while the other finished its last)."""
    groups, at = [], 0
    while at < len(batches):
        per = max(1, min(MAX_BATCHES_PER_TASK, math.ceil((len(batches) - at) / (TASKS_PER_WORKER * max(1, workers)))))
        groups.append(batches[at : at + per])
        at += per
    return groups


def _dask_task(indices: np.ndarray, chunk: np.ndarray, sizes: list[int], job: Job) -> tuple[np.ndarray, np.ndarray, np.ndarray] | list[list[list[Any]]]:
    """A Dask task: `_group_task` with this worker's runner of `job`; an `Ended` goes back as its status codes, last
    times and last states only (the client has the indices and points it sent: 24 bytes a run fewer with two axes)."""
    result = _group_task(runner_for(job), indices, chunk, sizes)
    if isinstance(result, Ended):
        return result.codes, result.t_last, result.y_last
    return result


def _group_task(runner: Runner, indices: np.ndarray, chunk: np.ndarray, sizes: list[int]) -> Ended | list[list[list[Any]]]:
    """How a group's runs ended: the points `chunk` (numbered `indices`), its batches of `sizes` one after the other.
    When every measure is read off a run's end on the compiled explicit path, all its runs in one compiled call and one
    `Ended` (the lanes are refilled across the batches: fewer idle lanes at the end of each batch's last runs, and one
    object to pickle and send, not five arrays a batch); otherwise the rows of each batch (`Runner.batch`)."""
    import numpy as np

    if runner.arrays:
        return runner._ended(indices.tolist(), chunk)
    bounds = np.cumsum([0, *sizes]).tolist()
    return [runner.batch(indices[a:b].tolist(), chunk[a:b]) for a, b in itertools.pairwise(bounds)]


def _group_rows(runner: Runner, result: Ended | list[list[list[Any]]], group: list[list[int]]) -> Iterator[tuple[list[list[Any]], int]]:
    """Each batch of `group`'s (rows, size) from `_group_task`'s result: an `Ended` cut into each batch's share, or the rows."""
    if isinstance(result, Ended):
        bounds = list(itertools.accumulate((len(b) for b in group), initial=0))
        for a, b in itertools.pairwise(bounds):
            yield runner.rows(result.part(a, b)), b - a
    else:
        yield from zip(result, map(len, group), strict=True)


# -- output and resume -----------------------------------------------------------------------------


def csv_line(row: Sequence[Any]) -> str:
    import csv
    import io

    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow([_cell(v) for v in row])
    return buffer.getvalue()


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ("nan" if math.isnan(value) else ("inf" if value > 0 else "-inf"))
    return str(value)


def identity(job: Job, sample: int | None, seed: int) -> str:
    """What makes two sweeps the same (the file's text, the axes, measures, settings, sample and
    seed): the first line of a journal, so that `--resume` never mixes two sweeps."""
    return f"# lagrange sweep {hashlib.sha256(f'{job.key} {sample} {seed}'.encode()).hexdigest()[:24]}"


def read_done(path: Path, columns: list[str], mark: str) -> tuple[set[int], int]:
    """The point indices already in a sweep's journal and the byte length of its complete lines;
    a journal of another sweep is an error."""
    import csv

    data = path.read_bytes()
    end = data.rfind(b"\n") + 1
    lines = data[:end].decode("utf-8", errors="replace").splitlines()
    if len(lines) < 2:
        return set(), 0
    if lines[0] != mark or next(csv.reader([lines[1]])) != columns:
        raise LagrangeError(f"--resume: {path} holds another sweep (other file, ranges, measures or settings); delete it, or run without --resume to start again")
    try:
        done = {int(row[0]) for row in csv.reader(lines[2:]) if row}
    except ValueError:
        raise LagrangeError(f"--resume: {path} is damaged (a row without its index); delete it, or run without --resume to start again") from None
    return done, end


def append_rows(path: Path, rows: list[list[Any]], header: list[str] | None = None, mark: str = "") -> None:
    """Append a batch's rows to `path` in one write (then fsync): a crash leaves whole batches and at most a cut last line, which `read_done` drops."""
    text = (f"{mark}\n" if mark else "") + (csv_line(header) if header else "") + "".join(csv_line(r) for r in rows)
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        os.write(fd, text.encode("utf-8"))
        os.fsync(fd)
    finally:
        os.close(fd)


def read_table(path: Path) -> Table:
    import csv

    with path.open(encoding="utf-8", newline="") as handle:
        reader = csv.reader(handle)
        columns = next(reader)
        if columns and columns[0].startswith("# lagrange sweep"):
            columns = next(reader)
        rows = [[_parse(v) for v in row] for row in reader if row]
    for row in rows:
        row[0] = int(row[0])
    return Table(columns, rows)


def _parse(text: str) -> Any:
    try:
        return float(text)
    except ValueError:
        return text


def sorted_table(table: Table) -> Table:
    """The rows in point order (a resumed sweep appends the rest after what was there)."""
    crossing = table.columns.index("crossing") if "crossing" in table.columns else None
    return Table(table.columns, sorted(table.rows, key=lambda r: (int(r[0]), r[crossing] if crossing is not None else 0)))


def write_parquet(table: Table, path: Path) -> None:
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise LagrangeError(f"{path}: Parquet needs pyarrow (`pip install pyarrow`); or write .csv") from None
    columns = {name: [row[k] for row in table.rows] for k, name in enumerate(table.columns)}
    pq.write_table(pa.table(columns), str(path))


def pyarrow_available() -> bool:
    import importlib.util

    return importlib.util.find_spec("pyarrow") is not None


# -- plots -----------------------------------------------------------------------------------------


def plot_column(table: Table, axes: Sequence[Axis], section: bool) -> str:
    """The column a plot shows: the first measure that is not a final state (else the first measure)."""
    start = table.columns.index("reason") + 1
    measured = table.columns[start:]
    if section:
        return ""
    chosen = [c for c in measured if not c.endswith("_final")]
    return (chosen or measured)[0]


def figure(table: Table, axes: Sequence[Axis], title: str, coordinates: Sequence[str] = (), surface: str = "", column: str | None = None) -> Any:
    """The picture that fits the sweep: a line over one axis, a heat map over a two-axis grid,
    a scatter of a Poincaré section's points (or of a sample's points, coloured by the measure)."""
    import numpy as np
    from matplotlib.figure import Figure

    from lagrange_cli.numeric.output import figure_title, inert, plot_text

    fig = Figure(figsize=(7, 5.2), layout="constrained")
    ax = fig.add_subplot()
    if "crossing" in table.columns:
        names = [c for c in coordinates if not re.search(rf"\b{re.escape(c)}\b", surface)] or list(coordinates)
        x_name, y_name = names[0], f"{names[0]}_dot"
        rows = [r for r in table.rows if r[table.columns.index("crossing")] > 0]
        xs = [r[table.columns.index(x_name)] for r in rows]
        ys = [r[table.columns.index(y_name)] for r in rows]
        colours = [r[0] for r in rows]
        points_ = ax.scatter(xs, ys, c=colours, s=2, cmap="viridis", linewidths=0)
        fig.colorbar(points_, ax=ax, label="run")
        ax.set_xlabel(x_name)
        ax.set_ylabel(y_name)
        inert(ax.xaxis.label, ax.yaxis.label)
        figure_title(fig, plot_text(f"{title}: Poincaré section {surface}"))
        return fig
    column = column or plot_column(table, axes, False)
    values = table.column(column)
    first = table.column(axes[0].column)
    if len(axes) == 1:
        ax.plot(first, values, ".-" if len(first) < 200 else ",", markersize=3)
        if axes[0].log:
            ax.set_xscale("log")
        ax.set_xlabel(axes[0].column)
        ax.set_ylabel(column)
    elif len(axes) == 2 and all(a.count is not None for a in axes):
        a, b = axes
        assert a.count is not None and b.count is not None
        grid = values.reshape(a.count, b.count)
        image = ax.pcolormesh(b.values(), a.values(), np.ma.masked_invalid(grid), shading="nearest", cmap="viridis")
        fig.colorbar(image, ax=ax, label=column)
        ax.set_xlabel(b.column)
        ax.set_ylabel(a.column)
        if a.log:
            ax.set_yscale("log")
        if b.log:
            ax.set_xscale("log")
    else:
        second = table.column(axes[1].column)
        spots = ax.scatter(second, first, c=values, s=8, cmap="viridis")
        fig.colorbar(spots, ax=ax, label=column)
        ax.set_xlabel(axes[1].column)
        ax.set_ylabel(axes[0].column)
    inert(ax.xaxis.label, ax.yaxis.label)
    figure_title(fig, plot_text(f"{title}: {column}"))
    return fig


def write_figure(fig: Any, path: Path) -> None:
    import matplotlib

    from lagrange_cli.files import atomic_write
    from lagrange_cli.numeric.output import plain_text

    matplotlib.use("Agg")
    with plain_text():
        atomic_write(path, lambda stream: fig.savefig(stream, format=path.suffix.lower().lstrip("."), dpi=120))
