"""Bodies with an orientation (FORMAT.md version 2): rotations, full inertia, points, loads.

The equations are compared with sympy.physics.mechanics (KanesMethod, frames oriented with
`orient_body_fixed` / `orient_space_fixed` / `orient_axis`) at random states, to 1e-9."""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

import pytest
import sympy as sp

from lagrange_cli.derive import derive
from lagrange_cli.errors import SpecError
from lagrange_cli.spec import parse

HERE = Path(__file__).parent


def accelerations(mass: Any, forcing: Any, variables: list[Any], values: list[float]) -> list[float]:
    """M^-1 F at `values`, evaluated in symengine (lambdify would print the expressions first): `mass` and
    `forcing` sympy matrices (in any symbols, dynamic ones too) or `Model.symengine` forms."""
    import symengine as se

    plain = {v: sp.Symbol(f"v{i}") for i, v in enumerate(variables)}
    at = {se.Symbol(f"v{i}"): se.RealDouble(x) for i, x in enumerate(values)}
    named = {se.sympify(v): se.RealDouble(x) for v, x in zip(variables, values, strict=True) if isinstance(v, sp.Symbol)}

    def value(e: Any) -> float:
        if isinstance(e, se.Basic):
            return float(e.xreplace(named).n(53, real=True))
        return float(se.sympify(e.xreplace(plain)).xreplace(at).n(53, real=True))

    if isinstance(mass, tuple):  # symengine forms: rows of entries, and a tuple of entries
        n = len(mass)
        m = sp.Matrix(n, n, lambda i, j: value(mass[i][j]))
        return [float(x) for x in m.LUsolve(sp.Matrix([value(f) for f in forcing]))]

    n = mass.shape[0]
    m = sp.Matrix(n, n, lambda i, j: value(mass[i, j]))
    f = sp.Matrix(n, 1, lambda i, _: value(forcing[i]))
    return [float(x) for x in m.LUsolve(f)]


INERTIA = "[[{m}*{l}**2/12, {m}*{l}**2/100, -{m}*{l}**2/90], [{m}*{l}**2/100, {m}*{l}**2/11, {m}*{l}**2/200], [-{m}*{l}**2/90, {m}*{l}**2/200, {m}*{l}**2/50]]"

CHAIN = f"""
coordinates: [a1, b1, c1, a2, b2, c2]
parameters: {{m1: 1.3, m2: 0.7, l1: 1.1, l2: 0.6, g: 9.81, k: 0.4, f: 0.9}}
gravity: [0, 0, -g]
bodies:
  upper:
    mass: m1
    orientation: {{sequence: zyx, angles: [a1, b1, c1]}}
    pivot: [0, 0, 0]
    center: [l1/7, 0, -l1/2]
    points: {{tip: [0, l1/5, -l1]}}
    inertia: {INERTIA.format(m="m1", l="l1")}
    torque: [k*sin(a1), 0, -k*b1_dot]
  lower:
    mass: m2
    orientation: {{sequence: XZY, angles: [a2, b2, c2], kind: space, relative_to: upper}}
    pivot: upper.tip
    center: [l2/3, 0, -l2/2]
    points: {{end: [0, 0, -l2]}}
    inertia: {INERTIA.format(m="m2", l="l2")}
    force: {{vector: [f, 0, c2_dot], axes: body, at: end}}
    torque: {{vector: [0, k*a2, 0], axes: body}}
"""


