"""Numerical stability on stiff and extreme cases: push a system towards its hard regimes and report what breaks.

    report = stress(model, scales=[("k", [1e2, 1e4, 1e6, 1e8])], accuracy=1e-6)
    report.outcomes        # per regime: every method's cheapest run meeting the accuracy, a diagnosis, a recommendation
    report.passed          # False when in some regime no method meets the accuracy
    report.failed          # ... and that regime is decided (no run of it was stopped by a time limit)

Budgets count steps (`max_steps` per run, see `accuracy`), never seconds, so that the verdict is
the same on any machine under any load. An optional `time_limit` (seconds per measured run) is a
safety net only: a regime where no method met the accuracy and some run was stopped by it is
"undecided", never failed.

Regimes: a parameter sweep (`k=1e2..1e8`), or else the file's own setup, a long horizon
(t_end x `long_factor`), a high energy (velocities x `energy_factor`; a start at rest gets the
velocity of the slowest mode times the factor; kept constraints are respected) and, when
one exists, a start near a singular configuration (where cond M(q) is largest, found by trying
0, +-pi/2 and pi for each coordinate, moved 0.01 away from it).

In each regime scipy's RK45 first runs at its default tolerances (rtol 1e-3, atol 1e-6: what a
user gets without asking), then every candidate runs at tolerances from 10x the accuracy down
by decades to 100x the reference's (stopping at the first that meets it, at a failure, or when
a tighter tolerance stops buying accuracy), against a reference as in `accuracy`: exact, or
computed at 1e-8 x the accuracy (at least TIGHTEST) and confirmed. For a chaotic system the
window is cut to where runs started the reference tolerance apart are 1e-3 x the accuracy
apart, beyond which no tolerance of the ladder can meet the accuracy; the diagnosis says so.
The diagnosis is made along the reference trajectory: the Jacobian's eigenvalues (stiffness
ratio, time scales, the fastest unmatched decay x t_end and the stability-limited explicit
step count, by the rules of `diagnostics.choose` that `simulate --method auto` also uses,
a decay counting only if no state of the run grows at MATCHED x its rate or more; growth
rates, which an implicit method does not help with, are reported apart), the
explicit method's step count against the implicit one's, cond M (coordinate singularities),
drift of the energy, ignorable momenta and constraints, and blow-ups.

Where the explicit reference cannot go (stiff at the start, or it fails or runs out of its
budget), the reference is Radau confirmed by LSODA (else BDF), at the tightest of 1e-4 x .. 0.1 x
the accuracy at which Radau finishes (scipy's implicit methods are round-off-limited well above
double precision on stiff systems); the two agree to within the reference's own error, and a run
meets the accuracy only when its error plus that own error is within it. A regime is undecided
(exit 0), never failed, when no reference can be made (unless both reference methods blow up at
the same time: the system's own blow-up), or when the reference's own error leaves it open (above
REFERENCE_ROOM x the accuracy, with no method meeting it); its
diagnosis is then made along what the reference run reached, and a measurement that could not be
made is reported as not measured, with why. cond M is sampled along the reference's dense
output (`diagnostics.condition_peak`), and a coordinate singularity names the coordinate and the
change of coordinates to make.

Rungs known to miss: a regime over a longer span from the same start and parameters (the long horizon after the
defaults) does not run again a rung the earlier regime's run showed to miss by more than any slack
(`_missed_before`): those methods take the same steps over the shared span.

Budget: compiled candidates (auto first) run before scipy's; once a method meets the accuracy,
the others' runs are capped at LOSING (scipy's RK45: NAIVE_LOSING; a scipy run after a compiled
one met it: PYTHON_AFTER_COMPILED) times its work, counted in right-hand side evaluations (`work`),
and only runs that could tie are timed again.

Timing: each method's final run (and scipy's default run) is timed again TIMED_RUNS times after
the ladders, in turns (`runs.interleave`), and methods within TIE_MARGIN (10%) of the recommended
one's run time are reported as ties (`Outcome.ties`), not as slower.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model
from lagrange_cli.numeric import accuracy as study
from lagrange_cli.numeric import compile, diagnostics, policy
from lagrange_cli.numeric.reference import (
    CHAOS_GROWTH,
    CONVERGENCE_STEP,
    HORIZON_THRESHOLD,
    IMPLICIT,
    IMPLICIT_TIGHTEST,
    STABLE_PROBE,
    Horizon,
    Reference,
    ReferenceFailed,
    ahead,
    dense,
    implicit_first,
    implicit_tolerances,
    prepare,
    stable_steps,
)
from lagrange_cli.numeric.runs import (
    COMPILED_STEPS,
    PACE_MARGIN,
    TIGHTEST,
    Candidate,
    Point,
    PointStatus,
    Ran,
    Setup,
    backend_for,
    capped_steps,
    check_steps,
    compiled_radau,
    component_scale,
    measure,
    retime,
    settings_for,
    start_of,
    starting,
    step_factor,
    ties,
    tol_text,
    unrun,
    warm_study,
    work,
)
from lagrange_cli.numeric.settings import Settings, validate
from lagrange_cli.numeric.status import Failure

NAIVE = Candidate("RK45", "python")
"""scipy's default method, what a user reaches for first."""
NAIVE_RTOL = 1e-3
"""solve_ivp's default rtol (with atol = rtol x ATOL_RATIO = 1e-6, its default too): how a user first runs it."""
SAMPLES = 2001
"""Evenly spaced times over the file's t_end at which errors are measured (the largest of them is what
"meets" judges by): dense enough to catch the worst point of an eccentric orbit (Kepler e = 0.9,
2.3 periods: the error at the periapsis passages; 101 or 201 samples understated it 1.6-1.7x,
2001 by 1-2%). A longer regime gets as many per unit time, up to MAX_SAMPLES."""
MAX_SAMPLES = 20001
STALLED = 2.0
"""Two decades in a row that each shrink an error below SATURATED by less than this end a
method's ladder; errors above SATURATED (a phase lost entirely) may not shrink for a while."""
SATURATED = 0.01
EXPLOSION = 10.0  # explicit steps / implicit steps above which the explicit step count has exploded
SCALES = 100.0  # fastest rate / typical slowest rate above which a run has two time scales
FAST_RADIANS = 1000.0  # ... provided the fast motion turns through this many radians over the run


@dataclass(frozen=True)
class Regime:
    name: str
    t_end: float
    parameters: Mapping[str, float]
    initial: Mapping[str, float]
    samples: int = SAMPLES
    """Evenly spaced times its errors are measured at."""
    horizon: bool = False
    """A regime of stress's own past the time the file (or --t-end) asks for: the long horizon."""


class Finding(str):
    """One thing the diagnosis found, as the sentence shown (`kind: detail`), with its `kind` (what
    the summary shows) and `detail` kept apart, so that nothing splits the sentence back."""

    kind: str
    detail: str
    note: bool
    """About one run (over its budget, stopped by the time limit), not the system: the summary's diagnosis leaves it out
    (audit 11, F5: a symplectic run's budget note read as the system's diagnosis)."""

    def __new__(cls, kind: str, detail: str = "", note: bool = False) -> Finding:
        finding = super().__new__(cls, f"{kind}: {detail}" if detail else kind)
        finding.kind, finding.detail, finding.note = kind, detail, note
        return finding


@dataclass(frozen=True)
class Diagnosis:
    """What was measured along the reference trajectory (or, when no reference could be made,
    along what its run reached, `where` says so); a measurement that could not be made is None,
    `unmeasured` saying why - never a placeholder number."""

    decay_span: float | None
    """max over the trajectory of the fastest unmatched decay rate x t_end (stiff above diagnostics.STIFF)."""
    stiffness_ratio: float | None
    scale_ratio: float | None
    rate: float | None
    condition: float | None
    """max cond M(q) along the trajectory, sampled densely (`diagnostics.condition_peak`)."""
    findings: tuple[Finding, ...]
    where: str = "along the reference trajectory"
    unmeasured: str = ""
    """Why the measurements that are None could not be made."""
    condition_at: float | None = None
    """When cond M peaked."""
    followed: float = 0.0
    """max over the trajectory of the fastest decay that was the solution's own motion (within
    diagnostics.OWN x the rate it changes at, `diagnostics.own_rate`) x t_end: not stiffness, not in `decay_span`."""


@dataclass(frozen=True)
class Outcome:
    regime: Regime
    t_end: float
    """The measured window (shorter than the regime's t_end when chaotic)."""
    reference: str
    reference_error: float
    points: tuple[Point, ...]
    """Per candidate, its cheapest run meeting the accuracy, else its last run."""
    diagnosis: Diagnosis
    recommended: Point | None
    naive: Point | None
    auto: Point | None
    naive_default: Point | None = None
    """scipy's RK45 at its default tolerances (rtol 1e-3, atol 1e-6)."""
    ties: tuple[Point, ...] = ()
    """Other methods meeting the accuracy within TIE_MARGIN of the recommended one's run time: as good a choice."""
    open_reason: str = ""
    """Why no verdict can be given although no method was shown to meet the accuracy: no reference
    could be made (short of a confirmed blow-up), or the reference's own error leaves it open."""
    known: tuple[str, ...] = ()
    """Rungs of a method's ladder not run because an earlier regime's run showed them to miss (`_missed_before`)."""
    beyond: str = ""
    """Why a regime of stress's own (the long horizon) was not run: the model itself ends before its
    t_end (its mass matrix singular in time, whatever the state). Such a regime has no verdict."""

    @property
    def met(self) -> bool:
        return self.recommended is not None

    @property
    def undecided(self) -> bool:
        """No method was shown to meet the accuracy, but it is open: some run was stopped by the
        time limit (it might have met it), or `open_reason`."""
        return not self.met and not self.beyond and (bool(self.open_reason) or any(p.status == PointStatus.UNDECIDED for p in self.points))

    def meets(self, point: Point, target: float) -> bool:
        """Whether `point` is shown to meet `target`: its error against the reference plus the
        reference's own error (a conservative bound on the true error) is within it."""
        own = self.reference_error if math.isfinite(self.reference_error) else math.inf
        return point.ok and point.error + own <= target

    @property
    def verdict(self) -> str:
        return "met" if self.met else "beyond the model" if self.beyond else "undecided" if self.undecided else "not met"


@dataclass(frozen=True)
class Report:
    title: str
    accuracy: float
    outcomes: tuple[Outcome, ...]

    @property
    def passed(self) -> bool:
        return all(o.met or o.beyond for o in self.outcomes)

    @property
    def failed(self) -> bool:
        """Some regime is decided and no method meets the accuracy there (what exits 1)."""
        return any(not o.met and not o.undecided and not o.beyond for o in self.outcomes)

    @property
    def verdict(self) -> str:
        return "passed" if self.passed else "failed" if self.failed else "undecided"


