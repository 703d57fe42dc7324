"""Text and LaTeX of big systems (issue 14): the general N-link chain (its own m_i and l_i per
link) printed from `Model.symengine` by one memoized walk, with output that is exactly the
model's equations and LaTeX that still fits the page. Work is counted (printer calls, characters
measured), never timed."""

from __future__ import annotations

import random
import re
import subprocess
from pathlib import Path

import pytest
import sympy as sp
from sympy.parsing.sympy_parser import implicit_multiplication, parse_expr, standard_transformations

from lagrange_cli.emit import common, latex, layout, text
from lagrange_cli.model import Model

from .conftest import ROOT, SYSTEMS
from .helpers import model_from, model_of
from .limits import DEADLOCK
from .test_latex_layout import PDFLATEX, needs_pdflatex, overflows


def chain(n: int) -> str:
    """The general planar n-link chain: link i has its own mass m_i and length l_i, angles from
    the downward vertical."""
    x, y, particles = [], [], []
    for i in range(1, n + 1):
        x.append(f"l{i}*sin(theta{i})")
        y.append(f"l{i}*cos(theta{i})")
        particles.append(f"  bob{i}: {{mass: m{i}, position: [{' + '.join(x)}, -({' + '.join(y)})]}}")
    names = [f"m{i}" for i in range(1, n + 1)] + [f"l{i}" for i in range(1, n + 1)]
    return (
        f"title: general {n}-link chain\ncoordinates: [{', '.join(f'theta{i}' for i in range(1, n + 1))}]\nparameters: [{', '.join(names)}, g]\ngravity: [0, -g]\nparticles:\n"
        + "\n".join(particles)
        + "\n"
    )


@pytest.fixture(scope="module")
def chains() -> dict[int, Model]:
    return {n: model_of(chain(n), f"chain_{n}.yaml") for n in (3, 6, 8)}


def _symbols(model: Model) -> dict[str, sp.Symbol]:
    found = {s.name: s for e in model.equations() for s in e.free_symbols if isinstance(s, sp.Symbol)}
    return found | {s.name: s for s in (*model.q, *model.qd, *model.qdd, *model.multipliers)}


def _agree(model: Model, parsed: list[sp.Expr], seeds: int = 3) -> None:
    """Each parsed equation equals the model's `M q_ddot - F - A^T lambda` at random points."""
    equations = model.equations()
    assert len(parsed) >= len(equations)
    symbols = sorted({s for e in equations for s in e.free_symbols} | {s for e in parsed for s in e.free_symbols}, key=str)
    for seed in range(seeds):
        rng = random.Random(seed)
        point = {s: rng.uniform(0.3, 1.7) for s in symbols}
        for mine, theirs in zip(parsed, equations, strict=False):
            a, b = complex(mine.evalf(subs=point)), complex(theirs.evalf(subs=point))
            assert abs(a - b) <= 1e-9 * max(1.0, abs(b)), (mine, theirs)


def test_text_of_the_general_chain_is_its_equations(chains: dict[int, Model]) -> None:
    model = chains[8]
    lines = text.emit(model).splitlines()
    assert len(lines) == 8 and all(line.endswith(" = 0") for line in lines)
    names = _symbols(model)
    _agree(model, [parse_expr(line.removesuffix(" = 0"), local_dict=names) for line in lines])
    # collected: the gravity terms of the first equation are one term with the sum of all masses
    first = lines[0]
    assert first.count("*sin(theta1)") == 1 and "g*l1*(m1 + m2 + m3 + m4 + m5 + m6 + m7 + m8)*sin(theta1)" in first


@pytest.mark.parametrize("path", SYSTEMS, ids=lambda p: p.stem)
def test_text_of_every_bundled_system_parses_back_to_its_equations(path: Path) -> None:
    model = model_from(path)
    names = _symbols(model)
    lines = text.emit(model).splitlines()
    parsed = [parse_expr(line.removesuffix(" = 0"), local_dict=names) for line in lines]
    for mine, theirs in zip(parsed, model.equations(), strict=False):
        assert _zero(mine - theirs), (mine, theirs)
    for mine, constraint in zip(parsed[model.n :], model.constraints, strict=True):
        assert sp.expand(mine - constraint.expr) == 0


def test_matrix_text_of_the_general_chain_is_its_matrices(chains: dict[int, Model]) -> None:
    model = chains[6]
    lines = text.emit(model, "matrix").splitlines()
    names = _symbols(model)
    start = lines.index("mass matrix =") + 1
    mass = [[parse_expr(x, local_dict=names) for x in line.strip()[1:-1].split(", ")] for line in lines[start : start + 6]]
    forcing = [parse_expr(line.strip()[1:-1], local_dict=names) for line in lines[start + 7 : start + 13]]
    rows = [sum((mass[i][j] * model.qdd[j] for j in range(6)), sp.Integer(0)) - forcing[i] for i in range(6)]
    _agree(model, rows)


