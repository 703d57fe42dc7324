"""`simulate(model, ...) -> Trajectory`: a system's motion from its initial state, and how far to trust it.

    trajectory = simulate(model, t_end=10, method="DOP853", rtol=1e-10)
    trajectory.t, trajectory.y          # samples; y = [q..., q_dot...]
    trajectory.invariants               # energy, ignorable momenta, constraint residuals
    trajectory.status, .message         # "finished", "event" or "failed", and why

Settings come from the arguments, then the file's `simulate` and `initial` blocks, then
defaults. Bad settings raise `LagrangeError`; a run that fails (a singular mass matrix,
non-finite values, the step size collapsing) returns its trajectory so far with status
"failed" and a message naming the time and state. Repeated calls on the same model reuse
its compiled functions, and `timing` keeps one-time costs apart from the run itself, so a
work-precision study can call `simulate` in a loop.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from lagrange_cli.errors import LagrangeError
from lagrange_cli.inputs import substitute
from lagrange_cli.model import Model
from lagrange_cli.numeric import codegen, compile, integrators, policy, projection, status, switching
from lagrange_cli.numeric.integrators import Problem, Progress, Run, Stats
from lagrange_cli.numeric.policy import resolve
from lagrange_cli.numeric.projection import Correction, Projector
from lagrange_cli.numeric.settings import STAGES, Settings, check
from lagrange_cli.numeric.status import Status

if TYPE_CHECKING:
    from lagrange_cli.numeric.diagnostics import MassCondition

FAILURES = {
    integrators.SINGULAR: "the mass matrix{} is singular (a coordinate singularity, such as Euler angles at theta = 0, or a configuration without inertia)",
    integrators.NONFINITE: "the state became infinite or NaN (the motion blows up, or leaves the domain of a function such as sqrt or log)",
    integrators.STEP_COLLAPSE: "the step size collapsed below the spacing of floating-point numbers (a singularity, or a problem too stiff for this method: try --method Radau)",
    integrators.NO_CONVERGENCE: "the implicit stage equations did not converge (the step is too large for this motion: give a smaller --step)",
}
SURFACE_COLLAPSE = (
    "the motion could not be followed across a switching surface (an argument of Abs, sign or Heaviside, a Piecewise condition or a"
    " Max/Min difference is 0 there) where the forces jump: the field on both sides points into the surface (a sliding mode, such as"
    " dry friction sign(v) where the body sticks: the equations have no classical solution there; write the switch smoothly,"
    " tanh(v/eps) for sign(v)), or, through scipy (the python backend), every step across the jump was rejected at this tolerance"
    " (loosen --rtol, or use the compiled backend, which steps across a jump)"
)
"""Why a run stopped, where its step size collapsed on a switching surface (`_on_surface`): not a singularity."""
SURFACE_TOLERANCE = 1e-9
"""A run's last state is on a switching surface where |g| <= SURFACE_TOLERANCE x (1 + max |y|)."""
BUDGET_HINT = "shorten t_end (--t-end), loosen the tolerances (--rtol/--atol), or raise the budget (--max-steps)"
FIXED_BUDGET_HINT = "shorten t_end (--t-end), give a larger --step, or raise the budget (--max-steps)"
"""What may help a run its step budget stopped: an adaptive method's (tolerances), the symplectic method's (its fixed
--step: it has no tolerances; audit 11, F5: the adaptive methods were told to give a larger --step)."""


class InvariantKind(enum.StrEnum):
    """What a monitored quantity is."""

    ENERGY = "energy"
    MOMENTUM = "momentum"
    """The momentum of an ignorable coordinate."""
    CONSTRAINT = "constraint"
    """The residual of a kept constraint."""


@dataclass(frozen=True)
class Invariant:
    """A monitored quantity: its initial value and how far it moved over the run."""

    name: str
    conserved: bool
    """True when the equations conserve it, so any change is numerical error."""
    initial: float
    max_change: float
    final_change: float
    scale: float = 0.0
    """The size the change is measured against: |initial|, or for the energy the larger of
    |initial| and the largest |sum p q_dot| (twice the kinetic energy of a natural system),
    so that an energy that starts at or near 0 still gets a meaningful relative error."""
    kind: InvariantKind | None = None
    """What it is (None only for an invariant made by hand)."""

    @property
    def relative(self) -> float:
        """The largest change relative to `scale` (absolute when that is 0)."""
        return self.max_change / self.scale if self.scale > 0 else self.max_change


@dataclass(frozen=True)
class Timing:
    """Seconds: writing the generated code, importing it (and numba), compiling or loading
    machine code, and the integration itself."""

    generate: float
    load: float
    compile: float
    run: float


@dataclass(frozen=True)
class Trajectory:
    """Samples of one run and its report."""

    title: str
    coordinates: tuple[str, ...]
    settings: Settings
    t: np.ndarray
    y: np.ndarray
    energy: np.ndarray
    status: str
    """"finished", "event" (the `until` condition crossed zero) or "failed"."""
    message: str
    t_last: float
    y_last: np.ndarray
    stats: Stats
    timing: Timing
    invariants: tuple[Invariant, ...] = ()
    notes: tuple[str, ...] = field(default=())
    outcome: Status = Status.FINISHED
    """How the integrator's run ended, by kind (`status` is only finished, event or failed)."""
    warnings: tuple[integrators.Uncontrolled, ...] = ()
    """Where the run's error was not controlled (the symplectic method's monitor; also in `notes`)."""

    @property
    def failed(self) -> bool:
        return self.status == "failed"

    @property
    def names(self) -> tuple[str, ...]:
        """The columns of y: the coordinates, then their velocities."""
        return (*self.coordinates, *(f"{c}_dot" for c in self.coordinates))

    def invariant(self, kind: InvariantKind) -> Invariant | None:
        """The first monitored quantity of this kind (the energy: `invariant(InvariantKind.ENERGY)`)."""
        return next((i for i in self.invariants if i.kind == kind), None)

    def column(self, name: str) -> np.ndarray:
        """The samples of one coordinate or velocity (`theta`, `theta_dot`), or `t`, or `energy`."""
        if name == "t":
            return self.t
        if name == "energy":
            return self.energy
        if name not in self.names:
            raise LagrangeError(f"'{name}' is not a coordinate or velocity of {self.title}; choose one of {', '.join(self.names)}")
        return self.y[:, self.names.index(name)]


