"""Issue 15, audit 5: `simulate`, `accuracy` and `stress` on eight systems the project has not seen
(tests/numeric_audit5/*.yaml), against references computed here, independently of lagrange.

The harness is audit 4's (benchmarks/numeric_audit4.py: the runs, the re-run of every recommendation
by `simulate`, the error measure, the table), pointed at this audit's files, result and reference
directories; only the systems are new. References (nothing of lagrange_cli is imported): plain sympy
derivations from a Lagrangian, Rayleigh function, generalized forces and constraints written here, in
other coordinates where that makes them independent (the swinging Atwood machine in the swinging
mass's Cartesian X, Y; the charge in a magnetic field in Cartesian x, y, z with A = B/2 (-y, x, 0);
Henon-Heiles in Cartesian x, y), integrated by scipy's solve_ivp at rtol 1e-13 and confirmed by a
second method; the tennis racket by Euler's equations for the body angular velocity with the rotation
matrix (dR/dt = R [omega]x, 12 unknowns, no Euler angles), its angles read off R; the others in the
file's coordinates by this file's own derivation (the sleigh's blade as a velocity constraint with a
multiplier).

    cp -r WARM /tmp/audit5-cache-X   # a cache warmed by another system (kernels compiled, system new)
    PYTHONPATH=. LAGRANGE_CACHE_DIR=/tmp/audit5-cache-X .venv/bin/python benchmarks/numeric_audit5.py [--only NAME] [--json out.json]
    .venv/bin/python benchmarks/numeric_audit5.py --table out1.json,out2.json
"""

from __future__ import annotations

import json
import math
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import sympy as sp
import yaml
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numeric_audit4
from numeric_audit3 import _syms, qd
from numeric_audit4 import System

ROOT = Path(__file__).resolve().parent.parent
AUDIT = ROOT / "tests" / "numeric_audit5"
t = sp.Symbol("t")
G = 9.81


def _vel(e: sp.Expr, q: list[sp.Symbol]) -> sp.Expr:
    """Total time derivative of a position component (explicit time included)."""
    return sum(sp.diff(e, x) * qd(x) for x in q) + sp.diff(e, t)


def _polar(yy: np.ndarray) -> np.ndarray:
    """Cartesian X, Y, X_dot, Y_dot -> r, phi (atan2(Y, X)), r_dot, phi_dot."""
    x_, y_, xd, yd = yy.T
    r = np.hypot(x_, y_)
    return np.column_stack([r, np.arctan2(y_, x_), (x_ * xd + y_ * yd) / r, (x_ * yd - y_ * xd) / r**2])


def _rot(a1: sp.Expr, a2: sp.Expr, a3: sp.Expr) -> sp.Matrix:
    """R = R_z(a1) R_x(a2) R_z(a3), written out here."""

    def rz(a: sp.Expr) -> sp.Matrix:
        return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])

    rx = sp.Matrix([[1, 0, 0], [0, sp.cos(a2), -sp.sin(a2)], [0, sp.sin(a2), sp.cos(a2)]])
    return rz(a1) * rx * rz(a3)


def _racket(inertia: tuple[float, float, float], y0: list[float]) -> tuple[list[sp.Symbol], sp.Expr, object]:
    """The free rigid body in ZXZ angles (Lagrangian from omega = axial(R^T dR/dt)) and its exact
    motion from Euler's equations with the rotation matrix, read back as angles and angle rates."""
    a = _syms("a1 a2 a3")
    R = _rot(*a)
    Rd = sum((sp.diff(R, x) * qd(x) for x in a), sp.zeros(3, 3))
    W = sp.simplify(R.T * Rd)
    om = sp.Matrix([W[2, 1], W[0, 2], W[1, 0]])
    T = sum(inertia[i] * om[i] ** 2 for i in range(3)) / 2
    J = om.jacobian([qd(x) for x in a])  # omega = J(a) a_dot
    Rf = sp.lambdify(a, R, "numpy")
    Jf = sp.lambdify(a, J, "numpy")
    I1, I2, I3 = inertia

    def euler(_t: float, y: np.ndarray) -> np.ndarray:
        w = y[:3]
        Rm = y[3:].reshape(3, 3)
        wx = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        dw = [(I2 - I3) * w[1] * w[2] / I1, (I3 - I1) * w[2] * w[0] / I2, (I1 - I2) * w[0] * w[1] / I3]
        return np.concatenate([dw, (Rm @ wx).ravel()])

    def exact(ts: np.ndarray) -> np.ndarray:
        w0 = np.asarray(Jf(*y0[:3]), dtype=float) @ np.asarray(y0[3:])
        R0 = np.asarray(Rf(*y0[:3]), dtype=float)
        sol = solve_ivp(euler, (0, ts[-1]), [*w0, *R0.ravel()], method="DOP853", rtol=1e-13, atol=1e-15, t_eval=ts)
        rows = []
        for y in sol.y.T:
            Rm = y[3:].reshape(3, 3)
            a2 = math.acos(max(-1.0, min(1.0, Rm[2, 2])))
            a1 = math.atan2(Rm[0, 2], -Rm[1, 2])
            a3 = math.atan2(Rm[2, 0], Rm[2, 1])
            rates = np.linalg.solve(np.asarray(Jf(a1, a2, a3), dtype=float), y[:3])
            rows.append([a1, a2, a3, *rates])
        return np.array(rows)

    return a, T, exact