def _tex_to_sympy(tex: str, model: Model) -> list[sp.Expr]:
    """The rows `... &= 0` of the Lagrange-form LaTeX, read back (the subset the chain uses:
    names, sums, products, powers, parentheses, sin and cos) in one pass over its tokens."""
    known = latex.names(model).symbols
    by_tex = {tex_name: f" S{k} " for k, tex_name in enumerate(known.values())}
    symbols = {f"S{k}": symbol for k, symbol in enumerate(known)}
    structure = {r"\cos{\left(": " cos(", r"\sin{\left(": " sin(", r"\right)}": ")", r"\left(": "(", r"\right)": ")", "^{": "**(", "}": ")"}
    junk = [r"\begin{align*}", r"\end{align*}", r"\begin{aligned}[b]", r"\end{aligned}", r"\left.", r"\right.", r"\quad", "{}", "&", "\\\\"]
    tokens = {**dict.fromkeys(junk, " "), **structure, **by_tex}
    pattern = re.compile("|".join(re.escape(t) for t in sorted(tokens, key=len, reverse=True)))
    body = re.sub(r"^%.*\n", "", tex, flags=re.M)
    rows = []
    for row in re.split(r"&= 0", body)[:-1]:
        python = pattern.sub(lambda match: tokens[match.group(0)], row)
        assert "\\" not in python and "{" not in python, python
        rows.append(parse_expr(" ".join(python.split()), local_dict={**symbols, "sin": sp.sin, "cos": sp.cos}, transformations=(*standard_transformations, implicit_multiplication)))
    return rows


def test_latex_of_the_general_chain_is_its_equations(chains: dict[int, Model]) -> None:
    model = chains[8]
    tex = latex.emit(model)
    parsed = _tex_to_sympy(tex, model)
    assert len(parsed) == 8
    _agree(model, parsed)


@pytest.mark.latex
@needs_pdflatex
def test_latex_of_the_general_chain_fits_an_article(chains: dict[int, Model], tmp_path: Path) -> None:
    parts = {f"chain8-{form}": latex.emit(chains[8], form) for form in ("lagrange", "matrix")}
    assert all(tex.count("&= ") >= 8 for tex in parts.values())
    too_wide = {name: width for name, width in overflows(tmp_path, "chain8", parts).items() if width > 1.0}
    assert not too_wide, too_wide


class _Counting(latex.TexPrinter):
    """Counts what laying out costs: calls from the layout and characters measured."""

    from_layout = 0

    def __call__(self, expr: object) -> str:
        self.from_layout += 1
        return self.doprint(expr)


def _work(model: Model, monkeypatch: pytest.MonkeyPatch) -> tuple[int, int, int, int]:
    """(terms, printer calls, layout calls, characters measured) for the Lagrange-form LaTeX."""
    measured = 0
    width = layout.width

    def counting_width(tex: str) -> float:
        nonlocal measured
        measured += len(tex)
        return width(tex)

    monkeypatch.setattr(layout, "width", counting_width)
    printer = _Counting(latex.names(model))
    rows = common.equation_terms(model, printer.keys)
    terms = sum(len(row) for row in rows)
    space = latex.room()
    output = pieces = 0
    for row in rows:
        laid = layout.terms(row, printer, space)
        pieces += len(laid)
        output += sum(len(line) for line in layout.lines(laid, 60.0, 58.0))
    assert measured <= 4 * output, (measured, output)  # each piece measured about once
    # one call per piece, plus a few per term broken inside (its factors, the rest of the product)
    assert printer.from_layout <= pieces + 8 * terms, (printer.from_layout, pieces, terms)
    return terms, printer.calls + printer.keys.calls, printer.from_layout, measured


def test_printing_work_grows_linearly_with_the_terms(chains: dict[int, Model], monkeypatch: pytest.MonkeyPatch) -> None:
    """From 3 to 8 links the terms grow about 7x; the printer's node prints, the layout's calls
    and the characters it measures per term stay bounded (a quadratic walk, which re-prints or
    re-measures subterms per line or per term, would grow with N)."""
    small, big = _work(chains[3], monkeypatch), _work(chains[8], monkeypatch)
    (t1, calls1, layout1, chars1), (t2, calls2, layout2, chars2) = small, big
    assert t2 > 5 * t1
    assert layout1 <= 2 * t1 and layout2 <= 2 * t2  # no term is broken at these sizes
    # nodes printed per term: the mass sums are shared between entries, so this even falls
    assert calls2 / t2 <= 2 * calls1 / t1
    # characters measured per term grow only with the length of a term (O(N) masses in a sum)
    assert chars2 / t2 <= 8 / 3 * 2 * chars1 / t1


def test_each_distinct_subexpression_is_printed_once(chains: dict[int, Model]) -> None:
    model = chains[6]
    printer = text.TextPrinter()
    rows = common.equation_terms(model, printer)
    first = [printer.doprint(term) for row in rows for term in row]
    calls = printer.calls
    again = [printer.doprint(term) for row in rows for term in row]
    assert again == first and printer.calls == calls  # memoized: a second pass prints nothing


