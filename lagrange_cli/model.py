"""The derived model of a system: frozen data that every emitter and numeric routine reads."""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import sympy as sp
from sympy.core.function import AppliedUndef

from lagrange_cli.errors import Span


@dataclass(frozen=True)
class Parameter:
    """A constant symbol; `value` is the default used by simulation (None when not given)."""

    symbol: sp.Symbol
    value: float | None
    real: bool = False
    description: str = ""

    @property
    def name(self) -> str:
        return str(self.symbol)


@dataclass(frozen=True)
class Input:
    """An external input u(t) (FORMAT.md version 2): a symbol in the equations, with its default
    value (0 unless the file gives one); see lagrange_cli/inputs.py."""

    symbol: sp.Symbol
    value: float = 0.0
    description: str = ""
    span: Span | None = field(default=None, compare=False)

    @property
    def name(self) -> str:
        return str(self.symbol)


@dataclass(frozen=True)
class ConstraintRow:
    """A constraint in velocity form `a . q_dot + b = 0` and acceleration form `a . q_ddot + c = 0`.

    For a holonomic constraint f(q, t) = 0: a = df/dq and b = df/dt.
    Its multiplier `lambda_<name>` enters the equations as `M q_ddot = F + a^T lambda`.
    """

    name: str
    expr: sp.Expr
    holonomic: bool
    multiplier: sp.Symbol
    jacobian: tuple[sp.Expr, ...]
    bias: sp.Expr
    acceleration_bias: sp.Expr


@dataclass(frozen=True)
class Carrier:
    """A particle or body that constraint forces act on (`forces.py`): its position and, for a body,
    its angular velocity (planar: one entry; spatial: body axes), in the model's coordinates."""

    name: str
    body: bool
    position: tuple[sp.Expr, ...]
    angular_velocity: tuple[sp.Expr, ...] = ()


class Lazy:
    """A sympy field of a `Model` that is built on first access (`make()`), then kept.

    `derive` computes in symengine and fills `Model.symengine`; the sympy fields (`mass_matrix`,
    `forcing`, `kinetic`, ...) are converted from it only when something reads them, so that a
    consumer printing from `Model.symengine` never pays for the conversion of a big system."""

    __slots__ = ("make",)

    def __init__(self, make: Callable[[], Any]) -> None:
        self.make = make


LAZY_FIELDS = ("kinetic", "potential", "lagrangian", "dissipation", "generalized_forces", "mass_matrix", "forcing", "momenta", "energy")
"""The sympy fields of a `Model` that `Model.from_symengine` leaves to be converted on first access."""


