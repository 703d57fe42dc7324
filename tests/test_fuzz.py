"""Fuzzing in the suite: hostile mutations of every bundled system file, and systems built from
generated expressions, each run through parse, derive, every emitter, the emitted `rhs`, `check`,
`info` and a short simulation (tests/fuzzing.py). Every step must end normally or with the
project's own error: never another exception, a hang, a file written on failure, code from the
file executed, or file text live in a sink.

Fixed seed and bounded counts (`make fuzz` runs the same cases by the ten thousand). Failures are
collected over all examples and reported together, deduplicated, each with the file text that
first showed it (hypothesis does not shrink them: that would take minutes per failure class).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

from tests.fuzzing import SYSTEMS, Failure, generated_systems, mutated_systems, run_case

MUTATIONS_PER_FILE = 3
GENERATED = 30
SETTINGS = {"derandomize": True, "deadline": None, "database": None, "suppress_health_check": list(HealthCheck)}


def _report(found: dict[str, tuple[Failure, str]]) -> str:
    lines = [f"{len(found)} distinct failure(s):"]
    for key, (failure, text) in sorted(found.items()):
        lines += [f"- {key}: {failure.detail}", "  file:", *("    " + line for line in text.splitlines()[:25])]
    return "\n".join(lines)


def _run(text: str, folder: Path, found: dict[str, tuple[Failure, str]]) -> None:
    folder.mkdir(parents=True)
    for failure in run_case(text, folder).failures:
        found.setdefault(failure.key, (failure, text))


@pytest.mark.parametrize(("index", "system"), list(enumerate(SYSTEMS)), ids=[p.stem for p in SYSTEMS])
def test_mutated_bundled_file(index: int, system: Path, tmp_path: Path) -> None:
    found: dict[str, tuple[Failure, str]] = {}
    count = iter(range(10**6))

    @settings(max_examples=MUTATIONS_PER_FILE, **SETTINGS)  # type: ignore[arg-type]
    @given(mutated_systems(path=system, rotate=index))
    def run(text: str) -> None:
        _run(text, tmp_path / str(next(count)), found)

    run()
    assert not found, _report(found)


def test_generated_expressions(tmp_path: Path) -> None:
    found: dict[str, tuple[Failure, str]] = {}
    count = iter(range(10**6))

    @settings(max_examples=GENERATED, **SETTINGS)  # type: ignore[arg-type]
    @given(generated_systems())
    def run(text: str) -> None:
        _run(text, tmp_path / str(next(count)), found)

    run()
    assert not found, _report(found)
