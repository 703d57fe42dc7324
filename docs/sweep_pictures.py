"""The README's sweep pictures: `python docs/sweep_pictures.py` writes docs/sweep_*.png.

1. docs/sweep_basin.png: which initial angles of the double pendulum (at rest) make the lower
   pendulum flip over (|phi| reaches pi) within 10 s, and when: `lagrange sweep double_pendulum
   --initial theta=-3..3:120 --initial phi=-3..3:120 --until 'Abs(phi)-pi' --measure t_event --t-end 10 --rtol 1e-6 --plot ...`
2. docs/sweep_kapitza.png: a bifurcation diagram of the Kapitza pendulum over the drive frequency:
   the angle once per drive period (a stroboscopic section `sin(omega*t)=0, cos(omega*t)>0`)
   after the first 5 s, started 0.1 rad from the inverted position. Below Kapitza's threshold
   (a omega > sqrt(2 g l), omega > 443 /s) the pendulum falls; above it swings about pi.
3. docs/sweep_elastic.png: a Poincaré section (theta = 0, theta_dot > 0) of the elastic pendulum,
   16 runs from x = 0.3 at rest at angles 0.2 .. 1.4: `lagrange sweep elastic_pendulum
   --initial theta=0.2..1.4:16 --initial x=0.3 --section 'theta=0, theta_dot>0' --t-end 300 --plot ...`
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from typer.testing import CliRunner

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lagrange_cli import sweep as library  # noqa: E402
from lagrange_cli.api import load  # noqa: E402
from lagrange_cli.cli import app  # noqa: E402

DOCS = ROOT / "docs"


def command(*arguments: str) -> None:
    result = CliRunner().invoke(app, ["sweep", *arguments, "--workers", "2", "-q"])
    if result.exit_code != 0:
        raise SystemExit(result.output)


def kapitza(path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    system = load("kapitza_pendulum")
    table = system.sweep(parameters={"omega": (200.0, 1000.0, 161)}, section="sin(omega*t)=0, cos(omega*t)>0", t_end=10, rtol=1e-8, atol=1e-10, workers=2)
    table = table if isinstance(table, library.Table) else library.Table(list(table.columns), table.values.tolist())
    omega, t, theta = table.column("omega"), table.column("t"), table.column("theta")
    late = t > 5
    wrapped = theta[late] % (2 * math.pi)
    fig = Figure(figsize=(7, 5.2), layout="constrained")
    ax = fig.add_subplot()
    ax.scatter(omega[late], wrapped, s=0.6, c="k", linewidths=0)
    ax.axvline(math.sqrt(2 * 9.81 * 1.0) / 0.01, color="tab:red", lw=0.8, ls="--", label="Kapitza's threshold a omega = sqrt(2 g l)")
    ax.set_xlabel("drive frequency omega (1/s)")
    ax.set_ylabel("theta once per drive period, t > 5 s (rad, mod 2 pi)")
    ax.set_ylim(0, 2 * math.pi)
    ax.legend(loc="lower right")
    fig.suptitle("Kapitza pendulum: bifurcation diagram over the drive frequency")
    fig.savefig(path, dpi=120)


def main() -> None:
    command(
        "double_pendulum",
        "--initial",
        "theta=-3..3:120",
        "--initial",
        "phi=-3..3:120",
        "--until",
        "Abs(phi)-pi",
        "--measure",
        "t_event",
        "--t-end",
        "10",
        "--rtol",
        "1e-6",
        "--plot",
        str(DOCS / "sweep_basin.png"),
    )
    kapitza(DOCS / "sweep_kapitza.png")
    command("elastic_pendulum", "--initial", "theta=0.2..1.4:16", "--initial", "x=0.3", "--section", "theta=0, theta_dot>0", "--t-end", "300", "--plot", str(DOCS / "sweep_elastic.png"))


if __name__ == "__main__":
    main()
