"""What makes a system hard to integrate, measured at a state: shared by `stress` and `simulate --method auto`.

- `spectrum(J)`: from the eigenvalues lambda of the Jacobian df/dy, the fastest decay
  max(-Re lambda) among real-dominated eigenvalues (|Re| > |Im|: dissipative stiffness), the
  spectral radius max |lambda| (the fastest time scale, oscillatory or not), and the slowest
  non-zero |lambda|; their ratios are the stiffness ratio and the ratio of time scales.
- `mass_condition(model, p)`: the 2-norm condition number of M(q, t), which grows without
  bound near a coordinate singularity (Euler angles at theta = 0, the pole of spherical
  coordinates).
- `jacobian(rhs, t, y)`: a forward-difference Jacobian of any right-hand side.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from lagrange_cli.model import Model

STIFF = 500.0
"""decay rate x time span of a real-dominated eigenvalue above which a problem counts as stiff."""
SINGULAR_CONDITION = 1e6
"""condition number of M above which the coordinates count as near-singular."""


@dataclass(frozen=True)
class Spectrum:
    """Rates (1/s) of the linearisation at one state."""

    decay: float
    """max -Re(lambda) over eigenvalues with |Re| > |Im| (0 when none decays)."""
    rate: float
    """max |lambda|, the spectral radius."""
    slowest: float
    """min |lambda| over eigenvalues above 1e-9 of the spectral radius (0 when all are 0)."""

    @property
    def stiffness_ratio(self) -> float:
        """Fastest decay over slowest rate: large means stiff in the dissipative sense."""
        return self.decay / self.slowest if self.slowest > 0 else (math.inf if self.decay > 0 else 1.0)

    @property
    def scale_ratio(self) -> float:
        """Fastest over slowest rate: large means two time scales (oscillatory or not)."""
        return self.rate / self.slowest if self.slowest > 0 else 1.0


def spectrum(jacobian: np.ndarray) -> Spectrum | None:
    """The rates of `jacobian`, or None when it is not finite."""
    if not np.all(np.isfinite(jacobian)):
        return None
    eigenvalues = np.linalg.eigvals(jacobian)
    if not np.all(np.isfinite(eigenvalues)):
        return None
    sizes = np.abs(eigenvalues)
    rate = float(np.max(sizes)) if len(sizes) else 0.0
    decays = [-e.real for e in eigenvalues if -e.real > abs(e.imag)]
    nonzero = sizes[sizes > 1e-9 * rate] if rate > 0 else sizes[:0]
    return Spectrum(max(decays, default=0.0), rate, float(np.min(nonzero)) if len(nonzero) else 0.0)


def jacobian(rhs: Callable[[float, np.ndarray], np.ndarray | None], t: float, y: np.ndarray) -> np.ndarray | None:
    """Forward differences of `rhs` (which returns None where it cannot be evaluated)."""
    f0 = rhs(t, y)
    if f0 is None:
        return None
    columns = []
    for j in range(len(y)):
        h = 1e-7 * max(1.0, abs(y[j]))
        shifted = y.copy()
        shifted[j] += h
        f1 = rhs(t, shifted)
        if f1 is None:
            return None
        columns.append((f1 - f0) / h)
    return np.array(columns).T


def mass_condition(model: Model, p: Sequence[float]) -> Callable[[float, np.ndarray], float]:
    """cond(M(q, t)) at (t, y) with y = [q..., q_dot...]; inf where M is singular or undefined."""
    import sympy as sp

    values = {parameter.symbol: value for parameter, value in zip(model.parameters, p, strict=False)}
    matrix = sp.Matrix(model.mass_matrix).subs(values)
    evaluate = sp.lambdify([model.t, *model.q], matrix.tolist(), modules="math")
    n = model.n

    def condition(t: float, y: np.ndarray) -> float:
        try:
            m = np.array(evaluate(t, *y[:n].tolist()), dtype=float)
        except (ZeroDivisionError, OverflowError, ValueError):
            return math.inf
        if not np.all(np.isfinite(m)):
            return math.inf
        with np.errstate(all="ignore"):
            value = float(np.linalg.cond(m))
        return value if math.isfinite(value) else math.inf

    return condition
