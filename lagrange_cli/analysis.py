"""What the equations say beyond themselves: generalized momenta and conserved quantities,
the Hamiltonian, equilibrium points, the linearization about them, and stability.

    p_i = dL/dq_dot_i                            (Eq. 6.35)
    q_k ignorable (dL/dq_k = 0)  =>  p_k = const  (Eqs. 6.37-6.38)
    h = sum p_i q_dot_i - L,  H(q, p) = h at q_dot = M^-1 (p - b)
    M0 x_ddot + C0 x_dot + K0 x = 0,  K0 = -dF/dq,  C0 = -dF/dq_dot  at (q0, 0)
"""

from __future__ import annotations

import math
import signal
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field

import sympy as sp

from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

HAMILTONIAN_MAX_N = 3


@dataclass(frozen=True)
class Info:
    """The structure of a system: what is conserved, and its Hamiltonian where it can be written."""

    coordinates: tuple[str, ...]
    degrees_of_freedom: int
    momenta: tuple[sp.Expr, ...]
    ignorable: tuple[str, ...]
    energy: sp.Expr
    energy_conserved: bool
    hamiltonian: sp.Expr | None
    hamiltonian_note: str
    momentum_symbols: tuple[sp.Symbol, ...]
    autonomous: bool
    conservative: bool
    constraints: tuple[tuple[str, str, str], ...]


def info(model: Model) -> Info:
    """Momenta, ignorable coordinates, energy function, Hamiltonian and the system's kind."""
    ignorables = tuple(c for i, c in enumerate(model.coordinates) if model.ignorable(i))
    symbols = tuple(sp.Symbol(f"p_{c}") for c in model.coordinates)
    hamiltonian, note = _hamiltonian(model, symbols)
    kinds = tuple((c.name, "holonomic" if c.holonomic else "velocity", str(c.multiplier)) for c in model.constraints)
    return Info(
        coordinates=model.coordinates,
        degrees_of_freedom=model.n - sum(1 for c in model.constraints),
        momenta=tuple(sp.factor_terms(p) for p in model.momenta),
        ignorable=ignorables,
        energy=sp.factor_terms(model.energy),
        energy_conserved=model.energy_conserved,
        hamiltonian=hamiltonian,
        hamiltonian_note=note,
        momentum_symbols=symbols,
        autonomous=model.autonomous,
        conservative=not model.dissipative and not model.forced,
        constraints=kinds,
    )


def _hamiltonian(model: Model, p: tuple[sp.Symbol, ...]) -> tuple[sp.Expr | None, str]:
    """H(q, p) = 1/2 (p - b)^T M^-1 (p - b) - L0 for L = 1/2 q_dot^T M q_dot + b . q_dot + L0."""
    if model.constraints:
        return None, "not written for a system with kept constraints (eliminate them first)"
    if any(model.mass_matrix.has(v) for v in model.qd):
        return None, "the Lagrangian is not quadratic in the velocities"
    if model.n > HAMILTONIAN_MAX_N:
        return None, f"not written for more than {HAMILTONIAN_MAX_N} coordinates (M^-1 grows too large)"
    zero = {v: 0 for v in model.qd}
    b = sp.Matrix([sp.diff(model.lagrangian, v).xreplace(zero) for v in model.qd])
    l0 = model.lagrangian.xreplace(zero)
    mass = sp.Matrix(model.mass_matrix)
    det = sp.factor_terms(sp.trigsimp(mass.det()))
    if det == 0:
        return None, "the mass matrix is singular (the Legendre transform does not exist)"
    shifted = sp.Matrix(p) - b
    adjugate = mass.adjugate()
    quadratic = (shifted.T * adjugate * shifted)[0]
    return sp.factor_terms(sp.expand(quadratic) / (2 * det) - l0), ""


# -- equilibria and linearization -----------------------------------------------------------


@dataclass(frozen=True)
class Linearization:
    """M0 x_ddot + C0 x_dot + K0 x = 0 about `point`, with its numeric modes at `values`."""

    point: Mapping[sp.Symbol, sp.Expr]
    mass: sp.Matrix
    damping: sp.Matrix
    stiffness: sp.Matrix
    stability: str
    condition: tuple[sp.Expr, ...] = ()
    neutral: tuple[str, ...] = ()
    frequencies: tuple[float, ...] = ()
    modes: tuple[tuple[float, ...], ...] = ()
    eigenvalues: tuple[complex, ...] = ()
    values: Mapping[str, float] = field(default_factory=dict)


