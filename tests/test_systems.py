"""Every bundled system derives, and every answer under `expect` is reproduced."""

from __future__ import annotations

from pathlib import Path

import pytest

from lagrange_cli import check, derive, spec

from .conftest import SYSTEMS


@pytest.mark.parametrize("path", SYSTEMS, ids=lambda p: p.stem)
def test_expected_answers_are_reproduced(path: Path) -> None:
    system = spec.load(path)
    results = check.check(system, derive.derive(system))
    assert results, f"{path.name} has no expect block"
    failures = [f"{r.entry}: {r.detail}" for r in results if not r.passed]
    assert not failures, failures


def test_bundled_systems_cover_the_chapter_and_the_classics() -> None:
    names = {p.stem for p in SYSTEMS}
    chapter = {
        "central_potential",
        "rotating_rod_strings",
        "double_pendulum",
        "elastic_pendulum",
        "rolling_disk_pendulum",
        "rotating_hoop_bead",
        "free_symmetric_top",
        "spherical_coordinates_particle",
        "particle_on_sphere",
        "damped_oscillator_rayleigh",
    }
    classics = {"simple_pendulum", "spherical_pendulum", "atwood_machine", "cart_pole", "pendulum_moving_support", "kepler", "charged_particle_magnetic", "chain_3"}
    assert chapter | classics <= names, sorted((chapter | classics) - names)
