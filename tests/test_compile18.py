"""What numba compiles for the integration loops (helper compile18): each entry point compiles the branches of the
features it has and no others, each helper once (never once per literal argument), and a second system reuses the
loops compiled for the first (its functions are passed as first-class functions of one type). Counted from numba's
own IR and signatures, never timed."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest
from numba.core import compiler, ir, types
from numba.core.analysis import dead_branch_prune
from numba.core.registry import CPUDispatcher

from lagrange_cli import api
from lagrange_cli.numeric import compile, kernels

from .conftest import ROOT

# the shared cache (no private_cache): erk_run compiles once per machine, and loads in about a second after that

SWITCHING = {"_changed", "_earliest", "_found", "_hop", "_hopped", "_landed"}
"""The crossing search and the hop: only the switched loops call them."""
PROJECTION = {"_project", "_projected"}
"""The projection onto kept constraints: only the projected loops call them."""


def _helpers_called(function: CPUDispatcher, absent: set[str]) -> set[str]:
    """The kernels' compiled helpers that `function` calls once numba has pruned the branches on its arguments
    `absent` (given None, as the entry points pass them): numba's own front end and branch pruning, the first steps
    of its compile, without compiling."""
    func_ir = compiler.run_frontend(function.py_func)
    names = list(inspect.signature(function.py_func).parameters)
    assert absent <= set(names)
    dead_branch_prune(func_ir, tuple(types.none if name in absent else types.float64[::1] for name in names))
    found = set()
    for block in func_ir.blocks.values():
        for inst in block.body:
            if isinstance(inst, ir.Assign) and isinstance(inst.value, (ir.Global, ir.FreeVar)) and isinstance(inst.value.value, CPUDispatcher):
                found.add(inst.value.name)
    return found


def test_each_radau_entry_point_compiles_only_its_own_features() -> None:
    """radau_run compiled the crossing search, the hop and the projection, never called, for every smooth system
    (about 5 s of a first `accuracy` or `stress`); radau_switched compiled the projection, radau_projected the
    crossing search."""
    switch, projection = {"switch", "record"}, {"rows", "energy", "bounds", "holonomic", "projected_record"}
    run = _helpers_called(kernels._radau_loop, switch | projection)
    switched = _helpers_called(kernels._radau_loop, projection)
    projected = _helpers_called(kernels._radau_loop, switch)
    assert not run & (SWITCHING | PROJECTION)
    assert switched >= SWITCHING and not switched & PROJECTION
    assert projected >= PROJECTION and not projected & SWITCHING
    assert {"_radau_newton", "_radau_jac", "_lu_back"} <= run  # the steps themselves are there


def test_each_explicit_entry_point_compiles_only_its_own_features() -> None:
    switch, projection = {"switch", "switching"}, {"rows", "energy", "bounds", "holonomic", "record"}
    run = _helpers_called(kernels._erk_loop, switch | projection)
    switched = _helpers_called(kernels._erk_loop, projection)
    projected = _helpers_called(kernels._erk_loop, switch)
    assert not run & (SWITCHING | PROJECTION)
    assert switched >= SWITCHING and not switched & PROJECTION
    assert projected >= PROJECTION and not projected & SWITCHING
    assert {"_erk_attempt", "_erk_samples"} <= run


def test_no_helper_is_called_with_a_literal() -> None:
    """numba compiles a helper once for each literal value it is called with (an int or bool constant, or a module
    constant holding one): `_interpolant(LINEAR, ...)` and `_interpolant(RADAU_KIND, ...)` compiled it, `_switch_root`
    and `_erk_eval` two more times each, `_found(..., True)` and `(..., False)` twice, `_initial_step` with Radau's
    order once more than with the explicit pairs'. None is allowed: it prunes a feature's branches."""
    tree = ast.parse(inspect.getsource(kernels))
    defined = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}

    def literal(arg: ast.expr) -> bool:
        if isinstance(arg, ast.UnaryOp):
            return literal(arg.operand)
        if isinstance(arg, ast.Constant):
            return isinstance(arg.value, bool | int)
        return isinstance(arg, ast.Name) and arg.id not in defined and isinstance(getattr(kernels, arg.id, None), bool | int)

    found = [
        (function.name, node.lineno, ast.unparse(arg))
        for function in tree.body
        if isinstance(function, ast.FunctionDef)
        for node in ast.walk(function)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in defined
        for arg in node.args
        if literal(arg)
    ]
    assert found == []


def test_a_second_system_reuses_the_compiled_loop() -> None:
    """Two systems through the compiled RK45 in one process: erk_run has one signature (the right-hand side a
    first-class function of one type, whatever the system), and each system's `_accel` one of its own."""
    systems = [api.load(str(ROOT / "systems" / f"{name}.yaml")) for name in ("double_pendulum", "elastic_pendulum")]
    for system in systems:
        run = system.simulate(method="RK45", backend="compiled", t_end=0.5, samples=11).run
        assert run.stats.steps > 0
    loops = compile.kernels_module()
    assert len(loops.compiled("erk_run").signatures) == 1
    # the two systems' modules (not those of other tests in this process: one whose `_accel` never ran has no signature)
    modules = [compile.build(system.model, "numba").module for system in systems]
    assert len({id(module) for module in modules}) == 2
    assert all(len(module._accel.signatures) == 1 for module in modules)


