"""Issue 15, audit 8: `simulate`, `accuracy` and `stress` on eight systems the project has not seen
(tests/numeric_audit8/*.yaml), against references computed here, independently of lagrange.

The harness is audits 4-7's (benchmarks/numeric_audit4.py: the runs, the re-run of every recommendation
by `simulate` with the report's own options, the error measure (maximum pointwise over 2001 samples of
max_i |y_i - ref_i| / max(1, max |ref_i|)), the table; numeric_audit5.py: auto against each method's
quickest run of the same true accuracy), pointed at this audit's files, result and reference
directories. Only the systems and their references are new, and every reference here is its own
formulation, not audit 3's generic multiplier derivation in the file's coordinates (nothing of
lagrange_cli is imported):

- the sled on the incline: Chaplygin's reduced equations in the blade speed v and the spin omega,
  derived here by Newton-Euler (no multiplier, no Lagrangian);
- the heavy asymmetric body: Euler's equations about the pivot with the rotation matrix (dR/dt =
  R [omega]x, 12 unknowns, no angles), the yaw-pitch-roll angles read off R; energy and the vertical
  angular momentum are exact invariants;
- the motor and load on the stiff shaft: exact (the linear flow between the torque's switch, eigen-
  decomposition of the derived first-order matrix plus the step's particular solution), confirmed by
  scipy's Radau at 1e-13 piece by piece;
- the double compound pendulum: the upper bar's angle and the relative angle;
- the four-bar linkage: its one degree of freedom, the crank angle, with the loop closed in closed
  form (circle intersection) and the Lagrangian written in it: no constraint, no multiplier;
- the stick-slip block: Filippov's solution, event-driven: slip phases with the friction's sign fixed,
  stick phases with x_dot = v0 exactly, switched where the relative speed vanishes or the friction
  needed to stick exceeds mu m g;
- the six-link chain: relative joint angles;
- the absorber pendulum: the Lagrangian written out by hand in the file's coordinates.

Each is integrated by scipy's solve_ivp at rtol 1e-13 (atol 1e-15) by a first method and confirmed by a
second (DOP853 and LSODA unless said), evaluated at exactly the 2001 sample times.

    PYTHONPATH=. LAGRANGE_CACHE_DIR=/tmp/audit8-cache-X .venv/bin/python benchmarks/numeric_audit8.py [--only NAME] [--json out.json]
    PYTHONPATH=. LAGRANGE_CACHE_DIR=/tmp/audit8-cache-X .venv/bin/python benchmarks/numeric_audit8.py --versus NAME --json versus.json
    .venv/bin/python benchmarks/numeric_audit8.py --refs            # every reference: own error, invariants, CPU
    .venv/bin/python benchmarks/numeric_audit8.py --table out1.json,out2.json
"""

from __future__ import annotations

import functools
import json
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numeric_audit4
import numeric_audit5
from numeric_audit3 import Ref, _error, _rhs, _syms, qd
from numeric_audit4 import System
from numeric_audit5 import _vel
from numeric_audit7 import linear_matrix

ROOT = Path(__file__).resolve().parent.parent
AUDIT = ROOT / "tests" / "numeric_audit8"
t = sp.Symbol("t")
G = 9.81
RTOL, ATOL = 1e-13, 1e-15

Runner = Callable[[list[float], np.ndarray, str], np.ndarray]
"""(the file's start state, sample times, method) -> the file's coordinates and velocities at the samples."""


@dataclass
class Own(System):
    """An audit system whose reference is run by `run` from a start state in the file's coordinates."""

    run: Runner | None = None
    pair: tuple[str, str] = ("DOP853", "LSODA")
    invariants: Callable[[np.ndarray], dict[str, float]] | None = None
    """the reference's drift of its exact invariants (largest relative change over the samples)."""


