"""`stress`'s reference: a second method far costlier than the primary waits for the primary's own convergence
(`reference.SECOND_COST`, `SECOND_STEPS`); it is still asked for where it is cheap, or where the convergence
cannot vouch."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from lagrange_cli.numeric import compile, reference, runs, stress
from lagrange_cli.numeric.runs import Candidate, Setup

from .conftest import ROOT
from .helpers import counting_integrations, model_from

pytestmark = [pytest.mark.usefixtures("private_cache"), pytest.mark.skipif(not compile.numba_available(), reason="the compiled methods need numba")]

PENDULUM = ROOT / "tests" / "numeric_audit3" / "pendulum_multiplier_large_swing.yaml"


def _reference(t_end: float, samples: int) -> tuple[Any, Setup, reference.Reference]:
    model = model_from(PENDULUM)
    setup = runs.starting(model, Setup(t_end, tuple(np.linspace(0.0, t_end, samples).tolist()), max_steps=stress.MAX_STEPS))
    found = reference.computed_reference(model, setup, stress.reference_tolerance(1e-6), implicit=stress.implicit_reference_tolerances(1e-6))
    return model, setup, found


def test_a_costly_second_method_waits_for_the_primarys_convergence(monkeypatch: pytest.MonkeyPatch) -> None:
    """The multiplier pendulum over t = 2000: compiled RK45 at 2.5e-14 needs some 1.3e6 steps, 12 x DOP853's: it is
    only probed, and DOP853 10 x and 100 x looser, converging, bound the reference's error. That bound holds against
    the RK45 run that was left out, made here."""
    made = counting_integrations(monkeypatch)
    model, setup, found = _reference(2000.0, 4001)
    assert found.settings is not None and (found.settings.method, found.settings.rtol) == ("DOP853", 2.5e-14)
    assert "converges with the tolerance" in found.description and "cannot finish within" in found.description, found.description
    primary = next(m for m in made if m[:3] == ("DOP853", "compiled", 2.5e-14))
    second = [m for m in made if m[:2] == ("RK45", "compiled")]
    assert second and all(m[4] <= reference.SECOND_COST * primary[4] and m[5] != "finished" for m in second), (primary, second)
    independent = runs.run(model, Candidate("RK45", "compiled"), 2.5e-14, replace(setup, reference_max_steps=40_000), reference=True)
    assert independent.outcome == runs.Status.FINISHED and independent.stats.steps > reference.SECOND_STEPS
    true = float(np.max(runs.scaled_errors(found.y, independent.y, runs.component_scale(found.y))))
    assert true <= found.own_error, (true, found.own_error)


def test_a_cheap_second_method_still_confirms(monkeypatch: pytest.MonkeyPatch) -> None:
    """Over t = 100 the same RK45 run takes some 6.4e4 steps, below SECOND_STEPS: it confirms at the primary's rtol."""
    made = counting_integrations(monkeypatch)
    _, _, found = _reference(100.0, 2001)
    assert found.confirmer == Candidate("RK45", "compiled") and found.confirmed_rtol == 2.5e-14, found.description
    assert any(m[:3] == ("RK45", "compiled", 2.5e-14) and m[5] == "finished" for m in made), made