def linearize(model: Model, point: Mapping[sp.Symbol, sp.Expr], values: Mapping[str, float] | None = None) -> Linearization:
    """Linearize about an equilibrium (q0, q_dot = 0): K0 = -dF/dq, C0 = -dF/dq_dot, M0 = M(q0)."""
    if model.constraints:
        raise DerivationError(f"{model.source}: linearization of a system with kept constraints is not supported; eliminate them (`eliminate:`) first")
    if not model.autonomous:
        raise DerivationError(f"{model.source}: the system depends explicitly on time, so it has no fixed equilibria to linearize about")
    point = {q: point.get(q, sp.Integer(0)) for q in model.q}  # coordinates not given are 0
    full = {**point, **{v: sp.Integer(0) for v in model.qd}}
    forcing = sp.Matrix(model.forcing)
    residual = [sp.simplify(f.xreplace(full)) for f in forcing]
    values = dict(values if values is not None else model.parameter_values())
    if any(r != 0 for r in residual) and not _numerically_zero(residual, values):
        raise DerivationError(f"{model.source}: {_point_text(point)} is not an equilibrium: the generalized forces there are {[str(r) for r in residual]}")
    stiffness = sp.Matrix([[sp.simplify(-sp.diff(f, q).xreplace(full)) for q in model.q] for f in forcing])
    damping = sp.Matrix([[sp.simplify(-sp.diff(f, v).xreplace(full)) for v in model.qd] for f in forcing])
    mass = sp.Matrix(model.mass_matrix).xreplace(full).applyfunc(sp.simplify)
    if sp.simplify(mass.det()) == 0:
        return Linearization(point, mass, damping, stiffness, "degenerate (the mass matrix is singular at this point: a coordinate singularity)", values=values)
    neutral = [i for i in range(model.n) if all(stiffness[i, j] == 0 and stiffness[j, i] == 0 for j in range(model.n))]
    keep = [i for i in range(model.n) if i not in neutral]
    condition = stability_condition(stiffness.extract(keep, keep), damping.extract(keep, keep), model) if keep else (sp.true,)
    lin = Linearization(point, mass, damping, stiffness, "", condition, tuple(model.coordinates[i] for i in neutral), values=values)
    return _modes(lin, model)


def stability_condition(stiffness: sp.Matrix, damping: sp.Matrix, model: Model) -> tuple[sp.Expr, ...]:
    """Sylvester's criterion on K0 (stable when K0 is positive definite and there are no
    gyroscopic terms): each leading principal minor > 0, positive factors removed."""
    if damping != damping.T or any(m.free_symbols - {p.symbol for p in model.parameters} for m in stiffness):
        return ()
    conditions = []
    for k in range(1, stiffness.rows + 1):
        minor = sp.factor(stiffness[:k, :k].det())
        condition = _positive(minor, model)
        if condition is sp.false:
            return (sp.false,)
        if condition is not sp.true:
            conditions.append(condition)
    return tuple(conditions) or (sp.true,)


def _positive(expr: sp.Expr, model: Model) -> sp.Basic:
    """`expr > 0` with factors known to be positive divided out, written as `a < b`."""
    positive = {p.symbol for p in model.parameters if not p.real}
    factors = sp.Mul.make_args(sp.factor(expr))
    sign = 1
    kept = []
    for f in factors:
        if f.is_number:
            sign *= 1 if f > 0 else -1
        elif f.free_symbols <= positive and (f.is_Symbol or (f.is_Pow and f.exp.is_even) or (f.is_Pow and f.base.is_Symbol)):
            continue
        else:
            kept.append(f)
    if not kept:
        return sp.true if sign > 0 else sp.false
    body = sp.expand(sign * sp.Mul(*kept))
    terms = sp.Add.make_args(body)
    negative = [-t for t in terms if t.could_extract_minus_sign()]
    positive_terms = [t for t in terms if not t.could_extract_minus_sign()]
    if body.free_symbols <= positive and not negative:
        return sp.true
    if body.free_symbols <= positive and not positive_terms:
        return sp.false
    if not negative or not positive_terms:
        return sp.StrictGreaterThan(body, 0)
    return _isolate(sp.Add(*negative), sp.Add(*positive_terms), positive)