def _solve(rhs: Callable[[float, np.ndarray], np.ndarray], z0: list[float] | np.ndarray, ts: np.ndarray, method: str, t0: float = 0.0, **kw: object) -> np.ndarray:
    done = solve_ivp(rhs, (t0, float(ts[-1])), np.asarray(z0, dtype=float), method=method, rtol=RTOL, atol=ATOL, t_eval=ts, **kw)  # type: ignore[arg-type]
    if done.status != 0:
        raise RuntimeError(f"reference {method} failed: {done.message}")
    return done.y.T  # type: ignore[no-any-return]


def _through(s: System, to_own: Callable[[list[float]], list[float]]) -> Runner:
    """A runner of audit 3's derivation of `s` (its own coordinates), started from the file's state mapped by `to_own`."""
    derived: list[Callable[[float, np.ndarray], np.ndarray]] = []

    def run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
        if not derived:  # derived on first use: the four-bar's and the chain's take a while
            derived.append(_rhs(s))
        return s.to_lagrange(_solve(derived[0], to_own(y0), ts, method))

    return run


# --- 1. Chaplygin sled on an incline: reduced equations in (x, y, th, v, omega) ---------------------------
SLED = {"m": 1.7, "J": 0.08, "a": 0.25, "alpha": 0.35, "c": 0.3, "b": 0.02}


def sled_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """Newton-Euler for the sled: along the blade m (v' - a w^2) = -m g sin(alpha) cos(th) - c v, and, the
    blade's side force eliminated from the moment about the centre of mass,
    (J + m a^2) w' = -m a v w + m a g sin(alpha) sin(th) - b w; the contact point moves along the blade."""
    m, J, a, al, c, b = (SLED[k] for k in ("m", "J", "a", "alpha", "c", "b"))
    gs = G * math.sin(al)

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        _x, _y, th, v, w = z
        return np.array([v * math.cos(th), v * math.sin(th), w, a * w * w + (-m * gs * math.cos(th) - c * v) / m, (-m * a * v * w + m * a * gs * math.sin(th) - b * w) / (J + m * a * a)])

    x, y, th, xd, yd, thd = y0
    z = _solve(rhs, [x, y, th, math.cos(th) * xd + math.sin(th) * yd, thd], ts, method)
    return np.column_stack([z[:, 0], z[:, 1], z[:, 2], z[:, 3] * np.cos(z[:, 2]), z[:, 3] * np.sin(z[:, 2]), z[:, 4]])


# --- 2. heavy asymmetric body on a pivot: Euler's equations with the rotation matrix -----------------------
BODY_M, BODY_C = 2.0, np.array([0.04, -0.03, -0.35])
BODY_I = np.array([[0.05, -0.004, 0.006], [-0.004, 0.07, 0.003], [0.006, 0.003, 0.03]])


@functools.cache
def _zyx() -> tuple[Callable[..., np.ndarray], Callable[..., np.ndarray]]:
    """R = R_z(psi) R_y(theta) R_x(phi) and J with omega_body = J(angles) angle_rates, written out here."""
    a = _syms("a1 a2 a3")
    c1, s1, c2, s2, c3, s3 = sp.cos(a[0]), sp.sin(a[0]), sp.cos(a[1]), sp.sin(a[1]), sp.cos(a[2]), sp.sin(a[2])
    rz = sp.Matrix([[c1, -s1, 0], [s1, c1, 0], [0, 0, 1]])
    ry = sp.Matrix([[c2, 0, s2], [0, 1, 0], [-s2, 0, c2]])
    rx = sp.Matrix([[1, 0, 0], [0, c3, -s3], [0, s3, c3]])
    R = rz * ry * rx
    Rd = sum((sp.diff(R, x) * qd(x) for x in a), sp.zeros(3, 3))
    W = R.T * Rd
    om = sp.Matrix([W[2, 1], W[0, 2], W[1, 0]])
    return sp.lambdify(a, R, "numpy"), sp.lambdify(a, om.jacobian([qd(x) for x in a]), "numpy")


