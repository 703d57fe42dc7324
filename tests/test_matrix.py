"""Every feature through every command: the feature x command matrix.

Features are the small systems in `tests/matrix/*.yaml`, one per feature (a new file joins the
matrix); commands are the ones registered on the typer app (a new command joins the matrix, and
fails it until `INVOCATIONS` says how to run it). Each cell runs the command line in-process and
must either work (exit 0) or refuse with exit 2 and a message that README.md documents under
"What each command refuses". No cell may end in a traceback, an "internal error" or exit 1 (the
answers under `expect` are right and the runs are short and tame).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.cli.boundary import INTERNAL_ERROR

from .conftest import ROOT

FEATURES = {path.stem: path for path in sorted((Path(__file__).parent / "matrix").glob("*.yaml"))}

SHORT = ["--t-end", "0.2"]
INVOCATIONS: dict[str, dict[str, list[str]]] = {
    "derive": {
        **{f"{fmt}-{form}": [f"--{fmt}", "--form", form] for fmt in ("text", "latex") for form in ("lagrange", "matrix", "solved")},
        **{f"latex-{form}-standalone": ["--latex", "--standalone", "--form", form] for form in ("lagrange", "matrix", "solved")},
        "python": ["--python"],
        **{f"{fmt}-hamilton": [f"--{fmt}", "--form", "hamilton"] for fmt in ("text", "latex", "python")},
        "latex-hamilton-standalone": ["--latex", "--standalone", "--form", "hamilton"],
        **{f"{fmt}-reduced": [f"--{fmt}", "--form", "reduced"] for fmt in ("text", "latex", "python")},
        **{f"{target}-reduced": ["--to", target, "--form", "reduced"] for target in ("c", "octave", "jax", "json")},
        "c": ["--to", "c"],
        "octave": ["--to", "octave"],
        "jax": ["--to", "jax"],
        "json": ["--to", "json"],
        **{f"{target}-hamilton": ["--to", target, "--form", "hamilton"] for target in ("c", "octave", "jax", "json")},
    },
    "check": {"": []},
    "info": {"text": [], "latex": ["--latex"], "json": ["--json"], "routh": ["--routh"]},
    "equilibria": {"": []},
    "linearize": {"text": [], "json": ["--json"]},
    "simulate": {
        "": [*SHORT, "--backend", "python", "--method", "DOP853", "--samples", "11"],
        "symplectic-stages": [*SHORT, "--method", "symplectic", "--step", "0.02", "--stages", "3", "--samples", "11"],
    },
    "accuracy": {"": ["--method", "DOP853:python", "--tolerances", "1e-4,1e-6", "--repeats", "0", "--samples", "11", *SHORT]},
    "stress": {"": ["--method", "DOP853:python", *SHORT, "--long", "2", "--energy", "2"]},
    "animate": {"": ["-o", "-", *SHORT, "--fps", "10"]},
    "sweep": {
        "": [*SHORT, "--backend", "python", "--method", "DOP853", "--measure", "final", "--measure", "energy_error", "--measure", "max(t)"],
        "symplectic-stages": [*SHORT, "--method", "symplectic", "--step", "0.02", "--stages", "1", "--measure", "final", "--measure", "energy_error"],
    },
}
"""How each command is run in the matrix: variant name -> arguments after the file. (The code targets' cells
only run `derive`; tests/test_target_c.py and tests/test_target_octave.py compile and run every feature's code
in its toolchain and compare it with the Python module.)"""

SHOWS = {
    ("check", ""): "1 file: 1 passed",  # the feature's `expect` was checked, not skipped
    ("derive", "python"): "def rhs(",
    ("derive", "python-hamilton"): "def rhs(",
    ("derive", "text-hamilton"): "H = ",
    ("derive", "text-reduced"): "independent velocities: ",
    ("derive", "python-reduced"): "def rhs(",
    ("derive", "c-reduced"): "static inline void eom_reduce(const double *qdot, double *out)",
    ("derive", "octave-reduced"): "function [dydt, qdot, Mr, Fr] = eom(t, y, p",  # then `, u` with inputs
    ("derive", "jax-reduced"): "def reduced_forcing(t, y, p=None",  # then `, u=None` with inputs
    ("derive", "json-reduced"): '"reduced": {',
    ("derive", "latex-hamilton-standalone"): "\\end{document}",
    ("info", "routh"): "V_eff = ",
    ("derive", "c"): "static inline int eom_rhs(double t, const double *y, const double *p, ",  # then `const double *u, ` with inputs
    ("derive", "octave"): "function [dydt, h, lambda] = eom(t, y, p",  # then `, u` with inputs
    ("derive", "c-hamilton"): "static inline int eom_velocities(double t, const double *y, const double *p, ",  # then `const double *u, ` with inputs
    ("derive", "octave-hamilton"): "function [dydt, H, qdot] = eom(t, y, p",  # then `, u` with inputs
    ("derive", "jax"): "def rhs(t, y, p=None",  # then `, u=None` with inputs
    ("derive", "json"): '"mass_matrix"',
    ("derive", "jax-hamilton"): "def velocities(t, y, p=None",  # then `, u=None` where q_dot depends on an input
    ("derive", "json-hamilton"): '"momentum_rates"',
    **{("derive", f"latex-{form}-standalone"): "\\end{document}" for form in ("lagrange", "matrix", "solved")},
    ("info", "json"): '"hamiltonian"',
    ("simulate", ""): "invariants",
    ("simulate", "symplectic-stages"): "step 0.02, 3 stages",
    ("animate", ""): "</html>",
    ("sweep", ""): "index,",
    ("sweep", "symplectic-stages"): "index,",
}
"""What a cell that works must print (on stdout), where a word says it did its job."""

ABOUT = {
    "holonomic_kept": "x=0,y=-1",
    "inputs_constrained": "x=0,y=-1",
    "cartesian_forces": "theta=atan(0.5/9.81)",
    "generalized_forces": "x=0.25",
    "functions_defined_energy": "r=1",
    "functions_undefined_energy": "r=1",
}
"""Where `linearize` linearizes a feature whose equilibrium is not at 0 (default: every coordinate 0)."""


def sweep_axis(feature: str) -> str:
    """The first coordinate the feature's system keeps (a sweep's cells sweep its initial velocity)."""
    from lagrange_cli import derive, spec

    return derive.derive(spec.load(FEATURES[feature])).coordinates[0]


def commands() -> list[str]:
    return sorted(info.name or info.callback.__name__ for info in app.registered_commands if info.callback is not None)


def cells() -> Iterator[object]:
    for command in sorted({*commands(), *INVOCATIONS}):
        for variant in INVOCATIONS.get(command, {"(no entry)": []}):
            for feature in FEATURES:
                yield pytest.param(feature, command, variant, id=f"{feature}-{command}{'-' + variant if variant else ''}")


def documented_refusals() -> list[re.Pattern[str]]:
    """The refusal messages README.md lists under "What each command refuses": each bullet's
    first `code span`, with `...` standing for any text."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = re.search(r"^### What each command refuses\n(.*?)(?=^#)", text, re.M | re.S)
    assert section, "README.md has no '### What each command refuses' section"
    patterns = re.findall(r"^- `([^`]+)`", section.group(1), re.M)
    assert patterns, "the README's refusal section lists no messages"
    return [re.compile(".*".join(re.escape(part) for part in pattern.split("...")) + "$") for pattern in patterns]


