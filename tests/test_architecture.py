"""Imports point one way: cli -> {spec, derive, emit, numeric, ...} -> model -> errors.

Nothing imports cli; only cli imports typer and rich; emitters never import the
frontend (spec, expr) or the deriver; numpy, scipy and matplotlib stay out of modules
that `derive` loads."""

from __future__ import annotations

import ast
from pathlib import Path

from .conftest import ROOT

PACKAGE = ROOT / "lagrange_cli"


def imports(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
    return found


def modules() -> dict[str, set[str]]:
    return {str(p.relative_to(ROOT).with_suffix("")).replace("/", "."): imports(p) for p in PACKAGE.rglob("*.py")}


def test_nothing_imports_the_cli() -> None:
    for name, found in modules().items():
        if not name.startswith(("lagrange_cli.cli", "lagrange_cli.__main__")):
            assert not any(i.startswith("lagrange_cli.cli") for i in found), name


def test_only_the_cli_imports_typer_and_rich() -> None:
    for name, found in modules().items():
        if not name.startswith("lagrange_cli.cli"):
            assert not any(i.split(".")[0] in ("typer", "rich", "click") for i in found), name


def test_emitters_do_not_import_the_frontend_or_the_deriver() -> None:
    for name, found in modules().items():
        if name.startswith("lagrange_cli.emit"):
            assert not any(i.startswith(("lagrange_cli.spec", "lagrange_cli.frontend", "lagrange_cli.expr", "lagrange_cli.derive")) for i in found), name


def test_model_depends_only_on_errors_and_symengine() -> None:
    found = modules()["lagrange_cli.model"]
    assert {i for i in found if i.startswith("lagrange_cli")} <= {"lagrange_cli.errors", "lagrange_cli.errors.Span", "lagrange_cli._symengine", "lagrange_cli._symengine.to_symengine"}


def test_symbolic_modules_import_no_numerics() -> None:
    """The modules `derive` loads; analysis and numeric ones import numpy inside functions."""
    for name, found in modules().items():
        if not name.startswith(("lagrange_cli.numeric", "lagrange_cli.cli", "lagrange_cli.analysis", "lagrange_cli.report", *LAZY)):
            assert not any(i.split(".")[0] in ("numpy", "scipy", "matplotlib") for i in found), name


FRONTEND = ("lagrange_cli.spec", "lagrange_cli.frontend", "lagrange_cli.expr", "lagrange_cli.derive", "lagrange_cli.files", "lagrange_cli.cli")
"""What `numeric` may not import: the frontend (files in, the spec, the deriver) and the CLI."""
NUMERIC_EXCEPTIONS = {
    ("lagrange_cli.numeric.settings", "lagrange_cli.expr"): "the library's `simulate(until=...)` takes the stop condition as text and parses it with the safe parser",
    ("lagrange_cli.numeric.compile", "lagrange_cli.files"): "the compile cache writes its files atomically",
    ("lagrange_cli.numeric.output", "lagrange_cli.files"): "`write_plot`/`write_npz` write the user's outputs atomically",
    ("lagrange_cli.numeric.reports", "lagrange_cli.files"): "`write_plot` writes the user's output atomically",
}
"""Known imports of the frontend from `numeric`, each with why (files.py is the ground floor of STYLE.md's layout)."""


def test_numeric_does_not_import_the_frontend() -> None:
    found = []
    for name, imported in modules().items():
        if name.startswith("lagrange_cli.numeric"):
            for module in imported:
                banned = next((f for f in FRONTEND if module == f or module.startswith(f + ".")), None)
                if banned is not None and (name, banned) not in NUMERIC_EXCEPTIONS:
                    found.append(f"{name} imports {module}")
    assert not found, found


def private_uses(path: Path) -> list[str]:
    """Names starting with `_` taken from another lagrange_cli module: `from m import _x`, or
    `m._x` where `m` is a lagrange_cli module imported by name."""
    tree = ast.parse(path.read_text())
    modules_by_alias: dict[str, str] = {}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("lagrange_cli"):
            for alias in node.names:
                if alias.name.startswith("_") and not alias.name.startswith("__"):
                    found.append(f"from {node.module} import {alias.name}")
                elif (PACKAGE / Path(*node.module.split(".")[1:]) / f"{alias.name}.py").exists():
                    modules_by_alias[alias.asname or alias.name] = f"{node.module}.{alias.name}"
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("lagrange_cli") and alias.asname:
                    modules_by_alias[alias.asname] = alias.name
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in modules_by_alias and node.attr.startswith("_") and not node.attr.startswith("__"):
            found.append(f"{modules_by_alias[node.value.id]}.{node.attr}")
    return found


def test_numeric_uses_no_private_names_of_other_modules() -> None:
    found = {str(p.relative_to(ROOT)): private_uses(p) for p in (PACKAGE / "numeric").rglob("*.py")}
    assert not {k: v for k, v in found.items() if v}, found


def test_the_private_name_check_can_fail(tmp_path: Path) -> None:
    source = tmp_path / "m.py"
    source.write_text("from lagrange_cli.numeric.settings import _positive\nfrom lagrange_cli.numeric import integrators\nintegrators._drive\n")
    assert private_uses(source) == ["from lagrange_cli.numeric.settings import _positive", "lagrange_cli.numeric.integrators._drive"]


def test_the_kernels_status_codes_are_defined_once() -> None:
    """Status codes and counter indices live in numeric/status.py, which imports nothing (no numba):
    no other numeric module assigns them."""
    names = {"RUNNING", "DONE", "EVENT", "SINGULAR", "NONFINITE", "STEP_COLLAPSE", "NO_CONVERGENCE", "BUDGET", "NFEV", "NJEV", "NSTEPS", "NREJECT", "HMIN", "HMAX", "PAUSE_STEPS"}
    status = PACKAGE / "numeric" / "status.py"
    assert {i.split(".")[0] for i in imports(status)} <= {"__future__", "enum"}
    for path in (PACKAGE / "numeric").rglob("*.py"):
        if path == status:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Assign):
                targets = [t for target in node.targets for t in (target.elts if isinstance(target, ast.Tuple) else [target])]
                assigned = {t.id for t in targets if isinstance(t, ast.Name)}
                assert not (assigned & names) or all(isinstance(v, ast.Attribute) for v in (node.value.elts if isinstance(node.value, ast.Tuple) else [node.value])), (path.name, assigned & names)