def body_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """I_p w' = -w x I_p w + c x (m R^T g) about the pivot (I_p by the parallel-axis theorem), R' = R [w]x."""
    Rf, Jf = _zyx()
    c = BODY_C
    Ip = BODY_I + BODY_M * (c @ c * np.eye(3) - np.outer(c, c))
    Ipinv = np.linalg.inv(Ip)
    gvec = np.array([0.0, 0.0, -G])

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        w, R = z[:3], z[3:].reshape(3, 3)
        torque = np.cross(c, BODY_M * (R.T @ gvec))
        wx = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        return np.concatenate([Ipinv @ (torque - np.cross(w, Ip @ w)), (R @ wx).ravel()])

    w0 = np.asarray(Jf(*y0[:3]), dtype=float) @ np.asarray(y0[3:])
    z = _solve(rhs, [*w0, *np.asarray(Rf(*y0[:3]), dtype=float).ravel()], ts, method)
    rows = []
    for zz in z:
        R = zz[3:].reshape(3, 3)
        th = -math.asin(max(-1.0, min(1.0, R[2, 0])))
        psi, phi = math.atan2(R[1, 0], R[0, 0]), math.atan2(R[2, 1], R[2, 2])
        rows.append([psi, th, phi, *np.linalg.solve(np.asarray(Jf(psi, th, phi), dtype=float), zz[:3])])
    return np.array(rows)


def body_invariants(y: np.ndarray) -> dict[str, float]:
    """Energy and the angular momentum about the vertical, from the file's angles and rates (relative drift)."""
    Rf, Jf = _zyx()
    c = BODY_C
    Ip = BODY_I + BODY_M * (c @ c * np.eye(3) - np.outer(c, c))
    E, L = [], []
    for row in y:
        R = np.asarray(Rf(*row[:3]), dtype=float)
        w = np.asarray(Jf(*row[:3]), dtype=float) @ row[3:]
        E.append(0.5 * w @ Ip @ w + BODY_M * G * (R @ c)[2])
        L.append((R @ Ip @ w)[2])
    E_, L_ = np.array(E), np.array(L)
    return {"energy": float(np.max(np.abs(E_ - E_[0])) / max(1.0, abs(E_[0]))), "L_z": float(np.max(np.abs(L_ - L_[0])) / max(1.0, abs(L_[0])))}


# --- 3. motor, stiff shaft and load with a step torque: exact ---------------------------------------------
SHAFT = {"J1": 0.012, "J2": 0.9, "k": 3.0e6, "c": 1500.0, "kL": 40.0, "bL": 0.8, "t0": 0.25, "tau": 6.0}


def _shaft_system() -> System:
    a1, a2 = _syms("a1 a2")
    p = SHAFT
    return System(
        "motor_stiff_shaft_load_step_torque.yaml",
        [a1, a2],
        p["J1"] * qd(a1) ** 2 / 2 + p["J2"] * qd(a2) ** 2 / 2,
        p["k"] * (a1 - a2) ** 2 / 2 + p["kL"] * a2**2 / 2,
        [0.001, 0.0, 0.0, 0.0],
        True,
        lambda yy: yy,
        names=["a1", "a2", "a1_dot", "a2_dot"],
        D=p["c"] * (qd(a1) - qd(a2)) ** 2 / 2 + p["bL"] * qd(a2) ** 2 / 2,
    )


