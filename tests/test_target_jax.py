"""The JAX target in JAX itself (64-bit mode): rhs, M, F and the energy agree with the Python module at
seeded random states for every bundled system; jax.jit and jax.vmap over 1000 states give what a loop
gives; jax.grad of a state after a few RK4 steps with respect to a parameter agrees with central finite
differences; hostile titles, file names and names stay data."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import os
import random
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from lagrange_cli.emit import jax as jax_target
from lagrange_cli.emit import python
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

from .conftest import ROOT, SYSTEMS
from .helpers import load_module, model_from, model_of, random_point
from .test_codegen_safety import HOSTILE, PENDULUM, ROD

jax = pytest.importorskip("jax")
jax.config.update("jax_enable_x64", True)
jnp = jax.numpy

HOSTILE_NAMES = sorted((ROOT / "tests" / "hostile").glob("name_*.yaml"))


def modules(model: Model, folder: Path) -> tuple[ModuleType, ModuleType]:
    """The Python module and the JAX module of `model`."""
    return load_module(python.emit(model), folder / "reference.py"), load_module(jax_target.emit(model), folder / "target.py")


def call_python(function: Callable[..., Any], t: float, *args: Any, u: Any = None) -> Any:
    """Call a Python-module function, which takes `t` only when it depends on time (and `u` only when it depends on an input)."""
    given = {"u": u} if u is not None and "u" in inspect.signature(function).parameters else {}
    return function(t, *args, **given) if "t" in inspect.signature(function).parameters else function(*args, **given)


def with_u(function: Callable[..., Any], *args: Any, u: Any = None) -> Any:
    """Call a generated function with `u` when it takes inputs (and `u` is given)."""
    return function(*args, u=u) if u is not None and "u" in inspect.signature(function).parameters else function(*args)


def random_inputs(model: Model, seed: int) -> dict[str, float] | None:
    """Random values for the model's inputs (None without inputs)."""
    rng = random.Random(1000 + seed)
    return {i.name: rng.uniform(-2.0, 2.0) for i in model.inputs} or None


