"""Runs in lockstep lanes (issue 18): a sweep's batch integrated LANES runs at a time, so that the
right-hand side is evaluated for all of them in one loop that the compiler turns into SIMD code.

The one-run loop (kernels.erk_run, called run by run by ensemble.batch) spends about 71% of a
run in the system's `accel` (a pivoted LU solve and libm's sin and cos, one state at a time) and
the rest in the Runge-Kutta loop. Neither can be vectorised within one run of a small system. Here:

- `source(model)`: the system's numba module (codegen.py) plus `_accel_lanes(T, Y, P, X, S, active)`,
  x = [q_ddot] for every lane l at once (structure of arrays: Y[i, l], P[i, l], X[i, l]), in one
  branch-free loop over the lanes: the same expressions (codegen's CSE) with sin and cos from
  `_vsin`/`_vcos` (fdlibm's argument reduction and polynomials: arithmetic only) and M x = F solved
  by the unrolled L D L^T of emit/jax.py (`unrolled_solve`, no pivoting: M is symmetric positive
  definite). S[l] > 0 says the lane's result stands; where it does not (a pivot below PIVOT x its
  diagonal entry, a non-finite result, or an angle beyond TRIG_LIMIT or not finite, where `_vsin`
  gives NaN), the lane is evaluated again by the scalar `_accel` (pivoted LU, libm), whose answer
  and singular flag count (S[l] = -1: singular). So a lane's singular or non-finite decision is the
  one-run path's.
- `lanes(...)`: the batch loop. DOP853 or RK45 with scipy's step control and initial step, each
  lane its own t, h and accept/reject (the same decisions, in the same floating-point order, as
  kernels.erk_run), the stages and error norms computed over the lanes in vectorisable loops; a
  lane whose run ended (done, singular, non-finite, step collapse, budget) is refilled with the
  batch's next run. Its first evaluation and step size (kernels.erk_start) and the dense output at
  samples (kernels._erk_dense, 3 more evaluations) are the one-run path's scalar code.

With the same right-hand side, each lane's run is the one-run loop's run bit for bit (tested, any
number of lanes). The lanes' right-hand side differs from `_accel` by round-off (L D L^T against
LU, polynomials against libm, within 1 ulp), so runs take the same steps except where round-off
tips an accept/reject decision (the error estimate cancels about 9 digits): on regular double-pendulum
runs 91% of final states within 1e-12 of the one-run path (median 3.7e-15), all within 1.6e-9 at
rtol 1e-9; on chaotic runs the difference grows as any round-off does, within the tolerance's error.

Covered: unconstrained systems without inputs, at most MAX_COORDINATES coordinates, no event
(`--until`) and no section. Everything else (and a system whose generated code is too long) runs on
ensemble.batch as before: `Runner.lanes_entry` is None then.
"""

from __future__ import annotations

import re
from typing import Any

from lagrange_cli.emit import python as emit_python
from lagrange_cli.emit.jax import COSINE, SINE, unrolled_solve
from lagrange_cli.emit.python import define
from lagrange_cli.model import Model
from lagrange_cli.numeric import codegen, compile

LANES = 32
"""Runs integrated together: four AVX-512 registers of 8 doubles (measured: 8 lanes 2.2x, 16 lanes 3.1-4.0x, 32 lanes
4.0-4.8x, 64 lanes 4.3-4.6x the run-by-run batch on 250-1000 runs; fewer lanes pay the loop's per-call overhead, more
lanes idle longer while a batch's last runs finish)."""
MAX_COORDINATES = 8
"""The largest system given lanes (its L D L^T is unrolled into the lane loop)."""
PIVOT = 1e-6
"""A lane whose L D L^T pivot D_j is not above PIVOT x M_jj is handed to the scalar `_accel`
(whose pivoted LU decides whether M is singular: below 1e-13 of a row's largest entry)."""
TRIG_LIMIT = 1.6e6
"""`_vsin`/`_vcos` reduce |x| < TRIG_LIMIT (k = round(2x/pi) < 2^20, so k times the first two
33-bit parts of pi/2 is exact); beyond it, or for NaN or inf, they give NaN and the lane is
evaluated by libm (through the scalar `_accel`)."""