def shaft_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """Exact ("exact"): y' = A y before t0, y' = A y + b after, b = tau/J1 on a1's acceleration: y = y_p +
    V exp(Lambda (t - t0)) V^-1 (y(t0) - y_p), y_p = -A^-1 b. Otherwise scipy's `method` piece by piece."""
    s = _shaft_system()
    A = linear_matrix(s)
    b = np.array([0.0, 0.0, SHAFT["tau"] / SHAFT["J1"], 0.0])
    t0 = SHAFT["t0"]
    out = np.empty((len(ts), 4))
    before, after = ts < t0, ts >= t0
    if method == "exact":
        lam, V = np.linalg.eig(A)
        Vinv = np.linalg.inv(V)

        def flow(y: np.ndarray, dt: np.ndarray) -> np.ndarray:
            return np.real((V[None, :, :] * np.exp(np.outer(dt, lam))[:, None, :]) @ (Vinv @ y.astype(complex)))

        y = np.asarray(y0, dtype=float)
        out[before] = flow(y, ts[before])
        yt0 = flow(y, np.array([t0]))[0]
        yp = -np.linalg.solve(A, b)
        out[after] = yp + flow(yt0 - yp, ts[after] - t0)
        return out
    # the check covers [0, min(t_end, 2 t0)] (the step and its transients; NaN after): scipy's Radau at 1e-13
    # takes minutes of CPU over the whole 3 s on the shared machine
    n = int(np.sum(ts <= 2 * t0))
    w, part = ts[:n], out[:n]
    out[:] = np.nan
    first = solve_ivp(lambda _t, y: A @ y, (0.0, t0), np.asarray(y0, dtype=float), method=method, rtol=RTOL, atol=ATOL, dense_output=True, jac=A)
    part[w < t0] = first.sol(w[w < t0]).T
    if np.any(w >= t0):
        second = solve_ivp(lambda _t, y: A @ y + b, (t0, float(w[-1])), first.y[:, -1], method=method, rtol=RTOL, atol=ATOL, dense_output=True, jac=A)
        part[w >= t0] = second.sol(w[w >= t0]).T
    return out


# --- 6. stick-slip: Filippov's solution, event-driven ------------------------------------------------------
SLIP = {"m": 1.0, "k": 25.0, "c": 0.4, "mu": 0.3, "v0": 0.4, "A": 0.3, "W": 1.7}


def slip_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """Slip: m v' = -k (x - A sin(W t)) - c v + s F (F = mu m g, s = sign(v0 - v) fixed); ends where v = v0.
    There, the friction needed to stick, f = k (x - A sin(W t)) + c v0, decides: |f| < F sticks (x' = v0
    until |f| = F), else the block crosses (s flips). A stick ends into slip with s = sign(f)."""
    p = SLIP
    m, k, c, v0, A, W = p["m"], p["k"], p["c"], p["v0"], p["A"], p["W"]
    F = p["mu"] * m * G
    t_end = float(ts[-1])
    out = np.full((len(ts), 2), np.nan)

    def need(time_: float, x: float) -> float:
        return k * (x - A * math.sin(W * time_)) + c * v0

    time_, y = 0.0, np.asarray(y0, dtype=float)
    mode = int(np.sign(v0 - y[1])) if y[1] != v0 else (0 if abs(need(0.0, y[0])) < F else int(np.sign(need(0.0, y[0]))))
    pieces = 0
    while time_ < t_end:
        pieces += 1
        if pieces > 10000:
            raise RuntimeError("stick-slip reference: too many pieces")
        if mode == 0:

            def rhs(_t: float, z: np.ndarray) -> np.ndarray:
                return np.array([v0, 0.0])

            def release(tt: float, z: np.ndarray) -> float:
                return F - abs(need(tt, z[0]))

            release.terminal, release.direction = True, -1.0  # type: ignore[attr-defined]
            event = release
        else:
            s = float(mode)

            def rhs(tt: float, z: np.ndarray, s: float = s) -> np.ndarray:
                return np.array([z[1], (-k * (z[0] - A * math.sin(W * tt)) - c * z[1] + s * F) / m])

            def meet(_t: float, z: np.ndarray) -> float:
                return z[1] - v0

            meet.terminal, meet.direction = True, s  # type: ignore[attr-defined]
            event = meet
        done = solve_ivp(rhs, (time_, t_end), y, method=method, rtol=RTOL, atol=ATOL, dense_output=True, events=event)
        if done.status == -1:
            raise RuntimeError(f"stick-slip reference failed: {done.message}")
        t1 = float(done.t[-1])
        part = (ts >= time_) & (ts <= t1)
        if part.any():
            out[part] = done.sol(ts[part]).T
        if done.status == 0:
            break
        time_, y = t1, done.y[:, -1].copy()
        if mode == 0:
            mode = 1 if need(time_, y[0]) > 0 else -1
        else:
            y[1] = v0
            f = need(time_, y[0])
            mode = 0 if abs(f) < F else -mode
    return out