def parse_scale(text: str) -> tuple[str, tuple[float, ...]]:
    """`k=1e2..1e8` (every decade), `k=1,10,50` (a list)."""
    name, equals, values = text.partition("=")
    try:
        if not equals or not name.strip():
            raise ValueError
        if ".." in values:
            low, high = (float(v) for v in values.split(".."))
            if not (low > 0 and high > 0):
                raise ValueError
            a, b = sorted((math.log10(low), math.log10(high)))
            found = tuple(10.0 ** (a + k) for k in range(round(b - a) + 1))
        else:
            found = tuple(float(v) for v in values.split(","))
    except ValueError:
        raise LagrangeError(f"--scale {text!r}: expected name=low..high (every decade, both positive) or name=v1,v2,..., e.g. --scale k=1e2..1e8") from None
    return name.strip(), found


def regimes(model: Model, scales: Sequence[tuple[str, Sequence[float]]], long_factor: float = 10.0, energy_factor: float = 3.0, t_end: float | None = None) -> tuple[Regime, ...]:
    """The regimes to run: the sweeps, or the defaults, a long horizon, high energy and near-singular start."""
    base = validate(model, method="DOP853", backend="python", t_end=t_end)
    known = [p.name for p in model.parameters]
    if scales:
        result = []
        for name, values in scales:
            if name not in known:
                raise LagrangeError(f"--scale: '{name}' is not a parameter of {model.source}; parameters: {', '.join(known) or 'none'}")
            result += [Regime(f"{name} = {v:g}", base.t_end, {name: v}, {}) for v in values]
        return tuple(result)
    longer = min(MAX_SAMPLES, max(SAMPLES, round((SAMPLES - 1) * long_factor) + 1))
    result = [Regime("defaults", base.t_end, {}, {}), Regime(f"long horizon (t_end x {long_factor:g})", base.t_end * long_factor, {}, {}, longer, horizon=True)]
    energetic, mode = _high_energy(model, base.values, base.y0, energy_factor, base.t0)  # at rest (mode): "x 3" would be 0, the velocities come from the slowest mode
    how = f"velocities x {energy_factor:g}" if mode is None else f"at rest in the file: velocities {energy_factor:g} x the {mode}'s rate x each coordinate's size"
    result.append(Regime(f"high energy ({how})", base.t_end, {}, energetic))
    singular = _near_singular(model, base.values, base.y0)
    if singular is not None:
        result.append(Regime(singular[0], base.t_end, {}, singular[1]))
    return tuple(result)


def _names(model: Model) -> list[str]:
    return [*model.coordinates, *(f"{c}_dot" for c in model.coordinates)]


CREEPING = 0.01
"""A high-energy regime started from rest sets its velocities from the slowest mode's rate, or, where that is
below this times the slowest oscillatory mode's (`diagnostics.Spectrum.oscillation`), from the latter: audit 6's
F1, a cart on a Coulomb (tanh) friction rail whose friction mode creeps at 4.5e-4/s got velocities of 1.4e-3
m/s and rad/s, the defaults again, for a pendulum that swings at 2.2 rad/s (Van der Pol, mu = 1000: 4.2e-4/s
against its oscillation's 1.5/s)."""


def _high_energy(model: Model, p: Sequence[float], y0: Sequence[float], factor: float, t0: float) -> tuple[dict[str, float], str | None]:
    """The high-energy regime's initial velocities, and which mode's rate set them where the file starts at rest
    ("slowest mode", or "slowest oscillation": CREEPING), None where it does not.

    With kept constraints a . v + b = 0 at (t0, q0), the velocities are the part the constraints prescribe,
    v_b = -a^T (a a^T)^-1 b (a constraint moving in time: b = df/dt), plus `factor` x the free part, the file's
    velocities projected onto a . v = 0: "at rest" means that free part is 0. Audit 9 F1: a pendulum whose length is
    pumped by a kept constraint was started with all its velocities x 3 projected onto a . v = 0, so at rest
    radially, off its constraint, and its verdict was about a state simulate calls inconsistent. The slowest mode
    is then one along the constraints (`policy.initial_spectrum`'s `tangent`): the Cartesian pendulum with a multiplier
    at rest got 2.2e-5 m/s from a spurious 2.7e-4/s mode across its rod, its defaults again."""
    n = model.n
    v = np.array(y0[n:], dtype=float)
    prescribed = np.zeros(n)
    free = np.eye(n)
    tangent = None  # the free directions, an orthonormal basis: the slowest mode is one that moves along the constraints
    if model.constraints:
        import sympy as sp

        values = {parameter.symbol: value for parameter, value in zip(model.parameters, p, strict=False)}
        rows = sp.Matrix([[*c.jacobian, c.bias] for c in model.constraints]).subs(values)
        try:
            ab = np.array(sp.lambdify([model.t, *model.q], rows.tolist(), modules="math")(t0, *y0[:n]), dtype=float)
            a, b = ab[:, :n], ab[:, n]
            prescribed = -a.T @ np.linalg.solve(a @ a.T, b)
            free = free - a.T @ np.linalg.solve(a @ a.T, a)
            _, _, rows = np.linalg.svd(a)
            tangent = rows[len(a) :].T
        except (ArithmeticError, ValueError, TypeError, np.linalg.LinAlgError):
            pass  # the constraint rows cannot be evaluated (or are dependent) at the start: velocities as they are; the run reports it
    moving = free @ v
    mode = None
    if not np.any(np.abs(moving) > (1e-12 * max(1.0, float(np.max(np.abs(v)))) if model.constraints else 0.0)):  # a projection's round-off is 0
        mode = "slowest mode"
        found = policy.initial_spectrum(model, p, y0, tangent)
        rate = found.slowest if found is not None and found.slowest > 0 else 1.0
        if found is not None and found.oscillation > 0 and rate < CREEPING * found.oscillation:
            rate, mode = found.oscillation, "slowest oscillation"  # a creeping mode (a friction's, a relaxation's) would leave it at rest
        sizes = diagnostics.coordinate_sizes(y0, n)  # r = 7e6 m moves by metres per second, not by 1e-6 of itself
        # along the constraints, each free direction at the rate x the sizes of the coordinates it moves: the rate x sizes
        # projected onto them can all but cancel (the multiplier pendulum at 2.5 rad: 0.07 of the rate, a slow creep)
        moving = free @ (rate * sizes) if tangent is None else tangent @ (rate * (np.abs(tangent).T @ sizes))
    v = prescribed + factor * moving
    return dict(zip(_names(model)[n:], v.tolist(), strict=True)), mode


def _near_singular(model: Model, p: Sequence[float], y0: Sequence[float]) -> tuple[str, dict[str, float]] | None:
    """Where cond M is largest when one coordinate is set to 0, +-pi/2 or pi: a start 0.01 from it
    (from 0, 0.01 of the coordinate's initial size when that is above 1: r = 7e6 m starts at
    7e4 m, not at 1 cm)."""
    condition = diagnostics.mass_condition(model, p, y0)
    best: tuple[float, int, float] | None = None
    for i in range(model.n):
        for value in (0.0, math.pi / 2, -math.pi / 2, math.pi):
            y = np.array(y0, dtype=float)
            y[i] = value
            c = condition(0.0, y)
            if c > 1e10 and (best is None or c > best[0]):
                best = (c, i, value)
    if best is None:
        return None
    _, i, value = best
    y = np.array(y0, dtype=float)
    start = value + (0.01 * float(diagnostics.coordinate_sizes(y0, model.n)[i]) if value == 0.0 else 0.01)
    y[i] = start
    name = model.coordinates[i]
    return f"near singular ({name} = {start:.3g}, cond M = {condition(0.0, y):.1e})", {name: start}


AUTO = Candidate("auto")
FAILURE_FINDINGS = (Failure.SINGULAR, Failure.NONFINITE, Failure.STEP_COLLAPSE, Failure.SURFACE_JUMP, Failure.STALLED)
"""Failed runs the diagnosis reports: a blow-up, a singular matrix, a step that collapsed (at a singularity, or too stiff)."""


def default_candidates(model: Model) -> tuple[Candidate, ...]:
    return (NAIVE, *study.default_candidates(model), AUTO)


TIMED_RUNS = 2
"""Timed runs of each method's final run (and scipy's default run) after the ladders, in turns."""
MAX_STEPS = 60_000
"""The default step budget of one run (scipy steps, about 4 s of RK45 or BDF in Python on a quiet
machine, as the old 5 s budget; compiled runs 100 x as many, reference runs 10 x)."""
REFERENCE_FACTOR = 1e-8
"""The reference runs at this times the accuracy asked for (at least TIGHTEST)."""
WINDOW_FACTOR = 1e-3
"""A chaotic regime is measured up to where runs started the reference tolerance apart are this
times the accuracy apart: the tightest tolerance of the ladder (100 x the reference's), whose
global error is some 10 x its tolerance, then still meets the accuracy."""


def reference_tolerance(target: float) -> float:
    return max(target * REFERENCE_FACTOR, TIGHTEST)


def ladder(target: float) -> tuple[float, ...]:
    """Tolerances from 10x the target down by decades to 100x the reference's (that floor the last
    rung): a long horizon needs a tolerance far below the error it wants, since errors add up
    over many periods. Each to 12 digits (the floor 2.5e-12, not 2.5000000000000003e-12): what the reference's own
    looser runs ask for (`reference._looser`), so that a rung the reference ran already is not run again (`runs.kept_runs`:
    the multiplier pendulum's long horizon, compiled DOP853 at 2.5e-12, 2.9e5 steps, 1 s), and the rtol a user is told."""
    floor = float(f"{100 * reference_tolerance(target):.12g}")
    rungs = [t for t in (float(f"{target * 10.0 ** (1 - k):.12g}") for k in range(20)) if floor * (1 + 1e-9) < t < 1]
    return (*rungs, floor)


