"""The integrators behind `simulate`: compiled loops (kernels.py) and scipy's solvers, one result shape.

- `run_erk`: RK45 or DOP853 compiled with numba, the same steps as scipy's;
- `run_radau`: Radau IIA (order 5, the RADAU5 algorithm) compiled, for stiff problems;
- `run_gauss`: the symplectic Gauss-Legendre method in (q, p), compiled, fixed step;
- `run_scipy`: scipy.integrate's RK45, DOP853, Radau, BDF, LSODA stepped one step at a time
  (so that a failure keeps the trajectory so far, and events and samples use dense output),
  with the generated Python right-hand side and, for the implicit methods, its analytic Jacobian.

Each returns a `Run`: the samples reached, how it ended, and its counts and timings. Behind one
interface (scipy's `OdeSolver` as the anchor): a `Solver` is made once from the decided settings
(`ExplicitRK`, `RadauCompiled`, `Gauss`, `Scipy`) and `solver.run(problem, progress)` integrates a `Problem` (or a
stretch of one: the scipy backend's projection runs it stretch by stretch; the compiled one projects
inside its loop, `run_erk_projected` and `run_radau_projected`) to a `Run`, with the status enum
(`status.Status`) and named counters (`Stats`).
"""

from __future__ import annotations

import dataclasses
import math
import time
import types
import warnings
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from lagrange_cli.numeric import diagnostics, status, switching
from lagrange_cli.numeric.compile import Functions, kernel_entry, note_compiling
from lagrange_cli.numeric.status import Status
from lagrange_cli.numeric.tableaux import EXPLICIT

# How a run ended (the kernels' status codes map onto these by `Status.of_code`; BUDGET is the drivers' own).
FINISHED, EVENT, SINGULAR, NONFINITE, STEP_COLLAPSE, NO_CONVERGENCE, BUDGET = (
    Status.FINISHED,
    Status.EVENT,
    Status.SINGULAR,
    Status.NONFINITE,
    Status.STEP_COLLAPSE,
    Status.NO_CONVERGENCE,
    Status.BUDGET,
)
MAX_STEPS = {"python": 20_000, "compiled": 1_000_000}
"""Default step budget of one run, by backend: a scipy step costs about 0.1 ms (these many take
seconds), a compiled one about 1 us. A run that has not reached t_end after its budget stops
with status BUDGET; the budget counts steps, never seconds, so that no verdict depends on the
machine's load."""
PROGRESS_PERIOD = 0.1  # seconds between progress reports of a compiled run
Progress = Callable[[float], None]
"""Called now and then with the fraction of the time span done."""


@dataclass(frozen=True)
class Stats:
    """Work done: right-hand side and Jacobian evaluations, LU decompositions, steps, step sizes."""

    nfev: int
    njev: int
    nlu: int
    steps: int
    rejected: int | None
    min_step: float | None
    max_step: float | None
    floored: int = 0
    """Steps whose error test was held at the round-off floor (the compiled Radau method: a component's
    tolerance below what double precision resolves for it, kernels._radau_floor)."""


@dataclass(frozen=True)
class Run:
    """What an integrator produced: samples y(t) for the times reached, the last state, how it
    ended, and for a failure where the equations could not be evaluated, that evaluation."""

    t: np.ndarray
    y: np.ndarray
    status: Status
    t_last: float
    y_last: np.ndarray
    stats: Stats
    compile_seconds: float
    run_seconds: float
    problem: EvaluationError | None = None
    gauss: GaussReport | None = None
    """What the symplectic method's loop measured (None for the other methods)."""
    warnings: tuple[Uncontrolled, ...] = ()
    """Where the run's error was not controlled (see `monitor`)."""
    switching: tuple[int, int] | None = None
    """(switching surfaces, crossings landed on) of a run that located them (switching.py); None: not located."""


@dataclass(frozen=True)
class Uncontrolled:
    """A warning: the symplectic method's fixed step did not resolve the motion near time `t`
    (its error indicator, the predictor deviation, reached `ratio` times what the step was chosen
    for, or `ratio` x UNRESOLVED when the step was given), so the run's error is not controlled."""

    t: float
    ratio: float
    step: float
    chosen: bool
    """Whether the step came from the pilot (else it was given)."""

    @property
    def message(self) -> str:
        seen = f"{self.ratio:.3g}x the error indicator the step was chosen for" if self.chosen else f"an error indicator {self.ratio:.3g}x the level of an unresolved step"
        return (
            f"warning: the symplectic method's error is not controlled near t = {self.t:.6g} ({seen}): it keeps its fixed step {self.step:.3g} "
            "(that is what makes it symplectic) and cannot shorten it where the motion is fast (a coordinate singularity, a close approach); "
            "give a smaller --step, use an adaptive --method (DOP853, Radau), or change coordinates"
        )


@dataclass(frozen=True)
class GaussPilot:
    """The symplectic step chosen from short runs at h and h/2 (`pilot_gauss`)."""

    step: float
    estimate: float
    """The estimated error at t_end of a run at `step`, in units of the tolerance (<= 1: met),
    from Richardson's estimate over the pilot's span, grown linearly to t_end."""
    span: float
    """The time the pilot runs covered."""
    yardstick: float
    """The largest predictor deviation of the pilot runs divided by h^(s + 1): a run at step h
    expects deviations up to yardstick x h^(s + 1) (see `monitor`)."""
    steps: int
    """Steps the pilot runs took in all."""
    controlled: bool
    """False when the rounds ran out (or every trial failed, or the next trial would exceed the step
    budget) before the estimate met the tolerance."""
    stages: int = 2
    evaluations: float = 0.0
    """Right-hand side evaluations per step of the pilot's run at step/2 (its stage solves): what a
    step of the run is expected to cost, to compare stage counts (`policy.symplectic_pilot`)."""

    @property
    def cost(self) -> float:
        """Expected evaluations per unit time of a run at `step`."""
        return self.evaluations / self.step


@dataclass(frozen=True)
class GaussReport:
    """What a run of the Gauss method measured along the way (kernels.gauss_run's diagnostics).

    `deviation_max` is the largest difference between a step's converged stage increments and
    their extrapolation from the step before (relative to each component's size): an error
    indicator of order s + 1 in h that costs nothing. Where it jumps far above its mean (`deviation_mean`),
    the fixed step does not resolve the motion there (a coordinate singularity, a close approach)."""

    iterations_max: int
    """The most sweeps (fixed-point or Newton) one step took."""
    correction_max: float
    """The largest last correction of a step (relative): the round-off level the stages reached."""
    deviation_max: float
    deviation_t: float
    """The time of the step where `deviation_max` occurred."""
    deviation_mean: float
    fallbacks: int = 0
    """Steps whose fixed-point iteration failed and were solved again by Newton iteration (kernels.FIXED_SLOW)."""


