"""A work-precision study: how much accuracy each method buys per second on one system.

    result = study(model)                      # every method x a ladder of tolerances
    result.points                              # one row per run, failures included with their reason
    result.fastest                             # (accuracy level, fastest run reaching it)

The reference is the file's `exact:` solution when it has one for every coordinate (and the
initial state is the file's), otherwise a run at a tolerance 1000 times tighter than the
tightest of the ladder, confirmed by a second, different method; their largest disagreement
is the reference's own error. Before that, two reference runs started `delta` apart (delta =
the reference tolerance) tell whether the system is chaotic: when their separation grows by
more than 100 over the second half of the time it takes to reach 1e-3 (exponential, not the
linear drift of a regular motion), the growth rate is reported as a Lyapunov exponent and the
errors are measured only up to the predictability horizon of the tightest tolerance: where
runs started that tolerance apart would be 1e-3 apart (the reference pair 1e-3 x delta /
tightest apart). Beyond it even the tightest run's error is of the order of the motion itself.

Errors compare the samples at evenly spaced times (dense output) with the reference's. At a
time t the error is max_i |y_i - y_ref,i| / s_i, with s_i = max(1, max_t |y_ref,i|) the size of
component i (coordinates and velocities): an absolute error for quantities of order one, a
relative one for large ones. `final_error` is that at the last time, `rms_error` its root mean
square over the times, and `max_error` its maximum over the times: `Point.error`, what "meets" and
"fastest" judge by (an average or the final error understates the worst error along an
eccentric orbit about tenfold). `energy_error` is max_t |E - E_ref| divided by the larger of max_t |E_ref|
and the largest |sum p q_dot| of the run (twice its kinetic energy, for a natural system), so
that an energy near 0 still gives a relative error;
`constraint_drift` the largest residual of a kept constraint.

Timing: the first run is the warm-up (its one-time compile/load cost is reported apart); then,
once every point has run, up to `repeats` more runs of each (fewer when one run is slow) in turns,
point after point (`runs.interleave`), so that a load that comes and goes slows them all alike;
the minimum of the integration time (`Trajectory.timing.run`) is kept. Methods within TIE_MARGIN
(10%) of the fastest are reported as ties (`Study.ties`), not as slower.

Budgets count steps, never seconds, so that no verdict depends on the machine's load: a measured
run that has not reached t_end after `max_steps` steps (scipy steps; a compiled run, whose step
costs about 1/COMPILED_STEPS as much, gets COMPILED_STEPS times as many) is stopped and kept as
"over step budget"; reference runs get REFERENCE_STEPS times the budget. An optional time limit
(`time_limit` seconds) is only a safety net: a measured run it stops is "undecided", never failed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model
from lagrange_cli.numeric.reference import (
    CHAOS_GROWTH,
    HORIZON_THRESHOLD,
    Horizon,
    Reference,
    ReferenceFailed,
    ahead,
    computed_reference,
    exact_reference,
    horizon,
    implicit_first,
    prepare,
    reference_candidates,
    stable_steps,
)
from lagrange_cli.numeric.reports import COLUMNS, csv_text, json_text, plot_label, rows, run_backend, study_figure, write_plot
from lagrange_cli.numeric.runs import (
    ATOL_RATIO,
    COMPILED_STEPS,
    MAX_STEPS,
    OVER_BUDGET,
    REFERENCE_STEPS,
    STUDY_METHODS,
    TIE_MARGIN,
    TIGHTEST,
    UNDECIDED,
    Candidate,
    Point,
    PointStatus,
    Ran,
    Setup,
    backend_for,
    capped_steps,
    check_steps,
    component_scale,
    contenders,
    default_candidates,
    errors,
    interleave,
    measure,
    over_step_budget,
    parse_candidate,
    retime,
    run,
    scaled_errors,
    ties,
    tol_text,
    unrun,
    warm_study,
    work,
)
from lagrange_cli.numeric.settings import validate
from lagrange_cli.numeric.status import Failure

__all__ = [
    "ATOL_RATIO",
    "CHAOS_GROWTH",
    "COLUMNS",
    "COMPILED_STEPS",
    "HORIZON_THRESHOLD",
    "MAX_STEPS",
    "OVER_BUDGET",
    "REFERENCE_FACTOR",
    "REFERENCE_STEPS",
    "SAMPLES",
    "STUDY_METHODS",
    "TIE_MARGIN",
    "TIGHTEST",
    "TOLERANCES",
    "UNDECIDED",
    "Candidate",
    "Horizon",
    "Point",
    "PointStatus",
    "ProgressReport",
    "Ran",
    "Reference",
    "ReferenceFailed",
    "Setup",
    "Step",
    "Study",
    "backend_for",
    "check_steps",
    "component_scale",
    "computed_reference",
    "csv_text",
    "default_candidates",
    "errors",
    "exact_reference",
    "fastest",
    "horizon",
    "interleave",
    "json_text",
    "measure",
    "over_step_budget",
    "parse_candidate",
    "plot_label",
    "prepare",
    "reference_candidates",
    "retime",
    "rows",
    "run",
    "run_backend",
    "scaled_errors",
    "study",
    "study_figure",
    "ties",
    "tol_text",
    "write_plot",
]

TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
REFERENCE_FACTOR = 1e-3  # the reference runs at this times the tightest tolerance
SAMPLES = 2001
"""Evenly spaced times the errors are taken at (see stress.SAMPLES: 201 understated the largest error
along an eccentric Kepler orbit 1.6x, 2001 by 1-2%)."""


@dataclass(frozen=True)
class Study:
    title: str
    source: str
    t_end: float
    """The end of the measured window (the predictability horizon for a chaotic system)."""
    full_t_end: float
    reference: Reference
    horizon: Horizon | None
    points: tuple[Point, ...]
    notes: tuple[str, ...] = ()

    @property
    def fastest(self) -> tuple[tuple[float, Point], ...]:
        """For each decade of error reached by some run, the fastest run reaching it; only
        levels the reference can vouch for (at least 10x its own error): none when no second method
        confirmed it (`unconfirmed`)."""
        return () if self.unconfirmed else fastest(self.points, floor=10 * self.reference.own_error)

    @property
    def unconfirmed(self) -> bool:
        """The reference is one run that no second method confirmed (its own error unknown): the errors are measured
        against it, but it vouches for none of them. Audit 12: a pendulum whose angle is acos(c), its reference a Radau
        run that stepped through the singular c = 1 where every other method stopped, "met" 1e-5 with Radau itself."""
        return self.reference.kind == "computed" and math.isnan(self.reference.own_error)

    def ties(self, level: float, best: Point) -> tuple[Point, ...]:
        """Other methods reaching `level` within TIE_MARGIN of `best`'s run time: a tie, not a win."""
        return ties(self.points, best, level)


