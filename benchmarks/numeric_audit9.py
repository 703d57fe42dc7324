"""Issue 15, audit 9: `simulate`, `accuracy` and `stress` on eight systems the project has not seen
(tests/numeric_audit9/*.yaml), against references computed here, independently of lagrange.

The harness is audits 4-8's (benchmarks/numeric_audit4.py: the runs, the re-run of every recommendation
by `simulate` with the report's own options, the error measure (maximum pointwise over 2001 samples of
max_i |y_i - ref_i| / max(1, max |ref_i|)), the table; numeric_audit5.py: auto against each method's
quickest run; numeric_audit8.py: a reference run by a system's own formulation from the file's start
state, confirmed by a second method, cached). Only the systems and their references are new, each its
own formulation (nothing of lagrange_cli is imported):

- the pendulum whose length is pumped by a kept constraint l(t) = l0 + a sin(w t): one coordinate, the
  angle theta, with d/dt(m l^2 theta') = -m g l sin(theta) (no constraint, no multiplier);
- the Kepler orbit of e = 0.99: exact (Kepler's equation; a and e read off the file's start state),
  confirmed by DOP853 at 1e-13 in Cartesian x, y; energy and angular momentum are exact invariants;
- the hanging chain of soft and stiff springs: exact (eigen-decomposition of the linear flow plus the
  static deflection under gravity), confirmed by products with expm(A dt) sample to sample;
- the double pendulum with quadratic drag: Lagrange's equations derived here (audit 3's generic
  derivation) with the drag's generalized forces Q_i = F . dr/dq_i worked out here;
- the tuned absorber under a chirp: the linear equations written by hand, forcing F0 sin(w0 t + beta t^2/2);
- the fast top: Euler's equations about the pivot with the rotation matrix (dR/dt = R [omega]x), psi and
  phi integrated alongside from omega (no angles in the dynamics); energy, L_z and the spin are invariants;
- the FPU chain: the forces written by hand in numpy; the energy is an exact invariant;
- the disk rolling on the incline: Chaplygin's reduced equations in phi, theta (the contact force
  eliminated by Newton-Euler), the contact point carried along by the rolling (no multiplier).

Each is integrated by scipy's solve_ivp at rtol 1e-13 (atol 1e-15) by a first method and confirmed by a
second (DOP853 and LSODA unless said), evaluated at exactly the 2001 sample times. Audit 8's three systems
its harness did not reach run through benchmarks/numeric_audit8.py itself.

    AUDIT5_REF_CACHE=/tmp/audit9/ref AUDIT5_RESULTS=/tmp/audit9/res LAGRANGE_CACHE_DIR=C PYTHONPATH=. \
        .venv/bin/python -u benchmarks/numeric_audit9.py [--only NAME ...] [--json out.json]
    .venv/bin/python benchmarks/numeric_audit9.py --refs [--only NAME,NAME]   # every reference: own error, invariants, CPU
    .venv/bin/python benchmarks/numeric_audit9.py --table out1.json,out2.json
"""

from __future__ import annotations

import functools
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import sympy as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numeric_audit4
import numeric_audit5
import numeric_audit8
from numeric_audit3 import _rhs, _syms, qd
from numeric_audit4 import System
from numeric_audit5 import _vel
from numeric_audit8 import Own, _solve

ROOT = Path(__file__).resolve().parent.parent
AUDIT = ROOT / "tests" / "numeric_audit9"
t = sp.Symbol("t")
G = 9.81
DUMMY = sp.Integer(0)


def _own(file: str, y0: list[float], names: list[str], run: Callable[[list[float], np.ndarray, str], np.ndarray], **kw: object) -> Own:
    return Own(file, [], DUMMY, DUMMY, y0, False, lambda yy: yy, names=names, run=run, **kw)  # type: ignore[arg-type]


def _drift(values: np.ndarray) -> float:
    return float(np.max(np.abs(values - values[0])) / max(1.0, abs(values[0])))


# --- 1. pendulum of prescribed length: the angle alone ---------------------------------------------------
PUMP = {"l0": 1.2, "a": 0.15, "w": 5.5}


