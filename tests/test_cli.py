"""Every command through typer's CliRunner, plus start-up checks in a real subprocess."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from lagrange_cli.cli import app

from .conftest import ROOT
from .limits import DEADLOCK

runner = CliRunner()


def test_derive_bundled_system_by_name() -> None:
    result = runner.invoke(app, ["derive", "double_pendulum"])
    assert result.exit_code == 0, result.output
    assert "theta_ddot" in result.stdout and result.stdout.count("= 0") == 2


def test_derive_formats_to_stdout() -> None:
    for flag, marker in (("--latex", "\\begin{align*}"), ("--python", "def rhs(t, y, p=PARAMETERS)"), ("--text", "= 0")):
        result = runner.invoke(app, ["derive", "double_pendulum", flag])
        assert result.exit_code == 0 and marker in result.stdout
    result = runner.invoke(app, ["derive", "double_pendulum", "--form", "matrix"])
    assert "mass matrix =" in result.stdout and "forcing =" in result.stdout


def test_output_file_written_atomically(tmp_path: Path) -> None:
    out = tmp_path / "eom.py"
    result = runner.invoke(app, ["derive", "double_pendulum", "--python", "-o", str(out)])
    assert result.exit_code == 0 and result.stdout == ""
    assert "def rhs" in out.read_text()
    assert [p.name for p in tmp_path.iterdir()] == ["eom.py"]


def test_two_formats_is_an_error() -> None:
    result = runner.invoke(app, ["derive", "double_pendulum", "--latex", "--python"])
    assert result.exit_code == 2 and "choose one" in result.output


def test_unknown_system_suggests_a_bundled_one() -> None:
    result = runner.invoke(app, ["derive", "double_pendulm"])
    assert result.exit_code == 2 and "double_pendulum" in result.output


def test_solved_form_refused_for_large_systems(tmp_path: Path) -> None:
    coordinates = ", ".join(f"x{i}" for i in range(6))
    kinetic = " + ".join(f"x{i}_dot**2" for i in range(6))
    path = tmp_path / "big.yaml"
    path.write_text(f"coordinates: [{coordinates}]\nkinetic: {kinetic}\n")
    result = runner.invoke(app, ["derive", str(path), "--form", "solved"])
    assert result.exit_code == 2 and "--form matrix" in result.output and "Traceback" not in result.output


def test_check_passes_on_the_bundled_systems() -> None:
    result = runner.invoke(app, ["check", str(ROOT / "systems" / "double_pendulum.yaml")])
    assert result.exit_code == 0, result.output
    assert "pass" in result.stdout


def test_check_rejects_a_wrong_answer(tmp_path: Path) -> None:
    text = (ROOT / "systems" / "double_pendulum.yaml").read_text().replace("2*g/l*sin(theta)", "g/l*sin(theta)")
    path = tmp_path / "wrong.yaml"
    path.write_text(text)
    result = runner.invoke(app, ["check", str(path)])
    assert result.exit_code == 1 and "FAIL" in result.stdout


def imported_modules(*args: str) -> set[str]:
    code = "import sys; from lagrange_cli.cli import app\ntry:\n    app(" + repr(list(args)) + ")\nexcept SystemExit:\n    pass\nprint(' '.join(sorted(sys.modules)), file=sys.stderr)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=DEADLOCK)
    return set(result.stderr.split())


def test_help_imports_no_sympy_numpy_or_scipy() -> None:
    modules = imported_modules("--help")
    assert not {"sympy", "numpy", "scipy", "symengine", "matplotlib"} & modules


def test_derive_imports_no_numerics() -> None:
    modules = imported_modules("derive", "double_pendulum", "--python")
    assert "sympy" in modules
    assert not {"numpy", "scipy", "matplotlib"} & modules


def test_python_dash_m_entry_point() -> None:
    result = subprocess.run([sys.executable, "-m", "lagrange_cli", "--help"], capture_output=True, text=True, cwd=ROOT, timeout=DEADLOCK)
    assert result.returncode == 0 and "derive" in result.stdout
