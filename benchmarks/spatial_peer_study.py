"""A randomized study of spatial systems written with the FORMAT.md version 2 keys against
sympy.physics.mechanics (issue 13), larger than tests/test_spatial_peer.py can afford.

Each case is a random system (tests/spatial_peer.py describes it once and writes it twice: a YAML
file for `lagrange`, an independent sympy.physics.mechanics model): 1 to `--max-bodies` bodies,
each oriented by one of the 12 sequences (body- or space-fixed), an axis and angle about a random
axis, or an explicit matrix (a random constant rotation times an elementary one in a coordinate),
often `relative_to` the previous body and pivoted at one of its points (`BODY.POINT`); random full
inertia tensors with products of inertia; random points; forces in world or body axes at points or
at the centre and torques in either axes, some holding the inputs and velocities; gravity; a
particle at a body point; sometimes time in an angle or a pivot. Compared at random states, times
and perturbed parameters: the accelerations; with a kept constraint on a body point's height, the
multipliers; and, for the time-independent systems, A, B, C, D of `System.state_space()` about a
random configuration held by generalized-force inputs, against the Jacobian of the peer's
first-order equations there.

    PYTHONPATH=. python benchmarks/spatial_peer_study.py --cases 40 --seed 1

prints one line per case and a summary (cases, comparisons, largest relative difference)."""

from __future__ import annotations

import argparse
import math
import random
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp
from sympy.physics import mechanics as me

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from lagrange_cli import api
from lagrange_cli.kinematics import SEQUENCES
from tests.spatial_peer import BodyDesc, Load, Orient, ParticleDesc, System, call, constrained_state, lagrange_module, lagrange_solve, perturbed, random_state
from tests.test_spatial_peer import peer_state_space

RTOL = 1e-8


def _f(x: float) -> str:
    return f"{x:.6g}"


def _combo(rng: random.Random, coords: list[str], time_ok: bool) -> str:
    """A random angle: a coordinate, a combination of two, a constant, maybe with t."""
    kind = rng.random()
    if kind < 0.5:
        text = rng.choice(coords)
    elif kind < 0.85:
        a, b = rng.sample(coords, 2) if len(coords) > 1 else (coords[0], coords[0])
        text = f"{a} {rng.choice('+-')} {_f(rng.uniform(0.2, 1.5))}*{b}"
    else:
        text = _f(rng.uniform(-1, 1))
    if time_ok and rng.random() < 0.2:
        text += f" + {_f(rng.uniform(0.1, 0.9))}*t"
    return text


def _rotation(rng: random.Random) -> sp.Matrix:
    """A random constant rotation (from a random unit quaternion)."""
    w, x, y, z = (rng.gauss(0, 1) for _ in range(4))
    r = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / r, x / r, y / r, z / r
    return sp.Matrix(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _orient(rng: random.Random, coords: list[str], time_ok: bool, parent: str | None) -> Orient:
    kind = rng.choice(["body", "space", "body", "space", "axis", "matrix"])
    if kind in ("body", "space"):
        angles = tuple(_combo(rng, coords, time_ok) for _ in range(3))
        sequence = rng.choice(SEQUENCES)
        return Orient(kind, sequence=sequence.lower() if rng.random() < 0.2 else sequence, angles=angles, relative_to=parent)  # type: ignore[arg-type]
    if kind == "axis":
        axis = tuple(_f(rng.uniform(-1, 1)) for _ in range(3))
        return Orient("axis", axis=axis, angle=_combo(rng, coords, time_ok), relative_to=parent)  # type: ignore[arg-type]
    q = sp.Symbol(rng.choice(coords))
    c, s = sp.cos(q), sp.sin(q)
    axis = rng.choice("XYZ")
    elementary = {"X": sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]]), "Y": sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]]), "Z": sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]
    matrix = _rotation(rng) * elementary
    rows = tuple(tuple(str(sp.Float(0) + e) for e in matrix.row(i)) for i in range(3))
    return Orient("matrix", matrix=rows, relative_to=parent)  # type: ignore[arg-type]


def _inertia(rng: random.Random) -> tuple[tuple[str, str, str], ...]:
    a = np.array([[rng.uniform(-0.5, 0.5) for _ in range(3)] for _ in range(3)])
    tensor = a @ a.T + 0.1 * np.eye(3)
    return tuple(tuple(_f(tensor[i][j]) if i <= j else _f(tensor[j][i]) for j in range(3)) for i in range(3))  # type: ignore[return-value]


