"""`lagrange animate` and `Trajectory.animate()`: every frame draws the simulated positions, the
files have the frames and size they should, the HTML plays offline in a real browser, and a bad
`draw` block is a located error."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lagrange_cli import load
from lagrange_cli.cli import app
from lagrange_cli.errors import LagrangeError, SpecError

from .conftest import ROOT
from .limits import DEADLOCK

pytestmark = pytest.mark.usefixtures("private_cache")
runner = CliRunner()
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
FFPROBE = shutil.which("ffprobe")


def drawn(artist: object, three: bool = False) -> np.ndarray:
    """The coordinates an artist draws, read from matplotlib: one row per point."""
    data = artist.get_data_3d() if three else artist.get_data()  # type: ignore[attr-defined]
    return np.column_stack([np.asarray(c, dtype=float) for c in data])


def sample(run: object, time: float) -> np.ndarray:
    """The simulated state at `time` (which is a sample time)."""
    t = run.times  # type: ignore[attr-defined]
    k = int(np.argmin(np.abs(t - time)))
    assert abs(t[k] - time) < 1e-12
    return run.run.y[k]  # type: ignore[attr-defined]


def test_each_frame_draws_the_simulated_positions() -> None:
    """Frame k of the double pendulum: its dots and rods where l sin(theta), ... put them at times[k]."""
    system = load("double_pendulum")
    run = system.simulate(t_end=1.0, samples=51, method="DOP853", backend="python")
    movie = run.animate(fps=50)
    assert len(movie) == 51 and movie.interval == pytest.approx(20.0)  # real time: 0.02 s of motion per 20 ms frame
    for k in (0, 7, 33, 50):
        movie.update(k)
        theta, phi = sample(run, movie.times[k])[:2]
        upper = np.array([math.sin(theta), -math.cos(theta)])  # l = 1
        lower = upper + np.array([math.sin(phi), -math.cos(phi)])
        assert drawn(movie.dots["upper"])[0] == pytest.approx(upper, abs=1e-12)
        assert drawn(movie.dots["lower"])[0] == pytest.approx(lower, abs=1e-12)
        assert drawn(movie.segments[0]) == pytest.approx(np.array([[0.0, 0.0], upper]), abs=1e-12)  # pivot to upper bob
        assert drawn(movie.segments[1]) == pytest.approx(np.array([upper, lower]), abs=1e-12)
        trail = drawn(movie.trails[0])
        assert len(trail) == k + 1 and trail[-1] == pytest.approx(lower, abs=1e-12)
        assert f"t = {movie.times[k]:.2f}" in movie.stamp.get_text()


def test_speed_and_sparse_samples_keep_real_time() -> None:
    run = load("simple_pendulum").simulate(t_end=2.0, samples=201, backend="python")
    fast = run.animate(speed=2, fps=10)  # 0.2 s of motion per frame: every 20th sample
    assert list(fast.times[:3]) == pytest.approx([0.0, 0.2, 0.4]) and fast.interval == pytest.approx(100.0)
    sparse = load("simple_pendulum").simulate(t_end=2.0, samples=5, backend="python").animate(fps=25)
    assert len(sparse) == 5 and sparse.interval == pytest.approx(500.0)  # a sample every 0.5 s, shown for 0.5 s
    chaos = load("double_pendulum").simulate(t_end=2.0, samples=201, backend="python").animate(trail=0.1, fps=100)
    chaos.update(100)
    assert len(chaos.trails[0].get_xdata()) == 11  # trails over the last 0.1 time units


def test_spatial_systems_in_3d_and_in_projection() -> None:
    system = load("spherical_pendulum")
    run = system.simulate(t_end=0.5, samples=11, backend="python")
    length = system.parameters["l"]
    assert length is not None
    for view in ("3d", "xz"):
        movie = run.animate(view=view)
        movie.update(6)
        theta, phi = sample(run, movie.times[6])[:2]
        where = length * np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), -math.cos(theta)])
        if view == "3d":
            assert drawn(movie.dots["bob"], three=True)[0] == pytest.approx(where, abs=1e-12)
        else:
            assert drawn(movie.dots["bob"])[0] == pytest.approx(where[[0, 2]], abs=1e-12)
    with pytest.raises(LagrangeError, match="unknown view 'side'"):
        run.animate(view="side")


def test_eliminated_coordinates_are_written_in_the_remaining_ones() -> None:
    """atwood_machine eliminates y2 = l - y1 (the string): mass2 is drawn at -(l - y1)."""
    system = load("atwood_machine")
    assert system.coordinates == ("y1",)
    run = system.simulate(t_end=0.5, samples=6, backend="python")
    movie = run.animate()
    movie.update(5)
    y1 = sample(run, movie.times[5])[0]
    assert drawn(movie.dots["mass2"])[0] == pytest.approx([-(3.0 - y1), 0.0], abs=1e-12)
    assert drawn(movie.dots["mass1"])[0] == pytest.approx([-y1, 0.0], abs=1e-12)


def test_a_system_without_anything_to_draw_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "abstract.yaml"
    path.write_text("coordinates: [x]\nparameters: {k: 1.0}\nkinetic: x_dot**2/2\npotential: k*x**2/2\ninitial: {x: 1}\n")
    result = runner.invoke(app, ["animate", str(path), "-o", str(tmp_path / "m.gif")])
    assert result.exit_code == 2 and f"error: {path}: nothing to draw" in result.stderr and not (tmp_path / "m.gif").exists()


@pytest.mark.parametrize(
    ("draw", "where", "message"),
    [
        ("{segments: [[[0, 0], bobb]]}", "4:28", "unknown point 'bobb' in 'draw'"),
        ("{segments: [[bob]]}", "4:19", "a segment of 'draw.segments' must be a pair of points, got 1 item"),
        ("{trails: [[0, 0, 1]]}", "4:17", "a point of 'draw' has 3 components"),
        ("{segments: [[bob, bob.tip]]}", "4:25", "unknown point 'bob.tip' in 'draw'"),
        ("{colour: red}", "4:8", "unknown key 'colour' in 'draw'"),
        ("[bob]", "4:7", "'draw' must be a map"),
    ],
)
def test_a_bad_draw_block_is_an_error_at_its_place(tmp_path: Path, draw: str, where: str, message: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(f"coordinates: [theta]\nparticles:\n  bob: {{mass: 1, position: [sin(theta), -cos(theta)]}}\ndraw: {draw}\n")
    with pytest.raises(SpecError) as caught:
        load(path)
    assert f"{path}:{where}: error: {message}" in str(caught.value)
    result = runner.invoke(app, ["animate", str(path), "-o", str(tmp_path / "m.gif")])
    assert result.exit_code == 2 and f"{path}:{where}: error: {message}" in result.stderr


def test_every_bundled_draw_block_reads_and_draws() -> None:
    """Each bundled system's points evaluate at its initial state (no run needed)."""
    from lagrange_cli import animate, derive, spec

    for path in sorted((ROOT / "systems").glob("*.yaml")):
        system = spec.load(path)
        model = derive.derive(system)
        scene = animate.scene(system, model)
        function = animate.position_function(scene, model)
        state = [model.initial.get(c, 0.0) for c in model.coordinates] + [0.0] * model.n
        values = function(0.0, state, [p.value or 1.0 for p in model.parameters])
        assert len(values) == sum(len(p) for p in scene.points) and all(math.isfinite(v) for v in values), path.name


