"""LaTeX output compiles with a real pdflatex, both as an \\input fragment and standalone."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from lagrange_cli.emit import latex
from lagrange_cli.errors import DerivationError

from .conftest import SYSTEMS
from .helpers import model_from
from .limits import DEADLOCK

PDFLATEX = shutil.which("pdflatex")
needs_pdflatex = pytest.mark.skipif(PDFLATEX is None and not os.environ.get("CI"), reason="pdflatex not installed (make test installs it)")


def compile_tex(folder: Path, name: str, document: str) -> None:
    assert PDFLATEX, "pdflatex is required in CI: `make latex-deps` installs texlive-latex-base"
    (folder / f"{name}.tex").write_text(document)
    result = subprocess.run([PDFLATEX, "-interaction=nonstopmode", "-halt-on-error", f"{name}.tex"], cwd=folder, capture_output=True, text=True, timeout=DEADLOCK)
    assert result.returncode == 0, result.stdout[-3000:]
    assert (folder / f"{name}.pdf").stat().st_size > 0


@pytest.mark.latex
@needs_pdflatex
@pytest.mark.parametrize("path", SYSTEMS, ids=lambda p: p.stem)
def test_fragments_compile_inside_a_document(path: Path, tmp_path: Path) -> None:
    model = model_from(path)
    inputs = []
    for form in ("lagrange", "matrix", "solved"):
        try:
            fragment = latex.emit(model, form)
        except DerivationError:
            continue
        (tmp_path / f"{form}.tex").write_text(fragment)
        inputs.append(f"\\input{{{form}.tex}}")
    assert inputs
    document = "\\documentclass{article}\n\\usepackage{amsmath}\n\\begin{document}\n" + "\n".join(inputs) + "\n\\end{document}\n"
    compile_tex(tmp_path, "main", document)


@pytest.mark.latex
@needs_pdflatex
def test_standalone_document_compiles(tmp_path: Path) -> None:
    compile_tex(tmp_path, "standalone", latex.emit(model_from(SYSTEMS[0]), standalone=True))


def test_dots_greek_and_subscripts() -> None:
    from .helpers import model_of

    model = model_of("coordinates: [theta1, x]\nparameters: [I_par, m]\nkinetic: I_par*theta1_dot**2/2 + m*x_dot**2/2\npotential: x**2\n")
    text = latex.emit(model)
    assert r"\ddot{\theta}_{1}" in text and r"I_{\parallel}" in text and r"\ddot{x}" in text
    assert text.count("&= 0") == 2 and "lambda" not in text
