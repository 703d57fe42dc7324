"""What makes a system hard to integrate, measured at a state: shared by `stress` and `simulate --method auto`.

- `spectrum(J)`: from the eigenvalues lambda of the Jacobian df/dy, the fastest decay
  max(-Re lambda) among real-dominated eigenvalues (|Re| > |Im|: dissipative stiffness) that
  have no matching growth (see below) and are faster than OWN x the rate at which the solution
  itself changes there (`own_rate`: slower ones are its own motion, such as an orbit's angular
  velocity falling as r grows), the fastest growth max Re lambda, the spectral radius
  max |lambda| (the fastest time scale, oscillatory or not), and the slowest non-zero |lambda|;
  their ratios are the stiffness ratio and the ratio of time scales.
- `choose(spectrum, t_end)`: the method `simulate --method auto` picks and the label `stress`
  gives (see its docstring): stiff only when a decay is both fast over the run and unmatched
  by growth, and Radau only when an explicit method's stability-limited step count is too
  large, against Radau's estimated steps, to be cheaper compiled.
- `mass_condition(model, p, y0)`: the 2-norm condition number of M in coordinates measured in
  their own sizes at y0 (q_i / max(1, |q0_i|)), which grows without bound near a coordinate
  singularity (Euler angles at theta = 0, the pole of spherical coordinates) but not with the
  units (diag(m, m r^2) at r = 7e6 m is well conditioned).
- `condition_peak(condition, t, y, rerun)`: the largest cond M along a trajectory, sampled
  densely: every sample, then around the highest local maxima (of at least PEAK_FLOOR) the trajectory run again with
  PEAK_SAMPLES samples between the neighbouring samples, PEAK_LEVELS times over (a pole passage
  lasting 1e-4 of the sample spacing is found, and its cond M, not that of the nearest sample).
- `singular_coordinate(model, condition, y)`: at such a peak, which coordinate is at its
  singularity and along which velocities M loses its inertia (for the suggestion to change
  coordinates).
- `time_singularity(mass, t0, t1, q0, scale)`: the first time at which M is singular whatever the
  state, where it depends on t explicitly (a rope reeled in to zero length, L(t) = L0 - u t): a
  singularity of the model itself, which no method and no change of coordinates passes.
  `model_end(model, values, t0, t1, y0)` asks it only of a mass matrix that depends on t.
- `jacobian(rhs, t, y)`: a forward-difference Jacobian of any right-hand side.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from lagrange_cli.model import Model

STIFF = 500.0
"""decay rate x time span of a real-dominated eigenvalue above which a problem counts as stiff."""
FAR = 100.0
"""decay / slowest rate above which a decaying mode is far faster than the motion of interest."""
MATCHED = 0.5
"""a decay d is matched (a saddle's +-pair, not stiffness) when some eigenvalue grows at >= MATCHED x d."""
OWN = 10.0
"""a decay d is the solution's own motion (not stiffness) where the solution itself changes at d / OWN
or faster (`own_rate`): an explicit method then needs steps of a fraction of 1 / that rate for
accuracy alone, so h d stays within its stability interval (3-6) and an implicit method buys no
longer steps (Kepler's escape in polar coordinates: phi_dot = L / r^2 decays at 2 r_dot / r, twice
its own rate, all along the run). Measured after the transients, the audits' stiff systems have
decay / own rate 50-250 (a chain of springs of mixed stiffness) to 1e4-8e5 (dampers of 1e5-1e6/s,
springs of k = 1e8-1e11 written in their length)."""
STABILITY = 3.0
"""|h lambda| on the negative real axis that RK45 and DOP853 stay stable for (about 3)."""
PER_RADIAN = 10.0
"""steps an implicit method takes per radian of the slowest motion (measured: Radau ~6-7 on the
damped stiff spring at rtol 1e-5), plus TRANSIENT steps for the fast transient."""
TRANSIENT = 100.0
COMPILED_COST_RATIO = 2.0
"""The same for the compiled Radau method (kernels.radau_run): a step attempt costs 1.8x a compiled DOP853
attempt (1.77-1.80 measured in CPU time: benchmarks/radau_bench.py, BENCHMARKS.md "Issue 15: a compiled Radau IIA")."""
SHORT = 1e4
"""Stability-limited explicit steps up to which compiled DOP853 stays the choice even where compiled Radau
would take fewer step costs: such a run takes ~10 ms, less than loading Radau's module with its Jacobian
(a second compiled module of the system), and `auto`'s own compiled run (policy.ATTEMPT_STEPS) decides
the same way where it can start."""
COST_RATIO = 100.0
"""cost of a scipy Radau step over a compiled DOP853 step, in units of the estimated steps:
measured on the damped stiff spring (`lagrange stress stiff_spring_pendulum_damped --scale
k=1e4..1e10 --method DOP853,Radau,auto`), a Radau step costs 250-350 us and a compiled DOP853
step 1.2-1.9 us, and DOP853 takes about half the steps `explicit_steps` estimates (its
stability interval is about 6, not 3) while Radau takes ~0.75 of `implicit_steps`: the two
break even near 300. 100 keeps a factor 3 in hand for larger systems, where a compiled step
grows faster than Radau's Python overhead; it puts the switch between k = 1e8 (DOP853 30 ms,
Radau 106 ms) and k = 1e9 (59 ms against 57-72 ms)."""
SINGULAR_CONDITION = 1e6
"""condition number of M above which the coordinates count as near-singular."""
PEAKS = 6
"""Local maxima of cond M along the samples that `condition_peak` looks at more closely."""
PEAK_SAMPLES = 101
PEAK_FLOOR = 100.0
"""Only local maxima of cond M at or above this are resampled: M well conditioned at every sample
has no pole passage between them worth a rerun (a pole passage lasting 1e-4 of the sample spacing
still shows cond M ~ 1e4 at the neighbouring samples), and each rerun restarts the reference's
method (scipy's Radau on a stiff spring: 18 reruns, 800 steps each, two thirds of a regime's time)."""
PEAK_LEVELS = 3
"""Each peak is resampled PEAK_LEVELS times, PEAK_SAMPLES samples between the neighbours of the highest one."""


@dataclass(frozen=True)
class Spectrum:
    """Rates (1/s) of the linearisation at one state."""

    decay: float
    """max -Re(lambda) over eigenvalues with |Re| > |Im| whose decay is not matched by a growth
    rate of MATCHED x its size or more (0 when none decays)."""
    rate: float
    """max |lambda|, the spectral radius."""
    slowest: float
    """min |lambda| over eigenvalues above 1e-9 of the spectral radius (0 when all are 0)."""
    growth: float = 0.0
    """max Re(lambda), 0 when nothing grows: an unstable mode (a saddle near a singular or
    inverted configuration, or chaos), which an implicit method does not help with."""
    own: float = 0.0
    """The rate at which the solution itself changes at that state (`own_rate`); 0 where not measured."""
    followed: float = 0.0
    """The fastest unmatched decay left out of `decay` because the solution itself changes that fast
    (at most OWN x `own`): its own motion, which an explicit method resolves for accuracy anyway (0: none)."""
    oscillation: float = 0.0
    """min |lambda| over the oscillatory eigenvalues (|Im| > |Re|, above 1e-9 of the spectral radius): the slowest
    mode that swings (0 when none does)."""

    @property
    def stiffness_ratio(self) -> float:
        """Fastest decay over slowest rate: large means stiff in the dissipative sense."""
        return self.decay / self.slowest if self.slowest > 0 else (math.inf if self.decay > 0 else 1.0)

    @property
    def scale_ratio(self) -> float:
        """Fastest over slowest rate: large means two time scales (oscillatory or not)."""
        return self.rate / self.slowest if self.slowest > 0 else 1.0


def spectrum(jacobian: np.ndarray, own: float = 0.0) -> Spectrum | None:
    """The rates of `jacobian`, or None when it is not finite; with `own`, the solution's own rate
    there (`own_rate`), decays of at most OWN x `own` are its motion (`Spectrum.followed`), not stiffness."""
    if not np.all(np.isfinite(jacobian)):
        return None
    eigenvalues = np.linalg.eigvals(jacobian)
    if not np.all(np.isfinite(eigenvalues)):
        return None
    sizes = np.abs(eigenvalues)
    rate = float(np.max(sizes)) if len(sizes) else 0.0
    growth = max(0.0, float(np.max(eigenvalues.real))) if len(eigenvalues) else 0.0
    decays = [-e.real for e in eigenvalues if -e.real > abs(e.imag) and growth < MATCHED * -e.real]
    faster = [d for d in decays if d > OWN * own]
    followed = max((d for d in decays if d <= OWN * own), default=0.0)
    nonzero = sizes[sizes > 1e-9 * rate] if rate > 0 else sizes[:0]
    turning = [float(abs(e)) for e in eigenvalues if abs(e.imag) > abs(e.real) and abs(e) > 1e-9 * rate]
    return Spectrum(max(faster, default=0.0), rate, float(np.min(nonzero)) if len(nonzero) else 0.0, growth, own, followed, min(turning, default=0.0))


def own_rate(f: np.ndarray | None, y: np.ndarray) -> float:
    """How fast the solution itself changes at a state y where dy/dt = f: ||f|| / ||y|| (0 where f is
    unknown or nothing moves, inf where y = 0 moves). A decay much faster than this is a mode the
    solution has left, where an explicit method's step is limited by stability, not accuracy
    (stiffness: the damped stiff springs and dampers of the audits, decay / own rate 50-1e5 after
    their transients); one about as fast is the solution's own motion (Kepler's escape in polar
    coordinates: phi_dot = L / r^2 decays at 2 r_dot / r, own rate about r_dot / r, all along the
    run). ||f|| / ||y|| rather than ||d2y/dt2|| / ||dy/dt||: on the escape, r_dot dominates dy/dt and
    hardly changes, so the latter falls to 1e-7/s while phi_dot still decays at 2 / t."""
    if f is None:
        return 0.0
    size, moving = float(np.linalg.norm(y)), float(np.linalg.norm(f))
    if not (math.isfinite(size) and math.isfinite(moving)) or moving == 0.0:
        return 0.0
    return moving / size if size > 0 else math.inf


def stiff(found: Spectrum, t_end: float) -> bool:
    """A decay (already free of matched growth and of the solution's own motion, see `spectrum`) fast
    over the run (decay x t_end > STIFF) and far faster than the slowest motion (stiffness ratio
    decay / slowest > FAR)."""
    return found.decay * t_end > STIFF and found.stiffness_ratio > FAR


def explicit_steps(decay: float, t_end: float) -> float:
    """The steps RK45/DOP853 need just to stay stable: decay x t_end / STABILITY."""
    return decay * t_end / STABILITY


def implicit_steps(slowest: float, t_end: float) -> float:
    """The steps Radau needs for the slow motion: PER_RADIAN x slowest rate x t_end + TRANSIENT."""
    return PER_RADIAN * slowest * t_end + TRANSIENT


def explicit_affordable(found: Spectrum, t_end: float, ratio: float = COST_RATIO) -> bool:
    """Whether compiled explicit steps (stability-limited) cost less than Radau's: explicit steps
    <= ratio x implicit steps, i.e. decay / STABILITY <= ratio x (PER_RADIAN x slowest
    + TRANSIENT / t_end) - a bound on the stiffness ratio decay / slowest, about 3000 on long runs
    against scipy's Radau (COST_RATIO), about 60 against the compiled one (COMPILED_COST_RATIO)."""
    return explicit_steps(found.decay, t_end) <= ratio * implicit_steps(found.slowest, t_end)


def choose(found: Spectrum | None, t_end: float, compiled: bool = True) -> tuple[str, str]:
    """(method, why) for `simulate --method auto`, from the linearisation at one state.

    - Not stiff -> DOP853: no unmatched decay d with d x t_end > STIFF and d > FAR x the
      slowest rate (a decay comparable with the motion itself is resolved anyway). Eigenvalues that are
      oscillatory (|Im| >= |Re|, e.g. a stiff undamped spring) or that come as a +-pair (a decay
      matched by a growth rate of at least MATCHED x d, e.g. the heavy top near theta = 0 or
      an inverted pendulum) are not stiffness: an implicit method would not buy larger steps.
    - Stiff but affordable -> DOP853: the stability limit forces about d x t_end / STABILITY
      explicit steps; while that is at most COST_RATIO x Radau's estimated steps
      (`explicit_affordable`), a compiled explicit method is cheaper (measured: damped stiff
      spring at k = 1e4..1e6, ~1-4 ms compiled against 59-174 ms for Radau).
    - Stiff and expensive -> Radau (e.g. the damped stiff spring at k = 1e9 over t_end = 10:
      1.05e5 explicit steps against 100 x ~390 estimated Radau steps), and
      any stiff case when explicit methods cannot run compiled (`compiled=False`: no numba).
      With `compiled`, Radau runs compiled too, and a step of it costs COMPILED_COST_RATIO compiled
      explicit steps, not COST_RATIO.
    """
    if found is None:
        return "DOP853", "the linearisation at the initial state could not be evaluated"
    if not stiff(found, t_end):
        return "DOP853", "not stiff at the initial state"
    steps = explicit_steps(found.decay, t_end)
    if compiled and (steps <= SHORT or explicit_affordable(found, t_end, COMPILED_COST_RATIO)):
        return "DOP853", f"mildly stiff (decay {found.decay:.3g}/s x t_end {t_end:g}): about {steps:.3g} stability-limited explicit steps, cheaper compiled than compiled Radau"
    return "Radau", f"stiff: a mode decays at rate {found.decay:.3g}/s over t_end = {t_end:g} (about {steps:.3g} explicit steps)"


def jacobian(rhs: Callable[[float, np.ndarray], np.ndarray | None], t: float, y: np.ndarray, f0: np.ndarray | None = None) -> np.ndarray | None:
    """Forward differences of `rhs` (which returns None where it cannot be evaluated); None also
    where a difference is not finite. Each component moves by 1.5e-8 of its size (of 1 when it is
    0), so that r = 7e6 m and x = 1e-8 m are both differentiated in their own units. `f0`: rhs(t, y)
    when the caller has it already."""
    f0 = rhs(t, y) if f0 is None else f0
    if f0 is None:
        return None
    columns = []
    for j in range(len(y)):
        h = 1.5e-8 * (abs(y[j]) or 1.0)
        shifted = y.copy()
        shifted[j] += h
        f1 = rhs(t, shifted)
        if f1 is None:
            return None
        columns.append((f1 - f0) / h)
    result = np.array(columns).T
    return result if np.all(np.isfinite(result)) else None


def spectrum_at(rhs: Callable[[float, np.ndarray], np.ndarray | None], t: float, y: np.ndarray, tangent: np.ndarray | None = None) -> Spectrum | None:
    """The rates of the linearisation of `rhs` at (t, y) (`jacobian`, `spectrum`), its decays told from the
    solution's own motion there (`own_rate`, from the same evaluation of rhs(t, y)); None where rhs cannot
    be evaluated or differentiated. `tangent` (n x k, orthonormal columns): the linearisation restricted to
    the coordinate directions it spans and their velocities, (tangent dq, tangent dv)."""
    f0 = rhs(t, y)
    found = jacobian(rhs, t, y, f0) if f0 is not None else None
    if found is not None and tangent is not None:
        zero = np.zeros_like(tangent)
        basis = np.block([[tangent, zero], [zero, tangent]])
        found = basis.T @ found @ basis
    return spectrum(found, own_rate(f0, y)) if found is not None else None


def coordinate_sizes(y0: Sequence[float], n: int) -> np.ndarray:
    """The size of each coordinate at the state y0, max(1, |q0_i|): the unit in which stress
    measures, perturbs and moves it (r = 7e6 m counts in metres times 7e6, an angle in radians)."""
    return np.maximum(1.0, np.abs(np.array(y0[:n], dtype=float)))


def mass_at(model: Model, p: Sequence[float]) -> Callable[[float, Sequence[float] | np.ndarray], np.ndarray | None]:
    """M(q, t) at (t, y) for the parameter values `p` (None where it is undefined or not finite)."""
    import sympy as sp

    values = {parameter.symbol: value for parameter, value in zip(model.parameters, p, strict=False)}
    matrix = sp.Matrix(model.mass_matrix).subs(values)
    evaluate = sp.lambdify([model.t, *model.q], matrix.tolist(), modules="math")
    n = model.n

    def mass(t: float, y: Sequence[float] | np.ndarray) -> np.ndarray | None:
        try:
            m = np.array(evaluate(t, *[float(v) for v in y[:n]]), dtype=float)
        except (ArithmeticError, ValueError, TypeError):  # a domain error, 1/0, an overflow, a complex value
            return None
        return m if np.all(np.isfinite(m)) else None

    return mass


def mass_condition(model: Model, p: Sequence[float], y0: Sequence[float] | None = None) -> MassCondition:
    """cond(L M(q, t) L) at (t, y) with y = [q..., q_dot...], L = diag(max(1, |q0_i|)) from the
    state y0 (the identity without it): M for the coordinates q_i / L_i, so that a coordinate
    of size 7e6 counts like one of size 1; inf where M is singular or undefined."""
    n = model.n
    return MassCondition(mass_at(model, p), np.ones(n) if y0 is None else coordinate_sizes(y0, n))


class MassCondition:
    """`mass_condition`'s cond(L M L) at one state (a call), or at many at once (`many`: one batched SVD)."""

    def __init__(self, mass: Callable[[float, Sequence[float] | np.ndarray], np.ndarray | None], scale: np.ndarray) -> None:
        self.mass, self.scale = mass, scale

    def __call__(self, t: float, y: np.ndarray) -> float:
        return float(self.many(np.array([t], dtype=float), np.array([y], dtype=float))[0])

    def many(self, t: np.ndarray, y: np.ndarray) -> np.ndarray:
        """cond(L M L) at each state (t_k, y_k), inf where M is singular or undefined."""
        n = len(self.scale)
        values = np.full(len(t), math.inf)
        found = [(k, m) for k in range(len(t)) if (m := self.mass(float(t[k]), y[k])) is not None]
        if found:
            stack = np.array([m for _, m in found]).reshape(len(found), n, n)
            with np.errstate(all="ignore"):
                cond = np.linalg.cond(self.scale[None, :, None] * stack * self.scale[None, None, :])
            values[[k for k, _ in found]] = np.where(np.isfinite(cond), cond, math.inf)
        return values


def _conditions(condition: Callable[[float, np.ndarray], float], t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """`condition` at each sample: at once where it can (`MassCondition.many`)."""
    if isinstance(condition, MassCondition):
        return condition.many(np.asarray(t, dtype=float), np.asarray(y, dtype=float))
    return np.array([condition(float(ti), yi) for ti, yi in zip(t, y, strict=True)])


Rerun = Callable[[float, np.ndarray, float, int], "tuple[np.ndarray, np.ndarray] | None"]
"""(t0, y0, t1, samples) -> the trajectory from y0 at t0 to t1 at `samples` even times, or None."""


@dataclass(frozen=True)
class Peak:
    """The largest cond M found along a trajectory, where and when."""

    condition: float
    t: float
    y: np.ndarray
    evaluations: int
    """States at which cond M was evaluated."""
    reruns: int
    """Short runs made to sample between the samples."""


def condition_peak(condition: Callable[[float, np.ndarray], float], t: np.ndarray, y: np.ndarray, rerun: Rerun | None = None, peaks: int = PEAKS, levels: int = PEAK_LEVELS) -> Peak | None:
    """The largest cond M at the samples (t, y) and, with `rerun`, between them: around each of the
    `peaks` highest local maxima the trajectory is run again between the neighbouring samples, and
    again around the highest of those, `levels` times (None without samples)."""
    if len(t) == 0:
        return None
    values = _conditions(condition, t, y)
    evaluations, reruns = len(values), 0
    k = int(np.argmax(values))
    best = (float(values[k]), float(t[k]), np.array(y[k]))
    if rerun is None or len(t) < 2:
        return Peak(*best, evaluations, reruns)
    finite = np.where(np.isfinite(values), values, np.inf)
    left, right = np.r_[-np.inf, finite[:-1]], np.r_[finite[1:], -np.inf]
    maxima = [int(i) for i in np.argsort(-finite, kind="stable") if finite[i] >= left[i] and finite[i] >= right[i] and finite[i] >= PEAK_FLOOR][:peaks]
    for i in maxima:
        times, states, m = t, y, i
        for _ in range(levels):
            if not math.isfinite(best[0]):
                break
            a, b = max(m - 1, 0), min(m + 1, len(times) - 1)
            found = rerun(float(times[a]), np.array(states[a]), float(times[b]), PEAK_SAMPLES)
            reruns += 1
            if found is None:
                break
            times, states = found
            local = _conditions(condition, times, states)
            evaluations += len(local)
            m = int(np.argmax(local))
            if local[m] > best[0]:
                best = (float(local[m]), float(times[m]), np.array(states[m]))
    return Peak(*best, evaluations, reruns)


TIME_GRID = 2001
"""Times at which `time_singularity` samples cond M over the span before refining its peaks."""
REFINE = 0.1
"""A local minimum of M's smallest eigenvalue (over its largest at the start) above this at the samples is not refined
(the lowest one always is): M losing 90% of its inertia between samples 1/2000 of the span apart is the only way to
hide a zero there. The parametric swing's cos(w t) makes 250 shallow minima over its long horizon."""
STATES = 4
"""Other states (the coordinates moved by up to their size, an angle by up to pi) at which a time singularity
must also be singular: a singularity of the coordinates depends on where they are, one of the model's on t alone."""


def time_singularity(mass: Callable[[float, Sequence[float] | np.ndarray], np.ndarray | None], t0: float, t1: float, q0: Sequence[float], scale: np.ndarray) -> float | None:
    """The first time in (t0, t1] at which M(q, t) is singular for the coordinates q0 and for STATES others, while
    at t0 it is regular for all of them: a singularity in time (a length, a mass or an inertia of the model reaching
    zero), None where there is none. Singular means: the smallest |eigenvalue| of L M(q, t) L (L = diag(scale))
    below 1 / SINGULAR_CONDITION of the largest at (q, t0). Not cond M at t alone: a mass matrix that shrinks as a
    whole, m (L0 - u t)^2 for a bead on a shrinking rod, keeps cond 1 all the way to zero.

    The ratio at q0 is sampled at TIME_GRID times; each local minimum is refined by a bounded minimisation
    between its neighbouring samples (a zero crossing of L(t) makes M vanish like L^2 over a stretch far shorter
    than the grid), then the other states are tried at the time found."""
    rng = np.random.default_rng(0)  # the same states every time: the diagnosis is reproducible
    n = len(q0)
    base = np.asarray(q0, dtype=float)
    states = [base] + [base + rng.uniform(-1.0, 1.0, n) * np.maximum(scale[:n], math.pi) for _ in range(STATES)]

    def eigenvalues(t: float, q: np.ndarray) -> np.ndarray | None:
        m = mass(t, q)
        if m is None:
            return None
        with np.errstate(all="ignore"):
            try:
                return np.abs(np.linalg.eigvalsh(0.5 * (scale[:n, None] * m * scale[None, :n] + (scale[:n, None] * m * scale[None, :n]).T)))
            except np.linalg.LinAlgError:
                return None

    start = [eigenvalues(t0, q) for q in states]
    if any(e is None or not np.all(np.isfinite(e)) or e.min() * SINGULAR_CONDITION < e.max() for e in start):
        return None  # singular at the start for some state: the coordinates' doing, or the model's from the outset
    largest = [float(e.max()) for e in start if e is not None]

    def ratio(t: float, k: int = 0) -> float:
        """The smallest |eigenvalue| at (t, state k) over the largest at (t0, state k): 0 where M is undefined."""
        e = eigenvalues(t, states[k])
        return float(e.min()) / largest[k] if e is not None and np.all(np.isfinite(e)) else 0.0

    times = np.linspace(t0, t1, TIME_GRID)
    values = np.array([ratio(float(t)) for t in times])
    before, after = np.r_[np.inf, values[:-1]], np.r_[values[1:], np.inf]
    lowest = int(np.argmin(values))
    for k in range(1, TIME_GRID):  # in time order: the first singular minimum is where the model ends
        if not (values[k] <= before[k] and values[k] <= after[k]) or (values[k] > REFINE and k != lowest):
            continue
        a, b = float(times[k - 1]), float(times[min(k + 1, TIME_GRID - 1)])
        found = _golden(ratio, a, b, 1e-12 * max(1.0, abs(b)))
        at = found if ratio(found) <= values[k] else float(times[k])
        if all(ratio(at, j) * SINGULAR_CONDITION < 1.0 for j in range(len(states))):
            return at
    return None


def model_end(model: Model, values: Sequence[float], t0: float, t1: float, y0: Sequence[float]) -> float | None:
    """Where the model itself ends in (t0, t1]: its mass matrix singular whatever the state (`time_singularity`, for
    the parameter `values` and the coordinates of the state y0), which only a mass matrix depending on t explicitly can
    be; None for every other model, without evaluating anything (shared by `stress`, which runs nothing past it, and
    `simulate`, which says a run stopped there stopped where the model ends)."""
    import sympy as sp

    if model.t not in sp.Matrix(model.mass_matrix).free_symbols:
        return None
    return time_singularity(mass_at(model, values), t0, t1, y0[: model.n], coordinate_sizes(y0, model.n))


GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def _golden(f: Callable[[float], float], a: float, b: float, tolerance: float) -> float:
    """A minimum of f on [a, b] by golden-section search, to `tolerance` (f unimodal there; scipy.optimize's
    import alone costs ~1 s of CPU, more than the search)."""
    c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
    fc, fd = f(c), f(d)
    while b - a > tolerance:
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - GOLDEN * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + GOLDEN * (b - a)
            fd = f(d)
    return c if fc <= fd else d


SPECIAL = (0.0, math.pi / 2, -math.pi / 2, math.pi, -math.pi)
"""Values at which angles are typically singular (the pole, the gimbal lock)."""


@dataclass(frozen=True)
class Singularity:
    """Which coordinate makes M singular at a state, and how."""

    coordinate: str
    value: float
    """Its value at the peak."""
    near: float | None
    """The special value (0, +-pi/2, pi) it is near, if any: where the coordinates are singular."""
    direction: tuple[tuple[str, float], ...]
    """The velocities along which M loses its inertia there (the eigenvector of the smallest eigenvalue), largest first;
    with `unbounded`, those along which its inertia grows without bound (the largest eigenvalue's)."""
    unbounded: bool = False
    """M's largest eigenvalue grew more (against the start's M) than its smallest shrank: the coordinates end at the edge
    of the region they describe (a height solved from a constraint, z = -sqrt(L^2 - x^2 - y^2), at x^2 + y^2 = L^2: a
    small change of x or y there moves the bob a long way), not at a configuration where they lose a direction."""


def singular_coordinate(
    names: Sequence[str], condition: Callable[[float, np.ndarray], float], t: float, y: np.ndarray, mass: np.ndarray | None = None, start: np.ndarray | None = None
) -> Singularity | None:
    """The coordinate whose moving (by 0.05 of its size either way) lowers cond M the most at (t,
    y): the one at its singularity; None when moving none of them helps. `start`: M at the start, against which
    `Singularity.unbounded` is judged (without it, M losing inertia is assumed)."""
    n = len(names)
    base = condition(t, y)
    best: tuple[float, int] | None = None
    for i in range(n):
        lowest = base
        for sign in (1.0, -1.0):
            moved = np.array(y, dtype=float)
            moved[i] += sign * 0.05 * max(1.0, abs(float(y[i])))
            lowest = min(lowest, condition(t, moved))
        gain = math.log10(base / lowest) if math.isfinite(base) and lowest > 0 else (math.inf if lowest < math.inf else 0.0)
        if gain > 0.5 and (best is None or gain > best[0]):
            best = (gain, i)
    if best is None:
        return None
    i = best[1]
    value = float(y[i])
    near = min(SPECIAL, key=lambda v: abs(value - v))
    direction: tuple[tuple[str, float], ...] = ()
    unbounded = False
    if mass is not None and np.all(np.isfinite(mass)):
        w, v = np.linalg.eigh(0.5 * (mass + mass.T))
        size = np.abs(w)
        if start is not None and np.all(np.isfinite(start)):
            before = np.abs(np.linalg.eigvalsh(0.5 * (start + start.T)))
            unbounded = bool(size.max() * before.max() ** -1 > before.min() / max(size.min(), 1e-300))
        vector = v[:, int(np.argmax(size) if unbounded else np.argmin(size))]
        vector = vector * (1.0 if vector[int(np.argmax(np.abs(vector)))] > 0 else -1.0)
        direction = tuple((names[j], float(vector[j])) for j in np.argsort(-np.abs(vector)) if abs(vector[j]) > 0.2)
    return Singularity(names[i], value, near if abs(value - near) < 0.2 else None, direction, unbounded)
