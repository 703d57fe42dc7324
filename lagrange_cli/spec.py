"""The frontend's public entry point: a system file (YAML) in, a validated `SystemSpec` out.

The code lives in lagrange_cli/frontend/ (YAML source positions, node types, section readers);
this module re-exports what users, the CLI and the tests import, so `spec.X` keeps working.
"""

from __future__ import annotations

from lagrange_cli.errors import SpecError
from lagrange_cli.frontend.checks import DRAW_KEYS, EXPECT_KEYS, SYMMETRY_KEYS
from lagrange_cli.frontend.core import FLOW_HINT, NAME
from lagrange_cli.frontend.declarations import FUNCTION_KEYS, MAX_COORDINATES
from lagrange_cli.frontend.files import MAX_FILE_BYTES, bundled_systems, iter_files, load, parse, resolve, shown_name
from lagrange_cli.frontend.mechanics import PARTICLE_KEYS
from lagrange_cli.frontend.nodes import Body, Constraint, Drawing, DrawPoint, Expect, Particle, Symmetry, SystemSpec, time_derivative
from lagrange_cli.frontend.reader import TOP_KEYS
from lagrange_cli.frontend.reader import Reader as _Reader
from lagrange_cli.frontend.runs import DEFAULT_T_END, LIMITS, MAX_STEPS, METHODS, SIMULATE_KEYS
from lagrange_cli.frontend.source import COMMA_AFTER, ESCAPES, IMPLICIT_TAGS, LINE_BREAK, MAX_YAML_DEPTH, MAX_YAML_VALUES, STANDARD_TAGS
from lagrange_cli.frontend.source import kind as _kind
from lagrange_cli.rigid import BODY_KEYS

__all__ = [
    "BODY_KEYS", "COMMA_AFTER", "DEFAULT_T_END", "DRAW_KEYS", "ESCAPES", "EXPECT_KEYS", "FLOW_HINT", "FUNCTION_KEYS",
    "IMPLICIT_TAGS", "LIMITS", "LINE_BREAK", "MAX_COORDINATES", "MAX_FILE_BYTES", "MAX_STEPS", "MAX_YAML_DEPTH",
    "MAX_YAML_VALUES", "METHODS", "NAME", "PARTICLE_KEYS", "SIMULATE_KEYS", "STANDARD_TAGS", "SYMMETRY_KEYS", "TOP_KEYS",
    "Body", "Constraint", "DrawPoint", "Drawing", "Expect", "Particle", "SpecError", "Symmetry", "SystemSpec",
    "_Reader", "_kind", "bundled_systems", "iter_files", "load", "parse", "resolve", "shown_name", "time_derivative",
]  # fmt: skip
