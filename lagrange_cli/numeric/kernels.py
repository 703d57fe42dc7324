"""Integration loops compiled once by numba and shared by every system.

A system's generated functions (`accel`, `hamilton`, `event`: see codegen.py) are compiled
with fixed signatures and passed in as first-class functions, so these loops are compiled
once per machine, cached, and call the right-hand side through a pointer (a few ns), with
nothing crossing back into Python per step. Everything works on float64 arrays and reports
by status codes (no exceptions in compiled code). compile.py copies this file into the cache
directory and imports it from there, so numba's cache sits beside it. The helpers are cached too
(`cache=True`, not only the entry points): an entry point compiled in one process (the explicit
loops in the command's own, Radau's in the one compiling ahead: `compile.warm_kernels`), or by an
earlier command, leaves the helpers it shares with the others (the projection, the LU, the initial
step) for them to load. The first `stress` of the pendulum with a multiplier: 34-36 s -> 30-32 s;
Radau's loops compiled after the explicit ones: 26 -> 20 s of CPU; erk_run and radau_run after their
projected cases: 21 -> 11 s. The entry points that only pick a loop's features (radau_run, radau_switched,
radau_projected, erk_switched, erk_projected) are compiled as that loop itself (`_loop_entry`): numba emits a
called function's code again inside its caller, so a one-line entry point cost a second pass over the whole loop
(Radau's: about 3 s of CPU; the first `stress` of the pendulum with a multiplier, 27-30 s -> 25.5-27.3 s).

- `erk_run`: adaptive explicit Runge-Kutta, Dormand-Prince 5(4) (`RK45`) or DOP853, with the
  same step-size control, initial step and dense output as scipy.integrate (so both take the
  same steps), samples written at requested times, and an event located by root finding on
  the dense output; it, `erk_switched` (a step landed on each crossing of the switching functions)
  and `erk_projected` are cases of one loop, `_erk_loop`;
- `erk_projected`: `erk_run` with the state projected onto kept constraints at given times (the
  samples) inside the loop: a step lands on each, the state is projected as `projection.Projector`
  does (`_project`, with the system's `rows` and `energy`), and the run goes on from it
  (`radau_projected`: the same for Radau IIA, which restarts at each projection);
- `gauss_run`: fixed-step Gauss-Legendre collocation in (q, p), symplectic and symmetric,
  stage equations solved to round-off by fixed-point iteration, or where that converges slowly
  (a stiff stretch) by simplified Newton iteration (a finite-difference Jacobian, refreshed when
  convergence slows); a sample between two steps is one Gauss step from the step's start (the
  method's own accuracy), events are found on a Hermite interpolant of degree 7 (`NODES`).
"""

# ruff: noqa: SIM108, SIM110  (explicit loops and branches compile best in numba)
# mypy: ignore-errors
from types import FunctionType
from typing import Any

import numpy as np
from numba import njit, types

from lagrange_cli.numeric.status import (
    ANALYTIC,
    ATOL,
    CHANGE_LIMIT,
    CHATTER,
    CONDITION_LIMIT,
    CONTRACTION,
    CURRENT_JAC,
    DONE,
    ENERGY,
    ENERGY_LIMIT,
    ERROR_OLD,
    EVENT,
    EVENT_VALUE,
    FAILED_AT,
    FAILURES,
    FLOOR_SAFETY,
    FLOORED,
    H_ABS_OLD,
    H_LAMBDA,
    HAVE_DENSE,
    HMAX,
    HMIN,
    LEVEL,
    LU_STEP,
    MAX_FACTOR,
    MAX_STEP,
    MIN_FACTOR,
    MIN_STEP_SPACINGS,
    MOVED,
    NEWTON,
    NEWTON_LIMIT,
    NEXT_BOUND,
    NEXT_SAMPLE,
    NFEV,
    NJEV,
    NLU,
    NO_CONVERGENCE,
    NONFINITE,
    NONSTIFF,
    NREJECT,
    NSTEPS,
    PAUSE_STEPS,
    POSITION,
    PROJECTIONS,
    QUICK_STEPS,
    ROUND_OFF_LEVEL,
    RTOL,
    RUNNING,
    SAFETY,
    SINGULAR,
    SIZE,
    STEP,
    STEP_COLLAPSE,
    STEP_OLD,
    STEPS,
    STIFF,
    STIFF_H_LAMBDA,
    STIFF_RESET,
    STIFF_STEPS,
    STIFFNESS,
    STRETCH,
    T0,
    T_BOUND,
    T_OLD,
    T_STOP,
    USE_EVENT,
    USE_LEVEL,
    VELOCITY,
    H,
    T,
)
from lagrange_cli.numeric.tableaux import (
    DOP853,
    DOP853_A,
    DOP853_B,
    DOP853_C,
    DOP853_D,
    DOP853_E3,
    DOP853_E5,
    GAUSS,
    MU_COMPLEX_IMAG,
    MU_COMPLEX_REAL,
    MU_REAL,
    RADAU_C,
    RADAU_E,
    RADAU_T,
    RADAU_TI,
    RK45,
    RK45_A,
    RK45_B,
    RK45_C,
    RK45_E,
    RK45_P,
)

__all__ = ["DIAGNOSTICS", "MAX_ITERATIONS", "PAUSE_STEPS", "SIGNATURES", "compiled", "diagnostics_start", "lu_solve", "memory_size"]
# The Gauss stage equations are solved to round-off (a looser tolerance, such as the 1e-11 used
# before, leaves an error that is not symmetric and makes the energy drift over long runs: issue 15).
ROUNDOFF = 2.220446049250313e-16
"""The iteration stops when the correction of every component is below this, relative to the
component's size (one ulp)."""
STAGNATION = 1e-12
"""Corrections that stop decreasing at or below this (relative) are round-off noise (a right-hand
side that cancels catastrophically cannot do better): the iteration has converged. Above it, they
mean no convergence."""
SLOW = 0.02
"""A step whose Newton corrections shrank by less than this factor a sweep (the Newton matrix is
stale: its Jacobian is from an earlier part of the motion) refreshes the matrix for the next step."""
MAX_ITERATIONS = 50
"""Sweeps of one step at most (a converging step takes about 4 to 12)."""
FIXED_SLOW = 0.25
"""A step is first solved by fixed-point iteration (W_i <- h sum_j a_ij F(z + W_j): s evaluations a
sweep and no linear algebra, cheaper than a Newton sweep on a non-stiff problem); where its corrections
shrink by less than this factor over two sweeps (well above round-off), stop growing smaller, or the
stages cannot be evaluated, the step is solved again by simplified Newton iteration from the same
predictor. Two sweeps, because the iteration matrix h (A x J) has complex eigenvalues (an
oscillation): the corrections' largest component shrinks unevenly, 100x in one sweep and 1.2x in
the next (Kepler e = 0.5 at pericentre), and a sweep-to-sweep test would fall back at every
pericentre."""
RETRY = 100
"""After a step fell back to Newton, the next RETRY steps use Newton directly, then fixed-point
iteration is tried again (a stiff stretch costs one failed attempt per RETRY steps)."""
# The tail of `memory` (gauss_run) after the predictor and the Newton matrix: the compensation of
# the summed state (n floats), then what the loop reports (DIAGNOSTICS floats, indices below).
ITERATIONS_MAX, CORRECTION_MAX, DEVIATION_MAX, DEVIATION_T, DEVIATION_STEPS, DEVIATION_SUM, NEWTON_UNTIL, FALLBACKS = range(8)
"""The most Newton sweeps of a step; the largest last correction of a step's stages (relative: the
round-off level reached); the largest predictor deviation (the converged stage increments minus their extrapolation
from the previous step, relative: an error indicator of order s + 1 in h), the time of the step where
it occurred, and the number of steps and the sum of the deviations (their mean). The deviation of a
component is measured against the largest size of its block (the coordinates, or the momenta).
Then the loop's own state: the step up to which Newton iteration is used directly (RETRY), and the
number of steps whose fixed-point iteration fell back to Newton."""
DIAGNOSTICS = 8


NODES = 4
"""Events between two steps are found on the Hermite interpolant (values and derivatives)
of the state at the step's two ends and at the starts of the NODES - 2 steps before it: degree
2 NODES - 1 = 7, an error of order h^8 (at most 2.2e-5 h^8 |z^(8)| on the last interval), below the
method's own error at the steps it is used at. The cubic Hermite interpolant of the step's ends
alone (order h^4, 2.6e-3 h^4 |z^(4)|) was the larger error at samples between steps: on Kepler
e = 0.5 at h = 0.2 (3 stages) it put an energy error of 1.2e-5 at samples mid-step, where the
method's own is 1e-8 at the steps. The first NODES - 2 steps of a run have fewer nodes (degree 3,
then 5). Samples come from `_gauss_sample` (a Gauss step to the sample: this interpolant still put
an energy error 200x the method's at s = 3, h = 0.2 midway), and from this interpolant only where
its fixed-point iteration does not converge (a stiff problem)."""


def memory_size(stages: int, n: int) -> int:
    """The length of gauss_run's `memory` for s stages and n = 2 x coordinates."""
    unknowns = stages * n
    return unknowns + unknowns * unknowns + n + DIAGNOSTICS + _HISTORY * (2 * n + 2)


def diagnostics_start(stages: int, n: int) -> int:
    """Where the loop's DIAGNOSTICS floats start in gauss_run's `memory`."""
    unknowns = stages * n
    return unknowns + unknowns * unknowns + n


_HISTORY = NODES - 1
"""Steps' starting states gauss_run keeps for its interpolant (a ring: step k in slot k % _HISTORY)."""


_RK45_A = np.array(RK45_A)
_RK45_B = np.array(RK45_B)
_RK45_C = np.array(RK45_C)
_RK45_E = np.array(RK45_E)
_RK45_P = np.array(RK45_P)
_DOP_A = np.array(DOP853_A)
_DOP_B = np.array(DOP853_B)
_DOP_C = np.array(DOP853_C)
_DOP_D = np.array(DOP853_D)
_DOP_E3 = np.array(DOP853_E3)
_DOP_E5 = np.array(DOP853_E5)
_DOP = DOP853.code
"""The pair number of DOP853 (`pair == _DOP`: its error estimate and dense output differ in form from RK45's)."""
_STAGES = np.array([RK45.stages, DOP853.stages])
_ROWS = np.array([RK45.rows, DOP853.rows])
_DENSE = np.array([RK45.dense, DOP853.dense])
_DENSE_EVALUATIONS = np.array([RK45.dense_evaluations, DOP853.dense_evaluations])
_ERROR_ORDER = np.array([RK45.error_order, DOP853.error_order])
assert RK45.code == 0 and DOP853.code == 1  # the arrays above are indexed by the pair's code
_GAUSS_C, _GAUSS_A, _GAUSS_B, _GAUSS_E = np.zeros((3, 3)), np.zeros((3, 3, 3)), np.zeros((3, 3)), np.zeros((3, 3, 3))


def _predictor(c: np.ndarray, b: np.ndarray) -> np.ndarray:
    """E with Z_i(next step) ~ z_next + h sum_j E_ij F_j: the collocation polynomial of a step,
    u(t + theta h) = z + h sum_j L_j(theta) F_j (L_j the integrated Lagrange basis on the nodes c),
    extrapolated to the next step's nodes theta = 1 + c_i."""
    e = np.zeros((len(c), len(c)))
    for j in range(len(c)):
        others = np.delete(c, j)
        basis = np.atleast_1d(np.poly(others)) / np.prod(c[j] - others)
        integral = np.polyint(basis)
        e[:, j] = np.polyval(integral, 1 + c) - np.polyval(integral, 0.0) - b[j]
    return e


_GAUSS_L = np.zeros((3, 3, 4))
"""_GAUSS_L[s - 1, j]: the coefficients (highest power first) of the integral from 0 of the Lagrange
basis polynomial j on the nodes c: the collocation polynomial of a step is u(t + theta h) =
z + h sum_j L_j(theta) F_j."""


def _integrated_basis(c: np.ndarray) -> np.ndarray:
    out = np.zeros((len(c), 4))
    for j in range(len(c)):
        others = np.delete(c, j)
        integral = np.polyint(np.atleast_1d(np.poly(others)) / np.prod(c[j] - others))
        out[j, 4 - len(integral) :] = integral
    return out


for _s, (_c, _a, _b) in GAUSS.items():
    _GAUSS_C[_s - 1, :_s], _GAUSS_A[_s - 1, :_s, :_s], _GAUSS_B[_s - 1, :_s] = _c, _a, _b
    _GAUSS_E[_s - 1, :_s, :_s] = _predictor(np.array(_c), np.array(_b))
    _GAUSS_L[_s - 1, :_s] = _integrated_basis(np.array(_c))

