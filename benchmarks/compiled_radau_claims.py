"""Issue 15 (helper claims15): every recommendation of a `stress` JSON (and its ties) re-run by
`lagrange simulate` with its own printed options, against an independent reference: the audits' own
equations (benchmarks/numeric_audit2/5/6.py systems and their `_rhs`, derived here by sympy in the
audits' coordinates: the stiff springs in their extension u = r - l, the angle-damped pendulum in
Cartesian x, y), integrated by scipy at rtol 1e-12 by two methods (Radau and LSODA, atol 1e-14)
whose disagreement is the reference's own error. Nothing of lagrange_cli's integrators is used for
the reference; lagrange_cli only gives each regime's start (`stress.regimes`, as `stress` built it).

Error measure: the audits' (`numeric_audit3._error`): the maximum over 2001 evenly spaced samples of
max_i |y_i - ref_i| / max(1, max|ref_i|). A claim is TRUE when the true error meets the accuracy
target and the reported error is within 2 x of the true one or above it (conservative).

    PYTHONPATH=$PWD python benchmarks/compiled_radau_claims.py FILE.yaml STRESS-OR-ACCURACY.json OUT.json [REGIME-PREFIX ...]
    python benchmarks/compiled_radau_claims.py table OUT.json ...   # the rows as a markdown table
"""

from __future__ import annotations

import json
import math
import os
import re
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import sympy as sp
import yaml
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).parent))

import numeric_audit2
import numeric_audit3
import numeric_audit4
import numeric_audit5
import numeric_audit6
from numeric_audit3 import Ref, _error

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = numeric_audit4.SAMPLES
REFERENCE_RUN = re.compile(r"^(\w+) \((compiled|python)\) at rtol (\S+), atol ([^,\s]+),")
"""stress's own reference (its JSON's "reference" text): method, backend, rtol, atol; re-run as a "reference" row
whose reported error is the regime's reference_error (no target: TRUE when that is at least half the true error)."""


def _elastic(m: float, rest: float, k: float, c: float) -> numeric_audit2.System:
    """numeric_audit2's elastic pendulum in the spring's extension u = r - l (its `systems().elastic`,
    with the file's drag coefficient c: Rayleigh function c u_dot^2)."""
    (u, th), (ud, thd) = numeric_audit2._syms("u th")
    r = rest + u
    shift = lambda y: np.column_stack([rest + y[:, 0], y[:, 1], y[:, 2], y[:, 3]])  # noqa: E731
    return numeric_audit2.System("", [u, th], [ud, thd], m / 2 * (ud**2 + r**2 * thd**2), k * u**2 / 2 - m * 9.81 * r * sp.cos(th), c * ud**2, [0, 0], [], True, shift)


def _cart(big: float, m: float, length: float, c: float) -> numeric_audit2.System:
    """numeric_audit2's cart pendulum (`systems()["cart_long"]`) with the file's masses, length and damping."""
    (x, th), (xd, thd) = numeric_audit2._syms("x th")
    T = big / 2 * xd**2 + m / 2 * ((xd + length * sp.cos(th) * thd) ** 2 + (length * sp.sin(th) * thd) ** 2)
    return numeric_audit2.System("", [x, th], [xd, thd], T, -m * 9.81 * length * sp.cos(th), c * xd**2 / 2, [0, 0], [], True, lambda y: y)


def _unshift(rest: float) -> Callable[[list[float]], list[float]]:
    return lambda y: [y[0] - rest, *y[1:]]


# file stem -> (reference system, its right-hand side builder, lagrange state -> reference state, wrapped components)
SYSTEMS: dict[str, Callable[[], tuple[object, Callable[..., object], Callable[[list[float]], list[float]], tuple[int, ...]]]] = {
    "stiff_elastic_pendulum_r": lambda: (_elastic(1.0, 1.0, 1e10, 10.0 * math.sqrt(1e10)), numeric_audit2._rhs, _unshift(1.0), ()),
    "elastic_pendulum_r_k1e11": lambda: (numeric_audit2.systems()["elastic_k1e11"], numeric_audit2._rhs, _unshift(0.5), ()),
    "damped_cart_pendulum": lambda: (_cart(1.0, 0.5, 1.0, 1e6), numeric_audit2._rhs, list, ()),
    "cart_pendulum_fast_damping_long": lambda: (numeric_audit2.systems()["cart_long"], numeric_audit2._rhs, list, ()),
    "van_der_pol_mu1000_coupled": lambda: (numeric_audit5.systems()["vdp"], numeric_audit3._rhs, list, ()),
    "spring_pendulum_angle_damper": lambda: (numeric_audit6.systems()["angle_damper"], numeric_audit3._rhs, lambda y: numeric_audit6._polar_start(*y), (1,)),
}