def mechanics_chain() -> tuple[sp.Matrix, sp.Matrix, list[sp.Basic], list[sp.Basic]]:
    from sympy.physics import mechanics as me

    q = me.dynamicsymbols("a1 b1 c1 a2 b2 c2")
    u = me.dynamicsymbols("u1:7")
    m1, m2, l1, l2, g, k, f = sp.symbols("m1 m2 l1 l2 g k f")
    N = me.ReferenceFrame("N")
    A = me.ReferenceFrame("A")
    B = me.ReferenceFrame("B")
    A.orient_body_fixed(N, (q[0], q[1], q[2]), "ZYX")
    B.orient_space_fixed(A, (q[3], q[4], q[5]), "XZY")
    origin = me.Point("O")
    origin.set_vel(N, 0)
    tip = origin.locatenew("tip", l1 / 5 * A.y - l1 * A.z)
    ca = origin.locatenew("ca", l1 / 7 * A.x - l1 / 2 * A.z)
    cb = tip.locatenew("cb", l2 / 3 * B.x - l2 / 2 * B.z)
    end = tip.locatenew("end", -l2 * B.z)
    for point in (ca, cb, end, tip):
        point.set_vel(N, point.pos_from(origin).dt(N))

    def tensor(m: sp.Expr, length: sp.Expr, frame: me.ReferenceFrame) -> me.Dyadic:
        c = m * length**2
        return me.inertia(frame, c / 12, c / 11, c / 50, c / 100, c / 200, -c / 90)

    upper = me.RigidBody("upper", ca, A, m1, (tensor(m1, l1, A), ca))
    lower = me.RigidBody("lower", cb, B, m2, (tensor(m2, l2, B), cb))
    qd = [qi.diff() for qi in q]
    loads = [
        (ca, -m1 * g * N.z),
        (cb, -m2 * g * N.z),
        (A, k * sp.sin(q[0]) * N.x - k * qd[1] * N.z),
        (end, f * B.x + qd[5] * B.z),
        (B, k * q[3] * B.y),
    ]
    kane = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=[qd[i] - u[i] for i in range(6)])
    kane.kanes_equations([upper, lower], loads)
    to_q = dict(zip(u, qd, strict=True))
    return kane.mass_matrix.xreplace(to_q), kane.forcing.xreplace(to_q), q, qd


def test_spatial_chain_agrees_with_sympy_mechanics() -> None:
    """A 2-link chain (ZYX body-fixed, then XZY space-fixed relative to it), full inertias with products,
    pivot at a point, forces at points in body axes and torques in world and body axes: the accelerations
    at random states agree with KanesMethod to 1e-9."""
    model = derive(parse(CHAIN, "chain.yaml"))
    mass, forcing, q, qd = mechanics_chain()
    rng = random.Random(13)
    parameters = {"m1": 1.3, "m2": 0.7, "l1": 1.1, "l2": 0.6, "g": 9.81, "k": 0.4, "f": 0.9}
    symbols = [sp.Symbol(n) for n in parameters]
    for _ in range(3):
        state = [rng.uniform(-2, 2) for _ in range(12)]
        ours = accelerations(model.symengine.mass, model.symengine.forcing, [*model.q, *model.qd, *symbols], [*state, *parameters.values()])
        theirs = accelerations(mass, forcing, [*q, *qd, *symbols], [*state, *parameters.values()])
        assert ours == pytest.approx(theirs, rel=1e-9, abs=1e-9)


