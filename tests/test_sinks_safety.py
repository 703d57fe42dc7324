"""File text is data in every sink (issue 11, class 1): LaTeX compiled by a real pdflatex, the
symbol names LaTeX gets, the text emitter, and matplotlib figures."""

from __future__ import annotations

import dataclasses
import functools
import json
import re
import shutil
import subprocess
import unicodedata
from pathlib import Path

import pytest
import sympy as sp

from lagrange_cli.analysis import info
from lagrange_cli.emit import latex, text
from lagrange_cli.model import Model
from lagrange_cli.report import info_latex

from .conftest import SYSTEMS
from .helpers import model_from, model_of
from .limits import DEADLOCK

PDFLATEX = shutil.which("pdflatex")
PDFTOTEXT = shutil.which("pdftotext")
needs_pdflatex = pytest.mark.skipif(PDFLATEX is None, reason="pdflatex not installed (make test installs it)")

HOSTILE_TITLES = [
    "x\n\\input{/nonexistent/lagrange-marker}",
    "x\r\\input{/nonexistent/lagrange-marker}\f\\input{/nonexistent/lagrange-marker}\v\x85\u2028\\input{/nonexistent/lagrange-marker}",
    "\\immediate\\write18{touch pwned-shell}",
    "\\newwrite\\f\\immediate\\openout\\f=pwned-file.tex\\immediate\\closeout\\f",
    "}\\end{document}",
    "$$ x^2 $ _ & # % ~ { }",
    "%",
    "^^5c^^5cinput{/nonexistent/lagrange-marker} ^^M ^^",
    "\\catcode`\\@=0 @input{/nonexistent/lagrange-marker}",
    "\\def\\x{}\\csname input\\endcsname{/nonexistent/lagrange-marker}",
    "a\n\nb\n\n\n\\par c",
    "\U0001f600 \u4e2d\u6587 e\u0301 a\u0301\u0302 M\u00fcller \u0141\u00f3d\u017a \u00e6\u00df \u03b8\u03a9 \u00b0 z\u200bw\ufeff \u2028 \x1b[2J \ud800",
]
# What pdftotext reads back where it is not the title's printable ASCII.
SHOWN = {HOSTILE_TITLES[-1]: "U+1F600 U+4E2D U+6587 \u00e9 \u00e1U+0302 M\u00fcller L\u00f3d\u017a \u00e6\u00df \u03b8\u03a9"}
NORMALIZE = {"\u02c6": "^", "\u02dc": "~", "\u2018": "`", "\u2019": "'", "\u201d": '"'}


def compile_tex(folder: Path, name: str, document: str) -> str:
    """Compile with pdflatex (no shell escape); the log. Fails on any error."""
    assert PDFLATEX
    (folder / f"{name}.tex").write_text(document, encoding="utf-8")
    result = subprocess.run([PDFLATEX, "-interaction=nonstopmode", "-halt-on-error", "-no-shell-escape", f"{name}.tex"], cwd=folder, capture_output=True, text=True, timeout=DEADLOCK)
    assert result.returncode == 0, result.stdout[-3000:]
    return (folder / f"{name}.log").read_text(errors="replace")


def pdf_text(pdf: Path) -> str | None:
    if PDFTOTEXT is None:
        return None
    return subprocess.run([PDFTOTEXT, str(pdf), "-"], capture_output=True, text=True, check=True).stdout


def squeeze(text: str) -> str:
    """Text to compare with pdftotext's: no spaces, no hyphens (a line broken at a hyphen comes
    back joined), and the OT1 glyphs of ^ ~ ` ' " as those characters."""
    return "".join(NORMALIZE.get(c, c) for c in text if not c.isspace() and c != "-")


