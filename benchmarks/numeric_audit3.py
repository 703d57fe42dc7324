"""Issue 15, audit 3: `simulate`, `accuracy` and `stress` on nine systems the project has not seen
(tests/numeric_audit3/*.yaml), against references computed here, independently of lagrange.

References (nothing of lagrange_cli is imported): each system's equations are derived here by plain
sympy from a Lagrangian, Rayleigh function, generalized forces and constraints written by hand,
often in other coordinates than the file's (the penalty pendulum in its extension u = r - l and
angle, the gimbal pendulum in Cartesian x, y, z with its rod as a multiplier, the hoop and the
multiplier pendulum in their one angle), and integrated by scipy's solve_ivp at rtol 1e-13:
Radau confirmed by DOP853 on stiff systems, DOP853 confirmed by Radau otherwise (on the long
horizons of the non-stiff systems, where Radau at 1e-13 would take many minutes, by DOP853 at
rtol 1e-12: said in the table). Kepler's orbit is Kepler's equation solved by Newton; the
multiplier pendulum is Jacobi's sn/cn solution. The reference is evaluated at exactly the 2001
sample times of the runs (no interpolation). Errors: the maximum over the 2001 samples of
max_i |y_i - y_ref,i| / max(1, max_t |y_ref,i|) (lagrange's own scaling), angles that the
reference cannot unwrap (the gimbal pendulum's a) compared modulo 2 pi.

For each system: `stress` and `accuracy` with their defaults (--json), every run they recommend
(stress: the recommendation and its ties in the defaults and long-horizon regimes; accuracy: the
fastest at each level) run again by `simulate` at 2001 samples and measured against the reference
here; `simulate --method auto` and five methods at rtol 1e-8. Each command's exit code, wall time
and CPU time (user + system of the child process, getrusage) are recorded.

    PYTHONPATH=. LAGRANGE_CACHE_DIR=/tmp/audit3-cache .venv/bin/python benchmarks/numeric_audit3.py [--only NAME] [--json out.json] [--table]

`--table FILE.json` prints the markdown table of BENCHMARKS.md from a saved run.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sympy as sp
import yaml
from scipy.integrate import solve_ivp
from scipy.special import ellipj, ellipk

ROOT = Path(__file__).resolve().parent.parent
AUDIT = ROOT / "tests" / "numeric_audit3"
PY = sys.executable
SAMPLES = 2001
REF_CACHE = Path(os.environ.get("AUDIT3_REF_CACHE", "/tmp/audit3-ref"))
t = sp.Symbol("t")
G = 9.81


@dataclass
class System:
    file: str
    q: list[sp.Symbol]
    T: sp.Expr
    V: sp.Expr
    y0: list[float]
    stiff: bool
    to_lagrange: Callable[[np.ndarray], np.ndarray]
    """reference rows (own coordinates, own velocities) -> lagrange's coordinates and velocities."""
    D: sp.Expr = sp.S.Zero
    Q: list[sp.Expr] = field(default_factory=list)
    constraints: list[sp.Expr] = field(default_factory=list)
    """velocity-level constraints c(q, qd, t) = 0, linear in qd (d/dt of a holonomic one)."""
    exact: Callable[[np.ndarray], np.ndarray] | None = None
    wrap: tuple[int, ...] = ()
    """components compared modulo 2 pi."""


def qd(s: sp.Symbol) -> sp.Symbol:
    return sp.Symbol(f"{s}_d")