def stress(
    model: Model,
    *,
    scales: Sequence[tuple[str, Sequence[float]]] = (),
    target: float = 1e-6,
    candidates: Sequence[Candidate] | None = None,
    t_end: float | None = None,
    long_factor: float = 10.0,
    energy_factor: float = 3.0,
    max_steps: int = MAX_STEPS,
    time_limit: float | None = None,
    progress: study.ProgressReport | None = None,
) -> Report:
    """Every regime; see the module docstring. `progress` is told as each regime finishes, and
    which run a regime is on."""
    if not (0 < target < 1e-1):
        raise LagrangeError(f"--accuracy must lie between 0 and 0.1, got {target:g}")
    if target < 1e3 * TIGHTEST:
        raise LagrangeError(f"--accuracy {target:g} leaves no room for a reference 1000 times tighter; give at least {1e3 * TIGHTEST:.1e}")
    model = model.with_definitions()  # the mass matrix and constraint rows are evaluated here too
    check_steps(max_steps)
    if time_limit is not None and not (math.isfinite(time_limit) and time_limit > 0):
        raise LagrangeError(f"the time limit must be a positive number of seconds, got {time_limit:g}")
    chosen = tuple(candidates) if candidates else default_candidates(model)
    planned = regimes(model, scales, long_factor, energy_factor, t_end)
    warm_study(model, chosen)
    outcomes = []
    earlier: list[_Earlier] = []
    for k, regime in enumerate(planned):
        say = (lambda text, k=k, name=regime.name: progress(study.Step(k, len(planned), name, text))) if progress else None
        outcomes.append(_regime(model, regime, target, chosen, Setup(0.0, (), max_steps=max_steps, time_limit=time_limit, raised=max(1.0, max_steps / MAX_STEPS)), say, earlier))
        if progress:  # a regime's work grows with its time span (a long horizon is long_factor x the others)
            progress(study.Step(k + 1, len(planned), regime.name, fraction=sum(r.t_end for r in planned[: k + 1]) / sum(r.t_end for r in planned)))
    return Report(model.title, target, tuple(outcomes))


LOSING = 10.0
"""Once a method meets the accuracy, another method's runs are stopped at this many times its work
(right-hand side evaluations; a compiled one counting 1/COMPILED_STEPS): it cannot be the
recommendation (work maps to run time only roughly, but a tie needs 1.1x), so the budget is spent where the
verdict is still open (30x and 100x before: two thirds of `stress`'s time on Kepler's orbit went to capped runs)."""
NAIVE_LOSING = 30.0
"""... scipy's RK45, whose cost against the recommendation the report shows, at this many times."""
RETIME_WITHIN = 2.0
"""Only runs within this factor of the fastest meeting run's first time are timed again (the
others cannot tie with it; 3 before: the k = 1e10 pendulum's long horizon timed compiled DOP853's
3.5 s run again against RK45's 1.5 s, a sixth of the regime)."""


def _order(model: Model, setup: Setup, candidates: Sequence[Candidate]) -> list[Candidate]:
    """auto first, then the method auto picks at the start (Radau when stiff), then compiled
    candidates before scipy's: so that a cheap method meeting the accuracy is found first and caps
    what the others may spend (a stiff system's explicit runs are then capped, not run to their budget);
    scipy's implicit methods before the compiled explicit ones where those are stability-limited to more
    than `reference.IMPLICIT_FIRST_STEPS` steps (`implicit_first`)."""
    picked = policy.decide(model, replace(start_of(model, setup), method="auto", backend="auto")).method
    stiff = picked in IMPLICIT  # then scipy's implicit methods before its explicit ones, which a stiff system keeps at their stability limit
    limited = implicit_first(model, setup)  # the pilot (not only the start) finds it stiff: auto may still pick compiled DOP853
    # compiled Radau before everything, auto too, where it runs compiled and the explicit methods are stability-limited: its run
    # caps theirs and scipy's (auto's pick in Python, LSODA: 4 rungs of 33000-60000 steps on the angle-damped spring at r = 0.011)
    first = limited and compiled_radau()
    return sorted(
        candidates,
        key=lambda c: (
            not (first and ahead(c)),
            c != AUTO,
            c.method != picked,
            limited and not ahead(c),
            backend_for(c) != "compiled",
            stiff and c.method not in IMPLICIT,
        ),
    )


REFERENCE_ROOM = 0.1
"""A regime where no method meets the accuracy is decided ("not met", exit 1) only when the reference's
own error is within this times the accuracy; above it, it is open (undecided): the penalty pendulum's
long horizon, own error 7.9e-7 from a Radau reference at 1e-7, left the runs 2.1e-7 while the ladder's
tightest rung, 10 x Radau's rtol, could not reach it (a false "not met")."""


@dataclass(frozen=True)
class _Earlier:
    """A regime's measured runs, kept for the regimes after it (`_missed_before`)."""

    name: str
    setup: Setup
    scale: np.ndarray
    own: float
    runs: Mapping[tuple[Candidate, float], Point]
    ended: frozenset[tuple[Candidate, float]]
    """The rungs where a ladder stopped because no tighter run could be the recommendation (its work, or the work its
    error's fall predicts, against the run that met the accuracy): not where the reference could not vouch."""
    stalled: ReferenceFailed | None = None
    """Its reference stopped where the coordinates end (`ReferenceFailed.coordinates`; `runs` then empty): a later regime from the same
    start over a longer span stalls there too, and makes no reference attempt of its own (`_stalled_before`)."""


def _stalled_before(setup: Setup, earlier: Sequence[_Earlier]) -> ReferenceFailed | None:
    """The reference failure of an earlier regime of the same parameters and start whose reference stalled where the
    coordinates end before this regime's t_end (audit 11's pendulum in x, y: the long horizon's reference attempts, as
    long as the defaults' own, stalled at the same state)."""
    for before in earlier:
        found = before.stalled
        reached = found.trajectory if found is not None else None
        if found is None or reached is None or reached.t_last >= setup.t_end:
            continue
        if dict(before.setup.parameters) == dict(setup.parameters) and dict(before.setup.initial) == dict(setup.initial):
            return ReferenceFailed(f"{found} (as in regime {before.name}, from the same start)", coordinates=True, trajectory=reached, attempts=found.attempts)
    return None


PREFIX_METHODS = ("RK45", "DOP853", "Radau", "BDF")
"""Methods whose steps do not depend on t_end or on the sample times, only on the start, the rtol and the system,
so that a run over a longer span takes the same steps as a shorter one up to the shorter one's last step (clipped to
end there): compiled and scipy's alike, checked bit for bit on the samples (LSODA's are not the same: its Fortran
steps towards the end time; `auto` and the symplectic method choose from t_end)."""
PREFIX_SLACK = 100.0
"""Where the shorter run's last step, clipped to end on its t_end, and the longer run's step there differ, their samples
differ by about a step's local error, within rtol x the scale; this many times the rtol is taken off the shorter
run's error before it counts as a lower bound of the longer run's."""


def _missed_before(
    model: Model, candidate: Candidate, tolerance: float, tighter: float | None, setup: Setup, earlier: Sequence[_Earlier], scale: np.ndarray, own: float, target: float
) -> tuple[str, bool]:
    """Why the run of `candidate` at `tolerance` need not be made in this regime: an earlier regime of the same
    parameters and start, over a shorter span whose sample times are among this one's, ran it with the same settings
    and it missed the accuracy there by more than any slack. The longer run takes the same steps over that span
    (PREFIX_METHODS), so its error at those samples, against this regime's reference, is at least the earlier error
    less PREFIX_SLACK x rtol and both references' own errors, rescaled to this regime's component scales. Only a rung
    the earlier ladder went on from (its next rung, `tighter`, was run there too), so that the ladder here goes on
    too, or the rung where the earlier ladder stopped because a tighter run could not be the recommendation ("not run
    tighter", True: the ladder here stops too, with that reason; its runs would take longer still). ("", False) when
    it must be run."""
    if model.constraints:
        return "", False  # kept constraints: the state is projected at each sample, so the samples change the steps
    times = np.array(setup.times)
    for before in earlier:
        shorter = before.setup
        point = before.runs.get((candidate, tolerance))
        if not shorter.t_end < setup.t_end or point is None or not point.ok or point.settings is None:
            continue
        went_on = tighter is not None and (candidate, tighter) in before.runs
        stopped = not went_on and (candidate, tolerance) in before.ended
        if not (went_on or stopped):
            continue
        theirs = np.array(shorter.times)
        at = np.clip(np.searchsorted(times, theirs), 0, len(times) - 1)
        near = np.minimum(np.abs(times[at] - theirs), np.abs(times[np.maximum(at - 1, 0)] - theirs))
        if len(theirs) == 0 or float(np.max(near)) > 1e-12 * setup.t_end:
            continue
        mine = settings_for(model, candidate, tolerance, setup)  # `auto` resolved: the same method, and it did not switch from it there
        if mine.method not in PREFIX_METHODS or point.ran != Ran(mine.method, mine.backend):
            continue
        if _made_key(replace(mine, t_end=0.0, t_eval=())) != _made_key(replace(point.settings, t_end=0.0, t_eval=())):
            continue  # the same start, parameters, method and tolerances: all but the span and the samples
        ratio = float(np.min(before.scale / scale))
        bound = (point.error - PREFIX_SLACK * tolerance) * ratio - before.own - own
        if bound > target:
            why = (
                f"{'auto -> ' if candidate == AUTO else ''}{point.resolved} at rtol {tol_text(tolerance)} not run: it misses over t = 0 .. {shorter.t_end:.3g} already (regime {before.name}: error"
                f" {point.error:.1e} there; over a longer span it takes the same steps, so its error here is at least {bound:.1e})"
            )
            return (f"{why}; there its ladder stopped: {point.reason}", True) if stopped else (why, False)
    return "", False


