"""The runs of a study: candidates, what they share (`Setup`), one measured run (`measure` -> `Point`).

A `Point` is typed: what was asked (`candidate`), what ran (`ran`: the method and backend), its
`status` (`PointStatus`) and, when it gave no error, why (`failure`, a `status.Failure`), so that
`stress` and the reports decide by kind and never parse a message back; `reason` is the message
for people.

Errors compare the samples at evenly spaced times with the reference's (see accuracy.py). Budgets
count steps, never seconds (`MAX_STEPS`, `COMPILED_STEPS`, `REFERENCE_STEPS`).
"""

from __future__ import annotations

import enum
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model
from lagrange_cli.numeric import compile, diagnostics, memo, policy, switching
from lagrange_cli.numeric.settings import COMPILED, METHODS, Settings, validate
from lagrange_cli.numeric.simulate import InvariantKind, Trajectory, fixed_steps, integrate, run_seconds
from lagrange_cli.numeric.status import Failure, Status

if TYPE_CHECKING:
    from lagrange_cli.numeric.reference import Reference

STUDY_METHODS = tuple(m for m in METHODS if m != "auto")
ATOL_RATIO = 1e-3  # atol = rtol x ATOL_RATIO (`atol_for`)


def atol_for(rtol: float) -> float:
    """The atol that goes with `rtol`: rtol x ATOL_RATIO to 12 digits, so that 1e-9 gives 1e-12 (the product is
    1.0000000000000002e-12, which a printed setting would have to repeat in full to repeat the run)."""
    return float(f"{rtol * ATOL_RATIO:.12g}")


TIGHTEST = 2.5e-14  # no run is asked for less (double precision)
MAX_STEPS = 200_000
"""The default step budget of one measured run of a study, in scipy steps (10-20 thousand a second
in Python on a small system, Radau about 5 thousand: some 10-40 s per run on a quiet machine, as
the old 20 s budget). Counted, never timed: the same run is over its budget on any machine under any load."""
COMPILED_STEPS = 100
"""A compiled run may take this many times the budget (a compiled step costs about 1 us)."""
REFERENCE_STEPS = 10
"""Reference runs (at tolerances 1000 x tighter, often over long windows) may take this many times the budget."""


def tol_text(value: float) -> str:
    """A tolerance or accuracy as written: 1e-06, 2.5e-12."""
    text = f"{value:.1e}"
    return f"{value:.0e}" if text[1:3] == ".0" else text


def exact_text(value: float) -> str:
    """A number as short as `tol_text` writes it where that reads back as the same float (1e-06),
    else in full (`repr`: 0.011296182345...): a printed setting that repeats the run bit for bit."""
    forms = (tol_text(value), f"{value:g}") if abs(value) < 1e-2 else (f"{value:g}", tol_text(value))
    return next((form for form in forms if float(form) == value), repr(float(value)))


@dataclass(frozen=True)
class Candidate:
    """A method and the backend it runs on ("auto" picks compiled for RK45/DOP853 when numba is there)."""

    method: str
    backend: str = "auto"

    @property
    def label(self) -> str:
        return self.method if self.backend == "auto" else f"{self.method}:{self.backend}"


def parse_candidate(text: str) -> Candidate:
    """`DOP853`, `RK45:python`, `auto`: a method, optionally with its backend (user input, parsed once)."""
    name, _, backend = text.strip().partition(":")
    for known in METHODS:
        if name.lower() == known.lower():
            if backend and backend not in ("auto", "compiled", "python"):
                raise LagrangeError(f"--method {text!r}: unknown backend '{backend}'; write METHOD or METHOD:compiled or METHOD:python")
            return Candidate(known, backend or "auto")
    raise LagrangeError(f"unknown method '{name}'; choose from {', '.join(METHODS)} (optionally METHOD:python or METHOD:compiled)")


def default_candidates(model: Model) -> tuple[Candidate, ...]:
    """Every method of `simulate` that applies to the system. The symplectic method is left out
    where it cannot run (kept constraints, no numba) and where the system dissipates (a Rayleigh
    function): there its energy is not conserved, so a symplectic method has nothing to keep and
    is an implicit Runge-Kutta method without error control; its pilot's compilation alone was a
    third of `stress` on a damped stiff system. `--method symplectic` still measures it.

    Radau is the compiled one (`backend_for`), with kept constraints too: it projects onto them inside
    its loop (kernels.radau_projected, one compiled run), as the compiled explicit pairs do."""
    skip = bool(model.constraints) or not compile.numba_available() or model.dissipative
    methods = [m for m in STUDY_METHODS if not (m == "symplectic" and skip)]
    return tuple(Candidate(m) for m in methods)


