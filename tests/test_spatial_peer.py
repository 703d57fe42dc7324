"""Spatial systems written with the FORMAT.md version 2 keys against sympy.physics.mechanics
(issue 13: "We will compare against sympy.physics.mechanics on hidden spatial systems written with
the version 2 keys, including accelerations, multipliers and state-space matrices").

Each system is one description (tests/spatial_peer.py) written twice: as a YAML file for
`lagrange` and as an independent sympy.physics.mechanics model. Compared at seeded random states
and perturbed parameters, to a relative tolerance of 1e-8: the accelerations, the multipliers
(ours: M q_ddot = F + A^T lambda, A = d(lhs - rhs)/dq; LagrangesMethod's `mass_matrix_full`
[M, -A^T] [q_ddot; lambda] = F with its A from the same expression: the same lambda), the named
constraint force (forces.py) and the state-space matrices A, B, C, D of `linearize --json` and
`System.state_space()` (the peer's: the Jacobian of its first-order equations at the operating
point, an equilibrium held by non-zero inputs)."""

from __future__ import annotations

import json
import math
import random
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from sympy.physics import mechanics as me

from lagrange_cli import api
from lagrange_cli.kinematics import SEQUENCES
from tests.limits import DEADLOCK
from tests.spatial_peer import BodyDesc, Load, Orient, ParticleDesc, System, call, close, constrained_state, lagrange_module, lagrange_solve, manifold_state_space, perturbed, random_state

ROOT = Path(__file__).resolve().parent.parent
FULL = (("0.5", "0.05", "-0.03"), ("0.05", "0.7", "0.02"), ("-0.03", "0.02", "0.9"))
"""An inertia tensor with products of inertia (positive definite)."""


def compare_accelerations(system: System, tmp_path: Path, seed: int, states: int = 3) -> None:
    peer = system.peer()
    module = lagrange_module(system.yaml(), tmp_path / f"m{seed}.py")
    rng = random.Random(seed)
    for k in range(states):
        p = system.parameters if k == 0 else perturbed(system.parameters, rng)
        u = {name: rng.uniform(-2, 2) for name in system.inputs}
        q, qd = constrained_state(system, peer, rng, p) if system.constraints else random_state(len(system.coordinates), rng)
        expected, lam_peer = peer.solve(q, qd, p, u)
        got, lam = lagrange_solve(module, q, qd, p, u, peer.n_lambda)
        assert close(got, expected), (system.yaml(), q, qd, p, got, expected)
        assert close(lam, lam_peer), ("multipliers", lam, lam_peer)


def sequence_system(sequence: str, kind: str) -> System:
    """One body about a fixed pivot, its three angles driven by two coordinates (all three rates
    non-zero), full inertia, a body-axes force at a point and a world-axes torque, gravity."""
    return System(
        coordinates=["a", "b"],
        parameters={"m": 1.3, "l": 0.7, "g": 9.81, "k": 0.4},
        gravity=("0", "0", "-g"),
        bodies=[
            BodyDesc(
                "B",
                "m",
                Orient(kind, sequence=sequence, angles=("a", "b", "a - 2*b")),
                FULL,
                pivot=("0", "0", "0"),
                center=("l", "0.1", "-0.2"),
                points={"tip": ("0.2", "l", "0.1")},
                forces=[Load(("k*a_dot", "0", "0.3"), "body", "tip")],
                torques=[Load(("0.1", "-k*b", "0.2"), "world")],
            )
        ],
    )


@pytest.mark.parametrize("kind", ["body", "space"])
@pytest.mark.parametrize("sequence", SEQUENCES)
def test_every_sequence_matches_sympy_mechanics(sequence: str, kind: str, tmp_path: Path) -> None:
    compare_accelerations(sequence_system(sequence.lower() if sequence == "ZYX" else sequence, kind), tmp_path, seed=SEQUENCES.index(sequence))