def fastest(points: Sequence[Point], floor: float = 0.0) -> tuple[tuple[float, Point], ...]:
    result = []
    for k in range(1, 15):
        level = 10.0**-k
        if level < floor:
            break
        reaching = [p for p in points if p.ok and p.error <= level]
        if reaching:
            quickest = min(reaching, key=lambda p: p.seconds)
            result.append((level, _least_work(reaching, quickest)))
    return tuple(result)


TIMING_NOISE = 2.5e-4
"""Seconds: two runs' times closer than this (plus TIE_MARGIN) cannot be told apart. A sub-millisecond run's
time is mostly what every run of it costs (its samples, the call), so of one method's runs the one with
the least work is taken within it: audit 4's bead on a turning parabola had compiled DOP853 at rtol 1e-7
(95 steps, 0.263 ms) "fastest" for every level from 0.1 down, beating its own runs at 1e-3 (32 steps,
0.391 ms) and 1e-5 (56 steps, 0.301 ms)."""


def _least_work(reaching: Sequence[Point], quickest: Point) -> Point:
    """Of the runs of `quickest`'s method and backend that reach the level within TIMING_NOISE (and
    TIE_MARGIN) of its time, the one with the least work (`runs.work`): more evaluations of the same
    method cannot be faster, and a timing that says so is noise."""
    limit = quickest.seconds * (1.0 + TIE_MARGIN) + TIMING_NOISE
    same = [p for p in reaching if p.method == quickest.method and p.ran == quickest.ran and p.seconds <= limit]
    return min(same, key=lambda p: (work(p), p.seconds))


