"""Functions with a numeric definition (`functions: {U: {arguments: [s], definition: -k/s}}`):
read and checked like every other key, kept general in the equations, written out where
numbers are needed (`derive --python`, `simulate`)."""

from __future__ import annotations

import json
import math
import random
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from typer.testing import CliRunner

from lagrange_cli import spec
from lagrange_cli.cli import app
from lagrange_cli.emit import python
from lagrange_cli.errors import SpecError
from lagrange_cli.numeric import compile, simulate

from .conftest import ROOT
from .helpers import load_module, model_from, model_of
from .test_bad_input import Bad, assert_located, derive_bad, position

runner = CliRunner()
CENTRAL = ROOT / "systems" / "central_potential.yaml"
DEFINED = "functions:\n  U: {arguments: [s], definition: -k/s, description: the potential energy at distance s from the centre}\n"


pytestmark = pytest.mark.usefixtures("private_cache")


def undefined_copy(folder: Path) -> Path:
    """The bundled central potential with U declared the old way, `functions: [U]`, under the same file name."""
    text = CENTRAL.read_text()
    assert DEFINED in text
    path = folder / CENTRAL.name
    path.write_text(text.replace(DEFINED, "functions: [U]\n"))
    return path


# -- reading --------------------------------------------------------------------------------------

SPRING = """\
coordinates: [x]
parameters: {m: 1.0, k: 2.0}
particles:
  bob: {mass: m, position: [x]}
"""


def test_map_form_gives_arguments_and_definition() -> None:
    system = spec.parse(SPRING + "functions:\n  V:\n    arguments: [s]\n    definition: k*s**2/2 + k*s**4\npotential: V(x)\n")
    s, k = sp.symbols("s k")
    assert system.functions == ("V",)
    assert system.definitions["V"] == sp.Lambda((s,), k * s**2 / 2 + k * s**4)
    assert system.potential == sp.Function("V")(sp.Symbol("x"))  # the equations keep the general V


def test_list_form_still_declares_undefined_functions() -> None:
    system = spec.parse(SPRING + "functions: [V, W]\npotential: V(x) + W(x, x)\n")
    assert system.functions == ("V", "W") and not system.definitions


def test_map_form_without_definition_checks_the_calls_only() -> None:
    system = spec.parse(SPRING + "functions: {V: {arguments: [s]}}\npotential: V(x)\n")
    assert system.functions == ("V",) and not system.definitions
    with pytest.raises(SpecError, match="'V' takes 1 argument, got 2"):
        spec.parse(SPRING + "functions: {V: {arguments: [s]}}\npotential: V(x, x)\n")


def test_an_argument_may_repeat_a_coordinate_name() -> None:
    """Arguments are local to the definition, so `arguments: [x]` is the natural way to write it."""
    model = model_of(SPRING + "functions: {V: {arguments: [x], definition: k*x**2/2}}\npotential: V(2*x)\n")
    x, k = sp.symbols("x k")
    assert sp.simplify(model.with_definitions().potential - 2 * k * x**2) == 0


def test_with_definitions_writes_out_calls_and_derivatives() -> None:
    model = model_from(CENTRAL)
    r, k, m, theta_dot = sp.symbols("r k m theta_dot")
    assert model.forcing[0].has(sp.Derivative)
    numeric = model.with_definitions()
    assert sp.simplify(numeric.forcing[0] - (m * r * theta_dot**2 - k / r**2)) == 0
    assert not numeric.energy.has(sp.Function("U")) and not numeric.definitions
    assert model.with_definitions() is numeric and numeric.with_definitions() is numeric  # once per model


# -- bad input --------------------------------------------------------------------------------------

