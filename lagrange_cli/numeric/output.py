"""A trajectory as CSV text, an .npz archive, or a figure; files are written atomically.

CSV: a header `t,<q>...,<q>_dot...,energy`, then one row per sample with every digit kept
(`repr` of each float), so reading it back gives the same numbers. The .npz archive holds the
same arrays plus the settings and the report. The figure (`simulation_figure`) has the
coordinates against time, grouped by what they measure (angles in radians, positions in the
file's units), the energy (its relative error when it is conserved, else h(t) itself: damping or
driving change it physically), the drift of kept constraints, and the phase portraits of the
first few coordinates, every axis labelled with its unit.
"""

from __future__ import annotations

import contextlib
import importlib.util
import re
import unicodedata
import warnings
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from lagrange_cli.errors import LagrangeError
from lagrange_cli.files import atomic_write
from lagrange_cli.model import Model
from lagrange_cli.numeric.simulate import InvariantKind, Trajectory

if TYPE_CHECKING:
    from matplotlib.figure import Figure

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


def fit_lines(text: str, width: float, fontsize: Any) -> str:
    """`text` broken at spaces into lines at most `width` points wide in `fontsize` (a word wider
    than a line is broken where it must be), measured as plain text: matplotlib's own `wrap=True`
    measures `$...$` as mathtext, whatever the Text's `parse_math`."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import text_to_path

    prop = FontProperties(size=fontsize)

    def fits(line: str) -> bool:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=r"Glyph \d+ .*missing from", category=UserWarning)
            return bool(text_to_path.get_text_width_height_descent(line, prop, ismath=False)[0] <= width)

    lines: list[str] = []
    current = ""
    for word in text.split(" "):
        if fits(f"{current} {word}" if current else word):
            current = f"{current} {word}" if current else word
            continue
        if current:
            lines.append(current)
        current = word
        while len(current) > 1 and not fits(current):
            low, high = 1, len(current) - 1  # the longest head that fits (at least one character)
            while low < high:
                middle = (low + high + 1) // 2
                low, high = (middle, high) if fits(current[:middle]) else (low, middle - 1)
            lines.append(current[:low])
            current = current[low:]
    lines.append(current)
    return "\n".join(lines)


def figure_title(figure: Any, text: str) -> None:
    """`text` (file text, plain) as the figure's title, in lines that fit its width."""
    import matplotlib

    size = matplotlib.rcParams["figure.titlesize"]
    figure.suptitle(fit_lines(text, 0.96 * figure.get_figwidth() * 72, size), parse_math=False, fontsize=size)


def plot_text(text: str) -> str:
    """File text for a figure: whitespace runs (newlines, U+2028, ...) one space, and control,
    format and unassigned characters dropped."""
    return "".join(char for char in re.sub(r"\s+", " ", text) if unicodedata.category(char)[0] != "C").strip()


# --- the figure of a simulation ---------------------------------------------------------------

PHASE_PANELS = 3
"""Phase portraits drawn (of the first coordinates): one small panel each, never all in one."""
LINES_PER_PANEL = 6
"""Coordinates of one kind drawn against time in one panel; more go to further panels."""
ANGLE_UNITS = frozenset({"rad", "radian", "radians"})
LENGTH_UNITS = frozenset({"m", "cm", "mm", "km", "um", "nm", "ft", "in", "inch", "mi", "au", "AU", "pc", "ly"})
ANGLE_NAME = re.compile(r"(theta|vartheta|phi|varphi|psi|alpha|beta|gamma|chi|th|ph|angle|yaw|pitch|roll)(\d+|_\w+)?", re.IGNORECASE)
"""Names that are angles by convention (`theta`, `phi2`, `psi_b`, `th1`)."""
FLOOR = 1e-17
"""Drawn in place of 0 on a logarithmic axis."""


@dataclass(frozen=True)
class Quantity:
    """What a coordinate measures, for the axis labels: an angle (in radians), a position, or
    another quantity, with the unit its file declares (None when the file declares no units)."""

    kind: str
    """"angle", "position" or "other" (a declared unit that is neither)."""
    unit: str | None = None

    @property
    def axis(self) -> str:
        """The label of an axis of such coordinates: `angle [rad]`, `position [m]`, `position (file units)`."""
        if self.kind == "angle":
            return "angle [rad]"
        if self.unit is None:
            return "position (file units)"
        return f"{self.kind if self.kind == 'position' else 'coordinate'} [{self.unit}]"

    def value(self, name: str) -> str:
        """The label of an axis of coordinate `name`: `theta [rad]`, `x (file units)`."""
        if self.kind == "angle":
            return f"{name} [rad]"
        return f"{name} [{self.unit}]" if self.unit is not None else f"{name} (file units)"

    def rate(self, name: str, seconds: bool) -> str:
        """The label of an axis of its velocity; `seconds`: time is in seconds (the file declares units)."""
        if self.kind == "angle":
            return f"{name}_dot [rad/s]" if seconds else f"{name}_dot (rad per time unit)"
        if self.unit is None or not seconds:
            return f"{name}_dot (file units)"
        return f"{name}_dot [{self.unit}/s]" if self.unit.isalnum() else f"{name}_dot [({self.unit})/s]"