@dataclass(frozen=True)
class Step:
    """Where a long computation stands, for a progress display: `done` of `total` units (runs of a
    study, regimes of a stress test) have finished. With `running` empty, unit `what` has just
    finished; otherwise unit `what` is under way and `running` says what it runs now."""

    done: int
    total: int
    what: str
    running: str = ""
    fraction: float | None = None
    """The share of the work done, where units differ in size (a long horizon weighs more); else done / total."""

    @property
    def share(self) -> float:
        return self.fraction if self.fraction is not None else self.done / self.total if self.total else 1.0


ProgressReport = Callable[[Step], None]
"""Told how far a study or stress test has come (the library never prints)."""


# -- the study ----------------------------------------------------------------------------------


STABILITY_MARGIN = 2.0
"""A capped compiled explicit run whose stability-limited steps (`reference.stable_steps`) exceed this times its
capped budget is not run: it would spend the cap to learn what the count says (as `stress.STABILITY_MARGIN`)."""
LOSING = 10.0
"""A run is stopped at this many times the work (right-hand side evaluations, `runs.work`) of the
cheapest finished run at the same tolerance: it is off the chart of error against time by a
decade, and the budget goes where a point is still open (scipy's Radau and BDF at rtol 1e-8 on a
stiff spring written in its length, round-off-limited, spent 30 s each of a 77 s study). Only for the
default candidates: the methods a user names (`--method`) each get the whole step budget."""


def _capped(model: Model, candidate: Candidate, tolerance: float, setup: Setup, reference: Reference, scale: np.ndarray, last: Point | None, cheapest: float, paced: bool = False) -> Point:
    """One point of the study, within LOSING x `cheapest`'s work; not run when the candidate's
    looser run (`last`) ran out of its budget already (a tighter tolerance takes more steps).
    `paced`: a Python run is stopped once its pace shows it cannot finish within its budget even
    when it is not capped (a run out of its budget is "over step budget" either way)."""
    if last is not None and last.failure == Failure.BUDGET:
        capped = last.status == PointStatus.CAPPED
        how = "was capped already, a tighter rtol costing more" if capped else "ran out of its budget already"
        # (a looser run's own "not run: at rtol ..." is passed on as it is: it names the rtol that was capped, audit 11, F5)
        reason = last.reason if last.reason.startswith("not run: at rtol") else f"not run: at rtol {tol_text(last.tolerance)} it {how} ({last.reason})"
        return unrun(candidate, tolerance, PointStatus.CAPPED if capped else PointStatus.OVER_BUDGET, reason, Failure.BUDGET)
    cap = capped_steps(candidate, LOSING * cheapest, last, setup)
    capped = cap < setup.steps  # then a losing run: stopped as soon as its pace shows it cannot finish (`runs.PACE_MARGIN`)
    needed = stable_steps(model, setup, candidate.method) if capped and backend_for(candidate) == "compiled" else 0.0
    if needed > STABILITY_MARGIN * cap * COMPILED_STEPS:
        reason = (
            f"not run: stiff, so its steps are stability-limited: about {needed:.3g} steps to t_end (the fastest decay along a pilot run x t_end / its stability"
            f" interval), above {STABILITY_MARGIN:g} x its budget of {LOSING:g} x the work of the cheapest run at rtol {tol_text(tolerance)} ({cap * COMPILED_STEPS} steps)"
        )
        return unrun(candidate, tolerance, PointStatus.CAPPED, reason, Failure.BUDGET)
    point = measure(model, candidate, tolerance, replace(setup, max_steps=cap) if capped else setup, reference, scale, repeats=0, paced=capped or paced)
    if capped and point.failure == Failure.BUDGET and point.steps and point.nfev:
        point = replace(point, status=PointStatus.CAPPED, reason=f"stopped after {point.steps} steps: {LOSING:g} x the work of the cheapest run at rtol {tol_text(tolerance)}")
    elif capped and point.failure == Failure.BUDGET:  # (also a fixed step whose count is over the cap: not run, `measure`)
        point = replace(point, status=PointStatus.CAPPED, reason=f"{point.reason}; its budget is {LOSING:g} x the work of the cheapest run at rtol {tol_text(tolerance)}")
    return point