def warm_study(model: Model, candidates: Sequence[Candidate]) -> None:
    """Start compiling ahead, in a process of their own (`compile.warm_kernels`), the loops of the study's methods
    other than the explicit ones its reference compiles first: compiled Radau's (radau_start and the loop the system
    needs: projected onto kept constraints, landing on switching surfaces, or plain) and the symplectic method's. A
    no-op once they are in the cache."""
    if not compile.numba_available():
        return
    loops = ["radau_projected"] if model.constraints else ["radau_run", "radau_switched"]
    if any(c.method == "Radau" and backend_for(c) == "compiled" for c in candidates) and not all(map(compile.kernel_cached, ["radau_start", *loops])):
        if len(loops) > 1:  # which of the two the system needs: its module (the one compiled Radau runs) says
            loops = loops[1:] if switching.located(compile.build(model, "numba", jacobian=True).module) else loops[:1]
        compile.warm_kernels(["radau_start", *loops])
    if any(c.method == "symplectic" for c in candidates):
        compile.warm_kernels(["gauss_run"], later=True)


def compiled_radau() -> bool:
    """Whether Radau runs compiled here (numba is installed and the compiled Radau IIA method exists):
    then a study's Radau is the compiled one, its step some 250 x cheaper than scipy's (2.3 us against
    0.6 ms on a 2-DOF system), and scipy's Radau runs only where asked for (`Radau:python`)."""
    return "Radau" in COMPILED and compile.numba_available()


def backend_for(candidate: Candidate) -> str:
    """The backend a candidate runs on: RK45/DOP853 (and Radau, `compiled_radau`) compiled when numba is available."""
    if candidate.backend != "auto":
        return candidate.backend
    if candidate.method == "symplectic":  # compiled only (without numba: a hint naming the extra)
        return "compiled"
    if candidate.method in ("RK45", "DOP853"):
        return "compiled" if compile.numba_available() else "python"
    if candidate.method == "Radau":
        return "compiled" if compiled_radau() else "python"
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
    raised: float = 1.0
    """How many times the command's default step budget `max_steps` is, at least 1: the fixed step caps of one reference
    attempt (`reference.COMPILED_RADAU_STEPS`, ...: `reference.scaled`) grow by it, so that a larger --max-steps gives
    reference runs more steps, as the messages that advise it say (audit 11, F2: it did not)."""
    start: Settings | None = field(default=None, compare=False)
    """The validated settings of these parameters and initial values (`starting`), made once."""

    @property
    def steps(self) -> int:
        return self.max_steps or MAX_STEPS

    @property
    def reference_steps(self) -> int:
        return self.reference_max_steps or REFERENCE_STEPS * self.steps


def starting(model: Model, setup: Setup) -> Setup:
    """`setup` with its `start`: the parameter values and initial state validated once (no
    compiling, no choice made), for everything that needs them besides the runs themselves."""
    if setup.start is not None:
        return setup
    return replace(setup, start=validate(model, method="DOP853", backend="python", t_end=setup.t_end, parameters=setup.parameters, initial=setup.initial))


def start_of(model: Model, setup: Setup) -> Settings:
    """The validated start of `setup` (made here when the setup was built without one)."""
    start = starting(model, setup).start
    assert start is not None
    return start


class PointStatus(enum.StrEnum):
    """How a measured run of a study ended (a `str`: shown and written as its value)."""

    FINISHED = "finished"
    FAILED = "failed"
    OVER_BUDGET = "over step budget"
    CAPPED = "capped"
    """Stopped at the work a cheaper run that met the accuracy (`stress`), or the cheapest run at its rtol
    (`accuracy`), leaves it: it could only lose. It says nothing of whether the method suits the system
    (a double pendulum's scipy Radau, stopped after 4 steps against compiled DOP853's 0.5 ms run, is no
    sign of trouble): not a finding, not "over step budget"."""
    UNDECIDED = "undecided"
    """Stopped by the time limit: it says nothing about the method."""
    NOT_APPLICABLE = "not applicable"


OVER_BUDGET = PointStatus.OVER_BUDGET
UNDECIDED = PointStatus.UNDECIDED


@dataclass(frozen=True)
class Ran:
    """What a run resolved to: the method (`auto` resolved) and the backend."""

    method: str
    backend: str

    def __str__(self) -> str:
        return f"{self.method} ({self.backend})"


