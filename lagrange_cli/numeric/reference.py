"""What a study measures against: the file's exact solution, or a computed reference confirmed by a
second method, and how nearby trajectories part (`Horizon`: chaos cuts the measured window).

The reference is the file's `exact:` solution when it has one for every coordinate (and the
initial state is the file's), else, for a linear system without a drive, its exact solution exp(A t)
(`linear_reference`), otherwise a run at the reference tolerance confirmed by a second,
different method; their largest disagreement is the reference's own error (where the second method,
confirming at a looser rtol, leaves it above 0.1 x the accuracy, the primary's own method at 10 x and
100 x its rtol may show the error converging with the tolerance: `_converged`). A reference run that
fails is a failed numerical run (`ReferenceFailed`, exit 1 with its time, state and cause), not bad
input.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from lagrange_cli.errors import LagrangeError
from lagrange_cli.inputs import substitute
from lagrange_cli.model import Model
from lagrange_cli.numeric import compile, diagnostics, integrators, memo, policy, switching
from lagrange_cli.numeric.codegen import real_diff
from lagrange_cli.numeric.runs import (
    COMPILED_STEPS,
    PACE_MARGIN,
    TIGHTEST,
    Candidate,
    Setup,
    Unaffordable,
    atol_for,
    backend_for,
    compiled_radau,
    component_scale,
    over_step_budget,
    run,
    run_steps,
    scaled_errors,
    settings_for,
    start_of,
    step_factor,
    tol_text,
)
from lagrange_cli.numeric.settings import Settings, code_parameters
from lagrange_cli.numeric.simulate import Trajectory, coordinates_end, integrate, state_text
from lagrange_cli.numeric.status import MAX_FACTOR, Status
from lagrange_cli.numeric.tableaux import EXPLICIT

HORIZON_THRESHOLD = 1e-3  # separation (scaled) at which nearby trajectories have parted
CHAOS_GROWTH = 100.0  # growth over the second half of the time to part, above which it is exponential
HORIZON_SAMPLES = 8001  # samples of the two runs that measure how nearby trajectories part (4 x the study's, at most this)


class ReferenceFailed(LagrangeError):
    """The reference run failed or ran out of its step budget: a failed numerical run (exit 1),
    the message naming the time, the state and the cause. `blowup`: every reference method that
    was tried failed by a blow-up or a singular matrix (not by its step budget), near the same time,
    so that the failure is the system's, not the methods'; `coordinates`: they stopped where the coordinates end (a
    stall, or a singular mass matrix at a state the motion reaches with bounded kinetic energy: `simulate.coordinates_end`),
    where no method in them can go, but the motion does; `trajectory`: the samples the primary run reached (for a
    diagnosis along them)."""

    exit_code = 1

    def __init__(self, message: str, *, blowup: bool = False, coordinates: bool = False, trajectory: Trajectory | None = None, attempts: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.blowup = blowup
        self.coordinates = coordinates or (trajectory is not None and trajectory.outcome == Status.STALLED and not blowup)
        self.trajectory = trajectory
        self.attempts = attempts


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
    settings: Settings | None = field(default=None, compare=False, repr=False)
    """What the primary reference run ran (to run parts of it again, densely: `dense`)."""
    confirmed_rtol: float = field(default=math.nan, compare=False)
    """The rtol of the run that confirmed it (nan: exact, or unconfirmed)."""
    confirmation: str = field(default="", compare=False)
    """How it was confirmed, for people ("RK45 (compiled) at the same tolerance"; "" when exact)."""
    confirmer: Candidate | None = field(default=None, compare=False)
    """The method (and backend) of the run that confirmed it (None: exact, or unconfirmed)."""
    convergence: float = field(default=math.nan, compare=False)
    """The disagreement of the primary's own method at CONVERGENCE_STEP x its rtol, where it is the own error
    (above the confirmation's: `_floored`); nan otherwise."""


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


def exact_reference(model: Model, setup: Setup) -> Reference | None:
    """The file's exact solution at the study's times, when it covers every coordinate and the
    initial state is the file's own (None otherwise)."""
    import sympy as sp

    if setup.initial or set(model.exact) != set(model.coordinates):
        return None
    s = start_of(model, setup)
    values = {p.symbol: v for p, v in zip(model.parameters, s.values, strict=True)}
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
        energy = _energies(module, times, y, list(s.p))
    except integrators.EvaluationError:
        return None
    return Reference("exact", "the file's exact solution", 0.0, times, y, energy, 0.0)


def _energies(module: object, times: np.ndarray, y: np.ndarray, p: list[float]) -> np.ndarray:
    """The energy function at each sample of a reference (integrators.EvaluationError where it cannot be evaluated)."""
    return np.array([integrators.evaluate(module._energy, ti, yi.tolist(), p, "the energy")[0] for ti, yi in zip(times.tolist(), y, strict=True)])  # type: ignore[attr-defined]


LINEAR_FLOOR = 100.0
"""A linear reference's own error is at least this x the double's epsilon x ||A||_1 x t_end: the phase error that
rounding A's entries and the exponential's own error leave after t_end (the harmonic oscillator over t = 20 against
its closed form: 1.2e-12 off, 60 x eps ||A||_1 t)."""
LINEAR_MARGIN = 4.0
"""... and at least this x the largest disagreement of the exponential at each time with the stepped one (the same
oscillator: 5.9e-13 apart, 6.0e-13 off the closed form, scaled)."""


def linear_reference(model: Model, setup: Setup) -> Reference | None:
    """The exact solution of a linear, autonomous system (`linear`, and t in neither M nor F): with
    y = (q, q_dot), y' = A y + b, so (y, 1) at t is exp(B t) (y0, 1), B = [[A, b], [0, 0]] (A the
    constant Jacobian, b the right-hand side at y = 0). Each sample is made of exponentials of B (scipy's
    scaling and squaring) that no other sample's error enters (`_exponential`); it is confirmed by
    stepping from sample to sample with exp(B h), whose rounding errors add up along the run, and
    its own error is LINEAR_MARGIN x their largest disagreement, at least LINEAR_FLOOR x eps x ||A||_1 x t_end. None
    (a computed reference instead) where the system is not such, or the solution grows past what a
    double holds."""
    if not autonomous_linear(model):
        return None
    began = time.perf_counter()
    s = start_of(model, setup)
    module = compile.build(model, "python", jacobian=True).module
    p = list(s.p)
    size = 2 * model.n
    times = np.array(setup.times, dtype=float)
    if len(times) == 0:
        return None
    try:
        with np.errstate(all="ignore"):
            a = np.asarray(module._jac(0.0, [0.0] * size, p), dtype=float)
            b = np.array([0.0] * model.n + list(module._accel(0.0, [0.0] * size, p))[: model.n])
            augmented = np.zeros((size + 1, size + 1))
            augmented[:size, :size], augmented[:size, size] = a, b
            z0 = np.array([*s.y0, 1.0])
            y, stepped, offset = _exponential(augmented, z0, times - s.t0)  # autonomous: exp(B (t - t0)) from the start
    except (ArithmeticError, ValueError, TypeError, np.linalg.LinAlgError):
        return None
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(stepped)) and np.all(np.isfinite(a))):
        return None
    if np.max(np.abs(y[0] - np.array(s.y0))) > 1e-12 * max(1.0, float(np.max(np.abs(y[0])))):
        return None  # the samples do not start at the start (a window that begins later)
    norm = float(np.linalg.norm(a, 1))  # the times a grid point is off its sample time move the solution by at most about offset x ||A||_1 (scaled)
    floor = LINEAR_FLOOR * float(np.finfo(float).eps) * norm * float(times[-1] - times[0]) + offset * norm
    own = max(LINEAR_MARGIN * float(np.max(scaled_errors(stepped, y, component_scale(y)))), floor)
    try:
        energy = _energies(module, times, y, p)
    except integrators.EvaluationError:
        return None
    description = "the exact solution of the linear equations, exp(A t) at each time, confirmed by stepping with exp(A h) from sample to sample"
    return Reference("linear", description, own, times, y, energy, time.perf_counter() - began)