def pump_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """theta'' = -(2 l' theta' + g sin theta) / l, l = l0 + a sin(w t); x = l sin theta, y = -l cos theta.
    The start's angular rate is (x y' - y x') / l^2 (its radial part is the constraint's, l'(0))."""
    l0, a, w = PUMP["l0"], PUMP["a"], PUMP["w"]

    def rhs(tt: float, z: np.ndarray) -> np.ndarray:
        ln, ld = l0 + a * math.sin(w * tt), a * w * math.cos(w * tt)
        return np.array([z[1], -(2 * ld * z[1] + G * math.sin(z[0])) / ln])

    x, y, xd, yd = y0
    z = _solve(rhs, [math.atan2(x, -y), (x * yd - y * xd) / (x * x + y * y)], ts, method)
    ln, ld = l0 + a * np.sin(w * ts), a * w * np.cos(w * ts)
    th, thd = z[:, 0], z[:, 1]
    return np.column_stack([ln * np.sin(th), -ln * np.cos(th), ld * np.sin(th) + ln * np.cos(th) * thd, -ld * np.cos(th) + ln * np.sin(th) * thd])


# --- 2. Kepler e = 0.99: exact, and Cartesian -------------------------------------------------------------
MU = 2.5


def kepler_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """Method "exact": from a periapsis start (r_dot = 0, phi = 0, an ellipse) by Kepler's equation, a = -mu / (2 eps),
    e = 1 - r0 / a; otherwise `method` in Cartesian x, y (x'' = -mu x / r^3), read back as polar."""
    r0, p0, rd0, pd0 = y0
    eps = (rd0 * rd0 + (r0 * pd0) ** 2) / 2 - MU / r0
    if method == "exact" and rd0 == 0.0 and p0 == 0.0 and eps < 0:
        a = -MU / (2 * eps)
        return numeric_audit4._kepler_polar(ts, 1 - r0 / a, a, MU)
    if method == "exact":
        method = "LSODA"  # not an ellipse from periapsis (a regime that moved the start): integrated instead

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        x, y, xd, yd, _phi = z
        rr = x * x + y * y
        r3 = rr**1.5
        return np.array([xd, yd, -MU * x / r3, -MU * y / r3, (x * yd - y * xd) / rr])

    c, s = math.cos(p0), math.sin(p0)
    z = _solve(rhs, [r0 * c, r0 * s, rd0 * c - r0 * pd0 * s, rd0 * s + r0 * pd0 * c, p0], ts, method)
    x, y, xd, yd, phi = z.T  # phi carried on continuously by phi' = (x y' - y x') / r^2 (the samples are far apart)
    r = np.hypot(x, y)
    return np.column_stack([r, phi, (x * xd + y * yd) / r, (x * yd - y * xd) / r**2])


def kepler_invariants(y: np.ndarray) -> dict[str, float]:
    r, _p, rd, pd = y.T
    return {"energy": _drift((rd * rd + (r * pd) ** 2) / 2 - MU / r), "r^2 phi_dot": _drift(r * r * pd)}


# --- 3. hanging chain of soft and stiff springs: exact ----------------------------------------------------
CHAIN = {"m": [1.1, 0.7, 0.6, 0.4], "k": [40.0, 4.0e7, 25.0, 2.5e7], "c1": 0.3, "c3": 0.8, "c4": 4.8}


@functools.cache
def _chain_matrix() -> tuple[np.ndarray, np.ndarray]:
    """y' = A y + b for y = (heights, velocities), written out here: K from the four springs in series,
    C from the drag on m1 and the dashpots across k3 and k4, b = -g on each acceleration."""
    m, k = np.array(CHAIN["m"]), CHAIN["k"]
    K = np.zeros((4, 4))
    K[0, 0] = k[0]
    for i, ki in enumerate(k[1:]):  # spring i+1 between masses i and i+1
        K[i : i + 2, i : i + 2] += ki * np.array([[1.0, -1.0], [-1.0, 1.0]])
    C = np.zeros((4, 4))
    C[0, 0] = CHAIN["c1"]
    C[1:3, 1:3] += CHAIN["c3"] * np.array([[1.0, -1.0], [-1.0, 1.0]])
    C[2:4, 2:4] += CHAIN["c4"] * np.array([[1.0, -1.0], [-1.0, 1.0]])
    A = np.block([[np.zeros((4, 4)), np.eye(4)], [-K / m[:, None], -C / m[:, None]]])
    b = np.concatenate([np.zeros(4), -G * np.ones(4)])
    return A, b