_F8, _I8, _ARR, _MAT = types.float64, types.int64, types.float64[::1], types.float64[:, ::1]
ACCEL_SIG = _I8(_F8, _ARR, _ARR, _ARR, _MAT)
"""accel(t, y, p, x, a): x = [q_ddot; lambda], a the (size x size) workspace; 1 when singular."""
HAMILTON_SIG = _I8(_F8, _ARR, _ARR, _ARR, _ARR, _MAT)
"""hamilton(t, z, p, out, x, a): out = (q_dot, p_dot) at z = (q, p); 1 when singular."""
EVENT_SIG = _F8(_F8, _ARR, _ARR, _ARR, _MAT)
"""event(t, y, p, x, a): the stop condition."""
ROWS_SIG = _I8(_F8, _ARR, _ARR, _ARR, _ARR, _ARR, _ARR)
"""rows(t, q, p, f, A, b, M): the kept constraints' rows at the positions q (codegen's `_rows`), A and M row by row."""
ENERGY_SIG = EVENT_SIG
"""energy(t, y, p, x, a): the energy function h."""
SWITCH_SIG = _I8(_F8, _ARR, _ARR, _ARR)
"""switch(t, y, p, out): the switching functions g(t, y) into out (codegen's `_switch`)."""
JAC_SIG = _I8(_F8, _ARR, _ARR, _MAT, _ARR, _MAT)
"""jac(t, y, p, r, x, a): the augmented matrix into a and dPhi/dy into r (codegen's numba `_jac`); 1 when singular."""
_JAC_T = types.FunctionType(JAC_SIG)
_ACCEL_T, _HAMILTON_T, _EVENT_T = types.FunctionType(ACCEL_SIG), types.FunctionType(HAMILTON_SIG), types.FunctionType(EVENT_SIG)
_ROWS_T, _ENERGY_T = types.FunctionType(ROWS_SIG), types.FunctionType(ENERGY_SIG)
_SWITCH_T = types.FunctionType(SWITCH_SIG)
SIGNATURES = {
    # (pair, t0, y, f, control, p, stats, accel)
    "erk_start": _F8(_I8, _F8, _ARR, _ARR, _ARR, _ARR, _ARR, _ACCEL_T),
    # (pair, y, f, state, control, ts, ys, p, stats, accel, event)
    "erk_run": _I8(_I8, _ARR, _ARR, _ARR, _ARR, _ARR, _MAT, _ARR, _ARR, _ACCEL_T, _EVENT_T),
    # (pair, y, f, state, control, ts, ys, p, stats, accel, event, switch, record)
    "erk_switched": _I8(_I8, _ARR, _ARR, _ARR, _ARR, _ARR, _MAT, _ARR, _ARR, _ACCEL_T, _EVENT_T, _SWITCH_T, _ARR),
    # (stages, z, state, control, ts, zs, p, stats, sizes, memory, pivots, hamilton, event)
    "gauss_run": _I8(_I8, _ARR, _ARR, _ARR, _ARR, _MAT, _ARR, _ARR, _ARR, _ARR, types.int64[::1], _HAMILTON_T, _EVENT_T),
    # (pair, y, f, state, control, ts, ys, p, stats, accel, event, rows, energy, bounds, holonomic, record)
    "erk_projected": _I8(_I8, _ARR, _ARR, _ARR, _ARR, _ARR, _MAT, _ARR, _ARR, _ACCEL_T, _EVENT_T, _ROWS_T, _ENERGY_T, _ARR, _ARR, _ARR),
    # (t, y, p, holonomic, record, out, size, rows, energy)
    "project_state": _I8(_F8, _ARR, _ARR, _ARR, _ARR, _ARR, _I8, _ROWS_T, _ENERGY_T),
    # (t0, y, f, control, p, stats, jac, memory, accel, jacobian)
    "radau_start": _F8(_F8, _ARR, _ARR, _ARR, _ARR, _ARR, _MAT, _ARR, _ACCEL_T, _JAC_T),
    # (y, f, state, control, ts, ys, p, stats, jac, dense, y_old, memory, accel, event, jacobian)
    "radau_run": _I8(_ARR, _ARR, _ARR, _ARR, _ARR, _MAT, _ARR, _ARR, _MAT, _MAT, _ARR, _ARR, _ACCEL_T, _EVENT_T, _JAC_T),
    # (y, f, state, control, ts, ys, p, stats, jac, dense, y_old, memory, accel, event, jacobian, switch, record)
    "radau_switched": _I8(_ARR, _ARR, _ARR, _ARR, _ARR, _MAT, _ARR, _ARR, _MAT, _MAT, _ARR, _ARR, _ACCEL_T, _EVENT_T, _JAC_T, _SWITCH_T, _ARR),
    # (y, f, state, control, ts, ys, p, stats, jac, dense, y_old, memory, accel, event, jacobian, rows, energy, bounds, holonomic, record)
    "radau_projected": _I8(_ARR, _ARR, _ARR, _ARR, _ARR, _MAT, _ARR, _ARR, _MAT, _MAT, _ARR, _ARR, _ACCEL_T, _EVENT_T, _JAC_T, _ROWS_T, _ENERGY_T, _ARR, _ARR, _ARR),
    # a stand-in for a system without `_jac` (control[ANALYTIC] = 0: never called)
    "no_jacobian": JAC_SIG,
}
"""The entry points. The arrays are records with named indices (status.py): `state` (T, H or the
steps done, EVENT_VALUE, NEXT_SAMPLE), `control` (RTOL, ATOL, MAX_STEP, T_BOUND, T_STOP, USE_EVENT,
SIZE, STEP, STEPS, T0, STIFFNESS, STRETCH) and `stats` (NFEV, NJEV, NSTEPS, NREJECT, HMIN, HMAX, STIFF, NONSTIFF, H_LAMBDA)."""
_COMPILED: dict[str, Any] = {}
_LOOP_ENTRIES = {
    # entry point: (the loop it calls, where the arguments it passes as None go, how many); erk_run stays a
    # compiled function of its own: ensemble.py's batch loop calls it from compiled code
    "erk_switched": ("_erk_loop", 13, 5),
    "erk_projected": ("_erk_loop", 11, 2),
    "radau_run": ("_radau_loop", 15, 7),
    "radau_switched": ("_radau_loop", 17, 5),
    "radau_projected": ("_radau_loop", 15, 2),
}
"""Entry points compiled as the loop they call, with None for the features they leave out (`_loop_entry`)."""


def compiled(name: str) -> Any:
    """The entry point `name` compiled for its signature (loaded from numba's cache when there)."""
    if name not in _COMPILED:
        _COMPILED[name] = _loop_entry(name) if name in _LOOP_ENTRIES else njit(SIGNATURES[name], cache=True, error_model="numpy", nogil=True)(globals()[name])
    return _COMPILED[name]


def _loop_entry(name: str) -> Any:
    """The entry point `name` (`_LOOP_ENTRIES`) as its loop compiled directly, its signature with None's type where
    the entry point passes None (numba prunes those features' branches as it does in a call), called from Python with
    the entry point's own arguments. numba links a called function's code into the caller's and optimizes and emits
    the whole again, so a one-line entry point around Radau's loop cost a second pass over all of it: 3.1 s of the
    19.5 s that the first compile of radau_start and radau_projected takes (16.4 s compiled this way, one machine);
    erk_projected 7.0-7.3 s, 6.1-6.7 s this way.
    The loop is compiled as a copy named after the entry point, so that each has numba cache files of its own, found
    by their name as those of the other entry points are."""
    loop, at, absent = _LOOP_ENTRIES[name]
    source = globals()[loop].py_func
    own = FunctionType(source.__code__, source.__globals__, name, source.__defaults__, source.__closure__)
    own.__qualname__ = own.__name__ = name  # numba's cache files named after the entry point (`compile.kernel_cached`)
    signature = SIGNATURES[name]
    arguments = list(signature.args)
    arguments[at:at] = [types.none] * absent
    loop_compiled = njit(signature.return_type(*arguments), cache=True, error_model="numpy", nogil=True)(own)
    nones = (None,) * absent

    def entry(*given: Any) -> int:
        return int(loop_compiled(*given[:at], *nones, *given[at:]))

    return entry


# -- linear algebra --------------------------------------------------------------------------


@njit(cache=True, error_model="numpy", inline="always")
def lu_solve(a, b):
    """Solve a x = b in place (b becomes x) by Gaussian elimination with partial pivoting, each
    row first divided by its largest entry; 1 when a pivot is below 1e-13 of its row's largest
    entry (a singular matrix), else 0. Measuring each row against itself keeps rows in
    different units (diag(m, m r^2) with r = 7e6 m) from being mistaken for a singular matrix."""
    n = b.shape[0]
    for i in range(n):
        largest = 0.0
        for j in range(n):
            largest = max(largest, abs(a[i, j]))
        if not largest > 0.0:
            return 1
        inverse = 1.0 / largest
        for j in range(n):
            a[i, j] *= inverse
        b[i] *= inverse
    for k in range(n):
        pivot = k
        for i in range(k + 1, n):
            if abs(a[i, k]) > abs(a[pivot, k]):
                pivot = i
        if not abs(a[pivot, k]) > 1e-13:
            return 1
        if pivot != k:
            for j in range(n):
                a[k, j], a[pivot, j] = a[pivot, j], a[k, j]
            b[k], b[pivot] = b[pivot], b[k]
        inverse = 1.0 / a[k, k]
        for i in range(k + 1, n):
            factor = a[i, k] * inverse
            if factor != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= factor * a[k, j]
                b[i] -= factor * b[k]
    for i in range(n - 1, -1, -1):
        total = b[i]
        for j in range(i + 1, n):
            total -= a[i, j] * b[j]
        b[i] = total / a[i, i]
    return 0


# -- the system as y' = f(t, y) ----------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def _rhs(accel, t, y, p, out, x, a):
    """out = (q_dot, q_ddot) at y = (q, q_dot); 1 when the matrix is singular (at a finite y: `_not_finite`)."""
    n = y.shape[0] // 2
    status = accel(t, y, p, x, a)
    if status != 0 and not _finite(y):
        status = _not_finite(x, n)
    for i in range(n):
        out[i] = y[n + i]
        out[n + i] = x[i]
    return status


@njit(cache=True, error_model="numpy")
def _not_finite(x, n):
    """At a state that is not finite (a trial stage of a step too large), the accelerations x[:n] are NaN, and 0 is
    returned: not "singular" (1), which stops a run. accel's LU finds no pivot in a row of M holding NaN or inf, and
    audit 12's s14 (a polar r = 956, cond M 9e5, beside a force K exp(2e4 (t - 1)) z) stopped there on "the mass
    matrix is singular" through compiled DOP853, where scipy's DOP853, given NaN, shrank the step and went on.
    Now the step is rejected and shrunk as for any derivative that is not finite."""
    for i in range(n):
        x[i] = np.nan
    return 0


@njit(cache=True, error_model="numpy")
def _rms(v, scale):
    total = 0.0
    for i in range(v.shape[0]):
        total += (v[i] / scale[i]) ** 2
    return (total / v.shape[0]) ** 0.5


@njit(cache=True, error_model="numpy")
def _finite(v):
    for i in range(v.shape[0]):
        if not np.isfinite(v[i]):
            return False
    return True


@njit(cache=True, error_model="numpy")
def _initial_step(accel, t0, y0, f0, t_bound, max_step, order, rtol, atol, p, x, a, stats):
    """scipy's `select_initial_step`: h0 from the norms of y0 and f0, refined by one Euler step."""
    n = y0.shape[0]
    interval = abs(t_bound - t0)
    if interval == 0.0:
        return 0.0
    scale = np.empty(n)
    for i in range(n):
        scale[i] = atol + abs(y0[i]) * rtol
    d0 = _rms(y0, scale)
    d1 = _rms(f0, scale)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, interval)
    y1, f1 = np.empty(n), np.empty(n)
    for i in range(n):
        y1[i] = y0[i] + h0 * f0[i]
    _rhs(accel, t0 + h0, y1, p, f1, x, a)
    stats[NFEV] += 1
    for i in range(n):
        f1[i] -= f0[i]
    d2 = _rms(f1, scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1))
    return min(100 * h0, h1, interval, max_step)


# -- explicit Runge-Kutta ---------------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def _erk_step(accel, pair, t, y, h, K, y_new, p, x, a, stats):
    """One step of the pair from (t, y) with K[0] = f(t, y); fills K and y_new, K[stages] = f(t + h, y_new).

    The right-hand side is evaluated here, `accel` called directly on this function's own arrays
    and its result copied into the rows of K, not through `_rhs(.., K[s], ..)`: every compiled
    function increments and decrements the reference counts of its array arguments (atomic
    operations), and a view K[s] is one more; with an indirect call (accel) in between, numba
    cannot prune them. Per evaluation that was 10 atomic operations, about half the time of a
    short run (issue 18: a double-pendulum sweep ran 1.5x faster without them, same steps and
    results)."""
    A, B, C = (_DOP_A, _DOP_B, _DOP_C) if pair == _DOP else (_RK45_A, _RK45_B, _RK45_C)
    stages = _STAGES[pair]
    n = y.shape[0]
    half = n // 2
    status = 0
    for s in range(1, stages):
        for i in range(n):
            dy = 0.0
            for j in range(s):
                dy += A[s, j] * K[j, i]
            y_new[i] = y[i] + h * dy
        code = accel(t + C[s] * h, y_new, p, x, a)
        if code != 0 and not _finite(y_new):  # a stage that is not finite: the step is rejected, not the run stopped (`_not_finite`)
            code = _not_finite(x, half)
        status += code
        for i in range(half):
            K[s, i] = y_new[half + i]
            K[s, half + i] = x[i]
    for i in range(n):
        dy = 0.0
        for j in range(stages):
            dy += B[j] * K[j, i]
        y_new[i] = y[i] + h * dy
    code = accel(t + h, y_new, p, x, a)
    if code != 0 and not _finite(y_new):
        code = _not_finite(x, half)
    status += code
    for i in range(half):
        K[stages, i] = y_new[half + i]
        K[stages, half + i] = x[i]
    stats[NFEV] += stages
    return status


@njit(cache=True, error_model="numpy")
def _erk_error(pair, K, h, y, y_new, rtol, atol):
    """The scaled error norm of the step (scipy's RK45 and DOP853 estimates)."""
    n = y.shape[0]
    if pair != _DOP:
        total = 0.0
        for i in range(n):
            e = 0.0
            for j in range(_ROWS[pair]):
                e += _RK45_E[j] * K[j, i]
            total += (e * h / (atol + max(abs(y[i]), abs(y_new[i])) * rtol)) ** 2
        return (total / n) ** 0.5
    err5, err3 = 0.0, 0.0
    for i in range(n):
        e5, e3 = 0.0, 0.0
        for j in range(_STAGES[pair] + 1):
            e5 += _DOP_E5[j] * K[j, i]
            e3 += _DOP_E3[j] * K[j, i]
        scale = atol + max(abs(y[i]), abs(y_new[i])) * rtol
        err5 += (e5 / scale) ** 2
        err3 += (e3 / scale) ** 2
    if err5 == 0.0 and err3 == 0.0:
        return 0.0
    return abs(h) * err5 / (n * (err5 + 0.01 * err3)) ** 0.5


@njit(cache=True, error_model="numpy")
def _erk_dense(accel, pair, t, y, y_new, f_new, h, K, coef, p, x, a, stats):
    """The interpolant's coefficients of the step [t, t + h] (DOP853: 3 more evaluations; accel
    called directly, as in `_erk_step`)."""
    n = y.shape[0]
    half = n // 2
    if pair != _DOP:
        for c in range(_DENSE[pair]):
            for i in range(n):
                total = 0.0
                for j in range(_ROWS[pair]):
                    total += K[j, i] * _RK45_P[j, c]
                coef[c, i] = total
        return 0
    status = 0
    work = np.empty(n)
    for s in range(_STAGES[pair] + 1, _ROWS[pair]):
        for i in range(n):
            dy = 0.0
            for j in range(s):
                dy += _DOP_A[s, j] * K[j, i]
            work[i] = y[i] + h * dy
        status += accel(t + _DOP_C[s] * h, work, p, x, a)
        for i in range(half):
            K[s, i] = work[half + i]
            K[s, half + i] = x[i]
    stats[NFEV] += _DENSE_EVALUATIONS[pair]
    for i in range(n):
        delta = y_new[i] - y[i]
        coef[0, i] = delta
        coef[1, i] = h * K[0, i] - delta
        coef[2, i] = 2 * delta - h * (f_new[i] + K[0, i])
        for r in range(4):
            total = 0.0
            for j in range(_ROWS[pair]):
                total += _DOP_D[r, j] * K[j, i]
            coef[3 + r, i] = h * total
    return status


@njit(cache=True, error_model="numpy")
def _erk_eval(pair, t_old, h, y_old, coef, t, out):
    """The dense output at t in [t_old, t_old + h]."""
    xi = (t - t_old) / h
    n = y_old.shape[0]
    if pair != _DOP:
        for i in range(n):
            total, power = 0.0, 1.0
            for c in range(_DENSE[pair]):
                power *= xi
                total += coef[c, i] * power
            out[i] = y_old[i] + h * total
        return
    for i in range(n):
        value = 0.0
        for r in range(_DENSE[pair] - 1, -1, -1):
            value += coef[r, i]
            value *= xi if (_DENSE[pair] - 1 - r) % 2 == 0 else 1.0 - xi
        out[i] = value + y_old[i]


@njit(error_model="numpy", inline="always")
def _illinois_guess(lo, hi, g_lo, g_hi):
    """The Illinois method's next point in (lo, hi): the secant's zero, or the midpoint where that is not inside."""
    mid = (lo * g_hi - hi * g_lo) / (g_hi - g_lo) if g_hi != g_lo else 0.5 * (lo + hi)
    return mid if lo < mid < hi else 0.5 * (lo + hi)


@njit(error_model="numpy", inline="always")
def _illinois_update(lo, hi, g_lo, g_hi, side, mid, g_mid):
    """The bracket (lo, hi, g_lo, g_hi, side) after the value g_mid at mid: the end on mid's side moves there, and
    the other end's value is halved when the same side moved twice in a row (the Illinois method)."""
    if (g_mid < 0.0) == (g_lo < 0.0):
        return mid, hi, g_mid, (0.5 * g_hi if side == -1 else g_hi), -1
    return lo, mid, (0.5 * g_lo if side == 1 else g_lo), g_mid, 1


