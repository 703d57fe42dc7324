"""Derivation that scales (issue 14): the general N-link chain, its own m_i and l_i per link.

`derive` computes in symengine and fills `Model.symengine`; the sympy fields are converted only when
read. The point masses' mass matrix is built from the Jacobians with the masses of equal geometric
terms added first, so the chain's M_ij is l_i l_j cos(q_i - q_j) (m_max(i,j) + ... + m_N). These
tests check the equations against hand-written and independent references, the shape of M, that
derive builds no sympy field, and that the symengine forms and the sympy fields agree everywhere.
"""

from __future__ import annotations

import dataclasses
import math
import random
from pathlib import Path

import pytest
import sympy as sp
from sympy.core.function import AppliedUndef

from lagrange_cli import derive, spec, validate
from lagrange_cli._symengine import se, to_symengine, to_sympy
from lagrange_cli.model import LAZY_FIELDS, Model

ROOT = Path(__file__).resolve().parent.parent
FILES = sorted((ROOT / "systems").glob("*.yaml")) + sorted((ROOT / "tests" / "matrix").glob("*.yaml"))


def chain_yaml(masses: list[float], lengths: list[float], g: float = 9.81) -> str:
    """The general planar chain: link k of length l_k, bob k of mass m_k at sum_{i<=k} l_i (sin th_i, -cos th_i)."""
    n = len(masses)
    values = ", ".join(f"m{k}: {masses[k - 1]!r}, l{k}: {lengths[k - 1]!r}" for k in range(1, n + 1))
    lines = [f"title: General {n}-link chain", f"coordinates: [{', '.join(f'th{k}' for k in range(1, n + 1))}]", f"parameters: {{{values}, g: {g!r}}}", "gravity: [0, -g]", "particles:"]
    for k in range(1, n + 1):
        x = " + ".join(f"l{i}*sin(th{i})" for i in range(1, k + 1))
        y = " - ".join(f"l{i}*cos(th{i})" for i in range(1, k + 1))
        lines.append(f"  p{k}: {{mass: m{k}, position: [{x}, -{y}]}}")
    return "\n".join(lines) + "\n"


def chain_values(n: int, seed: int) -> tuple[list[float], list[float]]:
    rng = random.Random(seed)
    masses = [round(rng.uniform(0.5, 3.0), 3) for _ in range(n)]
    lengths = [round(rng.uniform(0.3, 2.0), 3) for _ in range(n)]
    return masses, lengths


def chain(n: int, seed: int) -> tuple[Model, list[float], list[float]]:
    masses, lengths = chain_values(n, seed)
    return derive.derive(spec.parse(chain_yaml(masses, lengths), f"chain{n}.yaml")), masses, lengths


def hand_reference(th: list[float], w: list[float], m: list[float], length: list[float], g: float = 9.81) -> tuple[list[list[float]], list[float]]:
    """M_ij = l_i l_j cos(th_i - th_j) sum_{k >= max(i, j)} m_k and
    F_i = -sum_j l_i l_j sin(th_i - th_j) w_j^2 sum_{k >= max(i, j)} m_k - g l_i sin(th_i) sum_{k >= i} m_k."""
    n = len(th)
    below = [sum(m[k:]) for k in range(n)]
    mass = [[length[i] * length[j] * math.cos(th[i] - th[j]) * below[max(i, j)] for j in range(n)] for i in range(n)]
    force = [-sum(length[i] * length[j] * math.sin(th[i] - th[j]) * w[j] ** 2 * below[max(i, j)] for j in range(n)) - g * length[i] * math.sin(th[i]) * below[i] for i in range(n)]
    return mass, force


def values(model: Model, masses: list[float], lengths: list[float], th: list[float], w: list[float]) -> dict[str, float]:
    point = {f"m{k + 1}": masses[k] for k in range(model.n)} | {f"l{k + 1}": lengths[k] for k in range(model.n)} | {"g": 9.81}
    return point | {str(q): x for q, x in zip(model.q, th, strict=True)} | {str(v): x for v, x in zip(model.qd, w, strict=True)}


