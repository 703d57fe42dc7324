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
square over the times. `energy_error` is max_t |E - E_ref| divided by the larger of max_t |E_ref|
and the largest |sum p q_dot| of the run (twice its kinetic energy, for a natural system), so
that an energy near 0 still gives a relative error;
`constraint_drift` the largest residual of a kept constraint.

Timing: the first run is the warm-up (its one-time compile/load cost is reported apart); then
the minimum of up to `repeats` more runs (fewer when one run is slow, see `_repeats`) of the
integration itself (`Trajectory.timing.run`).

Budgets count steps, never seconds, so that no verdict depends on the machine's load: a measured
run that has not reached t_end after `max_steps` steps (scipy steps; a compiled run, whose step
costs about 1/COMPILED_STEPS as much, gets COMPILED_STEPS times as many) is stopped and kept as
"over step budget"; reference runs get REFERENCE_STEPS times the budget. An optional time limit
(`time_limit` seconds) is only a safety net: a measured run it stops is "undecided", never failed.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model
from lagrange_cli.numeric import compile, integrators
from lagrange_cli.numeric.output import figure_title, inert, plain_text, plot_text
from lagrange_cli.numeric.settings import METHODS, initial_spectrum, resolve
from lagrange_cli.numeric.settings import _symplectic_step as symplectic_step
from lagrange_cli.numeric.simulate import Trajectory, simulate

if TYPE_CHECKING:
    from matplotlib.figure import Figure

STUDY_METHODS = tuple(m for m in METHODS if m != "auto")
TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
ATOL_RATIO = 1e-3  # atol = rtol x ATOL_RATIO
REFERENCE_FACTOR = 1e-3  # the reference runs at this times the tightest tolerance
TIGHTEST = 2.5e-14  # no run is asked for less (double precision)
SAMPLES = 201
HORIZON_THRESHOLD = 1e-3  # separation (scaled) at which nearby trajectories have parted
CHAOS_GROWTH = 100.0  # growth over the second half of the time to part, above which it is exponential


def tol_text(value: float) -> str:
    """A tolerance or accuracy as written: 1e-06, 2.5e-12."""
    text = f"{value:.1e}"
    return f"{value:.0e}" if text[1:3] == ".0" else text


@dataclass(frozen=True)
class Candidate:
    """A method and the backend it runs on ("auto" picks compiled for RK45/DOP853 when numba is there)."""

    method: str
    backend: str = "auto"

    @property
    def label(self) -> str:
        return self.method if self.backend == "auto" else f"{self.method}:{self.backend}"


def parse_candidate(text: str) -> Candidate:
    """`DOP853`, `RK45:python`, `auto`: a method, optionally with its backend."""
    name, _, backend = text.strip().partition(":")
    for known in METHODS:
        if name.lower() == known.lower():
            if backend and backend not in ("auto", "compiled", "python"):
                raise LagrangeError(f"--method {text!r}: unknown backend '{backend}'; write METHOD or METHOD:compiled or METHOD:python")
            return Candidate(known, backend or "auto")
    raise LagrangeError(f"unknown method '{name}'; choose from {', '.join(METHODS)} (optionally METHOD:python or METHOD:compiled)")


def default_candidates(model: Model) -> tuple[Candidate, ...]:
    """Every method of `simulate` that applies to the system."""
    methods = [m for m in STUDY_METHODS if not (m == "symplectic" and (model.constraints or not compile.numba_available()))]
    return tuple(Candidate(m) for m in methods)


def backend_for(candidate: Candidate) -> str:
    """The backend a candidate runs on: RK45/DOP853 compiled when numba is available."""
    if candidate.backend != "auto":
        return candidate.backend
    if candidate.method == "symplectic":  # compiled only (without numba: a hint naming the extra)
        return "compiled"
    if candidate.method in ("RK45", "DOP853"):
        return "compiled" if compile.numba_available() else "python"
    return "auto" if candidate.method == "auto" else "python"


@dataclass(frozen=True)
class Setup:
    """What every run of a study shares: the time window, sample times, parameters and initial values."""

    t_end: float
    times: tuple[float, ...]
    parameters: Mapping[str, float] = field(default_factory=dict)
    initial: Mapping[str, float] = field(default_factory=dict)
    max_steps: int = 0
    """Steps a measured run may take (scipy steps; compiled runs COMPILED_STEPS times as many); 0: MAX_STEPS."""
    reference_max_steps: int = 0
    """Steps each reference run may take (same units); 0: REFERENCE_STEPS x max_steps."""
    time_limit: float | None = None
    """Seconds after which a measured run is stopped as undecided (a safety net; None: no limit)."""

    @property
    def steps(self) -> int:
        return self.max_steps or MAX_STEPS

    @property
    def reference_steps(self) -> int:
        return self.reference_max_steps or REFERENCE_STEPS * self.steps


