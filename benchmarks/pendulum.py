"""The systems the benchmarks use: planar N-link chains of point masses.

Two chains, angles th1..thN from the downward vertical, uniform gravity g:

- the GENERAL chain (the main benchmark system): its own mass m_i and length l_i per link,
  parameters m1..mN, l1..lN, g with distinct values m_i = 1 + 0.1 i, l_i = 0.5 + 0.05 i;
- the EQUAL chain (the second row, and what simulate_bench.py uses): one mass m and one
  length l for every link.

Each chain has its system file (`Chain.yaml`), its parameter values, and an independent
numeric reference for M q_ddot = F written out by hand (`Chain.reference_matrices`). A
3-D chain (the multibody issue) is meant to be one more `Chain` kind here: a new `yaml`
branch and its own reference, with nothing else in run.py to change.

This module imports only the standard library (numpy inside the one function that needs it).
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from math import cos, sin

KINDS = ("general", "equal")
G = 9.81
PARAMETERS = {"m": 1.0, "l": 1.0, "g": G}  # the equal chain's values (simulate_bench.py)


@dataclass(frozen=True)
class Chain:
    """The planar N-link chain: particle k at sum_{i<=k} l_i (sin th_i, -cos th_i)."""

    kind: str
    n: int

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"unknown chain kind {self.kind!r}: expected one of {', '.join(KINDS)}")
        if self.n < 1:
            raise ValueError("a chain needs at least one link")

    @property
    def name(self) -> str:
        return f"{self.kind}_chain_{self.n}"

    def coordinates(self) -> list[str]:
        return coordinates(self.n)

    def mass_names(self) -> list[str]:
        return [f"m{i}" for i in range(1, self.n + 1)] if self.kind == "general" else ["m"] * self.n

    def length_names(self) -> list[str]:
        return [f"l{i}" for i in range(1, self.n + 1)] if self.kind == "general" else ["l"] * self.n

    def parameters(self) -> dict[str, float]:
        """Parameter values, in file order (masses, lengths, g)."""
        if self.kind == "equal":
            return dict(PARAMETERS)
        values = {f"m{i}": round(1.0 + 0.1 * i, 10) for i in range(1, self.n + 1)}
        values.update({f"l{i}": round(0.5 + 0.05 * i, 10) for i in range(1, self.n + 1)})
        values["g"] = G
        return values

    def masses(self, p: dict[str, float] | None = None) -> list[float]:
        p = self.parameters() if p is None else p
        return [p[name] for name in self.mass_names()]

    def lengths(self, p: dict[str, float] | None = None) -> list[float]:
        p = self.parameters() if p is None else p
        return [p[name] for name in self.length_names()]

    def perturbed(self, seed: int = 7) -> dict[str, float]:
        """Other parameter values (each scaled by 0.7..1.3), to check that none is baked in."""
        rng = random.Random(seed + self.n)
        return {k: v * rng.uniform(0.7, 1.3) for k, v in self.parameters().items()}

    def yaml(self) -> str:
        names = self.coordinates()
        ms, ls = self.mass_names(), self.length_names()
        values = ", ".join(f"{k}: {v!r}" for k, v in self.parameters().items())
        title = f"Planar {self.n}-link chain" + (", its own mass and length per link" if self.kind == "general" else ", equal masses and lengths")
        lines = [f"title: {title}", f"coordinates: [{', '.join(names)}]", f"parameters: {{{values}}}", "gravity: [0, -g]", "particles:"]
        for k in range(self.n):
            x = " + ".join(f"{ls[i]}*sin({names[i]})" for i in range(k + 1))
            y = " - ".join(f"{ls[i]}*cos({names[i]})" for i in range(k + 1))
            lines.append(f"  p{k + 1}: {{mass: {ms[k]}, position: [{x}, -{y}]}}")
        return "\n".join(lines) + "\n"

    def reference_matrices(self, y: list[float], p: dict[str, float] | None = None) -> tuple[list[list[float]], list[float]]:
        """M and F of M q_ddot = F written out by hand (0-based i, j; S_k = sum of the masses
        from link k on, the masses hanging below both links i and j):

            M_ij = l_i l_j cos(th_i - th_j) S_max(i,j)
            F_i  = -sum_j l_i l_j sin(th_i - th_j) S_max(i,j) w_j^2 - g l_i sin(th_i) S_i
        """
        p = self.parameters() if p is None else p
        return reference_matrices(y, self.masses(p), self.lengths(p), p["g"])

    def reference_rhs(self, y: list[float], p: dict[str, float] | None = None) -> list[float]:
        import numpy

        mass, force = self.reference_matrices(y, p)
        return [*y[self.n :], *numpy.linalg.solve(mass, force).tolist()]


def reference_matrices(y: list[float], masses: list[float], lengths: list[float], g: float) -> tuple[list[list[float]], list[float]]:
    """The general chain's M and F (see Chain.reference_matrices), O(N^2)."""
    n = len(masses)
    th, w = [float(v) for v in y[:n]], [float(v) for v in y[n : 2 * n]]
    suffix = [0.0] * (n + 1)
    for k in range(n - 1, -1, -1):
        suffix[k] = suffix[k + 1] + masses[k]
    mass = [[lengths[i] * lengths[j] * cos(th[i] - th[j]) * suffix[max(i, j)] for j in range(n)] for i in range(n)]
    force = [-sum(lengths[i] * lengths[j] * sin(th[i] - th[j]) * suffix[max(i, j)] * w[j] ** 2 for j in range(n)) - g * lengths[i] * sin(th[i]) * suffix[i] for i in range(n)]
    return mass, force


def coordinates(n: int) -> list[str]:
    return [f"th{i}" for i in range(1, n + 1)]


def state(n: int, seed: int = 2024) -> list[float]:
    """A reproducible random state y = [angles..., angular velocities...]."""
    rng = random.Random(seed + n)
    return [rng.uniform(-1.5, 1.5) for _ in range(n)] + [rng.uniform(-2.0, 2.0) for _ in range(n)]


# -- the equal chain under its historical names (simulate_bench.py) -----------------------------


def system_yaml(n: int) -> str:
    return Chain("equal", n).yaml()


def reference_rhs(y: list[float], p: dict[str, float] = PARAMETERS) -> list[float]:
    return Chain("equal", len(y) // 2).reference_rhs(y, p)


def hand_rhs(t: float, y: list[float], p: dict[str, float] = PARAMETERS) -> list[float]:
    """The double pendulum written by hand with the `math` module (either chain's parameters):

    (m1 + m2) l1 a1 + m2 l2 c a2 = -m2 l2 s w2^2 - (m1 + m2) g sin th1,
    l1 c a1 + l2 a2 = l1 s w1^2 - g sin th2,
    with s, c = sin, cos(th1 - th2), solved by Cramer's rule.
    """
    if "m1" in p:
        m1, m2, l1, l2 = p["m1"], p["m2"], p["l1"], p["l2"]
    else:
        m1 = m2 = p["m"]
        l1 = l2 = p["l"]
    g = p["g"]
    th1, th2, w1, w2 = y
    d = th1 - th2
    s = sin(d)
    c = cos(d)
    total = m1 + m2
    a11, a12, a21, a22 = total * l1, m2 * l2 * c, l1 * c, l2
    f1 = -m2 * l2 * s * w2 * w2 - total * g * sin(th1)
    f2 = l1 * s * w1 * w1 - g * sin(th2)
    det = a11 * a22 - a12 * a21
    return [w1, w2, (f1 * a22 - a12 * f2) / det, (a11 * f2 - a21 * f1) / det]
