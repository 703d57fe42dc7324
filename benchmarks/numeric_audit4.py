"""Issue 15, audit 4: `simulate`, `accuracy` and `stress` on eight systems the project has not seen
(tests/numeric_audit4/*.yaml), against references computed here, independently of lagrange.

References (nothing of lagrange_cli is imported): each system's equations are derived here by plain
sympy from a Lagrangian, Rayleigh function, generalized forces and constraints written by hand, in
other coordinates than the file's where that makes the reference independent (the elastic pendulum
in Cartesian X, Y; the stiff double pendulum in the spring's extension u = r2 - l2; the spherical
pendulum in Cartesian X, Y, Z with its rod as a multiplier; the trammel in its one angle), and
integrated by scipy's solve_ivp at rtol 1e-13: Radau confirmed by DOP853 on stiff systems, DOP853
confirmed by Radau otherwise (long horizons: confirmed by the same method at rtol 1e-12). Kepler's
orbit (e = 0.8, polar) is Kepler's equation solved by Newton, checked against DOP853 1e-13. The
reference is evaluated at exactly the 2001 sample times of the runs. Errors: the maximum over the
samples of max_i |y_i - y_ref,i| / max(1, max_t |y_ref,i|) (lagrange's own scaling), angles that
the reference cannot unwrap compared modulo 2 pi.

For each system: `simulate --method auto` and five methods at rtol 1e-8; `stress` and `accuracy`
with their defaults (--json); every run they recommend (stress: the recommendation and its ties in
the defaults, long-horizon and high-energy regimes; accuracy: the fastest at each level) run again
by `simulate` with the report's own options at 2001 samples and measured against the reference.
Each command's exit code, wall time and CPU time (user + system of the child, getrusage) are
recorded. `--cold` instead times stress, accuracy and simulate auto each from an empty cache.

    cp -r WARM /tmp/audit4-cache-X   # a cache warmed by another system (kernels compiled, system new)
    PYTHONPATH=. LAGRANGE_CACHE_DIR=/tmp/audit4-cache-X .venv/bin/python benchmarks/numeric_audit4.py [--only NAME] [--json out.json] [--cold]
    .venv/bin/python benchmarks/numeric_audit4.py --table out1.json,out2.json
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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sympy as sp
import yaml
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numeric_audit3
from numeric_audit3 import Ref, _error, _rhs, _syms, fmt, qd, traceback_in  # audit 3's derivation and measures, shared

ROOT = Path(__file__).resolve().parent.parent
AUDIT = ROOT / "tests" / "numeric_audit4"
PY = sys.executable
SAMPLES = 2001
REF_CACHE = Path(os.environ.get("AUDIT4_REF_CACHE", "/tmp/audit4-ref"))
RESULTS = Path(os.environ.get("AUDIT4_RESULTS", "/tmp/audit4-results"))
t = sp.Symbol("t")
G = 9.81


@dataclass
class System(numeric_audit3.System):
    """Audit 3's system record, and the names of a reference in the file's own coordinates."""

    names: list[str] = field(default_factory=list)
    """the file's coordinates and velocities, when the reference is in the file's coordinates (identity map)."""

    @property
    def identity(self) -> bool:
        return bool(self.names)


def _kepler_polar(ts: np.ndarray, e: float, a: float, k: float) -> np.ndarray:
    """r, phi, r_dot, phi_dot of the orbit from periapsis on the +x axis at t = 0, exactly (Kepler's
    equation by Newton on the reduced mean anomaly; phi the true anomaly, continuous across orbits)."""
    n = math.sqrt(k / a**3)
    h = math.sqrt(k * a * (1 - e * e))
    beta = e / (1 + math.sqrt(1 - e * e))
    rows = []
    for time_ in ts:
        M_all = n * time_
        M = math.fmod(M_all, 2 * math.pi)
        E = M + 0.85 * e * (1 if math.sin(M) >= 0 else -1)
        for _ in range(100):
            dE = (E - e * math.sin(E) - M) / (1 - e * math.cos(E))
            E -= dE
            if abs(dE) < 1e-16:
                break
        E += M_all - M
        r = a * (1 - e * math.cos(E))
        Ed = n / (1 - e * math.cos(E))
        nu = E + 2 * math.atan2(beta * math.sin(E), 1 - beta * math.cos(E))
        rows.append([r, nu, a * e * math.sin(E) * Ed, h / r**2])
    return np.array(rows)


def systems() -> dict[str, System]:
    out: dict[str, System] = {}
    # 1. elastic pendulum: reference in Cartesian X, Y (the file is in r, phi)
    X, Y = _syms("X Y")
    m, l0, k, c, b = 0.35, 0.9, 60.0, 0.4, 0.05
    rr = sp.sqrt(X**2 + Y**2)
    r0, p0, rd0, pd0 = 1.1, 1.2, 0.0, -0.5

    def xy_to_rphi(yy: np.ndarray) -> np.ndarray:
        x_, y_, xd, yd = yy.T
        r = np.hypot(x_, y_)
        return np.column_stack([r, np.arctan2(x_, -y_), (x_ * xd + y_ * yd) / r, (x_ * yd - y_ * xd) / r**2])

    out["elastic"] = System(
        "elastic_pendulum_polar_damped.yaml",
        [X, Y],
        m / 2 * (qd(X) ** 2 + qd(Y) ** 2),
        m * G * Y + k * (rr - l0) ** 2 / 2,
        [r0 * math.sin(p0), -r0 * math.cos(p0), rd0 * math.sin(p0) + r0 * math.cos(p0) * pd0, -rd0 * math.cos(p0) + r0 * math.sin(p0) * pd0],
        False,
        xy_to_rphi,
        D=c * ((X * qd(X) + Y * qd(Y)) / rr) ** 2 / 2 + b * (X * qd(Y) - Y * qd(X)) ** 2 / rr**2 / 2,
        wrap=(1,),
    )
    # 2. stiff spring double pendulum: reference in the extension u = r2 - l2 (no round-off of r2)
    th1, u, th2 = _syms("th1 u th2")
    m1, m2, l1, l2, ks, cs = 1.1, 0.4, 0.7, 0.5, 5e7, 200.0
    x1, y1 = l1 * sp.sin(th1), -l1 * sp.cos(th1)
    x2, y2 = x1 + (l2 + u) * sp.sin(th2), y1 - (l2 + u) * sp.cos(th2)

    def vel2(e: sp.Expr) -> sp.Expr:
        return sum(sp.diff(e, s_) * qd(s_) for s_ in (th1, u, th2))

    out["stiff_double"] = System(
        "stiff_spring_double_pendulum.yaml",
        [th1, u, th2],
        m1 / 2 * (vel2(x1) ** 2 + vel2(y1) ** 2) + m2 / 2 * (vel2(x2) ** 2 + vel2(y2) ** 2),
        m1 * G * y1 + m2 * G * y2 + ks * u**2 / 2,
        [0.9, 2e-5, -0.4, 0.0, 0.0, 1.5],
        True,
        lambda yy: np.column_stack([yy[:, 0], l2 + yy[:, 1], yy[:, 2], yy[:, 3], yy[:, 4], yy[:, 5]]),
        D=cs * qd(u) ** 2 / 2,
    )
    # 3. cart with a damper of decay 1e5/s, driven
    x, th = _syms("x th")
    Mc, mb, lb, kc, cc, F, w = 0.25, 0.15, 0.6, 40.0, 2.5e4, 3.0, 2.0
    bx, by = x + lb * sp.sin(th), -lb * sp.cos(th)

    def vel_c(e: sp.Expr) -> sp.Expr:
        return sp.diff(e, x) * qd(x) + sp.diff(e, th) * qd(th)

    out["cart_damper"] = System(
        "cart_pendulum_damper_1e5_driven.yaml",
        [x, th],
        Mc / 2 * qd(x) ** 2 + mb / 2 * (vel_c(bx) ** 2 + vel_c(by) ** 2),
        kc * x**2 / 2 + mb * G * by,
        [0.02, 0.8, 0.0, 0.0],
        True,
        lambda yy: yy,
        names=["x", "theta", "x_dot", "theta_dot"],
        D=cc * qd(x) ** 2 / 2,
        Q=[F * sp.cos(w * t), sp.Integer(0)],
    )
    # 4. bead on a parabolic wire on a freely turning frame
    s_, ph = _syms("s ph")
    mbd, aw, mh, R = 0.2, 2.0, 1.0, 0.3
    out["bead_parabola"] = System(
        "bead_free_rotating_parabola.yaml",
        [s_, ph],
        mbd / 2 * (qd(s_) ** 2 + s_**2 * qd(ph) ** 2 + (2 * aw * s_ * qd(s_)) ** 2) + mh / 2 * R**2 * qd(ph) ** 2,
        mbd * G * aw * s_**2,
        [0.02, 0.0, 0.0, 6.0],
        False,
        lambda yy: yy,
        names=["s", "phi", "s_dot", "phi_dot"],
    )
    # 5. spherical pendulum near its pole: reference in Cartesian X, Y, Z with the rod kept
    X3 = _syms("X Y Z")
    ms, ls = 0.5, 1.3
    t0, f0, td0, fd0 = 0.6, 0.0, 0.0, 0.002
    pos = [ls * math.sin(t0) * math.cos(f0), ls * math.sin(t0) * math.sin(f0), -ls * math.cos(t0)]
    vel = [
        ls * (math.cos(t0) * math.cos(f0) * td0 - math.sin(t0) * math.sin(f0) * fd0),
        ls * (math.cos(t0) * math.sin(f0) * td0 + math.sin(t0) * math.cos(f0) * fd0),
        ls * math.sin(t0) * td0,
    ]

    def xyz_to_polar(yy: np.ndarray) -> np.ndarray:
        x_, y_, z_, xd, yd, zd = yy.T
        rho = np.hypot(x_, y_)
        rhod = (x_ * xd + y_ * yd) / rho
        return np.column_stack([np.arctan2(rho, -z_), np.arctan2(y_, x_), (rhod * -z_ + rho * zd) / (rho**2 + z_**2), (x_ * yd - y_ * xd) / rho**2])

    out["spherical_pole"] = System(
        "spherical_pendulum_polar_near_pole.yaml",
        X3,
        ms / 2 * sum(qd(q_) ** 2 for q_ in X3),
        ms * G * X3[2],
        [*pos, *vel],
        False,
        xyz_to_polar,
        constraints=[sum(q_ * qd(q_) for q_ in X3)],
        wrap=(1,),
    )
    # 6. chaotic Duffing
    (xd_,) = _syms("x,")
    out["duffing_chaos"] = System(
        "duffing_double_well_forced.yaml",
        [xd_],
        qd(xd_) ** 2 / 2,
        -(xd_**2) / 2 + xd_**4 / 4,
        [0.5, 0.1],
        False,
        lambda yy: yy,
        names=["x", "x_dot"],
        D=0.25 * qd(xd_) ** 2 / 2,
        Q=[0.42 * sp.cos(1.15 * t)],
    )
    # 7. Kepler e = 0.8 in polar coordinates: exact
    r_, f_ = _syms("r f")
    ek, ak, kk = 0.8, 0.9, 1.5
    out["kepler_e08"] = System(
        "kepler_e08_polar.yaml",
        [r_, f_],
        (qd(r_) ** 2 + r_**2 * qd(f_) ** 2) / 2,
        -kk / r_,
        [ak * (1 - ek), 0.0, 0.0, math.sqrt(kk * (1 + ek) / (ak * (1 - ek))) / (ak * (1 - ek))],
        False,
        lambda yy: yy,
        names=["r", "phi", "r_dot", "phi_dot"],
        exact=lambda ts: _kepler_polar(ts, ek, ak, kk),
    )
    # 8. trammel: reference in the rod's angle from the upright (one coordinate, no multiplier)
    (q,) = _syms("q,")
    mt1, mt2, lt, kt = 0.6, 0.9, 0.75, 20.0
    out["trammel"] = System(
        "trammel_kept_rod.yaml",
        [q],
        mt1 / 2 * (lt * sp.cos(q) * qd(q)) ** 2 + mt2 / 2 * (lt * sp.sin(q) * qd(q)) ** 2,
        mt2 * G * lt * sp.cos(q) + kt * lt**2 * sp.sin(q) ** 2 / 2,
        [1.0, 0.0],
        False,
        lambda yy: np.column_stack([lt * np.sin(yy[:, 0]), lt * np.cos(yy[:, 0]), lt * np.cos(yy[:, 0]) * yy[:, 1], -lt * np.sin(yy[:, 0]) * yy[:, 1]]),
    )
    return out


def reference(name: str, s: System, t_end: float, file_t_end: float, energy: float = 1.0, moved: str = "") -> Ref:
    """The independent reference at the SAMPLES sample times (cached on disk by system, t_end and
    velocity factor). `energy` multiplies the initial velocities (stress's high-energy regime): the
    map from generalized to Cartesian velocities is linear at fixed q, so the factor carries over to
    the reference's own coordinates."""
    REF_CACHE.mkdir(parents=True, exist_ok=True)
    cached = REF_CACHE / f"{name}-{t_end!r}-{energy!r}{'-' + moved if moved else ''}.npz"
    if cached.exists():
        d = np.load(cached)
        return Ref(t_end, d["y"], float(d["own"]), str(d["how"]), float(d["cpu"]))
    began = time.process_time()
    ts = np.linspace(0.0, t_end, SAMPLES)
    half = len(s.y0) // 2
    y0 = [*s.y0[:half], *(energy * v for v in s.y0[half:])]
    if moved:  # "name=value,..." in the file's coordinates (only for references in the file's coordinates)
        y0 = list(s.y0)
        for word in moved.split(","):
            key, _, value = word.partition("=")
            y0[s.names.index(key)] = float(value)
    if s.exact is not None and energy == 1.0 and not moved:
        y = s.exact(ts)
        own, how = 0.0, "exact"
        if t_end <= file_t_end:  # check the exact solution against an integration of the derived equations
            chk = solve_ivp(_rhs(s), (0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-15, t_eval=ts)
            own = _error(s.to_lagrange(chk.y.T), y, s.wrap)
            how = "exact; DOP853 1e-13 of the derived equations agrees to"
    else:
        rhs = _rhs(s)
        first_m, second_m, second_rtol = ("Radau", "DOP853", 1e-13) if s.stiff else ("DOP853", "Radau", 1e-13)
        if t_end > file_t_end:
            second_m, second_rtol = (first_m, 1e-12)
        first = solve_ivp(rhs, (0, t_end), y0, method=first_m, rtol=1e-13, atol=1e-15, t_eval=ts)
        if first.status != 0:
            raise RuntimeError(f"{s.file}: reference failed: {first.message}")
        second = solve_ivp(rhs, (0, t_end), y0, method=second_m, rtol=second_rtol, atol=1e-15, t_eval=ts)
        y = s.to_lagrange(first.y.T)
        own = _error(s.to_lagrange(second.y.T), y, s.wrap) if second.status == 0 else math.nan
        how = f"{first_m} 1e-13, {second_m} {second_rtol:g} agrees to"
    cpu = time.process_time() - began
    np.savez(cached, y=y, own=own, how=how, cpu=cpu)
    return Ref(t_end, y, own, how, cpu)


CACHE = os.environ.get("LAGRANGE_CACHE_DIR", "")
REUSE = False
STRESS_ONLY = False


def cli(*args: str, cache: str = "") -> tuple[subprocess.CompletedProcess[str], float, float]:
    """A lagrange command: its result, CPU time (user + system of the child) and wall time."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if cache or CACHE:
        env["LAGRANGE_CACHE_DIR"] = cache or CACHE
    before, wall = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    done = subprocess.run([PY, "-m", "lagrange_cli", *args], capture_output=True, text=True, cwd=ROOT, env=env)
    wall = time.perf_counter() - wall
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return done, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall


def run_simulate(s: System, ref: Ref, opts: list[str], tmp: Path, initial: list[str] = []) -> dict[str, object]:  # noqa: B006
    out = tmp / "run.npz"
    done, cpu, wall = cli("simulate", str(AUDIT / s.file), *initial, *opts, "--t-end", repr(ref.t_end), "--samples", str(SAMPLES), "-q", "-o", str(out))
    row: dict[str, object] = {"exit": done.returncode, "cpu": cpu, "wall": wall, "traceback": traceback_in(done), "opts": opts}
    if out.exists():
        d = np.load(out)
        row["true_max_error"] = _error(d["y"], ref.y, s.wrap)
        row["ran"] = f"{d['method']} ({d['backend']})"
        out.unlink()
    else:
        row["true_max_error"] = math.inf
    if done.returncode != 0:
        row["stderr"] = done.stderr[-400:]
    return row


def velocities_initial(path: str, energy: float) -> list[str]:
    """--initial setting every velocity of the file to `energy` x its value (stress's high-energy regime)."""
    data = yaml.safe_load(Path(path).read_text())
    moved = [f"{c}_dot={energy * float(data['initial'].get(c + '_dot', 0.0))!r}" for c in data["coordinates"]]
    return ["--initial", ",".join(moved)]


def try_lines(text: str) -> dict[str, dict[str, str]]:
    """The options of the first `try:` line of each regime in stress's text report: {regime: {option: value}}."""
    import re
    import shlex

    out: dict[str, dict[str, str]] = {}
    regime = ""
    for line in text.splitlines():
        head = re.match(r"^(\S.*): t_end = ", line)
        if head:
            regime = head.group(1)
        elif line.startswith("  try: ") and regime and regime not in out:
            words = shlex.split(line[len("  try: ") :])
            out[regime] = {w_: words[i + 1] for i, w_ in enumerate(words[:-1]) if w_.startswith("--")}
    return out


def audit(name: str, s: System, tmp: Path) -> dict[str, object]:
    path = str(AUDIT / s.file)
    t_file = float(yaml.safe_load(Path(path).read_text())["simulate"]["t_end"])
    result: dict[str, object] = {"system": name, "file": s.file, "dof": len(s.q) - len(s.constraints)}
    base = reference(name, s, t_file, t_file)
    result["reference"] = {"how": base.how, "own_error": base.own, "cpu": base.cpu}
    print(f"# {name}: reference {base.how} {base.own:.1e} in {base.cpu:.1f} s", file=sys.stderr, flush=True)
    # simulate --method auto, and five methods at rtol 1e-8, over the file's t_end
    runs: list[dict[str, object]] = []
    for method, backend in [] if STRESS_ONLY else [("auto", "auto"), ("DOP853", "compiled"), ("RK45", "compiled"), ("Radau", "python"), ("LSODA", "python"), ("symplectic", "auto")]:
        opts = ["--method", method, "--backend", backend] + ([] if method == "symplectic" else ["--rtol", "1e-8", "--atol", "1e-11"])
        runs.append({"method": method, "backend": backend, **run_simulate(s, base, opts, tmp)})
    if not STRESS_ONLY:
        done, cpu, wall = cli("simulate", path, "--method", "auto", "-q", "-o", str(tmp / "plain.npz"))
        runs.append({"method": "auto (file's defaults, no options)", "exit": done.returncode, "cpu": cpu, "wall": wall, "traceback": traceback_in(done)})
    result["simulate"] = runs
    print(f"# {name}: simulate done", file=sys.stderr, flush=True)
    # stress with defaults
    saved = RESULTS / f"{name}-stress-run.json"
    if REUSE and saved.exists():  # a previous run's stress report and its measurements (--reuse)
        result["stress_run"] = json.loads(saved.read_text())
        if (RESULTS / f"{name}-stress.json").exists():
            (tmp / "stress.json").write_text((RESULTS / f"{name}-stress.json").read_text())
    else:
        done, cpu, wall = cli("stress", path, "--json", str(tmp / "stress.json"))
        result["stress_run"] = {"exit": done.returncode, "cpu": cpu, "wall": wall, "traceback": traceback_in(done), "tail": done.stdout[-600:] + done.stderr[-600:]}
        saved.write_text(json.dumps(result["stress_run"]))
        (RESULTS / f"{name}-stress.txt").write_text(done.stdout + "\n--- stderr\n" + done.stderr)
    tried = try_lines((RESULTS / f"{name}-stress.txt").read_text() if (RESULTS / f"{name}-stress.txt").exists() else "")
    checks = []
    if (tmp / "stress.json").exists():
        report = json.loads((tmp / "stress.json").read_text())
        (RESULTS / f"{name}-stress.json").write_text(json.dumps(report, indent=1))
        (tmp / "stress.json").unlink()
        result["stress_accuracy"] = report["accuracy"]
        for regime in report["regimes"]:
            label = regime["regime"]
            row: dict[str, object] = {
                "regime": label,
                "verdict": regime["verdict"],
                "t_end": regime["t_end"],
                "reference": regime["reference"],
                "reference_error": regime.get("reference_error"),
                "open_reason": regime.get("open_reason"),
                "measures": {k: regime.get(k) for k in ("stiffness_ratio", "decay_x_t_end", "time_scale_ratio", "max_mass_condition", "max_mass_condition_at")},
                "findings": regime["findings"],
            }
            row["blowup_reported"] = any("blow-up" in f or "blew up" in f for f in regime["findings"])
            energy = 1.0
            moved = tried.get(label, {}).get("--initial", "")
            if label.startswith("high energy"):
                try:
                    energy = float(label.split("x")[-1].strip(" )"))
                except ValueError:  # "high energy (at rest in the file: velocities 3 x the slowest mode's rate ...)"
                    energy = math.nan
                expected = velocities_initial(path, energy)[1] if math.isfinite(energy) else ""
                if moved and {w_ for w_ in moved.split(",") if not w_.endswith("=0.0")} != {w_ for w_ in expected.split(",") if not w_.endswith("=0.0")}:
                    # stress moved other velocities than energy x the file's (e.g. all of them were 0): the
                    # reference is then made from its --initial, for systems whose reference is in the file's coordinates
                    row["initial_differs"] = moved
                    if s.identity:
                        energy = -1.0
                    else:
                        checks.append(row)
                        continue
                if not math.isfinite(energy):  # a state the audit cannot rebuild: verdicts recorded, claims not checked
                    checks.append(row)
                    continue
            recommended = [p for p in [regime["recommended"], *regime["ties"]] if p and p.get("simulate")]
            if recommended and (label == "defaults" or label.startswith("long horizon") or label.startswith("high energy")):
                try:
                    ref = reference(name, s, float(regime["t_end"]), t_file, energy, moved if energy == -1.0 else "")
                except Exception as exc:
                    row["ref_failed"] = str(exc)
                    checks.append(row)
                    continue
                row["ref_own"] = ref.own
                initial = ["--initial", moved] if energy == -1.0 else velocities_initial(path, energy) if energy != 1.0 else []
                claims = []
                for p in recommended:
                    info = run_simulate(s, ref, [str(w_) for w_ in p["simulate"]], tmp, initial)
                    reported = p.get("max_error", p.get("error"))
                    claims.append({"method": p["method"], "ran": p.get("ran"), "setting": p["setting"], "reported": reported, **info, "meets": info["true_max_error"] <= report["accuracy"]})  # type: ignore[operator]
                row["claims"] = claims
            checks.append(row)
    result["stress"] = checks
    print(f"# {name}: stress done", file=sys.stderr, flush=True)
    if STRESS_ONLY:
        result["accuracy"] = []
        return result
    # accuracy with defaults
    done, cpu, wall = cli("accuracy", path, "--json", str(tmp / "accuracy.json"))
    result["accuracy_run"] = {"exit": done.returncode, "cpu": cpu, "wall": wall, "traceback": traceback_in(done), "tail": done.stdout[-600:] + done.stderr[-600:]}
    (RESULTS / f"{name}-accuracy.txt").write_text(done.stdout + "\n--- stderr\n" + done.stderr)
    claims = []
    if (tmp / "accuracy.json").exists():
        study = json.loads((tmp / "accuracy.json").read_text())
        (RESULTS / f"{name}-accuracy.json").write_text(json.dumps(study, indent=1))
        (tmp / "accuracy.json").unlink()
        ref = reference(name, s, float(study["t_end"]), t_file)
        rows = {(p["method"], p["setting"]): p for p in study["points"]}
        for f in study["fastest"]:
            p = rows.get((f["method"], f["setting"]), {"method": f["method"]})
            opts = f.get("simulate") or p.get("simulate")
            if not opts:
                claims.append({"level": f["error"], "method": f["method"], "setting": f["setting"], "no_simulate": True, "meets": False, "true_max_error": math.inf, "reported": None})
                continue
            info = run_simulate(s, ref, [str(w_) for w_ in opts], tmp)
            claims.append(
                {"level": f["error"], "method": f["method"], "setting": f["setting"], "reported": p.get("max_error", f.get("error_reached")), **info, "meets": info["true_max_error"] <= f["error"]}
            )  # type: ignore[operator]
        result["accuracy_reference"] = study.get("reference")
    result["accuracy"] = claims
    return result


def cold(name: str, s: System, tmp: Path) -> dict[str, object]:
    """stress, accuracy and simulate --method auto, each from an empty cache (numba compiles everything)."""
    path = str(AUDIT / s.file)
    out: dict[str, object] = {"system": name, "cold": True}
    for label, args in [("simulate auto", ["simulate", path, "--method", "auto", "-q", "-o", str(tmp / "c.npz")]), ("stress", ["stress", path, "-q"]), ("accuracy", ["accuracy", path, "-q"])]:
        with tempfile.TemporaryDirectory() as cache:
            done, cpu, wall = cli(*args, cache=cache)
        out[label] = {"exit": done.returncode, "cpu": cpu, "wall": wall, "traceback": traceback_in(done)}
        print(f"# cold {name} {label}: exit {done.returncode}, CPU {cpu:.1f} s, wall {wall:.1f} s", file=sys.stderr, flush=True)
    return out


def table(results: list[dict[str, object]]) -> str:
    lines = [
        "| system | reference (own error) | `stress` exit, CPU / wall s | stress verdicts | stress claims: reported -> true max error | `accuracy` exit, CPU / wall s | accuracy fastest: meet / claimed, worst true/reported | auto at rtol 1e-8: ran, true error, CPU s (best other method, CPU s) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        if r.get("cold"):
            continue
        ref = r["reference"]  # type: ignore[index]
        st, ac = r["stress_run"], r.get("accuracy_run") or {"exit": "-", "cpu": math.nan, "wall": math.nan}  # type: ignore[index,union-attr]
        verdicts = ", ".join(f"{g['verdict']}{' (blow-up)' if g['blowup_reported'] else ''}" for g in r["stress"])  # type: ignore[union-attr,index]
        claims = "; ".join(
            f"{g['regime'].split(' (')[0]}: {c['ran']} {c['setting']} {fmt(c['reported'])} -> {fmt(c['true_max_error'])}{'' if c['meets'] else ' FAILS'}"
            for g in r["stress"]  # type: ignore[union-attr]
            for c in g.get("claims", [])  # type: ignore[union-attr]
        )
        acc = r["accuracy"]  # type: ignore[assignment]
        met = sum(1 for c in acc if c["meets"])  # type: ignore[union-attr,index]
        ratios = [c["true_max_error"] / c["reported"] for c in acc if isinstance(c["reported"], (int, float)) and c["reported"] and math.isfinite(c["true_max_error"])]  # type: ignore[union-attr,index,operator]
        fails = ", ".join(f"{fmt(c['level'])}: {c['method']} {c['setting']} true {fmt(c['true_max_error'])}" for c in acc if not c["meets"])  # type: ignore[union-attr,index]
        sims = r["simulate"]  # type: ignore[assignment]
        auto = sims[0] if sims else {"true_max_error": math.nan, "cpu": math.nan}  # type: ignore[index]
        accurate = [x for x in sims[1:6] if x["exit"] == 0 and x["true_max_error"] <= max(10 * auto["true_max_error"], 1e-6)]  # type: ignore[index,union-attr,operator]
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
    parser.add_argument("--cold", action="store_true", help="only time stress, accuracy and simulate auto from an empty cache")
    parser.add_argument("--table", default="", help="print the table of saved --json runs (comma-separated files) and stop")
    parser.add_argument("--reuse", action="store_true", help="take stress's report and measurements from a previous run (RESULTS)")
    parser.add_argument("--stress-only", action="store_true", help="only stress and its claims (no simulate table, no accuracy)")
    args = parser.parse_args()
    global REUSE, STRESS_ONLY
    REUSE, STRESS_ONLY = args.reuse, args.stress_only
    if args.table:
        print(table([r for f in args.table.split(",") for r in json.loads(Path(f).read_text())]))
        return
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average {os.getloadavg()}", flush=True)
    RESULTS.mkdir(parents=True, exist_ok=True)
    found = systems()
    results = []
    with tempfile.TemporaryDirectory() as d:
        for name, s in found.items():
            if args.only and name not in args.only:
                continue
            results.append(cold(name, s, Path(d)) if args.cold else audit(name, s, Path(d)))
            print(json.dumps(results[-1], default=float), flush=True)
            if args.json:
                Path(args.json).write_text(json.dumps(results, indent=1, default=float))
    print(f"# done {time.strftime('%H:%M UTC', time.gmtime())}, load average {os.getloadavg()}")
    print(table(results))


if __name__ == "__main__":
    main()