def _isolate(lhs: sp.Expr, rhs: sp.Expr, positive: set[sp.Symbol]) -> sp.Basic:
    """`lhs < rhs` for positive monomials, made readable: common square roots taken
    (g**2 < l**2*omega**4 -> g < l*omega**2), then the highest power isolated (omega**2 > g/l)."""
    if not (lhs.is_Mul or lhs.is_Pow or lhs.is_Symbol) or not (rhs.is_Mul or rhs.is_Pow or rhs.is_Symbol) or not (lhs.free_symbols | rhs.free_symbols) <= positive:
        return sp.StrictLessThan(lhs, rhs)
    dummies = {s: sp.Symbol(s.name, positive=True) for s in positive}
    back = {v: k for k, v in dummies.items()}
    a, b = lhs.xreplace(dummies), rhs.xreplace(dummies)
    while all(e % 2 == 0 for side in (a, b) for _, e in side.as_powers_dict().items() if not _.is_number):
        a, b = sp.sqrt(a), sp.sqrt(b)
    powers = [(e, str(f), f**e, side) for side, expr in (("left", a), ("right", b)) for f, e in expr.as_powers_dict().items() if f.free_symbols]
    if not powers:
        return sp.StrictLessThan(a.xreplace(back), b.xreplace(back))
    _, _, target, side = max(powers, key=lambda p: (p[0], p[1]))
    if side == "left":
        return sp.StrictLessThan(target.xreplace(back), sp.cancel(b / (a / target)).xreplace(back))
    return sp.StrictGreaterThan(target.xreplace(back), sp.cancel(a / (b / target)).xreplace(back))


def _modes(lin: Linearization, model: Model) -> Linearization:
    """Numeric eigen-analysis with the default parameter values (when all are known)."""
    import numpy as np

    symbols = {p.symbol: lin.values[p.name] for p in model.parameters if p.name in lin.values}
    if any(not sp.sympify(v).xreplace(symbols).is_real for v in lin.point.values() if sp.sympify(v).xreplace(symbols).is_number):
        return _replace(lin, stability="does not exist for the default parameter values (the point is not real)")
    try:
        m = np.array(lin.mass.xreplace(symbols).evalf(), dtype=float)
        c = np.array(lin.damping.xreplace(symbols).evalf(), dtype=float)
        k = np.array(lin.stiffness.xreplace(symbols).evalf(), dtype=float)
    except (TypeError, ValueError, ArithmeticError):
        if any(e.free_symbols for e in (*lin.mass, *lin.damping, *lin.stiffness) for e in [sp.sympify(e).xreplace(symbols)]):
            return _replace(lin, stability="unknown (give every parameter a value)")
        return _replace(lin, stability="unknown (M0, C0 or K0 is not a finite real number at this point: it lies on the edge of a function's domain)")
    if not (np.all(np.isfinite(m)) and np.all(np.isfinite(c)) and np.all(np.isfinite(k))):
        return _replace(lin, stability="unknown (M0, C0 or K0 is not finite at this point: it lies on the edge of a function's domain)")
    n = m.shape[0]
    try:
        system = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(m, k), -np.linalg.solve(m, c)]])
        eigenvalues = np.linalg.eigvals(system)
    except np.linalg.LinAlgError:
        return _replace(lin, stability="degenerate (the mass matrix is singular at this point)")
    if not np.all(np.isfinite(eigenvalues)):
        return _replace(lin, stability="degenerate (the mass matrix is nearly singular at this point)")
    scale = max(1.0, float(np.max(np.abs(eigenvalues))))
    largest = float(np.max(eigenvalues.real))
    if largest > 1e-9 * scale:
        stability = "unstable"
    elif largest < -1e-9 * scale:
        stability = "asymptotically stable"
    else:
        stability = "stable (marginally: undamped oscillations)"
    if lin.neutral and stability != "unstable":
        stability += f", with free drift along {', '.join(lin.neutral)}"
    frequencies: tuple[float, ...] = ()
    modes: tuple[tuple[float, ...], ...] = ()
    if np.allclose(c, 0) and np.allclose(k, k.T):
        squared, vectors = np.linalg.eig(np.linalg.solve(m, k))
        order = np.argsort(squared.real)
        frequencies = tuple(float(np.sqrt(s)) if s > 1e-12 * scale**2 else 0.0 if s > -1e-12 * scale**2 else float("nan") for s in squared.real[order])
        modes = tuple(tuple(float(x) for x in vectors[:, i].real / np.max(np.abs(vectors[:, i].real))) for i in order)
    return _replace(lin, stability=stability, frequencies=frequencies, modes=modes, eigenvalues=tuple(complex(e) for e in eigenvalues))


