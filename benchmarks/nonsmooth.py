"""Issue 15 (audit 6 F5): errors through switching surfaces, before and after locating them.

References independent of lagrange_cli:
- the ball in the cup (tests/numeric_audit6/ball_in_cup_penalty_k1e8.yaml): audit 6's own equations
  (benchmarks/numeric_audit6.py, plain sympy), integrated branch by branch: on each side of the wall the
  smooth formula of that side (free: no wall force; in contact: the penetration d - R without the max),
  the crossings located by scipy's events and the integration restarted there, scipy LSODA at rtol
  1e-12, confirmed by Radau at 1e-12 the same way (`branch_reference`);
- the bouncing mass (tests/nonsmooth/bouncing_mass.yaml): its exact solution (`bouncing_exact`).

Run: PYTHONPATH=$PWD python benchmarks/nonsmooth.py [diagnose|table]. `table` gives BENCHMARKS.md's numbers
(against the audit's reference for the ball); `diagnose` with the branch-by-branch reference did not finish
in 5 CPU minutes on 2026-11-27 (the lambdified right-hand side through 99 crossings) and has no numbers yet.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

HERE = Path(__file__).parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import numeric_audit3 as A3  # noqa: E402
import numeric_audit6 as A6  # noqa: E402

BALL = ROOT / "tests" / "numeric_audit6" / "ball_in_cup_penalty_k1e8.yaml"
BOUNCE = ROOT / "tests" / "nonsmooth" / "bouncing_mass.yaml"
G, K, H0 = 9.81, 1.0e6, 1.0


def _branches() -> tuple:
    """The ball's two smooth branches (free flight, contact) as audit-3 right-hand sides."""
    s = A6.systems()["ball_cup"]
    x, y = s.q
    d = sp.sqrt(x**2 + (y - 1) ** 2)
    ddot = (x * A3.qd(x) + (y - 1) * A3.qd(y)) / d
    free = dataclasses.replace(s, V=A6.G * y, D=sp.Integer(0))
    contact = dataclasses.replace(s, V=A6.G * y + 1e8 / 2 * (d - 1) ** 2, D=1e9 / 2 * (d - 1) * ddot**2)
    return s, A3._rhs(free), A3._rhs(contact)


def branch_reference(t_end: float, ts: np.ndarray, method: str = "LSODA", rtol: float = 1e-12) -> tuple[np.ndarray, list[float]]:
    """The ball's trajectory at ts, branch by branch (see the module's docstring), and the crossing times."""
    s, free, contact = _branches()

    def gap(t: float, y: np.ndarray) -> float:
        return math.hypot(y[0], y[1] - 1.0) - 1.0

    t0, y0, inside = 0.0, np.array(s.y0, dtype=float), False
    out = np.full((len(ts), 4), np.nan)
    crossings: list[float] = []
    while t0 < t_end:
        event = lambda t, y: gap(t, y)  # noqa: E731
        event.terminal, event.direction = True, (-1.0 if inside else 1.0)
        done = solve_ivp(contact if inside else free, (t0, t_end), y0, method=method, rtol=rtol, atol=1e-15, dense_output=True, events=event)
        assert done.status >= 0, done.message
        t1 = float(done.t[-1])
        pick = (ts >= t0) & (ts <= t1)
        if pick.any():
            out[pick] = done.sol(ts[pick]).T
        if done.status != 1:
            break
        crossings.append(t1)
        t0, y0, inside = t1, done.y[:, -1], not inside
    return s.to_lagrange(out), crossings


def bouncing_exact(ts: np.ndarray) -> np.ndarray:
    """The bouncing mass exactly: free fall from H0 to x = 0 at t1, a half-swing of the spring under
    gravity (x'' = -g - w^2 x) until x = 0 again (tc later), rising to H0: period 2 t1 + tc."""
    w = math.sqrt(K)
    t1, v = math.sqrt(2 * H0 / G), math.sqrt(2 * G * H0)

    def swing(tau: float) -> tuple[float, float]:
        x = -G / w**2 * (1 - math.cos(w * tau)) - v / w * math.sin(w * tau)
        return x, -G / w * math.sin(w * tau) - v * math.cos(w * tau)

    tc = brentq(lambda tau: swing(tau)[0], 1.0 / w, 1.9 * math.pi / w, xtol=1e-16, rtol=1e-15)
    period = 2 * t1 + tc
    out = np.empty((len(ts), 2))
    for j, t in enumerate(ts):
        r = math.fmod(t, period)  # time since the top: falling, in contact, rising
        if r <= t1:
            out[j] = H0 - G * r * r / 2, -G * r
        elif r <= t1 + tc:
            out[j] = swing(r - t1)
        else:
            u = r - t1 - tc
            out[j] = v * u - G * u * u / 2, v - G * u
    return out


def bouncing_contacts(t_end: float) -> int:
    """Contacts begun before t_end."""
    w = math.sqrt(K)
    t1 = math.sqrt(2 * H0 / G)
    tc = brentq(lambda tau: -G / w**2 * (1 - math.cos(w * tau)) - math.sqrt(2 * G * H0) / w * math.sin(w * tau), 1.0 / w, 1.9 * math.pi / w)
    return sum(1 for j in range(100) if t1 + j * (2 * t1 + tc) < t_end)