def _rhs(s: System) -> Callable[[float, np.ndarray], np.ndarray]:
    """Euler-Lagrange with Rayleigh dissipation, generalized forces and multipliers, derived here:
    [[M, -A^T], [A, 0]] [qdd, lambda] = [f, -r] with A = dc/dqd, r = dc/dq qd + dc/dt."""
    q, v = s.q, [qd(x) for x in s.q]
    n, L = len(q), s.T - s.V
    Q = s.Q or [sp.Integer(0)] * n
    M = sp.Matrix(n, n, lambda i, j: sp.diff(L, v[i], v[j]))
    f = sp.Matrix([Q[i] - sp.diff(s.D, v[i]) + sp.diff(L, q[i]) - sum(sp.diff(L, v[i], q[j]) * v[j] for j in range(n)) - sp.diff(L, v[i], t) for i in range(n)])
    k = len(s.constraints)
    if k:
        A = sp.Matrix(k, n, lambda i, j: sp.diff(s.constraints[i], v[j]))
        r = sp.Matrix([sum(sp.diff(c, q[j]) * v[j] for j in range(n)) + sp.diff(c, t) for c in s.constraints])
        M = sp.Matrix(sp.BlockMatrix([[M, -A.T], [A, sp.zeros(k, k)]]))
        f = sp.Matrix([*f, *(-r)])
    Mf = sp.lambdify([t, *q, *v], M, "numpy")
    ff = sp.lambdify([t, *q, *v], f, "numpy")

    def rhs(time_: float, y: np.ndarray) -> np.ndarray:
        a = np.linalg.solve(np.asarray(Mf(time_, *y), dtype=float), np.asarray(ff(time_, *y), dtype=float).ravel())
        return np.concatenate([y[n:], a[:n]])

    return rhs


def _syms(names: str) -> list[sp.Symbol]:
    return list(sp.symbols(names))


def _kepler(ts: np.ndarray, e: float, a: float, k: float) -> np.ndarray:
    """x, y, x_dot, y_dot of the orbit from periapsis on the +x axis at t = 0, exactly."""
    n = math.sqrt(k / a**3)
    b = a * math.sqrt(1 - e * e)
    rows = []
    for time_ in ts:
        M = math.fmod(n * time_, 2 * math.pi)
        E = M + e * math.sin(M)
        for _ in range(100):
            dE = (E - e * math.sin(E) - M) / (1 - e * math.cos(E))
            E -= dE
            if abs(dE) < 1e-16:
                break
        Ed = n / (1 - e * math.cos(E))
        rows.append([a * (math.cos(E) - e), b * math.sin(E), -a * math.sin(E) * Ed, b * math.cos(E) * Ed])
    return np.array(rows)


def _pendulum_exact(ts: np.ndarray, theta0: float, length: float) -> np.ndarray:
    """A pendulum released from rest at theta0 (Jacobi): sin(theta/2) = k sn(K - w t | k^2), as x, y, x_dot, y_dot."""
    w, k = math.sqrt(G / length), math.sin(theta0 / 2)
    m = k * k
    sn, cn, _, _ = ellipj(ellipk(m) - w * ts, m)
    th = 2 * np.arcsin(k * sn)
    thd = -2 * k * w * cn
    return np.column_stack([length * np.sin(th), -length * np.cos(th), length * np.cos(th) * thd, length * np.sin(th) * thd])


def _linear_exact(s: System) -> Callable[[np.ndarray], np.ndarray]:
    """A linear system y' = A y (A from the derived equations at y = 0, exactly linear): y(t) by
    repeated products with expm(A dt) on evenly spaced times."""
    from scipy.linalg import expm

    rhs, n2 = _rhs(s), len(s.y0)
    A = np.column_stack([rhs(0.0, e) for e in np.eye(n2)])

    def at(ts: np.ndarray) -> np.ndarray:
        step = expm(A * (ts[1] - ts[0]))
        rows = [np.asarray(s.y0, dtype=float)]
        for _ in ts[1:]:
            rows.append(step @ rows[-1])
        return np.array(rows)

    return at


