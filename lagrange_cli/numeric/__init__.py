"""Numerics: compiled right-hand sides, integrators, invariants, output and plots.

Only the `simulate` command and notebooks import this package; it needs numpy and scipy
(and numba for the compiled path), which `lagrange derive` never loads.
"""

from __future__ import annotations

from lagrange_cli.numeric.simulate import Invariant, InvariantKind, Timing, Trajectory, simulate

__all__ = ["Invariant", "InvariantKind", "Timing", "Trajectory", "simulate"]