def systems() -> dict[str, System]:
    out: dict[str, System] = {}
    # 1. swinging Atwood machine: reference in the swinging mass's Cartesian X, Y (counterweight at height r)
    X, Y = _syms("X Y")
    m, Mw = 1.0, 2.6
    rr = sp.sqrt(X**2 + Y**2)
    r0, th0 = 1.0, 1.2

    def xy_to_rtheta(yy: np.ndarray) -> np.ndarray:
        x_, y_, xd, yd = yy.T
        r = np.hypot(x_, y_)
        return np.column_stack([r, np.arctan2(x_, -y_), (x_ * xd + y_ * yd) / r, (-y_ * xd + x_ * yd) / r**2])

    out["atwood"] = System(
        "swinging_atwood_chaotic.yaml",
        [X, Y],
        m / 2 * (qd(X) ** 2 + qd(Y) ** 2) + Mw / 2 * _vel(rr, [X, Y]) ** 2,
        m * G * Y + Mw * G * rr,
        [r0 * math.sin(th0), -r0 * math.cos(th0), 0.0, 0.0],
        False,
        xy_to_rtheta,
        wrap=(1,),
    )
    # 2. charge around a centre in a magnetic field: reference in Cartesian x, y, z
    x, y, z = _syms("x y z")
    B, k = 4.0, 1.0
    rho0, z0, rhod0, phid0, zd0 = 1.0, 0.3, 0.0, 0.6, 0.2

    def cyl(yy: np.ndarray) -> np.ndarray:
        p = _polar(yy[:, [0, 1, 3, 4]])
        return np.column_stack([p[:, 0], p[:, 1], yy[:, 2], p[:, 2], p[:, 3], yy[:, 5]])

    out["diamagnetic"] = System(
        "diamagnetic_kepler_cylindrical.yaml",
        [x, y, z],
        (qd(x) ** 2 + qd(y) ** 2 + qd(z) ** 2) / 2 + B / 2 * (x * qd(y) - y * qd(x)),
        -k / sp.sqrt(x**2 + y**2 + z**2),
        [rho0, 0.0, z0, rhod0, rho0 * phid0, zd0],
        False,
        cyl,
        wrap=(1,),
    )
    # 3. Henon-Heiles at E = 1/8: reference in Cartesian x, y
    hx, hy = _syms("hx hy")
    hr0, hp0, hrd0, hpd0 = 0.1, -math.pi / 2, 0.25, 4.205155565889725
    out["henon_heiles"] = System(
        "henon_heiles_polar.yaml",
        [hx, hy],
        (qd(hx) ** 2 + qd(hy) ** 2) / 2,
        (hx**2 + hy**2) / 2 + hx**2 * hy - hy**3 / 3,
        [
            hr0 * math.cos(hp0),
            hr0 * math.sin(hp0),
            hrd0 * math.cos(hp0) - hr0 * math.sin(hp0) * hpd0,
            hrd0 * math.sin(hp0) + hr0 * math.cos(hp0) * hpd0,
        ],
        False,
        _polar,
        wrap=(1,),
    )
    # 4. Van der Pol, mu = 1000, coupled
    vx, vy = _syms("x y")
    mu, kc, ky, cv = 1000.0, 0.3, 2.0, 0.05
    out["vdp"] = System(
        "van_der_pol_mu1000_coupled.yaml",
        [vx, vy],
        (qd(vx) ** 2 + qd(vy) ** 2) / 2,
        vx**2 / 2 + kc * (vx - vy) ** 2 / 2 + ky * vy**2 / 2,
        [2.0, 0.0, 0.0, 0.0],
        True,
        lambda yy: yy,
        names=["x", "y", "x_dot", "y_dot"],
        D=cv * qd(vy) ** 2 / 2,
        Q=[mu * (1 - vx**2) * qd(vx), sp.Integer(0)],
    )
    # 5. chain of masses 1, 1e-3, 1e3
    x1, x2, x3 = _syms("x1 x2 x3")
    m1, m2, m3, kk, kn, cc = 1.0, 1e-3, 1e3, 10.0, 50.0, 0.02
    out["chain"] = System(
        "chain_mass_ratio_1e6.yaml",
        [x1, x2, x3],
        (m1 * qd(x1) ** 2 + m2 * qd(x2) ** 2 + m3 * qd(x3) ** 2) / 2,
        kk * x1**2 / 2 + kk * (x2 - x1) ** 2 / 2 + kk * (x3 - x2) ** 2 / 2 + kn * (x3 - x2) ** 4 / 4,
        [0.1, 0.0, 0.5, 0.0, 0.0, 0.0],
        True,
        lambda yy: yy,
        names=["x1", "x2", "x3", "x1_dot", "x2_dot", "x3_dot"],
        D=cc * qd(x2) ** 2 / 2,
    )
    # 6. sleigh with a sprung slider: blade as a velocity constraint with a multiplier
    sx, sy, th, s_ = _syms("x y th s")
    ms, Js, mp, aa, ks, cs = 2.0, 0.2, 0.5, 0.3, 30.0, 0.2
    q6 = [sx, sy, th, s_]
    px, py = sx + (aa + s_) * sp.cos(th), sy + (aa + s_) * sp.sin(th)
    out["sleigh"] = System(
        "sleigh_spring_slider.yaml",
        q6,
        ms / 2 * (qd(sx) ** 2 + qd(sy) ** 2) + Js / 2 * qd(th) ** 2 + mp / 2 * (_vel(px, q6) ** 2 + _vel(py, q6) ** 2),
        ks * s_**2 / 2,
        [0.0, 0.0, 0.3, 0.1, 0.8 * math.cos(0.3), 0.8 * math.sin(0.3), 1.5, 0.0],
        False,
        lambda yy: yy,
        names=["x", "y", "th", "s", "x_dot", "y_dot", "th_dot", "s_dot"],
        D=cs * qd(s_) ** 2 / 2,
        constraints=[-sp.sin(th) * qd(sx) + sp.cos(th) * qd(sy)],
    )
    # 7. tennis racket: Euler's equations and the rotation matrix
    y0r = [0.0, math.pi / 2, 0.0, 2.0, 0.002, 0.001]
    qa, Ta, exact = _racket((1.0, 2.0, 3.0), y0r)
    out["racket"] = System(
        "tennis_racket_zxz.yaml",
        qa,
        Ta,
        sp.Integer(0),
        y0r,
        False,
        lambda yy: yy,
        names=["a1", "a2", "a3", "a1_dot", "a2_dot", "a3_dot"],
        exact=exact,  # type: ignore[arg-type]
        wrap=(0, 2),
    )
    # 8. parametric swing on a sprung support (explicit time)
    px_, pth = _syms("x theta")
    mb, Ms, l0, eps, w, kx, cx = 1.0, 2.0, 1.0, 0.1, 5.531026978, 50.0, 0.5
    lt = l0 * (1 + eps * sp.cos(w * t))
    bx, by = px_ + lt * sp.sin(pth), -lt * sp.cos(pth)
    out["swing"] = System(
        "parametric_swing_sprung_support.yaml",
        [px_, pth],
        Ms / 2 * qd(px_) ** 2 + mb / 2 * (_vel(bx, [px_, pth]) ** 2 + _vel(by, [px_, pth]) ** 2),
        mb * G * by + kx * px_**2 / 2,
        [0.0, 0.05, 0.0, 0.0],
        False,
        lambda yy: yy,
        names=["x", "theta", "x_dot", "theta_dot"],
        D=cx * qd(px_) ** 2 / 2,
    )
    return out


