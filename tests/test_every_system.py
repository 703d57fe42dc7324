"""`lagrange accuracy` and `lagrange stress` work on every bundled system.

Short windows and few methods: what is checked is that each command runs end to end on each
file, its reference is confirmed, and every regime finds a method meeting the accuracy over a
short window. Budgets count steps (`--max-steps`), never seconds, so that a verdict here does not
depend on the machine's load; the stress runs get a third of the default budget, which every
bundled system meets within. Compiled code goes to the user's cache as usual (a fresh machine compiles each
system once). The full-length runs of every system are in BENCHMARKS.md
(`benchmarks/every_system.py`)."""

from __future__ import annotations

import json
import math

import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app

from .conftest import ROOT

runner = CliRunner()
SYSTEMS = sorted(p.stem for p in (ROOT / "systems").glob("*.yaml"))


def test_every_bundled_system_is_covered() -> None:
    assert len(SYSTEMS) >= 28


@pytest.mark.parametrize("name", SYSTEMS)
def test_accuracy_runs_on(name: str) -> None:
    result = runner.invoke(app, ["accuracy", name, "--method", "DOP853,Radau", "--tolerances", "1e-4,1e-7", "--t-end", "0.5", "--repeats", "0", "--samples", "11", "--json", "-"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert document["t_end"] == pytest.approx(0.5)
    reference = document["reference"]
    assert reference["kind"] == "exact" or (reference["own_error"] is not None and reference["own_error"] < 1e-7), reference
    points = {(p["method"], p["setting"]): p for p in document["points"]}
    assert len(points) == 4
    tight = points[("DOP853", "rtol 1e-07, atol 1e-10")]
    assert tight["status"] == "finished" and tight["final_error"] < 1e-4, tight
    assert all(p["status"] == "finished" and math.isfinite(p["rms_error"]) for p in points.values()), points


@pytest.mark.parametrize("name", SYSTEMS)
def test_stress_runs_on(name: str) -> None:
    result = runner.invoke(app, ["stress", name, "--method", "RK45:python,DOP853", "--t-end", "0.5", "--long", "2", "--accuracy", "1e-6", "--max-steps", "20000", "--json", "-"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    regimes = document["regimes"]
    assert [r["regime"].split(" ")[0] for r in regimes[:3]] == ["defaults", "long", "high"]
    for regime in regimes:
        assert regime["naive_default"] is not None and regime["naive_default"]["setting"] == "rtol 1e-03, atol 1e-06"
        assert math.isfinite(regime["max_mass_condition"]), regime
        if regime["verdict"] == "undecided":
            # only where the reference itself cannot vouch for 1e-6: two methods at 2.5e-14 disagree by more
            # (Kepler started at r = 0.01 falls to r ~ 1e-8: round-off, not any method, limits the error)
            # or where its second method cannot pass the singularity at all (central_potential: r falls to ~1e-8,
            # where compiled RK45 at 2.5e-14 collapses its step): unconfirmed, so nothing is claimed
            assert regime["regime"].startswith("near singular"), regime
            if regime["reference_error"] is None:
                assert "unconfirmed" in regime["reference"] and "reference is unconfirmed" in regime["open_reason"], regime
            else:
                assert regime["reference_error"] > 1e-7 and "reference's own error" in regime["open_reason"], regime
            continue
        assert regime["verdict"] == "met" and regime["recommended"]["error"] + regime["reference_error"] <= 1e-6, regime
    assert document["verdict"] == ("passed" if all(r["verdict"] == "met" for r in regimes) else "undecided")
