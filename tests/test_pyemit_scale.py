"""Emission that scales (issue 14): the general N-link chain (own m_i, l_i per link), emitted
from `Model.symengine` without touching the sympy fields, agrees with M and F written out by
hand at random states; its structure is O(N) trig calls; numba code cut into parts computes
what the uncut code computes."""

from __future__ import annotations

import math
import random
import re
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from lagrange_cli.emit import python
from lagrange_cli.numeric import codegen

from .conftest import ROOT
from .helpers import load_module, model_from, model_of


def chain_yaml(n: int) -> str:
    """Particle k at sum_{i<=k} l_i (sin th_i, -cos th_i), mass m_k; gravity g downwards."""
    rng = random.Random(n)
    values = ", ".join(f"m{i}: {rng.uniform(0.5, 2.0):.3f}, l{i}: {rng.uniform(0.5, 1.5):.3f}" for i in range(1, n + 1))
    lines = [f"title: General {n}-link chain", f"coordinates: [{', '.join(f'th{i}' for i in range(1, n + 1))}]", f"parameters: {{{values}, g: 9.81}}", "gravity: [0, -g]", "particles:"]
    for k in range(1, n + 1):
        x = " + ".join(f"l{i}*sin(th{i})" for i in range(1, k + 1))
        y = " - ".join(f"l{i}*cos(th{i})" for i in range(1, k + 1))
        lines.append(f"  p{k}: {{mass: m{k}, position: [{x}, -{y}]}}")
    return "\n".join(lines) + "\n"


def reference(y: list[float], p: dict[str, float]) -> tuple[list[list[float]], list[float], float]:
    """M, F and the energy written out by hand: S_k = m_k + ... + m_N,
    M_ij = l_i l_j S_max(i,j) cos(th_i - th_j), F_i = -sum_j l_i l_j S_max(i,j) sin(th_i - th_j) w_j^2 - g l_i S_i sin th_i,
    h = w^T M w / 2 - g sum_i l_i S_i cos th_i."""
    n = len(y) // 2
    th, w = y[:n], y[n:]
    m = [p[f"m{i + 1}"] for i in range(n)]
    length = [p[f"l{i + 1}"] for i in range(n)]
    g = p["g"]
    s = [sum(m[k:]) for k in range(n)]
    mass = [[length[i] * length[j] * s[max(i, j)] * math.cos(th[i] - th[j]) for j in range(n)] for i in range(n)]
    force = [-sum(length[i] * length[j] * s[max(i, j)] * math.sin(th[i] - th[j]) * w[j] ** 2 for j in range(n)) - g * length[i] * s[i] * math.sin(th[i]) for i in range(n)]
    energy = sum(w[i] * mass[i][j] * w[j] for i in range(n) for j in range(n)) / 2 - g * sum(length[i] * s[i] * math.cos(th[i]) for i in range(n))
    return mass, force, energy


def states(n: int, count: int = 3) -> list[list[float]]:
    rng = random.Random(100 + n)
    return [[rng.uniform(-2.0, 2.0) for _ in range(n)] + [rng.uniform(-3.0, 3.0) for _ in range(n)] for _ in range(count)]


@pytest.mark.parametrize("n", [3, 5, 8])
def test_general_chain_module_agrees_with_the_hand_written_equations(n: int, tmp_path: Path) -> None:
    model = model_of(chain_yaml(n), f"chain_{n}.yaml")
    module = load_module(python.emit(model), tmp_path / f"chain_{n}_eom.py")
    assert model.converted() == frozenset()  # printed from model.symengine: no sympy field was built
    p = dict(module.PARAMETERS)
    for y in states(n):
        mass, force, energy = reference(y, p)
        q, qd = y[:n], y[n:]
        assert np.allclose(module.mass_matrix(q, p), mass, rtol=1e-12, atol=1e-12)
        assert np.allclose(module.forcing(q, qd, p), force, rtol=1e-11, atol=1e-11)
        assert module.energy(q, qd, p) == pytest.approx(energy, rel=1e-11, abs=1e-11)
        expected = [*qd, *np.linalg.solve(mass, force)]
        for state in (y, np.array(y)):  # a list, and the numpy array solve_ivp passes
            assert np.allclose(module.rhs(0.0, state, p), expected, rtol=1e-9, atol=1e-10)