WORK = re.compile(r"work: (\d+) steps(?: \([^)]*\))?, (\d+) evaluations")
RUN_MS = re.compile(r"time: run ([0-9.]+) (ms|s)")
CANDIDATES = [("DOP853", "compiled"), ("RK45", "compiled"), ("Radau", "python"), ("BDF", "python"), ("LSODA", "python")]


def _one(s: System, ref: numeric_audit4.Ref, opts: list[str], tmp: Path) -> dict[str, object]:
    """A simulate run over the file's t_end: true error, process CPU, its own run time and steps."""
    out = tmp / "v.npz"
    done, cpu, wall = numeric_audit4.cli("simulate", str(AUDIT / s.file), *opts, "--samples", str(numeric_audit4.SAMPLES), "-o", str(out))
    row: dict[str, object] = {"opts": opts, "exit": done.returncode, "cpu": cpu, "wall": wall, "traceback": numeric_audit4.traceback_in(done)}
    work, run = WORK.search(done.stdout), RUN_MS.search(done.stdout)
    row["steps"], row["evals"] = (int(work.group(1)), int(work.group(2))) if work else (None, None)
    row["run_s"] = (float(run.group(1)) / (1000 if run.group(2) == "ms" else 1)) if run else None
    row["decision"] = " ".join(line.strip() for line in done.stdout.splitlines()[1:3] if "->" in line)
    if out.exists():
        d = np.load(out)
        row["true_max_error"] = numeric_audit4._error(d["y"], ref.y, s.wrap)
        row["ran"] = f"{d['method']} ({d['backend']})"
        out.unlink()
    else:
        row["true_max_error"] = math.inf
        row["stderr"] = done.stderr[-300:]
    return row