def diagnose(t_end: float = 0.4, samples: int = 401) -> None:
    from lagrange_cli import api
    from lagrange_cli.numeric import switching

    ts = np.linspace(0.0, t_end, samples)
    began = time.process_time()
    ref, crossings = branch_reference(t_end, ts)
    check, _ = branch_reference(t_end, ts, "Radau", 1e-12)
    print(
        f"ball to t = {t_end}: branch reference LSODA 1e-12, crossings {[f'{c:.9f}' for c in crossings]}, vs Radau 1e-12 branch: {A3._error(check, ref):.2e}, cpu {time.process_time() - began:.1f} s"
    )
    s = A6.systems()["ball_cup"]
    for method in ("LSODA", "DOP853"):
        plain = solve_ivp(A3._rhs(s), (0, t_end), s.y0, method=method, rtol=1e-12, atol=1e-14, t_eval=ts)
        print(f"  audit's reference (Max, no location) {method} 1e-12 vs branch: {A3._error(plain.y.T, ref):.2e}")
    np.save(f"/tmp/nonsmooth_ball_{t_end}.npy", ref)
    ball = api.load(BALL)
    first = int(np.searchsorted(ts, crossings[0])) if crossings else 0
    for locate in (False, True):
        switching.LOCATE = locate
        print(f" crossings located: {locate}")
        for rtol in (1e-6, 1e-7, 1e-8, 1e-9, 1e-10):
            row = []
            for method, backend in (("DOP853", "compiled"), ("RK45", "compiled"), ("LSODA", "python"), ("Radau", "python"), ("auto", None)):
                extra = {"backend": backend} if backend else {}
                run = ball.simulate(t_end=t_end, method=method, rtol=rtol, atol=rtol * 1e-3, samples=samples, max_steps=10**6, **extra).run
                if run.failed or len(run.y) < samples:
                    row.append(f"{method} failed ({run.message[-60:]})")
                    continue
                y = np.asarray(run.y)
                before = A3._error(y[:first], ref[:first]) if first else 0.0
                after = A3._error(y[first : first + 40], ref[first : first + 40])
                row.append(f"{method}{'' if backend else '->' + run.settings.method} {before:.1e}/{after:.1e}/{A3._error(y, ref):.1e} ({run.stats.steps} st)")
            print(f"  rtol {rtol:g} [before 1st contact / 0.04 s after / all]: " + " | ".join(row), flush=True)


def table(repeats: int = 3) -> None:
    """Errors and CPU (time.process_time, best of `repeats`, before/after interleaved, warm caches) at
    rtol 1e-6 .. 1e-10 (atol = rtol / 1000): the bouncing mass to t = 3 against its exact solution, the
    ball to t = 0.4 against audit 6's reference (LSODA rtol 1e-12 on its own Max equations,
    tests/helpers.audit_reference), crossings not located (switching.LOCATE off) and located."""
    from lagrange_cli import api
    from lagrange_cli.numeric import switching

    sys.path.insert(0, str(ROOT))
    from tests.helpers import audit_reference

    cases = []
    ts = np.linspace(0.0, 3.0, 301)
    cases.append(("bouncing mass, t 3", api.load(BOUNCE), 3.0, 301, bouncing_exact(ts)))
    cases.append(("ball, t 0.4", api.load(BALL), 0.4, 201, audit_reference(A6.systems()["ball_cup"], A3._rhs, 0.4, 201, "LSODA")))
    for name, system, t_end, samples, ref in cases:
        print(f"{name}: error (max over samples, audit-3 scaling) / steps / CPU ms, not located -> located")
        for rtol in (1e-6, 1e-7, 1e-8, 1e-9, 1e-10):
            cells = []
            for method, backend in (("DOP853", "compiled"), ("LSODA", "python"), ("auto", None)):
                extra = {"backend": backend} if backend else {}
                result: dict[bool, tuple[float, int, float, str]] = {}
                for _ in range(repeats):
                    for locate in (False, True):
                        switching.LOCATE = locate
                        began = time.process_time()
                        trajectory = system.simulate(t_end=t_end, method=method, rtol=rtol, atol=rtol * 1e-3, samples=samples, max_steps=200_000, **extra)
                        cpu = time.process_time() - began
                        run = trajectory.run
                        error = A3._error(np.asarray(run.y), ref) if not run.failed else math.inf
                        chosen = run.settings.method + ("" if run.settings.backend == "python" else "c")
                        if locate not in result or cpu < result[locate][2]:
                            result[locate] = (error, run.stats.steps, cpu, chosen)
                switching.LOCATE = True
                (e0, s0, c0, m0), (e1, s1, c1, m1) = result[False], result[True]
                label = method if backend else f"auto({m0}->{m1})"
                cells.append(f"{label} {e0:.1e}/{s0}/{1e3 * c0:.0f} -> {e1:.1e}/{s1}/{1e3 * c1:.0f}")
            print(f"  rtol {rtol:g}: " + " | ".join(cells), flush=True)


if __name__ == "__main__":
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load {os.getloadavg()}")
    if len(sys.argv) > 1 and sys.argv[1] == "table":
        table()
    else:
        diagnose(float(sys.argv[2]) if len(sys.argv) > 2 else 0.4)