def test_axis_angle_two_link_arm_of_format_md() -> None:
    """FORMAT.md's two-link arm (with its input `tau` as a parameter here) derives; its equations agree
    with KanesMethod (orient_axis) at random states."""
    from sympy.physics import mechanics as me

    text = ARM
    model = derive(parse(text, "arm.yaml"))
    q = me.dynamicsymbols("q1 q2")
    m1, m2, l1, l2, g, tau = sp.symbols("m1 m2 l1 l2 g tau")
    N, A, B = me.ReferenceFrame("N"), me.ReferenceFrame("A"), me.ReferenceFrame("B")
    A.orient_axis(N, N.z, q[0])
    B.orient_axis(A, A.y, q[1])
    origin = me.Point("O")
    origin.set_vel(N, 0)
    ca, elbow = origin.locatenew("ca", l1 / 2 * A.x), origin.locatenew("elbow", l1 * A.x)
    cb = elbow.locatenew("cb", l2 / 2 * B.x)
    for point in (ca, cb):
        point.set_vel(N, point.pos_from(origin).dt(N))
    upper = me.RigidBody("upper", ca, A, m1, (me.inertia(A, 0, m1 * l1**2 / 12, m1 * l1**2 / 12), ca))
    lower = me.RigidBody("lower", cb, B, m2, (me.inertia(B, 0, m2 * l2**2 / 12, m2 * l2**2 / 12), cb))
    u = me.dynamicsymbols("u1:3")
    qd = [x.diff() for x in q]
    kane = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=[qd[i] - u[i] for i in range(2)])
    kane.kanes_equations([upper, lower], [(ca, -m1 * g * N.z), (cb, -m2 * g * N.z), (A, tau * N.z)])
    to_q = dict(zip(u, qd, strict=True))
    values = {"m1": 1.0, "m2": 1.0, "l1": 1.0, "l2": 0.8, "g": 9.81, "tau": 0.3}
    symbols = [sp.Symbol(n) for n in values]
    rng = random.Random(5)
    for _ in range(3):
        state = [rng.uniform(-2, 2) for _ in range(4)]
        ours = accelerations(model.symengine.mass, model.symengine.forcing, [*model.q, *model.qd, *symbols], [*state, *values.values()])
        theirs = accelerations(kane.mass_matrix.xreplace(to_q), kane.forcing.xreplace(to_q), [*q, *qd, *symbols], [*state, *values.values()])
        assert ours == pytest.approx(theirs, rel=1e-9, abs=1e-9)


ARM = """
coordinates: [q1, q2]
parameters: {m1: 1.0, m2: 1.0, l1: 1.0, l2: 0.8, g: 9.81, tau: 0.3}
gravity: [0, 0, -g]
bodies:
  upper:
    mass: m1
    orientation: {axis: [0, 0, 1], angle: q1}
    pivot: [0, 0, 0]
    center: [l1/2, 0, 0]
    inertia: [[0, 0, 0], [0, m1*l1**2/12, 0], [0, 0, m1*l1**2/12]]
    points: {elbow: [l1, 0, 0]}
    torque: [0, 0, tau]
  lower:
    mass: m2
    orientation: {axis: [0, 1, 0], angle: q2, relative_to: upper}
    pivot: upper.elbow
    center: [l2/2, 0, 0]
    inertia: [[0, 0, 0], [0, m2*l2**2/12, 0], [0, 0, m2*l2**2/12]]
"""
"""FORMAT.md's two-link arm, its input `tau` a parameter here (inputs are read elsewhere)."""


BAD_BASE = """coordinates: [a, b]
parameters: {{m: 1.0, l: 1.0, g: 9.81}}
bodies:
  one:
    mass: m
    orientation: {one}
    pivot: [0, 0, 0]
    points: {{tip: [0, 0, -l]}}
    inertia: {inertia}
  two:
    mass: m
    orientation: {two}
    pivot: {pivot}
    inertia: [m, m, m]
"""
GOOD = {"one": "{axis: [0, 0, 1], angle: a}", "inertia": "[m, m, m]", "two": "{axis: [1, 0, 0], angle: b, relative_to: one}", "pivot": "one.tip"}


