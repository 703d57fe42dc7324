"""The settings of one simulation: arguments, then the file's `simulate` and `initial` blocks, then defaults.

`resolve` validates everything at once into a frozen `Settings` (or raises `LagrangeError`
saying what to change), and resolves `method="auto"` and `backend="auto"` from the system:
the linearisation at the initial state tells whether it is stiff enough that Radau beats a
compiled explicit method (`diagnostics.choose`, the same rule `lagrange stress` reports with)
or not (DOP853), and how fast it moves (whether compiling pays off, and the symplectic
method's step).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from lagrange_cli.algebra import check_invertible
from lagrange_cli.emit.common import require_defined
from lagrange_cli.errors import LagrangeError, Span, SpecError
from lagrange_cli.expr import Scope, parse_expression
from lagrange_cli.model import Model
from lagrange_cli.numeric import compile, diagnostics

METHODS = ("auto", "RK45", "DOP853", "Radau", "BDF", "LSODA", "symplectic")
COMPILED = ("RK45", "DOP853", "symplectic")
BACKENDS = ("auto", "compiled", "python")
DEFAULTS = {"t_end": 10.0, "rtol": 1e-8, "atol": 1e-10, "samples": 1001}
MAX_SAMPLES = 1_000_000
"""Samples one run may keep: each costs 16 bytes per coordinate, and the monitors evaluate at each."""
HEAVY = 3000.0  # rate x time span above which compiling pays off (about 1e4 steps)
STAGES = 2  # Gauss-Legendre stages of the symplectic method (order 4)


@dataclass(frozen=True)
class Settings:
    """Everything one run needs, validated; `method` and `backend` are resolved (never "auto")."""

    t0: float
    t_end: float
    method: str
    backend: str
    rtol: float
    atol: float
    step: float | None
    stages: int
    max_step: float
    t_eval: tuple[float, ...]
    parameters: tuple[tuple[str, float], ...]
    p: tuple[float, ...]
    y0: tuple[float, ...]
    until: str | None
    event: sp.Expr | None
    notes: tuple[str, ...]


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
    """Validated settings, with `auto` choices made; raises `LagrangeError` on bad input."""
    check(model)
    file = dict(model.simulate)
    end = _positive("t_end", t_end if t_end is not None else file.get("t_end", DEFAULTS["t_end"]))
    chosen_method = _method(method if method is not None else file.get("method", "auto"))
    relative = _positive("rtol", rtol if rtol is not None else file.get("rtol", DEFAULTS["rtol"]))
    absolute = _positive("atol", atol if atol is not None else file.get("atol", DEFAULTS["atol"]))
    if relative < 100 * np.finfo(float).eps:
        raise LagrangeError(f"rtol = {relative:g} is below what double precision can deliver; give at least {100 * np.finfo(float).eps:.1e}")
    fixed = step if step is not None else file.get("step")
    fixed = _positive("step", fixed) if fixed is not None else None
    limit = _positive("max_step", max_step) if max_step is not None else math.inf
    times = _times(end, t_eval, samples if samples is not None else file.get("samples"))
    names, p = _parameters(model, parameters or {})
    y0 = _initial(model, initial or {})
    event = parse_until(model, until) if until is not None else None
    if backend not in BACKENDS:
        raise LagrangeError(f"unknown backend '{backend}'; choose one of {', '.join(BACKENDS)}")
    chosen_method, backend, fixed, rate, notes = _choose(model, chosen_method, backend, fixed, end, relative, p, y0)
    vector = (*p, _stabilisation(rate, end)) if model.constraints else p
    notes = (*notes, *constraint_notes(model, p, y0))
    return Settings(0.0, end, chosen_method, backend, relative, absolute, fixed, STAGES, limit, times, tuple(zip(names, p, strict=True)), vector, y0, until, event, notes)


_ROWS: dict[int, tuple[Model, Callable[..., list[list[float]]]]] = {}


def constraint_notes(model: Model, p: Sequence[float], y0: Sequence[float]) -> list[str]:
    """A note for each kept constraint the initial state violates, in positions (f(q, 0) != 0)
    or velocities (a . q_dot + b != 0), beyond round-off relative to the sizes of its terms:
    the run then starts off the constrained motion (the stabilisation pulls it back)."""
    if not model.constraints:
        return []
    model = model.with_definitions()  # the rows are evaluated: defined functions written out
    if id(model) not in _ROWS:
        import sympy as sp

        rows = [[c.expr if c.holonomic else sp.Integer(0), *c.jacobian, c.bias] for c in model.constraints]  # a velocity row's expr has q_dot
        _ROWS[id(model)] = (model, sp.lambdify([model.t, *model.q, *(par.symbol for par in model.parameters)], rows, modules="math"))
    n = model.n
    q, qd = np.array(y0[:n], dtype=float), np.array(y0[n:], dtype=float)
    try:
        values = np.array(_ROWS[id(model)][1](0.0, *q, *p[: len(model.parameters)]), dtype=float)
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


def _stabilisation(rate: float, t_end: float) -> float:
    """Baumgarte's alpha for kept constraints: the system's own fastest rate (so that it adds
    no stiffness), at least 10 / t_end so that drift decays within the run."""
    return max(rate, 10.0 / t_end)


_CHECKED: dict[int, Model] = {}


def check(model: Model) -> None:
    """Every function defined and M invertible at a generic point (once per model object);
    raises `LagrangeError` saying what is missing."""
    if id(model) not in _CHECKED:
        require_defined(model, "simulation")
        check_invertible(model.with_definitions())
        _CHECKED[id(model)] = model


def _closest(name: str, candidates: Sequence[str]) -> str | None:
    """The candidate most like `name`, for a "did you mean" hint."""
    import difflib

    matches = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    return matches[0] if matches else None


def _positive(name: str, value: object) -> float:
    """A positive, finite number, or a LagrangeError naming the setting."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise LagrangeError(f"{name} must be a number, got {value!r}") from None
    if not (math.isfinite(number) and number > 0):
        raise LagrangeError(f"{name} must be a positive number, got {value!r}")
    return number