def _vector(rng: random.Random, coords: list[str], inputs: list[str]) -> tuple[str, str, str]:
    def one() -> str:
        r = rng.random()
        if r < 0.4:
            return _f(rng.uniform(-1, 1))
        if r < 0.6 and inputs:
            return rng.choice(inputs)
        if r < 0.8:
            return f"{_f(rng.uniform(-0.5, 0.5))}*{rng.choice(coords)}_dot"
        return f"{_f(rng.uniform(-0.5, 0.5))}*cos({rng.choice(coords)})"

    return (one(), one(), one())


def random_system(rng: random.Random, max_bodies: int, time_ok: bool, with_generalized: bool) -> System:
    n_bodies = rng.randint(1, max_bodies)
    coords = [f"q{i + 1}" for i in range(rng.randint(2, 3))]
    params = {"g": 9.81, **{f"m{i}": round(rng.uniform(0.5, 2.0), 3) for i in range(n_bodies)}, "mp": 0.4}
    inputs = ["tau", "F"]
    bodies: list[BodyDesc] = []
    for i in range(n_bodies):
        name = f"B{i}"
        previous = bodies[-1] if bodies else None
        parent = previous.name if previous is not None and rng.random() < 0.7 else None
        orient = _orient(rng, coords, time_ok, parent)
        points = {f"p{k}": tuple(_f(rng.uniform(-1, 1)) for _ in range(3)) for k in range(rng.randint(1, 2))}
        pivot: tuple[str, str, str] | str | None
        position = None
        if previous is not None and rng.random() < 0.7:
            pivot = f"{previous.name}.{rng.choice(list(previous.points))}"
        elif rng.random() < 0.3:
            pivot, position = None, (f"0.3*{rng.choice(coords)}", _f(rng.uniform(-1, 1)), "0")
        else:
            pivot = (_f(rng.uniform(-0.5, 0.5)), f"{_f(rng.uniform(0, 0.3))}*t" if time_ok and rng.random() < 0.3 else "0", "0")
        center = tuple(_f(rng.uniform(-0.6, 0.6)) for _ in range(3)) if pivot is not None else None
        forces = []
        for _ in range(rng.randint(0, 2)):
            at = rng.choice([None, name, *points, *(f"{name}.{p}" for p in points)])
            forces.append(Load(_vector(rng, coords, inputs), rng.choice(["world", "body"]), at, plain=False))
        if rng.random() < 0.3:
            forces.append(Load(_vector(rng, coords, inputs), plain=True))
        torques = [Load(_vector(rng, coords, inputs), rng.choice(["world", "body"])) for _ in range(rng.randint(0, 2))]
        bodies.append(BodyDesc(name, f"m{i}", orient, _inertia(rng), pivot=pivot, position=position, center=center, points=points, forces=forces, torques=torques))  # type: ignore[arg-type]
    particles = []
    if rng.random() < 0.5:
        body = rng.choice(bodies)
        particles.append(ParticleDesc("bob", "mp", rng.choice([f"{body.name}.{p}" for p in body.points] + [body.name])))
    gravity = (_f(rng.uniform(-1, 1)), _f(rng.uniform(-1, 1)), "-g")
    used = {s for b in bodies for load in (*b.forces, *b.torques) for s in load.vector}
    declared = {k: 0.0 for k in inputs if k in used}
    generalized = {}
    if with_generalized:
        for c in coords:
            declared[f"h_{c}"] = 0.0
            generalized[c] = f"h_{c}"
    outputs = {"y1": f"{coords[0]} + 0.5*{coords[-1]}_dot", **({"y2": f"sin({coords[1]}) + 2*{next(iter(declared))}"} if declared else {})}
    return System(coords, params, bodies, particles, gravity, declared, outputs, generalized=generalized)  # type: ignore[arg-type]


