"""`stress`'s reference: the primary's own looser runs (its convergence) are made beside the second method's, in a
thread of their own (`memo.ahead`, `reference.attempt_ahead`): the same runs, and the same reference, as one after
another, in less wall time on a machine with two cores."""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import pytest

from lagrange_cli.numeric import compile, memo, reference, runs, stress
from lagrange_cli.numeric.runs import Setup

from .conftest import ROOT
from .helpers import model_from

numba = pytest.mark.skipif(not compile.numba_available(), reason="the compiled methods need numba")

PENDULUM = ROOT / "tests" / "numeric_audit3" / "pendulum_multiplier_large_swing.yaml"


def test_a_value_started_ahead_is_the_one_once_returns_and_its_failure_is_raised_there() -> None:
    """`memo.ahead` computes in a thread; `once` with the key waits for it, returns its value (not computing again) or
    raises its exception; `settle` waits for what nobody asked for yet, which `once` still takes up."""

    class Owner:
        pass

    owner = Owner()
    gate = threading.Event()
    threads: list[str] = []

    def slow() -> int:
        gate.wait(10)
        threads.append(threading.current_thread().name)
        return 42

    memo.ahead(owner, "value", slow)
    memo.ahead(owner, "value", lambda: 0)  # started already: not again
    gate.set()
    assert memo.once(owner, "value", lambda: -1) == 42
    assert threads == ["lagrange-ahead"]
    memo.ahead(owner, "value", lambda: 0)  # known already: nothing started
    assert memo.once(owner, "value", lambda: -1) == 42

    def failing() -> int:
        raise ValueError("no run")

    memo.ahead(owner, "failure", failing)
    memo.settle(owner)
    with pytest.raises(ValueError, match="no run"):
        memo.once(owner, "failure", lambda: -1)
    memo.ahead(owner, "later", lambda: 7)
    memo.settle(owner)
    assert memo.once(owner, "later", lambda: -1) == 7


@numba
@pytest.mark.usefixtures("private_cache")
def test_the_primarys_looser_runs_are_made_beside_the_second_method_and_give_the_same_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    """The multiplier pendulum over t = 2000: compiled DOP853 at 10 x and 100 x the reference's rtol (its convergence) are
    started ahead, in a thread, while compiled RK45 at the reference's rtol is probed; `_converged` takes them up. Nothing
    started ahead is left running once the reference is made, and the reference (own error, trajectory, description)
    is the one made one run after another."""
    started: list[tuple[str, float]] = []
    real = memo.ahead

    def recording(owner: object, key: tuple[Any, ...], compute: Any) -> None:
        started.append((key[1].method, float(key[2])))
        real(owner, key, compute)

    monkeypatch.setattr(memo, "ahead", recording)
    t_end = 2000.0
    model = model_from(PENDULUM)
    setup = runs.starting(model, Setup(t_end, tuple(np.linspace(0.0, t_end, 4001).tolist()), max_steps=stress.MAX_STEPS))
    beside = reference.computed_reference(model, setup, stress.reference_tolerance(1e-6), implicit=stress.implicit_reference_tolerances(1e-6))
    assert started == [("DOP853", 2.5e-13), ("DOP853", 2.5e-12)], started
    assert not model.__dict__.get(memo.AHEAD_SLOT), "a run started ahead was left"
    assert "converges with the tolerance" in beside.description, beside.description
    monkeypatch.setattr(reference, "attempt_ahead", lambda *args, **options: None)
    alone_model = model_from(PENDULUM)
    alone = reference.computed_reference(alone_model, setup, stress.reference_tolerance(1e-6), implicit=stress.implicit_reference_tolerances(1e-6))
    assert (beside.own_error, beside.description) == (alone.own_error, alone.description)
    assert np.array_equal(beside.y, alone.y)
