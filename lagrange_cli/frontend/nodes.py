"""The node types of a validated system file: frozen dataclasses of sympy expressions, no YAML."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import sympy as sp

from lagrange_cli.errors import LagrangeError, Span
from lagrange_cli.inputs import ExpectedStateSpace
from lagrange_cli.model import Input, Parameter
from lagrange_cli.units import Units


@dataclass(frozen=True)
class Particle:
    name: str
    mass: sp.Expr
    position: tuple[sp.Expr, ...]
    force: tuple[sp.Expr, ...] | None = None
    damping: sp.Expr | None = None
    spans: Mapping[str, Span] = field(default_factory=dict, compare=False)
    """Where each field (`mass`, `position`, ...) is written in the file."""


@dataclass(frozen=True)
class Body:
    """A rigid body: planar when `inertia` and `angular_velocity` are scalars, spatial when 3-tuples."""

    name: str
    mass: sp.Expr
    position: tuple[sp.Expr, ...]
    inertia: tuple[sp.Expr, ...]
    angular_velocity: tuple[sp.Expr, ...]
    spans: Mapping[str, Span] = field(default_factory=dict, compare=False)
    """Where each field (`mass`, `inertia`, ...) is written in the file."""
    rotation: tuple[tuple[sp.Expr, ...], ...] | None = None
    """With `orientation` (FORMAT.md version 2): the rotation to world axes (2x2 planar, 3x3 spatial), whose
    columns are the body axes; `angular_velocity` is then the tool's body-axes omega (planar: omega_z).
    `inertia` has 9 entries (row by row) for a full tensor."""
    points: Mapping[str, tuple[sp.Expr, ...]] = field(default_factory=dict)
    """The body's `points`, as world positions."""
    forces: tuple[tuple[tuple[sp.Expr, ...], tuple[sp.Expr, ...]], ...] = ()
    """Each `force` load: (the force in world axes, the world position where it acts)."""
    torques: tuple[tuple[sp.Expr, ...], ...] = ()
    """Each `torque` load in body axes (a planar body's: its z component alone)."""
    local: tuple[tuple[sp.Expr, ...], ...] | None = None
    """With `orientation`: the rotation relative to the parent (`relative_to`, else the world)."""
    parent: str | None = None
    """The body named by `relative_to`."""
    velocity: tuple[sp.Expr, ...] | None = None
    """With `orientation`: the velocity of the centre of mass in body axes."""
    frame_forces: tuple[tuple[tuple[sp.Expr, ...], tuple[sp.Expr, ...]], ...] = ()
    """With `orientation`, each `force` load as (the force in body axes, the velocity of the point where it acts in body axes)."""
    anchor: tuple[str | None, tuple[sp.Expr, ...], tuple[sp.Expr, ...]] | None = None
    """With `orientation` and a `pivot` that is a point (or the centre) of the `relative_to` parent: (the parent, the
    pivot from the parent's centre of mass in the parent's axes, this body's centre from its pivot in its own axes),
    all constant: the body is then rigidly hinged to its parent (derive.py's composite bodies). Without
    `relative_to`, a pivot fixed in the world: (None, zeros, the centre from the pivot)."""


@dataclass(frozen=True)
class Constraint:
    """`expr = 0`: holonomic when it has no velocities, else linear in the velocities."""

    name: str
    expr: sp.Expr
    holonomic: bool
    span: Span


@dataclass(frozen=True)
class DrawPoint:
    """A point an animation draws: `label` is the particle or body it names (empty for a position
    list), `position` its Cartesian position in the file's coordinates, parameters and `t`."""

    label: str
    position: tuple[sp.Expr, ...]
    span: Span


@dataclass(frozen=True)
class Drawing:
    """The `draw` block: segments (pairs of points joined by a line) and trails (points whose
    recent path is drawn)."""

    segments: tuple[tuple[DrawPoint, DrawPoint], ...] = ()
    trails: tuple[DrawPoint, ...] = ()


@dataclass(frozen=True)
class Symmetry:
    """A declared continuous symmetry (`symmetries: {name: {coordinates: {q: delta_q}, time: delta_t}}`):
    the infinitesimal change of the listed coordinates (others unchanged) and of time, each an
    expression of the coordinates, parameters and `t`; lagrange_cli/noether.py checks it."""

    name: str
    coordinates: tuple[tuple[str, sp.Expr, Span], ...]
    time: sp.Expr | None
    span: Span
    time_span: Span | None = None


