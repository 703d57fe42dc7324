"""Issue 15 (helper radproj): the before/after table of `stress` and `accuracy` on the kept-constraint files
(CPU = user + sys of the whole process, from projection_cpu_run1.sh's NAME.CMD.time), with the verdicts, the
stress recommendations and accuracy's fastest per level compared regime by regime.

    python benchmarks/radproj_table.py BEFORE_DIR AFTER_DIR FILES.txt [--json out.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def _name(path: str) -> str:
    return path.removeprefix("tests/").replace("/", "__").removesuffix(".yaml")


def _cpu(folder: Path, name: str, command: str) -> float:
    user, system, _ = (folder / f"{name}.{command}.time").read_text().split()[-3:]
    return float(user) + float(system)


def _report(folder: Path, name: str, command: str) -> dict:  # type: ignore[type-arg]
    return json.loads((folder / f"{name}.{command}.json").read_text())  # type: ignore[no-any-return]


def _recommended(regime: dict) -> tuple[object, ...]:  # type: ignore[type-arg]
    chosen = regime.get("recommended") or {}
    return (chosen.get("method"), chosen.get("setting"))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("before")
    parser.add_argument("after")
    parser.add_argument("files")
    parser.add_argument("--json", default="")
    args = parser.parse_args()
    before, after = Path(args.before), Path(args.after)
    rows = []
    print(
        "| file | stress before | stress after | ratio | accuracy before | accuracy after | ratio | stress verdicts (before = after?) | stress recommendations changed | accuracy levels whose fastest changed |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for line in Path(args.files).read_text().split():
        name = _name(line)
        sb, sa, ab, aa = _cpu(before, name, "stress"), _cpu(after, name, "stress"), _cpu(before, name, "accuracy"), _cpu(after, name, "accuracy")
        rb, ra = _report(before, name, "stress"), _report(after, name, "stress")
        vb, va = [r["verdict"] for r in rb["regimes"]], [r["verdict"] for r in ra["regimes"]]
        changed = [
            f"{b['regime'].split(' (')[0]}: {_recommended(b)[0]} {_recommended(b)[1]} -> {_recommended(a)[0]} {_recommended(a)[1]}"
            for b, a in zip(rb["regimes"], ra["regimes"], strict=False)
            if _recommended(b) != _recommended(a)
        ]
        fb = [(x["error"], x["method"], x["setting"]) for x in _report(before, name, "accuracy")["fastest"]]
        fa = [(x["error"], x["method"], x["setting"]) for x in _report(after, name, "accuracy")["fastest"]]
        moved = [f"{b[0]:g}: {b[1]} {b[2]} -> {a[1]} {a[2]}" for b, a in zip(fb, fa, strict=False) if b != a]
        codes = f"exit {(before / f'{name}.stress.rc').read_text().strip()}/{(after / f'{name}.stress.rc').read_text().strip()}"
        radau = sum(1 for x in fa if x[1] == "Radau")
        print(
            f"| {line.removesuffix('.yaml')} | {sb:.1f} | {sa:.1f} | {sa / sb:.2f} | {ab:.1f} | {aa:.1f} | {aa / ab:.2f} | {', '.join(va)} ({'same' if va == vb else 'before: ' + ', '.join(vb)}; {codes}) "
            f"| {'; '.join(changed) or 'none'} | {len(moved)} of {len(fa)}{f' ({radau} now Radau)' if radau else ''} |"
        )
        rows.append({"file": line, "stress": [sb, sa], "accuracy": [ab, aa], "verdicts": [vb, va], "recommendations_changed": changed, "fastest_changed": moved})
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
