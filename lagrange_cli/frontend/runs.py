"""The sections about runs: `initial`, `simulate` (each setting within its documented range) and `exact`."""

from __future__ import annotations

import sys
from typing import Any

import sympy as sp
import yaml

from lagrange_cli.expr import Scope, _closest
from lagrange_cli.frontend.core import ReaderCore

SIMULATE_KEYS = ("t_end", "method", "rtol", "atol", "step", "samples")
METHODS = ("auto", "RK45", "DOP853", "Radau", "BDF", "LSODA", "symplectic")  # as in numeric/settings.py
DEFAULT_T_END = 10.0  # numeric/settings.py's default
MAX_STEPS = 10**8
LIMITS = {
    "t_end": (1e-9, 1e9, "the end time of a run, in the system's units"),
    "step": (1e-12, 1e9, "the fixed step of the symplectic method"),
    "rtol": (100 * sys.float_info.epsilon, 1.0, "the relative tolerance (below 100 machine epsilons double precision cannot deliver it)"),
    "atol": (1e-300, 1e300, "the absolute tolerance"),
    "samples": (2, 10**6, "the number of sample times in the output"),
}
"""Allowed ranges of the `simulate` settings (inclusive), each with what it means; see docs/format.md."""


class Runs(ReaderCore):
    """`initial`, `simulate` and `exact`."""

    def initial(self, node: yaml.Node | None, coordinates: tuple[str, ...]) -> dict[str, float]:
        if node is None:
            return {}
        allowed = [*coordinates, *(f"{c}_dot" for c in coordinates)]
        result = {}
        for key, key_node, value in self.mapping(node, "'initial'"):
            if key not in allowed:
                hint = _closest(key, allowed)
                self.problem(key_node, f"'{key}' is not a coordinate or velocity", "one of " + ", ".join(allowed) + (f"; did you mean '{hint}'?" if hint else ""))
                continue
            number = self.number(value, f"the initial value of '{key}'")
            if number is not None:
                result[key] = number
        return result

    def simulate(self, node: yaml.Node | None) -> dict[str, Any]:
        """The `simulate` block, each value checked against its documented range (`LIMITS`), and
        the number of fixed steps `t_end / step` against `MAX_STEPS`, so that no file can ask for
        a run that never ends."""
        if node is None:
            return {}
        result: dict[str, Any] = {}
        nodes: dict[str, yaml.Node] = {}
        for key, _, value in self.mapping(node, "'simulate'", SIMULATE_KEYS):
            nodes[key] = value
            if key == "method":
                method = self.string(value, "'simulate.method'")
                known = next((m for m in METHODS if method is not None and m.lower() == method.lower()), None)
                if method is not None and known is None:
                    hint = _closest(method, list(METHODS))
                    self.problem(value, f"unknown method '{method}' in 'simulate.method'", "one of " + ", ".join(METHODS) + (f" (did you mean '{hint}'?)" if hint else ""))
                elif known is not None:
                    result[key] = known
                continue
            number = self.number(value, f"'simulate.{key}'")
            if number is None:
                continue
            low, high, meaning = LIMITS[key]
            if key == "samples" and number != int(number):
                self.problem(value, f"'simulate.samples' must be a whole number, got {number:g}", f"a whole number from {low:g} to {high:g}: {meaning}")
            elif not low <= number <= high:
                self.problem(value, f"'simulate.{key}' is {number:g}, outside the allowed range", f"a number from {low:g} to {high:g}: {meaning}")
            else:
                result[key] = int(number) if key == "samples" else number
        if "step" in result:
            t_end = result.get("t_end", DEFAULT_T_END)
            if t_end / result["step"] > MAX_STEPS:
                self.problem(
                    nodes["step"],
                    f"'simulate.step' {result['step']:g} would take {t_end / result['step']:.3g} steps to reach t_end = {t_end:g}",
                    f"at most {MAX_STEPS:.0e} steps: a step of at least {t_end / MAX_STEPS:.3g}, or a shorter t_end",
                )
        return result

    def exact(self, node: yaml.Node | None, coordinates: tuple[str, ...], constants: Scope) -> dict[str, sp.Expr]:
        if node is None:
            return {}
        result = {}
        for key, key_node, value in self.mapping(node, "'exact'"):
            if key not in coordinates:
                self.problem(key_node, f"'{key}' is not a coordinate", "one of " + ", ".join(coordinates))
                continue
            expr = self.expression(value, f"the exact solution for '{key}'", constants)
            self.sources[f"exact.{key}"] = self.where(value)
            if expr is not None:
                result[key] = expr
        return result