@dataclass(frozen=True)
class Point:
    """One run of the study."""

    method: str
    """As requested (`DOP853`, `RK45:python`, `auto`)."""
    resolved: str
    """What ran: the method and backend (`auto` resolved)."""
    tolerance: float
    """rtol of an adaptive method; for the symplectic method the rtol its step was chosen for."""
    step: float | None
    status: str
    """"finished", "failed", OVER_BUDGET ("over step budget"), UNDECIDED (stopped by the time limit) or "not applicable"."""
    reason: str
    final_error: float
    rms_error: float
    energy_error: float
    constraint_drift: float | None
    seconds: float
    runs: int
    compile_seconds: float
    nfev: int
    njev: int
    steps: int
    drifts: tuple[tuple[str, float], ...] = ()
    """Relative change of each conserved energy or momentum over the run."""

    @property
    def ok(self) -> bool:
        return self.status == "finished" and math.isfinite(self.error)

    @property
    def error(self) -> float:
        """The larger of the final and the RMS error."""
        return max(self.final_error, self.rms_error)

    @property
    def setting(self) -> str:
        return f"step {self.step:.3g}" if self.step is not None else f"rtol {tol_text(self.tolerance)}"


@dataclass(frozen=True)
class Reference:
    """The solution errors are measured against, at the study's times."""

    kind: str
    """"exact" or "computed"."""
    description: str
    own_error: float
    """The largest scaled disagreement of the two reference runs (0 for an exact solution; nan when unconfirmed)."""
    t: np.ndarray
    y: np.ndarray
    energy: np.ndarray
    seconds: float


