"""Plots a person understands: every figure is rendered (Agg) and read back through matplotlib's
API: axis labels with units, angles apart from lengths, a few phase portraits however many
coordinates, legends beside the data, nothing clipped, physical energy change not called
"error", the constraint drift, and compiled and pure-Python runs told apart."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from lagrange_cli import spec
from lagrange_cli.model import Model
from lagrange_cli.numeric.simulate import Trajectory, simulate
from tests.helpers import model_from, model_of

pytest.importorskip("matplotlib")
pytestmark = pytest.mark.usefixtures("private_cache")

CHAIN = 6


def chain_text(n: int) -> str:
    """An n-link planar chain of point masses (coordinates th1..thn)."""
    lines = [f"title: {n}-link chain", f"coordinates: [{', '.join(f'th{i}' for i in range(1, n + 1))}]", "parameters: {m: 1.0, l: 1.0, g: 9.81}", "gravity: [0, -g]", "particles:"]
    for i in range(1, n + 1):
        x = " + ".join(f"l*sin(th{j})" for j in range(1, i + 1))
        y = " - ".join(f"l*cos(th{j})" for j in range(1, i + 1))
        lines.append(f"  b{i}: {{mass: m, position: [{x}, -{y}]}}")
    lines.append("initial: {" + ", ".join(f"th{i}: {0.1 * (n + 1 - i):.1f}" for i in range(1, n + 1)) + "}")
    return "\n".join(lines) + "\n"


def bundled(name: str) -> Model:
    return model_from(spec.resolve(name))


def run(model: Model, t_end: float = 1.0) -> Trajectory:
    return simulate(model, backend="python", t_end=t_end, samples=101)


def figure_of(model: Model, tmp_path: Path, name: str, t_end: float = 1.0) -> Any:
    """The simulation figure of a short run, drawn, and saved as `name`.png for a person to look at."""
    from lagrange_cli.numeric.output import plain_text, simulation_figure

    with plain_text():
        return drawn(simulation_figure(run(model, t_end), model), tmp_path / f"{name}.png")


def drawn(figure: Any, path: Path) -> Any:
    """The figure on an Agg canvas, saved to `path` for a person to look at; its layout is then
    done, and the canvas's renderer measures what was drawn."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(figure)
    figure.savefig(path)
    return figure


def texts(figure: Any) -> list[str]:
    from matplotlib.text import Text

    return [t.get_text() for t in figure.findobj(Text) if t.get_visible() and t.get_text()]


def time_panels(figure: Any) -> list[Any]:
    """The panels against time (left column), top to bottom."""
    return list(figure.subfigs[0].axes)


def phase_panels(figure: Any) -> list[Any]:
    return list(figure.subfigs[1].axes)


def legend_entries(axes: Any) -> list[str]:
    legend = axes.get_legend()
    return [t.get_text() for t in legend.get_texts()] if legend is not None else []


def overlaps(a: Any, b: Any, slack: float = 1.0) -> bool:
    """True when the two boxes share more than `slack` pixels both ways."""
    return min(a.x1, b.x1) - max(a.x0, b.x0) > slack and min(a.y1, b.y1) - max(a.y0, b.y0) > slack


def inside(box: Any, outer: Any, slack: float = 1.0) -> bool:
    return box.x0 >= outer.x0 - slack and box.y0 >= outer.y0 - slack and box.x1 <= outer.x1 + slack and box.y1 <= outer.y1 + slack