@dataclass(frozen=True)
class Problem:
    """One initial value problem: y' = f(t, y), y(t0) = y0 on [t0, t_end], samples at ts, parameters p."""

    t0: float
    t_end: float
    y0: np.ndarray
    ts: np.ndarray
    p: np.ndarray
    use_event: bool
    max_steps: int = MAX_STEPS["python"]
    pace: Callable[[int, float], None] | None = None
    """Told (steps taken, share of the span done) each time a compiled loop returns to Python (at most every
    status.PAUSE_STEPS steps); it may raise to stop the run there (`runs._compiled_pace`)."""
    exact: bool = False
    """Stop a compiled loop at `max_steps` to the step (the budget a user gave `simulate`: --max-steps 5000 ran
    20001 steps); else it is checked where the loop pauses (every status.PAUSE_STEPS steps), as the reference's
    probes and the studies' runs count on: a probe's budget is at least one stretch of the loop."""


EVALUATIONS_PER_STEP = 20
"""Right-hand side evaluations a scipy step may take on average (DOP853: 12, Radau: a few Newton
iterations, plus rejected steps) before the run counts as over its budget."""


class EvaluationError(Exception):
    """A generated function could not be evaluated at (t, y) to finite real numbers: `cause`
    says why (a math domain error, a division by zero, an overflow, a complex or NaN value);
    `singular` is true where the generated `_solve` found the (augmented) mass matrix singular."""

    def __init__(self, what: str, t: float, y: Sequence[float], cause: str, singular: bool = False) -> None:
        super().__init__(f"{what} cannot be evaluated: {cause}")
        self.what, self.t, self.y, self.cause, self.singular = what, float(t), np.array(y, dtype=float), cause, singular


def evaluate(function: Callable[..., Any], t: float, y: Sequence[float], p: Sequence[float], what: str) -> list[float]:
    """function(t, y, p) (a generated `_energy`, `_accel`, ...) as finite floats, or `EvaluationError`.
    A scalar result comes back as a one-element list."""
    try:
        result = function(t, list(y), list(p))
        values = [float(v) for v in (result if isinstance(result, list | tuple | np.ndarray) else [result])]
    except (ArithmeticError, ValueError, TypeError) as error:  # domain errors, 1/0, overflow, complex -> float
        raise EvaluationError(what, t, y, cause(error), _singular(error)) from None
    bad = [v for v in values if not math.isfinite(v)]
    if bad:
        raise EvaluationError(what, t, y, f"the value is {bad[0]} (a division by zero, an overflow, or a function such as sqrt or log outside its domain)")
    return values


class _Elementwise:
    """A `math` function applied to each element of its (array) arguments: math's own function at each, so that
    its values are those of a call per sample, and a domain error raises as it does there."""

    def __init__(self, function: Callable[..., Any]) -> None:
        self.function = function
        self.ufuncs: dict[int, np.ufunc] = {}

    def __call__(self, *args: Any) -> np.ndarray:
        ufunc = self.ufuncs.get(len(args))
        if ufunc is None:
            ufunc = self.ufuncs[len(args)] = np.frompyfunc(self.function, len(args), 1)
        return np.asarray(ufunc(*args), dtype=float)


def _as_float(value: Any) -> np.ndarray:
    return np.asarray(value, dtype=float)


_ELEMENTWISE_TWINS: weakref.WeakKeyDictionary[Callable[..., Any], Callable[..., Any]] = weakref.WeakKeyDictionary()


def _elementwise(function: Callable[..., Any]) -> Callable[..., Any]:
    """`function` (generated, straight-line) with each `math` function it imports applied elementwise (`_Elementwise`)
    and `float` an array conversion: the same compiled code, run on a row of samples per state component at once."""
    twin = _ELEMENTWISE_TWINS.get(function)
    if twin is None:
        scope = dict(function.__globals__)
        scope.update({name: _Elementwise(getattr(math, name)) for name, value in scope.items() if callable(value) and value is getattr(math, name, None)})
        scope["float"] = _as_float
        twin = types.FunctionType(function.__code__, scope, function.__name__, function.__defaults__, function.__closure__)
        _ELEMENTWISE_TWINS[function] = twin
    return twin


def evaluate_samples(function: Callable[..., Any], t: np.ndarray, y: np.ndarray, p: Sequence[float]) -> np.ndarray | None:
    """function(t, y, p) (a generated `_energy`, `_momenta`, ...) at every sample (`t`: k times, `y`: k x states)
    at once, one row each, where every value comes out finite: 5 us a sample in `evaluate` was a fifth of `stress`'s
    time on Kepler's orbit (four values a sample for each of its 130 runs). None where it cannot be evaluated so: a
    branch on a value (a sign, a piecewise force), a table of work slots (long generated code), a domain error, a
    value that is not finite. The caller then evaluates the samples one at a time, which says where and why a value is bad. The values
    are those of one call per sample to the last bit or so: the arithmetic is IEEE's either way and each math function
    is math's, but numpy squares where Python's x**2 calls pow (1 ulp apart at times)."""
    k = len(t)
    try:
        with np.errstate(all="ignore"):
            result = _elementwise(function)(np.asarray(t, dtype=float), np.asarray(y, dtype=float).T, list(p))
            columns = result if isinstance(result, list | tuple) else [result]
            rows = np.stack([np.broadcast_to(np.asarray(c, dtype=float), (k,)) for c in columns], axis=1) if columns else np.empty((k, 0))
    except Exception:  # any failure of the twin: the samples one at a time, with the exact error
        return None
    return rows if rows.shape == (k, len(columns)) and bool(np.all(np.isfinite(rows))) else None


def _singular(error: BaseException) -> bool:
    """Whether a generated function's exception is its `_solve` meeting a singular matrix (the
    generated module raises ZeroDivisionError("singular matrix"), emit/python.py)."""
    return isinstance(error, ZeroDivisionError) and str(error) == "singular matrix"


def cause(error: BaseException) -> str:
    """What an exception raised by generated code means, in words."""
    text = str(error)
    if isinstance(error, ZeroDivisionError):
        return "a division by zero" + (" (a singular matrix)" if _singular(error) else "")
    if isinstance(error, OverflowError):
        return "an overflow (a value too large for floating point)"
    if isinstance(error, TypeError) and "complex" in text:
        return "a complex value (a fractional power or root of a negative number)"
    if isinstance(error, ValueError) and "domain" in text:
        return "a math domain error (a function such as sqrt, log, acos or a fractional power outside its domain)"
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


def _stats(raw: np.ndarray, nlu: int = 0) -> Stats:
    """The counters of a compiled loop (status.NFEV, ...) by name."""
    low, high = float(raw[status.HMIN]), float(raw[status.HMAX])
    return Stats(
        int(raw[status.NFEV]), int(raw[status.NJEV]), nlu, int(raw[status.NSTEPS]), int(raw[status.NREJECT]), low if math.isfinite(low) else None, high if high > 0 else None, int(raw[status.FLOORED])
    )


def _new_stats(smallest: float, largest: float) -> np.ndarray:
    """A compiled loop's counter array: no work done, the smallest and largest step so far."""
    stats = np.zeros(status.STATS_SIZE)
    stats[status.HMIN], stats[status.HMAX] = smallest, largest
    return stats


