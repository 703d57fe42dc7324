"""`check` accepts every correct answer, in any form, and rejects every wrong one, naming the term."""

from __future__ import annotations

import json
import random
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import sympy as sp
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from lagrange_cli import check, derive, spec
from lagrange_cli.cli import app

from .conftest import ROOT

DOUBLE = """
coordinates: [theta1, theta2]
parameters: {m1: 1.0, m2: 1.5, l1: 1.0, l2: 0.8, g: 9.81}
gravity: [0, -g]
particles:
  a: {mass: m1, position: [l1*sin(theta1), -l1*cos(theta1)]}
  b: {mass: m2, position: [l1*sin(theta1) + l2*sin(theta2), -l1*cos(theta1) - l2*cos(theta2)]}
"""

POLAR = """
coordinates: [r, theta]
parameters: {m: 1.0, k: 2.0, c: 0.3}
particles:
  p: {mass: m, position: [r*cos(theta), r*sin(theta)], damping: c}
potential: k*r**2/2
"""

EQUAL = """
coordinates: [theta, phi]
parameters: {m: 1.0, l: 1.0, g: 9.81}
gravity: [0, -g]
particles:
  upper: {mass: m, position: [l*sin(theta), -l*cos(theta)]}
  lower: {mass: m, position: [l*sin(theta) + l*sin(phi), -l*cos(theta) - l*cos(phi)]}
"""
EQUAL_SECOND = "phi_ddot + cos(theta - phi)*theta_ddot - sin(theta - phi)*theta_dot**2 + g/l*sin(phi) = 0"

CHARGE = """
coordinates: [x, y]
parameters: {m: 1.0, qc: 1.0, B: 2.0}
particles:
  p: {mass: m, position: [x, y]}
lagrangian: qc*B*(x*y_dot - y*x_dot)/2
"""


def verdicts(system: str, expect: dict) -> list[check.Result]:
    text = system + yaml.safe_dump({"expect": expect}, width=1000)
    parsed = spec.parse(text, "answer.yaml")
    return check.check(parsed, derive.derive(parsed))


def passes(system: str, expect: dict) -> bool:
    return all(r.passed for r in verdicts(system, expect))


KEPLER_RIGHT = ["m*r_ddot - m*r*theta_dot**2 + k*r + c*r_dot = 0", "m*r**2*theta_ddot + 2*m*r*r_dot*theta_dot + c*r**2*theta_dot = 0"]

WRONG = [
    # (system, expect, what the diagnostic must say)
    (POLAR, {"equations": ["m*r_ddot - m*r*theta_dot**2 + k*r - c*r_dot = 0", KEPLER_RIGHT[1]]}, "wrong sign on -c*r_dot"),
    (POLAR, {"equations": [KEPLER_RIGHT[0], "m*r**2*theta_ddot + m*r*r_dot*theta_dot + c*r**2*theta_dot = 0"]}, "missing m*r*r_dot*theta_dot"),
    (POLAR, {"equations": ["m*r_ddot + k*r + c*r_dot = 0", KEPLER_RIGHT[1]]}, "missing -m*r*theta_dot**2"),
    (POLAR, {"equations": ["m*r_ddot - m*r*theta_dot**2 + k*r = 0", KEPLER_RIGHT[1]]}, "missing c*r_dot"),
    (
        EQUAL,
        {"equations": ["2*theta_ddot + cos(theta - phi)*phi_ddot + sin(theta - phi)*phi_dot**2 + 2*g/l*cos(theta) = 0", EQUAL_SECOND]},
        "extra term 2*g*cos(theta)/l; expected is missing 2*g*sin(theta)/l",
    ),
    (CHARGE, {"momenta": {"x": "m*x_dot"}}, "missing -B*qc*y/2"),
]


@pytest.mark.parametrize(("system", "expect", "message"), WRONG, ids=["sign", "coriolis-factor-2", "centrifugal", "damping", "sin-cos-swap", "kinetic-momentum"])
def test_wrong_answers_are_rejected_with_the_term(system: str, expect: dict, message: str) -> None:
    failed = [r for r in verdicts(system, expect) if not r.passed]
    assert failed, "a wrong answer was accepted"
    assert message in failed[0].detail, failed[0].detail


DOUBLE_ACCELERATIONS = {
    "theta1_ddot": "(-g*(2*m1 + m2)*sin(theta1) - m2*g*sin(theta1 - 2*theta2) - 2*sin(theta1 - theta2)*m2*(theta2_dot**2*l2 + theta1_dot**2*l1*cos(theta1 - theta2)))/(l1*(2*m1 + m2 - m2*cos(2*theta1 - 2*theta2)))",
    "theta2_ddot": "2*sin(theta1 - theta2)*(theta1_dot**2*l1*(m1 + m2) + g*(m1 + m2)*cos(theta1) + theta2_dot**2*l2*m2*cos(theta1 - theta2))/(l2*(2*m1 + m2 - m2*cos(2*theta1 - 2*theta2)))",
}
DOUBLE_EQUATIONS = [
    "(m1 + m2)*l1*theta1_ddot + m2*l2*cos(theta1 - theta2)*theta2_ddot + m2*l2*sin(theta1 - theta2)*theta2_dot**2 + (m1 + m2)*g*sin(theta1) = 0",
    "l2*theta2_ddot + l1*cos(theta1 - theta2)*theta1_ddot - l1*sin(theta1 - theta2)*theta1_dot**2 + g*sin(theta2) = 0",
]