@dataclass(frozen=True)
class Point:
    """One run of the study."""

    method: str
    """As requested, for people (`DOP853`, `RK45:python`, `auto`): `candidate.label`."""
    resolved: str
    """What ran, for people (`DOP853 (compiled)`): `str(ran)`."""
    tolerance: float
    """rtol of an adaptive method; for the symplectic method the rtol its step was chosen for."""
    step: float | None
    status: str
    """A `PointStatus`: finished, failed, over step budget, undecided (stopped by the time limit) or not applicable."""
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
    candidate: Candidate | None = None
    """What was asked (None only for points made by hand)."""
    ran: Ran | None = None
    """What ran (None when nothing ran: not applicable, or stopped before it started)."""
    failure: Failure | None = None
    """Why the run gave no error (None when it finished)."""
    max_error: float = math.nan
    """The largest error at any sample (the samples are the dense output at evenly spaced times)."""
    settings: Settings | None = field(default=None, compare=False, repr=False)
    """What ran, decided (to time it again without deciding anything again)."""
    reached: float | None = None
    """The share of the time span done when a run was stopped by its step budget or its pace (None otherwise)."""
    predicted: bool = False
    """Not run: its steps, evaluations and errors are its compiled twin's (the same algorithm, shown equal on a
    real run of it), its time predicted from its own time per step there (`stress._twin`). Never the
    recommendation nor timed again."""

    @property
    def ok(self) -> bool:
        return self.status == PointStatus.FINISHED and math.isfinite(self.error)

    @property
    def final_rms_error(self) -> float:
        """The larger of the final and the RMS error (the error measure before the pointwise maximum)."""
        return max(self.final_error, self.rms_error)

    @property
    def error(self) -> float:
        """The error a run is judged by ("meets", "fastest"): the largest error at any sample,
        which an average or the final error can understate (about 10x near the pericentre of an
        eccentric orbit); the larger of the final and the RMS error for a point made without it."""
        return self.max_error if not math.isnan(self.max_error) else self.final_rms_error

    @property
    def setting(self) -> str:
        """The run's complete setting, every number as it round-trips (`exact_text`): the symplectic
        step and stages, or rtol and atol (what `simulate` needs to repeat the run exactly)."""
        s = self.settings
        if self.step is not None:
            stages = f", {s.stages} stages" if s is not None and s.stages is not None else ""
            return f"step {exact_text(self.step)}{stages}"
        atol = s.atol if s is not None else atol_for(self.tolerance)
        return f"rtol {exact_text(self.tolerance)}, atol {exact_text(atol)}"


class TimeLimit(Exception):
    """A measured run went past the setup's time limit (`fraction` of its time span done)."""

    def __init__(self, fraction: float) -> None:
        super().__init__(fraction)
        self.fraction = fraction


Progress = Callable[[float], None]


def _time_limit(seconds: float) -> Progress:
    start = time.perf_counter()

    def progress(fraction: float) -> None:
        if time.perf_counter() - start > seconds:
            raise TimeLimit(fraction)

    return progress


PACE_AFTER = 0.25
"""A paced run (`run(..., paced=True)`: one capped at the work of a run that met the accuracy
already, which it can only lose to) is judged from this share of its step budget on ..."""
PACE_MARGIN = 4.0
"""... and stopped when its steps so far over the share of the time span done, the steps it needs
at that pace, exceed this times its budget: it cannot finish within the budget (scipy's BDF at rtol
1e-8 on the k = 1e10 pendulum started at r = 0.01 spent its whole cap, 14895 steps, 4 s, to reach
1% of the span). Counted in steps, never timed; Python runs every step, compiled ones each time their loop returns to
Python (`_compiled_pace`)."""


PACE_STEPS = 20
"""... and never before this many steps: a run's first steps are tiny by design (scipy's initial step,
then growing by at most 10 x a step), so a pace judged from them is no pace (scipy's Radau on an
elastic pendulum, capped at 6 steps, was judged after 2 to need 7.96e4 steps to t_end where 20 steps
had covered 0.18% of a 10 x longer window). A run whose budget is below it is stopped by its budget."""


PACE_EARLY = PACE_AFTER / 4
"""... or already from this share of its budget where the pace says it needs PACE_AFTER / PACE_EARLY times more
than that (16 x its budget at the default margin), judged from the faster of two paces: that of the latter half
of its steps and that of their last quarter, so that steps still growing (a transient left behind) are not
judged by the smaller ones before them. The weakly damped coupled oscillators over t = 1e5: scipy's BDF at rtol
1e-5, 28558 steps allowed, was stopped at a quarter of them, 7140 steps and 2.5 s of each regime, where the
first 1785 already put it at some 40 x its budget. Measured runs only, and LSODA's only where its pilot ended in
Adams steps on a problem not stiff (`_lsoda_judged_early`): LSODA starts with Adams steps,
stability-limited on a stiff system, and its pace changes when it switches to BDF, which may be after PACE_EARLY (a
damped stiff spring's reference, Radau confirmed by LSODA, was left unconfirmed); nor reference-side runs, the only
confirmation a reference may have."""


class Unaffordable(Exception):
    """A paced run was stopped: at its pace it needs `needed` steps, above PACE_MARGIN x its `budget`."""

    def __init__(self, steps: int, fraction: float, needed: float, budget: int, margin: float = PACE_MARGIN) -> None:
        super().__init__(steps)
        self.steps, self.fraction, self.needed, self.budget, self.margin = steps, fraction, needed, budget, margin


