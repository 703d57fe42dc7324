"""Issue 15: an audit of `stress`, `accuracy` and `simulate --method auto` on systems the project
has not seen (tests/numeric_audit2/*.yaml), against references computed here independently of
lagrange's own derivation and reference code.

For each system the equations are derived here from a Lagrangian, Rayleigh function and
generalized forces written by hand (sympy), in coordinates chosen for the reference: the stiff
springs in their extension u = r - l, so that k u carries no round-off of r (lagrange's r = l + u
loses it: k = 1e10 turns r's 1e-16 into forces of 1e-6). The reference is scipy's solve_ivp at
rtol 1e-12..1e-13 (Radau on stiff systems, DOP853 otherwise) confirmed by a second method (LSODA,
resp. Radau); the exact solution of Kepler's problem for the orbit. Then, per system:

(a) every run that `stress` recommends (or calls a tie) and every "fastest" run of `accuracy`,
    run again by `lagrange simulate` with its method, backend and setting over the same window at
    2001 samples, must truly meet the accuracy: the maximum pointwise error, scaled by max(1, |y|)
    per component as lagrange scales it, against the reference here;
(b) no regime of `stress` may report a blow-up where the reference here runs fine;
(c) `simulate --method auto` against every method at rtol 1e-8: its right-hand side evaluations
    (compiled ones counted at 1/100) and CPU time, within 2x of the best method that meets the
    same error (the CPU times come from the same run of this script);
(d) the CPU time of `stress` and `accuracy` with their defaults (target: under 30 s each on a
    two-degree-of-freedom system).

Run by hand (minutes; not part of the test suite):

    PYTHONPATH=. LAGRANGE_CACHE_DIR=/tmp/audit2-cache .venv/bin/python benchmarks/numeric_audit2.py [--only NAME] [--skip-accuracy]
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
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

ROOT = Path(__file__).resolve().parent.parent
AUDIT = ROOT / "tests" / "numeric_audit2"
PY = sys.executable
t = sp.Symbol("t")


@dataclass
class System:
    file: str
    q: list[sp.Symbol]
    qd: list[sp.Symbol]
    T: sp.Expr
    V: sp.Expr
    D: sp.Expr
    Q: list[sp.Expr]
    y0: list[float]
    stiff: bool
    to_lagrange: Callable[[np.ndarray], np.ndarray]
    """reference state rows (own coordinates) -> lagrange's coordinates and velocities."""
    exact: Callable[[np.ndarray], np.ndarray] | None = None


def _syms(names: str) -> tuple[list[sp.Symbol], list[sp.Symbol]]:
    q = list(sp.symbols(names))
    return q, [sp.Symbol(f"{s}_d") for s in q]


def _rhs(s: System) -> Callable[[float, np.ndarray], np.ndarray]:
    """Euler-Lagrange with Rayleigh dissipation and generalized forces, derived here: M qdd = f."""
    L = s.T - s.V
    n = len(s.q)
    M = sp.Matrix(n, n, lambda i, j: sp.diff(L, s.qd[i], s.qd[j]))
    f = sp.Matrix([s.Q[i] - sp.diff(s.D, s.qd[i]) + sp.diff(L, s.q[i]) - sum(sp.diff(L, s.qd[i], s.q[j]) * s.qd[j] for j in range(n)) - sp.diff(L, s.qd[i], t) for i in range(n)])
    Mf = sp.lambdify([t, *s.q, *s.qd], M, "numpy")
    ff = sp.lambdify([t, *s.q, *s.qd], f, "numpy")

    def rhs(time_: float, y: np.ndarray) -> np.ndarray:
        a = np.linalg.solve(np.asarray(Mf(time_, *y), dtype=float), np.asarray(ff(time_, *y), dtype=float).ravel())
        return np.concatenate([y[n:], a])

    return rhs


