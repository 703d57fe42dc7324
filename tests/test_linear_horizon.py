"""Audit 7 F4: `stress` ran two more tight reference runs over t = 1e5 to learn whether two coupled linear
oscillators are chaotic (about a sixth of its CPU). A system linear in its state with constant coefficients
(`reference.linear`) is never chaotic: two of its solutions part by the same linear map as each solution
itself. Its horizon is not measured. Counted: the runs made, never time."""

from __future__ import annotations

import numpy as np
import pytest

from lagrange_cli.numeric import reference
from lagrange_cli.numeric.runs import Setup

from .conftest import ROOT
from .helpers import model_from, model_of


@pytest.mark.parametrize(
    ("path", "expected"),
    [
        ("systems/harmonic_oscillator.yaml", True),
        ("systems/charged_particle_magnetic.yaml", True),
        ("tests/numeric_audit7/coupled_oscillators_weak_damping_t1e5.yaml", True),
        ("tests/numeric_audit2/driven_coupled_oscillators.yaml", True),  # a drive F(t) leaves it linear
        ("systems/simple_pendulum.yaml", False),
        ("systems/double_pendulum.yaml", False),  # M depends on the angles
        ("tests/numeric_audit6/ball_in_cup_penalty_k1e8.yaml", False),  # Abs
        ("systems/pendulum_multiplier.yaml", False),  # a kept constraint: linear in x, y, but not on the circle
    ],
)
def test_linear_systems_are_told_apart(path: str, expected: bool) -> None:
    assert reference.linear(model_from(ROOT / path)) is expected


def test_a_parametric_drive_is_not_constant_coefficients() -> None:
    # Mathieu's equation: linear in x, its stiffness varying with t
    model = model_of("coordinates: [x]\nparameters: {k: 1.0, e: 0.3, w: 2.0}\nkinetic: x_dot**2/2\npotential: k*(1 + e*cos(w*t))*x**2/2\n")
    assert not reference.linear(model)


def test_no_horizon_runs_for_a_linear_system(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[object] = []
    real = reference.run

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(args[1])
        return real(*args, **kwargs)

    monkeypatch.setattr(reference, "run", counted)
    monkeypatch.setattr(reference, "explicit_attempt", lambda *args, **kwargs: pytest.fail("a horizon run was made"))
    model = model_from(ROOT / "tests" / "numeric_audit7" / "coupled_oscillators_weak_damping_t1e5.yaml")
    assert reference.horizon(model, Setup(50.0, tuple(np.linspace(0.0, 50.0, 11).tolist())), 1e-12) is None
    assert calls == []
    pendulum = model_from(ROOT / "systems" / "simple_pendulum.yaml")
    monkeypatch.undo()
    found = reference.horizon(pendulum, Setup(2.0, tuple(np.linspace(0.0, 2.0, 11).tolist())), 1e-10)
    assert found is not None and not found.chaotic  # measured, as before