_TRIG = re.compile(r"(?<![\w.])(sin|cos)\(")
_PARAMETER = re.compile(r"^(\w+) = _p\[(\d+)\]$")
_STATE = re.compile(r"^(\w+) = _y\[(\d+)\]$")


def _horner(coefficients: tuple[str, ...]) -> str:
    text = coefficients[-1]
    for c in reversed(coefficients[:-1]):
        text = f"{c} + _z * ({text})"
    return text


def trig_source() -> str:
    """`_vsin` and `_vcos`, inlined into the lane loop (numba `inline="always"`)."""
    reduction = [
        "_k = (x * 0.6366197723675814 + 6755399441055744.0) - 6755399441055744.0",
        f"_near = abs(x) < {TRIG_LIMIT!r}",
        "_k = _k if _near else 0.0",
        "_t = x - _k * 1.5707963267341256",
        "_w = _k * 6.077100506303966e-11",
        "_a = _t - _w",
        "_b = _a - _t",
        "_e = (_t - (_a - _b)) + (-_w - _b)",
        "_w = _k * 2.0222662487111665e-21",
        "_h = _a - _w",
        "_b = _h - _a",
        "_e = (_e + ((_a - (_h - _b)) + (-_w - _b))) - _k * 8.47842766036889956997e-32",
        "_r = _h + _e",
        "_y = _e - (_r - _h)",
        "_z = _r * _r",
        "_n = int(_k) & 3",
    ]
    sine_kernel = ["_v = _z * _r", f"_q = {_horner(SINE[1:])}", f"_s = _r - ((_z * (0.5 * _y - _v * _q) - _y) - _v * {SINE[0]})"]
    cosine_kernel = [f"_q = _z * ({_horner(COSINE)})", "_hz = 0.5 * _z", "_w = 1.0 - _hz", "_c = _w + (((1.0 - _w) - _hz) + (_z * _q - _r * _y))"]
    sine = [*reduction, *sine_kernel, *cosine_kernel, "_v = _c if _n & 1 else _s", "_v = -_v if _n & 2 else _v", "return _v if _near else numpy.nan"]
    cosine = [*reduction, *sine_kernel, *cosine_kernel, "_v = _s if _n & 1 else _c", "_v = -_v if (_n + 1) & 2 else _v", "return _v if _near else numpy.nan"]
    doc = (
        "{} of x by fdlibm's reduction (r + y = x - k pi/2 in double-double, pi/2 in three exact 33-bit parts and a tail)\n"
        "and its kernels __kernel_sin and __kernel_cos on |r| <= pi/4 (within 1 ulp; measured: tests/test_sweep_lanes.py): arithmetic\n"
        "only, so that a loop over lanes vectorises; NaN for |x| >= TRIG_LIMIT or x not finite (the caller then uses libm)."
    )
    decorator = '@_njit(inline="always", error_model="numpy")\n'
    return decorator + define("_vsin", "x", doc.format("sin"), sine) + "\n\n\n" + decorator + define("_vcos", "x", doc.format("cos"), cosine)