def se_value(expr: object, point: dict[str, float]) -> float:
    return float(se.sympify(expr).xreplace({se.Symbol(k): se.RealDouble(v) for k, v in point.items()}))  # type: ignore[attr-defined]


def number(expr: sp.Expr, point: dict[sp.Symbol, float]) -> complex:
    """The value of a sympy expression at a point (undefined functions made concrete first)."""
    return complex(concrete(expr).xreplace({s: sp.Float(v) for s, v in point.items()}))


@pytest.mark.parametrize("n", [1, 2, 5, 8])
def test_the_general_chain_matches_the_hand_written_equations(n: int) -> None:
    model, masses, lengths = chain(n, seed=n)
    rng = random.Random(100 + n)
    for _ in range(3):
        th, w = [rng.uniform(-3, 3) for _ in range(n)], [rng.uniform(-2, 2) for _ in range(n)]
        mass, force = hand_reference(th, w, masses, lengths)
        point = values(model, masses, lengths, th, w)
        forms = model.symengine
        for i in range(n):
            assert se_value(forms.forcing[i], point) == pytest.approx(force[i], rel=1e-12, abs=1e-12)
            for j in range(n):
                assert se_value(forms.mass[i][j], point) == pytest.approx(mass[i][j], rel=1e-12, abs=1e-12)
    # the sympy fields, converted on first access, say the same
    th, w = [rng.uniform(-3, 3) for _ in range(n)], [rng.uniform(-2, 2) for _ in range(n)]
    mass, force = hand_reference(th, w, masses, lengths)
    subs = {sp.Symbol(k): v for k, v in values(model, masses, lengths, th, w).items()}
    assert [number(f, subs).real for f in model.forcing] == pytest.approx(force, rel=1e-12, abs=1e-12)
    assert [number(x, subs).real for x in model.mass_matrix] == pytest.approx([x for row in mass for x in row], rel=1e-12, abs=1e-12)


def test_the_chain_mass_matrix_shares_the_suffix_mass_sums() -> None:
    """M_ij = l_i l_j cos(th_i - th_j) (m_max(i,j) + ... + m_N): one cosine and one sum of masses, not
    N products of cosines; F_i has one term per link plus the weight."""
    n = 6
    model, _, _ = chain(n, seed=7)
    mass, force = model.symengine.mass, model.symengine.forcing
    m = [se.Symbol(f"m{k}") for k in range(1, n + 1)]
    th = model.symengine.q
    for i in range(n):
        for j in range(n):
            entry = mass[i][j]
            assert isinstance(entry, se.Mul), entry
            assert se.Add(*m[max(i, j) :]) in entry.args or (i == j == n - 1 and m[-1] in entry.args), entry
            trig = entry.atoms(se.cos)
            assert len(trig) == (i != j) and all({*t.free_symbols} == {th[i], th[j]} for t in trig), entry
            assert se.count_ops(entry) <= (n - max(i, j)) + 6, entry
        assert len(se.Add.make_args(force[i])) == n, force[i]


def test_derive_builds_no_sympy_field() -> None:
    """The chain's equations stay in symengine through derive and validation: nothing is converted to
    sympy until read, and what is read is converted once."""
    model, _, _ = chain(8, seed=3)
    assert model.native and model.converted() == frozenset()
    assert model.autonomous and not model.dissipative and not model.forced and model.converted() == frozenset()
    matrix = model.mass_matrix
    assert model.converted() == {"mass_matrix"} and model.mass_matrix is matrix
    assert isinstance(matrix, sp.ImmutableMatrix) and matrix.shape == (8, 8)
    kinetic = model.kinetic
    assert model.converted() == {"mass_matrix", "kinetic"} and sp.sympify(model.symengine.kinetic) == kinetic


def test_a_replaced_model_converts_its_own_sympy_fields() -> None:
    """`dataclasses.replace` with a new sympy field gives a model whose symengine forms follow that field."""
    model, _, _ = chain(2, seed=1)
    changed = dataclasses.replace(model, potential=model.potential + sp.Symbol("c"))
    assert not changed.native and changed.symengine.potential == to_symengine(model.potential + sp.Symbol("c"))
    assert changed.symengine.mass == model.symengine.mass
    assert dataclasses.replace(model, title="other").converted() == frozenset(LAZY_FIELDS)