def test_the_gif_has_a_frame_per_sample_and_the_frame_size(tmp_path: Path) -> None:
    from PIL import Image

    target = tmp_path / "motion.gif"
    result = runner.invoke(app, ["animate", "double_pendulum", "-o", str(target), "--t-end", "0.4", "--fps", "10"])
    assert result.exit_code == 0, result.output
    assert "5 frames at 10 per second" in result.stdout
    with Image.open(target) as image:
        assert image.n_frames == 5 and image.size == (480, 480)
        assert image.info["duration"] == 100  # ms per frame: real time


def test_mp4_needs_ffmpeg(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import matplotlib

    monkeypatch.setitem(matplotlib.rcParams, "animation.ffmpeg_path", str(tmp_path / "no-ffmpeg-here"))
    result = runner.invoke(app, ["animate", "double_pendulum", "-o", str(tmp_path / "m.mp4")])
    assert result.exit_code == 2 and "writing .mp4 needs ffmpeg, which is not installed" in result.stderr
    result = runner.invoke(app, ["animate", "double_pendulum", "-o", str(tmp_path / "m.avi")])
    assert result.exit_code == 2 and "cannot tell the animation format from the name; use one of .gif, .mp4, .html" in result.stderr


@pytest.mark.skipif(FFPROBE is None or shutil.which("ffmpeg") is None, reason="ffmpeg not installed (make test installs it)")
def test_the_mp4_has_the_frames_and_size(tmp_path: Path) -> None:
    target = tmp_path / "motion.mp4"
    result = runner.invoke(app, ["animate", "simple_pendulum", "-o", str(target), "--t-end", "0.8", "--fps", "10"])
    assert result.exit_code == 0, result.output
    probe = subprocess.run(
        [str(FFPROBE), "-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries", "stream=nb_read_frames,width,height", "-of", "json", str(target)],
        capture_output=True,
        text=True,
        timeout=DEADLOCK,
    )
    stream = json.loads(probe.stdout)["streams"][0]
    assert (int(stream["nb_read_frames"]), stream["width"], stream["height"]) == (9, 480, 480)


def test_html_on_stdout_is_a_whole_page() -> None:
    result = runner.invoke(app, ["animate", "simple_pendulum", "-o", "-", "--t-end", "0.2", "--fps", "10"])
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith("<!DOCTYPE html>") and result.stdout.rstrip().endswith("</html>") and "data:image/png;base64" in result.stdout
    assert "3 frames" in result.stderr
    assert "http://" not in result.stdout and "https://" not in result.stdout  # plays offline: nothing fetched (matplotlib's player links a CDN; replaced)
    assert ".fa-play:before" in result.stdout


def test_file_text_in_the_page_is_escaped(tmp_path: Path) -> None:
    path = tmp_path / "x.yaml"
    path.write_text("title: '<script>alert(1)</script> $x$'\ncoordinates: [x]\nparticles:\n  p: {mass: 1, position: [x]}\ninitial: {x_dot: 1}\n")
    movie = load(path).simulate(t_end=0.2, samples=3, backend="python").animate()
    page = movie.to_html()
    assert "<script>alert(1)" not in page and "&lt;script&gt;alert(1)&lt;/script&gt;" in page
    assert movie.figure.texts[0].get_text().startswith("<script>") and movie.figure.texts[0].get_parse_math() is False  # shown as written


@pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed (make test installs it)")
def test_the_html_plays_offline_in_chromium(tmp_path: Path) -> None:
    """Headless Chromium, without network: no console error, and the screenshot shows the rods
    and bobs (many pixels that are neither white nor the page's grey)."""
    from PIL import Image

    page = tmp_path / "motion.html"
    result = runner.invoke(app, ["animate", "double_pendulum", "-o", str(page), "--t-end", "0.4", "--fps", "10"])
    assert result.exit_code == 0, result.output
    shot = tmp_path / "shot.png"
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update", "--no-first-run", "--disable-sync"]
    run = subprocess.run(
        [str(CHROMIUM), *flags, f"--user-data-dir={tmp_path / 'profile'}", "--enable-logging=stderr", "--v=0", "--window-size=800,900", f"--screenshot={shot}", page.as_uri()],
        capture_output=True,
        text=True,
        timeout=DEADLOCK,
    )
    console = [line for line in run.stderr.splitlines() if "CONSOLE" in line]
    assert not [line for line in console if "error" in line.lower()], console
    with Image.open(shot) as image:
        pixels = np.asarray(image.convert("RGB"), dtype=int)
    coloured = np.sum(np.abs(pixels - pixels[:, :, :1]).max(axis=2) > 40)  # saturated: the bobs, not grey lines or text
    dark = np.sum(pixels.max(axis=2) < 100)  # the rods and the text
    assert coloured > 500 and dark > 500, (coloured, dark)


def test_a_failed_run_is_animated_up_to_the_failure_and_exits_1(tmp_path: Path) -> None:
    """x_ddot = 4 x**3 blows up in finite time: the frames up to there are written, then exit 1."""
    path = tmp_path / "blowup.yaml"
    path.write_text("coordinates: [x]\nparticles:\n  p: {mass: 1, position: [x]}\npotential: -x**4\ninitial: {x: 1, x_dot: 1}\nsimulate: {t_end: 2}\n")
    target = tmp_path / "m.gif"
    result = runner.invoke(app, ["animate", str(path), "-o", str(target), "--fps", "10"])
    assert result.exit_code == 1, result.output
    assert f"error: {path}: simulation failed at t = " in result.stderr and "the animation shows the run up to there" in result.stderr
    from PIL import Image

    with Image.open(target) as image:
        assert 1 <= image.n_frames < 21


@pytest.mark.slow
@pytest.mark.parametrize("path", sorted((ROOT / "systems").glob("*.yaml")), ids=lambda p: p.stem)
def test_every_bundled_system_animates(path: Path) -> None:
    """A short run of each bundled system draws: a PNG frame with its title and time stamp."""
    run = load(path).simulate(t_end=0.1, samples=3, backend="python")
    assert not run.failed, run.message
    movie = run.animate()
    assert len(movie) == 3 and movie.frame(2).startswith(b"\x89PNG")
    assert movie.stamp.get_text().startswith("t = 0.10")


def test_animate_without_matplotlib_names_the_extra(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "matplotlib", None)  # type: ignore[arg-type]
    result = runner.invoke(app, ["animate", "simple_pendulum", "-o", str(tmp_path / "m.gif")])
    assert result.exit_code == 2 and "animate needs matplotlib, which is not installed: `pip install 'lagrange-cli[plot]'`" in result.stderr
    assert not (tmp_path / "m.gif").exists()