def test_numeric_caches_are_not_keyed_by_id() -> None:
    """A cache keyed by `id(model)` hands a new model the entry of a dead one with the same id;
    per-model values live on the model (numeric/memo.py). compile.py keeps the model alive in each
    entry it keys by id (safe, if not tidy), so it is not checked here."""
    for path in (PACKAGE / "numeric").glob("*.py"):
        if path.name == "compile.py":
            continue
        calls = [node for node in ast.walk(ast.parse(path.read_text())) if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "id"]
        assert not calls, path.name


LAZY = ("lagrange_cli.api", "lagrange_cli.animate", "lagrange_cli.sweep", "lagrange_cli.statespace")
"""The notebook API, the animations, sweeps and state-space linearization: imported by `import lagrange_cli` (or `lagrange sweep`) on first use only, they
import numpy and matplotlib inside the functions that need them, never at module level."""


def test_the_api_imports_numerics_only_inside_functions() -> None:
    for name in LAZY:
        tree = ast.parse((ROOT / (name.replace(".", "/") + ".py")).read_text())
        top = [node for node in tree.body if isinstance(node, (ast.Import, ast.ImportFrom))]
        found = {alias.name for node in top if isinstance(node, ast.Import) for alias in node.names} | {node.module or "" for node in top if isinstance(node, ast.ImportFrom)}
        assert not any(i.split(".")[0] in ("numpy", "scipy", "matplotlib", "typer", "rich") for i in found), name


FRONTEND_MAY_IMPORT = ("errors", "expr", "units", "model", "inputs", "rigid", "kinematics", "hamilton", "files", "_symengine", "frontend")
"""What lagrange_cli/frontend/ may import from the package: the model level (errors, the safe expression parser,
units, the model's types, the readers of `inputs` and `bodies`, the file guards) and itself; never numeric, emit,
cli or derive (the frontend reads files, it does not derive or run them)."""