def add_constraint(system: System, rng: random.Random) -> bool:
    """Keep a point of a body at a height: z of that point, as the peer computes it in the
    coordinates, equals its value at a random configuration (so the surface is not empty)."""
    body = rng.choice(system.bodies)
    point = rng.choice(list(body.points))
    peer = system.peer()
    where = peer.wrench["points"][f"{body.name}.{point}"].pos_from(peer.wrench["origin"]).to_matrix(peer.wrench["N"])[2]
    plain = me.msubs(where, peer.wrench["table"])
    if plain.has(sp.Symbol("t")) or not plain.free_symbols & set(peer.q_symbols):
        return False
    q0 = {s: rng.uniform(-1, 1) for s in peer.q_symbols}
    height = float(plain.xreplace({**q0, **{sp.Symbol(k): v for k, v in system.parameters.items()}}))
    system.constraints = {"level": f"{sp.sstr(plain, full_prec=False)} - ({height!r})"}
    system.level = (body.name, point)  # type: ignore[attr-defined]
    return True


def projected_force_difference(system: System, peer: Any, module: Any, q: list[float], qd: list[float], p: dict[str, float], u: dict[str, float], lam: float) -> float:
    """The named force of the constraint "level" (a point's height) against the peer's physical one:
    lambda e_z at the point, with its moment about the body's centre (body axes), projected on the
    motions the coordinates allow (the range of J: the carriers' position rows d r/dq and angular
    rows d omega/d q_dot from the peer's points and frames), as docs/format.md defines `on`."""
    w = peer.wrench
    body_name, point = system.level  # type: ignore[attr-defined]
    values = {**dict(zip(peer.q_symbols, q, strict=True)), **dict(zip(peer.qd_symbols, qd, strict=True)), **{sp.Symbol(k): v for k, v in p.items()}}
    table = w["table"]
    rows: list[list[float]] = []
    physical: list[float] = []
    layout: list[tuple[str, str]] = []
    carriers = [(pd.name, w["particles"][pd.name], None) for pd in system.particles] + [(b.name, w["centres"][b.name], w["frames"][b.name]) for b in system.bodies]
    for name, centre, frame in carriers:
        position = me.msubs(centre.pos_from(w["origin"]).to_matrix(w["N"]), table)
        for i in range(3):
            rows.append([float(sp.diff(position[i], s).xreplace(values)) for s in peer.q_symbols])
        force = [0.0, 0.0, 1.0] if name == body_name else [0.0, 0.0, 0.0]
        physical += force
        layout.append((name, "force"))
        if frame is not None:
            omega = me.msubs(frame.ang_vel_in(w["N"]).to_matrix(frame), table)
            for i in range(3):
                rows.append([float(sp.diff(omega[i], s).xreplace(values)) for s in peer.qd_symbols])
            if name == body_name:
                arm = w["points"][f"{body_name}.{point}"].pos_from(centre)
                moment = me.msubs(arm.cross(w["N"].z).to_matrix(frame), table)
                physical += [float(x.xreplace(values)) for x in moment]
            else:
                physical += [0.0, 0.0, 0.0]
            layout.append((name, "torque"))
    j = np.array(rows)
    expected = lam * (j @ np.linalg.pinv(j) @ np.array(physical))
    found = call(module, "constraint_forces", 0.0, [*q, *qd], p, u)["level"]
    got: list[float] = []
    for name, kind in layout:
        got += list(found["on"].get(name, {}).get(kind, [0.0, 0.0, 0.0]))  # a carrier the coordinates do not move is not listed
    scale = max(1.0, float(np.abs(expected).max()))
    return float(np.abs(np.array(got) - expected).max()) / scale


