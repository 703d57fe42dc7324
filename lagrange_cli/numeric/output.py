"""A trajectory as CSV text, an .npz archive, or a figure; files are written atomically.

CSV: a header `t,<q>...,<q>_dot...,energy`, then one row per sample with every digit kept
(`repr` of each float), so reading it back gives the same numbers. The .npz archive holds the
same arrays plus the settings and the report. The figure has the coordinates against time, a
phase portrait, and the relative energy error.
"""

from __future__ import annotations

import contextlib
import importlib.util
import re
import unicodedata
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from lagrange_cli.errors import LagrangeError
from lagrange_cli.files import atomic_write
from lagrange_cli.numeric.simulate import Trajectory

DATA_SUFFIXES = (".csv", ".npz")
PLOT_SUFFIXES = (".png", ".svg", ".pdf")


def csv_text(trajectory: Trajectory) -> str:
    """The samples as CSV: t, coordinates, velocities, energy."""
    header = ",".join(["t", *trajectory.names, "energy"])
    rows = np.column_stack([trajectory.t, trajectory.y, trajectory.energy]) if len(trajectory.t) else np.empty((0, len(trajectory.names) + 2))
    return header + "\n" + "".join(",".join(repr(float(v)) for v in row) + "\n" for row in rows)


def write_npz(trajectory: Trajectory, path: Path) -> None:
    """The arrays and the report in a compressed .npz archive."""
    s = trajectory.settings
    arrays: dict[str, Any] = {
        "t": trajectory.t,
        "y": trajectory.y,
        "energy": trajectory.energy,
        "names": np.array(trajectory.names),
        "parameters": np.array([name for name, _ in s.parameters]),
        "parameter_values": np.array([value for _, value in s.parameters], dtype=float),
        "y0": np.array(s.y0),
        "method": np.array(s.method),
        "backend": np.array(s.backend),
        "status": np.array(trajectory.status),
        "message": np.array(trajectory.message),
        "t_last": np.array(trajectory.t_last),
        "y_last": trajectory.y_last,
    }
    atomic_write(path, lambda stream: np.savez_compressed(stream, **arrays))


@contextlib.contextmanager
def plain_text() -> Iterator[None]:
    """Inside (or in a function decorated with `@plain_text()`): no text goes to LaTeX (whatever
    the user's `text.usetex`), and a character the font lacks is drawn as a box without a
    warning. File text itself goes in as `plot_text(...)` on a Text with `parse_math=False`
    (see `inert`), so that `$` and `\\` are shown, not parsed as mathtext."""
    import matplotlib

    with matplotlib.rc_context({"text.usetex": False}), warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"Glyph \d+ .*missing from", category=UserWarning)
        yield


def inert(*texts: Any) -> None:
    """Show these matplotlib Texts as written: no mathtext (matplotlib's own tick labels keep it)."""
    for text in texts:
        text.set_parse_math(False)


def plot_text(text: str) -> str:
    """File text for a figure: whitespace runs (newlines, U+2028, ...) one space, and control,
    format and unassigned characters dropped."""
    return "".join(char for char in re.sub(r"\s+", " ", text) if unicodedata.category(char)[0] != "C").strip()


@plain_text()
def write_plot(trajectory: Trajectory, path: Path) -> None:
    """Coordinates against time, a phase portrait, and the relative energy error, in one figure."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    figure = Figure(figsize=(12, 4), layout="constrained")
    left, middle, right = figure.subplots(1, 3)
    n = len(trajectory.coordinates)
    for i, name in enumerate(trajectory.coordinates):
        left.plot(trajectory.t, trajectory.y[:, i], label=plot_text(name))
        middle.plot(trajectory.y[:, i], trajectory.y[:, n + i], label=plot_text(name))
    left.set(xlabel="t", title="coordinates")
    middle.set(xlabel="q", ylabel="q_dot", title="phase portrait")
    for axes in (left, middle):
        inert(*axes.legend(loc="best", fontsize="small").get_texts())
    _energy_panel(right, trajectory)
    figure.suptitle(f"{plot_text(trajectory.title)} ({trajectory.settings.method}, {trajectory.status})", parse_math=False)
    suffix = path.suffix.lower().lstrip(".")
    atomic_write(path, lambda stream: figure.savefig(stream, format=suffix, dpi=120))


def _energy_panel(axes: Any, trajectory: Trajectory) -> None:
    energy = trajectory.energy
    if len(energy) == 0:
        return
    invariant = next((i for i in trajectory.invariants if i.name == "energy"), None)
    scale = (invariant.scale if invariant is not None else 0.0) or abs(energy[0]) or max(float(np.max(np.abs(energy))), 1e-300)
    error = np.abs(energy - energy[0]) / scale
    conserved = invariant.conserved if invariant is not None else False
    if np.any(error[1:] > 0):
        axes.semilogy(trajectory.t[1:], np.maximum(error[1:], 1e-17))
    else:
        axes.plot(trajectory.t, error)
    axes.set(xlabel="t", title="relative energy error" + ("" if conserved else " (energy not conserved)"))


def check_suffix(path: Path, allowed: tuple[str, ...], what: str) -> None:
    """A LagrangeError unless `path` ends in one of `allowed`."""
    if path.suffix.lower() not in allowed:
        raise LagrangeError(f"{path}: cannot tell the {what} format from the name; use one of {', '.join(allowed)}")


def check_plot(path: Path) -> None:
    """A LagrangeError, before any work, unless a figure can be written to `path`: a known
    suffix, and matplotlib (optional: the `plot` extra) installed."""
    check_suffix(path, PLOT_SUFFIXES, "plot")
    if importlib.util.find_spec("matplotlib") is None:
        raise LagrangeError("--plot needs matplotlib, which is not installed: `pip install 'lagrange-cli[plot]'`")
