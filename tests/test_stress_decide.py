"""Issue 15: `stress` decides where a reference good enough to decide exists, and never fails a
regime its reference cannot vouch for. Counted: assertions are on errors and verdicts, never on time."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.special import ellipj, ellipk

from lagrange_cli.numeric import stress
from lagrange_cli.numeric.accuracy import Candidate
from lagrange_cli.numeric.runs import Setup, run

from .conftest import ROOT
from .helpers import model_from

pytestmark = pytest.mark.usefixtures("private_cache")

AUDIT3 = ROOT / "tests" / "numeric_audit3"


def pendulum_exact(ts: np.ndarray, theta0: float, length: float, g: float) -> np.ndarray:
    """A pendulum released from rest at theta0 (Jacobi): sin(theta/2) = k sn(K - w t | k^2), as x, y, x_dot, y_dot."""
    w, k = math.sqrt(g / length), math.sin(theta0 / 2)
    sn, cn, _, _ = ellipj(ellipk(k * k) - w * ts, k * k)
    th, thd = 2 * np.arcsin(k * sn), -2 * k * w * cn
    return np.column_stack([length * np.sin(th), -length * np.cos(th), length * np.cos(th) * thd, length * np.sin(th) * thd])


def true_error(y: np.ndarray, exact: np.ndarray) -> float:
    return float(np.max(np.abs(y - exact) / np.maximum(1.0, np.max(np.abs(exact), axis=0))))


def test_the_multiplier_pendulum_long_horizon_is_decided_and_its_recommendation_truly_meets() -> None:
    """Over t = 1e4 (the file's 1e3 x 10) the explicit reference (DOP853 at 2.5e-14, 4e-9 off the exact
    solution) was confirmed only by RK45 at 2.5e-10, whose own error (7e-5) left the regime undecided.
    Now RK45 confirms it at the same rtol (its paced run may take the steps it needs), or else DOP853
    10 x looser, the error converging with the tolerance (100 x looser is farther still); and the
    recommendation's error against the exact solution meets 1e-6."""
    model = model_from(AUDIT3 / "pendulum_multiplier_large_swing.yaml")
    long = next(r for r in stress.regimes(model, ()) if r.name.startswith("long horizon"))
    target = 1e-6
    outcome = stress._regime(model, long, target, [stress.AUTO], Setup(0.0, (), max_steps=stress.MAX_STEPS), None)
    assert outcome.verdict == "met" and outcome.recommended is not None, (outcome.reference, outcome.open_reason)
    # confirmed either by RK45 at the same rtol (its compiled run may now have up to 4 x its budget where its pace says that
    # suffices: stresscost) or by DOP853 10 x looser converging with the tolerance (`reference._converged`); either way it vouches
    assert ("converges with the tolerance" in outcome.reference or "at the same tolerance" in outcome.reference) and outcome.reference_error <= 0.1 * target
    ts = np.linspace(0.0, long.t_end, long.samples)
    exact = pendulum_exact(ts, 2.5, 1.6, 9.81)
    ran = outcome.recommended.ran
    assert ran is not None
    again = run(model, Candidate(ran.method, ran.backend), outcome.recommended.tolerance, Setup(long.t_end, tuple(ts.tolist()), max_steps=stress.MAX_STEPS))
    assert not again.failed
    assert true_error(again.y, exact) <= target  # the recommendation truly meets the accuracy
    # and its reported error is the true one to within the reference's own error. DOP853 and RK45 both at 2.5e-14, both
    # projected, agree to 1.4e-10 but are both 4.2e-9 off the exact solution (a known weak spot of same-rtol pairs, session
    # 11): the own error is now floored by DOP853 10 x looser (`reference._floored`, 4.4e-8), which bounds it
    assert abs(true_error(again.y, exact) - outcome.recommended.error) <= outcome.reference_error


@pytest.mark.parametrize(("own", "verdict"), [(0.5, "undecided"), (0.05, "not met")])
def test_no_method_meeting_is_a_failure_only_when_the_reference_leaves_the_runs_nine_tenths(monkeypatch: pytest.MonkeyPatch, own: float, verdict: str) -> None:
    """The hazard of stressb2: an own error just under the accuracy with no rung able to meet what is
    left gave "not met" (exit 1). A regime whose reference's own error is above REFERENCE_ROOM x the
    accuracy is undecided when no method meets it; below, it is decided."""
    target = 1e-6
    real = stress.prepare

    def prepared(*args, **kwargs):  # type: ignore[no-untyped-def]
        setup, reference, horizon, notes = real(*args, **kwargs)
        return setup, replace(reference, own_error=own * target), horizon, notes

    monkeypatch.setattr(stress, "prepare", prepared)
    model = model_from(ROOT / "systems" / "simple_pendulum.yaml")
    # scipy's RK45 with a budget of 30 steps over t = 100: it cannot meet 1e-6 (nor finish)
    report = stress.stress(model, scales=[("g", [9.81])], target=target, candidates=[Candidate("RK45", "python")], t_end=100.0, max_steps=30)
    (outcome,) = report.outcomes
    assert outcome.verdict == verdict, (outcome.open_reason, [p.status for p in outcome.points])
    assert report.failed == (verdict == "not met")