def chain_system() -> System:
    """A 3-deep `relative_to` chain of light bodies: an axis and angle, a sequence relative to it,
    an explicit matrix relative to that; each pivot at a point of the previous (`BODY.POINT`), a
    particle at the last body's point, world and body loads, a bare-list force and torque."""
    matrix = (("1", "0", "0"), ("0", "cos(b)", "-sin(b)"), ("0", "sin(b)", "cos(b)"))
    return System(
        coordinates=["a", "b"],
        parameters={"m1": 1.0, "m2": 0.8, "m3": 0.5, "mp": 0.3, "l": 0.9, "g": 9.81, "c": 0.7},
        gravity=("0", "-g/3", "-g"),
        bodies=[
            BodyDesc("one", "m1", Orient("axis", axis=("0", "0", "c"), angle="a"), FULL, pivot=("0.1", "0", "0"), center=("l/2", "0", "0"), points={"end": ("l", "0.1", "0")}),
            BodyDesc(
                "two",
                "m2",
                Orient("body", sequence="ZYX", angles=("b", "0.3", "a"), relative_to="one"),
                FULL,
                pivot="one.end",
                center=("0", "l/2", "0.05"),
                points={"end": ("0", "l", "0")},
                forces=[Load(("0", "0.5", "b"), plain=True)],
                torques=[Load(("a_dot", "0", "0.2"), plain=True)],
            ),
            BodyDesc(
                "three",
                "m3",
                Orient("matrix", matrix=matrix, relative_to="two"),
                (("0.2", "0", "0"), ("0", "0.3", "0.01"), ("0", "0.01", "0.25")),
                pivot="two.end",
                center=("0.1", "0", "l/3"),
                points={"tip": ("0", "0", "l")},
                forces=[Load(("0.2", "-0.1", "0.3*a"), "body", "three.tip"), Load(("1", "0", "0"), "world", "three")],
                torques=[Load(("0", "0.3", "b_dot"), "body")],
            ),
        ],
        particles=[ParticleDesc("bob", "mp", "three.tip", force=("0", "0.1", "0"))],
    )


def test_relative_to_chain_with_points_and_a_particle_matches_sympy_mechanics(tmp_path: Path) -> None:
    compare_accelerations(chain_system(), tmp_path, seed=7)


def test_body_positioned_at_a_reference_matches_sympy_mechanics(tmp_path: Path) -> None:
    """`position: BODY.POINT` (no pivot: the centre of mass there, points from it), and a body
    whose position is another body's name (its centre of mass, not its pivot)."""
    system = System(
        coordinates=["a", "b"],
        parameters={"m1": 1.0, "m2": 0.6, "l": 0.8, "g": 9.81},
        gravity=("0", "0", "-g"),
        bodies=[
            BodyDesc("arm", "m1", Orient("space", sequence="ZXY", angles=("a", "b", "0.2")), FULL, pivot=("0", "0", "0.5"), center=("0", "0", "-l/2"), points={"hand": ("0.1", "0", "-l")}),
            BodyDesc(
                "ball",
                "m2",
                Orient("axis", axis=("0", "1", "1"), angle="b - a", relative_to="arm"),
                FULL,
                position="arm.hand",
                points={"spot": ("0.1", "0.2", "0")},
                forces=[Load(("0", "1", "0"), "world", "spot")],
            ),
            BodyDesc("ghost", "m2", Orient("body", sequence="XYX", angles=("a", "b", "a")), FULL, position="arm"),
        ],
    )
    compare_accelerations(system, tmp_path, seed=11)