@dataclass(frozen=True)
class Model:
    """Equations of motion `M(q, t) q_ddot = F(q, q_dot, t) + A^T lambda`, with `A q_ddot + c = 0`.

    F collects everything but the accelerations: dL/dq - (d/dt of dL/dq_dot without q_ddot)
    - dR/dq_dot + Q. The Lagrange form of equation i is `(M q_ddot - F - A^T lambda)_i = 0`.

    A model made by `derive` (`Model.from_symengine`) holds its equations as symengine expressions
    (`symengine`) and converts a sympy field the first time it is read (see `Lazy`).
    """

    title: str
    source: str
    coordinates: tuple[str, ...]
    q: tuple[sp.Symbol, ...]
    qd: tuple[sp.Symbol, ...]
    qdd: tuple[sp.Symbol, ...]
    t: sp.Symbol
    parameters: tuple[Parameter, ...]
    kinetic: sp.Expr
    potential: sp.Expr
    lagrangian: sp.Expr
    dissipation: sp.Expr
    generalized_forces: tuple[sp.Expr, ...]
    mass_matrix: sp.ImmutableMatrix
    forcing: sp.ImmutableMatrix
    momenta: tuple[sp.Expr, ...]
    energy: sp.Expr
    constraints: tuple[ConstraintRow, ...] = ()
    eliminated: tuple[tuple[str, sp.Expr], ...] = ()
    description: str = ""
    carriers: tuple[Carrier, ...] = ()
    """The particles and bodies, for the constraint forces on each (`forces.py`)."""
    initial: Mapping[str, float] = field(default_factory=dict)
    simulate: Mapping[str, Any] = field(default_factory=dict)
    exact: Mapping[str, sp.Expr] = field(default_factory=dict)
    spans: Mapping[str, Span] = field(default_factory=dict)
    definitions: Mapping[str, sp.Lambda] = field(default_factory=dict)
    """The file's definitions of its functions, e.g. U -> Lambda(s, -k/s). The equations keep the
    general U(r); numeric code evaluates `with_definitions()`."""
    functions: tuple[str, ...] = ()
    """Every function the file declares (defined or not, `definitions` holds the defined ones)."""
    inputs: tuple[Input, ...] = ()
    """The file's inputs, in its order (lagrange_cli/inputs.py); numeric code evaluates `inputs.substitute(model)`."""
    outputs: tuple[tuple[str, sp.Expr], ...] = ()
    """The file's outputs, name -> expression of q, q_dot, t and the inputs, in its order."""

    def __getattribute__(self, name: str) -> Any:
        value = object.__getattribute__(self, name)
        if value.__class__ is Lazy:
            value = value.make()
            object.__setattr__(self, name, value)
        return value

    @classmethod
    def from_symengine(cls, forms: SymengineForms, sympy: Mapping[str, Any] | None = None, refuse: Exception | None = None, **fields: Any) -> Model:
        """A model whose equations are `forms`; each field of `LAZY_FIELDS` is converted to sympy on first
        access, unless `sympy` gives it already (a value computed in sympy on the way). With `refuse`, reading
        a sympy field raises it instead (equations too large to write out in full, usable in symengine only)."""
        import lagrange_cli._symengine as convert

        given = dict(sympy or {})
        n = len(forms.q)
        cache: dict[Any, Any] = {}  # shared by the fields: an entry of M is converted once for M, K, p and h

        def conv(value: Any) -> Any:
            return convert.to_sympy(value, cache)

        def one(value: Any) -> Lazy:
            return Lazy(lambda: conv(value))

        def many(values: tuple[Any, ...]) -> Lazy:
            return Lazy(lambda: tuple(conv(v) for v in values))

        lazy: dict[str, Any] = {
            "kinetic": one(forms.kinetic),
            "potential": one(forms.potential),
            "lagrangian": one(forms.lagrangian),
            "dissipation": one(forms.dissipation),
            "energy": one(forms.energy),
            "generalized_forces": many(forms.generalized_forces),
            "momenta": many(forms.momenta),
            "mass_matrix": Lazy(lambda: sp.ImmutableMatrix(n, n, [conv(m) for row in forms.mass for m in row])),
            "forcing": Lazy(lambda: sp.ImmutableMatrix(n, 1, [conv(f) for f in forms.forcing])),
        }
        if refuse is not None:

            def refused() -> Any:
                raise refuse

            lazy = {name: Lazy(refused) for name in lazy}
        lazy.update(given)
        model = cls(**fields, **lazy)
        object.__setattr__(model, "_symengine", forms)
        object.__setattr__(model, "_native", True)
        return model

    def converted(self) -> frozenset[str]:
        """The fields of `LAZY_FIELDS` that have been converted to sympy so far (all of them for a model
        not made by `from_symengine`)."""
        return frozenset(name for name in LAZY_FIELDS if object.__getattribute__(self, name).__class__ is not Lazy)

    @property
    def n(self) -> int:
        return len(self.q)

    @property
    def multipliers(self) -> tuple[sp.Symbol, ...]:
        return tuple(c.multiplier for c in self.constraints)

    @property
    def autonomous(self) -> bool:
        """True when nothing depends explicitly on time."""
        forms = self.symengine
        if any(forms.t in e.free_symbols for e in (*(m for row in forms.mass for m in row), *forms.forcing)):
            return False
        parts = [(*c.jacobian, c.bias, c.acceleration_bias) for c in self.constraints]
        return not any(sp.Matrix(p).has(self.t) for p in parts)

    @property
    def dissipative(self) -> bool:
        return self.symengine.dissipation != 0

    @property
    def forced(self) -> bool:
        return any(f != 0 for f in self.symengine.generalized_forces)

    @property
    def constraint_matrix(self) -> sp.ImmutableMatrix:
        """A, one row per constraint (empty 0 x n without constraints)."""
        return sp.ImmutableMatrix(len(self.constraints), self.n, [a for c in self.constraints for a in c.jacobian])

    def equations(self) -> tuple[sp.Expr, ...]:
        """The Lagrange form: one expression per coordinate, each `= 0`."""
        rows = []
        for i in range(self.n):
            lhs = sum((self.mass_matrix[i, j] * self.qdd[j] for j in range(self.n)), sp.Integer(0)) - self.forcing[i]
            lhs -= sum((c.jacobian[i] * c.multiplier for c in self.constraints), sp.Integer(0))
            rows.append(lhs)
        return tuple(rows)

    def ignorable(self, i: int) -> bool:
        """q_i is ignorable when dL/dq_i = 0 and nothing else acts along it, so that its
        momentum p_i = dL/dq_dot_i is conserved (Eqs. 6.37-6.38)."""
        return _vanishes(sp.diff(self.lagrangian, self.q[i])) and sp.diff(self.dissipation, self.qd[i]) == 0 and self.generalized_forces[i] == 0 and all(c.jacobian[i] == 0 for c in self.constraints)

    @property
    def energy_conserved(self) -> bool:
        """h = sum p q_dot - L is conserved when L has no explicit t, nothing dissipates or is
        applied, and every constraint is scleronomic."""
        forms = self.symengine  # not the sympy fields, which a big spatial model cannot convert
        return forms.t not in forms.lagrangian.free_symbols and forms.dissipation == 0 and not self.forced and all(c.bias == 0 and not c.expr.has(self.t) for c in self.constraints)

    @property
    def symengine(self) -> SymengineForms:
        """The equations as symengine expressions, for the emitters and code generators that print
        big systems: they read these and never need the sympy fields (which, for big systems, cost
        more to build than the derivation itself). A model from `derive` has them from the start;
        any other (e.g. made by `dataclasses.replace`) converts its sympy fields once."""
        forms = self.__dict__.get("_symengine")
        if forms is None:
            forms = self._symengine_from_sympy()
            object.__setattr__(self, "_symengine", forms)
        return forms

    @property
    def native(self) -> bool:
        """True for a model made by `derive` (its symengine forms are the computed equations, not a conversion)."""
        return "_native" in self.__dict__

    def _symengine_from_sympy(self) -> SymengineForms:
        from lagrange_cli._symengine import to_symengine

        def conv(values: Any) -> tuple[Any, ...]:
            return tuple(to_symengine(v) for v in values)

        n = self.n
        return SymengineForms(
            q=conv(self.q),
            qd=conv(self.qd),
            qdd=conv(self.qdd),
            t=to_symengine(self.t),
            mass=tuple(conv(self.mass_matrix[i, j] for j in range(n)) for i in range(n)),
            forcing=conv(self.forcing),
            kinetic=to_symengine(self.kinetic),
            potential=to_symengine(self.potential),
            lagrangian=to_symengine(self.lagrangian),
            dissipation=to_symengine(self.dissipation),
            energy=to_symengine(self.energy),
            momenta=conv(self.momenta),
            generalized_forces=conv(self.generalized_forces),
        )

    def parameter_values(self) -> dict[str, float]:
        return {p.name: p.value for p in self.parameters if p.value is not None}

    def with_definitions(self) -> Model:
        """This model with every defined function written out, `U(r)` -> `-k/r` and
        `Derivative(U(r), r)` -> `k/r**2`: what numeric code evaluates. Computed once per model."""
        return self._with_definitions

    @functools.cached_property
    def _with_definitions(self) -> Model:
        if not self.definitions:
            return self

        def sub(expr: sp.Expr) -> sp.Expr:
            return apply_definitions(expr, self.definitions)

        def subs_all(values: tuple[sp.Expr, ...]) -> tuple[sp.Expr, ...]:
            return tuple(sub(v) for v in values)

        rows = tuple(dataclasses.replace(c, expr=sub(c.expr), jacobian=subs_all(c.jacobian), bias=sub(c.bias), acceleration_bias=sub(c.acceleration_bias)) for c in self.constraints)
        return dataclasses.replace(
            self,
            kinetic=sub(self.kinetic),
            potential=sub(self.potential),
            lagrangian=sub(self.lagrangian),
            dissipation=sub(self.dissipation),
            generalized_forces=subs_all(self.generalized_forces),
            mass_matrix=self.mass_matrix.applyfunc(sub),
            forcing=self.forcing.applyfunc(sub),
            momenta=subs_all(self.momenta),
            energy=sub(self.energy),
            constraints=rows,
            carriers=tuple(dataclasses.replace(c, position=subs_all(c.position), angular_velocity=subs_all(c.angular_velocity)) for c in self.carriers),
            eliminated=tuple((name, sub(e)) for name, e in self.eliminated),
            exact={name: sub(e) for name, e in self.exact.items()},
            outputs=tuple((name, sub(e)) for name, e in self.outputs),
            definitions={},
        )


