"""`animate`: the mechanism moving, as a GIF, an MP4 or a self-contained HTML page."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from lagrange_cli.cli import app, check_outputs, fail_with, write_atomically
from lagrange_cli.cli.boundary import check_positive


@app.command()
def animate(
    file: Annotated[str, typer.Argument(help="A system file, or the name of a bundled system (e.g. double_pendulum).")],
    output_path: Annotated[Path, typer.Option("-o", "--output", help="The animation: .gif (pillow), .mp4 (needs ffmpeg) or .html (self-contained; - for HTML on stdout).")],
    t_end: Annotated[float | None, typer.Option("--t-end", help="Final time (default: the file's simulate.t_end, else 10).", callback=check_positive)] = None,
    speed: Annotated[float, typer.Option(help="Playback speed: 1 is real time, 2 twice as fast.", callback=check_positive)] = 1.0,
    fps: Annotated[float, typer.Option(help="Frames per second of the animation.", callback=check_positive)] = 25.0,
    view: Annotated[str | None, typer.Option(help="Spatial systems: 3d (the default), or the projection xy, xz or yz.")] = None,
    trail: Annotated[float | None, typer.Option(help="Draw trails over this much of the system's time (default: the whole run so far).", callback=check_positive)] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", help="Override parameters: name=value, repeated or separated by commas (k=1,m=2).")] = None,
    initial: Annotated[list[str] | None, typer.Option("--initial", help="Override initial values: q=value,q_dot=value, repeated or separated by commas.")] = None,
    method: Annotated[str | None, typer.Option(help="auto, RK45, DOP853, Radau, BDF, LSODA or symplectic.")] = None,
) -> None:
    """Animate a system: particles, bodies and the file's `draw` segments and trails, moving in real time (exit 1 if the run fails)."""
    check_outputs(output_path, reading=file)
    from lagrange_cli.errors import LagrangeError

    to_stdout = str(output_path) == "-"
    try:
        from lagrange_cli import animate as core
        from lagrange_cli.cli.numeric import assignments_of
        from lagrange_cli.derive import load_system_and_model

        core.check_output(Path("motion.html") if to_stdout else output_path)
        if view is not None and view.lower() not in core.VIEWS:
            raise LagrangeError(f"--view {view!r}: unknown view\n  expected: one of {', '.join(core.VIEWS)}")
        system, model = load_system_and_model(file, shared=True)  # compiled from the symengine forms
        core.scene(system, model)  # nothing to draw: refused before the run
        parameters, values = assignments_of(model, set_ or [], "--set"), assignments_of(model, initial or [], "--initial")
        run = core.simulate_for(model, speed=speed, fps=fps, t_end=t_end, method=method, parameters=parameters, initial=values)
        movie = core.animation(system, model, run, speed=speed, fps=fps, view=view, trail=trail)
        if to_stdout:
            write_atomically(output_path, movie.to_html())
        else:
            movie.save(output_path)
    except LagrangeError as error:
        fail_with(error)
    from lagrange_cli.cli.boundary import console, plain

    report = console(stderr=to_stdout)
    where = "stdout" if to_stdout else str(output_path)
    report.print(plain(f"{run.title}: {len(movie)} frames at {movie.fps:.3g} per second, t = {movie.times[0]:g} .. {movie.times[-1]:g}, written to {where}"), markup=False)
    if run.failed:
        console(stderr=True).print(plain(f"error: {run.message}; the animation shows the run up to there"), markup=False)
        raise typer.Exit(1)