def test_axis_and_angle_about_a_parameter_axis_matches_sympy_mechanics(tmp_path: Path) -> None:
    """An axis with parameters (normalised by the tool) relative to a sequence-oriented body."""
    system = System(
        coordinates=["a", "b"],
        parameters={"m1": 1.0, "m2": 0.8, "l": 0.9, "g": 9.81, "c": 0.7},
        gravity=("0", "0", "-g"),
        bodies=[
            BodyDesc("one", "m1", Orient("axis", axis=("1", "2", "c"), angle="a"), FULL, pivot=("0", "0", "0"), center=("l/2", "0", "0"), points={"end": ("l", "0", "0")}),
            BodyDesc("two", "m2", Orient("axis", axis=("c", "0", "-1"), angle="b", relative_to="one"), FULL, pivot="one.end", center=("0", "l/2", "0"), torques=[Load(("0", "0.5", "0"), "body")]),
        ],
    )
    compare_accelerations(system, tmp_path, seed=5)


def input_system() -> System:
    """A yawing arm carrying a pitching link: a torque input on the link (body axes) and a force
    input at the arm's tip (world axes), outputs of the state and the inputs."""
    return System(
        coordinates=["q1", "q2"],
        parameters={"m1": 1.0, "m2": 0.7, "l1": 0.6, "l2": 0.9, "g": 9.81, "c": 0.3},
        gravity=("0", "0", "-g"),
        inputs={"tau": 0.0, "F": 0.0},
        outputs={"tip_height": "-l2*sin(q2)", "yaw_rate": "q1_dot + c*q2_dot", "drive": "tau + 2*F*q1"},
        bodies=[
            BodyDesc(
                "arm",
                "m1",
                Orient("axis", axis=("0", "0", "1"), angle="q1"),
                FULL,
                pivot=("0", "0", "0"),
                center=("l1/2", "0", "0"),
                points={"tip": ("l1", "0", "0")},
                forces=[Load(("0", "F", "0"), "world", "tip")],
            ),
            BodyDesc(
                "link", "m2", Orient("body", sequence="YZX", angles=("q2", "0", "0"), relative_to="arm"), FULL, pivot="arm.tip", center=("l2", "0", "0"), torques=[Load(("0", "tau", "0"), "body")]
            ),
        ],
    )


def test_inputs_match_sympy_mechanics(tmp_path: Path) -> None:
    compare_accelerations(input_system(), tmp_path, seed=3)


def peer_state_space(system: System, q0: list[float], u0: dict[str, float], p: dict[str, float]) -> dict[str, np.ndarray]:
    """The peer's A, B, C, D: the Jacobian of its first-order equations [q_dot; M^-1 F] at the
    operating point (F = 0 there, so d(M^-1 F) = M^-1 dF), and of its outputs."""
    peer = system.peer()
    n = len(q0)
    values = {**dict(zip(peer.q_symbols, q0, strict=True)), **dict.fromkeys(peer.qd_symbols, 0.0), **{sp.Symbol(k): v for k, v in p.items()}, **{sp.Symbol(k): v for k, v in u0.items()}}
    state = [*peer.q_symbols, *peer.qd_symbols]
    mass = np.array(peer.mass_full.xreplace(values).evalf(), dtype=float)
    forcing = peer.forcing_full
    assert np.abs(np.array(forcing.xreplace(values).evalf(), dtype=float)).max() < 1e-9, "not an equilibrium"
    a = np.linalg.solve(mass, np.array(forcing.jacobian(state).xreplace(values).evalf(), dtype=float))
    b = np.linalg.solve(mass, np.array(forcing.jacobian(peer.inputs).xreplace(values).evalf(), dtype=float))
    h = sp.Matrix(peer.outputs)
    c = np.array(h.jacobian(state).xreplace(values).evalf(), dtype=float)
    d = np.array(h.jacobian(peer.inputs).xreplace(values).evalf(), dtype=float)
    assert a.shape == (2 * n, 2 * n)
    return {"A": a, "B": b, "C": c, "D": d}


