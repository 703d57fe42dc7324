"""What `auto` means for one run: the method, the backend, the symplectic step and Baumgarte's alpha.

`decide(model, settings)` takes validated `Settings` (settings.py) and returns them resolved,
with notes saying why: the linearisation at the initial state tells whether the system is stiff
enough that Radau beats a compiled explicit method (`diagnostics.choose`, the same rule `lagrange
stress` reports with) or not (DOP853), and how fast it moves (whether compiling pays off, the
symplectic method's step, and the stabilisation rate of kept constraints).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model
from lagrange_cli.numeric import compile, diagnostics, integrators, memo
from lagrange_cli.numeric.settings import COMPILED, STAGES, Settings, code_parameters, validate

HEAVY = 3000.0  # rate x time span above which compiling pays off (about 1e4 steps)
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
) -> Settings:
    """`validate`, then `decide`: settings ready to run; raises `LagrangeError` on bad input."""
    settings = validate(
        model, t_end=t_end, method=method, rtol=rtol, atol=atol, step=step, samples=samples, t_eval=t_eval, parameters=parameters, initial=initial, until=until, backend=backend, max_step=max_step
    )
    return decide(model, settings)


def decide(model: Model, settings: Settings) -> Settings:
    """`settings` with `auto` resolved (method and backend), the symplectic step, and Baumgarte's
    alpha for kept constraints; notes say why and flag an initial state off the constraints."""
    method, backend, step, rate, notes = _choose(model, settings.method, settings.backend, settings.step, settings.t_end, settings.rtol, settings.values, settings.y0)
    alpha = stabilisation(rate, settings.t_end) if model.constraints else None
    notes = (*notes, *constraint_notes(model, settings.values, settings.y0))
    return dataclasses.replace(settings, method=method, backend=backend, step=step, alpha=alpha, notes=(*settings.notes, *notes))


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


def _choose(model: Model, method: str, backend: str, step: float | None, t_end: float, rtol: float, p: Sequence[float], y0: Sequence[float]) -> tuple[str, str, float | None, float, tuple[str, ...]]:
    """Resolve `auto` (method and backend) and the symplectic step, saying why in notes."""
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
    if backend == "compiled" and method in ("Radau", "BDF", "LSODA"):
        raise LagrangeError(f"{method} runs through scipy; use --backend python (or auto)")
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
        else:
            method, why = diagnostics.choose(found, t_end, compiled=backend != "python" and compile.numba_available())
        notes.append(f"method auto -> {method}: {why}")
    if method == "symplectic" and step is None:
        step, chosen = _symplectic_choice(model, found, rate, t_end, rtol, p, y0)
        notes.extend(chosen)
    if backend == "auto":
        backend, why = _backend(model, method, rate, t_end)
        notes.append(f"backend auto -> {backend}: {why}")
    if backend == "compiled" and not compile.numba_available():
        if method == "symplectic":
            raise LagrangeError(f"the symplectic method needs numba: {compile.NUMBA_HINT}, or use another --method")
        backend = "python"
        notes.append(f"backend compiled -> python: numba is not installed ({compile.NUMBA_HINT})")
    return method, backend, step, rate, tuple(notes)


def _backend(model: Model, method: str, rate: float, t_end: float) -> tuple[str, str]:
    if method not in COMPILED:
        return "python", f"{method} runs through scipy"
    if not compile.numba_available():
        if method == "symplectic":
            raise LagrangeError(f"the symplectic method needs numba: {compile.NUMBA_HINT}, or use another --method")
        return "python", "numba is not installed"
    if method == "symplectic":
        return "compiled", "the symplectic method runs compiled"
    if rate * t_end > HEAVY:
        return "compiled", f"a long run (rate {rate:.3g}/s x t_end {t_end:g}): compiling pays off"
    if (compile.cache_dir() / f"lagrange_numba_{compile.fingerprint(model, 'numba', False, None)}.py").exists():
        return "compiled", "this system is compiled already (cached)"
    return "python", "a short run: compiling would cost more than it saves"


def _symplectic_choice(model: Model, found: diagnostics.Spectrum | None, rate: float, t_end: float, rtol: float, p: Sequence[float], y0: Sequence[float]) -> tuple[float, list[str]]:
    """The symplectic step from a pilot (`symplectic_pilot`) started at `symplectic_step`'s guess, and notes saying how."""
    guess = symplectic_step(rate, t_end, rtol)
    if found is None:
        origin = "t_end/1000: the linearisation at the initial state could not be evaluated"
    elif rate <= 0:
        origin = "t_end/1000: the linearisation at the initial state has no rates"
    else:
        origin = f"the fastest rate at the initial state, {rate:.3g}/s, and rtol"
    pilot = symplectic_pilot(model, guess, t_end, rtol, p, y0)
    if pilot is None:
        return guess, [f"symplectic step {guess:.3g} ({origin}): no pilot run (the momenta at the initial state cannot be evaluated; give --step)"]
    notes = [
        f"symplectic step {pilot.step:.3g} from a pilot run started at {guess:.3g} ({origin}): runs at h and h/2 over t = {pilot.span:.3g} estimate the error at t_end at "
        f"{pilot.estimate:.2g} x rtol ({pilot.steps} pilot steps); the step stays fixed (that is what makes the method symplectic)"
    ]
    if not pilot.controlled:
        notes.append(
            f"warning: the symplectic method's pilot could not find a step that meets rtol {rtol:g} (estimate {pilot.estimate:.2g} x rtol at step {pilot.step:.3g}): "
            "its error is not controlled; give a smaller --step, use an adaptive --method (DOP853, Radau), or change coordinates"
        )
    return pilot.step, notes