def _paced(budget: int, then: Progress | None, margin: float = PACE_MARGIN, early: bool = True) -> Progress:
    """A progress report, told once a step (scipy's runs), that raises Unaffordable (`PACE_MARGIN`). The
    pace is that of the latter half of the steps so far (`remaining`): the first steps are tiny by design.
    `early`: judged at PACE_EARLIEST and PACE_EARLY too (`EARLY_LEVELS`)."""
    done: list[float] = []
    judged: list[int] = []

    def progress(fraction: float) -> None:
        done.append(fraction)
        taken = len(done)
        if taken >= max(PACE_AFTER * budget, PACE_STEPS):
            needed = taken + remaining(done)
            if needed > margin * budget:
                raise Unaffordable(taken, fraction, needed, budget, margin)
        elif early:
            for level, (share, least) in enumerate(EARLY_LEVELS):
                if level in judged or taken < max(share * budget, least):
                    continue
                judged.append(level)  # each level judged once: a pace far beyond its budget now, however it speeds up later
                wide = margin * PACE_AFTER / share
                needed = taken + min(remaining(done), remaining(done, 4))
                if needed > wide * budget:
                    raise Unaffordable(taken, fraction, needed, budget, wide)
        if then is not None:
            then(fraction)

    return progress


PACE_EARLIEST = PACE_EARLY / 4
"""... and first from this share of its budget, where the pace says it needs PACE_AFTER / PACE_EARLIEST times more than
that (64 x its budget at the default margin), once it has taken PACE_EARLIEST_STEPS: the weakly damped coupled
oscillators over t = 1e5, scipy's BDF at rtol 1e-5, 28558 steps allowed, judged at PACE_EARLY (1785 steps, 0.6 s of
each regime) to need some 200 x them, which its first 446 show already."""
PACE_EARLIEST_STEPS = 100
"""The fewest steps a pace is judged from at PACE_EARLIEST: scipy's first steps grow by at most 10 x a step, and
a margin of 64 x is no room for a pace taken while they still grow."""
EARLY_LEVELS = ((PACE_EARLIEST, PACE_EARLIEST_STEPS), (PACE_EARLY, PACE_STEPS))
"""The early judgements of a paced Python run (`_paced`), earliest first: (share of the budget, fewest steps)."""


def _compiled_pace(budget: int, margin: float = PACE_MARGIN) -> Callable[[int, float], None]:
    """`_paced` for a compiled loop (`integrators.Problem.pace`), told (steps taken, share done) each time the
    loop returns to Python (every status.PAUSE_STEPS steps at most): judged from PACE_AFTER of its budget on,
    from the pace of the latter half of its steps (between those reports), never early (EARLY_LEVELS): measured
    runs only. Kepler e = 0.9 started at r = 0.01: compiled RK45 at rtol 1e-5 took 4.5e6 steps, 4-5 s, to reach
    t = 0.125 of 18.8, where its step collapsed; at 1.5e6 steps its pace needs some 40 x its budget of 6e6."""
    marks: list[tuple[int, float]] = []

    def pace(taken: int, fraction: float) -> None:
        marks.append((taken, fraction))
        if taken >= max(PACE_AFTER * budget, PACE_STEPS):
            needed = taken + _left(marks)
            if needed > margin * budget:
                raise Unaffordable(taken, fraction, needed, budget, margin)

    return pace


def _left(marks: Sequence[tuple[int, float]]) -> float:
    """`remaining` from (steps, share done) reports: the pace since the last report at or before half the steps taken."""
    taken, done = marks[-1]
    cut = taken // 2
    since, start = 0, 0.0
    for steps, fraction in marks[:-1]:
        if steps > cut:
            break
        since, start = steps, fraction
    gained = done - start
    return (taken - since) * (1.0 - done) / gained if gained > 0 else math.inf


def remaining(done: Sequence[float], part: int = 2) -> float:
    """The steps a run still needs to the end of its span at the pace of the latter half of its steps so far
    (`done`: the share of the span done after each step). The first half is left out, scipy's first steps
    being tiny by design: on an elastic pendulum its BDF at rtol 1e-5 needed 1472 steps to t_end, which the
    pace of its first 20 steps put at 5.1e3, that of steps 11-20 at 2.7e3 (at 100 steps: 1.74e3 and 1.50e3).
    `part`: the pace of the last 1/part of its steps instead (PACE_EARLY)."""
    taken = len(done)
    half = taken * (part - 1) // part  # the steps left out: the first half (`part` 4: the first three quarters)
    start = done[half - 1] if half > 0 else 0.0
    gained = done[-1] - start
    return (taken - half) * (1.0 - done[-1]) / gained if gained > 0 else math.inf


def settings_for(model: Model, candidate: Candidate, tolerance: float, setup: Setup, step: float | None = None) -> Settings:
    """The settings of one run of `candidate` at `tolerance`, validated and decided (`auto` resolved)."""
    asked = validate(
        model,
        t_end=setup.t_end,
        method=candidate.method,
        rtol=tolerance,
        atol=atol_for(tolerance),
        step=step,
        t_eval=setup.times,
        parameters=setup.parameters,
        initial=setup.initial,
        backend=backend_for(candidate),
    )
    return policy.decide(model, asked)


