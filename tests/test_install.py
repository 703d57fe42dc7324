"""A plain `pip install` (no extras: no numba, no matplotlib) runs every command.

The slow test builds a wheel of this working tree, installs it into a fresh virtual
environment with its dependencies from the package index, and runs every command on a
bundled system from there. The fast tests take numba and matplotlib away inside this process
(`sys.modules[name] = None` makes them unimportable) and check the fallbacks and hints.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app

from .conftest import ROOT
from .limits import DEADLOCK

runner = CliRunner()


@pytest.fixture
def without(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Iterator[Callable[[str], None]]:
    """`without("numba")`: that package cannot be found or imported for the test's duration."""
    monkeypatch.setenv("LAGRANGE_CACHE_DIR", str(tmp_path / "cache"))

    def hide(name: str) -> None:
        monkeypatch.setitem(sys.modules, name, None)  # type: ignore[arg-type]

    yield hide


def test_without_matplotlib_plot_is_a_one_line_hint_before_any_work(without: Callable[[str], None], tmp_path: Path) -> None:
    without("matplotlib")
    for command in (["simulate", "simple_pendulum", "--t-end", "0.1"], ["accuracy", "simple_pendulum", "--t-end", "0.1", "--repeats", "0"]):
        figure = tmp_path / "figure.png"
        # a file that does not exist: the hint must come before the file is read
        result = runner.invoke(app, [*command[:1], str(tmp_path / "missing.yaml"), *command[2:], "--plot", str(figure)])
        assert result.exit_code == 2, result.output
        assert "pip install 'lagrange-cli[plot]'" in result.output and "missing.yaml" not in result.output
        assert len(result.output.strip().splitlines()) == 1 and "Traceback" not in result.output
        assert not figure.exists()


def test_without_numba_the_compiled_backend_falls_back_with_a_note(without: Callable[[str], None]) -> None:
    without("numba")
    result = runner.invoke(app, ["simulate", "simple_pendulum", "--t-end", "0.5", "--backend", "compiled"])
    assert result.exit_code == 0, result.output
    assert "(python)" in result.output and "numba is not installed" in result.output and "lagrange-cli[fast]" in result.output
    quiet = runner.invoke(app, ["simulate", "simple_pendulum", "--t-end", "0.5"])
    assert quiet.exit_code == 0 and "lagrange-cli[fast]" not in quiet.output  # no note when nobody asked for numba


def test_without_numba_the_symplectic_method_names_the_extra(without: Callable[[str], None]) -> None:
    without("numba")
    result = runner.invoke(app, ["simulate", "simple_pendulum", "--t-end", "0.5", "--method", "symplectic"])
    assert result.exit_code == 2 and "lagrange-cli[fast]" in result.output and "Traceback" not in result.output


def test_without_numba_accuracy_runs_the_rest_and_names_the_extra_for_symplectic(without: Callable[[str], None]) -> None:
    without("numba")
    result = runner.invoke(app, ["accuracy", "simple_pendulum", "--t-end", "0.2", "--repeats", "0", "--tolerances", "1e-3", "--method", "symplectic,RK45"])
    assert result.exit_code == 0, result.output
    assert "lagrange-cli[fast]" in result.output
    # the symplectic method has no python backend: nothing suggests one, except the RK45 runs' reproducing commands
    assert not any("--backend python" in line for line in result.output.splitlines() if "try: lagrange simulate" not in line), result.output
    assert re.search(r"^ *RK45 \(python\) .* ok *$", result.output, re.MULTILINE), result.output


def run(venv: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(LAGRANGE_CACHE_DIR=str(cwd / "cache"), COLUMNS="100", PYTHONDONTWRITEBYTECODE="1")
    return subprocess.run([str(venv / "bin" / "lagrange"), *args], cwd=cwd, capture_output=True, text=True, timeout=DEADLOCK, env=env)


@pytest.mark.slow
def test_a_plain_install_runs_every_command(tmp_path: Path) -> None:
    wheels = tmp_path / "wheels"
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheels), str(ROOT)], capture_output=True, text=True, timeout=DEADLOCK)
    assert built.returncode == 0, built.stderr
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=DEADLOCK)
    pip = [str(venv / "bin" / "python"), "-m", "pip", "install", "-q"]
    installed = subprocess.run([*pip, *map(str, wheels.glob("*.whl"))], capture_output=True, text=True, timeout=DEADLOCK)
    assert installed.returncode == 0, installed.stderr
    listed = subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "list"], capture_output=True, text=True, timeout=DEADLOCK).stdout.lower()
    assert "numpy" in listed and "scipy" in listed and "numba" not in listed and "matplotlib" not in listed

    work = tmp_path / "work"  # away from the source tree: bundled systems come from the installed package
    work.mkdir()
    commands = [
        ["--version"],
        ["--help"],
        ["derive", "double_pendulum"],
        ["derive", "double_pendulum", "--latex", "--standalone"],
        ["derive", "double_pendulum", "--python"],
        ["check", "simple_pendulum"],
        ["info", "double_pendulum"],
        ["equilibria", "simple_pendulum"],
        ["linearize", "double_pendulum"],
        ["simulate", "simple_pendulum", "--t-end", "2", "-o", "trajectory.csv"],
        ["simulate", "simple_pendulum", "--t-end", "2", "--backend", "compiled"],
        ["accuracy", "simple_pendulum", "--t-end", "1", "--tolerances", "1e-3,1e-5", "--repeats", "0"],
        ["stress", "simple_pendulum", "--t-end", "1", "--long", "2", "--method", "RK45,DOP853"],
    ]
    for args in commands:
        result = run(venv, work, *args)
        assert result.returncode == 0 and "Traceback" not in result.stderr, f"lagrange {' '.join(args)}:\n{result.stdout}\n{result.stderr}"
    assert (work / "trajectory.csv").read_text().startswith("t,theta,theta_dot,energy")
    assert "lagrange-cli[fast]" in run(venv, work, "simulate", "simple_pendulum", "--t-end", "1", "--backend", "compiled").stdout
    for args in (["simulate", "simple_pendulum", "--plot", "motion.png"], ["accuracy", "simple_pendulum", "--plot", "study.png"]):
        result = run(venv, work, *args)
        assert result.returncode == 2 and "pip install 'lagrange-cli[plot]'" in result.stderr and "Traceback" not in result.stderr, result.stderr
        assert not (work / args[-1]).exists()
