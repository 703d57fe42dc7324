"""Writes docs/double_pendulum_frame.png, the animation frame the README shows:
`python docs/frame.py` (from the repository, with the package importable)."""

from __future__ import annotations

from pathlib import Path

from lagrange_cli import load

FRAME_TIME = 2.4
"""The time of the frame shown: the lower bob well into its chaotic swing, with its trail."""


def main() -> None:
    run = load("double_pendulum").simulate(t_end=3.0, samples=76, method="DOP853", backend="python")
    movie = run.animate(fps=25)
    k = round(FRAME_TIME * 25)
    (Path(__file__).parent / "double_pendulum_frame.png").write_bytes(movie.frame(k))


if __name__ == "__main__":
    main()