# --- 5. four-bar linkage: one coordinate, the loop closed in closed form --------------------------------------
FOUR = {"a": 0.22, "b": 0.75, "c": 0.5, "d": 0.62, "ma": 0.3, "mb": 0.8, "mc": 0.5, "kr": 2.0, "th30": 1.9, "cd": 0.01}


@functools.cache
def _four_closure() -> Callable[..., list[float]]:
    """th2(q), th3(q) of the crank angle q (the branch with the coupler's far pin above the ground line, by
    circle intersection) and their first and second derivatives in q, by sympy's diff of the closed form."""
    (q,) = _syms("q,")
    a, b, c, d = (FOUR[k] for k in "abcd")
    Bx, By = a * sp.cos(q), a * sp.sin(q)
    e = sp.sqrt((d - Bx) ** 2 + By**2)
    th2 = sp.atan2(-By, d - Bx) + sp.acos((b**2 + e**2 - c**2) / (2 * b * e))
    th3 = sp.atan2(By + b * sp.sin(th2), Bx + b * sp.cos(th2) - d)
    out = [th2, th3, sp.diff(th2, q), sp.diff(th3, q), sp.diff(th2, q, 2), sp.diff(th3, q, 2)]
    return sp.lambdify([q], out, "math", cse=True)  # type: ignore[no-any-return]


def four_bar_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """Lagrange in the crank angle q alone: T = m(q) q'^2 / 2 with m(q) = sum m_i |dc_i/dq|^2 + I_i (dth_i/dq)^2,
    so m q'' + m'(q) q'^2 / 2 + dV/dq + cd q' = 0, m' = 2 sum m_i dc_i/dq . d2c_i/dq2 + I_i th_i' th_i''."""
    p = FOUR
    a, b, c = p["a"], p["b"], p["c"]
    closure = _four_closure()
    masses, lens = [p["ma"], p["mb"], p["mc"]], [a, b, c]

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        q, w = z
        th2, th3, d2, d3, dd2, dd3 = closure(q)
        cq, sq = math.cos(q), math.sin(q)
        # centres of mass: first and second derivatives in q (e(th) = (cos, sin), n(th) = (-sin, cos))
        dc1 = np.array([-a / 2 * sq, a / 2 * cq])
        ddc1 = np.array([-a / 2 * cq, -a / 2 * sq])
        dB, ddB = np.array([-a * sq, a * cq]), np.array([-a * cq, -a * sq])
        e2, n2 = np.array([math.cos(th2), math.sin(th2)]), np.array([-math.sin(th2), math.cos(th2)])
        e3, n3 = np.array([math.cos(th3), math.sin(th3)]), np.array([-math.sin(th3), math.cos(th3)])
        dc2 = dB + b / 2 * d2 * n2
        ddc2 = ddB + b / 2 * (dd2 * n2 - d2 * d2 * e2)
        dc3 = c / 2 * d3 * n3
        ddc3 = c / 2 * (dd3 * n3 - d3 * d3 * e3)
        dth, ddth = [1.0, d2, d3], [0.0, dd2, dd3]
        dcs, ddcs = [dc1, dc2, dc3], [ddc1, ddc2, ddc3]
        inertia = [mi * li * li / 12 for mi, li in zip(masses, lens, strict=True)]
        mq = sum(masses[i] * dcs[i] @ dcs[i] + inertia[i] * dth[i] ** 2 for i in range(3))
        dm = 2 * sum(masses[i] * dcs[i] @ ddcs[i] + inertia[i] * dth[i] * ddth[i] for i in range(3))
        dV = G * sum(masses[i] * dcs[i][1] for i in range(3)) + p["kr"] * (th3 - p["th30"]) * d3
        return np.array([w, (-dm * w * w / 2 - dV - p["cd"] * w) / mq])

    z = _solve(rhs, [y0[0], y0[3]], ts, method)
    rows = []
    for q, w in z:
        th2, th3, d2, d3, _dd2, _dd3 = closure(q)
        rows.append([q, th2, th3, w, d2 * w, d3 * w])
    return np.array(rows)