def _exponential(matrix: np.ndarray, z0: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """exp(matrix t) z0 at the `times` (the state less its last entry), two ways: each time on its own, and stepped
    from sample to sample, with the largest offset of the times from the grid used. Evenly spaced times (what a study
    samples) t_k = (j m + i) h are exp(matrix j m h) exp(matrix i h) z0, about 2 sqrt(N) exponentials rather than N,
    none carrying another's error, and the stepped ones exp(matrix h) applied k times; other times take one
    exponential each."""
    from scipy.linalg import expm

    size = len(z0) - 1
    count = len(times)
    span = float(times[-1] - times[0]) if count > 1 else 0.0
    h = span / (count - 1) if count > 1 else 0.0
    k = np.arange(count)
    offset = float(np.max(np.abs(times - (times[0] + k * h)))) if count > 1 else 0.0
    if count < 3 or times[0] != 0.0 or offset > 1e-12 * max(span, 1e-300):
        direct = expm(matrix[None] * times[:, None, None]) @ z0
        steps = expm(matrix[None] * np.diff(times)[:, None, None])
        offset = 0.0
    else:
        m = math.isqrt(count - 1) + 1
        inner = expm(matrix[None] * (np.arange(m) * h)[:, None, None]) @ z0  # exp(matrix i h) z0, i < m
        outer = expm(matrix[None] * (np.arange((count - 1) // m + 1) * (m * h))[:, None, None])  # exp(matrix j m h)
        direct = np.einsum("kab,kb->ka", outer[k // m], inner[k % m])
        steps = np.broadcast_to(expm(matrix * h), (count - 1, *matrix.shape))
    stepped = np.empty_like(direct)
    z = z0
    stepped[0] = z
    for j, step in enumerate(steps, start=1):
        z = step @ z
        stepped[j] = z
    return direct[:, :size], stepped[:, :size], offset


def autonomous_linear(model: Model) -> bool:
    """`linear`, t in neither M nor F (no drive), and F a polynomial of degree at most 1 in the state: y' = A y + b
    with A and b constant. The last is not `linear`'s test, which differentiates as the generated Jacobian does (the
    derivative of sign(u) taken as 0): dry friction mu m g sign(v0 - x_dot) passes it, and exp(A t) would be wrong."""

    def compute() -> bool:
        import sympy as sp

        if not linear(model):
            return False
        forms = substitute(model).with_definitions().symengine
        if any(forms.t in entry.free_symbols for entry in (*forms.forcing, *(e for row in forms.mass for e in row))):
            return False
        state = [sp.sympify(v) for v in (*forms.q, *forms.qd)]
        for entry in forms.forcing:
            expression = sp.expand(sp.sympify(entry))
            if not expression.is_polynomial(*state) or sp.Poly(expression, *state).total_degree() > 1:
                return False
        return True

    return memo.once(model, ("autonomous linear",), compute)


IMPLICIT = ("Radau", "BDF", "LSODA")


def reference_candidates(model: Model, setup: Setup, tolerance: float) -> tuple[Candidate, Candidate]:
    """The primary reference method and a different second one: compiled DOP853 confirmed by
    compiled RK45 when numba is there (fast even when mildly stiff: stability only costs steps),
    unless the system is stiff (`stiff_start`): then Radau confirmed by BDF; without numba, what
    `auto` picks (Radau when stiff, else DOP853) confirmed by LSODA, whose high-order Adams and BDF
    formulas stay affordable at tight tolerances where scipy's Radau and RK45, stepping in Python,
    do not."""
    if stiff_start(model, setup):
        return Candidate("Radau"), Candidate("BDF") if compile.numba_available() else Candidate("LSODA")
    s = policy.decide(model, replace(start_of(model, setup), method="auto", backend="auto", rtol=tolerance))
    if compile.numba_available():
        return (Candidate("Radau"), Candidate("BDF")) if s.method in IMPLICIT else (Candidate("DOP853", "compiled"), Candidate("RK45", "compiled"))
    return (Candidate("Radau"), Candidate("LSODA")) if s.method in IMPLICIT else (Candidate(s.method), Candidate("LSODA"))


def stiff_start(model: Model, setup: Setup) -> bool:
    """Whether a stiff decay (`diagnostics.stiff`) shows anywhere along `auto`'s pilot run
    (`policy.pilot`, at a moderate rtol: the pilot measures the system, not the tolerance). An
    explicit reference is then no choice even where `auto` would take compiled DOP853 for a
    user's run ("mildly stiff"): at a reference's tolerance the stiff components' round-off
    noise drives its error estimate, and DOP853 takes many times its stability-limited steps,
    most of them rejected, or never finishes (a spring of k = 1e10 written in its length: 1e6
    steps for 0.65 s at rtol 1e-13)."""
    s = replace(start_of(model, setup), method="auto", backend="auto")
    measured = policy.pilot(model, replace(s, rtol=PILOT_RTOL, atol=atol_for(PILOT_RTOL)))
    if measured is None:
        return False
    return diagnostics.stiff(measured.worst, setup.t_end)


def stiff_at(model: Model, setup: Setup, t: float, y: np.ndarray) -> bool:
    """Whether the linearisation at the state (t, y) is stiff over the window (`diagnostics.stiff`):
    where an explicit reference attempt ran out of its budget there, its steps were stability-limited
    and looser attempts would fare no better (the elastic pendulum in r started at r = 0.01: three
    explicit attempts, 6e6 compiled steps, before the implicit reference)."""
    s = start_of(model, setup)
    rhs = policy.safe_rhs(compile.build(model, "python").module, code_parameters(s.values, 0.0 if model.constraints else None))
    spectrum = diagnostics.spectrum_at(rhs, t, np.array(y, dtype=float))
    return spectrum is not None and diagnostics.stiff(spectrum, setup.t_end)


PILOT_RTOL = 1e-6
"""The rtol of the pilot run that says whether a reference must be implicit (`stiff_start`)."""


IMPLICIT_TIGHTEST = 1e-12
"""The tightest rtol of an implicit reference run (scipy's Radau and BDF step in Python: tighter
costs many times the steps for little gain)."""
BLOWUP = (Status.NONFINITE, Status.SINGULAR, Status.STEP_COLLAPSE)
"""How a run ends when the solution itself may blow up (not a budget or a convergence failure)."""


LOOSER_CONFIRMATION = 100.0
"""Where the compiled second method cannot finish at the explicit reference's rtol, it confirms at this
times that rtol (`looser_confirmations`) before Radau is tried."""


def looser_confirmations(rtol: float, loosest: float) -> tuple[float, ...]:
    """The rtols at which the compiled second method confirms an explicit reference at `rtol` after it
    could not finish at `rtol` itself: LOOSER_CONFIRMATION x looser each time, no looser than
    1/100 of `loosest` (the loosest implicit rtol, 0.1 x the accuracy asked), at most two."""
    rungs: list[float] = []
    r = rtol
    while len(rungs) < 2 and r * LOOSER_CONFIRMATION <= loosest / 100 * (1 + 1e-9):
        r = float(f"{r * LOOSER_CONFIRMATION:.12g}")
        rungs.append(r)
    return tuple(rungs)


def implicit_tolerance(tolerance: float) -> float:
    """The rtol of an implicit reference run standing in for an explicit one at `tolerance`."""
    return max(tolerance, IMPLICIT_TIGHTEST)


def _stopped(model: Model, candidate: Candidate, tolerance: float, setup: Setup, trajectory: Trajectory, needed: float | None = None) -> str:
    """Why a reference run gave no reference, with the time, the state and the cause (`needed`: the steps
    its probe's pace needs, when only the probe ran: `explicit_attempt`)."""
    what = f"{trajectory.settings.method} ({trajectory.settings.backend}), rtol {tol_text(tolerance)}"
    if needed is not None:
        return (
            f"the reference run ({what}) cannot reach t = {setup.t_end:g} within its budget: a probe of {trajectory.stats.steps} steps reached t = {trajectory.t_last:.6g},"
            f" a pace of about {needed:.3g} steps to t_end; state there: {state_text(model, trajectory.y_last)}"
        )
    if over_step_budget(trajectory):
        return (
            f"the reference run ({what}) did not reach t = {setup.t_end:g} within {trajectory.stats.steps} steps"
            f" (the step budget of this reference attempt; a larger --max-steps raises it): it stopped at t = {trajectory.t_last:.6g}; state: {state_text(model, trajectory.y_last)}"
        )
    return f"the reference run ({what}) failed: {trajectory.message.removeprefix(f'{model.source}: ')}"


def implicit_tolerances(tolerance: float, loosest: float) -> tuple[float, ...]:
    """The rtols an implicit reference tries, tightest first: from `implicit_tolerance(tolerance)`
    by decades up to `loosest`. Scipy's implicit methods are round-off-limited well above
    double precision on stiff systems (a spring of k = 1e10 written in its length: Radau cannot
    pass 1e-8), and the second method's agreement, not the tolerance, says how good the reference is."""
    first = implicit_tolerance(tolerance)
    rungs = [first]
    while rungs[-1] * 10 <= loosest * (1 + 1e-9):
        rungs.append(rungs[-1] * 10)
    return tuple(rungs)


IMPLICIT_STEPS = 3000
"""The least step budget of one implicit reference attempt (scipy steps; more when the slow motion
needs it: IMPLICIT_MARGIN x `diagnostics.implicit_steps`); a round-off-limited attempt is given up at
it and the next, looser tolerance tried."""
IMPLICIT_MARGIN = 30.0


EXPLICIT_REFERENCE_STEPS = 20_000
"""The step budget (scipy steps; compiled runs COMPILED_STEPS x as many: 2e6) of one compiled explicit
reference attempt. Where it runs out, the next attempt is 100 x looser (`explicit_tolerances`):
an orbit passing within 1e-5 of a coordinate singularity (the Euler angles of a top at theta = 0)
spent 6e7 compiled steps, 155 s, at rtol 2.5e-14 without getting past it."""
EXPLICIT_ATTEMPTS = 3


def explicit_tolerances(tolerance: float, loosest: float) -> tuple[float, ...]:
    """The rtols a compiled explicit reference tries: `tolerance`, then 100 x looser each time, up
    to `loosest` (the loosest an implicit reference would try) and EXPLICIT_ATTEMPTS in all."""
    rungs = [tolerance]
    while len(rungs) < EXPLICIT_ATTEMPTS and rungs[-1] * 100 <= loosest * (1 + 1e-9):
        rungs.append(float(f"{rungs[-1] * 100:.12g}"))
    return tuple(rungs)


PACE_PROBE = 0.1
"""A compiled explicit reference run (`explicit_attempt`) first runs with this share of its step budget ..."""
PACE_SKIP = 1.0
"""... and, where that probe does not finish, is not run in full when its pace (steps over the share of the
window done) needs more than this times its budget: it would spend the whole budget to learn that it
cannot finish (the penalty pendulum of k = 1e9: DOP853 at rtol 2.5e-14 spent 2e6 compiled steps to reach
t = 0.08 of 5, three times a regime, in its reference and its horizon). 1.25 before: DOP853 at 2.5e-10 over
its long horizon, paced at 2.35e6 steps against 2e6, ran out at t = 41.9 of 50; at 2.5e-12 at high energy,
paced at 2.27e6, at t = 3.39 of 5 (9 s of the 48)."""
PACE_EXTENSION = 4.0
"""Where an explicit run at the reference's rtol is the last before a costlier one (Radau stepping in
Python), and for a compiled confirmation, the budget is raised to PACE_ROOM x what its pace needs, up to
this times its budget (and the reference budget of --max-steps): the multiplier pendulum's long horizon,
whose confirmation (compiled RK45 at 2.5e-14) ran out of its 2e6 steps, leaving the regime undecided."""
PACE_ROOM = 1.25


@dataclass(frozen=True)
class Attempt:
    """An explicit reference run (`explicit_attempt`): its trajectory, and when only its probe ran, the
    compiled steps its pace needs to the window's end (else None)."""

    trajectory: Trajectory
    needed: float | None = None


def explicit_attempt(model: Model, candidate: Candidate, rtol: float, setup: Setup, ceiling: int = 0, expected: int = 0) -> Attempt:
    """A compiled explicit reference run within `setup`'s reference budget, paced: a probe with PACE_PROBE
    of the budget first (when it finishes or fails it is the run: the same steps as a run with the whole
    budget); where it runs out, its pace (compiled steps over the share of the window done) says how many
    steps the run needs. Above PACE_SKIP x the budget (`ceiling` > 0: above the budget raised to at most
    PACE_EXTENSION x, and `ceiling`) it is not run (the probe returned, `needed` set); else it runs in full,
    with PACE_ROOM x what it needs when `ceiling` allows more than the budget. Counted in steps, never timed.

    The probe is sized so that it is not stopped only to be made again from t = 0 where the steps the run
    needs are known ahead: PACE_ROOM x its stability-limited steps (`stable_steps`), or `expected` (compiled
    steps: a finished run the attempt follows over the same window and takes no more steps than, `_bounded`),
    within the budget.

    Once per model and arguments: `horizon`'s base run is the reference's first attempt (the same call), and where its probe
    runs out the reference would probe it again (the penalty pendulum of k = 1e9: compiled DOP853 at 2.5e-14, 200000 steps,
    0.3-0.4 s, twice in each of its three regimes). A run is deterministic: the same arguments give the same steps."""
    return memo.once(model, _attempt_key(candidate, rtol, setup, ceiling, expected), lambda: _explicit_attempt(model, candidate, rtol, setup, ceiling, expected))


def _attempt_key(candidate: Candidate, rtol: float, setup: Setup, ceiling: int, expected: int) -> tuple[object, ...]:
    """The memo key of an explicit attempt, one for `explicit_attempt` and `attempt_ahead`: an attempt started ahead
    is taken up only by a call with the same key."""
    return ("explicit attempt", candidate, rtol, ceiling, expected, *reference_key(setup, rtol))


def attempt_ahead(model: Model, candidate: Candidate, rtol: float, setup: Setup, ceiling: int = 0, expected: int = 0) -> None:
    """`explicit_attempt` with these arguments started in a thread of its own (`memo.ahead`), for the call
    that follows to take up: compiled runs release the GIL, so on a machine with two cores it runs beside
    what the caller does meanwhile. What it looks up first (the pilot behind `stable_steps`) is looked up
    here, so that the thread only integrates."""
    stable_steps(model, setup, candidate.method)
    memo.ahead(model, _attempt_key(candidate, rtol, setup, ceiling, expected), lambda: _explicit_attempt(model, candidate, rtol, setup, ceiling, expected))


def _explicit_attempt(model: Model, candidate: Candidate, rtol: float, setup: Setup, ceiling: int, expected: int) -> Attempt:
    budget = setup.reference_steps
    share = max(1, math.ceil(PACE_PROBE * budget))
    stable = stable_steps(model, setup, candidate.method) / COMPILED_STEPS  # in the budget's scipy steps
    known = max(stable, expected / COMPILED_STEPS)
    bounded = share < PACE_ROOM * expected / COMPILED_STEPS <= budget and expected / COMPILED_STEPS > stable
    if share < PACE_ROOM * known <= budget:
        # a probe its stability limit, or a run it follows, says it would stop: PACE_ROOM x that, within the budget (the stiff
        # elastic pendulum in r over t = 100: compiled DOP853 at 1e-7 confirming RK45 at 1e-9, 1.19e7 steps, was probed with 6e6
        # steps, 8 s, stopped at 76 % of the window and made again from t = 0: 7.9e6 steps)
        share = math.ceil(PACE_ROOM * known)
    # a probe that ran out is kept by what its steps depend on, not its samples: `horizon`'s base run asks for 4 x the
    # study's samples, so its first attempt is not the reference's call, while the probe is the same run to the same
    # point (the Euler-angle top near its pole: compiled DOP853 at 2.5e-14, 200000 steps, 1.1 s, twice in three regimes)
    spent: dict[tuple[object, ...], Trajectory] = memo.once(model, ("explicit probes out of budget",), dict)
    steps_key = (candidate, rtol, share, setup.t_end, setup.times[:1], tuple(sorted(setup.parameters.items())), tuple(sorted(setup.initial.items())))
    kept = spent.get(steps_key)
    probe = kept if kept is not None else run(model, candidate, rtol, replace(setup, reference_max_steps=share), reference=True)
    if not over_step_budget(probe):
        return Attempt(probe)
    spent[steps_key] = probe
    span = setup.t_end - probe.settings.t0
    done = (probe.t_last - probe.settings.t0) / span if span > 0 else 0.0
    needed = probe.stats.steps / done if done > 0 else math.inf  # compiled steps (a compiled run's budget is COMPILED_STEPS x the setup's)
    scale = COMPILED_STEPS if probe.settings.backend == "compiled" else 1
    limit = min(PACE_EXTENSION * budget, max(ceiling, budget)) if ceiling else PACE_SKIP * budget
    if needed > limit * scale and not bounded:
        # a probe sized by `expected` that ran out is not judged by its pace: a pace judged later in the run than the tenth's can
        # differ from it (a stiff start), and the run the old probe would have made is made (accuracy on the stiff elastic pendulum:
        # DOP853 at 1e-9 after RK45 at 1e-10, probed with 4.6e6 steps, paced at more than its budget, finishes in 5.9e6)
        return Attempt(probe, needed)
    steps = max(budget, min(math.floor(limit), math.ceil(PACE_ROOM * needed / scale))) if ceiling else budget
    return Attempt(run(model, candidate, rtol, replace(setup, reference_max_steps=steps), reference=True))


IMPLICIT_FIRST_STEPS = 1_000_000
"""Where compiled DOP853 needs more than this many steps just to stay stable over the window (`stable_steps`),
`stress` and `accuracy` try scipy's implicit methods before the compiled explicit ones: such a run costs seconds
whatever its rtol, and an implicit run that comes first caps them (their LOSING rules), so that they are not run
in full to learn that they lose (the stiff elastic pendulum in r at high energy: compiled RK45 and DOP853 ran
6e6 and 3.1e6 steps, 8 s, after which Radau at rtol 1e-6, 555 steps, was recommended)."""


IMPLICIT_FIRST_RATIO = 1000.0
"""... and more than this many times the steps the pilot puts an implicit method at over the window
(`policy.Pilot.implicit_steps`): a compiled step costs about 1-2 us, a scipy implicit one 0.3-1 ms, so only
then is the implicit run the cheap one. Van der Pol (mu = 1000) over t = 2000: DOP853's stability limit
about 1e6 steps (573k taken), LSODA's some 2e4: there compiled runs still come first and cap scipy's."""


COMPILED_IMPLICIT_FIRST_STEPS = 100_000
"""Where Radau runs compiled (`runs.compiled_radau`), it goes before the compiled explicit methods once their
stability limit alone costs more than this many steps (0.1-0.2 s), whatever the pilot puts an implicit method at:
a compiled Radau run costs at most its budget (`runs.COMPILED_IMPLICIT_STEPS`, 1-3 s), and a pilot started in a fast
transient overstates an implicit method's steps (the stiff elastic pendulum in r started at r = 0.01: compiled RK45
ran to its 6e6 steps and DOP853 3.1e6, 7.5 s, before compiled Radau met the accuracy in 524 steps)."""


def implicit_first(model: Model, setup: Setup) -> bool:
    """Whether the implicit methods go before the compiled explicit ones: compiled Radau where it runs compiled
    (COMPILED_IMPLICIT_FIRST_STEPS), else scipy's (IMPLICIT_FIRST_STEPS, IMPLICIT_FIRST_RATIO)."""
    compiled = compiled_radau()
    stable = stable_steps(model, setup, "DOP853")
    if stable <= (COMPILED_IMPLICIT_FIRST_STEPS if compiled else IMPLICIT_FIRST_STEPS):
        return False
    if compiled:
        return True
    s = replace(start_of(model, setup), method="auto", backend="auto", rtol=PILOT_RTOL, atol=atol_for(PILOT_RTOL))
    measured = policy.pilot(model, s)
    return measured is not None and stable > IMPLICIT_FIRST_RATIO * max(measured.implicit_steps(setup.t_end), 1.0)


def ahead(candidate: Candidate) -> bool:
    """Whether `candidate` goes before the compiled explicit methods where `implicit_first` says so: compiled
    Radau where it runs compiled (`runs.compiled_radau`: scipy's implicit methods then come after the compiled
    ones, which cap them), else scipy's implicit methods."""
    return candidate.method in IMPLICIT and (backend_for(candidate) == "compiled" or not compiled_radau())


STABLE_PROBE = {"RK45": diagnostics.STABILITY, "DOP853": policy.DOP853_STABILITY}
"""|h lambda| on the negative real axis up to which each explicit method stays stable."""


def stable_steps(model: Model, setup: Setup, method: str) -> float:
    """The compiled steps an explicit `method` needs just to stay stable over `setup`'s window: the fastest
    decay along `auto`'s pilot run (memoized) x t_end / its stability interval; 0 where the pilot finds the
    system not stiff. `explicit_attempt` sizes its probe by it: a probe of PACE_PROBE of the budget that
    the stability limit alone stops is thrown away (the stiff elastic pendulum started at r = 0.01: compiled
    RK45 at rtol 1e-8 needs 6.06e6 steps; its probe of 6e6, 3.7 s, ran out at 99% of the window, then the run
    was made in full)."""
    interval = STABLE_PROBE.get(method)
    if interval is None:
        return 0.0
    s = replace(start_of(model, setup), method="auto", backend="auto", rtol=PILOT_RTOL, atol=atol_for(PILOT_RTOL))
    measured = policy.pilot(model, s)
    if measured is None or not diagnostics.stiff(measured.worst, setup.t_end):
        return 0.0
    return measured.worst.decay * setup.t_end / interval


CONFIRMATION_STEPS = 1_500_000
"""The most compiled steps a compiled explicit confirmation of an implicit reference may take (1-3 s): beyond it
compiled Radau's own convergence (`_converged`) confirms it, then scipy's LSODA and BDF (the stiff elastic pendulum
in r over t = 100: DOP853 needs 3.3e7 stability-limited steps, 40 s, to confirm compiled Radau at 1e-8)."""
COMPILED_RADAU_STEPS = 1_000_000
"""The most steps one compiled Radau reference attempt may take (2-5 s; `_implicit_budget`): no pace stops it where
it is round-off-limited (the stiff elastic pendulum in r: an attempt budget of 9.2e6 steps, 20 s, at rtol 1e-10,
and a probe of its first tenth that took 920000 steps to cover 0.116 of it)."""


def scaled(setup: Setup, steps: int) -> int:
    """A fixed step cap of one reference attempt (EXPLICIT_REFERENCE_STEPS, COMPILED_RADAU_STEPS, CONFIRMATION_STEPS,
    TIGHTER_RADAU_STEPS) for `setup`: raised as its --max-steps is over the command's default (`Setup.raised`)."""
    return math.ceil(steps * max(1.0, setup.raised))


def _implicit_budget(model: Model, setup: Setup) -> int:
    s = start_of(model, setup)
    found = policy.initial_spectrum(model, s.values, s.y0)
    expected = diagnostics.implicit_steps(found.slowest if found is not None else 0.0, setup.t_end)
    budget = min(setup.reference_steps, max(IMPLICIT_STEPS, math.ceil(IMPLICIT_MARGIN * expected)))
    return min(budget, scaled(setup, COMPILED_RADAU_STEPS) // COMPILED_STEPS) if backend_for(RADAU) == "compiled" else budget


PROBE_SPAN = 0.1
"""An implicit reference attempt first runs over this fraction of the window (`_doomed`) ..."""
PROBE_SHARE = 0.1
"""... with this fraction of the attempt's budget (at least PROBE_STEPS): an attempt that cannot
cover the first 10% of the window with 10% of its budget is round-off-limited at that rtol, and
the next, looser one is tried at once instead of after the whole budget (scipy's Radau on a spring
of k = 1e10 written in its length: 12000 steps, 10 s, to reach t = 2e-4 at rtol 1e-8; 500 steps
to t_end at 1e-7)."""
PROBE_STEPS = 300
RADAU = Candidate("Radau")
COMPILED_RADAU = Candidate("Radau", "compiled")
EXPLICIT_CONFIRMATION = 1.0
"""An implicit reference is confirmed first by compiled DOP853 at this times the loosest implicit rtol
(0.1 x the accuracy asked): on a stiff system an explicit method's stability limit
keeps its steps far below what accuracy needs at a moderate tolerance, so its error is tiny, and
it is not round-off-limited there as it is at a reference's 1e-14 (the damped spring of k = 1e10
in r: 3e5 compiled steps, 0.3 s, at rtol 1e-6, error 3e-8)."""


REFERENCE_PACE_MARGIN = PACE_MARGIN
"""A Python run on the reference's side - `_doomed`'s probe, a confirmation of the reference - is stopped once
its pace (`runs._paced`: judged after `runs.PACE_AFTER` of its budget, from the latter half of its steps) needs
more than this times its step budget: it would run out of the budget, which tells the same (not finished) at
up to 4 x the cost. The stiff elastic pendulum in r over t = 100: `_doomed`'s probe of Radau at rtol 1e-8 spent
its 9103 steps, 15 s, to cover the first tenth of the window; LSODA at rtol 1e-10 confirming Radau spent its
91024 steps, 7 s, without finishing."""


def paced_run(model: Model, candidate: Candidate, rtol: float, setup: Setup) -> Trajectory | Unaffordable:
    """A reference-side run within `setup`'s reference budget, stopped by its pace (REFERENCE_PACE_MARGIN) where
    it is a Python run: the trajectory, or the Unaffordable that stopped it (steps taken, share done). Compiled
    Radau (a confirmation), which no pace stops, gets an implicit reference attempt's budget (`_implicit_budget`),
    not the reference budget of 100 x 10 x --max-steps compiled steps (some 2 us each)."""
    if candidate.method == "Radau" and backend_for(candidate) == "compiled":
        setup = replace(setup, reference_max_steps=min(setup.reference_steps, _implicit_budget(model, setup)))
    try:
        return run(model, candidate, rtol, setup, reference=True, paced=True, margin=REFERENCE_PACE_MARGIN)
    except Unaffordable as over:
        return over


def _doomed(model: Model, setup: Setup, rtol: float, candidate: Candidate = RADAU, paced: bool = True) -> str:
    """Why an implicit reference attempt at `rtol` within `setup`'s reference budget cannot finish,
    judged cheaply ("" when it may): `auto`'s LSODA pilot at that rtol already extrapolates to more
    steps than the budget, or a probe of Radau over the first PROBE_SPAN of the window runs out of
    PROBE_SHARE of the budget."""
    budget = setup.reference_steps
    s = replace(start_of(model, setup), method="auto", backend="auto", rtol=rtol, atol=atol_for(rtol))
    # not for compiled Radau, whose probe costs 0.1-0.3 s: a pilot started in a fast transient overstates the steps (the stiff
    # elastic pendulum in r at high energy: every rtol doomed, so the explicit fallback, 23 s, where compiled Radau finishes)
    measured = policy.pilot(model, s) if candidate.method in IMPLICIT and backend_for(candidate) != "compiled" else None
    allowed = budget * step_factor(candidate.method, backend_for(candidate), reference=True)  # a compiled run's budget (`runs.run_steps`)
    if measured is not None and not measured.finished and measured.implicit_steps(setup.t_end) > allowed:
        return f"at rtol {tol_text(rtol)} a pilot run extrapolates to {measured.implicit_steps(setup.t_end):.3g} steps, above the budget of {allowed}"
    span = PROBE_SPAN * setup.t_end
    probe = replace(setup, t_end=span, times=(0.0, span), reference_max_steps=max(PROBE_STEPS, math.ceil(PROBE_SHARE * budget)))
    shared = _shared_probe(model, candidate, rtol, probe)
    if shared is not None:
        return f"at rtol {tol_text(rtol)} {candidate.method} took {shared.steps} steps to reach t = {shared.t_last:.3g} of the first {span:.3g}"
    # paced (REFERENCE_PACE_MARGIN) except for the loosest rtol, whose verdict decides between Radau and the explicit fallback: a pace
    # judged in a fast transient can doom an rtol that finishes (the elastic pendulum of k = 1e11 at high energy: Radau at 1e-7,
    # judged after 238 steps at 0.018% of the probe's span, finishes the window in its budget)
    found = paced_run(model, candidate, rtol, probe) if paced else run(model, candidate, rtol, probe, reference=True)
    if isinstance(found, Unaffordable):
        return (
            f"at rtol {tol_text(rtol)} {candidate.method} took {found.steps} steps to reach {100 * found.fraction:.2g}% of the first {span:.3g}: at that pace it would"
            f" not cover it within {found.margin:g} x its share of the budget ({found.budget})"
        )
    if over_step_budget(found):
        _keep_probe(model, candidate, rtol, probe, found)
        return f"at rtol {tol_text(rtol)} {candidate.method} took {found.stats.steps} steps to reach t = {found.t_last:.3g} of the first {span:.3g}"
    return ""


@dataclass(frozen=True)
class _Stopped:
    """A compiled Radau probe (`_doomed`) that ran out of its step budget inside its window, kept for the probes after it
    (`_shared_probe`): its decided settings (less the window and notes), its compiled step budget, the steps it took and
    where it stopped."""

    settings: Settings
    budget: int
    steps: int
    t_last: float
    span: float
    """The end of its window (its start the settings' t0)."""


def _stopped_probes(model: Model) -> list[_Stopped]:
    """The compiled Radau probes of this model that ran out of their budget (`_keep_probe`), once per model."""
    return memo.once(model, ("stopped probes",), list)


def _probe_settings(model: Model, candidate: Candidate, rtol: float, probe: Setup) -> tuple[Settings, int] | None:
    """The decided settings (window and notes blanked) and compiled step budget a compiled Radau probe over `probe` runs with
    (as `paced_run` sizes it), None where its steps may depend on the window's end other than through the last step: another
    method, scipy's Radau, kept constraints (projections restart the method with an initial step clamped to the window), switching
    functions (landings and hops restart it likewise) or a stop condition."""
    if candidate.method != "Radau" or backend_for(candidate) != "compiled" or model.constraints:
        return None
    sized = replace(probe, reference_max_steps=min(probe.reference_steps, _implicit_budget(model, probe)))
    decided = settings_for(model, candidate, rtol, sized)
    if decided.backend != "compiled" or decided.projection or decided.until is not None or decided.event is not None:
        return None
    if switching.located(compile.build(model, "python").module):
        return None
    return replace(decided, t_end=0.0, t_eval=(), notes=()), run_steps(decided, sized.reference_steps, reference=True)


def _shared_probe(model: Model, candidate: Candidate, rtol: float, probe: Setup) -> _Stopped | None:
    """A probe kept by `_keep_probe` that is this probe's run, where there is one (over a window no shorter). Compiled Radau's steps depend on the window's
    end only where a trial step is clamped to it (the initial step, scipy's, is at most the window; a step is shortened onto the
    end), so a run over a longer window from the same state with the same settings takes the same steps as a kept probe that
    never tried a step reaching its own end (`_keep_probe`); its driver checks the budget at the same step counts, so with a
    budget between the kept probe's and the steps the kept probe took it stops where that one stopped, at the same t. The
    stiff elastic pendulum in r: the long horizon's probes of Radau at 1e-10, 1e-9 and 1e-8 over [0, 10] stop at t = 0.0144,
    0.0421 and 0.289 after 100000 steps each, where the defaults' over [0, 1] stopped (1.4-2.2 s of `stress`)."""
    found = _probe_settings(model, candidate, rtol, probe)
    if found is None:
        return None
    settings, budget = found
    for kept in _stopped_probes(model):
        if kept.settings == settings and kept.span <= probe.t_end and kept.budget <= budget <= kept.steps:
            return kept
    return None


def _keep_probe(model: Model, candidate: Candidate, rtol: float, probe: Setup, found: Trajectory) -> None:
    """Keep `found`, a probe over `probe`'s window that ran out of its budget, for `_shared_probe`, where no trial step of it can
    have reached the window's end: every trial after the first is at most status.MAX_FACTOR x the largest step taken, from a t
    no later than where it stopped, and the first (scipy's initial step, `_first_step`) was below the window."""
    shared = _probe_settings(model, candidate, rtol, probe)
    largest = found.stats.max_step
    if shared is None or largest is None or not found.t_last + MAX_FACTOR * largest < probe.t_end:
        return
    settings, budget = shared
    if not max(_first_step(model, found.settings)) < FIRST_STEP_ROOM * probe.t_end:
        return
    _stopped_probes(model).append(_Stopped(settings, budget, found.stats.steps, found.t_last, probe.t_end))


FIRST_STEP_ROOM = 0.5
"""`_keep_probe` keeps a probe whose initial step, recomputed here in Python, is below this fraction of its window: the
compiled start computes it in a different order of operations, so not exactly alike."""


RADAU_ERROR_ORDER = 3
"""kernels.RADAU_ERROR_ORDER (kernels imports numba, which reference.py does not need)."""


def _first_step(model: Model, settings: Settings) -> tuple[float, float]:
    """The Euler step that tests the slope and the initial step compiled Radau takes at the start of `settings`
    (kernels.radau_start: scipy's `select_initial_step`, error order 3, rtol at least 100 x the machine epsilon) over an
    unbounded window, neither clamped to its end; inf where the right-hand side cannot be evaluated."""
    rhs = policy.safe_rhs(compile.build(model, "python").module, settings.p)
    y0 = np.array(settings.y0, dtype=float)
    f0 = rhs(settings.t0, y0)
    if f0 is None:
        return math.inf, math.inf
    rtol = max(settings.rtol, 100 * np.finfo(float).eps)
    scale = settings.atol + np.abs(y0) * rtol
    d0, d1 = float(np.sqrt(np.mean((y0 / scale) ** 2))), float(np.sqrt(np.mean((f0 / scale) ** 2)))
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    f1 = rhs(settings.t0 + h0, y0 + h0 * f0)
    if f1 is None:
        return math.inf, math.inf
    d2 = float(np.sqrt(np.mean(((f1 - f0) / scale) ** 2))) / h0
    h1 = max(1e-6, h0 * 1e-3) if d1 <= 1e-15 and d2 <= 1e-15 else (0.01 / max(d1, d2)) ** (1.0 / (RADAU_ERROR_ORDER + 1))
    return h0, min(100 * h0, h1, settings.max_step)


def reference_key(setup: Setup, tolerance: float, *more: object) -> tuple[object, ...]:
    """What a reference run depends on (the system aside: the memo lives on the model): the window
    and samples, the parameters and initial values, the reference step budget and the tolerance.
    Not the time limit (reference runs have none) nor a measured run's budget."""
    return (setup.t_end, setup.times, tuple(sorted(setup.parameters.items())), tuple(sorted(setup.initial.items())), setup.reference_steps, tolerance, *more)


def computed_reference(model: Model, setup: Setup, tolerance: float, hint: str = ", looser --tolerances", implicit: tuple[float, ...] | None = None) -> Reference:
    """`_computed_reference`, once per model and (setup, tolerance, implicit rtols): `stress` asks
    again for the same reference from regimes that share their window and state, and a Python
    session from one `accuracy` study to the next (a failure is remembered and raised again too)."""

    def compute() -> Reference | ReferenceFailed:
        try:
            return _computed_reference(model, setup, tolerance, hint, implicit)
        except ReferenceFailed as failure:
            return failure
        finally:
            memo.settle(model)  # no run started ahead (`attempt_ahead`) goes on beside the measured runs that follow

    found = memo.once(model, ("reference", *reference_key(setup, tolerance, implicit, hint)), compute)
    if isinstance(found, ReferenceFailed):
        raise found
    return found


SECOND_COST = 4.0
SECOND_STEPS = 1_000_000
"""In `stress`, a second method at the primary's rtol that would take more than SECOND_COST x the primary's steps,
and more than SECOND_STEPS compiled steps (a second or more: cheaper second opinions are always asked for), is
not run before the primary's own convergence (`_converged`: its runs 10 x and 100 x looser, together about 1.3 x
its steps, the first of them run anyway) has had the chance to bound the reference's error; it still runs where
that convergence cannot vouch. The Cartesian pendulum with a multiplier over t = 1e4: compiled RK45 at 2.5e-14 took
6.4e6 steps, 10 s of `stress`'s 42, to confirm DOP853's 5.1e5 by 1.3e-10, where DOP853 at 2.5e-13 and 2.5e-12 (3.8e5 and
2.9e5 steps) bound its error by 4.4e-8, the reference's own error either way (`_floored`)."""


def _computed_reference(model: Model, setup: Setup, tolerance: float, hint: str, implicit: tuple[float, ...] | None) -> Reference:
    """The primary reference run confirmed by the second; where the primary (explicit) run cannot
    go - it fails, or runs out of its step budget, as on a stiff system - or where the system is
    stiff at the start (`reference_candidates`), Radau confirmed by LSODA (else BDF), their largest
    disagreement the reference's own error (LSODA runs first at 1/100 and 1/10 of Radau's rtol where it
    can: a confirmation at a looser tolerance than it could reach would report its own error, not
    Radau's), at the first of the rtols `implicit` (default
    `implicit_tolerances(tolerance, 1e3 x tolerance)`, tightest first) at which Radau finishes
    within its budget; where the explicit pair's second run cannot go, Radau confirms the first.
    Raises ReferenceFailed when no reference can be made (`hint`: the option that loosens the
    reference, as the calling command names it)."""
    primary, second = reference_candidates(model, setup, tolerance)
    rtols = implicit if implicit else implicit_tolerances(tolerance, 1e3 * tolerance)
    began = time.perf_counter()
    reasons: list[str] = []
    main: Trajectory | None = None
    paced_need: float | None = None  # the compiled steps the last explicit attempt's pace needs, where it ran out of budget not stiff
    if primary.method not in IMPLICIT:
        capped = replace(setup, reference_max_steps=min(setup.reference_steps, scaled(setup, EXPLICIT_REFERENCE_STEPS))) if primary.backend == "compiled" else setup
        tried: list[str] = []
        attempts = explicit_tolerances(tolerance, rtols[-1])
        for k, rtol in enumerate(attempts):
            # at the reference's own rtol, the last explicit attempt may have more steps where its pace says they suffice (Radau
            # in Python comes next); a looser one may not: DOP853 at 2.5e-10 over the penalty pendulum's long horizon, given
            # them, disagreed with RK45 by 3.2e-7 but was 7e-7 off an independent reference, too close to the accuracy to vouch
            extend = setup.reference_steps if k == len(attempts) - 1 and rtol <= tolerance * (1 + 1e-9) else 0
            paced = explicit_attempt(model, primary, rtol, capped, extend) if primary.backend == "compiled" else None
            main = paced.trajectory if paced is not None else run(model, primary, rtol, capped, reference=True)
            if not main.failed:
                # the second method at the same rtol, else (round-off-limited there over a long horizon) compiled at
                # LOOSER_CONFIRMATION x it, before Radau in Python (the multiplier pendulum and the hoop over t_end x 10:
                # RK45 at 2.5e-14 ran out of its 2e6 steps, then Radau at 1e-10 its 20000, a third of `stress`'s time)
                looser = [(second, r) for r in looser_confirmations(rtol, rtols[-1])] if second.backend == "compiled" else []
                confirmations = [(second, rtol), *looser, (Candidate("Radau"), max(rtols[0], rtol))]
                # `stress` without looser rungs: a reference its own convergence already cannot let vouch asks no second method
                found = _unvouched(model, capped, main, rtol, primary, rtols[-1], time.perf_counter() - began) if implicit and not looser else None
                if implicit and looser:  # (looser confirmations are compiled ones: the primary is compiled DOP853)
                    # the primary's own run CONVERGENCE_STEP x looser is asked for on every path below (`_floored`, `_converged`):
                    # made beside the second method's
                    near = _looser(rtol, CONVERGENCE_STEP)
                    attempt_ahead(model, primary, near, capped, 0, _bounded(main, primary, near))
                    # `stress`, where the second method cannot finish at the primary's rtol: the primary's own convergence first
                    # (`_converged`), which its looser runs would be asked for anyway where the second method's looser run disagrees
                    # by its own error (the weakly damped oscillators over t = 1e5: compiled RK45 at 2.5e-10, 3.8e6 steps, 4.5 s,
                    # 1.6e-6 off DOP853 at 2.5e-14, whose runs at 2.5e-13 and 2.5e-12 then bounded its error by 5.2e-10)
                    # (and where it would take more than SECOND_COST x the primary's steps: the multiplier pendulum over t = 1e4)
                    affordable = math.ceil(max(SECOND_COST * main.stats.steps, SECOND_STEPS) / COMPILED_STEPS)
                    within = replace(capped, reference_max_steps=min(capped.reference_steps, affordable))
                    ceiling = min(setup.reference_steps, affordable) if affordable > capped.reference_steps else 0
                    same = _confirmed(model, within, main, rtol, confirmations[:1], time.perf_counter() - began, ceiling=ceiling)
                    if not math.isfinite(same.own_error):  # (where it finishes, the path below confirms and floors as before)
                        # `_converged` asks next for the run CONVERGENCE_STEP**2 x looser: made beside the one CONVERGENCE_STEP x looser
                        far = _looser(rtol, CONVERGENCE_STEP**2)
                        attempt_ahead(model, primary, far, capped, 0, _bounded(main, primary, far))
                        why = (
                            "within its budget"
                            if affordable >= setup.reference_steps
                            else f"within {affordable * COMPILED_STEPS} steps ({SECOND_COST:g} x those of {primary.method}, at least {SECOND_STEPS})"
                        )
                        same = replace(same, confirmation=f"{second.method} ({second.backend}) at the same tolerance cannot finish {why}")
                        early = _converged(model, capped, main, rtol, same, primary, rtols[-1], time.perf_counter() - began)
                        found = early if early.own_error <= rtols[-1] else None
                if found is None:
                    found = _confirmed(model, capped, main, rtol, confirmations, time.perf_counter() - began, ceiling=setup.reference_steps)
                    if implicit:  # `stress` (its loosest implicit rtol, 0.1 x the accuracy, is what a reference must reach to vouch)
                        found = _converged(model, capped, main, rtol, found, primary, rtols[-1], time.perf_counter() - began)
                return replace(found, description=f"{found.description} (looser than rtol {tol_text(tolerance)}: {'; '.join(tried)})") if tried else found
            tried.append(_stopped(model, primary, rtol, capped, main, paced.needed if paced is not None else None))
            paced_need = None
            if main.outcome == Status.SURFACE_JUMP:
                continue  # its steps collapsed onto a jump in the forces (a gated damper): a looser tolerance may step across it
            if main.outcome != Status.BUDGET:
                break  # a blow-up or a singular matrix: a looser tolerance will not pass it
            if stiff_at(model, setup, main.t_last, main.y_last):
                tried.append(f"stiff where it stopped (t = {main.t_last:.6g}): its steps are stability-limited, a looser rtol would not lengthen them")
                break
            paced_need = paced.needed if paced is not None else None
        reasons.append("; ".join(tried))
        if main is not None and main.outcome == Status.STALLED:
            raise _no_reference(model, reasons, hint, main)  # the coordinates end there: Radau stalls there too (1e6 steps, 3 s)
    attempt = replace(setup, reference_max_steps=_implicit_budget(model, setup))
    radau_backend = backend_for(RADAU)  # compiled where it can (`runs.compiled_radau`), its budget `runs.step_factor` x the scipy steps
    radau_steps = attempt.reference_steps * step_factor("Radau", radau_backend, reference=True)
    if paced_need is not None and paced_need > ACCURACY_LIMITED * radau_steps:
        # the explicit runs' steps were short for accuracy, not stability (not stiff where they stopped): an implicit method of
        # lower order needs at least as many, and Radau in Python has far fewer (audit4 F4: Kepler near r = 0 spent a
        # 60000-step Radau run on a reference the explicit probes had already shown out of reach)
        reasons.append(
            f"Radau ({radau_backend}) not tried: the explicit runs were not stiff where they stopped, so their steps were limited by accuracy, and their pace"
            f" needs about {paced_need:.3g} steps, more than {ACCURACY_LIMITED:g} x an implicit reference's budget of {radau_steps}"
        )
        raise _no_reference(model, reasons, hint, main)
    why = reasons[0] if reasons else "stiff at the start, where an explicit reference would be stability-limited"
    radau: Trajectory | None = None
    skipped: list[str] = []
    fallback_tried = False
    for k, rtol in enumerate(rtols):
        loosest = k == len(rtols) - 1
        # the loosest is run in full unless an explicit fallback may stand in for it: its failure is the one reported
        doomed = _doomed(model, attempt, rtol, paced=not loosest) if not loosest or (main is None and compile.numba_available()) else ""
        if doomed and not loosest:
            skipped.append(doomed)
            continue
        if doomed:  # the loosest cannot finish either: the explicit fallback at once, not Radau's whole budget to learn it
            fallback_tried = True
            also = f" (also: {'; '.join(skipped)})" if skipped else ""
            fallback = _explicit_fallback(
                model, setup, rtols, f"the reference run (Radau ({radau_backend})) cannot finish within its budget of {radau_steps} steps: {doomed}{also}", time.perf_counter() - began
            )
            if fallback is not None:
                return fallback
        radau = run(model, Candidate("Radau"), rtol, attempt, reference=True)
        if not radau.failed:
            # stiff at the start: compiled RK45, whose stability-limited steps are as accurate and cheaper than DOP853's there
            # (its error estimate rejects fewer steps in the stiff components' round-off: the k = 1e10 pendulum over t = 100
            # at rtol 1e-7, 3.7e6 steps and 2.5 s against DOP853's 7.9e6 and 9.4 s, the same disagreement with Radau)
            confirmers = ("RK45", "DOP853") if not reasons else ("DOP853",)
            explicit = [(Candidate(m, "compiled"), max(rtols[-1] * EXPLICIT_CONFIRMATION, TIGHTEST)) for m in confirmers] if compile.numba_available() else []
            scipy = [(Candidate("LSODA"), r) for r in (rtol / 100, rtol / 10, rtol) if r >= TIGHTEST] + [(Candidate("BDF"), rtol)]
            # the compiled explicit confirmations get the explicit fallback's budget (their stability limit sized) up to
            # CONFIRMATION_STEPS, not the implicit attempt's: the angle-damped spring pendulum started at r = 0.011 needs 9.5e5
            # DOP853 steps (1.3 s) at rtol 1e-7
            wide = replace(attempt, reference_max_steps=max(attempt.reference_steps, min(_explicit_budget(model, setup), scaled(setup, CONFIRMATION_STEPS) // COMPILED_STEPS)))
            first = _confirmed(model, wide, radau, rtol, explicit, time.perf_counter() - began) if explicit else None
            if first is not None:
                first = _vouched(model, wide, radau, rtol, first, rtols[-1], time.perf_counter() - began)
            if first is not None and not math.isfinite(first.own_error) and radau.settings.backend == "compiled":
                # no compiled explicit run could confirm it: Radau's own runs 10 x and 100 x looser, where its error converges with
                # the tolerance (`_converged`: the disagreement at 10 x then bounds the primary's error), before scipy's runs in Python
                first = _converged(model, attempt, radau, rtol, first, COMPILED_RADAU, rtols[-1], time.perf_counter() - began)
            if first is not None and implicit and k == 0 and radau.settings.backend == "compiled" and not first.own_error <= rtols[-1]:
                # the tightest rung finished (not round-off-limited) and left the verdict open: compiled Radau tighter still, confirmed by
                # its own convergence (the fast-damping cart over t = 1000: Radau 1e-10 and 1e-9 disagree by 8.4e-6; 1e-12 and 1e-11 by 3.4e-7)
                first = _tighter(model, attempt, rtol, first, rtols[-1], began)
            found = first if first is not None and math.isfinite(first.own_error) else _confirmed(model, attempt, radau, rtol, scipy, time.perf_counter() - began)
            if first is not None and not math.isfinite(found.own_error):
                names = ", ".join(c.method for c, _ in explicit)
                found = replace(found, description=found.description.replace("unconfirmed: ", f"unconfirmed: {names}, ", 1))
            # not "round-off-limited": a probe stopped in a fast transient is no proof of round-off (audit4 F3: Radau at 1e-10
            # "took 301 steps to reach t = 0.216 of the first 1" on a damped cart whose 608-step run finishes)
            tighter = f"; tighter rtols were not tried in full: a probe of each could not cover the first part of the window within its share of the budget ({'; '.join(skipped)})" if skipped else ""
            found = replace(found, description=f"{found.description} (implicit: {why}{tighter})")
            python = found.confirmer is not None and backend_for(found.confirmer) == "python"
            if implicit and radau.settings.backend == "compiled" and main is None and python and math.isfinite(found.own_error) and found.own_error > rtols[-1]:
                # in `stress`, compiled Radau confirmed only by scipy's runs (no compiled confirmation finished) to an own error
                # above the loosest rtol (0.1 x the accuracy): the explicit fallback, where its own error is smaller (the stiff
                # elastic pendulum in r at high energy: compiled Radau at 1e-7 confirmed by LSODA to 1e-7, the fallback to 1.7e-9)
                fallback = _explicit_fallback(model, setup, rtols, f"compiled Radau's reference ({found.description}) has own error {found.own_error:.1e}", time.perf_counter() - began)
                if fallback is not None and fallback.own_error < found.own_error:
                    return fallback
            return found
        if radau.outcome not in (Status.BUDGET, Status.SURFACE_JUMP):
            break  # a failure, not round-off or a jump in the forces: a looser tolerance will not pass it
    assert radau is not None
    reasons.append(_stopped(model, Candidate("Radau"), rtol, attempt, radau) + (f" (also at rtol {', '.join(tol_text(r) for r in rtols[:-1])})" if len(rtols) > 1 and rtol == rtols[-1] else ""))
    if main is None and radau.outcome == Status.BUDGET and compile.numba_available() and not fallback_tried:
        fallback = _explicit_fallback(model, setup, rtols, reasons[-1], time.perf_counter() - began)
        if fallback is not None:
            return fallback
    main = main if main is not None else radau
    blowup = main.outcome in BLOWUP and radau.outcome in BLOWUP and abs(radau.t_last - main.t_last) <= 0.01 * max(setup.t_end, 1e-300)
    stop = f"{'both stop' if main is not radau else 'it stops'} near t = {main.t_last:.6g}"
    if blowup and (ended := coordinates_end(model, main.settings, main.t, main.y, main.t_last, main.y_last, main.outcome == Status.SINGULAR)) is not None:
        # where the coordinates end, not the motion: no reference in them (undecided), not a blow-up of the system (not met)
        raise ReferenceFailed(f"{model.source}: " + "; and ".join(reasons) + f"; {stop}, where {ended}", coordinates=True, trajectory=main, attempts=tuple(reasons))
    raise _no_reference(model, reasons, hint, main, f"{stop}: the solution itself blows up or reaches a singular configuration there" if blowup else "")


TIGHTER_DECADES = 2
"""How many decades tighter than the tightest of its rtols `_tighter` runs compiled Radau (not past IMPLICIT_TIGHTEST) ..."""
TIGHTER_RADAU_STEPS = 2_000_000
"""... each run within this many steps (2-4 s; the fast-damping cart over t = 1000 at rtol 1e-12: 1.12e6 steps, 1.3 s)."""


def _tighter(model: Model, setup: Setup, rtol: float, found: Reference, enough: float, began: float) -> Reference:
    """`found` (compiled Radau at `rtol`, the tightest of the implicit rtols, with an own error above `enough` or
    unconfirmed), or compiled Radau a decade tighter at a time (TIGHTER_DECADES, not past IMPLICIT_TIGHTEST, a probe
    first: `_doomed`) confirmed by its own convergence (`_converged`: its runs 10 x and 100 x looser, the first of them
    `rtol`'s, kept) where that lowers the own error. Compiled Radau costs 1-2 us a step: the tighter runs cost what one
    scipy confirmation does, where no explicit run can confirm a stiff system over a long window (the fast-damping cart
    over t = 1000 needs 3e8 stability-limited steps)."""
    wide = replace(setup, reference_max_steps=max(setup.reference_steps, scaled(setup, TIGHTER_RADAU_STEPS) // COMPILED_STEPS))
    tight = rtol
    for _ in range(TIGHTER_DECADES):
        if found.own_error <= enough:
            break
        tight = float(f"{tight / CONVERGENCE_STEP:.12g}")
        if tight < IMPLICIT_TIGHTEST * (1 - 1e-9) or _doomed(model, wide, tight, COMPILED_RADAU):
            break  # round-off-limited there: a tighter one would be too
        main = run(model, COMPILED_RADAU, tight, wide, reference=True)
        if main.failed:
            break
        unconfirmed = _confirmed(model, setup, main, tight, [], time.perf_counter() - began)
        again = _converged(model, wide, main, tight, unconfirmed, COMPILED_RADAU, enough, time.perf_counter() - began)
        if math.isfinite(again.own_error) and not again.own_error >= found.own_error:
            before = found.confirmation + (f", {found.own_error:.1e} apart" if math.isfinite(found.own_error) else "")
            found = replace(again, description=again.description.replace("; unconfirmed:  did not finish)", f"; at rtol {tol_text(rtol)}: {before})"))
    return found


def _no_reference(model: Model, reasons: list[str], hint: str, main: Trajectory | None, blowup: str = "") -> ReferenceFailed:
    """The failure of `_computed_reference`: why each attempt could not make it (`reasons`), where the
    solution itself blows up (`blowup`, "" when it does not), and the options that would help (`hint`:
    the one that loosens the reference, as the calling command names it)."""
    message = f"{model.source}: " + "; and ".join(reasons) + (f"; {blowup}" if blowup else "")
    if main is not None and main.outcome == Status.SURFACE_JUMP and not blowup:
        # stopped on a switching surface (a sliding mode: no classical solution past it, which the reason says): neither
        # more steps nor a looser reference passes it (the stick-slip block at t = 0.1168, at every rtol)
        return ReferenceFailed(f"{message}; give a --t-end before t = {main.t_last:.6g}, where it stops", trajectory=main, attempts=tuple(reasons))
    if main is not None and main.outcome == Status.STALLED:
        return ReferenceFailed(message, trajectory=main, attempts=tuple(reasons))  # its reason says what to do (`simulate._stalled`)
    return ReferenceFailed(f"{message}; give a shorter --t-end{hint} or a larger --max-steps", blowup=bool(blowup), trajectory=main, attempts=tuple(reasons))


ACCURACY_LIMITED = 10.0
"""Radau (compiled, else in Python) is not tried as a reference where the explicit attempts ran out of budget, were not
stiff where they stopped, and their pace needs more than this many times Radau's step budget in compiled
steps: their steps were limited by accuracy, which a lower-order implicit method does not lengthen."""


EXPLICIT_MARGIN = 50.0
"""An explicit fallback reference may take this many times the stability-limited steps `auto`'s pilot
estimates (at least EXPLICIT_FLOOR compiled steps, at most the reference budget)."""
EXPLICIT_FLOOR = 100_000


FALLBACK_SPREAD = 0.01
"""The explicit fallback's primary run is at most 1/FALLBACK_SPREAD times tighter than its confirmation
(the loosest rtol): its own error is the confirmation's disagreement, which a tighter primary run
cannot lower (the k = 1e10 pendulum at r = 0.01: RK45 at rtol 1e-10, 3.1 s, and at 1e-9, 0.8 s,
agree to 3e-11; either disagrees with DOP853 at 1e-7 by 9e-9)."""


def confirmation_ladder(loosest: float, primary: float) -> tuple[float, ...]:
    """The rtols at which compiled DOP853 confirms the explicit fallback again after the loosest:
    a decade tighter each, down to the primary run's rtol (a confirmation tighter than the primary
    measures the primary's error, which a tighter one cannot lower): at most two more runs, the
    primary being at most 1/FALLBACK_SPREAD x tighter than the loosest."""
    rungs: list[float] = []
    r = loosest
    while r / 10 >= primary * (1 - 1e-9):
        r = float(f"{r / 10:.12g}")
        rungs.append(r)
    return tuple(rungs)


def _explicit_budget(model: Model, setup: Setup) -> int:
    """The reference step budget (scipy steps; compiled runs COMPILED_STEPS x as many) of a stability-limited compiled
    explicit reference run: EXPLICIT_MARGIN x the stability-limited steps `auto`'s pilot estimates, at least
    EXPLICIT_FLOOR compiled steps, at most `setup`'s reference budget."""
    s = replace(start_of(model, setup), method="auto", backend="auto", rtol=PILOT_RTOL, atol=atol_for(PILOT_RTOL))
    measured = policy.pilot(model, s)
    stable = measured.explicit_steps(setup.t_end) if measured is not None else 0.0
    return min(setup.reference_steps, max(EXPLICIT_FLOOR, math.ceil(EXPLICIT_MARGIN * stable)) // COMPILED_STEPS + 1)


def _explicit_fallback(model: Model, setup: Setup, rtols: tuple[float, ...], why: str, seconds: float) -> Reference | None:
    """Where Radau is round-off-limited at every rtol (a stiff spring written in its length: its
    Newton iterations and error estimate drown in the rounding of k (r - l)), compiled RK45 at the
    tightest of `rtols` (at most 1/FALLBACK_SPREAD x tighter than the loosest) that it can finish, confirmed by compiled DOP853 at the loosest (else Radau
    there): on a stiff system an explicit method's stability limit keeps its steps short, so at
    these moderate tolerances it is accurate, and compiled it is affordable. RK45, not DOP853, as
    the primary: at tight rtols DOP853's error estimate rejects step after step in the stiff
    components' round-off (the k = 1e10 pendulum started at r = 0.01 at rtol 1e-10: 1.6e7 steps,
    23 s, against RK45's 3.6e6 steps, 2.5 s); the confirmation at the loosest rtol is conservative
    (its own error, 9e-9 there, bounds the disagreement). None when it cannot finish either (the
    caller reports the failure)."""
    attempt = replace(setup, reference_max_steps=_explicit_budget(model, setup))
    primary = Candidate("RK45", "compiled")
    useful = tuple(r for r in rtols if r >= rtols[-1] * FALLBACK_SPREAD * (1 - 1e-9)) or rtols[-1:]
    for k, rtol in enumerate(useful):
        if k < len(useful) - 1 and _doomed(model, attempt, rtol, primary):
            continue
        main = run(model, primary, rtol, attempt, reference=True)
        if not main.failed:
            found = _fallback_confirmed(model, attempt, main, rtol, rtols, seconds)
            # the floor left it open (the primary accuracy-limited somewhere): the primary tighter, a decade at a time
            # down to 100 x tighter than the tightest of `rtols`, paced, while each lowers its own error (Van der Pol, mu = 1000: RK45 at 1e-9
            # floored at 4.8e-6 by its run at 1e-8)
            tighter, lowest = rtol / CONVERGENCE_STEP, max(rtols[0] / CONVERGENCE_STEP**2, TIGHTEST) * (1 - 1e-9)
            while found.own_error > rtols[-1] and tighter >= lowest and found.own_error <= rtols[-1] * RK45_GAIN ** (1 + math.floor(math.log10(tighter / lowest))):
                again = explicit_attempt(model, primary, tighter, attempt).trajectory
                if again.failed:
                    break
                better = _fallback_confirmed(model, attempt, again, tighter, rtols, seconds)
                if not (math.isfinite(better.own_error) and better.own_error < found.own_error):
                    break
                found, tighter = better, tighter / CONVERGENCE_STEP
            return replace(found, description=f"{found.description} (explicit, stability-limited: {why})")
        if main.outcome != Status.BUDGET:
            return None
    return None


def _fallback_confirmed(model: Model, setup: Setup, main: Trajectory, rtol: float, rtols: tuple[float, ...], seconds: float) -> Reference:
    """The explicit fallback's run `main` (compiled RK45 at `rtol`) confirmed: by compiled DOP853 at the loosest of
    `rtols`, at `rtol`, else Radau at the loosest; tightened (`_tightened`), and floored by RK45 itself at
    CONVERGENCE_STEP x `rtol` (`_floored`, always)."""
    primary = Candidate("RK45", "compiled")
    confirmations = [(Candidate("DOP853", "compiled"), rtols[-1]), (Candidate("DOP853", "compiled"), rtol), (Candidate("Radau"), rtols[-1])]
    found = _confirmed(model, setup, main, rtol, list(dict.fromkeys(confirmations)), seconds)
    # the confirmation at the loosest rtol may disagree by more than that rtol (its own error, not the primary's):
    # accuracy's ladder to 1e-8 on the k = 1e10 pendulum: 1.3e-8 at DOP853's 1e-8, 2e-9 at 1e-9; the damped chain of
    # k = 1e7: DOP853 at 1e-8 is itself 5.1e-7 off the exact solution at its stability-limited steps, at 1e-9 5.7e-8,
    # while the primary RK45 at 1e-9 is 7.2e-9 off
    found = _tightened(model, setup, main, rtol, found, Candidate("DOP853", "compiled"), confirmation_ladder(rtols[-1], rtol), rtols[-1], seconds)
    # stability-limited steps make the explicit runs accurate only where they are stability-limited: across the
    # fast jumps of a relaxation oscillation (Van der Pol, mu = 1000) they are accuracy-limited, and RK45 at 1e-9
    # and DOP853 at 1e-8 both lag the jumps alike (5.2e-7 and 5.4e-7 off, 2.5e-8 apart: audit 5's F10)
    return _floored(model, setup, main, rtol, found, primary, seconds, always=True)


CONVERGENCE_STEP = 10.0
"""`_converged` runs the primary method again at this and CONVERGENCE_STEP**2 times its rtol ..."""
RK45_GAIN = CONVERGENCE_STEP ** (4 / 5)
"""How much RK45's error (order 4) shrinks a decade of rtol: the explicit fallback tightens its reference only
while the decades left could bring its own error down to what it needs (Van der Pol's long horizon, own error
1e-2 where 1e-7 is needed, is not run at 1e-10, 1e-11 and 1e-12 over t = 2e4 to learn it)."""


CONVERGENCE_RATIO = (3.0, 20.0)
"""... and trusts the first run's disagreement only when the second's is between these times larger:
the error then shrinks with the tolerance as the method's order says (order p: about
CONVERGENCE_STEP**(p/(p+1)) a decade, 7.7 for DOP853), so the looser run's disagreement with the
primary, mostly its own error, bounds the primary's error from above. Faster than that, the looser runs
are not yet in the asymptotic regime and the primary's error need not follow them: Kepler's orbit of
e = 0.7 over 1000 periods, DOP853 at 2.5e-12, 2.5e-13 and 2.5e-14 are 2.3e-4, 4.2e-6 and 1.8e-6 off
Kepler's equation (round-off and the orbit's phase sensitivity at the tightest): the disagreements
at 10 x and 100 x looser, 1.4e-6 and 1.3e-4 (94 x), would understate the primary's error."""


def _looser(rtol: float, factor: float) -> float:
    """`rtol` x `factor` to 12 digits: 1e-11 x 10 is the 1e-10 of the rtol ladders (not 9.999999999999999e-11), so that
    a run made already at it (`runs.kept_runs`: the tighter reference's primary before, a measured rung) is not made again."""
    return float(f"{rtol * factor:.12g}")


def _own_looser(model: Model, setup: Setup, main: Trajectory, tolerance: float, method: Candidate, seconds: float, factor: float = CONVERGENCE_STEP) -> Reference:
    """`main` confirmed by its own method `factor` x looser (`_converged`, `_unvouched`, `_floored`)."""
    return _confirmed(model, setup, main, tolerance, [(method, _looser(tolerance, factor))], seconds)


def _converged(model: Model, setup: Setup, main: Trajectory, tolerance: float, found: Reference, method: Candidate, enough: float, seconds: float) -> Reference:
    """`found` where its own error is within `enough` (0.1 x the accuracy asked) or its second method
    confirmed at the primary's own rtol (the spherical pendulum in gimbal angles at high energy: RK45 at
    2.5e-14 disagrees by 6e-7 where DOP853 10 x looser does by 3e-8; near the pole neither can be told
    right, so the second opinion at equal terms stands); else, where the primary
    explicit run is confirmed by its own method at CONVERGENCE_STEP x its rtol with a smaller disagreement,
    and the disagreement at CONVERGENCE_STEP**2 x is at least CONVERGENCE_RATIO x larger still (the error
    converging with the tolerance), that confirmation. A different method confirming at a looser rtol
    (compiled RK45, whose budget ran out at the primary's) measures its own, larger error, not the
    primary's: the Cartesian pendulum with a multiplier over t = 1e4, DOP853 at 2.5e-14 confirmed by RK45
    at 2.5e-10: 7.1e-5 apart, while the primary is 4.1e-9 off the exact solution; DOP853 at 2.5e-13 is
    4.4e-8 off the primary (4.8e-8 off the exact solution), at 2.5e-12 5.7e-7: converging, own error 4.4e-8."""
    if method.backend != "compiled":
        return found
    if found.own_error <= enough or found.confirmed_rtol <= tolerance * (1 + 1e-9):
        return _floored(model, setup, main, tolerance, found, method, seconds)  # a second opinion at equal terms stands, floored
    near = _own_looser(model, setup, main, tolerance, method, seconds)
    if not (math.isfinite(near.own_error) and (near.own_error < found.own_error or not math.isfinite(found.own_error))):
        return found
    far = _own_looser(model, setup, main, tolerance, method, seconds, CONVERGENCE_STEP**2)
    low, high = CONVERGENCE_RATIO
    if not (math.isfinite(far.own_error) and low * near.own_error <= far.own_error <= high * near.own_error):
        return found  # not converging with the tolerance as the method's order says (round-off, a shared defect, not yet asymptotic): no bound
    ratio = far.own_error / max(near.own_error, 1e-300)
    how = f"the same method {CONVERGENCE_STEP:g} x looser, {ratio:.2g} x closer than at {CONVERGENCE_STEP**2:g} x looser: the error converges with the tolerance"
    before = found.confirmation
    before = f"{before} disagreed by {found.own_error:.1e}" if math.isfinite(found.own_error) else before
    return replace(near, description=f"{near.description} ({how}; {before})")


VOUCHING = ("DOP853", "RK45")
"""The compiled methods that confirm an implicit reference again, tighter (`_vouched`), in turn."""


def _vouched(model: Model, setup: Setup, main: Trajectory, tolerance: float, found: Reference, enough: float, seconds: float) -> Reference:
    """An implicit reference whose compiled explicit confirmation, at a looser rtol than the reference's,
    left its own error above `enough` (0.1 x the accuracy asked), confirmed again by compiled DOP853, then
    RK45, a decade tighter at a time down to the reference's own rtol (`_tightened`): the looser run's
    disagreement is its own error, not the reference's. The elastic pendulum in r started at r = 0.01:
    Radau at 1e-10 confirmed by RK45 at 1e-7, 1.7e-5 apart (RK45 at 1e-7 is that far off), left the
    regime undecided although DOP853 at 1e-9, 1e-10 and 1e-11 come within 2.6e-8, 5.3e-9 and 3.0e-10 of
    it (1117-1948 compiled steps)."""
    looser = math.isfinite(found.confirmed_rtol) and found.confirmed_rtol > tolerance * (1 + 1e-9)
    if found.own_error <= enough or not looser or found.confirmer is None or found.confirmer.backend != "compiled":
        return found
    before = found
    for method in VOUCHING:
        found = _tightened(model, setup, main, tolerance, found, Candidate(method, "compiled"), confirmation_ladder(before.confirmed_rtol, tolerance), enough, seconds)
        if found.own_error <= enough:
            break
    if found is before:
        return found
    return replace(found, description=f"{found.description} (first confirmed by {before.confirmation}, {before.own_error:.1e} apart: that looser run's own error)")


def _unvouched(model: Model, setup: Setup, main: Trajectory, tolerance: float, method: Candidate, enough: float, seconds: float) -> Reference | None:
    """In `stress`, an explicit compiled primary reference run whose own method at CONVERGENCE_STEP x its rtol
    disagrees with it by more than `enough` (0.1 x the accuracy asked), that confirmation, before any second
    method runs: the reference cannot vouch for the accuracy whatever a second method says, since a second
    opinion at (nearly) equal terms is floored to that disagreement (`_floored`) and a looser one measures
    mostly its own error (`_converged`). None where that run does not finish or agrees within `enough`: the
    second method is asked as before (the run is the one `_floored` asks for, made once). Only where the second
    method has no looser rungs (`looser_confirmations`): there this run is made beside the second's (`attempt_ahead`).
    Kepler e = 0.9 started at r = 0.01 (a near collision): DOP853 at 2.5e-10 and 2.5e-9 are 1.1 apart; compiled
    RK45 at 2.5e-10, 5.6e6 steps and 5.8 s of the regime's 19, came within 1.0 and changed nothing."""
    if method.backend != "compiled":
        return None
    near = _own_looser(model, setup, main, tolerance, method, seconds)
    if not (math.isfinite(near.own_error) and near.own_error > enough):
        return None
    how = (
        f"own error {near.own_error:.1e}, above {tol_text(enough)}: the reference cannot vouch for the accuracy, and no second method was asked"
        " (its agreement cannot lower a bound its own convergence sets)"
    )
    return replace(near, convergence=near.own_error, description=f"{near.description} ({how})")


def _floored(model: Model, setup: Setup, main: Trajectory, tolerance: float, found: Reference, method: Candidate, seconds: float, always: bool = False) -> Reference:
    """`found`, confirmed by a second method at less than CONVERGENCE_STEP x the primary's rtol, with its own
    error raised to the disagreement of the primary's own method at CONVERGENCE_STEP x its rtol where that is
    larger: two methods at (nearly) equal rtols may share an error their agreement does not show, while a
    method's error converging with the tolerance (DOP853: about 7.7 x a decade) makes its looser run's
    disagreement an upper bound of the primary's error. The Cartesian pendulum with a multiplier, both runs
    projected onto the kept constraint, over t = 1e4: DOP853 and RK45 at 2.5e-14 agree to 1.4e-10 while both
    are 4.2e-9 off the exact solution; DOP853 at 2.5e-13 is 4.4e-8 off the primary (0.3 of the primary's
    cost, 1.1 s). Where the looser run does not finish or agrees better, `found` stands.

    `always`: also where the second method ran CONVERGENCE_STEP x looser or more (the explicit fallback on a
    stiff system). Two methods may lag alike where both are accuracy-limited: the Van der Pol oscillator of
    mu = 1000 (audit 5), RK45 at 1e-9 confirmed by DOP853 at 1e-8 to 2.5e-8 while both are 5e-7 off a
    1e-13 reference at a fast jump. Where the steps are stability-limited, the primary's looser run takes
    about the same steps and agrees closely, and the floor costs nothing but that run."""
    if not always and not (found.confirmed_rtol < CONVERGENCE_STEP * tolerance * (1 - 1e-9)):
        return found  # confirmed (or not) at CONVERGENCE_STEP x looser or more: its disagreement is already the looser run's
    near = _own_looser(model, setup, main, tolerance, method, seconds)
    if not (math.isfinite(near.own_error) and near.own_error > found.own_error):
        return found
    how = (
        f"own error {near.own_error:.1e}: {near.confirmation} disagrees by that much, more than the second method ({found.own_error:.1e}),"
        " and bounds the primary's error while it converges with the tolerance"
    )
    return replace(found, own_error=near.own_error, convergence=near.own_error, description=f"{found.description} ({how})")


def _tightened(model: Model, setup: Setup, main: Trajectory, tolerance: float, found: Reference, confirmer: Candidate, rungs: tuple[float, ...], enough: float, seconds: float) -> Reference:
    """`found` confirmed again by `confirmer` at each of `rungs` (tighter and tighter) while its own
    error is above `enough` and each confirmation lowers it: a confirmation run's own error, not
    the primary's, may set the disagreement (a round-off- or stability-limited explicit run at a
    moderate rtol). Each own error is a disagreement of two finished runs, as the first."""
    for rtol in rungs:
        if found.own_error <= enough:
            break
        again = _confirmed(model, setup, main, tolerance, [(confirmer, rtol)], seconds)
        if not (math.isfinite(again.own_error) and again.own_error < found.own_error):
            break  # round-off, or the primary's own error: a tighter confirmation will not lower it
        found = again
    return found


def _bounded(main: Trajectory, candidate: Candidate, rtol: float) -> int:
    """The compiled steps of `main` where they bound those of a compiled explicit run of `candidate` at `rtol` over the
    same window (0 where they do not): `main` a finished compiled explicit run, and `candidate` its own method at
    CONVERGENCE_STEP x its rtol or looser, or one of a higher order with a wider stability interval (DOP853 after RK45) at
    CONVERGENCE_STEP**2 x or looser (a decade looser is not enough: on the stiff elastic pendulum in r DOP853 at 1e-9 took
    5.9e6 steps where RK45 at 1e-10 took 3.7e6, its error estimate rejecting steps in the stiff component), whose steps,
    limited by accuracy or by stability, are then expected to be fewer. `explicit_attempt` sizes its probe by it, so that a
    confirmation is not probed, stopped and made again from t = 0; where the run takes more all the same (DOP853's error
    estimate rejecting steps in a stiff component's round-off), its probe runs out and its pace decides, as before."""
    s = main.settings
    if main.failed or s.backend != "compiled" or candidate.backend != "compiled" or s.method not in STABLE_PROBE or candidate.method not in STABLE_PROBE:
        return 0
    looser = CONVERGENCE_STEP if candidate.method == s.method else CONVERGENCE_STEP**2
    if STABLE_PROBE[candidate.method] < STABLE_PROBE[s.method] or rtol < looser * s.rtol * (1 - 1e-9):
        return 0
    return main.stats.steps


def _confirmed(model: Model, setup: Setup, main: Trajectory, tolerance: float, confirmations: list[tuple[Candidate, float]], seconds: float, ceiling: int = 0) -> Reference:
    """`main` as the reference, confirmed by the first of `confirmations` that finishes (own error:
    their largest scaled disagreement), unconfirmed (own error nan) when none does. A compiled
    explicit confirmation is paced (`explicit_attempt`, up to `ceiling` steps when > 0): one that cannot
    finish does not spend its whole budget to learn it."""
    scale = component_scale(main.y)
    own, confirm = math.nan, f"unconfirmed: {', '.join(c.method for c, _ in confirmations)} did not finish"
    confirmed_rtol, confirmation = math.nan, confirm
    confirmer: Candidate | None = None
    for candidate, rtol in confirmations:
        paced = candidate.backend == "compiled" and candidate.method in EXPLICIT
        other = explicit_attempt(model, candidate, rtol, setup, ceiling, _bounded(main, candidate, rtol)).trajectory if paced else paced_run(model, candidate, rtol, setup)
        if isinstance(other, Unaffordable):
            continue  # at its pace it would not finish within its budget: not a confirmation
        if not other.failed and len(other.t) == len(main.t):
            own = float(np.max(scaled_errors(other.y, main.y, scale)))
            at = "at the same tolerance" if rtol == tolerance else f"at rtol {tol_text(rtol)}"
            confirmation = f"{other.settings.method} ({other.settings.backend}) {at}"
            confirm = f"confirmed by {confirmation}"
            confirmed_rtol, confirmer = rtol, candidate
            break
    description = f"{main.settings.method} ({main.settings.backend}) at rtol {tol_text(tolerance)}, atol {tol_text(atol_for(tolerance))}, {confirm}"
    return Reference("computed", description, own, main.t, main.y, main.energy, seconds, main.settings, confirmed_rtol, confirmation, confirmer)


def dense(model: Model, reference: Reference) -> Callable[[float, np.ndarray, float, int], tuple[np.ndarray, np.ndarray] | None] | None:
    """A function running the primary reference run again from the state y0 at t0 to t1 with
    `samples` evenly spaced times (its method and tolerance: the reference's dense output there),
    returning (t, y), or None where that run fails; None for a reference that cannot be rerun (exact)."""
    s = reference.settings
    if s is None:
        return None
    settings = s

    def between(t0: float, y0: np.ndarray, t1: float, samples: int) -> tuple[np.ndarray, np.ndarray] | None:
        if not t1 > t0:
            return None
        again = replace(settings, t0=t0, t_end=t1, y0=tuple(float(v) for v in y0), t_eval=tuple(np.linspace(t0, t1, samples).tolist()), until=None, event=None)
        found = integrate(model, again, None, 10 * integrators.MAX_STEPS[again.backend])
        return None if found.failed or len(found.t) != samples else (found.t, found.y)

    return between


def horizon(model: Model, setup: Setup, tolerance: float) -> Horizon | None:
    """Two primary reference runs started delta = tolerance apart (every component moved by
    delta times its size): whether they part exponentially, and when (once per model and setup)."""
    return memo.once(model, ("horizon", *reference_key(setup, tolerance)), lambda: _horizon(model, setup, tolerance))


def linear(model: Model) -> bool:
    """Whether the equations of motion are linear in the state with constant coefficients: M free of
    the state and of t, and F affine in the state with coefficients free of both (a drive F(t) allowed;
    inputs at their defaults, defined functions written out). Two solutions of such a system part as
    the homogeneous system's solutions do, by the same linear map as the solutions themselves: never
    chaotically."""

    def compute() -> bool:
        if model.constraints:
            return False  # the motion on a constraint surface is not linear in general
        forms = substitute(model).with_definitions().symengine
        variables = {*forms.q, *forms.qd, forms.t}
        if any(entry.free_symbols & variables for row in forms.mass for entry in row):
            return False
        return not any(real_diff(f, s).free_symbols & variables for f in forms.forcing for s in (*forms.q, *forms.qd))

    return memo.once(model, ("linear",), compute)


def _horizon(model: Model, setup: Setup, tolerance: float) -> Horizon | None:
    if model.constraints:
        return None  # moving the state would violate the constraints (decided before the base run, which was then thrown away: up to 2e6 steps a regime)
    if linear(model):
        return None  # nothing to measure: two more tight runs (audit 7 F4, two coupled oscillators over t = 1e5: 17 s of stress's 35)
    primary, _ = reference_candidates(model, setup, tolerance)
    if primary.method in IMPLICIT:
        return None  # stiff (dissipative) at the start: two more tight implicit runs would cost more than the whole study
    if primary.backend == "compiled":
        setup = replace(setup, reference_max_steps=min(setup.reference_steps, scaled(setup, EXPLICIT_REFERENCE_STEPS)))  # as the reference's own attempts
    base = explicit_attempt(model, primary, tolerance, setup).trajectory if primary.backend == "compiled" else run(model, primary, tolerance, setup, reference=True)
    if base.failed:
        return None
    names = [*model.coordinates, *(f"{c}_dot" for c in model.coordinates)]
    moved = {n: v + tolerance * max(1.0, abs(v)) for n, v in zip(names, base.settings.y0, strict=True)}
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


def prepare(
    model: Model,
    setup: Setup,
    ref_tol: float,
    progress: Callable[[str], None] | None = None,
    window: float = HORIZON_THRESHOLD,
    hint: str = ", looser --tolerances",
    implicit: tuple[float, ...] | None = None,
) -> tuple[Setup, Reference, Horizon | None, tuple[str, ...]]:
    """The reference (exact, or computed at `ref_tol` and confirmed), and the window: when nearby
    trajectories part exponentially, cut to where runs started `ref_tol` apart are `window` apart
    (at most HORIZON_THRESHOLD): the predictability horizon of the runs to be measured."""
    notes: list[str] = []
    reference = exact_reference(model, setup)
    found: Horizon | None = None
    if reference is None and model.exact:
        notes.append("the file's exact solution was not used (it does not cover every coordinate, or the initial state was changed)")
    if reference is None:
        reference = linear_reference(model, setup)
    if reference is None:
        if progress:
            progress("reference")
        found = horizon(model, replace(setup, times=tuple(np.linspace(0.0, setup.t_end, max(len(setup.times), min(4 * len(setup.times), HORIZON_SAMPLES))).tolist())), ref_tol)
        end = min(found.time_to(window), found.horizon) if found is not None and found.chaotic else math.inf
        if 0 < end < setup.t_end:
            assert found is not None
            setup = replace(setup, t_end=end, times=tuple(np.linspace(0.0, end, len(setup.times)).tolist()))
            notes.append(
                f"chaotic: nearby trajectories part at about {found.lyapunov:.2g}/s; errors are measured up to t = {end:.3g}, where runs started {tol_text(ref_tol)} apart are {window:.0e} apart"
            )
        reference = computed_reference(model, setup, ref_tol, hint, implicit)
    return setup, reference, found, tuple(notes)