@njit(cache=True, error_model="numpy")
def _erk_root(event, pair, t_old, h, y_old, coef, p, x, a, work, g_old):
    """The time in (t_old, t_old + h] where the event changes sign: the Illinois method on the dense output."""
    lo, hi = t_old, t_old + h
    g_lo = g_old
    _erk_eval(pair, t_old, h, y_old, coef, hi, work)
    g_hi = event(hi, work, p, x, a)
    side = 0
    for _ in range(100):
        if hi - lo <= 4e-16 * max(abs(hi), 1.0):
            break
        mid = _illinois_guess(lo, hi, g_lo, g_hi)
        _erk_eval(pair, t_old, h, y_old, coef, mid, work)
        g_mid = event(mid, work, p, x, a)
        if g_mid == 0.0:
            return mid
        lo, hi, g_lo, g_hi, side = _illinois_update(lo, hi, g_lo, g_hi, side, mid, g_mid)
    return hi


@njit(cache=True, error_model="numpy")
def _stiffness_test(K, h, y, y_new, work, stats):
    """DOP853's stiffness test on an accepted step (dop853.f): h |lambda| ~ h |f(t + h, y_new) - f(t + h, Y_12)| / |y_new - Y_12|,
    Y_12 the last stage's argument (c = 1); counts the positive tests (h |lambda| > STIFF_H_LAMBDA: the step is
    limited by stability) in stats[STIFF], cleared by STIFF_RESET negative ones in a row; True at STIFF_STEPS."""
    n = y.shape[0]
    last = _STAGES[_DOP] - 1
    numerator, denominator = 0.0, 0.0
    for i in range(n):
        dy = 0.0
        for j in range(last):
            dy += _DOP_A[last, j] * K[j, i]
        work[i] = y[i] + h * dy
        numerator += (K[_STAGES[_DOP], i] - K[last, i]) ** 2
        denominator += (y_new[i] - work[i]) ** 2
    if denominator > 0.0:
        stats[H_LAMBDA] = abs(h) * (numerator / denominator) ** 0.5
    if stats[H_LAMBDA] > STIFF_H_LAMBDA:
        stats[NONSTIFF] = 0.0
        stats[STIFF] += 1.0
        return stats[STIFF] >= STIFF_STEPS
    stats[NONSTIFF] += 1.0
    if stats[NONSTIFF] >= STIFF_RESET:
        stats[STIFF] = 0.0
    return False


def erk_start(pair, t0, y, f, control, p, stats, accel):
    """f = f(t0, y) and scipy's initial step; -1 when the matrix is singular at t0."""
    size = int(control[SIZE])
    x, a = np.empty(size), np.empty((size, size))
    if _rhs(accel, t0, y, p, f, x, a):
        return -1.0
    stats[NFEV] += 1
    return _initial_step(accel, t0, y, f, control[T_BOUND], control[MAX_STEP], _ERROR_ORDER[pair], control[RTOL], control[ATOL], p, x, a, stats)


@njit(cache=True, error_model="numpy")
def _erk_attempt(accel, pair, t, y, f, h_abs, min_step, limit, hold_landed, K, y_new, p, x, a, stats, state, rtol, atol, exponent):
    """One accepted step of the pair from (t, y), f = rhs there, trying h_abs and shrinking it on rejection
    (scipy's control), a step reaching `limit` shortened to land on it: (RUNNING, t_new, h, h_abs, the
    growth factor for the next step, landed), or a failure code (NONFINITE, STEP_COLLAPSE, SINGULAR) with
    state[T], state[H] set. The factor is at most 1 after a rejection, and after landing with `hold_landed`."""
    n = y.shape[0]
    rejected, bad = False, False
    while True:
        if h_abs < min_step:
            state[T], state[H] = t, h_abs
            return (NONFINITE if bad else STEP_COLLAPSE), t, 0.0, h_abs, 1.0, False
        landed = t + h_abs >= limit
        t_new = limit if landed else t + h_abs
        h = t_new - t
        for i in range(n):
            K[0, i] = f[i]
        if _erk_step(accel, pair, t, y, h, K, y_new, p, x, a, stats):
            state[T], state[H] = t, h
            return SINGULAR, t, h, h_abs, 1.0, False
        error = _erk_error(pair, K, h, y, y_new, rtol, atol)
        bad = not (np.isfinite(error) and _finite(y_new))
        if error < 1.0 and not bad:
            factor = MAX_FACTOR if error == 0.0 else min(MAX_FACTOR, SAFETY * error**exponent)
            if rejected or (landed and hold_landed):
                factor = min(1.0, factor)
            return RUNNING, t_new, h, h_abs, factor, landed
        h_abs *= MIN_FACTOR if bad else max(MIN_FACTOR, SAFETY * error**exponent)
        rejected = True
        stats[NREJECT] += 1


@njit(cache=True, error_model="numpy")
def _erk_samples(accel, event, pair, t, h, t_new, y, y_new, K, coef, work, ts, ys, p, x, a, state, stats, use_event):
    """After an accepted step t -> t_new (y -> y_new, stages K): the samples it passes written into ys
    (dense output), and the event looked for; (status, the time the step ends): RUNNING and t_new, or
    EVENT and the located crossing (y_new then the state there), or SINGULAR (state[T], state[H] set)."""
    j = int(state[NEXT_SAMPLE])
    need = j < ts.shape[0] and ts[j] <= t_new
    t_end_here = t_new
    status = RUNNING
    if use_event:
        g_new = event(t_new, y_new, p, x, a)
        if (state[EVENT_VALUE] < 0.0) != (g_new < 0.0) and state[EVENT_VALUE] != 0.0:
            need = True
            status = EVENT
        else:
            state[EVENT_VALUE] = g_new
    if need:
        if _erk_dense(accel, pair, t, y, y_new, K[_STAGES[pair]], h, K, coef, p, x, a, stats):
            state[T], state[H] = t, h
            return SINGULAR, t_end_here
        if status == EVENT:
            t_end_here = _erk_root(event, pair, t, h, y, coef, p, x, a, work, state[EVENT_VALUE])
        while j < ts.shape[0] and ts[j] <= t_end_here:
            _erk_eval(pair, t, h, y, coef, ts[j], ys[j])
            j += 1
        state[NEXT_SAMPLE] = j
        if status == EVENT:
            _erk_eval(pair, t, h, y, coef, t_end_here, y_new)
    return status, t_end_here


# -- the explicit loop: plain, switched and projected runs (issue 15) ------------------------------

SWITCH_PENDING, SWITCH_INDEX, SWITCH_COUNT, SWITCH_HOPS, SWITCH_SINCE, SWITCH_QUICK, SWITCH_LAST, SWITCH_WINDOW, SWITCH_CHATTER = 0, 1, 2, 3, 4, 5, 6, 7, 8
"""The first entries of a switched loop's `switching` record (erk_switched, radau_switched): the located crossing
ahead (inf: none), the surface crossing there, the crossings landed on so far (hops included), the hops across a
jump among them (`_hop`), the steps accepted since the last crossing and the crossings in a row each at most
SWITCH_WINDOW steps after the one before, of the same surface (`_chattering`), the surface crossed last (-1: none),
that window and the crossings in a row that make a sliding mode (QUICK_STEPS and CHATTER for the explicit pairs,
RADAU_QUICK_STEPS and RADAU_CHATTER for Radau); then g at the last accepted point (m values) and g at the end of the
step that found the crossing (m values)."""
SWITCH_HEAD = 9

LINEAR = 3
"""The interpolant kind of `_hop`'s path, y(t) = y_old + (t - t_old) coef[0] (kinds 0 and 1: the explicit pairs'
dense output, `_erk_eval`; RADAU_KIND: the collocation polynomial, `_radau_eval`)."""
RADAU_KIND = 2
_LINEAR, _RADAU_KIND = np.int64(LINEAR), np.int64(RADAU_KIND)
AHEAD = np.bool_(True)
"""The kinds and `_found`'s flag as typed values (int64, bool), never literals: numba compiles a helper once for each
literal value it is called with (3 and 2 made `_interpolant`, `_switch_root` and `_erk_eval`, never called for a
literal kind, two more times each; True and False, `_found` twice: helper compile18)."""
HOP_REACH = 2.0 / MIN_FACTOR
"""A hop looks for the crossing within HOP_REACH x the collapse step (MIN_STEP_SPACINGS spacings of t): the last step
rejected was at most 1 / MIN_FACTOR times that."""


def switching_record(m, window=QUICK_STEPS, chatter=CHATTER):
    """A switched loop's record for m switching functions, nothing located yet (g filled by the caller); `window`:
    the accepted steps at most between two crossings of a sliding mode, `chatter` such crossings in a row
    (`_chattering`)."""
    record = np.zeros(SWITCH_HEAD + 2 * m)
    record[SWITCH_WINDOW], record[SWITCH_CHATTER] = window, chatter
    record[SWITCH_LAST] = -1.0
    record[SWITCH_PENDING] = np.inf
    record[SWITCH_INDEX] = -1.0
    return record


@njit(cache=True, error_model="numpy")
def _interpolant(kind, t_old, h, y_old, coef, t, out):
    """The state at t on a step's interpolant: the explicit pair's dense output (kind = its code), Radau's collocation
    polynomial (RADAU_KIND) or the straight line of a hop (LINEAR: coef[0] the slope)."""
    if kind == RADAU_KIND:
        _radau_eval(t_old, h, y_old, coef, t, out)
    elif kind == LINEAR:
        for i in range(y_old.shape[0]):
            out[i] = y_old[i] + (t - t_old) * coef[0, i]
    else:
        _erk_eval(kind, t_old, h, y_old, coef, t, out)


@njit(cache=True, error_model="numpy")
def _switch_root(switch, i, kind, t_old, h, y_old, coef, p, work, g, g_lo, g_hi):
    """The time in (t_old, t_old + h] where switching function i changes sign: the Illinois method on the step's
    interpolant (`_interpolant`, as `_erk_root` for the event), the bracket's far end returned (g_i there on the new
    side), or a point where g_i is exactly 0."""
    lo, hi = t_old, t_old + h
    side = 0
    for _ in range(100):
        if hi - lo <= 4e-16 * max(abs(hi), 1.0):
            break
        mid = _illinois_guess(lo, hi, g_lo, g_hi)
        _interpolant(kind, t_old, h, y_old, coef, mid, work)
        switch(mid, work, p, g)
        g_mid = g[i]
        if g_mid == 0.0:
            return mid
        lo, hi, g_lo, g_hi, side = _illinois_update(lo, hi, g_lo, g_hi, side, mid, g_mid)
    return hi


@njit(cache=True, error_model="numpy")
def _changed(switch, t, y, p, record, m, g_end, g_start):
    """Whether a switching function changed sign over an accepted step from (t, y) (g_end: g at its end, against g at
    the last accepted point in `record`); g_start = g(t, y) computed once one of them may have. A function whose g at
    the step's start itself is 0 or on g_end's side did not cross in the step: after a landing record holds the far
    side's value, and the path touched the surface there and turned back."""
    started = False
    for i in range(m):
        g_old = record[SWITCH_HEAD + i]
        if (g_old < 0.0) != (g_end[i] < 0.0) and g_old != 0.0:
            if not started:
                switch(t, y, p, g_start)
                started = True
            if not (g_start[i] == 0.0 or (g_start[i] < 0.0) == (g_end[i] < 0.0)):
                return True
    return False


@njit(cache=True, error_model="numpy")
def _earliest(switch, kind, t, h, y, coef, p, record, m, g_end, g_start, g_work, work):
    """After `_changed` found a crossing in the step [t, t + h] (its interpolant `kind`, `coef`): (the surface crossed
    first, the time of its crossing), each located by `_switch_root`."""
    first, t_first = -1, t + h
    for i in range(m):
        g_old = record[SWITCH_HEAD + i]
        if (g_old < 0.0) != (g_end[i] < 0.0) and g_old != 0.0:
            if g_start[i] == 0.0 or (g_start[i] < 0.0) == (g_end[i] < 0.0):
                continue
            t_i = _switch_root(switch, i, kind, t, h, y, coef, p, work, g_work, g_start[i], g_end[i])
            if first < 0 or t_i < t_first:
                first, t_first = i, t_i
    return first, t_first


@njit(cache=True, error_model="numpy")
def _found(record, m, first, t_first, g_end, ahead):
    """A crossing of surface `first` found on an accepted step: `ahead` (inside the step, at t_first: the step is to
    be taken again onto it) or at the step's end (landed there); g at the step's end kept for the landing."""
    if ahead:
        record[SWITCH_PENDING] = t_first
    record[SWITCH_INDEX] = float(first)
    for i in range(m):
        record[SWITCH_HEAD + m + i] = g_end[i]


@njit(cache=True, error_model="numpy")
def _chattering(record, crossed):
    """One more crossing (a landing or a hop) of surface `crossed`: counted, and whether it is the
    record[SWITCH_CHATTER]-th in a row of that surface each at most record[SWITCH_WINDOW] accepted steps after the one before (a sliding mode: the same surface
    crossed back and forth). Crossings of different surfaces close together are no sliding mode: audit 9 F2, a double
    pendulum with drag |v| v on three velocities, each 0 near each turn of the swing, at rtol 1e-5."""
    record[SWITCH_COUNT] += 1.0
    same = record[SWITCH_SINCE] <= record[SWITCH_WINDOW] and record[SWITCH_LAST] == crossed
    record[SWITCH_QUICK] = record[SWITCH_QUICK] + 1.0 if same else 1.0
    record[SWITCH_SINCE] = 0.0
    record[SWITCH_LAST] = crossed
    return record[SWITCH_QUICK] >= record[SWITCH_CHATTER]


@njit(cache=True, error_model="numpy")
def _landed(switch, t, y, p, record, m, g):
    """The record after a landing on the crossing at t: g on the crossing's far side for the surface crossed, at the
    landing point for the others (g: workspace), nothing pending, one more crossing; True when it is a sliding mode
    (`_chattering`)."""
    switch(t, y, p, g)
    crossed = int(record[SWITCH_INDEX])
    for i in range(m):
        record[SWITCH_HEAD + i] = record[SWITCH_HEAD + m + i] if i == crossed else g[i]
    record[SWITCH_PENDING], record[SWITCH_INDEX] = np.inf, -1.0
    return _chattering(record, crossed)