def systems() -> dict[str, System]:
    out: dict[str, System] = {}
    x1, x2, x3, x4 = _syms("x1 x2 x3 x4")
    m, k, c = [1.0, 0.5, 2.0, 1.0], [10.0, 1e7, 3.0, 1e5], [4e3, 300.0]
    X = [x1, x2, x3, x4]
    out["chain4"] = System(
        "spring_chain_4_damped.yaml",
        X,
        sum(m[i] * qd(X[i]) ** 2 / 2 for i in range(4)),
        k[0] * x1**2 / 2 + k[1] * (x2 - x1) ** 2 / 2 + k[2] * (x3 - x2) ** 2 / 2 + k[3] * (x4 - x3) ** 2 / 2,
        [0.5, 0.5001, -0.3, -0.3, 0, 0, 0, 2.0],
        True,
        lambda y: y,
        D=c[0] * (qd(x2) - qd(x1)) ** 2 / 2 + c[1] * (qd(x4) - qd(x3)) ** 2 / 2,
    )
    out["chain4"].exact = _linear_exact(out["chain4"])
    # penalty pendulum, reference in (u, th): r = l + u, so k u carries no round-off of r
    u, th = _syms("u th")
    mp, lp, kp, cp = 0.8, 1.2, 1e9, 3e4

    def polar_to_xy(y: np.ndarray) -> np.ndarray:
        r, a, rd, ad = lp + y[:, 0], y[:, 1], y[:, 2], y[:, 3]
        return np.column_stack([r * np.sin(a), -r * np.cos(a), rd * np.sin(a) + r * np.cos(a) * ad, -rd * np.cos(a) + r * np.sin(a) * ad])

    out["penalty_k1e9"] = System(
        "pendulum_xy_penalty_k1e9.yaml",
        [u, th],
        mp / 2 * (qd(u) ** 2 + (lp + u) ** 2 * qd(th) ** 2),
        kp * u**2 / 2 - mp * G * (lp + u) * sp.cos(th),
        [1e-4, 1.1, 0.0, 1.5 / 1.2001],
        True,
        polar_to_xy,
        D=cp * qd(u) ** 2 / 2,
    )
    x, y = _syms("x y")
    e, a, kk = 0.7, 1.3, 2.0
    out["kepler_e07"] = System(
        "kepler_e07_cartesian_long.yaml", [x, y], (qd(x) ** 2 + qd(y) ** 2) / 2, -kk / sp.sqrt(x**2 + y**2), [0.39, 0, 0, 2.952617265740468], False, lambda y: y, exact=lambda ts: _kepler(ts, e, a, kk)
    )
    t1, t2 = _syms("t1 t2")
    m1, m2, l1, l2 = 1.3, 0.6, 0.8, 1.1
    T = m1 / 2 * l1**2 * qd(t1) ** 2 + m2 / 2 * (l1**2 * qd(t1) ** 2 + l2**2 * qd(t2) ** 2 + 2 * l1 * l2 * sp.cos(t1 - t2) * qd(t1) * qd(t2))
    out["double_high"] = System("double_pendulum_high_energy.yaml", [t1, t2], T, -(m1 + m2) * G * l1 * sp.cos(t1) - m2 * G * l2 * sp.cos(t2), [2.0, -1.0, 6.0, -3.0], False, lambda y: y)
    # gimbal pendulum: reference in Cartesian x, y, z with the rod kept (x x_dot + y y_dot + z z_dot = 0)
    X3 = _syms("X Y Z")
    mg, lg = 0.7, 0.9
    a0, b0, ad0, bd0 = 0.0, 0.0, 0.002, 5.72276157
    pos = np.array([lg * math.cos(b0) * math.sin(a0), lg * math.sin(b0), -lg * math.cos(b0) * math.cos(a0)])
    vel = np.array(
        [
            lg * (-math.sin(b0) * math.sin(a0) * bd0 + math.cos(b0) * math.cos(a0) * ad0),
            lg * math.cos(b0) * bd0,
            lg * (math.sin(b0) * math.cos(a0) * bd0 + math.cos(b0) * math.sin(a0) * ad0),
        ]
    )

    def xyz_to_ab(yy: np.ndarray) -> np.ndarray:
        X_, Y_, Z_, Xd, Yd, Zd = yy.T
        b = np.arcsin(np.clip(Y_ / lg, -1, 1))
        a_ = np.arctan2(X_, -Z_)
        rho2 = X_**2 + Z_**2
        return np.column_stack([a_, b, (Xd * -Z_ + X_ * Zd) / rho2, Yd / np.sqrt(rho2)])

    out["gimbal_pole"] = System(
        "spherical_pendulum_gimbal_pole.yaml",
        X3,
        mg / 2 * sum(qd(s_) ** 2 for s_ in X3),
        mg * G * X3[2],
        [*pos, *vel],
        False,
        xyz_to_ab,
        constraints=[sum(s_ * qd(s_) for s_ in X3)],
        wrap=(0,),
    )
    (h,) = _syms("h,")
    mh, ah, om = 0.4, 0.8, 5.0

    def hoop_to(yy: np.ndarray) -> np.ndarray:
        return np.column_stack([ah * np.sin(yy[:, 0]), -ah * np.cos(yy[:, 0]), ah * np.cos(yy[:, 0]) * yy[:, 1], ah * np.sin(yy[:, 0]) * yy[:, 1]])

    out["hoop_kept"] = System("hoop_bead_kept_constraint.yaml", [h], mh / 2 * (ah**2 * qd(h) ** 2 + om**2 * ah**2 * sp.sin(h) ** 2), -mh * G * ah * sp.cos(h), [0.3, 0.0], False, hoop_to)
    (p,) = _syms("p,")
    lm = 1.6
    out["multiplier_swing"] = System(
        "pendulum_multiplier_large_swing.yaml",
        [p],
        0.7 / 2 * lm**2 * qd(p) ** 2,
        -0.7 * G * lm * sp.cos(p),
        [2.5, 0.0],
        False,
        lambda yy: np.column_stack([lm * np.sin(yy[:, 0]), -lm * np.cos(yy[:, 0]), lm * np.cos(yy[:, 0]) * yy[:, 1], lm * np.sin(yy[:, 0]) * yy[:, 1]]),
        exact=lambda ts: _pendulum_exact(ts, 2.5, lm),
    )
    x, y, ph = _syms("x y ph")
    ms, J, a_s, tau, w = 1.5, 0.3, -0.4, 0.8, 1.3
    cx, cy = x + a_s * sp.cos(ph), y + a_s * sp.sin(ph)
    T = ms / 2 * (sp.diff(cx, x) * qd(x) + sp.diff(cx, ph) * qd(ph)) ** 2 + ms / 2 * (qd(y) + sp.diff(cy, ph) * qd(ph)) ** 2 + J / 2 * qd(ph) ** 2
    out["sleigh_driven"] = System(
        "sleigh_driven_torque.yaml",
        [x, y, ph],
        T,
        sp.Integer(0),
        [0, 0, 0.2, 0.5 * math.cos(0.2), 0.5 * math.sin(0.2), 1.0],
        False,
        lambda yy: yy,
        Q=[sp.Integer(0), sp.Integer(0), tau * sp.cos(w * t)],
        constraints=[-sp.sin(ph) * qd(x) + sp.cos(ph) * qd(y)],
    )
    u, v = _syms("u v")
    out["duffing_driven"] = System(
        "duffing_pair_driven_particles.yaml",
        [u, v],
        1.0 / 2 * qd(u) ** 2 + 0.7 / 2 * qd(v) ** 2,
        u**2 / 2 + 5 * u**4 / 4 + v**2 / 2 + 5 * v**4 / 4 + 0.5 * (u - v) ** 2 / 2,
        [0.3, -0.2, 0.0, 0.4],
        False,
        lambda yy: yy,
        D=0.15 / 2 * (qd(u) ** 2 + qd(v) ** 2),
        Q=[2.0 * sp.cos(1.4 * t), sp.Integer(0)],
    )
    return out