def test_trig_calls_and_mass_entries_grow_linearly_and_quadratically(tmp_path: Path) -> None:
    """sin and cos of each angle once (2N calls, not one per pair of links as cos(th_i - th_j)
    would need), and each of the N(N+1)/2 distinct entries of the symmetric M bound once."""
    n = 8
    code = python.emit(model_of(chain_yaml(n), "chain_8.yaml"))
    rhs = code[code.index("def rhs(") :]
    calls = sum(rhs.count(f"{name}(") for name in ("sin", "cos"))
    assert calls == 2 * n
    matrix = re.search(r"_solve\(\[\[(.*?)\]\]", rhs)
    assert matrix is not None
    entries = [entry for row in matrix.group(1).split("], [") for entry in row.split(", ")]
    assert len(entries) == n * n and all(entry.isidentifier() for entry in entries)  # names: each computed once, before
    assert len(set(entries)) == n * (n + 1) // 2  # symmetric: M[i][j] and M[j][i] are one name
    assert sum(f"{name}(" in line for line in code.splitlines() for name in ("sin", "cos")) <= 4 * 2 * n  # mass_matrix, forcing, energy, rhs


def test_suffix_mass_sums_are_shared(tmp_path: Path) -> None:
    """The sums m_k + ... + m_N are built one from the next: N - 1 additions of masses in all,
    not the O(N^2) of writing each sum out."""
    n = 8
    code = python.emit(model_of(chain_yaml(n), "chain_8.yaml"))
    rhs = code[code.index("def rhs(") :]
    additions = [line for line in rhs.splitlines() if " = " in line and " + " in line and all(word.startswith(("m", "_k")) for word in line.split(" = ")[1].split(" + "))]
    assert len(additions) == n - 1


def test_codegen_reads_no_sympy_field() -> None:
    model = model_of(chain_yaml(6), "chain_6.yaml")
    for target in ("python", "numba"):
        codegen.source(model, target)
    codegen.ignorable(model)
    assert model.converted() == frozenset()


def fake_numba() -> types.ModuleType:
    module = types.ModuleType("numba")
    module.njit = lambda *args, **kwargs: lambda f: f  # type: ignore[attr-defined]
    return module