def declared_units(model: Model | None) -> dict[str, str]:
    """The file's `units` (name -> unit text), empty when it declares none (or the model does not carry them)."""
    units = getattr(model, "units", None)
    return {str(name): plot_text(str(unit)) for name, unit in units.items()} if isinstance(units, Mapping) else {}


def quantities(model: Model | None, coordinates: Sequence[str]) -> tuple[Quantity, ...]:
    """What each coordinate measures, by the first rule that decides:

    1. the unit the file declares for it (`rad` is an angle);
    2. an angle when it enters the argument of a trigonometric function with a numerical
       coefficient, as in `sin(theta)`, `cos(theta1 - theta2)` or `sin(alpha + 2*phi)`, anywhere
       in the Lagrangian, dissipation, forces or constraints: that argument is dimensionless, so
       the coordinate is too (`cos(k*x)` says nothing about x);
    3. an angle when its name is one by convention (`ANGLE_NAME`: `theta`, `phi2`, `psi_b`), for
       the angles the equations do not settle: an ignorable one such as a top's precession, a
       torsion angle under `kappa*theta**2/2`;
    4. otherwise a position.

    Without the model (or one for other coordinates), only rules 3 and 4.
    """
    import sympy as sp
    from sympy.functions.elementary.trigonometric import TrigonometricFunction

    if model is not None and tuple(model.coordinates) != tuple(coordinates):
        model = None
    units = declared_units(model)
    symbols: dict[str, Any] = {}
    arguments: set[Any] = set()
    if model is not None:
        plain = model.with_definitions()
        symbols = dict(zip(model.coordinates, model.q, strict=True))
        for expr in (plain.lagrangian, plain.dissipation, *plain.generalized_forces, *(c.expr for c in plain.constraints)):
            arguments.update(f.args[0] for f in sp.sympify(expr).atoms(TrigonometricFunction))

    def kind(name: str) -> Quantity:
        unit = units.get(name)
        if unit is not None:
            return Quantity("angle" if unit in ANGLE_UNITS else "position" if unit in LENGTH_UNITS else "other", unit)
        q = symbols.get(name)
        if q is not None and any(_numeric_coefficient(argument, q) for argument in arguments):
            return Quantity("angle")
        return Quantity("angle" if ANGLE_NAME.fullmatch(name) else "position")

    return tuple(kind(name) for name in coordinates)


def _numeric_coefficient(argument: Any, q: Any) -> bool:
    """True when `argument` is linear in `q` with a nonzero numerical coefficient."""
    if not argument.has(q):
        return False
    slope = argument.diff(q)
    return bool(slope.is_number and slope != 0)


def time_label(model: Model | None) -> str:
    """`t [s]` when the file declares units (time is then in seconds), else `t (file units)`."""
    return "t [s]" if declared_units(model) else "t (file units)"


def energy_change(model: Model | None) -> str:
    """Why the energy h = sum p q_dot - L of a non-conservative system changes: a physical cause, not an error."""
    if model is None:
        return "not conserved by these equations"
    time_dependent = model.lagrangian.has(model.t) or any(c.bias != 0 or c.expr.has(model.t) for c in model.constraints)
    causes = [cause for present, cause in ((model.dissipative, "damping"), (model.forced, "applied forces"), (time_dependent, "time-dependent terms")) if present]
    return ", ".join(causes) or "not conserved by these equations"


