"""The deriver against independent computations: sympy.physics.mechanics, Newton's F = m a,
and properties of Lagrange's equation that any correct derivation must have."""

from __future__ import annotations

import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sympy.physics.mechanics import LagrangesMethod, dynamicsymbols

from lagrange_cli import algebra, derive, spec
from lagrange_cli.model import Model

from .helpers import model_of, random_point

DOUBLE_PENDULUM = """
coordinates: [theta, phi]
parameters: {m1: 1.0, m2: 2.0, l1: 1.0, l2: 0.7, g: 9.81}
gravity: [0, -g]
particles:
  upper: {mass: m1, position: [l1*sin(theta), -l1*cos(theta)]}
  lower: {mass: m2, position: [l1*sin(theta) + l2*sin(phi), -l1*cos(theta) - l2*cos(phi)]}
"""

SPHERICAL_PENDULUM = """
coordinates: [theta, phi]
parameters: {m: 1.0, l: 1.0, g: 9.81}
gravity: [0, 0, -g]
particles:
  bob: {mass: m, position: [l*sin(theta)*cos(phi), l*sin(theta)*sin(phi), -l*cos(theta)]}
"""

HOOP = """
coordinates: [theta]
parameters: {m: 1.0, a: 1.0, g: 9.81, omega: 3.0}
gravity: [0, -g]
particles:
  bead: {mass: m, position: [a*cos(omega*t) + a*cos(omega*t + theta), a*sin(omega*t) + a*sin(omega*t + theta)]}
"""

DISK = """
coordinates: [s, theta]
parameters: {M: 2.0, m: 1.0, R: 0.5, l: 0.3, g: 9.81, alpha: 0.3}
gravity: [0, -g]
bodies:
  disk: {mass: M, position: [s*cos(alpha), -s*sin(alpha)], inertia: M*R**2/2, angular_velocity: s_dot/R}
particles:
  bob: {mass: m, position: [s*cos(alpha) + l*sin(theta), -s*sin(alpha) - l*cos(theta)], damping: k}
"""


def mechanics_reference(text: str) -> tuple[Model, sp.Matrix, sp.Matrix]:
    """Mass matrix and forcing from sympy.physics.mechanics' LagrangesMethod, on the same
    positions, with q(t) as dynamic symbols; returned in our plain symbols."""
    system = spec.parse(text, "ref.yaml")
    model = derive.derive(system)
    t = system.t
    qs = dynamicsymbols(" ".join(system.coordinates) + " _unused")[: len(system.q)]
    to_dynamic = {**dict(zip(system.q, qs, strict=True)), **{v: f.diff(t) for v, f in zip(system.qd, qs, strict=True)}}
    lagrangian = sp.Integer(0)
    dissipation = sp.Integer(0)
    g = system.gravity
    for item in (*system.particles, *system.bodies):
        x = [c.xreplace(to_dynamic) for c in item.position]
        v2 = sum(c.diff(t) ** 2 for c in x)
        lagrangian += item.mass * v2 / 2 + (item.mass * sum(gi * xi for gi, xi in zip(g, x, strict=True)) if g else 0)
        if getattr(item, "damping", None) is not None:
            dissipation += item.damping * v2 / 2
    for body in system.bodies:
        lagrangian += sum(i.xreplace(to_dynamic) * w.xreplace(to_dynamic) ** 2 for i, w in zip(body.inertia, body.angular_velocity, strict=True)) / 2
    method = LagrangesMethod(lagrangian, qs)
    method.form_lagranges_equations()
    mass, forcing = method.mass_matrix, method.forcing
    if dissipation != 0:
        forcing = forcing - sp.Matrix([dissipation.diff(f.diff(t)) for f in qs])
    back = {**{f.diff(t): v for f, v in zip(qs, system.qd, strict=True)}}
    back_q = dict(zip(qs, system.q, strict=True))
    return model, mass.xreplace(back).xreplace(back_q), forcing.xreplace(back).xreplace(back_q)


def assert_same_numbers(a: sp.Matrix, b: sp.Matrix, point: dict[sp.Symbol, float]) -> None:
    difference = (sp.Matrix(a) - sp.Matrix(b)).xreplace(point).evalf(30)
    scale = 1 + max(abs(x) for x in sp.Matrix(a).xreplace(point).evalf(30))
    assert all(abs(x) < 1e-12 * scale for x in difference), difference


def test_matches_sympy_mechanics_on_classic_systems() -> None:
    for text in (DOUBLE_PENDULUM, SPHERICAL_PENDULUM, HOOP, DISK.replace("damping: k", "damping: 0.5")):
        model, mass, forcing = mechanics_reference(text)
        for seed in range(3):
            point = random_point(model, seed)
            assert_same_numbers(model.mass_matrix, mass, point)
            assert_same_numbers(model.forcing, forcing, point)


