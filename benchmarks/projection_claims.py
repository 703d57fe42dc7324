"""Issue 15 (helper projkern): the recommendations of `stress` and `accuracy` on the kept-constraint systems of
audits 3, 4, 5 and 6, re-run by `simulate` with their own printed options and measured against the audits'
independent references (benchmarks/numeric_audit3.py, numeric_audit4.py, numeric_audit5.py: their systems,
derived without lagrange, and audit 4's `reference`, scipy at rtol 1e-13 confirmed by a second method, or the
exact solution). Claims whose initial state the audit cannot rebuild (a high-energy regime of a system at
rest in its file, whose reference is not in the file's coordinates) are listed as not checked.

    PYTHONPATH=. LAGRANGE_CACHE_DIR=CACHE .venv/bin/python benchmarks/projection_claims.py DIR [--json out.json]

DIR holds NAME.stress.json, NAME.stress.out (the text report, for the high-energy regime's --initial) and
NAME.accuracy.json, NAME = numeric_audit4__trammel_kept_rod and so on (as /tmp/projkern/run1.sh writes them).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numeric_audit3
import numeric_audit4
import numeric_audit5
import numeric_audit6

ROOT = numeric_audit4.ROOT
CASES = [
    ("numeric_audit4__trammel_kept_rod", "tests/numeric_audit4/trammel_kept_rod.yaml", "trammel", lambda: numeric_audit4.systems()["trammel"]),
    ("numeric_audit3__pendulum_multiplier_large_swing", "tests/numeric_audit3/pendulum_multiplier_large_swing.yaml", "a3-multiplier_swing", lambda: numeric_audit3.systems()["multiplier_swing"]),
    ("numeric_audit3__hoop_bead_kept_constraint", "tests/numeric_audit3/hoop_bead_kept_constraint.yaml", "a3-hoop_kept", lambda: numeric_audit3.systems()["hoop_kept"]),
    ("numeric_audit3__sleigh_driven_torque", "tests/numeric_audit3/sleigh_driven_torque.yaml", "a3-sleigh_driven", lambda: numeric_audit3.systems()["sleigh_driven"]),
    ("numeric_audit5__sleigh_spring_slider", "tests/numeric_audit5/sleigh_spring_slider.yaml", "a5-sleigh", lambda: numeric_audit5.systems()["sleigh"]),
    ("numeric_audit6__particle_on_paraboloid_kept_drag", "tests/numeric_audit6/particle_on_paraboloid_kept_drag.yaml", "paraboloid", lambda: numeric_audit6.systems()["paraboloid"]),
]
"""Audit 6's paraboloid (added by helper radproj) takes audit 6's reference (`numeric_audit6.reference`: DOP853 at
rtol 1e-13 confirmed by LSODA, its long horizon too); the others audit 4's."""


def _reference(key: str, *args: object, **options: object) -> numeric_audit3.Ref:
    return (numeric_audit6.reference if key == "paraboloid" else numeric_audit4.reference)(key, *args, **options)  # type: ignore[arg-type, no-any-return]


def measured(path: str, system: object, ref: numeric_audit3.Ref, opts: list[str], initial: list[str], tmp: Path) -> dict[str, object]:
    out = tmp / "run.npz"
    done, cpu, _ = numeric_audit4.cli("simulate", path, *initial, *opts, "--t-end", repr(ref.t_end), "--samples", str(numeric_audit4.SAMPLES), "-q", "-o", str(out))
    row: dict[str, object] = {"exit": done.returncode, "cpu": cpu, "opts": opts}
    if out.exists():
        row["true"] = numeric_audit3._error(np.load(out)["y"], ref.y, system.wrap)  # type: ignore[attr-defined]
        out.unlink()
    else:
        row["true"], row["stderr"] = math.inf, done.stderr[-300:]
    return row