COMPILED_IMPLICIT_STEPS = 10
"""A measured compiled Radau run may take this many times the budget, not COMPILED_STEPS: its step costs 2-5 us on a
small system (3-7 evaluations with its LU factors reused; some 3 x a compiled explicit step, 1/100-1/250 of scipy's
Radau step), and no pace stops it where it is round-off-limited (60000 x 100 steps would be 15-30 s a run); 10 x
scipy's budget is still 10 x the steps in 1/25 of the time. Reference runs keep COMPILED_STEPS, within
`reference.COMPILED_RADAU_STEPS` an attempt."""


def step_factor(method: str, backend: str, reference: bool = False) -> int:
    """How many steps a run of `method` on `backend` may take per step of a budget (which counts scipy steps):
    1 for scipy's, COMPILED_STEPS for the compiled methods, COMPILED_IMPLICIT_STEPS for a measured compiled Radau run."""
    if backend != "compiled":
        return 1
    return COMPILED_IMPLICIT_STEPS if method == "Radau" and not reference else COMPILED_STEPS


def run_steps(settings: Settings, budget: int, reference: bool = False) -> int:
    """The step budget of one run (`reference`: a reference-side run): `budget` scipy steps, `step_factor` x that compiled."""
    return budget * step_factor(settings.method, settings.backend, reference)


def run(
    model: Model,
    candidate: Candidate,
    tolerance: float,
    setup: Setup,
    *,
    step: float | None = None,
    timed: bool = True,
    reference: bool = False,
    settings: Settings | None = None,
    paced: bool = False,
    margin: float = PACE_MARGIN,
) -> Trajectory:
    """One run of the study, within its step budget (the reference's when `reference`) and, when
    `timed` and the setup has one, its time limit (raises TimeLimit, LagrangeError); `paced`: a
    run is stopped once its pace shows it cannot finish within its budget (raises Unaffordable, see
    PACE_MARGIN; a compiled one only where it is a measured run, `_compiled_pace`). `settings`: those of an earlier run of the same point, so that a
    repeat decides nothing again."""
    limit = setup.time_limit if timed and not reference else None
    decided = settings if settings is not None else settings_for(model, candidate, tolerance, setup, step)
    budget = run_steps(decided, setup.reference_steps if reference else setup.steps, reference)
    if reference and decided.backend == "compiled":
        kept = kept_runs(model).get(replace(decided, notes=()))
        if kept is not None and kept.stats.steps <= budget:
            return replace(kept, settings=decided)  # the same finished run, made before on the reference's side (deterministic: the same steps)
    progress = _time_limit(limit) if limit is not None else None
    if paced and decided.backend == "python":  # a reference-side run too (`reference.paced_run`)
        progress = _paced(budget, progress, margin, early=not reference and (decided.method != "LSODA" or _lsoda_judged_early(model, decided)))
    # a compiled run at PACE_MARGIN at least, judged at PACE_AFTER only: its budget is some 100 x a Python run's, over which a pace
    # can change more (Kepler e = 0.9 started at r = 0.01: compiled Radau at 1e-5 had covered 9% of the span in 160000 steps, and
    # finished in 444132 of its 600000)
    pace = _compiled_pace(budget, max(margin, PACE_MARGIN)) if paced and decided.backend == "compiled" and not reference else None
    trajectory = integrate(model, decided, progress, budget, pace=pace)
    if reference and decided.backend == "compiled" and trajectory.outcome == Status.FINISHED:
        kept_runs(model).setdefault(replace(decided, notes=()), trajectory)
    return trajectory


def _lsoda_judged_early(model: Model, settings: Settings) -> bool:
    """Whether LSODA's pace may be judged early (EARLY_LEVELS): its own pilot (`policy.pilot`, LSODA at these
    tolerances from this start) ended in Adams steps and found nothing stiff. Then its steps are accuracy-limited, not
    stability-limited, and a later switch to BDF (where stiffness appears further on) would not make them longer: a
    pace far beyond its budget is its pace (the weakly damped coupled oscillators over t = 1e5: LSODA at 1e-5 took
    15000 steps, 0.8-1.3 s of each regime, to reach 0.13% of the span; its pilot switched to BDF and back in its
    first 200 steps)."""
    found = policy.pilot(model, settings)
    return found is not None and found.bdf is False and not diagnostics.stiff(found.worst, settings.t_end)


def kept_runs(model: Model) -> dict[Settings, Trajectory]:
    """The compiled reference-side runs (a reference, its confirmations and floors) that finished, by their
    decided settings less the notes, once per model: a measured run with the same settings is the same
    deterministic run (same steps, same samples), so `measure` takes it instead of running it again (Van der
    Pol, mu = 1000: compiled RK45 at 1e-9 and 1e-8 and DOP853 at 1e-8 and 1e-7, 0.6 s each, were run by the
    reference and again by the ladders)."""
    return memo.once(model, ("kept runs",), dict)