def _finite(what: str, value: object) -> float:
    """A finite real number (--set and --initial values), or a LagrangeError naming it."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise LagrangeError(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(number):
        raise LagrangeError(f"{what} must be a finite number, got {value!r}")
    return number


def _method(name: str) -> str:
    for known in METHODS:
        if name.lower() == known.lower():
            return known
    hint = _closest(name, list(METHODS))
    raise LagrangeError(f"unknown method '{name}'; choose one of {', '.join(METHODS)}" + (f" (did you mean '{hint}'?)" if hint else ""))


def _times(t_end: float, t_eval: Sequence[float] | None, samples: object) -> tuple[float, ...]:
    """The sample times: `t_eval` as given (sorted, within [0, t_end]) or `samples` evenly spaced."""
    if t_eval is not None:
        values = [_finite("a time of t_eval", v) for v in t_eval]
        if len(values) > MAX_SAMPLES:
            raise LagrangeError(f"t_eval has {len(values)} times, more than a run keeps (at most {MAX_SAMPLES}, for memory)")
        if not values or any(not (0.0 <= v <= t_end) for v in values) or values != sorted(values):
            raise LagrangeError(f"t_eval must be a non-empty increasing sequence of times in [0, {t_end:g}]")
        return tuple(values)
    count = DEFAULTS["samples"] if samples is None else samples
    if not isinstance(count, int) or isinstance(count, bool) or count < 2:
        raise LagrangeError(f"samples must be a whole number of at least 2, got {count!r}")
    if count > MAX_SAMPLES:
        raise LagrangeError(f"samples = {count} is more than a run keeps (at most {MAX_SAMPLES}, for memory); give fewer samples")
    return tuple(np.linspace(0.0, t_end, count).tolist())


def _parameters(model: Model, overrides: Mapping[str, float]) -> tuple[tuple[str, ...], tuple[float, ...]]:
    """Parameter values (defaults overridden), in the order of the generated code's p vector."""
    known = [p.name for p in model.parameters]
    for name, value in overrides.items():
        if name not in known:
            hint = _closest(name, known)
            choices = ", ".join(known) if known else "none: the system has no parameters"
            raise LagrangeError(f"'{name}' is not a parameter of {model.source}; parameters: {choices}" + (f" (did you mean '{hint}'?)" if hint else ""))
        _finite(f"the value of parameter '{name}'", value)
        declared = next(p for p in model.parameters if p.name == name)
        if not declared.real and float(value) <= 0:
            raise LagrangeError(
                f"'{name}' is positive in {model.source} (the equations were derived assuming so), but was given {float(value):g}; give a positive value, or declare it `{name}: {{value: ..., sign: real}}`"
            )
    values = {p.name: p.value for p in model.parameters}
    values.update({k: float(v) for k, v in overrides.items()})
    missing = [name for name, value in values.items() if value is None]
    if missing:
        listed = ", ".join(f"'{m}'" for m in missing)
        example = " ".join(f"--set {m}=VALUE" for m in missing)
        raise LagrangeError(f"{model.source}: parameter{'s' * (len(missing) > 1)} {listed} {'have' if len(missing) > 1 else 'has'} no value; give a default in the file, or `{example}`")
    return tuple(known), tuple(float(values[name]) for name in known)  # type: ignore[arg-type]