def chain_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """Method "exact": y = y_p + V exp(Lambda t) V^-1 (y0 - y_p), y_p = -A^-1 b; "expm": y_(j+1) = y_p + expm(A dt)
    (y_j - y_p) sample to sample (evenly spaced samples)."""
    A, b = _chain_matrix()
    yp = -np.linalg.solve(A, b)
    d0 = np.asarray(y0, dtype=float) - yp
    if method == "exact":
        lam, V = np.linalg.eig(A)
        c = np.linalg.solve(V, d0.astype(complex))
        return yp + np.real((V[None, :, :] * np.exp(np.outer(ts, lam))[:, None, :]) @ c)
    from scipy.linalg import expm

    step = expm(A * (ts[1] - ts[0]))
    out = np.empty((len(ts), 8))
    d = d0
    for j in range(len(ts)):
        out[j] = yp + d
        d = step @ d
    return out


# --- 4. double pendulum with quadratic drag: Lagrange derived here --------------------------------------------
DRAG = {"m1": 0.8, "m2": 0.35, "l1": 0.9, "l2": 0.6, "c": 0.4, "b": 0.05}


@functools.cache
def _drag_rhs() -> Callable[[float, np.ndarray], np.ndarray]:
    """T, V of the two bobs; Q_i = F . d(lower)/d(theta_i) with F = -c (|vx| vx, |vy| vy), plus the joint's
    -b |theta1'| theta1' on theta1: audit 3's derivation of Euler-Lagrange."""
    a1, a2 = _syms("a1 a2")
    p = DRAG
    up = [p["l1"] * sp.sin(a1), -p["l1"] * sp.cos(a1)]
    lo = [up[0] + p["l2"] * sp.sin(a2), up[1] - p["l2"] * sp.cos(a2)]
    vel = [_vel(e, [a1, a2]) for e in lo]
    T = p["m1"] / 2 * sum(_vel(e, [a1, a2]) ** 2 for e in up) + p["m2"] / 2 * sum(v**2 for v in vel)
    V = G * (p["m1"] * up[1] + p["m2"] * lo[1])
    F = [-p["c"] * sp.Abs(v) * v for v in vel]
    Q = [sum(F[j] * sp.diff(lo[j], x) for j in range(2)) for x in (a1, a2)]
    Q[0] += -p["b"] * sp.Abs(qd(a1)) * qd(a1)
    return _rhs(System("", [a1, a2], T, V, [], False, lambda yy: yy, Q=Q))


def drag_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    return _solve(_drag_rhs(), y0, ts, method)


# --- 5. tuned absorber under a chirp ---------------------------------------------------------------------
CHIRP = {"m1": 1.0, "m2": 0.1, "k1": 400.0, "k2": 30.0, "c2": 0.25, "w0": 0.5, "beta": 10.0, "F0": 3.0}


def chirp_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """m1 x1'' = -k1 x1 + k2 (x2 - x1) + c2 (x2' - x1') + F0 sin(w0 t + beta t^2 / 2), m2 x2'' = -k2 (x2 - x1) - c2 (x2' - x1')."""
    p = CHIRP

    def rhs(tt: float, z: np.ndarray) -> np.ndarray:
        x1, x2, v1, v2 = z
        spring, damper = p["k2"] * (x2 - x1), p["c2"] * (v2 - v1)
        force = p["F0"] * math.sin(p["w0"] * tt + p["beta"] * tt * tt / 2)
        return np.array([v1, v2, (-p["k1"] * x1 + spring + damper + force) / p["m1"], (-spring - damper) / p["m2"]])

    return _solve(rhs, y0, ts, method)


# --- 6. fast top: Euler's equations with the rotation matrix ------------------------------------------------
TOP = {"m": 0.5, "l": 0.02, "I1": 1.2e-4, "I3": 5.0e-5}


def _top_omega(psi: float, th: float, ph: float, rates: np.ndarray) -> np.ndarray:
    """Body angular velocity of R = R_z(psi) R_x(theta) R_z(phi) (the axial vector of R^T R'), checked against
    sympy in test_numeric_audit9."""
    pd, thd, phd = rates
    return np.array([pd * math.sin(th) * math.sin(ph) + thd * math.cos(ph), pd * math.sin(th) * math.cos(ph) - thd * math.sin(ph), pd * math.cos(th) + phd])


def _zxz(psi: float, th: float, ph: float) -> np.ndarray:
    def rz(a: float) -> np.ndarray:
        return np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])

    rx = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(th), -math.sin(th)], [0.0, math.sin(th), math.cos(th)]])
    return rz(psi) @ rx @ rz(ph)  # type: ignore[no-any-return]