def _regime(model: Model, regime: Regime, target: float, candidates: Sequence[Candidate], budget: Setup, say: Callable[[str], None] | None, earlier: list[_Earlier] | None = None) -> Outcome:
    """One regime; `budget` carries the step budget and time limit; `earlier` the regimes before it (this one is added)."""
    times = tuple(np.linspace(0.0, regime.t_end, regime.samples).tolist())
    setup = starting(model, Setup(regime.t_end, times, dict(regime.parameters), dict(regime.initial), budget.max_steps, time_limit=budget.time_limit, raised=budget.raised))
    ended = _model_end(model, setup)
    if ended is not None:
        return _ended(model, regime, setup, ended)
    ref_tol = reference_tolerance(target)
    ends = _stalled_before(setup, earlier or ())
    if ends is not None:
        return _without_reference(model, regime, setup, ends)
    try:
        setup, reference, horizon, _ = prepare(model, setup, ref_tol, say, window=WINDOW_FACTOR * target, hint=", a looser --accuracy", implicit=implicit_reference_tolerances(target))
    except ReferenceFailed as error:
        if earlier is not None and error.trajectory is not None and error.coordinates:
            earlier.append(_Earlier(regime.name, setup, np.ones(1), math.inf, {}, frozenset(), stalled=error))
        return _without_reference(model, regime, setup, error)
    scale = component_scale(reference.y)
    own = reference.own_error if math.isfinite(reference.own_error) else math.inf
    points: dict[Candidate, Point] = {}
    runs: dict[tuple[Candidate, float], Point] = {}
    made: dict[Settings, Point] = {}  # every run of the regime by its decided settings, so that none is made twice
    best: Point | None = None
    looser = reference.settings is not None and (reference.settings.method in IMPLICIT or reference.settings.rtol > ref_tol * (1 + 1e-9))
    floor = 10 * reference.settings.rtol if looser and reference.settings is not None else 0.0
    rungs = tuple(t for t in ladder(target) if t >= floor * (1 - 1e-9)) or (ladder(target)[0],)  # a run as tight as an implicit reference would measure the reference against itself
    vouches = own < target  # else no run can be shown to meet the accuracy: the verdict is open whatever they do
    open_only = own > REFERENCE_ROOM * target  # then, unless a run meets the accuracy, the verdict is open (never "not met")
    proof: dict[str, float] = {}  # scipy's RK45 shown equal to its compiled twin (`_twin`)
    twinned = any(c in candidates for c in (TWIN, Candidate("RK45")))  # the twin a candidate too: scipy's RK45 shows scipy's cost; else it is run as asked
    known: list[str] = []
    stopped_at: set[tuple[Candidate, float]] = set()  # (`_Earlier.ended`)
    for candidate in _order(model, setup, candidates):
        if not vouches and candidate != AUTO and backend_for(candidate) != "compiled":
            why = "unconfirmed" if not math.isfinite(own) else f"{own:.1e}"
            points[candidate] = unrun(candidate, rungs[0], PointStatus.UNDECIDED, f"not run: the reference's own error ({why}) cannot vouch for {tol_text(target)}, so no run could decide the verdict")
            continue
        last: Point | None = None
        near_misses: list[tuple[float, float]] = []  # scipy's RK45 not run: its near twin's rtol and error (`_near_twin_misses`)
        stalls = 0
        spent = 0.0  # the work of this method's runs so far
        previous_tolerance = rungs[0]
        for tolerance in rungs:
            if say:
                say(f"{candidate.label} {tol_text(tolerance)}")
            if best is not None and _remaining(candidate, best, spent) <= 0 and last is not None:
                reason = f"not run tighter: its runs already took {spent / max(work(best), 1e-300):.2g} x the work of {best.method} ({best.setting}), which meets the accuracy"
                last = runs[(candidate, previous_tolerance)] = replace(last, reason=reason)
                stopped_at.add((candidate, previous_tolerance))
                break
            tighter = next((r for r in rungs if r < tolerance * (1 - 1e-9)), None)
            # not where the reference cannot vouch: there a method's first run, the loosest, only shows how far off it is
            missed, stopped = ("", False) if (candidate == NAIVE and twinned) or not vouches else _missed_before(model, candidate, tolerance, tighter, setup, earlier or (), scale, own, target)
            if stopped:
                last = unrun(candidate, tolerance, PointStatus.CAPPED, missed)
                stopped_at.add((candidate, tolerance))
                break
            if missed:
                known.append(missed)
                continue
            near = _near_twin_misses(model, tolerance, setup, reference, scale, made, _cap(NAIVE, best, last, setup, spent), target) if candidate == NAIVE and twinned else None
            if near is not None:
                near_misses.append((tolerance, near))
                continue
            if candidate == NAIVE and twinned:
                previous, last = last, _twin(model, tolerance, setup, reference, scale, best, last, spent, made, open_only, proof)
            else:
                previous, last = last, _capped(model, candidate, tolerance, setup, reference, scale, best, last, spent, made, open_only)
            runs[(candidate, tolerance)] = last
            spent += work(last)
            previous_tolerance = tolerance
            if not last.ok or last.error + own <= target:
                break
            if not vouches:
                # no run can be shown to meet the accuracy (`vouches`): the regime is undecided whatever tighter runs do, and its
                # first run shows how far each method is from the reference (the Euler-angle top near its pole, every regime's
                # reference unable to vouch: 4 rungs of each compiled ladder per regime; Kepler e = 0.9 started at r = 0.01,
                # reference own error 1.1: compiled DOP853 at 1e-6, 1e-7 and 1e-8, 8.8 s, against a reference off by its size)
                why = "unconfirmed" if not math.isfinite(own) else f"{own:.1e}"
                last = runs[(candidate, tolerance)] = replace(
                    last, reason=f"not run tighter: the reference's own error ({why}) cannot vouch for {tol_text(target)}, so no tighter run could decide the verdict"
                )
                break
            if best is not None and work(last) > _losing(candidate, best, last) * work(best):
                if last.ok:
                    ratio = work(last) / max(work(best), 1e-300)
                    last = runs[(candidate, tolerance)] = replace(last, reason=f"not run tighter: it already took {ratio:.2g} x the work of {best.method} ({best.setting}), which meets the accuracy")
                    stopped_at.add((candidate, tolerance))
                break  # tighter tolerances cost more still: it cannot be the recommendation
            growth = predicted_growth(previous, last)
            if best is not None and work(last) * growth > _remaining(candidate, best, spent):
                ratio = work(last) * growth / max(work(best), 1e-300)
                reason = (
                    f"not run tighter: its work grew {growth:.2g} x from the rtol before, so the next would take about {ratio:.2g} x the work of"
                    f" {best.method} ({best.setting}), which meets the accuracy: above what it may spend"
                )
                last = runs[(candidate, tolerance)] = replace(last, reason=reason)
                stopped_at.add((candidate, tolerance))
                break  # it would be stopped at its cap: it cannot be the recommendation
            far = _out_of_reach(candidate, previous, last, target - own, best, spent, setup, open_only)
            if far:
                last = runs[(candidate, tolerance)] = replace(last, reason=far)
                stopped_at.add((candidate, tolerance))
                break  # at the pace its error falls, the run that would meet the accuracy costs more than it may spend
            stalled = previous is not None and previous.ok and previous.error < SATURATED and last.error > previous.error / STALLED
            stalls = stalls + 1 if stalled else 0
            if stalls == 2:
                break  # tighter tolerances no longer buy accuracy (round-off, or an error floor)
        if near_misses:
            known.append(_near_note(model, near_misses))
        if last is not None:
            points[candidate] = last
            if last.ok and last.error + own <= target and (best is None or work(last) < work(best)):
                best = last
    ordered = [points[c] for c in candidates if c in points]
    naive_default = None
    if NAIVE in candidates:  # after the ladders, so that a recommendation caps its budget
        if say:
            say(f"{NAIVE.label} {NAIVE_RTOL:.0e} (scipy's default)")
        near = _near_twin_misses(model, NAIVE_RTOL, setup, reference, scale, made, _cap(NAIVE, best, None, setup), target)
        naive_default = (
            unrun(NAIVE, NAIVE_RTOL, PointStatus.CAPPED, _near_note(model, [(NAIVE_RTOL, near)], named=False))
            if near is not None
            else _capped(model, NAIVE, NAIVE_RTOL, setup, reference, scale, best, None)
        )
    if say:
        say("timing the runs in turns")
    ordered, naive_default = _retimed(model, ordered, naive_default, setup, target, own)
    meeting = [p for p in ordered if p.ok and p.error + own <= target and not p.predicted]  # a predicted time decides nothing
    recommended = min(meeting, key=lambda p: p.seconds) if meeting else None
    tied = ties(meeting, recommended, target - own) if recommended is not None else ()
    naive = next((p for p in ordered if p.candidate == NAIVE), None)
    auto = next((p for p in ordered if p.candidate == AUTO), None)
    diagnosis = diagnose(model, setup, reference, ordered, runs, target, horizon, cut=setup.t_end < regime.t_end)
    open_reason = ""
    if recommended is None and not math.isfinite(reference.own_error):
        open_reason = "the reference is unconfirmed (its second method did not finish), so no run can be shown to meet the accuracy"
    elif recommended is None and any(p.ok and p.error <= target for p in ordered):
        open_reason = (
            f"runs come within {tol_text(target)} of the reference, but the reference's own error ({reference.own_error:.1e}) leaves open whether they meet it"
            f" ({_why_own(reference)}){_closest(ordered, own, target)}"
        )
    elif recommended is None and own > target:
        open_reason = f"the reference's own error ({reference.own_error:.1e}) is above the accuracy asked: no run can be shown to meet it ({_why_own(reference)}){_closest(ordered, own, target)}"
    elif recommended is None and own > REFERENCE_ROOM * target:
        open_reason = (
            f"the reference's own error ({reference.own_error:.1e}) leaves the runs less than {1 - REFERENCE_ROOM:.0%} of the accuracy asked, and no rung of the ladder"
            f" comes within what is left: a failure of the methods cannot be told from the reference's{_closest(ordered, own, target)}"
        )
    if earlier is not None:
        earlier.append(_Earlier(regime.name, setup, scale, own, dict(runs), frozenset(stopped_at)))
    return Outcome(regime, setup.t_end, reference.description, reference.own_error, tuple(ordered), diagnosis, recommended, naive, auto, naive_default, tied, open_reason, tuple(known))


def _why_own(reference: Reference) -> str:
    """Why the reference's own error is what it is, for an open verdict: a confirmation at a looser rtol
    than the reference's measures its own error (it could not finish tighter), else the two methods
    agree no better at equal terms (round-off, or the system's sensitivity)."""
    s = reference.settings
    if reference.convergence == reference.own_error:
        alone = s is not None and reference.confirmer == Candidate(s.method, s.backend)
        return f"it is the disagreement of the reference's own method at a {CONVERGENCE_STEP:g} x looser rtol, an upper bound of the reference's error while that converges with the tolerance" + (
            " (no second method was asked: its agreement could not lower it)" if alone else " (the second method agreed better, but two methods at equal rtols may share an error)"
        )
    if s is not None and math.isfinite(reference.confirmed_rtol) and reference.confirmed_rtol > s.rtol * (1 + 1e-9):
        return (
            f"its confirmation, {reference.confirmation}, ran looser than the reference's rtol {tol_text(s.rtol)}: the disagreement is mostly that run's"
            " own error, and no tighter confirmation finished or came closer"
        )
    return "the two methods, at equal terms, agree no better: round-off, or the trajectory's sensitivity, limits how well they can agree here"


def _closest(points: Sequence[Point], own: float, target: float) -> str:
    """ "; the closest run ..." with the numbers of an open verdict: the run nearest the reference, and
    what its distance says of its true error (at least that distance minus the own error)."""
    finished = [p for p in points if p.ok and math.isfinite(p.error)]
    if not finished:
        return ""
    best = min(finished, key=lambda p: p.error)
    text = f"; the closest run, {best.method} ({best.setting}), is {best.error:.1e} off the reference"
    if math.isfinite(own) and best.error - own > target:
        text += (
            f", so at least {best.error - own:.1e} off the true solution as far as the own error bounds the reference's:"
            f" no run measured meets {tol_text(target)}, though the ladder may not have been run to its end"
        )
    return text