def simulate(
    model: Model,
    *,
    t_end: float | None = None,
    method: str | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    step: float | None = None,
    samples: int | None = None,
    t_eval: Sequence[float] | None = None,
    parameters: Mapping[str, float] | None = None,
    initial: Mapping[str, float] | None = None,
    until: str | None = None,
    backend: str = "auto",
    max_step: float | None = None,
    progress: Progress | None = None,
    max_steps: int | None = None,
    projection: bool | None = None,
    stages: int | None = None,
) -> Trajectory:
    """Integrate `model` from its initial state; see the module docstring for the conventions.
    `max_steps` is the step budget (default `integrators.MAX_STEPS` of the backend): a run that
    has not reached t_end after it stops, failed, with the trajectory so far. `projection` (default:
    on for a model with kept constraints) projects the state onto them at the samples (`projection.py`;
    compiled: inside the integration loop). `stages` fixes the symplectic method's Gauss-Legendre stages (1, 2 or 3;
    default: the pilot picks 2 or 3 with the step, or 2 with a given step). A model's inputs are taken at
    their defaults (`inputs.substitute`)."""
    model = substitute(model)
    check(model)
    plain = compile.build(model, "python")  # here rather than in the policy's linearisation, so that its cost is reported
    settings = resolve(
        model,
        t_end=t_end,
        method=method,
        rtol=rtol,
        atol=atol,
        step=step,
        samples=samples,
        t_eval=t_eval,
        parameters=parameters,
        initial=initial,
        until=until,
        backend=backend,
        max_step=max_step,
        projection=projection,
        stages=stages,
    )
    return integrate(model, settings, progress, max_steps, Timing(plain.generate_seconds, plain.import_seconds, 0.0, 0.0), exact=True)


def integrate(
    model: Model,
    settings: Settings,
    progress: Progress | None = None,
    max_steps: int | None = None,
    before: Timing | None = None,
    pace: Callable[[int, float], None] | None = None,
    exact: bool = False,
) -> Trajectory:
    """Run `settings` as decided by `policy.decide` (method and backend resolved); `before` the
    one-time costs already spent on this run; `pace`: see `integrators.Problem.pace` (compiled loops only);
    `exact`: stop at `max_steps` to the step (`integrators.Problem.exact`: `simulate`'s budget, a user's)."""
    model = substitute(model)
    refused = _beyond_budget(model, settings, max_steps, before)
    if refused is not None:
        return refused
    run, python, timing, notes = _integrated(model, settings, progress, max_steps, before, pace, exact)
    trajectory = _trajectory(model, settings, python, run, timing)
    return dataclasses.replace(trajectory, notes=(*trajectory.notes, *notes)) if notes else trajectory


IMPLICIT_ADVICE = "an adaptive method (--method auto or DOP853), or an implicit one (LSODA, Radau, BDF) where the system is stiff"


def fixed_steps(settings: Settings) -> int:
    """The steps a symplectic run of `settings` takes to t_end, known before it starts (its step is
    fixed; the last one is shortened onto t_end): 0 for an adaptive method."""
    if settings.method != "symplectic" or not settings.step:
        return 0
    ratio = abs(settings.t_end - settings.t0) / settings.step
    return max(1, math.ceil(ratio - 1e-9)) if ratio < 2.0**62 else 2**62


def _beyond_budget(model: Model, settings: Settings, max_steps: int | None, before: Timing | None) -> Trajectory | None:
    """A symplectic run whose fixed step needs more steps to t_end than its budget, refused before it
    starts (failed, with the start as its only sample and a message that says why and what to use
    instead), rather than spending the whole budget to stop short of t_end; None for any other run."""
    needed = fixed_steps(settings)
    budget = integrators.MAX_STEPS[settings.backend] if max_steps is None else _budget(max_steps)
    if needed <= budget:
        return None
    python = compile.build(model, "python")
    y0 = np.array(settings.y0, dtype=float)
    first = len(settings.t_eval) > 0 and settings.t_eval[0] <= settings.t0
    t, y = (np.array([settings.t0]), y0[None, :]) if first else (np.empty(0), np.empty((0, len(y0))))
    run = Run(t, y, integrators.BUDGET, settings.t0, y0, Stats(0, 0, 0, 0, 0, None, None), 0.0, 0.0)
    timing = before if before is not None else Timing(python.generate_seconds, python.import_seconds, 0.0, 0.0)
    trajectory = _trajectory(model, settings, python, run, timing)
    step = f"the symplectic method's fixed step {settings.step!r} ({settings.stages} stages) needs {needed} steps to reach t_end = {_g(settings.t_end)}, more than the step budget ({budget}); not run"
    if model.dissipative:
        why = (
            "this system dissipates (a Rayleigh function): the step resolves its fastest motion at the start, and a fixed step cannot grow once that motion has decayed;"
            f" symplectic methods are for conservative systems: use {IMPLICIT_ADVICE}"
        )
    else:
        why = f"give a larger --step or a shorter --t-end, or use {IMPLICIT_ADVICE}"
    return dataclasses.replace(trajectory, message=f"{model.source}: {step}: {why}")


def run_seconds(model: Model, settings: Settings, max_steps: int | None = None) -> float:
    """The integration time (`Timing.run`) of one more run of `settings`, without the report
    (invariants along the samples): what a study times again, in turns, once it has the report."""
    _, _, timing, _ = _integrated(substitute(model), settings, None, max_steps, None)
    return timing.run


