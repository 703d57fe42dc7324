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
            assert not any(i.startswith(("lagrange_cli.spec", "lagrange_cli.expr", "lagrange_cli.derive")) for i in found), name


def test_model_depends_only_on_errors_and_symengine() -> None:
    found = modules()["lagrange_cli.model"]
    assert {i for i in found if i.startswith("lagrange_cli")} <= {"lagrange_cli.errors", "lagrange_cli.errors.Span", "lagrange_cli._symengine", "lagrange_cli._symengine.to_symengine"}


def test_symbolic_modules_import_no_numerics() -> None:
    """The modules `derive` loads; analysis and numeric ones import numpy inside functions."""
    for name, found in modules().items():
        if not name.startswith(("lagrange_cli.numeric", "lagrange_cli.cli", "lagrange_cli.analysis", "lagrange_cli.report", *LAZY)):
            assert not any(i.split(".")[0] in ("numpy", "scipy", "matplotlib") for i in found), name


LAZY = ("lagrange_cli.api", "lagrange_cli.animate")
"""The notebook API and the animations: imported by `import lagrange_cli` on first use only, they
import numpy and matplotlib inside the functions that need them, never at module level."""


def test_the_api_imports_numerics_only_inside_functions() -> None:
    for name in LAZY:
        tree = ast.parse((ROOT / (name.replace(".", "/") + ".py")).read_text())
        top = [node for node in tree.body if isinstance(node, (ast.Import, ast.ImportFrom))]
        found = {alias.name for node in top if isinstance(node, ast.Import) for alias in node.names} | {node.module or "" for node in top if isinstance(node, ast.ImportFrom)}
        assert not any(i.split(".")[0] in ("numpy", "scipy", "matplotlib", "typer", "rich") for i in found), name