@njit(cache=True, error_model="numpy")
def _hop(switch, accel, t, y, f, reach, p, record, m, g_start, g_end, g_work, work, slope, y_far, f_far, x, a, stats):
    """Across a jump of the forces: the step size collapsed at (t, y) (f = f(t, y)), the steps rejected because their
    stages straddle a switching surface where the forces jump (a step across it has an error of h x the jump, above
    any tight tolerance). The accepted steps have brought t to within a few spacings of the crossing, on the near
    side: the crossing is located on the line y + (s - t) f within `reach` (`_switch_root`, LINEAR; the line's error
    over that span, of order reach^2 y'', is far below round-off) and the state moved along it to the first point
    past the crossing (g there strictly on the far side, so that the forces restarting there are the far side's). The
    state's error is then the crossing's time error (a spacing of t) x the jump, as for any method landing on a
    floating-point time. A state exactly on the surface (g = 0: neither side's forces) is moved to the side the line
    goes to. (RUNNING, t_far): y_far, f_far = f(t_far, y_far) and g_end = g there filled, the record updated (a
    crossing, a hop); (STEP_COLLAPSE, t): no crossing within reach (a collapse for another reason), or a sliding mode
    (`_chattering`); (SINGULAR, t): the matrix singular at the far point."""
    n = y.shape[0]
    for i in range(n):
        slope[0, i] = f[i]
    t_reach = t + reach
    _interpolant(_LINEAR, t, reach, y, slope, t_reach, work)
    switch(t_reach, work, p, g_end)
    switch(t, y, p, g_start)
    first, t_far, far_negative = -1, t_reach, False
    for i in range(m):
        if g_end[i] != 0.0 and (g_start[i] == 0.0 or (g_start[i] < 0.0) != (g_end[i] < 0.0)):
            t_i = t if g_start[i] == 0.0 else _switch_root(switch, i, _LINEAR, t, reach, y, slope, p, work, g_work, g_start[i], g_end[i])
            if first < 0 or t_i < t_far:
                first, t_far, far_negative = i, t_i, g_end[i] < 0.0
    if first < 0:
        return STEP_COLLAPSE, t
    for _ in range(8):  # strictly past the surface: on it (g exactly 0) the forces are neither side's
        _interpolant(_LINEAR, t, reach, y, slope, t_far, y_far)
        switch(t_far, y_far, p, g_end)
        if g_end[first] != 0.0:
            break
        t_far = np.nextafter(t_far, np.inf)
    if g_end[first] == 0.0 or (g_end[first] < 0.0) != far_negative:
        return STEP_COLLAPSE, t
    if _rhs(accel, t_far, y_far, p, f_far, x, a):
        return SINGULAR, t
    stats[NFEV] += 1
    # a landing just before that stopped short of the surface (its step's end a spacing on the near side) counted this
    # crossing already: its record holds the far side's g
    counted = record[SWITCH_HEAD + first] != 0.0 and (record[SWITCH_HEAD + first] < 0.0) == far_negative
    for i in range(m):
        record[SWITCH_HEAD + i] = g_end[i]
    record[SWITCH_PENDING], record[SWITCH_INDEX] = np.inf, -1.0
    record[SWITCH_HOPS] += 1.0
    if not counted and _chattering(record, first):
        return STEP_COLLAPSE, t
    return RUNNING, t_far


@njit(cache=True, error_model="numpy")
def _hopped(event, t, t_far, y, f, y_far, f_far, slope, ts, ys, p, x, a, state, stats, use_event):
    """After a hop t -> t_far (`_hop`): the samples it passes written (on its line), (y, f) = (y_far, f_far), one
    step counted; EVENT where the stop condition changed sign across the hop (the run stops at t_far, the hop's
    few spacings of t the event's time error), else RUNNING."""
    j = int(state[NEXT_SAMPLE])
    while j < ts.shape[0] and ts[j] <= t_far:
        for i in range(y.shape[0]):
            ys[j, i] = y[i] + (ts[j] - t) * slope[0, i]
        j += 1
    state[NEXT_SAMPLE] = j
    for i in range(y.shape[0]):
        y[i] = y_far[i]
        f[i] = f_far[i]
    stats[NSTEPS] += 1
    if use_event:
        g = event(t_far, y, p, x, a)
        if (state[EVENT_VALUE] < 0.0) != (g < 0.0) and state[EVENT_VALUE] != 0.0:
            state[T] = t_far
            return EVENT
        state[EVENT_VALUE] = g
    return RUNNING


def erk_run(pair, y, f, state, control, ts, ys, p, stats, accel, event):
    """Advance (t = state[T], y, f = f(t, y), |h| = state[H], the stop condition's value state[EVENT_VALUE])
    with the pair numbered `pair` until t >= control[T_STOP], writing ys[j] = y(ts[j]) for the samples
    passed (state[NEXT_SAMPLE] = the next one); returns a status code. `_erk_loop` with no switching
    functions and no projection."""
    return _erk_loop(pair, y, f, state, control, ts, ys, p, stats, accel, event, None, None, None, None, None, None, None)


def erk_switched(pair, y, f, state, control, ts, ys, p, stats, accel, event, switch, record):
    """`erk_run` landing a step on each zero crossing of the switching functions `switch` (codegen's
    `_switch`): after an accepted step, g at its end is compared with g at its start (record); where one
    changed sign, the crossing is located on the step's dense output (`_switch_root`, the earliest of
    them), the step is discarded and taken again (shortened by the usual control as needed) to land on
    it; there the integrator restarts: f evaluated afresh (no FSAL reuse across the kink) and scipy's
    initial step chosen again. A step that lands on a crossing counts as one step; the discarded one as
    rejected. Where the forces jump across the surface and the steps collapse onto it (a tight rtol), the
    loop hops across (`_hop`, one step); CHATTER quick crossings in a row (a sliding mode) stop it
    (STEP_COLLAPSE). `record` (switching_record) carries what is located across pauses."""
    return _erk_loop(pair, y, f, state, control, ts, ys, p, stats, accel, event, switch, record, None, None, None, None, None)


@njit(error_model="numpy", inline="always")
def _erk_loop(pair, y, f, state, control, ts, ys, p, stats, accel, event, switch, switching, rows, energy, bounds, holonomic, record):
    """The explicit loop of erk_run, erk_switched and erk_projected. Each pass: one accepted step
    (`_erk_attempt`) ending at most at the limit (the end, the crossing located ahead, the next projection
    time); with switching functions (m > 0 in `switching`) a crossing inside it discards it, to be taken
    again onto the crossing; then the counters, the stiffness test, the samples and the event
    (`_erk_samples`); then a landing on a crossing restarts the integrator, and a landing on a projection
    time projects the state. `switch` (and its record `switching`) or `rows` (and `energy`, `bounds`,
    `holonomic`, the projection record `record`) None: that case is left out when numba compiles the loop
    (its branches `if switch is not None`, `if rows is not None` pruned), so erk_run compiles no more than
    its own steps and takes them exactly as before; inlined into each entry point (one function to compile,
    as each of the three loops was: 0.3 s less first-time compile than a loop called from the entry). Pauses
    (RUNNING) at control[T_STOP], after control[STRETCH] (or PAUSE_STEPS) steps, and with control[STIFFNESS]
    once the stiffness test has found the problem stiff."""
    n = y.shape[0]
    m = 0
    if switch is not None:
        m = (switching.shape[0] - SWITCH_HEAD) // 2
    rtol, atol, max_step, t_bound, t_stop, use_event = control[RTOL], control[ATOL], control[MAX_STEP], control[T_BOUND], control[T_STOP], control[USE_EVENT] != 0.0
    test_stiffness = control[STIFFNESS] != 0.0 and pair == _DOP
    pause = int(control[STRETCH]) if control[STRETCH] > 0.0 else PAUSE_STEPS
    size = int(control[SIZE])
    x, a = np.empty(size), np.empty((size, size))
    stages = _STAGES[pair]
    K = np.empty((_ROWS[pair], n))
    coef = np.empty((_DENSE[pair], n))
    y_new, work = np.empty(n), np.empty(n)
    if switch is not None:
        g_new, g_work, g_start, slope = np.empty(m), np.empty(m), np.empty(m), np.empty((1, n))
    if rows is not None:
        projected, found = np.empty(n), np.zeros(4)
    exponent = -1.0 / (_ERROR_ORDER[pair] + 1.0)
    t, h_abs = state[T], state[H]
    taken = 0
    while t < t_stop and t < t_bound and taken < pause:
        taken += 1
        min_step = MIN_STEP_SPACINGS * abs(np.nextafter(t, np.inf) - t)
        h_abs = min(max(h_abs, min_step), max_step)
        limit, pending, bound, hold_landed = t_bound, np.inf, np.inf, False
        if switch is not None:
            pending = switching[SWITCH_PENDING]
            limit = min(t_bound, pending)
        if rows is not None:
            # a step shortened onto a projection time says little about the next: keep the size before it
            bound, hold_landed = bounds[int(record[NEXT_BOUND])], True
            limit = min(limit, bound)
        code, t_new, h, h_abs, factor, landed = _erk_attempt(accel, pair, t, y, f, h_abs, min_step, limit, hold_landed, K, y_new, p, x, a, stats, state, rtol, atol, exponent)
        if switch is not None and code == STEP_COLLAPSE:  # onto a surface where the forces jump: across it (`_hop`)
            code, t_far = _hop(switch, accel, t, y, f, HOP_REACH * min_step, p, switching, m, g_start, g_new, g_work, work, slope, y_new, K[0], x, a, stats)
            if code == RUNNING:
                code = _hopped(event, t, t_far, y, f, y_new, K[0], slope, ts, ys, p, x, a, state, stats, use_event)
                t = t_far
                if code == EVENT:
                    state[H] = min_step
                    return EVENT
                h_abs = _initial_step(accel, t, y, f, t_bound, max_step, _ERROR_ORDER[pair], rtol, atol, p, x, a, stats)
                state[T], state[H] = t, h_abs
                continue
        if code != RUNNING:
            return code
        arrived = False
        if switch is not None:  # the switching functions: a crossing inside the step discards it (retaken to land there)
            arrived = landed and t_new == pending
            if not arrived:
                switch(t_new, y_new, p, g_new)
                first, t_first = -1, t_new
                if _changed(switch, t, y, p, switching, m, g_new, g_start):
                    if _erk_dense(accel, pair, t, y, y_new, K[stages], h, K, coef, p, x, a, stats):  # the step's interpolant
                        state[T], state[H] = t, h
                        return SINGULAR
                    first, t_first = _earliest(switch, pair, t, h, y, coef, p, switching, m, g_new, g_start, g_work, work)
                if first >= 0 and t < t_first < t_new:  # discard the step: take it again to land on the crossing
                    _found(switching, m, first, t_first, g_new, AHEAD)
                    stats[NREJECT] += 1
                    h_abs = t_first - t
                    state[H] = h_abs  # a pause right here resumes with this step
                    continue
                if first >= 0:  # the crossing is at the step's end: it has landed there
                    arrived = True
                    _found(switching, m, first, t_first, g_new, not AHEAD)
        stats[NSTEPS] += 1
        if not landed:
            stats[HMIN] = min(stats[HMIN], h)
        stats[HMAX] = max(stats[HMAX], h)
        stiff = test_stiffness and _stiffness_test(K, h, y, y_new, work, stats)
        status, t_end_here = _erk_samples(accel, event, pair, t, h, t_new, y, y_new, K, coef, work, ts, ys, p, x, a, state, stats, use_event)
        if status == SINGULAR:
            return SINGULAR
        for i in range(n):
            f[i] = K[stages, i]
            y[i] = y_new[i]
        t = t_end_here
        h_abs *= factor
        if switch is not None:
            if arrived and status != EVENT:
                if _landed(switch, t, y, p, switching, m, g_new):
                    state[T], state[H] = t, h_abs
                    return STEP_COLLAPSE
                if _rhs(accel, t, y, p, f, x, a):  # restart: f afresh, scipy's initial step
                    state[T], state[H] = t, h_abs
                    return SINGULAR
                stats[NFEV] += 1
                h_abs = _initial_step(accel, t, y, f, t_bound, max_step, _ERROR_ORDER[pair], rtol, atol, p, x, a, stats)
            elif not arrived:
                switching[SWITCH_SINCE] += 1.0
                for i in range(m):
                    switching[SWITCH_HEAD + i] = g_new[i]
        state[T], state[H] = t, h_abs
        if status == EVENT:
            return EVENT
        if rows is not None:  # noqa: SIM102  (a branch on the argument alone: numba prunes it where rows is None)
            if landed and t_new == bound:  # a projection time: the state projected there, f afresh
                record[PROJECTIONS] += 1.0
                _projected(_project(rows, energy, t, y, p, holonomic, record, projected, found, x, a), t, y, record, projected, found, state, ts, ys)
                if t < t_bound:
                    if _rhs(accel, t, y, p, f, x, a):
                        return SINGULAR
                    stats[NFEV] += 1
                    if use_event:
                        state[EVENT_VALUE] = event(t, y, p, x, a)
        if stiff and t < t_bound:
            return RUNNING  # paused: the caller asked to hear of stiffness (stats[STIFF] >= STIFF_STEPS)
    return DONE if t >= t_bound else RUNNING


# -- explicit Runge-Kutta with projection onto kept constraints ----------------------------------


@njit(cache=True, error_model="numpy")
def _solve(a, b):
    """`lu_solve` called, not inlined: its three copies in the projection (inlined by numba, as the system's `_accel`
    needs it) made compiling project_state take 9.7 s of CPU and radau_projected 23.0 s; called, 6.2 and 18.7 s."""
    return lu_solve(a, b)


@njit(cache=True, error_model="numpy")
def _all_finite(v):
    for i in range(v.shape[0]):
        if not np.isfinite(v[i]):
            return False
    return True


@njit(cache=True, error_model="numpy")
def _rows_at(rows, t, q, p, f, A, b, M):
    """f, A, b, M of the kept constraints at (t, q) (the system's `_rows`); False where a value is not finite."""
    rows(t, q, p, f, A, b, M)
    return _all_finite(f) and _all_finite(A) and _all_finite(b) and _all_finite(M)


@njit(cache=True, error_model="numpy")
def _inverse_rows(m, rows, w):
    """w = M^-1 R^T (n x count) for the rows R (count x n), column by column; 1 when M is singular."""
    count, n = rows.shape
    work, column = np.empty((n, n)), np.empty(n)
    for i in range(count):
        for r in range(n):
            for c in range(n):
                work[r, c] = m[r, c]
            column[r] = rows[i, r]
        if _solve(work, column):
            return 1
        for r in range(n):
            w[r, i] = column[r]
    return 0


@njit(cache=True, error_model="numpy")
def _normal(rows, w):
    """R M^-1 R^T from R and w = M^-1 R^T."""
    count, n = rows.shape
    normal = np.empty((count, count))
    for i in range(count):
        for j in range(count):
            total = 0.0
            for c in range(n):
                total += rows[i, c] * w[c, j]
            normal[i, j] = total
    return normal


@njit(cache=True, error_model="numpy")
def _weighted(m, rows, r, out):
    """out = M^-1 R^T (R M^-1 R^T)^-1 r: the M-weighted least-norm solution of R dx = r (projection._weighted); 1 when singular."""
    count, n = rows.shape
    w = np.empty((n, count))
    if _inverse_rows(m, rows, w):
        return 1
    normal = _normal(rows, w)
    z = np.empty(count)
    for i in range(count):
        z[i] = r[i]
    if _solve(normal, z):
        return 1
    for c in range(n):
        total = 0.0
        for i in range(count):
            total += w[c, i] * z[i]
        out[c] = total
    return 0