REFUSALS = documented_refusals()


def test_features_and_commands_are_discovered() -> None:
    assert len(FEATURES) >= 15
    assert {"derive", "check", "info", "equilibria", "linearize", "simulate", "accuracy", "stress"} <= set(commands())


def test_every_command_has_an_invocation() -> None:
    missing = sorted(set(commands()) - set(INVOCATIONS))
    assert not missing, f"commands without an entry in tests/test_matrix.py INVOCATIONS (say how the matrix runs them): {', '.join(missing)}"
    assert not set(INVOCATIONS) - set(commands()), "INVOCATIONS names commands the app no longer has"


def test_a_new_command_joins_the_matrix(monkeypatch: pytest.MonkeyPatch) -> None:
    """A command registered on the app gets a column of cells, which fail until INVOCATIONS has it."""
    import copy

    extra = copy.copy(app.registered_commands[0])
    extra.name = "brand-new"
    monkeypatch.setattr(app, "registered_commands", [*app.registered_commands, extra])
    new = [p for p in cells() if p.values[1] == "brand-new"]  # type: ignore[attr-defined]
    assert len(new) == len(FEATURES) and "brand-new" not in INVOCATIONS
    with pytest.raises(pytest.fail.Exception, match=r"no entry in tests/test_matrix\.py INVOCATIONS"):
        test_cell(next(iter(FEATURES)), "brand-new", "(no entry)", Path("."), Path("."))


def test_each_refusal_pattern_matches_its_example() -> None:
    """The patterns are not so loose that they match anything."""
    assert not any(p.match("error: internal error while processing x.yaml: NameError: name 'x_dot' is not defined (please report this)") for p in REFUSALS)
    assert not any(p.match("Traceback (most recent call last):") for p in REFUSALS)


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("matrix-cache")


@pytest.mark.parametrize(("feature", "command", "variant"), list(cells()))
def test_cell(feature: str, command: str, variant: str, cache: Path, tmp_path: Path) -> None:
    if command not in INVOCATIONS:
        pytest.fail(f"the command '{command}' has no entry in tests/test_matrix.py INVOCATIONS: add how the matrix should run it")
    args = [command, str(FEATURES[feature]), *INVOCATIONS[command][variant]]
    if command == "linearize" and feature in ABOUT:
        args += ["--about", ABOUT[feature]]
    if command == "sweep":
        args += ["--initial", f"{sweep_axis(feature)}_dot=0..0.1:2"]
    result = CliRunner().invoke(app, args, env={"LAGRANGE_CACHE_DIR": str(cache), "COLUMNS": "200"})
    shown = f"$ lagrange {' '.join(args)}\nexit {result.exit_code}\nstdout:\n{result.stdout[-3000:]}\nstderr:\n{result.stderr[-3000:]}"
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        import traceback

        pytest.fail(f"traceback:\n{''.join(traceback.format_exception(result.exception))}\n{shown}")
    assert "Traceback" not in result.output and INTERNAL_ERROR not in result.output, shown
    if result.exit_code == 0:
        assert result.stdout.strip(), f"exit 0 with nothing on stdout\n{shown}"
        assert SHOWS.get((command, variant), "") in result.stdout, f"exit 0 without {SHOWS[command, variant]!r} on stdout\n{shown}"
        return
    assert result.exit_code == 2, f"exit {result.exit_code} (only 0, or 2 with a documented refusal, is allowed here)\n{shown}"
    first = (result.stderr.strip().splitlines() or [""])[0]
    assert any(p.match(first) for p in REFUSALS), f"exit 2 with a message README.md does not document under 'What each command refuses':\n{shown}"