def lagrange_imports(found: set[str]) -> set[str]:
    """The lagrange_cli modules among `found`, as their first component under lagrange_cli (`lagrange_cli.x.y` -> `x`)."""
    return {i.split(".")[1] for i in found if i.startswith("lagrange_cli.")}


def test_the_frontend_imports_only_the_model_level() -> None:
    found = {name: lagrange_imports(imported) - set(FRONTEND_MAY_IMPORT) for name, imported in modules().items() if name.startswith("lagrange_cli.frontend")}
    assert len(found) >= 8, sorted(found)  # the package is there, split in modules
    assert not {k: v for k, v in found.items() if v}, found


def test_the_node_types_import_no_yaml() -> None:
    """nodes.py is what the rest of the program sees of a file: dataclasses of sympy expressions, no YAML nodes."""
    found = imports(PACKAGE / "frontend" / "nodes.py")
    assert not any(i.split(".")[0] == "yaml" for i in found), found
    assert not any(i.startswith("lagrange_cli.frontend") for i in found), found


def test_spec_only_reexports() -> None:
    """lagrange_cli/spec.py is the frontend's public entry point: a docstring, imports and `__all__`, no code;
    everything it imports is in `__all__` and everything in `__all__` is imported."""
    tree = ast.parse((PACKAGE / "spec.py").read_text())
    imported: set[str] = set()
    exported: list[str] = []
    for node in tree.body:
        if isinstance(node, ast.ImportFrom):
            if node.module != "__future__":
                imported.update(alias.asname or alias.name for alias in node.names)
        elif isinstance(node, ast.Assign) and [getattr(t, "id", None) for t in node.targets] == ["__all__"]:
            exported = [ast.literal_eval(e) for e in node.value.elts]  # type: ignore[attr-defined]
        else:
            assert isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and node is tree.body[0], ast.dump(node)[:200]
    assert exported and len(exported) == len(set(exported))
    assert imported == set(exported), imported ^ set(exported)


def spec_names(path: Path) -> set[str]:
    """The names a file takes from lagrange_cli.spec: `from lagrange_cli.spec import X`, and `spec.X`
    where `spec` is the module (`from lagrange_cli import spec`)."""
    tree = ast.parse(path.read_text())
    found = set()
    module = False
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module == "lagrange_cli.spec":
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module == "lagrange_cli" and any(alias.name == "spec" and alias.asname is None for alias in node.names):
            module = True
    if module:
        found.update(node.attr for node in ast.walk(tree) if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "spec")
    return found


def test_every_name_taken_from_spec_resolves() -> None:
    """Every `spec.X` and `from lagrange_cli.spec import X` in the package, the tests and the benchmarks still
    resolves now that the code lives in frontend/. A file that binds the module as `spec` may also name a
    `SystemSpec` (or an importlib `ModuleSpec`) `spec`: an attribute of those counts as resolved there."""
    import dataclasses
    import importlib.machinery

    from lagrange_cli import spec

    fields = {f.name for f in dataclasses.fields(spec.SystemSpec)} | set(dir(spec.SystemSpec))
    fields |= set(dir(importlib.machinery.ModuleSpec("m", None)))  # a benchmark loader's `spec = spec_from_file_location(...)`
    files = [*PACKAGE.rglob("*.py"), *(ROOT / "tests").rglob("*.py"), *(ROOT / "benchmarks").rglob("*.py")]
    used = {str(path.relative_to(ROOT)): spec_names(path) for path in files}
    assert sum(len(v) for v in used.values()) > 50  # the check sees the uses
    assert {"parse", "load", "resolve", "SpecError", "time_derivative", "MAX_COORDINATES"} <= set().union(*used.values())
    missing = {name: sorted(n for n in names if not hasattr(spec, n) and n not in fields) for name, names in used.items()}
    assert not {k: v for k, v in missing.items() if v}, missing


def test_the_spec_name_check_can_fail(tmp_path: Path) -> None:
    source = tmp_path / "m.py"
    source.write_text("from lagrange_cli import spec\nfrom lagrange_cli.spec import parse, Nowhere\nspec.load\nspec.gone\n")
    assert spec_names(source) == {"parse", "Nowhere", "load", "gone"}