def _top_inertia() -> tuple[np.ndarray, np.ndarray]:
    p = TOP
    Ip = np.diag([p["I1"] + p["m"] * p["l"] ** 2, p["I1"] + p["m"] * p["l"] ** 2, p["I3"]])
    return Ip, np.array([0.0, 0.0, p["l"]])


def top_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """I_p w' = c x (m R^T g) - w x I_p w, R' = R [w]x (15 unknowns with psi, phi: theta is read off R,
    psi' = (w1 sin phi + w2 cos phi) / sin theta and phi' = w3 - psi' cos theta carry psi and phi on
    continuously, phi from R's third row and psi from its third column)."""
    Ip, c = _top_inertia()
    Ipinv = np.linalg.inv(Ip)
    gvec = np.array([0.0, 0.0, -G])
    m = TOP["m"]

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        w, R = z[:3], z[3:12].reshape(3, 3)
        torque = np.cross(c, m * (R.T @ gvec))
        wx = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        th = math.atan2(math.hypot(R[2, 0], R[2, 1]), R[2, 2])
        ph = math.atan2(R[2, 0], R[2, 1])
        psid = (w[0] * math.sin(ph) + w[1] * math.cos(ph)) / math.sin(th)
        return np.concatenate([Ipinv @ (torque - np.cross(w, Ip @ w)), (R @ wx).ravel(), [psid, w[2] - psid * math.cos(th)]])

    psi, th, ph = y0[:3]
    w0 = _top_omega(psi, th, ph, np.asarray(y0[3:], dtype=float))
    z = _solve(rhs, [*w0, *_zxz(psi, th, ph).ravel(), psi, ph], ts, method)
    rows = []
    for zz in z:
        w, R = zz[:3], zz[3:12].reshape(3, 3)
        th_ = math.atan2(math.hypot(R[2, 0], R[2, 1]), R[2, 2])
        ph_ = math.atan2(R[2, 0], R[2, 1])
        psid = (w[0] * math.sin(ph_) + w[1] * math.cos(ph_)) / math.sin(th_)
        thd = w[0] * math.cos(ph_) - w[1] * math.sin(ph_)
        rows.append([zz[12], th_, zz[13], psid, thd, w[2] - psid * math.cos(th_)])
    return np.array(rows)


def top_invariants(y: np.ndarray) -> dict[str, float]:
    Ip, c = _top_inertia()
    E, L, S = [], [], []
    for row in y:
        R = _zxz(*row[:3])
        w = _top_omega(*row[:3], row[3:])
        E.append(0.5 * w @ Ip @ w + TOP["m"] * G * (R @ c)[2])
        L.append((R @ Ip @ w)[2])
        S.append(w[2])
    return {"energy": _drift(np.array(E)), "L_z": _drift(np.array(L)), "spin": _drift(np.array(S))}


# --- 7. FPU alpha chain --------------------------------------------------------------------------------------
FPU = {"k": 1.0, "alpha": 0.25}


def fpu_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """u_i'' = f(d_(i+1)) - f(d_i), d_i = u_i - u_(i-1) (walls u_0 = u_7 = 0), f(d) = k d + alpha d^2."""
    k, al = FPU["k"], FPU["alpha"]

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        u = np.concatenate([[0.0], z[:6], [0.0]])
        d = np.diff(u)
        f = k * d + al * d * d
        return np.concatenate([z[6:], np.diff(f)])

    return _solve(rhs, y0, ts, method)


def fpu_invariants(y: np.ndarray) -> dict[str, float]:
    u = np.column_stack([np.zeros(len(y)), y[:, :6], np.zeros(len(y))])
    d = np.diff(u, axis=1)
    E = 0.5 * np.sum(y[:, 6:] ** 2, axis=1) + np.sum(FPU["k"] * d * d / 2 + FPU["alpha"] * d**3 / 3, axis=1)
    return {"energy": _drift(E)}


# --- 8. upright disk rolling on an incline: Chaplygin's reduced equations --------------------------------------
DISK = {"m": 0.3, "R": 0.12, "alpha": 0.2, "b": 2.0e-4}