@dataclass
class Ref:
    t_end: float
    y: np.ndarray
    """lagrange's coordinates and velocities at linspace(0, t_end, SAMPLES)."""
    own: float
    how: str
    cpu: float


def reference(name: str, s: System, t_end: float, file_t_end: float) -> Ref:
    """The independent reference at the SAMPLES sample times (cached on disk by system and t_end)."""
    REF_CACHE.mkdir(parents=True, exist_ok=True)
    cached = REF_CACHE / f"{name}-{t_end!r}.npz"
    if cached.exists():
        d = np.load(cached)
        return Ref(t_end, d["y"], float(d["own"]), str(d["how"]), float(d["cpu"]))
    began = time.process_time()
    ts = np.linspace(0.0, t_end, SAMPLES)
    if s.exact is not None:
        y = s.exact(ts)
        own, how = 0.0, "exact"
        if t_end <= file_t_end:  # check the exact solution against an integration of the derived equations
            window = ts[: 101 if s.stiff else SAMPLES]
            chk = solve_ivp(_rhs(s), (0, window[-1]), s.y0, method="Radau" if s.stiff else "DOP853", rtol=1e-13, atol=1e-15, t_eval=window)
            own = _error(s.to_lagrange(chk.y.T), y[: len(window)], s.wrap)
            how = f"exact; {'Radau' if s.stiff else 'DOP853'} 1e-13 of the derived equations over [0, {window[-1]:g}] agrees to"
    else:
        rhs = _rhs(s)
        first_m, second_m, second_rtol = ("Radau", "DOP853", 1e-13) if s.stiff else ("DOP853", "Radau", 1e-13)
        if not s.stiff and t_end > file_t_end:
            second_m, second_rtol = "DOP853", 1e-12
        first = solve_ivp(rhs, (0, t_end), s.y0, method=first_m, rtol=1e-13, atol=1e-15, t_eval=ts)
        if first.status != 0:
            raise RuntimeError(f"{s.file}: reference failed: {first.message}")
        second = solve_ivp(rhs, (0, t_end), s.y0, method=second_m, rtol=second_rtol, atol=1e-15, t_eval=ts)
        y = s.to_lagrange(first.y.T)
        own = _error(s.to_lagrange(second.y.T), y, s.wrap) if second.status == 0 else math.nan
        how = f"{first_m} 1e-13, {second_m} {second_rtol:g} agrees to"
    cpu = time.process_time() - began
    np.savez(cached, y=y, own=own, how=how, cpu=cpu)
    return Ref(t_end, y, own, how, cpu)


