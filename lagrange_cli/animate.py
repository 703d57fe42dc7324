"""Trajectories -> frames: the mechanism drawn moving, as a GIF, an MP4 or a self-contained HTML page.

What is drawn comes from the file: each particle and body as a dot at its position (the file's
own position expressions, evaluated at the simulated states), and with a `draw` block its
`segments` (lines between two points) and `trails` (the path a point has taken so far).
Positions with `eliminate`d coordinates are written in the remaining ones, and functions the
file defines are written out, as for the equations. The positions become one generated Python
function (names mangled by `emit.python`, straight-line code from `cse_block`), compiled from
the source this module writes, never from file text.

Planar systems (positions of 1 or 2 components) are drawn in the plane, spatial ones in a 3-D
view or, with `view="xy"`, `"xz"` or `"yz"`, in that projection. Time runs in real time at
`speed` 1 (one second of the system's time per second of the animation); each frame shows the
time and the energy h. Frames are the trajectory's samples: the frame interval is a whole number
of sample intervals, so a frame shows exactly a simulated state (the command line simulates
with one sample per frame).
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import sympy as sp

from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model, apply_definitions
from lagrange_cli.spec import SystemSpec

if TYPE_CHECKING:
    import numpy as np

    from lagrange_cli.numeric.simulate import Trajectory

SUFFIXES = (".gif", ".mp4", ".html")
VIEWS = ("3d", "xy", "xz", "yz")
FPS = 25.0
"""Frames per second of the animation (at most: fewer when the samples are sparser)."""
MAX_FRAMES = 1500
"""Most frames of one animation: a longer run is shown with a larger stride (still in real time)."""
SIZE = (6.0, 6.0)
DPI = 80
"""A frame is SIZE x DPI pixels: 480 x 480."""
FFMPEG_HINT = "install ffmpeg (Debian: `apt-get install ffmpeg`), or write a .gif or .html"


@dataclass(frozen=True)
class Scene:
    """What is drawn: `dots` (each particle and body, by name), `segments` (pairs of point
    indices), `trails` (point indices); `points` are the distinct positions, `labels` their names
    (empty for a position list of `draw`)."""

    points: tuple[tuple[sp.Expr, ...], ...]
    labels: tuple[str, ...]
    dots: tuple[int, ...]
    segments: tuple[tuple[int, int], ...]
    trails: tuple[int, ...]
    dimension: int
    axes: tuple[int, ...] = ()
    """For each of the last `len(axes)` segments, a body's axis it draws (0 x, 1 y, 2 z): drawn thin, in AXIS_COLOURS."""


def scene(spec: SystemSpec, model: Model) -> Scene:
    """The points of `spec` to draw, in `model`'s coordinates (eliminated ones substituted,
    defined functions written out). Raises `LagrangeError` when there is nothing to draw or a
    position uses a function without a definition."""
    eliminated = {sp.Symbol(name): value for name, value in model.eliminated}
    points: list[tuple[sp.Expr, ...]] = []
    labels: list[str] = []

    def index(label: str, position: Sequence[sp.Expr]) -> int:
        value = tuple(apply_definitions(sp.sympify(x).xreplace(eliminated), model.definitions) for x in position)
        key = (label, value)
        for i, existing in enumerate(zip(labels, points, strict=True)):
            if existing == key:
                return i
        labels.append(label)
        points.append(value)
        return len(points) - 1

    masses: tuple[Any, ...] = (*spec.particles, *spec.bodies)
    dots = tuple(index(item.name, item.position) for item in masses)
    drawing = spec.draw
    segments = tuple((index(a.label, a.position), index(b.label, b.position)) for a, b in drawing.segments) if drawing else ()
    trails = tuple(index(p.label, p.position) for p in drawing.trails) if drawing else ()
    frames = [pair for body in spec.bodies for pair in body_axes(body, index)]
    segments += tuple(frames)
    if not points:
        raise LagrangeError(f"{model.source}: nothing to draw: the system has no particles, bodies or `draw` block; animate draws the positions of particles and bodies")
    undefined = sorted({str(f.func) for p in points for x in p for f in x.atoms(sp.core.function.AppliedUndef)})
    if undefined:
        raise LagrangeError(f"{model.source}: drawing needs every function defined, but {', '.join(undefined)} left undefined; give each a `definition`")
    axes = tuple(k for body in spec.bodies for k in range(len(getattr(body, "rotation", None) or ())))
    assert len(axes) == len(frames)
    return Scene(tuple(points), tuple(labels), dots, segments, trails, max(len(p) for p in points), axes)