@functools.cache
def odd_model() -> Model:
    """Names that sympy's printer turns into accents, \\mathscr or Greek with subscripts, and pairs
    that print alike by the plain rule (x_1 and x1)."""
    source = {
        "title": "odd names",
        "coordinates": ["th1", "x_1", "x1", "xdot", "alphahat", "Abar", "y_max"],
        "parameters": ["ymathscr", "thetavec", "a_b_c", "lambda_1", "m", "lamda_c", "I_perp", "Theta2", "xddot", "zhat", "qc"],
        "functions": {"U": {"arguments": ["s"]}, "pot": {"arguments": ["s"]}, "V_1": {"arguments": ["s"]}},
        "kinetic": "m*(th1_dot**2 + x_1_dot**2 + x1_dot**2 + xdot_dot**2 + alphahat_dot**2 + Abar_dot**2 + y_max_dot**2)/2 + thetavec*xddot",
        "potential": "ymathscr*th1**2 + a_b_c*x_1 + U(x1) + I_perp*alphahat + pot(th1) + V_1(Abar) + lambda_1*Theta2*y_max + zhat*qc*xdot",
        "constraints": {"c": "xdot = lamda_c", "roll_x": "alphahat = y_max"},
    }
    return model_of(json.dumps(source), "odd.yaml")


# --- LaTeX: file text ------------------------------------------------------------------------


@pytest.mark.latex
@needs_pdflatex
@pytest.mark.parametrize("title", HOSTILE_TITLES, ids=range(len(HOSTILE_TITLES)))
def test_hostile_title_is_text_in_a_standalone_document(title: str, tmp_path: Path) -> None:
    model = dataclasses.replace(model_from(SYSTEMS[0]), title=title, source=f"/tmp/{title}.yaml")
    document = latex.emit(model, standalone=True)
    assert document.isascii() or document.split("\n", 1)[1].isascii()  # only the comment may hold non-ASCII
    log = compile_tex(tmp_path, "doc", document)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["doc.aux", "doc.log", "doc.pdf", "doc.tex"]
    assert "runsystem" not in log and "not found" not in log  # an executed \\input of the marker stops pdflatex
    assert set(re.findall(r"\\openout\d+ = `([^']*)'", log)) == {"doc.aux"}
    shown = pdf_text(tmp_path / "doc.pdf")
    if shown is not None:
        first = unicodedata.normalize("NFC", squeeze(shown))
        expected = SHOWN.get(title) or "".join(c for c in title if c.isascii() and c.isprintable() and c != "_")
        assert first.startswith(squeeze(expected)), (first[:200], expected)


@pytest.mark.latex
@needs_pdflatex
def test_hostile_titles_in_fragments_inside_an_article(tmp_path: Path) -> None:
    inputs = []
    for i, title in enumerate(HOSTILE_TITLES):
        for form in ("lagrange", "matrix"):
            (tmp_path / f"f{i}{form}.tex").write_text(latex.emit(dataclasses.replace(odd_model(), title=title), form), encoding="utf-8")
            inputs.append(f"\\input{{f{i}{form}.tex}}")
        model = model_from(SYSTEMS[0])
        (tmp_path / f"info{i}.tex").write_text(info_latex(dataclasses.replace(model, title=title), info(model)), encoding="utf-8")
        inputs.append(f"\\input{{info{i}.tex}}")
    log = compile_tex(tmp_path, "main", "\\documentclass{article}\n\\usepackage{amsmath}\n\\begin{document}\n" + "\n".join(inputs) + "\n\\end{document}\n")
    assert "runsystem" not in log and "not found" not in log
    assert not [p.name for p in tmp_path.iterdir() if "pwned" in p.name]


def test_comments_stay_one_line() -> None:
    for title in HOSTILE_TITLES:
        model = dataclasses.replace(model_from(SYSTEMS[0]), title=title, source=f"dir/{title}\n\\input{{x}}.yaml")
        for output in (latex.emit(model), latex.emit(model, standalone=True)):
            header = output.split("\n", 1)[0]
            assert header.startswith("% ") and header.isprintable() and "\r" not in header
            body = [line for line in output.splitlines() if not line.startswith("%")]
            assert not any("\\input" in line or "^^" in line or "\\csname" in line for line in body)


def test_escape_text_covers_every_special_character() -> None:
    escaped = latex.escape_text("\\{}$&#^_%~ a\n\nb \x00\x1b\u200b")
    assert escaped.isascii() and "\n" not in escaped and "\x00" not in escaped and "\x1b" not in escaped
    unescaped = re.sub(r"\\(textbackslash|textasciicircum|textasciitilde)\{\}|\\[{}$&#_%]", "", escaped)
    assert not set("\\{}$&#^_%~") & set(unescaped), unescaped
    assert "a b" in escaped