# --- the systems --------------------------------------------------------------------------------------------


def systems() -> dict[str, Own]:
    out: dict[str, Own] = {}
    dummy = sp.Integer(0)
    # 1. sled
    out["sled"] = Own(
        "sled_on_incline_drag_and_spin_damping.yaml",
        [],
        dummy,
        dummy,
        [0.0, 0.0, 0.4, 1.5 * math.cos(0.4), 1.5 * math.sin(0.4), 3.0],
        False,
        lambda yy: yy,
        names=["x", "y", "th", "x_dot", "y_dot", "th_dot"],
        run=sled_run,
    )
    # 2. heavy asymmetric body: psi and phi compared modulo 2 pi
    out["heavy_body"] = Own(
        "heavy_asymmetric_body_zyx_full_inertia.yaml",
        [],
        dummy,
        dummy,
        [0.0, 0.4, -0.3, 8.0, 0.0, 1.0],
        False,
        lambda yy: yy,
        names=["psi", "theta", "phi", "psi_dot", "theta_dot", "phi_dot"],
        wrap=(0, 2),
        run=body_run,
        invariants=body_invariants,
    )
    # 3. shaft: exact, confirmed by Radau
    out["shaft"] = Own(
        "motor_stiff_shaft_load_step_torque.yaml",
        [],
        dummy,
        dummy,
        [0.001, 0.0, 0.0, 0.0],
        True,
        lambda yy: yy,
        names=["a1", "a2", "a1_dot", "a2_dot"],
        run=shaft_run,
        pair=("exact", "Radau"),
    )
    # 4. double compound pendulum: upper angle and relative angle
    u, r = _syms("u r")
    m1, l1, m2, l2 = 1.0, 1.0, 0.45, 0.65
    c1 = [l1 / 2 * sp.sin(u), -l1 / 2 * sp.cos(u)]
    tip = [l1 * sp.sin(u), -l1 * sp.cos(u)]
    c2 = [tip[0] + l2 / 2 * sp.sin(u + r), tip[1] - l2 / 2 * sp.cos(u + r)]
    bars = System(
        "",
        [u, r],
        m1 / 2 * sum(_vel(e, [u, r]) ** 2 for e in c1) + m1 * l1**2 / 24 * qd(u) ** 2 + m2 / 2 * sum(_vel(e, [u, r]) ** 2 for e in c2) + m2 * l2**2 / 24 * (qd(u) + qd(r)) ** 2,
        m1 * G * c1[1] + m2 * G * c2[1],
        [],
        False,
        lambda yy: np.column_stack([yy[:, 0], yy[:, 0] + yy[:, 1], yy[:, 2], yy[:, 2] + yy[:, 3]]),
    )
    out["bars"] = Own(
        "double_compound_pendulum_bars_t200.yaml",
        [],
        dummy,
        dummy,
        [2.2, -0.9, 3.0, -2.0],
        False,
        lambda yy: yy,
        names=["th1", "th2", "th1_dot", "th2_dot"],
        run=_through(bars, lambda y: [y[0], y[1] - y[0], y[2], y[3] - y[2]]),
    )
    # 5. four-bar: the crank angle only, the loop closed by circle intersection (four_bar_run)
    out["four_bar"] = Own(
        "four_bar_linkage_two_kept_loop_constraints.yaml",
        [],
        dummy,
        dummy,
        [0.5, 0.4545780912748132, 1.0543352710691731, 7.0, -1.9148643676669506, 0.2477692414820109],
        False,
        lambda yy: yy,
        names=["th1", "th2", "th3", "th1_dot", "th2_dot", "th3_dot"],
        wrap=(0, 1, 2),
        run=four_bar_run,
    )
    # 6. stick-slip
    out["stick_slip"] = Own(
        "stick_slip_block_on_belt_shaken_wall.yaml",
        [],
        dummy,
        dummy,
        [0.0, 0.0],
        False,
        lambda yy: yy,
        names=["x", "x_dot"],
        run=slip_run,
    )
    # 7. six-link chain: relative joint angles r_i = q_i - q_(i-1)
    rel = _syms("r1:7")
    L6 = [0.5, 0.35, 0.45, 0.3, 0.4, 0.25]
    M6 = [1.2, 0.9, 0.7, 0.5, 0.35, 0.2]
    absolute = [sum(rel[: i + 1]) for i in range(6)]
    px6, py6, T6, V6 = sp.Integer(0), sp.Integer(0), sp.Integer(0), sp.Integer(0)
    vx6 = vy6 = sp.Integer(0)
    for i in range(6):
        px6 += L6[i] * sp.sin(absolute[i])
        py6 -= L6[i] * sp.cos(absolute[i])
        vx6, vy6 = _vel(px6, rel), _vel(py6, rel)
        T6 += M6[i] / 2 * (vx6**2 + vy6**2)
        V6 += M6[i] * G * py6
    D6 = 0.02 / 2 * sum(qd(x) ** 2 for x in rel) + 0.05 / 2 * (vx6**2 + vy6**2)

    def chain_map(yy: np.ndarray) -> np.ndarray:
        return np.column_stack([np.cumsum(yy[:, :6], axis=1), np.cumsum(yy[:, 6:], axis=1)])

    chain = System("", rel, T6, V6, [], False, chain_map, D=D6)
    out["chain6"] = Own(
        "six_link_chain_distinct_links_joint_dampers.yaml",
        [],
        dummy,
        dummy,
        [0.6, 0.3, -0.2, 0.5, -0.4, 0.2, 0, 0, 0, 0, 0, 0],
        False,
        lambda yy: yy,
        names=[*(f"q{i}" for i in range(1, 7)), *(f"q{i}_dot" for i in range(1, 7))],
        run=_through(chain, lambda y: [y[0], *np.diff(y[:6]), y[6], *np.diff(y[6:])]),
    )
    # 8. absorber: the Lagrangian written out by hand (absorber velocity (l th' + s') e_t - s th' e_r)
    th, s_ = _syms("th s")
    Mb, lb, mf, kf, cf = 3.0, 2.4525, 0.02, 8.0e6, 0.08
    absorber = System(
        "",
        [th, s_],
        Mb / 2 * lb**2 * qd(th) ** 2 + mf / 2 * ((lb * qd(th) + qd(s_)) ** 2 + s_**2 * qd(th) ** 2),
        -Mb * G * lb * sp.cos(th) + mf * G * (-lb * sp.cos(th) + s_ * sp.sin(th)) + kf * s_**2 / 2,
        [],
        False,
        lambda yy: yy,
        D=cf * qd(s_) ** 2 / 2,
    )
    out["absorber"] = Own(
        "pendulum_with_stiff_lightly_damped_absorber_ratio_1e8.yaml",
        [],
        dummy,
        dummy,
        [0.9, 2.0e-4, 0.0, 0.0],
        False,
        lambda yy: yy,
        names=["theta", "s", "theta_dot", "s_dot"],
        run=_through(absorber, list),
    )
    return out