def systems() -> dict[str, System]:
    g = 9.81
    out: dict[str, System] = {}

    def elastic(file: str, m: float, rest: float, k: float, y0: list[float]) -> System:
        (u, th), (ud, thd) = _syms("u th")
        r = rest + u
        c = math.sqrt(k * m)
        shift = lambda y: np.column_stack([rest + y[:, 0], y[:, 1], y[:, 2], y[:, 3]])  # noqa: E731
        return System(file, [u, th], [ud, thd], m / 2 * (ud**2 + r**2 * thd**2), k * u**2 / 2 - m * g * r * sp.cos(th), c * ud**2, [0, 0], y0, True, shift)

    out["elastic_k1e8"] = elastic("elastic_pendulum_r_k1e8.yaml", 0.5, 2.0, 1e8, [0.0, 1.0, 0.0, 0.0])
    out["elastic_k1e11"] = elastic("elastic_pendulum_r_k1e11.yaml", 2.0, 0.5, 1e11, [1e-3, 0.3, 0.0, 2.0])
    (x, th), (xd, thd) = _syms("x th")
    M_, m_, l_, c_ = 2.0, 0.3, 0.7, 2e6
    T = M_ / 2 * xd**2 + m_ / 2 * ((xd + l_ * sp.cos(th) * thd) ** 2 + (l_ * sp.sin(th) * thd) ** 2)
    out["cart_long"] = System("cart_pendulum_fast_damping_long.yaml", [x, th], [xd, thd], T, -m_ * g * l_ * sp.cos(th), c_ * xd**2 / 2, [0, 0], [0.0, 0.8, 2.0, 0.0], True, lambda y: y)
    (r, ph), (rd, phd) = _syms("r ph")
    e, a = 0.9, 1.0
    out["kepler_e09"] = System(
        "kepler_e09.yaml",
        [r, ph],
        [rd, phd],
        (rd**2 + r**2 * phd**2) / 2,
        -1 / r,
        sp.Integer(0),
        [0, 0],
        [0.1, 0.0, 0.0, math.sqrt(1 - e**2) / 0.01],
        False,
        lambda y: y,
        exact=lambda ts: _kepler(ts, e, a),
    )
    (th, ph), (thd, phd) = _syms("th ph")
    ml = 1.5
    out["spherical_pole"] = System(
        "spherical_pendulum_through_pole.yaml",
        [th, ph],
        [thd, phd],
        ml**2 / 2 * (thd**2 + sp.sin(th) ** 2 * phd**2),
        -g * ml * sp.cos(th),
        sp.Integer(0),
        [0, 0],
        [0.9, 0.0, 0.0, 3e-4],
        False,
        lambda y: y,
    )
    (x1, x2, x3), (x1d, x2d, x3d) = _syms("x1 x2 x3")
    out["chain"] = System(
        "chain_mixed_stiffness.yaml",
        [x1, x2, x3],
        [x1d, x2d, x3d],
        (x1d**2 + x2d**2 + x3d**2) / 2,
        x1**2 / 2 + 1e6 * (x2 - x1) ** 2 / 2 + 1e3 * (x3 - x2) ** 2 / 2,
        2e3 * (x2d - x1d) ** 2 / 2,
        [0, 0, 0],
        [1.0, 1.01, 0.5, 0.0, 0.0, 0.0],
        True,
        lambda y: y,
    )
    (x,), (xd,) = _syms("x,")
    out["van_der_pol"] = System("van_der_pol_force.yaml", [x], [xd], xd**2 / 2, x**2 / 2, sp.Integer(0), [50 * (1 - x**2) * xd], [2.0, 0.0], True, lambda y: y)
    (x, yy), (xd, yd) = _syms("x y")
    out["driven"] = System(
        "driven_coupled_oscillators.yaml",
        [x, yy],
        [xd, yd],
        (xd**2 + yd**2) / 2,
        4 * x**2 / 2 + 4 * yy**2 / 2 + 1e5 * (yy - x) ** 2 / 2,
        400 * (yd - xd) ** 2 / 2,
        [sp.cos(1.7 * t), 0],
        [0.1, 0.0, 0.0, 0.0],
        True,
        lambda y: y,
    )
    (th, ph, ps), (thd, phd, psd) = _syms("th ph ps")
    I1, I3, mgl = 2.0, 2.0, 9.81
    out["top_pole"] = System(
        "heavy_top_zxz_near_pole.yaml",
        [th, ph, ps],
        [thd, phd, psd],
        I1 / 2 * (thd**2 + sp.sin(th) ** 2 * phd**2) + I3 / 2 * (psd + phd * sp.cos(th)) ** 2,
        mgl * sp.cos(th),
        sp.Integer(0),
        [0, 0, 0],
        [0.3, 0.0, 0.0, 0.0, 25.00168, 25.0],
        False,
        lambda y: y,
    )
    return out