def lane_function(generator: codegen.Generator) -> str | None:
    """`_accel_lanes` of the generator's model, None when the model is not covered (module docstring)."""
    model, n = generator.model, generator.n
    if generator.k or model.inputs or n > MAX_COORDINATES:
        return None
    if any(generator.forms.mass[i][i] == 0 for i in range(n)):
        return None
    exprs = [*generator.mass, *generator.forms.forcing]
    lines, results = generator.block(exprs)
    if len(lines) > emit_python.SPLIT:
        return None
    inputs = []
    for line in generator.unpack(exprs):
        parameter, state = _PARAMETER.match(line), _STATE.match(line)
        if parameter:
            inputs.append(f"{parameter[1]} = _P[{parameter[2]}, _l]")
        elif state:
            inputs.append(f"{state[1]} = _Y[{state[2]}, _l]")
        else:  # pragma: no cover - unpack writes only these two forms
            return None
    mass_codes = dict(zip(generator.upper, results[: len(generator.mass)], strict=True))
    zero = {ij for ij, expr in zip(generator.upper, generator.mass, strict=True) if expr == 0}
    mass = {ij: (None if ij in zero else code) for ij, code in mass_codes.items()}
    forcing = [None if expr == 0 else code for expr, code in zip(generator.forms.forcing, results[len(generator.mass) :], strict=True)]
    solved = unrolled_solve(n, mass, forcing, [], [])
    body = ["t = _T[_l]", *inputs, *(_TRIG.sub(lambda m: f"_v{m[1]}(", line) for line in lines), *solved.lines]
    body += [f"_X[{i}, _l] = {v}" for i, v in enumerate(solved.results)]
    margins = [f"({d}) - {PIVOT!r} * abs({mass_codes[(i, i)]})" for i, d in enumerate(solved.pivots)]
    margin = margins[0] if n == 1 else f"min({', '.join(margins)})"
    body.append(f"_S[_l] = {margin} + " + " + ".join(f"({v} - {v})" for v in solved.results))
    loop = ["for _l in range(_Y.shape[1]):", *(f"    {line}" for line in body)]
    fallback = [
        "for _l in range(_Y.shape[1]):",
        "    if _active[_l] != 0 and not _S[_l] > 0.0:",
        "        _x, _a = numpy.empty(_SIZE), numpy.empty((_SIZE, _SIZE))",
        "        _status = _accel(_T[_l], numpy.ascontiguousarray(_Y[:, _l]), numpy.ascontiguousarray(_P[:, _l]), _x, _a)",
        "        _S[_l] = -1.0 if _status else 1.0",
        "        for _i in range(_SIZE):",
        "            _X[_i, _l] = _x[_i]",
        "return 0",
    ]
    doc = (
        "X[:, l] = q_ddot at (T[l], Y[:, l], P[:, l]) for every lane l; S[l] > 0: computed here, 1: by the scalar\n"
        "_accel (for active lanes where this loop's result is in doubt), -1: singular (by _accel)."
    )
    lanewise = [
        "_T, _S, _active = numpy.full(1, t), numpy.empty(1), numpy.ones(1, dtype=numpy.int64)",
        "_X = numpy.empty((_SIZE, 1))",
        "_accel_lanes(_T, _y.copy().reshape((_y.shape[0], 1)), _p.copy().reshape((_p.shape[0], 1)), _X, _S, _active)",
        "for _i in range(_SIZE):",
        "    _x[_i] = _X[_i, 0]",
        "return 1 if _S[0] < 0.0 else 0",
    ]
    one = define("_accel_lane", "t, _y, _p, _x, _a", "`_accel`'s signature and the lane arithmetic of `_accel_lanes` (one lane): for tests of the lane loop.", lanewise)
    return define("_accel_lanes", "_T, _Y, _P, _X, _S, _active", doc, [*loop, *fallback]) + "\n\n" + one


def source(model: Model) -> str | None:
    """The numba module of `model` (compile.module_source) with `_vsin`, `_vcos` and `_accel_lanes`; None when not covered."""
    base = compile.module_source(model, "numba", False, None)
    generator = codegen.Generator(model, "numba")
    generator.tables = []
    lanes = lane_function(generator)
    if lanes is None:
        return None
    head, footer = base.split(compile.JIT_FOOTER)
    assert footer == ""
    head = head.replace("\n\nfrom ", "\n\nimport numpy\nfrom numba import njit as _njit\nfrom ", 1)
    return head + "\n\n" + trig_source() + "\n\n\n" + lanes + "\n" + compile.JIT_FOOTER


def build(model: Model) -> Any:
    """The lane module of `model` (compiled when first used, cached), or None when not covered."""
    text = source(model)
    if text is None:
        return None
    compile.kernels_module()  # the module imports the kernels' lu_solve
    return compile.cached_module("lagrange_lanes_", text)