# long horizons (stress's t_end x 10) whose reference this audit computes: the others (the chaotic bars to
# t = 2000, the absorber's 2e4 rad/s ringing to t = 30 in python at 1e-13) are recorded, not checked.
LONG_CHECKED = {"sled", "heavy_body", "shaft", "four_bar", "stick_slip", "chain6"}


def start(s: Own, energy: float, moved: str) -> list[float]:
    """The file's start state, its velocities x `energy`, or with `moved` ("name=value,...") applied."""
    y0 = list(s.y0)
    if moved:
        for word in moved.split(","):
            key, _, value = word.partition("=")
            y0[s.names.index(key)] = float(value)
        return y0
    half = len(y0) // 2
    return [*y0[:half], *(energy * v for v in y0[half:])]


def reference(name: str, s: Own, t_end: float, file_t_end: float, energy: float = 1.0, moved: str = "") -> Ref:
    """The system's own reference at the SAMPLES sample times by its first method, confirmed by its second
    (own error = their largest difference, the audits' measure), cached on disk."""
    if t_end > file_t_end * 1.0001 and name not in LONG_CHECKED:
        raise RuntimeError(f"long-horizon reference (t_end {t_end:g}) not computed by this audit")
    cache = numeric_audit4.REF_CACHE
    cache.mkdir(parents=True, exist_ok=True)
    cached = cache / f"{name}-{t_end!r}-{energy!r}{'-' + moved if moved else ''}.npz"
    if cached.exists():
        d = np.load(cached)
        return Ref(t_end, d["y"], float(d["own"]), str(d["how"]), float(d["cpu"]))
    began = time.process_time()
    ts = np.linspace(0.0, t_end, numeric_audit4.SAMPLES)
    y0 = start(s, energy, moved)
    assert s.run is not None
    first_m, second_m = s.pair
    y = s.run(y0, ts, first_m)
    try:
        second = s.run(y0, ts, second_m)
        kept = np.all(np.isfinite(second), axis=1)  # a second method run over a window only (the shaft's)
        own = _error(second[kept], y[kept], s.wrap)
    except RuntimeError:
        own = math.nan
    how = f"{first_m}{'' if first_m == 'exact' else ' 1e-13'}, {second_m} 1e-13 agrees to"
    if s.invariants is not None:
        how = f"{how} (invariants drift {', '.join(f'{k} {v:.1e}' for k, v in s.invariants(y).items())})"
    cpu = time.process_time() - began
    np.savez(cached, y=y, own=own, how=how, cpu=cpu)
    return Ref(t_end, y, own, how, cpu)