def test_state_space_at_a_nonzero_input_matches_sympy_mechanics(tmp_path: Path) -> None:
    """The link held at q2 = 0.4 by the torque input (tau0 = its weight's moment), the arm at
    q1 = 0.3: `linearize --about ... --json` and `System.state_space()` against the peer."""
    system = input_system()
    p = system.parameters
    q0 = [0.3, 0.4]
    tau0 = -p["m2"] * p["g"] * p["l2"] * np.cos(q0[1])  # the link's weight about its pitch axis, balanced
    peer_probe = system.peer()
    # find tau0 from the peer itself: the q2 row of F vanishes
    values = {**dict(zip(peer_probe.q_symbols, q0, strict=True)), **dict.fromkeys(peer_probe.qd_symbols, 0.0), **{sp.Symbol(k): v for k, v in p.items()}, sp.Symbol("F"): 0.0}
    row = sp.Matrix(peer_probe.forcing_full).xreplace(values)[3]
    tau0 = float(sp.solve(row, sp.Symbol("tau"))[0])
    u0 = {"tau": tau0, "F": 0.0}
    expected = peer_state_space(system, q0, u0, p)
    path = tmp_path / "arm.yaml"
    path.write_text(system.yaml())
    about = f"q1={q0[0]!r},q2={q0[1]!r},tau={tau0!r}"
    done = subprocess.run([sys.executable, "-m", "lagrange_cli", "linearize", str(path), "--about", about, "--json"], capture_output=True, text=True, timeout=DEADLOCK, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout)
    assert found["state"] == ["q1", "q2", "q1_dot", "q2_dot"] and found["inputs"] == ["tau", "F"] and found["outputs"] == list(system.outputs)
    for key in "ABCD":
        assert close(found[key], expected[key]), (key, found[key], expected[key])
    arrays = api.from_text(system.yaml()).state_space({"q1": q0[0], "q2": q0[1], "tau": tau0})
    for key in "ABCD":
        assert close(arrays[key], expected[key]), (key, arrays[key], expected[key])
        symbolic = arrays["symbolic"][key]  # the symbolic matrices, at the parameters' values, are the numeric ones
        table = {sp.Symbol(k): v for k, v in p.items()}
        assert symbolic is not None and close(np.array(symbolic.xreplace(table).evalf(), dtype=float).reshape(expected[key].shape), expected[key]), key


def test_state_space_with_perturbed_parameters_matches_sympy_mechanics() -> None:
    """The same at other parameter values (written as the file's defaults) and another pitch, held by
    the torque input (nothing holds the yaw against the force input, so F0 = 0)."""
    rng = random.Random(29)
    system = input_system()
    system.parameters = perturbed(system.parameters, rng)
    p = system.parameters
    q0 = [0.0, -0.7]
    probe = system.peer()
    values = {**dict(zip(probe.q_symbols, q0, strict=True)), **dict.fromkeys(probe.qd_symbols, 0.0), **{sp.Symbol(k): v for k, v in p.items()}, sp.Symbol("F"): 0.0}
    tau0 = float(sp.solve(sp.Matrix(probe.forcing_full).xreplace(values)[3], sp.Symbol("tau"))[0])
    u0 = {"tau": tau0, "F": 0.0}
    expected = peer_state_space(system, q0, u0, p)
    arrays = api.from_text(system.yaml()).state_space({"q1": q0[0], "q2": q0[1], "tau": tau0})
    for key in "ABCD":
        assert close(arrays[key], expected[key]), (key, arrays[key], expected[key])


def wall_system() -> System:
    """A body sliding in a plane whose point `tip` is kept on the wall x = 0 (a kept holonomic
    constraint written on that point's world position), pushed by force and torque inputs."""
    return System(
        coordinates=["x", "y", "th"],
        parameters={"m": 1.2, "a": 0.6, "g": 9.81},
        gravity=("0", "-g", "0"),
        inputs={"Fx": 0.0, "Fy": 0.0, "tau": 0.0},
        outputs={"tip_y": "y + a*sin(th)", "spin": "th_dot + Fx"},
        constraints={"wall": "x + a*cos(th)"},
        bodies=[
            BodyDesc(
                "B",
                "m",
                Orient("axis", axis=("0", "0", "1"), angle="th"),
                FULL,
                position=("x", "y", "0"),
                points={"tip": ("a", "0", "0")},
                forces=[Load(("Fx", "Fy", "0"), "world")],
                torques=[Load(("0", "0", "tau"), "body")],
            )
        ],
    )


