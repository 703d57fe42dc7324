"""What `auto` means for one run: the method, the backend, the symplectic step and Baumgarte's alpha.

`decide(model, settings)` takes validated `Settings` (settings.py) and returns them resolved,
with notes saying why. Where compiled DOP853 can run it (numba, no kept constraints, and a run long
enough to compile for or a system already compiled), `auto` first starts the run itself with it
(`explicit_attempt`), with Hairer's stiffness test (dop853.f: h |lambda| estimated on each accepted
step from the last stage and the new solution; above 6.1 on 15 steps, stiff), for at most
ATTEMPT_STEPS steps (about a pilot's cost):

- it finished (or stopped at its event, or failed): that is the run, `simulate` takes it up
  (`take_attempt`); no pilot is spent, and the run costs what `--method DOP853` costs;
- the test found it stiff, but the steps left at its stability-limited step are fewer than
  ATTEMPT_STEPS (cheaper than any implicit run): it goes on from where it paused;
- otherwise (stiff, over ATTEMPT_STEPS, or projected from its last CHECK_STEPS steps to need more than
  LONG_STEPS) the pilot below decides; where it picks DOP853 the run
  goes on from where it paused, and where the decay's estimate makes the choice close, the paused
  run goes on MEASURE_STEPS steps and its measured cost of the rest of the run decides (`measure_attempt`).

The method comes otherwise from a short pilot run (`pilot`): PILOT_STEPS (at most PILOT_MAX_STEPS)
steps of LSODA from the initial state, with the spectrum of the Jacobian sampled along it. The
pilot measures what one linearisation at t = 0 cannot: the fastest unmatched decay anywhere
along the start (stiffness: decay x t_end, and the steps an explicit method needs just to stay
stable, decay x t_end / DOP853_STABILITY) and the step an implicit method actually settles to
once the transient is over (LSODA's own step at the end of the pilot, hence its step count for
the run). Then:

- not stiff anywhere along the pilot (see `diagnostics.stiff`: oscillatory or saddle
  eigenvalues are not stiffness, nor a decay about as fast as the solution itself changes,
  `diagnostics.own_rate`: an orbit's angular velocity falling as r grows) -> DOP853;
- stiff, but the explicit steps cost less compiled than the implicit steps (explicit steps <=
  IMPLICIT_COST x implicit steps) -> DOP853. The explicit steps are first estimated from the
  decay (decay x t_end / DOP853_STABILITY); where that estimate would pick DOP853, a short
  explicit probe (the paused compiled run above, or where there is none `explicit_probe`: PROBE_STEPS
  steps of scipy's DOP853, the same step control as the compiled kernel, from where the pilot ended)
  measures them, rejected steps included:
  round-off in the stiff terms (a spring of k = 1e11 written in its length) or a double
  eigenvalue at the stability limit make DOP853 take 5-6x the estimate, half of them rejected;
- stiff and dearer explicitly -> Radau compiled where numba runs (a step costs RADAU_COST compiled
  DOP853 attempts, 100-240x less than scipy's Radau: issue 15); without numba (or with --backend python)
  -> LSODA (measured 3-6x faster than Radau and 2-4x faster than BDF through scipy on the stiff audit
  cases; it also switches to Adams by itself where the stiffness dies out).

The pilot runs on while LSODA still steps with Adams on a problem the sampled spectra call
stiff (LSODA switches to BDF by itself once it detects the stiffness; up to PILOT_MAX_STEPS), and
for PILOT_TAIL steps after a switch, so that its settled step is that of the method it will use.
The notes give the measured numbers. The initial linearisation still sets how fast the system
moves (whether compiling pays off, the symplectic step, Baumgarte's alpha for kept constraints).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model
from lagrange_cli.numeric import compile, diagnostics, integrators, memo, status, switching
from lagrange_cli.numeric.settings import COMPILED, STAGES, Settings, code_parameters, validate

HEAVY = 3000.0  # rate x time span above which compiling pays off (about 1e4 steps)
PILOT_STEPS = 200
"""Steps of the pilot run (LSODA, Python): about 400 right-hand side evaluations, ~10-20 ms ..."""
PILOT_MAX_STEPS = 800
"""... continued, while LSODA's step is still growing (the mean of its last PILOT_TAIL steps more
than SETTLED x that of the PILOT_TAIL before), up to this many: after a fast transient the step
grows for a while, and extrapolating it too early overestimates the implicit steps."""
SETTLED = 1.5
PILOT_SPECTRA = 8
"""Jacobians (forward differences) sampled along the pilot, besides the initial state's."""
PILOT_TAIL = 20
"""The pilot's last this many steps give the step size its implicit method settles to."""
DOP853_STABILITY = 6.0
"""|h lambda| on the negative real axis up to which DOP853 stays stable (measured: the damped
cart at decay 9e5/s over t_end = 10 takes 1.46e6 steps = decay x t_end / 6.2)."""
IMPLICIT_COST = 25.0
"""Cost of an LSODA step (Python right-hand side, ~1.5 evaluations) over a compiled DOP853 step
attempt (12 compiled evaluations). Measured in CPU time of whole `simulate` calls
(benchmarks/auto_bench.py, 2026-11-26, quiet machine): 24-25 us per LSODA step against 0.87-0.93 us per
compiled DOP853 attempt (ratio 26-28) on the damped stiff spring at k = 1e8 and the elastic
pendulum in r at k = 1e8, the two cases where the choice is close; earlier, loaded runs gave 20-30
(20 was used until then) and integration time alone 8-20."""
RADAU_COST = 2.0
"""Cost of a compiled Radau step attempt (kernels.radau_run, analytic Jacobian) over a compiled DOP853
attempt, where numba runs both: 1.77-1.80 measured (CPU time, best of 3, interleaved; 1.9-2.0 us against
1.07-1.09 us) on the damped stiff spring and the elastic pendulum in r at k = 1e8 (BENCHMARKS.md,
"Issue 15: a compiled Radau IIA"); the implicit steps are LSODA's settled steps from the pilot (order 5
in BDF like Radau's). Where numba is present a stiff run goes to compiled Radau, not LSODA."""
PROBE_STEPS = 80
"""Accepted steps of the explicit probe (`explicit_probe`): about 1000 Python right-hand side
evaluations (~15 ms), run only where the decay's estimate would pick DOP853 on a stiff system;
the rate is taken over the second half, once the step has grown to its stability limit."""
DOP853_EVALUATIONS = 12
"""Right-hand side evaluations per DOP853 step attempt (accepted or rejected)."""
GAUSS_STAGES = (2, 3)
"""The Gauss methods the pilot chooses from: 2 stages (order 4) and 3 (order 6, about 1.5x the
evaluations a step at 2-4x the step on Kepler e = 0.5 at 1e-8..1e-10: fewer evaluations in all)."""
PILOT_ATOL = 1e-2
"""The symplectic pilot's absolute tolerance, relative to rtol (a component near zero is measured against this)."""