STABILITY_MARGIN = 2.0
"""An explicit run whose stability-limited steps (`reference.stable_steps`) exceed this times its step
budget is not run: it would spend the whole budget to learn what the count says (scipy's RK45 on
the damped spring of k = 1e10 in r over the long horizon: 2 x 60000 steps, a third of `stress`'s time)."""


def _made_key(settings: Settings) -> Settings:
    """What makes two runs the same run: their decided settings, less the notes saying why they were chosen."""
    return replace(settings, notes=())


def _same_run(model: Model, candidate: Candidate, tolerance: float, setup: Setup, made: Mapping[Settings, Point], cap: int) -> Point | None:
    """An earlier run of the regime with the settings this one decides to (`auto`'s run of the method it
    resolved to: compiled DOP853 at the same rtol) that finished, or failed, within this run's step budget
    `cap`: the run is deterministic, so running it again takes the same steps to the same result (on the
    trammel, auto's four compiled DOP853 runs were made again by DOP853's ladder, 8 of the defaults' 32 s).
    None when there is none: the run is made."""
    if not made or candidate == AUTO:
        return None
    try:
        decided = settings_for(model, candidate, tolerance, setup)
    except LagrangeError:
        return None
    earlier = made.get(_made_key(decided))
    if earlier is None or earlier.status not in (PointStatus.FINISHED, PointStatus.FAILED) or earlier.failure in (Failure.BUDGET, Failure.TIME_LIMIT):
        return None
    if earlier.steps > cap * step_factor(decided.method, decided.backend):
        return None
    return replace(earlier, method=candidate.label, candidate=candidate)


def _capped(
    model: Model,
    candidate: Candidate,
    tolerance: float,
    setup: Setup,
    reference: Reference,
    scale: np.ndarray,
    best: Point | None,
    last: Point | None,
    spent: float = 0.0,
    made: dict[Settings, Point] | None = None,
    open_only: bool = False,
) -> Point:
    """`measure`, within the step budget `_cap` leaves it once `best` meets the accuracy; an explicit
    run that its stability limit alone would take past STABILITY_MARGIN x that budget is not run; a run
    the regime has made already (`made`, by decided settings: `_same_run`) is not made again.
    `open_only`: the regime cannot be "not met" (OPEN_PACE_MARGIN)."""
    cap = _cap(candidate, best, last, setup, spent)
    again = _same_run(model, candidate, tolerance, setup, made, cap) if made is not None else None
    if again is not None:
        return again
    method = candidate.method if candidate.method != "auto" else ""
    needed = stable_steps(model, setup, method)
    allowed = cap * (COMPILED_STEPS if backend_for(candidate) == "compiled" else 1)
    if needed > STABILITY_MARGIN * allowed:
        reason = (
            f"not run: stiff, so its steps are stability-limited: about {needed:.3g} steps to t_end (the fastest decay along a pilot run x t_end / {STABLE_PROBE[method]:g}),"
            f" above {STABILITY_MARGIN:g} x its step budget ({allowed})"
        )
        return unrun(candidate, tolerance, PointStatus.OVER_BUDGET, reason, Failure.BUDGET)
    beyond = _beyond_twin(model, tolerance, setup, reference, scale, made if made is not None else {}, cap) if candidate == NAIVE else ""
    if beyond:
        if cap < setup.steps and best is not None:
            reason = f"{beyond}; its budget is {_losing(candidate, best):g} x the work of {best.method} ({best.setting}), which meets the accuracy: it could only lose"
            return unrun(candidate, tolerance, PointStatus.CAPPED, reason, Failure.BUDGET)
        return unrun(candidate, tolerance, PointStatus.OVER_BUDGET, beyond, Failure.BUDGET)
    # a Python run is stopped as soon as its pace shows it cannot finish within PACE_MARGIN x its budget (`runs.PACE_AFTER` of it
    # taken first): whether it can only lose to `best` or would run out of its whole budget, it decides nothing more by going on
    # (audit4 F7: the trammel's long horizon, where nothing met the accuracy, ran scipy's four methods to 60000 steps each)
    margin = OPEN_PACE_MARGIN if open_only and best is None else PACE_MARGIN
    point = measure(model, candidate, tolerance, replace(setup, max_steps=cap) if cap < setup.steps else setup, reference, scale, repeats=0, paced=True, margin=margin)
    if cap < setup.steps and point.failure == Failure.BUDGET and best is not None and point.steps:
        beaten = f"{best.method} ({best.setting}), which meets the accuracy"
        if point.nfev:  # stopped by its cap
            done = f"{100 * point.reached:.0f}% of the time span" if point.reached is not None else "its step budget"
            reason = f"stopped after {point.steps} steps at {done}: it already took {work(point) / max(work(best), 1e-300):.2g} x the work of {beaten}"
        else:  # stopped by its pace (`runs.PACE_MARGIN`) before its cap
            reason = f"{point.reason}; its budget is {_losing(candidate, best):g} x the work of {beaten}: it could only lose"
        point = replace(point, status=PointStatus.CAPPED, reason=reason)
    if made is not None and point.settings is not None:
        made.setdefault(_made_key(point.settings), point)
    return point


TWIN = Candidate("RK45", "compiled")
"""scipy's RK45 (`NAIVE`)'s compiled twin: the same Dormand-Prince pair, step control and dense output."""
TWIN_ERROR = 1e-6
"""The relative difference of the errors below which scipy's RK45 and its twin count as the same run (with equal
steps and evaluations): round-off of two implementations of one algorithm (1e-11 apart on the double pendulum)."""


def _twin(
    model: Model,
    tolerance: float,
    setup: Setup,
    reference: Reference,
    scale: np.ndarray,
    best: Point | None,
    last: Point | None,
    spent: float,
    made: dict[Settings, Point],
    open_only: bool,
    proof: dict[str, float],
) -> Point:
    """A rung of scipy's RK45 (`NAIVE`) ladder. Its first finished run is made, and its compiled twin (TWIN, at
    the same rtol) with it: where the two take the same steps and evaluations to the same error (TWIN_ERROR), the
    regime's `proof` holds scipy's time per step, and every later rung is not run: its steps, evaluations and
    errors are the twin's at that rtol (a run of the regime, or made here, compiled: 100-500 x cheaper), its time
    that per-step time x the steps, and the point is `predicted` (never the recommendation nor timed again). The
    swinging Atwood machine's long horizon: scipy's ladder to rtol 2.5e-12, 20 s, took compiled RK45's steps
    exactly at every rung. Where the two differ (a projected run, or round-off), or the twin's steps exceed what
    scipy's run may take, the run is made."""
    cap = _cap(NAIVE, best, last, setup, spent)
    per_step = proof.get("per_step")
    if per_step is not None:
        twin = _twin_run(model, tolerance, setup, reference, scale, made, cap)
        if twin is not None and twin.steps <= cap:
            decided = settings_for(model, NAIVE, tolerance, setup)
            reason = (
                f"not run: the steps, evaluations and errors are those of compiled RK45 at this rtol (the same algorithm; equal on a real run at rtol"
                f" {tol_text(proof['rtol'])}: {proof['steps']:.0f} steps alike, errors equal to {TWIN_ERROR:g}), the time predicted from scipy's time per step there"
            )
            return replace(
                twin,
                method=NAIVE.label,
                candidate=NAIVE,
                ran=Ran(decided.method, decided.backend),
                resolved=str(Ran(decided.method, decided.backend)),
                settings=decided,
                seconds=per_step * twin.steps,
                runs=0,
                compile_seconds=0.0,
                predicted=True,
                reason=reason,
            )
    point = _capped(model, NAIVE, tolerance, setup, reference, scale, best, last, spent, made, open_only)
    if not proof and point.ok and point.steps:
        twin = _twin_run(model, tolerance, setup, reference, scale, made, cap)
        alike = twin is not None and twin.ok and twin.steps == point.steps and twin.nfev == point.nfev
        if alike and twin is not None and abs(twin.error - point.error) <= TWIN_ERROR * max(point.error, 1e-300):
            proof.update(per_step=point.seconds / point.steps, rtol=tolerance, steps=float(point.steps))
        else:
            proof["differs"] = 1.0  # not the same run: every rung is made
    return point


def _same_steps(model: Model) -> bool:
    """Whether scipy's RK45 and its compiled twin take the same steps on `model`: not with kept constraints (the twin
    projects inside its loop, scipy's run restarts at each projection) nor with switching functions (where the forces
    jump, scipy rejects steps the compiled loop steps across)."""
    return not model.constraints and int(getattr(compile.build(model, "python").module, "_SWITCHES", 0)) == 0


TWIN_BEYOND = 1.1
"""scipy's RK45 (`NAIVE`) is not run where its compiled twin (TWIN) at the same rtol takes more than this times the
scipy run's step budget (`_beyond_twin`): the same algorithm takes the same steps (to round-off, which this margin
covers), so it would run out of its budget. The penalty pendulum of k = 1e9 over t = 50: scipy's RK45 at its default
rtol spent 15000 steps, 5.3 s, to be stopped by its pace, where its twin is stability-limited to some 7e5 steps."""


def _beyond_twin(model: Model, tolerance: float, setup: Setup, reference: Reference, scale: np.ndarray, made: dict[Settings, Point], cap: int) -> str:
    """Why scipy's RK45 at `tolerance` within `cap` steps is not run ("" to run it): its compiled twin at that rtol (the
    regime's run, else made now within TWIN_BEYOND x `cap` compiled steps, a few ms to a second) took more than TWIN_BEYOND x
    `cap`. Only where the two are the same run: no kept constraints (projections) and no switching functions (where the
    forces jump, scipy rejects steps the compiled loop steps across)."""
    if not _same_steps(model):
        return ""
    try:
        decided = settings_for(model, TWIN, tolerance, setup)
    except LagrangeError:
        return ""
    if decided.backend != "compiled":
        return ""
    limit = math.floor(TWIN_BEYOND * cap)
    twin = made.get(_made_key(decided))
    if twin is None or twin.status not in (PointStatus.FINISHED, PointStatus.OVER_BUDGET):
        budget = max(1, math.ceil((limit + 1) / COMPILED_STEPS))  # scipy steps: the compiled run may take COMPILED_STEPS x as many
        twin = measure(model, TWIN, tolerance, replace(setup, max_steps=min(budget, setup.steps)), reference, scale, repeats=0)
        if twin.status == PointStatus.FINISHED and twin.settings is not None:
            made.setdefault(_made_key(twin.settings), twin)
    if twin.steps <= limit or twin.status not in (PointStatus.FINISHED, PointStatus.OVER_BUDGET):
        return ""
    took = f"took {twin.steps} steps" if twin.status == PointStatus.FINISHED else f"did not finish within {twin.steps} steps"
    return f"not run: its compiled twin (compiled RK45 at this rtol: the same Dormand-Prince pair and step control, so the same steps) {took}, more than {TWIN_BEYOND:g} x its step budget ({cap})"