def test_double_pendulum_reads_like_the_textbook() -> None:
    model = model_of(DOUBLE_PENDULUM)
    theta, phi = model.q
    assert model.mass_matrix[0, 1] == sp.Symbol("l1") * sp.Symbol("l2") * sp.Symbol("m2") * sp.cos(phi - theta)
    assert model.autonomous and not model.constraints and not model.dissipative


def test_time_dependent_constraint_is_not_autonomous() -> None:
    assert not model_of(HOOP).autonomous


# -- properties ------------------------------------------------------------------------------

COORDINATES = ("x", "y")
atoms = st.sampled_from(["x", "y", "sin(x)", "cos(y)", "sin(x - y)", "x*y", "cos(x)**2", "exp(-x**2)"])
coefficients = st.integers(min_value=1, max_value=5)
potentials = st.lists(st.tuples(coefficients, atoms), min_size=1, max_size=4).map(lambda terms: " + ".join(f"{c}*{a}" for c, a in terms))
positive_definite = st.tuples(st.integers(1, 4), st.integers(1, 4), st.integers(-1, 1)).map(lambda abc: ((abc[0] + 1, abc[2]), (abc[2], abc[1] + 1)))


def system_with(kinetic: str, potential: str, extra: str = "") -> str:
    return f"coordinates: [x, y]\nkinetic: '{kinetic}'\npotential: '{potential}'\n{extra}"


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(potentials, positive_definite)
def test_quadratic_lagrangian_gives_mass_matrix_and_gradient(potential: str, matrix: tuple[tuple[int, int], tuple[int, int]]) -> None:
    """L = 1/2 q_dot^T M q_dot - V(q) with constant M gives M q_ddot + grad V = 0."""
    (a, b), (_, d) = matrix
    kinetic = f"{a}*x_dot**2/2 + {b}*x_dot*y_dot + {d}*y_dot**2/2"
    model = model_of(system_with(kinetic, potential))
    x, y = model.q
    v = spec.parse(system_with("0", potential), "v.yaml").potential
    assert model.mass_matrix == sp.ImmutableMatrix([[a, b], [b, d]])
    assert sp.simplify(model.forcing + sp.Matrix([v.diff(x), v.diff(y)])) == sp.zeros(2, 1)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(potentials, st.sampled_from(["x*y*t", "sin(x)*cos(t)", "x**2*y", "exp(t)*cos(x - y)"]))
def test_adding_a_total_derivative_changes_nothing(potential: str, gauge: str) -> None:
    """L and L + dF(q, t)/dt have the same equations of motion."""
    base = system_with("x_dot**2 + x_dot*y_dot + y_dot**2", potential)
    plain = model_of(base)
    gauged = model_of(base + f"lagrangian: 'Derivative({gauge}, t)'\n")
    assert gauged.mass_matrix == plain.mass_matrix
    assert sp.simplify(sp.Matrix(gauged.forcing) - sp.Matrix(plain.forcing)) == sp.zeros(2, 1)


positions = st.tuples(atoms, atoms, coefficients).map(lambda a: (f"{a[2]}*{a[0]} + y", f"x + {a[1]}"))
forces = st.tuples(st.sampled_from(["0", "y_dot", "-x", "sin(t)", "x*y_dot"]), st.sampled_from(["0", "-x_dot", "y", "cos(x)"]))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(positions, forces)
def test_cartesian_particle_agrees_with_newton(position: tuple[str, str], force: tuple[str, str]) -> None:
    """Lagrange's equation i is sum_j (m a_j - f_j) dx_j/dq_i (the chapter's Eq. 6.18)."""
    text = f"coordinates: [x, y]\nparameters: [m]\nparticles:\n  p: {{mass: m, position: ['{position[0]}', '{position[1]}'], force: ['{force[0]}', '{force[1]}']}}\n"
    system = spec.parse(text, "newton.yaml")
    model = derive.derive(system)
    (particle,) = system.particles
    m = particle.mass

    def ddt(e: sp.Expr) -> sp.Expr:
        return spec.time_derivative(e, system.q, system.qd, system.qdd, system.t)

    acceleration = [ddt(ddt(x)) for x in particle.position]
    newton = [sum((m * a - f) * x.diff(q) for a, f, x in zip(acceleration, particle.force, particle.position, strict=True)) for q in system.q]
    for ours, theirs in zip(model.equations(), newton, strict=True):
        assert sp.simplify(sp.expand(ours - theirs)) == 0


def test_combine_trig_only_shortens() -> None:
    import symengine as se

    a, b, c = se.symbols("a b c")
    expr = c * se.cos(a) * se.cos(b) + c * se.sin(a) * se.sin(b) + se.sin(a) ** 2 + se.cos(a) ** 2 + se.sin(a) * se.cos(b) - se.cos(a) * se.sin(b)
    result = algebra.combine_trig(expr)
    assert sp.simplify(sp.sympify(result) - sp.sympify(expr)) == 0
    assert len(result.args) == 3
