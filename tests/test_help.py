"""The command line surface: readable help at 80 columns, -h, --version, and a quiet exit when
the reader of stdout stops early (`| head -1`)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import typer.main
from typer.testing import CliRunner

from lagrange_cli import __version__
from lagrange_cli.cli import app

from .conftest import ROOT
from .limits import DEADLOCK

runner = CliRunner()
GROUP = typer.main.get_command(app)
COMMANDS = ["derive", "check", "info", "equilibria", "linearize", "simulate", "animate", "accuracy", "stress", "sweep"]


def helps(command: str | None) -> tuple[str, list[str]]:
    """The help of `lagrange [command]` at 80 columns, and the help texts of its parameters."""
    args = [command, "--help"] if command else ["--help"]
    result = runner.invoke(app, args, env={"COLUMNS": "80"})
    assert result.exit_code == 0, result.output
    ctx = GROUP.make_context("lagrange", [command or "--version"], resilient_parsing=True)
    target = GROUP.get_command(ctx, command) if command else GROUP  # type: ignore[attr-defined]
    return result.stdout, [p.help for p in target.get_params(ctx) if getattr(p, "help", None)]


@pytest.mark.parametrize("command", [None, *COMMANDS])
def test_help_is_readable_at_80_columns(command: str | None) -> None:
    text, texts = helps(command)
    assert not re.search(r"<\w+(\[\w+\])?>|\{\w+\}", text), text  # no <bool>, <str>, <list[str]>, {file}
    assert max(len(line) for line in text.splitlines()) <= 80
    flat = " ".join(text.split())
    for help_text in texts:  # each description reads as one piece of text, only wrapped
        assert " ".join(help_text.split()) in flat, help_text
    widths = [len(line.strip()) for line in text.splitlines() if line.startswith("  ")]
    assert max(widths) >= 60  # descriptions use the width, not a narrow column


def test_usage_lines_name_arguments_plainly() -> None:
    assert re.search(r"Usage: \S+ derive \[OPTIONS\] FILE\n", helps("derive")[0])
    assert re.search(r"Usage: \S+ check \[OPTIONS\] PATHS\.\.\.\n", helps("check")[0])
    assert re.search(r"Usage: \S+ \[OPTIONS\] COMMAND \[ARGS\]\.\.\.\n", helps(None)[0])


def test_flags_have_no_metavar_and_options_show_what_they_take() -> None:
    text = helps("derive")[0]
    assert re.search(r"^  --latex +A LaTeX", text, re.MULTILINE)
    assert "--form [lagrange|matrix|solved|hamilton|reduced]" in text and "-o, --output FILE" in text
    assert "--t-end NUMBER" in helps("simulate")[0]


def test_the_command_list_follows_the_pipeline() -> None:
    text = helps(None)[0].split("Commands:")[1]
    assert [line.split()[0] for line in text.splitlines() if line.startswith("  ") and not line.startswith("   ")] == COMMANDS


@pytest.mark.parametrize("command", [None, "derive", "simulate"])
def test_h_is_help(command: str | None) -> None:
    prefix = [command] if command else []
    short, long = runner.invoke(app, [*prefix, "-h"]), runner.invoke(app, [*prefix, "--help"])
    assert short.exit_code == 0 and short.stdout == long.stdout and "Usage:" in short.stdout


def test_version() -> None:
    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0 and result.stdout == f"lagrange {__version__}\n"


def test_standalone_needs_latex() -> None:
    result = runner.invoke(app, ["derive", "simple_pendulum", "--standalone"])
    assert result.exit_code == 2 and "--standalone applies to --latex" in result.output
    assert runner.invoke(app, ["derive", "simple_pendulum", "--latex", "--standalone"]).exit_code == 0


@pytest.mark.parametrize("args", [["derive", "double_pendulum"], ["check", "systems/simple_pendulum.yaml"], ["--help"]])
def test_a_reader_that_stops_early_ends_the_run_quietly(args: list[str]) -> None:
    """stdout closed before anything is written: plain writes (derive), rich (check) and help."""
    with subprocess.Popen([sys.executable, "-m", "lagrange_cli", *args], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE) as process:
        assert process.stdout is not None and process.stderr is not None
        process.stdout.close()
        stderr = process.stderr.read()
        assert process.wait(timeout=DEADLOCK) == 0 and stderr == b""


def test_head_takes_the_first_line(tmp_path: Path) -> None:
    """A CSV trajectory of about 2 MB, far more than a pipe holds, read by `head -1`."""
    command = f"{sys.executable} -m lagrange_cli simulate simple_pendulum --t-end 1 --samples 20000 -o -"
    shell = f"{command} | head -1; exit ${{PIPESTATUS[0]}}"
    env = {**os.environ, "LAGRANGE_CACHE_DIR": str(tmp_path)}
    result = subprocess.run(["bash", "-c", shell], cwd=ROOT, capture_output=True, text=True, timeout=DEADLOCK, env=env)
    assert result.returncode == 0 and result.stdout == "t,theta,theta_dot,energy\n"
    assert not re.search("Traceback|Broken|Exception ignored|error", result.stderr), result.stderr


@pytest.mark.parametrize("json_report", [False, True])
def test_a_reader_that_stops_early_keeps_checks_verdict(tmp_path: Path, json_report: bool) -> None:
    """`lagrange check wrong.yaml | head`: the table is cut short, the wrong answer still exits 1."""
    wrong = (ROOT / "systems" / "simple_pendulum.yaml").read_text().replace("g/l*sin(theta)", "g/l*cos(theta)")
    assert wrong != (ROOT / "systems" / "simple_pendulum.yaml").read_text()
    path = tmp_path / "wrong.yaml"
    path.write_text(wrong)
    with subprocess.Popen([sys.executable, "-m", "lagrange_cli", "check", str(path), *(["--json"] if json_report else [])], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE) as process:
        assert process.stdout is not None and process.stderr is not None
        process.stdout.close()
        stderr = process.stderr.read()
        assert process.wait(timeout=DEADLOCK) == 1, stderr
        assert b"Traceback" not in stderr