def assert_readable(figure: Any) -> None:
    """Every panel has both axis labels (shared time axes: the bottom one), no legend covers any
    panel's data area, and no text (title included) reaches past the figure's edge."""
    renderer = figure.canvas.get_renderer()
    frame = figure.bbox
    axes_list = figure.axes
    for axes in axes_list:
        assert axes.get_ylabel().strip(), f"a panel without a y-label: {axes.get_title()!r}"
        shared = [other for other in axes.get_shared_x_axes().get_siblings(axes) if other is not axes]
        if not shared or axes is min([axes, *shared], key=lambda a: a.get_position().y0):
            assert axes.get_xlabel().strip(), f"a panel without an x-label: {axes.get_ylabel()!r}"
    legends = [a.get_legend() for a in axes_list if a.get_legend() is not None] + list(figure.legends)
    for legend in legends:
        box = legend.get_window_extent(renderer)
        assert inside(box, frame), "a legend is cut off"
        for axes in axes_list:
            assert not overlaps(box, axes.get_window_extent(renderer)), f"a legend covers the panel {axes.get_ylabel()!r}"
    for axes in axes_list:  # with its tick labels, axis labels, title and legend
        assert inside(axes.get_tightbbox(renderer), frame), f"the panel {axes.get_ylabel()!r} is cut off"
    titles = [f._suptitle for f in (figure, *figure.subfigs) if f._suptitle is not None]
    assert figure._suptitle in titles
    for title in titles:
        assert inside(title.get_window_extent(renderer), frame), f"clipped title: {title.get_text()!r}"
        assert not any(overlaps(title.get_window_extent(renderer), a.get_tightbbox(renderer)) for a in axes_list), f"title over a panel: {title.get_text()!r}"
        assert not any(overlaps(title.get_window_extent(renderer), legend.get_window_extent(renderer)) for legend in legends), f"title over a legend: {title.get_text()!r}"


# --- which coordinates are angles ---------------------------------------------------------------


def kinds(model: Model) -> list[str]:
    from lagrange_cli.numeric.output import quantities

    return [q.kind for q in quantities(model, model.coordinates)]


def test_angles_from_trigonometric_arguments_and_names() -> None:
    assert kinds(bundled("simple_pendulum")) == ["angle"]
    assert kinds(bundled("elastic_pendulum")) == ["position", "angle"]  # x in (l + x)*sin(theta)
    assert kinds(bundled("pendulum_multiplier")) == ["position", "position"]
    assert kinds(bundled("heavy_top")) == ["angle", "angle", "angle"]  # phi and psi are ignorable: their names decide
    assert kinds(bundled("central_potential")) == ["position", "angle"]
    periodic = "coordinates: [q, x, theta]\nparameters: {m: 1.0, a: 2.0, kappa: 1.0}\nkinetic: m*(q_dot**2 + x_dot**2 + theta_dot**2)/2\npotential: cos(q) + cos(2*pi*x/a) + kappa*theta**2/2\n"
    # q enters cos with a numerical coefficient (whatever its name); x only as 2*pi*x/a (a wave
    # number: x is a length); theta only as theta**2, and by its name
    assert kinds(model_of(periodic)) == ["angle", "position", "angle"]


def test_without_the_model_names_decide() -> None:
    from lagrange_cli.numeric.output import quantities

    assert [q.kind for q in quantities(None, ("q", "theta2", "phi_b", "th1", "x", "rho", "thrust"))] == ["position", "angle", "angle", "angle", "position", "position", "position"]


@dataclasses.dataclass(frozen=True)
class UnitModel(Model):
    """A model whose file declares `units` (FORMAT.md v2)."""

    units: Mapping[str, str] = dataclasses.field(default_factory=dict)


def test_declared_units_label_the_axes(tmp_path: Path) -> None:
    plain = bundled("elastic_pendulum")
    model = UnitModel(**{f.name: getattr(plain, f.name) for f in dataclasses.fields(Model)}, units={"x": "m", "theta": "rad", "m": "kg", "k": "N/m", "l": "m", "g": "m/s**2"})
    figure = figure_of(model, tmp_path, "units")
    assert [a.get_ylabel() for a in time_panels(figure)][:2] == ["position [m]", "angle [rad]"]
    assert time_panels(figure)[-1].get_xlabel() == "t [s]"
    assert [(a.get_xlabel(), a.get_ylabel()) for a in phase_panels(figure)] == [("x [m]", "x_dot [m/s]"), ("theta [rad]", "theta_dot [rad/s]")]
    assert_readable(figure)