def _control(problem: Problem, size: int, rtol: float = 0.0, atol: float = 0.0, max_step: float = math.inf, step: float = 0.0, steps: int = 0) -> np.ndarray:
    """A compiled loop's controls (status.RTOL, ...), T_STOP set by each `advance`."""
    control = np.zeros(status.CONTROL_SIZE)
    control[status.RTOL], control[status.ATOL], control[status.MAX_STEP] = rtol, atol, max_step
    control[status.T_BOUND], control[status.T_STOP], control[status.USE_EVENT] = problem.t_end, problem.t_end, float(problem.use_event)
    control[status.SIZE], control[status.STEP], control[status.STEPS], control[status.T0] = size, step, steps, problem.t0
    return control


def _state(t: float, h: float, event_value: float) -> np.ndarray:
    """A compiled loop's state (status.T, H, EVENT_VALUE, NEXT_SAMPLE)."""
    state = np.zeros(status.STATE_SIZE)
    state[status.T], state[status.H], state[status.EVENT_VALUE] = t, h, event_value
    return state


def _drive(step: Callable[[float], int], now: Callable[[], float], taken: Callable[[], int], problem: Problem, progress: Progress | None, control: np.ndarray | None = None) -> int:
    """Call a compiled loop (`step(t_stop)` -> status, -1 while running: at t_stop or after
    status.PAUSE_STEPS steps) until it stops or has taken `problem.max_steps` steps (status.BUDGET),
    returning to Python about every PROGRESS_PERIOD seconds to report progress. For an `exact` problem the loop's
    `control[STRETCH]` (where it pauses) is set before each call to what is left of the budget (at most PAUSE_STEPS),
    so that it stops at its budget, not at the next pause past it."""
    span = problem.t_end - problem.t0
    pace = problem.pace

    def advance(t_stop: float) -> int:
        if control is not None and problem.exact:
            control[status.STRETCH] = float(max(1, min(status.PAUSE_STEPS, problem.max_steps - taken())))
        return step(t_stop)

    if progress is None:
        code = advance(problem.t_end)
        while code == status.RUNNING:  # paused after status.PAUSE_STEPS steps
            if taken() >= problem.max_steps:
                return status.BUDGET
            if pace is not None:
                pace(taken(), (now() - problem.t0) / span)
            code = advance(problem.t_end)
        return code
    target = max(problem.t0 + span / 100, float(np.nextafter(problem.t0, math.inf)))
    while True:
        began, t_before = time.perf_counter(), now()
        code = advance(min(target, problem.t_end))
        progress((now() - problem.t0) / span)
        if code != status.RUNNING:
            return code
        if pace is not None:
            pace(taken(), (now() - problem.t0) / span)
        if taken() >= problem.max_steps:
            return status.BUDGET
        speed = (now() - t_before) / max(time.perf_counter() - began, 1e-6)
        target = max(now() + max(span / 100, speed * PROGRESS_PERIOD), float(np.nextafter(now(), math.inf)))  # always ahead, even when span / 100 underflows


def _compile(functions: Functions, kernel: str, pieces: Sequence[tuple[str, Any]]) -> tuple[Any, list[Any], float]:
    """The kernel entry point and the system's functions compiled for their signatures (or loaded)."""
    start = time.perf_counter()
    kernels = functions.kernels
    assert kernels is not None
    entry = kernel_entry(kernels, kernel)  # (compiled ahead in a process of its own: `compile.warm_kernels`)
    compiled = []
    for name, signature in pieces:
        dispatcher = getattr(functions.module, name)
        dispatcher.compile(signature.args)
        compiled.append(dispatcher)
    seconds = time.perf_counter() - start
    note_compiling(seconds)
    return entry, compiled, seconds


def run_erk(functions: Functions, problem: Problem, method: str, rtol: float, atol: float, max_step: float, progress: Progress | None = None) -> Run:
    """The explicit pair `method` (RK45 or DOP853, see tableaux.EXPLICIT) compiled, with scipy's step-size control."""
    return ErkLoop(functions, problem, method, rtol, atol, max_step).finish(progress)


