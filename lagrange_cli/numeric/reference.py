"""What a study measures against: the file's exact solution, or a computed reference confirmed by a
second method, and how nearby trajectories part (`Horizon`: chaos cuts the measured window).

The reference is the file's `exact:` solution when it has one for every coordinate (and the
initial state is the file's), otherwise a run at the reference tolerance confirmed by a second,
different method; their largest disagreement is the reference's own error. A reference run that
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
from lagrange_cli.model import Model
from lagrange_cli.numeric import compile, integrators, policy
from lagrange_cli.numeric.runs import ATOL_RATIO, REFERENCE_STEPS, Candidate, Setup, component_scale, over_step_budget, run, scaled_errors, start_of, tol_text
from lagrange_cli.numeric.simulate import state_text

HORIZON_THRESHOLD = 1e-3  # separation (scaled) at which nearby trajectories have parted
CHAOS_GROWTH = 100.0  # growth over the second half of the time to part, above which it is exponential


class ReferenceFailed(LagrangeError):
    """The reference run failed or ran out of its step budget: a failed numerical run (exit 1),
    the message naming the time, the state and the cause."""

    exit_code = 1


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
    s = policy.decide(model, replace(start_of(model, setup), method="auto", backend="auto", rtol=tolerance))
    return Candidate(s.method), Candidate("LSODA")


def computed_reference(model: Model, setup: Setup, tolerance: float, hint: str = ", looser --tolerances") -> Reference:
    """The primary reference run confirmed by the second; raises ReferenceFailed if the primary
    fails (`hint`: the option that loosens the reference, as the calling command names it)."""
    primary, second = reference_candidates(model, setup, tolerance)
    began = time.perf_counter()
    main = run(model, primary, tolerance, setup, reference=True)
    if over_step_budget(main):
        raise ReferenceFailed(
            f"{model.source}: the reference run ({primary.method}, rtol {tol_text(tolerance)}) did not reach t = {setup.t_end:g} within {main.stats.steps} steps"
            f" (the step budget of reference runs, {REFERENCE_STEPS} x --max-steps): it stopped at t = {main.t_last:.6g}; state: {state_text(model, main.y_last)};"
            f" give a shorter --t-end{hint} or a larger --max-steps"
        )
    if main.failed:
        raise ReferenceFailed(f"{model.source}: the reference run ({primary.method}, rtol {tol_text(tolerance)}) failed: {main.message}")
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
    names = [*model.coordinates, *(f"{c}_dot" for c in model.coordinates)]
    moved = {n: v + tolerance * max(1.0, abs(v)) for n, v in zip(names, base.settings.y0, strict=True)}
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


def prepare(
    model: Model, setup: Setup, ref_tol: float, progress: Callable[[str], None] | None = None, window: float = HORIZON_THRESHOLD, hint: str = ", looser --tolerances"
) -> tuple[Setup, Reference, Horizon | None, tuple[str, ...]]:
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
        reference = computed_reference(model, setup, ref_tol, hint)
    return setup, reference, found, tuple(notes)