def test_constraint_at_a_body_point_multipliers_and_force_match_sympy_mechanics(tmp_path: Path) -> None:
    """Accelerations and the multiplier (the same as LagrangesMethod's), and `constraint_forces` (with the inputs): the wall's push lambda * e_x at the tip,
    and its moment about the centre in body axes, from the peer's points."""
    system = wall_system()
    compare_accelerations(system, tmp_path, seed=17, states=2)
    peer = system.peer()
    module = lagrange_module(system.yaml(), tmp_path / "wall.py")
    rng = random.Random(23)
    for _ in range(2):
        p = perturbed(system.parameters, rng)
        u = {k: rng.uniform(-2, 2) for k in system.inputs}
        q, qd = constrained_state(system, peer, rng, p)
        _, lam_peer = peer.solve(q, qd, p, u)
        lam = lam_peer[0]
        found = call(module, "constraint_forces", 0.0, [*q, *qd], p, u)["wall"]
        assert close([found["lambda"]], [lam])
        info = peer.wrench
        values = {**dict(zip(peer.q, q, strict=True)), **{sp.Symbol(k): v for k, v in p.items()}}
        force = lam * info["N"].x
        arm = info["points"]["B.tip"].pos_from(info["centres"]["B"])
        torque = me.msubs(arm.cross(force).to_matrix(info["frames"]["B"]), values)
        on = found["on"]["B"]
        assert close(on["force"], [lam, 0.0, 0.0]), on
        assert close(on["torque"], np.array(torque.evalf(), dtype=float).ravel()), (on, torque)
        assert close([on["N"]], [lam])  # along the gradient of x_tip: N = lambda
        # the API's symbolic directions (System.constraint_forces): exact here, the same force and torque
        fm = api.from_text(system.yaml()).constraint_forces
        assert fm.status == "exact"
        table = {**{sp.Symbol(c): v for c, v in zip(system.coordinates, [*q], strict=True)}, **{sp.Symbol(k): v for k, v in p.items()}}
        for (carrier, kind), ws in fm.on(0).items():
            assert carrier == "B"
            value = [lam * float(sp.sympify(w).xreplace(table)) for w in ws]
            assert close(value, on[kind]), (kind, value, on[kind])