def _kepler(ts: np.ndarray, e: float, a: float) -> np.ndarray:
    """r, phi, r_dot, phi_dot of the orbit starting at periapsis at t = 0 (k = m = 1), exactly."""
    n = a**-1.5
    rows = []
    for time_ in ts:
        M = n * time_
        E = M
        for _ in range(100):
            dE = (E - e * math.sin(E) - M) / (1 - e * math.cos(E))
            E -= dE
            if abs(dE) < 1e-16:
                break
        r = a * (1 - e * math.cos(E))
        turns = 2 * math.pi * math.floor((E + math.pi) / (2 * math.pi))
        half = (E - turns) / 2  # in [-pi/2, pi/2)
        nu = 2 * math.atan2(math.sqrt(1 + e) * math.sin(half), math.sqrt(1 - e) * math.cos(half))
        phi = nu + turns  # unwrapped, as lagrange's theta
        Ed = n / (1 - e * math.cos(E))
        rows.append([r, phi, a * e * math.sin(E) * Ed, math.sqrt(a * (1 - e**2)) / r**2])
    return np.array(rows)


@dataclass
class Ref:
    t_end: float
    sol: Callable[[np.ndarray], np.ndarray]
    own: float
    how: str


def reference(s: System, t_end: float) -> Ref:
    """Independent reference at dense times (lagrange's coordinates)."""
    probe = np.linspace(0, t_end, 4001)
    if s.exact is not None:
        return Ref(t_end, s.exact, 0.0, "exact (Kepler's equation)")
    rhs = _rhs(s)
    kw = {"dense_output": True}
    if s.stiff:
        first = solve_ivp(rhs, (0, t_end), s.y0, method="Radau", rtol=1e-12, atol=1e-15, **kw)
        second = solve_ivp(rhs, (0, t_end), s.y0, method="LSODA", rtol=1e-12, atol=1e-15, **kw)
        how = "Radau rtol 1e-12 atol 1e-15, confirmed by LSODA at the same"
    else:
        first = solve_ivp(rhs, (0, t_end), s.y0, method="DOP853", rtol=1e-13, atol=1e-15, **kw)
        second = solve_ivp(rhs, (0, t_end), s.y0, method="Radau", rtol=1e-12, atol=1e-14, **kw)
        how = "DOP853 rtol 1e-13 atol 1e-15, confirmed by Radau rtol 1e-12"
    if first.status != 0:
        raise RuntimeError(f"{s.file}: reference failed: {first.message}")

    def at(ts: np.ndarray) -> np.ndarray:
        return s.to_lagrange(first.sol(ts).T)

    a_, b_ = at(probe), s.to_lagrange(second.sol(probe).T) if second.status == 0 else None
    own = float(np.max(np.abs(a_ - b_) / np.maximum(1.0, np.max(np.abs(a_), axis=0)))) if b_ is not None else math.nan
    return Ref(t_end, at, own, how)