def _error(y: np.ndarray, ref: np.ndarray, wrap: tuple[int, ...] = ()) -> float:
    """Maximum over samples of max_i |y_i - ref_i| / max(1, max|ref_i|)."""
    if y.shape != ref.shape or not np.all(np.isfinite(y)):
        return math.inf
    d = np.abs(y - ref)
    for i in wrap:
        d[:, i] = np.abs(np.remainder(y[:, i] - ref[:, i] + np.pi, 2 * np.pi) - np.pi)
    return float(np.max(d / np.maximum(1.0, np.max(np.abs(ref), axis=0))))


def cli(*args: str) -> tuple[subprocess.CompletedProcess[str], float, float]:
    """A lagrange command: its result, CPU time (user + system of the child) and wall time."""
    before, wall = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    done = subprocess.run([PY, "-m", "lagrange_cli", *args], capture_output=True, text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    wall = time.perf_counter() - wall
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return done, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall


def traceback_in(done: subprocess.CompletedProcess[str]) -> bool:
    return "Traceback" in done.stderr or "Traceback" in done.stdout


def run_simulate(s: System, ref: Ref, opts: list[str], tmp: Path) -> dict[str, object]:
    out = tmp / "run.npz"
    done, cpu, wall = cli("simulate", str(AUDIT / s.file), *opts, "--t-end", repr(ref.t_end), "--samples", str(SAMPLES), "-q", "-o", str(out))
    row: dict[str, object] = {"exit": done.returncode, "cpu": cpu, "wall": wall, "traceback": traceback_in(done)}
    if out.exists():
        d = np.load(out)
        row["true_max_error"] = _error(d["y"], ref.y, s.wrap)
        row["ran"] = f"{d['method']} ({d['backend']})"
        out.unlink()
    else:
        row["true_max_error"] = math.inf
        row["stderr"] = done.stderr[-300:]
    return row


def setting_opts(method: str, backend: str, setting: str, given: object = None) -> list[str]:
    """`simulate`'s options of a claim: the report's own (`"simulate"`, complete since recfix2), else parsed from its setting text."""
    if isinstance(given, list):
        return [str(word) for word in given]
    kind, _, value = setting.partition(" ")
    opts = ["--step", value] if kind == "step" else ["--rtol", value, "--atol", f"{float(value) * 1e-3:g}"]
    return ["--method", method, "--backend", backend, *opts]


def ran_of(point: dict[str, object]) -> tuple[str, str]:
    text = str(point.get("ran") or point["method"])
    method, _, backend = text.partition(" (")
    return method.strip(), backend.rstrip(")") or "auto"


def audit(name: str, s: System, tmp: Path) -> dict[str, object]:
    path = str(AUDIT / s.file)
    t_file = float(yaml.safe_load(Path(path).read_text())["simulate"]["t_end"])
    result: dict[str, object] = {"system": name, "file": s.file, "dof": len(s.q) - len(s.constraints) if s.constraints else len(s.q)}
    refs: dict[float, Ref] = {}

    def ref_for(t_end: float) -> Ref:
        if t_end not in refs:
            refs[t_end] = reference(name, s, t_end, t_file)
        return refs[t_end]

    base = ref_for(t_file)
    result["reference"] = {"how": base.how, "own_error": base.own, "cpu": base.cpu}
    # stress with defaults
    done, cpu, wall = cli("stress", path, "--json", str(tmp / "stress.json"), "-q")
    result["stress_run"] = {"exit": done.returncode, "cpu": cpu, "wall": wall, "traceback": traceback_in(done), "tail": done.stdout[-400:] + done.stderr[-400:]}
    checks = []
    if (tmp / "stress.json").exists():
        report = json.loads((tmp / "stress.json").read_text())
        (tmp / "stress.json").unlink()
        result["stress_accuracy"] = report["accuracy"]
        for regime in report["regimes"]:
            row: dict[str, object] = {
                "regime": regime["regime"],
                "verdict": regime["verdict"],
                "t_end": regime["t_end"],
                "reference": regime["reference"],
                "reference_error": regime.get("reference_error"),
                "open_reason": regime.get("open_reason"),
                "findings": [f[:200] for f in regime["findings"]],
            }
            row["blowup_reported"] = any("blow-up" in f or "blew up" in f for f in regime["findings"])
            if regime["regime"] == "defaults" or regime["regime"].startswith("long horizon"):
                ref = ref_for(float(regime["t_end"]))
                row["ref_own"] = ref.own
                claims = []
                for p in [regime["recommended"], *regime["ties"]]:
                    if not p:
                        continue
                    method, backend = ran_of(p)
                    info = run_simulate(s, ref, setting_opts(method, backend, str(p["setting"]), p.get("simulate")), tmp)
                    reported = p.get("max_error", p.get("error"))
                    claims.append({"method": method, "backend": backend, "setting": p["setting"], "reported": reported, **info, "meets": info["true_max_error"] <= report["accuracy"]})  # type: ignore[operator]
                row["claims"] = claims
            checks.append(row)
    result["stress"] = checks
    # accuracy with defaults
    done, cpu, wall = cli("accuracy", path, "--json", str(tmp / "accuracy.json"), "-q")
    result["accuracy_run"] = {"exit": done.returncode, "cpu": cpu, "wall": wall, "traceback": traceback_in(done), "tail": done.stdout[-400:] + done.stderr[-400:]}
    claims = []
    if (tmp / "accuracy.json").exists():
        study = json.loads((tmp / "accuracy.json").read_text())
        (tmp / "accuracy.json").unlink()
        ref = ref_for(float(study["t_end"]))
        rows = {(p["method"], p["setting"]): p for p in study["points"]}
        for f in study["fastest"]:
            p = rows.get((f["method"], f["setting"]), {"method": f["method"]})
            method, backend = ran_of(p)
            info = run_simulate(s, ref, setting_opts(method, backend, str(f["setting"]), f.get("simulate")), tmp)
            claims.append(
                {
                    "level": f["error"],
                    "method": method,
                    "backend": backend,
                    "setting": f["setting"],
                    "reported": p.get("max_error", f["error_reached"]),
                    **info,
                    "meets": info["true_max_error"] <= f["error"],
                }  # type: ignore[operator]
            )
        result["accuracy_reference"] = study.get("reference")
    result["accuracy"] = claims
    # simulate: auto and five methods at rtol 1e-8 over the file's t_end
    runs = []
    for method, backend in [("auto", "auto"), ("DOP853", "compiled"), ("RK45", "compiled"), ("Radau", "python"), ("LSODA", "python"), ("symplectic", "auto")]:
        opts = ["--method", method, "--backend", backend] + ([] if method == "symplectic" else ["--rtol", "1e-8", "--atol", "1e-11"])
        runs.append({"method": method, "backend": backend, **run_simulate(s, base, opts, tmp)})
    result["simulate"] = runs
    return result


def fmt(x: object) -> str:
    return f"{x:.1e}" if isinstance(x, float) and math.isfinite(x) else str(x)


def table(results: list[dict[str, object]]) -> str:
    lines = [
        "| system | reference (own error) | `stress` exit, CPU / wall s | stress verdicts | stress claims: reported -> true max error | `accuracy` exit, CPU / wall s | accuracy fastest: meet / claimed, worst true/reported | auto at rtol 1e-8: ran, true error, CPU s (best other method, CPU s) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        ref = r["reference"]  # type: ignore[index]
        st, ac = r["stress_run"], r["accuracy_run"]  # type: ignore[index]
        verdicts = ", ".join(f"{g['verdict']}{' (blow-up)' if g['blowup_reported'] else ''}" for g in r["stress"])  # type: ignore[union-attr,index]
        claims = "; ".join(
            f"{g['regime'].split(' (')[0]}: {c['method']} {c['backend']} {c['setting']} {fmt(c['reported'])} -> {fmt(c['true_max_error'])}{'' if c['meets'] else ' FAILS'}"
            for g in r["stress"]  # type: ignore[union-attr]
            for c in g.get("claims", [])  # type: ignore[union-attr]
        )
        acc = r["accuracy"]  # type: ignore[assignment]
        met = sum(1 for c in acc if c["meets"])  # type: ignore[union-attr,index]
        ratios = [c["true_max_error"] / c["reported"] for c in acc if isinstance(c["reported"], (int, float)) and c["reported"] and math.isfinite(c["true_max_error"])]  # type: ignore[union-attr,index,operator]
        fails = ", ".join(f"{fmt(c['level'])}: {c['method']} {c['setting']} true {fmt(c['true_max_error'])}" for c in acc if not c["meets"])  # type: ignore[union-attr,index]
        sims = r["simulate"]  # type: ignore[assignment]
        auto = sims[0]  # type: ignore[index]
        accurate = [x for x in sims[1:] if x["exit"] == 0 and x["true_max_error"] <= max(10 * auto["true_max_error"], 1e-6)]  # type: ignore[index,union-attr,operator]
        best = min(accurate, key=lambda x: x["cpu"]) if accurate else None  # type: ignore[index]
        lines.append(
            f"| {r['file'].removesuffix('.yaml')} | {ref['how']} {fmt(ref['own_error'])} | {st['exit']}, {st['cpu']:.1f} / {st['wall']:.1f} | {verdicts} | {claims or '-'} | {ac['exit']}, {ac['cpu']:.1f} / {ac['wall']:.1f} | "  # type: ignore[index]
            f"{met}/{len(acc)}, {fmt(max(ratios)) if ratios else '-'}{' FAILS ' + fails if fails else ''} | {auto.get('ran', 'none')}, {fmt(auto['true_max_error'])}, {auto['cpu']:.2f} "  # type: ignore[union-attr,index]
            f"({best['method'] + ' ' + best['backend'] + ', ' + format(best['cpu'], '.2f') if best else '-'}) |"  # type: ignore[index]
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--only", action="append", default=[])
    parser.add_argument("--json", default="")
    parser.add_argument("--table", default="", help="print the table of a saved --json run and stop")
    args = parser.parse_args()
    if args.table:
        print(table(json.loads(Path(args.table).read_text())))
        return
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average {os.getloadavg()}", flush=True)
    found = systems()
    results = []
    with tempfile.TemporaryDirectory() as d:
        for name, s in found.items():
            if args.only and name not in args.only:
                continue
            results.append(audit(name, s, Path(d)))
            print(json.dumps(results[-1], default=float), flush=True)
            if args.json:
                Path(args.json).write_text(json.dumps(results, indent=1, default=float))
    print(f"# done {time.strftime('%H:%M UTC', time.gmtime())}, load average {os.getloadavg()}")
    print(table(results))


if __name__ == "__main__":
    main()