@plain_text()
def simulation_figure(trajectory: Trajectory, model: Model | None = None) -> Figure:
    """The figure of a run: on the left, the coordinates against time (one panel per kind of
    quantity, with its unit), the energy (its relative error when it is conserved, else h(t)
    itself, whose change is physics) and, with kept constraints, their drift; on the right the
    phase portraits of the first PHASE_PANELS coordinates, one panel each.

    `model` (the one the trajectory was computed from) tells angles from positions, the file's
    units, why the energy changes, and the constraints; without it, names decide and those panels
    say less. File text is shown as written (no mathtext, no LaTeX)."""
    from matplotlib.figure import Figure

    if model is not None and tuple(model.coordinates) != tuple(trajectory.coordinates):
        model = None
    names, n = trajectory.coordinates, len(trajectory.coordinates)
    kinds = quantities(model, names)
    groups = _groups(kinds)
    drift = model is not None and bool(model.constraints) and len(trajectory.t) > 0
    shown = min(n, PHASE_PANELS)
    rows = max(len(groups) + 1 + drift, shown)
    figure = Figure(figsize=(11.0, 1.4 + 2.1 * rows), layout="constrained")
    left, right = figure.subfigures(1, 2, width_ratios=(2.1, 1.0)).tolist()  # type: ignore[union-attr]
    panels = left.subplots(len(groups) + 1 + drift, 1, sharex=True, squeeze=False)[:, 0]
    t, y = trajectory.t, trajectory.y
    for axes, (label, indices) in zip(panels, groups, strict=False):
        for i in indices:
            axes.plot(t, y[:, i], label=plot_text(names[i]))
        axes.set_ylabel(label, parse_math=False)
        _legend(axes)
    _energy_panel(panels[len(groups)], trajectory, model)
    if drift:
        assert model is not None
        _drift_panel(panels[-1], trajectory, model)
    panels[-1].set_xlabel(time_label(model), parse_math=False)
    left.suptitle("motion against time", fontsize="medium")
    seconds = bool(declared_units(model))
    for i, axes in enumerate(right.subplots(shown, 1, squeeze=False)[:, 0]):
        axes.plot(y[:, i], y[:, n + i], linewidth=1.0)
        if len(t):
            axes.plot(y[:1, i], y[:1, n + i], "o", color="black", markersize=4)
        axes.set_xlabel(kinds[i].value(plot_text(names[i])), parse_math=False)
        axes.set_ylabel(kinds[i].rate(plot_text(names[i]), seconds), parse_math=False)
    right.suptitle("phase portraits (dot: start)" if shown == n else f"phase portraits: first {shown} of {n} (dot: start)", fontsize="medium")
    s = trajectory.settings
    figure_title(figure, f"{plot_text(trajectory.title)} ({s.method}, {s.backend}; {trajectory.status})")
    return figure


@plain_text()
def write_plot(trajectory: Trajectory, path: Path, model: Model | None = None) -> None:
    """`simulation_figure` of the run, written atomically (.png, .svg or .pdf)."""
    import matplotlib

    matplotlib.use("Agg")
    figure = simulation_figure(trajectory, model)
    suffix = path.suffix.lower().lstrip(".")
    atomic_write(path, lambda stream: figure.savefig(stream, format=suffix, dpi=120))


def _groups(kinds: Sequence[Quantity]) -> list[tuple[str, list[int]]]:
    """The coordinates drawn in each panel against time: the same axis label, at most LINES_PER_PANEL."""
    by_axis: dict[str, list[int]] = {}
    for i, quantity in enumerate(kinds):
        by_axis.setdefault(quantity.axis, []).append(i)
    return [(axis, indices[k : k + LINES_PER_PANEL]) for axis, indices in by_axis.items() for k in range(0, len(indices), LINES_PER_PANEL)]


def _legend(axes: Any) -> None:
    """A legend beside the panel, outside its data area, with file text shown as written."""
    legend = axes.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize="small")
    inert(*legend.get_texts())


def _energy_panel(axes: Any, trajectory: Trajectory, model: Model | None) -> None:
    """Conserved energy: its relative change, which is numerical error. Otherwise h(t) itself:
    damping, applied forces or time-dependent terms change it physically."""
    energy, t = trajectory.energy, trajectory.t
    invariant = trajectory.invariant(InvariantKind.ENERGY)
    conserved = model.energy_conserved if model is not None else invariant is not None and invariant.conserved
    if not conserved:
        axes.plot(t, energy, color="tab:red")
        axes.set_ylabel("energy h (file units)", parse_math=False)
        axes.set_title(f"energy h(t): changes physically ({energy_change(model)})", fontsize="medium")
        return
    if len(energy):
        scale = (invariant.scale if invariant is not None else 0.0) or abs(energy[0]) or max(float(np.max(np.abs(energy))), 1e-300)
        error = np.abs(energy - energy[0]) / scale
        if np.any(error[1:] > 0):
            axes.semilogy(t[1:], np.maximum(error[1:], FLOOR), color="tab:red")
        else:
            axes.plot(t, error, color="tab:red")
    axes.set_ylabel("relative energy error", parse_math=False)
    axes.set_title("energy: conserved, so any change is numerical error", fontsize="medium")


def _drift_panel(axes: Any, trajectory: Trajectory, model: Model) -> None:
    """|residual| of each kept constraint along the samples: how far the run left them."""
    from lagrange_cli.numeric import compile

    module: Any = compile.build(model, "python").module
    p = list(trajectory.settings.p)
    residuals = np.abs(np.array([module._residuals(t, y.tolist(), p) for t, y in zip(trajectory.t, trajectory.y, strict=True)], dtype=float))
    for k, constraint in enumerate(model.constraints):
        axes.semilogy(trajectory.t, np.maximum(residuals[:, k], FLOOR), label=plot_text(constraint.name))
    axes.set_ylabel("|constraint residual| (file units)", parse_math=False)
    axes.set_title("constraint drift (kept constraints)", fontsize="medium")
    _legend(axes)


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
