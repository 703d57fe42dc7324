"""LaTeX fits the page: every bundled system (and those of tests/unseen and tests/matrix) and a 6-link chain with
its own masses and lengths, in every form and through `info --latex`, compiled inside a standard
`article` (default margins) and as `--standalone` documents, leave no `Overfull \\hbox` over 1 pt
in pdflatex's log. Then, without pdflatex, the width estimate and the line breaker."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest
import sympy as sp
from sympy.printing.latex import LatexPrinter

from lagrange_cli import report
from lagrange_cli.analysis import info
from lagrange_cli.emit import latex, layout, text
from lagrange_cli.emit.common import equation_terms, positive_denominator, tidy
from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

from .conftest import SYSTEMS
from .helpers import model_from, model_of
from .limits import DEADLOCK

PDFLATEX = shutil.which("pdflatex")
needs_pdflatex = pytest.mark.skipif(PDFLATEX is None, reason="pdflatex not installed (make latex-deps installs texlive-latex-base)")
OVERFULL = re.compile(r"Overfull \\hbox \((\d+\.\d+)pt too wide\)")


def chain(n: int) -> str:
    """An n-link planar chain, each link with its own mass m_i and length l_i."""
    x, y, particles = [], [], []
    for i in range(1, n + 1):
        x.append(f"l{i}*sin(theta{i})")
        y.append(f"l{i}*cos(theta{i})")
        particles.append(f"  bob{i}: {{mass: m{i}, position: [{' + '.join(x)}, -({' + '.join(y)})]}}")
    names = [f"m{i}" for i in range(1, n + 1)] + [f"l{i}" for i in range(1, n + 1)]
    return f"title: {n}-link chain\ncoordinates: [{', '.join(f'theta{i}' for i in range(1, n + 1))}]\nparameters: [{', '.join(names)}, g]\ngravity: [0, -g]\nparticles:\n" + "\n".join(particles) + "\n"


@pytest.fixture(scope="module")
def models() -> dict[str, Model]:
    # tests/unseen (a spring whose length is a square root, ...) and the feature systems of tests/matrix
    more = sorted((Path(__file__).parent / "unseen").glob("*.yaml")) + sorted((Path(__file__).parent / "matrix").glob("*.yaml"))
    found = {f"{path.parent.name}-{path.stem}": model_from(path) for path in [*SYSTEMS, *more]}
    found["chain_6_own"] = model_of(chain(6), "chain_6_own.yaml")
    return found


def render(model: Model, form: str) -> str | None:
    try:
        return report.info_latex(model, info(model)) if form == "info" else latex.emit(model, form)
    except DerivationError:
        return None  # solved is refused above four unknowns


def overflows(folder: Path, name: str, parts: dict[str, str], standalone: bool = False) -> dict[str, float]:
    """Compile `parts` (fragments `\\input` into one article, each on its own page, or whole
    documents one after another); return the widest overflow per part."""
    assert PDFLATEX
    widest: dict[str, float] = {}
    if standalone:
        documents = parts
    else:
        inputs = []
        for key, fragment in parts.items():
            (folder / f"{key}.tex").write_text(fragment)
            inputs.append(f"\\typeout{{@@PART {key}}}\n\\input{{{key}.tex}}\n\\clearpage")
        documents = {name: "\\documentclass{article}\n\\usepackage{amsmath}\n\\begin{document}\n" + "\n".join(inputs) + "\n\\end{document}\n"}
    for doc, source in documents.items():
        (folder / f"{doc}.tex").write_text(source)
        result = subprocess.run([PDFLATEX, "-interaction=nonstopmode", "-halt-on-error", f"{doc}.tex"], cwd=folder, capture_output=True, text=True, timeout=DEADLOCK)
        assert result.returncode == 0, result.stdout[-3000:]
        current = doc
        for line in (folder / f"{doc}.log").read_text(errors="replace").splitlines():
            if line.startswith("@@PART "):
                current = line.removeprefix("@@PART ").strip()
            elif match := OVERFULL.search(line):
                widest[current] = max(widest.get(current, 0.0), float(match.group(1)))
    return widest


@pytest.mark.latex
@needs_pdflatex
@pytest.mark.parametrize("form", ["lagrange", "matrix", "solved", "info"])
def test_every_system_fits_an_article(form: str, models: dict[str, Model], tmp_path: Path) -> None:
    parts = {name: tex for name, model in models.items() if (tex := render(model, form)) is not None}
    assert "chain_6_own" in parts or form == "solved"
    assert len(parts) >= len(SYSTEMS) - 1
    too_wide = {name: width for name, width in overflows(tmp_path, form, parts).items() if width > 1.0}
    assert not too_wide, f"{form}: overfull lines (pt): {too_wide}"


@pytest.mark.latex
@needs_pdflatex
def test_three_link_chain_solved_form_fits(tmp_path: Path) -> None:
    model = model_of(chain(3), "chain_3_own.yaml")
    tex = latex.emit(model, "solved")
    assert tex.count("&= ") >= 3
    assert not {k: w for k, w in overflows(tmp_path, "solved", {"chain3": tex}).items() if w > 1.0}


@pytest.mark.latex
@needs_pdflatex
def test_standalone_documents_fit(models: dict[str, Model], tmp_path: Path) -> None:
    documents = {f"{name}-{form}": latex.emit(models[name], form, standalone=True) for name in ("chain_6_own", "systems-heavy_top") for form in ("lagrange", "matrix")}
    too_wide = {name: width for name, width in overflows(tmp_path, "standalone", documents, standalone=True).items() if width > 1.0}
    assert not too_wide, too_wide


# --- without pdflatex ----------------------------------------------------------------------------


def test_width_grows_with_the_text(models: dict[str, Model]) -> None:
    top = models["systems-heavy_top"]
    doprint = latex.names(top).printer().doprint
    pieces = [doprint(term) for term in sp.Add.make_args(sp.expand(top.forcing[0] + top.forcing[1]))]
    sums = [" + ".join(pieces[:k]) for k in range(len(pieces) + 1)]
    for texts in [sums, *([tex[:end] for end in range(len(tex) + 1) if end == len(tex) or tex[end] == " "] for tex in [*pieces, " + ".join(pieces)])]:
        widths = [layout.width(t) for t in texts]
        assert widths == sorted(widths), texts
    for tex in pieces:
        for suffix in (" + x", "^{2}", r" \frac{a}{b}", r" \left(y\right)", r" \cos{\left(\theta \right)}"):
            assert layout.width(tex + suffix) > layout.width(tex)
    assert layout.width("a + b + c") < layout.width("a + b + c + d")
    assert layout.width(r"\frac{a b c d}{e}") < layout.width("a b c d e")
    assert layout.width("x^{abcd}") < layout.width("x abcd")


@pytest.mark.parametrize("widths", [[5.0] * 40, [1.0, 90.0, 2.0, 3.0, 70.0, 70.0], [200.0], [0.5] * 3])
def test_line_breaker_fills_lines_and_never_leaves_one_empty(widths: list[float]) -> None:
    parts = [layout.Piece(f"t{i}", w) for i, w in enumerate(widths)]
    lines = layout.lines(parts, 60.0, 50.0)
    assert all(line.strip() for line in lines)
    assert " ".join(lines).split() == [p.tex for p in parts]  # every piece once, in order
    by_tex = {p.tex: p.width for p in parts}
    for k, line in enumerate(lines):
        used = sum(by_tex[t] for t in line.split())
        room = 60.0 if k == 0 else 50.0
        assert used <= room or len(line.split()) == 1
        if k + 1 < len(lines):
            assert used + by_tex[lines[k + 1].split()[0]] > (60.0 if k == 0 else 50.0)  # greedy: the next piece did not fit


def test_delimiters_balance_on_every_line() -> None:
    x = sp.symbols("x0:40")
    expr = sp.Symbol("m") * sp.Add(*(xi * sp.cos(xi) for xi in x)) / sp.Add(*x)
    doprint = LatexPrinter().doprint
    rows = layout.lines(layout.pieces(expr, doprint, 40.0), 50.0, 45.0)
    assert len(rows) > 3
    for row in rows:
        assert row.count(r"\left") == row.count(r"\right"), row


@pytest.mark.parametrize("sign", [1, -1])
def test_a_broken_quotient_keeps_its_sign_in_front(sign: int) -> None:
    x = sp.symbols("x0:30")
    expr = sign * sp.Symbol("m") * sp.Add(*(xi * sp.cos(xi) for xi in x)) / (x[0] + x[1])
    doprint = LatexPrinter().doprint
    text = " ".join(layout.lines(layout.pieces(expr, doprint, 40.0), 50.0, 45.0))
    assert text.startswith(r"- \frac{1}{x_{0} + x_{1}} m \left(" if sign < 0 else r"\frac{1}{x_{0} + x_{1}} m \left(")
    assert text.count(" - ") == 0


def test_layout_is_linear_in_the_output(models: dict[str, Model]) -> None:
    """Each term is printed once: laying out takes one printer call per term (plus the few
    sums and products it looks inside), not one per line or per pair of terms."""
    model = models["chain_6_own"]

    class Counting(latex.TexPrinter):
        from_layout = 0

        def __call__(self, expr: object) -> str:
            self.from_layout += 1
            return self.doprint(expr)

    printer = Counting(latex.names(model))
    rows = equation_terms(model, printer.keys)
    terms = [term for row in rows for term in row]
    for row in rows:
        layout.lines(layout.terms(row, printer, 40.0), 60.0, 58.0)
    assert 0 < printer.from_layout <= 2 * len(terms)


def test_matrix_names_cannot_be_a_parameter() -> None:
    model = model_of("coordinates: [x, y]\nparameters: [M, F, m]\nkinetic: M*x_dot**2/2 + m*y_dot**2/2 + M*x_dot*y_dot/3\npotential: F*x\n")
    plain = text.emit(model, "matrix")
    assert "mass matrix =" in plain and "forcing =" in plain
    assert not any(line.startswith(("M =", "F =", "M*")) for line in plain.splitlines())
    wide = model_of(chain(6), "chain_6_own.yaml")
    tex = latex.emit(wide, "matrix")
    assert r"\mathbf{M}_{11} &= " in tex and r"\mathbf{F}_{6} &= " in tex and r"\mathbf{M}_{21}" not in tex


def test_solved_forms_have_positive_leading_denominators() -> None:
    for path in (p for p in SYSTEMS if p.stem in ("cart_pole", "rolling_disk_pendulum", "rolling_disk_pendulum_multiplier", "atwood_machine_multiplier")):
        model = model_from(path)
        try:
            solved = text.emit(model, "solved")
        except DerivationError:
            continue
        assert "/(-" not in solved and "*(-" not in solved.split("/")[-1], (path.stem, solved)
    m, big_m, c = sp.symbols("m M c", positive=True)
    flipped = positive_denominator((c - m) / (-big_m + m * sp.cos(c) ** 2 - m))
    assert sp.simplify(flipped - (c - m) / (-big_m + m * sp.cos(c) ** 2 - m)) == 0
    assert not sp.fraction(flipped)[1].as_ordered_terms()[0].could_extract_minus_sign()


def test_hamiltonian_common_factors_pulled_out() -> None:
    g, length, m, phi, theta = sp.symbols("g l m phi theta")
    h = -g * length * m * (sp.cos(phi) + sp.cos(theta)) - g * length * m * sp.cos(theta)
    assert tidy(h) == -g * length * m * (sp.cos(phi) + 2 * sp.cos(theta))
    model = model_from(next(p for p in SYSTEMS if p.stem == "double_pendulum"))
    assert "-g*l*m*(cos(phi) + 2*cos(theta))" in report.info_text(model, info(model))


def _nested_fractions(tex: str) -> list[str]:
    """Each `\\frac` argument that holds another `\\frac` (a fraction at script size)."""
    found = []
    for match in re.finditer(r"\\frac\{", tex):
        depth, end = 1, match.end()
        for _ in range(2):
            while depth and end < len(tex):
                depth += {"{": 1, "}": -1}.get(tex[end], 0)
                end += 1
            depth, end = (1, end + 1) if tex.startswith("{", end) else (0, end)
        if "\\frac{" in tex[match.end() : end]:
            found.append(tex[match.start() : end])
    return found


@pytest.mark.parametrize("name", ["kepler", "charged_particle_magnetic", "harmonic_oscillator", "damped_oscillator_rayleigh"])
def test_hamiltonian_has_no_fraction_inside_a_fraction(name: str, models: dict[str, Model]) -> None:
    model = models[f"systems-{name}"]
    tex = report.info_latex(model, info(model))
    assert not _nested_fractions(tex), _nested_fractions(tex)
    hamiltonian = info(model).hamiltonian
    assert hamiltonian is not None and sp.simplify(tidy(hamiltonian) - hamiltonian) == 0


def test_a_product_of_several_long_sums_is_broken_in_each_and_signs_combine() -> None:
    """A product of three long sums (what oriented bodies give, unexpanded) breaks inside every
    sum, not only the widest, so no line is wider than an article; and a term whose own factors
    print a minus never shows `- -`."""
    from lagrange_cli.emit import layout

    a, b, c = (sp.symbols(f"{name}_alpha0:9") for name in ("x", "y", "z"))
    theta = sp.Symbol("theta")
    product = sp.Mul(sp.Add(*(s * sp.cos(theta) for s in a)), sp.Add(*(s * sp.sin(theta) for s in b)), sp.Add(*(s**2 for s in c)), evaluate=False)
    for expr in (product, -product, sp.Symbol("m") - product * sp.Symbol("w")):
        parts = layout.pieces(expr, sp.latex, layout.LINE_WIDTH)
        text = layout.lines(parts, layout.LINE_WIDTH, layout.LINE_WIDTH - layout.QUAD)
        assert len(text) > 2
        assert all(layout.width(line) <= 345.0 / layout.UNIT_PT for line in text), [round(layout.width(line)) for line in text]  # an article's \\linewidth
        assert not any("- -" in line or "+ -" in line for line in text)