@pytest.mark.parametrize("path", SYSTEMS, ids=lambda p: p.stem)
def test_every_bundled_system_agrees_with_the_python_module(path: Path, tmp_path: Path) -> None:
    model = model_from(path)
    try:
        python.emit(model)
    except DerivationError:
        with pytest.raises(DerivationError):
            jax_target.emit(model)
        return
    reference, target = modules(model, tmp_path)
    assert target.COORDINATES == reference.COORDINATES and target.PARAMETERS == reference.PARAMETERS
    assert tuple(p.name for p in model.parameters) == target.PARAMETER_NAMES and (model.n, len(model.parameters)) == (target.NQ, target.NP)
    n = model.n
    for seed in range(3):
        point = random_point(model, seed)
        p = {parameter.name: point[parameter.symbol] for parameter in model.parameters}
        y = [point[s] for s in (*model.q, *model.qd)]
        t = point[model.t]
        u = random_inputs(model, seed)
        expected = np.asarray(with_u(reference.rhs, t, y, p, u=u), dtype=float)
        got = with_u(target.rhs, t, jnp.asarray(y), p, u=u)
        assert got.dtype == jnp.float64 and got.shape == (2 * n,)
        np.testing.assert_allclose(np.asarray(got), expected, rtol=1e-10, atol=1e-12)
        vector = target.default_parameters() if all(v.value is not None for v in model.parameters) else None
        if vector is not None and all(p[name] == value for name, value in target.PARAMETERS.items()):
            np.testing.assert_allclose(np.asarray(with_u(target.rhs, t, y, vector, u=u)), expected, rtol=1e-10, atol=1e-12)
        q, qd = y[:n], y[n:]
        np.testing.assert_allclose(np.asarray(with_u(target.mass_matrix, t, q, p, u=u)), np.asarray(call_python(reference.mass_matrix, t, q, p, u=u), dtype=float), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(np.asarray(with_u(target.forcing, t, q, qd, p, u=u)), np.asarray(call_python(reference.forcing, t, q, qd, p, u=u), dtype=float), rtol=1e-10, atol=1e-12)
        assert float(with_u(target.energy, t, q, qd, p, u=u)) == pytest.approx(call_python(reference.energy, t, q, qd, p, u=u), rel=1e-10, abs=1e-12)
        if model.outputs:
            np.testing.assert_allclose(np.asarray(with_u(target.outputs, t, y, p, u=u)), np.asarray(call_python(reference.outputs, t, y, p, u=u), dtype=float), rtol=1e-10, atol=1e-12)
        if model.constraints:
            np.testing.assert_allclose(np.asarray(target.multipliers(t, y, p)), np.asarray(reference.multipliers(t, y, p), dtype=float), rtol=1e-9, atol=1e-12)
            np.testing.assert_allclose(np.asarray(target.constraint_residuals(t, q, qd, p)), np.asarray(reference.constraint_residuals(q, qd, p), dtype=float), rtol=1e-10, atol=1e-12)


def test_p_is_optional_a_dict_by_name_or_an_array(tmp_path: Path) -> None:
    model = model_from(ROOT / "systems" / "double_pendulum.yaml")
    reference, target = modules(model, tmp_path)
    y = [0.3, -0.2, 0.1, 0.4]
    expected = np.asarray(reference.rhs(0.0, y), dtype=float)
    for p in (None, dict(target.PARAMETERS), {}, target.default_parameters(), list(target.PARAMETERS.values())):
        np.testing.assert_allclose(np.asarray(target.rhs(0.0, y, p)), expected, rtol=1e-12)
    changed = {**reference.PARAMETERS, "g": 3.5}
    np.testing.assert_allclose(np.asarray(target.rhs(0.0, y, {"g": 3.5})), np.asarray(reference.rhs(0.0, y, changed), dtype=float), rtol=1e-12)
    with pytest.raises(KeyError):
        load_module(jax_target.emit(model_of("coordinates: [x]\nparameters: [k]\nkinetic: x_dot**2/2\npotential: k*x**2\n")), tmp_path / "nodefault.py").rhs(0.0, [1.0, 0.0])


INPUT_SYSTEMS = ["cart_pole_state_space", "quadrotor", "arm_3dof"]
"""The bundled systems with inputs (and outputs)."""


@pytest.mark.parametrize("stem", INPUT_SYSTEMS)
def test_inputs_are_u_after_p_as_none_a_dict_or_an_array(stem: str, tmp_path: Path) -> None:
    """u after p on every function that depends on an input, as the Python module's `u=INPUTS`: at random
    states and random inputs the JAX module agrees with it for u a dict, a partial dict, an array and None
    (the defaults); jax.jit and jax.vmap over inputs, and jax.grad of rhs with respect to u agrees with
    central differences of the Python module."""
    model = model_from(ROOT / "systems" / f"{stem}.yaml")
    reference, target = modules(model, tmp_path)
    names = [i.name for i in model.inputs]
    assert tuple(names) == target.INPUT_NAMES and target.INPUTS == reference.INPUTS and len(names) == target.NU
    np.testing.assert_allclose(np.asarray(target.default_inputs()), [reference.INPUTS[k] for k in names])
    assert "u" in inspect.signature(target.rhs).parameters and "u" not in inspect.signature(target.mass_matrix).parameters
    assert list(inspect.signature(target.outputs).parameters) == ["t", "y", "p", "u"]
    n = model.n
    for seed in range(2):
        point = random_point(model, seed)
        p = {parameter.name: point[parameter.symbol] for parameter in model.parameters}
        y = [point[s] for s in (*model.q, *model.qd)]
        t = point[model.t]
        u = random_inputs(model, seed)
        assert u is not None
        expected = np.asarray(reference.rhs(t, y, p, u), dtype=float)
        assert not np.allclose(expected, np.asarray(reference.rhs(t, y, p), dtype=float))  # the inputs matter
        for given in (u, [u[k] for k in names], jnp.asarray([u[k] for k in names])):
            np.testing.assert_allclose(np.asarray(target.rhs(t, y, p, given)), expected, rtol=1e-10, atol=1e-12)
            np.testing.assert_allclose(np.asarray(target.outputs(t, y, p, given)), np.asarray(reference.outputs(t, y, p, u), dtype=float), rtol=1e-10, atol=1e-12)
        partial = {names[0]: u[names[0]]}
        np.testing.assert_allclose(np.asarray(target.rhs(t, y, p, partial)), np.asarray(reference.rhs(t, y, p, {**reference.INPUTS, **partial}), dtype=float), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(np.asarray(target.rhs(t, y, p)), np.asarray(reference.rhs(t, y, p), dtype=float), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(np.asarray(target.forcing(t, y[:n], y[n:], p, u)), np.asarray(call_python(reference.forcing, t, y[:n], y[n:], p, u=u), dtype=float), rtol=1e-10, atol=1e-12)
    # jit and vmap over a batch of inputs; grad with respect to u
    rng = np.random.default_rng(7)
    batch = rng.uniform(-2.0, 2.0, size=(50, len(names)))
    y0 = jnp.asarray([0.3] * n + [0.1] * n)
    fast = jax.jit(jax.vmap(lambda uu: target.rhs(0.0, y0, None, uu)))(jnp.asarray(batch))
    loop = np.asarray([reference.rhs(0.0, y0.tolist(), reference.PARAMETERS, dict(zip(names, row.tolist(), strict=True))) for row in batch], dtype=float)
    np.testing.assert_allclose(np.asarray(fast), loop, rtol=1e-10, atol=1e-12)
    u0 = jnp.asarray(batch[0])
    jacobian = np.asarray(jax.jacobian(lambda uu: target.rhs(0.0, y0, None, uu))(u0))
    step = 1e-6
    for k, name in enumerate(names):
        plus = dict(zip(names, batch[0].tolist(), strict=True))
        minus = dict(plus)
        plus[name] += step
        minus[name] -= step
        difference = (np.asarray(reference.rhs(0.0, y0.tolist(), reference.PARAMETERS, plus), dtype=float) - np.asarray(reference.rhs(0.0, y0.tolist(), reference.PARAMETERS, minus), dtype=float)) / (
            2 * step
        )
        np.testing.assert_allclose(jacobian[:, k], difference, rtol=1e-6, atol=1e-7)


def test_a_file_without_inputs_reserves_no_input_names() -> None:
    """`u`, `INPUTS` and `outputs` stay the user's names in a file without inputs or outputs (its module is what it was)."""
    code = jax_target.emit(model_of("coordinates: [u]\nparameters: {INPUTS: 2.0}\nkinetic: u_dot**2/2\npotential: INPUTS*u**2/2\n"))
    assert "u = jnp.asarray" not in code and "INPUT_NAMES" not in code and "_inputs" not in code and "u, = q[0]," in code


# -- jit, vmap, grad ------------------------------------------------------------------------------------

TRANSFORMED = ["double_pendulum", "pendulum_multiplier", "rotating_hoop_bead", "chain_3"]


@pytest.mark.parametrize("stem", TRANSFORMED)
def test_jit_and_vmap_over_1000_states_equal_the_loop(stem: str, tmp_path: Path) -> None:
    model = model_from(ROOT / "systems" / f"{stem}.yaml")
    reference, target = modules(model, tmp_path)
    rng = np.random.default_rng(7)
    n = model.n
    states = np.concatenate([rng.uniform(0.2, 1.3, (1000, n)), rng.uniform(-1.0, 1.0, (1000, n))], axis=1)
    t = 0.7
    rhs = jax.jit(target.rhs)
    batched = np.asarray(jax.jit(jax.vmap(target.rhs, in_axes=(None, 0, None)))(t, jnp.asarray(states), None))
    assert batched.shape == (1000, 2 * n)
    loop = np.array([reference.rhs(t, list(state)) for state in states], dtype=float)
    np.testing.assert_allclose(batched, loop, rtol=1e-10, atol=1e-12)
    jitted = np.array([np.asarray(rhs(t, jnp.asarray(state))) for state in states[:50]])
    np.testing.assert_allclose(jitted, batched[:50], rtol=1e-13, atol=1e-14)
    # vmap over parameter vectors too (a batch of systems)
    vector = target.default_parameters()
    parameters = jnp.stack([vector * (1.0 + 0.1 * i) for i in range(5)])
    over_p = np.asarray(jax.vmap(target.rhs, in_axes=(None, None, 0))(t, jnp.asarray(states[0]), parameters))
    for i in range(5):
        p = dict(zip(target.PARAMETER_NAMES, np.asarray(parameters[i]).tolist(), strict=True))
        np.testing.assert_allclose(over_p[i], np.asarray(reference.rhs(t, list(states[0]), p), dtype=float), rtol=1e-10, atol=1e-12)


def rk4(rhs: Callable[..., Any], y: Any, p: Any, steps: int, h: float) -> Any:
    """`steps` classical RK4 steps from t = 0, as one loop that JAX compiles once (`lax.fori_loop`)."""

    def step(i: Any, y: Any) -> Any:
        t = i * h
        k1 = rhs(t, y, p)
        k2 = rhs(t + h / 2, y + h / 2 * k1, p)
        k3 = rhs(t + h / 2, y + h / 2 * k2, p)
        k4 = rhs(t + h, y + h * k3, p)
        return y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    return jax.lax.fori_loop(0, steps, step, y)


@pytest.mark.parametrize(("stem", "parameter", "component"), [("double_pendulum", "g", 1), ("pendulum_multiplier", "g", 0), ("rotating_hoop_bead", "omega", 0)])
def test_grad_of_a_final_state_agrees_with_finite_differences(stem: str, parameter: str, component: int, tmp_path: Path) -> None:
    model = model_from(ROOT / "systems" / f"{stem}.yaml")
    target = load_module(jax_target.emit(model), tmp_path / "target.py")
    start = jnp.asarray([0.9, 0.5, 0.2, -0.1] if model.n == 2 else [0.9, 0.3])
    if stem == "pendulum_multiplier":  # on the circle x^2 + y^2 = l^2, moving along it
        start = jnp.asarray([np.sin(0.9), -np.cos(0.9), 0.3 * np.cos(0.9), 0.3 * np.sin(0.9)])
    index = target.PARAMETER_NAMES.index(parameter)

    def final(value: Any) -> Any:
        p = target.default_parameters().at[index].set(value)
        return rk4(target.rhs, start, p, steps=20, h=0.01)[component]

    def by_name(value: Any) -> Any:  # the derivative of one rhs through a dict of parameters
        return target.rhs(0.1, start, {parameter: value})[-1]

    def by_index(value: Any) -> Any:
        return target.rhs(0.1, start, target.default_parameters().at[index].set(value))[-1]

    value = float(target.PARAMETERS[parameter])
    step = 1e-5 * value

    @jax.jit  # one compilation for everything
    def results(value: Any) -> Any:
        return jax.grad(final)(value), final(value + step), final(value - step), jax.grad(by_name)(value), jax.grad(by_index)(value)

    gradient, above, below, named, indexed = (float(x) for x in results(value))
    assert abs(gradient) > 1e-4
    assert gradient == pytest.approx((above - below) / (2 * step), rel=1e-6)
    assert named == pytest.approx(indexed, rel=1e-12) and abs(named) > 1e-6


# -- file text is data, names never meet generated names ------------------------------------------------


def hostile(text: str, as_title: bool) -> Model:
    model = model_of(PENDULUM)
    return dataclasses.replace(model, title=text) if as_title else dataclasses.replace(model, source=f"/some/dir/{text}.yaml")


@pytest.mark.parametrize("as_title", [True, False], ids=["title", "file-name"])
@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_file_text_in_the_jax_module_is_data(text: str, as_title: bool, tmp_path: Path) -> None:
    code = jax_target.emit(hostile(text, as_title))
    ast.parse(code)
    assert all(c == "\n" or " " <= c <= "~" for c in code)
    module = load_module(code, tmp_path / "module.py")
    assert not (tmp_path / "EXECUTED").exists()
    assert text in module.__doc__ if as_title else Path(f"/some/dir/{text}.yaml").name in module.__doc__
    assert float(module.rhs(0.0, [0.3, 0.0])[1]) == pytest.approx(-9.81 / 2.0 * np.sin(0.3))


def test_names_like_the_generated_ones_agree_with_plain_names(tmp_path: Path) -> None:
    """Coordinates and parameters called jnp, jax, lax, p, y, rhs, PARAMETERS, a constraint with multiplier lambda_rhs."""
    renamed = "coordinates: [jnp, lax]\nparameters: {p: 1.5, jax: 2.0, PARAMETERS: 9.81}\ngravity: [0, -PARAMETERS]\nparticles:\n  bob: {mass: p, position: [jnp, lax]}\n"
    renamed += "constraints:\n  rhs: jnp**2 + lax**2 = jax**2\n"
    plain = load_module(jax_target.emit(model_of(ROD)), tmp_path / "plain.py")
    shadowed = load_module(jax_target.emit(model_of(renamed)), tmp_path / "shadowed.py")
    assert shadowed.PARAMETER_NAMES == ("p", "jax", "PARAMETERS")
    y = jnp.asarray([1.2, -1.6, 0.3, 0.225])
    np.testing.assert_allclose(np.asarray(shadowed.accelerations(0.0, y)), np.asarray(plain.accelerations(0.0, y)), rtol=1e-14)
    np.testing.assert_allclose(np.asarray(jax.jit(shadowed.rhs)(0.0, y)), np.asarray(plain.rhs(0.0, y)), rtol=1e-14)


@pytest.mark.parametrize("path", HOSTILE_NAMES, ids=lambda p: p.stem)
def test_hostile_names_from_files_agree_with_the_python_module(path: Path, tmp_path: Path) -> None:
    try:
        model = model_from(path)
        python.emit(model)
    except Exception:  # refused before there is code to write
        return
    reference, target = modules(model, tmp_path)
    rng = random.Random(3)
    y = [rng.uniform(0.2, 1.0) for _ in range(2 * model.n)]
    np.testing.assert_allclose(np.asarray(target.rhs(0.4, y)), np.asarray(reference.rhs(0.4, y), dtype=float), rtol=1e-10, atol=1e-12)


def test_the_signature_is_the_target_contract() -> None:
    signature = inspect.signature(jax_target.emit)
    assert list(signature.parameters) == ["model", "name"] and signature.parameters["name"].kind is inspect.Parameter.KEYWORD_ONLY


def test_the_readme_example_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """The README's JAX example, with the module it names written by this target."""
    readme = (ROOT / "README.md").read_text()
    example = readme.split("### JAX", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    (tmp_path / "eom.py").write_text(jax_target.emit(model_from(ROOT / "systems" / "double_pendulum.yaml")))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "eom", raising=False)
    namespace: dict[str, Any] = {}
    exec(compile(example, "README.md", "exec"), namespace)  # the project's own README
    assert namespace["rates"].shape == (10_000, 4)
    assert np.isfinite(float(capsys.readouterr().out))
    sys.modules.pop("eom", None)


SPLIT_PROBE = """
import jax, jax.numpy as jnp
jax.config.update("jax_enable_x64", True)
def work(y):  # enough arithmetic per state that XLA splits the loop when it has threads
    a, b = y[0], y[1]
    for _ in range(8):
        a, b = a * b + 1 / (1 + a * a), b - a / (2 + b * b)
    return a
compiled = jax.jit(jax.vmap(work)).lower(jnp.ones((10_000, 2))).compile().as_text()
print(compiled.count("outer_dimension_partitions"), len(os.sched_getaffinity(0)))
"""


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="os.sched_setaffinity (Linux)")
def test_the_readme_one_thread_recipe_stops_xla_splitting_loops() -> None:
    """The README's second JAX snippet (XLA's CPU client created while the process sees one CPU, then the CPUs
    given back) compiles a batched loop unsplit (no `outer_dimension_partitions`) and leaves the process all its
    CPUs; without it, on a machine with 2 or more CPUs, XLA splits the same loop."""
    readme = (ROOT / "README.md").read_text()
    recipe = readme.split("### JAX", 1)[1].split("```python\n", 2)[2].split("```", 1)[0]
    assert "sched_setaffinity" in recipe
    cpus = len(os.sched_getaffinity(0))
    for code, split in ((recipe + SPLIT_PROBE, False), ("import os" + SPLIT_PROBE, cpus > 1)):
        run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
        partitions, seen = map(int, run.stdout.split())
        assert seen == cpus
        assert (partitions > 0) == split, run.stdout


# -- the unrolled solve (small systems) and jnp.linalg.solve (large ones) ---------------------------------


@pytest.mark.parametrize("stem", ["double_pendulum", "pendulum_multiplier", "rolling_disk_pendulum_multiplier", "chain_3", "kepler"])
def test_the_unrolled_solve_and_jnp_linalg_solve_agree(stem: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Small systems are solved by unrolled L D L^T code (Schur complement for kept constraints), with no
    `jnp.linalg.solve` left; above `UNROLLED_MAX` the module calls `jnp.linalg.solve`; both give the Python module's values."""
    model = model_from(ROOT / "systems" / f"{stem}.yaml")
    unrolled_code = jax_target.emit(model)
    assert "jnp.linalg" not in unrolled_code
    monkeypatch.setattr(jax_target, "UNROLLED_MAX", 0)
    solved_code = jax_target.emit(model)
    assert "jnp.linalg.solve" in solved_code
    reference = load_module(python.emit(model), tmp_path / "reference.py")
    unrolled, solved = load_module(unrolled_code, tmp_path / "unrolled.py"), load_module(solved_code, tmp_path / "solved.py")
    rng = np.random.default_rng(5)
    states = jnp.asarray(rng.uniform(0.2, 1.2, (64, 2 * model.n)))
    fast = np.asarray(jax.vmap(unrolled.rhs, in_axes=(None, 0))(0.3, states))
    slow = np.asarray(jax.vmap(solved.rhs, in_axes=(None, 0))(0.3, states))
    loop = np.array([reference.rhs(0.3, list(np.asarray(state))) for state in states], dtype=float)
    np.testing.assert_allclose(fast, loop, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(slow, loop, rtol=1e-10, atol=1e-12)
    if model.constraints:
        np.testing.assert_allclose(np.asarray(unrolled.multipliers(0.3, states[0])), np.asarray(solved.multipliers(0.3, states[0])), rtol=1e-10, atol=1e-12)


def test_a_diagonal_mass_matrix_costs_one_division_per_coordinate() -> None:
    """Structural zeros of M are skipped: Kepler in polar coordinates (M diagonal) has no elimination step."""
    code = jax_target.emit(model_from(ROOT / "systems" / "kepler.yaml"))
    solve = code.split("def rhs", 1)[1]
    assert solve.count(" / _u") == 2 and " * _u" not in solve


def xla_trig_calls(module: ModuleType, n: int) -> int:
    """The sine and cosine operations in XLA's optimized CPU program for `jax.jit(jax.vmap(rhs))` over 100 states."""
    states = jnp.zeros((100, 2 * n))
    text = jax.jit(jax.vmap(module.rhs, in_axes=(None, 0))).lower(0.0, states).compile().as_text()
    return text.count(" sine(") + text.count(" cosine(")


def test_xla_computes_each_sine_and_cosine_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Sines and cosines go through `_kept`, so XLA's CPU fusion computes each once under jit of vmap (a count
    in the optimized program, not a timing): with `jnp.sin` and `jnp.cos` (FAST_TRIG off) the 3-link chain's
    rhs has 3 sines and 3 cosines, where without `_kept` XLA recomputes them in each fused loop that reads
    them; the values are the same. With `_sincos` (the default) XLA has no sine or cosine operation at all."""
    model = model_from(ROOT / "systems" / "chain_3.yaml")
    assert xla_trig_calls(load_module(jax_target.emit(model), tmp_path / "fast.py"), model.n) == 0, "_sincos: arithmetic only"
    monkeypatch.setattr(jax_target, "FAST_TRIG", False)
    kept = load_module(jax_target.emit(model), tmp_path / "kept.py")
    assert kept.rhs.__code__.co_names.count("_kept") and xla_trig_calls(kept, model.n) == 2 * model.n
    monkeypatch.setattr(jax_target, "KEEP", False)
    plain_code = jax_target.emit(model)
    assert "_kept" not in plain_code
    plain = load_module(plain_code, tmp_path / "plain.py")
    assert xla_trig_calls(plain, model.n) > 2 * 2 * model.n
    states = jnp.asarray(np.random.default_rng(3).uniform(-2.0, 2.0, (50, 2 * model.n)))
    np.testing.assert_allclose(np.asarray(jax.vmap(kept.rhs, in_axes=(None, 0))(0.0, states)), np.asarray(jax.vmap(plain.rhs, in_axes=(None, 0))(0.0, states)), rtol=1e-14, atol=1e-14)


def test_kept_is_the_identity_and_so_is_its_derivative(tmp_path: Path) -> None:
    """`_kept(v)` = v / (v * 0 + 1) is v bit for bit (signed zero, tiny, huge; XLA on CPU flushes subnormals to
    zero in every operation, so none is tried) and its derivative is 1; a non-finite value gives NaN (as sin
    and cos of a non-finite angle do)."""
    module = load_module(jax_target.emit(model_from(ROOT / "systems" / "chain_3.yaml")), tmp_path / "target.py")
    values = np.array([0.0, -0.0, 2.3e-308, -1e-300, 1.0, -0.3, 1e308, -1.7976931348623157e308, np.pi])
    out = np.asarray(jax.jit(jax.vmap(module._kept))(jnp.asarray(values)))
    assert out.tobytes() == values.tobytes()
    assert all(float(jax.grad(module._kept)(x)) == 1.0 for x in (0.0, -0.7, 1e300))
    assert np.isnan(np.asarray(module._kept(jnp.asarray([np.inf, np.nan])))).all()


def test_two_unknowns_store_nothing_and_three_do(tmp_path: Path) -> None:
    """`KEEP_MIN`: the double pendulum's module (n = 2) has no `_kept` (XLA's two fused loops recompute less than
    seven would store), the 3-link chain's has; both agree with the Python module (the other tests)."""
    assert jax_target.KEEP_MIN == 3
    assert "_kept" not in jax_target.emit(model_from(ROOT / "systems" / "double_pendulum.yaml"))
    assert "_kept(" in jax_target.emit(model_from(ROOT / "systems" / "chain_3.yaml")).split("def rhs", 1)[1]


def test_rhs_in_chunks_is_the_plain_rhs_under_every_transformation(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`_in_chunks` (here from n + k = 3, chunks of 7 states): jax.vmap over 2 * 7 + 3 states runs a loop over
    chunks (a `while` in XLA's program, counted, not timed) with the plain rhs's values, and every other use
    (t or p batched, vmap of vmap, grad, vmap of grad, grad of vmap, jacfwd) gives the plain rhs's values too."""
    monkeypatch.setattr(jax_target, "CHUNKED_MIN", 3)
    monkeypatch.setattr(jax_target, "CHUNK", 7)
    model = model_from(ROOT / "systems" / "chain_3.yaml")
    module = load_module(jax_target.emit(model), tmp_path / "chunked.py")
    rhs, plain, n = module.rhs, module._rhs, model.n
    y = jnp.asarray(np.random.default_rng(5).uniform(-1.0, 1.0, (17, 2 * n)))
    p = module.default_parameters()

    def same(a: Any, b: Any) -> None:
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-13, atol=1e-13)

    batched = jax.jit(jax.vmap(rhs, in_axes=(None, 0, None)))
    assert " while(" in batched.lower(0.3, y, p).compile().as_text()
    assert " while(" not in jax.jit(jax.vmap(plain, in_axes=(None, 0, None))).lower(0.3, y, p).compile().as_text()
    same(batched(0.3, y, p), jax.vmap(plain, in_axes=(None, 0, None))(0.3, y, p))
    same(jax.vmap(rhs, in_axes=(None, 0))(0.3, y), jax.vmap(plain, in_axes=(None, 0))(0.3, y))
    same(jax.vmap(rhs, in_axes=(None, 0, None))(0.3, y, {"g": 3.0}), jax.vmap(plain, in_axes=(None, 0, None))(0.3, y, {"g": 3.0}))
    ts = jnp.linspace(0.0, 1.0, 17)
    same(jax.vmap(rhs, in_axes=(0, 0, None))(ts, y, p), jax.vmap(plain, in_axes=(0, 0, None))(ts, y, p))
    ps = jnp.stack([p * (1.0 + 0.01 * i) for i in range(17)])
    same(jax.vmap(rhs, in_axes=(None, 0, 0))(0.3, y, ps), jax.vmap(plain, in_axes=(None, 0, 0))(0.3, y, ps))
    nested = jnp.concatenate([y, y])[:32].reshape(2, 16, 2 * n)
    same(jax.vmap(jax.vmap(rhs, in_axes=(None, 0, None)), in_axes=(None, 0, None))(0.3, nested, p), jax.vmap(jax.vmap(plain, in_axes=(None, 0, None)), in_axes=(None, 0, None))(0.3, nested, p))
    same(jax.grad(lambda q: rhs(0.3, y[0], q)[n])(p), jax.grad(lambda q: plain(0.3, y[0], q)[n])(p))
    same(jax.vmap(jax.grad(lambda s: rhs(0.3, s, p)[n]))(y), jax.vmap(jax.grad(lambda s: plain(0.3, s, p)[n]))(y))
    same(jax.grad(lambda q: jax.vmap(rhs, in_axes=(None, 0, None))(0.3, y, q).sum())(p), jax.grad(lambda q: jax.vmap(plain, in_axes=(None, 0, None))(0.3, y, q).sum())(p))
    same(jax.jacfwd(lambda s: rhs(0.3, s, p))(y[0]), jax.jacfwd(lambda s: plain(0.3, s, p))(y[0]))
    reference = load_module(python.emit(model), tmp_path / "reference.py")
    same(batched(0.3, y, None), np.array([reference.rhs(0.3, list(map(float, s))) for s in np.asarray(y)]))


def test_sincos_is_sin_and_cos_to_1e_14_below_1e15_and_nan_beyond(tmp_path: Path) -> None:
    """`_sincos` against numpy (libm) at 2000 random angles per decade up to 1e15, the quadrant boundaries and
    signed zero: within 2.3e-16 below 1e12 and 1e-14 below 1e15; NaN at and beyond 1e15 and for NaN or inf;
    its derivative (jax.grad, jit, vmap, second order) is (cos, -sin); float32 falls back to jnp.sin/jnp.cos."""
    module = load_module(jax_target.emit(model_from(ROOT / "systems" / "double_pendulum.yaml")), tmp_path / "target.py")
    sincos = jax.jit(jax.vmap(module._sincos))
    rng = np.random.default_rng(11)
    edges = np.array([0.0, -0.0, np.pi / 4, -np.pi / 4, np.pi / 2, np.pi, 3 * np.pi / 4, 1e-300, 1e6 * np.pi / 2])
    for decade in range(-3, 16):
        x = np.concatenate([rng.uniform(-1.0, 1.0, 2000) * 10.0**decade, edges])
        s, c = (np.asarray(v) for v in sincos(jnp.asarray(x)))
        bound = 2.3e-16 if decade < 12 else 1e-14
        assert np.max(np.abs(s - np.sin(x))) <= bound and np.max(np.abs(c - np.cos(x))) <= bound, decade
    assert np.signbit(np.asarray(sincos(jnp.asarray([-0.0]))[0]))[0]
    far = np.asarray(sincos(jnp.asarray([1e15, -3e20, np.inf, np.nan, 1e300])))
    assert np.isnan(far).all()
    for x in (0.3, -2.0, 1e5 + 0.1):
        assert float(jax.grad(lambda v: module._sincos(v)[0])(x)) == float(module._sincos(x)[1])
        assert float(jax.grad(lambda v: module._sincos(v)[1])(x)) == -float(module._sincos(x)[0])
        assert float(jax.grad(jax.grad(lambda v: module._sincos(v)[0]))(x)) == -float(module._sincos(x)[0])
    x32 = jnp.asarray([0.5, 1e20], dtype=jnp.float32)
    assert all(np.array_equal(np.asarray(a), np.asarray(b)) for a, b in zip(module._sincos(x32), (jnp.sin(x32), jnp.cos(x32)), strict=True))


# -- --form hamilton ------------------------------------------------------------------------------------


HAMILTON_SYSTEMS = [
    *("double_pendulum", "kepler", "chain_3", "charged_particle_magnetic", "damped_oscillator_rayleigh", "kapitza_pendulum"),
    *("heavy_top", "rotating_hoop_bead", "cart_pole", "rolling_coin", "central_potential"),
    *INPUT_SYSTEMS,
]
"""A velocity-dependent b, dissipation, time dependence, a 3 x 3 M, and refusals (kept constraints, an
undefined function); tests/test_target_c.py and test_target_octave.py take every bundled system."""


@pytest.mark.parametrize("stem", HAMILTON_SYSTEMS)
def test_hamilton_agrees_with_the_python_hamilton_module_and_the_lagrange_form(stem: str, tmp_path: Path) -> None:
    """rhs, velocities and H agree with `--python --form hamilton` at random (q, p); and from a state (q, q_dot),
    p = momenta(q, q_dot) gives back q_dot, and p_dot is d/dt of momenta along the Lagrange form's motion."""
    from lagrange_cli.emit import hamiltonian
    from lagrange_cli.errors import LagrangeError

    model = model_from(ROOT / "systems" / f"{stem}.yaml")
    try:
        reference = load_module(hamiltonian.python(model), tmp_path / "reference.py")
    except LagrangeError:
        with pytest.raises(LagrangeError):
            jax_target.emit_hamilton(model)
        return
    target = load_module(jax_target.emit_hamilton(model), tmp_path / "target.py")
    lagrange = load_module(jax_target.emit(model), tmp_path / "lagrange.py")
    assert target.MOMENTA == reference.MOMENTA and target.COORDINATES == reference.COORDINATES
    n = model.n
    for seed in range(2):
        point = random_point(model, seed)
        p = {parameter.name: point[parameter.symbol] for parameter in model.parameters}
        t = point[model.t]
        u = random_inputs(model, seed)  # inputs: given values, u after p as in the Python module
        q, qd = [point[s] for s in model.q], [point[s] for s in model.qd]
        momenta = np.asarray(with_u(target.momenta, t, q, qd, p, u=u))
        np.testing.assert_allclose(momenta, np.asarray(with_u(reference.momenta, t, q, qd, p, u=u), dtype=float), rtol=1e-10, atol=1e-12)
        y = [*q, *momenta.tolist()]
        expected = np.asarray(with_u(reference.rhs, t, y, p, u=u), dtype=float)
        got = with_u(target.rhs, t, jnp.asarray(y), p, u=u)
        assert got.dtype == jnp.float64 and got.shape == (2 * n,)
        np.testing.assert_allclose(np.asarray(got), expected, rtol=1e-9, atol=1e-11)
        if u is not None:
            assert "u" in inspect.signature(target.rhs).parameters and not np.allclose(np.asarray(target.rhs(t, y, p)), expected)  # the inputs matter
        np.testing.assert_allclose(np.asarray(with_u(target.velocities, t, y, p, u=u)), qd, rtol=1e-9, atol=1e-11)
        assert float(with_u(target.hamiltonian, t, y, p, u=u)) == pytest.approx(with_u(reference.hamiltonian, t, y, p, u=u), rel=1e-9, abs=1e-11)
        assert float(with_u(target.hamiltonian, t, y, p, u=u)) == pytest.approx(float(with_u(lagrange.energy, t, q, qd, p, u=u)), rel=1e-9, abs=1e-11)
        # Hamilton's equations against the Lagrange form: p_dot = d/dt momenta(t, q(t), q_dot(t))
        qdd = np.asarray(with_u(lagrange.rhs, t, jnp.asarray([*q, *qd]), p, u=u))[n:]
        _, rate = jax.jvp(
            lambda tt, qq, vv, p=p, u=u: with_u(target.momenta, tt, qq, vv, p, u=u), (jnp.asarray(t), jnp.asarray(q), jnp.asarray(qd)), (jnp.asarray(1.0), jnp.asarray(qd), jnp.asarray(qdd))
        )
        np.testing.assert_allclose(np.asarray(got)[n:], np.asarray(rate), rtol=1e-8, atol=1e-10)


def test_hamilton_jit_vmap_and_grad(tmp_path: Path) -> None:
    """The Hamilton module is jax-transformable: jit(vmap(rhs)) equals a loop, and grad of H with respect to the
    momenta is q_dot (Hamilton's first equation, by automatic differentiation)."""
    model = model_from(ROOT / "systems" / "double_pendulum.yaml")
    target = load_module(jax_target.emit_hamilton(model), tmp_path / "target.py")
    states = jnp.asarray(np.random.default_rng(2).uniform(-1.0, 1.0, (200, 4)))
    batched = np.asarray(jax.jit(jax.vmap(target.rhs, in_axes=(None, 0)))(0.0, states))
    np.testing.assert_allclose(batched[:20], np.array([np.asarray(target.rhs(0.0, s)) for s in states[:20]]), rtol=1e-13, atol=1e-14)
    for state in states[:5]:
        grad = jax.grad(lambda y: target.hamiltonian(0.0, y))(state)
        np.testing.assert_allclose(np.asarray(grad[2:]), np.asarray(target.rhs(0.0, state)[:2]), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(-np.asarray(grad[:2]), np.asarray(target.rhs(0.0, state)[2:]), rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("as_title", [True, False], ids=["title", "file-name"])
@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_file_text_in_every_hamilton_target_is_data(text: str, as_title: bool, tmp_path: Path) -> None:
    """A hostile title or file name in `--form hamilton` of jax (imported: nothing runs), c, octave (printable
    comments that cannot end early) and json (a JSON string that round-trips)."""
    import json

    from lagrange_cli.emit import c, jsonmodel, octave

    model = hostile(text, as_title)
    code = jax_target.emit_hamilton(model)
    ast.parse(code)
    module = load_module(code, tmp_path / "module.py")
    assert not (tmp_path / "EXECUTED").exists()
    assert float(module.rhs(0.0, [0.3, 0.0])[3]) == pytest.approx(-9.81 * 2.0 * np.sin(0.3))  # p_dot = -m g l sin(theta), m = 1, l = 2
    header = c.emit_hamilton(model)
    assert all(ch == "\n" or " " <= ch <= "~" for ch in header)
    assert header.count("*/") == header.count("/*") and "??" not in header.split("#ifndef", 1)[0].replace("? ?", "")
    matlab = octave.emit_hamilton(model)
    assert all(ch == "\n" or " " <= ch <= "~" for ch in matlab)
    help_text = matlab.split("\n  if nargin < 3\n", 1)[0].splitlines()[1:]
    assert len(help_text) >= 5 and all(line.startswith("% ") for line in help_text)
    data = json.loads(jsonmodel.emit_hamilton(model))
    assert data["title"] == model.title and data["source"] == Path(model.source).name


def test_the_benchmark_measures_what_it_claims(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """benchmarks/jax_bench.py on 20 states of the 2-link general chain: it checks the vmap result against the
    Python loop (and would raise on a disagreement) and reports the three timings; no timing is asserted."""
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    import importlib.util

    found = importlib.util.spec_from_file_location("jax_bench", ROOT / "benchmarks" / "jax_bench.py")
    assert found and found.loader
    bench = importlib.util.module_from_spec(found)
    found.loader.exec_module(bench)
    import pendulum

    row = bench.bench("general_chain_2", pendulum.Chain("general", 2).yaml(), 20, tmp_path)
    assert row["n"] == 2 and all(len(row[key]) == 2 and min(row[key]) >= 0.0 for key in ("compile", "vmap", "loop"))
    monkeypatch.setattr(python, "emit", lambda model, **_: jax_target.emit(model).replace("return jnp.concatenate([y[2:], _x])", "return jnp.concatenate([y[2:], 2 * _x])"))
    with pytest.raises(AssertionError):
        bench.bench("wrong", pendulum.Chain("general", 2).yaml(), 20, tmp_path)


# -- _spd_solve (unconstrained systems from COLUMNS_MIN coordinates) ----------------------------------------------------


def test_spd_solve_is_the_unrolled_solve_under_every_transformation(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """From `COLUMNS_MIN` coordinates (no kept constraints) rhs solves by `_spd_solve` (column-at-a-time L D L^T, batch
    last under vmap, in custom_linear_solve): its values, vmap, jacrev, jacfwd, grad with respect to p and vmap of
    grad are those of the unrolled solve, and both give the Python module's values."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import pendulum

    model = model_of(pendulum.Chain("general", 4).yaml())
    monkeypatch.setattr(jax_target, "COLUMNS_MIN", 4)
    columns_code = jax_target.emit(model)
    assert "_spd_solve(" in columns_code.split("def rhs", 1)[1] and not re.search(r"\b_u\d", columns_code)
    monkeypatch.setattr(jax_target, "COLUMNS_MIN", 5)
    unrolled_code = jax_target.emit(model)
    assert "_spd_solve" not in unrolled_code
    columns, unrolled = load_module(columns_code, tmp_path / "columns.py"), load_module(unrolled_code, tmp_path / "unrolled.py")
    reference = load_module(python.emit(model), tmp_path / "reference.py")
    rng = np.random.default_rng(7)
    states = jnp.asarray(rng.uniform(-1.0, 1.0, (32, 2 * model.n)))
    batched = np.asarray(jax.jit(jax.vmap(columns.rhs, in_axes=(None, 0)))(0.0, states))
    loop = np.array([reference.rhs(0.0, list(np.asarray(state))) for state in states], dtype=float)
    np.testing.assert_allclose(batched, loop, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.asarray(columns.rhs(0.0, states[0])), loop[0], rtol=1e-10, atol=1e-12)
    p = columns.default_parameters()
    for transform in (
        lambda m: jax.jacrev(lambda y: m.rhs(0.0, y))(states[0]),
        lambda m: jax.jacfwd(lambda y: m.rhs(0.0, y))(states[1]),
        lambda m: jax.grad(lambda q: jnp.sum(m.rhs(0.0, states[2], q) ** 2))(p),
        lambda m: jax.vmap(jax.grad(lambda y: jnp.sum(m.rhs(0.0, y))))(states),
        lambda m: jax.vmap(jax.vmap(m.rhs, in_axes=(None, 0)), in_axes=(None, 0))(0.0, states.reshape(4, 8, -1)),
    ):
        np.testing.assert_allclose(np.asarray(transform(columns)), np.asarray(transform(unrolled)), rtol=1e-9, atol=1e-11)


def test_spd_solve_makes_one_stored_loop_per_column(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Under jit of vmap, `_ldl_columns` is a few fused loops per column (not one per scalar of L, as the unrolled
    code's): the 6-link chain's optimized rhs has well under the fusions of its unrolled form (30 against 56 with
    jax 0.10.2; counts, no timing)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import pendulum

    model = model_of(pendulum.Chain("general", 6).yaml())

    def fusions(name: str) -> int:
        module = load_module(jax_target.emit(model), tmp_path / f"{name}.py")
        text = jax.jit(jax.vmap(module.rhs, in_axes=(None, 0))).lower(0.0, jnp.zeros((100, 12))).compile().as_text()
        return len(re.findall(r"^\s*\S+ = \S+ fusion\(", text, re.M))

    monkeypatch.setattr(jax_target, "COLUMNS_MIN", 6)
    columns = fusions("columns")
    monkeypatch.setattr(jax_target, "COLUMNS_MIN", 1000)
    unrolled = fusions("unrolled")
    assert columns < 0.6 * unrolled, (columns, unrolled)