def test_common_factor_and_collected() -> None:
    from lagrange_cli._symengine import se

    a, b, c, x, y = se.symbols("a b c x y")
    assert common.common_factor(2 * a * x + 4 * a * y) == 2 * a * (x + 2 * y)
    assert common.common_factor(-a - b) == -(a + b)
    assert common.common_factor(a * b * c + a * b) == a * b * (c + 1)
    assert common.common_factor(se.Rational(3, 2) * a + b) == se.Rational(3, 2) * a + b
    assert common.common_factor(a / x + b / x**2) == (a + b / x) / x
    printer = text.TextPrinter()
    terms = common.collected(a * se.sin(x) + b * se.sin(x) + c * x + a * b, frozenset([x]), printer)
    assert [printer.doprint(t) for t in terms] == ["(a + b)*sin(x)", "c*x", "a*b"]
    assert sum(terms, se.Integer(0)).expand() == (a * se.sin(x) + b * se.sin(x) + c * x + a * b).expand()


def test_names_sort_naturally() -> None:
    from lagrange_cli._symengine import se

    masses = se.symbols("m1 m2 m10 m11 m3")
    printer = text.TextPrinter()
    assert printer.doprint(se.Add(*masses)) == "m1 + m2 + m3 + m10 + m11"
    assert latex.TexPrinter(latex.names(model_of(chain(3)))).doprint(se.Add(*masses)) == "m_{1} + m_{2} + m_{3} + m_{10} + m_{11}"


@pytest.mark.latex
@needs_pdflatex
def test_an_equation_taller_than_a_page_breaks_across_pages(chains: dict[int, Model], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """An equation of more lines than a page holds (a 30-link chain's, on an article page; here
    a 8-link chain's on a page 4 cm high) is written `0 &= ...` in environments of at most
    `BREAKABLE_LINES` lines, between which pages break: no `Overfull \\vbox` (the bottom-aligned
    block it was before cannot break and ran off the page), no `Overfull \\hbox`."""
    monkeypatch.setattr(layout, "BREAKABLE_LINES", 4)
    tex = latex.emit(chains[8])
    assert tex.count(r"\begin{aligned}") == 0 and tex.count("0 &= ") == 8 and tex.count(r"\begin{align*}") > 16
    (tmp_path / "tall.tex").write_text(tex)
    document = "\\documentclass{article}\n\\usepackage{amsmath}\n\\usepackage[textheight=4cm,paperheight=8cm]{geometry}\n\\begin{document}\n\\input{tall.tex}\n\\end{document}\n"
    (tmp_path / "main.tex").write_text(document)
    assert PDFLATEX
    result = subprocess.run([PDFLATEX, "-interaction=nonstopmode", "-halt-on-error", "main.tex"], cwd=tmp_path, capture_output=True, text=True, timeout=DEADLOCK)
    assert result.returncode == 0, result.stdout[-3000:]
    log = (tmp_path / "main.log").read_text(errors="replace")
    assert "Overfull \\vbox" not in log and not [w for w in re.findall(r"Overfull \\hbox \((\d+\.\d+)pt", log) if float(w) > 1.0]


def _zero(expr: sp.Expr) -> bool:
    """`expr` is identically 0, exactly: expanded, with every sin(x)**2 written as 1 - cos(x)**2 (the
    text merges `R*sin(x)**2 + R*cos(x)**2` into `R`)."""
    expanded = sp.expand(expr)
    if expanded == 0:
        return True

    def squared_sine(e: sp.Basic) -> bool:
        return bool(e.is_Pow and isinstance(e.base, sp.sin) and e.exp.is_Integer and e.exp >= 2)

    def rewritten(e: sp.Pow) -> sp.Expr:
        angle, exponent = e.base.args[0], int(e.exp)
        return (1 - sp.cos(angle) ** 2) ** (exponent // 2) * sp.sin(angle) ** (exponent % 2)

    return bool(sp.expand(expanded.replace(squared_sine, rewritten)) == 0)


def test_zero_knows_the_pythagorean_identity_and_nothing_more() -> None:
    x, a = sp.symbols("x a")
    assert _zero(a * sp.sin(x) ** 2 + a * sp.cos(x) ** 2 - a)
    assert not _zero(a * sp.sin(x) ** 2 + a * sp.cos(x) ** 2)


def test_pythagorean_pairs_merge_in_the_text() -> None:
    """`R*sin(x)**2 + R*cos(x)**2` is printed as `R`, also when merged terms pair again; pairs with
    different coefficients stay."""
    from lagrange_cli._symengine import se
    from lagrange_cli.emit.common import pythagorean

    a, b, x, y = se.symbols("a b x y")
    nested = se.expand((se.sin(x) ** 2 + se.cos(x) ** 2) * (se.sin(y) ** 2 + se.cos(y) ** 2) * a + b * se.sin(x) ** 2)
    assert se.Add(*pythagorean(list(se.Add.make_args(nested)))) == a + b * se.sin(x) ** 2
    unequal = a * se.sin(x) ** 2 + b * se.cos(x) ** 2
    assert se.Add(*pythagorean(list(se.Add.make_args(unequal)))) == unequal
    gimbals = text.emit(model_from(ROOT / "systems" / "gyroscope_gimbals.yaml"))
    assert "gamma)**2" not in gimbals  # the rotor angle's squares cancel in every equation