@njit(cache=True, error_model="numpy")
def _project(rows, energy, t, y, p, holonomic, record, out, found, x, a):
    """`projection.Projector.project` compiled: out = y = [q; q_dot] projected onto the kept constraints at t
    (Gauss-Newton on the holonomic rows' positions, at most record[NEWTON_LIMIT] steps, stopping at
    round-off; then the velocities onto every row; then, with record[USE_LEVEL], the velocities onto the
    energy level record[LEVEL] with the rows, skipped at a turning point or for a correction that is not
    small), found = (position, velocity, moved, energy) as `projection.Correction`; 1 where it cannot be
    applied (M or A M^-1 A^T singular, values not finite: out is then not to be used), else 0."""
    n = y.shape[0] // 2
    k = holonomic.shape[0]
    round_off = record[ROUND_OFF_LEVEL]
    q, qd, dx = np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):
        q[i], qd[i] = y[i], y[n + i]
    f, flat, b, flat_m = np.empty(k), np.empty(k * n), np.empty(k), np.empty(n * n)
    A, M = flat.reshape((k, n)), flat_m.reshape((n, n))
    held = 0
    for r in range(k):
        if holonomic[r] != 0.0:
            held += 1
    first_position = 0.0
    if held > 0:
        fh, Ah = np.empty(held), np.empty((held, n))
        for step in range(int(record[NEWTON_LIMIT])):
            if not _rows_at(rows, t, q, p, f, flat, b, flat_m):
                return 1
            c, largest_f, largest_a, largest_q = 0, 0.0, 0.0, 0.0
            for r in range(k):
                if holonomic[r] != 0.0:
                    fh[c] = f[r]
                    largest_f = max(largest_f, abs(f[r]))
                    for j in range(n):
                        Ah[c, j] = A[r, j]
                        largest_a = max(largest_a, abs(A[r, j]))
                    c += 1
            for j in range(n):
                largest_q = max(largest_q, abs(q[j]))
            if step == 0:
                first_position = largest_f
            if largest_f <= round_off * (1.0 + largest_a * largest_q):
                break
            if _weighted(M, Ah, fh, dx):
                return 1
            for j in range(n):
                q[j] -= dx[j]
    if not _rows_at(rows, t, q, p, f, flat, b, flat_m):
        return 1
    residual = np.empty(k)
    largest_residual = 0.0
    for r in range(k):
        total = b[r]
        for j in range(n):
            total += A[r, j] * qd[j]
        residual[r] = total
        largest_residual = max(largest_residual, abs(total))
    if _weighted(M, A, residual, dx):
        return 1
    for j in range(n):
        qd[j] -= dx[j]
    energy_error = 0.0
    if record[USE_LEVEL] != 0.0:
        level = record[LEVEL]
        trial, state, gradient = qd.copy(), np.empty(2 * n), np.empty(n)
        stacked, w, rhs = np.empty((k + 1, n)), np.empty((n, k + 1)), np.empty(k + 1)
        first, skipped = -1.0, False
        for _ in range(int(record[ENERGY_LIMIT])):
            for j in range(n):
                state[j], state[n + j] = q[j], trial[j]
            error = energy(t, state, p, x, a) - level
            if first < 0.0:
                first = abs(error)
            moment = 0.0
            for i in range(n):
                total = 0.0
                for j in range(n):
                    total += M[i, j] * trial[j]
                gradient[i] = total  # dh/dq_dot = M q_dot
                moment += trial[i] * total
            if abs(error) <= round_off * (abs(level) + abs(moment)):
                break
            for r in range(k):
                for j in range(n):
                    stacked[r, j] = A[r, j]
            for j in range(n):
                stacked[k, j] = gradient[j]
            if _inverse_rows(M, stacked, w):
                return 1
            normal = _normal(stacked, w)
            if not _all_finite(normal.ravel()) or np.linalg.cond(normal) > record[CONDITION_LIMIT]:  # a turning point
                skipped = True
                break
            for r in range(k):
                total = b[r]
                for j in range(n):
                    total += A[r, j] * trial[j]
                rhs[r] = total
            rhs[k] = error
            if _solve(normal, rhs):
                skipped = True
                break
            for j in range(n):
                total = 0.0
                for i in range(k + 1):
                    total += w[j, i] * rhs[i]
                trial[j] -= total
        if not skipped:
            change, largest = 0.0, 0.0
            for j in range(n):
                largest = max(largest, abs(qd[j]))
            scale = largest + 1e-300
            for j in range(n):
                change = max(change, abs(trial[j] - qd[j]))
            if _all_finite(trial) and change <= record[CHANGE_LIMIT] * scale:
                for j in range(n):
                    qd[j] = trial[j]
                energy_error = first if first >= 0.0 else 0.0
    moved = 0.0
    for j in range(n):
        out[j], out[n + j] = q[j], qd[j]
    if not _all_finite(out):
        return 1
    for i in range(2 * n):
        moved = max(moved, abs(out[i] - y[i]))
    found[0], found[1], found[2], found[3] = first_position, largest_residual, moved, energy_error
    return 0


@njit(error_model="numpy", inline="always")
def _projected(failed, t, y, record, projected, found, state, ts, ys):
    """After `_project` at a projection time t (erk_projected's and radau_projected's loops): a failure counted
    (FAILURES, FAILED_AT) and the state kept; else the state replaced by the projected one, the corrections'
    maxima recorded, and a sample written at t rewritten with it. Then on to the next projection time."""
    if failed:
        record[FAILURES] += 1.0
        if not np.isfinite(record[FAILED_AT]):
            record[FAILED_AT] = t
    else:
        n = y.shape[0]
        for i in range(n):
            y[i] = projected[i]
        record[POSITION] = max(record[POSITION], found[0])
        record[VELOCITY] = max(record[VELOCITY], found[1])
        record[MOVED] = max(record[MOVED], found[2])
        record[ENERGY] = max(record[ENERGY], found[3])
        j = int(state[NEXT_SAMPLE])
        if j > 0 and ts[j - 1] == t:
            for i in range(n):
                ys[j - 1, i] = y[i]
    record[NEXT_BOUND] += 1.0


def project_state(t, y, p, holonomic, record, out, size, rows, energy):
    """One state projected as erk_projected projects (`_project`): out, and record[POSITION..ENERGY]
    what it corrected; 1 where the projection cannot be applied."""
    x, a, found = np.empty(size), np.empty((size, size)), np.zeros(4)
    if _project(rows, energy, t, y, p, holonomic, record, out, found, x, a):
        return 1
    record[POSITION], record[VELOCITY], record[MOVED], record[ENERGY] = found[0], found[1], found[2], found[3]
    return 0


def erk_projected(pair, y, f, state, control, ts, ys, p, stats, accel, event, rows, energy, bounds, holonomic, record):
    """`erk_run` with the state projected onto the kept constraints at the times `bounds` (increasing,
    the last one t_end): a step is shortened to land exactly on the next of them, the state there is
    projected (`_project`; where that cannot be applied it is kept as it was, and counted), a sample at
    that time takes the projected state, f is evaluated anew (the last stage no longer holds) and the run
    goes on with the step size it had before it was shortened. The largest corrections and the counts go
    into `record` (status.POSITION, ...); record[NEXT_BOUND] is the next projection time's index. Pauses as
    erk_run does; returns a status code. `_erk_loop` with no switching functions."""
    return _erk_loop(pair, y, f, state, control, ts, ys, p, stats, accel, event, None, None, rows, energy, bounds, holonomic, record)


# -- Gauss-Legendre in (q, p) -----------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def _jacobian(hamilton, t, z, p, x, a, jac, f0, work, column, sizes, stats):
    """J = dF/dz at z by forward differences (f0 = F(z) is computed too), each component moved
    by 1.5e-8 of its size (`sizes`: the largest |z_k| so far); 1 when M is singular."""
    n = z.shape[0]
    status = hamilton(t, z, p, f0, x, a)
    for k in range(n):
        for i in range(n):
            work[i] = z[i]
        scale = max(abs(z[k]), sizes[k])
        step = 1.5e-8 * (scale if scale > 0.0 else 1.0)
        work[k] += step
        status += hamilton(t, work, p, column, x, a)
        for i in range(n):
            jac[i, k] = (column[i] - f0[i]) / step
    stats[NFEV] += n + 1
    stats[NJEV] += 1
    return status


@njit(cache=True, error_model="numpy")
def _newton_matrix(s, h, jac, m, pivots):
    """LU factors of I - h (A x J), the simplified Newton matrix of the stage equations; 1 when singular."""
    n = jac.shape[0]
    for i in range(s):
        for j in range(s):
            for r in range(n):
                for c in range(n):
                    m[i * n + r, j * n + c] = (1.0 if i == j and r == c else 0.0) - h * _GAUSS_A[s - 1, i, j] * jac[r, c]
    size = s * n
    for k in range(size):
        pivot = k
        for i in range(k + 1, size):
            if abs(m[i, k]) > abs(m[pivot, k]):
                pivot = i
        pivots[k] = pivot
        if m[pivot, k] == 0.0:
            return 1
        for j in range(size):
            m[k, j], m[pivot, j] = m[pivot, j], m[k, j]
        for i in range(k + 1, size):
            m[i, k] /= m[k, k]
            for j in range(k + 1, size):
                m[i, j] -= m[i, k] * m[k, j]
    return 0


STAGES_DOC = """What gauss_run's stage loop does. Solve W_i = h sum_j a_ij F(z + W_j) for the stage increments W_i = Z_i - z by
    fixed-point iteration (FIXED_SLOW says when it falls back), else by simplified
    Newton iteration (matrix m from `_newton_matrix`, in gauss_run's loop), until the corrections reach round-off; FZ
    holds F at the stage values of the last iteration. It sets (status, iterations, the last
    correction, the slowest contraction of the corrections before the last: how stale the Newton
    matrix is). Working with increments (Hairer, Lubich and Wanner, VIII.6) keeps the stage
    values' round-off at the size of the increments, not of z.
    Corrections are measured component by component against that component's size (`sizes`, the
    largest |z_k| so far), so that coordinates and momenta of very different magnitudes all
    converge, and the iteration stops when a correction is below an ulp of every component, or
    when the corrections stop decreasing at the round-off level (STAGNATION); corrections that stop
    decreasing above it, or MAX_ITERATIONS sweeps, are NO_CONVERGENCE (the caller refreshes
    the Jacobian once, then fails with that status)."""


