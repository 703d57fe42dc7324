"""lagrange: equations of motion from a small YAML description of a mechanical system.

The Python API (docs/api.md) is imported on first use, so that `import lagrange_cli` (and the
command line's `--help`) loads no sympy, numpy or matplotlib:

    from lagrange_cli import load
    system = load("double_pendulum")
"""

from __future__ import annotations

from typing import Any

__version__ = "0.1.0"

API = ("load", "from_file", "from_text", "targets", "System", "Trajectory", "Equations", "Formula", "Formulas", "Report", "CheckReport", "Plot", "Animation")
"""The names `lagrange_cli` gives from `lagrange_cli.api`."""

__all__ = [*API, "__version__"]


def __getattr__(name: str) -> Any:
    if name in API:
        from lagrange_cli import api

        return getattr(api, name)
    raise AttributeError(f"module 'lagrange_cli' has no attribute '{name}'")


def __dir__() -> list[str]:
    return sorted({*globals(), *API})
