"""State-space linearization (FORMAT.md version 2, "Linearization"): A, B, C, D about an
operating point, `linearize --about/--json/--latex/--lqr`, `expect.state_space` and the API."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from typer.testing import CliRunner

from lagrange_cli import api, statespace
from lagrange_cli.cli import app
from lagrange_cli.errors import DerivationError

from .helpers import model_of

runner = CliRunner()

CART_POLE = """\
title: Cart-pole with a force input
coordinates: [x, theta]
parameters: {M: 1.0, m: 0.1, l: 0.5, g: 9.81}
inputs:
  F: {value: 0, description: horizontal force on the cart}
outputs:
  position: x
  angle: theta
gravity: [0, -g]
particles:
  cart: {mass: M, position: [x, 0], force: [F, 0]}
  bob: {mass: m, position: [x + l*sin(theta), l*cos(theta)]}
"""


def textbook_cart_pole() -> tuple[sp.Matrix, sp.Matrix]:
    """A and B from the textbook linearized equations of the cart-pole (point mass m at distance l,
    theta from the upright, F on the cart): (M + m) x'' + m l theta'' = F, x'' + l theta'' = g theta."""
    M, m, l, g, F = sp.symbols("M m l g F")  # noqa: E741
    x, th, xd, thd, xdd, thdd = sp.symbols("x theta x_dot theta_dot x_ddot theta_ddot")
    solution = sp.solve([(M + m) * xdd + m * l * thdd - F, xdd + l * thdd - g * th], [xdd, thdd], dict=True)[0]
    state = [x, th, xd, thd]
    rates = [xd, thd, solution[xdd], solution[thdd]]
    a = sp.Matrix([[sp.diff(r, s) for s in state] for r in rates])
    b = sp.Matrix([[sp.diff(r, F)] for r in rates])
    return a, b


def test_cart_pole_a_and_b_equal_the_textbook_matrices() -> None:
    ss = statespace.state_space(model_of(CART_POLE), {})
    a, b = textbook_cart_pole()
    assert ss.symbolic["A"] is not None and ss.symbolic["B"] is not None
    assert (ss.symbolic["A"] - a).applyfunc(sp.simplify).is_zero_matrix
    assert (ss.symbolic["B"] - b).applyfunc(sp.simplify).is_zero_matrix
    assert ss.symbolic["C"] == sp.Matrix([[1, 0, 0, 0], [0, 1, 0, 0]]) and ss.symbolic["D"] == sp.zeros(2, 1)
    values = {sp.Symbol(k): v for k, v in {"M": 1.0, "m": 0.1, "l": 0.5, "g": 9.81}.items()}
    assert np.allclose(np.array(ss.numeric["A"]), np.array(a.xreplace(values), dtype=float))  # type: ignore[index]
    assert ss.state == ("x", "theta", "x_dot", "theta_dot") and ss.inputs == ("F",) and ss.outputs == ("position", "angle")
    assert ss.controllability_rank == 4


def test_hanging_equilibrium_and_outputs_with_feedthrough() -> None:
    text = CART_POLE.replace("angle: theta", "angle: theta\n  push: 2*F + x_dot")
    ss = statespace.state_space(model_of(text), {sp.Symbol("theta"): sp.pi})
    a, _ = textbook_cart_pole()
    assert sp.simplify(ss.symbolic["A"][3, 1] + a[3, 1]) == 0  # the hanging pole oscillates: the sign flips
    assert ss.symbolic["D"] == sp.Matrix([[0], [0], [2]]) and list(ss.symbolic["C"].row(2)) == [0, 0, 1, 0]
    assert ss.y0[1] == sp.pi


def test_not_an_equilibrium_says_so_with_the_residual() -> None:
    with pytest.raises(DerivationError, match=r"not an equilibrium.*\['1', '0'\].*F = 1"):
        statespace.state_space(model_of(CART_POLE), {}, {"F": 1})
    with pytest.raises(DerivationError, match="not an equilibrium"):
        statespace.state_space(model_of(CART_POLE), {sp.Symbol("theta"): sp.Rational(1, 2)})


def test_an_input_can_hold_the_operating_point() -> None:
    text = CART_POLE.replace("  bob:", "  anchor: {mass: m, position: [x, 0], force: [-x, 0]}\n  bob:")
    with pytest.raises(DerivationError):
        statespace.state_space(model_of(text), {sp.Symbol("x"): 1})
    ss = statespace.state_space(model_of(text), {sp.Symbol("x"): 1}, {"F": 1})  # F = 1 balances the spring at x = 1
    assert ss.about["x"] == 1 and ss.about["F"] == 1


def test_kept_constraint_linearizes_in_the_independent_coordinates() -> None:
    text = """\
coordinates: [x, y]
parameters: {m: 1.0, g: 9.81, l: 1.0}
inputs: [tau]
outputs: {height: y}
gravity: [0, -g]
particles:
  bob: {mass: m, position: [x, y], force: [tau, 0]}
constraints:
  rod: x**2 + y**2 = l**2
