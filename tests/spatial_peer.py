"""One description of a small spatial system, written twice: as a FORMAT.md version 2 file for
`lagrange`, and as an independent sympy.physics.mechanics model (frames oriented with
`orient_body_fixed` / `orient_space_fixed` / `orient_axis` / `orient_explicit`, points located with
`locatenew` and their velocities from `pos_from(O).dt(N)`, `RigidBody` with an inertia dyadic,
`Particle`, loads as (point, vector) and (frame, vector)). The peer is KanesMethod with u = q_dot
(LagrangesMethod with `hol_coneqs` when constraints are kept, for the multipliers).

Shared by tests/test_spatial_peer.py (small cases) and benchmarks/spatial_peer_study.py (a
randomized study): both compare accelerations, multipliers and state-space matrices.

Expressions are strings read by both sides: by `lagrange` from the YAML, by sympy with the
coordinates as dynamic symbols and the parameters and inputs as plain symbols."""

from __future__ import annotations

import inspect
import math
import random
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp
from sympy.physics import mechanics as me

from tests.helpers import load_module

T = me.dynamicsymbols._t
Vec3 = tuple[str, str, str]


@dataclass
class Orient:
    kind: str  # "body" / "space" (a sequence), "axis", "matrix"
    sequence: str = ""
    angles: Vec3 = ("0", "0", "0")
    axis: Vec3 = ("0", "0", "1")
    angle: str = "0"
    matrix: tuple[Vec3, Vec3, Vec3] | None = None
    relative_to: str | None = None


@dataclass
class Load:
    vector: Vec3
    axes: str = "world"  # "world" or "body"
    at: str | None = None  # a point of the body (`tip` or `BODY.tip`), or None: the centre of mass
    plain: bool = False  # written as a bare list (world axes, at the centre)


@dataclass
class BodyDesc:
    name: str
    mass: str
    orient: Orient
    inertia: tuple[Vec3, Vec3, Vec3]
    pivot: Vec3 | str | None = None  # a world position list or a point reference; None: `position`
    position: Vec3 | str | None = None
    center: Vec3 | None = None
    points: dict[str, Vec3] = field(default_factory=dict)
    forces: list[Load] = field(default_factory=list)
    torques: list[Load] = field(default_factory=list)


@dataclass
class ParticleDesc:
    name: str
    mass: str
    position: Vec3 | str
    force: Vec3 | None = None


@dataclass
class System:
    coordinates: list[str]
    parameters: dict[str, float]
    bodies: list[BodyDesc]
    particles: list[ParticleDesc] = field(default_factory=list)
    gravity: Vec3 | None = None
    inputs: dict[str, float] = field(default_factory=dict)
    outputs: dict[str, str] = field(default_factory=dict)
    constraints: dict[str, str] = field(default_factory=dict)  # name -> expression (= 0)
    potential: str | None = None
    generalized: dict[str, str] = field(default_factory=dict)  # coordinate -> generalized force (`forces: {generalized: ...}`)

    # -- the file ------------------------------------------------------------------------------

    def yaml(self) -> str:
        lines = [f"coordinates: [{', '.join(self.coordinates)}]", "parameters: {" + ", ".join(f"{k}: {v!r}" for k, v in self.parameters.items()) + "}"]
        if self.inputs:
            lines.append("inputs:")
            lines += [f"  {k}: {{value: {v!r}}}" for k, v in self.inputs.items()]
        if self.outputs:
            lines.append("outputs:")
            lines += [f"  {k}: {_q(v)}" for k, v in self.outputs.items()]
        if self.gravity is not None:
            lines.append(f"gravity: {_list(self.gravity)}")
        if self.potential:
            lines.append(f"potential: {_q(self.potential)}")
        if self.generalized:
            lines.append("forces: {generalized: {" + ", ".join(f"{k}: {_q(v)}" for k, v in self.generalized.items()) + "}}")
        if self.constraints:
            lines.append("constraints:")
            lines += [f"  {k}: {_q(v)}" for k, v in self.constraints.items()]
        if self.particles:
            lines.append("particles:")
            for p in self.particles:
                pos = p.position if isinstance(p.position, str) else _list(p.position)
                extra = f", force: {_list(p.force)}" if p.force is not None else ""
                lines.append(f"  {p.name}: {{mass: {p.mass}, position: {pos}{extra}}}")
        lines.append("bodies:")
        for b in self.bodies:
            lines.append(f"  {b.name}:")
            lines.append(f"    mass: {b.mass}")
            lines.append(f"    orientation: {_orientation(b.orient)}")
            lines.append("    inertia: [" + ", ".join(_list(row) for row in b.inertia) + "]")
            if b.pivot is not None:
                lines.append(f"    pivot: {b.pivot if isinstance(b.pivot, str) else _list(b.pivot)}")
            if b.position is not None:
                lines.append(f"    position: {b.position if isinstance(b.position, str) else _list(b.position)}")
            if b.center is not None:
                lines.append(f"    center: {_list(b.center)}")
            if b.points:
                lines.append("    points: {" + ", ".join(f"{k}: {_list(v)}" for k, v in b.points.items()) + "}")
            for key, loads in (("force", b.forces), ("torque", b.torques)):
                if loads:
                    lines.append(f"    {key}:")
                    for load in loads:
                        if load.plain:
                            lines.append(f"      - {_list(load.vector)}")
                        else:
                            at = f", at: {load.at}" if load.at else ""
                            lines.append(f"      - {{vector: {_list(load.vector)}, axes: {load.axes}{at}}}")
        return "\n".join(lines) + "\n"

    # -- the peer ------------------------------------------------------------------------------

    def peer(self) -> Peer:
        return build_peer(self)


