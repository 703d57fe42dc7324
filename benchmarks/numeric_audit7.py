"""Issue 15, audit 7: `simulate`, `accuracy` and `stress` on eight systems the project has not seen
(tests/numeric_audit7/*.yaml), against references computed here, independently of lagrange.

The harness is audit 4's, 5's and 6's (benchmarks/numeric_audit4.py: the runs, the re-run of every
recommendation by `simulate`, the error measure (maximum pointwise over 2001 samples), the table;
numeric_audit5.py: auto against each method's quickest run of the same true accuracy;
numeric_audit6.py: references by a chosen pair of scipy methods), pointed at this audit's files,
result and reference directories; only the systems and the exact linear references are new.
References (nothing of lagrange_cli is imported): plain sympy derivations from a Lagrangian,
Rayleigh function and generalized forces written here, in other coordinates where that makes them
independent (the rolling wheel with the rolling constraint eliminated, x only; the double pendulum
in angles from the upward vertical; the contact with sympy's Max and Heaviside rather than Abs and
sign), integrated by scipy's solve_ivp at rtol 1e-13 and confirmed by a second method. The two
linear systems (the charged particle in a strong field and a weak trap; the weakly damped coupled
oscillators over t = 1e5) are solved exactly, y(t) = V exp(Lambda t) V^-1 y0 from the derived
first-order matrix, checked against DOP853 1e-13 of the derived equations over [0, min(t_end, 1000)].

    cp -r WARM /tmp/audit7-cache-X   # a cache warmed by another system (kernels compiled, system new)
    PYTHONPATH=. LAGRANGE_CACHE_DIR=/tmp/audit7-cache-X .venv/bin/python benchmarks/numeric_audit7.py [--only NAME] [--json out.json]
    PYTHONPATH=. LAGRANGE_CACHE_DIR=/tmp/audit7-cache-X .venv/bin/python benchmarks/numeric_audit7.py --versus NAME --json versus.json
    PYTHONPATH=. LAGRANGE_CACHE_DIR=/tmp/audit7-cache-X .venv/bin/python benchmarks/numeric_audit7.py --extra extra.json [--only dp_upright,wheel]
    .venv/bin/python benchmarks/numeric_audit7.py --table out1.json,out2.json
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import sympy as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numeric_audit4
import numeric_audit5
import numeric_audit6
from numeric_audit3 import Ref, _error, _rhs, _syms, qd
from numeric_audit4 import System
from numeric_audit5 import _vel
from scipy.integrate import solve_ivp

ROOT = Path(__file__).resolve().parent.parent
AUDIT = ROOT / "tests" / "numeric_audit7"
t = sp.Symbol("t")
G = 9.81


def linear_matrix(s: System) -> np.ndarray:
    """The first-order matrix A of a linear, autonomous system (y' = A y), derived from its
    Lagrangian and Rayleigh function by plain sympy: M qdd = f(q, qd), A = [[0, I], [M^-1 df/dq, M^-1 df/dqd]]."""
    q, v = s.q, [qd(x) for x in s.q]
    n, L = len(q), s.T - s.V
    M = sp.Matrix(n, n, lambda i, j: sp.diff(L, v[i], v[j]))
    f = sp.Matrix([-sp.diff(s.D, v[i]) + sp.diff(L, q[i]) - sum(sp.diff(L, v[i], q[j]) * v[j] for j in range(n)) for i in range(n)])
    Minv = np.array(M.inv(), dtype=float)
    top = np.hstack([np.zeros((n, n)), np.eye(n)])
    bottom = Minv @ np.hstack([np.array(f.jacobian(q), dtype=float), np.array(f.jacobian(v), dtype=float)])
    return np.vstack([top, bottom])


def linear_exact(s: System, y0: list[float], ts: np.ndarray) -> np.ndarray:
    """y(t) = V exp(Lambda t) V^-1 y0 at the times ts (rows)."""
    lam, V = np.linalg.eig(linear_matrix(s))
    c = np.linalg.solve(V, np.asarray(y0, dtype=complex))
    return np.real(np.exp(np.outer(ts, lam)) * c @ V.T)


def systems() -> dict[str, System]:
    out: dict[str, System] = {}
    # 1. block on a vertical spring and a 4e4 damper, pendulum below, kicked upward
    y, th = _syms("y theta")
    M, m, ll, k, c = 2.0, 0.4, 0.6, 400.0, 4.0e4
    out["vertical_damper"] = System(
        "vertical_spring_pendulum_damper_4e4_kicked.yaml",
        [y, th],
        M / 2 * qd(y) ** 2 + m / 2 * (_vel(ll * sp.sin(th), [y, th]) ** 2 + _vel(y - ll * sp.cos(th), [y, th]) ** 2),
        k * y**2 / 2 + M * G * y + m * G * (y - ll * sp.cos(th)),
        [0.05, 1.0, 3.0, 0.0],
        True,
        lambda yy: yy,
        names=["y", "theta", "y_dot", "theta_dot"],
        D=c * qd(y) ** 2 / 2,
    )
    # 2. rolling wheel on a stiff damped spring, pendulum at the hub: rolling eliminated (x, theta)
    wx, wth = _syms("x theta")
    Mw, R, mb, lw, kw, cw = 1.0, 0.3, 0.5, 0.7, 1.0e6, 2.0e4

    def wheel_map(yy: np.ndarray) -> np.ndarray:
        x_, t_, xd, td = yy.T
        return np.column_stack([x_, x_ / R, t_, xd, xd / R, td])

    bx, by = wx + lw * sp.sin(wth), R - lw * sp.cos(wth)
    out["wheel"] = System(
        "wheel_rolling_kept_stiff_spring.yaml",
        [wx, wth],
        Mw / 2 * qd(wx) ** 2 + Mw * R**2 / 4 * (qd(wx) / R) ** 2 + mb / 2 * (_vel(bx, [wx, wth]) ** 2 + _vel(by, [wx, wth]) ** 2),
        kw * wx**2 / 2 + mb * G * by,
        [0.01, 0.8, 0.0, 0.0],
        True,
        wheel_map,
        D=cw * qd(wx) ** 2 / 2,
    )
    # 3. charged particle, B = 100, anisotropic trap: linear, exact
    px, py = _syms("x y")
    B = 100.0
    charged = System(
        "charged_particle_strong_field_anisotropic_trap.yaml",
        [px, py],
        (qd(px) ** 2 + qd(py) ** 2) / 2 + (-B * py / 2 * qd(px) + B * px / 2 * qd(py)),
        px**2 / 2 + 4 * py**2 / 2,
        [1.0, 0.0, 0.0, 5.0],
        False,
        lambda yy: yy,
        names=["x", "y", "x_dot", "y_dot"],
    )
    charged.exact = lambda ts, s=charged: linear_exact(s, s.y0, ts)
    out["charged"] = charged
    # 4. double pendulum near upright: reference in angles from the upward vertical
    a1, a2 = _syms("a1 a2")
    l1, l2 = 1.0, 0.8
    u1 = [-l1 * sp.sin(a1), l1 * sp.cos(a1)]
    u2 = [u1[0] - l2 * sp.sin(a2), u1[1] + l2 * sp.cos(a2)]
    out["dp_upright"] = System(
        "double_pendulum_near_upright.yaml",
        [a1, a2],
        sum(_vel(e, [a1, a2]) ** 2 for e in u1) / 2 + sum(_vel(e, [a1, a2]) ** 2 for e in u2) / 2,
        G * u1[1] + G * u2[1],
        [-0.001, 0.002, 0.0, 0.0],
        False,
        lambda yy: np.column_stack([yy[:, 0] + math.pi, yy[:, 1] + math.pi, yy[:, 2], yy[:, 3]]),
    )
    # 5. crane: rope reeled in, trolley on a damped spring (explicit time)
    cx, cth = _syms("x theta")
    Lr = 2.0 - 0.15 * t
    ex, ey = cx + Lr * sp.sin(cth), -Lr * sp.cos(cth)
    out["crane"] = System(
        "crane_reeling_in_on_sprung_trolley.yaml",
        [cx, cth],
        qd(cx) ** 2 / 2 + 0.5 / 2 * (_vel(ex, [cx, cth]) ** 2 + _vel(ey, [cx, cth]) ** 2),
        10.0 * cx**2 / 2 + 0.5 * G * ey,
        [0.0, 0.5, 0.0, 0.0],
        False,
        lambda yy: yy,
        names=["x", "theta", "x_dot", "theta_dot"],
        D=0.3 * qd(cx) ** 2 / 2,
    )
    # 6. half car with a stiff tire (3 DOF)
    hy, hp, hz = _syms("y phi z")
    Mb, Ib, mw, a, b, ks, cs, ks2, cs2, kt, ct = 500.0, 800.0, 40.0, 1.2, 1.5, 2.0e4, 1500.0, 2.5e4, 1500.0, 4.0e8, 4.0e5
    front = hy + a * sp.sin(hp) - hz
    rear = hy - b * sp.sin(hp)
    vq = [hy, hp, hz]
    out["half_car"] = System(
        "half_car_stiff_tire_3dof.yaml",
        vq,
        Mb / 2 * qd(hy) ** 2 + Ib / 2 * qd(hp) ** 2 + mw / 2 * qd(hz) ** 2,
        ks / 2 * front**2 + ks2 / 2 * rear**2 + kt / 2 * hz**2,
        [0.1, 0.05, 0.0, 0.0, 0.0, 0.0],
        True,
        lambda yy: yy,
        names=["y", "phi", "z", "y_dot", "phi_dot", "z_dot"],
        D=cs / 2 * _vel(front, vq) ** 2 + cs2 / 2 * _vel(rear, vq) ** 2 + ct / 2 * qd(hz) ** 2,
    )
    # 7. pendulum striking a sprung wall plate: contact with Max and Heaviside
    wt, ww = _syms("theta w")
    gap = sp.sin(wt) - 0.3 - ww
    gap_rate = _vel(gap, [wt, ww])
    out["wall"] = System(
        "pendulum_hits_sprung_wall_gated_damping.yaml",
        [wt, ww],
        (_vel(sp.sin(wt), [wt, ww]) ** 2 + _vel(-sp.cos(wt), [wt, ww]) ** 2) / 2 + 0.5 / 2 * qd(ww) ** 2,
        -G * sp.cos(wt) + 200.0 * ww**2 / 2 + 1.0e6 / 2 * sp.Max(0, gap) ** 2,
        [-1.2, 0.0, 0.0, 0.0],
        False,
        lambda yy: yy,
        names=["theta", "w", "theta_dot", "w_dot"],
        D=300.0 / 2 * sp.Heaviside(gap, sp.Rational(1, 2)) * gap_rate**2,
    )
    # 8. weakly damped coupled oscillators to t = 1e5: linear, exact
    o1, o2 = _syms("x1 x2")
    osc = System(
        "coupled_oscillators_weak_damping_t1e5.yaml",
        [o1, o2],
        qd(o1) ** 2 / 2 + 2.0 * qd(o2) ** 2 / 2,
        o1**2 / 2 + 3.0 * o2**2 / 2 + 0.5 * (o2 - o1) ** 2 / 2,
        [1.0, 0.0, 0.0, 0.5],
        False,
        lambda yy: yy,
        names=["x1", "x2", "x1_dot", "x2_dot"],
        D=2.0e-5 * (qd(o1) ** 2 + qd(o2) ** 2) / 2,
    )
    osc.exact = lambda ts, s=osc: linear_exact(s, s.y0, ts)
    out["weak_damping_1e5"] = osc
    return out


LINEAR = {"charged", "weak_damping_1e5"}


def _wall_sides() -> tuple[System, System]:
    """The pendulum and the sprung wall plate out of contact and in contact, each smooth: the
    contact's Max(0, gap) is gap and its Heaviside gate is 1 in contact, both are 0 out of it."""
    wt, ww = _syms("theta w")
    gap = sp.sin(wt) - 0.3 - ww
    gap_rate = _vel(gap, [wt, ww])
    T = (_vel(sp.sin(wt), [wt, ww]) ** 2 + _vel(-sp.cos(wt), [wt, ww]) ** 2) / 2 + 0.5 / 2 * qd(ww) ** 2
    V = -G * sp.cos(wt) + 200.0 * ww**2 / 2
    names = ["theta", "w", "theta_dot", "w_dot"]
    free = System("", [wt, ww], T, V, [], False, lambda yy: yy, names=names)
    contact = System("", [wt, ww], T, V + 1.0e6 / 2 * gap**2, [], False, lambda yy: yy, names=names, D=300.0 / 2 * gap_rate**2)
    return free, contact


MAX_STEP = 1e-4
"""the wall reference's largest step: contacts last about 2 ms (kc = 1e6), and a grazing one that begins
and ends within one step would go unseen (the event finder looks at the gap's sign at step ends)."""


def wall_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """The wall system integrated piece by piece between contact switches (gap = sin(theta) - 0.3 - w
    crossing 0, located by solve_ivp's event finder), each piece with its own smooth equations at
    rtol 1e-13 with steps of at most MAX_STEP, so that no step straddles the switch (a plain run fails there: the damper's gate jumps)."""
    free, contact = _wall_sides()
    rhs = {False: _rhs(free), True: _rhs(contact)}

    def gap(_t: float, y: np.ndarray) -> float:
        return float(math.sin(y[0]) - 0.3 - y[1])

    def entering(_t: float, y: np.ndarray) -> float:
        return gap(_t, y)

    def leaving(_t: float, y: np.ndarray) -> float:
        return gap(_t, y)

    # out of contact only an upward crossing ends the piece, in contact only a downward one: a
    # restart on the switch (gap ~ 1e-17 of either sign) does not end its own piece at once
    entering.terminal, entering.direction = True, 1.0  # type: ignore[attr-defined]
    leaving.terminal, leaving.direction = True, -1.0  # type: ignore[attr-defined]
    out = np.full((len(ts), 4), np.nan)
    t0, y, t_end = 0.0, np.asarray(y0, dtype=float), float(ts[-1])
    inside = gap(0.0, y) > 0
    while t0 < t_end:
        keep = (ts >= t0) & (ts <= t_end)
        done = solve_ivp(rhs[inside], (t0, t_end), y, method=method, rtol=1e-13, atol=1e-15, dense_output=True, events=leaving if inside else entering, max_step=MAX_STEP)
        if done.status == -1:
            raise RuntimeError(f"wall reference failed: {done.message}")
        t1 = float(done.t[-1])
        part = keep & (ts <= t1)
        if part.any():
            out[part] = done.sol(ts[part]).T
        if done.status == 0:
            break
        # the event: restart on the other side (the crossing's direction says which)
        t0, y = t1, done.y[:, -1]
        rate = math.cos(y[0]) * y[2] - y[3]
        inside = rate > 0
    return out


def reference(name: str, s: System, t_end: float, file_t_end: float, energy: float = 1.0, moved: str = "") -> Ref:
    """Exact for the linear systems (any start: energy x the velocities, or a moved state), checked
    against DOP853 1e-13 of the derived equations over [0, min(t_end, 1000)]; audit 6's pair of
    scipy methods at rtol 1e-13 otherwise."""
    if name not in LINEAR and name != "wall":
        return numeric_audit6.reference(name, s, t_end, file_t_end, energy, moved)
    cache = numeric_audit4.REF_CACHE
    cache.mkdir(parents=True, exist_ok=True)
    cached = cache / f"{name}-{t_end!r}-{energy!r}{'-' + moved if moved else ''}.npz"
    if cached.exists():
        d = np.load(cached)
        return Ref(t_end, d["y"], float(d["own"]), str(d["how"]), float(d["cpu"]))
    began = time.process_time()
    half = len(s.y0) // 2
    y0 = [*s.y0[:half], *(energy * v for v in s.y0[half:])]
    if moved:
        y0 = list(s.y0)
        for word in moved.split(","):
            key, _, value = word.partition("=")
            y0[s.names.index(key)] = float(value)
    ts = np.linspace(0.0, t_end, numeric_audit4.SAMPLES)
    if name == "wall":
        y = wall_run(y0, ts, "DOP853")
        second = wall_run(y0, ts, "LSODA")
        own = _error(second, y, s.wrap)
        cpu = time.process_time() - began
        how = "DOP853 1e-13, LSODA 1e-13 agrees to (piecewise between contact switches, located as events)"
        np.savez(cached, y=y, own=own, how=how, cpu=cpu)
        return Ref(t_end, y, own, how, cpu)
    y = linear_exact(s, y0, ts)
    window = min(t_end, 1000.0)
    wts = ts[ts <= window]
    chk = solve_ivp(_rhs(s), (0, wts[-1]), y0, method="DOP853", rtol=1e-13, atol=1e-15, t_eval=wts)
    own = _error(chk.y.T, y[: len(wts)], s.wrap) if chk.status == 0 else math.nan
    how = f"exact; DOP853 1e-13 of the derived equations over [0, {wts[-1]:g}] agrees to"
    cpu = time.process_time() - began
    np.savez(cached, y=y, own=own, how=how, cpu=cpu)
    return Ref(t_end, y, own, how, cpu)


# stress claims the audit 4 harness does not re-run (its reference is not in the file's coordinates, or
# the regime's horizon is cut to a predictability horizon): (system, regime, start in the reference's
# coordinates, t_end, the claim's own simulate options as stress printed them, reference method pair).
EXTRA = [
    (
        "dp_upright",
        "high energy (theta1_dot = 23.78, theta2_dot = 23.80)",
        [-0.001, 0.002, 23.777337388243176, 23.800050302661795],
        4.0,
        ["--initial", "theta1_dot=23.777337388243176,theta2_dot=23.800050302661795", "--method", "DOP853", "--backend", "compiled", "--rtol", "1e-08", "--atol", "1.0000000000000001e-11"],
    ),
    (
        "dp_upright",
        "long horizon (t_end x 10, measured to t = 15.838)",
        [-0.001, 0.002, 0.0, 0.0],
        15.838000000000001,
        ["--method", "DOP853", "--backend", "compiled", "--rtol", "1e-11", "--atol", "1e-14"],
    ),
    (
        "wheel",
        "high energy (x_dot = 53.95, theta_dot = 150.8; phi_dot = x_dot / R)",
        [0.01, 0.8, 53.953876591087194, 150.7941679084232],
        5.0,
        ["--initial", "x_dot=53.953876591087194,phi_dot=179.846255303624,theta_dot=150.7941679084232", "--method", "RK45", "--backend", "compiled", "--rtol", "1e-05", "--atol", "1e-08"],
    ),
    (
        "wheel",
        "high energy, the tie",
        [0.01, 0.8, 53.953876591087194, 150.7941679084232],
        5.0,
        ["--initial", "x_dot=53.953876591087194,phi_dot=179.846255303624,theta_dot=150.7941679084232", "--method", "DOP853", "--backend", "compiled", "--rtol", "1e-06", "--atol", "1e-09"],
    ),
]


def extra(out: str, only: list[str]) -> None:
    """Re-run the EXTRA claims against a DOP853 1e-13 reference confirmed by LSODA 1e-13, at 2001 samples."""
    found, rows = systems(), []
    with tempfile.TemporaryDirectory() as d:
        for name, regime, y0, t_end, opts in EXTRA:
            if only and name not in only:
                continue
            s = found[name]
            ts = np.linspace(0.0, t_end, numeric_audit4.SAMPLES)
            began = time.process_time()
            first = solve_ivp(_rhs(s), (0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-15, t_eval=ts)
            second = solve_ivp(_rhs(s), (0, t_end), y0, method="LSODA", rtol=1e-13, atol=1e-15, t_eval=ts)
            y = s.to_lagrange(first.y.T)
            own = _error(s.to_lagrange(second.y.T), y, s.wrap) if second.status == 0 else math.nan
            ref = Ref(t_end, y, own, "DOP853 1e-13, LSODA 1e-13 agrees to", time.process_time() - began)
            row = {"system": name, "regime": regime, "ref_own": own, "ref_cpu": ref.cpu, **numeric_audit4.run_simulate(s, ref, opts, Path(d))}
            print(json.dumps(row, default=float), flush=True)
            rows.append(row)
            Path(out).write_text(json.dumps(rows, indent=1, default=float))


def main() -> None:
    """Audit 5's main (and its --versus), pointed at this audit's files, systems, references and results."""
    numeric_audit5.AUDIT = AUDIT
    numeric_audit4.AUDIT = AUDIT
    os.environ.setdefault("AUDIT5_REF_CACHE", "/tmp/audit7-ref")
    os.environ.setdefault("AUDIT5_RESULTS", "/tmp/audit7-results")
    # non-stiff and nonsmooth systems: DOP853 confirmed by LSODA; the stiff ones (vertical damper,
    # wheel, half car) keep audit 4's Radau 1e-13 confirmed by DOP853 1e-13
    numeric_audit6.PAIRS = {n: ("DOP853", "LSODA") for n in ("dp_upright", "crane", "wall")}
    numeric_audit6.LONG_CHECKED = {"crane"}
    numeric_audit5.systems = systems
    numeric_audit4.reference = reference
    if "--extra" in sys.argv:
        only = sys.argv[sys.argv.index("--only") + 1].split(",") if "--only" in sys.argv else []
        extra(sys.argv[sys.argv.index("--extra") + 1], only)
        return
    numeric_audit5.main()


if __name__ == "__main__":
    main()
