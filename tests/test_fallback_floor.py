"""Issue 15, audit 5's F10: an explicit reference standing in for an implicit one on a stiff system is accurate
only where its steps are stability-limited. Across the fast jumps of a relaxation oscillation (Van der Pol,
mu = 1000) they are accuracy-limited, and compiled RK45 and DOP853 at neighbouring rtols lag the jump alike:
their agreement understated the reference's own error about 20 x, and a recommendation reported at 8.8e-7
was truly 1.13e-6. The reference's own error is now floored by RK45 itself a decade looser, and tightened
while it can reach what is needed. Counted: assertions are on errors and texts, never on time."""

from __future__ import annotations

import numpy as np
import pytest

from lagrange_cli.numeric import compile, reference, runs, stress
from lagrange_cli.numeric.accuracy import Candidate
from lagrange_cli.numeric.runs import Setup, component_scale, run, scaled_errors

from .conftest import ROOT
from .helpers import model_from

pytestmark = [pytest.mark.usefixtures("private_cache"), pytest.mark.skipif(not compile.numba_available(), reason="the fallback is compiled RK45")]

VDP = ROOT / "tests" / "numeric_audit5" / "van_der_pol_mu1000_coupled.yaml"


@pytest.mark.parametrize("compiled", [False, True])
def test_the_explicit_fallback_bounds_its_own_error_across_a_jump(compiled: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """Over the file's t = 2000 (the slow branch from x = 2, jumps near t = 800 and 1600: stress's defaults
    regime) the reference is the explicit fallback where Radau runs in Python (it cannot finish within its budget),
    compiled Radau where that runs (helper radstress), and either's own error bounds its true error against compiled
    DOP853 at 1e-12."""
    if compiled and not runs.compiled_radau():
        pytest.skip("the compiled Radau method needs numba")
    if not compiled:
        monkeypatch.setattr(runs, "compiled_radau", lambda: False)
        monkeypatch.setattr(reference, "compiled_radau", lambda: False)
    model = model_from(VDP).with_definitions()
    target = 1e-6
    setup = Setup(2000.0, tuple(np.linspace(0.0, 2000.0, 2001).tolist()), max_steps=stress.MAX_STEPS)
    found = reference.computed_reference(model, setup, stress.reference_tolerance(target), implicit=stress.implicit_reference_tolerances(target))
    expected = ("Radau", "compiled") if compiled else ("RK45", "compiled")
    assert found.settings is not None and (found.settings.method, found.settings.backend) == expected, found.description
    assert compiled or "explicit, stability-limited" in found.description
    tight = run(model, Candidate("DOP853", "compiled"), 1e-12, setup, reference=True)
    assert not tight.failed
    truth = float(np.max(scaled_errors(found.y, tight.y, component_scale(tight.y))))
    assert truth <= found.own_error, (truth, found.description)
    # and the regime can still be decided: the reference is tightened until its own error leaves room for 1e-6
    assert found.own_error <= stress.REFERENCE_ROOM * target, found.description


def test_the_floor_applies_even_to_a_looser_confirmation() -> None:
    """`_floored(always=True)` raises the own error to RK45's own disagreement a decade looser even where the
    second method ran 10 x looser (where, without it, that looser run's agreement is taken as an upper bound)."""
    model = model_from(VDP).with_definitions()
    setup = Setup(1000.0, tuple(np.linspace(0.0, 1000.0, 1001).tolist()), max_steps=stress.MAX_STEPS)
    primary = Candidate("RK45", "compiled")
    main = run(model, primary, 1e-9, setup, reference=True)
    assert not main.failed
    found = reference._confirmed(model, setup, main, 1e-9, [(Candidate("DOP853", "compiled"), 1e-8)], 0.0)
    assert reference._floored(model, setup, main, 1e-9, found, primary, 0.0) is found  # 10 x looser: not floored by default
    floored = reference._floored(model, setup, main, 1e-9, found, primary, 0.0, always=True)
    looser = run(model, primary, 1e-8, setup, reference=True)
    apart = float(np.max(scaled_errors(looser.y, main.y, component_scale(main.y))))
    assert floored.own_error == max(found.own_error, apart)
