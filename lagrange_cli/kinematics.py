"""Rigid-body kinematics for the version 2 body keys: rotations, sequences, angular velocities.

Rotations are built as plain nested products (no simplification): an elementary rotation, a
product of three for an Euler or Tait-Bryan sequence, Rodrigues' formula for an axis and angle,
or a matrix written in the file. The angular velocity is never found by differentiating a
composed rotation: for a product of elementary rotations E_1(a_1) ... E_n(a_n) it is, in body axes,

    omega = sum_k (E_{k+1} ... E_n)^T e_k a_k_dot,

for an axis and angle n a_dot, and down a `relative_to` chain omega = L^T omega_parent + omega_rel,
where L is the rotation relative to the parent (its world rotation is R_parent L). Only for an
explicit matrix is omega the axial vector of L^T dL/dt, computed from its entries.

The derivation side (derive.py's `oriented_bodies`) works in symengine; `Rate` is its time derivative
(without the accelerations) of the nested velocities, each shared part differentiated once.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import sympy as sp

SEQUENCES = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX", "XYX", "XZX", "YXY", "YZY", "ZXZ", "ZYZ")
"""The twelve Euler (XYX ...) and Tait-Bryan (XYZ ...) sequences."""

Matrix = tuple[tuple[Any, ...], ...]
Vector = tuple[Any, ...]


def elementary(axis: str, angle: Any, lib: Any = sp) -> Matrix:
    """The right-handed rotation by `angle` about the X, Y or Z axis (`lib` supplies sin and cos)."""
    c, s = lib.cos(angle), lib.sin(angle)
    zero, one = lib.Integer(0), lib.Integer(1)
    if axis == "X":
        return ((one, zero, zero), (zero, c, -s), (zero, s, c))
    if axis == "Y":
        return ((c, zero, s), (zero, one, zero), (-s, zero, c))
    return ((c, -s, zero), (s, c, zero), (zero, zero, one))


def planar(angle: Any, lib: Any = sp) -> Matrix:
    """The 2-D rotation by `angle`."""
    c, s = lib.cos(angle), lib.sin(angle)
    return ((c, -s), (s, c))


def factors(sequence: str, angles: Sequence[Any], kind: str) -> list[tuple[str, Any]]:
    """The elementary rotations of a sequence in product order: body (intrinsic) R = R_a(a1) R_b(a2) R_c(a3),
    space (extrinsic) R = R_c(a3) R_b(a2) R_a(a1)."""
    pairs = list(zip(sequence.upper(), angles, strict=True))
    return pairs if kind == "body" else pairs[::-1]


def product(pairs: Sequence[tuple[str, Any]], lib: Any = sp) -> Matrix:
    result = identity(3, lib)
    for axis, angle in pairs:
        result = matmul(result, elementary(axis, angle, lib))
    return result


def product_omega(pairs: Sequence[tuple[str, Any]], rates: Sequence[Any], lib: Any = sp) -> Vector:
    """Body-axes angular velocity of E_1(a_1) ... E_n(a_n): sum_k (E_{k+1} ... E_n)^T e_k a_k_dot,
    accumulated from the last factor back (each step one more transposed elementary rotation)."""
    zero = lib.Integer(0)
    total: Vector = (zero, zero, zero)
    tail: Matrix = identity(3, lib)  # (E_{j+1} ... E_n)^T
    for (axis, angle), rate in zip(reversed(pairs), reversed(rates), strict=True):
        column = tuple(tail[i]["XYZ".index(axis)] for i in range(3))
        total = tuple(total[i] + column[i] * rate for i in range(3))
        tail = matmul(tail, transpose(elementary(axis, angle, lib)))
    return total


def rodrigues(axis: Sequence[Any], angle: Any, lib: Any = sp) -> Matrix:
    """The rotation by `angle` about the unit vector `axis`: cos I + sin [n]x + (1 - cos) n n^T."""
    c, s = lib.cos(angle), lib.sin(angle)
    x, y, z = axis
    cross = ((0, -z, y), (z, 0, -x), (-y, x, 0))
    return tuple(tuple((c if i == j else 0) + s * cross[i][j] + (1 - c) * axis[i] * axis[j] for j in range(3)) for i in range(3))


def identity(n: int, lib: Any = sp) -> Matrix:
    return tuple(tuple(lib.Integer(1 if i == j else 0) for j in range(n)) for i in range(n))


def transpose(a: Matrix) -> Matrix:
    return tuple(tuple(a[j][i] for j in range(len(a))) for i in range(len(a[0])))


def matmul(a: Matrix, b: Matrix) -> Matrix:
    return tuple(tuple(_sum(a[i][k] * b[k][j] for k in range(len(b)) if not _is_zero(a[i][k]) and not _is_zero(b[k][j])) for j in range(len(b[0]))) for i in range(len(a)))


def matvec(a: Matrix, v: Sequence[Any]) -> Vector:
    return tuple(_sum(a[i][k] * v[k] for k in range(len(v)) if not _is_zero(a[i][k]) and not _is_zero(v[k])) for i in range(len(a)))


def axial(w: Matrix) -> Vector:
    """The axial vector of a skew matrix W (W v = w x v), from its entries below the diagonal and above, averaged."""
    half = sp.Rational(1, 2)
    return ((w[2][1] - w[1][2]) * half, (w[0][2] - w[2][0]) * half, (w[1][0] - w[0][1]) * half)


def matrix_omega(rotation: Matrix, ddt: Callable[[Any], Any]) -> Vector:
    """Body-axes angular velocity of a rotation written as a matrix: the axial vector of R^T dR/dt."""
    rate = tuple(tuple(ddt(e) for e in row) for row in rotation)
    return axial(matmul(transpose(rotation), rate))


def _is_zero(value: Any) -> bool:
    return value == 0


def _sum(terms: Any) -> Any:
    items = list(terms)
    if not items:
        return sp.Integer(0)
    total = items[0]
    for item in items[1:]:
        total = total + item
    return total


class Rate:
    """The time derivative without the accelerations, sum_k dx/dq_k q_dot_k + dx/dt, of symengine expressions,
    taken node by node down the expression (forward mode) and remembered per distinct sub-expression.

    A body's velocity and angular velocity down a `relative_to` chain are nested (omega = L^T omega_parent +
    omega_rel), and bodies share their parents' parts: differentiating by each coordinate in turn
    (`se.diff(x, q_k)` for every k) writes out the chain once per coordinate, where this visits each shared part
    once and its derivative reuses the parts it was built from (d(L^T v) = dL^T v + L^T dv). Sums, products,
    integer and constant powers, sin and cos go node by node; anything else (rare: another function of the
    coordinates) by `se.diff` by each coordinate and t, which is what the whole would have cost."""

    def __init__(self, q: Sequence[Any], qd: Sequence[Any], t: Any) -> None:
        from lagrange_cli._symengine import se  # the frontend (rigid.py) uses this module without symengine

        self.se = se
        self.zero, self.one = se.Integer(0), se.Integer(1)
        self.q, self.qd, self.t = list(q), list(qd), t
        self.rates = dict(zip(self.q, self.qd, strict=True))
        self.memo: dict[Any, Any] = {}

    def __call__(self, expr: Any) -> Any:
        found = self.memo.get(expr)
        if found is None:
            found = self.memo[expr] = self._rate(expr)
        return found

    def _rate(self, e: Any) -> Any:
        se, zero = self.se, self.zero
        if e.is_Number:
            return zero
        if isinstance(e, se.Symbol) and not isinstance(e, se.FunctionSymbol):
            return self.rates.get(e, self.one if e == self.t else zero)
        if isinstance(e, se.Add):
            return se.Add(*(d for d in map(self, e.args) if d != zero))
        if isinstance(e, se.Mul):
            args = e.args
            terms = []
            for i, a in enumerate(args):
                d = self(a)
                if d != zero:
                    terms.append(se.Mul(*args[:i], d, *args[i + 1 :]))
            return se.Add(*terms)
        if isinstance(e, se.Pow) and e.args[1].is_Number:
            base, exponent = e.args
            d = self(base)
            return zero if d == zero else exponent * base ** (exponent - 1) * d
        if isinstance(e, se.sin):
            d = self(e.args[0])
            return zero if d == zero else se.cos(e.args[0]) * d
        if isinstance(e, se.cos):
            d = self(e.args[0])
            return zero if d == zero else -se.sin(e.args[0]) * d
        return se.Add(*(se.diff(e, qk) * self.rates[qk] for qk in self.q), se.diff(e, self.t))
