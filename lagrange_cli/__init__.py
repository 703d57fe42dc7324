"""lagrange: equations of motion from a small YAML description of a mechanical system."""

__version__ = "0.1.0"