def over_step_budget(trajectory: Trajectory) -> bool:
    """Whether a run was stopped by its step budget."""
    return trajectory.outcome == Status.BUDGET


REPEAT_SECONDS = 1.0
"""The timed runs after the warm-up (`_repeats`) spend at most about this much per point; a run longer
than it is not repeated, its first time stands (2 s and at least one repeat before: the repeats were
a quarter of `accuracy`'s time on the k = 1e10 pendulum, compiled DOP853 at rtol 1e-8 alone 5 s; a
run that long is timed well once, and cannot tie with the short ones)."""


def _repeats(first: float, repeats: int) -> int:
    """More timed runs after the warm-up: `repeats` when one run is short, fewer for slow runs
    (at most about REPEAT_SECONDS of repeats per point), none for a run longer than that."""
    if first <= 0:
        return repeats
    return min(repeats, int(REPEAT_SECONDS / first))


def unrun(candidate: Candidate, tolerance: float, status: PointStatus = PointStatus.NOT_APPLICABLE, reason: str = "", failure: Failure | None = None) -> Point:
    """A point that did not run (nothing measured): `status` and `reason` say why. Shown as a run is
    (`RK45 (python)`, not the option's `RK45:python`) where its backend is asked for."""
    shown = candidate.label if candidate.backend == "auto" else str(Ran(candidate.method, candidate.backend))
    empty = Point(candidate.label, shown, tolerance, None, "", "", math.nan, math.nan, math.nan, None, math.nan, 0, 0.0, 0, 0, 0, candidate=candidate)
    return replace(empty, status=status, reason=reason, failure=failure) if reason or failure is not None else empty


EVALUATIONS_PER_STEP = {"RK45": 6, "DOP853": 12, "Radau": 18, "BDF": 4, "LSODA": 2, "symplectic": 8, "auto": 12}
"""Rough right-hand side evaluations per step of each method (as `work` counts them: nfev + 2 njev), to turn
a work cap into steps before a method's first run tells its own. scipy's Radau takes about 19 (its Newton
iterations over three stages and finite-difference Jacobians: 43513 in 2279 steps and 567154 in 29216 on the
penalty pendulum of k = 1e9; 6 before, so that its first capped run spent 3 x its cap), BDF about 3.7."""


COMPILED_EVALUATIONS_PER_STEP = {"Radau": 8}
"""... and of a compiled method where it differs from scipy's: the compiled Radau IIA reuses its Jacobian
and LU factors across steps (RADAU5's rules), about 7.3 evaluations a step (the stiff elastic pendulum in r
at rtol 1e-8: 6237 in 851 steps, 13 Jacobians), where scipy's takes about 19."""


def work(point: Point) -> float:
    """A run's work in scipy right-hand side evaluations (a compiled evaluation costs about 1/COMPILED_STEPS as much)."""
    compiled = point.ran is not None and point.ran.backend == "compiled"
    return (point.nfev + 2 * point.njev) / (COMPILED_STEPS if compiled else 1)


def capped_steps(candidate: Candidate, allowed: float, last: Point | None, setup: Setup) -> int:
    """The step budget (scipy steps, as budgets count them) of a candidate's next run when it may
    spend `allowed` work (`work`, inf: the setup's budget); `last`, its previous run, gives its
    evaluations per step."""
    if not math.isfinite(allowed):
        return setup.steps
    first = COMPILED_EVALUATIONS_PER_STEP.get(candidate.method) if backend_for(candidate) == "compiled" else None
    per_step = last.nfev / last.steps if last is not None and last.steps else first or EVALUATIONS_PER_STEP.get(candidate.method, 6)
    steps = allowed / max(per_step, 1.0)  # compiled runs get COMPILED_STEPS x this, at 1/COMPILED_STEPS the cost each
    return max(1, min(setup.steps, math.ceil(steps)))