@njit(cache=True, error_model="numpy")
def _hermite(tn, Zn, Fn, m, t, out, xs, q):
    """The Hermite interpolant of (Zn[r], Fn[r]) at the times tn[r], r < m (m >= 2), at t: divided
    differences on the doubled nodes, in the variable theta = (t - tn[m - 2]) / (tn[m - 1] - tn[m - 2])
    (the last interval is [0, 1]); xs and q are work arrays of 2 m floats."""
    scale = tn[m - 1] - tn[m - 2]
    top = 2 * m
    theta = (t - tn[m - 2]) / scale
    for r in range(m):
        xs[2 * r] = xs[2 * r + 1] = (tn[r] - tn[m - 2]) / scale
    for i in range(Zn.shape[1]):
        for r in range(m):
            q[2 * r] = q[2 * r + 1] = Zn[r, i]
        for order in range(1, top):
            for r in range(top - 1, order - 1, -1):
                if order == 1 and r % 2 == 1:
                    q[r] = Fn[r // 2, i] * scale
                else:
                    q[r] = (q[r] - q[r - 1]) / (xs[r] - xs[r - order])
        value = q[top - 1]
        for r in range(top - 2, -1, -1):
            value = value * (theta - xs[r]) + q[r]
        out[i] = value


@njit(cache=True, error_model="numpy")
def _gauss_sample(hamilton, s, t, h, theta, z, compensation, FZ, sizes, p, x, a, out, W, F, work, fw, stats):
    """out = the state at t + theta h (0 < theta < 1) by one Gauss step of theta h from the step's start
    z: the method's own accuracy (order 2s), where an interpolant of the steps has its own error (of
    order h^8, larger than the method's at the steps it is used at: Kepler e = 0.5, 3 stages, h = 0.2:
    an energy error 200x the method's midway between steps). Its stages are predicted by the step's
    collocation polynomial (FZ) and solved by fixed-point iteration as the steps are; 1 when that
    does not converge (a stiff problem: the caller interpolates instead), else 0."""
    n = z.shape[0]
    sub = theta * h
    for i in range(s):
        x_i = theta * _GAUSS_C[s - 1, i]
        for k in range(n):
            value = 0.0
            for j in range(s):
                weight = 0.0
                for r in range(4):
                    weight = weight * x_i + _GAUSS_L[s - 1, j, r]
                value += weight * FZ[j, k]
            W[i, k] = h * value
    previous, before = np.inf, np.inf
    for iteration in range(1, MAX_ITERATIONS + 1):
        for i in range(s):
            for k in range(n):
                work[k] = z[k] + W[i, k]
            if hamilton(t + _GAUSS_C[s - 1, i] * sub, work, p, fw, x, a):
                return 1
            for k in range(n):
                F[i, k] = fw[k]
        stats[NFEV] += s
        change = 0.0
        for i in range(s):
            for k in range(n):
                value = 0.0
                for j in range(s):
                    value += sub * _GAUSS_A[s - 1, i, j] * F[j, k]
                step_change = abs(value - W[i, k])
                W[i, k] = value
                if step_change > 0.0:
                    change = max(change, step_change / (sizes[k] if sizes[k] > 0.0 else 1.0))
        if not np.isfinite(change):
            return 1
        converged = change <= ROUNDOFF or (iteration > 2 and change >= before and change <= STAGNATION)
        if not converged and ((iteration > 2 and change >= before) or (iteration > 2 and change > STAGNATION and change > FIXED_SLOW * before)):
            return 1
        if converged:
            for k in range(n):
                value = 0.0
                for i in range(s):
                    value += _GAUSS_B[s - 1, i] * F[i, k]
                out[k] = z[k] + (sub * value + compensation[k])  # z + compensation is the state at t
            return 0
        previous, before = change, previous
    return 1


@njit(cache=True, error_model="numpy")
def _velocity_state(z, f, out):
    """(q, q_dot) from z = (q, p) and f = (q_dot, p_dot)."""
    m = z.shape[0] // 2
    for k in range(m):
        out[k] = z[k]
        out[m + k] = f[k]


@njit(cache=True, error_model="numpy")
def _gauss_root(hamilton, event, tn, Zn, Fn, m, xs, q, p, x, a, g_old):
    """The event time in (tn[m - 2], tn[m - 1]], by bisection on the Hermite interpolant (`_hermite`)."""
    n = Zn.shape[1]
    lo, hi = tn[m - 2], tn[m - 1]
    g_lo = g_old
    work, f, state = np.empty(n), np.empty(n), np.empty(n)
    for _ in range(200):
        if hi - lo <= 4e-16 * max(abs(hi), 1.0):
            break
        mid = 0.5 * (lo + hi)
        _hermite(tn, Zn, Fn, m, mid, work, xs, q)
        hamilton(mid, work, p, f, x, a)
        _velocity_state(work, f, state)
        g_mid = event(mid, state, p, x, a)
        if (g_mid < 0.0) == (g_lo < 0.0):
            lo, g_lo = mid, g_mid
        else:
            hi = mid
    return hi


def gauss_run(s, z, state, control, ts, zs, p, stats, sizes, memory, pivots, hamilton, event):
    """Advance z = (q, p) by fixed steps h = control[STEP] (t = state[T], state[H] steps taken of
    control[STEPS]) until t >= control[T_STOP], writing zs[j] = (q, q_dot) at the samples ts[j]
    passed (state[NEXT_SAMPLE] = the next one); returns a status code.
    Time is t0 + k h, computed afresh at each step (one rounding, no accumulated error); the last
    step ends at t_end exactly. The state is summed with compensation (Kahan): z + delta rounds,
    and what the rounding lost is carried into the next step's delta, so that a million steps add
    no more round-off than one.
    `sizes` keeps the largest |z_k| so far (the scale of each component's convergence test).
    What the iteration carries from step to step lives in the caller's arrays, so that a run
    paused and resumed (for progress, at times that depend on the clock) takes exactly the steps
    of one that was not: `memory` (zeros at the start, `memory_size(s, n)` floats) holds the stage
    derivatives of the last step (the next step's predictor), the LU factors of the Newton matrix,
    the compensation of the sum and the loop's diagnostics (ITERATIONS_MAX, ...), `pivots` the
    factors' row exchanges, state[NEWTON] 1.0 while those factors are current."""
    n = z.shape[0]
    unknowns = s * n
    h, steps, t0, t_end, t_stop, use_event = control[STEP], int(control[STEPS]), control[T0], control[T_BOUND], control[T_STOP], control[USE_EVENT] != 0.0
    size = int(control[SIZE])
    x, a = np.empty(size), np.empty((size, size))
    W, predicted = np.empty((s, n)), np.empty((s, n))
    FZ = memory[: s * n].reshape((s, n))
    base = s * n + (s * n) * (s * n)
    m = memory[s * n : base].reshape((s * n, s * n))
    compensation = memory[base : base + n]
    report = memory[base + n : base + n + DIAGNOSTICS]
    ring = base + n + DIAGNOSTICS  # the interpolant's history: the state at the start of step k, F there, whether F is known, k + 1 (0: empty)
    Zh = memory[ring : ring + _HISTORY * n].reshape((_HISTORY, n))
    Fh = memory[ring + _HISTORY * n : ring + 2 * _HISTORY * n].reshape((_HISTORY, n))
    known = memory[ring + 2 * _HISTORY * n : ring + 2 * _HISTORY * n + _HISTORY]
    held = memory[ring + 2 * _HISTORY * n + _HISTORY : ring + 2 * _HISTORY * n + 2 * _HISTORY]
    tn, Zn, Fn, xs, q = np.empty(NODES), np.empty((NODES, n)), np.empty((NODES, n)), np.empty(2 * NODES), np.empty(2 * NODES)
    W_sample, F_sample, scratch = np.empty((s, n)), np.empty((s, n)), np.empty(n)
    z_new, f0, f1, work, fw, z_event, lost = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    jac, g = np.empty((n, n)), np.empty(s * n)
    done = int(state[H])
    t = state[T]
    fresh, refreshed = state[NEWTON] != 0.0, False
    taken = 0
    while done < steps and t < t_stop and taken < PAUSE_STEPS:
        taken += 1
        slot = done % _HISTORY
        if held[slot] != done + 1:
            for k in range(n):
                Zh[slot, k] = z[k]
            known[slot], held[slot] = 0.0, done + 1
        for i in range(s):
            for k in range(n):
                value = 0.0
                for j in range(s):
                    value += _GAUSS_E[s - 1, i, j] * FZ[j, k]
                predicted[i, k] = h * value
        # The stage equations, solved here rather than in a function of their own: a call of a compiled
        # function (and a view such as FZ[i]) costs atomic reference-count operations on every array
        # it takes, which numba cannot prune around the indirect call of `hamilton`; they were about
        # 40% of a step's time on Kepler's problem (issue 15). STAGES_DOC says what this does.
        newton = done < report[NEWTON_UNTIL]
        status, iterations, correction, slowest = NO_CONVERGENCE, MAX_ITERATIONS, np.inf, 0.0
        for _attempt in range(3):
            if newton and not fresh:
                state[NEWTON] = 0.0
                if _jacobian(hamilton, t, z, p, x, a, jac, f0, work, fw, sizes, stats) or _newton_matrix(s, h, jac, m, pivots):
                    return SINGULAR
                fresh, refreshed = True, True
                state[NEWTON] = 1.0
            for i in range(s):
                for k in range(n):
                    W[i, k] = predicted[i, k]
            previous, before, slowest = np.inf, np.inf, 0.0
            status, iterations, correction = NO_CONVERGENCE, MAX_ITERATIONS, np.inf
            for iteration in range(1, MAX_ITERATIONS + 1):
                singular = False
                for i in range(s):
                    for k in range(n):
                        work[k] = z[k] + W[i, k]
                    if hamilton(t + _GAUSS_C[s - 1, i] * h, work, p, fw, x, a):
                        singular = True
                        break
                    for k in range(n):
                        FZ[i, k] = fw[k]
                if singular:
                    status, iterations, correction = SINGULAR, iteration, np.inf
                    break
                stats[NFEV] += s
                for i in range(s):
                    for k in range(n):
                        value = -W[i, k]
                        for j in range(s):
                            value += h * _GAUSS_A[s - 1, i, j] * FZ[j, k]
                        g[i * n + k] = value
                if newton:  # g = m^-1 g with the LU factors of `_newton_matrix` (their row exchanges in `pivots`)
                    for k in range(unknowns):
                        g[k], g[pivots[k]] = g[pivots[k]], g[k]
                    for i in range(unknowns):
                        for j in range(i):
                            g[i] -= m[i, j] * g[j]
                    for i in range(unknowns - 1, -1, -1):
                        for j in range(i + 1, unknowns):
                            g[i] -= m[i, j] * g[j]
                        g[i] /= m[i, i]
                change = 0.0
                for i in range(s):
                    for k in range(n):
                        W[i, k] += g[i * n + k]
                        step_change = abs(g[i * n + k])
                        if step_change > 0.0:
                            change = max(change, step_change / (sizes[k] if sizes[k] > 0.0 else 1.0))
                if not np.isfinite(change):
                    status, iterations, correction = NONFINITE, iteration, change
                    break
                if change <= ROUNDOFF:  # FZ was evaluated at stage values within an ulp of the solution
                    status, iterations, correction = DONE, iteration, change
                    break
                if iteration > (1 if newton else 2) and change >= (previous if newton else before):
                    # the corrections stopped decreasing (fixed-point: over two sweeps): round-off, or no convergence
                    status, iterations, correction = (DONE if change <= STAGNATION else NO_CONVERGENCE), iteration, change
                    break
                if not newton and iteration > 2 and change > STAGNATION and change > FIXED_SLOW * before:
                    status, iterations, correction = NO_CONVERGENCE, iteration, change  # too slow: Newton's turn
                    break
                if iteration > 1:
                    slowest = max(slowest, change / previous)
                previous, before = change, previous
                correction = change
            if status == DONE:
                break
            if not newton:  # fixed-point iteration failed: the same step by Newton, with a fresh matrix
                newton, fresh = True, False
                report[NEWTON_UNTIL] = done + RETRY
                report[FALLBACKS] += 1.0
                continue
            if status == NO_CONVERGENCE and not refreshed:
                fresh = False  # a Jacobian from an earlier step: refresh it and try again
                continue
            break
        if status != DONE:
            return status
        if newton:
            fresh, refreshed = slowest <= SLOW, False
            state[NEWTON] = 1.0 if fresh else 0.0
        report[ITERATIONS_MAX] = max(report[ITERATIONS_MAX], iterations)
        report[CORRECTION_MAX] = max(report[CORRECTION_MAX], correction)
        deviation = 0.0
        half = n // 2
        q_size, p_size = 0.0, 0.0
        for k in range(half):
            q_size, p_size = max(q_size, sizes[k]), max(p_size, sizes[half + k])
        for i in range(s):
            for k in range(n):
                scale = q_size if k < half else p_size  # the block's size: a component that starts at 0 is not measured against its own tiny size
                deviation = max(deviation, abs(W[i, k] - predicted[i, k]) / (scale if scale > 0.0 else 1.0))
        if done > 0:  # the first step has no predictor
            if deviation > report[DEVIATION_MAX]:
                report[DEVIATION_MAX], report[DEVIATION_T] = deviation, t
            report[DEVIATION_STEPS] += 1.0
            report[DEVIATION_SUM] += deviation
        for k in range(n):
            value = 0.0
            for i in range(s):
                value += _GAUSS_B[s - 1, i] * FZ[i, k]
            delta = h * value + compensation[k]
            z_new[k] = z[k] + delta
            lost[k] = (z[k] - z_new[k]) + delta  # what the rounding of z + delta lost
        finite = True
        for k in range(n):
            finite = finite and np.isfinite(z_new[k])
        if not finite:
            return NONFINITE
        done += 1
        t_new = t_end if done >= steps else t0 + done * h
        stats[NSTEPS] += 1
        j = int(state[NEXT_SAMPLE])
        m_nodes = 0
        if (j < ts.shape[0] and ts[j] <= t_new) or use_event:
            # the interpolant's nodes: the starts of this step and of the NODES - 2 before it (F computed
            # once for each and kept), and this step's end
            for r in range(max(0, done - NODES + 1), done):
                slot = r % _HISTORY
                if held[slot] != r + 1:
                    continue  # not kept (never, within one run: every step's start is stored)
                if known[slot] == 0.0:
                    for k in range(n):
                        work[k] = Zh[slot, k]
                    if hamilton(t0 + r * h, work, p, fw, x, a):
                        return SINGULAR
                    stats[NFEV] += 1
                    for k in range(n):
                        Fh[slot, k] = fw[k]
                    known[slot] = 1.0
                tn[m_nodes] = t0 + r * h
                for k in range(n):
                    Zn[m_nodes, k], Fn[m_nodes, k] = Zh[slot, k], Fh[slot, k]
                m_nodes += 1
            if hamilton(t_new, z_new, p, f1, x, a):
                return SINGULAR
            stats[NFEV] += 1
            tn[m_nodes] = t_new
            for k in range(n):
                Zn[m_nodes, k], Fn[m_nodes, k] = z_new[k], f1[k]
            m_nodes += 1
        t_end_here = t_new
        event_found = False
        if use_event:
            _velocity_state(z_new, f1, work)
            g_new = event(t_new, work, p, x, a)
            if (state[EVENT_VALUE] < 0.0) != (g_new < 0.0) and state[EVENT_VALUE] != 0.0:
                event_found = True
                t_end_here = _gauss_root(hamilton, event, tn, Zn, Fn, m_nodes, xs, q, p, x, a, state[EVENT_VALUE])
                theta = (t_end_here - t) / h
                if not 0.0 < theta < 1.0 or _gauss_sample(hamilton, s, t, h, theta, z, compensation, FZ, sizes, p, x, a, z_event, W_sample, F_sample, work, fw, stats):
                    _hermite(tn, Zn, Fn, m_nodes, t_end_here, z_event, xs, q)
            else:
                state[EVENT_VALUE] = g_new
        while j < ts.shape[0] and ts[j] <= t_end_here:
            theta = (ts[j] - t) / h
            if ts[j] == t_new:
                for k in range(n):
                    work[k] = z_new[k]
            elif not 0.0 < theta < 1.0 or _gauss_sample(hamilton, s, t, h, theta, z, compensation, FZ, sizes, p, x, a, work, W_sample, F_sample, scratch, fw, stats):
                _hermite(tn, Zn, Fn, m_nodes, ts[j], work, xs, q)
            hamilton(ts[j], work, p, fw, x, a)
            _velocity_state(work, fw, zs[j])
            j += 1
        state[NEXT_SAMPLE] = j
        for k in range(n):
            if event_found:
                z[k], compensation[k] = z_event[k], 0.0
            else:
                z[k], compensation[k] = z_new[k], lost[k]
            sizes[k] = max(sizes[k], abs(z[k]))
        if m_nodes > 0 and not event_found:  # the next step's start, with F known
            slot = done % _HISTORY
            for k in range(n):
                Zh[slot, k], Fh[slot, k] = z[k], f1[k]
            known[slot], held[slot] = 1.0, done + 1
        t = t_end_here
        state[T], state[H] = t, done
        if event_found:
            return EVENT
    return DONE if done >= steps else RUNNING


# -- Radau IIA (3 stages, order 5), the RADAU5 algorithm (Hairer and Wanner, Solving ODEs II, IV.8) ----------
#
# Stages Z_i = y(t + c_i h) - y solve Z = h (A x I) F(Z) by simplified Newton iteration, transformed by
# T (tableaux.RADAU_T) into one real system (MU_REAL / h - J) and one complex one (MU_COMPLEX / h - J),
# each n x n, factored once and reused while the step changes little; the Jacobian J is refreshed where
# Newton iteration converges slowly, and the step is halved where it does not converge with a fresh one.
# The error estimate is the embedded one filtered by (MU_REAL / h - J)^-1 (and evaluated once more where
# it is large on the first or a rejected step); the step follows the predictive (Gustafsson) controller
# with a safety factor that shrinks with the Newton iterations taken. The same decisions as scipy's
# `Radau` (which reads as a reference), so that both take about the same steps; the dense output is the
# collocation polynomial.

NEWTON_MAXITER = 6
"""Newton iterations of one step at most (RADAU5's NIT = 7 is the default there; scipy takes 6)."""
RADAU_ERROR_ORDER = 3
"""The error estimate's order (scipy's `error_estimator_order` of Radau): the initial step is chosen for it."""
_RADAU_ORDER = np.int64(RADAU_ERROR_ORDER)
"""RADAU_ERROR_ORDER typed int64 as the explicit pairs' orders are, so that `_initial_step` compiles once for both."""
JAC_RATE = 1e-3
"""A step whose Newton iteration took more than 2 iterations at a contraction rate above this refreshes J."""
DIVERGENT = 0.99
"""Newton corrections shrinking by less than this factor an iteration do not converge (radau5.f)."""
KEEP_FACTOR = 1.2
"""A step that would grow by less than this keeps its size (and the Newton matrices' factors)."""
_RC = np.array(RADAU_C)
_RE = np.array(RADAU_E)
_RT = np.array(RADAU_T)
_RTI = np.array(RADAU_TI)
_RP = np.linalg.inv(np.array([[c ** (k + 1) for k in range(3)] for c in RADAU_C])).T.copy()
"""The dense output's coefficients Q = Z^T P: y(t + x h) = y + sum_k Q_k x^(k + 1) passes through y + Z_i at x = c_i."""
_MU_REAL = MU_REAL
_MU_COMPLEX = complex(MU_COMPLEX_REAL, MU_COMPLEX_IMAG)
_EPS = 2.220446049250313e-16


@njit(cache=True, error_model="numpy")
def _lu_factor(a, pivots):
    """LU factors of a (real or complex) in place, partial pivoting (pivots[k]: the row swapped with
    row k); 1 when a pivot is zero or not finite (singular, or NaN entries), else 0."""
    n = a.shape[0]
    for k in range(n):
        pivot = k
        big = abs(a[k, k])
        for i in range(k + 1, n):
            if abs(a[i, k]) > big:
                big = abs(a[i, k])
                pivot = i
        pivots[k] = pivot
        if not (big > 0.0 and big < np.inf):
            return 1
        if pivot != k:
            for j in range(n):
                a[k, j], a[pivot, j] = a[pivot, j], a[k, j]
        inverse = 1.0 / a[k, k]
        for i in range(k + 1, n):
            a[i, k] *= inverse
            factor = a[i, k]
            if factor != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= factor * a[k, j]
    return 0


@njit(cache=True, error_model="numpy")
def _lu_back(a, pivots, b):
    """Solve with `_lu_factor`'s factors: b becomes a^-1 b."""
    n = b.shape[0]
    for k in range(n):  # every interchange first: the factors' rows were swapped whole, L's columns included
        r = pivots[k]
        if r != k:
            b[k], b[r] = b[r], b[k]
    for k in range(n):
        for i in range(k + 1, n):
            b[i] -= a[i, k] * b[k]
    for i in range(n - 1, -1, -1):
        total = b[i]
        for j in range(i + 1, n):
            total -= a[i, j] * b[j]
        b[i] = total / a[i, i]


@njit(cache=True, error_model="numpy")
def _radau_matrices(jac, h, lu_real, pivots_real, lu_complex, pivots_complex, stats):
    """The Newton matrices' factors: MU_REAL / h - J and MU_COMPLEX / h - J; 1 when one is singular."""
    n = jac.shape[0]
    real, cplx = _MU_REAL / h, _MU_COMPLEX / h
    for i in range(n):
        for j in range(n):
            lu_real[i, j] = -jac[i, j]
            lu_complex[i, j] = -jac[i, j]
        lu_real[i, i] += real
        lu_complex[i, i] += cplx
    stats[NLU] += 2
    if _lu_factor(lu_real, pivots_real):
        return 1
    return _lu_factor(lu_complex, pivots_complex)


@njit(cache=True, error_model="numpy")
def _floor_solve(lu_real, pivots_real, delta, floor, work):
    """floor = FLOOR_SAFETY x |(MU_REAL / h - J)^-1 delta| for perturbations of the sizes `delta` whose signs
    are unknown: solved with three sign patterns (alike, alternating, alternating in pairs: one alone can
    cancel) and the largest of each component kept."""
    n = delta.shape[0]
    for pattern in range(3):
        for i in range(n):
            sign = 1.0
            if (pattern == 1 and i % 2 == 1) or (pattern == 2 and (i // 2) % 2 == 1):
                sign = -1.0
            work[i] = delta[i] * sign
        _lu_back(lu_real, pivots_real, work)
        for i in range(n):
            value = FLOOR_SAFETY * abs(work[i])
            if pattern == 0 or value > floor[i]:
                floor[i] = value


@njit(cache=True, error_model="numpy")
def _radau_floor(accel, t, y, f, p, x, a, jac, lu_real, pivots_real, floor, delta, measured, work, fw, atol, rtol, newton_tol, stats):
    """The round-off floor of each component's Newton corrections and error estimate (into `floor`): what
    evaluating f at a state rounded to double precision puts into them through the factors of MU_REAL / h - J
    (`lu_real`). A stiff spring written in its length shows why: each stage sees r rounded to its spacing, so
    the force k (r - l) carries k eps |r| and r_dot's corrections h k eps |r| / MU_REAL, far above an atol of
    1e-12 at k = 1e10. A Newton iteration held to less stalls, the step is halved, which leaves that noise as
    it is, and the run crawls (1e6 steps of 1e-9 s). The scale of Newton's test and of the error test is
    raised to this floor instead (FLOORED counts the steps where the error test's was).

    First from J: eps x (sum_k |J_jk| |y_k| + |f_j|) per equation. J may be stale (kept while Newton
    converges: a relaxation oscillator's slow branch keeps the J of its last jump, 1e5 x too large), so where
    that floor would bind, the perturbation is also measured: f at y moved by eps |y| (one spacing or two)
    with two sign patterns, two evaluations, |f(y') - f(y)| + eps |f|, and the smaller of the two kept (the
    measured one overstates where y' is across a jump of the forces: a gated damper's 970 at its touch).
    1 when f cannot be evaluated."""
    n = y.shape[0]
    for i in range(n):
        total = abs(f[i])
        for k in range(n):
            total += abs(jac[i, k]) * abs(y[k])
        delta[i] = _EPS * total
    _floor_solve(lu_real, pivots_real, delta, floor, work)
    binds = False
    for i in range(n):
        if floor[i] > newton_tol * (atol + abs(y[i]) * rtol):
            binds = True
    if not binds:
        return 0
    for i in range(n):
        measured[i] = 0.0
    for pattern in range(2):
        for k in range(n):
            sign = -1.0 if pattern == 1 and k % 2 == 1 else 1.0
            work[k] = y[k] + sign * _EPS * abs(y[k])
        if _rhs(accel, t, work, p, fw, x, a):
            return 1
        stats[NFEV] += 1
        for i in range(n):
            measured[i] = max(measured[i], abs(fw[i] - f[i]))
    for i in range(n):  # the smaller: J's overstates where J is stale, the measured one where y' is across a jump of f
        delta[i] = min(delta[i], measured[i] + _EPS * abs(f[i]))
    _floor_solve(lu_real, pivots_real, delta, floor, work)
    return 0


@njit(cache=True, error_model="numpy")
def _radau_jacobian(accel, t, y, f, p, x, a, jac, work, fw, stats):
    """J = df/dy at (t, y) by forward differences (radau5.f's increments sqrt(eps max(1e-5, |y_j|))),
    f = f(t, y) given; the rows of dq/dt are exact ([0 I]). 1 when the matrix is singular."""
    n = y.shape[0]
    half = n // 2
    for i in range(n):
        work[i] = y[i]
    for j in range(n):
        step = (_EPS * max(1e-5, abs(y[j]))) ** 0.5
        work[j] = y[j] + step
        step = work[j] - y[j]
        if accel(t, work, p, x, a):
            return 1
        for i in range(half):
            jac[i, j] = 1.0 if j == half + i else 0.0
            jac[half + i, j] = (x[i] - f[half + i]) / step
        work[j] = y[j]
    stats[NFEV] += n
    stats[NJEV] += 1
    return 0


def no_jacobian(t, y, p, r, x, a):
    """The Jacobian argument of a system without an analytic one (forward differences are used)."""
    return 1


@njit(cache=True, error_model="numpy")
def _radau_analytic(jacobian, t, y, p, x, a, rows, jac, pivots, column, stats):
    """J from the system's analytic `_jac` (the derivative of the augmented system, codegen.jac_numba):
    the first n rows of a^-1 r, the rows of dq/dt exact ([0 I]); 1 when the matrix is singular, 2 where a
    value of it is not finite (0/0 in the derivative of |v| v at rest: the caller takes differences)."""
    n = y.shape[0]
    half = n // 2
    size = x.shape[0]
    if jacobian(t, y, p, rows, x, a):
        return 1
    stats[NFEV] += 1
    if _lu_factor(a, pivots):
        return 1
    for c in range(n):
        for i in range(size):
            column[i] = rows[i, c]
        _lu_back(a, pivots, column)
        for i in range(half):
            if not np.isfinite(column[i]):
                return 2
            jac[i, c] = 1.0 if c == half + i else 0.0
            jac[half + i, c] = column[i]
    stats[NJEV] += 1
    return 0


@njit(cache=True, error_model="numpy")
def _radau_jac(accel, jacobian, analytic, t, y, f, p, x, a, jac, work, fw, rows, pivots, column, stats):
    """J at (t, y) (f = f(t, y)): analytic where the system has one and its values are finite, else by
    forward differences; 1 when the matrix is singular."""
    if analytic:
        found = _radau_analytic(jacobian, t, y, p, x, a, rows, jac, pivots, column, stats)
        if found != 2:
            return found
    return _radau_jacobian(accel, t, y, f, p, x, a, jac, work, fw, stats)


@njit(cache=True, error_model="numpy")
def _radau_afresh(accel, jacobian, analytic, t, y, f, p, x, a, jac, work, fw, rows, pivots, column, stats, memory):
    """A restart of the Radau loop at (t, y) with f = f(t, y) (after a landing on a crossing, a hop across a jump, a
    projection): the Jacobian afresh, no predictor, no controller memory (as radau_start). True where the Jacobian
    cannot be evaluated there (the caller returns SINGULAR); the caller marks J current and the factors stale."""
    if _radau_jac(accel, jacobian, analytic, t, y, f, p, x, a, jac, work, fw, rows, pivots, column, stats):
        return True
    memory[CURRENT_JAC], memory[LU_STEP], memory[HAVE_DENSE], memory[CONTRACTION] = 1.0, 0.0, 0.0, 1.0
    memory[H_ABS_OLD], memory[ERROR_OLD] = np.nan, np.nan
    return False


@njit(cache=True, error_model="numpy")
def _radau_eval(t_old, h, y_old, dense, t, out):
    """The collocation polynomial of the step [t_old, t_old + h] at t (dense[k]: the coefficient of x^(k + 1))."""
    xi = (t - t_old) / h
    for i in range(y_old.shape[0]):
        out[i] = y_old[i] + xi * (dense[0, i] + xi * (dense[1, i] + xi * dense[2, i]))


@njit(cache=True, error_model="numpy")
def _radau_newton(accel, t, y, h, Z, W, F, dW, scale, tol, contraction, lu_real, pivots_real, lu_complex, pivots_complex, rhs_complex, work, p, x, a, stats):
    """Simplified Newton iteration on the collocation system from the predictor Z (overwritten by the
    stages): (code, converged, iterations, the last contraction rate (NaN before a second iteration),
    the contraction factor rate / (1 - rate)). The code is SINGULAR where the matrix of the equations is
    singular at a stage, NONFINITE where a stage's value is not finite (not converged), else RUNNING.
    As in radau5.f, a correction counts as converged once contraction x its norm <= tol, the first
    one judged by the factor of the steps before (`contraction`): an accurate predictor converges in one
    iteration (scipy waits for a second correction to measure the rate: 3 more evaluations). The iteration
    stops, not converged, when the corrections stop contracting (rate >= 0.99) or would not reach `tol`
    within NEWTON_MAXITER at their rate."""
    n = y.shape[0]
    half = n // 2
    real, cplx = _MU_REAL / h, _MU_COMPLEX / h
    for r in range(3):
        for i in range(n):
            W[r, i] = _RTI[r, 0] * Z[0, i] + _RTI[r, 1] * Z[1, i] + _RTI[r, 2] * Z[2, i]
    norm_old, rate = -1.0, np.nan
    for k in range(NEWTON_MAXITER):
        for r in range(3):
            for i in range(n):
                work[i] = y[i] + Z[r, i]
            if accel(t + _RC[r] * h, work, p, x, a):  # (at a stage that is not finite: NONFINITE, the step shrunk, as `_not_finite`)
                return (SINGULAR if _finite(work) else NONFINITE), False, k + 1, rate, contraction
            for i in range(half):
                F[r, i] = work[half + i]
                F[r, half + i] = x[i]
        stats[NFEV] += 3
        for r in range(3):
            for i in range(n):
                if not np.isfinite(F[r, i]):
                    return NONFINITE, False, k + 1, rate, contraction
        for i in range(n):
            dW[0, i] = _RTI[0, 0] * F[0, i] + _RTI[0, 1] * F[1, i] + _RTI[0, 2] * F[2, i] - real * W[0, i]
            re = _RTI[1, 0] * F[0, i] + _RTI[1, 1] * F[1, i] + _RTI[1, 2] * F[2, i]
            im = _RTI[2, 0] * F[0, i] + _RTI[2, 1] * F[1, i] + _RTI[2, 2] * F[2, i]
            rhs_complex[i] = complex(re, im) - cplx * complex(W[1, i], W[2, i])
        _lu_back(lu_real, pivots_real, dW[0])
        _lu_back(lu_complex, pivots_complex, rhs_complex)
        total = 0.0
        for i in range(n):
            dW[1, i], dW[2, i] = rhs_complex[i].real, rhs_complex[i].imag
            total += (dW[0, i] / scale[i]) ** 2 + (dW[1, i] / scale[i]) ** 2 + (dW[2, i] / scale[i]) ** 2
        norm = (total / (3 * n)) ** 0.5
        if not np.isfinite(norm):
            return NONFINITE, False, k + 1, rate, contraction
        if norm_old >= 0.0:
            rate = norm / norm_old
            if rate >= DIVERGENT or rate ** (NEWTON_MAXITER - k) / (1.0 - rate) * norm > tol:
                return RUNNING, False, k + 1, rate, contraction
            contraction = rate / (1.0 - rate)
        for r in range(3):
            for i in range(n):
                W[r, i] += dW[r, i]
        for r in range(3):
            for i in range(n):
                Z[r, i] = _RT[r, 0] * W[0, i] + _RT[r, 1] * W[1, i] + _RT[r, 2] * W[2, i]
        if norm == 0.0 or contraction * norm <= tol:
            return RUNNING, True, k + 1, rate, contraction
        norm_old = norm
    return RUNNING, False, NEWTON_MAXITER, rate, contraction


@njit(cache=True, error_model="numpy")
def _predict_factor(h_abs, h_abs_old, error_norm, error_old):
    """The predictive (Gustafsson) controller's factor (radau5.f; h_abs_old, error_old NaN: none)."""
    if np.isnan(h_abs_old) or np.isnan(error_old) or error_norm == 0.0:
        multiplier = 1.0
    else:
        multiplier = h_abs / h_abs_old * (error_old / error_norm) ** 0.25
    if error_norm == 0.0:
        return np.inf
    return min(1.0, multiplier) * error_norm**-0.25


@njit(cache=True, error_model="numpy")
def _radau_root(event, t_old, h, y_old, dense, hi, p, x, a, work, g_old):
    """The time in (t_old, hi] where the event changes sign: the Illinois method on the collocation polynomial."""
    lo = t_old
    g_lo = g_old
    _radau_eval(t_old, h, y_old, dense, hi, work)
    g_hi = event(hi, work, p, x, a)
    side = 0
    for _ in range(100):
        if hi - lo <= 4e-16 * max(abs(hi), 1.0):
            break
        mid = _illinois_guess(lo, hi, g_lo, g_hi)
        _radau_eval(t_old, h, y_old, dense, mid, work)
        g_mid = event(mid, work, p, x, a)
        if g_mid == 0.0:
            return mid
        lo, hi, g_lo, g_hi, side = _illinois_update(lo, hi, g_lo, g_hi, side, mid, g_mid)
    return hi


def radau_start(t0, y, f, control, p, stats, jac, memory, accel, jacobian):
    """f = f(t0, y), J at (t0, y), a fresh `memory` (status.T_OLD, ...) and scipy's initial step for
    Radau; -1 when the matrix is singular at t0."""
    n = y.shape[0]
    size = int(control[SIZE])
    x, a = np.empty(size), np.empty((size, size))
    if _rhs(accel, t0, y, p, f, x, a):
        return -1.0
    stats[NFEV] += 1
    rows, pivots, column = np.empty((size, n)), np.empty(size, dtype=np.int64), np.empty(size)
    if _radau_jac(accel, jacobian, control[ANALYTIC] != 0.0, t0, y, f, p, x, a, jac, np.empty(n), np.empty(n), rows, pivots, column, stats):
        return -1.0
    memory[T_OLD], memory[STEP_OLD], memory[H_ABS_OLD], memory[ERROR_OLD] = t0, 0.0, np.nan, np.nan
    memory[CURRENT_JAC], memory[LU_STEP], memory[HAVE_DENSE], memory[CONTRACTION] = 1.0, 0.0, 0.0, 1.0
    rtol = max(control[RTOL], 100 * _EPS)
    return _initial_step(accel, t0, y, f, control[T_BOUND], control[MAX_STEP], _RADAU_ORDER, rtol, control[ATOL], p, x, a, stats)


def radau_run(y, f, state, control, ts, ys, p, stats, jac, dense, y_old, memory, accel, event, jacobian):
    """Advance (t = state[T], y, f = f(t, y), |h| = state[H], the stop condition's value state[EVENT_VALUE],
    J = jac, the last step's collocation polynomial (dense, y_old) and the step control's `memory`, all
    from `radau_start` or the call before) by Radau IIA until t >= control[T_STOP], writing ys[j] = y(ts[j])
    for the samples passed (state[NEXT_SAMPLE]: the next one); returns a status code (RUNNING: paused)."""
    return _radau_loop(y, f, state, control, ts, ys, p, stats, jac, dense, y_old, memory, accel, event, jacobian, None, None, None, None, None, None, None)


def radau_switched(y, f, state, control, ts, ys, p, stats, jac, dense, y_old, memory, accel, event, jacobian, switch, record):
    """`radau_run` landing a step on each zero crossing of the switching functions `switch` (codegen's
    `_switch`), as `erk_switched`: after an accepted step, g at its end is compared with g at its start
    (record, switching_record); where one changed sign, the crossing is located on the step's collocation
    polynomial (the Illinois method, the earliest of them), the step is discarded (counted as rejected) and
    taken again to land on it; there the method restarts as at t0: a fresh Jacobian and LU, scipy's
    initial step, no predictor from the step before and the predictive controller's memory cleared. A
    collapse onto a surface where the forces jump hops across it, and a sliding mode stops the run, as in
    erk_switched."""
    return _radau_loop(y, f, state, control, ts, ys, p, stats, jac, dense, y_old, memory, accel, event, jacobian, switch, record, None, None, None, None, None)


def radau_projected(y, f, state, control, ts, ys, p, stats, jac, dense, y_old, memory, accel, event, jacobian, rows, energy, bounds, holonomic, record):
    """`radau_run` with the state projected onto the kept constraints at the times `bounds` (increasing, the
    last one t_end), as `erk_projected`: a step reaching the next of them is shortened to land exactly on it,
    the state there is projected (`_project`, the same routine, constants and skip rules; where it cannot be
    applied the state is kept as it was, and counted), a sample at that time takes the projected state, and
    the method restarts there as radau_switched does at a crossing (f evaluated anew, a fresh Jacobian and
    LU, no predictor from the step before, the predictive controller's memory cleared), going on with the
    step size it had before it was shortened (its growth capped at 1). The largest corrections and the
    counts go into `record` (status.POSITION, ...); record[NEXT_BOUND] is the next projection time's index.
    No switching functions are located (as erk_projected). Pauses as radau_run does; returns a status code."""
    return _radau_loop(y, f, state, control, ts, ys, p, stats, jac, dense, y_old, memory, accel, event, jacobian, None, None, rows, energy, bounds, holonomic, record)


@njit(cache=True, error_model="numpy")
def _radau_loop(y, f, state, control, ts, ys, p, stats, jac, dense, y_old, memory, accel, event, jacobian, switch, record, rows, energy, bounds, holonomic, projected_record):
    """radau_run, radau_switched and radau_projected. `switch` (and its `record`) or `rows` (and `energy`, `bounds`,
    `holonomic`, `projected_record`) None: that case is left out when numba compiles the loop for the entry point
    (its branches `if switch is not None`, `if rows is not None` pruned, as in `_erk_loop`), so radau_run compiles
    none of the crossing search, the hop or the projection (helper compile18: it compiled them, never called, for
    every smooth system) and takes its steps exactly as before."""
    n = y.shape[0]
    m = 0
    if switch is not None:
        m = (record.shape[0] - SWITCH_HEAD) // 2
    g_end, g_work, g_start, trial, slope = np.empty(m), np.empty(m), np.empty(m), np.empty((3, n)), np.empty((1, n))
    rtol = max(control[RTOL], 100 * _EPS)  # scipy's floor for Radau
    atol, max_step, t_bound, t_stop, use_event = control[ATOL], control[MAX_STEP], control[T_BOUND], control[T_STOP], control[USE_EVENT] != 0.0
    newton_tol = max(10 * _EPS / rtol, min(0.03, rtol**0.5))
    pause = int(control[STRETCH]) if control[STRETCH] > 0.0 else PAUSE_STEPS
    size = int(control[SIZE])
    x, a = np.empty(size), np.empty((size, size))
    lu_real, lu_complex = np.empty((n, n)), np.empty((n, n), dtype=np.complex128)
    pivots_real, pivots_complex = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    Z, W, F, dW = np.empty((3, n)), np.empty((3, n)), np.empty((3, n)), np.empty((3, n))
    rhs_complex = np.empty(n, dtype=np.complex128)
    y_new, f_new, work, fw, error, scale = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    ze, floor, delta, measured = np.empty(n), np.zeros(n), np.empty(n), np.empty(n)
    floor_due = True
    projected, found_projection = np.empty(n), np.zeros(4)
    analytic = control[ANALYTIC] != 0.0
    rows_work, pivots, column = np.empty((size, n)), np.empty(size, dtype=np.int64), np.empty(size)
    have_lu = False
    if memory[LU_STEP] != 0.0:  # resumed: the factors of the call before, made again for the same step (the same run as one straight through)
        have_lu = _radau_matrices(jac, memory[LU_STEP], lu_real, pivots_real, lu_complex, pivots_complex, stats) == 0
        stats[NLU] -= 2
    current_jac = memory[CURRENT_JAC] != 0.0
    t, h_abs = state[T], state[H]
    taken = 0
    while t < t_stop and t < t_bound and taken < pause:
        taken += 1
        min_step = MIN_STEP_SPACINGS * abs(np.nextafter(t, np.inf) - t)
        pending, bound = np.inf, np.inf  # the crossing located ahead, the next projection time (+inf: none)
        if switch is not None:
            pending = record[SWITCH_PENDING]
        if rows is not None:
            next_bound = int(projected_record[NEXT_BOUND])
            if next_bound < bounds.shape[0]:
                bound = bounds[next_bound]
        limit = min(t_bound, pending, bound)
        h_abs_start = h_abs
        if h_abs > max_step:
            h_abs, h_abs_old, error_old = max_step, np.nan, np.nan
        elif h_abs < min_step:
            h_abs, h_abs_old, error_old = min_step, np.nan, np.nan
        else:
            h_abs_old, error_old = memory[H_ABS_OLD], memory[ERROR_OLD]
        rejected, bad = False, False
        first = memory[HAVE_DENSE] == 0.0
        contraction = max(memory[CONTRACTION], _EPS) ** 0.8  # radau5.f: the last factor, relaxed toward 1
        converged, iterations, rate, error_norm, safety, t_new, h, h_wanted = False, 0, np.nan, 0.0, 1.0, t, 0.0, h_abs
        hop = False
        while True:
            if h_abs < min_step:
                state[T], state[H] = t, h_abs
                if bad or m == 0:
                    return NONFINITE if bad else STEP_COLLAPSE
                hop = True  # onto a surface where the forces jump: across it (`_hop`)
                break
            t_new = t + h_abs
            h_wanted = h_abs
            if t_new > limit or (limit < t_bound and limit - t_new <= 4 * _EPS * abs(limit)):
                t_new = limit  # the end, a projection time, or the crossing located (retaken: land on it, round-off apart)
            h = t_new - t
            h_abs = abs(h)
            converged = False
            while True:
                if not have_lu:
                    have_lu = _radau_matrices(jac, h, lu_real, pivots_real, lu_complex, pivots_complex, stats) == 0
                    memory[LU_STEP] = h if have_lu else 0.0
                    floor_due = True
                if have_lu:
                    if floor_due:  # once per factorization
                        if _radau_floor(accel, t, y, f, p, x, a, jac, lu_real, pivots_real, floor, delta, measured, work, fw, atol, rtol, newton_tol, stats):
                            state[T], state[H] = t, h
                            return SINGULAR
                        floor_due = False
                    for i in range(n):  # Newton's corrections converge to their round-off floor, not below
                        scale[i] = max(atol + abs(y[i]) * rtol, floor[i] / newton_tol)
                    for r in range(3):  # the predictor: the last step's collocation polynomial extrapolated (zero at the start)
                        if memory[HAVE_DENSE] != 0.0:
                            _radau_eval(memory[T_OLD], memory[STEP_OLD], y_old, dense, t + _RC[r] * h, work)
                            for i in range(n):
                                Z[r, i] = work[i] - y[i]
                        else:
                            for i in range(n):
                                Z[r, i] = 0.0
                    code, converged, iterations, rate, contraction = _radau_newton(
                        accel, t, y, h, Z, W, F, dW, scale, newton_tol, contraction, lu_real, pivots_real, lu_complex, pivots_complex, rhs_complex, work, p, x, a, stats
                    )
                    if code == SINGULAR:
                        state[T], state[H] = t, h
                        return SINGULAR
                    bad = code == NONFINITE
                if converged or current_jac:
                    break
                if _radau_jac(accel, jacobian, analytic, t, y, f, p, x, a, jac, work, fw, rows_work, pivots, column, stats):
                    state[T], state[H] = t, h
                    return SINGULAR
                current_jac = True
                have_lu = False
            if not converged:
                h_abs *= 0.5
                have_lu = False
                memory[LU_STEP] = 0.0
                stats[NREJECT] += 1
                rejected = True
                continue
            floored = False
            for i in range(n):
                y_new[i] = y[i] + Z[2, i]
                ze[i] = (_RE[0] * Z[0, i] + _RE[1] * Z[1, i] + _RE[2] * Z[2, i]) / h
                error[i] = f[i] + ze[i]
                scale[i] = atol + max(abs(y[i]), abs(y_new[i])) * rtol
                if floor[i] > scale[i]:
                    scale[i] = floor[i]
                    floored = True
            _lu_back(lu_real, pivots_real, error)
            error_norm = _rms(error, scale)
            safety = 0.9 * (2 * NEWTON_MAXITER + 1) / (2 * NEWTON_MAXITER + iterations)
            if error_norm > 1.0 and (rejected or first):  # the estimate once more, from f at y + err (Hairer's second estimate)
                for i in range(n):
                    work[i] = y[i] + error[i]
                if _rhs(accel, t, work, p, fw, x, a):
                    state[T], state[H] = t, h
                    return SINGULAR
                stats[NFEV] += 1
                for i in range(n):
                    error[i] = fw[i] + ze[i]
                _lu_back(lu_real, pivots_real, error)
                error_norm = _rms(error, scale)
            if not np.isfinite(error_norm) or not _finite(y_new):
                bad = True
                h_abs *= MIN_FACTOR
                have_lu = False
                memory[LU_STEP] = 0.0
                stats[NREJECT] += 1
                rejected = True
                continue
            if error_norm > 1.0:
                factor = _predict_factor(h_abs, h_abs_old, error_norm, error_old)
                h_abs *= max(MIN_FACTOR, safety * factor)
                have_lu = False
                memory[LU_STEP] = 0.0
                stats[NREJECT] += 1
                rejected = True
                continue
            break
        if switch is not None and hop:
            code, t_far = _hop(switch, accel, t, y, f, HOP_REACH * min_step, p, record, m, g_start, g_end, g_work, work, slope, y_new, f_new, x, a, stats)
            if code != RUNNING:
                return code
            code = _hopped(event, t, t_far, y, f, y_new, f_new, slope, ts, ys, p, x, a, state, stats, use_event)
            t = t_far
            if code == EVENT:
                state[H] = min_step
                return EVENT
            # restart as at a landing: J and the factors afresh, no predictor, no controller memory, scipy's initial step
            if _radau_afresh(accel, jacobian, analytic, t, y, f, p, x, a, jac, work, fw, rows_work, pivots, column, stats, memory):
                state[T], state[H] = t, min_step
                return SINGULAR
            current_jac, have_lu = True, False
            h_abs = _initial_step(accel, t, y, f, t_bound, max_step, _RADAU_ORDER, rtol, atol, p, x, a, stats)
            state[T], state[H] = t, h_abs
            continue
        arrived = False
        if switch is not None and m > 0:  # the switching functions: a crossing inside the step discards it (retaken to land there)
            arrived = t_new == pending
            if not arrived:
                switch(t_new, y_new, p, g_end)
                first, t_first = -1, t_new
                if _changed(switch, t, y, p, record, m, g_end, g_start):
                    for k in range(3):  # the step's collocation polynomial
                        for j in range(n):
                            trial[k, j] = Z[0, j] * _RP[0, k] + Z[1, j] * _RP[1, k] + Z[2, j] * _RP[2, k]
                    first, t_first = _earliest(switch, _RADAU_KIND, t, h, y, trial, p, record, m, g_end, g_start, g_work, work)
                if first >= 0 and t < t_first < t_new:  # discard the step: take it again to land on the crossing
                    _found(record, m, first, t_first, g_end, AHEAD)
                    stats[NREJECT] += 1
                    h_abs = t_first - t
                    have_lu = False  # the factors were for the step discarded
                    memory[LU_STEP] = 0.0
                    state[H] = h_abs  # a pause right here resumes with this step
                    continue
                if first >= 0:  # the crossing is at the step's end: it has landed there
                    arrived = True
                    _found(record, m, first, t_first, g_end, not AHEAD)
        landed = t_new == bound  # on a projection time: the state is projected there and the method restarts (before t_bound)
        recompute_jac = iterations > 2 and rate > JAC_RATE and not arrived and not (landed and t_new < t_bound)  # (a landing computes J afresh)
        factor = min(MAX_FACTOR, safety * _predict_factor(h_abs, h_abs_old, error_norm, error_old))
        if not recompute_jac and factor < KEEP_FACTOR:
            factor = 1.0
        else:
            have_lu = False
            memory[LU_STEP] = 0.0
        if _rhs(accel, t_new, y_new, p, f_new, x, a):
            state[T], state[H] = t, h
            return SINGULAR
        stats[NFEV] += 1
        if recompute_jac:
            if _radau_jac(accel, jacobian, analytic, t_new, y_new, f_new, p, x, a, jac, work, fw, rows_work, pivots, column, stats):
                state[T], state[H] = t_new, h
                return SINGULAR
            current_jac = True
        else:
            current_jac = False
        memory[CURRENT_JAC] = 1.0 if current_jac else 0.0
        memory[CONTRACTION] = contraction
        memory[H_ABS_OLD], memory[ERROR_OLD] = h_abs_start, error_norm
        for k in range(3):
            for i in range(n):
                dense[k, i] = Z[0, i] * _RP[0, k] + Z[1, i] * _RP[1, k] + Z[2, i] * _RP[2, k]
        for i in range(n):
            y_old[i] = y[i]
        memory[T_OLD], memory[STEP_OLD], memory[HAVE_DENSE] = t, h, 1.0
        stats[NSTEPS] += 1
        if floored:
            stats[FLOORED] += 1
        if t_new < limit:
            stats[HMIN] = min(stats[HMIN], h)
        stats[HMAX] = max(stats[HMAX], h)
        # samples and the event, on the collocation polynomial
        t_end_here = t_new
        found = False
        if use_event:
            g_new = event(t_new, y_new, p, x, a)
            if (state[EVENT_VALUE] < 0.0) != (g_new < 0.0) and state[EVENT_VALUE] != 0.0:
                found = True
                t_end_here = _radau_root(event, t, h, y_old, dense, t_new, p, x, a, work, state[EVENT_VALUE])
            else:
                state[EVENT_VALUE] = g_new
        j = int(state[NEXT_SAMPLE])
        while j < ts.shape[0] and ts[j] <= t_end_here:
            if ts[j] == t_new:
                for i in range(n):
                    ys[j, i] = y_new[i]
            else:
                _radau_eval(t, h, y_old, dense, ts[j], ys[j])
            j += 1
        state[NEXT_SAMPLE] = j
        if found:
            _radau_eval(t, h, y_old, dense, t_end_here, y)
            state[T], state[H] = t_end_here, h_abs * factor
            return EVENT
        for i in range(n):
            y[i] = y_new[i]
            f[i] = f_new[i]
        t = t_new
        h_abs *= factor
        if switch is not None and arrived:
            if _landed(switch, t, y, p, record, m, g_end):
                state[T], state[H] = t, h_abs
                return STEP_COLLAPSE
            # restart as radau_start (f = f(t, y) is fresh): J and the factors afresh, no predictor, no controller memory, scipy's initial step
            if _radau_afresh(accel, jacobian, analytic, t, y, f, p, x, a, jac, work, fw, rows_work, pivots, column, stats, memory):
                state[T], state[H] = t, h_abs
                return SINGULAR
            current_jac, have_lu = True, False
            h_abs = _initial_step(accel, t, y, f, t_bound, max_step, _RADAU_ORDER, rtol, atol, p, x, a, stats)
        elif switch is not None and m > 0:
            record[SWITCH_SINCE] += 1.0
            for i in range(m):
                record[SWITCH_HEAD + i] = g_end[i]
        if rows is not None and landed:
            h_abs = h_wanted * min(1.0, factor)  # the step size before it was shortened onto the projection time
            projected_record[PROJECTIONS] += 1.0
            failed = _project(rows, energy, t, y, p, holonomic, projected_record, projected, found_projection, x, a)
            _projected(failed, t, y, projected_record, projected, found_projection, state, ts, ys)
            if t < t_bound:  # restart as at a crossing (f at the projected state; J and the factors afresh, no predictor, no controller memory)
                if _rhs(accel, t, y, p, f, x, a):
                    state[T], state[H] = t, h_abs
                    return SINGULAR
                stats[NFEV] += 1
                if use_event:
                    state[EVENT_VALUE] = event(t, y, p, x, a)
                if _radau_afresh(accel, jacobian, analytic, t, y, f, p, x, a, jac, work, fw, rows_work, pivots, column, stats, memory):
                    state[T], state[H] = t, h_abs
                    return SINGULAR
                current_jac, have_lu = True, False
        state[T], state[H] = t, h_abs
    return DONE if t >= t_bound else RUNNING
