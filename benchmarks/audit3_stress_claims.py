"""The claims of a saved `stress --json` report on an audit-3 system, checked against the audit's
independent references (benchmarks/numeric_audit3.py): each defaults / long-horizon regime's verdict,
reference and own error, and for its recommendation and ties the true max error of the printed
`simulate` command. The stress run itself is not repeated (its CPU time is measured apart).

    PYTHONPATH=. LAGRANGE_CACHE_DIR=/tmp/x .venv/bin/python benchmarks/audit3_stress_claims.py NAME stress.json
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numeric_audit3 as audit


def main() -> None:
    name, report_path = sys.argv[1], Path(sys.argv[2])
    s = audit.systems()[name]
    t_file = float(yaml.safe_load((audit.AUDIT / s.file).read_text())["simulate"]["t_end"])
    report = json.loads(report_path.read_text())
    with tempfile.TemporaryDirectory() as d:
        for regime in report["regimes"]:
            line = f"{name} | {regime['regime']} | {regime['verdict']} | own error {regime.get('reference_error')}"
            if not (regime["regime"] == "defaults" or regime["regime"].startswith("long horizon")):
                print(line + " | (not checked: the audit has references for the file's start only)")
                continue
            ref = audit.reference(name, s, float(regime["t_end"]), t_file)
            claims = []
            for p in [regime["recommended"], *regime["ties"]]:
                if not p:
                    continue
                method, backend = audit.ran_of(p)
                info = audit.run_simulate(s, ref, audit.setting_opts(method, backend, str(p["setting"]), p.get("simulate")), Path(d))
                reported = p.get("max_error", p.get("error"))
                verdict = "meets" if info["true_max_error"] <= report["accuracy"] else "FAILS"  # type: ignore[operator]
                claims.append(f"{method} {backend} {p['setting']}: reported {reported:.2e} -> true {info['true_max_error']:.2e} {verdict}")
            print(f"{line} | audit reference: {ref.how} {ref.own:.1e} | " + ("; ".join(claims) or "no claim"), flush=True)


if __name__ == "__main__":
    main()
