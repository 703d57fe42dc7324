"""`eliminate`: the pairing of coordinates with constraints does not depend on the list's order,
every refusal is located at the offending entry, and solving is bounded in operations (no
`sympy.solve`/`sympy.simplify`, which can take minutes on a constraint of a few dozen operations)."""

from __future__ import annotations

import pytest
import sympy as sp

from lagrange_cli import derive, spec
from lagrange_cli.errors import Diagnostic, SpecError

BASE = """\
coordinates: [x, phi, y]
parameters: {m: 1.0, R: 0.5, I: 0.2, g: 9.81}
gravity: [0, -g]
particles:
  bob: {mass: m, position: [x, y]}
bodies:
  wheel: {mass: m, position: [x, 0], inertia: I, angular_velocity: phi_dot}
"""
# 'parabola' determines x uniquely but phi twice (phi = +-sqrt(x/R)); 'rolling' determines phi uniquely.
ORDER = BASE + "constraints:\n  parabola: x = R*phi**2\n  rolling: phi = y/R\n"

PLANE = "coordinates: [x, y]\nparameters: {m: 1.0}\nparticles:\n  p: {mass: m, position: [x, y]}\n"


def refused(text: str) -> Diagnostic:
    with pytest.raises(SpecError) as caught:
        derive.derive(spec.parse(text, "sys.yaml"))
    return caught.value.diagnostics[0]


def position(text: str, anchor: str, shift: int = 0) -> tuple[int, int]:
    index = text.index(anchor) + shift
    return text.count("\n", 0, index) + 1, index - (text.rfind("\n", 0, index) + 1) + 1


@pytest.mark.parametrize("order", ["[x, phi]", "[phi, x]"])
def test_the_order_of_the_list_does_not_matter(order: str) -> None:
    """[phi, x] used to be refused ('parabola' has two solutions for phi) where [x, phi] worked."""
    model = derive.derive(spec.parse(ORDER + f"eliminate: {order}\n", "sys.yaml"))
    reference = derive.derive(spec.parse(ORDER + "eliminate: [x, phi]\n", "sys.yaml"))
    assert model.coordinates == ("y",)
    assert model.equations() == reference.equations()
    assert model.mass_matrix == reference.mass_matrix and model.forcing == reference.forcing
    assert dict(model.eliminated) == dict(reference.eliminated)
    y = model.q[0]
    R = sp.Symbol("R")
    assert sp.simplify(dict(model.eliminated)["phi"] - y / R) == 0
    assert sp.simplify(dict(model.eliminated)["x"] - y**2 / R) == 0


def test_a_constraint_with_a_unique_solution_is_preferred_to_the_first_one() -> None:
    """For phi alone: 'parabola' comes first in the file but has two solutions; 'rolling' is taken."""
    model = derive.derive(spec.parse(ORDER + "eliminate: [phi]\n", "sys.yaml"))
    assert [c.name for c in model.constraints] == ["parabola"]
    assert dict(model.eliminated)["phi"] == model.q[1] / sp.Symbol("R")


def test_the_coordinate_with_fewest_choices_goes_first() -> None:
    """x can come from 'a' or 'b', y only from 'a': taking 'a' for x first would leave y unsolvable."""
    text = "coordinates: [x, y, z]\nparameters: {m: 1.0}\nparticles:\n  p: {mass: m, position: [x, y, z]}\n"
    text += "constraints:\n  a: x + y = z\n  b: x = 2*z\neliminate: [x, y]\n"
    model = derive.derive(spec.parse(text, "sys.yaml"))
    assert model.coordinates == ("z",) and not model.constraints