LOOP = '''"""The lane loop of lagrange's sweeps (generated from lagrange_cli/numeric/lanes.py). Do not edit."""
import numpy as np
from numba import njit, types

from {kernels} import ACCEL_SIG, EVENT_SIG, PAUSE_STEPS
from {kernels} import _DOP, _DOP_A, _DOP_B, _DOP_C, _DOP_E3, _DOP_E5, _DENSE, _ERROR_ORDER, _RK45_A, _RK45_B, _RK45_C, _RK45_E, _ROWS, _STAGES
from {kernels} import _erk_dense, _erk_eval
from {kernels} import compiled as _compiled
from lagrange_cli.numeric.status import SIZE, ATOL, BUDGET, DONE, HMIN, MAX_FACTOR, MAX_STEP, MIN_FACTOR, MIN_STEP_SPACINGS, NONFINITE, NSTEPS, RTOL, SAFETY, SINGULAR, STATS_SIZE, STEP_COLLAPSE, T0, T_BOUND

_start = _compiled("erk_start")
_F8, _I8 = types.float64, types.int64
LANES_SIG = _I8(_F8[::1], _F8[:, ::1], _F8[:, ::1], _F8[:, ::1], _F8[::1], _I8[::1])
SIGNATURE = types.Tuple((_I8[::1], _F8[::1], _F8[:, ::1], _F8[:, :, ::1], _I8[::1], _I8))(
    _I8, _F8[:, ::1], _F8[:, ::1], _F8[::1], _F8[::1], _I8, _I8, types.FunctionType(ACCEL_SIG), types.FunctionType(LANES_SIG)
)


@njit(cache=True, error_model="numpy")
def _finish(l, code, codes, t_last, y_last, nsteps, Y, Tl, run, steps, active):
    b = run[l]
    codes[b] = code
    t_last[b] = Tl[l]
    for i in range(Y.shape[0]):
        y_last[b, i] = Y[i, l]
    nsteps[b] = steps[l]
    active[l] = 0
    run[l] = -1


@njit(cache=True, error_model="numpy")
def _fill(l, following, pair, y0s, ps, control, t0, t_bound, codes, t_last, y_last, nsteps, Y, F, P, Tl, Habs, run, active, fresh, rejected, bad, steps, next_sample, y, f, p, stats, accel):
    """Start the batch's next runs in lane l until one needs steps (a run singular at t0, or with nothing to
    integrate, ends here): (the run after it, 1 when lane l is running one)."""
    count, n = y0s.shape
    while following < count:
        b = following
        following += 1
        for i in range(n):
            y[i] = y0s[b, i]
        for i in range(ps.shape[1]):
            p[i] = ps[b, i]
        stats[:] = 0.0
        stats[HMIN] = np.inf
        h0 = _start(pair, t0, y, f, control, p, stats, accel)
        if h0 < 0 or not t0 < t_bound:
            codes[b] = SINGULAR if h0 < 0 else DONE
            t_last[b] = t0
            y_last[b] = y
            nsteps[b] = 0
            continue
        for i in range(n):
            Y[i, l], F[i, l] = y[i], f[i]
        for i in range(p.shape[0]):
            P[i, l] = p[i]
        Tl[l], Habs[l] = t0, h0
        run[l], active[l], steps[l], next_sample[l] = b, 1, 0, 0
        fresh[l], rejected[l], bad[l] = True, False, False
        return following, 1
    return following, 0


@njit(SIGNATURE, cache=True, nogil=True, error_model="numpy")
def lanes(pair, y0s, ps, control, ts, budget, width, accel, accel_lanes):
    """ensemble.batch's runs (no event), `width` at a time in lockstep lanes: (codes, t_last, y_last, ys, nsteps, evaluations),
    evaluations counting lane evaluations of accel_lanes (width per call)."""
    count, n = y0s.shape
    half = n // 2
    npar = ps.shape[1]
    codes = np.empty(count, dtype=np.int64)
    t_last = np.empty(count)
    y_last = np.empty((count, n))
    ys = np.full((count, ts.shape[0], n), np.nan)
    nsteps = np.zeros(count, dtype=np.int64)
    rtol, atol, max_step, t_bound, t0 = control[RTOL], control[ATOL], control[MAX_STEP], control[T_BOUND], control[T0]
    size = x_size = int(control[SIZE])
    stages, rows = _STAGES[pair], _ROWS[pair]
    A, B, C = (_DOP_A, _DOP_B, _DOP_C) if pair == _DOP else (_RK45_A, _RK45_B, _RK45_C)
    exponent = -1.0 / (_ERROR_ORDER[pair] + 1.0)
    L = width
    Y, F, Ynew = np.zeros((n, L)), np.zeros((n, L)), np.zeros((n, L))
    K = np.zeros((rows, n, L))
    X, P = np.zeros((size, L)), np.zeros((npar, L))
    S, Tl, Ts, Hl, Habs, D = np.ones(L), np.zeros(L), np.zeros(L), np.zeros(L), np.zeros(L), np.zeros(L)
    E5, E3, Err5, Err3, MinStep = np.zeros(L), np.zeros(L), np.zeros(L), np.zeros(L), np.zeros(L)
    run = np.full(L, -1, dtype=np.int64)
    active = np.zeros(L, dtype=np.int64)
    singular = np.zeros(L, dtype=np.int64)
    stepping = np.zeros(L, dtype=np.int64)
    fresh = np.ones(L, dtype=np.bool_)
    rejected = np.zeros(L, dtype=np.bool_)
    bad = np.zeros(L, dtype=np.bool_)
    steps = np.zeros(L, dtype=np.int64)
    next_sample = np.zeros(L, dtype=np.int64)
    y, f, p = np.empty(n), np.empty(n), np.empty(npar)
    y_new, f_new = np.empty(n), np.empty(n)
    Kl = np.empty((rows, n))
    coef = np.empty((_DENSE[pair], n))
    x, a = np.empty(x_size), np.empty((x_size, x_size))
    stats = np.zeros(STATS_SIZE)
    evaluations = 0
    following = 0
    live = 0
    l = 0
    while l < L:  # fill the lanes
        following, started = _fill(l, following, pair, y0s, ps, control, t0, t_bound, codes, t_last, y_last, nsteps, Y, F, P, Tl, Habs, run, active, fresh, rejected, bad, steps, next_sample, y, f, p, stats, accel)
        live += started
        l += 1
    while live > 0:
        for l in range(L):
            stepping[l] = 0
            if active[l] != 0 and fresh[l]:
                t = Tl[l]
                MinStep[l] = MIN_STEP_SPACINGS * abs(np.nextafter(t, np.inf) - t)
                Habs[l] = min(max(Habs[l], MinStep[l]), max_step)
                rejected[l], bad[l] = False, False
            if active[l] != 0:
                if Habs[l] < MinStep[l]:
                    _finish(l, NONFINITE if bad[l] else STEP_COLLAPSE, codes, t_last, y_last, nsteps, Y, Tl, run, steps, active)
                    live -= 1
                    following, started = _fill(l, following, pair, y0s, ps, control, t0, t_bound, codes, t_last, y_last, nsteps, Y, F, P, Tl, Habs, run, active, fresh, rejected, bad, steps, next_sample, y, f, p, stats, accel)
                    live += started
                    continue  # the refilled lane steps with the next round
                t = Tl[l]
                Hl[l] = min(t + Habs[l], t_bound) - t
                stepping[l] = 1
            else:
                Hl[l] = 0.0
            singular[l] = 0
        if live == 0:
            break
        for i in range(n):
            for l in range(L):
                K[0, i, l] = F[i, l]
        for s in range(1, stages + 1):
            last = s == stages
            for i in range(n):
                for l in range(L):
                    D[l] = 0.0
                for j in range(s):
                    c = B[j] if last else A[s, j]
                    for l in range(L):
                        D[l] += c * K[j, i, l]
                for l in range(L):
                    Ynew[i, l] = Y[i, l] + Hl[l] * D[l]
            cs = 1.0 if last else C[s]
            for l in range(L):
                Ts[l] = Tl[l] + cs * Hl[l] if not last else Tl[l] + Hl[l]
            accel_lanes(Ts, Ynew, P, X, S, stepping)
            evaluations += L
            for l in range(L):
                if S[l] < 0.0:
                    singular[l] = 1
            for i in range(half):
                for l in range(L):
                    K[s, i, l] = Ynew[half + i, l]
                    K[s, half + i, l] = X[i, l]
        # the error norms (kernels._erk_error, same order of operations)
        for l in range(L):
            Err5[l], Err3[l] = 0.0, 0.0
        for i in range(n):
            for l in range(L):
                E5[l], E3[l] = 0.0, 0.0
            if pair == _DOP:
                for j in range(stages + 1):
                    c5, c3 = _DOP_E5[j], _DOP_E3[j]
                    for l in range(L):
                        E5[l] += c5 * K[j, i, l]
                        E3[l] += c3 * K[j, i, l]
            else:
                for j in range(rows):
                    c5 = _RK45_E[j]
                    for l in range(L):
                        E5[l] += c5 * K[j, i, l]
            for l in range(L):
                scale = atol + max(abs(Y[i, l]), abs(Ynew[i, l])) * rtol
                if pair == _DOP:
                    Err5[l] += (E5[l] / scale) ** 2
                    Err3[l] += (E3[l] / scale) ** 2
                else:
                    Err5[l] += (E5[l] * Hl[l] / scale) ** 2
        for l in range(L):
            if stepping[l] == 0:
                continue
            b = run[l]
            t, h = Tl[l], Hl[l]
            if singular[l] != 0:
                _finish(l, SINGULAR, codes, t_last, y_last, nsteps, Y, Tl, run, steps, active)
                live -= 1
                following, started = _fill(l, following, pair, y0s, ps, control, t0, t_bound, codes, t_last, y_last, nsteps, Y, F, P, Tl, Habs, run, active, fresh, rejected, bad, steps, next_sample, y, f, p, stats, accel)
                live += started
                continue
            if pair == _DOP:
                err5, err3 = Err5[l], Err3[l]
                if err5 == 0.0 and err3 == 0.0:
                    error = 0.0
                else:
                    error = abs(h) * err5 / (n * (err5 + 0.01 * err3)) ** 0.5
            else:
                error = (Err5[l] / n) ** 0.5
            finite = True
            for i in range(n):
                if not np.isfinite(Ynew[i, l]):
                    finite = False
            bad[l] = not (np.isfinite(error) and finite)
            if not (error < 1.0 and not bad[l]):
                Habs[l] *= MIN_FACTOR if bad[l] else max(MIN_FACTOR, SAFETY * error**exponent)
                rejected[l] = True
                fresh[l] = False
                continue
            factor = MAX_FACTOR if error == 0.0 else min(MAX_FACTOR, SAFETY * error**exponent)
            if rejected[l]:
                factor = min(1.0, factor)
            steps[l] += 1
            t_new = min(t + Habs[l], t_bound)
            j = next_sample[l]
            if j < ts.shape[0] and ts[j] <= t_new:
                for i in range(n):
                    y[i], y_new[i] = Y[i, l], Ynew[i, l]
                    f_new[i] = K[stages, i, l]
                    for r in range(stages + 1):
                        Kl[r, i] = K[r, i, l]
                for i in range(npar):
                    p[i] = P[i, l]
                if _erk_dense(accel, pair, t, y, y_new, f_new, h, Kl, coef, p, x, a, stats):
                    _finish(l, SINGULAR, codes, t_last, y_last, nsteps, Y, Tl, run, steps, active)
                    live -= 1
                    following, started = _fill(l, following, pair, y0s, ps, control, t0, t_bound, codes, t_last, y_last, nsteps, Y, F, P, Tl, Habs, run, active, fresh, rejected, bad, steps, next_sample, y, f, p, stats, accel)
                    live += started
                    continue
                while j < ts.shape[0] and ts[j] <= t_new:
                    _erk_eval(pair, t, h, y, coef, ts[j], ys[b, j])
                    j += 1
                next_sample[l] = j
            for i in range(n):
                F[i, l] = K[stages, i, l]
                Y[i, l] = Ynew[i, l]
            Tl[l] = t_new
            Habs[l] *= factor
            fresh[l] = True
            code = -1
            if not t_new < t_bound:
                code = DONE
            elif steps[l] % PAUSE_STEPS == 0 and steps[l] >= budget:
                code = BUDGET
            if code >= 0:
                _finish(l, code, codes, t_last, y_last, nsteps, Y, Tl, run, steps, active)
                live -= 1
                following, started = _fill(l, following, pair, y0s, ps, control, t0, t_bound, codes, t_last, y_last, nsteps, Y, F, P, Tl, Habs, run, active, fresh, rejected, bad, steps, next_sample, y, f, p, stats, accel)
                live += started
    return codes, t_last, y_last, ys, nsteps, evaluations
'''


def loop_module() -> Any:
    """The compiled lane loop's module (its `lanes` and `LANES_SIG`, the signature of `_accel_lanes`)."""
    kernels = compile.kernels_module()
    return compile.cached_module("lagrange_lanes_loop_", LOOP.replace("{kernels}", kernels.__name__))


def lane_loop() -> Any:
    """lanes(pair, y0s, ps, control, ts, budget, width, accel, accel_lanes) -> (codes, t_last, y_last, ys, nsteps,
    evaluations): ensemble.batch's runs and results (no event) `width` at a time in lockstep lanes; `accel` (the
    system's scalar `_accel`) gives each run's first evaluation and step and the dense output at samples."""
    return loop_module().lanes