AXIS_COLOURS = ("tab:red", "tab:green", "tab:blue")
"""A body's x, y and z axes (the usual red, green, blue), thinner than the `draw` segments."""
AXIS_SHARE = 0.25
"""The length of a body's drawn axes, as a share of the half-width of the view."""


def body_axes(body: Any, index: Callable[[str, Sequence[sp.Expr]], int]) -> list[tuple[int, int]]:
    """Segments from the centre of a body with an `orientation` along its axes (the columns of R), of unit
    length here; the animation draws them `AXIS_SHARE` of its view long, whatever the system's size."""
    rotation = getattr(body, "rotation", None)
    if rotation is None:
        return []
    centre = tuple(body.position)
    origin = index(body.name, centre)
    return [(origin, index(f"{body.name} {'xyz'[k]} axis", tuple(c + rotation[i][k] for i, c in enumerate(centre)))) for k in range(len(rotation))]


def position_function(scene: Scene, model: Model) -> Callable[[float, Sequence[float], Sequence[float]], list[float]]:
    """`positions(t, y, p)`: every point's components, flattened, at time t, state y = [q..., q_dot...]
    and parameter values p (in the model's order); generated code, names mangled."""
    from lagrange_cli._symengine import to_symengine
    from lagrange_cli.emit.python import PythonPrinter, define, python_names

    names = python_names(model)
    exprs = [x for point in scene.points for x in point]
    used = set().union(*(sp.sympify(e).free_symbols for e in exprs))
    unknown = sorted(str(s) for s in used if s not in names)
    if unknown:  # a coordinate removed without a substitute, which derive would have refused
        raise LagrangeError(f"{model.source}: a drawn position uses {', '.join(unknown)}, which is not a coordinate, parameter or t of the derived system")
    printer = PythonPrinter({str(symbol): name for symbol, name in names.items()})
    temporaries, results = printer.block([to_symengine(sp.sympify(e)) for e in exprs], "_d")
    body = [f"{names[p.symbol]} = _p[{i}]" for i, p in enumerate(model.parameters) if p.symbol in used]
    body += [f"{names[q]} = _y[{i}]" for i, q in enumerate(model.q) if q in used]
    body += [*(f"{name} = {code}" for name, code in temporaries), f"return [{', '.join(f'float({r})' for r in results)}]"]
    source = define("_positions", "t, _y, _p", "The drawn points' positions, flattened.", body)
    math_names = printer.imports()
    namespace: dict[str, Any] = {}
    code = (f"from math import {', '.join(math_names)}\n" if math_names else "") + source + "\n"
    exec(compile(code, "<lagrange animate: positions>", "exec"), namespace)  # generated code, no file text
    return namespace["_positions"]  # type: ignore[no-any-return]


def frame_indices(times: np.ndarray, speed: float, fps: float, frames: int | None = None) -> tuple[list[int], float]:
    """The sample indices shown as frames, and the interval between frames in milliseconds, so
    that the animation runs at `speed` (1: real time) with at most `fps` frames per second and at
    most `frames` (default MAX_FRAMES) frames."""
    count = len(times)
    if count < 2:
        return list(range(count)), 1000.0 / fps
    step = float(times[-1] - times[0]) / (count - 1)
    stride = max(1, math.ceil(speed / fps / step - 1e-9)) if step > 0 else 1
    limit = frames or MAX_FRAMES
    stride = max(stride, math.ceil(count / limit))
    indices = list(range(0, count, stride))
    return indices, 1000.0 * stride * step / speed if step > 0 else 1000.0 / fps


def _check_number(value: float | None, what: str, positive: bool = True) -> None:
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or (positive and value <= 0):
        raise LagrangeError(f"{what} must be a finite number above 0, got {value!r}")