EDGE_CASES = [
    ("listed-twice", ORDER + "eliminate: [x, x]\n", ("eliminate: [x, x]", 15), "'x' is listed twice in 'eliminate'", "each coordinate once"),
    ("every-coordinate", PLANE + "constraints:\n  c: y = 2*x\n  d: y = 3\neliminate: [x, y]\n", ("eliminate: [x, y]", 15), "lists every coordinate", "keep at least one coordinate"),
    ("lambert-w", PLANE + "constraints:\n  c: y = x*exp(x)\neliminate: [x]\n", ("[x]", 1), "more than one factor", "can be solved for it"),
    ("inverse-not-supported", PLANE + "constraints:\n  c: y = sinh(x)\neliminate: [x]\n", ("[x]", 1), "asinh is not one of the supported functions", "can be solved for it"),
    ("two-solutions", PLANE + "constraints:\n  c: x**2 + y**2 = 1\neliminate: [y]\n", ("[y]", 1), "has 2 solutions for 'y'", "a single solution"),
    ("degree-five", PLANE + "constraints:\n  c: x**5 + x = y\neliminate: [x]\n", ("[x]", 1), "has 5 solutions for 'x'", "a single solution"),
    ("sin-twice-a-period", PLANE + "constraints:\n  c: sin(x) = y\neliminate: [x]\n", ("[x]", 1), "sin takes each value twice", "a single solution"),
    ("abs-twice", PLANE + "constraints:\n  c: Abs(x) = y\neliminate: [x]\n", ("[x]", 1), "Abs takes each value twice", "a single solution"),
    ("solution-with-kink", PLANE + "constraints:\n  c: x = sign(y)*y**2\neliminate: [x]\n", ("[x]", 1), "contains DiracDelta(y)", "a smooth expression"),
    ("solution-with-abs", PLANE + "constraints:\n  c: x = Abs(y)\neliminate: [x]\n", ("[x]", 1), "second derivative of the solution x = Abs(y)", "a smooth expression"),
    (
        "undefined-after-substitution",
        PLANE + "potential: 1/(x - y)\nconstraints:\n  c: x = y\neliminate: [x]\n",
        ("[x]", 1),
        "turns the potential into an expression with zoo",
        "keeps every expression defined",
    ),
    (
        "repeated-constraint",
        PLANE.replace("[x, y]\n", "[x, y, z]\n", 1) + "constraints:\n  c: x = 2*y\n  d: 2*x = 4*y\neliminate: [x]\n",
        ("2*x = 4*y", 0),
        "says nothing once 'x' is eliminated",
        "remove 'd'",
    ),
    ("velocity-constraint-only", PLANE + "constraints:\n  c: x_dot = y_dot\neliminate: [y]\n", ("[y]", 1), "no holonomic constraint can be solved for 'y'", "a velocity constraint"),
]


@pytest.mark.parametrize(("text", "at", "says", "expected"), [c[1:] for c in EDGE_CASES], ids=[c[0] for c in EDGE_CASES])
def test_edge_cases_are_refused_at_the_entry(text: str, at: tuple[str, int], says: str, expected: str) -> None:
    problem = refused(text)
    assert problem.span is not None and problem.span.file == "sys.yaml"
    assert (problem.span.line, problem.span.column) == position(text, *at), problem.render()
    assert says in problem.message, problem.render()
    assert expected in problem.expected, problem.render()


HARD = [
    "exp(x) + exp(2*x) + exp(3*x) + exp(4*x) = y",
    "sqrt(x) + sqrt(x + 1) + sqrt(x + 2) = y",
    "log(x) + log(x + y) + log(x + 2) = y",
    "sin(x)**3 + cos(x)**2*exp(x) + x**3*tan(x) = y",
    "x*(sin(y)**7 + cos(y)**5 + tan(y)*exp(y) + log(y**2 + 1)*sin(y)**3) = y + y**3*sin(y)",
    "x**999 + x = y",
    "(x + y + 1)**30*(x - y)**30 = 1",
]