def measure(model: Model, candidate: Candidate, tolerance: float, setup: Setup, reference: Reference, scale: np.ndarray, repeats: int = 3, paced: bool = False, margin: float = PACE_MARGIN) -> Point:
    """Run one point (warm-up, then timed repeats) and compare it with the reference. The
    symplectic method's step is the one `policy.decide` chooses for `simulate` (its pilot run at
    this tolerance), so a study measures the method as `simulate` runs it. `paced`: see `run`."""
    step = None
    empty = unrun(candidate, tolerance)
    if candidate.method == "symplectic" and not compile.numba_available():  # not the compiled path's hint: no python backend here
        return replace(empty, reason=f"the symplectic method runs only compiled, with numba: {compile.NUMBA_HINT}", failure=Failure.NOT_APPLICABLE)
    try:
        decided = settings_for(model, candidate, tolerance, setup, step)
        needed = fixed_steps(decided)
        if needed > run_steps(decided, setup.steps):  # a fixed step's count is known before the run: no need to spend the budget to learn it
            ran = Ran(decided.method, decided.backend)
            reason = f"not run: its fixed step {decided.step:.3g} needs {needed:.3g} steps to t_end, above this run's step budget ({run_steps(decided, setup.steps)})"
            return replace(empty, resolved=str(ran), ran=ran, settings=decided, step=decided.step, status=PointStatus.OVER_BUDGET, reason=reason, failure=Failure.BUDGET)
        kept = kept_runs(model).get(replace(decided, notes=())) if decided.backend == "compiled" else None
        if kept is not None and (setup.time_limit is None or kept.timing.run <= setup.time_limit):
            # the same run, made on the reference's side (`kept_runs`): its steps, samples and run time, made already whatever this run's
            # budget (the fast-damping cart over t = 1000: compiled Radau at 1e-11, 620376 steps, confirmed the reference at 1e-12 and
            # meets the accuracy; a measured run's budget of 600000 would have left the regime undecided)
            first = replace(kept, settings=decided)
        else:
            first = run(model, candidate, tolerance, setup, step=step, settings=decided, paced=paced, margin=margin)
    except Unaffordable as over:
        ran = Ran(decided.method, decided.backend)
        # no step count to t_end is claimed: a pace from a transient (scipy's Radau through a stiff spring's first 66 steps)
        # overstated the count 185 x (1873 steps); the pace only says the run would not finish within its budget
        reason = (
            f"stopped after {over.steps} steps at {100 * over.fraction:.2g}% of the time span: at that pace (that of the latter half of its steps)"
            f" it would not finish within {over.margin:g} x its step budget ({over.budget})"
        )
        return replace(empty, resolved=str(ran), ran=ran, settings=decided, steps=over.steps, status=PointStatus.OVER_BUDGET, reason=reason, failure=Failure.BUDGET, reached=over.fraction)
    except TimeLimit as over:
        reason = f"stopped by the time limit ({setup.time_limit:g} s, --budget) at {100 * over.fraction:.0f}% of the time span"
        return replace(empty, status=PointStatus.UNDECIDED, reason=reason, failure=Failure.TIME_LIMIT)
    except LagrangeError as error:
        return replace(empty, status=PointStatus.NOT_APPLICABLE, reason=str(error), failure=Failure.NOT_APPLICABLE)
    s = first.settings
    ran = Ran(s.method, s.backend)
    compiled = first.timing.compile + first.timing.load + first.timing.generate
    base = replace(
        empty,
        resolved=str(ran),
        ran=ran,
        settings=s,
        compile_seconds=compiled,
        nfev=first.stats.nfev,
        njev=first.stats.njev,
        steps=first.stats.steps,
        seconds=first.timing.run,
        runs=1,
        step=s.step if s.method == "symplectic" else None,
    )
    if over_step_budget(first):
        factor = step_factor(first.settings.method, first.settings.backend)
        times = f" x {factor} for a compiled run" if factor > 1 else ""
        done = (first.t_last - first.settings.t0) / (setup.t_end - first.settings.t0) if setup.t_end > first.settings.t0 else 0.0
        reason = f"stopped after {first.stats.steps} steps (the step budget, --max-steps {setup.steps}{times}) at {100 * done:.0f}% of the time span"
        return replace(base, status=PointStatus.OVER_BUDGET, reason=reason, failure=Failure.BUDGET, reached=done)
    if first.failed:
        return replace(base, status=PointStatus.FAILED, reason=first.message, failure=Failure.of(first.outcome) or Failure.NONFINITE)
    found = errors(first, reference, scale)
    drifts = [inv.max_change for inv in first.invariants if inv.kind == InvariantKind.CONSTRAINT]
    conserved = tuple((inv.name, inv.relative) for inv in first.invariants if inv.conserved and inv.kind != InvariantKind.CONSTRAINT)
    seconds = [first.timing.run]
    again = _repeats(first.timing.run, repeats) if repeats > 0 else 0
    for _ in range(again):
        seconds.append(run(model, candidate, tolerance, setup, step=step, timed=False, settings=s).timing.run)
    if again:
        seconds = seconds[1:]  # the warm-up's time dropped
    return replace(
        base,
        status=PointStatus.FINISHED,
        final_error=found.final,
        rms_error=found.rms,
        max_error=found.largest,
        energy_error=found.energy,
        constraint_drift=max(drifts) if drifts else None,
        seconds=min(seconds),
        runs=len(seconds),
        drifts=conserved,
    )


# -- timing: in turns, and close times are ties ----------------------------------------------------

TIE_MARGIN = 0.10
"""Run times within this fraction of the fastest are a tie, not a win: re-timing the same pair of
runs on a loaded machine reverses or evens out many differences of a few percent."""
Timer = Callable[[], float]
"""Runs something once and returns its run time in seconds."""


def interleave(timers: Sequence[Timer], rounds: Sequence[int]) -> list[list[float]]:
    """Time runs in turns: in round r every run k with rounds[k] > r runs once, in order. A load
    that comes and goes then slows all of them alike, not those that happened to run during it.
    Returns the times of each run."""
    times: list[list[float]] = [[] for _ in timers]
    for r in range(max(rounds, default=0)):
        for k, timer in enumerate(timers):
            if r < rounds[k]:
                times[k].append(timer())
    return times