def _integrated(
    model: Model, settings: Settings, progress: Progress | None, max_steps: int | None, before: Timing | None, pace: Callable[[int, float], None] | None = None, exact: bool = False
) -> tuple[Run, compile.Functions, Timing, tuple[str, ...]]:
    """The integrator's run of `settings`, the Python functions, the timing and the projection's notes.

    Compiled Radau projected onto kept constraints takes its Jacobian by forward differences: it restarts at
    each projection (a Jacobian per sample), where differences cost the same run time as the analytic `_jac`
    (trammel, rolling disk, multiplier pendulum at rtol 1e-5 and 1e-7: the same steps and errors, run times
    within 15 %), while the analytic Jacobian's module is a second compiled module of the system (1.3-4 s CPU
    to compile) beside the one the explicit pairs use (BENCHMARKS.md, issue 15, helper radproj)."""
    python = compile.build(model, "python", jacobian=settings.method in ("Radau", "BDF", "LSODA") and settings.backend != "compiled", event=settings.event)
    generate = python.generate_seconds + (before.generate if before else 0.0)
    load = python.import_seconds + (before.load if before else 0.0)
    budget = integrators.MAX_STEPS[settings.backend] if max_steps is None else _budget(max_steps)
    problem = Problem(
        settings.t0, settings.t_end, np.array(settings.y0, dtype=float), np.array(settings.t_eval, dtype=float), np.array(settings.p, dtype=float), settings.event is not None, budget, pace, exact
    )
    solver: integrators.Solver
    if settings.backend == "compiled":
        numba = compile.build(model, "numba", jacobian=settings.method == "Radau" and not (settings.projection and model.constraints), event=settings.event)
        generate, load = generate + numba.generate_seconds, load + numba.import_seconds
        solver = solver_for(settings, python, numba)
    else:
        solver = solver_for(settings, python)

    def runner(part: Problem, report: Progress | None) -> Run:
        run = solver.run(part, report)
        return _verified_event(python, part, run) if settings.backend == "compiled" else run

    notes: tuple[str, ...] = ()
    started = policy.take_attempt(model, settings, problem) if isinstance(solver, integrators.ExplicitRK) and solver.method == "DOP853" else None
    if started is not None and problem.exact and started.steps > problem.max_steps:
        # `auto`'s attempt took more steps than this run's budget (--max-steps 50): the run afresh, stopped at its budget
        notes = (f"the compiled run `auto` started with took {started.steps} steps, more than the step budget ({problem.max_steps}): the run started afresh",)
        started = None
    if settings.projection and model.constraints and isinstance(solver, (integrators.ExplicitRK, integrators.RadauCompiled)):
        run, notes = _projected_compiled(model, solver, problem, progress)
        run = _verified_event(python, problem, run)
    elif settings.projection and model.constraints:
        run, notes = _projected(model, settings, python, problem, runner, progress)
    elif started is not None:  # `auto` started this very run (policy.explicit_attempt): it goes on from where it paused
        run = _verified_event(python, problem, started.finish(progress))
    else:
        run = runner(problem, progress)
    if settings.method == "symplectic" and settings.step is not None:
        run = integrators.monitor(run, settings.step, policy.chosen_pilot(model, settings))
    return run, python, Timing(generate, load, run.compile_seconds, run.run_seconds), notes


MAX_STRETCHES = 1000
"""Projections of a run at most: with more samples than this, the state is projected at every k-th
sample only (with the scipy backend each stretch between two projections restarts the integrator)."""


def _bounds(problem: Problem) -> list[float]:
    """The times the state is projected at: the samples inside the span (every k-th with more than
    MAX_STRETCHES of them), and t_end."""
    inner = sorted({float(t) for t in problem.ts if problem.t0 < t < problem.t_end})
    every = max(1, math.ceil((len(inner) + 1) / MAX_STRETCHES))
    return [*inner[every - 1 :: every], problem.t_end] if every > 1 else [*inner, problem.t_end]


def _projected_compiled(model: Model, solver: integrators.ExplicitRK | integrators.RadauCompiled, problem: Problem, progress: Progress | None) -> tuple[Run, tuple[str, ...]]:
    """The compiled run with the state projected at the `_bounds` times inside its loop
    (integrators.run_erk_projected, or run_radau_projected for Radau: one compiled run, the same projection
    as `projection.Projector`), and a note saying what was corrected."""
    numba, holonomic = solver.functions, projection.holonomic_rows(model)
    level = None
    if model.energy_conserved:  # the level of the constrained state nearest the start (the start itself when it satisfies the constraints)
        start = integrators.project_compiled(numba, problem.t0, problem.y0, problem.p, holonomic, projection.record())
        if start is not None:
            size = numba.module._SIZE
            value = float(numba.module._energy(problem.t0, start, problem.p, np.empty(size), np.empty((size, size))))
            level = value if math.isfinite(value) else None
    found = projection.record(level)
    bounds = np.array(_bounds(problem), dtype=float)
    if isinstance(solver, integrators.RadauCompiled):
        run = integrators.run_radau_projected(numba, problem, solver.rtol, solver.atol, solver.max_step, bounds, holonomic, found, progress)
    else:
        run = integrators.run_erk_projected(numba, problem, solver.method, solver.rtol, solver.atol, solver.max_step, bounds, holonomic, found, progress)
    failures = int(found[status.FAILURES])
    failed = (
        f"; it could not be applied at {failures} of them, first at t = {_g(float(found[status.FAILED_AT]))} (the mass matrix or A M^-1 A^T singular there, or values not finite), and the run went on without it there"
        if failures
        else ""
    )
    restart = "; Radau restarts there: f, its Jacobian and LU afresh, no controller memory" if isinstance(solver, integrators.RadauCompiled) else ""
    where = f"at each of {int(found[status.PROJECTIONS])} sample times, inside the compiled loop (a step is shortened to land on each; the run goes on from the projected state{restart})"
    return run, (_projection_note(level is not None, where, projection.correction(found), failed),)


def _projection_note(energy: bool, where: str, largest: Correction, failed: str) -> str:
    """The note of a projected run: where it projected and the largest residuals it corrected."""
    return (
        f"projection onto the kept constraints{' and the energy level' if energy else ''} {where}"
        f" (M-weighted Gauss-Newton on the positions, then the velocities): largest residual corrected {largest.position:.2g} in the positions, {largest.velocity:.2g} in the velocities"
        + (f", {largest.energy:.2g} in the energy" if energy else "")
        + " (the drift between two projections; the monitored residuals"
        + (" and energy" if energy else "")
        + " are measured after projection)"
        + failed
    )