class ErkLoop:
    """A compiled run of an explicit pair that can pause and go on (`run_erk` runs one straight through).

    `advance(steps, stiffness=True)` runs one stretch of the kernel: to the end, an event or a failure, or
    until it pauses after `steps` steps or, with `stiffness`, once DOP853's stiffness
    test (kernels._stiffness_test, Hairer's) has found STIFF_STEPS steps limited by stability;
    `finish` then takes it to its end (the test off) and returns the `Run`, the same run as one
    made straight through (the same steps: pausing changes nothing in the loop)."""

    def __init__(self, functions: Functions, problem: Problem, method: str, rtol: float, atol: float, max_step: float, projection: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> None:
        """`projection` (bounds, holonomic, record): the loop projects onto the kept constraints (`run_erk_projected`)."""
        kernels = functions.kernels
        assert kernels is not None
        self.problem, self.pair, self.functions = problem, EXPLICIT[method].code, functions
        start_entry, _, compile_start = _compile(functions, "erk_start", [])
        pieces = [("_accel", kernels.ACCEL_SIG), ("_event", kernels.EVENT_SIG)]
        self.switches = switching.located(functions.module) if projection is None else 0
        """Switching functions whose crossings the loop lands on (kernels.erk_switched; 0: erk_run). The three entry
        points (erk_run, erk_switched, erk_projected) are one loop, kernels._erk_loop: the same steps where they overlap."""
        if projection is None and self.switches:
            self._entry, (self._accel, self._event, switch), compile_run = _compile(functions, "erk_switched", [*pieces, ("_switch", kernels.SWITCH_SIG)])
            self.record = kernels.switching_record(self.switches)
            g = np.empty(self.switches)
            switch(problem.t0, problem.y0, problem.p, g)
            self.record[kernels.SWITCH_HEAD : kernels.SWITCH_HEAD + self.switches] = g
            self._cases: tuple[Any, ...] = (switch, self.record)
            """The entry's arguments after `accel` and `event`: which case of the one explicit loop (kernels._erk_loop) it runs."""
        elif projection is None:
            self._entry, (self._accel, self._event), compile_run = _compile(functions, "erk_run", pieces)
            self._cases = ()
        else:
            self._entry, (self._accel, self._event, rows, energy), compile_run = _compile(functions, "erk_projected", [*pieces, ("_rows", kernels.ROWS_SIG), ("_energy", kernels.ENERGY_SIG)])
            self._cases = (rows, energy, *projection)
        self.compile_seconds = compile_start + compile_run
        began = time.perf_counter()
        self.y, self.f = problem.y0.copy(), np.empty_like(problem.y0)
        self.stats = _new_stats(math.inf, 0.0)
        self.ys = np.full((len(problem.ts), len(self.y)), np.nan)
        self.control = _control(problem, functions.module._SIZE, rtol=rtol, atol=atol, max_step=max_step)
        h0 = start_entry(self.pair, problem.t0, self.y, self.f, self.control, problem.p, self.stats, self._accel)
        self.state = _state(problem.t0, h0, _initial_event(functions, problem))
        self.code = status.SINGULAR if h0 < 0 else status.RUNNING
        """The last stretch's status code: RUNNING while paused."""
        self.seconds = time.perf_counter() - began

    @property
    def t(self) -> float:
        return float(self.state[status.T])

    @property
    def steps(self) -> int:
        return int(self.stats[status.NSTEPS])

    @property
    def attempts(self) -> int:
        """Steps tried, accepted and rejected."""
        return int(self.stats[status.NSTEPS] + self.stats[status.NREJECT])

    @property
    def ended(self) -> bool:
        """Whether it has stopped for good (finished, at its event, or failed): not paused."""
        return self.code != status.RUNNING

    @property
    def stiff(self) -> bool:
        """Whether the stiffness test has found the problem stiff (STIFF_STEPS steps limited by stability)."""
        return bool(self.stats[status.STIFF] >= status.STIFF_STEPS)

    def _advance(self, t_stop: float) -> int:
        began = time.perf_counter()
        self.control[status.T_STOP] = t_stop
        self.code = int(self._entry(self.pair, self.y, self.f, self.state, self.control, self.problem.ts, self.ys, self.problem.p, self.stats, self._accel, self._event, *self._cases))
        self.seconds += time.perf_counter() - began
        return self.code

    def advance(self, steps: int, stiffness: bool = False) -> int:
        """One stretch of at most `steps` steps (see the class docstring), and never past an `exact` problem's step
        budget; the status code (RUNNING: paused)."""
        steps = min(steps, self.problem.max_steps - self.steps) if self.problem.exact else steps
        if self.code == status.RUNNING and steps <= 0:
            self.code = status.BUDGET
        if self.code == status.RUNNING:
            self.control[status.STIFFNESS], self.control[status.STRETCH] = (1.0 if stiffness else 0.0), float(steps)
            self._advance(self.problem.t_end)
            self.control[status.STIFFNESS], self.control[status.STRETCH] = 0.0, 0.0
        return self.code

    def finish(self, progress: Progress | None = None) -> Run:
        """Go on to the end (or an event, a failure, the problem's step budget); the run."""
        if self.code == status.RUNNING and self.steps >= self.problem.max_steps:  # paused past the budget already
            self.code = status.BUDGET
        if self.code == status.RUNNING:
            self.code = _drive(self._advance, lambda: self.t, lambda: self.steps, self.problem, progress, self.control)
        m = int(self.state[status.NEXT_SAMPLE])
        kernels = self.functions.kernels
        switched = (self.switches, int(self.record[kernels.SWITCH_COUNT])) if self.switches and kernels is not None else None
        return Run(self.problem.ts[:m], self.ys[:m], Status.of_code(self.code), self.t, self.y, _stats(self.stats), self.compile_seconds, self.seconds, switching=switched)


def run_erk_projected(
    functions: Functions, problem: Problem, method: str, rtol: float, atol: float, max_step: float, bounds: np.ndarray, holonomic: np.ndarray, record: np.ndarray, progress: Progress | None = None
) -> Run:
    """`run_erk` with the state projected onto the kept constraints at the times `bounds` inside the
    compiled loop (kernels.erk_projected): one run, no restart at a projection. `holonomic` marks the
    holonomic rows (1.0), `record` is the projection record (status.LEVEL, ...: `projection.record`),
    which the loop fills with what it corrected and counted."""
    return ErkLoop(functions, problem, method, rtol, atol, max_step, (bounds, holonomic, record)).finish(progress)


def run_radau_projected(
    functions: Functions, problem: Problem, rtol: float, atol: float, max_step: float, bounds: np.ndarray, holonomic: np.ndarray, record: np.ndarray, progress: Progress | None = None
) -> Run:
    """`run_radau` with the state projected onto the kept constraints at the times `bounds` inside the
    compiled loop (kernels.radau_projected), as `run_erk_projected`: one run, the method restarting (J, LU,
    controller) at each projection inside it; `record` as there."""
    return run_radau(functions, problem, rtol, atol, max_step, progress, (bounds, holonomic, record))


def project_compiled(functions: Functions, t: float, y: np.ndarray, p: np.ndarray, holonomic: np.ndarray, record: np.ndarray) -> np.ndarray | None:
    """One state projected as the compiled loop projects it (kernels.project_state): the projected state,
    what it corrected in record[status.POSITION..ENERGY]; None where the projection cannot be applied."""
    kernels = functions.kernels
    assert kernels is not None
    entry, (rows, energy), _ = _compile(functions, "project_state", [("_rows", kernels.ROWS_SIG), ("_energy", kernels.ENERGY_SIG)])
    out = np.empty(len(y))
    failed = entry(float(t), np.array(y, dtype=float), np.array(p, dtype=float), holonomic, record, out, functions.module._SIZE, rows, energy)
    return None if failed else out


def run_gauss(functions: Functions, problem: Problem, z0: np.ndarray, stages: int, step: float, progress: Progress | None = None) -> Run:
    """The s-stage Gauss-Legendre method (order 2s) in z = (q, p) with a fixed step near `step`."""
    kernels = functions.kernels
    assert kernels is not None
    entry, (hamilton, event), compile_seconds = _compile(functions, "gauss_run", [("_hamilton", kernels.HAMILTON_SIG), ("_event", kernels.EVENT_SIG)])
    began = time.perf_counter()
    size = functions.module._SIZE
    ratio = (problem.t_end - problem.t0) / step
    steps = max(1, math.ceil(ratio - 1e-9)) if ratio < 2.0**62 else 2**62  # beyond any budget: the run stops at its budget
    h = (problem.t_end - problem.t0) / steps if ratio < 2.0**62 else step
    z = z0.copy()
    stats = _new_stats(h, h)
    ys = np.full((len(problem.ts), len(z)), np.nan)
    control = _control(problem, size, step=h, steps=steps)
    state = _state(problem.t0, 0.0, _initial_event(functions, problem))
    sizes = np.abs(z)
    memory, pivots = np.zeros(kernels.memory_size(stages, len(z))), np.zeros(stages * len(z), dtype=np.int64)  # carried across pauses (see kernels.gauss_run)

    def advance(t_stop: float) -> int:
        control[status.T_STOP] = t_stop
        return int(entry(stages, z, state, control, problem.ts, ys, problem.p, stats, sizes, memory, pivots, hamilton, event))

    code = _drive(advance, lambda: float(state[status.T]), lambda: int(state[status.H]), problem, progress)
    out, x, a = np.empty_like(z), np.empty(size), np.empty((size, size))
    hamilton(float(state[status.T]), z, problem.p, out, x, a)
    y_last = np.concatenate([z[: len(z) // 2], out[: len(z) // 2]])
    m = int(state[status.NEXT_SAMPLE])
    start = kernels.diagnostics_start(stages, len(z))
    report = memory[start : start + kernels.DIAGNOSTICS]
    counted = report[kernels.DEVIATION_STEPS]
    gauss = GaussReport(
        int(report[kernels.ITERATIONS_MAX]),
        float(report[kernels.CORRECTION_MAX]),
        float(report[kernels.DEVIATION_MAX]),
        float(report[kernels.DEVIATION_T]),
        float(report[kernels.DEVIATION_SUM] / counted) if counted else 0.0,
        int(report[kernels.FALLBACKS]),
    )
    stats_record = _stats(stats, nlu=int(stats[status.NJEV]))
    return Run(problem.ts[:m], ys[:m], Status.of_code(code), float(state[status.T]), y_last, stats_record, compile_seconds, time.perf_counter() - began, gauss=gauss)


def run_radau(
    functions: Functions, problem: Problem, rtol: float, atol: float, max_step: float = math.inf, progress: Progress | None = None, projection: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
) -> Run:
    """Radau IIA (3 stages, order 5) compiled (kernels.radau_run: the RADAU5 algorithm, scipy's step
    control), with the system's analytic Jacobian where `functions` has one (`compile.build(..., jacobian=True)`:
    codegen.jac_numba), else (or where its values are not finite) by forward differences of the compiled
    right-hand side. A system with switching functions (`_SWITCHES`, switching.py) runs
    kernels.radau_switched, which lands a step on each of their crossings (switching.LOCATE on).
    `projection` (bounds, holonomic, record): kernels.radau_projected, which projects onto the kept
    constraints inside its loop (`run_radau_projected`; no switching functions located, as run_erk_projected)."""
    kernels = functions.kernels
    assert kernels is not None
    start, _, compile_start = _compile(functions, "radau_start", [])
    pieces = [("_accel", kernels.ACCEL_SIG), ("_event", kernels.EVENT_SIG)]
    analytic = hasattr(functions.module, "_jac")
    if analytic:
        pieces.append(("_jac", kernels.JAC_SIG))
    switches = switching.located(functions.module) if projection is None else 0
    if switches:
        pieces.append(("_switch", kernels.SWITCH_SIG))
    if projection is not None:
        pieces += [("_rows", kernels.ROWS_SIG), ("_energy", kernels.ENERGY_SIG)]
    kernel = "radau_projected" if projection is not None else "radau_switched" if switches else "radau_run"
    entry, (accel, event, *given), compile_run = _compile(functions, kernel, pieces)
    jacobian = given[0] if analytic else kernels.compiled("no_jacobian")
    extra: tuple[Any, ...] = ()
    if projection is not None:
        extra = (given[-2], given[-1], *projection)
    elif switches:
        switch, record = given[-1], kernels.switching_record(switches, status.RADAU_QUICK_STEPS, status.RADAU_CHATTER)
        g = np.empty(switches)
        switch(problem.t0, problem.y0, problem.p, g)
        record[kernels.SWITCH_HEAD : kernels.SWITCH_HEAD + switches] = g
        extra = (switch, record)
    began = time.perf_counter()
    n = len(problem.y0)
    y, f = problem.y0.copy(), np.empty(n)
    stats = _new_stats(math.inf, 0.0)
    ys = np.full((len(problem.ts), n), np.nan)
    control = _control(problem, functions.module._SIZE, rtol=rtol, atol=atol, max_step=max_step)
    control[status.ANALYTIC] = float(analytic)
    jac, dense, y_old, memory = np.zeros((n, n)), np.zeros((3, n)), np.zeros(n), np.zeros(status.RADAU_SIZE)
    h0 = start(problem.t0, y, f, control, problem.p, stats, jac, memory, accel, jacobian)
    state = _state(problem.t0, h0, _initial_event(functions, problem))

    def advance(t_stop: float) -> int:
        control[status.T_STOP] = t_stop
        return int(entry(y, f, state, control, problem.ts, ys, problem.p, stats, jac, dense, y_old, memory, accel, event, jacobian, *extra))

    code = status.SINGULAR if h0 < 0 else _drive(advance, lambda: float(state[status.T]), lambda: int(stats[status.NSTEPS]), problem, progress, control)
    m = int(state[status.NEXT_SAMPLE])
    switched = (switches, int(extra[1][kernels.SWITCH_COUNT])) if switches else None
    return Run(
        problem.ts[:m], ys[:m], Status.of_code(code), float(state[status.T]), y, _stats(stats, nlu=int(stats[status.NLU])), compile_start + compile_run, time.perf_counter() - began, switching=switched
    )


PILOT_STEPS = 1000
"""A pilot spans at most this many steps of the first trial step (about 3 oscillations of the
fastest rate at the step `policy.symplectic_step` proposes), and at most the whole run."""
PILOT_ROUNDS = 4
"""Trial steps at most before the pilot settles for the last one."""
PILOT_SAMPLES = 50
"""Points where the runs at h and h/2 are compared."""
AIM = 0.5
"""The pilot aims the estimated error at t_end at this fraction of the tolerance."""
MONITOR_FACTOR = 30.0
"""A run warns where its predictor deviation exceeds this many times what the pilot saw at that step."""
UNRESOLVED = 1e-2
"""With a given step (no pilot), a predictor deviation of this much of a component's size means the
step does not resolve the motion there."""


def pilot_gauss(functions: Functions, problem: Problem, z0: np.ndarray, stages: int, h0: float, rtol: float, atol: float) -> GaussPilot:
    """Choose the symplectic method's fixed step from an error estimate: run it at h and h/2 over
    a short span (`PILOT_STEPS` steps of h0, at most the run), estimate the error of the run at h
    by Richardson's extrapolation (|y_h - y_h/2| 2^p / (2^p - 1), p = 2s, scaled by atol + rtol
    x the size of each component), let it grow linearly to t_end (the phase error of a symplectic
    method on a regular orbit) and take the step whose estimate is AIM x the tolerance; repeat
    from that step while it is much smaller (the first trial step was outside the asymptotic range)."""
    order = 2 * stages
    total = problem.t_end - problem.t0
    span = min(total, PILOT_STEPS * h0)
    ts = problem.t0 + span * np.arange(1, PILOT_SAMPLES + 1) / PILOT_SAMPLES
    ts[-1] = problem.t0 + span
    pilot = Problem(problem.t0, problem.t0 + span, problem.y0, ts, problem.p, False, problem.max_steps)
    h, taken, yardstick, estimate, per_step = h0, 0, 0.0, math.inf, 0.0
    for round_ in range(PILOT_ROUNDS):
        steps = max(2, math.ceil(span / h - 1e-9))
        if 3 * steps > problem.max_steps:  # the pilot alone would exceed the run's budget
            break
        coarse = run_gauss(functions, pilot, z0, stages, span / steps)
        fine = run_gauss(functions, pilot, z0, stages, span / (2 * steps))
        taken += coarse.stats.steps + fine.stats.steps
        per_step = fine.stats.nfev / fine.stats.steps if fine.stats.steps else 0.0
        h = span / steps
        if coarse.status.failed or fine.status.failed or len(coarse.t) < len(ts) or len(fine.t) < len(ts):
            h /= 4.0  # the trial step does not even converge over the span
            continue
        assert coarse.gauss is not None and fine.gauss is not None
        yardstick = max(coarse.gauss.deviation_max / h ** (stages + 1), fine.gauss.deviation_max / (h / 2) ** (stages + 1))
        scale = atol + rtol * np.max(np.abs(fine.y), axis=0)
        difference = float(np.max(np.abs(coarse.y - fine.y) / scale)) * 2.0**order / (2.0**order - 1.0)
        estimate = difference * total / span
        if estimate == 0.0:
            return GaussPilot(min(4.0 * h, span), 0.0, span, yardstick, taken, True, stages, per_step)
        proposed = h * min(4.0, max(0.1, (AIM / estimate) ** (1.0 / order)))
        if 0.5 * h <= proposed < 4.0 * h or (proposed >= 0.5 * h and round_ == PILOT_ROUNDS - 1):
            # the estimate at h is trustworthy enough to move from it (and the move is not capped,
            # or no round is left: a capped move, 4x, is tried again from there)
            return GaussPilot(proposed, estimate * (proposed / h) ** order, span, yardstick, taken, True, stages, per_step)
        h = proposed
    return GaussPilot(h, estimate, span, yardstick, taken, False, stages, per_step)


def monitor(run: Run, step: float, pilot: GaussPilot | None) -> Run:
    """`run` with a warning when its error indicator (the largest predictor deviation) went far
    beyond what the step was chosen for (MONITOR_FACTOR x the pilot's yardstick x h^(s + 1)), or,
    for a given step, beyond UNRESOLVED: the fixed step did not resolve the motion somewhere."""
    report = run.gauss
    if report is None:
        return run
    if pilot is not None and pilot.yardstick > 0.0:
        expected = pilot.yardstick * step ** (pilot.stages + 1)
        ratio = report.deviation_max / expected
        uncontrolled = ratio > MONITOR_FACTOR
    else:
        ratio = report.deviation_max / UNRESOLVED
        uncontrolled = ratio > 1.0
    if not uncontrolled:
        return run
    return dataclasses.replace(run, warnings=(*run.warnings, Uncontrolled(report.deviation_t, ratio, step, pilot is not None)))


def _initial_event(functions: Functions, problem: Problem) -> float:
    """The stop condition at the start (1 when there is none)."""
    if not problem.use_event:
        return 1.0
    kernels = functions.kernels
    assert kernels is not None
    size = functions.module._SIZE
    return float(functions.module._event(problem.t0, problem.y0, problem.p, np.empty(size), np.empty((size, size))))


# -- scipy --------------------------------------------------------------------------------------


class _Failure(Exception):
    """Raised from inside the right-hand side to stop a scipy solver with a reason."""

    def __init__(self, status: Status, problem: EvaluationError | None = None) -> None:
        super().__init__(status)
        self.status, self.problem = status, problem


class _Problems:
    """The last state where the right-hand side could not be evaluated (a solver that meets NaN
    rejects the step and retries a smaller one; when it gives up, this says why), and the
    evaluations left: a solver retrying without end inside one step (a NaN step size) stops too."""

    def __init__(self, evaluations: int = 20 * MAX_STEPS["python"]) -> None:
        self.last: EvaluationError | None = None
        self.evaluations = evaluations


def python_rhs(module: Any, p: Sequence[float], problems: _Problems | None = None) -> Callable[[float, np.ndarray], list[float]]:
    """f(t, y) from the generated Python `_accel`: `_Failure(SINGULAR)` at a singular matrix; NaN
    where it cannot be evaluated (a math domain error, division by zero, overflow, a complex
    value), which makes the solvers reject the step, the cause kept in `problems`."""
    accel, n, params = module._accel, module._N, list(p)

    def rhs(t: float, y: np.ndarray) -> list[float]:
        if problems is not None:
            problems.evaluations -= 1
            if problems.evaluations < 0:
                raise _Failure(BUDGET)
        if not math.isfinite(t):  # the step size became NaN after NaN values: scipy would retry forever
            raise _Failure(NONFINITE, problems.last if problems is not None else None)
        values = y.tolist()
        if not all(map(math.isfinite, values)):  # a stage built from NaN values: it only propagates them
            return [math.nan] * len(values)
        try:
            x = evaluate(accel, t, values, params, "the equations of motion")
        except EvaluationError as problem:
            if problem.singular:
                raise _Failure(SINGULAR) from None
            if problems is not None:
                problems.last = problem
            return [math.nan] * len(values)
        return values[n:] + x[:n]

    return rhs


def python_jac(module: Any, p: Sequence[float], problems: _Problems | None = None) -> Callable[[float, np.ndarray], np.ndarray]:
    """The analytic Jacobian df/dy from the generated Python `_jac`; where a formula of it cannot
    be evaluated although f can (0/0 in the derivative of |v| v at rest, say), forward differences
    of f instead. A singular augmented matrix is a failure."""
    jac, params, rhs = module._jac, list(p), python_rhs(module, p, problems)

    def finite_rhs(t: float, y: np.ndarray) -> np.ndarray | None:
        f = np.array(rhs(t, y))
        return f if np.all(np.isfinite(f)) else None

    def jacobian(t: float, y: np.ndarray) -> np.ndarray:
        try:
            found = np.asarray(jac(t, y.tolist(), params), dtype=float)
            if np.all(np.isfinite(found)):
                return found
        except np.linalg.LinAlgError:
            raise _Failure(SINGULAR) from None
        except (ArithmeticError, ValueError, TypeError):  # the formula fails here: differences of f instead
            pass
        differences = diagnostics.jacobian(finite_rhs, t, y)  # rhs raises _Failure at a singular matrix
        if differences is None:
            raise _Failure(NONFINITE, problems.last if problems is not None else None) from None
        return differences

    return jacobian


def run_scipy(functions: Functions, problem: Problem, method: str, rtol: float, atol: float, max_step: float, progress: Progress | None = None) -> Run:
    """One of scipy.integrate's solvers, stepped by hand: samples and the event from its dense output."""
    import scipy.integrate

    module, p = functions.module, problem.p.tolist()
    problems = _Problems(EVALUATIONS_PER_STEP * problem.max_steps + 1000)
    options: dict[str, Any] = {"rtol": rtol, "atol": atol, "max_step": max_step}
    if method in ("Radau", "BDF", "LSODA"):
        options["jac"] = python_jac(module, p, problems)
    began = time.perf_counter()
    solver_class = getattr(scipy.integrate, method)
    ts, steps = problem.ts, 0
    samples: list[np.ndarray] = []
    sizes: list[float] = []
    event = _python_event(module, p) if problem.use_event else None
    outcome, t_last, y_last = FINISHED, problem.t0, problem.y0.copy()
    failure: EvaluationError | None = None
    rhs = python_rhs(module, p, problems)
    switches = _Switches(module, p, rhs) if hasattr(module, "_switch") and switching.LOCATE else None
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        try:
            g_old = event(problem.t0, problem.y0) if event else 1.0
            solver = solver_class(rhs, problem.t0, problem.y0, problem.t_end, **options)
            if switches is not None:
                switches.start(problem.t0, problem.y0)
            while solver.status == "running":
                if steps >= problem.max_steps:
                    outcome = BUDGET
                    break
                t_old, y_old = solver.t, solver.y.copy()
                solver.step()
                if solver.status == "failed":  # scipy's only failures: TOO_SMALL_STEP, or LSODA's "unexpected istate" (its step also gave out)
                    outcome = STEP_COLLAPSE
                    break
                if not np.all(np.isfinite(solver.y)):
                    outcome, t_last, y_last = NONFINITE, t_old, y_old
                    break
                if switches is not None and switches.crossed(solver, t_old):  # discard the step: land on the crossing
                    switches.retire(solver)
                    solver = solver_class(rhs, t_old, y_old, switches.pending, **options)
                    continue
                steps += 1
                sizes.append(solver.t - t_old)
                t_end_here, outcome = _scipy_samples(solver, t_old, ts, samples, event, g_old)
                t_last, y_last = t_end_here, solver.y.copy() if outcome != EVENT else solver.dense_output()(t_end_here)
                if event:
                    g_old = event(solver.t, solver.y)
                if progress is not None:
                    progress((t_last - problem.t0) / (problem.t_end - problem.t0))
                if outcome == EVENT:
                    break
                if switches is not None and switches.crawling(t_old, solver.t, solver.y, problem.t_end - problem.t0):
                    outcome = Status.SURFACE_JUMP
                    break
                if switches is not None and switches.landed(solver) and solver.t < problem.t_end:  # restart there: no history, a fresh step
                    if switches.sliding:  # the field points into the surface from both sides: no classical solution goes on
                        outcome = Status.SURFACE_JUMP
                        break
                    switches.retire(solver)
                    solver = solver_class(rhs, solver.t, solver.y.copy(), problem.t_end, **options)
        except _Failure as stop:
            outcome, failure = stop.status, stop.problem
        except EvaluationError as problem_found:  # the stop condition
            outcome, failure = NONFINITE, problem_found
    if outcome in (NONFINITE, STEP_COLLAPSE) and failure is None and problems.last is not None and problems.last.t >= t_last:
        failure = problems.last  # the solver gave up where the equations cannot be evaluated
    nfev, njev, nlu = (int(getattr(solver, k, 0)) + (switches.work[k] if switches is not None else 0) for k in ("nfev", "njev", "nlu")) if "solver" in locals() else (0, 0, 0)
    stats = Stats(nfev, njev, nlu, steps, None, min(sizes[:-1]) if len(sizes) > 1 else (sizes[0] if sizes else None), max(sizes) if sizes else None)
    m = len(samples)
    y = np.array(samples) if samples else np.empty((0, len(problem.y0)))
    switched = (switches.count, switches.crossings) if switches is not None else None
    return Run(ts[:m], y, outcome, float(t_last), np.asarray(y_last, dtype=float), stats, 0.0, time.perf_counter() - began, failure, switching=switched)


CRAWL = 1e-9
"""A scipy step shorter than this fraction of the run's span, next to a switching surface, is tested for a sliding
mode (`_Switches.crawling`)."""


class _Switches:
    """The switching functions g(t, y) of a scipy run (the generated `_switch`, switching.py): a step
    over which one changes sign is discarded, the solver started again from the step's start to land
    on the crossing (located by brentq on the step's dense output), and there restarted afresh (a
    multistep method's history, which spans the kink, dropped; a new initial step)."""

    def __init__(self, module: Any, p: Sequence[float], rhs: Callable[[float, np.ndarray], Sequence[float]]) -> None:
        self.function, self.p, self.count, self.rhs = module._switch, list(p), int(module._SWITCHES), rhs
        self.g = np.zeros(self.count)
        self.pending, self.far, self.index, self.crossings = math.inf, np.zeros(self.count), -1, 0
        self.since, self.quick, self.last = 0, 0, -1
        """Accepted steps since the last landing, the landings in a row of one surface each at most status.QUICK_STEPS
        steps after the one before (`sliding`), and the surface landed on last."""
        self.work = {"nfev": 0, "njev": 0, "nlu": 0}
        """The counters of the solvers replaced so far."""

    def retire(self, solver: Any) -> None:
        for key in self.work:
            self.work[key] += int(getattr(solver, key, 0))

    def values(self, t: float, y: np.ndarray) -> np.ndarray:
        return np.array(evaluate(self.function, t, np.asarray(y).tolist(), self.p, "the switching functions"))

    def start(self, t: float, y: np.ndarray) -> None:
        self.g = self.values(t, y)

    def crossed(self, solver: Any, t_old: float) -> bool:
        """Whether the step t_old -> solver.t crosses a surface before its end (then `pending` is the crossing)."""
        g_new = self.values(solver.t, solver.y)
        changed = [i for i in range(self.count) if self.g[i] != 0.0 and (self.g[i] < 0.0) != (g_new[i] < 0.0)]
        if not changed:
            if solver.t != self.pending:
                self.g = g_new
                self.since += 1
            return False
        from scipy.optimize import brentq

        dense = solver.dense_output()
        g_start = self.values(t_old, dense(t_old))  # after a landing, self.g holds the far side's value
        changed = [i for i in changed if g_start[i] != 0.0 and (g_start[i] < 0.0) != (g_new[i] < 0.0)]  # else it touched the surface and turned back
        if not changed:
            self.g = g_new
            self.since += 1
            return False
        g_dense = self.values(solver.t, dense(solver.t))
        roots = []
        for i in changed:
            if g_dense[i] != 0.0 and (g_dense[i] < 0.0) == (g_start[i] < 0.0):
                # the dense output's end is not quite the step's end (LSODA, BDF): its sign did not change where y's did, so
                # there is no bracket on it: the crossing is at the step's end (brentq raised "f(a) and f(b) must have
                # different signs", an internal error of `stress` on the ball in the cup)
                roots.append((solver.t, i))
                continue
            root = brentq(lambda s, i=i: self.values(s, dense(s))[i], t_old, solver.t, xtol=4e-16 * max(abs(solver.t), 1.0), rtol=1e-15)
            roots.append((root, i))
        t_star, self.index = min(roots)
        self.far = g_new
        if t_old < t_star < solver.t:
            self.pending = t_star
            return True
        self.pending = solver.t  # the crossing is at the step's end: landed
        return False

    def landed(self, solver: Any) -> bool:
        """Whether the step ended on the located crossing: g set past it, the count increased, and whether the
        field points into that surface from both sides there (`attracted`)."""
        if solver.t != self.pending:
            return False
        g_here = self.values(solver.t, solver.y)
        self.attracted = self.attracting(solver.t, solver.y, self.index)
        self.g = np.where(np.arange(self.count) == self.index, self.far, g_here)
        self.crossings += 1
        self.quick = self.quick + 1 if self.since <= status.QUICK_STEPS and self.index == self.last else 1
        self.since, self.last = 0, self.index
        self.pending, self.index = math.inf, -1
        return True

    attracted = False
    """Whether the field pointed into the surface from both sides where the last landing was (`attracting`)."""

    @property
    def sliding(self) -> bool:
        """A sliding mode: at the last landing the field points into the surface from both sides (`attracting`),
        or the last status.CHATTER landings, all on one surface, each came at most status.QUICK_STEPS accepted steps
        after the one before, every restart crossing back at once (dry friction where a body sticks, audit 8 F1: 1302 landings
        in 2617 steps, to the step budget). The first catches a method that crawls along the surface instead
        (scipy's RK45 on a sticking block: one landing, then 19558 steps of 6e-11 to the budget)."""
        return self.attracted or self.quick >= status.CHATTER

    def crawling(self, t_old: float, t: float, y: np.ndarray, span: float) -> bool:
        """Whether an accepted step shorter than CRAWL x the run's span ends next to a surface whose field points
        into it from both sides (`attracting`): a method that crawls along a sliding surface in tiny steps without
        landing on it (scipy's RK45 on a sticking block, its stages straddling the surface). Only such tiny steps
        are tested, so that a run that takes ordinary steps pays nothing."""
        return t - t_old < CRAWL * span and any(self.attracting(t, y, i) for i in range(self.count))

    def attracting(self, t: float, y: np.ndarray, index: int) -> bool:
        """Filippov's condition for a sliding mode on surface `index` at (t, y), a point on it: the rate of g
        (grad g . f + dg/dt) is negative just on its positive side and positive just on its negative side, and f
        truly jumps across it. The sides are y moved along grad g (finite differences of the switching functions)
        to g = +s and g = -s, s a 1e-7 relative change of y; f jumps where the difference of the two rates is
        over 100 x the change of the rate from g = s to g = 2s on one side (a force that is continuous with a
        kink, such as a contact k max(0, e), changes by as much over each: so a grazing contact is never taken
        for a sliding mode). A few evaluations per landing."""
        y = np.asarray(y, dtype=float)
        g0 = float(self.values(t, y)[index])
        grad = np.zeros(len(y))
        for j in range(len(y)):
            h = 1.5e-8 * max(abs(y[j]), 1.0)
            moved = y.copy()
            moved[j] += h
            grad[j] = (float(self.values(t, moved)[index]) - g0) / h
        ht = 1.5e-8 * max(abs(t), 1.0)
        g_t = (float(self.values(t + ht, y)[index]) - g0) / ht
        norm2 = float(grad @ grad)
        if not (norm2 > 0.0 and math.isfinite(norm2) and math.isfinite(g_t)):
            return False
        s = 1e-7 * max(float(np.max(np.abs(y))), 1.0) * math.sqrt(norm2)
        if abs(g0) > 1e3 * s:  # not next to the surface
            return False

        def rate(level: float) -> float:
            return float(grad @ np.asarray(self.rhs(t, y + (level - g0) * grad / norm2), dtype=float)) + g_t

        above, below, further = rate(s), rate(-s), rate(2.0 * s)
        if not all(map(math.isfinite, (above, below, further))):
            return False
        return above < 0.0 < below and below - above > 100.0 * abs(further - above)


def _scipy_samples(solver: Any, t_old: float, ts: np.ndarray, samples: list[np.ndarray], event: Callable[[float, np.ndarray], float] | None, g_old: float) -> tuple[float, Status]:
    """Append the samples in (t_old, t] (or up to an event found in it); returns where the step ends."""
    dense = None
    t_new = solver.t
    outcome = FINISHED
    if event is not None:
        g_new = event(t_new, solver.y)
        if g_old != 0.0 and (g_old < 0.0) != (g_new < 0.0):
            from scipy.optimize import brentq

            dense = solver.dense_output()
            a, b = event(t_old, dense(t_old)), event(solver.t, dense(solver.t))
            if a == 0.0 or b == 0.0 or (a < 0.0) != (b < 0.0):
                t_new = brentq(lambda s: event(s, dense(s)), t_old, solver.t, xtol=4e-16 * max(abs(solver.t), 1.0), rtol=1e-15)
            # else the dense output's ends are not quite the steps' (LSODA, BDF) and bracket nothing: the event at the step's end
            outcome = EVENT
    j = len(samples)
    while j < len(ts) and ts[j] <= t_new:
        if dense is None:
            dense = solver.dense_output()
        samples.append(np.asarray(dense(ts[j]), dtype=float))
        j += 1
    return t_new, outcome


def _python_event(module: Any, p: Sequence[float]) -> Callable[[float, np.ndarray], float]:
    """The stop condition g(t, y); `EvaluationError` where it cannot be evaluated."""
    event, params = module._event, list(p)

    def g(t: float, y: np.ndarray) -> float:
        return evaluate(event, t, np.asarray(y).tolist(), params, "the stop condition (--until)")[0]

    return g


# -- one interface -------------------------------------------------------------------------------


class Solver(Protocol):
    """An integrator with its settings bound: `run` takes a problem to its end, an event, a failure or
    its step budget, and reports a `Run` (never raises for a failed run)."""

    @property
    def name(self) -> str: ...

    def run(self, problem: Problem, progress: Progress | None = None) -> Run: ...


@dataclass(frozen=True)
class ExplicitRK:
    """RK45 or DOP853 compiled (`run_erk`)."""

    functions: Functions
    method: str
    rtol: float
    atol: float
    max_step: float = math.inf

    @property
    def name(self) -> str:
        return f"{self.method} (compiled)"

    def run(self, problem: Problem, progress: Progress | None = None) -> Run:
        return run_erk(self.functions, problem, self.method, self.rtol, self.atol, self.max_step, progress)


@dataclass(frozen=True)
class RadauCompiled:
    """Radau IIA compiled (`run_radau`)."""

    functions: Functions
    rtol: float
    atol: float
    max_step: float = math.inf
    method: str = "Radau"

    @property
    def name(self) -> str:
        return "Radau (compiled)"

    def run(self, problem: Problem, progress: Progress | None = None) -> Run:
        return run_radau(self.functions, problem, self.rtol, self.atol, self.max_step, progress)


@dataclass(frozen=True)
class Gauss:
    """The symplectic Gauss-Legendre method (`run_gauss`), in (q, p): the momenta of each problem's
    start come from `python`'s canonical momenta; where they cannot be evaluated the run is
    NONFINITE at its start, with the cause."""

    functions: Functions
    python: Functions
    stages: int
    step: float

    @property
    def name(self) -> str:
        return "symplectic (compiled)"

    def run(self, problem: Problem, progress: Progress | None = None) -> Run:
        try:
            momenta = evaluate(self.python.module._canonical, problem.t0, problem.y0.tolist(), problem.p.tolist(), "the momenta at the initial state")
        except EvaluationError as found:
            empty = np.empty((0, len(problem.y0)))
            return Run(problem.ts[:0], empty, NONFINITE, problem.t0, problem.y0.copy(), Stats(0, 0, 0, 0, None, None, None), 0.0, 0.0, found)
        z0 = np.concatenate([problem.y0[: len(problem.y0) // 2], np.array(momenta, dtype=float)])
        return run_gauss(self.functions, problem, z0, self.stages, self.step, progress)


@dataclass(frozen=True)
class Scipy:
    """scipy.integrate's `method` on the generated Python functions (`run_scipy`)."""

    functions: Functions
    method: str
    rtol: float
    atol: float
    max_step: float = math.inf

    @property
    def name(self) -> str:
        return f"{self.method} (python)"

    def run(self, problem: Problem, progress: Progress | None = None) -> Run:
        return run_scipy(self.functions, problem, self.method, self.rtol, self.atol, self.max_step, progress)