def run_case(k: int, rng: random.Random, max_bodies: int, folder: Path, only: str | None = None) -> dict[str, object]:
    from lagrange_cli.errors import LagrangeError

    kind = rng.choice(["plain", "plain", "time", "constraint", "state_space"])
    kind = only or kind
    for _ in range(50):  # draw until every coordinate moves something with inertia (else the file is rightly refused)
        system = random_system(rng, max_bodies, time_ok=kind == "time", with_generalized=kind == "state_space")
        if kind == "constraint" and not add_constraint(system, rng):
            continue
        try:
            module = lagrange_module(system.yaml(), folder / f"case{k}.py")
        except LagrangeError as error:
            if "appears nowhere" in str(error) or "is singular" in str(error):
                continue
            raise
        break
    else:
        raise AssertionError("no acceptable system drawn")
    started = time.process_time()
    peer = system.peer()
    peer_cpu = time.process_time() - started
    worst = {"acc": 0.0, "lambda": 0.0, "force": 0.0, "ss": 0.0}
    compared = 0
    for s in range(3):
        p = system.parameters if s == 0 else perturbed(system.parameters, rng)
        u = {name: rng.uniform(-2, 2) for name in system.inputs}
        t = rng.uniform(0, 2) if kind == "time" else 0.0
        q, qd = constrained_state(system, peer, rng, p) if system.constraints else random_state(len(system.coordinates), rng)
        expected, lam_peer = peer.solve(q, qd, p, u, t)
        got, lam = lagrange_solve(module, q, qd, p, u, peer.n_lambda, t)
        scale = max(1.0, float(np.abs(expected).max()))
        worst["acc"] = max(worst["acc"], float(np.abs(got - expected).max()) / scale)
        if peer.n_lambda:
            worst["lambda"] = max(worst["lambda"], float(np.abs(lam - lam_peer).max()) / max(1.0, float(np.abs(lam_peer).max())))
        compared += 1
    if peer.n_lambda:
        worst["force"] = projected_force_difference(system, peer, module, q, qd, p, u, lam_peer[0])
    if kind == "state_space":
        p = system.parameters
        q0 = [rng.uniform(-1, 1) for _ in system.coordinates]
        u0 = {name: (rng.uniform(-1, 1) if not name.startswith("h_") else 0.0) for name in system.inputs}
        # the generalized-force inputs hold the configuration: h = -F(q0, 0, other inputs)
        _, forcing = peer.numeric()
        pv = [p[str(x)] for x in peer.params]
        f = np.array(forcing(q0, [0.0] * len(q0), pv, [u0[str(x)] for x in peer.inputs], 0.0), dtype=float).ravel()[len(q0) :]
        for i, c in enumerate(system.coordinates):
            u0[f"h_{c}"] = -float(f[i])
        expected = peer_state_space(system, q0, u0, p)
        found = api.from_text(system.yaml()).state_space({**dict(zip(system.coordinates, q0, strict=True)), **u0})
        for key in "ABCD":
            e, g = np.asarray(expected[key], dtype=float), np.asarray(found[key], dtype=float)
            if e.shape != g.shape:
                worst["ss"] = math.inf
                continue
            if e.size:
                worst["ss"] = max(worst["ss"], float(np.abs(g - e).max()) / max(1.0, float(np.abs(e).max())))
    return {"kind": kind, "bodies": len(system.bodies), "coordinates": len(system.coordinates), "worst": worst, "states": compared, "peer_cpu": peer_cpu, "system": system}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=30)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--max-bodies", type=int, default=3)
    parser.add_argument("--kind", choices=["plain", "time", "constraint", "state_space"], help="only cases of this kind")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    agree = disagree = errors = 0
    largest = 0.0
    kinds: dict[str, int] = {}
    with tempfile.TemporaryDirectory() as folder:
        for k in range(args.cases):
            case_rng = random.Random(rng.getrandbits(32))
            try:
                result = run_case(k, case_rng, args.max_bodies, Path(folder), args.kind)
            except Exception:  # a case that could not be compared is counted and shown, never hidden
                errors += 1
                print(f"case {k}: ERROR\n{traceback.format_exc()}", flush=True)
                continue
            worst = result["worst"]
            assert isinstance(worst, dict)
            bad = max(worst.values())
            largest = max(largest, bad)
            ok = bad <= RTOL
            agree += ok
            disagree += not ok
            kinds[str(result["kind"])] = kinds.get(str(result["kind"]), 0) + 1
            print(
                f"case {k}: {result['kind']:<11} bodies {result['bodies']} coordinates {result['coordinates']}  max rel. diff: acc {worst['acc']:.1e} lambda {worst['lambda']:.1e} force {worst['force']:.1e} state-space {worst['ss']:.1e}  {'ok' if ok else 'DISAGREE'}  (peer {result['peer_cpu']:.1f} s CPU)",
                flush=True,
            )
            if not ok:
                system = result["system"]
                print(system.yaml())  # type: ignore[union-attr]
    print(
        f"\n{args.cases} cases ({', '.join(f'{v} {k}' for k, v in sorted(kinds.items()))}): {agree} agree to {RTOL:g}, {disagree} disagree, {errors} errors; largest relative difference {largest:.2e}"
    )
    return 0 if not disagree and not errors else 1


if __name__ == "__main__":
    raise SystemExit(main())