# --- LaTeX: names ---------------------------------------------------------------------------

# What sympy prints for the expressions themselves (not for names).
EXPRESSION_MACROS = {"left", "right", "frac", "sin", "cos", "tan", "sqrt", "begin", "end", "quad", "cdot", "log", "partial", "substack"}


def macros(tex: str) -> set[str]:
    return set(re.findall(r"\\([A-Za-z]+)", tex))


def test_names_use_only_allowed_macros() -> None:
    model = odd_model()
    rendered = latex.names(model, info(model).momentum_symbols)
    for tex in [*rendered.symbols.values(), *rendered.functions.values()]:
        assert macros(tex) <= latex.NAME_MACROS, tex
    symbols = rendered.symbols
    assert len(set(symbols.values())) == len(symbols), "two symbols print alike"
    by_name = {str(s): tex for s, tex in symbols.items()}
    assert by_name["th1_dot"] == r"\dot{\mathit{th}}_{1}" and by_name["th1"] == r"\mathit{th}_{1}"
    assert by_name["x_1"] != by_name["x1"]
    assert by_name["lambda_roll_x"] == r"\lambda_{\mathrm{roll},x}"
    assert by_name["I_perp"] == r"I_{\perp}" and by_name["Theta2"] == r"\Theta_{2}" and by_name["a_b_c"] == "a_{b,c}"
    for name in ("xdot", "ymathscr", "alphahat", "Abar", "thetavec", "xddot", "zhat"):
        assert by_name[name] == rf"\mathit{{{name}}}", by_name[name]
    assert not {"mathscr", "hat", "bar", "vec", "boldsymbol"} & macros(latex.emit(model))


@pytest.mark.parametrize("path", SYSTEMS, ids=lambda p: p.stem)
def test_bundled_systems_use_only_allowed_macros(path: Path) -> None:
    model = model_from(path)
    tex = latex.emit(model) + info_latex(model, info(model))
    assert macros(tex) <= latex.NAME_MACROS | EXPRESSION_MACROS, macros(tex) - latex.NAME_MACROS - EXPRESSION_MACROS


@pytest.mark.latex
@needs_pdflatex
def test_odd_names_compile_in_a_plain_article(tmp_path: Path) -> None:
    model = odd_model()
    parts = [latex.emit(model, form) for form in ("lagrange", "matrix")] + [info_latex(model, info(model))]
    compile_tex(tmp_path, "names", "\\documentclass{article}\n\\usepackage{amsmath}\n\\begin{document}\n" + "\n".join(parts) + "\n\\end{document}\n")
    compile_tex(tmp_path, "standalone", latex.emit(model, standalone=True))


def rename(model: Model, old: str, new: str) -> Model:
    """`model` with the symbol `old` renamed to `new` everywhere (no file could name it so)."""
    swap = {sp.Symbol(old): sp.Symbol(new)}

    def sub(value: object) -> object:
        if isinstance(value, sp.Basic):
            return value.xreplace(swap)
        if isinstance(value, tuple):
            return tuple(sub(v) for v in value)
        return value

    changes = {f.name: sub(getattr(model, f.name)) for f in dataclasses.fields(model) if f.name not in ("parameters", "constraints", "spans")}
    parameters = tuple(dataclasses.replace(p, symbol=swap.get(p.symbol, p.symbol)) for p in model.parameters)
    return dataclasses.replace(model, **changes, parameters=parameters)  # type: ignore[arg-type]


def test_control_characters_in_names_reach_no_output(tmp_path: Path) -> None:
    model = rename(model_from(SYSTEMS[0]), "g", "g\x1b[2J\n\\input{x}\u2028$")
    for form in ("lagrange", "matrix", "solved"):
        out = text.emit(model, form)
        assert "\x1b" not in out and "\u2028" not in out and "U+001B[2J" in out
        assert out.count("\n") == text.emit(model_from(SYSTEMS[0]), form).count("\n")
        tex = latex.emit(model, form)
        assert "\x1b" not in tex and "\\input" not in tex and r"\textbackslash{}input" in tex
    if PDFLATEX:
        compile_tex(tmp_path, "renamed", latex.emit(model, standalone=True))


