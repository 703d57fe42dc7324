"""Hostile system files through the real command line: each file in tests/hostile/ is one case.

Every case runs in its own temporary folder (also the working directory, and the compile cache),
in one subprocess that runs each applicable command line in turn (tests/hostile_driver.py), and
must show, for every command:

- exit code 0 or 2 (1 only from `simulate`, `accuracy` and `stress`, a failed run, and `check`, a
  wrong answer), or the one the case's header pins;
- no `Traceback` and no `internal error` in its output, no terminal control character that came
  from the file;
- on exit 2, a message that names the file; and no output file left behind (a JUnit report is
  written on purpose, and must then be well-formed XML);
- nothing executed: no file named PWNED* appears in the folder or in the current directory, also
  when the written Python module is imported and the written LaTeX document is compiled (which
  must then succeed, without reading /etc/passwd);
- an end (the driver's watchdog, 90 s of CPU time, is a safety net against hangs; the cases take a few seconds, and the load of other programs does not count).

A case file starts with comment lines that say what applies (adding a case is adding a file):

    # class: 1 (sinks) - what the case is about, for the reader
    # commands: derive-text derive-python simulate   (default: DEFAULT_COMMANDS)
    # exit: 2            (every command), or per command: derive-text=0 simulate=1
    # filename: "name.yaml"   (a JSON string: the name the file gets, default the case's name)
    # names: text        (what an error message must contain, default the file's name)
    # rhs: [y] -> [dy/dt]   (the written module's rhs(0, y) with the file's parameters)
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from .limits import DEADLOCK

ROOT = Path(__file__).resolve().parent.parent
CASES = sorted((ROOT / "tests" / "hostile").glob("*.yaml"))
LIMIT = 90.0
"""CPU seconds one command may use (the driver's watchdog): a safety net against hangs, far above any case."""
"""Seconds before a command counts as hung: a safety net far above any case (the slowest take a few
seconds on a quiet machine), so that a loaded machine cannot fail the test."""
MARKER = "PWNED"
DEFAULT_COMMANDS = ("derive-text", "derive-latex", "derive-standalone", "derive-python", "check", "info", "equilibria", "simulate")
# name -> (arguments after the file, the output it writes or None)
COMMANDS: dict[str, tuple[tuple[str, ...], str | None]] = {
    "derive-text": (("-o", "out/derive.txt"), "out/derive.txt"),
    "derive-stdout": ((), None),
    "derive-matrix": (("--form", "matrix", "-o", "out/matrix.txt"), "out/matrix.txt"),
    "derive-solved": (("--form", "solved", "-o", "out/solved.txt"), "out/solved.txt"),
    "derive-latex": (("--latex", "-o", "out/derive.tex"), "out/derive.tex"),
    "derive-latex-solved": (("--latex", "--form", "solved", "-o", "out/solved.tex"), "out/solved.tex"),
    "derive-standalone": (("--latex", "--standalone", "-o", "out/standalone.tex"), "out/standalone.tex"),
    "derive-python": (("--python", "-o", "out/module.py"), "out/module.py"),
    "check": (("--junit", "out/check.xml"), "out/check.xml"),
    "check-json": (("--json",), None),
    "info": (("-o", "out/info.txt"), "out/info.txt"),
    "info-stdout": ((), None),
    "info-latex": (("--latex", "-o", "out/info.tex"), "out/info.tex"),
    "info-json": (("--json", "-o", "out/info.json"), "out/info.json"),
    "equilibria": ((), None),
    "linearize": ((), None),
    "accuracy": (("--method", "RK45:python", "--tolerances", "1e-3", "--t-end", "0.1", "--repeats", "1", "--samples", "11", "--csv", "out/accuracy.csv"), "out/accuracy.csv"),
    "stress": (("--method", "RK45:python", "--t-end", "0.1", "--budget", "2", "--json", "out/stress.json"), "out/stress.json"),
    "simulate": (("--t-end", "0.1", "--backend", "python", "-o", "out/simulate.csv"), "out/simulate.csv"),
    "simulate-file": (("--backend", "python", "-o", "out/simulate-file.csv"), "out/simulate-file.csv"),
    "simulate-file-auto": (("-o", "out/simulate-file-auto.csv"), "out/simulate-file-auto.csv"),
    "simulate-numba": (("--t-end", "0.1", "--backend", "compiled", "--method", "DOP853", "-o", "out/simulate-numba.csv"), "out/simulate-numba.csv"),
    "simulate-plot": (("--t-end", "0.1", "--backend", "python", "--plot", "out/simulate.png"), "out/simulate.png"),
}
CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")  # C0 but tab and newline (\r rewrites the line), DEL, C1 (\x9b is CSI)


@dataclass
class Case:
    path: Path
    klass: str = ""
    commands: tuple[str, ...] = DEFAULT_COMMANDS
    exits: dict[str, int] = field(default_factory=dict)
    filename: str = ""
    names: str = ""
    rhs: tuple[list[float], list[float]] | None = None


def read_case(path: Path) -> Case:
    case = Case(path, filename=path.name)
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        key, _, value = line[1:].strip().partition(":")
        value = value.strip()
        if key == "class":
            case.klass = value
        elif key == "commands":
            case.commands = tuple(value.split())
            unknown = set(case.commands) - set(COMMANDS)
            assert not unknown, f"{path.name}: unknown commands {unknown}"
        elif key == "exit":
            for item in value.split():
                name, eq, code = item.partition("=")
                if eq:
                    case.exits[name] = int(code)
                else:
                    case.exits.update(dict.fromkeys(COMMANDS, int(name)))
        elif key == "filename":
            case.filename = json.loads(value)
        elif key == "names":
            case.names = value
        elif key == "rhs":
            y, _, expected = value.partition("->")
            case.rhs = (json.loads(y), json.loads(expected))
    return case


def command_line(name: str, file: str) -> list[str]:
    args, _ = COMMANDS[name]
    verb = name.split("-")[0]
    return [verb, file, *args]


def markers(*folders: Path) -> list[Path]:
    found: list[Path] = []
    for folder in folders:
        found += [p for p in folder.rglob(f"{MARKER}*")] if folder.is_dir() else []
    return found


def environment(tmp: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("LAGRANGE_", "PYTHON"))}
    env.update(PYTHONPATH=str(ROOT), LAGRANGE_CACHE_DIR=str(tmp / "cache"), MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1")
    return env


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_hostile_file(path: Path, tmp_path: Path) -> None:
    case = read_case(path)
    work = tmp_path / "work"
    (work / "out").mkdir(parents=True)
    target = work / "case" / case.filename
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(path, target)
    file = str(target.relative_to(work))
    results = tmp_path / "results.jsonl"
    argv = [sys.executable, "-m", "tests.hostile_driver", "--limit", str(LIMIT), str(results)]
    for name in case.commands:
        argv += ["--", *command_line(name, file)]
    before = set(markers(Path.cwd()))
    try:
        driver = subprocess.run(argv, cwd=work, env=environment(tmp_path), capture_output=True, text=True, timeout=DEADLOCK * len(case.commands))
    except subprocess.TimeoutExpired:
        pytest.fail(f"{path.name}: the commands ran over {DEADLOCK * len(case.commands):g} s of wall time together (a deadlock: the CPU-time watchdog did not fire)")
    ran = [json.loads(line) for line in results.read_text(encoding="utf-8").splitlines()] if results.exists() else []
    problems = [f"driver: {driver.stderr.strip()[-2000:]}"] if driver.returncode != 0 else []
    for name, result in zip(case.commands, ran, strict=False):
        problems += [f"{name}: {p}" for p in judge(case, name, result, work)]
    problems += follow_up(case, work, tmp_path)
    problems += [f"marker file created: {p}" for p in set(markers(tmp_path, Path.cwd())) - before]
    for p in set(markers(Path.cwd())) - before:
        p.unlink()
    assert not problems, f"{path.name} ({case.klass}):\n" + "\n".join(problems)


def judge(case: Case, name: str, result: dict, work: Path) -> list[str]:
    """What is wrong with one command's outcome."""
    code, out, err = result["code"], result["stdout"], result["stderr"]
    problems = []
    allowed = {case.exits[name]} if name in case.exits else {0, 1, 2} if name.startswith(("simulate", "check", "accuracy", "stress")) else {0, 2}
    if code not in allowed:
        problems.append(f"exit {code}, expected {' or '.join(map(str, sorted(allowed)))}")
    for text, where in ((out, "stdout"), (err, "stderr")):
        if "Traceback" in text or "internal error" in text.lower():
            problems.append(f"{where} has a traceback:\n{text[-3000:]}")
        elif CONTROL.search(text):
            problems.append(f"{where} has control character {CONTROL.search(text).group()!r}: {text[:300]!r}")  # type: ignore[union-attr]
    named = case.names or case.filename
    if code == 2 and named not in out + err:
        problems.append(f"the message does not name the file ({named!r}): {err[:500]!r}")
    _, written = COMMANDS[name]
    if written and (work / written).exists():
        if name.startswith("check"):
            try:
                ET.parse(work / written)
            except ET.ParseError as error:
                problems.append(f"{written} is not well-formed XML: {error}")
        elif code == 2 or (code != 0 and not name.startswith(("simulate", "accuracy", "stress"))):
            problems.append(f"{written} was written although the command failed (exit {code})")
    return problems


def follow_up(case: Case, work: Path, tmp: Path) -> list[str]:
    """Import the written module (and check its rhs), compile the written LaTeX document."""
    problems = []
    module = work / "out" / "module.py"
    if module.exists():
        script = "import runpy, json, sys; m = runpy.run_path(sys.argv[1]); y = json.loads(sys.argv[2]); print(json.dumps([float(v) for v in m['rhs'](0.0, y)] if y else []))"
        y = json.dumps(case.rhs[0] if case.rhs else [])
        try:
            run = subprocess.run([sys.executable, "-c", script, str(module), y], cwd=work, env=environment(tmp), capture_output=True, text=True, timeout=DEADLOCK)
        except subprocess.TimeoutExpired:
            return [f"importing the written module ran over {LIMIT:g} s"]
        if run.returncode != 0:
            problems.append(f"the written module fails to import or run:\n{run.stderr[-2000:]}")
        elif case.rhs:
            got = json.loads(run.stdout)
            if len(got) != len(case.rhs[1]) or not all(math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12) for a, b in zip(got, case.rhs[1], strict=False)):
                problems.append(f"the written module's rhs(0, {case.rhs[0]}) = {got}, expected {case.rhs[1]}")
    if shutil.which("pdflatex"):
        problems += compile_latex(work, "standalone.tex", None)
        problems += compile_latex(work, "derive.tex", WRAPPER)
        problems += compile_latex(work, "info.tex", WRAPPER)
    return problems