NEAR_TWIN_MISS = 100.0
"""scipy's RK45 (`NAIVE`) on a system with kept constraints or switching functions, where its compiled twin takes other
steps (projected at the samples inside its loop, where scipy's restarts there; crossings located on its own dense
output), is not run at an rtol where that twin misses the accuracy by more than this factor (`_near_twin_misses`): the
same Dormand-Prince pair and step control at the same rtol, they differ in how the steps meet the samples and the
surfaces, not by orders of magnitude. The trammel's long horizon, where nothing met the accuracy, spent 11 of its 27 s on
scipy's RK45 at rtol 1e-5 (6.6 s) and at its default 1e-3 (4.3 s, error 2.0) to show it missing."""


def _near_twin_misses(model: Model, tolerance: float, setup: Setup, reference: Reference, scale: np.ndarray, made: dict[Settings, Point], cap: int, target: float) -> float | None:
    """The error of scipy's RK45's near twin at `tolerance` where it shows that scipy's run need not be made, on a system
    where the compiled twin is not the same run (kept constraints or switching functions: `_twin` cannot prove them
    alike, `_beyond_twin` does not apply): that twin at this rtol (the regime's run, else made now within `cap` scipy
    steps' worth) misses by more than NEAR_TWIN_MISS x `target`. None: run it."""
    if _same_steps(model):
        return None
    twin = _twin_run(model, tolerance, setup, reference, scale, made, cap)
    return twin.error if twin is not None and twin.ok and twin.error > NEAR_TWIN_MISS * target else None


def _near_note(model: Model, misses: Sequence[tuple[float, float]], named: bool = True) -> str:
    """What `_near_twin_misses` found at the rtols `misses` (rtol, the compiled twin's error), in a line (`named`: for the
    regime's notes, else for the run's own row)."""
    rtols, errors = [tol_text(rtol) for rtol, _ in misses], [f"{error:.1e}" for _, error in misses]
    at = f"rtol {rtols[0]}" if len(misses) == 1 else f"rtols {', '.join(rtols)}"
    by = ", ".join(errors)
    how = "projected at the samples inside its loop, where scipy's restarts at each" if model.constraints else "its crossings located on its own dense output"
    return (
        f"{f'{NAIVE.label} at {at} ' if named else ''}not run: compiled RK45 {'there' if named else 'at this rtol'} misses by {by}, more than {NEAR_TWIN_MISS:g} x the accuracy asked; scipy's RK45 is the same"
        f" Dormand-Prince pair and step control (the twin {how}), so it misses too"
    )


def _twin_run(model: Model, tolerance: float, setup: Setup, reference: Reference, scale: np.ndarray, made: dict[Settings, Point], cap: int) -> Point | None:
    """TWIN's run at `tolerance`: the regime's (`made`), else made now within `cap` scipy steps' worth of compiled steps."""
    try:
        decided = settings_for(model, TWIN, tolerance, setup)
    except LagrangeError:
        return None
    if decided.backend != "compiled":
        return None
    earlier = made.get(_made_key(decided))
    if earlier is not None and earlier.status in (PointStatus.FINISHED, PointStatus.FAILED):
        return earlier
    point = measure(model, TWIN, tolerance, replace(setup, max_steps=min(cap, setup.steps)), reference, scale, repeats=0)
    if point.settings is not None:
        made.setdefault(_made_key(point.settings), point)
    return point if point.status == PointStatus.FINISHED else None


OPEN_PACE_MARGIN = 1.0
"""Where the reference's own error leaves a regime open unless some run meets the accuracy (above
REFERENCE_ROOM x it: never "not met"), and none has yet, a Python run is stopped once its pace (judged
after `runs.PACE_AFTER` of its budget) needs more than this times its budget, not PACE_MARGIN: a run
out of its budget meets nothing, and one stopped early can at most leave the verdict open, which it is
already (audit4 F7: the trammel's long horizon, own error 3.7e-7, ran scipy's Radau, BDF, LSODA and
RK45 each to its 60000 steps, at 62%, 33%, 39% and 94% of the span, about two thirds of its 112 s)."""


SAME_BACKEND_LOSING = {"compiled": 1.5, "python": 2.5}
"""Once a method's run misses the accuracy with more than this times the work of `best`, a run that
meets it, on the same backend, its tighter tolerances (more work still) are not run: on one backend
work maps to run time closely (compiled RK45 73 ns an evaluation, DOP853 69 ns; scipy's LSODA 31 us,
Radau 39 us, BDF 62 us with their Jacobians and factorisations), so it cannot be the recommendation
nor tie with it (compiled DOP853 over the k = 1e10 pendulum's long horizon: 1.6 x the work of RK45
at rtol 1e-5, then 3.5 s at 1e-6 to meet the accuracy 2.4 x slower)."""


PYTHON_AFTER_COMPILED = 2.0
"""Once a compiled run meets the accuracy, a scipy run (Python right-hand side) is stopped at this
many times its work: `work` already counts a compiled evaluation as 1/COMPILED_STEPS of a scipy one,
where it costs 1/170-1/500 as much (73-170 ns against 29-62 us), so such a run is already 3-8x slower
than the compiled one and cannot be the recommendation nor tie with it (the penalty pendulum of
k = 1e9: scipy's RK45, Radau, BDF and LSODA spent 38 of the defaults regime's 46 s losing to
compiled DOP853's 0.05 s run at 10-30x). Not lower: 0.5 was tried, and on the stiff elastic pendulum
started near r = 0 (compiled evaluations 170 ns, LSODA's 29 us) it stopped LSODA's ladder before rtol
1e-8, whose run is 2x faster than compiled RK45's, so the recommendation became the slower method."""


FASTEST_FALL = 10.0
"""`_out_of_reach` counts the rungs a ladder still needs as if its error fell at least this many times a rung (a
decade of rtol) from its last run on, however slowly it fell so far: a fall measured at loose rtols can speed
up (the damped cart's long horizon: LSODA 1.3 x from 1e-7 to 1e-8, then 8 x to 1e-9, where it met the accuracy)."""


def _out_of_reach(candidate: Candidate, previous: Point | None, last: Point | None, need: float, best: Point | None, spent: float, setup: Setup, open_only: bool = True) -> str:
    """Why a scipy method's ladder stops where its error falls too slowly to meet the accuracy affordably ("" to go
    on): from its last two finished runs, the error falling g x a rung and the work growing `predicted_growth` x, the
    rung that would bring it within `need` (the accuracy less the reference's own error) is n rungs on; at least two
    rungs on (the next alone is `_regime`'s own rule), it stops where those n runs would take more than what it may
    still spend once `best` meets the accuracy (`_remaining`), or, before anything meets and only where the regime
    can at most stay open (`open_only`: its reference's own error above REFERENCE_ROOM x the accuracy), where the last
    of them alone would take more than one run's whole step budget at its work per step: a prediction from two
    rungs can be pessimistic (the swinging Atwood machine's long horizon, chaotic: LSODA's error fell 1.1 x from
    1e-6 to 1e-7, and 10 x a decade further on), so it never stops the only runs that could decide a verdict.
    A compiled method's ladder (not auto's) stops too once `best` meets, where the last of those runs alone would
    take more than `_losing` x best's work, as `_regime` stops it once a run has: the weakly damped coupled
    oscillators over t = 1e5, compiled RK45 at rtol 1e-7 and 1e-8 (1.1e6 and 1.7e6 steps, 3.4 s of each regime's
    18) to end 6.8e-5 off against 1e-6.
    Counted in evaluations. Van der
    Pol (mu = 1000): scipy's BDF at rtol 1e-5, 1e-6 and 1e-7 over t = 2000 was 1.9e-4 ... 1.7e-4 off, each rung
    some 1.4 x the work of the one before (10 s of the regime's 31)."""
    compiled = backend_for(candidate) == "compiled" and candidate != AUTO
    if not (backend_for(candidate) == "python" or (compiled and best is not None)) or previous is None or last is None or not (previous.ok and last.ok) or not (need > 0) or last.error <= need:
        return ""
    gain = previous.error / last.error if last.error > 0 else math.inf
    if not (gain > 1.0) or not math.isfinite(gain):
        return ""  # not falling: the stalls rule decides
    gain = max(gain, FASTEST_FALL)  # a slow fall may speed up (pre-asymptotic): the fewest rungs it could need
    rungs = math.ceil(math.log(last.error / need) / math.log(gain))
    if rungs < 2:
        return ""
    growth = predicted_growth(previous, last)
    if compiled and best is not None:  # `_regime` stops a compiled ladder whose run takes more than `_losing` x best's: the last, the one that would meet, alone
        final = work(last) * growth**rungs
        if final <= _losing(candidate, best, last) * work(best):
            return ""
        return (
            f"not run tighter: even with its error falling {gain:.2g} x a rtol from here, meeting the accuracy needs {rungs} more rtols, the last of them"
            f" alone about {final / max(work(best), 1e-300):.2g} x the work of {best.method} ({best.setting}), which meets it: above what it may spend"
        )
    if best is not None:
        total = work(last) * sum(growth**k for k in range(1, rungs + 1))
        allowed = _remaining(candidate, best, spent)
        if total <= allowed:
            return ""
        return (
            f"not run tighter: even with its error falling {gain:.2g} x a rtol from here, meeting the accuracy needs {rungs} more rtols, taking together about"
            f" {total / max(work(best), 1e-300):.2g} x the work of {best.method} ({best.setting}), which meets it: above what it may spend"
        )
    if not open_only:
        return ""
    per_step = work(last) / max(last.steps, 1)
    final = work(last) * growth**rungs
    allowed = setup.steps * per_step
    if final <= allowed:
        return ""
    return (
        f"not run tighter: even with its error falling {gain:.2g} x a rtol from here, meeting the accuracy needs {rungs} more rtols, the last of them about"
        f" {final / max(per_step, 1e-300):.3g} steps at its {growth:.2g} x growth a rtol: above its step budget ({setup.steps})"
    )


