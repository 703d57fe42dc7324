"""The benchmark harness itself (benchmarks/run.py, pendulum.py, peer.py, worker.py) works:
the chain files, the hand-written reference (against sympy.physics.mechanics), the module
check (it must reject a wrong module), the timeout, and one tiny whole-process row at N = 2.
No timing assertions: only that the machinery measures and checks what it claims."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "benchmarks"
sys.path.insert(0, str(BENCH))

import pendulum  # noqa: E402
import worker  # noqa: E402


def load_run() -> Any:
    spec = importlib.util.spec_from_file_location("bench_run", BENCH / "run.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_general_chain_file_has_its_own_mass_and_length_per_link() -> None:
    from lagrange_cli import derive, spec

    chain = pendulum.Chain("general", 4)
    values = chain.parameters()
    assert list(values) == ["m1", "m2", "m3", "m4", "l1", "l2", "l3", "l4", "g"]
    assert len(set(chain.masses())) == 4 and len(set(chain.lengths())) == 4
    model = derive.derive(spec.parse(chain.yaml(), "general_chain_4.yaml"))
    assert model.n == 4 and {p.name for p in model.parameters} == set(values)
    equal = pendulum.Chain("equal", 3)
    assert equal.parameters() == pendulum.PARAMETERS and pendulum.system_yaml(3) == equal.yaml()
    with pytest.raises(ValueError, match="unknown chain kind"):
        pendulum.Chain("spatial", 3)


@pytest.mark.parametrize(("kind", "n"), [("general", 3), ("equal", 2)])
def test_reference_matches_sympy_mechanics(kind: str, n: int) -> None:
    """The hand-written M and F equal LagrangesMethod's at random states and parameter values."""
    import peer
    import sympy as sp

    chain = pendulum.Chain(kind, n)
    mass, forcing, q, symbols = peer.derive_chain(chain)
    mass, forcing, qs, us = peer.plain(mass, forcing, q)
    f = sp.lambdify([qs, us, symbols], (mass.tolist(), list(forcing)), modules="math")
    for seed in (1, 2, 3):
        y = pendulum.state(n, seed)
        p = chain.perturbed(seed)
        m_sympy, f_sympy = f(y[:n], y[n:], [p[str(s)] for s in symbols])
        m_ref, f_ref = chain.reference_matrices(y, p)
        assert max(abs(float(a) - b) for ra, rb in zip(m_sympy, m_ref, strict=True) for a, b in zip(ra, rb, strict=True)) < 1e-12
        assert max(abs(float(a) - b) for a, b in zip(f_sympy, f_ref, strict=True)) < 1e-12


def reference_module(chain: pendulum.Chain, mass_factor: float = 1.0, accel_offset: float = 0.0) -> SimpleNamespace:
    """A module built from the reference itself, optionally with one wrong M entry or a wrong acceleration."""
    defaults = chain.parameters()

    def mass_matrix(q: list[float], p: dict[str, float] = defaults) -> list[list[float]]:
        m = chain.reference_matrices([*q, *[0.0] * chain.n], p)[0]
        m[0][-1] *= mass_factor
        return m

    def forcing(q: list[float], q_dot: list[float], p: dict[str, float] = defaults) -> list[float]:
        return chain.reference_matrices([*q, *q_dot], p)[1]

    def rhs(t: float, y: Any, p: dict[str, float] = defaults) -> list[float]:
        out = chain.reference_rhs([float(v) for v in y], p)
        out[-1] += accel_offset
        return out

    return SimpleNamespace(mass_matrix=mass_matrix, forcing=forcing, rhs=rhs)


def test_check_accepts_the_reference_and_rejects_a_wrong_module() -> None:
    chain = pendulum.Chain("general", 5)
    right = worker.check_module(reference_module(chain), chain)
    assert right["ok"] and max(right["deviation"].values()) < 1e-12
    wrong_m = worker.check_module(reference_module(chain, mass_factor=1.001), chain)
    assert not wrong_m["ok"] and wrong_m["deviation"]["M"] > 1e-6 and wrong_m["deviation"]["rhs residual"] < 1e-12
    wrong_a = worker.check_module(reference_module(chain, accel_offset=1e-5), chain)
    assert not wrong_a["ok"] and wrong_a["deviation"]["rhs residual"] > 1e-9
    assert not worker.check_module(SimpleNamespace(rhs=lambda t, y, p=None: [0.0] * chain.n), chain)["ok"]  # wrong length
    run = load_run()
    assert run.verdict(wrong_m).startswith("**WRONG**") and run.verdict(right).startswith("ok")