def disk_run(y0: list[float], ts: np.ndarray, method: str) -> np.ndarray:
    """Newton-Euler with the contact force eliminated: (m R^2/4) phi'' = -b phi', (3/2 m R^2) theta'' =
    m g sin(alpha) R cos(phi) (gravity's moment about the contact line), x' = R cos(phi) theta',
    y' = R sin(phi) theta' (no multiplier)."""
    p = DISK
    decay, push = 4 * p["b"] / (p["m"] * p["R"] ** 2), 2 * G * math.sin(p["alpha"]) / (3 * p["R"])

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        _x, _y, ph, _th, phd, thd = z
        return np.array([p["R"] * math.cos(ph) * thd, p["R"] * math.sin(ph) * thd, phd, thd, -decay * phd, push * math.cos(ph)])

    x, y, ph, th, _xd, _yd, phd, thd = y0
    z = _solve(rhs, [x, y, ph, th, phd, thd], ts, method)
    ph_, thd_ = z[:, 2], z[:, 5]
    return np.column_stack([z[:, :4], p["R"] * np.cos(ph_) * thd_, p["R"] * np.sin(ph_) * thd_, z[:, 4], thd_])


# --- the systems --------------------------------------------------------------------------------------------


def _initial(file: str) -> tuple[list[float], list[str]]:
    """The file's start state and its coordinate/velocity names (the references start from the file's own numbers)."""
    import yaml

    data = yaml.safe_load((AUDIT / file).read_text())
    q = data["coordinates"]
    given = data.get("initial", {})
    return [float(given.get(x, 0.0)) for x in q] + [float(given.get(x + "_dot", 0.0)) for x in q], [*q, *(x + "_dot" for x in q)]


def systems() -> dict[str, Own]:
    spec: list[tuple[str, str, Callable[..., np.ndarray], dict[str, object]]] = [
        ("pumped_pendulum", "pendulum_length_pumped_by_kept_rheonomic_constraint.yaml", pump_run, {}),
        ("kepler099", "kepler_e099_polar_near_collision_20_orbits.yaml", kepler_run, {"pair": ("exact", "DOP853"), "wrap": (1,), "invariants": kepler_invariants}),
        ("soft_hard_chain", "hanging_chain_soft_and_undamped_stiff_springs_ratio_1e6.yaml", chain_run, {"pair": ("exact", "expm")}),
        ("drag_pendulum", "double_pendulum_quadratic_air_drag_abs.yaml", drag_run, {}),
        ("chirp", "tuned_absorber_fast_chirp_input_force.yaml", chirp_run, {}),
        ("fast_top", "fast_top_spin_1e3_precession_zxz.yaml", top_run, {"wrap": (0, 2), "invariants": top_invariants}),
        ("fpu", "fpu_alpha_chain_six_masses_t1e4.yaml", fpu_run, {"invariants": fpu_invariants}),
        ("rolling_disk", "disk_rolling_on_incline_heading_damper_kept_velocity_constraints.yaml", disk_run, {}),
    ]
    out = {}
    for name, file, run, kw in spec:
        y0, names = _initial(file)
        out[name] = _own(file, y0, names, run, **kw)
    return out


# long horizons (stress's t_end x 10) whose reference this audit computes: the FPU chain's 1e5 s is not.
LONG_CHECKED = {"pumped_pendulum", "kepler099", "soft_hard_chain", "drag_pendulum", "chirp", "fast_top", "rolling_disk"}


def main() -> None:
    """Audit 8's reference (its own formulation by a first method, confirmed by a second) and audit 5's main,
    pointed at this audit's files, systems, references and results."""
    numeric_audit8.LONG_CHECKED = LONG_CHECKED
    numeric_audit8.AUDIT = AUDIT
    numeric_audit8.systems = systems  # type: ignore[assignment]
    numeric_audit5.AUDIT = AUDIT
    numeric_audit4.AUDIT = AUDIT
    os.environ.setdefault("AUDIT5_REF_CACHE", "/tmp/audit9-ref")
    os.environ.setdefault("AUDIT5_RESULTS", "/tmp/audit9-results")
    numeric_audit5.systems = systems  # type: ignore[assignment]
    numeric_audit4.reference = numeric_audit8.reference  # type: ignore[assignment]
    if "--refs" in sys.argv:
        numeric_audit4.REF_CACHE = Path(os.environ["AUDIT5_REF_CACHE"])
        numeric_audit8.refs(sys.argv[sys.argv.index("--only") + 1].split(",") if "--only" in sys.argv else [])
        return
    numeric_audit5.main()


if __name__ == "__main__":
    main()