@dataclass(frozen=True)
class Expect:
    equations: tuple[tuple[sp.Expr, Span], ...] = ()
    accelerations: tuple[tuple[str, sp.Expr, Span], ...] = ()
    momenta: tuple[tuple[str, sp.Expr, Span], ...] = ()
    conserved: tuple[tuple[str, Span], ...] = ()
    """Coordinate names and `energy` (their conservation is decided symbolically)."""
    hamiltonian: tuple[sp.Expr, Span] | None = None
    """H in the coordinates and the momenta `p_<q>` (FORMAT.md version 2)."""
    hamilton_equations: tuple[tuple[sp.Expr, Span], ...] = ()
    """Equations in `<q>_dot`, `p_<q>` and `p_<q>_dot` (each `lhs - rhs`)."""
    state_space: ExpectedStateSpace | None = None
    """`expect.state_space` (FORMAT.md version 2; lagrange_cli/inputs.py)."""
    conserved_expressions: tuple[tuple[str, sp.Expr | None, Span], ...] = ()
    """`conserved` entries that are expressions (text, expression) or the name of a declared
    symmetry (name, None: its Noether charge); each is checked to be constant along every motion."""

    def __bool__(self) -> bool:
        return bool(self.equations or self.accelerations or self.momenta or self.conserved or self.conserved_expressions or self.hamiltonian or self.hamilton_equations or self.state_space)


@dataclass(frozen=True)
class SystemSpec:
    """A validated system file. Symbols are plain (no assumptions); `q_dot` names are `<q>_dot`."""

    path: str
    title: str
    description: str
    coordinates: tuple[str, ...]
    q: tuple[sp.Symbol, ...]
    qd: tuple[sp.Symbol, ...]
    qdd: tuple[sp.Symbol, ...]
    t: sp.Symbol
    parameters: tuple[Parameter, ...]
    functions: tuple[str, ...] = ()
    definitions: Mapping[str, sp.Lambda] = field(default_factory=dict)
    """Functions given a numeric definition (map form of `functions`): name -> Lambda(arguments, expression)."""
    gravity: tuple[sp.Expr, ...] | None = None
    particles: tuple[Particle, ...] = ()
    bodies: tuple[Body, ...] = ()
    kinetic: sp.Expr = sp.S.Zero
    potential: sp.Expr = sp.S.Zero
    lagrangian: sp.Expr = sp.S.Zero
    dissipation: sp.Expr = sp.S.Zero
    generalized_forces: tuple[sp.Expr, ...] = ()
    constraints: tuple[Constraint, ...] = ()
    eliminate: tuple[tuple[str, Span], ...] = ()
    initial: Mapping[str, float] = field(default_factory=dict)
    simulate: Mapping[str, Any] = field(default_factory=dict)
    exact: Mapping[str, sp.Expr] = field(default_factory=dict)
    spans: Mapping[str, Span] = field(default_factory=dict)
    sources: Mapping[str, Span] = field(default_factory=dict)
    """Where the other expressions are written: `potential`, `kinetic`, `lagrangian`, `dissipation`,
    `gravity`, `forces.<q>`, `functions.<f>`, `exact.<q>` (so that a bad term found after
    derivation is reported at its source)."""
    expect: Expect = Expect()
    draw: Drawing | None = None
    """The `draw` block (None without one: an animation then draws particles and bodies as dots)."""
    inputs: tuple[Input, ...] = ()
    """The `inputs` (lagrange_cli/inputs.py), in the file's order."""
    outputs: tuple[tuple[str, sp.Expr], ...] = ()
    """The `outputs`, name -> expression of q, q_dot, t and the inputs, in the file's order."""
    symmetries: tuple[Symmetry, ...] = ()
    """The declared continuous symmetries, in file order (checked by lagrange_cli/noether.py)."""
    units: Units | None = None
    """The `units` block (None without one: no dimensional checking); see units.py."""


def time_derivative(expr: sp.Expr, q: tuple[sp.Symbol, ...], qd: tuple[sp.Symbol, ...], qdd: tuple[sp.Symbol, ...], t: sp.Symbol) -> sp.Expr:
    """Total time derivative: d/dt f = sum df/dq q_dot + df/dq_dot q_ddot + df/dt."""
    if any(expr.has(a) for a in qdd):
        raise LagrangeError("cannot take the time derivative of an expression with accelerations")
    result = sp.diff(expr, t)
    for qi, qdi, qddi in zip(q, qd, qdd, strict=True):
        result += sp.diff(expr, qi) * qdi + sp.diff(expr, qdi) * qddi
    return result