def test_a_process_over_the_timeout_is_killed_and_reported(tmp_path: Path) -> None:
    run = load_run()
    runner = run.Runner(ROOT, tmp_path, 0.5)
    value = runner.run([sys.executable, "-c", "import time; time.sleep(60)"])
    assert value == {"error": "over 0.5 s", "timeout": True}
    assert run.timed(value) == "over 0.5 s"
    failed = runner.run([sys.executable, "-c", "raise SystemExit('broken on purpose')"])
    assert failed["error"] == "exit 1: broken on purpose"
    diagnostic = "x.yaml: error: too big\n  ^\nexpected: a smaller system\n"
    assert run.failure(diagnostic) == "error: too big; expected: a smaller system"


def test_whole_process_row_at_n2(capsys: pytest.CaptureFixture[str]) -> None:
    """One tiny row: the installed CLI and the peer as whole processes, both modules checked."""
    before = (ROOT / "BENCHMARKS.md").read_text()
    run = load_run()
    # the timeout is a deadlock net only (as tests/limits.py on main), never a verdict on speed
    assert run.main(["--only", "general", "--sizes", "2", "--repeats", "1", "--no-write", "--timeout", "1800"]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("| 2 |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[3].startswith("ok ") and cells[6].startswith("ok "), row  # lagrange's and the peer's module vs the reference
    assert cells[7].endswith("x") and math.isfinite(float(cells[7].rstrip("x")))
    assert "| general chain N = 15, file to Python module, peer / lagrange | >= 60x | not measured" in out
    assert (ROOT / "BENCHMARKS.md").read_text() == before


def load_spatial() -> Any:
    spec = importlib.util.spec_from_file_location("spatial_bench", BENCH / "spatial_bench.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_spatial_chain_files_parse_derive_and_match_the_bundled_six_link_chain() -> None:
    """Issue 13's benchmark family: N = 6 is benchmarks/spatial_chain_6.yaml, N = 2 derives (6 coordinates)."""
    import yaml

    from lagrange_cli import derive, spec

    bench = load_spatial()
    assert yaml.safe_load(bench.chain_yaml(6)) == yaml.safe_load((BENCH / "spatial_chain_6.yaml").read_text())
    model = derive.derive(spec.parse(bench.chain_yaml(2), "spatial_chain_2.yaml"))
    assert model.n == 6 and list(model.coordinates) == bench.coordinates(2)
    assert {p.name for p in model.parameters} == set(bench.parameters(2))


def test_spatial_check_agrees_with_kanes_method_and_rejects_another_inertia(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """One link: lagrange's module and KanesMethod's (frames, orient_body_fixed, RigidBody) give the
    same accelerations; a module of a chain with other products of inertia is rejected."""
    import json

    from lagrange_cli import api

    bench = load_spatial()
    text = bench.chain_yaml(1)
    ours, other, kane = tmp_path / "ours.py", tmp_path / "other.py", tmp_path / "kane.py"
    ours.write_text(api.from_text(text).to("python"))
    other.write_text(api.from_text(text.replace("/100", "/40")).to("python"))
    bench.peer("kane", "1", str(kane))
    capsys.readouterr()

    def verdict(*paths: Path) -> dict[str, Any]:
        bench.check("1", *map(str, paths))
        return json.loads(capsys.readouterr().out.strip().splitlines()[-1][len("RESULT ") :])

    good = verdict(ours, kane)
    assert good["ok"] and max(good["deviation"]) < 1e-10, good
    bad = verdict(ours, other)
    assert not bad["ok"] and bad["deviation"][1] > 1e-6, bad


def test_spatial_runner_reports_a_process_over_its_cpu_limit(tmp_path: Path) -> None:
    """RLIMIT_CPU stops a busy process, reported as not finished within the limit (a CPU-time cap, not a wall-clock verdict)."""
    bench = load_spatial()
    runner = bench.Runner(ROOT, tmp_path, 1.0)
    value = runner.run([sys.executable, "-c", "while True: pass"])
    assert value["error"] == "did not finish within 1 s of CPU" and value["limit"], value
    done = runner.run([sys.executable, "-c", "print('RESULT {\"x\": 1}')"])
    assert done["x"] == 1 and done["cpu"] > 0 and "error" not in done