def _q(text: str) -> str:
    return '"' + text + '"'


def _list(values: Any) -> str:
    return "[" + ", ".join(_q(str(v)) for v in values) + "]"


def _orientation(o: Orient) -> str:
    rel = f", relative_to: {o.relative_to}" if o.relative_to else ""
    if o.kind in ("body", "space"):
        return f"{{sequence: {o.sequence}, angles: {_list(o.angles)}, kind: {o.kind}{rel}}}"
    if o.kind == "axis":
        return f"{{axis: {_list(o.axis)}, angle: {_q(o.angle)}{rel}}}"
    assert o.matrix is not None
    return "{matrix: [" + ", ".join(_list(row) for row in o.matrix) + f"]{rel}}}"


# -- sympy.physics.mechanics ------------------------------------------------------------------


@dataclass
class Peer:
    q: list[Any]
    qd_symbols: list[sp.Symbol]
    q_symbols: list[sp.Symbol]
    params: list[sp.Symbol]
    inputs: list[sp.Symbol]
    mass_full: sp.Matrix  # unknowns [q_dot, q_ddot, lambda] (Lagrange) or [q_dot, u_dot] (Kane)
    forcing_full: sp.Matrix
    n_lambda: int
    outputs: list[sp.Expr]
    constraint_rows: sp.Matrix  # d(constraint)/dq, plain symbols
    method: Any
    wrench: dict[str, Any] = field(default_factory=dict)  # per constraint: (body, force at its point) for the named force
    _fn: Any = None

    def numeric(self) -> Any:
        if self._fn is None:
            args = (self.q_symbols, self.qd_symbols, self.params, self.inputs, T)
            self._fn = (sp.lambdify(args, self.mass_full, cse=True), sp.lambdify(args, self.forcing_full, cse=True))
        return self._fn

    def solve(self, q: list[float], qd: list[float], p: dict[str, float], u: dict[str, float], t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(q_ddot, lambda) at a state and time."""
        mass, forcing = self.numeric()
        pv = [p[str(s)] for s in self.params]
        uv = [u[str(s)] for s in self.inputs]
        m = np.array(mass(q, qd, pv, uv, t), dtype=float)
        f = np.array(forcing(q, qd, pv, uv, t), dtype=float).ravel()
        x = np.linalg.solve(m, f)
        n = len(q)
        return x[n : 2 * n], x[2 * n : 2 * n + self.n_lambda]


def build_peer(system: System) -> Peer:
    qs = list(me.dynamicsymbols(" ".join(system.coordinates), seq=True))
    us = [sp.Symbol(f"{c}_dot") for c in system.coordinates]
    params = {k: sp.Symbol(k) for k in system.parameters}
    inputs = {k: sp.Symbol(k) for k in system.inputs}
    names: dict[str, Any] = {**dict(zip(system.coordinates, qs, strict=True)), **params, **inputs}
    velocities = {f"{c}_dot": q.diff(T) for c, q in zip(system.coordinates, qs, strict=True)}

    def ex(text: str) -> sp.Expr:
        return sp.sympify(text, locals={**names, **velocities, "t": T})

    n_frame = me.ReferenceFrame("N")
    origin = me.Point("O")
    origin.set_vel(n_frame, 0)
    frames: dict[str, me.ReferenceFrame] = {}
    centres: dict[str, me.Point] = {}
    points: dict[str, me.Point] = {}
    refs: dict[str, me.Point] = {}
    particles = {p.name: p for p in system.particles}

    def vec(values: Vec3, frame: me.ReferenceFrame) -> me.Vector:
        return ex(values[0]) * frame.x + ex(values[1]) * frame.y + ex(values[2]) * frame.z

    def locate(name: str, position: me.Vector) -> me.Point:
        point = origin.locatenew(name, position)
        point.set_vel(n_frame, position.dt(n_frame))
        return point

    def point_of(text: str) -> me.Point:
        body, dot, pt = text.partition(".")
        if dot:
            make(body)
            return points[f"{body}.{pt}"]
        if body in particles:
            return particle_point(body)
        make(body)
        return centres[body]

    particle_points: dict[str, me.Point] = {}

    def particle_point(name: str) -> me.Point:
        if name not in particle_points:
            pos = particles[name].position
            particle_points[name] = point_of(pos) if isinstance(pos, str) else locate(name, vec(pos, n_frame))
        return particle_points[name]

    descs = {b.name: b for b in system.bodies}

    def make(name: str) -> None:
        if name in frames:
            return
        b = descs[name]
        o = b.orient
        parent = n_frame
        if o.relative_to:
            make(o.relative_to)
            parent = frames[o.relative_to]
        frame = me.ReferenceFrame(f"F_{name}")
        if o.kind == "body":
            frame.orient_body_fixed(parent, tuple(ex(a) for a in o.angles), o.sequence)
        elif o.kind == "space":
            frame.orient_space_fixed(parent, tuple(ex(a) for a in o.angles), o.sequence)
        elif o.kind == "axis":
            axis = [ex(a) for a in o.axis]
            length = sp.sqrt(sum(a**2 for a in axis))
            frame.orient_axis(parent, (axis[0] * parent.x + axis[1] * parent.y + axis[2] * parent.z) / length, ex(o.angle))
        else:
            assert o.matrix is not None
            frame.orient_explicit(parent, sp.Matrix([[ex(e) for e in row] for row in o.matrix]))
        frames[name] = frame
        if b.pivot is not None:
            ref = point_of(b.pivot) if isinstance(b.pivot, str) else origin.locatenew(f"R_{name}", vec(b.pivot, n_frame))
        else:
            assert b.position is not None
            ref = point_of(b.position) if isinstance(b.position, str) else origin.locatenew(f"R_{name}", vec(b.position, n_frame))
        if ref.name.startswith("R_"):  # a position list: its velocity by differentiation in N
            ref.set_vel(n_frame, ref.pos_from(origin).dt(n_frame))
        refs[name] = ref
        centre = ref.locatenew(f"G_{name}", vec(b.center, frame) if b.center is not None else 0 * frame.x)
        centre.v2pt_theory(ref, n_frame, frame)  # fixed in the body: v = v_ref + omega x r
        centres[name] = centre
        for pt, offset in b.points.items():
            point = ref.locatenew(f"P_{name}_{pt}", vec(offset, frame))
            point.v2pt_theory(ref, n_frame, frame)
            points[f"{name}.{pt}"] = point

    for b in system.bodies:
        make(b.name)
    bodies = []
    loads: list[tuple[Any, me.Vector]] = []
    gravity = vec(system.gravity, n_frame) if system.gravity is not None else None
    for b in system.bodies:
        frame = frames[b.name]
        inertia = [[ex(e) for e in row] for row in b.inertia]
        dyadic = me.inertia(frame, inertia[0][0], inertia[1][1], inertia[2][2], inertia[0][1], inertia[1][2], inertia[0][2])
        mass = ex(b.mass)
        bodies.append(me.RigidBody(b.name, centres[b.name], frame, mass, (dyadic, centres[b.name])))
        if gravity is not None:
            loads.append((centres[b.name], mass * gravity))
        for load in b.forces:
            at = centres[b.name]
            if load.at:
                pt = load.at.split(".")[-1]
                at = centres[b.name] if pt == b.name else points[f"{b.name}.{pt}"]
            loads.append((at, vec(load.vector, frame if load.axes == "body" else n_frame)))
        for load in b.torques:
            loads.append((frame, vec(load.vector, frame if load.axes == "body" else n_frame)))
    for p in system.particles:
        point = particle_point(p.name)
        mass = ex(p.mass)
        bodies.append(me.Particle(p.name, point, mass))
        if gravity is not None:
            loads.append((point, mass * gravity))
        if p.force is not None:
            loads.append((point, vec(p.force, n_frame)))
    table = {**{q.diff(T): u for q, u in zip(qs, us, strict=True)}, **{q: sp.Symbol(c) for q, c in zip(qs, system.coordinates, strict=True)}}
    plain_q = [sp.Symbol(c) for c in system.coordinates]
    outputs = [me.msubs(ex(v), table) for v in system.outputs.values()]
    cons = [ex(c) for c in system.constraints.values()]
    rows = sp.Matrix([[me.msubs(sp.diff(c, q), table) for q in qs] for c in cons]) if cons else sp.zeros(0, len(qs))
    if system.potential:
        raise NotImplementedError("potential: use loads")
    if cons:
        assert not system.generalized, "generalized forces: Kane's form only"
        lagrangian = me.Lagrangian(n_frame, *bodies)
        method = me.LagrangesMethod(lagrangian, qs, forcelist=loads, frame=n_frame, hol_coneqs=cons)
        method.form_lagranges_equations()
        mass_full = me.msubs(method.mass_matrix_full, table)
        forcing_full = me.msubs(method.forcing_full, table)
    else:
        ud = me.dynamicsymbols(" ".join(f"{c}_u" for c in system.coordinates), seq=True)
        kd = [q.diff(T) - u for q, u in zip(qs, ud, strict=True)]
        method = me.KanesMethod(n_frame, q_ind=qs, u_ind=ud, kd_eqs=kd)
        method.kanes_equations(bodies, loads)
        swap = {**{u: s for u, s in zip(ud, us, strict=True)}, **{q: sp.Symbol(c) for q, c in zip(qs, system.coordinates, strict=True)}}
        mass_full = me.msubs(method.mass_matrix_full, swap)
        forcing_full = me.msubs(method.forcing_full, swap)
        if system.generalized:  # Kane's dynamic rows are in the order of u = q_dot: add Q_i to row n + i
            n = len(qs)
            extra = [me.msubs(ex(system.generalized.get(c, "0")), table) for c in system.coordinates]
            forcing_full = forcing_full + sp.Matrix([*([0] * n), *extra])
    peer = Peer(qs, us, plain_q, list(params.values()), list(inputs.values()), mass_full, forcing_full, len(cons), outputs, rows, method)
    peer.wrench = {"centres": centres, "frames": frames, "points": points, "particles": particle_points, "origin": origin, "N": n_frame, "table": table, "ex": ex}
    return peer


# -- lagrange ---------------------------------------------------------------------------------


def lagrange_module(system_text: str, path: Path) -> Any:
    from lagrange_cli import api

    return load_module(api.from_text(system_text).to("python"), path)


def call(module: Any, name: str, t: float, y: list[float], p: dict[str, float], u: dict[str, float]) -> Any:
    fn = getattr(module, name)
    if "u" in inspect.signature(fn).parameters:
        return fn(t, y, p, u=u)
    return fn(t, y, p)


def lagrange_solve(module: Any, q: list[float], qd: list[float], p: dict[str, float], u: dict[str, float], n_lambda: int, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    n = len(q)
    y = [*q, *qd]
    if n_lambda:
        x = np.asarray(call(module, "accelerations", t, y, p, u), dtype=float)
        return x[:n], x[n:]
    return np.asarray(call(module, "rhs", t, y, p, u), dtype=float)[n:], np.zeros(0)


def close(got: Any, expected: Any, rtol: float = 1e-8) -> bool:
    got, expected = np.asarray(got, dtype=float), np.asarray(expected, dtype=float)
    if got.shape != expected.shape:
        return False
    scale = max(1.0, float(np.abs(expected).max()) if expected.size else 1.0)
    return bool(np.all(np.abs(got - expected) <= rtol * scale))


def perturbed(parameters: dict[str, float], rng: random.Random) -> dict[str, float]:
    return {k: v * rng.uniform(0.7, 1.4) if v != 0 else v for k, v in parameters.items()}


def random_state(n: int, rng: random.Random) -> tuple[list[float], list[float]]:
    return [rng.uniform(-1.4, 1.4) for _ in range(n)], [rng.uniform(-2.0, 2.0) for _ in range(n)]


def constrained_state(system: System, peer: Peer, rng: random.Random, p: dict[str, float]) -> tuple[list[float], list[float]]:
    """A random state on the kept constraints: a random configuration moved onto them by Gauss-Newton
    steps (the smallest change of the coordinates), the velocities projected on the constraints' null space."""
    n = len(system.coordinates)
    cons = sp.Matrix([me.msubs(sp.sympify(c, locals={**{k: sp.Symbol(k) for k in system.coordinates}, **{k: sp.Symbol(k) for k in p}}), {}) for c in system.constraints.values()])
    args = (peer.q_symbols, [sp.Symbol(k) for k in p])
    f = sp.lambdify(args, cons)
    jac = sp.lambdify(args, cons.jacobian(peer.q_symbols))
    pv = list(p.values())
    for _ in range(20):
        q, _ = random_state(n, rng)
        for _ in range(50):
            r = np.array(f(q, pv), dtype=float).ravel()
            if np.abs(r).max() < 1e-14:
                break
            j = np.array(jac(q, pv), dtype=float)
            q = (np.array(q) + np.linalg.lstsq(j, -r, rcond=None)[0]).tolist()  # Gauss-Newton, the smallest step
        r = np.array(f(q, pv), dtype=float).ravel()
        if np.abs(r).max() < 1e-13 and all(math.isfinite(x) for x in q):
            a = np.array(jac(q, pv), dtype=float)
            v = np.array(random_state(n, rng)[1])
            v = v - np.linalg.pinv(a) @ (a @ v)
            return q, v.tolist()
    raise AssertionError("no state on the constraints found")


def manifold_state_space(system: System, peer: Peer, q0: list[float], u0: dict[str, float], p: dict[str, float], independent: list[str], h: float = 1e-3) -> dict[str, np.ndarray]:
    """The peer's state-space matrices in the independent coordinates `independent`: its
    accelerations and outputs as functions of (z, z_dot, u) on the kept constraints (the dependent
    coordinates by Newton's method, their rates from the constraints' rows), differentiated by
    central differences with one Richardson step (error O(h^4))."""
    n = len(system.coordinates)
    ind = [system.coordinates.index(c) for c in independent]
    dep = [i for i in range(n) if i not in ind]
    plain = {k: sp.Symbol(k) for k in (*system.coordinates, *p)}
    cons = sp.Matrix([sp.sympify(c, locals=plain) for c in system.constraints.values()])
    args = (peer.q_symbols, [sp.Symbol(k) for k in p])
    f, jac = sp.lambdify(args, cons), sp.lambdify(args, cons.jacobian(peer.q_symbols))
    pv = list(p.values())
    names = list(system.inputs)
    outputs = sp.lambdify((peer.q_symbols, peer.qd_symbols, [sp.Symbol(k) for k in p], [sp.Symbol(k) for k in names]), sp.Matrix(peer.outputs)) if peer.outputs else None

    def state(z: np.ndarray, zd: np.ndarray) -> tuple[list[float], list[float]]:
        q = np.array(q0, dtype=float)
        q[ind] = z
        for _ in range(60):
            r = np.array(f(q.tolist(), pv), dtype=float).ravel()
            if np.abs(r).max() < 1e-15:
                break
            q[dep] += np.linalg.solve(np.array(jac(q.tolist(), pv), dtype=float)[:, dep], -r)
        a = np.array(jac(q.tolist(), pv), dtype=float)
        qd = np.zeros(n)
        qd[ind] = zd
        qd[dep] = np.linalg.solve(a[:, dep], -a[:, ind] @ zd)
        return q.tolist(), qd.tolist()

    def rhs(x: np.ndarray, u: np.ndarray) -> np.ndarray:
        k = len(ind)
        q, qd = state(x[:k], x[k:])
        uu = dict(zip(names, u.tolist(), strict=True))
        acc, _ = peer.solve(q, qd, p, uu)
        y = np.array(outputs(q, qd, pv, u.tolist()), dtype=float).ravel() if outputs is not None else np.zeros(0)
        return np.concatenate([x[k:], acc[ind], y])

    def derivative(fun: Any, x: np.ndarray, j: int) -> np.ndarray:
        def d(step: float) -> np.ndarray:
            e = np.zeros_like(x)
            e[j] = step
            return (fun(x + e) - fun(x - e)) / (2 * step)

        return (4 * d(h / 2) - d(h)) / 3

    x0 = np.array([*[q0[i] for i in ind], *([0.0] * len(ind))])
    u0v = np.array([u0[k] for k in names], dtype=float)
    jx = np.column_stack([derivative(lambda x: rhs(x, u0v), x0, j) for j in range(len(x0))]) if len(x0) else np.zeros((0, 0))
    ju = np.column_stack([derivative(lambda u: rhs(x0, u), u0v, j) for j in range(len(u0v))]) if len(u0v) else np.zeros((len(x0) + len(peer.outputs), 0))
    s = len(x0)
    return {"A": jx[:s], "B": ju[:s], "C": jx[s:], "D": ju[s:], "residual": rhs(x0, u0v)[:s]}