def animation(
    spec: SystemSpec,
    model: Model,
    run: Trajectory,
    *,
    speed: float = 1.0,
    fps: float | None = None,
    view: str | None = None,
    trail: float | None = None,
    frames: int | None = None,
) -> Animation:
    """The animation of `run` (a trajectory of `model`, derived from `spec`): `speed` times real
    time, at most `fps` frames per second (default FPS), `view` for spatial systems (3d, the
    default, or a projection xy, xz, yz), trails over the last `trail` time units (default: the
    whole run so far), at most `frames` frames."""
    import numpy as np

    _check_number(speed, "speed")
    _check_number(fps, "fps")
    _check_number(trail, "trail")
    if frames is not None and (isinstance(frames, bool) or not isinstance(frames, int) or frames < 1):
        raise LagrangeError(f"frames must be a whole number of at least 1, got {frames!r}")
    if view is not None and view.lower() not in VIEWS:
        raise LagrangeError(f"unknown view '{view}'; choose one of {', '.join(VIEWS)}")
    drawn = scene(spec, model)
    if len(run.t) == 0:
        raise LagrangeError(f"{model.source}: nothing to animate: the run has no samples ({run.message})")
    function = position_function(drawn, model)
    values = dict(run.settings.parameters)
    p = [float(values.get(q.name, q.value if q.value is not None else math.nan)) for q in model.parameters]
    indices, interval = frame_indices(run.t, speed, fps or FPS, frames)
    try:
        flat = np.array([function(float(run.t[k]), run.y[k].tolist(), p) for k in indices], dtype=float)
    except (ValueError, ZeroDivisionError, OverflowError, TypeError) as error:
        raise LagrangeError(f"{model.source}: a drawn position cannot be evaluated along the run: {error}") from None
    dimension = drawn.dimension
    positions = np.zeros((len(indices), len(drawn.points), max(dimension, 2)))
    at = 0
    for i, point in enumerate(drawn.points):
        positions[:, i, : len(point)] = flat[:, at : at + len(point)]
        at += len(point)
    chosen = (view or "3d").lower() if dimension == 3 else "plane"
    return Animation(
        title=run.title,
        scene=drawn,
        times=np.asarray(run.t[indices], dtype=float),
        energy=np.asarray(run.energy[indices], dtype=float) if len(run.energy) == len(run.t) else np.full(len(indices), math.nan),
        positions=positions,
        interval=interval,
        view=chosen,
        trail=trail,
    )


def _axes_of(view: str) -> tuple[int, int]:
    return {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}.get(view, (0, 1))