@dataclass(frozen=True)
class SymengineForms:
    """`Model.symengine`: the model's equations as symengine expressions (same symbol names as the
    sympy fields; the functions of the file's `functions` stay undefined, as in the sympy fields)."""

    q: tuple[Any, ...]
    qd: tuple[Any, ...]
    qdd: tuple[Any, ...]
    t: Any
    mass: tuple[tuple[Any, ...], ...]
    forcing: tuple[Any, ...]
    kinetic: Any
    potential: Any
    lagrangian: Any
    dissipation: Any
    energy: Any
    momenta: tuple[Any, ...]
    generalized_forces: tuple[Any, ...]


def apply_definitions(expr: sp.Expr, definitions: Mapping[str, sp.Lambda]) -> sp.Expr:
    """`expr` with each call of a defined function replaced by its definition (matched by name,
    as the function comes back from symengine as a new object), then the derivatives of those
    calls taken: `Derivative(U(r), r)` and `Subs(Derivative(U(x), x), x, r - s)` become numbers'
    expressions. Derivatives are taken with real stand-ins, as in the parser: every quantity is
    real, and sympy differentiates `Abs(x)` of an unknown x into `re` and `im` terms."""
    if not definitions or not expr.has(AppliedUndef):
        return expr

    def wanted(e: sp.Basic) -> bool:
        return (isinstance(e, AppliedUndef) and str(e.func) in definitions) or isinstance(e, (sp.Derivative, sp.Subs))

    def value(e: sp.Basic) -> sp.Basic:
        if isinstance(e, AppliedUndef):
            return definitions[str(e.func)](*e.args)
        real = {s: sp.Dummy(s.name, real=True) for s in e.free_symbols if isinstance(s, sp.Symbol)}
        return e.xreplace(real).doit().xreplace({v: s for s, v in real.items()})

    return expr.replace(wanted, value)


def _vanishes(expr: sp.Expr) -> bool:
    """expr == 0 identically. Oriented bodies give L unsimplified (a symmetric rotor's spin angle
    enters only through sin^2 + cos^2), so a structural test is not enough: a value at two random
    points settles most non-zero cases cheaply; what is zero there is simplified."""
    if expr == 0:
        return True
    import random

    rng = random.Random(1)
    names = sorted(expr.free_symbols, key=str)
    for _ in range(2):
        try:
            value = complex(expr.xreplace({s: sp.Float(rng.uniform(0.3, 1.7)) for s in names}).evalf())
        except (TypeError, ValueError):
            break
        if abs(value) > 1e-9:
            return False
    return bool(sp.simplify(sp.expand_trig(expr)) == 0)