def equilibria(model: Model, ranges: Mapping[sp.Symbol, tuple[float, float]] | None = None, seconds: float = 10.0) -> list[dict[sp.Symbol, sp.Expr]]:
    """Points where the system can rest (q_dot = 0 and F(q, 0) = 0): symbolically where sympy
    can solve within `seconds`, otherwise numerically from many starts inside `ranges`."""
    if model.constraints:
        raise DerivationError(f"{model.source}: equilibria of a system with kept constraints are not supported; eliminate them (`eliminate:`) first")
    if not model.autonomous:
        raise DerivationError(f"{model.source}: the system depends explicitly on time, so it has no fixed equilibria")
    rest = {v: 0 for v in model.qd}
    equations = [sp.factor(f.xreplace(rest)) for f in model.forcing]
    if all(e == 0 for e in equations):
        return [{q: sp.Symbol(f"{q}_0") for q in model.q}]
    found = _symbolic_equilibria(model, equations, seconds)
    if found is not None:
        return _in_ranges(found, ranges, model)
    return _numeric_equilibria(model, equations, ranges or {})


def _symbolic_equilibria(model: Model, equations: list[sp.Expr], seconds: float) -> list[dict[sp.Symbol, sp.Expr]] | None:
    unknowns = [q for q in model.q if any(e.has(q) for e in equations)]
    nonzero = [e for e in equations if e != 0]
    if any(not any(e.has(q) for q in model.q) for e in nonzero):
        return []  # a generalized force that no configuration can cancel (e.g. a slope)
    try:
        with time_limit(seconds):
            solutions = sp.solve(nonzero, unknowns, dict=True)
    except (TimeoutError, NotImplementedError):
        return None
    if not solutions:
        return []
    free = [q for q in model.q if q not in unknowns]
    return [{**{q: sp.Symbol(f"{q}_0") for q in free}, **{q: sp.simplify(s.get(q, q)) for q in unknowns}} for s in solutions]


def _numeric_equilibria(model: Model, equations: list[sp.Expr], ranges: Mapping[sp.Symbol, tuple[float, float]]) -> list[dict[sp.Symbol, sp.Expr]]:
    import numpy as np
    from scipy.optimize import root

    values = {p.symbol: v for p in model.parameters if (v := model.parameter_values().get(p.name)) is not None}
    missing = [p.name for p in model.parameters if p.symbol not in values and any(e.has(p.symbol) for e in equations)]
    if missing:
        raise DerivationError(f"{model.source}: sympy could not solve for the equilibria symbolically, and a numeric search needs values for {', '.join(missing)}")
    function = sp.lambdify([model.q], [e.xreplace(values) for e in equations], "math")
    bounds = [ranges.get(q, (-np.pi, np.pi)) for q in model.q]
    rng = np.random.default_rng(0)
    points: list[np.ndarray] = []
    failures: dict[str, int] = {}
    for _ in range(STARTS):
        start = np.array([rng.uniform(a, b) for a, b in bounds])
        try:
            with np.errstate(all="ignore"):
                result = root(lambda x: _forces(function, x), start, method="hybr")
        except _Unevaluable as bad:  # a start (or the search from it) where the forces cannot be evaluated
            failures[str(bad)] = failures.get(str(bad), 0) + 1
            continue
        if not (result.success and np.all(np.isfinite(result.x))):
            continue
        if all(a - 1e-9 <= x <= b + 1e-9 for x, (a, b) in zip(result.x, bounds, strict=True)) and not any(np.allclose(result.x, p, atol=1e-7) for p in points):
            points.append(result.x)
    if failures and sum(failures.values()) == STARTS:
        where = ", ".join(f"{q} in [{a:g}, {b:g}]" for q, (a, b) in zip(model.q, bounds, strict=True))
        raise DerivationError(
            f"{model.source}: the forces cannot be evaluated from any of {STARTS} starting points of the numeric search ({where}): {max(failures, key=lambda k: failures[k])}; give ranges inside their domain (--range)"
        )
    points.sort(key=lambda x: tuple(x))
    return [{q: sp.Float(x, 12) for q, x in zip(model.q, p, strict=True)} for p in points]