def reference(rhs: object, y0: list[float], t_end: float, to_lagrange: Callable[[np.ndarray], np.ndarray], wrap: tuple[int, ...]) -> Ref:
    ts = np.linspace(0.0, t_end, SAMPLES)
    began = time.process_time()
    first = solve_ivp(rhs, (0.0, t_end), y0, method="Radau", rtol=1e-12, atol=1e-14, t_eval=ts)  # type: ignore[arg-type]
    if first.status != 0:
        raise RuntimeError(f"reference failed: {first.message}")
    second = solve_ivp(rhs, (0.0, t_end), y0, method="LSODA", rtol=1e-12, atol=1e-14, t_eval=ts)  # type: ignore[arg-type]
    y = to_lagrange(first.y.T)
    own = _error(to_lagrange(second.y.T), y, wrap) if second.status == 0 else math.nan
    return Ref(t_end, y, own, "scipy Radau 1e-12, LSODA 1e-12 agrees to", time.process_time() - began)


def table(paths: list[str]) -> None:
    """`table ROWS.json ...`: the rows as BENCHMARKS.md's table."""
    print("| file | regime | claim | setting | target | reported | true (ref own) | verdict |\n|---|---|---|---|---|---|---|---|")
    for p in paths:
        for r in json.loads(Path(p).read_text()):
            print(
                f"| {r['file']} | {r['regime']} ({r['kind']}) | {r['claim']} | {r['setting']} | {r.get('target', 1e-6) or '-'} | {r['reported']:.3g} | {r['true']:.3g} ({r['ref_own']:.1g}) | {r['verdict']} |"
            )


def main() -> None:
    if sys.argv[1] == "table":
        table(sys.argv[2:])
        return
    from lagrange_cli import api
    from lagrange_cli.numeric import stress

    path, report, out = Path(sys.argv[1]), json.loads(Path(sys.argv[2]).read_text()), Path(sys.argv[3])
    only = sys.argv[4:]
    s, rhs_of, from_lagrange, wrap = SYSTEMS[path.stem]()
    model = api.load(path).model
    data = yaml.safe_load(path.read_text())
    names = [*data["coordinates"], *(f"{c}_dot" for c in data["coordinates"])]
    planned = {r.name: r for r in stress.regimes(model, ())}
    numeric_audit4.AUDIT = path.parent
    s.file = path.name  # type: ignore[attr-defined]
    rhs = rhs_of(s)
    rows = json.loads(out.read_text()) if out.exists() else []
    if "fastest" in report:  # an `accuracy` JSON: its fastest run per error level, from the file's start
        report = {"accuracy": None, "regimes": [{"regime": "defaults", "t_end": report["t_end"], "levels": report["fastest"]}]}
    with tempfile.TemporaryDirectory() as d:
        for regime in report["regimes"]:
            if only and not any(regime["regime"].startswith(p) for p in only):
                continue
            if not regime.get("recommended") and not regime.get("levels"):
                continue  # undecided: no claim to check
            plan = planned[regime["regime"]]
            start = {**{n: float(data["initial"].get(n, 0.0)) for n in names}, **plan.initial}
            y0 = from_lagrange([start[n] for n in names])
            ref = reference(rhs, y0, float(regime["t_end"]), s.to_lagrange, wrap)  # type: ignore[attr-defined]
            s.wrap = wrap  # type: ignore[attr-defined]
            initial = ["--initial", ",".join(f"{k}={v!r}" for k, v in plan.initial.items())] if plan.initial else []
            claims = [("recommended", report["accuracy"], regime.get("recommended")), *(("tie", report["accuracy"], t) for t in regime.get("ties") or [])]
            own_run = REFERENCE_RUN.match(regime.get("reference") or "")
            if own_run and os.environ.get("CLAIMS_REFERENCE", "1") == "1":  # stress's own reference run: is its own error an honest bound?
                method, backend, rtol, atol = own_run.groups()
                opts = ["--method", method, "--backend", backend, "--rtol", rtol, "--atol", atol, "--max-steps", "100000000"]  # stress's reference budget is not simulate's
                claims.append(("reference", None, {"method": method, "ran": f"{method} ({backend})", "setting": f"rtol {rtol}, atol {atol}", "simulate": opts, "error": regime.get("reference_error")}))
            for level in regime.get("levels", []):  # accuracy: the level's fastest run and its ties
                claims += [(f"fastest at {level['error']:g}", level["error"], {**c, "error": c.get("error_reached", level["error_reached"])}) for c in [level, *level.get("ties", [])]]
            for kind, target, claim in claims:
                if not claim or not claim.get("simulate"):
                    continue
                run = numeric_audit4.run_simulate(s, ref, list(claim["simulate"]), Path(d), initial)  # type: ignore[arg-type]
                true, reported = float(run["true_max_error"]), claim["error"]  # type: ignore[arg-type]
                verdict = "TRUE" if (target is None or true <= target) and reported is not None and reported >= true / 2 else "FALSE"
                row = {
                    "file": path.stem,
                    "regime": regime["regime"],
                    "kind": kind,
                    "target": target,
                    "claim": f"{claim['method']} -> {claim.get('ran') or run.get('ran')}",
                    "setting": claim["setting"],
                    "reported": reported,
                    "true": true,
                    "ref_own": ref.own,
                    "ref_cpu": ref.cpu,
                    "verdict": verdict,
                    **run,
                }
                print(json.dumps(row, default=float), flush=True)
                rows.append(row)
                out.write_text(json.dumps(rows, indent=1, default=float))


if __name__ == "__main__":
    main()