def predicted_growth(previous: Point | None, last: Point | None) -> float:
    """How many times its work a method's next, tighter run will take, predicted from the last two
    finished runs of its ladder (their ratio, at least 1); 1 when there are not two (no prediction).
    Counted in evaluations: scipy's Radau over the damped chain's long horizon took 11 s to be
    stopped at its cap at rtol 1e-7, its work growing steadily from rung to rung."""
    if previous is None or last is None or not (previous.ok and last.ok) or not (work(previous) > 0):
        return 1.0
    return max(1.0, work(last) / work(previous))


def _losing(candidate: Candidate, best: Point | None = None, last: Point | None = None) -> float:
    """How many times `best`'s work a candidate may spend (LOSING; scipy's RK45 NAIVE_LOSING; a scipy
    run once a compiled `best` meets the accuracy PYTHON_AFTER_COMPILED), or
    (with `last`, a finished run of it on `best`'s backend) go on from: SAME_BACKEND_LOSING."""
    if best is not None and last is not None and last.ok and best.ran is not None and last.ran is not None and last.ran.backend == best.ran.backend and candidate != NAIVE:
        return SAME_BACKEND_LOSING.get(last.ran.backend, LOSING)
    if best is not None and best.ran is not None and best.ran.backend == "compiled" and candidate != AUTO and backend_for(candidate) == "python":
        return PYTHON_AFTER_COMPILED
    return NAIVE_LOSING if candidate == NAIVE else LOSING


def _remaining(candidate: Candidate, best: Point, spent: float) -> float:
    """The work a candidate's next run may spend once `best` meets the accuracy: `_losing` x its work,
    less what the candidate's earlier runs spent when they are scipy runs after a compiled `best`
    (PYTHON_AFTER_COMPILED: the whole ladder's, so that four rungs of BDF and LSODA do not each spend
    it; scipy's BDF, LSODA and Radau over the damped chain's long horizon, 33598, 59836 and 9306
    steps, were most of its 24 s)."""
    allowed = _losing(candidate, best) * work(best)
    return allowed - spent if _losing(candidate, best) == PYTHON_AFTER_COMPILED else allowed


def _cap(candidate: Candidate, best: Point | None, last: Point | None, setup: Setup, spent: float = 0.0) -> int:
    """The step budget of a candidate's next run: the setup's, or, once `best` meets the accuracy,
    what `_losing` x its work buys this candidate (in scipy steps, as budgets count them)."""
    return capped_steps(candidate, math.inf if best is None else max(_remaining(candidate, best, spent), 1.0), last, setup)


def _retimed(model: Model, points: list[Point], naive_default: Point | None, setup: Setup, target: float, own: float) -> tuple[list[Point], Point | None]:
    """The runs that may decide the recommendation or a tie: those meeting the accuracy within RETIME_WITHIN of
    the fastest of them (a run that misses it is neither; its first time stands), and scipy's default run, timed
    again in turns (`runs.interleave`). Runs of the same decided settings (auto and the method it picked, at one
    rtol) are one run: timed once, the time given to each (the weakly damped oscillators over t = 1e5: auto's and
    DOP853's 0.9 s run, and RK45's 0.6 s one that missed, each timed twice more, 3 s of each regime)."""
    deciding = [p.ok and p.error + own <= target and not p.predicted for p in points]
    meeting = [p.seconds for p, d in zip(points, deciding, strict=True) if d]
    if not meeting:
        return list(points), naive_default  # no recommendation for the times to decide: the first ones stand
    limit = RETIME_WITHIN * min(meeting)
    chosen = [k for k, p in enumerate(points) if deciding[k] and p.seconds <= limit and p.status == PointStatus.FINISHED]  # only finished runs are timed again
    extra = [naive_default] if naive_default is not None and naive_default.seconds <= limit and naive_default.status == PointStatus.FINISHED else []
    runs_of: dict[object, list[int]] = {}  # the chosen points by their run: one timer each
    for k in chosen:
        settings = points[k].settings
        runs_of.setdefault(replace(settings, notes=()) if settings is not None else k, []).append(k)
    if len(runs_of) + len(extra) < 2:
        return list(points), naive_default  # nothing to compare the one run with: its first time stands
    firsts = [group[0] for group in runs_of.values()]
    timed = retime(model, [points[k] for k in firsts] + extra, setup, TIMED_RUNS)  # in turns: a changing load slows all alike
    result = list(points)
    for group, point in zip(runs_of.values(), timed, strict=False):
        for k in group:
            result[k] = replace(points[k], seconds=point.seconds, runs=point.runs)
    return result, (timed[-1] if extra else naive_default)


def implicit_reference_tolerances(target: float) -> tuple[float, ...]:
    """The rtols an implicit reference (Radau confirmed by LSODA) tries for accuracy `target`,
    tightest first: from 1e-4 x it (at least IMPLICIT_TIGHTEST) to 0.1 x it, the loosest whose
    confirmed error can still vouch for the target (the confirmation decides whether it does)."""
    return implicit_tolerances(max(target * 1e-4, IMPLICIT_TIGHTEST), 0.1 * target)


def _model_end(model: Model, setup: Setup) -> float | None:
    """Where the model itself ends before the regime's t_end: its mass matrix singular whatever the state
    (`diagnostics.time_singularity`), which only a mass matrix depending on t explicitly can be. Audit 7's crane
    reels its rope in to zero length at t = 13.33: the long horizon ran four reference runs of up to 2e6 steps
    each into it, to report "no reference" and a coordinate singularity no coordinates remove."""
    start = start_of(model, setup)
    return diagnostics.model_end(model, start.values, start.t0, setup.t_end, start.y0)


def _ended(model: Model, regime: Regime, setup: Setup, ended: float) -> Outcome:
    """A regime whose t_end lies past the model's end (`_model_end`): nothing is run. The long horizon, stress's
    own, has no verdict (`Outcome.beyond`); a regime over the time the file asks for is not met (exit 1), as no
    method and no coordinates pass that time."""
    start = start_of(model, setup)
    measured = _measure(model, setup, np.array([start.t0]), np.array([start.y0], dtype=float), None, setup.t_end)
    detail = (
        f"the mass matrix is singular at t = {ended:.6g} whatever the state (it depends on t explicitly: a length, mass or inertia of the"
        f" model reaches zero there), before this regime's t_end = {setup.t_end:.6g}. The model itself ends there: no method and no change of"
        f" coordinates passes it; give a t_end before it (--t-end)"
    )
    diagnosis = replace(measured, findings=(Finding("singular in time", detail), *measured.findings), where="at the initial state only (nothing was run)")
    beyond = f"not run: the model ends at t = {ended:.6g}, before this regime's t_end (see the diagnosis)" if regime.horizon else ""
    return Outcome(regime, setup.t_end, "none", math.nan, (), diagnosis, None, None, None, beyond=beyond)


def _without_reference(model: Model, regime: Regime, setup: Setup, error: ReferenceFailed) -> Outcome:
    """A regime where no reference could be made: the diagnosis along what the reference run
    reached, no method tried (nothing to measure them against), and the verdict open - unless
    both reference methods blew up at the same time (a blow-up of the system itself: failed)."""
    reached = error.trajectory
    t, y = (reached.t, reached.y) if reached is not None and len(reached.t) else (np.array([0.0]), np.array([start_of(model, setup).y0], dtype=float))
    where = f"along the reference run up to t = {float(t[-1]):.3g}, where it stopped" if len(t) > 1 else "at the initial state only (the reference run stopped before its first sample)"
    if reached is not None and math.isfinite(reached.t_last) and reached.t_last > float(t[-1]) and np.all(np.isfinite(reached.y_last)):
        # the state it stopped at, past its last sample: where the coordinates end, the one whose cond M shows it (audit 11's
        # Foucault pendulum in x, y: 1.3e4 at the last sample, 1.6e8 where Radau stalled)
        t, y = np.append(t, reached.t_last), np.vstack([y, reached.y_last])
        where = f"along the reference run up to t = {reached.t_last:.6g}, where it stopped"
    measured = _measure(model, setup, t, y, None, setup.t_end)
    kind = "blow-up (both reference methods stop there)" if error.blowup else "no reference: the coordinates end" if error.coordinates else "no reference"
    findings = (Finding(kind, str(error).removeprefix(f"{model.source}: ")), *measured.findings)
    diagnosis = replace(measured, findings=findings, where=where)
    open_reason = "" if error.blowup else "no reference could be made (see the diagnosis), so no method could be measured"
    return Outcome(regime, setup.t_end, "none", math.nan, (), diagnosis, None, None, None, open_reason=open_reason)


def diagnose(
    model: Model,
    setup: Setup,
    reference: Reference,
    points: Sequence[Point],
    runs: Mapping[tuple[Candidate, float], Point],
    target: float,
    horizon: Horizon | None = None,
    cut: bool = False,
) -> Diagnosis:
    """Stiffness, time scales and conditioning along the reference, and what the runs showed
    (`horizon`: how nearby trajectories parted, which says whether growing modes of the linearization are
    chaos; `cut`: whether that chaos cut the window short)."""
    base = _measure(model, setup, reference.t, reference.y, dense(model, reference), setup.t_end)
    if horizon is not None and not horizon.chaotic:
        base = replace(base, findings=tuple(_local(f, horizon) if f.kind == GROWING else f for f in base.findings))
    findings: list[Finding] = []
    if horizon is not None and cut:
        findings.append(
            Finding(
                "chaotic",
                f"nearby trajectories part at about {horizon.lyapunov:.2g}/s, so an error of {tol_text(target)} can only be had up to t = {setup.t_end:.3g}"
                f" (runs started {tol_text(horizon.delta)} apart are {HORIZON_THRESHOLD:.0e} apart at t = {horizon.horizon:.3g}); errors are measured up to there",
            )
        )
    findings += base.findings
    found = _explosion(runs, target)
    if found is not None:
        findings.append(found)
    for point in points:
        if point.status == PointStatus.FAILED and point.failure in FAILURE_FINDINGS:
            findings.append(Finding(f"{point.method} ({point.setting}) failed", point.reason.removeprefix(f"{model.source}: ")))
        elif point.status in (PointStatus.OVER_BUDGET, PointStatus.UNDECIDED):
            findings.append(Finding(f"{point.method} ({point.setting}) {point.reason}", note=True))
        for name, drift in point.drifts:
            if point.ok and drift > 10 * target and point.candidate == NAIVE:
                findings.append(Finding(f"{point.method} ({point.setting})", f"{name} drifts by {drift:.1e} (relative)"))
        if point.ok and point.constraint_drift is not None and point.constraint_drift > target and point.candidate == NAIVE:
            findings.append(Finding(f"{point.method} ({point.setting})", f"constraint drift {point.constraint_drift:.1e}"))
    return replace(base, findings=tuple(findings))


