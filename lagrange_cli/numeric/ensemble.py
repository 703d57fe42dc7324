"""A batch of runs in one compiled call: the explicit Runge-Kutta loops of kernels.py over many
initial states and parameter vectors, so that a run costs its integration and nothing more.

Calling a compiled loop from Python resolves the types of the system's functions (passed as
first-class functions) on every call, a fraction of a millisecond: more than a short run itself.
`erk_batch()` is a loop compiled by numba that calls `erk_start` and `erk_run` for each row of a
batch, with the GIL released (threads run batches in parallel); `sections()` does the same for a
Poincaré section's runs, recording every crossing and going on from it. Like the kernels, its source is
written to the compile cache beside the kernels' copy (numeric/compile.py) and imported from
there, so that numba caches its machine code: it compiles once per machine, not per process.
"""

from __future__ import annotations

from typing import Any

from lagrange_cli.numeric import compile

SOURCE = '''"""The batch loop of lagrange's sweeps (generated from lagrange_cli/numeric/ensemble.py). Do not edit."""
import numpy as np
from numba import njit, types

from {kernels} import ACCEL_SIG, EVENT_SIG
from {kernels} import compiled as _compiled
from lagrange_cli.numeric.status import BUDGET, EVENT, EVENT_VALUE, HMIN, NSTEPS, RUNNING, SINGULAR, SIZE, STATE_SIZE, STATS_SIZE, T, T0, USE_EVENT, H

_start, _run = _compiled("erk_start"), _compiled("erk_run")
_F8, _I8 = types.float64, types.int64
# explicit types (the system's functions as first-class function types, as the kernels take them), so
# that the machine code cached by one process is found by the next
SIGNATURE = types.Tuple((_I8[::1], _F8[::1], _F8[:, ::1], _F8[:, :, ::1], _I8[::1]))(
    _I8, _F8[:, ::1], _F8[:, ::1], _F8[::1], _F8[::1], _I8, types.FunctionType(ACCEL_SIG), types.FunctionType(EVENT_SIG)
)


@njit(SIGNATURE, cache=True, nogil=True, error_model="numpy")
def batch(pair, y0s, ps, control, ts, budget, accel, event):
    """Run b of the batch from y0s[b] with parameters ps[b] at control[T0]: (codes, t_last, y_last, ys, nsteps)."""
    count, n = y0s.shape
    codes = np.empty(count, dtype=np.int64)
    t_last = np.empty(count)
    y_last = np.empty((count, n))
    ys = np.full((count, ts.shape[0], n), np.nan)
    nsteps = np.zeros(count, dtype=np.int64)
    size = int(control[SIZE])
    x, a = np.empty(size), np.empty((size, size))
    for b in range(count):
        y = y0s[b].copy()
        f = np.empty(n)
        p = ps[b].copy()
        stats = np.zeros(STATS_SIZE)
        stats[HMIN] = np.inf
        state = np.zeros(STATE_SIZE)
        samples = np.full((ts.shape[0], n), np.nan)
        h0 = _start(pair, control[T0], y, f, control, p, stats, accel)
        state[T] = control[T0]
        if h0 < 0:
            code = SINGULAR
        else:
            state[H] = h0
            state[EVENT_VALUE] = event(control[T0], y, p, x, a) if control[USE_EVENT] != 0.0 else 1.0
            code = _run(pair, y, f, state, control, ts, samples, p, stats, accel, event)
            while code == RUNNING:
                if stats[NSTEPS] >= budget:
                    code = BUDGET
                    break
                code = _run(pair, y, f, state, control, ts, samples, p, stats, accel, event)
        codes[b] = code
        t_last[b] = state[T]
        y_last[b] = y
        ys[b] = samples
        nsteps[b] = int(stats[NSTEPS])
    return codes, t_last, y_last, ys, nsteps


SECTIONS_SIGNATURE = types.Tuple((_I8[::1], _F8[::1], _F8[:, ::1], _I8[::1], _F8[::1], _F8[:, ::1]))(
    _I8, _F8[:, ::1], _F8[:, ::1], _F8[::1], _F8[::1], _I8, _I8, types.FunctionType(ACCEL_SIG), types.FunctionType(EVENT_SIG)
)


@njit(SECTIONS_SIGNATURE, cache=True, nogil=True, error_model="numpy")
def sections(pair, y0s, ps, control, ts, budget, limit, accel, event):
    """Runs through a Poincare section (the event is the surface): each crossing is recorded and the run goes on,
    from the crossing with f and the first step computed afresh, up to `limit` crossings a run (the run ends with
    EVENT at the crossing after them). Returns (codes, t_last, y_last, counts, times, states): run b's crossings
    are the counts[b] rows of times and states after those of the runs before it."""
    count, n = y0s.shape
    codes = np.empty(count, dtype=np.int64)
    t_last = np.empty(count)
    y_last = np.empty((count, n))
    counts = np.zeros(count, dtype=np.int64)
    capacity = max(16, 4 * count)
    times = np.empty(capacity)
    states = np.empty((capacity, n))
    total = 0
    size = int(control[SIZE])
    x, a = np.empty(size), np.empty((size, size))
    samples = np.full((ts.shape[0], n), np.nan)
    for b in range(count):
        y = y0s[b].copy()
        f = np.empty(n)
        p = ps[b].copy()
        stats = np.zeros(STATS_SIZE)
        stats[HMIN] = np.inf
        state = np.zeros(STATE_SIZE)
        samples[:, :] = np.nan
        found = 0
        h0 = _start(pair, control[T0], y, f, control, p, stats, accel)
        state[T] = control[T0]
        if h0 < 0:
            code = SINGULAR
        else:
            state[H] = h0
            state[EVENT_VALUE] = event(control[T0], y, p, x, a) if control[USE_EVENT] != 0.0 else 1.0
            while True:
                code = _run(pair, y, f, state, control, ts, samples, p, stats, accel, event)
                if code == RUNNING:
                    if stats[NSTEPS] >= budget:
                        code = BUDGET
                    else:
                        continue
                if code == EVENT and found < limit:
                    if total == capacity:
                        capacity *= 2
                        grown_times, grown_states = np.empty(capacity), np.empty((capacity, n))
                        grown_times[:total] = times[:total]
                        grown_states[:total] = states[:total]
                        times, states = grown_times, grown_states
                    times[total] = state[T]
                    states[total] = y
                    total += 1
                    found += 1
                    h = _start(pair, state[T], y, f, control, p, stats, accel)  # f at the crossing, a fresh step
                    if h < 0:
                        code = SINGULAR
                    else:
                        state[H], state[EVENT_VALUE] = h, 0.0  # 0: the next step does not see this crossing again
                        continue
                break
        codes[b] = code
        t_last[b] = state[T]
        y_last[b] = y
        counts[b] = found
    return codes, t_last, y_last, counts, times, states
'''


def erk_batch() -> Any:
    """batch(pair, y0s, ps, control, ts, budget, accel, event) -> (codes, t_last, y_last, ys, nsteps):
    row b of y0s and ps starts run b at control[T0]; ys[b] its samples at ts (NaN where not
    reached), codes[b] its status code (status.py), nsteps[b] its steps; budget the step budget
    of each run."""
    return _module().batch


def erk_sections() -> Any:
    """sections(pair, y0s, ps, control, ts, budget, limit, accel, event) -> (codes, t_last, y_last, counts,
    times, states): the runs of a Poincare section, every crossing kept (at most `limit` a run), as
    `sweep.Runner._erk` does run by run."""
    return _module().sections


def _module() -> Any:
    kernels = compile.kernels_module()
    return compile.cached_module("lagrange_ensemble_", SOURCE.replace("{kernels}", kernels.__name__))
