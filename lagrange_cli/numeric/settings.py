"""The settings of one simulation: arguments, then the file's `simulate` and `initial` blocks, then defaults.

`validate` checks everything at once into a frozen `Settings` (or raises `LagrangeError` saying
what to change). It only validates: it compiles nothing and chooses nothing, so that `accuracy`
and `stress` can call it once for the parameter values and the initial state. Choosing what
`auto` means (the method, the backend, the symplectic step, Baumgarte's alpha for kept
constraints) is `policy.decide`'s; `policy.resolve` does both.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from lagrange_cli.algebra import check_solvable
from lagrange_cli.emit.common import require_defined
from lagrange_cli.errors import LagrangeError, Span, SpecError
from lagrange_cli.expr import Scope, parse_expression
from lagrange_cli.model import Model
from lagrange_cli.numeric import memo

METHODS = ("auto", "RK45", "DOP853", "Radau", "BDF", "LSODA", "symplectic")
COMPILED = ("RK45", "DOP853", "symplectic", "Radau")
BACKENDS = ("auto", "compiled", "python")
DEFAULTS = {"t_end": 10.0, "rtol": 1e-8, "atol": 1e-10, "samples": 1001}
MAX_SAMPLES = 1_000_000
"""Samples one run may keep: each costs 16 bytes per coordinate, and the monitors evaluate at each."""
STAGES = 2  # Gauss-Legendre stages of the symplectic method (order 4)


@dataclass(frozen=True)
class Settings:
    """Everything one run needs, validated. As `validate` returns them, `method` and `backend` are
    as asked (possibly "auto"); `policy.decide` returns them resolved (never "auto"), with the
    symplectic step, Baumgarte's `alpha` for kept constraints and notes saying why."""

    t0: float
    t_end: float
    method: str
    backend: str
    rtol: float
    atol: float
    step: float | None
    stages: int | None
    """Gauss-Legendre stages of the symplectic method; None (as `validate` returns it when not given):
    `policy.decide` chooses them with the step (given a step, STAGES)."""
    max_step: float
    t_eval: tuple[float, ...]
    parameters: tuple[tuple[str, float], ...]
    """(name, value) of each of the model's parameters, in the model's order."""
    y0: tuple[float, ...]
    until: str | None
    event: sp.Expr | None
    projection: bool = False
    """Project the state onto the kept constraints (positions and velocities, `projection.py`)
    after each stretch of the run between two samples: on by default for a model that keeps
    constraints, off without them."""
    alpha: float | None = None
    """Baumgarte's stabilisation rate for kept constraints (None without them, or before `policy.decide`)."""
    notes: tuple[str, ...] = ()

    @property
    def values(self) -> tuple[float, ...]:
        """The model's parameter values, in its order."""
        return tuple(value for _, value in self.parameters)

    @property
    def p(self) -> tuple[float, ...]:
        """The generated code's parameter vector: the model's parameters, then alpha when the
        model keeps constraints (see `code_parameters`)."""
        return code_parameters(self.values, self.alpha)


def code_parameters(values: Sequence[float], alpha: float | None) -> tuple[float, ...]:
    """The one place the generated code's `_p` is built: the model's parameter values, then
    Baumgarte's `_alpha` (codegen appends it to the parameters of a model with kept constraints)."""
    return (*values, alpha) if alpha is not None else tuple(values)


def validate(
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
    """Validated settings, `auto` left as asked; raises `LagrangeError` on bad input. `projection`
    (default: on when the model keeps constraints) projects onto them along the run. `stages`: the
    symplectic method's Gauss-Legendre stages (1, 2 or 3: order 2, 4, 6; default: the pilot's choice)."""
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
    if projection is not None and not isinstance(projection, bool):
        raise LagrangeError(f"projection must be true or false, got {projection!r}")
    project = bool(model.constraints) if projection is None else projection and bool(model.constraints)
    if stages is not None and (isinstance(stages, bool) or stages not in (1, 2, 3)):
        raise LagrangeError(f"stages must be 1, 2 or 3 (the Gauss-Legendre method of order 2, 4 or 6), got {stages!r}")
    return Settings(0.0, end, chosen_method, backend, relative, absolute, fixed, stages, limit, times, tuple(zip(names, p, strict=True)), y0, until, event, project)


def resolve(model: Model, **arguments: object) -> Settings:
    """`policy.resolve`: validated, then decided (kept here for callers of the old name)."""
    from lagrange_cli.numeric import policy

    return policy.resolve(model, **arguments)  # type: ignore[arg-type]


def check(model: Model) -> None:
    """Every function defined and M invertible at a generic point (once per model object);
    raises `LagrangeError` saying what is missing."""

    def checked() -> bool:
        require_defined(model, "simulation")
        check_solvable(model.with_definitions())
        return True

    memo.once(model, "checked for simulation", checked)


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


def _finite_times(t_eval: Sequence[float]) -> list[float]:
    """The times of `t_eval` as finite floats (all at once where they all are: `stress` and `accuracy` decide the
    settings of some 150 runs of 2001 samples each), else a LagrangeError naming the first that is not."""
    if isinstance(t_eval, np.ndarray | tuple | list):
        try:
            array = np.asarray(t_eval, dtype=float)
        except (TypeError, ValueError, OverflowError):
            array = None
        if array is not None and array.ndim == 1 and bool(np.all(np.isfinite(array))):
            return array.tolist()
    return [_finite("a time of t_eval", v) for v in t_eval]


def _times(t_end: float, t_eval: Sequence[float] | None, samples: object) -> tuple[float, ...]:
    """The sample times: `t_eval` as given (sorted, within [0, t_end]) or `samples` evenly spaced."""
    if t_eval is not None:
        values = _finite_times(t_eval)
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