# --- simulate --plot ------------------------------------------------------------------------


def test_pendulum_has_one_angle_panel_and_a_relative_energy_error(tmp_path: Path) -> None:
    figure = figure_of(bundled("simple_pendulum"), tmp_path, "pendulum")
    left = time_panels(figure)
    assert [a.get_ylabel() for a in left] == ["angle [rad]", "relative energy error"]
    assert legend_entries(left[0]) == ["theta"]
    assert left[-1].get_xlabel() == "t (file units)" and left[-1].get_yscale() == "log"
    assert "numerical error" in left[-1].get_title()
    assert [(a.get_xlabel(), a.get_ylabel()) for a in phase_panels(figure)] == [("theta [rad]", "theta_dot (rad per time unit)")]
    assert figure.get_suptitle() == "Simple pendulum (DOP853, python; finished)"
    assert_readable(figure)


def test_a_length_and_an_angle_get_two_axes(tmp_path: Path) -> None:
    figure = figure_of(bundled("elastic_pendulum"), tmp_path, "elastic")
    left = time_panels(figure)
    assert [a.get_ylabel() for a in left] == ["position (file units)", "angle [rad]", "relative energy error"]
    assert [legend_entries(a) for a in left[:2]] == [["x"], ["theta"]]
    x, theta = (a.get_lines()[0].get_ydata() for a in left[:2])
    assert np.isclose(x[0], 0.3) and np.isclose(theta[0], 0.6)  # each curve in its panel
    assert [(a.get_xlabel(), a.get_ylabel()) for a in phase_panels(figure)] == [("x (file units)", "x_dot (file units)"), ("theta [rad]", "theta_dot (rad per time unit)")]
    assert_readable(figure)


def test_a_six_link_chain_gets_a_few_phase_portraits_not_spaghetti(tmp_path: Path) -> None:
    from lagrange_cli.numeric.output import PHASE_PANELS

    figure = figure_of(model_of(chain_text(CHAIN)), tmp_path, "chain", t_end=0.5)
    phases = phase_panels(figure)
    assert len(phases) == PHASE_PANELS < CHAIN
    assert all(len(a.get_lines()) <= 2 for a in phases)  # the orbit and its starting dot
    assert [a.get_xlabel() for a in phases] == [f"th{i} [rad]" for i in range(1, PHASE_PANELS + 1)]
    assert figure.subfigs[1].get_suptitle() == f"phase portraits: first {PHASE_PANELS} of {CHAIN} (dot: start)"
    left = time_panels(figure)
    assert [a.get_ylabel() for a in left] == ["angle [rad]", "relative energy error"]
    assert legend_entries(left[0]) == [f"th{i}" for i in range(1, CHAIN + 1)]
    width, height = figure.get_size_inches()
    assert height <= 8.5 and width <= 12
    assert_readable(figure)


def test_many_coordinates_keep_panels_short(tmp_path: Path) -> None:
    """Twelve coordinates: two panels of six against time, still three phase portraits."""
    from lagrange_cli.numeric.output import LINES_PER_PANEL, PHASE_PANELS

    n = 12
    text = f"coordinates: [{', '.join(f'x{i}' for i in range(n))}]\nparameters: {{m: 1.0}}\nkinetic: m*({' + '.join(f'x{i}_dot**2' for i in range(n))})/2\npotential: {' + '.join(f'(x{i} - x{i - 1})**2' for i in range(1, n))}\ninitial: {{x0: 1.0}}\n"
    figure = figure_of(model_of(text), tmp_path, "twelve", t_end=0.5)
    left = time_panels(figure)
    assert [len(legend_entries(a)) for a in left[:-1]] == [LINES_PER_PANEL, n - LINES_PER_PANEL]
    assert len(phase_panels(figure)) == PHASE_PANELS
    assert figure.get_size_inches()[1] <= 8.5
    assert_readable(figure)