@dataclass(frozen=True)
class Horizon:
    """How nearby trajectories separate: two reference runs started `delta` apart."""

    delta: float
    chaotic: bool
    lyapunov: float
    """ln(growth over the second half) / (half the time to part), 1/s; 0 when not chaotic."""
    horizon: float
    """When the separation reached HORIZON_THRESHOLD (inf when it never did)."""
    growth: float
    """The largest separation over delta."""
    t: np.ndarray = field(default_factory=lambda: np.zeros(0), compare=False, repr=False)
    separation: np.ndarray = field(default_factory=lambda: np.zeros(0), compare=False, repr=False)
    """The running maximum of the scaled separation at the times t."""

    def time_to(self, level: float) -> float:
        """When the separation first reached `level` (inf when it never did)."""
        reached = np.nonzero(self.separation >= level)[0]
        return float(self.t[reached[0]]) if len(reached) else math.inf


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
        levels the reference can vouch for (at least 10x its own error)."""
        return fastest(self.points, floor=10 * self.reference.own_error)


def fastest(points: Sequence[Point], floor: float = 0.0) -> tuple[tuple[float, Point], ...]:
    result = []
    for k in range(1, 15):
        level = 10.0**-k
        if level < floor:
            break
        reaching = [p for p in points if p.ok and p.error <= level]
        if reaching:
            result.append((level, min(reaching, key=lambda p: p.seconds)))
    return tuple(result)


class _TimeLimit(Exception):
    def __init__(self, fraction: float) -> None:
        super().__init__(fraction)
        self.fraction = fraction


Progress = Callable[[float], None]


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


MAX_STEPS = 200_000
"""The default step budget of one measured run of a study, in scipy steps (10-20 thousand a second
in Python on a small system, Radau about 5 thousand: some 10-40 s per run on a quiet machine, as
the old 20 s budget). Counted, never timed: the same run is over its budget on any machine under any load."""
COMPILED_STEPS = 100
"""A compiled run may take this many times the budget (a compiled step costs about 1 us)."""
REFERENCE_STEPS = 10
"""Reference runs (at tolerances 1000 x tighter, often over long windows) may take this many times the budget."""
OVER_BUDGET = "over step budget"
UNDECIDED = "undecided"
"""A measured run stopped by the time limit: it says nothing about the method."""


def _time_limit(seconds: float) -> Progress:
    start = time.perf_counter()

    def progress(fraction: float) -> None:
        if time.perf_counter() - start > seconds:
            raise _TimeLimit(fraction)

    return progress


def run_steps(model: Model, candidate: Candidate, tolerance: float, setup: Setup, budget: int) -> int:
    """The step budget of one run of `candidate`: `budget` scipy steps, COMPILED_STEPS x that compiled."""
    backend = backend_for(candidate)
    if backend == "auto":
        backend = resolve(model, method=candidate.method, rtol=tolerance, atol=tolerance * ATOL_RATIO, t_end=setup.t_end, parameters=setup.parameters, initial=setup.initial).backend
    return budget * COMPILED_STEPS if backend == "compiled" else budget


def run(model: Model, candidate: Candidate, tolerance: float, setup: Setup, *, step: float | None = None, timed: bool = True, reference: bool = False) -> Trajectory:
    """One simulate() call of the study, within its step budget (the reference's when `reference`)
    and, when `timed` and the setup has one, its time limit (raises _TimeLimit, LagrangeError)."""
    limit = setup.time_limit if timed and not reference else None
    return simulate(
        model,
        t_end=setup.t_end,
        method=candidate.method,
        rtol=tolerance,
        atol=tolerance * ATOL_RATIO,
        step=step,
        t_eval=setup.times,
        parameters=setup.parameters,
        initial=setup.initial,
        backend=backend_for(candidate),
        progress=_time_limit(limit) if limit is not None else None,
        max_steps=run_steps(model, candidate, tolerance, setup, setup.reference_steps if reference else setup.steps),
    )


def over_step_budget(trajectory: Trajectory) -> bool:
    """Whether a run was stopped by its step budget (simulate's BUDGET status)."""
    return trajectory.failed and "(the step budget)" in trajectory.message


def _repeats(first: float, repeats: int) -> int:
    """More timed runs after the warm-up: `repeats` when one run is short, fewer for slow runs
    (at most about 2 s of repeats per point), and at least one."""
    if first <= 0:
        return repeats
    return max(1, min(repeats, int(2.0 / first)))


def measure(model: Model, candidate: Candidate, tolerance: float, setup: Setup, reference: Reference, scale: np.ndarray, repeats: int = 3) -> Point:
    """Run one point (warm-up, then timed repeats) and compare it with the reference."""
    step = None
    if candidate.method == "symplectic":
        step = symplectic_step(_rate(model, setup), setup.t_end, tolerance)
    empty = Point(candidate.label, candidate.label, tolerance, step, "", "", math.nan, math.nan, math.nan, None, math.nan, 0, 0.0, 0, 0, 0)
    try:
        first = run(model, candidate, tolerance, setup, step=step)
    except _TimeLimit as over:
        return replace(empty, status=UNDECIDED, reason=f"stopped by the time limit ({setup.time_limit:g} s, --budget) at {100 * over.fraction:.0f}% of the time span")
    except LagrangeError as error:
        return replace(empty, status="not applicable", reason=str(error))
    s = first.settings
    resolved = f"{s.method} ({s.backend})"
    compiled = first.timing.compile + first.timing.load + first.timing.generate
    base = replace(
        empty,
        resolved=resolved,
        compile_seconds=compiled,
        nfev=first.stats.nfev,
        njev=first.stats.njev,
        steps=first.stats.steps,
        seconds=first.timing.run,
        runs=1,
        step=s.step if s.method == "symplectic" else None,
    )
    if over_step_budget(first):
        times = f" x {COMPILED_STEPS} for a compiled run" if first.settings.backend == "compiled" else ""
        done = (first.t_last - first.settings.t0) / (setup.t_end - first.settings.t0) if setup.t_end > first.settings.t0 else 0.0
        return replace(base, status=OVER_BUDGET, reason=f"stopped after {first.stats.steps} steps (the step budget, --max-steps {setup.steps}{times}) at {100 * done:.0f}% of the time span")
    if first.failed:
        return replace(base, status="failed", reason=first.message)
    final, rms, energy = errors(first, reference, scale)
    drifts = [inv.max_change for inv in first.invariants if inv.name.startswith("constraint ")]
    conserved = tuple((inv.name, inv.relative) for inv in first.invariants if inv.conserved and not inv.name.startswith("constraint "))
    seconds = [first.timing.run]
    if repeats > 0:
        for _ in range(_repeats(first.timing.run, repeats)):
            seconds.append(run(model, candidate, tolerance, setup, step=step, timed=False).timing.run)
        seconds = seconds[1:]
    return replace(
        base, status="finished", final_error=final, rms_error=rms, energy_error=energy, constraint_drift=max(drifts) if drifts else None, seconds=min(seconds), runs=len(seconds), drifts=conserved
    )


_RATES: dict[tuple[int, tuple[tuple[str, float], ...], tuple[tuple[str, float], ...]], float] = {}


def _rate(model: Model, setup: Setup) -> float:
    """The spectral radius at the initial state (what the symplectic step is chosen from)."""
    key = (id(model), tuple(sorted(setup.parameters.items())), tuple(sorted(setup.initial.items())))
    if key not in _RATES:
        s = resolve(model, method="DOP853", backend="python", parameters=setup.parameters, initial=setup.initial, t_end=setup.t_end)
        found = initial_spectrum(model, s.p[: len(model.parameters)], s.y0)
        _RATES[key] = found.rate if found is not None else 0.0
    return _RATES[key]


def scaled_errors(y: np.ndarray, reference: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """max_i |y_i - y_ref,i| / s_i at each sample."""
    return np.max(np.abs(y - reference) / scale, axis=1)


def errors(trajectory: Trajectory, reference: Reference, scale: np.ndarray) -> tuple[float, float, float]:
    """(final error, RMS error, relative energy error) of a finished run."""
    if len(trajectory.t) != len(reference.t) or not np.all(np.isfinite(trajectory.y)):
        return math.nan, math.nan, math.nan
    e = scaled_errors(trajectory.y, reference.y, scale)
    kinetic = next((i.scale for i in trajectory.invariants if i.name == "energy"), 0.0)  # the largest |sum p q_dot|
    size = max(float(np.max(np.abs(reference.energy))), kinetic, 1e-300)
    return float(e[-1]), float(np.sqrt(np.mean(e**2))), float(np.max(np.abs(trajectory.energy - reference.energy)) / size)


def component_scale(y: np.ndarray) -> np.ndarray:
    return np.maximum(1.0, np.max(np.abs(y), axis=0))


# -- the reference ------------------------------------------------------------------------------


def exact_reference(model: Model, setup: Setup) -> Reference | None:
    """The file's exact solution at the study's times, when it covers every coordinate and the
    initial state is the file's own (None otherwise)."""
    import sympy as sp

    if setup.initial or set(model.exact) != set(model.coordinates):
        return None
    s = resolve(model, method="DOP853", backend="python", parameters=setup.parameters, t_end=setup.t_end)
    values = {p.symbol: v for p, v in zip(model.parameters, s.p, strict=False)}
    t = sp.Symbol("t")
    exprs = [sp.sympify(model.exact[c]).subs(values) for c in model.coordinates]
    exprs += [sp.diff(e, t) for e in exprs[: model.n]]
    evaluate = sp.lambdify(t, exprs, modules="math")
    times = np.array(setup.times)
    module = compile.build(model, "python").module
    try:  # the exact solution and the energy at every time, or no exact reference where they cannot be evaluated
        y = np.array([integrators.evaluate(lambda ti, _y, _p: evaluate(ti), ti, [], [], "the exact solution") for ti in times.tolist()])
        if np.max(np.abs(y[0] - np.array(s.y0))) > 1e-9 * max(1.0, float(np.max(np.abs(y[0])))):
            return None
        energy = np.array([integrators.evaluate(module._energy, ti, yi.tolist(), list(s.p), "the energy")[0] for ti, yi in zip(times.tolist(), y, strict=True)])
    except integrators.EvaluationError:
        return None
    return Reference("exact", "the file's exact solution", 0.0, times, y, energy, 0.0)


def reference_candidates(model: Model, setup: Setup, tolerance: float) -> tuple[Candidate, Candidate]:
    """The primary reference method and a different second one: compiled DOP853 confirmed by
    compiled RK45 when numba is there (fast even when stiff: stability only costs steps);
    otherwise what `auto` picks (Radau when stiff, else DOP853) confirmed by LSODA, whose
    high-order Adams and BDF formulas stay affordable at tight tolerances where scipy's Radau
    and RK45, stepping in Python, do not."""
    if compile.numba_available():
        return Candidate("DOP853", "compiled"), Candidate("RK45", "compiled")
    s = resolve(model, method="auto", rtol=tolerance, parameters=setup.parameters, initial=setup.initial, t_end=setup.t_end)
    return Candidate(s.method), Candidate("LSODA")


def computed_reference(model: Model, setup: Setup, tolerance: float) -> Reference:
    """The primary reference run confirmed by the second; raises LagrangeError if the primary fails."""
    primary, second = reference_candidates(model, setup, tolerance)
    began = time.perf_counter()
    main = run(model, primary, tolerance, setup, reference=True)
    if over_step_budget(main):
        raise LagrangeError(
            f"{model.source}: the reference run ({primary.method}, rtol {tol_text(tolerance)}) did not reach t = {setup.t_end:g} within {main.stats.steps} steps"
            f" (the step budget of reference runs, {REFERENCE_STEPS} x --max-steps); give a shorter --t-end, looser --tolerances or a larger --max-steps"
        )
    if main.failed:
        raise LagrangeError(f"{model.source}: the reference run ({primary.method}, rtol {tol_text(tolerance)}) failed: {main.message}")
    seconds = time.perf_counter() - began
    scale = component_scale(main.y)
    own, confirm = math.nan, f"unconfirmed: {second.method} at the same tolerance did not finish"
    other = run(model, second, tolerance, setup, reference=True)
    if not other.failed and len(other.t) == len(main.t):
        own = float(np.max(scaled_errors(other.y, main.y, scale)))
        confirm = f"confirmed by {other.settings.method} ({other.settings.backend})"
    description = f"{main.settings.method} ({main.settings.backend}) at rtol {tol_text(tolerance)}, atol {tol_text(tolerance * ATOL_RATIO)}, {confirm}"
    return Reference("computed", description, own, main.t, main.y, main.energy, seconds)


def horizon(model: Model, setup: Setup, tolerance: float) -> Horizon | None:
    """Two primary reference runs started delta = tolerance apart (every component moved by
    delta times its size): whether they part exponentially, and when."""
    primary, _ = reference_candidates(model, setup, tolerance)
    base = run(model, primary, tolerance, setup, reference=True)
    if base.failed:
        return None
    s = base.settings
    names = [*model.coordinates, *(f"{c}_dot" for c in model.coordinates)]
    moved = {n: v + tolerance * max(1.0, abs(v)) for n, v in zip(names, s.y0, strict=True)}
    if model.constraints:
        return None  # moving the state would violate the constraints
    other = run(model, primary, tolerance, replace(setup, initial=moved), reference=True)
    if other.failed or len(other.t) != len(base.t):
        return None
    separation = np.maximum.accumulate(scaled_errors(other.y, base.y, component_scale(base.y)))
    t = base.t
    parted = np.nonzero(separation >= HORIZON_THRESHOLD)[0]
    end = int(parted[0]) if len(parted) else len(t) - 1
    half = int(np.searchsorted(t, t[end] / 2))
    growth_half = separation[end] / max(separation[half], 1e-300)
    chaotic = t[end] > 0 and growth_half > CHAOS_GROWTH
    lyapunov = math.log(growth_half) / (t[end] / 2) if chaotic else 0.0
    return Horizon(tolerance, bool(chaotic), lyapunov, float(t[end]) if len(parted) else math.inf, float(separation[-1] / tolerance), t, separation)


# -- the study ----------------------------------------------------------------------------------


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
    settings = resolve(model, method="DOP853", backend="python", t_end=t_end, parameters=parameters, initial=initial)
    full = settings.t_end
    check_steps(max_steps)
    if time_limit is not None and not (math.isfinite(time_limit) and time_limit > 0):
        raise LagrangeError(f"the time limit must be a positive number of seconds, got {time_limit:g}")
    setup = Setup(full, tuple(np.linspace(0.0, full, samples).tolist()), dict(parameters or {}), dict(initial or {}), max_steps, time_limit=time_limit)
    ref_tol = max(min(tolerances) * REFERENCE_FACTOR, TIGHTEST)
    total = 1 + len(chosen) * len(tolerances)
    say = (lambda text: progress(Step(0, total, "reference", text))) if progress else None
    setup, reference, found, notes = prepare(model, setup, ref_tol, say, window=HORIZON_THRESHOLD * ref_tol / min(tolerances))
    if progress:
        progress(Step(1, total, "reference"))
    scale = component_scale(reference.y)
    points: list[Point] = []
    for candidate in chosen:
        for tolerance in tolerances:
            what = f"{candidate.label} {tol_text(tolerance)}"
            if progress:
                progress(Step(len(points) + 1, total, what, what))
            points.append(measure(model, candidate, tolerance, setup, reference, scale, repeats))
            if progress:
                progress(Step(len(points) + 1, total, what))
    return Study(model.title, model.source, setup.t_end, full, reference, found, tuple(points), notes)


def check_steps(max_steps: object) -> int:
    """A step budget: a whole number of at least 1 (LagrangeError otherwise)."""
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
        raise LagrangeError(f"the step budget (--max-steps) must be a whole number of at least 1, got {max_steps!r}")
    return max_steps


def prepare(model: Model, setup: Setup, ref_tol: float, progress: Callable[[str], None] | None = None, window: float = HORIZON_THRESHOLD) -> tuple[Setup, Reference, Horizon | None, tuple[str, ...]]:
    """The reference (exact, or computed at `ref_tol` and confirmed), and the window: when nearby
    trajectories part exponentially, cut to where runs started `ref_tol` apart are `window` apart
    (at most HORIZON_THRESHOLD): the predictability horizon of the runs to be measured."""
    notes: list[str] = []
    reference = exact_reference(model, setup)
    found: Horizon | None = None
    if reference is None:
        if model.exact:
            notes.append("the file's exact solution was not used (it does not cover every coordinate, or the initial state was changed)")
        if progress:
            progress("reference")
        found = horizon(model, replace(setup, times=tuple(np.linspace(0.0, setup.t_end, 4 * len(setup.times)).tolist())), ref_tol)
        end = min(found.time_to(window), found.horizon) if found is not None and found.chaotic else math.inf
        if 0 < end < setup.t_end:
            assert found is not None
            setup = replace(setup, t_end=end, times=tuple(np.linspace(0.0, end, len(setup.times)).tolist()))
            notes.append(
                f"chaotic: nearby trajectories part at about {found.lyapunov:.2g}/s; errors are measured up to t = {end:.3g}, where runs started {tol_text(ref_tol)} apart are {window:.0e} apart"
            )
        reference = computed_reference(model, setup, ref_tol)
    return setup, reference, found, tuple(notes)


# -- output -------------------------------------------------------------------------------------

COLUMNS = ("method", "ran", "setting", "status", "final_error", "rms_error", "energy_error", "constraint_drift", "seconds", "runs", "compile_seconds", "nfev", "njev", "steps", "reason")


def rows(result: Study) -> list[dict[str, object]]:
    """One plain dict per point (for CSV and JSON)."""
    out = []
    for p in result.points:
        out.append(
            {
                "method": p.method,
                "ran": p.resolved,
                "setting": p.setting,
                "status": p.status,
                "final_error": p.final_error,
                "rms_error": p.rms_error,
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

    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows(result):
        writer.writerow({k: ("" if v is None else repr(v) if isinstance(v, float) else v) for k, v in row.items()})
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
        "fastest": [{"error": level, "method": p.method, "setting": p.setting, "seconds": p.seconds, "error_reached": p.error} for level, p in result.fastest],
        "notes": list(result.notes),
    }
    return json.dumps(document, indent=2, allow_nan=False) + "\n"


BACKEND_STYLES = {"compiled": ("-", "o", "full"), "python": ("--", "s", "none")}
"""Line style, marker and marker fill of each backend, so that a method's compiled and pure-Python runs differ at a glance."""
BACKEND_NAMES = {"compiled": "compiled (numba)", "python": "pure Python (scipy)"}


def run_backend(point: Point) -> str:
    """The backend a point ran on, "compiled" or "python" ("" when neither is named)."""
    for text in (point.resolved, point.method):
        found = re.search(r"\b(compiled|python)\b", text)
        if found:
            return found.group(1)
    return ""


def plot_label(point: Point) -> str:
    """`DOP853 (compiled)`, `RK45 (python)`; `auto -> DOP853 (compiled)` when the request named another method."""
    ran = re.split(r"[\s:(]", point.resolved.strip(), maxsplit=1)[0] or point.method
    backend = run_backend(point)
    label = f"{ran} ({backend})" if backend else ran
    requested = point.method.split(":")[0]
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
        colour = colours.setdefault(label.split(" ")[0], cycle[len(colours) % len(cycle)])
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
        axes.set_ylabel("error (larger of final and RMS, scaled)")
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