@pytest.mark.parametrize("constraint", HARD)
def test_solving_never_calls_the_unbounded_sympy_solvers(monkeypatch: pytest.MonkeyPatch, constraint: str) -> None:
    """These took from 30 s to minutes with sympy.solve and sympy.simplify; now each either
    derives or is refused, and neither of those is called at all."""

    def forbidden(*args: object, **kwargs: object) -> None:
        raise AssertionError("an unbounded sympy routine was called")

    for name in ("solve", "simplify", "nsimplify", "solveset"):
        monkeypatch.setattr(sp, name, forbidden)
    text = PLANE + f"constraints:\n  c: {constraint}\neliminate: [x]\n"
    try:
        derive.derive(spec.parse(text, "sys.yaml"))
    except SpecError as error:
        assert error.diagnostics[0].span is not None and "eliminate" in error.diagnostics[0].span.text


def test_the_number_of_solving_attempts_is_bounded(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every (coordinate, constraint) pair tried counts against MAX_SOLVES; beyond it, a clear refusal."""
    monkeypatch.setattr(derive, "MAX_SOLVES", 3)
    text = "coordinates: [a, b, c, d]\nparameters: {m: 1.0}\nparticles:\n  p: {mass: m, position: [a, b, c]}\n  q: {mass: m, position: [d]}\n"
    text += "constraints:\n  u: a*b = c*d\n  v: a = b + c*d\neliminate: [a, b]\n"
    problem = refused(text)
    assert "more than 3 attempts" in problem.message and problem.span is not None and problem.span.line == text.count("\n")


def test_a_linear_solution_is_tidied_without_simplify() -> None:
    """The bundled eliminations keep their familiar forms: y2 = l - y1 and phi = s/R."""
    text = "coordinates: [y1, y2]\nparameters: {m1: 1.0, m2: 2.0, l: 3.0, g: 9.81}\ngravity: [-g]\nparticles:\n  a: {mass: m1, position: [y1]}\n  b: {mass: m2, position: [y2]}\n"
    model = derive.derive(spec.parse(text + "constraints:\n  string: y1 + y2 = l\neliminate: [y2]\n", "sys.yaml"))
    assert dict(model.eliminated)["y2"] == sp.Symbol("l") - sp.Symbol("y1")


def test_a_constraint_undefined_at_zero_is_refused_not_a_nan_comparison() -> None:
    """atan2(0, cot(x)) has derivative 0 in x, so the constraint looks linear; solving it evaluates
    cot(0) (sympy then compares a NaN, a TypeError): a located refusal instead."""
    text = PLANE + "constraints:\n  c: 'sqrt(atan2(0, 2*cot(x))) = x'\neliminate: [x]\n"
    problem = refused(text)
    assert problem.span is not None and (problem.span.line, problem.span.column) == position(text, "[x]\n", 1)


@pytest.mark.parametrize("order", ["circle, line", "line, circle"])
def test_the_linear_constraint_is_picked_whatever_the_order(order: str) -> None:
    """Constraints [x**2 + y**2 - l**2, y - x*tan(a)], eliminate x: the circle has two solutions
    for x, the line one; in either order of the list the line is used and the circle kept."""
    rows = {"circle": "  circle: x**2 + y**2 = l**2\n", "line": "  line: y = x*tan(a)\n"}
    text = "coordinates: [x, y]\nparameters: {m: 1.0, l: 1.0, a: 0.5}\nparticles:\n  p: {mass: m, position: [x, y]}\nconstraints:\n"
    text += "".join(rows[name] for name in order.split(", ")) + "eliminate: [x]\n"
    model = derive.derive(spec.parse(text, "sys.yaml"))
    assert [c.name for c in model.constraints] == ["circle"]
    y, a = model.q[0], sp.Symbol("a")
    assert sp.simplify(dict(model.eliminated)["x"] - y / sp.tan(a)) == 0


def test_no_constraint_that_determines_the_coordinate_uniquely_is_refused() -> None:
    text = "coordinates: [x, y]\nparameters: {m: 1.0, l: 1.0}\nparticles:\n  p: {mass: m, position: [x, y]}\n"
    text += "constraints:\n  circle: x**2 + y**2 = l**2\n  other: x**2 = y + 2\neliminate: [x]\n"
    diagnostic = refused(text)
    assert "cannot eliminate 'x'" in diagnostic.message and "solutions for 'x'" in diagnostic.message
