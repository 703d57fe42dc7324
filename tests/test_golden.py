"""Golden files: every bundled system in every format, side by side in tests/golden/.

Regenerate with `make golden` (pytest --update-golden) and review the diff.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from lagrange_cli import derive, spec
from lagrange_cli.emit import latex, python, text
from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model

from .conftest import ROOT, SYSTEMS

GOLDEN = ROOT / "tests" / "golden"
FORMATS: dict[str, Callable[[Model], str]] = {
    "txt": lambda m: text.emit(m),
    "matrix.txt": lambda m: text.emit(m, "matrix"),
    "solved.txt": lambda m: text.emit(m, "solved"),
    "tex": lambda m: latex.emit(m),
    "py": python.emit,
}


@pytest.mark.parametrize("path", SYSTEMS, ids=lambda p: p.stem)
def test_golden(path: Path, update_golden: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    model = derive.derive(spec.load(path.relative_to(ROOT)))
    mismatches = []
    for suffix, emit in FORMATS.items():
        try:
            output = emit(model)
        except LagrangeError as error:
            output = f"error: {error}\n"
        golden = GOLDEN / f"{path.stem}.{suffix}"
        if update_golden:
            golden.write_text(output)
        elif not golden.exists() or golden.read_text() != output:
            mismatches.append(golden.name)
    assert not mismatches, f"output differs from {mismatches}; run `make golden` and review the diff"


def test_no_stale_golden_files() -> None:
    stems = {p.stem for p in SYSTEMS}
    stale = [g.name for g in GOLDEN.iterdir() if g.name.split(".")[0] not in stems]
    assert not stale, stale
