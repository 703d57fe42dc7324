"""Sweeps in lockstep lanes (numeric/lanes.py): the vectorised sin and cos, the lane loop against the
one-run loop, failed runs, and which sweeps fall back to the run-by-run batch."""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np
import pytest

from lagrange_cli import derive, spec
from lagrange_cli import sweep as library
from lagrange_cli.numeric import compile, integrators, lanes
from lagrange_cli.numeric import status as st
from lagrange_cli.numeric.ensemble import erk_batch
from lagrange_cli.sweep import Axis

pytest.importorskip("numba")


def model(name: str):  # type: ignore[no-untyped-def]
    return derive.derive(spec.load(spec.resolve(name)))


class Parts:
    """A system's compiled pieces: the scalar `_accel` (pivoted LU, libm), `_accel_lane` (the lane arithmetic, one state),
    `_accel_lanes`, `_event`, and the two batch loops."""

    def __init__(self, name: str) -> None:
        self.model = model(name)
        numba = compile.build(self.model, "numba")
        kernels = numba.kernels
        assert kernels is not None
        self.module = lanes.build(self.model)
        assert self.module is not None
        self.accel = numba.module._accel
        self.accel.compile(kernels.ACCEL_SIG.args)
        self.event = numba.module._event
        self.event.compile(kernels.EVENT_SIG.args)
        self.lane = self.module._accel_lane
        self.lane.compile(kernels.ACCEL_SIG.args)
        self.lanes = self.module._accel_lanes
        self.lanes.compile(lanes.loop_module().LANES_SIG.args)
        self.size = numba.module._SIZE
        self.batch, self.loop = erk_batch(), lanes.lane_loop()

    def control(self, t_end: float, rtol: float = 1e-9, atol: float = 1e-12) -> np.ndarray:
        control = np.zeros(st.CONTROL_SIZE)
        control[st.RTOL], control[st.ATOL], control[st.MAX_STEP] = rtol, atol, math.inf
        control[st.T_BOUND] = control[st.T_STOP] = t_end
        control[st.SIZE] = self.size
        return control


_PARTS: dict[str, Parts] = {}


def parts(name: str) -> Parts:
    if name not in _PARTS:
        _PARTS[name] = Parts(name)
    return _PARTS[name]