def check(name: str, path: str, key: str, system: object, folder: Path, tmp: Path) -> list[dict[str, object]]:
    t_file = float(yaml.safe_load((ROOT / path).read_text())["simulate"]["t_end"])
    rows: list[dict[str, object]] = []
    report = json.loads((folder / f"{name}.stress.json").read_text())
    tried = numeric_audit4.try_lines((folder / f"{name}.stress.out").read_text())
    for regime in report["regimes"]:
        label = regime["regime"]
        recommended = [p for p in [regime["recommended"], *regime["ties"]] if p and p.get("simulate")]
        if not recommended or not (label == "defaults" or label.startswith("long horizon") or label.startswith("high energy")):
            continue
        energy, moved, initial = 1.0, "", []
        if label.startswith("high energy"):
            moved = tried.get(label, {}).get("--initial", "")
            try:
                energy = float(label.split("x")[-1].strip(" )"))
            except ValueError:
                energy = math.nan
            expected = numeric_audit5.velocities_initial(str(ROOT / path), energy)[1] if math.isfinite(energy) else ""
            differs = moved and {w for w in moved.split(",") if not w.endswith("=0.0")} != {w for w in expected.split(",") if not w.endswith("=0.0")}
            if not math.isfinite(energy) or (differs and not getattr(system, "names", None)):
                rows.extend({"system": name, "what": f"stress {label}", "method": p["method"], "setting": p["setting"], "checked": False} for p in recommended)
                continue
            if differs:
                energy = -1.0
            initial = ["--initial", moved] if energy == -1.0 else numeric_audit5.velocities_initial(str(ROOT / path), energy)
        ref = _reference(key, system, float(regime["t_end"]), t_file, energy, moved if energy == -1.0 else "")  # type: ignore[arg-type]
        for p in recommended:
            got = measured(str(ROOT / path), system, ref, [str(w) for w in p["simulate"]], initial, tmp)
            reported = p.get("max_error", p.get("error"))
            rows.append(
                {
                    "system": name,
                    "what": f"stress {label}",
                    "method": p["method"],
                    "setting": p["setting"],
                    "reported": reported,
                    "ref_own": ref.own,
                    "checked": True,
                    **got,
                    "meets": got["true"] <= report["accuracy"],
                }
            )
    study = json.loads((folder / f"{name}.accuracy.json").read_text())
    ref = _reference(key, system, float(study["t_end"]), t_file)  # type: ignore[arg-type]
    points = {(p["method"], p["setting"]): p for p in study["points"]}
    for fastest in study["fastest"]:
        point = points.get((fastest["method"], fastest["setting"]), {})
        opts = fastest.get("simulate") or point.get("simulate")
        if not opts:
            continue
        got = measured(str(ROOT / path), system, ref, [str(w) for w in opts], [], tmp)
        reported = point.get("max_error", fastest.get("error_reached"))
        rows.append(
            {
                "system": name,
                "what": f"accuracy {fastest['error']:g}",
                "method": fastest["method"],
                "setting": fastest["setting"],
                "reported": reported,
                "ref_own": ref.own,
                "checked": True,
                **got,
                "meets": got["true"] <= fastest["error"],
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("folder")
    parser.add_argument("--json", default="")
    parser.add_argument("--only", action="append", default=[])
    args = parser.parse_args()
    folder = Path(args.folder)
    rows: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, path, key, system in CASES:
            if args.only and not any(o in name for o in args.only):
                continue
            if not (folder / f"{name}.stress.json").exists():
                continue
            found = check(name, path, key, system(), folder, Path(tmp))
            rows += found
            for r in found:
                if r["checked"]:
                    print(
                        f"{r['system']} | {r['what']} | {r['method']} {r['setting']} | reported {r['reported']:.3g} | true {r['true']:.3g} (reference own {r['ref_own']:.1g}) | {'meets' if r['meets'] else 'FAILS'}",
                        flush=True,
                    )
                else:
                    print(f"{r['system']} | {r['what']} | {r['method']} {r['setting']} | not checked (initial state not rebuilt)", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
