"""Issue 15 (helper radstress): the `stress` recommendations that changed when Radau ran compiled, re-run with
`lagrange simulate` (their own printed options) against independent references: the audits' own equations
(benchmarks/numeric_audit3-6.py, plain sympy, other coordinates; nothing of lagrange_cli imported there),
integrated by scipy at rtol 1e-12 by two methods whose disagreement is the reference's own error.

    PYTHONPATH=$PWD python benchmarks/radstress_claims.py OUT.json [NAME ...]
"""

from __future__ import annotations

import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).parent))

import numeric_audit4
import numeric_audit6
from numeric_audit3 import Ref, _error, _rhs

# (name, audit module, system, regime, start in the reference's coordinates, t_end, the claim's simulate options, methods)
CLAIMS = [
    (
        "angle_damper near singular",
        numeric_audit6,
        "angle_damper",
        "near singular (r = 0.011)",
        numeric_audit6._polar_start(0.011000000000000001, 1.0, 0.0, 2.0),
        20.0,
        ["--initial", "r=0.011000000000000001", "--method", "Radau", "--backend", "compiled", "--rtol", "1e-07", "--atol", "1e-10"],
        ("LSODA", "Radau"),
    ),
]


def main() -> None:
    out = Path(sys.argv[1])
    only = set(sys.argv[2:])
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for name, module, system, regime, y0, t_end, opts, (first_m, second_m) in CLAIMS:
            if only and name not in only:
                continue
            s = module.systems()[system]
            numeric_audit4.AUDIT = module.AUDIT
            ts = np.linspace(0.0, t_end, numeric_audit4.SAMPLES)
            began = time.process_time()
            first = solve_ivp(_rhs(s), (0, t_end), y0, method=first_m, rtol=1e-12, atol=1e-14, t_eval=ts)
            second = solve_ivp(_rhs(s), (0, t_end), y0, method=second_m, rtol=1e-12, atol=1e-14, t_eval=ts)
            y = s.to_lagrange(first.y.T)
            own = _error(s.to_lagrange(second.y.T), y, s.wrap) if second.status == 0 and first.status == 0 else math.nan
            ref = Ref(t_end, y, own, f"{first_m} 1e-12, {second_m} 1e-12 agrees to", time.process_time() - began)
            row = {"claim": name, "regime": regime, "ref_own": own, "ref_cpu": ref.cpu, **numeric_audit4.run_simulate(s, ref, opts, Path(d))}
            print(json.dumps(row, default=float), flush=True)
            rows.append(row)
            out.write_text(json.dumps(rows, indent=1, default=float))


if __name__ == "__main__":
    main()
