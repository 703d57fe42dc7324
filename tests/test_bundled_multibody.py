"""The bundled version 2 multibody systems against independent models: sympy.physics.mechanics
(frames with orient_body_fixed / orient_axis, inertia dyadics, LagrangesMethod) for the heavy top
with an off-axis disk, the 3-D rolling disk, the gimbal gyroscope and the 3-DOF arm, and the
textbook cart-pole and quadrotor linearizations written out here by hand."""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from sympy.physics import mechanics as me

from lagrange_cli import api, derive, spec
from tests.helpers import load_module

SYSTEMS = Path(__file__).resolve().parent.parent / "systems"
TOL = 1e-9


def _module(name: str, tmp_path: Path) -> object:
    system = api.load(SYSTEMS / f"{name}.yaml")
    return load_module(system.to("python"), tmp_path / f"{name}_eom.py")


def _accelerations(module: object, state: list[float], **u: object) -> np.ndarray:
    """q_ddot (then the multipliers, with kept constraints) from the generated module."""
    y = np.array(state, dtype=float)
    if hasattr(module, "accelerations"):
        return np.asarray(module.accelerations(0.0, y, module.PARAMETERS, **u), dtype=float)  # type: ignore[attr-defined]
    return np.asarray(module.rhs(0.0, y, module.PARAMETERS, **u), dtype=float)[len(state) // 2 :]  # type: ignore[attr-defined]


def _defaults(name: str) -> dict[str, float]:
    parsed = spec.load(SYSTEMS / f"{name}.yaml")
    return {p.name: float(p.value) for p in parsed.parameters}


def _lagranges_accelerations(lm: me.LagrangesMethod, q: list, values: dict, n_lambda: int = 0) -> np.ndarray:
    """q_ddot (and the multipliers) of a LagrangesMethod at the numeric `values` (symbols and
    dynamicsymbols q, q_dot replaced by numbers)."""
    qd = [sp.diff(x, me.dynamicsymbols._t) for x in q]
    mass = lm.mass_matrix_full
    forcing = lm.forcing_full
    table = {**{a: values[a] for a in qd}, **{a: values[a] for a in q}, **{s: v for s, v in values.items() if isinstance(s, sp.Symbol)}}
    m_num = np.array(me.msubs(mass, table).evalf(), dtype=float)
    f_num = np.array(me.msubs(forcing, table).evalf(), dtype=float).ravel()
    solution = np.linalg.solve(m_num, f_num)
    n = len(q)
    return solution[n : 2 * n + n_lambda]


def _heavy_top_sympy(p: dict[str, float]) -> tuple[me.LagrangesMethod, list]:
    phi, theta, psi = me.dynamicsymbols("phi theta psi")
    n = me.ReferenceFrame("N")
    b = me.ReferenceFrame("B")
    b.orient_body_fixed(n, (phi, theta, psi), "zxz")
    o = me.Point("O")
    o.set_vel(n, 0)
    g_star = o.locatenew("G", p["e"] * b.x + p["l"] * b.z)
    g_star.v2pt_theory(o, n, b)
    m, r, beta = p["m"], p["r"], p["beta"]
    # the disk's principal moments about its own axes, turned by beta about body x (the dyadic does the rotation)
    disk = me.ReferenceFrame("D")
    disk.orient_axis(b, b.x, beta)
    inertia = me.inertia(disk, m * r**2 / 4, m * r**2 / 4, m * r**2 / 2)
    body = me.RigidBody("top", g_star, b, m, (inertia, g_star))
    body.potential_energy = m * p["g"] * g_star.pos_from(o).dot(n.z)
    lm = me.LagrangesMethod(me.Lagrangian(n, body), [phi, theta, psi], frame=n)
    lm.form_lagranges_equations()
    return lm, [phi, theta, psi]


def test_heavy_top_offaxis_disk_accelerations_match_sympy_mechanics(tmp_path: Path) -> None:
    p = _defaults("heavy_top_offaxis_disk")
    lm, q = _heavy_top_sympy(p)
    module = _module("heavy_top_offaxis_disk", tmp_path)
    rng = random.Random(13)
    for _ in range(4):
        qs = [rng.uniform(-3, 3), rng.uniform(0.3, 2.8), rng.uniform(-3, 3)]
        vs = [rng.uniform(-5, 5) for _ in range(3)]
        values = {**dict(zip(q, qs, strict=True)), **{sp.diff(a, me.dynamicsymbols._t): v for a, v in zip(q, vs, strict=True)}}
        expected = _lagranges_accelerations(lm, q, values)
        got = _accelerations(module, qs + vs)[:3]
        assert np.allclose(got, expected, rtol=TOL, atol=TOL), (got, expected)


def test_heavy_top_offaxis_disk_is_not_symmetric() -> None:
    """The disk's tilt and offset matter: psi is not ignorable (dL/dpsi != 0 at a random state)."""
    model = derive.derive(spec.load(SYSTEMS / "heavy_top_offaxis_disk.yaml"))
    assert not model.ignorable(model.coordinates.index("psi"))
    assert model.ignorable(model.coordinates.index("phi"))


def _rolling_disk_sympy(p: dict[str, float]) -> tuple[me.LagrangesMethod, list, me.Point, me.ReferenceFrame]:
    x, y, psi, theta, phi = me.dynamicsymbols("x y psi theta phi")
    n = me.ReferenceFrame("N")
    lean = me.ReferenceFrame("L")
    lean.orient_body_fixed(n, (psi, theta, 0), "zxy")
    disk = me.ReferenceFrame("D")
    disk.orient_axis(lean, lean.y, phi)
    o = me.Point("O")
    o.set_vel(n, 0)
    contact = o.locatenew("C", x * n.x + y * n.y)
    centre = contact.locatenew("G", p["R"] * lean.z)
    centre.set_vel(n, centre.pos_from(o).dt(n))
    m, radius = p["m"], p["R"]
    body = me.RigidBody("coin", centre, disk, m, (me.inertia(disk, m * radius**2 / 4, m * radius**2 / 2, m * radius**2 / 4), centre))
    body.potential_energy = m * p["g"] * centre.pos_from(o).dot(n.z)
    # the material point at the contact is still (the horizontal components; the vertical one holds by the geometry)
    slip = centre.vel(n) + disk.ang_vel_in(n).cross(-radius * lean.z)
    constraints = [slip.dot(n.x), slip.dot(n.y)]
    q = [x, y, psi, theta, phi]
    lm = me.LagrangesMethod(me.Lagrangian(n, body), q, nonhol_coneqs=constraints, frame=n)
    lm.form_lagranges_equations()
    return lm, q, centre, n


def test_rolling_disk_3d_accelerations_match_sympy_mechanics(tmp_path: Path) -> None:
    p = _defaults("rolling_disk_3d")
    lm, q, centre, n = _rolling_disk_sympy(p)
    module = _module("rolling_disk_3d", tmp_path)
    t = me.dynamicsymbols._t
    rng = random.Random(31)
    for _ in range(4):
        psi, theta, phi = rng.uniform(-3, 3), rng.uniform(-1.2, 1.2), rng.uniform(-3, 3)
        psi_d, theta_d, phi_d = (rng.uniform(-4, 4) for _ in range(3))
        # velocities on the constraint manifold
        x_d, y_d = p["R"] * np.cos(psi) * phi_d, p["R"] * np.sin(psi) * phi_d
        qs = [rng.uniform(-1, 1), rng.uniform(-1, 1), psi, theta, phi]
        vs = [x_d, y_d, psi_d, theta_d, phi_d]
        values = {**dict(zip(q, qs, strict=True)), **{sp.diff(a, t): v for a, v in zip(q, vs, strict=True)}}
        expected = _lagranges_accelerations(lm, q, values)
        result = _accelerations(module, qs + vs)
        assert np.allclose(result[:5], expected, rtol=TOL, atol=TOL), (result[:5], expected)
        # the multipliers are the friction force of the plane: m times the centre's horizontal acceleration
        acceleration = centre.vel(n).dt(n)
        table = {**{sp.diff(a, t, 2): v for a, v in zip(q, result[:5], strict=True)}, **{sp.diff(a, t): v for a, v in zip(q, vs, strict=True)}, **dict(zip(q, qs, strict=True))}
        friction = [p["m"] * float(me.msubs(acceleration.dot(axis), table)) for axis in (n.x, n.y)]
        assert np.allclose(result[5:7], friction, rtol=TOL, atol=TOL), (result[5:7], friction)


def test_gyroscope_gimbals_accelerations_match_sympy_mechanics(tmp_path: Path) -> None:
    p = _defaults("gyroscope_gimbals")
    alpha, beta, gamma = me.dynamicsymbols("alpha beta gamma")
    n = me.ReferenceFrame("N")
    outer, inner, rotor = me.ReferenceFrame("O"), me.ReferenceFrame("I"), me.ReferenceFrame("R")
    outer.orient_axis(n, n.z, alpha)
    inner.orient_axis(outer, outer.x, beta)
    rotor.orient_axis(inner, inner.z, gamma)
    o = me.Point("O")
    o.set_vel(n, 0)
    bodies = [
        me.RigidBody("outer", o, outer, p["M_o"], (me.inertia(outer, p["J"], p["J"], p["J"]), o)),
        me.RigidBody("inner", o, inner, p["M_i"], (me.inertia(inner, p["B1"], p["B2"], p["B3"]), o)),
        me.RigidBody("rotor", o, rotor, p["M_r"], (me.inertia(rotor, p["A"], p["A"], p["C"]), o)),
    ]
    q = [alpha, beta, gamma]
    lm = me.LagrangesMethod(me.Lagrangian(n, *bodies), q, frame=n)
    lm.form_lagranges_equations()
    module = _module("gyroscope_gimbals", tmp_path)
    rng = random.Random(5)
    for _ in range(3):
        qs = [rng.uniform(-3, 3), rng.uniform(0.3, 2.8), rng.uniform(-3, 3)]
        vs = [rng.uniform(-5, 5) for _ in range(3)]
        values = {**dict(zip(q, qs, strict=True)), **{sp.diff(a, me.dynamicsymbols._t): v for a, v in zip(q, vs, strict=True)}}
        expected = _lagranges_accelerations(lm, q, values)
        got = _accelerations(module, qs + vs)[:3]
        assert np.allclose(got, expected, rtol=TOL, atol=TOL), (got, expected)


def test_arm_3dof_accelerations_with_torques_match_sympy_mechanics(tmp_path: Path) -> None:
    p = _defaults("arm_3dof")
    q = list(me.dynamicsymbols("q1 q2 q3"))
    n = me.ReferenceFrame("N")
    base, upper, fore = me.ReferenceFrame("B"), me.ReferenceFrame("U"), me.ReferenceFrame("F")
    base.orient_axis(n, n.z, q[0])
    upper.orient_axis(base, base.y, q[1])
    fore.orient_axis(upper, upper.y, q[2])
    o = me.Point("O")
    o.set_vel(n, 0)
    shoulder = o.locatenew("S", p["h"] * base.z)
    elbow = shoulder.locatenew("E", p["l1"] * upper.x)
    g_base = o.locatenew("Gb", p["h"] / 2 * base.z)
    g_upper = shoulder.locatenew("Gu", p["l1"] / 2 * upper.x)
    g_fore = elbow.locatenew("Gf", p["l2"] / 2 * fore.x)
    for point in (g_base, g_upper, g_fore):
        point.set_vel(n, point.pos_from(o).dt(n))
    m0, m1, m2, h, l1, l2 = p["m0"], p["m1"], p["m2"], p["h"], p["l1"], p["l2"]
    bodies = [
        me.RigidBody("base", g_base, base, m0, (me.inertia(base, m0 * h**2 / 12, m0 * h**2 / 12, p["J0"]), g_base)),
        me.RigidBody("upper", g_upper, upper, m1, (me.inertia(upper, 0, m1 * l1**2 / 12, m1 * l1**2 / 12), g_upper)),
        me.RigidBody("fore", g_fore, fore, m2, (me.inertia(fore, 0, m2 * l2**2 / 12, m2 * l2**2 / 12), g_fore)),
    ]
    for body in bodies:
        body.potential_energy = body.mass * p["g"] * body.masscenter.pos_from(o).dot(n.z)
    taus = (0.7, -1.3, 0.4)
    loads = [(base, taus[0] * n.z - taus[1] * base.y), (upper, taus[1] * upper.y - taus[2] * upper.y), (fore, taus[2] * fore.y)]
    lm = me.LagrangesMethod(me.Lagrangian(n, *bodies), q, forcelist=loads, frame=n)
    lm.form_lagranges_equations()
    module = _module("arm_3dof", tmp_path)
    u = dict(zip(("tau1", "tau2", "tau3"), taus, strict=True))
    rng = random.Random(3)
    for _ in range(3):
        qs = [rng.uniform(-3, 3) for _ in range(3)]
        vs = [rng.uniform(-3, 3) for _ in range(3)]
        values = {**dict(zip(q, qs, strict=True)), **{sp.diff(a, me.dynamicsymbols._t): v for a, v in zip(q, vs, strict=True)}}
        expected = _lagranges_accelerations(lm, q, values)
        got = _accelerations(module, qs + vs, u=u)[:3]
        assert np.allclose(got, expected, rtol=TOL, atol=TOL), (got, expected)


def _state_space(name: str, about: dict[str, float] | None = None) -> dict[str, np.ndarray]:
    result = api.load(SYSTEMS / f"{name}.yaml").state_space(about)
    return {k: np.asarray(result[k], dtype=float) for k in ("A", "B", "C", "D")}


def test_cart_pole_state_space_is_the_textbook_linearization() -> None:
    """Derived by hand from (M + m) x'' + m l cos(th) th'' - m l sin(th) th'^2 = F and
    (4/3) l th'' + cos(th) x'' - g sin(th) = 0 (pole of length 2 l, I = m l^2/3) at th = 0."""
    p = _defaults("cart_pole_state_space")
    big, m, half, g = p["M"], p["m"], p["l"], p["g"]
    d = 4 * big + m
    a = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [0, -3 * m * g / d, 0, 0], [0, 3 * (big + m) * g / (half * d), 0, 0]])
    b = np.array([[0], [0], [4 / d], [-3 / (half * d)]])
    got = _state_space("cart_pole_state_space", {"theta": 0})
    assert np.allclose(got["A"], a, rtol=TOL, atol=TOL)
    assert np.allclose(got["B"], b, rtol=TOL, atol=TOL)
    assert np.allclose(got["C"], [[1, 0, 0, 0], [0, 1, 0, 0]])
    assert np.allclose(got["D"], [[0], [0]])
    # the open loop's unstable eigenvalue
    assert max(np.linalg.eigvals(got["A"]).real) == pytest.approx(np.sqrt(3 * (big + m) * g / (half * d)), rel=1e-9)


def test_quadrotor_hover_is_the_small_angle_model() -> None:
    p = _defaults("quadrotor")
    g, m, arm, k = p["g"], p["m"], p["L"], p["k"]
    got = _state_space("quadrotor")
    a = np.zeros((12, 12))
    a[:6, 6:] = np.eye(6)
    a[6, 4], a[7, 5] = g, -g
    b = np.zeros((12, 4))
    b[8] = 1 / m
    b[9] = [k / p["Izz"], -k / p["Izz"], k / p["Izz"], -k / p["Izz"]]
    b[10] = [-arm / p["Iyy"], 0, arm / p["Iyy"], 0]
    b[11] = [0, arm / p["Ixx"], 0, -arm / p["Ixx"]]
    assert np.allclose(got["A"], a, rtol=TOL, atol=TOL)
    assert np.allclose(got["B"], b, rtol=TOL, atol=TOL)


@pytest.mark.parametrize("name", ["heavy_top_offaxis_disk", "gyroscope_gimbals", "arm_3dof", "rolling_disk_3d", "quadrotor", "cart_pole_state_space"])
def test_bundled_multibody_system_checks(name: str) -> None:
    report = api.load(SYSTEMS / f"{name}.yaml").check()
    assert report.passed, report.json()
