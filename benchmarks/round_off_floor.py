"""Do `stress`'s recommendations on the audit's stiff pendulum in r (k = 1e10, critically damped) truly meet
1e-6? Each regime's `try:` command is run as a whole process and compared with a reference computed here
from equations derived by hand (nothing of lagrange_cli is imported for it): scipy's Radau with the exact
Jacobian at rtol 1e-12, confirmed by the same at rtol 1e-11 (and, on the 10 s regimes, by scipy's DOP853
at rtol 1e-12). r_dot's atol is 1e-9 in the references: below about 1e-11 it is under its round-off floor
(k / c x eps |r|) and scipy's Radau crawls as compiled Radau did before kernels._radau_floor.

The error is `stress`'s: the largest over samples and components of |y - reference| / max(1, max |reference|).

    .venv/bin/python benchmarks/round_off_floor.py [stress-output.txt]

Without an argument it runs `lagrange stress` on the file first (about 10-20 s)."""

from __future__ import annotations

import math
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

ROOT = Path(__file__).resolve().parent.parent
FILE = "tests/numeric_audit_pilot/stiff_elastic_pendulum_r.yaml"
M, L, G, K = 1.0, 1.0, 9.81, 1.0e10
C = 2.0 * math.sqrt(K * M)
REQUIRED = 1e-6
LAGRANGE = [sys.executable, "-m", "lagrange_cli"]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
"""This checkout's lagrange_cli, whichever is installed in the interpreter."""


def rhs(t: float, y: np.ndarray) -> np.ndarray:
    r, th, rd, thd = y
    return np.array([rd, thd, r * thd**2 + G * math.cos(th) - (K * (r - L) + C * rd) / M, -(2.0 * rd * thd + G * math.sin(th)) / r])


def jac(t: float, y: np.ndarray) -> np.ndarray:
    r, th, rd, thd = y
    return np.array(
        [
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [thd**2 - K / M, -G * math.sin(th), -C / M, 2.0 * r * thd],
            [(2.0 * rd * thd + G * math.sin(th)) / r**2, -G * math.cos(th) / r, -2.0 * thd / r, -2.0 * rd / r],
        ]
    )


def reference(y0: np.ndarray, t: np.ndarray, method: str, rtol: float) -> np.ndarray:
    atol = np.array([1e-15, 1e-15, 1e-9, 1e-13])
    options = {"jac": jac} if method == "Radau" else {}
    found = solve_ivp(rhs, (t[0], t[-1]), y0, method=method, t_eval=t, rtol=rtol, atol=atol, **options)
    assert found.status == 0, found.message
    return found.y.T


def error(y: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.abs(y - ref) / np.maximum(1.0, np.max(np.abs(ref), axis=0))))


def main() -> None:
    if len(sys.argv) > 1:
        text = Path(sys.argv[1]).read_text()
    else:
        began = time.process_time()
        found = subprocess.run([*LAGRANGE, "stress", FILE], cwd=ROOT, capture_output=True, text=True, check=False, env=ENV)
        text = found.stdout
        print(f"stress exit {found.returncode}; its CPU time is a child's: see `time lagrange stress {FILE}` ({time.process_time() - began:.1f} s here)")
    for line in text.splitlines():
        if not line.strip().startswith("try: lagrange simulate"):
            continue
        words = shlex.split(line.strip().removeprefix("try: "))
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "run.npz"
            subprocess.run([*LAGRANGE, *words[1:], "-q", "-o", str(out)], cwd=ROOT, capture_output=True, check=True, env=ENV)
            run = np.load(out)
            t, y, y0 = run["t"], run["y"], run["y0"]
        main_ref = reference(y0, t, "Radau", 1e-12)
        second = reference(y0, t, "Radau", 1e-11)
        spread = error(second, main_ref)
        if t[-1] <= 10.0:
            spread = max(spread, error(reference(y0, t, "DOP853", 1e-12), main_ref))
        setting = " ".join(words[3:])
        true = error(y, main_ref)
        print(f"{setting}\n  true error {true:.2e} (reference spread {spread:.1e}): {'meets' if true <= REQUIRED else 'MISSES'} {REQUIRED:g}")


if __name__ == "__main__":
    main()