def cli(*args: str) -> tuple[subprocess.CompletedProcess[str], float]:
    """A lagrange command and its CPU time (user + system of the child)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run([PY, "-m", "lagrange_cli", *args], capture_output=True, text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return done, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def true_error(s: System, ref: Ref, method: str, backend: str, setting: str, t_end: float, tmp: Path) -> tuple[float, dict[str, object]]:
    """Run `simulate` with a study's method and setting over [0, t_end] at 2001 samples; the
    maximum pointwise scaled error against `ref`."""
    kind, _, value = setting.partition(" ")
    rtol, _, atol = value.partition(", atol ")  # "rtol 1e-07, atol 1e-10" as `stress` writes a setting now
    opts = ["--step", value] if kind == "step" else ["--rtol", rtol, "--atol", atol or f"{float(rtol) * 1e-3:g}"]
    out = tmp / "run.npz"
    done, cpu = cli("simulate", str(AUDIT / s.file), "--method", method, "--backend", backend, *opts, "--t-end", repr(t_end), "--samples", "2001", "-q", "-o", str(out))
    if not out.exists():
        return math.inf, {"exit": done.returncode, "cpu": cpu}
    d = np.load(out)
    y, ts = d["y"], d["t"]
    truth = ref.sol(ts)
    scale = np.maximum(1.0, np.max(np.abs(truth), axis=0))
    err = float(np.max(np.abs(y - truth) / scale)) if len(ts) == len(truth) else math.inf
    out.unlink()
    return err, {"exit": done.returncode, "cpu": cpu, "samples": len(ts)}


def ran_of(point: dict[str, object]) -> tuple[str, str]:
    text = str(point.get("ran") or point["method"])
    method, _, backend = text.partition(" (")
    return method.strip(), backend.rstrip(")") or "auto"


def audit(name: str, s: System, tmp: Path, do_accuracy: bool) -> dict[str, object]:
    result: dict[str, object] = {"system": name, "file": s.file, "dof": len(s.q)}
    path = str(AUDIT / s.file)
    t_file = float(__import__("yaml").safe_load(Path(path).read_text())["simulate"]["t_end"])
    refs: dict[float, Ref] = {}

    def ref_for(t_end: float) -> Ref:
        if t_end not in refs:
            refs[t_end] = reference(s, t_end)
        return refs[t_end]

    began = time.process_time()
    base = ref_for(t_file)
    result["reference"] = {"how": base.how, "own_error": base.own, "cpu": time.process_time() - began}
    # (d) and (a), (b): stress
    done, cpu = cli("stress", path, "--json", str(tmp / "stress.json"), "-q")
    result["stress_cpu"], result["stress_exit"] = cpu, done.returncode
    checks = []
    if (tmp / "stress.json").exists():
        report = json.loads((tmp / "stress.json").read_text())
        for regime in report["regimes"]:
            row: dict[str, object] = {"regime": regime["regime"], "verdict": regime["verdict"], "reference": regime["reference"], "findings": [f[:120] for f in regime["findings"]]}
            if any("blow-up" in f for f in regime["findings"]):
                row["blowup_reported"] = True
            if regime["regime"] in ("defaults",) or regime["regime"].startswith("long horizon"):
                ref = ref_for(float(regime["t_end"]))
                claimed = [p for p in [regime["recommended"], *regime["ties"]] if p]
                row["claims"] = []
                for p in claimed:
                    method, backend = ran_of(p)
                    err, info = true_error(s, ref, method, backend, str(p["setting"]), float(regime["t_end"]), tmp)
                    row["claims"].append({"method": method, "backend": backend, "setting": p["setting"], "reported": p["error"], "true_max_error": err, "meets": err <= report["accuracy"], **info})  # type: ignore[union-attr]
            checks.append(row)
    result["stress"] = checks
    if do_accuracy:
        done, cpu = cli("accuracy", path, "--json", str(tmp / "accuracy.json"), "-q")
        result["accuracy_cpu"], result["accuracy_exit"] = cpu, done.returncode
        claims = []
        if (tmp / "accuracy.json").exists():
            study = json.loads((tmp / "accuracy.json").read_text())
            rows = {(p["method"], p["setting"]): p for p in study["points"]}
            for f in study["fastest"]:
                p = rows.get((f["method"], f["setting"]), {"method": f["method"]})
                method, backend = ran_of(p)
                err, info = true_error(s, ref_for(float(study["t_end"])), method, backend, str(f["setting"]), float(study["t_end"]), tmp)
                claims.append(
                    {"level": f["error"], "method": method, "backend": backend, "setting": f["setting"], "reported": f["error_reached"], "true_max_error": err, "meets": err <= f["error"], **info}
                )
        result["accuracy"] = claims
    # (c) auto against every method at rtol 1e-8
    runs = []
    for method, backend in [("auto", "auto"), ("DOP853", "compiled"), ("RK45", "compiled"), ("Radau", "python"), ("BDF", "python"), ("LSODA", "python"), ("DOP853", "python")]:
        out = tmp / "auto.npz"
        done, cpu = cli("simulate", path, "--method", method, "--backend", backend, "--rtol", "1e-8", "--atol", "1e-11", "--samples", "2001", "-q", "-o", str(out))
        row = {"method": method, "backend": backend, "exit": done.returncode, "cpu": cpu}
        work = [line for line in done.stdout.splitlines() + done.stderr.splitlines() if "work:" in line or "method auto" in line]
        row["notes"] = [w.strip()[:160] for w in work]
        if out.exists():
            d = np.load(out)
            truth = base.sol(d["t"])
            scale = np.maximum(1.0, np.max(np.abs(truth), axis=0))
            row["true_max_error"] = float(np.max(np.abs(d["y"] - truth) / scale)) if len(d["t"]) == len(truth) else math.inf
            row["ran"] = f"{d['method']} ({d['backend']})"
            out.unlink()
        runs.append(row)
    result["auto"] = runs
    return result


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--only", action="append", default=[])
    parser.add_argument("--skip-accuracy", action="store_true")
    parser.add_argument("--json", default="")
    args = parser.parse_args()
    found = systems()
    results = []
    with tempfile.TemporaryDirectory() as d:
        for name, s in found.items():
            if args.only and name not in args.only:
                continue
            r = audit(name, s, Path(d), not args.skip_accuracy)
            results.append(r)
            print(json.dumps(r, default=float), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1, default=float))


if __name__ == "__main__":
    main()