def test_the_kernels_cache_key_covers_every_module_whose_constants_they_take(monkeypatch: pytest.MonkeyPatch) -> None:
    """numba freezes the values kernels.py imports into the machine code it caches beside the kernels' copy, whose
    name is the cache key: every lagrange module kernels.py imports from is hashed into that name, so a changed
    status code or step-control constant compiles afresh instead of loading machine code made with the old value."""
    tree = ast.parse(inspect.getsource(kernels))
    imported = {node.module for node in tree.body if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("lagrange_cli")}
    assert imported == {f"lagrange_cli.numeric.{name.removesuffix('.py')}" for name in compile.KERNEL_CONSTANTS}
    from importlib import resources

    before = compile.kernels_name()
    original = resources.files

    class Changed:
        def __init__(self, package: str) -> None:
            self.package = package

        def joinpath(self, name: str) -> object:
            path = original(self.package).joinpath(name)
            if name != "status.py":
                return path
            text = path.read_text(encoding="utf-8").replace("CHATTER = 8", "CHATTER = 9")
            return type("Text", (), {"read_text": lambda self, encoding="utf-8": text})()

    compile.kernels_name.cache_clear()
    monkeypatch.setattr(compile.resources, "files", Changed)
    try:
        assert compile.kernels_name() != before
    finally:
        monkeypatch.undo()
        compile.kernels_name.cache_clear()
    assert compile.kernels_name() == before


@pytest.mark.parametrize("name", sorted(kernels._LOOP_ENTRIES))
def test_a_loop_entry_point_passes_none_where_its_documented_function_does(name: str) -> None:
    """The entry points compiled as their loop (kernels._LOOP_ENTRIES, to spare numba a second pass over the whole
    loop) take the loop's arguments in the order their Python function (radau_run, ...) passes them, None in the
    places that function passes None: the table and the functions cannot drift apart."""
    loop, at, absent = kernels._LOOP_ENTRIES[name]
    tree = ast.parse(inspect.getsource(getattr(kernels, name)))
    call = next(node for node in ast.walk(tree) if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == loop)
    nones = [i for i, arg in enumerate(call.args) if isinstance(arg, ast.Constant) and arg.value is None]
    assert nones == list(range(at, at + absent)), (name, nones)
    given = [arg.id for arg in call.args if isinstance(arg, ast.Name)]
    assert given == list(inspect.signature(getattr(kernels, name)).parameters), name  # its own arguments, in order
    assert len(call.args) == len(inspect.signature(getattr(kernels, loop).py_func).parameters)
    assert len(kernels.SIGNATURES[name].args) + absent == len(call.args)


def test_a_loop_entry_point_is_found_in_the_cache_under_its_own_name() -> None:
    """`compile.kernel_cached` looks for an entry point's numba index by its name: the loop compiled as erk_projected
    is cached as erk_projected, so that a second command neither compiles it ahead again nor waits for it."""
    module = compile.kernels_module()
    module.compiled("erk_projected")
    # beside the module's copy, where `kernel_cached` looks in the command's cache (the module loaded first in this
    # process may be another test's private cache's)
    folder = Path(module.__file__).parent / "__pycache__"
    assert any(folder.glob(f"{module.__name__}.erk_projected-*.nbi")), sorted(path.name for path in folder.glob("*erk*"))