def concrete(expr: sp.Expr) -> sp.Expr:
    """Undefined functions replaced by a fixed smooth one (so that expressions with them have values)."""
    if not expr.has(AppliedUndef):
        return expr
    x = sp.Dummy("x")
    return expr.replace(lambda e: isinstance(e, AppliedUndef), lambda e: sp.Lambda(x, sp.exp(x / 7) + x**2 / 3)(sum(e.args) / len(e.args))).doit()


def fields(model: Model, forms: object) -> list[tuple[str, object, sp.Expr]]:
    """(name, symengine expression, sympy expression) for every lazily converted field."""
    f = forms
    n = model.n
    pairs = [("kinetic", f.kinetic, model.kinetic), ("potential", f.potential, model.potential), ("lagrangian", f.lagrangian, model.lagrangian)]  # type: ignore[attr-defined]
    pairs += [("dissipation", f.dissipation, model.dissipation), ("energy", f.energy, model.energy)]  # type: ignore[attr-defined]
    pairs += [(f"momenta[{i}]", f.momenta[i], model.momenta[i]) for i in range(n)]  # type: ignore[attr-defined]
    pairs += [(f"generalized_forces[{i}]", f.generalized_forces[i], model.generalized_forces[i]) for i in range(n)]  # type: ignore[attr-defined]
    pairs += [(f"forcing[{i}]", f.forcing[i], model.forcing[i]) for i in range(n)]  # type: ignore[attr-defined]
    pairs += [(f"mass[{i}][{j}]", f.mass[i][j], model.mass_matrix[i, j]) for i in range(n) for j in range(n)]  # type: ignore[attr-defined]
    return pairs


