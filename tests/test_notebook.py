"""docs/tour.ipynb runs clean: every cell executes without an error (nbclient, a real kernel)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from .conftest import ROOT
from .limits import DEADLOCK

NOTEBOOK = ROOT / "docs" / "tour.ipynb"


@pytest.mark.slow
def test_the_tour_runs_clean(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    monkeypatch.setenv("LAGRANGE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    monkeypatch.setenv("PYDEVD_DISABLE_FILE_VALIDATION", "1")
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    assert not any(cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code"), "commit the notebook without outputs"
    client = nbclient.NotebookClient(notebook, timeout=DEADLOCK, kernel_name="python3", resources={"metadata": {"path": str(ROOT / "docs")}})
    client.execute()  # raises CellExecutionError, naming the cell, on any error
    outputs = {i: cell.outputs for i, cell in enumerate(notebook.cells) if cell.cell_type == "code"}
    kinds = [set().union(*(o.get("data", {}).keys() for o in out)) for out in outputs.values()]
    assert any("text/latex" in k for k in kinds) and any("text/html" in k for k in kinds) and any("image/png" in k for k in kinds)
    assert not any(o.get("output_type") == "error" for out in outputs.values() for o in out)
    assert not any(o.get("name") == "stderr" and "Warning" in o.get("text", "") for out in outputs.values() for o in out)