STARTS = 200
"""Starting points of the numeric search for equilibria."""


class _Unevaluable(Exception):
    """The forces cannot be evaluated at a point to finite real numbers; the text says why."""


def _forces(function: Callable[[list[float]], list[float]], x: Sequence[float]) -> list[float]:
    """F(q, 0) at q = x as finite floats, or `_Unevaluable` (a math domain error, a division by
    zero, an overflow, a complex or NaN value)."""
    try:
        values = [float(v) for v in function([float(v) for v in x])]
    except (ArithmeticError, ValueError, TypeError) as error:
        raise _Unevaluable(f"{type(error).__name__}: {error}" if str(error) else type(error).__name__) from None
    if not all(math.isfinite(v) for v in values):
        raise _Unevaluable("a force is not finite (a division by zero or an overflow)")
    return values


def _in_ranges(found: list[dict[sp.Symbol, sp.Expr]], ranges: Mapping[sp.Symbol, tuple[float, float]] | None, model: Model) -> list[dict[sp.Symbol, sp.Expr]]:
    if not ranges:
        return found
    values = {p.symbol: v for p in model.parameters if (v := model.parameter_values().get(p.name)) is not None}
    kept = []
    for point in found:
        ok = True
        for q, (a, b) in ranges.items():
            x = point.get(q)
            if x is None:
                continue
            number = x.xreplace(values)
            if number.is_number and number.is_real and not (a - 1e-12 <= float(number) <= b + 1e-12):
                ok = False
        if ok:
            kept.append(point)
    return kept


def steady_motions(model: Model, seconds: float = 10.0) -> list[tuple[sp.Symbol, sp.Expr]]:
    """Steady motions: the other coordinates at rest while ignorable ones turn at constant
    rates. With q_ddot = 0 and the non-ignorable velocities zero, each non-ignorable
    equation F_i = 0 becomes a relation among the ignorable rates, solved for the last one
    (e.g. the free top's steady precession psi_dot = (I_perp - I_par)/I_par cos(theta) phi_dot)."""
    cyclic = [i for i in range(model.n) if model.ignorable(i)]
    if not cyclic or len(cyclic) == model.n or model.constraints:
        return []
    rest = {model.qd[i]: 0 for i in range(model.n) if i not in cyclic}
    target = model.qd[cyclic[-1]]
    relations = []
    for i in range(model.n):
        if i in cyclic:
            continue
        equation = sp.factor(model.forcing[i].xreplace(rest))
        if not equation.has(target):
            continue
        try:
            with time_limit(seconds):
                solutions = sp.solve(equation, target)
        except (TimeoutError, NotImplementedError):
            continue
        relations += [(target, sp.factor_terms(sp.simplify(x))) for x in solutions]
    return relations


@contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise TimeoutError in the block after `seconds` (main thread on Unix; else no limit)."""
    import threading

    if seconds <= 0 or threading.current_thread() is not threading.main_thread() or not hasattr(signal, "SIGALRM"):
        yield
        return

    def expire(signum: int, frame: object) -> None:
        raise TimeoutError

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _numerically_zero(values: Sequence[sp.Expr], parameters: Mapping[str, float]) -> bool:
    numbers = {sp.Symbol(k): v for k, v in parameters.items()}
    try:
        return all(abs(complex(sp.N(v.xreplace(numbers)))) < 1e-9 for v in values)
    except (TypeError, ValueError):
        return False


def _point_text(point: Mapping[sp.Symbol, sp.Expr]) -> str:
    return ", ".join(f"{k} = {v}" for k, v in point.items())


def _replace(lin: Linearization, **changes: object) -> Linearization:
    import dataclasses

    return dataclasses.replace(lin, **changes)  # type: ignore[arg-type]