@pytest.mark.parametrize("path", FILES, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_symengine_forms_equal_the_sympy_fields(path: Path) -> None:
    """On every bundled system and every feature of the matrix: `Model.symengine` and the sympy fields
    are the same expressions (compared as numbers at random points), and so are the forms a model
    converts from its sympy fields (after `dataclasses.replace`)."""
    model = derive.derive(spec.load(path))
    converted = dataclasses.replace(model, title="copy").symengine
    rng = random.Random(path.stem)
    point = {s: rng.uniform(0.3, 1.2) for s in (*model.q, *model.qd, model.t, *(p.symbol for p in model.parameters), *(i.symbol for i in model.inputs))}
    for (name, native, field), (_, other, _) in zip(fields(model, model.symengine), fields(model, converted), strict=True):
        want = number(field, point)
        assert number(sp.sympify(native), point) == pytest.approx(want, rel=1e-9, abs=1e-9), (path.name, name)
        assert number(sp.sympify(other), point) == pytest.approx(want, rel=1e-9, abs=1e-9), (path.name, name, "converted")


def reference_equations(s: spec.SystemSpec) -> tuple[list[object], list[object]]:
    """M and F from the file's entries the textbook way: the whole Lagrangian (velocities by sympy's chain
    rule), then Lagrange's equation by differentiating it twice (in symengine, for speed): independent of
    `derive`'s Jacobians, grouped masses and Christoffel symbols."""
    q, qd, qdd, t = s.q, s.qd, s.qdd, s.t

    def ddt(e: sp.Expr) -> sp.Expr:
        return spec.time_derivative(e, q, qd, qdd, t)

    kinetic, potential, rayleigh = s.kinetic, s.potential, s.dissipation
    forces = list(s.generalized_forces) or [sp.Integer(0)] * len(q)
    for item in (*s.particles, *s.bodies):
        kinetic += item.mass * sum(ddt(x) ** 2 for x in item.position) / 2
        if s.gravity is not None:
            potential -= item.mass * sum(g * x for g, x in zip(s.gravity, item.position, strict=True))
    for body in s.bodies:
        w = body.angular_velocity
        if len(body.inertia) == 9:  # a full tensor (FORMAT.md version 2)
            kinetic += sum(body.inertia[3 * i + j] * w[i] * w[j] for i in range(3) for j in range(3)) / 2
        else:
            kinetic += sum(i * wk**2 for i, wk in zip(body.inertia, w, strict=True)) / 2
        for i, qi in enumerate(q):  # loads (version 2), by the virtual power
            forces[i] += sum((fk * sp.diff(x, qi) for f, at in body.forces for fk, x in zip(f, at, strict=True)), sp.Integer(0))
            forces[i] += sum((fk * sp.diff(v, qd[i]) for f, rate in body.frame_forces for fk, v in zip(f, rate, strict=True)), sp.Integer(0))
            forces[i] += sum((tk * sp.diff(wk, qd[i]) for tau in body.torques for tk, wk in zip(tau, w, strict=True)), sp.Integer(0))
    for particle in s.particles:
        if particle.damping is not None:
            rayleigh += particle.damping * sum(ddt(x) ** 2 for x in particle.position) / 2
        if particle.force is not None:
            for i, qi in enumerate(q):
                forces[i] += sum(f * sp.diff(x, qi) for f, x in zip(particle.force, particle.position, strict=True))
    lagrangian, rayleigh = to_symengine(kinetic - potential + s.lagrangian), to_symengine(rayleigh)
    sq, sqd, st = [to_symengine(x) for x in q], [to_symengine(x) for x in qd], to_symengine(t)
    n = len(q)
    momenta = [se.diff(lagrangian, v) for v in sqd]
    mass = [se.diff(momenta[i], sqd[j]) for i in range(n) for j in range(n)]
    force = [
        se.diff(lagrangian, sq[i]) - sum((se.diff(momenta[i], sq[k]) * sqd[k] for k in range(n)), se.Integer(0)) - se.diff(momenta[i], st) - se.diff(rayleigh, sqd[i]) + to_symengine(forces[i])
        for i in range(n)
    ]
    return mass, force


MOVING = """
title: a bead on a rotating rod on a shaken support, its mass changing in time
coordinates: [r, phi]
parameters: {m: 1.3, k: 2.0, w: 0.7, a: 0.4, g: 9.81, c: 0.3}
gravity: [0, -g]
particles:
  bead: {mass: m*(1 + t**2/5), position: [r*cos(phi + w*t) + a*sin(w*t), r*sin(phi + w*t)], damping: c}
  pivot: {mass: m, position: [a*sin(w*t) + cos(phi), sin(phi)]}
potential: k*r**2/2
"""


@pytest.mark.parametrize("path", [None, *FILES], ids=lambda p: "moving" if p is None else f"{p.parent.name}/{p.stem}")
def test_the_structured_derivation_agrees_with_the_textbook_one(path: Path | None) -> None:
    """Jacobians, grouped masses and Christoffel symbols give the same M and F as differentiating the
    whole Lagrangian, for time-dependent positions, bodies,
    damping and forces, and a mass that changes in time (the files with eliminated coordinates or undefined functions are left out)."""
    s = spec.parse(MOVING, "moving.yaml") if path is None else spec.load(path)
    if s.eliminate or s.definitions or any(e.has(AppliedUndef) for src in derive.sources(s) for e in src.exprs):
        pytest.skip("eliminated coordinates or general functions")
    model = derive.derive(s)
    mass, force = reference_equations(s)
    rng = random.Random(11)
    for _ in range(2):
        point = {str(x): rng.uniform(0.3, 1.2) for x in (*model.q, *model.qd, model.t, *(p.symbol for p in model.parameters), *(i.symbol for i in model.inputs))}
        point |= {p.name: p.value for p in model.parameters if p.value is not None}
        forms = model.symengine
        assert [se_value(x, point) for row in forms.mass for x in row] == pytest.approx([se_value(x, point) for x in mass], rel=1e-9, abs=1e-9)
        assert [se_value(x, point) for x in forms.forcing] == pytest.approx([se_value(x, point) for x in force], rel=1e-9, abs=1e-9)


X, Y = se.Symbol("x"), se.Symbol("y")
U = se.Function("U")


@pytest.mark.parametrize(
    "node",
    [
        se.zoo,
        se.oo,
        -se.oo,
        se.nan,
        se.I,
        se.RealDouble(float("nan")),
        se.RealDouble(float("inf")),
        se.RealDouble(-float("inf")),
        se.Subs(se.Derivative(U(X), X), [X], [X * Y]),
        se.Derivative(se.Abs(X), X),
        se.Derivative(se.sign(X), X),
        X**20000,
        se.Integer(10) ** 400,
        se.EulerGamma,
    ],
    ids=str,
)
def test_the_symengine_survey_clears_nothing_the_sympy_check_refuses(node: object) -> None:
    """`validate.survey` clears a node only if `validate.refusal` allows its sympy form; what it does not
    clear goes to the full sympy check (so validating on symengine is never weaker)."""
    expr = node * X + se.sin(Y)  # type: ignore[operator]
    assert validate.survey([expr])[2] is False
    allowed = se.sin(X) * Y**3 / 7 + 2.5 * U(X) + se.Derivative(U(X), X) + se.exp(X) + se.atan2(X, Y) + se.pi
    assert validate.survey([allowed])[2] is True
    assert validate.refusal(sp.sympify(allowed)) is None


def test_the_survey_counts_shared_nodes_once_and_trees_in_full_and_stops_at_its_limit() -> None:
    shared = se.Add(*(se.Symbol(f"a{i}") for i in range(50)))
    exprs = [shared * se.Symbol(f"b{i}") for i in range(10)]
    size, tree, cleared = validate.survey(exprs)
    assert cleared and size == 1 + 50 + 10 * 2 and tree == 10 * (1 + 1 + 51) == sum(derive.tree_size(e) for e in exprs)
    assert validate.survey(exprs, 20)[0] > 20


def test_equations_too_large_written_out_are_refused_though_they_share_parts(monkeypatch: pytest.MonkeyPatch) -> None:
    """The equations are bounded both as distinct parts (what symengine and common subexpressions cost)
    and written out in full (what printing them in sympy costs): a product of many factors has a
    derivative of few distinct parts but a long written-out form. Over the second bound the model is
    still made (code with common subexpressions shares its parts), and its sympy fields are refused."""
    model, _, _ = chain(3, seed=2)
    size, tree, _ = validate.survey(validate.forms_parts(model.symengine))
    assert size < tree
    monkeypatch.setattr(derive, "MAX_EQUATION_TREE", tree - 1)
    with pytest.raises(spec.SpecError, match="written out without sharing, amount to more than"):
        chain(3, seed=2)
    masses, lengths = chain_values(3, seed=2)
    shared = derive.derive(spec.parse(chain_yaml(masses, lengths), "chain3.yaml"), shared=True)  # for generated code, which shares them
    assert shared.symengine.mass == model.symengine.mass
    with pytest.raises(spec.SpecError, match="written out without sharing, amount to more than"):
        _ = shared.mass_matrix  # not converted to sympy
    monkeypatch.setattr(derive, "MAX_EQUATION_TREE", tree)
    monkeypatch.setattr(derive, "MAX_EQUATION_NODES", size - 1)
    with pytest.raises(spec.SpecError, match="the equations of motion amount to more than"):
        chain(3, seed=2)


@pytest.mark.parametrize("path", [None, *FILES[:12]], ids=lambda p: "chain" if p is None else p.stem)
def test_the_lazy_conversion_is_sympify_done_once_per_shared_node(path: Path | None) -> None:
    """Each sympy field is exactly `sympy.sympify` of its symengine form (`to_sympy` converts a node
    shared by M, K, p and h once, with sympy's own constructors)."""
    model = chain(4, seed=5)[0] if path is None else derive.derive(spec.load(path))
    if model.converted():
        pytest.skip("fields computed in sympy on the way (derivatives of Abs or sign)")
    for name, native, field in fields(model, model.symengine):
        assert field == sp.sympify(native), name
    shared = se.Add(*(se.Symbol(f"a{i}") for i in range(5)))
    cache: dict[object, object] = {}
    first = to_sympy(se.sin(shared) * shared, cache)
    assert first == sp.sin(sp.Add(*sp.symbols("a0:5"))) * sp.Add(*sp.symbols("a0:5")) and any(a is cache[shared] for a in to_sympy(shared * se.Symbol("b"), cache).args)  # type: ignore[attr-defined]