@pytest.mark.parametrize(
    ("change", "where", "message"),
    [
        ({"one": "{matrix: [[1, 0, 0], [0, 1, 0], [0, 0.5, 1]]}"}, "6:27", "not a rotation: column 2 . column 2 is 1.25, not 1"),
        ({"one": "{matrix: [[1, 0, 0], [0, 1, 0], [0, 0, -1]]}"}, "6:27", "its determinant is -1, not 1 (a reflection)"),
        ({"one": "{matrix: [[cos(a), -sin(a), 0], [sin(a), cos(a), 0], [0, 0, 1 + a**2]]}"}, "6:27", "column 3 . column 3 is"),
        ({"one": "{sequence: ZYY, angles: [a, 0, 0]}"}, "6:29", "unknown sequence 'ZYY'"),
        ({"one": "{sequence: zyx, angles: [a, 0, 0], kind: fixed}"}, "6:59", "unknown kind 'fixed'"),
        ({"one": "{axis: [0, 0, 1], angle: a, relative_to: two}"}, "12:59", "cycle: one -> two -> one"),
        ({"two": "{axis: [1, 0, 0], angle: b, relative_to: two}"}, "12:59", "cycle: two -> two"),
        ({"pivot": "one.top"}, "13:12", "body 'one' has no point 'top'"),
        ({"pivot": "three.tip"}, "13:12", "there is no body 'three'"),
        ({"pivot": "nothing"}, "13:12", "unknown point 'nothing'"),
        ({"inertia": "[[m, 1, 0], [2, m, 0], [0, 0, m]]"}, "9:27", "is not symmetric: entry (2, 1) is 2 but entry (1, 2) is 1"),
        ({"inertia": "[[m, 2*m, 0], [2*m, m, 0], [0, 0, m]]"}, "9:14", "not positive semi-definite at the default parameters"),
        ({"one": "{axis: [0, 0, 0], angle: a}"}, "6:25", "the axis of 'one' is zero"),
        ({"one": "{axis: [0, 0, a], angle: a}"}, "6:32", "'a' is a coordinate"),
        ({"one": "{axis: [0, 0, t], angle: a}"}, "6:25", "depends on time"),
        ({"one": "{angle: a}"}, "6:18", "has 'angle' but no 'axis'"),
    ],
)
def test_bad_orientation_is_reported_at_its_place(change: dict[str, str], where: str, message: str) -> None:
    text = BAD_BASE.format(**{**GOOD, **change})
    with pytest.raises(SpecError) as caught:
        parse(text, "bad.yaml")
    rendered = str(caught.value)
    assert f"bad.yaml:{where}: error:" in rendered and message in rendered, rendered


@pytest.mark.parametrize(
    ("body", "where", "message"),
    [
        ("{mass: m, position: [0, 0, 0], inertia: [m, m, m], angular_velocity: [0, 0, a_dot], orientation: {axis: [0, 0, 1], angle: a}}", "4:77", "gives both 'angular_velocity' and 'orientation'"),
        ("{mass: m, pivot: [0, 0, 0], inertia: [m, m, m], angular_velocity: [0, 0, a_dot]}", "4:25", "'pivot' of body 'one' needs an 'orientation'"),
        ("{mass: m, position: [0, 0, 0], center: [0, 0, 1], inertia: [m, m, m], angular_velocity: [0, 0, a_dot]}", "4:47", "'center' of body 'one' needs an 'orientation'"),
        ("{mass: m, position: [0, 0, 0], points: {p: [0, 0, 1]}, inertia: [m, m, m], angular_velocity: [0, 0, a_dot]}", "4:47", "'points' of body 'one' needs an 'orientation'"),
        ("{mass: m, position: [0, 0, 0], inertia: [m, m, m], orientation: {axis: [0, 0, 1], angle: a}, force: {vector: [1, 0, 0], at: tip}}", "4:132", "body 'one' has no point 'tip'"),
        ("{mass: m, position: [0, 0, 0], inertia: [m, m, m], orientation: {axis: [0, 0, 1], angle: a}, torque: {vector: [1, 0, 0], axes: inertial}}", "4:135", "unknown axes 'inertial'"),
    ],
)
def test_bad_body_keys(body: str, where: str, message: str) -> None:
    text = f"coordinates: [a]\nparameters: {{m: 1.0}}\nbodies:\n  one: {body}\n"
    with pytest.raises(SpecError) as caught:
        parse(text, "bad.yaml")
    rendered = str(caught.value)
    assert f"bad.yaml:{where}: error:" in rendered and message in rendered, rendered