def resolve(
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
    projection: bool | None = None,
    stages: int | None = None,
) -> Settings:
    """`validate`, then `decide`: settings ready to run; raises `LagrangeError` on bad input."""
    settings = validate(
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
    return decide(model, settings)


def decide(model: Model, settings: Settings) -> Settings:
    """`settings` with `auto` resolved (method and backend), the symplectic step, and Baumgarte's
    alpha for kept constraints; notes say why and flag an initial state off the constraints."""
    method, backend, step, stages, rate, notes = _choose(model, settings)
    alpha = stabilisation(rate, settings.t_end) if model.constraints else None
    notes = (*notes, *constraint_notes(model, settings.values, settings.y0))
    return dataclasses.replace(settings, method=method, backend=backend, step=step, stages=stages, alpha=alpha, notes=(*settings.notes, *notes))


def stabilisation(rate: float, t_end: float) -> float:
    """Baumgarte's alpha for kept constraints: the system's own fastest rate (so that it adds
    no stiffness), at least 10 / t_end so that drift decays within the run."""
    return max(rate, 10.0 / t_end)


def initial_rate(model: Model, settings: Settings) -> float:
    """The spectral radius of the linearisation at the initial state of `settings` (0 where it
    cannot be evaluated): what the symplectic step is chosen from. Once per model and start."""

    def compute() -> float:
        found = initial_spectrum(model, settings.values, settings.y0)
        return found.rate if found is not None else 0.0

    return memo.once(model, ("initial rate", settings.values, settings.y0), compute)


def _constraint_rows(model: Model) -> Callable[..., list[list[float]]]:
    """(f, its gradient, the bias) of each kept constraint as a function of (t, q, parameters)."""
    rows = [[c.expr if c.holonomic else sp.Integer(0), *c.jacobian, c.bias] for c in model.constraints]  # a velocity row's expr has q_dot
    return sp.lambdify([model.t, *model.q, *(par.symbol for par in model.parameters)], rows, modules="math")  # type: ignore[no-any-return]


def constraint_notes(model: Model, p: Sequence[float], y0: Sequence[float]) -> list[str]:
    """A note for each kept constraint the initial state violates, in positions (f(q, 0) != 0)
    or velocities (a . q_dot + b != 0), beyond round-off relative to the sizes of its terms:
    the run then starts off the constrained motion (the stabilisation pulls it back)."""
    if not model.constraints:
        return []
    model = model.with_definitions()  # the rows are evaluated: defined functions written out
    evaluate = memo.once(model, "constraint rows", lambda: _constraint_rows(model))
    n = model.n
    q, qd = np.array(y0[:n], dtype=float), np.array(y0[n:], dtype=float)
    try:
        values = np.array(evaluate(0.0, *q, *p), dtype=float)
    except (ArithmeticError, ValueError, TypeError):
        return []
    notes = []
    for c, row in zip(model.constraints, values, strict=True):
        gradient, bias = row[1 : n + 1], row[n + 1]
        velocity = float(gradient @ qd + bias)
        off = []
        if c.holonomic and abs(row[0]) > 1e-8 * (1.0 + float(np.linalg.norm(gradient) * np.linalg.norm(q))):
            off.append(f"residual {row[0]:.3g} in the positions")
        if abs(velocity) > 1e-8 * (float(np.linalg.norm(gradient) * np.linalg.norm(qd)) + abs(bias)):
            off.append(f"{velocity:.3g} in the velocities")
        if off:
            notes.append(f"the initial state violates constraint '{c.name}' ({', '.join(off)}): the run starts off the constrained motion; give initial values that satisfy it")
    return notes


def _choose(model: Model, settings: Settings) -> tuple[str, str, float | None, int, float, tuple[str, ...]]:
    """Resolve `auto` (method and backend) and the symplectic step and stages, saying why in notes."""
    method, backend, step, t_end, rtol, p, y0 = settings.method, settings.backend, settings.step, settings.t_end, settings.rtol, settings.values, settings.y0
    notes: list[str] = []
    if method == "symplectic" and any(not c.holonomic for c in model.constraints):
        name = next(c.name for c in model.constraints if not c.holonomic)
        raise LagrangeError(
            f"{model.source}: the symplectic method cannot integrate velocity constraint '{name}': a nonholonomic system has no canonical (q, p) form; use another --method (DOP853, RK45, Radau)"
        )
    if method == "symplectic" and model.constraints:
        raise LagrangeError(f"{model.source}: the symplectic method needs a system without kept constraints; eliminate them (`eliminate:`) or use another --method")
    if step is not None and method not in ("auto", "symplectic"):
        raise LagrangeError(f"--step sets the fixed step of the symplectic method; {method} adapts its step to --rtol/--atol (use --max-step to bound it)")
    if method == "symplectic" and backend == "python":
        raise LagrangeError("the symplectic method runs only compiled (numba); drop --backend python")
    if backend == "compiled" and method in ("BDF", "LSODA"):
        raise LagrangeError(f"{method} runs through scipy; use --backend python (or auto), or --method Radau, which runs compiled too")
    needs_rates = method == "auto" or backend == "auto" or (method == "symplectic" and step is None) or bool(model.constraints)
    found = initial_spectrum(model, p, y0) if needs_rates else None
    rate = found.rate if found is not None else 0.0
    if method == "auto":
        if step is not None and not model.constraints:
            if backend == "python":
                raise LagrangeError(
                    f"{model.source}: a fixed step (simulate: step) selects the symplectic method, which runs only compiled (numba); drop --backend python, or the step to let the method adapt it"
                )
            method, why = "symplectic", "a fixed step was given"
            notes.append(f"method auto -> {method}: {why}")
        else:
            compiled = backend != "python" and compile.numba_available()
            attempt = compiled and not model.constraints and (backend == "compiled" or _backend(model, "DOP853", rate, t_end)[0] == "compiled")
            method, why = choose(model, settings, found, compiled=compiled, attempt=attempt)
            notes.append(f"method auto -> {method}: {why}")
            if attempt and method == "DOP853" and backend == "auto":
                backend = "compiled"
                notes.append("backend auto -> compiled: the compiled run `auto` started with goes on")
    if settings.method == "symplectic" and model.dissipative:
        notes.append(
            "warning: this system dissipates (a Rayleigh function), so its energy is not conserved and the symplectic method has nothing to keep:"
            " it is a fixed-step implicit Runge-Kutta method without error control, its step chosen for the fastest motion at the start even after"
            " that motion has decayed; symplectic methods are for conservative systems: use an adaptive method (--method auto, DOP853), or an implicit one (LSODA, Radau) where it is stiff"
        )
    stages = settings.stages
    if method == "symplectic" and step is None:
        step, stages, chosen = _symplectic_choice(model, found, rate, t_end, rtol, p, y0, (stages,) if stages is not None else GAUSS_STAGES)
        notes.extend(chosen)
    stages = stages if stages is not None else STAGES
    if backend == "auto":
        backend, why = _backend(model, method, rate, t_end)
        notes.append(f"backend auto -> {backend}: {why}")
    if backend == "compiled" and not compile.numba_available():
        if method == "symplectic":
            raise LagrangeError(f"the symplectic method needs numba: {compile.NUMBA_HINT}, or use another --method")
        backend = "python"
        notes.append(f"backend compiled -> python: numba is not installed ({compile.NUMBA_HINT})")
    return method, backend, step, stages, rate, tuple(notes)


def _backend(model: Model, method: str, rate: float, t_end: float) -> tuple[str, str]:
    if method not in COMPILED:
        return "python", f"{method} runs through scipy"
    if not compile.numba_available():
        if method == "symplectic":
            raise LagrangeError(f"the symplectic method needs numba: {compile.NUMBA_HINT}, or use another --method")
        return "python", "numba is not installed"
    if method == "symplectic":
        return "compiled", "the symplectic method runs compiled"
    if method == "Radau":
        return "compiled", "Radau runs compiled (an implicit step costs about 100x less than scipy's)"
    if rate * t_end > HEAVY:
        return "compiled", f"a long run (rate {rate:.3g}/s x t_end {t_end:g}): compiling pays off"
    if (compile.cache_dir() / f"lagrange_numba_{compile.fingerprint(model, 'numba', False, None)}.py").exists():
        return "compiled", "this system is compiled already (cached)"
    return "python", "a short run: compiling would cost more than it saves"


def _symplectic_choice(
    model: Model, found: diagnostics.Spectrum | None, rate: float, t_end: float, rtol: float, p: Sequence[float], y0: Sequence[float], choices: tuple[int, ...]
) -> tuple[float, int, list[str]]:
    """The symplectic step and stages from pilots (`symplectic_pilot`) started at `symplectic_step`'s guess, and notes saying how."""
    guess = symplectic_step(rate, t_end, rtol)
    if found is None:
        origin = "t_end/1000: the linearisation at the initial state could not be evaluated"
    elif rate <= 0:
        origin = "t_end/1000: the linearisation at the initial state has no rates"
    else:
        origin = f"the fastest rate at the initial state, {rate:.3g}/s, and rtol"
    pilot = symplectic_pilot(model, guess, t_end, rtol, p, y0, choices)
    if pilot is None:
        return guess, choices[0] if len(choices) == 1 else STAGES, [f"symplectic step {guess:.3g} ({origin}): no pilot run (the momenta at the initial state cannot be evaluated; give --step)"]
    notes = [
        f"symplectic step {pilot.step:.3g}, {pilot.stages} stages (order {2 * pilot.stages}) from pilot runs started at {guess:.3g} ({origin}): runs at h and h/2 over t = {pilot.span:.3g} estimate the error at t_end at "
        f"{pilot.estimate:.2g} x rtol ({pilot.steps} pilot steps), at an expected {pilot.cost:.3g} evaluations per unit time, the fewest of {', '.join(f'{s} stages' for s in choices)}; "
        "the step stays fixed (that is what makes the method symplectic)"
    ]
    if not pilot.controlled:
        notes.append(
            f"warning: the symplectic method's pilot could not find a step that meets rtol {rtol:g} (estimate {pilot.estimate:.2g} x rtol at step {pilot.step:.3g}): "
            "its error is not controlled; give a smaller --step, use an adaptive --method (DOP853, Radau), or change coordinates"
        )
    return pilot.step, pilot.stages, notes


def symplectic_pilot(model: Model, guess: float, t_end: float, rtol: float, p: Sequence[float], y0: Sequence[float], choices: tuple[int, ...] = GAUSS_STAGES) -> integrators.GaussPilot | None:
    """The pilot runs of the symplectic method from the step `guess` (integrators.pilot_gauss), for
    each stage count of `choices`, and the one whose step meets the tolerance at the fewest
    evaluations per unit time (the stage count with the best step and cost; the default STAGES when
    none meets it), once per model and start; None where the momenta cannot be evaluated at the initial state.
    `simulate` asks again (the same answer) for the yardstick of its run's monitor."""

    def compute() -> integrators.GaussPilot | None:
        python, numba = compile.build(model, "python"), compile.build(model, "numba")
        values = code_parameters(p, None)
        state = np.array(y0, dtype=float)
        try:
            momenta = integrators.evaluate(python.module._canonical, 0.0, state.tolist(), list(values), "the momenta at the initial state")
        except integrators.EvaluationError:
            return None
        z0 = np.concatenate([state[: len(state) // 2], np.array(momenta, dtype=float)])
        problem = integrators.Problem(0.0, t_end, state, np.empty(0), np.array(values, dtype=float), False, integrators.MAX_STEPS["compiled"])
        pilots = [integrators.pilot_gauss(numba, problem, z0, stages, guess, rtol, PILOT_ATOL * rtol) for stages in choices]
        controlled = [pilot for pilot in pilots if pilot.controlled and pilot.evaluations > 0.0]
        if not controlled:
            return next((pilot for pilot in pilots if pilot.stages == STAGES), pilots[0])
        return min(controlled, key=lambda pilot: pilot.cost)

    return memo.once(model, ("symplectic pilot", guess, t_end, rtol, tuple(p), tuple(y0), choices), compute)


def chosen_pilot(model: Model, settings: Settings) -> integrators.GaussPilot | None:
    """The pilot that chose the step of `settings` (None when the step was given, or for another method)."""
    if settings.method != "symplectic" or settings.step is None:
        return None
    guess = symplectic_step(initial_rate(model, settings), settings.t_end, settings.rtol)
    store = model.__dict__.get(memo.SLOT, {})
    for choices in (GAUSS_STAGES, (settings.stages,)):  # the stages were chosen, or given
        pilot = store.get(("symplectic pilot", guess, settings.t_end, settings.rtol, tuple(settings.values), tuple(settings.y0), choices))
        if pilot is not None and pilot.step == settings.step and pilot.stages == settings.stages:
            return pilot
    return None


def symplectic_step(rate: float, t_end: float, rtol: float) -> float:
    """A step for the order-4 Gauss method: h * rate = 2 rtol^(1/4), the local energy error then
    being about rtol; at most t_end / 100."""
    if rate <= 0:
        return t_end / 1000
    return min(t_end / 100, 2.0 * rtol**0.25 / rate)


def initial_spectrum(model: Model, p: Sequence[float], y0: Sequence[float], tangent: np.ndarray | None = None) -> diagnostics.Spectrum | None:
    """The rates of the linearisation at y0 for the model's parameter values `p` (None where the
    right-hand side cannot be evaluated); the same diagnosis `lagrange stress` makes along a
    trajectory. Kept constraints without stabilisation (alpha = 0): alpha is chosen from these rates.

    `tangent` (n x k, orthonormal columns: the coordinate directions the kept constraints leave free at q0),
    the rates of the motion along the constraints only, the linearisation taken on (tangent dq, tangent dv):
    the directions across them, which the constraints hold at 0, add a double zero rate that forward differences
    turn into a spurious slow mode (the Cartesian pendulum with a multiplier at rest: 2.7e-4/s beside its 2.2/s)."""
    functions = compile.build(model, "python")
    rhs = safe_rhs(functions.module, code_parameters(p, 0.0 if model.constraints else None))
    return diagnostics.spectrum_at(rhs, 0.0, np.array(y0, dtype=float), tangent)


def safe_rhs(module: object, p: tuple[float, ...]) -> Callable[[float, np.ndarray], np.ndarray | None]:
    """The right-hand side f(t, y) of a generated Python module, None where it cannot be evaluated."""
    accel, n = module._accel, module._N  # type: ignore[attr-defined]

    def rhs(t: float, y: np.ndarray) -> np.ndarray | None:
        try:
            x = accel(t, y.tolist(), list(p))
        except (ArithmeticError, ValueError, TypeError):
            return None
        return np.array(y.tolist()[n:] + x[:n])

    return rhs


@dataclasses.dataclass(frozen=True)
class Pilot:
    """What a short pilot run measured (see the module docstring)."""

    steps: int
    t_reached: float
    finished: bool
    worst: diagnostics.Spectrum
    """The sampled spectrum with the fastest unmatched decay (the initial one when none decays), its
    slowest rate the median of the sampled ones where that is lower (so that the stiffness ratio
    compares the fastest decay with the motion, not with that state's other fast modes)."""
    t_worst: float
    """Where that spectrum was sampled."""
    settled_step: float
    """LSODA's mean step over the pilot's last PILOT_TAIL steps (after its last switch of method, when it switched)."""
    spectra: int
    y_reached: tuple[float, ...] = ()
    """The state at t_reached."""
    switches: int = 0
    """Times LSODA switched between Adams (non-stiff) and BDF (stiff) along the pilot."""
    bdf: bool | None = None
    """Whether LSODA stepped with BDF (it judged the problem stiff) at the end of the pilot; None where unknown."""
    followed: float = 0.0
    """The fastest decay sampled that was the solution's own motion (`diagnostics.Spectrum.followed`), not stiffness."""

    def implicit_steps(self, t_end: float) -> float:
        """The steps an implicit method takes over the run: the pilot's, then the rest at its settled step."""
        if self.finished or self.settled_step <= 0:
            return float(self.steps)
        return self.steps + (t_end - self.t_reached) / self.settled_step

    def explicit_steps(self, t_end: float) -> float:
        """The steps DOP853 needs just to stay stable: decay x t_end / DOP853_STABILITY."""
        return self.worst.decay * t_end / DOP853_STABILITY


def pilot(model: Model, settings: Settings) -> Pilot | None:
    """PILOT_STEPS steps (more while its step grows) of LSODA (Python right-hand side, no Jacobian) from the
    initial state of `settings`, the spectrum sampled at the start and at PILOT_SPECTRA states
    along it; None where the right-hand side or a Jacobian cannot be evaluated at the start.
    Once per model, parameters, start, horizon and tolerances."""
    key = ("pilot", settings.values, settings.y0, settings.t_end, settings.rtol, settings.atol)
    return memo.once(model, key, lambda: _pilot(model, settings))


class _Unevaluable(Exception):
    pass


def _pilot(model: Model, settings: Settings) -> Pilot | None:
    import warnings

    import scipy.integrate

    functions = compile.build(model, "python")
    rhs = safe_rhs(functions.module, code_parameters(settings.values, 0.0 if model.constraints else None))
    y0 = np.array(settings.y0, dtype=float)
    start = diagnostics.spectrum_at(rhs, 0.0, y0)
    if start is None:
        return None

    def f(t: float, y: np.ndarray) -> np.ndarray:
        value = rhs(t, y)
        if value is None or not np.all(np.isfinite(value)):
            raise _Unevaluable
        return value

    worst, t_worst, spectra, followed = start, 0.0, 0, start.followed
    last_followed = [start.followed]  # the fastest decay that was the solution's own motion at the last state sampled
    slowest = [start.slowest] if start.slowest > 0 else []
    times = [0.0]
    every = max(1, PILOT_STEPS // PILOT_SPECTRA)

    method: list[int | None] = [None]  # LSODA's current method: 1 Adams, 2 BDF
    switched = [0, 0]  # switches, the step count at the last one

    def growing() -> bool:
        if len(times) <= 2 * PILOT_TAIL:
            return True
        recent, before = times[-1] - times[-1 - PILOT_TAIL], times[-1 - PILOT_TAIL] - times[-1 - 2 * PILOT_TAIL]
        return recent > SETTLED * before

    def unsettled() -> bool:
        """LSODA still in Adams on a problem that looks stiff, or just switched: its step is not yet that of its method;
        or still in a fast transient: at the last state sampled the solution itself changed as fast as a decay that would
        be stiff over the run (`diagnostics.own_rate`), so whether that decay is stiffness shows only once it is over
        (the damped spring of k = 1e10 in r started at r = 0.01: 200 steps at rtol 1e-7 reach t = 1.2e-4, in the transient)."""
        adams_on_stiff = method[0] == 1 and diagnostics.stiff(worst, settings.t_end)
        transient = last_followed[0] * settings.t_end > diagnostics.STIFF
        return adams_on_stiff or transient or (switched[0] > 0 and len(times) - 1 - switched[1] < 2 * PILOT_TAIL)

    y_reached = y0
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        try:
            solver = scipy.integrate.LSODA(f, 0.0, y0, settings.t_end, rtol=settings.rtol, atol=settings.atol, max_step=settings.max_step)
            while solver.status == "running" and (len(times) <= PILOT_STEPS or (len(times) <= PILOT_MAX_STEPS and (growing() or unsettled()))):
                solver.step()
                if solver.status == "failed" or not np.all(np.isfinite(solver.y)):
                    break
                times.append(float(solver.t))
                y_reached = np.array(solver.y, dtype=float)
                now = _lsoda_method(solver)
                if now is not None and method[0] is not None and now != method[0]:
                    switched[0], switched[1] = switched[0] + 1, len(times) - 1
                method[0] = now
                if (len(times) - 1) % every == 0 or solver.status != "running":
                    sampled = diagnostics.spectrum_at(rhs, float(solver.t), np.array(solver.y, dtype=float))
                    spectra += 1
                    if sampled is not None and sampled.slowest > 0:
                        slowest.append(sampled.slowest)
                    last_followed[0] = sampled.followed if sampled is not None else 0.0
                    followed = max(followed, last_followed[0])
                    if sampled is not None and sampled.decay > worst.decay:
                        worst, t_worst = sampled, float(solver.t)
        except _Unevaluable:
            pass
    if slowest and worst.decay > 0:  # the motion's typical slowest rate, not that at the worst state alone (a violent start: 1e5/s there, 3/s along the rest)
        worst = dataclasses.replace(worst, slowest=min(worst.slowest, float(np.median(slowest))))
    steps = len(times) - 1
    since = steps - switched[1] if switched[0] > 0 else steps
    tail = min(PILOT_TAIL, since if since > 0 else steps)
    settled = (times[-1] - times[-1 - tail]) / tail if tail > 0 else 0.0
    bdf = None if method[0] is None else method[0] == 2
    return Pilot(steps, times[-1], times[-1] >= settings.t_end, worst, t_worst, settled, spectra, tuple(float(v) for v in y_reached), switches=switched[0], bdf=bdf, followed=followed)


def _lsoda_method(solver: object) -> int | None:
    """The method scipy's LSODA steps with now (ODEPACK's MCUR, IWORK(20): 1 Adams, 2 BDF); None where scipy does not expose it."""
    try:
        value = int(solver._lsoda_solver._integrator.iwork[19])  # type: ignore[attr-defined]
    except (AttributeError, IndexError, TypeError, ValueError):
        return None
    return value if value in (1, 2) else None


@dataclasses.dataclass(frozen=True)
class Probe:
    """What a short run of DOP853 (scipy's, Python) measured from where the pilot ended."""

    t0: float
    t_reached: float
    steps: int
    evaluations: int
    rate: float
    """Step attempts (accepted and rejected: evaluations / DOP853_EVALUATIONS) per unit time over the probe's second half."""
    failed: bool
    """The probe could not go on (an evaluation failed, or the step collapsed)."""

    def attempts(self, t_end: float) -> float:
        """DOP853's step attempts over the run, at the probe's rate (inf when the probe failed)."""
        if self.failed:
            return math.inf
        if self.t_reached >= t_end:
            return self.evaluations / DOP853_EVALUATIONS
        return self.rate * t_end


def explicit_probe(model: Model, settings: Settings, measured: Pilot) -> Probe:
    """PROBE_STEPS steps of scipy's DOP853 from the pilot's last state (from the start when the
    pilot finished the run), counting right-hand side evaluations: the steps DOP853 really takes
    where the system is stiff, rejections included. Once per model and settings."""
    key = ("explicit probe", settings.values, settings.y0, settings.t_end, settings.rtol, settings.atol, measured.t_reached)
    return memo.once(model, key, lambda: _explicit_probe(model, settings, measured))


def _explicit_probe(model: Model, settings: Settings, measured: Pilot) -> Probe:
    import warnings

    import scipy.integrate

    functions = compile.build(model, "python")
    rhs = safe_rhs(functions.module, code_parameters(settings.values, 0.0 if model.constraints else None))
    t0, y0 = (0.0, np.array(settings.y0, dtype=float)) if measured.finished or not measured.y_reached else (measured.t_reached, np.array(measured.y_reached))
    count = [0]

    def f(t: float, y: np.ndarray) -> np.ndarray:
        count[0] += 1
        value = rhs(t, y)
        if value is None or not np.all(np.isfinite(value)):
            raise _Unevaluable
        return value

    times, evaluations, failed = [t0], [0], False
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        try:
            solver = scipy.integrate.DOP853(f, t0, y0, settings.t_end, rtol=settings.rtol, atol=settings.atol, max_step=settings.max_step)
            evaluations[0] = count[0]
            while solver.status == "running" and len(times) <= PROBE_STEPS:
                solver.step()
                if solver.status == "failed" or not np.all(np.isfinite(solver.y)):
                    failed = True
                    break
                times.append(float(solver.t))
                evaluations.append(count[0])
        except _Unevaluable:
            failed = True
    half = len(times) // 2
    span = times[-1] - times[half]
    rate = (evaluations[-1] - evaluations[half]) / DOP853_EVALUATIONS / span if span > 0 else math.inf
    return Probe(t0, times[-1], len(times) - 1, count[0], rate, failed or not math.isfinite(rate))


ATTEMPT_STEPS = 10000
"""Steps the compiled DOP853 run that `auto` starts with (`explicit_attempt`) may take before the
pilot decides: about 10 ms on a small system (0.9-1.3 us a step attempt), the cost of a pilot
run, so that a run just longer than this costs at most about twice itself with the pilot added,
and a stiff run the test missed wastes no more than the pilot. A run that needs no more is done by
then. Also the explicit steps left, at DOP853's stability-limited step, below which a stiff run
goes on explicitly: fewer than an implicit run's cost (IMPLICIT_COST x ~500 steps at the least)."""
CHECK_STEPS = 1000
"""The attempt looks at its progress after every this many steps ..."""
LONG_STEPS = 3 * ATTEMPT_STEPS
"""... and hands over to the pilot as soon as its steps so far and the rest of the run at the rate of
its last CHECK_STEPS steps come to more than these: a run this long will not finish within ATTEMPT_STEPS,
the pilot costs a third of it at most, and a stiff run that Hairer's test misses (the elastic pendulum
in r: round-off in the stiff terms keeps the accepted steps at h |lambda| ~ 2-4, a third of the steps
rejected) is caught after CHECK_STEPS steps rather than ATTEMPT_STEPS."""
MEASURE_STEPS = 2000
"""Steps the paused run goes on (stiffness test off) to measure what compiled DOP853 really costs
per unit time on a mildly stiff problem (`measure_attempt`), rejected steps included."""
_ATTEMPT_SLOT = "_explicit_attempt"
"""Where the live attempt waits (on the model) for `simulate` to take it up (`take_attempt`)."""


@dataclasses.dataclass(frozen=True)
class Attempt:
    """What the compiled DOP853 run that `auto` starts with measured (see `explicit_attempt`)."""

    code: int
    """Its status code so far (status.RUNNING while it is paused)."""
    t: float
    steps: int
    rejected: int
    stiff_at: float | None
    """Where Hairer's stiffness test found the steps limited by stability (None: it did not)."""
    h_lambda: float
    """The last h |lambda| the test measured."""
    step: float
    """The next step size (at the stability limit where the test found stiffness)."""
    rate: float | None = None
    """Step attempts per unit time over a stretch run on past the stiffness (`measure_attempt`), rejected steps included."""
    projected: float = math.nan
    """The steps of the whole run, projected from the last CHECK_STEPS (see LONG_STEPS)."""

    @property
    def ended(self) -> bool:
        return self.code != status.RUNNING

    def left(self, t_end: float) -> float:
        """The explicit steps left to t_end at the current step (at `rate` once measured)."""
        if self.ended:
            return 0.0
        if self.rate is not None:
            return self.rate * (t_end - self.t)
        return (t_end - self.t) / self.step if self.step > 0 else math.inf


def _attempt_key(settings: Settings) -> tuple[object, ...]:
    return ("explicit attempt", settings.t0, settings.t_end, settings.rtol, settings.atol, settings.max_step, settings.t_eval, settings.parameters, settings.y0, settings.until)


def _summary(loop: integrators.ErkLoop, stiff_at: float | None, rate: float | None = None) -> Attempt:
    stats = loop.stats
    return Attempt(loop.code, loop.t, loop.steps, int(stats[status.NREJECT]), stiff_at, float(stats[status.H_LAMBDA]), float(loop.state[status.H]), rate)


def explicit_attempt(model: Model, settings: Settings) -> Attempt:
    """Start the run itself with compiled DOP853 and Hairer's stiffness test (dop853.f: h |lambda|
    estimated from the last stage and the new solution, above 6.1 on 15 accepted steps): at most
    ATTEMPT_STEPS steps. Finished (or stopped at its event, or failed): that is the run. Stiff, or
    over ATTEMPT_STEPS: paused, for the pilot to decide. The live run waits on the model for
    `simulate` (`take_attempt`), which goes on from where it stopped. Once per model and settings."""
    return memo.once(model, _attempt_key(settings), lambda: _explicit_attempt(model, settings))


def _explicit_attempt(model: Model, settings: Settings) -> Attempt:
    numba = compile.build(model, "numba", event=settings.event)
    problem = integrators.Problem(
        settings.t0, settings.t_end, np.array(settings.y0, dtype=float), np.array(settings.t_eval, dtype=float), np.array(settings.p, dtype=float), settings.event is not None
    )
    loop = integrators.ErkLoop(numba, problem, "DOP853", settings.rtol, settings.atol, settings.max_step)
    projected = math.nan
    while not loop.ended and not loop.stiff and loop.steps < ATTEMPT_STEPS:
        t, steps = loop.t, loop.steps
        loop.advance(min(CHECK_STEPS, ATTEMPT_STEPS - steps), stiffness=True)
        span = loop.t - t
        projected = loop.steps + (settings.t_end - loop.t) * (loop.steps - steps) / span if span > 0 else math.inf
        if projected > LONG_STEPS:  # a long run: the pilot costs little beside it, and a stiff one the test misses wastes no more steps
            break
    model.__dict__[_ATTEMPT_SLOT] = (_attempt_key(settings), loop)
    return dataclasses.replace(_summary(loop, loop.t if loop.stiff and not loop.ended else None), projected=projected)


def measure_attempt(model: Model, settings: Settings, found: Attempt) -> Attempt:
    """Run the paused attempt on (stiffness test off) for up to MEASURE_STEPS more steps and measure its
    step attempts per unit time, rejected steps included: what compiled DOP853 really costs on a stiff
    problem (round-off in the stiff terms or a double eigenvalue at the stability limit make it 2-6x
    the decay's estimate, a third of them rejected). Once per model and settings."""

    def compute() -> Attempt:
        stash = model.__dict__.get(_ATTEMPT_SLOT)
        if stash is None or stash[0] != _attempt_key(settings) or stash[1].ended:
            return found
        loop = stash[1]
        t, attempts = loop.t, loop.attempts
        loop.advance(MEASURE_STEPS)
        span = loop.t - t
        rate = (loop.attempts - attempts) / span if span > 0 else math.inf
        return _summary(loop, found.stiff_at, rate)

    return memo.once(model, ("measured attempt", *_attempt_key(settings)), compute)


def take_attempt(model: Model, settings: Settings, problem: integrators.Problem) -> integrators.ErkLoop | None:
    """The compiled DOP853 run `auto` started for these settings (`explicit_attempt`), taken from the
    model (once: a later run starts afresh), if it runs the same problem; None otherwise."""
    stash = model.__dict__.get(_ATTEMPT_SLOT)
    if stash is None or stash[0] != _attempt_key(settings):
        return None
    del model.__dict__[_ATTEMPT_SLOT]
    loop: integrators.ErkLoop = stash[1]
    mine = loop.problem
    same = (
        mine.t0 == problem.t0
        and mine.t_end == problem.t_end
        and mine.use_event == problem.use_event
        and np.array_equal(mine.y0, problem.y0)
        and np.array_equal(mine.ts, problem.ts)
        and np.array_equal(mine.p, problem.p)
    )
    if not same:
        return None
    loop.problem = dataclasses.replace(mine, max_steps=problem.max_steps, pace=problem.pace)
    return loop


def choose(model: Model, settings: Settings, found: diagnostics.Spectrum | None, compiled: bool, attempt: bool = False) -> tuple[str, str]:
    """(method, why) for `--method auto` (see the module docstring): with `attempt` (compiled DOP853
    can run it), from the compiled run started with a stiffness test (`explicit_attempt`) first; then
    from a pilot run; from the linearisation at the initial state (`found`, `diagnostics.choose`) where
    the pilot cannot run."""
    t_end = settings.t_end
    tried = explicit_attempt(model, settings) if attempt else None
    test = f"Hairer's stiffness test: h |lambda| > {status.STIFF_H_LAMBDA:g} on {status.STIFF_STEPS} steps"
    if tried is not None and tried.code in (status.DONE, status.EVENT):
        end = "finished" if tried.code == status.DONE else "reached the stop condition"
        return "DOP853", f"the compiled DOP853 run itself {end} in {tried.steps} steps ({tried.rejected} rejected) without its steps being limited by stability ({test}): no pilot needed"
    if tried is not None and tried.stiff_at is not None and tried.steps + tried.left(t_end) <= ATTEMPT_STEPS:
        return "DOP853", (
            f"stiff from t = {tried.stiff_at:.3g} ({test}; h |lambda| = {tried.h_lambda:.3g}), but the compiled DOP853 run needs only about "
            f"{tried.left(t_end):.3g} more steps at its step {tried.step:.3g} after {tried.steps}: fewer than {ATTEMPT_STEPS}, cheaper than an implicit run; it goes on from t = {tried.t:.3g}"
        )
    goes_on, dropped = "", ""
    if tried is not None and not tried.ended:
        if tried.stiff_at is not None:
            seen = f"its steps limited by stability from t = {tried.stiff_at:.3g}"
        elif tried.projected > LONG_STEPS:
            seen = f"no stiffness found in {tried.steps} steps, but about {tried.projected:.3g} steps projected for the run"
        else:
            seen = f"no stiffness in {tried.steps} steps"
        goes_on = f"; the compiled DOP853 run started first ({seen}) goes on from t = {tried.t:.3g}"
        dropped = f"; the compiled DOP853 run started first ({seen}) is dropped at t = {tried.t:.3g}"
    implicit_method, cost, costs = _implicit(compiled)
    measured = pilot(model, settings)
    if measured is None:
        method, why = diagnostics.choose(found, t_end, compiled=compiled)
        return (implicit_method if method == "Radau" else method), why + (goes_on if method == "DOP853" else dropped)
    worst = measured.worst
    where = f"at t = {measured.t_worst:.3g}" if measured.t_worst > 0 else "at the start"
    span = f"a pilot run of {measured.steps} LSODA steps to t = {measured.t_reached:.3g}, {measured.spectra + 1} Jacobians sampled"
    if not diagnostics.stiff(worst, t_end):
        own = f"; decays of up to {measured.followed:.3g}/s are the solution's own motion (within {diagnostics.OWN:g} x the rate it changes at there)" if measured.followed > worst.decay else ""
        if worst.decay > 0:
            return (
                "DOP853",
                f"not stiff along {span}: fastest unmatched decay {worst.decay:.3g}/s ({where}) x t_end {t_end:g} = {worst.decay * t_end:.3g}, slowest rate {worst.slowest:.3g}/s{own}{goes_on}",
            )
        return "DOP853", f"not stiff along {span}: no decaying mode faster than the motion (fastest rate {worst.rate:.3g}/s){own}{goes_on}"
    explicit, implicit = measured.explicit_steps(t_end), measured.implicit_steps(t_end)
    lsoda = f"about {implicit:.3g} LSODA steps (its step settled to {measured.settled_step:.3g} over {span}{', in BDF' if measured.bdf else ''})"
    numbers = f"decay {worst.decay:.3g}/s ({where}) x t_end {t_end:g}: about {explicit:.3g} stability-limited DOP853 steps, against {lsoda}"
    if not compiled:
        return "LSODA", f"stiff: {numbers}; explicit methods cannot run compiled here"
    if tried is not None and not tried.ended and switching.located(compile.build(model, "python").module):
        # switching surfaces (a contact, a one-sided wall): the pilot's decay is a contact's, a transient, not the
        # whole run's; the compiled run's measured cost decides (issue 15: on the ball in the cup LSODA, 1e-3 off
        # at rtol 1e-8 with every crossing located, ran out of its budget where compiled DOP853 finished)
        return _measured_choice(model, settings, tried, worst, where, lsoda, implicit)
    if explicit > cost * implicit:
        return implicit_method, f"stiff: {numbers}; {costs}{dropped}"
    if tried is not None and not tried.ended:
        return _measured_choice(model, settings, tried, worst, where, lsoda, implicit)
    probe = explicit_probe(model, settings, measured)
    attempts = probe.attempts(t_end)
    tried_text = (
        f"a DOP853 probe of {probe.steps} steps from t = {probe.t0:.3g} failed"
        if probe.failed
        else f"a DOP853 probe of {probe.steps} steps from t = {probe.t0:.3g} ({probe.evaluations} evaluations, rejected steps included) extrapolates to {attempts:.3g} step attempts"
    )
    numbers = f"decay {worst.decay:.3g}/s ({where}) x t_end {t_end:g}; {tried_text}, against {lsoda}"
    if attempts <= cost * implicit:
        return "DOP853", f"mildly stiff: {numbers}; compiled explicit steps are cheaper ({costs})"
    return implicit_method, f"stiff: {numbers}; {costs}"


def _implicit(compiled: bool) -> tuple[str, float, str]:
    """The implicit method `auto` picks for a stiff run, what one of its steps costs in compiled DOP853
    step attempts, and that said in words: compiled Radau where numba runs (RADAU_COST), else LSODA
    (IMPLICIT_COST: scipy's, with the Python right-hand side)."""
    if compiled:
        return "Radau", RADAU_COST, f"a compiled Radau step costs ~{RADAU_COST:g} compiled explicit steps"
    return "LSODA", IMPLICIT_COST, f"an implicit step costs ~{IMPLICIT_COST:g} compiled explicit steps"


def _measured_choice(model: Model, settings: Settings, tried: Attempt, worst: diagnostics.Spectrum, where: str, lsoda: str, implicit: float) -> tuple[str, str]:
    """Mildly stiff by the decay's estimate: the paused compiled run goes on for up to MEASURE_STEPS
    steps (`measure_attempt`), and its measured cost of the rest of the run decides against a whole implicit run."""
    t_end = settings.t_end
    found = measure_attempt(model, settings, tried)
    if found.code in (status.DONE, status.EVENT):
        return (
            "DOP853",
            f"mildly stiff (decay {worst.decay:.3g}/s {where}): the compiled DOP853 run, gone on past the stiffness, finished in {found.steps} steps ({found.rejected} rejected), against {lsoda}",
        )
    implicit_method, cost, costs = _implicit(True)
    if found.ended:
        return implicit_method, f"mildly stiff (decay {worst.decay:.3g}/s {where}): the compiled DOP853 run failed at t = {found.t:.3g}; {lsoda}"
    attempts = found.left(t_end)  # what is done is paid for either way: the attempts left against a whole implicit run
    numbers = (
        f"decay {worst.decay:.3g}/s ({where}) x t_end {t_end:g}; the compiled DOP853 run, gone on to t = {found.t:.3g} ({found.steps} steps, {found.rejected} rejected), "
        f"needs about {attempts:.3g} more step attempts at its measured rate, against {lsoda}"
    )
    if attempts <= cost * implicit:
        return "DOP853", f"mildly stiff: {numbers}; compiled explicit steps are cheaper ({costs}); it goes on from there"
    return implicit_method, f"stiff: {numbers}; {costs}"