CASES = [
    Bad(
        "unknown-function-key",
        SPRING + "functions:\n  V: {arguments: [s], defintion: k*s**2}\npotential: V(x)\n",
        ("defintion", 0),
        "unknown key 'defintion' in function 'V'",
        "did you mean 'definition'?",
    ),
    Bad("missing-arguments", SPRING + "functions:\n  V: {definition: k*s**2}\npotential: V(x)\n", ("{definition", 0), "function 'V' has no 'arguments'", "`arguments:` a list of names"),
    Bad("no-arguments", SPRING + "functions:\n  V: {arguments: [], definition: k}\npotential: V(x)\n", ("[]", 0), "function 'V' has no arguments", "a constant belongs under `parameters`"),
    Bad("functions-neither-list-nor-map", SPRING + "functions: V\npotential: x\n", ("V\n", 0), "'functions' must be a list or a map, got the text 'V'", "a map such as `{U: {arguments: [s]"),
    Bad(
        "definition-uses-a-coordinate",
        SPRING + "functions:\n  V: {arguments: [s], definition: k*x**2}\npotential: V(x)\n",
        ("x**2}", 0),
        "'x' is a coordinate, which cannot appear here",
        "the arguments of 'V' (s) or a parameter; a definition depends on nothing else",
    ),
    Bad("definition-uses-time", SPRING + "functions:\n  V: {arguments: [s], definition: k*s*t}\npotential: V(x)\n", ("t}", 0), "'t' is time, which cannot appear here", "`V(..., t)`"),
    Bad(
        "definition-uses-a-velocity",
        SPRING + "functions:\n  V: {arguments: [s], definition: s*x_dot}\npotential: V(x)\n",
        ("x_dot", 0),
        "'x_dot' is a velocity, which cannot appear here",
        "the arguments of 'V'",
    ),
    Bad(
        "definition-uses-an-unknown-name",
        SPRING + "functions:\n  V: {arguments: [s], definition: q*s**2}\npotential: V(x)\n",
        ("q*s", 0),
        "unknown name 'q'",
        "the arguments of 'V' (s) or a parameter",
    ),
    Bad(
        "definition-calls-a-declared-function",
        SPRING + "functions:\n  V: {arguments: [s], definition: W(s)}\n  W: {arguments: [s], definition: s}\npotential: V(x)\n",
        ("W(s)}", 0),
        "'W' is a declared function, which cannot appear here",
        "the arguments of 'V'",
    ),
    Bad(
        "definition-syntax",
        SPRING + "functions:\n  V:\n    arguments: [s]\n    definition: k*s**2 +\npotential: V(x)\n",
        ("k*s**2 +", len("k*s**2 +")),
        "invalid expression syntax",
        "Python/SymPy syntax",
    ),
    Bad(
        "call-with-too-many-arguments",
        SPRING + "functions:\n  V: {arguments: [s], definition: k*s**2}\npotential: k*V(x, x)\n",
        ("V(x, x)", 0),
        "'V' takes 1 argument, got 2",
        "1 argument, as declared under `functions`",
    ),
    Bad(
        "call-with-too-few-arguments",
        SPRING + "functions:\n  V: {arguments: [s, u], definition: k*s*u}\nexpect:\n  equations: [m*x_ddot = -V(x)]\npotential: V(x, x)\n",
        ("V(x)]", 0),
        "'V' takes 2 arguments, got 1",
        "2 arguments, as declared under `functions`",
    ),
    Bad(
        "argument-hides-a-parameter",
        SPRING + "functions:\n  V: {arguments: [k], definition: k**2}\npotential: V(x)\n",
        ("k]", 0),
        "argument 'k' of 'V' is also a parameter, which it would hide in the definition",
        "another name for the argument",
    ),
    Bad("argument-named-t", SPRING + "functions:\n  V: {arguments: [t], definition: k}\npotential: V(x)\n", ("t]", 0), "'t' is reserved and cannot be a function argument", "`t` is time"),
    Bad("argument-twice", SPRING + "functions:\n  V: {arguments: [s, s], definition: s}\npotential: V(x, x)\n", ("s]", 0), "'s' is already declared as a function argument", "each name declared once"),
    Bad(
        "function-named-like-a-parameter", SPRING + "functions:\n  k: {arguments: [s], definition: s}\npotential: x\n", ("k: {", 0), "'k' is already declared as a parameter", "each name declared once"
    ),
]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_function_is_reported_in_place(tmp_path: Path, case: Bad) -> None:
    stderr, path = derive_bad(tmp_path, case.text)
    lines = assert_located(stderr, path, case.text, *position(case.text, *case.at))
    assert case.says in lines[0]
    expected = next(item for item in lines if item.startswith("  expected: "))
    assert case.expected in expected
    assert stderr.count(": error: ") == 1, stderr


# -- symbolic output keeps the general U --------------------------------------------------------------


@pytest.mark.parametrize(
    "command",
    [["derive"], ["derive", "--latex"], ["derive", "--latex", "--standalone"], ["derive", "--form", "matrix"], ["derive", "--form", "solved"], ["info"]],
    ids=lambda c: "-".join(c),
)
def test_symbolic_output_is_that_of_the_undefined_function(tmp_path: Path, command: list[str]) -> None:
    defined = runner.invoke(app, [*command, str(CENTRAL)])
    undefined = runner.invoke(app, [*command, str(undefined_copy(tmp_path))])
    assert defined.exit_code == 0 and undefined.exit_code == 0, defined.output + undefined.output
    assert defined.stdout == undefined.stdout and "U" in defined.stdout


def test_check_passes_with_the_general_answers() -> None:
    result = runner.invoke(app, ["check", str(CENTRAL)])
    assert result.exit_code == 0, result.output
    assert "1 file: 1 passed" in result.stdout


