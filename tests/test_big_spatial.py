"""Systems whose equations are small only with their common parts shared (a spatial chain with
`relative_to`): the commands whose code shares them take such a system, the others refuse it with
the documented message.

A 2-link spatial chain stands in for the 6-link one (benchmarks/spatial_chain_6.yaml, about 59 million
nodes written out): `derive.MAX_EQUATION_TREE` is lowered below its size, so that its
sympy fields refuse to be read exactly as the big chain's do, and the tests stay fast."""

from __future__ import annotations

import importlib.util
import math
import random
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lagrange_cli import derive, spec, validate
from lagrange_cli.cli import app
from lagrange_cli.emit import python

from .conftest import ROOT
from .helpers import load_module
from .test_target_c import GCC, Case, build_and_run

BENCH = importlib.util.spec_from_file_location("spatial_bench_for_tests", ROOT / "benchmarks" / "spatial_bench.py")
assert BENCH and BENCH.loader
spatial_bench = importlib.util.module_from_spec(BENCH)
sys.modules["spatial_bench_for_tests"] = spatial_bench
BENCH.loader.exec_module(spatial_bench)

SHARING = ["derive --to python", "derive --to c", "derive --to octave", "derive --to jax"]
WRITTEN_OUT = ["derive --text", "derive --latex", "derive --to json", "info", "linearize", "check"]


@pytest.fixture
def chain(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The 2-link chain's file, with the written-out limit just below its size."""
    path = tmp_path / "chain2.yaml"
    path.write_text(spatial_bench.chain_yaml(2), encoding="utf-8")
    model = derive.derive(spec.load(path))
    size, tree, _ = validate.survey(validate.forms_parts(model.symengine))
    assert size < tree  # shared, the equations are smaller than written out
    monkeypatch.setattr(derive, "MAX_EQUATION_TREE", size // 2)  # below both the composite and the body-by-body forms
    with pytest.raises(spec.SpecError, match="written out without sharing"):
        derive.derive(spec.load(path))
    return path


@pytest.mark.parametrize("command", SHARING)
def test_code_targets_take_it(chain: Path, command: str) -> None:
    name, *options = command.split()
    result = CliRunner().invoke(app, [name, str(chain), *options])
    assert result.exit_code == 0, result.output
    assert "without sharing" not in result.output and len(result.stdout) > 1000


@pytest.mark.parametrize("command", WRITTEN_OUT)
def test_commands_that_write_it_out_refuse_it_saying_what_works(chain: Path, command: str) -> None:
    name, *options = command.split()
    result = CliRunner().invoke(app, [name, str(chain), *options])
    assert result.exit_code == 2, result.output
    assert "written out without sharing" in result.output and "`simulate`" in result.output


def test_simulate_takes_it_and_agrees_with_the_python_module(chain: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LAGRANGE_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(app, ["simulate", str(chain), "--t-end", "0.3", "--backend", "python", "--method", "DOP853", "--rtol", "1e-10", "--atol", "1e-12", "-o", str(out)])
    assert result.exit_code == 0, result.output
    rows = [line.split(",") for line in out.read_text().splitlines()]
    model = derive.derive(spec.load(chain), shared=True)
    states = slice(1, 1 + 2 * model.n)  # after t; the energy follows
    assert rows[0][states] == [*model.coordinates, *(f"{q}_dot" for q in model.coordinates)]
    first, last = [float(v) for v in rows[1]], [float(v) for v in rows[-1]]
    module = load_module(python.emit(model), tmp_path / "chain2.py")
    from scipy.integrate import solve_ivp

    expected = solve_ivp(module.rhs, (0.0, last[0]), first[states], method="DOP853", rtol=1e-11, atol=1e-13).y[:, -1]
    assert max(abs(a - b) for a, b in zip(last[states], expected, strict=True)) < 1e-7


def test_its_c_code_agrees_with_its_python_module(chain: Path, tmp_path: Path) -> None:
    model = derive.derive(spec.load(chain), shared=True)
    module = load_module(python.emit(model), tmp_path / "chain2.py")
    rng = random.Random(3)
    p = {q.name: q.value for q in model.parameters}
    states = [(0.0, [rng.uniform(-1.0, 1.0) for _ in range(2 * model.n)], p) for _ in range(3)]
    results = build_and_run([Case("chain2", model, "chain2", states)], tmp_path / "c", GCC)
    for k, (t, y, _) in enumerate(states):
        status, dydt, _ = results[(0, k)]
        expected = module.rhs(t, y)
        assert status == 0
        assert all(math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-11) for a, b in zip(dydt, expected, strict=True)), (dydt, expected)