def study(
    model: Model,
    *,
    candidates: Sequence[Candidate] | None = None,
    tolerances: Sequence[float] = TOLERANCES,
    t_end: float | None = None,
    parameters: Mapping[str, float] | None = None,
    initial: Mapping[str, float] | None = None,
    samples: int = SAMPLES,
    repeats: int = 3,
    max_steps: int = MAX_STEPS,
    time_limit: float | None = None,
    progress: ProgressReport | None = None,
) -> Study:
    """Every candidate at every tolerance against one reference; see the module docstring.
    `max_steps`: the step budget of a measured run; `time_limit`: seconds after which a measured
    run is stopped as undecided (None: none); `progress` is told as each run finishes."""
    if not tolerances:
        raise LagrangeError("give at least one tolerance")
    if any(not (math.isfinite(t) and 0 < t < 1) for t in tolerances):
        raise LagrangeError(f"tolerances must lie between 0 and 1, got {', '.join(f'{t:g}' for t in tolerances)}")
    if samples < 2:
        raise LagrangeError(f"samples must be at least 2, got {samples}")
    tolerances = sorted(set(tolerances), reverse=True)
    if min(tolerances) < 100 * TIGHTEST:
        raise LagrangeError(f"the tightest tolerance {min(tolerances):g} leaves no room for a reference 1000 times tighter; give tolerances of at least {100 * TIGHTEST:.1e}")
    model = model.with_definitions()  # the exact solution is evaluated here too
    chosen = tuple(candidates) if candidates else default_candidates(model)
    start = validate(model, method="DOP853", backend="python", t_end=t_end, parameters=parameters, initial=initial)
    full = start.t_end
    check_steps(max_steps)
    if time_limit is not None and not (math.isfinite(time_limit) and time_limit > 0):
        raise LagrangeError(f"the time limit must be a positive number of seconds, got {time_limit:g}")
    warm_study(model, chosen)
    setup = Setup(
        full, tuple(np.linspace(0.0, full, samples).tolist()), dict(parameters or {}), dict(initial or {}), max_steps, time_limit=time_limit, raised=max(1.0, max_steps / MAX_STEPS), start=start
    )
    ref_tol = max(min(tolerances) * REFERENCE_FACTOR, TIGHTEST)
    total = 1 + len(chosen) * len(tolerances)
    say = (lambda text: progress(Step(0, total, "reference", text))) if progress else None
    setup, reference, found, notes = prepare(model, setup, ref_tol, say, window=HORIZON_THRESHOLD * ref_tol / min(tolerances))
    if progress:
        progress(Step(1, total, "reference"))
    scale = component_scale(reference.y)
    found_points: dict[tuple[Candidate, float], Point] = {}
    cheapest: dict[float, float] = {}  # per tolerance, the least work of a finished run
    limited = implicit_first(model, setup)  # compiled explicit runs stability-limited to seconds each: scipy's implicit ones set the caps
    for candidate in sorted(chosen, key=lambda c: (limited and not ahead(c), backend_for(c) != "compiled", c.method != "LSODA")):  # cheap runs first (compiled, then LSODA): they set the caps
        last: Point | None = None
        for tolerance in tolerances:
            what = f"{candidate.label} {tol_text(tolerance)}"
            if progress:
                progress(Step(len(found_points) + 1, total, what, what))
            limit = cheapest.get(tolerance, math.inf) if not candidates else math.inf  # methods the user named are measured in full
            # the methods a user named get their whole budget; the default ones are stopped once their pace shows they cannot finish
            found_points[(candidate, tolerance)] = last = _capped(model, candidate, tolerance, setup, reference, scale, last, limit, paced=not candidates)
            if last.ok:
                cheapest[tolerance] = min(cheapest.get(tolerance, math.inf), work(last))
            if progress:
                progress(Step(len(found_points) + 1, total, what))
    points = [found_points[(c, t)] for c in chosen for t in tolerances]
    if repeats > 0:  # the run times, measured in turns so that a changing load slows every run alike
        if progress:
            progress(Step(total, total, "timing", "timing the runs in turns"))
        points = retime(model, points, setup, repeats, only=contenders(points))  # a dominated run keeps its first time
    return Study(model.title, model.source, setup.t_end, full, reference, found, tuple(points), notes)