def test_numba_code_as_loops_computes_the_same(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`--numba` code of a long function is written as loops over tables (`vectorize`); run as
    plain Python (numba's decorator replaced), it gives exactly what the straight-line code gives,
    with far fewer statements for numba to compile."""
    n = 5
    model = model_of(chain_yaml(n), "chain_5.yaml")
    whole = python.emit(model, numba=True)
    monkeypatch.setattr(python, "SPLIT", 7)
    cut = python.emit(model, numba=True)
    assert "for _r in range(" not in whole and "_rhs_T0 = numpy.array(" in cut
    kernel = cut[cut.index("def _rhs(") :]
    assert kernel.count("\n") < whole[whole.index("def _rhs(") :].count("\n")
    monkeypatch.setitem(sys.modules, "numba", fake_numba())
    a = load_module(whole, tmp_path / "whole.py")
    b = load_module(cut, tmp_path / "cut.py")
    for y in states(n):
        assert np.array_equal(a.rhs(0.0, y), b.rhs(0.0, y))
        mass, force, _ = reference(y, dict(a.PARAMETERS))
        assert np.allclose(b.rhs(0.0, y)[n:], np.linalg.solve(mass, force), rtol=1e-9)


def test_codegen_numba_loops_compute_the_same(monkeypatch: pytest.MonkeyPatch) -> None:
    """The simulate backend's `_accel` and `_hamilton`, as loops over tables, give what the straight-line ones give."""
    n = 4
    model = model_of(chain_yaml(n), "chain_4.yaml")

    def run(source: str) -> tuple[np.ndarray, np.ndarray]:
        def lu_solve(a: np.ndarray, x: np.ndarray) -> int:
            x[:] = np.linalg.solve(a, x)
            return 0

        namespace: dict[str, object] = {"_lu_solve": lu_solve}
        exec(compile(source, "<generated>", "exec"), namespace)
        y = np.array(states(n)[0])
        p = np.array([model.parameter_values()[name] for name in codegen.parameter_names(model)])
        x, a, out = np.empty(n), np.empty((n, n)), np.empty(2 * n)
        assert namespace["_accel"](0.0, y, p, x, a) == 0  # type: ignore[operator]
        assert namespace["_hamilton"](0.0, y, p, out, np.empty(n), np.empty((n, n))) == 0  # type: ignore[operator]
        return x.copy(), out.copy()

    whole = codegen.source(model, "numba")
    monkeypatch.setattr(python, "SPLIT", 5)
    cut = codegen.source(model, "numba")
    assert "for _r in range(" not in whole and "_accel_T0 = " in cut and "_hamilton_T0 = " in cut
    (x1, out1), (x2, out2) = run(whole), run(cut)
    assert np.array_equal(x1, x2) and np.array_equal(out1, out2)
    mass, force, _ = reference(states(n)[0], model.parameter_values())
    assert np.allclose(x1, np.linalg.solve(mass, force), rtol=1e-9)


@pytest.mark.parametrize("name", ["rolling_disk_pendulum_multiplier", "pendulum_multiplier", "kapitza_pendulum", "double_pendulum"])
def test_loops_keep_constraints_and_time_dependence(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Kept constraints (multipliers, Baumgarte's _alpha) and an explicit t survive `vectorize`, in
    both the simulate backend's `_accel`/`_hamilton` and `derive --numba`'s rhs (run as plain Python)."""
    model = model_from(ROOT / "systems" / f"{name}.yaml")
    n, k = model.n, len(model.constraints)
    y = np.linspace(0.3, 0.9, 2 * n)
    values = model.parameter_values()
    p = np.array([2.0 if key == "_alpha" else values.get(key, 1.3) for key in codegen.parameter_names(model)])

    def lu_solve(a: np.ndarray, x: np.ndarray) -> int:
        x[:] = np.linalg.solve(a, x)
        return 0

    def run(limit: int) -> tuple[np.ndarray, np.ndarray]:
        monkeypatch.setattr(python, "SPLIT", limit)
        namespace: dict[str, object] = {"_lu_solve": lu_solve}
        exec(compile(codegen.source(model, "numba"), "<generated>", "exec"), namespace)
        x, a = np.empty(n + k), np.empty((n + k, n + k))
        namespace["_accel"](0.7, y, p, x, a)  # type: ignore[operator]
        emitted: dict[str, object] = {}
        exec(compile(python.emit(model, numba=True), "<emitted>", "exec"), emitted)
        parameters = {**emitted["PARAMETERS"], **{q.name: 1.3 for q in model.parameters if q.value is None}}  # type: ignore[dict-item]
        return x, np.asarray(emitted["rhs"](0.7, y, parameters))  # type: ignore[operator]

    monkeypatch.setitem(sys.modules, "numba", fake_numba())
    (x1, r1), (x2, r2) = run(1000), run(2)
    assert np.array_equal(x1, x2) and np.array_equal(r1, r2)


def test_numba_kernel_has_one_loop_body_per_shape_whatever_the_size(monkeypatch: pytest.MonkeyPatch) -> None:
    """The vectorized `--numba` kernel writes each statement shape once (one loop over its table) and
    walks the runs of the levels through a dispatch table (`_rhs_R`): its size does not grow with N,
    so numba's compile time does not either (one loop per level and shape grew with N: 52 loops at
    N = 12, 105 at N = 20)."""
    monkeypatch.setattr(python, "SPLIT", 5)
    kernels = {}
    for n in (6, 12, 20):
        source = python.emit(model_of(chain_yaml(n), f"chain_{n}.yaml"), numba=True)
        kernels[n] = source[source.index("def _rhs(") :]
        loops = re.findall(r"for _r in range\(_rhs_R\[_k, 1\], _rhs_R\[_k, 2\]\):\n\s+(.*)", kernels[n])
        tables = [re.findall(r"_rhs_T\d+", line) for line in loops]
        assert all(len(set(names)) == 1 for names in tables) and len({names[0] for names in tables}) == len(loops)
    assert kernels[20].count("\n") == kernels[12].count("\n") and kernels[20].count("for _r in range(") <= 20


def test_numba_lu_solve_agrees_with_numpy_and_refuses_a_singular_matrix() -> None:
    """`derive --numba`'s `_lu_solve` (in place of numpy.linalg.solve, whose LAPACK binding takes
    numba seconds to compile) pivots, agrees with numpy, and raises ZeroDivisionError on a singular
    matrix as the plain module's `_solve` does."""
    namespace: dict[str, object] = {"numba": fake_numba()}
    exec(compile(python.LU_SOLVE, "<lu>", "exec"), namespace)
    solve = namespace["_lu_solve"]
    rng = np.random.default_rng(5)
    for n in (2, 5, 12):
        a, b = rng.normal(size=(n, n)), rng.normal(size=n)
        a[0, 0] = 0.0  # needs a row exchange
        expected = np.linalg.solve(a, b)
        assert np.allclose(solve(a.copy(), b.copy()), expected, rtol=1e-10, atol=1e-12)  # type: ignore[operator]
    saddle = np.array([[2.0, 0.0, -1.0], [0.0, 3.0, -1.0], [1.0, 1.0, 0.0]])  # [M, -A^T; A, 0] of a kept constraint
    assert np.allclose(solve(saddle.copy(), np.array([1.0, 2.0, 0.5])), np.linalg.solve(saddle, [1.0, 2.0, 0.5]))  # type: ignore[operator]
    with pytest.raises(ZeroDivisionError, match="singular"):
        solve(np.array([[1.0, 2.0], [2.0, 4.0]]), np.array([1.0, 1.0]))  # type: ignore[operator]