# --- matplotlib -----------------------------------------------------------------------------

PLOT_TITLE = "$x^{$ \\alpha_1 {y} ^^ _ \\input{x} 50% \\\\ end"


@pytest.fixture
def saved_figures(monkeypatch: pytest.MonkeyPatch) -> list[object]:
    """The figures write_plot saves (captured at savefig, after they are drawn)."""
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    figures: list[object] = []
    save = Figure.savefig

    def savefig(self: Figure, *args: object, **kwargs: object) -> None:
        save(self, *args, **kwargs)  # type: ignore[arg-type]
        figures.append(self)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return figures


def all_texts(figure: object) -> list[object]:
    from matplotlib.text import Text

    return list(figure.findobj(Text))  # type: ignore[attr-defined]


def assert_plain(figure: object) -> None:
    """No text goes to LaTeX; the title is not mathtext; matplotlib's own log-scale tick labels
    ($\\mathdefault{10^{-8}}$) still are."""
    texts = all_texts(figure)
    assert not any(t.get_usetex() for t in texts)  # type: ignore[attr-defined]
    assert not figure._suptitle.get_parse_math()  # type: ignore[attr-defined]
    ticks = [t for t in texts if "mathdefault" in t.get_text()]  # type: ignore[attr-defined]
    assert ticks and all(t.get_parse_math() for t in ticks)  # type: ignore[attr-defined]


@pytest.mark.usefixtures("private_cache")
def test_simulate_plot_shows_file_text_as_written(tmp_path: Path, saved_figures: list[object]) -> None:
    import matplotlib

    from lagrange_cli.numeric import simulate
    from lagrange_cli.numeric.output import write_plot

    model = model_of("title: 'placeholder'\ncoordinates: [x_1]\nparameters: {m: 1.0, k: 1.0}\nkinetic: m*x_1_dot**2/2\npotential: k*x_1**2/2\ninitial: {x_1: 1.0}\n")
    trajectory = dataclasses.replace(simulate(model, backend="python", t_end=1.0), title=PLOT_TITLE + "\n\x1b[2J\u2028")
    with matplotlib.rc_context({"text.usetex": True}):  # a user's matplotlibrc must not send file text to LaTeX
        write_plot(trajectory, tmp_path / "plot.png")
    assert (tmp_path / "plot.png").read_bytes()[:4] == b"\x89PNG"
    for figure in saved_figures:
        title = figure.get_suptitle()  # type: ignore[attr-defined]
        assert title.startswith(PLOT_TITLE + " ") and "\x1b" not in title and "\n" not in title
        assert_plain(figure)
        legends = [t for axes in figure.axes if axes.get_legend() for t in axes.get_legend().get_texts()]  # type: ignore[attr-defined]
        assert "x_1" in [t.get_text() for t in legends] and not any(t.get_parse_math() for t in legends)


def test_accuracy_plot_shows_file_text_as_written(tmp_path: Path, saved_figures: list[object]) -> None:
    import numpy as np

    from lagrange_cli.numeric.accuracy import Point, Reference, Study, write_plot

    points = tuple(Point("DOP853", "DOP853:python", tol, None, "finished", "", err, err, 0.0, None, 0.01 / tol**0.1, 1, 0.0, 100, 0, 10) for tol, err in ((1e-6, 1e-5), (1e-9, 1e-8)))
    reference = Reference("computed", "two runs", 1e-12, np.zeros(2), np.zeros((2, 2)), np.zeros(2), 0.1)
    study = Study(PLOT_TITLE + "\n\n\x07", "s.yaml", 1.0, 1.0, reference, None, points)
    write_plot(study, tmp_path / "work.png")
    (figure,) = saved_figures
    assert figure.get_suptitle().startswith(PLOT_TITLE + ": work-precision")  # type: ignore[attr-defined]
    assert_plain(figure)