MIXED = """
coordinates: [q1, q2, q3]
parameters: {m1: 1.0, m2: 0.5, mp: 0.3, l: 0.7, h: 0.2, w: 1.5, g: 9.81}
gravity: [0, 0, -g]
particles:
  bead: {mass: mp, position: arm.end}
bodies:
  arm:
    mass: m2
    orientation: {sequence: zxz, angles: [q2, q3, 0.3], kind: space}
    position: base.rim
    points: {end: [0, 0, l]}
    inertia: [[m2/10, 0, m2/50], [0, m2/9, 0], [m2/50, 0, m2/20]]
    force: [0, 0.5, 0]
  base:
    mass: m1
    orientation: {axis: [1, 1, 1], angle: q1}
    pivot: [0, 0, h*sin(w*t)]
    center: [l/2, 0, 0]
    points: {rim: [l, 0, l/3]}
    inertia: [m1/10, m1/12, m1/15]
"""


def test_references_across_bodies_moving_pivot_and_particle() -> None:
    """A body whose centre is a point of another body that is not its parent (written before it), a pivot that
    moves with time, a particle at a body's point, an axis that is not a unit vector: KanesMethod agrees."""
    from sympy.physics import mechanics as me

    model = derive(parse(MIXED, "mixed.yaml"))
    q = me.dynamicsymbols("q1 q2 q3")
    m1, m2, mp, length, h, w, g = sp.symbols("m1 m2 mp l h w g")
    time = me.dynamicsymbols._t
    N, A, B = me.ReferenceFrame("N"), me.ReferenceFrame("A"), me.ReferenceFrame("B")
    A.orient_axis(N, (N.x + N.y + N.z).normalize(), q[0])
    B.orient_space_fixed(N, (q[1], q[2], sp.Rational(3, 10)), "ZXZ")
    origin = me.Point("O")
    origin.set_vel(N, 0)
    pivot = origin.locatenew("P", h * sp.sin(w * time) * N.z)
    ca, rim = pivot.locatenew("ca", length / 2 * A.x), pivot.locatenew("rim", length * A.x + length / 3 * A.z)
    end = rim.locatenew("end", length * B.z)
    for point in (ca, rim, end):
        point.set_vel(N, point.pos_from(origin).dt(N))
    base = me.RigidBody("base", ca, A, m1, (me.inertia(A, m1 / 10, m1 / 12, m1 / 15), ca))
    arm = me.RigidBody("arm", rim, B, m2, (me.inertia(B, m2 / 10, m2 / 9, m2 / 20, 0, 0, m2 / 50), rim))
    bead = me.Particle("bead", end, mp)
    u = me.dynamicsymbols("u1:4")
    qd = [x.diff() for x in q]
    kane = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=[qd[i] - u[i] for i in range(3)])
    kane.kanes_equations([base, arm, bead], [(ca, -m1 * g * N.z), (rim, -m2 * g * N.z + sp.Rational(1, 2) * N.y), (end, -mp * g * N.z)])
    to_q = dict(zip(u, qd, strict=True))
    values = {"m1": 1.0, "m2": 0.5, "mp": 0.3, "l": 0.7, "h": 0.2, "w": 1.5, "g": 9.81}
    symbols = [sp.Symbol(n) for n in values]
    rng = random.Random(7)
    for _ in range(3):
        state = [rng.uniform(-2, 2) for _ in range(7)]
        ours = accelerations(model.symengine.mass, model.symengine.forcing, [*model.q, *model.qd, sp.Symbol("t"), *symbols], [*state, *values.values()])
        theirs = accelerations(kane.mass_matrix.xreplace(to_q), kane.forcing.xreplace(to_q), [*q, *qd, time, *symbols], [*state, *values.values()])
        assert ours == pytest.approx(theirs, rel=1e-9, abs=1e-9)