def _projected(
    model: Model, settings: Settings, python: compile.Functions, problem: Problem, runner: Callable[[Problem, Progress | None], Run], progress: Progress | None
) -> tuple[Run, tuple[str, ...]]:
    """The run in stretches between consecutive sample times (every k-th with more than
    MAX_STRETCHES samples), the state projected onto the kept
    constraints (positions and velocities, `projection.Projector`) at the end of each stretch
    before the next starts from it; one `Run` of them all, and a note saying what was corrected."""
    level, energy = None, None
    if model.energy_conserved:
        module, p = python.module, list(problem.p)

        def energy(t: float, y: np.ndarray) -> float:
            return integrators.evaluate(module._energy, t, y.tolist(), p, "the energy")[0]

        try:  # the level of the constrained state nearest the start (the start itself when it satisfies the constraints)
            level = energy(problem.t0, Projector(model, settings.values).project(problem.t0, problem.y0)[0])
        except (integrators.EvaluationError, ArithmeticError, ValueError, TypeError, np.linalg.LinAlgError):
            level = None
    projector = Projector(model, settings.values, energy, level)
    ts = problem.ts
    bounds = _bounds(problem)
    t_start, y = problem.t0, problem.y0.copy()
    pieces_t, pieces_y, runs = [ts[:0]], [np.empty((0, len(y)))], []
    if len(ts) and ts[0] <= problem.t0:  # the first sample is the start itself
        pieces_t.append(ts[:1])
        pieces_y.append(y[None, :])
    largest = Correction(0.0, 0.0, 0.0, 0.0)
    projections, failed = 0, ""
    steps_left = problem.max_steps
    span = problem.t_end - problem.t0
    over_budget = False
    began = time.perf_counter()
    for t_stop in bounds:
        if steps_left <= 0:
            over_budget = True
            break
        inside = ts[(ts > t_start) & (ts <= t_stop)]
        part = Problem(t_start, t_stop, y, inside, problem.p, problem.use_event, steps_left, exact=problem.exact)
        report = (lambda fraction, a=t_start, b=t_stop: progress((a - problem.t0 + fraction * (b - a)) / span)) if progress is not None else None
        run = runner(part, report)
        runs.append(run)
        steps_left -= run.stats.steps
        pieces_t.append(run.t)
        if run.status != integrators.FINISHED:
            pieces_y.append(run.y)
            break
        try:
            y, correction = projector.project(t_stop, run.y_last)
        except (ArithmeticError, ValueError, TypeError, np.linalg.LinAlgError) as error:
            y, failed = run.y_last, f"; it could not be applied at t = {_g(t_stop)} ({error}), and the run went on without it"
            correction = Correction(0.0, 0.0, 0.0, 0.0)
        projections += 1
        largest = Correction(*(max(getattr(largest, k), getattr(correction, k)) for k in ("position", "velocity", "moved", "energy")))
        pieces_y.append(np.vstack([run.y[:-1], y[None, :]]) if len(run.t) and run.t[-1] == t_stop else run.y)  # the sample at the end of a stretch: projected
        t_start = t_stop
    last = runs[-1]
    stats = Stats(
        sum(r.stats.nfev for r in runs),
        sum(r.stats.njev for r in runs),
        sum(r.stats.nlu for r in runs),
        sum(r.stats.steps for r in runs),
        None if any(r.stats.rejected is None for r in runs) else sum(r.stats.rejected or 0 for r in runs),
        min((r.stats.min_step for r in runs if r.stats.min_step is not None), default=None),
        max((r.stats.max_step for r in runs if r.stats.max_step is not None), default=None),
        sum(r.stats.floored for r in runs),
    )
    outcome = integrators.BUDGET if over_budget else last.status
    # (a stretch stopped by its budget ends at its own last state, not at the last projected sample: audit 12, F4)
    y_last = y if outcome == integrators.FINISHED or over_budget else last.y_last
    compile_seconds = sum(r.compile_seconds for r in runs)
    elapsed = time.perf_counter() - began - compile_seconds  # the projections count as part of the run
    run = Run(np.concatenate(pieces_t), np.vstack(pieces_y), outcome, t_start if over_budget else last.t_last, y_last, stats, compile_seconds, elapsed, last.problem)
    return run, (_projection_note(level is not None, f"after each of {projections} stretches of the run (at the samples)", largest, failed),)


def _budget(max_steps: object) -> int:
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
        raise LagrangeError(f"max_steps must be a whole number of at least 1, got {max_steps!r}")
    return max_steps


def solver_for(settings: Settings, python: compile.Functions, numba: compile.Functions | None = None) -> integrators.Solver:
    """The solver of decided `settings` (method and backend resolved by `policy.decide`): `numba`
    the system compiled, for the compiled backend."""
    if settings.backend != "compiled":
        return integrators.Scipy(python, settings.method, settings.rtol, settings.atol, settings.max_step)
    if numba is None:
        raise ValueError("the compiled backend needs the compiled functions")
    if settings.method == "symplectic":
        if settings.step is None:
            raise ValueError("the symplectic method needs its step (policy.decide chooses it)")
        return integrators.Gauss(numba, python, settings.stages if settings.stages is not None else STAGES, settings.step)
    if settings.method == "Radau":
        return integrators.RadauCompiled(numba, settings.rtol, settings.atol, settings.max_step)
    return integrators.ExplicitRK(numba, settings.method, settings.rtol, settings.atol, settings.max_step)


def _verified_event(python: compile.Functions, problem: Problem, run: Run) -> Run:
    """A compiled loop (NaN arithmetic, no exceptions) takes a stop condition that turns NaN for a
    crossing: where the condition cannot be evaluated at the located event, the run failed there."""
    if run.status != integrators.EVENT:
        return run
    try:
        integrators.evaluate(python.module._event, run.t_last, run.y_last.tolist(), problem.p.tolist(), "the stop condition (--until)")
    except integrators.EvaluationError as problem_found:
        return dataclasses.replace(run, status=integrators.NONFINITE, problem=problem_found)
    return run