class Animation:
    """Frames of a moving mechanism. `positions[k, i]` is point i (`scene.labels[i]`) in frame k,
    at time `times[k]`; `update(k)` sets the figure's artists to frame k (`dots`, `segments` and
    `trails` are the matplotlib artists, `dots` by particle or body name). `save(path)` writes a
    .gif (pillow), .mp4 (ffmpeg) or .html (self-contained, plays offline); in Jupyter it plays
    (`_repr_html_`); `frame(k)` is one frame as PNG bytes."""

    def __init__(self, *, title: str, scene: Scene, times: np.ndarray, energy: np.ndarray, positions: np.ndarray, interval: float, view: str, trail: float | None) -> None:
        self.title, self.scene, self.times, self.energy, self.positions = title, scene, times, energy, positions
        self.interval, self.view, self.trail = interval, view, trail
        self.figure, self.axes, self.dots, self.segments, self.trails, self.stamp = self._draw()
        self.update(0)

    def __len__(self) -> int:
        return len(self.times)

    @property
    def fps(self) -> float:
        return 1000.0 / self.interval

    def _coordinates(self, frame: Any, i: int) -> list[Any]:
        """The drawn coordinates of point i in frame(s) `frame` (2 in the plane or a projection, 3 in 3-D)."""
        if self.view == "3d":
            return [self.positions[frame, i, c] for c in range(3)]
        a, b = _axes_of(self.view)
        return [self.positions[frame, i, a], self.positions[frame, i, b]]

    def _draw(self) -> tuple[Any, Any, dict[str, Any], list[Any], list[Any], Any]:
        import numpy as np
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        from lagrange_cli.numeric.output import figure_title, plain_text, plot_text

        with plain_text():
            figure = Figure(figsize=SIZE, dpi=DPI, layout="constrained")
            FigureCanvasAgg(figure)
            three = self.view == "3d"
            axes: Any = figure.add_subplot(projection="3d") if three else figure.add_subplot()
            tips = {b for _, b in self.scene.segments[len(self.scene.segments) - len(self.scene.axes) :]}  # axes' ends: sized to the view, not sizing it
            kept = [i for i in range(self.positions.shape[1]) if i not in tips]
            every = self.positions[:, kept, :].reshape(-1, self.positions.shape[2])
            finite = every[np.all(np.isfinite(every), axis=1)]
            names = ("x", "y", "z")
            used = (0, 1, 2) if three else _axes_of(self.view) if self.view != "plane" else (0, 1)
            low = finite.min(axis=0) if len(finite) else np.zeros(every.shape[1])
            high = finite.max(axis=0) if len(finite) else np.ones(every.shape[1])
            centre, half = (low + high) / 2, max(float(np.max(high[list(used)] - low[list(used)])) / 2 * 1.1, 1e-3)
            self.axis_length = AXIS_SHARE * half
            setters = (axes.set_xlim, axes.set_ylim, getattr(axes, "set_zlim", None))
            for k, c in enumerate(used):
                setter = setters[k]
                assert setter is not None
                setter(centre[c] - half, centre[c] + half)
            if three:
                axes.set_box_aspect((1, 1, 1))
                axes.set_xlabel("x")
                axes.set_ylabel("y")
                axes.set_zlabel("z")
            else:
                axes.set_aspect("equal")
                axes.set_xlabel(names[used[0]])
                axes.set_ylabel(names[used[1]] if self.scene.dimension > 1 else "")
                axes.grid(True, alpha=0.3)
            figure_title(figure, plot_text(self.title))
            drawn = len(self.scene.segments) - len(self.scene.axes)
            styles: list[dict[str, Any]] = [{"color": "0.25", "linewidth": 3, "zorder": 2}] * drawn + [{"color": AXIS_COLOURS[k], "linewidth": 2, "zorder": 2.5} for k in self.scene.axes]
            segments = [axes.plot(*([[0.0, 0.0]] * len(used)), "-", solid_capstyle="round", **style)[0] for style in styles]
            trails = [axes.plot(*([[0.0]] * len(used)), "-", linewidth=1, alpha=0.6, zorder=1)[0] for _ in self.scene.trails]
            dots = {}
            for i in self.scene.dots:
                (dot,) = axes.plot(*([[0.0]] * len(used)), "o", markersize=12, zorder=3)
                dot.set_gid(self.scene.labels[i])
                dots[self.scene.labels[i]] = dot
            place = (lambda x, y, s: axes.text2D(x, y, s, transform=axes.transAxes)) if three else (lambda x, y, s: axes.text(x, y, s, transform=axes.transAxes))
            stamp = place(0.02, 0.95, "")
            stamp.set_parse_math(False)
            if self.scene.axes:
                shown = sorted(set(self.scene.axes))
                place(0.02, 0.91, "body axes: " + ", ".join(f"{'xyz'[k]} {AXIS_COLOURS[k].removeprefix('tab:')}" for k in shown)).set_parse_math(False)
        return figure, axes, dots, segments, trails, stamp

    def update(self, k: int) -> list[Any]:
        """Set every artist to frame k; returns them (for FuncAnimation)."""
        import numpy as np

        three = self.view == "3d"

        def put(artist: Any, coordinates: list[Any]) -> None:
            if three:
                artist.set_data_3d(*(np.atleast_1d(c) for c in coordinates))
            else:
                artist.set_data(*(np.atleast_1d(c) for c in coordinates))

        for i, dot in zip(self.scene.dots, self.dots.values(), strict=True):
            put(dot, self._coordinates(k, i))
        drawn = len(self.scene.segments) - len(self.scene.axes)
        for j, ((a, b), line) in enumerate(zip(self.scene.segments, self.segments, strict=True)):
            first, second = self._coordinates(k, a), self._coordinates(k, b)
            if j >= drawn:  # a body's axis: a unit vector from its centre, drawn AXIS_SHARE of the view long
                second = [u + self.axis_length * (v - u) for u, v in zip(first, second, strict=True)]
            put(line, [np.array([u, v]) for u, v in zip(first, second, strict=True)])
        start = 0
        if self.trail is not None:
            start = int(np.searchsorted(self.times, self.times[k] - self.trail))
        for i, line in zip(self.scene.trails, self.trails, strict=True):
            put(line, self._coordinates(slice(start, k + 1), i))
        energy = self.energy[k]
        self.stamp.set_text(f"t = {self.times[k]:.2f}   h = {energy:.6g}" if math.isfinite(energy) else f"t = {self.times[k]:.2f}")
        return [*self.dots.values(), *self.segments, *self.trails, self.stamp]

    def _animation(self) -> Any:
        from matplotlib.animation import FuncAnimation

        return FuncAnimation(self.figure, self.update, frames=len(self), interval=self.interval, blit=False, repeat=True)

    def frame(self, k: int) -> bytes:
        """Frame k as PNG bytes."""
        import io

        self.update(k)
        buffer = io.BytesIO()
        self.figure.savefig(buffer, format="png", dpi=DPI)
        return buffer.getvalue()

    def _repr_png_(self) -> bytes:
        return self.frame(0)

    def to_html(self) -> str:
        """A self-contained HTML page that plays the animation offline (frames embedded as PNG,
        matplotlib's JavaScript player inline)."""
        import html

        return f'<!DOCTYPE html>\n<html>\n<head>\n<meta charset="utf-8">\n<title>{html.escape(self.title)}</title>\n</head>\n<body>\n' + self._jshtml() + "\n</body>\n</html>\n"

    def _jshtml(self) -> str:
        import matplotlib

        from lagrange_cli.numeric.output import plain_text

        with plain_text(), matplotlib.rc_context({"animation.embed_limit": 1000.0}):
            player = str(self._animation().to_jshtml(fps=self.fps, embed_frames=True, default_mode="loop"))
        return offline(player)

    def _repr_html_(self) -> str:
        return self._jshtml()

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the animation to `path` atomically: .gif (pillow), .mp4 (ffmpeg, which must be
        installed) or .html (self-contained)."""
        from lagrange_cli.files import atomic_write, write_text

        target = Path(path)
        suffix = check_output(target)
        if suffix == ".html":
            write_text(target, self.to_html())
            return
        from matplotlib.animation import FFMpegWriter, PillowWriter

        from lagrange_cli.numeric.output import plain_text

        fps: Any = self.fps  # a float: the frame interval of a real-time run need not be whole milliseconds
        writer = PillowWriter(fps=fps) if suffix == ".gif" else FFMpegWriter(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"])
        with tempfile.TemporaryDirectory(prefix="lagrange-animate-") as folder:
            scratch = Path(folder) / f"motion{suffix}"
            with plain_text():
                self._animation().save(str(scratch), writer=writer, dpi=DPI)
            data = scratch.read_bytes()
        atomic_write(target, lambda stream: stream.write(data))


ICONS = (
    "<style>.anim-buttons .fa{font-style:normal;font-family:sans-serif}"
    ".fa-flip-horizontal{display:inline-block;transform:scaleX(-1)}"
    '.fa-play:before{content:"\\25B6"}.fa-pause:before{content:"\\275A\\275A"}'
    '.fa-step-forward:before{content:"\\25B6\\2759"}.fa-step-backward:before{content:"\\2759\\25C0"}'
    '.fa-fast-forward:before{content:"\\25B6\\25B6"}.fa-fast-backward:before{content:"\\25C0\\25C0"}'
    '.fa-plus:before{content:"+"}.fa-minus:before{content:"\\2212"}</style>'
)
"""The player's button icons as characters: matplotlib's player links Font Awesome from a CDN,
which an offline page cannot load."""


def offline(player: str) -> str:
    """matplotlib's HTML player with nothing fetched from the network: its stylesheet link to
    Font Awesome replaced by `ICONS`. A player that still names a web address is an error here,
    not a page that fails without a network."""
    import re

    page = re.sub(r"<link\s+rel=\"stylesheet\"\s+href=\"https?://[^\"]*font-awesome[^\"]*\"\s*/?>", lambda _: ICONS, player)
    if re.search(r"(src|href)=\"https?://", page):
        raise LagrangeError("matplotlib's HTML player refers to a web address; the page would not work offline")
    return page


def check_output(path: Path) -> str:
    """The output's suffix (.gif, .mp4 or .html), checked before any work: a known suffix,
    matplotlib installed, and for .mp4 ffmpeg present. Raises `LagrangeError` saying what is missing."""
    import importlib.util

    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise LagrangeError(f"{path}: cannot tell the animation format from the name; use one of {', '.join(SUFFIXES)}")
    if importlib.util.find_spec("matplotlib") is None:
        raise LagrangeError("animate needs matplotlib, which is not installed: `pip install 'lagrange-cli[plot]'`")
    if suffix == ".mp4" and not ffmpeg_available():
        raise LagrangeError(f"{path}: writing .mp4 needs ffmpeg, which is not installed: {FFMPEG_HINT}")
    return suffix


def ffmpeg_available() -> bool:
    import shutil

    import matplotlib

    return shutil.which(str(matplotlib.rcParams["animation.ffmpeg_path"])) is not None


def simulate_for(model: Model, *, speed: float = 1.0, fps: float | None = None, t_end: float | None = None, **settings: Any) -> Trajectory:
    """`numeric.simulate` of `model` with one sample per frame of an animation at `speed` and
    `fps` (at most MAX_FRAMES samples), so that every frame shows a simulated state exactly."""
    from lagrange_cli.numeric.simulate import simulate
    from lagrange_cli.spec import DEFAULT_T_END

    _check_number(speed, "speed")
    _check_number(fps, "fps")
    _check_number(t_end, "t_end")
    end = float(t_end if t_end is not None else model.simulate.get("t_end", DEFAULT_T_END))
    samples = min(MAX_FRAMES, max(2, round(end * (fps or FPS) / speed) + 1))
    return simulate(model, t_end=t_end, samples=samples, **settings)
