"""Every derived model is validated before anything else sees it, and no file makes the frontend
or the deriver work without bound.

- Objects that differentiation, substitution and float arithmetic create (DiracDelta, zoo,
  Piecewise, LambertW, re/im, Subs of a general function, floats out of double range) are
  refused with a `SpecError` at the entry of the file they come from.
- Powers, products and literals that would explode are refused at parse time or kept unexpanded,
  measured in terms and operations, never in time.
- The `simulate:` and `initial:` settings are checked against documented ranges when the file is read.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from math import comb

import pytest
import sympy as sp

from lagrange_cli import algebra, derive, spec, validate
from lagrange_cli.errors import Diagnostic, SpecError

from .conftest import ROOT
from .limits import DEADLOCK

LINE = "coordinates: [x, y]\nparameters: {m: 1.0, k: 2.0}\nparticles:\n  p: {mass: m, position: [x, y]}\n"
ONE = "coordinates: [x]\nparameters: {m: 1.0}\nparticles:\n  p: {mass: m, position: [x]}\n"


def refused(text: str) -> Diagnostic:
    """The first problem `parse` + `derive` report for `text` (which must be refused)."""
    with pytest.raises(SpecError) as caught:
        derive.derive(spec.parse(text, "sys.yaml"))
    return caught.value.diagnostics[0]


def position(text: str, anchor: str) -> tuple[int, int]:
    """1-based line and column of the first `anchor` in `text`."""
    index = text.index(anchor)
    return text.count("\n", 0, index) + 1, index - (text.rfind("\n", 0, index) + 1) + 1


# -- class 3: objects made after parsing -----------------------------------------------------------

MADE_AFTER_PARSING = [
    ("sign-in-potential", LINE + "potential: k*sign(x)*x**3 + k*sign(x)\n", "k*sign", "derivative of the potential with respect to x contains DiracDelta(x)", "differentiable"),
    ("derivative-of-abs", LINE + "potential: diff(Abs(x), x)\n", "diff(Abs", "DiracDelta(x) (from the derivative of sign/Abs)", "sqrt(x**2)"),
    ("abs-in-position", ONE.replace("position: [x]", "position: [Abs(x)]"), "[Abs(x)]", "second derivative of the position of particle 'p' with respect to x contains DiracDelta(x)", "differentiable"),
    ("sign-of-time-in-position", ONE.replace("position: [x]", "position: [x*sign(t)]"), "[x*sign", "with respect to t contains DiracDelta(t)", "differentiable"),
    ("sign-in-kinetic", LINE + "kinetic: sign(x)*x_dot**2\n", "sign(x)*x_dot", "'kinetic' with respect to x contains DiracDelta(x)", "differentiable"),
    ("kept-constraint-with-abs", LINE + "constraints:\n  c: y = Abs(x)\n", "y = Abs", "constraint 'c' with respect to x contains DiracDelta(x)", "differentiable"),
    ("velocity-constraint-with-sign", LINE + "constraints:\n  c: y_dot = sign(x)*x_dot\n", "y_dot = sign", "constraint 'c' with respect to x contains DiracDelta(x)", "differentiable"),
    (
        "general-function-at-compound-argument",
        "coordinates: [x]\nfunctions: [U]\nparticles:\n  p: {mass: 1, position: [U(2*x)]}\n",
        "[U(2*x)]",
        "the derivative of 'U' at a compound argument (2*x)",
        "a function with `arguments` and a `definition`",
    ),
    (
        "definition-with-sign",
        "coordinates: [x]\nfunctions:\n  f: {arguments: [u], definition: 1 + sign(u)*u**2}\nparticles:\n  p: {mass: 1, position: [x]}\nkinetic: f(x)*x_dot**2\n",
        "1 + sign(u)",
        "the derivative of the definition of 'f' with respect to u contains DiracDelta(u)",
        "differentiable",
    ),
    ("zero-to-a-variable-power", LINE + "forces:\n  generalized: {x: 0**x}\n", "0**x", "zero to a variable power", "a non-zero base"),
    ("overflowing-product", ONE.replace("mass: m", "mass: 1e300*1e300"), "1e300*", "overflows double precision", "between 1e-300 and 1e300"),
    ("underflowing-product", ONE.replace("mass: m", "mass: 1e-200*1e-200"), "1e-200*", "underflows to 0", "between 1e-300 and 1e300"),
    ("underflowing-product-with-symbol", ONE.replace("mass: m", "mass: m*1e-200*1e-200"), "m*1e-200", "underflows to 0", "between 1e-300 and 1e300"),
    ("underflowing-function-value", ONE.replace("position: [x]", "position: ['exp(1 - 1e300) + x']"), "exp(1", "this number underflows to 0", "between 1e-300 and 1e300"),
    ("underflowing-literal", ONE.replace("m: 1.0", "m: 1e-400"), "1e-400", "number 1e-400 underflows to 0", "between 1e-300 and 1e300"),
    ("mass-vanishing-in-doubles", ONE.replace("mass: m", "mass: m*exp(-800)"), "m*exp(-800)", "the mass of 'p' is written non-zero (m*exp(-800)) but is 0 in double precision", "between 1e-300"),
    (
        "inertia-vanishing-in-doubles",
        "coordinates: [x]\nbodies:\n  b: {mass: 1, position: [0], inertia: exp(-750), angular_velocity: x_dot}\n",
        "exp(-750)",
        "the inertia of 'b' is written non-zero",
        "between 1e-300",
    ),
    ("overflowing-literal", ONE.replace("mass: m", "mass: 1e400"), "1e400", "number is not finite", "finite"),
    ("zero-to-a-negative-power", LINE + "potential: 0**-1\n", "0**-1", "zero to a non-positive power", "a defined power"),
    ("zoo-by-name", LINE + "potential: zoo*x\n", "zoo", "unknown name 'zoo'", "a coordinate"),
    ("power-overflowing", LINE + "potential: (3*x)**1000\n", "(3*x)", "overflows double precision", "between 1e-300 and 1e300"),
]


@pytest.mark.parametrize(("text", "anchor", "says", "expected"), [c[1:] for c in MADE_AFTER_PARSING], ids=[c[0] for c in MADE_AFTER_PARSING])
def test_objects_made_after_parsing_are_refused_at_their_entry(text: str, anchor: str, says: str, expected: str) -> None:
    problem = refused(text)
    assert problem.span is not None and problem.span.file == "sys.yaml"
    assert (problem.span.line, problem.span.column) == position(text, anchor), problem.render()
    assert says in problem.message, problem.render()
    assert expected in problem.expected, problem.render()


def test_a_defined_function_at_a_compound_argument_is_still_derived() -> None:
    """Subs of a function with a definition is fine: numeric code writes the definition out."""
    text = "coordinates: [x]\nparameters: {m: 1.0}\nfunctions:\n  U: {arguments: [s], definition: s**2}\nparticles:\n  p: {mass: m, position: [x]}\npotential: U(2*x)\n"
    model = derive.derive(spec.parse(text, "sys.yaml"))
    assert model.forcing[0].has(sp.Subs)
    assert sp.simplify(model.with_definitions().forcing[0] + 8 * model.q[0]) == 0


@pytest.mark.parametrize(
    "node",
    [
        sp.LambertW(sp.Symbol("x")),
        sp.Piecewise((sp.Symbol("x"), sp.Symbol("x") > 0), (0, True)),
        sp.re(sp.Symbol("x")),
        sp.im(sp.Symbol("x")),
        sp.arg(sp.Symbol("x")),
        sp.Heaviside(sp.Symbol("x")),
        sp.DiracDelta(sp.Symbol("x")),
        sp.nan,
        sp.zoo,
        sp.oo,
        sp.I * sp.Symbol("x"),
        sp.Float("1e-400"),
        sp.Float("1e400"),
        sp.CRootOf(sp.Symbol("x") ** 5 + sp.Symbol("x") + 1, 0),
        sp.Derivative(sp.Function("U")(2 * sp.Symbol("x")), sp.Symbol("x")),
        sp.Subs(sp.Derivative(sp.Function("U")(sp.Symbol("s")), sp.Symbol("s")), sp.Symbol("s"), 2 * sp.Symbol("x")),
        sp.Derivative(sp.sign(sp.Symbol("x")), sp.Symbol("x")),
        sp.Symbol("x") ** 20000,
    ],
    ids=str,
)
def test_the_validator_refuses_every_kind_of_foreign_node(node: sp.Basic) -> None:
    """However the node got there, a model holding it is refused with the file's name; an
    expression of allowed nodes passes."""
    model = derive.derive(spec.parse(LINE, "sys.yaml"))
    x = model.q[0]
    assert validate.refusal(sp.sin(x) + model.q[1] ** 3 / 7 + sp.Float(2.5) * sp.Function("U")(x) + sp.Derivative(sp.Function("U")(x), x)) is None
    assert validate.refusal(node + x) is not None
    broken = dataclasses.replace(model, potential=model.potential + node, energy=model.energy + node)
    with pytest.raises(SpecError) as caught:
        validate.validate(broken, derive.sources(spec.parse(LINE, "sys.yaml")), (*model.q, *model.qd, model.t))
    assert "sys.yaml" in str(caught.value) and "which the equations cannot use" in str(caught.value)


def test_validation_reads_every_part_of_the_model() -> None:
    """A refused node anywhere (jacobians, biases, eliminated solutions, definitions ...) is found."""
    model = derive.derive(spec.parse(LINE + "constraints:\n  c: x = y**2\nexact: {x: cos(t)}\n", "sys.yaml"))
    parts = [expr for _, expr in validate.model_parts(model)]
    row = model.constraints[0]
    for expr in (model.mass_matrix[1, 1], model.forcing[0], model.kinetic, model.energy, *row.jacobian, row.acceleration_bias, model.exact["x"]):
        assert any(expr == p for p in parts)


# -- class 6: bounded work ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "expr",
    ["(a + b)**2*(c + d)", "(a + b + c)**3", "(a + b)*(c + d)*(a - d)", "sin(a + b)*(a + c)**2", "(a + b)**2 + (c + d)**3", "1/(a + b)**2"],
)
def test_the_expansion_estimate_is_an_upper_bound(expr: str) -> None:
    value = sp.sympify(expr)
    assert algebra.expansion_size(value) >= len(sp.Add.make_args(sp.expand(value)))


@pytest.mark.parametrize(
    ("expr", "terms"),
    [("(x + y + 1)**200", None), ("(a + b)**30*(c + d)**30", None), ("(a + b)**6", 7), ("(a + b + c)**4", comb(6, 2)), ("*".join(f"(a + {i})" for i in range(1, 13)), None)],
)
def test_explosive_expansions_are_recognised_before_expanding(expr: str, terms: int | None) -> None:
    """Counted, not timed: an expansion beyond MAX_TERMS terms (or a power of a sum above 6) is never started."""
    value = sp.sympify(expr)
    if terms is None:
        assert not algebra.expandable(value)
        assert algebra.expand_bounded(value) == value
    else:
        assert algebra.expansion_size(value) == terms and algebra.expandable(value)


@pytest.mark.parametrize(
    "extra",
    [
        "potential: (x + y + 1)**200\n",
        "kinetic: (x + y + 1)**200*x_dot**2\n",
        "potential: (x + y)**30*(x - y + 1)**30\n",
        "kinetic: x_dot*y_dot*" + "*".join(f"(x + y + {i})" for i in range(40)) + "\n",
        "constraints:\n  c: (x + y + 1)**30*(x - y)**30 = 1\n",
    ],
    ids=["power-in-potential", "power-in-kinetic", "product-of-powers", "product-of-forty-sums", "kept-constraint"],
)
def test_explosive_expressions_derive_unexpanded(extra: str) -> None:
    """The equations keep the powers and products as written: their size stays that of the input."""
    model = derive.derive(spec.parse(LINE + extra, "sys.yaml"))
    parts = [expr for _, expr in validate.model_parts(model)]
    # differentiating a product of 40 sums makes 40 x 40 factors (quadratic); expanding it would make 2**40 terms
    assert max(sp.count_ops(p) for p in parts) < 50_000


@pytest.mark.parametrize(
    ("expression", "says"),
    [
        ("x**(10**9)", "exponent 1000000000 is too large"),
        ("2**2**2**2**2*x", "exponent 65536 is too large"),
        ("123456789012345678901234567890123456789012345*x", "integer literal is too long"),
        ("-" * 3990 + "x", "nested too deeply"),
        ("(" * 5000 + "x" + ")" * 5000, "characters long"),
        ("-(" * 150 + "x" + ")" * 150, "nested too deeply"),
        ("sin(" * 60 + "x" + ")" * 60, "nested too deeply"),
    ],
    ids=["huge-exponent", "exponent-tower", "huge-integer", "unary-minus-chain", "parentheses-too-long", "nested-negations", "nested-calls"],
)
def test_huge_and_deep_expressions_are_refused_at_parse_time(expression: str, says: str) -> None:
    text = LINE + f"potential: '{expression}'\n"
    problem = refused(text)
    assert says in problem.message and problem.span is not None and problem.span.line == 5


# -- simulate and initial settings -----------------------------------------------------------------

BAD_SETTINGS = [
    ("t_end: 1e300", "'simulate.t_end' is 1e+300, outside the allowed range", "from 1e-09 to 1e+09"),
    ("t_end: 5e-324", "'simulate.t_end' is 4.94066e-324, outside the allowed range", "from 1e-09 to 1e+09"),
    ("t_end: -1", "'simulate.t_end' is -1, outside the allowed range", "from 1e-09"),
    ("t_end: 0", "'simulate.t_end' is 0, outside the allowed range", "from 1e-09"),
    ("t_end: .nan", "must be a finite real number", "a number"),
    ("t_end: .inf", "must be a finite real number", "a number"),
    ("t_end: soon", "must be a number, got 'soon'", "a number"),
    ("step: 1e-300", "'simulate.step' is 1e-300, outside the allowed range", "from 1e-12"),
    ("samples: 1e12", "'simulate.samples' is 1e+12, outside the allowed range", "from 2 to 1e+06"),
    ("samples: 2.5", "'simulate.samples' must be a whole number", "a whole number"),
    ("samples: 1", "'simulate.samples' is 1, outside the allowed range", "from 2"),
    ("rtol: 1e-20", "'simulate.rtol' is 1e-20, outside the allowed range", "100 machine epsilons"),
    ("atol: -1e-9", "'simulate.atol' is -1e-09, outside the allowed range", "the absolute tolerance"),
    ("method: RK99", "unknown method 'RK99'", "RK45"),
    ("{t_end: 1000, step: 1e-6}", "would take 1e+09 steps", "at most 1e+08 steps"),
    ("{step: 1e-8}", "would take 1e+09 steps to reach t_end = 10", "at most 1e+08 steps"),
]


@pytest.mark.parametrize(("setting", "says", "expected"), BAD_SETTINGS, ids=[s[0] for s in BAD_SETTINGS])
def test_bad_simulate_settings_are_refused_where_written(setting: str, says: str, expected: str) -> None:
    block = f"simulate: {setting}\n" if setting.startswith("{") else f"simulate:\n  {setting}\n"
    text = ONE + block
    with pytest.raises(SpecError) as caught:
        spec.parse(text, "sys.yaml")
    problem = caught.value.diagnostics[0]
    assert says in problem.message and expected in problem.expected, problem.render()
    key = "step: " if setting.startswith("{") else setting.split(": ")[0] + ": "
    line, column = position(text, "simulate:" if setting.startswith("{") else setting)
    column = (text.splitlines()[line - 1].index(key) + 1) if setting.startswith("{") else column
    assert problem.span is not None and (problem.span.line, problem.span.column) == (line, column + len(key)), problem.render()


def test_good_simulate_settings_are_kept() -> None:
    parsed = spec.parse(ONE + "simulate: {t_end: 20, step: 0.01, samples: 500, method: rk45, rtol: 1e-9, atol: 1e-12}\n", "sys.yaml")
    assert dict(parsed.simulate) == {"t_end": 20.0, "step": 0.01, "samples": 500, "method": "RK45", "rtol": 1e-9, "atol": 1e-12}


@pytest.mark.parametrize("value", [".inf", "-.inf", ".nan", "1e300*1e300", "1e999", "log(0)"])
def test_initial_values_must_be_finite(value: str) -> None:
    text = ONE + f"initial: {{x: {value}}}\n"
    with pytest.raises(SpecError) as caught:
        spec.parse(text, "sys.yaml")
    assert caught.value.diagnostics[0].span is not None and caught.value.diagnostics[0].span.line == 5


# -- through the command line ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("extra", "anchor", "says"),
    [("potential: k*sign(x)\n", "k*sign", "DiracDelta(x)"), ("simulate: {t_end: 1e300}\n", "1e300", "outside the allowed range")],
    ids=["dirac-delta", "t-end"],
)
def test_the_cli_reports_located_errors_without_a_traceback(tmp_path: object, extra: str, anchor: str, says: str) -> None:
    from pathlib import Path

    folder = Path(str(tmp_path))
    text = LINE + extra
    path = folder / "sys.yaml"
    path.write_text(text)
    result = subprocess.run([sys.executable, "-m", "lagrange_cli", "derive", str(path)], capture_output=True, text=True, cwd=ROOT, timeout=DEADLOCK)
    line, column = position(text, anchor)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr and result.stdout == ""
    assert result.stderr.startswith(f"{path}:{line}:{column}: error: ") and says in result.stderr


# -- the size of a derivation ---------------------------------------------------------------------


def test_the_input_and_the_equations_are_counted_before_the_slow_steps(monkeypatch: pytest.MonkeyPatch) -> None:
    """A file whose derivation would be too large is refused by counting terms and factors: the
    file's expressions (each times the coordinates in it) before differentiating, the equations
    before they are converted to sympy. The bundled systems are far below both bounds."""
    text = LINE + "potential: k*(x - y)**4 + sin(x*y)\n"
    system = spec.parse(text, "sys.yaml")
    work = derive.input_work(system)
    assert 0 < work < derive.MAX_INPUT_WORK / 100
    monkeypatch.setattr(derive, "MAX_INPUT_WORK", work - 1)
    with pytest.raises(SpecError, match=r"the file's expressions.*amount to more than"):
        derive.derive(system)
    monkeypatch.setattr(derive, "MAX_INPUT_WORK", work)
    monkeypatch.setattr(derive, "MAX_EQUATION_NODES", 20)
    with pytest.raises(SpecError, match="the equations of motion amount to more than 20 terms and factors"):
        derive.derive(system)


def test_the_tree_size_count_stops_at_its_limit() -> None:
    big = sp.Add(*(sp.Symbol(f"a{i}") * sp.Symbol(f"b{i}") for i in range(1000)))
    assert derive.tree_size(big) == 1 + 3 * 1000
    assert derive.tree_size(big, 50) <= 51 + 3


def test_too_many_coordinates_are_refused_where_listed() -> None:
    names = ", ".join(f"q{i}" for i in range(spec.MAX_COORDINATES + 1))
    with pytest.raises(SpecError) as caught:
        spec.parse(f"coordinates: [{names}]\n", "sys.yaml")
    problem = caught.value.diagnostics[0]
    assert f"lists {spec.MAX_COORDINATES + 1} coordinates" in problem.message and problem.span is not None and (problem.span.line, problem.span.column) == (1, 14)


def test_a_mass_matrix_that_is_not_real_at_random_points_gets_no_verdict() -> None:
    """sqrt of a negative at the random points of the invertibility check: other points are tried,
    then no verdict (the numeric run reports where it fails), never a symengine RuntimeError."""
    model = derive.derive(spec.parse(LINE + "kinetic: 'sqrt(atan((sin(x_dot) - 2)/x_dot))*x_dot**2'\n", "sys.yaml"))
    matrix = algebra.augmented(model)[0]
    assert algebra.pivot_ratio(matrix, model) == 1.0
    algebra.check_invertible(model)


def test_a_mass_of_huge_constants_is_checked_without_sympy_evaluating_them() -> None:
    """Putting parameter values into atan(exp(csc(sinh(1e300 - k)))) made sympy's evalf recurse
    without end; the written constants are evaluated bottom-up in floats instead."""
    model = derive.derive(spec.parse(ONE.replace("mass: m", "mass: 'atan(exp(csc(sinh(1e300 - m))))'"), "sys.yaml"))
    assert model.mass_matrix[0, 0].has(sp.sinh)


@pytest.mark.parametrize(("potential", "force"), [("k*sign(x)*x", "k*sign(x)"), ("k*sign(x)*x**2/2", "k*x*sign(x)"), ("k*Abs(x)", "k*sign(x)")])
def test_a_delta_times_what_vanishes_there_is_zero(potential: str, force: str) -> None:
    """sign(x)*x is |x|: its derivative's x DiracDelta(x) term is 0, so the potential is accepted."""
    model = derive.derive(spec.parse(LINE + f"potential: {potential}\n", "sys.yaml"))
    names = {str(s): s for s in model.forcing[0].free_symbols}
    assert not model.forcing[0].has(sp.DiracDelta)
    assert sp.expand(model.forcing[0] + sp.sympify(force, locals=names)) == 0