def symplectic_pilot(model: Model, guess: float, t_end: float, rtol: float, p: Sequence[float], y0: Sequence[float]) -> integrators.GaussPilot | None:
    """The pilot runs of the symplectic method from the step `guess` (integrators.pilot_gauss),
    once per model and start; None where the momenta cannot be evaluated at the initial state.
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
        return integrators.pilot_gauss(numba, problem, z0, STAGES, guess, rtol, PILOT_ATOL * rtol)

    return memo.once(model, ("symplectic pilot", guess, t_end, rtol, tuple(p), tuple(y0)), compute)


def chosen_pilot(model: Model, settings: Settings) -> integrators.GaussPilot | None:
    """The pilot that chose the step of `settings` (None when the step was given, or for another method)."""
    if settings.method != "symplectic" or settings.step is None:
        return None
    guess = symplectic_step(initial_rate(model, settings), settings.t_end, settings.rtol)
    store = model.__dict__.get(memo.SLOT, {})
    pilot = store.get(("symplectic pilot", guess, settings.t_end, settings.rtol, tuple(settings.values), tuple(settings.y0)))
    return pilot if pilot is not None and pilot.step == settings.step else None


def symplectic_step(rate: float, t_end: float, rtol: float) -> float:
    """A step for the order-4 Gauss method: h * rate = 2 rtol^(1/4), the local energy error then
    being about rtol; at most t_end / 100."""
    if rate <= 0:
        return t_end / 1000
    return min(t_end / 100, 2.0 * rtol**0.25 / rate)


def initial_spectrum(model: Model, p: Sequence[float], y0: Sequence[float]) -> diagnostics.Spectrum | None:
    """The rates of the linearisation at y0 for the model's parameter values `p` (None where the
    right-hand side cannot be evaluated); the same diagnosis `lagrange stress` makes along a
    trajectory. Kept constraints without stabilisation (alpha = 0): alpha is chosen from these rates."""
    functions = compile.build(model, "python")
    rhs = _safe_rhs(functions.module, code_parameters(p, 0.0 if model.constraints else None))
    found = diagnostics.jacobian(rhs, 0.0, np.array(y0, dtype=float))
    return diagnostics.spectrum(found) if found is not None else None


def _safe_rhs(module: object, p: tuple[float, ...]) -> Callable[[float, np.ndarray], np.ndarray | None]:
    accel, n = module._accel, module._N  # type: ignore[attr-defined]

    def rhs(t: float, y: np.ndarray) -> np.ndarray | None:
        try:
            x = accel(t, y.tolist(), list(p))
        except (ArithmeticError, ValueError, TypeError):
            return None
        return np.array(y.tolist()[n:] + x[:n])

    return rhs
