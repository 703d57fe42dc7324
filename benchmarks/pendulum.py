"""The system every benchmark uses: the planar N-link pendulum.

N equal point masses m on massless links of length l, angles th1..thN from the downward
vertical, uniform gravity g. This module has the system file, an independent numeric
reference for its equations of motion, and a hand-written double pendulum; it imports
only the standard library (numpy is imported inside the one function that needs it).
"""

from __future__ import annotations

import random
from math import cos, sin

PARAMETERS = {"m": 1.0, "l": 1.0, "g": 9.81}


def coordinates(n: int) -> list[str]:
    return [f"th{i}" for i in range(1, n + 1)]


def system_yaml(n: int) -> str:
    """The system file: particle k sits at sum_{i<=k} l (sin th_i, -cos th_i)."""
    names = coordinates(n)
    values = ", ".join(f"{k}: {v}" for k, v in PARAMETERS.items())
    lines = [
        f"title: Planar {n}-link pendulum",
        f"coordinates: [{', '.join(names)}]",
        f"parameters: {{{values}}}",
        "gravity: [0, -g]",
        "particles:",
    ]
    for k in range(1, n + 1):
        x = " + ".join(f"l*sin({a})" for a in names[:k])
        y = " - ".join(f"l*cos({a})" for a in names[:k])
        lines.append(f"  p{k}: {{mass: m, position: [{x}, -{y}]}}")
    return "\n".join(lines) + "\n"


def state(n: int, seed: int = 2024) -> list[float]:
    """A reproducible random state y = [angles..., angular velocities...]."""
    rng = random.Random(seed + n)
    return [rng.uniform(-1.5, 1.5) for _ in range(n)] + [rng.uniform(-2.0, 2.0) for _ in range(n)]


def reference_matrices(y: list[float], p: dict[str, float] = PARAMETERS) -> tuple[list[list[float]], list[float]]:
    """M and F of M q_ddot = F written out by hand (0-based i, j; c_ij = N - max(i, j) masses
    hang below both links):

        M_ij = m l^2 c_ij cos(th_i - th_j)
        F_i  = -m l^2 sum_j c_ij sin(th_i - th_j) w_j^2 - m g l (N - i) sin th_i
    """
    n = len(y) // 2
    th, w = y[:n], y[n:]
    m, length, g = p["m"], p["l"], p["g"]
    mass = [[m * length**2 * (n - max(i, j)) * cos(th[i] - th[j]) for j in range(n)] for i in range(n)]
    force = [-m * length**2 * sum((n - max(i, j)) * sin(th[i] - th[j]) * w[j] ** 2 for j in range(n)) - m * g * length * (n - i) * sin(th[i]) for i in range(n)]
    return mass, force


def reference_rhs(y: list[float], p: dict[str, float] = PARAMETERS) -> list[float]:
    import numpy

    n = len(y) // 2
    mass, force = reference_matrices(y, p)
    return [*y[n:], *numpy.linalg.solve(mass, force).tolist()]


def hand_rhs(t: float, y: list[float], p: dict[str, float] = PARAMETERS) -> list[float]:
    """The double pendulum (equal masses and lengths) written by hand with the `math` module:

    2 a1 + c a2 = -s w2^2 - 2 (g/l) sin th1,   c a1 + a2 = s w1^2 - (g/l) sin th2,
    with s, c = sin, cos(th1 - th2), solved by Cramer's rule (det = 2 - c^2).
    """
    k = p["g"] / p["l"]
    th1, th2, w1, w2 = y
    d = th1 - th2
    s = sin(d)
    c = cos(d)
    f1 = -s * w2 * w2 - 2.0 * k * sin(th1)
    f2 = s * w1 * w1 - k * sin(th2)
    det = 2.0 - c * c
    return [w1, w2, (f1 - c * f2) / det, (2.0 * f2 - c * f1) / det]
