"""The heyoka.py candidate for the compiled path, measured on the double pendulum (t = 0..10).

Run it in a scratch environment, not the project's (heyoka is not a dependency):

    python3 -m venv /tmp/hyvenv && /tmp/hyvenv/bin/pip install heyoka numpy scipy
    /tmp/hyvenv/bin/python benchmarks/simulate_heyoka.py

It prints, as JSON: the import time, the JIT compile time of the Taylor integrator (paid in
every new process: heyoka caches compiled code in memory only), the run time and the final
error at each tolerance, against scipy's DOP853 at rtol 1e-13 on the same equations.
"""

from __future__ import annotations

import json
import math
import time

start = time.perf_counter()
import heyoka as hy  # noqa: E402

IMPORT = time.perf_counter() - start
import numpy as np  # noqa: E402


def equations() -> list[tuple[object, object]]:
    """The double pendulum, m = l = 1, g = 9.81, accelerations by Cramer's rule."""
    th1, th2, w1, w2 = hy.make_vars("th1", "th2", "w1", "w2")
    s, c = hy.sin(th1 - th2), hy.cos(th1 - th2)
    f1 = -s * w2 * w2 - 2 * 9.81 * hy.sin(th1)
    f2 = s * w1 * w1 - 9.81 * hy.sin(th2)
    det = 2.0 - c * c
    return [(th1, w1), (th2, w2), (w1, (f1 - c * f2) / det), (w2, (2.0 * f2 - c * f1) / det)]


def reference() -> np.ndarray:
    from scipy.integrate import solve_ivp

    def rhs(t: float, y: np.ndarray) -> list[float]:
        th1, th2, w1, w2 = y
        s, c = math.sin(th1 - th2), math.cos(th1 - th2)
        f1 = -s * w2 * w2 - 2 * 9.81 * math.sin(th1)
        f2 = s * w1 * w1 - 9.81 * math.sin(th2)
        return [w1, w2, (f1 - c * f2) / (2 - c * c), (2 * f2 - c * f1) / (2 - c * c)]

    return solve_ivp(rhs, (0, 10), [1.0, 0.5, 0.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-15).y[:, -1]


def main() -> None:
    y_ref = reference()
    result: dict[str, object] = {"heyoka": hy.__version__, "import_s": IMPORT, "runs": []}
    for tol in (1e-6, 1e-8, 1e-10, 1e-12):
        began = time.perf_counter()
        ta = hy.taylor_adaptive(equations(), [1.0, 0.5, 0.0, 0.0], tol=tol)
        compiled = time.perf_counter() - began
        best = math.inf
        for _ in range(5):
            ta.time, ta.state[:] = 0.0, [1.0, 0.5, 0.0, 0.0]
            began = time.perf_counter()
            ta.propagate_until(10.0)
            best = min(best, time.perf_counter() - began)
        error = float(np.max(np.abs(ta.state - y_ref)))
        result["runs"].append({"tol": tol, "compile_s": compiled, "run_s": best, "error": error})  # type: ignore[attr-defined]
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
