"""Projection of a state onto the manifold of a model's kept constraints.

The index-1 equations that `simulate` integrates (codegen's `_accel`, with Baumgarte's
stabilisation) enforce the constraints only at the acceleration level, so that integration
errors accumulate in the positions and velocities. `Projector.project(t, y)` puts a state back:

- positions, for the holonomic constraints f(q, t) = 0: a few Gauss-Newton steps of the
  M-weighted (mass-metric) projection q <- q - M^-1 A^T (A M^-1 A^T)^-1 f(q, t), A = df/dq, the
  smallest correction in kinetic-energy norm, until |f| is at round-off level;
- velocities, for every kept constraint a(q, t) . q_dot + b(q, t) = 0 (holonomic or not), at the
  projected positions: q_dot <- q_dot - M^-1 A^T (A M^-1 A^T)^-1 (A q_dot + b), which is exact
  (the constraint is linear in q_dot);
- for a system that conserves its energy h (`Model.energy_conserved`), given the level h0 of the
  start: the velocities onto h(q, q_dot) = h0 as well, together with the velocity constraints
  (Gauss-Newton with the rows [A; (M q_dot)^T], dh/dq_dot = M q_dot being exact for Lagrangians
  quadratic in the velocities), skipped where q_dot is too small for the energy to be set
  through it (a turning point) or the correction would not be small. Kept constraints then hold
  the phase error of a long run to the integrator's own: the Cartesian pendulum's energy no
  longer drifts, so its period does not either.

The rows (f, the gradient rows `ConstraintRow.jacobian`, the bias b) and the mass matrix are the
model's own symbolic expressions, evaluated exactly (no numerical differentiation). `simulate`
projects after each stretch of the run between two samples (settings `projection`), and reports
the largest correction in its notes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from lagrange_cli.model import Model
from lagrange_cli.numeric import memo

NEWTON_STEPS = 4
"""Gauss-Newton steps at most for the positions (the residual squares each step: two suffice from
an integration error of 1e-8)."""
ROUND_OFF = 4.0 * float(np.finfo(float).eps)
"""A position residual below this (relative to the sizes of its terms) is at round-off: stop."""


ENERGY_STEPS = 3
"""Gauss-Newton steps at most for the energy level (h is quadratic in q_dot)."""
ENERGY_CONDITION = 1e8
"""Condition number of [A; (M q_dot)^T] M^-1 [A; (M q_dot)^T]^T above which the energy is not
projected at this state (q_dot nearly 0 or along the constraint normals)."""
ENERGY_CHANGE = 1e-4
"""Largest relative change of q_dot the energy projection may make (a correction of integration
error is far smaller; anything larger means h cannot be set through q_dot here)."""


@dataclass(frozen=True)
class Correction:
    """How far one projection moved a state: the residuals before, and the size of the changes."""

    position: float
    """max |f(q, t)| before (0 without holonomic constraints)."""
    velocity: float
    """max |a . q_dot + b| before (after the position projection)."""
    moved: float
    """max |change| of any coordinate or velocity."""
    energy: float = 0.0
    """|h - h0| before the energy step (0 when the energy is not projected)."""


class Projector:
    """Projects states of one model, at given parameter values, onto its kept constraints."""

    def __init__(self, model: Model, values: Sequence[float], energy: Callable[[float, np.ndarray], float] | None = None, level: float | None = None) -> None:
        """`energy(t, y)` and its `level` h0: also project onto h = h0 (a conserved energy)."""
        self.n = model.n
        both = energy is not None and level is not None
        self.energy: Callable[[float, np.ndarray], float] | None = energy if both else None
        self.level: float | None = level if both else None
        self.holonomic = np.array([c.holonomic for c in model.constraints], dtype=bool)
        self._rows = memo.once(model, "projection rows", lambda: _rows(model))
        self._values = [float(v) for v in values]

    def _evaluate(self, t: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(f, A, b, M) at (t, q): f of the holonomic rows (0 for the others), the k x n gradient
        rows, the biases and the n x n mass matrix."""
        f, a, b, m = self._rows(t, *q.tolist(), *self._values)
        return np.array(f, dtype=float), np.array(a, dtype=float).reshape(len(self.holonomic), self.n), np.array(b, dtype=float), np.array(m, dtype=float).reshape(self.n, self.n)

    def project(self, t: float, y: np.ndarray) -> tuple[np.ndarray, Correction]:
        """The state y = [q..., q_dot...] projected onto the constraints at t, and how far it moved.
        Raises ArithmeticError, ValueError or numpy's LinAlgError where the rows cannot be
        evaluated or A M^-1 A^T is singular (the caller keeps the state as it was)."""
        n = self.n
        q, qd = y[:n].astype(float), y[n:].astype(float)
        first_position = 0.0
        if self.holonomic.any():
            for step in range(NEWTON_STEPS):
                f, a, _, m = self._evaluate(t, q)
                f, a = f[self.holonomic], a[self.holonomic]
                if step == 0:
                    first_position = float(np.max(np.abs(f)))
                size = 1.0 + float(np.max(np.abs(a))) * float(np.max(np.abs(q)))
                if float(np.max(np.abs(f))) <= ROUND_OFF * size:
                    break
                q = q - _weighted(m, a, f)
        _, a, b, m = self._evaluate(t, q)
        residual = a @ qd + b
        qd = qd - _weighted(m, a, residual)
        off_level = self._energy_level(t, q, qd, a, b, m) if self.energy is not None else None
        if off_level is not None:
            qd, energy_error = off_level
        else:
            energy_error = 0.0
        projected = np.concatenate([q, qd])
        if not np.all(np.isfinite(projected)):
            raise ArithmeticError("the projection gave non-finite values")
        return projected, Correction(first_position, float(np.max(np.abs(residual))), float(np.max(np.abs(projected - y))), energy_error)

    def _energy_level(self, t: float, q: np.ndarray, qd: np.ndarray, a: np.ndarray, b: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, float] | None:
        """q_dot moved onto h(q, q_dot) = h0 and A q_dot + b = 0 (None where that is skipped: q_dot
        too small to carry the correction, or the correction not small)."""
        assert self.energy is not None and self.level is not None
        start = qd
        first = None
        for _ in range(ENERGY_STEPS):
            error = self.energy(t, np.concatenate([q, qd])) - self.level
            first = abs(error) if first is None else first
            gradient = m @ qd  # dh/dq_dot
            size = abs(self.level) + abs(float(qd @ gradient))
            if abs(error) <= ROUND_OFF * size:
                break
            rows = np.vstack([a, gradient[None, :]])
            w = np.linalg.solve(m, rows.T)
            normal = rows @ w
            if np.linalg.cond(normal) > ENERGY_CONDITION:  # q_dot (nearly) along the constraint normals or 0: a turning point
                return None
            qd = qd - w @ np.linalg.solve(normal, np.concatenate([a @ qd + b, [error]]))
        scale = float(np.max(np.abs(start))) + 1e-300
        if not np.all(np.isfinite(qd)) or float(np.max(np.abs(qd - start))) > ENERGY_CHANGE * scale:
            return None
        return qd, float(first or 0.0)


def _weighted(m: np.ndarray, a: np.ndarray, r: np.ndarray) -> np.ndarray:
    """M^-1 A^T (A M^-1 A^T)^-1 r: the M-weighted least-norm solution of A dx = r."""
    w = np.linalg.solve(m, a.T)  # M^-1 A^T
    return w @ np.linalg.solve(a @ w, r)  # type: ignore[no-any-return]


def _rows(model: Model) -> Callable[..., tuple[list[float], list[float], list[float], list[float]]]:
    """(f, A, b, M) as one function of (t, q..., parameters...): the model's symbolic rows."""
    model = model.with_definitions()
    f = [c.expr if c.holonomic else sp.Integer(0) for c in model.constraints]  # a velocity row's expr has q_dot
    a = [entry for c in model.constraints for entry in c.jacobian]
    b = [c.bias for c in model.constraints]
    m = list(sp.Matrix(model.mass_matrix))
    return sp.lambdify([model.t, *model.q, *(par.symbol for par in model.parameters)], [f, a, b, m], modules="math")  # type: ignore[no-any-return]