# -- numbers use the definition ----------------------------------------------------------------------


def test_simulate_runs_the_defined_potential_and_conserves_energy_and_angular_momentum(tmp_path: Path) -> None:
    out = tmp_path / "orbit.csv"
    result = runner.invoke(app, ["simulate", "central_potential", "--backend", "python", "--rtol", "1e-10", "--atol", "1e-12", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "energy" in result.stdout and "p_theta" in result.stdout
    data = np.genfromtxt(out, delimiter=",", names=True)
    m, k = 1.0, 1.25
    r, r_dot, theta_dot = data["r"], data["r_dot"], data["theta_dot"]
    energy = m * (r_dot**2 + r**2 * theta_dot**2) / 2 - k / r
    momentum = m * r**2 * theta_dot
    assert np.max(np.abs(energy - energy[0])) < 1e-8 and np.max(np.abs(momentum - momentum[0])) < 1e-8
    assert np.allclose(data["energy"], energy, atol=1e-12)  # the reported energy is the defined one
    # the Kepler ellipse from the file's description: r between 2/3 and 1, period 2 pi sqrt(m a^3 / k), a = 5/6
    assert r.min() == pytest.approx(2 / 3, abs=1e-3) and r.max() == pytest.approx(1.0, abs=1e-9)
    period = 2 * math.pi * math.sqrt(m * (5 / 6) ** 3 / k)
    returns = data["t"][1:][(r_dot[:-1] > 0) & (r_dot[1:] <= 0)]
    assert returns[0] == pytest.approx(period, abs=0.03)


def test_simulation_agrees_with_the_potential_written_out() -> None:
    """central_potential (U(r) with U(s) = -k/s) and kepler.yaml (-k/r written out) from the same state."""
    runs = [
        simulate(model_from(path), parameters={"k": 1.25}, initial={"r": 1.0, "theta_dot": 1.0}, t_end=10.0, samples=101, method="DOP853", backend="python", rtol=1e-11, atol=1e-12)
        for path in (CENTRAL, ROOT / "systems" / "kepler.yaml")
    ]
    assert np.max(np.abs(runs[0].y - runs[1].y)) < 1e-10


def test_symplectic_method_uses_the_definition_too() -> None:
    pytest.importorskip("numba")
    model = model_from(CENTRAL)
    gauss = simulate(model, method="symplectic", step=0.01, t_end=10.0, samples=11)
    dop = simulate(model, method="DOP853", backend="python", t_end=10.0, samples=11, rtol=1e-12, atol=1e-13)
    assert np.max(np.abs(gauss.y - dop.y)) < 1e-6
    assert abs(gauss.energy[-1] - gauss.energy[0]) < 1e-8


def test_derive_python_module_runs_with_the_definition(tmp_path: Path) -> None:
    out = tmp_path / "orbit_eom.py"
    result = runner.invoke(app, ["derive", "central_potential", "--python", "-o", str(out)])
    assert result.exit_code == 0, result.output
    module = load_module(out.read_text(), out)
    assert "Functions written out from their definitions in the file: U(s) = -k/s." in (module.__doc__ or "")
    assert module.PARAMETERS == {"m": 1.0, "k": 1.25}
    # at r = 2, moving sideways with theta_dot = 0.5: r_ddot = r theta_dot^2 - k/(m r^2)
    y = [2.0, 0.3, 0.1, 0.5]
    expected = 2.0 * 0.25 - 1.25 / 4.0
    assert module.rhs(0.0, y)[2] == pytest.approx(expected, rel=1e-14)
    assert module.forcing(y[:2], y[2:])[0] == pytest.approx(expected, rel=1e-14)  # k/(r*r), not k/r*r
    assert module.energy(y[:2], y[2:]) == pytest.approx((0.1**2 + 4 * 0.25) / 2 - 1.25 / 2, rel=1e-14)


MULTI = """\
coordinates: [x, y]
parameters: {m: 1.0, a: 0.7, b: 1.3}
particles:
  one: {mass: m, position: [x, y]}
kinetic: g(x)*y_dot**2/2
"""


def test_definitions_of_several_arguments_at_compound_arguments(tmp_path: Path) -> None:
    """f(x - y, x*y) and g(x) (in the mass matrix) against the same expressions written out."""
    functions = "functions:\n  f: {arguments: [u, v], definition: a*u**4 + b*exp(-v)*Abs(u)**3}\n  g: {arguments: [x], definition: 1 + x**2}\n"
    defined = python.emit(model_of(MULTI + functions + "potential: f(x - y, x*y)\n"))
    written = python.emit(model_of(MULTI.replace("g(x)", "(1 + x**2)") + "potential: a*(x - y)**4 + b*exp(-x*y)*Abs(x - y)**3\n"))
    one, two = load_module(defined, tmp_path / "defined.py"), load_module(written, tmp_path / "written.py")
    rng = random.Random(7)
    for _ in range(5):
        y = [rng.uniform(-1.5, 1.5) for _ in range(4)]
        assert one.rhs(0.0, y) == pytest.approx(two.rhs(0.0, y), rel=1e-12, abs=1e-12)
        assert one.energy(y[:2], y[2:]) == pytest.approx(two.energy(y[:2], y[2:]), rel=1e-12)


def test_generated_code_is_cached_by_definition() -> None:
    """Two files whose equations are the same general U(r) but whose definitions differ get different modules."""
    text = CENTRAL.read_text()
    first = model_of(text)
    second = model_of(text.replace("definition: -k/s", "definition: -k/s**2").replace("k: J*m", "k: J*m**2"))  # (k's unit follows: the file has `units`)
    assert str(first.forcing) == str(second.forcing)
    assert compile.fingerprint(first, "python", False, None) != compile.fingerprint(second, "python", False, None)


# -- no definition: the clear error stays --------------------------------------------------------------


@pytest.mark.parametrize("command", [["derive", "--python"], ["simulate"]], ids=["python", "simulate"])
@pytest.mark.parametrize("declaration", ["functions: [U]\n", "functions: {U: {arguments: [s]}}\n"], ids=["list", "map-without-definition"])
def test_without_a_definition_numbers_are_refused_by_name(tmp_path: Path, command: list[str], declaration: str) -> None:
    path = tmp_path / "central_potential.yaml"
    path.write_text(CENTRAL.read_text().replace(DEFINED, declaration))
    result = runner.invoke(app, [*command, str(path)])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert "U is left undefined" in result.stderr and result.stdout == ""


BEAD = """title: Bead on a curve y = H(x)
coordinates: [x, y]
parameters: {m: 1.0, g: 9.81}
functions:
  H: {arguments: [s]DEFINITION}
gravity: [0, -g]
particles:
  bead: {mass: m, position: [x, y]}
constraints:
  curve: y = H(x)
initial: {x: 0.5, y: 0.125, x_dot: 0.0, y_dot: 0.0}
simulate: {t_end: 2}
"""


def test_a_kept_constraint_through_a_defined_function_simulates(tmp_path: Path) -> None:
    """The constraint rows (and the augmented matrix checked for invertibility) hold H'(x)."""
    path = tmp_path / "bead.yaml"
    path.write_text(BEAD.replace("DEFINITION", ", definition: s**2/2"))
    result = runner.invoke(app, ["simulate", str(path), "--samples", "11"])
    assert result.exit_code == 0 and "finished: reached t = 2" in result.output, result.output


def test_the_solved_form_of_a_general_function_in_the_mass_matrix(tmp_path: Path) -> None:
    """Invertibility at a generic point gives H' and H'' generic values of their own."""
    path = tmp_path / "bead.yaml"
    path.write_text(BEAD.replace("DEFINITION", ""))
    result = runner.invoke(app, ["derive", str(path), "--form", "solved"])
    assert result.exit_code == 0 and "lambda_curve = " in result.output and "Derivative(H(x), x)" in result.output, result.output


RADIAL = """title: particle in a radial potential
coordinates: [x, y]
parameters: {m: 1.5, k: 2.0}
functions:
  U: {arguments: [s], definition: k*s**4/4}
kinetic: m*(x_dot**2 + y_dot**2)/2
potential: U(sqrt(x**2 + y**2))
initial: {x: 1.0, y: 0.5}
"""


@pytest.mark.parametrize("form", ["lagrange", "matrix", "solved", "hamilton"])
@pytest.mark.parametrize("target", ["text", "latex", "python", "c", "octave", "jax", "json"])
def test_a_defined_function_at_a_compound_argument_in_every_form_and_target(tmp_path: Path, form: str, target: str) -> None:
    """U'(sqrt(x^2 + y^2)) is a `Subs`: the solved form (symengine has no Subs) and JSON (the file syntax
    has none) once failed on it."""
    path = tmp_path / "radial.yaml"
    path.write_text(RADIAL)
    result = runner.invoke(app, ["derive", str(path), "--to", target, "--form", form])
    assert result.exit_code == 0, result.output
    if target == "json":
        document = json.loads(result.stdout)
        # written out from the definition: F = -k r^2 (x, y), which the file's parser reads back
        assert [f["text"] for f in document["forcing"]] == ["-k*x*(x**2 + y**2)", "-k*y*(x**2 + y**2)"]
    if target == "text" and form == "solved":
        assert "x_ddot = " in result.stdout and "Subs(Derivative(U(" in result.stdout