RIGHT = [
    (DOUBLE, {"equations": DOUBLE_EQUATIONS}),
    (DOUBLE, {"equations": list(reversed(DOUBLE_EQUATIONS))}),
    (DOUBLE, {"equations": [f"({DOUBLE_EQUATIONS[0].split(' = ')[0]}) + 3*({DOUBLE_EQUATIONS[1].split(' = ')[0]}) = 0", DOUBLE_EQUATIONS[1]]}),
    (DOUBLE, {"accelerations": DOUBLE_ACCELERATIONS}),
    (DOUBLE, {"equations": [DOUBLE_EQUATIONS[0].replace("sin(theta1)", "2*sin(theta1/2)*cos(theta1/2)"), DOUBLE_EQUATIONS[1]]}),
    (POLAR, {"equations": ["r_ddot - r*theta_dot**2 + k/m*r + c/m*r_dot = 0", "Derivative(m*r**2*theta_dot, t) + c*r**2*theta_dot = 0"]}),
    (CHARGE, {"momenta": {"x": "m*x_dot - qc*B*y/2", "y": "m*y_dot + qc*B*x/2"}, "conserved": ["energy"]}),
]


@pytest.mark.parametrize(("system", "expect"), RIGHT, ids=["textbook", "reordered", "recombined", "explicit-accelerations", "half-angles", "divided-and-ddt", "canonical-momenta"])
def test_correct_answers_in_unusual_forms_are_accepted(system: str, expect: dict) -> None:
    failed = [f"{r.entry}: {r.detail}" for r in verdicts(system, expect) if not r.passed]
    assert not failed, failed


def derived_equations(system: str) -> list[sp.Expr]:
    return list(derive.derive(spec.parse(system, "x.yaml")).equations())


FACTORS = [sp.Integer(1), sp.Symbol("m1"), sp.Symbol("l2") ** 2, 1 + sp.cos(sp.Symbol("theta2")) ** 2]


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(-3, 3), st.integers(-3, 3), st.integers(-3, 3), st.integers(-3, 3), st.sampled_from(FACTORS))
def test_invertible_recombinations_are_accepted(a: int, b: int, c: int, d: int, factor: sp.Expr) -> None:
    if a * d - b * c == 0:
        return
    e1, e2 = derived_equations(DOUBLE)
    recombined = [sp.expand(factor * (a * e1 + b * e2)), sp.expand(c * e1 + d * e2)]
    assert passes(DOUBLE, {"equations": [f"{e} = 0" for e in recombined]})


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 1), st.data())
def test_single_term_perturbations_are_rejected(which: int, data: st.DataObject) -> None:
    equations = derived_equations(POLAR)
    terms = list(sp.Add.make_args(sp.expand(equations[which])))
    index = data.draw(st.integers(0, len(terms) - 1))
    change = data.draw(st.sampled_from(["drop", "double", "negate"]))
    factor = {"drop": 0, "double": 2, "negate": -1}[change]
    perturbed = sp.Add(*(t * factor if i == index else t for i, t in enumerate(terms)))
    equations[which] = perturbed
    assert not passes(POLAR, {"equations": [f"{e} = 0" for e in equations]})


def test_random_seeded_answers_are_reproducible() -> None:
    random.seed(0)
    assert passes(DOUBLE, {"equations": DOUBLE_EQUATIONS}) == passes(DOUBLE, {"equations": DOUBLE_EQUATIONS})


runner = CliRunner()


def test_junit_and_json_reports(tmp_path: Path) -> None:
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text(DOUBLE + yaml.safe_dump({"expect": {"equations": [DOUBLE_EQUATIONS[0].replace("(m1 + m2)*g", "m1*g"), DOUBLE_EQUATIONS[1]]}}, width=1000))
    junit = tmp_path / "report.xml"
    result = runner.invoke(app, ["check", str(ROOT / "systems" / "kepler.yaml"), str(wrong), "--junit", str(junit)])
    assert result.exit_code == 1
    root = ET.parse(junit).getroot()
    assert root.tag == "testsuites"
    suites = root.findall("testsuite")
    assert [int(s.get("failures", "0")) for s in suites] == [0, 1]
    failure = suites[1].find("testcase/failure")
    assert failure is not None and "missing" in failure.get("message", "")
    report = json.loads(runner.invoke(app, ["check", str(wrong), "--json"]).stdout)
    assert report["summary"] == {"files": 1, "pass": 0, "fail": 1, "error": 0, "skip": 0, "exit_code": 1}
    assert report["files"][0]["results"][0]["line"] is not None


def test_bad_input_exits_2_and_is_reported(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("coordinates: [x]\nkinetic: x_dot**2 +\n")
    result = runner.invoke(app, ["check", str(bad), str(ROOT / "systems" / "kepler.yaml")])
    assert result.exit_code == 2
    assert "bad.yaml:2:" in result.output


def test_pre_commit_hook_is_declared() -> None:
    hooks = yaml.safe_load((ROOT / ".pre-commit-hooks.yaml").read_text())
    assert hooks[0]["id"] == "lagrange-check" and hooks[0]["entry"] == "lagrange check"