WRAPPER = "\\documentclass{article}\n\\usepackage{amsmath}\n\\begin{document}\n\\input{fragment.tex}\n\\end{document}\n"


def compile_latex(work: Path, name: str, wrapper: str | None) -> list[str]:
    """Compile a written LaTeX document (or a fragment \\input into `wrapper`) without shell escape."""
    written = work / "out" / name
    if not written.exists():
        return []
    latex = work / f"latex-{written.stem}"
    latex.mkdir()
    shutil.copyfile(written, latex / ("fragment.tex" if wrapper else "main.tex"))
    if wrapper:
        (latex / "main.tex").write_text(wrapper)
    try:
        run = subprocess.run(["pdflatex", "-no-shell-escape", "-halt-on-error", "-interaction=nonstopmode", "main.tex"], cwd=latex, capture_output=True, text=True, errors="replace", timeout=DEADLOCK)
    except subprocess.TimeoutExpired:
        return [f"pdflatex on {name} ran over {LIMIT:g} s"]
    log = (latex / "main.log").read_text(errors="replace") if (latex / "main.log").exists() else ""
    problems = []
    if run.returncode != 0:
        problems.append(f"the written {name} does not compile:\n{run.stdout[-1500:]}")
    if "/etc/" in log.replace("/etc/texmf", ""):
        problems.append(f"compiling the written {name} read a file under /etc")
    return problems