def _trajectory(model: Model, settings: Settings, python: compile.Functions, run: Run, timing: Timing) -> Trajectory:
    """The report of a run: invariants along the samples, and a message for an event or a failure.
    A monitored quantity that cannot be evaluated at a sample ends the run there, failed."""
    module, p = python.module, list(settings.p)
    while True:
        try:
            energy = _values(module._energy, run, p, "the energy")[:, 0] if len(run.t) else np.empty(0)
            invariants = _invariants(model, module, p, run, energy)
            break
        except _MonitorFailure as stop:
            run = _cut(run, stop.index, stop.problem)
    if run.status == integrators.FINISHED:
        status, message = "finished", f"reached t = {_g(run.t_last)}"
    elif run.status == integrators.EVENT:
        status, message = "event", f"stopped at t = {_g(run.t_last)}, where {settings.until} crossed zero"
    elif run.status == integrators.BUDGET:
        status = "failed"
        message = (
            f"{model.source}: stopped after {run.stats.steps} steps (the step budget) at t = {_g(run.t_last)}, of t_end = {_g(settings.t_end)}; state: {state_text(model, run.y_last)};"
            f" {FIXED_BUDGET_HINT if settings.method == 'symplectic' else BUDGET_HINT}"
        )
    else:
        status = "failed"
        if run.problem is not None:
            reason = f"{run.problem.what} cannot be evaluated at t = {_g(run.problem.t)} ({state_text(model, run.problem.y)}): {run.problem.cause}"
        elif run.status == Status.SURFACE_JUMP or (run.status == integrators.STEP_COLLAPSE and _on_surface(python.module, run, p)):
            reason = SURFACE_COLLAPSE
            run = dataclasses.replace(run, status=Status.SURFACE_JUMP)
        elif run.status == integrators.SINGULAR and (ended_here := coordinates_end(model, settings, run.t, run.y, run.t_last, run.y_last, singular=True)) is not None:
            reason = ended_here  # how the coordinates end there (audit 12: a spherical pendulum in x, y at x^2 + y^2 = L^2)
        else:
            reason = FAILURES[run.status].format(" (with the constraint rows)" if model.constraints else "")
        message = f"{model.source}: simulation failed at t = {_g(run.t_last)}: {reason}; state: {state_text(model, run.y_last)}"
    if status == "failed" and run.problem is None:
        ended = model_end(model, settings, run.t_last)
        if ended is not None:
            message = (
                f"{model.source}: stopped at t = {_g(run.t_last)} ({run.stats.steps} steps), where the model itself ends: its mass matrix is singular at"
                f" t = {_g(ended)} whatever the state (it depends on t explicitly: a length, mass or inertia of the model reaches zero there); no method"
                f" and no change of coordinates passes it: give a t_end before it (--t-end); state: {state_text(model, run.y_last)}"
            )
        elif run.status in (integrators.BUDGET, integrators.STEP_COLLAPSE) and (stalled := _stalled(model, settings, run, python.module)) is not None:
            run = dataclasses.replace(run, status=Status.STALLED)
            message = f"{model.source}: stopped at t = {_g(run.t_last)}, of t_end = {_g(settings.t_end)}, after {run.stats.steps} steps: {stalled}; state: {state_text(model, run.y_last)}"
    alarm = _energy_alarm(settings, run, energy, invariants) if status != "failed" else None
    notes = (
        *settings.notes,
        *(warning.message for warning in run.warnings),
        *switching.notes(run.switching, getattr(python.module, "_SWITCHES", 0), switching.LOCATE),
        *((alarm,) if alarm else ()),
    )
    return Trajectory(model.title, model.coordinates, settings, run.t, run.y, energy, status, message, run.t_last, run.y_last, run.stats, timing, invariants, notes, run.status, run.warnings)


ENERGY_ALARM = 1e-2
"""A run that finished is warned about when the energy its system conserves jumped, between two samples, by more than
ENERGY_ALARM of its scale (`Invariant.scale`) and ENERGY_JUMP x rtol, or moved over the run by more than ENERGY_ALARM and
ENERGY_DRIFT x rtol (for the symplectic method, whose step has no rtol, ENERGY_ALARM alone). Audit 12: a pendulum written
in x with its height -sqrt(L^2 - x^2), given the energy to pass the horizontal, "finished" at rtol 1e-8 with its energy
changed by 23 % (100 % of its initial value), the motion reflected at x = L, the edge of the region its coordinates
describe; a pendulum whose angle is acos(c), by 51 %. An accurate run's energy moves by about rtol per unit time."""
ENERGY_JUMP = 100.0
ENERGY_DRIFT = 1e4


def _energy_alarm(settings: Settings, run: Run, energy: np.ndarray, invariants: Sequence[Invariant]) -> str | None:
    """The warning for a finished run whose conserved energy jumped or drifted far beyond its tolerance (ENERGY_ALARM);
    else None."""
    found = next((i for i in invariants if i.kind == InvariantKind.ENERGY and i.conserved), None)
    if found is None or len(energy) < 2 or found.scale <= 0 or not np.all(np.isfinite(energy)):
        return None
    steps = np.abs(np.diff(energy)) / found.scale
    k = int(np.argmax(steps))
    fixed = settings.method == "symplectic"
    jump = steps[k] > ENERGY_ALARM and (fixed or steps[k] > ENERGY_JUMP * settings.rtol)
    drift = found.relative > ENERGY_ALARM and (fixed or found.relative > ENERGY_DRIFT * settings.rtol)
    if not (jump or drift):
        return None
    where = f"jumping by {steps[k]:.2g} between t = {_g(float(run.t[k]))} and {_g(float(run.t[k + 1]))}" if jump else "drifting steadily"
    tolerance = "its step" if fixed else f"rtol {settings.rtol:g}"
    return (
        f"warning: the energy, which this system conserves, changed by {found.relative:.2g} of its scale along the run ({where}), far more"
        f" than {tolerance} allows: the run likely stepped across a point where its equations are singular (the edge of the region its"
        " coordinates describe, or a collision) without resolving it, and the trajectory past there is not to be trusted; describe the"
        " system in coordinates regular there, or give a t_end before it" + ("" if jump else "; or, if nothing is singular along it, tighten the tolerance")
    )


STALL_STEP = 1e-8
"""A run stopped by its step budget or a collapsed step stalled at a coordinate singularity (Status.STALLED, `_stalled`)
where its smallest step was below STALL_STEP x max(1, |t|) ..."""
STALL_CONDITION = 1e5
"""... cond M at its last state (scaled as `diagnostics.mass_condition`, by the larger of the coordinates' sizes there and
at the start) above this ..."""
STALL_GROWTH = 1e3
"""... and above this times its value at the start. Audit 11's Foucault pendulum in x, y (z = -sqrt(L^2 - x^2 - y^2))
given the energy to reach the pivot's height: DOP853 took 1e6 steps down to 2e-12 (5e6 more moved t by 7e-6),
Radau 1e6 down to 4e-15, each stopping at x^2 + y^2 = L^2 (to 1e-5) with cond M 3e5-7e5 against 1.15 at the start;
the message advised more steps, a larger --step and looser tolerances, none of which could help."""