def _initial(model: Model, overrides: Mapping[str, float]) -> tuple[float, ...]:
    """y0 = [q..., q_dot...] from the file's `initial` (missing entries 0) and the overrides."""
    names = [*model.coordinates, *(f"{c}_dot" for c in model.coordinates)]
    for name, value in overrides.items():
        if name not in names:
            hint = _closest(name, names)
            raise LagrangeError(f"'{name}' is not a coordinate or velocity of {model.source}; choose from {', '.join(names)}" + (f" (did you mean '{hint}'?)" if hint else ""))
        _finite(f"the initial value of '{name}'", value)
    values = {**model.initial, **{k: float(v) for k, v in overrides.items()}}
    return tuple(float(values.get(name, 0.0)) for name in names)


def parse_until(model: Model, text: str) -> sp.Expr:
    """The stop condition `text`, parsed by the safe parser: coordinates, velocities,
    accelerations, multipliers (`lambda_<constraint>`), parameters and `t`."""
    symbols: dict[str, sp.Expr] = {str(s): s for s in (*model.q, *model.qd, *model.qdd, *model.multipliers, model.t)}
    symbols.update({p.name: p.symbol for p in model.parameters})

    def no_derivative(expr: sp.Expr) -> sp.Expr:
        raise LagrangeError("time derivatives are not allowed in a stop condition; write velocities as `<q>_dot` and accelerations as `<q>_ddot`")  # shown with a caret

    scope = Scope(symbols, {}, model.t, no_derivative, "a coordinate, velocity, acceleration (`<q>_ddot`), multiplier, parameter or `t`")
    try:
        return parse_expression(text, Span("--until", 1, 1, text), scope)
    except SpecError as error:
        if not error.diagnostics:
            raise LagrangeError(f"--until: time derivatives are not allowed in a stop condition; write velocities as `<q>_dot`: {text}") from None
        raise


def _choose(
    model: Model, method: str, backend: str, step: float | None, t_end: float, rtol: float, p: tuple[float, ...], y0: tuple[float, ...]
) -> tuple[str, str, float | None, float, tuple[str, ...]]:
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
        step = _symplectic_step(rate, t_end, rtol)
        if found is None:
            notes.append(f"symplectic step {step:.3g} = t_end/1000: the linearisation at the initial state could not be evaluated (give --step)")
        elif rate <= 0:
            notes.append(f"symplectic step {step:.3g} = t_end/1000: the linearisation at the initial state has no rates (give --step)")
        else:
            notes.append(f"symplectic step {step:.3g} from the fastest rate at the initial state ({rate:.3g}/s) and rtol")
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


def _symplectic_step(rate: float, t_end: float, rtol: float) -> float:
    """A step for the order-4 Gauss method: h * rate = 2 rtol^(1/4), the local energy error then
    being about rtol; at most t_end / 100."""
    if rate <= 0:
        return t_end / 1000
    return min(t_end / 100, 2.0 * rtol**0.25 / rate)


def initial_spectrum(model: Model, p: tuple[float, ...], y0: tuple[float, ...]) -> diagnostics.Spectrum | None:
    """The rates of the linearisation at y0 (None where the right-hand side cannot be evaluated);
    the same diagnosis `lagrange stress` makes along a trajectory."""
    functions = compile.build(model, "python")
    rhs = _safe_rhs(functions.module, (*p, 0.0) if model.constraints else p)
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
