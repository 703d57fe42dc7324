"""`info`, `equilibria` and `linearize`: what the equations say about momenta, conserved
quantities, equilibrium points and small oscillations."""

from __future__ import annotations

import typer  # noqa: F401

from lagrange_cli.cli import app  # noqa: F401