STALL_KINETIC = 100.0
"""... unless its kinetic energy 1/2 q_dot^T M q_dot there is above this times its largest at the run's samples: then the
motion blows up (a radial infall in polar coordinates reaches r = 1e-9 with T 1e8 x its largest sample's), not only
the coordinates; where they end, T stays bounded (M's inertia grows where the velocities shrink, or the other way)."""
STALL_SAMPLES = 200
"""The kinetic energy is compared with its values at this many of the run's samples (and its start), evenly spread."""


def _kinetic(mass: Callable[[float, Sequence[float] | np.ndarray], np.ndarray | None], t: float, y: np.ndarray) -> float:
    """1/2 q_dot^T M(q, t) q_dot at (t, y); 0 where M cannot be evaluated."""
    n = len(y) // 2
    m = mass(t, y)
    return 0.0 if m is None else float(0.5 * y[n:] @ m @ y[n:])


def _spread(settings: Settings, t: np.ndarray, y: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """The run's start and up to STALL_SAMPLES of its samples (`t`, `y`), evenly spread."""
    picked = np.unique(np.linspace(0, len(t) - 1, min(STALL_SAMPLES, len(t))).astype(int)) if len(t) else np.array([], dtype=int)
    return [(settings.t0, np.asarray(settings.y0, dtype=float)), *((float(t[k]), np.asarray(y[k], dtype=float)) for k in picked)]


STALL_PROBE = 20_000
"""A candidate stall is confirmed by a probe: scipy's DOP853 (rtol at least STALL_PROBE_RTOL) from the last state must get
stuck within this many right-hand side evaluations (0.1-0.5 s): its step collapses (scipy's status -1) or it steps where
the equations cannot be evaluated, before it reaches t_end or a state where cond M is below STALL_LEFT x its value at
the stop, and before its evaluations run out (then it is not shown to be stuck). A run whose budget ended inside a close
pass goes on past it: Kepler's orbit at e = 0.9 through periapsis in polar coordinates (cond M 7e8 against 1e4 at the
start, steps of 1e-9), a top whose axis passes within 1e-4 (or, given its steps, 1e-6) of the vertical in Euler angles."""
STALL_PROBE_RTOL = 1e-8
STALL_LEFT = 1e-2


class _ProbeOver(Exception):
    """The probe's evaluations ran out."""


class _ProbeStuck(Exception):
    """The probe reached a state where the right-hand side cannot be evaluated (or is not finite)."""


def _leaves(module: Any, settings: Settings, run: Run, condition: Callable[[float, np.ndarray], float], last: float) -> bool:
    """Whether the motion leaves the near-singular state a run stopped at (STALL_PROBE)."""
    import warnings

    from scipy.integrate import solve_ivp

    rhs = policy.safe_rhs(module, tuple(float(v) for v in settings.p))
    seen: list[tuple[float, np.ndarray]] = []
    count = 0

    def f(t: float, y: np.ndarray) -> np.ndarray:
        nonlocal count
        count += 1
        if count > STALL_PROBE:
            raise _ProbeOver
        value = rhs(t, y)
        if value is None or not np.all(np.isfinite(value)):
            raise _ProbeStuck
        if count % 50 == 0:
            seen.append((t, np.array(y, dtype=float)))
        return value

    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        try:
            found = solve_ivp(f, (run.t_last, settings.t_end), np.asarray(run.y_last, dtype=float), method="DOP853", rtol=max(settings.rtol, STALL_PROBE_RTOL), atol=max(settings.atol, 1e-12))
            if found.status == 0:
                return True  # it reached t_end
        except _ProbeOver:
            return True  # still going when its evaluations ran out: not shown to be stuck (audit 12: a top's axis passing within 1e-6 of the vertical needs 16578 steps)
        except _ProbeStuck:
            pass
    # stuck: its step collapsed (scipy's status -1) or it stepped where the equations cannot be evaluated; unless it left first
    return any(condition(t, y) <= STALL_LEFT * last for t, y in seen)


def _stalled(model: Model, settings: Settings, run: Run, module: Any) -> str | None:
    """Why a run that its step budget or a collapsed step stopped cannot go on, where its steps shrank at a state with a
    nearly singular mass matrix that the start did not have (STALL_STEP, STALL_CONDITION, STALL_GROWTH): the coordinates
    end there; else None (a run merely over its budget, or a blow-up: FAILURES says what)."""
    smallest = run.stats.min_step
    if smallest is None or not math.isfinite(run.t_last) or smallest > STALL_STEP * max(1.0, abs(run.t_last)):
        return None
    found = _ending(model, settings, run.t_last, run.y_last, _spread(settings, run.t, run.y))
    if found is None:
        return None
    condition, last, what = found
    if _leaves(module, settings, run, condition, last):
        return None  # a close pass that its budget ended in, not a stall
    return f"its steps shrank to {smallest:.1e} where {what}"


def coordinates_end(model: Model, settings: Settings, t: np.ndarray, y: np.ndarray, t_last: float, y_last: np.ndarray, singular: bool = False) -> str | None:
    """Where a run that stopped at (t_last, y_last) on a singular mass matrix (`singular`: its LU's pivot test said so)
    or a collapsed step stopped because its coordinates end there (`_ending`), what they do there and what to do; else
    None (a blow-up of the motion itself: a collision). `t`, `y`: the run's samples. A reference whose methods all stop
    there has found where the description ends, not the solution: audit 12's heavy top in Euler angles started at
    theta = 0.01, whose axis passes within 3e-7 of the vertical (cond M 4e13), stopped DOP853 and Radau alike on "the
    mass matrix is singular", which `stress` called a blow-up of the system and not met; so did a pendulum whose angle
    is acos(c), at c = 1."""
    found = _ending(model, settings, t_last, y_last, _spread(settings, t, y), singular, floor=ENDED_CONDITION)
    return None if found is None else found[2]


ENDED_CONDITION = 1e10
"""`coordinates_end`, which has no probe (a stop on a singular M, or a reference whose methods all stop at one state),
asks for cond M above this at the stop (and, with one coordinate, M's one entry this many times above or below its value
at the start, or not finite): M about singular in double precision. Audit 12: a free particle in polar coordinates at
r = 956 (cond M 9e5 in the sizes there, regular) beside an oscillator whose stiffness overflows stopped compiled DOP853
on "the mass matrix is singular" (a trial stage's forces were not finite; since then such a stage rejects the step,
kernels._not_finite): the coordinates do not end there."""


def _entry_ends(at_stop: np.ndarray | None, at_start: np.ndarray | None, floor: float) -> bool:
    """Whether a 1 x 1 M at the stop is `floor` x its value at the start or 1 / `floor` of it, or not finite."""
    if at_stop is None or not np.all(np.isfinite(at_stop)):
        return True
    if at_start is None or not np.all(np.isfinite(at_start)):
        return False
    stop, start = abs(float(at_stop[0, 0])), abs(float(at_start[0, 0]))
    return stop > floor * start or stop * floor < start


def _ending(
    model: Model, settings: Settings, t_last: float, y_last: np.ndarray, samples: Sequence[tuple[float, np.ndarray]], singular: bool = False, floor: float = STALL_CONDITION
) -> tuple[MassCondition, float, str] | None:
    """Whether the coordinates end at (t_last, y_last): cond M there, in the larger of the coordinates' sizes there and at
    the start, above `floor` (STALL_CONDITION, or ENDED_CONDITION without a probe) and STALL_GROWTH x its value at the
    start (or, for one coordinate, `singular`: M found singular there by the integrator, in a model without kept
    constraints, whose rows can lose rank where the motion does not end, and its one entry `floor` x its start's or
    1 / `floor` of it, or not finite), and
    the kinetic energy there within STALL_KINETIC x its largest at `samples` (else the motion blows up there, not only
    the coordinates: a collision; where M itself is infinite, as 1/(1 - c^2) at c = 1, no collision is). Then cond M's
    measure, its value there and the words that say so (what the coordinates do there, which one, what to do); else
    None."""
    from lagrange_cli.numeric import diagnostics, memo

    if not math.isfinite(t_last) or not np.all(np.isfinite(y_last)):
        return None
    values = tuple(float(v) for v in settings.values)
    begin = memo.once(model, ("stall condition", values, tuple(settings.y0)), lambda: diagnostics.mass_condition(model, values, settings.y0))
    # at the stop, in the larger of the coordinates' sizes there and at the start: a polar r grown from 1 to 1000 makes
    # M = diag(m, m r^2) 1e6-conditioned in the start's sizes, regular in its own (audit 12: a free particle flying out)
    sizes = np.maximum(np.abs(np.asarray(settings.y0, dtype=float)), np.abs(np.asarray(y_last, dtype=float)))
    condition = diagnostics.MassCondition(begin.mass, diagnostics.coordinate_sizes(sizes, model.n))
    last, start = condition(t_last, y_last), begin(settings.t0, np.asarray(settings.y0, dtype=float))
    singular = singular and not model.constraints
    mass = condition.mass
    at_stop, at_start = mass(t_last, y_last), mass(settings.t0, settings.y0)
    if model.n == 1:  # cond of a 1 x 1 M is 1: the integrator's finding M singular and its one entry are the test
        if not singular or not _entry_ends(at_stop, at_start, floor):
            return None
    elif not (last > floor and last > STALL_GROWTH * start):
        return None
    kinetic = _kinetic(mass, t_last, y_last)
    if math.isfinite(kinetic) and kinetic > STALL_KINETIC * max(_kinetic(mass, float(t), y) for t, y in samples):
        return None  # the motion blows up there, not only the coordinates: a collision (FAILURES says what)
    if model.n == 1:  # its one entry says how M turns singular
        unbounded = at_stop is None or not np.all(np.isfinite(at_stop)) or (at_start is not None and abs(float(at_stop[0, 0])) > abs(float(at_start[0, 0])))
        how = "grows without bound" if unbounded else "vanishes"
        state = f"the mass matrix is {'singular' if singular else 'nearly singular'} (its one entry {how} at {model.coordinates[0]} = {_g(float(y_last[0]))})"
    else:
        moved = diagnostics.singular_coordinate(model.coordinates, condition, t_last, y_last, at_stop, at_start)
        named = f"; it changes fastest with {moved.coordinate} = {_g(moved.value)}" if moved is not None else ""
        level = "infinite" if math.isinf(last) else f"{last:.1e}"
        state = f"the mass matrix is {'singular' if singular else 'nearly singular'} (cond M = {level} there, {start:.3g} at the start{named})"
        unbounded = moved is not None and moved.unbounded
    if unbounded:
        what = "the edge of the region they describe (M's inertia grows without bound, as where a height solved from a constraint with sqrt reaches 0)"
        regular = "angles or a unit vector for a direction or a position on a sphere"
    else:
        what = "a configuration where they lose a direction (M's inertia vanishes, as for Euler angles at gimbal lock or polar angles at the pole)"
        regular = "a unit vector or a quaternion for an orientation, Cartesian components for a direction"
    words = (
        f"{state}: the coordinates end there, not the motion: {what}. A larger step budget or a looser tolerance passes it at best with a large"
        f" error there: describe the system in coordinates regular there ({regular}), or give a t_end before it (--t-end)"
    )
    return condition, last, words


ENDED = 1e-3
"""A run that stops within ENDED x max(1, |t|) of a time at which the mass matrix is singular whatever the state
(`diagnostics.time_singularity`) stopped because the model ends there."""


def model_end(model: Model, settings: Settings, t_last: float) -> float | None:
    """The time at which the model itself ends (its mass matrix singular whatever the state, which only a mass
    matrix depending on t explicitly can be) where a run stopped at `t_last` next to it; else None. Audit 7's crane
    reels its rope in to zero length at t = 13.33: a run past it stopped at its step budget with the angle's rate
    at 4e8/s, a "singularity" no coordinates remove."""
    from lagrange_cli.numeric import diagnostics

    if not math.isfinite(t_last):
        return None
    ended = diagnostics.model_end(model, settings.values, settings.t0, t_last + ENDED * max(1.0, abs(t_last)), settings.y0)
    return ended if ended is not None and abs(ended - t_last) <= ENDED * max(1.0, abs(ended)) else None


SURFACE_TIME = 1e-6
"""... or its flow reaches one within this times max(1, |t|): a compiled explicit run whose steps collapsed while it
crept onto a sliding surface (the block on a belt, dry friction sign(v0 - x_dot): stopped 3.7e-9 short of x_dot = v0,
reached at its rate in 1.2e-9 s, at t = 0.117) stopped there, not at a singularity."""
SURFACE_PROBE = 1e-8
"""The time step (x max(1, |t|)) along the flow over which `_on_surface` measures a switching function's rate."""


def _on_surface(module: Any, run: Run, p: Sequence[float]) -> bool:
    """Whether a run's last state lies on one of the system's switching surfaces (codegen's `_switch`), or next to one
    that its flow reaches within SURFACE_TIME x max(1, |t|)."""
    if not switching.located(module):
        return False
    t, y, values = run.t_last, run.y_last.tolist(), list(p)
    try:
        g = integrators.evaluate(module._switch, t, y, values, "the switching functions")
    except integrators.EvaluationError:
        return False
    scale = 1.0 + float(np.max(np.abs(run.y_last))) if run.y_last.size else 1.0
    if any(abs(value) <= SURFACE_TOLERANCE * scale for value in g):
        return True
    delta = SURFACE_PROBE * max(1.0, abs(t))
    n = len(y) // 2
    try:
        f = y[n:] + integrators.evaluate(module._accel, t, y, values, "the equations of motion")[:n]
        moved = integrators.evaluate(module._switch, t + delta, [v + delta * d for v, d in zip(y, f, strict=True)], values, "the switching functions")
    except integrators.EvaluationError:  # the forces cannot be evaluated there (a singular matrix, a domain error): no verdict
        return False
    horizon = SURFACE_TIME * max(1.0, abs(t))
    return any(value * (after - value) < 0 and abs(value) * delta <= horizon * abs(after - value) for value, after in zip(g, moved, strict=True))


class _MonitorFailure(Exception):
    def __init__(self, index: int, problem: integrators.EvaluationError) -> None:
        super().__init__(str(problem))
        self.index, self.problem = index, problem


def _values(function: object, run: Run, p: list[float], what: str, every: int = 1) -> np.ndarray:
    """function(t, y, p) at the samples (every `every`-th), one row each; `_MonitorFailure` at
    the first sample where it cannot be evaluated (all samples at once where they can be: `integrators.evaluate_samples`)."""
    at_once = integrators.evaluate_samples(function, run.t[::every], run.y[::every], p)  # type: ignore[arg-type]
    if at_once is not None:
        return at_once
    rows = []
    for k in range(0, len(run.t), every):
        try:
            rows.append(integrators.evaluate(function, float(run.t[k]), run.y[k].tolist(), p, what))  # type: ignore[arg-type]
        except integrators.EvaluationError as problem:
            raise _MonitorFailure(k, problem) from None
    return np.array(rows, dtype=float)


def _cut(run: Run, index: int, problem: integrators.EvaluationError) -> Run:
    """The run up to (not including) sample `index`, failed there because of `problem`."""
    t_last = float(run.t[index - 1]) if index > 0 else float(run.t[0])
    y_last = run.y[index - 1] if index > 0 else run.y[0]
    return dataclasses.replace(run, t=run.t[:index], y=run.y[:index], status=integrators.NONFINITE, t_last=t_last, y_last=y_last, problem=problem)


def _invariants(model: Model, module: object, p: list[float], run: Run, energy: np.ndarray) -> tuple[Invariant, ...]:
    """Energy, the momenta of ignorable coordinates, and constraint residuals along the samples."""
    if len(run.t) == 0:
        return ()
    result = [_invariant("energy", InvariantKind.ENERGY, model.energy_conserved, energy, scale=_energy_scale(module, p, run))]
    ignorable = codegen.ignorable(model)
    if ignorable:
        momenta = _values(module._momenta, run, p, "the momenta")  # type: ignore[attr-defined]
        result += [_invariant(f"p_{model.coordinates[i]}", InvariantKind.MOMENTUM, True, momenta[:, k]) for k, i in enumerate(ignorable)]
    if model.constraints:
        residuals = _values(module._residuals, run, p, "the constraint residuals")  # type: ignore[attr-defined]
        result += [_invariant(f"constraint {c.name}", InvariantKind.CONSTRAINT, True, residuals[:, k], drift=True) for k, c in enumerate(model.constraints)]
    return tuple(result)


def _invariant(name: str, kind: InvariantKind, conserved: bool, values: np.ndarray, drift: bool = False, scale: float = 0.0) -> Invariant:
    start = 0.0 if drift else float(values[0])
    change = np.abs(values - start)
    size = max(abs(start), scale) if math.isfinite(scale) else abs(start)
    return Invariant(name, conserved, start, float(np.nanmax(change)) if len(change) else 0.0, float(change[-1]), size, kind)


ENERGY_SCALE_SAMPLES = 101  # samples at which sum p q_dot is evaluated for the energy's scale


def _energy_scale(module: object, p: list[float], run: Run) -> float:
    """The largest |sum p_i q_dot_i| over (at most ENERGY_SCALE_SAMPLES of) the samples."""
    n = run.y.shape[1] // 2
    every = max(1, math.ceil(len(run.t) / ENERGY_SCALE_SAMPLES))
    largest = 0.0
    momenta = _values(module._canonical, run, p, "the momenta", every)  # type: ignore[attr-defined]
    for row, y in zip(momenta, run.y[::every], strict=True):
        largest = max(largest, abs(math.fsum(m * v for m, v in zip(row.tolist(), y[n:].tolist(), strict=True))))
    return largest


def state_text(model: Model, y: np.ndarray) -> str:
    """`theta = 0.1, theta_dot = -2`: a state for messages."""
    names = (*model.coordinates, *(f"{c}_dot" for c in model.coordinates))
    return ", ".join(f"{n} = {_g(float(v))}" for n, v in zip(names, y, strict=True))


def _g(value: float) -> str:
    return f"{value:.6g}" if math.isfinite(value) else str(value)