def refs(only: list[str]) -> None:
    """Every system's reference over its file's t_end: own error, invariants, CPU."""
    import yaml

    for name, s in systems().items():
        if only and name not in only:
            continue
        t_file = float(yaml.safe_load((AUDIT / s.file).read_text())["simulate"]["t_end"])
        r = reference(name, s, t_file, t_file)
        print(json.dumps({"system": name, "how": r.how, "own": r.own, "cpu": r.cpu, "max_abs": np.max(np.abs(r.y), axis=0).tolist()}), flush=True)


def main() -> None:
    """Audit 5's main (and its --versus), pointed at this audit's files, systems, references and results."""
    numeric_audit5.AUDIT = AUDIT
    numeric_audit4.AUDIT = AUDIT
    os.environ.setdefault("AUDIT5_REF_CACHE", "/tmp/audit8-ref")
    os.environ.setdefault("AUDIT5_RESULTS", "/tmp/audit8-results")
    numeric_audit5.systems = systems  # type: ignore[assignment]
    numeric_audit4.reference = reference  # type: ignore[assignment]
    if "--refs" in sys.argv:
        numeric_audit4.REF_CACHE = Path(os.environ["AUDIT5_REF_CACHE"])
        refs(sys.argv[sys.argv.index("--only") + 1].split(",") if "--only" in sys.argv else [])
        return
    numeric_audit5.main()


if __name__ == "__main__":
    main()