"""
    ss = statespace.state_space(model_of(text), {sp.Symbol("y"): -1})
    assert ss.state == ("x", "x_dot")
    assert np.allclose(np.array(ss.numeric["A"]), [[0, 1], [-9.81, 0]])  # type: ignore[index]
    assert np.allclose(np.array(ss.numeric["B"]), [[0], [1]])  # type: ignore[index]
    assert np.allclose(np.array(ss.numeric["C"]), [[0, 0]])  # type: ignore[index]


def test_no_inputs_is_said_plainly() -> None:
    text = CART_POLE.replace("inputs:\n  F: {value: 0, description: horizontal force on the cart}\n", "").replace("force: [F, 0]", "force: [0, 0]")
    ss = statespace.state_space(model_of(text), {})
    assert np.array(ss.numeric["B"]).size == 0  # type: ignore[index]
    assert any("declares no `inputs`" in n for n in ss.notes)
    assert ss.controllability_rank == 0


def test_lqr_gain_stabilises() -> None:
    ss = statespace.state_space(model_of(CART_POLE), {})
    gain = np.array(statespace.lqr(ss, [1, 1, 10, 10], [0.1]))
    closed = np.array(ss.numeric["A"]) - np.array(ss.numeric["B"]) @ gain  # type: ignore[index]
    assert np.all(np.linalg.eigvals(closed).real < 0)
    with pytest.raises(DerivationError, match="one per state"):
        statespace.lqr(ss, [1, 2], None)


def write(tmp_path: Path, text: str = CART_POLE) -> str:
    path = tmp_path / "cart.yaml"
    path.write_text(text)
    return str(path)


def test_linearize_json_has_the_format_keys(tmp_path: Path) -> None:
    result = runner.invoke(app, ["linearize", write(tmp_path), "--about", "theta=0,F=0", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    for key in ("A", "B", "C", "D", "state", "inputs", "outputs", "about"):
        assert key in data
    assert data["B"] == [[0.0], [0.0], [1.0], [-2.0]] and data["inputs"] == ["F"] and data["outputs"] == ["position", "angle"]
    assert data["about"] == {"x": 0.0, "theta": 0.0, "F": 0.0}


def test_linearize_text_latex_and_lqr(tmp_path: Path) -> None:
    path = write(tmp_path)
    result = runner.invoke(app, ["linearize", path, "--lqr-q", "1,1,10,10", "--lqr-r", "0.1"])
    assert result.exit_code == 0, result.output
    assert "controllability rank: 4 of 4" in result.output and "LQR gain K" in result.output and "B = [[0], [0], [1/M], [-1/(M*l)]]" in result.output
    result = runner.invoke(app, ["linearize", path, "--latex"])
    assert result.exit_code == 0 and r"\frac{1}{M}" in result.output


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--about", "F=1"], "not an equilibrium"),
        (["--about", "G=1"], "'G'"),
        (["--lqr-q", "1,2"], "one per state"),
        (["--latex", "--json"], "choose one"),
    ],
)
def test_linearize_refusals(tmp_path: Path, args: list[str], message: str) -> None:
    result = runner.invoke(app, ["linearize", write(tmp_path), *args])
    assert result.exit_code == 2 and message in result.output and "Traceback" not in result.output


def test_check_verifies_state_space(tmp_path: Path) -> None:
    expect = """\
expect:
  state_space:
    about: {theta: 0}
    A: [[0, 0, 1, 0], [0, 0, 0, 1], [0, -m*g/M, 0, 0], [0, (M + m)*g/(M*l), 0, 0]]
    B: [[0], [0], [1/M], [-1/(M*l)]]
    D: [[0], [0]]
"""
    result = runner.invoke(app, ["check", write(tmp_path, CART_POLE + expect)])
    assert result.exit_code == 0, result.output
    result = runner.invoke(app, ["check", write(tmp_path, CART_POLE + expect.replace("(M + m)*g", "(M + 2*m)*g"))])
    assert result.exit_code == 1 and "A[4][2]" in result.output
    result = runner.invoke(app, ["check", write(tmp_path, CART_POLE + expect.replace("D: [[0], [0]]", "D: [[0, 0]]"))])
    assert result.exit_code == 1 and "D is 1x2" in result.output
    result = runner.invoke(app, ["check", write(tmp_path, CART_POLE + expect.replace("about: {theta: 0}", "about: {theta: 0, F: 1}"))])
    assert result.exit_code == 2 and "not an equilibrium" in result.output


def test_api_returns_arrays() -> None:
    system = api.from_text(CART_POLE)
    result = system.state_space({"theta": 0}, lqr=(None, None))
    assert isinstance(result["A"], np.ndarray) and result["A"].shape == (4, 4) and result["B"].shape == (4, 1) and result["D"].shape == (2, 1)
    assert result["K"].shape == (1, 4)


def test_api_simulate_takes_input_expressions() -> None:
    system = api.from_text(CART_POLE)
    run = system.simulate(t_end=3.0, initial={"theta": 0.1}, inputs={"F": "40*theta + 10*theta_dot + 2*x + 3*x_dot"}, backend="python", samples=31)
    assert abs(run.states["theta"][-1]) < 0.05
    with pytest.raises(Exception, match="not an input"):
        system.simulate(t_end=0.1, inputs={"G": "0"})
