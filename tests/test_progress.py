"""Long commands show progress on stderr (plain lines with an estimate when stderr is not a
terminal), never on stdout, and `--quiet` silences it."""

from __future__ import annotations

import json
import re

import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.cli.progress import Reporter, left
from lagrange_cli.numeric.accuracy import Step

runner = CliRunner()
STRESS = ["stress", "harmonic_oscillator", "--scale", "k=4,9", "--t-end", "2", "--method", "RK45:python"]
STUDY = ["accuracy", "harmonic_oscillator", "--method", "RK45:python", "--tolerances", "1e-3,1e-5", "--repeats", "0", "--samples", "11"]


def test_stress_reports_each_regime_on_stderr_and_json_on_stdout_still_parses() -> None:
    result = runner.invoke(app, [*STRESS, "--json", "-"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["passed"] is True
    lines = [line for line in result.stderr.splitlines() if line.startswith("stress: ")]
    assert lines[0].startswith("stress: regime 1/2 (k = 4) done, about ") and lines[0].endswith(" left"), lines
    assert lines[1] == "stress: regime 2/2 (k = 9) done", lines
    assert "stress: regime" not in result.stdout


def test_accuracy_reports_each_run_on_stderr() -> None:
    result = runner.invoke(app, [*STUDY, "--json", "-"])
    assert result.exit_code == 0, result.output
    assert len(json.loads(result.stdout)["points"]) == 2
    lines = [line for line in result.stderr.splitlines() if line.startswith("accuracy: ")]
    assert [re.sub(r", about .*", "", line) for line in lines] == [
        "accuracy: run 1/3 (reference) done",
        "accuracy: run 2/3 (RK45:python 1e-03) done",
        "accuracy: run 3/3 (RK45:python 1e-05) done",
    ]
    assert "accuracy: run" not in result.stdout


@pytest.mark.parametrize("args", [[*STRESS, "--quiet"], [*STUDY, "-q"]])
def test_quiet_shows_no_progress(args: list[str]) -> None:
    result = runner.invoke(app, [*args, "--json", "-"])
    assert result.exit_code == 0, result.output
    json.loads(result.stdout)
    assert " done" not in result.stderr


def test_progress_text_from_the_file_is_data(capsys: pytest.CaptureFixture[str]) -> None:
    with Reporter("stress", "regime", terminal=False) as report:
        report(Step(0, 2, "k\x1b[2J = 1", running="DOP853 1e-06"))  # under way: no line
        report(Step(1, 2, "k\x1b[2J = 1\nfake: line"))
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and "\x1b" not in captured.err and "\\x1b[2J" in captured.err, captured.err


def test_the_estimate_reads_as_a_person_would_say_it() -> None:
    assert left(0.4) == "about 1 s left" and left(42.2) == "about 42 s left" and left(75) == "about 75 s left" and left(600) == "about 10 min left"


def test_a_terminal_gets_a_bar_that_is_cleared() -> None:
    with Reporter("stress", "regime", terminal=True) as report:
        report(Step(0, 3, "[bold]k[/bold] = 1", running="reference"))
        report(Step(1, 3, "[bold]k[/bold] = 1"))
        assert report._bar is not None
    assert report._bar is None


def test_the_estimate_weighs_units_by_their_share(monkeypatch: pytest.MonkeyPatch) -> None:
    import time

    report = Reporter("stress", "regime", terminal=False)
    report.start = 0.0
    monkeypatch.setattr(time, "perf_counter", lambda: 10.0)
    assert report.eta(Step(1, 3, "defaults")) == "about 20 s left"
    assert report.eta(Step(1, 3, "defaults", fraction=1 / 12)) == "about 2 min left"  # the long horizon is still to come
    assert report.eta(Step(3, 3, "high energy", fraction=1.0)) == "finished"


def test_the_estimate_leaves_the_compiling_out(monkeypatch: pytest.MonkeyPatch) -> None:
    """The first run on a machine spends seconds compiling the loops, once: the pace of the rest is the pace
    without them (a cold first regime of three took 10 s, 6 of them compiling: 8 s left, not 20)."""
    import time

    from lagrange_cli.numeric import compile

    monkeypatch.setattr(compile, "_COMPILING", [100.0])  # compiled before this command (a notebook's earlier study)
    report = Reporter("stress", "regime", terminal=False)
    report.start = 0.0
    monkeypatch.setattr(time, "perf_counter", lambda: 10.0)
    assert report.eta(Step(1, 3, "defaults")) == "about 20 s left"
    compile.note_compiling(6.0)
    assert report.eta(Step(1, 3, "defaults")) == "about 8 s left"
    compile.note_compiling(194.0)
    assert report.eta(Step(1, 3, "defaults")) == "about 1 s left"  # never a negative pace


def test_simulate_takes_quiet_and_prints_no_progress_off_a_terminal() -> None:
    result = runner.invoke(app, ["simulate", "simple_pendulum", "--t-end", "1", "--backend", "python", "--quiet"])
    assert result.exit_code == 0, result.output
    assert "finished" in result.stdout and "simulating" not in result.stderr and "preparing" not in result.stderr


def test_simulate_bar_says_preparing_until_the_run_reports(monkeypatch: pytest.MonkeyPatch) -> None:
    """On a terminal the bar appears while numba compiles (before the run's first report)."""
    import sys

    from lagrange_cli.cli import numeric

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    monkeypatch.setattr(numeric, "PROGRESS_AFTER", 0.0)
    with numeric._Progress() as progress:
        assert progress.timer is not None
        progress.timer.cancel()
        progress.timer.function(*progress.timer.args)  # what the timer does when the second has passed: deterministic here
        assert progress.bar is not None and progress.bar.tasks[0].description.startswith("preparing")
        progress(0.5)
        assert progress.bar.tasks[0].description == "simulating" and progress.bar.tasks[0].completed == 0.5
    assert progress.bar is None
    with numeric._Progress(quiet=True) as silent:
        silent(0.5)
        assert silent.timer is None and silent.bar is None