def test_state_space_with_a_kept_constraint_matches_sympy_mechanics(tmp_path: Path) -> None:
    """About th = 0.5 held by the inputs (the wall pushes back: lambda0 = -Fx0 != 0), in the
    independent coordinates `lagrange` names: A, B, C, D against the peer's on the constraint."""
    system = wall_system()
    p = system.parameters
    th0 = 0.5
    x0 = -p["a"] * math.cos(th0)
    u0 = {"Fx": 1.0, "Fy": p["m"] * p["g"], "tau": -p["a"] * math.sin(th0) * 1.0}
    path = tmp_path / "wall.yaml"
    path.write_text(system.yaml())
    about = f"x={x0!r},th={th0!r}," + ",".join(f"{k}={v!r}" for k, v in u0.items())
    done = subprocess.run([sys.executable, "-m", "lagrange_cli", "linearize", str(path), "--about", about, "--json"], capture_output=True, text=True, timeout=DEADLOCK, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout)
    independent = found["state"][: len(found["state"]) // 2]
    assert len(independent) == 2 and found["inputs"] == list(system.inputs)
    expected = manifold_state_space(system, system.peer(), [x0, 0.0, th0], u0, p, independent)
    assert np.abs(expected["residual"]).max() < 1e-9
    for key in "ABCD":
        assert close(found[key], expected[key], rtol=1e-8), (key, found[key], expected[key])
    arrays = api.from_text(system.yaml()).state_space({"x": x0, "th": th0, **u0})
    table = {sp.Symbol(k): v for k, v in p.items()}
    for key in "ABCD":
        assert close(arrays[key], found[key], rtol=1e-12), key
        symbolic = arrays["symbolic"][key]
        assert symbolic is not None and close(np.array(symbolic.xreplace(table).evalf(), dtype=float).reshape(arrays[key].shape), expected[key], rtol=1e-8), key


# -- bad input: exit 2 at the file, line and column ----------------------------------------------

BASE = """coordinates: [a, b]
parameters: {m: 1.0, l: 1.0, g: 9.81}
gravity: [0, 0, -g]
particles:
  p: {mass: m, position: [l*sin(a), 0, 0]}
bodies:
  A:
    mass: m
    orientation: {sequence: ZXZ, angles: [a, b, 0]}
    pivot: [0, 0, 0]
    center: [0, 0, l]
    inertia: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    points: {tip: [0, 0, l]}
"""
ORIENTATION = "orientation: {sequence: ZXZ, angles: [a, b, 0]}"
INERTIA = "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]"
POINTS = "    points: {tip: [0, 0, l]}"
WITH_U = BASE.replace("gravity:", "inputs: [u]\ngravity:")
OTHER = "  B:\n    mass: m\n    orientation: {axis: [0, 0, 1], angle: b, relative_to: A}\n    pivot: [0, 0, 0]\n    inertia: [1, 1, 1]\n"
BAD = {
    # the list
    "not_orthonormal": (BASE.replace(ORIENTATION, "orientation: {matrix: [[1, 0, 0], [0, 1, 0], [0, 0.5, 1]]}"), "9:27", "is not a rotation"),
    "reflection": (BASE.replace(ORIENTATION, "orientation: {matrix: [[-1, 0, 0], [0, 1, 0], [0, 0, 1]]}"), "9:27", "a reflection"),
    "unknown_sequence": (BASE.replace("ZXZ", "ZZX"), "9:29", "unknown sequence 'ZZX'"),
    "relative_to_cycle": (BASE.replace("angles: [a, b, 0]}", "angles: [a, b, 0], relative_to: B}") + OTHER, "16:59", "cycle: A -> B -> A"),
    "missing_body": (BASE.replace("pivot: [0, 0, 0]", "pivot: Z.tip"), "10:12", "there is no body 'Z'"),
    "missing_point": (BASE.replace("position: [l*sin(a), 0, 0]", "position: A.top"), "5:26", "has no point 'top'"),
    "not_symmetric": (BASE.replace(INERTIA, "[[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]"), "12:29", "is not symmetric"),
    "not_psd": (BASE.replace(INERTIA, "[[1, 2, 0], [2, 1, 0], [0, 0, 1]]"), "12:14", "not positive semi-definite"),
    "input_unused": (WITH_U, "3:10", "input 'u' is used nowhere"),
    "angular_velocity_too": (BASE.replace(POINTS, POINTS + "\n    angular_velocity: [a, b, 0]"), "14:23", "gives both 'angular_velocity' and 'orientation'"),
    # variants
    "relative_to_itself": (BASE.replace("angles: [a, b, 0]}", "angles: [a, b, 0], relative_to: A}"), "9:66", "cycle: A -> A"),
    "two_letter_sequence": (BASE.replace("ZXZ", "ZX"), "9:29", "unknown sequence 'ZX'"),
    "matrix_two_rows": (BASE.replace(ORIENTATION, "orientation: {matrix: [[1, 0, 0], [0, 1, 0]]}"), "9:27", "has 2 rows"),
    "matrix_short_row": (BASE.replace(ORIENTATION, "orientation: {matrix: [[1, 0, 0], [0, 1], [0, 0, 1]]}"), "9:39", "has 2 components"),
    "matrix_flat": (BASE.replace(ORIENTATION, "orientation: {matrix: [1, 0, 0, 0, 1, 0, 0, 0, 1]}"), "9:27", "has 9 rows"),
    "matrix_name": (BASE.replace(ORIENTATION, "orientation: {matrix: [[1, 0, 0], [0, foo, 0], [0, 0, 1]]}"), "9:43", "unknown name 'foo'"),
    "matrix_boolean": (BASE.replace(ORIENTATION, "orientation: {matrix: [[true, 0, 0], [0, 1, 0], [0, 0, 1]]}"), "9:29", "boolean"),
    "inertia_two_rows": (BASE.replace(INERTIA, "[[1, 0, 0], [0, 1, 0]]"), "12:14", "has 2 rows"),
    "inertia_four_entries": (BASE.replace(INERTIA, "[1, 1, 1, 1]"), "12:14", "has 4 components"),
    "three_dots": (BASE.replace("position: [l*sin(a), 0, 0]", "position: A.tip.x"), "5:26", "unknown point 'A.tip.x'"),
    "point_of_a_particle": (BASE.replace("pivot: [0, 0, 0]", "pivot: p.x"), "10:12", "unknown point 'p.x'"),
    "body_named_like_a_particle": (BASE.replace("  A:\n", "  p:\n"), "7:3", "body 'p' has the name of a particle"),
    "at_another_body": (BASE.replace(POINTS, POINTS + "\n    force: {vector: [1, 0, 0], at: Q.tip}"), "14:36", "not a point of 'A'"),
    "at_a_particle": (BASE.replace(POINTS, POINTS + "\n    force: {vector: [1, 0, 0], at: p}"), "14:36", "has no point 'p'"),
    "input_named_like_a_parameter": (BASE.replace("gravity:", "inputs: [m]\ngravity:"), "3:10", "'m' is already declared as a parameter"),
    # an input where the angular velocity or a reference point's velocity would need u_dot
    "input_in_angles": (WITH_U.replace("angles: [a, b, 0]", "angles: [a, b, u]"), "10:42", "input 'u' appears in the angles of 'A'"),
    "input_in_angle": (WITH_U.replace(ORIENTATION, "orientation: {axis: [0, 0, 1], angle: a*u}"), "10:43", "input 'u' appears in the angle of 'A'"),
    "input_in_matrix": (WITH_U.replace(ORIENTATION, "orientation: {matrix: [[cos(u), -sin(u), 0], [sin(u), cos(u), 0], [0, 0, 1]]}"), "10:27", "input 'u' appears in the orientation matrix of 'A'"),
    "input_in_pivot": (WITH_U.replace("pivot: [0, 0, 0]", "pivot: [u, 0, 0]"), "11:12", "input 'u' appears in the position of the reference point of 'A'"),
    "input_in_referenced_particle": (
        WITH_U.replace("position: [l*sin(a), 0, 0]", "position: [l*sin(a), u, 0], force: [u, 0, 0]").replace("pivot: [0, 0, 0]", "pivot: p"),
        "11:12",
        "input 'u' appears in the position of the reference point",
    ),
    # a rigid body's mass, inertia, centre and points are constant: Kane's form (v = v_ref + omega x p,
    # m v_i . a, I alpha + omega x I omega) had silently left out m_dot v, I_dot omega and the rate of p
    "mass_with_time": (BASE.replace("    mass: m\n", "    mass: m*(2 + sin(t))\n"), "8:11", "the mass of 'A' depends on time `t`"),
    "inertia_with_a_coordinate": (BASE.replace(INERTIA, "[[1, 0, 0], [0, 1, 0], [0, 0, a]]"), "12:14", "the inertia of 'A' depends on the coordinate 'a'"),
    "center_with_time": (BASE.replace("center: [0, 0, l]", "center: [0, 0, l*(1 + t)]"), "11:13", "the centre of mass of 'A' depends on time `t`"),
    "point_with_time": (BASE.replace("points: {tip: [0, 0, l]}", "points: {tip: [0, 0, t]}"), "13:19", "point 'tip' of 'A' depends on time `t`"),
    # a '.' in a body's or point's name makes `BODY.POINT` ambiguous
    "body_name_with_a_dot": (BASE.replace("  A:\n", "  A.x:\n"), "7:3", "'A.x' cannot name a body"),
    "point_name_with_a_dot": (BASE.replace("points: {tip: [0, 0, l]}", "points: {ti.p: [0, 0, l]}"), "13:14", "'ti.p' cannot name a point of 'A'"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_spatial_input_is_reported_at_its_line_and_column(case: str) -> None:
    from lagrange_cli.errors import LagrangeError

    text, where, message = BAD[case]
    with pytest.raises(LagrangeError) as raised:
        _ = api.from_text(text, f"{case}.yaml").model
    shown = str(raised.value)
    assert f"{case}.yaml:{where}: error: " in shown and message in shown, shown
    assert "Traceback" not in shown


@pytest.mark.parametrize("case", ["input_in_angles", "body_named_like_a_particle"])
def test_bad_spatial_input_exits_2_through_the_command_line(case: str, tmp_path: Path) -> None:
    path = tmp_path / f"{case}.yaml"
    text, where, message = BAD[case]
    path.write_text(text)
    done = subprocess.run([sys.executable, "-m", "lagrange_cli", "derive", str(path)], capture_output=True, text=True, timeout=DEADLOCK, cwd=tmp_path)
    assert done.returncode == 2 and f"{case}.yaml:{where}: error: " in done.stderr and message in done.stderr and "Traceback" not in done.stderr, done.stderr


def test_body_with_angular_velocity_full_inertia_and_body_torque_matches_sympy_mechanics(tmp_path: Path) -> None:
    """A version 1 body (its body-axes angular velocity written out for ZXZ angles by hand) with a full
    inertia tensor, a body-axes torque and a world force: the same as the oriented body of the peer."""
    text = """coordinates: [f, th, ps]
parameters: {m: 1.3, l: 0.7, g: 9.81}
gravity: [0, 0, -g]
bodies:
  B:
    mass: m
    position: [l*sin(f)*sin(th), -l*cos(f)*sin(th), l*cos(th)]
    angular_velocity: [f_dot*sin(th)*sin(ps) + th_dot*cos(ps), f_dot*sin(th)*cos(ps) - th_dot*sin(ps), f_dot*cos(th) + ps_dot]
    inertia: [[0.5, 0.05, -0.03], [0.05, 0.7, 0.02], [-0.03, 0.02, 0.9]]
    torque: {vector: [0.1, 0.2*th, 0.3], axes: body}
    force: [0.3, 0, f_dot]
"""
    system = System(
        ["f", "th", "ps"],
        {"m": 1.3, "l": 0.7, "g": 9.81},
        [
            BodyDesc(
                "B",
                "m",
                Orient("body", sequence="ZXZ", angles=("f", "th", "ps")),
                FULL,
                pivot=("0", "0", "0"),
                center=("0", "0", "l"),
                torques=[Load(("0.1", "0.2*th", "0.3"), "body")],
                forces=[Load(("0.3", "0", "f_dot"), plain=True)],
            )
        ],
        gravity=("0", "0", "-g"),
    )
    peer = system.peer()
    module = lagrange_module(text, tmp_path / "v1.py")
    rng = random.Random(41)
    for _ in range(3):
        q, qd = random_state(3, rng)
        expected, _ = peer.solve(q, qd, system.parameters, {})
        got, _ = lagrange_solve(module, q, qd, system.parameters, {}, 0)
        assert close(got, expected), (got, expected)