PLANAR = """
coordinates: [th, ph]
parameters: {m: 1.0, l: 1.0, g: 9.81, c: 0.2}
gravity: [0, -g]
bodies:
  a: {mass: m, orientation: {angle: th}, pivot: [0, 0], center: [0, -l/2], points: {tip: [0, -l]}, inertia: m*l**2/12}
  b: {mass: m, orientation: {angle: ph, relative_to: a}, pivot: a.tip, center: [0, -l/2], inertia: m*l**2/12, torque: -c*ph_dot}
draw: {segments: [[[0, 0], a.tip], [a.tip, b]], trails: [b]}
"""
PLANAR_V1 = """
coordinates: [th, ph]
parameters: {m: 1.0, l: 1.0, g: 9.81, c: 0.2}
gravity: [0, -g]
bodies:
  a: {mass: m, position: [l/2*sin(th), -l/2*cos(th)], inertia: m*l**2/12, angular_velocity: th_dot}
  b: {mass: m, position: [l*sin(th) + l/2*sin(th + ph), -l*cos(th) - l/2*cos(th + ph)], inertia: m*l**2/12, angular_velocity: th_dot + ph_dot}
forces: {generalized: {th: -c*ph_dot, ph: -c*ph_dot}}
"""


def test_planar_orientation_matches_the_written_out_double_pendulum() -> None:
    """`{angle: EXPR}` with `relative_to`, a pivot at a point and a scalar torque give the equations of the same
    compound double pendulum written with version 1 keys; draw points may be point references."""
    ours, theirs = derive(parse(PLANAR, "planar.yaml")), derive(parse(PLANAR_V1, "v1.yaml"))
    assert sp.simplify(ours.mass_matrix - theirs.mass_matrix) == sp.zeros(2, 2)
    assert sp.simplify(ours.forcing - theirs.forcing) == sp.zeros(2, 1)
    spec = parse(PLANAR, "planar.yaml")
    assert spec.draw is not None and [p.label for p in spec.draw.trails] == ["b"]
    assert sp.simplify(spec.draw.segments[0][1].position[0] - sp.sympify("l*sin(th)")) == 0


def test_animate_draws_the_axes_of_oriented_bodies() -> None:
    """`lagrange animate` draws each oriented body's axes from its centre along the columns of R (the planar
    rod 'a' turned by th: its x axis is (cos th, sin th)), in red, green (and blue), `AXIS_SHARE` of the view
    long whatever the system's size, and the axes' ends do not size the view."""
    import numpy as np

    from lagrange_cli.animate import AXIS_COLOURS, AXIS_SHARE, animation, scene, simulate_for

    spec = parse(PLANAR, "planar.yaml")
    model = derive(spec)
    drawn = scene(spec, model)
    assert len(drawn.segments) == 2 + 2 * 2  # the draw block's, and two axes per planar body
    assert drawn.axes == (0, 1, 0, 1)
    labels = [drawn.labels[b] for _, b in drawn.segments[2:]]
    assert labels == ["a x axis", "a y axis", "b x axis", "b y axis"]
    a, x_end = drawn.segments[2]
    th = sp.Symbol("th")
    offset = [sp.simplify(e - c) for e, c in zip(drawn.points[x_end], drawn.points[a], strict=True)]
    assert offset == [sp.cos(th), sp.sin(th)]
    b, _ = drawn.segments[4]
    assert sp.simplify(drawn.points[drawn.segments[4][1]][0] - drawn.points[b][0] - sp.cos(th + sp.Symbol("ph"))) == 0
    movie = animation(spec, model, simulate_for(model, fps=4, t_end=0.5), fps=4)
    lines = movie.segments[2:]
    assert [line.get_color() for line in lines] == [AXIS_COLOURS[k] for k in drawn.axes]
    movie.update(1)
    half = (movie.axes.get_xlim()[1] - movie.axes.get_xlim()[0]) / 2
    for line in lines:
        xs, ys = line.get_data()
        assert np.hypot(xs[1] - xs[0], ys[1] - ys[0]) == pytest.approx(AXIS_SHARE * half)