def test_damped_energy_change_is_physics_not_error(tmp_path: Path) -> None:
    figure = figure_of(bundled("damped_oscillator_rayleigh"), tmp_path, "damped", t_end=3.0)
    energy = time_panels(figure)[-1]
    assert energy.get_ylabel() == "energy h (file units)" and energy.get_yscale() == "linear"
    assert energy.get_title() == "energy h(t): changes physically (damping)"
    assert not [text for text in texts(figure) if "error" in text.lower()]
    h = energy.get_lines()[0].get_ydata()
    assert h[-1] < h[0]  # the energy itself is drawn, and it decays
    assert_readable(figure)


def test_driven_energy_names_its_cause(tmp_path: Path) -> None:
    text = "coordinates: [x]\nparameters: {m: 1.0, k: 1.0, F: 0.5, w: 2.0}\nkinetic: m*x_dot**2/2\npotential: k*x**2/2\nforces: {generalized: {x: F*cos(w*t)}}\ninitial: {x: 1.0}\n"
    energy = time_panels(figure_of(model_of(text), tmp_path, "driven"))[-1]
    assert energy.get_title() == "energy h(t): changes physically (applied forces)"


def test_kept_constraints_get_a_drift_panel(tmp_path: Path) -> None:
    figure = figure_of(bundled("pendulum_multiplier"), tmp_path, "constrained")
    left = time_panels(figure)
    assert [a.get_ylabel() for a in left] == ["position (file units)", "relative energy error", "|constraint residual| (file units)"]
    drift = left[-1]
    assert drift.get_title() == "constraint drift (kept constraints)" and legend_entries(drift) == ["rod"]
    residual = drift.get_lines()[0].get_ydata()
    assert drift.get_yscale() == "log" and 0 < np.max(residual) < 1e-4
    assert drift.get_xlabel() == "t (file units)"
    assert_readable(figure)


LONG_TITLE = "a very long title with $x^{$ in it " * 8 + "W" * 150


def test_a_long_title_is_wrapped_not_clipped(tmp_path: Path) -> None:
    """Broken into lines that fit (a word wider than the figure too), every character kept, `$` not mathtext."""
    model = model_of(f"title: '{LONG_TITLE}'\ncoordinates: [x]\nparameters: {{m: 1.0}}\nkinetic: m*x_dot**2/2\npotential: x**2/2\ninitial: {{x: 1.0}}\n")
    figure = figure_of(model, tmp_path, "title")
    shown = figure.get_suptitle()
    assert shown.count("\n") >= 3 and "".join(shown.split()) == "".join((LONG_TITLE + " (DOP853, python; finished)").split())
    assert not figure._suptitle.get_parse_math()
    assert_readable(figure)


