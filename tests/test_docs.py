"""The project's own description of the format stays in step with the code and the README."""

from __future__ import annotations

import re

from lagrange_cli import spec

from .conftest import ROOT

DOCS = (ROOT / "docs" / "format.md").read_text()


def documented_keys(heading: str) -> set[str]:
    section = DOCS.split(heading, 1)[1].split("\n#", 1)[0]
    return set(re.findall(r"^\| `(\w+)` \|", section, flags=re.MULTILINE))


def test_every_key_is_documented() -> None:
    assert documented_keys("## Top-level keys") == set(spec.TOP_KEYS)
    assert documented_keys("### Particles") == set(spec.PARTICLE_KEYS)
    assert documented_keys("### Bodies") == set(spec.BODY_KEYS)
    assert documented_keys("### Functions") == set(spec.FUNCTION_KEYS)
    assert documented_keys("## `expect`") == set(spec.EXPECT_KEYS)
    for key in spec.SIMULATE_KEYS:
        assert f"`{key}`" in DOCS


def test_readme_opens_with_the_two_commands() -> None:
    lines = (ROOT / "README.md").read_text().splitlines()
    assert lines[2].strip().startswith("make demo") and lines[3].strip().startswith("make test")
