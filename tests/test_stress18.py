"""Issue 15, `stress` within 30 s: work a regime repeated from another. The long horizon shares the defaults' initial
state, and its compiled Radau probes (`reference._doomed`) over the first tenth of its window ran the defaults' probes
again over a longer window, to stop where those stopped (the stiff elastic pendulum in r: three probes of 1e5 steps at
1e-10, 1e-9 and 1e-8); `horizon`'s base run is the reference's first explicit attempt, made twice where its probe ran
out. Counted in integrations, steps and where they stopped, never timed."""

from __future__ import annotations

import numpy as np
import pytest

from lagrange_cli.numeric import compile, reference
from lagrange_cli.numeric.accuracy import Candidate
from lagrange_cli.numeric.runs import Setup
from lagrange_cli.numeric.status import Status

from .conftest import ROOT
from .helpers import model_from
from .test_budget17 import _counting

pytestmark = pytest.mark.skipif(not compile.numba_available(), reason="compiled Radau probes and explicit reference runs")

PILOT = ROOT / "tests" / "numeric_audit_pilot" / "stiff_elastic_pendulum_r.yaml"
STIFF = ROOT / "tests" / "numeric_audit7" / "coupled_oscillators_weak_damping_t1e5.yaml"
"""Compiled Radau at 1e-10 over t = 1e5 of two weakly damped oscillators: about 40 steps a period, so a probe of the
first tenth runs out of its 30000 steps (the stiff pendulum in r was the example until kernels._radau_floor ended its
crawl)."""
WINDOW = 1e5
DOUBLE = ROOT / "systems" / "double_pendulum.yaml"
PROBE_BUDGET = 3000  # scipy steps: a probe of a tenth of it, 300 x COMPILED_STEPS = 30000 compiled Radau steps


def _setup(t_end: float, budget: int = PROBE_BUDGET) -> Setup:
    return Setup(t_end, (0.0, t_end), reference_max_steps=budget)


def test_a_longer_windows_probe_is_the_kept_probe(monkeypatch: pytest.MonkeyPatch) -> None:
    """Compiled Radau at 1e-10 on the oscillators runs out of its probe's 30000 steps inside the first tenth; the
    probe of a window ten times longer (the long horizon's) is answered by it without a run, and a model that kept no probe
    runs that longer probe and stops at the same step count and the same t (the same steps: their end is not reached)."""
    model = model_from(STIFF).with_definitions()
    made = _counting(monkeypatch)
    short = reference._doomed(model, _setup(WINDOW), 1e-10)
    assert len(made) == 1 and made[0].outcome == Status.BUDGET and made[0].t_last < 0.1 * WINDOW, short
    kept = reference._stopped_probes(model)
    assert len(kept) == 1 and kept[0].steps == made[0].stats.steps and kept[0].t_last == made[0].t_last
    made.clear()
    shared = reference._doomed(model, _setup(10 * WINDOW), 1e-10)
    assert made == [] and shared == short.replace(f"of the first {0.1 * WINDOW:.3g}", f"of the first {WINDOW:.3g}")
    fresh = model_from(STIFF).with_definitions()
    ran = reference._doomed(fresh, _setup(10 * WINDOW), 1e-10)
    assert len(made) == 1 and made[0].outcome == Status.BUDGET
    assert ran == shared  # the same steps, stopped at the same t, as the kept probe says
    assert made[0].stats.steps == kept[0].steps and made[0].t_last == kept[0].t_last


def test_a_probe_is_shared_only_where_it_is_the_same_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """Not for another rtol, another initial state, or a budget past the steps the kept probe took (the longer probe
    would go on past where it stopped); nor is a probe kept whose trial steps could have reached its window's end."""
    model = model_from(STIFF).with_definitions()
    reference._doomed(model, _setup(WINDOW), 1e-10)
    assert len(reference._stopped_probes(model)) == 1
    made = _counting(monkeypatch)
    reference._doomed(model, _setup(10 * WINDOW), 1e-9)
    reference._doomed(model, Setup(10 * WINDOW, (0.0, 10 * WINDOW), initial={"x1": 0.4}, reference_max_steps=PROBE_BUDGET), 1e-10)
    reference._doomed(model, _setup(10 * WINDOW, 2 * PROBE_BUDGET), 1e-10)  # 60000 steps allowed, the kept probe took 30000
    reference._doomed(model, _setup(0.5 * WINDOW), 1e-10)  # a shorter window: a trial step of the kept probe may have gone past its end
    assert len(made) == 4 and all(t.outcome == Status.BUDGET for t in made)
    # a window so short that the probe's steps come near its end: 300 probe steps... its largest step x MAX_FACTOR past it
    tiny = model_from(PILOT).with_definitions()
    made.clear()
    found = reference._doomed(tiny, Setup(1e-4, (0.0, 1e-4), reference_max_steps=PROBE_BUDGET), 1e-10)
    assert len(made) == 1
    stopped = made[0]
    if stopped.outcome == Status.BUDGET:
        reach = stopped.t_last + reference.MAX_FACTOR * (stopped.stats.max_step or 0.0)
        assert (reach < 1e-5) == (len(reference._stopped_probes(tiny)) == 1), found
    else:
        assert reference._stopped_probes(tiny) == []


def test_the_first_step_is_scipys() -> None:
    """`_first_step` gives scipy's `select_initial_step` (which numba's `kernels._initial_step` mirrors) for Radau's error
    order over a window long enough not to clamp it, on the stiff pendulum's start and at high energy."""
    from scipy.integrate._ivp.common import select_initial_step

    from lagrange_cli.numeric import policy
    from lagrange_cli.numeric.runs import settings_for

    model = model_from(PILOT).with_definitions()
    for initial in ({}, {"r_dot": 3.0, "theta_dot": 2.0}):
        settings = settings_for(model, Candidate("Radau", "compiled"), 1e-9, Setup(10.0, (0.0, 10.0), initial=initial))
        rhs = policy.safe_rhs(compile.build(model, "python").module, settings.p)
        y0 = np.array(settings.y0)
        f0 = rhs(0.0, y0)
        assert f0 is not None
        expected = select_initial_step(rhs, 0.0, y0, 1e300, np.inf, f0, 1, reference.RADAU_ERROR_ORDER, settings.rtol, settings.atol)
        euler, first = reference._first_step(model, settings)
        assert first == pytest.approx(expected, rel=1e-12) and euler > 0


def test_an_explicit_attempt_is_made_once_per_arguments(monkeypatch: pytest.MonkeyPatch) -> None:
    """`horizon`'s base run and the reference's first attempt are the same call: where its probe runs out (here compiled
    DOP853 at 1e-13 over t = 2000, some 1.6e5 steps, stopped at the driver's first check of its budget) it is not probed again, and the second call returns the first's attempt."""
    model = model_from(DOUBLE).with_definitions()
    setup = Setup(2000.0, tuple(np.linspace(0.0, 2000.0, 101).tolist()), reference_max_steps=20)
    made = _counting(monkeypatch)
    first = reference.explicit_attempt(model, Candidate("DOP853", "compiled"), 1e-13, setup)
    count = len(made)
    assert count >= 1 and made[0].outcome == Status.BUDGET
    again = reference.explicit_attempt(model, Candidate("DOP853", "compiled"), 1e-13, setup)
    assert len(made) == count and again is first
    other = reference.explicit_attempt(model, Candidate("DOP853", "compiled"), 1e-12, setup)
    assert len(made) > count and other is not first