def versus(name: str, s: System, tmp: Path) -> dict[str, object]:
    """Issue 15's "auto runs within 2x of the best method": `simulate --method auto` with the
    defaults, against each method's quickest run (rtol 1e-3 .. 1e-12 in decades, atol 1e-3 rtol,
    loosest first, stopped at the first that meets) whose true error is within auto's own (and
    within 1e-6). CPU is the child's user + system (getrusage), run time is simulate's own."""
    t_file = float(yaml.safe_load((AUDIT / s.file).read_text())["simulate"]["t_end"])
    ref = numeric_audit4.reference(name, s, t_file, t_file)
    auto = _one(s, ref, ["--method", "auto"], tmp)
    print(f"# {name}: auto {auto.get('ran')} error {auto['true_max_error']:.2e} CPU {auto['cpu']:.2f} s steps {auto['steps']}", file=sys.stderr, flush=True)
    goals = {"auto's error": max(float(auto["true_max_error"]), 1e-12), "1e-6": 1e-6}  # type: ignore[arg-type]
    best: dict[str, list[dict[str, object]]] = {g: [] for g in goals}
    tried = []
    for method, backend in CANDIDATES:
        for goal, level in goals.items():
            for k in range(3, 13):
                row = _one(s, ref, ["--method", method, "--backend", backend, "--rtol", f"1e-{k}", "--atol", f"1e-{k + 3}"], tmp)
                row["method"] = f"{method} ({backend})"
                tried.append(row)
                if row["exit"] != 0 and not math.isfinite(row["true_max_error"]):  # type: ignore[arg-type]
                    break
                if row["true_max_error"] <= level:  # type: ignore[operator]
                    best[goal].append(row)
                    break
            print(f"# {name}: {method} ({backend}) for {goal}: {best[goal][-1]['opts'] if best[goal] and best[goal][-1]['method'] == f'{method} ({backend})' else 'none'}", file=sys.stderr, flush=True)
    return {"system": name, "versus": True, "auto": auto, "best": best, "goals": goals, "tried": tried}


def velocities_initial(path: str, energy: float) -> list[str]:
    """Audit 4's --initial of `energy` x the file's velocities, reading expressions (`0.8*cos(0.3)`) too."""
    data = yaml.safe_load(Path(path).read_text())
    given = data["initial"]
    moved = [f"{c}_dot={energy * float(sp.sympify(str(given.get(c + '_dot', 0.0))))!r}" for c in data["coordinates"]]
    return ["--initial", ",".join(moved)]


def main() -> None:
    """Audit 4's main, pointed at this audit's files, systems, references and results; or, with
    --versus NAME,..., auto against each method's quickest run of the same accuracy."""
    numeric_audit4.AUDIT = AUDIT
    numeric_audit4.REF_CACHE = Path(os.environ.get("AUDIT5_REF_CACHE", "/tmp/audit5-ref"))
    numeric_audit4.RESULTS = Path(os.environ.get("AUDIT5_RESULTS", "/tmp/audit5-results"))
    numeric_audit4.systems = systems
    numeric_audit4.velocities_initial = velocities_initial
    if "--versus" in sys.argv:
        names = sys.argv[sys.argv.index("--versus") + 1].split(",")
        out = sys.argv[sys.argv.index("--json") + 1] if "--json" in sys.argv else ""
        print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average {os.getloadavg()}", flush=True)
        found, results = systems(), []
        with tempfile.TemporaryDirectory() as d:
            for name in names:
                results.append(versus(name, found[name], Path(d)))
                if out:
                    Path(out).write_text(json.dumps(results, indent=1, default=float))
        print(f"# done {time.strftime('%H:%M UTC', time.gmtime())}, load average {os.getloadavg()}")
        return
    numeric_audit4.main()


if __name__ == "__main__":
    main()