def test_the_command_plots_with_the_model(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`simulate --plot` hands the model over: `q` in `cos(q)` is an angle (its name alone would make it a position)."""
    from matplotlib.figure import Figure
    from typer.testing import CliRunner

    from lagrange_cli.cli import app

    saved: list[Any] = []
    save = Figure.savefig

    def savefig(self: Figure, *args: Any, **kwargs: Any) -> None:
        save(self, *args, **kwargs)
        saved.append(self)

    monkeypatch.setattr(Figure, "savefig", savefig)
    system = tmp_path / "swing.yaml"
    system.write_text("title: Swing\ncoordinates: [q]\nparameters: {g: 9.81}\nkinetic: q_dot**2/2\npotential: -g*cos(q)\ninitial: {q: 1.0}\n")
    result = CliRunner().invoke(app, ["simulate", str(system), "--t-end", "1", "--backend", "python", "--plot", str(tmp_path / "swing.png")])
    assert result.exit_code == 0, result.output
    (figure,) = saved
    assert time_panels(figure)[0].get_ylabel() == "angle [rad]"
    assert (tmp_path / "swing.png").read_bytes()[:4] == b"\x89PNG"


# --- accuracy --plot ------------------------------------------------------------------------


def study(title: str = "Pendulum") -> Any:
    from lagrange_cli.numeric.accuracy import Candidate, Point, Ran, Reference, Study

    def point(candidate: Candidate, ran: Ran, tolerance: float, error: float, seconds: float) -> Point:
        return Point(candidate.label, str(ran), tolerance, None, "finished", "", error, error / 2, 1e-9, None, seconds, 3, 0.5, int(100 / tolerance**0.2), 0, 10, candidate=candidate, ran=ran)

    points = [point(Candidate("DOP853"), Ran("DOP853", "compiled"), tol, tol, 1e-4 / tol**0.1) for tol in (1e-4, 1e-6, 1e-8)]
    points += [point(Candidate("DOP853", "python"), Ran("DOP853", "python"), tol, tol, 1e-2 / tol**0.1) for tol in (1e-4, 1e-6, 1e-8)]
    points += [point(Candidate("RK45", "python"), Ran("RK45", "python"), tol, 10 * tol, 2e-2 / tol**0.2) for tol in (1e-4, 1e-6)]
    points.append(dataclasses.replace(points[-1], tolerance=1e-8, status="over budget", final_error=float("nan"), rms_error=float("nan")))
    reference = Reference("computed", "two runs", 1e-12, np.zeros(2), np.zeros((2, 2)), np.zeros(2), 0.1)
    return Study(title, "s.yaml", 10.0, 10.0, reference, None, tuple(points))


def study_figure_of(result: Any, tmp_path: Path, name: str) -> Any:
    from lagrange_cli.numeric.accuracy import study_figure
    from lagrange_cli.numeric.output import plain_text

    with plain_text():
        return drawn(study_figure(result), tmp_path / f"{name}.png")


def test_accuracy_plot_tells_compiled_from_python_runs(tmp_path: Path) -> None:
    figure = study_figure_of(study(), tmp_path, "accuracy")
    (legend,) = figure.legends
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels == ["DOP853 (compiled)", "DOP853 (python)", "RK45 (python)", "reference's own error"]
    assert legend.get_title().get_text() == "solid: compiled (numba); dashed: pure Python (scipy)"
    left, right = figure.axes
    lines = {line.get_label(): line for line in left.get_lines() if not line.get_label().startswith("_")}
    compiled, python = lines["DOP853 (compiled)"], lines["DOP853 (python)"]
    assert compiled.get_color() == python.get_color()  # one method, one colour
    assert (compiled.get_linestyle(), compiled.get_marker()) != (python.get_linestyle(), python.get_marker())
    assert python.get_linestyle() == lines["RK45 (python)"].get_linestyle() == "--"
    assert len(lines["RK45 (python)"].get_xdata()) == 2  # the run over budget is not drawn
    assert left.get_xlabel() == "run time [s] (one-time compile excluded)" and right.get_xlabel() == "right-hand side evaluations"
    assert left.get_ylabel() == right.get_ylabel() == "error (largest over the samples, scaled)"
    assert_readable(figure)


def test_accuracy_labels_follow_what_ran() -> None:
    from lagrange_cli.numeric.accuracy import Candidate, plot_label, run_backend

    points = study().points
    assert [run_backend(p) for p in points[::3]] == ["compiled", "python", "python"]
    auto = dataclasses.replace(points[0], method="auto", candidate=Candidate("auto"))
    assert plot_label(auto) == "auto -> DOP853 (compiled)"


def test_accuracy_plot_with_a_long_title_and_no_finished_run(tmp_path: Path) -> None:
    result = study(LONG_TITLE)
    failed = dataclasses.replace(result, points=tuple(dataclasses.replace(p, status="failed") for p in result.points))
    figure = study_figure_of(failed, tmp_path, "failed")
    assert "no run finished" in texts(figure)
    assert_readable(figure)
    assert_readable(study_figure_of(result, tmp_path, "long"))