CONTENDER = 2.0
"""A finished run is timed again only if no other run reached at least its accuracy in less than
1/CONTENDER of its time (`contenders`): a run that much slower cannot be the fastest at any accuracy
whatever the noise of its first time, so repeating it would decide nothing."""


def contenders(points: Sequence[Point], factor: float = CONTENDER) -> list[bool]:
    """For each point: whether it is finished and not dominated (another finished run with an error
    at most its own in less than 1/factor of its time)."""
    done = [p for p in points if p.status == PointStatus.FINISHED]
    return [p.status == PointStatus.FINISHED and not any(q.error <= p.error and q.seconds * factor < p.seconds for q in done) for p in points]


def retime(model: Model, points: Sequence[Point], setup: Setup, repeats: int, timer: Callable[[Point], Timer] | None = None, only: Sequence[bool] | None = None) -> list[Point]:
    """The finished points with their run times measured again in turns (`interleave`): up to
    `repeats` timed runs each (fewer for slow runs), the fastest kept. `timer` makes the timer of a
    point (default: run its settings again and take the integration time); `only` (one flag per
    point, e.g. `contenders`) limits the repeats to the flagged points, the others keep their first time."""
    make = timer if timer is not None else (lambda point: _timer(model, point, setup))
    flags = list(only) if only is not None else [True] * len(points)
    chosen = [k for k, p in enumerate(points) if flags[k] and p.status == PointStatus.FINISHED and (p.settings is not None or timer is not None)]
    times = interleave([make(points[k]) for k in chosen], [_repeats(points[k].seconds, repeats) for k in chosen])
    result = list(points)
    for k, found in zip(chosen, times, strict=True):
        if found:
            result[k] = replace(points[k], seconds=min(found), runs=len(found))
    return result


def _timer(model: Model, point: Point, setup: Setup) -> Timer:
    settings = point.settings
    assert settings is not None

    def timed() -> float:
        return run_seconds(model, settings, run_steps(settings, setup.steps))  # the run alone: its report is known already

    return timed


def ties(points: Sequence[Point], best: Point, level: float = math.inf, margin: float = TIE_MARGIN) -> tuple[Point, ...]:
    """The fastest run of each other candidate that also reaches `level` in at most (1 + margin) x
    the time of `best`: ties with it, not losses. Not the same run under another name (`auto` resolved to the method and
    settings of `best`: the same decided settings), which is no second method (audit 7: the recommended run printed
    again as its own tie, with the same `try:` line twice)."""
    found: dict[Candidate | str, Point] = {}
    mine = best.candidate if best.candidate is not None else best.method
    for p in points:
        who = p.candidate if p.candidate is not None else p.method
        close = p.ok and p.error <= level and p.seconds <= best.seconds * (1.0 + margin)
        if p.settings is not None and best.settings is not None and replace(p.settings, notes=()) == replace(best.settings, notes=()):
            continue
        if who != mine and close and (who not in found or p.seconds < found[who].seconds):
            found[who] = p
    return tuple(sorted(found.values(), key=lambda p: p.seconds))


def scaled_errors(y: np.ndarray, reference: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """max_i |y_i - y_ref,i| / s_i at each sample."""
    return np.max(np.abs(y - reference) / scale, axis=1)


class Errors(NamedTuple):
    """The errors of a finished run against the reference (scaled, see accuracy.py)."""

    final: float
    rms: float
    largest: float
    """The maximum over the samples."""
    energy: float
    """The largest energy error, relative."""


def errors(trajectory: Trajectory, reference: Reference, scale: np.ndarray) -> Errors:
    """The final, RMS and largest error over the samples, and the relative energy error, of a finished run."""
    if len(trajectory.t) != len(reference.t) or not np.all(np.isfinite(trajectory.y)):
        return Errors(math.nan, math.nan, math.nan, math.nan)
    e = scaled_errors(trajectory.y, reference.y, scale)
    kinetic = next((i.scale for i in trajectory.invariants if i.kind == InvariantKind.ENERGY), 0.0)  # the largest |sum p q_dot|
    size = max(float(np.max(np.abs(reference.energy))), kinetic, 1e-300)
    return Errors(float(e[-1]), float(np.sqrt(np.mean(e**2))), float(np.max(e)), float(np.max(np.abs(trajectory.energy - reference.energy)) / size))


def component_scale(y: np.ndarray) -> np.ndarray:
    return np.maximum(1.0, np.max(np.abs(y), axis=0))


def check_steps(max_steps: object) -> int:
    """A step budget: a whole number of at least 1 (LagrangeError otherwise)."""
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
        raise LagrangeError(f"the step budget (--max-steps) must be a whole number of at least 1, got {max_steps!r}")
    return max_steps