def pendulum_starts(count: int, spread: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Double-pendulum states (theta, phi at rest in [-spread, spread]) and its file's parameters."""
    rng = np.random.default_rng(seed)
    y0s = np.zeros((count, 4))
    y0s[:, :2] = rng.uniform(-spread, spread, (count, 2))
    m = parts("double_pendulum").model
    values = [float(p.value) for p in m.parameters]
    return y0s, np.tile(values, (count, 1))


# -- sin and cos ------------------------------------------------------------------------------------


def test_vectorised_sin_and_cos_are_within_one_ulp_of_libm() -> None:
    from numba import njit

    vsin, vcos = parts("double_pendulum").module._vsin, parts("double_pendulum").module._vcos

    @njit
    def both(xs, s, c):  # type: ignore[no-untyped-def]
        for i in range(xs.shape[0]):
            s[i] = vsin(xs[i])
            c[i] = vcos(xs[i])

    rng = np.random.default_rng(1)
    k = np.arange(1, 1_000_000, 97, dtype=float)
    near = k * (np.pi / 2)  # the hardest arguments: next to multiples of pi/2, where the result is tiny
    xs = np.concatenate([rng.uniform(-10, 10, 20000), rng.uniform(-1.5e6, 1.5e6, 20000), np.logspace(-300, 0, 2000), -np.logspace(-300, 0, 2000), near, np.nextafter(near, np.inf), [0.0, 5e-324]])
    s, c = np.empty_like(xs), np.empty_like(xs)
    both(xs, s, c)
    for mine, exact in ((s, np.array([math.sin(x) for x in xs])), (c, np.array([math.cos(x) for x in xs]))):
        ulps = np.abs(mine - exact) / np.spacing(np.abs(exact))
        assert ulps.max() <= 1.0
    special = np.array([math.nan, math.inf, -math.inf, lanes.TRIG_LIMIT, -1e300])
    s, c = np.empty(5), np.empty(5)
    both(special, s, c)
    assert np.isnan(s).all() and np.isnan(c).all()  # the lane is then evaluated by libm (the scalar _accel)


def test_the_lane_loop_is_vectorised() -> None:
    """LLVM's output for `_accel_lanes` has packed double arithmetic (AVX-512 zmm, AVX ymm or SSE2 xmm registers),
    the sines and cosines included."""
    from numba import njit

    signature = lanes.loop_module().LANES_SIG.args
    fresh = njit(error_model="numpy")(parts("double_pendulum").lanes.py_func)  # numba does not show cached code
    fresh.compile(signature)
    asm = fresh.inspect_asm(signature)
    assert re.search(r"\bv?mulpd\s", asm) and re.search(r"\bv?divpd\s", asm)
    llvm = fresh.inspect_llvm(signature)
    # sin and cos of both angles: their argument reduction (x 2/pi) on vectors of lanes loaded from Y (libm's sin
    # and cos appear only in the scalar _accel, linked in for the lanes in doubt)
    assert len(re.findall(r"fmul <(\d+) x double> %wide\.load\w*, .*0x3FE45F306DC9C883", llvm)) >= 2


def test_lane_results_fall_back_to_the_scalar_accel_where_in_doubt() -> None:
    """Far angles, NaN and a singular mass matrix (the elastic pendulum at l + x = 0) come from the scalar
    _accel: its values and its singular flag (S = -1)."""
    p = parts("elastic_pendulum")
    m = p.model
    values = [float(q.value) for q in m.parameters]
    names = list(m.coordinates)
    states = np.zeros((4, 4))
    states[:, names.index("theta")] = [0.3, 3e7, math.nan, 0.2]
    states[:, names.index("x")] = [0.1, 0.1, 0.1, -1.0]  # l = 1: the last is singular
    Y, P = np.ascontiguousarray(states.T), np.ascontiguousarray(np.tile(values, (4, 1)).T)
    X, S = np.empty((p.size, 4)), np.empty(4)
    p.lanes(np.zeros(4), Y, P, X, S, np.ones(4, dtype=np.int64))
    assert S[0] > 0 and S[1] == 1.0 and S[2] == 1.0 and S[3] == -1.0
    x, a = np.empty(p.size), np.empty((p.size, p.size))
    for lane in range(3):
        p.accel(0.0, states[lane].copy(), np.array(values), x, a)
        if lane == 0:
            assert np.allclose(X[:, 0], x, rtol=1e-14, atol=1e-14)
        else:
            assert np.array_equal(X[:, lane], x, equal_nan=True)


# -- the loop ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("pair", [1, 0])  # DOP853, RK45
def test_each_lane_is_the_one_run_loops_run(pair: int) -> None:
    """With the same right-hand side (`_accel_lane`: the lane arithmetic for one state), the lane loop and
    ensemble.batch (kernels.erk_run run by run) give identical runs: codes, final times and states, samples,
    steps, whatever the number of lanes (chaotic runs included: any difference would grow)."""
    p = parts("double_pendulum")
    y0s, ps = pendulum_starts(120, 2.0)
    ts = np.linspace(0.0, 5.0, 7)
    control = p.control(5.0)
    budget = integrators.MAX_STEPS["compiled"]
    one = p.batch(pair, y0s, ps, control, ts, budget, p.lane, p.event)
    for width in (1, 5, 32):
        got = p.loop(pair, y0s, ps, control, ts, budget, width, p.lane, p.lanes)
        for mine, theirs in zip(got[:5], one, strict=True):
            assert np.array_equal(mine, theirs, equal_nan=True)
        assert got[5] > 0 and got[5] % width == 0


def test_final_states_against_the_default_path() -> None:
    """Against the sweep's previous path (pivoted LU and libm sin and cos): the same statuses and final times; on
    regular runs (angles within 0.3) final states within 1e-12 (relative) in 91% of runs, median 3.7e-15 (measured):
    the rest took another step somewhere, where round-off tipped an accept/reject decision (the error estimate
    cancels about 9 digits, so the right-hand side's last bit moves it by ~1e-7), up to 1.6e-9 (tolerance 1e-9)."""
    p = parts("double_pendulum")
    y0s, ps = pendulum_starts(300, 0.3, seed=2)
    ts = np.array([0.0, 10.0])
    control = p.control(10.0)
    budget = integrators.MAX_STEPS["compiled"]
    one = p.batch(1, y0s, ps, control, ts, budget, p.accel, p.event)
    got = p.loop(1, y0s, ps, control, ts, budget, lanes.LANES, p.accel, p.lanes)
    assert np.array_equal(got[0], one[0]) and np.array_equal(got[1], one[1])
    difference = np.max(np.abs(got[2] - one[2]) / np.maximum(1.0, np.abs(one[2])), axis=1)
    assert np.median(difference) < 1e-13 and np.mean(difference <= 1e-12) > 0.8 and difference.max() < 1e-7


def test_failed_runs_come_back_with_their_reasons() -> None:
    """A singular start, a run that reaches a singular matrix or blows up, and a step budget: the rows (status,
    reason) of the lanes equal those of the run-by-run batch; the budget cuts both at the same step."""
    kepler = model("kepler")
    axes = [Axis("initial", "theta_dot", 0.0, 1.2, 4), Axis("initial", "r", 0.0, 1.0, 3)]  # r = 0: singular at t0
    options: dict[str, Any] = {"measures": ["final"], "t_end": 20, "method": "DOP853", "backend": "compiled", "batch": 5}
    with_lanes = library.sweep(kepler, axes, **options)
    assert any(r.lanes_entry is not None for r in library._RUNNERS.values() if r.model is kepler)
    try:
        library.LANES = False
        library._RUNNERS.clear()
        without = library.sweep(kepler, axes, **options)
    finally:
        library.LANES = True
        library._RUNNERS.clear()
    status, reason = with_lanes.columns.index("status"), with_lanes.columns.index("reason")
    assert [r[status] for r in with_lanes.rows] == [r[status] for r in without.rows]
    assert {r[status] for r in with_lanes.rows} == {"failed", "finished"}
    for mine, theirs in zip(with_lanes.rows, without.rows, strict=True):
        assert mine[reason].split(" at t =")[0] == theirs[reason].split(" at t =")[0]

    p = parts("double_pendulum")
    y0s, ps = pendulum_starts(3, 1.5)
    control = p.control(1e4, rtol=1e-12, atol=1e-14)  # far more than PAUSE_STEPS steps: the budget (1) stops them there
    one = p.batch(1, y0s, ps, control, np.array([0.0]), 1, p.lane, p.event)
    got = p.loop(1, y0s, ps, control, np.array([0.0]), 1, 4, p.lane, p.lanes)
    assert (one[0] == st.BUDGET).all() and (one[4] == st.PAUSE_STEPS).all()
    for mine, theirs in zip(got[:5], one, strict=True):
        assert np.array_equal(mine, theirs, equal_nan=True)


def test_what_falls_back_to_the_run_by_run_batch() -> None:
    """An event (--until), a section, kept constraints: ensemble.batch as before (Runner.lanes_entry None)."""
    pendulum = model("double_pendulum")
    axes = [Axis("initial", "theta", 0.1, 0.5, 2)]
    base = {"t_end": 2, "method": "DOP853", "backend": "compiled"}
    library.sweep(pendulum, axes, measures=["final"], **base)
    library.sweep(pendulum, axes, measures=["t_event"], until="theta", **base)
    library.sweep(model("elastic_pendulum"), [Axis("initial", "theta", 0.2, 0.4, 2)], section="theta=0, theta_dot>0", **{**base, "t_end": 10})
    runners = list(library._RUNNERS.values())
    assert any(r.lanes_entry is not None and r.model is pendulum for r in runners)
    assert all(r.lanes_entry is None for r in runners if r.settings.event is not None)
    constrained = model("pendulum_multiplier") if spec.resolve("pendulum_multiplier").exists() else None
    if constrained is not None:
        library.sweep(constrained, [Axis("set", "g", 9.0, 10.0, 2)], measures=["final"], **base)
        assert all(r.lanes_entry is None for r in library._RUNNERS.values() if r.model is constrained)


@pytest.mark.parametrize("name", ["chain_3", "heavy_top_offaxis_disk", "kapitza_pendulum"])
def test_lanes_agree_with_the_scalar_accel(name: str) -> None:
    """Three coordinates, a top whose mass matrix nears singular (a lane goes to the scalar accel), a driven
    (time-dependent) system: `_accel_lanes` equals `_accel` to round-off on 64 random states at t = 0.7, and says
    singular exactly where `_accel` does. (Measured on every bundled unconstrained system: within 2.1e-14.)"""
    m = model(name)
    module = lanes.build(m)
    assert module is not None
    numba = compile.build(m, "numba")
    rng = np.random.default_rng(0)
    count = 64
    Y = np.ascontiguousarray(rng.uniform(-1.5, 1.5, (2 * m.n, count)))
    P = np.ascontiguousarray(np.tile([float(p.value) for p in m.parameters], (count, 1)).T)
    X, S = np.empty((module._SIZE, count)), np.empty(count)
    module._accel_lanes(np.full(count, 0.7), Y, P, X, S, np.ones(count, dtype=np.int64))
    x, a = np.empty(module._SIZE), np.empty((module._SIZE, module._SIZE))
    for lane in range(count):
        singular = numba.module._accel(0.7, Y[:, lane].copy(), P[:, lane].copy(), x, a)
        assert (S[lane] == -1.0) == bool(singular)
        assert np.allclose(X[:, lane], x, rtol=1e-13, atol=1e-13)