GROWING = "growing modes in the linearization"
"""The finding of a positive eigenvalue along the run (x t_end above diagnostics.STIFF): "unstable modes" before,
which read as instability on integrable systems (Kepler's orbit near periapsis, a trammel passing its potential's
saddle: audit4 F4, F7)."""


def _local(finding: Finding, parting: Horizon) -> Finding:
    """A GROWING finding where runs started `parting.delta` apart were not found chaotic (`reference.CHAOS_GROWTH`)."""
    return Finding(
        finding.kind,
        f"{finding.detail}; runs started {tol_text(parting.delta)} apart end {parting.growth:.2g} x farther apart, growing less than {CHAOS_GROWTH:g} x over"
        " the window's second half: not counted as chaos (a saddle passed, or an effect of the coordinates, makes a linearization grow locally)",
    )


def _explosion(runs: Mapping[tuple[Candidate, float], Point], target: float) -> Finding | None:
    """ "explicit step count explodes" where, at some rtol of the ladder, an explicit run took more than
    EXPLOSION x the steps of Radau's at the same rtol, both finished: a run stopped by its cap or its pace
    took a few steps of its initial transient, which say nothing of its count to t_end (scipy's Radau,
    stopped after 2 steps on a non-stiff elastic pendulum, "against" DOP853's 153 to t_end)."""
    by_method = {(candidate.method, tolerance): point for (candidate, tolerance), point in runs.items() if point.status == PointStatus.FINISHED}
    for tolerance in ladder(target):
        implicit = by_method.get(("Radau", tolerance))
        explicit = max((by_method[(m, tolerance)] for m in ("RK45", "DOP853") if (m, tolerance) in by_method), key=lambda p: p.steps, default=None)
        if explicit and implicit and explicit.steps and implicit.steps and explicit.steps > EXPLOSION * implicit.steps:
            return Finding("explicit step count explodes", f"{explicit.method} took {explicit.steps} steps against Radau's {implicit.steps} at rtol {tol_text(tolerance)}, both to t_end")
    return None


def _measure(model: Model, setup: Setup, t: np.ndarray, y: np.ndarray, rerun: diagnostics.Rerun | None, t_end: float) -> Diagnosis:
    """The spectrum (stiffness, time scales, growth) and cond M along the states (t, y), with the
    findings they make: stiff, two time scales, growing modes, near a coordinate singularity
    (with the coordinate to change)."""
    s: Settings = starting(model, setup).start  # type: ignore[assignment]
    module = compile.build(model, "python", jacobian=True).module
    p = list(policy.code_parameters(s.values, 0.0 if model.constraints else None))
    rhs = policy.safe_rhs(module, tuple(p))
    spectra = []
    for k in np.linspace(0, len(t) - 1, min(25, len(t))).astype(int):
        try:
            state = np.asarray(y[k], dtype=float)  # a decay about as fast as the solution itself changes is its own motion, not stiffness
            found = diagnostics.spectrum(np.asarray(module._jac(float(t[k]), y[k].tolist(), p), dtype=float), diagnostics.own_rate(rhs(float(t[k]), state), state))
        except (ArithmeticError, ValueError, TypeError, np.linalg.LinAlgError):  # also complex values
            found = None
        if found is not None:
            spectra.append(found)
    base = validate(model, method="DOP853", backend="python", t_end=setup.t_end, parameters=setup.parameters).y0  # the file's start sets the coordinates' sizes
    condition = diagnostics.mass_condition(model, s.values, base)
    peak = diagnostics.condition_peak(condition, t, y, rerun)
    findings: list[Finding] = []
    unmeasured = []
    if not spectra:
        unmeasured.append("the Jacobian could not be evaluated at any state reached")
    if peak is None:
        unmeasured.append("no state was reached to evaluate M at")
    decay = max((x.decay for x in spectra), default=0.0)
    rate = max((x.rate for x in spectra), default=0.0)
    stiffness = max((x.stiffness_ratio for x in spectra), default=1.0)
    # the slow scale is the typical slowest rate along the run: at a turning point or an
    # inflection (g cos(theta) = 0) one state's slowest rate passes through 0, which says nothing
    # about time scales
    slow = [x.slowest for x in spectra if x.slowest > 0]
    scales = rate / float(np.median(slow)) if slow else 1.0
    growth = max((x.growth for x in spectra), default=0.0)
    followed = max((x.followed for x in spectra), default=0.0)
    if growth >= diagnostics.MATCHED * decay:
        decay = 0.0  # matched by growth somewhere along the run (a saddle's +-pair, chaos): not stiffness
    # the slowest rate that makes the largest per-state stiffness ratio, so that `stiff` judges by that ratio
    overall = diagnostics.Spectrum(decay, rate, decay / stiffness if 0 < stiffness < math.inf else 0.0, growth)
    if spectra and diagnostics.stiff(overall, t_end):
        steps = diagnostics.explicit_steps(decay, t_end)
        affordable = diagnostics.explicit_affordable(overall, t_end)
        cheap = " (explicit affordable)" if affordable else ""
        findings.append(
            Finding(
                f"stiff{cheap}",
                f"a mode decays at up to {decay:.3g}/s (x t_end = {decay * t_end:.3g}), stiffness ratio {stiffness:.3g}, at most about {steps:.3g} stability-limited"
                f" RK45 steps (the fastest decay x t_end / {diagnostics.STABILITY:g}; DOP853, stable to about {policy.DOP853_STABILITY:g}, half as many; fewer where"
                " the decay is slower along part of the run)",
            )
        )
    elif scales > SCALES and rate * t_end > FAST_RADIANS:
        findings.append(Finding("two time scales (a fast oscillation, not stiff)", f"fastest rate {rate:.3g}/s, {scales:.3g} x the slowest"))
    if growth * t_end > diagnostics.STIFF:
        findings.append(Finding(GROWING, f"growth rate up to {growth:.3g}/s (a saddle, chaos or constraint drift; not stiffness: decays matched by growth are not counted)"))
    if peak is not None and peak.condition > diagnostics.SINGULAR_CONDITION:
        findings.append(_singularity(model, s, condition, peak))
    if not spectra:
        return Diagnosis(None, None, None, None, peak.condition if peak else None, tuple(findings), unmeasured="; ".join(unmeasured), condition_at=peak.t if peak else None)
    return Diagnosis(
        decay * t_end, stiffness, scales, rate, peak.condition if peak else None, tuple(findings), unmeasured="; ".join(unmeasured), condition_at=peak.t if peak else None, followed=followed * t_end
    )


def _singularity(model: Model, start: Settings, condition: Callable[[float, np.ndarray], float], peak: diagnostics.Peak) -> Finding:
    """`near a coordinate singularity`, naming the coordinate, where, how M turns singular (against M at the regime's
    `start`), and the change to make."""
    mass_of = diagnostics.mass_at(model, start.values)
    mass = mass_of(peak.t, peak.y)
    found = diagnostics.singular_coordinate(model.coordinates, condition, peak.t, peak.y, mass, mass_of(start.t0, start.y0))
    detail = f"cond M reaches {peak.condition:.2g} at t = {peak.t:.4g}"
    if found is None:
        return Finding("near a coordinate singularity", f"{detail} along the trajectory")
    at = f"{found.coordinate} = {_angle(found.near)}" if found.near is not None else f"{found.coordinate} near {found.value:.3g}"
    along = " + ".join(f"{w:.2g} {name}_dot" for name, w in found.direction).replace("+ -", "- ")
    how = "grows without bound" if found.unbounded else "vanishes"
    where = f" ({found.coordinate} = {found.value:.3g} there; M's inertia {how} along {along})" if along else f" ({found.coordinate} = {found.value:.3g} there)"
    regular = (
        "for a direction or a position on a sphere, angles or a unit vector instead of components with a height solved from the constraint"
        " (sqrt reaches 0 at the edge of the region such coordinates describe)"
        if found.unbounded
        else "for an orientation a unit vector or a quaternion, or Euler angles whose singular axis points away from the motion; for a direction,"
        " Cartesian components instead of polar and azimuthal angles"
    )
    away = "give a t_end before the motion gets there (--t-end)" if found.unbounded else f"start away from {at} (--initial {found.coordinate}=...)"
    advice = f"coordinates singular at {at}: {detail}{where}. The coordinates, not the motion, are singular there: describe the system with coordinates regular there ({regular}), or {away}"
    return Finding("near a coordinate singularity", advice)


def _angle(value: float) -> str:
    return {0.0: "0", math.pi / 2: "pi/2", -math.pi / 2: "-pi/2", math.pi: "pi", -math.pi: "-pi"}.get(value, f"{value:.3g}")


def json_text(report: Report) -> str:
    import json

    from lagrange_cli.numeric.reports import simulate_options

    def number(value: float | None) -> float | None:
        return value if value is not None and math.isfinite(value) else None

    def point(p: Point | None) -> dict[str, object] | None:
        if p is None:
            return None
        return {
            "method": p.method,
            "ran": p.resolved,
            "setting": p.setting,
            "simulate": simulate_options(p),
            "status": p.status,
            "error": number(p.error),
            "final_rms_error": number(p.final_rms_error),
            "seconds": number(p.seconds),
            "steps": p.steps,
            "nfev": p.nfev,
            "reason": p.reason,
        }

    document = {
        "system": report.title,
        "accuracy": report.accuracy,
        "passed": report.passed,
        "verdict": report.verdict,
        "regimes": [
            {
                "regime": o.regime.name,
                "verdict": o.verdict,
                "t_end": o.t_end,
                "parameters": dict(o.regime.parameters),
                "initial": dict(o.regime.initial),
                "reference": o.reference,
                "reference_error": number(o.reference_error),
                "open_reason": o.open_reason or None,
                "beyond": o.beyond or None,
                "measured": o.diagnosis.where,
                "not_measured": o.diagnosis.unmeasured or None,
                "max_mass_condition_at": number(o.diagnosis.condition_at),
                "stiffness_ratio": number(o.diagnosis.stiffness_ratio),
                "decay_x_t_end": number(o.diagnosis.decay_span),
                "own_motion_decay_x_t_end": number(o.diagnosis.followed),
                "time_scale_ratio": number(o.diagnosis.scale_ratio),
                "max_mass_condition": number(o.diagnosis.condition),
                "findings": [str(f) for f in o.diagnosis.findings],
                "not_run": list(o.known),
                "recommended": point(o.recommended),
                "ties": [point(p) for p in o.ties],
                "naive": point(o.naive),
                "naive_default": point(o.naive_default),
                "auto": point(o.auto),
                "runs": [point(p) for p in o.points],
            }
            for o in report.outcomes
        ],
    }
    return json.dumps(document, indent=2, allow_nan=False) + "\n"
